//! Eight lanes in an AVX register, for CPUs with x86-64-v3 ([`super::HasAvx2`]).

use std::arch::x86_64::*;

use glam::{Vec2, Vec3A};

use super::{
    BitLanes, CompressLanes, FusedLanes, HasAvx2, Kernel, Lanes, SampleLanes, lanes::isa_methods, u32_lanes::U32x8,
};

/// Eight lanes in an AVX register. The field is private: a value is made only from a
/// [`HasAvx2`] token or from other values, so it proves the CPU has x86-64-v3.
#[derive(Clone, Copy)]
pub(crate) struct Avx(__m256);

/// A lane mask of [`Avx`]: all bits of a lane set or clear.
#[derive(Clone, Copy)]
pub(crate) struct AvxMask(__m256);

impl Avx {
    /// The lanes of register `x`.
    #[inline(always)]
    pub(crate) fn from_raw(_: HasAvx2, x: __m256) -> Self {
        Avx(x)
    }

    /// The register.
    #[inline(always)]
    pub(crate) fn raw(self) -> __m256 {
        self.0
    }
}

impl FusedLanes for Avx {
    isa_methods! {
        fn mul_add(self, b: Self, c: Self) -> Self {
            Avx(_mm256_fmadd_ps(self.0, b.0, c.0))
        }
    }
}

impl SampleLanes for Avx {
    type U32 = U32x8;

    isa_methods! {
        /// AVX2 has no unsigned conversion: the high and low halves convert exactly and their
        /// sum rounds once, which is the conversion's rounding.
        fn from_u32(i: U32x8) -> Self {
            let i = i.0;
            let high = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(i)), _mm256_set1_ps(65_536.0));
            let low = _mm256_cvtepi32_ps(_mm256_and_si256(i, _mm256_set1_epi32(0xffff)));
            Avx(_mm256_add_ps(high, low))
        }
        fn from_small_u32(i: U32x8) -> Self {
            Avx(_mm256_cvtepi32_ps(i.0))
        }
        fn truncate_small(self) -> U32x8 {
            U32x8(_mm256_cvttps_epi32(self.0))
        }
        fn store_points(x: Self, y: Self, out: &mut [Vec2]) {
            let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
            // (x, y) pairs as `Vec2`s lie in memory: points 0–3, then 4–7.
            let (low, high) = (_mm256_unpacklo_ps(x.0, y.0), _mm256_unpackhi_ps(x.0, y.0));
            let pairs = [_mm256_permute2f128_ps::<0x20>(low, high), _mm256_permute2f128_ps::<0x31>(low, high)];
            let floats = out.as_mut_ptr().cast::<f32>();
            for (h, pair) in pairs.into_iter().enumerate() {
                // The floats of this half that `out` holds (it may be short).
                let n = (2 * out.len()).saturating_sub(8 * h).min(8) as i32;
                let keep = _mm256_cmpgt_epi32(_mm256_set1_epi32(n), iota);
                // A `Vec2` is two f32 (`repr(C)`); the masked store writes only the first
                // 2·len floats of `out`.
                _mm256_maskstore_ps(floats.wrapping_add(8 * h), keep, pair);
            }
        }
    }
}

/// For each 8-bit lane mask, the indices of its set lanes in order, a byte each from the
/// lowest (bytes past them 0): the permutation that compresses those lanes to the front.
const COMPRESS: [u64; 256] = {
    let mut table = [0u64; 256];
    let mut m = 0;
    while m < 256 {
        let (mut packed, mut n, mut lane) = (0u64, 0, 0);
        while lane < 8 {
            if m >> lane & 1 != 0 {
                packed |= (lane as u64) << (8 * n);
                n += 1;
            }
            lane += 1;
        }
        table[m] = packed;
        m += 1;
    }
    table
};

/// The lanes below `n` (at most eight) set, as a mask for AVX2's masked loads and stores.
#[inline(always)]
fn first_lanes(_: HasAvx2, n: usize) -> __m256i {
    // SAFETY: the token proves the CPU has x86-64-v3.
    unsafe { _mm256_cmpgt_epi32(_mm256_set1_epi32(n.min(8) as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)) }
}

/// The permutation that moves the lanes of `m` (its low eight bits) to the front, in order.
#[inline(always)]
fn compress_permutation(_: HasAvx2, m: u32) -> __m256i {
    // SAFETY: the token proves the CPU has x86-64-v3.
    unsafe { _mm256_cvtepu8_epi32(_mm_cvtsi64_si128(COMPRESS[(m & 0xff) as usize] as i64)) }
}

