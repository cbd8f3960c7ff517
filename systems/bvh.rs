//! Stage 2: keeps the two-level acceleration structure in step with the scene, doing only the
//! work that a change needs:
//!
//! - a new mesh (a `TriangleMesh` holding an `Arc<Mesh>` not seen before) builds its BLAS once,
//!   however many entities share it;
//! - a [`Deforming`] mesh whose vertices changed refits its BLAS (tree kept from the rest pose);
//! - a moved mesh instance only rebuilds the top-level BVH over the instances;
//! - static meshes used by one entity each (not [`Dynamic`], not deforming) are baked in world
//!   space into one BLAS, rebuilt when one of them changes (or which meshes qualify does);
//!   static meshes that several entities share are baked too where a jittered render's camera
//!   rays pay for the bake (`max_spp` × pixels at least 64 per triangle they place), and
//!   instanced otherwise;
//! - each sphere and cuboid is a small world-space BLAS, rebuilt when one of them changes;
//! - a textured mesh ([`Surface`]) is baked like any other, its triangles' indices kept for
//!   texture lookups; an alpha-tested one is never baked: it goes into the scene's alpha layer
//!   instead of the top level, traversed apart with a test at each candidate hit;
//! - a material change only updates the material table; an unchanged scene does nothing.

use std::{
    collections::{HashMap, HashSet},
    sync::Arc,
    time::Instant,
};

use bevy_ecs::{name::Name, prelude::*, system::SystemParam};

use crate::{
    components::{Cuboid, Deforming, Dynamic, Matte, Mesh, Plane, Sphere, Transform, TriangleMesh},
    geometry::{
        Object, SceneGeometry,
        accel::{AlphaLayer, AlphaMesh, Blas, BvhWork, Instance},
        shapes::PlanePrim,
        world_space,
    },
    material::{PlacedSurface, Surface},
    resources::{Accumulation, RenderSettings, SceneProblems, ShapeValueChanges},
    stats::FrameStats,
};

/// Camera rays per placed triangle (`max_spp` × pixels ÷ the triangles that baking the shared
/// meshes would place) from which a jittered render bakes those meshes rather than instancing
/// them: its camera rays, one per sample, trace the bake about a tenth faster than the placed
/// instances, which pays for the bake's build (and its memory) from about twice the break-even
/// of some 32 camera rays per triangle (docs/benchmarks.md, "BVH build"). Occlusion rays trace
/// placed instances as fast as the bake, so a render at pixel centres (one camera ray a pixel)
/// keeps them instanced.
const SHARED_BAKE_CAMERA_RAYS_PER_TRIANGLE: u64 = 64;

/// Most triangles baking the shared meshes may place (a baked triangle takes about 150 bytes of
/// tree and triangle data; instanced, it takes none).
const SHARED_BAKE_MAX_TRIANGLES: usize = 1 << 21;

type Shaped = Or<(With<Sphere>, With<Plane>, With<Cuboid>, With<TriangleMesh>)>;
type WorldShaped = Or<(With<Sphere>, With<Plane>, With<Cuboid>)>;
type GeometryChanged = Or<(
    Changed<Transform>,
    Changed<Sphere>,
    Changed<Plane>,
    Changed<Cuboid>,
    Changed<TriangleMesh>,
    Changed<Deforming>,
    Changed<Surface>,
)>;
type WorldChanged = Or<(Changed<Transform>, Changed<Sphere>, Changed<Plane>, Changed<Cuboid>)>;
type ShapeAdded = Or<(Added<Sphere>, Added<Plane>, Added<Cuboid>, Added<TriangleMesh>)>;
/// A mesh entity moved or got another mesh.
type MeshChanged = Or<(Changed<Transform>, Changed<TriangleMesh>)>;

/// A mesh written or deformed: a change whatever its value (meshes are compared by pointer).
type MeshWritten = Or<(Changed<TriangleMesh>, Changed<Deforming>)>;
/// Changes that can decide whether a mesh is baked: markers added, or a mesh swapped (which
/// changes how many entities share it).
type BakingChanged =
    Or<(Added<Dynamic>, Added<Deforming>, Changed<Surface>, (Changed<TriangleMesh>, Without<Deforming>))>;
