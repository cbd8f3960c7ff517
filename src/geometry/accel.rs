//! The scene's two-level acceleration structure. Each unique triangle mesh gets one
//! bottom-level BVH ([`Blas`]) in its own frame, built once (obvhs PLOC) and refit when its
//! vertices move; spheres and cuboids share one world-space BLAS. A top-level BVH over the
//! instances (BLAS + affine transform) is rebuilt whenever an instance moves, which costs
//! microseconds per hundred instances. Infinite planes stay outside both levels.
//!
//! Traversal is hemi's own, front to back, honouring the ray's full (0, tmax) range at every
//! scale. Rays enter an instance through its inverse affine with the direction kept
//! un-normalised, so `t` means the same in both frames; as in pbrt-v4, the transformed origin
//! is advanced past its own rounding error and hit points carry the transform's error back to
//! world space, so spawned rays stay free of self-intersection under any instance transform.

use std::{
    sync::Arc,
    time::{Duration, Instant},
};

use bevy_ecs::prelude::{Entity, Resource};
use glam::{Affine3A, Mat3A, Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::{Bvh2, builder::build_bvh2, node::Bvh2Node},
};
use rayon::prelude::*;

use super::{
    binned_sah,
    hit::SurfaceHit,
    ray::{Ray, Shear},
    shapes::{PlanePrim, SpherePrim, Triangle},
    tri4::{RayTri4, Tri4},
    wide_bvh::{Bvh4, Node, NodeTest, WideBvh, prefetch},
};
#[cfg(target_arch = "x86_64")]
use super::{
    tri4::RayTriPacket,
    wide_bvh::{Bvh8, FusedPacket, LaneHits, PACKET_MIN_LANES, RayPacket},
};
#[cfg(target_arch = "x86_64")]
use crate::geometry::lanes::{Avx, Avx512, Lanes, RayLanes};
use crate::{
    components::{Matte, Mesh},
    math::gamma,
};

/// A bounded primitive.
#[derive(Clone, Copy, Debug)]
pub enum Shape {
    /// A triangle.
    Triangle(Triangle),
    /// A sphere.
    Sphere(SpherePrim),
}

/// A bounded primitive and the object it belongs to.
#[derive(Clone, Copy, Debug)]
pub struct Prim {
    /// Geometry.
    pub shape: Shape,
    /// Index into [`SceneGeometry::objects`] (unused in a mesh BLAS: the instance names it).
    pub object: u32,
}

impl Prim {
    /// Axis-aligned bounds.
    pub fn bounds(&self) -> Aabb {
        match self.shape {
            Shape::Triangle(t) => {
                let (min, max) = t.bounds();
                Aabb::new(min, max)
            }
            Shape::Sphere(s) => Aabb::new(s.center - s.radius, s.center + s.radius),
        }
    }
}

/// A scene object: the entity it came from and its material.
#[derive(Clone, Copy, Debug)]
pub struct Object {
    /// Source entity.
    pub entity: Entity,
    /// Surface material.
    pub material: Matte,
}

/// Intersects one primitive: (t, b1, b2). `shear` is [`Shear::new`]`(ray.dir)`.
#[inline(always)]
fn hit_prim(prim: &Prim, ray: &Ray, shear: &Shear) -> Option<(f32, f32, f32)> {
    match prim.shape {
        Shape::Triangle(t) => t.intersect(ray, shear),
        Shape::Sphere(s) => s.intersect(ray).map(|t| (t, 0.0, 0.0)),
    }
}

/// Primitives per task in the BVH build's parallel loops.
const PAR_CHUNK: usize = 4096;

/// The wide tree traversal uses: eight children per node where the CPU has AVX, else four.
#[derive(Clone, Debug)]
enum Tree {
    Four(Bvh4),
    #[cfg(target_arch = "x86_64")]
    Eight(super::wide_bvh::Bvh8),
}

impl Default for Tree {
    fn default() -> Self {
        Tree::Four(Bvh4::default())
    }
}

impl Tree {
    /// Collapses `bvh2` to eight children per node where the CPU has AVX and `HEMI_BVH_WIDTH`
    /// is not 4, else to four.
    fn from_bvh2(bvh2: &[Bvh2Node]) -> Self {
        #[cfg(target_arch = "x86_64")]
        if bvh_width() == 8
            && let Some(tree) = super::wide_bvh::Bvh8::from_bvh2(bvh2)
        {
            return Tree::Eight(tree);
        }
        Tree::Four(Bvh4::from_bvh2(bvh2))
    }

    fn map_leaves(&mut self, f: impl FnMut(u32, u32) -> (u32, u32)) {
        match self {
            Tree::Four(t) => t.map_leaves(f),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(t) => t.map_leaves(f),
        }
    }

    fn memory_bytes(&self) -> usize {
        match self {
            Tree::Four(t) => t.memory_bytes(),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(t) => t.memory_bytes(),
        }
    }

    fn len(&self) -> usize {
        match self {
            Tree::Four(t) => t.len(),
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(t) => t.len(),
        }
    }

    fn width(&self) -> usize {
        match self {
            Tree::Four(_) => 4,
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(_) => 8,
        }
    }

    /// Runs `query` over this tree; an eight-wide tree is traversed by code compiled for AVX.
    #[inline(always)]
    fn query<Q: TreeQuery>(&self, query: Q) -> Q::Output {
        match self {
            Tree::Four(tree) => query.run(tree),
            // SAFETY: an eight-wide tree is built only where AVX was detected.
            #[cfg(target_arch = "x86_64")]
            Tree::Eight(tree) => unsafe { query_avx(tree, query) },
        }
    }
}

/// A traversal written once for either node width.
trait TreeQuery {
    type Output;
    fn run<const W: usize>(self, tree: &WideBvh<W>) -> Self::Output
    where
        Node<W>: NodeTest<W>;
}

/// [`TreeQuery::run`] compiled for the eight-lane instruction sets ([`crate::simd::avx2`]), so
/// that the eight-wide node test inlines.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
fn query_avx<Q: TreeQuery>(tree: &super::wide_bvh::Bvh8, query: Q) -> Q::Output {
    query.run(tree)
}

/// Closest hit in a BLAS: (primitive slot, b1, b2).
struct BlasClosest<'a> {
    blas: &'a Blas,
    ray: &'a mut Ray,
    stack: &'a mut Vec<(u32, f32)>,
}

impl TreeQuery for BlasClosest<'_> {
    type Output = Option<(u32, f32, f32)>;
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>) -> Self::Output
    where
        Node<W>: NodeTest<W>,
    {
        self.blas.closest_in(tree, self.ray, self.stack)
    }
}

