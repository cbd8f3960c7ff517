//! Stateless hashing and permutations: every random decision in hemi is a pure function of its
//! inputs, so tile order and thread count never change an image.

use crate::random::mix64;
#[cfg(target_arch = "x86_64")]
use crate::simd::U32Lanes;

/// The key [`hash_sample`] takes for a seed (computed once per seed).
#[inline]
pub fn seed_key(seed: u64) -> u64 {
    mix64(seed ^ 0x9e37_79b9_7f4a_7c15)
}

/// Hashes a (pixel, pass, dimension) tuple under a [`seed_key`] into 64 well-mixed bits.
#[inline]
pub fn hash_sample(pixel: u32, pass: u32, dim: u32, key: u64) -> u64 {
    mix64(mix64(key ^ ((pixel as u64) << 32 | pass as u64)) ^ dim as u64)
}

/// A divisor fixed once and used for many divisions: Lemire, Kaser and Kurz's exact 32-bit
/// division and remainder by multiplication ("Faster remainder by direct computation", 2019),
/// with the bit mask Kensler's permutation needs. A hardware division costs 20–40 cycles, and
/// sampling does several per sample.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Modulus {
    d: u32,
    magic: u64,
    mask: u32,
}

impl Modulus {
    /// Division by `d` (clamped to at least 1).
    pub const fn new(d: u32) -> Self {
        let d = if d == 0 { 1 } else { d };
        let magic = (u64::MAX / d as u64).wrapping_add(1);
        let mut mask = d - 1;
        mask |= mask >> 1;
        mask |= mask >> 2;
        mask |= mask >> 4;
        mask |= mask >> 8;
        mask |= mask >> 16;
        Modulus { d, magic, mask }
    }

    /// The divisor.
    #[inline]
    pub fn get(self) -> u32 {
        self.d
    }

    /// Whether the divisor is a power of two (1 included).
    #[inline]
    pub fn is_power_of_two(self) -> bool {
        self.mask == self.d - 1
    }

    /// `d − 1` with every lower bit set: `d − 1` itself when `d` is a power of two.
    #[inline]
    pub fn mask(self) -> u32 {
        self.mask
    }

    /// `a / d`, exact for every `a`.
    #[inline]
    pub fn quotient(self, a: u32) -> u32 {
        if self.d == 1 { a } else { ((self.magic as u128 * a as u128) >> 64) as u32 }
    }

    /// `a % d`, exact for every `a`.
    #[inline]
    pub fn remainder(self, a: u32) -> u32 {
        let low = self.magic.wrapping_mul(a as u64);
        ((low as u128 * self.d as u128) >> 64) as u32
    }
}

/// Kensler's hashed permutation ("Correlated Multi-Jittered Sampling", 2013): element `i` of a
/// pseudo-random permutation of `0..len` chosen by `seed`, in O(1) memory.
#[inline]
pub fn permute(i: u32, len: Modulus, seed: u32) -> u32 {
    debug_assert!(i < len.get());
    if len.is_power_of_two() {
        return permute_pow2(i, len.mask, seed);
    }
    let mut i = i;
    loop {
        i = permute_round(i, len.mask, seed);
        if i < len.get() {
            break;
        }
    }
    len.remainder(i.wrapping_add(seed))
}

/// [`permute`] for a power-of-two length `mask + 1`: the values are the same, but one round
/// always lands in range (no loop) and the final remainder is a mask, so a run of indices can
/// be computed as one vector loop.
#[inline]
pub fn permute_pow2(i: u32, mask: u32, seed: u32) -> u32 {
    debug_assert!(i <= mask && mask & mask.wrapping_add(1) == 0);
    permute_round(i, mask, seed).wrapping_add(seed) & mask
}

