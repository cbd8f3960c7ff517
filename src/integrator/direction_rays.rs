//! The shadow rays of a direction run ([`PlacedLight::sample_directions`]): set up a SIMD
//! vector of samples at a time, laid out quadrant by quadrant around the surface normal so
//! that consecutive rays make coherent packets, traced in one call, and their answers added
//! back to each sample's arriving light. Every sample gets exactly what
//! [`DirectionTerms::light_sample`] and its own shadow ray give it. A cosine run
//! ([`PlacedLight::cosine_run`]) can go from sample points to packets in one pass instead
//! ([`DirectionRays::add_cosine`]), and where its samples are whole correlated multi-jittered
//! patterns it needs no sort: the patterns' columns give each sample's quadrant of azimuth
//! ([`QuadrantPattern`]).
//!
//! [`PlacedLight::sample_directions`]: crate::light::PlacedLight::sample_directions
//! [`PlacedLight::cosine_run`]: crate::light::PlacedLight::cosine_run

use glam::{BVec3A, Vec3A};

#[cfg(target_arch = "x86_64")]
use crate::{
    geometry::lanes::{Avx, Avx512, Lanes, RayLanes},
    sampling::{
        cmj::{Cmj, GridLanes, QuadrantPattern, SmallGrid8, SmallGrid16},
        cosine_table::CosineTable,
        warp::cosine_hemisphere16,
    },
};
use crate::{
    geometry::{
        accel::{RayOrder, SceneGeometry},
        hit::SpawnOrigins,
        ray::Ray,
    },
    integrator::RunSum,
    light::{DirectionRun, DirectionTerms},
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

/// [`QuadrantLanes`] from the lanes that need a ray and those negative along each tangent.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn quadrant_lanes(needs: u32, negative: [u32; 2]) -> QuadrantLanes {
    let [nu, nv] = negative;
    let (pu, nu) = (needs & !nu, needs & nu);
    [pu & !nv, nu & !nv, nu & nv, pu & nv]
}

