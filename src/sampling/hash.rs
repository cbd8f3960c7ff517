//! Stateless hashing and permutations: every random decision in hemi is a pure function of its
//! inputs, so tile order and thread count never change an image.

/// SplitMix64 finaliser: a fast, well-mixed 64-bit hash.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// Hashes a (pixel, pass, dimension, seed) tuple into 64 well-mixed bits.
#[inline]
pub fn hash_sample(pixel: u32, pass: u32, dim: u32, seed: u64) -> u64 {
    let a = mix64(seed ^ 0x9e37_79b9_7f4a_7c15);
    let b = mix64(a ^ ((pixel as u64) << 32 | pass as u64));
    mix64(b ^ dim as u64)
}

/// Kensler's hashed permutation ("Correlated Multi-Jittered Sampling", 2013): element `i` of a
/// pseudo-random permutation of `0..len` chosen by `seed`, in O(1) memory.
#[inline]
pub fn permute(mut i: u32, len: u32, seed: u32) -> u32 {
    debug_assert!(len > 0 && i < len);
    if len == 1 {
        return 0;
    }
    let p = seed;
    let mut w = len - 1;
    w |= w >> 1;
    w |= w >> 2;
    w |= w >> 4;
    w |= w >> 8;
    w |= w >> 16;
    loop {
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
        i ^= i >> 5;
        if i < len {
            break;
        }
    }
    (i.wrapping_add(p)) % len
}

/// A small deterministic generator (SplitMix64) for building sample sets from a seed.
#[derive(Clone, Debug)]
pub struct SplitMix64(u64);

impl SplitMix64 {
    /// A generator whose whole stream is fixed by `seed`.
    pub fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    /// The next 64 random bits.
    #[inline]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        mix64(self.0)
    }

    /// A uniform float in [0, 1).
    #[inline]
    pub fn next_f32(&mut self) -> f32 {
        unit_f32(self.next_u64() as u32)
    }

    /// A uniform integer in `0..n` (n > 0), without modulo bias worth measuring at 64 bits.
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        (((self.next_u64() >> 32) * n as u64) >> 32) as u32
    }
}

/// Maps 32 random bits to a float in [0, 1) using the top 24 bits (never rounds up to 1).
#[inline]
pub fn unit_f32(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn permute_is_a_bijection_for_many_lengths_and_seeds() {
        for len in [1u32, 2, 3, 7, 16, 17, 100, 257] {
            for seed in [0u32, 1, 0xdead_beef, 12345] {
                let mut seen = vec![false; len as usize];
                for i in 0..len {
                    let j = permute(i, len, seed) as usize;
                    assert!(!seen[j], "len {len} seed {seed}: {j} twice");
                    seen[j] = true;
                }
            }
        }
    }

    #[test]
    fn permutations_differ_between_seeds() {
        let a: Vec<u32> = (0..64).map(|i| permute(i, 64, 1)).collect();
        let b: Vec<u32> = (0..64).map(|i| permute(i, 64, 2)).collect();
        assert_ne!(a, b);
    }

    #[test]
    fn unit_f32_stays_below_one() {
        assert!(unit_f32(u32::MAX) < 1.0);
        assert_eq!(unit_f32(0), 0.0);
    }
}
