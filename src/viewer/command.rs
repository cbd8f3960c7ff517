//! `hemi view`: its options and what it runs (feature `view`).

use std::{path::PathBuf, time::Instant};

use super::{SceneSource, Viewer, ViewerOptions, window};
use crate::{
    cli::shot::{LookArgs, RunArgs, SceneArgs},
    error::HemiError,
    resources::RenderSettings,
};

/// Options of `hemi view`.
#[derive(clap::Args, Debug)]
pub struct ViewArgs {
    #[command(flatten)]
    shot: SceneArgs,
    #[command(flatten)]
    look: LookArgs,
    #[command(flatten)]
    run: RunArgs,
    /// Samples per pixel a still view converges to [default: 1024, or a peer scene's
    /// ao.samples]: the image `hemi render --spp N` writes (byte for byte with --spf).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1_000_000))]
    spp: Option<u32>,
    /// Samples per frame of a still view [default: as many as fit --target-ms]; with k, the
    /// view converges to `hemi render --spp N --spf k` byte for byte.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65_536))]
    spf: Option<u32>,
    /// Target frame time in milliseconds: samples per frame and, while moving, the internal
    /// resolution adapt to it.
    #[arg(long, default_value_t = 33.0, value_parser = parse_ms)]
    target_ms: f64,
    /// Keep the full resolution while moving.
    #[arg(long)]
    no_dynamic_resolution: bool,
    /// Orbit once around the scene in this many seconds.
    #[arg(long, value_name = "SECONDS", value_parser = parse_ms)]
    turntable: Option<f64>,
    /// Start with the animation playing.
    #[arg(long)]
    play: bool,
    /// Start with the overlay shown (H toggles it).
    #[arg(long)]
    overlay: bool,
    /// Close the window after N frames.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u64).range(1..))]
    quit_after_frames: Option<u64>,
    /// Write what the window showed on its last frame (PNG).
    #[arg(long, value_name = "FILE")]
    screenshot: Option<PathBuf>,
    /// Write per-frame fps, latency, spp and resolution (JSON).
    #[arg(long, value_name = "FILE")]
    stats_json: Option<PathBuf>,
}

fn parse_ms(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("'{s}' must be a positive number")),
    }
}

/// Runs `hemi view`.
pub fn run(args: ViewArgs) -> Result<(), HemiError> {
    let launched = Instant::now();
    let warn = |w: String| crate::cli::console::note(&format!("hemi: warning: {w}"));
    if args.shot.transparent() {
        return Err(HemiError::Usage("--background transparent: a window has no alpha; give a colour".into()));
    }
    args.shot.check()?;
    let shot = &args.shot;
    let source = SceneSource::open(shot.scene.as_deref(), shot.camera.clone(), shot.animation.clone(), warn)?;
    let (size, spp, seed) = source.defaults();
    let settings =
        RenderSettings { seed: args.run.seed.unwrap_or(seed), sampler: args.run.sampler, ..Default::default() };
    let mut renderer = source.renderer(settings, warn)?;
    shot.stage(renderer.world_mut())?;
    if let Some(background) = shot.background_radiance() {
        renderer.settings_mut().background = background;
    }
    if let Some(threads) = args.run.threads {
        renderer = renderer.with_threads(threads as usize)?;
    }
    let options = ViewerOptions {
        size: args.run.size.unwrap_or(size),
        spp: args.spp.or(spp).unwrap_or(1024),
        spf: args.spf,
        target: std::time::Duration::from_secs_f64(args.target_ms / 1e3),
        dynamic_resolution: !args.no_dynamic_resolution,
        turntable: args.turntable,
        overlay: args.overlay,
        play: args.play,
        ..Default::default()
    };
    let mut viewer = Viewer::new(renderer, source.name(), options)?;
    viewer.set_tonemap(args.look.tonemap);
    viewer.set_exposure(args.look.exposure);
    let window_options = window::WindowOptions {
        quit_after_frames: args.quit_after_frames,
        screenshot: args.screenshot,
        stats_json: args.stats_json,
        launched: Some(launched),
        load_seconds: launched.elapsed().as_secs_f64(),
    };
    window::run(viewer, window_options)
}
