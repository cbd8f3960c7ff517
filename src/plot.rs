//! A small log-log line plot rasteriser for convergence curves (PNG output via `image`).

use font8x8::legacy::BASIC_LEGACY;
use image::{Rgb, RgbImage};

/// One named curve.
pub struct Series {
    /// Legend text.
    pub label: String,
    /// (x, y) points, both > 0.
    pub points: Vec<(f64, f64)>,
}

/// Colours for up to eight series (then they repeat).
const PALETTE: [[u8; 3]; 8] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
    [227, 119, 194],
    [23, 190, 207],
];

/// Draws a log-log panel of `series` into `img` within the rectangle (x0, y0, w, h).
pub fn draw_panel(
    img: &mut RgbImage,
    (x0, y0, w, h): (i32, i32, i32, i32),
    title: &str,
    x_label: &str,
    series: &[Series],
) {
    let all = series.iter().flat_map(|s| s.points.iter()).filter(|(x, y)| *x > 0.0 && *y > 0.0);
    let (mut xmin, mut xmax, mut ymin, mut ymax) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in all {
        xmin = xmin.min(x);
        xmax = xmax.max(x);
        ymin = ymin.min(y);
        ymax = ymax.max(y);
    }
    if xmin > xmax {
        return;
    }
    let (lx0, lx1) = (xmin.log10().floor(), xmax.log10().ceil().max(xmin.log10().floor() + 1.0));
    let (ly0, ly1) = (ymin.log10().floor(), ymax.log10().ceil().max(ymin.log10().floor() + 1.0));
    let (px0, py0, pw, ph) = (x0 + 56, y0 + 24, w - 72, h - 60);
    let to_px = |x: f64, y: f64| {
        let u = (x.log10() - lx0) / (lx1 - lx0);
        let v = (y.log10() - ly0) / (ly1 - ly0);
        (px0 as f64 + u * pw as f64, (py0 + ph) as f64 - v * ph as f64)
    };
    let grid = Rgb([225, 225, 225]);
    let axis = Rgb([40, 40, 40]);
    for d in lx0 as i32..=lx1 as i32 {
        let (x, _) = to_px(10f64.powi(d), 10f64.powf(ly0));
        line(img, (x, py0 as f64), (x, (py0 + ph) as f64), grid);
        text(img, x as i32 - 12, py0 + ph + 6, &format!("1e{d}"), axis);
    }
    for d in ly0 as i32..=ly1 as i32 {
        let (_, y) = to_px(10f64.powf(lx0), 10f64.powi(d));
        line(img, (px0 as f64, y), ((px0 + pw) as f64, y), grid);
        text(img, x0 + 4, y as i32 - 4, &format!("1e{d}"), axis);
    }
    line(img, (px0 as f64, (py0 + ph) as f64), ((px0 + pw) as f64, (py0 + ph) as f64), axis);
    line(img, (px0 as f64, py0 as f64), (px0 as f64, (py0 + ph) as f64), axis);
    text(img, px0, y0 + 6, title, axis);
    text(img, px0 + pw / 2 - 4 * x_label.len() as i32, py0 + ph + 22, x_label, axis);
    for (k, s) in series.iter().enumerate() {
        let c = Rgb(PALETTE[k % PALETTE.len()]);
        let pts: Vec<(f64, f64)> =
            s.points.iter().filter(|(x, y)| *x > 0.0 && *y > 0.0).map(|&(x, y)| to_px(x, y)).collect();
        for w in pts.windows(2) {
            line(img, w[0], w[1], c);
        }
        for &(x, y) in &pts {
            for dy in -2..=2 {
                for dx in -2..=2 {
                    put(img, x as i32 + dx, y as i32 + dy, c);
                }
            }
        }
        let ly = py0 + 8 + 12 * k as i32;
        for dx in 0..14 {
            put(img, px0 + pw - 230 + dx, ly + 3, c);
            put(img, px0 + pw - 230 + dx, ly + 4, c);
        }
        text(img, px0 + pw - 212, ly, &s.label, axis);
    }
}

fn put(img: &mut RgbImage, x: i32, y: i32, c: Rgb<u8>) {
    if x >= 0 && y >= 0 && (x as u32) < img.width() && (y as u32) < img.height() {
        img.put_pixel(x as u32, y as u32, c);
    }
}

fn line(img: &mut RgbImage, (x0, y0): (f64, f64), (x1, y1): (f64, f64), c: Rgb<u8>) {
    let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as i32;
    for i in 0..=steps {
        let t = i as f64 / steps as f64;
        put(img, (x0 + (x1 - x0) * t).round() as i32, (y0 + (y1 - y0) * t).round() as i32, c);
    }
}

/// Writes ASCII `s` with the 8×8 font, top-left at (x, y).
pub fn text(img: &mut RgbImage, x: i32, y: i32, s: &str, c: Rgb<u8>) {
    for (i, ch) in s.chars().enumerate() {
        let glyph = BASIC_LEGACY.get(ch as usize).copied().unwrap_or([0; 8]);
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits >> col & 1 == 1 {
                    put(img, x + 8 * i as i32 + col, y + row as i32, c);
                }
            }
        }
    }
}
