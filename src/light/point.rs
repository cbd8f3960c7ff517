//! The point light, written on the light extension point like any other light.

use bevy_ecs::prelude::Component;
use glam::{Vec3, Vec3A};

use crate::{
    components::Transform,
    light::{Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Shadow, check_emission, check_position},
};

/// A point light at the entity's translation. With `falloff` it is glTF's
/// `KHR_lights_punctual` point light: `ls·color` is the intensity in candela (W/sr in hemi's
/// units), irradiance I·cos θ/d².
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(Transform)]
pub struct PointLight {
    /// Intensity scale.
    pub ls: f32,
    /// Light colour (linear RGB).
    pub color: Vec3,
    /// Trace a shadow ray for every lit point.
    pub shadows: bool,
    /// Divide by the squared distance (physical falloff); RTGU's default has none.
    pub falloff: bool,
}

impl Default for PointLight {
    fn default() -> Self {
        PointLight { ls: 1.0, color: Vec3::ONE, shadows: true, falloff: true }
    }
}

/// A [`PointLight`] placed in world space.
#[derive(Clone, Copy, Debug)]
pub struct PlacedPoint(PointSource);

/// Light from one point that every shading point sees alike (a placed [`PointLight`]): what
/// [`PlacedLight::point_source`] hands the core, which then lights many points in lanes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointSource {
    /// Where the light is.
    pub position: Vec3A,
    /// Intensity (`ls·color`).
    pub intensity: Vec3,
    /// Whether a lit point's light depends on a shadow ray to `position`.
    pub shadows: bool,
    /// Whether the light falls off with the squared distance.
    pub falloff: bool,
}

impl PointSource {
    /// Irradiance `I·cos θ/d²` (`I·cos θ` without falloff) at `at`; nothing behind the surface.
    #[inline]
    pub fn sample(&self, at: &ShadingPoint) -> Option<LightSample> {
        let to_light = self.position - at.p;
        let dist2 = to_light.length_squared();
        let cos = at.normal.dot(to_light);
        if cos <= 0.0 || dist2 == 0.0 {
            return None;
        }
        let cos = cos / dist2.sqrt();
        Some(LightSample {
            unoccluded: self.intensity * if self.falloff { cos / dist2 } else { cos },
            occluded: Vec3::ZERO,
            shadow: self.shadows.then_some(Shadow::ToPoint(self.position)),
        })
    }
}

impl Light for PointLight {
    type Placed = PlacedPoint;
    const NAME: &'static str = "point light";

    fn validate(&self, transform: &Transform) -> Result<(), String> {
        check_emission(Self::NAME, self.ls, self.color)?;
        check_position(Self::NAME, transform)
    }

    fn place(&self, transform: &Transform) -> Option<PlacedPoint> {
        let intensity = self.color * self.ls;
        (intensity.max_element() > 0.0).then_some(PlacedPoint(PointSource {
            position: transform.translation.into(),
            intensity,
            shadows: self.shadows,
            falloff: self.falloff,
        }))
    }
}

impl PlacedLight for PlacedPoint {
    const DIMS: u32 = 0;

    /// Irradiance `I·cos θ/d²` (`I·cos θ` without falloff); nothing behind the surface.
    #[inline]
    fn sample(&self, at: &ShadingPoint, _: &LightSamples) -> Option<LightSample> {
        self.0.sample(at)
    }

    #[inline]
    fn point_source(&self) -> Option<PointSource> {
        Some(self.0)
    }
}
