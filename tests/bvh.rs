//! BVH traversal against brute force on random rays (closest hits and occlusion).

use bevy_ecs::entity::Entity;
use glam::{Vec3, Vec3A};
use hemi::{
    components::{Matte, Mesh, Plane, Transform},
    geometry::{Object, Prim, Ray, RayOrder, SceneGeometry, Shape, SurfaceHit, shapes::SpherePrim, world_space},
    random::SplitMix64,
    scene::mesh_gen::{torus_knot, uv_sphere},
};

fn random_unit(rng: &mut SplitMix64) -> Vec3A {
    loop {
        let v = Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.0 - 1.0;
        if v.length_squared() > 1e-4 && v.length_squared() <= 1.0 {
            return v.normalize();
        }
    }
}

/// Meshes and spheres scattered in a 10-unit box, with planes outside the BVH.
fn scene() -> SceneGeometry {
    let mut rng = SplitMix64::new(1);
    let mut prims = Vec::new();
    let mut objects = Vec::new();
    let meshes = [uv_sphere(0.7, 10, 20), torus_knot(2, 3, 0.8, 0.15, 120, 10)];
    for i in 0..40u32 {
        let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0 - 5.0;
        if i % 3 == 0 {
            prims.push(Prim {
                shape: Shape::Sphere(SpherePrim { center: p.into(), radius: 0.2 + rng.next_f32() }),
                object: i,
            });
        } else {
            let t = Transform::from_translation(p);
            prims.extend(world_space::mesh(&meshes[i as usize % 2], &t, i).unwrap().prims);
        }
        objects.push(Object { entity: Entity::PLACEHOLDER, material: Matte::default() });
    }
    let planes = vec![world_space::plane(&Default::default(), &Transform::from_xyz(0.0, -6.0, 0.0), 40).unwrap()];
    objects.push(Object { entity: Entity::PLACEHOLDER, material: Matte::default() });
    SceneGeometry::build(prims, planes, objects)
}

#[test]
fn closest_hits_match_brute_force() {
    let geometry = scene();
    assert!(geometry.node_count() > 100);
    let mut rng = SplitMix64::new(2);
    let mut stack = Vec::new();
    let mut hits = 0;
    for _ in 0..6_000 {
        let origin = (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0) - 7.0;
        let ray = Ray::new(origin, random_unit(&mut rng), f32::INFINITY);
        let fast = geometry.intersect(&ray, &mut stack);
        let slow = geometry.intersect_brute_force(&ray);
        match (fast, slow) {
            (None, None) => {}
            (Some(a), Some(b)) => {
                hits += 1;
                assert_eq!(a.t, b.t, "different closest t");
                assert_eq!(a.object, b.object);
            }
            (a, b) => panic!("BVH {a:?} vs brute force {b:?}"),
        }
    }
    assert!(hits > 1_500, "rays should hit often ({hits})");
}

#[test]
fn occlusion_matches_brute_force_for_segments() {
    let geometry = scene();
    let mut rng = SplitMix64::new(3);
    let mut stack = Vec::new();
    let (mut blocked, mut free) = (0, 0);
    for _ in 0..6_000 {
        let origin = (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 14.0) - 7.0;
        let ray = Ray::new(origin, random_unit(&mut rng), rng.next_f32() * 8.0);
        let expected = geometry.intersect_brute_force(&ray).is_some();
        assert_eq!(geometry.occluded(&ray, &mut stack), expected);
        if expected { blocked += 1 } else { free += 1 }
    }
    assert!(blocked > 600 && free > 600, "{blocked} blocked, {free} free");
}

