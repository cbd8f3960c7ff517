//! Resources: render settings and the buffers that carry a frame from tracing to the image.

use bevy_ecs::prelude::Resource;
use bytemuck::Zeroable;
use glam::{DVec3, Vec3};
use rayon::prelude::*;

use crate::{
    geometry::RayEnd,
    sampling::{SampleRuns, SamplerKind},
    srgb::linear_to_srgb8,
};

/// What to render and how.
#[derive(Resource, Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel traced by each frame.
    pub samples_per_frame: u32,
    /// Points per sample set: the stratified unit; samples `k·n .. (k+1)·n` of a pixel form one
    /// whole set. Best equal to the total spp a render aims for.
    pub samples_per_set: u32,
    /// Stop tracing a static scene once every pixel has this many samples (`None`: never stop).
    pub max_spp: Option<u32>,
    /// Global index of the first sample the accumulation takes: a pixel's samples are numbered
    /// from here (0: a whole render). With [`RenderSettings::end_sample`] it renders one part
    /// of a render split by sample index; the parts' sums add up to the whole render's.
    pub first_sample: u32,
    /// Global index at which the accumulation stops, in place of `max_spp` (`None`: at
    /// `max_spp`): the accumulation then holds the samples `first_sample..end_sample`.
    /// `max_spp` stays the whole render's total, which other choices (such as baking shared
    /// meshes) follow, so that every part traces what the whole render would.
    pub end_sample: Option<u32>,
    /// Seed of every random decision.
    pub seed: u64,
    /// Sample pattern.
    pub sampler: SamplerKind,
    /// Edge length of the square tiles traced in parallel.
    pub tile_size: u32,
    /// Radiance of rays that hit nothing (linear RGB).
    pub background: Vec3,
    /// Jitter primary rays inside their pixel (anti-aliasing); `false` shoots them through pixel
    /// centres, as the peer renderers' contract does.
    pub jitter: bool,
    /// Accumulate the AOVs ([`Aov`]) beside the beauty image.
    pub aovs: bool,
    /// Adaptive sampling: a pixel stops being traced once it has at least
    /// [`RenderSettings::ADAPTIVE_MIN_SPP`] samples and the standard error of its mean
    /// luminance is at most this (`None`: every pixel gets every sample).
    pub target_error: Option<f32>,
    /// Least distance (world units) along the surface normal at which shadow and AO rays
    /// start from a hit. 0: just past the hit point's own rounding error, the smallest offset
    /// that is safe at any scale; a peer scene sets its `ao.epsilon`, so that hemi traces the
    /// rays of the peers' contract (`o = p + ε·n`).
    pub ray_offset: f32,
    /// When a frame completes the sample target and the sums hold that one frame (f32, every
    /// pixel at the same count: [`AccumulationLayout::one_frame`], not adaptive), the image takes
    /// their memory: resolve divides them in place instead of filling a second buffer, so a
    /// finished render holds one per-pixel buffer, not two. The accumulation is then spent: the
    /// image stays while nothing changes, and a frame that asks for more samples starts it anew
    /// (raising `max_spp` renders again from the first sample). For renders that end at their
    /// target, as `hemi render` does; the default keeps the sums.
    pub release_sums: bool,
}

impl Default for RenderSettings {
    fn default() -> Self {
        RenderSettings {
            width: 640,
            height: 360,
            samples_per_frame: 4,
            samples_per_set: 16,
            max_spp: None,
            first_sample: 0,
            end_sample: None,
            seed: 0,
            sampler: SamplerKind::default(),
            tile_size: 16,
            background: Vec3::ZERO,
            jitter: true,
            aovs: false,
            target_error: None,
            ray_offset: 0.0,
            release_sums: false,
        }
    }
}

impl RenderSettings {
    /// Samples a pixel takes before adaptive sampling may judge its error.
    pub const ADAPTIVE_MIN_SPP: u32 = 16;

    /// The largest sample set, and frame, that the command line and `hemi compare` make for a
    /// render of a given total: up to this many samples per pixel go in one frame, one pass of
    /// one pattern (one camera ray per pixel under the peers' contract, whole passes for the
    /// occluder's quadrant packets).
    pub const ONE_FRAME_SPP: u32 = 4096;

