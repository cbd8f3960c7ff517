//! Maps from the unit square to the unit disk and to the hemisphere.

use std::f32::consts::{FRAC_PI_4, TAU};

use glam::{Vec2, Vec3, Vec4};

use crate::math::Onb;

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

/// Four [`HemisphereSample`]s, component by component.
#[derive(Clone, Copy, Debug)]
pub struct HemisphereSamples4 {
    /// x of each direction.
    pub x: Vec4,
    /// y of each direction.
    pub y: Vec4,
    /// z (cos θ) of each direction.
    pub z: Vec4,
    /// Each sample's weight.
    pub weight: Vec4,
}

/// RTGU's cosine-power mapping (Suffern §7.3): φ = 2π u₀, cos θ = (1 − u₁)^{1/(e+1)}.
/// The pdf is (e+1)/(2π) cos^e θ; the returned weight makes the AO estimate unbiased for any e.
/// Lane 0 of [`cosine_power_hemisphere4`], so both give the same bits.
#[inline]
pub fn cosine_power_hemisphere(u: Vec2, e: f32) -> HemisphereSample {
    let (sin_phi, cos_phi) = sin_cos_2pi_one(u.x);
    let cos_theta = if e == 1.0 { (1.0 - u.y).sqrt() } else { (1.0 - u.y).powf(1.0 / (e + 1.0)) };
    let sin_theta = (1.0 - cos_theta * cos_theta).max(0.0).sqrt();
    let weight = if e == 1.0 { 1.0 } else { cosine_power_weight(cos_theta, e) };
    HemisphereSample { dir: Vec3::new(sin_theta * cos_phi, sin_theta * sin_phi, cos_theta), weight }
}

/// The weight 2 cos^{1−e} θ / (e + 1) of a direction with cosine `c` (0 where not finite).
#[inline]
fn cosine_power_weight(c: f32, e: f32) -> f32 {
    let w = if c > 0.0 { 2.0 * c.powf(1.0 - e) / (e + 1.0) } else { 0.0 };
    if w.is_finite() { w } else { 0.0 }
}

/// [`cosine_power_hemisphere`] for four sample points (u₀, u₁) = (`u0[i]`, `u1[i]`), in SIMD
/// lanes (SSE on x86_64): sin and cos of 2πu₀ come from one polynomial evaluation.
#[inline]
pub fn cosine_power_hemisphere4(u0: Vec4, u1: Vec4, e: f32) -> HemisphereSamples4 {
    let (sin_phi, cos_phi) = sin_cos_2pi(u0);
    let cos_theta = if e == 1.0 { (Vec4::ONE - u1).sqrt() } else { (Vec4::ONE - u1).powf(1.0 / (e + 1.0)) };
    let sin_theta = (Vec4::ONE - cos_theta * cos_theta).max(Vec4::ZERO).sqrt();
    let weight =
        if e == 1.0 { Vec4::ONE } else { Vec4::from_array(cos_theta.to_array().map(|c| cosine_power_weight(c, e))) };
    HemisphereSamples4 { x: sin_theta * cos_phi, y: sin_theta * sin_phi, z: cos_theta, weight }
}

