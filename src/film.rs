//! Turning radiance into pixels: sRGB encoding and writing PNG (8-bit sRGB) or EXR (linear f32).

use std::{
    fs::File,
    io::{BufWriter, Seek, Write},
    path::{Path, PathBuf},
};

use image::{ImageEncoder, ImageFormat, Rgb32FImage, RgbImage, codecs::png::PngEncoder};

use crate::{error::HemiError, resources::Image};

/// sRGB transfer function of a linear value, clamped to [0, 1]; NaN maps to 0.
#[inline]
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v <= 0.003_130_8 { v * 12.92 } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// Inverse sRGB transfer function (for encoding thresholds).
fn srgb_to_linear(s: f64) -> f64 {
    if s <= 0.040_45 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

/// Linear value at which each 8-bit sRGB code starts: code k covers `[T[k-1], T[k])`.
static SRGB8_THRESHOLDS: std::sync::LazyLock<[f32; 255]> =
    std::sync::LazyLock::new(|| std::array::from_fn(|k| srgb_to_linear((k as f64 + 0.5) / 255.0) as f32));

/// Low bits dropped from a positive float's bit pattern to index [`SRGB8_BUCKETS`]: buckets
/// 1/128 of an octave wide, narrower than the gap between any two code thresholds.
const BUCKET_SHIFT: u32 = 16;

/// For each bucket of floats from the first threshold up (by bit pattern), the code of its
/// smallest value: the number of thresholds at or below it.
static SRGB8_BUCKETS: std::sync::LazyLock<Vec<u8>> = std::sync::LazyLock::new(|| {
    let t = &*SRGB8_THRESHOLDS;
    let (first, last) = (t[0].to_bits(), t[254].to_bits());
    (0..=(last - first) >> BUCKET_SHIFT)
        .map(|b| t.partition_point(|&x| x <= f32::from_bits(first + (b << BUCKET_SHIFT))) as u8)
        .collect()
});

/// 8-bit sRGB code of a linear value (round to nearest): the number of code thresholds at or
/// below it, found from its bucket's code plus at most one step (a bucket is narrower than any
/// gap between thresholds; the loop does not rely on it). Exact, as a binary search over the
/// thresholds is.
#[inline]
pub fn linear_to_srgb8(v: f32) -> u8 {
    let t = &*SRGB8_THRESHOLDS;
    // NaN maps to 0, with everything below the first threshold.
    if v.is_nan() || v < t[0] {
        return 0;
    }
    if v >= t[254] {
        return 255;
    }
    // A positive float's bits grow with it, so buckets split the range in order.
    let mut code = SRGB8_BUCKETS[((v.to_bits() - t[0].to_bits()) >> BUCKET_SHIFT) as usize] as usize;
    while t[code] <= v {
        code += 1;
    }
    code as u8
}

/// Image file formats hemi writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// 8-bit sRGB PNG.
    Png,
    /// Linear 32-bit float OpenEXR, unclamped.
    Exr,
}

impl OutputFormat {
    /// The format named by a path's extension.
    pub fn from_path(path: &Path) -> Result<Self, HemiError> {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("png") => Ok(OutputFormat::Png),
            Some("exr") => Ok(OutputFormat::Exr),
            _ => Err(HemiError::Io {
                path: path.to_path_buf(),
                message: "unsupported output format: use a .png or .exr extension".into(),
            }),
        }
    }
}

/// An output file opened (and so checked to be writable) before any rendering starts.
pub struct OutputFile {
    path: PathBuf,
    /// The image format its extension names (`None` for non-image files).
    format: Option<OutputFormat>,
    file: File,
}

impl OutputFile {
    /// Creates `path` for writing; fails early on an unknown extension or unwritable location.
    pub fn create(path: &Path) -> Result<Self, HemiError> {
        let format = OutputFormat::from_path(path)?;
        Ok(OutputFile { format: Some(format), ..Self::create_any(path)? })
    }

    /// Creates any output file (no image-format check), failing early if it is unwritable.
    pub fn create_any(path: &Path) -> Result<Self, HemiError> {
        let file = File::create(path).map_err(|e| io_error(path, "cannot create output file", e))?;
        Ok(OutputFile { path: path.to_path_buf(), format: None, file })
    }

    /// Writes `image` in the format the file's extension names.
    pub fn write(self, image: &Image) -> Result<(), HemiError> {
        let path = self.path.clone();
        let format = self.format.ok_or_else(|| io_error(&path, "cannot write image", "no .png or .exr extension"))?;
        let mut out = BufWriter::new(self.file);
        write_image(image, format, &mut out).map_err(|e| io_error(&path, "cannot write image", e))?;
        out.flush().map_err(|e| io_error(&path, "cannot write image", e))
    }

