//! hemi's own lights. Each is written exactly as an outside crate would write one: a
//! component implementing [`crate::light::Light`], registered by [`crate::Renderer::new`]
//! through the same [`crate::Renderer::add_light`] call a user makes.

pub mod ambient;
pub mod point;

pub use ambient::AmbientOccluder;
pub use point::PointLight;
