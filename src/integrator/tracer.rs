//! The per-sample tracer: a primary ray, then every registered light group at the hit, with
//! per-thread scratch space and ray counts.

use glam::{Vec2, Vec3, Vec3A};

use super::{
    direction_rays::{CosinePoint, DirectionRays},
    light_groups::{LightGroup, RunSum},
    sample::{OwnSample, PrimaryHit, SampleOut, SampleResult, ShadedSum, TwoValues},
};
use crate::{
    components::Matte,
    geometry::{Ray, RayEnd, RayOrder, SceneGeometry, SpawnOrigins, SurfaceHit},
    light::{DirectionRun, LightSample, LightSamples, PlacedLight, ShadingPoint, Shadow, Term, point::PointSource},
    sampling::{SampleSets, dims},
    stats::{RayCounts, TraceSplit, cycle_count, cycles_since},
};

/// Everything a sample needs to read, shared by all threads.
pub struct Scene<'a> {
    /// Geometry and materials.
    pub geometry: &'a SceneGeometry,
    /// Light groups with their first sample dimension, in registration order.
    pub lights: &'a [(u32, &'a dyn LightGroup)],
    /// Sample sets.
    pub sets: &'a SampleSets,
    /// Radiance of escaped primary rays.
    pub background: Vec3,
    /// Least distance along the normal at which shadow and AO rays start from a hit
    /// ([`crate::resources::RenderSettings::ray_offset`]).
    pub ray_offset: f32,
}

impl Scene<'_> {
    /// Camera hit `hit` ready to be lit: its shading point (material from the scene, frame
    /// turned or mirrored by `symmetry`, its pixel's [`SampleSets::frame_symmetry`]) and where
    /// its shadow rays start, [`Scene::ray_offset`] or more off the surface.
    #[inline(always)]
    fn lit_point(&self, hit: &SurfaceHit, symmetry: Option<u32>) -> (ShadingPoint, SpawnOrigins) {
        let at = ShadingPoint::new(hit.p, hit.normal, self.material(hit));
        (symmetry.map_or(at, |k| at.with_symmetry(k)), hit.spawn_origins(self.ray_offset))
    }

    /// The material at camera hit `hit`: its object's, with the colour of a textured surface
    /// (texture and vertex colours at the hit) multiplied in.
    #[inline(always)]
    fn material(&self, hit: &SurfaceHit) -> Matte {
        let mut material = self.geometry.objects[hit.object as usize].material;
        if let Some(surface) = self.geometry.surface_of(hit) {
            let [b1, b2] = hit.bary;
            material.cd *= surface.at(hit.prim, b1, b2).truncate();
        }
        material
    }

    /// How many light groups draw no samples (`Scene::fixed_groups`).
    pub fn fixed_group_count(&self) -> usize {
        self.fixed_groups().count()
    }

    /// The light groups that draw no samples ([`LightGroup::dims`] 0: point lights), with their
    /// first sample dimension, in `lights` order.
    fn fixed_groups(&self) -> impl Iterator<Item = &(u32, &dyn LightGroup)> {
        self.lights.iter().filter(|(_, g)| g.dims() == 0)
    }
}

/// Per-thread scratch state and counters.
#[derive(Default)]
pub struct Tracer {
    stack: Vec<(u32, f32)>,
    /// One light's sample values for a run of samples, dimension by dimension.
    samples: Vec<Vec2>,
    /// One light group's arriving light for a run of samples.
    arriving: Vec<Vec3A>,
    /// Whether every element of `arriving` is zero: a run whose lights all added whole-run
    /// sums ([`RunSum`]) leaves it untouched, and the next run then need not clear it.
    arriving_zero: bool,
    /// One light's samples for a run of samples.
    drawn: Vec<Option<LightSample>>,
    /// The point sources of a group of lights ([`PlacedLight::point_source`]), kept between runs.
    point_sources: Vec<PointSource>,
    /// One direction light's samples for a run at one point.
    directions: DirectionRun,
    /// The shadow rays of a run, and which of them are blocked.
    shadow_rays: Vec<Ray>,
    shadow_blocked: Vec<bool>,
    /// A direction run's shadow rays and answers.
    direction_rays: DirectionRays,
    /// Every light dimension's samples for a pixel's run of camera samples that do not share a
    /// hit (jittered or lens rays), computed ahead by [`Tracer::prepare_runs`].
    run: RunSamples,
    /// The shading points of such a run.
    points: Vec<RunPoint>,
    /// The camera hits of a row of pixels, for the lights that draw no samples.
    row: Vec<RunPoint>,
    /// The camera rays of a row whose ends were not known, and their places in the row.
    unknown_rays: Vec<Ray>,
    unknown_at: Vec<u32>,
    unknown_ends: Vec<RayEnd>,
    /// Rays traced by this tracer.
    pub rays: RayCounts,
    /// Whether the pixel being traced is timed: light groups' cycles then go to `split`.
    pub timing: bool,
    /// Whether the scene queries of the pixel being traced are timed too (only in a timed
    /// pixel): their cycles then go to `split`.
    pub timing_queries: bool,
    /// Cycle counts of the timed pixels ([`TraceSplit`]); the caller counts whole pixels.
    pub split: TraceSplit,
}

