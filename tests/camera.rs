//! The thin-lens camera: the focal plane renders as sharp as the pinhole, and a small sphere
//! off the focal plane spreads over the predicted circle of confusion.
//!
//! Model (see [`ThinLensCamera`]): a point at depth d reaches the film points
//! x = p·f/d + l·(1 − f/d) on the focal plane for lens points l, a uniform disk of radius
//! ρ = A·|d − f|/d there, i.e. ρ·H/(2·f·tan(vfov/2)) pixels. A sphere of radius a projects
//! to a disk of a·H/(2·d·tan(vfov/2)) pixels; the blurred spot is the two disks convolved, so
//! its intensity-weighted second moment about its centre is (ρ² + s²)/2 plus 1/6 for
//! measuring at pixel centres (1/12 per axis).

mod common;

use common::{settings, white};
use hemi::{bevy_ecs::bundle::Bundle, prelude::*};

const SIZE: u32 = 64;
const VFOV: f32 = 30.0;

/// Unlit-by-geometry emission: AO with `min_amount` 1 makes every hit exactly 1 (no AO rays),
/// the black background 0, so a pixel is the fraction of its samples that hit something.
fn coverage_scene(camera: impl Bundle, objects: impl Bundle) -> Renderer {
    let mut r = Renderer::new(settings(SIZE, SIZE, 256, SamplerKind::MultiJittered));
    let w = r.world_mut();
    w.spawn(AmbientOccluder { min_amount: 1.0, ..Default::default() });
    w.spawn(objects);
    w.spawn(camera);
    r.run_frame().expect("scene is valid");
    r
}

