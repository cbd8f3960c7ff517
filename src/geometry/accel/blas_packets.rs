//! A BLAS's packet queries: occlusion and closest hits of ray packets through one bottom-level
//! tree, written once over the lane type and compiled per instruction set by
//! [`Lanes::compiled`](crate::simd::Lanes::compiled).
//!
//! Each kernel below is one out-of-line copy per lane type (as a call between them was before
//! they were generic), and the closures they hand to the generic traversal are written inside
//! their `run`, which is inlined into that copy, with the token (`isa`) that lets it run. The
//! top level's kernels (`scene_packets`) hand the rays that reach an instance to these.

use super::{blas::Blas, ray_order::RayOrder, tree::OccludedEach};
#[cfg(target_arch = "x86_64")]
use super::{
    blas::PACKET_RUN,
    ray_order::in_packets,
    tree::{ClosestHit, Tree},
};
use crate::geometry::ray::Ray;
#[cfg(target_arch = "x86_64")]
use crate::geometry::{ray::Shear, shapes::Triangle};
#[cfg(target_arch = "x86_64")]
use crate::geometry::{
    tri4::RayTriPacket,
    wide_bvh::{Bvh8, FusedPacket, LaneHits, RayPacket},
};
#[cfg(target_arch = "x86_64")]
use crate::{
    geometry::lanes::{PacketLanes, RayLanes},
    simd::{FusedLanes, Kernel, packet_lanes, run_in},
};

impl Blas {
    /// [`Blas::occluded`] for each of `rays` not yet `blocked` (same length), in one call: in
    /// ray packets where the tree is eight-wide and holds triangle packets.
    pub(super) fn occluded_many(
        &self,
        rays: &[Ray],
        order: RayOrder,
        stack: &mut Vec<(u32, f32)>,
        blocked: &mut [bool],
    ) {
        #[cfg(target_arch = "x86_64")]
        if let Tree::Eight(tree, _) = &self.tree
            && !self.packets.is_empty()
            && rays.len() >= PACKET_RUN
        {
            let kernel = BlasPackets { blas: self, tree, rays, order, stack, blocked };
            // Packets are eight or sixteen wide where `simd::isa` allows them.
            return run_in(packet_lanes(), kernel).expect("eight or sixteen lanes");
        }
        // Without packets the order does not matter.
        let _ = order;
        self.tree.query(OccludedEach { target: self, rays, stack, blocked });
    }
}

/// Lane types the packet kernels run in: rays gathered into them, nodes tested by fused
/// multiply-adds.
#[cfg(target_arch = "x86_64")]
pub(crate) trait KernelLanes: PacketLanes + FusedLanes {}
#[cfg(target_arch = "x86_64")]
impl<L: PacketLanes + FusedLanes> KernelLanes for L {}

/// The closest hits of `rays` (one packet; lanes of `live`) in `tree`, `blas`'s eight-wide
/// tree, as instance `instance`, traced together and offered to `hits`: exactly what
/// [`Blas::closest`] finds, except that a second hit at exactly a lane's closest distance is
/// marked a tie. Returns the lanes whose subtree overflowed the packet's stack; trace those,
/// and the tied ones, alone.
#[cfg(target_arch = "x86_64")]
pub(super) struct BlasClosestLanes<'a> {
    pub(super) blas: &'a Blas,
    pub(super) tree: &'a Bvh8,
    pub(super) rays: &'a [Ray],
    pub(super) live: u32,
    pub(super) instance: u32,
    pub(super) hits: &'a mut LaneHits<ClosestHit>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes> Kernel<L> for BlasClosestLanes<'_> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let BlasClosestLanes { blas, tree, rays, live, instance, hits } = self;
        let in_lanes = L::rays(isa, rays);
        let packet = RayPacket::new(&in_lanes);
        let edges = RayTriPacket::new(&in_lanes);
        let mut e = [[0.0f32; 16]; 3];
        let mut distances = [0.0f32; 16];
        let leaf = |first: u32, count: u32, lanes: u32, hits: &mut LaneHits<ClosestHit>| {
            for packet in &blas.packets[first as usize..(first + count) as usize] {
                for (lane, &slot) in packet.slot.iter().enumerate() {
                    if slot == u32::MAX {
                        continue;
                    }
                    let classes = packet.edges_packet_with(lane, &edges, &mut e);
                    let mut crossing = (classes.pass | classes.exact) & lanes;
                    if crossing == 0 {
                        continue;
                    }
                    let tri = packet.triangle(lane);
                    // Where the lanes that passed meet the triangle's plane, worked out for all
                    // lanes at once, each with the scalar test's operations
                    // (`TrianglePlane::distance`).
                    let meets = if classes.pass & lanes != 0 {
                        let (t, meets) = edges.plane_distances(&tri.plane());
                        t.store(&mut distances);
                        meets
                    } else {
                        0
                    };
                    while crossing != 0 {
                        let k = crossing.trailing_zeros() as usize;
                        crossing &= crossing - 1;
                        // The scalar test's end, as the single-ray leaf finishes it: from the
                        // lane's own edge functions and plane distance where they passed (the
                        // values the scalar test computes), the whole scalar test where an edge
                        // function is zero or NaN.
                        let ray = hits.probe(rays, k);
                        let found = if classes.exact & (1 << k) != 0 {
                            tri.intersect(&ray, &Shear::new(ray.dir))
                        } else {
                            let t = || (meets & (1 << k) != 0).then_some(distances[k]);
                            Triangle::finish_at(t, ray.tmax, e[0][k], e[1][k], e[2][k])
                        };
                        if let Some((t, b1, b2)) = found {
                            hits.offer(k, t, (instance, slot, b1, b2));
                        }
                    }
                }
            }
        };
        let first = &rays[live.trailing_zeros() as usize];
        tree.closest_packet(L::node_test8(isa), &packet, first, live, hits, leaf)
    }
}

