//! The `hemi` binary: renders to PNG/EXR, refuses bad arguments with one line and a non-zero
//! exit, never panics.

use std::process::Command;

fn hemi(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_hemi")).args(args).output().expect("binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn temp(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hemi-cli");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn renders_png_and_exr() {
    let png = temp("frame.png");
    let (code, _, err) = hemi(&["render", "--out", png.to_str().unwrap(), "--size", "32x18", "--spp", "4"]);
    assert_eq!(code, 0, "{err}");
    let img = image::open(&png).unwrap().into_rgb8();
    assert_eq!(img.dimensions(), (32, 18));

    let exr = temp("frame.exr");
    let (code, _, err) =
        hemi(&["render", "--out", exr.to_str().unwrap(), "--size", "32x18", "--spp", "2", "--seed", "3"]);
    assert_eq!(code, 0, "{err}");
    let img = image::open(&exr).unwrap().into_rgb32f();
    assert_eq!(img.dimensions(), (32, 18));
    assert!(img.pixels().all(|p| p.0.iter().all(|v| v.is_finite() && *v >= 0.0)));
}

#[test]
fn stats_prints_a_table_per_frame() {
    let png = temp("stats.png");
    let (code, out, err) =
        hemi(&["render", "--out", png.to_str().unwrap(), "--size", "16x16", "--spp", "4", "--spf", "2", "--stats"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(out.lines().filter(|l| l.starts_with("frame ")).count(), 2, "{out}");
    for system in ["scene_changes", "bvh", "trace", "accumulate", "resolve", "of which     AO"] {
        assert!(out.contains(system), "missing {system} in {out}");
    }
    assert!(err.contains("Mrays/s"));
    // Without --spf the whole --spp is one frame (one camera ray per pixel, one sample set).
    let (code, out, err) = hemi(&["render", "--out", png.to_str().unwrap(), "--size", "8x8", "--spp", "80", "--stats"]);
    assert_eq!(code, 0, "{err}");
    let frames: Vec<&str> = out.lines().filter(|l| l.starts_with("frame ")).collect();
    assert_eq!(frames.len(), 1, "{out}");
    assert!(frames[0].contains("spp    80 (+80)"), "{out}");
}

#[test]
fn stats_json_holds_the_ao_rate_of_the_trace_the_ao_kernel_and_its_queries() {
    let (png, json) = (temp("stats_json.png"), temp("stats.json"));
    let args = ["render", "--out", png.to_str().unwrap(), "--size", "32x32", "--spp", "4", "--stats-json"];
    let (code, _, err) = hemi(&[&args[..], &[json.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    let doc: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let total = &doc["total"];
    let (trace, kernel) = (total["ao_mrays_per_s"].as_f64().unwrap(), total["ao_kernel_mrays_per_s"].as_f64().unwrap());
    // The AO kernel is part of the trace system's time, so its rate is the higher one.
    assert!(trace > 0.0 && kernel > trace, "trace {trace}, kernel {kernel}");
    let ao_seconds = total["ao_seconds"].as_f64().unwrap();
    assert!(ao_seconds > 0.0 && ao_seconds < total["trace_seconds"].as_f64().unwrap());
    // The AO rays' scene queries are part of the AO kernel's time.
    let (query_seconds, query) =
        (total["ao_query_seconds"].as_f64().unwrap(), total["ao_query_mrays_per_s"].as_f64().unwrap());
    assert!(query_seconds > 0.0 && query_seconds < ao_seconds, "queries {query_seconds} s of {ao_seconds} s");
    assert!(query > kernel, "queries {query}, kernel {kernel}");
    let frame = &doc["frames"][0];
    let split = &frame["trace_split"];
    let (ao_ms, queries_ms) = (split["ao_ms"].as_f64().unwrap(), split["ao_queries_ms"].as_f64().unwrap());
    assert!(ao_ms > 0.0 && queries_ms > 0.0 && queries_ms < ao_ms, "{frame}");
    assert!(frame["ao_query_mrays_per_s"].as_f64().unwrap() > frame["ao_kernel_mrays_per_s"].as_f64().unwrap());
    // The frame built the BVH: its largest tree's SAH cost, whose root alone counts 1.
    let blas = &frame["bvh"]["largest_blas"];
    let (inner, leaves) = (blas["sah_inner"].as_f64().unwrap(), blas["sah_leaves"].as_f64().unwrap());
    assert!(inner >= 1.0 && leaves > 0.0 && blas["prims"].as_u64().unwrap() > 0, "{blas}");
    assert_eq!(blas["sah"].as_f64().unwrap(), inner + leaves);
}

/// The AVX2 copies (eight-lane packets, the AVX2 loops of CMJ and the cosine directions) and
/// the AVX-512 ones (sixteen-lane packets) give the same image bit for bit, with the
/// occluder's one-pass cosine runs at the shared camera hits of the peer Cornell box in both;
/// `HEMI_NO_AVX512=1` picks the former.
#[test]
fn cpus_with_and_without_avx512_render_the_same_image() {
    let cornell = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/peers/scenes/cornell.json");
    for scene in [None, Some(cornell)] {
        let render = |no_avx512: &str, out: &std::path::Path| {
            let mut args = vec!["render", "--size", "64x36", "--spp", "8", "--stats", "--out", out.to_str().unwrap()];
            args.extend(scene);
            let out =
                Command::new(env!("CARGO_BIN_EXE_hemi")).args(args).env("HEMI_NO_AVX512", no_avx512).output().unwrap();
            assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
            String::from_utf8_lossy(&out.stderr).into_owned()
        };
        let (wide, narrow) = (temp("avx512.exr"), temp("avx2.exr"));
        let (wide_stats, narrow_stats) = (render("0", &wide), render("1", &narrow));
        assert_eq!(std::fs::read(&wide).unwrap(), std::fs::read(&narrow).unwrap(), "{scene:?}");
        if wide_stats.contains("16-ray packets") {
            assert!(narrow_stats.contains("8-ray packets"), "{narrow_stats}");
        } else {
            eprintln!("no AVX-512 on this CPU: both runs took the same copies");
        }
    }
}

#[test]
fn error_study_writes_csv_and_plot() {
    let (csv, png) = (temp("err.csv"), temp("err.png"));
    let args = [
        "error",
        "wall",
        "--max-spp",
        "8",
        "--samplers",
        "random,zsobol",
        "--csv",
        csv.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ];
    let (code, out, err) = hemi(&args);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let rows: Vec<&str> = text.lines().collect();
    assert_eq!(rows[0], "sampler,spp,seconds,rays,rmse,relative_rmse");
    assert_eq!(rows.len(), 1 + 2 * 4, "2 samplers × spp 1, 2, 4, 8");
    assert!(rows[1].starts_with("random,1,"));
    assert!(out.contains("slope(spp)") && out.contains("zsobol"));
    assert_eq!(image::open(&png).unwrap().into_rgb8().dimensions(), (1400, 560));
    let (code, _, err) = hemi(&["error", "default"]);
    assert_eq!(code, 2);
    assert!(err.contains("--reference"), "{err}");
}

#[test]
fn peer_scene_with_aovs_writes_one_exr_per_aov() {
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/peers/scenes/cornell.json");
    let out = temp("cornell.exr");
    let aovs = ["--aov", "ao,direct,albedo,normal,depth", "--aov-files"];
    let args = [&["render", scene, "--spp", "2", "--size", "32x32"][..], &aovs, &["--out"]].concat();
    let (code, _, err) = hemi(&[&args[..], &[out.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    for name in ["ao", "direct", "albedo", "normal", "depth"] {
        let img = image::open(temp(&format!("cornell.{name}.exr"))).unwrap().into_rgb32f();
        assert_eq!(img.dimensions(), (32, 32), "{name}");
        assert!(img.pixels().all(|p| p.0.iter().all(|v| v.is_finite())), "{name}");
    }
    // Normals are unit length wherever the camera sees the box (everywhere here).
    let normals = image::open(temp("cornell.normal.exr")).unwrap().into_rgb32f();
    for p in normals.pixels() {
        let len = (p.0[0] * p.0[0] + p.0[1] * p.0[1] + p.0[2] * p.0[2]).sqrt();
        assert!((len - 1.0).abs() < 1e-3, "normal length {len}");
    }
    let ao = image::open(temp("cornell.ao.exr")).unwrap().into_rgb32f();
    assert!(ao.pixels().all(|p| (0.0..=1.0).contains(&p.0[0])));
}

/// Usage errors exit with 2: hemi's own checks in one line, clap's with its usage line and
/// hint; a file that cannot be written exits with 1, in one line naming it.
#[test]
fn bad_arguments_name_the_problem_and_exit_with_the_documented_status() {
    // Under a file, so not even root can create the folder.
    let unwritable = "/dev/null/x.png";
    let hemis_own: [(&[&str], &str, i32); 10] = [
        (&["render", "--out", "picture.bmp"], ".png or .exr", 2),
        (&["render", "--out", "g_{:04}.png"], "placeholder", 2),
        (&["render", "--out", "g_{:04}.png", "--frames", "0..4", "--shard", "7/10"], "gets no frame", 2),
        (&["render", "--out", "g_{:04}.png", "--frames", "1..2", "--fps", "1e-45"], "beyond what a frame time", 2),
        (
            &["render", "--out", "same.exr", "--stats-json", "same.exr"],
            "--stats-json same.exr is also the file of --out",
            2,
        ),
        (
            &["render", "--out", "x.png", "--aov", "ao", "--aov-files", "--stats-json", "x.ao.exr"],
            "is also the file of --aov ao",
            2,
        ),
        (&["render", "scene.gltf", "--out", "scene.gltf"], "would overwrite the input", 2),
        (&["render", "--shard", "0/2"], "--shard needs --frames", 2),
        (&["render", "--out", unwritable], "/dev/null/x.png", 1),
        (&["error", "wall", "--csv", "e.png", "--plot", "e.png"], "also the file of --csv", 2),
    ];
    for (args, needle, status) in hemis_own {
        let (code, _, err) = hemi(args);
        assert_eq!(code, status, "{args:?}: {err}");
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: not one line: {err}");
        assert!(err.contains(needle), "{args:?}: '{needle}' not in {err}");
    }
    let claps: [(&[&str], &str); 8] = [
        (&["render", "--size", "0x0"], "empty"),
        (&["render", "--size", "4294967296x1"], "width 4294967296 is too large"),
        (&["render", "--aov", "shadows"], "unknown AOV 'shadows'"),
        (&["render", "--bogus"], "--bogus"),
        (&["render", "--size", "12"], "WIDTHxHEIGHT"),
        (&["render", "--spp", "many"], "--spp"),
        (&["render", "--spp", "0"], "--spp"),
        (&["render", "--sampler", "sobolish"], "sobolish"),
    ];
    for (args, needle) in claps {
        let (code, _, err) = hemi(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        let first = err.lines().next().unwrap_or_default();
        assert!(first.starts_with("hemi: error: ") && first.contains(needle), "{args:?}: '{needle}' not in {err}");
        assert!(err.contains("try '--help'"), "{args:?}: no hint: {err}");
    }
    let (_, _, err) = hemi(&["render", "--bogus"]);
    assert!(err.contains("Usage: hemi render"), "no usage line: {err}");
}

/// Without the arguments it needs, a command prints its help and exits with 2.
#[test]
fn bare_commands_print_their_usage() {
    for (args, usage) in
        [(&[][..], "Usage: hemi <COMMAND>"), (&["compare"], "Usage: hemi compare"), (&["error"], "Usage: hemi error")]
    {
        let (code, out, err) = hemi(args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(out.is_empty() && err.contains(usage) && err.contains("Options:"), "{args:?}: {err}");
    }
}

fn asset(rel: &str) -> String {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets").join(rel);
    assert!(path.is_file(), "shared test asset missing: {} (CI keeps ../shared beside the checkout)", path.display());
    path.to_str().unwrap().to_string()
}

#[test]
fn renders_a_gltf_file_with_default_ambient_occlusion() {
    let png = temp("fox.png");
    let fox = asset("Fox/glTF-Binary/Fox.glb");
    let (code, _, err) = hemi(&["render", &fox, "--out", png.to_str().unwrap(), "--size", "40x30", "--spp", "2"]);
    assert_eq!(code, 0, "{err}");
    let img = image::open(&png).unwrap().into_rgb8();
    assert!(img.pixels().any(|p| p.0[0] > 100), "the fox is visible");
    let cams = asset("Cameras/glTF/Cameras.gltf");
    for camera in ["0", "1"] {
        let (code, _, err) =
            hemi(&["render", &cams, "--camera", camera, "--out", png.to_str().unwrap(), "--size", "8x8"]);
        assert_eq!(code, 0, "camera {camera}: {err}");
    }
    let (code, _, err) = hemi(&["render", &cams, "--camera", "nope", "--out", png.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(err.contains("no camera 'nope'") && err.contains("Cameras.gltf"), "{err}");
}

#[test]
fn shards_write_the_same_frames_as_one_run() {
    let model = asset("BoxAnimated/glTF-Binary/BoxAnimated.glb");
    let run = |dir: &str, shard: Option<&str>| {
        let out = temp(dir).join("f_{:04}.exr");
        let mut args = vec!["render", &model, "--frames", "0..5", "--fps", "3", "--size", "24x16", "--spp", "4"];
        let out = out.to_str().unwrap().to_string();
        args.extend(["--out", &out]);
        if let Some(s) = shard {
            args.extend(["--shard", s]);
        }
        let (code, _, err) = hemi(&args);
        assert_eq!(code, 0, "{err}");
    };
    run("seq-all", None);
    run("seq-shards", Some("0/2"));
    run("seq-shards", Some("1/2"));
    let mut differ = 0;
    for f in 0..5 {
        let name = format!("f_{f:04}.exr");
        let a = std::fs::read(temp("seq-all").join(&name)).unwrap();
        let b = std::fs::read(temp("seq-shards").join(&name)).unwrap();
        assert!(a == b, "frame {f} differs between the sharded and the single run");
        if f > 0 && a != std::fs::read(temp("seq-all").join("f_0000.exr")).unwrap() {
            differ += 1;
        }
    }
    assert!(differ > 0, "the animation moves");
    let (code, _, err) = hemi(&["render", &model, "--frames", "0..2", "--out", "x.png"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("placeholder"), "{err}");
}

#[test]
fn malformed_gltf_gives_one_line_naming_the_file() {
    let glb = std::fs::read(asset("Box/glTF-Binary/Box.glb")).unwrap();
    let truncated = temp("truncated.glb");
    std::fs::write(&truncated, &glb[..glb.len() / 2]).unwrap();
    let (code, _, err) = hemi(&["render", truncated.to_str().unwrap(), "--out", temp("t.png").to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "not one line: {err}");
    assert!(err.contains("truncated.glb"), "{err}");
}