/// Light samples of a run computed ahead: dimension `dims::LIGHTS + k` of sample `j` is
/// `values[k * stride + j]`.
#[derive(Default)]
struct RunSamples {
    values: Vec<Vec2>,
    stride: usize,
}

/// A camera hit ready to be lit: one sample of a pixel's run of camera samples (jittered or
/// lens rays), one pixel of a tile's row (shared hits, for the lights that draw no samples), or
/// one sample of a row's pooled runs ([`Tracer::shade_row_sums`]).
#[derive(Clone, Copy)]
pub struct RunPoint {
    /// Its place in the run or row: where its light goes, and where a run's light samples
    /// computed ahead are read.
    j: u32,
    /// The pixel and the sample's number, for light samples drawn on demand.
    pixel: u32,
    sample: u32,
    /// The lit point.
    at: ShadingPoint,
    /// Where its shadow rays start.
    spawn: SpawnOrigins,
}

impl RunPoint {
    /// The point `j` of a run or row: camera hit `hit` ([`Scene::lit_point`] under the pixel's
    /// `symmetry`), sample `sample` of `pixel`.
    #[inline(always)]
    fn new(scene: &Scene, hit: &SurfaceHit, j: usize, (pixel, symmetry): (u32, Option<u32>), sample: u32) -> Self {
        let (at, spawn) = scene.lit_point(hit, symmetry);
        RunPoint { j: j as u32, pixel, sample, at, spawn }
    }
}

impl CosinePoint for RunPoint {
    #[inline(always)]
    fn symmetry(&self) -> u32 {
        self.at.symmetry()
    }

    #[inline(always)]
    fn spawn(&self) -> &SpawnOrigins {
        &self.spawn
    }
}

/// pbrt-v4's ShadowEpsilon: shadow rays to a point stop this fraction short of it.
const SHADOW_EPSILON: f32 = 1e-4;

impl Tracer {
    /// Every light dimension's samples for the samples `first..first + count` of each of
    /// `pixels` (pixel, first), pixel after pixel: pixel i's sample s is run entry `i·count + s`
    /// (one hash per pass, vectorised patterns).
    fn prepare_runs(&mut self, scene: &Scene, pixels: &[(u32, u32)], count: u32) {
        let dims = scene.lights.iter().map(|(d, g)| d + g.dims()).max().unwrap_or(dims::LIGHTS) - dims::LIGHTS;
        let (run, n) = (&mut self.run, count as usize);
        run.stride = pixels.len() * n;
        run.values.resize(dims as usize * run.stride, Vec2::ZERO);
        for (k, column) in (0..dims).zip(run.values.chunks_exact_mut(run.stride.max(1))) {
            scene.sets.fill_runs(pixels, count, dims::LIGHTS + k, column);
        }
    }

    /// [`Tracer::shade_sum`] of the lights that draw samples for each of a row's shared camera
    /// hits (`hits[i]`, the hit of `pixels[i]`: the pixel and its first sample this frame),
    /// `count` samples each, into `out[i]` (zero where the camera ray escaped). The row's runs
    /// are pooled: each light type lights all their samples in one call, as the samples of a
    /// jittered run ([`Tracer::shade_runs`]), so a cosine run's rays from neighbouring pixels
    /// share packets, which pays where a pixel's own run would leave most lanes of its packet
    /// empty. Each pixel's light is its samples' light added in sample order. `timed` of the
    /// pixels are timed ([`crate::stats::timed_pixel`]): that share of the cycles goes to
    /// `split`.
    pub fn shade_row_sums(
        &mut self,
        scene: &Scene,
        pixels: &[(u32, u32)],
        hits: &[Option<PrimaryHit>],
        count: u32,
        timed: u64,
        out: &mut Vec<Vec3A>,
    ) {
        out.clear();
        out.resize(hits.len(), Vec3A::ZERO);
        let n = count as usize;
        if n == 0 || hits.is_empty() {
            return;
        }
        let started = |_: usize, _: &RunPoint| {};
        self.shade_row_points(scene, pixels, hits, count, timed, true, started, |run, term, light| {
            let reflectance = term.reflectance(&run[0].at.material);
            if reflectance.max_element() > 0.0 {
                out[run[0].j as usize / n] += Vec3A::from(reflectance) * light.iter().sum::<Vec3A>();
            }
        });
    }

