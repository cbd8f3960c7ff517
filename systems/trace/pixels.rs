//! The trace stage's pixels: the accumulation's per-pixel buffers cut into bands of rows and
//! each band into its tiles' row slices, so that tiles add their samples to their own pixels in
//! parallel; and what a tile reads of its pixels (their counts, whether adaptive sampling has
//! retired them, the camera ends kept from earlier frames).

use glam::{DVec3, Vec3};

use crate::{
    geometry::RayEnd,
    resources::{AOV_FLOATS, Accumulation, AovValues, Sums, merge_deviations, retired, standard_error},
};

/// A rectangle of pixels traced as one task.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tile {
    pub(super) x0: u32,
    pub(super) y0: u32,
    pub(super) x1: u32,
    pub(super) y1: u32,
}

/// The pixels one tile owns: a slice per row of each per-pixel buffer (no rows for a buffer
/// the render does not keep), cut from the image's buffers so that tiles write in parallel.
pub(super) struct TilePixels<'a> {
    pub(super) tile: Tile,
    width: u32,
    /// Samples every pixel has when the accumulation keeps no per-pixel counts.
    spp: u32,
    one_frame_sums: Vec<&'a mut [Vec3]>,
    sums: Vec<&'a mut [DVec3]>,
    counts: Vec<&'a mut [u32]>,
    deviations: Vec<&'a mut [f64]>,
    one_frame_aovs: Vec<&'a mut [AovValues]>,
    aovs: Vec<&'a mut [[f64; AOV_FLOATS]]>,
    frame_sums: Vec<&'a mut [Vec3]>,
    /// Where each pixel's camera ray ends ([`Accumulation::camera_ends`]; no rows where it is
    /// not kept).
    camera_ends: Vec<&'a mut [RayEnd]>,
    /// The light of the groups that draw no samples at those ends
    /// ([`Accumulation::camera_light`]; no rows where it is not kept).
    camera_light: Vec<&'a mut [Vec3]>,
}

impl TilePixels<'_> {
    /// Row `y`'s kept camera ends and light, where the accumulation keeps them for `groups`
    /// light groups that draw no samples.
    pub(super) fn kept_row(&mut self, y: u32, groups: usize) -> Option<KeptRow<'_>> {
        let r = (y - self.tile.y0) as usize;
        let ends = self.camera_ends.get_mut(r)?;
        let light = match self.camera_light.get_mut(r) {
            Some(light) => &mut **light,
            None => &mut [],
        };
        (light.len() == ends.len() * groups).then_some(KeptRow {
            ends,
            light,
            groups,
            x0: self.tile.x0,
            width: self.width,
        })
    }

    /// The pixels of row `y` this frame samples, as (column, pixel, number of its first sample,
    /// counted from `first_sample`) into `out`; returns how many of them are `timed`.
    pub(super) fn row_to_trace(
        &self,
        y: u32,
        (first_sample, target): (u32, Option<f32>),
        timed: impl Fn(u32) -> bool,
        out: &mut Vec<(u32, u32, u32)>,
    ) -> u64 {
        out.clear();
        let mut n = 0;
        for x in self.tile.x0..self.tile.x1 {
            let pixel = y * self.width + x;
            if !self.pixel_done((x, y), target) {
                out.push((x, pixel, first_sample.wrapping_add(self.count((x, y)))));
                n += u64::from(timed(pixel));
            }
        }
        n
    }

    /// Row and column inside the tile of image pixel (x, y).
    #[inline]
    fn at(&self, (x, y): (u32, u32)) -> (usize, usize) {
        ((y - self.tile.y0) as usize, (x - self.tile.x0) as usize)
    }

    /// Samples image pixel (x, y) has accumulated.
    #[inline]
    pub(super) fn count(&self, xy: (u32, u32)) -> u32 {
        let (r, c) = self.at(xy);
        self.count_at(r, c)
    }

    /// Samples the pixel at row `r`, column `c` of the tile has accumulated.
    #[inline]
    fn count_at(&self, r: usize, c: usize) -> u32 {
        self.counts.get(r).map_or(self.spp, |row| row[c])
    }

    /// The radiance sum of the pixel at row `r`, column `c` of the tile.
    #[inline]
    fn sum(&self, r: usize, c: usize) -> DVec3 {
        self.sums.get(r).map_or_else(|| self.one_frame_sums[r][c].as_dvec3(), |row| row[c])
    }

    /// Whether adaptive sampling has retired image pixel (x, y) for target error `e` (as
    /// [`Accumulation::pixel_done`]).
    #[inline]
    pub(super) fn pixel_done(&self, xy: (u32, u32), target: Option<f32>) -> bool {
        target.is_some_and(|e| {
            let (r, c) = self.at(xy);
            let count = self.count_at(r, c);
            retired(count, || standard_error(count, self.deviations[r][c]), e)
        })
    }

    /// Adds the tile's frame samples, row-major over the tile, to its pixels: their sums,
    /// counts, luminances' squared deviations from their mean (adaptive sampling) and AOVs.
    pub(super) fn add(&mut self, sums: &[Vec3], counts: &[u32], deviations: &[f64], aovs: &[AovValues]) {
        let w = (self.tile.x1 - self.tile.x0) as usize;
        if !self.deviations.is_empty() {
            // Before the sums and counts take the frame's: merged with the pixel's earlier mean.
            let rows = sums.chunks(w).zip(counts.chunks(w)).zip(deviations.chunks(w));
            for (r, ((sums, counts), deviations)) in rows.enumerate() {
                for (c, ((&sum, &count), &frame)) in sums.iter().zip(counts).zip(deviations).enumerate() {
                    let before = (self.count_at(r, c), self.sum(r, c));
                    merge_deviations(&mut self.deviations[r][c], before, (count, sum.as_dvec3(), frame));
                }
            }
        }
        // 0 + x rounds alike in f32 and f64: one frame's f32 sum is the f64 sum's value.
        fold(&mut self.one_frame_sums, sums, w, |s, a| *s += *a);
        fold(&mut self.sums, sums, w, |s, a| *s += a.as_dvec3());
        fold(&mut self.counts, counts, w, |s, a| *s += a);
        fold(&mut self.one_frame_aovs, aovs, w, |s, a| s.iter_mut().zip(a).for_each(|(s, a)| *s += *a));
        fold(&mut self.aovs, aovs, w, |s, a| s.iter_mut().zip(a).for_each(|(s, a)| *s += *a as f64));
        fold(&mut self.frame_sums, sums, w, |s, a| *s = *a);
    }
}