/// The directions of [`cosine_power_hemisphere`] with e = 1 for a vector of sample points
/// (u₀, u₁) in lanes `L`: x, y and z lanes, each lane the scalar code's bits (same operations
/// in the same order, [`sin_cos_2pi_one`]'s quarter turns by lane masks).
#[cfg(target_arch = "x86_64")]
#[inline(always)]
pub(crate) fn cosine_hemisphere_lanes<L: crate::simd::Lanes>(u0: L, u1: L) -> [L; 3] {
    let isa = u0.isa();
    let k = |x: f32| L::splat(isa, x);
    let round = |x: L| x.add(k(ROUNDER)).sub(k(ROUNDER));
    let q = round(u0.mul(k(4.0)));
    let x = u0.sub(q.mul(k(0.25))).mul(k(TAU));
    let z = x.mul(x);
    let sin = k(SIN[0]).mul(z).add(k(SIN[1])).mul(z).add(k(SIN[2])).mul(z).mul(x).add(x);
    let cos = k(COS[0]).mul(z).add(k(COS[1])).mul(z).add(k(COS[2])).mul(z).mul(z).sub(z.mul(k(0.5))).add(k(1.0));
    let half = q.mul(k(0.5));
    let odd = half.ne(round(half));
    let (s, c) = (sin.select(odd, cos), cos.select(odd, sin));
    let within = |lo: f32, hi: f32| L::and(k(lo).le(q), q.lt(k(hi)));
    let flip = |v: L, m: L::Mask| v.select(m, v.neg());
    let (sin_phi, cos_phi) = (flip(s, within(2.0, 4.0)), flip(c, within(1.0, 3.0)));
    let cos_theta = k(1.0).sub(u1).sqrt();
    let sin_theta = k(1.0).sub(cos_theta.mul(cos_theta)).max_keep(k(0.0)).sqrt();
    [sin_theta.mul(cos_phi), sin_theta.mul(sin_phi), cos_theta]
}

/// Adding and removing 2²³ rounds to the nearest integer (exactly, below 2²²).
const ROUNDER: f32 = 8_388_608.0;
/// Cephes's sinf polynomial on [−π/4, π/4]: x + x³(S0 + x²(S1 + x²·S2)), in Horner order.
const SIN: [f32; 3] = [-1.951_529_6e-4, 8.332_161e-3, -1.666_665_5e-1];
/// Cephes's cosf polynomial on [−π/4, π/4]: 1 − x²/2 + x⁴(C0 + x²(C1 + x²·C2)).
const COS: [f32; 3] = [2.443_315_7e-5, -1.388_731_6e-3, 4.166_664_6e-2];

/// (sin 2πu, cos 2πu) for u in [0, 1], within 2e-7 of the true values. The angle is reduced
/// exactly to a quarter turn q/4 plus r in [−1/8, 1/8]; sin and cos of 2πr are Cephes's sinf
/// and cosf polynomials, then rotated by q quarter turns. [`sin_cos_2pi_one`] does the same
/// operations on one value, so both give the same bits.
#[inline(always)]
fn sin_cos_2pi(u: Vec4) -> (Vec4, Vec4) {
    let round = |x: Vec4| (x + Vec4::splat(ROUNDER)) - Vec4::splat(ROUNDER);
    let q = round(u * 4.0);
    // Exact: q/4 is a float within 1/8 of u.
    let x = (u - q * 0.25) * TAU;
    let z = x * x;
    let sin = ((Vec4::splat(SIN[0]) * z + Vec4::splat(SIN[1])) * z + Vec4::splat(SIN[2])) * z * x + x;
    let cos = ((Vec4::splat(COS[0]) * z + Vec4::splat(COS[1])) * z + Vec4::splat(COS[2])) * z * z - z * 0.5 + Vec4::ONE;
    // Quarter turns: q odd swaps sin and cos; sin < 0 for q mod 4 in {2, 3}, cos for {1, 2}.
    let half = q * 0.5;
    let odd = half.cmpne(round(half));
    let (s, c) = (Vec4::select(odd, cos, sin), Vec4::select(odd, sin, cos));
    let sin_negative = q.cmpge(Vec4::splat(2.0)) & q.cmplt(Vec4::splat(4.0));
    let cos_negative = q.cmpge(Vec4::ONE) & q.cmplt(Vec4::splat(3.0));
    (Vec4::select(sin_negative, -s, s), Vec4::select(cos_negative, -c, c))
}

