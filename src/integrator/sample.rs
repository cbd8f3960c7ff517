//! What a camera sample yields: its radiance and AOVs ([`SampleResult`]), or the radiance
//! alone, written through one interface ([`SampleOut`]) so the tracer serves both.

use glam::{Vec3, Vec3A};

use crate::{
    components::Matte,
    geometry::{Ray, SurfaceHit},
    light::Term,
    resources::AovValues,
};

/// What one camera sample saw, for the beauty image and the AOVs.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SampleResult {
    /// Radiance (the beauty image).
    pub radiance: Vec3,
    /// Ambient light arriving (channel mean of Σ occluders' `ls·color·(min + (1 − min)·V·w)`):
    /// for one white unit occluder with `min_amount` 0 the raw AO estimate of (1/π)∫V cos θ dω.
    pub ao: f32,
    /// Reflected radiance of the diffuse-term lights (point, spot, directional, disk, …).
    pub direct: Vec3,
    /// The material's `cd`.
    pub albedo: Vec3,
    /// Unit geometric normal facing the camera.
    pub normal: Vec3,
    /// Distance from the camera ray's origin to the hit.
    pub depth: f32,
    /// Whether the camera ray hit anything (AOVs are 0 where it did not).
    pub hit: bool,
}

impl SampleResult {
    /// A sample at a camera hit on `material`, before any light.
    #[inline]
    pub(crate) fn at_hit(primary: &PrimaryHit, material: &Matte) -> Self {
        SampleResult {
            albedo: material.cd,
            normal: primary.hit.normal.into(),
            depth: primary.depth,
            hit: true,
            ..Default::default()
        }
    }

    /// Adds light `a` arriving from a light of `term`, reflected by `reflectance`.
    #[inline]
    pub(crate) fn add_light(&mut self, term: Term, reflectance: Vec3, a: Vec3) {
        let reflected = reflectance * a;
        self.radiance += reflected;
        match term {
            Term::Ambient => self.ao += a.element_sum() / 3.0,
            Term::Diffuse => self.direct += reflected,
        }
    }

    /// The AOVs in the [`AovValues`] layout.
    #[inline]
    pub fn aov_values(&self) -> AovValues {
        let (d, a, n) = (self.direct, self.albedo, self.normal);
        [self.ao, d.x, d.y, d.z, a.x, a.y, a.z, n.x, n.y, n.z, self.depth, f32::from(u8::from(self.hit))]
    }

    /// The radiance and AOV sums of `count` samples at one hit, each this result (the hit and
    /// the light of the lights that draw no samples) plus its share of `run`, the light of the
    /// lights that draw samples summed over the run.
    #[inline]
    pub fn with_run(&self, run: &ShadedSum, count: u32) -> (Vec3A, AovValues) {
        let n = count as f32;
        let mut values = self.aov_values().map(|v| v * n);
        values[0] += run.ao;
        for (v, d) in values[1..4].iter_mut().zip(run.direct.to_array()) {
            *v += d;
        }
        (run.radiance + Vec3A::from(self.radiance) * n, values)
    }
}

/// The parts of [`SampleResult`] that vary from sample to sample, summed over a run of samples
/// at one hit ([`Tracer::shade_sum`](super::Tracer::shade_sum)).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ShadedSum {
    /// Radiance.
    pub radiance: Vec3A,
    /// Ambient light arriving, as [`SampleResult::ao`].
    pub ao: f32,
    /// Reflected radiance of the diffuse-term lights.
    pub direct: Vec3A,
    /// Each sample's radiance, where the run's takes at most two values (one light's counted
    /// run, every other light the same for every sample): what adaptive sampling needs of the
    /// samples without making them.
    pub values: Option<TwoValues>,
}

/// A value over a run of samples that takes one of two: `clear` for all but `dark` of them,
/// `floor` for those (a cosine run that counts its blocked rays).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TwoValues {
    /// The value of the samples that are not dark.
    pub clear: Vec3A,
    /// The value of the dark samples.
    pub floor: Vec3A,
    /// How many samples are dark.
    pub dark: u32,
}

impl TwoValues {
    /// The one value of a run of `samples` where every sample has it.
    fn only(&self, samples: u32) -> Option<Vec3A> {
        if self.dark == 0 || self.clear == self.floor {
            Some(self.clear)
        } else if self.dark == samples {
            Some(self.floor)
        } else {
            None
        }
    }

    /// Each sample's value plus its value in `other` (the same run of `samples`), where that
    /// sum takes at most two values too: one of the two is the same for every sample. `None`
    /// where both vary, for which samples are dark in one and in the other is not known.
    pub fn plus(&self, other: &TwoValues, samples: u32) -> Option<TwoValues> {
        if let Some(v) = other.only(samples) {
            Some(TwoValues { clear: self.clear + v, floor: self.floor + v, dark: self.dark })
        } else {
            let v = self.only(samples)?;
            Some(TwoValues { clear: v + other.clear, floor: v + other.floor, dark: other.dark })
        }
    }

