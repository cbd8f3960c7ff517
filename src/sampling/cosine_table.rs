//! The cosine-weighted hemisphere directions of a pool of correlated multi-jittered patterns,
//! worked out once with the sample sets, in one of two orders. Where the occluder traces whole
//! passes of patterns that split into quadrants, in the order its quadrant packets trace them
//! ([`QuadrantPattern`]): a pass of AO rays then loads its local directions instead of hashing,
//! warping and taking two square roots for each (on this project's Zen 1 VM the occluder took
//! 7–8 % less time for it). Elsewhere (progressive frames and adaptive batches that take part of
//! a pass, sets of other sizes), in sample order: a run copies its samples' directions and
//! sorts them into quadrants itself, without computing the points. Whole passes of patterns
//! that do not split into quadrants (sets of 48, say) read theirs sorted by azimuth.

#[cfg(target_arch = "x86_64")]
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
use super::{
    cmj::{Cmj, QuadrantPattern},
    warp::cosine_hemisphere_lanes,
};
#[cfg(target_arch = "x86_64")]
use crate::geometry::huge_pages::vec_on_huge_pages;
#[cfg(target_arch = "x86_64")]
use crate::simd::{Kernel, SampleLanes};
#[cfg(target_arch = "x86_64")]
use glam::Vec2;

/// Which order a [`CosineTable`] keeps each pattern's directions in.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum TableOrder {
    /// Packet by packet as the pattern's [`QuadrantPattern`] orders the slots for packets
    /// `lanes` wide: per packet, its `lanes` x, then its y, then its z.
    Quadrants,
    /// Sample by sample as three columns: the pattern's n x, then its n y, then its n z.
    Samples,
    /// Sorted by azimuth: grouped by quadrant, (+x, +y), (−x, +y), (−x, −y), (+x, −y), and
    /// counter-clockwise within each, then cut into packets `lanes` wide as
    /// [`TableOrder::Quadrants`] lays them out, so that each packet is one wedge of azimuth; the
    /// last packet's lanes past the pattern's n hold (0, 0, 1). For whole passes of
    /// patterns without quadrants that fill more than one packet, whose packets then need no
    /// sort.
    Sorted,
}

/// The local cosine directions (around +z) of patterns `first, first + 1, …` (`count` of
/// them, wrapping) of a [`Cmj`], each pattern in the table's [`TableOrder`]. Every direction
/// has the bits that [`cosine_hemisphere_lanes`] gives its sample's point.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Debug)]
pub(crate) struct CosineTable {
    order: TableOrder,
    lanes: usize,
    first: u32,
    count: u32,
    /// Floats per pattern: three per sample (and per padding lane).
    per_pattern: usize,
    /// The patterns' directions from `dirs[start]`, the first float on a 64-byte boundary,
    /// so that a pattern of a multiple of sixteen samples starts a cache line (a hint: a clone's
    /// copy may not, and reads the same values).
    start: usize,
    dirs: Vec<f32>,
}

#[cfg(target_arch = "x86_64")]
impl CosineTable {
    /// The table of `count` patterns from `first` for packets `lanes` wide: `None` where
    /// `cmj` has no quadrants, or for sixteen lanes where [`crate::simd::isa`] does not allow
    /// AVX-512 (eight lanes run anywhere, AVX2's or the portable ones). Patterns are filled in parallel, each on its own, so the table does not
    /// depend on the thread count.
    pub(crate) fn build(cmj: &Cmj, n: u32, first: u32, count: u32, lanes: usize) -> Option<Self> {
        if !lanes_allowed(lanes) {
            return None;
        }
        if !cmj.has_quadrants() {
            return None;
        }
        Some(Self::filled(TableOrder::Quadrants, lanes, 3 * n as usize, first, count, |p, out| {
            crate::simd::run_in(lanes, FillPattern { cmj, p, out });
        }))
    }

