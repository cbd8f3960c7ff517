//! How linear radiance becomes a display picture: exposure, a tone curve and, for a
//! transparent background, straight alpha. Only 8-bit output (PNG, the viewer) gets a look;
//! EXR output stays the linear, unscaled radiance the renderer computed.

use glam::Vec3;

use crate::srgb::linear_to_srgb8;

/// A tone curve from scene-referred linear radiance to display-referred linear [0, 1].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tonemap {
    /// Clamp to [0, 1]: what hemi always wrote.
    #[default]
    None,
    /// Khronos PBR Neutral (2024): identity-like below 0.76, hue-preserving roll-off above.
    KhronosNeutral,
    /// ACES filmic curve, Narkowicz's 2015 fit of the RRT+ODT, applied per channel without
    /// his 0.6 input scale (add `--exposure -0.74` for it).
    Aces,
}

impl Tonemap {
    /// Every curve.
    pub const ALL: [Tonemap; 3] = [Tonemap::None, Tonemap::KhronosNeutral, Tonemap::Aces];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            Tonemap::None => "none",
            Tonemap::KhronosNeutral => "khronos-neutral",
            Tonemap::Aces => "aces",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// The curve applied to linear `c` (finite, non-negative input gives [0, 1]).
    pub fn apply(self, c: Vec3) -> Vec3 {
        match self {
            Tonemap::None => c.clamp(Vec3::ZERO, Vec3::ONE),
            Tonemap::KhronosNeutral => khronos_neutral(c),
            Tonemap::Aces => Vec3::new(aces_narkowicz(c.x), aces_narkowicz(c.y), aces_narkowicz(c.z)),
        }
    }
}

/// Khronos PBR Neutral, as in the reference GLSL of the Khronos PBR Neutral specification.
pub fn khronos_neutral(color: Vec3) -> Vec3 {
    const START_COMPRESSION: f32 = 0.8 - 0.04;
    const DESATURATION: f32 = 0.15;
    let x = color.min_element();
    let offset = if x < 0.08 { x - 6.25 * x * x } else { 0.04 };
    let color = color - offset;
    let peak = color.max_element();
    if peak < START_COMPRESSION {
        return color;
    }
    let d = 1.0 - START_COMPRESSION;
    let new_peak = 1.0 - d * d / (peak + d - START_COMPRESSION);
    let color = color * (new_peak / peak);
    let g = 1.0 - 1.0 / (DESATURATION * (peak - new_peak) + 1.0);
    color.lerp(Vec3::splat(new_peak), g)
}

/// Narkowicz's ACES fit `x(2.51x + 0.03) / (x(2.43x + 0.59) + 0.14)`, clamped to [0, 1].
pub fn aces_narkowicz(x: f32) -> f32 {
    ((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)).clamp(0.0, 1.0)
}

/// Exposure and tone curve of 8-bit output.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Look {
    /// Stops: linear radiance is multiplied by 2^exposure before the tone curve.
    pub exposure: f32,
    /// The tone curve.
    pub tonemap: Tonemap,
}

impl Look {
    /// Whether this look leaves the clamped sRGB encoding of the image as it is.
    pub fn is_identity(&self) -> bool {
        self.exposure == 0.0 && self.tonemap == Tonemap::None
    }

    /// Display-referred linear colour of radiance `c`; not-a-number and negative parts give 0.
    pub fn map(&self, c: Vec3) -> Vec3 {
        let c = Vec3::select(c.cmpge(Vec3::ZERO), c, Vec3::ZERO);
        let scaled = if self.exposure == 0.0 { c } else { c * 2f32.powf(self.exposure) };
        // Every curve is flat (1) long before 1e9; beyond it x² would overflow into ∞/∞.
        self.tonemap.apply(scaled.min(Vec3::splat(1e9)))
    }

    /// 8-bit sRGB of radiance `c`.
    pub fn srgb8(&self, c: Vec3) -> [u8; 3] {
        let m = self.map(c);
        [linear_to_srgb8(m.x), linear_to_srgb8(m.y), linear_to_srgb8(m.z)]
    }

