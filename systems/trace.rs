//! Stage 4: traces this frame's samples, tile-parallel with rayon. Each pixel sample is a
//! primary ray, then every registered light group shades the hit (one AO ray per occluder, one
//! shadow ray per light that can light the point); every random number comes from (pixel, sample index, dimension), so the image does
//! not depend on tile order or thread count. Each tile adds its samples straight into its own
//! pixels of [`Accumulation`] as it completes: no image-sized frame buffer exists.

use std::time::Instant;

use bevy_ecs::prelude::*;
use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;

mod pixels;

use pixels::{Band, KeptRow, TilePixels, bands};

use crate::{
    camera::{ActiveCamera, CameraRays, Cameras},
    geometry::{Ray, RayEnd, SceneGeometry, TraversalCounts, accel::AlphaCounts, counters},
    integrator::{LightGroup, LightRegistry, OwnSample, PrimaryHit, SampleResult, Scene, ShadedSum, Tracer},
    resources::{
        AOV_FLOATS, Accumulation, AovValues, FrameSamples, LuminanceSpread, RenderSettings, SceneProblems, luminance,
    },
    sampling::{SampleSets, dims},
    stats::{FrameStats, RayCounts, TraceSplit, cycle_count, cycles_since, query_timed_pixel, timed_pixel},
};

/// What tiles counted while they traced (their samples went into the accumulation).
#[derive(Default)]
struct TileResult {
    rays: RayCounts,
    split: TraceSplit,
    traversal: TraversalCounts,
    alpha: AlphaCounts,
    nonfinite: u64,
    /// Pixels that got samples.
    active: usize,
}

impl TileResult {
    /// Both tiles' counts (integers: the totals do not depend on the order tiles finish in).
    fn merge(mut self, other: TileResult) -> TileResult {
        self.rays.add(&other.rays);
        self.split.add(&other.split);
        self.traversal.add(&other.traversal);
        self.alpha.add(&other.alpha);
        self.nonfinite += other.nonfinite;
        self.active += other.active;
        self
    }
}

/// Traces `samples_per_frame` samples per pixel (fewer once the target spp is near) into
/// [`Accumulation`] (the accumulate stage then counts them); traces nothing when the scene is
/// invalid or has converged.
#[allow(clippy::too_many_arguments)]
pub fn trace(
    settings: Res<RenderSettings>,
    geometry: Res<SceneGeometry>,
    sets: Res<SampleSets>,
    problems: Res<SceneProblems>,
    mut accumulation: ResMut<Accumulation>,
    cameras: Cameras,
    lights: Res<LightRegistry>,
    mut frame: ResMut<FrameSamples>,
    mut stats: ResMut<FrameStats>,
) {
    let start = Instant::now();
    let remaining = settings.target_spp().map_or(u32::MAX, |target| target.saturating_sub(accumulation.spp));
    let count = settings.samples_per_frame.min(remaining);
    let camera = cameras.active(settings.width, settings.height);
    let (Some(camera), None, true) = (camera, problems.first(), count > 0) else {
        if frame.samples_per_pixel != 0 {
            frame.samples_per_pixel = 0;
        }
        let why = if count == 0 { "skipped: converged" } else { "skipped: invalid scene" };
        stats.record("trace", start.elapsed(), why);
        return;
    };

    // Registration order, then entity order, fixes which sample dimensions each light uses.
    let groups: Vec<(u32, &dyn LightGroup)> = lights.groups().filter(|(_, g)| g.count() > 0).collect();
    let scene = Scene {
        geometry: &geometry,
        lights: &groups,
        sets: &sets,
        background: settings.background,
        ray_offset: settings.ray_offset,
    };

    let job = Job {
        width: settings.width,
        first_sample: settings.first_sample,
        count,
        jitter: settings.jitter,
        aovs: settings.aovs,
        adaptive: settings.target_error.is_some(),
        time_split: stats.time_split,
    };
    let n = settings.pixel_count();
    let acc = &mut *accumulation;
    debug_assert_eq!(acc.sums.len(), n, "the accumulation is sized for the settings");
    if acc.spp > 0 {
        // A second frame: one frame's f32 sums become f64 before it adds to them.
        acc.sums.frames_mut();
        acc.aovs.frames_mut();
    }
    if job.aovs && acc.aovs.len() != n {
        acc.aovs.size(n);
    }
    // Frames after this one will find the camera rays' ends here, where every sample of a
    // pixel shares its camera ray and the scene's hits have ends ([`RayEnd`]); a render that
    // ends with this frame keeps none.
    let shared_camera_rays = job.shares_camera_rays(camera.uses_lens()) && !geometry.has_alpha();
    let more_frames = settings.target_spp().is_none_or(|target| target > acc.spp + count);
    if shared_camera_rays && more_frames && acc.camera_ends.len() != n {
        acc.camera_ends = vec![RayEnd::UNKNOWN; n];
        acc.camera_light = vec![Vec3::ZERO; n * scene.fixed_group_count()];
    }
    let frame = &mut *frame;
    frame.sums.clear();
    if frame.keep_sums {
        frame.sums.resize(n, Vec3::ZERO);
    }
    let (size, target) = (settings.tile_size, settings.target_error);
    let bands = bands(acc, &mut frame.sums, settings.width, size);
    let tiles = bands.len() * settings.width.div_ceil(size) as usize;
    let result = match camera {
        ActiveCamera::Pinhole(c) => trace_bands(&scene, &c, bands, &job, target, size),
        ActiveCamera::ThinLens(c) => trace_bands(&scene, &c, bands, &job, target, size),
        ActiveCamera::Orthographic(c) => trace_bands(&scene, &c, bands, &job, target, size),
    };
    frame.samples_per_pixel = count;
    frame.active_pixels = result.active;
    let TileResult { rays, split, traversal, alpha, nonfinite, .. } = result;
    stats.nonfinite_samples += nonfinite;
    stats.rays = rays;
    stats.trace_split = split;
    stats.traversal = traversal;
    stats.alpha = alpha;
    stats.samples_traced = count;
    let note = format!("{tiles} tiles, {count} spp, {}", lights.summary());
    stats.record("trace", start.elapsed(), note);
}

