//! Helpers shared by the integration tests.
#![allow(dead_code)]

use hemi::{camera::PinholeRays, prelude::*};

/// Settings for a small test render.
pub fn settings(width: u32, height: u32, spp: u32, sampler: SamplerKind) -> RenderSettings {
    RenderSettings {
        width,
        height,
        samples_per_frame: spp,
        samples_per_set: spp,
        max_spp: None,
        seed: 7,
        sampler,
        tile_size: 8,
        background: Vec3::ZERO,
    }
}

/// White matte, ka = kd = 1, cd = 1: pixel values equal the AO or irradiance/π directly.
pub fn white() -> Matte {
    Matte { ka: 1.0, kd: 1.0, cd: Vec3::ONE }
}

/// An occluder with unit radiance and the given floor.
pub fn occluder(min_amount: f32) -> AmbientOccluder {
    AmbientOccluder { min_amount, ..Default::default() }
}

/// Point where a camera ray meets the floor y = `floor_y` (in f64, so the expected values do
/// not suffer the rounding the renderer is being tested for).
pub fn floor_hit(cam: &PinholeRays, x: u32, y: u32, u: glam::Vec2, floor_y: f32) -> Vec3 {
    let ray = cam.ray(x, y, u);
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let t = (floor_y as f64 - o.y) / d.y;
    (o + d * t).as_vec3()
}

/// Mean of `f` over a pixel's footprint on the floor (8 × 8 sub-pixel grid).
pub fn pixel_mean(cam: &PinholeRays, x: u32, y: u32, floor_y: f32, f: impl Fn(Vec3) -> f32) -> f32 {
    let mut sum = 0.0;
    for j in 0..8 {
        for i in 0..8 {
            let u = glam::Vec2::new((i as f32 + 0.5) / 8.0, (j as f32 + 0.5) / 8.0);
            sum += f(floor_hit(cam, x, y, u, floor_y));
        }
    }
    sum / 64.0
}

/// Every pixel's red channel is within 5 binomial standard errors of the pixel mean of `ao`,
/// and the z-scores do not drift as a whole (a bias check). Stratified samplers do better
/// than binomial, never worse.
pub fn assert_matches_binomial(
    r: &Renderer,
    cam: &PinholeRays,
    (width, height, spp): (u32, u32, u32),
    floor_y: f32,
    ao: impl Fn(Vec3) -> f32,
) {
    let (mut z_sum, mut n) = (0.0f64, 0);
    for y in 0..height {
        for x in 0..width {
            let expected = pixel_mean(cam, x, y, floor_y, &ao);
            let got = r.image().pixel(x, y).x;
            let sigma = (expected * (1.0 - expected) / spp as f32).sqrt().max(1e-4);
            let z = (got - expected) / sigma;
            assert!(z.abs() < 5.0, "pixel ({x},{y}): AO {got} vs analytic {expected} (z = {z:.1})");
            z_sum += z as f64;
            n += 1;
        }
    }
    let mean_z = z_sum / n as f64;
    assert!(mean_z.abs() < 5.0 / (n as f64).sqrt(), "mean z-score {mean_z}: AO is biased");
}

/// Renders a sphere (radius 1, centre height 1.5) over a plane, all scaled by
/// `scale` and moved by `offset`, and checks AO(x) = 1 − r²h/(h² + x²)^{3/2} per pixel.
pub fn check_sphere_over_plane(sampler: SamplerKind, scale: f32, offset: Vec3, spp: u32) {
    let (r, h) = (1.0f32, 1.5f32);
    let (width, height) = (48, 12);
    let mut renderer = Renderer::new(settings(width, height, spp, sampler));
    // Look straight down at floor points x ∈ [~1.1, ~4.9] beside the sphere, from high up so
    // no line of sight passes through the sphere.
    let camera = Camera {
        eye: offset + Vec3::new(3.0, 30.0, 0.0) * scale,
        target: offset + Vec3::new(3.0, 0.0, 0.0) * scale,
        up: Vec3::NEG_Z,
        vfov_degrees: 1.8,
    };
    let w = renderer.world_mut();
    w.spawn((
        Sphere { radius: r * scale },
        Transform::from_translation(offset + Vec3::new(0.0, h, 0.0) * scale),
        white(),
    ));
    w.spawn((Plane::default(), Transform::from_translation(offset), white()));
    w.spawn(occluder(0.0));
    w.spawn(camera);
    renderer.run_frame().expect("valid scene");
    let cam = PinholeRays::new(&camera, width, height).unwrap();
    let ao = |p: Vec3| {
        let d = (p - offset) / scale;
        1.0 - r * r * h / (h * h + d.x * d.x + d.z * d.z).powf(1.5)
    };
    assert_matches_binomial(&renderer, &cam, (width, height, spp), offset.y, ao);
}
