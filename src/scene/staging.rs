//! Staging a loaded scene for a shot: a camera put in place of the file's, and a ground plane
//! under an isolated model so that it gets its contact shadows.

use bevy_ecs::{
    entity::Entity,
    prelude::World,
    query::{Or, With},
};
use glam::Vec3;

use crate::components::{
    Camera, Cuboid, Matte, OrthographicCamera, Plane, Sphere, ThinLensCamera, Transform, TriangleMesh,
};

/// Axis-aligned bounds of the world's finite objects (meshes, spheres, boxes) as their
/// transforms place them now; planes are unbounded and left out. `None` without any.
pub fn world_bounds(world: &mut World) -> Option<(Vec3, Vec3)> {
    let mut points: Vec<Vec3> = Vec::new();
    for (mesh, t) in world.query::<(&TriangleMesh, &Transform)>().iter(world) {
        let Some(m) = t.to_affine() else { continue };
        points.extend(mesh.0.positions.iter().map(|&p| m.transform_point3(p)));
    }
    for (sphere, t) in world.query::<(&Sphere, &Transform)>().iter(world) {
        let r = Vec3::splat(sphere.radius * t.scale.abs().max_element());
        points.extend([t.translation - r, t.translation + r]);
    }
    for (cuboid, t) in world.query::<(&Cuboid, &Transform)>().iter(world) {
        let Some(m) = t.to_affine() else { continue };
        let h = cuboid.half_extents;
        points.extend((0..8).map(|k| {
            let corner = Vec3::new(
                if k & 1 == 0 { -h.x } else { h.x },
                if k & 2 == 0 { -h.y } else { h.y },
                if k & 4 == 0 { -h.z } else { h.z },
            );
            m.transform_point3(corner)
        }));
    }
    points
        .into_iter()
        .filter(|p| p.is_finite())
        .fold(None, |acc, p| Some(acc.map_or((p, p), |(lo, hi)| (lo.min(p), hi.max(p)))))
}

/// Fraction of the bounds' diagonal by which the ground lies below their lowest point: a flat
/// underside resting there is not coplanar with the ground, yet the gap is far below a pixel.
const GROUND_GAP: f32 = 1e-4;

/// Spawns a default grey [`Matte`] ground plane (y up) just under the world's objects as they
/// are placed now, and returns its height; `None` (nothing spawned) for a world without
/// finite objects.
pub fn spawn_ground(world: &mut World) -> Option<f32> {
    let (lo, hi) = world_bounds(world)?;
    let y = lo.y - GROUND_GAP * (hi - lo).length().max(f32::MIN_POSITIVE);
    world.spawn((Plane::default(), Transform::from_xyz(0.0, y, 0.0), Matte::default()));
    Some(y)
}

/// Puts `camera` in place of every camera of the world (the file's, animated or not), after
/// checking it: one line naming what makes it unusable.
pub fn replace_camera(world: &mut World, camera: Camera) -> Result<(), String> {
    camera.validate()?;
    let old: Vec<Entity> = world
        .query_filtered::<Entity, Or<(With<Camera>, With<OrthographicCamera>, With<ThinLensCamera>)>>()
        .iter(world)
        .collect();
    for entity in old {
        world.despawn(entity);
    }
    world.spawn(camera);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_cover_every_finite_object_and_the_ground_lies_under_them() {
        let mut world = World::new();
        assert_eq!(world_bounds(&mut world), None);
        assert_eq!(spawn_ground(&mut world), None);
        world.spawn((Sphere { radius: 1.0 }, Transform::from_xyz(0.0, 2.0, 0.0).with_scale(2.0)));
        world.spawn((Cuboid { half_extents: Vec3::splat(0.5) }, Transform::from_xyz(5.0, 0.0, 0.0)));
        world.spawn(Plane::default());
        let (lo, hi) = world_bounds(&mut world).unwrap();
        assert_eq!((lo, hi), (Vec3::new(-2.0, -0.5, -2.0), Vec3::new(5.5, 4.0, 2.0)));
        let y = spawn_ground(&mut world).unwrap();
        assert!(y < -0.5 && y > -0.5 - 1e-3, "{y}");
    }

    #[test]
    fn a_replaced_camera_is_the_only_one_and_a_degenerate_one_is_refused() {
        let mut world = World::new();
        world.spawn(Camera::look_at(Vec3::Z, Vec3::ZERO, 40.0));
        world.spawn(OrthographicCamera { eye: Vec3::Z, target: Vec3::ZERO, up: Vec3::Y, half_height: 1.0 });
        let same = Camera::look_at(Vec3::ONE, Vec3::ONE, 40.0);
        assert!(replace_camera(&mut world, same).unwrap_err().contains("same point"));
        let parallel = Camera { up: Vec3::Y, ..Camera::look_at(Vec3::Y, Vec3::ZERO, 40.0) };
        assert!(replace_camera(&mut world, parallel).unwrap_err().contains("parallel"));
        let new = Camera::look_at(Vec3::new(0.0, 1.0, 5.0), Vec3::ZERO, 30.0);
        replace_camera(&mut world, new).unwrap();
        let cameras: Vec<Camera> = world.query::<&Camera>().iter(&world).copied().collect();
        assert_eq!(cameras, [new]);
        assert_eq!(world.query::<&OrthographicCamera>().iter(&world).count(), 0);
    }
}