/// Whether every component of `v` is finite, in one SIMD compare: x · 0 is ±0 exactly when x
/// is finite (NaN for ±∞ and NaN).
#[inline(always)]
fn all_finite(v: Vec3A) -> bool {
    (v * 0.0).cmpeq(Vec3A::ZERO).all()
}

/// The camera rays of one row of a tile's pixels still sampled, each pixel's one ray.
struct RowCamera<'a> {
    rays: &'a [Ray],
    /// Each ray's pixel and the number of its first sample this frame.
    pixels: &'a [(u32, u32)],
    /// Whether light is skipped where the reflectance is black (no AOVs).
    skip_black: bool,
    /// How many of the pixels are timed.
    timed: u64,
}

impl RowCamera<'_> {
    /// The row's camera hits into `hits` and what the lights that draw no samples bring to
    /// each into `fixed` ([`Tracer::fixed_lights_row`]'s layout): taken from `kept` where an
    /// earlier frame left them there, else traced, and kept where `kept` is given.
    fn hits_and_light(
        &self,
        tracer: &mut Tracer,
        scene: &Scene,
        kept: Option<KeptRow>,
        ends: &mut Vec<RayEnd>,
        hits: &mut Vec<Option<PrimaryHit>>,
        fixed: &mut Vec<Vec3A>,
    ) {
        if let Some(kept) = kept
            && self.through_kept(tracer, scene, kept, ends, hits, fixed)
        {
            return;
        }
        tracer.primaries(scene, self.rays, hits);
        // The lights that draw no samples, once per pixel, the row's shadow rays together.
        tracer.fixed_lights_row(scene, self.pixels, hits, self.skip_black, self.timed, fixed);
    }

    /// [`RowCamera::hits_and_light`] through `kept`; `false` (nothing done) where the scene's
    /// hits have no [`RayEnd`].
    fn through_kept(
        &self,
        tracer: &mut Tracer,
        scene: &Scene,
        kept: KeptRow,
        ends: &mut Vec<RayEnd>,
        hits: &mut Vec<Option<PrimaryHit>>,
        fixed: &mut Vec<Vec3A>,
    ) -> bool {
        let column = |pixel: u32| (pixel % kept.width - kept.x0) as usize;
        ends.clear();
        ends.extend(self.pixels.iter().map(|&(pixel, _)| kept.ends[column(pixel)]));
        let known = ends.iter().all(RayEnd::is_known);
        if !tracer.primaries_from_ends(scene, self.rays, ends, hits) {
            return false;
        }
        let (n, g) = (self.pixels.len(), kept.groups);
        if known {
            fixed.clear();
            fixed.resize(n * g, Vec3A::ZERO);
        } else {
            tracer.fixed_lights_row(scene, self.pixels, hits, self.skip_black, self.timed, fixed);
        }
        for (k, &(pixel, _)) in self.pixels.iter().enumerate() {
            let c = column(pixel);
            kept.ends[c] = ends[k];
            for i in 0..g {
                if known {
                    fixed[i * n + k] = kept.light[c * g + i].into();
                } else {
                    kept.light[c * g + i] = fixed[i * n + k].into();
                }
            }
        }
        true
    }
}