/// [`sin_cos_2pi`] of one value. The quarter turn is applied by masks on the bits, not by
/// branches: which of the two it takes is as good as random from one sample to the next.
#[inline(always)]
fn sin_cos_2pi_one(u: f32) -> (f32, f32) {
    let round = |x: f32| (x + ROUNDER) - ROUNDER;
    let q = round(u * 4.0);
    let x = (u - q * 0.25) * TAU;
    let z = x * x;
    let sin = ((SIN[0] * z + SIN[1]) * z + SIN[2]) * z * x + x;
    let cos = ((COS[0] * z + COS[1]) * z + COS[2]) * z * z - z * 0.5 + 1.0;
    let half = q * 0.5;
    // All ones where q is odd (sin and cos swap), and the sign bit where each is negative.
    let odd = u32::from(half != round(half)).wrapping_neg();
    let (sin, cos) = (sin.to_bits(), cos.to_bits());
    let (s, c) = ((cos & odd) | (sin & !odd), (sin & odd) | (cos & !odd));
    let sin_negative = u32::from((2.0..4.0).contains(&q)) << 31;
    let cos_negative = u32::from((1.0..3.0).contains(&q)) << 31;
    (f32::from_bits(s ^ sin_negative), f32::from_bits(c ^ cos_negative))
}

