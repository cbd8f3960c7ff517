//! Triangles in packets of four, stored as structure-of-arrays, whose watertight edge tests
//! (Woop, Benthin, Wald 2013) run for all four lanes at once. The lane arithmetic is the
//! scalar [`Triangle::intersect`]'s, operation for operation, so every lane's edge functions
//! are bit-identical to it; lanes where one is zero or NaN go through the scalar test (with
//! its f64 edge fallback), and only lanes that pass the sign test get their determinant and
//! their f64 plane distance computed, by the scalar [`Triangle::finish`].

use glam::{Vec3A, Vec4};

use super::{
    counters::{Event, count},
    ray::{Ray, Shear},
    shapes::Triangle,
};
#[cfg(target_arch = "x86_64")]
use crate::{
    geometry::{
        lanes::{PacketLanes, RayLanes},
        shapes::TrianglePlane,
    },
    simd::Lanes,
};

/// Four triangles (fewer in a leaf's last packet: unused lanes have slot `u32::MAX`). Aligned
/// to 32 bytes, so that in an array each 160-byte packet starts on or halfway into a 64-byte
/// cache line and spans three lines (16-byte alignment let half of them straddle four, whose
/// last, with the slots, a prefetch of 160 bytes from the packet's start does not reach).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
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
pub struct Edges {
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

    /// The vertices of the triangle in `lane`, exactly as packed: vertex by vertex, x, y, z.
    #[inline(always)]
    pub fn vertices(&self, lane: usize) -> [f32; 9] {
        std::array::from_fn(|i| self.p[i / 3][i % 3][lane])
    }

    /// Edge tests of the four lanes (unused lanes come back in `exact`; skip them by slot).
    #[inline(always)]
    pub fn edges(&self, r: &RayTri4) -> Edges {
        count(Event::TrianglePacketTest);
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
        Edges { pass: (pos | neg).bitmask() & !exact, exact, e: [e0.to_array(), e1.to_array(), e2.to_array()] }
    }
}

/// A packet of rays' constants for the edge tests, one ray per lane: origin, shear, and which
/// axis each ray's shear runs along.
#[cfg(target_arch = "x86_64")]
pub(crate) struct RayTriPacket<L: Lanes> {
    origin: [L; 3],
    dir: [L; 3],
    tmax: L,
    sx: L,
    sy: L,
    axes: Axes<L>,
}

#[cfg(target_arch = "x86_64")]
impl<L: Lanes> RayTriPacket<L> {
    /// The edge-test constants of a packet's rays. Each lane's axes and shear are
    /// [`Shear::new`]'s for its ray, bit for bit.
    #[inline(always)]
    pub(crate) fn new(rays: &RayLanes<L>) -> Self {
        let d = rays.dir;
        let abs = [d[0].abs(), d[1].abs(), d[2].abs()];
        let x_over_y = abs[0].gt(abs[1]);
        let x_wins = L::and(x_over_y, abs[0].gt(abs[2]));
        let y_wins = L::andnot(x_over_y, abs[1].gt(abs[2]));
        let axes = Axes { x_wins, y_wins };
        let [dx, dy, dz] = axes.permute(d);
        RayTriPacket { origin: rays.origin, dir: d, tmax: rays.tmax, sx: dx.neg().div(dz), sy: dy.neg().div(dz), axes }
    }
}

#[cfg(target_arch = "x86_64")]
impl<L: PacketLanes> RayTriPacket<L> {
    /// The lanes whose ray meets `tri`'s plane in (0, tmax): for lanes whose edge functions
    /// passed, exactly the lanes where [`Triangle::finish`] finds a hit (their determinant, a
    /// sum of three non-zero values of one sign, is never zero).
    #[inline(always)]
    pub(crate) fn plane_hits(&self, tri: &Triangle) -> u32 {
        let plane = tri.plane();
        L::plane_hits(plane.n, plane.a, &self.origin, &self.dir, self.tmax)
    }

    /// Where each lane's ray meets `plane`, and the lanes where it meets it at all
    /// ([`PacketLanes::plane_distances`]).
    #[inline(always)]
    pub(crate) fn plane_distances(&self, plane: &TrianglePlane) -> (L, u32) {
        L::plane_distances(plane.n, plane.a, &self.origin, &self.dir)
    }
}

