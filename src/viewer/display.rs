//! What the window shows: one buffer of the resolved image (beauty or an AOV), exposed,
//! sRGB-encoded and upscaled (nearest) to the window, with an optional text overlay.

use font8x8::legacy::BASIC_LEGACY;
use glam::Vec3;
use rayon::prelude::*;

use crate::{
    look::{Look, Tonemap},
    resources::{Aov, Image},
    srgb::linear_to_srgb8,
};

/// The buffer on display: keys 1–6 pick beauty, ao, direct, albedo, normal, depth.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Buffer {
    /// The rendered image.
    Beauty,
    /// An arbitrary output variable (accumulated only while displayed).
    Aov(Aov),
}

impl Buffer {
    /// The buffer of digit key `digit` (1–6).
    pub fn from_digit(digit: u8) -> Option<Self> {
        match digit {
            1 => Some(Buffer::Beauty),
            2..=6 => Some(Buffer::Aov(Aov::ALL[digit as usize - 2])),
            _ => None,
        }
    }

    /// Its name, as the overlay and the title show it.
    pub fn name(self) -> &'static str {
        match self {
            Buffer::Beauty => "beauty",
            Buffer::Aov(a) => a.name(),
        }
    }
}

/// How the image is shown.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Display {
    /// The buffer on display.
    pub buffer: Buffer,
    /// Exposure in stops (0: the image as `hemi render` writes it).
    pub exposure: f32,
    /// Whether the text overlay is drawn.
    pub overlay: bool,
    /// Tone curve of the beauty image (`hemi view --tonemap`).
    pub tonemap: Tonemap,
}

impl Default for Display {
    fn default() -> Self {
        Display { buffer: Buffer::Beauty, exposure: 0.0, overlay: false, tonemap: Tonemap::None }
    }
}

/// Packs 8-bit RGB as the window's `0x00RRGGBB` pixel.
#[inline]
pub fn pack(r: u8, g: u8, b: u8) -> u32 {
    (u32::from(r) << 16) | (u32::from(g) << 8) | u32::from(b)
}

/// Unpacks a `0x00RRGGBB` pixel.
#[inline]
pub fn unpack(p: u32) -> [u8; 3] {
    [(p >> 16) as u8, (p >> 8) as u8, p as u8]
}

/// The displayed buffer of `image` at its own resolution, as `0x00RRGGBB` pixels. The beauty
/// image at exposure 0 is the image's own sRGB encoding, byte for byte what `hemi render`
/// writes; AOVs not (yet) accumulated show the beauty image.
pub fn encode(image: &Image, display: &Display) -> Vec<u32> {
    let scale = 2f32.powf(display.exposure);
    let aov = match display.buffer {
        Buffer::Aov(a) => image.aov(a).map(|px| (a, px)),
        Buffer::Beauty => None,
    };
    match aov {
        // The image's 8-bit encoding, made here for the window (the image keeps none).
        None if display.exposure == 0.0 && display.tonemap == Tonemap::None => {
            image.linear.par_iter().map(|&c| encode_linear(c)).collect()
        }
        None => {
            let look = Look { exposure: display.exposure, tonemap: display.tonemap };
            image.linear.iter().map(|&c| look.srgb8(c)).map(|[r, g, b]| pack(r, g, b)).collect()
        }
        Some((Aov::Normal, px)) => px
            .iter()
            .map(|n| {
                let c = (*n * 0.5 + 0.5).clamp(Vec3::ZERO, Vec3::ONE) * 255.0 + 0.5;
                pack(c.x as u8, c.y as u8, c.z as u8)
            })
            .collect(),
        Some((Aov::Depth, px)) => {
            // Nearer is brighter: depth over the farthest hit, inverted; misses are black.
            let far = px.iter().map(|d| d.x).filter(|d| d.is_finite()).fold(0.0f32, f32::max).max(1e-12);
            px.iter()
                .map(|d| if d.x > 0.0 { encode_linear(Vec3::splat((1.0 - d.x / far) * scale)) } else { 0 })
                .collect()
        }
        Some((_, px)) => px.iter().map(|&c| encode_linear(c * scale)).collect(),
    }
}

fn encode_linear(c: Vec3) -> u32 {
    pack(linear_to_srgb8(c.x), linear_to_srgb8(c.y), linear_to_srgb8(c.z))
}

/// Nearest-neighbour upscale of a `sw × sh` picture to `dw × dh` into `out`.
pub fn upscale(src: &[u32], sw: u32, sh: u32, dw: u32, dh: u32, out: &mut Vec<u32>) {
    out.clear();
    if sw == 0 || sh == 0 || src.len() < sw as usize * sh as usize {
        out.resize(dw as usize * dh as usize, 0);
        return;
    }
    if (sw, sh) == (dw, dh) {
        out.extend_from_slice(&src[..sw as usize * sh as usize]);
        return;
    }
    let xs: Vec<usize> = (0..dw).map(|x| (x as u64 * sw as u64 / dw as u64) as usize).collect();
    for y in 0..dh {
        let row = (y as u64 * sh as u64 / dh as u64) as usize * sw as usize;
        out.extend(xs.iter().map(|&x| src[row + x]));
    }
}

/// Draws `lines` of text at the top-left of a `width`-wide framebuffer, white on a darkened
/// band, with the 8×8 built-in font.
pub fn draw_overlay(fb: &mut [u32], width: u32, lines: &[String]) {
    let height = fb.len() / width.max(1) as usize;
    let (w, line_h, margin) = (width as usize, 10usize, 4usize);
    let cols = lines.iter().map(|l| l.chars().count()).max().unwrap_or(0);
    let band_w = (cols * 8 + 2 * margin).min(w);
    let band_h = (lines.len() * line_h + 2 * margin).min(height);
    for y in 0..band_h {
        for p in &mut fb[y * w..y * w + band_w] {
            // Halve every channel: the image stays visible behind the text.
            *p = (*p >> 1) & 0x7f7f7f;
        }
    }
    for (i, line) in lines.iter().enumerate() {
        let y0 = margin + i * line_h;
        for (j, ch) in line.chars().enumerate() {
            let x0 = margin + j * 8;
            let Some(glyph) = BASIC_LEGACY.get(ch as usize) else { continue };
            for (dy, bits) in glyph.iter().enumerate() {
                for dx in 0..8 {
                    let (x, y) = (x0 + dx, y0 + dy);
                    if bits >> dx & 1 == 1 && x < w && y < height {
                        fb[y * w + x] = 0xffffff;
                    }
                }
            }
        }
    }
}