/// Scratch for runs whose samples each have a camera ray of their own (jittered pixels or a
/// lens).
#[derive(Default)]
struct OwnRays {
    films: Vec<Vec2>,
    lenses: Vec<Vec2>,
    rays: Vec<Ray>,
    hits: Vec<Option<PrimaryHit>>,
    pixels: Vec<(u32, u32)>,
}

impl OwnRays {
    /// Traces and lights the runs of `count` samples of each of `runs` (column, pixel, first
    /// sample) in row `y` into `out`, sample s of run i at `i·count + s`: every dimension's
    /// samples computed ahead, the camera rays traced in one call, then every hit lit by one
    /// call per light type for all the runs ([`Tracer::shade_runs`]).
    #[allow(clippy::too_many_arguments)]
    fn trace<C: CameraRays, O: OwnSample>(
        &mut self,
        tracer: &mut Tracer,
        scene: &Scene,
        camera: &C,
        job: &Job,
        y: u32,
        runs: &[(u32, u32, u32)],
        count: u32,
        out: &mut Vec<O>,
    ) {
        let n = count as usize;
        self.pixels.clear();
        self.pixels.extend(runs.iter().map(|&(_, pixel, first)| (pixel, first)));
        self.films.clear();
        self.films.resize(runs.len() * n, Vec2::splat(0.5));
        self.lenses.clear();
        self.lenses.resize(runs.len() * n, Vec2::ZERO);
        if job.jitter {
            scene.sets.fill_runs(&self.pixels, count, dims::PIXEL, &mut self.films);
        }
        if C::USES_LENS {
            scene.sets.fill_runs(&self.pixels, count, dims::LENS, &mut self.lenses);
        }
        self.rays.clear();
        for (&(x, _, _), (films, lenses)) in
            runs.iter().zip(self.films.chunks_exact(n.max(1)).zip(self.lenses.chunks_exact(n.max(1))))
        {
            self.rays.extend(films.iter().zip(lenses).map(|(&film, &lens)| camera.ray(x, y, film, lens)));
        }
        tracer.primaries(scene, &self.rays, &mut self.hits);
        out.resize(self.rays.len(), O::missed(Vec3::ZERO));
        tracer.shade_runs(scene, &self.hits, &self.pixels, count, !job.aovs, out);
    }
}

/// Traces every band's tiles in parallel; a band is cut into its tiles only when a thread
/// reaches it, so that the row slices of only the bands in flight exist at once.
fn trace_bands<C: CameraRays + Sync>(
    scene: &Scene,
    camera: &C,
    bands: Vec<Band>,
    job: &Job,
    target: Option<f32>,
    size: u32,
) -> TileResult {
    bands
        .into_par_iter()
        .map(|band| {
            band.tiles(job.width, size)
                .into_par_iter()
                .map_init(TileScratch::default, |scratch, mut pixels| {
                    trace_tile(scene, camera, &mut pixels, job, target, scratch)
                })
                .reduce(TileResult::default, TileResult::merge)
        })
        .reduce(TileResult::default, TileResult::merge)
}

