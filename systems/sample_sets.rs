//! Stage 3: (re)generates the sample sets, only when the sampler, set size or seed changed.

use std::time::Instant;

use bevy_ecs::prelude::*;

use crate::{resources::RenderSettings, sampling::SampleSets, stats::FrameStats};

/// Regenerates [`SampleSets`] if they no longer match the settings.
pub fn update_sample_sets(settings: Res<RenderSettings>, mut sets: ResMut<SampleSets>, mut stats: ResMut<FrameStats>) {
    let start = Instant::now();
    let s = &*settings;
    let runs = s.sample_runs();
    let note = if sets.matches(s.sampler, s.samples_per_set, s.seed, (s.width, s.height), runs) {
        "unchanged".to_string()
    } else {
        *sets = SampleSets::generate_for(s.sampler, s.samples_per_set, s.seed, s.width, s.height, runs);
        let tabled = match sets.cosine_table_order() {
            Some(order) => format!(", their cosine directions tabled in {order} order"),
            None => String::new(),
        };
        format!("generated {} sets of {} {} samples{tabled}", sets.num_sets(), sets.set_size(), sets.kind().name())
    };
    stats.record("sample_sets", start.elapsed(), note);
}
