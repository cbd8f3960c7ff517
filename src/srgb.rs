//! The sRGB transfer function and the exact 8-bit sRGB encoding of linear values, shared by
//! the images hemi writes, the looks applied to them and the viewer's window.

/// sRGB transfer function of a linear value, clamped to [0, 1]; NaN maps to 0.
#[inline]
pub fn linear_to_srgb(v: f32) -> f32 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    if v <= 0.003_130_8 { v * 12.92 } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 }
}

/// Inverse sRGB transfer function (for encoding thresholds).
fn srgb_to_linear(s: f64) -> f64 {
    if s <= 0.040_45 { s / 12.92 } else { ((s + 0.055) / 1.055).powf(2.4) }
}

/// Linear value at which each 8-bit sRGB code starts: code k covers `[T[k-1], T[k])`.
static SRGB8_THRESHOLDS: std::sync::LazyLock<[f32; 255]> =
    std::sync::LazyLock::new(|| std::array::from_fn(|k| srgb_to_linear((k as f64 + 0.5) / 255.0) as f32));

/// Low bits dropped from a positive float's bit pattern to index [`SRGB8_BUCKETS`]: buckets
/// 1/128 of an octave wide, narrower than the gap between any two code thresholds.
const BUCKET_SHIFT: u32 = 16;

/// For each bucket of floats from the first threshold up (by bit pattern), the code of its
/// smallest value: the number of thresholds at or below it.
static SRGB8_BUCKETS: std::sync::LazyLock<Vec<u8>> = std::sync::LazyLock::new(|| {
    let t = &*SRGB8_THRESHOLDS;
    let (first, last) = (t[0].to_bits(), t[254].to_bits());
    (0..=(last - first) >> BUCKET_SHIFT)
        .map(|b| t.partition_point(|&x| x <= f32::from_bits(first + (b << BUCKET_SHIFT))) as u8)
        .collect()
});

/// 8-bit sRGB code of a linear value (round to nearest): the number of code thresholds at or
/// below it, found from its bucket's code plus at most one step (a bucket is narrower than any
/// gap between thresholds; the loop does not rely on it). Exact, as a binary search over the
/// thresholds is.
#[inline]
pub fn linear_to_srgb8(v: f32) -> u8 {
    let t = &*SRGB8_THRESHOLDS;
    // NaN maps to 0, with everything below the first threshold.
    if v.is_nan() || v < t[0] {
        return 0;
    }
    if v >= t[254] {
        return 255;
    }
    // A positive float's bits grow with it, so buckets split the range in order.
    let mut code = SRGB8_BUCKETS[((v.to_bits() - t[0].to_bits()) >> BUCKET_SHIFT) as usize] as usize;
    while t[code] <= v {
        code += 1;
    }
    code as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srgb_encoding_matches_the_standard() {
        assert_eq!(linear_to_srgb8(0.0), 0);
        assert_eq!(linear_to_srgb8(1.0), 255);
        assert_eq!(linear_to_srgb8(0.5), 188); // 0.7354 · 255 = 187.5
        assert!((linear_to_srgb(0.214_041) - 0.5).abs() < 1e-5);
        assert_eq!(linear_to_srgb8(f32::NAN), 0);
        assert_eq!(linear_to_srgb8(7.0), 255);
        assert!((linear_to_srgb(0.002) - 0.02584).abs() < 1e-6);
    }

    /// The bucketed search gives the binary search's code for every float between the first
    /// and last thresholds (each threshold, its neighbours, and every bucket's edges) and
    /// outside them.
    #[test]
    fn bucketed_encoding_equals_the_binary_search() {
        let search = |v: f32| if v.is_nan() { 0 } else { SRGB8_THRESHOLDS.partition_point(|&t| t <= v) as u8 };
        let t = &*SRGB8_THRESHOLDS;
        let mut values = vec![f32::NAN, -1.0, -0.0, 0.0, 1e-30, 1.0, 7.0, f32::INFINITY];
        for &x in t.iter() {
            values.extend([f32::from_bits(x.to_bits() - 1), x, f32::from_bits(x.to_bits() + 1)]);
        }
        for b in 0..SRGB8_BUCKETS.len() as u32 {
            let edge = t[0].to_bits() + (b << BUCKET_SHIFT);
            values.extend([f32::from_bits(edge - 1), f32::from_bits(edge), f32::from_bits(edge + 1)]);
        }
        let mut rng = crate::random::SplitMix64::new(10);
        values.extend((0..100_000).map(|_| rng.next_f32()));
        for v in values {
            assert_eq!(linear_to_srgb8(v), search(v), "v = {v:e}");
        }
    }

    #[test]
    fn table_encoding_equals_the_transfer_function() {
        let mut rng = crate::random::SplitMix64::new(9);
        for i in 0..200_000 {
            let v = if i % 2 == 0 { rng.next_f32() } else { rng.next_f32() * 0.01 };
            let exact = linear_to_srgb(v) as f64 * 255.0;
            let code = linear_to_srgb8(v);
            // Equal, except within float rounding of a half-code boundary.
            if (exact - exact.floor() - 0.5).abs() > 1e-3 {
                assert_eq!(code, exact.round() as u8, "v = {v}");
            }
        }
    }
}