#[test]
fn long_thin_triangles_give_the_brute_force_hits() {
    // Two long triangles among many small ones, their boxes far from tight: hits must still be
    // exactly the brute-force ones.
    let mut prims = world_space::mesh(&torus_knot(2, 3, 0.8, 0.15, 200, 12), &Transform::IDENTITY, 0).unwrap().prims;
    // A long thin beam along the diagonal of x and z: its boxes are far from tight.
    let beam = Mesh {
        positions: vec![
            Vec3::new(-6.0, -2.0, -6.0),
            Vec3::new(6.0, -1.0, 6.0),
            Vec3::new(6.5, -1.0, 5.5),
            Vec3::new(-5.5, -2.0, -6.5),
        ],
        indices: vec![[0, 1, 2], [0, 2, 3]],
    };
    prims.extend(world_space::mesh(&beam, &Transform::IDENTITY, 1).unwrap().prims);
    let object = Object { entity: Entity::PLACEHOLDER, material: Matte::default() };
    let geometry = SceneGeometry::build(prims, vec![], vec![object; 2]);
    assert_eq!(geometry.prim_count(), 200 * 12 * 2 + 2);
    let mut rng = SplitMix64::new(4);
    let mut stack = Vec::new();
    let (mut hits, mut blocked) = (0, 0);
    for i in 0..6_000 {
        let origin = (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0) - 4.0;
        let tmax = if i % 2 == 0 { f32::INFINITY } else { rng.next_f32() * 6.0 };
        // Every other ray aims at a point of the beam.
        let dir = if i % 4 < 2 {
            random_unit(&mut rng)
        } else {
            let target = Vec3A::new(-6.0, -2.0, -6.0) + Vec3A::new(12.0, 1.0, 12.0) * rng.next_f32();
            (target + Vec3A::new(0.5, 0.0, -0.5) * rng.next_f32() - origin).normalize()
        };
        let ray = Ray::new(origin, dir, tmax);
        let slow = geometry.intersect_brute_force(&ray);
        assert_eq!(geometry.intersect(&ray, &mut stack).map(|h| (h.t, h.object)), slow.map(|h| (h.t, h.object)));
        assert_eq!(geometry.occluded(&ray, &mut stack), slow.is_some());
        hits += usize::from(slow.is_some_and(|h| h.object == 1));
        blocked += usize::from(slow.is_some());
    }
    assert!(hits > 1_000 && blocked < 5_500, "{hits} hits on the beam, {blocked} blocked");
}

#[test]
fn axis_parallel_rays_and_rays_in_slab_planes_are_handled() {
    // Directions with zero components, from origins exactly on box faces: the slab test must
    // neither produce NaN nor cull real hits.
    let mesh = uv_sphere(1.0, 8, 16);
    let prims = world_space::mesh(&mesh, &Transform::IDENTITY, 0).unwrap().prims;
    let geometry =
        SceneGeometry::build(prims, vec![], vec![Object { entity: Entity::PLACEHOLDER, material: Matte::default() }]);
    let mut stack = Vec::new();
    for dir in [Vec3A::X, Vec3A::NEG_X, Vec3A::Y, Vec3A::NEG_Y, Vec3A::Z, Vec3A::NEG_Z] {
        for origin in [Vec3A::ZERO, -dir * 3.0, Vec3A::new(1.0, 0.0, 0.0), Vec3A::new(0.0, 1.0, 0.0)] {
            let ray = Ray::new(origin, dir, f32::INFINITY);
            let a = geometry.intersect(&ray, &mut stack).map(|h| h.t);
            let b = geometry.intersect_brute_force(&ray).map(|h| h.t);
            // These rays pass exactly through mesh vertices, where several triangles tie to
            // within an ULP; the hit must be found, at the same distance up to that tie.
            match (a, b) {
                (Some(a), Some(b)) => assert!((a - b).abs() <= 1e-6 * b, "origin {origin} dir {dir}: {a} vs {b}"),
                (a, b) => assert_eq!(a, b, "origin {origin} dir {dir}"),
            }
        }
    }
}