    /// The most samples per pixel a render may ask for (`--spp`, a peer scene's `ao.samples`).
    pub const MAX_SPP: u32 = 1_000_000;

    /// Largest image hemi accepts, in pixels (8192 × 4096); buffers take 12 to 48 bytes each (192 with AOVs).
    pub const MAX_PIXELS: u64 = 1 << 25;

    /// How this render's runs of samples at a shading point fall on its sample sets' passes:
    /// one sample per point with jittered pixels (each sample its own camera hit); else whole
    /// passes where every frame takes whole passes and every pixel takes every frame's samples
    /// (no adaptive sampling).
    pub fn sample_runs(&self) -> SampleRuns {
        let set = self.samples_per_set.max(1);
        let whole = self.target_error.is_none()
            && self.samples_per_frame.is_multiple_of(set)
            && self.first_sample.is_multiple_of(set);
        match (self.jitter, whole) {
            (true, _) => SampleRuns::OnePerPoint,
            (false, true) => SampleRuns::WholePasses,
            (false, false) => SampleRuns::Partial,
        }
    }

    /// A one-line description of the first unusable setting.
    pub fn validate(&self) -> Result<(), String> {
        if self.width == 0 || self.height == 0 {
            return Err(format!("image size {}x{} is empty", self.width, self.height));
        }
        let pixels = self.width as u64 * self.height as u64;
        if pixels > Self::MAX_PIXELS {
            return Err(format!(
                "image size {}x{} has {pixels} pixels; the limit is {}",
                self.width,
                self.height,
                Self::MAX_PIXELS
            ));
        }
        if self.samples_per_frame == 0 {
            return Err("samples per frame must be at least 1".into());
        }
        if self.samples_per_set == 0 {
            return Err("samples per set must be at least 1".into());
        }
        if let Some(end) = self.end_sample
            && end <= self.first_sample
        {
            return Err(format!("sample range {}..{end} is empty", self.first_sample));
        }
        if (self.first_sample > 0 || self.end_sample.is_some()) && self.target_error.is_some() {
            return Err("a sample range cannot be combined with a target error (adaptive sampling)".into());
        }
        if self.tile_size == 0 {
            return Err("tile size must be at least 1".into());
        }
        if let Some(e) = self.target_error
            && !(e.is_finite() && e > 0.0)
        {
            return Err(format!("target error {e} must be positive and finite"));
        }
        if !self.background.is_finite() || self.background.min_element() < 0.0 {
            return Err(format!("background {} must be finite and non-negative", self.background));
        }
        if !(self.ray_offset.is_finite() && self.ray_offset >= 0.0) {
            return Err(format!("ray offset {} must be finite and non-negative", self.ray_offset));
        }
        Ok(())
    }

    /// Samples per pixel the accumulation aims for: `max_spp`, or `end_sample - first_sample`
    /// for a part of a render (`None`: no target).
    pub fn target_spp(&self) -> Option<u32> {
        self.end_sample.or(self.max_spp).map(|end| end.saturating_sub(self.first_sample))
    }

    /// Number of pixels.
    pub fn pixel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// The buffers an accumulation for these settings keeps.
    pub fn accumulation_layout(&self) -> AccumulationLayout {
        AccumulationLayout {
            one_frame: self.target_spp().is_some_and(|spp| spp <= self.samples_per_frame),
            adaptive: self.target_error.is_some(),
        }
    }
}

/// Arbitrary output variables: per-pixel quantities written beside the beauty image (as
/// `<stem>.<name>.exr`), for comparisons with other renderers and for denoisers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Aov {
    /// Ambient light arriving: with one white unit occluder and `min_amount` 0 (the default),
    /// the raw AO estimate (1/π)∫V cos θ dω; 0 where the camera ray misses.
    Ao,
    /// Reflected radiance of the diffuse-term lights (point, spot, directional, disk).
    Direct,
    /// The material's `cd`.
    Albedo,
    /// Unit geometric normal facing the camera (world space, xyz as rgb).
    Normal,
    /// Distance from the camera to the hit.
    Depth,
    /// Coverage: the fraction of the pixel's camera rays that hit geometry (anti-aliased
    /// alpha, for a transparent background).
    Alpha,
}

