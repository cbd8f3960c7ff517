//! Helpers shared by the integration tests.
#![allow(dead_code)]

use hemi::{
    analytic::{AnalyticScene, pixel_mean_on_floor},
    camera::PinholeRays,
    prelude::*,
};

/// Settings for a small test render.
pub fn settings(width: u32, height: u32, spp: u32, sampler: SamplerKind) -> RenderSettings {
    RenderSettings {
        width,
        height,
        samples_per_frame: spp,
        samples_per_set: spp,
        max_spp: None,
        first_sample: 0,
        end_sample: None,
        seed: 7,
        sampler,
        tile_size: 8,
        background: Vec3::ZERO,
        jitter: true,
        aovs: false,
        target_error: None,
        ray_offset: 0.0,
        release_sums: false,
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
            let expected = pixel_mean_on_floor(cam, x, y, floor_y, &ao);
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

/// Renders an analytic scene scaled by `scale` and moved by `offset`, and checks every pixel
/// against its closed-form AO.
pub fn check_analytic(scene: AnalyticScene, sampler: SamplerKind, scale: f32, offset: Vec3, spp: u32) {
    let (width, height) = scene.size();
    let mut renderer = Renderer::new(settings(width, height, spp, sampler));
    let camera = scene.spawn(renderer.world_mut(), scale, offset);
    renderer.run_frame().expect("valid scene");
    let cam = PinholeRays::new(&camera, width, height).unwrap();
    let ao = |p: Vec3| scene.ao((p - offset) / scale);
    assert_matches_binomial(&renderer, &cam, (width, height, spp), offset.y, ao);
}

/// Standard base64 with padding, for `data:` URIs in hand-made glTF files.
pub fn base64(bytes: &[u8]) -> String {
    const T: &[u8] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = c.iter().enumerate().fold(0u32, |acc, (i, &b)| acc | (b as u32) << (16 - 8 * i));
        for i in 0..4 {
            s.push(if i <= c.len() { T[(n >> (18 - 6 * i) & 63) as usize] as char } else { '=' });
        }
    }
    s
}
