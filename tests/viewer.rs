//! The viewer's logic without a window: synthetic input moves the camera through the ECS
//! world, change detection restarts accumulation, the frame budget picks resolution and
//! samples, and a still view shows exactly the image `hemi render` makes.

use std::{path::Path, time::Duration};

use glam::Vec2;
use hemi::{
    prelude::*,
    resources::Aov,
    scene::gltf::{self, SpawnOptions},
    viewer::{
        Buffer, Button, FrameBudget, InputEvent, Key, Viewer, ViewerOptions,
        budget::scaled,
        controller::{CameraPose, move_pose},
        display,
        input::Input,
    },
};

const W: u32 = 64;
const H: u32 = 36;

fn options(spp: u32, spf: Option<u32>) -> ViewerOptions {
    ViewerOptions { size: (W, H), spp, spf, ..Default::default() }
}

fn builtin(spp: u32, spf: Option<u32>) -> Viewer {
    let r = Renderer::with_default_scene(RenderSettings { seed: 3, ..Default::default() });
    Viewer::new(r, "built-in", options(spp, spf)).unwrap()
}

/// Frames of `dt` until the view has converged (at most `limit`).
fn converge(v: &mut Viewer, limit: usize) {
    for _ in 0..limit {
        v.frame(Duration::from_millis(16)).unwrap();
        if v.renderer().converged() && !v.needs_frame() {
            return;
        }
    }
    panic!("the view did not converge in {limit} frames");
}

/// `hemi render --spp spp --spf spf --seed 3` of the built-in scene at W×H, as sRGB pixels.
fn render_reference(spp: u32, spf: u32) -> Vec<u32> {
    let mut r = Renderer::with_default_scene(RenderSettings {
        width: W,
        height: H,
        samples_per_frame: spf,
        samples_per_set: spp.min(RenderSettings::ONE_FRAME_SPP),
        seed: 3,
        ..Default::default()
    });
    r.render(spp).unwrap();
    r.image().srgb8().chunks_exact(3).map(|c| display::pack(c[0], c[1], c[2])).collect()
}

fn camera(v: &Viewer) -> Camera {
    let w = v.renderer().world();
    *w.try_query::<&Camera>().unwrap().iter(w).next().unwrap()
}

fn drag(v: &mut Viewer, button: Button, from: Vec2, to: Vec2) {
    v.handle(InputEvent::ButtonDown(button));
    v.handle(InputEvent::CursorMoved(from));
    v.handle(InputEvent::CursorMoved(to));
    v.handle(InputEvent::ButtonUp(button));
}

#[test]
fn a_still_view_shows_exactly_what_hemi_render_writes() {
    let mut v = builtin(8, Some(2));
    converge(&mut v, 20);
    assert_eq!(v.renderer().spp(), 8);
    assert_eq!(v.framebuffer(), render_reference(8, 2).as_slice());
    // Every still frame was at full resolution, two samples at a time, without a restart
    // after the first.
    let r = v.records();
    assert!(r.iter().all(|f| (f.width, f.height, f.scale) == (W, H, 1)));
    assert_eq!(r.iter().filter(|f| f.reset).count(), 1);
    // The screenshot is the framebuffer.
    let shot = v.screenshot();
    assert_eq!(shot.dimensions(), (W, H));
    assert_eq!(display::pack(shot.as_raw()[0], shot.as_raw()[1], shot.as_raw()[2]), v.framebuffer()[0]);
}

#[test]
fn adaptive_frames_take_the_same_samples_as_one_frame() {
    // Samples per frame chosen by the budget (the first frame takes one): the same sample
    // sequence, only summed in other groups, so the 8-bit image agrees to within a code.
    let mut v = builtin(16, None);
    converge(&mut v, 64);
    let reference = render_reference(16, 16);
    let worst = v
        .framebuffer()
        .iter()
        .zip(&reference)
        .flat_map(|(&a, &b)| display::unpack(a).into_iter().zip(display::unpack(b)))
        .map(|(a, b)| a.abs_diff(b))
        .max()
        .unwrap();
    assert!(worst <= 1, "largest difference {worst}");
}

