//! Hostile input: each case the adversarial pass found is refused with one line naming the
//! file and the element, quickly and without a large allocation; time stays finite; peer
//! sample counts obey the `--spp` limit.

mod common;

use std::{
    path::{Path, PathBuf},
    time::Instant,
};

use hemi::{
    HemiError,
    cli::peer_scene::PeerScene,
    prelude::*,
    scene::gltf::{self, LoadOptions, SpawnOptions},
};
use serde_json::{Value, json};

fn dir(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hemi-hostile").join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A one-triangle glTF with an animation: buffer = 3 positions (36 bytes), 2 key times
/// (8 bytes), 2 rotation keys (32 bytes). Accessors: 0 POSITION, 1 times, 2 rotations.
fn animated_triangle(positions: [f32; 9], rotations: [[f32; 4]; 2]) -> Value {
    let mut data: Vec<u8> = positions.iter().flat_map(|v| v.to_le_bytes()).collect();
    data.extend([0.0f32, 1.0].iter().flat_map(|v| v.to_le_bytes()));
    data.extend(rotations.iter().flatten().flat_map(|v| v.to_le_bytes()));
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0, "name": "spinner"}],
        "meshes": [{"name": "Body", "primitives": [{"attributes": {"POSITION": 0}}]}],
        "buffers": [{"byteLength": data.len(), "uri": format!("data:application/octet-stream;base64,{}", common::base64(&data))}],
        "bufferViews": [
            {"buffer": 0, "byteLength": 36},
            {"buffer": 0, "byteOffset": 36, "byteLength": 8},
            {"buffer": 0, "byteOffset": 44, "byteLength": 32}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [-1, -1, -1], "max": [1, 1, 1]},
            {"bufferView": 1, "componentType": 5126, "count": 2, "type": "SCALAR", "min": [0], "max": [1]},
            {"bufferView": 2, "componentType": 5126, "count": 2, "type": "VEC4"}
        ],
        "animations": [{
            "name": "Spin",
            "samplers": [{"input": 1, "output": 2}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]
        }]
    })
}

const TRI: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
const TURN: [[f32; 4]; 2] = [[0.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.0]];

fn write(dir: &Path, name: &str, value: &Value) -> PathBuf {
    let path = dir.join(name);
    std::fs::write(&path, serde_json::to_string(value).unwrap()).unwrap();
    path
}

/// The load error of `value` written as `name`, checked to be one line naming the file.
fn load_error(name: &str, value: &Value) -> String {
    let path = write(&dir("errors"), name, value);
    let start = Instant::now();
    let e = gltf::load(&path).err().unwrap_or_else(|| panic!("{name} loaded"));
    assert!(start.elapsed().as_secs_f64() < 2.0, "{name} took {:?}", start.elapsed());
    one_line(&e, name)
}

fn one_line(e: &HemiError, name: &str) -> String {
    let text = e.to_string();
    assert!(text.contains(name), "'{text}' does not name {name}");
    assert_eq!(text.lines().count(), 1, "'{text}' is not one line");
    text
}

fn asset(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets").join(rel)
}

#[test]
fn the_fixture_loads_and_animates() {
    let path = write(&dir("ok"), "ok.gltf", &animated_triangle(TRI, TURN));
    let scene = gltf::load(&path).unwrap();
    assert_eq!(scene.scene_triangle_count(), 1);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
}

#[test]
fn sparse_accessors_without_data_cannot_ask_for_gigabytes() {
    for count in [1u64 << 31, 1 << 28, u32::MAX as u64] {
        let mut v = animated_triangle(TRI, TURN);
        v["accessors"][0] = json!({
            "componentType": 5126, "count": count, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1],
            "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5125}, "values": {"bufferView": 0}}
        });
        let e = load_error("sparse-bomb.gltf", &v);
        assert!(e.contains("accessor 0 (POSITION of mesh 0 ('Body'), primitive 0)"), "{e}");
        assert!(e.contains("without a buffer view"), "{e}");
    }
    // A sparse count above the accessor's own count.
    let mut v = animated_triangle(TRI, TURN);
    v["accessors"][0]["sparse"] =
        json!({"count": 4, "indices": {"bufferView": 1, "componentType": 5125}, "values": {"bufferView": 0}});
    let e = load_error("sparse-count.gltf", &v);
    assert!(e.contains("sparse count 4 must be between 1 and the accessor's count 3"), "{e}");
}

