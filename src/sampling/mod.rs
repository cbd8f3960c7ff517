//! Sampling: the RTGU sample-set families, their maps to the disk and hemisphere, and a
//! stateless lookup `sample(pixel, index, dimension)` that replaces the book's shared
//! `count`/`jump` state.
//!
//! A [`SampleSets`] resource holds `num_sets` precomputed sets of `n` points. Sample index `i`
//! of a pixel belongs to pass `i / n`; for each (pixel, pass, dimension) a hash picks one set and
//! a hashed permutation (Kensler 2013) orders it, so the `n` samples of a pass are a whole,
//! stratified set, different in every pixel and dimension, and independent of tile order.
//! Correlated multi-jittered points (the default) are computed per sample instead, from one
//! of [`SampleSets::PREFERRED_SETS`] patterns per seed that the same hash picks; where the
//! occluder traces them in quadrant packets, their cosine directions are tabled once
//! (`cosine_table`). ZSobol points are computed per sample, a pattern of their own for every
//! (pixel, pass, dimension).

pub mod cmj;
pub(crate) mod cosine_table;
pub mod generators;
pub mod hash;
pub mod sobol;
pub mod warp;

use std::ops::Range;

use bevy_ecs::prelude::Resource;

use glam::Vec2;

use crate::random::{SplitMix64, mix64};
use cmj::Cmj;
#[cfg(target_arch = "x86_64")]
use cosine_table::{CosineTable, TableOrder};
pub use generators::SamplerKind;
use hash::{Modulus, hash_sample, permute, seed_key};
use sobol::ZSobol;

/// The largest f32 below 1: where sample coordinates are clamped so that they stay in [0, 1).
pub(crate) const ONE_MINUS_EPSILON: f32 = 1.0 - crate::math::MACHINE_EPSILON;

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

/// How a render's runs of samples at a shading point fall on the sets' passes (samples
/// `k·n .. (k+1)·n` of a pixel): whole passes, as a render of its whole sample target in one
/// frame traces, or parts of them, as progressive frames and adaptive batches do; or one
/// sample at each point, where every sample has a camera ray of its own (jittered pixels).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleRuns {
    /// Every run is whole passes.
    WholePasses,
    /// Runs may take part of a pass.
    Partial,
    /// One sample at each shading point: no run to table directions for.
    OnePerPoint,
}

/// Precomputed sets of 2-D sample points for one sampler kind and set size (or, for ZSobol,
/// which is computed per sample, its parameters).
#[derive(Resource, Clone, Debug)]
pub struct SampleSets {
    kind: SamplerKind,
    n: u32,
    runs: SampleRuns,
    num_sets: u32,
    seed: u64,
    width: u32,
    zsobol: ZSobol,
    cmj: Cmj,
    /// Division by `n`.
    modulus: Modulus,
    /// The seed's hash key.
    key: u64,
    /// The first of the seed's correlated multi-jittered patterns.
    first_pattern: u32,
    points: Vec<Vec2>,
    /// The local cosine directions of those patterns, for the packet width of this CPU.
    #[cfg(target_arch = "x86_64")]
    cosine: Option<CosineTable>,
    /// Whether pixels share sets, so that [`SampleSets::frame_symmetry`] picks one per pixel.
    symmetries: bool,
}

impl SampleSets {
    /// Most points kept in memory across all sets (32 MiB).
    const MAX_POINTS: usize = 1 << 22;
    /// Sets generated when memory allows, and the number of correlated multi-jittered patterns
    /// per seed. Pixels that draw the same set in a pass have correlated errors (the book's 83
    /// sets make that visible); with 4096 such pixels are few and scattered, so the shared
    /// error looks like noise, not structure.
    pub const PREFERRED_SETS: u32 = 4096;

