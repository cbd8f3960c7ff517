//! The stages of a frame, in the order [`crate::systems::frame_schedule`] runs them, the
//! system sets other modules hang their systems on, and how a reset names its cause.

use bevy_ecs::{entity::Entity, name::Name, schedule::SystemSet};

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

/// `Transform of entity 4v0 ("crate")`: how a reset names what changed.
pub fn describe_change(component: &str, entity: Entity, name: Option<&Name>) -> String {
    match name {
        Some(name) => format!("{component} of entity {entity} ({:?})", name.as_str()),
        None => format!("{component} of entity {entity}"),
    }
}

/// The last path segment of `T`'s type name (`Transform`, not `hemi::components::Transform`).
pub fn short_type_name<T: ?Sized>() -> &'static str {
    let full = std::any::type_name::<T>();
    full.rsplit("::").next().unwrap_or(full)
}