#[test]
fn a_batch_of_occlusion_queries_answers_as_single_queries_do() {
    use std::sync::Arc;

    use glam::{Affine3A, Quat};
    use hemi::geometry::accel::{Blas, Instance};
    // One world-space BLAS with a plane, and twelve rotated, scaled instances of a torus knot.
    let baked = scene();
    let blas = Arc::new(Blas::from_mesh(&torus_knot(2, 3, 0.8, 0.15, 120, 10)));
    let mut rng = SplitMix64::new(11);
    let instances = (0..12)
        .map(|i| {
            let p = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 8.0 - 4.0;
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.5 + rng.next_f32()),
                Quat::from_rotation_y(i as f32),
                p,
            );
            Instance::new(0, blas.bounds().unwrap(), m, Some(0)).unwrap()
        })
        .collect();
    let object = Object { entity: Entity::PLACEHOLDER, material: Matte::default() };
    let instanced = SceneGeometry::from_instances(vec![blas], instances, vec![], vec![object]);
    let mut stack = Vec::new();
    for geometry in [&baked, &instanced] {
        let rays: Vec<Ray> = (0..3_000)
            .map(|i| {
                let origin = (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 12.0) - 6.0;
                let tmax = if i % 2 == 0 { f32::INFINITY } else { rng.next_f32() * 6.0 };
                Ray::new(origin, random_unit(&mut rng), tmax)
            })
            .collect();
        let single: Vec<bool> = rays.iter().map(|r| geometry.occluded(r, &mut stack)).collect();
        let truth: Vec<bool> = rays.iter().map(|r| geometry.intersect_brute_force(r).is_some()).collect();
        let mut batch = vec![false; rays.len()];
        geometry.occluded_many(&rays, RayOrder::Mixed, &mut stack, &mut batch);
        assert_eq!(batch, truth);
        assert_eq!(single, truth);
        let blocked = single.iter().filter(|&&b| b).count();
        assert!(blocked > 150 && blocked < 2_850, "{blocked} of 3000 blocked");
    }
}

/// A pixel's AO rays leave one surface point together: `occluded_many` traces such runs in
/// packets (eight-wide trees over triangles), and each ray must get exactly the brute-force
/// answer. The scene is all triangles (packets apply) plus a plane (rays it blocks are never
/// traced); runs start on the meshes and the ground, with short and unbounded rays, rays at
/// grid vertices (zero edge functions) and rays parallel to an axis.
#[test]
fn runs_from_surface_points_match_brute_force() {
    let mut rng = SplitMix64::new(31);
    for geometry in &surface_scenes(Vec3::ZERO) {
        runs_match_brute_force(geometry, Vec3::ZERO, &mut rng, false);
    }
}

/// Runs of bounded rays (as AO rays with a `max_distance`), many ending exactly at, just
/// before or just past the surface they point at: packets of such rays start their traversal
/// below the root, at the node their segments lead to, and must still get the brute-force
/// answers, near the origin and 3·10⁴ from it.
#[test]
fn bounded_runs_ending_at_surfaces_match_brute_force() {
    let mut rng = SplitMix64::new(37);
    for offset in [Vec3::ZERO, Vec3::new(3.0e4, 0.0, -2.0e4)] {
        for geometry in &surface_scenes(offset) {
            runs_match_brute_force(geometry, offset, &mut rng, true);
        }
    }
}

