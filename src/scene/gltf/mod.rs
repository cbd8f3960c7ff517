//! glTF 2.0 scenes (`.gltf` with external or `data:` buffers, `.glb`): meshes (triangle lists,
//! strips, fans; indexed or not; strided and sparse accessors), the default scene's node
//! hierarchy, `EXT_mesh_gpu_instancing`, perspective and orthographic cameras,
//! `KHR_lights_punctual` point lights, base colours and textures, alpha modes, node animations,
//! skins and morph targets.
//!
//! [`load`] reads a file into a [`GltfScene`]; [`GltfScene::spawn`] puts it into a renderer's
//! world as ordinary hemi entities (one `TriangleMesh` per primitive, shared by every node that
//! uses the mesh) plus a [`NodeGraph`] resource that the animation systems pose from
//! [`Time`]. Malformed input is refused with one line naming the file and the element: every
//! index, byte range, stride and count is checked ([`validate`]) before the gltf crate's
//! wrappers and readers run, and what the loader allocates is bounded by the size of the file
//! ([`accessors::Data`]). Files must be regular files of at most [`MAX_FILE_BYTES`], and
//! external buffers must lie in the model's folder unless [`LoadOptions::allow_external_uris`]
//! is set. As a last line of defence the reader runs under `catch_unwind` with the panic
//! message kept out of stderr (see [`load_with`]).
//!
//! Units: a point light's `intensity` (candela) becomes `PointLight::ls` with inverse-square
//! falloff, so with a white Lambertian surface at 1 m a 1 cd light gives radiance 1/π, the same
//! scale on which the default ambient occluder (`ls = 1`) gives radiance 1 to unoccluded white.

pub mod accessors;
pub mod buffers;
mod clips;
mod framing;
mod materials;
mod spawn;
pub mod validate;

pub use framing::framing_camera;

use std::{
    cell::{Cell, RefCell},
    collections::HashMap,
    panic::AssertUnwindSafe,
    path::{Path, PathBuf},
    sync::{Arc, Once},
};

use accessors::Data;
pub use buffers::{LoadOptions, MAX_FILE_BYTES};
pub use framing::MAX_FRAMING_POSES;

use ::gltf::{
    Document,
    accessor::Dimensions,
    khr_lights_punctual::Kind as LightKind,
    mesh::{Mode, Semantic},
};
use bevy_ecs::{name::Name, prelude::World};
use glam::{Affine3A, Mat4, Quat, Vec3};

use crate::{
    animation::{Clip, Influences, Node, NodeGraph, NodeLink, Skin},
    components::{
        AmbientOccluder, Camera, Deforming, DirectionalLight, Dynamic, Matte, Mesh, OrthographicCamera, PointLight,
        SpotLight, Transform, TriangleMesh,
    },
    error::HemiError,
    light::Light,
    material::Surface,
    resources::Time,
};

/// One drawable piece of a glTF mesh: triangles and a material.
#[derive(Clone, Debug)]
pub struct Primitive {
    /// Triangles in the mesh's frame.
    pub mesh: Arc<Mesh>,
    /// Base colour as a matte material.
    pub material: Matte,
    /// What varies over the surface (texture, vertex colours) or lets rays through (alpha),
    /// if anything does.
    pub surface: Option<Surface>,
    /// Skinning influences per vertex, when the primitive has JOINTS_0 and WEIGHTS_0.
    pub influences: Option<Influences>,
    /// Position offsets of each morph target, one per vertex (empty for a target without
    /// POSITION); no targets, no entries.
    pub targets: Arc<Vec<Vec<Vec3>>>,
}

/// A camera's projection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Perspective with this vertical field of view in degrees.
    Perspective(f32),
    /// Orthographic with this half height.
    Orthographic(f32),
}

/// A camera placed at a node.
#[derive(Clone, Debug, PartialEq)]
pub struct CameraNode {
    /// Node index in [`GltfScene::graph`].
    pub node: usize,
    /// Index in the file's `cameras` array.
    pub index: usize,
    /// Camera name, or the node's name, or `camera N`.
    pub name: String,
    /// Projection.
    pub projection: Projection,
}

/// A mesh placed at a node (with its `EXT_mesh_gpu_instancing` offsets, if any).
#[derive(Clone, Debug)]
struct Placement {
    node: usize,
    mesh: usize,
    skin: Option<usize>,
    offsets: Vec<Affine3A>,
}

