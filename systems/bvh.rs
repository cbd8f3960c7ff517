//! Stage 2: keeps the acceleration structure in step with the scene. The BVH is rebuilt only
//! when a shape or a shaped entity's transform was added, changed or removed; a material
//! change only updates the material table; an unchanged scene does no BVH work at all.

use std::time::Instant;

use bevy_ecs::{name::Name, prelude::*, system::SystemParam};

use crate::{
    components::{Cuboid, Matte, Plane, Sphere, Transform, TriangleMesh},
    geometry::{Object, SceneGeometry, world_space},
    resources::SceneProblems,
    stats::FrameStats,
};

type Shaped = Or<(With<Sphere>, With<Plane>, With<Cuboid>, With<TriangleMesh>)>;
type GeometryChanged =
    Or<(Changed<Transform>, Changed<Sphere>, Changed<Plane>, Changed<Cuboid>, Changed<TriangleMesh>)>;
type ShapeData<'a> = (
    Entity,
    Option<&'a Name>,
    &'a Transform,
    &'a Matte,
    Option<&'a Sphere>,
    Option<&'a Plane>,
    Option<&'a Cuboid>,
    Option<&'a TriangleMesh>,
);

/// Removals of shape components (despawns included).
#[derive(SystemParam)]
pub struct ShapeRemovals<'w, 's> {
    sphere: RemovedComponents<'w, 's, Sphere>,
    plane: RemovedComponents<'w, 's, Plane>,
    cuboid: RemovedComponents<'w, 's, Cuboid>,
    mesh: RemovedComponents<'w, 's, TriangleMesh>,
}

impl ShapeRemovals<'_, '_> {
    fn any(&mut self) -> bool {
        let counts = [
            self.sphere.read().count(),
            self.plane.read().count(),
            self.cuboid.read().count(),
            self.mesh.read().count(),
        ];
        counts.iter().any(|&c| c > 0)
    }
}

/// Rebuilds the BVH when geometry changed, or refreshes materials when only they changed.
#[allow(clippy::too_many_arguments)]
pub fn update_bvh(
    changed: Query<(), (GeometryChanged, Shaped)>,
    mut removed: ShapeRemovals,
    recoloured: Query<(Entity, &Matte), (Changed<Matte>, Shaped)>,
    shapes: Query<ShapeData, Shaped>,
    mut geometry: ResMut<SceneGeometry>,
    mut problems: ResMut<SceneProblems>,
    mut stats: ResMut<FrameStats>,
    mut built_once: Local<bool>,
) {
    let start = Instant::now();
    let removed_any = removed.any();
    let note = if !*built_once || !changed.is_empty() || removed_any {
        *built_once = true;
        let (built, found) = build(&shapes);
        problems.geometry = found;
        *geometry = built;
        stats.bvh_built = true;
        format!(
            "rebuilt: {} triangles ({} zero-area skipped), {} spheres, {} planes in {:.2} ms",
            geometry.triangle_count,
            geometry.degenerate_triangles,
            geometry.prim_count() - geometry.triangle_count,
            geometry.plane_count(),
            geometry.build_time.as_secs_f64() * 1e3
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
    stats.bvh_prims = geometry.prim_count();
    stats.bvh_bytes = geometry.memory_bytes();
    stats.record("bvh", start.elapsed(), note);
}

/// Converts every shaped entity (in entity order, for determinism) and builds the BVH.
fn build(shapes: &Query<ShapeData, Shaped>) -> (SceneGeometry, Vec<String>) {
    let mut entries: Vec<ShapeData> = shapes.iter().collect();
    entries.sort_by_key(|e| e.0);
    let (mut prims, mut planes, mut objects, mut problems) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut degenerate = 0;
    for (entity, name, transform, matte, sphere, plane, cuboid, mesh) in entries {
        let object = objects.len() as u32;
        let shape_count = [sphere.is_some(), plane.is_some(), cuboid.is_some(), mesh.is_some()];
        let result = if shape_count.iter().filter(|&&s| s).count() > 1 {
            Err("has more than one shape component (Sphere, Plane, Cuboid, TriangleMesh)".to_string())
        } else {
            world_space::validate_material(matte).and_then(|()| {
                if let Some(s) = sphere {
                    prims.push(world_space::sphere(s, transform, object)?);
                } else if let Some(p) = plane {
                    planes.push(world_space::plane(p, transform, object)?);
                } else {
                    let converted = match (cuboid, mesh) {
                        (Some(c), _) => world_space::cuboid(c, transform, object)?,
                        (_, Some(m)) => world_space::mesh(&m.0, transform, object)?,
                        _ => unreachable!("the query only matches shaped entities"),
                    };
                    degenerate += converted.degenerate;
                    prims.extend(converted.prims);
                }
                Ok(())
            })
        };
        match result {
            Ok(()) => objects.push(Object { entity, material: *matte }),
            Err(e) => problems.push(match name {
                Some(name) => format!("entity {entity} ({name}): {e}"),
                None => format!("entity {entity}: {e}"),
            }),
        }
    }
    let mut geometry = SceneGeometry::build(prims, planes, objects);
    geometry.degenerate_triangles = degenerate;
    (geometry, problems)
}
