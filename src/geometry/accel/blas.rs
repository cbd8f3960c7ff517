//! Bottom-level BVHs: one per unique mesh, in its own frame.

use std::time::Duration;

use glam::{Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::{Bvh2, builder::build_bvh2, node::Bvh2Node},
};
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
use super::kernels::BlasPackets;
use super::{
    PAR_CHUNK, Prim, Shape, hit_prim,
    ray_order::RayOrder,
    tree::{OccludedEach, Occluder, Tree, TreeQuery},
};
use crate::components::Mesh;
#[cfg(target_arch = "x86_64")]
use crate::geometry::lanes::PacketLanes;
#[cfg(target_arch = "x86_64")]
use crate::geometry::tri4::RayTriPacket;
use crate::geometry::{
    binned_sah,
    hit::SurfaceHit,
    ray::{Ray, Shear},
    shapes::Triangle,
    tri4::{RayTri4, Tri4},
    wide_bvh::{NodeTest, WideBvh, prefetch},
};
use crate::simd::{Kernel, Lanes};
#[cfg(target_arch = "x86_64")]
use crate::simd::{packet_lanes, run_in};

/// The BVH2 build settings for small sets (under [`SMALL_SET`] primitives): obvhs's medium
/// preset with leaves of at most one packet, collapsed less eagerly (traversal cost 1.5 instead
/// of 3): small scenes trace much faster with them, while meshes of a few thousand triangles
/// and more trace a little slower. Larger sets get [`binned_sah::build`].
fn small_set_params() -> BvhBuildParams {
    BvhBuildParams { max_prims_per_leaf: 4, collapse_traversal_cost: 1.5, ..BvhBuildParams::medium_build() }
}

/// Fewest rays in one [`Blas::occluded_many`] call for packet traversal (a point light's
/// single shadow ray goes on its own).
pub(super) const PACKET_RUN: usize = 4;

/// Primitive count under which a BLAS gets small leaves (see [`small_set_params`]).
pub(super) const SMALL_SET: usize = 1024;

/// A bottom-level BVH: an obvhs BVH2 over primitives stored in leaf order.
#[derive(Clone)]
pub struct Blas {
    bvh: Bvh2,
    /// The BVH2 collapsed to a wide tree, which traversal uses. Its leaves are ranges of
    /// `packets` when every primitive is a triangle, else ranges of `prims`.
    pub(super) tree: Tree,
    /// Each leaf's triangles in packets of four, when every primitive is a triangle.
    pub(super) packets: Vec<Tri4>,
    /// The primitives in leaf order.
    pub(super) prims: Vec<Prim>,
    /// Triangles stored.
    pub triangle_count: usize,
    /// Zero-area triangles dropped at build time (they can never be hit).
    pub degenerate_triangles: usize,
    /// Depth of the tree.
    pub depth: usize,
    /// For a world-space bake of textured meshes, each slot's triangle index in its mesh
    /// (`None` elsewhere): read once per camera hit, never during traversal.
    pub(super) source_triangles: Option<Vec<u32>>,
}

