//! Rays with precomputed reciprocal directions for slab tests.

use glam::Vec3A;

/// A ray segment `origin + t·dir` for t in (0, tmax). `dir` need not be unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3A,
    /// Direction (any non-zero length; t is measured in units of it).
    pub dir: Vec3A,
    /// Reciprocal of `dir`, finite in every component.
    pub inv_dir: Vec3A,
    /// Far end of the segment.
    pub tmax: f32,
}

impl Ray {
    /// A ray from `origin` along `dir` up to `tmax`.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A, tmax: f32) -> Self {
        // Zero components get ±MAX instead of ±∞ so that 0·inv never yields NaN in slab tests.
        let inv = |d: f32| {
            let r = 1.0 / d;
            if r.is_finite() { r } else { f32::MAX.copysign(d) }
        };
        Ray { origin, dir, inv_dir: Vec3A::new(inv(dir.x), inv(dir.y), inv(dir.z)), tmax }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.dir * t
    }
}
