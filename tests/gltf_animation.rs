//! glTF animation as exporters write it: CUBICSPLINE keys against hand-computed Hermite values
//! (Blender's zero tangents included), several clips playing together, clips that cannot be
//! played, morph targets, and a camera-less file framed over the frames it renders.

mod common;

use std::path::{Path, PathBuf};

use glam::{Quat, Vec3};
use hemi::{
    animation::NodeGraph,
    prelude::*,
    scene::gltf::{self, SpawnOptions},
};
use serde_json::{Value, json};

fn dir(name: &str) -> PathBuf {
    let d = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!("hemi-anim-{name}"));
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// Float accessors in one buffer, each in a view of its own.
#[derive(Default)]
struct Data {
    bytes: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Data {
    /// Adds `values` as an accessor of `kind` (SCALAR, VEC3, VEC4) and returns its index.
    fn add(&mut self, kind: &str, values: &[f32]) -> usize {
        let size = match kind {
            "SCALAR" => 1,
            "VEC3" => 3,
            _ => 4,
        };
        let offset = self.bytes.len();
        self.bytes.extend(values.iter().flat_map(|v| v.to_le_bytes()));
        self.views.push(json!({"buffer": 0, "byteOffset": offset, "byteLength": values.len() * 4}));
        let mut accessor = json!({"bufferView": self.views.len() - 1, "componentType": 5126,
                                  "count": values.len() / size, "type": kind});
        if kind == "VEC3" {
            let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
            for v in values.chunks(3) {
                for k in 0..3 {
                    lo[k] = lo[k].min(v[k]);
                    hi[k] = hi[k].max(v[k]);
                }
            }
            accessor["min"] = json!(lo);
            accessor["max"] = json!(hi);
        }
        self.accessors.push(accessor);
        self.accessors.len() - 1
    }

    /// A glTF document of these buffers and the given nodes, meshes and extra fields.
    fn gltf(self, nodes: Value, meshes: Value, extra: Value) -> Value {
        let uri = format!("data:application/octet-stream;base64,{}", common::base64(&self.bytes));
        let roots: Vec<usize> = (0..nodes.as_array().unwrap().len()).collect();
        let mut v = json!({
            "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": roots}],
            "nodes": nodes, "meshes": meshes,
            "buffers": [{"byteLength": self.bytes.len(), "uri": uri}],
            "bufferViews": self.views, "accessors": self.accessors,
        });
        for (k, x) in extra.as_object().unwrap() {
            v[k] = x.clone();
        }
        v
    }
}

const TRIANGLE: [f32; 9] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];

fn write(name: &str, v: &Value) -> PathBuf {
    let path = dir("files").join(name);
    std::fs::write(&path, serde_json::to_string(v).unwrap()).unwrap();
    path
}

fn load(name: &str, v: &Value) -> gltf::GltfScene {
    gltf::load(&write(name, v)).unwrap()
}

/// A renderer holding `scene` spawned with `animation`, posed at `t`.
fn posed(scene: &gltf::GltfScene, animation: Option<&str>, t: f32) -> Renderer {
    let mut r = Renderer::new(common::settings(8, 8, 1, SamplerKind::Jittered));
    let options = SpawnOptions { animation: animation.map(str::to_string), ..Default::default() };
    scene.spawn(r.world_mut(), &options).unwrap();
    r.set_time(t).unwrap();
    r.run_frame().unwrap();
    r
}

fn translation(r: &Renderer, node: usize) -> Vec3 {
    r.world().resource::<NodeGraph>().world[node].translation.into()
}

fn mesh_positions(r: &mut Renderer) -> Vec<Vec3> {
    let w = r.world_mut();
    w.query::<&TriangleMesh>().single(w).unwrap().0.positions.clone()
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).length() < 1e-5
}

/// Whether two unit quaternions are the same rotation, to within `1e-5` per component.
fn same_rotation(a: Quat, b: Quat) -> bool {
    let (a, b) = (glam::Vec4::from(a), glam::Vec4::from(b));
    (a - b).length().min((a + b).length()) < 1e-5
}

