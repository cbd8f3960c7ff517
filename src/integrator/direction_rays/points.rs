//! Cosine runs over many shading points: one sample at each of a pixel's camera hits (jittered
//! or lens rays), its direction and ray set up in lanes, and the rays traced in packets by the
//! quadrant of their local direction.

use glam::{Vec2, Vec3A};

use super::{
    CosinePoint, DirectionRays, clear_and_floor, first_lanes,
    lanes::{PassLanes, add_group, occluded_lanes},
    mark_blocked, quadrant_lanes, quadrant_starts, scatter_by_quadrant,
};
use crate::{
    geometry::{accel::SceneGeometry, lanes::RayLanes},
    light::{DirectionTerms, point::PointSource},
    sampling::warp::cosine_hemisphere_lanes,
    simd::{BitLanes, CompressLanes, Kernel, dot3},
};

/// Columns of [`PointColumns`]: the sample point (2), the normal (3; the shading frame's w, and
/// the normal whose side picks a ray's origin), the hit point (3) and its push off the surface
/// (3, [`SpawnOrigins::offset`](crate::geometry::hit::SpawnOrigins::offset)).
const U: usize = 0;
const NORMAL: usize = 2;
const POINT: usize = 5;
const OFFSET: usize = 8;
const COLUMNS: usize = 11;

/// A run of shading points as columns, one entry per point, padded to whole groups of the
/// lanes that take them.
#[derive(Debug, Default)]
pub(super) struct PointColumns {
    columns: [Vec<f32>; COLUMNS],
    /// The points in a group: the width of the lanes that take them.
    width: usize,
    /// Bit k of entry g: point g·width + k is lit.
    lit: Vec<u32>,
    /// The bits of each point's frame symmetry ([`Onb::symmetry`](crate::math::Onb::symmetry)),
    /// one mask per group as in `lit`: a quarter turn (bit 0 of the symmetry), a half turn (bit
    /// 1), a mirror (bit 2).
    symmetry: [Vec<u32>; 3],
    /// Each point's ray origin (x, y, z).
    origins: [Vec<f32>; 3],
    /// Ray origins (x, y, z) in tracing order, beside the directions in `ray_dirs`.
    ray_origins: [Vec<f32>; 3],
}

impl PointColumns {
    /// Writes `points`, their sample points `u` and whether each is `lit`, into the columns,
    /// a column at a time (each a plain pass over the points), for lanes `width` wide.
    pub(super) fn gather<P: CosinePoint>(
        &mut self,
        points: &[P],
        u: impl Fn(&P) -> Vec2,
        lit: impl Fn(&P) -> bool,
        width: usize,
    ) {
        self.width = width;
        let [ux, uy, nx, ny, nz, px, py, pz, ox, oy, oz] = &mut self.columns;
        let padded = points.len().next_multiple_of(width);
        fill(ux, points, padded, |p| u(p).x);
        fill(uy, points, padded, |p| u(p).y);
        fill(nx, points, padded, |p| p.spawn().normal().x);
        fill(ny, points, padded, |p| p.spawn().normal().y);
        fill(nz, points, padded, |p| p.spawn().normal().z);
        fill(px, points, padded, |p| p.spawn().p.x);
        fill(py, points, padded, |p| p.spawn().p.y);
        fill(pz, points, padded, |p| p.spawn().p.z);
        fill(ox, points, padded, |p| p.spawn().offset().x);
        fill(oy, points, padded, |p| p.spawn().offset().y);
        fill(oz, points, padded, |p| p.spawn().offset().z);
        // One pass for the four masks: bit k of entry g is point g·width + k's.
        self.lit.clear();
        self.symmetry.iter_mut().for_each(Vec::clear);
        for group in points.chunks(width) {
            let (mut lit_bits, mut symmetry_bits) = (0, [0; 3]);
            for (k, p) in group.iter().enumerate() {
                lit_bits |= u32::from(lit(p)) << k;
                let symmetry = p.symmetry();
                for (b, bits) in symmetry_bits.iter_mut().enumerate() {
                    *bits |= (symmetry >> b & 1) << k;
                }
            }
            self.lit.push(lit_bits);
            for (mask, bits) in self.symmetry.iter_mut().zip(symmetry_bits) {
                mask.push(bits);
            }
        }
    }
}

