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
//! [`Renderer::run_frame`] as often as you like. A static scene converges progressively;
//! any change to an entity or to the settings restarts accumulation automatically.

pub mod analytic;
pub mod animation;
pub mod camera;
pub mod cli;
pub mod components;
pub mod convergence;
pub mod error;
pub mod film;
pub mod frame;
pub mod geometry;
mod huge_pages;
pub mod integrator;
pub mod light;
pub mod math;
pub mod npy;
pub mod partial;
pub mod plot;
pub mod random;
pub mod renderer;
pub mod resources;
pub mod sampling;
pub mod scene;
pub mod sequence;
mod simd;
pub mod stats;
#[path = "../systems/mod.rs"]
pub mod systems;

pub use bevy_ecs;
pub use error::HemiError;
pub use glam;
pub use renderer::Renderer;

/// The types most programs need.
pub mod prelude {
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
    pub use bevy_ecs::{
        component::Component,
        entity::Entity,
        name::Name,
        query::{With, Without},
        world::World,
    };
    pub use glam::{Quat, Vec2, Vec3, Vec3A};
}
