//! `hemi view` in a real window under Xvfb: the screenshot of a still view is byte for byte
//! the PNG `hemi render` writes for the same camera, spp, spf and seed. Needs `xvfb-run`
//! (`.ci/run` installs it); without it the window tests print why and pass. Without a display
//! the command fails with one line.

use std::process::{Command, Output};

fn hemi(args: &[&str]) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_hemi"));
    c.args(args);
    c
}

/// A folder for one test's files, removed when dropped.
fn temp_dir() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("hemi-view-").tempdir().unwrap()
}

fn xvfb(args: &[&str]) -> Option<Output> {
    if Command::new("xvfb-run").arg("--help").output().is_err() {
        println!("skipped: xvfb-run not found (apt-get install xvfb)");
        return None;
    }
    let mut c = Command::new("xvfb-run");
    c.args(["-a", env!("CARGO_BIN_EXE_hemi"), "view"]).args(args);
    Some(c.output().unwrap())
}

fn asset(rel: &str) -> String {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets").join(rel).display().to_string()
}

/// Runs the view and the render with the same options; their PNGs must be identical.
fn same_as_render(scene: Option<&str>, name: &str, view_extra: &[&str]) {
    let dir = temp_dir();
    let (shot, reference) =
        (dir.path().join(format!("{name}-view.png")), dir.path().join(format!("{name}-render.png")));
    let common = ["--size", "320x180", "--spp", "16", "--spf", "4", "--seed", "7"];
    let mut view: Vec<&str> = scene.into_iter().chain(common).collect();
    let shot_arg = shot.display().to_string();
    view.extend(["--quit-after-frames", "8", "--screenshot", &shot_arg]);
    view.extend(view_extra);
    let Some(out) = xvfb(&view) else { return };
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut render: Vec<&str> = vec!["render"];
    render.extend(scene);
    render.extend(common);
    let out = hemi(&render).arg("--out").arg(&reference).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (a, b) = (std::fs::read(&shot).unwrap(), std::fs::read(&reference).unwrap());
    assert!(a == b, "{} and {} differ", shot.display(), reference.display());
}

#[test]
fn the_window_shows_what_hemi_render_writes() {
    same_as_render(None, "builtin", &[]);
}

#[test]
fn a_gltf_scene_with_its_camera_matches_too() {
    same_as_render(Some(&asset("Cameras/glTF/Cameras.gltf")), "cameras", &["--stats-json", "/dev/null"]);
}

#[test]
fn turntable_and_overlay_run_and_write_per_frame_stats() {
    let dir = temp_dir();
    let stats = dir.path().join("turntable.json");
    let stats_arg = stats.display().to_string();
    let args =
        ["--size", "160x90", "--turntable", "2", "--overlay", "--quit-after-frames", "6", "--stats-json", &stats_arg];
    let Some(out) = xvfb(&args) else { return };
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&stats).unwrap()).unwrap();
    let frames = json["frames"].as_array().unwrap();
    assert_eq!(frames.len(), 6);
    assert!(frames.iter().skip(1).all(|f| f["moving"] == true), "the turntable keeps the view moving");
    assert!(json["summary"]["first_frame_seconds"].as_f64().unwrap() > 0.0);
}

#[test]
fn no_display_is_one_line_suggesting_hemi_render() {
    let out = hemi(&["view", "--size", "32x18"]).env_remove("DISPLAY").env_remove("WAYLAND_DISPLAY").output().unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim().lines().count(), 1, "{err}");
    assert!(err.contains("hemi render") && err.contains("DISPLAY"), "{err}");
}

#[test]
fn scene_errors_are_the_same_as_hemi_render() {
    let dir = temp_dir();
    let missing = dir.path().join("missing.gltf").display().to_string();
    let view = hemi(&["view", &missing]).env_remove("DISPLAY").output().unwrap();
    let render =
        hemi(&["render", &missing, "--out", &dir.path().join("x.png").display().to_string()]).output().unwrap();
    assert_eq!(view.status.code(), render.status.code());
    assert_eq!(String::from_utf8_lossy(&view.stderr), String::from_utf8_lossy(&render.stderr));
}
