//! A live view of a [`Renderer`]'s world: the logic behind `hemi view`, free of any window.
//!
//! [`Viewer`] is a thin layer over the same renderer and frame schedule `hemi render` uses.
//! Input becomes the [`Input`] resource; the [`control_camera`] system (in
//! [`FrameStage::Animate`]) moves the camera component, and the schedule's own change
//! detection restarts accumulation. Between frames the viewer only picks the frame's internal
//! resolution and samples per pixel ([`FrameBudget`]), advances the scene time while the
//! animation plays, and turns the resolved image into the displayed framebuffer
//! ([`display`]). A window shell (the `view` feature) feeds it events and presents the
//! framebuffer; tests drive it with synthetic events.
//!
//! A still view renders at full resolution with the sample sets `hemi render --spp N` uses,
//! so it converges to that image: with `spf` fixed to k, to `hemi render --spp N --spf k`
//! byte for byte (frames only split a pixel's samples into sums differently, so other frame
//! sizes agree up to the rounding of those sums).

pub mod budget;
#[cfg(feature = "view")]
pub mod command;
pub mod controller;
pub mod display;
pub mod input;
#[cfg(feature = "view")]
pub mod window;

use std::{
    path::{Path, PathBuf},
    time::{Duration, Instant},
};

use bevy_ecs::prelude::*;

pub use budget::{FrameBudget, FramePlan};
pub use controller::{CameraController, CameraPose, control_camera};
pub use display::{Buffer, Display};
pub use input::{Button, Input, InputEvent, Key};

use crate::{
    Renderer,
    animation::NodeGraph,
    cli::peer_scene::PeerScene,
    error::HemiError,
    film::OutputFile,
    frame::FrameStage,
    resources::{Accumulation, Image, RenderSettings},
    sampling::SampleSets,
    scene::gltf::{GltfScene, SpawnOptions},
};

/// Seconds one press of ← or → moves the animation.
pub const STEP_SECONDS: f64 = 1.0 / 30.0;
/// Stops one press of `[` or `]` changes the exposure by.
pub const EXPOSURE_STEP: f32 = 0.5;
/// Longest wall-clock step (seconds) one frame of flying stands for.
pub const MAX_FLY_STEP: f32 = 0.1;
/// Sample sets kept for the internal resolutions used lately.
const CACHED_SETS: usize = 4;

/// How a [`Viewer`] renders.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewerOptions {
    /// Full resolution (the window's size).
    pub size: (u32, u32),
    /// Samples per pixel a still view converges to.
    pub spp: u32,
    /// Samples per frame of a still view (`None`: as many as fit the frame budget).
    pub spf: Option<u32>,
    /// Target frame time.
    pub target: Duration,
    /// Lower the internal resolution while the view moves.
    pub dynamic_resolution: bool,
    /// Orbit once around the target in this many seconds.
    pub turntable: Option<f64>,
    /// Show the overlay from the start.
    pub overlay: bool,
    /// Start playing the animation.
    pub play: bool,
    /// Where P saves: `<stem>-NNN.png` (the display) and `<stem>-NNN.exr` (the linear image).
    pub save_stem: PathBuf,
}

impl Default for ViewerOptions {
    fn default() -> Self {
        ViewerOptions {
            size: (640, 360),
            spp: 1024,
            spf: None,
            target: Duration::from_millis(33),
            dynamic_resolution: true,
            turntable: None,
            overlay: false,
            play: false,
            save_stem: PathBuf::from("hemi-view"),
        }
    }
}

