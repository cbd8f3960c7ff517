//! Split-sample stills: the sample indices of one image cut into ranges rendered apart (on
//! several machines, say), each saved as a *partial*, then merged into the image a single
//! render makes.
//!
//! A partial renders the samples `first..end` of a render of `spp` samples per pixel (global
//! indices, through [`crate::resources::RenderSettings::first_sample`] and
//! [`crate::resources::RenderSettings::end_sample`]) in
//! frames of `spf` samples, and keeps every frame's per-pixel f32 sums as they left the trace,
//! untouched. [`merge`] adds those frames in global sample order into f64 sums, exactly as
//! the accumulation of a single render does, then resolves them as every frame does. So the
//! merged image equals, bit for bit, the single render with the same `spf`, provided every
//! range boundary falls on a frame boundary of that render (a multiple of `spf`, or `spp`).
//!
//! # File layout
//!
//! A partial is a single-part OpenEXR file (lossless ZIP compression) with, for frame `j` of
//! the partial (in sample order), the f32 channels `fJJJJ.R`, `fJJJJ.G`, `fJJJJ.B` holding the
//! frame's sum of radiance samples per pixel, a u32 channel `count` with the samples each pixel
//! holds, and a text attribute `hemiPartial`: the JSON of [`PartialInfo`] (what it was rendered
//! from, the range, and the samples of each frame).

use std::{collections::BTreeMap, io::Cursor, path::Path};

use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image as ExrImage, Layer, LayerAttributes,
    ReadChannels, ReadLayers, SmallVec, Text, WritableImage,
};
use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::{
    Renderer,
    error::HemiError,
    film::OutputFile,
    resources::{Accumulation, FrameSamples, Image},
};

/// The EXR attribute holding a partial's [`PartialInfo`] as JSON.
pub const ATTRIBUTE: &str = "hemiPartial";

/// The key of [`PartialInfo::settings`] that holds every render setting at once, compared
/// after the single ones (so that a mismatch names the single setting where it can).
pub const ALL_SETTINGS: &str = "all settings";

/// What a partial was rendered from, and which samples it holds.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartialInfo {
    /// Version of hemi that rendered it.
    pub hemi_version: String,
    /// The scene file as given on the command line (`default` for the built-in scene).
    pub scene: String,
    /// FNV-1a 64-bit hash of the scene file's bytes, in hex (empty for the built-in scene).
    pub scene_hash: String,
    /// Everything else the image depends on (size, seed, sampler, time, camera, …): partials
    /// merge only when these are equal.
    pub settings: BTreeMap<String, serde_json::Value>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel of the whole render.
    pub spp: u32,
    /// Samples per frame.
    pub spf: u32,
    /// Global index of the first sample held.
    pub first: u32,
    /// Global index past the last sample held.
    pub end: u32,
    /// Samples per pixel of each frame, in order (filled in by [`render`]).
    pub frames: Vec<u32>,
}

/// A partial in memory: its description, each frame's per-pixel sums, and per-pixel counts.
#[derive(Clone, Debug, PartialEq)]
pub struct Partial {
    /// What it was rendered from.
    pub info: PartialInfo,
    /// Per frame, in sample order: the frame's f32 sum of samples per pixel, row-major.
    pub frames: Vec<Vec<Vec3>>,
    /// Samples per pixel held.
    pub counts: Vec<u32>,
}

/// FNV-1a, 64 bits: a file's identity in a partial (not a cryptographic hash).
pub fn fnv1a64(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3))
}

/// The hex FNV-1a hash of the file at `path`.
pub fn file_hash(path: &Path) -> Result<String, HemiError> {
    let bytes = std::fs::read(path)
        .map_err(|e| HemiError::Io { path: path.to_path_buf(), message: format!("cannot read: {e}") })?;
    Ok(format!("{:016x}", fnv1a64(&bytes)))
}

