//! Stage 0b: deforms skinned and morphing meshes when the pose changed: each [`Morph`]'s rest
//! vertices move by its targets under the node's weights, then each [`Skin`]'s are blended by
//! its joints' world transforms (linear blend skinning), into a new `TriangleMesh`, which the
//! BVH system refits (the mesh is `Deforming`). Unchanged vertices are not written.

use std::{sync::Arc, time::Instant};

use bevy_ecs::prelude::*;
use rayon::prelude::*;

use crate::{
    animation::{Morph, NodeGraph, Skin},
    components::{Mesh, TriangleMesh},
    stats::FrameStats,
};

/// What the system reads and writes of a deforming mesh entity.
type DeformQuery = (Option<&'static Skin>, Option<&'static Morph>, &'static mut TriangleMesh);
/// Entities with a skin or morph targets.
type DeformFilter = Or<(With<Skin>, With<Morph>)>;
type Deformed<'a> = (Option<&'a Skin>, Option<&'a Morph>, Mut<'a, TriangleMesh>);

/// Re-skins and re-morphs every deforming mesh for the current pose of the [`NodeGraph`].
pub fn skin_meshes(
    graph: Res<NodeGraph>,
    mut deforming: Query<DeformQuery, DeformFilter>,
    mut stats: ResMut<FrameStats>,
) {
    let start = Instant::now();
    let mut meshes: Vec<Deformed> = deforming.iter_mut().collect();
    let deformed: Vec<Option<Vec<glam::Vec3>>> = meshes
        .par_iter()
        .map(|(skin, morph, mesh)| {
            let morphed = morph.map(|m| m.deform(graph.weights.get(m.node).map_or(&[], Vec::as_slice)));
            let positions = match (skin, morphed) {
                (Some(skin), Some(points)) => skin.deform_points(&graph.world, &points),
                (Some(skin), None) => skin.deform(&graph.world),
                (None, Some(points)) => points,
                (None, None) => return None,
            };
            (positions != mesh.0.positions).then_some(positions)
        })
        .collect();
    let mut updated = 0;
    for ((_, _, mesh), positions) in meshes.iter_mut().zip(deformed) {
        if let Some(positions) = positions {
            // The triangles never change; only the vertices move.
            mesh.0 = Arc::new(Mesh { positions, indices: mesh.0.indices.clone() });
            updated += 1;
        }
    }
    stats.record("skinning", start.elapsed(), format!("{updated} of {} deforming meshes deformed", meshes.len()));
}
