//! Surface hits with a floating-point error bound, and scale-invariant ray spawning from them.

use glam::Vec3A;

use crate::math::{next_float_down, next_float_up};

/// A ray–surface intersection.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    /// Ray parameter of the hit.
    pub t: f32,
    /// Hit point.
    pub p: Vec3A,
    /// Conservative per-axis bound on the rounding error in `p`.
    pub p_error: Vec3A,
    /// Unit geometric normal, facing the side the ray came from.
    pub normal: Vec3A,
    /// Index of the scene object that was hit.
    pub object: u32,
}

impl SurfaceHit {
    /// The origin for a ray leaving this surface towards `w`: the hit point pushed along the
    /// normal just past its own error bound (pbrt-v4's `OffsetRayOrigin`), then rounded away
    /// from the surface. The offset tracks the real rounding error, so it is as small as the
    /// arithmetic allows at any scale or distance from the origin.
    #[inline]
    pub fn spawn_origin(&self, w: Vec3A) -> Vec3A {
        offset_ray_origin(self.p, self.p_error, self.normal, w)
    }

    /// Both origins [`SurfaceHit::spawn_origin`] can return, worked out once for a hit that
    /// spawns many rays.
    #[inline]
    pub fn spawn_origins(&self) -> SpawnOrigins {
        SpawnOrigins {
            p: self.p,
            normal: self.normal,
            front: self.spawn_origin(self.normal),
            back: self.spawn_origin(-self.normal),
        }
    }
}

/// The ray origins of one hit on either side of its surface.
#[derive(Clone, Copy, Debug)]
pub struct SpawnOrigins {
    /// The hit point.
    pub p: Vec3A,
    normal: Vec3A,
    front: Vec3A,
    back: Vec3A,
}

impl SpawnOrigins {
    /// The origin for a ray towards `w`: exactly [`SurfaceHit::spawn_origin`]`(w)`.
    #[inline]
    pub fn towards(&self, w: Vec3A) -> Vec3A {
        if w.dot(self.normal) < 0.0 { self.back } else { self.front }
    }

    /// The normal whose side [`SpawnOrigins::towards`] tests: a direction `w` starts behind
    /// the surface when `w.x·n.x + w.y·n.y + w.z·n.z < 0`, summed in that order.
    #[inline(always)]
    pub fn normal(&self) -> Vec3A {
        self.normal
    }

    /// The origin in front of the surface and the one behind it.
    #[inline(always)]
    pub fn sides(&self) -> (Vec3A, Vec3A) {
        (self.front, self.back)
    }
}

/// Offsets `p` (with error bound `err`) along `n` to the side of `w`, far enough that the
/// spawned ray cannot re-hit the surface that `p` lies on.
#[inline]
pub fn offset_ray_origin(p: Vec3A, err: Vec3A, n: Vec3A, w: Vec3A) -> Vec3A {
    let d = n.abs().dot(err);
    let mut offset = n * d;
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    let po = p + offset;
    let round = |v: f32, o: f32| {
        if o > 0.0 {
            next_float_up(v)
        } else if o < 0.0 {
            next_float_down(v)
        } else {
            v
        }
    };
    Vec3A::new(round(po.x, offset.x), round(po.y, offset.y), round(po.z, offset.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spawn_origins_are_those_of_spawn_origin() {
        let hit = SurfaceHit {
            t: 1.0,
            p: Vec3A::new(1e3, -2.5, 1e-3),
            p_error: Vec3A::new(1e-4, 3e-7, 0.0),
            normal: Vec3A::new(0.6, 0.0, -0.8),
            object: 0,
        };
        let origins = hit.spawn_origins();
        let ws = [Vec3A::X, -Vec3A::X, Vec3A::Z, Vec3A::new(0.8, 0.3, 0.6), Vec3A::new(0.8, 0.0, 0.6), Vec3A::ZERO];
        for w in ws {
            assert_eq!(origins.towards(w), hit.spawn_origin(w), "w = {w}");
        }
        assert_ne!(origins.towards(Vec3A::X), origins.towards(-Vec3A::X));
    }
}
