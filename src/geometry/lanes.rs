//! Rays in SIMD lanes, for packet traversal and direction runs: [`RayLanes`], and the
//! [`PacketLanes`] a lane type needs to gather rays into lanes and scatter them back.

use std::arch::x86_64::*;

use glam::{DVec3, Vec3A};

use super::{ray::Ray, wide_bvh::NodeTest};
use crate::simd::{Avx, Avx512, HasAvx2, HasAvx512, Lanes, Plain, Portable, avx::transpose8, avx512::transpose16};

/// A packet's rays in lanes, one ray per lane: origin, direction and reciprocal direction per
/// axis, and the far end of the segment.
#[derive(Clone, Copy)]
pub(crate) struct RayLanes<L> {
    /// Origin x, y, z.
    pub origin: [L; 3],
    /// Direction x, y, z.
    pub dir: [L; 3],
    /// Reciprocal direction x, y, z.
    pub inv_dir: [L; 3],
    /// `tmax`.
    pub tmax: L,
}

impl<L: Lanes> RayLanes<L> {
    /// Lane `k`'s ray, its floats read out of the lanes.
    #[inline(always)]
    pub(crate) fn ray(&self, k: usize) -> Ray {
        let v = |a: &[L; 3]| Vec3A::new(a[0].lane(k), a[1].lane(k), a[2].lane(k));
        Ray { origin: v(&self.origin), dir: v(&self.dir), inv_dir: v(&self.inv_dir), tmax: self.tmax.lane(k) }
    }

    /// A box holding every point within `bounds` of the segments (origin to `tmax` along the
    /// direction) of the lanes of `live`, and their origins, grown by 2⁻¹⁸ of its largest
    /// coordinate (as split triangles' boxes are): far more than the rounding of its corners
    /// and of any hit a triangle test finds before `tmax`. `None` where a segment is unbounded
    /// and leaves no finite `bounds`.
    #[inline(always)]
    pub(crate) fn segments_box(&self, live: u32, bounds: &obvhs::aabb::Aabb) -> Option<(Vec3A, Vec3A)> {
        let (mut lo, mut hi) = ([0.0f32; 3], [0.0f32; 3]);
        let isa = self.tmax.isa();
        let inf = L::splat(isa, f32::INFINITY);
        let mut length = self.tmax;
        if L::bits(length.lt(inf)) & live != live {
            // Unbounded segments cut where they leave `bounds`, past which nothing lies
            // (bounded ones are left whole: cutting them seldom pays for its cost): at the
            // least of the distances to the far plane on each axis (a NaN one, from a
            // zero direction component on one of the box's planes, counts as unbounded),
            // and no less than 0.
            // (Loops, not closures: a closure is compiled without the caller's instruction set.)
            for a in 0..3 {
                let mut exit = L::splat(isa, f32::NEG_INFINITY);
                for p in [bounds.min[a], bounds.max[a]] {
                    let t = L::splat(isa, p).sub(self.origin[a]).mul(self.inv_dir[a]);
                    exit = t.select(t.ne(t), inf).max_keep(exit);
                }
                length = exit.min_keep(length);
            }
            length = length.max_keep(L::splat(isa, 0.0));
            if L::bits(length.lt(inf)) & live != live {
                return None;
            }
        }
        let dead = L::mask(isa, !live);
        for a in 0..3 {
            // Finite origins, directions and lengths: each end is a number, or an
            // infinity on overflow, which the check below rejects.
            let (o, end) = (self.origin[a], self.origin[a].add(self.dir[a].mul(length)));
            lo[a] = o.min_keep(end).select(dead, inf).least();
            hi[a] = o.max_keep(end).select(dead, L::splat(isa, f32::NEG_INFINITY)).greatest();
        }
        let (lo, hi) = (Vec3A::from_array(lo), Vec3A::from_array(hi));
        if !(lo.is_finite() && hi.is_finite()) {
            return None;
        }
        let pad = lo.abs().max(hi.abs()).max_element() * (1.0 / 262_144.0);
        Some((lo - pad, hi + pad))
    }
}

/// Floats of a [`Ray`] read into lanes: origin, direction and reciprocal direction (four each,
/// the fourth unused) and `tmax`. The rest of a `Ray` is padding, which is never read.
const RAY_FLOATS: usize = 13;