    /// [`Tracer::shade_row_sums`] sample by sample, each light traced whatever its reflectance,
    /// for the AOVs: sample s of `pixels[i]` into `out[i·count + s]`, exactly what
    /// [`Tracer::shade`] gives it (the background where the camera ray escaped).
    pub fn shade_row_samples(
        &mut self,
        scene: &Scene,
        pixels: &[(u32, u32)],
        hits: &[Option<PrimaryHit>],
        count: u32,
        timed: u64,
        out: &mut Vec<SampleResult>,
    ) {
        let n = count as usize;
        out.clear();
        out.resize(hits.len() * n, SampleResult::missed(scene.background));
        if n == 0 || hits.is_empty() {
            return;
        }
        let out = std::cell::RefCell::new(out);
        let started = |i: usize, point: &RunPoint| {
            let primary = hits[i].as_ref().expect("a point at a camera hit");
            out.borrow_mut()[i * n..][..n].start(primary, &point.at.material);
        };
        self.shade_row_points(scene, pixels, hits, count, timed, false, started, |run, term, light| {
            let first = run[0].j as usize;
            out.borrow_mut()[first..first + n].add_light(term, term.reflectance(&run[0].at.material), light);
        });
    }

    /// Lights the runs of `count` samples at each of a row's shared camera hits together
    /// ([`Tracer::shade_row_sums`]): `started(i, point)` for each hit `hits[i]` as its point is
    /// made, then, light group by light group (those that draw samples), `lit(run, term,
    /// light)` for each hit's run of points and the light arriving at each of its samples.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn shade_row_points(
        &mut self,
        scene: &Scene,
        pixels: &[(u32, u32)],
        hits: &[Option<PrimaryHit>],
        count: u32,
        timed: u64,
        skip_black: bool,
        mut started: impl FnMut(usize, &RunPoint),
        mut lit: impl FnMut(&[RunPoint], Term, &[Vec3A]),
    ) {
        let n = count as usize;
        self.prepare_runs(scene, pixels, count);
        let mut points = std::mem::take(&mut self.points);
        points.clear();
        for (i, (&(pixel, first), hit)) in pixels.iter().zip(hits).enumerate() {
            let Some(primary) = hit else { continue };
            let symmetry = scene.sets.frame_symmetry(pixel);
            let point = RunPoint::new(scene, &primary.hit, i * n, (pixel, symmetry), first);
            started(i, &point);
            points.extend((0..n).map(|s| RunPoint {
                j: (i * n + s) as u32,
                sample: first.wrapping_add(s as u32),
                ..point
            }));
        }
        let mut arriving = std::mem::take(&mut self.arriving);
        self.for_row(timed, hits.len(), |tracer| {
            for &(first_dim, group) in scene.lights {
                if group.dims() == 0 {
                    continue;
                }
                tracer.light_points(scene, group, first_dim, &points, skip_black, &mut arriving);
                let term = group.term();
                for (run, light) in points.chunks_exact(n).zip(arriving.chunks_exact(n)) {
                    lit(run, term, light);
                }
            }
        });
        self.arriving = arriving;
        self.points = points;
    }

    /// Light reflected for the runs of samples `first, first + 1, …` (`count` of them) of each
    /// of `pixels` (pixel, first), each sample at its own camera hit (`hits[i·count + s]` for
    /// sample s of pixel i, `None` where the camera ray escaped), into `out` (same layout).
    /// `skip_black` lets lights whose reflectance is zero at a hit be skipped there (no rays);
    /// AOVs need them traced. Every light dimension's samples are computed ahead, and each
    /// light type is called once for all the runs: a row of pixels' few samples each share
    /// packets as one pixel's many do. Each sample is kept as `O` ([`OwnSample`]): all of it
    /// or its radiance alone.
    pub fn shade_runs<O: OwnSample>(
        &mut self,
        scene: &Scene,
        hits: &[Option<PrimaryHit>],
        pixels: &[(u32, u32)],
        count: u32,
        skip_black: bool,
        out: &mut [O],
    ) {
        self.prepare_runs(scene, pixels, count);
        let mut points = std::mem::take(&mut self.points);
        points.clear();
        let n = count as usize;
        for (i, &(pixel, first)) in pixels.iter().enumerate() {
            // One pixel: one symmetry for all its points.
            let pixel = (pixel, scene.sets.frame_symmetry(pixel));
            for s in 0..n {
                let (j, o) = (i * n + s, &mut out[i * n + s]);
                let Some(primary) = &hits[j] else {
                    *o = O::missed(scene.background);
                    continue;
                };
                let point = RunPoint::new(scene, &primary.hit, j, pixel, first.wrapping_add(s as u32));
                *o = O::at_hit(primary, &point.at.material);
                points.push(point);
            }
        }
        let mut arriving = std::mem::take(&mut self.arriving);
        for &(first_dim, group) in scene.lights {
            self.light_points(scene, group, first_dim, &points, skip_black, &mut arriving);
            let term = group.term();
            for (p, &a) in points.iter().zip(&arriving) {
                out[p.j as usize].add_light(term, term.reflectance(&p.at.material), a);
            }
        }
        self.arriving = arriving;
        self.points = points;
    }

    /// Runs `work` for a row of `n` pixels of which `timed` are timed
    /// ([`crate::stats::timed_pixel`]): its cycles are counted apart, every query timed when any
    /// pixel is (a row's rays go in few queries), and the timed pixels' share of them goes to
    /// `split`.
    pub fn for_row<R>(&mut self, timed: u64, n: usize, work: impl FnOnce(&mut Self) -> R) -> R {
        let (split, timing) = (std::mem::take(&mut self.split), (self.timing, self.timing_queries));
        (self.timing, self.timing_queries) = (timed > 0, timed > 0);
        let result = work(self);
        let row = std::mem::replace(&mut self.split, split);
        // `timed` ≤ n: nothing to share out of an empty row.
        self.split.add(&row.scaled(timed, n.max(1) as u64));
        (self.timing, self.timing_queries) = timing;
        result
    }

    /// Sets `arriving` to the light `group` (first sample dimension `first_dim`) brings to each
    /// of `points`, one element per point, its cycles counted in `split` when timing.
    fn light_points(
        &mut self,
        scene: &Scene,
        group: &dyn LightGroup,
        first_dim: u32,
        points: &[RunPoint],
        skip_black: bool,
        arriving: &mut Vec<Vec3A>,
    ) {
        arriving.clear();
        arriving.resize(points.len(), Vec3A::ZERO);
        self.arriving_zero = false;
        let start = self.timing.then(cycle_count);
        group.shade_points(self, scene, points, first_dim, skip_black, arriving);
        if let Some(start) = start {
            self.split.add_term(group.term(), cycles_since(start), self.timing_queries);
        }
    }

    /// The first hits of a run of camera rays that travel together (one pixel's samples, or a
    /// row of pixels), with the distance each travelled, into `out`; traced in packets where
    /// the scene allows ([`SceneGeometry::intersect_many`]).
    pub fn primaries(&mut self, scene: &Scene, rays: &[Ray], out: &mut Vec<Option<PrimaryHit>>) {
        self.rays.primary += rays.len() as u64;
        out.clear();
        out.resize(rays.len(), None);
        scene.geometry.intersect_many(rays, &mut self.stack, out, PrimaryHit::along);
    }

    /// [`Tracer::primaries`] for rays whose ends (`ends[k]` for `rays[k]`) may be known from
    /// an earlier frame: only the rays whose end is [`RayEnd::UNKNOWN`] are traced (together,
    /// in their order) and their ends written to `ends`; every hit is then made from its end,
    /// the same hit bit for bit. `false` (nothing done) where the scene's hits have no
    /// [`RayEnd`] (alpha-tested meshes).
    pub fn primaries_from_ends(
        &mut self,
        scene: &Scene,
        rays: &[Ray],
        ends: &mut [RayEnd],
        out: &mut Vec<Option<PrimaryHit>>,
    ) -> bool {
        if scene.geometry.has_alpha() {
            return false;
        }
        self.unknown_rays.clear();
        self.unknown_at.clear();
        for (k, (ray, end)) in rays.iter().zip(ends.iter()).enumerate() {
            if !end.is_known() {
                self.unknown_rays.push(*ray);
                self.unknown_at.push(k as u32);
            }
        }
        if !self.unknown_rays.is_empty() {
            self.rays.primary += self.unknown_rays.len() as u64;
            self.unknown_ends.clear();
            self.unknown_ends.resize(self.unknown_rays.len(), RayEnd::UNKNOWN);
            scene.geometry.ray_ends(&self.unknown_rays, &mut self.stack, &mut self.unknown_ends);
            for (&k, &end) in self.unknown_at.iter().zip(&self.unknown_ends) {
                ends[k as usize] = end;
            }
        }
        out.clear();
        out.resize(rays.len(), None);
        for ((ray, &end), out) in rays.iter().zip(ends.iter()).zip(out.iter_mut()) {
            scene.geometry.hit_at_into(ray, end, out, |hit| PrimaryHit::along(ray, hit));
        }
        true
    }

    /// The light that each group of lights drawing no samples (point lights: [`LightGroup::dims`]
    /// 0) brings to each camera hit of a row of pixels, before reflectance, into `out`: entry
    /// `g · hits.len() + k` for the g-th such group of `scene.lights` and `hits[k]`, the hit of
    /// `pixels[k]` (the pixel and the number of its first sample this frame), zero where the
    /// camera ray escaped or, with `skip_black`, where the group's reflectance at the hit is
    /// black. Each entry is
    /// exactly what [`Tracer::shade`] would add up at that hit; the row's shadow rays are traced
    /// in one call, so neighbouring pixels' rays to a light go as packets. `timed` of the hits
    /// are timed pixels' ([`crate::stats::timed_pixel`]): that share of the cycles goes to
    /// `split`.
    pub fn fixed_lights_row(
        &mut self,
        scene: &Scene,
        pixels: &[(u32, u32)],
        hits: &[Option<PrimaryHit>],
        skip_black: bool,
        timed: u64,
        out: &mut Vec<Vec3A>,
    ) {
        let n = hits.len();
        let fixed = scene.fixed_groups().count();
        out.clear();
        out.resize(fixed * n, Vec3A::ZERO);
        if fixed == 0 || n == 0 {
            return;
        }
        let mut points = std::mem::take(&mut self.row);
        points.clear();
        // A plain loop: through `filter_map` each point was copied by a call to memcpy.
        for (j, (&(pixel, sample), hit)) in pixels.iter().zip(hits).enumerate() {
            let Some(PrimaryHit { hit, .. }) = hit else { continue };
            points.push(RunPoint::new(scene, hit, j, (pixel, scene.sets.frame_symmetry(pixel)), sample));
        }
        let mut arriving = std::mem::take(&mut self.arriving);
        self.for_row(timed, n, |tracer| {
            for (g, &(first_dim, group)) in scene.fixed_groups().enumerate() {
                tracer.light_points(scene, group, first_dim, &points, skip_black, &mut arriving);
                for (p, &a) in points.iter().zip(&arriving) {
                    out[g * n + p.j as usize] = a;
                }
            }
        });
        self.arriving = arriving;
        self.row = points;
    }

    /// What [`Tracer::shade`] does for the lights that draw no samples, with their light at the
    /// hit already worked out ([`Tracer::fixed_lights_row`]): `arriving(g)` for the g-th such
    /// group. Sets `out` to the camera hit `primary` and adds each group's reflected light.
    pub fn shade_fixed<O: SampleOut + ?Sized>(
        &self,
        scene: &Scene,
        primary: &PrimaryHit,
        skip_black: bool,
        arriving: impl Fn(usize) -> Vec3A,
        out: &mut O,
    ) {
        let material = scene.material(&primary.hit);
        out.start(primary, &material);
        for (g, &(_, group)) in scene.fixed_groups().enumerate() {
            let term = group.term();
            let reflectance = term.reflectance(&material);
            if skip_black && reflectance.max_element() <= 0.0 {
                continue;
            }
            out.add_light(term, reflectance, &[arriving(g)]);
        }
    }

    /// Light reflected at a primary hit for the samples `first, first + 1, …` of `pixel`, one
    /// per element of `out` (each light's own sample dimensions), from the lights that draw
    /// samples (those that draw none come from [`Tracer::fixed_lights_row`]). The samples share
    /// the hit, so per-hit work and each pass's sample set-up are done once for all of them.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub fn shade<O: SampleOut + ?Sized>(
        &mut self,
        scene: &Scene,
        primary: &PrimaryHit,
        pixel: u32,
        first: u32,
        skip_black: bool,
        out: &mut O,
    ) {
        let (at, spawn) = scene.lit_point(&primary.hit, scene.sets.frame_symmetry(pixel));
        out.start(primary, &at.material);
        let sample = (pixel, first, out.len());
        self.shade_groups(scene, (&at, &spawn), sample, skip_black, false, |term, reflectance, arriving, _| {
            out.add_light(term, reflectance, arriving)
        });
    }

    /// What [`Tracer::shade`] gives the `count` samples from the lights that draw samples,
    /// summed (black reflectance skipped where `skip_black`), and each sample's radiance where
    /// it takes two values: a light that adds a whole run at once ([`RunSum`]: the occluder's
    /// cosine runs in lanes, which count their blocked rays) makes no per-sample values. The
    /// same rays as [`Tracer::shade`]; the sums may differ from its samples' in the last bits.
    #[inline]
    pub fn shade_sum(
        &mut self,
        scene: &Scene,
        primary: &PrimaryHit,
        (pixel, first, count): (u32, u32, u32),
        skip_black: bool,
    ) -> ShadedSum {
        let (at, spawn) = scene.lit_point(&primary.hit, scene.sets.frame_symmetry(pixel));
        let mut total = ShadedSum { values: Some(TwoValues::default()), ..Default::default() };
        let sample = (pixel, first, count as usize);
        self.shade_groups(scene, (&at, &spawn), sample, skip_black, true, |term, reflectance, arriving, sum| {
            let (reflectance, mut light) = (Vec3A::from(reflectance), sum.light());
            if sum.per_sample() {
                light += arriving.iter().sum::<Vec3A>();
            }
            total.values = total.values.zip(sum.values()).and_then(|(t, v)| t.plus(&v.scaled(reflectance), count));
            let reflected = reflectance * light;
            total.radiance += reflected;
            match term {
                Term::Ambient => total.ao += light.element_sum() / 3.0,
                Term::Diffuse => total.direct += reflected,
            }
        });
        total
    }

    /// Lights the samples `first, first + 1, …` (`n` of them) of `pixel` at `at` with every
    /// light group that draws samples, giving `add` each group's term, reflectance, light
    /// arriving per sample and, when `sums`, the light it added as a whole-run sum instead.
    #[inline]
    fn shade_groups(
        &mut self,
        scene: &Scene,
        (at, spawn): (&ShadingPoint, &SpawnOrigins),
        (pixel, first, n): (u32, u32, usize),
        skip_black: bool,
        sums: bool,
        mut add: impl FnMut(Term, Vec3, &[Vec3A], RunSum),
    ) {
        let mut arriving = std::mem::take(&mut self.arriving);
        for &(first_dim, group) in scene.lights {
            if group.dims() == 0 {
                continue;
            }
            let term = group.term();
            let reflectance = term.reflectance(&at.material);
            if skip_black && reflectance.max_element() <= 0.0 {
                continue;
            }
            if !self.arriving_zero {
                arriving.clear();
            }
            arriving.resize(n, Vec3A::ZERO);
            let mut sum = RunSum::default();
            let start = self.timing.then(cycle_count);
            group.shade(self, scene, spawn, at, pixel, first, first_dim, &mut arriving, sums.then_some(&mut sum));
            if let Some(start) = start {
                self.split.add_term(term, cycles_since(start), self.timing_queries);
            }
            self.arriving_zero = sums && !sum.per_sample();
            add(term, reflectance, &arriving, sum);
        }
        self.arriving = arriving;
    }

    /// Adds the light arriving from `lights` (all of one type) at a hit for the samples
    /// `first, first + 1, …` of `pixel`, one per element of `arriving`: each light's sample,
    /// with its shadow ray when it can matter.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn shade_lights<P: PlacedLight>(
        &mut self,
        scene: &Scene,
        spawn: &SpawnOrigins,
        at: &ShadingPoint,
        lights: &[P],
        pixel: u32,
        first: u32,
        first_dim: u32,
        arriving: &mut [Vec3A],
        mut sum: Option<&mut RunSum>,
    ) {
        let n = arriving.len();
        // Each light's sample values for the whole run, dimension after dimension, and its
        // drawn samples: each resized only where used (a cosine run uses neither, a direction
        // run no `drawn`), every entry written before it is read.
        let mut values = std::mem::take(&mut self.samples);
        let mut drawn = std::mem::take(&mut self.drawn);
        for (l, light) in lights.iter().enumerate() {
            let dim = first_dim + l as u32 * P::DIMS;
            // A cosine run in one pass, where the CPU and sampler allow.
            if let Some(terms) = light.cosine_run().filter(|_| P::DIMS > 0) {
                let (geometry, rays) = (scene.geometry, &mut self.direction_rays);
                rays.timing = self.timing_queries;
                let sample = (pixel, first, dim);
                let (stack, sum) = (&mut self.stack, sum.as_deref_mut());
                if let Some((traced, cycles)) =
                    rays.add_cosine(geometry, stack, spawn, &at.frame(), scene.sets, sample, &terms, arriving, sum)
                {
                    self.rays.count(P::TERM, traced);
                    self.split.add_queries(P::TERM, cycles);
                    continue;
                }
            }
            // Every way below adds sample by sample.
            if let Some(sum) = sum.as_deref_mut() {
                sum.add_per_sample();
            }
            if P::DIMS > 0 {
                values.resize(n * P::DIMS as usize, Vec2::ZERO);
                for (k, column) in (0..P::DIMS).zip(values.chunks_exact_mut(n.max(1))) {
                    scene.sets.fill(pixel, first, dim + k, column);
                }
                // A direction light's run goes in bulk: exactly what `add_run` would do with
                // its samples' `DirectionRun::light_sample`s, without making them.
                if let Some(terms) = light.sample_directions(at, &values, &mut self.directions) {
                    let (geometry, run) = (scene.geometry, &self.directions);
                    self.direction_rays.timing = self.timing_queries;
                    let (traced, cycles) =
                        self.direction_rays.add(geometry, &mut self.stack, spawn, run, &terms, arriving);
                    self.rays.count(P::TERM, traced);
                    self.split.add_queries(P::TERM, cycles);
                    continue;
                }
                drawn.resize(n, None);
                light.sample_run(at, &values, &mut drawn);
            } else {
                drawn.resize(n, None);
                for (j, d) in drawn.iter_mut().enumerate() {
                    *d = light
                        .sample(at, &LightSamples::from_sets(scene.sets, pixel, first.wrapping_add(j as u32), dim, 0));
                }
            }
            self.add_run(scene, |_| spawn, &drawn, P::TERM, arriving);
        }
        self.samples = values;
        self.drawn = drawn;
    }

    /// Adds the light arriving from `lights` (all of one type) at each of `points` into
    /// `arriving`: lights that draw samples read them from the run computed ahead (at `p.j`;
    /// only points of one pixel's run), the others get sample `p.sample` of `p.pixel`. Points
    /// whose reflectance for `P::TERM` is black are skipped when `skip_black`.
    pub(crate) fn shade_points_lights<P: PlacedLight>(
        &mut self,
        scene: &Scene,
        points: &[RunPoint],
        lights: &[P],
        first_dim: u32,
        skip_black: bool,
        arriving: &mut [Vec3A],
    ) {
        // Lights that shine from a point: all at once in lanes, where the CPU and scene allow.
        if P::DIMS == 0 {
            let mut sources = std::mem::take(&mut self.point_sources);
            sources.clear();
            sources.extend(lights.iter().map_while(PlacedLight::point_source));
            let done = sources.len() == lights.len()
                && self.shade_point_sources(scene, points, &sources, P::TERM, skip_black, arriving);
            self.point_sources = sources;
            if done {
                return;
            }
        }
        let run = std::mem::take(&mut self.run);
        let mut drawn = std::mem::take(&mut self.drawn);
        for (l, light) in lights.iter().enumerate() {
            let dim = first_dim + l as u32 * P::DIMS;
            // No columns for lights that draw no samples (a row's points have no run).
            let columns = if P::DIMS == 0 {
                &[][..]
            } else {
                let start = (dim - dims::LIGHTS) as usize * run.stride;
                &run.values[start..start + P::DIMS as usize * run.stride]
            };
            let lit = |p: &RunPoint| !(skip_black && P::TERM.reflectance(&p.at.material).max_element() <= 0.0);
            // A cosine run over the points in one pass, where the CPU and scene allow.
            if let Some(terms) = light.cosine_run().filter(|_| P::DIMS > 0) {
                let u = |p: &RunPoint| columns[p.j as usize];
                let (geometry, rays) = (scene.geometry, &mut self.direction_rays);
                rays.timing = self.timing_queries;
                if let Some((traced, cycles)) =
                    rays.add_cosine_points(geometry, &mut self.stack, points, u, lit, &terms, arriving)
                {
                    self.rays.count(P::TERM, traced);
                    self.split.add_queries(P::TERM, cycles);
                    continue;
                }
            }
            drawn.clear();
            drawn.extend(points.iter().map(|p| {
                if !lit(p) {
                    return None;
                }
                let u = if P::DIMS == 0 {
                    LightSamples::from_sets(scene.sets, p.pixel, p.sample, dim, 0)
                } else {
                    LightSamples::from_columns(columns, p.j as usize, run.stride)
                };
                light.sample(&p.at, &u)
            }));
            self.add_run(scene, |k| &points[k].spawn, &drawn, P::TERM, arriving);
        }
        self.drawn = drawn;
        self.run = run;
    }

    /// Adds the light of `sources` (in order) at `points` to `arriving` (one element each), lit
    /// as `term`'s light (points whose reflectance for it is black skipped where `skip_black`),
    /// in lanes ([`DirectionRays::add_point_sources`]): the general path's light and shadow
    /// rays. False, having done nothing, where the CPU or scene does not allow it. Out of line:
    /// the generic per-light loop that calls it stays as small as before for other lights.
    #[inline(never)]
    fn shade_point_sources(
        &mut self,
        scene: &Scene,
        points: &[RunPoint],
        sources: &[PointSource],
        term: Term,
        skip_black: bool,
        arriving: &mut [Vec3A],
    ) -> bool {
        let lit = |p: &RunPoint| !(skip_black && term.reflectance(&p.at.material).max_element() <= 0.0);
        let (geometry, rays) = (scene.geometry, &mut self.direction_rays);
        rays.timing = self.timing_queries;
        let far = 1.0 - SHADOW_EPSILON;
        let Some((traced, cycles)) =
            rays.add_point_sources(geometry, &mut self.stack, points, lit, (sources, far), arriving)
        else {
            return false;
        };
        self.rays.count(term, traced);
        self.split.add_queries(term, cycles);
        true
    }

    /// Adds a run of drawn samples to `arriving`, tracing the shadow rays whose answer matters in
    /// one call; sample `j`'s rays start at `spawn(j)`.
    fn add_run<'a>(
        &mut self,
        scene: &Scene,
        spawn: impl Fn(usize) -> &'a SpawnOrigins,
        drawn: &[Option<LightSample>],
        term: Term,
        arriving: &mut [Vec3A],
    ) {
        // A shadow ray only when its answer changes the result.
        let needs_ray = |s: &LightSample| s.shadow.filter(|_| s.unoccluded != s.occluded);
        let rays = &mut self.shadow_rays;
        rays.clear();
        rays.reserve(drawn.len());
        for (j, s) in drawn.iter().enumerate() {
            if let Some(shadow) = s.as_ref().and_then(needs_ray) {
                rays.push(shadow_ray(spawn(j), shadow));
            }
        }
        self.shadow_blocked.resize(rays.len(), false);
        let start = self.timing_queries.then(cycle_count);
        scene.geometry.occluded_many(rays, RayOrder::Mixed, &mut self.stack, &mut self.shadow_blocked);
        if let Some(start) = start {
            self.split.add_queries(term, cycles_since(start));
        }
        self.rays.count(term, rays.len() as u64);
        let mut blocked = self.shadow_blocked.iter();
        for (sum, s) in arriving.iter_mut().zip(drawn) {
            let Some(s) = s else { continue };
            let occluded = needs_ray(s).is_some() && blocked.next().copied().unwrap_or(false);
            *sum += Vec3A::from(if occluded { s.occluded } else { s.unoccluded });
        }
    }
}

/// The ray that tests `shadow` from a hit, its origin just off the surface on the ray's side.
#[inline]
fn shadow_ray(spawn: &SpawnOrigins, shadow: Shadow) -> Ray {
    match shadow {
        Shadow::ToPoint(q) => {
            let origin = spawn.towards(q - spawn.p);
            Ray::new(origin, q - origin, 1.0 - SHADOW_EPSILON)
        }
        Shadow::Along { dir, max_distance } => Ray::new(spawn.towards(dir), dir, max_distance),
    }
}