/// What the BVH system reads of a shaped entity.
type ShapeQuery = (
    Entity,
    Option<&'static Name>,
    &'static Transform,
    &'static Matte,
    Option<&'static Sphere>,
    Option<&'static Plane>,
    Option<&'static Cuboid>,
    Option<&'static TriangleMesh>,
    Option<&'static Deforming>,
    Has<Dynamic>,
    Option<&'static Surface>,
);
/// One shaped entity as read by [`ShapeQuery`].
type ShapeData<'a> = (
    Entity,
    Option<&'a Name>,
    &'a Transform,
    &'a Matte,
    Option<&'a Sphere>,
    Option<&'a Plane>,
    Option<&'a Cuboid>,
    Option<&'a TriangleMesh>,
    Option<&'a Deforming>,
    bool,
    Option<&'a Surface>,
);

/// Removals of shape components (despawns included).
#[derive(SystemParam)]
pub struct ShapeRemovals<'w, 's> {
    sphere: RemovedComponents<'w, 's, Sphere>,
    plane: RemovedComponents<'w, 's, Plane>,
    cuboid: RemovedComponents<'w, 's, Cuboid>,
    mesh: RemovedComponents<'w, 's, TriangleMesh>,
    dynamic: RemovedComponents<'w, 's, Dynamic>,
    deforming: RemovedComponents<'w, 's, Deforming>,
    surface: RemovedComponents<'w, 's, Surface>,
}

impl ShapeRemovals<'_, '_> {
    fn any(&mut self) -> bool {
        let counts = [
            self.sphere.read().count(),
            self.plane.read().count(),
            self.cuboid.read().count(),
            self.mesh.read().count(),
            self.dynamic.read().count(),
            self.deforming.read().count(),
            self.surface.read().count(),
        ];
        counts.iter().any(|&c| c > 0)
    }
}

/// The BLAS of a mesh (keyed by its `Arc` address, kept alive here so the key stays unique),
/// or why the mesh is unusable.
struct MeshEntry {
    _mesh: Arc<Mesh>,
    blas: Result<Arc<Blas>, String>,
}

/// A deforming entity's BLAS and the vertices it was last refit to.
struct DeformEntry {
    rest: Arc<Mesh>,
    current: Arc<Mesh>,
    blas: Arc<Blas>,
}

/// What the BVH system keeps between frames.
#[derive(Default)]
pub struct BvhCache {
    built_once: bool,
    meshes: HashMap<usize, MeshEntry>,
    templates: HashMap<usize, MeshEntry>,
    deforming: HashMap<Entity, DeformEntry>,
    world: Vec<Arc<Blas>>,
    /// Entities baked into the world-space BLAS of static meshes.
    baked: HashSet<Entity>,
    /// Whether that BLAS holds the shared meshes too ([`bakes_shared`]).
    bakes_shared: bool,
    planes: Vec<PlanePrim>,
    world_problems: Vec<String>,
}

fn key(mesh: &Arc<Mesh>) -> usize {
    Arc::as_ptr(mesh) as usize
}

