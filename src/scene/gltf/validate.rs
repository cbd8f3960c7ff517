//! Checks a glTF document before any of the gltf crate's wrappers or readers touch it, so
//! that malformed input is a one-line error naming the element instead of a panic inside
//! the crate, and every allocation a count in the file asks for is bounded by what the file
//! holds:
//!
//! * [`references`]: every index (scene, node, mesh, accessor, buffer view, buffer, material,
//!   texture, image, sampler, skin, camera, light, animation sampler and target) is in range,
//!   and cameras and spot lights have their parameters; the gltf crate's own validation
//!   indexes some of these unchecked and its wrappers unwrap the rest;
//! * [`rules`]: the gltf crate's validation, first problem as one line;
//! * [`data`]: every buffer view lies inside its buffer and every accessor (and its sparse
//!   indices and values) inside its buffer view, with a stride no smaller than its element;
//!   sparse counts are at most the accessor's count, and an accessor without a buffer view
//!   (zeros plus sparse values) is no larger than [`zero_fill_limit`].

use ::gltf::json::{
    self, Root,
    accessor::{ComponentType, Type},
    validation::{Checked, Validate},
};

/// Bytes an accessor without a buffer view may cover: as many as the file's buffers hold
/// together, and at least 1 MiB. Such an accessor is zeros plus a few sparse values, so
/// nothing else bounds its `count`.
pub fn zero_fill_limit(buffer_bytes: u64) -> u64 {
    buffer_bytes.max(1 << 20)
}

fn name_of(name: &Option<String>) -> String {
    name.as_deref().map_or(String::new(), |n| format!(" ('{n}')"))
}

/// What each accessor is used for, for messages: `POSITION of mesh 0 ('Body'), primitive 0`.
pub fn accessor_uses(root: &Root) -> Vec<Option<String>> {
    let mut uses: Vec<Option<String>> = vec![None; root.accessors.len()];
    let mut note = |i: usize, what: String| {
        if let Some(slot @ None) = uses.get_mut(i) {
            *slot = Some(what);
        }
    };
    for (m, mesh) in root.meshes.iter().enumerate() {
        let mesh_label = format!("mesh {m}{}", name_of(&mesh.name));
        for (p, prim) in mesh.primitives.iter().enumerate() {
            for (semantic, acc) in &prim.attributes {
                let semantic = match semantic {
                    Checked::Valid(s) => s.to_string(),
                    Checked::Invalid => "an attribute".into(),
                };
                note(acc.value(), format!("{semantic} of {mesh_label}, primitive {p}"));
            }
            if let Some(acc) = prim.indices {
                note(acc.value(), format!("indices of {mesh_label}, primitive {p}"));
            }
        }
    }
    for (s, skin) in root.skins.iter().enumerate() {
        if let Some(acc) = skin.inverse_bind_matrices {
            note(acc.value(), format!("inverseBindMatrices of skin {s}{}", name_of(&skin.name)));
        }
    }
    for (a, anim) in root.animations.iter().enumerate() {
        for (k, sampler) in anim.samplers.iter().enumerate() {
            let label = format!("animation {a}{} sampler {k}", name_of(&anim.name));
            note(sampler.input.value(), format!("input of {label}"));
            note(sampler.output.value(), format!("output of {label}"));
        }
    }
    uses
}

/// `accessor 7 (POSITION of mesh 0 ('Body'), primitive 0)`.
pub fn accessor_label(index: usize, uses: &[Option<String>]) -> String {
    match uses.get(index).and_then(Option::as_ref) {
        Some(u) => format!("accessor {index} ({u})"),
        None => format!("accessor {index}"),
    }
}

