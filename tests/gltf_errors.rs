//! Malformed glTF input is refused with one line naming the file and the element, never a
//! panic; URIs with spaces and percent-encoding load.

mod common;

use std::path::PathBuf;

use hemi::{HemiError, scene::gltf};

fn temp(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hemi-gltf");
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A one-triangle glTF: 3 positions then 3 u32 indices in one 48-byte buffer at `uri`
/// (`None`: a base64 data URI), with the index accessor's component type given.
fn triangle(positions: [f32; 9], indices: [u32; 3], index_type: u32, uri: Option<&str>) -> (String, Vec<u8>) {
    let mut data: Vec<u8> = positions.iter().flat_map(|v| v.to_le_bytes()).collect();
    data.extend(indices.iter().flat_map(|v| v.to_le_bytes()));
    let uri = uri.map_or(format!("data:application/octet-stream;base64,{}", common::base64(&data)), str::to_string);
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
        "meshes":[{{"name":"tri","primitives":[{{"attributes":{{"POSITION":0}},"indices":1}}]}}],
        "buffers":[{{"byteLength":48,"uri":"{uri}"}}],
        "bufferViews":[{{"buffer":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":12}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":{index_type},"count":3,"type":"SCALAR"}}]}}"#
    );
    (json, data)
}

const TRI: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

fn load_error(name: &str, json: &str) -> String {
    let path = temp(name);
    std::fs::write(&path, json).unwrap();
    match gltf::load(&path) {
        Ok(_) => panic!("{name} loaded"),
        Err(e @ HemiError::Load { .. }) => {
            let text = e.to_string();
            assert!(text.contains(name), "{text} does not name the file");
            assert_eq!(text.lines().count(), 1);
            text
        }
        Err(e) => panic!("unexpected error kind: {e}"),
    }
}

#[test]
fn valid_triangle_loads_from_a_data_uri() {
    let (json, _) = triangle(TRI, [0, 1, 2], 5125, None);
    let path = temp("ok.gltf");
    std::fs::write(&path, json).unwrap();
    assert_eq!(gltf::load(&path).unwrap().scene_triangle_count(), 1);
}

#[test]
fn external_buffers_with_spaces_and_percent_encoding_load() {
    let (json, data) = triangle(TRI, [0, 1, 2], 5125, Some("my%20tri%2Bdata.bin"));
    std::fs::write(temp("my tri+data.bin"), data).unwrap();
    let path = temp("spaces.gltf");
    std::fs::write(&path, json).unwrap();
    assert_eq!(gltf::load(&path).unwrap().scene_triangle_count(), 1);
}

#[test]
fn bad_accessors_indices_buffers_and_positions_are_refused() {
    let (json, _) = triangle(TRI, [0, 1, 2], 5126, None);
    let e = load_error("float-indices.gltf", &json);
    assert!(e.contains("mesh 0 ('tri') primitive 0: indices accessor 1 is SCALAR FLOAT"), "{e}");

    let (json, _) = triangle(TRI, [0, 1, 7], 5125, None);
    let e = load_error("out-of-range.gltf", &json);
    assert!(e.contains("index 7 at position 2 is out of range (3 vertices)"), "{e}");

    let (json, _) = triangle(TRI, [0, 1, 2], 5125, Some("missing.bin"));
    let e = load_error("missing-buffer.gltf", &json);
    assert!(e.contains("buffer 0: cannot read") && e.contains("missing.bin"), "{e}");

    let mut nan = TRI;
    nan[4] = f32::NAN;
    let (json, _) = triangle(nan, [0, 1, 2], 5125, None);
    let e = load_error("nan.gltf", &json);
    assert!(e.contains("vertex 1 has a non-finite position"), "{e}");

    let (json, _) = triangle(TRI, [0, 1, 2], 5125, None);
    let e = load_error(
        "wrong-position-type.gltf",
        &json.replace(r#""count":3,"type":"VEC3""#, r#""count":3,"type":"VEC2""#),
    );
    assert!(e.contains("POSITION accessor 0 is VEC2 FLOAT, expected VEC3 FLOAT"), "{e}");

    let e = load_error("truncated.gltf", &json[..json.len() / 2]);
    assert!(e.contains("not a valid glTF"), "{e}");
}
