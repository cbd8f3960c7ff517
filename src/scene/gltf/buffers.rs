//! Buffer data of a glTF asset: the GLB binary chunk, base64 `data:` URIs and external files
//! (percent-encoded URIs resolved against the asset's folder). Images are never decoded here.
//!
//! Every file hemi reads goes through [`read_file`]: it must be a regular file (not a device,
//! pipe or directory) of at most [`MAX_FILE_BYTES`], and no more than its size when it was
//! opened is read. External URIs must stay inside the asset's own folder (no absolute paths,
//! no `..` escapes, no symbolic links leading out) unless [`LoadOptions::allow_external_uris`]
//! says otherwise.

use std::{
    io::Read,
    path::{Component, Path, PathBuf},
};

use ::gltf::{Document, buffer::Source};

/// The largest file hemi reads (a `.gltf`, `.glb`, external buffer or peer scene): 4 GiB.
pub const MAX_FILE_BYTES: u64 = 4 << 30;

/// How a glTF file may reach other files.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Let buffer URIs name files outside the asset's folder (absolute paths, `..`, links
    /// leading out). Off by default: a downloaded model cannot make hemi read `/etc/passwd` as
    /// mesh data. Devices, pipes and files over [`MAX_FILE_BYTES`] are refused either way.
    pub allow_external_uris: bool,
    /// Read the geometry alone (what a geometry-only spawn keeps, as peer scenes are spawned):
    /// no surfaces, so no texture is decoded and no texture coordinates or colours are read.
    pub geometry_only: bool,
}

/// Reads a whole regular file of at most `limit` bytes (and at most the size it had when
/// opened). Errors are one line: `cannot read: why` (callers name the file).
pub fn read_file(path: &Path, limit: u64) -> Result<Vec<u8>, String> {
    read_file_inner(path, limit).map_err(|e| format!("cannot read: {e}"))
}

fn read_file_inner(path: &Path, limit: u64) -> Result<Vec<u8>, String> {
    let meta = std::fs::metadata(path).map_err(|e| e.to_string())?;
    if !meta.is_file() {
        let kind = if meta.is_dir() { "a directory" } else { "a device, pipe or socket" };
        return Err(format!("it is {kind}, not a regular file"));
    }
    let size = meta.len();
    if size > limit {
        return Err(format!("it is {size} bytes, more than the limit of {limit}"));
    }
    let file = std::fs::File::open(path).map_err(|e| e.to_string())?;
    let mut bytes = Vec::with_capacity(size as usize);
    file.take(size + 1).read_to_end(&mut bytes).map_err(|e| e.to_string())?;
    if bytes.len() as u64 > size {
        return Err(format!("it grew past its size of {size} bytes while being read"));
    }
    Ok(bytes)
}

/// Loads every buffer of `doc`, checking each holds at least its declared `byteLength`.
pub fn load(doc: &Document, blob: Option<Vec<u8>>, base: &Path, options: &LoadOptions) -> Result<Vec<Vec<u8>>, String> {
    let mut blob = blob;
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            Source::Bin => {
                blob.take().ok_or_else(|| format!("buffer {i} refers to a GLB binary chunk the file lacks"))?
            }
            Source::Uri(uri) => read_uri(uri, base, options).map_err(|e| format!("buffer {i}: {e}"))?,
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {i} holds {} bytes, fewer than its byteLength {}",
                data.len(),
                buffer.length()
            ));
        }
        out.push(data);
    }
    Ok(out)
}

/// The bytes behind a URI: a `data:` URI or a file relative to `base` (inside it unless
/// `options` allow external files).
pub fn read_uri(uri: &str, base: &Path, options: &LoadOptions) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest.split_once(";base64,").ok_or_else(|| "data URI is not base64-encoded".to_string())?;
        return decode_base64(payload).ok_or_else(|| "data URI holds invalid base64".to_string());
    }
    let path = resolve(uri, base, options)?;
    read_file_inner(&path, MAX_FILE_BYTES).map_err(|e| format!("cannot read '{}': {e}", path.display()))
}

/// Where a relative URI points, refused when it has a scheme other than `data:` or, without
/// `allow_external_uris`, when it leaves `base`.
pub fn resolve(uri: &str, base: &Path, options: &LoadOptions) -> Result<PathBuf, String> {
    if let Some((scheme, _)) = uri.split_once(':')
        && scheme.len() > 1
        && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
        && scheme.chars().all(|c| c.is_ascii_alphanumeric() || "+-.".contains(c))
    {
        return Err(format!(
            "URI '{uri}': the scheme '{scheme}:' is not supported (only relative paths and data: URIs)"
        ));
    }
    let relative = PathBuf::from(percent_decode(uri));
    let base = if base.as_os_str().is_empty() { Path::new(".") } else { base };
    let path = base.join(&relative);
    if options.allow_external_uris {
        return Ok(path);
    }
    let outside = || format!("URI '{uri}' leads outside the model's folder (allow_external_uris is off)");
    let mut depth = 0usize;
    for c in relative.components() {
        match c {
            Component::Normal(_) => depth += 1,
            Component::CurDir => {}
            Component::ParentDir => depth = depth.checked_sub(1).ok_or_else(outside)?,
            Component::RootDir | Component::Prefix(_) => return Err(outside()),
        }
    }
    // Symbolic links may still lead out: compare the real paths (a missing file is reported
    // by the read that follows).
    if let (Ok(real_base), Ok(real)) = (base.canonicalize(), path.canonicalize())
        && !real.starts_with(&real_base)
    {
        return Err(outside());
    }
    Ok(path)
}

/// Decodes `%XX` escapes (RFC 3986); invalid escapes are kept as written.
pub fn percent_decode(s: &str) -> String {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%'
            && let Some(v) = s.get(i + 1..i + 3).and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// Standard base64 (RFC 4648, padding optional, whitespace ignored).
pub fn decode_base64(s: &str) -> Option<Vec<u8>> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' | b'-' => 62,
            b'/' | b'_' => 63,
            _ => return None,
        } as u32)
    };
    let digits: Vec<u8> = s.bytes().filter(|c| !c.is_ascii_whitespace()).collect();
    let digits = digits.strip_suffix(b"==").or_else(|| digits.strip_suffix(b"=")).unwrap_or(&digits);
    if digits.len() % 4 == 1 {
        return None;
    }
    let mut out = Vec::with_capacity(digits.len() * 3 / 4);
    for chunk in digits.chunks(4) {
        let mut acc = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            acc |= value(c)? << (18 - 6 * k);
        }
        let bytes = acc.to_be_bytes();
        out.extend_from_slice(&bytes[1..chunk.len()]);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_and_percent_decoding() {
        assert_eq!(decode_base64("aGVtaQ==").unwrap(), b"hemi");
        assert_eq!(decode_base64("aGVtaXM").unwrap(), b"hemis");
        assert_eq!(decode_base64("AAEC").unwrap(), [0, 1, 2]);
        assert!(decode_base64("a$==").is_none());
        assert_eq!(percent_decode("my%20model%2Fpart.bin"), "my model/part.bin");
        assert_eq!(percent_decode("100%"), "100%");
    }
}
