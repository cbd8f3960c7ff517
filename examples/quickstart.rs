//! hemi as a library: spawn a camera, the ambient occluder, a light and some shapes into a
//! renderer's world, add a system of your own, render and save.
//!
//! ```sh
//! cargo run --release --example quickstart -- quickstart.png
//! ```

use hemi::prelude::*;

/// Marks the entities `spin` turns. Deriving `Component` needs no dependency but hemi: the
/// prelude brings in the `bevy_ecs` the derive refers to.
#[derive(Component)]
struct Spin {
    /// Turns per second.
    speed: f32,
}

/// Turns each spinning entity about +Y for the scene time. Driven by [`Time`], not by frame
/// count, so the scene holds still while a render to a sample count accumulates.
fn spin(time: Res<Time>, mut spinning: Query<(&Spin, &mut Transform)>) {
    for (spin, mut transform) in &mut spinning {
        let rotation = Quat::from_rotation_y(std::f32::consts::TAU * spin.speed * time.seconds);
        // Writing the same value again would not restart accumulation, but skipping it saves
        // the BVH update.
        if transform.rotation != rotation {
            transform.rotation = rotation;
        }
    }
}

fn main() -> Result<(), HemiError> {
    let out = std::env::args().nth(1).unwrap_or_else(|| "quickstart.png".into());
    let mut renderer = Renderer::new(RenderSettings { width: 640, height: 360, ..Default::default() });
    renderer.schedule_mut().add_systems(spin.in_set(FrameStage::Animate));

    let world = renderer.world_mut();
    world.spawn(Camera::look_at(Vec3::new(0.0, 2.0, 7.0), Vec3::new(0.0, 0.8, 0.0), 40.0));
    world.spawn(AmbientOccluder { ls: 0.6, ..Default::default() });
    world.spawn((PointLight { ls: 12.0, ..Default::default() }, Transform::from_xyz(-3.0, 5.0, 2.0)));
    world.spawn((Sphere { radius: 0.8 }, Transform::from_xyz(-1.2, 0.8, 0.0), Matte::new(Vec3::new(0.85, 0.3, 0.25))));
    world.spawn((
        Spin { speed: 0.25 },
        Cuboid { half_extents: Vec3::new(0.6, 0.6, 0.6) },
        Transform::from_xyz(1.2, 0.6, 0.0),
        Matte::new(Vec3::new(0.3, 0.55, 0.85)),
    ));
    world.spawn((Plane::default(), Matte::new(Vec3::splat(0.75))));

    // 0.3 s in: the cube has turned by 27 degrees.
    renderer.set_time(0.3);
    renderer.render(16)?;
    renderer.save(out.as_ref())?;
    println!("wrote {out}: {} spp", renderer.spp());
    Ok(())
}
