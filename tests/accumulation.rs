//! `Renderer::render` continues the accumulation it has, ignores writes of equal values, and
//! fails, naming what changed, when the scene changes in every frame.

use hemi::{prelude::*, resources::Accumulation};

fn small_default_scene() -> Renderer {
    let s = RenderSettings { width: 48, height: 27, samples_per_frame: 2, samples_per_set: 8, ..Default::default() };
    Renderer::with_default_scene(s)
}

#[test]
fn render_continues_the_accumulation_and_matches_a_fresh_render() {
    let mut fresh = small_default_scene();
    assert_eq!(fresh.render(64).unwrap(), 32);

    let mut continued = small_default_scene();
    assert_eq!(continued.render(16).unwrap(), 8);
    // 48 more samples per pixel, two per frame.
    assert_eq!(continued.render(64).unwrap(), 24);
    assert_eq!(continued.spp(), 64);
    assert!(continued.image() == fresh.image(), "continuing to 64 spp differs from a fresh render to 64");

    // Reached already: one frame that traces nothing.
    assert_eq!(continued.render(64).unwrap(), 1);
    assert_eq!(continued.stats().samples_traced, 0);

    // A lower target starts over, giving the image of a fresh render to it.
    let mut fresh16 = small_default_scene();
    fresh16.render(16).unwrap();
    assert_eq!(continued.render(16).unwrap(), 8);
    assert_eq!(continued.spp(), 16);
    assert!(continued.image() == fresh16.image(), "going back to 16 spp differs from a fresh render to 16");
}

#[derive(Component)]
struct Held(Transform);

/// Writes every held entity's transform every frame, always with the value it already has, and
/// marks the camera and lights written (what writing their own value through `Mut` does).
fn rewrite_the_same_values(
    mut held: Query<(&Held, &mut Transform)>,
    mut cameras: Query<&mut Camera>,
    mut lights: Query<&mut PointLight>,
    mut occluders: Query<&mut AmbientOccluder>,
) {
    for (held, mut transform) in &mut held {
        *transform = held.0;
    }
    for mut camera in &mut cameras {
        camera.set_changed();
    }
    for mut light in &mut lights {
        light.set_changed();
    }
    for mut occluder in &mut occluders {
        occluder.set_changed();
    }
}

#[test]
fn writing_equal_values_every_frame_does_not_restart_accumulation() {
    let mut plain = small_default_scene();
    plain.render(32).unwrap();

    let mut rewritten = small_default_scene();
    let spheres: Vec<(Entity, Transform)> = rewritten
        .world_mut()
        .query_filtered::<(Entity, &Transform), With<Sphere>>()
        .iter(rewritten.world())
        .map(|(e, t)| (e, *t))
        .collect();
    assert!(!spheres.is_empty());
    for (entity, transform) in spheres {
        rewritten.world_mut().entity_mut(entity).insert(Held(transform));
    }
    rewritten.schedule_mut().add_systems(rewrite_the_same_values.in_set(FrameStage::Animate));
    assert_eq!(rewritten.render(32).unwrap(), 16, "one frame per two samples, none restarted");
    assert_eq!(rewritten.stats().reset, None);
    assert!(rewritten.image() == plain.image());
    // Nor does it make the BVH refit or rebuild anything.
    assert_eq!(bvh_note(&rewritten), "unchanged");

    // A sphere that really moves each frame does make the BVH work.
    let mut moving = small_default_scene();
    moving.world_mut().spawn((Wobble, Sphere { radius: 0.2 }));
    moving.schedule_mut().add_systems(wobble.in_set(FrameStage::Animate));
    moving.run_frame().unwrap();
    moving.run_frame().unwrap();
    assert!(bvh_note(&moving).contains("TLAS over"), "{}", bvh_note(&moving));
}

/// What the BVH system did in the last frame.
fn bvh_note(r: &Renderer) -> String {
    r.stats().systems.iter().find(|s| s.name == "bvh").expect("the BVH system ran").note.clone()
}

#[derive(Component)]
struct Wobble;

fn wobble(mut frame: Local<u32>, mut wobbling: Query<&mut Transform, With<Wobble>>) {
    *frame += 1;
    for mut transform in &mut wobbling {
        transform.translation.y = 1.0 + 0.01 * (*frame % 2) as f32;
    }
}

fn flicker(mut frame: Local<u32>, mut lights: Query<&mut PointLight>) {
    *frame += 1;
    for mut light in &mut lights {
        light.ls = 1.0 + (*frame % 2) as f32;
    }
}