/// A sphere, a torus knot and a ground of unit squares (two triangles each) at y = 0, moved
/// by `offset`, plus a wall plane: baked into one world-space BLAS, and as instances.
fn surface_scenes(offset: Vec3) -> [SceneGeometry; 2] {
    use std::sync::Arc;

    use glam::{Affine3A, Quat};
    use hemi::geometry::accel::{Blas, Instance};

    let n = 8;
    let ground = Mesh {
        positions: (0..=n).flat_map(|z| (0..=n).map(move |x| Vec3::new(x as f32 - 4.0, 0.0, z as f32 - 4.0))).collect(),
        indices: (0..n)
            .flat_map(|z| {
                (0..n).flat_map(move |x| {
                    let i = z * (n + 1) + x;
                    [[i, i + n + 1, i + 1], [i + 1, i + n + 1, i + n + 2]]
                })
            })
            .collect(),
    };
    let meshes = [uv_sphere(1.0, 24, 48), torus_knot(2, 3, 0.8, 0.15, 200, 12), ground];
    let places = [
        Affine3A::from_translation(offset + Vec3::new(-1.25, 1.2, 0.0)),
        Affine3A::from_scale_rotation_translation(
            Vec3::splat(1.3),
            Quat::from_rotation_y(0.7),
            offset + Vec3::new(1.25, 1.2, 0.0),
        ),
        Affine3A::from_translation(offset),
    ];
    let wall = || {
        let at = Transform::from_translation(offset + Vec3::new(0.0, 0.0, -3.0));
        vec![world_space::plane(&Plane { normal: Vec3::Z }, &at, 3).unwrap()]
    };
    let objects = vec![Object { entity: Entity::PLACEHOLDER, material: Matte::default() }; 4];
    let mut prims = Vec::new();
    for (i, (mesh, m)) in meshes.iter().zip(&places).enumerate() {
        prims.extend(world_space::mesh(mesh, &Transform::from_affine(m), i as u32).unwrap().prims);
    }
    let baked = SceneGeometry::build(prims, wall(), objects.clone());
    let blases: Vec<Arc<Blas>> = meshes.iter().map(|m| Arc::new(Blas::from_mesh(m))).collect();
    let instances = (0..3)
        .map(|i| Instance::new(i as u32, blases[i].bounds().unwrap(), places[i], Some(i as u32)).unwrap())
        .collect();
    [baked, SceneGeometry::from_instances(blases, instances, wall(), objects)]
}

/// 300 runs (100 if `bounded`) of 64 rays (some 13) from surface points of a scene moved by
/// `offset`, traced by `occluded_many` in both orders and one by one, against brute force.
/// Unbounded rays, and every fourth short, unless `bounded`: then every ray ends near what it
/// points at (exactly at it, one step before or past, at half or twice its distance) or,
/// pointing at nothing, within 3.
fn runs_match_brute_force(geometry: &SceneGeometry, offset: Vec3, rng: &mut SplitMix64, bounded: bool) {
    let offset = Vec3A::from(offset);
    let mut stack = Vec::new();
    let (mut blocked, mut total) = (0, 0);
    let runs = if bounded { 100 } else { 300 };
    for run in 0..runs {
        // A surface point: the first hit of a ray from above, then 64 directions around its
        // normal, some aimed at ground vertices, the last run short (a partial packet).
        let from = offset + Vec3A::new(rng.next_f32() * 8.0 - 4.0, 5.0, rng.next_f32() * 6.0 - 3.0);
        let Some(hit) = geometry.intersect(&Ray::new(from, Vec3A::new(0.1, -1.0, 0.05), f32::INFINITY), &mut stack)
        else {
            continue;
        };
        let count = if run % 10 == 9 { 13 } else { 64 };
        let rays: Vec<Ray> = (0..count)
            .map(|i| {
                let mut dir = random_unit(rng);
                if dir.dot(hit.normal) < 0.0 {
                    dir = -dir;
                }
                if i % 9 == 0 {
                    let vertex = offset
                        + Vec3A::new((rng.next_f32() * 8.0).floor() - 4.0, 0.0, (rng.next_f32() * 8.0).floor() - 4.0);
                    dir = (vertex - hit.p).normalize_or(hit.normal);
                }
                if i % 13 == 0 {
                    dir[i % 3] = 0.0;
                    dir = dir.normalize_or(hit.normal);
                }
                let origin = hit.spawn_origin(dir);
                let tmax = if !bounded {
                    if i % 4 == 0 { rng.next_f32() * 2.0 } else { f32::INFINITY }
                } else {
                    match geometry.intersect(&Ray::new(origin, dir, f32::INFINITY), &mut stack) {
                        Some(h) => [h.t, h.t.next_down(), h.t.next_up(), h.t * 0.5, h.t * 2.0][i % 5],
                        None => rng.next_f32() * 3.0,
                    }
                };
                Ray::new(origin, dir, tmax)
            })
            .collect();
        let truth: Vec<bool> = rays.iter().map(|r| geometry.intersect_brute_force(r).is_some()).collect();
        // Cut into packets either way (as given, or grouped by octant first).
        for order in [RayOrder::Mixed, RayOrder::Grouped] {
            let mut batch = vec![false; rays.len()];
            geometry.occluded_many(&rays, order, &mut stack, &mut batch);
            assert_eq!(batch, truth, "run {run}, {order:?}, offset {offset}");
        }
        let single: Vec<bool> = rays.iter().map(|r| geometry.occluded(r, &mut stack)).collect();
        assert_eq!(single, truth, "run {run}, offset {offset}");
        blocked += truth.iter().filter(|&&b| b).count();
        total += rays.len();
    }
    assert!(total > runs * 30 && blocked > total / 10 && blocked < total * 9 / 10, "{blocked} of {total} blocked");
}

