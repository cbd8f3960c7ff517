//! `hemi info FILE`: what a glTF file holds, as the loader reads it (its checks, its one-line
//! errors and its warnings), for a person or, with `--json`, for a script.

use std::path::PathBuf;

use serde_json::{Value, json};

use crate::{
    error::HemiError,
    scene::gltf::{GltfLight, LoadOptions, MAX_FILE_BYTES, Projection, buffers},
};

/// Options of `hemi info`.
#[derive(clap::Args, Debug)]
pub(super) struct InfoArgs {
    /// A .gltf or .glb file.
    file: PathBuf,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
    /// Let the file's buffer URIs name files outside its folder (absolute paths, `..`).
    #[arg(long)]
    allow_external_uris: bool,
}

pub(super) fn info(args: InfoArgs) -> Result<(), HemiError> {
    let summary =
        summarize(&args.file, &LoadOptions { allow_external_uris: args.allow_external_uris, ..Default::default() })?;
    let text = if args.json { format!("{summary:#}\n") } else { human(&summary) };
    super::console::out(&text)
}

/// The file's contents as JSON: the loader reads (and checks) it; the document it checked
/// adds what the loader does not keep (scenes, materials, skins).
pub fn summarize(path: &std::path::Path, options: &LoadOptions) -> Result<Value, HemiError> {
    let fail = |message: String| HemiError::Load { path: path.to_path_buf(), message };
    let bytes = buffers::read_file(path, MAX_FILE_BYTES).map_err(fail)?;
    let scene = crate::scene::gltf::from_slice(&bytes, path, options)?;
    // The same bytes the loader accepted: every reference in them is valid.
    let doc = ::gltf::Gltf::from_slice_without_validation(&bytes)
        .map_err(|e| fail(format!("not a valid glTF 2.0 file: {e}").replace(['\n', '\r'], " ")))?
        .document;
    let meshes: Vec<Value> = doc
        .meshes()
        .map(|m| {
            let loaded = scene.meshes.get(m.index()).map_or(&[][..], Vec::as_slice);
            json!({
                "index": m.index(),
                "name": m.name(),
                "primitives": m.primitives().len(),
                "triangles": loaded.iter().map(|p| p.mesh.triangle_count()).sum::<usize>(),
                "in_scene": !loaded.is_empty(),
            })
        })
        .collect();
    let materials: Vec<Value> = doc
        .materials()
        .map(|m| {
            let pbr = m.pbr_metallic_roughness();
            let textures: Vec<&str> = [
                ("base_color", pbr.base_color_texture().is_some()),
                ("metallic_roughness", pbr.metallic_roughness_texture().is_some()),
                ("normal", m.normal_texture().is_some()),
                ("occlusion", m.occlusion_texture().is_some()),
                ("emissive", m.emissive_texture().is_some()),
            ]
            .into_iter()
            .filter_map(|(name, used)| used.then_some(name))
            .collect();
            let alpha = match m.alpha_mode() {
                ::gltf::material::AlphaMode::Opaque => "opaque",
                ::gltf::material::AlphaMode::Mask => "mask",
                ::gltf::material::AlphaMode::Blend => "blend",
            };
            json!({ "index": m.index(), "name": m.name(), "textures": textures, "alpha": alpha })
        })
        .collect();
    let cameras: Vec<Value> = scene
        .cameras
        .iter()
        .map(|c| match c.projection {
            Projection::Perspective(yfov) => {
                json!({ "index": c.index, "name": c.name, "type": "perspective", "yfov_degrees": yfov })
            }
            Projection::Orthographic(ymag) => {
                json!({ "index": c.index, "name": c.name, "type": "orthographic", "ymag": ymag })
            }
        })
        .collect();
    let lights: Vec<Value> = scene
        .lights
        .iter()
        .map(|(node, light)| {
            let (kind, intensity, color) = match light {
                GltfLight::Point(l) => ("point", l.ls, l.color),
                GltfLight::Spot(l) => ("spot", l.ls, l.color),
                GltfLight::Directional(l) => ("directional", l.ls, l.color),
            };
            json!({ "node": scene.graph.nodes[*node].name, "type": kind, "intensity": intensity, "color": color.to_array() })
        })
        .collect();
    let animations: Vec<Value> = scene
        .graph
        .clips
        .iter()
        .enumerate()
        .map(|(i, clip)| {
            let mut nodes: Vec<usize> = clip.channels.iter().map(|c| c.node).collect();
            nodes.sort_unstable();
            nodes.dedup();
            let names: Vec<&str> = nodes.iter().map(|&n| scene.graph.nodes[n].name.as_str()).collect();
            json!({ "index": i, "name": clip.name, "duration": clip.duration, "channels": clip.channels.len(), "nodes": names })
        })
        .collect();
    Ok(json!({
        "file": path.display().to_string(),
        "scenes": doc.scenes().len(),
        "default_scene": doc.default_scene().map(|s| s.index()),
        "nodes": scene.graph.nodes.len(),
        "meshes": meshes,
        "triangles": scene.scene_triangle_count(),
        "materials": materials,
        "cameras": cameras,
        "lights": lights,
        "animations": animations,
        "skins": doc.skins().len(),
        "warnings": scene.warnings,
    }))
}

