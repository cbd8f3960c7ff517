//! Owen-scrambled Sobol' samples in Morton (Z) pixel order: pbrt-v4's `ZSobolSampler`
//! (Ahmed & Wonka 2020, "Screen-Space Blue-Noise Diffusion of Monte Carlo Sampling Error via
//! Hierarchical Ordering of Pixels") with Burley's (2020) hash-based Owen scrambling.
//!
//! Pixel `p` owns the consecutive indices `morton(p)·spp .. morton(p)·spp + spp` of one global
//! (0,2)-sequence; base-4 digits of that index are permuted by a hash of the higher digits, so
//! neighbouring pixels get well-distributed, decorrelated sub-sequences: the error is blue noise.

use crate::random::mix64;

/// All 24 permutations of four base-4 digits.
const PERMUTATIONS: [[u8; 4]; 24] = {
    let mut p = [[0u8; 4]; 24];
    let mut k = 0;
    let mut a = 0;
    while a < 4 {
        let mut b = 0;
        while b < 4 {
            let mut c = 0;
            while c < 4 {
                let d = 6 - a - b - c;
                if a != b && a != c && b != c {
                    p[k] = [a as u8, b as u8, c as u8, d as u8];
                    k += 1;
                }
                c += 1;
            }
            b += 1;
        }
        a += 1;
    }
    p
};

/// pbrt-v4's `MixBits`.
#[inline]
fn mix_bits(mut v: u64) -> u64 {
    v ^= v >> 31;
    v = v.wrapping_mul(0x7fb5_d329_728e_a185);
    v ^= v >> 27;
    v = v.wrapping_mul(0x81da_def4_bc2d_d44d);
    v ^ (v >> 33)
}

