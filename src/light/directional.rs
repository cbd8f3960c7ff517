//! The directional light (sun), written on the light extension point.

use bevy_ecs::prelude::Component;
use glam::{Vec3, Vec3A};

use crate::{
    components::Transform,
    light::{Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Shadow, check_direction, check_emission},
};

/// A light at infinity shining along the entity's local −Z axis (its rotation; position and
/// scale are ignored), like glTF's `KHR_lights_punctual` `directional` light: `ls·color` is the
/// irradiance on a surface facing the light (glTF `intensity`, lux), so E = ls·color·cos θ.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(Transform)]
pub struct DirectionalLight {
    /// Irradiance at normal incidence.
    pub ls: f32,
    /// Light colour (linear RGB).
    pub color: Vec3,
    /// Trace a shadow ray (to infinity) for every lit point.
    pub shadows: bool,
}

impl Default for DirectionalLight {
    fn default() -> Self {
        DirectionalLight { ls: 1.0, color: Vec3::ONE, shadows: true }
    }
}

/// A [`DirectionalLight`] placed in world space.
#[derive(Clone, Copy, Debug)]
pub struct PlacedDirectional {
    to_light: Vec3A,
    irradiance: Vec3,
    shadows: bool,
}

impl Light for DirectionalLight {
    type Placed = PlacedDirectional;
    const NAME: &'static str = "directional light";

    fn validate(&self, transform: &Transform) -> Result<(), String> {
        check_emission(Self::NAME, self.ls, self.color)?;
        check_direction(Self::NAME, transform)
    }

    fn place(&self, transform: &Transform) -> Option<PlacedDirectional> {
        let irradiance = self.color * self.ls;
        (irradiance.max_element() > 0.0).then_some(PlacedDirectional {
            to_light: (-transform.forward()).into(),
            irradiance,
            shadows: self.shadows,
        })
    }
}

impl PlacedLight for PlacedDirectional {
    const DIMS: u32 = 0;

    /// `E·cos θ`; nothing for surfaces facing away.
    #[inline]
    fn sample(&self, at: &ShadingPoint, _: &LightSamples) -> Option<LightSample> {
        let cos = at.normal.dot(self.to_light);
        (cos > 0.0).then(|| LightSample {
            unoccluded: self.irradiance * cos,
            occluded: Vec3::ZERO,
            shadow: self.shadows.then_some(Shadow::Along { dir: self.to_light, max_distance: f32::INFINITY }),
        })
    }
}
