//! Renders checked against analytic truth (prior-art §6): any self-intersection, light leak,
//! bias in the AO estimator or error in the light term makes these fail.

mod common;

use common::{check_analytic, occluder, settings, white};
use hemi::{
    analytic::{AnalyticScene, floor_hit},
    camera::PinholeRays,
    prelude::*,
};

/// Renders one frame and returns the renderer.
fn render(mut r: Renderer) -> Renderer {
    r.run_frame().expect("scene is valid");
    r
}

/// An open plane under AO alone is exactly ka·cd·ls·color at every pixel, at every scale and
/// distance from the origin: any darker pixel is self-intersection.
#[test]
fn open_plane_is_exactly_one_at_any_scale_and_offset() {
    for scale in [1e-4f32, 1.0, 1e3, 1e5] {
        for offset in [0.0f32, 1e3, 1e5] {
            if offset * 1e-6 > scale {
                continue; // f32 cannot place a camera that small that far out
            }
            let base = Vec3::new(offset, -offset * 0.5, offset * 0.25);
            let mut r = Renderer::new(settings(24, 16, 8, SamplerKind::Jittered));
            let w = r.world_mut();
            w.spawn((Plane::default(), Transform::from_translation(base), white()));
            w.spawn(occluder(0.0));
            // A tilted view (45° down, 60° field): rays arrive at many angles, none misses.
            let eye = base + Vec3::new(0.0, 1.0, 0.5) * scale;
            w.spawn(Camera::look_at(eye, base + Vec3::new(0.0, 0.0, -0.5) * scale, 60.0));
            let r = render(r);
            assert_eq!(r.stats().rays.ao, r.stats().rays.primary, "every primary ray hits the floor");
            for p in &r.image().linear {
                assert_eq!(*p, Vec3::ONE, "scale {scale} offset {offset}: self-intersection");
            }
        }
    }
}

/// A lone sphere (convex) sees the open sky from every point: AO is exactly 1.
#[test]
fn lone_sphere_is_unoccluded_everywhere() {
    for (center, radius) in [(Vec3::ZERO, 1.0f32), (Vec3::splat(2e4), 3e-3), (Vec3::new(-5e3, 0.0, 1e2), 40.0)] {
        let mut r = Renderer::new(settings(16, 16, 8, SamplerKind::MultiJittered));
        let w = r.world_mut();
        w.spawn((Sphere { radius }, Transform::from_translation(center), white()));
        w.spawn(occluder(0.0));
        w.spawn(Camera::look_at(center + Vec3::new(0.3, 0.2, 1.6) * radius, center, 50.0));
        let r = render(r);
        for p in &r.image().linear {
            assert_eq!(*p, Vec3::ONE, "sphere r={radius} at {center}");
        }
    }
}

/// Inside a closed sphere every AO ray is blocked: the image is the min_amount floor exactly.
#[test]
fn inside_closed_sphere_is_the_min_amount_floor() {
    for (radius, min_amount) in [(1.0f32, 0.25f32), (1e-3, 0.1), (500.0, 0.0)] {
        let mut r = Renderer::new(settings(16, 16, 16, SamplerKind::Jittered));
        let w = r.world_mut();
        w.spawn((Sphere { radius }, Transform::from_xyz(3.0, 1.0, -2.0), white()));
        w.spawn(occluder(min_amount));
        w.spawn(Camera::look_at(Vec3::new(3.0, 1.0, -2.0), Vec3::new(4.0, 1.2, -2.0), 90.0));
        let r = render(r);
        // Summing the floor value spp times in f32 may round its last bit.
        for p in &r.image().linear {
            assert!((*p - min_amount).abs().max_element() <= 1e-6, "r={radius}: {p}");
        }
    }
}

