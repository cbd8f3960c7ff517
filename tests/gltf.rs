//! glTF scenes from `../shared/assets`: every file loads with the documented triangle count,
//! transforms give outward normals, animation keys are met exactly, static sequences build the
//! BVH once, and animated sequences change only what moves, identically however they are split.

mod common;

use std::path::{Path, PathBuf};

use hemi::{
    animation::{Keys, NodeGraph},
    geometry::accel::{BvhWork, outward_normal},
    prelude::*,
    scene::gltf::{self, SpawnOptions},
};

/// The shared assets folder beside the checkout.
fn assets() -> PathBuf {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/assets");
    assert!(
        dir.join("SOURCES.md").is_file(),
        "shared test assets not found at {} (CI keeps ../shared beside the checkout)",
        dir.display()
    );
    dir
}

fn asset(rel: &str) -> PathBuf {
    assets().join(rel)
}

/// Expected placed-triangle counts from SOURCES.md: by folder (Khronos table, "scene" column)
/// and by folder/file (classic table, "tris" column).
fn documented_counts() -> Vec<(String, usize)> {
    let text = std::fs::read_to_string(asset("SOURCES.md")).unwrap();
    let number = |s: &str| -> Option<usize> {
        let digits: String = s.trim().trim_matches('*').split_whitespace().next()?.replace(',', "");
        digits.parse().ok()
    };
    let mut out = Vec::new();
    let mut khronos = false;
    for line in text.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 6 {
            continue;
        }
        let (name, rest) = (cells[1], &cells[2..]);
        if name == "name" {
            khronos = rest.get(3) == Some(&"scene");
            continue;
        }
        if khronos {
            if let Some(n) = number(rest[3]) {
                out.push((name.to_string(), n));
            }
        } else if let (Some((folder, _)), Some(n)) = (name.split_once('/'), number(rest[2])) {
            for file in name.split('`').filter(|f| f.ends_with(".glb") || f.ends_with(".gltf")) {
                out.push((format!("{folder}/{file}"), n));
            }
        }
    }
    out
}

fn gltf_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            gltf_files(&p, out);
        } else if p.extension().is_some_and(|e| e == "gltf" || e == "glb") {
            out.push(p);
        }
    }
}

