//! Unusable input is refused with a one-line reason naming what is wrong; nothing panics and
//! no NaN or Inf reaches a pixel.

mod common;

use std::sync::Arc;

use common::{occluder, settings};
use hemi::{bevy_ecs::bundle::Bundle, prelude::*};

fn base() -> Renderer {
    let mut r = Renderer::new(settings(8, 8, 1, SamplerKind::Jittered));
    r.world_mut().spawn(Camera::look_at(Vec3::new(0.0, 2.0, 4.0), Vec3::ZERO, 45.0));
    r.world_mut().spawn(occluder(0.0));
    r
}

fn error_of(mut r: Renderer) -> String {
    let e = r.run_frame().expect_err("the scene should be refused").to_string();
    assert!(!e.contains('\n'), "multi-line error: {e}");
    assert!(r.image().linear.iter().all(|p| p.is_finite()));
    e
}

#[test]
fn nan_transform_is_refused_naming_the_entity() {
    let mut r = base();
    let e =
        r.world_mut().spawn((Sphere { radius: 1.0 }, Transform::from_xyz(f32::NAN, 0.0, 0.0), Name::new("ball"))).id();
    let msg = error_of(r);
    assert!(msg.contains("ball") && msg.contains(&e.to_string()) && msg.contains("transform"), "{msg}");
}

/// Spawns one entity into a valid base scene and expects the frame to be refused with a
/// message containing `expected`.
fn assert_refused(bundle: impl Bundle, expected: &str) {
    let mut r = base();
    r.world_mut().spawn(bundle);
    let msg = error_of(r);
    assert!(msg.contains(expected), "expected '{expected}' in: {msg}");
}

#[test]
fn degenerate_shapes_are_refused() {
    assert_refused(Sphere { radius: 0.0 }, "radius");
    assert_refused(Sphere { radius: -1.0 }, "radius");
    let stretched = Transform { scale: Vec3::new(1.0, 2.0, 1.0), ..Default::default() };
    assert_refused((Sphere { radius: 1.0 }, stretched), "non-uniform");
    assert_refused(Plane { normal: Vec3::ZERO }, "normal");
    assert_refused(Cuboid { half_extents: Vec3::new(1.0, 0.0, 1.0) }, "half extents");
    assert_refused((Sphere { radius: 1.0 }, Transform::default().with_scale(0.0)), "singular");
    let bad_index = Mesh { positions: vec![Vec3::ZERO, Vec3::X], indices: vec![[0, 1, 2]] };
    assert_refused(TriangleMesh(Arc::new(bad_index)), "indexes vertex");
    let inf =
        Mesh { positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(0.0, f32::INFINITY, 0.0)], indices: vec![[0, 1, 2]] };
    assert_refused(TriangleMesh(Arc::new(inf)), "non-finite");
    assert_refused((Sphere { radius: 1.0 }, Matte { ka: f32::NAN, kd: 1.0, cd: Vec3::ONE }), "material");
    assert_refused((Sphere { radius: 1.0 }, Plane::default()), "more than one shape");
}

#[test]
fn bad_cameras_lights_and_settings_are_refused() {
    let mut none = Renderer::new(settings(8, 8, 1, SamplerKind::Jittered));
    none.world_mut().spawn(Sphere { radius: 1.0 });
    assert!(error_of(none).contains("no Camera"));

    let mut two = base();
    two.world_mut().spawn(Camera::look_at(Vec3::ONE, Vec3::ZERO, 30.0));
    assert!(error_of(two).contains("2 cameras"));

    let mut same = Renderer::new(settings(8, 8, 1, SamplerKind::Jittered));
    same.world_mut().spawn(Camera::look_at(Vec3::ONE, Vec3::ONE, 30.0));
    assert!(error_of(same).contains("same point"));

    let mut fov = Renderer::new(settings(8, 8, 1, SamplerKind::Jittered));
    fov.world_mut().spawn(Camera::look_at(Vec3::ONE, Vec3::ZERO, 180.0));
    assert!(error_of(fov).contains("field of view"));

    let mut light = base();
    light.world_mut().spawn((PointLight::default(), Transform::from_xyz(0.0, f32::NAN, 0.0)));
    assert!(error_of(light).contains("point light position"));

    let mut occ = base();
    occ.world_mut().spawn(AmbientOccluder { min_amount: 1.5, ..Default::default() });
    assert!(error_of(occ).contains("min_amount"));

    let mut empty = base();
    empty.settings_mut().width = 0;
    assert!(error_of(empty).contains("empty"));

    let mut huge = base();
    huge.settings_mut().width = 100_000;
    huge.settings_mut().height = 100_000;
    assert!(error_of(huge).contains("limit"));
}

#[test]
fn fixing_the_scene_lets_rendering_resume() {
    let mut r = base();
    let e = r.world_mut().spawn(Sphere { radius: -1.0 }).id();
    assert!(r.run_frame().is_err());
    r.world_mut().get_mut::<Sphere>(e).unwrap().radius = 1.0;
    let stats = r.run_frame().unwrap();
    assert!(stats.rays.primary > 0);
}

#[test]
fn zero_area_triangles_are_skipped_not_fatal() {
    let mut r = base();
    let mesh = Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0],
        // The second triangle is collinear (zero area); the third repeats a vertex.
        indices: vec![[0, 1, 2], [0, 1, 3], [1, 1, 2]],
    };
    r.world_mut().spawn(TriangleMesh(Arc::new(mesh)));
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_prims, 1);
    assert!(stats.systems.iter().any(|s| s.note.contains("2 zero-area skipped")));
}

#[test]
fn tiny_and_one_pixel_images_work() {
    let mut r = base();
    r.world_mut().spawn(Sphere { radius: 1.0 });
    r.settings_mut().width = 1;
    r.settings_mut().height = 1;
    r.run_frame().unwrap();
    assert_eq!(r.image().linear.len(), 1);
    assert!(r.image().linear[0].is_finite());
}

#[test]
fn a_pinhole_and_an_orthographic_camera_together_are_refused() {
    let mut r = base();
    r.world_mut().spawn(OrthographicCamera {
        eye: Vec3::new(0.0, 5.0, 0.0),
        target: Vec3::ZERO,
        up: Vec3::Z,
        half_height: 2.0,
    });
    assert!(error_of(r).contains("2 cameras"));
    let mut r = Renderer::new(common::settings(8, 8, 1, SamplerKind::Jittered));
    r.world_mut().spawn(OrthographicCamera { eye: Vec3::Y, target: Vec3::ZERO, up: Vec3::Z, half_height: 0.0 });
    assert!(error_of(r).contains("half height"));
}

/// An orthographic camera looking straight down at an open plane: every ray is parallel, hits
/// the plane and sees the open sky, so every pixel is exactly 1.
#[test]
fn orthographic_view_of_an_open_plane_is_exactly_one() {
    let mut r = Renderer::new(common::settings(12, 8, 4, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), common::white()));
    w.spawn(common::occluder(0.0));
    w.spawn(OrthographicCamera {
        eye: Vec3::new(3.0, 2.0, 1.0),
        target: Vec3::new(3.0, 0.0, 1.0),
        up: Vec3::Z,
        half_height: 5.0,
    });
    let stats = r.run_frame().unwrap().clone();
    assert_eq!(stats.rays.ao, stats.rays.primary);
    assert!(r.image().linear.iter().all(|p| *p == Vec3::ONE));
}
