//! Surface hits with a floating-point error bound, and scale-invariant ray spawning from them.

use glam::Vec3A;

#[cfg(any(test, not(target_arch = "x86_64")))]
use crate::math::step_float;

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
    /// The triangle hit, by its index in the object's mesh (`u32::MAX` for other shapes and
    /// baked meshes): with `bary`, where a textured surface is read.
    pub prim: u32,
    /// Barycentrics (b1, b2) of a triangle hit, weighing its second and third vertices.
    pub bary: [f32; 2],
}

impl SurfaceHit {
    /// The origin for a ray leaving this surface towards `w`: the hit point pushed along the
    /// normal just past its own error bound (pbrt-v4's `OffsetRayOrigin`), then rounded away
    /// from the surface. The offset tracks the real rounding error, so it is as small as the
    /// arithmetic allows at any scale or distance from the origin.
    #[inline]
    pub fn spawn_origin(&self, w: Vec3A) -> Vec3A {
        offset_ray_origin(self.p, self.p_error, self.normal, w, 0.0)
    }

    /// Both origins a ray leaving this surface can start from: those of
    /// [`SurfaceHit::spawn_origin`], pushed along the normal at least `least` (world units)
    /// instead where that is farther (a fixed offset, as the peer renderers' contract has it;
    /// 0 keeps the error bound's alone). What they are made of is worked out once for a hit
    /// that spawns many rays; each origin is made when a ray asks for it.
    #[inline]
    pub fn spawn_origins(&self, least: f32) -> SpawnOrigins {
        SpawnOrigins {
            p: self.p,
            normal: self.normal,
            offset: self.normal * offset_distance(self.normal, self.p_error, least),
        }
    }
}

/// Where the rays leaving one hit start, on either side of its surface: the hit point pushed
/// by `offset` (in front) or by −`offset` (behind), then one float further away.
#[derive(Clone, Copy, Debug)]
pub struct SpawnOrigins {
    /// The hit point.
    pub p: Vec3A,
    normal: Vec3A,
    /// The push in front of the surface: the normal times the error bound's reach along it.
    offset: Vec3A,
}

impl SpawnOrigins {
    /// The origin for a ray towards `w`: exactly [`SurfaceHit::spawn_origin`]`(w)`.
    #[inline]
    pub fn towards(&self, w: Vec3A) -> Vec3A {
        let offset = if w.dot(self.normal) < 0.0 { -self.offset } else { self.offset };
        step_away(self.p + offset, offset)
    }

    /// The normal whose side [`SpawnOrigins::towards`] tests: a direction `w` starts behind
    /// the surface when `w.x·n.x + w.y·n.y + w.z·n.z < 0`, summed in that order.
    #[inline(always)]
    pub fn normal(&self) -> Vec3A {
        self.normal
    }

    /// The push in front of the surface: an origin is `p` plus it (in front) or plus its
    /// negation (behind), each component then moved one float the way the push points.
    #[inline(always)]
    pub fn offset(&self) -> Vec3A {
        self.offset
    }

    /// The origin in front of the surface and the one behind it.
    #[inline]
    pub fn sides(&self) -> (Vec3A, Vec3A) {
        (step_away(self.p + self.offset, self.offset), step_away(self.p + -self.offset, -self.offset))
    }
}

/// How far along the unit normal `n` a point with error bound `err` is pushed: past the bound's
/// reach along `n`, and at least `least`.
#[inline(always)]
fn offset_distance(n: Vec3A, err: Vec3A, least: f32) -> f32 {
    n.abs().dot(err).max(least)
}

/// Offsets `p` (with error bound `err`) along `n` to the side of `w`, far enough that the
/// spawned ray cannot re-hit the surface that `p` lies on, and at least `least` (world units).
#[inline]
pub fn offset_ray_origin(p: Vec3A, err: Vec3A, n: Vec3A, w: Vec3A, least: f32) -> Vec3A {
    let mut offset = n * offset_distance(n, err, least);
    if w.dot(n) < 0.0 {
        offset = -offset;
    }
    step_away(p + offset, offset)
}

