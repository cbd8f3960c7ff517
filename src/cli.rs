//! The `hemi` command line.

use std::{path::PathBuf, time::Instant};

use clap::{Parser, Subcommand, error::ErrorKind};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::{
    Renderer, error::HemiError, film::OutputFile, resources::RenderSettings, sampling::SamplerKind, shading::RayCounts,
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
    /// Render the built-in default scene to an image.
    Render(RenderArgs),
}

/// Options of `hemi render`.
#[derive(clap::Args, Debug)]
struct RenderArgs {
    /// Output image: .png (8-bit sRGB) or .exr (linear f32, unclamped).
    #[arg(long, default_value = "hemi.png")]
    out: PathBuf,
    /// Total samples per pixel, reached progressively over frames.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    spp: u32,
    /// Samples per pixel traced by each frame.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=65_536))]
    spf: u32,
    /// Image size, WIDTHxHEIGHT.
    #[arg(long, default_value = "640x360", value_parser = parse_size)]
    size: (u32, u32),
    /// Seed of every random decision: the same seed gives the same image bit for bit.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Sample pattern: regular, random, jittered, n-rooks, multi-jittered, hammersley, cmj, zsobol.
    #[arg(long, default_value = "jittered", value_parser = parse_sampler)]
    sampler: SamplerKind,
    /// Worker threads (default: one per core).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    threads: Option<u32>,
    /// Print a per-system timing table for every frame.
    #[arg(long)]
    stats: bool,
}

fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s.split_once(['x', 'X']).ok_or("expected WIDTHxHEIGHT, e.g. 640x360")?;
    let w: u32 = w.trim().parse().map_err(|_| format!("width '{w}' is not a whole number"))?;
    let h: u32 = h.trim().parse().map_err(|_| format!("height '{h}' is not a whole number"))?;
    let settings = RenderSettings { width: w, height: h, ..Default::default() };
    settings.validate()?;
    Ok((w, h))
}

fn parse_sampler(s: &str) -> Result<SamplerKind, String> {
    SamplerKind::from_name(s).ok_or_else(|| {
        let names: Vec<&str> = SamplerKind::ALL.iter().map(|k| k.name()).collect();
        format!("unknown sampler '{s}' (expected one of: {})", names.join(", "))
    })
}

/// Parses `args` and runs the command. `Ok(None)` means help or version was printed.
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
        Command::Render(args) => render(args),
    }
}

fn render(args: RenderArgs) -> Result<(), HemiError> {
    // Open the output first: a bad path fails before any work is done.
    let output = OutputFile::create(&args.out)?;
    let settings = RenderSettings {
        width: args.size.0,
        height: args.size.1,
        samples_per_frame: args.spf,
        samples_per_set: args.spp.min(4096),
        max_spp: Some(args.spp),
        seed: args.seed,
        sampler: args.sampler,
        ..Default::default()
    };
    let mut renderer = Renderer::with_default_scene(settings);
    if let Some(threads) = args.threads {
        renderer = renderer.with_threads(threads as usize)?;
    }
    let progress = ProgressBar::with_draw_target(Some(args.spp as u64), ProgressDrawTarget::stderr());
    progress.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} spp ({eta} left)")
            .expect("valid template"),
    );
    let start = Instant::now();
    let (mut rays, mut trace_secs, mut frames) = (RayCounts::default(), 0.0, 0u32);
    while !renderer.converged() {
        let stats = renderer.run_frame()?;
        rays.add(&stats.rays);
        trace_secs += stats.time_of("trace").as_secs_f64();
        frames += 1;
        if args.stats {
            progress.suspend(|| print!("{}", stats.table()));
        }
        progress.set_position(stats.spp as u64);
    }
    progress.finish_and_clear();
    let elapsed = start.elapsed().as_secs_f64();
    output.write(renderer.image())?;
    eprintln!(
        "hemi: {}x{} at {} spp in {:.2} s ({} frames, {:.1} M rays, {:.2} Mrays/s while tracing) -> {}",
        args.size.0,
        args.size.1,
        renderer.spp(),
        elapsed,
        frames,
        rays.total() as f64 / 1e6,
        if trace_secs > 0.0 { rays.total() as f64 / trace_secs / 1e6 } else { 0.0 },
        args.out.display()
    );
    Ok(())
}
