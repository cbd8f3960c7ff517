//! Stage 0b: deforms skinned meshes when the pose changed: each [`Skin`]'s rest vertices are
//! blended by its joints' world transforms (linear blend skinning) into a new `TriangleMesh`,
//! which the BVH system refits (the mesh is `Deforming`). Unchanged vertices are not written.

use std::{sync::Arc, time::Instant};

use bevy_ecs::prelude::*;
use rayon::prelude::*;

use crate::{
    animation::{NodeGraph, Skin},
    components::{Mesh, TriangleMesh},
    stats::FrameStats,
};

/// Re-skins every skinned mesh for the current pose of the [`NodeGraph`].
pub fn skin_meshes(
    graph: Res<NodeGraph>,
    mut skinned: Query<(&Skin, &mut TriangleMesh)>,
    mut stats: ResMut<FrameStats>,
) {
    let start = Instant::now();
    let mut meshes: Vec<(&Skin, Mut<TriangleMesh>)> = skinned.iter_mut().collect();
    let deformed: Vec<Option<Vec<glam::Vec3>>> = meshes
        .par_iter()
        .map(|(skin, mesh)| {
            let positions = skin.deform(&graph.world);
            (positions != mesh.0.positions).then_some(positions)
        })
        .collect();
    let mut updated = 0;
    for ((skin, mesh), positions) in meshes.iter_mut().zip(deformed) {
        if let Some(positions) = positions {
            mesh.0 = Arc::new(Mesh { positions, indices: skin.rest.indices.clone() });
            updated += 1;
        }
    }
    stats.record("skinning", start.elapsed(), format!("{updated} of {} skinned meshes deformed", meshes.len()));
}
