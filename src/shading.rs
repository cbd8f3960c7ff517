//! The per-sample integrator: ambient occlusion (Suffern ch. 17, made unbiased for any
//! cosine exponent) plus Lambertian direct light from point lights with shadow rays.

use std::f32::consts::FRAC_1_PI;

use glam::{Vec3, Vec3A};

use crate::{
    components::{AmbientOccluder, Matte, PointLight},
    geometry::{Ray, SceneGeometry, SurfaceHit},
    math::Onb,
    sampling::{SampleSets, dims, warp::cosine_power_hemisphere},
};

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays.
    pub primary: u64,
    /// Ambient-occlusion visibility rays.
    pub ao: u64,
    /// Point-light shadow rays.
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

/// A point light resolved to world space.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Position.
    pub position: Vec3A,
    /// `ls · color`.
    pub intensity: Vec3,
    /// Trace shadow rays.
    pub shadows: bool,
    /// Apply 1/d².
    pub falloff: bool,
}

impl LightSample {
    /// The light at `position`; `None` when it can never contribute (zero intensity).
    pub fn new(light: &PointLight, position: Vec3) -> Option<Self> {
        let intensity = light.color * light.ls;
        (intensity.max_element() > 0.0).then_some(LightSample {
            position: position.into(),
            intensity,
            shadows: light.shadows,
            falloff: light.falloff,
        })
    }
}

/// Everything a sample needs to read, shared by all threads.
pub struct Scene<'a> {
    /// Geometry and materials.
    pub geometry: &'a SceneGeometry,
    /// Active ambient occluders (empty: no AO rays at all).
    pub occluders: &'a [AmbientOccluder],
    /// Lights that can contribute.
    pub lights: &'a [LightSample],
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

/// pbrt-v4's ShadowEpsilon: shadow rays to a light stop this fraction short of it.
const SHADOW_EPSILON: f32 = 1e-4;

impl Tracer {
    /// Radiance along one camera ray for sample `index` of `pixel`.
    #[inline]
    pub fn radiance(&mut self, scene: &Scene, ray: &Ray, pixel: u32, index: u32) -> Vec3 {
        self.rays.primary += 1;
        let Some(hit) = scene.geometry.intersect(ray, &mut self.stack) else {
            return scene.background;
        };
        let material = scene.geometry.objects[hit.object as usize].material;
        let mut l = Vec3::ZERO;
        for (k, occluder) in scene.occluders.iter().enumerate() {
            l += self.ambient(scene, occluder, &hit, &material, pixel, index, dims::AO + k as u32);
        }
        for light in scene.lights {
            l += self.direct(scene, light, &hit, &material);
        }
        l
    }

    /// Ambient occluder term for one sample: ka·cd·ls·c·(min + (1 − min)·V·w).
    #[inline]
    #[allow(clippy::too_many_arguments)]
    fn ambient(
        &mut self,
        scene: &Scene,
        occ: &AmbientOccluder,
        hit: &SurfaceHit,
        m: &Matte,
        pixel: u32,
        index: u32,
        dim: u32,
    ) -> Vec3 {
        let scale = m.cd * (m.ka * occ.ls) * occ.color;
        if scale.max_element() <= 0.0 {
            return Vec3::ZERO;
        }
        let s = cosine_power_hemisphere(scene.sets.sample(pixel, index, dim), occ.exponent);
        let mut visible = 0.0;
        if s.weight > 0.0 {
            let w = Onb::from_normal(hit.normal.into()).to_world(s.dir);
            let w = Vec3A::from(w);
            let ray = Ray::new(hit.spawn_origin(w), w, occ.max_distance);
            self.rays.ao += 1;
            if !scene.geometry.occluded(&ray, &mut self.stack) {
                visible = s.weight;
            }
        }
        scale * (occ.min_amount + (1.0 - occ.min_amount) * visible)
    }

    /// Lambertian direct light from one point light, with its shadow ray when it can matter.
    #[inline]
    fn direct(&mut self, scene: &Scene, light: &LightSample, hit: &SurfaceHit, m: &Matte) -> Vec3 {
        let to_light = light.position - hit.p;
        let dist2 = to_light.length_squared();
        let cos = hit.normal.dot(to_light);
        if cos <= 0.0 || dist2 == 0.0 || m.kd <= 0.0 {
            return Vec3::ZERO;
        }
        let cos = cos / dist2.sqrt();
        if light.shadows {
            let origin = hit.spawn_origin(to_light);
            let ray = Ray::new(origin, light.position - origin, 1.0 - SHADOW_EPSILON);
            self.rays.shadow += 1;
            if scene.geometry.occluded(&ray, &mut self.stack) {
                return Vec3::ZERO;
            }
        }
        let e = light.intensity * if light.falloff { cos / dist2 } else { cos };
        m.cd * (m.kd * FRAC_1_PI) * e
    }
}
