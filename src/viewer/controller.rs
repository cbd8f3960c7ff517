//! The camera controller: a system in [`crate::frame::FrameStage::Animate`] that turns the
//! [`Input`] resource into a new camera pose. Writing the camera component is all it does: the
//! frame's change detection restarts accumulation as for any other change.

use bevy_ecs::prelude::*;
use glam::{Quat, Vec3};

use super::input::{Input, Key};
use crate::{
    animation::NodeLink,
    components::{Camera, OrthographicCamera, ThinLensCamera},
    geometry::SceneGeometry,
};

/// Radians of orbit per pixel of cursor travel.
pub const ORBIT_PER_PIXEL: f32 = 0.006;
/// Distance factor per wheel line (dolly in for positive lines).
pub const DOLLY_PER_LINE: f32 = 0.85;
/// Fly speed in scene radii per second.
pub const FLY_RADII_PER_SECOND: f32 = 0.5;

/// Where a camera is and what it sees: the part of every camera type the controller moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CameraPose {
    /// Centre of projection.
    pub eye: Vec3,
    /// Point looked at (orbit centre).
    pub target: Vec3,
    /// Up hint.
    pub up: Vec3,
    /// Vertical field of view in degrees (perspective cameras).
    pub vfov_degrees: f32,
    /// Half the film height (orthographic cameras; 0 for perspective ones).
    pub half_height: f32,
}

impl CameraPose {
    /// The unit view direction.
    pub fn forward(&self) -> Vec3 {
        (self.target - self.eye).normalize_or(Vec3::NEG_Z)
    }

    /// Distance from eye to target.
    pub fn distance(&self) -> f32 {
        (self.target - self.eye).length()
    }

    /// Whether a camera in this pose renders (finite, eye ≠ target, up not along the view).
    pub fn valid(&self) -> bool {
        Camera { eye: self.eye, target: self.target, up: self.up, vfov_degrees: 45.0 }.validate().is_ok()
    }
}

/// The controller's state: the file's camera, to go back to with R.
#[derive(Resource, Clone, Debug, Default)]
pub struct CameraController {
    /// The pose the scene was loaded with (set on the first frame).
    pub home: Option<CameraPose>,
    /// Bounds of the scene's objects from the last built BVH (planes left out), for F and for
    /// the fly speed.
    pub bounds: Option<(Vec3, Vec3)>,
    /// Camera changes made so far.
    pub moves: u64,
}

type AnyCamera = (
    Entity,
    Option<&'static mut Camera>,
    Option<&'static mut OrthographicCamera>,
    Option<&'static mut ThinLensCamera>,
    Has<NodeLink>,
);
type CameraFilter = Or<(With<Camera>, With<OrthographicCamera>, With<ThinLensCamera>)>;

/// Moves the scene's camera as [`Input`] says (orbit, pan, dolly, fly, frame, reset). A camera
/// that an animation drives is detached from it on the first move.
pub fn control_camera(
    input: Res<Input>,
    geometry: Res<SceneGeometry>,
    mut controller: ResMut<CameraController>,
    mut cameras: Query<AnyCamera, CameraFilter>,
    mut commands: Commands,
) {
    if geometry.is_changed() || controller.bounds.is_none() {
        controller.bounds = scene_bounds(&geometry);
    }
    let Some((entity, mut pinhole, mut ortho, mut lens, linked)) = cameras.iter_mut().next() else { return };
    let pose = if let Some(c) = &pinhole {
        CameraPose { eye: c.eye, target: c.target, up: c.up, vfov_degrees: c.vfov_degrees, half_height: 0.0 }
    } else if let Some(c) = &ortho {
        CameraPose { eye: c.eye, target: c.target, up: c.up, vfov_degrees: 0.0, half_height: c.half_height }
    } else if let Some(c) = &lens {
        CameraPose { eye: c.eye, target: c.target, up: c.up, vfov_degrees: c.vfov_degrees, half_height: 0.0 }
    } else {
        return;
    };
    let home = *controller.home.get_or_insert(pose);
    if !input.moves_camera() {
        return;
    }
    let new = move_pose(pose, &input, controller.bounds, home);
    if new == pose || !new.valid() {
        return;
    }
    controller.moves += 1;
    if let Some(c) = &mut pinhole {
        **c = Camera { eye: new.eye, target: new.target, up: new.up, vfov_degrees: new.vfov_degrees };
    } else if let Some(c) = &mut ortho {
        **c = OrthographicCamera { eye: new.eye, target: new.target, up: new.up, half_height: new.half_height };
    } else if let Some(c) = &mut lens {
        let focal_distance = if new.distance() > 0.0 { new.distance() } else { c.focal_distance };
        **c = ThinLensCamera { eye: new.eye, target: new.target, up: new.up, focal_distance, ..**c };
    }
    if linked {
        commands.entity(entity).remove::<NodeLink>();
    }
}

