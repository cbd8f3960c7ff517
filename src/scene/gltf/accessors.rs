//! Typed, checked reads of glTF accessors. gltf 1.4 reads whatever bytes an accessor points
//! at (and panics on FLOAT indices), so every read here first checks the accessor's type and
//! then that it yields exactly `count` elements; any mismatch is a one-line error. Byte
//! ranges and strides were checked beforehand ([`super::validate::data`]), and every read is
//! charged to a [`Data`]'s budget, so that a small file cannot make the loader allocate
//! without bound by referring to the same large accessor many times.

use std::cell::Cell;

use ::gltf::{
    Accessor,
    accessor::{DataType, Dimensions, Item, Iter},
    buffer::Buffer,
};

/// The loaded buffers of a glTF file and what is left of the bytes the loader may still
/// produce from them.
#[derive(Debug)]
pub struct Data {
    /// Each buffer's bytes, indexed like the file's `buffers`.
    pub buffers: Vec<Vec<u8>>,
    budget: Cell<u64>,
}

/// How many bytes of vertices, indices, keys and matrices the loader may produce per byte of
/// buffer data, beyond a fixed [`BUDGET_BASE`]: reading every accessor once takes about 1×
/// (the triangle lists of strips and fans up to 12×), so this only stops a file that reads
/// the same data over and over.
pub const BUDGET_PER_BUFFER_BYTE: u64 = 32;

/// Bytes the loader may produce whatever the size of the file's buffers (256 MiB).
pub const BUDGET_BASE: u64 = 256 << 20;

impl Data {
    /// Buffers with the budget [`BUDGET_BASE`] + [`BUDGET_PER_BUFFER_BYTE`] × their size.
    pub fn new(buffers: Vec<Vec<u8>>) -> Self {
        let bytes: u64 = buffers.iter().map(|b| b.len() as u64).sum();
        let budget = BUDGET_BASE.saturating_add(bytes.saturating_mul(BUDGET_PER_BUFFER_BYTE));
        Data { buffers, budget: Cell::new(budget) }
    }

    /// Takes `count` items of `size` bytes from the budget, or says why not.
    pub fn charge(&self, count: usize, size: usize, what: &str) -> Result<(), String> {
        let bytes = (count as u64).saturating_mul(size as u64);
        match self.budget.get().checked_sub(bytes) {
            Some(left) => {
                self.budget.set(left);
                Ok(())
            }
            None => Err(format!(
                "{what}: {bytes} more bytes would exceed what the loader may produce from this file's buffers \
                 ({BUDGET_BASE} + {BUDGET_PER_BUFFER_BYTE} per buffer byte)"
            )),
        }
    }
}

/// The buffer lookup the gltf readers take.
pub fn getter<'s>(buffers: &'s [Vec<u8>]) -> impl Clone + Fn(Buffer<'_>) -> Option<&'s [u8]> {
    move |b: Buffer| buffers.get(b.index()).map(|d| d.as_slice())
}

fn type_name(d: DataType) -> &'static str {
    match d {
        DataType::I8 => "BYTE",
        DataType::U8 => "UNSIGNED_BYTE",
        DataType::I16 => "SHORT",
        DataType::U16 => "UNSIGNED_SHORT",
        DataType::U32 => "UNSIGNED_INT",
        DataType::F32 => "FLOAT",
    }
}

fn dims_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

/// Checks an accessor's element type against what a reader of it expects.
pub fn check(acc: &Accessor, dims: Dimensions, types: &[DataType]) -> Result<(), String> {
    if acc.dimensions() != dims || !types.contains(&acc.data_type()) {
        let expected: Vec<&str> = types.iter().map(|&t| type_name(t)).collect();
        return Err(format!(
            "accessor {} is {} {}, expected {} {}",
            acc.index(),
            dims_name(acc.dimensions()),
            type_name(acc.data_type()),
            dims_name(dims),
            expected.join("/")
        ));
    }
    if acc.count() == 0 {
        return Err(format!("accessor {} is empty", acc.index()));
    }
    Ok(())
}

