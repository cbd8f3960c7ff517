//! The spot light, written on the light extension point.

use std::f32::consts::{FRAC_PI_2, FRAC_PI_4};

use bevy_ecs::prelude::Component;
use glam::{Vec3, Vec3A};

use crate::{
    components::Transform,
    light::{
        Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Shadow, check_direction, check_emission,
        check_position,
    },
};

/// A spot light at the entity's translation shining along its local −Z axis, with glTF
/// `KHR_lights_punctual` `spot` semantics: `ls·color` is the intensity inside the inner cone
/// in candela (W/sr in hemi's units), inverse-square falloff, and between the cone angles the
/// glTF reference attenuation
/// `a = clamp((cos α − cos outer) / max(0.001, cos inner − cos outer), 0, 1)²`,
/// α being the angle from the axis: full inside `inner_cone_angle`, zero outside
/// `outer_cone_angle`, smooth between. (glTF's optional `range` cut-off is not modelled.)
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(Transform)]
pub struct SpotLight {
    /// Intensity on the axis.
    pub ls: f32,
    /// Light colour (linear RGB).
    pub color: Vec3,
    /// Angle from the axis, in radians, where the falloff begins (glTF `innerConeAngle`, ≥ 0).
    pub inner_cone_angle: f32,
    /// Angle from the axis, in radians, where it ends (glTF `outerConeAngle`, ≤ π/2).
    pub outer_cone_angle: f32,
    /// Trace a shadow ray for every lit point.
    pub shadows: bool,
}

impl Default for SpotLight {
    /// glTF's defaults: inner 0, outer π/4.
    fn default() -> Self {
        SpotLight { ls: 1.0, color: Vec3::ONE, inner_cone_angle: 0.0, outer_cone_angle: FRAC_PI_4, shadows: true }
    }
}

impl SpotLight {
    /// The glTF angular attenuation at cos α = `cos_axis` (α measured from the spot's axis).
    pub fn attenuation(&self, cos_axis: f32) -> f32 {
        let (scale, offset) = self.scale_offset();
        (cos_axis * scale + offset).clamp(0.0, 1.0).powi(2)
    }

    /// glTF's `lightAngleScale` and `lightAngleOffset`.
    fn scale_offset(&self) -> (f32, f32) {
        let cos_outer = self.outer_cone_angle.cos();
        let scale = 1.0 / (self.inner_cone_angle.cos() - cos_outer).max(0.001);
        (scale, -cos_outer * scale)
    }
}

/// A [`SpotLight`] placed in world space.
#[derive(Clone, Copy, Debug)]
pub struct PlacedSpot {
    position: Vec3A,
    axis: Vec3A,
    intensity: Vec3,
    scale: f32,
    offset: f32,
    shadows: bool,
}

impl Light for SpotLight {
    type Placed = PlacedSpot;
    const NAME: &'static str = "spot light";

    fn validate(&self, transform: &Transform) -> Result<(), String> {
        check_emission(Self::NAME, self.ls, self.color)?;
        let (inner, outer) = (self.inner_cone_angle, self.outer_cone_angle);
        if !(inner >= 0.0 && inner < outer && outer <= FRAC_PI_2) {
            return Err(format!("spot light cone angles {inner} and {outer} must satisfy 0 ≤ inner < outer ≤ π/2"));
        }
        check_position(Self::NAME, transform)?;
        check_direction(Self::NAME, transform)
    }

    fn place(&self, transform: &Transform) -> Option<PlacedSpot> {
        let intensity = self.color * self.ls;
        let (scale, offset) = self.scale_offset();
        (intensity.max_element() > 0.0).then_some(PlacedSpot {
            position: transform.translation.into(),
            axis: transform.forward().into(),
            intensity,
            scale,
            offset,
            shadows: self.shadows,
        })
    }
}

impl PlacedLight for PlacedSpot {
    const DIMS: u32 = 0;

    /// `I·a(α)·cos θ/d²`; nothing behind the surface or outside the outer cone.
    #[inline]
    fn sample(&self, at: &ShadingPoint, _: &LightSamples) -> Option<LightSample> {
        let to_light = self.position - at.p;
        let dist2 = to_light.length_squared();
        if dist2 == 0.0 {
            return None;
        }
        let dir = to_light / dist2.sqrt();
        let cos = at.normal.dot(dir);
        let a = (-dir.dot(self.axis) * self.scale + self.offset).clamp(0.0, 1.0);
        if cos <= 0.0 || a <= 0.0 {
            return None;
        }
        Some(LightSample {
            unoccluded: self.intensity * (a * a * cos / dist2),
            occluded: Vec3::ZERO,
            shadow: self.shadows.then_some(Shadow::ToPoint(self.position)),
        })
    }
}