/// AVX2 has no compressing store: the lanes are permuted to the front by a table of the 256
/// masks' permutations, then the first ones stored under a mask.
impl CompressLanes for Avx {
    isa_methods! {
        fn load_partial(isa: HasAvx2, x: &[f32]) -> Self {
            // The masked load reads only the first `x.len()` floats (at most eight): masked-out
            // lanes are not read and cannot fault.
            Avx(_mm256_maskload_ps(x.as_ptr(), first_lanes(isa, x.len())))
        }
        fn compress_store(self, m: u32, out: &mut [f32]) {
            let n = (m & 0xff).count_ones() as usize;
            let out = &mut out[..n];
            let isa = self.isa();
            let packed = _mm256_permutevar8x32_ps(self.0, compress_permutation(isa, m));
            // The masked store writes the first `n` floats of `out`, checked above.
            _mm256_maskstore_ps(out.as_mut_ptr(), first_lanes(isa, n), packed)
        }
        fn compress_indices(isa: HasAvx2, base: u32, m: u32, out: &mut [u32]) {
            let n = (m & 0xff).count_ones() as usize;
            let out = &mut out[..n];
            let index = _mm256_add_epi32(_mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7), _mm256_set1_epi32(base as i32));
            let packed = _mm256_permutevar8x32_epi32(index, compress_permutation(isa, m));
            // The masked store writes the first `n` integers of `out`, checked above.
            _mm256_maskstore_epi32(out.as_mut_ptr().cast(), first_lanes(isa, n), packed)
        }
        fn store_partial(self, out: &mut [f32]) {
            // The masked store writes only the first `out.len()` floats (at most eight).
            _mm256_maskstore_ps(out.as_mut_ptr(), first_lanes(self.isa(), out.len()), self.0)
        }
    }
}

/// The float bit operations of `geometry::hit`'s SSE `step_away`, eight lanes wide.
impl BitLanes for Avx {
    isa_methods! {
        fn copysign(self, sign: Self) -> Self {
            let magnitude = _mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0);
            Avx(_mm256_or_ps(magnitude, _mm256_and_ps(sign.0, _mm256_set1_ps(-0.0))))
        }
        fn step_away(self, o: Self) -> Self {
            let (v, o, zero) = (self.0, o.0, _mm256_setzero_ps());
            let mask = |m: __m256| _mm256_castps_si256(m);
            let blend = |m: __m256i, a: __m256i, b: __m256i| _mm256_blendv_epi8(b, a, m);
            let bits = _mm256_castps_si256(v);
            let (up, down) = (mask(_mm256_cmp_ps::<_CMP_GT_OQ>(o, zero)), mask(_mm256_cmp_ps::<_CMP_LT_OQ>(o, zero)));
            let positive = mask(_mm256_cmp_ps::<_CMP_GT_OQ>(v, zero));
            // Away from zero (+1 on the bits) when moving up from a positive value or down from
            // a negative one (a NaN counts as negative), towards it (−1) otherwise.
            let away = _mm256_xor_si256(_mm256_xor_si256(up, positive), _mm256_set1_epi32(-1));
            let moved = _mm256_add_epi32(bits, blend(away, _mm256_set1_epi32(1), _mm256_set1_epi32(-1)));
            // From either zero: the least positive float up, the least negative one down.
            let from_zero = blend(up, _mm256_set1_epi32(1), _mm256_set1_epi32(0x8000_0001_u32 as i32));
            let moved = blend(mask(_mm256_cmp_ps::<_CMP_EQ_OQ>(v, zero)), from_zero, moved);
            // Infinities stay where they are the far end.
            let at_end = _mm256_or_si256(
                _mm256_and_si256(up, mask(_mm256_cmp_ps::<_CMP_EQ_OQ>(v, _mm256_set1_ps(f32::INFINITY)))),
                _mm256_and_si256(down, mask(_mm256_cmp_ps::<_CMP_EQ_OQ>(v, _mm256_set1_ps(f32::NEG_INFINITY)))),
            );
            let moves = _mm256_andnot_si256(at_end, _mm256_or_si256(up, down));
            Avx(_mm256_castsi256_ps(blend(moves, moved, bits)))
        }
    }
}

