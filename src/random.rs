//! The bits every sampler and randomised test draws from: the SplitMix64 finaliser as a
//! stateless hash, a seeded generator over it, and the map from random bits to [0, 1).

/// SplitMix64 finaliser: a fast, well-mixed 64-bit hash.
#[inline]
pub fn mix64(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
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
    fn unit_f32_stays_below_one() {
        assert!(unit_f32(u32::MAX) < 1.0);
        assert_eq!(unit_f32(0), 0.0);
    }
}