/// Brings [`SceneGeometry`] up to date with the shaped entities.
#[allow(clippy::too_many_arguments)]
pub fn update_bvh(
    changed: Query<(), (GeometryChanged, Shaped)>,
    world_changed: Query<(), (WorldChanged, WorldShaped)>,
    meshes_moved: Query<Entity, (MeshChanged, With<TriangleMesh>)>,
    baking_changed: Query<(), (BakingChanged, With<TriangleMesh>)>,
    added: Query<(), ShapeAdded>,
    mut removed: ShapeRemovals,
    recoloured: Query<(Entity, &Matte), (Changed<Matte>, Shaped)>,
    meshes_written: Query<(), (MeshWritten, Shaped)>,
    shape_changes: Res<ShapeValueChanges>,
    shapes: Query<ShapeQuery, Shaped>,
    settings: Res<RenderSettings>,
    mut geometry: ResMut<SceneGeometry>,
    mut problems: ResMut<SceneProblems>,
    mut accumulation: ResMut<Accumulation>,
    mut stats: ResMut<FrameStats>,
    mut cache: Local<BvhCache>,
) {
    let start = Instant::now();
    // New settings can change whether the shared meshes are worth baking.
    let rebake = cache.built_once && settings.is_changed() && {
        let entries: Vec<ShapeData> = shapes.iter().collect();
        bakes_shared(&settings, &mesh_users(&entries), &entries) != cache.bakes_shared
    };
    // Baked and instanced triangles round differently: samples of the two never mix, so a new
    // sample target that flips the choice renders what a fresh render to that target would.
    if rebake && stats.reset.is_none() {
        let (width, height) = (accumulation.width, accumulation.height);
        accumulation.reset(width, height, settings.accumulation_layout());
        stats.reset = Some("the shared meshes' baking changed with max_spp".into());
    }
    let structural = !cache.built_once || !added.is_empty() || removed.any() || rebake;
    // Writes of equal shape values change nothing. Meshes are compared by pointer, which a mesh
    // deformed in place keeps: their writes always count.
    let changed = !changed.is_empty() && (shape_changes.any || !meshes_written.is_empty());
    let note = if structural || changed {
        cache.built_once = true;
        // Drop the old scene's references first so deforming BLASes refit in place.
        let objects_before = std::mem::take(&mut geometry.objects);
        *geometry = SceneGeometry::default();
        drop(objects_before);
        let rebuild_world = structural
            || !world_changed.is_empty()
            || !baking_changed.is_empty()
            || meshes_moved.iter().any(|e| cache.baked.contains(&e));
        let (built, found, work) = update(&shapes, &settings, &mut cache, rebuild_world);
        problems.geometry = found;
        *geometry = built;
        stats.bvh_built = work.any();
        stats.bvh_work = work;
        stats.bvh_sah = geometry.largest_blas_sah();
        let alpha = match geometry.alpha_mesh_count() {
            0 => String::new(),
            n => format!(" and {n} alpha-tested meshes apart"),
        };
        format!(
            "{} BLAS built, {} refit{}, TLAS over {} instances{alpha}; {} triangles stored, {} placed \
             ({} zero-area skipped), {} planes in {:.2} ms",
            work.blas_built,
            work.blas_refit,
            if rebuild_world { " (world shapes rebuilt)" } else { "" },
            geometry.instances().len(),
            geometry.triangle_count,
            geometry.instanced_triangle_count,
            geometry.degenerate_triangles,
            geometry.plane_count(),
            start.elapsed().as_secs_f64() * 1e3
        )
    } else if !recoloured.is_empty() {
        let mut updated = 0;
        for (entity, matte) in &recoloured {
            if let Ok(i) = geometry.objects.binary_search_by_key(&entity, |o| o.entity) {
                geometry.objects[i].material = *matte;
                updated += 1;
            }
        }
        format!("unchanged; {updated} materials updated")
    } else {
        "unchanged".to_string()
    };
    stats.bvh_nodes = geometry.node_count();
    stats.bvh_wide_nodes = geometry.wide_node_count();
    stats.bvh_width = geometry.node_width();
    stats.packet_lanes = geometry.packet_lanes();
    stats.bvh_prims = geometry.prim_count();
    stats.bvh_bytes = geometry.memory_bytes();
    stats.bvh_triangles = geometry.triangle_count;
    stats.record("bvh", start.elapsed(), note);
}

fn describe(entity: Entity, name: Option<&Name>, e: String) -> String {
    match name {
        Some(name) => format!("entity {entity} ({name}): {e}"),
        None => format!("entity {entity}: {e}"),
    }
}

