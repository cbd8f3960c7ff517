//! `hemi render`: an image or a numbered sequence of a glTF, peer or the built-in scene.

use std::{path::PathBuf, time::Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use super::{
    check_distinct, console,
    frames::{Frames, animation_end, frame_count, parse_frames},
    parse_aov, parse_fps, parse_shard, parse_time,
    peer_scene::PeerScene,
    shot::{LookArgs, RunArgs, SceneArgs},
};
use crate::{
    Renderer,
    error::HemiError,
    film::{OutputFile, OutputFormat, Picture, is_complete_image},
    partial::{self, Partial},
    resources::{Aov, RenderSettings},
    scene::gltf::{LoadOptions, MAX_FRAMING_POSES, SpawnOptions},
    sequence::frame_path,
    stats::{RayCounts, mrays_per_second},
};

/// Options of `hemi render`.
#[derive(clap::Args, Debug)]
pub(super) struct RenderArgs {
    #[command(flatten)]
    shot: SceneArgs,
    #[command(flatten)]
    look: LookArgs,
    #[command(flatten)]
    run: RunArgs,
    /// Output image: .png (8-bit sRGB) or .exr (linear f32, unclamped). With --frames it must
    /// hold a frame-number placeholder: `{}`, `{:0N}` (zero-padded to N digits) or N `#`.
    #[arg(long, default_value = "hemi.png")]
    out: PathBuf,
    /// Render a numbered sequence: `all` (the whole animation, floor(duration·fps)+1 frames),
    /// `N` (one frame), `A..B` (B excluded) or `A..` (to the end of the animation).
    #[arg(long, value_parser = parse_frames)]
    frames: Option<Frames>,
    /// Frames per second of the sequence: frame f shows time f / fps.
    #[arg(long, default_value_t = 24.0, value_parser = parse_fps)]
    fps: f64,
    /// Render only every n-th frame of the sequence starting at the i-th, `i/n` (for array jobs);
    /// every frame is identical to the one an unsharded run writes.
    #[arg(long, value_parser = parse_shard)]
    shard: Option<(u32, u32)>,
    /// With --frames, leave out frames whose file is already complete (it decodes as an image
    /// of the right size, and so do its AOV files): a re-run after a failure or a cancel
    /// renders only what is missing. With --sample-range, keep a partial already there for
    /// the same render and range.
    #[arg(long)]
    skip_existing: bool,
    /// Render part K of N of a still split by sample index, `K/N`, into a partial (.exr) for
    /// `hemi merge`: whole frames of --spf samples (default: spp/N, up to 4096), shared out
    /// evenly, so that the merged image equals one render with that --spf bit for bit.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    sample_range: Option<(u32, u32)>,
    /// Scene time in seconds of a single image.
    #[arg(long, default_value_t = 0.0, value_parser = parse_time)]
    time: f32,
    /// Total samples per pixel, reached progressively over frames [default: 16, or a peer
    /// scene's ao.samples].
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=RenderSettings::MAX_SPP as i64))]
    spp: Option<u32>,
    /// Samples per pixel traced by each frame [default: all of --spp in one frame, up to 4096;
    /// 16 with --target-error, so pixels retire early]. Larger frames amortise the camera ray
    /// and per-frame work.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=65_536))]
    spf: Option<u32>,
    /// Print a per-system timing table for every frame.
    #[arg(long)]
    stats: bool,
    /// Adaptive sampling: stop sampling each pixel once the standard error of its mean
    /// luminance is at most E (after at least 16 samples; `--spp` stays the upper bound).
    #[arg(long, value_name = "E")]
    target_error: Option<f32>,
    /// Write every frame's statistics and the totals as JSON (throughput of AO rays under
    /// `ao_mrays_per_s`).
    #[arg(long)]
    stats_json: Option<PathBuf>,
    /// Also write these AOVs (comma-separated: ao, direct, albedo, normal, depth, alpha) as
    /// layers of one linear EXR beside the beauty (`ao`, `direct.R/G/B`, `albedo.R/G/B`,
    /// `N.X/Y/Z`, `Z`, and coverage `A`): the --out EXR itself, or `<stem>.exr` beside a PNG.
    #[arg(long, value_delimiter = ',', value_parser = parse_aov)]
    aov: Vec<Aov>,
    /// Write each --aov as a file of its own, `<stem>.<name>.exr` (RGB; one-channel AOVs
    /// repeated), instead of layers of one EXR.
    #[arg(long, requires = "aov")]
    aov_files: bool,
    /// Let a glTF file's buffer URIs name files outside its folder (absolute paths, `..`).
    #[arg(long)]
    allow_external_uris: bool,
    /// Stream the progressive image to a running tev (its --hostname, e.g. 127.0.0.1:14158).
    #[arg(long, value_name = "HOST:PORT")]
    display_server: Option<String>,
}

