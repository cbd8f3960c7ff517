//! Eight lanes in an AVX register, for CPUs with x86-64-v3 ([`super::avx2()`]).

use std::arch::x86_64::*;

use glam::{Vec2, Vec3A};

use super::{FusedLanes, Kernel, Lanes, SampleLanes};

/// Eight lanes in an AVX register.
#[derive(Clone, Copy)]
pub(crate) struct Avx(pub(crate) __m256);

impl FusedLanes for Avx {
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn mul_add(self, b: Self, c: Self) -> Self {
        Avx(_mm256_fmadd_ps(self.0, b.0, c.0))
    }
}

impl SampleLanes for Avx {
    type U32 = __m256i;

    /// AVX2 has no unsigned conversion: the high and low halves convert exactly and their sum
    /// rounds once, which is the conversion's rounding.
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn from_u32(i: __m256i) -> Self {
        let high = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32::<16>(i)), _mm256_set1_ps(65_536.0));
        let low = _mm256_cvtepi32_ps(_mm256_and_si256(i, _mm256_set1_epi32(0xffff)));
        Avx(_mm256_add_ps(high, low))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn from_small_u32(i: __m256i) -> Self {
        Avx(_mm256_cvtepi32_ps(i))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn store_points(x: Self, y: Self, out: &mut [Vec2]) {
        let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
        // (x, y) pairs as `Vec2`s lie in memory: points 0–3, then 4–7.
        let (low, high) = (_mm256_unpacklo_ps(x.0, y.0), _mm256_unpackhi_ps(x.0, y.0));
        let pairs = [_mm256_permute2f128_ps::<0x20>(low, high), _mm256_permute2f128_ps::<0x31>(low, high)];
        let floats = out.as_mut_ptr().cast::<f32>();
        for (h, pair) in pairs.into_iter().enumerate() {
            // The floats of this half that `out` holds (it may be short).
            let n = (2 * out.len()).saturating_sub(8 * h).min(8) as i32;
            let keep = _mm256_cmpgt_epi32(_mm256_set1_epi32(n), iota);
            // SAFETY: a `Vec2` is two f32 (`repr(C)`); the masked store writes only the first
            // 2·len floats of `out`.
            unsafe { _mm256_maskstore_ps(floats.wrapping_add(8 * h), keep, pair) };
        }
    }
}

/// The transpose of eight rows of eight floats: lane k of row c becomes lane c of row k.
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline]
pub(crate) fn transpose8(row: &[__m256; 8]) -> [__m256; 8] {
    // Rows 2i and 2i + 1 interleaved: pairs[2i] holds elements 0 and 1 of each 128-bit block,
    // pairs[2i + 1] elements 2 and 3.
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

impl Lanes for Avx {
    const WIDTH: usize = 8;
    type Mask = __m256;

    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn splat(x: f32) -> Self {
        Avx(_mm256_set1_ps(x))
    }
    /// Lane by lane, without a branch.
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn places(groups: &[u32; 4], start: &[u32; 4], none: u32) -> [u32; 16] {
        super::lanes::places8(groups, start, none)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn load(x: &[f32]) -> Self {
        let x = &x[..8];
        // SAFETY: eight floats, checked above.
        unsafe { Avx(_mm256_loadu_ps(x.as_ptr())) }
    }
    #[inline(always)]
    fn lane(&self, j: usize) -> f32 {
        // SAFETY: an `__m256` is eight f32 in memory.
        let floats = unsafe { &*(&raw const self.0).cast::<[f32; 8]>() };
        floats[j]
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn store(self, out: &mut [f32]) {
        let out = &mut out[..8];
        // SAFETY: eight floats, checked above.
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) }
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn add_to(x: Self, y: Self, z: Self, out: &mut [Vec3A]) {
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
            // SAFETY: `out` holds eight `Vec3A`s (16 bytes each), checked above.
            unsafe {
                let at = p.add(8 * j);
                _mm256_storeu_ps(at, _mm256_add_ps(_mm256_loadu_ps(at), pair));
            }
        }
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn add(self, b: Self) -> Self {
        Avx(_mm256_add_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn sub(self, b: Self) -> Self {
        Avx(_mm256_sub_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn mul(self, b: Self) -> Self {
        Avx(_mm256_mul_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn div(self, b: Self) -> Self {
        Avx(_mm256_div_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn neg(self) -> Self {
        Avx(_mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn sqrt(self) -> Self {
        Avx(_mm256_sqrt_ps(self.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn abs(self) -> Self {
        Avx(_mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn max_keep(self, b: Self) -> Self {
        Avx(_mm256_max_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn min_keep(self, b: Self) -> Self {
        Avx(_mm256_min_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn lt(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn gt(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn le(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn ne(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_NEQ_UQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn eq_or_nan(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_EQ_UQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn select(self, m: __m256, if_set: Self) -> Self {
        Avx(_mm256_blendv_ps(self.0, if_set.0, m))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn and(a: __m256, b: __m256) -> __m256 {
        _mm256_and_ps(a, b)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn or(a: __m256, b: __m256) -> __m256 {
        _mm256_or_ps(a, b)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn andnot(a: __m256, b: __m256) -> __m256 {
        _mm256_andnot_ps(a, b)
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn least(self) -> f32 {
        let m = _mm_min_ps(_mm256_castps256_ps128(self.0), _mm256_extractf128_ps::<1>(self.0));
        let m = _mm_min_ps(m, _mm_movehl_ps(m, m));
        _mm_cvtss_f32(_mm_min_ss(m, _mm_movehdup_ps(m)))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn greatest(self) -> f32 {
        let m = _mm_max_ps(_mm256_castps256_ps128(self.0), _mm256_extractf128_ps::<1>(self.0));
        let m = _mm_max_ps(m, _mm_movehl_ps(m, m));
        _mm_cvtss_f32(_mm_max_ss(m, _mm_movehdup_ps(m)))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn bits(m: __m256) -> u32 {
        _mm256_movemask_ps(m) as u32
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline]
    unsafe fn mask(bits: u32) -> __m256 {
        let bit = _mm256_setr_epi32(1, 2, 4, 8, 16, 32, 64, 128);
        _mm256_castsi256_ps(_mm256_cmpeq_epi32(_mm256_and_si256(_mm256_set1_epi32(bits as i32), bit), bit))
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn compiled<K: Kernel<Self>>(kernel: K) -> K::Output {
        // SAFETY: compiled for x86-64-v3, which the caller's CPU has.
        unsafe { kernel.run() }
    }
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline(never)]
    unsafe fn compiled_apart<K: Kernel<Self>>(kernel: K) -> K::Output {
        // SAFETY: compiled for x86-64-v3, which the caller's CPU has.
        unsafe { kernel.run() }
    }
}
