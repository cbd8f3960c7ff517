//! The light extension point. A light is an ECS component implementing [`Light`]; once per
//! change it is *placed* in world space ([`Light::place`]), and for every shading point the
//! placed light ([`PlacedLight::sample`]) returns what arrives there and the shadow ray that
//! decides whether it does. Registering a light type is one call,
//! [`Renderer::add_light`](crate::Renderer::add_light) (or
//! [`register_light`](crate::integrator::register_light) on a bare world and schedule): it adds a system that notices changes to that component (restarting
//! accumulation), validates it and keeps the placed lights ready for the trace system.
//!
//! The core never looks at light kinds: it multiplies what a light returns by the material
//! reflectance the light names ([`Term`]), traces the shadow ray (offsetting its origin past the
//! surface's error bound), and counts it. Every built-in light, the ambient occluder included,
//! goes through exactly this path.
//!
//! Sample dimensions: dimension [`dims::LIGHTS`](crate::sampling::dims::LIGHTS) onwards is
//! dealt out in registration order, then entity order, [`PlacedLight::DIMS`] per light, so
//! every light's random numbers are a pure function of (pixel, sample index, dimension).

pub mod ambient;
pub mod directional;
pub mod disk;
pub mod point;
pub mod spot;

use bevy_ecs::component::Component;
use glam::{Vec2, Vec3, Vec3A, Vec4};

use crate::{
    components::{Matte, Transform},
    math::Onb,
    sampling::SampleSets,
};

/// Checks a light's `ls` and `color`: finite and non-negative. `name` starts the message.
pub fn check_emission(name: &str, ls: f32, color: Vec3) -> Result<(), String> {
    if ls.is_finite() && ls >= 0.0 && color.is_finite() && color.min_element() >= 0.0 {
        Ok(())
    } else {
        Err(format!("{name} ls {ls} color {color} must be finite and non-negative"))
    }
}

/// Checks that a light's transform places it at a finite position.
pub fn check_position(name: &str, transform: &Transform) -> Result<(), String> {
    if transform.translation.is_finite() {
        Ok(())
    } else {
        Err(format!("{name} position {} is not finite", transform.translation))
    }
}

/// Checks that a light's transform gives it a direction (its local −Z).
pub fn check_direction(name: &str, transform: &Transform) -> Result<(), String> {
    if transform.forward() == Vec3::ZERO {
        Err(format!("{name} rotation {} gives no direction", transform.rotation))
    } else {
        Ok(())
    }
}

/// The reflectance a light's samples are multiplied by.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Term {
    /// RTGU's ambient BRDF `ka·cd`: the light returns radiance. Its shadow rays count as AO rays.
    Ambient,
    /// The Lambertian BRDF `kd·cd/π`: the light returns an irradiance estimate `L·cos θ / pdf`.
    /// Its shadow rays count as shadow rays.
    Diffuse,
}

impl Term {
    /// The material's reflectance for this term.
    #[inline]
    pub fn reflectance(self, m: &Matte) -> Vec3 {
        match self {
            Term::Ambient => m.cd * m.ka,
            Term::Diffuse => m.cd * (m.kd * std::f32::consts::FRAC_1_PI),
        }
    }
}

/// The surface point being lit.
#[derive(Clone, Copy, Debug)]
pub struct ShadingPoint {
    /// Position.
    pub p: Vec3A,
    /// Unit geometric normal, facing the side the camera ray came from.
    pub normal: Vec3A,
    /// Material at the point.
    pub material: Matte,
    /// The symmetry of the tangent square its frame is turned by ([`Onb::symmetry`], 0..8; 0
    /// leaves it as built).
    symmetry: u32,
}

impl ShadingPoint {
    /// The point at `p` with unit normal `normal`.
    #[inline]
    pub fn new(p: Vec3A, normal: Vec3A, material: Matte) -> Self {
        ShadingPoint { p, normal, material, symmetry: 0 }
    }

    /// The point with its frame turned by symmetry `k` (0..8) of its tangent square.
    #[inline]
    pub fn with_symmetry(self, k: u32) -> Self {
        ShadingPoint { symmetry: k, ..self }
    }

    /// The symmetry its frame is turned by (0..8).
    #[inline(always)]
    pub fn symmetry(&self) -> u32 {
        self.symmetry
    }

    /// Orthonormal frame with `w` = `normal`, for lights that sample directions around the
    /// normal (`frame().to_world(local)`): [`Onb::from_normal`], turned by the point's
    /// symmetry. Made when asked: a light that samples a run of directions at one point asks
    /// once for them all.
    #[inline]
    pub fn frame(&self) -> Onb {
        Onb::from_normal(self.normal.into()).symmetry(self.symmetry)
    }
}

/// The segment a shadow ray tests. The core starts it just off the surface.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shadow {
    /// Towards a point on the light: blocked by anything strictly between surface and point.
    ToPoint(Vec3A),
    /// Along a unit direction, up to a distance (`f32::INFINITY` for lights at infinity).
    Along {
        /// Unit direction towards the light.
        dir: Vec3A,
        /// Blockers farther than this do not count.
        max_distance: f32,
    },
}

