//! The user-facing scene model: every object, camera and light is an entity with these
//! components. Spawn them into the renderer's world; change detection does the rest.

use std::sync::Arc;

use bevy_ecs::prelude::Component;
use glam::{Affine3A, Quat, Vec3};

pub use crate::light::{
    ambient::AmbientOccluder, directional::DirectionalLight, disk::DiskLight, point::PointLight, spot::SpotLight,
};

/// Placement of an entity: scale, then rotation, then translation.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Transform {
    /// Position in world space.
    pub translation: Vec3,
    /// Orientation.
    pub rotation: Quat,
    /// Per-axis scale.
    pub scale: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Transform::IDENTITY
    }
}

impl Transform {
    /// No translation, rotation or scale.
    pub const IDENTITY: Transform = Transform { translation: Vec3::ZERO, rotation: Quat::IDENTITY, scale: Vec3::ONE };

    /// A pure translation.
    pub fn from_xyz(x: f32, y: f32, z: f32) -> Self {
        Transform { translation: Vec3::new(x, y, z), ..Transform::IDENTITY }
    }

    /// A pure translation.
    pub fn from_translation(translation: Vec3) -> Self {
        Transform { translation, ..Transform::IDENTITY }
    }

    /// This transform with its rotation replaced.
    pub fn with_rotation(self, rotation: Quat) -> Self {
        Transform { rotation, ..self }
    }

    /// This transform rotated so that its local −Z axis, where cameras look and lights shine,
    /// points along `dir` (a zero or non-finite `dir` gives a NaN rotation, refused by validation).
    pub fn facing(self, dir: Vec3) -> Self {
        Transform { rotation: Quat::from_rotation_arc(Vec3::NEG_Z, dir.normalize()), ..self }
    }

    /// The unit direction of the local −Z axis (glTF's light and camera direction), or zero
    /// when the rotation is degenerate or not finite.
    pub fn forward(&self) -> Vec3 {
        (self.rotation * Vec3::NEG_Z).normalize_or_zero()
    }

    /// This transform with a uniform scale.
    pub fn with_scale(self, scale: f32) -> Self {
        Transform { scale: Vec3::splat(scale), ..self }
    }

    /// The scale, rotation and translation of an affine matrix (a mirroring matrix gets a
    /// negative x scale; shear, which a `Transform` cannot hold, is dropped).
    pub fn from_affine(m: &Affine3A) -> Self {
        let (scale, rotation, translation) = m.to_scale_rotation_translation();
        Transform { translation, rotation, scale }
    }

    /// The affine matrix, or `None` if it holds NaN/Inf or is singular.
    pub fn to_affine(&self) -> Option<Affine3A> {
        let m = Affine3A::from_scale_rotation_translation(self.scale, self.rotation, self.translation);
        let det = m.matrix3.determinant();
        (m.is_finite() && det != 0.0 && det.is_finite()).then_some(m)
    }
}

/// A sphere of the given radius centred at the entity's translation (uniform scale only).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(Transform, Matte)]
pub struct Sphere {
    /// Radius before scaling.
    pub radius: f32,
}

/// An infinite plane through the entity's translation. Kept outside the BVH.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(Transform, Matte)]
pub struct Plane {
    /// Normal in the entity's local frame (rotated by its transform); +Y by default.
    pub normal: Vec3,
}

impl Default for Plane {
    fn default() -> Self {
        Plane { normal: Vec3::Y }
    }
}

/// An axis-aligned box in the entity's local frame, centred at its origin.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(Transform, Matte)]
pub struct Cuboid {
    /// Half the box's size along each local axis.
    pub half_extents: Vec3,
}

/// Triangle data shared by any number of [`TriangleMesh`] entities.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions in the mesh's local frame.
    pub positions: Vec<Vec3>,
    /// Vertex indices, three per triangle, counter-clockwise seen from outside.
    pub indices: Vec<[u32; 3]>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// First problem that makes this mesh unusable: a non-finite position or an index past
    /// the end of `positions`.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(i) = self.positions.iter().position(|p| !p.is_finite()) {
            return Err(format!("vertex {i} has a non-finite position {}", self.positions[i]));
        }
        let n = self.positions.len() as u32;
        if let Some(t) = self.indices.iter().position(|tri| tri.iter().any(|&i| i >= n)) {
            return Err(format!("triangle {t} indexes vertex {:?} but the mesh has {n} vertices", self.indices[t]));
        }
        Ok(())
    }
}

/// An instance of shared triangle data, placed by the entity's transform.
#[derive(Component, Clone, Debug)]
#[require(Transform, Matte)]
pub struct TriangleMesh(pub Arc<Mesh>);

/// Marks a [`TriangleMesh`] entity that moves often (animated nodes, objects a user drives by
/// hand): it stays an instance of its own, so moving it only rebuilds the top-level BVH.
/// Static meshes that no other entity shares are instead baked, in world space, into one BVH
/// with each other (one tree to traverse instead of one per mesh: 1.8× on Sponza's 37
/// pieces), which is rebuilt whenever one of them changes. glTF nodes that an animation drives
/// get this marker from the loader.
#[derive(Component, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dynamic;