/// Total, centroid and second moment about the centroid of an image, in pixels.
fn moments(img: &Image) -> (f64, (f64, f64), f64) {
    let (mut total, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for y in 0..img.height {
        for x in 0..img.width {
            let v = img.pixel(x, y).x as f64;
            total += v;
            sx += v * (x as f64 + 0.5);
            sy += v * (y as f64 + 0.5);
        }
    }
    let (cx, cy) = (sx / total, sy / total);
    let mut m2 = 0.0;
    for y in 0..img.height {
        for x in 0..img.width {
            let v = img.pixel(x, y).x as f64;
            m2 += v * ((x as f64 + 0.5 - cx).powi(2) + (y as f64 + 0.5 - cy).powi(2));
        }
    }
    (total, (cx, cy), m2 / total)
}

/// Pixels per world unit on the focal plane at distance f.
fn pixels_per_unit(f: f32) -> f64 {
    SIZE as f64 / (2.0 * f as f64 * (VFOV as f64 / 2.0).to_radians().tan())
}

#[test]
fn the_focal_plane_is_as_sharp_as_the_pinhole() {
    // A thin card on the focal plane, its corner in view: two sharp edges.
    let (eye, f, lens) = (Vec3::new(0.0, 0.0, 5.0), 5.0, 0.4);
    let card = (
        Cuboid { half_extents: Vec3::new(1.0, 1.0, 1e-4) },
        Transform::from_xyz(0.7, 0.6, 0.0).with_rotation(Quat::from_rotation_z(0.3)),
        white(),
    );
    let thin = ThinLensCamera::look_at(eye, Vec3::ZERO, VFOV, lens);
    assert_eq!(thin.focal_distance, f);
    let sharp = coverage_scene(thin, card);
    let pinhole = coverage_scene(thin.pinhole(), card);
    let (a, b) = (sharp.image(), pinhole.image());
    let edge_pixels = b.linear.iter().filter(|p| p.x > 0.05 && p.x < 0.95).count();
    assert!(edge_pixels > 20, "the card has edges in view");
    for (i, (p, q)) in a.linear.iter().zip(&b.linear).enumerate() {
        assert!((p.x - q.x).abs() < 0.02, "pixel {i}: thin lens {} vs pinhole {}", p.x, q.x);
    }
    // The same card out of focus is clearly not.
    let blurred = coverage_scene(ThinLensCamera { focal_distance: 2.5, ..thin }, card);
    let differ = blurred.image().linear.iter().zip(&b.linear).filter(|(p, q)| (p.x - q.x).abs() > 0.1).count();
    assert!(differ > 2 * edge_pixels, "defocus blurs the edges: {differ} pixels differ");
}

#[test]
fn a_small_sphere_spreads_over_the_circle_of_confusion() {
    let (f, lens) = (5.0f32, 0.5f32);
    // (depth, sphere radius): behind and in front of the focal plane, and on it.
    for (d, a) in [(10.0f32, 0.1f32), (3.0, 0.05), (5.0, 0.1)] {
        let camera = ThinLensCamera {
            eye: Vec3::ZERO,
            target: Vec3::NEG_Z,
            up: Vec3::Y,
            vfov_degrees: VFOV,
            lens_radius: lens,
            focal_distance: f,
        };
        let sphere = (Sphere { radius: a }, Transform::from_xyz(0.0, 0.0, -d), white());
        let r = coverage_scene(camera, sphere);
        let (total, (cx, cy), m2) = moments(r.image());
        let rho = (lens * (d - f).abs() / d) as f64 * pixels_per_unit(f);
        let s = (a / d) as f64 * pixels_per_unit(1.0);
        let expected = (rho * rho + s * s) / 2.0 + 1.0 / 6.0;
        assert!((m2 - expected).abs() < 0.05 * expected, "d = {d}: second moment {m2:.3} px² vs {expected:.3}");
        assert!((cx - 32.0).abs() < 0.1 && (cy - 32.0).abs() < 0.1, "d = {d}: centred at ({cx}, {cy})");
        // Blur moves light around but keeps it: the total matches the pinhole's.
        let (pin_total, ..) = moments(coverage_scene(camera.pinhole(), sphere).image());
        assert!((total - pin_total).abs() < 0.02 * pin_total, "d = {d}: total {total} vs pinhole {pin_total}");
        // Nothing lands outside the predicted spot (plus the pixel it touches).
        let reach = rho + s + 1.5;
        for y in 0..SIZE {
            for x in 0..SIZE {
                let dist = (x as f64 + 0.5 - 32.0).hypot(y as f64 + 0.5 - 32.0);
                if dist > reach {
                    assert_eq!(r.image().pixel(x, y).x, 0.0, "d = {d}: light at {dist:.1} px > {reach:.1}");
                }
            }
        }
    }
}

#[test]
fn thin_lens_cameras_are_validated_counted_and_change_detected() {
    let mut r = Renderer::new(settings(8, 8, 1, SamplerKind::Jittered));
    r.world_mut().spawn(AmbientOccluder::default());
    r.world_mut().spawn(Sphere { radius: 1.0 });
    let cam = r.world_mut().spawn(ThinLensCamera::look_at(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 40.0, 0.1)).id();
    r.run_frame().unwrap();
    r.run_frame().unwrap();
    assert_eq!(r.spp(), 2);
    r.world_mut().get_mut::<ThinLensCamera>(cam).unwrap().focal_distance = 3.0;
    r.run_frame().unwrap();
    assert_eq!(r.spp(), 1, "refocusing restarts accumulation");
    r.world_mut().get_mut::<ThinLensCamera>(cam).unwrap().lens_radius = -1.0;
    let e = r.run_frame().unwrap_err().to_string();
    assert!(e.contains("lens radius"), "{e}");
    r.world_mut().get_mut::<ThinLensCamera>(cam).unwrap().lens_radius = 0.1;
    r.world_mut().get_mut::<ThinLensCamera>(cam).unwrap().focal_distance = 0.0;
    assert!(r.run_frame().unwrap_err().to_string().contains("focal distance"));
    r.world_mut().get_mut::<ThinLensCamera>(cam).unwrap().focal_distance = 4.0;
    r.world_mut().spawn(Camera::look_at(Vec3::ONE, Vec3::ZERO, 30.0));
    assert!(r.run_frame().unwrap_err().to_string().contains("2 cameras"));
}
