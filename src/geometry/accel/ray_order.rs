//! How a run of rays is cut into packets.

use glam::Vec3A;

use crate::geometry::ray::Ray;
#[cfg(target_arch = "x86_64")]
use crate::simd::Lanes;

/// How a run of rays given to [`SceneGeometry::occluded_many`] is ordered, which decides how it
/// is cut into packets. Either way every ray gets the answer of its own query.
///
/// [`SceneGeometry::occluded_many`]: super::SceneGeometry::occluded_many
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayOrder {
    /// Any order: within each block of 64, the rays are grouped by direction octant first.
    Mixed,
    /// Already grouped (rays that should travel together are consecutive, e.g. one point's
    /// rays quadrant by quadrant around its normal): packets are consecutive rays.
    Grouped,
}

/// Calls `trace(packet, live)` for packets of up to `L::WIDTH` of the `rays` not yet
/// `blocked`, and marks blocked the rays of the lanes it returns: by [`by_packets`] for
/// [`RayOrder::Mixed`], consecutive rays for [`RayOrder::Grouped`].
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(super) fn in_packets<L: Lanes>(
    rays: &[Ray],
    order: RayOrder,
    blocked: &mut [bool],
    mut trace: impl FnMut(&[Ray], u32) -> u32,
) {
    if order == RayOrder::Mixed {
        return by_packets::<L>(rays, blocked, trace);
    }
    for (packet, done) in rays.chunks(L::WIDTH).zip(blocked.chunks_mut(L::WIDTH)) {
        let live = done.iter().enumerate().fold(0, |live, (k, &b)| live | u32::from(!b) << k);
        if live == 0 {
            continue;
        }
        let mut hit = trace(packet, live);
        while hit != 0 {
            done[hit.trailing_zeros() as usize] = true;
            hit &= hit - 1;
        }
    }
}

/// Calls `trace(packet, live)` for packets of up to `L::WIDTH` of the `rays` not yet `blocked`, and
/// marks blocked the rays of the lanes it returns. Within each block of 64 consecutive rays, the
/// rays still to answer are grouped by the octant of their direction: a pixel's run leaves one
/// point, so a packet then holds rays from one point into one octant, which share more nodes.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn by_packets<L: Lanes>(rays: &[Ray], blocked: &mut [bool], mut trace: impl FnMut(&[Ray], u32) -> u32) {
    for (block, done) in rays.chunks(64).zip(blocked.chunks_mut(64)) {
        // A counting sort of the live rays' indices by octant (8 for rays already blocked).
        let mut octants = [8u8; 64];
        let mut start = [0u8; 10];
        for ((o, r), &b) in octants.iter_mut().zip(block).zip(done.iter()) {
            if !b {
                *o = r.inv_dir.cmplt(Vec3A::ZERO).bitmask() as u8;
            }
            start[*o as usize + 1] += 1;
        }
        for o in 1..10 {
            start[o] += start[o - 1];
        }
        let live = start[8] as usize;
        let mut index = [0u8; 64];
        for (k, &o) in octants[..block.len()].iter().enumerate() {
            index[start[o as usize] as usize] = k as u8;
            start[o as usize] += 1;
        }
        let mut packet = [block[0]; 16];
        for order in index[..live].chunks(L::WIDTH) {
            for (p, &k) in packet.iter_mut().zip(order) {
                *p = block[k as usize];
            }
            let mut hit = trace(&packet[..order.len()], (1 << order.len()) - 1);
            while hit != 0 {
                done[order[hit.trailing_zeros() as usize] as usize] = true;
                hit &= hit - 1;
            }
        }
    }
}