    /// Writes text (e.g. JSON statistics).
    pub fn write_text(self, text: &str) -> Result<(), HemiError> {
        let path = self.path.clone();
        let mut out = BufWriter::new(self.file);
        out.write_all(text.as_bytes()).and_then(|()| out.flush()).map_err(|e| io_error(&path, "cannot write", e))
    }

    /// Writes an 8-bit RGB picture (plots and the like) as PNG.
    pub fn write_rgb8(self, rgb: &RgbImage) -> Result<(), HemiError> {
        let path = self.path.clone();
        let mut out = BufWriter::new(self.file);
        PngEncoder::new(&mut out)
            .write_image(rgb, rgb.width(), rgb.height(), image::ExtendedColorType::Rgb8)
            .map_err(|e| io_error(&path, "cannot write image", e))?;
        out.flush().map_err(|e| io_error(&path, "cannot write image", e))
    }
}

/// Saves `image` to `path`, in the format its extension names.
pub fn save(image: &Image, path: &Path) -> Result<(), HemiError> {
    OutputFile::create(path)?.write(image)
}

/// Encodes `image` into `out` as PNG or EXR.
pub fn write_image<W: Write + Seek>(image: &Image, format: OutputFormat, out: &mut W) -> Result<(), image::ImageError> {
    match format {
        OutputFormat::Png => {
            let rgb = RgbImage::from_raw(image.width, image.height, image.srgb.clone()).expect("buffer size matches");
            PngEncoder::new(out).write_image(&rgb, image.width, image.height, image::ExtendedColorType::Rgb8)
        }
        OutputFormat::Exr => {
            let data: Vec<f32> = image.linear.iter().flat_map(|p| p.to_array()).collect();
            let rgb = Rgb32FImage::from_raw(image.width, image.height, data).expect("buffer size matches");
            rgb.write_to(out, ImageFormat::OpenExr)
        }
    }
}

fn io_error(path: &Path, what: &str, e: impl std::fmt::Display) -> HemiError {
    HemiError::Io { path: path.to_path_buf(), message: format!("{what}: {e}") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_encoding_matches_the_standard() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188); // 0.7354 · 255 = 187.5
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-5);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert!((linear_to_srgb(0.002) - 0.02584).abs() < 1e-6);
    }

    /// The bucketed search gives the binary search's code for every float between the first
    /// and last thresholds (each threshold, its neighbours, and every bucket's edges) and
    /// outside them.
    #[test]
    fn bucketed_encoding_equals_the_binary_search() {
        let search = |v: f32| if v.is_nan() { 0 } else { SRGB8_THRESHOLDS.partition_point(|&t| t <= v) as u8 };
        let t = &*SRGB8_THRESHOLDS;
        let mut values = vec![f32::NAN, -1.0, -0.0, 0.0, 1e-30, 1.0, 7.0, f32::INFINITY];
        for &x in t.iter() {
            values.extend([f32::from_bits(x.to_bits() - 1), x, f32::from_bits(x.to_bits() + 1)]);
        }
        for b in 0..SRGB8_BUCKETS.len() as u32 {
            let edge = t[0].to_bits() + (b << BUCKET_SHIFT);
            values.extend([f32::from_bits(edge - 1), f32::from_bits(edge), f32::from_bits(edge + 1)]);
        }
        let mut rng = crate::random::SplitMix64::new(10);
        values.extend((0..100_000).map(|_| rng.next_f32()));
        for v in values {
            assert_eq!(linear_to_srgb8(v), search(v), "v = {v:e}");
        }
    }

    #[test]
    fn table_encoding_equals_the_transfer_function() {
        let mut rng = crate::random::SplitMix64::new(9);
        for i in 0..200_000 {
            let v = if i % 2 == 0 { rng.next_f32() } else { rng.next_f32() * 0.01 };
            let exact = linear_to_srgb(v) as f64 * 255.0;
            let code = linear_to_srgb8(v);
            // Equal, except within float rounding of a half-code boundary.
            if (exact - exact.floor() - 0.5).abs() > 1e-3 {
                assert_eq!(code, exact.round() as u8, "v = {v}");
            }
        }
    }

    #[test]
    fn exr_round_trips_linear_values_exactly() {
        use glam::Vec3;
        let linear = vec![Vec3::new(0.25, 1.5, 1e-3), Vec3::new(7.0, 0.0, 0.125)];
        let image = Image { width: 2, height: 1, srgb: vec![0; 6], linear: linear.clone(), aovs: vec![] };
        let mut buf = std::io::Cursor::new(Vec::new());
        write_image(&image, OutputFormat::Exr, &mut buf).unwrap();
        let back = image::load_from_memory_with_format(buf.get_ref(), ImageFormat::OpenExr).unwrap().into_rgb32f();
        let values: Vec<f32> = back.into_raw();
        assert_eq!(values, linear.iter().flat_map(|p| p.to_array()).collect::<Vec<_>>());
    }
}
