//! hemi's occlusion queries on a fixed set of AO rays, one thread, and the rays written out so
//! that another engine can trace exactly the same ones (`scripts/compare-kernels.sh` feeds them
//! to Embree 4). Tracing only: no sampling, shading or frame around the queries.
//!
//! ```sh
//! cargo run --release --example kernel_rays -- SCENE.json RAYS.bin [RAYS_PER_POINT] [ROUNDS]
//! ```
//!
//! Rays: the camera ray through each pixel's centre finds a point; from it (pushed the scene's
//! `ao.epsilon` along the normal, as the renderer does) leave
//! `RAYS_PER_POINT` (default 4) cosine-distributed rays as long as the scene's
//! `ao.max_distance` (unbounded where it is null; SplitMix64 seed 5). Four orders of the same
//! rays are timed, each as the best of `ROUNDS` (default 3) passes: one at a time in point
//! order, one at a time in a shuffled order, in packets of 16 consecutive rays from a few points
//! (point order), and in packets of 16 from 16 neighbouring points, one ray each (sample order:
//! how Mitsuba's wavefront groups its rays).
//!
//! RAYS.bin, little-endian: u64 triangle count, 9 f32 per triangle; u64 ray count, u32 rays
//! per point, 6 f32 per ray (origin, direction) in point order; the shuffled order as u32; the
//! rays' length as f32 (+∞ for none).

use std::{io::Write, path::Path, process::ExitCode, time::Instant};

use hemi::{
    camera::PinholeRays,
    cli::peer_scene::PeerScene,
    geometry::{Ray, RayOrder, SceneGeometry, Shape},
    math::Onb,
    prelude::*,
    random::SplitMix64,
    sampling::warp::cosine_power_hemisphere,
};

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("kernel_rays: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: kernel_rays SCENE.json RAYS.bin [RAYS_PER_POINT] [ROUNDS]";
    let (Some(scene_path), Some(out)) = (args.first(), args.get(1)) else { return Err(usage.into()) };
    let number = |i: usize, default: usize| -> Result<usize, String> {
        args.get(i).map_or(Ok(default), |a| match a.parse() {
            Ok(n) if n > 0 => Ok(n),
            _ => Err(format!("'{a}' is not a positive whole number ({usage})")),
        })
    };
    let (per_point, rounds) = (number(2, 4)?, number(3, 3)?);
    let scene = PeerScene::load(Path::new(scene_path)).map_err(|e| e.to_string())?;
    let geometry = scene_geometry(&scene)?;
    let rays = ao_rays(&scene, &geometry, per_point)?;
    let shuffled = shuffled_order(rays.len());
    write_rays(Path::new(out), &geometry, &rays, per_point, &shuffled, scene.max_distance)?;

    let mut stack = Vec::new();
    let single = |order: &mut dyn Iterator<Item = &Ray>, stack: &mut Vec<(u32, f32)>| {
        order.fold(0, |n, ray| n + geometry.occluded(ray, stack) as usize)
    };
    let packets = |rays: &[Ray], stack: &mut Vec<(u32, f32)>| {
        let mut blocked = vec![false; rays.len()];
        for (packet, b) in rays.chunks(16).zip(blocked.chunks_mut(16)) {
            geometry.occluded_many(packet, RayOrder::Grouped, stack, b);
        }
        blocked.iter().filter(|&&b| b).count()
    };
    let by_sample = sample_order(&rays, per_point);
    let results = [
        best_of(rounds, rays.len(), || single(&mut rays.iter(), &mut stack)),
        best_of(rounds, rays.len(), || single(&mut shuffled.iter().map(|&i| &rays[i as usize]), &mut stack)),
        best_of(rounds, rays.len(), || packets(&rays, &mut stack)),
        best_of(rounds, rays.len(), || packets(&by_sample, &mut stack)),
    ];
    let blocked = results[0].1;
    if results.iter().any(|r| r.1 != blocked) {
        return Err(format!("the orders disagree on how many rays are blocked: {results:?}"));
    }
    println!(
        "hemi   {} rays, {blocked} blocked; Mrays/s, one thread: single {:.2}, single shuffled {:.2}, \
         packets of 16 (point order) {:.2}, packets of 16 (sample order) {:.2}",
        rays.len(),
        results[0].0,
        results[1].0,
        results[2].0,
        results[3].0
    );
    Ok(())
}

