//! Rays with the per-ray constant of the slab test, and the watertight triangle test's own
//! per-ray constants ([`Shear`]), computed only once a ray reaches a triangle.

use glam::{Vec3A, Vec3Swizzles};

/// A ray segment `origin + t·dir` for t in (0, tmax). `dir` need not be unit length.
/// `repr(C)`: packets read its fields in this order (`Lanes::rays`).
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3A,
    /// Direction (any non-zero length; t is measured in units of it).
    pub dir: Vec3A,
    /// Reciprocal of `dir` (±∞ for zero components).
    pub inv_dir: Vec3A,
    /// Far end of the segment.
    pub tmax: f32,
}

impl Ray {
    /// A ray from `origin` along `dir` up to `tmax`.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A, tmax: f32) -> Self {
        Ray { origin, dir, inv_dir: dir.recip(), tmax }
    }

    /// The same ray with another far end.
    #[inline]
    pub fn with_tmax(self, tmax: f32) -> Self {
        Ray { tmax, ..self }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3A {
        self.origin + self.dir * t
    }
}

/// The watertight triangle test's constants for a ray direction (Woop, Benthin, Wald 2013).
#[derive(Clone, Copy, Debug)]
pub struct Shear {
    /// Axis of the largest |dir| component, then the two others (cyclic order).
    pub axes: [usize; 3],
    /// Shear taking `dir` to +z in the permuted frame: (−dx/dz, −dy/dz, 1/dz).
    pub s: Vec3A,
}

impl Shear {
    /// The constants of direction `dir`.
    #[inline]
    pub fn new(dir: Vec3A) -> Self {
        // The axes (kx, ky, kz), kz that of the largest |dir| component, and `dir` in that order.
        let abs = dir.abs();
        let (axes, d) = if abs.x > abs.y {
            if abs.x > abs.z { ([1, 2, 0], dir.yzx()) } else { ([0, 1, 2], dir) }
        } else if abs.y > abs.z {
            ([2, 0, 1], dir.zxy())
        } else {
            ([0, 1, 2], dir)
        };
        // One vector division: the same quotients as three scalar ones.
        Shear { axes, s: Vec3A::new(-d.x, -d.y, 1.0) / d.z }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shear_and_axes_are_the_scalar_definitions() {
        let dirs = [
            Vec3A::new(0.3, -0.2, 0.9),
            Vec3A::new(-5.0, 1.0, 2.0),
            Vec3A::new(0.1, 7.0, -3.0),
            Vec3A::new(1.0, 1.0, 1.0),
            Vec3A::new(0.0, 0.0, -1.0),
            Vec3A::new(1e-30, -3e-7, 2.5e-7),
        ];
        for dir in dirs {
            let shear = Shear::new(dir);
            let [kx, ky, kz] = shear.axes;
            let abs = dir.abs();
            assert!(abs[kz] >= abs[kx] && abs[kz] >= abs[ky] && (kz + 1) % 3 == kx && (kx + 1) % 3 == ky, "{dir}");
            let dz = dir[kz];
            assert_eq!(shear.s, Vec3A::new(-dir[kx] / dz, -dir[ky] / dz, 1.0 / dz), "{dir}");
        }
    }
}