/// One round of Kensler's permutation: a bijection of `0..=w` (`w` all ones below its top bit);
/// [`permute`] repeats it until the result falls below the length (cycle walking).
#[inline(always)]
fn permute_round(mut i: u32, w: u32, p: u32) -> u32 {
    i ^= p;
    i = i.wrapping_mul(0xe170_893d);
    i ^= p >> 16;
    i ^= (i & w) >> 4;
    i ^= p >> 8;
    i = i.wrapping_mul(0x0929_eb3f);
    i ^= p >> 23;
    i ^= (i & w) >> 1;
    i = i.wrapping_mul(1 | p >> 27);
    i = i.wrapping_mul(0x6935_fa69);
    i ^= (i & w) >> 11;
    i = i.wrapping_mul(0x74dc_b303);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0x9e50_1cc3);
    i ^= (i & w) >> 2;
    i = i.wrapping_mul(0xc860_a3df);
    i &= w;
    i ^ (i >> 5)
}

/// [`permute_pow2`] of each lane by its lane of `seed`, with the scalar function's operations,
/// so each lane gets its value.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn permute_pow2_lanes<V: U32Lanes>(i: V, mask: u32, seed: V) -> V {
    let isa = i.isa();
    permute_round_lanes(i, mask, seed).add(seed).and(V::splat(isa, mask))
}

/// Whether `permute_lanes` gives [`permute`]'s values for `len` and `seed`: a power of two,
/// or a length below 2³¹ whose last step (`i + seed` for i < len) cannot wrap around 2³², so
/// that its remainder comes from `seed`'s. Only a seed within `len` of 2³² fails.
#[inline]
pub fn permutes_in_lanes(len: Modulus, seed: u32) -> bool {
    len.is_power_of_two() || (len.get() < 1 << 31 && seed.checked_add(len.get() - 1).is_some())
}

/// [`permute`] of each lane below `len` (lanes at or past it give some value below `len`), for
/// a length and seed that [`permutes_in_lanes`]: every lane does the scalar function's rounds,
/// those that land past the length again (cycle walking) until none does.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn permute_lanes<V: U32Lanes>(i: V, len: Modulus, seed: u32) -> V {
    if len.is_power_of_two() {
        return permute_pow2_lanes(i, len.mask, V::splat(i.isa(), seed));
    }
    debug_assert!(permutes_in_lanes(len, seed));
    let isa = i.isa();
    let u = |x: u32| V::splat(isa, x);
    let ones = u(u32::MAX);
    // All ones in the lanes at or past the length, from the sign of len − 1 − x (every value
    // here is below 2³¹).
    let past = |x: V| u(len.get() - 1).add(x.xor(ones).add(u(1))).shr(u(31)).mul(ones);
    // Lanes past the length start from 0: their walk might never come back below it.
    let mut i = i.and(past(i).xor(ones));
    let seeds = u(seed);
    i = permute_round_lanes(i, len.mask, seeds);
    loop {
        let out = past(i);
        if out.test(ones) == 0 {
            break;
        }
        i = permute_round_lanes(i, len.mask, seeds).and(out).or(i.and(out.xor(ones)));
    }
    // (i + seed) mod len = (i + seed mod len) mod len, as i + seed does not wrap; the sum is
    // below twice the length.
    let sum = i.add(u(seed % len.get()));
    sum.add(u(len.get().wrapping_neg()).and(past(sum)))
}

