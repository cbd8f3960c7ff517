//! A primitive's varying surface: the base-colour texture (its image decoded with the `image`
//! crate, PNG or JPEG, its sampler and `KHR_texture_transform`), `TEXCOORD_n`, `COLOR_0` and
//! the material's alpha mode. Images come from buffer views or URIs, under the same rules as
//! buffers (inside the model's folder unless allowed), and their decoded size is charged to
//! the file's read budget and capped per image. An image that is missing or fails to decode is
//! one warning naming the texture, its image and the material; the factor is used instead.

use std::{
    collections::{HashMap, HashSet},
    io::Cursor,
    path::Path,
};

use ::gltf::{
    Document,
    accessor::{DataType, Dimensions},
    material::AlphaMode as GltfAlphaMode,
    mesh::Semantic,
    texture::{MagFilter, MinFilter, WrappingMode},
};
use glam::{Vec2, Vec4};

use super::{accessors, buffers, label};
use crate::material::{
    AlphaMode, BaseColorTexture, Filter, Sampler, Surface, SurfaceAttributes, Texture, TextureTransform, Wrap,
};

/// The largest image side hemi decodes, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 16384;

/// The most bytes one image's decoder may allocate (the `image` crate's own default).
pub const MAX_IMAGE_BYTES: u64 = 512 << 20;

/// What reading the file's textures needs, and the textures read so far.
pub(super) struct Textures<'a> {
    doc: &'a Document,
    buffers: &'a accessors::Data,
    base: &'a Path,
    options: &'a buffers::LoadOptions,
    /// Each glTF texture read so far (by index): the texture, or why it could not be read.
    read: HashMap<usize, Result<std::sync::Arc<Texture>, String>>,
    /// Materials whose texture failed, warned about once each.
    warned: HashSet<usize>,
}

impl<'a> Textures<'a> {
    pub(super) fn new(
        doc: &'a Document,
        buffers: &'a accessors::Data,
        base: &'a Path,
        options: &'a buffers::LoadOptions,
    ) -> Self {
        Textures { doc, buffers, base, options, read: HashMap::new(), warned: HashSet::new() }
    }

    /// The surface of primitive `p`, or `None` when it has nothing that varies (no usable
    /// texture, no vertex colours) and no alpha that can let a ray through: such a primitive
    /// renders as a plain `Matte` mesh, exactly as before textures were read. Always `None`
    /// for a file read for its geometry alone ([`buffers::LoadOptions::geometry_only`]).
    pub(super) fn surface(
        &mut self,
        p: &::gltf::Primitive,
        vertices: usize,
        warnings: &mut Vec<String>,
    ) -> Result<Option<Surface>, String> {
        if self.options.geometry_only {
            return Ok(None);
        }
        let material = p.material();
        let pbr = material.pbr_metallic_roughness();
        let alpha = pbr.base_color_factor()[3];
        let alpha_mode = match material.alpha_mode() {
            GltfAlphaMode::Opaque => AlphaMode::Opaque,
            GltfAlphaMode::Mask => AlphaMode::Mask { cutoff: material.alpha_cutoff().unwrap_or(0.5) },
            GltfAlphaMode::Blend => AlphaMode::Blend,
        };
        if !alpha.is_finite() || matches!(alpha_mode, AlphaMode::Mask { cutoff } if !cutoff.is_finite()) {
            return Err("the material's alpha factor or cutoff is not finite".into());
        }
        let mut attributes = SurfaceAttributes::default();
        let mut base_color = None;
        if let Some(info) = pbr.base_color_texture() {
            let transform = info.texture_transform();
            let set = transform.as_ref().and_then(|t| t.tex_coord()).unwrap_or(info.tex_coord()) as usize;
            let transform = transform.map_or(TextureTransform::default(), |t| TextureTransform {
                offset: Vec2::from(t.offset()),
                rotation: t.rotation(),
                scale: Vec2::from(t.scale()),
            });
            if !(transform.offset.is_finite() && transform.rotation.is_finite() && transform.scale.is_finite()) {
                return Err("KHR_texture_transform has a non-finite value".into());
            }
            let texture = self.texture(info.texture().index(), material.index(), material.name(), warnings);
            match (texture, p.get(&Semantic::TexCoords(set as u32))) {
                (Some(texture), Some(acc)) => {
                    let uvs = tex_coords(&acc, self.buffers).map_err(|e| format!("TEXCOORD_{set} {e}"))?;
                    if uvs.len() != vertices {
                        return Err(format!("TEXCOORD_{set} has {} entries for {vertices} vertices", uvs.len()));
                    }
                    attributes.tex_coords = vec![Vec::new(); set];
                    attributes.tex_coords.push(uvs);
                    base_color = Some(BaseColorTexture { texture, tex_coord: set, transform });
                }
                (Some(_), None) => warnings.push(format!(
                    "{}: the base-colour texture reads TEXCOORD_{set}, which the primitive lacks; the factor is used",
                    label("material", material.index().unwrap_or(0), material.name())
                )),
                (None, _) => {}
            }
        }
        if let Some(acc) = p.get(&Semantic::Colors(0)) {
            let colors = colors(&acc, self.buffers).map_err(|e| format!("COLOR_0 {e}"))?;
            if colors.len() != vertices {
                return Err(format!("COLOR_0 has {} entries for {vertices} vertices", colors.len()));
            }
            attributes.colors = Some(colors);
        }
        let varies = base_color.is_some() || attributes.colors.is_some();
        let surface = Surface { attributes: attributes.into(), base_color, alpha, alpha_mode };
        // A constant alpha that keeps every ray (a mask it passes, a blend of 1) is opaque.
        let constant_opaque = match alpha_mode {
            AlphaMode::Opaque => true,
            AlphaMode::Mask { cutoff } => alpha >= cutoff,
            AlphaMode::Blend => alpha >= 1.0,
        };
        Ok((varies || !constant_opaque).then_some(surface))
    }

