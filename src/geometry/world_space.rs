//! Turns shape components into world-space primitives, rejecting unusable input with a
//! one-line reason.

use glam::{Affine3A, Vec3, Vec3A};

use super::{
    accel::{IndexedTriangles, Prim, Shape},
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
}

/// Meshes' triangles in world space, gathered for one BLAS by [`append_mesh`].
#[derive(Default)]
pub(crate) struct Bake {
    /// The triangles, each with its object's index.
    pub(crate) triangles: IndexedTriangles,
    /// Zero-area triangles skipped (they can never be hit).
    pub(crate) degenerate: usize,
    /// When kept (`Some`), each triangle's index in its mesh, in `triangles` order: what a
    /// bake of textured meshes needs to find the texture coordinates of a hit.
    pub(crate) sources: Option<Vec<u32>>,
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
    let mut world = Vec::new();
    append_vertices(mesh, t, &mut world)?;
    let mut out = Converted { prims: Vec::with_capacity(mesh.indices.len()), degenerate: 0 };
    for tri in &mesh.indices {
        match Triangle::new(world[tri[0] as usize], world[tri[1] as usize], world[tri[2] as usize]) {
            Some(tri) => out.prims.push(Prim { shape: Shape::Triangle(tri), object }),
            None => out.degenerate += 1,
        }
    }
    Ok(out)
}

/// [`mesh`], appended to `out` as indexed triangles (nothing is appended on an error): a bake
/// gathers every mesh in one set of vectors this way, 16 bytes a vertex and 16 a triangle
/// (the dragon's 871k triangles took 70 MB as primitives of their own).
pub(crate) fn append_mesh(mesh: &Mesh, t: &Transform, object: u32, out: &mut Bake) -> Result<(), String> {
    let base = out.triangles.positions.len();
    let first = u32::try_from(base + mesh.positions.len())
        .map(|_| base as u32)
        .map_err(|_| format!("the baked meshes hold more than {} vertices", u32::MAX))?;
    append_vertices(mesh, t, &mut out.triangles.positions)?;
    let IndexedTriangles { positions, triangles, objects } = &mut out.triangles;
    triangles.reserve(mesh.indices.len());
    objects.reserve(mesh.indices.len());
    for (k, tri) in mesh.indices.iter().enumerate() {
        let tri = tri.map(|i| first + i);
        let [a, b, c] = tri.map(|i| positions[i as usize]);
        if Triangle::new(a, b, c).is_some() {
            triangles.push(tri);
            objects.push(object);
            if let Some(sources) = &mut out.sources {
                sources.push(k as u32);
            }
        } else {
            out.degenerate += 1;
        }
    }
    Ok(())
}

/// Appends `mesh`'s vertices placed by `t` to `out` (nothing on an error).
fn append_vertices(mesh: &Mesh, t: &Transform, out: &mut Vec<Vec3A>) -> Result<(), String> {
    let m = affine(t)?;
    mesh.validate()?;
    let base = out.len();
    out.extend(mesh.positions.iter().map(|&p| m.transform_point3a(p.into())));
    if let Some(i) = out[base..].iter().position(|p| !p.is_finite()) {
        let e = format!("vertex {i} overflows to {} after the transform", out[base + i]);
        out.truncate(base);
        return Err(e);
    }
    Ok(())
}