/// Checks that every index in the document names an existing element.
pub fn references(root: &Root) -> Result<(), String> {
    let check = |what: String, index: usize, len: usize, kind: &str| -> Result<(), String> {
        if index >= len {
            let have = if len == 1 { "1 is".to_string() } else { format!("{len} are") };
            return Err(format!("{what}: {kind} {index} does not exist ({have} defined)"));
        }
        Ok(())
    };
    let (accessors, views, nodes) = (root.accessors.len(), root.buffer_views.len(), root.nodes.len());
    if let Some(s) = root.scene {
        check("the default scene".into(), s.value(), root.scenes.len(), "scene")?;
    }
    for (i, scene) in root.scenes.iter().enumerate() {
        for n in &scene.nodes {
            check(format!("scene {i}{}", name_of(&scene.name)), n.value(), nodes, "node")?;
        }
    }
    let lights = root.extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref()).map_or(0, |l| l.lights.len());
    for (i, node) in root.nodes.iter().enumerate() {
        let label = || format!("node {i}{}", name_of(&node.name));
        for c in node.children.iter().flatten() {
            check(label(), c.value(), nodes, "child node")?;
        }
        if let Some(m) = node.mesh {
            check(label(), m.value(), root.meshes.len(), "mesh")?;
        }
        if let Some(s) = node.skin {
            check(label(), s.value(), root.skins.len(), "skin")?;
        }
        if let Some(c) = node.camera {
            check(label(), c.value(), root.cameras.len(), "camera")?;
        }
        if let Some(l) = node.extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref()) {
            check(label(), l.light.value(), lights, "KHR_lights_punctual light")?;
        }
    }
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, prim) in mesh.primitives.iter().enumerate() {
            let label = || format!("mesh {m}{} primitive {p}", name_of(&mesh.name));
            for (semantic, acc) in &prim.attributes {
                let what = match semantic {
                    Checked::Valid(s) => format!("{} accessor", s.to_string()),
                    Checked::Invalid => "attribute accessor".into(),
                };
                check(label(), acc.value(), accessors, &what)?;
            }
            if let Some(acc) = prim.indices {
                check(label(), acc.value(), accessors, "indices accessor")?;
            }
            if let Some(mat) = prim.material {
                check(label(), mat.value(), root.materials.len(), "material")?;
            }
            for target in prim.targets.iter().flatten() {
                for acc in [target.positions, target.normals, target.tangents].into_iter().flatten() {
                    check(label(), acc.value(), accessors, "morph target accessor")?;
                }
            }
        }
    }
    for (i, mat) in root.materials.iter().enumerate() {
        let pbr = &mat.pbr_metallic_roughness;
        let textures = [
            pbr.base_color_texture.as_ref().map(|t| t.index),
            pbr.metallic_roughness_texture.as_ref().map(|t| t.index),
            mat.normal_texture.as_ref().map(|t| t.index),
            mat.occlusion_texture.as_ref().map(|t| t.index),
            mat.emissive_texture.as_ref().map(|t| t.index),
        ];
        for t in textures.into_iter().flatten() {
            check(format!("material {i}{}", name_of(&mat.name)), t.value(), root.textures.len(), "texture")?;
        }
    }
    for (i, tex) in root.textures.iter().enumerate() {
        check(format!("texture {i}"), tex.source.value(), root.images.len(), "image")?;
        if let Some(s) = tex.sampler {
            check(format!("texture {i}"), s.value(), root.samplers.len(), "sampler")?;
        }
    }
    for (i, image) in root.images.iter().enumerate() {
        if let Some(v) = image.buffer_view {
            check(format!("image {i}"), v.value(), views, "buffer view")?;
        }
    }
    for (i, skin) in root.skins.iter().enumerate() {
        let label = || format!("skin {i}{}", name_of(&skin.name));
        for j in &skin.joints {
            check(label(), j.value(), nodes, "joint node")?;
        }
        if let Some(s) = skin.skeleton {
            check(label(), s.value(), nodes, "skeleton node")?;
        }
        if let Some(acc) = skin.inverse_bind_matrices {
            check(label(), acc.value(), accessors, "inverseBindMatrices accessor")?;
        }
    }
    for (a, anim) in root.animations.iter().enumerate() {
        let label = format!("animation {a}{}", name_of(&anim.name));
        for (k, s) in anim.samplers.iter().enumerate() {
            check(format!("{label} sampler {k}"), s.input.value(), accessors, "input accessor")?;
            check(format!("{label} sampler {k}"), s.output.value(), accessors, "output accessor")?;
        }
        for (c, ch) in anim.channels.iter().enumerate() {
            check(format!("{label} channel {c}"), ch.sampler.value(), anim.samplers.len(), "sampler")?;
            check(format!("{label} channel {c}"), ch.target.node.value(), nodes, "target node")?;
        }
    }
    for (i, acc) in root.accessors.iter().enumerate() {
        if let Some(v) = acc.buffer_view {
            check(format!("accessor {i}"), v.value(), views, "buffer view")?;
        }
        if let Some(sparse) = &acc.sparse {
            check(format!("accessor {i} sparse indices"), sparse.indices.buffer_view.value(), views, "buffer view")?;
            check(format!("accessor {i} sparse values"), sparse.values.buffer_view.value(), views, "buffer view")?;
        }
    }
    for (i, view) in root.buffer_views.iter().enumerate() {
        check(format!("buffer view {i}"), view.buffer.value(), root.buffers.len(), "buffer")?;
    }
    // The crate's wrappers also assume that a camera or light has the parameters of its type.
    for (i, camera) in root.cameras.iter().enumerate() {
        let has = match camera.type_ {
            Checked::Valid(json::camera::Type::Perspective) => camera.perspective.is_some(),
            Checked::Valid(json::camera::Type::Orthographic) => camera.orthographic.is_some(),
            Checked::Invalid => true,
        };
        if !has {
            return Err(format!("camera {i}{}: the parameters of its type are missing", name_of(&camera.name)));
        }
    }
    let lights = root.extensions.as_ref().and_then(|e| e.khr_lights_punctual.as_ref());
    for (i, light) in lights.iter().flat_map(|l| l.lights.iter()).enumerate() {
        use json::extensions::scene::khr_lights_punctual::Type as Kind;
        if light.type_ == Checked::Valid(Kind::Spot) && light.spot.is_none() {
            return Err(format!("KHR_lights_punctual light {i}{}: a spot light without 'spot'", name_of(&light.name)));
        }
    }
    Ok(())
}