/// Rebuilds the instance list and the top-level BVH, building or refitting only the BLASes
/// whose meshes are new or deformed. Every shaped entity (in entity order, for determinism)
/// is an object whether or not it is valid, so object indices only move when entities do.
fn update(
    shapes: &Query<ShapeQuery, Shaped>,
    settings: &RenderSettings,
    cache: &mut BvhCache,
    rebuild_world: bool,
) -> (SceneGeometry, Vec<String>, BvhWork) {
    let mut entries: Vec<ShapeData> = shapes.iter().collect();
    entries.sort_by_key(|e| e.0);
    let objects: Vec<Object> = entries.iter().map(|e| Object { entity: e.0, material: *e.3 }).collect();
    let mut work = BvhWork { tlas_built: true, ..Default::default() };
    let mut problems = Vec::new();

    if rebuild_world {
        let (mut world, mut planes, mut found) = (Vec::new(), Vec::new(), Vec::new());
        let users = mesh_users(&entries);
        cache.bakes_shared = bakes_shared(settings, &users, &entries);
        let (baked, baked_blas) = bake_static_meshes(&entries, &users, cache.bakes_shared, &mut found);
        world.extend(baked_blas);
        cache.baked = baked;
        for (object, &(entity, name, transform, matte, sphere, plane, cuboid, mesh, ..)) in entries.iter().enumerate() {
            let object = object as u32;
            let count = [sphere.is_some(), plane.is_some(), cuboid.is_some(), mesh.is_some()];
            let result = if count.iter().filter(|&&s| s).count() > 1 {
                Err("has more than one shape component (Sphere, Plane, Cuboid, TriangleMesh)".to_string())
            } else if mesh.is_some() {
                continue;
            } else {
                world_space::validate_material(matte).and_then(|()| {
                    if let Some(s) = sphere {
                        world.push(Arc::new(Blas::build(vec![world_space::sphere(s, transform, object)?])));
                    } else if let Some(p) = plane {
                        planes.push(world_space::plane(p, transform, object)?);
                    } else if let Some(c) = cuboid {
                        world.push(Arc::new(Blas::build(world_space::cuboid(c, transform, object)?.prims)));
                    }
                    Ok(())
                })
            };
            if let Err(e) = result {
                found.push(describe(entity, name, e));
            }
        }
        work.blas_built += world.len();
        cache.world = world;
        cache.planes = planes;
        cache.world_problems = found;
    }
    problems.extend(cache.world_problems.iter().cloned());

    let mut blases: Vec<Arc<Blas>> = Vec::new();
    let mut blas_index: HashMap<usize, u32> = HashMap::new();
    let mut instances = Vec::new();
    let mut index_of = |blas: &Arc<Blas>, blases: &mut Vec<Arc<Blas>>| {
        *blas_index.entry(Arc::as_ptr(blas) as usize).or_insert_with(|| {
            blases.push(blas.clone());
            blases.len() as u32 - 1
        })
    };
    // Each sphere and cuboid is its own small world-space BLAS, so the top level separates them
    // from the meshes (one shared world BLAS mixing them traced the default scene's AO rays slower).
    for world_blas in &cache.world {
        if let Some(bounds) = world_blas.bounds() {
            let i = index_of(world_blas, &mut blases);
            instances.extend(Instance::new(i, bounds, glam::Affine3A::IDENTITY, None));
        }
    }
    let planes = cache.planes.clone();

    // The surfaces of textured or alpha-tested meshes, baked or not, by object.
    let mut surfaces: Vec<Option<Arc<PlacedSurface>>> = Vec::new();
    for (object, &(entity, name, .., mesh, _, _, surface)) in entries.iter().enumerate() {
        let (Some(mesh), Some(surface)) = (mesh, surface) else { continue };
        match surface.validate(&mesh.0) {
            Ok(()) => {
                surfaces.resize(entries.len(), None);
                surfaces[object] = Some(Arc::new(PlacedSurface { surface: surface.clone(), mesh: mesh.0.clone() }));
            }
            Err(e) => problems.push(describe(entity, name, e)),
        }
    }

    let mut used_meshes = Vec::new();
    let mut used_deforming = Vec::new();
    let mut alpha_meshes = Vec::new();
    for (object, &(entity, name, transform, matte, sphere, plane, cuboid, mesh, deforming, _, surface)) in
        entries.iter().enumerate()
    {
        let Some(mesh) = mesh else { continue };
        if sphere.is_some() || plane.is_some() || cuboid.is_some() || cache.baked.contains(&entity) {
            continue; // reported with the world shapes, or baked
        }
        let blas = world_space::validate_material(matte).and_then(|()| match deforming {
            None => {
                used_meshes.push(key(&mesh.0));
                mesh_blas(cache, &mesh.0, &mut work)
            }
            Some(d) => {
                used_deforming.push(entity);
                deformed_blas(cache, entity, &d.rest, &mesh.0, &mut work)
            }
        });
        let placed = blas.and_then(|blas| {
            let affine = world_space::affine(transform)?;
            if surface.is_some_and(Surface::alpha_tested) {
                // Unless its surface was refused above (and the frame with it).
                if let Some(placed) = surfaces.get(object).cloned().flatten() {
                    let object = object as u32;
                    alpha_meshes.push(AlphaMesh { blas, surface: placed, to_world: affine, object });
                }
                return Ok(());
            }
            let Some(bounds) = blas.bounds() else { return Ok(()) };
            let i = index_of(&blas, &mut blases);
            let instance = Instance::new(i, bounds, affine, Some(object as u32))
                .ok_or_else(|| "mesh vertices overflow to non-finite values after the transform".to_string())?;
            instances.push(instance);
            Ok(())
        });
        if let Err(e) = placed {
            problems.push(describe(entity, name, e));
        }
    }
    // Forget meshes no longer in the scene.
    cache.meshes.retain(|k, _| used_meshes.contains(k));
    cache.deforming.retain(|e, _| used_deforming.contains(e));
    let rests: Vec<usize> = cache.deforming.values().map(|d| key(&d.rest)).collect();
    cache.templates.retain(|k, _| rests.contains(k));

    let geometry = SceneGeometry::from_instances(blases, instances, planes, objects);
    (geometry.with_surfaces(AlphaLayer::new(alpha_meshes), surfaces), problems, work)
}

