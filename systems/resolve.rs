//! Stage 6: averages the accumulated sums into the linear image.
//! Runs only when the accumulation changed. No NaN or Inf can reach a pixel.

use std::time::Instant;

use bevy_ecs::prelude::*;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::{
    resources::{AOV_FLOATS, Accumulation, Image, RenderSettings, Sums},
    stats::FrameStats,
};

/// Writes [`Image`] from [`Accumulation`], in the sums' own memory where the settings let the
/// finished image take it ([`RenderSettings::release_sums`]).
pub fn resolve(
    mut accumulation: ResMut<Accumulation>,
    settings: Res<RenderSettings>,
    mut image: ResMut<Image>,
    mut stats: ResMut<FrameStats>,
) {
    let start = Instant::now();
    let note = if accumulation.spent() {
        format!("{} spp, kept: the image holds the finished sums", accumulation.spp)
    } else if releases_sums(&accumulation, &settings) {
        // Not a change to the accumulation: its samples are the image's now.
        release_into(accumulation.bypass_change_detection(), &mut image);
        format!("{} spp, in the sums' memory", accumulation.spp)
    } else {
        resolve_into(&accumulation, &mut image);
        format!("{} spp", accumulation.spp)
    };
    stats.record("resolve", start.elapsed(), note);
}

/// Whether the image takes the sums: the settings ask for it, the sums hold one frame at one
/// count per pixel (f32, not adaptive) and that frame completed the target.
fn releases_sums(accumulation: &Accumulation, settings: &RenderSettings) -> bool {
    settings.release_sums
        && matches!(accumulation.sums, Sums::OneFrame(_))
        && accumulation.counts.is_empty()
        && accumulation.spp > 0
        && settings.target_spp().is_some_and(|target| accumulation.spp >= target)
}

/// [`resolve_into`]'s image, divided in place in the one-frame sums, which the image then
/// owns (the accumulation is left spent, [`Accumulation::spent`]): the same values, as a
/// pixel's mean is its f32 sum widened and divided in f64 either way.
fn release_into(accumulation: &mut Accumulation, image: &mut Image) {
    let count = f64::from(accumulation.spp);
    image.width = accumulation.width;
    image.height = accumulation.height;
    // The last image goes before the sums become the next: never both at once.
    image.linear = Vec::new();
    image.aovs = Vec::new();
    let Sums::OneFrame(mut linear) = std::mem::take(&mut accumulation.sums) else {
        unreachable!("checked by releases_sums")
    };
    linear.par_iter_mut().for_each(|s| *s = mean(s.as_dvec3(), count));
    if let Sums::OneFrame(mut aovs) = std::mem::take(&mut accumulation.aovs)
        && aovs.len() == linear.len()
    {
        aovs.as_flattened_mut().par_iter_mut().for_each(|s| *s = aov_mean(f64::from(*s), count));
        image.aovs = aovs;
    }
    image.linear = linear;
}

/// Averages `accumulation` into `image` (resized to it): what every frame's resolve does, for
/// sums made elsewhere too (e.g. merged parts of a render split by sample index).
pub fn resolve_into(accumulation: &Accumulation, image: &mut Image) {
    let n = accumulation.sums.len();
    image.width = accumulation.width;
    image.height = accumulation.height;
    image.linear.resize(n, Vec3::ZERO);
    image.linear.par_iter_mut().enumerate().for_each(|(i, linear)| {
        let count = accumulation.count(i);
        *linear = if count > 0 { mean(accumulation.sums.get(i), count as f64) } else { Vec3::ZERO };
    });
    image.aovs.clear();
    if accumulation.aovs.len() == n {
        image.aovs.par_extend((0..n).into_par_iter().map(|i| {
            let count = accumulation.count(i);
            let mut means = [0.0f32; AOV_FLOATS];
            if count > 0 {
                for (m, s) in means.iter_mut().zip(accumulation.aovs.get(i)) {
                    *m = aov_mean(s, count as f64);
                }
            }
            means
        }));
    }
}

/// A pixel's mean radiance from its sum and its (nonzero) sample count, divided in f64; black
/// where that is not finite.
#[inline]
fn mean(sum: DVec3, count: f64) -> Vec3 {
    let mean = (sum / count).as_vec3();
    if mean.is_finite() { mean } else { Vec3::ZERO }
}

/// One AOV float's mean from its sum and its (nonzero) sample count, as [`mean`] makes it.
#[inline]
fn aov_mean(sum: f64, count: f64) -> f32 {
    let mean = (sum / count) as f32;
    if mean.is_finite() { mean } else { 0.0 }
}
