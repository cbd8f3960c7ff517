//! `Renderer::render` continues the accumulation it has, ignores writes of equal values, and
//! fails, naming what changed, when the scene changes in every frame.

use hemi::prelude::*;

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
