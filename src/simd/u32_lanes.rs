//! Vectors of u32 lanes: sixteen in an AVX-512 register ([`U32x16`]), eight in an AVX2 one
//! ([`U32x8`]), for the integer hashes and shuffle tables of the samplers.

use std::arch::x86_64::*;

use super::{HasAvx2, HasAvx512, lanes::isa_methods};

/// Vectors of u32 lanes with the operations Kensler's hashes and the CMJ shuffle tables need
/// (wrapping like the scalar code). As with the f32 lanes, a value proves the CPU has its
/// type's instruction set, and constructors without one take the token.
pub(crate) trait U32Lanes: Copy {
    /// Lanes per vector.
    const WIDTH: usize;
    /// Sixteen u32 entries held in registers, looked up by [`U32Lanes::lookup16`].
    type Table16: Copy;
    /// The token that proves the CPU has this type's instruction set.
    type Isa: Copy;

    /// The token these lanes prove.
    fn isa(self) -> Self::Isa;
    /// `x` in every lane.
    fn splat(isa: Self::Isa, x: u32) -> Self;
    /// `first, first + 1, …` (wrapping), lane by lane.
    fn consecutive(isa: Self::Isa, first: u32) -> Self;
    /// `self ^ b`.
    fn xor(self, b: Self) -> Self;
    /// `self & b`.
    fn and(self, b: Self) -> Self;
    /// `self + b` (wrapping).
    fn add(self, b: Self) -> Self;
    /// `self · b` (wrapping: the low 32 bits).
    fn mul(self, b: Self) -> Self;
    /// `self >> n`, lane by lane.
    fn shr(self, n: Self) -> Self;
    /// `self << n`, lane by lane.
    fn shl(self, n: Self) -> Self;
    /// `self | b`.
    fn or(self, b: Self) -> Self;
    /// The first lanes' worth of `x` (which must hold that many).
    fn load(isa: Self::Isa, x: &[u32]) -> Self;
    /// Writes the lanes to the first lanes' worth of `out` (which must hold that many).
    fn store(self, out: &mut [u32]);
    /// `entries` as a table for [`U32Lanes::lookup16`].
    fn table16(isa: Self::Isa, entries: &[u32; 16]) -> Self::Table16;
    /// Entry `self` of `table` in each lane (every lane below 16): lane permutes, no memory.
    fn lookup16(self, table: Self::Table16) -> Self;
    /// Bit k set where lane k of `self & b` is not zero.
    fn test(self, b: Self) -> u32;
}

/// Sixteen u32 lanes in an AVX-512 register; the private field makes a value a proof of
/// AVX-512F, as an [`super::Avx512`] is.
#[derive(Clone, Copy)]
pub(crate) struct U32x16(pub(super) __m512i);

/// Eight u32 lanes in an AVX2 register; a value proves x86-64-v3, as an [`super::Avx`] does.
#[derive(Clone, Copy)]
pub(crate) struct U32x8(pub(super) __m256i);

/// Sixteen entries in one register ([`U32x16`]'s lookup table).
#[derive(Clone, Copy)]
pub(crate) struct Table16x16(__m512i);

/// Entries 0–7 and 8–15 in two registers ([`U32x8`]'s lookup table).
#[derive(Clone, Copy)]
pub(crate) struct Table16x8([__m256i; 2]);

