//! Stage 1: notices any change to the scene or settings (change detection), validates what
//! the frame will read, and resets the accumulation so a changed scene starts converging anew.

use std::{collections::HashMap, time::Instant};

use bevy_ecs::{name::Name, prelude::*, system::SystemParam};

use crate::{
    camera::Cameras,
    components::{Camera, Cuboid, Matte, OrthographicCamera, Plane, Sphere, ThinLensCamera, Transform, TriangleMesh},
    frame::{describe_change, short_type_name},
    integrator::LightRegistry,
    material::Surface,
    resources::{Accumulation, RenderSettings, SceneProblems, ShapeValueChanges},
    stats::FrameStats,
};

/// Whether two values of a scene component render the same image.
pub trait SameValue {
    /// `true` when swapping `self` for `other` changes nothing.
    fn same_value(&self, other: &Self) -> bool;
}

macro_rules! same_by_partial_eq {
    ($($t:ty),*) => {$(
        impl SameValue for $t {
            fn same_value(&self, other: &Self) -> bool {
                self == other
            }
        }
    )*};
}

same_by_partial_eq!(Transform, Sphere, Plane, Cuboid, Matte, Surface, Camera, OrthographicCamera, ThinLensCamera);

/// By pointer: meshes are shared data, and comparing vertices every frame would cost what a
/// refit does. A mesh swapped for an equal copy counts as a change.
impl SameValue for TriangleMesh {
    fn same_value(&self, other: &Self) -> bool {
        std::sync::Arc::ptr_eq(&self.0, &other.0)
    }
}