/// A hit's t, point, error bound, normal, object, triangle and barycentrics, as bits for exact
/// comparisons.
type HitBits = (u32, [u32; 3], [u32; 3], [u32; 3], u32, u32, [u32; 2]);

/// The bits of a hit.
fn hit_bits(hit: &Option<SurfaceHit>) -> Option<HitBits> {
    let bits = |v: Vec3A| v.to_array().map(f32::to_bits);
    hit.map(|h| (h.t.to_bits(), bits(h.p), bits(h.p_error), bits(h.normal), h.object, h.prim, h.bary.map(f32::to_bits)))
}

#[test]
fn runs_of_camera_rays_get_the_hits_of_single_queries() {
    use std::sync::Arc;

    use glam::{Affine3A, Quat};
    use hemi::geometry::accel::{Blas, Instance};

    let mut rng = SplitMix64::new(5);
    let meshes = [uv_sphere(0.7, 10, 20), torus_knot(2, 3, 0.8, 0.15, 120, 10)];
    let matte = || Object { entity: Entity::PLACEHOLDER, material: Matte::default() };
    let plane = || vec![world_space::plane(&Default::default(), &Transform::from_xyz(0.0, -6.0, 0.0), 30).unwrap()];
    // Thirty meshes in world space, their triangle corners, and one BLAS each.
    let (mut vertices, mut pieces) = (Vec::new(), Vec::new());
    for i in 0..30u32 {
        let t = Transform::from_translation(Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0 - 5.0);
        let prims = world_space::mesh(&meshes[i as usize % 2], &t, i).unwrap().prims;
        for p in &prims {
            if let Shape::Triangle(tri) = p.shape {
                vertices.extend(tri.p);
            }
        }
        pieces.push(prims);
    }
    // Two halves of a ground grid at y = −5.5 that meet along x = 0: rays at a seam vertex hit
    // both halves at one distance.
    let n = 6;
    let half = |x0: i32| Mesh {
        positions: (0..=n)
            .flat_map(|z| (0..=n).map(move |x| Vec3::new((x0 + x) as f32, -5.5, z as f32 - 3.0)))
            .collect(),
        indices: (0..n as u32)
            .flat_map(|z| {
                (0..n as u32).flat_map(move |x| {
                    let i = z * (n as u32 + 1) + x;
                    [[i, i + n as u32 + 1, i + 1], [i + 1, i + n as u32 + 1, i + n as u32 + 2]]
                })
            })
            .collect(),
    };
    for (k, x0) in [-n, 0].into_iter().enumerate() {
        pieces.push(world_space::mesh(&half(x0), &Transform::default(), 30 + k as u32).unwrap().prims);
    }
    let seam: Vec<Vec3A> = (0..=n).map(|z| Vec3A::new(0.0, -5.5, z as f32 - 3.0)).collect();
    // Baked into one BLAS of triangles (a static scene: packets straight into it).
    let baked = SceneGeometry::build(pieces.concat(), plane(), (0..33).map(|_| matte()).collect());
    // The same without the plane: every hit on a triangle packet.
    let baked_alone = SceneGeometry::build(pieces.concat(), Vec::new(), (0..33).map(|_| matte()).collect());
    // As world-space instances under a top level, with a BLAS of spheres (traced ray by ray);
    // and once more with a rotated, scaled instance besides (entered lane by lane in its frame).
    let mut blases: Vec<Arc<Blas>> = pieces.into_iter().map(|p| Arc::new(Blas::build(p))).collect();
    let spheres = (0..6)
        .map(|i| Prim {
            shape: Shape::Sphere(SpherePrim {
                center: (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 10.0) - 5.0,
                radius: 0.3 + rng.next_f32(),
            }),
            object: 32 + i,
        })
        .collect();
    blases.push(Arc::new(Blas::build(spheres)));
    blases.push(Arc::new(Blas::from_mesh(&meshes[1])));
    let mut instances: Vec<Instance> = (0..33)
        .map(|b| Instance::new(b, blases[b as usize].bounds().unwrap(), Affine3A::IDENTITY, None).unwrap())
        .collect();
    let objects = || (0..40).map(|_| matte()).collect();
    let world = SceneGeometry::from_instances(blases.clone(), instances.clone(), plane(), objects());
    let m = Affine3A::from_scale_rotation_translation(
        Vec3::splat(1.5),
        Quat::from_rotation_y(0.6),
        Vec3::new(1.0, 2.0, 0.5),
    );
    instances.push(Instance::new(33, blases[33].bounds().unwrap(), m, Some(38)).unwrap());
    let transformed = SceneGeometry::from_instances(blases.clone(), instances.clone(), plane(), objects());
    // And copies of the ground's halves placed over the right half: the left half moved by n,
    // and the right half turned half a turn about its middle (onto its own triangles, but for
    // the rounding of the turn): their hits there lie at or within rounding of the right
    // half's own, ties that only a ray traced alone settles.
    let moved = Affine3A::from_translation(Vec3::new(n as f32, 0.0, 0.0));
    let turned =
        Affine3A::from_rotation_translation(Quat::from_rotation_y(std::f32::consts::PI), Vec3::new(n as f32, 0.0, 0.0));
    instances.push(Instance::new(30, blases[30].bounds().unwrap(), moved, Some(39)).unwrap());
    instances.push(Instance::new(31, blases[31].bounds().unwrap(), turned, Some(39)).unwrap());
    let coincident = SceneGeometry::from_instances(blases, instances, plane(), objects());
    for geometry in [&baked, &baked_alone, &world, &transformed, &coincident] {
        bundles_get_single_hits(geometry, &vertices, &seam, &mut rng);
    }
}