/// Floats per pixel holding every AOV: ao 1, direct 3, albedo 3, normal 3, depth 1, alpha 1.
pub const AOV_FLOATS: usize = 12;

/// All AOVs of one pixel (sums or means), laid out as [`Aov::range`] says.
pub type AovValues = [f32; AOV_FLOATS];

impl Aov {
    /// Every AOV.
    pub const ALL: [Aov; 6] = [Aov::Ao, Aov::Direct, Aov::Albedo, Aov::Normal, Aov::Depth, Aov::Alpha];

    /// Command-line and file-name name.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Ao => "ao",
            Aov::Direct => "direct",
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
            Aov::Alpha => "alpha",
        }
    }

    /// Parses a name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Where the AOV sits in [`AovValues`].
    pub fn range(self) -> std::ops::Range<usize> {
        match self {
            Aov::Ao => 0..1,
            Aov::Direct => 1..4,
            Aov::Albedo => 4..7,
            Aov::Normal => 7..10,
            Aov::Depth => 10..11,
            Aov::Alpha => 11..12,
        }
    }
}

/// What the current frame traced (the trace system adds its samples straight into
/// [`Accumulation`], tile by tile, so that no image-sized frame buffer sits beside the sums).
#[derive(Resource, Clone, Debug, Default)]
pub struct FrameSamples {
    /// Samples per pixel traced this frame (0 when the frame traced nothing); pixels that
    /// adaptive sampling retired got none.
    pub samples_per_pixel: u32,
    /// Pixels traced this frame.
    pub active_pixels: usize,
    /// Keep each frame's per-pixel radiance sums in [`FrameSamples::sums`]: the parts of a
    /// render split by sample index store them, so that merged parts add up bit for bit.
    pub keep_sums: bool,
    /// Sum of this frame's radiance samples per pixel, row-major (empty unless `keep_sums`).
    pub sums: Vec<Vec3>,
}

/// Running sums over frames; reset whenever the scene or the settings change.
#[derive(Resource, Clone, Debug, Default)]
pub struct Accumulation {
    /// Image width the buffer was sized for.
    pub width: u32,
    /// Image height the buffer was sized for.
    pub height: u32,
    /// Sum of all radiance samples per pixel.
    pub sums: Sums<Vec3>,
    /// Samples accumulated per pixel: kept only for adaptive sampling, where pixels differ
    /// (empty otherwise: every pixel has `spp`). [`Accumulation::count`] reads either.
    pub counts: Vec<u32>,
    /// Per pixel, the sum of its samples' luminances' squared deviations from their mean: kept
    /// only for adaptive sampling (empty otherwise), as nothing else reads it.
    pub deviations: Vec<f64>,
    /// Per-pixel AOV sums (empty unless `RenderSettings::aovs`), of the radiance sums' kind.
    pub aovs: Sums<AovValues>,
    /// Where each pixel's camera ray ends, kept from the first frame after a reset for the
    /// frames after it where every sample of a pixel shares one camera ray (pixel centres, no
    /// lens): as long as nothing resets the accumulation, the scene and camera are the ones
    /// those rays were traced in. Empty when not kept (one-frame renders, jittered pixels, a
    /// lens, alpha-tested meshes).
    pub camera_ends: Vec<RayEnd>,
    /// What each light group that draws no samples (point lights) brings to each pixel's
    /// camera hit, kept with `camera_ends`: the groups' values pixel by pixel.
    pub camera_light: Vec<Vec3>,
    /// Samples per pixel accumulated so far (every pixel has the same count).
    pub spp: u32,
    /// How many times the buffer has been reset.
    pub resets: u64,
}

/// Which per-pixel buffers an [`Accumulation`] keeps besides its sums.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AccumulationLayout {
    /// The first frame completes the render: the sums start as [`Sums::OneFrame`].
    pub one_frame: bool,
    /// Adaptive sampling: per-pixel counts and squared sums.
    pub adaptive: bool,
}

/// Per-pixel sums: f32 while they hold one frame (what an f64 sum of that frame holds,
/// exactly: 0 + x rounds alike in both), f64 once frames add up (a sum of frames in f32 would
/// round differently, and the image would depend on how the samples were split into frames).
#[derive(Clone, Debug, PartialEq)]
pub enum Sums<T: Widen> {
    /// One frame's sums.
    OneFrame(Vec<T>),
    /// Sums over frames.
    Frames(Vec<T::Wide>),
}