/// The transpose of eight rows of eight floats: lane k of row c becomes lane c of row k.
#[inline(always)]
pub(crate) fn transpose8(_: HasAvx2, row: &[__m256; 8]) -> [__m256; 8] {
    // SAFETY: the token proves the CPU has x86-64-v3; inlined, the intrinsics compile into
    // the `#[target_feature]` copy that calls this.
    unsafe {
        // Rows 2i and 2i + 1 interleaved: pairs[2i] holds elements 0 and 1 of each 128-bit
        // block, pairs[2i + 1] elements 2 and 3.
        let mut pairs = [_mm256_setzero_pd(); 8];
        for i in 0..4 {
            pairs[2 * i] = _mm256_castps_pd(_mm256_unpacklo_ps(row[2 * i], row[2 * i + 1]));
            pairs[2 * i + 1] = _mm256_castps_pd(_mm256_unpackhi_ps(row[2 * i], row[2 * i + 1]));
        }
        let mut out = [_mm256_setzero_ps(); 8];
        for e in 0..4 {
            // Element e of each block of rows 0..4 (q0) and 4..8 (q1).
            let h = e / 2;
            let (q0, q1) = if e % 2 == 0 {
                (_mm256_unpacklo_pd(pairs[h], pairs[2 + h]), _mm256_unpacklo_pd(pairs[4 + h], pairs[6 + h]))
            } else {
                (_mm256_unpackhi_pd(pairs[h], pairs[2 + h]), _mm256_unpackhi_pd(pairs[4 + h], pairs[6 + h]))
            };
            let (q0, q1) = (_mm256_castpd_ps(q0), _mm256_castpd_ps(q1));
            out[e] = _mm256_permute2f128_ps::<0x20>(q0, q1);
            out[e + 4] = _mm256_permute2f128_ps::<0x31>(q0, q1);
        }
        out
    }
}

impl Lanes for Avx {
    const WIDTH: usize = 8;
    type Mask = AvxMask;
    type Isa = HasAvx2;