/// One light sample at a shading point: what arrives when the shadow ray is clear and when it
/// is blocked (non-zero only for lights with a floor, like the ambient occluder's
/// `min_amount`). The core multiplies the chosen value by the reflectance of the light's
/// [`Term`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Contribution when the shadow ray is clear (or when there is none).
    pub unoccluded: Vec3,
    /// Contribution when the shadow ray is blocked.
    pub occluded: Vec3,
    /// The visibility test; `None`: always unoccluded. No ray is traced either when the two
    /// values are equal.
    pub shadow: Option<Shadow>,
}

/// What a *direction light* brings at a point: each sample is a direction `ω` with a weight
/// `w`, tested up to `max_distance`, and brings `radiance·(floor + (1 − floor)·w)` when its ray
/// is clear and `radiance·floor` when it is blocked (or when `w ≤ 0`, with no ray). The ambient
/// occluder is one. See [`PlacedLight::sample_directions`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DirectionTerms {
    /// Radiance of a clear sample of weight 1 with no floor.
    pub radiance: Vec3,
    /// Fraction that still arrives from blocked directions, in [0, 1].
    pub floor: f32,
    /// Blockers farther than this do not count (`f32::INFINITY` for none).
    pub max_distance: f32,
}

impl DirectionTerms {
    /// The [`LightSample`] of one direction `dir` (world space, unit) of weight `weight`.
    #[inline(always)]
    pub fn light_sample(&self, weight: f32, dir: Vec3A) -> LightSample {
        let floor = self.radiance * self.floor;
        if weight <= 0.0 {
            return LightSample { unoccluded: floor, occluded: floor, shadow: None };
        }
        LightSample {
            unoccluded: self.radiance * (self.floor + (1.0 - self.floor) * weight),
            occluded: floor,
            shadow: Some(Shadow::Along { dir, max_distance: self.max_distance }),
        }
    }
}

/// A run of direction samples at one point as structure-of-arrays: sample `j` is the world-space
/// unit direction (`x[j]`, `y[j]`, `z[j]`) with weight `weight[j]`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DirectionRun {
    /// x of each direction.
    pub x: Vec<f32>,
    /// y of each direction.
    pub y: Vec<f32>,
    /// z of each direction.
    pub z: Vec<f32>,
    /// Each sample's weight.
    pub weight: Vec<f32>,
}

impl DirectionRun {
    /// Makes room for `n` samples, in whole groups of sixteen lanes: each column gets `n`
    /// rounded up to a multiple of sixteen entries (lanes past `n` may hold anything; they are
    /// not used).
    pub fn resize(&mut self, n: usize) {
        for column in [&mut self.x, &mut self.y, &mut self.z, &mut self.weight] {
            column.resize(n.next_multiple_of(16), 0.0);
        }
    }

    /// Writes group `k` (samples `4k..4k + 4`): x, y, z and weight lanes.
    #[inline(always)]
    pub fn set_group(&mut self, k: usize, lanes: [Vec4; 4]) {
        for (column, v) in [&mut self.x, &mut self.y, &mut self.z, &mut self.weight].into_iter().zip(lanes) {
            v.write_to_slice(&mut column[4 * k..4 * k + 4]);
        }
    }

    /// Sample `j`'s direction.
    #[inline]
    pub fn dir(&self, j: usize) -> Vec3A {
        Vec3A::new(self.x[j], self.y[j], self.z[j])
    }

    /// The [`LightSample`] that sample `j` stands for under `terms`.
    pub fn light_sample(&self, j: usize, terms: &DirectionTerms) -> LightSample {
        terms.light_sample(self.weight[j], self.dir(j))
    }
}

/// The 2-D sample values of one light at one shading point.
#[derive(Clone, Copy, Debug)]
pub struct LightSamples<'a> {
    source: Source<'a>,
}

