//! Stage 5: counts this frame's samples into the accumulation. The trace system already added
//! them to the per-pixel sums, tile by tile, so that no image-sized frame buffer sits between
//! tracing and the sums.

use std::time::Instant;

use bevy_ecs::prelude::*;

use crate::{
    resources::{Accumulation, FrameSamples},
    stats::FrameStats,
};

/// Adds the frame's samples per pixel to [`Accumulation::spp`] (untouched when the frame
/// traced nothing).
pub fn accumulate(frame: Res<FrameSamples>, mut accumulation: ResMut<Accumulation>, mut stats: ResMut<FrameStats>) {
    let start = Instant::now();
    let spp = frame.samples_per_pixel;
    if spp == 0 {
        stats.spp = accumulation.spp;
        stats.record("accumulate", start.elapsed(), "nothing traced");
        return;
    }
    accumulation.spp += spp;
    stats.spp = accumulation.spp;
    stats.record("accumulate", start.elapsed(), format!("+{spp} spp"));
}