    /// Generates the sets for `kind` with `n` points each, fixed by `seed`, for an image
    /// `width × height` (ZSobol orders pixels along a Morton curve of that size), for renders
    /// that trace whole passes ([`SampleRuns::WholePasses`]).
    pub fn generate(kind: SamplerKind, n: u32, seed: u64, width: u32, height: u32) -> Self {
        Self::generate_for(kind, n, seed, width, height, SampleRuns::WholePasses)
    }

    /// [`SampleSets::generate`] for renders whose runs of samples are `runs`, which decides the
    /// order the occluder's cosine directions are tabled in (`cosine_table`): where runs are
    /// whole passes, the quadrant order for patterns with quadrants and sorted by azimuth
    /// for the others of more than one packet; else sample order. The sets' samples are the
    /// same either way.
    pub fn generate_for(kind: SamplerKind, n: u32, seed: u64, width: u32, height: u32, runs: SampleRuns) -> Self {
        let n = n.max(1);
        let stored = match kind {
            SamplerKind::Regular => 1,
            k if !k.uses_stored_sets() => 0,
            _ => (Self::MAX_POINTS / n as usize).clamp(1, Self::PREFERRED_SETS as usize) as u32,
        };
        let mut rng = SplitMix64::new(seed ^ 0x5eed_5e75);
        let mut points = Vec::with_capacity(n as usize * stored as usize);
        for _ in 0..stored {
            kind.generate(n, &mut rng, &mut points);
        }
        // CMJ's patterns are computed, not stored, but there are as many as stored sets.
        let num_sets = if kind == SamplerKind::CorrelatedMultiJittered { Self::PREFERRED_SETS } else { stored };
        let zsobol = ZSobol::new(n, width.max(height));
        let (cmj, key) = (Cmj::new(n), seed_key(seed));
        let first_pattern = (key >> 32) as u32;
        // Only the occluder's runs read the table: its packets of whole passes in the width the
        // CPU's packets have, or its runs in sample order, sorted into packets of that width.
        #[cfg(target_arch = "x86_64")]
        let cosine = (kind == SamplerKind::CorrelatedMultiJittered)
            .then(|| {
                let lanes = crate::simd::packet_lanes();
                let whole = (runs == SampleRuns::WholePasses).then(|| {
                    CosineTable::build(&cmj, n, first_pattern, Self::PREFERRED_SETS, lanes)
                        .or_else(|| CosineTable::build_sorted(&cmj, n, first_pattern, Self::PREFERRED_SETS, lanes))
                });
                whole.flatten().or_else(|| {
                    (runs != SampleRuns::OnePerPoint)
                        .then(|| {
                            CosineTable::build_in_sample_order(&cmj, n, first_pattern, Self::PREFERRED_SETS, lanes)
                        })
                        .flatten()
                })
            })
            .flatten();
        // Pixels share sets wherever the sets are not the pixel's own (ZSobol) or one set for
        // all by definition (regular).
        let symmetries = !matches!(kind, SamplerKind::ZSobol | SamplerKind::Regular);
        SampleSets {
            kind,
            n,
            runs,
            num_sets,
            seed,
            width: width.max(1),
            zsobol,
            cmj,
            modulus: Modulus::new(n),
            key,
            first_pattern,
            points,
            #[cfg(target_arch = "x86_64")]
            cosine,
            symmetries,
        }
    }

    /// The symmetry ([`crate::math::Onb::symmetry`], 0..8) of `pixel`'s shading frame, for
    /// samplers whose pixels share sets: pixels that draw the same set with the same normal
    /// would otherwise trace the same directions and share their errors. A symmetry of the
    /// tangent square keeps the points' distribution, their stratification and the quadrants
    /// that ray packets are grouped by. `None` where pixels have sets of their own (ZSobol) or
    /// one set by definition (regular).
    #[inline]
    pub fn frame_symmetry(&self, pixel: u32) -> Option<u32> {
        // One symmetry per 8 × 8 block of pixels: neighbours keep one orientation (and the
        // caches the traversal warmed), while pixels that share a pattern lie far apart.
        let block = (u64::from(pixel / self.width / 8) << 32) | u64::from(pixel % self.width / 8);
        let h = mix64(self.key ^ 0x7a21_0f3e_c4d9_86b5 ^ block);
        self.symmetries.then_some((h >> 61) as u32)
    }