/// Where [`DirectionRays::add_cosine_quadrants`] puts a run's light: one element per sample,
/// or summed over the run (its samples, and the sum it adds to).
#[cfg(target_arch = "x86_64")]
enum QuadrantOut<'a> {
    Each(&'a mut [Vec3A]),
    Sum(usize, &'a mut Vec3A),
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
    /// A cosine run's blocked samples, bit k of entry g for sample 16g + k.
    #[cfg(target_arch = "x86_64")]
    dark: Vec<u32>,
    /// Whether [`DirectionRays::add`] times its scene query (in the pixels whose queries the
    /// tracer times, [`crate::stats::query_timed_pixel`]).
    pub(crate) timing: bool,
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
        match geometry.packet_lanes() {
            // SAFETY: sixteen- and eight-lane packets are used only where AVX-512 (with POPCNT)
            // and AVX were detected.
            16 => return unsafe { self.add_avx512(geometry, stack, spawn, run, terms, arriving) },
            8 => return unsafe { self.add_avx(geometry, stack, spawn, run, terms, arriving) },
            _ => {}
        }
        self.add_each(geometry, stack, spawn, run, terms, arriving)
    }

    /// [`DirectionRays::add`] for a light whose samples are cosine directions around
    /// `frame`'s normal ([`PlacedLight::cosine_run`](crate::light::PlacedLight::cosine_run)),
    /// drawn from `sets` for samples `first, first + 1, …` of `pixel` in dimension `dim`: the
    /// same rays, answers and sums, in one pass from sample points to packets, where the
    /// scene's packets are eight or sixteen wide and the sets are computed in lanes: straight
    /// from the patterns in quadrant order where the run is whole passes that split into
    /// quadrants ([`SampleSets::quadrant_passes`]), else, with sixteen-lane packets, sorted
    /// into quadrants from columns ([`SampleSets::fill_columns`]). `None`, having done
    /// nothing, elsewhere. With `sum`, whole quadrant passes add the run's light there,
    /// summed, instead of to `arriving`.
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
            && let Some((cmj, table, passes)) = sets.quadrant_passes(pixel, first, dim, arriving.len())
            && table.lanes() == lanes
        {
            let passes = QuadrantPasses { cmj, table, n: sets.set_size() as usize, passes };
            let out = match sum {
                Some(sum) => QuadrantOut::Sum(arriving.len(), &mut sum.light),
                None => QuadrantOut::Each(arriving),
            };
            // SAFETY: sixteen-lane packets are used only where AVX-512 was detected, eight-lane
            // ones only where AVX2 was ([`crate::cpu`]), and quadrant patterns need AVX2.
            return Some(unsafe {
                if lanes == 16 {
                    Avx512::add_quadrants(self, geometry, stack, spawn, frame, passes, terms, out)
                } else {
                    Avx::add_quadrants(self, geometry, stack, spawn, frame, passes, terms, out)
                }
            });
        }
        #[cfg(target_arch = "x86_64")]
        if geometry.packet_lanes() == 16 {
            let n = arriving.len().next_multiple_of(16);
            let [xs, ys, ..] = &mut self.samples;
            xs.resize(n, 0.5);
            ys.resize(n, 0.5);
            let len = arriving.len();
            if sets.fill_columns(pixel, first, dim, &mut xs[..len], &mut ys[..len]) {
                if let Some(sum) = sum {
                    sum.per_sample = true;
                }
                // SAFETY: sixteen-lane packets are used only where AVX-512 (and POPCNT) was detected.
                return Some(unsafe { self.add_cosine_avx512(geometry, stack, spawn, frame, terms, arriving) });
            }
        }
        let _ = (geometry, stack, spawn, frame, sets, pixel, first, dim, terms, arriving, sum);
        None
    }

    /// [`DirectionRays::add_cosine`] in AVX-512 lanes, the sample points already in
    /// `samples[0]` and `samples[1]`. Each group of sixteen samples is mapped to directions
    /// ([`cosine_hemisphere16`]) and sorted into the quadrants of [`DirectionRays::add_lanes`]
    /// by lane compression; packets load their lanes straight from those columns.
    ///
    /// # Safety
    /// The CPU must have AVX-512F and POPCNT ([`crate::simd::avx512`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn add_cosine_avx512(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        frame: &Onb,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> (u64, u64) {
        use std::arch::x86_64::*;

        let n = arriving.len();
        let groups = n.div_ceil(16);
        // Every sample has weight 1: one clear value and one floor for all.
        let (clear, floor) = clear_and_floor(terms, 1.0);
        self.dark.clear();
        self.dark.resize(groups, 0);
        let mut traced = 0;
        let mut cycles = 0;
        if clear.cmpne(floor).any() {
            let [xs, ys, dx, dy, dz] = &mut self.samples;
            for column in [&mut *dx, &mut *dy, &mut *dz] {
                column.resize(groups * 16, 0.0);
            }
            let normal = spawn.normal();
            let tangents = Onb::from_normal(normal.into());
            let (tu, tv) = (Vec3A::from(tangents.u), Vec3A::from(tangents.v));
            let k = |x: f32| Avx512(_mm512_set1_ps(x));
            // Directions, quadrants and their counts.
            self.groups.clear();
            let mut count = [0u32; 4];
            for g in 0..groups {
                let at = g * 16;
                // SAFETY (this block): the CPU has AVX-512F; the loads and stores are of
                // sixteen floats within the columns, which hold whole groups.
                let masks = unsafe {
                    let local = cosine_hemisphere16(
                        _mm512_loadu_ps(xs[at..at + 16].as_ptr()),
                        _mm512_loadu_ps(ys[at..at + 16].as_ptr()),
                    );
                    let d = to_world(frame, local.map(Avx512));
                    for (column, lanes) in [&mut *dx, &mut *dy, &mut *dz].into_iter().zip(d) {
                        _mm512_storeu_ps(column[at..at + 16].as_mut_ptr(), lanes.0);
                    }
                    let valid = (1u32 << (n - at).min(16)) - 1;
                    let negative = [Avx512::bits(along(&d, tu).lt(k(0.0))), Avx512::bits(along(&d, tv).lt(k(0.0)))];
                    quadrant_lanes(valid, negative)
                };
                for (count, lanes) in count.iter_mut().zip(masks) {
                    *count += lanes.count_ones();
                }
                self.groups.push(masks);
            }
            let mut cursor;
            (cursor, traced) = quadrant_starts(count);
            for column in &mut self.ray_dirs {
                column.resize(traced, 0.0);
            }
            self.ray_samples.resize(traced, 0);
            let iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
            for (g, masks) in self.groups.iter().enumerate() {
                let at = g * 16;
                for (cursor, &lanes) in cursor.iter_mut().zip(masks) {
                    if lanes == 0 {
                        continue;
                    }
                    let (m, to) = (lanes as __mmask16, *cursor as usize);
                    let keep = ((1u32 << lanes.count_ones()) - 1) as __mmask16;
                    // SAFETY (this block): the CPU has AVX-512F; the loads read one group of
                    // the sample columns and the masked stores write the quadrant's next
                    // `lanes.count_ones()` entries, within the `traced` of each ray column.
                    unsafe {
                        for (from, to_column) in [&*dx, &*dy, &*dz].into_iter().zip(&mut self.ray_dirs) {
                            let lanes = _mm512_maskz_compress_ps(m, _mm512_loadu_ps(from[at..at + 16].as_ptr()));
                            _mm512_mask_storeu_ps(to_column[to..].as_mut_ptr(), keep, lanes);
                        }
                        let index =
                            _mm512_maskz_compress_epi32(m, _mm512_add_epi32(iota, _mm512_set1_epi32(at as i32)));
                        _mm512_mask_storeu_epi32(self.ray_samples[to..].as_mut_ptr().cast(), keep, index);
                    }
                    *cursor += lanes.count_ones();
                }
            }
            // Packets of sixteen consecutive rays, as `RayOrder::Grouped` cuts them, each
            // query timed (when timing) as `DirectionRays::trace` times the whole call.
            stack.clear();
            for p in (0..traced).step_by(16) {
                let live = (1u32 << (traced - p).min(16)) - 1;
                // SAFETY: the CPU has AVX-512F; the masked loads read the packet's `live` rays
                // within the ray columns.
                let (hit, took) = unsafe {
                    let load = |c: &Vec<f32>| Avx512(_mm512_maskz_loadu_ps(live as __mmask16, c[p..].as_ptr()));
                    let d = [load(&self.ray_dirs[0]), load(&self.ray_dirs[1]), load(&self.ray_dirs[2])];
                    let lanes = spawned_lanes(d, spawn, terms.max_distance);
                    occluded_lanes(geometry, stack, &lanes, live, self.timing)
                };
                cycles += took;
                let mut each = hit;
                while each != 0 {
                    let j = self.ray_samples[p + each.trailing_zeros() as usize] as usize;
                    each &= each - 1;
                    self.dark[j / 16] |= 1 << (j % 16);
                }
            }
        }
        for (sums, &dark) in arriving.chunks_mut(16).zip(&self.dark) {
            // SAFETY: the CPU has AVX-512F.
            unsafe { add_clear_or_floor::<Avx512>(clear, floor, dark, sums) };
        }
        (traced as u64, cycles)
    }

    /// [`DirectionRays::add_cosine`] for runs of whole passes of quadrant patterns: each
    /// pass's n samples traced `L::WIDTH` slots at a time in the pattern's quadrant order
    /// ([`QuadrantPattern`]), so every packet is rays into one quarter of the hemisphere around
    /// the shading normal (n/4 ≥ `L::WIDTH`), their local directions loaded from the table
    /// ([`CosineTable`]) in that order, with no columns written and no sort; then each sample's
    /// answer is read back by its slot, in sample order, or, for a sum, the blocked ones
    /// counted. Each sample gets the same ray, answer and light as in [`DirectionRays::add`].
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn add_cosine_quadrants<L: PassLanes>(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        frame: &Onb,
        QuadrantPasses { cmj, table, n, passes }: QuadrantPasses<impl Iterator<Item = u32>>,
        terms: &DirectionTerms,
        mut out: QuadrantOut,
    ) -> (u64, u64) {
        // Every sample has weight 1: one clear value and one floor for all.
        let (clear, floor) = clear_and_floor(terms, 1.0);
        let tracing = clear.cmpne(floor).any();
        let (mut traced, mut cycles, mut dark) = (0, 0, 0);
        let all = (1u32 << L::WIDTH) - 1;
        stack.clear();
        for (pass, p) in passes.enumerate() {
            // Bit t % 16 of entry t / 16: slot t is blocked.
            let mut blocked = [0u32; 16];
            if tracing {
                for (packet, local) in table.pattern(p).chunks_exact(3 * L::WIDTH).enumerate() {
                    // SAFETY (every block below): the caller's CPU has `L`'s instruction set.
                    let (hit, took) = unsafe {
                        let local = [0, 1, 2].map(|axis| L::load(&local[axis * L::WIDTH..]));
                        let lanes = spawned_lanes(to_world(frame, local), spawn, terms.max_distance);
                        occluded_lanes(geometry, stack, &lanes, all, self.timing)
                    };
                    cycles += took;
                    let slot = packet * L::WIDTH;
                    blocked[slot / 16] |= hit << (slot % 16);
                }
                traced += n;
            }
            let QuadrantOut::Each(arriving) = &mut out else {
                dark += blocked.iter().map(|b| b.count_ones()).sum::<u32>();
                continue;
            };
            let pattern = unsafe { QuadrantPattern::<L::Grid>::new(cmj, p) };
            for (group, sums) in arriving[pass * n..][..n].chunks_mut(L::WIDTH).enumerate() {
                unsafe { add_clear_or_floor::<L>(clear, floor, pattern.marked(group, &blocked), sums) };
            }
        }
        if let QuadrantOut::Sum(samples, sum) = out {
            // Whole numbers of samples (at most 2²⁴): exact as floats.
            *sum += clear * (samples as u32 - dark) as f32 + floor * dark as f32;
        }
        (traced as u64, cycles)
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

    /// [`DirectionRays::add`] for sixteen-lane packets.
    ///
    /// # Safety
    /// The CPU must have AVX-512F and POPCNT ([`crate::simd::avx512`]).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn add_avx512(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        run: &DirectionRun,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> (u64, u64) {
        // SAFETY: this function is compiled for AVX-512F, which the caller's CPU has.
        unsafe { self.add_lanes::<Avx512>(geometry, stack, spawn, run, terms, arriving) }
    }

    /// [`DirectionRays::add`] for eight-lane packets.
    ///
    /// # Safety
    /// The CPU must have AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    unsafe fn add_avx(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        run: &DirectionRun,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> (u64, u64) {
        // SAFETY: this function is compiled for AVX, which the caller's CPU has.
        unsafe { self.add_lanes::<Avx>(geometry, stack, spawn, run, terms, arriving) }
    }

    /// [`DirectionRays::add`] `L::WIDTH` samples at a time: which need a ray and their
    /// quadrants around the surface normal by mask arithmetic, their rays made in lanes and
    /// transposed into place quadrant by quadrant, the answers added back without a branch
    /// (whether a ray is blocked is as good as random).
    ///
    /// A packet of rays from one point into one quarter of the hemisphere (a wedge around the
    /// normal) stays together deeper than one from the world octants, whose pieces of a
    /// hemisphere can be thin slivers, and fewer of its rays go on alone. Trace system at 64
    /// spp against octants, fastest / median of nine (three copies of each binary): cornell
    /// −8 % / −9 %, many_spheres −2 % / −3 %, Sponza −2 % / −3 %, sphere_plane −3 % / −1 %, the
    /// dragon −1 % / +1 %.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn add_lanes<L: Lanes>(
        &mut self,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        run: &DirectionRun,
        terms: &DirectionTerms,
        arriving: &mut [Vec3A],
    ) -> (u64, u64) {
        let n = arriving.len();
        let width = L::WIDTH;
        let groups = n.div_ceil(width);
        let floor = Vec3A::from(terms.radiance * terms.floor);
        // SAFETY (every block below): the caller's CPU has `L`'s instruction set.
        let zero = unsafe { L::splat(0.0) };
        // Which lanes need a ray (a positive weight whose clear value differs from the floor),
        // their quadrants counted.
        self.groups.clear();
        let normal = spawn.normal();
        let tangents = Onb::from_normal(normal.into());
        let (u, v) = (Vec3A::from(tangents.u), Vec3A::from(tangents.v));
        let mut count = [0u32; 4];
        for g in 0..groups {
            let masks = unsafe {
                let (w, c) = clear_lanes::<L>(run, terms, g);
                let [x, y, z] = dir_lanes::<L>(run, g);
                let differs = L::bits(c[0].ne(L::splat(floor.x)))
                    | L::bits(c[1].ne(L::splat(floor.y)))
                    | L::bits(c[2].ne(L::splat(floor.z)));
                let valid = (1u32 << (n - g * width).min(width)) - 1;
                let negative = [L::bits(along(&[x, y, z], u).lt(zero)), L::bits(along(&[x, y, z], v).lt(zero))];
                quadrant_lanes(L::bits(w.gt(zero)) & differs & valid, negative)
            };
            for (count, lanes) in count.iter_mut().zip(masks) {
                *count += lanes.count_ones();
            }
            self.groups.push(masks);
        }
        let (mut cursor, traced) = quadrant_starts(count);
        let (front, back) = spawn.sides();
        // Room for the rays and one more, where lanes without a ray write theirs. Every ray
        // below is written before it is read, so the buffer is never cleared.
        if self.rays.len() <= traced {
            self.rays.resize(traced + 1, Ray::new(front, Vec3A::X, 0.0));
        }
        self.slots.resize(groups * width, 0);
        for (g, masks) in self.groups.iter().enumerate() {
            if masks.iter().all(|&m| m == 0) {
                self.slots[g * width..(g + 1) * width].fill(traced as u32);
                continue;
            }
            // Each lane's place: its quadrant's next, counting the lanes before it in that
            // quadrant, or past the rays for none.
            let at = unsafe { L::places(masks, &cursor, traced as u32) };
            for (cursor, lanes) in cursor.iter_mut().zip(masks) {
                *cursor += lanes.count_ones();
            }
            unsafe {
                let [x, y, z] = dir_lanes::<L>(run, g);
                // Behind the surface: the same products and sums as `SpawnOrigins::towards`.
                let behind = along(&[x, y, z], normal).lt(zero);
                let one = L::splat(1.0);
                let lanes = RayLanes {
                    origin: [
                        L::splat(front.x).select(behind, L::splat(back.x)),
                        L::splat(front.y).select(behind, L::splat(back.y)),
                        L::splat(front.z).select(behind, L::splat(back.z)),
                    ],
                    dir: [x, y, z],
                    inv_dir: [one.div(x), one.div(y), one.div(z)],
                    tmax: L::splat(terms.max_distance),
                };
                L::write_rays(&lanes, &mut self.rays, &at);
            }
            self.slots[g * width..(g + 1) * width].copy_from_slice(&at[..width]);
        }
        let cycles = self.trace(geometry, stack, traced, RayOrder::Grouped);
        for (g, sums) in arriving.chunks_mut(width).enumerate() {
            // Dark lanes get the floor: blocked ones (read without a branch: whether a ray is
            // blocked is as good as random), and those of weight ≤ 0 (no ray).
            let mut dark = 0;
            for (k, &slot) in self.slots[g * width..g * width + sums.len()].iter().enumerate() {
                dark |= u32::from(self.blocked[slot as usize]) << k;
            }
            unsafe {
                let (w, c) = clear_lanes::<L>(run, terms, g);
                let dark = L::mask(dark | L::bits(w.le(zero)));
                let x = c[0].select(dark, L::splat(floor.x));
                let y = c[1].select(dark, L::splat(floor.y));
                let z = c[2].select(dark, L::splat(floor.z));
                add_group(x, y, z, sums);
            }
        }
        (traced as u64, cycles)
    }
}

