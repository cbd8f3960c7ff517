//! Procedural meshes: tessellated spheres and torus knots for scenes, tests and benchmarks.

use std::f32::consts::TAU;

use glam::Vec3;

use crate::components::Mesh;

/// A closed UV sphere of radius `radius` with `rings × segments` quads (as triangles).
pub fn uv_sphere(radius: f32, rings: u32, segments: u32) -> Mesh {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let mut positions = vec![Vec3::Y * radius];
    for r in 1..rings {
        let theta = std::f32::consts::PI * r as f32 / rings as f32;
        for s in 0..segments {
            let phi = TAU * s as f32 / segments as f32;
            positions.push(Vec3::new(theta.sin() * phi.cos(), theta.cos(), -theta.sin() * phi.sin()) * radius);
        }
    }
    positions.push(-Vec3::Y * radius);
    let bottom = positions.len() as u32 - 1;
    let ring = |r: u32, s: u32| 1 + (r - 1) * segments + s % segments;
    let mut indices = Vec::new();
    for s in 0..segments {
        indices.push([0, ring(1, s), ring(1, s + 1)]);
        indices.push([bottom, ring(rings - 1, s + 1), ring(rings - 1, s)]);
    }
    for r in 1..rings - 1 {
        for s in 0..segments {
            let (a, b, c, d) = (ring(r, s), ring(r + 1, s), ring(r + 1, s + 1), ring(r, s + 1));
            indices.push([a, b, c]);
            indices.push([a, c, d]);
        }
    }
    Mesh { positions, indices }
}

/// A (p, q) torus knot: a tube of radius `tube` around the knot curve on a torus of radius
/// `radius`, with `steps` segments along the curve and `sides` around the tube.
pub fn torus_knot(p: u32, q: u32, radius: f32, tube: f32, steps: u32, sides: u32) -> Mesh {
    let curve = |t: f32| {
        let (pt, qt) = (p as f32 * t, q as f32 * t);
        let r = radius * (0.5 * (2.0 + qt.cos()));
        Vec3::new(r * pt.cos(), radius * 0.5 * qt.sin(), r * pt.sin())
    };
    let mut positions = Vec::with_capacity((steps * sides) as usize);
    for i in 0..steps {
        let t = TAU * i as f32 / steps as f32;
        let c = curve(t);
        let tangent = (curve(t + 1e-3) - curve(t - 1e-3)).normalize();
        let normal = (curve(t + 1e-3) + curve(t - 1e-3) - 2.0 * c).normalize();
        let binormal = tangent.cross(normal).normalize();
        let normal = binormal.cross(tangent);
        for j in 0..sides {
            let a = TAU * j as f32 / sides as f32;
            positions.push(c + (normal * a.cos() + binormal * a.sin()) * tube);
        }
    }
    let idx = |i: u32, j: u32| (i % steps) * sides + j % sides;
    let mut indices = Vec::with_capacity((2 * steps * sides) as usize);
    for i in 0..steps {
        for j in 0..sides {
            let (a, b, c, d) = (idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1));
            indices.push([a, c, b]);
            indices.push([a, d, c]);
        }
    }
    Mesh { positions, indices }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    /// Every edge of a closed, consistently oriented mesh appears once in each direction.
    fn is_closed_and_oriented(m: &Mesh) -> bool {
        let mut edges: HashMap<(u32, u32), i32> = HashMap::new();
        for t in &m.indices {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
            }
        }
        edges.iter().all(|(&(a, b), &n)| n == 1 && edges.get(&(b, a)) == Some(&1))
    }

    #[test]
    fn uv_sphere_is_closed_with_outward_winding() {
        let m = uv_sphere(2.0, 12, 24);
        assert!(is_closed_and_oriented(&m));
        for t in &m.indices {
            let [a, b, c] = t.map(|i| m.positions[i as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.dot(a + b + c) > 0.0, "inward-facing triangle {t:?}");
        }
        assert!(m.positions.iter().all(|p| (p.length() - 2.0).abs() < 1e-5));
    }

    #[test]
    fn torus_knot_is_closed() {
        let m = torus_knot(2, 3, 1.0, 0.2, 128, 12);
        assert!(is_closed_and_oriented(&m));
        assert_eq!(m.triangle_count(), 2 * 128 * 12);
    }
}