/// Watches one scene component: its writes, its removals (despawns included), and the value
/// each entity had when last looked at, so that writing an equal value is not a change.
#[derive(SystemParam)]
pub struct Watch<'w, 's, T: Component + Clone + SameValue> {
    written: Query<'w, 's, (Entity, &'static T), Changed<T>>,
    removed: RemovedComponents<'w, 's, T>,
    seen: Local<'s, HashMap<Entity, T>>,
}

impl<T: Component + Clone + SameValue> Watch<'_, '_, T> {
    /// The first entity whose `T` was removed (`true`), added or given a different value since
    /// the last call; takes in the new values either way.
    fn first_change(&mut self) -> Option<(Entity, bool)> {
        let mut first = None;
        for entity in self.removed.read() {
            // Added and removed between two frames: never rendered, so no change.
            if self.seen.remove(&entity).is_some() {
                first.get_or_insert((entity, true));
            }
        }
        for (entity, value) in &self.written {
            match self.seen.get_mut(&entity) {
                Some(old) if old.same_value(value) => {}
                Some(old) => {
                    *old = value.clone();
                    first.get_or_insert((entity, false));
                }
                None => {
                    self.seen.insert(entity, value.clone());
                    first.get_or_insert((entity, false));
                }
            }
        }
        first
    }
}

/// Every scene component whose change restarts accumulation. Lights are watched by the
/// systems their registration adds ([`crate::integrator::register_light`]).
#[derive(SystemParam)]
pub struct SceneWatch<'w, 's> {
    transform: Watch<'w, 's, Transform>,
    sphere: Watch<'w, 's, Sphere>,
    plane: Watch<'w, 's, Plane>,
    cuboid: Watch<'w, 's, Cuboid>,
    mesh: Watch<'w, 's, TriangleMesh>,
    matte: Watch<'w, 's, Matte>,
    surface: Watch<'w, 's, Surface>,
    camera: Watch<'w, 's, Camera>,
    orthographic: Watch<'w, 's, OrthographicCamera>,
    lens: Watch<'w, 's, ThinLensCamera>,
    names: Query<'w, 's, &'static Name>,
}

impl SceneWatch<'_, '_> {
    /// What changed first (`Sphere of entity 3v0 changed`), if anything did, and whether a shape
    /// value (a transform, sphere, plane, cuboid or surface) did; every watch is brought up to
    /// date so that no change is seen twice.
    fn first_change(&mut self) -> (Option<String>, bool) {
        // Each watch's first change, and whether its component is a shape value the BVH reads
        // (meshes are compared by pointer and count on their own: see `update_bvh`).
        let changes = [
            (short_type_name::<Transform>(), true, self.transform.first_change()),
            (short_type_name::<Sphere>(), true, self.sphere.first_change()),
            (short_type_name::<Plane>(), true, self.plane.first_change()),
            (short_type_name::<Cuboid>(), true, self.cuboid.first_change()),
            (short_type_name::<TriangleMesh>(), false, self.mesh.first_change()),
            (short_type_name::<Matte>(), false, self.matte.first_change()),
            (short_type_name::<Surface>(), true, self.surface.first_change()),
            (short_type_name::<Camera>(), false, self.camera.first_change()),
            (short_type_name::<OrthographicCamera>(), false, self.orthographic.first_change()),
            (short_type_name::<ThinLensCamera>(), false, self.lens.first_change()),
        ];
        let shapes = changes.iter().any(|&(_, shape, change)| shape && change.is_some());
        let first = changes.into_iter().find_map(|(c, _, e)| Some((c, e?))).map(|(component, (entity, removed))| {
            let what = describe_change(component, entity, self.names.get(entity).ok());
            format!("{what} {}", if removed { "was removed" } else { "changed" })
        });
        (first, shapes)
    }
}

/// The settings as they bear on the image: the sample target only says when to stop, so
/// raising it continues the accumulation, and releasing the sums only says where the finished
/// image is kept.
fn image_settings(settings: &RenderSettings) -> RenderSettings {
    RenderSettings { max_spp: None, release_sums: false, ..settings.clone() }
}

/// Validates camera, lights and settings; resets the accumulation when anything changed: a
/// component's value (not a write of the same value), an entity or component removed, a light,
/// a setting other than `max_spp`, or `max_spp` lowered below the samples already taken (so
/// that the image is the one a fresh render to that target gives); and when more samples are
/// asked of sums the finished image took.
#[allow(clippy::too_many_arguments)]
pub fn detect_scene_changes(
    mut watch: SceneWatch,
    settings: Res<RenderSettings>,
    cameras: Cameras,
    mut lights: ResMut<LightRegistry>,
    mut accumulation: ResMut<Accumulation>,
    mut problems: ResMut<SceneProblems>,
    mut shape_changes: ResMut<ShapeValueChanges>,
    mut stats: ResMut<FrameStats>,
    mut seen_settings: Local<Option<RenderSettings>>,
) {
    let start = Instant::now();
    let (component_change, shapes_changed) = watch.first_change();
    shape_changes.any = shapes_changed;
    let light_change = lights.take_changed();
    let settings_changed = settings.is_changed() && {
        let changed = seen_settings.as_ref().is_none_or(|old| image_settings(old) != image_settings(&settings));
        *seen_settings = Some(settings.clone());
        changed
    };
    let cause = if settings_changed {
        Some("the render settings changed".to_string())
    } else if accumulation.width != settings.width || accumulation.height != settings.height {
        Some("the image size changed".to_string())
    } else if accumulation.spent() && settings.target_spp().is_none_or(|target| target > accumulation.spp) {
        Some("the finished image took the sums (release_sums)".to_string())
    } else if settings.max_spp.is_some_and(|max| accumulation.spp > max) {
        Some(format!("max_spp fell below the {} spp accumulated", accumulation.spp))
    } else {
        component_change.or(light_change)
    };
    if cause.is_some() {
        problems.view = validate_view(&settings, &cameras, &lights);
        // Never allocate for settings that were refused (e.g. an absurd image size).
        match settings.validate() {
            Ok(()) => accumulation.reset(settings.width, settings.height, settings.accumulation_layout()),
            Err(_) => accumulation.reset(0, 0, Default::default()),
        }
    }
    let note = match &cause {
        Some(cause) => format!("accumulation reset: {cause}"),
        None => "unchanged".to_string(),
    };
    stats.reset = cause;
    stats.record("scene_changes", start.elapsed(), note);
}

fn validate_view(settings: &RenderSettings, cameras: &Cameras, lights: &LightRegistry) -> Vec<String> {
    let mut problems = Vec::new();
    if let Err(e) = settings.validate() {
        problems.push(e);
    }
    match cameras.pinhole.iter().count() + cameras.orthographic.iter().count() + cameras.lens.iter().count() {
        0 => problems.push("the scene has no Camera".into()),
        1 => {}
        n => problems.push(format!("the scene has {n} cameras; exactly one is rendered")),
    }
    problems.extend(cameras.pinhole.iter().filter_map(|c| c.validate().err()));
    problems.extend(cameras.orthographic.iter().filter_map(|c| c.validate().err()));
    problems.extend(cameras.lens.iter().filter_map(|c| c.validate().err()));
    problems.extend(lights.problems().cloned());
    problems
}