/// Times of at most `count` frames of `start..end` at `fps`, evenly spaced with the first and
/// the last included (a long range is not listed frame by frame).
fn frame_times(start: u32, end: u32, fps: f64, count: usize) -> Vec<f32> {
    let n = (end - start) as u64;
    let count = (count.max(2) as u64).min(n);
    let frame = |i: u64| if count < 2 { start as u64 } else { start as u64 + i * (n - 1) / (count - 1) };
    (0..count).map(|i| (frame(i) as f64 / fps) as f32).collect()
}

/// The frames this run renders: `spec` ended by the animation (`animation_end` frames, or an
/// error when it is too long to count), shared out by `--shard`; each frame's time checked.
fn frame_list(
    args: &RenderArgs,
    spec: Frames,
    animation_end: Result<Option<u32>, String>,
) -> Result<Vec<u32>, HemiError> {
    let range = spec.resolve(animation_end.map_err(HemiError::Usage)?).map_err(HemiError::Usage)?;
    let shard = args.shard.unwrap_or((0, 1));
    let list = shard_frames(range, shard);
    if list.is_empty() {
        return Err(HemiError::Usage(format!(
            "--shard {}/{} gets no frame of {}..{}",
            shard.0, shard.1, range.0, range.1
        )));
    }
    // Every frame's time must be a number the animation can be sampled at.
    let last_time = (range.1 - 1) as f64 / args.fps;
    if !(last_time as f32).is_finite() {
        return Err(HemiError::Usage(format!(
            "--frames {}..{} at --fps {} reaches time {last_time:e} s, beyond what a frame time can hold",
            range.0, range.1, args.fps
        )));
    }
    Ok(list)
}

/// The frames of `start..end` that shard `i/n` renders: every n-th, starting at the i-th.
fn shard_frames((start, end): (u32, u32), (i, n): (u32, u32)) -> Vec<u32> {
    (start..end).skip(i as usize).step_by(n as usize).collect()
}

/// Whether frame `out` and its AOV files are all complete images of `size`.
fn frame_complete(out: &std::path::Path, args: &RenderArgs, size: (u32, u32)) -> bool {
    is_complete_image(out, Some(size)) && aov_outputs(out, args).iter().all(|(_, p)| is_complete_image(p, Some(size)))
}

