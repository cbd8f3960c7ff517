//! The light extension point and the lights built on it, checked against analytic truth:
//! directional E = L·cos θ, glTF spot cone attenuation, disk irradiance on its axis
//! E = L·π·R²/(R² + h²) and its penumbra, a light registered from outside, skipped work,
//! change detection and validation.

mod common;

use std::f32::consts::{FRAC_PI_2, PI};

use common::{occluder, settings, white};
use hemi::{bevy_ecs::bundle::Bundle, camera::PinholeRays, integrator::register_light, prelude::*, resources::Aov};

/// Floor point hit by a camera ray (the floor is y = 0).
fn floor_hit(cam: &PinholeRays, x: u32, y: u32, u: Vec2) -> Vec3 {
    let ray = cam.ray(x, y, u);
    let t = -ray.origin.y / ray.dir.y;
    (ray.origin + ray.dir * t).into()
}

/// Mean of `f` over a pixel's footprint on the floor (n × n sub-pixel grid).
fn pixel_mean(cam: &PinholeRays, x: u32, y: u32, n: u32, f: impl Fn(Vec3) -> f64) -> f64 {
    let mut sum = 0.0;
    for j in 0..n {
        for i in 0..n {
            let u = Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32);
            sum += f(floor_hit(cam, x, y, u));
        }
    }
    sum / (n * n) as f64
}

/// A white floor, a camera looking down at it, and one light.
fn floor_with(light: impl Bundle, camera: Camera, width: u32, height: u32, spp: u32, kind: SamplerKind) -> Renderer {
    let mut r = Renderer::new(settings(width, height, spp, kind));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn(light);
    w.spawn(camera);
    r.run_frame().expect("scene is valid");
    r
}

/// A camera at `eye` looking straight down.
fn looking_down(eye: Vec3, vfov_degrees: f32) -> Camera {
    Camera { eye, target: eye - Vec3::Y, up: Vec3::NEG_Z, vfov_degrees }
}

#[test]
fn directional_light_gives_l_cos_theta_on_a_plane() {
    for (angle, ls) in [(0.0f32, 2.0f32), (0.7, 3.0), (1.3, 1.5)] {
        // Shining down, tilted by `angle` from the floor normal.
        let dir = Vec3::new(angle.sin(), -angle.cos(), 0.0);
        let light = (DirectionalLight { ls, ..Default::default() }, Transform::default().facing(dir));
        let cam = Camera::look_at(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO, 50.0);
        let r = floor_with(light, cam, 12, 8, 2, SamplerKind::Jittered);
        let expected = ls * angle.cos() / PI;
        for p in &r.image().linear {
            assert!((p.x - expected).abs() <= 1e-6 * expected, "angle {angle}: {p} vs {expected}");
        }
        assert_eq!(r.stats().rays.shadow, r.stats().rays.primary, "one shadow ray per lit point");
    }
    // From below the floor: nothing, and no shadow rays.
    let light = (DirectionalLight::default(), Transform::default().facing(Vec3::Y));
    let r = floor_with(light, looking_down(Vec3::Y, 30.0), 8, 8, 1, SamplerKind::Jittered);
    assert!(r.image().linear.iter().all(|p| *p == Vec3::ZERO));
    assert_eq!(r.stats().rays.shadow, 0);
}

