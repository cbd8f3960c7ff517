//! The built-in scene `hemi render` draws: spheres, boxes and a torus-knot mesh over a ground
//! plane, lit by an ambient occluder and one shadow-casting point light.

use std::sync::Arc;

use bevy_ecs::prelude::World;
use glam::{Quat, Vec3};

use super::mesh_gen::torus_knot;
use crate::components::{AmbientOccluder, Camera, Cuboid, Matte, Plane, PointLight, Sphere, Transform, TriangleMesh};

/// Sky colour behind the default scene.
pub const DEFAULT_BACKGROUND: Vec3 = Vec3::new(0.62, 0.72, 0.86);

/// Spawns the default scene into `world`.
pub fn spawn_default_scene(world: &mut World) {
    world.spawn(Camera::look_at(Vec3::new(0.0, 2.6, 8.2), Vec3::new(0.0, 0.9, 0.0), 38.0));
    world.spawn(AmbientOccluder { ls: 0.7, min_amount: 0.05, ..Default::default() });
    world.spawn((
        PointLight { ls: 55.0, color: Vec3::new(1.0, 0.93, 0.82), ..Default::default() },
        Transform::from_xyz(-4.0, 7.0, 5.0),
    ));

    world.spawn((Plane::default(), Matte::new(Vec3::splat(0.75))));
    world.spawn((Sphere { radius: 1.0 }, Transform::from_xyz(-2.3, 1.0, 0.0), Matte::new(Vec3::new(0.85, 0.3, 0.25))));
    world.spawn((Sphere { radius: 0.45 }, Transform::from_xyz(1.2, 0.45, 1.9), Matte::new(Vec3::new(0.3, 0.55, 0.85))));
    world.spawn((Sphere { radius: 0.3 }, Transform::from_xyz(-0.9, 0.3, 2.0), Matte::new(Vec3::new(0.95, 0.8, 0.3))));
    world.spawn((
        Cuboid { half_extents: Vec3::new(0.7, 0.7, 0.7) },
        Transform::from_xyz(2.4, 0.7, -0.6).with_rotation(Quat::from_rotation_y(0.6)),
        Matte::new(Vec3::new(0.45, 0.75, 0.4)),
    ));
    world.spawn((
        Cuboid { half_extents: Vec3::new(1.5, 0.12, 1.0) },
        Transform::from_xyz(0.1, 0.12, -1.5).with_rotation(Quat::from_rotation_y(-0.25)),
        Matte::new(Vec3::new(0.72, 0.55, 0.38)),
    ));
    world.spawn((
        TriangleMesh(Arc::new(torus_knot(2, 3, 0.75, 0.2, 240, 20))),
        Transform::from_xyz(0.1, 0.82, -1.5),
        Matte::new(Vec3::new(0.9, 0.9, 0.88)),
    ));
}