/// The samples `first..end` of part `k` of `n` of a render of `spp` samples in frames of
/// `spf`: whole frames, shared out as evenly as they go, so that every boundary is a frame
/// boundary of the single render with that `spf`. `None` when there are fewer frames than
/// parts.
pub fn part_range(spp: u32, spf: u32, k: u32, n: u32) -> Option<(u32, u32)> {
    let frames = u64::from(spp.div_ceil(spf.max(1)));
    if n == 0 || k >= n || frames < u64::from(n) {
        return None;
    }
    let edge = |i: u64| ((frames * i / u64::from(n)) * u64::from(spf)).min(u64::from(spp)) as u32;
    Some((edge(u64::from(k)), edge(u64::from(k) + 1)))
}

/// Samples per frame a partial of `parts` parts uses unless told: one frame per part where
/// that stays at most [`crate::resources::RenderSettings::ONE_FRAME_SPP`].
pub fn default_spf(spp: u32, parts: u32) -> u32 {
    spp.div_ceil(parts.max(1)).clamp(1, crate::resources::RenderSettings::ONE_FRAME_SPP)
}

/// Renders the samples `info.first..info.end` of the renderer's scene in frames of
/// `info.spf`, keeping every frame's sums; `on_frame` sees each frame's statistics.
pub fn render(
    renderer: &mut Renderer,
    mut info: PartialInfo,
    mut on_frame: impl FnMut(&crate::stats::FrameStats),
) -> Result<Partial, HemiError> {
    {
        let mut s = renderer.settings_mut();
        s.max_spp = Some(info.spp);
        s.first_sample = info.first;
        s.end_sample = Some(info.end);
        s.samples_per_frame = info.spf;
        s.validate().map_err(HemiError::Usage)?;
    }
    renderer.world_mut().resource_mut::<FrameSamples>().keep_sums = true;
    let mut frames = Vec::new();
    info.frames.clear();
    loop {
        let stats = renderer.run_frame()?;
        on_frame(stats);
        let samples = renderer.world().resource::<FrameSamples>();
        if samples.samples_per_pixel > 0 {
            info.frames.push(samples.samples_per_pixel);
            frames.push(samples.sums.clone());
        }
        if renderer.converged() {
            break;
        }
    }
    let acc = renderer.world().resource::<Accumulation>();
    let counts = (0..acc.sums.len()).map(|i| acc.count(i)).collect();
    Ok(Partial { info, frames, counts })
}