/// How many entities use each mesh (by [`key`]).
fn mesh_users(entries: &[ShapeData]) -> HashMap<usize, usize> {
    let mut users: HashMap<usize, usize> = HashMap::new();
    for e in entries {
        if let Some(mesh) = e.7 {
            *users.entry(key(&mesh.0)).or_default() += 1;
        }
    }
    users
}

/// The mesh of an entry that can be baked: static (no [`Dynamic`] marker, not deforming), not
/// alpha-tested (see [`Surface`]) and its only shape component; with whether other entities (counted in `users`) share it.
fn static_mesh<'a>(entry: &ShapeData<'a>, users: &HashMap<usize, usize>) -> Option<(&'a TriangleMesh, bool)> {
    let &(_, _, _, _, sphere, plane, cuboid, mesh, deforming, dynamic, surface) = entry;
    let other_shape = sphere.is_some() || plane.is_some() || cuboid.is_some();
    let kept_apart = dynamic || deforming.is_some() || surface.is_some_and(Surface::alpha_tested);
    mesh.filter(|_| !(other_shape || kept_apart)).map(|m| (m, users[&key(&m.0)] > 1))
}

/// Whether the static meshes that several entities share are baked as well: when the render
/// is jittered (every sample traces a camera ray) and has a sample target (`max_spp`) that
/// comes to at least [`SHARED_BAKE_CAMERA_RAYS_PER_TRIANGLE`] camera rays per triangle they
/// would place, and they would place at most [`SHARED_BAKE_MAX_TRIANGLES`]. Without a target
/// (progressive rendering, the window) they stay instanced.
fn bakes_shared(settings: &RenderSettings, users: &HashMap<usize, usize>, entries: &[ShapeData]) -> bool {
    let shared: usize = entries
        .iter()
        .filter_map(|e| static_mesh(e, users))
        .filter(|&(_, shared)| shared)
        .map(|(m, _)| m.0.indices.len())
        .sum();
    let samples = |spp: u32| u64::from(settings.width) * u64::from(settings.height) * u64::from(spp);
    shared > 0
        && shared <= SHARED_BAKE_MAX_TRIANGLES
        && settings.jitter
        && settings.max_spp.is_some_and(|spp| samples(spp) >= SHARED_BAKE_CAMERA_RAYS_PER_TRIANGLE * shared as u64)
}

