//! Watertightness in the spirit of Embree's verify tool: rays must not slip between triangles
//! that share an edge or a vertex. Miss rates must stay at or below 0.002 %.

use std::{collections::HashMap, path::PathBuf};

use glam::{Quat, Vec3, Vec3A};
use hemi::{
    components::{Matte, Mesh, Transform},
    geometry::{Object, Ray, SceneGeometry, world_space},
    prelude::Entity,
    random::SplitMix64,
    scene::mesh_gen::uv_sphere,
};

const MAX_MISS_RATE: f64 = 0.002 / 100.0;

fn geometry(mesh: &Mesh, transform: &Transform) -> SceneGeometry {
    let prims = world_space::mesh(mesh, transform, 0).unwrap().prims;
    SceneGeometry::build(prims, vec![], vec![Object { entity: Entity::PLACEHOLDER, material: Matte::default() }])
}

fn random_unit(rng: &mut SplitMix64) -> Vec3A {
    loop {
        let v = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

/// Closed tessellated spheres, placed by several transforms: random rays from inside must all
/// hit (Embree's `WatertightTest`).
#[test]
fn rays_from_inside_closed_spheres_always_hit() {
    let transforms = [
        Transform::IDENTITY,
        Transform::from_xyz(1e3, -2e3, 5e2).with_rotation(Quat::from_rotation_y(0.7)).with_scale(30.0),
        Transform::from_xyz(-3.0, 0.5, 2.0).with_scale(1e-3),
    ];
    let mut rng = SplitMix64::new(11);
    for mesh in [uv_sphere(1.0, 32, 64), uv_sphere(1.0, 7, 9)] {
        for t in &transforms {
            let geometry = geometry(&mesh, t);
            let m = t.to_affine().unwrap();
            let (mut misses, n) = (0u32, 60_000u32);
            let mut stack = Vec::new();
            for i in 0..n {
                // Origins at the centre, and at random points well inside.
                let local = if i % 2 == 0 { Vec3A::ZERO } else { random_unit(&mut rng) * 0.5 * rng.next_f32() };
                let ray = Ray::new(m.transform_point3a(local), random_unit(&mut rng), f32::INFINITY);
                misses += u32::from(geometry.intersect(&ray, &mut stack).is_none());
            }
            // And from the centre exactly at every vertex and at points of every edge.
            let centre = m.transform_point3a(Vec3A::ZERO);
            let world: Vec<Vec3A> = mesh.positions.iter().map(|&p| m.transform_point3a(p.into())).collect();
            let mut aimed = 0u32;
            for tri in &mesh.indices {
                for k in 0..3 {
                    let (a, b) = (world[tri[k] as usize], world[tri[(k + 1) % 3] as usize]);
                    for target in [a, a.lerp(b, rng.next_f32())] {
                        aimed += 1;
                        // Inside a closed mesh any hit will do (f32 perturbs the aimed direction).
                        let ray = Ray::new(centre, target - centre, f32::INFINITY);
                        misses += u32::from(geometry.intersect(&ray, &mut stack).is_none());
                    }
                }
            }
            let rate = misses as f64 / (n + aimed) as f64;
            assert!(rate <= MAX_MISS_RATE, "{misses} of {} rays escaped a closed sphere under {t:?}", n + aimed);
        }
    }
}

/// Where the ray meets the plane of a triangle, in f64.
fn plane_t_f64(ray: &Ray, [a, b, c]: [Vec3A; 3]) -> f64 {
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
    let n = (b - a).cross(c - a);
    n.dot(a - o) / n.dot(d)
}

/// Reads the vertex positions and triangles of an ASCII PLY file.
fn read_ascii_ply(path: &PathBuf) -> Mesh {
    let text = std::fs::read_to_string(path)
        .unwrap_or_else(|e| panic!("{}: {e} (../shared must sit beside the repo)", path.display()));
    let mut lines = text.lines();
    let (mut vertices, mut faces) = (0usize, 0usize);
    for line in lines.by_ref() {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["element", "vertex", n] => vertices = n.parse().unwrap(),
            ["element", "face", n] => faces = n.parse().unwrap(),
            ["end_header"] => break,
            _ => {}
        }
    }
    let number = |w: &str| w.parse::<f32>().unwrap();
    let positions = lines.by_ref().take(vertices).map(|l| {
        let w: Vec<f32> = l.split_whitespace().take(3).map(number).collect();
        Vec3::new(w[0], w[1], w[2])
    });
    let positions: Vec<Vec3> = positions.collect();
    let indices = lines.take(faces).map(|l| {
        let w: Vec<u32> = l.split_whitespace().skip(1).map(|x| x.parse().unwrap()).collect();
        [w[0], w[1], w[2]]
    });
    Mesh { positions, indices: indices.collect() }
}

/// The Stanford bunny (the original scan, open at its base): rays aimed at points of edges
/// shared by two triangles must hit the mesh no later than where they cross those triangles:
/// no cracks along shared edges, under any transform.
#[test]
fn bunny_has_no_cracks_along_shared_edges() {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/assets/StanfordBunny/bun_zipper.ply");
    let mesh = read_ascii_ply(&path);
    assert_eq!(mesh.triangle_count(), 69_451, "SOURCES.md's triangle count");
    for t in [
        Transform::IDENTITY,
        Transform::from_xyz(300.0, -120.0, 40.0).with_rotation(Quat::from_rotation_z(0.4)).with_scale(17.0),
    ] {
        let geometry = geometry(&mesh, &t);
        let m = t.to_affine().unwrap();
        let world: Vec<Vec3A> = mesh.positions.iter().map(|&p| m.transform_point3a(p.into())).collect();
        // Each edge with the third vertices of the triangles using it.
        let mut uses: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
        for tri in &mesh.indices {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                uses.entry((a.min(b), a.max(b))).or_default().push(tri[(k + 2) % 3]);
            }
        }
        let mut shared: Vec<((u32, u32), [u32; 2])> =
            uses.into_iter().filter(|(_, c)| c.len() == 2).map(|(e, c)| (e, [c[0], c[1]])).collect();
        shared.sort_unstable();
        let centroid = world.iter().copied().sum::<Vec3A>() / world.len() as f32;
        let mut rng = SplitMix64::new(3);
        let mut stack = Vec::new();
        let (mut misses, mut n) = (0u32, 0u32);
        for &((a, b), [c1, c2]) in &shared {
            let (pa, pb) = (world[a as usize], world[b as usize]);
            let target = pa.lerp(pb, 0.05 + 0.9 * rng.next_f32());
            // From the centroid and from a random point around the model.
            for origin in [centroid, centroid + random_unit(&mut rng) * (target - centroid).length() * 2.0] {
                // Only edges whose two triangles clearly lie on opposite sides of the plane
                // through the origin and the edge: then they cover a neighbourhood of the edge
                // and any ray through it must hit one. (At silhouettes a ray rounded past the
                // edge rightly grazes by.)
                let m = (pa - origin).cross(pb - origin).normalize();
                let (d1, d2) = (world[c1 as usize] - origin, world[c2 as usize] - origin);
                let (s1, s2) = (m.dot(d1) / d1.length(), m.dot(d2) / d2.length());
                if s1 * s2 >= 0.0 || s1.abs().min(s2.abs()) < 1e-3 {
                    continue;
                }
                let ray = Ray::new(origin, target - origin, f32::INFINITY);
                // The f32 ray crosses one of the two triangles no later than the farther of
                // their planes (computed in f64 for the ray as actually stored).
                let t_planes = [c1, c2].map(|c| plane_t_f64(&ray, [pa, pb, world[c as usize]]));
                let t_max = t_planes[0].max(t_planes[1]) * (1.0 + 1e-6);
                n += 1;
                misses += u32::from(geometry.intersect(&ray.with_tmax(t_max as f32), &mut stack).is_none());
            }
        }
        let rate = misses as f64 / n as f64;
        assert!(n > 100_000, "{n} rays");
        assert!(rate <= MAX_MISS_RATE, "{misses} of {n} edge-aimed rays slipped through (transform {t:?})");
    }
}