    /// The glTF texture `index` decoded with its sampler (once per file), or `None` after a
    /// warning naming it, its image and material `material` (once per material).
    fn texture(
        &mut self,
        index: usize,
        material: Option<usize>,
        material_name: Option<&str>,
        warnings: &mut Vec<String>,
    ) -> Option<std::sync::Arc<Texture>> {
        let doc = self.doc;
        let texture = doc.textures().nth(index)?;
        let image = texture.source();
        let result = match self.read.get(&index) {
            Some(done) => done.clone(),
            None => {
                let decoded = self.decode(image.index()).and_then(|(w, h, texels)| {
                    let texture = Texture::new(w, h, texels, sampler(&texture.sampler()));
                    texture.map(std::sync::Arc::new).ok_or_else(|| "the image is empty".to_string())
                });
                self.read.insert(index, decoded.clone());
                decoded
            }
        };
        match result {
            Ok(t) => Some(t),
            Err(why) => {
                let m = material.unwrap_or(usize::MAX);
                if self.warned.insert(m) {
                    let image_name = image.name().map(str::to_string).or_else(|| uri_of(doc, image.index()));
                    let what = match material {
                        Some(i) => label("material", i, material_name),
                        None => "the default material".into(),
                    };
                    warnings.push(format!(
                        "{} ({}) of {what}: {}; the base colour factor is used",
                        label("texture", index, texture.name()),
                        label("image", image.index(), image_name.as_deref()),
                        why
                    ));
                }
                None
            }
        }
    }

    /// Image `index` decoded to RGBA8 (PNG or JPEG), within [`MAX_IMAGE_SIDE`],
    /// [`MAX_IMAGE_BYTES`] and the file's read budget.
    fn decode(&self, index: usize) -> Result<(u32, u32, Vec<[u8; 4]>), String> {
        let json = &self.doc.as_json().images[index];
        let bytes: Vec<u8> = match (&json.buffer_view, &json.uri) {
            (Some(view), _) => {
                let view = &self.doc.as_json().buffer_views[view.value()];
                let buffer = self.buffers.buffers.get(view.buffer.value()).ok_or("its buffer is missing")?;
                let start = view.byte_offset.map_or(0, |o| o.0) as usize;
                let range = start..start.saturating_add(view.byte_length.0 as usize);
                buffer.get(range).ok_or("its buffer view lies outside its buffer")?.to_vec()
            }
            (None, Some(uri)) => buffers::read_uri(uri, self.base, self.options)?,
            (None, None) => return Err("the image has neither a uri nor a bufferView".into()),
        };
        let cannot = |e: image::ImageError| format!("cannot decode: {e}");
        let reader = || {
            image::ImageReader::new(Cursor::new(&bytes[..]))
                .with_guessed_format()
                .map_err(|e| format!("cannot decode: {e}"))
        };
        // The header first: the size is checked and charged before any texel is allocated.
        let (w, h) = reader()?.into_dimensions().map_err(cannot)?;
        if w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
            return Err(format!("it is {w}×{h} pixels, more than the limit of {MAX_IMAGE_SIDE} a side"));
        }
        self.buffers.charge(w as usize * h as usize, 8, "decoded image")?;
        let mut limits = image::Limits::default();
        limits.max_image_width = Some(MAX_IMAGE_SIDE);
        limits.max_image_height = Some(MAX_IMAGE_SIDE);
        limits.max_alloc = Some(MAX_IMAGE_BYTES);
        let mut decoder = reader()?;
        decoder.limits(limits);
        let image = decoder.decode().map_err(cannot)?.into_rgba8();
        let (w, h) = image.dimensions();
        let texels = image.into_raw().chunks_exact(4).map(|p| [p[0], p[1], p[2], p[3]]).collect();
        Ok((w, h, texels))
    }
}