#[derive(Clone, Debug)]
struct SkinData {
    joints: Vec<usize>,
    inverse_bind: Vec<Affine3A>,
}

/// A loaded glTF asset, ready to spawn.
#[derive(Clone, Debug)]
pub struct GltfScene {
    /// The file it came from.
    pub path: PathBuf,
    /// The default scene's nodes (parents first) and the animations.
    pub graph: NodeGraph,
    /// Primitives of each glTF mesh used by the scene (indexed like the file's `meshes`).
    pub meshes: Vec<Vec<Primitive>>,
    /// Cameras of the scene, in hierarchy order.
    pub cameras: Vec<CameraNode>,
    /// `KHR_lights_punctual` lights of the scene: (node, light).
    pub lights: Vec<(usize, GltfLight)>,
    /// What was skipped or approximated, one line each.
    pub warnings: Vec<String>,
    placements: Vec<Placement>,
    skins: Vec<SkinData>,
    /// `mesh 0 ('Body') primitive 0 (POSITION accessor 7)` for each entry of `meshes`.
    labels: Vec<Vec<String>>,
    /// The file's index of each clip in `graph.clips`.
    clip_index: Vec<usize>,
    /// Animations that cannot be played: (file index, name, why).
    refused_clips: Vec<(usize, String, String)>,
}

/// A `KHR_lights_punctual` light mapped to hemi's component: point and spot intensities are
/// in candela (hemi's `ls`, with inverse-square falloff), directional ones in lux (irradiance
/// at normal incidence). Spot and directional lights shine down their node's −Z axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GltfLight {
    /// A point light.
    Point(PointLight),
    /// A spot light with glTF's cone angles.
    Spot(SpotLight),
    /// A directional (sun) light.
    Directional(DirectionalLight),
}

/// Which camera and animation to use, and the start time.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SpawnOptions {
    /// Camera by name or index in the file's `cameras` (default: the first in the scene).
    pub camera: Option<String>,
    /// Animations that play together: `all`, or a comma-separated list of names and indices
    /// (default: all of them when no two animate the same node, as exporters that write one
    /// clip per object do; otherwise the first).
    pub animation: Option<String>,
    /// Time in seconds the scene is posed at (and, for a file without cameras, framed at).
    pub time: f32,
    /// Further times that the camera framing a file without cameras keeps in view, such as
    /// every frame of a sequence (at most [`MAX_FRAMING_POSES`] of them are sampled, evenly).
    pub framing_times: Vec<f32>,
    /// Spawn only the posed, static geometry: no camera, lights, default occluder, animation
    /// graph or node links (for merging several files into one scene, as peer scenes do).
    pub geometry_only: bool,
}

/// Reads a `.gltf` or `.glb` file with the default [`LoadOptions`] (external buffers only
/// inside the file's folder). Errors name the file and the offending element.
pub fn load(path: &Path) -> Result<GltfScene, HemiError> {
    load_with(path, &LoadOptions::default())
}

/// Reads a `.gltf` or `.glb` file: a regular file of at most [`MAX_FILE_BYTES`], whose
/// external buffers resolve in its folder unless `options` allow more. Errors are one line
/// naming the file and the offending element.
///
/// Should the gltf crate still panic on some input that the checks before it missed, the
/// panic is caught and reported as an error, and its message is kept off stderr: the first
/// load installs a process-wide panic hook that stays silent while, on the same thread, a
/// load is running and otherwise defers to the hook that was installed before it. (A hook
/// swapped in and out around each load would race with panics on other threads.)
pub fn load_with(path: &Path, options: &LoadOptions) -> Result<GltfScene, HemiError> {
    let fail = |message: String| HemiError::Load { path: path.to_path_buf(), message };
    let bytes = buffers::read_file(path, MAX_FILE_BYTES).map_err(fail)?;
    from_slice(&bytes, path, options)
}