/// `'name'` or `#index` of a JSON item.
fn label(item: &Value) -> String {
    match item["name"].as_str() {
        Some(n) => format!("'{n}'"),
        None => format!("#{}", item["index"]),
    }
}

/// One line per section, then one indented line per item.
fn human(s: &Value) -> String {
    let mut out = format!("{}\n", s["file"].as_str().unwrap_or_default());
    let default = s["default_scene"].as_u64().map_or("none".into(), |d| d.to_string());
    out.push_str(&format!("  scenes      {} (default {default}), {} nodes in it\n", s["scenes"], s["nodes"]));
    let items = |key: &str| s[key].as_array().map_or(&[][..], Vec::as_slice);
    fn section(out: &mut String, title: &str, lines: Vec<String>, extra: String) {
        out.push_str(&format!("  {title:<11} {}{extra}\n", lines.len()));
        for line in lines {
            out.push_str(&format!("    {line}\n"));
        }
    }
    let meshes = items("meshes").iter().map(|m| {
        let placed = if m["in_scene"].as_bool() == Some(true) { "" } else { ", not in the scene" };
        format!("{}: {} primitives, {} triangles{placed}", label(m), m["primitives"], m["triangles"])
    });
    section(&mut out, "meshes", meshes.collect(), format!(" ({} triangles placed)", s["triangles"]));
    let materials = items("materials").iter().map(|m| {
        let textures: Vec<&str> = m["textures"].as_array().into_iter().flatten().filter_map(Value::as_str).collect();
        let textures =
            if textures.is_empty() { "no textures".into() } else { format!("textures: {}", textures.join(", ")) };
        format!("{}: {textures}, alpha {}", label(m), m["alpha"].as_str().unwrap_or_default())
    });
    section(&mut out, "materials", materials.collect(), String::new());
    let cameras = items("cameras").iter().map(|c| match c["type"].as_str() {
        Some("perspective") => {
            format!("{}: perspective, {:.1}° vertical", label(c), c["yfov_degrees"].as_f64().unwrap_or(0.0))
        }
        _ => format!("{}: orthographic, half height {}", label(c), c["ymag"]),
    });
    section(&mut out, "cameras", cameras.collect(), String::new());
    let lights = items("lights").iter().map(|l| {
        format!(
            "{} at node '{}', intensity {}",
            l["type"].as_str().unwrap_or_default(),
            l["node"].as_str().unwrap_or_default(),
            l["intensity"]
        )
    });
    section(&mut out, "lights", lights.collect(), String::new());
    let animations = items("animations").iter().map(|a| {
        let nodes = a["nodes"].as_array().map_or(0, Vec::len);
        format!(
            "{}: {:.3} s, {} channels on {nodes} nodes",
            label(a),
            a["duration"].as_f64().unwrap_or(0.0),
            a["channels"]
        )
    });
    section(&mut out, "animations", animations.collect(), String::new());
    out.push_str(&format!("  skins       {}\n", s["skins"]));
    let warnings = items("warnings").iter().map(|w| w.as_str().unwrap_or_default().to_string()).collect();
    section(&mut out, "warnings", warnings, String::new());
    out
}
