//! The packet kernels: occlusion and closest hits of ray packets, written once over the lane
//! type and compiled per instruction set by [`Lanes::compiled`](crate::simd::Lanes::compiled).
//!
//! Each kernel below is one out-of-line copy per lane type (as a call between them was before
//! they were generic), and the closures they hand to the generic traversal are written inside
//! their `run`, which is inlined into that copy, with the token (`isa`) that lets it run.

use super::{
    blas::Blas,
    ray_order::{RayOrder, in_packets},
    scene::SceneGeometry,
    tlas::Instance,
    tree::{ClosestHit, Tree},
};
use crate::geometry::ray::{Ray, Shear};
#[cfg(target_arch = "x86_64")]
use crate::geometry::{
    tri4::RayTriPacket,
    wide_bvh::{Bvh8, FusedPacket, LaneHits, PACKET_MIN_LANES, RayPacket},
};
#[cfg(target_arch = "x86_64")]
use crate::{
    geometry::lanes::{PacketLanes, RayLanes},
    simd::{FusedLanes, Kernel},
};

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
                    let plane = tri.plane();
                    while crossing != 0 {
                        let k = crossing.trailing_zeros() as usize;
                        crossing &= crossing - 1;
                        // The scalar test's end, as the single-ray leaf finishes it: from the
                        // lane's own edge functions where they passed (the values the scalar
                        // test computes), the whole scalar test where one is zero or NaN.
                        let ray = hits.probe(rays, k);
                        let found = if classes.exact & (1 << k) != 0 {
                            tri.intersect(&ray, &Shear::new(ray.dir))
                        } else {
                            tri.finish_on(&plane, &ray, e[0][k], e[1][k], e[2][k])
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
pub(super) struct BlasPackets<'a> {
    pub(super) blas: &'a Blas,
    pub(super) tree: &'a Bvh8,
    pub(super) rays: &'a [Ray],
    pub(super) order: RayOrder,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) blocked: &'a mut [bool],
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
struct BlasLanesOf<'a, L, F> {
    blas: &'a Blas,
    tree: &'a Bvh8,
    in_lanes: &'a RayLanes<L>,
    ray: F,
    live: u32,
    stack: &'a mut Vec<(u32, f32)>,
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

/// The closest hits of `rays` (one packet; lanes of `live`) through the top-level tree `top`,
/// whose instances must all be in world space, traced together and offered to `hits`
/// (instance, slot, b1, b2): exactly what [`SceneGeometry::intersect`] finds before the planes,
/// except that a second hit at exactly a lane's closest distance (in another triangle or
/// instance) is marked a tie. An instance's BLAS of triangle packets takes the rays it gets as
/// a packet, any other BLAS each ray alone. Returns the lanes whose subtree overflowed a
/// packet's stack; trace those, and the tied ones, alone.
#[cfg(target_arch = "x86_64")]
pub(super) struct TopClosestLanes<'a> {
    pub(super) scene: &'a SceneGeometry,
    pub(super) top: &'a Bvh8,
    pub(super) rays: &'a [Ray],
    pub(super) live: u32,
    pub(super) hits: &'a mut LaneHits<ClosestHit>,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes> Kernel<L> for TopClosestLanes<'_> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let TopClosestLanes { scene, top, rays, live, hits, stack } = self;
        let mut overflow = 0u32;
        let leaf = |first: u32, count: u32, lanes: u32, hits: &mut LaneHits<ClosestHit>| {
            for i in first..first + count {
                let blas = &scene.blases[scene.instances[i as usize].blas as usize];
                match &blas.tree {
                    Tree::Eight(tree, _) if !blas.packets.is_empty() && lanes.count_ones() >= 2 => {
                        let kernel = BlasClosestLanes { blas, tree, rays, live: lanes, instance: i, hits };
                        overflow |= L::compiled(isa, kernel);
                    }
                    _ => {
                        let mut each = lanes;
                        while each != 0 {
                            let k = each.trailing_zeros() as usize;
                            each &= each - 1;
                            let mut ray = hits.probe(rays, k);
                            if let Some((slot, b1, b2)) = blas.closest(&mut ray, stack) {
                                hits.offer(k, ray.tmax, (i, slot, b1, b2));
                            }
                        }
                    }
                }
            }
        };
        let top_overflow = {
            let packet = RayPacket::new(&L::rays(isa, rays));
            top.closest_packet(L::node_test8(isa), &packet, &rays[live.trailing_zeros() as usize], live, hits, leaf)
        };
        overflow | top_overflow
    }
}