/// [`permute_round`] of each lane by its lane of `seed`, with its operations.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn permute_round_lanes<V: U32Lanes>(i: V, mask: u32, seed: V) -> V {
    let isa = i.isa();
    let u = |x: u32| V::splat(isa, x);
    let w = u(mask);
    let masked_shift = |i: V, n: u32| i.and(w).shr(u(n));
    let mut i = i.xor(seed);
    i = i.mul(u(0xe170_893d));
    i = i.xor(seed.shr(u(16)));
    i = i.xor(masked_shift(i, 4));
    i = i.xor(seed.shr(u(8)));
    i = i.mul(u(0x0929_eb3f));
    i = i.xor(seed.shr(u(23)));
    i = i.xor(masked_shift(i, 1));
    i = i.mul(u(1).or(seed.shr(u(27))));
    i = i.mul(u(0x6935_fa69));
    i = i.xor(masked_shift(i, 11));
    i = i.mul(u(0x74dc_b303));
    i = i.xor(masked_shift(i, 2));
    i = i.mul(u(0x9e50_1cc3));
    i = i.xor(masked_shift(i, 2));
    i = i.mul(u(0xc860_a3df));
    i = i.and(w);
    i.xor(i.shr(u(5)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    #[test]
    fn permute_is_a_bijection_for_many_lengths_and_seeds() {
        for len in [1u32, 2, 3, 7, 16, 17, 100, 257] {
            for seed in [0u32, 1, 0xdead_beef, 12345] {
                let mut seen = vec![false; len as usize];
                for i in 0..len {
                    let j = permute(i, Modulus::new(len), seed) as usize;
                    assert!(!seen[j], "len {len} seed {seed}: {j} twice");
                    seen[j] = true;
                }
            }
        }
    }

    #[test]
    fn power_of_two_permutation_matches_the_general_one() {
        // The general loop (cycle walking, exact remainder) against the single-round form.
        let general = |i: u32, len: u32, p: u32| {
            let (len, mut i) = (Modulus::new(len), i);
            loop {
                i = permute_round(i, len.mask, p);
                if i < len.get() {
                    break;
                }
            }
            len.remainder(i.wrapping_add(p))
        };
        for len in [1u32, 2, 4, 16, 64, 256, 4096] {
            for seed in [0u32, 7, 0xdead_beef, u32::MAX] {
                for i in 0..len {
                    assert_eq!(permute_pow2(i, len - 1, seed), general(i, len, seed), "len {len}");
                    assert_eq!(permute(i, Modulus::new(len), seed), general(i, len, seed), "len {len}");
                }
            }
        }
    }

    /// The lane permutation gives the scalar one in every lane below the length, for lengths
    /// that are and are not powers of two (cycle walking a different number of rounds per
    /// lane), and a value below the length in the lanes past it.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn lane_permutation_is_the_scalar_one() {
        use crate::simd::{Plain, Portable, SampleLanes};
        type PortableU32 = <Portable as SampleLanes>::U32;
        for len in [1u32, 3, 8, 17, 48, 100, 1000, 70_001] {
            let len = Modulus::new(len);
            for seed in [0u32, 5, 0xdead_beef, u32::MAX - len.get() + 1] {
                assert!(permutes_in_lanes(len, seed));
                for first in (0..len.get() + 8).step_by(8) {
                    let mut out = [0; 8];
                    permute_lanes(PortableU32::consecutive(Plain, first), len, seed).store(&mut out);
                    for (i, &v) in (first..).zip(&out) {
                        assert!(v < len.get(), "len {}, seed {seed}: lane {i} gave {v}", len.get());
                        if i < len.get() {
                            assert_eq!(v, permute(i, len, seed), "len {}, seed {seed}, i {i}", len.get());
                        }
                    }
                }
            }
            assert_eq!(permutes_in_lanes(len, (u32::MAX - len.get()).wrapping_add(2)), len.is_power_of_two());
        }
    }

    #[test]
    fn permutations_differ_between_seeds() {
        let a: Vec<u32> = (0..64).map(|i| permute(i, Modulus::new(64), 1)).collect();
        let b: Vec<u32> = (0..64).map(|i| permute(i, Modulus::new(64), 2)).collect();
        assert_ne!(a, b);
    }

    #[test]
    fn modulus_divides_exactly() {
        let mut rng = SplitMix64::new(7);
        for d in [1u32, 2, 3, 7, 16, 17, 100, 1 << 31, u32::MAX] {
            let m = Modulus::new(d);
            for a in [0u32, 1, d - 1, d, d.wrapping_add(1), u32::MAX]
                .into_iter()
                .chain((0..1000).map(|_| rng.next_u64() as u32))
            {
                assert_eq!((m.quotient(a), m.remainder(a)), (a / d, a % d), "{a} / {d}");
            }
        }
    }
}
