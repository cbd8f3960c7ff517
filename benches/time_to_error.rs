//! Time to reach a target RMSE, per sampler: on the analytic scenes (exact references) and on
//! the shipped peer scenes cornell and sphere_plane (AO against Embree's 4096-spp references,
//! whose own noise floors the RMSE near 1e-2 at 512×512).
//!
//! `cargo bench --bench time_to_error` prints, for each scene and sampler, the seconds
//! (interpolated log-log between measured spp) to reach two RMSE targets, and the fitted
//! convergence slopes.

use std::path::PathBuf;

use glam::Vec3;
use hemi::{
    Renderer,
    analytic::AnalyticScene,
    cli::{
        convergence::{self, ErrorPoint},
        peer_scene::PeerScene,
    },
    resources::{Aov, RenderSettings},
    sampling::SamplerKind,
};

/// Prints one row per sampler: slopes and the time to reach each target.
fn print_rows(scene: &str, samplers: &[SamplerKind], points: &[ErrorPoint], targets: [f64; 2]) {
    for &k in samplers {
        let (s_spp, s_time) = convergence::slopes(points, k);
        let ms = |target| {
            convergence::time_to_error(points, k, target)
                .map_or("-".into(), |d| format!("{:.2}", d.as_secs_f64() * 1e3))
        };
        println!(
            "{:<18} {:<15} {:>11.3} {:>11.3} {:>14} {:>14}",
            scene,
            k.name(),
            s_spp.unwrap_or(f64::NAN),
            s_time.unwrap_or(f64::NAN),
            format!("{}@{:.0e}", ms(targets[0]), targets[0]),
            format!("{}@{:.0e}", ms(targets[1]), targets[1]),
        );
    }
}

fn main() {
    // `cargo test --benches` runs bench binaries with `--bench` absent: stay quick then.
    let quick = !std::env::args().any(|a| a == "--bench");
    let max_spp = if quick { 8 } else { 2048 };
    println!(
        "{:<18} {:<15} {:>11} {:>11} {:>14} {:>14}",
        "scene", "sampler", "slope(spp)", "slope(s)", "ms@target", "ms@target"
    );
    for scene in AnalyticScene::ALL {
        let (width, height) = scene.size();
        let base = RenderSettings { width, height, ..Default::default() };
        let camera = scene.camera(1.0, Vec3::ZERO);
        let reference: Vec<Vec3> =
            scene.reference(&camera, width, height, 1.0, Vec3::ZERO).unwrap().into_iter().map(Vec3::splat).collect();
        let build = |s: RenderSettings| {
            let mut r = Renderer::new(s);
            scene.spawn(r.world_mut(), 1.0, Vec3::ZERO);
            Ok(r)
        };
        let points =
            convergence::study(build, &base, &SamplerKind::ALL, max_spp, &reference, None, None, |_| {}).unwrap();
        print_rows(scene.name(), &SamplerKind::ALL, &points, [1e-2, 3e-3]);
    }
    let samplers =
        [SamplerKind::Random, SamplerKind::Jittered, SamplerKind::CorrelatedMultiJittered, SamplerKind::ZSobol];
    for name in ["cornell", "sphere_plane"] {
        let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(format!("../shared/peers/scenes/{name}.json"));
        let peer = PeerScene::load(&path).unwrap();
        let (ao, mask) = peer.read_reference().unwrap();
        let reference: Vec<Vec3> = ao.into_iter().map(Vec3::splat).collect();
        let base = RenderSettings { width: peer.width, height: peer.height, jitter: false, ..Default::default() };
        let build = |s: RenderSettings| {
            let mut r = Renderer::new(s);
            peer.spawn(r.world_mut())?;
            Ok(r)
        };
        let max = if quick { 2 } else { 64 };
        let points =
            convergence::study(build, &base, &samplers, max, &reference, Some(&mask), Some(Aov::Ao), |_| {}).unwrap();
        print_rows(name, &samplers, &points, [5e-2, 2e-2]);
    }
}
