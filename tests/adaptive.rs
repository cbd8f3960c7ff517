//! Adaptive sampling's error estimate: the spread of a pixel's sample luminances, kept as
//! squared deviations from their mean and merged frame by frame, has no cancellation, so
//! pixels whose samples are all alike retire at the minimum however bright they are.

mod common;

use common::{occluder, settings, white};
use hemi::{
    glam::DVec3,
    integrator::TwoValues,
    prelude::*,
    resources::{Accumulation, LuminanceSpread, merge_deviations, standard_error},
};

/// Deterministic luminances in [level, level + spread).
fn luminances(n: usize, level: f32, spread: f32, seed: u64) -> Vec<f32> {
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            level + spread * ((state >> 40) as f32 / (1u64 << 24) as f32)
        })
        .collect()
}

/// Squared deviations about the mean, from the definition in f64.
fn two_pass(values: &[f32]) -> f64 {
    let mean = values.iter().map(|&v| v as f64).sum::<f64>() / values.len() as f64;
    values.iter().map(|&v| (v as f64 - mean).powi(2)).sum()
}

#[test]
fn frames_merge_into_the_spread_of_all_their_samples() {
    for (level, spread) in [(0.0, 1.0), (40.0, 0.5), (1e4, 1.0)] {
        let samples = luminances(16 + 8 + 32 + 1 + 7, level, spread, 3);
        let (mut deviations, mut count, mut sum) = (0.0, 0u32, DVec3::ZERO);
        let mut at = 0;
        for frame in [16, 8, 32, 1, 7] {
            let part = &samples[at..at + frame];
            // Grey samples: luminance is the channel value.
            let frame_sum = DVec3::splat(part.iter().map(|&l| l as f64).sum());
            let mut spread = LuminanceSpread::default();
            part.iter().for_each(|&l| spread.add(l));
            merge_deviations(&mut deviations, (count, sum), (frame as u32, frame_sum, spread.deviations()));
            count += frame as u32;
            sum += frame_sum;
            at += frame;
        }
        // Each frame's spread is summed in f32, about its first sample.
        let whole = two_pass(&samples);
        assert!((deviations - whole).abs() <= 1e-5 * whole, "level {level}: {deviations} against {whole}");
        let error = standard_error(count, deviations);
        let expected = (whole / (count as f64 * (count as f64 - 1.0))).sqrt();
        assert!((error - expected).abs() <= 1e-5 * expected, "{error} against {expected}");
    }
    // Samples all alike: no spread at any level.
    for level in [0.3, 37.0, 1e5] {
        let mut spread = LuminanceSpread::default();
        (0..16).for_each(|_| spread.add(level));
        assert_eq!(spread.deviations(), 0.0);
    }
}

#[test]
fn a_two_valued_run_has_the_spread_of_its_samples() {
    let (clear, floor) = (Vec3A::new(3.0, 2.0, 1.0), Vec3A::new(0.25, 0.5, 0.75));
    let lum = |v: Vec3A| hemi::resources::luminance(v.into());
    for dark in 0..=16 {
        let run = TwoValues { clear, floor, dark };
        let each: Vec<f32> = (0..16).map(|j| lum(if j < dark { floor } else { clear })).collect();
        let (got, expected) = (run.squared_deviations(16, lum), two_pass(&each));
        assert!((got - expected).abs() <= 1e-6 * expected.max(1e-6), "{dark} dark: {got} against {expected}");
        let sum: Vec3A = (0..16).map(|j| if j < dark { floor } else { clear }).sum();
        assert!((run.sum(16) - sum).abs().max_element() <= 1e-5, "{dark} dark");
    }
    // A run that varies plus one that does not still takes two values; two that vary do not.
    let constant = TwoValues { clear: Vec3A::ONE, floor: Vec3A::ONE, dark: 0 };
    let varying = TwoValues { clear, floor, dark: 5 };
    let both = varying.plus(&constant, 16).expect("one of them is constant");
    assert_eq!((both.clear, both.floor, both.dark), (clear + 1.0, floor + 1.0, 5));
    assert_eq!(constant.plus(&varying, 16), Some(both));
    assert_eq!(varying.plus(&TwoValues { dark: 16, ..varying }, 16).map(|v| v.floor), Some(floor + floor));
    assert_eq!(varying.plus(&varying, 16), None);
}

/// A flat floor under a bright occluder that nothing blocks: every sample of a pixel has the
/// same radiance (tens of units), made one by one (jittered pixels, where each sample has its
/// own camera hit) or known from a run's sum (pixel centres, with AOVs or without, a point
/// light adding its own light to each pixel's samples, the same for every sample). Every
/// pixel retires after the minimum of samples at a target error far below the rounding of a
/// sum of squares at that level.
#[test]
fn bright_pixels_without_variance_retire_at_the_minimum() {
    for ls in [37.0, 41.0, 53.0, 67.0, 89.0] {
        for (jitter, aovs) in [(true, false), (true, true), (false, false), (false, true)] {
            let s = RenderSettings {
                samples_per_frame: 16,
                samples_per_set: 64,
                max_spp: Some(256),
                target_error: Some(1e-4),
                jitter,
                aovs,
                ..settings(16, 16, 16, SamplerKind::MultiJittered)
            };
            let mut r = Renderer::new(s);
            let w = r.world_mut();
            w.spawn((Plane::default(), white()));
            w.spawn(Camera::look_at(Vec3::new(0.0, 3.0, 1.0), Vec3::ZERO, 40.0));
            w.spawn(AmbientOccluder { ls, ..occluder(0.0) });
            if !jitter {
                // Light that varies from pixel to pixel, not from sample to sample.
                w.spawn((PointLight { ls: 20.0, ..Default::default() }, Transform::from_xyz(0.5, 2.0, 0.0)));
            }
            let mut frames = 0;
            while !r.converged() && frames < 16 {
                r.run_frame().unwrap();
                frames += 1;
            }
            let bright = r.image().linear.iter().map(|c| c.min_element()).fold(f32::INFINITY, f32::min);
            assert!(bright > 10.0, "ls {ls}: the floor's radiance is {bright}");
            let acc = r.world().resource::<Accumulation>();
            let kept = acc.counts.iter().filter(|&&c| c != RenderSettings::ADAPTIVE_MIN_SPP).count();
            assert_eq!(kept, 0, "ls {ls}, jitter {jitter}, AOVs {aovs}: {kept} pixels went on sampling");
        }
    }
}
