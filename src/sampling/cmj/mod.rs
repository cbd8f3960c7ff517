//! Correlated multi-jittered sampling (Kensler 2013, "Correlated Multi-Jittered Sampling"):
//! stateless multi-jittered patterns of any size, each a pure function of (index, pattern).

#[cfg(target_arch = "x86_64")]
mod lanes;
#[cfg(test)]
mod tests;

#[cfg(target_arch = "x86_64")]
pub(crate) use lanes::QuadrantPattern;
#[cfg(target_arch = "x86_64")]
use lanes::{FillColumns, FillEach, FillPattern, quadrant_bits, quadrant_sample};

use glam::Vec2;

use super::{
    ONE_MINUS_EPSILON,
    generators::grid_shape,
    hash::{Modulus, permute, permute_pow2},
};

/// Kensler's hash to a float in [0, 1).
#[inline]
fn randfloat(mut i: u32, p: u32) -> f32 {
    i ^= p;
    i ^= i >> 17;
    i ^= i >> 10;
    i = i.wrapping_mul(0xb365_34e5);
    i ^= i >> 12;
    i ^= i >> 21;
    i = i.wrapping_mul(0x93fc_4795);
    i ^= 0xdf6e_307f;
    i ^= i >> 17;
    i = i.wrapping_mul(1 | p >> 18);
    (i as f32 * (1.0 / 4_294_967_808.0)).min(ONE_MINUS_EPSILON)
}

/// The `n`-point correlated multi-jittered patterns, with the grid shape worked out once. Each
/// pattern is stratified on an m × k grid (m·k = n) and in both 1-D projections, with the
/// sample order itself shuffled. Computed per sample, so every (pixel, pass, dimension) gets a pattern of its own without a
/// stored table (a table lookup per sample is a cache miss on large images).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cmj {
    n: Modulus,
    m: Modulus,
    k: Modulus,
    /// 1/m and 1/k.
    inv: [f32; 2],
    /// Where the patterns have quadrants: for packets of eight and of sixteen slots, each
    /// slot's shuffled sample number ([`QuadrantPattern`]). It depends on the grid alone, not
    /// on the pattern, so it is worked out once: made per packet from the slot's bit fields,
    /// it cost the AO kernel measurable time.
    #[cfg(target_arch = "x86_64")]
    quadrant_samples: [[u32; 256]; 2],
}

impl Cmj {
    /// Patterns of `n` ≥ 1 points.
    pub fn new(n: u32) -> Self {
        let n = n.max(1);
        let (m, k) = grid_shape(n);
        let mut cmj = Cmj {
            n: Modulus::new(n),
            m: Modulus::new(m),
            k: Modulus::new(k),
            inv: [1.0 / m as f32, 1.0 / k as f32],
            #[cfg(target_arch = "x86_64")]
            quadrant_samples: [[0; 256]; 2],
        };
        #[cfg(target_arch = "x86_64")]
        if cmj.has_quadrant_grid() {
            for (w, width) in [8, 16].into_iter().enumerate() {
                let (bits, packet_bits) = quadrant_bits(&cmj, width);
                for t in 0..n {
                    cmj.quadrant_samples[w][t as usize] = quadrant_sample(t, bits, packet_bits);
                }
            }
        }
        cmj
    }

    /// Sample `s` (< n) of pattern `p`.
    #[inline]
    pub fn sample(&self, s: u32, p: u32) -> [f32; 2] {
        let sc = Scrambles::new(p);
        let s = permute(s, self.n, sc.order);
        let (col, row) = (self.m.remainder(s), self.m.quotient(s));
        let (sx, sy) = (permute(col, self.m, sc.x), permute(row, self.k, sc.y));
        self.point(s, col, row, sx, sy, &sc)
    }

