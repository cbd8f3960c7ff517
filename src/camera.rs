//! Primary ray generation: the pinhole, thin-lens and orthographic cameras.

use bevy_ecs::{prelude::Query, system::SystemParam};
use glam::{Vec2, Vec3, Vec3A};

use crate::{
    components::{Camera, OrthographicCamera, ThinLensCamera},
    geometry::Ray,
    sampling::warp::concentric_disk,
};

/// A camera prepared for one image size: turns film positions (and lens samples) into rays.
pub trait CameraRays: Sync {
    /// Whether rays use a lens sample (dimension [`crate::sampling::dims::LENS`]); when not,
    /// none is computed.
    const USES_LENS: bool;

    /// The ray through film position (x + u.x, y + u.y), pixel (0, 0) being the top-left one,
    /// leaving the lens at the point `lens` in [0, 1)² maps to.
    fn ray(&self, x: u32, y: u32, u: Vec2, lens: Vec2) -> Ray;
}

/// The camera frame (forward, right, up) from eye, target and an up hint.
fn view_basis(eye: Vec3, target: Vec3, up_hint: Vec3) -> (Vec3, Vec3, Vec3) {
    let forward = (target - eye).normalize();
    let right = forward.cross(up_hint).normalize();
    (forward, right, right.cross(forward))
}

/// Film coordinates in [−1, 1]² (x right, y up) of film position (x + u.x, y + u.y), pixel
/// (0, 0) being the top-left one.
#[inline]
fn film_xy(x: u32, y: u32, u: Vec2, inv_width: f32, inv_height: f32) -> (f32, f32) {
    (2.0 * (x as f32 + u.x) * inv_width - 1.0, 1.0 - 2.0 * (y as f32 + u.y) * inv_height)
}

/// A pinhole camera prepared for one image size.
#[derive(Clone, Copy, Debug)]
pub struct PinholeRays {
    eye: Vec3A,
    forward: Vec3A,
    /// Unit right and up vectors.
    right_unit: Vec3A,
    up_unit: Vec3A,
    /// Right and up scaled to the film's half-width and half-height at distance 1.
    right: Vec3A,
    up: Vec3A,
    inv_width: f32,
    inv_height: f32,
}

impl PinholeRays {
    /// Prepares `camera` for a `width × height` image; `Err` names what makes it unusable.
    pub fn new(camera: &Camera, width: u32, height: u32) -> Result<Self, String> {
        camera.validate()?;
        let (forward, right, up) = view_basis(camera.eye, camera.target, camera.up);
        let tan_half = (camera.vfov_degrees.to_radians() * 0.5).tan();
        let aspect = width as f32 / height as f32;
        Ok(PinholeRays {
            eye: camera.eye.into(),
            forward: forward.into(),
            right_unit: right.into(),
            up_unit: up.into(),
            right: Vec3A::from(right) * (tan_half * aspect),
            up: Vec3A::from(up) * tan_half,
            inv_width: 1.0 / width as f32,
            inv_height: 1.0 / height as f32,
        })
    }

    /// The unnormalised direction through film position (x + u.x, y + u.y), of unit depth.
    #[inline]
    fn film_dir(&self, x: u32, y: u32, u: Vec2) -> Vec3A {
        let (sx, sy) = film_xy(x, y, u, self.inv_width, self.inv_height);
        self.forward + self.right * sx + self.up * sy
    }

    /// The ray through film position (x + u.x, y + u.y), pixel (0, 0) being the top-left one.
    #[inline]
    pub fn ray(&self, x: u32, y: u32, u: Vec2) -> Ray {
        Ray::new(self.eye, self.film_dir(x, y, u).normalize(), f32::INFINITY)
    }
}

impl CameraRays for PinholeRays {
    const USES_LENS: bool = false;

    #[inline]
    fn ray(&self, x: u32, y: u32, u: Vec2, _: Vec2) -> Ray {
        PinholeRays::ray(self, x, y, u)
    }
}

/// A thin-lens camera prepared for one image size.
#[derive(Clone, Copy, Debug)]
pub struct ThinLensRays {
    pinhole: PinholeRays,
    lens_radius: f32,
    focal_distance: f32,
}

