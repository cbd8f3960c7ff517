//! Sampling: the RTGU sample-set families, their maps to the disk and hemisphere, and a
//! stateless lookup `sample(pixel, index, dimension)` that replaces the book's shared
//! `count`/`jump` state.
//!
//! A [`SampleSets`] resource holds `num_sets` precomputed sets of `n` points. Sample index `i`
//! of a pixel belongs to pass `i / n`; for each (pixel, pass, dimension) a hash picks one set and
//! a hashed permutation (Kensler 2013) orders it, so the `n` samples of a pass are a whole,
//! stratified set, different in every pixel and dimension, and independent of tile order.

pub mod generators;
pub mod hash;
pub mod warp;

use bevy_ecs::prelude::Resource;
use glam::Vec2;

pub use generators::SamplerKind;
use hash::{SplitMix64, hash_sample, permute};

/// Sample dimensions: each consumer of 2-D samples owns one pair.
pub mod dims {
    /// Sub-pixel position of the primary ray.
    pub const PIXEL: u32 = 0;
    /// Lens position of a thin-lens camera.
    pub const LENS: u32 = 1;
    /// First light dimension: lights take theirs from here on, in registration order, then
    /// entity order (see [`crate::light`]).
    pub const LIGHTS: u32 = 2;
}

/// Precomputed sets of 2-D sample points for one sampler kind and set size.
#[derive(Resource, Clone, Debug)]
pub struct SampleSets {
    kind: SamplerKind,
    n: u32,
    num_sets: u32,
    seed: u64,
    points: Vec<Vec2>,
}

impl SampleSets {
    /// Most points kept in memory across all sets (32 MiB).
    const MAX_POINTS: usize = 1 << 22;
    /// Sets generated when memory allows: enough that pixels sharing a set are rare neighbours.
    const PREFERRED_SETS: u32 = 256;

    /// Generates the sets for `kind` with `n` points each, fixed by `seed`.
    pub fn generate(kind: SamplerKind, n: u32, seed: u64) -> Self {
        let n = n.max(1);
        let num_sets = if kind == SamplerKind::Regular {
            1
        } else {
            (Self::MAX_POINTS / n as usize).clamp(1, Self::PREFERRED_SETS as usize) as u32
        };
        let mut rng = SplitMix64::new(seed ^ 0x5eed_5e75);
        let mut points = Vec::with_capacity(n as usize * num_sets as usize);
        for _ in 0..num_sets {
            kind.generate(n, &mut rng, &mut points);
        }
        SampleSets { kind, n, num_sets, seed, points }
    }

    /// The pattern of these sets.
    pub fn kind(&self) -> SamplerKind {
        self.kind
    }

    /// Points per set.
    pub fn set_size(&self) -> u32 {
        self.n
    }

    /// Number of distinct sets.
    pub fn num_sets(&self) -> u32 {
        self.num_sets
    }

    /// Whether these sets were made for the given parameters.
    pub fn matches(&self, kind: SamplerKind, n: u32, seed: u64) -> bool {
        self.kind == kind && self.n == n.max(1) && self.seed == seed
    }

    /// Bytes held by the point sets.
    pub fn memory_bytes(&self) -> usize {
        self.points.len() * std::mem::size_of::<Vec2>()
    }

    /// The 2-D sample for (pixel, sample index, dimension): a pure function of its arguments
    /// and the sets, so images do not depend on scheduling.
    #[inline]
    pub fn sample(&self, pixel: u32, index: u32, dim: u32) -> Vec2 {
        let n = self.n;
        if self.kind == SamplerKind::Regular {
            return self.points[(index % n) as usize];
        }
        let pass = index / n;
        let h = hash_sample(pixel, pass, dim, self.seed);
        let set = (((h >> 32) * self.num_sets as u64) >> 32) as u32;
        let k = permute(index % n, n, h as u32);
        self.points[(set * n + k) as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_pixel_index_dimension_gives_the_same_value() {
        for kind in SamplerKind::ALL {
            let a = SampleSets::generate(kind, 16, 42);
            let b = SampleSets::generate(kind, 16, 42);
            for (p, i, d) in [(0, 0, 0), (17, 5, 1), (1000, 31, 2), (5, 100, 3)] {
                assert_eq!(a.sample(p, i, d), b.sample(p, i, d), "{kind:?}");
            }
        }
    }

    #[test]
    fn one_pass_of_a_pixel_is_a_whole_stratified_set() {
        // The 16 samples of one pass in one pixel fill all 4×4 jittered strata.
        let sets = SampleSets::generate(SamplerKind::Jittered, 16, 1);
        for pixel in [0, 9, 12345] {
            for pass in 0..3 {
                let mut cells = [0; 16];
                for j in 0..16 {
                    let p = sets.sample(pixel, pass * 16 + j, dims::LIGHTS);
                    cells[(p.y * 4.0) as usize * 4 + (p.x * 4.0) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1));
            }
        }
    }

    #[test]
    fn dimensions_and_pixels_are_decorrelated() {
        // Pearson correlation between dimension 0 and 1 over many pixels is near zero.
        let sets = SampleSets::generate(SamplerKind::MultiJittered, 16, 3);
        let n = 20_000u32;
        let (mut sx, mut sy, mut sxy, mut sxx, mut syy) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for pixel in 0..n {
            let a = sets.sample(pixel, 0, 0).x as f64;
            let b = sets.sample(pixel, 0, 1).x as f64;
            sx += a;
            sy += b;
            sxy += a * b;
            sxx += a * a;
            syy += b * b;
        }
        let nf = n as f64;
        let cov = sxy / nf - sx / nf * sy / nf;
        let corr = cov / ((sxx / nf - (sx / nf).powi(2)) * (syy / nf - (sy / nf).powi(2))).sqrt();
        assert!(corr.abs() < 0.03, "correlation {corr}");
        assert_ne!(sets.sample(0, 0, 0), sets.sample(1, 0, 0));
    }

    #[test]
    fn different_seeds_give_different_sets() {
        let a = SampleSets::generate(SamplerKind::Jittered, 16, 1);
        let b = SampleSets::generate(SamplerKind::Jittered, 16, 2);
        assert_ne!(a.sample(3, 0, 0), b.sample(3, 0, 0));
    }
}
