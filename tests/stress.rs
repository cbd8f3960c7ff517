//! Numerical stress: scale and offset invariance, grazing rays, tiny gaps, the camera inside
//! geometry, sliver triangles, and random scenes. No acne, no leaks, no NaN, ever.

mod common;

use std::sync::Arc;

use common::{check_analytic, occluder, settings, white};
use hemi::{analytic::AnalyticScene, prelude::*, random::SplitMix64, scene::mesh_gen};

/// The sphere-over-plane form factor holds from 1e-4 to 1e6 scale and up to 1e6 from the
/// origin. (f32 quantises a unit-size scene 1e6 away to 1/16, which no renderer can undo, so
/// offsets stay within 1e3 scene sizes.)
#[test]
fn sphere_over_plane_is_scale_and_offset_invariant() {
    for scale in [1e-4f32, 1e-2, 1e2, 1e4, 1e6] {
        for offset in [Vec3::ZERO, Vec3::new(1e3, -2e2, 5e2) * scale, Vec3::new(-7e2, 1e3, 3e2) * scale] {
            if offset.length() > 1e6 * scale.max(1.0) {
                continue;
            }
            check_analytic(AnalyticScene::SphereOverPlane, SamplerKind::Jittered, scale, offset, 64);
            check_analytic(AnalyticScene::Wall, SamplerKind::Jittered, scale, offset, 64);
        }
    }
}

/// A camera skimming the floor: primary rays at grazing angles, and AO rays leaving nearly
/// tangent, must never re-hit the floor.
#[test]
fn grazing_rays_do_not_self_intersect() {
    for height in [1e-3f32, 1e-1] {
        let mut r = Renderer::new(settings(64, 16, 8, SamplerKind::ZSobol));
        let w = r.world_mut();
        w.spawn((Plane::default(), white()));
        w.spawn(occluder(0.0));
        // Looking just below the horizon: the lower rows hit the floor at glancing angles.
        w.spawn(Camera::look_at(Vec3::new(0.0, height, 0.0), Vec3::new(0.0, 0.0, -100.0 * height), 20.0));
        r.settings_mut().background = Vec3::ONE; // rays that escape count as 1 too
        r.run_frame().unwrap();
        for p in &r.image().linear {
            assert_eq!(*p, Vec3::ONE, "grazing acne at camera height {height}");
        }
    }
}

