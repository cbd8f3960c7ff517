//! The packet kernels: occlusion and closest hits of ray packets, per lane type.

use super::{
    blas::Blas,
    ray_order::{RayOrder, in_packets},
    scene::SceneGeometry,
    tlas::Instance,
    tree::Tree,
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
    simd::{Avx, Avx512, Lanes},
};

/// Rays per packet: sixteen where the CPU has AVX-512 (and `HEMI_NO_AVX512` is not `1`, see
/// [`crate::simd::isa`]), eight with AVX only.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) enum PacketWidth {
    Eight,
    Sixteen,
}

#[cfg(target_arch = "x86_64")]
impl PacketWidth {
    /// Rays per packet.
    pub(super) fn lanes(self) -> usize {
        match self {
            PacketWidth::Eight => 8,
            PacketWidth::Sixteen => 16,
        }
    }
}

/// A closest hit in a scene: (instance, primitive slot, b1, b2).
pub(super) type ClosestHit = (u32, u32, f32, f32);

/// Where [`SceneGeometry::intersect_many`] traces a packet.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
pub(super) enum CameraPackets<'a> {
    /// Straight into a static scene's one world-space BLAS of triangle packets, and its tree.
    World(&'a Blas, &'a Bvh8),
    /// Through the top level (every instance in world space).
    Top(&'a Bvh8),
}

/// The packet width this CPU and environment get.
#[cfg(target_arch = "x86_64")]
pub(super) fn packet_width() -> PacketWidth {
    if crate::simd::packet_lanes() == 16 { PacketWidth::Sixteen } else { PacketWidth::Eight }
}

