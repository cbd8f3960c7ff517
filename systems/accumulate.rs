//! Stage 5: adds this frame's samples to the running per-pixel sums.

use std::time::Instant;

use bevy_ecs::prelude::*;
use rayon::prelude::*;

use crate::{
    resources::{Accumulation, FrameSamples},
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
    acc.sums.par_iter_mut().zip(acc.counts.par_iter_mut()).zip(frame.sums.par_iter()).for_each(
        |((sum, count), add)| {
            *sum += add.as_dvec3();
            *count += spp;
        },
    );
    acc.spp += spp;
    stats.spp = acc.spp;
    stats.record("accumulate", start.elapsed(), format!("+{spp} spp"));
}