pub(super) fn render(args: RenderArgs) -> Result<(), HemiError> {
    match args.frames {
        Some(spec) if frame_path(&args.out, spec.start()).is_none() => {
            return Err(HemiError::Usage(format!(
                "--out {} needs a frame-number placeholder such as {{:04}} or #### with --frames",
                args.out.display()
            )));
        }
        // The scene is posed at the first frame's time: it must be a number.
        Some(spec) if !((spec.start() as f64 / args.fps) as f32).is_finite() => {
            return Err(HemiError::Usage(format!(
                "--frames {spec} at --fps {} starts at time {:e} s, beyond what a frame time can hold",
                args.fps,
                spec.start() as f64 / args.fps
            )));
        }
        Some(_) => {}
        None if args.shard.is_some() => return Err(HemiError::Usage("--shard needs --frames".into())),
        None if frame_path(&args.out, 0).is_some() => {
            return Err(HemiError::Usage(format!(
                "--out {} has a frame-number placeholder: add --frames, or name one file",
                args.out.display()
            )));
        }
        None if args.skip_existing && args.sample_range.is_none() => {
            return Err(HemiError::Usage("--skip-existing needs --frames or --sample-range".into()));
        }
        None => {}
    }
    if args.sample_range.is_some() {
        let conflict = [
            (args.frames.is_some(), "--frames"),
            (args.target_error.is_some(), "--target-error"),
            (!args.aov.is_empty(), "--aov"),
        ];
        if let Some((_, what)) = conflict.iter().find(|(on, _)| *on) {
            return Err(HemiError::Usage(format!("--sample-range renders one still: drop {what}")));
        }
        if !args.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr")) {
            return Err(HemiError::Usage(format!(
                "--sample-range writes a partial: --out {} must end in .exr",
                args.out.display()
            )));
        }
    }
    // Check the outputs first: a bad or colliding path fails before any work is done, and
    // nothing is written under an output's name until that output is complete.
    let first_out = match args.frames {
        Some(spec) => frame_path(&args.out, spec.start()).expect("checked above"),
        None => args.out.clone(),
    };
    let aov_paths = aov_outputs(&first_out, &args);
    let mut outputs: Vec<(&str, &std::path::Path)> = vec![("--out", &first_out)];
    outputs.extend(aov_paths.iter().map(|(option, path)| (option.as_str(), path.as_path())));
    outputs.extend(args.stats_json.as_deref().map(|p| ("--stats-json", p)));
    check_distinct(&outputs, &args.shot.scene.iter().map(PathBuf::as_path).collect::<Vec<_>>())?;
    OutputFormat::from_path(&first_out).map_err(|e| HemiError::Usage(e.to_string()))?;
    OutputFile::create(&first_out)?;
    for (_, path) in &aov_paths {
        OutputFile::create(path)?;
    }
    args.shot.check()?;
    let load_options = LoadOptions { allow_external_uris: args.allow_external_uris, ..Default::default() };
    let peer = match &args.shot.scene {
        Some(path) if path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) => {
            if args.shot.camera.is_some() || args.shot.animation.is_some() || args.frames.is_some() {
                return Err(HemiError::Usage("--camera, --animation and --frames need a glTF scene".into()));
            }
            Some(PeerScene::load_with(path, &load_options)?)
        }
        _ => None,
    };
    let size = args.run.size.or(peer.as_ref().map(|p| (p.width, p.height))).unwrap_or((640, 360));
    let spp = args.spp.or(peer.as_ref().map(|p| p.samples)).unwrap_or(16);
    let set = spp.min(RenderSettings::ONE_FRAME_SPP);
    let default_spf = match args.sample_range {
        Some((_, parts)) => partial::default_spf(spp, parts),
        None if args.target_error.is_some() => RenderSettings::ADAPTIVE_MIN_SPP,
        None => set,
    };
    let settings = RenderSettings {
        width: size.0,
        height: size.1,
        samples_per_frame: args.spf.unwrap_or(default_spf),
        samples_per_set: set,
        max_spp: Some(spp),
        seed: args.run.seed.or(peer.as_ref().map(|p| p.seed)).unwrap_or(0),
        sampler: args.run.sampler,
        // The peers' contract: one primary ray through each pixel centre.
        jitter: peer.is_none(),
        // Coverage (alpha) is accumulated with the AOVs.
        aovs: !args.aov.is_empty() || args.shot.transparent(),
        target_error: args.target_error,
        // Every image ends at its target; a part of a split render keeps its frames' sums.
        release_sums: args.sample_range.is_none(),
        ..Default::default()
    };
    settings.validate().map_err(HemiError::Usage)?;
    let mut renderer = match (&args.shot.scene, peer) {
        (None, _) => {
            if args.shot.camera.is_some() || args.shot.animation.is_some() {
                return Err(HemiError::Usage("--camera and --animation need a glTF scene".into()));
            }
            Renderer::with_default_scene(settings)
        }
        (Some(_), Some(peer)) => {
            let mut r = Renderer::new(settings);
            for w in peer.spawn(r.world_mut())? {
                console::note(&format!("hemi: warning: {w}"));
            }
            r
        }
        (Some(path), None) => {
            let scene = crate::scene::gltf::load_with(path, &load_options)?;
            for w in &scene.warnings {
                console::note(&format!("hemi: warning: {}: {w}", path.display()));
            }
            let mut r = Renderer::new(settings);
            // Posed at the start of the whole range and, without a camera in the file, framed
            // over all of its frames, so that every shard of a sequence sees the same camera.
            let time = args.frames.map_or(args.time, |spec| (spec.start() as f64 / args.fps) as f32);
            let framing_times = match args.frames {
                Some(spec) => {
                    // A range that does not resolve is refused below, once the scene is spawned.
                    let duration = scene.animation_duration(args.shot.animation.as_deref());
                    let end = duration.and_then(|d| frame_count(d, args.fps));
                    spec.resolve(end)
                        .map_or(Vec::new(), |(start, end)| frame_times(start, end, args.fps, MAX_FRAMING_POSES))
                }
                None => Vec::new(),
            };
            let options = SpawnOptions {
                camera: args.shot.camera.clone(),
                animation: args.shot.animation.clone(),
                time,
                framing_times,
                geometry_only: false,
            };
            scene.spawn(r.world_mut(), &options)?;
            r
        }
    };
    args.shot.stage(renderer.world_mut())?;
    if let Some(background) = args.shot.background_radiance() {
        renderer.settings_mut().background = background;
    }
    if let Some(threads) = args.run.threads {
        renderer = renderer.with_threads(threads as usize)?;
    }
    let picture = Picture { look: args.look.look(), alpha: args.shot.transparent() };
    let frames = match args.frames {
        Some(spec) => Some(frame_list(&args, spec, animation_end(renderer.world(), args.fps))?),
        None => None,
    };
    let stats_file = args.stats_json.as_deref().map(OutputFile::create_any).transpose()?;
    renderer.measure_memory(args.stats || stats_file.is_some());
    renderer.time_split(args.stats || stats_file.is_some());
    let start = Instant::now();
    let display =
        args.display_server.as_deref().map(|a| super::tev::DisplayServer::connect(a, &args.out.to_string_lossy()));
    let mut totals =
        Totals { json: stats_file.is_some().then(Vec::new), display: display.transpose()?, ..Default::default() };
    match frames {
        None if args.sample_range.is_some() => {
            render_partial(&args, &mut renderer, spp)?;
        }
        None => {
            renderer.set_time(args.time)?;
            render_image(&mut renderer, spp, args.stats, &mut totals)?;
            write_outputs(OutputFile::create(&args.out)?, renderer.image(), &args.out, &picture, &args)?;
            report(size, &renderer, &totals, start, &args.out.display().to_string());
            if args.target_error.is_some() {
                let (taken, uniform) =
                    renderer.world().resource::<crate::resources::Accumulation>().samples_against_uniform();
                console::note(&format!(
                    "hemi: adaptive sampling took {taken} samples; uniform sampling needs {uniform:.0} for the same RMS error ({:.2}x)",
                    uniform / taken.max(1) as f64
                ));
            }
        }
        Some(list) => {
            for &frame in &list {
                let out = frame_path(&args.out, frame).unwrap_or_else(|| args.out.clone());
                if args.skip_existing && frame_complete(&out, &args, size) {
                    super::console::note(&format!("hemi: frame {frame} exists, skipped: {}", out.display()));
                    continue;
                }
                let file = OutputFile::create(&out)?;
                renderer.set_time((frame as f64 / args.fps) as f32)?;
                render_image(&mut renderer, spp, args.stats, &mut totals)?;
                write_outputs(file, renderer.image(), &out, &picture, &args)?;
                if !args.stats {
                    console::note(&format!("hemi: frame {frame} -> {}", out.display()));
                }
            }
            report(size, &renderer, &totals, start, &format!("{} frames", list.len()));
        }
    }
    if let Some(file) = stats_file {
        file.write_text(&totals.to_json(start.elapsed().as_secs_f64()).to_string())?;
    }
    Ok(())
}