    /// Both values multiplied by `by`.
    pub fn scaled(&self, by: Vec3A) -> TwoValues {
        TwoValues { clear: self.clear * by, floor: self.floor * by, ..*self }
    }

    /// The values' sum over a run of `samples`.
    pub fn sum(&self, samples: u32) -> Vec3A {
        // Whole numbers of samples (at most 2²⁴): exact as floats.
        self.clear * (samples - self.dark) as f32 + self.floor * self.dark as f32
    }

    /// The sum over a run of `samples` of `f(value)`'s squared deviations from its mean.
    pub fn squared_deviations(&self, samples: u32, f: impl Fn(Vec3A) -> f32) -> f64 {
        if self.dark == 0 || self.dark == samples {
            return 0.0;
        }
        let (clear, dark) = ((samples - self.dark) as f64, self.dark as f64);
        clear * dark / samples as f64 * (f(self.clear) as f64 - f(self.floor) as f64).powi(2)
    }
}

/// What [`Tracer::shade`](super::Tracer::shade) keeps of each of a run of samples at one hit: everything
/// ([`SampleResult`], for AOVs) or the radiance alone (`Vec3A`, for the beauty image).
pub trait SampleOut {
    /// Samples in the run.
    fn len(&self) -> usize;
    /// Whether the run is empty.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Sets every sample to a camera hit on `material`, before any light.
    fn start(&mut self, primary: &PrimaryHit, material: &Matte);
    /// Adds light `arriving[j]` from a light of `term`, reflected by `reflectance`, to sample `j`.
    fn add_light(&mut self, term: Term, reflectance: Vec3, arriving: &[Vec3A]);
}

impl<O: OwnSample> SampleOut for [O] {
    fn len(&self) -> usize {
        self.len()
    }

    #[inline]
    fn start(&mut self, primary: &PrimaryHit, material: &Matte) {
        self.fill(O::at_hit(primary, material));
    }

    #[inline]
    fn add_light(&mut self, term: Term, reflectance: Vec3, arriving: &[Vec3A]) {
        for (o, &a) in self.iter_mut().zip(arriving) {
            o.add_light(term, reflectance, a);
        }
    }
}

/// What a sample keeps, in a run at one hit ([`SampleOut`]) or at a camera hit of its own
/// ([`Tracer::shade_runs`](super::Tracer::shade_runs)): everything ([`SampleResult`], for
/// AOVs) or the radiance alone (`Vec3A`, for the beauty image), each with the same radiance
/// bit for bit.
pub trait OwnSample: Copy {
    /// A sample whose camera ray escaped, seeing `background`.
    fn missed(background: Vec3) -> Self;
    /// A sample at a camera hit on `material`, before any light.
    fn at_hit(primary: &PrimaryHit, material: &Matte) -> Self;
    /// Adds light `a` arriving from a light of `term`, reflected by `reflectance`.
    fn add_light(&mut self, term: Term, reflectance: Vec3, a: Vec3A);
}

impl OwnSample for SampleResult {
    #[inline(always)]
    fn missed(background: Vec3) -> Self {
        SampleResult { radiance: background, ..Default::default() }
    }

    #[inline(always)]
    fn at_hit(primary: &PrimaryHit, material: &Matte) -> Self {
        SampleResult::at_hit(primary, material)
    }

    #[inline(always)]
    fn add_light(&mut self, term: Term, reflectance: Vec3, a: Vec3A) {
        SampleResult::add_light(self, term, reflectance, a.into());
    }
}

impl OwnSample for Vec3A {
    #[inline(always)]
    fn missed(background: Vec3) -> Self {
        background.into()
    }

    #[inline(always)]
    fn at_hit(_: &PrimaryHit, _: &Matte) -> Self {
        Vec3A::ZERO
    }

    /// `SampleResult::add_light`'s radiance, in one SIMD operation per step (same bits).
    #[inline(always)]
    fn add_light(&mut self, _: Term, reflectance: Vec3, a: Vec3A) {
        *self += Vec3A::from(reflectance) * a;
    }
}

/// A camera ray's first hit.
#[derive(Clone, Copy, Debug)]
pub struct PrimaryHit {
    /// The surface hit.
    pub hit: SurfaceHit,
    /// Distance from the ray's origin.
    pub depth: f32,
}

impl PrimaryHit {
    /// The hit `hit` of camera ray `ray`, at the distance it travelled.
    #[inline]
    pub fn along(ray: &Ray, hit: SurfaceHit) -> Self {
        PrimaryHit { hit, depth: hit.t * ray.dir.length() }
    }
}