/// Occlusion of each of `rays` not yet known to be blocked (`blocked`, same length), by
/// `target`'s traversal of the tree: one call, one dispatch to the tree's width.
struct OccludedEach<'a, T> {
    target: &'a T,
    rays: &'a [Ray],
    stack: &'a mut Vec<(u32, f32)>,
    blocked: &'a mut [bool],
}

/// What an [`OccludedEach`] query traverses: a BLAS, or the scene through its top level.
trait Occluder {
    /// Whether anything reached through `tree` blocks `ray`. Uses `stack` above its length.
    fn occluded_in<const W: usize>(&self, tree: &WideBvh<W>, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool
    where
        Node<W>: NodeTest<W>;
}

impl<T: Occluder> TreeQuery for OccludedEach<'_, T> {
    type Output = ();
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>)
    where
        Node<W>: NodeTest<W>,
    {
        for (ray, b) in self.rays.iter().zip(self.blocked.iter_mut()) {
            *b = *b || self.target.occluded_in(tree, ray, self.stack);
        }
    }
}

/// Closest hit through the top level: (instance, primitive slot, b1, b2).
struct TopClosest<'a> {
    scene: &'a SceneGeometry,
    ray: &'a mut Ray,
    stack: &'a mut Vec<(u32, f32)>,
}

impl TreeQuery for TopClosest<'_> {
    type Output = Option<ClosestHit>;
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>) -> Self::Output
    where
        Node<W>: NodeTest<W>,
    {
        self.scene.closest_through(tree, self.ray, self.stack)
    }
}

/// The node width asked for: 4 when the environment variable `HEMI_BVH_WIDTH` is `4`,
/// else 8 (which falls back to 4 without AVX). Read once per process.
#[cfg(target_arch = "x86_64")]
fn bvh_width() -> usize {
    static WIDTH: std::sync::OnceLock<usize> = std::sync::OnceLock::new();
    *WIDTH.get_or_init(|| if std::env::var("HEMI_BVH_WIDTH").is_ok_and(|w| w.trim() == "4") { 4 } else { 8 })
}

/// The BVH2 build settings for small sets (under [`SMALL_SET`] primitives): obvhs's medium
/// preset with leaves of at most one packet, collapsed less eagerly (traversal cost 1.5 instead
/// of 3): the peer Cornell box traced 44 % faster with them, while from 3.9k triangles up
/// (Suzanne, Duck, bunny, teapot, FlightHelmet, dragon) they were 0–8 % slower. Larger sets
/// get [`binned_sah::build`].
fn small_set_params() -> BvhBuildParams {
    BvhBuildParams { max_prims_per_leaf: 4, collapse_traversal_cost: 1.5, ..BvhBuildParams::medium_build() }
}

