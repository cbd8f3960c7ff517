//! Sixteen lanes in an AVX-512 register ([`super::avx512()`]).

use std::arch::x86_64::*;

use glam::{Vec2, Vec3A};

use super::{
    BitLanes, CompressLanes, FusedLanes, HasAvx512, Kernel, Lanes, SampleLanes, lanes::isa_methods, u32_lanes::U32x16,
};

/// Sixteen lanes in an AVX-512 register. The field is private: a value is made only from a
/// [`HasAvx512`] token or from other values, so it proves the CPU has AVX-512F.
#[derive(Clone, Copy)]
pub(crate) struct Avx512(__m512);

impl Avx512 {
    /// The lanes of register `x`.
    #[inline(always)]
    pub(crate) fn from_raw(_: HasAvx512, x: __m512) -> Self {
        Avx512(x)
    }

    /// The register.
    #[inline(always)]
    pub(crate) fn raw(self) -> __m512 {
        self.0
    }
}

impl FusedLanes for Avx512 {
    isa_methods! {
        fn mul_add(self, b: Self, c: Self) -> Self {
            Avx512(_mm512_fmadd_ps(self.0, b.0, c.0))
        }
    }
}

/// The transpose of sixteen rows of sixteen floats: lane k of row c becomes lane c of row k.
#[inline(always)]
pub(crate) fn transpose16(_: HasAvx512, row: &[__m512; 16]) -> [__m512; 16] {
    // SAFETY: the token proves the CPU has AVX-512F; inlined, the intrinsics compile into the
    // `#[target_feature]` copy that calls this.
    unsafe {
        // Rows 2i and 2i + 1 interleaved: pairs[2i] holds elements 0 and 1 of each 128-bit
        // block, pairs[2i + 1] elements 2 and 3.
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
            let front =
                [_mm512_shuffle_f32x4::<0x44>(quad[0], quad[1]), _mm512_shuffle_f32x4::<0x44>(quad[2], quad[3])];
            let back = [_mm512_shuffle_f32x4::<0xEE>(quad[0], quad[1]), _mm512_shuffle_f32x4::<0xEE>(quad[2], quad[3])];
            out[e] = _mm512_shuffle_f32x4::<0x88>(front[0], front[1]);
            out[4 + e] = _mm512_shuffle_f32x4::<0xDD>(front[0], front[1]);
            out[8 + e] = _mm512_shuffle_f32x4::<0x88>(back[0], back[1]);
            out[12 + e] = _mm512_shuffle_f32x4::<0xDD>(back[0], back[1]);
        }
        out
    }
}

impl CompressLanes for Avx512 {
    isa_methods! {
        fn load_partial(_: HasAvx512, x: &[f32]) -> Self {
            let lanes = ((1u32 << x.len().min(16)) - 1) as __mmask16;
            // The masked load reads only the first `x.len()` floats (at most sixteen).
            Avx512(_mm512_maskz_loadu_ps(lanes, x.as_ptr()))
        }
        fn compress_store(self, m: u32, out: &mut [f32]) {
            let n = m.count_ones();
            let out = &mut out[..n as usize];
            // The masked store writes the first `n` floats of `out`, checked above.
            _mm512_mask_storeu_ps(
                out.as_mut_ptr(),
                ((1u32 << n) - 1) as __mmask16,
                _mm512_maskz_compress_ps(m as __mmask16, self.0),
            )
        }
        fn compress_indices(_: HasAvx512, base: u32, m: u32, out: &mut [u32]) {
            let n = m.count_ones();
            let out = &mut out[..n as usize];
            let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
            let index =
                _mm512_maskz_compress_epi32(m as __mmask16, _mm512_add_epi32(iota, _mm512_set1_epi32(base as i32)));
            // The masked store writes the first `n` integers of `out`, checked above.
            _mm512_mask_storeu_epi32(out.as_mut_ptr().cast(), ((1u32 << n) - 1) as __mmask16, index)
        }
        fn store_partial(self, out: &mut [f32]) {
            let keep = ((1u32 << out.len().min(16)) - 1) as __mmask16;
            // The masked store writes only the first `out.len()` floats (at most sixteen).
            _mm512_mask_storeu_ps(out.as_mut_ptr(), keep, self.0)
        }
    }
}

