//! The shadow rays of a direction run ([`PlacedLight::sample_directions`]): set up a SIMD
//! vector of samples at a time, laid out quadrant by quadrant around the surface normal so
//! that consecutive rays make coherent packets, traced in one call, and their answers added
//! back to each sample's arriving light. Every sample gets exactly what
//! [`DirectionTerms::light_sample`] and its own shadow ray give it. A cosine run
//! ([`PlacedLight::cosine_run`]) can go from sample points to packets in one pass instead
//! ([`DirectionRays::add_cosine`]), and where its samples are whole correlated multi-jittered
//! patterns it needs no sort: the patterns' columns give each sample's quadrant of azimuth
//! ([`QuadrantPattern`](crate::sampling::cmj::QuadrantPattern)). A cosine run of one sample
//! at each of many points (jittered camera hits) is set up in lanes point by point
//! ([`DirectionRays::add_cosine_points`]).
//!
//! [`PlacedLight::sample_directions`]: crate::light::PlacedLight::sample_directions
//! [`PlacedLight::cosine_run`]: crate::light::PlacedLight::cosine_run

#[cfg(target_arch = "x86_64")]
mod cosine;
#[cfg(target_arch = "x86_64")]
mod lanes;
#[cfg(target_arch = "x86_64")]
mod points;

use glam::{BVec3A, Vec2, Vec3A};

#[cfg(target_arch = "x86_64")]
use crate::sampling::{
    cmj::Cmj,
    cosine_table::{CosineTable, TableOrder},
};
use crate::{
    geometry::{
        accel::{RayOrder, SceneGeometry},
        hit::SpawnOrigins,
        ray::Ray,
    },
    integrator::RunSum,
    light::{DirectionRun, DirectionTerms, point::PointSource},
    math::Onb,
    sampling::SampleSets,
    stats::{cycle_count, cycles_since},
};

/// The lanes of a group that need a ray, by the quadrant of their direction around the
/// surface normal, in azimuth order: (+u, +v), (−u, +v), (−u, −v), (+u, −v) for the signs of
/// its components along the tangents u and v; bit k for lane k. Neighbouring quadrants come
/// one after the other, so a packet that spans two holds two adjacent quarters of the
/// hemisphere.
#[cfg(target_arch = "x86_64")]
type QuadrantLanes = [u32; 4];

/// Where each quadrant's rays start, given how many each has (each where the previous one's
/// end), and how many there are in all.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn quadrant_starts(count: [u32; 4]) -> ([u32; 4], usize) {
    let mut start = [0u32; 4];
    let mut at = 0;
    for (start, count) in start.iter_mut().zip(count) {
        (*start, at) = (at, at + count);
    }
    (start, at as usize)
}

/// Puts a run's rays in tracing order: each group's lanes, quadrant by quadrant (`groups`,
/// its [`QuadrantLanes`]), compressed from the `from` columns (one value per sample) into the
/// `to` columns at that quadrant's cursor (from [`quadrant_starts`]), with each ray's sample in
/// `ray_samples`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn scatter_by_quadrant<L: lanes::PassLanes + crate::simd::CompressLanes, const C: usize>(
    isa: L::Isa,
    groups: &[QuadrantLanes],
    mut cursor: [u32; 4],
    from: [&[f32]; C],
    mut to: [&mut [f32]; C],
    ray_samples: &mut [u32],
) {
    for (g, masks) in groups.iter().enumerate() {
        let at = g * L::WIDTH;
        for (cursor, &lanes) in cursor.iter_mut().zip(masks) {
            if lanes == 0 {
                continue;
            }
            let first = *cursor as usize;
            for (from, to) in from.iter().zip(to.iter_mut()) {
                L::load(isa, &from[at..]).compress_store(lanes, &mut to[first..]);
            }
            L::compress_indices(isa, at as u32, lanes, &mut ray_samples[first..]);
            *cursor += lanes.count_ones();
        }
    }
}