/// [`SceneGeometry::occluded_many`] through the top level by packets of consecutive rays, as
/// within one BLAS; an instance reached by at least [`PACKET_MIN_LANES`] of a packet's rays
/// gets them as one packet in its own frame.
#[cfg(target_arch = "x86_64")]
pub(super) struct TopPackets<'a> {
    pub(super) scene: &'a SceneGeometry,
    pub(super) top: &'a Bvh8,
    pub(super) rays: &'a [Ray],
    pub(super) order: RayOrder,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
    pub(super) blocked: &'a mut [bool],
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes> Kernel<L> for TopPackets<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self, isa: L::Isa) {
        let TopPackets { scene, top, rays, order, stack, blocked } = self;
        in_packets::<L>(rays, order, blocked, |rays, live| L::compiled(isa, TopRays { scene, top, rays, live, stack }));
    }
}

/// [`TopPacket`] of one packet of `rays` (lanes of `live`), gathered into lanes here: a kernel
/// of its own, as the gather's intrinsics inline only into code compiled for their set.
#[cfg(target_arch = "x86_64")]
struct TopRays<'a> {
    scene: &'a SceneGeometry,
    top: &'a Bvh8,
    rays: &'a [Ray],
    live: u32,
    stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes> Kernel<L> for TopRays<'_> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let TopRays { scene, top, rays, live, stack } = self;
        let lanes = L::rays(isa, rays);
        L::compiled(isa, TopPacket { scene, top, lanes: &lanes, ray: |k| rays[k], live, stack })
    }
}

/// The lanes of `live` whose ray anything blocks, for one packet of world-space rays in lanes
/// (`ray(k)` gives lane k's ray, for what takes rays one by one): each lane gets exactly the
/// answer [`SceneGeometry::occluded_many`] gives its ray, and the packet is traced as that call
/// traces a packet. Uses `stack` above its length.
#[cfg(target_arch = "x86_64")]
pub(crate) struct SceneLanes<'a, L, F> {
    pub(crate) scene: &'a SceneGeometry,
    pub(crate) lanes: &'a RayLanes<L>,
    pub(crate) ray: F,
    pub(crate) live: u32,
    pub(crate) stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes, F: Fn(usize) -> Ray> Kernel<L> for SceneLanes<'_, L, F> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let SceneLanes { scene, lanes, ray, live, stack } = self;
        let on_planes = if scene.planes.is_empty() {
            0
        } else {
            lanes_where(live, &ray, |r| scene.planes.iter().any(|p| p.intersect(r).is_some()))
        };
        let live = live & !on_planes;
        if live == 0 {
            return on_planes;
        }
        let traced = if let Some(blas) = &scene.world_blas {
            match &blas.tree {
                Tree::Eight(tree, _) if !blas.packets.is_empty() => {
                    L::compiled(isa, BlasLanesOf { blas, tree, in_lanes: lanes, ray: &ray, live, stack })
                }
                _ => lanes_where(live, &ray, |r| blas.occluded(r, stack)),
            }
        } else if let Tree::Eight(top, _) = &scene.top {
            L::compiled(isa, TopPacket { scene, top, lanes, ray: &ray, live, stack })
        } else {
            lanes_where(live, &ray, |r| scene.occluded(r, stack))
        };
        on_planes | traced
    }
}

