//! The `hemi` command line and the tools only it uses: the error study ([`convergence`], its
//! [`plot`]), the peer renderers' scenes ([`peer_scene`]) and references ([`npy`],
//! [`peer_compare`]). Behind the cargo feature `cli` (on by default), so that a library user
//! who turns default features off compiles none of clap, indicatif or plotters.

mod compare;
pub mod console;
pub mod convergence;
mod error_study;
mod frames;
mod info;
mod merge;
pub mod npy;
pub mod peer_compare;
pub mod peer_scene;
pub mod plot;
mod render;
pub mod shot;
pub mod tev;

use std::path::{Path, PathBuf};

use clap::{Parser, Subcommand, error::ErrorKind};

use crate::{
    error::HemiError,
    resources::{Aov, RenderSettings},
    sampling::SamplerKind,
};

/// hemi: ambient occlusion + direct lighting by CPU ray tracing on bevy_ecs.
#[derive(Parser, Debug)]
#[command(name = "hemi", version, about, arg_required_else_help = true)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a glTF 2.0 scene (or, without one, the built-in scene) to an image or a sequence.
    Render(render::RenderArgs),
    /// Measure RMSE against run time and spp for every sampler (CSV + log-log plot).
    #[command(arg_required_else_help = true)]
    Error(error_study::ErrorArgs),
    /// Compare AO with the peer renderers' references: bias and RMSE per scene.
    #[command(arg_required_else_help = true)]
    Compare(compare::CompareArgs),
    /// Sum the partials of a still split by sample index (`render --sample-range`) into the
    /// image a single render makes.
    Merge(merge::MergeArgs),
    /// Which frames of a sequence are done, partial (being written, or a writer was killed) or
    /// missing; exits 0 when all are done, 1 otherwise.
    Status(merge::StatusArgs),
    /// What a glTF file holds: scenes, nodes, meshes, materials, cameras, lights, animations,
    /// skins, and every warning the loader gives.
    #[command(arg_required_else_help = true)]
    Info(info::InfoArgs),
    /// Open a window on the scene and watch it converge; move the camera, play the animation.
    #[cfg(feature = "view")]
    View(crate::viewer::command::ViewArgs),
}

fn parse_aov(s: &str) -> Result<Aov, String> {
    Aov::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
        format!("unknown AOV '{s}' (expected one of: {})", names.join(", "))
    })
}

/// A whole number that fits a `u32`, or a message naming `what` and why not.
fn parse_count(s: &str, what: &str) -> Result<u32, String> {
    match s.trim().parse::<u32>() {
        Ok(v) => Ok(v),
        Err(e) if matches!(e.kind(), std::num::IntErrorKind::PosOverflow) => {
            Err(format!("{what} {} is too large (at most {})", s.trim(), u32::MAX))
        }
        Err(_) => Err(format!("{what} '{}' is not a whole number", s.trim())),
    }
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WIDTHxHEIGHT, e.g. 640x360")?;
    let (w, h) = (parse_count(w, "width")?, parse_count(h, "height")?);
    let settings = RenderSettings { width: w, height: h, ..Default::default() };
    settings.validate()?;
    Ok((w, h))
}

fn parse_fps(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("fps '{s}' must be a positive number")),
    }
}

fn parse_time(s: &str) -> Result<f32, String> {
    match s.parse::<f32>() {
        Ok(v) if v.is_finite() => Ok(v),
        _ => Err(format!("time '{s}' must be a finite number of seconds")),
    }
}

fn parse_shard(s: &str) -> Result<(u32, u32), String> {
    let (i, n) = s.split_once('/').ok_or("expected INDEX/COUNT, e.g. 0/4")?;
    let (i, n) = (parse_count(i, "shard index")?, parse_count(n, "shard count")?);
    if n == 0 || i >= n {
        return Err(format!("shard {i}/{n}: the index must be below the count"));
    }
    Ok((i, n))
}

/// Where `path` really is, as far as can be told without it existing: absolute, with its
/// folder resolved through links and `..` when the folder exists.
fn resolved(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    match (absolute.parent().and_then(|d| d.canonicalize().ok()), absolute.file_name()) {
        (Some(dir), Some(name)) => dir.join(name),
        _ => absolute,
    }
}

/// Refuses a command whose outputs (each with the option that names it) would overwrite each
/// other or one of its inputs.
fn check_distinct(outputs: &[(&str, &Path)], inputs: &[&Path]) -> Result<(), HemiError> {
    for (k, (option, path)) in outputs.iter().enumerate() {
        let here = resolved(path);
        if let Some(input) = inputs.iter().find(|input| resolved(input) == here) {
            return Err(HemiError::Usage(format!(
                "{option} {} would overwrite the input {}",
                path.display(),
                input.display()
            )));
        }
        if let Some((other, _)) = outputs[..k].iter().find(|(_, p)| resolved(p) == here) {
            return Err(HemiError::Usage(format!("{option} {} is also the file of {other}", path.display())));
        }
    }
    Ok(())
}

fn parse_sampler(s: &str) -> Result<SamplerKind, String> {
    SamplerKind::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = SamplerKind::ALL.iter().map(|k| k.name()).collect();
        format!("unknown sampler '{s}' (expected one of: {})", names.join(", "))
    })
}

/// Parses `args` (the program name first) and runs the command; `--help` and `--version`
/// print and return `Ok(())`. A usage error keeps clap's message, usage line and hint; a
/// bare `hemi` or a subcommand missing its arguments gets the help text as the error.
pub fn run<I, T>(args: I) -> Result<(), HemiError>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    crate::geometry::huge_pages::unmap_large_blocks_when_freed();
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => {
            return console::out(&e.render().to_string());
        }
        Err(e) if e.kind() == ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand => {
            // Nothing to run: the help is the answer, and the status says it was a usage error.
            console::note_raw(&e.render().to_string());
            std::process::exit(2);
        }
        Err(e) => {
            let text = e.render().to_string();
            return Err(HemiError::Usage(text.trim_start_matches("error: ").trim_end().to_string()));
        }
    };
    match cli.command {
        Command::Render(args) => render::render(args),
        Command::Error(args) => error_study::error_study(args),
        Command::Compare(args) => compare::compare(args),
        Command::Merge(args) => merge::merge(args),
        Command::Status(args) => merge::status(args),
        Command::Info(args) => info::info(args),
        #[cfg(feature = "view")]
        Command::View(args) => crate::viewer::command::run(args),
    }
}