#[test]
fn orbit_drag_moves_the_camera_and_restarts_accumulation() {
    let mut v = builtin(4, Some(4));
    converge(&mut v, 10);
    let before = camera(&v);
    let resets = v.renderer().world().resource::<hemi::resources::Accumulation>().resets;
    drag(&mut v, Button::Left, Vec2::new(10.0, 10.0), Vec2::new(40.0, 10.0));
    assert!(v.needs_frame());
    let rec = v.frame(Duration::from_millis(16)).unwrap().clone();
    assert!(rec.moving && rec.reset);
    let after = camera(&v);
    assert_ne!(before, after);
    // Orbiting keeps the target and the distance.
    assert_eq!(before.target, after.target);
    assert!(((before.eye - before.target).length() - (after.eye - after.target).length()).abs() < 1e-4);
    assert!(v.renderer().world().resource::<hemi::resources::Accumulation>().resets > resets);
    // Still again: back to full resolution, converging from scratch to the new camera's image.
    converge(&mut v, 20);
    let last = v.records().last().unwrap();
    assert_eq!((last.width, last.height, last.spp), (W, H, 4));
}

#[test]
fn pan_dolly_fly_frame_and_reset() {
    let mut v = builtin(1, Some(1));
    v.frame(Duration::ZERO).unwrap();
    let home = camera(&v);
    drag(&mut v, Button::Middle, Vec2::ZERO, Vec2::new(5.0, 0.0));
    v.frame(Duration::from_millis(16)).unwrap();
    let panned = camera(&v);
    assert_ne!(panned.target, home.target, "pan moves the target");
    assert!(((panned.eye - panned.target) - (home.eye - home.target)).length() < 1e-4, "and keeps the offset");

    v.handle(InputEvent::Wheel(2.0));
    v.frame(Duration::from_millis(16)).unwrap();
    let dollied = camera(&v);
    assert!((dollied.eye - dollied.target).length() < (panned.eye - panned.target).length());

    v.handle(InputEvent::KeyDown(Key::W));
    v.frame(Duration::from_millis(100)).unwrap();
    let flown = camera(&v);
    let step = flown.eye - dollied.eye;
    assert!(step.length() > 0.0 && step.normalize().dot((dollied.target - dollied.eye).normalize()) > 0.99);
    // A long pause before a frame (the window idles once converged) flies no farther.
    v.frame(Duration::from_secs(10)).unwrap();
    v.handle(InputEvent::KeyUp(Key::W));
    let again = camera(&v).eye - flown.eye;
    assert!((again.length() - step.length()).abs() < 1e-3 * step.length(), "{again} vs {step}");

    v.handle(InputEvent::KeyDown(Key::R));
    v.frame(Duration::from_millis(16)).unwrap();
    assert_eq!(camera(&v), home, "R goes back to the file's camera");

    v.handle(InputEvent::KeyDown(Key::F));
    v.frame(Duration::from_millis(16)).unwrap();
    let framed = camera(&v);
    assert_ne!(framed, home);
    let dir = |c: &Camera| (c.target - c.eye).normalize();
    assert!(dir(&framed).dot(dir(&home)) > 0.9999, "F keeps the view direction");
}

#[test]
fn shift_and_left_button_pan_instead_of_orbiting() {
    let mut input = Input::default();
    input.apply(InputEvent::KeyDown(Key::Shift));
    input.apply(InputEvent::ButtonDown(Button::Left));
    input.apply(InputEvent::CursorMoved(Vec2::ZERO));
    input.apply(InputEvent::CursorMoved(Vec2::new(3.0, 4.0)));
    assert_eq!((input.pan, input.orbit), (Vec2::new(3.0, 4.0), Vec2::ZERO));
    input.apply(InputEvent::KeyUp(Key::Shift));
    input.apply(InputEvent::CursorMoved(Vec2::new(4.0, 4.0)));
    assert_eq!(input.orbit, Vec2::new(1.0, 0.0));
    input.end_frame();
    assert!(!input.moves_camera());
}