/// The lanes of `live` whose ray anything blocks, for one packet of world-space rays in lanes
/// (`ray(k)` gives lane k's ray, for what takes rays one by one), traced together through the
/// top-level tree `top`.
#[cfg(target_arch = "x86_64")]
struct TopPacket<'a, L, F> {
    scene: &'a SceneGeometry,
    top: &'a Bvh8,
    lanes: &'a RayLanes<L>,
    ray: F,
    live: u32,
    stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes, F: Fn(usize) -> Ray> Kernel<L> for TopPacket<'_, L, F> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let TopPacket { scene, top, lanes, ray, live, stack } = self;
        let leaf = |first: u32, count: u32, entered: u32, stack: &mut Vec<(u32, f32)>| {
            let mut open = entered;
            for inst in &scene.instances[first as usize..(first + count) as usize] {
                let kernel = InstanceLanes { scene, inst, lanes, ray: &ray, entered: open, stack };
                open &= !L::compiled(isa, kernel);
                if open == 0 {
                    break;
                }
            }
            entered & !open
        };
        let single = |node, lane: usize, stack: &mut Vec<(u32, f32)>| {
            L::compiled(isa, TopLoneRay { scene, top, node, ray: ray(lane), stack })
        };
        let Some(start) = top.entry_node_of(L::node_test8(isa), lanes, live) else { return 0 };
        // The fused node test, as in a BLAS: cheaper than the plain one here, with the same
        // answers (the leaves decide).
        top.occluded_packet(&FusedPacket::new(lanes, live), start, live, stack, leaf, single)
    }
}

/// Whether anything blocks `ray`, a ray of a packet that goes on alone from `node` of the
/// top-level tree `top` (a kernel of its own, as [`BlasLoneRay`]).
#[cfg(target_arch = "x86_64")]
struct TopLoneRay<'a> {
    scene: &'a SceneGeometry,
    top: &'a Bvh8,
    node: u32,
    ray: Ray,
    stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: PacketLanes> Kernel<L> for TopLoneRay<'_> {
    type Output = bool;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> bool {
        let TopLoneRay { scene, top, node, ray, stack } = self;
        top.occluded_from(L::node_test8(isa), node, &ray, stack, |first, count, stack| {
            scene.instances_block(first, count, &ray, stack)
        })
    }
}

/// The lanes of `entered` whose ray (world space; in `lanes`, and `ray(k)` for lane k)
/// instance `inst` blocks: as one packet in the instance's frame (or the packet itself, for an
/// identity transform) where its BLAS takes packets and at least [`PACKET_MIN_LANES`] rays
/// reach it. Fewer would go on alone from the packet's first node after the packet's set-up
/// (its move into the instance's frame, box and constants) for nothing, so that few rays
/// trace faster one by one.
#[cfg(target_arch = "x86_64")]
struct InstanceLanes<'a, L, F> {
    scene: &'a SceneGeometry,
    inst: &'a Instance,
    lanes: &'a RayLanes<L>,
    ray: &'a F,
    entered: u32,
    stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes, F: Fn(usize) -> Ray> Kernel<L> for InstanceLanes<'_, L, F> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let InstanceLanes { scene, inst, lanes, ray, entered, stack } = self;
        let blas = &scene.blases[inst.blas as usize];
        let tree = match &blas.tree {
            Tree::Eight(tree, _) if !blas.packets.is_empty() && entered.count_ones() >= PACKET_MIN_LANES => tree,
            _ => return lanes_where(entered, ray, |r| scene.instance_blocks(inst, r, stack)),
        };
        if inst.identity {
            return L::compiled(isa, BlasLanesOf { blas, tree, in_lanes: lanes, ray, live: entered, stack });
        }
        let (local, live) = inst.local_lanes(lanes, entered);
        if live == 0 {
            return 0;
        }
        let ray = |k| local.ray(k);
        L::compiled(isa, BlasLanesOf { blas, tree, in_lanes: &local, ray, live, stack })
    }
}

/// The lanes of `lanes` whose ray (`ray(k)` for lane k) `blocks`, asked one ray at a time.
#[cfg(target_arch = "x86_64")]
#[inline]
fn lanes_where(lanes: u32, ray: &impl Fn(usize) -> Ray, mut blocks: impl FnMut(&Ray) -> bool) -> u32 {
    let (mut todo, mut hit) = (lanes, 0);
    while todo != 0 {
        let k = todo.trailing_zeros() as usize;
        todo &= todo - 1;
        if blocks(&ray(k)) {
            hit |= 1 << k;
        }
    }
    hit
}
