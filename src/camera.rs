//! Primary ray generation for the pinhole camera.

use glam::{Vec2, Vec3A};

use crate::{components::Camera, geometry::Ray};

/// A camera prepared for one image size: turns film positions into primary rays.
#[derive(Clone, Copy, Debug)]
pub struct PinholeRays {
    eye: Vec3A,
    forward: Vec3A,
    right: Vec3A,
    up: Vec3A,
    inv_width: f32,
    inv_height: f32,
}

impl PinholeRays {
    /// Prepares `camera` for a `width × height` image; `Err` names what makes it unusable.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Result<Self, String> {
        camera.validate()?;
        let forward = (camera.target - camera.eye).normalize();
        let right = forward.cross(camera.up).normalize();
        let up = right.cross(forward);
        let tan_half = (camera.vfov_degrees.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        Ok(PinholeRays {
            eye: camera.eye.into(),
            forward: forward.into(),
            right: Vec3A::from(right) * (tan_half * aspect),
            up: Vec3A::from(up) * tan_half,
            inv_width: 1.0 / width as f32,
            inv_height: 1.0 / height as f32,
        })
    }

    /// The ray through film position (x + u.x, y + u.y), pixel (0, 0) being the top-left one.
    #[inline]
    pub fn ray(&self, x: u32, y: u32, u: Vec2) -> Ray {
        let sx = 2.0 * (x as f32 + u.x) * self.inv_width - 1.0;
        let sy = 1.0 - 2.0 * (y as f32 + u.y) * self.inv_height;
        let dir = (self.forward + self.right * sx + self.up * sy).normalize();
        Ray::new(self.eye, dir, f32::INFINITY)
    }
}

impl Camera {
    /// A one-line description of what makes this camera unusable, if anything.
    pub fn validate(&self) -> Result<(), String> {
        if !(self.eye.is_finite() && self.target.is_finite() && self.up.is_finite()) {
            return Err(format!("camera eye {}, target {} or up {} is not finite", self.eye, self.target, self.up));
        }
        let forward = self.target - self.eye;
        if forward.length_squared() == 0.0 {
            return Err(format!("camera eye and target are the same point {}", self.eye));
        }
        let right = forward.normalize().cross(self.up);
        if right.length_squared() < 1e-12 || !right.is_finite() {
            return Err(format!("camera up {} is parallel to its view direction", self.up));
        }
        if !(self.vfov_degrees > 0.0 && self.vfov_degrees < 180.0) {
            return Err(format!("camera field of view {}° is outside (0°, 180°)", self.vfov_degrees));
        }
        Ok(())
    }
}