#[test]
fn orbit_never_goes_over_the_pole() {
    let pose = CameraPose {
        eye: Vec3::new(0.0, 0.0, 5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        vfov_degrees: 40.0,
        half_height: 0.0,
    };
    let mut input = Input::default();
    input.viewport_height = 100.0;
    input.orbit = Vec2::new(0.0, 10_000.0);
    let p = move_pose(pose, &input, None, pose);
    assert!(p.valid(), "{p:?}");
}

#[test]
fn moving_frames_lower_the_resolution_to_fit_the_budget_and_still_ones_restore_it() {
    let r = Renderer::with_default_scene(RenderSettings::default());
    let opts = ViewerOptions {
        size: (320, 180),
        spp: 64,
        target: Duration::from_micros(200),
        turntable: Some(10.0),
        ..Default::default()
    };
    let mut v = Viewer::new(r, "built-in", opts).unwrap();
    for _ in 0..4 {
        v.frame(Duration::from_millis(30)).unwrap();
    }
    let last = v.records().last().unwrap().clone();
    assert!(last.moving && last.scale > 1 && last.width < 320, "{last:?}");
    assert_eq!(v.framebuffer().len(), 320 * 180, "the window stays full size");
    assert_eq!(last.spf, 1);

    // A generous budget while still: full resolution and, once the first frame has measured
    // the cost, more samples per frame (all that are left, where they fit: the view may then
    // have converged, and a converged frame traces none).
    let mut v = builtin(64, None);
    for _ in 0..3 {
        v.frame(Duration::from_millis(30)).unwrap();
    }
    let records = v.records();
    let last = records.last().unwrap();
    assert_eq!((last.scale, last.width), (1, W));
    assert!(records[1].spf > 1, "{records:?}");
}

#[test]
fn the_budget_plan_follows_the_measured_cost() {
    let mut b = FrameBudget::new(Duration::from_millis(33));
    // Nothing measured: one sample at full resolution.
    let p = b.plan((640, 360), true, true, 100, None);
    assert_eq!((p.width, p.scale, p.spf), (640, 1, 1));
    // 1 µs per sample: 640×360 takes 230 ms per sample, so moving frames divide by 3
    // (213×120 = 25.6k samples, 25.6 ms).
    b.observe(640 * 360, 1, Duration::from_micros(640 * 360), Duration::from_micros(640 * 360));
    let p = b.plan((640, 360), true, true, 100, None);
    assert_eq!((p.scale, (p.width, p.height), p.spf), (3, scaled(640, 360, 3), 1));
    // Without dynamic resolution: full resolution, one sample.
    let p = b.plan((640, 360), true, false, 100, None);
    assert_eq!((p.scale, p.spf), (1, 1));
    // Still: full resolution, never more than the samples left, or the fixed count.
    assert_eq!(b.plan((64, 36), false, true, 5, None).spf, 5);
    assert_eq!(b.plan((64, 36), false, true, 100, Some(3)).spf, 3);
}

#[test]
fn digit_keys_switch_buffers_and_brackets_change_exposure() {
    let mut v = builtin(2, Some(2));
    converge(&mut v, 10);
    let beauty = v.framebuffer().to_vec();
    v.handle(InputEvent::KeyDown(Key::Digit(2)));
    assert_eq!(v.display().buffer, Buffer::Aov(Aov::Ao));
    assert!(v.renderer().settings().aovs, "AOVs are accumulated while one is shown");
    converge(&mut v, 10);
    assert_ne!(v.framebuffer(), beauty.as_slice());
    for (digit, aov) in [(3, Aov::Direct), (4, Aov::Albedo), (5, Aov::Normal), (6, Aov::Depth)] {
        v.handle(InputEvent::KeyDown(Key::Digit(digit)));
        assert_eq!(v.display().buffer, Buffer::Aov(aov));
        v.frame(Duration::ZERO).unwrap();
    }
    v.handle(InputEvent::KeyDown(Key::Digit(1)));
    assert!(!v.renderer().settings().aovs);
    converge(&mut v, 10);
    assert_eq!(v.framebuffer(), beauty.as_slice(), "back to the same beauty image");

    v.handle(InputEvent::KeyDown(Key::BracketRight));
    v.frame(Duration::ZERO).unwrap();
    assert_eq!(v.display().exposure, 0.5);
    let brighter: u64 = v.framebuffer().iter().map(|&p| display::unpack(p)[1] as u64).sum();
    let base: u64 = beauty.iter().map(|&p| display::unpack(p)[1] as u64).sum();
    assert!(brighter > base);
    v.handle(InputEvent::KeyDown(Key::BracketLeft));
    v.frame(Duration::ZERO).unwrap();
    assert_eq!(v.framebuffer(), beauty.as_slice());
}

#[test]
fn the_overlay_is_drawn_into_the_framebuffer_and_names_fps_spp_and_systems() {
    let mut v = builtin(2, Some(2));
    converge(&mut v, 10);
    let plain = v.framebuffer().to_vec();
    v.handle(InputEvent::KeyDown(Key::H));
    assert!(v.needs_frame());
    v.frame(Duration::from_millis(16)).unwrap();
    assert_ne!(v.framebuffer(), plain.as_slice());
    let text = v.overlay_lines().join("\n");
    for word in ["fps", "spp 2/2 (done)", "res 64x36", "trace", "accumulate"] {
        assert!(text.contains(word), "{word} missing from\n{text}");
    }
    assert!(v.title().contains("built-in") && v.title().contains("2/2 spp"));
}

#[test]
fn playing_advances_scene_time_by_the_wall_clock_and_arrows_step() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets/BoxAnimated/glTF-Binary/BoxAnimated.glb");
    let scene = gltf::load(&path).unwrap();
    let mut r = Renderer::new(RenderSettings::default());
    scene.spawn(r.world_mut(), &SpawnOptions::default()).unwrap();
    let mut v = Viewer::new(r, "BoxAnimated", options(4, Some(1))).unwrap();
    assert!(v.animation_duration().is_some());
    v.frame(Duration::ZERO).unwrap();
    v.handle(InputEvent::KeyDown(Key::Space));
    assert!(v.playing() && v.needs_frame());
    let mut resets = 0;
    for _ in 0..5 {
        resets += u32::from(v.frame(Duration::from_millis(100)).unwrap().reset);
    }
    assert!((v.time() - 0.5).abs() < 1e-9, "real time: 5 frames of 100 ms are 0.5 s");
    assert!(resets >= 4, "moving boxes restart accumulation");
    assert!(v.records().iter().skip(1).all(|r| r.moving));
    v.handle(InputEvent::KeyDown(Key::Space));
    v.handle(InputEvent::KeyDown(Key::Right));
    assert!(!v.playing());
    v.frame(Duration::from_millis(100)).unwrap();
    assert!((v.time() - (0.5 + hemi::viewer::STEP_SECONDS)).abs() < 1e-9);
}

