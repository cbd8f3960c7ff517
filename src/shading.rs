//! The per-sample integrator: a primary ray, then every registered light group at the hit
//! (see [`crate::light`]). The core knows no light kinds; it applies the reflectance a light
//! names, traces the shadow rays lights ask for, and counts them.

use glam::Vec3;

use crate::{
    geometry::{Ray, SceneGeometry, SurfaceHit},
    light::{LightGroup, LightSamples, PlacedLight, ShadingPoint, Shadow, Term},
    sampling::SampleSets,
};

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays.
    pub primary: u64,
    /// Visibility rays of ambient-term lights (the ambient occluder).
    pub ao: u64,
    /// Shadow rays of all other lights.
    pub shadow: u64,
}

impl RayCounts {
    /// All rays.
    pub fn total(&self) -> u64 {
        self.primary + self.ao + self.shadow
    }

    /// Adds another count to this one.
    pub fn add(&mut self, other: &RayCounts) {
        self.primary += other.primary;
        self.ao += other.ao;
        self.shadow += other.shadow;
    }
}

/// Everything a sample needs to read, shared by all threads.
pub struct Scene<'a> {
    /// Geometry and materials.
    pub geometry: &'a SceneGeometry,
    /// Light groups with their first sample dimension, in registration order.
    pub lights: &'a [(u32, &'a dyn LightGroup)],
    /// Sample sets.
    pub sets: &'a SampleSets,
    /// Radiance of escaped primary rays.
    pub background: Vec3,
}

/// Per-thread scratch state and counters.
#[derive(Default)]
pub struct Tracer {
    stack: Vec<(u32, f32)>,
    /// Rays traced by this tracer.
    pub rays: RayCounts,
}

/// pbrt-v4's ShadowEpsilon: shadow rays to a point stop this fraction short of it.
const SHADOW_EPSILON: f32 = 1e-4;

impl Tracer {
    /// Radiance along one camera ray for sample `index` of `pixel`.
    #[inline(always)]
    pub fn radiance(&mut self, scene: &Scene, ray: &Ray, pixel: u32, index: u32) -> Vec3 {
        self.rays.primary += 1;
        let Some(hit) = scene.geometry.intersect(ray, &mut self.stack) else {
            return scene.background;
        };
        let material = scene.geometry.objects[hit.object as usize].material;
        let at = ShadingPoint { p: hit.p, normal: hit.normal, material };
        let mut l = Vec3::ZERO;
        for &(first_dim, group) in scene.lights {
            l += group.shade(self, scene, &hit, &at, pixel, index, first_dim);
        }
        l
    }

    /// Reflected radiance from `lights` (all of one type) at a hit: each light's sample,
    /// its shadow ray when it can matter, times the reflectance of the light's term.
    #[inline]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn shade_lights<P: PlacedLight>(
        &mut self,
        scene: &Scene,
        hit: &SurfaceHit,
        at: &ShadingPoint,
        lights: &[P],
        pixel: u32,
        index: u32,
        first_dim: u32,
    ) -> Vec3 {
        let reflectance = P::TERM.reflectance(&at.material);
        if reflectance.max_element() <= 0.0 {
            return Vec3::ZERO;
        }
        let mut sum = Vec3::ZERO;
        let mut dim = first_dim;
        for light in lights {
            let u = LightSamples::from_sets(scene.sets, pixel, index, dim, P::DIMS);
            dim += P::DIMS;
            let Some(s) = light.sample(at, &u) else { continue };
            sum += match s.shadow {
                // A shadow ray only when its answer changes the result.
                Some(shadow) if s.unoccluded != s.occluded => {
                    if self.blocked(scene, hit, shadow, P::TERM) {
                        s.occluded
                    } else {
                        s.unoccluded
                    }
                }
                _ => s.unoccluded,
            };
        }
        reflectance * sum
    }

    /// Traces a shadow segment from the hit, counted by the light's term; true if blocked.
    #[inline]
    fn blocked(&mut self, scene: &Scene, hit: &SurfaceHit, shadow: Shadow, term: Term) -> bool {
        let ray = match shadow {
            Shadow::ToPoint(q) => {
                let origin = hit.spawn_origin(q - hit.p);
                Ray::new(origin, q - origin, 1.0 - SHADOW_EPSILON)
            }
            Shadow::Along { dir, max_distance } => Ray::new(hit.spawn_origin(dir), dir, max_distance),
        };
        match term {
            Term::Ambient => self.rays.ao += 1,
            Term::Diffuse => self.rays.shadow += 1,
        }
        scene.geometry.occluded(&ray, &mut self.stack)
    }
}