/// Most samples per pixel a frame may trace for its shared hits' runs to be pooled a row at a
/// time ([`Tracer::shade_row_sums`]): a pixel's own run of so few rays leaves most of its
/// packet's lanes empty. Pooling eight was slower than each pixel's own packet on cornell and
/// sphere_plane (docs/benchmarks.md, "Frames of few samples").
const POOLED_SHARED_RUN_MAX: u32 = 4;

/// Most samples per pixel a frame may trace for runs whose samples each have a camera ray of
/// their own to be traced and lit a row at a time ([`Tracer::shade_runs`]): their points are
/// set up one by one either way, and pooling pays up to eight; at 64 a pixel's own run fills
/// its packets, and pooling's larger run was slower.
const POOLED_OWN_RUN_MAX: u32 = 8;

/// What every tile of this frame traces.
struct Job {
    width: u32,
    /// Global index of the accumulation's first sample.
    first_sample: u32,
    count: u32,
    jitter: bool,
    aovs: bool,
    adaptive: bool,
    /// Whether the timed pixels ([`timed_pixel`]) are timed: the split is asked for.
    time_split: bool,
}

impl Job {
    /// Whether `pixel` is timed for the split ([`timed_pixel`]).
    fn timed(&self, pixel: u32) -> bool {
        self.time_split && timed_pixel(pixel)
    }

    /// Whether every sample of a pixel has the same camera ray (no jitter, and a camera
    /// without a lens: `uses_lens`).
    fn shares_camera_rays(&self, uses_lens: bool) -> bool {
        !self.jitter && !uses_lens
    }
}

/// A tracer and its buffers, kept from one tile to the next a thread traces: a frame of few
/// samples a pixel would otherwise spend a noticeable part of its time allocating them anew
/// for every tile. No result depends on what they held.
#[derive(Default)]
struct TileScratch {
    tracer: Tracer,
    own: OwnRays,
    buffers: TileBuffers,
}

/// The per-pixel and per-row vectors [`trace_tile`] fills, emptied at the start of each tile.
#[derive(Default)]
struct TileBuffers {
    /// One pixel's samples of this frame: all of each with AOVs, else each one's radiance.
    samples: Vec<SampleResult>,
    radiance: Vec<Vec3A>,
    /// Each pixel's sums, sample count, luminance spread and AOV sums, in tile order.
    sums: Vec<Vec3>,
    counts: Vec<u32>,
    deviations: Vec<f64>,
    aovs: Vec<AovValues>,
    /// A row's camera rays, pixels, hits, fixed light and kept ray ends.
    camera_rays: Vec<Ray>,
    row_pixels: Vec<(u32, u32)>,
    row_hits: Vec<Option<PrimaryHit>>,
    row_fixed: Vec<Vec3A>,
    row_ends: Vec<RayEnd>,
    /// A row's pooled runs: their pixels, their sums, and their samples with and without AOVs.
    row_runs: Vec<(u32, u32, u32)>,
    row_sums: Vec<Vec3A>,
    row_samples: Vec<SampleResult>,
    row_radiance: Vec<Vec3A>,
}

impl TileBuffers {
    /// Every vector emptied, its memory kept.
    fn cleared(&mut self) -> &mut Self {
        self.samples.clear();
        self.radiance.clear();
        self.sums.clear();
        self.counts.clear();
        self.deviations.clear();
        self.aovs.clear();
        self.camera_rays.clear();
        self.row_pixels.clear();
        self.row_hits.clear();
        self.row_fixed.clear();
        self.row_ends.clear();
        self.row_runs.clear();
        self.row_sums.clear();
        self.row_samples.clear();
        self.row_radiance.clear();
        self
    }
}

/// What adaptive sampling needs of a run of `count` samples summed at a shared hit (`run`), each
/// sample `fixed` brighter: the squared deviations of their luminances from their mean, from
/// the run's two values ([`ShadedSum::values`]). `None` where the sum does not tell its samples
/// apart, which also clears `sums_tell_samples`: the runs at the tile's other pixels, lit by
/// the same lights, likely do not either. 0 without adaptive sampling, which does not ask.
fn spread_of_sum(run: &ShadedSum, count: u32, fixed: Vec3A, job: &Job, sums_tell_samples: &mut bool) -> Option<f64> {
    if !job.adaptive {
        return Some(0.0);
    }
    let Some(values) = run.values else {
        *sums_tell_samples = false;
        return None;
    };
    Some(values.squared_deviations(count, |v| luminance((v + fixed).into())))
}

