//! Correlated multi-jittered sampling (Kensler 2013, "Correlated Multi-Jittered Sampling"):
//! stateless multi-jittered patterns of any size, each a pure function of (index, pattern).

use super::{
    generators::grid_shape,
    hash::{Modulus, permute},
};

/// Kensler's hash to a float in [0, 1).
#[inline]
fn randfloat(mut i: u32, p: u32) -> f32 {
    i ^= p;
    i ^= i >> 17;
    i ^= i >> 10;
    i = i.wrapping_mul(0xb365_34e5);
    i ^= i >> 12;
    i ^= i >> 21;
    i = i.wrapping_mul(0x93fc_4795);
    i ^= 0xdf6e_307f;
    i ^= i >> 17;
    i = i.wrapping_mul(1 | p >> 18);
    (i as f32 * (1.0 / 4_294_967_808.0)).min(1.0 - f32::EPSILON * 0.5)
}

/// The `n`-point correlated multi-jittered patterns, with the grid shape worked out once. Each
/// pattern is stratified on an m × k grid (m·k = n) and in both 1-D projections, with the
/// sample order itself shuffled. Computed per sample, so every (pixel, pass, dimension) gets a pattern of its own without a
/// stored table (a table lookup per sample is a cache miss on large images).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cmj {
    n: Modulus,
    m: Modulus,
    k: Modulus,
    /// 1/m and 1/k.
    inv: [f32; 2],
}

impl Cmj {
    /// Patterns of `n` ≥ 1 points.
    pub fn new(n: u32) -> Self {
        let n = n.max(1);
        let (m, k) = grid_shape(n);
        Cmj { n: Modulus::new(n), m: Modulus::new(m), k: Modulus::new(k), inv: [1.0 / m as f32, 1.0 / k as f32] }
    }

    /// Sample `s` (< n) of pattern `p`.
    #[inline]
    pub fn sample(&self, s: u32, p: u32) -> [f32; 2] {
        let Cmj { n, m, k, inv: [inv_m, inv_k] } = *self;
        let s = permute(s, n, p.wrapping_mul(0x5163_3e2d));
        let (col, row) = (m.remainder(s), m.quotient(s));
        let sx = permute(col, m, p.wrapping_mul(0xa511_e9b3));
        let sy = permute(row, k, p.wrapping_mul(0x63d8_3595));
        let jx = randfloat(s, p.wrapping_mul(0xa399_d265));
        let jy = randfloat(s, p.wrapping_mul(0x711a_d6a5));
        let x = (col as f32 + (sy as f32 + jx) * inv_k) * inv_m;
        let y = (row as f32 + (sx as f32 + jy) * inv_m) * inv_k;
        let below_one = |v: f32| v.min(1.0 - f32::EPSILON * 0.5);
        [below_one(x), below_one(y)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cmj_is_stratified_on_the_grid_and_both_axes() {
        for n in [16u32, 12, 64] {
            let (m, k) = grid_shape(n);
            for p in [1u32, 99, 12345] {
                let pts: Vec<[f32; 2]> = (0..n).map(|s| Cmj::new(n).sample(s, p)).collect();
                let mut cells = vec![0; n as usize];
                let mut xs = vec![0; n as usize];
                let mut ys = vec![0; n as usize];
                for [x, y] in &pts {
                    cells[((y * k as f32) as u32 * m + (x * m as f32) as u32) as usize] += 1;
                    xs[(x * n as f32) as usize] += 1;
                    ys[(y * n as f32) as usize] += 1;
                }
                assert!(cells.iter().all(|&c| c == 1), "grid, n={n}");
                assert!(xs.iter().all(|&c| c == 1) && ys.iter().all(|&c| c == 1), "1-D, n={n}");
            }
        }
    }
}