/// Renders this process's part of a still split by sample index (`--sample-range K/N`) and
/// writes it as a partial.
fn render_partial(args: &RenderArgs, renderer: &mut Renderer, spp: u32) -> Result<(), HemiError> {
    let (k, n) = args.sample_range.expect("called with --sample-range");
    let settings = renderer.settings().clone();
    let spf = settings.samples_per_frame;
    let (first, end) = partial::part_range(spp, spf, k, n).ok_or_else(|| {
        HemiError::Usage(format!(
            "--sample-range {k}/{n}: {spp} spp make {} frames of {spf}, fewer than {n} parts (lower --spf)",
            spp.div_ceil(spf)
        ))
    })?;
    let (scene, scene_hash) = match &args.shot.scene {
        Some(path) => (path.display().to_string(), partial::file_hash(path)?),
        None => ("default".to_string(), String::new()),
    };
    let all = RenderSettings { max_spp: None, first_sample: 0, end_sample: None, ..settings.clone() };
    let mut info = partial::PartialInfo {
        hemi_version: env!("CARGO_PKG_VERSION").to_string(),
        scene,
        scene_hash,
        settings: Default::default(),
        width: settings.width,
        height: settings.height,
        spp,
        spf,
        first,
        end,
        frames: vec![],
    };
    let keyed: [(&str, serde_json::Value); 6] = [
        ("seed", settings.seed.into()),
        ("sampler", settings.sampler.name().into()),
        ("time", args.time.into()),
        ("camera", args.shot.camera.clone().into()),
        ("animation", args.shot.animation.clone().into()),
        (partial::ALL_SETTINGS, format!("{all:?}").into()),
    ];
    for (key, value) in keyed {
        info.settings.insert(key.to_string(), value);
    }
    if args.skip_existing
        && let Ok(existing) = Partial::load(&args.out)
        && (partial::PartialInfo { frames: vec![], ..existing.info }) == info
    {
        super::console::note(&format!("hemi: partial exists, skipped: {}", args.out.display()));
        return Ok(());
    }
    let file = OutputFile::create_any(&args.out)?;
    super::console::note(&format!(
        "hemi: samples {first}..{end} of {spp} in frames of {spf} (merged, the same image as one render with --spf {spf})"
    ));
    renderer.set_time(args.time)?;
    let start = Instant::now();
    let part = partial::render(renderer, info, |_| {})?;
    let bytes =
        part.to_exr().map_err(|e| HemiError::Io { path: args.out.clone(), message: format!("cannot encode: {e}") })?;
    file.write_bytes(&bytes)?;
    super::console::note(&format!(
        "hemi: {}x{}, samples {first}..{end} in {} frames, {:.2} s -> {}",
        settings.width,
        settings.height,
        part.frames.len(),
        start.elapsed().as_secs_f64(),
        args.out.display()
    ));
    Ok(())
}