crate::simd::multiversion! {
    /// Cosine-distributed directions (e = 1, weight 1) around `frame`'s w for the sample points
    /// `values`, into the columns `[x, y, z, weight]` (each `values.len()` rounded up to a
    /// multiple of sixteen long): [`cosine_power_hemisphere`] and the frame's `to_world`, sample
    /// by sample, in fixed-size groups whose loops the compiler vectorises (sixteen or eight
    /// lanes wide where the CPU and environment allow AVX-512 or AVX2). Each sample gets the
    /// one-sample bits.
    pub fn cosine_directions(frame: &Onb, values: &[Vec2], columns: [&mut [f32]; 4]) {
        let [x_out, y_out, z_out, weight] = columns;
        const GROUP: usize = 16;
        let (u, v, w) = (frame.u, frame.v, frame.w);
        for (k, group) in values.chunks(GROUP).enumerate() {
            // A whole group of points (a short last group padded), so that the loop below has no
            // conditional load: with one, the AVX2 copy left this loop scalar (twice the AO
            // kernel's time outside its queries on the peer Cornell box, forced onto that copy).
            let mut points = [Vec2::splat(0.5); GROUP];
            points[..group.len()].copy_from_slice(group);
            let mut d = [Vec3::ZERO; GROUP];
            for (d, &p) in d.iter_mut().zip(&points) {
                *d = cosine_power_hemisphere(p, 1.0).dir;
            }
            let (mut x, mut y, mut z) = ([0.0f32; GROUP], [0.0f32; GROUP], [0.0f32; GROUP]);
            for i in 0..GROUP {
                // to_world, component by component: u·x + v·y + w·z.
                x[i] = u.x * d[i].x + v.x * d[i].y + w.x * d[i].z;
                y[i] = u.y * d[i].x + v.y * d[i].y + w.y * d[i].z;
                z[i] = u.z * d[i].x + v.z * d[i].y + w.z * d[i].z;
            }
            // Whole groups (the run's columns hold a multiple of sixteen): fixed-size stores.
            let range = k * GROUP..(k + 1) * GROUP;
            x_out[range.clone()].copy_from_slice(&x);
            y_out[range.clone()].copy_from_slice(&y);
            z_out[range.clone()].copy_from_slice(&z);
            weight[range].fill(1.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::random::SplitMix64;

    fn uniform_points(n: usize, seed: u64) -> Vec<Vec2> {
        let mut rng = SplitMix64::new(seed);
        (0..n).map(|_| Vec2::new(rng.next_f32(), rng.next_f32())).collect()
    }

    /// The cosine directions in portable, eight- and sixteen-lane vectors give the scalar
    /// map's bits, for random
    /// points and for the quarter-turn and end values where a rounding or sign choice could
    /// differ.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn lane_cosine_directions_give_the_scalar_bits() {
        use crate::simd::Lanes;
        let below_one = crate::sampling::ONE_MINUS_EPSILON;
        let edges = [0.0, 0.125, 0.25, 0.375, 0.5, 0.625, 0.75, 0.875, below_one, 1e-8, 0.2499999, 0.7500001];
        let mut points: Vec<Vec2> = edges.iter().flat_map(|&x| edges.iter().map(move |&y| Vec2::new(x, y))).collect();
        points.extend(uniform_points(4000, 8));
        type Copy = Box<dyn Fn(&[[f32; 16]; 2]) -> [[f32; 16]; 3]>;
        /// The directions of sixteen points in lanes `L`, a vector at a time.
        fn in_lanes<L: Lanes>(isa: L::Isa, u: &[[f32; 16]; 2]) -> [[f32; 16]; 3] {
            let mut out = [[0.0f32; 16]; 3];
            for h in (0..16).step_by(L::WIDTH) {
                let d = cosine_hemisphere_lanes(L::load(isa, &u[0][h..]), L::load(isa, &u[1][h..]));
                for (o, d) in out.iter_mut().zip(d) {
                    d.store(&mut o[h..]);
                }
            }
            out
        }
        let mut copies: Vec<(&str, Copy)> =
            vec![("portable", Box::new(|u| in_lanes::<crate::simd::Portable>(crate::simd::Plain, u)))];
        if let Some(isa) = crate::simd::HasAvx2::on_cpu() {
            copies.push(("avx2", Box::new(move |u| in_lanes::<crate::simd::Avx>(isa, u))));
        }
        if let Some(isa) = crate::simd::HasAvx512::on_cpu() {
            copies.push(("avx512", Box::new(move |u| in_lanes::<crate::simd::Avx512>(isa, u))));
        }
        if copies.len() < 3 {
            eprintln!("no AVX2 or no AVX-512 on this CPU: its copy is not used and not tested");
        }
        for group in points.chunks(16) {
            let mut u = [[0.5f32; 16]; 2];
            for (k, p) in group.iter().enumerate() {
                (u[0][k], u[1][k]) = (p.x, p.y);
            }
            for (name, copy) in &copies {
                let out = copy(&u);
                for (k, &p) in group.iter().enumerate() {
                    let d = cosine_power_hemisphere(p, 1.0).dir;
                    let lane = Vec3::new(out[0][k], out[1][k], out[2][k]);
                    assert_eq!(lane.to_array().map(f32::to_bits), d.to_array().map(f32::to_bits), "{name}: {p}");
                }
            }
        }
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
            let angle = p.y.atan2(p.x).rem_euclid(TAU);
            let sector = ((angle / TAU * sectors as f32) as usize).min(sectors - 1);
            counts[ring * sectors + sector] += 1.0;
        }
        let expected = n as f64 / counts.len() as f64;
        let chi2: f64 = counts.iter().map(|c| (c - expected).powi(2) / expected).sum();
        // 63 degrees of freedom: the 99.9 % quantile is 103.4.
        assert!(chi2 < 103.4, "chi² = {chi2}");
    }

    #[test]
    fn sin_cos_2pi_is_within_2e_7_of_f64() {
        let mut worst = 0.0f64;
        for i in 0..=100_000u32 {
            let u = i as f32 / 100_000.0;
            let (s, c) = sin_cos_2pi(Vec4::splat(u));
            assert_eq!((s.x, c.x), sin_cos_2pi_one(u), "u = {u}");
            let a = std::f64::consts::TAU * u as f64;
            worst = worst.max((s.x as f64 - a.sin()).abs()).max((c.x as f64 - a.cos()).abs());
        }
        assert!(worst < 2e-7, "max error {worst}");
    }

    #[test]
    fn four_lanes_give_the_one_lane_bits() {
        let pts = uniform_points(4_000, 3);
        for e in [0.0f32, 1.0, 2.5] {
            for q in pts.chunks_exact(4) {
                let s = cosine_power_hemisphere4(
                    Vec4::from_array(std::array::from_fn(|i| q[i].x)),
                    Vec4::from_array(std::array::from_fn(|i| q[i].y)),
                    e,
                );
                for (i, &u) in q.iter().enumerate() {
                    let one = cosine_power_hemisphere(u, e);
                    assert_eq!((one.dir, one.weight), (Vec3::new(s.x[i], s.y[i], s.z[i]), s.weight[i]), "{u} e={e}");
                }
            }
        }
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
