//! Stage 3: (re)generates the sample sets, only when the sampler, set size or seed changed.

use std::time::Instant;

use bevy_ecs::prelude::*;

use crate::{resources::RenderSettings, sampling::SampleSets, stats::FrameStats};

/// Regenerates [`SampleSets`] if they no longer match the settings.
pub fn update_sample_sets(settings: Res<RenderSettings>, mut sets: ResMut<SampleSets>, mut stats: ResMut<FrameStats>) {
    let start = Instant::now();
    let note = if sets.matches(&settings) {
        "unchanged".to_string()
    } else {
        *sets = SampleSets::for_settings(&settings);
        let tabled = if sets.has_cosine_table() { ", their cosine directions tabled" } else { "" };
        format!("generated {} sets of {} {} samples{tabled}", sets.num_sets(), sets.set_size(), sets.kind().name())
    };
    stats.record("sample_sets", start.elapsed(), note);
}
