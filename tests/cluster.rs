//! Rendering on several machines through the command line: `--skip-existing` frame arrays,
//! split-sample stills (`--sample-range`, `hemi merge`) and `hemi status`.

use std::{path::PathBuf, process::Command};

fn hemi(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_hemi")).args(args).output().expect("binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn asset(rel: &str) -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets").join(rel);
    assert!(path.is_file(), "shared test asset missing: {} (CI keeps ../shared beside the checkout)", path.display());
    path.to_str().unwrap().to_string()
}

fn s(p: &std::path::Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn skip_existing_renders_only_missing_or_broken_frames() {
    let dir = tempfile::tempdir().unwrap();
    let model = asset("BoxAnimated/glTF-Binary/BoxAnimated.glb");
    let pattern = dir.path().join("f_{:04}.png");
    let opts = ["--frames", "0..4", "--fps", "3", "--size", "24x16", "--spp", "4"];
    let run = |extra: &[&str]| {
        let mut args = vec!["render", &model, "--out", s(&pattern)];
        args.extend(opts);
        args.extend(extra);
        let (code, _, err) = hemi(&args);
        assert_eq!(code, 0, "{err}");
        err
    };
    run(&[]);
    let frame = |f: u32| dir.path().join(format!("f_{f:04}.png"));
    let reference: Vec<Vec<u8>> = (0..4).map(|f| std::fs::read(frame(f)).unwrap()).collect();
    // Frame 1 gone, frame 2 truncated, frame 3 of another size: those three are rendered again.
    std::fs::remove_file(frame(1)).unwrap();
    std::fs::write(frame(2), &reference[2][..reference[2].len() / 2]).unwrap();
    image::RgbImage::new(8, 8).save(frame(3)).unwrap();
    let mtime = |f: u32| std::fs::metadata(frame(f)).unwrap().modified().unwrap();
    let kept = mtime(0);
    let err = run(&["--skip-existing"]);
    assert!(err.contains("frame 0 exists, skipped"), "{err}");
    assert_eq!(err.matches("exists, skipped").count(), 1, "{err}");
    assert_eq!(mtime(0), kept, "a complete frame was written again");
    for f in 0..4 {
        assert!(std::fs::read(frame(f)).unwrap() == reference[f as usize], "frame {f} differs");
    }
    let err = run(&["--skip-existing"]);
    assert_eq!(err.matches("exists, skipped").count(), 4, "{err}");
    let (code, _, err) = hemi(&["render", "--skip-existing", "--out", s(&dir.path().join("x.png"))]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--skip-existing needs --frames"), "{err}");
}

#[test]
fn merged_partials_equal_the_single_render_bit_for_bit() {
    let dir = tempfile::tempdir().unwrap();
    let model = asset("BoxAnimated/glTF-Binary/BoxAnimated.glb");
    let common = ["--size", "20x14", "--spp", "24", "--time", "0.4", "--seed", "5"];
    let render = |extra: &[&str]| {
        let mut args = vec!["render", model.as_str()];
        args.extend(common);
        args.extend(extra);
        let (code, _, err) = hemi(&args);
        assert_eq!(code, 0, "{err}");
        err
    };
    // Four parts of 24 spp: frames of 6 samples by default, one per part.
    let parts: Vec<PathBuf> = (0..4).map(|k| dir.path().join(format!("part_{k}.exr"))).collect();
    for (k, part) in parts.iter().enumerate() {
        let err = render(&["--sample-range", &format!("{k}/4"), "--out", s(part)]);
        assert!(err.contains("--spf 6"), "{err}");
    }
    for ext in ["png", "exr"] {
        let single = dir.path().join(format!("single.{ext}"));
        render(&["--spf", "6", "--out", s(&single)]);
        let merged = dir.path().join(format!("merged.{ext}"));
        let mut args = vec!["merge"];
        // Any order.
        args.extend(parts.iter().rev().map(|p| s(p)));
        args.extend(["--out", s(&merged)]);
        let (code, _, err) = hemi(&args);
        assert_eq!(code, 0, "{err}");
        assert!(std::fs::read(&single).unwrap() == std::fs::read(&merged).unwrap(), "merged .{ext} differs");
    }
    // With --spf 3 each part holds two frames; the same image as a single render with --spf 3.
    let two = dir.path().join("two_{}.exr");
    for k in 0..3 {
        render(&["--spf", "3", "--sample-range", &format!("{k}/3"), "--out", &s(&two).replace("{}", &k.to_string())]);
    }
    let single = dir.path().join("single3.exr");
    render(&["--spf", "3", "--out", s(&single)]);
    let merged = dir.path().join("merged3.exr");
    let names: Vec<String> = (0..3).map(|k| s(&two).replace("{}", &k.to_string())).collect();
    let mut args = vec!["merge"];
    args.extend(names.iter().map(String::as_str));
    args.extend(["--out", s(&merged)]);
    assert_eq!(hemi(&args).0, 0);
    assert!(std::fs::read(&single).unwrap() == std::fs::read(&merged).unwrap(), "merged --spf 3 differs");
    // --skip-existing keeps a partial of the same render and range.
    let err = render(&["--sample-range", "0/4", "--out", s(&parts[0]), "--skip-existing"]);
    assert!(err.contains("partial exists, skipped"), "{err}");
}

#[test]
fn merge_refuses_missing_overlapping_and_mismatched_partials() {
    let dir = tempfile::tempdir().unwrap();
    let part = |name: &str, range: &str, extra: &[&str]| {
        let path = dir.path().join(name);
        let mut args = vec!["render", "--spp", "8", "--sample-range", range, "--out", s(&path)];
        if !extra.contains(&"--size") {
            args.extend(["--size", "12x8"]);
        }
        args.extend(extra);
        let (code, _, err) = hemi(&args);
        assert_eq!(code, 0, "{err}");
        path
    };
    let a = part("a.exr", "0/2", &[]);
    let b = part("b.exr", "1/2", &[]);
    let b_seed = part("b_seed.exr", "1/2", &["--seed", "9"]);
    let b_size = part("b_size.exr", "1/2", &["--size", "12x9"]);
    let whole = part("whole.exr", "0/1", &["--spf", "4"]);
    let out = dir.path().join("m.png");
    let merge = |parts: &[&PathBuf]| {
        let mut args = vec!["merge"];
        args.extend(parts.iter().map(|p| s(p)));
        args.extend(["--out", s(&out)]);
        let (code, _, err) = hemi(&args);
        assert_ne!(code, 0, "{err}");
        assert_eq!(err.lines().count(), 1, "{err}");
        err
    };
    let err = merge(&[&a]);
    assert!(err.contains("missing partial") && err.contains("4..8"), "{err}");
    let err = merge(&[&a, &whole]);
    assert!(err.contains("overlaps"), "{err}");
    let err = merge(&[&a, &b_seed]);
    assert!(err.contains("b_seed.exr") && err.contains("seed 9"), "{err}");
    let err = merge(&[&a, &b_size]);
    assert!(err.contains("size 12x9"), "{err}");
    let err = merge(&[&a, &dir.path().join("nothing.exr")]);
    assert!(err.contains("nothing.exr"), "{err}");
    assert!(!out.exists());
    let (code, _, err) = hemi(&["merge", s(&a), s(&b), "--out", s(&out)]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = hemi(&["render", "--spp", "4", "--sample-range", "0/8", "--out", s(&a)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("fewer than 8 parts"), "{err}");
    let (code, _, err) = hemi(&["render", "--sample-range", "0/2", "--out", s(&out)]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains(".exr"), "{err}");
}

#[test]
fn status_lists_done_partial_and_missing_frames() {
    let dir = tempfile::tempdir().unwrap();
    let pattern = dir.path().join("f_{:04}.png");
    image::RgbImage::new(8, 8).save(dir.path().join("f_0000.png")).unwrap();
    image::RgbImage::new(8, 8).save(dir.path().join("f_0001.png")).unwrap();
    std::fs::write(dir.path().join(".f_0002.png.Xy12ab.tmp"), b"").unwrap();
    let (code, out, _) = hemi(&["status", s(&pattern), "--frames", "0..4"]);
    assert_eq!(code, 1, "{out}");
    let lines: Vec<&str> = out.lines().collect();
    assert!(lines[0].trim_start().starts_with("0  done"), "{out}");
    assert!(lines[2].contains("partial") && lines[2].contains(".f_0002.png.Xy12ab.tmp"), "{out}");
    assert!(lines[3].contains("missing"), "{out}");
    assert_eq!(lines[4], "4 frames: 2 done, 1 partial, 1 missing");
    let (code, out, _) = hemi(&["status", s(&pattern), "--frames", "0..2", "--size", "8x8"]);
    assert_eq!(code, 0, "{out}");
    assert!(out.ends_with("2 frames: 2 done, 0 partial, 0 missing (complete)\n"), "{out}");
    let (code, _, err) = hemi(&["status", s(&dir.path().join("plain.png")), "--frames", "0..2"]);
    assert_eq!(code, 2, "{err}");
}
