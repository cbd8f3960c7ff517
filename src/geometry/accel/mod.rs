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

mod alpha;
mod blas;
mod blas_packets;
mod ray_order;
mod reference;
mod scene;
mod scene_packets;
mod tlas;
mod tree;

pub use alpha::{AlphaCounts, AlphaLayer, AlphaMesh};
pub use blas::Blas;
pub(crate) use blas::IndexedTriangles;
#[cfg(test)]
pub(crate) use blas::subtree_depth;
#[cfg(target_arch = "x86_64")]
pub(crate) use blas_packets::KernelLanes;
pub use ray_order::RayOrder;
pub use scene::{BvhWork, RayEnd, SceneGeometry};
#[cfg(target_arch = "x86_64")]
pub(crate) use scene_packets::SceneLanes;
pub use tlas::Instance;

use bevy_ecs::prelude::Entity;
use glam::{Affine3A, Vec3, Vec3A};
use obvhs::aabb::Aabb;

use super::{
    ray::{Ray, Shear},
    shapes::{SpherePrim, Triangle},
};
use crate::components::{Matte, Mesh};

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

/// The world-space geometric normal of a mesh triangle placed by `to_world`, oriented by the
/// mesh's winding (counter-clockwise = front) whatever the sign of the transform's determinant:
/// normals transform by the inverse transpose, so a mirroring transform keeps them outward.
pub fn outward_normal(mesh: &Mesh, triangle: usize, to_world: &Affine3A) -> Vec3 {
    let [a, b, c] = mesh.indices[triangle].map(|i| mesh.positions[i as usize]);
    let n = (b - a).cross(c - a);
    (to_world.matrix3.inverse().transpose() * Vec3A::from(n)).normalize().into()
}
