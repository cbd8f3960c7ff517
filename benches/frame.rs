//! Benchmarks: a whole frame of the default scene, each system on its own, BVH builds by size,
//! sample-set generation, and raw AO-ray throughput (rays/s shown as items/s).
//!
//! Run with `cargo bench --bench frame`; filter with e.g. `cargo bench --bench frame -- ao_rays`.

use std::sync::Arc;

use divan::{Bencher, counter::ItemsCount};
use hemi::{
    bevy_ecs::system::RunSystemOnce,
    camera::PinholeRays,
    geometry::{Object, Ray, SceneGeometry, world_space},
    math::Onb,
    prelude::*,
    random::SplitMix64,
    sampling::{SampleSets, warp::cosine_power_hemisphere},
    scene::mesh_gen::torus_knot,
    systems::{accumulate, resolve, trace},
};

fn main() {
    divan::main();
}

fn default_scene(width: u32, height: u32) -> Renderer {
    default_scene_spp(width, height, 1)
}

fn default_scene_spp(width: u32, height: u32, spp: u32) -> Renderer {
    let settings = RenderSettings { width, height, samples_per_frame: spp, samples_per_set: 16, ..Default::default() };
    let mut r = Renderer::with_default_scene(settings);
    r.run_frame().unwrap();
    r
}

/// One whole frame (all six systems) of the default scene at 320×180, 1 spp, static scene.
#[divan::bench(sample_count = 20)]
fn frame_320x180_1spp(bencher: Bencher) {
    let mut r = default_scene(320, 180);
    bencher.counter(ItemsCount::new(320 * 180u32)).bench_local(|| {
        r.run_frame().unwrap();
    });
}

/// The trace system alone (320×180, 1 spp): primary + AO + shadow rays.
#[divan::bench(sample_count = 20)]
fn system_trace_320x180_1spp(bencher: Bencher) {
    let mut r = default_scene(320, 180);
    bencher.bench_local(|| r.world_mut().run_system_once(trace::trace).unwrap());
}

/// How the trace system's cost grows with pixels: the default scene at 1 spp, width w and
/// height 9w/16 (items: pixels).
#[divan::bench(args = [160, 320, 640], sample_count = 10)]
fn system_trace_by_width(bencher: Bencher, width: u32) {
    let mut r = default_scene(width, width * 9 / 16);
    bencher
        .counter(ItemsCount::new(width * width * 9 / 16))
        .bench_local(|| r.world_mut().run_system_once(trace::trace).unwrap());
}

/// How the trace system's cost grows with samples per pixel: the default scene at 160×90
/// (items: samples).
#[divan::bench(args = [1, 4, 16], sample_count = 10)]
fn system_trace_by_spp(bencher: Bencher, spp: u32) {
    let mut r = default_scene_spp(160, 90, spp);
    bencher
        .counter(ItemsCount::new(160 * 90 * spp))
        .bench_local(|| r.world_mut().run_system_once(trace::trace).unwrap());
}

/// The accumulate system alone (640×360).
#[divan::bench(sample_count = 50)]
fn system_accumulate_640x360(bencher: Bencher) {
    let mut r = default_scene(640, 360);
    bencher.bench_local(|| r.world_mut().run_system_once(accumulate::accumulate).unwrap());
}

/// The resolve system alone (640×360).
#[divan::bench(sample_count = 50)]
fn system_resolve_640x360(bencher: Bencher) {
    let mut r = default_scene(640, 360);
    bencher.bench_local(|| r.world_mut().run_system_once(resolve::resolve).unwrap());
}

/// Sample-set generation for each sampler kind (4096 sets × 64 points; for CMJ, the cosine
/// table of its 4096 patterns).
#[divan::bench(args = SamplerKind::ALL, sample_count = 20)]
fn system_sample_sets(bencher: Bencher, kind: SamplerKind) {
    bencher.bench(|| SampleSets::generate(kind, 64, 1, 640, 360));
}

/// Per-sample cost of each sampler: 64 samples for each of 1,024 pixels, one dimension (what
/// the trace system asks for per pixel, per light dimension). CMJ and ZSobol compute their
/// points; the others read stored sets.
#[divan::bench(args = SamplerKind::ALL, sample_count = 20)]
fn samples_fill_64k(bencher: Bencher, kind: SamplerKind) {
    let sets = SampleSets::generate(kind, 64, 1, 640, 360);
    let mut out = vec![glam::Vec2::ZERO; 64];
    bencher.bench_local(|| {
        for pixel in 0..1024 {
            sets.fill(pixel * 97, 0, 2, &mut out);
            divan::black_box(&out);
        }
    });
}

/// BVH build over n triangles (copies of a torus knot on a grid).
#[divan::bench(args = [10_000, 100_000, 1_000_000], sample_count = 3)]
fn system_bvh_build(bencher: Bencher, triangles: usize) {
    let knot = Arc::new(torus_knot(2, 3, 0.8, 0.2, 250, 20)); // 10,000 triangles
    let copies = triangles.div_ceil(knot.triangle_count());
    let mut prims = Vec::new();
    let mut objects = Vec::new();
    for i in 0..copies {
        let t = Transform::from_xyz((i % 10) as f32 * 3.0, 0.0, (i / 10) as f32 * 3.0);
        prims.extend(world_space::mesh(&knot, &t, i as u32).unwrap().prims);
        objects.push(Object { entity: Entity::PLACEHOLDER, material: Matte::default() });
    }
    bencher
        .counter(ItemsCount::new(prims.len()))
        .bench(|| SceneGeometry::build(prims.clone(), vec![], objects.clone()));
}