/// Checks `intersect_many` against `intersect` on bundles of nearly parallel rays from one
/// point (a pixel's worth), every third aimed exactly at one of `vertices` (hits at a shared
/// vertex or edge, on several triangles at one distance), every fifth with finite segments.
/// Every sixth spreads wide with its second ray exact at a `seam` vertex (two BLASes hit at one
/// distance), so that one exact ray, not the packet's first, can reach a mesh alone.
fn bundles_get_single_hits(geometry: &SceneGeometry, vertices: &[Vec3A], seam: &[Vec3A], rng: &mut SplitMix64) {
    let mut stack = Vec::new();
    let (mut hits, mut rays_traced) = (0, 0);
    for bundle in 0..900 {
        let origin = (Vec3A::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 16.0) - 8.0;
        let pick = |list: &[Vec3A], u: f32| list[(u * list.len() as f32) as usize % list.len()];
        let wide = bundle % 6 == 3;
        let aim = match bundle % 3 {
            _ if wide => pick(seam, rng.next_f32()),
            0 => pick(vertices, rng.next_f32()),
            _ => origin + random_unit(rng) * 10.0,
        };
        let count = [16, 37, 8, 5][bundle % 4];
        let rays: Vec<Ray> = (0..count)
            .map(|k| {
                let exact = if wide { k == 1 } else { k % 4 == 0 };
                let jitter = if exact { Vec3A::ZERO } else { random_unit(rng) * if wide { 2.0 } else { 2e-3 } };
                let tmax = if bundle % 5 == 0 { rng.next_f32() * 12.0 } else { f32::INFINITY };
                Ray::new(origin, aim - origin + jitter, tmax)
            })
            .collect();
        let mut many = vec![None; count];
        geometry.intersect_many(&rays, &mut stack, &mut many, |_, hit| hit);
        for (ray, hit) in rays.iter().zip(&many) {
            let single = geometry.intersect(ray, &mut stack);
            assert_eq!(hit_bits(hit), hit_bits(&single), "bundle {bundle}, ray {ray:?}");
            hits += usize::from(single.is_some());
            rays_traced += 1;
        }
    }
    assert!(hits > rays_traced / 3, "{hits} of {rays_traced} rays hit");
}

