//! Alpha-tested meshes (glTF `MASK` and `BLEND`): kept out of the scene's other trees and
//! traversed apart, with a test at every candidate hit. Closest-hit queries go on past a
//! cut-out hit; occlusion queries ignore it. A scene without such meshes has no layer, so its
//! queries run exactly the code they run without this module.
//!
//! The layer is a small two-level structure of its own: each mesh's BLAS (shared with the
//! opaque instances of the same mesh) under a top-level tree of the layer's instances.
//! Traversal is the single-ray path, with the triangle packets' hits filtered one by one.

use std::{cell::Cell, sync::Arc, time::Duration};

use glam::Affine3A;
use obvhs::{BvhBuildParams, aabb::Aabb, bvh2::builder::build_bvh2};
use serde::Serialize;

use super::{
    blas::Blas,
    tlas::Instance,
    tree::{Tree, TreeQuery},
};
use crate::{
    geometry::{
        hit::SurfaceHit,
        ray::Ray,
        tri4::RayTri4,
        wide_bvh::{NodeTest, WideBvh},
    },
    material::PlacedSurface,
    random::mix64,
};

/// One alpha-tested mesh placed in the world.
#[derive(Clone, Debug)]
pub struct AlphaMesh {
    /// The mesh's BLAS (each primitive's `object` is its triangle's index).
    pub blas: Arc<Blas>,
    /// The mesh's surface, whose alpha decides which hits count.
    pub surface: Arc<PlacedSurface>,
    /// Placement in the world.
    pub to_world: Affine3A,
    /// Index into the scene's objects.
    pub object: u32,
}

/// The alpha-tested meshes of a scene and their top-level tree.
#[derive(Clone, Debug)]
pub struct AlphaLayer {
    meshes: Vec<(Instance, Arc<Blas>, Arc<PlacedSurface>)>,
    top: Tree,
}

/// A closest alpha-tested hit: (index in the layer, primitive slot, b1, b2).
type AlphaHit = (u32, u32, f32, f32);

impl AlphaLayer {
    /// The placed alpha-tested meshes, each as an instance of its own tree.
    pub fn instances(&self) -> impl Iterator<Item = &Instance> {
        self.meshes.iter().map(|(instance, ..)| instance)
    }

    /// The layer over `meshes` (those with no bounds or an unusable placement are left out,
    /// as their opaque twins are), or `None` when none is left.
    pub fn new(meshes: Vec<AlphaMesh>) -> Option<Self> {
        let placed: Vec<_> = meshes
            .into_iter()
            .filter_map(|m| {
                let instance = Instance::new(0, m.blas.bounds()?, m.to_world, Some(m.object))?;
                Some((instance, m.blas, m.surface))
            })
            .collect();
        if placed.is_empty() {
            return None;
        }
        let aabbs: Vec<Aabb> = placed.iter().map(|(i, ..)| i.bounds).collect();
        let params = BvhBuildParams { max_prims_per_leaf: 1, ..BvhBuildParams::fast_build() };
        let bvh = build_bvh2(&aabbs, params, &mut Duration::default());
        let meshes = bvh.primitive_indices.iter().map(|&i| placed[i as usize].clone()).collect();
        Some(AlphaLayer { meshes, top: Tree::from_bvh2(&bvh.nodes) })
    }

    /// Number of alpha-tested meshes.
    pub fn len(&self) -> usize {
        self.meshes.len()
    }

    /// Whether the layer is empty (it never is once built).
    pub fn is_empty(&self) -> bool {
        self.meshes.is_empty()
    }

