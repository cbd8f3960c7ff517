//! Vectors of u32 lanes: sixteen in an AVX-512 register (`__m512i`), eight in an AVX2 one
//! (`__m256i`), for the integer hashes and shuffle tables of the samplers.

use std::arch::x86_64::*;

/// Vectors of u32 lanes with the operations Kensler's hashes and the CMJ shuffle tables need
/// (wrapping like the scalar code): sixteen lanes with AVX-512F (`__m512i`), eight with AVX2
/// (`__m256i`). Every method is compiled for its type's instruction set, which the CPU must
/// have; callers are generic code inlined into functions compiled for it.
pub(crate) trait U32Lanes: Copy {
    /// Lanes per vector.
    const WIDTH: usize;
    /// Sixteen u32 entries held in registers, looked up by [`U32Lanes::lookup16`].
    type Table16: Copy;

    /// `x` in every lane.
    unsafe fn splat(x: u32) -> Self;
    /// `first, first + 1, …` (wrapping), lane by lane.
    unsafe fn consecutive(first: u32) -> Self;
    /// `self ^ b`.
    unsafe fn xor(self, b: Self) -> Self;
    /// `self & b`.
    unsafe fn and(self, b: Self) -> Self;
    /// `self + b` (wrapping).
    unsafe fn add(self, b: Self) -> Self;
    /// `self · b` (wrapping: the low 32 bits).
    unsafe fn mul(self, b: Self) -> Self;
    /// `self >> n`, lane by lane.
    unsafe fn shr(self, n: Self) -> Self;
    /// `self << n`, lane by lane.
    unsafe fn shl(self, n: Self) -> Self;
    /// `self | b`.
    unsafe fn or(self, b: Self) -> Self;
    /// The first lanes' worth of `x` (which must hold that many).
    unsafe fn load(x: &[u32]) -> Self;
    /// Writes the lanes to the first lanes' worth of `out` (which must hold that many).
    unsafe fn store(self, out: &mut [u32]);
    /// `entries` as a table for [`U32Lanes::lookup16`].
    unsafe fn table16(entries: &[u32; 16]) -> Self::Table16;
    /// Entry `self` of `table` in each lane (every lane below 16): lane permutes, no memory.
    unsafe fn lookup16(self, table: Self::Table16) -> Self;
    /// Bit k set where lane k of `self & b` is not zero.
    unsafe fn test(self, b: Self) -> u32;
}

/// The methods both vector types implement with one intrinsic each; the rest follow in the
/// invocation.
macro_rules! u32_lanes {
    (
        $ty:ty,
        $feature:literal,
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
            $($rest)*
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn splat(x: u32) -> Self {
                $set1(x as i32)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn xor(self, b: Self) -> Self {
                $xor(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn and(self, b: Self) -> Self {
                $and(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn add(self, b: Self) -> Self {
                $add(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn mul(self, b: Self) -> Self {
                $mul(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn shr(self, n: Self) -> Self {
                $shr(self, n)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn shl(self, n: Self) -> Self {
                $shl(self, n)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn or(self, b: Self) -> Self {
                $or(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn load(x: &[u32]) -> Self {
                let x = &x[..Self::WIDTH];
                // SAFETY: `x` holds a whole vector of u32, checked above.
                unsafe { std::ptr::read_unaligned(x.as_ptr().cast::<Self>()) }
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn store(self, out: &mut [u32]) {
                let out = &mut out[..Self::WIDTH];
                // SAFETY: `out` holds a whole vector of u32, checked above.
                unsafe { std::ptr::write_unaligned(out.as_mut_ptr().cast::<Self>(), self) }
            }
        }
    };
}

u32_lanes!(
    __m512i,
    "avx512f",
    _mm512_set1_epi32,
    _mm512_xor_si512,
    _mm512_and_si512,
    _mm512_add_epi32,
    _mm512_mullo_epi32,
    _mm512_srlv_epi32,
    _mm512_sllv_epi32,
    _mm512_or_si512,
    {
        /// One register.
        type Table16 = __m512i;

        #[target_feature(enable = "avx512f")]
        #[inline]
        unsafe fn consecutive(first: u32) -> Self {
            let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
            _mm512_add_epi32(_mm512_set1_epi32(first as i32), iota)
        }
        #[target_feature(enable = "avx512f")]
        #[inline]
        unsafe fn table16(entries: &[u32; 16]) -> __m512i {
            // SAFETY: the load reads the sixteen entries.
            unsafe { _mm512_loadu_si512(entries.as_ptr().cast()) }
        }
        /// One permute (it reads the low four bits of each index).
        #[target_feature(enable = "avx512f")]
        #[inline]
        unsafe fn lookup16(self, table: __m512i) -> Self {
            _mm512_permutexvar_epi32(self, table)
        }
        #[target_feature(enable = "avx512f")]
        #[inline]
        unsafe fn test(self, b: Self) -> u32 {
            _mm512_test_epi32_mask(self, b).into()
        }
    }
);
u32_lanes!(
    __m256i,
    "avx2",
    _mm256_set1_epi32,
    _mm256_xor_si256,
    _mm256_and_si256,
    _mm256_add_epi32,
    _mm256_mullo_epi32,
    _mm256_srlv_epi32,
    _mm256_sllv_epi32,
    _mm256_or_si256,
    {
        /// Entries 0–7 and 8–15 in two registers.
        type Table16 = [__m256i; 2];

        #[target_feature(enable = "avx2")]
        #[inline]
        unsafe fn consecutive(first: u32) -> Self {
            _mm256_add_epi32(_mm256_set1_epi32(first as i32), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7))
        }
        #[target_feature(enable = "avx2")]
        #[inline]
        unsafe fn table16(entries: &[u32; 16]) -> [__m256i; 2] {
            let words = entries.as_ptr().cast::<__m256i>();
            // SAFETY: the loads read the sixteen entries.
            unsafe { [_mm256_loadu_si256(words), _mm256_loadu_si256(words.add(1))] }
        }
        /// Two lane permutes (each reads the low three bits of each index) and a blend.
        #[target_feature(enable = "avx2")]
        #[inline]
        unsafe fn lookup16(self, table: [__m256i; 2]) -> Self {
            let (low, high) =
                (_mm256_permutevar8x32_epi32(table[0], self), _mm256_permutevar8x32_epi32(table[1], self));
            _mm256_blendv_epi8(low, high, _mm256_cmpgt_epi32(self, _mm256_set1_epi32(7)))
        }
        #[target_feature(enable = "avx2")]
        #[inline]
        unsafe fn test(self, b: Self) -> u32 {
            let zero = _mm256_cmpeq_epi32(_mm256_and_si256(self, b), _mm256_setzero_si256());
            !(_mm256_movemask_ps(_mm256_castsi256_ps(zero)) as u32) & 0xff
        }
    }
);
