//! The stages of a frame, in the order [`crate::systems::frame_schedule`] runs them, and the
//! system sets other modules hang their systems on.

use bevy_ecs::schedule::SystemSet;

/// The stages of a frame; add your own animation systems `.in_set(FrameStage::Animate)` (or
/// anywhere `.before(FrameStage::SceneChanges)`).
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FrameStage {
    /// Animation and skinning (time → node transforms → vertices).
    Animate,
    /// Change detection, validation and accumulation reset.
    SceneChanges,
    /// Acceleration structure upkeep.
    Bvh,
    /// Sample set upkeep.
    SampleSets,
    /// Ray tracing.
    Trace,
    /// Accumulation.
    Accumulate,
    /// Resolve to images.
    Resolve,
}

/// The light types' update systems ([`crate::integrator::register_light`]): they run in
/// [`FrameStage::SceneChanges`] before the change detection that reads what they flagged.
#[derive(SystemSet, Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct LightUpdates;
