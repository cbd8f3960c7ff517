//! Frame-pipeline behaviour: progressive accumulation, change detection, skipped work,
//! determinism across thread counts.

mod common;

use std::sync::Arc;

use common::{occluder, settings, white};
use hemi::scene::mesh_gen::uv_sphere;
use hemi::{
    geometry::{SceneGeometry, accel::BvhWork},
    prelude::*,
};

fn small_default_scene(threads: Option<usize>) -> Renderer {
    let s = RenderSettings { width: 64, height: 36, samples_per_frame: 2, samples_per_set: 8, ..Default::default() };
    let r = Renderer::with_default_scene(s);
    match threads {
        Some(n) => r.with_threads(n).unwrap(),
        None => r,
    }
}

/// Lights that draw no samples (the default scene's point light) are lit once per pixel, a
/// tile's row at a time, the row's shadow rays traced together in packets: whatever the
/// tile's width (one pixel, whose ray goes alone, or 32), every pixel gets the same bits, AOVs
/// or not, and the same shadow rays are traced.
#[test]
fn point_lights_give_the_same_image_whatever_the_width_of_a_row() {
    for aovs in [false, true] {
        let render = |tile_size| {
            let s = RenderSettings {
                width: 64,
                height: 36,
                samples_per_frame: 2,
                samples_per_set: 8,
                tile_size,
                jitter: false,
                aovs,
                ..Default::default()
            };
            let mut r = Renderer::with_default_scene(s);
            let rays = r.run_frame().unwrap().rays;
            (r.image().clone(), rays)
        };
        let (narrow, wide) = (render(1), render(32));
        assert!(wide.1.shadow > 1000, "aovs {aovs}: {:?}", wide.1);
        assert_eq!(narrow.1, wide.1, "aovs {aovs}");
        assert!(narrow.0 == wide.0, "aovs {aovs}: the images differ");
    }
}

/// Jittered samples, each with a camera hit of its own, keep their radiance alone when no AOV
/// is asked for: the beauty image is the AOV render's bit for bit, for runs lit a row at a
/// time (two samples a frame), a pixel's own runs (sixteen) and adaptive sampling.
#[test]
fn jittered_beauty_images_are_the_same_with_aovs_or_without() {
    for (spf, target_error) in [(2, None), (16, None), (4, Some(0.05))] {
        let render = |aovs| {
            let s = RenderSettings {
                width: 48,
                height: 27,
                samples_per_frame: spf,
                samples_per_set: 16,
                max_spp: Some(32),
                target_error,
                aovs,
                ..Default::default()
            };
            assert!(s.jitter);
            let mut r = Renderer::with_default_scene(s);
            let mut rays = Vec::new();
            while !r.converged() {
                rays.push(r.run_frame().unwrap().rays);
            }
            (r.image().linear.clone(), rays)
        };
        let ((beauty, beauty_rays), (with_aovs, aov_rays)) = (render(false), render(true));
        assert!(beauty_rays.len() >= 2, "spf {spf}: {} frames", beauty_rays.len());
        assert_eq!(beauty_rays, aov_rays, "spf {spf}");
        assert!(beauty == with_aovs, "spf {spf}, target {target_error:?}: the images differ");
        assert!(beauty.iter().any(|p| *p != beauty[0]), "spf {spf}: a flat image");
    }
}

#[test]
fn a_64x64_frame_renders_in_memory() {
    let mut r = Renderer::with_default_scene(RenderSettings { width: 64, height: 64, ..Default::default() });
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.spp, 4);
    let img = r.image();
    assert_eq!((img.width, img.height, img.linear.len(), img.srgb8().len()), (64, 64, 4096, 3 * 4096));
    assert!(img.linear.iter().all(|p| p.is_finite() && p.min_element() >= 0.0));
    // A real picture: the sky, lit surfaces and AO-darkened contact regions all present.
    let luminance: Vec<f32> = img.linear.iter().map(|p| p.dot(Vec3::new(0.2126, 0.7152, 0.0722))).collect();
    let min = luminance.iter().cloned().fold(f32::MAX, f32::min);
    let max = luminance.iter().cloned().fold(0.0, f32::max);
    assert!(min < 0.2 && max > 0.6, "flat image: luminance {min}..{max}");
}

