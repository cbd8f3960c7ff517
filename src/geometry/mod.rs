//! Geometry: rays, primitive intersection with error bounds, and the acceleration structure.

pub mod accel;
pub mod binned_sah;
pub mod counters;
pub mod hit;
pub(crate) mod huge_pages;
#[cfg(target_arch = "x86_64")]
pub(crate) mod lanes;
pub mod ray;
pub mod shapes;
#[cfg(target_arch = "x86_64")]
pub(crate) mod surface_lanes;
pub mod tri4;
pub mod wide_bvh;
pub mod world_space;

pub use accel::{Object, Prim, RayEnd, RayOrder, SceneGeometry, Shape};
pub use counters::TraversalCounts;
pub use hit::{SpawnOrigins, SurfaceHit};
pub use ray::{Ray, Shear};