/// What one frame did.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FrameRecord {
    /// Frame number (0 first).
    pub frame: u64,
    /// Viewer clock (sum of the frames' wall-clock steps) in seconds.
    pub seconds: f64,
    /// Wall-clock step this frame stood for (time since the previous one), milliseconds.
    pub dt_ms: f64,
    /// Time [`Viewer::frame`] took: the frame's systems plus the display, milliseconds.
    pub frame_ms: f64,
    /// Of which the trace system, milliseconds.
    pub trace_ms: f64,
    /// Frames per second, smoothed over the last frames' steps.
    pub fps: f64,
    /// Samples per pixel accumulated after the frame.
    pub spp: u32,
    /// Samples per pixel the frame traced.
    pub spf: u32,
    /// Internal resolution.
    pub width: u32,
    /// Internal resolution.
    pub height: u32,
    /// Resolution divisor (1: full).
    pub scale: u32,
    /// Whether the frame was planned as a moving one.
    pub moving: bool,
    /// Whether the accumulation restarted this frame.
    pub reset: bool,
    /// Scene time in seconds.
    pub time: f64,
    /// From the oldest input event this frame took in to the frame on screen, milliseconds
    /// (filled in by the window shell).
    pub latency_ms: Option<f64>,
}

/// A live view: renderer, camera controller, frame budget and display.
pub struct Viewer {
    renderer: Renderer,
    name: String,
    options: ViewerOptions,
    budget: FrameBudget,
    display: Display,
    framebuffer: Vec<u32>,
    /// The last frame's image encoded at its own resolution (scratch).
    encoded: Vec<u32>,
    playing: bool,
    time: f64,
    clock: f64,
    fps: f64,
    sets: Vec<SampleSets>,
    records: Vec<FrameRecord>,
    saves: u32,
    save_requested: bool,
    messages: Vec<String>,
    redisplay: bool,
}

impl Viewer {
    /// A viewer of `renderer`'s world, `name` being the scene's (title and overlay). Sets the
    /// renderer's size, `max_spp` and set size as `hemi render --spp` does; seed and sampler
    /// stay the renderer's.
    pub fn new(mut renderer: Renderer, name: impl Into<String>, options: ViewerOptions) -> Result<Self, HemiError> {
        {
            let mut s = renderer.settings_mut();
            s.width = options.size.0;
            s.height = options.size.1;
            s.max_spp = Some(options.spp);
            s.samples_per_set = options.spp.min(RenderSettings::ONE_FRAME_SPP);
            s.samples_per_frame = 1;
            s.validate().map_err(HemiError::Usage)?;
        }
        if options.spp == 0 || options.spf == Some(0) {
            return Err(HemiError::Usage("--spp and --spf must be at least 1".into()));
        }
        let world = renderer.world_mut();
        let mut input = Input::default();
        input.viewport_height = options.size.1 as f32;
        world.insert_resource(input);
        world.init_resource::<CameraController>();
        renderer
            .schedule_mut()
            .add_systems(control_camera.in_set(FrameStage::Animate).after(crate::systems::animation::animate));
        let playing = options.play;
        let display = Display { overlay: options.overlay, ..Default::default() };
        let mut v = Viewer {
            renderer,
            name: name.into(),
            budget: FrameBudget::new(options.target),
            options,
            display,
            framebuffer: Vec::new(),
            encoded: Vec::new(),
            playing: false,
            time: 0.0,
            clock: 0.0,
            fps: 0.0,
            sets: Vec::new(),
            records: Vec::new(),
            saves: 0,
            save_requested: false,
            messages: Vec::new(),
            redisplay: true,
        };
        v.time = v.renderer.world().get_resource::<crate::resources::Time>().map_or(0.0, |t| t.seconds as f64);
        v.playing = playing && v.animation_duration().is_some();
        Ok(v)
    }

    /// The renderer.
    pub fn renderer(&self) -> &Renderer {
        &self.renderer
    }

    /// The renderer, to change the world between frames.
    pub fn renderer_mut(&mut self) -> &mut Renderer {
        &mut self.renderer
    }

    /// The scene's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// The options.
    pub fn options(&self) -> &ViewerOptions {
        &self.options
    }

    /// How the image is shown.
    pub fn display(&self) -> &Display {
        &self.display
    }

    /// The frame budget's cost model.
    pub fn budget(&self) -> &FrameBudget {
        &self.budget
    }

    /// Whether the animation is playing.
    pub fn playing(&self) -> bool {
        self.playing
    }