/// A room of large triangles (a floor, two walls, long beams across it) around two meshes: its
/// BLAS is built with spatial splits, which put the large triangles in several leaves each, and
/// single rays, packets of occlusion rays from surface points and bundles of camera rays must
/// still get exactly the brute-force answers, rays at the room's vertices and along its edges
/// included.
#[test]
fn spatially_split_triangles_give_the_brute_force_answers() {
    let mut rng = SplitMix64::new(41);
    let v = Vec3::new;
    let mut room = Mesh {
        positions: vec![
            v(-8.0, 0.0, -6.0),
            v(8.0, 0.0, -6.0),
            v(8.0, 0.0, 6.0),
            v(-8.0, 0.0, 6.0),
            v(-8.0, 8.0, -6.0),
            v(8.0, 8.0, -6.0),
            v(-8.0, 8.0, 6.0),
        ],
        indices: vec![[0, 2, 1], [0, 3, 2], [0, 1, 5], [0, 5, 4], [0, 4, 6], [0, 6, 3]],
    };
    // Enough beams that spatial splits are tried among them (from 512 triangles a node).
    for k in 0..600 {
        let (y, s) = (0.3 + k as f32 * 0.006, rng.next_f32() * 2.0 - 1.0);
        let first = room.positions.len() as u32;
        room.positions.extend([v(-7.6, y, -5.6 * s), v(7.6, y + 0.2, 5.6 * s), v(7.6, y + 0.35, 5.6 * s + 0.3)]);
        room.indices.push([first, first + 1, first + 2]);
    }
    let mut prims = world_space::mesh(&room, &Transform::IDENTITY, 0).unwrap().prims;
    let room_triangles: Vec<[Vec3A; 3]> =
        room.indices.iter().map(|t| t.map(|i| Vec3A::from(room.positions[i as usize]))).collect();
    for (i, mesh) in [uv_sphere(0.8, 16, 32), torus_knot(2, 3, 0.6, 0.12, 120, 8)].iter().enumerate() {
        let t = Transform::from_xyz(if i == 0 { -1.5 } else { 1.5 }, 1.2, 0.0);
        prims.extend(world_space::mesh(mesh, &t, i as u32 + 1).unwrap().prims);
    }
    let triangles = prims.len();
    let objects = vec![Object { entity: Entity::PLACEHOLDER, material: Matte::default() }; 3];
    let geometry = SceneGeometry::build(prims, vec![], objects);
    assert!(geometry.prim_count() > triangles, "spatial splits were made");
    assert_eq!(geometry.world_prims().len(), triangles, "each triangle listed once");

    let mut stack = Vec::new();
    let (mut on_room, mut blocked) = (0, 0);
    for i in 0..6_000 {
        let origin = Vec3A::new(rng.next_f32() * 7.6 - 3.8, rng.next_f32() * 3.8 + 0.1, rng.next_f32() * 5.6 - 2.8);
        // Every other ray aims at a vertex or an edge point of a room triangle.
        let dir = if i % 2 == 0 {
            random_unit(&mut rng)
        } else {
            let [a, b, c] = room_triangles[(rng.next_u64() % room_triangles.len() as u64) as usize];
            let target = match i % 6 {
                1 => [a, b, c][i % 3],
                3 => a + (b - a) * rng.next_f32(),
                _ => c + (a - c) * rng.next_f32(),
            };
            (target - origin).normalize_or(Vec3A::Y)
        };
        let tmax = if i % 3 == 0 { rng.next_f32() * 3.0 } else { f32::INFINITY };
        let ray = Ray::new(origin, dir, tmax);
        let slow = geometry.intersect_brute_force(&ray);
        assert_eq!(
            geometry.intersect(&ray, &mut stack).map(|h| (h.t, h.object)),
            slow.map(|h| (h.t, h.object)),
            "ray {i}"
        );
        assert_eq!(geometry.occluded(&ray, &mut stack), slow.is_some(), "ray {i}");
        on_room += usize::from(slow.is_some_and(|h| h.object == 0));
        blocked += usize::from(slow.is_some());
    }
    assert!(on_room > 2_000 && blocked < 5_900, "{on_room} on the room, {blocked} blocked");
    runs_match_brute_force(&geometry, Vec3::ZERO, &mut rng, false);
    runs_match_brute_force(&geometry, Vec3::ZERO, &mut rng, true);
    let vertices: Vec<Vec3A> = room_triangles.iter().flatten().copied().collect();
    bundles_get_single_hits(&geometry, &vertices, &vertices[..6], &mut rng);
}

