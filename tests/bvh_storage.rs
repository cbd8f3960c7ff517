//! What a BLAS keeps after its build: the bytes it reports against sizes computed by hand, and
//! the triangles its packets hold (the only copy it keeps) against the mesh they came from.

use std::sync::Arc;

use bevy_ecs::entity::Entity;
use glam::{Affine3A, Vec3, Vec3A};
use hemi::{
    components::{Matte, Mesh},
    geometry::{
        Object, Ray, SceneGeometry, Shape,
        accel::{Blas, Instance},
    },
    random::SplitMix64,
    scene::mesh_gen::torus_knot,
};

/// Bytes of a wide node of `width` children: six planes and two `u32` per child.
fn node_bytes(width: usize) -> usize {
    width * (6 * 4 + 2 * 4)
}

/// Bytes of a packet of four triangles (nine `f32` lanes of four and four `u32` slots), plus
/// its four slots' objects.
const PACKET_BYTES: usize = 9 * 16 + 16 + 4 * 4;

#[test]
fn a_one_triangle_blas_holds_one_node_one_packet_and_the_packets_objects() {
    let mesh = Mesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y], indices: vec![[0, 1, 2]] };
    let blas = Blas::from_mesh(&mesh);
    assert_eq!(blas.wide_node_count(), 1);
    let width = blas.node_width();
    assert!(width == 4 || width == 8, "width {width}");
    // Nothing else stays: neither the binary tree nor a second copy of the triangle.
    assert_eq!(blas.memory_bytes(), node_bytes(width) + PACKET_BYTES, "width {width}");
}

#[test]
fn a_large_blas_stores_at_most_a_packet_per_four_triangles_and_a_leaf_beside_its_nodes() {
    // 4800 triangles: the binned builder, whose leaves hold at most two packets.
    let mesh = torus_knot(2, 3, 0.8, 0.15, 240, 10);
    let blas = Blas::from_mesh(&mesh);
    let n = mesh.indices.len();
    let nodes = blas.wide_node_count() * node_bytes(blas.node_width());
    let packets = blas.memory_bytes() - nodes;
    assert_eq!(packets % PACKET_BYTES, 0, "whole packets and their objects: {packets} bytes");
    let count = packets / PACKET_BYTES;
    // Every leaf's last packet may be partly empty, and leaves hold 1 to 8 triangles.
    assert!(count >= n.div_ceil(4) && count <= n, "{count} packets for {n} triangles");
    // Binned SAH fills leaves in whole packets: at most one in ten lanes is left empty here.
    assert!(count * 4 <= n * 11 / 10, "{count} packets for {n} triangles");
}

#[test]
fn a_mesh_blas_holds_exactly_its_triangles_each_once_with_its_index() {
    let mut mesh = torus_knot(2, 3, 0.8, 0.15, 200, 12);
    // A zero-area triangle in the middle: skipped, and the indices after it keep their numbers.
    mesh.indices.insert(700, [3, 3, 4]);
    let blas = Blas::from_mesh(&mesh);
    assert_eq!(blas.degenerate_triangles, 1);
    let mut seen = vec![false; mesh.indices.len()];
    for prim in blas.prims() {
        let Shape::Triangle(t) = prim.shape else { panic!("a mesh BLAS holds triangles") };
        let k = prim.object as usize;
        assert!(!std::mem::replace(&mut seen[k], true), "triangle {k} twice");
        let want = mesh.indices[k].map(|i| Vec3A::from(mesh.positions[i as usize]));
        assert_eq!(t.p.map(|v| v.to_array().map(f32::to_bits)), want.map(|v| v.to_array().map(f32::to_bits)), "{k}");
    }
    let missing: Vec<usize> = (0..seen.len()).filter(|&k| !seen[k]).collect();
    assert_eq!(missing, vec![700], "every triangle but the degenerate one");
}

#[test]
fn a_refit_blas_finds_the_hits_of_the_moved_mesh() {
    let rest = torus_knot(2, 3, 0.8, 0.15, 200, 12);
    // Every vertex moved by its own offset: a deformation no transform gives.
    let mut rng = SplitMix64::new(5);
    let moved: Vec<Vec3> =
        rest.positions.iter().map(|&p| p + Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 0.1).collect();
    let mut blas = Blas::deformable(&rest);
    blas.refit(&moved, &rest.indices);
    let scene = |blas: Blas| {
        let blas = Arc::new(blas);
        let instance = Instance::new(0, blas.bounds().unwrap(), Affine3A::IDENTITY, Some(0)).unwrap();
        let object = Object { entity: Entity::PLACEHOLDER, material: Matte::default() };
        SceneGeometry::from_instances(vec![blas], vec![instance], vec![], vec![object])
    };
    let refit = scene(blas);
    let fresh = scene(Blas::from_mesh(&Mesh { positions: moved, indices: rest.indices.clone() }));
    let mut stack = Vec::new();
    let mut hits = 0;
    for _ in 0..2_000 {
        let origin = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 4.0 - 2.0;
        let target = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5;
        let ray = Ray::new(origin, (target - origin).normalize(), f32::INFINITY);
        let (a, b) = (refit.intersect(&ray, &mut stack), fresh.intersect(&ray, &mut stack));
        // The same triangle at the same distance (a hit reports its triangle's index).
        assert_eq!(a.map(|h| (h.t.to_bits(), h.prim)), b.map(|h| (h.t.to_bits(), h.prim)), "{ray:?}");
        assert_eq!(a.is_some(), fresh.intersect_brute_force(&ray).is_some());
        hits += usize::from(a.is_some());
    }
    assert!(hits > 200 && hits < 1_800, "{hits} of 2000 hit");
}