/// Bakes the static meshes (no [`Dynamic`] marker, not deforming, no other shape component)
/// that one entity each uses, and with `shared` those that several do, into one world-space
/// BLAS: which entities went in, and the BLAS (`None` when there are none). Unusable meshes
/// are reported and left out.
fn bake_static_meshes<'a>(
    entries: &[ShapeData<'a>],
    users: &HashMap<usize, usize>,
    shared: bool,
    found: &mut Vec<String>,
) -> (HashSet<Entity>, Option<Arc<Blas>>) {
    let bakes = |entry: &ShapeData<'a>| static_mesh(entry, users).filter(|&(_, s)| shared || !s).map(|(m, _)| m);
    // Every baked triangle goes straight into one set of vectors, sized once.
    let mut all = world_space::Bake::default();
    let (vertices, triangles) =
        entries.iter().filter_map(bakes).fold((0, 0), |(v, t), m| (v + m.0.positions.len(), t + m.0.indices.len()));
    all.triangles.positions.reserve_exact(vertices);
    all.triangles.triangles.reserve_exact(triangles);
    all.triangles.objects.reserve_exact(triangles);
    // Textured meshes' hits need their triangles: kept only when some baked mesh has a surface.
    let textured = entries.iter().any(|e| bakes(e).is_some() && e.10.is_some());
    all.sources = textured.then(|| Vec::with_capacity(triangles));
    let mut baked = HashSet::new();
    for (object, entry) in entries.iter().enumerate() {
        let Some(mesh) = bakes(entry) else { continue };
        let &(entity, name, transform, matte, ..) = entry;
        baked.insert(entity);
        let converted = world_space::validate_material(matte)
            .and_then(|()| world_space::append_mesh(&mesh.0, transform, object as u32, &mut all));
        if let Err(e) = converted {
            found.push(describe(entity, name, e));
        }
    }
    if all.triangles.triangles.is_empty() {
        return (baked, None);
    }
    let world_space::Bake { triangles, degenerate, sources } = all;
    let mut blas = Blas::build_indexed(triangles, sources.as_deref());
    blas.degenerate_triangles = degenerate;
    (baked, Some(Arc::new(blas)))
}

/// The shared BLAS of a static mesh, built on first use.
fn mesh_blas(cache: &mut BvhCache, mesh: &Arc<Mesh>, work: &mut BvhWork) -> Result<Arc<Blas>, String> {
    let entry = cache.meshes.entry(key(mesh)).or_insert_with(|| {
        let blas = mesh.validate().map(|()| {
            work.blas_built += 1;
            Arc::new(Blas::from_mesh(mesh))
        });
        MeshEntry { _mesh: mesh.clone(), blas }
    });
    entry.blas.clone()
}

/// A deforming entity's BLAS: the rest pose's tree (built once per rest mesh), refit to the
/// current vertices when they changed.
fn deformed_blas(
    cache: &mut BvhCache,
    entity: Entity,
    rest: &Arc<Mesh>,
    current: &Arc<Mesh>,
    work: &mut BvhWork,
) -> Result<Arc<Blas>, String> {
    if let Some(d) = cache.deforming.get(&entity)
        && Arc::ptr_eq(&d.current, current)
        && Arc::ptr_eq(&d.rest, rest)
    {
        return Ok(d.blas.clone());
    }
    let template = cache.templates.entry(key(rest)).or_insert_with(|| {
        let blas = rest.validate().map(|()| {
            work.blas_built += 1;
            Arc::new(Blas::deformable(rest))
        });
        MeshEntry { _mesh: rest.clone(), blas }
    });
    let template = template.blas.clone()?;
    if current.indices != rest.indices || current.positions.len() != rest.positions.len() {
        return Err("deforming mesh has different triangles or vertex count than its rest mesh".into());
    }
    if let Some(i) = current.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!("deformed vertex {i} has a non-finite position {}", current.positions[i]));
    }
    let mut blas = match cache.deforming.remove(&entity) {
        Some(d) if Arc::ptr_eq(&d.rest, rest) => d.blas,
        _ => template,
    };
    Arc::make_mut(&mut blas).refit(&current.positions, &current.indices);
    work.blas_refit += 1;
    cache.deforming.insert(entity, DeformEntry { rest: rest.clone(), current: current.clone(), blas: blas.clone() });
    Ok(blas)
}