/// How a run of rays given to [`SceneGeometry::occluded_many`] is ordered, which decides how
/// it is cut into packets. Either way every ray gets the answer of its own query.
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
fn in_packets<L: Lanes>(
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

/// Rays per packet: sixteen where the CPU has AVX-512 (and `HEMI_NO_AVX512` is not `1`, see
/// [`crate::cpu`]), eight with AVX only.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
enum PacketWidth {
    Eight,
    Sixteen,
}

#[cfg(target_arch = "x86_64")]
impl PacketWidth {
    /// Rays per packet.
    fn lanes(self) -> usize {
        match self {
            PacketWidth::Eight => 8,
            PacketWidth::Sixteen => 16,
        }
    }
}

/// A closest hit in a scene: (instance, primitive slot, b1, b2).
type ClosestHit = (u32, u32, f32, f32);

/// Where [`SceneGeometry::intersect_many`] traces a packet.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
enum CameraPackets<'a> {
    /// Straight into a static scene's one world-space BLAS of triangle packets, and its tree.
    World(&'a Blas, &'a Bvh8),
    /// Through the top level (every instance in world space).
    Top(&'a Bvh8),
}

/// The packet width this CPU and environment get.
#[cfg(target_arch = "x86_64")]
fn packet_width() -> PacketWidth {
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
            fn $closest(
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
            fn $packets(
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
            fn $closest_top(
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
            fn $scene(
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
                    // The fused node test, as in a BLAS: many_spheres 2.7 % faster than the
                    // plain one here (same answers: the leaves decide).
                    top.occluded_packet(&FusedPacket::new(lanes, live), start, live, stack, leaf, single)
                }
            }

            /// The lanes of `entered` whose ray (world space; in `lanes`, and `ray(k)` for lane k)
            /// instance `inst` blocks: as one packet in the instance's frame (or the packet
            /// itself, for an identity transform) where its BLAS takes packets and at least
            /// [`PACKET_MIN_LANES`] rays reach it. Fewer would go on alone from the packet's first
            /// node after the packet's set-up (its transpose, box and constants) for nothing:
            /// one by one they trace many_spheres 3.4 % faster than from two rays up, 1.5 %
            /// faster than from three.
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

/// Fewest rays in one [`Blas::occluded_many`] call for packet traversal (a point light's
/// single shadow ray goes on its own).
const PACKET_RUN: usize = 4;

/// Primitive count under which a BLAS gets small leaves (see [`small_set_params`]).
const SMALL_SET: usize = 1024;

/// A bottom-level BVH: an obvhs BVH2 over primitives stored in leaf order.
#[derive(Clone)]
pub struct Blas {
    bvh: Bvh2,
    /// The BVH2 collapsed to a wide tree, which traversal uses. Its leaves are ranges of
    /// `packets` when every primitive is a triangle, else ranges of `prims`.
    tree: Tree,
    /// Each leaf's triangles in packets of four, when every primitive is a triangle.
    packets: Vec<Tri4>,
    /// The primitives in leaf order.
    prims: Vec<Prim>,
    /// Triangles stored.
    pub triangle_count: usize,
    /// Zero-area triangles dropped at build time (they can never be hit).
    pub degenerate_triangles: usize,
    /// Depth of the tree.
    pub depth: usize,
}

impl Blas {
    /// Builds a BVH over `prims` (in any order) that is never refit: by
    /// [`binned_sah::build_with_spatial_splits`] from 1024 primitives up where all are
    /// triangles (the spatial splits only where enough of them are large), by
    /// [`binned_sah::build`] from 1024 up otherwise, else by obvhs's PLOC with its medium
    /// preset and leaves of at most one packet. (obvhs's spatial pre-splits, tried with PLOC,
    /// traced sphere_plane and Sponza 4–8 % slower and cost the dragon 60–90 ms of build; with
    /// the binned builder they left Sponza's SAH cost where it was. Splits chosen node by node
    /// trace Sponza's AO rays 16 % faster.)
    pub fn build(prims: Vec<Prim>) -> Self {
        Blas::build_with(prims, true)
    }

    /// [`Blas::build`], with or without spatial splits. Without them each primitive is in one
    /// leaf, so that a deformable BLAS can be refit.
    fn build_with(prims: Vec<Prim>, spatial_splits: bool) -> Self {
        let triangle_count = prims.iter().filter(|p| matches!(p.shape, Shape::Triangle(_))).count();
        let (bvh, depth) = if prims.is_empty() {
            (Bvh2::default(), 0)
        } else if prims.len() < SMALL_SET {
            let aabbs: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
            let bvh = build_bvh2(&aabbs, small_set_params(), &mut Duration::default());
            let depth = subtree_depth(&bvh.nodes);
            (bvh, depth)
        } else if spatial_splits && triangle_count == prims.len() {
            binned_sah::build_with_spatial_splits(prims.len(), |i| match prims[i].shape {
                Shape::Triangle(t) => t.p,
                Shape::Sphere(_) => unreachable!("an all-triangle set"),
            })
        } else {
            binned_sah::build(prims.len(), |i| prims[i].bounds())
        };
        let prims = bvh.primitive_indices.par_iter().with_min_len(PAR_CHUNK).map(|&i| prims[i as usize]).collect();
        let mut blas = Blas {
            bvh,
            tree: Tree::default(),
            packets: Vec::new(),
            prims,
            triangle_count,
            degenerate_triangles: 0,
            depth,
        };
        blas.build_tree();
        blas
    }

    /// Collapses the BVH2 into the wide tree and, for an all-triangle BLAS, packs each leaf's
    /// triangles into packets of four.
    fn build_tree(&mut self) {
        self.tree = Tree::from_bvh2(&self.bvh.nodes);
        self.packets.clear();
        let prims = &self.prims;
        if prims.is_empty() || !prims.iter().all(|p| matches!(p.shape, Shape::Triangle(_))) {
            return;
        }
        let triangle = |k: u32| match prims[k as usize].shape {
            Shape::Triangle(t) => (k, t),
            Shape::Sphere(_) => unreachable!("an all-triangle BLAS"),
        };
        // Leaves in node order get consecutive packet ranges; the packets are filled in parallel.
        let mut lanes = Vec::new();
        self.tree.map_leaves(|first, count| {
            let start = lanes.len() as u32;
            lanes.extend((first..first + count).step_by(4).map(|lane0| (lane0, (lane0 + 4).min(first + count))));
            (start, lanes.len() as u32 - start)
        });
        // Written straight into an allocation of the right size, advised onto huge pages.
        self.packets = crate::huge_pages::vec_on_huge_pages(lanes.len());
        self.packets.par_extend(
            lanes.par_iter().with_min_len(PAR_CHUNK / 4).map(|&(first, end)| Tri4::pack((first..end).map(triangle))),
        );
    }

    /// A mesh's triangles in its own frame; zero-area triangles are counted and skipped.
    pub fn from_mesh(mesh: &Mesh) -> Self {
        let mut prims = Vec::with_capacity(mesh.indices.len());
        let mut degenerate = 0;
        for tri in &mesh.indices {
            let [a, b, c] = tri.map(|i| Vec3A::from(mesh.positions[i as usize]));
            match Triangle::new(a, b, c) {
                Some(t) => prims.push(Prim { shape: Shape::Triangle(t), object: 0 }),
                None => degenerate += 1,
            }
        }
        let mut blas = Blas::build(prims);
        blas.degenerate_triangles = degenerate;
        blas
    }

    /// A BLAS for a deforming mesh: every triangle keeps its slot (zero-area ones included, they
    /// are never hit) so that [`Blas::refit`] can move the vertices without rebuilding.
    pub fn deformable(mesh: &Mesh) -> Self {
        let prims = mesh.indices.iter().map(|tri| {
            let p = tri.map(|i| Vec3A::from(mesh.positions[i as usize]));
            Prim { shape: Shape::Triangle(Triangle { p }), object: 0 }
        });
        Blas::build_with(prims.collect(), false)
    }

    /// Moves the triangles of a [`Blas::deformable`] BLAS to `positions` (same triangles as at
    /// build time) and refits the node bounds bottom-up (obvhs `refit_all`); the tree topology
    /// stays that of the build, so the result depends only on the build mesh and `positions`.
    pub fn refit(&mut self, positions: &[Vec3], indices: &[[u32; 3]]) {
        for (slot, &original) in self.bvh.primitive_indices.iter().enumerate() {
            let p = indices[original as usize].map(|i| Vec3A::from(positions[i as usize]));
            self.prims[slot].shape = Shape::Triangle(Triangle { p });
        }
        for node in &mut self.bvh.nodes {
            if node.prim_count > 0 {
                let first = node.first_index as usize;
                let leaf = &self.prims[first..first + node.prim_count as usize];
                let aabb = leaf.iter().fold(Aabb::empty(), |acc, p| acc.union(&p.bounds()));
                node.set_aabb(aabb);
            }
        }
        self.bvh.refit_all();
        self.build_tree();
    }

    /// Bounds of everything in this BLAS.
    pub fn bounds(&self) -> Option<Aabb> {
        self.bvh.nodes.first().map(|n| *n.aabb())
    }

    /// Number of nodes of the binary tree as built.
    pub fn node_count(&self) -> usize {
        self.bvh.nodes.len()
    }

    /// Number of nodes of the wide tree traversal uses ([`Blas::node_width`] children each).
    pub fn wide_node_count(&self) -> usize {
        self.tree.len()
    }

    /// The primitives, each once (a triangle that spatial splits put in several leaves is
    /// stored once per leaf), in the order of their first leaves.
    pub fn prims(&self) -> impl Iterator<Item = &Prim> {
        let mut seen = vec![false; self.prims.len()];
        let mut first_leaf = move |&i: &u32| !std::mem::replace(&mut seen[i as usize], true);
        self.bvh.primitive_indices.iter().zip(&self.prims).filter_map(move |(i, p)| first_leaf(i).then_some(p))
    }

    /// Bytes held by nodes and primitives.
    pub fn memory_bytes(&self) -> usize {
        self.bvh.nodes.len() * size_of::<Bvh2Node>()
            + self.tree.memory_bytes()
            + self.packets.len() * size_of::<Tri4>()
            + self.prims.len() * (size_of::<Prim>() + 4)
    }

    /// Children per node of the tree traversal uses (8 with AVX, else 4).
    pub fn node_width(&self) -> usize {
        self.tree.width()
    }

    /// Front-to-back traversal; shrinks `ray.tmax` to the closest hit and returns the
    /// primitive slot and barycentrics. Uses `stack` above its current length only.
    #[inline]
    fn closest(&self, ray: &mut Ray, stack: &mut Vec<(u32, f32)>) -> Option<(u32, f32, f32)> {
        self.tree.query(BlasClosest { blas: self, ray, stack })
    }

    #[inline(always)]
    fn closest_in<const W: usize>(
        &self,
        tree: &WideBvh<W>,
        ray: &mut Ray,
        stack: &mut Vec<(u32, f32)>,
    ) -> Option<(u32, f32, f32)>
    where
        Node<W>: NodeTest<W>,
    {
        let prims = &self.prims;
        let mut best = None;
        if !self.packets.is_empty() {
            let r = RayTri4::new(ray);
            tree.closest(ray, stack, |first, count, ray, _| {
                for packet in &self.packets[first as usize..(first + count) as usize] {
                    self.packet_hits(packet, &r, ray, |slot, (t, b1, b2), ray| {
                        ray.tmax = t;
                        best = Some((slot, b1, b2));
                        false
                    });
                }
            });
            return best;
        }
        let shear = Shear::new(ray.dir);
        tree.closest(ray, stack, |first, count, ray, _| {
            for k in first..first + count {
                if let Some((t, b1, b2)) = hit_prim(&prims[k as usize], ray, &shear) {
                    ray.tmax = t;
                    best = Some((k, b1, b2));
                }
            }
        });
        best
    }

    /// Whether any primitive blocks `ray` in (0, tmax). Uses `stack` above its current length.
    #[inline]
    fn occluded(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let mut blocked = [false];
        let rays = std::slice::from_ref(ray);
        self.tree.query(OccludedEach { target: self, rays, stack, blocked: &mut blocked });
        blocked[0]
    }

    /// [`Blas::occluded`] for each of `rays` not yet `blocked` (same length), in one call: in
    /// ray packets where the tree is eight-wide and holds triangle packets.
    fn occluded_many(&self, rays: &[Ray], order: RayOrder, stack: &mut Vec<(u32, f32)>, blocked: &mut [bool]) {
        #[cfg(target_arch = "x86_64")]
        if let Tree::Eight(tree) = &self.tree
            && !self.packets.is_empty()
            && rays.len() >= PACKET_RUN
        {
            // SAFETY: an eight-wide tree is built only where AVX was detected, and sixteen-lane
            // packets are chosen only where AVX-512 (with POPCNT) was.
            return unsafe {
                match packet_width() {
                    PacketWidth::Sixteen => self.occluded_packets_avx512(tree, rays, order, stack, blocked),
                    PacketWidth::Eight => self.occluded_packets_avx(tree, rays, order, stack, blocked),
                }
            };
        }
        // Without packets the order does not matter.
        let _ = order;
        self.tree.query(OccludedEach { target: self, rays, stack, blocked });
    }

    /// The lanes of `lanes` whose ray (`ray(k)` for lane k) a triangle in packets
    /// `first..first + count` blocks, each triangle tested against all those rays at once.
    ///
    /// # Safety
    /// The CPU must have `L`'s instruction set.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn packets_block_lanes<L: Lanes>(
        &self,
        first: u32,
        count: u32,
        ray: &impl Fn(usize) -> Ray,
        r: &RayTriPacket<L>,
        lanes: u32,
    ) -> u32 {
        let mut open = lanes;
        for packet in &self.packets[first as usize..(first + count) as usize] {
            for (lane, &slot) in packet.slot.iter().enumerate() {
                if slot == u32::MAX {
                    continue;
                }
                // SAFETY: the caller's CPU has `L`'s instruction set.
                let edges = unsafe { packet.edges_packet(lane, r) };
                let (pass, mut exact) = (edges.pass & open, edges.exact & open);
                if pass | exact == 0 {
                    continue;
                }
                let tri = packet.triangle(lane);
                if pass != 0 {
                    // SAFETY: the caller's CPU has `L`'s instruction set.
                    open &= !(unsafe { r.plane_hits(&tri) } & pass);
                }
                // Lanes with a zero or NaN edge function: the scalar test with its f64 edges.
                while exact != 0 {
                    let k = exact.trailing_zeros() as usize;
                    exact &= exact - 1;
                    let ray = ray(k);
                    if tri.intersect(&ray, &Shear::new(ray.dir)).is_some() {
                        open &= !(1 << k);
                    }
                }
                if open == 0 {
                    return lanes;
                }
            }
        }
        lanes & !open
    }

    /// Starts loading triangle packets `first..first + count` into the cache (a leaf a ray will
    /// test): their misses then overlap instead of stalling one after another.
    #[inline(always)]
    fn prefetch_packets(&self, first: u32, count: u32) {
        for packet in &self.packets[first as usize..(first + count) as usize] {
            prefetch(packet);
        }
    }

    /// Whether a triangle in packets `first..first + count` blocks `ray`, by the copy of the
    /// test compiled for a tree of width `W`: for AVX under eight-wide trees. Both copies are
    /// out of line, so the packet test's set-up runs per leaf reached, not per ray (most AO
    /// rays reach none).
    #[inline(always)]
    fn packets_block<const W: usize>(&self, first: u32, count: u32, ray: &Ray) -> bool {
        #[cfg(target_arch = "x86_64")]
        if W == 8 {
            // SAFETY: eight-wide trees are built only where AVX was detected.
            return unsafe { self.packets_block_avx(first, count, ray) };
        }
        self.packets_block_baseline(first, count, ray)
    }

    /// [`Blas::packets_block`] for the target's baseline instruction set.
    #[inline(never)]
    fn packets_block_baseline(&self, first: u32, count: u32, ray: &Ray) -> bool {
        self.packets_block_body(first, count, ray)
    }

    /// [`Blas::packets_block`] compiled for AVX (three-operand encodings; same arithmetic).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma,bmi1,bmi2,lzcnt,popcnt")]
    #[inline(never)]
    fn packets_block_avx(&self, first: u32, count: u32, ray: &Ray) -> bool {
        self.packets_block_body(first, count, ray)
    }

    #[inline(always)]
    fn packets_block_body(&self, first: u32, count: u32, ray: &Ray) -> bool {
        let r = RayTri4::new(ray);
        let mut local = *ray;
        for k in first as usize..(first + count) as usize {
            if self.packet_hits(&self.packets[k], &r, &mut local, |_, _, _| true) {
                return true;
            }
        }
        false
    }

    /// Tests the triangles of `packet` in lane order, calling `hit(slot, (t, b1, b2), ray)` for
    /// each hit in (0, ray.tmax) (the callback may shrink `ray.tmax`); stops and returns true as
    /// soon as `hit` does. Gives exactly the hits of the scalar test in the same order.
    #[inline(always)]
    fn packet_hits(
        &self,
        packet: &Tri4,
        r: &RayTri4,
        ray: &mut Ray,
        mut hit: impl FnMut(u32, (f32, f32, f32), &mut Ray) -> bool,
    ) -> bool {
        let lanes = packet.edges(r);
        let mut todo = lanes.pass | lanes.exact;
        while todo != 0 {
            let i = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let slot = packet.slot[i];
            if slot == u32::MAX {
                continue;
            }
            // The packet's own copy of the triangle: already in cache, unlike `prims`.
            let tri = packet.triangle(i);
            let found = if lanes.exact & (1 << i) != 0 {
                tri.intersect(ray, &r.shear)
            } else {
                tri.finish(ray, lanes.e[0][i], lanes.e[1][i], lanes.e[2][i])
            };
            if let Some(h) = found
                && hit(slot, h, ray)
            {
                return true;
            }
        }
        false
    }

    fn surface(&self, slot: u32, ray: &Ray, b1: f32, b2: f32, object: u32) -> SurfaceHit {
        let prim = &self.prims[slot as usize];
        match prim.shape {
            Shape::Triangle(tri) => tri.surface(ray, ray.tmax, b1, b2, object),
            Shape::Sphere(s) => s.surface(ray, ray.tmax, object),
        }
    }
}

impl Occluder for Blas {
    #[inline(always)]
    fn occluded_in<const W: usize>(&self, tree: &WideBvh<W>, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool
    where
        Node<W>: NodeTest<W>,
    {
        let prims = &self.prims;
        if !self.packets.is_empty() {
            return tree.occluded(ray, stack, |first, count, _| self.packets_block::<W>(first, count, ray));
        }
        let shear = Shear::new(ray.dir);
        tree.occluded(ray, stack, |first, count, _| {
            prims[first as usize..(first + count) as usize].iter().any(|p| hit_prim(p, ray, &shear).is_some())
        })
    }
}

impl std::fmt::Debug for Blas {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Blas")
            .field("nodes", &self.bvh.nodes.len())
            .field("prims", &self.prims.len())
            .field("depth", &self.depth)
            .finish()
    }
}

/// Depth of the deepest leaf of a BVH2 (the root alone is 1; an empty tree is 0), by a
/// depth-first walk from the root. The binned builder counts its trees' depth as it builds.
pub(super) fn subtree_depth(nodes: &[Bvh2Node]) -> usize {
    let mut max = 0;
    let mut stack = vec![(0usize, 1usize)];
    while let Some((i, d)) = stack.pop() {
        let Some(n) = nodes.get(i) else { continue };
        max = max.max(d);
        if n.prim_count == 0 {
            stack.push((n.first_index as usize, d + 1));
            stack.push((n.first_index as usize + 1, d + 1));
        }
    }
    max
}

/// One placement of a BLAS in the world.
#[derive(Clone, Debug)]
pub struct Instance {
    /// Index into the scene's BLAS list.
    pub blas: u32,
    /// The object every primitive of this instance belongs to (`None`: each prim names its own).
    pub object: Option<u32>,
    to_world: Affine3A,
    to_local: Affine3A,
    identity: bool,
    translation_only: bool,
    bounds: Aabb,
}

impl Instance {
    /// An instance of `blas` (whose bounds are `local`) placed by `to_world`, or `None` when
    /// the transform is singular or the placed bounds overflow.
    pub fn new(blas: u32, local: Aabb, to_world: Affine3A, object: Option<u32>) -> Option<Self> {
        let to_local = to_world.inverse();
        if !to_local.is_finite() {
            return None;
        }
        let mut bounds = Aabb::empty();
        for i in 0..8 {
            let corner = Vec3A::new(
                if i & 1 == 0 { local.min.x } else { local.max.x },
                if i & 2 == 0 { local.min.y } else { local.max.y },
                if i & 4 == 0 { local.min.z } else { local.max.z },
            );
            bounds.extend(to_world.transform_point3a(corner));
        }
        // Pad by the rounding of the corner transform so no true hit is culled.
        let pad = bounds.min.abs().max(bounds.max.abs()) * gamma(4);
        let bounds = Aabb::new(bounds.min - pad, bounds.max + pad);
        if !(bounds.min.is_finite() && bounds.max.is_finite()) {
            return None;
        }
        Some(Instance {
            blas,
            object,
            to_world,
            to_local,
            identity: to_world == Affine3A::IDENTITY,
            translation_only: to_world.matrix3 == Mat3A::IDENTITY,
            bounds,
        })
    }

    /// Placed bounds in world space.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// The transform from the BLAS frame to world space.
    pub fn to_world(&self) -> Affine3A {
        self.to_world
    }

    /// The ray in the instance's frame and the parameter shift `dt` (world t = local t + dt):
    /// the origin is moved along the direction past its transform's rounding error (pbrt-v4).
    #[inline]
    fn local_ray(&self, ray: &Ray) -> Option<(Ray, f32)> {
        let m = &self.to_local;
        if self.translation_only {
            // Same direction: only the origin moves, by one rounded subtraction.
            let o = ray.origin + m.translation;
            let o_err = (ray.origin.abs() + m.translation.abs()) * gamma(1);
            let len2 = ray.dir.length_squared();
            let dt = if len2 > 0.0 { ray.dir.abs().dot(o_err) / len2 } else { 0.0 };
            let tmax = ray.tmax - dt;
            return (tmax > 0.0).then(|| (Ray { origin: o + ray.dir * dt, tmax, ..*ray }, dt));
        }
        let o = m.transform_point3a(ray.origin);
        let d = m.matrix3 * ray.dir;
        let o_err = (abs_mat(&m.matrix3) * ray.origin.abs() + m.translation.abs()) * gamma(3);
        let len2 = d.length_squared();
        let dt = if len2 > 0.0 { d.abs().dot(o_err) / len2 } else { 0.0 };
        let tmax = ray.tmax - dt;
        (tmax > 0.0).then(|| (Ray::new(o + d * dt, d, tmax), dt))
    }

    /// A hit found in the instance's frame, moved to world space with its error bound grown by
    /// the transform's rounding (pbrt-v4's `Transform::operator()(Point3fi)`).
    #[inline]
    fn to_world_hit(&self, hit: SurfaceHit, dt: f32) -> SurfaceHit {
        let m = &self.to_world;
        let abs = abs_mat(&m.matrix3);
        let p = m.transform_point3a(hit.p);
        let p_error = (abs * hit.p_error) * (1.0 + gamma(3)) + (abs * hit.p.abs() + m.translation.abs()) * gamma(3);
        // Normals go by the inverse transpose; it keeps the side the ray came from.
        let normal = (self.to_local.matrix3.transpose() * hit.normal).normalize();
        SurfaceHit { t: hit.t + dt, p, p_error, normal, object: hit.object }
    }
}

#[inline(always)]
fn abs_mat(m: &Mat3A) -> Mat3A {
    Mat3A::from_cols(m.x_axis.abs(), m.y_axis.abs(), m.z_axis.abs())
}

/// What the last BVH update did, for statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BvhWork {
    /// Bottom-level BVHs built from scratch.
    pub blas_built: usize,
    /// Bottom-level BVHs refit to moved vertices.
    pub blas_refit: usize,
    /// Whether the top-level BVH over the instances was rebuilt.
    pub tlas_built: bool,
}

impl BvhWork {
    /// Whether any BVH work was done.
    pub fn any(&self) -> bool {
        self.blas_built + self.blas_refit > 0 || self.tlas_built
    }
}

/// Everything rays can hit.
#[derive(Resource, Clone, Debug, Default)]
pub struct SceneGeometry {
    blases: Vec<Arc<Blas>>,
    instances: Vec<Instance>,
    tlas: Vec<Bvh2Node>,
    /// The top-level BVH2 collapsed to a wide tree, which traversal uses.
    top: Tree,
    /// Whether runs of camera rays go through the top level in packets: every instance is in
    /// world space (no transform) and some BLAS holds triangle packets.
    top_packets: bool,
    /// The BLAS of a scene that is one world-space instance (a baked static scene), which
    /// queries take directly, with no top level: held here so that a query reaches it in one
    /// load rather than through the instance list.
    world_blas: Option<Arc<Blas>>,
    planes: Vec<PlanePrim>,
    /// Objects, indexed by `SurfaceHit::object`.
    pub objects: Vec<Object>,
    /// Triangles stored (each shared mesh once).
    pub triangle_count: usize,
    /// Triangles placed in the scene (each instance counted).
    pub instanced_triangle_count: usize,
    /// Zero-area triangles dropped from the input (they can never be hit).
    pub degenerate_triangles: usize,
    /// Bounds of the bounded primitives (empty when there are none).
    pub bounds: Option<(Vec3A, Vec3A)>,
    /// Depth of the top-level BVH plus the deepest BLAS.
    pub depth: usize,
    /// Time the last update took.
    pub build_time: Duration,
}

impl SceneGeometry {
    /// A scene whose bounded primitives (given in world space, any order) form one BLAS,
    /// with `planes` beside it.
    pub fn build(prims: Vec<Prim>, planes: Vec<PlanePrim>, objects: Vec<Object>) -> Self {
        let start = Instant::now();
        let blas = Arc::new(Blas::build(prims));
        let instances = blas.bounds().and_then(|b| Instance::new(0, b, Affine3A::IDENTITY, None));
        let mut g = SceneGeometry::from_instances(vec![blas], instances.into_iter().collect(), planes, objects);
        g.build_time = start.elapsed();
        g
    }

    /// A scene of BLAS instances plus `planes`; builds the top-level BVH over the instances.
    pub fn from_instances(
        blases: Vec<Arc<Blas>>,
        instances: Vec<Instance>,
        planes: Vec<PlanePrim>,
        objects: Vec<Object>,
    ) -> Self {
        let start = Instant::now();
        let (tlas, instances) = if instances.is_empty() {
            (Vec::new(), instances)
        } else {
            // PLOC merges equal Morton codes pair by pair, so thousands of instances at one
            // position would build in quadratic time; the binned builder halves such sets.
            let bvh = if instances.len() < SMALL_SET {
                let aabbs: Vec<Aabb> = instances.iter().map(|i| i.bounds).collect();
                let params = BvhBuildParams { max_prims_per_leaf: 1, ..BvhBuildParams::fast_build() };
                build_bvh2(&aabbs, params, &mut Duration::default())
            } else {
                binned_sah::build(instances.len(), |i| instances[i].bounds).0
            };
            let ordered = bvh.primitive_indices.iter().map(|&i| instances[i as usize].clone()).collect();
            (bvh.nodes, ordered)
        };
        let triangle_count = blases.iter().map(|b| b.triangle_count).sum();
        let instanced_triangle_count = instances.iter().map(|i| blases[i.blas as usize].triangle_count).sum();
        let degenerate_triangles = blases.iter().map(|b| b.degenerate_triangles).sum();
        let bounds = tlas.first().map(|n| (n.aabb().min, n.aabb().max));
        let depth = subtree_depth(&tlas) + blases.iter().map(|b| b.depth).max().unwrap_or(0);
        let world_blas = match &instances[..] {
            [inst] if inst.identity => Some(blases[inst.blas as usize].clone()),
            _ => None,
        };
        SceneGeometry {
            top_packets: instances.iter().all(|i| i.identity) && blases.iter().any(|b| !b.packets.is_empty()),
            world_blas,
            blases,
            instances,
            top: Tree::from_bvh2(&tlas),
            tlas,
            planes,
            objects,
            triangle_count,
            instanced_triangle_count,
            degenerate_triangles,
            bounds,
            depth,
            build_time: start.elapsed(),
        }
    }

    /// Children per node of the trees traversal uses (8 with AVX, else 4).
    pub fn node_width(&self) -> usize {
        self.blases.iter().map(|b| b.node_width()).max().unwrap_or(self.top.width())
    }

    /// Rays per packet in occlusion runs: 16 with AVX-512, 8 with AVX, 0 where trees are
    /// four-wide and every ray is traced alone.
    pub fn packet_lanes(&self) -> usize {
        #[cfg(target_arch = "x86_64")]
        if self.node_width() == 8 {
            return packet_width().lanes();
        }
        0
    }

    /// Number of binary BVH nodes as built (top level plus every BLAS once).
    pub fn node_count(&self) -> usize {
        self.tlas.len() + self.blases.iter().map(|b| b.node_count()).sum::<usize>()
    }

    /// Number of nodes of the wide trees traversal uses ([`SceneGeometry::node_width`]
    /// children each; top level plus every BLAS once).
    pub fn wide_node_count(&self) -> usize {
        self.top.len() + self.blases.iter().map(|b| b.wide_node_count()).sum::<usize>()
    }

    /// Number of primitives stored in the leaves (shared meshes once; a triangle that spatial
    /// splits put in several leaves once per leaf).
    pub fn prim_count(&self) -> usize {
        self.blases.iter().map(|b| b.prims.len()).sum()
    }

    /// The bottom-level BVHs.
    pub fn blases(&self) -> &[Arc<Blas>] {
        &self.blases
    }

    /// The instances, in top-level leaf order.
    pub fn instances(&self) -> &[Instance] {
        &self.instances
    }

    /// Every bounded primitive placed in world space (instances expanded), for comparisons.
    pub fn world_prims(&self) -> Vec<Prim> {
        let mut out = Vec::new();
        for inst in &self.instances {
            let m = inst.to_world;
            for prim in self.blases[inst.blas as usize].prims() {
                let object = inst.object.unwrap_or(prim.object);
                let shape = match prim.shape {
                    Shape::Triangle(t) => Shape::Triangle(Triangle { p: t.p.map(|p| m.transform_point3a(p)) }),
                    Shape::Sphere(s) => {
                        let scale = m.matrix3.x_axis.length();
                        Shape::Sphere(SpherePrim { center: m.transform_point3a(s.center), radius: s.radius * scale })
                    }
                };
                out.push(Prim { shape, object });
            }
        }
        out
    }

    /// Number of infinite planes.
    pub fn plane_count(&self) -> usize {
        self.planes.len()
    }

    /// Bytes held by nodes, instances and primitives.
    pub fn memory_bytes(&self) -> usize {
        self.tlas.len() * size_of::<Bvh2Node>()
            + self.instances.len() * size_of::<Instance>()
            + self.blases.iter().map(|b| b.memory_bytes()).sum::<usize>()
            + self.planes.len() * size_of::<PlanePrim>()
    }

    /// Diagonal length of the bounded geometry's box (0 when there is none).
    pub fn extent(&self) -> f32 {
        self.bounds.map_or(0.0, |(min, max)| (max - min).length())
    }

    /// Closest hit along `ray`, if any. `stack` is reusable scratch space.
    #[inline]
    pub fn intersect(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> Option<SurfaceHit> {
        let mut ray = *ray;
        let best = self.closest_instance(&mut ray, stack);
        self.hit_with_planes(ray, best)
    }

    /// [`SceneGeometry::intersect`] for each of `rays` into `hits` (same length), the same hits:
    /// in packets where the trees are eight-wide, every instance is in world space and there are
    /// triangle packets (straight into the one BLAS of a static scene, else through the top
    /// level), which suits runs of rays that travel together, such as one pixel's camera rays.
    pub fn intersect_many(&self, rays: &[Ray], stack: &mut Vec<(u32, f32)>, hits: &mut [Option<SurfaceHit>]) {
        #[cfg(target_arch = "x86_64")]
        if rays.len() >= PACKET_RUN
            && let Some(into) = self.camera_packets()
        {
            let width = packet_width().lanes();
            for (chunk, out) in rays.chunks(width).zip(hits.chunks_mut(width)) {
                let mut found = LaneHits::new(chunk);
                let live = (1u32 << chunk.len()) - 1;
                let alone = self.closest_packet(into, chunk, live, &mut found, stack) | found.tied;
                for (k, (ray, hit)) in chunk.iter().zip(out).enumerate() {
                    *hit = if alone & (1 << k) != 0 {
                        self.intersect(ray, stack)
                    } else {
                        self.hit_with_planes(ray.with_tmax(found.tmax[k]), found.best[k])
                    };
                }
            }
            return;
        }
        for (ray, hit) in rays.iter().zip(hits) {
            *hit = self.intersect(ray, stack);
        }
    }

    /// Where [`SceneGeometry::intersect_many`] traces packets, if anywhere: straight into the
    /// one world-space BLAS of triangle packets of a static scene, else through an eight-wide
    /// top level whose instances are all in world space, with some triangle packets.
    #[cfg(target_arch = "x86_64")]
    fn camera_packets(&self) -> Option<CameraPackets<'_>> {
        if let Some(blas) = &self.world_blas
            && let Tree::Eight(tree) = &blas.tree
            && !blas.packets.is_empty()
        {
            return Some(CameraPackets::World(blas, tree));
        }
        match &self.top {
            Tree::Eight(top) if self.top_packets => Some(CameraPackets::Top(top)),
            _ => None,
        }
    }

    /// One packet of [`SceneGeometry::intersect_many`] traced `into` the scene, offered to
    /// `hits`. Returns the lanes whose subtree overflowed a packet's stack.
    #[cfg(target_arch = "x86_64")]
    fn closest_packet(
        &self,
        into: CameraPackets,
        rays: &[Ray],
        live: u32,
        hits: &mut LaneHits<ClosestHit>,
        stack: &mut Vec<(u32, f32)>,
    ) -> u32 {
        let sixteen = matches!(packet_width(), PacketWidth::Sixteen);
        // SAFETY: eight-wide trees are built only where AVX was detected, and sixteen-lane
        // packets are chosen only where AVX-512 (with POPCNT) was.
        unsafe {
            match into {
                CameraPackets::World(blas, tree) if sixteen => blas.closest_lanes_avx512(tree, rays, live, 0, hits),
                CameraPackets::World(blas, tree) => blas.closest_lanes_avx(tree, rays, live, 0, hits),
                CameraPackets::Top(top) if sixteen => self.closest_top_avx512(top, rays, live, hits, stack),
                CameraPackets::Top(top) => self.closest_top_avx(top, rays, live, hits, stack),
            }
        }
    }

    /// The closest hit along `ray` given the closest primitive hit `best` (instance, slot,
    /// barycentrics) at `ray.tmax`: a plane hit before it wins.
    #[inline]
    fn hit_with_planes(&self, mut ray: Ray, best: Option<ClosestHit>) -> Option<SurfaceHit> {
        let mut plane_hit = None;
        for plane in &self.planes {
            if let Some(t) = plane.intersect(&ray) {
                ray.tmax = t;
                plane_hit = Some(plane);
            }
        }
        if let Some(plane) = plane_hit {
            return Some(plane.surface(&ray, ray.tmax));
        }
        best.map(|(i, slot, b1, b2)| self.surface(i, slot, &ray, b1, b2))
    }

    /// The surface at a hit of instance `i`'s primitive `slot`; `ray.tmax` is the world t.
    fn surface(&self, i: u32, slot: u32, ray: &Ray, b1: f32, b2: f32) -> SurfaceHit {
        let inst = &self.instances[i as usize];
        let blas = &self.blases[inst.blas as usize];
        let object = inst.object.unwrap_or(blas.prims[slot as usize].object);
        if inst.identity {
            return blas.surface(slot, ray, b1, b2, object);
        }
        // The same local ray as during traversal (a pure function of the world ray's origin and
        // direction), so the local hit is the one that was found.
        let Some((local, dt)) = inst.local_ray(&ray.with_tmax(f32::INFINITY)) else {
            return blas.surface(slot, ray, b1, b2, object);
        };
        let local = local.with_tmax(ray.tmax - dt);
        inst.to_world_hit(blas.surface(slot, &local, b1, b2, object), dt)
    }

    /// Front-to-back top-level traversal; shrinks `ray.tmax` (world t) to the closest hit and
    /// returns (instance, primitive slot, b1, b2).
    #[inline]
    fn closest_instance(&self, ray: &mut Ray, stack: &mut Vec<(u32, f32)>) -> Option<ClosestHit> {
        stack.clear();
        if let Some(blas) = &self.world_blas {
            // One world-space BLAS (a static scene): no top level to traverse.
            return blas.closest(ray, stack).map(|(slot, b1, b2)| (0, slot, b1, b2));
        }
        self.top.query(TopClosest { scene: self, ray, stack })
    }

    /// Closest hit through the top-level tree `top`.
    #[inline(always)]
    fn closest_through<const W: usize>(
        &self,
        top: &WideBvh<W>,
        ray: &mut Ray,
        stack: &mut Vec<(u32, f32)>,
    ) -> Option<ClosestHit>
    where
        Node<W>: NodeTest<W>,
    {
        let mut best = None;
        top.closest(ray, stack, |first, count, ray, stack| {
            for k in first..first + count {
                let inst = &self.instances[k as usize];
                let blas = &self.blases[inst.blas as usize];
                if inst.identity {
                    if let Some((slot, b1, b2)) = blas.closest(ray, stack) {
                        best = Some((k, slot, b1, b2));
                    }
                } else if let Some((mut local, dt)) = inst.local_ray(ray)
                    && let Some((slot, b1, b2)) = blas.closest(&mut local, stack)
                {
                    ray.tmax = ray.tmax.min(local.tmax + dt);
                    best = Some((k, slot, b1, b2));
                }
            }
        });
        best
    }

    /// Whether anything blocks `ray` in (0, tmax); stops at the first blocker found.
    #[inline]
    pub fn occluded(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let mut blocked = [false];
        self.occluded_many(std::slice::from_ref(ray), RayOrder::Mixed, stack, &mut blocked);
        blocked[0]
    }

    /// [`SceneGeometry::occluded`] for each of `rays` into `blocked` (same length; every entry is
    /// written, whatever it held), in one call:
    /// the dispatch to the tree's width and the traversal's set-up outside the loop over rays;
    /// `order` says how the rays are cut into packets.
    pub fn occluded_many(&self, rays: &[Ray], order: RayOrder, stack: &mut Vec<(u32, f32)>, blocked: &mut [bool]) {
        for (ray, b) in rays.iter().zip(blocked.iter_mut()) {
            *b = self.planes.iter().any(|p| p.intersect(ray).is_some());
        }
        stack.clear();
        if let Some(blas) = &self.world_blas {
            // One world-space BLAS (a static scene): no top level to traverse.
            blas.occluded_many(rays, order, stack, blocked);
        } else {
            #[cfg(target_arch = "x86_64")]
            if let Tree::Eight(top) = &self.top
                && rays.len() >= PACKET_RUN
            {
                // SAFETY: an eight-wide tree is built only where AVX was detected, and
                // sixteen-lane packets are chosen only where AVX-512 (with POPCNT) was.
                return unsafe {
                    match packet_width() {
                        PacketWidth::Sixteen => self.occluded_packets_avx512(top, rays, order, stack, blocked),
                        PacketWidth::Eight => self.occluded_packets_avx(top, rays, order, stack, blocked),
                    }
                };
            }
            let _ = order;
            self.top.query(OccludedEach { target: self, rays, stack, blocked });
        }
    }

    /// Whether anything in instances `first..first + count` (a top-level leaf) blocks `ray`.
    #[inline(always)]
    fn instances_block(&self, first: u32, count: u32, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let instances = &self.instances[first as usize..(first + count) as usize];
        instances.iter().any(|inst| self.instance_blocks(inst, ray, stack))
    }

    /// Whether anything in instance `inst` blocks `ray` (world space).
    #[inline(always)]
    fn instance_blocks(&self, inst: &Instance, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let blas = &self.blases[inst.blas as usize];
        if inst.identity {
            blas.occluded(ray, stack)
        } else {
            inst.local_ray(ray).is_some_and(|(local, _)| blas.occluded(&local, stack))
        }
    }

    /// Intersects one world-space primitive: (t, b1, b2).
    #[inline(always)]
    pub fn hit_prim(prim: &Prim, ray: &Ray) -> Option<(f32, f32, f32)> {
        hit_prim(prim, ray, &Shear::new(ray.dir))
    }

    /// Closest hit by testing every primitive of every instance (for tests and validation).
    pub fn intersect_brute_force(&self, ray: &Ray) -> Option<SurfaceHit> {
        let mut ray = *ray;
        let mut best = None;
        for (i, inst) in self.instances.iter().enumerate() {
            let blas = &self.blases[inst.blas as usize];
            let (mut local, dt) = if inst.identity {
                (ray, 0.0)
            } else {
                match inst.local_ray(&ray) {
                    Some(local) => local,
                    None => continue,
                }
            };
            let shear = Shear::new(local.dir);
            for (slot, prim) in blas.prims.iter().enumerate() {
                if let Some((t, b1, b2)) = hit_prim(prim, &local, &shear) {
                    local.tmax = t;
                    ray.tmax = t + dt;
                    best = Some((i as u32, slot as u32, b1, b2));
                }
            }
        }
        let mut plane_hit = None;
        for plane in &self.planes {
            if let Some(t) = plane.intersect(&ray) {
                ray.tmax = t;
                plane_hit = Some(plane.surface(&ray, t));
            }
        }
        plane_hit.or_else(|| best.map(|(i, slot, b1, b2)| self.surface(i, slot, &ray, b1, b2)))
    }
}

/// Occlusion through the top-level tree.
impl Occluder for SceneGeometry {
    #[inline(always)]
    fn occluded_in<const W: usize>(&self, top: &WideBvh<W>, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool
    where
        Node<W>: NodeTest<W>,
    {
        top.occluded(ray, stack, |first, count, stack| self.instances_block(first, count, ray, stack))
    }
}

/// The world-space geometric normal of a mesh triangle placed by `to_world`, oriented by the
/// mesh's winding (counter-clockwise = front) whatever the sign of the transform's determinant:
/// normals transform by the inverse transpose, so a mirroring transform keeps them outward.
pub fn outward_normal(mesh: &Mesh, triangle: usize, to_world: &Affine3A) -> Vec3 {
    let [a, b, c] = mesh.indices[triangle].map(|i| mesh.positions[i as usize]);
    let n = (b - a).cross(c - a);
    (to_world.matrix3.inverse().transpose() * Vec3A::from(n)).normalize().into()
}