    /// Triangles stored in the layer's BLASes (a BLAS shared with opaque instances counted again).
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|(_, b, _)| b.triangle_count).sum()
    }

    /// Bytes of the layer's own tree and instances (its BLASes are counted with the scene's).
    pub fn memory_bytes(&self) -> usize {
        self.top.memory_bytes() + self.meshes.len() * size_of::<(Instance, usize, usize)>()
    }

    /// Closest hit along `ray` in (0, ray.tmax) that is not cut out; shrinks `ray.tmax` to it.
    /// Uses `stack` above its current length.
    pub(super) fn closest(&self, ray: &mut Ray, stack: &mut Vec<(u32, f32)>) -> Option<AlphaHit> {
        let key = ray_key(ray);
        let mut counts = AlphaCounts::default();
        let best = self.top.query(LayerClosest { layer: self, ray, stack, key, counts: &mut counts });
        counts.flush();
        best
    }

    /// Whether a hit that is not cut out blocks `ray` in (0, tmax). Uses `stack` above its length.
    pub(super) fn occluded(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        let key = ray_key(ray);
        let mut counts = AlphaCounts::default();
        let blocked = self.top.query(LayerOccluded { layer: self, ray, stack, key, counts: &mut counts });
        counts.flush();
        blocked
    }

    /// The surface at hit `hit` of [`AlphaLayer::closest`]; `ray.tmax` is the world t.
    pub(super) fn surface(&self, (k, slot, b1, b2): AlphaHit, ray: &Ray) -> SurfaceHit {
        let (inst, blas, _) = &self.meshes[k as usize];
        let object = inst.object.unwrap_or(0);
        let tri = blas.object(slot);
        let hit = match inst.local_ray(&ray.with_tmax(f32::INFINITY)) {
            Some((local, dt)) if !inst.identity => {
                inst.to_world_hit(blas.surface(slot, &local.with_tmax(ray.tmax - dt), b1, b2, object), dt)
            }
            _ => blas.surface(slot, ray, b1, b2, object),
        };
        SurfaceHit { prim: tri, ..hit }
    }
}

/// A stateless identity of a ray (its origin and direction bits), which with the triangle
/// decides a blended surface's pass or block: the same ray always gets the same answer.
fn ray_key(ray: &Ray) -> u64 {
    let bits = |v: glam::Vec3A| {
        let [x, y, z] = v.to_array().map(f32::to_bits);
        mix64(u64::from(x) | u64::from(y) << 32) ^ u64::from(z)
    };
    mix64(bits(ray.origin)) ^ bits(ray.dir)
}

/// Whether the hit of `ray` at triangle slot `slot` (b1, b2) of layer mesh `k` is cut out.
#[inline]
fn cut_out(layer: &AlphaLayer, k: u32, slot: u32, (b1, b2): (f32, f32), key: u64, counts: &mut AlphaCounts) -> bool {
    let (_, blas, surface) = &layer.meshes[k as usize];
    let tri = blas.object(slot);
    let passes = surface.passes(tri, b1, b2, key ^ u64::from(k).wrapping_mul(0xd6e8_feb8_6659_fd93));
    counts.candidates += 1;
    counts.cut += u64::from(passes);
    passes
}

/// Closest non-cut-out hit through the layer's top level.
struct LayerClosest<'a> {
    layer: &'a AlphaLayer,
    ray: &'a mut Ray,
    stack: &'a mut Vec<(u32, f32)>,
    key: u64,
    counts: &'a mut AlphaCounts,
}

impl TreeQuery for LayerClosest<'_> {
    type Output = Option<AlphaHit>;
    #[inline(always)]
    fn run<const W: usize>(self, top: &WideBvh<W>, node_test: impl NodeTest<W>) -> Self::Output {
        let LayerClosest { layer, ray, stack, key, counts } = self;
        let mut best = None;
        top.closest(node_test, ray, stack, |first, n, ray, stack| {
            for k in first..first + n {
                let (inst, blas, _) = &layer.meshes[k as usize];
                counts.reached = true;
                let mut test = |slot, b: (f32, f32)| !cut_out(layer, k, slot, b, key, counts);
                if inst.identity {
                    if let Some((slot, b1, b2)) = blas.tree.query(MeshClosest { blas, ray, stack, keep: &mut test }) {
                        best = Some((k, slot, b1, b2));
                    }
                } else if let Some((mut local, dt)) = inst.local_ray(ray)
                    && let Some((slot, b1, b2)) =
                        blas.tree.query(MeshClosest { blas, ray: &mut local, stack, keep: &mut test })
                {
                    ray.tmax = ray.tmax.min(local.tmax + dt);
                    best = Some((k, slot, b1, b2));
                }
            }
        });
        best
    }
}

/// Any non-cut-out hit through the layer's top level.
struct LayerOccluded<'a> {
    layer: &'a AlphaLayer,
    ray: &'a Ray,
    stack: &'a mut Vec<(u32, f32)>,
    key: u64,
    counts: &'a mut AlphaCounts,
}