/// Reads a glTF or GLB file already in memory; `path` names it in errors, and external
/// buffers resolve against its folder.
pub fn from_slice(bytes: &[u8], path: &Path, options: &LoadOptions) -> Result<GltfScene, HemiError> {
    let fail = |message: String| HemiError::Load { path: path.to_path_buf(), message };
    let base = path.parent().unwrap_or(Path::new("."));
    match catch_quietly(|| parse(bytes, base, options)) {
        Ok(Ok(mut scene)) => {
            scene.path = path.to_path_buf();
            Ok(scene)
        }
        Ok(Err(message)) => Err(fail(message)),
        Err(panic) => Err(fail(format!("the glTF reader failed on malformed data ({panic})"))),
    }
}

thread_local! {
    static QUIET: Cell<bool> = const { Cell::new(false) };
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Runs `f`, turning a panic into its message (one line) without printing it.
fn catch_quietly<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    static HOOK: Once = Once::new();
    HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !QUIET.with(Cell::get) {
                return previous(info);
            }
            let payload = info.payload();
            let message = payload
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| payload.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "a panic".into());
            let place = info.location().map_or(String::new(), |l| {
                let file: Vec<&str> = l.file().rsplit(['/', '\\']).take(3).collect();
                let file: Vec<&str> = file.into_iter().rev().collect();
                format!(" at {}:{}", file.join("/"), l.line())
            });
            let line = format!("{message}{place}").replace(['\n', '\r'], " ");
            LAST_PANIC.with(|p| *p.borrow_mut() = Some(line));
        }));
    });
    let was = QUIET.with(|q| q.replace(true));
    let result = std::panic::catch_unwind(AssertUnwindSafe(f));
    QUIET.with(|q| q.set(was));
    result.map_err(|_| LAST_PANIC.with(|p| p.borrow_mut().take()).unwrap_or_else(|| "a panic".into()))
}

fn label(kind: &str, index: usize, name: Option<&str>) -> String {
    match name {
        Some(n) => format!("{kind} {index} ('{n}')"),
        None => format!("{kind} {index}"),
    }
}