/// Adds each lane's x, y and z to its sample's sum in `sums`, one group of at most `L::WIDTH`
/// samples (lanes past its end are dropped).
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn add_group<L: Lanes>(x: L, y: L, z: L, sums: &mut [Vec3A]) {
    // SAFETY (both blocks): the caller's CPU has `L`'s instruction set.
    if sums.len() == L::WIDTH {
        unsafe { L::add_to(x, y, z, sums) };
    } else {
        // −0 + v is v, bit for bit, for every v.
        let mut full = [Vec3A::splat(-0.0); 16];
        unsafe { L::add_to(x, y, z, &mut full) };
        for (sum, add) in sums.iter_mut().zip(full) {
            *sum += add;
        }
    }
}

/// Adds `clear` to each sample of `sums` (at most `L::WIDTH`) whose bit in `dark` is clear,
/// and `floor` to the others.
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn add_clear_or_floor<L: Lanes>(clear: Vec3A, floor: Vec3A, dark: u32, sums: &mut [Vec3A]) {
    // SAFETY: the caller's CPU has `L`'s instruction set.
    unsafe {
        let dark = L::mask(dark);
        let pick = |c: f32, f: f32| L::splat(c).select(dark, L::splat(f));
        add_group(pick(clear.x, floor.x), pick(clear.y, floor.y), pick(clear.z, floor.z), sums);
    }
}