    /// Scene time in seconds.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Length of the longest playing animation clip, if the scene has one.
    pub fn animation_duration(&self) -> Option<f32> {
        let graph = self.renderer.world().get_resource::<NodeGraph>()?;
        graph.playing().map(|c| c.duration).filter(|d| *d > 0.0).reduce(f32::max)
    }

    /// The frames so far.
    pub fn records(&self) -> &[FrameRecord] {
        &self.records
    }

    /// Sets the latency of the last frame (measured by the window shell).
    pub fn set_latency(&mut self, ms: f64) {
        if let Some(r) = self.records.last_mut() {
            r.latency_ms = Some(ms);
        }
    }

    /// Notes for the user since the last call (saved files, failed saves).
    pub fn take_messages(&mut self) -> Vec<String> {
        std::mem::take(&mut self.messages)
    }

    /// Takes in one input event: display, animation and save keys act at once; the rest is
    /// left in the [`Input`] resource for the next frame's camera controller.
    pub fn handle(&mut self, event: InputEvent) {
        if let InputEvent::KeyDown(key) = event {
            match key {
                Key::Digit(d) => {
                    if let Some(b) = Buffer::from_digit(d) {
                        self.set_buffer(b);
                    }
                }
                Key::BracketLeft => self.set_exposure(self.display.exposure - EXPOSURE_STEP),
                Key::BracketRight => self.set_exposure(self.display.exposure + EXPOSURE_STEP),
                Key::H => {
                    self.display.overlay = !self.display.overlay;
                    self.redisplay = true;
                }
                Key::P => self.save_requested = true,
                Key::Space => self.playing = !self.playing && self.animation_duration().is_some(),
                Key::Left | Key::Right if self.animation_duration().is_some() => {
                    self.playing = false;
                    let step = if key == Key::Left { -STEP_SECONDS } else { STEP_SECONDS };
                    self.time = (self.time + step).max(0.0);
                }
                _ => {}
            }
        }
        self.renderer.world_mut().resource_mut::<Input>().apply(event);
    }

    /// Shows `buffer`; AOVs are accumulated only while one is shown (turning them on or off
    /// restarts accumulation).
    pub fn set_buffer(&mut self, buffer: Buffer) {
        self.display.buffer = buffer;
        let aovs = buffer != Buffer::Beauty;
        if self.renderer.settings().aovs != aovs {
            self.renderer.settings_mut().aovs = aovs;
        }
        self.redisplay = true;
    }

    /// Sets the exposure in stops.
    pub fn set_exposure(&mut self, stops: f32) {
        self.display.exposure = stops.clamp(-16.0, 16.0);
        self.redisplay = true;
    }

    /// Sets the tone curve of the beauty image.
    pub fn set_tonemap(&mut self, tonemap: crate::look::Tonemap) {
        self.display.tonemap = tonemap;
        self.redisplay = true;
    }

    /// Changes the full resolution (the window was resized).
    pub fn resize(&mut self, width: u32, height: u32) {
        self.options.size = (width.max(1), height.max(1));
        self.renderer.world_mut().resource_mut::<Input>().viewport_height = height.max(1) as f32;
        self.redisplay = true;
    }

    /// Whether another frame would change what is shown: the image is still converging, the
    /// animation plays, the turntable turns, or input or a display change is waiting.
    pub fn needs_frame(&self) -> bool {
        let input = self.renderer.world().resource::<Input>();
        self.redisplay
            || self.save_requested
            || self.playing
            || self.options.turntable.is_some()
            || input.moves_camera()
            || !self.renderer.converged()
            || self.renderer.settings().width != self.options.size.0
            || self.renderer.settings().height != self.options.size.1
    }