fn parse(bytes: &[u8], base: &Path, options: &LoadOptions) -> Result<GltfScene, String> {
    let ::gltf::Gltf { document: doc, blob } = ::gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| format!("not a valid glTF 2.0 file: {e}").replace(['\n', '\r'], " "))?;
    // The order matters: the crate's own validation indexes some arrays unchecked, and its
    // wrappers index all of them, so references are checked first.
    validate::references(doc.as_json())?;
    validate::rules(doc.as_json())?;
    let buffers = buffers::load(&doc, blob, base, options)?;
    let uses = validate::accessor_uses(doc.as_json());
    let lens: Vec<usize> = buffers.iter().map(Vec::len).collect();
    validate::data(doc.as_json(), &lens, &uses)?;
    let buffers = Data::new(buffers);
    let mut warnings = Vec::new();
    let (nodes, graph_index) = hierarchy(&doc, &mut warnings)?;

    let mut scene = GltfScene {
        path: PathBuf::new(),
        graph: NodeGraph { nodes, ..Default::default() },
        meshes: vec![Vec::new(); doc.meshes().len()],
        cameras: Vec::new(),
        lights: Vec::new(),
        warnings: Vec::new(),
        placements: Vec::new(),
        skins: Vec::new(),
        labels: vec![Vec::new(); doc.meshes().len()],
        clip_index: Vec::new(),
        refused_clips: Vec::new(),
    };
    let mut mesh_read = vec![false; doc.meshes().len()];
    let mut skin_slot: HashMap<usize, usize> = HashMap::new();
    let mut skipped_prims = 0;
    let mut textures = materials::Textures::new(&doc, &buffers, base, options);

    // Walk the scene's nodes in hierarchy order.
    let mut order: Vec<(usize, ::gltf::Node)> =
        doc.nodes().filter_map(|n| graph_index[n.index()].map(|g| (g, n))).collect();
    order.sort_by_key(|(g, _)| *g);
    for (g, node) in &order {
        let g = *g;
        let node_label = label("node", node.index(), node.name());
        if let Some(mesh) = node.mesh() {
            let m = mesh.index();
            if !mesh_read[m] {
                mesh_read[m] = true;
                let mesh_label = label("mesh", m, mesh.name());
                for p in mesh.primitives() {
                    let prim_label = format!("{mesh_label} primitive {}", p.index());
                    let read = read_primitive(&p, &buffers, &mut textures, &mut warnings);
                    match read.map_err(|e| format!("{prim_label}: {e}"))? {
                        Some(prim) => {
                            let position = p.get(&Semantic::Positions).map_or(0, |a| a.index());
                            scene.labels[m].push(format!("{prim_label} (POSITION accessor {position})"));
                            scene.meshes[m].push(prim);
                        }
                        None => skipped_prims += 1,
                    }
                }
            }
            let skin = match node.skin() {
                Some(skin) => {
                    let next = scene.skins.len();
                    let slot = *skin_slot.entry(skin.index()).or_insert(next);
                    if slot == next {
                        let data = read_skin(&skin, &buffers, &graph_index)
                            .map_err(|e| format!("{}: {e}", label("skin", skin.index(), skin.name())))?;
                        scene.skins.push(data);
                    }
                    Some(slot)
                }
                None => None,
            };
            let offsets = gpu_instances(&doc, node, &buffers).map_err(|e| format!("{node_label}: {e}"))?;
            // What spawning costs: an entity per primitive and instance, and for a skinned
            // mesh a posed copy of its vertices and triangles.
            for prim in &scene.meshes[m] {
                buffers.charge(offsets.len(), 256, &node_label)?;
                if skin.is_some() && prim.influences.is_some() {
                    let size = prim.mesh.positions.len() + prim.mesh.indices.len();
                    buffers.charge(size, 12, &format!("{node_label} (skinned copy)"))?;
                }
                if !prim.targets.is_empty() {
                    let size = (prim.mesh.positions.len() + prim.mesh.indices.len()).saturating_mul(offsets.len());
                    buffers.charge(size, 12, &format!("{node_label} (morphed copy)"))?;
                }
            }
            scene.placements.push(Placement { node: g, mesh: m, skin, offsets });
        }
        if let Some(camera) = node.camera() {
            let projection = match camera.projection() {
                ::gltf::camera::Projection::Perspective(p) => Projection::Perspective(p.yfov().to_degrees()),
                ::gltf::camera::Projection::Orthographic(o) => Projection::Orthographic(o.ymag().abs()),
            };
            let name = camera.name().or(node.name()).map_or(format!("camera {}", camera.index()), str::to_string);
            scene.cameras.push(CameraNode { node: g, index: camera.index(), name, projection });
        }
        if let Some(light) = node.light() {
            let light_label = label("light", light.index(), light.name());
            let [r, gr, b] = light.color();
            let (ls, color) = (light.intensity(), Vec3::new(r, gr, b));
            let mapped = match light.kind() {
                LightKind::Point => GltfLight::Point(PointLight { ls, color, shadows: true, falloff: true }),
                LightKind::Directional => GltfLight::Directional(DirectionalLight { ls, color, shadows: true }),
                LightKind::Spot { inner_cone_angle, outer_cone_angle } => {
                    GltfLight::Spot(SpotLight { ls, color, inner_cone_angle, outer_cone_angle, shadows: true })
                }
            };
            let checked = match &mapped {
                GltfLight::Point(l) => l.validate(&Transform::IDENTITY),
                GltfLight::Spot(l) => l.validate(&Transform::IDENTITY),
                GltfLight::Directional(l) => l.validate(&Transform::IDENTITY),
            };
            checked.map_err(|e| format!("{light_label}: {e}"))?;
            scene.lights.push((g, mapped));
        }
    }
    // A clip that cannot be played costs only itself: it is refused when chosen, and the
    // others still load and play.
    for animation in doc.animations() {
        let name = animation.name().map_or(format!("animation {}", animation.index()), str::to_string);
        match clips::read_clip(&animation, &buffers, &graph_index, &scene.graph.nodes, &mut warnings) {
            Ok(clip) => {
                scene.graph.clips.push(Clip { name, ..clip });
                scene.clip_index.push(animation.index());
            }
            Err(e) => {
                let clip = label("animation", animation.index(), animation.name());
                warnings.push(format!("{clip} cannot be played and is left out: {e}"));
                let why = format!("{clip}: {e}");
                scene.refused_clips.push((animation.index(), name, why));
            }
        }
    }
    let sheared = sheared_nodes(&scene.graph, scene.placements.iter().map(|p| p.node));
    if sheared > 0 {
        warnings.push(format!(
            "{sheared} mesh nodes have a sheared world matrix (non-uniform scale under a rotated parent); \
             hemi keeps its scale, rotation and translation only"
        ));
    }
    if skipped_prims > 0 {
        warnings.push(format!("skipped {skipped_prims} point/line primitives (hemi renders triangles only)"));
    }
    scene.warnings = warnings;
    Ok(scene)
}