    /// Samples `first..first + out.len()` (all < n) of pattern `p`, in order: the values of
    /// [`Cmj::sample`], with the pattern's scrambles derived once. For a power-of-two n (then m
    /// and k are powers of two too) every permutation is a single round and every division a
    /// shift or mask: a loop without branches that the compiler can vectorise.
    #[inline]
    pub fn fill(&self, first: u32, p: u32, out: &mut [Vec2]) {
        debug_assert!(first as u64 + out.len() as u64 <= self.n.get() as u64);
        // In the packets' lanes wherever they give the pattern exactly (`in_lanes`).
        #[cfg(target_arch = "x86_64")]
        if self.in_lanes(p) {
            let kernel = FillPattern { cmj: self, first, p, out };
            // `packet_lanes` is sixteen where AVX-512 is allowed, else eight (AVX2's lanes or
            // the portable ones).
            return crate::simd::run_in(crate::simd::packet_lanes(), kernel).expect("eight or sixteen lanes");
        }
        fill_in_lanes(self, first, p, out);
    }

    /// Whether [`Cmj::fill_each`] runs in lanes: on this architecture, for patterns of a
    /// power-of-two size.
    pub(crate) fn fills_each_in_lanes(&self) -> bool {
        cfg!(target_arch = "x86_64") && self.n.is_power_of_two()
    }

    /// Sample `samples[j]` (< n) of pattern `patterns[j]` into `out[j]`, each element its own
    /// pattern (all three of one length): [`Cmj::sample`]'s values, in lanes where
    /// [`Cmj::fills_each_in_lanes`], else one by one.
    pub(crate) fn fill_each(&self, samples: &[u32], patterns: &[u32], out: &mut [Vec2]) {
        debug_assert!(samples.len() == out.len() && patterns.len() == out.len());
        #[cfg(target_arch = "x86_64")]
        if self.fills_each_in_lanes() {
            let kernel = FillEach { cmj: self, samples, patterns, out };
            return crate::simd::run_in(crate::simd::packet_lanes(), kernel).expect("eight or sixteen lanes");
        }
        for ((&s, &p), out) in samples.iter().zip(patterns).zip(out) {
            *out = Vec2::from(self.sample(s, p));
        }
    }

