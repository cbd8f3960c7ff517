//! Stage 6: averages the accumulated sums into the linear image.
//! Runs only when the accumulation changed. No NaN or Inf can reach a pixel.

use std::time::Instant;

use bevy_ecs::prelude::*;
use glam::Vec3;
use rayon::prelude::*;

use crate::{
    resources::{AOV_FLOATS, Accumulation, Image},
    stats::FrameStats,
};

/// Writes [`Image`] from [`Accumulation`].
pub fn resolve(accumulation: Res<Accumulation>, mut image: ResMut<Image>, mut stats: ResMut<FrameStats>) {
    let start = Instant::now();
    resolve_into(&accumulation, &mut image);
    stats.record("resolve", start.elapsed(), format!("{} spp", accumulation.spp));
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
        let mean = if count > 0 { (accumulation.sums.get(i) / count as f64).as_vec3() } else { Vec3::ZERO };
        *linear = if mean.is_finite() { mean } else { Vec3::ZERO };
    });
    image.aovs.clear();
    if accumulation.aovs.len() == n {
        image.aovs.par_extend((0..n).into_par_iter().map(|i| {
            let count = accumulation.count(i);
            let mut mean = [0.0f32; AOV_FLOATS];
            if count > 0 {
                for (m, s) in mean.iter_mut().zip(accumulation.aovs.get(i)) {
                    let v = (s / count as f64) as f32;
                    *m = if v.is_finite() { v } else { 0.0 };
                }
            }
            mean
        }));
    }
}
