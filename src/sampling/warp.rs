//! Maps from the unit square to the unit disk and to the hemisphere.

use std::f32::consts::{FRAC_PI_4, PI};

use glam::{Vec2, Vec3};

/// Shirley–Chiu concentric mapping of [0,1)² onto the unit disk: area-preserving, low
/// distortion, and continuous, so stratification survives the mapping.
#[inline]
pub fn concentric_disk(u: Vec2) -> Vec2 {
    let a = 2.0 * u.x - 1.0;
    let b = 2.0 * u.y - 1.0;
    if a == 0.0 && b == 0.0 {
        return Vec2::ZERO;
    }
    let (r, phi) =
        if a.abs() > b.abs() { (a, FRAC_PI_4 * (b / a)) } else { (b, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (a / b)) };
    Vec2::new(r * phi.cos(), r * phi.sin())
}

/// A direction on the hemisphere around +z with density ∝ cos^e θ, and its weight for an
/// estimate of the cosine-weighted integral (1/π)∫ f cos θ dω.
#[derive(Clone, Copy, Debug)]
pub struct HemisphereSample {
    /// Unit direction, z ≥ 0.
    pub dir: Vec3,
    /// cos θ / (π · pdf): exactly 1 for e = 1; 2 cos^{1−e} θ / (e + 1) in general; 0 where the
    /// pdf vanishes.
    pub weight: f32,
}

/// RTGU's cosine-power mapping (Suffern §7.3): φ = 2π u₀, cos θ = (1 − u₁)^{1/(e+1)}.
/// The pdf is (e+1)/(2π) cos^e θ; the returned weight makes the AO estimate unbiased for any e.
#[inline]
pub fn cosine_power_hemisphere(u: Vec2, e: f32) -> HemisphereSample {
    let phi = 2.0 * PI * u.x;
    let cos_theta = if e == 1.0 { (1.0 - u.y).sqrt() } else { (1.0 - u.y).powf(1.0 / (e + 1.0)) };
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let dir = Vec3::new(sin_theta * phi.cos(), sin_theta * phi.sin(), cos_theta);
    let weight = if e == 1.0 {
        1.0
    } else if cos_theta > 0.0 {
        2.0 * cos_theta.powf(1.0 - e) / (e + 1.0)
    } else {
        0.0
    };
    HemisphereSample { dir, weight: if weight.is_finite() { weight } else { 0.0 } }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::hash::SplitMix64;

    fn uniform_points(n: usize, seed: u64) -> Vec<Vec2> {
        let mut rng = SplitMix64::new(seed);
        (0..n).map(|_| Vec2::new(rng.next_f32(), rng.next_f32())).collect()
    }

    #[test]
    fn concentric_disk_stays_inside_and_is_area_preserving() {
        // Chi-square test of uniformity over 8 rings × 8 sectors of equal area.
        let n = 200_000;
        let (rings, sectors) = (8usize, 8usize);
        let mut counts = vec![0f64; rings * sectors];
        for u in uniform_points(n, 7) {
            let p = concentric_disk(u);
            let r2 = p.length_squared();
            assert!(r2 <= 1.0 + 1e-6, "{p} outside the disk");
            let ring = ((r2 * rings as f32) as usize).min(rings - 1);
            let angle = p.y.atan2(p.x).rem_euclid(2.0 * PI);
            let sector = ((angle / (2.0 * PI) * sectors as f32) as usize).min(sectors - 1);
            counts[ring * sectors + sector] += 1.0;
        }
        let expected = n as f64 / counts.len() as f64;
        let chi2: f64 = counts.iter().map(|c| (c - expected).powi(2) / expected).sum();
        // 63 degrees of freedom: the 99.9 % quantile is 103.4.
        assert!(chi2 < 103.4, "chi² = {chi2}");
    }

    #[test]
    fn concentric_disk_maps_corners_and_centre() {
        assert_eq!(concentric_disk(Vec2::splat(0.5)), Vec2::ZERO);
        let c = concentric_disk(Vec2::new(1.0, 1.0));
        assert!((c.length() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn hemisphere_mean_cosine_matches_cos_power_density() {
        // Under density ∝ cos^e θ, E[cos θ] = (e + 1) / (e + 2).
        let n = 400_000;
        let pts = uniform_points(n, 11);
        for e in [0.0f32, 1.0, 2.0, 5.0, 20.0] {
            let mut sum = 0.0f64;
            let mut sum2 = 0.0f64;
            for &u in &pts {
                let s = cosine_power_hemisphere(u, e);
                assert!(s.dir.z >= 0.0 && (s.dir.length() - 1.0).abs() < 1e-5);
                sum += s.dir.z as f64;
                sum2 += (s.dir.z as f64).powi(2);
            }
            let mean = sum / n as f64;
            let sd = ((sum2 / n as f64 - mean * mean) / n as f64).sqrt();
            let expected = (e as f64 + 1.0) / (e as f64 + 2.0);
            assert!((mean - expected).abs() < 4.0 * sd + 1e-6, "e={e}: {mean} vs {expected}");
        }
    }

    #[test]
    fn weighted_hemisphere_estimate_is_unbiased_for_any_exponent() {
        // (1/π)∫ cos θ dω over the hemisphere = 1; so is the mean weight, for every e.
        // For the partial integral over θ < 60°: (1/π)∫ cos θ dω = sin² 60° = 0.75.
        let n = 400_000;
        let pts = uniform_points(n, 5);
        for e in [0.0f32, 1.0, 3.0] {
            let (mut full, mut cap, mut cap2) = (0.0f64, 0.0f64, 0.0f64);
            for &u in &pts {
                let s = cosine_power_hemisphere(u, e);
                full += s.weight as f64;
                let v = if s.dir.z > 0.5 { s.weight as f64 } else { 0.0 };
                cap += v;
                cap2 += v * v;
            }
            let mean = cap / n as f64;
            let sd = ((cap2 / n as f64 - mean * mean) / n as f64).sqrt();
            assert!((mean - 0.75).abs() < 4.0 * sd, "e={e}: cap {mean}");
            if e == 1.0 {
                assert_eq!(full, n as f64, "e = 1 weights must be exactly 1");
            }
        }
    }
}
