//! glTF materials as hemi reads them: base-colour textures (PNG in `data:` URIs) with their
//! samplers and `KHR_texture_transform`, `COLOR_0`, alpha modes; images that are missing or
//! corrupt are one warning naming them, and the factor is used.

mod common;

use std::{io::Cursor, path::Path};

use hemi::{
    glam::{Vec2, Vec4},
    material::{AlphaMode, Filter, Surface, Wrap},
    prelude::*,
    resources::Aov,
    scene::gltf::{self, GltfScene, LoadOptions, SpawnOptions},
};
use serde_json::{Value, json};

/// A PNG of `w` × `h` RGBA texels.
fn png(w: u32, h: u32, texels: &[[u8; 4]]) -> Vec<u8> {
    let img = image::RgbaImage::from_raw(w, h, texels.concat()).unwrap();
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, image::ImageFormat::Png).unwrap();
    out.into_inner()
}

fn data_uri(mime: &str, bytes: &[u8]) -> String {
    format!("data:{mime};base64,{}", common::base64(bytes))
}

/// A unit quad in the z = 0 plane, (0, 0) to (1, 1), texture coordinates equal to x and y,
/// with `colors` (4 RGBA floats) as COLOR_0 if given, material `material`, and `extra` (images,
/// textures, samplers) merged into the document.
fn quad(material: Value, colors: Option<[[f32; 4]; 4]>, extra: Value) -> Value {
    let positions = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 1.0, 0.0]];
    let uvs = [[0.0f32, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
    let mut data: Vec<u8> = positions.iter().flatten().flat_map(|v| v.to_le_bytes()).collect();
    data.extend(uvs.iter().flatten().flat_map(|v| v.to_le_bytes()));
    data.extend([0u32, 1, 2, 0, 2, 3].iter().flat_map(|v| v.to_le_bytes()));
    let mut attributes = json!({"POSITION": 0, "TEXCOORD_0": 1});
    let mut views = vec![
        json!({"buffer": 0, "byteLength": 48}),
        json!({"buffer": 0, "byteOffset": 48, "byteLength": 32}),
        json!({"buffer": 0, "byteOffset": 80, "byteLength": 24}),
    ];
    let mut accessors = vec![
        json!({"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}),
        json!({"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2"}),
        json!({"bufferView": 2, "componentType": 5125, "count": 6, "type": "SCALAR"}),
    ];
    if let Some(colors) = colors {
        views.push(json!({"buffer": 0, "byteOffset": data.len(), "byteLength": 64}));
        data.extend(colors.iter().flatten().flat_map(|v| v.to_le_bytes()));
        accessors.push(json!({"bufferView": 3, "componentType": 5126, "count": 4, "type": "VEC4"}));
        attributes["COLOR_0"] = json!(3);
    }
    let mut doc = json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": attributes, "indices": 2, "material": 0}]}],
        "materials": [material],
        "buffers": [{"byteLength": data.len(), "uri": data_uri("application/octet-stream", &data)}],
        "bufferViews": views,
        "accessors": accessors,
    });
    for (k, v) in extra.as_object().unwrap() {
        doc[k] = v.clone();
    }
    doc
}

/// A material whose base colour is texture 0, with `texture_info` fields added.
fn textured_material(texture_info: Value, alpha: Value) -> Value {
    let mut info = json!({"index": 0});
    for (k, v) in texture_info.as_object().unwrap() {
        info[k] = v.clone();
    }
    let mut m = json!({"name": "Painted", "pbrMetallicRoughness": {"baseColorTexture": info}});
    for (k, v) in alpha.as_object().unwrap() {
        m[k] = v.clone();
    }
    m
}

/// One image (a PNG of `texels`) used by texture 0 through `sampler`.
fn one_texture(w: u32, h: u32, texels: &[[u8; 4]], sampler: Value) -> Value {
    json!({
        "images": [{"name": "paint", "uri": data_uri("image/png", &png(w, h, texels))}],
        "samplers": [sampler],
        "textures": [{"source": 0, "sampler": 0}],
    })
}

fn load(name: &str, doc: &Value) -> GltfScene {
    let bytes = serde_json::to_vec(doc).unwrap();
    gltf::from_slice(&bytes, Path::new(name), &LoadOptions::default()).unwrap()
}

fn surface(scene: &GltfScene) -> &Surface {
    scene.meshes[0][0].surface.as_ref().expect("the primitive has a surface")
}

/// 2 × 2 texels: red, green / blue, white with alpha 0.
const QUADRANTS: [[u8; 4]; 4] = [[255, 0, 0, 255], [0, 255, 0, 255], [0, 0, 255, 255], [255, 255, 255, 0]];
const NEAREST_CLAMP: &str = r#"{"magFilter": 9728, "minFilter": 9728, "wrapS": 33071, "wrapT": 33071}"#;

#[test]
fn a_base_colour_texture_is_read_with_its_sampler_at_the_hits_coordinates() {
    let sampler: Value = serde_json::from_str(NEAREST_CLAMP).unwrap();
    let doc = quad(textured_material(json!({}), json!({})), None, one_texture(2, 2, &QUADRANTS, sampler));
    let scene = load("painted.gltf", &doc);
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let s = surface(&scene);
    let t = &s.base_color.as_ref().unwrap().texture;
    assert_eq!(
        (t.sampler.wrap_u, t.sampler.wrap_v, t.sampler.filter),
        (Wrap::ClampToEdge, Wrap::ClampToEdge, Filter::Nearest)
    );
    assert_eq!(s.alpha_mode, AlphaMode::Opaque);
    let mesh = &scene.meshes[0][0].mesh;
    // Triangle 0 is vertices 0, 1, 2 (uv = xy): b1 = 0.5, b2 = 0.25 lands on uv (0.75, 0.25),
    // the top-right texel, green.
    assert_eq!(s.at(mesh, 0, 0.5, 0.25), Vec4::new(0.0, 1.0, 0.0, 1.0));
    // Triangle 1 is vertices 0, 2, 3: b1 = 0.25, b2 = 0.5 lands on (0.25, 0.75), blue.
    assert_eq!(s.at(mesh, 1, 0.25, 0.5), Vec4::new(0.0, 0.0, 1.0, 1.0));
    // Repeat (the default) and linear filtering (no filter given): uv (0.5, 0) lies halfway
    // between the red and green texel centres across, and across the wrapped seam halfway
    // between the top row and the bottom one (blue, white with alpha 0): all four weigh ¼.
    let doc = quad(textured_material(json!({}), json!({})), None, one_texture(2, 2, &QUADRANTS, json!({})));
    let scene = load("painted.gltf", &doc);
    let s = surface(&scene);
    assert_eq!(s.base_color.as_ref().unwrap().texture.sampler.filter, Filter::Linear);
    let c = s.at(&scene.meshes[0][0].mesh, 0, 0.5, 0.0);
    assert!((c - Vec4::new(0.5, 0.5, 0.5, 0.75)).abs().max_element() < 1e-6, "{c}");
}

#[test]
fn khr_texture_transform_moves_a_known_coordinate_to_another_texel() {
    let sampler: Value = serde_json::from_str(NEAREST_CLAMP).unwrap();
    let transform = json!({"extensions": {"KHR_texture_transform": {"offset": [1.0, 0.75], "rotation": std::f32::consts::PI, "scale": [1.0, 1.0]}}});
    let material = textured_material(transform, json!({}));
    let mut doc = quad(material, None, one_texture(2, 2, &QUADRANTS, sampler));
    doc["extensionsUsed"] = json!(["KHR_texture_transform"]);
    doc["extensionsRequired"] = json!(["KHR_texture_transform"]);
    let scene = load("moved.gltf", &doc);
    let s = surface(&scene);
    // b1 = 0.25, b2 = 0 on triangle 0 is uv (0.25, 0) (red untransformed); rotated by π and
    // offset it is (1 − 0.25, 0.75 − 0) = (0.75, 0.75): the white texel with alpha 0.
    let c = s.at(&scene.meshes[0][0].mesh, 0, 0.25, 0.0);
    assert!((c - Vec4::new(1.0, 1.0, 1.0, 0.0)).abs().max_element() < 1e-6, "{c}");
    let t = s.base_color.as_ref().unwrap().transform;
    assert!((t.apply(Vec2::new(0.25, 0.0)) - Vec2::new(0.75, 0.75)).abs().max_element() < 1e-6);
}

#[test]
fn vertex_colours_multiply_the_base_colour_and_alpha_modes_are_read() {
    let colors = [[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 0.5], [0.0, 0.0, 1.0, 0.0], [1.0, 1.0, 1.0, 1.0]];
    let material =
        json!({"alphaMode": "MASK", "alphaCutoff": 0.4, "pbrMetallicRoughness": {"baseColorFactor": [1, 1, 1, 0.8]}});
    let scene = load("coloured.gltf", &quad(material, Some(colors), json!({})));
    let s = surface(&scene);
    assert_eq!(s.alpha_mode, AlphaMode::Mask { cutoff: 0.4 });
    let mesh = &scene.meshes[0][0].mesh;
    // b0 = 0.25, b1 = 0.25, b2 = 0.5: rgb (0.25, 0.25, 0.5), alpha 0.8 × (0.25 + 0.125).
    let c = s.at(mesh, 0, 0.25, 0.5);
    assert!((c - Vec4::new(0.25, 0.25, 0.5, 0.3)).abs().max_element() < 1e-6, "{c}");
    assert!(s.passes(mesh, 0, 0.25, 0.5, 0), "alpha 0.3 is below the cutoff 0.4");
    assert!(!s.passes(mesh, 0, 0.0, 0.0, 0), "alpha 0.8 at vertex 0 is not");
    // A plain material keeps no surface at all: such meshes render exactly as before.
    let plain = load(
        "plain.gltf",
        &quad(json!({"pbrMetallicRoughness": {"baseColorFactor": [1, 0.5, 0, 1]}}), None, json!({})),
    );
    assert!(plain.meshes[0][0].surface.is_none());
    assert_eq!(plain.meshes[0][0].material.cd, Vec3::new(1.0, 0.5, 0.0));
}

#[test]
fn a_corrupt_or_missing_image_is_one_warning_naming_it_and_the_factor_is_used() {
    let corrupt = b"\x89PNG\r\n\x1a\nthis is not a png".to_vec();
    let images = json!({
        "images": [{"name": "broken", "uri": data_uri("image/png", &corrupt)}],
        "textures": [{"source": 0}],
    });
    let material = textured_material(json!({}), json!({}));
    let scene = load("corrupt.gltf", &quad(material.clone(), None, images));
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    let w = &scene.warnings[0];
    assert!(w.contains("texture 0") && w.contains("image 0 ('broken')") && w.contains("material 0 ('Painted')"), "{w}");
    assert!(w.contains("factor"), "{w}");
    assert!(scene.meshes[0][0].surface.is_none(), "nothing varies without the texture");
    // An image file that is not there (as BoomBox ships without its images).
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hemi-materials");
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("missing.gltf");
    let images = json!({"images": [{"uri": "gone.png"}], "textures": [{"source": 0}]});
    std::fs::write(&path, serde_json::to_vec(&quad(material, None, images)).unwrap()).unwrap();
    let scene = gltf::load(&path).unwrap();
    assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
    assert!(scene.warnings[0].contains("image 0 ('gone.png')"), "{}", scene.warnings[0]);
    // Read for its geometry alone (as peer scenes are), the file's images are never opened.
    let geometry = gltf::load_with(&path, &gltf::LoadOptions { geometry_only: true, ..Default::default() }).unwrap();
    assert!(geometry.warnings.is_empty(), "{:?}", geometry.warnings);
    assert!(geometry.meshes[0][0].surface.is_none());
    assert_eq!(geometry.meshes[0][0].mesh.positions, scene.meshes[0][0].mesh.positions);
    // The shared assets without their images load with warnings.
    let boombox = gltf::load(Path::new("../shared/assets/BoomBox/glTF/BoomBox.gltf")).unwrap();
    assert!(boombox.warnings.iter().any(|w| w.contains("BoomBox_baseColor.png")), "{:?}", boombox.warnings);
}

/// The unit quad in z = 0, alpha-masked (`MASK`) by a 2 × 1 texture whose left texel is clear
/// and whose right one is opaque red.
fn half_cut_out_quad() -> GltfScene {
    let sampler: Value = serde_json::from_str(NEAREST_CLAMP).unwrap();
    let halves = [[255, 255, 255, 0], [255, 0, 0, 255]];
    let material = textured_material(json!({}), json!({"alphaMode": "MASK"}));
    load("cutout.gltf", &quad(material, None, one_texture(2, 1, &halves, sampler)))
}

/// The whole path: a glTF quad whose texture cuts out its left half, spawned over a floor;
/// the albedo AOV shows the floor through the cut-out half and the texture elsewhere.
#[test]
fn a_loaded_alpha_mask_lets_camera_rays_through_to_the_floor() {
    let scene = half_cut_out_quad();
    let mut s = common::settings(16, 16, 1, SamplerKind::CorrelatedMultiJittered);
    (s.aovs, s.jitter) = (true, false);
    let mut r = Renderer::new(s);
    let world = r.world_mut();
    let floor = Vec3::new(0.0, 0.3, 0.0);
    world.spawn((Plane { normal: Vec3::Z }, Transform::from_xyz(0.0, 0.0, -1.0), Matte::new(floor)));
    scene.spawn(world, &SpawnOptions::default()).unwrap();
    // The file has no camera: the one framing it is replaced by one looking at it head on.
    for mut camera in world.query::<&mut Camera>().iter_mut(world) {
        *camera =
            Camera { eye: Vec3::new(0.5, 0.5, 3.0), target: Vec3::new(0.5, 0.5, 0.0), up: Vec3::Y, vfov_degrees: 15.0 };
    }
    r.run_frame().unwrap();
    let albedo = r.image().aov(Aov::Albedo).unwrap();
    for row in albedo.chunks(16) {
        assert!(row[..8].iter().all(|&a| a == floor), "{row:?}");
        assert!(row[8..].iter().all(|&a| a == Vec3::X), "{row:?}");
    }
}

/// The viewer frames what it can see: a scene whose only bounded mesh is alpha-tested has that
/// mesh's bounds (the plane beside it is unbounded and left out).
#[cfg(feature = "view")]
#[test]
fn the_viewers_scene_bounds_include_alpha_tested_meshes() {
    let scene = half_cut_out_quad();
    let mut r = Renderer::new(common::settings(8, 8, 1, SamplerKind::CorrelatedMultiJittered));
    let world = r.world_mut();
    world.spawn((Plane { normal: Vec3::Z }, Transform::from_xyz(0.0, 0.0, -1.0), Matte::new(Vec3::ONE)));
    scene.spawn(world, &SpawnOptions::default()).unwrap();
    r.run_frame().unwrap();
    let geometry = r.world().resource::<hemi::geometry::accel::SceneGeometry>();
    assert!(geometry.has_alpha() && geometry.instances().is_empty(), "the quad is the alpha layer's alone");
    let (lo, hi) = hemi::viewer::controller::scene_bounds(geometry).expect("the quad's bounds");
    assert!(lo.abs_diff_eq(Vec3::ZERO, 1e-5) && hi.abs_diff_eq(Vec3::new(1.0, 1.0, 0.0), 1e-5), "{lo} {hi}");
}

/// A PNG header (signature, IHDR, IDAT, IEND) claiming `w` × `h` RGBA pixels, with no pixel data.
fn png_header(w: u32, h: u32) -> Vec<u8> {
    fn crc32(bytes: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in bytes {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 { 0xedb8_8320 ^ (c >> 1) } else { c >> 1 };
            }
        }
        !c
    }
    let chunk = |kind: &[u8], data: &[u8]| {
        let mut out = (data.len() as u32).to_be_bytes().to_vec();
        let body = [kind, data].concat();
        out.extend(&body);
        out.extend(crc32(&body).to_be_bytes());
        out
    };
    let ihdr = [&w.to_be_bytes()[..], &h.to_be_bytes(), &[8, 6, 0, 0, 0]].concat();
    // The first IDAT chunk ends the header (an empty zlib stream; nothing gets that far).
    let idat = chunk(b"IDAT", &[0x78, 0x9c, 0x03, 0x00, 0x00, 0x00, 0x00, 0x01]);
    [&b"\x89PNG\r\n\x1a\n"[..], &chunk(b"IHDR", &ihdr), &idat, &chunk(b"IEND", &[])].concat()
}

/// A small file cannot make the loader allocate an image it claims to be huge: the header's
/// size is checked against a per-side limit and the file's read budget before decoding.
#[test]
fn an_image_claiming_a_huge_size_is_refused_before_any_allocation() {
    for (w, h, why) in [(20_000, 20_000, "more than the limit"), (16_000, 16_000, "would exceed")] {
        let images = json!({
            "images": [{"name": "huge", "uri": data_uri("image/png", &png_header(w, h))}],
            "textures": [{"source": 0}],
        });
        let scene = load("huge.gltf", &quad(textured_material(json!({}), json!({})), None, images));
        assert_eq!(scene.warnings.len(), 1, "{:?}", scene.warnings);
        assert!(
            scene.warnings[0].contains("image 0 ('huge')") && scene.warnings[0].contains(why),
            "{}",
            scene.warnings[0]
        );
    }
}
