//! Geometry: rays, primitive intersection with error bounds, and the acceleration structure.

pub mod accel;
pub mod hit;
pub mod ray;
pub mod shapes;
pub mod tri4;
pub mod wide_bvh;
pub mod world_space;

pub use accel::{Object, Prim, SceneGeometry, Shape};
pub use hit::{SpawnOrigins, SurfaceHit};
pub use ray::{Ray, Shear};
