//! The library entry point: a bevy_ecs world holding the scene, and the frame schedule.

use std::path::Path;

use bevy_ecs::prelude::*;

use crate::{
    components::{AmbientOccluder, DirectionalLight, DiskLight, PointLight, SpotLight},
    error::HemiError,
    film,
    geometry::SceneGeometry,
    integrator::register_light,
    light::Light,
    resources::{Accumulation, FrameSamples, Image, RenderSettings, SceneProblems, ShapeValueChanges, Time},
    sampling::{SampleSets, SamplerKind},
    scene::{DEFAULT_BACKGROUND, spawn_default_scene},
    stats::{FrameStats, take_peak_rss},
    systems::frame_schedule,
};

/// A world plus the schedule that renders it, one frame per [`Renderer::run_frame`].
///
/// ```
/// use hemi::prelude::*;
/// let mut r = Renderer::new(RenderSettings { width: 32, height: 24, ..Default::default() });
/// r.world_mut().spawn(Camera::look_at(Vec3::new(0.0, 1.0, 4.0), Vec3::ZERO, 40.0));
/// r.world_mut().spawn(AmbientOccluder::default());
/// r.world_mut().spawn((Sphere { radius: 1.0 }, Transform::from_xyz(0.0, 1.0, 0.0)));
/// r.world_mut().spawn(Plane::default());
/// r.run_frame().unwrap();
/// assert_eq!(r.image().linear.len(), 32 * 24);
/// ```
pub struct Renderer {
    world: World,
    schedule: Schedule,
    pool: Option<rayon::ThreadPool>,
    frames: u64,
    measure_memory: bool,
    time_split: bool,
}

impl Renderer {
    /// An empty scene with these settings, traced on rayon's global thread pool.
    pub fn new(settings: RenderSettings) -> Self {
        let mut world = World::new();
        // The smallest sets: the first frame's sample-set system makes the ones the settings
        // call for (unless these are), so that their cost shows in that frame and its stats.
        world.insert_resource(SampleSets::generate(SamplerKind::Regular, 1, settings.seed, 1, 1));
        world.insert_resource(settings);
        world.init_resource::<SceneGeometry>();
        world.init_resource::<Accumulation>();
        world.init_resource::<FrameSamples>();
        world.init_resource::<Image>();
        world.init_resource::<SceneProblems>();
        world.init_resource::<ShapeValueChanges>();
        world.init_resource::<FrameStats>();
        let mut r = Renderer {
            world,
            schedule: frame_schedule(),
            pool: None,
            frames: 0,
            measure_memory: false,
            time_split: false,
        };
        r.add_light::<AmbientOccluder>()
            .add_light::<PointLight>()
            .add_light::<DirectionalLight>()
            .add_light::<SpotLight>()
            .add_light::<DiskLight>();
        r
    }

    /// Registers a light component type: from the next frame on, its entities are validated,
    /// placed and traced, and adding, changing or removing one restarts accumulation.
    /// Registering a type twice does nothing. Lights take their sample dimensions in
    /// registration order, so register in the same order for the same image.
    pub fn add_light<L: Light>(&mut self) -> &mut Self {
        register_light::<L>(&mut self.world, &mut self.schedule);
        self
    }

    /// The built-in default scene with these settings (its sky replaces the background).
    pub fn with_default_scene(settings: RenderSettings) -> Self {
        let mut r = Renderer::new(RenderSettings { background: DEFAULT_BACKGROUND, ..settings });
        spawn_default_scene(r.world_mut());
        r
    }