    /// Renders one frame standing for `dt` of wall-clock time (the time since the previous
    /// frame: it advances a playing animation and the turntable), then updates the framebuffer.
    pub fn frame(&mut self, dt: Duration) -> Result<&FrameRecord, HemiError> {
        let start = Instant::now();
        let dt_s = dt.as_secs_f64();
        self.clock += dt_s;
        if self.playing {
            self.time += dt_s;
        }
        if self.animation_duration().is_some() {
            self.renderer.set_time(self.time as f32)?;
        }
        let turn = self.options.turntable.map_or(0.0, |t| (std::f64::consts::TAU * dt_s / t.max(1e-3)) as f32);
        let moving = {
            let mut input = self.renderer.world_mut().resource_mut::<Input>();
            input.turntable += turn;
            // Flying moves by the frame's time, but never by the idle time before a first
            // key press (the window waits for events once the view has converged).
            input.dt = (dt_s as f32).min(MAX_FLY_STEP);
            input.moves_camera()
        } || self.playing;

        let remaining = self.options.spp.saturating_sub(self.renderer.spp());
        let plan =
            self.budget.plan(self.options.size, moving, self.options.dynamic_resolution, remaining, self.options.spf);
        self.apply_plan(plan);
        let resets = self.renderer.world().resource::<Accumulation>().resets;
        let result = self.renderer.run_frame().map(|s| (s.time_of("trace"), s.samples_traced));
        self.renderer.world_mut().resource_mut::<Input>().end_frame();
        let (trace, traced) = result?;
        let reset = self.renderer.world().resource::<Accumulation>().resets != resets;

        self.update_framebuffer();
        if self.save_requested {
            self.save_requested = false;
            self.saves += 1;
            let stem = self.options.save_stem.display().to_string();
            let (png, exr) = (
                PathBuf::from(format!("{stem}-{:03}.png", self.saves)),
                PathBuf::from(format!("{stem}-{:03}.exr", self.saves)),
            );
            match self.save_view(&png, &exr) {
                Ok(()) => self.messages.push(format!("saved {} and {}", png.display(), exr.display())),
                Err(e) => self.messages.push(format!("cannot save the view: {e}")),
            }
        }
        let elapsed = start.elapsed();
        self.budget.observe(plan.width as usize * plan.height as usize, traced, trace, elapsed);
        if dt_s > 0.0 {
            let fps = 1.0 / dt_s;
            self.fps = if self.fps == 0.0 { fps } else { self.fps + 0.2 * (fps - self.fps) };
        }
        self.records.push(FrameRecord {
            frame: self.records.len() as u64,
            seconds: self.clock,
            dt_ms: dt_s * 1e3,
            frame_ms: elapsed.as_secs_f64() * 1e3,
            trace_ms: trace.as_secs_f64() * 1e3,
            fps: self.fps,
            spp: self.renderer.spp(),
            spf: traced,
            width: plan.width,
            height: plan.height,
            scale: plan.scale,
            moving,
            reset,
            time: self.time,
            latency_ms: None,
        });
        Ok(self.records.last().expect("a record was just pushed"))
    }

    /// Sets the frame's internal size (a change restarts accumulation) and samples per frame
    /// (never restarts it: samples are numbered per pixel, so frames of any size continue the
    /// same sequence), and brings back cached sample sets for that size.
    fn apply_plan(&mut self, plan: FramePlan) {
        let s = self.renderer.settings();
        if (s.width, s.height) != (plan.width, plan.height) {
            let mut s = self.renderer.settings_mut();
            s.width = plan.width;
            s.height = plan.height;
        }
        let world = self.renderer.world_mut();
        world.resource_mut::<RenderSettings>().bypass_change_detection().samples_per_frame = plan.spf;
        let s = world.resource::<RenderSettings>().clone();
        let runs = s.sample_runs();
        let matches = |sets: &SampleSets| sets.matches(s.sampler, s.samples_per_set, s.seed, (s.width, s.height), runs);
        if matches(world.resource::<SampleSets>()) {
            return;
        }
        // Keep the current sets for when the view comes back to their size; take cached ones
        // for this size, or leave a placeholder for the sample-set system to replace.
        let cached = self.sets.iter().position(matches).map(|i| self.sets.remove(i));
        let fresh = cached.unwrap_or_else(|| SampleSets::generate(crate::sampling::SamplerKind::Regular, 1, 0, 1, 1));
        if let Some(old) = world.remove_resource::<SampleSets>() {
            if !old.matches(
                crate::sampling::SamplerKind::Regular,
                1,
                0,
                (1, 1),
                crate::sampling::SampleRuns::WholePasses,
            ) {
                self.sets.push(old);
            }
            if self.sets.len() > CACHED_SETS {
                self.sets.remove(0);
            }
        }
        world.insert_resource(fresh);
        // The sample-set system runs when the settings changed; make sure it does.
        world.resource_mut::<RenderSettings>().set_changed();
    }