/// All elements of an accessor whose type was checked to match `T`.
pub fn read<T: Item>(acc: &Accessor, data: &Data) -> Result<Vec<T>, String> {
    data.charge(acc.count(), std::mem::size_of::<T>().max(4), &format!("accessor {}", acc.index()))?;
    let out: Vec<T> = Iter::<T>::new(acc.clone(), getter(&data.buffers))
        .ok_or_else(|| format!("accessor {} has no data in range of its buffer view", acc.index()))?
        .collect();
    if out.len() != acc.count() {
        return Err(format!(
            "accessor {} declares {} elements but its buffer view holds {}",
            acc.index(),
            acc.count(),
            out.len()
        ));
    }
    Ok(out)
}

/// Reads a float accessor of the given shape.
pub fn floats<T: Item>(acc: &Accessor, dims: Dimensions, data: &Data) -> Result<Vec<T>, String> {
    check(acc, dims, &[DataType::F32])?;
    read(acc, data)
}

/// Reads an unsigned integer scalar accessor (indices) as u32.
pub fn indices(acc: &Accessor, data: &Data) -> Result<Vec<u32>, String> {
    check(acc, Dimensions::Scalar, &[DataType::U8, DataType::U16, DataType::U32])?;
    Ok(match acc.data_type() {
        DataType::U8 => read::<u8>(acc, data)?.into_iter().map(u32::from).collect(),
        DataType::U16 => read::<u16>(acc, data)?.into_iter().map(u32::from).collect(),
        _ => read::<u32>(acc, data)?,
    })
}

/// Reads a VEC4 accessor of floats or normalized unsigned integers as f32 in [0, 1].
pub fn unorm4(acc: &Accessor, data: &Data) -> Result<Vec<[f32; 4]>, String> {
    check(acc, Dimensions::Vec4, &[DataType::F32, DataType::U8, DataType::U16])?;
    Ok(match acc.data_type() {
        DataType::U8 => read::<[u8; 4]>(acc, data)?.into_iter().map(|v| v.map(|x| x as f32 / 255.0)).collect(),
        DataType::U16 => read::<[u16; 4]>(acc, data)?.into_iter().map(|v| v.map(|x| x as f32 / 65535.0)).collect(),
        _ => read::<[f32; 4]>(acc, data)?,
    })
}

/// Reads a VEC4 accessor of unsigned integers (joint indices).
pub fn uint4(acc: &Accessor, data: &Data) -> Result<Vec<[u16; 4]>, String> {
    check(acc, Dimensions::Vec4, &[DataType::U8, DataType::U16])?;
    Ok(match acc.data_type() {
        DataType::U8 => read::<[u8; 4]>(acc, data)?.into_iter().map(|v| v.map(u16::from)).collect(),
        _ => read::<[u16; 4]>(acc, data)?,
    })
}

/// Reads rotations: VEC4 floats or normalized signed integers.
pub fn quats(acc: &Accessor, data: &Data) -> Result<Vec<[f32; 4]>, String> {
    check(acc, Dimensions::Vec4, &[DataType::F32, DataType::I8, DataType::I16, DataType::U8, DataType::U16])?;
    Ok(match acc.data_type() {
        DataType::I8 => {
            read::<[i8; 4]>(acc, data)?.into_iter().map(|v| v.map(|x| (x as f32 / 127.0).max(-1.0))).collect()
        }
        DataType::I16 => {
            read::<[i16; 4]>(acc, data)?.into_iter().map(|v| v.map(|x| (x as f32 / 32767.0).max(-1.0))).collect()
        }
        DataType::U8 => read::<[u8; 4]>(acc, data)?.into_iter().map(|v| v.map(|x| x as f32 / 255.0)).collect(),
        DataType::U16 => read::<[u16; 4]>(acc, data)?.into_iter().map(|v| v.map(|x| x as f32 / 65535.0)).collect(),
        _ => read::<[f32; 4]>(acc, data)?,
    })
}