/// The gltf crate's own validation (run after [`references`], which it relies on), with the
/// first problem as one line.
pub fn rules(root: &Root) -> Result<(), String> {
    let mut errors: Vec<(json::Path, json::validation::Error)> = Vec::new();
    root.validate(root, json::Path::new, &mut |path, error| errors.push((path(), error)));
    match errors.first() {
        None => Ok(()),
        Some((path, error)) => {
            let more = match errors.len() - 1 {
                0 => String::new(),
                n => format!(" (and {n} more problems)"),
            };
            Err(format!("{path}: {}{more}", error.to_string().to_lowercase()))
        }
    }
}

fn component_size(c: ComponentType) -> u64 {
    match c {
        ComponentType::I8 | ComponentType::U8 => 1,
        ComponentType::I16 | ComponentType::U16 => 2,
        ComponentType::U32 | ComponentType::F32 => 4,
    }
}

fn components(t: Type) -> u64 {
    match t {
        Type::Scalar => 1,
        Type::Vec2 => 2,
        Type::Vec3 => 3,
        Type::Vec4 | Type::Mat2 => 4,
        Type::Mat3 => 9,
        Type::Mat4 => 16,
    }
}

/// Checks that `count` elements of `elem` bytes, `stride` apart from `offset`, fit in
/// `view_len` bytes; `what` names the element in messages.
fn fits(
    what: &str,
    view: usize,
    view_len: u64,
    offset: u64,
    stride: Option<u64>,
    elem: u64,
    count: u64,
) -> Result<(), String> {
    let stride = stride.unwrap_or(elem);
    if stride < elem {
        return Err(format!("{what}: byteStride {stride} is smaller than its {elem}-byte element"));
    }
    let need = u128::from(offset) + u128::from(stride) * u128::from(count.saturating_sub(1)) + u128::from(elem);
    if need > u128::from(view_len) {
        return Err(format!(
            "{what}: {count} elements of {elem} bytes (stride {stride}, offset {offset}) need {need} bytes, \
             but buffer view {view} holds {view_len}"
        ));
    }
    Ok(())
}

