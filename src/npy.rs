//! Reading NumPy `.npy` arrays (version 1–3, little-endian `<f4` or `|b1`, C order): the
//! format of the peer renderers' reference images (`../shared/peers/refs/*.ao.npy`, `*.hit.npy`).

use std::path::Path;

use crate::error::HemiError;

/// A 2-D array read from a `.npy` file.
#[derive(Clone, Debug, PartialEq)]
pub struct Array2<T> {
    /// Rows (image height).
    pub rows: usize,
    /// Columns (image width).
    pub cols: usize,
    /// Values, row-major.
    pub data: Vec<T>,
}

fn bad(path: &Path, what: impl Into<String>) -> HemiError {
    HemiError::Io { path: path.to_path_buf(), message: what.into() }
}

/// Parses the header; returns (dtype descriptor, shape, offset of the data).
fn header(path: &Path, bytes: &[u8]) -> Result<(String, Vec<usize>, usize), HemiError> {
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(bad(path, "not a .npy file (bad magic)"));
    }
    let (len, start) = match bytes[6] {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10),
        2 | 3 if bytes.len() >= 12 => (u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize, 12),
        v => return Err(bad(path, format!("unsupported .npy version {v}"))),
    };
    let text = bytes.get(start..start + len).ok_or_else(|| bad(path, "truncated .npy header"))?;
    let text = String::from_utf8_lossy(text);
    let field = |key: &str| -> Option<String> {
        let rest = &text[text.find(&format!("'{key}'"))? + key.len() + 2..];
        let rest = rest.trim_start().strip_prefix(':')?.trim_start();
        Some(match rest.chars().next()? {
            '(' => rest[..=rest.find(')')?].to_string(),
            '\'' => rest[1..1 + rest[1..].find('\'')?].to_string(),
            _ => rest[..rest.find([',', '}'])?].trim().to_string(),
        })
    };
    let descr = field("descr").ok_or_else(|| bad(path, ".npy header has no descr"))?;
    if field("fortran_order").as_deref() != Some("False") {
        return Err(bad(path, ".npy array is not in C order"));
    }
    let text_shape = field("shape").ok_or_else(|| bad(path, ".npy header has no shape"))?;
    let shape: Result<Vec<usize>, _> = text_shape
        .trim_matches(['(', ')'])
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(str::parse)
        .collect();
    let shape = shape.map_err(|_| bad(path, format!("bad .npy shape {text_shape}")))?;
    Ok((descr, shape, start + len))
}

/// Reads a 2-D array of `dtype` (`<f4` or `|b1`), converting each element with `convert`.
fn read<T>(path: &Path, dtype: &str, size: usize, convert: impl Fn(&[u8]) -> T) -> Result<Array2<T>, HemiError> {
    let bytes = std::fs::read(path).map_err(|e| bad(path, format!("cannot read: {e}")))?;
    let (descr, shape, offset) = header(path, &bytes)?;
    if descr != dtype {
        return Err(bad(path, format!("expected dtype {dtype}, found {descr}")));
    }
    let [rows, cols] = shape[..] else {
        return Err(bad(path, format!("expected a 2-D array, found shape {shape:?}")));
    };
    let data = &bytes[offset..];
    if data.len() != rows * cols * size {
        return Err(bad(
            path,
            format!("holds {} bytes of data, shape {rows}x{cols} needs {}", data.len(), rows * cols * size),
        ));
    }
    Ok(Array2 { rows, cols, data: data.chunks_exact(size).map(convert).collect() })
}

/// Reads a 2-D float32 array.
pub fn read_f32(path: &Path) -> Result<Array2<f32>, HemiError> {
    read(path, "<f4", 4, |b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
}

/// Reads a 2-D boolean array.
pub fn read_bool(path: &Path) -> Result<Array2<bool>, HemiError> {
    read(path, "|b1", 1, |b| b[0] != 0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_npy(name: &str, descr: &str, shape: &str, data: &[u8]) -> std::path::PathBuf {
        let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((header.len() as u16).to_le_bytes());
        bytes.extend(header.as_bytes());
        bytes.extend(data);
        let path = std::env::temp_dir().join(format!("hemi-npy-{}-{name}", std::process::id()));
        std::fs::write(&path, bytes).unwrap();
        path
    }

    #[test]
    fn reads_float_and_bool_arrays() {
        let floats: Vec<u8> = [0.5f32, 1.0, -2.0, 3.25, 0.0, 7.0].iter().flat_map(|f| f.to_le_bytes()).collect();
        let a = read_f32(&write_npy("f.npy", "<f4", "(2, 3)", &floats)).unwrap();
        assert_eq!((a.rows, a.cols, a.data), (2, 3, vec![0.5, 1.0, -2.0, 3.25, 0.0, 7.0]));
        let b = read_bool(&write_npy("b.npy", "|b1", "(1, 3)", &[1, 0, 1])).unwrap();
        assert_eq!(b.data, vec![true, false, true]);
    }

    #[test]
    fn malformed_files_give_clear_errors() {
        let floats: Vec<u8> = [1.0f32; 5].iter().flat_map(|f| f.to_le_bytes()).collect();
        let short = read_f32(&write_npy("s.npy", "<f4", "(2, 3)", &floats)).unwrap_err().to_string();
        assert!(short.contains("needs 24"), "{short}");
        let dtype = read_f32(&write_npy("d.npy", "<f8", "(1, 1)", &[0; 8])).unwrap_err().to_string();
        assert!(dtype.contains("expected dtype <f4"), "{dtype}");
        let path = std::env::temp_dir().join("hemi-npy-not.npy");
        std::fs::write(&path, b"hello world").unwrap();
        assert!(read_bool(&path).unwrap_err().to_string().contains("bad magic"));
    }
}