#[test]
fn same_image_bit_for_bit_with_one_or_two_threads() {
    let mut one = small_default_scene(Some(1));
    let mut two = small_default_scene(Some(2));
    for _ in 0..3 {
        one.run_frame().unwrap();
        two.run_frame().unwrap();
    }
    assert_eq!(one.image(), two.image());
    let mut other_seed = small_default_scene(Some(2));
    other_seed.settings_mut().seed = 99;
    for _ in 0..3 {
        other_seed.run_frame().unwrap();
    }
    assert_ne!(one.image(), other_seed.image(), "the seed must matter");
}

#[test]
fn static_scene_accumulates_and_builds_the_bvh_once() {
    let mut r = small_default_scene(None);
    let first = r.run_frame().unwrap().clone();
    assert!(first.bvh_built);
    assert_eq!(first.spp, 2);
    for frame in 2..=4 {
        let stats = r.run_frame().unwrap();
        assert!(!stats.bvh_built, "frame {frame} rebuilt an unchanged BVH");
        assert_eq!(stats.spp, 2 * frame);
        assert!(stats.systems.iter().all(|s| s.name != "sample_sets"), "sample sets regenerated");
    }
}

#[test]
fn tracing_stops_once_max_spp_is_reached() {
    let mut r = small_default_scene(None);
    assert_eq!(r.render(5).unwrap(), 3, "2 + 2 + 1 spp");
    assert_eq!(r.spp(), 5);
    let before = r.image().clone();
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.rays.total(), 0, "a converged static scene traces nothing");
    assert!(stats.systems.iter().all(|s| s.name != "resolve"), "nothing to resolve");
    assert_eq!(r.image(), &before);
}

#[test]
fn moving_an_object_resets_accumulation_and_rebuilds_the_bvh() {
    let mut r = small_default_scene(None);
    r.run_frame().unwrap();
    r.run_frame().unwrap();
    let before = r.image().clone();
    let mut q = r.world_mut().query_filtered::<&mut Transform, With<Sphere>>();
    for mut t in q.iter_mut(r.world_mut()) {
        t.translation.y += 0.5;
    }
    let stats = r.run_frame().unwrap();
    assert!(stats.bvh_built);
    assert_eq!(stats.spp, 2, "accumulation restarted");
    assert_ne!(r.image(), &before);
}

#[test]
fn changing_a_material_resets_accumulation_without_bvh_work() {
    let mut r = small_default_scene(None);
    r.run_frame().unwrap();
    let mut q = r.world_mut().query_filtered::<&mut Matte, With<Sphere>>();
    for mut m in q.iter_mut(r.world_mut()) {
        m.cd = Vec3::new(0.0, 1.0, 0.0);
    }
    let stats = r.run_frame().unwrap();
    assert!(!stats.bvh_built);
    assert_eq!(stats.spp, 2);
    let geometry = r.world().resource::<SceneGeometry>();
    assert!(geometry.objects.iter().any(|o| o.material.cd == Vec3::new(0.0, 1.0, 0.0)));
}

#[test]
fn moving_the_camera_or_a_light_resets_without_bvh_work() {
    let mut r = small_default_scene(None);
    r.run_frame().unwrap();
    r.run_frame().unwrap();
    let mut cams = r.world_mut().query::<&mut Camera>();
    cams.single_mut(r.world_mut()).unwrap().eye.x += 0.3;
    let stats = r.run_frame().unwrap();
    assert!(!stats.bvh_built);
    assert_eq!(stats.spp, 2);
    r.run_frame().unwrap();
    let mut lights = r.world_mut().query_filtered::<&mut Transform, With<PointLight>>();
    lights.single_mut(r.world_mut()).unwrap().translation.y += 1.0;
    let stats = r.run_frame().unwrap();
    assert!(!stats.bvh_built);
    assert_eq!(stats.spp, 2);
}

#[test]
fn despawning_an_object_rebuilds_and_changes_the_image() {
    let mut r = small_default_scene(None);
    r.run_frame().unwrap();
    let prims = r.stats().bvh_prims;
    let mesh = r.world_mut().query_filtered::<Entity, With<TriangleMesh>>().single(r.world()).unwrap();
    r.world_mut().despawn(mesh);
    let stats = r.run_frame().unwrap();
    assert!(stats.bvh_built);
    assert!(stats.bvh_prims < prims);
    assert_eq!(stats.spp, 2);
}