/// One row's kept camera ends and light ([`TilePixels::kept_row`]): a tile's row, from
/// column `x0` of an image `width` wide; `groups` light values per pixel.
pub(super) struct KeptRow<'a> {
    pub(super) ends: &'a mut [RayEnd],
    pub(super) light: &'a mut [Vec3],
    pub(super) groups: usize,
    pub(super) x0: u32,
    pub(super) width: u32,
}

/// Applies `f` to each pixel of `rows` and its value in `values` (row-major, `w` per row).
fn fold<T, U>(rows: &mut [&mut [T]], values: &[U], w: usize, f: impl Fn(&mut T, &U)) {
    for (row, values) in rows.iter_mut().zip(values.chunks(w)) {
        row.iter_mut().zip(values).for_each(|(d, v)| f(d, v));
    }
}

/// `size` rows of each per-pixel buffer (empty: a buffer the render does not keep).
pub(super) struct Band<'a> {
    y0: u32,
    y1: u32,
    spp: u32,
    one_frame_sums: &'a mut [Vec3],
    sums: &'a mut [DVec3],
    counts: &'a mut [u32],
    deviations: &'a mut [f64],
    one_frame_aovs: &'a mut [AovValues],
    aovs: &'a mut [[f64; AOV_FLOATS]],
    frame_sums: &'a mut [Vec3],
    camera_ends: &'a mut [RayEnd],
    camera_light: &'a mut [Vec3],
    /// Entries of `camera_light` per pixel.
    light_groups: usize,
}

