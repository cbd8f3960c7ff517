//! Pixels' errors are independent: over many seeds, the variance of a block of pixels' mean
//! matches what the pixels' own variances predict for independent errors. Pixels that draw the
//! same pattern trace the same directions unless their frames differ; without the per-pixel
//! symmetry of the frame the default sampler's 128×128 blocks vary about twice as much.

mod common;

use common::settings;
use hemi::{analytic::AnalyticScene, prelude::*};

const SIZE: usize = 256;
const SEEDS: u64 = 32;

/// The AO image of the floor beside a long wall (AO varies across the image, as it does on
/// any real floor), pixel centres only, `spp` samples.
fn wall_floor(sampler: SamplerKind, spp: u32, seed: u64) -> Vec<f64> {
    let mut s = settings(SIZE as u32, SIZE as u32, spp, sampler);
    s.seed = seed;
    s.jitter = false;
    let mut r = Renderer::new(s);
    let w = r.world_mut();
    AnalyticScene::Wall.spawn(w, 1.0, Vec3::ZERO);
    let cameras: Vec<Entity> = w.query_filtered::<Entity, With<Camera>>().iter(w).collect();
    for camera in cameras {
        w.despawn(camera);
    }
    // Straight down at the floor 0.2 to 3 from the wall's face.
    w.spawn(Camera {
        eye: Vec3::new(0.0, 40.0, 1.6),
        target: Vec3::new(0.0, 0.0, 1.6),
        up: Vec3::NEG_X,
        vfov_degrees: 4.0,
    });
    r.run_frame().expect("scene is valid");
    r.image().linear.iter().map(|p| f64::from(p.x)).collect()
}

/// Sample variance of `values`.
fn variance(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = values.clone().count() as f64;
    let mean = values.clone().sum::<f64>() / n;
    values.map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0)
}

/// The variance of `block`×`block` means over the seeds, times block², over the mean pixel
/// variance: 1 for independent errors, more for positively correlated ones, less for blue
/// noise. Averaged over the image's blocks.
fn block_variance_ratio(images: &[Vec<f64>], block: usize) -> f64 {
    let pixel = (0..SIZE * SIZE).map(|i| variance(images.iter().map(|im| im[i]))).sum::<f64>() / (SIZE * SIZE) as f64;
    let blocks = SIZE / block;
    let mut sum = 0.0;
    for by in 0..blocks {
        for bx in 0..blocks {
            let means = images.iter().map(|im| {
                let rows = (0..block).map(|y| (by * block + y) * SIZE + bx * block);
                rows.flat_map(|row| im[row..row + block].iter()).sum::<f64>() / (block * block) as f64
            });
            sum += variance(means) * (block * block) as f64 / pixel;
        }
    }
    sum / (blocks * blocks) as f64
}

/// The default sampler's errors are independent at every scale: 8×8 blocks (1024 of them,
/// so the ratio's spread is ±0.01) and 128×128 blocks (4, ±0.13), where pixels that share a
/// pattern meet.
#[test]
fn default_sampler_errors_are_independent_between_pixels() {
    let images: Vec<_> = (1..=SEEDS).map(|seed| wall_floor(SamplerKind::CorrelatedMultiJittered, 16, seed)).collect();
    let small = block_variance_ratio(&images, 8);
    let large = block_variance_ratio(&images, 128);
    eprintln!("cmj: 8×8 {small:.3}, 128×128 {large:.3}");
    assert!((small - 1.0).abs() < 0.06, "8×8 blocks vary {small:.3} times as independent pixels predict");
    assert!((large - 1.0).abs() < 0.35, "128×128 blocks vary {large:.3} times as independent pixels predict");
}

/// ZSobol's errors are blue noise: neighbouring pixels' errors cancel, so blocks vary less
/// than independent pixels would make them.
#[test]
fn zsobol_errors_cancel_between_neighbours() {
    let images: Vec<_> = (1..=SEEDS).map(|seed| wall_floor(SamplerKind::ZSobol, 16, seed)).collect();
    let small = block_variance_ratio(&images, 8);
    eprintln!("zsobol: 8×8 {small:.3}");
    assert!(small < 0.5, "8×8 blocks vary {small:.3} times as independent pixels predict");
}