// `Lanes::write_rays` writes sixteen floats per ray.
const _: () = assert!(size_of::<Ray>() == 64);

/// Lanes that rays can be gathered into and written back from.
pub(crate) trait PacketLanes: Lanes {
    /// The eight-wide node test these lanes imply: what a packet traversal's single-ray work
    /// (its front-to-back order, its entry node, rays that go on alone) runs in.
    type NodeTest8: NodeTest<8>;
    /// That node test's token.
    fn node_test8(isa: Self::Isa) -> Self::NodeTest8;
    /// `rays` (one to `WIDTH`) in lanes 0, 1, …, lanes past the last repeating it: each field
    /// gathered by register shuffles, with no round trip through memory.
    fn rays(isa: Self::Isa, rays: &[Ray]) -> RayLanes<Self>;
    /// The inverse of [`PacketLanes::rays`]: lane k's ray written to `out[at[k]]`, for every lane
    /// (`at` holds at least `WIDTH` indices; lanes may share one); the fourth lane of each
    /// vector is 0.
    fn write_rays(lanes: &RayLanes<Self>, out: &mut [Ray], at: &[u32]);
    /// Where each lane's ray (origin `o`, direction `d`) meets the plane through `a` with
    /// normal `n`: `t = (n·(a − o)) / (n·d)` in f64, rounded to f32, each lane with exactly the
    /// operations of [`TrianglePlane::distance`], and the lanes where `n·d ≠ 0` (elsewhere the
    /// ray meets no plane, whatever `t` holds).
    ///
    /// [`TrianglePlane::distance`]: super::shapes::TrianglePlane::distance
    fn plane_distances(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3]) -> (Self, u32);

    /// The lanes whose ray meets that plane at a `t` in (0, `tmax`) ([`PacketLanes::plane_distances`]).
    #[inline(always)]
    fn plane_hits(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3], tmax: Self) -> u32 {
        let (t, meets) = Self::plane_distances(n, a, o, d);
        let zero = Self::splat(tmax.isa(), 0.0);
        meets & Self::bits(Self::and(t.gt(zero), t.lt(tmax)))
    }
}