/// How many of `nodes` have a rest-pose world matrix that a scale-rotation-translation cannot
/// reproduce (shear).
fn sheared_nodes(graph: &NodeGraph, nodes: impl Iterator<Item = usize>) -> usize {
    let world = graph.pose(0.0);
    nodes
        .filter(|&n| {
            let m = world[n];
            let back = Transform::from_affine(&m);
            let r = Affine3A::from_scale_rotation_translation(back.scale, back.rotation, back.translation);
            let size = m.matrix3.x_axis.length() + m.matrix3.y_axis.length() + m.matrix3.z_axis.length();
            (r.matrix3 - m.matrix3).to_cols_array().iter().any(|d| d.abs() > 1e-4 * size)
        })
        .count()
}

/// The default scene's nodes in depth-first order (parents first), and each file node's index
/// in that order (`None` for nodes outside the scene).
fn hierarchy(doc: &Document, warnings: &mut Vec<String>) -> Result<(Vec<Node>, Vec<Option<usize>>), String> {
    let roots: Vec<::gltf::Node> = match doc.default_scene().or_else(|| doc.scenes().next()) {
        Some(scene) => scene.nodes().collect(),
        None => {
            let mut is_child = vec![false; doc.nodes().len()];
            for n in doc.nodes() {
                for c in n.children() {
                    is_child[c.index()] = true;
                }
            }
            doc.nodes().filter(|n| !is_child[n.index()]).collect()
        }
    };
    let mut index = vec![None; doc.nodes().len()];
    let mut nodes = Vec::new();
    let mut stack: Vec<(::gltf::Node, Option<usize>)> = roots.into_iter().rev().map(|n| (n, None)).collect();
    while let Some((node, parent)) = stack.pop() {
        let node_label = label("node", node.index(), node.name());
        if index[node.index()].is_some() {
            return Err(format!("{node_label} appears twice in the scene hierarchy (a cycle or a shared child)"));
        }
        let (t, r, s) = node.transform().decomposed();
        let mut rest = Transform { translation: Vec3::from(t), rotation: Quat::from_array(r), scale: Vec3::from(s) };
        if !(rest.translation.is_finite() && rest.rotation.is_finite() && rest.scale.is_finite()) {
            return Err(format!("{node_label} has a non-finite transform"));
        }
        if let ::gltf::scene::Transform::Decomposed { rotation, .. } = node.transform() {
            let length = Quat::from_array(rotation).length();
            if length <= 1e-6 {
                return Err(format!("{node_label}: rotation {rotation:?} is zero and cannot be normalised"));
            }
            if (length - 1.0).abs() > 1e-3 {
                rest.rotation = rest.rotation.normalize();
                warnings.push(format!("{node_label}: rotation is not unit length ({length}); normalised"));
            }
        }
        let g = nodes.len();
        index[node.index()] = Some(g);
        let weights = rest_weights(&node, &node_label, warnings);
        nodes.push(Node {
            name: node.name().map_or(format!("node {}", node.index()), str::to_string),
            parent,
            rest,
            weights,
        });
        let children: Vec<::gltf::Node> = node.children().collect();
        stack.extend(children.into_iter().rev().map(|c| (c, Some(g))));
    }
    Ok((nodes, index))
}

/// A node's morph weights without animation: its own `weights`, else its mesh's, one per
/// morph target (targets without a given weight get 0).
fn rest_weights(node: &::gltf::Node, node_label: &str, warnings: &mut Vec<String>) -> Vec<f32> {
    let Some(mesh) = node.mesh() else { return Vec::new() };
    let targets = mesh.primitives().map(|p| p.morph_targets().len()).max().unwrap_or(0);
    let given = node.weights().or(mesh.weights()).unwrap_or(&[]);
    if !given.is_empty() && given.len() != targets {
        warnings.push(format!(
            "{node_label}: {} morph weights for {targets} morph targets; missing ones are 0, extra ones unused",
            given.len()
        ));
    }
    let mut weights = vec![0.0; targets];
    for (w, &g) in weights.iter_mut().zip(given) {
        *w = if g.is_finite() { g } else { 0.0 };
    }
    weights
}