impl ThinLensRays {
    /// Prepares `camera` for a `width × height` image; `Err` names what makes it unusable.
    pub fn new(camera: &ThinLensCamera, width: u32, height: u32) -> Result<Self, String> {
        camera.validate()?;
        let pinhole = PinholeRays::new(&camera.pinhole(), width, height)?;
        Ok(ThinLensRays { pinhole, lens_radius: camera.lens_radius, focal_distance: camera.focal_distance })
    }
}

impl CameraRays for ThinLensRays {
    const USES_LENS: bool = true;

    /// From the lens point to where the pinhole ray meets the focal plane.
    #[inline]
    fn ray(&self, x: u32, y: u32, u: Vec2, lens: Vec2) -> Ray {
        let c = &self.pinhole;
        let focus = c.eye + c.film_dir(x, y, u) * self.focal_distance;
        let d = concentric_disk(lens) * self.lens_radius;
        let origin = c.eye + c.right_unit * d.x + c.up_unit * d.y;
        Ray::new(origin, (focus - origin).normalize(), f32::INFINITY)
    }
}

/// The scene's one camera, prepared for an image size.
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
        let (forward, right, up) = view_basis(camera.eye, camera.target, camera.up);
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
        let (sx, sy) = film_xy(x, y, u, self.inv_width, self.inv_height);
        Ray::new(self.eye + self.right * sx + self.up * sy, self.forward, f32::INFINITY)
    }
}

impl CameraRays for OrthographicRays {
    const USES_LENS: bool = false;

    #[inline]
    fn ray(&self, x: u32, y: u32, u: Vec2, _: Vec2) -> Ray {
        OrthographicRays::ray(self, x, y, u)
    }
}

/// The scene's camera components; a frame renders exactly one of them.
#[derive(SystemParam)]
pub struct Cameras<'w, 's> {
    /// Pinhole cameras.
    pub pinhole: Query<'w, 's, &'static Camera>,
    /// Orthographic cameras.
    pub orthographic: Query<'w, 's, &'static OrthographicCamera>,
    /// Thin-lens cameras.
    pub lens: Query<'w, 's, &'static ThinLensCamera>,
}

impl Cameras<'_, '_> {
    /// The single camera prepared for the image, or `None` unless exactly one usable camera exists.
    pub fn active(&self, width: u32, height: u32) -> Option<ActiveCamera> {
        match (self.pinhole.iter().count(), self.orthographic.iter().count(), self.lens.iter().count()) {
            (1, 0, 0) => PinholeRays::new(self.pinhole.single().ok()?, width, height).ok().map(ActiveCamera::Pinhole),
            (0, 1, 0) => OrthographicRays::new(self.orthographic.single().ok()?, width, height)
                .ok()
                .map(ActiveCamera::Orthographic),
            (0, 0, 1) => ThinLensRays::new(self.lens.single().ok()?, width, height).ok().map(ActiveCamera::ThinLens),
            _ => None,
        }
    }
}

#[derive(Clone, Copy, Debug)]
pub enum ActiveCamera {
    /// A [`Camera`].
    Pinhole(PinholeRays),
    /// A [`ThinLensCamera`].
    ThinLens(ThinLensRays),
    /// An [`OrthographicCamera`].
    Orthographic(OrthographicRays),
}

impl ActiveCamera {
    /// Whether its rays start on a lens ([`CameraRays::USES_LENS`]), so that each sample of a
    /// pixel has a camera ray of its own.
    pub fn uses_lens(&self) -> bool {
        match self {
            ActiveCamera::Pinhole(_) => PinholeRays::USES_LENS,
            ActiveCamera::ThinLens(_) => ThinLensRays::USES_LENS,
            ActiveCamera::Orthographic(_) => OrthographicRays::USES_LENS,
        }
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

impl ThinLensCamera {
    /// A one-line description of what makes this camera unusable, if anything.
    pub fn validate(&self) -> Result<(), String> {
        self.pinhole().validate()?;
        if !(self.lens_radius.is_finite() && self.lens_radius >= 0.0) {
            return Err(format!("thin-lens camera lens radius {} must be finite and non-negative", self.lens_radius));
        }
        if !(self.focal_distance.is_finite() && self.focal_distance > 0.0) {
            return Err(format!("thin-lens camera focal distance {} must be finite and positive", self.focal_distance));
        }
        Ok(())
    }
}
