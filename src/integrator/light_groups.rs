//! Registered light types as type-erased groups: [`register_light`] adds a light type's
//! update system to the frame schedule, which validates and places its lights when they
//! change; the tracer then shades each group behind one virtual call per run of samples.

use std::any::TypeId;

use bevy_ecs::prelude::*;
use glam::Vec3A;

use super::{RunPoint, Scene, Tracer, sample::TwoValues};
use crate::{
    components::Transform,
    frame::{FrameStage, LightUpdates, describe_change, short_type_name},
    geometry::SpawnOrigins,
    light::{Light, PlacedLight, ShadingPoint, Term},
};

/// The placed lights of one registered type, behind one virtual call per run of samples at a
/// shading point.
pub trait LightGroup: Send + Sync {
    /// Lights in the group.
    fn count(&self) -> usize;
    /// Sample dimensions the group uses, in all.
    fn dims(&self) -> u32;
    /// The reflectance the group's light is multiplied by.
    fn term(&self) -> Term;
    /// Adds the group's light arriving at `at` (before the material's reflectance) for the
    /// samples `first, first + 1, …` of `pixel`, one per element of `arriving`, tracing shadow
    /// rays from `spawn` with `tracer`. The samples share the hit, so per-hit work is done once.
    /// With `sum`, lights that can add their whole run at once add it there instead
    /// ([`RunSum`]).
    #[allow(clippy::too_many_arguments)]
    fn shade(
        &self,
        tracer: &mut Tracer,
        scene: &Scene,
        spawn: &SpawnOrigins,
        at: &ShadingPoint,
        pixel: u32,
        first: u32,
        first_dim: u32,
        arriving: &mut [Vec3A],
        sum: Option<&mut RunSum>,
    );
    /// Adds the group's light arriving at each of `points` into `arriving`, one element per
    /// point: a pixel's run of camera samples (their light samples computed ahead), or, for
    /// groups that draw no samples ([`LightGroup::dims`] 0), the pixels of a row, each lit once
    /// ([`Tracer::fixed_lights_row`]).
    fn shade_points(
        &self,
        tracer: &mut Tracer,
        scene: &Scene,
        points: &[RunPoint],
        first_dim: u32,
        skip_black: bool,
        arriving: &mut [Vec3A],
    );
}

/// A run's light summed over its samples, for callers that need only the sum (the beauty
/// image) or the sum and each sample's value where it takes two (adaptive sampling): lights
/// that can add a whole run at once (cosine runs in lanes, which count their blocked rays) add
/// it here ([`RunSum::add_counted`]); the others still add theirs sample by sample to the run's
/// `arriving`, and say so ([`RunSum::add_per_sample`]).
#[derive(Clone, Copy, Debug)]
pub struct RunSum {
    light: Vec3A,
    per_sample: bool,
    values: Option<TwoValues>,
}

impl Default for RunSum {
    fn default() -> Self {
        RunSum { light: Vec3A::ZERO, per_sample: false, values: Some(TwoValues::default()) }
    }
}

impl RunSum {
    /// Adds a run of `samples` samples whose light is `values`.
    #[inline]
    pub fn add_counted(&mut self, values: TwoValues, samples: u32) {
        self.light += values.sum(samples);
        self.values = self.values.and_then(|v| v.plus(&values, samples));
    }

    /// Records that some of the run's light went to `arriving` sample by sample.
    #[inline]
    pub fn add_per_sample(&mut self) {
        self.per_sample = true;
        self.values = None;
    }

    /// The light added here, summed over the run's samples.
    pub fn light(&self) -> Vec3A {
        self.light
    }

    /// Whether some of the run's light went to `arriving` instead.
    pub fn per_sample(&self) -> bool {
        self.per_sample
    }

    /// Each sample's light, where all of it was added here and it takes at most two values.
    pub fn values(&self) -> Option<TwoValues> {
        self.values
    }
}

struct Group<P>(Vec<P>);

impl<P: PlacedLight> LightGroup for Group<P> {
    fn count(&self) -> usize {
        self.0.len()
    }

    fn dims(&self) -> u32 {
        self.0.len() as u32 * P::DIMS
    }

    fn term(&self) -> Term {
        P::TERM
    }

    #[inline]
    fn shade(
        &self,
        tracer: &mut Tracer,
        scene: &Scene,
        spawn: &SpawnOrigins,
        at: &ShadingPoint,
        pixel: u32,
        first: u32,
        first_dim: u32,
        arriving: &mut [Vec3A],
        sum: Option<&mut RunSum>,
    ) {
        tracer.shade_lights(scene, spawn, at, &self.0, pixel, first, first_dim, arriving, sum)
    }

    fn shade_points(
        &self,
        tracer: &mut Tracer,
        scene: &Scene,
        points: &[RunPoint],
        first_dim: u32,
        skip_black: bool,
        arriving: &mut [Vec3A],
    ) {
        tracer.shade_points_lights(scene, points, &self.0, first_dim, skip_black, arriving)
    }
}

/// One registered light type.
struct Slot {
    type_id: TypeId,
    name: &'static str,
    group: Box<dyn LightGroup>,
    problems: Vec<String>,
}

/// Registered light types, in registration order, with their placed lights and problems.
#[derive(Resource, Default)]
pub struct LightRegistry {
    slots: Vec<Slot>,
    changed: Option<String>,
}

