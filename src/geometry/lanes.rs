//! Rays in SIMD lanes, for packet traversal: eight per AVX register ([`Avx`]) or sixteen per
//! AVX-512 register ([`Avx512`]). Each operation is one IEEE operation of the single-ray code
//! (no fused multiply-adds), so a lane computes bit for bit what that ray's own traversal does.
//!
//! Every method is `unsafe` and compiled for its type's instruction set, which the CPU must
//! have; callers are generic code inlined into functions compiled for it, where the methods
//! inline in turn.

use std::arch::x86_64::*;

use super::ray::Ray;

/// `N` scalars of each of `rays` (one to `L::WIDTH`; `fields` picks them) laid out for
/// [`Lanes::load`]: `columns[c][k]` is field `c` of ray `k`, lanes past the last ray repeating
/// it. `fields` reads scalars only, so it needs no instruction set of its own.
#[inline(always)]
pub(crate) fn columns<L: Lanes, const N: usize>(rays: &[Ray], fields: impl Fn(&Ray) -> [f32; N]) -> [[f32; 16]; N] {
    let mut columns = [[0.0f32; 16]; N];
    for k in 0..L::WIDTH {
        let values = fields(&rays[k.min(rays.len() - 1)]);
        for c in 0..N {
            columns[c][k] = values[c];
        }
    }
    columns
}

/// A vector of f32 lanes, one per ray of a packet, with a mask of one bit per lane.
pub(crate) trait Lanes: Copy {
    /// Lanes per vector.
    const WIDTH: usize;
    /// A lane mask.
    type Mask: Copy;

    /// `x` in every lane.
    unsafe fn splat(x: f32) -> Self;
    /// Lanes `0..WIDTH` of `x`.
    unsafe fn load(x: &[f32; 16]) -> Self;
    /// Writes the lanes to `out[0..WIDTH]`.
    unsafe fn store(self, out: &mut [f32; 16]);
    /// `self + b`.
    unsafe fn add(self, b: Self) -> Self;
    /// `self − b`.
    unsafe fn sub(self, b: Self) -> Self;
    /// `self · b`.
    unsafe fn mul(self, b: Self) -> Self;
    /// `self / b`.
    unsafe fn div(self, b: Self) -> Self;
    /// `−self`.
    unsafe fn neg(self) -> Self;
    /// `|self|`.
    unsafe fn abs(self) -> Self;
    /// `max(self, b)`, `b` where either is NaN (`maxps`).
    unsafe fn max_keep(self, b: Self) -> Self;
    /// `min(self, b)`, `b` where either is NaN (`minps`).
    unsafe fn min_keep(self, b: Self) -> Self;
    /// `self < b` (false for NaN).
    unsafe fn lt(self, b: Self) -> Self::Mask;
    /// `self > b` (false for NaN).
    unsafe fn gt(self, b: Self) -> Self::Mask;
    /// `self ≤ b` (false for NaN).
    unsafe fn le(self, b: Self) -> Self::Mask;
    /// `self == b`, or either is NaN.
    unsafe fn eq_or_nan(self, b: Self) -> Self::Mask;
    /// `if_set` in the lanes of `m`, `self` elsewhere.
    unsafe fn select(self, m: Self::Mask, if_set: Self) -> Self;
    /// Lanes in both masks.
    unsafe fn and(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Lanes in either mask.
    unsafe fn or(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Lanes in `b` and not in `a`.
    unsafe fn andnot(a: Self::Mask, b: Self::Mask) -> Self::Mask;
    /// Bit `i` set for lane `i` in the mask.
    unsafe fn bits(m: Self::Mask) -> u32;
}

/// Eight lanes in an AVX register.
#[derive(Clone, Copy)]
pub(crate) struct Avx(__m256);

/// Sixteen lanes in an AVX-512 register.
#[derive(Clone, Copy)]
pub(crate) struct Avx512(__m512);

impl Lanes for Avx {
    const WIDTH: usize = 8;
    type Mask = __m256;

    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn splat(x: f32) -> Self {
        Avx(_mm256_set1_ps(x))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn load(x: &[f32; 16]) -> Self {
        unsafe { Avx(_mm256_loadu_ps(x.as_ptr())) }
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn store(self, out: &mut [f32; 16]) {
        unsafe { _mm256_storeu_ps(out.as_mut_ptr(), self.0) }
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn add(self, b: Self) -> Self {
        Avx(_mm256_add_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn sub(self, b: Self) -> Self {
        Avx(_mm256_sub_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn mul(self, b: Self) -> Self {
        Avx(_mm256_mul_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn div(self, b: Self) -> Self {
        Avx(_mm256_div_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn neg(self) -> Self {
        Avx(_mm256_xor_ps(self.0, _mm256_set1_ps(-0.0)))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn abs(self) -> Self {
        Avx(_mm256_andnot_ps(_mm256_set1_ps(-0.0), self.0))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn max_keep(self, b: Self) -> Self {
        Avx(_mm256_max_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn min_keep(self, b: Self) -> Self {
        Avx(_mm256_min_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn lt(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_LT_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn gt(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn le(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn eq_or_nan(self, b: Self) -> __m256 {
        _mm256_cmp_ps::<_CMP_EQ_UQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn select(self, m: __m256, if_set: Self) -> Self {
        Avx(_mm256_blendv_ps(self.0, if_set.0, m))
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn and(a: __m256, b: __m256) -> __m256 {
        _mm256_and_ps(a, b)
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn or(a: __m256, b: __m256) -> __m256 {
        _mm256_or_ps(a, b)
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn andnot(a: __m256, b: __m256) -> __m256 {
        _mm256_andnot_ps(a, b)
    }
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn bits(m: __m256) -> u32 {
        _mm256_movemask_ps(m) as u32
    }
}

impl Lanes for Avx512 {
    const WIDTH: usize = 16;
    type Mask = __mmask16;

    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn splat(x: f32) -> Self {
        Avx512(_mm512_set1_ps(x))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn load(x: &[f32; 16]) -> Self {
        unsafe { Avx512(_mm512_loadu_ps(x.as_ptr())) }
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn store(self, out: &mut [f32; 16]) {
        unsafe { _mm512_storeu_ps(out.as_mut_ptr(), self.0) }
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn add(self, b: Self) -> Self {
        Avx512(_mm512_add_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn sub(self, b: Self) -> Self {
        Avx512(_mm512_sub_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn mul(self, b: Self) -> Self {
        Avx512(_mm512_mul_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn div(self, b: Self) -> Self {
        Avx512(_mm512_div_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn neg(self) -> Self {
        Avx512(_mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(self.0), _mm512_set1_epi32(i32::MIN))))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn abs(self) -> Self {
        Avx512(_mm512_abs_ps(self.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn max_keep(self, b: Self) -> Self {
        Avx512(_mm512_max_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn min_keep(self, b: Self) -> Self {
        Avx512(_mm512_min_ps(self.0, b.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn lt(self, b: Self) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn gt(self, b: Self) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn le(self, b: Self) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn eq_or_nan(self, b: Self) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_EQ_UQ>(self.0, b.0)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn select(self, m: __mmask16, if_set: Self) -> Self {
        Avx512(_mm512_mask_blend_ps(m, self.0, if_set.0))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn and(a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn or(a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn andnot(a: __mmask16, b: __mmask16) -> __mmask16 {
        !a & b
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn bits(m: __mmask16) -> u32 {
        m as u32
    }
}
