//! Per-frame cost of animated scenes: each iteration advances time one frame (1/24 s), runs the
//! animation, skinning and BVH systems, and traces 4 spp at 320×180. After each benchmark the
//! share of the frame spent on BVH upkeep (BLAS refits + TLAS rebuild) is printed.
//!
//! Run with `cargo bench --bench animation`.

use std::{path::Path, sync::Arc, time::Duration};

use divan::Bencher;
use hemi::{
    prelude::*,
    scene::gltf::{self, SpawnOptions},
};

fn main() {
    divan::main();
}

fn asset(rel: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets").join(rel)
}

fn settings() -> RenderSettings {
    RenderSettings { width: 320, height: 180, samples_per_frame: 4, samples_per_set: 4, ..Default::default() }
}

fn gltf_scene(rel: &str) -> Renderer {
    let scene = gltf::load(&asset(rel)).expect("shared asset loads");
    let mut r = Renderer::new(settings());
    scene.spawn(r.world_mut(), &SpawnOptions::default()).unwrap();
    r.run_frame().unwrap();
    r
}

/// 1,000 copies of the Stanford bunny (one shared 69k-triangle BLAS) on a 10×10×10 grid, each
/// spinning about its own axis, with a camera that sees them all.
fn bunnies() -> (Renderer, Vec<Entity>) {
    let scene = gltf::load(&asset("StanfordBunny/bunny.glb")).expect("bunny loads");
    let mesh = scene.meshes.iter().flatten().next().unwrap().mesh.clone();
    let mut r = Renderer::new(settings());
    let w = r.world_mut();
    w.spawn(Camera::look_at(Vec3::new(1.6, 1.2, 2.2), Vec3::splat(0.45), 40.0));
    w.spawn(AmbientOccluder::default());
    let entities = (0..1000)
        .map(|i| {
            let p = Vec3::new((i % 10) as f32, ((i / 10) % 10) as f32, (i / 100) as f32) * 0.1;
            w.spawn((TriangleMesh(Arc::clone(&mesh)), Transform::from_translation(p))).id()
        })
        .collect();
    r.run_frame().unwrap();
    (r, entities)
}

/// Runs `frame` under divan and prints the mean BVH share of the frame time.
fn measure(bencher: Bencher, name: &str, mut frame: impl FnMut(u32) -> (Duration, Duration, Duration)) {
    let mut n = 0;
    let (mut bvh, mut anim, mut total) = (Duration::ZERO, Duration::ZERO, Duration::ZERO);
    bencher.bench_local(|| {
        n += 1;
        let (b, a, t) = frame(n);
        bvh += b;
        anim += a;
        total += t;
    });
    let ms = |d: Duration| d.as_secs_f64() * 1e3 / n as f64;
    eprintln!(
        "{name}: per frame bvh {:.3} ms, animation+skinning {:.3} ms, whole frame {:.2} ms: BVH {:.2} % of the frame",
        ms(bvh),
        ms(anim),
        ms(total),
        100.0 * bvh.as_secs_f64() / total.as_secs_f64()
    );
}

fn split(stats: &FrameStats) -> (Duration, Duration, Duration) {
    (stats.time_of("bvh"), stats.time_of("animation") + stats.time_of("skinning"), stats.total_time())
}

/// BoxAnimated: two node animations (translation + rotation), TLAS rebuild every frame.
#[divan::bench(sample_count = 20)]
fn box_animated(bencher: Bencher) {
    let mut r = gltf_scene("BoxAnimated/glTF-Binary/BoxAnimated.glb");
    measure(bencher, "BoxAnimated", |f| {
        r.set_time(f as f32 / 24.0).unwrap();
        split(r.run_frame().unwrap())
    });
}

/// Fox: a skinned mesh re-skinned and its BLAS refit every frame.
#[divan::bench(sample_count = 20)]
fn fox(bencher: Bencher) {
    let mut r = gltf_scene("Fox/glTF-Binary/Fox.glb");
    measure(bencher, "Fox", |f| {
        r.set_time(f as f32 / 24.0).unwrap();
        split(r.run_frame().unwrap())
    });
}

/// 1,000 moving bunny instances (69 M placed triangles): TLAS rebuild over 1,000 instances.
#[divan::bench(sample_count = 10)]
fn bunnies_1000_moving(bencher: Bencher) {
    let (mut r, entities) = bunnies();
    measure(bencher, "1000 bunnies", |f| {
        for (i, &e) in entities.iter().enumerate() {
            let mut t = r.world_mut().get_mut::<Transform>(e).unwrap();
            t.rotation = Quat::from_rotation_y(0.05 * f as f32 + i as f32);
        }
        split(r.run_frame().unwrap())
    });
}
