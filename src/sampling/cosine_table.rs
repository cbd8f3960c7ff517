//! The cosine-weighted hemisphere directions of a pool of correlated multi-jittered patterns,
//! worked out once with the sample sets, in the order in which the occluder's quadrant packets
//! trace them ([`QuadrantPattern`]). A pass of AO rays then loads its local directions instead
//! of hashing, warping and taking two square roots for each: on this project's Zen 1 VM the
//! occluder took 7–8 % less time for it.

#[cfg(target_arch = "x86_64")]
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
use super::{
    cmj::{Cmj, QuadrantPattern},
    warp::cosine_hemisphere_lanes,
};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Kernel, SampleLanes};

/// The local cosine directions (around +z) of patterns `first, first + 1, …` (`count` of
/// them, wrapping) of a [`Cmj`] with quadrants ([`Cmj::has_quadrants`]), each pattern packet
/// by packet as its [`QuadrantPattern`] orders the slots for packets `lanes` wide: per packet,
/// its `lanes` x, then its y, then its z. Every direction has the bits that
/// [`cosine_hemisphere_lanes`] gives its sample's point.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Debug)]
pub(crate) struct CosineTable {
    lanes: usize,
    first: u32,
    count: u32,
    /// Floats per pattern: three per sample.
    per_pattern: usize,
    dirs: Vec<f32>,
}

#[cfg(target_arch = "x86_64")]
impl CosineTable {
    /// The table of `count` patterns from `first` for packets `lanes` wide: `None` where
    /// `cmj` has no quadrants, or for sixteen lanes where [`crate::simd::isa`] does not allow
    /// AVX-512 (eight lanes run anywhere, AVX2's or the portable ones). Patterns are filled in parallel, each on its own, so the table does not
    /// depend on the thread count.
    pub(crate) fn build(cmj: &Cmj, n: u32, first: u32, count: u32, lanes: usize) -> Option<Self> {
        let lanes_allowed = match lanes {
            16 => crate::simd::avx512(),
            8 => true,
            _ => false,
        };
        if !lanes_allowed {
            return None;
        }
        if !cmj.has_quadrants() {
            return None;
        }
        let per_pattern = 3 * n as usize;
        let mut dirs = vec![0.0; per_pattern * count as usize];
        dirs.par_chunks_mut(per_pattern).enumerate().for_each(|(i, out)| {
            let fill = FillPattern { cmj, p: first.wrapping_add(i as u32), out };
            crate::simd::run_in(lanes, fill);
        });
        Some(CosineTable { lanes, first, count, per_pattern, dirs })
    }

    /// The packet width the table is laid out for.
    pub(crate) fn lanes(&self) -> usize {
        self.lanes
    }

    /// Pattern `p`'s directions (three floats per sample, as laid out above); `p` must be one
    /// of the table's.
    #[inline(always)]
    pub(crate) fn pattern(&self, p: u32) -> &[f32] {
        let i = p.wrapping_sub(self.first);
        debug_assert!(i < self.count, "pattern {p} is not in the table");
        &self.dirs[i as usize * self.per_pattern..][..self.per_pattern]
    }

    /// Bytes held by the directions.
    pub(crate) fn memory_bytes(&self) -> usize {
        self.dirs.len() * size_of::<f32>()
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
                assert_eq!(table.memory_bytes(), 4 * 3 * n as usize * size_of::<f32>());
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
}
