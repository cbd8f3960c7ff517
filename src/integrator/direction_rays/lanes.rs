//! Direction runs in SIMD lanes: which samples need a ray, their quadrants, their rays and the
//! answers added back, a vector of samples at a time.

use glam::Vec3A;

use super::{DirectionRays, QuadrantPasses, RunOut, first_lanes, quadrant_lanes, quadrant_starts};
#[cfg(target_arch = "x86_64")]
use crate::{
    geometry::{
        accel::{KernelLanes, SceneLanes},
        lanes::{PacketLanes, RayLanes},
    },
    simd::{Kernel, Lanes, SampleLanes, dot3},
};
use crate::{
    geometry::{
        accel::{RayOrder, SceneGeometry},
        hit::SpawnOrigins,
        ray::Ray,
    },
    light::{DirectionRun, DirectionTerms},
    math::Onb,
    stats::{cycle_count, cycles_since},
};

/// [`DirectionRays::add`] in packets, as a kernel over the lane type ([`DirectionRays::add_lanes`]).
pub(super) struct AddRun<'a> {
    pub(super) rays: &'a mut DirectionRays,
    pub(super) geometry: &'a SceneGeometry,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) spawn: &'a SpawnOrigins,
    pub(super) run: &'a DirectionRun,
    pub(super) terms: &'a DirectionTerms,
    pub(super) arriving: &'a mut [Vec3A],
}

impl<L: PacketLanes> Kernel<L> for AddRun<'_> {
    type Output = (u64, u64);
    #[inline(always)]
    fn run(self, isa: L::Isa) -> (u64, u64) {
        let AddRun { rays, geometry, stack, spawn, run, terms, arriving } = self;
        rays.add_lanes::<L>(isa, geometry, stack, spawn, run, terms, arriving)
    }
}

impl DirectionRays {
    /// [`DirectionRays::add`] `L::WIDTH` samples at a time: which need a ray and their
    /// quadrants around the surface normal by mask arithmetic, their rays made in lanes and
    /// transposed into place quadrant by quadrant, the answers added back without a branch
    /// (whether a ray is blocked is as good as random).
    ///
    /// A packet of rays from one point into one quarter of the hemisphere (a wedge around the
    /// normal) stays together deeper than one from the world octants, whose pieces of a
    /// hemisphere can be thin slivers, and fewer of its rays go on alone, which traces faster
    /// than packets by octant on every peer scene but the dragon (the same there).
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn add_lanes<L: PacketLanes>(
        &mut self,
        isa: L::Isa,
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
        let zero = L::splat(isa, 0.0);
        // Which lanes need a ray (a positive weight whose clear value differs from the floor),
        // their quadrants counted.
        self.groups.clear();
        let normal = spawn.normal();
        let tangents = Onb::from_normal(normal.into());
        let (u, v) = (Vec3A::from(tangents.u), Vec3A::from(tangents.v));
        let mut count = [0u32; 4];
        for g in 0..groups {
            let masks = {
                let (w, c) = clear_lanes::<L>(isa, run, terms, g);
                let [x, y, z] = dir_lanes::<L>(isa, run, g);
                let differs = L::bits(c[0].ne(L::splat(isa, floor.x)))
                    | L::bits(c[1].ne(L::splat(isa, floor.y)))
                    | L::bits(c[2].ne(L::splat(isa, floor.z)));
                let valid = first_lanes(n - g * width, width);
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
            let at = L::places(isa, masks, &cursor, traced as u32);
            for (cursor, lanes) in cursor.iter_mut().zip(masks) {
                *cursor += lanes.count_ones();
            }
            let [x, y, z] = dir_lanes::<L>(isa, run, g);
            // Behind the surface: the same products and sums as `SpawnOrigins::towards`.
            let behind = along(&[x, y, z], normal).lt(zero);
            let one = L::splat(isa, 1.0);
            let lanes = RayLanes {
                origin: [
                    L::splat(isa, front.x).select(behind, L::splat(isa, back.x)),
                    L::splat(isa, front.y).select(behind, L::splat(isa, back.y)),
                    L::splat(isa, front.z).select(behind, L::splat(isa, back.z)),
                ],
                dir: [x, y, z],
                inv_dir: [one.div(x), one.div(y), one.div(z)],
                tmax: L::splat(isa, terms.max_distance),
            };
            L::write_rays(&lanes, &mut self.rays, &at);
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
            let (w, c) = clear_lanes::<L>(isa, run, terms, g);
            let dark = L::mask(isa, dark | L::bits(w.le(zero)));
            let x = c[0].select(dark, L::splat(isa, floor.x));
            let y = c[1].select(dark, L::splat(isa, floor.y));
            let z = c[2].select(dark, L::splat(isa, floor.z));
            add_group(x, y, z, sums);
        }
        (traced as u64, cycles)
    }
}

/// Adds each lane's x, y and z to its sample's sum in `sums`, one group of at most `L::WIDTH`
/// samples (lanes past its end are dropped).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn add_group<L: Lanes>(x: L, y: L, z: L, sums: &mut [Vec3A]) {
    if sums.len() == L::WIDTH {
        L::add_to(x, y, z, sums);
    } else {
        // −0 + v is v, bit for bit, for every v.
        let mut full = [Vec3A::splat(-0.0); 16];
        L::add_to(x, y, z, &mut full);
        for (sum, add) in sums.iter_mut().zip(full) {
            *sum += add;
        }
    }
}

