//! Turning radiance into pixels: writing PNG (8-bit sRGB) or EXR (linear f32).

use std::{
    fs::File,
    io::{BufWriter, Seek, Write},
    path::{Path, PathBuf},
};

use exr::prelude::{Image as ExrImage, SpecificChannels, WritableImage};
use image::{ImageEncoder, ImageFormat, RgbImage, codecs::png::PngEncoder};

use crate::{
    error::HemiError,
    layers::write_layered_exr,
    look::Look,
    resources::{Aov, Image},
};

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

/// An output file that never leaves a partial file under its name: everything is written to a
/// temporary file beside it (same directory, so the final rename cannot cross file systems),
/// flushed to disk, and renamed over `path` only when complete. A failed, killed or
/// out-of-space run leaves an existing file at `path` untouched, and at most a hidden
/// `.NAME.*.tmp` file beside it (removed on any failure the process survives).
///
/// Creating one checks early, before any rendering, that the format is known and the
/// directory writable; missing parent directories are created. A destination that exists and
/// is not a regular file (`/dev/null`, a named pipe) is written in place: renaming over it
/// would replace the device with a file.
pub struct OutputFile {
    path: PathBuf,
    /// The image format its extension names (`None` for non-image files).
    format: Option<OutputFormat>,
    target: Target,
}

/// Where an [`OutputFile`]'s bytes go until it is finished.
enum Target {
    /// A temporary file beside the destination, renamed over it when complete.
    Temporary(tempfile::NamedTempFile),
    /// The destination itself, a device or pipe opened for writing.
    InPlace(File),
}

impl OutputFile {
    /// Prepares to write the image file `path`; fails early on an unknown extension or an
    /// unwritable location.
    pub fn create(path: &Path) -> Result<Self, HemiError> {
        let format = OutputFormat::from_path(path)?;
        Ok(OutputFile { format: Some(format), ..Self::create_any(path)? })
    }

    /// Prepares to write any output file (no image-format check), failing early if its
    /// directory cannot be created or written.
    pub fn create_any(path: &Path) -> Result<Self, HemiError> {
        if std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir()) {
            let file = std::fs::OpenOptions::new()
                .write(true)
                .open(path)
                .map_err(|e| io_error(path, "cannot open output for writing", e))?;
            return Ok(OutputFile { path: path.to_path_buf(), format: None, target: Target::InPlace(file) });
        }
        let name = path.file_name().ok_or_else(|| io_error(path, "cannot create output file", "no file name"))?;
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        std::fs::create_dir_all(dir).map_err(|e| io_error(path, "cannot create the output's folder", e))?;
        let mut prefix = std::ffi::OsString::from(".");
        prefix.push(name);
        prefix.push(".");
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).suffix(".tmp");
        // Temporary files are private (0600) by default; the finished file should get the
        // permissions any new file gets (0666 less the umask), as `File::create` gives.
        #[cfg(unix)]
        builder.permissions(std::os::unix::fs::PermissionsExt::from_mode(0o666));
        let file = builder.tempfile_in(dir).map_err(|e| io_error(path, "cannot create output file", e))?;
        Ok(OutputFile { path: path.to_path_buf(), format: None, target: Target::Temporary(file) })
    }

    /// Writes `image` in the format the file's extension names, then puts the file in place.
    pub fn write(self, image: &Image) -> Result<(), HemiError> {
        self.write_picture(image, &Picture::default())
    }

    /// Writes `image` as `picture` says (a look for PNG, alpha), then puts the file in place.
    pub fn write_picture(self, image: &Image, picture: &Picture) -> Result<(), HemiError> {
        let path = self.path.clone();
        let format = self.format.ok_or_else(|| io_error(&path, "cannot write image", "no .png or .exr extension"))?;
        self.finish("cannot write image", |out| write_picture(image, format, picture, out).map_err(|e| e.to_string()))
    }

    /// Writes `image` and its AOVs `aovs` as one layered EXR ([`write_layered_exr`]), then
    /// puts the file in place.
    pub fn write_layered(self, image: &Image, aovs: &[Aov]) -> Result<(), HemiError> {
        self.finish("cannot write image", |out| write_layered_exr(image, aovs, out))
    }

    /// Writes text (e.g. JSON statistics), then puts the file in place.
    pub fn write_text(self, text: &str) -> Result<(), HemiError> {
        self.finish("cannot write", |out| out.write_all(text.as_bytes()).map_err(|e| e.to_string()))
    }

    /// Writes raw bytes (an already encoded file), then puts the file in place.
    pub fn write_bytes(self, bytes: &[u8]) -> Result<(), HemiError> {
        self.finish("cannot write", |out| out.write_all(bytes).map_err(|e| e.to_string()))
    }

    /// Writes an 8-bit RGB picture (plots and the like) as PNG, then puts the file in place.
    pub fn write_rgb8(self, rgb: &RgbImage) -> Result<(), HemiError> {
        self.finish("cannot write image", |out| {
            PngEncoder::new(out)
                .write_image(rgb, rgb.width(), rgb.height(), image::ExtendedColorType::Rgb8)
                .map_err(|e| e.to_string())
        })
    }

    /// Runs `write` on a buffered writer over the temporary file, flushes it to disk and
    /// renames it over the final path; on any error the temporary file is removed.
    fn finish(
        self,
        what: &str,
        write: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), String>,
    ) -> Result<(), HemiError> {
        let OutputFile { path, target, .. } = self;
        match target {
            Target::InPlace(mut file) => {
                let mut out = BufWriter::new(&mut file);
                write(&mut out).map_err(|e| io_error(&path, what, e))?;
                out.flush().map_err(|e| io_error(&path, what, e))
            }
            Target::Temporary(mut file) => {
                let mut out = BufWriter::new(file.as_file_mut());
                write(&mut out).map_err(|e| io_error(&path, what, e))?;
                out.flush().map_err(|e| io_error(&path, what, e))?;
                drop(out);
                file.as_file().sync_all().map_err(|e| io_error(&path, what, e))?;
                file.persist(&path).map_err(|e| io_error(&path, "cannot put the finished file in place", e.error))?;
                Ok(())
            }
        }
    }
}