impl PacketLanes for Avx {
    type NodeTest8 = HasAvx2;
    #[inline(always)]
    fn node_test8(isa: HasAvx2) -> HasAvx2 {
        isa
    }
    /// Each ray as two rows of eight (origin and direction; reciprocal direction and `tmax`),
    /// transposed eight by eight.
    #[inline(always)]
    fn rays(isa: HasAvx2, rays: &[Ray]) -> RayLanes<Self> {
        let last = rays.len() - 1;
        // SAFETY: the token proves x86-64-v3; a `Ray` is `repr(C)` with these floats first,
        // and the masked load reads only the first RAY_FLOATS - 8 floats of the back row.
        let (front, back) = unsafe {
            let tail = _mm256_setr_epi32(-1, -1, -1, -1, -1, 0, 0, 0);
            let (mut front, mut back) = ([_mm256_setzero_ps(); 8], [_mm256_setzero_ps(); 8]);
            for k in 0..8 {
                let p = (&rays[k.min(last)] as *const Ray).cast::<f32>();
                front[k] = _mm256_loadu_ps(p);
                back[k] = _mm256_maskload_ps(p.add(8), tail);
            }
            (front, back)
        };
        // Indexed, not `.map(..)`: `map` is generic std code, and out of line it passes the
        // rows through memory.
        let (f, b) = (transpose8(isa, &front), transpose8(isa, &back));
        let v = |x| Avx::from_raw(isa, x);
        RayLanes {
            origin: [v(f[0]), v(f[1]), v(f[2])],
            dir: [v(f[4]), v(f[5]), v(f[6])],
            inv_dir: [v(b[0]), v(b[1]), v(b[2])],
            tmax: v(b[4]),
        }
    }
    #[inline(always)]
    fn write_rays(lanes: &RayLanes<Self>, out: &mut [Ray], at: &[u32]) {
        let isa = lanes.tmax.isa();
        // SAFETY: the lanes prove x86-64-v3.
        let zero = unsafe { _mm256_setzero_ps() };
        let ([ox, oy, oz], [dx, dy, dz], [ix, iy, iz]) = (lanes.origin, lanes.dir, lanes.inv_dir);
        let front = transpose8(isa, &[ox.raw(), oy.raw(), oz.raw(), zero, dx.raw(), dy.raw(), dz.raw(), zero]);
        let back = transpose8(isa, &[ix.raw(), iy.raw(), iz.raw(), zero, lanes.tmax.raw(), zero, zero, zero]);
        for (k, &at) in at[..8].iter().enumerate() {
            let p = (&mut out[at as usize] as *mut Ray).cast::<f32>();
            // SAFETY: the lanes prove x86-64-v3; a `Ray` is `repr(C)`, 64 bytes: sixteen
            // floats' room.
            unsafe {
                _mm256_storeu_ps(p, front[k]);
                _mm256_storeu_ps(p.add(8), back[k]);
            }
        }
    }
    /// In two halves of four f64 lanes.
    #[inline(always)]
    fn plane_distances(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3]) -> (Self, u32) {
        let isa = o[0].isa();
        // SAFETY: the lanes prove x86-64-v3.
        unsafe {
            let half = |v: &Avx, h: usize| {
                let q = if h == 0 { _mm256_castps256_ps128(v.raw()) } else { _mm256_extractf128_ps::<1>(v.raw()) };
                _mm256_cvtps_pd(q)
            };
            let dot = |x: __m256d, y: __m256d, z: __m256d| {
                let xy = _mm256_add_pd(_mm256_mul_pd(_mm256_set1_pd(n.x), x), _mm256_mul_pd(_mm256_set1_pd(n.y), y));
                _mm256_add_pd(xy, _mm256_mul_pd(_mm256_set1_pd(n.z), z))
            };
            let mut t = [_mm_setzero_ps(); 2];
            let mut meets = 0;
            for (h, t) in t.iter_mut().enumerate() {
                let denom = dot(half(&d[0], h), half(&d[1], h), half(&d[2], h));
                let to = |k: usize, c: f64| _mm256_sub_pd(_mm256_set1_pd(c), half(&o[k], h));
                let num = dot(to(0, a.x), to(1, a.y), to(2, a.z));
                *t = _mm256_cvtpd_ps(_mm256_div_pd(num, denom));
                let nonzero = _mm256_cmp_pd::<_CMP_NEQ_UQ>(denom, _mm256_setzero_pd());
                meets |= (_mm256_movemask_pd(nonzero) as u32) << (4 * h);
            }
            let t = _mm256_insertf128_ps::<1>(_mm256_castps128_ps256(t[0]), t[1]);
            (Avx::from_raw(isa, t), meets)
        }
    }
}

