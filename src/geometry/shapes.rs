//! Ray intersection with hemi's primitive shapes: triangles, spheres and infinite planes.
//! Each returns the hit parameter; `surface` recomputes the point with its error bound.

use glam::Vec3A;

use super::{
    hit::SurfaceHit,
    ray::{Ray, Shear},
};
use crate::math::gamma;

/// A triangle's plane in f64 ([`Triangle::plane`]).
#[derive(Clone, Copy, Debug)]
pub struct TrianglePlane {
    pub(super) a: glam::DVec3,
    pub(super) n: glam::DVec3,
}

impl TrianglePlane {
    /// Where `ray` meets the plane: its distance along the ray in f64, rounded to f32, so a ray
    /// spawned just off the surface (by the hit's error bound) can never re-hit it (pbrt-v4
    /// instead rejects t below an error bound that grows with the triangle's extent, which
    /// loses true nearby hits on large triangles: biased contact AO). `None` where the ray is
    /// parallel to it.
    #[inline(always)]
    pub fn distance(&self, ray: &Ray) -> Option<f32> {
        let TrianglePlane { a, n } = *self;
        let denom = n.dot(ray.dir.as_dvec3());
        if denom == 0.0 {
            return None;
        }
        Some((n.dot(a - ray.origin.as_dvec3()) / denom) as f32)
    }
}

/// A triangle by its three vertices.
#[derive(Clone, Copy, Debug)]
pub struct Triangle {
    /// Vertices, counter-clockwise seen from the front.
    pub p: [Vec3A; 3],
}

impl Triangle {
    /// The triangle (a, b, c), or `None` if it has zero (or non-finite) area.
    pub fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Option<Self> {
        let n = (b - a).cross(c - a);
        (n.length_squared() > 0.0 && n.is_finite()).then_some(Triangle { p: [a, b, c] })
    }

    /// Watertight intersection (Woop, Benthin, Wald 2013, as in pbrt-v4): rays through shared
    /// edges and vertices hit exactly one of the adjacent triangles or more, never none.
    /// Returns (t, b1, b2) for a hit with 0 < t < tmax, `t` conservatively above zero.
    /// `shear` is [`Shear::new`]`(ray.dir)`, computed once for all the ray's triangles.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray, shear: &Shear) -> Option<(f32, f32, f32)> {
        let [kx, ky, kz] = shear.axes;
        let s = shear.s;
        // Translate to the ray origin, permute so the ray runs along +z, shear.
        // (Three explicit calls: `array::map` is not always inlined into the traversal loops.)
        let f = |p: Vec3A| {
            let q = p - ray.origin;
            Vec3A::new(q[kx] + s.x * q[kz], q[ky] + s.y * q[kz], q[kz])
        };
        let v = [f(self.p[0]), f(self.p[1]), f(self.p[2])];
        let mut e0 = v[1].x * v[2].y - v[1].y * v[2].x;
        let mut e1 = v[2].x * v[0].y - v[2].y * v[0].x;
        let mut e2 = v[0].x * v[1].y - v[0].y * v[1].x;
        if e0 == 0.0 || e1 == 0.0 || e2 == 0.0 {
            // Exactly on an edge in f32: decide in f64.
            let d = |a: Vec3A, b: Vec3A| (a.x as f64 * b.y as f64 - a.y as f64 * b.x as f64) as f32;
            e0 = d(v[1], v[2]);
            e1 = d(v[2], v[0]);
            e2 = d(v[0], v[1]);
        }
        if (e0 < 0.0 || e1 < 0.0 || e2 < 0.0) && (e0 > 0.0 || e1 > 0.0 || e2 > 0.0) {
            return None;
        }
        self.finish(ray, e0, e1, e2)
    }

    /// The rest of [`Triangle::intersect`] once the edge functions (e0, e1, e2) of `ray` have
    /// passed the sign test: the determinant, `t` from the triangle's plane, the barycentrics.
    #[inline(always)]
    pub fn finish(&self, ray: &Ray, e0: f32, e1: f32, e2: f32) -> Option<(f32, f32, f32)> {
        Self::finish_at(|| self.plane().distance(ray), ray.tmax, e0, e1, e2)
    }

    /// The triangle's plane in f64, as [`Triangle::finish`] uses it: a vertex and the normal
    /// (not normalised). Differences of f32 inputs are exact in f64, so the own triangle and
    /// coplanar neighbours share one plane.
    #[inline(always)]
    pub fn plane(&self) -> TrianglePlane {
        let [a, b, c] = self.p.map(|p| p.as_dvec3());
        TrianglePlane { a, n: (b - a).cross(c - a) }
    }

    /// [`Triangle::finish`] of a ray reaching `tmax`, given where it meets the triangle's plane
    /// (`t()`, asked for once the determinant is known not to be zero: [`TrianglePlane::distance`],
    /// or that worked out for many rays at once by `PacketLanes::plane_distances`).
    #[inline(always)]
    pub fn finish_at(t: impl FnOnce() -> Option<f32>, tmax: f32, e0: f32, e1: f32, e2: f32) -> Option<(f32, f32, f32)> {
        let det = e0 + e1 + e2;
        if det == 0.0 {
            return None;
        }
        let t = t()?;
        if !(t > 0.0 && t < tmax) {
            return None;
        }
        let inv_det = 1.0 / det;
        Some((t, e1 * inv_det, e2 * inv_det))
    }

    /// The hit at barycentrics (b1, b2), with pbrt's error bound on the interpolated point.
    #[inline]
    pub fn surface(&self, ray: &Ray, t: f32, b1: f32, b2: f32, object: u32) -> SurfaceHit {
        let b0 = 1.0 - b1 - b2;
        let (a, b, c) = (self.p[0] * b0, self.p[1] * b1, self.p[2] * b2);
        let p = a + b + c;
        let p_error = (a.abs() + b.abs() + c.abs()) * gamma(7);
        let n = (self.p[1] - self.p[0]).cross(self.p[2] - self.p[0]).normalize();
        SurfaceHit { t, p, p_error, normal: facing(n, ray.dir), object, prim: u32::MAX, bary: [b1, b2] }
    }

    /// Bounding box corners.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        let [a, b, c] = self.p;
        (a.min(b).min(c), a.max(b).max(c))
    }
}