impl TreeQuery for LayerOccluded<'_> {
    type Output = bool;
    #[inline(always)]
    fn run<const W: usize>(self, top: &WideBvh<W>, node_test: impl NodeTest<W>) -> bool {
        let LayerOccluded { layer, ray, stack, key, counts } = self;
        top.occluded(node_test, ray, stack, |first, n, stack| {
            (first..first + n).any(|k| {
                let (inst, blas, _) = &layer.meshes[k as usize];
                counts.reached = true;
                let mut test = |slot, b: (f32, f32)| !cut_out(layer, k, slot, b, key, counts);
                let local = if inst.identity { Some(*ray) } else { inst.local_ray(ray).map(|(l, _)| l) };
                local.is_some_and(|local| blas.tree.query(MeshOccluded { blas, ray: &local, stack, keep: &mut test }))
            })
        })
    }
}

/// Closest hit in one mesh's BLAS among the candidate hits `keep` accepts.
struct MeshClosest<'a, F> {
    blas: &'a Blas,
    ray: &'a mut Ray,
    stack: &'a mut Vec<(u32, f32)>,
    keep: &'a mut F,
}

impl<F: FnMut(u32, (f32, f32)) -> bool> TreeQuery for MeshClosest<'_, F> {
    type Output = Option<(u32, f32, f32)>;
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>, node_test: impl NodeTest<W>) -> Self::Output {
        let MeshClosest { blas, ray, stack, keep } = self;
        let r = RayTri4::new(ray);
        let mut best = None;
        tree.closest(node_test, ray, stack, |first, count, ray, _| {
            for packet in &blas.packets[first as usize..(first + count) as usize] {
                blas.packet_hits(packet, &r, ray, |slot, (t, b1, b2), ray| {
                    if keep(slot, (b1, b2)) {
                        ray.tmax = t;
                        best = Some((slot, b1, b2));
                    }
                    false
                });
            }
        });
        best
    }
}

/// Whether a candidate hit that `keep` accepts lies in one mesh's BLAS.
struct MeshOccluded<'a, F> {
    blas: &'a Blas,
    ray: &'a Ray,
    stack: &'a mut Vec<(u32, f32)>,
    keep: &'a mut F,
}

impl<F: FnMut(u32, (f32, f32)) -> bool> TreeQuery for MeshOccluded<'_, F> {
    type Output = bool;
    #[inline(always)]
    fn run<const W: usize>(self, tree: &WideBvh<W>, node_test: impl NodeTest<W>) -> bool {
        let MeshOccluded { blas, ray, stack, keep } = self;
        let r = RayTri4::new(ray);
        tree.occluded(node_test, ray, stack, |first, count, _| {
            let mut local = *ray;
            blas.packets[first as usize..(first + count) as usize]
                .iter()
                .any(|packet| blas.packet_hits(packet, &r, &mut local, |slot, (_, b1, b2), _| keep(slot, (b1, b2))))
        })
    }
}

/// What the alpha path did, summed over some rays (`--stats`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct AlphaCounts {
    /// Queries that reached an alpha-tested mesh.
    pub rays: u64,
    /// Candidate hits on alpha-tested triangles, each tested against the surface's alpha.
    pub candidates: u64,
    /// Those of them that were cut out (the ray went on through).
    pub cut: u64,
    #[serde(skip)]
    reached: bool,
}

thread_local! {
    static COUNTS: Cell<[u64; 3]> = const { Cell::new([0; 3]) };
}

impl AlphaCounts {
    /// Adds another set of counts to this one.
    pub fn add(&mut self, other: &AlphaCounts) {
        self.rays += other.rays;
        self.candidates += other.candidates;
        self.cut += other.cut;
    }

    /// Adds one query's counts to this thread's.
    fn flush(self) {
        if self.reached {
            COUNTS.with(|c| {
                let [r, n, k] = c.get();
                c.set([r + 1, n + self.candidates, k + self.cut]);
            });
        }
    }

    /// This thread's counts since the last call, which starts them again from 0.
    pub fn take() -> AlphaCounts {
        let [rays, candidates, cut] = COUNTS.with(|c| c.replace([0; 3]));
        AlphaCounts { rays, candidates, cut, reached: false }
    }
}