impl BitLanes for Avx512 {
    isa_methods! {
        fn copysign(self, sign: Self) -> Self {
            let magnitude = _mm512_and_si512(_mm512_castps_si512(self.0), _mm512_set1_epi32(i32::MAX));
            let sign = _mm512_and_si512(_mm512_castps_si512(sign.0), _mm512_set1_epi32(i32::MIN));
            Avx512(_mm512_castsi512_ps(_mm512_or_si512(magnitude, sign)))
        }
        fn step_away(self, o: Self) -> Self {
            let (v, o, zero) = (self.0, o.0, _mm512_setzero_ps());
            let bits = _mm512_castps_si512(v);
            let (up, down) = (_mm512_cmp_ps_mask::<_CMP_GT_OQ>(o, zero), _mm512_cmp_ps_mask::<_CMP_LT_OQ>(o, zero));
            let positive = _mm512_cmp_ps_mask::<_CMP_GT_OQ>(v, zero);
            // Away from zero (+1 on the bits) when moving up from a positive value or down from
            // a negative one (a NaN counts as negative), towards it (−1) otherwise.
            let away = !(up ^ positive);
            let moved = _mm512_add_epi32(bits, _mm512_mask_blend_epi32(away, _mm512_set1_epi32(-1), _mm512_set1_epi32(1)));
            // From either zero: the least positive float up, the least negative one down.
            let from_zero = _mm512_mask_blend_epi32(up, _mm512_set1_epi32(0x8000_0001_u32 as i32), _mm512_set1_epi32(1));
            let moved = _mm512_mask_blend_epi32(_mm512_cmp_ps_mask::<_CMP_EQ_OQ>(v, zero), moved, from_zero);
            // Infinities stay where they are the far end.
            let at_end = (up & _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(v, _mm512_set1_ps(f32::INFINITY)))
                | (down & _mm512_cmp_ps_mask::<_CMP_EQ_OQ>(v, _mm512_set1_ps(f32::NEG_INFINITY)));
            let moves = (up | down) & !at_end;
            Avx512(_mm512_castsi512_ps(_mm512_mask_blend_epi32(moves, bits, moved)))
        }
    }
}

impl SampleLanes for Avx512 {
    type U32 = U32x16;

    isa_methods! {
        fn from_u32(i: U32x16) -> Self {
            Avx512(_mm512_cvtepu32_ps(i.0))
        }
        fn from_small_u32(i: U32x16) -> Self {
            Avx512(_mm512_cvtepi32_ps(i.0))
        }
        fn truncate_small(self) -> U32x16 {
            U32x16(_mm512_cvttps_epi32(self.0))
        }
        fn store_points(x: Self, y: Self, out: &mut [Vec2]) {
            // x and y of lanes 0–7, then of lanes 8–15, interleaved as `Vec2`s lie in memory.
            let low = _mm512_setr_epi32(0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6, 22, 7, 23);
            let high = _mm512_add_epi32(low, _mm512_set1_epi32(8));
            let pairs = [_mm512_permutex2var_ps(x.0, low, y.0), _mm512_permutex2var_ps(x.0, high, y.0)];
            let floats = out.as_mut_ptr().cast::<f32>();
            for (h, pair) in pairs.into_iter().enumerate() {
                // The floats of this half that `out` holds (it may be short).
                let n = (2 * out.len()).saturating_sub(16 * h).min(16);
                // A `Vec2` is two f32 (`repr(C)`); the masked store writes only the first
                // 2·len floats of `out`.
                _mm512_mask_storeu_ps(floats.wrapping_add(16 * h), ((1u32 << n) - 1) as __mmask16, pair);
            }
        }
    }
}

/// Masks are plain bit sets (`__mmask16`), combined and read without intrinsics.
impl Lanes for Avx512 {
    const WIDTH: usize = 16;
    type Mask = __mmask16;
    type Isa = HasAvx512;