#[test]
fn p_saves_the_display_and_the_linear_image() {
    let folder = tempfile::Builder::new().prefix("hemi-viewer-").tempdir().unwrap();
    let dir = folder.path();
    let r = Renderer::with_default_scene(RenderSettings::default());
    let opts = ViewerOptions { save_stem: dir.join("shot"), ..options(1, Some(1)) };
    let mut v = Viewer::new(r, "built-in", opts).unwrap();
    v.frame(Duration::ZERO).unwrap();
    v.handle(InputEvent::KeyDown(Key::P));
    v.frame(Duration::ZERO).unwrap();
    let messages = v.take_messages();
    assert!(messages.iter().any(|m| m.contains("shot-001.png")), "{messages:?}");
    let png = image::open(dir.join("shot-001.png")).unwrap().into_rgb8();
    assert_eq!(png.dimensions(), (W, H));
    let exr = image::open(dir.join("shot-001.exr")).unwrap().into_rgb32f();
    assert_eq!(exr.dimensions(), (W, H));
}

#[test]
fn an_invalid_scene_fails_the_frame_with_one_line() {
    let mut r = Renderer::new(RenderSettings::default());
    r.world_mut().spawn(AmbientOccluder::default());
    let mut v = Viewer::new(r, "empty", options(1, None)).unwrap();
    let e = v.frame(Duration::ZERO).unwrap_err().to_string();
    assert!(e.contains("no Camera") && !e.contains('\n'), "{e}");
}
