//! # hemi
//!
//! Ambient occlusion plus direct illumination by CPU ray tracing, structured as a bevy_ecs
//! world whose systems run once per frame (see [`systems`]):
//! scene changes → BVH → sample sets → trace → accumulate → resolve.
//!
//! Lights are an extension point ([`light`]): hemi's own (beside it in [`light`]) are written exactly as a
//! user's would be and registered through the same [`Renderer::add_light`] call.
//!
//! Scene objects, the camera, the ambient occluder and lights are ECS components
//! ([`components`]); spawn them into a [`Renderer`]'s world and call
//! [`Renderer::run_frame`] as often as you like, or [`Renderer::render`] to a sample count. A
//! static scene converges progressively; any change to an entity's components or to the
//! settings restarts accumulation automatically (writing a value equal to the old one is no
//! change). [`prelude`] has what a program needs, bevy's derives included.
//!
//! The cargo feature `cli` (on by default) builds the `hemi` binary and its `cli` module; a
//! library user who sets `default-features = false` compiles none of its dependencies.

pub mod analytic;
pub mod animation;
pub mod camera;
#[cfg(feature = "cli")]
pub mod cli;
pub mod components;
pub mod error;
pub mod film;
pub mod frame;
pub mod geometry;
pub mod integrator;
pub mod layers;
pub mod light;
pub mod look;
pub mod material;
pub mod math;
pub mod partial;
pub mod random;
pub mod renderer;
pub mod resources;
pub mod sampling;
pub mod scene;
pub mod sequence;
mod simd;
pub mod srgb;
pub mod stats;
#[path = "../systems/mod.rs"]
pub mod systems;
#[cfg(feature = "cli")]
pub mod viewer;

pub use bevy_ecs;
pub use error::HemiError;
pub use glam;
pub use renderer::Renderer;

/// The README's library example, compiled and run as a doctest so it stays true.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

/// What a program that drives a [`Renderer`] reaches for: hemi's components, resources and
/// light API, the bevy_ecs items its systems are written with, and glam's vectors.
///
/// It also brings the `bevy_ecs` crate itself into scope, which is what lets bevy's derive
/// macros work in a crate whose only dependency is hemi: `#[derive(Component)]` expands to
/// paths that start with `bevy_ecs::` whenever the crate's `Cargo.toml` names neither `bevy`
/// nor `bevy_ecs`, and those paths then resolve through this re-export. A module that does not
/// glob-import the prelude gets the same with `use hemi::bevy_ecs;`.
///
/// ```
/// use hemi::prelude::*;
///
/// #[derive(Component)]
/// struct Spin;
///
/// fn spin(time: Res<Time>, mut spinning: Query<&mut Transform, With<Spin>>) {
///     for mut transform in &mut spinning {
///         transform.rotation = Quat::from_rotation_y(time.seconds);
///     }
/// }
///
/// let mut renderer = Renderer::new(RenderSettings { width: 16, height: 8, ..Default::default() });
/// renderer.schedule_mut().add_systems(spin.in_set(FrameStage::Animate));
/// renderer.world_mut().spawn((Spin, Cuboid { half_extents: Vec3::ONE }));
/// ```
pub mod prelude {
    pub use bevy_ecs::{
        self,
        change_detection::{DetectChanges, DetectChangesMut, Mut},
        component::Component,
        entity::Entity,
        name::Name,
        query::{Changed, With, Without},
        resource::Resource,
        schedule::{IntoScheduleConfigs, Schedule},
        system::{Commands, Local, Query, Res, ResMut},
        world::World,
    };
    pub use glam::{Quat, Vec2, Vec3, Vec3A};

    pub use crate::{
        Renderer,
        components::{
            AmbientOccluder, Camera, Cuboid, Deforming, DirectionalLight, DiskLight, Dynamic, Matte, Mesh,
            OrthographicCamera, Plane, PointLight, Sphere, SpotLight, ThinLensCamera, Transform, TriangleMesh,
        },
        error::HemiError,
        frame::FrameStage,
        light::{Light, LightSample, LightSamples, PlacedLight, ShadingPoint, Shadow, Term},
        resources::{Image, RenderSettings, Time},
        sampling::SamplerKind,
        stats::FrameStats,
    };
}