    #[inline(always)]
    fn isa(self) -> HasAvx512 {
        HasAvx512(())
    }
    #[inline(always)]
    fn lane(&self, j: usize) -> f32 {
        // SAFETY: an `__m512` is sixteen f32 in memory.
        let floats = unsafe { &*(&raw const self.0).cast::<[f32; 16]>() };
        floats[j]
    }
    #[inline(always)]
    fn and(a: __mmask16, b: __mmask16) -> __mmask16 {
        a & b
    }
    #[inline(always)]
    fn or(a: __mmask16, b: __mmask16) -> __mmask16 {
        a | b
    }
    #[inline(always)]
    fn andnot(a: __mmask16, b: __mmask16) -> __mmask16 {
        !a & b
    }
    #[inline(always)]
    fn bits(m: __mmask16) -> u32 {
        m as u32
    }
    #[inline(always)]
    fn mask(_: HasAvx512, bits: u32) -> __mmask16 {
        bits as __mmask16
    }
    isa_methods! {
        fn splat(_: HasAvx512, x: f32) -> Self {
            Avx512(_mm512_set1_ps(x))
        }
        /// One expand per group: `start[q], start[q] + 1, …` spread over the group's lanes in
        /// order.
        fn places(_: HasAvx512, groups: &[u32; 4], start: &[u32; 4], none: u32) -> [u32; 16] {
            let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
            let mut at = _mm512_set1_epi32(none as i32);
            for (&lanes, &start) in groups.iter().zip(start) {
                let run = _mm512_add_epi32(_mm512_set1_epi32(start as i32), iota);
                at = _mm512_mask_expand_epi32(at, lanes as __mmask16, run);
            }
            let mut out = [0u32; 16];
            // `out` holds sixteen u32.
            _mm512_storeu_si512(out.as_mut_ptr().cast(), at);
            out
        }
        fn load(_: HasAvx512, x: &[f32]) -> Self {
            let x = &x[..16];
            // Sixteen floats, checked above.
            Avx512(_mm512_loadu_ps(x.as_ptr()))
        }
        fn store(self, out: &mut [f32]) {
            let out = &mut out[..16];
            // Sixteen floats, checked above.
            _mm512_storeu_ps(out.as_mut_ptr(), self.0)
        }
        fn add_to(x: Self, y: Self, z: Self, out: &mut [Vec3A]) {
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
            let front =
                [_mm512_shuffle_f32x4::<0x44>(rows[0], rows[1]), _mm512_shuffle_f32x4::<0x44>(rows[2], rows[3])];
            let back =
                [_mm512_shuffle_f32x4::<0xEE>(rows[0], rows[1]), _mm512_shuffle_f32x4::<0xEE>(rows[2], rows[3])];
            // Elements 4j..4j + 4, as they lie in memory.
            let quads = [
                _mm512_shuffle_f32x4::<0x88>(front[0], front[1]),
                _mm512_shuffle_f32x4::<0xDD>(front[0], front[1]),
                _mm512_shuffle_f32x4::<0x88>(back[0], back[1]),
                _mm512_shuffle_f32x4::<0xDD>(back[0], back[1]),
            ];
            let p = out.as_mut_ptr().cast::<f32>();
            for (j, quad) in quads.into_iter().enumerate() {
                // `out` holds sixteen `Vec3A`s (16 bytes each), checked above.
                let at = p.add(16 * j);
                _mm512_storeu_ps(at, _mm512_add_ps(_mm512_loadu_ps(at), quad));
            }
        }
        fn add(self, b: Self) -> Self {
            Avx512(_mm512_add_ps(self.0, b.0))
        }
        fn sub(self, b: Self) -> Self {
            Avx512(_mm512_sub_ps(self.0, b.0))
        }
        fn mul(self, b: Self) -> Self {
            Avx512(_mm512_mul_ps(self.0, b.0))
        }
        fn div(self, b: Self) -> Self {
            Avx512(_mm512_div_ps(self.0, b.0))
        }
        fn neg(self) -> Self {
            Avx512(_mm512_castsi512_ps(_mm512_xor_si512(_mm512_castps_si512(self.0), _mm512_set1_epi32(i32::MIN))))
        }
        fn sqrt(self) -> Self {
            Avx512(_mm512_sqrt_ps(self.0))
        }
        fn abs(self) -> Self {
            Avx512(_mm512_abs_ps(self.0))
        }
        fn max_keep(self, b: Self) -> Self {
            Avx512(_mm512_max_ps(self.0, b.0))
        }
        fn min_keep(self, b: Self) -> Self {
            Avx512(_mm512_min_ps(self.0, b.0))
        }
        fn lt(self, b: Self) -> __mmask16 {
            _mm512_cmp_ps_mask::<_CMP_LT_OQ>(self.0, b.0)
        }
        fn gt(self, b: Self) -> __mmask16 {
            _mm512_cmp_ps_mask::<_CMP_GT_OQ>(self.0, b.0)
        }
        fn le(self, b: Self) -> __mmask16 {
            _mm512_cmp_ps_mask::<_CMP_LE_OQ>(self.0, b.0)
        }
        fn eq_or_nan(self, b: Self) -> __mmask16 {
            _mm512_cmp_ps_mask::<_CMP_EQ_UQ>(self.0, b.0)
        }
        fn ne(self, b: Self) -> __mmask16 {
            _mm512_cmp_ps_mask::<_CMP_NEQ_UQ>(self.0, b.0)
        }
        fn select(self, m: __mmask16, if_set: Self) -> Self {
            Avx512(_mm512_mask_blend_ps(m, self.0, if_set.0))
        }
        fn least(self) -> f32 {
            _mm512_reduce_min_ps(self.0)
        }
        fn greatest(self) -> f32 {
            _mm512_reduce_max_ps(self.0)
        }
    }
    #[inline(always)]
    fn compiled<K: Kernel<Self>>(isa: HasAvx512, kernel: K) -> K::Output {
        // SAFETY: the token proves the CPU has AVX-512F and x86-64-v3, which the copy is compiled for.
        unsafe { compiled_v4(isa, kernel) }
    }
    #[inline(always)]
    fn compiled_apart<K: Kernel<Self>>(isa: HasAvx512, kernel: K) -> K::Output {
        // SAFETY: the token proves the CPU has AVX-512F and x86-64-v3, which the copy is compiled for.
        unsafe { compiled_apart_v4(isa, kernel) }
    }
}

/// [`Lanes::compiled`] for [`Avx512`]: the `#[target_feature]` copy of `kernel`.
#[target_feature(enable = "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn compiled_v4<K: Kernel<Avx512>>(isa: HasAvx512, kernel: K) -> K::Output {
    kernel.run(isa)
}

/// [`Lanes::compiled_apart`] for [`Avx512`].
#[target_feature(enable = "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
#[inline(never)]
fn compiled_apart_v4<K: Kernel<Avx512>>(isa: HasAvx512, kernel: K) -> K::Output {
    kernel.run(isa)
}
