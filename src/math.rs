//! Floating-point helpers and the orthonormal basis used to orient hemisphere samples.

use glam::Vec3;

/// Unit roundoff of `f32` (half an ULP at 1.0).
pub const MACHINE_EPSILON: f32 = f32::EPSILON * 0.5;

/// Higham's γ(n) = nε / (1 − nε): bounds the relative error of n chained roundings.
#[inline]
pub fn gamma(n: i32) -> f32 {
    let ne = n as f32 * MACHINE_EPSILON;
    ne / (1.0 - ne)
}

/// The next representable `f32` above `v` (infinity stays infinity).
#[inline]
pub fn next_float_up(v: f32) -> f32 {
    if v.is_infinite() && v > 0.0 {
        return v;
    }
    let v = if v == -0.0 { 0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v >= 0.0 { bits + 1 } else { bits - 1 };
    f32::from_bits(bits)
}

/// The next representable `f32` below `v` (negative infinity stays).
#[inline]
pub fn next_float_down(v: f32) -> f32 {
    if v.is_infinite() && v < 0.0 {
        return v;
    }
    let v = if v == 0.0 { -0.0 } else { v };
    let bits = v.to_bits();
    let bits = if v > 0.0 { bits - 1 } else { bits + 1 };
    f32::from_bits(bits)
}

/// `v` moved one float the way `o` points: [`next_float_up`] where `o` is positive,
/// [`next_float_down`] where it is negative, unchanged otherwise (zero or NaN). The definition
/// that the geometry's `step_away` and the lanes' `BitLanes::step_away` give bit for bit.
#[inline]
pub fn step_float(v: f32, o: f32) -> f32 {
    if o > 0.0 {
        next_float_up(v)
    } else if o < 0.0 {
        next_float_down(v)
    } else {
        v
    }
}

/// An orthonormal frame (u, v, w) with w along a given unit normal.
#[derive(Clone, Copy, Debug)]
pub struct Onb {
    /// First tangent.
    pub u: Vec3,
    /// Second tangent.
    pub v: Vec3,
    /// The normal.
    pub w: Vec3,
}

impl Onb {
    /// Builds a frame around the unit vector `n` by Duff et al. 2017 ("Building an Orthonormal
    /// Basis, Revisited"): branchless and accurate for every direction, including n = ±up.
    #[inline]
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let u = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let v = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Onb { u, v, w: n }
    }

    /// The frame under symmetry `k` (0..8) of the square its tangents span: turned about the
    /// normal by k quarter turns ((u, v) → (v, −u) each), then mirrored (v negated) for k ≥ 4.
    /// Exact (only swaps and negations), and a quadrant of the tangent plane stays a quadrant.
    /// Made by bit masks, without branches: `k` changes unpredictably from one block of pixels
    /// to the next.
    #[inline]
    pub fn symmetry(&self, k: u32) -> Self {
        // An odd number of quarter turns swaps the tangents; u's new value is negated from two
        // quarter turns on, v's for one or two of them, and again when mirrored.
        let swap = 0u32.wrapping_sub(k & 1);
        let negate_u = (k >> 1 & 1) << 31;
        let negate_v = ((k ^ k >> 1 ^ k >> 2) & 1) << 31;
        let pick = |a: Vec3, b: Vec3, negate: u32| {
            let (a, b) = (a.to_array(), b.to_array());
            Vec3::from_array(std::array::from_fn(|i| {
                f32::from_bits((a[i].to_bits() & !swap | b[i].to_bits() & swap) ^ negate)
            }))
        };
        Onb { u: pick(self.u, self.v, negate_u), v: pick(self.v, self.u, negate_v), w: self.w }
    }

    /// Maps a direction from the local frame (z along the normal) to world space.
    #[inline]
    pub fn to_world(&self, local: Vec3) -> Vec3 {
        self.u * local.x + self.v * local.y + self.w * local.z
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn onb_is_orthonormal_for_every_normal_including_poles() {
        let mut normals = vec![
            Vec3::Z,
            -Vec3::Z,
            Vec3::Y,
            -Vec3::Y,
            Vec3::X,
            Vec3::new(0.0, 1e-8, -1.0).normalize(),
            Vec3::new(1e-7, 0.0, -1.0).normalize(),
        ];
        // A deterministic spiral over the sphere.
        for i in 0..2000 {
            let z = 1.0 - 2.0 * (i as f32 + 0.5) / 2000.0;
            let r = (1.0 - z * z).sqrt();
            let phi = i as f32 * 2.399_963;
            normals.push(Vec3::new(r * phi.cos(), r * phi.sin(), z).normalize());
        }
        for n in normals {
            let f = Onb::from_normal(n);
            for (a, b) in [(f.u, f.v), (f.u, f.w), (f.v, f.w)] {
                assert!(a.dot(b).abs() < 1e-5, "not orthogonal for n = {n}");
            }
            for x in [f.u, f.v, f.w] {
                assert!((x.length() - 1.0).abs() < 1e-5, "not unit for n = {n}");
            }
            // Right-handed: u × v = w.
            assert!(f.u.cross(f.v).distance(n) < 1e-5, "left-handed for n = {n}");
        }
    }

    #[test]
    fn symmetries_turn_and_mirror_the_tangents_exactly() {
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        // Signed zeros too: a negation must flip them as `-x` does.
        for n in [Vec3::Z, -Vec3::Z, Vec3::Y, Vec3::new(0.48, -0.6, 0.64), Vec3::new(-0.0, 0.0, 1.0)] {
            let f = Onb::from_normal(n);
            for k in 0..8 {
                // k quarter turns, (u, v) → (v, −u) each, then v negated for k ≥ 4.
                let (mut u, mut v) = (f.u, f.v);
                for _ in 0..k % 4 {
                    (u, v) = (v, -u);
                }
                let v = if k >= 4 { -v } else { v };
                let g = f.symmetry(k);
                assert_eq!([bits(g.u), bits(g.v), bits(g.w)], [bits(u), bits(v), bits(f.w)], "n = {n}, k = {k}");
            }
        }
    }

    #[test]
    fn next_float_steps_one_ulp() {
        assert!(next_float_up(1.0) > 1.0 && next_float_down(1.0) < 1.0);
        assert_eq!(next_float_up(0.0), f32::from_bits(1));
        assert_eq!(next_float_down(0.0), -f32::from_bits(1));
        assert_eq!(next_float_up(-1.0), f32::from_bits((-1.0f32).to_bits() - 1));
        assert!(gamma(3) > 3.0 * MACHINE_EPSILON);
    }
}