/// [`Blas::occluded_many`] by packets of consecutive rays (a pixel's shadow rays, which leave
/// one point), traversed together while at least four of them enter a node. Every ray gets
/// exactly the answer of its own traversal.
#[cfg(target_arch = "x86_64")]
struct BlasPackets<'a> {
    blas: &'a Blas,
    tree: &'a Bvh8,
    rays: &'a [Ray],
    order: RayOrder,
    stack: &'a mut Vec<(u32, f32)>,
    blocked: &'a mut [bool],
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes> Kernel<L> for BlasPackets<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let BlasPackets { blas, tree, rays, order, stack, blocked } = self;
        in_packets::<L>(rays, order, blocked, |rays, live| {
            L::compiled(isa, BlasLanes { blas, tree, rays, live, stack })
        });
    }
}

/// The lanes of `live` whose ray in `rays` (one packet) anything in `blas` blocks, the rays
/// traced together in `tree`, its eight-wide tree.
#[cfg(target_arch = "x86_64")]
struct BlasLanes<'a> {
    blas: &'a Blas,
    tree: &'a Bvh8,
    rays: &'a [Ray],
    live: u32,
    stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes> Kernel<L> for BlasLanes<'_> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let BlasLanes { blas, tree, rays, live, stack } = self;
        if live == 0 {
            return 0;
        }
        let in_lanes = L::rays(isa, rays);
        L::compiled(isa, BlasLanesOf { blas, tree, in_lanes: &in_lanes, ray: |k| rays[k], live, stack })
    }
}

/// The lanes of `live` whose ray anything in `blas` blocks, as [`BlasLanes`], for a packet
/// already in lanes (`in_lanes`); `ray(k)` gives lane k's ray, for rays that go on alone and
/// tests that take one ray.
#[cfg(target_arch = "x86_64")]
pub(super) struct BlasLanesOf<'a, L, F> {
    pub(super) blas: &'a Blas,
    pub(super) tree: &'a Bvh8,
    pub(super) in_lanes: &'a RayLanes<L>,
    pub(super) ray: F,
    pub(super) live: u32,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes, F: Fn(usize) -> Ray> Kernel<L> for BlasLanesOf<'_, L, F> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let BlasLanesOf { blas, tree, in_lanes, ray, live, stack } = self;
        // The packet starts at its entry node; where its segments' box overlaps no leaf,
        // nothing can block its rays, and nothing more is made.
        let Some(start) = tree.entry_node_of(L::node_test8(isa), in_lanes, live) else { return 0 };
        // Nodes are tested by fused multiply-adds at both widths ([`FusedPacket`]).
        let packet = FusedPacket::new(in_lanes, live);
        // The edge tests' constants, made when the packet first reaches a leaf.
        let mut edges = None;
        let leaf = |first, count, lanes: u32, _: &mut Vec<(u32, f32)>| {
            if lanes.count_ones() == 1 {
                let lane = lanes.trailing_zeros() as usize;
                return if blas.packets_block(L::node_test8(isa), first, count, &ray(lane)) { lanes } else { 0 };
            }
            if edges.is_none() {
                edges = Some(RayTriPacket::new(in_lanes));
            }
            let r = edges.as_ref().expect("made above");
            blas.packets_block_lanes(first, count, &ray, r, lanes)
        };
        let single = |node, lane: usize, stack: &mut Vec<(u32, f32)>| {
            L::compiled(isa, BlasLoneRay { blas, tree, node, ray: ray(lane), stack })
        };
        tree.occluded_packet(&packet, start, live, stack, leaf, single)
    }
}

/// Whether anything in `blas` blocks `ray`, a ray of a packet that goes on alone from `node` of
/// `tree`: a kernel of its own, as a closure is compiled for the instruction set of the function
/// it is written in (here none) where the compiler leaves it out of line.
#[cfg(target_arch = "x86_64")]
struct BlasLoneRay<'a> {
    blas: &'a Blas,
    tree: &'a Bvh8,
    node: u32,
    ray: Ray,
    stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: PacketLanes> Kernel<L> for BlasLoneRay<'_> {
    type Output = bool;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> bool {
        let BlasLoneRay { blas, tree, node, ray, stack } = self;
        let leaf = |first, count, _: &mut Vec<(u32, f32)>| blas.packets_block(L::node_test8(isa), first, count, &ray);
        tree.occluded_from_touch(L::node_test8(isa), node, &ray, stack, leaf, |first, count| {
            blas.prefetch_packets(first, count)
        })
    }
}
