//! Correlated multi-jittered sampling (Kensler 2013, "Correlated Multi-Jittered Sampling"):
//! stateless multi-jittered patterns of any size, each a pure function of (index, pattern).

use glam::Vec2;

#[cfg(target_arch = "x86_64")]
use super::hash::{U32Lanes, permute_pow2_lanes};
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

/// The integer part of [`randfloat`] in each lane, with its operations.
///
/// # Safety
/// The CPU must have `V`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn randfloat_bits<V: U32Lanes>(i: V, p: u32) -> V {
    // SAFETY: the caller's CPU has `V`'s instruction set.
    unsafe {
        let u = |x: u32| V::splat(x);
        let mut i = i.xor(u(p));
        i = i.xor(i.shr(u(17)));
        i = i.xor(i.shr(u(10)));
        i = i.mul(u(0xb365_34e5));
        i = i.xor(i.shr(u(12)));
        i = i.xor(i.shr(u(21)));
        i = i.mul(u(0x93fc_4795));
        i = i.xor(u(0xdf6e_307f));
        i = i.xor(i.shr(u(17)));
        i.mul(u(1 | p >> 18))
    }
}

/// [`randfloat`] of each of sixteen lanes (AVX-512F), with its operations, so each lane gets its
/// value.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn randfloat_lanes(i: std::arch::x86_64::__m512i, p: u32) -> std::arch::x86_64::__m512 {
    use std::arch::x86_64::*;
    // SAFETY: this function is compiled for AVX-512F.
    let i = unsafe { randfloat_bits(i, p) };
    let f = _mm512_mul_ps(_mm512_cvtepu32_ps(i), _mm512_set1_ps(1.0 / 4_294_967_808.0));
    _mm512_min_ps(f, _mm512_set1_ps(ONE_MINUS_EPSILON))
}

