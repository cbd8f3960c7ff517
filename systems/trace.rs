//! Stage 4: traces this frame's samples, tile-parallel with rayon. Each pixel sample is a
//! primary ray, then every registered light group shades the hit (one AO ray per occluder, one
//! shadow ray per light that can light the point); every random number comes from (pixel, sample index, dimension), so the image does
//! not depend on tile order or thread count.

use std::time::Instant;

use bevy_ecs::prelude::*;
use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;

use crate::{
    camera::{ActiveCamera, CameraRays, Cameras},
    geometry::{SceneGeometry, TraversalCounts, accel::AlphaCounts, counters},
    integrator::{LightGroup, LightRegistry, SampleResult, Scene, Tracer},
    resources::{AOV_FLOATS, Accumulation, AovValues, FrameSamples, RenderSettings, SceneProblems, luminance},
    sampling::{SampleSets, dims},
    stats::{FrameStats, RayCounts, TraceSplit, cycle_count, cycles_since, query_timed_pixel, timed_pixel},
};

/// A rectangle of pixels traced as one task.
#[derive(Clone, Copy, Debug)]
struct Tile {
    x0: u32,
    y0: u32,
    x1: u32,
    y1: u32,
}

/// What one tile produced.
struct TileResult {
    sums: Vec<Vec3>,
    counts: Vec<u32>,
    sq_sums: Vec<f32>,
    aovs: Vec<AovValues>,
    rays: RayCounts,
    split: TraceSplit,
    traversal: TraversalCounts,
    alpha: AlphaCounts,
    nonfinite: u64,
}

/// Traces `samples_per_frame` samples per pixel (fewer once the target spp is near) into
/// [`FrameSamples`]; traces nothing when the scene is invalid or has converged.
#[allow(clippy::too_many_arguments)]
pub fn trace(
    settings: Res<RenderSettings>,
    geometry: Res<SceneGeometry>,
    sets: Res<SampleSets>,
    problems: Res<SceneProblems>,
    accumulation: Res<Accumulation>,
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

    let tiles = tiles(settings.width, settings.height, settings.tile_size);
    let job = Job {
        width: settings.width,
        first_sample: settings.first_sample,
        count,
        jitter: settings.jitter,
        aovs: settings.aovs,
        adaptive: settings.target_error.is_some(),
    };
    let acc = &*accumulation;
    let target = settings.target_error;
    let results: Vec<TileResult> = match camera {
        ActiveCamera::Pinhole(c) => tiles.par_iter().map(|t| trace_tile(&scene, &c, *t, &job, acc, target)).collect(),
        ActiveCamera::ThinLens(c) => tiles.par_iter().map(|t| trace_tile(&scene, &c, *t, &job, acc, target)).collect(),
        ActiveCamera::Orthographic(c) => {
            tiles.par_iter().map(|t| trace_tile(&scene, &c, *t, &job, acc, target)).collect()
        }
    };

    let frame = &mut *frame;
    frame.sums.resize(settings.pixel_count(), Vec3::ZERO);
    frame.counts.resize(settings.pixel_count(), 0);
    frame.sq_sums.resize(settings.pixel_count(), 0.0);
    frame.aovs.resize(if settings.aovs { settings.pixel_count() } else { 0 }, [0.0; AOV_FLOATS]);
    frame.samples_per_pixel = count;
    frame.active_pixels = results.iter().map(|r| r.counts.iter().filter(|&&c| c > 0).count()).sum();
    let mut rays = RayCounts::default();
    let mut split = TraceSplit::default();
    let mut traversal = TraversalCounts::default();
    let mut alpha = AlphaCounts::default();
    for (tile, result) in tiles.iter().zip(&results) {
        let w = (tile.x1 - tile.x0) as usize;
        for (row, y) in (tile.y0..tile.y1).enumerate() {
            let dst = (y * settings.width + tile.x0) as usize;
            let src = row * w..(row + 1) * w;
            frame.sums[dst..dst + w].copy_from_slice(&result.sums[src.clone()]);
            frame.counts[dst..dst + w].copy_from_slice(&result.counts[src.clone()]);
            frame.sq_sums[dst..dst + w].copy_from_slice(&result.sq_sums[src]);
            if settings.aovs {
                frame.aovs[dst..dst + w].copy_from_slice(&result.aovs[row * w..(row + 1) * w]);
            }
        }
        rays.add(&result.rays);
        split.add(&result.split);
        traversal.add(&result.traversal);
        alpha.add(&result.alpha);
        stats.nonfinite_samples += result.nonfinite;
    }
    stats.rays = rays;
    stats.trace_split = split;
    stats.traversal = traversal;
    stats.alpha = alpha;
    stats.samples_traced = count;
    let note = format!("{} tiles, {count} spp, {}", tiles.len(), lights.summary());
    stats.record("trace", start.elapsed(), note);
}

