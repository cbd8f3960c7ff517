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
    let s = RenderSettings { jitter: false, ..settings(16, 16, 64, SamplerKind::MultiJittered) };
    let mut r = Renderer::new(s);
    let w = r.world_mut();
    w.spawn((TriangleMesh(Arc::new(mesh)), white()));
    w.spawn(Camera::look_at(Vec3::new(0.0, 4.0, 0.5), Vec3::ZERO, 60.0));
    if ao {
        w.spawn(occluder(0.0));
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