#[derive(Clone, Copy, Debug)]
enum Source<'a> {
    Sets { sets: &'a SampleSets, pixel: u32, index: u32, first_dim: u32, last: u32 },
    Columns { values: &'a [Vec2], at: usize, stride: usize, last: u32 },
    Fixed(Vec2),
}

impl<'a> LightSamples<'a> {
    /// The samples the renderer uses: dimensions `first_dim .. first_dim + dims`, computed on
    /// demand.
    #[inline]
    pub fn from_sets(sets: &'a SampleSets, pixel: u32, index: u32, first_dim: u32, dims: u32) -> Self {
        LightSamples { source: Source::Sets { sets, pixel, index, first_dim, last: dims.saturating_sub(1) } }
    }

    /// Sample `at` of a run computed ahead: dimension `k`'s samples are
    /// `values[k * stride..(k + 1) * stride]`, as [`SampleSets::fill`] writes them.
    #[inline]
    pub(crate) fn from_columns(values: &'a [Vec2], at: usize, stride: usize) -> Self {
        let last = (values.len() / stride.max(1)).saturating_sub(1) as u32;
        LightSamples { source: Source::Columns { values, at, stride, last } }
    }

    /// The same value for every dimension (for testing a light directly).
    pub fn fixed(u: Vec2) -> Self {
        LightSamples { source: Source::Fixed(u) }
    }

    /// Sample `k` in [0, 1)², `k < DIMS`; larger `k` repeats the light's last dimension
    /// rather than reading another light's.
    #[inline(always)]
    pub fn get(&self, k: u32) -> Vec2 {
        match self.source {
            Source::Sets { sets, pixel, index, first_dim, last } => {
                sample_once(sets, pixel, index, first_dim + k.min(last))
            }
            Source::Columns { values, at, stride, last } => values[k.min(last) as usize * stride + at],
            Source::Fixed(u) => u,
        }
    }
}

/// One sample computed on demand, out of line: the renderer computes its samples ahead.
#[inline(never)]
fn sample_once(sets: &SampleSets, pixel: u32, index: u32, dim: u32) -> Vec2 {
    sets.sample(pixel, index, dim)
}

/// A light resolved to world space: what the tracer samples at every shading point.
pub trait PlacedLight: Send + Sync + 'static {
    /// 2-D sample dimensions used per shading point (0 for lights that need no random numbers).
    const DIMS: u32 = 1;
    /// The reflectance the samples feed.
    const TERM: Term = Term::Diffuse;

    /// The light arriving at `at` for the sample values `u`, or `None` when this sample
    /// contributes nothing (behind the surface, outside a cone, …): then no shadow ray is traced.
    fn sample(&self, at: &ShadingPoint, u: &LightSamples) -> Option<LightSample>;

    /// For a direction light (see [`DirectionTerms`]): the samples of a run at one shading point
    /// as structure-of-arrays into `run` (resized with [`DirectionRun::resize`] to
    /// `n = values.len() / DIMS` samples; sample `j` for the values whose dimension `k` is
    /// `values[k * n + j]`), and the terms they share. The core then sets up, traces and adds the
    /// run's shadow rays in bulk. Each sample must stand for exactly what [`PlacedLight::sample`]
    /// returns ([`DirectionRun::light_sample`]). `None` (the default): the light goes through
    /// [`PlacedLight::sample_run`].
    #[inline]
    fn sample_directions(
        &self,
        _at: &ShadingPoint,
        _values: &[Vec2],
        _run: &mut DirectionRun,
    ) -> Option<DirectionTerms> {
        None
    }

    /// `Some(terms)` when every sample is a cosine-distributed direction around the shading
    /// normal (density cos θ / π, weight 1) under `terms`, drawn from the light's first sample
    /// dimension as [`cosine_power_hemisphere`](crate::sampling::warp::cosine_power_hemisphere)
    /// with e = 1 maps it, exactly what [`PlacedLight::sample_directions`] gives: the core then
    /// draws, sets up and traces a run in one pass where the CPU and sampler allow. `None`
    /// (the default) otherwise.
    #[inline]
    fn cosine_run(&self) -> Option<DirectionTerms> {
        None
    }

    /// `Some(source)` when every sample at every shading point is exactly `source`'s
    /// [`PointSource::sample`] (the light draws no samples): the core then lights many points
    /// at once (a row's camera hits, or the jittered hits of a run) in lanes, shadow rays
    /// included, where the CPU allows.
    /// `None` (the default) otherwise.
    ///
    /// [`PointSource::sample`]: point::PointSource::sample
    #[inline]
    fn point_source(&self) -> Option<point::PointSource> {
        None
    }

    /// [`PlacedLight::sample`] for each sample of a run at one shading point: `out[j]` for the
    /// sample values whose dimension `k` is `values[k * out.len() + j]`. An implementation may
    /// compute several samples at once, but must give the same values as `sample`.
    #[inline]
    fn sample_run(&self, at: &ShadingPoint, values: &[Vec2], out: &mut [Option<LightSample>]) {
        let n = out.len();
        for (j, o) in out.iter_mut().enumerate() {
            *o = self.sample(at, &LightSamples::from_columns(values, j, n));
        }
    }
}

/// A light component. Implement it, then register the type once with
/// [`Renderer::add_light`](crate::Renderer::add_light). `Clone + PartialEq` let the renderer
/// compare a light with its previous value, so that writing an equal value every frame does
/// not restart accumulation.
pub trait Light: Component + Clone + PartialEq + Sized {
    /// The world-space form the tracer samples.
    type Placed: PlacedLight;
    /// What the light is called in statistics.
    const NAME: &'static str;

    /// A one-line description of the first unusable parameter (the frame is then refused).
    /// `transform` is the entity's, or the identity when it has none.
    fn validate(&self, transform: &Transform) -> Result<(), String>;

    /// The light placed by `transform`, or `None` when it can never contribute (e.g. zero
    /// intensity): it is then skipped entirely.
    fn place(&self, transform: &Transform) -> Option<Self::Placed>;
}
