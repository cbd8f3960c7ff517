//! Sixteen lanes in an AVX-512 register ([`super::avx512()`]).

use std::arch::x86_64::*;

use glam::{Vec2, Vec3A};

use super::{CompressLanes, FusedLanes, Kernel, Lanes, SampleLanes};

/// Sixteen lanes in an AVX-512 register.
#[derive(Clone, Copy)]
pub(crate) struct Avx512(pub(crate) __m512);

impl FusedLanes for Avx512 {
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn mul_add(self, b: Self, c: Self) -> Self {
        Avx512(_mm512_fmadd_ps(self.0, b.0, c.0))
    }
}

/// The transpose of sixteen rows of sixteen floats: lane k of row c becomes lane c of row k.
#[target_feature(enable = "avx512f")]
#[inline]
pub(crate) fn transpose16(row: &[__m512; 16]) -> [__m512; 16] {
    // Rows 2i and 2i + 1 interleaved: pairs[2i] holds elements 0 and 1 of each 128-bit block,
    // pairs[2i + 1] elements 2 and 3.
    let mut pairs = [_mm512_setzero_pd(); 16];
    for i in 0..8 {
        pairs[2 * i] = _mm512_castps_pd(_mm512_unpacklo_ps(row[2 * i], row[2 * i + 1]));
        pairs[2 * i + 1] = _mm512_castps_pd(_mm512_unpackhi_ps(row[2 * i], row[2 * i + 1]));
    }
    let mut out = [_mm512_setzero_ps(); 16];
    for e in 0..4 {
        // Element e of each block of rows 4q..4q + 4.
        let h = e / 2;
        let mut quad = [_mm512_setzero_ps(); 4];
        for (q, quad) in quad.iter_mut().enumerate() {
            let (x, y) = (pairs[4 * q + h], pairs[4 * q + 2 + h]);
            let v = if e % 2 == 0 { _mm512_unpacklo_pd(x, y) } else { _mm512_unpackhi_pd(x, y) };
            *quad = _mm512_castpd_ps(v);
        }
        // Blocks 0, 1 (front) and 2, 3 (back) of the four quads, then each block's four.
        let front = [_mm512_shuffle_f32x4::<0x44>(quad[0], quad[1]), _mm512_shuffle_f32x4::<0x44>(quad[2], quad[3])];
        let back = [_mm512_shuffle_f32x4::<0xEE>(quad[0], quad[1]), _mm512_shuffle_f32x4::<0xEE>(quad[2], quad[3])];
        out[e] = _mm512_shuffle_f32x4::<0x88>(front[0], front[1]);
        out[4 + e] = _mm512_shuffle_f32x4::<0xDD>(front[0], front[1]);
        out[8 + e] = _mm512_shuffle_f32x4::<0x88>(back[0], back[1]);
        out[12 + e] = _mm512_shuffle_f32x4::<0xDD>(back[0], back[1]);
    }
    out
}