    /// The table of `count` patterns from `first` of `n` ≤ [`CosineTable::MAX_SAMPLES`] points
    /// in sample order, for the runs in packets `lanes` wide that sort directions into
    /// quadrants themselves: `None` for sixteen lanes where [`crate::simd::isa`] does not allow
    /// AVX-512, and for other widths than eight and sixteen. Filled in parallel, each pattern on
    /// its own, as [`CosineTable::build`] fills.
    pub(crate) fn build_in_sample_order(cmj: &Cmj, n: u32, first: u32, count: u32, lanes: usize) -> Option<Self> {
        if !lanes_allowed(lanes) || n > Self::MAX_SAMPLES {
            return None;
        }
        Some(Self::filled(TableOrder::Samples, lanes, 3 * n as usize, first, count, |p, out| {
            crate::simd::run_in(lanes, FillSamples { cmj, p, out });
        }))
    }

    /// The table of `count` patterns from `first` of `n` ≤ [`CosineTable::MAX_SAMPLES`] points
    /// sorted by azimuth ([`TableOrder::Sorted`]) for packets `lanes` wide: `None` where `cmj`
    /// has quadrants (their own order is better), where a pattern fits one packet (its order
    /// does not matter, and a table in sample order is half the size or less), or for sixteen
    /// lanes where [`crate::simd::isa`] does not allow AVX-512. Filled in parallel, each
    /// pattern on its own, as [`CosineTable::build`] fills.
    pub(crate) fn build_sorted(cmj: &Cmj, n: u32, first: u32, count: u32, lanes: usize) -> Option<Self> {
        if !lanes_allowed(lanes) || cmj.has_quadrants() || n as usize <= lanes || n > Self::MAX_SAMPLES {
            return None;
        }
        let padded = (n as usize).next_multiple_of(lanes);
        Some(Self::filled(TableOrder::Sorted, lanes, 3 * padded, first, count, |p, out| {
            let mut samples = vec![0.0; 3 * n as usize];
            crate::simd::run_in(lanes, FillSamples { cmj, p, out: &mut samples });
            sort_by_azimuth(&samples, lanes, out);
        }))
    }

    /// A table of `count` patterns from `first`, each pattern's `per_pattern` floats written
    /// by `fill(pattern, out)`, in parallel, each pattern on its own, so the table does not
    /// depend on the thread count.
    fn filled(
        order: TableOrder,
        lanes: usize,
        per_pattern: usize,
        first: u32,
        count: u32,
        fill: impl Fn(u32, &mut [f32]) + Sync,
    ) -> Self {
        let len = per_pattern * count as usize;
        let (start, mut dirs) = aligned_floats(len);
        dirs[start..start + len]
            .par_chunks_exact_mut(per_pattern)
            .enumerate()
            .for_each(|(i, out)| fill(first.wrapping_add(i as u32), out));
        CosineTable { order, lanes, first, count, per_pattern, start, dirs }
    }

    /// Most points per pattern that a table in sample order is kept for: as many as the
    /// largest patterns with quadrants (12 MiB for 4096 patterns).
    pub(crate) const MAX_SAMPLES: u32 = 256;

    /// The order the directions are kept in.
    pub(crate) fn order(&self) -> TableOrder {
        self.order
    }

    /// The packet width the table is laid out for.
    pub(crate) fn lanes(&self) -> usize {
        self.lanes
    }

    /// Pattern `p`'s directions (three floats per sample, in the table's order); `p` must be
    /// one of the table's.
    #[inline(always)]
    pub(crate) fn pattern(&self, p: u32) -> &[f32] {
        let i = p.wrapping_sub(self.first);
        debug_assert!(i < self.count, "pattern {p} is not in the table");
        &self.dirs[self.start + i as usize * self.per_pattern..][..self.per_pattern]
    }

    /// Bytes held by the directions (with up to one cache line of alignment).
    pub(crate) fn memory_bytes(&self) -> usize {
        self.dirs.len() * size_of::<f32>()
    }
}

/// Whether packets `lanes` wide may be tabled for: eight lanes run anywhere (AVX2's or the
/// portable ones), sixteen where [`crate::simd::isa`] allows AVX-512.
#[cfg(target_arch = "x86_64")]
fn lanes_allowed(lanes: usize) -> bool {
    match lanes {
        16 => crate::simd::avx512(),
        8 => true,
        _ => false,
    }
}