impl Partial {
    /// Encodes the partial as EXR bytes (see the module's file layout).
    pub fn to_exr(&self) -> Result<Vec<u8>, String> {
        let (w, h) = (self.info.width as usize, self.info.height as usize);
        let json = ascii_json(&serde_json::to_string(&self.info).map_err(|e| e.to_string())?);
        let mut list = Vec::with_capacity(self.frames.len() * 3 + 1);
        for (j, sums) in self.frames.iter().enumerate() {
            for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
                let values: Vec<f32> = sums.iter().map(|p| p[c]).collect();
                list.push(AnyChannel::new(format!("f{j:04}.{name}").as_str(), FlatSamples::F32(values)));
            }
        }
        list.push(AnyChannel::new("count", FlatSamples::U32(self.counts.clone())));
        let mut attributes = LayerAttributes::named("partial");
        let text = Text::new_or_none(&json).ok_or("metadata is not ASCII")?;
        attributes.other.insert(Text::from(ATTRIBUTE), AttributeValue::Text(text));
        let layer =
            Layer::new((w, h), attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(SmallVec::from_vec(list)));
        let mut out = Cursor::new(Vec::new());
        ExrImage::from_layer(layer).write().to_buffered(&mut out).map_err(|e| e.to_string())?;
        Ok(out.into_inner())
    }

    /// Writes the partial to `path` (atomically, as every output).
    pub fn save(&self, path: &Path) -> Result<(), HemiError> {
        let file = OutputFile::create_any(path)?;
        let bytes = self
            .to_exr()
            .map_err(|e| HemiError::Io { path: path.to_path_buf(), message: format!("cannot encode: {e}") })?;
        file.write_bytes(&bytes)
    }

    /// Reads a partial written by [`Partial::save`]; every failure names the file.
    pub fn load(path: &Path) -> Result<Self, HemiError> {
        let err = |m: String| HemiError::Io { path: path.to_path_buf(), message: m };
        let image = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_file(path)
            .map_err(|e| err(format!("cannot read partial: {e}")))?;
        let layer = &image.layer_data;
        let text = match layer.attributes.other.get(&Text::from(ATTRIBUTE)) {
            Some(AttributeValue::Text(t)) => t.to_string(),
            _ => return Err(err(format!("not a hemi partial (no {ATTRIBUTE} attribute)"))),
        };
        let info: PartialInfo =
            serde_json::from_str(&text).map_err(|e| err(format!("unreadable partial metadata: {e}")))?;
        let (w, h) = (layer.size.0, layer.size.1);
        if (w, h) != (info.width as usize, info.height as usize) {
            return Err(err(format!("image is {w}x{h}, its metadata says {}x{}", info.width, info.height)));
        }
        let channel = |name: &str| layer.channel_data.list.iter().find(|c| c.name == *name);
        let f32s = |name: &str| match channel(name).map(|c| &c.sample_data) {
            Some(FlatSamples::F32(v)) => Ok(v),
            _ => Err(err(format!("missing f32 channel {name}"))),
        };
        let mut frames = Vec::with_capacity(info.frames.len());
        for j in 0..info.frames.len() {
            let (r, g, b) = (f32s(&format!("f{j:04}.R"))?, f32s(&format!("f{j:04}.G"))?, f32s(&format!("f{j:04}.B"))?);
            frames.push((0..w * h).map(|i| Vec3::new(r[i], g[i], b[i])).collect());
        }
        let counts = match channel("count").map(|c| &c.sample_data) {
            Some(FlatSamples::U32(v)) => v.clone(),
            _ => return Err(err("missing u32 channel count".into())),
        };
        let held: u64 = info.frames.iter().map(|&n| u64::from(n)).sum();
        if info.end <= info.first || held != u64::from(info.end - info.first) || counts.iter().any(|&c| c > info.end) {
            return Err(err(format!(
                "inconsistent partial: samples {}..{} but frames of {:?}",
                info.first, info.end, info.frames
            )));
        }
        Ok(Partial { info, frames, counts })
    }
}

/// JSON with every non-ASCII character escaped (EXR text attributes are 8-bit).
fn ascii_json(json: &str) -> String {
    let mut out = String::with_capacity(json.len());
    for c in json.chars() {
        if c.is_ascii() {
            out.push(c);
        } else {
            let mut units = [0u16; 2];
            for u in c.encode_utf16(&mut units) {
                out.push_str(&format!("\\u{u:04x}"));
            }
        }
    }
    out
}