/// Lanes that trace whole passes of quadrant patterns
/// ([`DirectionRays::add_cosine_quadrants`]): their pattern grid, cosine map and scene query.
/// Every method needs the lanes' instruction set.
#[cfg(target_arch = "x86_64")]
trait PassLanes: Lanes {
    /// The pattern grid of this width.
    type Grid: GridLanes;
    /// [`SceneGeometry::occluded_lanes16`] or its eight-lane twin.
    unsafe fn occluded(
        geometry: &SceneGeometry,
        lanes: &RayLanes<Self>,
        ray: impl Fn(usize) -> Ray,
        live: u32,
        stack: &mut Vec<(u32, f32)>,
    ) -> u32;
    /// [`DirectionRays::add_cosine_quadrants`] in these lanes, compiled for their instruction
    /// set.
    #[allow(clippy::too_many_arguments)]
    unsafe fn add_quadrants(
        rays: &mut DirectionRays,
        geometry: &SceneGeometry,
        stack: &mut Vec<(u32, f32)>,
        spawn: &SpawnOrigins,
        frame: &Onb,
        passes: QuadrantPasses<impl Iterator<Item = u32>>,
        terms: &DirectionTerms,
        out: QuadrantOut,
    ) -> (u64, u64);
}

/// [`PassLanes`] for one lane type: its grid, its instruction set, its cosine map and its
/// scene query.
#[cfg(target_arch = "x86_64")]
macro_rules! pass_lanes {
    ($lanes:ident, $grid:ty, $feature:literal, $occluded:ident) => {
        impl PassLanes for $lanes {
            type Grid = $grid;
            #[target_feature(enable = $feature)]
            #[inline]
            unsafe fn occluded(
                geometry: &SceneGeometry,
                lanes: &RayLanes<Self>,
                ray: impl Fn(usize) -> Ray,
                live: u32,
                stack: &mut Vec<(u32, f32)>,
            ) -> u32 {
                geometry.$occluded(lanes, ray, live, stack)
            }
            #[target_feature(enable = $feature)]
            #[allow(clippy::too_many_arguments)]
            unsafe fn add_quadrants(
                rays: &mut DirectionRays,
                geometry: &SceneGeometry,
                stack: &mut Vec<(u32, f32)>,
                spawn: &SpawnOrigins,
                frame: &Onb,
                passes: QuadrantPasses<impl Iterator<Item = u32>>,
                terms: &DirectionTerms,
                out: QuadrantOut,
            ) -> (u64, u64) {
                // SAFETY: this function is compiled for the lanes' instruction set.
                unsafe { rays.add_cosine_quadrants::<Self>(geometry, stack, spawn, frame, passes, terms, out) }
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
pass_lanes!(Avx512, SmallGrid16, "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt", occluded_lanes16);
#[cfg(target_arch = "x86_64")]
pass_lanes!(Avx, SmallGrid8, "avx2,fma,bmi1,bmi2,lzcnt,popcnt", occluded_lanes8);

/// Local directions (x, y and z lanes) in `frame`, in world space: `u·x + v·y + w·z`,
/// component by component (the frame's `to_world`).
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn to_world<L: Lanes>(frame: &Onb, [x, y, z]: [L; 3]) -> [L; 3] {
    let (u, v, w) = (frame.u, frame.v, frame.w);
    // SAFETY: the caller's CPU has `L`'s instruction set.
    let world = |a: usize| unsafe { L::splat(u[a]).mul(x).add(L::splat(v[a]).mul(y)).add(L::splat(w[a]).mul(z)) };
    [world(0), world(1), world(2)]
}

/// Shadow rays along `d` (x, y and z lanes) leaving `spawn`, each from the side of the surface
/// its direction points to (the same products and sums as `SpawnOrigins::towards`), up to
/// `tmax`.
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn spawned_lanes<L: Lanes>(d: [L; 3], spawn: &SpawnOrigins, tmax: f32) -> RayLanes<L> {
    let (front, back) = spawn.sides();
    // SAFETY: the caller's CPU has `L`'s instruction set.
    unsafe {
        let k = |x: f32| L::splat(x);
        let behind = along(&d, spawn.normal()).lt(k(0.0));
        let one = k(1.0);
        RayLanes {
            origin: [
                k(front.x).select(behind, k(back.x)),
                k(front.y).select(behind, k(back.y)),
                k(front.z).select(behind, k(back.z)),
            ],
            dir: d,
            inv_dir: [one.div(d[0]), one.div(d[1]), one.div(d[2])],
            tmax: k(tmax),
        }
    }
}

/// The lanes of `live` whose ray in `lanes` something in `geometry` blocks, and the cycles
/// the query took ([`cycle_count`]) when `timing` (0 otherwise).
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn occluded_lanes<L: PassLanes>(
    geometry: &SceneGeometry,
    stack: &mut Vec<(u32, f32)>,
    lanes: &RayLanes<L>,
    live: u32,
    timing: bool,
) -> (u32, u64) {
    // A lane's ray, for rays that go on alone and tests that take one ray, read from the lanes
    // where they lie: writing all the rays out by a transpose (as the general path does) took
    // back all that this path saves on cornell (counter cycles, eight rounds, sixteen lanes),
    // and a copy of the lanes as rows of sixteen floats, zeroed first, cost sphere_plane and
    // cornell 5 % of the AO kernel, Sponza 2 %.
    let [ox, oy, oz] = &lanes.origin;
    let [dx, dy, dz] = &lanes.dir;
    let [ix, iy, iz] = &lanes.inv_dir;
    let ray = |j: usize| Ray {
        origin: Vec3A::new(ox.lane(j), oy.lane(j), oz.lane(j)),
        dir: Vec3A::new(dx.lane(j), dy.lane(j), dz.lane(j)),
        inv_dir: Vec3A::new(ix.lane(j), iy.lane(j), iz.lane(j)),
        tmax: lanes.tmax.lane(j),
    };
    let start = timing.then(cycle_count);
    // SAFETY: the caller's CPU has `L`'s instruction set.
    let hit = unsafe { L::occluded(geometry, lanes, ray, live, stack) };
    (hit, start.map_or(0, cycles_since))
}

/// Group `g`'s weights, and the light each lane brings when clear, per channel: the lanes of
/// [`clear_and_floor`].
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn clear_lanes<L: Lanes>(run: &DirectionRun, terms: &DirectionTerms, g: usize) -> (L, [L; 3]) {
    let (radiance, f) = (terms.radiance, terms.floor);
    // SAFETY: the caller's CPU has `L`'s instruction set.
    unsafe {
        let w = L::load(&run.weight[g * L::WIDTH..]);
        let s = L::splat(f).add(L::splat(1.0 - f).mul(w));
        (w, [L::splat(radiance.x).mul(s), L::splat(radiance.y).mul(s), L::splat(radiance.z).mul(s)])
    }
}

/// Each lane's component of direction `d` (x, y and z lanes) along `t`: `x·t.x + y·t.y + z·t.z`,
/// summed in that order.
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn along<L: Lanes>(d: &[L; 3], t: Vec3A) -> L {
    let [x, y, z] = *d;
    // SAFETY: the caller's CPU has `L`'s instruction set.
    unsafe { x.mul(L::splat(t.x)).add(y.mul(L::splat(t.y))).add(z.mul(L::splat(t.z))) }
}

/// Group `g`'s directions: x, y and z lanes.
///
/// # Safety
/// The CPU must have `L`'s instruction set.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn dir_lanes<L: Lanes>(run: &DirectionRun, g: usize) -> [L; 3] {
    let at = g * L::WIDTH;
    // SAFETY: the caller's CPU has `L`'s instruction set.
    unsafe { [L::load(&run.x[at..]), L::load(&run.y[at..]), L::load(&run.z[at..])] }
}