/// Adds `clear` to each sample of `sums` (at most `L::WIDTH`) whose bit in `dark` is clear,
/// and `floor` to the others.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn add_clear_or_floor<L: Lanes>(isa: L::Isa, clear: Vec3A, floor: Vec3A, dark: u32, sums: &mut [Vec3A]) {
    let dark = L::mask(isa, dark);
    let pick = |c: f32, f: f32| L::splat(isa, c).select(dark, L::splat(isa, f));
    add_group(pick(clear.x, floor.x), pick(clear.y, floor.y), pick(clear.z, floor.z), sums);
}

/// Lanes that trace whole passes of quadrant patterns
/// ([`DirectionRays::add_cosine_quadrants`]): their pattern grid and cosine map
/// ([`SampleLanes`]) and the packet kernels' lanes ([`KernelLanes`]) for their scene query.
#[cfg(target_arch = "x86_64")]
pub(super) trait PassLanes: SampleLanes + KernelLanes {}

#[cfg(target_arch = "x86_64")]
impl<L: SampleLanes + KernelLanes> PassLanes for L {}

/// [`DirectionRays::add_cosine_quadrants`] as a kernel over the lane type.
#[cfg(target_arch = "x86_64")]
pub(super) struct QuadrantRun<'a, I> {
    pub(super) rays: &'a mut DirectionRays,
    pub(super) geometry: &'a SceneGeometry,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) spawn: &'a SpawnOrigins,
    pub(super) frame: &'a Onb,
    pub(super) passes: QuadrantPasses<'a, I>,
    pub(super) terms: &'a DirectionTerms,
    pub(super) out: RunOut<'a>,
}

#[cfg(target_arch = "x86_64")]
impl<L: PassLanes, I: Iterator<Item = u32>> Kernel<L> for QuadrantRun<'_, I> {
    type Output = (u64, u64);
    #[inline(always)]
    fn run(self, isa: L::Isa) -> (u64, u64) {
        let QuadrantRun { rays, geometry, stack, spawn, frame, passes, terms, out } = self;
        rays.add_cosine_quadrants::<L>(isa, geometry, stack, spawn, frame, passes, terms, out)
    }
}

/// Local directions (x, y and z lanes) in `frame`, in world space: `u·x + v·y + w·z`,
/// component by component (the frame's `to_world`).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn to_world<L: Lanes>(frame: &Onb, [x, y, z]: [L; 3]) -> [L; 3] {
    let (u, v, w) = (frame.u, frame.v, frame.w);
    let isa = x.isa();
    let world = |a: usize| dot3(&[L::splat(isa, u[a]), L::splat(isa, v[a]), L::splat(isa, w[a])], &[x, y, z]);
    [world(0), world(1), world(2)]
}

/// Shadow rays along `d` (x, y and z lanes) leaving `spawn`, each from the side of the surface
/// its direction points to (the same products and sums as `SpawnOrigins::towards`), up to
/// `tmax`.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn spawned_lanes<L: Lanes>(d: [L; 3], spawn: &SpawnOrigins, tmax: f32) -> RayLanes<L> {
    let (front, back) = spawn.sides();
    let isa = d[0].isa();
    let k = |x: f32| L::splat(isa, x);
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

/// The lanes of `live` whose ray in `lanes` something in `geometry` blocks, and the cycles
/// the query took ([`cycle_count`]) when `timing` (0 otherwise).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn occluded_lanes<L: PassLanes>(
    geometry: &SceneGeometry,
    stack: &mut Vec<(u32, f32)>,
    lanes: &RayLanes<L>,
    live: u32,
    timing: bool,
) -> (u32, u64) {
    // A lane's ray, for rays that go on alone and tests that take one ray, read from the lanes
    // where they lie: writing all the rays out by a transpose (as the general path does) took
    // back all that this path saves on cornell (counter cycles, eight rounds, sixteen lanes),
    // and a copy of the lanes as rows of sixteen floats, zeroed first, cost a measurable
    // share of the AO kernel.
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
    let hit = L::compiled(lanes.tmax.isa(), SceneLanes { scene: geometry, lanes, ray, live, stack });
    (hit, start.map_or(0, cycles_since))
}

/// Group `g`'s weights, and the light each lane brings when clear, per channel: the lanes of
/// [`clear_and_floor`](super::clear_and_floor).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn clear_lanes<L: Lanes>(isa: L::Isa, run: &DirectionRun, terms: &DirectionTerms, g: usize) -> (L, [L; 3]) {
    let (radiance, f) = (terms.radiance, terms.floor);
    let w = L::load(isa, &run.weight[g * L::WIDTH..]);
    let s = L::splat(isa, f).add(L::splat(isa, 1.0 - f).mul(w));
    (w, [L::splat(isa, radiance.x).mul(s), L::splat(isa, radiance.y).mul(s), L::splat(isa, radiance.z).mul(s)])
}

/// Each lane's component of direction `d` (x, y and z lanes) along `t`: `x·t.x + y·t.y + z·t.z`,
/// summed in that order.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn along<L: Lanes>(d: &[L; 3], t: Vec3A) -> L {
    let isa = d[0].isa();
    dot3(d, &[L::splat(isa, t.x), L::splat(isa, t.y), L::splat(isa, t.z)])
}

/// Group `g`'s directions: x, y and z lanes.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn dir_lanes<L: Lanes>(isa: L::Isa, run: &DirectionRun, g: usize) -> [L; 3] {
    let at = g * L::WIDTH;
    [L::load(isa, &run.x[at..]), L::load(isa, &run.y[at..]), L::load(isa, &run.z[at..])]
}