#[test]
fn directional_light_casts_a_sharp_shadow() {
    // Sun straight down over a sphere: the floor point below its centre is dark.
    let mut r = Renderer::new(settings(8, 8, 4, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn((Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 2.0, 0.0), white()));
    w.spawn((DirectionalLight::default(), Transform::default().facing(Vec3::NEG_Y)));
    w.spawn(looking_down(Vec3::Y, 10.0));
    r.run_frame().unwrap();
    assert!(r.image().linear.iter().all(|p| *p == Vec3::ZERO), "light leaked into the umbra");
}

/// The glTF reference attenuation, written out independently of hemi's.
fn gltf_spot(inner: f32, outer: f32, cos_axis: f64) -> f64 {
    let scale = 1.0 / (inner.cos() as f64 - outer.cos() as f64).max(0.001);
    let offset = -(outer.cos() as f64) * scale;
    (cos_axis * scale + offset).clamp(0.0, 1.0).powi(2)
}

#[test]
fn spot_light_follows_the_gltf_cone() {
    let (intensity, h, inner, outer) = (20.0f32, 2.0f32, 0.35f32, 0.7f32);
    let (width, height) = (40, 30);
    let camera = Camera { eye: Vec3::new(0.0, 5.0, 0.01), target: Vec3::ZERO, up: Vec3::NEG_Z, vfov_degrees: 50.0 };
    let spot = SpotLight { ls: intensity, inner_cone_angle: inner, outer_cone_angle: outer, ..Default::default() };
    let light = (spot, Transform::from_xyz(0.0, h, 0.0).facing(Vec3::NEG_Y));
    let r = floor_with(light, camera, width, height, 16, SamplerKind::Regular);
    let cam = PinholeRays::new(&camera, width, height).unwrap();
    let h = h as f64;
    let radiance = |p: Vec3| {
        let d2 = h * h + (p.x as f64).powi(2) + (p.z as f64).powi(2);
        let cos = h / d2.sqrt();
        intensity as f64 * gltf_spot(inner, outer, cos) * cos / d2 / std::f64::consts::PI
    };
    let within = |p: Vec3| p.x.hypot(p.z) as f64 / h;
    let (mut inside, mut between, mut outside) = (0, 0, 0);
    for y in 0..height {
        for x in 0..width {
            let expected = pixel_mean(&cam, x, y, 4, radiance);
            let got = r.image().pixel(x, y).x as f64;
            assert!((got - expected).abs() <= 1e-4 * expected + 1e-7, "pixel ({x},{y}): {got} vs {expected}");
            // Classify by the pixel footprint's corners (tan of the angle from the axis).
            let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)]
                .map(|(i, j)| within(floor_hit(&cam, x, y, Vec2::new(i, j))));
            let (lo, hi) = corners.iter().fold((f64::MAX, 0.0f64), |(lo, hi), &t| (lo.min(t), hi.max(t)));
            if hi < (inner as f64).tan() {
                inside += 1;
                let point = pixel_mean(&cam, x, y, 4, |p| {
                    let d2 = h * h + (p.x as f64).powi(2) + (p.z as f64).powi(2);
                    intensity as f64 * h / d2.powf(1.5) / std::f64::consts::PI
                });
                assert!((got - point).abs() <= 1e-4 * point, "inside the inner cone the spot is a point light");
            } else if lo > (outer as f64).tan() {
                outside += 1;
                assert_eq!(got, 0.0, "pixel ({x},{y}) is outside the outer cone");
            } else if got > 0.0 {
                between += 1;
            }
        }
    }
    assert!(inside > 20 && between > 100 && outside > 100, "{inside} / {between} / {outside}");
    // Only points inside the outer cone cost a shadow ray.
    let stats = r.stats();
    assert!(stats.rays.shadow < stats.rays.primary / 2, "{} shadow rays", stats.rays.shadow);
}

#[test]
fn spot_attenuation_is_full_inside_zero_outside_and_smooth_between() {
    let spot = SpotLight { inner_cone_angle: 0.2, outer_cone_angle: 0.6, ..Default::default() };
    let placed = spot.place(&Transform::default().facing(Vec3::NEG_Y)).unwrap();
    let at_angle = |a: f32| {
        // A floor point at angle `a` from the axis, at distance 1 from the light at the origin.
        let p = Vec3::new(a.sin(), -a.cos(), 0.0);
        let at = ShadingPoint::new(p.into(), (-p).into(), white());
        placed.sample(&at, &LightSamples::fixed(Vec2::ZERO)).map_or(0.0, |s| s.unoccluded.x)
    };
    assert!((at_angle(0.0) - 1.0).abs() < 1e-6);
    assert!((at_angle(0.19) - 1.0).abs() < 1e-6);
    assert_eq!(at_angle(0.61), 0.0);
    assert!(spot.place(&Transform::default().facing(Vec3::NEG_Y)).is_some());
    let mut previous = 1.0;
    for k in 1..100 {
        let a = 0.2 + 0.4 * k as f32 / 100.0;
        let v = at_angle(a);
        assert!(v < previous && v > 0.0, "not decreasing at {a}");
        assert!(previous - v < 0.05, "jump at {a}: {previous} → {v}");
        assert!((v as f64 - gltf_spot(0.2, 0.6, a.cos() as f64)).abs() < 1e-5);
        previous = v;
    }
    assert_eq!(spot.attenuation(0.6f32.cos() - 1e-3), 0.0);
}

/// Disk of radiance L, radius R at height h facing a white floor: on the axis
/// E = L·π·R²/(R² + h²). One sample is f = L·π·R²·h²/(h² + s)² with s = r² uniform on [0, R²],
/// whose variance is known exactly; the mean of N samples must be within 4σ/√N.
#[test]
fn disk_light_on_its_axis_gives_the_analytic_irradiance() {
    for (l, radius, h) in [(3.0f64, 0.5f64, 2.0f64), (1.0, 2.0, 1.0), (0.5, 1.0, 0.25)] {
        let disk = DiskLight { ls: l as f32, radius: radius as f32, ..Default::default() };
        let light = (disk, Transform::from_xyz(0.0, h as f32, 0.0).facing(Vec3::NEG_Y));
        let spp = 1024;
        let r = floor_with(light, looking_down(Vec3::new(0.0, 0.01, 0.0), 0.01), 4, 4, spp, SamplerKind::MultiJittered);
        let img = r.image();
        let mean = img.linear.iter().map(|p| p.x as f64).sum::<f64>() / img.linear.len() as f64 * PI as f64;
        let (r2, h2) = (radius * radius, h * h);
        let expected = l * std::f64::consts::PI * r2 / (r2 + h2);
        let k = l * std::f64::consts::PI * r2 * h2;
        let second = k * k / r2 / 3.0 * (h2.powi(-3) - (h2 + r2).powi(-3));
        let sigma = (second - expected * expected).sqrt();
        let n = (img.linear.len() * spp as usize) as f64;
        assert!(
            (mean - expected).abs() < 4.0 * sigma / n.sqrt(),
            "L={l} R={radius} h={h}: E = {mean} vs {expected} (σ/√N = {})",
            sigma / n.sqrt()
        );
    }
}