/// Sums a set of partials, named by their files, into the accumulation a single render makes
/// and resolves it. Refuses, with one line naming the files, partials from different scenes,
/// settings or versions, overlapping ranges, and ranges that leave samples out.
pub fn merge(parts: &[(std::path::PathBuf, Partial)]) -> Result<Image, HemiError> {
    let usage = HemiError::Usage;
    let Some((first_path, first)) = parts.first() else {
        return Err(usage("no partials to merge".into()));
    };
    let name = |p: &Path| p.display().to_string();
    for (path, part) in &parts[1..] {
        let (a, b) = (&first.info, &part.info);
        let differs = |what: &str, x: String, y: String| {
            usage(format!(
                "{} was rendered with {what} {y}, {} with {what} {x}: partials of different renders cannot be merged",
                name(path),
                name(first_path)
            ))
        };
        if a.scene_hash != b.scene_hash {
            return Err(differs(
                "scene",
                format!("{} (hash {})", a.scene, a.scene_hash),
                format!("{} (hash {})", b.scene, b.scene_hash),
            ));
        }
        if a.hemi_version != b.hemi_version {
            return Err(differs("hemi", a.hemi_version.clone(), b.hemi_version.clone()));
        }
        for (what, x, y) in [("size", (a.width, a.height), (b.width, b.height))] {
            if x != y {
                return Err(differs(what, format!("{}x{}", x.0, x.1), format!("{}x{}", y.0, y.1)));
            }
        }
        for (what, x, y) in [("spp", a.spp, b.spp), ("spf", a.spf, b.spf)] {
            if x != y {
                return Err(differs(what, x.to_string(), y.to_string()));
            }
        }
        // Single settings first, the catch-all `all settings` (when present) last.
        let mut keys: Vec<&String> = a.settings.keys().chain(b.settings.keys()).collect();
        keys.sort_by_key(|k| (k.as_str() == ALL_SETTINGS, k.as_str()));
        keys.dedup();
        for key in keys {
            let (x, y) = (a.settings.get(key), b.settings.get(key));
            if x != y {
                let show = |v: Option<&serde_json::Value>| v.map_or("(none)".to_string(), |v| v.to_string());
                return Err(differs(key, show(x), show(y)));
            }
        }
    }
    let mut order: Vec<&(std::path::PathBuf, Partial)> = parts.iter().collect();
    order.sort_by_key(|(_, p)| (p.info.first, p.info.end));
    let spp = first.info.spp;
    let mut covered = 0;
    let mut previous: Option<&Path> = None;
    for (path, part) in &order {
        let (start, end) = (part.info.first, part.info.end);
        if start < covered {
            let other = previous.map_or(String::new(), name);
            return Err(usage(format!(
                "{} (samples {start}..{end}) overlaps {other} (samples ..{covered})",
                name(path)
            )));
        }
        if start > covered {
            return Err(usage(format!("missing partial: no file holds samples {covered}..{start} of {spp}")));
        }
        covered = end;
        previous = Some(path);
    }
    if covered != spp {
        return Err(usage(format!("missing partial: no file holds samples {covered}..{spp} of {spp}")));
    }

    let (w, h) = (first.info.width, first.info.height);
    let mut acc = Accumulation::default();
    acc.reset(w, h, Default::default());
    // Per-pixel counts, as the parts hold them.
    acc.counts.resize(acc.sums.len(), 0);
    for (path, part) in order {
        if part.counts.len() != acc.counts.len() || part.frames.iter().any(|f| f.len() != acc.counts.len()) {
            return Err(HemiError::Io {
                path: path.clone(),
                message: "pixel data does not match the image size".into(),
            });
        }
        // Frame by frame in sample order, each added as the accumulate system adds a frame.
        for (frame, &n) in part.frames.iter().zip(&part.info.frames) {
            for (sum, add) in acc.sums.frames_mut().iter_mut().zip(frame) {
                *sum += add.as_dvec3();
            }
            acc.spp += n;
        }
        for (count, n) in acc.counts.iter_mut().zip(&part.counts) {
            *count += n;
        }
    }
    let mut image = Image::default();
    crate::systems::resolve::resolve_into(&acc, &mut image);
    Ok(image)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::resources::RenderSettings;

    const SPP: u32 = 12;
    const SPF: u32 = 3;

    fn settings() -> RenderSettings {
        RenderSettings { width: 20, height: 12, samples_per_frame: SPF, samples_per_set: SPP, ..Default::default() }
    }

    fn info(first: u32, end: u32) -> PartialInfo {
        PartialInfo {
            hemi_version: "test".into(),
            scene: "default".into(),
            scene_hash: String::new(),
            settings: BTreeMap::from([("seed".to_string(), serde_json::json!(0))]),
            width: 20,
            height: 12,
            spp: SPP,
            spf: SPF,
            first,
            end,
            frames: vec![],
        }
    }

    fn part(first: u32, end: u32) -> (std::path::PathBuf, Partial) {
        let mut r = Renderer::with_default_scene(settings());
        let p = render(&mut r, info(first, end), |_| {}).unwrap();
        (format!("part_{first}_{end}.exr").into(), p)
    }

    #[test]
    fn parts_merge_into_the_single_render_bit_for_bit() {
        let mut whole = Renderer::with_default_scene(settings());
        whole.render(SPP).unwrap();
        // Ranges on frame boundaries, in any order, through the file format.
        let dir = tempfile::tempdir().unwrap();
        let mut parts = Vec::new();
        for (a, b) in [(6, 12), (0, 3), (3, 6)] {
            let (name, p) = part(a, b);
            let path = dir.path().join(name);
            p.save(&path).unwrap();
            let back = Partial::load(&path).unwrap();
            assert_eq!(back, p);
            parts.push((path, back));
        }
        let merged = merge(&parts).unwrap();
        assert_eq!(merged.linear, whole.image().linear);
        assert_eq!(merged.srgb8(), whole.image().srgb8());
        // A part holds other samples than the whole: its image differs.
        assert_eq!(merge(&[part(0, SPP)]).unwrap().linear, whole.image().linear);
        assert_ne!(parts[0].1.frames[0], parts[1].1.frames[0]);
    }

    #[test]
    fn part_ranges_fall_on_frame_boundaries() {
        assert_eq!(part_range(4096, 1024, 1, 4), Some((1024, 2048)));
        assert_eq!(part_range(100, 34, 2, 3), Some((68, 100)));
        assert_eq!(part_range(10, 3, 0, 2), Some((0, 6)));
        assert_eq!(part_range(10, 3, 1, 2), Some((6, 10)));
        assert_eq!(part_range(8, 4, 0, 3), None);
        assert_eq!(default_spf(4096, 4), 1024);
        assert_eq!(default_spf(100, 3), 34);
        assert_eq!(default_spf(1 << 20, 2), 4096);
    }

    #[test]
    fn merge_refuses_gaps_overlaps_and_other_renders() {
        let (a, b, c) = (part(0, 6), part(6, 12), part(3, 9));
        let message = |parts: &[(std::path::PathBuf, Partial)]| merge(parts).unwrap_err().to_string();
        let m = message(std::slice::from_ref(&a));
        assert!(m.contains("missing partial") && m.contains("6..12"), "{m}");
        let m = message(std::slice::from_ref(&b));
        assert!(m.contains("missing partial") && m.contains("0..6"), "{m}");
        let m = message(&[a.clone(), c.clone(), b.clone()]);
        assert!(m.contains("overlaps") && m.contains("part_3_9.exr"), "{m}");
        let mut other = b.clone();
        other.1.info.settings.insert("seed".into(), serde_json::json!(7));
        let m = message(&[a.clone(), other]);
        assert!(m.contains("seed 7") && m.contains("part_6_12.exr"), "{m}");
        let mut other = b.clone();
        other.1.info.scene_hash = "0123".into();
        assert!(message(&[a.clone(), other]).contains("scene"));
        let mut other = b.clone();
        other.1.info.width = 21;
        assert!(message(&[a.clone(), other]).contains("size 21x12"));
        for m in [message(&[]), message(&[a.clone(), c])] {
            assert_eq!(m.lines().count(), 1, "{m}");
        }
    }

    #[test]
    fn unreadable_partials_name_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("broken.exr");
        std::fs::write(&path, b"not an exr").unwrap();
        let m = Partial::load(&path).unwrap_err().to_string();
        assert!(m.contains("broken.exr") && m.lines().count() == 1, "{m}");
        // A plain EXR image is not a partial.
        let image = Image { width: 1, height: 1, linear: vec![Vec3::ONE], aovs: vec![] };
        crate::film::save(&image, &path).unwrap();
        let m = Partial::load(&path).unwrap_err().to_string();
        assert!(m.contains("not a hemi partial"), "{m}");
    }
}
