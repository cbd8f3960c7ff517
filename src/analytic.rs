//! Scenes with closed-form ambient occlusion, used as ground truth by tests and by
//! `hemi error`: every pixel's expected value is the analytic AO averaged over the pixel.

use bevy_ecs::prelude::World;
use glam::{DVec3, Vec2, Vec3};

use crate::{
    camera::PinholeRays,
    components::{AmbientOccluder, Camera, Cuboid, Matte, Plane, Sphere, Transform},
};

/// A scene whose AO has a closed form.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum AnalyticScene {
    /// A sphere (radius 1, centre height 1.5) over a plane, seen from above beside the sphere:
    /// AO(x) = 1 − r²h/(h² + x²)^{3/2} (the sphere's configuration factor).
    SphereOverPlane,
    /// The floor beside a long wall of height 1: AO(x) = ½(1 + x/√(x² + H²)).
    Wall,
}

impl AnalyticScene {
    /// Every analytic scene.
    pub const ALL: [AnalyticScene; 2] = [AnalyticScene::SphereOverPlane, AnalyticScene::Wall];

    /// Command-line name.
    pub fn name(self) -> &'static str {
        match self {
            AnalyticScene::SphereOverPlane => "sphere-over-plane",
            AnalyticScene::Wall => "wall",
        }
    }

    /// Parses a command-line name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Default image size (wide strips of floor).
    pub fn size(self) -> (u32, u32) {
        (48, 12)
    }

    /// Spawns the scene, scaled by `scale` and moved by `offset`, with a white matte
    /// (ka = kd = 1, cd = 1) and a unit occluder, so each pixel's value is its AO. Returns the
    /// camera.
    pub fn spawn(self, world: &mut World, scale: f32, offset: Vec3) -> Camera {
        let white = Matte { ka: 1.0, kd: 1.0, cd: Vec3::ONE };
        let at = |p: Vec3| Transform::from_translation(offset + p * scale);
        world.spawn((Plane::default(), at(Vec3::ZERO), white));
        world.spawn(AmbientOccluder::default());
        match self {
            AnalyticScene::SphereOverPlane => {
                world.spawn((Sphere { radius: scale }, at(Vec3::new(0.0, 1.5, 0.0)), white));
            }
            AnalyticScene::Wall => {
                // A 4000-long, 0.01-thick wall whose face is the plane z = 0.
                let half = Vec3::new(2000.0, 0.5, 0.005) * scale;
                world.spawn((Cuboid { half_extents: half }, at(Vec3::new(0.0, 0.5, -0.005)), white));
            }
        }
        let camera = self.camera(scale, offset);
        world.spawn(camera);
        camera
    }

    /// The scene's camera, scaled by `scale` and moved by `offset` with the scene.
    pub fn camera(self, scale: f32, offset: Vec3) -> Camera {
        let camera = match self {
            // Straight down at floor points x ∈ [~1.1, ~4.9]: no line of sight meets the sphere.
            AnalyticScene::SphereOverPlane => Camera {
                eye: Vec3::new(3.0, 30.0, 0.0),
                target: Vec3::new(3.0, 0.0, 0.0),
                up: Vec3::NEG_Z,
                vfov_degrees: 1.8,
            },
            // Straight down at the floor in front of the wall's face.
            AnalyticScene::Wall => Camera {
                eye: Vec3::new(0.0, 40.0, 1.6),
                target: Vec3::new(0.0, 0.0, 1.6),
                up: Vec3::NEG_X,
                vfov_degrees: 0.6,
            },
        };
        Camera { eye: offset + camera.eye * scale, target: offset + camera.target * scale, ..camera }
    }

    /// AO at a floor point given in scene units (before scale and offset).
    pub fn ao(self, p: Vec3) -> f32 {
        match self {
            AnalyticScene::SphereOverPlane => {
                let (r, h) = (1.0f32, 1.5f32);
                1.0 - r * r * h / (h * h + p.x * p.x + p.z * p.z).powf(1.5)
            }
            AnalyticScene::Wall => 0.5 * (1.0 + p.z / (p.z * p.z + 1.0).sqrt()),
        }
    }

    /// Expected value of every pixel: the analytic AO averaged over the pixel's footprint.
    pub fn reference(
        self,
        camera: &Camera,
        width: u32,
        height: u32,
        scale: f32,
        offset: Vec3,
    ) -> Result<Vec<f32>, String> {
        let rays = PinholeRays::new(camera, width, height)?;
        let mut out = Vec::with_capacity((width * height) as usize);
        for y in 0..height {
            for x in 0..width {
                out.push(pixel_mean_on_floor(&rays, x, y, offset.y, |p| self.ao((p - offset) / scale)));
            }
        }
        Ok(out)
    }
}

/// Point where the camera ray through film position (x + u) meets the floor y = `floor_y`,
/// computed in f64 so that references carry none of the rounding being tested.
pub fn floor_hit(rays: &PinholeRays, x: u32, y: u32, u: Vec2, floor_y: f32) -> Vec3 {
    let ray = rays.ray(x, y, u);
    let (o, d): (DVec3, DVec3) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let t = (floor_y as f64 - o.y) / d.y;
    (o + d * t).as_vec3()
}

/// Mean of `f` over a pixel's footprint on the floor (8 × 8 sub-pixel grid).
pub fn pixel_mean_on_floor(rays: &PinholeRays, x: u32, y: u32, floor_y: f32, f: impl Fn(Vec3) -> f32) -> f32 {
    let mut sum = 0.0;
    for j in 0..8 {
        for i in 0..8 {
            let u = Vec2::new((i as f32 + 0.5) / 8.0, (j as f32 + 0.5) / 8.0);
            sum += f(floor_hit(rays, x, y, u, floor_y));
        }
    }
    sum / 64.0
}