/// The visible part of a disk (radius R at height h, facing down, centre above the origin)
/// seen from floor point `p` when everything with x below `cut(p)` on the disk is hidden:
/// E and the second moment of the one-sample estimator, by polar quadrature.
fn disk_quadrature(l: f64, radius: f64, h: f64, p: Vec3, cut: f64) -> (f64, f64) {
    let (nr, nphi) = (64, 128);
    let area = std::f64::consts::PI * radius * radius;
    let (mut e, mut second) = (0.0, 0.0);
    for i in 0..nr {
        let r = (i as f64 + 0.5) / nr as f64 * radius;
        for j in 0..nphi {
            let phi = (j as f64 + 0.5) / nphi as f64 * 2.0 * std::f64::consts::PI;
            let (qx, qz) = (r * phi.cos(), r * phi.sin());
            if qx < cut {
                continue;
            }
            let d2 = (qx - p.x as f64).powi(2) + h * h + (qz - p.z as f64).powi(2);
            let g = l * h * h / (d2 * d2);
            let da = r * (radius / nr as f64) * (2.0 * std::f64::consts::PI / nphi as f64);
            e += g * da;
            second += area * g * g * da;
        }
    }
    (e, second)
}

/// Off-axis irradiance from a whole disk onto a parallel facing plane (configuration factor):
/// E = (L·π/2)·(1 − (h² + a² − R²)/√((h² + a² + R²)² − 4a²R²)), a = distance from the axis.
fn disk_off_axis(l: f64, radius: f64, h: f64, a: f64) -> f64 {
    let (r2, h2, a2) = (radius * radius, h * h, a * a);
    l * std::f64::consts::PI / 2.0 * (1.0 - (h2 + a2 - r2) / ((h2 + a2 + r2).powi(2) - 4.0 * a2 * r2).sqrt())
}