#[test]
fn changing_settings_resets_and_resizes() {
    let mut r = small_default_scene(None);
    r.run_frame().unwrap();
    r.settings_mut().width = 40;
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.spp, 2);
    assert_eq!(r.image().linear.len(), 40 * 36);
    r.settings_mut().sampler = SamplerKind::Hammersley;
    let stats = r.run_frame().unwrap();
    assert!(stats.systems.iter().any(|s| s.name == "sample_sets" && s.note.starts_with("generated")));
}

/// A floor with a sphere, a camera, and the given lights.
fn floor_scene(occluders: usize, light: Option<(PointLight, Vec3)>) -> Renderer {
    let mut r = Renderer::new(settings(16, 16, 2, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn((Plane::default(), white()));
    w.spawn((Sphere { radius: 0.5 }, Transform::from_xyz(0.0, 0.5, 0.0), white()));
    w.spawn(Camera::look_at(Vec3::new(0.0, 3.0, 3.0), Vec3::ZERO, 60.0));
    for _ in 0..occluders {
        w.spawn(occluder(0.0));
    }
    if let Some((l, p)) = light {
        w.spawn((l, Transform::from_translation(p)));
    }
    r
}

#[test]
fn no_ao_rays_without_an_occluder() {
    let mut r = floor_scene(0, Some((PointLight::default(), Vec3::new(0.0, 3.0, 0.0))));
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.rays.ao, 0);
    assert!(stats.rays.shadow > 0);
    let mut two = floor_scene(2, None);
    let stats = two.run_frame().unwrap();
    assert_eq!(stats.rays.ao, 2 * stats.rays.primary, "one AO ray per occluder per hit (all rays hit)");
}

#[test]
fn no_shadow_rays_when_a_light_cannot_contribute() {
    let below = (PointLight::default(), Vec3::new(0.0, -2.0, 0.0)); // behind the floor
    let dark = (PointLight { ls: 0.0, ..Default::default() }, Vec3::new(0.0, 3.0, 0.0));
    let unshadowed = (PointLight { shadows: false, ..Default::default() }, Vec3::new(0.0, 3.0, 0.0));
    for light in [dark, unshadowed] {
        let mut r = floor_scene(1, Some(light));
        assert_eq!(r.run_frame().unwrap().rays.shadow, 0);
    }
    // From below, only the sphere's underside could face the light, and the camera sees none.
    let mut r = floor_scene(1, Some(below));
    let stats = r.run_frame().unwrap();
    assert!(stats.rays.shadow < stats.rays.primary / 20, "{} shadow rays", stats.rays.shadow);
}

#[test]
fn the_trace_split_times_only_the_lights_a_scene_has() {
    let light = || Some((PointLight::default(), Vec3::new(0.0, 3.0, 0.0)));
    let split = |occluders, light| {
        let mut r = floor_scene(occluders, light);
        r.time_split(true);
        r.run_frame().unwrap().trace_split
    };
    // Unless asked for, nothing is timed, and the image is the same.
    let mut untimed = floor_scene(1, light());
    assert_eq!(untimed.run_frame().unwrap().trace_split, Default::default());
    let mut timed = floor_scene(1, light());
    timed.time_split(true);
    timed.run_frame().unwrap();
    let bits = |r: &Renderer| r.image().linear.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    assert_eq!(bits(&untimed), bits(&timed));
    let both = split(1, light());
    assert!(both.ambient > 0 && both.diffuse > 0, "{both:?}");
    assert!(both.ambient + both.diffuse < both.pixels, "{both:?}");
    // Each term's scene queries are a part of its time.
    assert!(0 < both.ambient_queries && both.ambient_queries < both.ambient, "{both:?}");
    assert!(0 < both.diffuse_queries && both.diffuse_queries < both.diffuse, "{both:?}");
    let direct_only = split(0, light());
    assert!(direct_only.ambient == 0 && direct_only.ambient_queries == 0, "{direct_only:?}");
    assert!(direct_only.diffuse > 0 && direct_only.diffuse_queries > 0, "{direct_only:?}");
    let ao_only = split(2, None);
    assert!(ao_only.ambient > 0 && ao_only.ambient_queries > 0, "{ao_only:?}");
    assert!(ao_only.diffuse == 0 && ao_only.diffuse_queries == 0, "{ao_only:?}");
}

#[test]
fn shared_meshes_are_instanced_by_many_entities() {
    let mesh = Arc::new(hemi::scene::mesh_gen::uv_sphere(0.4, 8, 16));
    let mut r = floor_scene(1, None);
    for i in 0..5 {
        r.world_mut().spawn((TriangleMesh(mesh.clone()), Transform::from_xyz(i as f32 - 2.0, 0.4, -1.0)));
    }
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_prims, 1 + mesh.triangle_count(), "the mesh is stored once");
    assert_eq!(stats.bvh_work.blas_built, 2, "one BLAS for the sphere, one for the shared mesh");
    let geometry = r.world().resource::<SceneGeometry>();
    assert_eq!(geometry.instanced_triangle_count, 5 * mesh.triangle_count());
    assert_eq!(geometry.instances().len(), 6);
}