    /// Traces on a dedicated pool of `threads` threads instead of rayon's global pool.
    pub fn with_threads(mut self, threads: usize) -> Result<Self, HemiError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .map_err(|e| HemiError::Usage(format!("cannot start {threads} threads: {e}")))?;
        self.pool = Some(pool);
        Ok(self)
    }

    /// The world: spawn, change and despawn entities here between frames.
    pub fn world(&self) -> &World {
        &self.world
    }

    /// Mutable access to the world.
    pub fn world_mut(&mut self) -> &mut World {
        &mut self.world
    }

    /// The frame schedule, to add systems of your own (e.g. animation before
    /// [`crate::frame::FrameStage::SceneChanges`]).
    pub fn schedule_mut(&mut self) -> &mut Schedule {
        &mut self.schedule
    }

    /// The render settings, for reading.
    pub fn settings(&self) -> &RenderSettings {
        self.world.resource::<RenderSettings>()
    }

    /// The render settings, for changing (any change restarts accumulation).
    pub fn settings_mut(&mut self) -> Mut<'_, RenderSettings> {
        self.world.resource_mut::<RenderSettings>()
    }

    /// Sets the scene time in seconds (the animation systems pose the scene for it on the next
    /// frame); setting the same time again changes nothing. A time that is not finite (an
    /// overflowing frame / fps, say) is refused.
    pub fn set_time(&mut self, seconds: f32) -> Result<(), HemiError> {
        if !seconds.is_finite() {
            return Err(HemiError::Usage(format!("scene time {seconds} s is not a finite number")));
        }
        match self.world.get_resource_mut::<Time>() {
            Some(mut time) => {
                time.set_if_neq(Time { seconds });
            }
            None => self.world.insert_resource(Time { seconds }),
        }
        Ok(())
    }

    /// Poses the scene at `seconds` and runs frames until every pixel has `spp` samples: one
    /// frame of an animation, as `hemi render --frames` makes it. The image depends only on the
    /// scene at that time, never on the frames rendered before. A time that is not finite is
    /// refused; otherwise it fails as [`Renderer::render`] does.
    pub fn render_at(&mut self, seconds: f32, spp: u32) -> Result<u32, HemiError> {
        self.set_time(seconds)?;
        self.render(spp)
    }

    /// Whether frames measure the process's peak resident set size before them and in each
    /// system ([`FrameStats::peak_rss_before`], [`crate::stats::SystemTime::peak_rss`]): off
    /// by default, as it reads `/proc` twice per system.
    pub fn measure_memory(&mut self, on: bool) {
        self.measure_memory = on;
    }

    /// Whether frames split the trace system's time by stage ([`FrameStats::trace_split`]: the
    /// lights' and their scene queries' share): off by default, as its fenced readings of the
    /// cycle counter cost frames of a few samples a pixel a few percent of their time.
    pub fn time_split(&mut self, on: bool) {
        self.time_split = on;
    }

    /// Runs one frame: BVH upkeep, sample sets, tracing, accumulation, resolve.
    /// Fails, without tracing, while the scene holds something that cannot be rendered.
    pub fn run_frame(&mut self) -> Result<&FrameStats, HemiError> {
        let (measure_memory, peak_rss_before) =
            (self.measure_memory, self.measure_memory.then(take_peak_rss).flatten());
        *self.world.resource_mut::<FrameStats>() = FrameStats {
            frame: self.frames,
            measure_memory,
            time_split: self.time_split,
            peak_rss_before,
            ..Default::default()
        };
        match &self.pool {
            Some(pool) => pool.install(|| self.schedule.run(&mut self.world)),
            None => self.schedule.run(&mut self.world),
        }
        self.world.clear_trackers();
        self.frames += 1;
        let buffer_bytes = self.buffer_bytes();
        self.world.resource_mut::<FrameStats>().buffer_bytes = buffer_bytes;
        if let Some(problem) = self.world.resource::<SceneProblems>().first() {
            return Err(HemiError::InvalidScene(problem.clone()));
        }
        Ok(self.world.resource::<FrameStats>())
    }

    fn buffer_bytes(&self) -> usize {
        let frame = self.world.resource::<FrameSamples>();
        self.world.resource::<Accumulation>().buffer_bytes()
            + size_of_val(&frame.sums[..])
            + self.world.resource::<Image>().buffer_bytes()
            + self.world.resource::<SampleSets>().memory_bytes()
    }

    /// Frames in a row that may each restart accumulation before [`Renderer::render`] gives
    /// up: the first frame of a render restarts after any change made before it, and a system
    /// that settles the scene over a few frames still converges, while one that changes
    /// something every frame fails within a few frames' work instead of looping forever.
    pub const MAX_CONSECUTIVE_RESETS: u32 = 8;

    /// Runs frames until every pixel has `spp` samples (sets `max_spp`); returns frames run.
    ///
    /// Continues the accumulation there is: `render(16)` then `render(64)` traces 48 more
    /// samples per pixel, and, sample indices being global, gives the image a fresh
    /// `render(64)` gives when both run the same frames (`samples_per_frame` dividing 16).
    /// A lower `spp` than accumulated starts over, so that the image is the one a fresh
    /// render to `spp` gives.
    ///
    /// Fails with [`HemiError::KeepsChanging`], naming the component and entity, when
    /// [`Renderer::MAX_CONSECUTIVE_RESETS`] frames in a row restarted accumulation before it
    /// reached `spp` (writing a component's same value again is no change).
    pub fn render(&mut self, spp: u32) -> Result<u32, HemiError> {
        if self.settings().max_spp != Some(spp) {
            self.settings_mut().max_spp = Some(spp);
        }
        let (mut frames, mut resets_in_a_row) = (0, 0);
        while !self.converged() || frames == 0 {
            self.run_frame()?;
            frames += 1;
            let Some(what) = &self.stats().reset else {
                resets_in_a_row = 0;
                continue;
            };
            resets_in_a_row += 1;
            if resets_in_a_row >= Self::MAX_CONSECUTIVE_RESETS && !self.converged() {
                return Err(HemiError::KeepsChanging { frames: resets_in_a_row, what: what.clone() });
            }
        }
        Ok(frames)
    }

    /// Whether tracing has stopped: the accumulation reached `max_spp` (or, for a part of a
    /// render, its sample range: [`RenderSettings::target_spp`]), or, with a
    /// `target_error`, the last frame found every pixel done (never true without a target).
    pub fn converged(&self) -> bool {
        let acc = self.world.resource::<Accumulation>();
        let settings = self.settings();
        let spp_done = settings.target_spp().is_some_and(|target| acc.spp >= target);
        let error_done =
            settings.target_error.is_some() && acc.spp > 0 && self.world.resource::<FrameSamples>().active_pixels == 0;
        spp_done || error_done
    }

    /// Samples per pixel accumulated so far.
    pub fn spp(&self) -> u32 {
        self.world.resource::<Accumulation>().spp
    }

    /// The resolved image of the last frame.
    pub fn image(&self) -> &Image {
        self.world.resource::<Image>()
    }

    /// Statistics of the last frame.
    pub fn stats(&self) -> &FrameStats {
        self.world.resource::<FrameStats>()
    }

    /// Saves the image as PNG (sRGB 8-bit) or EXR (linear f32), by extension.
    pub fn save(&self, path: &Path) -> Result<(), HemiError> {
        film::save(self.image(), path)
    }
}
