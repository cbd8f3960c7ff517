//! Bottom-level BVHs: one per unique mesh, in its own frame.

use std::{sync::OnceLock, time::Duration};

use glam::{Vec3, Vec3A};
use obvhs::{
    BvhBuildParams,
    aabb::Aabb,
    bvh2::{Bvh2, builder::build_bvh2, node::Bvh2Node},
};
use rayon::prelude::*;

#[cfg(target_arch = "x86_64")]
use super::{
    PAR_CHUNK, Prim, Shape, hit_prim,
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
    wide_bvh::{NodeTest, SahCost, WideBvh},
};
use crate::simd::{Kernel, Lanes, prefetch};

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

/// A bottom-level BVH: a wide tree over primitives stored in leaf order.
///
/// An all-triangle BLAS keeps its triangles only in the leaves' packets of four, where
/// primitive slot `4p + l` is lane `l` of packet `p`; a BLAS with spheres keeps its primitives
/// in leaf order, slot `k` being the `k`-th. The binary tree it was collapsed from is dropped
/// once the wide tree is built, except where it is refit.
#[derive(Clone)]
pub struct Blas {
    /// The binary tree as built, kept for [`Blas::refit`] in a deformable BLAS only.
    refit_tree: Option<Bvh2>,
    /// Bounds of everything in this BLAS (`None` when it is empty).
    bounds: Option<Aabb>,
    /// Nodes of the binary tree as built.
    binary_nodes: usize,
    /// The BVH2 collapsed to a wide tree, which traversal uses. Its leaves are ranges of
    /// `packets` when every primitive is a triangle, else ranges of `prims`.
    pub(super) tree: Tree,
    /// Each leaf's triangles in packets of four, when every primitive is a triangle.
    pub(super) packets: Vec<Tri4>,
    /// Each packet lane's [`Prim::object`] (`u32::MAX` in unused lanes), beside `packets`.
    objects: Vec<u32>,
    /// The primitives in leaf order, when some are not triangles.
    pub(super) prims: Vec<Prim>,
    /// Primitives in the leaves (a triangle that spatial splits put in several leaves once per
    /// leaf).
    slots: usize,
    /// Triangles stored.
    pub triangle_count: usize,
    /// Zero-area triangles dropped at build time (they can never be hit).
    pub degenerate_triangles: usize,
    /// Depth of the tree.
    pub depth: usize,
    /// For a world-space bake of textured meshes, each slot's triangle index in its mesh
    /// (`None` elsewhere): read once per camera hit, never during traversal.
    pub(super) source_triangles: Option<Vec<u32>>,
    /// The wide tree's [`SahCost`], worked out the first time [`Blas::sah_cost`] is asked for
    /// (a frame that only moves instances asks again) and again after a refit.
    sah: OnceLock<Option<SahCost>>,
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
        Blas::build_with(prims, true, None)
    }

    /// [`Blas::build`] over indexed triangles, keeping each slot's `sources` entry (the
    /// triangle's index in its mesh, in the order of `triangles`) where given, so that hits on
    /// it report their triangle.
    pub(crate) fn build_indexed(triangles: IndexedTriangles, sources: Option<&[u32]>) -> Self {
        Blas::build_with(triangles, true, sources)
    }

    /// [`Blas::build`], with or without spatial splits. Without them each primitive is in one
    /// leaf, and the binary tree is kept so that a deformable BLAS can be refit.
    fn build_with(input: impl BuildInput, spatial_splits: bool, sources: Option<&[u32]>) -> Self {
        let len = input.len();
        let triangle_count = input.triangle_count();
        let prim = |i: usize| input.prim(i as u32);
        let (bvh, depth) = if len == 0 {
            (Bvh2::default(), 0)
        } else if len < SMALL_SET {
            let aabbs: Vec<Aabb> = (0..len).map(|i| prim(i).bounds()).collect();
            let bvh = build_bvh2(&aabbs, small_set_params(), &mut Duration::default());
            let depth = subtree_depth(&bvh.nodes);
            (bvh, depth)
        } else if spatial_splits && triangle_count == len {
            binned_sah::build_with_spatial_splits(len, |i| triangle_of(&prim(i)).p)
        } else {
            binned_sah::build(len, |i| prim(i).bounds())
        };
        let mut blas = Blas {
            refit_tree: None,
            bounds: bvh.nodes.first().map(|n| *n.aabb()),
            binary_nodes: bvh.nodes.len(),
            tree: Tree::from_bvh2(&bvh.nodes),
            packets: Vec::new(),
            objects: Vec::new(),
            prims: Vec::new(),
            slots: bvh.primitive_indices.len(),
            triangle_count,
            degenerate_triangles: 0,
            depth,
            source_triangles: None,
            sah: OnceLock::new(),
        };
        let mut bvh = bvh;
        if spatial_splits {
            // Traversal reads the wide tree: the binary nodes go before the packets are written,
            // unless the BLAS is refit.
            bvh.nodes = Vec::new();
        }
        let order = &bvh.primitive_indices;
        let inputs = if len > 0 && triangle_count == len {
            let inputs = blas.pack(order, |i| triangle_of(&input.prim(i)));
            blas.objects = slot_values(&inputs, |i| input.prim(i).object);
            inputs
        } else {
            blas.prims = order.par_iter().with_min_len(PAR_CHUNK).map(|&i| input.prim(i)).collect();
            order.clone()
        };
        blas.source_triangles =
            sources.map(|t| slot_values(&inputs, |i| t.get(i as usize).copied().unwrap_or(u32::MAX)));
        if !spatial_splits {
            blas.refit_tree = Some(bvh);
        }
        blas
    }

    /// Packs each leaf's triangles (`triangle(i)` for input primitive `i`; the leaves hold
    /// ranges of `order`) into packets of four and points the leaves at their packets: returns
    /// the input primitive behind each packet lane (`u32::MAX` in unused lanes).
    fn pack(&mut self, order: &[u32], triangle: impl Fn(u32) -> Triangle + Sync) -> Vec<u32> {
        // Leaves in node order get consecutive packet ranges; the packets are filled in parallel.
        let mut lanes = Vec::new();
        self.tree.map_leaves(|first, count| {
            let start = lanes.len() as u32;
            lanes.extend((first..first + count).step_by(4).map(|lane0| (lane0, (lane0 + 4).min(first + count))));
            (start, lanes.len() as u32 - start)
        });
        // Written straight into an allocation of the right size, advised onto huge pages.
        self.packets = crate::geometry::huge_pages::vec_on_huge_pages(lanes.len());
        self.packets.par_extend(lanes.par_iter().enumerate().with_min_len(PAR_CHUNK / 4).map(|(p, &(first, end))| {
            Tri4::pack((first..end).enumerate().map(|(l, k)| ((4 * p + l) as u32, triangle(order[k as usize]))))
        }));
        let mut inputs = vec![u32::MAX; 4 * lanes.len()];
        for (packet, &(first, end)) in inputs.chunks_exact_mut(4).zip(&lanes) {
            for (lane, k) in packet.iter_mut().zip(first..end) {
                *lane = order[k as usize];
            }
        }
        inputs
    }

    /// A mesh's triangles in its own frame; zero-area triangles are counted and skipped. Each
    /// primitive's `object` is its triangle's index in the mesh (the instance names the object),
    /// which a hit reports for textured surfaces.
    pub fn from_mesh(mesh: &Mesh) -> Self {
        let mut input = IndexedTriangles::with_vertices(mesh);
        input.triangles.reserve_exact(mesh.indices.len());
        input.objects.reserve_exact(mesh.indices.len());
        let mut degenerate = 0;
        for (k, &tri) in mesh.indices.iter().enumerate() {
            let [a, b, c] = tri.map(|i| input.positions[i as usize]);
            if Triangle::new(a, b, c).is_some() {
                input.triangles.push(tri);
                input.objects.push(k as u32);
            } else {
                degenerate += 1;
            }
        }
        let mut blas = Blas::build_indexed(input, None);
        blas.degenerate_triangles = degenerate;
        blas
    }

    /// A BLAS for a deforming mesh: every triangle keeps its slot (zero-area ones included, they
    /// are never hit) so that [`Blas::refit`] can move the vertices without rebuilding; as in
    /// [`Blas::from_mesh`], a primitive's `object` is its triangle's index.
    pub fn deformable(mesh: &Mesh) -> Self {
        let mut input = IndexedTriangles::with_vertices(mesh);
        input.triangles = mesh.indices.clone();
        input.objects = (0..mesh.indices.len() as u32).collect();
        Blas::build_with(input, false, None)
    }

    /// Moves the triangles of a [`Blas::deformable`] BLAS to `positions` (same triangles as at
    /// build time) and refits the node bounds bottom-up (obvhs `refit_all`); the tree topology
    /// stays that of the build, so the result depends only on the build mesh and `positions`.
    pub fn refit(&mut self, positions: &[Vec3], indices: &[[u32; 3]]) {
        let Some(mut bvh) = self.refit_tree.take() else { return };
        let triangle = |i: u32| Triangle { p: indices[i as usize].map(|v| Vec3A::from(positions[v as usize])) };
        for node in &mut bvh.nodes {
            if node.prim_count > 0 {
                let first = node.first_index as usize;
                let leaf = &bvh.primitive_indices[first..first + node.prim_count as usize];
                let aabb = leaf.iter().fold(Aabb::empty(), |acc, &i| {
                    let (min, max) = triangle(i).bounds();
                    acc.union(&Aabb::new(min, max))
                });
                node.set_aabb(aabb);
            }
        }
        bvh.refit_all();
        self.bounds = bvh.nodes.first().map(|n| *n.aabb());
        // The moved boxes may collapse into another wide tree, whose leaves take the slots in
        // another order: each slot's object (a deformable BLAS's: its triangle) follows.
        self.tree = Tree::from_bvh2(&bvh.nodes);
        self.objects = self.pack(&bvh.primitive_indices, triangle);
        self.refit_tree = Some(bvh);
        self.sah = OnceLock::new();
    }

    /// Bounds of everything in this BLAS.
    pub fn bounds(&self) -> Option<Aabb> {
        self.bounds
    }

    /// Number of nodes of the binary tree as built.
    pub fn node_count(&self) -> usize {
        self.binary_nodes
    }

    /// Number of nodes of the wide tree traversal uses ([`Blas::node_width`] children each).
    pub fn wide_node_count(&self) -> usize {
        self.tree.len()
    }

    /// Number of primitives in the leaves (a triangle that spatial splits put in several
    /// leaves once per leaf).
    pub fn slot_count(&self) -> usize {
        self.slots
    }

    /// The wide tree's [`SahCost`]: a triangle leaf tests its packets of four, any other leaf
    /// each of its primitives (`None` without primitives).
    pub fn sah_cost(&self) -> Option<SahCost> {
        *self.sah.get_or_init(|| self.tree.sah_cost(f64::from))
    }

    /// Each primitive slot and its primitive, in slot order.
    pub(super) fn slotted(&self) -> impl Iterator<Item = (u32, Prim)> + '_ {
        let packed = self.packets.iter().enumerate().flat_map(move |(p, packet)| {
            (0..4).filter(move |&l| packet.slot[l] != u32::MAX).map(move |l| {
                let slot = (4 * p + l) as u32;
                (slot, Prim { shape: Shape::Triangle(packet.triangle(l)), object: self.objects[slot as usize] })
            })
        });
        packed.chain(self.prims.iter().enumerate().map(|(k, p)| (k as u32, *p)))
    }

    /// The primitives, each once (a triangle that spatial splits put in several leaves is
    /// stored once per leaf; the same vertices with the same object and source triangle count
    /// once), in slot order.
    pub fn prims(&self) -> impl Iterator<Item = Prim> + '_ {
        let mut seen = std::collections::HashSet::new();
        self.slotted().filter_map(move |(slot, prim)| {
            let shape = match prim.shape {
                Shape::Triangle(t) => t.p.map(|v| v.to_array().map(f32::to_bits)),
                Shape::Sphere(_) => return Some(prim),
            };
            let source = self.source_triangles.as_ref().map(|t| t[slot as usize]);
            seen.insert((shape, prim.object, source)).then_some(prim)
        })
    }

    /// The `object` of the primitive in `slot` (see [`Prim::object`]).
    #[inline]
    pub(super) fn object(&self, slot: u32) -> u32 {
        if self.packets.is_empty() { self.prims[slot as usize].object } else { self.objects[slot as usize] }
    }

    /// Bytes held by the tree traversal reads, the primitives and the per-slot tables (and the
    /// binary tree a deformable BLAS keeps).
    pub fn memory_bytes(&self) -> usize {
        let binary = self
            .refit_tree
            .as_ref()
            .map_or(0, |b| b.nodes.len() * size_of::<Bvh2Node>() + b.primitive_indices.len() * size_of::<u32>());
        binary
            + self.tree.memory_bytes()
            + self.packets.len() * size_of::<Tri4>()
            + self.objects.len() * size_of::<u32>()
            + self.prims.len() * size_of::<Prim>()
            + self.source_triangles.as_ref().map_or(0, |t| t.len() * size_of::<u32>())
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

    /// The surface at a hit of primitive `slot` at barycentrics (b1, b2) (triangles) of `ray`,
    /// whose `tmax` is the hit's t. Inlined into its caller, which overwrites some of the
    /// result's fields: built in registers, the hit is not read back from memory field by field.
    #[inline(always)]
    pub(super) fn surface(&self, slot: u32, ray: &Ray, b1: f32, b2: f32, object: u32) -> SurfaceHit {
        if let Some(packet) = self.packets.get(slot as usize / 4) {
            return packet.triangle(slot as usize % 4).surface(ray, ray.tmax, b1, b2, object);
        }
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
            .field("nodes", &self.binary_nodes)
            .field("slots", &self.slots)
            .field("depth", &self.depth)
            .finish()
    }
}