    /// The correlated multi-jittered pattern of (pixel, pass, dimension): one of the seed's
    /// [`SampleSets::PREFERRED_SETS`], picked by the hash that picks stored sets.
    #[inline(always)]
    fn cmj_pattern(&self, pixel: u32, pass: u32, dim: u32) -> u32 {
        let h = hash_sample(pixel, pass, dim, self.key);
        self.first_pattern.wrapping_add((((h >> 32) * u64::from(Self::PREFERRED_SETS)) >> 32) as u32)
    }

    /// The pattern of these sets.
    pub fn kind(&self) -> SamplerKind {
        self.kind
    }

    /// Points per set.
    pub fn set_size(&self) -> u32 {
        self.n
    }

    /// Number of distinct sets (CMJ patterns; 0 for ZSobol, whose every pixel has its own).
    pub fn num_sets(&self) -> u32 {
        self.num_sets
    }

    /// The order the occluder's cosine directions are tabled in (`cosine_table`): "quadrant",
    /// "azimuth" or "sample"; `None` where they are not tabled.
    pub fn cosine_table_order(&self) -> Option<&'static str> {
        #[cfg(target_arch = "x86_64")]
        return self.cosine.as_ref().map(|t| match t.order() {
            cosine_table::TableOrder::Quadrants => "quadrant",
            cosine_table::TableOrder::Samples => "sample",
            cosine_table::TableOrder::Sorted => "azimuth",
        });
        #[cfg(not(target_arch = "x86_64"))]
        None
    }

    /// Whether these sets are the ones [`SampleSets::generate_for`] makes from the same
    /// arguments (`runs` matters only where it picks the table's order).
    pub fn matches(
        &self,
        kind: SamplerKind,
        samples_per_set: u32,
        seed: u64,
        (width, height): (u32, u32),
        runs: SampleRuns,
    ) -> bool {
        let n = samples_per_set.max(1);
        let same_image = self.width == width.max(1) && self.zsobol == ZSobol::new(n, width.max(height));
        let same_table = self.runs == runs || kind != SamplerKind::CorrelatedMultiJittered;
        self.kind == kind && self.n == n && self.seed == seed && same_image && same_table
    }

    /// Bytes held by the point sets and the cosine directions' table.
    pub fn memory_bytes(&self) -> usize {
        #[cfg(target_arch = "x86_64")]
        let table = self.cosine.as_ref().map_or(0, CosineTable::memory_bytes);
        #[cfg(not(target_arch = "x86_64"))]
        let table = 0;
        self.points.len() * std::mem::size_of::<Vec2>() + table
    }

    /// The 2-D sample for (pixel, sample index, dimension): a pure function of its arguments
    /// and the sets, so images do not depend on scheduling.
    #[inline]
    pub fn sample(&self, pixel: u32, index: u32, dim: u32) -> Vec2 {
        let mut out = [Vec2::ZERO];
        self.fill_pass(pixel, self.modulus.quotient(index), self.modulus.remainder(index), dim, &mut out);
        out[0]
    }

    /// The samples `first, first + 1, …` of `pixel` in dimension `dim`, one per element of
    /// `out`: exactly [`SampleSets::sample`] for each index, but the (pixel, pass, dimension)
    /// hash and the pattern's set-up are done once per pass instead of once per sample.
    #[inline]
    pub fn fill(&self, pixel: u32, first: u32, dim: u32, out: &mut [Vec2]) {
        if let [one] = out {
            *one = self.sample(pixel, first, dim);
            return;
        }
        for (pass, i, run) in self.passes(first, out.len()) {
            self.fill_pass(pixel, pass, i, dim, &mut out[run]);
        }
    }

    /// [`SampleSets::fill`] for runs of `count` samples of each of `runs` (pixel, first sample):
    /// run i's sample s into `out[i·count + s]`. Short runs (frames of a few samples a pixel)
    /// are made together where the sets allow it in lanes ([`Cmj::fill_each`]), not a vector's
    /// set-up for each run's few lanes; runs of one sample, made one by one otherwise, always.
    pub(crate) fn fill_runs(&self, runs: &[(u32, u32)], count: u32, dim: u32, out: &mut [Vec2]) {
        let n = count as usize;
        debug_assert_eq!(out.len(), runs.len() * n);
        let each = self.kind == SamplerKind::CorrelatedMultiJittered && (n == 1 || self.cmj.fills_each_in_lanes());
        if n > Self::SHORT_RUN || !each {
            for (&(pixel, first), out) in runs.iter().zip(out.chunks_exact_mut(n.max(1))) {
                self.fill(pixel, first, dim, out);
            }
            return;
        }
        const BLOCK: usize = 64;
        let (mut samples, mut patterns) = ([0u32; BLOCK], [0u32; BLOCK]);
        let (mut k, mut at) = (0, 0);
        for &(pixel, first) in runs {
            for index in (0..count).map(|s| first.wrapping_add(s)) {
                let pass = self.modulus.quotient(index);
                (samples[k], patterns[k]) = (self.modulus.remainder(index), self.cmj_pattern(pixel, pass, dim));
                k += 1;
                if k == BLOCK {
                    self.cmj.fill_each(&samples, &patterns, &mut out[at..at + BLOCK]);
                    (k, at) = (0, at + BLOCK);
                }
            }
        }
        self.cmj.fill_each(&samples[..k], &patterns[..k], &mut out[at..at + k]);
    }

    /// Longest run [`SampleSets::fill_runs`] makes with the others, sample by sample.
    const SHORT_RUN: usize = 8;

    /// [`SampleSets::fill`] as two columns, x into `xs` and y into `ys` (same length):
    /// correlated multi-jittered sets whose patterns [`Cmj::fill_columns`] computes in lanes go
    /// straight to the columns, other sets through [`SampleSets::fill`] a block at a time.
    pub(crate) fn fill_columns(&self, pixel: u32, first: u32, dim: u32, xs: &mut [f32], ys: &mut [f32]) {
        assert_eq!(xs.len(), ys.len(), "two columns of the same length");
        // The lanes take a pass unless its pattern's order would wrap (a few patterns in 2³² of
        // sizes not a power of two): a refusal falls back to filling every sample below.
        if self.kind == SamplerKind::CorrelatedMultiJittered
            && self.passes(first, xs.len()).all(|(pass, i, run)| {
                let p = self.cmj_pattern(pixel, pass, dim);
                self.cmj.fill_columns(i, p, &mut xs[run.clone()], &mut ys[run])
            })
        {
            return;
        }
        const BLOCK: usize = 64;
        let mut points = [Vec2::ZERO; BLOCK];
        for (b, (xs, ys)) in xs.chunks_mut(BLOCK).zip(ys.chunks_mut(BLOCK)).enumerate() {
            let points = &mut points[..xs.len()];
            self.fill(pixel, first.wrapping_add((b * BLOCK) as u32), dim, points);
            for ((x, y), p) in xs.iter_mut().zip(ys.iter_mut()).zip(points.iter()) {
                (*x, *y) = (p.x, p.y);
            }
        }
    }

    /// The cosine table, where the sets keep one in `order`.
    #[cfg(target_arch = "x86_64")]
    fn table_in(&self, order: cosine_table::TableOrder) -> Option<&CosineTable> {
        self.cosine.as_ref().filter(|t| t.order() == order)
    }

    /// The local cosine directions (around +z) of samples `first, first + 1, …` of `pixel` in
    /// dimension `dim`, one per element of the columns `dx`, `dy`, `dz` (same length), copied
    /// from the table in sample order: the bits [`cosine_hemisphere_lanes`] gives the points
    /// [`SampleSets::fill_columns`] fills. Returns false, writing nothing, where the sets keep
    /// no such table.
    ///
    /// [`cosine_hemisphere_lanes`]: warp::cosine_hemisphere_lanes
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn fill_directions(&self, pixel: u32, first: u32, dim: u32, [dx, dy, dz]: [&mut [f32]; 3]) -> bool {
        let Some(table) = self.table_in(cosine_table::TableOrder::Samples) else {
            return false;
        };
        let n = self.n as usize;
        for (pass, i, run) in self.passes(first, dx.len()) {
            let dirs = table.pattern(self.cmj_pattern(pixel, pass, dim));
            let from = i as usize..i as usize + run.len();
            for (axis, column) in [&mut *dx, &mut *dy, &mut *dz].into_iter().enumerate() {
                column[run.clone()].copy_from_slice(&dirs[axis * n..][from.clone()]);
            }
        }
        true
    }

    /// [`SampleSets::fill_directions`] read in place: the local cosine directions of samples
    /// `first, first + 1, …` (`len` of them) of `pixel` in dimension `dim`, one slice per axis,
    /// where the run lies within one pass and the sets keep a table in sample order. `None`
    /// elsewhere.
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn table_directions(&self, pixel: u32, first: u32, dim: u32, len: usize) -> Option<[&[f32]; 3]> {
        let table = self.table_in(cosine_table::TableOrder::Samples)?;
        let (pass, i, run) = self.passes(first, len).next()?;
        if run.len() != len {
            return None;
        }
        let (n, i) = (self.n as usize, i as usize);
        let dirs = table.pattern(self.cmj_pattern(pixel, pass, dim));
        Some([0, 1, 2].map(|axis| &dirs[axis * n + i..][..len]))
    }

    /// Asks the CPU to start loading what [`SampleSets::fill_directions`] of the same
    /// arguments (`len` samples) will read, so that a run issued for the next pixel finds it
    /// in cache (a hint; no effect on results).
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn prefetch_directions(&self, pixel: u32, first: u32, dim: u32, len: usize) {
        let Some(table) = self.table_in(cosine_table::TableOrder::Samples) else {
            return;
        };
        let n = self.n as usize;
        for (pass, i, run) in self.passes(first, len) {
            let dirs = table.pattern(self.cmj_pattern(pixel, pass, dim));
            for axis in 0..3 {
                crate::simd::prefetch_slice(&dirs[axis * n + i as usize..][..run.len()]);
            }
        }
    }

    /// Where samples `first, first + 1, …` (`len` of them) of `pixel` in dimension `dim` are
    /// whole passes of correlated multi-jittered patterns whose cosine directions are tabled in
    /// packets: in the quadrant order of patterns that split into quadrants
    /// ([`Cmj::has_quadrants`]), or sorted by azimuth. The sets' patterns, the table, and each
    /// pass's pattern number, in order (pass k holds samples `k·n … k·n + n − 1` of the run).
    /// `None` elsewhere.
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn quadrant_passes(
        &self,
        pixel: u32,
        first: u32,
        dim: u32,
        len: usize,
    ) -> Option<(&Cmj, &CosineTable, impl Iterator<Item = u32> + '_)> {
        let n = self.n as usize;
        let whole = first.is_multiple_of(self.n) && len.is_multiple_of(n) && len > 0;
        let packets = |t: &&CosineTable| matches!(t.order(), TableOrder::Quadrants | TableOrder::Sorted);
        let table = self.cosine.as_ref().filter(packets).filter(|_| whole)?;
        // Whole passes: each run of `passes` is one pass, from its first sample.
        let passes = self.passes(first, len).map(move |(pass, _, _)| self.cmj_pattern(pixel, pass, dim));
        Some((&self.cmj, table, passes))
    }

    /// The passes of samples `first, first + 1, …` (`len` of them): each pass, the index in
    /// it of the run's first sample there, and which of the run's samples it holds.
    #[inline(always)]
    fn passes(&self, first: u32, len: usize) -> impl Iterator<Item = (u32, u32, Range<usize>)> + '_ {
        let (mut index, mut at) = (first, 0);
        std::iter::from_fn(move || {
            (at < len).then(|| {
                let (pass, i) = (self.modulus.quotient(index), self.modulus.remainder(index));
                let count = ((self.n - i) as usize).min(len - at);
                let run = at..at + count;
                index = index.wrapping_add(count as u32);
                at += count;
                (pass, i, run)
            })
        })
    }

    /// Samples `first..first + out.len()` (all < n) of one pass.
    #[inline(always)]
    fn fill_pass(&self, pixel: u32, pass: u32, first: u32, dim: u32, out: &mut [Vec2]) {
        let indices = first..;
        match self.kind {
            SamplerKind::Regular => out.copy_from_slice(&self.points[first as usize..][..out.len()]),
            SamplerKind::ZSobol => {
                let (x, y) = (pixel % self.width, pixel / self.width);
                self.zsobol.fill(x, y, first, dim, self.seed ^ mix64(pass as u64), out);
            }
            SamplerKind::CorrelatedMultiJittered => {
                let p = self.cmj_pattern(pixel, pass, dim);
                match out {
                    // A lone sample skips the vector loop's set-up.
                    [one] => *one = Vec2::from(self.cmj.sample(first, p)),
                    _ => self.cmj.fill(first, p, out),
                }
            }
            _ => {
                let h = hash_sample(pixel, pass, dim, self.key);
                let set = &self.points[((((h >> 32) * self.num_sets as u64) >> 32) * self.n as u64) as usize..];
                for (i, o) in indices.zip(out) {
                    *o = set[permute(i, self.modulus, h as u32) as usize];
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_pixel_index_dimension_gives_the_same_value() {
        for kind in SamplerKind::ALL {
            let a = SampleSets::generate(kind, 16, 42, 64, 64);
            let b = SampleSets::generate(kind, 16, 42, 64, 64);
            for (p, i, d) in [(0, 0, 0), (17, 5, 1), (1000, 31, 2), (5, 100, 3)] {
                assert_eq!(a.sample(p, i, d), b.sample(p, i, d), "{kind:?}");
            }
        }
    }

    /// Correlated multi-jittered passes draw their patterns from the seed's pool of
    /// [`SampleSets::PREFERRED_SETS`]: over 20,000 (pixel, pass) pairs at most that many
    /// distinct ones, nearly all of them drawn (4,065 expected); another seed has another pool.
    #[test]
    fn cmj_patterns_come_from_a_pool_per_seed() {
        let pool = |seed| {
            let sets = SampleSets::generate(SamplerKind::CorrelatedMultiJittered, 16, seed, 64, 64);
            (0..20_000).map(|i| sets.cmj_pattern(i % 1000, i / 1000, 2)).collect::<std::collections::HashSet<u32>>()
        };
        let (a, b) = (pool(1), pool(2));
        assert!((4000..=SampleSets::PREFERRED_SETS as usize).contains(&a.len()), "{} patterns", a.len());
        assert!(a.is_disjoint(&b));
    }

    #[test]
    fn one_pass_of_a_pixel_is_a_whole_stratified_set() {
        // The 16 samples of one pass in one pixel fill all 4×4 jittered strata.
        let sets = SampleSets::generate(SamplerKind::Jittered, 16, 1, 64, 64);
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
        let sets = SampleSets::generate(SamplerKind::MultiJittered, 16, 3, 64, 64);
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

    /// Whether `pts` (2^m of them) put exactly one point in every base-2 elementary interval
    /// of area 2^-m: the (0, m, 2)-net property.
    fn is_02_net(pts: &[Vec2]) -> bool {
        let m = pts.len().trailing_zeros();
        (0..=m).all(|bx| {
            let (sx, sy) = (1u32 << bx, 1u32 << (m - bx));
            let mut cells = vec![0; pts.len()];
            for p in pts {
                cells[((p.y * sy as f32) as u32 * sx + (p.x * sx as f32) as u32) as usize] += 1;
            }
            cells.iter().all(|&c| c == 1)
        })
    }

    #[test]
    fn zsobol_pixels_get_02_nets_in_every_dimension() {
        for spp in [4u32, 16, 64, 128] {
            let sets = SampleSets::generate(SamplerKind::ZSobol, spp, 5, 37, 23);
            for pixel in [0u32, 1, 36, 37 * 10 + 5, 37 * 23 - 1] {
                for dim in 0..4 {
                    for pass in 0..2 {
                        let pts: Vec<Vec2> = (0..spp).map(|i| sets.sample(pixel, pass * spp + i, dim)).collect();
                        assert!(pts.iter().all(|p| (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)));
                        assert!(is_02_net(&pts), "spp {spp}, pixel {pixel}, dim {dim}, pass {pass}");
                    }
                }
            }
        }
    }

    #[test]
    fn zsobol_neighbours_and_dimensions_differ() {
        let sets = SampleSets::generate(SamplerKind::ZSobol, 16, 1, 64, 64);
        assert_ne!(sets.sample(0, 0, 0), sets.sample(1, 0, 0));
        assert_ne!(sets.sample(0, 0, 0), sets.sample(0, 0, 1));
        assert_ne!(sets.sample(0, 0, 0), sets.sample(0, 16, 0), "passes are scrambled anew");
    }

    #[test]
    fn cmj_pixels_are_stratified_and_decorrelated() {
        let sets = SampleSets::generate(SamplerKind::CorrelatedMultiJittered, 16, 3, 64, 64);
        for pixel in [0, 7, 999] {
            let mut cells = [0; 16];
            for i in 0..16 {
                let p = sets.sample(pixel, i, dims::LIGHTS);
                cells[(p.y * 4.0) as usize * 4 + (p.x * 4.0) as usize] += 1;
            }
            assert!(cells.iter().all(|&c| c == 1));
        }
        assert_ne!(sets.sample(0, 0, 0), sets.sample(1, 0, 0));
    }

    #[test]
    fn fill_gives_the_samples_of_sample_across_passes() {
        for kind in SamplerKind::ALL {
            for n in [1u32, 12, 16] {
                let sets = SampleSets::generate(kind, n, 9, 37, 23);
                for (pixel, first, len) in [(0u32, 0u32, 40usize), (5, 7, 1), (100, 15, 33), (850, 3, 16)] {
                    let mut out = vec![Vec2::NAN; len];
                    sets.fill(pixel, first, 4, &mut out);
                    for (index, v) in (first..).zip(&out) {
                        assert_eq!(*v, sets.sample(pixel, index, 4), "{kind:?}, n {n}, index {index}");
                    }
                    // Columns: in lanes for power-of-two CMJ sets where the CPU has AVX-512, a
                    // block at a time otherwise (runs longer than a block included).
                    for len in [len, 150] {
                        let (mut xs, mut ys) = (vec![f32::NAN; len], vec![f32::NAN; len]);
                        sets.fill_columns(pixel, first, 4, &mut xs, &mut ys);
                        for (index, (&x, &y)) in (first..).zip(xs.iter().zip(&ys)) {
                            let v = sets.sample(pixel, index, 4);
                            assert_eq!((x, y), (v.x, v.y), "columns: {kind:?}, n {n}, index {index}");
                        }
                    }
                }
            }
        }
    }

    /// Runs of any length, many pixels' together, get [`SampleSets::sample`]'s values, across
    /// passes: short runs of CMJ sets of a power-of-two size in lanes, each its own pattern
    /// (more than one block of them), the rest run by run.
    #[test]
    fn fill_runs_gives_the_samples_of_sample() {
        for kind in SamplerKind::ALL {
            for n in [1u32, 12, 16, 64] {
                let sets = SampleSets::generate(kind, n, 9, 37, 23);
                for count in [1u32, 2, 3, 8, 9, 20] {
                    let runs: Vec<(u32, u32)> = (0..50u32).map(|i| (i * 17 % 851, i * 7 % 90)).collect();
                    let mut out = vec![Vec2::NAN; runs.len() * count as usize];
                    sets.fill_runs(&runs, count, 3, &mut out);
                    for (&(pixel, first), run) in runs.iter().zip(out.chunks_exact(count as usize)) {
                        for (index, v) in (first..).zip(run) {
                            let want = sets.sample(pixel, index, 3);
                            assert_eq!(v.to_array(), want.to_array(), "{kind:?}, n {n}, count {count}, index {index}");
                        }
                    }
                }
            }
        }
    }

    /// Sets for partial runs table the occluder's directions in sample order, and a run's
    /// copy from it across passes gives, bit for bit, the cosine map of [`SampleSets::sample`]
    /// for each of its samples; sets for whole passes table them in packets, in quadrant order
    /// where the patterns have quadrants, sorted by azimuth where not; the order is part of
    /// what [`SampleSets::matches`] compares, for CMJ only.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn partial_runs_copy_their_directions_from_a_table_in_sample_order() {
        use crate::sampling::warp::cosine_power_hemisphere;
        let cmj = SamplerKind::CorrelatedMultiJittered;
        for n in [16u32, 48] {
            let sets = SampleSets::generate_for(cmj, n, 9, 37, 23, SampleRuns::Partial);
            let whole = SampleSets::generate_for(cmj, n, 9, 37, 23, SampleRuns::WholePasses);
            assert!(sets.matches(cmj, n, 9, (37, 23), SampleRuns::Partial));
            assert!(!sets.matches(cmj, n, 9, (37, 23), SampleRuns::WholePasses));
            let regular = SampleSets::generate_for(SamplerKind::Regular, n, 9, 37, 23, SampleRuns::Partial);
            assert!(regular.matches(SamplerKind::Regular, n, 9, (37, 23), SampleRuns::WholePasses));
            let quadrants = n.is_power_of_two();
            let packets = if quadrants { "quadrant" } else { "azimuth" };
            // In eight lanes or sixteen, whichever the CPU's packets have.
            assert_eq!(sets.cosine_table_order(), Some("sample"), "n {n}");
            assert_eq!(whole.cosine_table_order(), Some(packets), "n {n}");
            for (pixel, first, len) in [(0u32, 0u32, 40usize), (5, 7, 1), (100, 15, 33), (850, 3, 16)] {
                let mut columns = [vec![f32::NAN; len], vec![f32::NAN; len], vec![f32::NAN; len]];
                let [dx, dy, dz] = &mut columns;
                assert!(sets.fill_directions(pixel, first, 4, [dx, dy, dz]));
                for (k, index) in (first..).take(len).enumerate() {
                    let dir = cosine_power_hemisphere(sets.sample(pixel, index, 4), 1.0).dir;
                    let got = [columns[0][k], columns[1][k], columns[2][k]].map(f32::to_bits);
                    assert_eq!(got, dir.to_array().map(f32::to_bits), "n {n}, pixel {pixel}, index {index}");
                }
            }
            let mut column = [0.0f32; 3];
            let [a, b, c] = column.each_mut().map(std::slice::from_mut);
            assert!(!whole.fill_directions(0, 0, 4, [a, b, c]), "n {n}: whole passes");
            let single = SampleSets::generate_for(cmj, n, 9, 37, 23, SampleRuns::OnePerPoint);
            assert_eq!(single.cosine_table_order(), None, "n {n}: one sample per point");
        }
    }

    #[test]
    fn different_seeds_give_different_sets() {
        let a = SampleSets::generate(SamplerKind::Jittered, 16, 1, 64, 64);
        let b = SampleSets::generate(SamplerKind::Jittered, 16, 2, 64, 64);
        assert_ne!(a.sample(3, 0, 0), b.sample(3, 0, 0));
    }
}
