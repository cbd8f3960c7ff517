//! Primary rays for whichever camera the scene has: the pinhole [`Camera`] or the
//! [`OrthographicCamera`].

use glam::{Vec2, Vec3A};

use crate::{
    camera::PinholeRays,
    components::{Camera, OrthographicCamera},
    geometry::Ray,
};

/// An orthographic camera prepared for one image size.
#[derive(Clone, Copy, Debug)]
pub struct OrthographicRays {
    eye: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
    inv_width: f32,
    inv_height: f32,
}

impl OrthographicRays {
    /// Prepares `camera` for a `width × height` image; `Err` names what makes it unusable.
    pub fn new(camera: &OrthographicCamera, width: u32, height: u32) -> Result<Self, String> {
        camera.validate()?;
        let forward = (camera.target - camera.eye).normalize();
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        let aspect = width as f32 / height as f32;
        Ok(OrthographicRays {
            eye: camera.eye.into(),
            forward: forward.into(),
            right: Vec3A::from(right) * (camera.half_height * aspect),
            up: Vec3A::from(up) * camera.half_height,
            inv_width: 1.0 / width as f32,
            inv_height: 1.0 / height as f32,
        })
    }

    /// The ray through film position (x + u.x, y + u.y), pixel (0, 0) being the top-left one.
    #[inline]
    pub fn ray(&self, x: u32, y: u32, u: Vec2) -> Ray {
        let sx = 2.0 * (x as f32 + u.x) * self.inv_width - 1.0;
        let sy = 1.0 - 2.0 * (y as f32 + u.y) * self.inv_height;
        Ray::new(self.eye + self.right * sx + self.up * sy, self.forward, f32::INFINITY)
    }
}

/// The scene's one camera, prepared for an image size.
#[derive(Clone, Copy, Debug)]
pub enum PrimaryRays {
    /// A pinhole camera.
    Pinhole(PinholeRays),
    /// An orthographic camera.
    Orthographic(OrthographicRays),
}

impl PrimaryRays {
    /// The rays of the scene's single camera of either kind (`None` unless exactly one exists
    /// and it is usable).
    pub fn single<'a>(
        mut pinhole: impl Iterator<Item = &'a Camera>,
        mut orthographic: impl Iterator<Item = &'a OrthographicCamera>,
        width: u32,
        height: u32,
    ) -> Option<Self> {
        match (pinhole.next(), pinhole.next(), orthographic.next(), orthographic.next()) {
            (Some(c), None, None, None) => PinholeRays::new(c, width, height).ok().map(PrimaryRays::Pinhole),
            (None, None, Some(c), None) => OrthographicRays::new(c, width, height).ok().map(PrimaryRays::Orthographic),
            _ => None,
        }
    }

    /// The ray through film position (x + u.x, y + u.y).
    #[inline]
    pub fn ray(&self, x: u32, y: u32, u: Vec2) -> Ray {
        match self {
            PrimaryRays::Pinhole(c) => c.ray(x, y, u),
            PrimaryRays::Orthographic(c) => c.ray(x, y, u),
        }
    }
}
