//! The scene's queries of many rays at once: camera rays' closest hits and occlusion, traced in
//! packets through the top level where the trees allow, and the top level's packet kernels,
//! written once over the lane type and compiled per instruction set by
//! [`Lanes::compiled`](crate::simd::Lanes::compiled). The rays that reach an instance go on
//! through its BLAS's kernels (`blas_packets`).

#[cfg(target_arch = "x86_64")]
use super::{
    blas::{Blas, PACKET_RUN},
    blas_packets::{BlasClosestLanes, BlasLanesOf, KernelLanes},
    ray_order::in_packets,
    scene::hit_ids,
    tlas::Instance,
    tree::{ClosestHit, Tree},
};
use super::{
    ray_order::RayOrder,
    scene::{RayEnd, SceneGeometry},
    tree::OccludedEach,
};
use crate::geometry::{hit::SurfaceHit, ray::Ray};
#[cfg(target_arch = "x86_64")]
use crate::geometry::{
    lanes::{PacketLanes, RayLanes},
    surface_lanes::{HitColumns, SurfaceColumns, SurfaceLanes},
    wide_bvh::{Bvh8, FusedPacket, LaneHits, PACKET_MIN_LANES, RayPacket},
};
#[cfg(target_arch = "x86_64")]
use crate::simd::{Kernel, run_in};

impl SceneGeometry {
    /// [`SceneGeometry::intersect`] for each of `rays`, the same hits:
    /// in packets where the trees are eight-wide and there are triangle packets (straight into
    /// the one BLAS of a static scene, else through the top level and into each instance in its
    /// own frame), which suits runs of rays that travel together, such as one pixel's camera
    /// rays.
    /// Writes `make(ray, hit)` of each `rays[k]`'s hit (`None` where it has none) to `out[k]`.
    pub fn intersect_many<T>(
        &self,
        rays: &[Ray],
        stack: &mut Vec<(u32, f32)>,
        out: &mut [Option<T>],
        make: impl Fn(&Ray, SurfaceHit) -> T,
    ) {
        if self.alpha.is_some() {
            // Alpha-tested meshes take the single-ray path.
            for (k, ray) in rays.iter().enumerate() {
                out[k] = self.intersect(ray, stack).map(|hit| make(ray, hit));
            }
            return;
        }
        #[cfg(target_arch = "x86_64")]
        if rays.len() >= PACKET_RUN
            && let Some(into) = self.camera_packets()
        {
            let mut lanes = (HitColumns::default(), SurfaceColumns::default());
            self.closest_packets(into, rays, stack, |at, chunk, found, alone, stack| {
                let packet = (chunk, found, alone);
                self.packet_hits_into(packet, stack, &mut lanes, &mut out[at..][..chunk.len()], &make);
            });
            return;
        }
        self.closest_each(rays, stack, |k, ray, end| self.hit_at_into(ray, end, &mut out[k], |hit| make(ray, hit)));
    }

    /// Where each of `rays` ends ([`RayEnd`]) into `ends` (same length), found as
    /// [`SceneGeometry::intersect_many`] finds its hits; `false` (and nothing written) where
    /// the scene has alpha-tested meshes, whose hits a [`RayEnd`] does not hold.
    pub fn ray_ends(&self, rays: &[Ray], stack: &mut Vec<(u32, f32)>, ends: &mut [RayEnd]) -> bool {
        if self.alpha.is_some() {
            return false;
        }
        self.closest_each(rays, stack, |k, _, end| ends[k] = end);
        true
    }

    /// Calls `out(k, ray, end)` with where each `rays[k]` ends among the opaque primitives
    /// (planes aside): in packets where the scene allows ([`SceneGeometry::camera_packets`]).
    #[inline(always)]
    fn closest_each(&self, rays: &[Ray], stack: &mut Vec<(u32, f32)>, mut out: impl FnMut(usize, &Ray, RayEnd)) {
        #[cfg(target_arch = "x86_64")]
        if rays.len() >= PACKET_RUN
            && let Some(into) = self.camera_packets()
        {
            self.closest_packets(into, rays, stack, |at, chunk, found, alone, stack| {
                for (k, ray) in chunk.iter().enumerate() {
                    let end = if alone & (1 << k) != 0 {
                        self.ray_end(ray, stack)
                    } else {
                        RayEnd::new(found.best[k], found.tmax[k])
                    };
                    out(at + k, ray, end);
                }
            });
            return;
        }
        for (k, ray) in rays.iter().enumerate() {
            out(k, ray, self.ray_end(ray, stack));
        }
    }