/// `len` zeroed floats from index `start` of the vector returned, `dirs[start]` on a 64-byte
/// boundary, advised onto huge pages: runs read patterns all over the table, one TLB entry
/// per 2 MiB instead of per 4 KiB.
#[cfg(target_arch = "x86_64")]
fn aligned_floats(len: usize) -> (usize, Vec<f32>) {
    const LINE_FLOATS: usize = 16;
    let mut dirs = vec_on_huge_pages(len + LINE_FLOATS);
    dirs.resize(len + LINE_FLOATS, 0.0f32);
    let start = dirs.as_ptr().align_offset(64).min(LINE_FLOATS);
    (start, dirs)
}

/// Writes the directions `samples` (n x, then n y, then n z) to `out` in [`TableOrder::Sorted`]
/// for packets `lanes` wide: by [`quadrant`], then counter-clockwise within a quadrant (by the
/// sign of two directions' cross product, whose terms are exact in f64).
#[cfg(target_arch = "x86_64")]
fn sort_by_azimuth(samples: &[f32], lanes: usize, out: &mut [f32]) {
    let n = samples.len() / 3;
    let (xs, ys) = (&samples[..n], &samples[n..2 * n]);
    let mut order: Vec<(u8, usize)> = (0..n).map(|i| (quadrant(xs[i], ys[i]), i)).collect();
    // a comes first where b lies counter-clockwise of it: ax·by > ay·bx (the samples' distinct
    // azimuths leave no ties).
    let term = |u: f32, v: f32| f64::from(u) * f64::from(v);
    order.sort_unstable_by(|&(qa, a), &(qb, b)| {
        qa.cmp(&qb).then_with(|| term(xs[b], ys[a]).total_cmp(&term(xs[a], ys[b])))
    });
    for slot in 0..out.len() / 3 {
        let (packet, lane) = (slot / lanes, slot % lanes);
        let dir = order.get(slot).map_or([0.0, 0.0, 1.0], |&(_, i)| [xs[i], ys[i], samples[2 * n + i]]);
        for (axis, v) in dir.into_iter().enumerate() {
            out[packet * 3 * lanes + axis * lanes + lane] = v;
        }
    }
}

/// The quadrant of azimuth of a direction (its x and y), in counter-clockwise order: (+x, +y),
/// (−x, +y), (−x, −y), (+x, −y).
#[cfg(target_arch = "x86_64")]
fn quadrant(x: f32, y: f32) -> u8 {
    match (x < 0.0, y < 0.0) {
        (false, false) => 0,
        (true, false) => 1,
        (true, true) => 2,
        (false, true) => 3,
    }
}

/// Writes pattern `p`'s directions to `out`, packet by packet in the kernel's lanes.
#[cfg(target_arch = "x86_64")]
struct FillPattern<'a> {
    cmj: &'a Cmj,
    p: u32,
    out: &'a mut [f32],
}

#[cfg(target_arch = "x86_64")]
impl<L: SampleLanes> Kernel<L> for FillPattern<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let FillPattern { cmj, p, out } = self;
        let width = L::WIDTH;
        let pattern = QuadrantPattern::<L>::new(isa, cmj, p);
        for (packet, out) in out.chunks_exact_mut(3 * width).enumerate() {
            let (x, y) = pattern.points(packet);
            let dirs = cosine_hemisphere_lanes(x, y);
            for (axis, v) in dirs.into_iter().enumerate() {
                v.store(&mut out[axis * width..]);
            }
        }
    }
}

/// Writes pattern `p`'s directions to `out` in sample order: its n x, then its y, then its z.
#[cfg(target_arch = "x86_64")]
struct FillSamples<'a> {
    cmj: &'a Cmj,
    p: u32,
    out: &'a mut [f32],
}