/// Triangles of one primitive and their surface, or `None` for points and lines.
fn read_primitive(
    p: &::gltf::Primitive,
    buffers: &Data,
    textures: &mut materials::Textures,
    warnings: &mut Vec<String>,
) -> Result<Option<Primitive>, String> {
    if !matches!(p.mode(), Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan) {
        return Ok(None);
    }
    let pos = p.get(&Semantic::Positions).ok_or("has no POSITION attribute")?;
    let positions: Vec<Vec3> = accessors::floats::<[f32; 3]>(&pos, Dimensions::Vec3, buffers)
        .map_err(|e| format!("POSITION {e}"))?
        .into_iter()
        .map(Vec3::from)
        .collect();
    let n = positions.len() as u32;
    let verts: Vec<u32> = match p.indices() {
        Some(acc) => {
            let idx = accessors::indices(&acc, buffers).map_err(|e| format!("indices {e}"))?;
            if let Some(k) = idx.iter().position(|&i| i >= n) {
                return Err(format!("index {} at position {k} is out of range ({n} vertices)", idx[k]));
            }
            idx
        }
        None => (0..n).collect(),
    };
    let m = verts.len();
    buffers.charge(m, 12, "triangles")?;
    let indices: Vec<[u32; 3]> = match p.mode() {
        Mode::Triangles => verts.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
        // glTF 2.0 §3.7.2.1: strip triangle i is (i, i+1+i%2, i+2-i%2); fan i is (i+1, i+2, 0).
        Mode::TriangleStrip => {
            (0..m.saturating_sub(2)).map(|i| [verts[i], verts[i + 1 + i % 2], verts[i + 2 - i % 2]]).collect()
        }
        _ => (0..m.saturating_sub(2)).map(|i| [verts[i + 1], verts[i + 2], verts[0]]).collect(),
    };
    let mesh = Mesh { positions, indices };
    mesh.validate().map_err(|e| format!("POSITION accessor {}: {e}", pos.index()))?;
    let [r, g, b, _] = p.material().pbr_metallic_roughness().base_color_factor();
    let material = Matte::new(Vec3::new(r, g, b));
    let influences = match (p.get(&Semantic::Joints(0)), p.get(&Semantic::Weights(0))) {
        (Some(j), Some(w)) => {
            let joints = accessors::uint4(&j, buffers).map_err(|e| format!("JOINTS_0 {e}"))?;
            let weights = accessors::unorm4(&w, buffers).map_err(|e| format!("WEIGHTS_0 {e}"))?;
            if joints.len() != mesh.positions.len() || weights.len() != mesh.positions.len() {
                return Err("JOINTS_0/WEIGHTS_0 counts differ from POSITION's".into());
            }
            let inf = joints.iter().zip(&weights).map(|(j, w)| std::array::from_fn(|k| (j[k], w[k]))).collect();
            Some(Arc::new(inf))
        }
        _ => None,
    };
    let mut targets = Vec::new();
    for (i, target) in p.morph_targets().enumerate() {
        let Some(acc) = target.positions() else {
            targets.push(Vec::new());
            continue;
        };
        let offsets = accessors::floats::<[f32; 3]>(&acc, Dimensions::Vec3, buffers)
            .map_err(|e| format!("morph target {i} POSITION {e}"))?;
        if offsets.len() != mesh.positions.len() {
            return Err(format!(
                "morph target {i} POSITION has {} offsets for {} vertices",
                offsets.len(),
                mesh.positions.len()
            ));
        }
        if let Some(k) = offsets.iter().position(|o| !o.iter().all(|x| x.is_finite())) {
            return Err(format!("morph target {i} POSITION offset {k} is not finite"));
        }
        targets.push(offsets.into_iter().map(Vec3::from).collect());
    }
    let surface = textures.surface(p, mesh.positions.len(), warnings)?;
    Ok(Some(Primitive { mesh: Arc::new(mesh), material, surface, influences, targets: Arc::new(targets) }))
}

