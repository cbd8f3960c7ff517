//! Buffer data of a glTF asset: the GLB binary chunk, base64 `data:` URIs and external files
//! (percent-encoded URIs resolved against the asset's folder). Images are never decoded here.

use std::path::Path;

use ::gltf::{Document, buffer::Source};

/// Loads every buffer of `doc`, checking each holds at least its declared `byteLength`.
pub fn load(doc: &Document, blob: Option<Vec<u8>>, base: &Path) -> Result<Vec<Vec<u8>>, String> {
    let mut blob = blob;
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            Source::Bin => {
                blob.take().ok_or_else(|| format!("buffer {i} refers to a GLB binary chunk the file lacks"))?
            }
            Source::Uri(uri) => read_uri(uri, base).map_err(|e| format!("buffer {i}: {e}"))?,
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

/// The bytes behind a URI: a `data:` URI or a file relative to `base`.
pub fn read_uri(uri: &str, base: &Path) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest.split_once(";base64,").ok_or_else(|| "data URI is not base64-encoded".to_string())?;
        return decode_base64(payload).ok_or_else(|| "data URI holds invalid base64".to_string());
    }
    let path = base.join(percent_decode(uri));
    std::fs::read(&path).map_err(|e| format!("cannot read '{}': {e}", path.display()))
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
