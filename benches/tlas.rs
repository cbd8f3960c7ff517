//! Top-level BVH build time over n instances of one small BLAS, spread on a grid or all at
//! the same position (co-located instances must not make the build quadratic).
//!
//! Run with `cargo bench --bench tlas`.

use std::sync::Arc;

use divan::Bencher;
use hemi::geometry::{
    Prim, SceneGeometry, Shape,
    accel::{Blas, Instance},
    shapes::SpherePrim,
};
use hemi::glam::{Affine3A, Vec3, Vec3A};

fn main() {
    divan::main();
}

fn instances(n: usize, co_located: bool) -> (Vec<Arc<Blas>>, Vec<Instance>) {
    let sphere = Prim { shape: Shape::Sphere(SpherePrim { center: Vec3A::ZERO, radius: 0.5 }), object: 0 };
    let blas = Arc::new(Blas::build(vec![sphere]));
    let local = blas.bounds().expect("one sphere has bounds");
    let side = (n as f32).cbrt().ceil() as usize;
    let instances = (0..n)
        .map(|i| {
            let at = if co_located {
                Vec3::ZERO
            } else {
                Vec3::new((i % side) as f32, (i / side % side) as f32, (i / (side * side)) as f32) * 2.0
            };
            Instance::new(0, local, Affine3A::from_translation(at), Some(0)).expect("finite instance")
        })
        .collect();
    (vec![blas], instances)
}

#[divan::bench(args = [10_000, 100_000, 1_000_000], sample_count = 3, sample_size = 1)]
fn spread(bencher: Bencher, n: usize) {
    bencher
        .with_inputs(|| instances(n, false))
        .bench_values(|(blases, inst)| SceneGeometry::from_instances(blases, inst, Vec::new(), Vec::new()));
}

#[divan::bench(args = [10_000, 100_000, 1_000_000], sample_count = 3, sample_size = 1)]
fn co_located(bencher: Bencher, n: usize) {
    bencher
        .with_inputs(|| instances(n, true))
        .bench_values(|(blases, inst)| SceneGeometry::from_instances(blases, inst, Vec::new(), Vec::new()));
}
