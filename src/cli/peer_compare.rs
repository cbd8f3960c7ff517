//! Comparing hemi's AO with the peer renderers' references (`../shared/peers/refs`): over the
//! reference's hit pixels, the mean difference (bias) and the RMSE, beside the RMSE that
//! independent noise in both images explains, √(mean p(1−p)·(1/N + 1/N_ref)).

use std::time::Instant;

use super::peer_scene::PeerScene;
use crate::{
    Renderer,
    error::HemiError,
    resources::{Aov, RenderSettings},
    sampling::SamplerKind,
};

/// Samples per pixel of the shipped references.
pub const REFERENCE_SPP: u32 = 4096;

/// The outcome of one comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct Comparison {
    /// Scene name.
    pub scene: String,
    /// hemi's samples per pixel.
    pub spp: u32,
    /// Pixels the reference's primary rays hit.
    pub hit_pixels: usize,
    /// Pixels where hemi's hit/miss differs from the reference's.
    pub hit_mismatches: usize,
    /// Mean of (hemi − reference) AO over hit pixels.
    pub bias: f64,
    /// RMSE of hemi's AO against the reference over hit pixels.
    pub rmse: f64,
    /// RMSE explained by independent binomial noise in both images.
    pub predicted_rmse: f64,
    /// Seconds hemi's render took (scene loading excluded).
    pub seconds: f64,
    /// Rays traced.
    pub rays: u64,
}

/// Renders `scene` at `spp` with `sampler` under the peers' contract and compares its `ao`
/// AOV with the reference.
pub fn compare(
    scene: &PeerScene,
    spp: u32,
    sampler: SamplerKind,
    threads: Option<usize>,
) -> Result<Comparison, HemiError> {
    let (reference, hit) = scene.read_reference()?;
    let settings = RenderSettings {
        width: scene.width,
        height: scene.height,
        samples_per_frame: spp.min(RenderSettings::ONE_FRAME_SPP),
        samples_per_set: spp.min(RenderSettings::ONE_FRAME_SPP),
        max_spp: Some(spp),
        seed: scene.seed,
        sampler,
        jitter: false,
        aovs: true,
        ..Default::default()
    };
    let mut renderer = Renderer::new(settings);
    if let Some(n) = threads {
        renderer = renderer.with_threads(n)?;
    }
    scene.spawn(renderer.world_mut())?;
    let start = Instant::now();
    let mut rays = 0;
    while !renderer.converged() {
        rays += renderer.run_frame()?.rays.total();
    }
    let seconds = start.elapsed().as_secs_f64();
    let image = renderer.image();
    let ao = image.aov(Aov::Ao).unwrap_or_default();
    let depth = image.aov(Aov::Depth).unwrap_or_default();
    let (mut n, mut diff, mut diff2, mut var, mut mismatches) = (0usize, 0.0f64, 0.0f64, 0.0f64, 0usize);
    for i in 0..reference.len() {
        let hemi_hit = depth[i].x > 0.0;
        if hemi_hit != hit[i] {
            mismatches += 1;
        }
        if !hit[i] {
            continue;
        }
        let p = reference[i] as f64;
        let d = ao[i].x as f64 - p;
        n += 1;
        diff += d;
        diff2 += d * d;
        var += p * (1.0 - p);
    }
    let nf = n.max(1) as f64;
    Ok(Comparison {
        scene: scene.name.clone(),
        spp,
        hit_pixels: n,
        hit_mismatches: mismatches,
        bias: diff / nf,
        rmse: (diff2 / nf).sqrt(),
        predicted_rmse: (var / nf * (1.0 / spp as f64 + 1.0 / REFERENCE_SPP as f64)).sqrt(),
        seconds,
        rays,
    })
}