    /// Re-encodes the displayed buffer into the framebuffer (full resolution, overlay drawn).
    fn update_framebuffer(&mut self) {
        let image = self.renderer.image();
        let (w, h) = self.options.size;
        self.encoded = display::encode(image, &self.display);
        display::upscale(&self.encoded, image.width, image.height, w, h, &mut self.framebuffer);
        if self.display.overlay {
            let lines = self.overlay_lines();
            display::draw_overlay(&mut self.framebuffer, w, &lines);
        }
        self.redisplay = false;
    }

    /// The overlay's text: fps, spp, resolution, per-system milliseconds.
    pub fn overlay_lines(&self) -> Vec<String> {
        let r = &self.renderer;
        let image = r.image();
        let last = self.records.last();
        let mut lines = vec![
            format!("{}  [{}]  ev {:+.1}", self.name, self.display.buffer.name(), self.display.exposure),
            format!(
                "{:.1} fps  {:.1} ms  spp {}/{}{}",
                self.fps,
                last.map_or(0.0, |l| l.frame_ms),
                r.spp(),
                self.options.spp,
                if r.converged() { " (done)" } else { "" }
            ),
            format!(
                "res {}x{} (1/{})  spf {}",
                image.width,
                image.height,
                last.map_or(1, |l| l.scale),
                last.map_or(0, |l| l.spf)
            ),
        ];
        if let Some(d) = self.animation_duration() {
            let state = if self.playing { "playing" } else { "paused" };
            lines.push(format!("t {:.2}/{d:.2} s {state}", self.time));
        }
        for s in &r.stats().systems {
            lines.push(format!("{:<14}{:>8.2} ms", s.name, s.time.as_secs_f64() * 1e3));
        }
        lines
    }

    /// The window title: scene name and samples per pixel.
    pub fn title(&self) -> String {
        format!("hemi view: {} ({}/{} spp)", self.name, self.renderer.spp(), self.options.spp)
    }

    /// What the window shows, `0x00RRGGBB` pixels, row-major, at the full resolution.
    pub fn framebuffer(&self) -> &[u32] {
        &self.framebuffer
    }

    /// The framebuffer as an RGB image.
    pub fn screenshot(&self) -> image::RgbImage {
        let (w, h) = self.options.size;
        let mut bytes = Vec::with_capacity(self.framebuffer.len() * 3);
        for &p in &self.framebuffer {
            bytes.extend_from_slice(&display::unpack(p));
        }
        bytes.resize(w as usize * h as usize * 3, 0);
        image::RgbImage::from_raw(w, h, bytes).expect("the buffer has w·h·3 bytes")
    }

    /// Writes the display as PNG at `png` and the linear image (internal resolution) as EXR
    /// at `exr`.
    pub fn save_view(&self, png: &Path, exr: &Path) -> Result<(), HemiError> {
        OutputFile::create(png)?.write_rgb8(&self.screenshot())?;
        let image = self.renderer.image();
        let linear =
            Image { width: image.width, height: image.height, linear: image.linear.clone(), ..Default::default() };
        OutputFile::create(exr)?.write(&linear)
    }