/// Each component of `v` moved one float the way `o`'s component points
/// ([`step_float`](crate::math::step_float)), bit for bit (NaN included). In SSE2 lanes by
/// masks rather than branches: each normal component's sign is as good as random from one hit
/// to the next.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn step_away(v: Vec3A, o: Vec3A) -> Vec3A {
    use std::arch::x86_64::*;
    // SAFETY: SSE2 is part of x86_64.
    unsafe {
        let (v, o): (__m128, __m128) = (v.into(), o.into());
        let zero = _mm_setzero_ps();
        let mask = |m: __m128| _mm_castps_si128(m);
        let blend = |m: __m128i, a: __m128i, b: __m128i| _mm_or_si128(_mm_and_si128(m, a), _mm_andnot_si128(m, b));
        let bits = _mm_castps_si128(v);
        let (up, down) = (mask(_mm_cmpgt_ps(o, zero)), mask(_mm_cmplt_ps(o, zero)));
        let positive = mask(_mm_cmpgt_ps(v, zero));
        // Away from zero (+1 on the bits) when moving up from a positive value or down from a
        // negative one (a NaN counts as negative), towards it (−1) otherwise.
        let away = _mm_xor_si128(_mm_xor_si128(up, positive), _mm_set1_epi32(-1));
        let moved = _mm_add_epi32(bits, blend(away, _mm_set1_epi32(1), _mm_set1_epi32(-1)));
        // From either zero: the least positive float up, the least negative one down.
        let from_zero = blend(up, _mm_set1_epi32(1), _mm_set1_epi32(0x8000_0001_u32 as i32));
        let moved = blend(mask(_mm_cmpeq_ps(v, zero)), from_zero, moved);
        // Infinities stay where they are the far end.
        let at_end = _mm_or_si128(
            _mm_and_si128(up, mask(_mm_cmpeq_ps(v, _mm_set1_ps(f32::INFINITY)))),
            _mm_and_si128(down, mask(_mm_cmpeq_ps(v, _mm_set1_ps(f32::NEG_INFINITY)))),
        );
        let moves = _mm_andnot_si128(at_end, _mm_or_si128(up, down));
        Vec3A::from(_mm_castsi128_ps(blend(moves, moved, bits)))
    }
}

/// [`step_away`] component by component where there is no SSE2.
#[cfg(not(target_arch = "x86_64"))]
#[inline]
fn step_away(v: Vec3A, o: Vec3A) -> Vec3A {
    Vec3A::new(step_float(v.x, o.x), step_float(v.y, o.y), step_float(v.z, o.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `step_away` is the branchy definition it replaces (`step_float`), bit for bit, in every
    /// lane, on zeros, infinities, NaN, subnormals, the largest floats and random bits.
    #[test]
    fn step_away_is_next_float_up_or_down() {
        let mut values = vec![0.0, -0.0, 1.0, -1.0, f32::INFINITY, f32::NEG_INFINITY, f32::NAN, -f32::NAN];
        values.extend([f32::MIN_POSITIVE, -f32::MIN_POSITIVE, 1e-45, -1e-45, f32::MAX, f32::MIN, 1e3, -2.5e-7]);
        let mut rng = crate::random::SplitMix64::new(5);
        values.extend((0..1000).map(|_| f32::from_bits(rng.next_u64() as u32)));
        let offsets = [1e-7, -1e-7, 0.0, -0.0, f32::NAN];
        for (k, &v) in values.iter().enumerate() {
            // Three values and three offsets per call, in every lane.
            let vs = [v, values[(k + 1) % values.len()], values[(k + 7) % values.len()]];
            for (j, _) in offsets.iter().enumerate() {
                let os = [offsets[j], offsets[(j + 1) % 5], offsets[(j + 3) % 5]];
                let got = step_away(Vec3A::from_array(vs), Vec3A::from_array(os)).to_array();
                for a in 0..3 {
                    let (v, o) = (vs[a], os[a]);
                    assert_eq!(got[a].to_bits(), step_float(v, o).to_bits(), "v = {v:e} ({:#x}), o = {o}", v.to_bits());
                }
            }
        }
    }

    #[test]
    fn spawn_origins_are_those_of_spawn_origin() {
        let hit = SurfaceHit {
            t: 1.0,
            p: Vec3A::new(1e3, -2.5, 1e-3),
            p_error: Vec3A::new(1e-4, 3e-7, 0.0),
            normal: Vec3A::new(0.6, 0.0, -0.8),
            object: 0,
            prim: u32::MAX,
            bary: [0.0; 2],
        };
        let origins = hit.spawn_origins(0.0);
        let ws = [Vec3A::X, -Vec3A::X, Vec3A::Z, Vec3A::new(0.8, 0.3, 0.6), Vec3A::new(0.8, 0.0, 0.6), Vec3A::ZERO];
        for w in ws {
            assert_eq!(origins.towards(w), hit.spawn_origin(w), "w = {w}");
        }
        assert_ne!(origins.towards(Vec3A::X), origins.towards(-Vec3A::X));
        // A least offset below the error bound's changes nothing.
        assert_eq!(hit.spawn_origins(1e-9).sides(), origins.sides());
    }

    #[test]
    fn a_least_offset_past_the_error_bound_starts_rays_that_far_along_the_normal() {
        let hit = SurfaceHit {
            t: 1.0,
            p: Vec3A::new(2.0, 0.5, -1.0),
            p_error: Vec3A::splat(1e-7),
            normal: Vec3A::new(0.0, 0.6, 0.8),
            object: 0,
            prim: u32::MAX,
            bary: [0.0; 2],
        };
        let (front, back) = hit.spawn_origins(1e-3).sides();
        for (origin, side) in [(front, 1.0), (back, -1.0)] {
            // p + ε·n, then one float further from the surface.
            let along = (origin - hit.p).dot(hit.normal) * side;
            assert!((along - 1e-3).abs() < 1e-6, "{side}: {along}");
            assert!((origin - hit.p - hit.normal * along * side).length() < 1e-6);
        }
        // Farther than the error bound alone would put them.
        assert!((front - hit.p).length() > (hit.spawn_origin(hit.normal) - hit.p).length() * 100.0);
    }
}