impl PacketLanes for Avx512 {
    type NodeTest8 = HasAvx2;
    #[inline(always)]
    fn node_test8(isa: HasAvx512) -> HasAvx2 {
        isa.into()
    }
    /// Each ray as one row of sixteen, transposed sixteen by sixteen.
    #[inline(always)]
    fn rays(isa: HasAvx512, rays: &[Ray]) -> RayLanes<Self> {
        let last = rays.len() - 1;
        // SAFETY: the token proves AVX-512F; a `Ray` is `repr(C)` with these floats first, and
        // the masked load reads only the first RAY_FLOATS.
        let row = unsafe {
            let mut row = [_mm512_setzero_ps(); 16];
            for (k, row) in row.iter_mut().enumerate() {
                let p = (&rays[k.min(last)] as *const Ray).cast::<f32>();
                *row = _mm512_maskz_loadu_ps((1 << RAY_FLOATS) - 1, p);
            }
            row
        };
        // Indexed, not `.map(..)`: `map` is generic std code, and out of line it passes the
        // rows through memory.
        let t = transpose16(isa, &row);
        let v = |x| Avx512::from_raw(isa, x);
        RayLanes {
            origin: [v(t[0]), v(t[1]), v(t[2])],
            dir: [v(t[4]), v(t[5]), v(t[6])],
            inv_dir: [v(t[8]), v(t[9]), v(t[10])],
            tmax: v(t[12]),
        }
    }
    #[inline(always)]
    fn write_rays(lanes: &RayLanes<Self>, out: &mut [Ray], at: &[u32]) {
        let isa = lanes.tmax.isa();
        // SAFETY: the lanes prove AVX-512F.
        let zero = unsafe { _mm512_setzero_ps() };
        let ([ox, oy, oz], [dx, dy, dz], [ix, iy, iz]) = (lanes.origin, lanes.dir, lanes.inv_dir);
        let rows = transpose16(
            isa,
            &[
                ox.raw(),
                oy.raw(),
                oz.raw(),
                zero,
                dx.raw(),
                dy.raw(),
                dz.raw(),
                zero,
                ix.raw(),
                iy.raw(),
                iz.raw(),
                zero,
                lanes.tmax.raw(),
                zero,
                zero,
                zero,
            ],
        );
        for (&at, row) in at[..16].iter().zip(rows) {
            // SAFETY: the lanes prove AVX-512F; a `Ray` is `repr(C)`, 64 bytes: sixteen floats'
            // room.
            unsafe { _mm512_storeu_ps((&mut out[at as usize] as *mut Ray).cast::<f32>(), row) };
        }
    }
    /// In two halves of eight f64 lanes.
    #[inline(always)]
    fn plane_distances(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3]) -> (Self, u32) {
        let isa = o[0].isa();
        // SAFETY: the lanes prove AVX-512F.
        unsafe {
            let half = |v: &Avx512, h: usize| {
                let q = if h == 0 {
                    _mm512_castps512_ps256(v.raw())
                } else {
                    _mm256_castpd_ps(_mm512_extractf64x4_pd::<1>(_mm512_castps_pd(v.raw())))
                };
                _mm512_cvtps_pd(q)
            };
            let dot = |x: __m512d, y: __m512d, z: __m512d| {
                let xy = _mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(n.x), x), _mm512_mul_pd(_mm512_set1_pd(n.y), y));
                _mm512_add_pd(xy, _mm512_mul_pd(_mm512_set1_pd(n.z), z))
            };
            let mut t = [_mm256_setzero_ps(); 2];
            let mut meets = 0;
            for (h, t) in t.iter_mut().enumerate() {
                let denom = dot(half(&d[0], h), half(&d[1], h), half(&d[2], h));
                let to = |k: usize, c: f64| _mm512_sub_pd(_mm512_set1_pd(c), half(&o[k], h));
                let num = dot(to(0, a.x), to(1, a.y), to(2, a.z));
                *t = _mm512_cvtpd_ps(_mm512_div_pd(num, denom));
                let nonzero = _mm512_cmp_pd_mask::<_CMP_NEQ_UQ>(denom, _mm512_setzero_pd());
                meets |= (nonzero as u32) << (8 * h);
            }
            let t = _mm512_castpd_ps(_mm512_insertf64x4::<1>(
                _mm512_castps_pd(_mm512_castps256_ps512(t[0])),
                _mm256_castps_pd(t[1]),
            ));
            (Avx512::from_raw(isa, t), meets)
        }
    }
}