/// Marks a [`TriangleMesh`] whose vertices move from frame to frame while its triangles stay
/// the same (skinning): its BVH keeps the tree built once from `rest` and is only refit to the
/// current vertices, so a deforming mesh costs a refit per frame, not a rebuild.
#[derive(Component, Clone, Debug)]
pub struct Deforming {
    /// The mesh in its rest pose, with the same triangles as the entity's `TriangleMesh`.
    pub rest: Arc<Mesh>,
}

/// RTGU's matte material: ambient reflectance `ka·cd`, Lambertian diffuse `kd·cd/π`.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Matte {
    /// Ambient coefficient.
    pub ka: f32,
    /// Diffuse coefficient.
    pub kd: f32,
    /// Diffuse colour (linear RGB).
    pub cd: Vec3,
}

impl Default for Matte {
    fn default() -> Self {
        Matte { ka: 1.0, kd: 1.0, cd: Vec3::splat(0.8) }
    }
}

impl Matte {
    /// A matte material of colour `cd` with ka = kd = 1.
    pub fn new(cd: Vec3) -> Self {
        Matte { ka: 1.0, kd: 1.0, cd }
    }
}

/// A pinhole camera looking from `eye` at `target`; image size comes from the render settings.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Centre of projection.
    pub eye: Vec3,
    /// Point the camera looks at.
    pub target: Vec3,
    /// Approximate up direction.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub vfov_degrees: f32,
}

impl Camera {
    /// A camera at `eye` looking at `target` with +Y up.
    pub fn look_at(eye: Vec3, target: Vec3, vfov_degrees: f32) -> Self {
        Camera { eye, target, up: Vec3::Y, vfov_degrees }
    }

    /// A camera placed by a transform: it looks down the transform's −Z with its +Y up.
    pub fn from_transform(t: &Transform, vfov_degrees: f32) -> Self {
        let forward = t.rotation * Vec3::NEG_Z;
        Camera { eye: t.translation, target: t.translation + forward, up: t.rotation * Vec3::Y, vfov_degrees }
    }
}

/// An orthographic camera looking from `eye` towards `target`: parallel rays along the view
/// direction through a film `2·half_height` tall (width from the image's aspect ratio).
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct OrthographicCamera {
    /// Centre of the film.
    pub eye: Vec3,
    /// A point the camera looks towards.
    pub target: Vec3,
    /// Approximate up direction.
    pub up: Vec3,
    /// Half the film height in world units (glTF's `ymag`).
    pub half_height: f32,
}

impl OrthographicCamera {
    /// A camera placed by a transform: it looks down the transform's −Z with its +Y up.
    pub fn from_transform(t: &Transform, half_height: f32) -> Self {
        let forward = t.rotation * Vec3::NEG_Z;
        OrthographicCamera {
            eye: t.translation,
            target: t.translation + forward,
            up: t.rotation * Vec3::Y,
            half_height,
        }
    }

    /// A one-line description of what makes this camera unusable, if anything.
    pub fn validate(&self) -> Result<(), String> {
        let as_pinhole = Camera { eye: self.eye, target: self.target, up: self.up, vfov_degrees: 90.0 };
        as_pinhole.validate().map_err(|e| format!("orthographic {e}"))?;
        if !(self.half_height.is_finite() && self.half_height > 0.0) {
            return Err(format!("orthographic camera half height {} must be positive and finite", self.half_height));
        }
        Ok(())
    }
}

/// A thin-lens camera (Suffern ch. 10, pbrt-v4 §5.2.3): a [`Camera`] whose rays start on a
/// lens disk of `lens_radius` (sampled with the concentric mapping) and pass through the
/// pinhole ray's point on the focal plane, `focal_distance` ahead and perpendicular to the
/// view direction. Points on that plane stay sharp. A point at depth d (distance along the
/// view direction) is seen by the film points x = p·f/d + l·(1 − f/d) for lens points l, a
/// disk on the focal plane of diameter `c = 2·lens_radius·|d − f|/d` — the circle of
/// confusion — that is `c·H / (2·f·tan(vfov/2))` pixels for an image `H` pixels high.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct ThinLensCamera {
    /// Centre of the lens.
    pub eye: Vec3,
    /// Point the camera looks at.
    pub target: Vec3,
    /// Approximate up direction.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub vfov_degrees: f32,
    /// Radius of the lens aperture (0: a pinhole).
    pub lens_radius: f32,
    /// Depth of the plane in focus, along the view direction.
    pub focal_distance: f32,
}

impl ThinLensCamera {
    /// A thin-lens camera at `eye` looking at, and focused on, `target`, with +Y up.
    pub fn look_at(eye: Vec3, target: Vec3, vfov_degrees: f32, lens_radius: f32) -> Self {
        let focal_distance = (target - eye).length();
        ThinLensCamera { eye, target, up: Vec3::Y, vfov_degrees, lens_radius, focal_distance }
    }

    /// The pinhole camera with the same view.
    pub fn pinhole(&self) -> Camera {
        Camera { eye: self.eye, target: self.target, up: self.up, vfov_degrees: self.vfov_degrees }
    }
}
