//! Scene building: the built-in default scene, procedural meshes and glTF 2.0 files.

pub mod default_scene;
pub mod gltf;
pub mod mesh_gen;
pub mod staging;

pub use default_scene::{DEFAULT_BACKGROUND, spawn_default_scene};
