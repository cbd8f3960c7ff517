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

/// A packet of up to eight rays' constants for the edge tests, one ray per AVX lane: origin,
/// shear, and which axis each ray's shear runs along.
#[cfg(target_arch = "x86_64")]
pub struct RayTriPacket {
    origin: [std::arch::x86_64::__m256; 3],
    sx: std::arch::x86_64::__m256,
    sy: std::arch::x86_64::__m256,
    /// All ones in lanes whose kz is x (resp. y, where it is not x); kz is z in the others.
    x_wins: std::arch::x86_64::__m256,
    y_wins: std::arch::x86_64::__m256,
}

#[cfg(target_arch = "x86_64")]
impl RayTriPacket {
    /// The constants of `rays` (one to eight) in lanes 0, 1, …; lanes past the last repeat it.
    /// Each lane's axes and shear are [`Shear::new`]'s for its ray, bit for bit.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    pub fn new(rays: &[Ray]) -> Self {
        use std::arch::x86_64::*;
        let mut columns = [[0.0f32; 8]; 6];
        for k in 0..8 {
            let r = &rays[k.min(rays.len() - 1)];
            let (o, d) = (r.origin.to_array(), r.dir.to_array());
            for a in 0..3 {
                columns[a][k] = o[a];
                columns[3 + a][k] = d[a];
            }
        }
        // SAFETY: each column holds eight f32.
        let load = |c: &[f32; 8]| unsafe { _mm256_loadu_ps(c.as_ptr()) };
        let d = [load(&columns[3]), load(&columns[4]), load(&columns[5])];
        let sign = _mm256_set1_ps(-0.0);
        let abs = [_mm256_andnot_ps(sign, d[0]), _mm256_andnot_ps(sign, d[1]), _mm256_andnot_ps(sign, d[2])];
        let x_over_y = _mm256_cmp_ps::<_CMP_GT_OQ>(abs[0], abs[1]);
        let x_wins = _mm256_and_ps(x_over_y, _mm256_cmp_ps::<_CMP_GT_OQ>(abs[0], abs[2]));
        let y_wins = _mm256_andnot_ps(x_over_y, _mm256_cmp_ps::<_CMP_GT_OQ>(abs[1], abs[2]));
        let [dx, dy, dz] = Axes { x_wins, y_wins }.permute(d);
        RayTriPacket {
            origin: [load(&columns[0]), load(&columns[1]), load(&columns[2])],
            sx: _mm256_div_ps(_mm256_xor_ps(dx, sign), dz),
            sy: _mm256_div_ps(_mm256_xor_ps(dy, sign), dz),
            x_wins,
            y_wins,
        }
    }
}

/// Each lane's axis order (kx, ky, kz) as [`Shear::new`] picks it.
#[cfg(target_arch = "x86_64")]
struct Axes {
    x_wins: std::arch::x86_64::__m256,
    y_wins: std::arch::x86_64::__m256,
}

#[cfg(target_arch = "x86_64")]
impl Axes {
    /// Lanes of `v` (x, y, z) in each lane's (kx, ky, kz) order: (y, z, x) where kz is x,
    /// (z, x, y) where it is y, (x, y, z) elsewhere.
    #[target_feature(enable = "avx")]
    #[inline]
    fn permute(&self, v: [std::arch::x86_64::__m256; 3]) -> [std::arch::x86_64::__m256; 3] {
        use std::arch::x86_64::*;
        let pick = |if_x: usize, if_y: usize, otherwise: usize| {
            _mm256_blendv_ps(_mm256_blendv_ps(v[otherwise], v[if_y], self.y_wins), v[if_x], self.x_wins)
        };
        [pick(1, 2, 0), pick(2, 0, 1), pick(0, 1, 2)]
    }
}

/// A triangle's edge tests against a packet of rays.
#[cfg(target_arch = "x86_64")]
pub struct PacketLanes {
    /// Rays whose edge functions are all non-zero and of one sign: call [`Triangle::finish`].
    pub pass: u32,
    /// Rays with a zero or NaN edge function: call the scalar [`Triangle::intersect`].
    pub exact: u32,
    /// The edge functions (e0, e1, e2) of each ray.
    pub e: [[f32; 8]; 3],
}

