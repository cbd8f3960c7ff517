//! The look of an image: coverage as alpha (straight in PNG, premultiplied in EXR), the
//! ground put under an isolated object, and the command line's look and camera options.

mod common;

use std::process::Command;

use common::{assert_matches_binomial, occluder, settings, white};
use hemi::{
    analytic::AnalyticScene,
    camera::PinholeRays,
    film::{OutputFormat, Picture, write_picture},
    look::{Look, Tonemap},
    prelude::*,
    resources::Aov,
    scene::staging::spawn_ground,
};

/// A 2×1 orthographic view of a box whose left edge halves pixel 0 and which covers pixel 1,
/// on a transparent (zero) background.
fn half_covered() -> Renderer {
    let mut r =
        Renderer::new(RenderSettings { aovs: true, ..settings(2, 1, 16, SamplerKind::CorrelatedMultiJittered) });
    let world = r.world_mut();
    // The film spans x ∈ [−1, 1]: pixel 0 is x ∈ [−1, 0], the box starts at x = −0.5.
    world.spawn(OrthographicCamera {
        eye: Vec3::new(0.0, 0.0, 5.0),
        target: Vec3::ZERO,
        up: Vec3::Y,
        half_height: 0.5,
    });
    world.spawn(occluder(0.0));
    let material = Matte { cd: Vec3::new(0.6, 0.3, 0.1), ..white() };
    world.spawn((Cuboid { half_extents: Vec3::new(2.0, 2.0, 0.5) }, Transform::from_xyz(1.5, 0.0, -0.5), material));
    r.run_frame().unwrap();
    r
}

#[test]
fn half_covered_pixels_get_half_alpha_and_the_surface_colour() {
    let r = half_covered();
    let image = r.image();
    let alpha = image.aov(Aov::Alpha).unwrap();
    // Sixteen stratified samples: eight on each side of the pixel's centre line.
    assert_eq!((alpha[0].x, alpha[1].x), (0.5, 1.0));
    // Nothing occludes the front face: its radiance is ka·cd, and pixel 0 holds half of it.
    let surface = Vec3::new(0.6, 0.3, 0.1);
    assert!((image.linear[1] - surface).abs().max_element() < 1e-5, "{}", image.linear[1]);
    assert!((image.linear[0] - surface * 0.5).abs().max_element() < 1e-5, "{}", image.linear[0]);

    // PNG: straight alpha, so both pixels have the surface's colour.
    let picture = Picture { look: Look::default(), alpha: true };
    let mut png = std::io::Cursor::new(Vec::new());
    write_picture(image, OutputFormat::Png, &picture, &mut png).unwrap();
    let rgba = image::load_from_memory(png.get_ref()).unwrap();
    assert_eq!(rgba.color(), image::ColorType::Rgba8);
    let rgba = rgba.into_rgba8();
    let code = |v: f32| hemi::srgb::linear_to_srgb8(v);
    let colour = [code(0.6), code(0.3), code(0.1)];
    assert_eq!(rgba.get_pixel(0, 0).0, [colour[0], colour[1], colour[2], 128]);
    assert_eq!(rgba.get_pixel(1, 0).0, [colour[0], colour[1], colour[2], 255]);

    // EXR: premultiplied, the linear values as they are, A the coverage.
    let mut exr = std::io::Cursor::new(Vec::new());
    write_picture(image, OutputFormat::Exr, &picture, &mut exr).unwrap();
    let back = image::load_from_memory(exr.get_ref()).unwrap().into_rgba32f();
    let p = image.linear[0];
    assert_eq!(back.get_pixel(0, 0).0, [p.x, p.y, p.z, 0.5]);
}

#[test]
fn the_ground_under_a_resting_sphere_has_its_analytic_occlusion() {
    let (width, height, spp) = (48, 12, 64);
    let mut r = Renderer::new(settings(width, height, spp, SamplerKind::CorrelatedMultiJittered));
    let world = r.world_mut();
    // A unit sphere resting on y = 0, seen from above beside it (no sight line meets it).
    world.spawn((Sphere { radius: 1.0 }, Transform::from_xyz(0.0, 1.0, 0.0), white()));
    world.spawn(occluder(0.0));
    let camera = AnalyticScene::SphereOverPlane.camera(1.0, Vec3::ZERO);
    world.spawn(camera);
    let ground = spawn_ground(world).unwrap();
    assert!(ground < 0.0 && ground > -1e-3, "{ground}");
    for mut m in world.query_filtered::<&mut Matte, With<Plane>>().iter_mut(world) {
        *m = white();
    }
    r.run_frame().unwrap();
    // The sphere's configuration factor from a floor point at horizontal distance x, the
    // centre h above: AO = 1 − r²h/(h² + x²)^{3/2}.
    let h = 1.0 - ground;
    let ao = |p: Vec3| 1.0 - h / (h * h + p.x * p.x + p.z * p.z).powf(1.5);
    let rays = PinholeRays::new(&camera, width, height).unwrap();
    assert_matches_binomial(&r, &rays, (width, height, spp), ground, ao);
    // Darker next to the sphere than far from it.
    assert!(r.image().pixel(0, height / 2).x < 0.75 && r.image().pixel(width - 1, height / 2).x > 0.95);
}

