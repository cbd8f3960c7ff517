//! Run time against error: renders a scene at 1, 2, 4, … spp with each sampler and measures
//! RMSE against a reference, the time each render took, and the fitted convergence rates.

use std::{fmt::Write, time::Duration};

use glam::Vec3;

use crate::{
    Renderer,
    error::HemiError,
    resources::{Aov, RenderSettings},
    sampling::SamplerKind,
};

/// One render of the study.
#[derive(Clone, Debug, PartialEq)]
pub struct ErrorPoint {
    /// Sampler used.
    pub sampler: SamplerKind,
    /// Samples per pixel.
    pub spp: u32,
    /// Wall time of the frame (sample sets, tracing, accumulation, resolve).
    pub seconds: f64,
    /// Rays traced.
    pub rays: u64,
    /// Root-mean-square error against the reference over the compared pixels and channels.
    pub rmse: f64,
    /// RMSE divided by the reference's mean over the compared pixels.
    pub relative_rmse: f64,
}

/// RMSE of `image` against `reference` over the pixels where `mask` is true (all if `None`).
pub fn rmse(image: &[Vec3], reference: &[Vec3], mask: Option<&[bool]>) -> (f64, f64) {
    let (mut sum2, mut sum_ref, mut n) = (0.0f64, 0.0f64, 0usize);
    for (i, (a, b)) in image.iter().zip(reference).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        let d = (*a - *b).as_dvec3();
        sum2 += d.length_squared();
        sum_ref += b.as_dvec3().element_sum();
        n += 3;
    }
    if n == 0 {
        return (0.0, 0.0);
    }
    let rmse = (sum2 / n as f64).sqrt();
    let mean = sum_ref / n as f64;
    (rmse, if mean > 0.0 { rmse / mean } else { 0.0 })
}

/// What a study compares with its reference: the beauty image, or one AOV.
pub fn measured(renderer: &Renderer, aov: Option<Aov>) -> Vec<Vec3> {
    match aov {
        Some(a) => renderer.image().aov(a).unwrap_or_default(),
        None => renderer.image().linear.clone(),
    }
}

/// Renders with every sampler at spp = 1, 2, 4, … up to `max_spp`. `scene` builds a fresh
/// renderer holding the scene; each spp is one frame with sample sets of exactly that size.
/// The beauty image (or the AOV `aov`, which turns AOVs on) is compared with `reference`
/// over the pixels `mask` keeps.
#[allow(clippy::too_many_arguments)]
pub fn study(
    scene: impl Fn(RenderSettings) -> Result<Renderer, HemiError>,
    base: &RenderSettings,
    samplers: &[SamplerKind],
    max_spp: u32,
    reference: &[Vec3],
    mask: Option<&[bool]>,
    aov: Option<Aov>,
    mut progress: impl FnMut(&ErrorPoint),
) -> Result<Vec<ErrorPoint>, HemiError> {
    let mut points = Vec::new();
    for &sampler in samplers {
        let mut renderer = scene(RenderSettings { sampler, aovs: base.aovs || aov.is_some(), ..base.clone() })?;
        // Warm-up frame: builds the BVH so that it is not charged to the first spp.
        renderer.run_frame()?;
        let mut spp = 1;
        while spp <= max_spp {
            {
                let mut s = renderer.settings_mut();
                s.samples_per_frame = spp;
                s.samples_per_set = spp;
                s.max_spp = Some(spp);
            }
            let stats = renderer.run_frame()?;
            let seconds = stats.total_time().as_secs_f64();
            let rays = stats.rays.total();
            let (rmse, relative_rmse) = rmse(&measured(&renderer, aov), reference, mask);
            let point = ErrorPoint { sampler, spp, seconds, rays, rmse, relative_rmse };
            progress(&point);
            points.push(point);
            spp *= 2;
        }
    }
    Ok(points)
}

/// Least-squares slope of log(y) against log(x) over points with x, y > 0.
pub fn log_log_slope(xy: impl IntoIterator<Item = (f64, f64)>) -> Option<f64> {
    let pts: Vec<(f64, f64)> =
        xy.into_iter().filter(|(x, y)| *x > 0.0 && *y > 0.0).map(|(x, y)| (x.ln(), y.ln())).collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (mx, my) = (pts.iter().map(|p| p.0).sum::<f64>() / n, pts.iter().map(|p| p.1).sum::<f64>() / n);
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Fitted slopes of RMSE against spp and against seconds for one sampler's points.
pub fn slopes(points: &[ErrorPoint], sampler: SamplerKind) -> (Option<f64>, Option<f64>) {
    let mine = || points.iter().filter(move |p| p.sampler == sampler);
    (log_log_slope(mine().map(|p| (p.spp as f64, p.rmse))), log_log_slope(mine().map(|p| (p.seconds, p.rmse))))
}

/// The study as CSV: `sampler,spp,seconds,rays,rmse,relative_rmse`.
pub fn to_csv(points: &[ErrorPoint]) -> String {
    let mut s = String::from("sampler,spp,seconds,rays,rmse,relative_rmse\n");
    for p in points {
        let _ = writeln!(
            s,
            "{},{},{:.6},{},{:.6e},{:.6e}",
            p.sampler.name(),
            p.spp,
            p.seconds,
            p.rays,
            p.rmse,
            p.relative_rmse
        );
    }
    s
}

/// Time to reach `target` RMSE for a sampler, interpolated log-log between measured points.
pub fn time_to_error(points: &[ErrorPoint], sampler: SamplerKind, target: f64) -> Option<Duration> {
    let mine: Vec<&ErrorPoint> = points.iter().filter(|p| p.sampler == sampler).collect();
    let first = mine.first()?;
    if first.rmse <= target {
        return Some(Duration::from_secs_f64(first.seconds));
    }
    mine.windows(2).find(|w| w[1].rmse <= target && w[1].rmse > 0.0).map(|w| {
        let (a, b) = (w[0], w[1]);
        let f = (target.ln() - a.rmse.ln()) / (b.rmse.ln() - a.rmse.ln());
        Duration::from_secs_f64(
            (a.seconds.max(1e-9).ln() + f * (b.seconds.max(1e-9).ln() - a.seconds.max(1e-9).ln())).exp(),
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_of_a_power_law_is_its_exponent() {
        let pts = (0..8).map(|i| {
            let x = 2f64.powi(i);
            (x, 3.0 * x.powf(-0.75))
        });
        assert!((log_log_slope(pts).unwrap() + 0.75).abs() < 1e-12);
    }

    #[test]
    fn rmse_respects_the_mask() {
        let a = [Vec3::ONE, Vec3::ZERO];
        let b = [Vec3::ZERO, Vec3::ZERO];
        assert_eq!(rmse(&a, &b, None).0, (0.5f64).sqrt());
        assert_eq!(rmse(&a, &b, Some(&[false, true])).0, 0.0);
    }
}
