//! Scene building: the built-in default scene and procedural meshes.

pub mod default_scene;
pub mod mesh_gen;

pub use default_scene::{DEFAULT_BACKGROUND, spawn_default_scene};
