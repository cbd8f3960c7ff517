//! Turns shape components into world-space primitives, rejecting unusable input with a
//! one-line reason.

use glam::{Affine3A, Vec3, Vec3A};

use super::{
    accel::{Prim, Shape},
    shapes::{PlanePrim, SpherePrim, Triangle},
};
use crate::components::{Cuboid, Matte, Mesh, Plane, Sphere, Transform};

/// Primitives made from one entity, and how many degenerate triangles were dropped.
#[derive(Default)]
pub struct Converted {
    /// Bounded primitives.
    pub prims: Vec<Prim>,
    /// Zero-area triangles skipped (they can never be hit).
    pub degenerate: usize,
    /// When kept (`Some`), each mesh triangle primitive's index in its mesh, in `prims` order:
    /// what a bake of textured meshes needs to find the texture coordinates of a hit.
    pub triangles: Option<Vec<u32>>,
}

/// The entity's affine transform, or why it is unusable.
pub fn affine(t: &Transform) -> Result<Affine3A, String> {
    t.to_affine().ok_or_else(|| {
        format!(
            "transform is not usable (translation {}, rotation {}, scale {}): non-finite or singular",
            t.translation, t.rotation, t.scale
        )
    })
}

/// Checks a material's coefficients.
pub fn validate_material(m: &Matte) -> Result<(), String> {
    let ok = m.ka.is_finite() && m.kd.is_finite() && m.cd.is_finite();
    if !ok || m.ka < 0.0 || m.kd < 0.0 || m.cd.min_element() < 0.0 {
        return Err(format!("material ka {} kd {} cd {} must be finite and non-negative", m.ka, m.kd, m.cd));
    }
    Ok(())
}

/// A sphere in world space; non-uniform scale is refused (use a mesh for ellipsoids).
pub fn sphere(s: &Sphere, t: &Transform, object: u32) -> Result<Prim, String> {
    affine(t)?;
    let scale = t.scale.abs();
    if (scale.max_element() - scale.min_element()) > 1e-6 * scale.max_element() {
        return Err(format!("sphere has non-uniform scale {}; use a TriangleMesh for ellipsoids", t.scale));
    }
    let radius = s.radius * scale.x;
    if !(radius.is_finite() && radius > 0.0) {
        return Err(format!("sphere radius {} (scaled: {radius}) must be positive and finite", s.radius));
    }
    Ok(Prim { shape: Shape::Sphere(SpherePrim { center: t.translation.into(), radius }), object })
}

/// An infinite plane in world space.
pub fn plane(p: &Plane, t: &Transform, object: u32) -> Result<PlanePrim, String> {
    let m = affine(t)?;
    // Normals transform by the inverse transpose.
    let n = m.matrix3.inverse().transpose() * Vec3A::from(p.normal);
    if !(n.is_finite() && n.length_squared() > 0.0) {
        return Err(format!("plane normal {} has zero length or is not finite", p.normal));
    }
    Ok(PlanePrim { point: t.translation.into(), normal: n.normalize(), object })
}

/// Twelve world-space triangles of a box.
pub fn cuboid(c: &Cuboid, t: &Transform, object: u32) -> Result<Converted, String> {
    let h = c.half_extents;
    if !(h.is_finite() && h.min_element() > 0.0) {
        return Err(format!("cuboid half extents {h} must be positive and finite"));
    }
    let corners: Vec<Vec3> =
        (0..8).map(|i| Vec3::new(sign(i & 1) * h.x, sign(i & 2) * h.y, sign(i & 4) * h.z)).collect();
    // Faces as corner quads, counter-clockwise from outside.
    const QUADS: [[u32; 4]; 6] = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
    let indices: Vec<[u32; 3]> = QUADS.iter().flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]]).collect();
    mesh(&Mesh { positions: corners, indices }, t, object)
}

fn sign(bit: i32) -> f32 {
    if bit != 0 { 1.0 } else { -1.0 }
}

/// A mesh's triangles in world space; zero-area triangles are counted and skipped.
pub fn mesh(mesh: &Mesh, t: &Transform, object: u32) -> Result<Converted, String> {
    let mut out = Converted::default();
    append_mesh(mesh, t, object, &mut out)?;
    Ok(out)
}

/// [`mesh`], appended to `out` (nothing is appended on an error): a bake gathers every mesh
/// in one allocation this way (the dragon's 871k triangles, 70 MB, were copied once more and
/// their pages touched twice when each mesh had a vector of its own).
pub fn append_mesh(mesh: &Mesh, t: &Transform, object: u32, out: &mut Converted) -> Result<(), String> {
    let m = affine(t)?;
    mesh.validate()?;
    let world: Vec<Vec3A> = mesh.positions.iter().map(|&p| m.transform_point3a(p.into())).collect();
    if let Some(i) = world.iter().position(|p| !p.is_finite()) {
        return Err(format!("vertex {i} overflows to {} after the transform", world[i]));
    }
    out.prims.reserve(mesh.indices.len());
    for (k, tri) in mesh.indices.iter().enumerate() {
        let [a, b, c] = tri.map(|i| world[i as usize]);
        match Triangle::new(a, b, c) {
            Some(tri) => {
                out.prims.push(Prim { shape: Shape::Triangle(tri), object });
                if let Some(triangles) = &mut out.triangles {
                    triangles.push(k as u32);
                }
            }
            None => out.degenerate += 1,
        }
    }
    Ok(())
}
