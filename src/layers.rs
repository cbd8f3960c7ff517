//! The beauty image and its AOVs as one multi-layer EXR, with the channel names Blender and
//! Nuke read as layers: `R G B A`, `ao`, `direct.R/G/B`, `albedo.R/G/B`, `N.X/Y/Z`, `Z`.

use std::io::{Seek, Write};

use exr::prelude::{
    AnyChannel, AnyChannels, Encoding, FlatSamples, Image as ExrImage, Layer, LayerAttributes, SmallVec, WritableImage,
};

use crate::resources::{Aov, Image};

/// The EXR channel names of an AOV's components, in the order [`Aov::range`] lays them out.
pub fn channel_names(aov: Aov) -> &'static [&'static str] {
    match aov {
        Aov::Ao => &["ao"],
        Aov::Direct => &["direct.R", "direct.G", "direct.B"],
        Aov::Albedo => &["albedo.R", "albedo.G", "albedo.B"],
        Aov::Normal => &["N.X", "N.Y", "N.Z"],
        Aov::Depth => &["Z"],
        Aov::Alpha => &["A"],
    }
}

/// Encodes the linear beauty image (`R`, `G`, `B`) and the AOVs `aovs` of `image`, plus
/// coverage as `A` whenever the image has AOVs, as one 32-bit float EXR into `out` (the file
/// itself: the encoded image is never held whole in memory). AOVs the image did not
/// accumulate are left out.
pub fn write_layered_exr(image: &Image, aovs: &[Aov], out: &mut (impl Write + Seek)) -> Result<(), String> {
    let (w, h) = (image.width as usize, image.height as usize);
    let mut list: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (c, name) in ["R", "G", "B"].into_iter().enumerate() {
        list.push(AnyChannel::new(name, FlatSamples::F32(image.linear.iter().map(|p| p[c]).collect())));
    }
    let has_aovs = !image.aovs.is_empty() && image.aovs.len() == image.linear.len();
    let mut wanted: Vec<Aov> = aovs.to_vec();
    if has_aovs && !wanted.contains(&Aov::Alpha) {
        wanted.push(Aov::Alpha);
    }
    for aov in wanted.into_iter().filter(|_| has_aovs) {
        for (k, name) in aov.range().zip(channel_names(aov)) {
            list.push(AnyChannel::new(*name, FlatSamples::F32(image.aovs.iter().map(|v| v[k]).collect())));
        }
    }
    let layer = Layer::new(
        (w, h),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    ExrImage::from_layer(layer).write().to_buffered(out).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use std::io::Cursor;

    use exr::prelude::{ReadChannels, ReadLayers};
    use glam::Vec3;

    use super::*;

    #[test]
    fn every_channel_reads_back_under_its_name() {
        let mut aov = [0.0f32; crate::resources::AOV_FLOATS];
        for (k, v) in aov.iter_mut().enumerate() {
            *v = k as f32 + 0.5;
        }
        let image = Image { width: 1, height: 1, linear: vec![Vec3::new(1.0, 2.0, 3.0)], aovs: vec![aov] };
        let mut bytes = Cursor::new(Vec::new());
        write_layered_exr(&image, &[Aov::Ao, Aov::Direct, Aov::Albedo, Aov::Normal, Aov::Depth], &mut bytes).unwrap();
        bytes.set_position(0);
        let read = exr::prelude::read()
            .no_deep_data()
            .largest_resolution_level()
            .all_channels()
            .first_valid_layer()
            .all_attributes()
            .from_buffered(bytes)
            .unwrap();
        let mut got: Vec<(String, f32)> = read
            .layer_data
            .channel_data
            .list
            .iter()
            .map(|c| (c.name.to_string(), c.sample_data.value_by_flat_index(0).to_f32()))
            .collect();
        got.sort_by(|a, b| a.1.total_cmp(&b.1));
        let expected = [
            ("ao", 0.5),
            ("R", 1.0),
            ("direct.R", 1.5),
            ("G", 2.0),
            ("direct.G", 2.5),
            ("B", 3.0),
            ("direct.B", 3.5),
            ("albedo.R", 4.5),
            ("albedo.G", 5.5),
            ("albedo.B", 6.5),
            ("N.X", 7.5),
            ("N.Y", 8.5),
            ("N.Z", 9.5),
            ("Z", 10.5),
            ("A", 11.5),
        ];
        let expected: Vec<(String, f32)> = expected.iter().map(|(n, v)| (n.to_string(), *v)).collect();
        assert_eq!(got, expected);
    }
}
