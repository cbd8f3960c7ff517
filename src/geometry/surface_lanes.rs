//! A packet's triangle hits made into surfaces in SIMD lanes: hit point, its error bound and
//! the facing normal of up to sixteen hits together, each lane exactly what
//! [`Triangle::surface`](super::shapes::Triangle::surface) gives its hit, operation for
//! operation.

use crate::{
    math::gamma,
    simd::{Kernel, Lanes, dot3},
};

/// Up to sixteen triangle hits in columns, one hit per lane.
#[derive(Default)]
pub(crate) struct HitColumns {
    /// Axis `a` of vertex `v` of each lane's triangle: `vertices[3v + a]`.
    pub vertices: [[f32; 16]; 9],
    /// Barycentrics (b1, b2) of each hit, weighing its triangle's second and third vertices.
    pub bary: [[f32; 16]; 2],
    /// Each hit's ray direction, by axis.
    pub dir: [[f32; 16]; 3],
}

impl HitColumns {
    /// Puts in lane `k` the hit at barycentrics `bary` of the triangle `vertices` (vertex by
    /// vertex, x, y, z each) along direction `dir`.
    #[inline(always)]
    pub(crate) fn set(&mut self, k: usize, vertices: [f32; 9], bary: [f32; 2], dir: [f32; 3]) {
        for (column, v) in self.vertices.iter_mut().zip(vertices) {
            column[k] = v;
        }
        for (column, b) in self.bary.iter_mut().zip(bary) {
            column[k] = b;
        }
        for (column, d) in self.dir.iter_mut().zip(dir) {
            column[k] = d;
        }
    }
}

/// The surfaces of [`HitColumns`]' hits, by axis: hit points, their error bounds, and unit
/// geometric normals facing the side each ray came from.
#[derive(Default)]
pub(crate) struct SurfaceColumns {
    pub p: [[f32; 16]; 3],
    pub p_error: [[f32; 16]; 3],
    pub normal: [[f32; 16]; 3],
}

/// The surfaces of the first `n` lanes of `hits` into `out`, as a kernel over the lane type.
pub(crate) struct SurfaceLanes<'a> {
    pub hits: &'a HitColumns,
    pub n: usize,
    pub out: &'a mut SurfaceColumns,
}

impl<L: Lanes> Kernel<L> for SurfaceLanes<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let SurfaceLanes { hits, n, out } = self;
        let gamma7 = L::splat(isa, gamma(7));
        let zero = L::splat(isa, 0.0);
        for at in (0..n).step_by(L::WIDTH) {
            let load = |column: &[f32; 16]| L::load(isa, &column[at..]);
            let v: [[L; 3]; 3] = std::array::from_fn(|v| std::array::from_fn(|a| load(&hits.vertices[3 * v + a])));
            let [b1, b2] = hits.bary.each_ref().map(load);
            // b0 = 1 − b1 − b2; p = (a + b) + c; error = (|a| + |b| + |c|)·γ₇.
            let b0 = L::splat(isa, 1.0).sub(b1).sub(b2);
            for (axis, (p, p_error)) in out.p.iter_mut().zip(&mut out.p_error).enumerate() {
                let (a, b, c) = (v[0][axis].mul(b0), v[1][axis].mul(b1), v[2][axis].mul(b2));
                a.add(b).add(c).store(&mut p[at..]);
                a.abs().add(b.abs()).add(c.abs()).mul(gamma7).store(&mut p_error[at..]);
            }
            // (p1 − p0) × (p2 − p0), each component as glam's `Vec3A::cross` makes it, divided
            // by its length (`Vec3A::normalize`), negated where it faces along the ray.
            let e1: [L; 3] = std::array::from_fn(|a| v[1][a].sub(v[0][a]));
            let e2: [L; 3] = std::array::from_fn(|a| v[2][a].sub(v[0][a]));
            let cross = [
                e1[1].mul(e2[2]).sub(e2[1].mul(e1[2])),
                e1[2].mul(e2[0]).sub(e2[2].mul(e1[0])),
                e1[0].mul(e2[1]).sub(e2[0].mul(e1[1])),
            ];
            let length = dot3(&cross, &cross).sqrt();
            let normal = cross.map(|c| c.div(length));
            let dir = hits.dir.each_ref().map(load);
            let away = dot3(&normal, &dir).gt(zero);
            for (axis, n) in normal.into_iter().enumerate() {
                n.select(away, n.neg()).store(&mut out.normal[axis][at..]);
            }
        }
    }
}