/// hemi's sampler for a glTF sampler: its wrap modes, and nearest filtering where the
/// magnification filter says so (or, without one, the minification filter does).
fn sampler(s: &::gltf::texture::Sampler) -> Sampler {
    let wrap = |w: WrappingMode| match w {
        WrappingMode::ClampToEdge => Wrap::ClampToEdge,
        WrappingMode::MirroredRepeat => Wrap::MirroredRepeat,
        WrappingMode::Repeat => Wrap::Repeat,
    };
    let nearest = match s.mag_filter() {
        Some(f) => f == MagFilter::Nearest,
        None => matches!(
            s.min_filter(),
            Some(MinFilter::Nearest | MinFilter::NearestMipmapNearest | MinFilter::NearestMipmapLinear)
        ),
    };
    Sampler {
        wrap_u: wrap(s.wrap_s()),
        wrap_v: wrap(s.wrap_t()),
        filter: if nearest { Filter::Nearest } else { Filter::Linear },
    }
}

/// The URI of image `index`, for messages (a `data:` URI is not worth printing).
fn uri_of(doc: &Document, index: usize) -> Option<String> {
    let uri = doc.as_json().images.get(index)?.uri.as_ref()?;
    (!uri.starts_with("data:")).then(|| uri.clone())
}

/// Reads texture coordinates: VEC2 floats or normalized unsigned bytes or shorts.
fn tex_coords(acc: &::gltf::Accessor, data: &accessors::Data) -> Result<Vec<Vec2>, String> {
    accessors::check(acc, Dimensions::Vec2, &[DataType::F32, DataType::U8, DataType::U16])?;
    Ok(match acc.data_type() {
        DataType::U8 => {
            accessors::read::<[u8; 2]>(acc, data)?.into_iter().map(|v| unorm(v.map(f32::from), 255.0)).collect()
        }
        DataType::U16 => {
            accessors::read::<[u16; 2]>(acc, data)?.into_iter().map(|v| unorm(v.map(f32::from), 65535.0)).collect()
        }
        _ => accessors::read::<[f32; 2]>(acc, data)?.into_iter().map(Vec2::from).collect(),
    })
}

fn unorm(v: [f32; 2], max: f32) -> Vec2 {
    Vec2::from(v) / max
}

/// Reads vertex colours: VEC3 or VEC4, floats or normalized unsigned bytes or shorts; a VEC3
/// colour has alpha 1.
fn colors(acc: &::gltf::Accessor, data: &accessors::Data) -> Result<Vec<Vec4>, String> {
    if acc.dimensions() == Dimensions::Vec4 {
        return Ok(accessors::unorm4(acc, data)?.into_iter().map(Vec4::from).collect());
    }
    accessors::check(acc, Dimensions::Vec3, &[DataType::F32, DataType::U8, DataType::U16])?;
    let rgb: Vec<[f32; 3]> = match acc.data_type() {
        DataType::U8 => {
            accessors::read::<[u8; 3]>(acc, data)?.into_iter().map(|v| v.map(|x| x as f32 / 255.0)).collect()
        }
        DataType::U16 => {
            accessors::read::<[u16; 3]>(acc, data)?.into_iter().map(|v| v.map(|x| x as f32 / 65535.0)).collect()
        }
        _ => accessors::read::<[f32; 3]>(acc, data)?,
    };
    Ok(rgb.into_iter().map(|[r, g, b]| Vec4::new(r, g, b, 1.0)).collect())
}