/// Defines, for one lane type and the instruction set it needs, the packet kernels: for
/// occlusion, `Blas::$packets` and `SceneGeometry::$scene` (a run of rays by packets, within one
/// BLAS or through the top level) and the per-packet `Blas::$lanes` (with `$lanes_of`, for a
/// packet already in lanes), `SceneGeometry::$scene_packet` and `SceneGeometry::$instance` they
/// use; for closest hits, the per-packet `Blas::$closest`. Each is compiled for that
/// instruction set, and the closures they hand to the generic traversal are written inside them
/// so that they are compiled for it too (a closure gets the instruction set of the function it
/// is written in, and cannot be inlined into a function compiled for less: the kernels and the
/// one-pass cosine runs, whose closures they call per lone ray, all take the x86-64-v3 set
/// of [`crate::simd::avx2`] as well). Callers must make sure the CPU has the instruction set.
#[cfg(target_arch = "x86_64")]
macro_rules! packet_kernels {
    (
        $lanes_type:ty,
        $feature:literal,
        $packets:ident,
        $lanes:ident,
        $lanes_of:ident,
        $scene:ident,
        $scene_packet:ident,
        $instance:ident,
        $closest:ident,
        $closest_top:ident,
        $scene_lanes:ident
    ) => {
        impl Blas {
            /// The closest hits of `rays` (one packet; lanes of `live`) in `tree`, this BLAS's
            /// eight-wide tree, as instance `instance`, traced together and offered to `hits`:
            /// exactly what [`Blas::closest`] finds, except that a second hit at exactly a
            /// lane's closest distance is marked a tie. Returns the lanes whose subtree
            /// overflowed the packet's stack; trace those, and the tied ones, alone.
            #[target_feature(enable = $feature)]
            pub(super) fn $closest(
                &self,
                tree: &Bvh8,
                rays: &[Ray],
                live: u32,
                instance: u32,
                hits: &mut LaneHits<ClosestHit>,
            ) -> u32 {
                // SAFETY (all blocks below): this function is compiled for the lane type's
                // instruction set and AVX, which the caller's CPU has.
                let in_lanes = unsafe { <$lanes_type>::rays(rays) };
                let packet = unsafe { RayPacket::new(&in_lanes) };
                let edges = unsafe { RayTriPacket::new(&in_lanes) };
                let leaf = |first: u32, count: u32, lanes: u32, hits: &mut LaneHits<ClosestHit>| {
                    for packet in &self.packets[first as usize..(first + count) as usize] {
                        for (lane, &slot) in packet.slot.iter().enumerate() {
                            if slot == u32::MAX {
                                continue;
                            }
                            let e = unsafe { packet.edges_packet(lane, &edges) };
                            let mut crossing = (e.pass | e.exact) & lanes;
                            if crossing == 0 {
                                continue;
                            }
                            let tri = packet.triangle(lane);
                            while crossing != 0 {
                                let k = crossing.trailing_zeros() as usize;
                                crossing &= crossing - 1;
                                // The scalar test, as the single-ray leaf finishes it.
                                let ray = hits.probe(rays, k);
                                if let Some((t, b1, b2)) = tri.intersect(&ray, &Shear::new(ray.dir)) {
                                    hits.offer(k, t, (instance, slot, b1, b2));
                                }
                            }
                        }
                    }
                };
                let first = &rays[live.trailing_zeros() as usize];
                unsafe { tree.closest_packet(&packet, first, live, hits, leaf) }
            }

            /// [`Blas::occluded_many`] by packets of consecutive rays (a pixel's shadow rays,
            /// which leave one point), traversed together while at least four of them enter
            /// a node. Every ray gets exactly the answer of its own traversal.
            #[target_feature(enable = $feature)]
            pub(super) fn $packets(
                &self,
                tree: &Bvh8,
                rays: &[Ray],
                order: RayOrder,
                stack: &mut Vec<(u32, f32)>,
                blocked: &mut [bool],
            ) {
                in_packets::<$lanes_type>(rays, order, blocked, |packet, live| self.$lanes(tree, packet, live, stack));
            }

            /// The lanes of `live` whose ray in `rays` (one packet) anything in this BLAS
            /// blocks, the rays traced together in `tree`, this BLAS's eight-wide tree.
            #[target_feature(enable = $feature)]
            fn $lanes(&self, tree: &Bvh8, rays: &[Ray], live: u32, stack: &mut Vec<(u32, f32)>) -> u32 {
                if live == 0 {
                    return 0;
                }
                // SAFETY: this function is compiled for the lane type's instruction set and
                // AVX, which the caller's CPU has.
                let in_lanes = unsafe { <$lanes_type>::rays(rays) };
                self.$lanes_of(tree, &in_lanes, |k| rays[k], live, stack)
            }

            /// The lanes of `live` whose ray anything in this BLAS blocks, as above, for a
            /// packet already in lanes (`in_lanes`); `ray(k)` gives lane k's ray, for rays that
            /// go on alone and tests that take one ray.
            #[target_feature(enable = $feature)]
            fn $lanes_of(
                &self,
                tree: &Bvh8,
                in_lanes: &RayLanes<$lanes_type>,
                ray: impl Fn(usize) -> Ray,
                live: u32,
                stack: &mut Vec<(u32, f32)>,
            ) -> u32 {
                // SAFETY (all blocks below): this function is compiled for the lane type's
                // instruction set and AVX, which the caller's CPU has.
                // The packet starts at its entry node; where its segments' box overlaps no
                // leaf, nothing can block its rays, and nothing more is made.
                let Some(start) = (unsafe { tree.entry_node_of(in_lanes, live) }) else { return 0 };
                // Nodes are tested by fused multiply-adds at both widths ([`FusedPacket`]).
                let packet = unsafe { FusedPacket::new(in_lanes, live) };
                // The edge tests' constants, made when the packet first reaches a leaf.
                let mut edges = None;
                let leaf = |first, count, lanes: u32, _: &mut Vec<(u32, f32)>| {
                    if lanes.count_ones() == 1 {
                        let lane = lanes.trailing_zeros() as usize;
                        return if self.packets_block::<8>(first, count, &ray(lane)) { lanes } else { 0 };
                    }
                    if edges.is_none() {
                        edges = Some(unsafe { RayTriPacket::new(in_lanes) });
                    }
                    let r = edges.as_ref().expect("made above");
                    unsafe { self.packets_block_lanes(first, count, &ray, r, lanes) }
                };
                let single = |node, lane: usize, stack: &mut Vec<(u32, f32)>| {
                    let ray = ray(lane);
                    let leaf = |first, count, _: &mut Vec<(u32, f32)>| self.packets_block::<8>(first, count, &ray);
                    tree.occluded_from_touch(node, &ray, stack, leaf, |first, count| {
                        self.prefetch_packets(first, count)
                    })
                };
                unsafe { tree.occluded_packet(&packet, start, live, stack, leaf, single) }
            }
        }

        impl SceneGeometry {
            /// The closest hits of `rays` (one packet; lanes of `live`) through the top-level
            /// tree `top`, whose instances must all be in world space, traced together and
            /// offered to `hits` (instance, slot, b1, b2): exactly what
            /// [`SceneGeometry::intersect`] finds before the planes, except that a second hit
            /// at exactly a lane's closest distance (in another triangle or instance) is marked
            /// a tie. An instance's BLAS of triangle packets takes the rays it gets as a packet,
            /// any other BLAS each ray alone. Returns the lanes whose subtree overflowed a
            /// packet's stack; trace those, and the tied ones, alone.
            #[target_feature(enable = $feature)]
            pub(super) fn $closest_top(
                &self,
                top: &Bvh8,
                rays: &[Ray],
                live: u32,
                hits: &mut LaneHits<ClosestHit>,
                stack: &mut Vec<(u32, f32)>,
            ) -> u32 {
                let mut overflow = 0u32;
                let leaf = |first: u32, count: u32, lanes: u32, hits: &mut LaneHits<ClosestHit>| {
                    for i in first..first + count {
                        let blas = &self.blases[self.instances[i as usize].blas as usize];
                        match &blas.tree {
                            Tree::Eight(tree) if !blas.packets.is_empty() && lanes.count_ones() >= 2 => {
                                overflow |= blas.$closest(tree, rays, lanes, i, hits);
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
                // SAFETY: this function is compiled for the lane type's instruction set and
                // AVX, which the caller's CPU has.
                let top_overflow = unsafe {
                    let packet = RayPacket::new(&<$lanes_type>::rays(rays));
                    top.closest_packet(&packet, &rays[live.trailing_zeros() as usize], live, hits, leaf)
                };
                overflow | top_overflow
            }

            /// [`SceneGeometry::occluded_many`] through the top level by packets of consecutive
            /// rays, as within one BLAS; an instance reached by at least [`PACKET_MIN_LANES`] of
            /// a packet's rays gets them as one packet in its own frame.
            #[target_feature(enable = $feature)]
            pub(super) fn $scene(
                &self,
                top: &Bvh8,
                rays: &[Ray],
                order: RayOrder,
                stack: &mut Vec<(u32, f32)>,
                blocked: &mut [bool],
            ) {
                in_packets::<$lanes_type>(rays, order, blocked, |chunk, live| {
                    // SAFETY: this function is compiled for the lane type's instruction set.
                    let lanes = unsafe { <$lanes_type>::rays(chunk) };
                    self.$scene_packet(top, &lanes, |k| chunk[k], live, stack)
                });
            }

            /// The lanes of `live` whose ray anything blocks, for one packet of world-space
            /// rays in lanes (`ray(k)` gives lane k's ray, for what takes rays one by one):
            /// each lane gets exactly the answer [`SceneGeometry::occluded_many`] gives its
            /// ray, and the packet is traced as that call traces a packet. Uses `stack` above
            /// its length.
            #[target_feature(enable = $feature)]
            pub(crate) fn $scene_lanes(
                &self,
                lanes: &RayLanes<$lanes_type>,
                ray: impl Fn(usize) -> Ray,
                live: u32,
                stack: &mut Vec<(u32, f32)>,
            ) -> u32 {
                let on_planes = if self.planes.is_empty() {
                    0
                } else {
                    lanes_where(live, &ray, |r| self.planes.iter().any(|p| p.intersect(r).is_some()))
                };
                let live = live & !on_planes;
                if live == 0 {
                    return on_planes;
                }
                let traced = if let Some(blas) = &self.world_blas {
                    match &blas.tree {
                        Tree::Eight(tree) if !blas.packets.is_empty() => blas.$lanes_of(tree, lanes, &ray, live, stack),
                        _ => lanes_where(live, &ray, |r| blas.occluded(r, stack)),
                    }
                } else if let Tree::Eight(top) = &self.top {
                    self.$scene_packet(top, lanes, &ray, live, stack)
                } else {
                    lanes_where(live, &ray, |r| self.occluded(r, stack))
                };
                on_planes | traced
            }

            /// The lanes of `live` whose ray anything blocks, for one packet of world-space
            /// rays in lanes (`ray(k)` gives lane k's ray, for what takes rays one by one),
            /// traced together through the top-level tree `top`.
            #[target_feature(enable = $feature)]
            fn $scene_packet(
                &self,
                top: &Bvh8,
                lanes: &RayLanes<$lanes_type>,
                ray: impl Fn(usize) -> Ray,
                live: u32,
                stack: &mut Vec<(u32, f32)>,
            ) -> u32 {
                let leaf = |first: u32, count: u32, entered: u32, stack: &mut Vec<(u32, f32)>| {
                    let mut open = entered;
                    for inst in &self.instances[first as usize..(first + count) as usize] {
                        open &= !self.$instance(inst, lanes, &ray, open, stack);
                        if open == 0 {
                            break;
                        }
                    }
                    entered & !open
                };
                let single = |node, lane: usize, stack: &mut Vec<(u32, f32)>| {
                    let ray = ray(lane);
                    top.occluded_from(node, &ray, stack, |first, count, stack| {
                        self.instances_block(first, count, &ray, stack)
                    })
                };
                // SAFETY: this function is compiled for the lane type's instruction set and
                // AVX, which the caller's CPU has.
                unsafe {
                    let Some(start) = top.entry_node_of(lanes, live) else { return 0 };
                    // The fused node test, as in a BLAS: cheaper than the plain one here, with
                    // the same answers (the leaves decide).
                    top.occluded_packet(&FusedPacket::new(lanes, live), start, live, stack, leaf, single)
                }
            }

            /// The lanes of `entered` whose ray (world space; in `lanes`, and `ray(k)` for lane k)
            /// instance `inst` blocks: as one packet in the instance's frame (or the packet
            /// itself, for an identity transform) where its BLAS takes packets and at least
            /// [`PACKET_MIN_LANES`] rays reach it. Fewer would go on alone from the packet's first
            /// node after the packet's set-up (its transpose, box and constants) for nothing,
            /// so that few rays trace faster one by one.
            #[target_feature(enable = $feature)]
            fn $instance(
                &self,
                inst: &Instance,
                lanes: &RayLanes<$lanes_type>,
                ray: &impl Fn(usize) -> Ray,
                entered: u32,
                stack: &mut Vec<(u32, f32)>,
            ) -> u32 {
                let blas = &self.blases[inst.blas as usize];
                let tree = match &blas.tree {
                    Tree::Eight(tree) if !blas.packets.is_empty() && entered.count_ones() >= PACKET_MIN_LANES => tree,
                    _ => return lanes_where(entered, ray, |r| self.instance_blocks(inst, r, stack)),
                };
                if inst.identity {
                    return blas.$lanes_of(tree, lanes, ray, entered, stack);
                }
                // Lanes not traced keep a copy of a traced ray: they only fill the packet.
                let mut local = [ray(entered.trailing_zeros() as usize); <$lanes_type>::WIDTH];
                let mut live = 0;
                let mut each = entered;
                while each != 0 {
                    let k = each.trailing_zeros() as usize;
                    each &= each - 1;
                    if let Some((moved, _)) = inst.local_ray(&ray(k)) {
                        local[k] = moved;
                        live |= 1 << k;
                    }
                }
                blas.$lanes(tree, &local, live, stack)
            }
        }
    };
}

#[cfg(target_arch = "x86_64")]
packet_kernels!(
    Avx,
    "avx2,fma,bmi1,bmi2,lzcnt,popcnt",
    occluded_packets_avx,
    occluded_lanes_avx,
    occluded_lanes_of_avx,
    occluded_packets_avx,
    occluded_packet_avx,
    instance_blocks_avx,
    closest_lanes_avx,
    closest_top_avx,
    occluded_lanes8
);
#[cfg(target_arch = "x86_64")]
packet_kernels!(
    Avx512,
    "avx512f,avx2,fma,bmi1,bmi2,lzcnt,popcnt",
    occluded_packets_avx512,
    occluded_lanes_avx512,
    occluded_lanes_of_avx512,
    occluded_packets_avx512,
    occluded_packet_avx512,
    instance_blocks_avx512,
    closest_lanes_avx512,
    closest_top_avx512,
    occluded_lanes16
);

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