/// Triangles as indices into shared vertices, each with its [`Prim::object`]: a large mesh's
/// input to a BLAS at 16 bytes a vertex and 16 a triangle, where a [`Prim`] takes 80.
/// The vertex indices must be in range (the meshes are validated first).
#[derive(Clone, Debug, Default)]
pub(crate) struct IndexedTriangles {
    /// Vertices.
    pub(crate) positions: Vec<Vec3A>,
    /// Each triangle's vertices, counter-clockwise seen from the front.
    pub(crate) triangles: Vec<[u32; 3]>,
    /// Each triangle's [`Prim::object`].
    pub(crate) objects: Vec<u32>,
}

impl IndexedTriangles {
    /// `mesh`'s vertices and no triangles yet.
    fn with_vertices(mesh: &Mesh) -> Self {
        IndexedTriangles { positions: mesh.positions.iter().map(|&p| p.into()).collect(), ..Default::default() }
    }
}

/// The primitives a BLAS is built from, by index.
trait BuildInput: Sync {
    /// Number of primitives.
    fn len(&self) -> usize;
    /// Number of them that are triangles.
    fn triangle_count(&self) -> usize;
    /// Primitive `i`.
    fn prim(&self, i: u32) -> Prim;
}

impl BuildInput for Vec<Prim> {
    fn len(&self) -> usize {
        self.as_slice().len()
    }

    fn triangle_count(&self) -> usize {
        self.iter().filter(|p| matches!(p.shape, Shape::Triangle(_))).count()
    }

    #[inline]
    fn prim(&self, i: u32) -> Prim {
        self[i as usize]
    }
}

impl BuildInput for IndexedTriangles {
    fn len(&self) -> usize {
        self.triangles.len()
    }

    fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    #[inline]
    fn prim(&self, i: u32) -> Prim {
        let p = self.triangles[i as usize].map(|v| self.positions[v as usize]);
        Prim { shape: Shape::Triangle(Triangle { p }), object: self.objects[i as usize] }
    }
}

/// The triangle of a primitive of an all-triangle set.
#[inline]
fn triangle_of(prim: &Prim) -> Triangle {
    match prim.shape {
        Shape::Triangle(t) => t,
        Shape::Sphere(_) => unreachable!("an all-triangle set"),
    }
}

/// `value(i)` for the input primitive `i` behind each slot (`u32::MAX` where there is none).
fn slot_values(inputs: &[u32], value: impl Fn(u32) -> u32 + Sync) -> Vec<u32> {
    inputs.par_iter().with_min_len(PAR_CHUNK).map(|&i| if i == u32::MAX { u32::MAX } else { value(i) }).collect()
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