/// Whether every component of `v` is finite, in one SIMD compare: x · 0 is ±0 exactly when x
/// is finite (NaN for ±∞ and NaN).
#[inline(always)]
fn all_finite(v: Vec3A) -> bool {
    (v * 0.0).cmpeq(Vec3A::ZERO).all()
}

/// Tiles covering the image in row-major order.
fn tiles(width: u32, height: u32, size: u32) -> Vec<Tile> {
    let mut tiles = Vec::new();
    for y0 in (0..height).step_by(size as usize) {
        for x0 in (0..width).step_by(size as usize) {
            tiles.push(Tile { x0, y0, x1: (x0 + size).min(width), y1: (y0 + size).min(height) });
        }
    }
    tiles
}

/// What every tile of this frame traces.
struct Job {
    width: u32,
    /// Global index of the accumulation's first sample.
    first_sample: u32,
    count: u32,
    jitter: bool,
    aovs: bool,
    adaptive: bool,
}

fn trace_tile<C: CameraRays>(
    scene: &Scene,
    camera: &C,
    tile: Tile,
    job: &Job,
    acc: &Accumulation,
    target: Option<f32>,
) -> TileResult {
    // Counts from this thread's earlier work are not this tile's.
    counters::take();
    AlphaCounts::take();
    let mut tracer = Tracer::default();
    // One pixel's samples of this frame.
    let mut samples = Vec::with_capacity(job.count as usize);
    let (mut films, mut lenses, mut hits, mut radiance) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut camera_rays = Vec::new();
    let mut nonfinite = 0;
    let pixels = ((tile.x1 - tile.x0) * (tile.y1 - tile.y0)) as usize;
    let mut sums = Vec::with_capacity(pixels);
    let mut counts = Vec::with_capacity(pixels);
    let mut sq_sums = Vec::with_capacity(pixels);
    let mut aovs = Vec::with_capacity(if job.aovs { pixels } else { 0 });
    // Without jitter or lens every sample of a pixel has the same camera ray: it is traced once
    // per pixel, a row of the tile's pixels at a time (neighbouring rays travel together).
    let one_ray_per_pixel = !job.jitter && !C::USES_LENS;
    let (mut row_hits, mut row_pixels, mut row_fixed) = (Vec::new(), Vec::new(), Vec::new());
    for y in tile.y0..tile.y1 {
        if one_ray_per_pixel {
            camera_rays.clear();
            row_pixels.clear();
            let (mut timed, start) = (0, cycle_count());
            for x in tile.x0..tile.x1 {
                let pixel = y * job.width + x;
                if !acc.pixel_done(pixel as usize, target) {
                    camera_rays.push(camera.ray(x, y, Vec2::splat(0.5), Vec2::ZERO));
                    row_pixels.push((pixel, job.first_sample.wrapping_add(acc.counts[pixel as usize])));
                    timed += u64::from(timed_pixel(pixel));
                }
            }
            tracer.primaries(scene, &camera_rays, &mut row_hits);
            // The lights that draw no samples, once per pixel, the row's shadow rays together.
            tracer.fixed_lights_row(scene, &row_pixels, &row_hits, !job.aovs, timed, &mut row_fixed);
            // The timed pixels' part of the row's camera rays and fixed lights.
            if timed > 0 {
                tracer.split.pixels += cycles_since(start) * timed / camera_rays.len() as u64;
            }
        }
        let row_len = row_hits.len();
        let mut row_hits = row_hits.iter().enumerate();
        for x in tile.x0..tile.x1 {
            let pixel = y * job.width + x;
            tracer.timing = timed_pixel(pixel);
            tracer.timing_queries = query_timed_pixel(pixel);
            let start = tracer.timing.then(cycle_count);
            let mut sum = Vec3::ZERO;
            let mut sq_sum = 0.0;
            let mut aov = [0.0; AOV_FLOATS];
            // A pixel's samples are numbered 0, 1, … (from `first_sample` for a part of a
            // render) whatever the others do (adaptive sampling retires pixels independently).
            let first = job.first_sample.wrapping_add(acc.counts[pixel as usize]);
            let count = if acc.pixel_done(pixel as usize, target) { 0 } else { job.count };
            if count == 0 {
                sums.push(sum);
                counts.push(0);
                sq_sums.push(0.0);
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
                    // (no `samples` for the loop below).
                    let mut fixed_radiance = [Vec3A::ZERO];
                    tracer.shade_fixed(scene, hit, true, fixed_light(k), &mut fixed_radiance[..]);
                    let fixed_radiance = fixed_radiance[0];
                    // Without adaptive sampling (which needs each sample's luminance) the
                    // samples' sum alone, made without per-sample values where the lights allow
                    // ([`Tracer::shade_sum`]). A finite sum means every sample was finite (∞ and
                    // NaN survive a sum); otherwise the samples are made (and their rays traced
                    // and counted) again, one by one, and the non-finite ones dropped.
                    let quick = (!job.adaptive)
                        .then(|| tracer.shade_sum(scene, hit, pixel, first, count) + fixed_radiance * count as f32)
                        .filter(|&t| all_finite(t));
                    let total = quick.unwrap_or_else(|| {
                        radiance.resize(count as usize, Vec3A::ZERO);
                        tracer.shade(scene, hit, pixel, first, true, &mut radiance[..]);
                        let mut total = Vec3A::ZERO;
                        for &r in &radiance {
                            let r = r + fixed_radiance;
                            if !all_finite(r) {
                                nonfinite += 1;
                                continue;
                            }
                            total += r;
                            if job.adaptive {
                                sq_sum += luminance(r.into()).powi(2);
                            }
                        }
                        total
                    });
                    sum = total.into();
                    samples.clear();
                }
                Some((k, Some(hit))) => {
                    tracer.shade_fixed(scene, hit, !job.aovs, fixed_light(k), std::slice::from_mut(&mut fixed));
                    // `shade` sets every field of every sample: no need to clear them first.
                    samples.resize(count as usize, SampleResult::default());
                    tracer.shade(scene, hit, pixel, first, !job.aovs, &mut samples[..]);
                }
                Some((_, None)) => {
                    samples.clear();
                    samples.resize(count as usize, SampleResult { radiance: scene.background, ..Default::default() })
                }
                None => {
                    // Every sample has a camera ray of its own: compute the run's samples of
                    // every dimension ahead, trace the camera rays, then light every hit, one
                    // call per light type for the whole run.
                    films.clear();
                    films.resize(count as usize, Vec2::splat(0.5));
                    lenses.clear();
                    lenses.resize(count as usize, Vec2::ZERO);
                    if job.jitter {
                        scene.sets.fill(pixel, first, dims::PIXEL, &mut films);
                    }
                    if C::USES_LENS {
                        scene.sets.fill(pixel, first, dims::LENS, &mut lenses);
                    }
                    tracer.prepare_run(scene, pixel, first, count);
                    camera_rays.clear();
                    camera_rays.extend((0..count as usize).map(|j| camera.ray(x, y, films[j], lenses[j])));
                    tracer.primaries(scene, &camera_rays, &mut hits);
                    samples.resize(count as usize, SampleResult::default());
                    tracer.shade_run(scene, &hits, pixel, first, !job.aovs, &mut samples);
                }
            }
            for s in &samples {
                let s = &SampleResult { radiance: s.radiance + fixed.radiance, direct: s.direct + fixed.direct, ..*s };
                let values = job.aovs.then(|| s.aov_values());
                if !all_finite(s.radiance.into()) || values.is_some_and(|v| v.iter().any(|x| !x.is_finite())) {
                    nonfinite += 1;
                    continue;
                }
                sum += s.radiance;
                if job.adaptive {
                    sq_sum += luminance(s.radiance).powi(2);
                }
                if let Some(values) = values {
                    aov.iter_mut().zip(values).for_each(|(a, v)| *a += v);
                }
            }
            sums.push(sum);
            counts.push(count);
            sq_sums.push(sq_sum);
            if job.aovs {
                aovs.push(aov);
            }
            if let Some(start) = start {
                tracer.split.pixels += cycles_since(start);
            }
        }
    }
    let (traversal, alpha) = (counters::take(), AlphaCounts::take());
    TileResult { sums, counts, sq_sums, aovs, rays: tracer.rays, split: tracer.split, traversal, alpha, nonfinite }
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