/// Sets `column` to `value` of each of `points`, padded with 0.5 to `padded` entries.
#[inline(always)]
fn fill<P>(column: &mut Vec<f32>, points: &[P], padded: usize, value: impl Fn(&P) -> f32) {
    column.clear();
    column.extend(points.iter().map(value));
    column.resize(padded, 0.5);
}

/// [`DirectionRays::add_cosine_points_lanes`] as a kernel over the lane type.
pub(super) struct PointsRun<'a> {
    pub(super) rays: &'a mut DirectionRays,
    pub(super) geometry: &'a SceneGeometry,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) terms: &'a DirectionTerms,
    pub(super) arriving: &'a mut [Vec3A],
}

impl<L: PassLanes + CompressLanes + BitLanes> Kernel<L> for PointsRun<'_> {
    type Output = (u64, u64);
    #[inline(always)]
    fn run(self, isa: L::Isa) -> (u64, u64) {
        let PointsRun { rays, geometry, stack, terms, arriving } = self;
        rays.add_cosine_points_lanes::<L>(isa, geometry, stack, terms, arriving)
    }
}

impl DirectionRays {
    /// [`DirectionRays::add_cosine_points`] in lanes that compress, the points already in
    /// `points`: each group of `L::WIDTH` points' directions ([`cosine_hemisphere_lanes`], then
    /// each point's own frame) and origins (each point's side of its surface) made in lanes,
    /// sorted by lane compression into the quadrants of their local directions (the pixel's
    /// points share a frame up to the little its normal turns across the pixel, so a quadrant
    /// is one quarter of the hemisphere nearly everywhere), and traced as packets of
    /// consecutive rays. Each point gets the ray, answer and light of [`DirectionRays::add`].
    #[inline(always)]
    pub(super) fn add_cosine_points_lanes<L: PassLanes + CompressLanes + BitLanes>(
        &mut self,
        isa: L::Isa,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> (u64, u64) {
        let w = L::WIDTH;
        debug_assert_eq!(w, self.points.width, "the columns hold points in groups of the lanes' width");
        let n = arriving.len();
        let groups = n.div_ceil(w);
        // Every sample has weight 1: one clear value and one floor for all.
        let (clear, floor) = clear_and_floor(terms, 1.0);
        self.dark.clear();
        self.dark.resize(groups, 0);
        let (mut traced, mut cycles) = (0, 0);
        let points = &mut self.points;
        if clear.cmpne(floor).any() {
            let [.., dx, dy, dz] = &mut self.samples;
            let [ox, oy, oz] = &mut points.origins;
            for column in [&mut *dx, &mut *dy, &mut *dz, &mut *ox, &mut *oy, &mut *oz] {
                column.resize(groups * w, 0.0);
            }
            let zero = L::splat(isa, 0.0);
            self.groups.clear();
            let mut count = [0u32; 4];
            for g in 0..groups {
                let at = g * w;
                let c = |k: usize| L::load(isa, &points.columns[k][at..]);
                let local = cosine_hemisphere_lanes(c(U), c(U + 1));
                let normal = [c(NORMAL), c(NORMAL + 1), c(NORMAL + 2)];
                let symmetry = points.symmetry.each_ref().map(|m| L::mask(isa, m[g]));
                let (u, v) = frame_lanes(isa, normal, symmetry);
                // The frame's `to_world`, u·x + v·y + w·z, and `SpawnOrigins::towards`'s side
                // test, x·n.x + y·n.y + z·n.z: the scalar code's products and sums.
                let d = [0, 1, 2].map(|a| dot3(&[u[a], v[a], normal[a]], &local));
                let side = dot3(&d, &normal);
                let behind = side.lt(zero);
                for (a, column) in [&mut *dx, &mut *dy, &mut *dz].into_iter().enumerate() {
                    d[a].store(&mut column[at..]);
                }
                // `SpawnOrigins::towards`: the point pushed to the ray's side, one float further.
                for (a, column) in [&mut *ox, &mut *oy, &mut *oz].into_iter().enumerate() {
                    let push = c(OFFSET + a).select(behind, c(OFFSET + a).neg());
                    c(POINT + a).add(push).step_away(push).store(&mut column[at..]);
                }
                let valid = first_lanes(n - at, w) & points.lit[g];
                let negative = [L::bits(local[0].lt(zero)), L::bits(local[1].lt(zero))];
                let masks = quadrant_lanes(valid, negative);
                for (count, lanes) in count.iter_mut().zip(masks) {
                    *count += lanes.count_ones();
                }
                self.groups.push(masks);
            }
            let cursor;
            (cursor, traced) = quadrant_starts(count);
            for column in self.ray_dirs.iter_mut().chain(&mut points.ray_origins) {
                column.resize(traced, 0.0);
            }
            self.ray_samples.resize(traced, 0);
            let [.., dx, dy, dz] = &self.samples;
            let [ox, oy, oz] = &points.origins;
            let ([rx, ry, rz], [qx, qy, qz]) = (&mut self.ray_dirs, &mut points.ray_origins);
            let to = [rx, ry, rz, qx, qy, qz].map(|c| c.as_mut_slice());
            let from = [dx, dy, dz, ox, oy, oz].map(|c| c.as_slice());
            scatter_by_quadrant::<L, 6>(isa, &self.groups, cursor, from, to, &mut self.ray_samples);
            // Packets of `L::WIDTH` consecutive rays, each query timed (when timing) as
            // `DirectionRays::trace` times the whole call.
            stack.clear();
            let one = L::splat(isa, 1.0);
            for p in (0..traced).step_by(w) {
                let live = first_lanes(traced - p, w);
                let (hit, took) = {
                    // Written out, not by `map` (see `cosine::local_group`).
                    let ([dx, dy, dz], [ox, oy, oz]) = (&self.ray_dirs, &points.ray_origins);
                    let load = |c: &[f32]| L::load_partial(isa, &c[p..traced]);
                    let d = [load(dx), load(dy), load(dz)];
                    let lanes = RayLanes {
                        origin: [load(ox), load(oy), load(oz)],
                        dir: d,
                        inv_dir: [one.div(d[0]), one.div(d[1]), one.div(d[2])],
                        tmax: L::splat(isa, terms.max_distance),
                    };
                    occluded_lanes(geometry, stack, &lanes, live, self.timing)
                };
                cycles += took;
                mark_blocked(&mut self.dark, &self.ray_samples, p, hit, w);
            }
        }
        // Lit points get the clear value or the floor; the others −0, which adds nothing.
        let pick = |clear: f32, floor: f32, dark: L::Mask, unlit: L::Mask| {
            L::splat(isa, clear).select(dark, L::splat(isa, floor)).select(unlit, L::splat(isa, -0.0))
        };
        for ((sums, &dark), &lit) in arriving.chunks_mut(w).zip(&self.dark).zip(&points.lit) {
            let (dark, unlit) = (L::mask(isa, dark), L::mask(isa, !lit));
            add_group(
                pick(clear.x, floor.x, dark, unlit),
                pick(clear.y, floor.y, dark, unlit),
                pick(clear.z, floor.z, dark, unlit),
                sums,
            );
        }
        (traced as u64, cycles)
    }
}

/// [`DirectionRays::add_point_sources`] as a kernel over the lane type, the points already in
/// `rays.points`.
pub(super) struct PointSourcesRun<'a> {
    pub(super) rays: &'a mut DirectionRays,
    pub(super) geometry: &'a SceneGeometry,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) sources: &'a [PointSource],
    pub(super) far: f32,
    pub(super) arriving: &'a mut [Vec3A],
}