    /// Traces `rays` `into` the scene a packet at a time, calling `each(at, chunk, found,
    /// alone, stack)` for the packet of `rays[at..]`: its closest hits in `found`, and the
    /// lanes it leaves to be traced alone (their subtree overflowed a packet's stack, or a hit
    /// tied at their closest distance) in `alone`.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn closest_packets(
        &self,
        into: CameraPackets,
        rays: &[Ray],
        stack: &mut Vec<(u32, f32)>,
        mut each: impl FnMut(usize, &[Ray], &LaneHits<ClosestHit>, u32, &mut Vec<(u32, f32)>),
    ) {
        let width = crate::simd::packet_lanes();
        for (c, chunk) in rays.chunks(width).enumerate() {
            let mut found = LaneHits::new(chunk);
            let live = (1u32 << chunk.len()) - 1;
            let alone = self.closest_packet(into, chunk, live, &mut found, stack) | found.tied;
            each(c * width, chunk, &found, alone, stack);
        }
    }

    /// The hits of one packet of [`SceneGeometry::intersect_many`] (its rays, their closest
    /// hits and the lanes it leaves alone) made into `out` by `make`: the hits on triangle
    /// packets of world-space instances with no plane before them as surfaces in lanes
    /// (`lanes`' columns), the others one by one.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    fn packet_hits_into<T>(
        &self,
        (rays, found, alone): (&[Ray], &LaneHits<ClosestHit>, u32),
        stack: &mut Vec<(u32, f32)>,
        (columns, surfaces): &mut (HitColumns, SurfaceColumns),
        out: &mut [Option<T>],
        make: &impl Fn(&Ray, SurfaceHit) -> T,
    ) {
        let mut in_lanes = 0u32;
        for (k, ray) in rays.iter().enumerate() {
            if let Some((i, slot, b1, b2)) = found.best[k]
                && alone & (1 << k) == 0
                && let inst = &self.instances[i as usize]
                && inst.identity
                && let Some(packet) = self.blases[inst.blas as usize].packets.get(slot as usize / 4)
                && !self.plane_before(ray, found.tmax[k])
            {
                columns.set(k, packet.vertices(slot as usize % 4), [b1, b2], ray.dir.to_array());
                in_lanes |= 1 << k;
            }
        }
        if in_lanes != 0 {
            let kernel = SurfaceLanes { hits: columns, n: rays.len(), out: surfaces };
            run_in(crate::simd::packet_lanes(), kernel).expect("eight or sixteen lanes");
        }
        for (k, (ray, out)) in rays.iter().zip(out.iter_mut()).enumerate() {
            if in_lanes & (1 << k) == 0 {
                let end = if alone & (1 << k) != 0 {
                    self.ray_end(ray, stack)
                } else {
                    RayEnd::new(found.best[k], found.tmax[k])
                };
                self.hit_at_into(ray, end, out, |hit| make(ray, hit));
                continue;
            }
            let (i, slot, b1, b2) = found.best[k].expect("a hit made in lanes");
            let inst = &self.instances[i as usize];
            let (object, prim) = hit_ids(inst, &self.blases[inst.blas as usize], slot);
            let lane = |c: &[[f32; 16]; 3]| glam::Vec3A::new(c[0][k], c[1][k], c[2][k]);
            let (p, p_error, normal) = (lane(&surfaces.p), lane(&surfaces.p_error), lane(&surfaces.normal));
            *out = Some(make(ray, SurfaceHit { t: found.tmax[k], p, p_error, normal, object, prim, bary: [b1, b2] }));
        }
    }

    /// Where [`SceneGeometry::intersect_many`] traces packets, if anywhere: straight into the
    /// one world-space BLAS of triangle packets of a static scene, else through an eight-wide
    /// top level, with some triangle packets.
    #[cfg(target_arch = "x86_64")]
    fn camera_packets(&self) -> Option<CameraPackets<'_>> {
        if let Some(blas) = &self.world_blas
            && let Tree::Eight(tree, _) = &blas.tree
            && !blas.packets.is_empty()
        {
            return Some(CameraPackets::World(blas, tree));
        }
        match &self.top {
            Tree::Eight(top, _) if self.top_packets => Some(CameraPackets::Top(top)),
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
        // Packets are eight or sixteen wide where `simd::isa` allows them.
        match into {
            CameraPackets::World(blas, tree) => {
                let kernel = BlasClosestLanes { blas, tree, rays, live, instance: 0, hits };
                run_in(crate::simd::packet_lanes(), kernel)
            }
            CameraPackets::Top(top) => {
                run_in(crate::simd::packet_lanes(), TopClosestLanes { scene: self, top, rays, live, hits, stack })
            }
        }
        .expect("eight or sixteen lanes")
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
        self.opaque_occluded_many(rays, order, stack, blocked);
        if let Some(alpha) = &self.alpha {
            for (ray, b) in rays.iter().zip(blocked.iter_mut()) {
                *b = *b || alpha.occluded(ray, stack);
            }
        }
    }

    /// [`SceneGeometry::occluded_many`] for everything but the alpha-tested meshes.
    #[inline(always)]
    fn opaque_occluded_many(&self, rays: &[Ray], order: RayOrder, stack: &mut Vec<(u32, f32)>, blocked: &mut [bool]) {
        for (ray, b) in rays.iter().zip(blocked.iter_mut()) {
            *b = self.planes.iter().any(|p| p.intersect(ray).is_some());
        }
        stack.clear();
        if let Some(blas) = &self.world_blas {
            // One world-space BLAS (a static scene): no top level to traverse.
            blas.occluded_many(rays, order, stack, blocked);
        } else {
            #[cfg(target_arch = "x86_64")]
            if let Tree::Eight(top, _) = &self.top
                && rays.len() >= PACKET_RUN
            {
                let kernel = TopPackets { scene: self, top, rays, order, stack, blocked };
                // Packets are eight or sixteen wide where `simd::isa` allows them.
                return run_in(crate::simd::packet_lanes(), kernel).expect("eight or sixteen lanes");
            }
            let _ = order;
            self.top.query(OccludedEach { target: self, rays, stack, blocked });
        }
    }
}