/// Marks in `dark` (bit `j % width` of entry `j / width` for sample `j`) the samples whose
/// rays, those of the packet starting at `first` in tracing order (`ray_samples`: each ray's
/// sample), `hit` says are blocked.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn mark_blocked(dark: &mut [u32], ray_samples: &[u32], first: usize, hit: u32, width: usize) {
    let mut each = hit;
    while each != 0 {
        let j = ray_samples[first + each.trailing_zeros() as usize] as usize;
        each &= each - 1;
        dark[j / width] |= 1 << (j % width);
    }
}

/// The lanes of a group of `width` that hold one of the `left` items from its first on: all of
/// them, or the first `left` in the run's last, partial group.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn first_lanes(left: usize, width: usize) -> u32 {
    (1u32 << left.min(width)) - 1
}

/// [`QuadrantLanes`] from the lanes that need a ray and those negative along each tangent.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn quadrant_lanes(needs: u32, negative: [u32; 2]) -> QuadrantLanes {
    let [nu, nv] = negative;
    let (pu, nu) = (needs & !nu, needs & nu);
    [pu & !nv, nu & !nv, nu & nv, pu & nv]
}

/// Where a cosine run in lanes ([`DirectionRays::add_cosine_quadrants`],
/// [`DirectionRays::add_cosine_compressed`]) puts its light: one element per sample, or summed
/// over the run (its samples, and the sum it adds to).
#[cfg(target_arch = "x86_64")]
enum RunOut<'a> {
    Each(&'a mut [Vec3A]),
    Sum(usize, &'a mut RunSum),
}

#[cfg(target_arch = "x86_64")]
impl<'a> RunOut<'a> {
    /// Per-sample output, or the sum where one is asked for.
    fn new(arriving: &'a mut [Vec3A], sum: Option<&'a mut RunSum>) -> Self {
        match sum {
            Some(sum) => RunOut::Sum(arriving.len(), sum),
            None => RunOut::Each(arriving),
        }
    }

    /// The run's samples.
    fn len(&self) -> usize {
        match self {
            RunOut::Each(arriving) => arriving.len(),
            RunOut::Sum(samples, _) => *samples,
        }
    }
}

/// Where a cosine run in lanes ([`DirectionRays::add_cosine_compressed`]) finds its samples.
#[cfg(target_arch = "x86_64")]
enum RunDirections<'a> {
    /// Sample points, in the point columns.
    Points,
    /// Local directions copied from the table into the direction columns.
    Columns,
    /// Local directions in place in the table (a run of at most sixteen samples within one pass):
    /// x, y and z, one slice each.
    Table([&'a [f32]; 3]),
}

/// A run of whole passes of quadrant patterns ([`SampleSets::quadrant_passes`]): the sets'
/// patterns, the table of their cosine directions, the patterns' size n, and each pass's
/// pattern number.
#[cfg(target_arch = "x86_64")]
struct QuadrantPasses<'a, P> {
    cmj: &'a Cmj,
    table: &'a CosineTable,
    n: usize,
    passes: P,
}

/// The width of the runs set up in lanes and sorted into quadrants by lane compression (a run
/// at one point from columns, [`cosine::CompressedRun`], or runs over many points,
/// [`points::PointsRun`]), and of the point-light runs over many points: that of `geometry`'s
/// packets, where they are eight or sixteen lanes wide ([`crate::simd::run_in`] runs either)
/// and it has no alpha-tested meshes (which those packet queries do not see).
#[cfg(target_arch = "x86_64")]
fn lane_runs(geometry: &SceneGeometry) -> Option<usize> {
    match geometry.packet_lanes() {
        lanes @ (8 | 16) if !geometry.has_alpha() => Some(lanes),
        _ => None,
    }
}

/// Scratch buffers for [`DirectionRays::add`], kept between runs.
#[derive(Debug, Default)]
pub(crate) struct DirectionRays {
    rays: Vec<Ray>,
    /// Which rays are blocked, plus one entry past them that stays false.
    blocked: Vec<bool>,
    /// Per sample: its ray's index in `rays`, or the number of rays traced for none.
    slots: Vec<u32>,
    #[cfg(target_arch = "x86_64")]
    groups: Vec<QuadrantLanes>,
    /// A cosine run's sample points (x, y) and world directions (x, y, z), sample by sample.
    #[cfg(target_arch = "x86_64")]
    samples: [Vec<f32>; 5],
    /// A cosine run's ray directions (x, y, z) in tracing order.
    #[cfg(target_arch = "x86_64")]
    ray_dirs: [Vec<f32>; 3],
    /// Each of those rays' sample.
    #[cfg(target_arch = "x86_64")]
    ray_samples: Vec<u32>,
    /// A cosine run's blocked samples, bit k of entry g for sample g·w + k in runs of lanes w wide.
    #[cfg(target_arch = "x86_64")]
    dark: Vec<u32>,
    /// The shading points of a cosine run over many points, as columns.
    #[cfg(target_arch = "x86_64")]
    points: points::PointColumns,
    /// Whether [`DirectionRays::add`] times its scene query (in the pixels whose queries the
    /// tracer times, [`crate::stats::query_timed_pixel`]).
    pub(crate) timing: bool,
}

/// A shading point of a cosine run over many points ([`DirectionRays::add_cosine_points`]).
pub(crate) trait CosinePoint {
    /// The symmetry its shading frame is turned by ([`Onb::symmetry`]); the frame is built
    /// around the normal of its [`CosinePoint::spawn`] ([`Onb::from_normal`]).
    fn symmetry(&self) -> u32;
    /// Where its rays start.
    fn spawn(&self) -> &SpawnOrigins;
}

/// The light a clear sample of weight `w` brings (per channel) and the floor a blocked one
/// brings: `radiance·(floor + (1 − floor)·w)` and `radiance·floor`.
#[inline(always)]
fn clear_and_floor(terms: &DirectionTerms, w: f32) -> (Vec3A, Vec3A) {
    let (radiance, f) = (terms.radiance, terms.floor);
    let s = f + (1.0 - f) * w;
    (Vec3A::new(radiance.x * s, radiance.y * s, radiance.z * s), Vec3A::from(radiance * f))
}

impl DirectionRays {
    /// Adds the light of `run` (samples at one point, rays leaving from `spawn`, under `terms`)
    /// to `arriving` (one element per sample), tracing in `geometry` the shadow rays whose
    /// answer matters. Returns how many rays it traced, and the cycles its scene query took
    /// ([`cycle_count`]) when [`DirectionRays::timing`] is set (0 otherwise).
    pub(crate) fn add(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        run: &DirectionRun,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> (u64, u64) {
        #[cfg(target_arch = "x86_64")]
        {
            let lanes = geometry.packet_lanes();
            if matches!(lanes, 8 | 16) {
                let kernel = lanes::AddRun { rays: self, geometry, stack, spawn, run, terms, arriving };
                // Sixteen- and eight-lane packets are used only where `simd::isa` allows them.
                return crate::simd::run_in(lanes, kernel).expect("eight or sixteen lanes");
            }
        }
        self.add_each(geometry, stack, spawn, run, terms, arriving)
    }

    /// [`DirectionRays::add`] for a light whose samples are cosine directions around
    /// `frame`'s normal ([`PlacedLight::cosine_run`](crate::light::PlacedLight::cosine_run)),
    /// drawn from `sets` for samples `first, first + 1, …` of `pixel` in dimension `dim`: the
    /// same rays, answers and sums, in one pass from sample points to packets, where the
    /// scene's packets are eight or sixteen wide and the sets are computed in lanes: straight
    /// from the patterns in quadrant order where the run is whole passes that split into
    /// quadrants ([`SampleSets::quadrant_passes`]), else sorted into quadrants from columns
    /// ([`SampleSets::fill_columns`], any sampler). `None`, having
    /// done nothing, elsewhere, and in scenes with alpha-tested meshes, which those packet queries
    /// do not see (the general path's queries do). With `sum`, the run's light is added there,
    /// its blocked rays counted, instead of to `arriving`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn add_cosine(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        frame: &Onb,
        sets: &SampleSets,
        (pixel, first, dim): (u32, u32, u32),
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
        sum: Option<&mut RunSum>,
    ) -> Option<(u64, u64)> {
        #[cfg(target_arch = "x86_64")]
        if let lanes @ (8 | 16) = geometry.packet_lanes()
            && !geometry.has_alpha()
            && let Some((cmj, table, passes)) = sets.quadrant_passes(pixel, first, dim, arriving.len())
            && table.lanes() == lanes
            // A table sorted by azimuth says nothing of which sample a ray is: sums only.
            && (sum.is_some() || table.order() == TableOrder::Quadrants)
        {
            let passes = QuadrantPasses { cmj, table, n: sets.set_size() as usize, passes };
            let out = RunOut::new(arriving, sum);
            let kernel = lanes::QuadrantRun { rays: self, geometry, stack, spawn, frame, passes, terms, out };
            return crate::simd::run_in(lanes, kernel);
        }
        #[cfg(target_arch = "x86_64")]
        if let Some(lanes) = lane_runs(geometry) {
            let n = arriving.len().next_multiple_of(16);
            let len = arriving.len();
            // Local directions from the table where it is in sample order (read in place where
            // the run is at most sixteen samples within one pass), else sample points.
            let in_table = if len <= 16 { sets.table_directions(pixel, first, dim, len) } else { None };
            let directions = match in_table {
                Some(columns) => RunDirections::Table(columns),
                None => {
                    let [xs, ys, dx, dy, dz] = &mut self.samples;
                    for column in [&mut *dx, &mut *dy, &mut *dz] {
                        column.resize(n, 0.0);
                    }
                    if sets.fill_directions(pixel, first, dim, [&mut dx[..len], &mut dy[..len], &mut dz[..len]]) {
                        RunDirections::Columns
                    } else {
                        xs.resize(n, 0.5);
                        ys.resize(n, 0.5);
                        sets.fill_columns(pixel, first, dim, &mut xs[..len], &mut ys[..len]);
                        RunDirections::Points
                    }
                }
            };
            if !matches!(directions, RunDirections::Points) {
                // Pixels of a row come one after the other: the next one's directions load
                // while this one's rays are traced.
                sets.prefetch_directions(pixel.wrapping_add(1), first, dim, len);
            }
            let out = RunOut::new(arriving, sum);
            let kernel = cosine::CompressedRun { rays: self, geometry, stack, spawn, frame, terms, directions, out };
            return crate::simd::run_in(lanes, kernel);
        }
        let _ = (geometry, stack, spawn, frame, sets, pixel, first, dim, terms, arriving, sum);
        None
    }

    /// [`DirectionRays::add_cosine`] for one sample at each of many points (a pixel's camera
    /// hits when each sample has its own): point `points[i]` draws sample point `u(p)`
    /// (mapped as [`cosine_power_hemisphere`](crate::sampling::warp::cosine_power_hemisphere)
    /// with e = 1 maps it) into `arriving[i]`, where `lit(p)` (elsewhere no ray, nothing added).
    /// The same rays, answers and light as [`DirectionRays::add`] gives each point's sample,
    /// set up in lanes and traced as packets by quadrant, where the scene's packets are eight or
    /// sixteen wide. `None`, having done nothing, elsewhere, and in scenes with alpha-tested
    /// meshes (as for [`DirectionRays::add_cosine`]).
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn add_cosine_points<P: CosinePoint>(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        points: &[P],
        u: impl Fn(&P) -> Vec2,
        lit: impl Fn(&P) -> bool,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> Option<(u64, u64)> {
        debug_assert_eq!(points.len(), arriving.len(), "one sample per point");
        #[cfg(target_arch = "x86_64")]
        if let Some(lanes) = lane_runs(geometry) {
            self.points.gather(points, u, lit, lanes);
            let kernel = points::PointsRun { rays: self, geometry, stack, terms, arriving };
            return crate::simd::run_in(lanes, kernel);
        }
        let _ = (geometry, stack, points, u, lit, terms, arriving);
        None
    }

    /// The light of each of `sources`, one after the other, at each of `points` added to
    /// `arriving[i]` for `points[i]`, where `lit(p)` (elsewhere nothing added):
    /// [`PointSource::sample`] and, where its light is not zero and the source casts shadows, a
    /// shadow ray to it from the point's side of its surface, `far` of the way there (what the
    /// tracer's general path traces for it). The same light and rays bit for bit, set up in
    /// lanes and traced as packets of neighbouring points, where the scene's packets are eight
    /// or sixteen wide; the points are gathered into columns once for all the sources. `None`,
    /// having done nothing, elsewhere, and in scenes with alpha-tested meshes (as for
    /// [`DirectionRays::add_cosine`]).
    ///
    /// [`PointSource::sample`]: crate::light::point::PointSource::sample
    pub(crate) fn add_point_sources<P: CosinePoint>(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        points: &[P],
        lit: impl Fn(&P) -> bool,
        (sources, far): (&[PointSource], f32),
        arriving: &mut [Vec3A],
    ) -> Option<(u64, u64)> {
        debug_assert_eq!(points.len(), arriving.len(), "one sample per point");
        #[cfg(target_arch = "x86_64")]
        if let Some(lanes) = lane_runs(geometry) {
            self.points.gather(points, |_| Vec2::ZERO, lit, lanes);
            let kernel = points::PointSourcesRun { rays: self, geometry, stack, sources, far, arriving };
            return crate::simd::run_in(lanes, kernel);
        }
        let _ = (geometry, stack, points, lit, sources, far, arriving);
        None
    }

    /// [`DirectionRays::add`] one sample at a time, in sample order: for trees traversed
    /// without packets, where the order of the rays does not matter.
    fn add_each(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        run: &DirectionRun,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> (u64, u64) {
        self.rays.clear();
        self.slots.clear();
        for j in 0..arriving.len() {
            let (clear, floor) = clear_and_floor(terms, run.weight[j]);
            let slot = if run.weight[j] > 0.0 && clear.cmpne(floor).any() {
                let dir = run.dir(j);
                self.rays.push(Ray::new(spawn.towards(dir), dir, terms.max_distance));
                self.rays.len() - 1
            } else {
                usize::MAX
            };
            self.slots.push(slot as u32);
        }
        let traced = self.rays.len();
        // No ray: the entry past the rays, which stays false.
        for slot in &mut self.slots {
            *slot = (*slot).min(traced as u32);
        }
        let cycles = self.trace(geometry, stack, traced, RayOrder::Mixed);
        for (j, sum) in arriving.iter_mut().enumerate() {
            let (clear, floor) = clear_and_floor(terms, run.weight[j]);
            let dark = run.weight[j] <= 0.0 || self.blocked[self.slots[j] as usize];
            *sum += Vec3A::select(BVec3A::splat(dark), floor, clear);
        }
        (traced as u64, cycles)
    }

    /// Traces the first `traced` of `rays` into `blocked`, which gets one more entry, false.
    /// Returns the cycles the query took when `timing`, else 0.
    fn trace(&mut self, geometry: &SceneGeometry, stack: &mut Vec<(u32, f32)>, traced: usize, order: RayOrder) -> u64 {
        // The query writes every ray's entry, so only the one past them is set here (no
        // clearing pass over the others first).
        self.blocked.resize(traced + 1, false);
        self.blocked[traced] = false;
        let start = self.timing.then(cycle_count);
        geometry.occluded_many(&self.rays[..traced], order, stack, &mut self.blocked[..traced]);
        start.map_or(0, cycles_since)
    }
}