/// Saves `image` to `path`, in the format its extension names.
pub fn save(image: &Image, path: &Path) -> Result<(), HemiError> {
    OutputFile::create(path)?.write(image)
}

/// How an image becomes a file beyond its format: the look of 8-bit output and whether it
/// carries alpha. The default writes the image as hemi always did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Picture {
    /// Exposure and tone curve of PNG output (EXR stays linear and unscaled).
    pub look: Look,
    /// Write coverage as alpha (the image's [`Aov::Alpha`], 1 where it has none): straight
    /// RGBA in PNG, premultiplied RGBA in EXR (the radiance of a transparent background, 0,
    /// already is premultiplied).
    pub alpha: bool,
}

/// Encodes `image` into `out` as PNG or EXR.
pub fn write_image<W: Write + Seek>(image: &Image, format: OutputFormat, out: &mut W) -> Result<(), image::ImageError> {
    write_picture(image, format, &Picture::default(), out)
}

/// Encodes `image` into `out` as PNG or EXR, as `picture` says. The encoders read the
/// image's own buffers: only a PNG with a look or alpha makes its 8-bit pixels first.
pub fn write_picture<W: Write + Seek>(
    image: &Image,
    format: OutputFormat,
    picture: &Picture,
    out: &mut W,
) -> Result<(), image::ImageError> {
    let (w, h) = (image.width, image.height);
    let has_alpha = !image.aovs.is_empty() && image.aovs.len() == image.linear.len();
    let alpha = |i: usize| if has_alpha { image.aovs[i][Aov::Alpha.range().start] } else { 1.0 };
    let size = exr::math::Vec2(w as usize, h as usize);
    match (format, picture.alpha) {
        (OutputFormat::Png, false) if picture.look.is_identity() => {
            PngEncoder::new(out).write_image(&image.srgb8(), w, h, image::ExtendedColorType::Rgb8)
        }
        (OutputFormat::Png, false) => {
            let bytes: Vec<u8> = image.linear.iter().flat_map(|&c| picture.look.srgb8(c)).collect();
            PngEncoder::new(out).write_image(&bytes, w, h, image::ExtendedColorType::Rgb8)
        }
        (OutputFormat::Png, true) => {
            let bytes: Vec<u8> =
                image.linear.iter().enumerate().flat_map(|(i, &c)| picture.look.srgba8(c, alpha(i))).collect();
            PngEncoder::new(out).write_image(&bytes, w, h, image::ExtendedColorType::Rgba8)
        }
        // The EXR the `image` crate writes for an RGB(A) f32 buffer, from the image itself.
        (OutputFormat::Exr, false) => ExrImage::from_channels(
            size,
            SpecificChannels::rgb(|p: exr::math::Vec2<usize>| {
                let c = image.linear[p.flat_index_for_size(size)];
                (c.x, c.y, c.z)
            }),
        )
        .write()
        .to_buffered(out)
        .map_err(exr_error),
        (OutputFormat::Exr, true) => ExrImage::from_channels(
            size,
            SpecificChannels::rgba(|p: exr::math::Vec2<usize>| {
                let i = p.flat_index_for_size(size);
                let c = image.linear[i];
                (c.x, c.y, c.z, alpha(i))
            }),
        )
        .write()
        .to_buffered(out)
        .map_err(exr_error),
    }
}