/// A per-pixel f32 value and its f64 counterpart.
pub trait Widen: Copy + Zeroable {
    /// The same value in f64.
    type Wide: Copy + Zeroable;
    /// Converts exactly.
    fn widen(self) -> Self::Wide;
}

impl Widen for Vec3 {
    type Wide = DVec3;
    fn widen(self) -> DVec3 {
        self.as_dvec3()
    }
}

impl Widen for AovValues {
    type Wide = [f64; AOV_FLOATS];
    fn widen(self) -> [f64; AOV_FLOATS] {
        self.map(f64::from)
    }
}

impl<T: Widen> Default for Sums<T> {
    fn default() -> Self {
        Sums::Frames(Vec::new())
    }
}

impl<T: Widen> Sums<T> {
    /// Number of pixels.
    pub fn len(&self) -> usize {
        match self {
            Sums::OneFrame(v) => v.len(),
            Sums::Frames(v) => v.len(),
        }
    }

    /// Whether there are no pixels.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Pixel `i`'s sum.
    #[inline]
    pub fn get(&self, i: usize) -> T::Wide {
        match self {
            Sums::OneFrame(v) => v[i].widen(),
            Sums::Frames(v) => v[i],
        }
    }

    /// Bytes the sums hold.
    pub fn bytes(&self) -> usize {
        match self {
            Sums::OneFrame(v) => size_of_val(&v[..]),
            Sums::Frames(v) => size_of_val(&v[..]),
        }
    }

    /// The f64 sums, widened first from one frame's f32 (exactly), for more frames to add to.
    pub fn frames_mut(&mut self) -> &mut Vec<T::Wide> {
        if let Sums::OneFrame(v) = self {
            *self = Sums::Frames(v.iter().map(|s| s.widen()).collect());
        }
        match self {
            Sums::Frames(v) => v,
            Sums::OneFrame(_) => unreachable!("widened above"),
        }
    }

    /// Empties the sums and sizes them for `n` pixels of zero, f32 if `one_frame`, reusing the
    /// buffer there is when it is of that kind (progressive views reset often).
    fn reset(&mut self, n: usize, one_frame: bool) {
        match (&mut *self, one_frame) {
            (Sums::OneFrame(v), true) => zeros(v, n),
            (Sums::Frames(v), false) => zeros(v, n),
            (_, true) => {
                *self = Sums::default();
                *self = Sums::OneFrame(bytemuck::zeroed_vec(n));
            }
            (_, false) => {
                *self = Sums::default();
                *self = Sums::Frames(bytemuck::zeroed_vec(n));
            }
        }
    }

    /// Sizes the sums for `n` pixels of zero, of the kind they are, if they are not.
    pub fn size(&mut self, n: usize) {
        match self {
            Sums::OneFrame(v) => v.resize(n, T::zeroed()),
            Sums::Frames(v) => v.resize(n, T::Wide::zeroed()),
        }
    }
}

/// Empties `v` and sizes it to `n` zeros: in its own memory where that holds them, else in
/// fresh zeroed pages, which become resident only as frames write them, so that a buffer reset
/// before the BVH build does not sit in memory beside the build's temporaries.
fn zeros<T: Zeroable + Clone>(v: &mut Vec<T>, n: usize) {
    if v.capacity() >= n {
        v.clear();
        v.resize(n, T::zeroed());
    } else {
        *v = Vec::new();
        *v = bytemuck::zeroed_vec(n);
    }
}

/// Luminance (Rec. 709) of linear RGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// Whether adaptive sampling retires a pixel of `count` samples for target error `target`:
/// enough samples, and the standard error of their mean (`error`, asked only then) at most it.
#[inline]
pub fn retired(count: u32, error: impl FnOnce() -> f64, target: f32) -> bool {
    count >= RenderSettings::ADAPTIVE_MIN_SPP && error() <= target as f64
}

/// Standard error of a pixel's mean luminance from the count of its samples and the sum of
/// their luminances' squared deviations from their mean (∞ below 2 samples).
#[inline]
pub fn standard_error(count: u32, deviations: f64) -> f64 {
    let n = count as f64;
    if n < 2.0 {
        return f64::INFINITY;
    }
    (deviations.max(0.0) / (n * (n - 1.0))).sqrt()
}

