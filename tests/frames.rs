//! Frame sequences from the command line: `--frames all`, one frame, open ranges, and the
//! file names every placeholder gives.

use std::{path::Path, process::Command};

fn hemi(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_hemi")).args(args).output().expect("binary runs");
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into_owned())
}

const FOX: &str = "../shared/assets/Fox/glTF-Binary/Fox.glb";

/// The last key time of the file's first animation, from its accessors' `max` as stored.
fn first_clip_duration() -> f32 {
    let gltf = gltf::Gltf::open(FOX).unwrap();
    let animation = gltf.animations().next().unwrap();
    animation
        .samplers()
        .map(|s| s.input().max().unwrap().as_array().unwrap()[0].as_f64().unwrap() as f32)
        .fold(0.0, f32::max)
}

fn names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> =
        std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    names.sort();
    names
}

#[test]
fn all_frames_of_the_animation_under_each_placeholder() {
    let dir = tempfile::tempdir().unwrap();
    let base = ["render", FOX, "--size", "4x4", "--spp", "1"];
    let pattern = dir.path().join("all/f_####.png");
    let (code, err) = hemi(&[&base[..], &["--frames", "all", "--out", pattern.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    // floor(duration · 24) + 1 frames: the last shows the last key.
    let count = (first_clip_duration() as f64 * 24.0).floor() as u32 + 1;
    assert!(count > 24, "{count}");
    let expected: Vec<String> = (0..count).map(|f| format!("f_{f:04}.png")).collect();
    assert_eq!(names(&dir.path().join("all")), expected);
    let (code, err) = hemi(&["status", pattern.to_str().unwrap(), "--frames", &format!("0..{count}")]);
    assert_eq!(code, 0, "{err}");

    // One frame, zero-padded to 2 and to 7 digits; `{}` unpadded.
    for (frames, out, file) in [
        ("5", "one/g_{:02}.png", "g_05.png"),
        ("12", "wide/g_{:07}.png", "g_0000012.png"),
        ("3", "plain/{}.png", "3.png"),
    ] {
        let out = dir.path().join(out);
        let (code, err) = hemi(&[&base[..], &["--frames", frames, "--out", out.to_str().unwrap()]].concat());
        assert_eq!(code, 0, "{err}");
        assert_eq!(names(out.parent().unwrap()), [file]);
    }

    // An open range ends with the animation; a shard takes every other frame of it.
    let out = dir.path().join("open/h_###.png");
    let from = (count - 3).to_string();
    let (code, err) = hemi(
        &[&base[..], &["--frames", &format!("{from}.."), "--shard", "1/2", "--out", out.to_str().unwrap()]].concat(),
    );
    assert_eq!(code, 0, "{err}");
    assert_eq!(names(&dir.path().join("open")), [format!("h_{:03}.png", count - 2)]);
}

#[test]
fn frames_that_cannot_be_resolved_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("f_{:03}.png");
    let out = out.to_str().unwrap();
    for (args, says) in [
        (&["render", "--frames", "all", "--out", out][..], "no animation"),
        (&["render", FOX, "--frames", "900..", "--out", out], "empty"),
        (&["render", FOX, "--frames", "all", "--out", "f.png"], "placeholder"),
        (&["render", "--out", "f_##.png"], "placeholder"),
        (&["status", out, "--frames", "all"], "START..END"),
    ] {
        let (code, err) = hemi(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
        assert_eq!(err.lines().filter(|l| l.starts_with("hemi: error")).count(), 1, "{err}");
    }
}
