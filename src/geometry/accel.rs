//! The scene's acceleration structure: an obvhs PLOC-built BVH2 over triangles and sphere
//! bounds, with primitives stored in BVH leaf order, plus the infinite planes kept outside it.
//! Traversal is hemi's own, so that it honours the ray's full (0, tmax) range at every scale.

use std::time::{Duration, Instant};

use bevy_ecs::prelude::{Entity, Resource};
use glam::Vec3A;
use obvhs::{BvhBuildParams, aabb::Aabb, bvh2::builder::build_bvh2, bvh2::node::Bvh2Node};

use super::{
    hit::SurfaceHit,
    ray::Ray,
    shapes::{PlanePrim, SpherePrim, Triangle},
};
use crate::{components::Matte, math::gamma};

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
    /// Index into [`SceneGeometry::objects`].
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

/// Everything rays can hit.
#[derive(Resource, Clone, Debug, Default)]
pub struct SceneGeometry {
    nodes: Vec<Bvh2Node>,
    prims: Vec<Prim>,
    planes: Vec<PlanePrim>,
    /// Objects, indexed by `SurfaceHit::object`.
    pub objects: Vec<Object>,
    /// Number of triangles in the BVH.
    pub triangle_count: usize,
    /// Zero-area triangles dropped from the input (they can never be hit).
    pub degenerate_triangles: usize,
    /// Bounds of the bounded primitives (empty when there are none).
    pub bounds: Option<(Vec3A, Vec3A)>,
    /// Depth of the BVH.
    pub depth: usize,
    /// Time the last BVH build took.
    pub build_time: Duration,
}

impl SceneGeometry {
    /// Builds the BVH over `prims` (in any order) and keeps `planes` beside it.
    pub fn build(prims: Vec<Prim>, planes: Vec<PlanePrim>, objects: Vec<Object>) -> Self {
        let start = Instant::now();
        let triangle_count = prims.iter().filter(|p| matches!(p.shape, Shape::Triangle(_))).count();
        let (nodes, prims) = if prims.is_empty() {
            (Vec::new(), prims)
        } else {
            let aabbs: Vec<Aabb> = prims.iter().map(Prim::bounds).collect();
            let bvh = build_bvh2(&aabbs, BvhBuildParams::medium_build(), &mut Duration::default());
            let ordered = bvh.primitive_indices.iter().map(|&i| prims[i as usize]).collect();
            (bvh.nodes, ordered)
        };
        let bounds = nodes.first().map(|n| (n.aabb.min, n.aabb.max));
        let mut geometry = SceneGeometry {
            nodes,
            prims,
            planes,
            objects,
            triangle_count,
            degenerate_triangles: 0,
            bounds,
            depth: 0,
            build_time: Duration::ZERO,
        };
        geometry.depth = geometry.subtree_depth(0);
        geometry.build_time = start.elapsed();
        geometry
    }

    fn subtree_depth(&self, root: usize) -> usize {
        let mut max = 0;
        let mut stack = vec![(root, 1usize)];
        while let Some((i, d)) = stack.pop() {
            let Some(n) = self.nodes.get(i) else { continue };
            max = max.max(d);
            if n.prim_count == 0 {
                stack.push((n.first_index as usize, d + 1));
                stack.push((n.first_index as usize + 1, d + 1));
            }
        }
        max
    }

    /// Number of BVH nodes.
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// Number of bounded primitives (triangles and spheres).
    pub fn prim_count(&self) -> usize {
        self.prims.len()
    }

    /// The bounded primitives, in BVH leaf order.
    pub fn prims(&self) -> &[Prim] {
        &self.prims
    }

    /// Number of infinite planes.
    pub fn plane_count(&self) -> usize {
        self.planes.len()
    }