/// The scene's geometry as the renderer builds it (one frame at a tiny size, one thread).
fn scene_geometry(scene: &PeerScene) -> Result<SceneGeometry, String> {
    let settings = RenderSettings { width: 8, height: 8, samples_per_frame: 1, ..Default::default() };
    let mut r = Renderer::new(settings).with_threads(1).map_err(|e| e.to_string())?;
    scene.spawn(r.world_mut()).map_err(|e| e.to_string())?;
    r.run_frame().map_err(|e| e.to_string())?;
    Ok(r.world().resource::<SceneGeometry>().clone())
}

/// `per_point` cosine-distributed rays from the point each pixel's centre sees.
fn ao_rays(scene: &PeerScene, geometry: &SceneGeometry, per_point: usize) -> Result<Vec<Ray>, String> {
    let cam = PinholeRays::new(&scene.camera, scene.width, scene.height).map_err(|e| e.to_string())?;
    let mut rng = SplitMix64::new(5);
    let mut stack = Vec::new();
    let mut rays = Vec::new();
    for y in 0..scene.height {
        for x in 0..scene.width {
            let Some(hit) = geometry.intersect(&cam.ray(x, y, Vec2::splat(0.5)), &mut stack) else { continue };
            let onb = Onb::from_normal(hit.normal.into());
            // The renderer's origins for this scene: `ao.epsilon` along the normal.
            let spawn = hit.spawn_origins(scene.epsilon);
            for _ in 0..per_point {
                let s = cosine_power_hemisphere(Vec2::new(rng.next_f32(), rng.next_f32()), 1.0);
                let w = glam::Vec3A::from(onb.to_world(s.dir));
                rays.push(Ray::new(spawn.towards(w), w, scene.max_distance));
            }
        }
    }
    Ok(rays)
}

/// A shuffle of `0..n` (Fisher–Yates, SplitMix64 seed 7).
fn shuffled_order(n: usize) -> Vec<u32> {
    let mut rng = SplitMix64::new(7);
    let mut order: Vec<u32> = (0..n as u32).collect();
    for i in (1..n).rev() {
        order.swap(i, (rng.next_u64() % (i as u64 + 1)) as usize);
    }
    order
}

/// The rays in sample order: every point's first ray, then every point's second, and so on.
fn sample_order(rays: &[Ray], per_point: usize) -> Vec<Ray> {
    let points = rays.len() / per_point;
    (0..rays.len()).map(|i| rays[(i % points) * per_point + i / points]).collect()
}

/// Rays per second (millions) of the fastest of `rounds` runs of `trace`, and its answer.
fn best_of(rounds: usize, rays: usize, mut trace: impl FnMut() -> usize) -> (f64, usize) {
    let mut best = f64::INFINITY;
    let mut answer = 0;
    for _ in 0..rounds {
        let start = Instant::now();
        answer = trace();
        best = best.min(start.elapsed().as_secs_f64());
    }
    (rays as f64 / best / 1e6, answer)
}

fn write_rays(
    path: &Path,
    geometry: &SceneGeometry,
    rays: &[Ray],
    per_point: usize,
    order: &[u32],
    length: f32,
) -> Result<(), String> {
    let fail = |e: std::io::Error| format!("{}: {e}", path.display());
    let mut f = std::io::BufWriter::new(std::fs::File::create(path).map_err(fail)?);
    let prims = geometry.world_prims();
    let triangles: Vec<[f32; 9]> = prims
        .iter()
        .filter_map(|p| match p.shape {
            Shape::Triangle(t) => Some(std::array::from_fn(|k| t.p[k / 3][k % 3])),
            Shape::Sphere(_) => None,
        })
        .collect();
    if geometry.plane_count() > 0 || triangles.len() != prims.len() {
        return Err("the scene holds planes or spheres; only triangle meshes can be compared".into());
    }
    let mut bytes = Vec::new();
    bytes.extend((triangles.len() as u64).to_le_bytes());
    bytes.extend(triangles.iter().flatten().flat_map(|v| v.to_le_bytes()));
    bytes.extend((rays.len() as u64).to_le_bytes());
    bytes.extend((per_point as u32).to_le_bytes());
    for ray in rays {
        bytes.extend(ray.origin.to_array().iter().chain(&ray.dir.to_array()).flat_map(|v| v.to_le_bytes()));
    }
    bytes.extend(order.iter().flat_map(|i| i.to_le_bytes()));
    bytes.extend(length.to_le_bytes());
    f.write_all(&bytes).map_err(fail)?;
    f.flush().map_err(fail)
}