impl Blas {
    /// Builds a BVH over `prims` (in any order) that is never refit: by
    /// [`binned_sah::build_with_spatial_splits`] from 1024 primitives up where all are
    /// triangles (the spatial splits only where enough of them are large), by
    /// [`binned_sah::build`] from 1024 up otherwise, else by obvhs's PLOC with its medium
    /// preset and leaves of at most one packet. (obvhs's spatial pre-splits traced slower and
    /// cost build time without lowering the SAH cost; splits chosen node by node pay off in
    /// scenes of large triangles such as Sponza.)
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
            source_triangles: None,
        };
        blas.build_tree();
        blas
    }

    /// This BLAS, built from primitives whose triangle indices in their meshes were
    /// `triangles` (in the order given to [`Blas::build`]), keeping each slot's index so that
    /// hits on it report their triangle.
    pub fn with_source_triangles(mut self, triangles: &[u32]) -> Self {
        let slots = self.bvh.primitive_indices.iter().map(|&i| triangles.get(i as usize).copied().unwrap_or(u32::MAX));
        self.source_triangles = Some(slots.collect());
        self
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
        self.packets = crate::geometry::huge_pages::vec_on_huge_pages(lanes.len());
        self.packets.par_extend(
            lanes.par_iter().with_min_len(PAR_CHUNK / 4).map(|&(first, end)| Tri4::pack((first..end).map(triangle))),
        );
    }

    /// A mesh's triangles in its own frame; zero-area triangles are counted and skipped. Each
    /// primitive's `object` is its triangle's index in the mesh (the instance names the object),
    /// which a hit reports for textured surfaces.
    pub fn from_mesh(mesh: &Mesh) -> Self {
        let mut prims = Vec::with_capacity(mesh.indices.len());
        let mut degenerate = 0;
        for (k, tri) in mesh.indices.iter().enumerate() {
            let [a, b, c] = tri.map(|i| Vec3A::from(mesh.positions[i as usize]));
            match Triangle::new(a, b, c) {
                Some(t) => prims.push(Prim { shape: Shape::Triangle(t), object: k as u32 }),
                None => degenerate += 1,
            }
        }
        let mut blas = Blas::build(prims);
        blas.degenerate_triangles = degenerate;
        blas
    }

    /// A BLAS for a deforming mesh: every triangle keeps its slot (zero-area ones included, they
    /// are never hit) so that [`Blas::refit`] can move the vertices without rebuilding; as in
    /// [`Blas::from_mesh`], a primitive's `object` is its triangle's index.
    pub fn deformable(mesh: &Mesh) -> Self {
        let prims = mesh.indices.iter().enumerate().map(|(k, tri)| {
            let p = tri.map(|i| Vec3A::from(mesh.positions[i as usize]));
            Prim { shape: Shape::Triangle(Triangle { p }), object: k as u32 }
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
            + self.source_triangles.as_ref().map_or(0, |t| t.len() * 4)
    }

    /// Children per node of the tree traversal uses (8 with AVX, else 4).
    pub fn node_width(&self) -> usize {
        self.tree.width()
    }

    /// Front-to-back traversal; shrinks `ray.tmax` to the closest hit and returns the
    /// primitive slot and barycentrics. Uses `stack` above its current length only.
    #[inline]
    pub(super) fn closest(&self, ray: &mut Ray, stack: &mut Vec<(u32, f32)>) -> Option<(u32, f32, f32)> {
        self.tree.query(BlasClosest { blas: self, ray, stack })
    }

    #[inline(always)]
    pub(super) fn closest_in<const W: usize>(
        &self,
        tree: &WideBvh<W>,
        node_test: impl NodeTest<W>,
        ray: &mut Ray,
        stack: &mut Vec<(u32, f32)>,
    ) -> Option<(u32, f32, f32)> {
        let prims = &self.prims;
        let mut best = None;
        if !self.packets.is_empty() {
            let r = RayTri4::new(ray);
            tree.closest(node_test, ray, stack, |first, count, ray, _| {
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
        tree.closest(node_test, ray, stack, |first, count, ray, _| {
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
    pub(super) fn occluded(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let mut blocked = [false];
        let rays = std::slice::from_ref(ray);
        self.tree.query(OccludedEach { target: self, rays, stack, blocked: &mut blocked });
        blocked[0]
    }

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

    /// The lanes of `lanes` whose ray (`ray(k)` for lane k) a triangle in packets
    /// `first..first + count` blocks, each triangle tested against all those rays at once.
    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    pub(super) fn packets_block_lanes<L: PacketLanes>(
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
                let edges = packet.edges_packet(lane, r);
                let (pass, mut exact) = (edges.pass & open, edges.exact & open);
                if pass | exact == 0 {
                    continue;
                }
                let tri = packet.triangle(lane);
                if pass != 0 {
                    open &= !(r.plane_hits(&tri) & pass);
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
    pub(super) fn prefetch_packets(&self, first: u32, count: u32) {
        for packet in &self.packets[first as usize..(first + count) as usize] {
            prefetch(packet);
        }
    }

    /// Whether a triangle in packets `first..first + count` blocks `ray`, by the copy of the
    /// test compiled for a tree of width `W`: for AVX2 under eight-wide trees. Both copies are
    /// out of line, so the packet test's set-up runs per leaf reached, not per ray (most AO
    /// rays reach none).
    #[inline(always)]
    pub(super) fn packets_block<const W: usize, T: NodeTest<W>>(
        &self,
        test: T,
        first: u32,
        count: u32,
        ray: &Ray,
    ) -> bool {
        T::Lanes::compiled_apart(test, PacketsBlock { blas: self, first, count, ray })
    }

    /// Tests the triangles of `packet` in lane order, calling `hit(slot, (t, b1, b2), ray)` for
    /// each hit in (0, ray.tmax) (the callback may shrink `ray.tmax`); stops and returns true as
    /// soon as `hit` does. Gives exactly the hits of the scalar test in the same order.
    #[inline(always)]
    pub(super) fn packet_hits(
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

    pub(super) fn surface(&self, slot: u32, ray: &Ray, b1: f32, b2: f32, object: u32) -> SurfaceHit {
        let prim = &self.prims[slot as usize];
        match prim.shape {
            Shape::Triangle(tri) => tri.surface(ray, ray.tmax, b1, b2, object),
            Shape::Sphere(s) => s.surface(ray, ray.tmax, object),
        }
    }
}

/// [`Blas::packets_block`] as a kernel: the single-ray packet test of one leaf.
struct PacketsBlock<'a> {
    blas: &'a Blas,
    first: u32,
    count: u32,
    ray: &'a Ray,
}

impl<L: Lanes> Kernel<L> for PacketsBlock<'_> {
    type Output = bool;
    #[inline(always)]
    fn run(self, _: L::Isa) -> bool {
        let PacketsBlock { blas, first, count, ray } = self;
        let r = RayTri4::new(ray);
        let mut local = *ray;
        for k in first as usize..(first + count) as usize {
            if blas.packet_hits(&blas.packets[k], &r, &mut local, |_, _, _| true) {
                return true;
            }
        }
        false
    }
}

impl Occluder for Blas {
    #[inline(always)]
    fn occluded_in<const W: usize>(
        &self,
        tree: &WideBvh<W>,
        node_test: impl NodeTest<W>,
        ray: &Ray,
        stack: &mut Vec<(u32, f32)>,
    ) -> bool {
        let prims = &self.prims;
        if !self.packets.is_empty() {
            return tree
                .occluded(node_test, ray, stack, |first, count, _| self.packets_block(node_test, first, count, ray));
        }
        let shear = Shear::new(ray.dir);
        tree.occluded(node_test, ray, stack, |first, count, _| {
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
pub(crate) fn subtree_depth(nodes: &[Bvh2Node]) -> usize {
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

/// Closest hit in a BLAS: (primitive slot, b1, b2).
pub(super) struct BlasClosest<'a> {
    pub(super) blas: &'a Blas,
    pub(super) ray: &'a mut Ray,
    pub(super) stack: &'a mut Vec<(u32, f32)>,
}

impl TreeQuery for BlasClosest<'_> {
    type Output = Option<(u32, f32, f32)>;
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>, node_test: impl NodeTest<W>) -> Self::Output {
        self.blas.closest_in(tree, node_test, self.ray, self.stack)
    }
}