/// Lane by lane: each field copied from its ray, each plane distance computed as
/// [`Triangle::finish`] computes it.
///
/// [`Triangle::finish`]: super::shapes::Triangle::finish
impl PacketLanes for Portable {
    type NodeTest8 = Plain;
    #[inline(always)]
    fn node_test8(isa: Plain) -> Plain {
        isa
    }
    #[inline(always)]
    fn rays(_: Plain, rays: &[Ray]) -> RayLanes<Self> {
        let last = rays.len() - 1;
        let field = |f: &dyn Fn(&Ray) -> f32| Portable(std::array::from_fn(|k| f(&rays[k.min(last)])));
        RayLanes {
            origin: [field(&|r| r.origin.x), field(&|r| r.origin.y), field(&|r| r.origin.z)],
            dir: [field(&|r| r.dir.x), field(&|r| r.dir.y), field(&|r| r.dir.z)],
            inv_dir: [field(&|r| r.inv_dir.x), field(&|r| r.inv_dir.y), field(&|r| r.inv_dir.z)],
            tmax: field(&|r| r.tmax),
        }
    }
    #[inline(always)]
    fn write_rays(lanes: &RayLanes<Self>, out: &mut [Ray], at: &[u32]) {
        // The fourth lane 0, as the vector types write it.
        let vector =
            |v: &[Portable; 3], k: usize| Vec3A::from_vec4(glam::Vec4::new(v[0].0[k], v[1].0[k], v[2].0[k], 0.0));
        for (k, &at) in at[..8].iter().enumerate() {
            out[at as usize] = Ray {
                origin: vector(&lanes.origin, k),
                dir: vector(&lanes.dir, k),
                inv_dir: vector(&lanes.inv_dir, k),
                tmax: lanes.tmax.0[k],
            };
        }
    }
    #[inline(always)]
    fn plane_distances(n: DVec3, a: DVec3, o: &[Self; 3], d: &[Self; 3]) -> (Self, u32) {
        let dot = |x: f64, y: f64, z: f64| n.x * x + n.y * y + n.z * z;
        let (mut t, mut meets) = ([0.0; 8], 0);
        for (k, t) in t.iter_mut().enumerate() {
            let lane = |v: &[Self; 3], i: usize| f64::from(v[i].0[k]);
            let denom = dot(lane(d, 0), lane(d, 1), lane(d, 2));
            let num = dot(a.x - lane(o, 0), a.y - lane(o, 1), a.z - lane(o, 2));
            *t = (num / denom) as f32;
            meets |= u32::from(denom != 0.0) << k;
        }
        (Portable(t), meets)
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3A;

    use super::*;
    use crate::random::SplitMix64;
    use crate::simd::both_widths;

    /// Every field of every ray lands in its own lane, bit for bit (as [`Lanes::lane`] reads
    /// it), for packets of one ray up to a full one, lanes past the last ray repeating it;
    /// written back, each ray is itself again; lanes added to elements give each element its
    /// own lane.
    #[test]
    fn rays_are_transposed_into_their_lanes() {
        rays_into_lanes::<Portable>(Plain);
        both_widths(rays_into_lanes::<Avx>, rays_into_lanes::<Avx512>);
    }

    /// Lanes split into four disjoint groups at random get consecutive places group by group,
    /// in lane order within a group, and lanes in none get the given index.
    #[test]
    fn grouped_lanes_get_their_places_in_order() {
        places_in_order::<Portable>(Plain);
        both_widths(places_in_order::<Avx>, places_in_order::<Avx512>);
    }

    /// The portable lanes gather, write back and plane-test rays with the vector lanes' bits,
    /// rays with zero, infinite and NaN components and planes parallel to them included.
    #[test]
    fn portable_packets_give_the_vector_lanes_bits() {
        both_widths(same_packets_as::<Avx>, same_packets_as::<Avx512>);
    }

    /// Every lane's plane distance is the scalar one (`TrianglePlane::distance`) bit for bit (a
    /// NaN is a NaN), and the lanes said to meet the plane are those where it has one, in every
    /// lane type: rays with zero, infinite and NaN components and planes parallel to them
    /// included.
    #[test]
    fn plane_distances_are_the_scalar_distances() {
        distances_as_scalar::<Portable>(Plain);
        both_widths(distances_as_scalar::<Avx>, distances_as_scalar::<Avx512>);
    }

    /// [`plane_distances_are_the_scalar_distances`] for `L`.
    fn distances_as_scalar<L: PacketLanes>(isa: L::Isa) {
        use crate::geometry::shapes::TrianglePlane;
        let (mut rng, mut shape) = (SplitMix64::new(29), SplitMix64::new(31));
        let special = [0.0, -0.0, 1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let mut x = || {
            let r = rng.next_f32();
            if r < 0.15 { special[(r * 40.0) as usize % 6] } else { (r - 0.5) * 8.0 }
        };
        let (mut met, mut parallel) = (0, 0);
        for p in 0..1_000 {
            let rays: Vec<Ray> = (0..L::WIDTH)
                .map(|_| Ray::new(Vec3A::new(x(), x(), x()), Vec3A::new(x(), x(), x()), x().abs()))
                .collect();
            // A triangle's plane (its normal rounded in f64), now and then one that every ray
            // with no z component runs along.
            let mut vertex =
                || Vec3A::new(shape.next_f32() * 4.0 - 2.0, shape.next_f32() * 4.0 - 2.0, shape.next_f32());
            let tri = crate::geometry::shapes::Triangle::new(vertex(), vertex(), vertex()).expect("a random triangle");
            let TrianglePlane { a, n } = tri.plane();
            let n = if p % 7 == 0 { glam::DVec3::Z } else { n };
            let lanes = L::rays(isa, &rays);
            let (t, meets) = L::plane_distances(n, a, &lanes.origin, &lanes.dir);
            let mut got = [0.0; 16];
            t.store(&mut got);
            for (k, ray) in rays.iter().enumerate() {
                let want = TrianglePlane { a, n }.distance(ray);
                assert_eq!(meets & (1 << k) != 0, want.is_some(), "packet {p}, lane {k}: meets the plane");
                if let Some(want) = want {
                    // A NaN is no hit whatever its sign bit.
                    let same = got[k].to_bits() == want.to_bits() || (got[k].is_nan() && want.is_nan());
                    assert!(same, "packet {p}, lane {k}: distance {} against {want}", got[k]);
                    met += 1;
                } else {
                    parallel += 1;
                }
            }
        }
        assert!(met > 1_000 && parallel > 10, "{met} distances, {parallel} parallel lanes");
    }

    /// [`portable_packets_give_the_vector_lanes_bits`] for `L` (eight or sixteen lanes).
    fn same_packets_as<L: PacketLanes>(isa: L::Isa) {
        use glam::DVec3;
        let mut rng = SplitMix64::new(17);
        let special = [0.0, -0.0, 1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN];
        let mut x = || {
            let r = rng.next_f32();
            if r < 0.15 { special[(r * 40.0) as usize % 6] } else { (r - 0.5) * 8.0 }
        };
        let mut hits = 0;
        for p in 0..1_000 {
            let rays: Vec<Ray> = (0..L::WIDTH)
                .map(|_| Ray::new(Vec3A::new(x(), x(), x()), Vec3A::new(x(), x(), x()), x().abs()))
                .collect();
            // The plane's normal along the rays' first direction now and then (no hit).
            let n = if p % 7 == 0 { DVec3::new(0.0, 0.0, 1.0) } else { DVec3::new(x().into(), x().into(), 1.5) };
            let a = DVec3::new(x().into(), 0.5, -0.25);
            let (v, q) = (L::rays(isa, &rays), Portable::rays(Plain, &rays[..8]));
            let mut back = vec![Ray::new(Vec3A::ZERO, Vec3A::X, 0.0); 8];
            Portable::write_rays(&q, &mut back, &[7, 6, 5, 4, 3, 2, 1, 0]);
            let want = L::plane_hits(n, a, &v.origin, &v.dir, v.tmax) & 0xff;
            let got = Portable::plane_hits(n, a, &q.origin, &q.dir, q.tmax);
            assert_eq!(got, want, "packet {p}: plane hits");
            hits += got.count_ones();
            let bits = |v: Vec3A| glam::Vec4::from(__m128::from(v)).to_array().map(f32::to_bits);
            for (k, ray) in rays[..8].iter().enumerate() {
                let b = &back[7 - k];
                let zero_w = |v: Vec3A| {
                    let mut w = bits(v);
                    w[3] = 0;
                    w
                };
                assert_eq!(bits(b.origin), zero_w(ray.origin), "packet {p}: origin {k} written back");
                assert_eq!(bits(b.dir), zero_w(ray.dir), "packet {p}: dir {k} written back");
                assert_eq!(bits(b.inv_dir), zero_w(ray.inv_dir), "packet {p}: inv_dir {k} written back");
                assert_eq!(b.tmax.to_bits(), ray.tmax.to_bits(), "packet {p}: tmax {k} written back");
            }
        }
        assert!(hits > 500 && hits < 7_000, "{hits} plane hits in 8000 lanes");
    }

    /// The segments' box holds, in exact arithmetic, every live lane's origin and every point
    /// `o + t·d` of its segment that lies in the bounds, for t up to `tmax·(1 + 2⁻²⁰)` (more
    /// than a triangle test's hit distance can be rounded down by), near the origin and
    /// 3·10⁴ from it; no dead lane's; and it is `None` only where a live segment is unbounded
    /// and so are the bounds.
    #[test]
    fn the_segments_box_holds_every_live_segment() {
        segments_in_the_box::<Portable>(Plain);
        both_widths(segments_in_the_box::<Avx>, segments_in_the_box::<Avx512>);
    }

    /// [`the_segments_box_holds_every_live_segment`] for `L`.
    fn segments_in_the_box<L: PacketLanes>(isa: L::Isa) {
        use glam::DVec3;
        let mut rng = SplitMix64::new(9);
        let (mut cut, mut whole) = (0, 0);
        for p in 0..3_000 {
            let offset = if p % 2 == 0 { Vec3A::ZERO } else { Vec3A::new(3.0e4, -1.0e4, 5.0) };
            let bounds = if p % 13 == 0 {
                obvhs::aabb::Aabb::new(Vec3A::NEG_INFINITY, Vec3A::INFINITY)
            } else {
                obvhs::aabb::Aabb::new(offset - Vec3A::new(3.0, 1.0, 2.0), offset + Vec3A::new(2.0, 3.0, 1.0))
            };
            let mut v = || Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
            // Most packets leave from inside the bounds, some from outside.
            let origin = offset + if p % 11 == 0 { Vec3A::new(5.0, 0.0, 0.0) } else { v() * 0.5 };
            let live = if p % 5 == 0 { 0b1010_0110_1101_0011 & ((1 << L::WIDTH) - 1) } else { (1 << L::WIDTH) - 1 };
            let rays: Vec<Ray> = (0..L::WIDTH)
                .map(|k| {
                    let unbounded = p % 3 == 0 || (p % 7 == 3 && k == 5);
                    let tmax = if unbounded { f32::INFINITY } else { 1e-3 + v().x.abs() * 2.0 };
                    // Dead lanes far off: the box must not reach them.
                    let away = if live & (1 << k) == 0 { Vec3A::splat(100.0) } else { Vec3A::ZERO };
                    let mut dir = v();
                    if k == 2 {
                        dir.y = 0.0;
                    }
                    Ray::new(origin + away + v() * 1e-4, dir.normalize_or(Vec3A::X), tmax)
                })
                .collect();
            let found = L::rays(isa, &rays).segments_box(live, &bounds);
            let live_rays: Vec<&Ray> =
                rays.iter().enumerate().filter(|(k, _)| live & (1 << k) != 0).map(|(_, r)| r).collect();
            let unbounded = live_rays.iter().any(|r| r.tmax.is_infinite());
            if unbounded && !bounds.min.is_finite() {
                assert!(found.is_none(), "packet {p}: unbounded segments and bounds, yet a box");
                continue;
            }
            let (lo, hi) = found.unwrap_or_else(|| panic!("packet {p}: no box"));
            let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
            let inside = |x: DVec3| x.cmpge(lo).all() && x.cmple(hi).all();
            let (b0, b1) = (bounds.min.as_dvec3(), bounds.max.as_dvec3());
            for r in &live_rays {
                let (o, d) = (r.origin.as_dvec3(), r.dir.as_dvec3());
                assert!(inside(o), "packet {p}: origin {o} outside {lo}..{hi}");
                // Where the line leaves the bounds, exactly.
                let exit = (0..3)
                    .filter(|&a| d[a] != 0.0)
                    .map(|a| ((b0[a] - o[a]) / d[a]).max((b1[a] - o[a]) / d[a]))
                    .fold(f64::INFINITY, f64::min);
                let end = f64::from(r.tmax).min(exit).max(0.0);
                for t in [0.25, 0.5, 1.0, 1.0 + 2f64.powi(-20)].map(|f| f * end).into_iter().chain([f64::from(r.tmax)])
                {
                    let x = o + d * t;
                    if t.is_finite() && x.cmpge(b0).all() && x.cmple(b1).all() {
                        assert!(inside(x), "packet {p}: {x} at t = {t} outside {lo}..{hi}");
                    }
                }
            }
            // The box fits the live segments, cut by the bounds (its padding is 0.12 at 3·10⁴).
            if unbounded {
                let (o, grown) = (origin.as_dvec3(), DVec3::splat(0.25));
                let fits = lo.cmpge(b0.min(o) - grown).all() && hi.cmple(b1.max(o) + grown).all();
                assert!(fits, "packet {p}: {lo}..{hi} reaches past the bounds");
                cut += 1;
            } else {
                let reach = live_rays.iter().map(|r| r.tmax).fold(0.0, f32::max) as f64 + 0.01;
                assert!((hi - lo).max_element() < 2.0 * reach + 0.25, "packet {p}: {lo}..{hi} is loose");
                whole += 1;
            }
        }
        assert!(cut > 800 && whole > 1_500, "{cut} cut and {whole} whole packets");
    }

    /// [`grouped_lanes_get_their_places_in_order`] for `L`.
    fn places_in_order<L: Lanes>(isa: L::Isa) {
        let mut rng = SplitMix64::new(8);
        for _ in 0..200 {
            // Lane k in group g[k] (4: none).
            let g: Vec<usize> = (0..L::WIDTH).map(|_| (rng.next_f32() * 5.0) as usize).collect();
            let mut groups = [0u32; 4];
            for (k, &g) in g.iter().enumerate() {
                if g < 4 {
                    groups[g] |= 1 << k;
                }
            }
            let start = [3, 40, 41, 90].map(|s| s + (rng.next_f32() * 4.0) as u32);
            let at = L::places(isa, &groups, &start, 999);
            let mut next = start;
            for (k, &g) in g.iter().enumerate() {
                let want = if g < 4 {
                    next[g] += 1;
                    next[g] - 1
                } else {
                    999
                };
                assert_eq!(at[k], want, "{} lanes, lane {k} in group {g}", L::WIDTH);
            }
        }
    }

    /// [`rays_are_transposed_into_their_lanes`] for `L`.
    fn rays_into_lanes<L: PacketLanes>(isa: L::Isa) {
        let mut rng = SplitMix64::new(7);
        let mut v = || Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0 - 4.0;
        for n in 1..=L::WIDTH {
            let rays: Vec<Ray> = (0..n).map(|k| Ray::new(v(), v(), k as f32 + 0.5)).collect();
            let lanes = L::rays(isa, &rays);
            for a in 0..3 {
                let fields = [(lanes.origin[a], "origin"), (lanes.dir[a], "dir"), (lanes.inv_dir[a], "inv_dir")];
                for (got, name) in fields {
                    for (k, x) in (0..L::WIDTH).map(|k| (k, got.lane(k))) {
                        let ray = &rays[k.min(n - 1)];
                        let want = match name {
                            "origin" => ray.origin[a],
                            "dir" => ray.dir[a],
                            _ => ray.inv_dir[a],
                        };
                        assert_eq!(x.to_bits(), want.to_bits(), "{n} rays: {name}[{a}] of lane {k}");
                    }
                }
            }
            for (k, t) in (0..L::WIDTH).map(|k| (k, lanes.tmax.lane(k))) {
                assert_eq!(t, rays[k.min(n - 1)].tmax, "{n} rays: tmax of lane {k}");
            }
            // And back: lane k to out[at[k]], in reverse order, the lanes past n all to one.
            let at: Vec<u32> = (0..L::WIDTH).map(|k| if k < n { (n - 1 - k) as u32 } else { n as u32 }).collect();
            let mut out = vec![Ray::new(Vec3A::ZERO, Vec3A::X, 0.0); n + 1];
            L::write_rays(&lanes, &mut out, &at);
            for (k, ray) in rays.iter().enumerate() {
                let back = &out[n - 1 - k];
                let same = |a: Vec3A, b: Vec3A| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits);
                assert!(same(back.origin, ray.origin) && same(back.dir, ray.dir), "{n} rays: ray {k} written back");
                assert!(same(back.inv_dir, ray.inv_dir) && back.tmax == ray.tmax, "{n} rays: ray {k} written back");
            }
        }
        // Lanes added to whole vectors of elements: each gets its lane, the fourth its z.
        let sums: Vec<Vec3A> = (0..L::WIDTH).map(|_| v()).collect();
        let rays: Vec<Ray> = (0..L::WIDTH).map(|_| Ray::new(v(), v(), 1.0)).collect();
        let [x, y, z] = L::rays(isa, &rays).origin;
        let mut out = sums.clone();
        L::add_to(x, y, z, &mut out);
        for (k, (out, sum)) in out.iter().zip(&sums).enumerate() {
            let o = rays[k].origin;
            // All four lanes, the fourth included.
            let lanes = |v: Vec3A| glam::Vec4::from(__m128::from(v));
            let want = lanes(*sum) + glam::Vec4::new(o.x, o.y, o.z, o.z);
            assert_eq!(lanes(*out).to_array().map(f32::to_bits), want.to_array().map(f32::to_bits), "lane {k}");
        }
    }
}