#[test]
fn every_shared_gltf_loads_with_the_documented_triangle_count() {
    let root = assets();
    let counts = documented_counts();
    let mut files = Vec::new();
    gltf_files(&root, &mut files);
    assert!(files.len() >= 30, "found only {} glTF files", files.len());
    for file in files {
        let rel = file.strip_prefix(&root).unwrap();
        let folder = rel.components().next().unwrap().as_os_str().to_str().unwrap();
        let key = format!("{folder}/{}", file.file_name().unwrap().to_str().unwrap());
        let expected = counts
            .iter()
            .find(|(k, _)| *k == key)
            .or_else(|| counts.iter().find(|(k, _)| k == folder))
            .unwrap_or_else(|| panic!("{key} is not in SOURCES.md"))
            .1;
        let scene = gltf::load(&file).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(scene.scene_triangle_count(), expected, "{}", rel.display());
        let mut world = World::new();
        scene.spawn(&mut world, &SpawnOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        let spawned: usize = world.query::<&TriangleMesh>().iter(&world).map(|m| m.0.triangle_count()).sum();
        assert_eq!(spawned, expected, "{}: spawned triangles", rel.display());
    }
}

/// Σ area·n·(centroid − centre) over a closed mesh is 3× its volume: positive exactly when the
/// normals point outwards, whatever the mesh's shape.
/// Whether every edge (vertices welded by position) is shared by two oppositely wound triangles.
fn is_closed(mesh: &Mesh) -> bool {
    use std::collections::HashMap;
    let key = |i: u32| mesh.positions[i as usize].to_array().map(f32::to_bits);
    let mut edges: HashMap<([u32; 3], [u32; 3]), i32> = HashMap::new();
    for t in &mesh.indices {
        for k in 0..3 {
            *edges.entry((key(t[k]), key(t[(k + 1) % 3]))).or_default() += 1;
        }
    }
    edges.iter().all(|(&(a, b), &n)| edges.get(&(b, a)) == Some(&n))
}

fn outward_flux(mesh: &Mesh, m: &glam::Affine3A) -> f32 {
    let world: Vec<Vec3> = mesh.positions.iter().map(|&p| m.transform_point3(p)).collect();
    let centre = world.iter().copied().sum::<Vec3>() / world.len() as f32;
    (0..mesh.indices.len())
        .map(|i| {
            let [a, b, c] = mesh.indices[i].map(|k| world[k as usize]);
            let area = (b - a).cross(c - a).length() * 0.5;
            area * outward_normal(mesh, i, m).dot((a + b + c) / 3.0 - centre)
        })
        .sum()
}

#[test]
fn node_transforms_give_outward_normals_even_when_mirrored() {
    for file in
        ["OrientationTest/glTF-Binary/OrientationTest.glb", "NegativeScaleTest/glTF-Binary/NegativeScaleTest.glb"]
    {
        let scene = gltf::load(&asset(file)).unwrap();
        let mut world = World::new();
        scene.spawn(&mut world, &SpawnOptions::default()).unwrap();
        let (mut checked, mut mirrored) = (0, 0);
        for (mesh, t) in world.query::<(&TriangleMesh, &Transform)>().iter(&world) {
            if !is_closed(&mesh.0) {
                continue; // labels and backdrops have no inside
            }
            let m = t.to_affine().unwrap();
            mirrored += usize::from(m.matrix3.determinant() < 0.0);
            let flux = outward_flux(&mesh.0, &m);
            assert!(flux > 0.0, "{file}: inward normals (flux {flux}) under scale {}", t.scale);
            checked += 1;
        }
        assert!(checked >= 6, "{file}: only {checked} closed meshes");
        if file.starts_with("Negative") {
            assert!(mirrored >= 3, "NegativeScaleTest has mirrored closed instances");
        }
    }
}

#[test]
fn box_animated_poses_are_the_keyframes_exactly() {
    let scene = gltf::load(&asset("BoxAnimated/glTF-Binary/BoxAnimated.glb")).unwrap();
    let mut graph: NodeGraph = scene.graph.clone();
    graph.active = vec![0];
    let clip = &graph.clips[0];
    let mut keys_checked = 0;
    for ch in &clip.channels {
        for (k, &t) in ch.times.iter().enumerate() {
            let mut locals: Vec<Transform> = graph.nodes.iter().map(|n| n.rest).collect();
            clip.apply(t, &mut locals);
            match &ch.keys {
                Keys::Translation(v) => assert_eq!(locals[ch.node].translation, v[k], "t = {t}"),
                Keys::Rotation(q) => assert_eq!(locals[ch.node].rotation, q[k], "t = {t}"),
                Keys::Scale(v) => assert_eq!(locals[ch.node].scale, v[k], "t = {t}"),
                Keys::Weights { .. } => unreachable!("BoxAnimated has no morph targets"),
            }
            keys_checked += 1;
        }
    }
    assert_eq!(keys_checked, 6, "2 rotation + 4 translation keys");

    // Through the renderer: the moving box's entity sits at the keyed translation.
    let mut r = Renderer::new(common::settings(16, 16, 1, SamplerKind::Jittered));
    scene.spawn(r.world_mut(), &SpawnOptions::default()).unwrap();
    let ch = clip.channels.iter().find(|c| matches!(c.keys, Keys::Translation(_))).unwrap();
    let Keys::Translation(v) = &ch.keys else { unreachable!() };
    for (k, &t) in ch.times.iter().enumerate() {
        r.set_time(t).unwrap();
        r.run_frame().unwrap();
        let world = &r.world().resource::<NodeGraph>().world;
        let root_rotation = graph.nodes[ch.node].rest.rotation;
        assert!((world[ch.node].translation - glam::Vec3A::from(root_rotation * v[k])).length() < 1e-6);
    }
}

#[test]
fn static_scene_sequence_builds_the_bvh_once() {
    let scene = gltf::load(&asset("Duck/glTF-Binary/Duck.glb")).unwrap();
    let mut r = Renderer::new(common::settings(24, 16, 1, SamplerKind::Jittered));
    scene.spawn(r.world_mut(), &SpawnOptions::default()).unwrap();
    let (mut blas, mut tlas) = (0, 0);
    for frame in 0..4 {
        r.set_time(frame as f32 / 24.0).unwrap();
        let stats = r.run_frame().unwrap();
        blas += stats.bvh_work.blas_built + stats.bvh_work.blas_refit;
        tlas += usize::from(stats.bvh_work.tlas_built);
        assert_eq!(stats.spp, frame + 1, "a static scene keeps accumulating");
    }
    assert_eq!((blas, tlas), (1, 1), "one BLAS and one TLAS build for four frames");
}

/// BoxAnimated plus a static sphere far to the side whose AO cannot reach the boxes
/// (occluder max distance 2); a fixed camera sees both.
fn box_and_sphere() -> Renderer {
    let scene = gltf::load(&asset("BoxAnimated/glTF-Binary/BoxAnimated.glb")).unwrap();
    let mut r = Renderer::new(common::settings(96, 48, 4, SamplerKind::Jittered));
    let w = r.world_mut();
    w.spawn(AmbientOccluder { max_distance: 2.0, ..Default::default() });
    scene.spawn(w, &SpawnOptions::default()).unwrap();
    let cams: Vec<Entity> = w.query_filtered::<Entity, With<Camera>>().iter(w).collect();
    for c in cams {
        w.despawn(c);
    }
    w.spawn(Camera::look_at(Vec3::new(6.0, 1.0, 14.0), Vec3::new(6.0, 1.0, 0.0), 40.0));
    w.spawn((Sphere { radius: 1.5 }, Transform::from_xyz(12.0, 1.0, 0.0)));
    r
}

#[test]
fn animated_nodes_stay_instances_and_moving_them_rebuilds_only_the_top_level() {
    let mut r = box_and_sphere();
    r.run_frame().unwrap();
    let w = r.world_mut();
    let mut meshes: Vec<bool> =
        w.query_filtered::<hemi::bevy_ecs::query::Has<Dynamic>, With<TriangleMesh>>().iter(w).collect();
    meshes.sort();
    assert_eq!(meshes, [false, true], "one box hangs under an animated node, the other under none");
    r.set_time(0.5).unwrap();
    let stats = r.run_frame().unwrap();
    let top_level_only = hemi::geometry::accel::BvhWork { blas_built: 0, blas_refit: 0, tlas_built: true };
    assert_eq!(stats.bvh_work, top_level_only, "the static box stays baked, the moving one is an instance");
}

#[test]
fn animated_frames_change_where_things_move_and_nowhere_else() {
    let mut r = box_and_sphere();
    let mut frames = Vec::new();
    for frame in [0u32, 24, 48] {
        r.render_at(frame as f32 / 24.0, 8).unwrap();
        frames.push(r.image().linear.clone());
    }
    let width = 96;
    for pair in frames.windows(2) {
        let (a, b) = (&pair[0], &pair[1]);
        let changed: Vec<usize> = (0..a.len()).filter(|&i| a[i] != b[i]).collect();
        assert!(changed.len() > 10, "the boxes move: {} pixels changed", changed.len());
        // The sphere and everything right of column 72 (world x ≳ 9) never changes.
        assert!(changed.iter().all(|&i| i % width < 72), "a pixel away from the boxes changed");
        let static_lit = (0..a.len()).filter(|&i| i % width >= 72 && a[i] != Vec3::ZERO).count();
        assert!(static_lit > 20, "the static sphere is in view");
    }
    // Any frame rendered alone (as a shard would) is bit-identical to the sequence's.
    let mut alone = box_and_sphere();
    alone.render_at(48.0 / 24.0, 8).unwrap();
    assert_eq!(alone.image().linear, frames[2]);
}

#[test]
fn skinned_fox_deforms_and_only_refits_its_blas() {
    let scene = gltf::load(&asset("Fox/glTF-Binary/Fox.glb")).unwrap();
    let mut r = Renderer::new(common::settings(32, 24, 1, SamplerKind::Jittered));
    scene.spawn(r.world_mut(), &SpawnOptions { animation: Some("Run".into()), ..Default::default() }).unwrap();
    let first = r.run_frame().unwrap().bvh_work;
    assert_eq!(first.blas_built, 1, "the rest-pose tree is built once");
    let before = r.world_mut().query::<&TriangleMesh>().single(r.world()).unwrap().0.clone();
    for frame in 1..4 {
        r.set_time(frame as f32 / 24.0).unwrap();
        let stats = r.run_frame().unwrap();
        assert_eq!(stats.bvh_work, BvhWork { blas_built: 0, blas_refit: 1, tlas_built: true }, "frame {frame}");
        assert_eq!(stats.spp, 1, "accumulation restarts on every moved frame");
    }
    let after = r.world_mut().query::<&TriangleMesh>().single(r.world()).unwrap().0.clone();
    assert_eq!(after.indices, before.indices);
    assert_ne!(after.positions, before.positions, "the skin moved the vertices");
    // Unknown animation names are refused with the list of names.
    let mut w = World::new();
    let e = scene.spawn(&mut w, &SpawnOptions { animation: Some("Dance".into()), ..Default::default() });
    let e = e.unwrap_err().to_string();
    assert!(e.contains("no animation 'Dance'") && e.contains("Survey"), "{e}");
}

#[test]
fn point_lights_and_both_camera_kinds_are_spawned() {
    let scene = gltf::load(&asset("LightsPunctualLamp/glTF/LightsPunctualLamp.gltf")).unwrap();
    let mut world = World::new();
    scene.spawn(&mut world, &SpawnOptions::default()).unwrap();
    let mut ls: Vec<f32> = world.query::<&PointLight>().iter(&world).map(|l| l.ls).collect();
    ls.sort_by(f32::total_cmp);
    assert_eq!(ls, [1.5, 15.0, 80.0, 80.0, 180.0], "candela map to ls one to one");
    assert!(world.query::<&PointLight>().iter(&world).all(|l| l.falloff && l.shadows));
    assert_eq!(world.query::<&AmbientOccluder>().iter(&world).count(), 1, "a default occluder");

    let cameras = gltf::load(&asset("Cameras/glTF/Cameras.gltf")).unwrap();
    for (key, orthographic) in [("0", false), ("1", true)] {
        let mut r = Renderer::new(common::settings(16, 16, 2, SamplerKind::Jittered));
        cameras.spawn(r.world_mut(), &SpawnOptions { camera: Some(key.into()), ..Default::default() }).unwrap();
        let w = r.world_mut();
        assert_eq!(w.query::<&OrthographicCamera>().iter(w).count(), usize::from(orthographic));
        assert_eq!(w.query::<&Camera>().iter(w).count(), usize::from(!orthographic));
        let stats = r.run_frame().unwrap();
        assert!(stats.rays.ao > 0, "camera {key} sees the geometry");
    }
}
