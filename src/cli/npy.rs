//! Reading 2-D NumPy `.npy` arrays (C order) with `npyz`: the format of the peer renderers'
//! reference images (`../shared/peers/refs/*.ao.npy`, `*.hit.npy`).

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

/// Reads a 2-D array whose dtype `T` can be read from (`npyz` refuses any other).
fn read<T: npyz::Deserialize>(path: &Path) -> Result<Array2<T>, HemiError> {
    let bytes = std::fs::read(path).map_err(|e| bad(path, format!("cannot read: {e}")))?;
    let npy = npyz::NpyFile::new(&bytes[..]).map_err(|e| bad(path, format!("not a .npy file: {e}")))?;
    if npy.order() != npyz::Order::C {
        return Err(bad(path, ".npy array is not in C order"));
    }
    let shape = npy.shape().to_vec();
    let (rows, cols) = match shape[..] {
        [rows, cols] => (usize::try_from(rows), usize::try_from(cols)),
        _ => return Err(bad(path, format!("expected a 2-D array, found shape {shape:?}"))),
    };
    let (Ok(rows), Ok(cols)) = (rows, cols) else {
        return Err(bad(path, format!("shape {shape:?} is too large")));
    };
    let dtype = npy.dtype().descr();
    let reader = npy.data::<T>().map_err(|e| bad(path, format!("dtype {dtype}: {e}")))?;
    let data = reader
        .collect::<Result<Vec<T>, _>>()
        .map_err(|e| bad(path, format!("shape {rows}x{cols} of dtype {dtype}: {e}")))?;
    Ok(Array2 { rows, cols, data })
}

/// Reads a 2-D float32 array.
pub fn read_f32(path: &Path) -> Result<Array2<f32>, HemiError> {
    read(path)
}

/// Reads a 2-D boolean array.
pub fn read_bool(path: &Path) -> Result<Array2<bool>, HemiError> {
    read(path)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_npy(dir: &tempfile::TempDir, name: &str, descr: &str, shape: &str, data: &[u8]) -> std::path::PathBuf {
        let mut header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
        bytes.extend((header.len() as u16).to_le_bytes());
        bytes.extend(header.as_bytes());
        bytes.extend(data);
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    #[test]
    fn reads_float_and_bool_arrays() {
        let dir = tempfile::tempdir().unwrap();
        let floats: Vec<u8> = [0.5f32, 1.0, -2.0, 3.25, 0.0, 7.0].iter().flat_map(|f| f.to_le_bytes()).collect();
        let a = read_f32(&write_npy(&dir, "f.npy", "<f4", "(2, 3)", &floats)).unwrap();
        assert_eq!((a.rows, a.cols, a.data), (2, 3, vec![0.5, 1.0, -2.0, 3.25, 0.0, 7.0]));
        let b = read_bool(&write_npy(&dir, "b.npy", "|b1", "(1, 3)", &[1, 0, 1])).unwrap();
        assert_eq!(b.data, vec![true, false, true]);
    }

    #[test]
    fn malformed_files_give_clear_errors() {
        let dir = tempfile::tempdir().unwrap();
        let floats: Vec<u8> = [1.0f32; 5].iter().flat_map(|f| f.to_le_bytes()).collect();
        let short = read_f32(&write_npy(&dir, "s.npy", "<f4", "(2, 3)", &floats)).unwrap_err().to_string();
        assert!(short.contains("s.npy") && short.contains("shape 2x3"), "{short}");
        let dtype = read_f32(&write_npy(&dir, "d.npy", "<f8", "(1, 1)", &[0; 8])).unwrap_err().to_string();
        assert!(dtype.contains("dtype '<f8'"), "{dtype}");
        let flat = read_f32(&write_npy(&dir, "v.npy", "<f4", "(3,)", &floats[..12])).unwrap_err().to_string();
        assert!(flat.contains("expected a 2-D array"), "{flat}");
        let path = dir.path().join("not.npy");
        std::fs::write(&path, b"hello world").unwrap();
        assert!(read_bool(&path).unwrap_err().to_string().contains("not a .npy file"));
    }
}