    #[inline(always)]
    fn isa(self) -> HasAvx2 {
        HasAvx2(())
    }
    #[inline(always)]
    fn lane(&self, j: usize) -> f32 {
        // SAFETY: an `__m256` is eight f32 in memory.
        let floats = unsafe { &*(&raw const self.0).cast::<[f32; 8]>() };
        floats[j]
    }
    /// Lane by lane, without a branch.
    #[inline(always)]
    fn places(_: HasAvx2, groups: &[u32; 4], start: &[u32; 4], none: u32) -> [u32; 16] {
        super::lanes::places8(groups, start, none)
    }
    #[inline(always)]
    fn bits(m: AvxMask) -> u32 {
        // SAFETY: an `AvxMask` proves the CPU has x86-64-v3, as an `Avx` does.
        unsafe { _mm256_movemask_ps(m.0) as u32 }
    }
    isa_methods! {
        fn splat(_: HasAvx2, x: f32) -> Self {
            Avx(_mm256_set1_ps(x))
        }
        fn load(_: HasAvx2, x: &[f32]) -> Self {
            let x = &x[..8];
            // Eight floats, checked above.
            Avx(_mm256_loadu_ps(x.as_ptr()))
        }
        fn store(self, out: &mut [f32]) {
            let out = &mut out[..8];
            // Eight floats, checked above.
            _mm256_storeu_ps(out.as_mut_ptr(), self.0)
        }
        fn add_to(x: Self, y: Self, z: Self, out: &mut [Vec3A]) {
            let out = &mut out[..8];
            let xy_lo = _mm256_castps_pd(_mm256_unpacklo_ps(x.0, y.0));
            let xy_hi = _mm256_castps_pd(_mm256_unpackhi_ps(x.0, y.0));
            let zz_lo = _mm256_castps_pd(_mm256_unpacklo_ps(z.0, z.0));
            let zz_hi = _mm256_castps_pd(_mm256_unpackhi_ps(z.0, z.0));
            // Block i of rows[j]: element 4i + j as (x, y, z, z).
            let rows = [
                _mm256_castpd_ps(_mm256_unpacklo_pd(xy_lo, zz_lo)),
                _mm256_castpd_ps(_mm256_unpackhi_pd(xy_lo, zz_lo)),
                _mm256_castpd_ps(_mm256_unpacklo_pd(xy_hi, zz_hi)),
                _mm256_castpd_ps(_mm256_unpackhi_pd(xy_hi, zz_hi)),
            ];
            // Elements 2j and 2j + 1, as they lie in memory.
            let pairs = [
                _mm256_permute2f128_ps::<0x20>(rows[0], rows[1]),
                _mm256_permute2f128_ps::<0x20>(rows[2], rows[3]),
                _mm256_permute2f128_ps::<0x31>(rows[0], rows[1]),
                _mm256_permute2f128_ps::<0x31>(rows[2], rows[3]),
            ];
            let p = out.as_mut_ptr().cast::<f32>();
            for (j, pair) in pairs.into_iter().enumerate() {
                // `out` holds eight `Vec3A`s (16 bytes each), checked above.
                let at = p.add(8 * j);
                _mm256_storeu_ps(at, _mm256_add_ps(_mm256_loadu_ps(at), pair));
            }
        }
        fn add(self, b: Self) -> Self {
            Avx(_mm256_add_ps(self.0, b.0))
        }
        fn sub(self, b: Self) -> Self {
            Avx(_mm256_sub_ps(self.0, b.0))
        }
        fn mul(self, b: Self) -> Self {
            Avx(_mm256_mul_ps(self.0, b.0))
        }
        fn div(self, b: Self) -> Self {
            Avx(_mm256_div_ps(self.0, b.0))
        }
        fn neg(self) -> Self {
            Avx(_mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)))
        }
        fn sqrt(self) -> Self {
            Avx(_mm256_sqrt_ps(self.0))
        }
        fn abs(self) -> Self {
            Avx(_mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0))
        }
        fn max_keep(self, b: Self) -> Self {
            Avx(_mm256_max_ps(self.0, b.0))
        }
        fn min_keep(self, b: Self) -> Self {
            Avx(_mm256_min_ps(self.0, b.0))
        }
        fn lt(self, b: Self) -> AvxMask {
            AvxMask(_mm256_cmp_ps::<_CMP_LT_OQ>(self.0, b.0))
        }
        fn gt(self, b: Self) -> AvxMask {
            AvxMask(_mm256_cmp_ps::<_CMP_GT_OQ>(self.0, b.0))
        }
        fn le(self, b: Self) -> AvxMask {
            AvxMask(_mm256_cmp_ps::<_CMP_LE_OQ>(self.0, b.0))
        }
        fn ne(self, b: Self) -> AvxMask {
            AvxMask(_mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, b.0))
        }
        fn eq_or_nan(self, b: Self) -> AvxMask {
            AvxMask(_mm256_cmp_ps::<_CMP_EQ_UQ>(self.0, b.0))
        }
        fn select(self, m: AvxMask, if_set: Self) -> Self {
            Avx(_mm256_blendv_ps(self.0, if_set.0, m.0))
        }
        fn and(a: AvxMask, b: AvxMask) -> AvxMask {
            AvxMask(_mm256_and_ps(a.0, b.0))
        }
        fn or(a: AvxMask, b: AvxMask) -> AvxMask {
            AvxMask(_mm256_or_ps(a.0, b.0))
        }
        fn andnot(a: AvxMask, b: AvxMask) -> AvxMask {
            AvxMask(_mm256_andnot_ps(a.0, b.0))
        }
        fn least(self) -> f32 {
            let m = _mm_min_ps(_mm256_castps256_ps128(self.0), _mm256_extractf128_ps::<1>(self.0));
            let m = _mm_min_ps(m, _mm_movehl_ps(m, m));
            _mm_cvtss_f32(_mm_min_ss(m, _mm_movehdup_ps(m)))
        }
        fn greatest(self) -> f32 {
            let m = _mm_max_ps(_mm256_castps256_ps128(self.0), _mm256_extractf128_ps::<1>(self.0));
            let m = _mm_max_ps(m, _mm_movehl_ps(m, m));
            _mm_cvtss_f32(_mm_max_ss(m, _mm_movehdup_ps(m)))
        }
        fn mask(_: HasAvx2, bits: u32) -> AvxMask {
            let bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
            AvxMask(_mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits as i32), bit), bit)))
        }
    }
    #[inline(always)]
    fn compiled<K: Kernel<Self>>(isa: HasAvx2, kernel: K) -> K::Output {
        // SAFETY: the token proves the CPU has x86-64-v3, which the copy is compiled for.
        unsafe { compiled_v3(isa, kernel) }
    }
    #[inline(always)]
    fn compiled_apart<K: Kernel<Self>>(isa: HasAvx2, kernel: K) -> K::Output {
        // SAFETY: the token proves the CPU has x86-64-v3, which the copy is compiled for.
        unsafe { compiled_apart_v3(isa, kernel) }
    }
}

/// [`Lanes::compiled`] for [`Avx`]: the `#[target_feature]` copy of `kernel`.
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn compiled_v3<K: Kernel<Avx>>(isa: HasAvx2, kernel: K) -> K::Output {
    kernel.run(isa)
}

/// [`Lanes::compiled_apart`] for [`Avx`].
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline(never)]
fn compiled_apart_v3<K: Kernel<Avx>>(isa: HasAvx2, kernel: K) -> K::Output {
    kernel.run(isa)
}
