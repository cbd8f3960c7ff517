//! Time to reach a target RMSE, per sampler, on scenes with exact references.
//!
//! `cargo bench --bench time_to_error` prints, for each analytic scene and sampler, the
//! seconds (interpolated log-log between measured spp) to reach RMSE 1e-2 and 3e-3, and the
//! fitted convergence slopes. One thread of work per render as the renderer schedules it.

use glam::Vec3;
use hemi::{Renderer, analytic::AnalyticScene, convergence, resources::RenderSettings, sampling::SamplerKind};

fn main() {
    // `cargo test --benches` runs bench binaries with `--bench` absent: stay quick then.
    let quick = !std::env::args().any(|a| a == "--bench");
    let max_spp = if quick { 8 } else { 2048 };
    println!(
        "{:<18} {:<15} {:>11} {:>11} {:>12} {:>12}",
        "scene", "sampler", "slope(spp)", "slope(s)", "t@1e-2 (ms)", "t@3e-3 (ms)"
    );
    for scene in AnalyticScene::ALL {
        let (width, height) = scene.size();
        let base = RenderSettings { width, height, ..Default::default() };
        let mut probe = Renderer::new(base.clone());
        let camera = scene.spawn(probe.world_mut(), 1.0, Vec3::ZERO);
        let reference: Vec<Vec3> =
            scene.reference(&camera, width, height, 1.0, Vec3::ZERO).unwrap().into_iter().map(Vec3::splat).collect();
        let build = |s: RenderSettings| {
            let mut r = Renderer::new(s);
            scene.spawn(r.world_mut(), 1.0, Vec3::ZERO);
            Ok(r)
        };
        let points = convergence::study(build, &base, &SamplerKind::ALL, max_spp, &reference, None, |_| {}).unwrap();
        for k in SamplerKind::ALL {
            let (s_spp, s_time) = convergence::slopes(&points, k);
            let ms = |target| {
                convergence::time_to_error(&points, k, target)
                    .map_or("-".into(), |d| format!("{:.2}", d.as_secs_f64() * 1e3))
            };
            println!(
                "{:<18} {:<15} {:>11.3} {:>11.3} {:>12} {:>12}",
                scene.name(),
                k.name(),
                s_spp.unwrap_or(f64::NAN),
                s_time.unwrap_or(f64::NAN),
                ms(1e-2),
                ms(3e-3)
            );
        }
    }
}