/// A jittered render bakes shared meshes once its camera rays pay for the bake: from 64 per
/// triangle the placements add; at pixel centres they stay instanced whatever the target.
#[test]
fn shared_meshes_are_baked_where_the_sample_target_pays_for_it() {
    let mesh = Arc::new(hemi::scene::mesh_gen::uv_sphere(0.4, 8, 16));
    let mut r = floor_scene(1, None);
    let first = r.world_mut().spawn((TriangleMesh(mesh.clone()), Transform::from_xyz(-2.0, 0.4, -1.0))).id();
    for i in 1..5 {
        r.world_mut().spawn((TriangleMesh(mesh.clone()), Transform::from_xyz(i as f32 - 2.0, 0.4, -1.0)));
    }
    let instances = |r: &Renderer| r.world().resource::<SceneGeometry>().instances().len();
    // The bake pays from 64 camera rays (16 × 16 pixels × max_spp) per triangle it places.
    let enough = (64 * 5 * mesh.triangle_count()).div_ceil(16 * 16) as u32;
    r.run_frame().unwrap();
    assert_eq!(instances(&r), 6, "no sample target: the plane's sphere and five instances");
    let instanced = r.image().linear.clone();

    r.settings_mut().max_spp = Some(enough - 1);
    assert!(!r.run_frame().unwrap().bvh_built, "a target too small to pay changes nothing");
    r.settings_mut().max_spp = Some(enough);
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_work.blas_built, 2, "the sphere and one tree for the five placements");
    assert_eq!(instances(&r), 2);
    // Baked or instanced, the first frame after the restart is the same up to rounding.
    let differ =
        r.image().linear.iter().zip(&instanced).filter(|(x, y)| (**x - **y).abs().max_element() > 1e-4).count();
    assert!(differ <= 2, "{differ} of {} pixels differ", instanced.len());

    r.world_mut().get_mut::<Transform>(first).unwrap().translation.y += 0.1;
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_work.blas_built, 2, "a baked placement moved: the baked tree is rebuilt");
    r.settings_mut().max_spp = Some(enough - 1);
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_work.blas_built, 2, "instanced again: the sphere and the shared mesh's BLAS");
    assert_eq!(instances(&r), 6);

    // At pixel centres the camera rays are one a pixel: any target keeps the instances.
    r.settings_mut().jitter = false;
    r.settings_mut().max_spp = Some(64 * enough);
    r.run_frame().unwrap();
    assert_eq!(instances(&r), 6, "pixel centres: instanced");
    r.settings_mut().jitter = true;
    let stats = r.run_frame().unwrap();
    assert_eq!((stats.bvh_work.blas_built, instances(&r)), (2, 2), "jittered again: baked");
}

#[test]
fn moving_a_mesh_instance_rebuilds_only_the_top_level() {
    let mesh = Arc::new(hemi::scene::mesh_gen::uv_sphere(0.4, 8, 16));
    let mut r = floor_scene(1, None);
    let e = r.world_mut().spawn((TriangleMesh(mesh.clone()), Transform::from_xyz(1.0, 0.4, -1.0))).id();
    r.world_mut().spawn((TriangleMesh(mesh), Transform::from_xyz(-1.0, 0.4, -1.0)));
    r.run_frame().unwrap();
    r.world_mut().get_mut::<Transform>(e).unwrap().translation.y += 0.3;
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_work, BvhWork { blas_built: 0, blas_refit: 0, tlas_built: true });
    assert_eq!(stats.spp, 2, "accumulation restarted");
}

