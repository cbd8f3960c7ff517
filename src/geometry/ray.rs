//! Rays with the per-ray constants that the slab and watertight triangle tests need.

use glam::Vec3A;

/// A ray segment `origin + t·dir` for t in (0, tmax). `dir` need not be unit length.
#[derive(Clone, Copy, Debug)]
pub struct Ray {
    /// Start point.
    pub origin: Vec3A,
    /// Direction (any non-zero length; t is measured in units of it).
    pub dir: Vec3A,
    /// Reciprocal of `dir` (±∞ for zero components).
    pub inv_dir: Vec3A,
    /// Far end of the segment.
    pub tmax: f32,
    /// Axis of the largest |dir| component, then the two others (cyclic order).
    pub axes: [usize; 3],
    /// Shear taking `dir` to +z in the permuted frame: (−dx/dz, −dy/dz, 1/dz).
    pub shear: Vec3A,
}

impl Ray {
    /// A ray from `origin` along `dir` up to `tmax`.
    #[inline]
    pub fn new(origin: Vec3A, dir: Vec3A, tmax: f32) -> Self {
        let abs = dir.abs();
        let kz = if abs.x > abs.y {
            if abs.x > abs.z { 0 } else { 2 }
        } else if abs.y > abs.z {
            1
        } else {
            2
        };
        let kx = (kz + 1) % 3;
        let ky = (kx + 1) % 3;
        let dz = dir[kz];
        Ray {
            origin,
            dir,
            inv_dir: dir.recip(),
            tmax,
            axes: [kx, ky, kz],
            shear: Vec3A::new(-dir[kx] / dz, -dir[ky] / dz, 1.0 / dz),
        }
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