/// Rays and timings summed over a run.
#[derive(Default)]
struct Totals {
    rays: RayCounts,
    trace_secs: f64,
    /// The part of `trace_secs` spent in the ambient occluder (see [`crate::stats::TraceSplit`]).
    ao_secs: f64,
    /// The part of `ao_secs` spent in its rays' scene queries.
    ao_query_secs: f64,
    /// What the BVH queries did (with the feature `counters`).
    traversal: crate::geometry::TraversalCounts,
    frames: u32,
    /// Per-frame JSON records, kept only for `--stats-json`.
    json: Option<Vec<serde_json::Value>>,
    /// Where `--display-server` streams the image.
    display: Option<super::tev::DisplayServer>,
}

impl Totals {
    /// The `--stats-json` document: every frame, then the totals.
    fn to_json(&self, seconds: f64) -> serde_json::Value {
        let per_s = |rays: u64| mrays_per_second(rays, self.trace_secs);
        let ao_per_s = |secs: f64| mrays_per_second(self.rays.ao, secs);
        let mut json = serde_json::json!({
            "frames": self.json.clone().unwrap_or_default(),
            "total": {
                "seconds": seconds,
                "trace_seconds": self.trace_secs,
                "frames": self.frames,
                "rays": { "primary": self.rays.primary, "ao": self.rays.ao, "shadow": self.rays.shadow },
                "mrays_per_s": per_s(self.rays.total()),
                "ao_mrays_per_s": per_s(self.rays.ao),
                "ao_seconds": self.ao_secs,
                "ao_kernel_mrays_per_s": ao_per_s(self.ao_secs),
                "ao_query_seconds": self.ao_query_secs,
                "ao_query_mrays_per_s": ao_per_s(self.ao_query_secs),
            }
        });
        if crate::geometry::TraversalCounts::ENABLED {
            json["total"]["traversal"] = serde_json::json!(self.traversal);
        }
        json
    }
}

/// Runs frames until the current scene state reaches `--spp`.
fn render_image(renderer: &mut Renderer, spp: u32, print_stats: bool, totals: &mut Totals) -> Result<(), HemiError> {
    let progress = ProgressBar::with_draw_target(Some(spp as u64), ProgressDrawTarget::stderr());
    progress.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {wide_bar} {pos}/{len} spp ({eta} left)")
            .expect("valid template"),
    );
    renderer.settings_mut().max_spp = Some(spp);
    let mut first = true;
    while first || !renderer.converged() {
        first = false;
        let stats = renderer.run_frame()?;
        totals.rays.add(&stats.rays);
        totals.trace_secs += stats.time_of("trace").as_secs_f64();
        totals.ao_secs += stats.trace_time_of(crate::light::Term::Ambient).as_secs_f64();
        totals.ao_query_secs += stats.queries_time_of(crate::light::Term::Ambient).as_secs_f64();
        totals.traversal.add(&stats.traversal);
        totals.frames += 1;
        if let Some(records) = &mut totals.json {
            records.push(stats.to_json());
        }
        if print_stats {
            progress.suspend(|| console::out(&stats.table()))?;
        }
        progress.set_position(stats.spp as u64);
        if let Some(display) = &mut totals.display {
            display.update(renderer.image(), renderer.converged());
        }
    }
    progress.finish_and_clear();
    Ok(())
}

