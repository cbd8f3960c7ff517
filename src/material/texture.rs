//! Images sampled over a surface: texels, wrap modes, nearest or bilinear filtering, and
//! `KHR_texture_transform`'s placement of texture coordinates.
//!
//! There are no mip maps and no pixel footprints: a camera hit samples the base level with
//! the filter glTF names for magnification. Ambient occlusion and alpha cut-outs only need the
//! texel under the hit; a texture much finer than the pixels aliases, and more samples per
//! pixel average it out.

use std::sync::LazyLock;

use glam::{Vec2, Vec4};

/// What happens to texture coordinates outside [0, 1] along one axis (glTF's `wrapS`/`wrapT`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    /// The image tiles the plane.
    #[default]
    Repeat,
    /// The edge texels extend outwards.
    ClampToEdge,
    /// The image tiles the plane, every other copy mirrored.
    MirroredRepeat,
}

impl Wrap {
    /// Texel `i` of a row or column of `n` texels (n ≥ 1) under this mode.
    #[inline]
    fn texel(self, i: i64, n: i64) -> usize {
        let k = match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::ClampToEdge => i.clamp(0, n - 1),
            Wrap::MirroredRepeat => {
                let p = i.rem_euclid(2 * n);
                if p < n { p } else { 2 * n - 1 - p }
            }
        };
        k as usize
    }
}

/// How texels are combined (glTF's `magFilter`; without mip maps the same filter serves
/// minification).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Filter {
    /// The texel whose square holds the point.
    Nearest,
    /// Bilinear interpolation between the four texel centres around the point.
    #[default]
    Linear,
}

/// Wrap modes and filter of a texture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    /// Along u (across a row).
    pub wrap_u: Wrap,
    /// Along v (down the image).
    pub wrap_v: Wrap,
    /// How texels are combined.
    pub filter: Filter,
}

/// An image of RGBA texels, 8 bits per channel: colour sRGB-encoded, alpha linear (glTF's
/// base-colour encoding). Row 0 is the top of the image, at v = 0.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    width: u32,
    height: u32,
    texels: Vec<[u8; 4]>,
    /// Wrap modes and filter.
    pub sampler: Sampler,
}

/// sRGB-encoded byte to linear value (IEC 61966-2-1), once for all 256 codes.
static SRGB_TO_LINEAR: LazyLock<[f32; 256]> = LazyLock::new(|| {
    std::array::from_fn(|i| {
        let c = i as f32 / 255.0;
        if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
    })
});

impl Texture {
    /// A `width` × `height` image of `texels` in rows from the top, or `None` when the sizes
    /// disagree or the image is empty.
    pub fn new(width: u32, height: u32, texels: Vec<[u8; 4]>, sampler: Sampler) -> Option<Self> {
        let n = (width as usize).checked_mul(height as usize)?;
        (n > 0 && texels.len() == n).then_some(Texture { width, height, texels, sampler })
    }

    /// Width and height in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// The texel at column `x`, row `y`, decoded: linear RGB and alpha.
    #[inline]
    fn texel(&self, x: usize, y: usize) -> Vec4 {
        let [r, g, b, a] = self.texels[y * self.width as usize + x];
        let lut = &*SRGB_TO_LINEAR;
        Vec4::new(lut[r as usize], lut[g as usize], lut[b as usize], a as f32 / 255.0)
    }

    /// Linear RGB and alpha at texture coordinates `uv` (any finite or infinite value: wrap
    /// modes bring it onto the image; NaN reads texel 0).
    pub fn sample(&self, uv: Vec2) -> Vec4 {
        let (w, h) = (i64::from(self.width), i64::from(self.height));
        let s = &self.sampler;
        // Texel space, clamped so that the casts below stay exact (a repeat every 2^40 texels
        // is as good as any); NaN reads as 0.
        let limit = (1u64 << 40) as f32;
        let texels = |t: f32, n: i64| if t.is_nan() { 0.0 } else { (t * n as f32).clamp(-limit, limit) };
        let (x, y) = (texels(uv.x, w), texels(uv.y, h));
        match s.filter {
            Filter::Nearest => {
                let (i, j) = (x.floor() as i64, y.floor() as i64);
                self.texel(s.wrap_u.texel(i, w), s.wrap_v.texel(j, h))
            }
            Filter::Linear => {
                let (x, y) = (x - 0.5, y - 0.5);
                let (x0, y0) = (x.floor(), y.floor());
                let (fx, fy) = (x - x0, y - y0);
                let (i, j) = (x0 as i64, y0 as i64);
                let (i0, i1) = (s.wrap_u.texel(i, w), s.wrap_u.texel(i + 1, w));
                let (j0, j1) = (s.wrap_v.texel(j, h), s.wrap_v.texel(j + 1, h));
                let top = self.texel(i0, j0).lerp(self.texel(i1, j0), fx);
                let bottom = self.texel(i0, j1).lerp(self.texel(i1, j1), fx);
                top.lerp(bottom, fy)
            }
        }
    }
}

