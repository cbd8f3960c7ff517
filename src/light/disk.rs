//! The disk area light, written on the light extension point.

use std::f32::consts::PI;

use bevy_ecs::prelude::Component;
use glam::{Vec3, Vec3A};

use crate::{
    components::Transform,
    light::{
        Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Shadow, check_direction, check_emission,
        check_position,
    },
    math::Onb,
    sampling::warp::concentric_disk,
};

/// A one-sided disk of `radius` centred at the entity's translation, facing (and emitting
/// along) its local −Z axis, with uniform radiance `ls·color`. Each shading point samples one
/// point on the disk, by area through the concentric mapping, and traces one shadow ray to
/// it: shadows get penumbrae. On the axis at distance h a facing surface receives
/// E = L·π·R²/(R² + h²). Scale is ignored.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
#[require(Transform)]
pub struct DiskLight {
    /// Emitted radiance.
    pub ls: f32,
    /// Light colour (linear RGB).
    pub color: Vec3,
    /// Disk radius.
    pub radius: f32,
    /// Trace shadow rays (without, the disk lights through everything).
    pub shadows: bool,
}

impl Default for DiskLight {
    fn default() -> Self {
        DiskLight { ls: 1.0, color: Vec3::ONE, radius: 0.5, shadows: true }
    }
}

/// A [`DiskLight`] placed in world space.
#[derive(Clone, Copy, Debug)]
pub struct PlacedDisk {
    centre: Vec3A,
    /// Emission direction (the disk's −Z).
    normal: Vec3A,
    /// Tangents scaled by the radius.
    u: Vec3A,
    v: Vec3A,
    /// Radiance times area: the estimator's 1/pdf is folded in.
    power: Vec3,
    shadows: bool,
}

impl Light for DiskLight {
    type Placed = PlacedDisk;
    const NAME: &'static str = "disk light";

    fn validate(&self, transform: &Transform) -> Result<(), String> {
        check_emission(Self::NAME, self.ls, self.color)?;
        if !(self.radius.is_finite() && self.radius > 0.0) {
            return Err(format!("disk light radius {} must be finite and positive", self.radius));
        }
        check_position(Self::NAME, transform)?;
        check_direction(Self::NAME, transform)
    }

    fn place(&self, transform: &Transform) -> Option<PlacedDisk> {
        let power = self.color * (self.ls * PI * self.radius * self.radius);
        let normal = transform.forward();
        let frame = Onb::from_normal(normal);
        (power.max_element() > 0.0).then_some(PlacedDisk {
            centre: transform.translation.into(),
            normal: normal.into(),
            u: (frame.u * self.radius).into(),
            v: (frame.v * self.radius).into(),
            power,
            shadows: self.shadows,
        })
    }
}

impl PlacedLight for PlacedDisk {
    /// Irradiance estimate `L·A·cos θ·cos θ'/d²` for one point on the disk (area pdf 1/A).
    #[inline]
    fn sample(&self, at: &ShadingPoint, u: &LightSamples) -> Option<LightSample> {
        let d = concentric_disk(u.get(0));
        let q = self.centre + self.u * d.x + self.v * d.y;
        let to_light = q - at.p;
        let dist2 = to_light.length_squared();
        let cos = at.normal.dot(to_light);
        let cos_light = -self.normal.dot(to_light);
        if cos <= 0.0 || cos_light <= 0.0 || dist2 == 0.0 {
            return None;
        }
        Some(LightSample {
            unoccluded: self.power * (cos * cos_light / (dist2 * dist2)),
            occluded: Vec3::ZERO,
            shadow: self.shadows.then_some(Shadow::ToPoint(q)),
        })
    }
}
