//! Stage 5: adds this frame's samples to the running per-pixel sums.

use std::time::Instant;

use bevy_ecs::prelude::*;
use rayon::prelude::*;

use crate::{
    resources::{AOV_FLOATS, Accumulation, FrameSamples},
    stats::FrameStats,
};

/// Adds [`FrameSamples`] into [`Accumulation`] (untouched when the frame traced nothing).
pub fn accumulate(frame: Res<FrameSamples>, mut accumulation: ResMut<Accumulation>, mut stats: ResMut<FrameStats>) {
    let start = Instant::now();
    let spp = frame.samples_per_pixel;
    if spp == 0 || frame.sums.len() != accumulation.sums.len() {
        stats.spp = accumulation.spp;
        stats.record("accumulate", start.elapsed(), "nothing traced");
        return;
    }
    let acc = &mut *accumulation;
    acc.sums
        .par_iter_mut()
        .zip(acc.counts.par_iter_mut())
        .zip(acc.sq_sums.par_iter_mut())
        .zip(frame.sums.par_iter().zip(frame.counts.par_iter()).zip(frame.sq_sums.par_iter()))
        .for_each(|(((sum, count), sq), ((add, n), add_sq))| {
            *sum += add.as_dvec3();
            *count += n;
            *sq += *add_sq as f64;
        });
    if !frame.aovs.is_empty() {
        acc.aovs.resize(frame.aovs.len(), [0.0; AOV_FLOATS]);
        acc.aovs.par_iter_mut().zip(frame.aovs.par_iter()).for_each(|(sum, add)| {
            sum.iter_mut().zip(add).for_each(|(s, a)| *s += *a as f64);
        });
    }
    acc.spp += spp;
    stats.spp = acc.spp;
    stats.record("accumulate", start.elapsed(), format!("+{spp} spp"));
}