/// A sphere in world space.
#[derive(Clone, Copy, Debug)]
pub struct SpherePrim {
    /// Centre.
    pub center: Vec3A,
    /// Radius (> 0).
    pub radius: f32,
}

impl SpherePrim {
    /// Nearest intersection in (0, tmax), using the precise discriminant of Haines et al.
    /// (Ray Tracing Gems ch. 7) so that distant and small spheres stay accurate.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let len = ray.dir.length();
        let d = ray.dir / len;
        let f = ray.origin - self.center;
        let b = -f.dot(d);
        let r2 = self.radius * self.radius;
        let perp = f + d * b;
        let disc = r2 - perp.length_squared();
        if disc < 0.0 {
            return None;
        }
        let flen = f.length();
        let c = (flen - self.radius) * (flen + self.radius);
        // Outside and moving away: no hit, whatever rounding says about the roots.
        if c > 0.0 && b < 0.0 {
            return None;
        }
        let q = b + disc.sqrt().copysign(b);
        let (t0, t1) = if q == 0.0 { (0.0, 0.0) } else { (c / q, q) };
        let (near, far) = if t0 < t1 { (t0, t1) } else { (t1, t0) };
        let (near, far) = (near / len, far / len);
        if near > 0.0 && near < ray.tmax {
            Some(near)
        } else if far > 0.0 && far < ray.tmax && c <= 0.0 {
            Some(far)
        } else {
            None
        }
    }

    /// The hit at parameter t: the point is re-projected onto the sphere (pbrt), which bounds
    /// its error by a few ULPs of its distance to the centre and of the centre itself.
    #[inline]
    pub fn surface(&self, ray: &Ray, t: f32, object: u32) -> SurfaceHit {
        let v = ray.at(t) - self.center;
        let n = v.normalize();
        let v = n * self.radius;
        let p = self.center + v;
        let p_error = (v.abs() + p.abs()) * gamma(6);
        SurfaceHit { t, p, p_error, normal: facing(n, ray.dir), object, prim: u32::MAX, bary: [0.0; 2] }
    }
}

/// An infinite plane.
#[derive(Clone, Copy, Debug)]
pub struct PlanePrim {
    /// A point on the plane.
    pub point: Vec3A,
    /// Unit normal.
    pub normal: Vec3A,
    /// Object index.
    pub object: u32,
}

impl PlanePrim {
    /// Intersection in (0, tmax).
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray) -> Option<f32> {
        let denom = ray.dir.dot(self.normal);
        if denom == 0.0 {
            return None;
        }
        let t = (self.point - ray.origin).dot(self.normal) / denom;
        (t > 0.0 && t < ray.tmax).then_some(t)
    }

    /// The hit at t, re-projected onto the plane so that its error is bounded by a few ULPs of
    /// its coordinates, independent of the ray's angle and length.
    #[inline]
    pub fn surface(&self, ray: &Ray, t: f32) -> SurfaceHit {
        let q = ray.at(t);
        let p = q - self.normal * (q - self.point).dot(self.normal);
        let p_error = (p.abs() + self.point.abs()) * gamma(6);
        SurfaceHit {
            t,
            p,
            p_error,
            normal: facing(self.normal, ray.dir),
            object: self.object,
            prim: u32::MAX,
            bary: [0.0; 2],
        }
    }
}

/// `n` flipped to face against `dir` (two-sided shading).
#[inline]
fn facing(n: Vec3A, dir: Vec3A) -> Vec3A {
    if n.dot(dir) > 0.0 { -n } else { n }
}