impl<L: PassLanes + BitLanes> Kernel<L> for PointSourcesRun<'_> {
    type Output = (u64, u64);
    #[inline(always)]
    fn run(self, isa: L::Isa) -> (u64, u64) {
        let PointSourcesRun { rays, geometry, stack, sources, far, arriving } = self;
        stack.clear();
        let (mut traced, mut cycles) = (0, 0);
        for source in sources {
            let (t, c) =
                point_source_lanes::<L>(isa, &rays.points, (geometry, &mut *stack, rays.timing), source, far, arriving);
            (traced, cycles) = (traced + t, cycles + c);
        }
        (traced, cycles)
    }
}

/// One source's light at the points in `points` added to `arriving`, with its shadow rays
/// traced in `geometry` (queries timed where `timing`): [`DirectionRays::add_point_sources`]
/// for one source. Returns the rays traced and the cycles their queries took.
#[inline(always)]
fn point_source_lanes<L: PassLanes + BitLanes>(
    isa: L::Isa,
    points: &PointColumns,
    (geometry, stack, timing): (&SceneGeometry, &mut Vec<(u32, f32)>, bool),
    source: &PointSource,
    far: f32,
    arriving: &mut [Vec3A],
) -> (u64, u64) {
    let w = L::WIDTH;
    debug_assert_eq!(w, points.width, "the columns hold points in groups of the lanes' width");
    let (zero, one) = (L::splat(isa, 0.0), L::splat(isa, 1.0));
    let q = source.position.to_array().map(|x| L::splat(isa, x));
    let intensity = source.intensity.to_array().map(|x| L::splat(isa, x));
    let (mut traced, mut cycles) = (0, 0);
    for (g, sums) in arriving.chunks_mut(w).enumerate() {
        let at = g * w;
        let c = |k: usize| L::load(isa, &points.columns[k][at..]);
        let (p, normal) = ([c(POINT), c(POINT + 1), c(POINT + 2)], [c(NORMAL), c(NORMAL + 1), c(NORMAL + 2)]);
        // `PointSource::sample`: the scalar code's operations, lane by lane.
        let to_light = [0, 1, 2].map(|a| q[a].sub(p[a]));
        let dist2 = dot3(&to_light, &to_light);
        let cos = dot3(&normal, &to_light);
        let dark = L::or(cos.le(zero), dist2.le(zero));
        let lit = L::bits(L::andnot(dark, L::mask(isa, points.lit[g]))) & first_lanes(sums.len(), w);
        let cos = cos.div(dist2.sqrt());
        let scale = if source.falloff { cos.div(dist2) } else { cos };
        let light = intensity.map(|i| i.mul(scale));
        let nonzero = L::or(L::or(light[0].ne(zero), light[1].ne(zero)), light[2].ne(zero));
        let needs_ray = if source.shadows { lit & L::bits(nonzero) } else { 0 };
        let mut blocked = 0;
        if needs_ray != 0 {
            // `SpawnOrigins::towards(q − p)`, then the ray from there to `q`.
            let behind = dot3(&to_light, &normal).lt(zero);
            let origin = [0, 1, 2].map(|a| {
                let push = c(OFFSET + a).select(behind, c(OFFSET + a).neg());
                p[a].add(push).step_away(push)
            });
            let dir = [0, 1, 2].map(|a| q[a].sub(origin[a]));
            let lanes = RayLanes { origin, dir, inv_dir: dir.map(|d| one.div(d)), tmax: L::splat(isa, far) };
            let took;
            (blocked, took) = occluded_lanes(geometry, stack, &lanes, needs_ray, timing);
            cycles += took;
            traced += u64::from(needs_ray.count_ones());
        }
        // Lit points get their light, or +0 where blocked; the others −0, which adds nothing.
        let (unlit, blocked) = (L::mask(isa, !lit), L::mask(isa, blocked));
        let pick = |x: L| x.select(blocked, zero).select(unlit, L::splat(isa, -0.0));
        add_group(pick(light[0]), pick(light[1]), pick(light[2]), sums);
    }
    (traced, cycles)
}