/// `KHR_texture_transform`: texture coordinates scaled, then rotated, then offset.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureTransform {
    /// Added last.
    pub offset: Vec2,
    /// Counter-clockwise rotation in radians (in the image, whose v axis points down).
    pub rotation: f32,
    /// Applied first, per axis.
    pub scale: Vec2,
}

impl Default for TextureTransform {
    fn default() -> Self {
        TextureTransform { offset: Vec2::ZERO, rotation: 0.0, scale: Vec2::ONE }
    }
}

impl TextureTransform {
    /// `uv` placed by the transform: offset + R(rotation)·(scale ∘ uv), with the extension's
    /// matrix R = [[cos, sin], [−sin, cos]].
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let s = uv * self.scale;
        let (sin, cos) = self.rotation.sin_cos();
        self.offset + Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2×1 texture: a black texel then a white one, half transparent.
    fn pair(wrap: Wrap, filter: Filter) -> Texture {
        let sampler = Sampler { wrap_u: wrap, wrap_v: wrap, filter };
        Texture::new(2, 1, vec![[0, 0, 0, 255], [255, 255, 255, 128]], sampler).unwrap()
    }

    #[test]
    fn wrap_modes_fold_texel_indices() {
        let n = 3;
        let row = |w: Wrap| (-4..7).map(|i| w.texel(i, n)).collect::<Vec<_>>();
        assert_eq!(row(Wrap::Repeat), [2, 0, 1, 2, 0, 1, 2, 0, 1, 2, 0]);
        assert_eq!(row(Wrap::ClampToEdge), [0, 0, 0, 0, 0, 1, 2, 2, 2, 2, 2]);
        assert_eq!(row(Wrap::MirroredRepeat), [2, 2, 1, 0, 0, 1, 2, 2, 1, 0, 0]);
    }

    #[test]
    fn nearest_and_linear_filters_on_hand_computed_texels() {
        let t = pair(Wrap::ClampToEdge, Filter::Nearest);
        assert_eq!(t.sample(Vec2::new(0.49, 0.5)).x, 0.0);
        assert_eq!(t.sample(Vec2::new(0.51, 0.5)), Vec4::new(1.0, 1.0, 1.0, 128.0 / 255.0));
        let t = pair(Wrap::ClampToEdge, Filter::Linear);
        // u = 0.5 is halfway between the texel centres 0.25 and 0.75.
        let mid = t.sample(Vec2::new(0.5, 0.5));
        assert!((mid - Vec4::new(0.5, 0.5, 0.5, (1.0 + 128.0 / 255.0) / 2.0)).abs().max_element() < 1e-6, "{mid}");
        // Past the centres, clamping holds the edge texels.
        assert_eq!(t.sample(Vec2::new(0.1, 0.5)).x, 0.0);
        assert_eq!(t.sample(Vec2::new(0.9, 0.5)).x, 1.0);
        // Repeat blends the last texel with the first across the seam: u = 0 is halfway.
        let seam = pair(Wrap::Repeat, Filter::Linear).sample(Vec2::new(0.0, 0.5)).x;
        assert!((seam - 0.5).abs() < 1e-6, "{seam}");
        // Mirrored repeat: u = 0 lies between the first texel and its mirror image.
        assert_eq!(pair(Wrap::MirroredRepeat, Filter::Linear).sample(Vec2::new(0.0, 0.5)).x, 0.0);
    }

    #[test]
    fn colour_is_decoded_from_srgb_and_alpha_is_not() {
        let sampler = Sampler { filter: Filter::Nearest, ..Default::default() };
        let t = Texture::new(1, 1, vec![[188, 10, 255, 51]], sampler).unwrap();
        let c = t.sample(Vec2::ZERO);
        // sRGB 188/255 is linear 0.5029; 10/255 is on the linear segment, 10/255/12.92.
        assert!((c.x - 0.502_886).abs() < 1e-4, "{c}");
        assert!((c.y - 10.0 / 255.0 / 12.92).abs() < 1e-7, "{c}");
        assert_eq!((c.z, c.w), (1.0, 0.2));
    }

    #[test]
    fn non_finite_coordinates_read_a_texel() {
        let t = pair(Wrap::MirroredRepeat, Filter::Linear);
        for u in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, 1e30] {
            assert!(t.sample(Vec2::new(u, u)).is_finite(), "{u}");
        }
    }

    #[test]
    fn texture_transform_scales_rotates_then_offsets() {
        let t = TextureTransform {
            offset: Vec2::new(0.1, 0.2),
            rotation: std::f32::consts::FRAC_PI_2,
            scale: Vec2::new(2.0, 2.0),
        };
        // scale: (1, 0.5); rotate: (cos·1 + sin·0.5, −sin·1 + cos·0.5) = (0.5, −1); offset.
        let uv = t.apply(Vec2::new(0.5, 0.25));
        assert!((uv - Vec2::new(0.6, -0.8)).abs().max_element() < 1e-6, "{uv}");
        assert_eq!(TextureTransform::default().apply(Vec2::new(0.3, 0.7)), Vec2::new(0.3, 0.7));
    }
}