/// [`randfloat`] of each of eight lanes (AVX2). AVX2 has no unsigned conversion: the high and
/// low halves convert exactly and their sum rounds once, which is the conversion's rounding.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn randfloat_lanes8(i: std::arch::x86_64::__m256i, p: u32) -> std::arch::x86_64::__m256 {
    use std::arch::x86_64::*;
    // SAFETY: this function is compiled for AVX2.
    let i = unsafe { randfloat_bits(i, p) };
    let high = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(i)), _mm256_set1_ps(65_536.0));
    let low = _mm256_cvtepi32_ps(_mm256_and_si256(i, _mm256_set1_epi32(0xffff)));
    let f = _mm256_mul_ps(_mm256_add_ps(high, low), _mm256_set1_ps(1.0 / 4_294_967_808.0));
    _mm256_min_ps(f, _mm256_set1_ps(ONE_MINUS_EPSILON))
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
    /// it cost sphere_plane's AO 3 % and Sponza's 2 % (one thread, 64 spp).
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
            for (w, (width, column_bits)) in
                [(8, SmallGrid8::PACKET_COLUMN_BITS), (16, SmallGrid16::PACKET_COLUMN_BITS)].into_iter().enumerate()
            {
                let (bits, packet_bits) = quadrant_bits(&cmj, width, column_bits);
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
        #[cfg(target_arch = "x86_64")]
        if crate::simd::avx512() {
            // SAFETY: the CPU has AVX-512F, checked just above.
            return unsafe { self.fill_avx512(first, p, out) };
        }
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            return unsafe { self.fill_avx2(first, p, out) };
        }
        self.fill_portable(first, p, out);
    }

    /// [`Cmj::fill`] compiled for AVX2: eight lanes of 32-bit multiplies (SSE2 has no 32-bit
    /// lane multiply, so the portable loop vectorises poorly). Same operations, same values.
    /// Where n is a power of two and the grid at most 16 × 16, the column and row shuffles are
    /// worked out once per call and looked up by lane permutes ([`SmallGrid8`]), as
    /// [`Cmj::fill_small_grid_avx512`] does sixteen-wide.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn fill_avx2(&self, first: u32, p: u32, out: &mut [Vec2]) {
        if self.has_small_grid16() {
            return self.fill_small_grid_avx2(first, p, out);
        }
        self.fill_portable(first, p, out);
    }

    /// [`Cmj::fill_small_grid_avx512`] eight samples at a time in AVX2 lanes
    /// ([`SmallGrid8`]), stored as the `Vec2`s they are.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    fn fill_small_grid_avx2(&self, first: u32, p: u32, out: &mut [Vec2]) {
        use std::arch::x86_64::*;

        // SAFETY (both blocks): this function is compiled for AVX2.
        let grid = unsafe { SmallGrid8::new(self, p) };
        let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        for (i, chunk) in out.chunks_mut(8).enumerate() {
            let (x, y) = unsafe { grid.points_of(grid.shuffled(consecutive8(first + 8 * i as u32))) };
            // (x, y) pairs as `Vec2`s lie in memory: samples 0–3, then 4–7.
            let (low, high) = (_mm256_unpacklo_ps(x, y), _mm256_unpackhi_ps(x, y));
            let pairs = [_mm256_permute2f128_ps::<0x20>(low, high), _mm256_permute2f128_ps::<0x31>(low, high)];
            let floats = chunk.as_mut_ptr().cast::<f32>();
            for (h, pair) in pairs.into_iter().enumerate() {
                // The floats of this half that the chunk holds (a chunk may be short).
                let n = (2 * chunk.len()).saturating_sub(8 * h).min(8) as i32;
                let keep = _mm256_cmpgt_epi32(_mm256_set1_epi32(n), iota);
                // SAFETY: the masked store writes only the chunk's first 2·len floats.
                unsafe { _mm256_maskstore_ps(floats.add(8 * h), keep, pair) };
            }
        }
    }

    /// [`Cmj::fill`] compiled for AVX-512F: sixteen lanes. Same operations, same values. Where
    /// n is a power of two and the grid at most 16 × 16, the column and row shuffles are
    /// worked out once per call, for all 16 columns and rows at once, and looked up by a lane
    /// permute ([`Cmj::fill_small_grid_avx512`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn fill_avx512(&self, first: u32, p: u32, out: &mut [Vec2]) {
        if self.has_small_grid16() {
            return self.fill_small_grid_avx512(first, p, out);
        }
        self.fill_portable(first, p, out);
    }

    /// [`Cmj::fill`] for a power-of-two n on a grid of at most 16 × 16, sixteen samples at a
    /// time ([`SmallGrid16::points`]), stored as the `Vec2`s they are.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn fill_small_grid_avx512(&self, first: u32, p: u32, out: &mut [Vec2]) {
        use std::arch::x86_64::*;

        let grid = SmallGrid16::new(self, p);
        // x and y of lanes 0–7, then of lanes 8–15, interleaved as `Vec2`s lie in memory.
        let low = _mm512_setr_epi32(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
        let high = _mm512_add_epi32(low, _mm512_set1_epi32(8));
        for (i, chunk) in out.chunks_mut(16).enumerate() {
            let (x, y) = grid.points(first + 16 * i as u32);
            let pairs = [_mm512_permutex2var_ps(x, low, y), _mm512_permutex2var_ps(x, high, y)];
            let floats = chunk.as_mut_ptr().cast::<f32>();
            for (h, pair) in pairs.into_iter().enumerate() {
                // The floats of this half that the chunk holds (a chunk may be short).
                let n = (2 * chunk.len()).saturating_sub(16 * h).min(16);
                // SAFETY: the masked store writes only the chunk's first 2·len floats.
                unsafe { _mm512_mask_storeu_ps(floats.add(16 * h), ((1u32 << n) - 1) as __mmask16, pair) };
            }
        }
    }

    /// Samples `first..first + xs.len()` (all < n) of pattern `p` as two columns, x into `xs`
    /// and y into `ys` (same length): [`Cmj::fill`]'s values. Returns false, writing nothing,
    /// unless this CPU has AVX-512 (see [`crate::cpu`]) and n is a power of two on a grid of at
    /// most 16 × 16, where sixteen samples at a time go straight from lanes to the columns.
    pub(crate) fn fill_columns(&self, first: u32, p: u32, xs: &mut [f32], ys: &mut [f32]) -> bool {
        #[cfg(target_arch = "x86_64")]
        if self.has_small_grid16() && crate::simd::avx512() {
            // SAFETY: the CPU has AVX-512F, checked just above.
            unsafe { self.fill_columns_avx512(first, p, xs, ys) };
            return true;
        }
        let _ = (first, p, xs, ys);
        false
    }

    /// Whether this CPU has AVX2 (see [`crate::cpu`]) and the patterns are
    /// [`QuadrantPattern`]s ([`Cmj::has_quadrant_grid`]).
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn has_quadrants(&self) -> bool {
        self.has_quadrant_grid() && crate::simd::avx2()
    }

    /// Whether the grid suits [`QuadrantPattern`]s, whatever the CPU: n a power of two on a
    /// grid of at most 16 × 16 whose m columns split into quarters (n = 16 … 256).
    #[cfg(target_arch = "x86_64")]
    fn has_quadrant_grid(&self) -> bool {
        self.has_small_grid16() && self.m.get().is_multiple_of(4)
    }

    /// Whether n is a power of two on a grid of at most 16 × 16 ([`SmallGrid16`]'s patterns).
    #[cfg(target_arch = "x86_64")]
    fn has_small_grid16(&self) -> bool {
        self.n.is_power_of_two() && self.m.get() <= 16 && self.k.get() <= 16
    }

    /// [`Cmj::fill_columns`] in AVX-512 lanes.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f")]
    fn fill_columns_avx512(&self, first: u32, p: u32, xs: &mut [f32], ys: &mut [f32]) {
        use std::arch::x86_64::*;

        assert_eq!(xs.len(), ys.len(), "one column per coordinate");
        let grid = SmallGrid16::new(self, p);
        for (i, (xs, ys)) in xs.chunks_mut(16).zip(ys.chunks_mut(16)).enumerate() {
            let (x, y) = grid.points(first + 16 * i as u32);
            let keep = ((1u32 << xs.len()) - 1) as __mmask16;
            // SAFETY: the masked stores write only the chunks' floats.
            unsafe {
                _mm512_mask_storeu_ps(xs.as_mut_ptr(), keep, x);
                _mm512_mask_storeu_ps(ys.as_mut_ptr(), keep, y);
            }
        }
    }

    #[inline(always)]
    fn fill_portable(&self, first: u32, p: u32, out: &mut [Vec2]) {
        if !self.n.is_power_of_two() {
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

/// One pattern of a [`Cmj`] whose n is a power of two on a grid of at most 16 × 16, set up
/// for sixteen samples at a time in AVX-512 lanes: the sample order's permutation and the two
/// jitters per sample (three of the five hashes) computed in lanes, the column and row
/// shuffles looked up from tables of sixteen lanes worked out once. Each lane does the scalar
/// code's operations in its order, so every value is [`Cmj::sample`]'s.
#[cfg(target_arch = "x86_64")]
pub(crate) struct SmallGrid16 {
    sc: Scrambles,
    masks: [u32; 3],
    shift: u32,
    inv: [f32; 2],
    /// Column c's shuffled sub-column in lane c (lanes past m hold values never looked up).
    by_col: std::arch::x86_64::__m512i,
    /// Row r's shuffled sub-row in lane r.
    by_row: std::arch::x86_64::__m512i,
}

#[cfg(target_arch = "x86_64")]
impl SmallGrid16 {
    /// Pattern `p` of `cmj`, which must have a small grid ([`Cmj::has_small_grid16`]).
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn new(cmj: &Cmj, p: u32) -> Self {
        use std::arch::x86_64::*;

        debug_assert!(cmj.has_small_grid16());
        let sc = Scrambles::new(p);
        let (wm, wk) = (cmj.m.mask(), cmj.k.mask());
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        // SAFETY (both calls): this function is compiled for AVX-512F.
        let by_col = unsafe { permute_pow2_lanes(_mm512_and_si512(iota, _mm512_set1_epi32(wm as i32)), wm, sc.x) };
        let by_row = unsafe { permute_pow2_lanes(_mm512_and_si512(iota, _mm512_set1_epi32(wk as i32)), wk, sc.y) };
        SmallGrid16 {
            sc,
            masks: [cmj.n.mask(), wm, wk],
            shift: cmj.m.get().trailing_zeros(),
            inv: cmj.inv,
            by_col,
            by_row,
        }
    }

    /// Samples `first..first + 16` (x lanes, y lanes); lanes past n hold values of no sample.
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn points(&self, first: u32) -> (std::arch::x86_64::__m512, std::arch::x86_64::__m512) {
        // SAFETY: this function is compiled for AVX-512F.
        self.points_of(unsafe { permute_pow2_lanes(consecutive16(first), self.masks[0], self.sc.order) })
    }

    /// The points of the shuffled samples `s` (each lane a sample's place in the pattern,
    /// after the sample order's permutation): x lanes, y lanes.
    #[target_feature(enable = "avx512f")]
    #[inline]
    fn points_of(&self, s: std::arch::x86_64::__m512i) -> (std::arch::x86_64::__m512, std::arch::x86_64::__m512) {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm512_set1_epi32(x as i32);
        let wm = self.masks[1];
        let (col, row) = (_mm512_and_si512(s, u(wm)), _mm512_srlv_epi32(s, u(self.shift)));
        let sx = _mm512_permutexvar_epi32(col, self.by_col);
        let sy = _mm512_permutexvar_epi32(row, self.by_row);
        let (jx, jy) = (randfloat_lanes(s, self.sc.jx), randfloat_lanes(s, self.sc.jy));
        let [inv_m, inv_k] = self.inv.map(|v| _mm512_set1_ps(v));
        let f = |v| _mm512_cvtepu32_ps(v);
        let x = _mm512_mul_ps(_mm512_add_ps(f(col), _mm512_mul_ps(_mm512_add_ps(f(sy), jx), inv_k)), inv_m);
        let y = _mm512_mul_ps(_mm512_add_ps(f(row), _mm512_mul_ps(_mm512_add_ps(f(sx), jy), inv_m)), inv_k);
        let below_one = _mm512_set1_ps(ONE_MINUS_EPSILON);
        (_mm512_min_ps(x, below_one), _mm512_min_ps(y, below_one))
    }
}

/// A pattern's grid set up for SIMD lanes: [`SmallGrid16`] (sixteen lanes, AVX-512F) or
/// [`SmallGrid8`] (eight, AVX2). Every method needs the grid's instruction set.
#[cfg(target_arch = "x86_64")]
pub(crate) trait GridLanes: Sized {
    /// Lanes of u32.
    type Index: U32Lanes;
    /// Lanes of f32.
    type Point: Copy;
    /// Lanes per vector.
    const WIDTH: u32;
    /// Most bits of a packet's slots that pick a column ([`QuadrantPattern`]).
    const PACKET_COLUMN_BITS: u32;
    /// Pattern `p` of `cmj`, which must have a small grid ([`Cmj::has_small_grid16`]).
    unsafe fn new(cmj: &Cmj, p: u32) -> Self;
    /// `first, first + 1, …` in lanes.
    unsafe fn consecutive(first: u32) -> Self::Index;
    /// The points of the shuffled samples `s`: x lanes, y lanes.
    unsafe fn points_of(&self, s: Self::Index) -> (Self::Point, Self::Point);
    /// Each lane's sample `s` after the sample order's permutation.
    unsafe fn shuffled(&self, s: Self::Index) -> Self::Index;
    /// The lanes whose slot (`slots`, one per lane, each below 256) is marked, slot `t` being
    /// marked where bit `t % 16` of `marks[t / 16]` is set.
    unsafe fn marked_lanes(slots: Self::Index, marks: &[u32; 16]) -> u32;
}

#[cfg(target_arch = "x86_64")]
impl GridLanes for SmallGrid16 {
    type Index = std::arch::x86_64::__m512i;
    type Point = std::arch::x86_64::__m512;
    const WIDTH: u32 = 16;
    const PACKET_COLUMN_BITS: u32 = 2;
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn new(cmj: &Cmj, p: u32) -> Self {
        SmallGrid16::new(cmj, p)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn consecutive(first: u32) -> Self::Index {
        consecutive16(first)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn points_of(&self, s: Self::Index) -> (Self::Point, Self::Point) {
        SmallGrid16::points_of(self, s)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn shuffled(&self, s: Self::Index) -> Self::Index {
        // SAFETY: this function is compiled for AVX-512F.
        unsafe { permute_pow2_lanes(s, self.masks[0], self.sc.order) }
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn marked_lanes(slots: Self::Index, marks: &[u32; 16]) -> u32 {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm512_set1_epi32(x as i32);
        // SAFETY: the load reads the sixteen entries of `marks`.
        let marks = unsafe { _mm512_loadu_si512(marks.as_ptr().cast()) };
        let word = _mm512_permutexvar_epi32(_mm512_srli_epi32::<4>(slots), marks);
        let bit = _mm512_srlv_epi32(word, _mm512_and_si512(slots, u(15)));
        _mm512_test_epi32_mask(bit, u(1)).into()
    }
}

/// [`SmallGrid16`] eight samples at a time in AVX2 lanes: the same hashes in lanes, each
/// sixteen-entry shuffle table held in two registers and looked up by two lane permutes and a
/// blend ([`lookup16`]). Every value is [`Cmj::sample`]'s.
#[cfg(target_arch = "x86_64")]
pub(crate) struct SmallGrid8 {
    sc: Scrambles,
    masks: [u32; 3],
    shift: u32,
    inv: [f32; 2],
    /// Column c's shuffled sub-column in lane c % 8 of entry c / 8 (lanes past m hold values
    /// never looked up).
    by_col: [std::arch::x86_64::__m256i; 2],
    /// Row r's shuffled sub-row, likewise.
    by_row: [std::arch::x86_64::__m256i; 2],
}

#[cfg(target_arch = "x86_64")]
impl GridLanes for SmallGrid8 {
    type Index = std::arch::x86_64::__m256i;
    type Point = std::arch::x86_64::__m256;
    const WIDTH: u32 = 8;
    const PACKET_COLUMN_BITS: u32 = 1;

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn new(cmj: &Cmj, p: u32) -> Self {
        use std::arch::x86_64::*;

        debug_assert!(cmj.has_small_grid16());
        let sc = Scrambles::new(p);
        let (wm, wk) = (cmj.m.mask(), cmj.k.mask());
        // SAFETY: this function is compiled for AVX2.
        let table = |w: u32, seed: u32| {
            [0, 8].map(|from| unsafe {
                permute_pow2_lanes(_mm256_and_si256(consecutive8(from), _mm256_set1_epi32(w as i32)), w, seed)
            })
        };
        SmallGrid8 {
            by_col: table(wm, sc.x),
            by_row: table(wk, sc.y),
            sc,
            masks: [cmj.n.mask(), wm, wk],
            shift: cmj.m.get().trailing_zeros(),
            inv: cmj.inv,
        }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn consecutive(first: u32) -> Self::Index {
        consecutive8(first)
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn points_of(&self, s: Self::Index) -> (Self::Point, Self::Point) {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm256_set1_epi32(x as i32);
        let (col, row) = (_mm256_and_si256(s, u(self.masks[1])), _mm256_srlv_epi32(s, u(self.shift)));
        let (sx, sy) = (lookup16(self.by_col, col), lookup16(self.by_row, row));
        let (jx, jy) = (randfloat_lanes8(s, self.sc.jx), randfloat_lanes8(s, self.sc.jy));
        let [inv_m, inv_k] = self.inv.map(|v| _mm256_set1_ps(v));
        // Grid indices are small: the signed conversion is exact.
        let f = |v| _mm256_cvtepi32_ps(v);
        let x = _mm256_mul_ps(_mm256_add_ps(f(col), _mm256_mul_ps(_mm256_add_ps(f(sy), jx), inv_k)), inv_m);
        let y = _mm256_mul_ps(_mm256_add_ps(f(row), _mm256_mul_ps(_mm256_add_ps(f(sx), jy), inv_m)), inv_k);
        let below_one = _mm256_set1_ps(ONE_MINUS_EPSILON);
        (_mm256_min_ps(x, below_one), _mm256_min_ps(y, below_one))
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn shuffled(&self, s: Self::Index) -> Self::Index {
        // SAFETY: this function is compiled for AVX2.
        unsafe { permute_pow2_lanes(s, self.masks[0], self.sc.order) }
    }

    #[target_feature(enable = "avx2")]
    #[inline]
    unsafe fn marked_lanes(slots: Self::Index, marks: &[u32; 16]) -> u32 {
        use std::arch::x86_64::*;

        let u = |x: u32| _mm256_set1_epi32(x as i32);
        // SAFETY: the loads read the sixteen entries of `marks`.
        let table = unsafe {
            let words = marks.as_ptr().cast::<__m256i>();
            [_mm256_loadu_si256(words), _mm256_loadu_si256(words.add(1))]
        };
        let word = lookup16(table, _mm256_srli_epi32::<4>(slots));
        let bit = _mm256_and_si256(_mm256_srlv_epi32(word, _mm256_and_si256(slots, u(15))), u(1));
        _mm256_movemask_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(bit, u(1)))) as u32
    }
}

/// Entry `i` (0 to 15) of a sixteen-entry table held as two registers of eight, in each lane.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn lookup16(table: [std::arch::x86_64::__m256i; 2], i: std::arch::x86_64::__m256i) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    // The permutes read the low three bits of each index.
    let (low, high) = (_mm256_permutevar8x32_epi32(table[0], i), _mm256_permutevar8x32_epi32(table[1], i));
    _mm256_blendv_epi8(low, high, _mm256_cmpgt_epi32(i, _mm256_set1_epi32(7)))
}

/// `first, first + 1, …, first + 7` in eight lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline]
fn consecutive8(first: u32) -> std::arch::x86_64::__m256i {
    use std::arch::x86_64::*;
    _mm256_add_epi32(_mm256_set1_epi32(first as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7))
}

/// A pattern of a [`Cmj`] whose columns fall into quarters of [0, 1) ([`Cmj::has_quadrants`]),
/// its samples taken quadrant by quadrant, `G::WIDTH` slots at a time: slots
/// `q·n/4 … (q + 1)·n/4 − 1` hold the n/4 samples whose x lies in [q/4, (q + 1)/4) (their
/// coarse columns are the m/4 columns of that quarter). A cosine direction's azimuth is 2πx,
/// so consecutive slots make rays into one quarter of the hemisphere (for n/4 ≥ the width;
/// below it one packet spans the quarters in azimuth order), with no sort. Each sample keeps
/// the point [`Cmj::sample`] gives it: only the order in which they are made changes.
///
/// A slot's bits are (low to high) its column within the quarter, its row, its quarter; a
/// shuffled sample number's are its column within the quarter, its quarter, its row, so one
/// is a swap of bit fields of the other.
#[cfg(target_arch = "x86_64")]
pub(crate) struct QuadrantPattern<'a, G> {
    grid: G,
    /// Each slot's shuffled sample number ([`Cmj::quadrant_samples`] for this width).
    samples: &'a [u32; 256],
    /// Bits of the column within a quarter (log₂ m − 2) and of the row (log₂ k).
    bits: [u32; 2],
    /// Bits of a packet's slots that pick a column and a row.
    packet_bits: [u32; 2],
}

#[cfg(target_arch = "x86_64")]
impl<'a, G: GridLanes> QuadrantPattern<'a, G> {
    /// Pattern `p` of `cmj`, which must have quadrants ([`Cmj::has_quadrants`]).
    ///
    /// # Safety
    /// The CPU must have `G`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn new(cmj: &'a Cmj, p: u32) -> Self {
        debug_assert!(cmj.has_quadrants());
        let (bits, packet_bits) = quadrant_bits(cmj, G::WIDTH, G::PACKET_COLUMN_BITS);
        let samples = &cmj.quadrant_samples[usize::from(G::WIDTH == 16)];
        // SAFETY: the caller's CPU has `G`'s instruction set.
        QuadrantPattern { grid: unsafe { G::new(cmj, p) }, samples, bits, packet_bits }
    }

    /// The points of the slots of packet `packet` (`G::WIDTH` consecutive slots): x lanes, y
    /// lanes.
    ///
    /// # Safety
    /// The CPU must have `G`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn points(&self, packet: usize) -> (G::Point, G::Point) {
        let at = G::WIDTH as usize * packet;
        // SAFETY: the caller's CPU has `G`'s instruction set.
        unsafe { self.grid.points_of(G::Index::load(&self.samples[at..at + G::WIDTH as usize])) }
    }

    /// Which of the samples `G::WIDTH·group …` (in sample order, as [`Cmj::fill`] numbers
    /// them) lie in a marked slot, slot `t` being marked where bit `t % 16` of `marks[t / 16]`
    /// is set: bit k for the group's sample k.
    ///
    /// # Safety
    /// The CPU must have `G`'s instruction set.
    #[inline(always)]
    pub(crate) unsafe fn marked(&self, group: usize, marks: &[u32; 16]) -> u32 {
        let ([a, b], [pc, pr]) = (self.bits, self.packet_bits);
        // SAFETY: the caller's CPU has `G`'s instruction set.
        unsafe {
            let s = self.grid.shuffled(G::consecutive(G::WIDTH * group as u32));
            let [col, quarter, row] = split_bits(s, [a, 2, b]);
            let [col_lo, col_hi, _] = split_bits(col, [pc, a - pc, 0]);
            let [row_lo, row_hi, _] = split_bits(row, [pr, b - pr, 0]);
            let rest = join_bits([col_hi, row_hi, quarter], [a - pc, b - pr, 2]);
            G::marked_lanes(join_bits([col_lo, row_lo, rest], [pc, pr, 0]), marks)
        }
    }
}

/// `first, first + 1, …, first + 15` in sixteen lanes.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
#[inline]
fn consecutive16(first: u32) -> std::arch::x86_64::__m512i {
    use std::arch::x86_64::*;
    let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    _mm512_add_epi32(_mm512_set1_epi32(first as i32), iota)
}

/// Each lane of `v` cut into three bit fields of `widths` bits, lowest first.
///
/// # Safety
/// The CPU must have `V`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn split_bits<V: U32Lanes>(v: V, widths: [u32; 3]) -> [V; 3] {
    // SAFETY: the caller's CPU has `V`'s instruction set.
    let field = |shift: u32, bits: u32| unsafe { v.shr(V::splat(shift)).and(V::splat((1 << bits) - 1)) };
    let [a, b, c] = widths;
    [field(0, a), field(a, b), field(a + b, c)]
}

/// Three bit fields of `widths` bits joined in each lane, the first lowest: the inverse of
/// [`split_bits`].
///
/// # Safety
/// The CPU must have `V`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn join_bits<V: U32Lanes>(fields: [V; 3], widths: [u32; 3]) -> V {
    let [x, y, z] = fields;
    // SAFETY: the caller's CPU has `V`'s instruction set.
    unsafe { x.or(y.shl(V::splat(widths[0]))).or(z.shl(V::splat(widths[0] + widths[1]))) }
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
    #[inline(always)]
    fn new(p: u32) -> Self {
        Scrambles {
            order: p.wrapping_mul(0x5163_3e2d),
            x: p.wrapping_mul(0xa511_e9b3),
            y: p.wrapping_mul(0x63d8_3595),
            jx: p.wrapping_mul(0xa399_d265),
            jy: p.wrapping_mul(0x711a_d6a5),
        }
    }
}

/// The bits of a quadrant pattern's slots ([`QuadrantPattern`]) for packets of `width` slots
/// with at most `column_bits` of them picking a column: the bits of the column within a quarter
/// and of the row, and those of a packet's slots that pick a column and a row.
#[cfg(target_arch = "x86_64")]
fn quadrant_bits(cmj: &Cmj, width: u32, column_bits: u32) -> ([u32; 2], [u32; 2]) {
    let [a, b] = [cmj.m.get().trailing_zeros() - 2, cmj.k.get().trailing_zeros()];
    let lanes = width.trailing_zeros();
    let packet_bits = if a + b <= lanes {
        [a, b]
    } else {
        let columns = a.min(column_bits).max(lanes.saturating_sub(b));
        [columns, lanes - columns]
    };
    ([a, b], packet_bits)
}

/// Slot `t`'s shuffled sample number in a quadrant pattern of these bits: its column within
/// the quarter, row and quarter (the slot's fields, packet bits lowest) rearranged as column,
/// quarter, row.
#[cfg(target_arch = "x86_64")]
fn quadrant_sample(t: u32, [a, b]: [u32; 2], [pc, pr]: [u32; 2]) -> u32 {
    let field = |v: u32, shift: u32, bits: u32| (v >> shift) & ((1 << bits) - 1);
    let (col_lo, row_lo, rest) = (field(t, 0, pc), field(t, pc, pr), t >> (pc + pr));
    let (col_hi, row_hi, quarter) =
        (field(rest, 0, a - pc), field(rest, a - pc, b - pr), field(rest, a - pc + b - pr, 2));
    let col = col_lo | col_hi << pc;
    let row = row_lo | row_hi << pr;
    col | quarter << a | row << (a + 2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cmj_is_stratified_on_the_grid_and_both_axes() {
        for n in [16u32, 12, 64] {
            let (m, k) = grid_shape(n);
            for p in [1u32, 99, 12345] {
                let pts: Vec<[f32; 2]> = (0..n).map(|s| Cmj::new(n).sample(s, p)).collect();
                let mut cells = vec![0; n as usize];
                let mut xs = vec![0; n as usize];
                let mut ys = vec![0; n as usize];
                for [x, y] in &pts {
                    cells[((y * k as f32) as u32 * m + (x * m as f32) as u32) as usize] += 1;
                    xs[(x * n as f32) as usize] += 1;
                    ys[(y * n as f32) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1), "grid, n={n}");
                assert!(xs.iter().all(|&c| c == 1) && ys.iter().all(|&c| c == 1), "1-D, n={n}");
            }
        }
    }

    /// Every fill path gives `sample`'s values: each vector copy this CPU has (AVX-512 and AVX2
    /// lanes for power-of-two grids up to 16 × 16, n ≤ 256; the vectorised loop above that,
    /// 1024 being 32 × 32), the portable loop, and the dispatch;
    /// one sample at a time for other n. So do the columns, wherever they are computed.
    #[test]
    fn fill_gives_the_samples_of_sample() {
        type Fill = fn(&Cmj, u32, u32, &mut [Vec2]);
        let mut fills: Vec<(&str, Fill)> =
            vec![("fill", Cmj::fill), ("portable", |c, f, p, o| c.fill_portable(f, p, o))];
        #[cfg(target_arch = "x86_64")]
        {
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2, checked just above.
                fills.push(("avx2", |c, f, p, o| unsafe { c.fill_avx2(f, p, o) }));
            }
            if std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F, checked just above.
                fills.push(("avx512", |c, f, p, o| unsafe { c.fill_avx512(f, p, o) }));
            }
        }
        for n in [1u32, 2, 8, 12, 16, 32, 64, 128, 256, 1024] {
            let cmj = Cmj::new(n);
            for p in [0u32, 1, 99, 0xdead_beef] {
                for first in [0, n / 3, n - 1] {
                    for (name, fill) in &fills {
                        let mut out = vec![Vec2::NAN; (n - first) as usize];
                        fill(&cmj, first, p, &mut out);
                        for (s, v) in (first..).zip(&out) {
                            assert_eq!(v.to_array(), cmj.sample(s, p), "{name}: n {n}, p {p}, s {s}");
                        }
                    }
                    let (mut xs, mut ys) = (vec![f32::NAN; (n - first) as usize], vec![f32::NAN; (n - first) as usize]);
                    if cmj.fill_columns(first, p, &mut xs, &mut ys) {
                        for (s, (&x, &y)) in (first..).zip(xs.iter().zip(&ys)) {
                            assert_eq!([x, y], cmj.sample(s, p), "columns: n {n}, p {p}, s {s}");
                        }
                    } else {
                        #[cfg(target_arch = "x86_64")]
                        assert!(!(crate::simd::avx512() && cmj.has_small_grid16()), "n {n}: columns refused");
                        assert!(xs.iter().chain(&ys).all(|v| v.is_nan()), "refused, yet written");
                    }
                }
            }
        }
    }

    /// The slot tables of both packet widths, on every CPU (the patterns' own test below runs
    /// each width only where the CPU has its lanes): each is a permutation of the samples, and
    /// slot t holds a sample of quarter t / (n/4), its coarse column in that quarter of the m.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn quadrant_slot_tables_put_each_sample_once_in_its_quarter() {
        for n in [16u32, 32, 64, 128, 256] {
            let cmj = Cmj::new(n);
            let (m, a) = (cmj.m.get(), cmj.m.get().trailing_zeros() - 2);
            for (w, table) in cmj.quadrant_samples.iter().enumerate() {
                let mut seen = vec![false; n as usize];
                for (t, &s) in table[..n as usize].iter().enumerate() {
                    assert!(s < n && !seen[s as usize], "n {n}, width {}: sample {s} twice or out of range", 8 << w);
                    seen[s as usize] = true;
                    // The shuffled sample number's bits: column within the quarter, quarter, row;
                    // the low a + 2 are the coarse column.
                    let column = s & ((4 << a) - 1);
                    assert_eq!(column / (m / 4), t as u32 / (n / 4), "n {n}, width {}: slot {t}", 8 << w);
                }
                assert!(table[n as usize..].iter().all(|&s| s == 0), "n {n}: entries past n");
            }
        }
    }

    /// A quadrant pattern's slots hold every sample of the pattern once, each at
    /// [`Cmj::sample`]'s point, quarter by quarter of x (so of the azimuth 2πx); and a mark on
    /// a slot reads back on exactly the sample whose point that slot holds. For each width
    /// this CPU has: eight lanes (AVX2) and sixteen (AVX-512).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn quadrant_patterns_hold_each_sample_once_in_its_quarter() {
        use std::arch::x86_64::*;

        for n in [4u32, 8, 12, 16, 32, 64, 128, 256, 512] {
            let cmj = Cmj::new(n);
            let splits = [16, 32, 64, 128, 256].contains(&n);
            if !crate::simd::avx2() {
                assert!(!cmj.has_quadrants(), "n {n}: quadrants without AVX2");
                continue;
            }
            assert_eq!(cmj.has_quadrants(), splits, "n {n}");
            if !splits {
                continue;
            }
            for p in [0u32, 1, 99, 0xdead_beef] {
                // SAFETY (every block): the CPU has AVX2, checked above.
                let pattern = unsafe { QuadrantPattern::<SmallGrid8>::new(&cmj, p) };
                let points = |packet| {
                    let (mut x, mut y) = ([0.0f32; 8], [0.0f32; 8]);
                    unsafe {
                        let (xs, ys) = pattern.points(packet);
                        _mm256_storeu_ps(x.as_mut_ptr(), xs);
                        _mm256_storeu_ps(y.as_mut_ptr(), ys);
                    }
                    (x.to_vec(), y.to_vec())
                };
                let marked = |g, marks: &[u32; 16]| unsafe { pattern.marked(g, marks) };
                slots_hold_their_samples(&cmj, p, 8, points, marked);
                if !crate::simd::avx512() {
                    continue;
                }
                // SAFETY (every block): the CPU has AVX-512F, checked just above.
                let pattern = unsafe { QuadrantPattern::<SmallGrid16>::new(&cmj, p) };
                let points = |packet| {
                    let (mut x, mut y) = ([0.0f32; 16], [0.0f32; 16]);
                    unsafe {
                        let (xs, ys) = pattern.points(packet);
                        _mm512_storeu_ps(x.as_mut_ptr(), xs);
                        _mm512_storeu_ps(y.as_mut_ptr(), ys);
                    }
                    (x.to_vec(), y.to_vec())
                };
                let marked = |g, marks: &[u32; 16]| unsafe { pattern.marked(g, marks) };
                slots_hold_their_samples(&cmj, p, 16, points, marked);
            }
        }
    }

    /// The checks of the test above for one pattern `p` of `cmj` taken `width` slots at a time
    /// (n / `width` packets): `points(packet)` gives a packet's x and y, `marked(group, marks)`
    /// the samples of a group that `marks` (bit t % 16 of word t / 16 for slot t) marks.
    #[cfg(target_arch = "x86_64")]
    fn slots_hold_their_samples(
        cmj: &Cmj,
        p: u32,
        width: usize,
        points: impl Fn(usize) -> (Vec<f32>, Vec<f32>),
        marked: impl Fn(usize, &[u32; 16]) -> u32,
    ) {
        let n = cmj.n.get();
        let packets = n as usize / width;
        // Each slot's point, bit for bit.
        let slots: Vec<[f32; 2]> = (0..packets)
            .flat_map(|packet| {
                let (x, y) = points(packet);
                x.into_iter().zip(y).map(|(x, y)| [x, y])
            })
            .collect();
        let samples: Vec<[f32; 2]> = (0..n).map(|s| cmj.sample(s, p)).collect();
        let quarter = n as usize / 4;
        for (t, point) in slots.iter().enumerate() {
            let q = (t / quarter) as f32;
            assert!((q / 4.0..(q + 1.0) / 4.0).contains(&point[0]), "n {n}, p {p}: slot {t} at x {}", point[0]);
            let owners: Vec<usize> = (0..n as usize).filter(|&s| samples[s] == *point).collect();
            assert_eq!(owners.len(), 1, "n {n}, p {p}: slot {t} holds no single sample");
            // A mark on this slot alone reads back on its sample alone.
            let mut marks = [0u32; 16];
            marks[t / 16] = 1 << (t % 16);
            let marked: Vec<usize> = (0..packets)
                .flat_map(|g| {
                    let bits = marked(g, &marks);
                    (0..width).filter(move |k| bits & (1 << k) != 0).map(move |k| width * g + k)
                })
                .collect();
            assert_eq!(marked, owners, "n {n}, p {p}, width {width}: slot {t}");
        }
    }
}
