//! The integrator: for every camera sample, a primary ray, then every registered light group
//! at its hit. The core knows no light kinds ([`crate::light`] is the extension point): it
//! applies the reflectance a light names, traces the shadow rays lights ask for, and counts them.
//!
//! - [`tracer`]: the per-thread [`Tracer`] and what a sample reads ([`Scene`]);
//! - [`light_groups`]: the registry of light types, each a type-erased group of placed lights;
//! - [`sample`]: what a sample yields ([`SampleResult`]);
//! - `direction_rays`: the occluder's shadow rays, set up and traced a SIMD vector at a time.

pub(crate) mod direction_rays;
pub mod light_groups;
pub mod sample;
pub mod tracer;

pub use light_groups::{LightGroup, LightRegistry, RunSum, register_light};
pub use sample::{OwnSample, PrimaryHit, SampleOut, SampleResult, ShadedSum, TwoValues};
pub use tracer::{RunPoint, Scene, Tracer};
