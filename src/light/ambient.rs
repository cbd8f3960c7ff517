//! The ambient occluder, written on the light extension point like any other light.

use bevy_ecs::prelude::Component;
use glam::{Vec2, Vec3, Vec4};

use crate::{
    components::Transform,
    light::{
        DirectionRun, DirectionTerms, Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Term, check_emission,
    },
    math::Onb,
    sampling::warp::{cosine_directions, cosine_power_hemisphere, cosine_power_hemisphere4},
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
        Some(self.terms().light_sample(s.weight, at.frame().to_world(s.dir).into()))
    }

    /// Cosine sampling (e = 1) draws exactly such runs.
    #[inline]
    fn cosine_run(&self) -> Option<DirectionTerms> {
        (self.exponent == 1.0).then(|| self.terms())
    }

    /// Cosine-sampled runs (e = 1) by [`cosine_directions`], in groups the compiler vectorises;
    /// other exponents four at a time. Same values as `sample`.
    #[inline]
    fn sample_directions(&self, at: &ShadingPoint, values: &[Vec2], run: &mut DirectionRun) -> Option<DirectionTerms> {
        run.resize(values.len());
        let frame = at.frame();
        if self.exponent == 1.0 {
            cosine_directions(&frame, values, [&mut run.x, &mut run.y, &mut run.z, &mut run.weight]);
        } else {
            self.directions4(&frame, values, run);
        }
        Some(self.terms())
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
}