/// `<stem>.<name>.exr` beside `out`: where an AOV of that image goes.
fn aov_path(out: &std::path::Path, aov: Aov) -> PathBuf {
    let stem = out.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    out.with_file_name(format!("{stem}.{}.exr", aov.name()))
}

/// Whether `path` names an EXR file.
fn is_exr(path: &std::path::Path) -> bool {
    OutputFormat::from_path(path).is_ok_and(|f| f == OutputFormat::Exr)
}

/// The files the AOVs of image `out` go to, each with the option that names it: one per AOV
/// with --aov-files, else the layered `<stem>.exr` beside a PNG (an EXR holds its own layers).
fn aov_outputs(out: &std::path::Path, args: &RenderArgs) -> Vec<(String, PathBuf)> {
    if args.aov_files {
        args.aov.iter().map(|&aov| (format!("--aov {}", aov.name()), aov_path(out, aov))).collect()
    } else if args.aov.is_empty() || is_exr(out) {
        Vec::new()
    } else {
        vec![("--aov".to_string(), out.with_extension("exr"))]
    }
}

/// Writes image `out` through `file`, and its AOVs: as layers of the EXR itself, of an EXR
/// beside a PNG, or (--aov-files) as files of their own.
fn write_outputs(
    file: OutputFile,
    image: &crate::resources::Image,
    out: &std::path::Path,
    picture: &Picture,
    args: &RenderArgs,
) -> Result<(), HemiError> {
    let layered = !args.aov.is_empty() && !args.aov_files;
    if layered && is_exr(out) {
        return file.write_layered(image, &args.aov);
    }
    file.write_picture(image, picture)?;
    if args.aov_files {
        return write_aovs(image, out, &args.aov);
    }
    for (_, path) in aov_outputs(out, args) {
        OutputFile::create(&path)?.write_layered(image, &args.aov)?;
    }
    Ok(())
}

/// Writes the requested AOVs of `image` beside `out`, a file each.
fn write_aovs(image: &crate::resources::Image, out: &std::path::Path, aovs: &[Aov]) -> Result<(), HemiError> {
    for &aov in aovs {
        let pixels = image.aov(aov).unwrap_or_default();
        let layer =
            crate::resources::Image { width: image.width, height: image.height, linear: pixels, ..Default::default() };
        OutputFile::create(&aov_path(out, aov))?.write(&layer)?;
    }
    Ok(())
}

fn report(size: (u32, u32), renderer: &Renderer, totals: &Totals, start: Instant, what: &str) {
    console::note(&format!(
        "hemi: {}x{} at {} spp in {:.2} s ({} frames, {:.1} M rays, {:.2} Mrays/s while tracing) -> {}",
        size.0,
        size.1,
        renderer.spp(),
        start.elapsed().as_secs_f64(),
        totals.frames,
        totals.rays.total() as f64 / 1e6,
        if totals.trace_secs > 0.0 { totals.rays.total() as f64 / totals.trace_secs / 1e6 } else { 0.0 },
        what
    ));
    if crate::geometry::TraversalCounts::ENABLED {
        console::note(&format!("hemi: {}", crate::stats::traversal_line(&totals.traversal, totals.rays.total())));
    }
}

#[cfg(test)]
mod tests {
    use super::frame_times;

    #[test]
    fn framing_samples_the_first_and_last_frame_and_evenly_between() {
        assert_eq!(frame_times(0, 4, 2.0, 256), [0.0, 0.5, 1.0, 1.5]);
        assert_eq!(frame_times(5, 6, 24.0, 256), [5.0 / 24.0]);
        // 1000 frames from 10, three samples: frames 10, 10 + 999/2 and 1009.
        let expected = [10.0f64, 509.0, 1009.0].map(|f| (f / 24.0) as f32);
        assert_eq!(frame_times(10, 1010, 24.0, 3), expected);
    }
}