/// Each lane's axis order (kx, ky, kz) as [`Shear::new`] picks it.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
struct Axes<L: Lanes> {
    /// Lanes whose kz is x.
    x_wins: L::Mask,
    /// Lanes whose kz is y (kz is z in the others).
    y_wins: L::Mask,
}

#[cfg(target_arch = "x86_64")]
impl<L: Lanes> Axes<L> {
    /// Lanes of `v` (x, y, z) in each lane's (kx, ky, kz) order: (y, z, x) where kz is x,
    /// (z, x, y) where it is y, (x, y, z) elsewhere.
    #[inline(always)]
    fn permute(&self, v: [L; 3]) -> [L; 3] {
        [self.pick(&v, 1, 2, 0), self.pick(&v, 2, 0, 1), self.pick(&v, 0, 1, 2)]
    }

    /// `v[if_x]` where kz is x, `v[if_y]` where it is y, `v[otherwise]` elsewhere.
    #[inline(always)]
    fn pick(&self, v: &[L; 3], if_x: usize, if_y: usize, otherwise: usize) -> L {
        v[otherwise].select(self.y_wins, v[if_y]).select(self.x_wins, v[if_x])
    }
}

/// A triangle's edge tests against a packet of rays.
#[cfg(target_arch = "x86_64")]
pub(crate) struct PacketEdges {
    /// Rays whose edge functions are all non-zero and of one sign: then the plane decides
    /// ([`RayTriPacket::plane_hits`]).
    pub pass: u32,
    /// Rays with a zero or NaN edge function: call the scalar [`Triangle::intersect`].
    pub exact: u32,
}

#[cfg(target_arch = "x86_64")]
impl Tri4 {
    /// The edge tests of triangle `lane` against every ray of `r`: per ray, the operations of
    /// [`Tri4::edges`] in the same order, so each ray's edge functions, and so its class, are
    /// bit-identical to it.
    #[inline(always)]
    pub(crate) fn edges_packet<L: Lanes>(&self, lane: usize, r: &RayTriPacket<L>) -> PacketEdges {
        self.edge_lanes(lane, r).1
    }

    /// [`Tri4::edges_packet`], with each ray's edge functions (e0, e1, e2) written to `e`
    /// (lane k of each at index k): for rays that pass, the values [`Triangle::intersect`]
    /// hands to [`Triangle::finish`].
    #[inline(always)]
    pub(crate) fn edges_packet_with<L: Lanes>(
        &self,
        lane: usize,
        r: &RayTriPacket<L>,
        e: &mut [[f32; 16]; 3],
    ) -> PacketEdges {
        let (lanes, edges) = self.edge_lanes(lane, r);
        for (lanes, out) in lanes.into_iter().zip(e) {
            lanes.store(&mut out[..]);
        }
        edges
    }

    /// The edge functions of triangle `lane` against every ray of `r`, and their classes.
    #[inline(always)]
    fn edge_lanes<L: Lanes>(&self, lane: usize, r: &RayTriPacket<L>) -> ([L; 3], PacketEdges) {
        count(Event::PacketTriangleTest);
        let (v0, v1, v2) = (self.sheared(0, lane, r), self.sheared(1, lane, r), self.sheared(2, lane, r));
        let cross = cross_2d::<L>;
        let e = [cross(v1, v2), cross(v2, v0), cross(v0, v1)];
        let zero = L::splat(r.sx.isa(), 0.0);
        // Zero or NaN, then all of one sign.
        let exact = L::or(L::or(e[0].eq_or_nan(zero), e[1].eq_or_nan(zero)), e[2].eq_or_nan(zero));
        let pos = L::and(L::and(e[0].gt(zero), e[1].gt(zero)), e[2].gt(zero));
        let neg = L::and(L::and(e[0].lt(zero), e[1].lt(zero)), e[2].lt(zero));
        let exact = L::bits(exact);
        (e, PacketEdges { pass: L::bits(L::or(pos, neg)) & !exact, exact })
    }

