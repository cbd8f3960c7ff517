//! The ambient occluder, written on the light extension point like any other light.

use bevy_ecs::prelude::Component;
use glam::{Vec2, Vec3, Vec4};

use crate::{
    components::Transform,
    light::{
        DirectionRun, DirectionTerms, Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Term, check_emission,
    },
    math::Onb,
    sampling::warp::{cosine_power_hemisphere, cosine_power_hemisphere4},
};

/// RTGU's ambient occluder (Suffern ch. 17) as a light: it adds
/// `ka·cd·ls·color·(min_amount + (1 − min_amount)·AO)` with AO = (1/π)∫V(ω) cos θ dω.
/// Needs no transform. One AO ray per shading point, counted as an `ao` ray.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct AmbientOccluder {
    /// Radiance scale.
    pub ls: f32,
    /// Light colour (linear RGB).
    pub color: Vec3,
    /// Fraction of light still received from occluded directions, in [0, 1].
    pub min_amount: f32,
    /// Occluders farther than this do not count (∞ for classic AO).
    pub max_distance: f32,
    /// Directions are sampled with density ∝ cos^e θ; the estimate is weighted to stay
    /// unbiased for every e ≥ 0 (e = 1 is cosine sampling, the lowest-variance choice).
    pub exponent: f32,
}

impl Default for AmbientOccluder {
    fn default() -> Self {
        AmbientOccluder { ls: 1.0, color: Vec3::ONE, min_amount: 0.0, max_distance: f32::INFINITY, exponent: 1.0 }
    }
}

impl AmbientOccluder {
    /// A one-line description of the first unusable parameter.
    pub fn validate(&self) -> Result<(), String> {
        check_emission("ambient occluder", self.ls, self.color)?;
        if !(0.0..=1.0).contains(&self.min_amount) {
            return Err(format!("ambient occluder min_amount {} is outside [0, 1]", self.min_amount));
        }
        if self.max_distance.is_nan() || self.max_distance <= 0.0 {
            return Err(format!("ambient occluder max_distance {} must be positive (∞ allowed)", self.max_distance));
        }
        if !(self.exponent.is_finite() && self.exponent >= 0.0) {
            return Err(format!("ambient occluder exponent {} must be finite and non-negative", self.exponent));
        }
        Ok(())
    }
}

/// An [`AmbientOccluder`] ready to sample.
#[derive(Clone, Copy, Debug)]
pub struct PlacedOccluder {
    radiance: Vec3,
    min_amount: f32,
    max_distance: f32,
    exponent: f32,
}

impl Light for AmbientOccluder {
    type Placed = PlacedOccluder;
    const NAME: &'static str = "ambient occluder";

    fn validate(&self, _: &Transform) -> Result<(), String> {
        AmbientOccluder::validate(self)
    }

    fn place(&self, _: &Transform) -> Option<PlacedOccluder> {
        let radiance = self.color * self.ls;
        (radiance.max_element() > 0.0).then_some(PlacedOccluder {
            radiance,
            min_amount: self.min_amount,
            max_distance: self.max_distance,
            exponent: self.exponent,
        })
    }
}

impl PlacedLight for PlacedOccluder {
    const TERM: Term = Term::Ambient;

    /// `ls·color·(min + (1 − min)·V·w)`: one direction with density ∝ cos^e θ and its weight
    /// w = cos θ / (π·pdf), so the estimate of the cosine-weighted AO is unbiased for every e.
    #[inline]
    fn sample(&self, at: &ShadingPoint, u: &LightSamples) -> Option<LightSample> {
        let s = cosine_power_hemisphere(u.get(0), self.exponent);
        Some(self.terms().light_sample(s.weight, at.frame.to_world(s.dir).into()))
    }

    /// Cosine sampling (e = 1) draws exactly such runs.
    #[inline]
    fn cosine_run(&self) -> Option<DirectionTerms> {
        (self.exponent == 1.0).then(|| self.terms())
    }

    /// Cosine-sampled runs (e = 1) sixteen or eight lanes at a time where the CPU has AVX-512
    /// or AVX2; other exponents four at a time. Same values as `sample`.
    #[inline]
    fn sample_directions(&self, at: &ShadingPoint, values: &[Vec2], run: &mut DirectionRun) -> Option<DirectionTerms> {
        run.resize(values.len());
        if !(self.exponent == 1.0 && cosine_directions_wide(&at.frame, values, run)) {
            self.directions4(&at.frame, values, run);
        }
        Some(self.terms())
    }
}

/// [`cosine_directions`] sixteen or eight lanes at a time where the CPU has AVX-512 or AVX2;
/// false (nothing written) elsewhere.
#[inline]
fn cosine_directions_wide(frame: &Onb, values: &[Vec2], run: &mut DirectionRun) -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        if crate::simd::avx512() {
            // SAFETY: the CPU has AVX-512F, checked just above.
            unsafe { cosine_directions_avx512(frame, values, run) };
            return true;
        }
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU has AVX2, checked just above.
            unsafe { cosine_directions_avx2(frame, values, run) };
            return true;
        }
    }
    let _ = (frame, values, run);
    false
}