    /// Bytes held by nodes and primitives.
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * size_of::<Bvh2Node>()
            + self.prims.len() * size_of::<Prim>()
            + self.planes.len() * size_of::<PlanePrim>()
    }

    /// Diagonal length of the bounded geometry's box (0 when there is none).
    pub fn extent(&self) -> f32 {
        self.bounds.map_or(0.0, |(min, max)| (max - min).length())
    }

    /// Entry distance of the ray into `node`'s box, if it enters before `tmax`.
    /// A zero direction component gives 0·∞ = NaN exactly when the origin lies on that slab's
    /// plane; such a bound is replaced by the infinity that leaves the slab unbounded, so rays
    /// running inside a box face are not culled. The far distance is widened by 2γ(3)
    /// (Ize 2013) so rounding never culls a true hit.
    #[inline(always)]
    fn enter(node: &Bvh2Node, ray: &Ray, tmax: f32) -> Option<f32> {
        let t1 = (node.aabb.min - ray.origin) * ray.inv_dir;
        let t2 = (node.aabb.max - ray.origin) * ray.inv_dir;
        let t1 = Vec3A::select(t1.is_nan_mask(), -ray.inv_dir, t1);
        let t2 = Vec3A::select(t2.is_nan_mask(), ray.inv_dir, t2);
        let near = t1.min(t2).max_element().max(0.0);
        let far = t1.max(t2).min_element() * (1.0 + 2.0 * gamma(3));
        (near <= far.min(tmax)).then_some(near)
    }

    /// Closest hit along `ray`, if any. `stack` is reusable scratch space.
    #[inline]
    pub fn intersect(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> Option<SurfaceHit> {
        let mut ray = *ray;
        let best = self.closest_prim(&mut ray, stack);
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
        best.map(|(i, b1, b2)| self.surface(i, &ray, b1, b2))
    }

    fn surface(&self, index: u32, ray: &Ray, b1: f32, b2: f32) -> SurfaceHit {
        let prim = &self.prims[index as usize];
        match prim.shape {
            Shape::Triangle(tri) => tri.surface(ray, ray.tmax, b1, b2, prim.object),
            Shape::Sphere(s) => s.surface(ray, ray.tmax, prim.object),
        }
    }

    /// Intersects one primitive: (t, b1, b2).
    #[inline(always)]
    pub fn hit_prim(prim: &Prim, ray: &Ray) -> Option<(f32, f32, f32)> {
        match prim.shape {
            Shape::Triangle(t) => t.intersect(ray),
            Shape::Sphere(s) => s.intersect(ray).map(|t| (t, 0.0, 0.0)),
        }
    }

    /// Front-to-back BVH traversal; shrinks `ray.tmax` to the closest hit and returns the
    /// primitive index and barycentrics.
    #[inline]
    fn closest_prim(&self, ray: &mut Ray, stack: &mut Vec<(u32, f32)>) -> Option<(u32, f32, f32)> {
        let root = self.nodes.first()?;
        Self::enter(root, ray, ray.tmax)?;
        let mut best = None;
        stack.clear();
        let mut node = root;
        loop {
            if node.prim_count > 0 {
                let first = node.first_index as usize;
                let leaf = &self.prims[first..first + node.prim_count as usize];
                for (k, prim) in leaf.iter().enumerate() {
                    if let Some((t, b1, b2)) = Self::hit_prim(prim, ray) {
                        ray.tmax = t;
                        best = Some(((first + k) as u32, b1, b2));
                    }
                }
            } else {
                let (li, ri) = (node.first_index, node.first_index + 1);
                let left = &self.nodes[li as usize];
                let right = &self.nodes[ri as usize];
                match (Self::enter(left, ray, ray.tmax), Self::enter(right, ray, ray.tmax)) {
                    (Some(dl), Some(dr)) => {
                        let (near, far, dfar) = if dl <= dr { (left, ri, dr) } else { (right, li, dl) };
                        stack.push((far, dfar));
                        node = near;
                        continue;
                    }
                    (Some(_), None) => {
                        node = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = right;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            loop {
                match stack.pop() {
                    Some((i, d)) if d <= ray.tmax => {
                        node = &self.nodes[i as usize];
                        break;
                    }
                    Some(_) => continue,
                    None => return best,
                }
            }
        }
    }

    /// Whether anything blocks `ray` in (0, tmax); stops at the first blocker found.
    #[inline]
    pub fn occluded(&self, ray: &Ray, stack: &mut Vec<(u32, f32)>) -> bool {
        if self.planes.iter().any(|p| p.intersect(ray).is_some()) {
            return true;
        }
        let Some(root) = self.nodes.first() else { return false };
        if Self::enter(root, ray, ray.tmax).is_none() {
            return false;
        }
        stack.clear();
        let mut node = root;
        loop {
            if node.prim_count > 0 {
                let first = node.first_index as usize;
                for prim in &self.prims[first..first + node.prim_count as usize] {
                    if Self::hit_prim(prim, ray).is_some() {
                        return true;
                    }
                }
            } else {
                let left = &self.nodes[node.first_index as usize];
                let right = &self.nodes[node.first_index as usize + 1];
                match (Self::enter(left, ray, ray.tmax), Self::enter(right, ray, ray.tmax)) {
                    (Some(_), Some(_)) => {
                        stack.push((node.first_index + 1, 0.0));
                        node = left;
                        continue;
                    }
                    (Some(_), None) => {
                        node = left;
                        continue;
                    }
                    (None, Some(_)) => {
                        node = right;
                        continue;
                    }
                    (None, None) => {}
                }
            }
            match stack.pop() {
                Some((i, _)) => node = &self.nodes[i as usize],
                None => return false,
            }
        }
    }

    /// Closest hit by testing every primitive (for tests and validation).
    pub fn intersect_brute_force(&self, ray: &Ray) -> Option<SurfaceHit> {
        let mut ray = *ray;
        let mut best = None;
        for (i, prim) in self.prims.iter().enumerate() {
            if let Some((t, b1, b2)) = Self::hit_prim(prim, &ray) {
                ray.tmax = t;
                best = Some((i as u32, b1, b2));
            }
        }
        let mut plane_hit = None;
        for plane in &self.planes {
            if let Some(t) = plane.intersect(&ray) {
                ray.tmax = t;
                plane_hit = Some(plane.surface(&ray, t));
            }
        }
        plane_hit.or_else(|| best.map(|(i, b1, b2)| self.surface(i, &ray, b1, b2)))
    }
}