    /// Vertex `v` of triangle `lane` in each ray's frame: translated to its origin, permuted so
    /// that the ray runs along +z, sheared; (x, y).
    #[inline(always)]
    fn sheared<L: Lanes>(&self, v: usize, lane: usize, r: &RayTriPacket<L>) -> (L, L) {
        let (p, isa) = (&self.p[v], r.sx.isa());
        let q = [
            L::splat(isa, p[0].as_ref()[lane]).sub(r.origin[0]),
            L::splat(isa, p[1].as_ref()[lane]).sub(r.origin[1]),
            L::splat(isa, p[2].as_ref()[lane]).sub(r.origin[2]),
        ];
        let [x, y, z] = r.axes.permute(q);
        (x.add(r.sx.mul(z)), y.add(r.sy.mul(z)))
    }
}

/// `a.x·b.y − a.y·b.x` per lane.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn cross_2d<L: Lanes>(a: (L, L), b: (L, L)) -> L {
    a.0.mul(b.1).sub(a.1.mul(b.0))
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    /// The packet edge test gives each ray exactly the single-ray test's lane classes, and the
    /// packet plane test exactly `finish`'s answer, for rays along every axis order, rays
    /// through vertices and edges, rays parallel to an axis, and segments of every length.
    #[test]
    fn packet_edges_are_the_single_ray_edges_bit_for_bit() {
        use crate::simd::{Avx, Avx512, both_widths};
        packet_edges_are_single_ray_edges::<crate::simd::Portable>(crate::simd::Plain);
        both_widths(packet_edges_are_single_ray_edges::<Avx>, packet_edges_are_single_ray_edges::<Avx512>);
    }

    /// [`packet_edges_are_the_single_ray_edges_bit_for_bit`] for packets of `L::WIDTH` rays.
    fn packet_edges_are_single_ray_edges<L: PacketLanes>(isa: L::Isa) {
        let mut rng = SplitMix64::new(23);
        let mut v = |s: f32| Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * s - s * 0.5;
        let tris: Vec<(u32, Triangle)> = (0..4)
            .map(|k| (k, Triangle { p: [v(4.0), v(4.0), v(4.0)] }))
            .chain([(4, Triangle { p: [Vec3A::ZERO, Vec3A::X, Vec3A::Z] })])
            .collect();
        let packets = [Tri4::pack(tris[..4].iter().copied()), Tri4::pack(tris[4..].iter().copied())];
        let (mut passed, mut exact, mut hits) = (0, 0, 0);
        for p in 0..400 {
            let origin = if p % 4 == 0 { Vec3A::new(0.0, 1.0, 0.0) } else { v(6.0) };
            let rays: Vec<Ray> = (0..L::WIDTH)
                .map(|i| {
                    let target = match (p + i) % 4 {
                        // A vertex or an edge midpoint of the last triangle: zero edge functions.
                        0 => Vec3A::X,
                        1 => Vec3A::new(0.5, 0.0, 0.5),
                        _ => v(3.0),
                    };
                    let mut dir = target - origin;
                    if i == L::WIDTH - 1 {
                        dir[p % 3] = 0.0;
                    }
                    // Segments of every length: the plane test's t < tmax decides some lanes.
                    let tmax = if (p + i) % 3 == 0 { f32::INFINITY } else { v(8.0).x + 4.0 };
                    Ray::new(origin, dir.normalize_or(Vec3A::Y), tmax)
                })
                .collect();
            let r = RayTriPacket::<L>::new(&L::rays(isa, &rays));
            for packet in &packets {
                for lane in 0..4 {
                    let lanes = packet.edges_packet(lane, &r);
                    let planes = r.plane_hits(&packet.triangle(lane));
                    for (k, ray) in rays.iter().enumerate() {
                        let one = packet.edges(&RayTri4::new(ray));
                        let bit = |mask: u32, i: usize| (mask >> i) & 1;
                        let at = format!("{} lanes, packet {p}, ray {k}, lane {lane}", L::WIDTH);
                        assert_eq!(bit(lanes.exact, k), bit(one.exact, lane), "{at}");
                        if one.exact & (1 << lane) == 0 {
                            assert_eq!(bit(lanes.pass, k), bit(one.pass, lane), "{at}");
                        }
                        // Where the edges pass, the plane test decides exactly as `finish` does.
                        if lanes.pass & (1 << k) != 0 {
                            let tri = packet.triangle(lane);
                            let found = tri.finish(ray, one.e[0][lane], one.e[1][lane], one.e[2][lane]).is_some();
                            assert_eq!(bit(planes, k), u32::from(found), "{at}: plane");
                            hits += u32::from(found);
                        }
                        passed += bit(lanes.pass, k);
                        exact += bit(lanes.exact, k) * u32::from(packet.slot[lane] != u32::MAX);
                    }
                }
            }
        }
        assert!(
            passed > 500 && exact > 100 && hits > 100 && hits < passed,
            "{passed} passed, {exact} exact, {hits} hit"
        );
    }

    /// A packet leaving a triangle (every ray's line crosses it just behind the ray, as a
    /// packet of shadow rays crosses the triangle it leaves) gets no plane hit, as `finish`
    /// finds none; with one ray turned back towards the triangle, that ray alone is hit.
    #[test]
    fn a_packet_leaving_a_triangle_gets_exactly_finish_s_plane_hits() {
        use crate::simd::{Avx, Avx512, both_widths};
        packet_leaving_a_triangle::<crate::simd::Portable>(crate::simd::Plain);
        both_widths(packet_leaving_a_triangle::<Avx>, packet_leaving_a_triangle::<Avx512>);
    }

    #[test]
    fn every_packet_of_an_array_spans_three_cache_lines() {
        assert_eq!(size_of::<Tri4>(), 160);
        let lines = |start: usize| (start + size_of::<Tri4>() - 1) / 64 - start / 64 + 1;
        // Wherever its alignment lets an array start within a line.
        for base in (0..64).step_by(align_of::<Tri4>()) {
            for k in 0..4 {
                assert_eq!(lines(base + k * size_of::<Tri4>()), 3, "array at {base} mod 64, packet {k}");
            }
        }
        let tri = Triangle { p: [Vec3A::ZERO, Vec3A::X, Vec3A::Y] };
        let packets: Vec<Tri4> = (0..8).map(|_| Tri4::pack([(0, tri)].into_iter())).collect();
        assert!(packets.iter().all(|p| lines(p as *const Tri4 as usize) == 3));
    }

    /// [`a_packet_leaving_a_triangle_gets_exactly_finish_s_plane_hits`] for `L::WIDTH` rays.
    fn packet_leaving_a_triangle<L: PacketLanes>(isa: L::Isa) {
        let tri = Triangle { p: [Vec3A::new(-1.0, 0.0, -1.0), Vec3A::new(2.0, 0.0, -1.0), Vec3A::new(-1.0, 0.0, 2.0)] };
        let packet = Tri4::pack([(0, tri)].into_iter());
        let origin = Vec3A::new(0.1, 1e-3, 0.1);
        for back in [None, Some(3)] {
            let rays: Vec<Ray> = (0..L::WIDTH)
                .map(|i| {
                    let tilt = i as f32 / L::WIDTH as f32 - 0.5;
                    let up = if back == Some(i) { -1.0 } else { 1.0 };
                    Ray::new(origin, Vec3A::new(tilt, up, 0.3 * tilt).normalize(), f32::INFINITY)
                })
                .collect();
            let (edges, planes) = {
                let r = RayTriPacket::<L>::new(&L::rays(isa, &rays));
                let edges = packet.edges_packet(0, &r);
                (edges.pass, r.plane_hits(&tri) & edges.pass)
            };
            assert_eq!(edges, (1u32 << L::WIDTH) - 1, "{} lanes: every line crosses the triangle", L::WIDTH);
            let found: u32 = rays
                .iter()
                .enumerate()
                .map(|(k, ray)| {
                    let one = packet.edges(&RayTri4::new(ray));
                    u32::from(tri.finish(ray, one.e[0][0], one.e[1][0], one.e[2][0]).is_some()) << k
                })
                .sum();
            assert_eq!(planes, found, "{} lanes, ray {back:?} turned back", L::WIDTH);
            assert_eq!(found, back.map_or(0, |k| 1 << k), "{} lanes: finish", L::WIDTH);
        }
    }
}
