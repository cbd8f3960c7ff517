//! The traversal counters (cargo feature `counters`): what they count, against scenes whose
//! queries are known. Run by `cargo test --release --features counters --test traversal_counts`
//! (`.ci/run` does); without the feature this file is empty.
#![cfg(feature = "counters")]

mod common;

use std::sync::Arc;

use common::{occluder, settings, white};
use hemi::{geometry::TraversalCounts, prelude::*, stats::FrameStats};

/// A 20 × 20 ground quad (two triangles) seen from above, every pixel on it; an ambient
/// occluder when `ao`; one camera ray per pixel, 64 AO rays each.
fn ground(ao: bool) -> Renderer {
    let mesh = Mesh {
        positions: vec![
            Vec3::new(-10.0, 0.0, -10.0),
            Vec3::new(10.0, 0.0, -10.0),
            Vec3::new(10.0, 0.0, 10.0),
            Vec3::new(-10.0, 0.0, 10.0),
        ],
        indices: vec![[0, 2, 1], [0, 3, 2]],
    };
    seen_from(mesh, 16, Vec3::new(0.0, 4.0, 0.5), ao.then(|| occluder(0.0)))
}

/// `mesh` (white) seen from `eye` towards the origin (60°) at `size` × `size` pixels, one
/// camera ray per pixel (no jitter) and 64 samples each, lit by `ao` alone.
fn seen_from(mesh: Mesh, size: u32, eye: Vec3, ao: Option<AmbientOccluder>) -> Renderer {
    let s = RenderSettings { jitter: false, ..settings(size, size, 64, SamplerKind::MultiJittered) };
    let mut r = Renderer::new(s);
    let w = r.world_mut();
    w.spawn((TriangleMesh(Arc::new(mesh)), white()));
    w.spawn(Camera::look_at(eye, Vec3::ZERO, 60.0));
    if let Some(ao) = ao {
        w.spawn(ao);
    }
    r
}

fn frame(mut r: Renderer) -> FrameStats {
    r.run_frame().unwrap().clone()
}

/// `a − b`, field by field.
fn minus(a: &TraversalCounts, b: &TraversalCounts) -> [u64; 6] {
    [
        a.packet_node_tests - b.packet_node_tests,
        a.packet_triangle_tests - b.packet_triangle_tests,
        a.lone_rays - b.lone_rays,
        a.node_tests - b.node_tests,
        a.leaf_tests - b.leaf_tests,
        a.triangle_packet_tests - b.triangle_packet_tests,
    ]
}

/// AO rays leaving a lone flat ground upwards enter no box but the root's: each packet of them
/// costs one node test (each ray one, where rays go alone), and none reaches a leaf, a triangle,
/// or goes on alone from a packet. The camera rays, the same in both renders, cancel out.
#[test]
fn escaping_ao_rays_cost_one_node_test_per_packet_and_nothing_else() {
    let (with, without) = (frame(ground(true)), frame(ground(false)));
    assert_eq!(with.rays.primary, 16 * 16);
    assert_eq!(with.rays.ao, 16 * 16 * 64);
    assert_eq!(without.rays.ao, 0);
    assert!(without.traversal.leaf_tests + without.traversal.packet_triangle_tests > 0, "camera rays hit the ground");
    let extra = minus(&with.traversal, &without.traversal);
    let ao = with.rays.ao;
    // Runs of 64 rays (one pixel's, quadrant by quadrant) cut into packets of `lanes`.
    let expected = match with.packet_lanes as u64 {
        0 => [0, 0, 0, ao, 0, 0],
        lanes => [ao / lanes, 0, 0, 0, 0, 0],
    };
    assert_eq!(extra, expected, "{:?} against {:?}", with.traversal, without.traversal);
}

/// Short AO rays (0.5 long) from an 8 × 8 grid of unit cubes 3 apart, seen from above at an
/// angle (pixels between the cubes see nothing): a packet's segments reach no cube but the
/// one its rays leave, so the packet starts at the node holding that cube's leaves, below the
/// root, and tests that node alone, or two; no ray enters a leaf (each leaves a convex cube's
/// face outwards). From the root every packet would test each node on the way down to its
/// cube that its rays enter.
#[test]
fn short_ao_rays_start_at_the_node_of_their_own_cube() {
    let grid = |ao: bool| {
        let mut mesh = Mesh { positions: Vec::new(), indices: Vec::new() };
        let faces = [[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 6, 7], [0, 1, 5], [0, 5, 4]];
        let faces = faces.into_iter().chain([[1, 2, 6], [1, 6, 5], [2, 3, 7], [2, 7, 6], [3, 0, 4], [3, 4, 7]]);
        let faces: Vec<[u32; 3]> = faces.collect();
        for (i, j) in (0..8).flat_map(|i| (0..8).map(move |j| (i as f32 * 3.0 - 10.5, j as f32 * 3.0 - 10.5))) {
            let k = mesh.positions.len() as u32;
            // Tops at four heights: the tree's boxes are tall, and rays leaving a low top climb
            // through them.
            let base = ((i + j) / 3.0).rem_euclid(4.0).round() * 1.5;
            for y in [base, base + 1.0] {
                mesh.positions
                    .extend([(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)].map(|(x, z)| Vec3::new(i + x, y, j + z)));
            }
            mesh.indices.extend(faces.iter().map(|f| f.map(|v| k + v)));
        }
        let ao = ao.then(|| AmbientOccluder { max_distance: 0.5, ..occluder(0.0) });
        seen_from(mesh, 32, Vec3::new(0.0, 22.0, 16.0), ao)
    };
    let (with, without) = (frame(grid(true)), frame(grid(false)));
    let lanes = with.packet_lanes as u64;
    if lanes == 0 {
        eprintln!("no packets on this CPU (or with four-wide trees): nothing to count");
        return;
    }
    assert!(with.bvh_wide_nodes > 8, "{} wide nodes: the tree should have levels", with.bvh_wide_nodes);
    let packets = with.rays.ao / lanes;
    assert!(with.rays.ao > 4000, "{} AO rays: the camera should see many cubes", with.rays.ao);
    let extra = minus(&with.traversal, &without.traversal);
    // One node test for most packets, two where a cube's leaves lie under two wide nodes
    // (1.25 a packet here; from the root it was 2.06 when measured).
    let [packet_nodes, rest @ ..] = extra;
    assert!(packet_nodes >= packets && 2 * packet_nodes <= 3 * packets, "{packet_nodes} node tests, {packets} packets");
    assert_eq!(rest, [0; 5], "{:?} against {:?}", with.traversal, without.traversal);
}

/// A tile's counts are taken on the thread that traced it, so the frame's sum is the same
/// whatever the thread count, and the default scene exercises every single-ray count.
#[test]
fn counts_do_not_depend_on_the_thread_count() {
    let render = |threads| {
        let s =
            RenderSettings { width: 64, height: 36, samples_per_frame: 4, samples_per_set: 8, ..Default::default() };
        let mut r = Renderer::with_default_scene(s).with_threads(threads).unwrap();
        r.run_frame().unwrap().clone()
    };
    let (one, two) = (render(1), render(2));
    assert_eq!(one.traversal, two.traversal);
    let t = &one.traversal;
    assert!(t.node_tests > 0 && t.leaf_tests > 0 && t.triangle_packet_tests > 0, "{t:?}");
    if one.packet_lanes > 0 {
        assert!(t.packet_node_tests > 0 && t.packet_triangle_tests > 0 && t.lone_rays > 0, "{t:?}");
    }
}