/// Union of the placed objects' bounds, alpha-tested meshes included (planes are unbounded and
/// left out).
pub fn scene_bounds(geometry: &SceneGeometry) -> Option<(Vec3, Vec3)> {
    geometry.instances().iter().chain(geometry.alpha_instances()).map(|i| i.bounds()).fold(None, |acc, b| {
        let (lo, hi) = (Vec3::from(b.min), Vec3::from(b.max));
        if !(lo.is_finite() && hi.is_finite()) || lo.cmpgt(hi).any() {
            return acc;
        }
        Some(acc.map_or((lo, hi), |(a, c): (Vec3, Vec3)| (a.min(lo), c.max(hi))))
    })
}

/// The pose after one frame of input: reset (R) and frame (F) first, then orbit (cursor and
/// turntable), pan, dolly and fly.
pub fn move_pose(pose: CameraPose, input: &Input, bounds: Option<(Vec3, Vec3)>, home: CameraPose) -> CameraPose {
    let mut p = pose;
    let (center, radius) = match bounds {
        Some((lo, hi)) => ((lo + hi) * 0.5, ((hi - lo).length() * 0.5).max(1e-3)),
        None => (p.target, p.distance().max(1e-3)),
    };
    for key in &input.pressed {
        match key {
            Key::R => p = home,
            Key::F => p = frame_bounds(p, center, radius),
            _ => {}
        }
    }
    // Orbit: yaw about the world's vertical through the target, pitch about the camera's right.
    let yaw = -input.orbit.x * ORBIT_PER_PIXEL + input.turntable;
    let pitch = -input.orbit.y * ORBIT_PER_PIXEL;
    if yaw != 0.0 || pitch != 0.0 {
        let offset = p.eye - p.target;
        let right = p.forward().cross(p.up).normalize_or(Vec3::X);
        let mut q = Quat::from_axis_angle(Vec3::Y, yaw);
        let pitched = Quat::from_axis_angle(right, pitch) * offset;
        // Never over the pole: keep the view at least ~2.5° from the vertical.
        if pitch != 0.0 && pitched.normalize_or_zero().dot(Vec3::Y).abs() < 0.999 {
            q *= Quat::from_axis_angle(right, pitch);
        }
        p.eye = p.target + q * offset;
        p.up = (q * p.up).normalize_or(Vec3::Y);
    }
    let forward = p.forward();
    let right = forward.cross(p.up).normalize_or(Vec3::X);
    let up = right.cross(forward);
    if input.pan != glam::Vec2::ZERO {
        // World units per pixel at the target's depth, so the target follows the cursor.
        let film_height = if p.half_height > 0.0 {
            2.0 * p.half_height
        } else {
            2.0 * p.distance() * (p.vfov_degrees.to_radians() * 0.5).tan()
        };
        let per_pixel = film_height / input.viewport_height.max(1.0);
        let d = (-input.pan.x * right + input.pan.y * up) * per_pixel;
        p.eye += d;
        p.target += d;
    }
    if input.wheel != 0.0 {
        let factor = DOLLY_PER_LINE.powf(input.wheel);
        if p.half_height > 0.0 {
            p.half_height = (p.half_height * factor).max(1e-6);
        } else {
            let distance = (p.distance() * factor).max(radius * 1e-4);
            p.eye = p.target - forward * distance;
        }
    }
    let fly = input.fly();
    if fly != Vec3::ZERO && input.dt > 0.0 {
        let d = (right * fly.x + Vec3::Y * fly.y + forward * fly.z).normalize_or_zero()
            * (radius * FLY_RADII_PER_SECOND * input.dt);
        p.eye += d;
        p.target += d;
    }
    p
}

/// `pose` looking along its own direction at the centre of a sphere, from just far enough
/// that the sphere fits the view.
pub fn frame_bounds(pose: CameraPose, center: Vec3, radius: f32) -> CameraPose {
    let forward = pose.forward();
    if pose.half_height > 0.0 {
        let distance = pose.distance().max(radius * 2.0);
        return CameraPose { eye: center - forward * distance, target: center, half_height: radius * 1.05, ..pose };
    }
    let half = (pose.vfov_degrees.to_radians() * 0.5).clamp(0.01, 1.5);
    let distance = radius / half.sin() * 1.05;
    CameraPose { eye: center - forward * distance, target: center, ..pose }
}
