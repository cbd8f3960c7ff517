//! The ambient occluder, written on the light extension point like any other light.

use bevy_ecs::prelude::Component;
use glam::{Vec3, Vec3A};

use crate::{
    components::Transform,
    light::{Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Shadow, Term, check_emission},
    sampling::warp::cosine_power_hemisphere,
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
        let floor = self.radiance * self.min_amount;
        let s = cosine_power_hemisphere(u.get(0), self.exponent);
        if s.weight <= 0.0 {
            return Some(LightSample { unoccluded: floor, occluded: floor, shadow: None });
        }
        let dir = Vec3A::from(at.frame.to_world(s.dir));
        Some(LightSample {
            unoccluded: self.radiance * (self.min_amount + (1.0 - self.min_amount) * s.weight),
            occluded: floor,
            shadow: Some(Shadow::Along { dir, max_distance: self.max_distance }),
        })
    }
}
