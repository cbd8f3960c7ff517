//! Typed, checked reads of glTF accessors. gltf 1.4 reads whatever bytes an accessor points
//! at (and panics on FLOAT indices), so every read here first checks the accessor's type and
//! then that it yields exactly `count` elements; any mismatch is a one-line error.

use ::gltf::{
    Accessor,
    accessor::{DataType, Dimensions, Item, Iter},
    buffer::Buffer,
};

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
pub fn read<T: Item>(acc: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<T>, String> {
    let out: Vec<T> = Iter::<T>::new(acc.clone(), getter(buffers))
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
pub fn floats<T: Item>(acc: &Accessor, dims: Dimensions, buffers: &[Vec<u8>]) -> Result<Vec<T>, String> {
    check(acc, dims, &[DataType::F32])?;
    read(acc, buffers)
}

/// Reads an unsigned integer scalar accessor (indices) as u32.
pub fn indices(acc: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<u32>, String> {
    check(acc, Dimensions::Scalar, &[DataType::U8, DataType::U16, DataType::U32])?;
    Ok(match acc.data_type() {
        DataType::U8 => read::<u8>(acc, buffers)?.into_iter().map(u32::from).collect(),
        DataType::U16 => read::<u16>(acc, buffers)?.into_iter().map(u32::from).collect(),
        _ => read::<u32>(acc, buffers)?,
    })
}

/// Reads a VEC4 accessor of floats or normalized unsigned integers as f32 in [0, 1].
pub fn unorm4(acc: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<[f32; 4]>, String> {
    check(acc, Dimensions::Vec4, &[DataType::F32, DataType::U8, DataType::U16])?;
    Ok(match acc.data_type() {
        DataType::U8 => read::<[u8; 4]>(acc, buffers)?.into_iter().map(|v| v.map(|x| x as f32 / 255.0)).collect(),
        DataType::U16 => read::<[u16; 4]>(acc, buffers)?.into_iter().map(|v| v.map(|x| x as f32 / 65535.0)).collect(),
        _ => read::<[f32; 4]>(acc, buffers)?,
    })
}

/// Reads a VEC4 accessor of unsigned integers (joint indices).
pub fn uint4(acc: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<[u16; 4]>, String> {
    check(acc, Dimensions::Vec4, &[DataType::U8, DataType::U16])?;
    Ok(match acc.data_type() {
        DataType::U8 => read::<[u8; 4]>(acc, buffers)?.into_iter().map(|v| v.map(u16::from)).collect(),
        _ => read::<[u16; 4]>(acc, buffers)?,
    })
}

/// Reads rotations: VEC4 floats or normalized signed integers.
pub fn quats(acc: &Accessor, buffers: &[Vec<u8>]) -> Result<Vec<[f32; 4]>, String> {
    check(acc, Dimensions::Vec4, &[DataType::F32, DataType::I8, DataType::I16, DataType::U8, DataType::U16])?;
    Ok(match acc.data_type() {
        DataType::I8 => {
            read::<[i8; 4]>(acc, buffers)?.into_iter().map(|v| v.map(|x| (x as f32 / 127.0).max(-1.0))).collect()
        }
        DataType::I16 => {
            read::<[i16; 4]>(acc, buffers)?.into_iter().map(|v| v.map(|x| (x as f32 / 32767.0).max(-1.0))).collect()
        }
        DataType::U8 => read::<[u8; 4]>(acc, buffers)?.into_iter().map(|v| v.map(|x| x as f32 / 255.0)).collect(),
        DataType::U16 => read::<[u16; 4]>(acc, buffers)?.into_iter().map(|v| v.map(|x| x as f32 / 65535.0)).collect(),
        _ => read::<[f32; 4]>(acc, buffers)?,
    })
}
