//! Vectors of u32 lanes: sixteen in an AVX-512 register (`__m512i`), eight in an AVX2 one
//! (`__m256i`), for the integer hashes of the samplers.

/// Vectors of u32 lanes with the operations Kensler's hashes need (wrapping like the scalar
/// code): sixteen lanes with AVX-512F (`__m512i`), eight with AVX2 (`__m256i`). Every method is
/// compiled for its type's instruction set, which the CPU must have; callers are generic code
/// inlined into functions compiled for it.
pub(crate) trait U32Lanes: Copy {
    /// `x` in every lane.
    unsafe fn splat(x: u32) -> Self;
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
}

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
        $or:ident
    ) => {
        impl U32Lanes for $ty {
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn splat(x: u32) -> Self {
                std::arch::x86_64::$set1(x as i32)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn xor(self, b: Self) -> Self {
                std::arch::x86_64::$xor(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn and(self, b: Self) -> Self {
                std::arch::x86_64::$and(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn add(self, b: Self) -> Self {
                std::arch::x86_64::$add(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn mul(self, b: Self) -> Self {
                std::arch::x86_64::$mul(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn shr(self, n: Self) -> Self {
                std::arch::x86_64::$shr(self, n)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn shl(self, n: Self) -> Self {
                std::arch::x86_64::$shl(self, n)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn or(self, b: Self) -> Self {
                std::arch::x86_64::$or(self, b)
            }
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn load(x: &[u32]) -> Self {
                let x = &x[..size_of::<Self>() / 4];
                // SAFETY: `x` holds a whole vector of u32, checked above.
                unsafe { std::ptr::read_unaligned(x.as_ptr().cast::<Self>()) }
            }
        }
    };
}

u32_lanes!(
    std::arch::x86_64::__m512i,
    "avx512f",
    _mm512_set1_epi32,
    _mm512_xor_si512,
    _mm512_and_si512,
    _mm512_add_epi32,
    _mm512_mullo_epi32,
    _mm512_srlv_epi32,
    _mm512_sllv_epi32,
    _mm512_or_si512
);
u32_lanes!(
    std::arch::x86_64::__m256i,
    "avx2",
    _mm256_set1_epi32,
    _mm256_xor_si256,
    _mm256_and_si256,
    _mm256_add_epi32,
    _mm256_mullo_epi32,
    _mm256_srlv_epi32,
    _mm256_sllv_epi32,
    _mm256_or_si256
);