#[cfg(target_arch = "x86_64")]
impl Tri4 {
    /// The edge tests of triangle `lane` against every ray of `r`: per ray, the operations of
    /// [`Tri4::edges`] in the same order, so each ray's edge functions are bit-identical to it.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[target_feature(enable = "avx")]
    pub fn edges_packet(&self, lane: usize, r: &RayTriPacket) -> PacketLanes {
        use std::arch::x86_64::*;
        let axes = Axes { x_wins: r.x_wins, y_wins: r.y_wins };
        // Translate to each ray's origin, permute so that ray runs along +z, shear.
        let f = |v: usize| {
            let p = &self.p[v];
            let q = [
                _mm256_sub_ps(_mm256_set1_ps(p[0].as_ref()[lane]), r.origin[0]),
                _mm256_sub_ps(_mm256_set1_ps(p[1].as_ref()[lane]), r.origin[1]),
                _mm256_sub_ps(_mm256_set1_ps(p[2].as_ref()[lane]), r.origin[2]),
            ];
            let [x, y, z] = axes.permute(q);
            (_mm256_add_ps(x, _mm256_mul_ps(r.sx, z)), _mm256_add_ps(y, _mm256_mul_ps(r.sy, z)))
        };
        let (v0, v1, v2) = (f(0), f(1), f(2));
        let cross =
            |a: (__m256, __m256), b: (__m256, __m256)| _mm256_sub_ps(_mm256_mul_ps(a.0, b.1), _mm256_mul_ps(a.1, b.0));
        let e = [cross(v1, v2), cross(v2, v0), cross(v0, v1)];
        let zero = _mm256_setzero_ps();
        let mut exact = zero;
        let (mut pos, mut neg) =
            (_mm256_castsi256_ps(_mm256_set1_epi32(-1)), _mm256_castsi256_ps(_mm256_set1_epi32(-1)));
        for &x in &e {
            // Zero or NaN.
            exact = _mm256_or_ps(exact, _mm256_cmp_ps::<_CMP_EQ_UQ>(x, zero));
            pos = _mm256_and_ps(pos, _mm256_cmp_ps::<_CMP_GT_OQ>(x, zero));
            neg = _mm256_and_ps(neg, _mm256_cmp_ps::<_CMP_LT_OQ>(x, zero));
        }
        let exact = _mm256_movemask_ps(exact) as u32;
        let pass = _mm256_movemask_ps(_mm256_or_ps(pos, neg)) as u32 & !exact;
        let mut out = [[0.0; 8]; 3];
        for k in 0..3 {
            // SAFETY: each row of `out` holds eight f32.
            unsafe { _mm256_storeu_ps(out[k].as_mut_ptr(), e[k]) };
        }
        PacketLanes { pass, exact, e: out }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::*;
    use crate::sampling::hash::SplitMix64;

    /// The packet edge test gives each ray exactly the single-ray test's edge functions and
    /// lane classes, for rays along every axis order, rays through vertices and edges, and
    /// rays parallel to an axis.
    #[test]
    fn packet_edges_are_the_single_ray_edges_bit_for_bit() {
        if !std::arch::is_x86_feature_detected!("avx") {
            eprintln!("no AVX on this CPU: packets are not used and not tested");
            return;
        }
        let mut rng = SplitMix64::new(23);
        let mut v = |s: f32| Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * s - s * 0.5;
        let tris: Vec<(u32, Triangle)> = (0..4)
            .map(|k| (k, Triangle { p: [v(4.0), v(4.0), v(4.0)] }))
            .chain([(4, Triangle { p: [Vec3A::ZERO, Vec3A::X, Vec3A::Z] })])
            .collect();
        let packets = [Tri4::pack(tris[..4].iter().copied()), Tri4::pack(tris[4..].iter().copied())];
        let (mut passed, mut exact) = (0, 0);
        for p in 0..400 {
            let origin = if p % 4 == 0 { Vec3A::new(0.0, 1.0, 0.0) } else { v(6.0) };
            let rays: Vec<Ray> = (0..8)
                .map(|i| {
                    let target = match (p + i) % 4 {
                        // A vertex or an edge midpoint of the last triangle: zero edge functions.
                        0 => Vec3A::X,
                        1 => Vec3A::new(0.5, 0.0, 0.5),
                        _ => v(3.0),
                    };
                    let mut dir = target - origin;
                    if i == 7 {
                        dir[p % 3] = 0.0;
                    }
                    Ray::new(origin, dir.normalize_or(Vec3A::Y), f32::INFINITY)
                })
                .collect();
            // SAFETY: AVX was detected above.
            let r = unsafe { RayTriPacket::new(&rays) };
            for packet in &packets {
                for lane in 0..4 {
                    // SAFETY: AVX was detected above.
                    let lanes = unsafe { packet.edges_packet(lane, &r) };
                    for (k, ray) in rays.iter().enumerate() {
                        let one = packet.edges(&RayTri4::new(ray));
                        let bit = |mask: u32, i: usize| (mask >> i) & 1;
                        assert_eq!(bit(lanes.exact, k), bit(one.exact, lane), "packet {p}, ray {k}, lane {lane}");
                        if one.exact & (1 << lane) == 0 {
                            assert_eq!(bit(lanes.pass, k), bit(one.pass, lane), "packet {p}, ray {k}, lane {lane}");
                            for e in 0..3 {
                                assert_eq!(lanes.e[e][k].to_bits(), one.e[e][lane].to_bits(), "packet {p}, ray {k}");
                            }
                        }
                        passed += bit(lanes.pass, k);
                        exact += bit(lanes.exact, k) * u32::from(packet.slot[lane] != u32::MAX);
                    }
                }
            }
        }
        assert!(passed > 500 && exact > 100, "{passed} passed, {exact} exact");
    }
}