fn read_skin(skin: &::gltf::Skin, buffers: &Data, graph_index: &[Option<usize>]) -> Result<SkinData, String> {
    let joints = skin
        .joints()
        .map(|j| graph_index[j.index()].ok_or_else(|| format!("joint node {} is not in the scene", j.index())))
        .collect::<Result<Vec<_>, _>>()?;
    let inverse_bind = match skin.inverse_bind_matrices() {
        Some(acc) => {
            let m = accessors::floats::<[[f32; 4]; 4]>(&acc, Dimensions::Mat4, buffers)
                .map_err(|e| format!("inverseBindMatrices {e}"))?;
            if m.len() < joints.len() {
                return Err(format!("{} inverse bind matrices for {} joints", m.len(), joints.len()));
            }
            m.iter().map(|c| Affine3A::from_mat4(Mat4::from_cols_array_2d(c))).collect()
        }
        None => vec![Affine3A::IDENTITY; joints.len()],
    };
    if inverse_bind.iter().any(|m: &Affine3A| !m.is_finite()) {
        return Err("an inverse bind matrix is not finite".into());
    }
    Ok(SkinData { joints, inverse_bind })
}

/// The per-instance transforms of `EXT_mesh_gpu_instancing` (one identity without it).
fn gpu_instances(doc: &Document, node: &::gltf::Node, buffers: &Data) -> Result<Vec<Affine3A>, String> {
    let Some(ext) = node.extension_value("EXT_mesh_gpu_instancing") else {
        return Ok(vec![Affine3A::IDENTITY]);
    };
    let attribute = |name: &str| -> Result<Option<Vec<[f32; 4]>>, String> {
        let Some(i) = ext.get("attributes").and_then(|a| a.get(name)).and_then(|v| v.as_u64()) else {
            return Ok(None);
        };
        let acc = doc.accessors().nth(i as usize).ok_or_else(|| format!("instancing {name} accessor {i} missing"))?;
        let values = if name == "ROTATION" {
            accessors::quats(&acc, buffers)
        } else {
            accessors::floats::<[f32; 3]>(&acc, Dimensions::Vec3, buffers)
                .map(|v| v.into_iter().map(|[x, y, z]| [x, y, z, 0.0]).collect())
        };
        values.map(Some).map_err(|e| format!("instancing {name} {e}"))
    };
    let (t, r, s) = (attribute("TRANSLATION")?, attribute("ROTATION")?, attribute("SCALE")?);
    let count = [&t, &r, &s].iter().filter_map(|a| a.as_ref().map(Vec::len)).max().unwrap_or(0);
    if [&t, &r, &s].iter().any(|a| a.as_ref().is_some_and(|v| v.len() != count)) {
        return Err("EXT_mesh_gpu_instancing attributes have different counts".into());
    }
    let at = |a: &Option<Vec<[f32; 4]>>, i: usize, default: [f32; 4]| a.as_ref().map_or(default, |v| v[i]);
    let offsets: Vec<Affine3A> = (0..count)
        .map(|i| {
            let [tx, ty, tz, _] = at(&t, i, [0.0; 4]);
            let [sx, sy, sz, _] = at(&s, i, [1.0; 4]);
            let q = Quat::from_array(at(&r, i, [0.0, 0.0, 0.0, 1.0])).normalize();
            Affine3A::from_scale_rotation_translation(Vec3::new(sx, sy, sz), q, Vec3::new(tx, ty, tz))
        })
        .collect();
    if offsets.iter().any(|m| !m.is_finite()) {
        return Err("EXT_mesh_gpu_instancing has a non-finite instance transform".into());
    }
    Ok(offsets)
}

/// Finds an item by index (a whole number) or by name.
fn choose<'a, T>(items: &'a [T], key: &str, index: impl Fn(&T) -> usize, name: impl Fn(&T) -> &str) -> Option<&'a T> {
    match key.parse::<usize>() {
        Ok(i) => items.iter().find(|c| index(c) == i),
        Err(_) => items.iter().find(|c| name(c) == key),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_caught_panic_becomes_one_quiet_line() {
        let e = catch_quietly(|| -> u32 { panic!("first\nsecond") }).unwrap_err();
        assert!(e.starts_with("first second at "), "{e}");
        assert!(e.contains("gltf/mod.rs:"), "{e}");
        assert_eq!(catch_quietly(|| 7).unwrap(), 7);
        // Panics outside still reach the previous hook (and are caught here by the harness).
        assert!(!QUIET.with(Cell::get));
    }
}