    /// 8-bit straight-alpha RGBA of a premultiplied pixel `c` with coverage `alpha`: the colour
    /// of the covered part (`c / alpha`) is mapped, then alpha is rounded to 8 bits.
    pub fn srgba8(&self, c: Vec3, alpha: f32) -> [u8; 4] {
        let a = if alpha.is_finite() { alpha.clamp(0.0, 1.0) } else { 0.0 };
        let [r, g, b] = if a > 0.0 { self.srgb8(c / a) } else { [0; 3] };
        [r, g, b, (a * 255.0).round() as u8]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn khronos_neutral_matches_hand_computed_points() {
        let grey = |v: f32| khronos_neutral(Vec3::splat(v)).x;
        // Below the compression start only the offset applies: v − 0.04 from 0.08 up,
        // 6.25 v² below.
        assert!((grey(0.5) - 0.46).abs() < 1e-6);
        assert!((grey(0.18) - 0.14).abs() < 1e-6);
        assert!((grey(0.04) - 0.01).abs() < 1e-7);
        assert_eq!(grey(0.0), 0.0);
        // 1.0: peak 0.96, new peak 1 − 0.24²/0.44 = 0.869 090 9.
        assert!((grey(1.0) - 0.869_090_9).abs() < 1e-6, "{}", grey(1.0));
        // A colour with a zero channel below the threshold is unchanged.
        let c = Vec3::new(0.7, 0.3, 0.0);
        assert_eq!(khronos_neutral(c), c);
        // Monotone in grey and below 1 everywhere.
        let mut last = -1.0;
        for k in 0..4000 {
            let v = grey(k as f32 * 0.01);
            assert!(v >= last && v < 1.0, "at {}", k as f32 * 0.01);
            last = v;
        }
        assert!(grey(1e30) <= 1.0);
    }

    #[test]
    fn aces_fit_matches_hand_computed_points() {
        assert_eq!(aces_narkowicz(0.0), 0.0);
        // 2.54 / 3.16 and 0.086724 / 0.324932.
        assert!((aces_narkowicz(1.0) - 0.803_797_5).abs() < 1e-6);
        assert!((aces_narkowicz(0.18) - 0.266_900).abs() < 1e-5);
        assert_eq!(aces_narkowicz(100.0), 1.0);
        let mut last = -1.0;
        for k in 0..2000 {
            let v = aces_narkowicz(k as f32 * 0.01);
            assert!(v >= last);
            last = v;
        }
    }

    #[test]
    fn the_default_look_is_the_clamped_srgb_encoding() {
        let look = Look::default();
        assert!(look.is_identity());
        for v in [0.0, 0.2, 0.5, 1.0, 7.0, f32::NAN, f32::INFINITY, -1.0] {
            assert_eq!(look.srgb8(Vec3::splat(v)), [linear_to_srgb8(v); 3], "{v}");
        }
        // One stop up doubles the radiance before encoding.
        let up = Look { exposure: 1.0, ..Default::default() };
        assert_eq!(up.srgb8(Vec3::splat(0.25)), [linear_to_srgb8(0.5); 3]);
        for t in Tonemap::ALL {
            let look = Look { tonemap: t, exposure: 3.0 };
            for v in [f32::NAN, f32::INFINITY, -5.0, 1e38] {
                let m = look.map(Vec3::splat(v));
                assert!(m.is_finite() && m.min_element() >= 0.0 && m.max_element() <= 1.0, "{t:?} {v}: {m}");
            }
        }
    }

    #[test]
    fn straight_alpha_undoes_the_premultiplication() {
        let look = Look::default();
        // Half covered by colour 0.5: the premultiplied pixel is 0.25.
        assert_eq!(look.srgba8(Vec3::splat(0.25), 0.5), [188, 188, 188, 128]);
        assert_eq!(look.srgba8(Vec3::ZERO, 0.0), [0, 0, 0, 0]);
        assert_eq!(look.srgba8(Vec3::splat(0.5), 1.0)[3], 255);
    }
}
