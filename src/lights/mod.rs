//! hemi's own lights. Each is written exactly as an outside crate would write one: a
//! component implementing [`crate::light::Light`], registered by [`crate::Renderer::new`]
//! through the same [`crate::Renderer::add_light`] call a user makes, in this order:
//! ambient occluder, point, directional, spot, disk.

pub mod ambient;
pub mod directional;
pub mod disk;
pub mod point;
pub mod spot;

pub use ambient::AmbientOccluder;
pub use directional::DirectionalLight;
pub use disk::DiskLight;
pub use point::PointLight;
pub use spot::SpotLight;