#[test]
fn static_meshes_are_baked_into_one_tree_and_dynamic_ones_stay_instances() {
    let (a, b) = (Arc::new(uv_sphere(0.4, 8, 16)), Arc::new(uv_sphere(0.3, 6, 12)));
    let bake = |dynamic: bool| {
        let mut r = floor_scene(1, None);
        let w = r.world_mut();
        let baked = w.spawn((TriangleMesh(a.clone()), Transform::from_xyz(1.0, 0.4, -1.0))).id();
        let moving = w.spawn((TriangleMesh(b.clone()), Transform::from_xyz(-1.0, 0.3, -1.0))).id();
        if dynamic {
            w.entity_mut(moving).insert(Dynamic);
        }
        let stats = r.run_frame().unwrap().clone();
        (r, baked, moving, stats)
    };

    let (mut r, baked, moving, stats) = bake(true);
    assert_eq!(stats.bvh_work.blas_built, 3, "the sphere, the baked mesh and the dynamic mesh");
    assert_eq!(r.world().resource::<SceneGeometry>().instances().len(), 3);
    let instanced = r.image().linear.clone();
    r.world_mut().get_mut::<Transform>(moving).unwrap().translation.y += 0.1;
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_work, BvhWork { blas_built: 0, blas_refit: 0, tlas_built: true }, "dynamic: top level only");
    r.world_mut().get_mut::<Transform>(baked).unwrap().translation.y += 0.1;
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.bvh_work.blas_built, 2, "a baked mesh moved: the world shapes and the baked tree are rebuilt");

    // Baked or instanced, the same scene renders the same image up to rounding (which may flip
    // a ray grazing an edge, so allow a stray pixel).
    let (r, _, _, stats) = bake(false);
    assert_eq!(stats.bvh_work.blas_built, 2, "the sphere and one tree for both meshes");
    assert_eq!(r.world().resource::<SceneGeometry>().instances().len(), 2);
    let differ =
        r.image().linear.iter().zip(&instanced).filter(|(x, y)| (**x - **y).abs().max_element() > 1e-4).count();
    assert!(differ <= 2, "{differ} of {} pixels differ", instanced.len());
}

#[test]
fn adaptive_sampling_retires_converged_pixels_and_saves_samples() {
    let settings = RenderSettings {
        width: 48,
        height: 27,
        samples_per_frame: 8,
        samples_per_set: 8,
        max_spp: Some(1024),
        target_error: Some(0.02),
        ..Default::default()
    };
    let mut r = Renderer::with_default_scene(settings.clone());
    let mut frames = 0;
    while !r.converged() {
        r.run_frame().unwrap();
        frames += 1;
    }
    let acc = r.world().resource::<hemi::resources::Accumulation>();
    // Sky pixels have no variance: they stop at the minimum; noisy ones go on.
    let min = *acc.counts.iter().min().unwrap();
    let max = *acc.counts.iter().max().unwrap();
    assert_eq!(min, RenderSettings::ADAPTIVE_MIN_SPP);
    assert!(max > 4 * min, "noisy pixels should keep sampling ({min}..{max})");
    // Every pixel stopped before the cap, meeting the target.
    for i in 0..acc.counts.len() {
        assert!(acc.counts[i] < 1024 && acc.standard_error(i) <= 0.02, "pixel {i}: error {}", acc.standard_error(i));
    }
    let (taken, uniform) = acc.samples_against_uniform();
    assert!(uniform > 1.5 * taken as f64, "adaptive {taken} vs uniform {uniform}");
    assert!(frames < 1024 / 8, "stopped before the cap");
    // Still deterministic whatever the thread count.
    let image = r.image().clone();
    let mut one = Renderer::with_default_scene(settings).with_threads(1).unwrap();
    while !one.converged() {
        one.run_frame().unwrap();
    }
    assert_eq!(one.image(), &image);
}

#[test]
fn pixels_that_miss_cost_one_ray() {
    // Looking up at the empty sky, with two occluders and a light in the scene: every sample
    // traces its camera ray and nothing else.
    let mut r = floor_scene(2, Some((PointLight::default(), Vec3::new(0.0, 3.0, 0.0))));
    let mut cams = r.world_mut().query::<&mut Camera>();
    *cams.single_mut(r.world_mut()).unwrap() =
        Camera::look_at(Vec3::new(0.0, 3.0, 3.0), Vec3::new(0.0, 30.0, 3.5), 60.0);
    let stats = r.run_frame().unwrap();
    assert_eq!(stats.rays.primary, 16 * 16 * 2);
    assert_eq!(stats.rays.total(), stats.rays.primary, "{:?}", stats.rays);
}