/// The sparse bomb through the binary, whose address space is limited to 1 GiB (the file
/// asks for 3 GiB): it must fail with its one-line error, not die of the limit.
#[cfg(target_os = "linux")]
#[test]
fn the_sparse_bomb_is_refused_within_a_small_address_space() {
    use std::os::unix::process::CommandExt;
    let mut v = animated_triangle(TRI, TURN);
    v["accessors"][0] = json!({
        "componentType": 5126, "count": 1u64 << 28, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 1],
        "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5125}, "values": {"bufferView": 0}}
    });
    let d = dir("bomb");
    let path = write(&d, "bomb.gltf", &v);
    let mut command = std::process::Command::new(env!("CARGO_BIN_EXE_hemi"));
    command.arg("render").arg(&path).arg("--out").arg(d.join("bomb.png"));
    // SAFETY: setrlimit is async-signal-safe and only changes the child's own limit.
    unsafe {
        command.pre_exec(|| {
            let limit = libc::rlimit { rlim_cur: 1 << 30, rlim_max: 1 << 30 };
            if libc::setrlimit(libc::RLIMIT_AS, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let start = Instant::now();
    let out = command.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("bomb.gltf: accessor 0 (POSITION of mesh 0 ('Body'), primitive 0)"), "{err}");
    assert!(start.elapsed().as_secs_f64() < 5.0);
}

#[test]
fn counts_and_ranges_are_checked_against_the_buffer_view() {
    let mut v = animated_triangle(TRI, TURN);
    v["accessors"][0]["count"] = json!(1u64 << 40);
    let e = load_error("count.gltf", &v);
    assert!(
        e.contains("accessor 0 (POSITION of mesh 0 ('Body'), primitive 0)") && e.contains("buffer view 0 holds 36")
    );
    let mut v = animated_triangle(TRI, TURN);
    v["bufferViews"][0]["byteOffset"] = json!(u64::MAX - 8);
    let e = load_error("view.gltf", &v);
    assert!(e.contains("buffer view 0: bytes up to") && e.contains("outside buffer 0"), "{e}");
}

#[test]
fn indices_the_gltf_crate_would_panic_on_are_refused_by_name() {
    let mut v = animated_triangle(TRI, TURN);
    v["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = json!(7);
    let e = load_error("position-index.gltf", &v);
    assert!(e.ends_with("mesh 0 ('Body') primitive 0: POSITION accessor 7 does not exist (3 are defined)"), "{e}");

    let mut v = animated_triangle(TRI, TURN);
    v["animations"][0]["channels"][0]["target"]["node"] = json!(5);
    let e = load_error("target.gltf", &v);
    assert!(e.ends_with("animation 0 ('Spin') channel 0: target node 5 does not exist (1 is defined)"), "{e}");

    for (field, value, expect) in [
        ("/nodes/0/mesh", json!(3), "node 0 ('spinner'): mesh 3 does not exist"),
        ("/nodes/0/skin", json!(0), "node 0 ('spinner'): skin 0 does not exist (0 are defined)"),
        ("/nodes/0/camera", json!(2), "node 0 ('spinner'): camera 2 does not exist"),
        ("/nodes/0/children", json!([9]), "node 0 ('spinner'): child node 9 does not exist"),
        ("/bufferViews/2/buffer", json!(4), "buffer view 2: buffer 4 does not exist"),
        ("/accessors/2/bufferView", json!(8), "accessor 2: buffer view 8 does not exist"),
        ("/meshes/0/primitives/0/material", json!(1), "primitive 0: material 1 does not exist"),
        ("/animations/0/samplers/0/output", json!(9), "sampler 0: output accessor 9 does not exist"),
        ("/scene", json!(2), "the default scene: scene 2 does not exist"),
    ] {
        let mut v = animated_triangle(TRI, TURN);
        let (parent, key) = field.rsplit_once('/').unwrap();
        let parent = if parent.is_empty() { &mut v } else { v.pointer_mut(parent).unwrap() };
        parent[key] = value;
        let e = load_error("index.gltf", &v);
        assert!(e.contains(expect), "{field}: {e}");
    }
}

#[test]
fn cameras_and_spot_lights_without_their_parameters_are_refused() {
    let mut v = animated_triangle(TRI, TURN);
    v["cameras"] = json!([{"type": "perspective", "orthographic": {"xmag": 1, "ymag": 1, "zfar": 10, "znear": 1}}]);
    let e = load_error("camera.gltf", &v);
    assert!(e.ends_with("camera 0: the parameters of its type are missing"), "{e}");
    let mut v = animated_triangle(TRI, TURN);
    v["extensionsUsed"] = json!(["KHR_lights_punctual"]);
    v["extensions"] = json!({"KHR_lights_punctual": {"lights": [{"type": "spot", "name": "lamp"}]}});
    let e = load_error("spot.gltf", &v);
    assert!(e.ends_with("KHR_lights_punctual light 0 ('lamp'): a spot light without 'spot'"), "{e}");
}

#[test]
fn a_stride_smaller_than_the_element_is_refused_by_name() {
    let mut v = animated_triangle(TRI, TURN);
    v["bufferViews"][0]["byteStride"] = json!(4);
    let e = load_error("stride.gltf", &v);
    assert!(
        e.ends_with("stride.gltf: accessor 0 (POSITION of mesh 0 ('Body'), primitive 0): byteStride 4 is smaller than its 12-byte element"),
        "{e}"
    );
}

#[test]
fn files_that_are_not_regular_are_refused() {
    let mut paths = vec![PathBuf::from("/dev/zero"), PathBuf::from("/dev/urandom"), PathBuf::from("/proc/self")];
    paths.push(dir("not-regular"));
    // A named pipe: opening it would wait for a writer for ever.
    #[cfg(target_os = "linux")]
    {
        let fifo = dir("not-regular").join("pipe.glb");
        let _ = std::fs::remove_file(&fifo);
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: mkfifo reads the NUL-terminated path it is given.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        paths.push(fifo);
    }
    for path in paths {
        let e = gltf::load(&path).unwrap_err().to_string();
        assert!(e.starts_with(path.to_str().unwrap()) && e.contains("not a regular file"), "{e}");
        let e = PeerScene::load(&path).unwrap_err().to_string();
        assert!(e.contains("not a regular file"), "{e}");
    }
}

#[test]
fn buffer_uris_stay_in_the_models_folder_unless_allowed() {
    let d = dir("uris");
    let sub = d.join("model");
    std::fs::create_dir_all(&sub).unwrap();
    // A real buffer one folder up, reachable only with the option.
    let data = std::fs::read(asset("Box/glTF/Box0.bin")).unwrap();
    std::fs::write(d.join("outside.bin"), &data).unwrap();
    let mut box_json: Value = serde_json::from_slice(&std::fs::read(asset("Box/glTF/Box.gltf")).unwrap()).unwrap();
    for (uri, expect) in [
        ("../../../../etc/passwd", "leads outside the model's folder"),
        ("/etc/passwd", "leads outside the model's folder"),
        ("/dev/zero", "leads outside the model's folder"),
        ("%2e%2e/outside.bin", "leads outside the model's folder"),
        ("file:///etc/passwd", "scheme 'file:' is not supported"),
        ("http://example.com/x.bin", "scheme 'http:' is not supported"),
    ] {
        box_json["buffers"][0]["uri"] = json!(uri);
        let path = write(&sub, "box.gltf", &box_json);
        let e = gltf::load(&path).unwrap_err().to_string();
        assert!(e.contains("buffer 0") && e.contains(expect), "{uri}: {e}");
        assert_eq!(e.lines().count(), 1);
    }
    // Opting in reaches the file one folder up, but a device is still no file.
    let allow = LoadOptions { allow_external_uris: true, ..Default::default() };
    box_json["buffers"][0]["uri"] = json!("../outside.bin");
    let path = write(&sub, "box.gltf", &box_json);
    assert!(gltf::load(&path).unwrap_err().to_string().contains("leads outside"));
    assert_eq!(gltf::load_with(&path, &allow).unwrap().scene_triangle_count(), 12);
    box_json["buffers"][0]["uri"] = json!("/dev/zero");
    let path = write(&sub, "box.gltf", &box_json);
    let e = gltf::load_with(&path, &allow).unwrap_err().to_string();
    assert!(e.contains("cannot read '/dev/zero': it is a device, pipe or socket, not a regular file"), "{e}");
    // A symbolic link in the folder that leads out of it.
    #[cfg(unix)]
    {
        let link = sub.join("link.bin");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(d.join("outside.bin"), &link).unwrap();
        box_json["buffers"][0]["uri"] = json!("link.bin");
        let path = write(&sub, "box.gltf", &box_json);
        assert!(gltf::load(&path).unwrap_err().to_string().contains("leads outside"));
        assert!(gltf::load_with(&path, &allow).is_ok());
    }
    // A subfolder stays inside.
    std::fs::create_dir_all(sub.join("bin")).unwrap();
    std::fs::write(sub.join("bin/box.bin"), &data).unwrap();
    box_json["buffers"][0]["uri"] = json!("bin/../bin/box.bin");
    let path = write(&sub, "box.gltf", &box_json);
    assert_eq!(gltf::load(&path).unwrap().scene_triangle_count(), 12);
}

#[test]
fn a_peer_mesh_that_is_a_device_is_refused() {
    let d = dir("peer-device");
    let scene = json!({
        "name": "zero", "mesh": "/dev/zero",
        "camera": {"eye": [0, 0, 3], "target": [0, 0, 0], "up": [0, 1, 0], "vfov_deg": 40},
        "width": 8, "height": 8, "ao": {"samples": 4}, "seed": 1
    });
    let path = write(&d, "zero.json", &scene);
    let peer = PeerScene::load(&path).unwrap();
    let e = peer.spawn(&mut World::new()).unwrap_err().to_string();
    assert!(e.starts_with("/dev/zero: cannot read: it is a device"), "{e}");
}

#[test]
fn peer_samples_obey_the_spp_limit_and_zero_is_an_error() {
    let d = dir("peer-spp");
    let mut scene: Value = serde_json::from_slice(
        &std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/peers/scenes/cornell.json")).unwrap(),
    )
    .unwrap();
    for samples in [0u64, u32::MAX as u64, RenderSettings::MAX_SPP as u64 + 1] {
        scene["ao"]["samples"] = json!(samples);
        let path = write(&d, "spp.json", &scene);
        let e = PeerScene::load(&path).unwrap_err().to_string();
        assert!(e.contains(&format!("ao.samples {samples} must be between 1 and 1000000")), "{e}");
        assert!(e.contains("spp.json"));
    }
    scene["ao"]["samples"] = json!(RenderSettings::MAX_SPP);
    let path = write(&d, "spp.json", &scene);
    assert_eq!(PeerScene::load(&path).unwrap().samples, RenderSettings::MAX_SPP);
}

#[test]
fn time_that_is_not_finite_is_refused_at_the_library_boundary() {
    let path = write(&dir("time"), "time.gltf", &animated_triangle(TRI, TURN));
    let scene = gltf::load(&path).unwrap();
    let mut r = Renderer::new(RenderSettings { width: 8, height: 8, ..Default::default() });
    for t in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let e = scene.spawn(r.world_mut(), &SpawnOptions { time: t, ..Default::default() }).unwrap_err();
        assert!(e.to_string().contains("is not a finite number"), "{e}");
    }
    scene.spawn(r.world_mut(), &SpawnOptions { time: 1e30, ..Default::default() }).unwrap();
    for t in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        assert!(matches!(r.set_time(t), Err(HemiError::Usage(_))));
        assert!(r.render_at(t, 1).is_err());
    }
    // Huge but finite times loop over the clip; none panics.
    for t in [f32::MAX, -f32::MAX, 1e-45, -0.0] {
        r.render_at(t, 1).unwrap();
    }
}

#[test]
fn the_cli_refuses_an_overflowing_frame_time_in_one_line() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_hemi"))
        .args(["render", "--frames", "1..2", "--fps", "1e-45", "--spp", "1", "--size", "8x8"])
        .arg(asset("BoxAnimated/glTF-Binary/BoxAnimated.glb"))
        .arg("--out")
        .arg(dir("cli").join("f{:04}.png"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("beyond what a frame time can hold"), "{err}");
}

#[test]
fn a_zero_rotation_key_is_named_as_such() {
    let v = animated_triangle(TRI, [[0.0, 0.0, 0.0, 1.0], [0.0; 4]]);
    let channel =
        "channel 0 (rotation of node 0 ('spinner')) key 1: quaternion [0, 0, 0, 0] is zero and cannot be normalised";
    let why = format!("animation 0 ('Spin'): {channel}");
    // The file loads without the clip; choosing the clip is the error.
    let path = write(&dir("errors"), "zero-key.gltf", &v);
    let scene = gltf::load(&path).unwrap();
    assert_eq!(scene.warnings, [format!("animation 0 ('Spin') cannot be played and is left out: {channel}")]);
    scene.spawn(&mut World::new(), &SpawnOptions::default()).unwrap();
    let e = scene.spawn(&mut World::new(), &SpawnOptions { animation: Some("Spin".into()), ..Default::default() });
    let e = e.unwrap_err();
    assert!(one_line(&e, "zero-key.gltf").ends_with(&why), "{e}");
}

#[test]
fn a_node_rotation_that_is_not_unit_length_is_normalised_with_a_warning() {
    let mut v = animated_triangle(TRI, TURN);
    v["nodes"][0]["rotation"] = json!([0.0, 0.0, 0.0, 2.0]);
    v["nodes"][0]["scale"] = json!([1.0, 3.0, 1.0]);
    let path = write(&dir("rotation"), "unit.gltf", &v);
    let scene = gltf::load(&path).unwrap();
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert_eq!(scene.warnings[0], "node 0 ('spinner'): rotation is not unit length (2); normalised");
    assert_eq!(scene.graph.nodes[0].rest.rotation, Quat::IDENTITY);
    v["nodes"][0]["rotation"] = json!([0.0, 0.0, 0.0, 0.0]);
    let e = load_error("zero-rotation.gltf", &v);
    assert!(e.ends_with("node 0 ('spinner'): rotation [0.0, 0.0, 0.0, 0.0] is zero and cannot be normalised"), "{e}");
}

#[test]
fn vertices_too_large_to_frame_name_the_mesh_not_the_camera() {
    let huge = [0.0, 0.0, 0.0, 3e38, 0.0, 0.0, 0.0, -3e38, 0.0];
    let path = write(&dir("huge"), "huge.gltf", &animated_triangle(huge, TURN));
    let scene = gltf::load(&path).unwrap();
    let e = scene.spawn(&mut World::new(), &SpawnOptions::default()).unwrap_err();
    let e = one_line(&e, "huge.gltf");
    assert!(!e.contains("camera eye"), "{e}");
    assert!(e.contains("mesh 0 ('Body') primitive 0 (POSITION accessor 0) at node 'spinner'"), "{e}");
    // Scaled past f32 by its node.
    let mut v = animated_triangle([0.0, 0.0, 0.0, 1e30, 0.0, 0.0, 0.0, 1.0, 0.0], TURN);
    v["nodes"][0]["scale"] = json!([1e30, 1.0, 1.0]);
    v["animations"] = json!([]);
    let path = write(&dir("huge"), "scaled.gltf", &v);
    let e = gltf::load(&path).unwrap().spawn(&mut World::new(), &SpawnOptions::default()).unwrap_err();
    let e = one_line(&e, "scaled.gltf");
    assert!(e.contains("mesh 0 ('Body') primitive 0 (POSITION accessor 0) at node 'spinner': vertex 1"), "{e}");
    assert!(e.contains("is not finite once placed"), "{e}");
}

#[test]
fn glb_headers_that_lie_about_lengths_are_refused() {
    let glb = std::fs::read(asset("Box/glTF-Binary/Box.glb")).unwrap();
    let d = dir("glb");
    for (at, value) in [(12usize, u32::MAX), (12, 0), (12, 7), (16, 0x1234_5678)] {
        let mut bytes = glb.clone();
        bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
        let path = d.join("box.glb");
        std::fs::write(&path, &bytes).unwrap();
        let e = gltf::load(&path).unwrap_err();
        one_line(&e, "box.glb");
    }
}
