//! The `hemi` command line and the tools only it uses: the error study ([`convergence`], its
//! [`plot`]), the peer renderers' scenes ([`peer_scene`]) and references ([`npy`],
//! [`peer_compare`]). Behind the cargo feature `cli` (on by default), so that a library user
//! who turns default features off compiles none of clap, indicatif or plotters.

mod compare;
pub mod convergence;
mod error_study;
mod merge;
pub mod npy;
pub mod peer_compare;
pub mod peer_scene;
pub mod plot;
mod render;

use clap::{Parser, Subcommand, error::ErrorKind};

use crate::{
    error::HemiError,
    resources::{Aov, RenderSettings},
    sampling::SamplerKind,
};

/// hemi: ambient occlusion + direct lighting by CPU ray tracing on bevy_ecs.
#[derive(Parser, Debug)]
#[command(name = "hemi", version, about)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Render a glTF 2.0 scene (or, without one, the built-in scene) to an image or a sequence.
    Render(render::RenderArgs),
    /// Measure RMSE against run time and spp for every sampler (CSV + log-log plot).
    Error(error_study::ErrorArgs),
    /// Compare AO with the peer renderers' references: bias and RMSE per scene.
    Compare(compare::CompareArgs),
    /// Sum the partials of a still split by sample index (`render --sample-range`) into the
    /// image a single render makes.
    Merge(merge::MergeArgs),
    /// Which frames of a sequence are done, partial (being written, or a writer was killed) or
    /// missing; exits 0 when all are done, 1 otherwise.
    Status(merge::StatusArgs),
}

fn parse_aov(s: &str) -> Result<Aov, String> {
    Aov::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = Aov::ALL.iter().map(|a| a.name()).collect();
        format!("unknown AOV '{s}' (expected one of: {})", names.join(", "))
    })
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WIDTHxHEIGHT, e.g. 640x360")?;
    let w: u32 = w.trim().parse().map_err(|_| format!("width '{w}' is not a whole number"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("height '{h}' is not a whole number"))?;
    let settings = RenderSettings { width: w, height: h, ..Default::default() };
    settings.validate()?;
    Ok((w, h))
}

fn parse_frames(s: &str) -> Result<(u32, u32), String> {
    let (a, b) = s.split_once("..").ok_or("expected a range START..END, e.g. 0..48")?;
    let a: u32 = a.trim().parse().map_err(|_| format!("frame '{a}' is not a whole number"))?;
    let b: u32 = b.trim().parse().map_err(|_| format!("frame '{b}' is not a whole number"))?;
    if b <= a {
        return Err(format!("frame range {a}..{b} is empty"));
    }
    Ok((a, b))
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
    let i: u32 = i.trim().parse().map_err(|_| format!("shard index '{i}' is not a whole number"))?;
    let n: u32 = n.trim().parse().map_err(|_| format!("shard count '{n}' is not a whole number"))?;
    if n == 0 || i >= n {
        return Err(format!("shard {i}/{n}: the index must be below the count"));
    }
    Ok((i, n))
}

fn parse_sampler(s: &str) -> Result<SamplerKind, String> {
    SamplerKind::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = SamplerKind::ALL.iter().map(|k| k.name()).collect();
        format!("unknown sampler '{s}' (expected one of: {})", names.join(", "))
    })
}

/// Parses `args` (the program name first) and runs the command; `--help` and `--version`
/// print and return `Ok(())`.
pub fn run<I, T>(args: I) -> Result<(), HemiError>
where
    I: IntoIterator<Item = T>,
    T: Into<std::ffi::OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e) if matches!(e.kind(), ErrorKind::DisplayHelp | ErrorKind::DisplayVersion) => {
            let _ = e.print();
            return Ok(());
        }
        Err(e) => {
            let text = e.render().to_string();
            let first = text.lines().next().unwrap_or("invalid arguments");
            return Err(HemiError::Usage(first.trim_start_matches("error: ").to_string()));
        }
    };
    match cli.command {
        Command::Render(args) => render::render(args),
        Command::Error(args) => error_study::error_study(args),
        Command::Compare(args) => compare::compare(args),
        Command::Merge(args) => merge::merge(args),
        Command::Status(args) => merge::status(args),
    }
}
