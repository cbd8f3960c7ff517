//! Triangles in packets of four, stored as structure-of-arrays, whose watertight edge tests
//! (Woop, Benthin, Wald 2013) run for all four lanes at once. The lane arithmetic is the
//! scalar [`Triangle::intersect`]'s, operation for operation, so every lane's edge functions
//! are bit-identical to it; lanes where one is zero or NaN go through the scalar test (with
//! its f64 edge fallback), and only lanes that pass the sign test get their determinant and
//! their f64 plane distance computed, by the scalar [`Triangle::finish`].

use glam::{Vec3A, Vec4};

use super::{
    ray::{Ray, Shear},
    shapes::Triangle,
};

/// Four triangles (fewer in a leaf's last packet: unused lanes have slot `u32::MAX`).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(16))]
pub struct Tri4 {
    /// `p[v][a]`: axis `a` of vertex `v` of the four triangles.
    p: [[Vec4; 3]; 3],
    /// Primitive slot of each lane in the BLAS's leaf order.
    pub slot: [u32; 4],
}

/// A ray's constants for the packet test: origin, axis permutation and shear.
#[derive(Clone, Copy)]
pub struct RayTri4 {
    origin: [Vec4; 3],
    sx: Vec4,
    sy: Vec4,
    /// The scalar test's constants (axes for the lanes here too; the scalar test for lanes
    /// that need it).
    pub shear: Shear,
}

impl RayTri4 {
    /// The packet-test constants of `ray`.
    #[inline(always)]
    pub fn new(ray: &Ray) -> Self {
        let o = ray.origin;
        let shear = Shear::new(ray.dir);
        RayTri4 {
            origin: [Vec4::splat(o.x), Vec4::splat(o.y), Vec4::splat(o.z)],
            sx: Vec4::splat(shear.s.x),
            sy: Vec4::splat(shear.s.y),
            shear,
        }
    }
}

/// Lanes of a packet after the edge tests.
pub struct Lanes {
    /// Lanes whose edge functions are all non-zero and of one sign: call [`Triangle::finish`].
    pub pass: u32,
    /// Lanes with a zero or NaN edge function: call the scalar [`Triangle::intersect`].
    pub exact: u32,
    /// The edge functions (e0, e1, e2).
    pub e: [[f32; 4]; 3],
}

impl Tri4 {
    /// Packs up to four (slot, triangle) pairs.
    pub fn pack(tris: impl Iterator<Item = (u32, Triangle)>) -> Self {
        let mut packet = Tri4 { p: [[Vec4::ZERO; 3]; 3], slot: [u32::MAX; 4] };
        for (lane, (slot, tri)) in tris.take(4).enumerate() {
            packet.slot[lane] = slot;
            for v in 0..3 {
                for a in 0..3 {
                    packet.p[v][a][lane] = tri.p[v][a];
                }
            }
        }
        packet
    }

    /// The triangle in `lane`, exactly as packed.
    #[inline(always)]
    pub fn triangle(&self, lane: usize) -> Triangle {
        let vertex = |v: usize| Vec3A::new(self.p[v][0][lane], self.p[v][1][lane], self.p[v][2][lane]);
        Triangle { p: [vertex(0), vertex(1), vertex(2)] }
    }

    /// Edge tests of the four lanes (unused lanes come back in `exact`; skip them by slot).
    #[inline(always)]
    pub fn edges(&self, r: &RayTri4) -> Lanes {
        let [kx, ky, kz] = r.shear.axes;
        let o = &r.origin;
        // Translate to the ray origin, permute so the ray runs along +z, shear.
        let f = |v: usize| {
            let p = &self.p[v];
            let z = p[kz] - o[kz];
            (p[kx] - o[kx] + r.sx * z, p[ky] - o[ky] + r.sy * z)
        };
        let (v0, v1, v2) = (f(0), f(1), f(2));
        let e0 = v1.0 * v2.1 - v1.1 * v2.0;
        let e1 = v2.0 * v0.1 - v2.1 * v0.0;
        let e2 = v0.0 * v1.1 - v0.1 * v1.0;
        let zero = Vec4::ZERO;
        // Zero or NaN: `e != e` is NaN, and `cmpeq` catches both zeros.
        let exact =
            e0.cmpeq(zero) | e1.cmpeq(zero) | e2.cmpeq(zero) | e0.is_nan_mask() | e1.is_nan_mask() | e2.is_nan_mask();
        let pos = e0.cmpgt(zero) & e1.cmpgt(zero) & e2.cmpgt(zero);
        let neg = e0.cmplt(zero) & e1.cmplt(zero) & e2.cmplt(zero);
        let exact = exact.bitmask();
        Lanes { pass: (pos | neg).bitmask() & !exact, exact, e: [e0.to_array(), e1.to_array(), e2.to_array()] }
    }
}