/// The methods both vector types implement with one intrinsic each; the rest follow in the
/// invocation.
macro_rules! u32_lanes {
    (
        $ty:ident,
        $raw:ty,
        $isa:ident,
        $set1:ident,
        $xor:ident,
        $and:ident,
        $add:ident,
        $mul:ident,
        $shr:ident,
        $shl:ident,
        $or:ident,
        { $($rest:tt)* }
    ) => {
        impl U32Lanes for $ty {
            const WIDTH: usize = size_of::<Self>() / 4;
            type Isa = $isa;
            $($rest)*
            #[inline(always)]
            fn isa(self) -> $isa {
                $isa(())
            }
            isa_methods! {
                fn splat(_: $isa, x: u32) -> Self {
                    $ty($set1(x as i32))
                }
                fn xor(self, b: Self) -> Self {
                    $ty($xor(self.0, b.0))
                }
                fn and(self, b: Self) -> Self {
                    $ty($and(self.0, b.0))
                }
                fn add(self, b: Self) -> Self {
                    $ty($add(self.0, b.0))
                }
                fn mul(self, b: Self) -> Self {
                    $ty($mul(self.0, b.0))
                }
                fn shr(self, n: Self) -> Self {
                    $ty($shr(self.0, n.0))
                }
                fn shl(self, n: Self) -> Self {
                    $ty($shl(self.0, n.0))
                }
                fn or(self, b: Self) -> Self {
                    $ty($or(self.0, b.0))
                }
                fn load(_: $isa, x: &[u32]) -> Self {
                    let x = &x[..Self::WIDTH];
                    // `x` holds a whole vector of u32, checked above.
                    $ty(std::ptr::read_unaligned(x.as_ptr().cast::<$raw>()))
                }
                fn store(self, out: &mut [u32]) {
                    let out = &mut out[..Self::WIDTH];
                    // `out` holds a whole vector of u32, checked above.
                    std::ptr::write_unaligned(out.as_mut_ptr().cast::<$raw>(), self.0)
                }
            }
        }
    };
}

u32_lanes!(
    U32x16,
    __m512i,
    HasAvx512,
    _mm512_set1_epi32,
    _mm512_xor_si512,
    _mm512_and_si512,
    _mm512_add_epi32,
    _mm512_mullo_epi32,
    _mm512_srlv_epi32,
    _mm512_sllv_epi32,
    _mm512_or_si512,
    {
        type Table16 = Table16x16;

        isa_methods! {
            fn consecutive(_: HasAvx512, first: u32) -> Self {
                let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
                U32x16(_mm512_add_epi32(_mm512_set1_epi32(first as i32), iota))
            }
            fn table16(_: HasAvx512, entries: &[u32; 16]) -> Table16x16 {
                // The load reads the sixteen entries.
                Table16x16(_mm512_loadu_si512(entries.as_ptr().cast()))
            }
            /// One permute (it reads the low four bits of each index).
            fn lookup16(self, table: Table16x16) -> Self {
                U32x16(_mm512_permutexvar_epi32(self.0, table.0))
            }
            fn test(self, b: Self) -> u32 {
                _mm512_test_epi32_mask(self.0, b.0).into()
            }
        }
    }
);
u32_lanes!(
    U32x8,
    __m256i,
    HasAvx2,
    _mm256_set1_epi32,
    _mm256_xor_si256,
    _mm256_and_si256,
    _mm256_add_epi32,
    _mm256_mullo_epi32,
    _mm256_srlv_epi32,
    _mm256_sllv_epi32,
    _mm256_or_si256,
    {
        type Table16 = Table16x8;

        isa_methods! {
            fn consecutive(_: HasAvx2, first: u32) -> Self {
                U32x8(_mm256_add_epi32(_mm256_set1_epi32(first as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)))
            }
            fn table16(_: HasAvx2, entries: &[u32; 16]) -> Table16x8 {
                let words = entries.as_ptr().cast::<__m256i>();
                // The loads read the sixteen entries.
                Table16x8([_mm256_loadu_si256(words), _mm256_loadu_si256(words.add(1))])
            }
            /// Two lane permutes (each reads the low three bits of each index) and a blend.
            fn lookup16(self, table: Table16x8) -> Self {
                let (low, high) =
                    (_mm256_permutevar8x32_epi32(table.0[0], self.0), _mm256_permutevar8x32_epi32(table.0[1], self.0));
                U32x8(_mm256_blendv_epi8(low, high, _mm256_cmpgt_epi32(self.0, _mm256_set1_epi32(7))))
            }
            fn test(self, b: Self) -> u32 {
                let zero = _mm256_cmpeq_epi32(_mm256_and_si256(self.0, b.0), _mm256_setzero_si256());
                !(_mm256_movemask_ps(_mm256_castsi256_ps(zero)) as u32) & 0xff
            }
        }
    }
);

