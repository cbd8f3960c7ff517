//! The `hemi` command line.

use std::{io::IsTerminal, path::PathBuf, time::Instant};

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
    /// Measure RMSE against run time and spp for every sampler (CSV + log-log plot).
    Error(ErrorArgs),
}

/// Options of `hemi error`.
#[derive(clap::Args, Debug)]
struct ErrorArgs {
    /// Scene: `sphere-over-plane` or `wall` (analytic references), or `default` (needs --reference).
    scene: String,
    /// Reference image (linear EXR of the same size), e.g. `hemi render --spp 4096 --out ref.exr`.
    #[arg(long)]
    reference: Option<PathBuf>,
    /// Largest spp measured (powers of two from 1).
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65_536))]
    max_spp: u32,
    /// Comma-separated samplers (default: all).
    #[arg(long, value_delimiter = ',', value_parser = parse_sampler)]
    samplers: Vec<SamplerKind>,
    /// Image size, WIDTHxHEIGHT (default: the scene's own).
    #[arg(long, value_parser = parse_size)]
    size: Option<(u32, u32)>,
    /// Seed.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// CSV output: sampler, spp, seconds, rays, rmse, relative_rmse.
    #[arg(long, default_value = "error.csv")]
    csv: PathBuf,
    /// Plot output (PNG): RMSE against spp and against seconds, log-log, with fitted slopes.
    #[arg(long, default_value = "error.png")]
    plot: PathBuf,
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
    #[arg(long, default_value = "cmj", value_parser = parse_sampler)]
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
        Command::Error(args) => error_study(args),
    }
}

fn error_study(args: ErrorArgs) -> Result<(), HemiError> {
    use crate::{analytic::AnalyticScene, convergence, plot};
    use glam::Vec3;

    let plot_file = OutputFile::create(&args.plot)?;
    let analytic = AnalyticScene::from_name(&args.scene);
    let (width, height) = match (args.size, analytic) {
        (Some(size), _) => size,
        (None, Some(a)) => a.size(),
        (None, None) => (160, 90),
    };
    let base = RenderSettings { width, height, seed: args.seed, ..Default::default() };
    let reference: Vec<Vec3> = match (analytic, &args.reference) {
        (_, Some(path)) => read_reference(path, width, height)?,
        (Some(a), None) => {
            let mut probe = Renderer::new(base.clone());
            let camera = a.spawn(probe.world_mut(), 1.0, Vec3::ZERO);
            a.reference(&camera, width, height, 1.0, Vec3::ZERO)
                .map_err(HemiError::InvalidScene)?
                .into_iter()
                .map(Vec3::splat)
                .collect()
        }
        (None, None) if args.scene == "default" => {
            return Err(HemiError::Usage(
                "scene 'default' needs --reference FILE.exr (e.g. hemi render --size 160x90 --spp 4096 --out ref.exr)"
                    .into(),
            ));
        }
        (None, None) => {
            return Err(HemiError::Usage(format!(
                "unknown scene '{}' (expected sphere-over-plane, wall or default)",
                args.scene
            )));
        }
    };
    let build = |settings: RenderSettings| -> Result<Renderer, HemiError> {
        Ok(match analytic {
            Some(a) => {
                let mut r = Renderer::new(settings);
                a.spawn(r.world_mut(), 1.0, Vec3::ZERO);
                r
            }
            None => Renderer::with_default_scene(settings),
        })
    };
    let samplers = if args.samplers.is_empty() { SamplerKind::ALL.to_vec() } else { args.samplers.clone() };
    let tty = std::io::stderr().is_terminal();
    let points = convergence::study(build, &base, &samplers, args.max_spp, &reference, None, |p| {
        if tty {
            eprint!("\r{:>15} {:>6} spp  rmse {:.3e}   ", p.sampler.name(), p.spp, p.rmse);
        }
    })?;
    if tty {
        eprintln!();
    }
    std::fs::write(&args.csv, convergence::to_csv(&points))
        .map_err(|e| HemiError::Io { path: args.csv.clone(), message: format!("cannot write CSV: {e}") })?;

    let mut by_spp = Vec::new();
    let mut by_time = Vec::new();
    println!(
        "{:<16} {:>12} {:>14} {:>14} {:>16}",
        "sampler", "slope(spp)", "slope(seconds)", "rmse@max", "seconds@max"
    );
    for &k in &samplers {
        let (s_spp, s_time) = convergence::slopes(&points, k);
        let last = points.iter().rfind(|p| p.sampler == k).expect("every sampler was measured");
        let fmt = |s: Option<f64>| s.map_or("-".to_string(), |v| format!("{v:.3}"));
        println!("{:<16} {:>12} {:>14} {:>14.3e} {:>16.4}", k.name(), fmt(s_spp), fmt(s_time), last.rmse, last.seconds);
        let mine = || points.iter().filter(|p| p.sampler == k);
        by_spp.push(plot::Series {
            label: format!("{} {}", k.name(), fmt(s_spp)),
            points: mine().map(|p| (p.spp as f64, p.rmse)).collect(),
        });
        by_time.push(plot::Series {
            label: format!("{} {}", k.name(), fmt(s_time)),
            points: mine().map(|p| (p.seconds, p.rmse)).collect(),
        });
    }
    let mut img = image::RgbImage::from_pixel(1400, 560, image::Rgb([255, 255, 255]));
    let title = format!("{}: RMSE vs spp (slope)", args.scene);
    plot::draw_panel(&mut img, (0, 0, 700, 560), &title, "samples per pixel", &by_spp);
    plot::draw_panel(&mut img, (700, 0, 700, 560), "RMSE vs seconds (slope)", "seconds", &by_time);
    plot_file.write_rgb8(&img)?;
    eprintln!("hemi: wrote {} and {}", args.csv.display(), args.plot.display());
    Ok(())
}

/// Reads a linear reference image of the expected size.
fn read_reference(path: &std::path::Path, width: u32, height: u32) -> Result<Vec<glam::Vec3>, HemiError> {
    let img = image::open(path)
        .map_err(|e| HemiError::Io { path: path.to_path_buf(), message: format!("cannot read reference: {e}") })?
        .into_rgb32f();
    if img.dimensions() != (width, height) {
        return Err(HemiError::Io {
            path: path.to_path_buf(),
            message: format!(
                "reference is {}x{}, the render is {width}x{height} (use --size)",
                img.width(),
                img.height()
            ),
        });
    }
    Ok(img.pixels().map(|p| glam::Vec3::from_array(p.0)).collect())
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