/// A half-infinite opaque sheet at height b covers x < 0 between a disk light (height h) and
/// the floor. Floor point x sees the disk where q.x ≥ −x(h − b)/b: umbra for x ≤ −R·b/(h − b),
/// fully lit for x ≥ R·b/(h − b), a penumbra between. Every pixel is checked against the
/// quadrature of the visible part within 5σ (σ from the same quadrature), the lit side
/// against the closed form, the umbra is exactly 0, and the penumbra rises steadily.
#[test]
fn disk_light_penumbra_matches_the_visible_fraction_of_the_disk() {
    let (l, radius, h, b) = (4.0f64, 0.5f64, 2.0f64, 1.0f64);
    let (width, height, spp) = (40u32, 2u32, 512u32);
    // From below the sheet, looking down at x ∈ [−1, 1]: 0.05 per pixel.
    let camera = looking_down(Vec3::new(0.0, 0.5, 0.0), 2.0 * 0.1f32.atan().to_degrees());
    let mut r = Renderer::new(settings(width, height, spp, SamplerKind::MultiJittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn((Cuboid { half_extents: Vec3::new(50.0, 1e-3, 50.0) }, Transform::from_xyz(-50.0, b as f32, 0.0)));
    let disk = DiskLight { ls: l as f32, radius: radius as f32, ..Default::default() };
    w.spawn((disk, Transform::from_xyz(0.0, h as f32, 0.0).facing(Vec3::NEG_Y)));
    w.spawn(camera);
    r.run_frame().unwrap();
    let cam = PinholeRays::new(&camera, width, height).unwrap();
    let half_width = radius * b / (h - b);
    let pi = std::f64::consts::PI;
    let (mut z_sum, mut n) = (0.0, 0);
    for y in 0..height {
        let mut row = Vec::new();
        for x in 0..width {
            let got = r.image().pixel(x, y).x as f64 * pi;
            let e = pixel_mean(&cam, x, y, 3, |p| disk_quadrature(l, radius, h, p, -p.x as f64 * (h - b) / b).0);
            let second = pixel_mean(&cam, x, y, 3, |p| disk_quadrature(l, radius, h, p, -p.x as f64 * (h - b) / b).1);
            let sigma = (second - e * e).max(0.0).sqrt() / (spp as f64).sqrt() + 1e-5;
            let z = (got - e) / sigma;
            assert!(z.abs() < 5.0, "pixel ({x},{y}): E {got} vs {e} (z = {z:.1})");
            z_sum += z;
            n += 1;
            let x0 = floor_hit(&cam, x, y, Vec2::ZERO).x as f64;
            let x1 = floor_hit(&cam, x, y, Vec2::ONE).x as f64;
            if x1 < -half_width {
                assert_eq!(got, 0.0, "pixel ({x},{y}) is in the umbra");
            } else if x0 > half_width {
                let full = pixel_mean(&cam, x, y, 3, |p| disk_off_axis(l, radius, h, p.x.hypot(p.z) as f64));
                assert!((e - full).abs() < 1e-3 * full, "quadrature {e} vs closed form {full}");
            } else if x0 > -half_width + 0.2 && x1 < half_width {
                // Four pixels (a fifth of the penumbra) apart the light has clearly grown.
                assert!(got > 0.0 && got > row[x as usize - 4], "penumbra does not rise at pixel ({x},{y})");
            }
            row.push(got);
        }
    }
    let mean_z = z_sum / n as f64;
    assert!(mean_z.abs() < 5.0 / (n as f64).sqrt(), "mean z-score {mean_z}: biased");
}

#[test]
fn lights_facing_away_cost_no_shadow_rays() {
    let cam = looking_down(Vec3::new(0.0, 3.0, 0.0), 60.0);
    let spot_up = (SpotLight::default(), Transform::from_xyz(0.0, 1.0, 0.0).facing(Vec3::Y));
    let disk_up = (DiskLight::default(), Transform::from_xyz(0.0, 1.0, 0.0).facing(Vec3::Y));
    let dark_disk = (DiskLight { ls: 0.0, ..Default::default() }, Transform::from_xyz(0.0, 1.0, 0.0));
    let r = floor_with(spot_up, cam, 8, 8, 2, SamplerKind::Jittered);
    assert_eq!(r.stats().rays.shadow, 0);
    let r = floor_with(disk_up, cam, 8, 8, 2, SamplerKind::Jittered);
    assert_eq!(r.stats().rays.shadow, 0);
    let r = floor_with(dark_disk, cam, 8, 8, 2, SamplerKind::Jittered);
    assert_eq!(r.stats().rays.shadow, 0);
    // An occluder with min_amount 1 needs no AO rays: occlusion cannot change the result.
    let r = floor_with(AmbientOccluder { min_amount: 1.0, ..Default::default() }, cam, 8, 8, 2, SamplerKind::Jittered);
    assert_eq!(r.stats().rays.ao, 0);
    assert!(r.image().linear.iter().all(|p| *p == Vec3::ONE));
}

/// A uniform sky dome of radiance L, defined here like any user light: cosine-sampled, so
/// every sample of an open floor is exactly π·L and the floor's radiance is exactly L.
#[derive(Component, Clone, Copy, PartialEq)]
struct Dome {
    radiance: f32,
}

impl Light for Dome {
    type Placed = Dome;
    const NAME: &'static str = "dome";

    fn validate(&self, _: &Transform) -> Result<(), String> {
        if self.radiance >= 0.0 { Ok(()) } else { Err(format!("dome radiance {} is negative", self.radiance)) }
    }

    fn place(&self, _: &Transform) -> Option<Dome> {
        (self.radiance > 0.0).then_some(*self)
    }
}

impl PlacedLight for Dome {
    fn sample(&self, at: &ShadingPoint, u: &LightSamples) -> Option<LightSample> {
        let s = hemi::sampling::warp::cosine_power_hemisphere(u.get(0), 1.0);
        let dir = hemi::math::Onb::from_normal(at.normal.into()).to_world(s.dir);
        Some(LightSample {
            unoccluded: Vec3::splat(PI * self.radiance),
            occluded: Vec3::ZERO,
            shadow: Some(Shadow::Along { dir: dir.into(), max_distance: f32::INFINITY }),
        })
    }
}

#[test]
fn a_light_defined_outside_hemi_renders_changes_and_validates() {
    let mut r = Renderer::new(settings(8, 8, 4, SamplerKind::Jittered));
    r.add_light::<Dome>();
    assert!(!register_light::<Dome>(r.world_mut(), &mut Default::default()), "registered once");
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    let dome = w.spawn(Dome { radiance: 0.5 }).id();
    w.spawn(looking_down(Vec3::Y, 40.0));
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.rays.shadow, stats.rays.primary);
    assert!(stats.systems.iter().any(|s| s.name == "trace" && s.note.contains("1 dome")), "{:?}", stats.systems);
    assert!(r.image().linear.iter().all(|p| (*p - Vec3::splat(0.5)).abs().max_element() < 1e-6));
    r.run_frame().unwrap();
    assert_eq!(r.spp(), 8);
    // Changing the light restarts accumulation; a bad value is refused; despawning resets.
    r.world_mut().get_mut::<Dome>(dome).unwrap().radiance = 1.0;
    r.run_frame().unwrap();
    assert_eq!(r.spp(), 4);
    assert!(r.image().linear.iter().all(|p| (*p - Vec3::ONE).abs().max_element() < 1e-6));
    r.world_mut().get_mut::<Dome>(dome).unwrap().radiance = -1.0;
    let e = r.run_frame().unwrap_err().to_string();
    assert!(e.contains("dome radiance -1 is negative"), "{e}");
    r.world_mut().despawn(dome);
    r.run_frame().unwrap();
    assert_eq!(r.spp(), 4);
    assert!(r.image().linear.iter().all(|p| *p == Vec3::ZERO));
}

#[test]
fn unregistered_light_components_are_ignored() {
    let mut r = Renderer::new(settings(4, 4, 1, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn(Dome { radiance: 1.0 });
    w.spawn(looking_down(Vec3::Y, 40.0));
    assert_eq!(r.run_frame().unwrap().rays.shadow, 0);
}

#[test]
fn moving_or_removing_a_new_light_restarts_accumulation() {
    let mut r = Renderer::new(settings(8, 8, 2, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    let spot = w
        .spawn((SpotLight { ls: 5.0, ..Default::default() }, Transform::from_xyz(0.0, 2.0, 0.0).facing(Vec3::NEG_Y)))
        .id();
    let disk = w.spawn((DiskLight::default(), Transform::from_xyz(1.0, 2.0, 0.0).facing(Vec3::NEG_Y))).id();
    w.spawn(looking_down(Vec3::new(0.0, 3.0, 0.0), 60.0));
    r.run_frame().unwrap();
    r.run_frame().unwrap();
    assert_eq!(r.spp(), 4);
    let before = r.image().clone();
    r.world_mut().get_mut::<Transform>(spot).unwrap().translation.x += 0.5;
    let stats = r.run_frame().unwrap();
    assert!(!stats.bvh_built);
    assert_eq!(r.spp(), 2);
    assert_ne!(r.image(), &before);
    r.run_frame().unwrap();
    r.world_mut().entity_mut(disk).remove::<DiskLight>();
    r.run_frame().unwrap();
    assert_eq!(r.spp(), 2);
}

/// Spawns `bundle` into a valid scene and expects the frame to be refused with `expected`.
fn assert_refused(bundle: impl Bundle, expected: &str) {
    let mut r = Renderer::new(settings(4, 4, 1, SamplerKind::Jittered));
    r.world_mut().spawn(Camera::look_at(Vec3::ONE, Vec3::ZERO, 40.0));
    r.world_mut().spawn(occluder(0.0));
    r.world_mut().spawn(bundle);
    let e = r.run_frame().expect_err("refused").to_string();
    assert!(e.contains(expected) && !e.contains('\n'), "expected '{expected}' in: {e}");
    assert_eq!(r.stats().rays.total(), 0);
}

#[test]
fn bad_new_lights_are_refused_with_one_line() {
    assert_refused(SpotLight { inner_cone_angle: 0.8, outer_cone_angle: 0.5, ..Default::default() }, "cone angles");
    assert_refused(SpotLight { outer_cone_angle: 2.0, ..Default::default() }, "cone angles");
    assert_refused(SpotLight { ls: f32::NAN, ..Default::default() }, "spot light ls");
    assert_refused(DiskLight { radius: 0.0, ..Default::default() }, "disk light radius");
    assert_refused((DiskLight::default(), Transform::default().facing(Vec3::ZERO)), "disk light rotation");
    assert_refused(DirectionalLight { color: Vec3::NEG_ONE, ..Default::default() }, "directional light");
    let degenerate = Transform::default().with_rotation(Quat::from_xyzw(0.0, 0.0, 0.0, 0.0));
    assert_refused((DirectionalLight::default(), degenerate), "no direction");
}

#[test]
fn new_lights_are_bit_identical_with_one_or_two_threads() {
    let scene = |threads| {
        let mut r = Renderer::new(settings(24, 16, 4, SamplerKind::MultiJittered)).with_threads(threads).unwrap();
        let w = r.world_mut();
        w.spawn((Plane::default(), white()));
        w.spawn((Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 0.5, 0.0), white()));
        w.spawn((DiskLight::default(), Transform::from_xyz(0.5, 3.0, 0.0).facing(Vec3::NEG_Y)));
        w.spawn((
            DiskLight { radius: 0.2, ..Default::default() },
            Transform::from_xyz(-1.0, 2.0, 1.0).facing(Vec3::NEG_Y),
        ));
        w.spawn((
            SpotLight { ls: 4.0, outer_cone_angle: FRAC_PI_2, ..Default::default() },
            Transform::from_xyz(1.0, 2.0, 1.0).facing(Vec3::NEG_Y),
        ));
        w.spawn(occluder(0.1));
        w.spawn(Camera::look_at(Vec3::new(0.0, 2.0, 4.0), Vec3::ZERO, 50.0));
        for _ in 0..2 {
            r.run_frame().unwrap();
        }
        r.image().clone()
    };
    assert_eq!(scene(1), scene(2));
}

/// A light behind a light type that only has the per-sample `sample`: it takes the core's
/// general path, where the light itself takes a bulk one (the occluder's direction runs, the
/// point light's lanes).
#[derive(Component, Clone, Copy, PartialEq)]
struct PerSample<L: Light + Copy>(L);

/// [`PerSample`] placed.
struct PlacedPerSample<P>(P);

impl<L: Light + Copy> Light for PerSample<L> {
    type Placed = PlacedPerSample<L::Placed>;
    const NAME: &'static str = "per-sample light";

    fn validate(&self, t: &Transform) -> Result<(), String> {
        Light::validate(&self.0, t)
    }

    fn place(&self, t: &Transform) -> Option<Self::Placed> {
        self.0.place(t).map(PlacedPerSample)
    }
}

impl<P: PlacedLight> PlacedLight for PlacedPerSample<P> {
    const DIMS: u32 = P::DIMS;
    const TERM: Term = P::TERM;

    fn sample(&self, at: &ShadingPoint, u: &LightSamples) -> Option<LightSample> {
        self.0.sample(at, u)
    }
}

/// Point lights lit in lanes at many points (jittered camera hits, and rows of shared hits)
/// give every pixel exactly the light and the shadow rays of the per-sample path: two lights of
/// the type, with and without falloff and shadows, one above or level with the floor (points
/// facing away get none), over an analytic sphere, a mesh and instances, with and without AOVs.
#[test]
fn point_lights_in_lanes_match_the_per_sample_path() {
    let mesh = std::sync::Arc::new(hemi::scene::mesh_gen::uv_sphere(0.3, 12, 24));
    for blockers in [Blockers::Sphere, Blockers::Mesh, Blockers::Instances] {
        for (falloff, shadows, height) in
            [(true, true, 2.0), (false, true, 0.3), (true, false, 2.0), (false, false, 0.0)]
        {
            for (jitter, aovs) in [(true, false), (true, true), (false, false)] {
                let render = |per_sample: bool| {
                    let settings =
                        RenderSettings { jitter, aovs, ..settings(13, 11, 8, SamplerKind::CorrelatedMultiJittered) };
                    let mut r = Renderer::new(settings);
                    r.add_light::<PerSample<PointLight>>();
                    let w = r.world_mut();
                    w.spawn((Plane::default(), white()));
                    blockers.spawn(w, &mesh);
                    let light = PointLight { ls: 3.0, color: Vec3::new(1.0, 0.8, 0.6), shadows, falloff };
                    // Two lights of one type: the lanes take them one after the other.
                    let second = PointLight { ls: 0.5, color: Vec3::ONE, ..light };
                    for (light, at) in [(light, (0.7, height, 0.4)), (second, (-1.0, 1.5, -0.5))] {
                        let at = Transform::from_xyz(at.0, at.1, at.2);
                        if per_sample {
                            w.spawn((PerSample(light), at));
                        } else {
                            w.spawn((light, at));
                        }
                    }
                    w.spawn(occluder(0.2));
                    w.spawn(Camera::look_at(Vec3::new(0.0, 1.5, 2.5), Vec3::new(0.0, 0.3, 0.0), 60.0));
                    let rays = r.run_frame().unwrap().rays;
                    let aov = r.image().aov(Aov::Direct).unwrap_or_default();
                    (r.image().linear.clone(), aov, rays)
                };
                let (lanes, per_sample) = (render(false), render(true));
                let case = format!(
                    "{blockers:?}, falloff {falloff}, shadows {shadows}, height {height}, jitter {jitter}, aovs {aovs}"
                );
                assert_eq!(lanes.2, per_sample.2, "{case}: ray counts");
                assert!(lanes.0 == per_sample.0 && lanes.1 == per_sample.1, "{case}: images differ");
                assert!(lanes.0.iter().any(|p| p.max_element() > 0.0), "{case}: a lit image");
                if shadows && height > 1.0 {
                    assert!(lanes.2.shadow > 0, "{case}: shadow rays traced");
                }
            }
        }
    }
}

/// Asserts that two images agree pixel by pixel to within float rounding (a relative 2e-6 of
/// the brighter channel): far below what one sample of a pixel's run weighs.
fn assert_close(a: &[Vec3], b: &[Vec3], case: &str) {
    assert_eq!(a.len(), b.len(), "{case}: image sizes");
    for (i, (p, q)) in a.iter().zip(b).enumerate() {
        let tolerance = 2e-6 * p.abs().max(q.abs()).max_element().max(1e-6);
        assert!((*p - *q).abs().max_element() <= tolerance, "{case}: pixel {i} {p} against {q}");
    }
}

/// What stands on the plane in [`the_occluder_s_bulk_path_matches_the_per_sample_path`] and
/// [`point_lights_in_lanes_match_the_per_sample_path`]: an analytic sphere, one triangle mesh
/// (a world-space tree of triangle packets), or three instances of one mesh (traced through the
/// top level).
#[derive(Clone, Copy, Debug)]
enum Blockers {
    Sphere,
    Mesh,
    Instances,
}

impl Blockers {
    /// Spawns them (white) into `w`, the meshes as `mesh`.
    fn spawn(self, w: &mut World, mesh: &std::sync::Arc<Mesh>) {
        match self {
            Blockers::Sphere => {
                w.spawn((Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 0.5, 0.0), white()));
            }
            Blockers::Mesh => {
                w.spawn((TriangleMesh(mesh.clone()), Transform::from_xyz(0.0, 0.3, 0.0), white()));
            }
            Blockers::Instances => {
                for x in [-0.5, 0.0, 0.5] {
                    w.spawn((TriangleMesh(mesh.clone()), Transform::from_xyz(x, 0.3, 0.0), white()));
                }
            }
        }
    }
}

/// The occluder's bulk paths (rays made in lanes, sorted or in quadrant order, whole-run sums,
/// and, for jittered hits, one sample at each of a pixel's points, set up in lanes) trace the
/// same rays as its per-sample path and give the same bits, except the beauty image of shared
/// hits, which sums each pixel's samples as a whole: the same up to rounding. For every other
/// occluder the plane reflects no ambient light, so the beauty image skips its points (no AO
/// ray) beside the blockers' within one pixel's run.
#[test]
fn the_occluder_s_bulk_path_matches_the_per_sample_path() {
    let occluders = [
        AmbientOccluder { min_amount: 0.3, max_distance: 0.7, color: Vec3::new(1.0, 0.5, 0.25), ..Default::default() },
        AmbientOccluder { exponent: 0.0, ls: 3.0, ..Default::default() },
        AmbientOccluder { exponent: 3.0, min_amount: 1.0, ..Default::default() },
        AmbientOccluder { min_amount: 1.0, ..Default::default() },
    ];
    let mesh = std::sync::Arc::new(hemi::scene::mesh_gen::uv_sphere(0.3, 12, 24));
    // (sampler, set size, samples per pixel). 37 samples: full groups of four, eight and
    // sixteen lanes, and a partial one of each. Correlated multi-jittered sets take the
    // occluder's one-pass paths for cosine runs where the CPU has AVX2 or AVX-512: with sets
    // of 16 and 37 samples a run spans three passes, the first and last partial (directions
    // copied from the table in sample order and sorted into quadrants);
    // with sets of 24 and 48 samples two whole passes of a set without quadrants (the same);
    // with sets of 16 and 32 samples two whole passes and with sets of 64 one (rays made in
    // the patterns' quadrant order, a packet of sixteen spanning the quadrants of a set of 16
    // and holding one quadrant of a set of 64, a packet of eight spanning two quadrants of a
    // set of 16 and holding half of one of a set of 64); 16 samples of a set of 64 (a
    // progressive frame's run) fill one sixteen-lane packet or two eight-lane ones, and 25
    // samples two sixteen-lane packets or four eight-lane ones, the last partial, all traced in
    // sample order. Frames of four samples
    // or fewer light the shared hits of a row of pixels together (`Tracer::shade_row_sums`,
    // with AOVs `Tracer::shade_row_samples`): a row's runs pooled, the occluder's rays from
    // neighbouring pixels in shared packets.
    let samplers = [
        (SamplerKind::CorrelatedMultiJittered, 16, 4),
        (SamplerKind::MultiJittered, 9, 3),
        (SamplerKind::MultiJittered, 37, 37),
        (SamplerKind::MultiJittered, 25, 25),
        (SamplerKind::CorrelatedMultiJittered, 16, 37),
        (SamplerKind::CorrelatedMultiJittered, 24, 48),
        (SamplerKind::CorrelatedMultiJittered, 16, 32),
        (SamplerKind::CorrelatedMultiJittered, 64, 16),
        (SamplerKind::CorrelatedMultiJittered, 64, 64),
    ];
    for (sampler, set, spp) in samplers {
        for blockers in [Blockers::Sphere, Blockers::Mesh, Blockers::Instances] {
            for (k, occluder) in occluders.into_iter().enumerate() {
                // Shared and jittered hits, with and without AOVs (the beauty image alone takes
                // its own path).
                let mut shared = Vec::new();
                let plane = if k % 2 == 0 { Matte { ka: 0.0, ..white() } } else { white() };
                for (jitter, aovs) in [(false, false), (false, true), (true, false), (true, true)] {
                    let render = |per_sample: bool| {
                        let base = settings(12, 10, spp, sampler);
                        let settings = RenderSettings { jitter, aovs, samples_per_set: set, ..base };
                        let mut r = Renderer::new(settings);
                        r.add_light::<PerSample<AmbientOccluder>>();
                        let w = r.world_mut();
                        w.spawn((Plane::default(), plane));
                        blockers.spawn(w, &mesh);
                        w.spawn((PointLight::default(), Transform::from_xyz(1.0, 2.0, 1.0)));
                        if per_sample {
                            w.spawn(PerSample(occluder));
                        } else {
                            w.spawn(occluder);
                        }
                        w.spawn(Camera::look_at(Vec3::new(0.0, 1.5, 2.5), Vec3::new(0.0, 0.3, 0.0), 60.0));
                        let rays = r.run_frame().unwrap().rays;
                        let aovs = [Aov::Ao, Aov::Direct, Aov::Albedo].map(|a| r.image().aov(a).unwrap_or_default());
                        (r.image().linear.clone(), rays, aovs)
                    };
                    let (bulk, per_sample) = (render(false), render(true));
                    let case = format!(
                        "{sampler:?} ({spp} of sets of {set}), {blockers:?}, occluder {k}, jitter {jitter}, aovs {aovs}"
                    );
                    assert_eq!(bulk.1, per_sample.1, "{case}: ray counts");
                    if jitter {
                        assert!(bulk.0 == per_sample.0 && bulk.2 == per_sample.2, "{case}: images differ");
                    } else {
                        // Shared hits sum each pixel's samples as a whole (`Tracer::shade_sum`),
                        // AOVs too: cosine runs in lanes count their blocked rays instead of
                        // adding a value per sample. The same up to rounding.
                        assert_close(&bulk.0, &per_sample.0, &case);
                        for (a, b) in bulk.2.iter().zip(&per_sample.2) {
                            assert_close(a, b, &format!("{case}: AOVs"));
                        }
                    }
                    if k == 0 {
                        assert!(bulk.1.ao > 0, "{case}: AO rays traced");
                    }
                    if !jitter {
                        shared.push(bulk.0);
                    }
                }
                // Runs of more than four samples at a shared hit give the beauty image the
                // same sum with AOVs as without; smaller ones are lit a row at a time, and with
                // AOVs sample by sample.
                if spp > 4 {
                    assert!(shared[0] == shared[1], "occluder {k}: the beauty image differs with AOVs");
                } else {
                    assert_close(&shared[0], &shared[1], &format!("occluder {k}: with and without AOVs"));
                }
            }
        }
    }
}

/// A light that brings NaN or +∞ for some sample values and 1 for the others, with no shadow ray.
#[derive(Component, Clone, Copy, PartialEq)]
struct Flaky;

impl Light for Flaky {
    type Placed = Flaky;
    const NAME: &'static str = "flaky";

    fn validate(&self, _: &Transform) -> Result<(), String> {
        Ok(())
    }

    fn place(&self, _: &Transform) -> Option<Flaky> {
        Some(*self)
    }
}

impl PlacedLight for Flaky {
    const TERM: Term = Term::Ambient;

    fn sample(&self, _: &ShadingPoint, u: &LightSamples) -> Option<LightSample> {
        let x = u.get(0).x;
        let value = if x < 0.2 {
            f32::NAN
        } else if x < 0.3 {
            f32::INFINITY
        } else {
            1.0
        };
        Some(LightSample { unoccluded: Vec3::splat(value), occluded: Vec3::ZERO, shadow: None })
    }
}

#[test]
fn non_finite_samples_are_dropped_and_counted_alike_on_every_path() {
    let render = |jitter, aovs| {
        let mut r = Renderer::new(RenderSettings { jitter, aovs, ..settings(6, 4, 16, SamplerKind::MultiJittered) });
        r.add_light::<Flaky>();
        let w = r.world_mut();
        w.spawn((Plane::default(), white()));
        w.spawn(Flaky);
        w.spawn(looking_down(Vec3::Y, 40.0));
        let dropped = r.run_frame().unwrap().nonfinite_samples;
        // About 30 % of 6 × 4 × 16 samples. A dropped sample adds nothing (it still counts
        // towards the pixel's samples), so every pixel is (finite samples) / 16.
        assert!((50..=200).contains(&dropped), "jitter {jitter}, aovs {aovs}: {dropped} dropped");
        let image = r.image().linear.clone();
        for p in &image {
            let finite = p.x * 16.0;
            assert!(*p == Vec3::splat(p.x) && finite == finite.round() && (4.0..16.0).contains(&finite), "{p}");
        }
        (dropped, image)
    };
    for jitter in [false, true] {
        assert_eq!(render(jitter, false), render(jitter, true), "jitter {jitter}: with and without AOVs");
    }
}