    /// Samples `first..first + xs.len()` (all < n) of pattern `p` as two columns, x into `xs`
    /// and y into `ys` (same length): [`Cmj::fill`]'s values. Returns false, writing nothing,
    /// unless the CPU's packets are eight or sixteen lanes wide ([`crate::simd::packet_lanes`])
    /// and the pattern is taken in lanes ([`Cmj::in_lanes`]), where a vector of samples at a
    /// time goes straight from lanes to the columns.
    pub(crate) fn fill_columns(&self, first: u32, p: u32, xs: &mut [f32], ys: &mut [f32]) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.in_lanes(p) {
            return crate::simd::run_in(crate::simd::packet_lanes(), FillColumns { cmj: self, first, p, xs, ys })
                .is_some();
        }
        let _ = (first, p, xs, ys);
        false
    }

    /// Whether the patterns are taken as [`QuadrantPattern`]s ([`Cmj::has_quadrant_grid`]) by
    /// the lane kernels, which exist on this architecture.
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn has_quadrants(&self) -> bool {
        self.has_quadrant_grid()
    }

    /// Whether the grid suits [`QuadrantPattern`]s, whatever the CPU: n a power of two on a
    /// grid of at most 16 × 16 whose m columns split into quarters (n = 16 … 256).
    #[cfg(target_arch = "x86_64")]
    fn has_quadrant_grid(&self) -> bool {
        self.n.is_power_of_two() && self.has_small_grid() && self.m.get().is_multiple_of(4)
    }

    /// Whether pattern `p` is computed in lanes ([`lanes::PatternLanes`]): wherever the lanes
    /// give its permutations exactly ([`permutes_in_lanes`](super::hash::permutes_in_lanes): all but a few patterns in 2³²
    /// where a length is not a power of two), for patterns of up to 2²³ points.
    #[cfg(target_arch = "x86_64")]
    fn in_lanes(&self, p: u32) -> bool {
        lanes::takes_pattern(self, &Scrambles::new(p))
    }

    /// Whether the grid is at most 16 × 16, so that its columns and rows fit the lanes' tables.
    #[cfg(target_arch = "x86_64")]
    fn has_small_grid(&self) -> bool {
        self.m.get() <= 16 && self.k.get() <= 16
    }

    #[inline(always)]
    fn fill_portable(&self, first: u32, p: u32, out: &mut [Vec2]) {
        if !self.n.is_power_of_two() {
            let (m, k) = (self.m.get() as usize, self.k.get() as usize);
            // A run longer than the grid's sides looks the column and row shuffles up in
            // tables: m + k permutations (each a loop of rounds) instead of two per sample.
            if out.len() > m + k && m <= SHUFFLE_TABLE && k <= SHUFFLE_TABLE {
                let sc = Scrambles::new(p);
                let (mut sx, mut sy) = ([0u32; SHUFFLE_TABLE], [0u32; SHUFFLE_TABLE]);
                for (col, x) in (0..).zip(&mut sx[..m]) {
                    *x = permute(col, self.m, sc.x);
                }
                for (row, y) in (0..).zip(&mut sy[..k]) {
                    *y = permute(row, self.k, sc.y);
                }
                for (s, o) in (first..).zip(out) {
                    let s = permute(s, self.n, sc.order);
                    let (col, row) = (self.m.remainder(s), self.m.quotient(s));
                    *o = Vec2::from(self.point(s, col, row, sx[col as usize], sy[row as usize], &sc));
                }
                return;
            }
            for (s, o) in (first..).zip(out) {
                *o = Vec2::from(self.sample(s, p));
            }
            return;
        }
        let sc = Scrambles::new(p);
        let (wn, wm, wk, shift) = (self.n.mask(), self.m.mask(), self.k.mask(), self.m.get().trailing_zeros());
        for (s, o) in (first..).zip(out) {
            let s = permute_pow2(s, wn, sc.order);
            let (col, row) = (s & wm, s >> shift);
            let (sx, sy) = (permute_pow2(col, wm, sc.x), permute_pow2(row, wk, sc.y));
            *o = Vec2::from(self.point(s, col, row, sx, sy, &sc));
        }
    }

    /// The point of (shuffled) sample `s` in cell (`col`, `row`), with `sx`, `sy` its
    /// permuted sub-cell coordinates.
    #[inline(always)]
    fn point(&self, s: u32, col: u32, row: u32, sx: u32, sy: u32, sc: &Scrambles) -> [f32; 2] {
        let [inv_m, inv_k] = self.inv;
        let jx = randfloat(s, sc.jx);
        let jy = randfloat(s, sc.jy);
        let x = (col as f32 + (sy as f32 + jx) * inv_k) * inv_m;
        let y = (row as f32 + (sx as f32 + jy) * inv_m) * inv_k;
        let below_one = |v: f32| v.min(ONE_MINUS_EPSILON);
        [below_one(x), below_one(y)]
    }
}

/// The longest grid side whose shuffles [`Cmj::fill_portable`] tables (patterns of up to 4096
/// points on square grids).
const SHUFFLE_TABLE: usize = 64;

crate::simd::multiversion! {
    /// [`Cmj::fill`]'s loop ([`Cmj::fill_portable`]), compiled for each instruction set: with
    /// AVX2, eight lanes of 32-bit multiplies (SSE2 has no 32-bit lane multiply, so the
    /// baseline copy vectorises poorly), with AVX-512 sixteen. Same operations, same values.
    fn fill_in_lanes(cmj: &Cmj, first: u32, p: u32, out: &mut [Vec2]) {
        cmj.fill_portable(first, p, out);
    }
}

/// The per-pattern seeds of Kensler's five hashes, derived from the pattern number.
struct Scrambles {
    /// Sample order.
    order: u32,
    /// Column and row shuffles.
    x: u32,
    y: u32,
    /// Jitter within the sub-cell.
    jx: u32,
    jy: u32,
}

impl Scrambles {
    /// The odd factors that make each seed from the pattern number, in the fields' order.
    const FACTORS: [u32; 5] = [0x5163_3e2d, 0xa511_e9b3, 0x63d8_3595, 0xa399_d265, 0x711a_d6a5];

    #[inline(always)]
    fn new(p: u32) -> Self {
        let [order, x, y, jx, jy] = Self::FACTORS.map(|f| p.wrapping_mul(f));
        Scrambles { order, x, y, jx, jy }
    }
}