#[cfg(target_arch = "x86_64")]
impl<L: SampleLanes> Kernel<L> for FillSamples<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let FillSamples { cmj, p, out } = self;
        let n = out.len() / 3;
        let width = L::WIDTH;
        // The points as columns padded to whole groups (as a run's columns are padded).
        let mut xs = vec![0.5; n.next_multiple_of(width)];
        let mut ys = xs.clone();
        if !cmj.fill_columns(0, p, &mut xs[..n], &mut ys[..n]) {
            let mut points = vec![Vec2::ZERO; n];
            cmj.fill(0, p, &mut points);
            for ((x, y), point) in xs.iter_mut().zip(ys.iter_mut()).zip(&points) {
                (*x, *y) = (point.x, point.y);
            }
        }
        let (dx, rest) = out.split_at_mut(n);
        let (dy, dz) = rest.split_at_mut(n);
        let mut group = [[0.0f32; 16]; 3];
        for at in (0..n).step_by(width) {
            let dirs = cosine_hemisphere_lanes(L::load(isa, &xs[at..]), L::load(isa, &ys[at..]));
            let len = (n - at).min(width);
            for ((v, column), store) in dirs.into_iter().zip([&mut *dx, &mut *dy, &mut *dz]).zip(&mut group) {
                v.store(&mut store[..]);
                column[at..at + len].copy_from_slice(&store[..len]);
            }
        }
    }
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use glam::Vec2;

    use super::*;
    use crate::sampling::warp::cosine_power_hemisphere;

    /// Each pattern's table holds, bit for bit and once each, the directions the scalar
    /// cosine map gives the pattern's samples ([`Cmj::sample`]), slot t in quarter t / (n/4)
    /// of the azimuth; for every width this CPU has, with pattern numbers that wrap.
    #[test]
    fn each_pattern_holds_its_samples_cosine_directions_quarter_by_quarter() {
        for n in [16u32, 64, 256] {
            let cmj = Cmj::new(n);
            for lanes in [8, 16] {
                let Some(table) = CosineTable::build(&cmj, n, u32::MAX - 1, 4, lanes) else {
                    let has = lanes == 8 || crate::simd::avx512();
                    assert!(!has, "n {n}: no table for {lanes} lanes");
                    continue;
                };
                assert_eq!(table.memory_bytes(), (4 * 3 * n as usize + 16) * size_of::<f32>());
                for p in [u32::MAX - 1, u32::MAX, 0, 1] {
                    let dirs = table.pattern(p);
                    let mut got = Vec::new();
                    for (packet, chunk) in dirs.chunks_exact(3 * lanes).enumerate() {
                        for k in 0..lanes {
                            let (x, y) = (chunk[k], chunk[lanes + k]);
                            let quarter = (packet * lanes + k) / (n as usize / 4);
                            let signs = [
                                (x >= 0.0, y >= 0.0),
                                (x <= 0.0, y >= 0.0),
                                (x <= 0.0, y <= 0.0),
                                (x >= 0.0, y <= 0.0),
                            ];
                            assert_eq!(
                                signs[quarter],
                                (true, true),
                                "n {n}, p {p}, {lanes} lanes: slot {k} of packet {packet}"
                            );
                            got.push([x, y, chunk[2 * lanes + k]].map(f32::to_bits));
                        }
                    }
                    let mut expected: Vec<[u32; 3]> = (0..n)
                        .map(|i| {
                            cosine_power_hemisphere(Vec2::from(cmj.sample(i, p)), 1.0).dir.to_array().map(f32::to_bits)
                        })
                        .collect();
                    got.sort_unstable();
                    expected.sort_unstable();
                    assert_eq!(got, expected, "n {n}, p {p}, {lanes} lanes");
                }
            }
        }
    }

    /// A table sorted by azimuth holds, bit for bit and once each, the directions the scalar
    /// cosine map gives a pattern's samples ([`Cmj::sample`]), quadrant by quadrant and in
    /// order of azimuth (`atan2`) within each, the last packet padded with (0, 0, 1); for
    /// sizes without quadrants, with a partial last packet or not, for every width this CPU
    /// has, with pattern numbers that wrap. Patterns with quadrants get none, nor do patterns
    /// that fit one packet.
    #[test]
    fn a_table_sorted_by_azimuth_holds_each_direction_once_in_azimuth_order() {
        for n in [1u32, 7, 24, 37, 48, 100, 64, 257] {
            let cmj = Cmj::new(n);
            for lanes in [8, 16] {
                let Some(table) = CosineTable::build_sorted(&cmj, n, u32::MAX - 1, 4, lanes) else {
                    let has = lanes == 8 || crate::simd::avx512();
                    let needs = !cmj.has_quadrants() && n as usize > lanes && n <= CosineTable::MAX_SAMPLES;
                    assert!(!has || !needs, "n {n}: no table");
                    continue;
                };
                assert!(!cmj.has_quadrants() && n as usize > lanes, "n {n}, {lanes} lanes: a table");
                assert_eq!(table.order(), TableOrder::Sorted);
                let padded = (n as usize).next_multiple_of(lanes);
                assert_eq!(table.memory_bytes(), (4 * 3 * padded + 16) * size_of::<f32>());
                for p in [u32::MAX - 1, u32::MAX, 0, 1] {
                    let mut expected: Vec<[u32; 3]> = (0..n)
                        .map(|i| {
                            cosine_power_hemisphere(Vec2::from(cmj.sample(i, p)), 1.0).dir.to_array().map(f32::to_bits)
                        })
                        .collect();
                    let dirs = table.pattern(p);
                    let slots: Vec<[f32; 3]> = (0..padded)
                        .map(|slot| {
                            let (packet, lane) = (slot / lanes, slot % lanes);
                            [0, 1, 2].map(|axis| dirs[packet * 3 * lanes + axis * lanes + lane])
                        })
                        .collect();
                    let (held, padding) = slots.split_at(n as usize);
                    assert!(padding.iter().all(|d| *d == [0.0, 0.0, 1.0]), "n {n}, p {p}, {lanes} lanes: padding");
                    let mut got: Vec<[u32; 3]> = held.iter().map(|d| d.map(f32::to_bits)).collect();
                    got.sort_unstable();
                    expected.sort_unstable();
                    assert_eq!(got, expected, "n {n}, p {p}, {lanes} lanes: the pattern's directions");
                    // Quadrant by quadrant, counter-clockwise within each.
                    let key = |d: &[f32; 3]| (quadrant(d[0], d[1]), f64::from(d[1]).atan2(f64::from(d[0])));
                    for (slot, pair) in held.windows(2).enumerate() {
                        let (a, b) = (key(&pair[0]), key(&pair[1]));
                        assert!(a.0 < b.0 || (a.0 == b.0 && a.1 <= b.1), "n {n}, p {p}, {lanes} lanes: slot {slot}");
                    }
                }
            }
        }
    }

    /// A table in sample order holds, bit for bit, the direction the scalar cosine map gives
    /// each sample ([`Cmj::sample`]) at its sample's place, for sizes with quadrants or not,
    /// with a partial last group of lanes or not, and pattern numbers that wrap, filled in
    /// eight lanes or sixteen; and is kept for patterns of at most [`CosineTable::MAX_SAMPLES`]
    /// points, for sixteen lanes where AVX-512 is allowed.
    #[test]
    fn a_table_in_sample_order_holds_each_sample_s_direction_in_its_place() {
        for (n, lanes) in [1u32, 7, 24, 48, 64, 100, 256, 257].into_iter().flat_map(|n| [(n, 8), (n, 16)]) {
            let cmj = Cmj::new(n);
            let Some(table) = CosineTable::build_in_sample_order(&cmj, n, u32::MAX - 1, 4, lanes) else {
                let sixteen_refused = lanes == 16 && !crate::simd::avx512();
                assert!(sixteen_refused || n > CosineTable::MAX_SAMPLES, "n {n}, {lanes} lanes: no table");
                continue;
            };
            assert!(n <= CosineTable::MAX_SAMPLES, "n {n}: a table");
            assert_eq!(table.order(), TableOrder::Samples);
            assert_eq!(table.memory_bytes(), (4 * 3 * n as usize + 16) * size_of::<f32>());
            assert_eq!(table.pattern(u32::MAX - 1).as_ptr().align_offset(64), 0, "n {n}: aligned");
            for p in [u32::MAX - 1, u32::MAX, 0, 1] {
                let dirs = table.pattern(p);
                let n = n as usize;
                for i in 0..n {
                    let got = [dirs[i], dirs[n + i], dirs[2 * n + i]].map(f32::to_bits);
                    let expected = cosine_power_hemisphere(Vec2::from(cmj.sample(i as u32, p)), 1.0).dir;
                    assert_eq!(got, expected.to_array().map(f32::to_bits), "n {n}, p {p}, sample {i}");
                }
            }
        }
    }
}