/// A slab hovering 1e-5 above the floor: the floor beneath gets no light from a point light
/// above, and almost no AO (only through the far-away rim).
#[test]
fn tiny_gaps_do_not_leak_light() {
    let gap = 1e-5f32;
    let mut r = Renderer::new(settings(16, 16, 16, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn((Cuboid { half_extents: Vec3::new(5.0, 0.1, 5.0) }, Transform::from_xyz(0.0, 0.1 + gap, 0.0), white()));
    w.spawn((PointLight { ls: 50.0, ..Default::default() }, Transform::from_xyz(0.3, 3.0, 0.2)));
    w.spawn(occluder(0.0));
    // The camera sits inside the gap, looking down at the floor under the slab's centre.
    w.spawn(Camera { eye: Vec3::new(0.0, gap * 0.5, 0.0), target: Vec3::ZERO, up: Vec3::NEG_Z, vfov_degrees: 60.0 });
    r.run_frame().unwrap();
    for p in &r.image().linear {
        // AO through a 1e-5 slit 5 units away: about gap/distance ≈ 2e-6.
        assert!(p.max_element() < 1e-3, "light leaked into a {gap} gap: {p}");
    }
}

/// A camera inside a closed box sees only the box's inside: the AO floor everywhere.
#[test]
fn camera_inside_a_closed_box_sees_the_floor_value() {
    let mut r = Renderer::new(settings(16, 16, 8, SamplerKind::Jittered));
    let w = r.world_mut();
    let rotation = Quat::from_euler(glam::EulerRot::XYZ, 0.3, 0.7, -0.2);
    w.spawn((
        Cuboid { half_extents: Vec3::new(2.0, 1.0, 3.0) },
        Transform::from_xyz(5.0, 2.0, 1.0).with_rotation(rotation),
        white(),
    ));
    w.spawn(AmbientOccluder { min_amount: 0.125, ..Default::default() });
    w.spawn(Camera::look_at(Vec3::new(5.2, 2.1, 1.3), Vec3::new(7.0, 1.0, 0.0), 110.0));
    r.run_frame().unwrap();
    for p in &r.image().linear {
        assert!((*p - 0.125).abs().max_element() <= 1e-6, "{p}");
    }
}

/// Sliver triangles (area ~1e-12 of their bounding box) give finite, bounded pixels.
#[test]
fn sliver_triangles_stay_finite() {
    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for i in 0..200u32 {
        let x = i as f32 * 0.01 - 1.0;
        positions.extend([Vec3::new(x, 0.0, -1.0), Vec3::new(x + 1e-6, 1e-6, 1.0), Vec3::new(x + 2e-6, 2e-6, 3.0)]);
        indices.push([3 * i, 3 * i + 1, 3 * i + 2]);
    }
    let mut r = Renderer::new(settings(32, 32, 4, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((TriangleMesh(Arc::new(Mesh { positions, indices })), white()));
    w.spawn((Plane::default(), Transform::from_xyz(0.0, -0.5, 0.0), white()));
    w.spawn(occluder(0.0));
    w.spawn((PointLight { ls: 5.0, ..Default::default() }, Transform::from_xyz(0.0, 2.0, 0.0)));
    w.spawn(Camera::look_at(Vec3::new(0.0, 0.5, 2.5), Vec3::ZERO, 60.0));
    r.run_frame().unwrap();
    assert_eq!(r.stats().nonfinite_samples, 0);
    assert!(r.image().linear.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
}

/// Many random scenes and settings: every pixel is finite and within the physical bound
/// Σ ka·cd·ls·color (AO, e = 1) + Σ kd·cd/π·I (lights without falloff).
#[test]
fn random_scenes_give_finite_bounded_pixels() {
    let mut rng = SplitMix64::new(2024);
    let mesh = Arc::new(mesh_gen::uv_sphere(1.0, 6, 12));
    for case in 0..40 {
        let scale = 10f32.powf(rng.next_f32() * 8.0 - 4.0);
        let offset = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * scale * 100.0;
        let sampler = SamplerKind::ALL[rng.below(SamplerKind::ALL.len() as u32) as usize];
        let (w_px, h_px) = (1 + rng.below(24), 1 + rng.below(24));
        let mut r = Renderer::new(settings(w_px, h_px, 1 + rng.below(4), sampler));
        let mut bound = 0.0f32;
        let world = r.world_mut();
        let random_point = |rng: &mut SplitMix64| {
            offset + (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 4.0 * scale
        };
        for _ in 0..1 + rng.below(8) {
            let m = Matte {
                ka: rng.next_f32(),
                kd: rng.next_f32(),
                cd: Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()),
            };
            let t = Transform::from_translation(random_point(&mut rng)).with_rotation(Quat::from_euler(
                glam::EulerRot::XYZ,
                rng.next_f32() * 6.0,
                rng.next_f32() * 6.0,
                rng.next_f32() * 6.0,
            ));
            match rng.below(4) {
                0 => world.spawn((Sphere { radius: scale * (0.05 + rng.next_f32()) }, t, m)),
                1 => world.spawn((Cuboid { half_extents: Vec3::splat(scale * (0.05 + rng.next_f32())) }, t, m)),
                2 => world.spawn((TriangleMesh(mesh.clone()), t.with_scale(scale * (0.05 + rng.next_f32())), m)),
                _ => world.spawn((Plane { normal: Vec3::new(rng.next_f32(), 1.0, rng.next_f32()) }, t, m)),
            };
        }
        for _ in 0..rng.below(3) {
            let o = AmbientOccluder {
                ls: rng.next_f32() * 2.0,
                min_amount: rng.next_f32(),
                max_distance: scale * (0.1 + rng.next_f32() * 10.0),
                ..Default::default()
            };
            bound += o.ls;
            world.spawn(o);
        }
        for _ in 0..rng.below(3) {
            let l = PointLight {
                ls: rng.next_f32() * 10.0,
                falloff: false,
                shadows: rng.below(2) == 0,
                ..Default::default()
            };
            bound += l.ls / std::f32::consts::PI;
            world.spawn((l, Transform::from_translation(random_point(&mut rng))));
        }
        world.spawn(Camera::look_at(
            random_point(&mut rng) + Vec3::Y * scale * 3.0,
            offset,
            10.0 + rng.next_f32() * 120.0,
        ));
        r.run_frame().unwrap_or_else(|e| panic!("case {case}: {e}"));
        assert_eq!(r.stats().nonfinite_samples, 0, "case {case}");
        for p in &r.image().linear {
            assert!(p.is_finite() && p.min_element() >= 0.0, "case {case}: {p}");
            assert!(p.max_element() <= bound * (1.0 + 1e-5) + 1e-6, "case {case}: {p} above {bound}");
        }
    }
}