/// Interleaves the bits of x and y (x in the even bits).
#[inline]
pub fn morton2(x: u32, y: u32) -> u64 {
    fn spread(v: u32) -> u64 {
        let mut v = v as u64;
        v = (v | (v << 16)) & 0x0000_ffff_0000_ffff;
        v = (v | (v << 8)) & 0x00ff_00ff_00ff_00ff;
        v = (v | (v << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
        v = (v | (v << 2)) & 0x3333_3333_3333_3333;
        (v | (v << 1)) & 0x5555_5555_5555_5555
    }
    spread(x) | (spread(y) << 1)
}

/// Burley's hash-based Owen scrambling (pbrt-v4's `FastOwenScrambler`, Vegdahl's constants).
#[inline]
pub fn fast_owen(v: u32, seed: u32) -> u32 {
    fast_owen_of_reversed(v.reverse_bits(), seed)
}

/// [`fast_owen`] of the value whose bits `v` holds reversed (its first step).
#[inline(always)]
fn fast_owen_of_reversed(mut v: u32, seed: u32) -> u32 {
    v ^= v.wrapping_mul(0x3d20_adea);
    v = v.wrapping_add(seed);
    v = v.wrapping_mul((seed >> 16) | 1);
    v ^= v.wrapping_mul(0x0552_6c56);
    v ^= v.wrapping_mul(0x53a2_2864);
    v.reverse_bits()
}

/// Dimension 1's matrix, bit-reversed: column b of the matrix, reversed, holds row b of
/// Pascal's triangle mod 2 (bit r is C(b, r) mod 2, which by Lucas' theorem is 1 where the
/// bits of r are a subset of b's), so bit r of the product is the XOR of the index's bits b
/// that are supersets of r: five shift-and-XOR steps, one per bit of a bit position, in
/// plain arithmetic that vectorises without tables.
#[inline(always)]
fn pascal(mut a: u32) -> u32 {
    a ^= (a >> 1) & 0x5555_5555;
    a ^= (a >> 2) & 0x3333_3333;
    a ^= (a >> 4) & 0x0f0f_0f0f;
    a ^= (a >> 8) & 0x00ff_00ff;
    a ^ (a >> 16)
}

/// The Z-order Sobol' sampler's fixed parameters.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ZSobol {
    log2_spp: u32,
    base4_digits: u32,
}

impl ZSobol {
    /// A sampler for `spp` samples per pixel (rounded up to a power of two) on images up to
    /// `resolution` pixels on a side.
    pub fn new(spp: u32, resolution: u32) -> Self {
        let log2_spp = spp.max(1).next_power_of_two().trailing_zeros();
        let res_bits = resolution.max(1).next_power_of_two().trailing_zeros();
        ZSobol { log2_spp, base4_digits: res_bits + log2_spp.div_ceil(2) }
    }

    /// The base-4 digits of pbrt-v4's `ZSobolSampler::GetSampleIndex` that lie wholly above the
    /// sample's bits (digit `log2_spp.div_ceil(2)` up) of `pixel` (the pixel's Morton index
    /// shifted up by `log2_spp`), each permuted by a hash of the digits above it: the same for
    /// every sample of the pixel.
    #[inline]
    fn pixel_digits(&self, pixel: u64, dim_key: u64) -> u64 {
        let odd = u32::from(self.log2_spp & 1 == 1);
        let mut index = 0u64;
        for i in self.log2_spp.div_ceil(2)..self.base4_digits {
            let shift = 2 * i - odd;
            index |= permuted_digit(pixel, shift, mix_bits((pixel >> (shift + 2)) ^ dim_key));
        }
        index
    }

    /// The 2-D sample of pixel (x, y), sample `index` (< 2^log2_spp), dimension `dim`.
    #[inline]
    pub fn sample(&self, x: u32, y: u32, index: u32, dim: u32, seed: u64) -> [f32; 2] {
        let mut out = [glam::Vec2::ZERO];
        self.fill(x, y, index, dim, seed, &mut out);
        out[0].to_array()
    }

    /// [`ZSobol::sample`] for samples `first, first + 1, …` of pixel (x, y), one per element of
    /// `out` (all below 2^log2_spp). A digit's permutation depends only on the digits above it,
    /// so the pixel's own digits are permuted once for the run, and each of the sample's digits
    /// (and the odd power of two's low bit) again only when the digits above it change: once
    /// per 4^k samples for the k-th digit from the bottom, not once per sample.
    #[inline]
    pub fn fill(&self, x: u32, y: u32, first: u32, dim: u32, seed: u64, out: &mut [glam::Vec2]) {
        let pixel = morton2(x, y) << self.log2_spp;
        let dim_key = 0x5555_5555u64.wrapping_mul(dim as u64);
        let high = self.pixel_digits(pixel, dim_key);
        let hash = mix64(seed ^ mix64(dim as u64 + 1));
        fill_samples(self.log2_spp, [pixel, high], first, dim_key, (hash as u32, (hash >> 32) as u32), out);
    }
}

/// The base-4 digit of `morton` at bit `shift`, permuted by `hash` (of the digits above it) and
/// put back in its place.
#[inline(always)]
fn permuted_digit(morton: u64, shift: u32, hash: u64) -> u64 {
    u64::from(packed_permutation(hash) >> (2 * ((morton >> shift) & 3)) & 3) << shift
}

/// The permutation of a base-4 digit that `hash` picks, packed two bits a digit: digit d goes
/// to bits `2d..2d + 2`.
#[inline(always)]
fn packed_permutation(hash: u64) -> u8 {
    let perm = PERMUTATIONS[((hash >> 24) % 24) as usize];
    perm[0] | perm[1] << 2 | perm[2] << 4 | perm[3] << 6
}

/// The permuted sample bits (pbrt-v4's `GetSampleIndex` below the pixel's digits) of samples
/// `start, start + 1, …` of the pixel whose Morton index shifted up by `log2_spp` is `pixel`,
/// one per element of `lows`. A digit's permutation depends only on the digits above it, so
/// the digits are permuted top down, level by level: a level hashes each distinct prefix of
/// the run's indices once and writes its children's digits, in place (a child's slot never
/// lies below its parent's). A run of `n` samples hashes about n / 3 prefixes.
#[inline(always)]
fn permuted_lows(log2_spp: u32, pixel: u64, start: u32, dim_key: u64, lows: &mut [u32]) {
    let Some(last) = (lows.len() as u32).checked_sub(1).map(|n| start + n) else {
        return;
    };
    lows[0] = 0;
    let mut above = log2_spp;
    while above > 0 {
        // Base-4 digits, down to a lone low bit when log2_spp is odd.
        let width = if above == 1 { 1 } else { 2 };
        let shift = above - width;
        let (first_parent, first_child) = (start >> above, start >> shift);
        let last_child = last >> shift;
        for parent in (first_parent..=last >> above).rev() {
            let hash = mix_bits(((pixel >> above) | u64::from(parent)) ^ dim_key);
            let high = lows[(parent - first_parent) as usize];
            let (eldest, youngest) = (parent << width, (parent << width) | ((1 << width) - 1));
            if width == 2 && eldest >= first_child && youngest <= last_child {
                // All four children, the common case.
                let packed = u32::from(packed_permutation(hash));
                let slot = (eldest - first_child) as usize;
                let digits = [0, 2, 4, 6].map(|at| high | (packed >> at & 3) << shift);
                lows[slot..slot + 4].copy_from_slice(&digits);
            } else if width == 2 {
                let packed = packed_permutation(hash);
                for child in (eldest.max(first_child)..=youngest.min(last_child)).rev() {
                    let digit = u32::from(packed >> (2 * (child & 3)) & 3);
                    lows[(child - first_child) as usize] = high | digit << shift;
                }
            } else {
                for child in (eldest.max(first_child)..=youngest.min(last_child)).rev() {
                    lows[(child - first_child) as usize] = high | ((child & 1) ^ (hash as u32 & 1));
                }
            }
        }
        above = shift;
    }
}

crate::simd::multiversion! {
    /// The loop of [`ZSobol::fill`]: `pixel_and_digits` holds the pixel's Morton index shifted
    /// up by `log2_spp` and its digits permuted ([`ZSobol::pixel_digits`]), `dim_key` the
    /// dimension's hash key and `seeds` the Owen scrambling seeds of the two coordinates.
    /// Compiled per instruction set (AVX-512 converts u32 to f32 in one instruction).
    fn fill_samples(log2_spp: u32, pixel_and_digits: [u64; 2], first: u32, dim_key: u64, seeds: (u32, u32), out: &mut [glam::Vec2]) {
        let [pixel, high] = pixel_and_digits;
        let to_unit = |bits: u32| (bits as f32 * (1.0 / 4_294_967_296.0)).min(super::ONE_MINUS_EPSILON);
        // A block of samples at a time: their permuted indices, then their Sobol' bits (both
        // matrices in arithmetic, reversed as the scrambling first reverses them), the
        // scrambling and the conversion in a loop of its own, which the compiler vectorises.
        const BLOCK: usize = 64;
        let mut lows = [0u32; BLOCK];
        for (b, out) in out.chunks_mut(BLOCK).enumerate() {
            let lows = &mut lows[..out.len()];
            permuted_lows(log2_spp, pixel, first.wrapping_add((b * BLOCK) as u32), dim_key, lows);
            for (o, &low) in out.iter_mut().zip(lows.iter()) {
                let index = high as u32 | low;
                let (x, y) = (fast_owen_of_reversed(index, seeds.0), fast_owen_of_reversed(pascal(index), seeds.1));
                *o = glam::Vec2::new(to_unit(x), to_unit(y));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sobol' dimension `dim` (0 or 1) of index `a`, as 32 fixed-point bits: dimension 0's
    /// matrix is the bit reversal (van der Corput), dimension 1's [`pascal`] reversed.
    fn sobol_bits(a: u32, dim: usize) -> u32 {
        if dim == 0 { a.reverse_bits() } else { pascal(a).reverse_bits() }
    }

    /// 2-D Sobol' generator matrices (32-bit columns): dimension 0 is the van der Corput sequence,
    /// dimension 1 follows v_i = v_{i−1} ⊕ (v_{i−1} >> 1) (the (0,2)-sequence's second component).
    const SOBOL: [[u32; 32]; 2] = {
        let mut m = [[0u32; 32]; 2];
        let mut i = 0;
        let mut v = 1u32 << 31;
        while i < 32 {
            m[0][i] = 1 << (31 - i);
            m[1][i] = v;
            v ^= v >> 1;
            i += 1;
        }
        m
    };

    #[test]
    fn first_sobol_points_are_the_classic_02_sequence() {
        let pts: Vec<(u32, u32)> = (0..4).map(|i| (sobol_bits(i, 0) >> 30, sobol_bits(i, 1) >> 30)).collect();
        // (0,0), (1/2,1/2), (1/4,3/4), (3/4,1/4) in units of 1/4.
        assert_eq!(pts, vec![(0, 0), (2, 2), (1, 3), (3, 1)]);
    }

    #[test]
    fn sobol_bits_equal_the_matrix_product() {
        let mut x = 0x1234_5678u32;
        for _ in 0..1000 {
            x = x.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
            for (dim, matrix) in SOBOL.iter().enumerate() {
                let slow = (0..32).filter(|i| x >> i & 1 == 1).fold(0, |v, i| v ^ matrix[i]);
                assert_eq!(sobol_bits(x, dim), slow);
            }
        }
    }

    #[test]
    fn permutations_are_all_distinct() {
        for (i, a) in PERMUTATIONS.iter().enumerate() {
            let mut s = *a;
            s.sort();
            assert_eq!(s, [0, 1, 2, 3]);
            assert!(PERMUTATIONS[..i].iter().all(|b| b != a));
        }
    }

    /// pbrt-v4's `GetSampleIndex` as written there: one loop over every digit.
    fn pbrt_sample_index(z: &ZSobol, morton: u64, dim: u32) -> u64 {
        let pow2 = z.log2_spp & 1 == 1;
        let last = u32::from(pow2);
        let mut index = 0u64;
        let mut i = z.base4_digits;
        while i > last {
            i -= 1;
            let shift = 2 * i - u32::from(pow2);
            let digit = (morton >> shift) & 3;
            let higher = morton >> (shift + 2);
            let p = (mix_bits(higher ^ (0x5555_5555u64.wrapping_mul(dim as u64))) >> 24) % 24;
            index |= (PERMUTATIONS[p as usize][digit as usize] as u64) << shift;
        }
        if pow2 {
            let digit = morton & 1;
            index |= digit ^ (mix_bits((morton >> 1) ^ (0x5555_5555u64.wrapping_mul(dim as u64))) & 1);
        }
        index
    }

    #[test]
    fn runs_of_samples_equal_pbrts_index_sample_by_sample() {
        for spp in [1, 2, 8, 16, 32, 64, 128, 1024, 2048, 4096] {
            let z = ZSobol::new(spp, 640);
            for (x, y, dim, seed) in [(0, 0, 0, 0), (3, 5, 1, 7), (639, 359, 4, 0xdead_beef), (100, 7, 2, 1 << 40)] {
                let mut run = vec![glam::Vec2::ZERO; spp as usize];
                z.fill(x, y, 0, dim, seed, &mut run);
                let hash = mix64(seed ^ mix64(dim as u64 + 1));
                for (i, got) in run.iter().enumerate() {
                    let morton = (morton2(x, y) << z.log2_spp) | i as u64;
                    let a = pbrt_sample_index(&z, morton, dim) as u32;
                    let unit = |b: u32| (b as f32 * (1.0 / 4_294_967_296.0)).min(crate::sampling::ONE_MINUS_EPSILON);
                    let want = [
                        unit(fast_owen(sobol_bits(a, 0), hash as u32)),
                        unit(fast_owen(sobol_bits(a, 1), (hash >> 32) as u32)),
                    ];
                    assert_eq!(got.to_array(), want, "spp {spp}, pixel ({x}, {y}), dim {dim}, sample {i}");
                    assert_eq!(z.sample(x, y, i as u32, dim, seed), want);
                }
                // Runs that start mid-pixel, of any length, give the same samples.
                for (start, len) in [(spp / 2, spp / 2), (1, spp - 1), (spp / 4 + 3, spp / 3), (spp - 1, 1), (5, 70)] {
                    let (start, len) = (start.min(spp - 1), len.min(spp - start.min(spp - 1)));
                    let mut part = vec![glam::Vec2::ZERO; len as usize];
                    z.fill(x, y, start, dim, seed, &mut part);
                    assert_eq!(part[..], run[start as usize..(start + len) as usize], "spp {spp}, run {start}+{len}");
                }
            }
        }
    }

    #[test]
    fn owen_scrambling_is_a_bijection_on_prefixes() {
        // Owen scrambling permutes each elementary interval: the top k bits of 2^k points stay distinct.
        for seed in [1u32, 77, 0xdead_beef] {
            let mut seen = vec![false; 256];
            for i in 0..256u32 {
                let v = fast_owen(i << 24, seed) >> 24;
                assert!(!seen[v as usize]);
                seen[v as usize] = true;
            }
        }
    }
}