/// The spread of sample luminances added one by one: their sum and sum of squares taken about
/// the first of them (shifted sums), so that the squared deviations from their mean do not
/// cancel at any level (samples all alike give 0) and cost a subtraction and a fused
/// multiply-add a sample.
#[derive(Clone, Copy, Debug, Default)]
pub struct LuminanceSpread {
    shift: Option<f32>,
    count: u32,
    sum: f32,
    squares: f32,
}

impl LuminanceSpread {
    /// Adds a sample of luminance `l`.
    #[inline]
    pub fn add(&mut self, l: f32) {
        let d = l - *self.shift.get_or_insert(l);
        self.count += 1;
        self.sum += d;
        self.squares = d.mul_add(d, self.squares);
    }

    /// The sum of the samples' squared deviations from their mean (0 without samples).
    pub fn deviations(&self) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        let sum = self.sum as f64;
        (self.squares as f64 - sum * sum / self.count as f64).max(0.0)
    }
}

/// A pixel's squared deviations (`deviations`, of its `count` samples summing to `sum`) with
/// a frame's added: its `frame_count` samples summing to `frame_sum` and their squared
/// deviations from their own mean (Chan, Golub and LeVeque's pairwise update).
#[inline]
pub fn merge_deviations(deviations: &mut f64, (count, sum): (u32, DVec3), frame: (u32, DVec3, f64)) {
    let (frame_count, frame_sum, frame_deviations) = frame;
    if frame_count == 0 {
        return;
    }
    *deviations += frame_deviations;
    if count > 0 {
        // δ² na nb / (na + nb) for δ the difference of the means, with one division.
        let (na, nb) = (count as f64, frame_count as f64);
        let scaled_delta = luminance_f64(frame_sum) * na - luminance_f64(sum) * nb;
        *deviations += scaled_delta * scaled_delta / (na * nb * (na + nb));
    }
}

/// [`luminance`] in f64.
#[inline]
fn luminance_f64(c: DVec3) -> f64 {
    c.dot(DVec3::new(0.2126, 0.7152, 0.0722))
}

impl Accumulation {
    /// Standard error of pixel `i`'s mean luminance from its samples so far (∞ below 2
    /// samples, and without squared sums: a render that is not adaptive keeps none).
    pub fn standard_error(&self, i: usize) -> f64 {
        self.deviations.get(i).map_or(f64::INFINITY, |&d| standard_error(self.count(i), d))
    }

    /// Samples taken in all, and the samples uniform sampling would need for the same RMS of
    /// the pixels' standard errors (N = mean variance / RMS², the same N in every pixel).
    pub fn samples_against_uniform(&self) -> (u64, f64) {
        let (mut taken, mut var_sum, mut err2_sum, mut n) = (0u64, 0.0f64, 0.0f64, 0usize);
        for i in 0..self.sums.len() {
            let e = self.standard_error(i);
            if !e.is_finite() {
                continue;
            }
            taken += self.count(i) as u64;
            var_sum += e * e * self.count(i) as f64;
            err2_sum += e * e;
            n += 1;
        }
        if n == 0 || err2_sum == 0.0 {
            return (taken, taken as f64);
        }
        let uniform_spp = (var_sum / n as f64) / (err2_sum / n as f64);
        (taken, uniform_spp * n as f64)
    }

    /// Whether adaptive sampling has retired pixel `i` for target error `e`.
    #[inline]
    pub fn pixel_done(&self, i: usize, target: Option<f32>) -> bool {
        target.is_some_and(|e| retired(self.count(i), || self.standard_error(i), e))
    }

    /// Samples pixel `i` has accumulated.
    #[inline]
    pub fn count(&self, i: usize) -> u32 {
        self.counts.get(i).copied().unwrap_or(self.spp)
    }

    /// Whether the finished image took the sums ([`RenderSettings::release_sums`]): a frame
    /// that asks for more samples starts the accumulation anew.
    pub fn spent(&self) -> bool {
        self.sums.len() != self.width as usize * self.height as usize
    }

