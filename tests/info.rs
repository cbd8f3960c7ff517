//! `hemi info`: what a glTF file holds, checked against the files themselves (read here with
//! the gltf crate), and the loader's own refusal of a malformed file.

use std::process::Command;

use serde_json::Value;

fn hemi(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_hemi")).args(args).output().expect("binary runs");
    let text = |b: &[u8]| String::from_utf8_lossy(b).into_owned();
    (out.status.code().unwrap_or(-1), text(&out.stdout), text(&out.stderr))
}

fn info(path: &str) -> Value {
    let (code, out, err) = hemi(&["info", path, "--json"]);
    assert_eq!(code, 0, "{err}");
    serde_json::from_str(&out).unwrap()
}

const ASSETS: &str = "../shared/assets";

#[test]
fn fox_has_three_clips_with_their_durations_and_one_skin() {
    let path = format!("{ASSETS}/Fox/glTF-Binary/Fox.glb");
    let summary = info(&path);
    let gltf = gltf::Gltf::open(&path).unwrap();
    let expected: Vec<(String, f64)> = gltf
        .animations()
        .map(|a| {
            let end = a.samplers().map(|s| s.input().max().unwrap()[0].as_f64().unwrap()).fold(0.0, f64::max);
            (a.name().unwrap().to_string(), end)
        })
        .collect();
    let clips = summary["animations"].as_array().unwrap();
    assert_eq!(clips.len(), 3);
    for (clip, (name, end)) in clips.iter().zip(&expected) {
        assert_eq!(clip["name"], name.as_str());
        assert!((clip["duration"].as_f64().unwrap() - end).abs() < 1e-6, "{clip}");
        // Every channel targets a node of the scene, named.
        assert!(!clip["nodes"].as_array().unwrap().is_empty());
    }
    assert_eq!(summary["skins"], 1);
    // Indexed or not, three vertices a triangle.
    let vertices = |p: gltf::Primitive| {
        p.indices().map_or_else(|| p.get(&gltf::Semantic::Positions).unwrap().count(), |i| i.count())
    };
    let triangles: usize = gltf.meshes().flat_map(|m| m.primitives()).map(|p| vertices(p) / 3).sum();
    assert_eq!(summary["triangles"], triangles);
    assert_eq!(summary["materials"][0]["textures"][0], "base_color");
    // Its texture decodes: nothing to warn about.
    assert_eq!(summary["warnings"].as_array().unwrap().len(), 0, "{summary}");
}

/// The loader's warnings are listed: BoomBox ships without its images.
#[test]
fn warnings_are_the_loaders() {
    let summary = info(&format!("{ASSETS}/BoomBox/glTF/BoomBox.gltf"));
    let warnings = summary["warnings"].as_array().unwrap();
    assert!(warnings.iter().any(|w| w.as_str().unwrap().contains("BoomBox_baseColor.png")), "{summary}");
}

#[test]
fn cameras_and_lights_are_listed_as_the_file_defines_them() {
    let cameras = info(&format!("{ASSETS}/Cameras/glTF/Cameras.gltf"));
    let list = cameras["cameras"].as_array().unwrap();
    assert_eq!(list.len(), 2);
    let gltf = gltf::Gltf::open(format!("{ASSETS}/Cameras/glTF/Cameras.gltf")).unwrap();
    for (c, camera) in list.iter().zip(gltf.cameras()) {
        match camera.projection() {
            gltf::camera::Projection::Perspective(p) => {
                assert_eq!(c["type"], "perspective");
                assert!((c["yfov_degrees"].as_f64().unwrap() - p.yfov().to_degrees() as f64).abs() < 1e-4);
            }
            gltf::camera::Projection::Orthographic(o) => {
                assert_eq!(c["type"], "orthographic");
                assert_eq!(c["ymag"].as_f64().unwrap(), o.ymag() as f64);
            }
        }
    }
    let lamp = info(&format!("{ASSETS}/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf"));
    let lights = lamp["lights"].as_array().unwrap();
    assert_eq!(lights.len(), 5);
    assert!(lights.iter().all(|l| l["type"] == "point"));
    let intensities: f64 = lights.iter().map(|l| l["intensity"].as_f64().unwrap()).sum();
    assert_eq!(intensities, 15.0 + 1.5 + 80.0 + 80.0 + 180.0);
    // The human form has a line per light.
    let (code, out, _) = hemi(&["info", &format!("{ASSETS}/LightsPunctualLamp/glTF/LightsPunctualLamp.gltf")]);
    assert_eq!(code, 0);
    assert_eq!(out.lines().filter(|l| l.trim_start().starts_with("point at node")).count(), 5, "{out}");
}

#[test]
fn a_malformed_file_gets_the_loaders_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.gltf");
    std::fs::write(&path, r#"{"asset":{"version":"2.0"},"nodes":[{"mesh":5}]}"#).unwrap();
    let (code, out, err) = hemi(&["info", path.to_str().unwrap()]);
    assert_eq!(code, 1, "{err}");
    assert!(out.is_empty());
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("bad.gltf") && err.contains("mesh 5"), "{err}");
    // The same line `hemi render` gives.
    let (_, _, render_err) =
        hemi(&["render", path.to_str().unwrap(), "--out", dir.path().join("x.png").to_str().unwrap()]);
    assert_eq!(render_err.lines().last(), err.lines().last());
}
