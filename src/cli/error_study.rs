//! `hemi error`: RMSE against spp and run time for every sampler, as CSV and a log-log plot.

use std::{io::IsTerminal, path::PathBuf};

use super::{check_distinct, console, convergence, parse_sampler, parse_size, peer_scene::PeerScene, plot};
use crate::{
    Renderer,
    analytic::AnalyticScene,
    error::HemiError,
    film::{OutputFile, OutputFormat},
    resources::{Aov, RenderSettings},
    sampling::SamplerKind,
};

/// Options of `hemi error`.
#[derive(clap::Args, Debug)]
pub(super) struct ErrorArgs {
    /// Scene: `sphere-over-plane` or `wall` (analytic references), a peer scene `.json` (its
    /// `ao` against `../refs/<name>.ao.npy` over hit pixels), or `default` (needs --reference).
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

pub(super) fn error_study(args: ErrorArgs) -> Result<(), HemiError> {
    use glam::Vec3;

    if OutputFormat::from_path(&args.plot)? != OutputFormat::Png {
        return Err(HemiError::Usage(format!("--plot {}: plots are written as .png", args.plot.display())));
    }
    let scene_file = std::path::Path::new(&args.scene);
    let inputs: Vec<&std::path::Path> = args.reference.iter().map(PathBuf::as_path).chain([scene_file]).collect();
    check_distinct(&[("--csv", &args.csv), ("--plot", &args.plot)], &inputs)?;
    let plot_file = OutputFile::create(&args.plot)?;
    let analytic = AnalyticScene::from_name(&args.scene);
    let peer =
        if args.scene.ends_with(".json") { Some(PeerScene::load(std::path::Path::new(&args.scene))?) } else { None };
    let (width, height) = match (args.size, analytic, &peer) {
        (Some(size), _, _) => size,
        (None, Some(a), _) => a.size(),
        (None, None, Some(p)) => (p.width, p.height),
        (None, None, None) => (160, 90),
    };
    let mut base = RenderSettings { width, height, seed: args.seed, ..Default::default() };
    let mut mask = None;
    let reference: Vec<Vec3> = match (analytic, &peer, &args.reference) {
        (_, _, Some(path)) => read_reference(path, width, height)?,
        (Some(a), _, None) => {
            let camera = a.camera(1.0, Vec3::ZERO);
            a.reference(&camera, width, height, 1.0, Vec3::ZERO)
                .map_err(HemiError::InvalidScene)?
                .into_iter()
                .map(Vec3::splat)
                .collect()
        }
        (None, Some(p), None) => {
            if (width, height) != (p.width, p.height) {
                return Err(HemiError::Usage(format!("peer references are {}x{}: drop --size", p.width, p.height)));
            }
            let (ao, hit) = p.read_reference()?;
            base.jitter = false;
            mask = Some(hit);
            ao.into_iter().map(Vec3::splat).collect()
        }
        (None, None, None) if args.scene == "default" => {
            return Err(HemiError::Usage(
                "scene 'default' needs --reference FILE.exr (e.g. hemi render --size 160x90 --spp 4096 --out ref.exr)"
                    .into(),
            ));
        }
        (None, None, None) => {
            return Err(HemiError::Usage(format!(
                "unknown scene '{}' (expected sphere-over-plane, wall, a peer .json or default)",
                args.scene
            )));
        }
    };
    let build = |settings: RenderSettings| -> Result<Renderer, HemiError> {
        Ok(match (analytic, &peer) {
            (Some(a), _) => {
                let mut r = Renderer::new(settings);
                a.spawn(r.world_mut(), 1.0, Vec3::ZERO);
                r
            }
            (None, Some(p)) => {
                let mut r = Renderer::new(settings);
                p.spawn(r.world_mut())?;
                r
            }
            (None, None) => Renderer::with_default_scene(settings),
        })
    };
    let samplers = if args.samplers.is_empty() { SamplerKind::ALL.to_vec() } else { args.samplers.clone() };
    let tty = std::io::stderr().is_terminal();
    let aov = peer.as_ref().map(|_| Aov::Ao);
    let points = convergence::study(build, &base, &samplers, args.max_spp, &reference, mask.as_deref(), aov, |p| {
        if tty {
            console::note_raw(&format!("\r{:>15} {:>6} spp  rmse {:.3e}   ", p.sampler.name(), p.spp, p.rmse));
        }
    })?;
    if tty {
        console::note("");
    }
    OutputFile::create_any(&args.csv)?.write_text(&convergence::to_csv(&points))?;

    let mut by_spp = Vec::new();
    let mut by_time = Vec::new();
    console::out(&format!(
        "{:<16} {:>12} {:>14} {:>14} {:>16}\n",
        "sampler", "slope(spp)", "slope(seconds)", "rmse@max", "seconds@max"
    ))?;
    for &k in &samplers {
        let (s_spp, s_time) = convergence::slopes(&points, k);
        let last = points.iter().rfind(|p| p.sampler == k).expect("every sampler was measured");
        let fmt = |s: Option<f64>| s.map_or("-".to_string(), |v| format!("{v:.3}"));
        console::out(&format!(
            "{:<16} {:>12} {:>14} {:>14.3e} {:>16.4}\n",
            k.name(),
            fmt(s_spp),
            fmt(s_time),
            last.rmse,
            last.seconds
        ))?;
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
    let title = format!("{}: RMSE vs spp (slope)", args.scene);
    let panels = [
        plot::Panel { title: &title, x_label: "samples per pixel", series: &by_spp },
        plot::Panel { title: "RMSE vs seconds (slope)", x_label: "seconds", series: &by_time },
    ];
    let img = plot::draw(&panels, (700, 560))
        .map_err(|e| HemiError::Io { path: args.plot.clone(), message: format!("cannot draw the plot: {e}") })?;
    plot_file.write_rgb8(&img)?;
    console::note(&format!("hemi: wrote {} and {}", args.csv.display(), args.plot.display()));
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
