//! Rays in SIMD lanes, for packet traversal: eight per AVX register ([`Avx`]) or sixteen per
//! AVX-512 register ([`Avx512`]). Each operation is one IEEE operation of the single-ray code
//! (no fused multiply-adds), so a lane computes bit for bit what that ray's own traversal does.
//!
//! Every method is `unsafe` and compiled for its type's instruction set, which the CPU must
//! have; callers are generic code inlined into functions compiled for it, where the methods
//! inline in turn.

use std::arch::x86_64::*;

use glam::DVec3;

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
    /// The lanes whose ray (origin `o`, direction `d`) meets the plane through `a` with normal
    /// `n` at a `t` in (0, `tmax`): `t = (n·(a − o)) / (n·d)` in f64, rounded to f32, no hit
    /// where `n·d = 0`, each lane with exactly the operations of [`Triangle::finish`].
    ///
    /// [`Triangle::finish`]: super::shapes::Triangle::finish
    unsafe fn plane_hits(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3], tmax: Self) -> u32;
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
    /// In two halves of four f64 lanes.
    #[target_feature(enable = "avx")]
    #[inline]
    unsafe fn plane_hits(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3], tmax: Self) -> u32 {
        let half = |v: &Avx, h: usize| {
            let q = if h == 0 { _mm256_castps256_ps128(v.0) } else { _mm256_extractf128_ps::<1>(v.0) };
            _mm256_cvtps_pd(q)
        };
        let dot = |x: __m256d, y: __m256d, z: __m256d| {
            let xy = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(n.x), x), _mm256_mul_pd(_mm256_set1_pd(n.y), y));
            _mm256_add_pd(xy, _mm256_mul_pd(_mm256_set1_pd(n.z), z))
        };
        let mut t = [_mm_setzero_ps(); 2];
        let mut meets = 0;
        for (h, t) in t.iter_mut().enumerate() {
            let denom = dot(half(&d[0], h), half(&d[1], h), half(&d[2], h));
            let to = |k: usize, c: f64| _mm256_sub_pd(_mm256_set1_pd(c), half(&o[k], h));
            let num = dot(to(0, a.x), to(1, a.y), to(2, a.z));
            *t = _mm256_cvtpd_ps(_mm256_div_pd(num, denom));
            let nonzero = _mm256_cmp_pd::<_CMP_NEQ_UQ>(denom, _mm256_setzero_pd());
            meets |= (_mm256_movemask_pd(nonzero) as u32) << (4 * h);
        }
        let t = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(t[0]), t[1]);
        let ahead = _mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_setzero_ps());
        let short = _mm256_cmp_ps::<_CMP_LT_OQ>(t, tmax.0);
        meets & _mm256_movemask_ps(_mm256_and_ps(ahead, short)) as u32
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
    /// In two halves of eight f64 lanes.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn plane_hits(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3], tmax: Self) -> u32 {
        let half = |v: &Avx512, h: usize| {
            let q = if h == 0 {
                _mm512_castps512_ps256(v.0)
            } else {
                _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v.0)))
            };
            _mm512_cvtps_pd(q)
        };
        let dot = |x: __m512d, y: __m512d, z: __m512d| {
            let xy = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(n.x), x), _mm512_mul_pd(_mm512_set1_pd(n.y), y));
            _mm512_add_pd(xy, _mm512_mul_pd(_mm512_set1_pd(n.z), z))
        };
        let mut t = [_mm256_setzero_ps(); 2];
        let mut meets = 0;
        for (h, t) in t.iter_mut().enumerate() {
            let denom = dot(half(&d[0], h), half(&d[1], h), half(&d[2], h));
            let to = |k: usize, c: f64| _mm512_sub_pd(_mm512_set1_pd(c), half(&o[k], h));
            let num = dot(to(0, a.x), to(1, a.y), to(2, a.z));
            *t = _mm512_cvtpd_ps(_mm512_div_pd(num, denom));
            let nonzero = _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(denom, _mm512_setzero_pd());
            meets |= (nonzero as u32) << (8 * h);
        }
        let t = _mm512_castpd_ps(_mm512_insertf64x4::<1>(
            _mm512_castps_pd(_mm512_castps256_ps512(t[0])),
            _mm256_castps_pd(t[1]),
        ));
        let ahead = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(t, _mm512_setzero_ps());
        let short = _mm512_cmp_ps_mask::<_CMP_LT_OQ>(t, tmax.0);
        meets & (ahead & short) as u32
    }
}