/// An EXR encoding failure as the `image` crate's encoder reports one (on one line).
fn exr_error(e: exr::error::Error) -> image::ImageError {
    let format = image::error::ImageFormatHint::Exact(ImageFormat::OpenExr);
    image::ImageError::Decoding(image::error::DecodingError::new(format, e.to_string()))
}

/// Whether `path` holds a complete image: it decodes, entirely, as a PNG or EXR, and is
/// `size` (width, height) when given. Decoding a whole frame costs far less than rendering it.
pub fn is_complete_image(path: &Path, size: Option<(u32, u32)>) -> bool {
    let Ok(reader) = image::ImageReader::open(path).and_then(|r| r.with_guessed_format()) else {
        return false;
    };
    match reader.decode() {
        Ok(img) => size.is_none_or(|s| (img.width(), img.height()) == s),
        Err(_) => false,
    }
}

fn io_error(path: &Path, what: &str, e: impl std::fmt::Display) -> HemiError {
    HemiError::Io { path: path.to_path_buf(), message: format!("{what}: {e}") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exr_round_trips_linear_values_exactly() {
        use glam::Vec3;
        let linear = vec![Vec3::new(0.25, 1.5, 1e-3), Vec3::new(7.0, 0.0, 0.125)];
        let image = Image { width: 2, height: 1, linear: linear.clone(), aovs: vec![] };
        let mut buf = std::io::Cursor::new(Vec::new());
        write_image(&image, OutputFormat::Exr, &mut buf).unwrap();
        let back = image::load_from_memory_with_format(buf.get_ref(), ImageFormat::OpenExr).unwrap().into_rgb32f();
        let values: Vec<f32> = back.into_raw();
        assert_eq!(values, linear.iter().flat_map(|p| p.to_array()).collect::<Vec<_>>());
    }

    /// Files in `dir`, sorted.
    fn listing(dir: &Path) -> Vec<String> {
        let mut names: Vec<String> =
            std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
        names.sort();
        names
    }

    #[test]
    fn a_failed_write_leaves_the_existing_file_and_no_temporary_file() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.json");
        std::fs::write(&path, "good").unwrap();
        let failed = OutputFile::create_any(&path).unwrap().finish("cannot write", |out| {
            out.write_all(b"half of it").unwrap();
            Err("disk full".into())
        });
        let message = failed.unwrap_err().to_string();
        assert!(message.contains("out.json") && message.contains("disk full"), "{message}");
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "good");
        assert_eq!(listing(dir.path()), ["out.json"]);
    }

    #[test]
    fn a_finished_write_replaces_the_file_and_creates_missing_folders() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("a/b/out.json");
        let pending = OutputFile::create_any(&path).unwrap();
        assert!(!path.exists(), "nothing under the final name before the write completes");
        pending.write_text("new").unwrap();
        assert_eq!(std::fs::read_to_string(&path).unwrap(), "new");
        assert_eq!(listing(&dir.path().join("a/b")), ["out.json"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_ne!(mode & 0o044, 0, "readable by others as new files are (mode {mode:o})");
        }
    }

    /// `--out /dev/null` must not rename a file over the device.
    #[cfg(unix)]
    #[test]
    fn a_device_is_written_in_place() {
        use std::os::unix::fs::FileTypeExt;
        let null = Path::new("/dev/null");
        if !std::fs::metadata(null).is_ok_and(|m| m.file_type().is_char_device()) {
            eprintln!("skipped: /dev/null is not a device on this machine");
            return;
        }
        OutputFile::create_any(null).unwrap().write_text("discarded").unwrap();
        assert!(std::fs::metadata(null).unwrap().file_type().is_char_device());
    }
}
