//! The systems that make a frame, one file per stage (the trace stage's pixel buffers in
//! `trace/pixels.rs`), run in this order:
//!
//! 0. [`animation`] then [`skinning`]: pose the node hierarchy for the current time and
//!    deform skinned meshes (only when a glTF scene put a `NodeGraph` in the world).
//! 1. [`scene_changes`]: detect changed entities/settings, validate them, reset accumulation.
//! 2. [`bvh`]: rebuild the BVH only when geometry changed.
//! 3. [`sample_sets`]: regenerate sample sets only when sampler settings changed.
//! 4. [`trace`]: tile-parallel AO + direct tracing of this frame's samples, each tile's
//!    samples added to its pixels' running sums.
//! 5. [`accumulate`]: count the frame's samples per pixel.
//! 6. [`resolve`]: average into the linear image.

pub mod accumulate;
pub mod animation;
pub mod bvh;
pub mod resolve;
pub mod sample_sets;
pub mod scene_changes;
pub mod skinning;
pub mod trace;

use bevy_ecs::prelude::*;

use crate::{
    animation::NodeGraph,
    frame::{FrameStage, LightUpdates},
};

/// The schedule `Renderer::run_frame` runs once per frame.
pub fn frame_schedule() -> Schedule {
    let mut schedule = Schedule::default();
    schedule.configure_sets(
        (
            FrameStage::Animate,
            FrameStage::SceneChanges,
            FrameStage::Bvh,
            FrameStage::SampleSets,
            FrameStage::Trace,
            FrameStage::Accumulate,
            FrameStage::Resolve,
        )
            .chain(),
    );
    schedule.add_systems((
        (
            animation::animate.run_if(resource_exists::<NodeGraph>),
            skinning::skin_meshes.run_if(resource_exists_and_changed::<NodeGraph>),
        )
            .chain()
            .in_set(FrameStage::Animate),
        scene_changes::detect_scene_changes.in_set(FrameStage::SceneChanges).after(LightUpdates),
        bvh::update_bvh.in_set(FrameStage::Bvh),
        sample_sets::update_sample_sets
            .run_if(resource_changed::<crate::resources::RenderSettings>)
            .in_set(FrameStage::SampleSets),
        trace::trace.in_set(FrameStage::Trace),
        accumulate::accumulate.in_set(FrameStage::Accumulate),
        resolve::resolve.run_if(resource_changed::<crate::resources::Accumulation>).in_set(FrameStage::Resolve),
    ));
    schedule
}
