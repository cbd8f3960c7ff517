//! Instances: a BLAS placed in the world, which the top level is built over.

use glam::{Affine3A, Mat3A, Vec3A};
use obvhs::aabb::Aabb;

use crate::geometry::{hit::SurfaceHit, ray::Ray};
use crate::math::gamma;

/// One placement of a BLAS in the world.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Index into the scene's BLAS list.
    pub blas: u32,
    /// The object every primitive of this instance belongs to (`None`: each prim names its own).
    pub object: Option<u32>,
    pub(super) to_world: Affine3A,
    to_local: Affine3A,
    pub(super) identity: bool,
    translation_only: bool,
    pub(super) bounds: Aabb,
}

impl Instance {
    /// An instance of `blas` (whose bounds are `local`) placed by `to_world`, or `None` when
    /// the transform is singular or the placed bounds overflow.
    pub fn new(blas: u32, local: Aabb, to_world: Affine3A, object: Option<u32>) -> Option<Self> {
        let to_local = to_world.inverse();
        if !to_local.is_finite() {
            return None;
        }
        let mut bounds = Aabb::empty();
        for i in 0..8 {
            let corner = Vec3A::new(
                if i & 1 == 0 { local.min.x } else { local.max.x },
                if i & 2 == 0 { local.min.y } else { local.max.y },
                if i & 4 == 0 { local.min.z } else { local.max.z },
            );
            bounds.extend(to_world.transform_point3a(corner));
        }
        // Pad by the rounding of the corner transform so no true hit is culled.
        let pad = bounds.min.abs().max(bounds.max.abs()) * gamma(4);
        let bounds = Aabb::new(bounds.min - pad, bounds.max + pad);
        if !(bounds.min.is_finite() && bounds.max.is_finite()) {
            return None;
        }
        Some(Instance {
            blas,
            object,
            to_world,
            to_local,
            identity: to_world == Affine3A::IDENTITY,
            translation_only: to_world.matrix3 == Mat3A::IDENTITY,
            bounds,
        })
    }

    /// Placed bounds in world space.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The transform from the BLAS frame to world space.
    pub fn to_world(&self) -> Affine3A {
        self.to_world
    }

    /// The ray in the instance's frame and the parameter shift `dt` (world t = local t + dt):
    /// the origin is moved along the direction past its transform's rounding error (pbrt-v4).
    #[inline]
    pub(super) fn local_ray(&self, ray: &Ray) -> Option<(Ray, f32)> {
        let m = &self.to_local;
        if self.translation_only {
            // Same direction: only the origin moves, by one rounded subtraction.
            let o = ray.origin + m.translation;
            let o_err = (ray.origin.abs() + m.translation.abs()) * gamma(1);
            let len2 = ray.dir.length_squared();
            let dt = if len2 > 0.0 { ray.dir.abs().dot(o_err) / len2 } else { 0.0 };
            let tmax = ray.tmax - dt;
            return (tmax > 0.0).then(|| (Ray { origin: o + ray.dir * dt, tmax, ..*ray }, dt));
        }
        let o = m.transform_point3a(ray.origin);
        let d = m.matrix3 * ray.dir;
        let o_err = (abs_mat(&m.matrix3) * ray.origin.abs() + m.translation.abs()) * gamma(3);
        let len2 = d.length_squared();
        let dt = if len2 > 0.0 { d.abs().dot(o_err) / len2 } else { 0.0 };
        let tmax = ray.tmax - dt;
        (tmax > 0.0).then(|| (Ray::new(o + d * dt, d, tmax), dt))
    }

    /// A hit found in the instance's frame, moved to world space with its error bound grown by
    /// the transform's rounding (pbrt-v4's `Transform::operator()(Point3fi)`).
    #[inline]
    pub(super) fn to_world_hit(&self, hit: SurfaceHit, dt: f32) -> SurfaceHit {
        let m = &self.to_world;
        let abs = abs_mat(&m.matrix3);
        let p = m.transform_point3a(hit.p);
        let p_error = (abs * hit.p_error) * (1.0 + gamma(3)) + (abs * hit.p.abs() + m.translation.abs()) * gamma(3);
        // Normals go by the inverse transpose; it keeps the side the ray came from.
        let normal = (self.to_local.matrix3.transpose() * hit.normal).normalize();
        SurfaceHit { t: hit.t + dt, p, p_error, normal, ..hit }
    }
}

#[inline(always)]
fn abs_mat(m: &Mat3A) -> Mat3A {
    Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs())
}
