//! Stage 1: notices any change to the scene or settings (change detection), validates what
//! the frame will read, and resets the accumulation so a changed scene starts converging anew.

use std::time::Instant;

use bevy_ecs::{prelude::*, system::SystemParam};

use crate::{
    camera::Cameras,
    components::{Camera, Cuboid, Matte, OrthographicCamera, Plane, Sphere, ThinLensCamera, Transform, TriangleMesh},
    integrator::LightRegistry,
    resources::{Accumulation, RenderSettings, SceneProblems},
    stats::FrameStats,
};

type SceneChanged = Or<(
    Changed<Transform>,
    Changed<Sphere>,
    Changed<Plane>,
    Changed<Cuboid>,
    Changed<TriangleMesh>,
    Changed<Matte>,
    Changed<Camera>,
    Changed<OrthographicCamera>,
    Changed<ThinLensCamera>,
)>;

/// Removals of any scene component (including despawns) since the last frame. Lights are
/// watched by the systems their registration adds ([`crate::integrator::register_light`]).
#[derive(SystemParam)]
pub struct SceneRemovals<'w, 's> {
    transform: RemovedComponents<'w, 's, Transform>,
    sphere: RemovedComponents<'w, 's, Sphere>,
    plane: RemovedComponents<'w, 's, Plane>,
    cuboid: RemovedComponents<'w, 's, Cuboid>,
    mesh: RemovedComponents<'w, 's, TriangleMesh>,
    matte: RemovedComponents<'w, 's, Matte>,
    camera: RemovedComponents<'w, 's, Camera>,
    orthographic: RemovedComponents<'w, 's, OrthographicCamera>,
    lens: RemovedComponents<'w, 's, ThinLensCamera>,
}

impl SceneRemovals<'_, '_> {
    /// Whether anything was removed; reads every list so none is seen twice.
    fn any(&mut self) -> bool {
        let counts = [
            self.transform.read().count(),
            self.sphere.read().count(),
            self.plane.read().count(),
            self.cuboid.read().count(),
            self.mesh.read().count(),
            self.matte.read().count(),
            self.camera.read().count(),
            self.orthographic.read().count(),
            self.lens.read().count(),
        ];
        counts.iter().any(|&c| c > 0)
    }
}

/// Validates camera, lights and settings; resets the accumulation when anything changed.
#[allow(clippy::too_many_arguments)]
pub fn detect_scene_changes(
    changed: Query<(), SceneChanged>,
    mut removed: SceneRemovals,
    settings: Res<RenderSettings>,
    cameras: Cameras,
    mut lights: ResMut<LightRegistry>,
    mut accumulation: ResMut<Accumulation>,
    mut problems: ResMut<SceneProblems>,
    mut stats: ResMut<FrameStats>,
) {
    let start = Instant::now();
    let removed_any = removed.any();
    let resized = accumulation.width != settings.width || accumulation.height != settings.height;
    let lights_changed = lights.take_changed();
    let dirty = !changed.is_empty() || removed_any || lights_changed || settings.is_changed() || resized;
    if dirty {
        problems.view = validate_view(&settings, &cameras, &lights);
        // Never allocate for settings that were refused (e.g. an absurd image size).
        match settings.validate() {
            Ok(()) => accumulation.reset(settings.width, settings.height),
            Err(_) => accumulation.reset(0, 0),
        }
    }
    let note = if dirty { "changed: accumulation reset" } else { "unchanged" };
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