/// The tangents u and v of each lane's shading frame around unit normal `n`, turned by its
/// symmetry (masks of a quarter turn, a half turn and a mirror): [`Onb::from_normal`] and
/// [`Onb::symmetry`], operation for operation, so every lane has the scalar frame's bits.
///
/// [`Onb::from_normal`]: crate::math::Onb::from_normal
/// [`Onb::symmetry`]: crate::math::Onb::symmetry
#[inline(always)]
fn frame_lanes<L: BitLanes>(isa: L::Isa, n: [L; 3], [quarter, half, mirror]: [L::Mask; 3]) -> ([L; 3], [L; 3]) {
    let one = L::splat(isa, 1.0);
    let sign = one.copysign(n[2]);
    let a = L::splat(isa, -1.0).div(sign.add(n[2]));
    let b = n[0].mul(n[1]).mul(a);
    let u = [one.add(sign.mul(n[0]).mul(n[0]).mul(a)), sign.mul(b), sign.neg().mul(n[0])];
    let v = [b, sign.add(n[1].mul(n[1]).mul(a)), n[1].neg()];
    // A quarter turn takes (u, v) to (v, −u), a half turn to (−u, −v); a mirror negates v.
    let (u, v) = ([0, 1, 2].map(|k| u[k].select(quarter, v[k])), [0, 1, 2].map(|k| v[k].select(quarter, u[k].neg())));
    let negate = |x: L, m: L::Mask| x.select(m, x.neg());
    (u.map(|x| negate(x, half)), v.map(|x| negate(negate(x, half), mirror)))
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::{
        math::Onb,
        random::SplitMix64,
        simd::{Avx, Avx512},
    };

    /// Each lane's frame is the scalar frame of its normal under its symmetry, bit for bit, on
    /// normals along and against every axis (±0 in z included) and random ones, under all eight
    /// symmetries, in eight lanes and sixteen (where the CPU has them).
    #[test]
    fn frames_in_lanes_are_the_scalar_frames() {
        crate::simd::both_widths(frames::<Avx>, frames::<Avx512>);
    }

    /// [`frames_in_lanes_are_the_scalar_frames`] in lanes `L`.
    fn frames<L: BitLanes>(isa: L::Isa) {
        let w = L::WIDTH;
        let mut normals = vec![Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z];
        normals.extend([Vec3::new(0.6, 0.8, 0.0), Vec3::new(0.6, 0.8, -0.0), Vec3::new(0.0, 0.6, -0.8)]);
        let mut rng = SplitMix64::new(11);
        let mut unit = || rng.next_f32() * 2.0 - 1.0;
        normals.extend((0..200).map(|_| Vec3::new(unit(), unit(), unit()).normalize()));
        let bits = |v: Vec3| v.to_array().map(f32::to_bits);
        for (start, chunk) in normals.chunks(w).enumerate() {
            let lane = |k: usize| chunk[k % chunk.len()];
            let column = |a: usize| L::load(isa, &(0..w).map(|k| lane(k)[a]).collect::<Vec<f32>>());
            let symmetry = |k: usize| ((start + 3 * k) % 8) as u32;
            let masks = [0, 1, 2].map(|b| L::mask(isa, (0..w).fold(0, |m, k| m | (symmetry(k) >> b & 1) << k)));
            let (u, v) = frame_lanes(isa, [column(0), column(1), column(2)], masks);
            for k in 0..w {
                let want = Onb::from_normal(lane(k)).symmetry(symmetry(k));
                let got = |x: [L; 3]| Vec3::from_array(x.map(|c| c.lane(k)));
                let n = lane(k);
                assert_eq!(
                    (bits(got(u)), bits(got(v))),
                    (bits(want.u), bits(want.v)),
                    "n = {n}, symmetry {}, {w} lanes",
                    symmetry(k)
                );
            }
        }
    }
}
