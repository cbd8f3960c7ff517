//! Ray intersection with hemi's primitive shapes: triangles, spheres and infinite planes.
//! Each returns the hit parameter; `surface` recomputes the point with its error bound.

use glam::Vec3A;

use super::{hit::SurfaceHit, ray::Ray};
use crate::math::gamma;

/// A triangle stored as a vertex and two edges.
#[derive(Clone, Copy, Debug)]
pub struct Triangle {
    /// First vertex.
    pub p0: Vec3A,
    /// p1 − p0.
    pub e1: Vec3A,
    /// p2 − p0.
    pub e2: Vec3A,
}

impl Triangle {
    /// The triangle (a, b, c), or `None` if it has zero (or non-finite) area.
    pub fn new(a: Vec3A, b: Vec3A, c: Vec3A) -> Option<Self> {
        let t = Triangle { p0: a, e1: b - a, e2: c - a };
        let n = t.e1.cross(t.e2);
        (n.length_squared() > 0.0 && n.is_finite()).then_some(t)
    }

    /// Möller–Trumbore intersection: (t, b1, b2) for 0 < t < tmax.
    #[inline(always)]
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, f32, f32)> {
        let pvec = ray.dir.cross(self.e2);
        let det = self.e1.dot(pvec);
        if det == 0.0 {
            return None;
        }
        let inv_det = 1.0 / det;
        let tvec = ray.origin - self.p0;
        let b1 = tvec.dot(pvec) * inv_det;
        if !(0.0..=1.0).contains(&b1) {
            return None;
        }
        let qvec = tvec.cross(self.e1);
        let b2 = ray.dir.dot(qvec) * inv_det;
        if b2 < 0.0 || b1 + b2 > 1.0 {
            return None;
        }
        let t = self.e2.dot(qvec) * inv_det;
        (t > 0.0 && t < ray.tmax).then_some((t, b1, b2))
    }

    /// The hit at barycentrics (b1, b2), with pbrt's error bound on the interpolated point.
    #[inline]
    pub fn surface(&self, ray: &Ray, t: f32, b1: f32, b2: f32, object: u32) -> SurfaceHit {
        let a = self.e1 * b1;
        let b = self.e2 * b2;
        let p = self.p0 + a + b;
        let p_error = (self.p0.abs() + a.abs() + b.abs()) * gamma(7);
        SurfaceHit { t, p, p_error, normal: facing(self.e1.cross(self.e2).normalize(), ray.dir), object }
    }

    /// Bounding box corners.
    pub fn bounds(&self) -> (Vec3A, Vec3A) {
        let (p1, p2) = (self.p0 + self.e1, self.p0 + self.e2);
        (self.p0.min(p1).min(p2), self.p0.max(p1).max(p2))
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
        SurfaceHit { t, p, p_error, normal: facing(n, ray.dir), object }
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
        SurfaceHit { t, p, p_error, normal: facing(self.normal, ray.dir), object: self.object }
    }
}

/// `n` flipped to face against `dir` (two-sided shading).
#[inline]
fn facing(n: Vec3A, dir: Vec3A) -> Vec3A {
    if n.dot(dir) > 0.0 { -n } else { n }
}