/// Cosine-distributed AO rays leaving the visible surface of the default scene (160×90, 8 per
/// pixel), with the scene's geometry.
fn ao_rays() -> (SceneGeometry, Vec<Ray>) {
    let mut r = default_scene(160, 90);
    let geometry = r.world().resource::<SceneGeometry>().clone();
    let mut cameras = r.world_mut().query::<&Camera>();
    let camera = *cameras.single(r.world()).unwrap();
    let cam = PinholeRays::new(&camera, 160, 90).unwrap();
    let mut rng = SplitMix64::new(5);
    let mut stack = Vec::new();
    let mut rays = Vec::new();
    for y in 0..90 {
        for x in 0..160 {
            let Some(hit) = geometry.intersect(&cam.ray(x, y, glam::Vec2::splat(0.5)), &mut stack) else { continue };
            for _ in 0..8 {
                let s = cosine_power_hemisphere(glam::Vec2::new(rng.next_f32(), rng.next_f32()), 1.0);
                let w = glam::Vec3A::from(Onb::from_normal(hit.normal.into()).to_world(s.dir));
                rays.push(Ray::new(hit.spawn_origin(w), w, f32::INFINITY));
            }
        }
    }
    (geometry, rays)
}

/// How AO-ray cost grows with triangles: one torus knot tessellated to about n near-square
/// triangles, 8 cosine-distributed rays leaving each of 10,000 random points on it (items: rays).
#[divan::bench(args = [10_000, 100_000, 1_000_000], sample_count = 5)]
fn ao_rays_by_triangles(bencher: Bencher, triangles: u32) {
    // Near-square triangles: the tube's length is about ten times its circumference.
    let sides = (triangles as f32 / 20.0).sqrt().round() as u32;
    let knot = torus_knot(2, 3, 0.8, 0.2, 10 * sides, sides);
    let prims = world_space::mesh(&knot, &Transform::IDENTITY, 0).unwrap().prims;
    let object = Object { entity: Entity::PLACEHOLDER, material: Matte::default() };
    let geometry = SceneGeometry::build(prims, vec![], vec![object]);
    let mut rng = SplitMix64::new(9);
    let mut stack = Vec::new();
    let mut rays = Vec::new();
    while rays.len() < 80_000 {
        // Rays from outside towards the knot's centre find points on its surface.
        let p = glam::Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        let Some(hit) = geometry.intersect(&Ray::new(p * 4.0, -p, f32::INFINITY), &mut stack) else { continue };
        for _ in 0..8 {
            let s = cosine_power_hemisphere(glam::Vec2::new(rng.next_f32(), rng.next_f32()), 1.0);
            let w = glam::Vec3A::from(Onb::from_normal(hit.normal.into()).to_world(s.dir));
            rays.push(Ray::new(hit.spawn_origin(w), w, f32::INFINITY));
        }
    }
    bencher
        .counter(ItemsCount::new(rays.len()))
        .bench_local(|| rays.iter().filter(|ray| geometry.occluded(ray, &mut stack)).count());
}

/// AO occlusion queries through hemi's BVH traversal, one thread.
#[divan::bench(sample_count = 20)]
fn ao_rays_default_scene(bencher: Bencher) {
    let (geometry, rays) = ao_rays();
    let mut stack = Vec::new();
    bencher
        .counter(ItemsCount::new(rays.len()))
        .bench_local(|| rays.iter().filter(|ray| geometry.occluded(ray, &mut stack)).count());
}

/// The same queries through obvhs's CWBVH (`ray_traverse_miss`, SSE2 node tests) over the same
/// primitives and intersection routines: the yardstick for choosing the BVH layout.
#[divan::bench(sample_count = 20)]
fn ao_rays_default_scene_obvhs_cwbvh(bencher: Bencher) {
    use obvhs::{BvhBuildParams, cwbvh::builder::build_cwbvh};
    let (geometry, rays) = ao_rays();
    let world = geometry.world_prims();
    let aabbs: Vec<_> = world.iter().map(|p| p.bounds()).collect();
    let bvh = build_cwbvh(&aabbs, BvhBuildParams::medium_build(), &mut std::time::Duration::default());
    let prims: Vec<_> = bvh.primitive_indices.iter().map(|&i| world[i as usize]).collect();
    // The default scene's only plane is the ground y = 0, below every AO ray origin.
    assert_eq!(geometry.plane_count(), 1);
    let obvhs_rays: Vec<_> = rays.iter().map(|r| obvhs::ray::Ray::new(r.origin, r.dir, 0.0, r.tmax)).collect();
    bencher.counter(ItemsCount::new(rays.len())).bench_local(|| {
        let mut blocked = 0;
        for (ray, o) in rays.iter().zip(&obvhs_rays) {
            // The plane test first, as hemi does: a downward ray always meets the ground.
            if ray.dir.y < 0.0 {
                blocked += 1;
                continue;
            }
            let free = bvh
                .ray_traverse_miss(*o, |_, id| SceneGeometry::hit_prim(&prims[id], ray).map_or(f32::INFINITY, |h| h.0));
            blocked += usize::from(!free);
        }
        blocked
    });
}