    /// Bytes its per-pixel buffers hold.
    pub fn buffer_bytes(&self) -> usize {
        self.sums.bytes()
            + size_of_val(&self.counts[..])
            + size_of_val(&self.deviations[..])
            + self.aovs.bytes()
            + size_of_val(&self.camera_ends[..])
            + size_of_val(&self.camera_light[..])
    }

    /// Empties the buffers and sizes those `layout` keeps for `width × height` (AOV sums are
    /// sized by the first frame that makes them).
    pub fn reset(&mut self, width: u32, height: u32, layout: AccumulationLayout) {
        let n = width as usize * height as usize;
        self.width = width;
        self.height = height;
        self.sums.reset(n, layout.one_frame);
        self.aovs.reset(0, layout.one_frame);
        let adaptive = if layout.adaptive { n } else { 0 };
        zeros(&mut self.counts, adaptive);
        zeros(&mut self.deviations, adaptive);
        self.camera_ends = Vec::new();
        self.camera_light = Vec::new();
        self.spp = 0;
        self.resets += 1;
    }
}

/// The resolved image: linear radiance (its 8-bit sRGB encoding is made when asked for,
/// [`Image::srgb8`]: only PNG output and the window need it).
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub struct Image {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Mean radiance per pixel, linear RGB, row-major, top row first. Always finite.
    pub linear: Vec<Vec3>,
    /// Per-pixel AOV means (empty unless `RenderSettings::aovs`). Always finite.
    pub aovs: Vec<AovValues>,
}

impl Image {
    /// One AOV as an RGB image (single-channel AOVs repeated in r, g, b); `None` when AOVs
    /// were not accumulated.
    pub fn aov(&self, aov: Aov) -> Option<Vec<Vec3>> {
        if self.aovs.len() != self.linear.len() || self.aovs.is_empty() {
            return None;
        }
        let r = aov.range();
        Some(
            self.aovs
                .iter()
                .map(|v| match r.len() {
                    1 => Vec3::splat(v[r.start]),
                    _ => Vec3::new(v[r.start], v[r.start + 1], v[r.start + 2]),
                })
                .collect(),
        )
    }

    /// Bytes its per-pixel buffers hold.
    pub fn buffer_bytes(&self) -> usize {
        size_of_val(&self.linear[..]) + size_of_val(&self.aovs[..])
    }

    /// The image clamped to \[0, 1\] and sRGB-encoded, 3 bytes per pixel, row-major.
    pub fn srgb8(&self) -> Vec<u8> {
        let mut srgb = vec![0; 3 * self.linear.len()];
        srgb.par_chunks_mut(3).zip(self.linear.par_iter()).for_each(|(srgb, linear)| {
            for (c, v) in srgb.iter_mut().zip(linear.to_array()) {
                *c = linear_to_srgb8(v);
            }
        });
        srgb
    }

    /// Linear radiance at pixel (x, y).
    pub fn pixel(&self, x: u32, y: u32) -> Vec3 {
        self.linear[(y * self.width + x) as usize]
    }
}

/// Whether this frame's writes to shape values (transforms, spheres, planes, cuboids, surfaces)
/// changed any, as [`detect_scene_changes`](crate::systems::scene_changes::detect_scene_changes)
/// found them: a write of an equal value is no change, and leaves the BVH as it is.
#[derive(Resource, Clone, Copy, Debug, Default)]
pub struct ShapeValueChanges {
    /// Some written shape value differs from the one it replaced.
    pub any: bool,
}

/// Problems found in the scene; while any is present nothing is traced and `run_frame` fails.
#[derive(Resource, Clone, Debug, Default)]
pub struct SceneProblems {
    /// Found while building geometry (shapes, transforms, meshes, materials).
    pub geometry: Vec<String>,
    /// Found in the camera, lights or settings.
    pub view: Vec<String>,
}

impl SceneProblems {
    /// The first problem, if any.
    pub fn first(&self) -> Option<&String> {
        self.geometry.first().or(self.view.first())
    }
}

/// Scene time in seconds: the animation systems pose the scene for it. Changing it restarts
/// accumulation only when something actually moves.
#[derive(Resource, Clone, Copy, Debug, Default, PartialEq)]
pub struct Time {
    /// Seconds since the start of the animation.
    pub seconds: f32,
}