/// Where [`SceneGeometry::intersect_many`] traces a packet.
#[cfg(target_arch = "x86_64")]
#[derive(Clone, Copy)]
enum CameraPackets<'a> {
    /// Straight into a static scene's one world-space BLAS of triangle packets, and its tree.
    World(&'a Blas, &'a Bvh8),
    /// Through the top level.
    Top(&'a Bvh8),
}

/// The closest hits of `rays` (one packet; lanes of `live`) through the top-level tree `top`,
/// traced together and offered to `hits` (instance, slot, b1, b2): exactly what
/// [`SceneGeometry::intersect`] finds before the planes, except that a second hit at exactly a
/// lane's closest distance (in another triangle or instance), or within rounding of it where a
/// placed instance's distance is one of the two, is marked a tie. An instance's BLAS of
/// triangle packets takes the rays it gets as a packet (a placed instance's moved into its
/// frame lane by lane, [`placed_closest`]), any other BLAS each ray alone. Returns the lanes
/// whose subtree overflowed a packet's stack; trace those, and the tied ones, alone.
#[cfg(target_arch = "x86_64")]
struct TopClosestLanes<'a> {
    scene: &'a SceneGeometry,
    top: &'a Bvh8,
    rays: &'a [Ray],
    live: u32,
    hits: &'a mut LaneHits<ClosestHit>,
    stack: &'a mut Vec<(u32, f32)>,
}