// Cubic Hermite basis at s = 1/4 (t = 0.5 between keys at 0 and 2, so every tangent is
// scaled by the interval, 2): h00 = 2s³ − 3s² + 1, h10 = s³ − 2s² + s, h01 = −2s³ + 3s²,
// h11 = s³ − s².
const H00: f32 = 0.84375;
const H10: f32 = 0.140625;
const H01: f32 = 0.15625;
const H11: f32 = -0.046875;

/// One triangle with two morph targets (+Z and +Y on every vertex) under a node animated by
/// CUBICSPLINE translation, rotation, scale and weights over keys at 0 and 2 s.
fn cubic_file() -> Value {
    let mut d = Data::default();
    let pos = d.add("VEC3", &TRIANGLE);
    let up_z = d.add("VEC3", &[0.0, 0.0, 1.0].repeat(3));
    let up_y = d.add("VEC3", &[0.0, 1.0, 0.0].repeat(3));
    let times = d.add("SCALAR", &[0.0, 2.0]);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    // Per key: in-tangent, value, out-tangent.
    let translation = d.add("VEC3", &[0., 0., 0., 0., 0., 0., 1., 0., 0., 0., 2., 0., 4., 0., 0., 9., 9., 9.]);
    let rotation =
        d.add("VEC4", &[0., 0., 0., 0., 0., 0., 0., 1., 0., 0.5, 0., 0., 0., 0., 0., 0., 0., s, 0., s, 0., 0., 0., 0.]);
    let scale = d.add("VEC3", &[0., 0., 0., 1., 1., 1., 0., 0., 0., 0., 0., 0., 3., 1., 1., 0., 0., 0.]);
    // Two targets per entry: in-tangents, values, out-tangents of each key.
    let weights = d.add("SCALAR", &[0., 0., 0., 1., 0.5, 0., 0., 0., 1., 0., 0., 0.]);
    let sampler = |output| json!({"input": times, "output": output, "interpolation": "CUBICSPLINE"});
    let channel = |k: usize, path: &str| json!({"sampler": k, "target": {"node": 0, "path": path}});
    d.gltf(
        json!([{"name": "morphing", "mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}, "targets": [{"POSITION": up_z}, {"POSITION": up_y}]}]}]),
        json!({"animations": [{
            "name": "Spline",
            "samplers": [sampler(translation), sampler(rotation), sampler(scale), sampler(weights)],
            "channels": [channel(0, "translation"), channel(1, "rotation"), channel(2, "scale"), channel(3, "weights")]
        }]}),
    )
}

#[test]
fn cubic_splines_follow_hand_computed_hermite_values() {
    let scene = load("cubic.gltf", &cubic_file());
    let graph = &scene.graph;
    let mut locals: Vec<Transform> = graph.nodes.iter().map(|n| n.rest).collect();
    graph.clips[0].apply(0.5, &mut locals);
    // Translation: v0 = 0, b0 = (1,0,0), v1 = (4,0,0), a1 = (0,2,0).
    let expected = Vec3::new(H10 * 2.0 + H01 * 4.0, H11 * 2.0 * 2.0, 0.0);
    assert!(close(expected, Vec3::new(0.90625, -0.1875, 0.0)));
    assert!(close(locals[0].translation, expected), "{}", locals[0].translation);
    // Scale: v0 = 1, v1 = (3,1,1), zero tangents.
    assert!(close(locals[0].scale, Vec3::new(H00 + 3.0 * H01, 1.0, 1.0)), "{}", locals[0].scale);
    assert!(close(locals[0].scale, Vec3::new(1.3125, 1.0, 1.0)));
    // Rotation: v0 = identity, b0 = (0,0.5,0,0), v1 = 90° about Y, a1 = 0: the sum
    // (0, 0.28125 + 0.15625·√½, 0, 0.84375 + 0.15625·√½), normalised, is 0.5146 rad about Y.
    let q = locals[0].rotation;
    assert!(q.is_normalized());
    assert!(same_rotation(q, Quat::from_rotation_y(0.514_639_3)), "{q}");
    // The keys themselves, exactly.
    graph.clips[0].apply(2.0, &mut locals);
    assert_eq!(locals[0].translation, Vec3::new(4.0, 0.0, 0.0));
    assert_eq!(locals[0].scale, Vec3::new(3.0, 1.0, 1.0));

    // Weights: target 0 goes 0 → 1 with out-tangent 0.5, target 1 goes 1 → 0.
    let mut g = graph.clone();
    g.active = vec![0];
    let w = &g.pose_weights(0.5)[0];
    assert!((w[0] - (H10 * 2.0 * 0.5 + H01)).abs() < 1e-6 && (w[0] - 0.296875).abs() < 1e-6, "{w:?}");
    assert!((w[1] - H00).abs() < 1e-6, "{w:?}");
    assert_eq!(g.pose_weights(2.0)[0], [1.0, 0.0]);

    // Through the renderer: the morphing mesh is rebuilt from its rest pose by the weights.
    let mut r = posed(&scene, None, 0.5);
    let p = mesh_positions(&mut r);
    for (k, v) in TRIANGLE.chunks(3).enumerate() {
        let expected = Vec3::from_slice(v) + Vec3::new(0.0, H00, 0.296875);
        assert!(close(p[k], expected), "vertex {k}: {} vs {expected}", p[k]);
    }
    // Moving the weights refits the tree kept from the rest pose.
    r.set_time(1.0).unwrap();
    let work = r.run_frame().unwrap().bvh_work;
    assert_eq!((work.blas_built, work.blas_refit), (0, 1));
}

/// A rotation clip as Blender writes it: CUBICSPLINE with every tangent (0,0,0,0), three keys.
fn blender_rotation() -> Value {
    let mut d = Data::default();
    let pos = d.add("VEC3", &TRIANGLE);
    let times = d.add("SCALAR", &[0.0, 1.0, 2.0]);
    let s = std::f32::consts::FRAC_1_SQRT_2;
    let keys = [[0.0, 0.0, 0.0, 1.0], [0.0, s, 0.0, s], [0.0, 1.0, 0.0, 0.0]];
    let values: Vec<f32> = keys.iter().flat_map(|k| [[0.0; 4], *k, [0.0; 4]]).flatten().collect();
    let output = d.add("VEC4", &values);
    d.gltf(
        json!([{"name": "Camera", "mesh": 0}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]),
        json!({"animations": [{
            "name": "CameraAnimation",
            "samplers": [{"input": times, "output": output, "interpolation": "CUBICSPLINE"}],
            "channels": [{"sampler": 0, "target": {"node": 0, "path": "rotation"}}]
        }]}),
    )
}

#[test]
fn blender_zero_tangents_give_finite_smoothstep_rotations() {
    let scene = load("blender.gltf", &blender_rotation());
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    let clip = &scene.graph.clips[0];
    let mut locals = vec![Transform::IDENTITY];
    for (t, angle) in [(0.0, 0.0), (1.0, 90.0f32), (2.0, 180.0)] {
        clip.apply(t, &mut locals);
        assert!(same_rotation(locals[0].rotation, Quat::from_rotation_y(angle.to_radians())), "t = {t}");
    }
    // Zero tangents: the value blend h00·q0 + h01·q1 at s = 1/4, normalised (0.2305 rad).
    clip.apply(0.25, &mut locals);
    let q = locals[0].rotation;
    assert!(q.is_finite() && q.is_normalized(), "{q}");
    assert!(same_rotation(q, Quat::from_rotation_y(0.230_541_94)), "{q}");
    // It plays when chosen by index, at any time.
    let r = posed(&scene, Some("0"), 1.5);
    assert!(r.world().resource::<NodeGraph>().world[0].is_finite());
}

/// Nodes 0 and 1 (a triangle and a camera) and a spot light (node 2), each moved along +X by
/// a clip of its own, as exporters write one clip per object; clip 3 (`Both`) drives nodes 0
/// and 1 again.
fn per_object_clips() -> Value {
    let mut d = Data::default();
    let pos = d.add("VEC3", &TRIANGLE);
    let times = d.add("SCALAR", &[0.0, 1.0]);
    let tracks: Vec<usize> =
        (0..3).map(|n| d.add("VEC3", &[0.0, n as f32, 0.0, 2.0 * (n + 1) as f32, n as f32, 0.0])).collect();
    let clip = |name: &str, nodes: &[usize]| {
        let samplers: Vec<Value> = nodes.iter().map(|&n| json!({"input": times, "output": tracks[n]})).collect();
        let channels: Vec<Value> = (0..nodes.len())
            .map(|k| json!({"sampler": k, "target": {"node": nodes[k], "path": "translation"}}))
            .collect();
        json!({"name": name, "samplers": samplers, "channels": channels})
    };
    d.gltf(
        json!([{"name": "Cube", "mesh": 0}, {"name": "Cam", "camera": 0, "translation": [0, 1, 0]},
               {"name": "Spot", "translation": [0, 2, 0], "extensions": {"KHR_lights_punctual": {"light": 0}}}]),
        json!([{"primitives": [{"attributes": {"POSITION": pos}}]}]),
        json!({
            "cameras": [{"type": "perspective", "perspective": {"yfov": 0.7, "znear": 0.1}}],
            "extensionsUsed": ["KHR_lights_punctual"],
            "extensions": {"KHR_lights_punctual": {"lights": [{"type": "spot", "intensity": 5.0, "spot": {"outerConeAngle": 0.7}}]}},
            "animations": [clip("CubeAction", &[0]), clip("CamAction", &[1]), clip("SpotAction", &[2]), clip("Both", &[0, 1])]
        }),
    )
}

#[test]
fn clips_on_disjoint_nodes_play_together_and_overlapping_ones_are_refused() {
    let mut v = per_object_clips();
    let both = v["animations"].as_array_mut().unwrap().pop().unwrap();
    let scene = load("per-object.gltf", &v);
    // Default: the three clips animate three different nodes, so all play. At t = 0.5 each
    // node is half way to x = 2(n + 1).
    let mut r = posed(&scene, None, 0.5);
    for n in 0..3 {
        assert!(close(translation(&r, n), Vec3::new((n + 1) as f32, n as f32, 0.0)), "node {n}");
    }
    let eye = r.world_mut().query::<&Camera>().single(r.world()).unwrap().eye;
    assert!(close(eye, Vec3::new(2.0, 1.0, 0.0)), "the camera follows its clip: {eye}");
    let w = r.world_mut();
    let spot = w.query_filtered::<&Transform, With<SpotLight>>().single(w).unwrap().translation;
    assert!(close(spot, Vec3::new(3.0, 2.0, 0.0)), "the light follows its clip: {spot}");
    // The same by `all` and by a list of names and indices; one clip alone moves one node.
    for key in ["all", "CubeAction,1, SpotAction"] {
        let r = posed(&scene, Some(key), 0.5);
        assert!((0..3).all(|n| close(translation(&r, n), Vec3::new((n + 1) as f32, n as f32, 0.0))), "{key}");
    }
    let r = posed(&scene, Some("CamAction"), 0.5);
    assert!(close(translation(&r, 0), Vec3::ZERO) && close(translation(&r, 1), Vec3::new(2.0, 1.0, 0.0)));
    let e = scene.spawn(&mut World::new(), &SpawnOptions { animation: Some("0,Dance".into()), ..Default::default() });
    let e = e.unwrap_err().to_string();
    assert!(e.contains("no animation 'Dance' (available: 0: CubeAction, 1: CamAction, 2: SpotAction, or all)"), "{e}");

    // With a clip that drives two nodes again, clips overlap: the default is the first alone,
    // and two clips driving one property are refused together.
    v["animations"].as_array_mut().unwrap().push(both);
    let scene = load("overlapping.gltf", &v);
    let r = posed(&scene, None, 0.5);
    assert!(close(translation(&r, 0), Vec3::X) && close(translation(&r, 1), Vec3::Y), "only CubeAction plays");
    let e = scene.spawn(&mut World::new(), &SpawnOptions { animation: Some("all".into()), ..Default::default() });
    let e = e.unwrap_err().to_string();
    assert!(e.contains("overlapping.gltf"), "{e}");
    assert!(e.contains("animations 'CubeAction' and 'Both' both drive the translation of node 'Cube'"), "{e}");
    let r = posed(&scene, Some("Both,SpotAction"), 0.5);
    assert!((0..3).all(|n| close(translation(&r, n), Vec3::new((n + 1) as f32, n as f32, 0.0))));
}

#[test]
fn a_clip_that_cannot_be_played_is_a_warning_until_it_is_chosen() {
    let mut v = per_object_clips();
    v["animations"].as_array_mut().unwrap().truncate(2);
    // CamAction's output holds 1 value for 2 keys.
    let bad = v["accessors"].as_array().unwrap().len();
    let mut accessor = v["accessors"][2].clone();
    accessor["count"] = json!(1);
    v["accessors"].as_array_mut().unwrap().push(accessor);
    v["animations"][1]["samplers"][0]["output"] = json!(bad);
    let path = write("bad-clip.gltf", &v);
    let scene = gltf::load(&path).unwrap();
    let channel = "channel 0 (translation of node 1 ('Cam')): 1 output values for 2 keys; expected 2";
    let why = format!("animation 1 ('CamAction'): {channel}");
    assert_eq!(scene.warnings, [format!("animation 1 ('CamAction') cannot be played and is left out: {channel}")]);
    assert_eq!(scene.animation_names(), ["CubeAction"]);
    let r = posed(&scene, None, 0.5);
    assert!(close(translation(&r, 0), Vec3::X) && close(translation(&r, 1), Vec3::Y), "CubeAction alone plays");
    for key in ["1", "CamAction", "all,1"] {
        let e = scene.spawn(&mut World::new(), &SpawnOptions { animation: Some(key.into()), ..Default::default() });
        let e = e.unwrap_err().to_string();
        assert!(e.starts_with(&path.display().to_string()) && e.ends_with(&why), "{key}: {e}");
    }
}

#[test]
fn morph_weights_of_a_half_move_vertices_half_way() {
    let mut d = Data::default();
    let pos = d.add("VEC3", &TRIANGLE);
    let offsets = d.add("VEC3", &[0.0, 0.0, 2.0, 0.0, 0.0, 2.0, 4.0, 0.0, 0.0]);
    let mesh = json!([{"weights": [0.25],
                       "primitives": [{"attributes": {"POSITION": pos}, "targets": [{"POSITION": offsets}]}]}]);
    let v = d.gltf(json!([{"mesh": 0, "weights": [0.5]}, {"mesh": 0, "translation": [5, 0, 0]}]), mesh, json!({}));
    let scene = load("morph.gltf", &v);
    assert_eq!(scene.graph.nodes.iter().map(|n| n.weights.clone()).collect::<Vec<_>>(), [vec![0.5], vec![0.25]]);
    let mut r = Renderer::new(common::settings(8, 8, 1, SamplerKind::Jittered));
    scene.spawn(r.world_mut(), &SpawnOptions::default()).unwrap();
    let w = r.world_mut();
    let mut placed: Vec<(Vec3, Vec<Vec3>, bool)> = w
        .query::<(&Transform, &TriangleMesh, hemi::bevy_ecs::query::Has<Deforming>)>()
        .iter(w)
        .map(|(t, m, d)| (t.translation, m.0.positions.clone(), d))
        .collect();
    placed.sort_by(|a, b| a.0.x.total_cmp(&b.0.x));
    // Node weight 0.5 (over the mesh's 0.25): half of each offset; the second node keeps the
    // mesh's own weight. Neither is animated, so neither deforms per frame.
    let half = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(2.0, 1.0, 0.0)];
    let quarter = [Vec3::new(0.0, 0.0, 0.5), Vec3::new(1.0, 0.0, 0.5), Vec3::new(1.0, 1.0, 0.0)];
    assert_eq!(placed[0].1, half);
    assert_eq!(placed[1].1, quarter);
    assert!(placed.iter().all(|p| !p.2));
    r.run_frame().unwrap();
}

/// Corners of the world bounds of every mesh in `r`'s world.
fn corners(r: &mut Renderer) -> Vec<Vec3> {
    let w = r.world_mut();
    let mut out = Vec::new();
    for (t, m) in w.query::<(&Transform, &TriangleMesh)>().iter(w) {
        let a = glam::Affine3A::from_scale_rotation_translation(t.scale, t.rotation, t.translation);
        let (lo, hi) = m.0.positions.iter().fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| {
            let q = a.transform_point3(p);
            (lo.min(q), hi.max(q))
        });
        for k in 0..8 {
            out.push(Vec3::new([lo.x, hi.x][k & 1], [lo.y, hi.y][k >> 1 & 1], [lo.z, hi.z][k >> 2]));
        }
    }
    out
}

/// Whether `p` projects inside a square image of `camera`.
fn in_view(camera: &Camera, p: Vec3) -> bool {
    let w = (camera.eye - camera.target).normalize();
    let u = camera.up.cross(w).normalize();
    let v = w.cross(u);
    let d = p - camera.eye;
    let depth = -d.dot(w);
    let half = (camera.vfov_degrees.to_radians() * 0.5).tan();
    depth > 0.0 && (d.dot(u) / depth).abs() <= half && (d.dot(v) / depth).abs() <= half
}

#[test]
fn a_camera_less_file_is_framed_over_every_frame_it_renders() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets/BoxAnimated/glTF-Binary/BoxAnimated.glb");
    let scene = gltf::load(&path).unwrap();
    let frames: Vec<f32> = (0..96).map(|f| f as f32 / 24.0).collect();
    let framed = |framing_times: Vec<f32>| {
        let mut r = Renderer::new(common::settings(8, 8, 1, SamplerKind::Jittered));
        scene.spawn(r.world_mut(), &SpawnOptions { framing_times, ..Default::default() }).unwrap();
        let camera = *r.world_mut().query::<&Camera>().single(r.world()).unwrap();
        (r, camera)
    };
    let (mut r, camera) = framed(frames.clone());
    let (_, still) = framed(Vec::new());
    assert_ne!(camera, still, "the range widens the view");
    assert!(camera.eye.z > camera.target.z, "it looks at the model's front (+Z)");
    let mut outside_still = 0;
    for &t in &frames {
        r.set_time(t).unwrap();
        r.run_frame().unwrap();
        for p in corners(&mut r) {
            assert!(in_view(&camera, p), "t = {t}: {p} leaves the frame");
            outside_still += usize::from(!in_view(&still, p));
        }
    }
    assert!(outside_still > 0, "framed at its first frame only, the box leaves the view");

    // A file that does not move keeps the camera of its first frame exactly.
    let still_file = path.with_file_name("../../Box/glTF-Binary/Box.glb");
    let still_file = gltf::load(&still_file).unwrap();
    let cameras: Vec<Camera> = [Vec::new(), frames]
        .into_iter()
        .map(|framing_times| {
            let mut w = World::new();
            still_file.spawn(&mut w, &SpawnOptions { framing_times, camera: None, ..Default::default() }).unwrap();
            *w.query::<&Camera>().single(&w).unwrap()
        })
        .collect();
    assert_eq!(cameras[0], cameras[1]);
}