/// Traces one tile and adds its samples to its pixels (`acc`).
fn trace_tile<C: CameraRays>(
    scene: &Scene,
    camera: &C,
    acc: &mut TilePixels,
    job: &Job,
    target: Option<f32>,
    TileScratch { tracer, own, buffers }: &mut TileScratch,
) -> TileResult {
    let tile = acc.tile;
    // Counts from this thread's earlier work are not this tile's.
    counters::take();
    AlphaCounts::take();
    (tracer.rays, tracer.split) = Default::default();
    let TileBuffers {
        samples,
        radiance,
        sums,
        counts,
        deviations,
        aovs,
        camera_rays,
        row_pixels,
        row_hits,
        row_fixed,
        row_ends,
        row_runs,
        row_sums,
        row_samples,
        row_radiance,
    } = buffers.cleared();
    let mut nonfinite = 0;
    // Without jitter or lens every sample of a pixel has the same camera ray: it is traced once
    // per pixel, a row of the tile's pixels at a time (neighbouring rays travel together).
    let one_ray_per_pixel = job.shares_camera_rays(C::USES_LENS);
    // Small runs of shared hits, summed without per-sample values, are lit a row at a time;
    // so are small runs of samples with camera rays of their own.
    let pooled = one_ray_per_pixel && !job.aovs && !job.adaptive && job.count <= POOLED_SHARED_RUN_MAX;
    // With AOVs, such runs are lit a row at a time sample by sample.
    let pooled_aovs = one_ray_per_pixel && job.aovs && job.count <= POOLED_SHARED_RUN_MAX;
    let pooled_own = !one_ray_per_pixel && job.count <= POOLED_OWN_RUN_MAX;
    let mut own_run = 0;
    let fixed_groups = scene.fixed_group_count();
    // Whether adaptive sampling takes a run's spread from its sum ([`spread_of_sum`]); once a
    // sum does not tell its samples apart, the tile's runs are made one by one.
    let mut sums_tell_samples = true;
    for y in tile.y0..tile.y1 {
        // Rows traced before their pixels: shared camera hits, or pooled runs of own rays.
        if one_ray_per_pixel || pooled_own {
            let start = job.time_split.then(cycle_count);
            let timed = acc.row_to_trace(y, (job.first_sample, target), |pixel| job.timed(pixel), row_runs);
            if one_ray_per_pixel {
                camera_rays.clear();
                camera_rays.extend(row_runs.iter().map(|&(x, _, _)| camera.ray(x, y, Vec2::splat(0.5), Vec2::ZERO)));
                row_pixels.clear();
                row_pixels.extend(row_runs.iter().map(|&(_, pixel, first)| (pixel, first)));
                let row = RowCamera { rays: camera_rays, pixels: row_pixels, skip_black: !job.aovs, timed };
                let kept = acc.kept_row(y, fixed_groups);
                row.hits_and_light(tracer, scene, kept, row_ends, row_hits, row_fixed);
                if pooled {
                    tracer.shade_row_sums(scene, row_pixels, row_hits, job.count, timed, row_sums);
                }
                if pooled_aovs {
                    tracer.shade_row_samples(scene, row_pixels, row_hits, job.count, timed, row_samples);
                }
            } else {
                // Each sample has a camera ray of its own, and a pixel's few of them would leave
                // most of a packet empty: the row's runs are traced and lit together.
                if !row_runs.is_empty() {
                    tracer.for_row(timed, row_runs.len(), |tracer| {
                        if job.aovs {
                            own.trace(tracer, scene, camera, job, y, row_runs, job.count, row_samples);
                        } else {
                            own.trace(tracer, scene, camera, job, y, row_runs, job.count, row_radiance);
                        }
                    });
                }
                own_run = 0;
            }
            // The timed pixels' part of the row's work.
            if let Some(start) = start
                && timed > 0
            {
                tracer.split.pixels += cycles_since(start) * timed / row_runs.len() as u64;
            }
        }
        let row_len = row_hits.len();
        let mut row_hits = row_hits.iter().enumerate();
        // Where the row was gathered before its pixels, its runs are its pixels still sampled,
        // in column order: no pixel's error is worked out twice.
        let row_gathered = one_ray_per_pixel || pooled_own;
        let mut row_left = row_runs.iter().peekable();
        for x in tile.x0..tile.x1 {
            let pixel = y * job.width + x;
            tracer.timing = job.timed(pixel);
            tracer.timing_queries = job.time_split && query_timed_pixel(pixel);
            let start = tracer.timing.then(cycle_count);
            let mut sum = Vec3::ZERO;
            // The spread of the pixel's sample luminances (adaptive sampling): from a run's sum,
            // or added sample by sample.
            let mut deviation = 0.0;
            let mut spread = LuminanceSpread::default();
            let mut aov = [0.0; AOV_FLOATS];
            // A pixel's samples are numbered 0, 1, … (from `first_sample` for a part of a
            // render) whatever the others do (adaptive sampling retires pixels independently).
            let first = job.first_sample.wrapping_add(acc.count((x, y)));
            let done = if row_gathered {
                row_left.next_if(|&&(column, _, _)| column == x).is_none()
            } else {
                acc.pixel_done((x, y), target)
            };
            let count = if done { 0 } else { job.count };
            if count == 0 {
                sums.push(sum);
                counts.push(0);
                deviations.push(0.0);
                if job.aovs {
                    aovs.push(aov);
                }
                continue;
            }
            // A shared camera hit: shade all samples at it together, evaluating the lights that
            // draw no samples (point lights) once.
            let shared = one_ray_per_pixel.then(|| row_hits.next().expect("one camera ray per pixel still sampled"));
            // What the lights that draw no samples add to every sample (shared hits only): the
            // row's, this pixel's k-th.
            let row_fixed = &row_fixed;
            let fixed_light = |k: usize| move |g: usize| row_fixed[g * row_len + k];
            let mut fixed = SampleResult::default();
            match shared {
                Some((k, Some(hit))) if !job.aovs => {
                    // The beauty image alone: each sample's radiance, no other AOV, summed here
                    // (no `radiance` left for the loop below).
                    let mut fixed_radiance = [Vec3A::ZERO];
                    tracer.shade_fixed(scene, hit, true, fixed_light(k), &mut fixed_radiance[..]);
                    let fixed_radiance = fixed_radiance[0];
                    // The samples' sum alone, made without per-sample values where the lights
                    // allow ([`Tracer::shade_sum`]), and for adaptive sampling their luminances'
                    // spread, where the sum says what each sample is (two values). A finite sum
                    // means every sample was finite (∞ and NaN survive a sum); otherwise the
                    // samples are made (and their rays traced and counted) again, one by one,
                    // and the non-finite ones dropped.
                    let quick = (!job.adaptive || sums_tell_samples)
                        .then(|| {
                            if pooled {
                                return Some((row_sums[k] + fixed_radiance * count as f32, 0.0));
                            }
                            let run = tracer.shade_sum(scene, hit, (pixel, first, count), true);
                            let spread = spread_of_sum(&run, count, fixed_radiance, job, &mut sums_tell_samples)?;
                            Some((run.radiance + fixed_radiance * count as f32, spread))
                        })
                        .flatten()
                        .filter(|&(t, _)| all_finite(t));
                    let (total, spread_of_run) = quick.unwrap_or_else(|| {
                        radiance.resize(count as usize, Vec3A::ZERO);
                        tracer.shade(scene, hit, pixel, first, true, &mut radiance[..]);
                        let mut total = Vec3A::ZERO;
                        for &r in radiance.iter() {
                            let r = r + fixed_radiance;
                            if !all_finite(r) {
                                nonfinite += 1;
                                continue;
                            }
                            total += r;
                            if job.adaptive {
                                spread.add(luminance(r.into()));
                            }
                        }
                        (total, 0.0)
                    });
                    sum = total.into();
                    deviation = spread_of_run;
                    radiance.clear();
                }
                Some((k, Some(hit))) => {
                    // With AOVs: black reflectance still has an AO value.
                    tracer.shade_fixed(scene, hit, false, fixed_light(k), std::slice::from_mut(&mut fixed));
                    samples.clear();
                    if pooled_aovs {
                        samples.extend_from_slice(&row_samples[k * count as usize..][..count as usize]);
                    } else {
                        // The run's sums alone, as for the beauty image: the AOVs that the hit
                        // decides are the same for every sample. Where a sum is not finite (or
                        // adaptive sampling's spread is not known from it) the samples are made
                        // one by one, as there.
                        let summed = (!job.adaptive || sums_tell_samples)
                            .then(|| {
                                let run = tracer.shade_sum(scene, hit, (pixel, first, count), false);
                                let radiance = Vec3A::from(fixed.radiance);
                                let spread = spread_of_sum(&run, count, radiance, job, &mut sums_tell_samples)?;
                                Some((fixed.with_run(&run, count), spread))
                            })
                            .flatten()
                            .filter(|((radiance, values), _)| {
                                all_finite(*radiance) && values.iter().all(|v| v.is_finite())
                            });
                        if let Some(((radiance, values), spread_of_run)) = summed {
                            sum = radiance.into();
                            aov = values;
                            deviation = spread_of_run;
                        } else {
                            // `shade` sets every field of every sample: no need to clear them first.
                            samples.resize(count as usize, SampleResult::default());
                            tracer.shade(scene, hit, pixel, first, false, &mut samples[..]);
                        }
                    }
                }
                Some((_, None)) if job.aovs => {
                    samples.clear();
                    samples.resize(count as usize, SampleResult::missed(scene.background))
                }
                Some((_, None)) => {
                    radiance.clear();
                    radiance.resize(count as usize, scene.background.into());
                }
                None if pooled_own => {
                    // Lit with the row's other pixels before the loop.
                    let run = own_run * count as usize..(own_run + 1) * count as usize;
                    if job.aovs {
                        samples.clear();
                        samples.extend_from_slice(&row_samples[run]);
                    } else {
                        radiance.clear();
                        radiance.extend_from_slice(&row_radiance[run]);
                    }
                    own_run += 1;
                }
                None => {
                    let run = [(x, pixel, first)];
                    if job.aovs {
                        own.trace(tracer, scene, camera, job, y, &run, count, samples);
                    } else {
                        own.trace(tracer, scene, camera, job, y, &run, count, radiance);
                    }
                }
            }
            let mut add = |radiance: Vec3| {
                sum += radiance;
                if job.adaptive {
                    spread.add(luminance(radiance));
                }
            };
            if job.aovs {
                for s in samples.iter() {
                    let radiance = s.radiance + fixed.radiance;
                    let values = SampleResult { direct: s.direct + fixed.direct, ..*s }.aov_values();
                    if !all_finite(radiance.into()) || !values.iter().fold(true, |finite, x| finite & x.is_finite()) {
                        nonfinite += 1;
                        continue;
                    }
                    add(radiance);
                    aov.iter_mut().zip(values).for_each(|(a, v)| *a += v);
                }
            } else {
                // `fixed` is the AOV arm's alone: the beauty image's shared hits sum above.
                for &r in radiance.iter() {
                    if !all_finite(r) {
                        nonfinite += 1;
                        continue;
                    }
                    add(r.into());
                }
            }
            sums.push(sum);
            counts.push(count);
            if job.adaptive {
                deviation += spread.deviations();
            }
            deviations.push(deviation);
            if job.aovs {
                aovs.push(aov);
            }
            if let Some(start) = start {
                tracer.split.pixels += cycles_since(start);
            }
        }
    }
    let (traversal, alpha) = (counters::take(), AlphaCounts::take());
    acc.add(sums, counts, deviations, aovs);
    let active = counts.iter().filter(|&&c| c > 0).count();
    TileResult {
        rays: std::mem::take(&mut tracer.rays),
        split: std::mem::take(&mut tracer.split),
        traversal,
        alpha,
        nonfinite,
        active,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_finite_is_glams_is_finite() {
        let values =
            [0.0, -0.0, 1.0, -3.0e38, f32::MAX, f32::MIN_POSITIVE, 1e-45, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        for &x in &values {
            for &y in &values {
                for &z in &values {
                    let v = Vec3A::new(x, y, z);
                    assert_eq!(all_finite(v), v.is_finite(), "{v}");
                }
            }
        }
    }
}
