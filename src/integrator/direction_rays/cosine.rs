//! Cosine runs in one pass: sample points to directions to packets, with no sort where whole CMJ
//! patterns give each sample's quadrant.

use glam::Vec3A;

use super::{
    DirectionRays, QuadrantPasses, RunDirections, RunOut, clear_and_floor, first_lanes,
    lanes::{PassLanes, add_clear_or_floor, along, occluded_lanes, spawned_lanes, to_world},
    mark_blocked, quadrant_lanes, quadrant_starts, scatter_by_quadrant,
};
use crate::{
    geometry::{accel::SceneGeometry, hit::SpawnOrigins},
    light::DirectionTerms,
    math::Onb,
};
#[cfg(target_arch = "x86_64")]
use crate::{
    integrator::TwoValues,
    sampling::{cmj::QuadrantPattern, cosine_table::TableOrder, warp::cosine_hemisphere_lanes},
    simd::{CompressLanes, Kernel},
};

/// The local directions of a cosine run's group of `L::WIDTH` samples from `at`: from the
/// table where the run reads it in place, from the direction columns `dx`, `dy`, `dz` where
/// they were copied there, else mapped from the sample points in `xs` and `ys`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn local_group<L: PassLanes + CompressLanes>(
    isa: L::Isa,
    directions: &RunDirections,
    columns: [&[f32]; 5],
    at: usize,
) -> [L; 3] {
    let [xs, ys, dx, dy, dz] = columns;
    match directions {
        // Written out, not `table.map`: a closure is compiled without the kernel's instruction
        // set, and where `map` stays out of line its intrinsics become calls.
        RunDirections::Table([x, y, z]) => {
            [L::load_partial(isa, &x[at..]), L::load_partial(isa, &y[at..]), L::load_partial(isa, &z[at..])]
        }
        RunDirections::Columns => [L::load(isa, &dx[at..]), L::load(isa, &dy[at..]), L::load(isa, &dz[at..])],
        RunDirections::Points => cosine_hemisphere_lanes(L::load(isa, &xs[at..]), L::load(isa, &ys[at..])),
    }
}

/// The longest cosine run [`DirectionRays::add_cosine_compressed`] traces in sample order, a
/// packet per group of lanes, rather than sorted into quadrants: over so few rays, the sort and
/// its columns cost more than half-hemisphere packets save over packets spanning the whole
/// hemisphere (a progressive frame of 16 or 32 samples, an adaptive batch of 16, on either
/// lane width; sorted runs of 64 trace faster).
#[cfg(target_arch = "x86_64")]
const SAMPLE_ORDER_RUN: usize = 32;

/// [`DirectionRays::add_cosine_compressed`] as a kernel over the lane type.
#[cfg(target_arch = "x86_64")]
pub(super) struct CompressedRun<'a> {
    pub(super) rays: &'a mut DirectionRays,
    pub(super) geometry: &'a SceneGeometry,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) spawn: &'a SpawnOrigins,
    pub(super) frame: &'a Onb,
    pub(super) terms: &'a DirectionTerms,
    /// Where the run's samples are.
    pub(super) directions: RunDirections<'a>,
    pub(super) out: RunOut<'a>,
}

#[cfg(target_arch = "x86_64")]
impl<L: PassLanes + CompressLanes> Kernel<L> for CompressedRun<'_> {
    type Output = (u64, u64);
    #[inline(always)]
    fn run(self, isa: L::Isa) -> (u64, u64) {
        let CompressedRun { rays, geometry, stack, spawn, frame, terms, directions, out } = self;
        rays.add_cosine_compressed::<L>(isa, geometry, stack, spawn, frame, terms, &directions, out)
    }
}