impl CompressLanes for Avx512 {
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn load_partial(x: &[f32]) -> Self {
        let lanes = ((1u32 << x.len().min(16)) - 1) as __mmask16;
        // SAFETY: the masked load reads only the first `x.len()` floats (at most sixteen).
        unsafe { Avx512(_mm512_maskz_loadu_ps(lanes, x.as_ptr())) }
    }
    #[target_feature(enable = "avx512f,popcnt")]
    #[inline]
    unsafe fn compress_store(self, m: u32, out: &mut [f32]) {
        let n = m.count_ones();
        let out = &mut out[..n as usize];
        // SAFETY: the masked store writes the first `n` floats of `out`, checked above.
        unsafe {
            _mm512_mask_storeu_ps(
                out.as_mut_ptr(),
                ((1u32 << n) - 1) as __mmask16,
                _mm512_maskz_compress_ps(m as __mmask16, self.0),
            )
        }
    }
    #[target_feature(enable = "avx512f,popcnt")]
    #[inline]
    unsafe fn compress_indices(base: u32, m: u32, out: &mut [u32]) {
        let n = m.count_ones();
        let out = &mut out[..n as usize];
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        let index = _mm512_maskz_compress_epi32(m as __mmask16, _mm512_add_epi32(iota, _mm512_set1_epi32(base as i32)));
        // SAFETY: the masked store writes the first `n` integers of `out`, checked above.
        unsafe { _mm512_mask_storeu_epi32(out.as_mut_ptr().cast(), ((1u32 << n) - 1) as __mmask16, index) }
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn store_partial(self, out: &mut [f32]) {
        let keep = ((1u32 << out.len().min(16)) - 1) as __mmask16;
        // SAFETY: the masked store writes only the first `out.len()` floats (at most sixteen).
        unsafe { _mm512_mask_storeu_ps(out.as_mut_ptr(), keep, self.0) }
    }
}

impl SampleLanes for Avx512 {
    type U32 = __m512i;

    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn from_u32(i: __m512i) -> Self {
        Avx512(_mm512_cvtepu32_ps(i))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn from_small_u32(i: __m512i) -> Self {
        Avx512(_mm512_cvtepi32_ps(i))
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn store_points(x: Self, y: Self, out: &mut [Vec2]) {
        // x and y of lanes 0–7, then of lanes 8–15, interleaved as `Vec2`s lie in memory.
        let low = _mm512_setr_epi32(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
        let high = _mm512_add_epi32(low, _mm512_set1_epi32(8));
        let pairs = [_mm512_permutex2var_ps(x.0, low, y.0), _mm512_permutex2var_ps(x.0, high, y.0)];
        let floats = out.as_mut_ptr().cast::<f32>();
        for (h, pair) in pairs.into_iter().enumerate() {
            // The floats of this half that `out` holds (it may be short).
            let n = (2 * out.len()).saturating_sub(16 * h).min(16);
            // SAFETY: a `Vec2` is two f32 (`repr(C)`); the masked store writes only the first
            // 2·len floats of `out`.
            unsafe { _mm512_mask_storeu_ps(floats.wrapping_add(16 * h), ((1u32 << n) - 1) as __mmask16, pair) };
        }
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
    /// One expand per group: `start[q], start[q] + 1, …` spread over the group's lanes in
    /// order.
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn places(groups: &[u32; 4], start: &[u32; 4], none: u32) -> [u32; 16] {
        let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
        let mut at = _mm512_set1_epi32(none as i32);
        for (&lanes, &start) in groups.iter().zip(start) {
            let run = _mm512_add_epi32(_mm512_set1_epi32(start as i32), iota);
            at = _mm512_mask_expand_epi32(at, lanes as __mmask16, run);
        }
        let mut out = [0u32; 16];
        // SAFETY: `out` holds sixteen u32.
        unsafe { _mm512_storeu_si512(out.as_mut_ptr().cast(), at) };
        out
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn load(x: &[f32]) -> Self {
        let x = &x[..16];
        // SAFETY: sixteen floats, checked above.
        unsafe { Avx512(_mm512_loadu_ps(x.as_ptr())) }
    }
    #[inline(always)]
    fn lane(&self, j: usize) -> f32 {
        // SAFETY: an `__m512` is sixteen f32 in memory.
        let floats = unsafe { &*(&raw const self.0).cast::<[f32; 16]>() };
        floats[j]
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn store(self, out: &mut [f32]) {
        let out = &mut out[..16];
        // SAFETY: sixteen floats, checked above.
        unsafe { _mm512_storeu_ps(out.as_mut_ptr(), self.0) }
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn add_to(x: Self, y: Self, z: Self, out: &mut [Vec3A]) {
        let out = &mut out[..16];
        let xy_lo = _mm512_castps_pd(_mm512_unpacklo_ps(x.0, y.0));
        let xy_hi = _mm512_castps_pd(_mm512_unpackhi_ps(x.0, y.0));
        let zz_lo = _mm512_castps_pd(_mm512_unpacklo_ps(z.0, z.0));
        let zz_hi = _mm512_castps_pd(_mm512_unpackhi_ps(z.0, z.0));
        // Block i of rows[j]: element 4i + j as (x, y, z, z).
        let rows = [
            _mm512_castpd_ps(_mm512_unpacklo_pd(xy_lo, zz_lo)),
            _mm512_castpd_ps(_mm512_unpackhi_pd(xy_lo, zz_lo)),
            _mm512_castpd_ps(_mm512_unpacklo_pd(xy_hi, zz_hi)),
            _mm512_castpd_ps(_mm512_unpackhi_pd(xy_hi, zz_hi)),
        ];
        let front = [_mm512_shuffle_f32x4::<0x44>(rows[0], rows[1]), _mm512_shuffle_f32x4::<0x44>(rows[2], rows[3])];
        let back = [_mm512_shuffle_f32x4::<0xEE>(rows[0], rows[1]), _mm512_shuffle_f32x4::<0xEE>(rows[2], rows[3])];
        // Elements 4j..4j + 4, as they lie in memory.
        let quads = [
            _mm512_shuffle_f32x4::<0x88>(front[0], front[1]),
            _mm512_shuffle_f32x4::<0xDD>(front[0], front[1]),
            _mm512_shuffle_f32x4::<0x88>(back[0], back[1]),
            _mm512_shuffle_f32x4::<0xDD>(back[0], back[1]),
        ];
        let p = out.as_mut_ptr().cast::<f32>();
        for (j, quad) in quads.into_iter().enumerate() {
            // SAFETY: `out` holds sixteen `Vec3A`s (16 bytes each), checked above.
            unsafe {
                let at = p.add(16 * j);
                _mm512_storeu_ps(at, _mm512_add_ps(_mm512_loadu_ps(at), quad));
            }
        }
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
    unsafe fn sqrt(self) -> Self {
        Avx512(_mm512_sqrt_ps(self.0))
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
    unsafe fn ne(self, b: Self) -> __mmask16 {
        _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(self.0, b.0)
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
    unsafe fn least(self) -> f32 {
        _mm512_reduce_min_ps(self.0)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn greatest(self) -> f32 {
        _mm512_reduce_max_ps(self.0)
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn bits(m: __mmask16) -> u32 {
        m as u32
    }
    #[target_feature(enable = "avx512f")]
    #[inline]
    unsafe fn mask(bits: u32) -> __mmask16 {
        bits as __mmask16
    }
    #[target_feature(enable = "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn compiled<K: Kernel<Self>>(kernel: K) -> K::Output {
        // SAFETY: compiled for AVX-512 and x86-64-v3, which the caller's CPU has.
        unsafe { kernel.run() }
    }
    #[target_feature(enable = "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline(never)]
    unsafe fn compiled_apart<K: Kernel<Self>>(kernel: K) -> K::Output {
        // SAFETY: compiled for AVX-512 and x86-64-v3, which the caller's CPU has.
        unsafe { kernel.run() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    /// Compression keeps the lanes of the mask in lane order and writes nothing past them, and a
    /// partial load fills the lanes past the slice with 0 (where the CPU has AVX-512).
    #[test]
    fn compression_packs_the_masked_lanes_in_order() {
        crate::simd::both_widths(|| {}, packs);
    }

    /// [`compression_packs_the_masked_lanes_in_order`].
    ///
    /// # Safety
    /// The CPU must have AVX-512 and x86-64-v3.
    unsafe fn packs() {
        let mut rng = SplitMix64::new(7);
        let x: [f32; 16] = std::array::from_fn(|k| k as f32 * 1.5 - 4.0);
        for round in 0..500 {
            let m = if round < 2 { [0, 0xffff][round] } else { (rng.next_u64() & 0xffff) as u32 };
            let kept: Vec<usize> = (0..16).filter(|k| m >> k & 1 != 0).collect();
            let (mut floats, mut indices) = ([-7.0f32; 17], [u32::MAX; 17]);
            // SAFETY: the caller's CPU has AVX-512.
            unsafe {
                Avx512::load(&x).compress_store(m, &mut floats);
                Avx512::compress_indices(100, m, &mut indices);
            }
            for (j, &k) in kept.iter().enumerate() {
                assert_eq!((floats[j], indices[j]), (x[k], 100 + k as u32), "mask {m:#x}, place {j}");
            }
            assert!(floats[kept.len()..].iter().all(|&f| f == -7.0), "mask {m:#x}: wrote past its lanes");
            assert!(indices[kept.len()..].iter().all(|&i| i == u32::MAX), "mask {m:#x}: wrote past its lanes");
        }
        for len in 0..=16 {
            // SAFETY: the caller's CPU has AVX-512.
            let lanes = unsafe { Avx512::load_partial(&x[..len]) };
            let want: [f32; 16] = std::array::from_fn(|k| if k < len { x[k] } else { 0.0 });
            assert_eq!(std::array::from_fn::<f32, 16, _>(|k| lanes.lane(k)), want, "length {len}");
        }
    }
}
