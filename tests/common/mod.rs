//! Helpers shared by the integration tests.
#![allow(dead_code)]

use hemi::prelude::*;

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