impl DirectionRays {
    /// [`DirectionRays::add_cosine`] in lanes that compress ([`CompressLanes`]), the local
    /// directions read from the table or already copied to `samples[2..5]`, else the sample
    /// points in `samples[0]` and `samples[1]` mapped to directions
    /// ([`cosine_hemisphere_lanes`]), as `directions` says, a group of `L::WIDTH` at a time.
    /// Each group is turned into the world and sorted into the quadrants of
    /// [`DirectionRays::add_lanes`] by lane compression; packets load their lanes straight from
    /// those columns. A run of at most [`SAMPLE_ORDER_RUN`] samples is traced in sample order,
    /// a packet per group. A summed run ([`RunOut::Sum`]) counts its blocked rays.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn add_cosine_compressed<L: PassLanes + CompressLanes>(
        &mut self,
        isa: L::Isa,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        frame: &Onb,
        terms: &DirectionTerms,
        directions: &RunDirections,
        out: RunOut,
    ) -> (u64, u64) {
        let w = L::WIDTH;
        let n = out.len();
        let groups = n.div_ceil(w);
        // Every sample has weight 1: one clear value and one floor for all.
        let (clear, floor) = clear_and_floor(terms, 1.0);
        self.dark.clear();
        self.dark.resize(groups, 0);
        let mut traced = 0;
        let mut cycles = 0;
        if clear.cmpne(floor).any() {
            let [xs, ys, dx, dy, dz] = &mut self.samples;
            stack.clear();
            if n <= SAMPLE_ORDER_RUN {
                // A short run (a progressive frame's or an adaptive batch's samples): each group
                // traced as it comes, as answers do not depend on the lanes' order.
                for g in 0..groups {
                    let at = g * w;
                    let live = first_lanes(n - at, w);
                    let lanes = spawned_lanes(
                        to_world(frame, local_group::<L>(isa, directions, [xs, ys, dx, dy, dz], at)),
                        spawn,
                        terms.max_distance,
                    );
                    let (hit, took) = occluded_lanes(geometry, stack, &lanes, live, self.timing);
                    self.dark[g] = hit;
                    cycles += took;
                }
                return self.add_run_light::<L>(isa, (clear, floor), out, (n as u64, cycles));
            }
            for column in [&mut *dx, &mut *dy, &mut *dz] {
                column.resize(groups * w, 0.0);
            }
            let normal = spawn.normal();
            let tangents = Onb::from_normal(normal.into());
            let (tu, tv) = (Vec3A::from(tangents.u), Vec3A::from(tangents.v));
            // Directions, quadrants and their counts.
            self.groups.clear();
            let mut count = [0u32; 4];
            for g in 0..groups {
                let at = g * w;
                let masks = {
                    let d = to_world(frame, local_group::<L>(isa, directions, [xs, ys, dx, dy, dz], at));
                    for (column, lanes) in [&mut *dx, &mut *dy, &mut *dz].into_iter().zip(d) {
                        lanes.store(&mut column[at..]);
                    }
                    let valid = first_lanes(n - at, w);
                    let zero = L::splat(isa, 0.0);
                    let negative = [L::bits(along(&d, tu).lt(zero)), L::bits(along(&d, tv).lt(zero))];
                    quadrant_lanes(valid, negative)
                };
                for (count, lanes) in count.iter_mut().zip(masks) {
                    *count += lanes.count_ones();
                }
                self.groups.push(masks);
            }
            let cursor;
            (cursor, traced) = quadrant_starts(count);
            for column in &mut self.ray_dirs {
                column.resize(traced, 0.0);
            }
            self.ray_samples.resize(traced, 0);
            let to = self.ray_dirs.each_mut().map(|c| c.as_mut_slice());
            scatter_by_quadrant::<L, 3>(isa, &self.groups, cursor, [dx, dy, dz], to, &mut self.ray_samples);
            // Packets of `L::WIDTH` consecutive rays, as `RayOrder::Grouped` cuts them, each
            // query timed (when timing) as `DirectionRays::trace` times the whole call.
            for p in (0..traced).step_by(w) {
                let live = first_lanes(traced - p, w);
                let (hit, took) = {
                    let [x, y, z] = &self.ray_dirs;
                    let d =
                        [L::load_partial(isa, &x[p..]), L::load_partial(isa, &y[p..]), L::load_partial(isa, &z[p..])];
                    let lanes = spawned_lanes(d, spawn, terms.max_distance);
                    occluded_lanes(geometry, stack, &lanes, live, self.timing)
                };
                cycles += took;
                mark_blocked(&mut self.dark, &self.ray_samples, p, hit, w);
            }
        }
        self.add_run_light::<L>(isa, (clear, floor), out, (traced as u64, cycles))
    }

    /// Adds each sample's light to `out`: `floor` where `dark` marks it blocked, else `clear`,
    /// sample by sample or, for a sum, the blocked samples counted; passes `counts` (rays
    /// traced, cycles) through.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn add_run_light<L: PassLanes>(
        &self,
        isa: L::Isa,
        (clear, floor): (Vec3A, Vec3A),
        out: RunOut,
        counts: (u64, u64),
    ) -> (u64, u64) {
        match out {
            RunOut::Each(arriving) => {
                for (sums, &dark) in arriving.chunks_mut(L::WIDTH).zip(&self.dark) {
                    add_clear_or_floor::<L>(isa, clear, floor, dark, sums);
                }
            }
            RunOut::Sum(samples, sum) => {
                let dark = self.dark.iter().map(|d| d.count_ones()).sum();
                sum.add_counted(TwoValues { clear, floor, dark }, samples as u32);
            }
        }
        counts
    }

    /// [`DirectionRays::add_cosine`] for runs of whole passes of quadrant patterns: each
    /// pass's n samples traced `L::WIDTH` slots at a time in the pattern's quadrant order
    /// ([`QuadrantPattern`]), so every packet is rays into one quarter of the hemisphere around
    /// the shading normal (n/4 ≥ `L::WIDTH`), their local directions loaded from the table
    /// ([`CosineTable`](crate::sampling::cosine_table::CosineTable)) in that order, with no columns written and no sort; then each sample's
    /// answer is read back by its slot, in sample order, or, for a sum, the blocked ones
    /// counted. Each sample gets the same ray, answer and light as in [`DirectionRays::add`].
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(super) fn add_cosine_quadrants<L: PassLanes>(
        &mut self,
        isa: L::Isa,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        frame: &Onb,
        QuadrantPasses { cmj, table, n, passes }: QuadrantPasses<impl Iterator<Item = u32>>,
        terms: &DirectionTerms,
        mut out: RunOut,
    ) -> (u64, u64) {
        // Every sample has weight 1: one clear value and one floor for all.
        let (clear, floor) = clear_and_floor(terms, 1.0);
        let tracing = clear.cmpne(floor).any();
        let (mut traced, mut cycles, mut dark) = (0, 0, 0);
        // A table sorted by azimuth pads its last packet, which `first_lanes` leaves out (summed
        // runs only); a quadrant table's packets are full.
        debug_assert!(
            table.order() != TableOrder::Sorted || matches!(out, RunOut::Sum(..)),
            "a sorted table gives sums only"
        );
        stack.clear();
        for (pass, p) in passes.enumerate() {
            // Bit t % 16 of entry t / 16: slot t is blocked.
            let mut blocked = [0u32; 16];
            if tracing {
                for (packet, local) in table.pattern(p).chunks_exact(3 * L::WIDTH).enumerate() {
                    let live = first_lanes(n - packet * L::WIDTH, L::WIDTH);
                    let (hit, took) = {
                        let local = [0, 1, 2].map(|axis| L::load(isa, &local[axis * L::WIDTH..]));
                        let lanes = spawned_lanes(to_world(frame, local), spawn, terms.max_distance);
                        occluded_lanes(geometry, stack, &lanes, live, self.timing)
                    };
                    cycles += took;
                    let slot = packet * L::WIDTH;
                    blocked[slot / 16] |= hit << (slot % 16);
                }
                traced += n;
            }
            let RunOut::Each(arriving) = &mut out else {
                dark += blocked.iter().map(|b| b.count_ones()).sum::<u32>();
                continue;
            };
            let pattern = QuadrantPattern::<L>::new(isa, cmj, p);
            for (group, sums) in arriving[pass * n..][..n].chunks_mut(L::WIDTH).enumerate() {
                add_clear_or_floor::<L>(isa, clear, floor, pattern.marked(group, &blocked), sums);
            }
        }
        if let RunOut::Sum(samples, sum) = out {
            sum.add_counted(TwoValues { clear, floor, dark }, samples as u32);
        }
        (traced as u64, cycles)
    }
}