#[cfg(target_arch = "x86_64")]
impl<L: KernelLanes> Kernel<L> for TopClosestLanes<'_> {
    type Output = u32;
    #[inline(always)]
    fn run(self, isa: L::Isa) -> u32 {
        let TopClosestLanes { scene, top, rays, live, hits, stack } = self;
        let mut overflow = 0u32;
        // The lanes moved into a placed instance's frame, filled once per packet: each instance
        // rewrites the lanes that enter it, and the others are never read.
        let mut local: [Ray; 16] = std::array::from_fn(|k| rays[k.min(rays.len() - 1)]);
        let leaf = |first: u32, count: u32, lanes: u32, hits: &mut LaneHits<ClosestHit>| {
            for i in first..first + count {
                let inst = &scene.instances[i as usize];
                let blas = &scene.blases[inst.blas as usize];
                if !inst.identity {
                    let moved = &mut local[..rays.len()];
                    overflow |= placed_closest::<L>(isa, (i, inst, blas), (rays, moved), lanes, hits, stack);
                    continue;
                }
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

/// The closest hits in placed instance `i` (`inst`, of `blas`) of the lanes `lanes` of
/// `rays`, offered to `hits` at their world distances ([`LaneHits::offer_inexact`]): each lane
/// moved into the instance's frame as [`SceneGeometry::intersect`] moves its ray there
/// (`Instance::local_ray` of its probe, written to `local`, whose other lanes hold any ray and
/// are not read), and the moved rays traced as one packet in the
/// instance's tree where it has triangle packets and two or more lanes enter, else one by
/// one. Returns the lanes to trace alone (their subtree overflowed the packet's stack, or two
/// hits in the instance tied).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn placed_closest<L: KernelLanes>(
    isa: L::Isa,
    (i, inst, blas): (u32, &Instance, &Blas),
    (rays, local): (&[Ray], &mut [Ray]),
    lanes: u32,
    hits: &mut LaneHits<ClosestHit>,
    stack: &mut Vec<(u32, f32)>,
) -> u32 {
    let (mut shift, mut live) = ([0.0f32; 16], 0u32);
    let mut each = lanes;
    while each != 0 {
        let k = each.trailing_zeros() as usize;
        each &= each - 1;
        if let Some((ray, dt)) = inst.local_ray(&hits.probe(rays, k)) {
            (local[k], shift[k], live) = (ray, dt, live | 1 << k);
        }
    }
    let mut found = LaneHits::new(local);
    let mut alone = 0;
    match &blas.tree {
        Tree::Eight(tree, _) if !blas.packets.is_empty() && live.count_ones() >= 2 => {
            let kernel = BlasClosestLanes { blas, tree, rays: local, live, instance: i, hits: &mut found };
            alone = L::compiled(isa, kernel) | found.tied;
        }
        _ => {
            let mut each = live;
            while each != 0 {
                let k = each.trailing_zeros() as usize;
                each &= each - 1;
                if let Some((slot, b1, b2)) = blas.closest(&mut local[k], stack) {
                    (found.tmax[k], found.best[k]) = (local[k].tmax, Some((i, slot, b1, b2)));
                }
            }
        }
    }
    let mut each = live & !alone;
    while each != 0 {
        let k = each.trailing_zeros() as usize;
        each &= each - 1;
        if let Some(hit) = found.best[k] {
            hits.offer_inexact(k, found.tmax[k] + shift[k], hit);
        }
    }
    alone
}

/// [`SceneGeometry::occluded_many`] through the top level by packets of consecutive rays, as
/// within one BLAS; an instance reached by at least [`PACKET_MIN_LANES`] of a packet's rays
/// gets them as one packet in its own frame.
#[cfg(target_arch = "x86_64")]
struct TopPackets<'a> {
    scene: &'a SceneGeometry,
    top: &'a Bvh8,
    rays: &'a [Ray],
    order: RayOrder,
    stack: &'a mut Vec<(u32, f32)>,
    blocked: &'a mut [bool],
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
/// top-level tree `top` (a kernel of its own, as a BLAS's lone ray is).
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
