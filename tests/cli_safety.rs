//! What a run does to files and streams when things go wrong: a failed or killed run leaves
//! every existing output as it was and never a partial file under an output's name, a full
//! disk or a closed pipe is met with one line or a quiet exit, never a panic.

use std::{
    path::{Path, PathBuf},
    process::{Command, Stdio},
    time::{Duration, Instant},
};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_hemi"))
}

/// A fresh folder for one test.
fn folder(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("hemi-safety-{name}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

fn asset(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets").join(rel)
}

#[test]
fn a_failed_run_leaves_existing_outputs_byte_identical() {
    let dir = folder("failed");
    let out = dir.join("good.png");
    let aov = dir.join("good.ao.exr");
    std::fs::write(&out, b"a good image").unwrap();
    std::fs::write(&aov, b"a good layer").unwrap();
    let bad_scene = dir.join("bad.gltf");
    std::fs::write(&bad_scene, b"{ not json").unwrap();
    let box_file = asset("Box/glTF-Binary/Box.glb");
    for args in [
        vec![bad_scene.to_str().unwrap(), "--aov", "ao"],
        vec![box_file.to_str().unwrap(), "--camera", "nonexistent", "--aov", "ao"],
    ] {
        let status = bin().arg("render").args(&args).arg("--out").arg(&out).stderr(Stdio::null()).status().unwrap();
        assert_eq!(status.code(), Some(1), "{args:?}");
        assert_eq!(std::fs::read(&out).unwrap(), b"a good image", "{args:?}");
        assert_eq!(std::fs::read(&aov).unwrap(), b"a good layer", "{args:?}");
        assert_eq!(names(&dir), ["bad.gltf", "good.ao.exr", "good.png"], "{args:?}: a file left behind");
    }
}

/// Killed at any moment, a sequence leaves only complete frames under their names (a hidden
/// temporary file may stay beside them).
#[test]
fn a_sequence_killed_with_sigkill_leaves_only_complete_frames() {
    let dir = folder("killed");
    let pattern = dir.join("frame_{:04}.exr");
    let mut child = bin()
        .args(["render", asset("BoxAnimated/glTF-Binary/BoxAnimated.glb").to_str().unwrap()])
        .args(["--frames", "0..400", "--size", "160x120", "--spp", "4", "--threads", "1", "--out"])
        .arg(&pattern)
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let frames = |dir: &Path| names(dir).into_iter().filter(|n| n.starts_with("frame_")).count();
    let deadline = Instant::now() + Duration::from_secs(60);
    while frames(&dir) < 3 && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    let written: Vec<String> = names(&dir).into_iter().filter(|n| n.starts_with("frame_")).collect();
    assert!(written.len() >= 3 && written.len() < 400, "{} frames written", written.len());
    for name in &written {
        let img = image::open(dir.join(name)).unwrap_or_else(|e| panic!("{name} is not a complete image: {e}"));
        assert_eq!((img.width(), img.height()), (160, 120), "{name}");
    }
    for name in names(&dir) {
        assert!(name.starts_with("frame_") || (name.starts_with(".frame_") && name.ends_with(".tmp")), "{name}");
    }
}

/// Runs `hemi ARGS` under a file-size limit of `kib` KiB with SIGXFSZ ignored, as a full disk
/// behaves: writes past the limit fail.
fn render_on_a_small_disk(kib: u32, args: &[&str]) -> (Option<i32>, String) {
    let script = format!("trap '' XFSZ; ulimit -f {}; exec \"$0\" \"$@\"", kib * 2);
    let out = Command::new("bash").arg("-c").arg(script).arg(env!("CARGO_BIN_EXE_hemi")).args(args).output().unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn a_full_disk_gives_one_line_and_no_partial_file() {
    let dir = folder("full");
    let out = dir.join("big.exr");
    std::fs::write(&out, b"the previous render").unwrap();
    let (code, err) =
        render_on_a_small_disk(64, &["render", "--size", "320x240", "--spp", "1", "--out", out.to_str().unwrap()]);
    assert_eq!(code, Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(err.contains("big.exr"), "{err}");
    assert_eq!(std::fs::read(&out).unwrap(), b"the previous render");
    assert_eq!(names(&dir), ["big.exr"]);
}

#[test]
fn a_closed_or_full_standard_output_never_panics() {
    let render = ["render", "--size", "32x16", "--spp", "2", "--stats", "--out"];
    let dir = folder("streams");
    let out = dir.join("x.png");

    // The reader has gone before the first table: the run ends quietly, as if by SIGPIPE.
    let mut child = bin().args(render).arg(&out).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().unwrap();
    drop(child.stdout.take());
    let result = child.wait_with_output().unwrap();
    assert_eq!(result.status.code(), Some(141), "{}", String::from_utf8_lossy(&result.stderr));
    assert!(!String::from_utf8_lossy(&result.stderr).contains("panicked"));

    // A full disk behind standard output: one line.
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let result = bin().args(render).arg(&out).stdout(full).output().unwrap();
    let err = String::from_utf8_lossy(&result.stderr);
    assert_eq!(result.status.code(), Some(1), "{err}");
    assert!(err.contains("standard output") && !err.contains("panicked"), "{err}");

    // Standard error full: nothing to say it with, but the render still succeeds.
    let full = std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap();
    let result = bin().args(render).arg(&out).stdout(Stdio::null()).stderr(full).output().unwrap();
    assert_eq!(result.status.code(), Some(0));
}