impl LightRegistry {
    /// Whether `L` is registered.
    pub fn contains<L: Light>(&self) -> bool {
        self.slots.iter().any(|s| s.type_id == TypeId::of::<L>())
    }

    /// Placed light groups in registration order, each with its first sample dimension.
    pub fn groups(&self) -> impl Iterator<Item = (u32, &dyn LightGroup)> {
        let mut dim = crate::sampling::dims::LIGHTS;
        self.slots.iter().map(move |s| {
            let first = dim;
            dim += s.group.dims();
            (first, &*s.group)
        })
    }

    /// Problems found in registered lights, in registration order.
    pub fn problems(&self) -> impl Iterator<Item = &String> {
        self.slots.iter().flat_map(|s| &s.problems)
    }

    /// "2 point light, 1 ambient occluder": the non-empty groups.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self
            .slots
            .iter()
            .filter(|s| s.group.count() > 0)
            .map(|s| format!("{} {}", s.group.count(), s.name))
            .collect();
        if parts.is_empty() { "no lights".into() } else { parts.join(", ") }
    }

    /// What light was added, changed or removed since the last call (`PointLight of entity
    /// 3v0 changed`), if any; clears it.
    pub fn take_changed(&mut self) -> Option<String> {
        self.changed.take()
    }

    fn slot_mut<L: Light>(&mut self) -> Option<&mut Slot> {
        self.slots.iter_mut().find(|s| s.type_id == TypeId::of::<L>())
    }
}

/// Registers light type `L` on a world and its frame schedule: its lights are validated,
/// placed and traced from the next frame on, and any change to them restarts accumulation.
/// Returns `false` (and does nothing) if `L` was already registered.
pub fn register_light<L: Light>(world: &mut World, schedule: &mut Schedule) -> bool {
    let mut registry = world.get_resource_or_init::<LightRegistry>();
    if registry.contains::<L>() {
        return false;
    }
    registry.slots.push(Slot {
        type_id: TypeId::of::<L>(),
        name: L::NAME,
        group: Box::new(Group::<L::Placed>(Vec::new())),
        problems: Vec::new(),
    });
    schedule.add_systems(update_lights::<L>.in_set(FrameStage::SceneChanges).in_set(LightUpdates));
    true
}

/// What [`update_lights`] reads of a light entity.
type LightData<'a, L> = (Entity, Ref<'a, L>, Option<Ref<'a, Transform>>, Option<&'a Name>);

/// A light as last placed: entity, value, and transform (the identity where it has none).
type SeenLight<L> = (Entity, L, Transform);

/// Re-validates and re-places all lights of type `L` when any of them (or its transform) was
/// added, removed or given a different value, and names the change for the accumulation reset.
fn update_lights<L: Light>(
    lights: Query<LightData<L>>,
    mut removed: RemovedComponents<L>,
    mut removed_transforms: RemovedComponents<Transform>,
    mut registry: ResMut<LightRegistry>,
    mut seen: Local<Vec<SeenLight<L>>>,
) {
    let removed_any = removed.read().count() > 0;
    let moved_any = removed_transforms.read().any(|e| lights.contains(e));
    let written = lights.iter().any(|(_, l, t, _)| l.is_changed() || t.is_some_and(|t| t.is_changed()));
    if !(removed_any || moved_any || written) {
        return;
    }
    let mut found: Vec<SeenLight<L>> =
        lights.iter().map(|(e, l, t, _)| (e, (*l).clone(), t.map_or(Transform::IDENTITY, |t| *t))).collect();
    found.sort_by_key(|(e, ..)| *e);
    // The first difference from the lights last placed, in entity order; none: equal writes.
    let differs = |a: Option<&SeenLight<L>>, b: Option<&SeenLight<L>>| match (a, b) {
        (Some((ea, la, ta)), Some((eb, lb, tb))) if ea == eb => (la != lb || ta != tb).then_some(*ea),
        // The smaller entity is the one added or removed.
        (Some((ea, ..)), Some((eb, ..))) => Some(*ea.min(eb)),
        (Some((e, ..)), None) | (None, Some((e, ..))) => Some(*e),
        (None, None) => None,
    };
    let n = found.len().max(seen.len());
    let Some(entity) = (0..n).find_map(|i| differs(found.get(i), seen.get(i))) else {
        return;
    };
    let what = match lights.get(entity) {
        Ok((_, light, _, name)) => {
            let light_changed = seen.iter().find(|(e, ..)| *e == entity).is_none_or(|(_, l, _)| l != &*light);
            let component = if light_changed { short_type_name::<L>() } else { "Transform" };
            format!("{} changed", describe_change(component, entity, name))
        }
        Err(_) => format!("{} was removed", describe_change(short_type_name::<L>(), entity, None)),
    };
    let mut placed = Vec::with_capacity(found.len());
    let mut problems = Vec::new();
    for (_, light, transform) in &found {
        match light.validate(transform) {
            Ok(()) => placed.extend(light.place(transform)),
            Err(e) => problems.push(e),
        }
    }
    *seen = found;
    let registry = &mut *registry;
    registry.changed = Some(what);
    if let Some(slot) = registry.slot_mut::<L>() {
        slot.group = Box::new(Group(placed));
        slot.problems = problems;
    }
}