impl<'a> Band<'a> {
    /// The band's tiles, left to right, `size` pixels wide.
    pub(super) fn tiles(self, width: u32, size: u32) -> Vec<TilePixels<'a>> {
        let mut one_frame_sums = tile_rows(self.one_frame_sums, width, size);
        let mut sums = tile_rows(self.sums, width, size);
        let mut counts = tile_rows(self.counts, width, size);
        let mut deviations = tile_rows(self.deviations, width, size);
        let mut one_frame_aovs = tile_rows(self.one_frame_aovs, width, size);
        let mut aovs = tile_rows(self.aovs, width, size);
        let mut frame_sums = tile_rows(self.frame_sums, width, size);
        let mut camera_ends = tile_rows(self.camera_ends, width, size);
        let g = self.light_groups.max(1) as u32;
        let mut camera_light = tile_rows(self.camera_light, width * g, size * g);
        (0..width.div_ceil(size))
            .map(|i| TilePixels {
                tile: Tile { x0: i * size, y0: self.y0, x1: ((i + 1) * size).min(width), y1: self.y1 },
                width,
                spp: self.spp,
                one_frame_sums: one_frame_sums.next().unwrap_or_default(),
                sums: sums.next().unwrap_or_default(),
                counts: counts.next().unwrap_or_default(),
                deviations: deviations.next().unwrap_or_default(),
                one_frame_aovs: one_frame_aovs.next().unwrap_or_default(),
                aovs: aovs.next().unwrap_or_default(),
                frame_sums: frame_sums.next().unwrap_or_default(),
                camera_ends: camera_ends.next().unwrap_or_default(),
                camera_light: camera_light.next().unwrap_or_default(),
            })
            .collect()
    }
}

/// Cuts the accumulation's buffers and the frame's kept sums into bands of `size` rows.
pub(super) fn bands<'a>(acc: &'a mut Accumulation, frame_sums: &'a mut [Vec3], width: u32, size: u32) -> Vec<Band<'a>> {
    let height = (acc.sums.len() / width as usize) as u32;
    let (len, count) = (width as usize * size as usize, height.div_ceil(size) as usize);
    let (one_frame_sums, sums): (&mut [Vec3], &mut [DVec3]) = match &mut acc.sums {
        Sums::OneFrame(v) => (v, &mut []),
        Sums::Frames(v) => (&mut [], v),
    };
    let mut one_frame_sums = split(one_frame_sums, len, count);
    let mut sums = split(sums, len, count);
    let mut counts = split(&mut acc.counts, len, count);
    let mut deviations = split(&mut acc.deviations, len, count);
    let (one_frame_aovs, aovs): (&mut [AovValues], &mut [[f64; AOV_FLOATS]]) = match &mut acc.aovs {
        Sums::OneFrame(v) => (v, &mut []),
        Sums::Frames(v) => (&mut [], v),
    };
    let mut one_frame_aovs = split(one_frame_aovs, len, count);
    let mut aovs = split(aovs, len, count);
    let mut frame = split(frame_sums, len, count);
    let light_groups = acc.camera_light.len().checked_div(acc.camera_ends.len()).unwrap_or(0);
    let mut camera_ends = split(&mut acc.camera_ends, len, count);
    let mut camera_light = split(&mut acc.camera_light, len * light_groups.max(1), count);
    (0..count as u32)
        .filter_map(|b| {
            Some(Band {
                y0: b * size,
                y1: ((b + 1) * size).min(height),
                spp: acc.spp,
                one_frame_sums: one_frame_sums.next()?,
                sums: sums.next()?,
                counts: counts.next()?,
                deviations: deviations.next()?,
                one_frame_aovs: one_frame_aovs.next()?,
                aovs: aovs.next()?,
                frame_sums: frame.next()?,
                camera_ends: camera_ends.next()?,
                camera_light: camera_light.next()?,
                light_groups,
            })
        })
        .collect()
}

/// `buffer` in `count` chunks of `len` (empty ones for an empty buffer).
fn split<T>(buffer: &mut [T], len: usize, count: usize) -> impl Iterator<Item = &mut [T]> {
    buffer.chunks_mut(len).chain(std::iter::repeat_with(|| -> &mut [T] { &mut [] })).take(count)
}

/// A band's rows cut at the tile edges: each tile's row slices, left to right (nothing for an
/// empty band).
fn tile_rows<T>(band: &mut [T], width: u32, size: u32) -> impl Iterator<Item = Vec<&mut [T]>> {
    let mut tiles: Vec<Vec<&mut [T]>> = Vec::new();
    for row in band.chunks_mut(width as usize) {
        tiles.resize_with(width.div_ceil(size) as usize, Vec::new);
        for (tile, piece) in tiles.iter_mut().zip(row.chunks_mut(size as usize)) {
            tile.push(piece);
        }
    }
    tiles.into_iter()
}