#[test]
fn a_scene_that_changes_every_frame_fails_naming_the_component_and_entity() {
    let mut r = small_default_scene();
    let entity = r.world_mut().spawn((Wobble, Name::new("wobbler"), Sphere { radius: 0.2 })).id();
    r.schedule_mut().add_systems(wobble.in_set(FrameStage::Animate));
    let e = r.render(64).unwrap_err();
    let message = e.to_string();
    assert!(matches!(e, HemiError::KeepsChanging { frames: Renderer::MAX_CONSECUTIVE_RESETS, .. }), "{message}");
    assert!(message.contains(&format!("Transform of entity {entity} (\"wobbler\") changed")), "{message}");

    let mut r = small_default_scene();
    r.schedule_mut().add_systems(flicker.in_set(FrameStage::Animate));
    let message = r.render_at(0.0, 64).unwrap_err().to_string();
    assert!(message.contains("PointLight of entity") && message.contains("changed"), "{message}");

    // One frame that traces every sample converges however often the scene changes.
    let mut r = small_default_scene();
    r.settings_mut().samples_per_frame = 16;
    r.schedule_mut().add_systems(flicker.in_set(FrameStage::Animate));
    assert_eq!(r.render(16).unwrap(), 1);
}

/// The default scene, tracing pixel centres two samples a frame with no sample target: frames
/// after the first take each pixel's camera hit and point-light light from the accumulation.
fn pixel_centre_scene(max_spp: Option<u32>) -> Renderer {
    let s = RenderSettings {
        width: 48,
        height: 27,
        samples_per_frame: 2,
        samples_per_set: 8,
        jitter: false,
        max_spp,
        ..Default::default()
    };
    Renderer::with_default_scene(s)
}

#[test]
fn later_frames_take_the_kept_camera_hits_and_give_the_image_of_tracing_them_again() {
    let mut kept = pixel_centre_scene(Some(8));
    let mut traced = pixel_centre_scene(Some(8));
    let pixels = 48 * 27;
    for frame in 0..4 {
        // Forgetting the kept ends makes the frame trace its camera rays again.
        traced.world_mut().resource_mut::<Accumulation>().camera_ends.clear();
        let t = traced.run_frame().unwrap().rays;
        let k = kept.run_frame().unwrap().rays;
        assert_eq!(t.primary, pixels, "frame {frame}: every camera ray traced");
        assert!(t.shadow > 0, "frame {frame}: the point light's shadow rays traced");
        let (primary, shadow) = if frame == 0 { (t.primary, t.shadow) } else { (0, 0) };
        assert_eq!((k.primary, k.shadow), (primary, shadow), "frame {frame}: camera and point-light rays");
        assert_eq!(k.ao, t.ao, "frame {frame}");
    }
    assert!(kept.image() == traced.image(), "kept camera hits change the image");
    assert_eq!(kept.world().resource::<Accumulation>().camera_ends.len(), pixels as usize);

    // A render that is one frame keeps nothing.
    let mut one = pixel_centre_scene(Some(2));
    one.run_frame().unwrap();
    assert!(one.world().resource::<Accumulation>().camera_ends.is_empty());
}

#[test]
fn kept_camera_hits_are_dropped_when_the_camera_a_shape_or_a_light_changes() {
    fn change_camera(world: &mut World) {
        for mut camera in world.query::<&mut Camera>().iter_mut(world) {
            camera.eye.x += 0.3;
        }
    }
    fn change_shape(world: &mut World) {
        for mut t in world.query_filtered::<&mut Transform, With<Sphere>>().iter_mut(world) {
            t.translation.x += 0.2;
        }
    }
    fn change_light(world: &mut World) {
        for mut light in world.query::<&mut PointLight>().iter_mut(world) {
            light.ls *= 0.5;
        }
    }
    for (what, change) in
        [("camera", change_camera as fn(&mut World)), ("shape", change_shape), ("light", change_light)]
    {
        let mut changed = pixel_centre_scene(None);
        changed.run_frame().unwrap();
        changed.run_frame().unwrap();
        change(changed.world_mut());
        let rays = changed.run_frame().unwrap().rays;
        assert_eq!(rays.primary, 48 * 27, "{what}: the camera rays traced again");

        let mut fresh = pixel_centre_scene(None);
        change(fresh.world_mut());
        fresh.run_frame().unwrap();
        assert!(changed.image() == fresh.image(), "{what}: the frame after the change differs from a fresh render");
    }
}