fn hemi(args: &[&str]) -> (i32, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_hemi")).args(args).output().expect("binary runs");
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn png_look_is_the_tone_curve_of_the_exposed_exr() {
    let dir = tempfile::tempdir().unwrap();
    let (png, exr) = (dir.path().join("a.png"), dir.path().join("a.exr"));
    let base = ["render", "--size", "24x16", "--spp", "4", "--exposure", "1.5", "--tonemap", "khronos-neutral"];
    for out in [&png, &exr] {
        let (code, err) = hemi(&[&base[..], &["--out", out.to_str().unwrap()]].concat());
        assert_eq!(code, 0, "{err}");
    }
    let linear = image::open(&exr).unwrap().into_rgb32f();
    let srgb = image::open(&png).unwrap().into_rgb8();
    let look = Look { exposure: 1.5, tonemap: Tonemap::KhronosNeutral };
    let mut brightest = 0.0f32;
    for (l, s) in linear.pixels().zip(srgb.pixels()) {
        let c = Vec3::from(l.0);
        brightest = brightest.max(c.max_element());
        assert_eq!(look.srgb8(c), s.0, "linear {c}");
    }
    // The EXR is not exposed: the built-in scene's light stays below 2^1.5 times its peak.
    assert!(brightest > 0.5 && brightest < 2.0, "{brightest}");
}

#[test]
fn look_from_the_scene_camera_gives_the_same_image_and_bad_cameras_are_usage_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (dir.path().join("a.png"), dir.path().join("b.png"));
    let base = ["render", "--size", "32x18", "--spp", "2"];
    assert_eq!(hemi(&[&base[..], &["--out", a.to_str().unwrap()]].concat()).0, 0);
    // The built-in scene's own camera, given on the command line.
    let camera = ["--look-from", "0,2.6,8.2", "--look-at", "0,0.9,0", "--fov", "38"];
    let (code, err) = hemi(&[&base[..], &camera, &["--out", b.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap());

    let out = ["--out", b.to_str().unwrap()];
    for (bad, says) in [
        (&["--look-from", "1,1,1", "--look-at", "1,1,1"][..], "same point"),
        (&["--look-from", "0,5,0", "--look-at", "0,0,0"], "parallel"),
        (&["--look-from", "0,5,0"], "--look-at"),
        (&["--look-from", "0,1,5", "--look-at", "0,0,0", "--fov", "180"], "field of view"),
        (&["--exposure", "nan"], "exposure"),
        (&["--tonemap", "filmic"], "khronos-neutral"),
    ] {
        let (code, err) = hemi(&[&base[..], bad, &out].concat());
        assert_eq!(code, 2, "{bad:?}: {err}");
        assert!(err.contains(says), "{bad:?}: {err}");
    }
}

/// Every channel of `path` (one layer) by name.
fn exr_channels(path: &std::path::Path) -> std::collections::HashMap<String, Vec<f32>> {
    use exr::prelude::{ReadChannels, ReadLayers};
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .unwrap();
    let channels = image.layer_data.channel_data.list;
    channels.into_iter().map(|c| (c.name.to_string(), c.sample_data.values_as_f32().collect())).collect()
}

#[test]
fn layered_aovs_equal_the_files_of_each_aov() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "../shared/peers/scenes/cornell.json";
    let base = ["render", scene, "--size", "24x24", "--spp", "2", "--aov", "ao,direct,albedo,normal,depth,alpha"];
    let (layered, files) = (dir.path().join("layered.exr"), dir.path().join("files.exr"));
    let (code, err) = hemi(&[&base[..], &["--out", layered.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    let (code, err) = hemi(&[&base[..], &["--aov-files", "--out", files.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    let got = exr_channels(&layered);
    let mut names: Vec<&str> = got.keys().map(String::as_str).collect();
    names.sort_unstable();
    let expected = [
        "A", "B", "G", "N.X", "N.Y", "N.Z", "R", "Z", "albedo.B", "albedo.G", "albedo.R", "ao", "direct.B", "direct.G",
        "direct.R",
    ];
    assert_eq!(names, expected);
    let beauty = exr_channels(&files);
    for c in ["R", "G", "B"] {
        assert_eq!(got[c], beauty[c], "{c}");
    }
    for (file, channels) in [
        ("ao", ["ao", "ao", "ao"]),
        ("direct", ["direct.R", "direct.G", "direct.B"]),
        ("albedo", ["albedo.R", "albedo.G", "albedo.B"]),
        ("normal", ["N.X", "N.Y", "N.Z"]),
        ("depth", ["Z", "Z", "Z"]),
        ("alpha", ["A", "A", "A"]),
    ] {
        let single = exr_channels(&dir.path().join(format!("files.{file}.exr")));
        for (c, name) in ["R", "G", "B"].into_iter().zip(channels) {
            assert_eq!(got[name], single[c], "{file}.{c} against {name}");
        }
    }
    // The cornell box fills the view: coverage 1 everywhere.
    assert!(got["A"].iter().all(|&a| a == 1.0));
    // Beside a PNG the layers go to <stem>.exr.
    let png = dir.path().join("beside.png");
    let (code, err) = hemi(&[&base[..], &["--out", png.to_str().unwrap()]].concat());
    assert_eq!(code, 0, "{err}");
    assert_eq!(exr_channels(&dir.path().join("beside.exr"))["ao"], got["ao"]);
}