/// The same inside a closed tessellated sphere: no ray escapes through a crack between triangles.
#[test]
fn inside_closed_mesh_is_the_min_amount_floor() {
    let mesh = std::sync::Arc::new(hemi::scene::mesh_gen::uv_sphere(1.0, 24, 48));
    let mut r = Renderer::new(settings(32, 32, 16, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((TriangleMesh(mesh), white()));
    w.spawn(occluder(0.3));
    w.spawn(Camera::look_at(Vec3::new(0.1, 0.05, 0.0), Vec3::new(1.0, 0.3, 0.2), 100.0));
    let r = render(r);
    for p in &r.image().linear {
        assert!((*p - 0.3).abs().max_element() <= 1e-6, "light leaked through the mesh: {p}");
    }
}

/// A non-trivial instance transform: rotation, non-uniform scale and a large translation.
fn far_transform(scale: Vec3) -> Transform {
    Transform {
        translation: Vec3::new(3.0e3, -1.5e3, 7.5e2),
        rotation: Quat::from_euler(glam::EulerRot::YXZ, 0.7, -0.4, 0.25),
        scale,
    }
}

/// The closed-mesh floor test through an instance transform: the ray enters the BLAS frame and
/// the hit comes back with its error bound, and still no AO ray escapes.
#[test]
fn inside_closed_instanced_mesh_is_the_min_amount_floor() {
    let mesh = std::sync::Arc::new(hemi::scene::mesh_gen::uv_sphere(1.0, 24, 48));
    let t = far_transform(Vec3::new(2.5, 1.5, 3.5));
    let mut r = Renderer::new(settings(32, 32, 16, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((TriangleMesh(mesh), t, white()));
    w.spawn(occluder(0.3));
    let eye = t.translation + t.rotation * Vec3::new(0.1, 0.05, 0.0);
    w.spawn(Camera::look_at(eye, eye + t.rotation * Vec3::new(1.0, 0.3, 0.2), 100.0));
    let r = render(r);
    assert_eq!(r.stats().rays.ao, r.stats().rays.primary, "every primary ray hits the mesh");
    for p in &r.image().linear {
        assert!((*p - 0.3).abs().max_element() <= 1e-6, "light leaked through the instanced mesh: {p}");
    }
}

/// A convex tessellated sphere seen from outside through the same kind of transform: AO is
/// exactly 1 at every pixel, so no spawned ray re-hits its own instanced surface.
#[test]
fn convex_instanced_mesh_is_unoccluded_everywhere() {
    let mesh = std::sync::Arc::new(hemi::scene::mesh_gen::uv_sphere(1.0, 16, 32));
    for scale in [Vec3::new(2.0, 0.5, 1.0), Vec3::splat(1e-2), Vec3::new(-3.0, 3.0, 3.0)] {
        let t = far_transform(scale);
        let mut r = Renderer::new(settings(24, 24, 8, SamplerKind::Jittered));
        let w = r.world_mut();
        w.spawn((TriangleMesh(mesh.clone()), t, white()));
        w.spawn(occluder(0.0));
        // Look at the centre along the local axis of least scale, close enough that the
        // surface fills the view.
        let axis = Vec3::AXES[scale.abs().min_position()];
        let eye = t.translation + t.rotation * (axis * 1.6 * scale.abs().min_element());
        w.spawn(Camera::look_at(eye, t.translation, 20.0));
        let r = render(r);
        assert_eq!(r.stats().rays.ao, r.stats().rays.primary, "every primary ray hits the mesh");
        for p in &r.image().linear {
            assert_eq!(*p, Vec3::ONE, "scale {scale}: self-intersection");
        }
    }
}

/// Sphere of radius r, centre at height h over a plane: AO(x) = 1 − r²h/(h² + x²)^{3/2}
/// (the sphere's configuration factor), for every sampler whose AO directions are random.
#[test]
fn sphere_over_plane_matches_the_form_factor() {
    for sampler in SamplerKind::ALL.into_iter().filter(|&k| k != SamplerKind::Regular) {
        check_analytic(AnalyticScene::SphereOverPlane, sampler, 1.0, Vec3::ZERO, 128);
    }
}

/// Floor beside a long wall of height H: AO(x) = ½(1 + x/√(x² + H²)). The wall is made of
/// triangles 4000 units long: contact AO must not suffer from their size.
#[test]
fn floor_beside_a_long_wall() {
    for sampler in [SamplerKind::ZSobol, SamplerKind::Jittered, SamplerKind::Random] {
        check_analytic(AnalyticScene::Wall, sampler, 1.0, Vec3::ZERO, 256);
    }
}

/// Unbiased weighting: with cos^e sampling for e ≠ 1 the estimate still converges to the
/// cosine-weighted AO (the book's unweighted estimator would not).
#[test]
fn ao_with_other_exponents_converges_to_the_same_value() {
    let (r, h) = (1.0f32, 1.5f32);
    let expected = 1.0 - r * r / (h * h); // directly below the centre
    // e < 3 keeps the weighted estimator's variance finite.
    for exponent in [0.0f32, 1.0, 2.0] {
        let mut renderer = Renderer::new(settings(4, 4, 1024, SamplerKind::Jittered));
        let w = renderer.world_mut();
        w.spawn((Sphere { radius: r }, Transform::from_xyz(0.0, h, 0.0), white()));
        w.spawn((Plane::default(), white()));
        w.spawn(AmbientOccluder { exponent, ..Default::default() });
        // A camera just above the floor looking straight down at the point below the centre.
        w.spawn(Camera { eye: Vec3::new(0.0, 0.01, 0.0), target: Vec3::ZERO, up: Vec3::NEG_Z, vfov_degrees: 0.01 });
        let renderer = render(renderer);
        let img = renderer.image();
        let mean: f32 = img.linear.iter().map(|p| p.x).sum::<f32>() / img.linear.len() as f32;
        // 16 pixels × 1024 samples; the per-sample spread is below 1 for these exponents.
        // The book's unweighted estimator would be off by 0.19 (e = 0) or 0.14 (e = 2).
        let tolerance = 5.0 / (16.0f32 * 1024.0).sqrt();
        assert!((mean - expected).abs() < tolerance, "e = {exponent}: {mean} vs {expected}");
    }
}

/// Point light at height h over a plane, with falloff: E = I·h/(h² + x²)^{3/2}, L = E/π for a
/// white Lambertian floor. With the regular sampler the pixel positions are known exactly, so
/// the check is tight.
#[test]
fn point_light_on_a_plane_gives_inverse_square_cosine_irradiance() {
    let (intensity, h) = (20.0f32, 2.0f32);
    let (width, height, spp) = (32, 24, 16);
    let camera =
        Camera { eye: Vec3::new(0.5, 6.0, 4.0), target: Vec3::new(0.5, 0.0, 0.0), up: Vec3::Y, vfov_degrees: 45.0 };
    let mut r = Renderer::new(settings(width, height, spp, SamplerKind::Regular));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn((PointLight { ls: intensity, ..Default::default() }, Transform::from_xyz(0.0, h, 0.0)));
    w.spawn(camera);
    let r = render(r);
    let cam = PinholeRays::new(&camera, width, height).unwrap();
    let radiance = |p: Vec3| intensity * h / (h * h + p.x * p.x + p.z * p.z).powf(1.5) / std::f32::consts::PI;
    for y in 0..height {
        for x in 0..width {
            let mut expected = 0.0;
            for j in 0..4 {
                for i in 0..4 {
                    let u = glam::Vec2::new((i as f32 + 0.5) / 4.0, (j as f32 + 0.5) / 4.0);
                    expected += radiance(floor_hit(&cam, x, y, u, 0.0)) / 16.0;
                }
            }
            let got = r.image().pixel(x, y);
            assert!((got.x - expected).abs() <= 1e-4 * expected, "pixel ({x},{y}): {got} vs {expected}");
            assert_eq!(got.x, got.y);
        }
    }
}

/// Without falloff the light term is RTGU's kd·cd/π · ls·color · cos θ.
#[test]
fn point_light_without_falloff_is_cosine_only() {
    let mut r = Renderer::new(settings(8, 8, 1, SamplerKind::Regular));
    let w = r.world_mut();
    w.spawn((Plane::default(), Matte { ka: 0.0, kd: 0.5, cd: Vec3::new(1.0, 0.5, 0.25) }));
    w.spawn((PointLight { ls: 3.0, falloff: false, ..Default::default() }, Transform::from_xyz(0.0, 5.0, 0.0)));
    w.spawn(Camera { eye: Vec3::new(0.0, 1.0, 0.0), target: Vec3::ZERO, up: Vec3::NEG_Z, vfov_degrees: 0.1 });
    let r = render(r);
    let expected = Vec3::new(1.0, 0.5, 0.25) * 0.5 / std::f32::consts::PI * 3.0; // cos θ ≈ 1
    let got = r.image().pixel(4, 4);
    assert!((got - expected).abs().max_element() < 1e-5, "{got} vs {expected}");
}

/// A floor point directly behind an opaque sphere (seen from the light) gets no light; one
/// well outside the shadow gets the unshadowed value.
#[test]
fn point_behind_an_opaque_sphere_is_unlit() {
    let mut r = Renderer::new(settings(16, 16, 4, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn((Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 2.0, 0.0), white()));
    w.spawn((PointLight { ls: 10.0, ..Default::default() }, Transform::from_xyz(0.0, 4.0, 0.0)));
    // Looking down from between sphere and floor at the centre of the umbra.
    w.spawn(Camera { eye: Vec3::new(0.0, 1.0, 0.0), target: Vec3::ZERO, up: Vec3::NEG_Z, vfov_degrees: 5.0 });
    let r = render(r);
    for p in &r.image().linear {
        assert_eq!(*p, Vec3::ZERO, "light leaked into the umbra");
    }
    let mut lit = Renderer::new(settings(4, 4, 4, SamplerKind::Jittered));
    let w = lit.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn((Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 2.0, 0.0), white()));
    w.spawn((PointLight { ls: 10.0, ..Default::default() }, Transform::from_xyz(0.0, 4.0, 0.0)));
    w.spawn(Camera {
        eye: Vec3::new(3.0, 1.0, 0.0),
        target: Vec3::new(3.0, 0.0, 0.0),
        up: Vec3::NEG_Z,
        vfov_degrees: 0.5,
    });
    let lit = render(lit);
    let expected = 10.0 * 4.0 / (16.0f32 + 9.0).powf(1.5) / std::f32::consts::PI;
    let got = lit.image().pixel(2, 2).x;
    assert!((got - expected).abs() < 1e-3 * expected, "{got} vs {expected}");
}