/// Thousands of instances at one position (a crowd placed by copying one node, or
/// EXT_mesh_gpu_instancing without offsets) build a top level of logarithmic depth, half a
/// cluster per level, and every ray still gets the brute-force answer: the nearest copy of
/// the cluster and the lone sphere off to the side.
#[test]
fn co_located_instances_build_a_shallow_top_level() {
    use glam::Affine3A;
    use hemi::geometry::accel::{Blas, Instance};
    use std::sync::Arc;

    let sphere = Prim { shape: Shape::Sphere(SpherePrim { center: Vec3A::ZERO, radius: 0.5 }), object: 0 };
    let blas = Arc::new(Blas::build(vec![sphere]));
    let local = blas.bounds().unwrap();
    let n = 20_000;
    let mut instances: Vec<Instance> = (0..n)
        .map(|_| Instance::new(0, local, Affine3A::from_translation(Vec3::new(0.0, 0.0, 0.0)), Some(0)).unwrap())
        .collect();
    instances.push(Instance::new(0, local, Affine3A::from_translation(Vec3::new(3.0, 0.0, 0.0)), Some(0)).unwrap());
    let objects = vec![Object { material: Matte::default(), entity: Entity::PLACEHOLDER }];
    let geometry = SceneGeometry::from_instances(vec![blas], instances, Vec::new(), objects);
    let balanced = (n as f64).log2().ceil() as usize + 2;
    assert!(geometry.depth <= 2 * balanced, "top level {} deep for {n} co-located instances", geometry.depth);
    let mut stack = Vec::new();
    for (origin, expected) in [(Vec3A::new(0.0, 0.0, 5.0), Some(4.5)), (Vec3A::new(3.0, 0.0, 5.0), Some(4.5))] {
        let ray = Ray::new(origin, Vec3A::NEG_Z, f32::INFINITY);
        let hit = geometry.intersect(&ray, &mut stack).map(|h| (h.p - origin).length());
        assert_eq!(hit.map(|t| (t * 1e3).round() / 1e3), expected);
    }
}