    /// Every frame's record and a summary, as `--stats-json` writes them.
    pub fn stats_json(&self) -> serde_json::Value {
        let n = self.records.len().max(1) as f64;
        let skip = self.records.iter().skip(1);
        let mean_dt = skip.clone().map(|r| r.dt_ms).sum::<f64>() / (n - 1.0).max(1.0);
        let latencies: Vec<f64> = self.records.iter().filter_map(|r| r.latency_ms).collect();
        serde_json::json!({
            "scene": self.name,
            "size": [self.options.size.0, self.options.size.1],
            "target_ms": self.options.target.as_secs_f64() * 1e3,
            "frames": self.records,
            "summary": {
                "frames": self.records.len(),
                "mean_fps": if mean_dt > 0.0 { 1e3 / mean_dt } else { 0.0 },
                "mean_frame_ms": self.records.iter().map(|r| r.frame_ms).sum::<f64>() / n,
                "full_resolution_frames": self.records.iter().filter(|r| r.scale == 1).count(),
                "final_spp": self.renderer.spp(),
                "mean_latency_ms": if latencies.is_empty() { None } else { Some(latencies.iter().sum::<f64>() / latencies.len() as f64) },
                "max_latency_ms": latencies.iter().copied().fold(None, |m: Option<f64>, l| Some(m.map_or(l, |m| m.max(l)))),
            }
        })
    }
}

/// A scene to view, opened as `hemi render` opens it (the same checks and messages).
pub enum SceneSource {
    /// The built-in scene.
    Builtin,
    /// A peer scene `.json`.
    Peer(Box<PeerScene>),
    /// A glTF scene with the camera and animation to use.
    Gltf {
        /// The loaded file.
        scene: Box<GltfScene>,
        /// `--camera`.
        camera: Option<String>,
        /// `--animation`.
        animation: Option<String>,
    },
}

impl SceneSource {
    /// Opens `path` (none: the built-in scene). Warnings go to `warn`.
    pub fn open(
        path: Option<&Path>,
        camera: Option<String>,
        animation: Option<String>,
        mut warn: impl FnMut(String),
    ) -> Result<Self, HemiError> {
        match path {
            None if camera.is_some() || animation.is_some() => {
                Err(HemiError::Usage("--camera and --animation need a glTF scene".into()))
            }
            None => Ok(SceneSource::Builtin),
            Some(p) if p.extension().is_some_and(|e| e.eq_ignore_ascii_case("json")) => {
                if camera.is_some() || animation.is_some() {
                    return Err(HemiError::Usage("--camera, --animation and --frames need a glTF scene".into()));
                }
                Ok(SceneSource::Peer(Box::new(PeerScene::load(p)?)))
            }
            Some(p) => {
                let scene = crate::scene::gltf::load(p)?;
                for w in &scene.warnings {
                    warn(format!("{}: {w}", p.display()));
                }
                Ok(SceneSource::Gltf { scene: Box::new(scene), camera, animation })
            }
        }
    }

    /// The scene's name (its file stem, or `built-in`).
    pub fn name(&self) -> String {
        let stem = |p: &Path| p.file_stem().map_or_else(|| p.display().to_string(), |s| s.to_string_lossy().into());
        match self {
            SceneSource::Builtin => "built-in".into(),
            SceneSource::Peer(p) => p.name.clone(),
            SceneSource::Gltf { scene, .. } => stem(&scene.path),
        }
    }

    /// Image size, spp and seed the scene asks for (a peer scene's own), else `hemi render`'s
    /// defaults.
    pub fn defaults(&self) -> ((u32, u32), Option<u32>, u64) {
        match self {
            SceneSource::Peer(p) => ((p.width, p.height), Some(p.samples), p.seed),
            _ => ((640, 360), None, 0),
        }
    }

    /// A renderer holding the scene, with `settings` (peer scenes trace pixel centres, as
    /// `hemi render` does for them).
    pub fn renderer(&self, settings: RenderSettings, mut warn: impl FnMut(String)) -> Result<Renderer, HemiError> {
        Ok(match self {
            SceneSource::Builtin => Renderer::with_default_scene(settings),
            SceneSource::Peer(p) => {
                let mut r = Renderer::new(RenderSettings { jitter: false, ..settings });
                for w in p.spawn(r.world_mut())? {
                    warn(w);
                }
                r
            }
            SceneSource::Gltf { scene, camera, animation } => {
                let mut r = Renderer::new(settings);
                let options = SpawnOptions {
                    camera: camera.clone(),
                    animation: animation.clone(),
                    time: 0.0,
                    framing_times: Vec::new(),
                    geometry_only: false,
                };
                scene.spawn(r.world_mut(), &options)?;
                r
            }
        })
    }
}