/// Checks every buffer view against its buffer and every accessor against its buffer view,
/// given the byte length of each loaded buffer.
pub fn data(root: &Root, buffer_lens: &[usize], uses: &[Option<String>]) -> Result<(), String> {
    for (i, view) in root.buffer_views.iter().enumerate() {
        let b = view.buffer.value();
        let have = buffer_lens.get(b).copied().unwrap_or(0) as u64;
        let declared = root.buffers.get(b).map_or(0, |b| b.byte_length.0).min(have);
        let end = u128::from(view.byte_offset.map_or(0, |o| o.0)) + u128::from(view.byte_length.0);
        if end > u128::from(declared) {
            return Err(format!("buffer view {i}: bytes up to {end} lie outside buffer {b} ({declared} bytes)"));
        }
        if let Some(s) = view.byte_stride
            && !(4..=252).contains(&s.0)
        {
            return Err(format!("buffer view {i}: byteStride {} is outside 4..=252", s.0));
        }
    }
    let view_len = |v: usize| root.buffer_views.get(v).map_or(0, |v| v.byte_length.0);
    let view_stride = |v: usize| root.buffer_views.get(v).and_then(|v| v.byte_stride).map(|s| s.0 as u64);
    let buffer_bytes: u64 = buffer_lens.iter().map(|&l| l as u64).sum();
    for (i, acc) in root.accessors.iter().enumerate() {
        let label = accessor_label(i, uses);
        let (Checked::Valid(ct), Checked::Valid(ty)) = (&acc.component_type, &acc.type_) else {
            return Err(format!("{label}: unknown componentType or type"));
        };
        let elem = component_size(ct.0) * components(*ty);
        let count = acc.count.0;
        if count == 0 {
            return Err(format!("{label}: count is 0"));
        }
        match acc.buffer_view {
            Some(v) => {
                let offset = acc.byte_offset.map_or(0, |o| o.0);
                fits(&label, v.value(), view_len(v.value()), offset, view_stride(v.value()), elem, count)?;
            }
            None => {
                let bytes = u128::from(count) * u128::from(elem);
                let limit = zero_fill_limit(buffer_bytes);
                if acc.sparse.is_some() && bytes > u128::from(limit) {
                    return Err(format!(
                        "{label}: {count} elements without a buffer view would take {bytes} bytes, \
                         more than the file's buffers hold (limit {limit})"
                    ));
                }
            }
        }
        if let Some(sparse) = &acc.sparse {
            let sc = sparse.count.0;
            if sc == 0 || sc > count {
                return Err(format!("{label}: sparse count {sc} must be between 1 and the accessor's count {count}"));
            }
            let Checked::Valid(it) = &sparse.indices.component_type else {
                return Err(format!("{label}: unknown sparse index componentType"));
            };
            if !matches!(it.0, ComponentType::U8 | ComponentType::U16 | ComponentType::U32) {
                return Err(format!("{label}: sparse indices must be unsigned integers"));
            }
            let (iv, vv) = (sparse.indices.buffer_view.value(), sparse.values.buffer_view.value());
            let what = format!("{label} sparse indices");
            fits(&what, iv, view_len(iv), sparse.indices.byte_offset.0, view_stride(iv), component_size(it.0), sc)?;
            let what = format!("{label} sparse values");
            fits(&what, vv, view_len(vv), sparse.values.byte_offset.0, view_stride(vv), elem, sc)?;
        }
    }
    Ok(())
}