#[cfg(test)]
mod tests {
    use glam::Vec2;

    use super::*;
    use crate::{
        random::SplitMix64,
        simd::{Avx, Avx512, Plain, Portable, SampleLanes},
    };

    /// The u32 lanes' tables, lookups, tests and runs, the conversions to f32 lanes (rounded as
    /// `as f32` rounds, halfway cases and the top of the range included) and the stores of
    /// points give the scalar values lane by lane and write nothing past their lanes: for
    /// the portable lanes, eight lanes (AVX2) and sixteen (AVX-512), where the CPU has them.
    #[test]
    fn u32_lanes_give_the_scalar_values() {
        same_as_scalar::<Portable>(Plain);
        crate::simd::both_widths(same_as_scalar::<Avx>, same_as_scalar::<Avx512>);
    }

    /// [`u32_lanes_give_the_scalar_values`] for `L`.
    fn same_as_scalar<L: SampleLanes>(isa: L::Isa) {
        let w = L::WIDTH;
        assert_eq!(<L::U32 as U32Lanes>::WIDTH, w);
        let lanes = |v: L::U32| {
            let mut out = vec![0u32; w];
            v.store(&mut out);
            out
        };
        let floats = |v: L| (0..w).map(|k| v.lane(k).to_bits()).collect::<Vec<_>>();
        let special: [u32; 9] = [0, 1, 0xffff, 0x1_0000, 0xff_ffff, 0x100_0001, 0x100_0003, 0x7fff_ffff, 0x8000_0000];
        let mut rng = SplitMix64::new(11);
        for round in 0..1_000 {
            let a: Vec<u32> = (0..w)
                .map(|k| match (round + k) % 4 {
                    0 => {
                        special[(round / 4 + k) % special.len()].wrapping_add([0, 0x8000_0000, 0x7f00_0000][round % 3])
                    }
                    _ => rng.next_u64() as u32,
                })
                .collect();
            let b: Vec<u32> = (0..w).map(|_| rng.next_u64() as u32 >> (rng.next_u64() % 32)).collect();
            let entries: [u32; 16] = std::array::from_fn(|_| rng.next_u64() as u32);
            let first = rng.next_u64() as u32;
            let (va, vb) = (L::U32::load(isa, &a), L::U32::load(isa, &b));
            assert_eq!(lanes(va), a);
            let run: Vec<u32> = (0..w as u32).map(|k| first.wrapping_add(k)).collect();
            assert_eq!(lanes(L::U32::consecutive(isa, first)), run, "{w} lanes from {first}");
            let index = va.and(L::U32::splat(isa, 15));
            let want: Vec<u32> = a.iter().map(|&i| entries[(i & 15) as usize]).collect();
            assert_eq!(lanes(index.lookup16(L::U32::table16(isa, &entries))), want, "lookup of {a:?}");
            let set = (0..w).fold(0, |m, k| m | u32::from(a[k] & b[k] != 0) << k);
            assert_eq!(va.test(vb), set, "test of {a:?}, {b:?}");
            let want: Vec<u32> = a.iter().map(|&i| (i as f32).to_bits()).collect();
            assert_eq!(floats(L::from_u32(va)), want, "conversion of {a:?}");
            let small = va.shr(L::U32::splat(isa, 1));
            let want: Vec<u32> = a.iter().map(|&i| ((i >> 1) as f32).to_bits()).collect();
            assert_eq!(floats(L::from_small_u32(small)), want, "conversion of {a:?} / 2");
        }
        let (x, y): (Vec<f32>, Vec<f32>) = (0..w).map(|k| (k as f32 + 0.25, -(k as f32))).unzip();
        for len in 0..=w {
            let mut out = vec![Vec2::NAN; w + 1];
            L::store_points(L::load(isa, &x), L::load(isa, &y), &mut out[..len]);
            for (k, v) in out.iter().enumerate() {
                let want = if k < len { [x[k], y[k]] } else { [f32::NAN; 2] };
                assert_eq!(v.to_array().map(f32::to_bits), want.map(f32::to_bits), "{w} lanes, {len} points: {k}");
            }
        }
    }
}