/// [`cosine_directions`] compiled for AVX-512F, where it vectorises sixteen-wide.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f")]
fn cosine_directions_avx512(frame: &Onb, values: &[Vec2], run: &mut DirectionRun) {
    cosine_directions(frame, values, run);
}

/// [`cosine_directions`] compiled for AVX2, where it vectorises eight-wide.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn cosine_directions_avx2(frame: &Onb, values: &[Vec2], run: &mut DirectionRun) {
    cosine_directions(frame, values, run);
}

/// Cosine-distributed directions (e = 1, weight 1) around `frame`'s w for the sample points
/// `values`, into `run`: [`cosine_power_hemisphere`] and the frame's `to_world`, sample by
/// sample, in fixed-size groups whose loops the compiler vectorises.
#[inline(always)]
fn cosine_directions(frame: &Onb, values: &[Vec2], run: &mut DirectionRun) {
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
        run.x[range.clone()].copy_from_slice(&x);
        run.y[range.clone()].copy_from_slice(&y);
        run.z[range.clone()].copy_from_slice(&z);
        run.weight[range].fill(1.0);
    }
}

impl PlacedOccluder {
    /// What every sample of a run shares.
    fn terms(&self) -> DirectionTerms {
        DirectionTerms { radiance: self.radiance, floor: self.min_amount, max_distance: self.max_distance }
    }

    /// [`PlacedLight::sample_directions`] four samples at a time (any exponent).
    #[inline]
    fn directions4(&self, f: &Onb, values: &[Vec2], run: &mut DirectionRun) {
        for (k, u) in values.chunks(4).enumerate() {
            let lane = |f: fn(&Vec2) -> f32| Vec4::from_array(std::array::from_fn(|i| u.get(i).map_or(0.5, f)));
            let s = cosine_power_hemisphere4(lane(|v| v.x), lane(|v| v.y), self.exponent);
            // The frame's to_world lane by lane, in its order of operations: u·x + v·y + w·z.
            let world = |a: usize| Vec4::splat(f.u[a]) * s.x + Vec4::splat(f.v[a]) * s.y + Vec4::splat(f.w[a]) * s.z;
            run.set_group(k, [world(0), world(1), world(2), s.weight]);
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3A;

    use super::*;
    use crate::{components::Matte, random::SplitMix64};

    #[test]
    fn a_run_gives_each_sample_s_bits() {
        let mut rng = SplitMix64::new(9);
        for exponent in [1.0, 0.0, 3.0] {
            let light = AmbientOccluder { min_amount: 0.25, max_distance: 7.0, exponent, ..Default::default() };
            let placed = light.place(&Transform::default()).unwrap();
            let normal = Vec3A::new(rng.next_f32() - 0.5, rng.next_f32() - 0.5, rng.next_f32() - 0.5).normalize();
            let at = ShadingPoint::new(Vec3A::ONE, normal, Matte::default());
            // 37 samples: full groups of four and of sixteen, and a partial one of each.
            let values: Vec<Vec2> = (0..37).map(|_| Vec2::new(rng.next_f32(), rng.next_f32())).collect();
            let mut run = DirectionRun::default();
            let terms = placed.sample_directions(&at, &values, &mut run).expect("a direction light");
            assert_eq!(run.weight.len(), values.len().next_multiple_of(16));
            for (j, &u) in values.iter().enumerate() {
                let expected = placed.sample(&at, &LightSamples::fixed(u));
                assert_eq!(Some(run.light_sample(j, &terms)), expected, "sample {j}, e = {exponent}");
            }
        }
    }

    /// Both vector copies of the cosine directions give the one-sample bits, whichever one
    /// this CPU's runs use.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn each_vector_copy_of_the_cosine_directions_gives_each_sample_s_bits() {
        let mut rng = SplitMix64::new(4);
        let frame = Onb::from_normal(Vec3::new(0.3, -0.8, 0.5).normalize());
        // 37 points: two full groups of sixteen and a partial one.
        let values: Vec<Vec2> = (0..37).map(|_| Vec2::new(rng.next_f32(), rng.next_f32())).collect();
        let mut expected = DirectionRun::default();
        expected.resize(values.len());
        cosine_directions(&frame, &values, &mut expected);
        for (j, &u) in values.iter().enumerate() {
            let d = cosine_power_hemisphere(u, 1.0).dir;
            let world = frame.u * d.x + frame.v * d.y + frame.w * d.z;
            assert_eq!(expected.dir(j), Vec3A::from(world), "sample {j}");
        }
        type Copy = unsafe fn(&Onb, &[Vec2], &mut DirectionRun);
        let copies: [(&str, Copy); 2] = [("avx2", cosine_directions_avx2), ("avx512f", cosine_directions_avx512)];
        for (feature, copy) in copies {
            if !std::arch::is_x86_feature_detected!("avx2")
                || (feature == "avx512f" && !std::arch::is_x86_feature_detected!("avx512f"))
            {
                continue;
            }
            let mut run = DirectionRun::default();
            run.resize(values.len());
            // SAFETY: the CPU has the copy's instruction set, checked above.
            unsafe { copy(&frame, &values, &mut run) };
            assert_eq!(
                (&run.x, &run.y, &run.z, &run.weight),
                (&expected.x, &expected.y, &expected.z, &expected.weight),
                "{feature}"
            );
        }
    }
}
