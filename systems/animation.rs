//! Stage 0a: poses the [`NodeGraph`] for the current [`Time`] (the playing clips sampled from
//! the rest pose, so a frame's pose depends only on its time) and moves every entity linked to
//! a node: mesh instances, lights and the camera; morph weights are posed for the deformation
//! stage. Values are only written when they differ, so a
//! static scene, or a held pose, changes nothing and costs no BVH work or accumulation reset.

use std::time::Instant;

use bevy_ecs::prelude::*;

use crate::{
    animation::{NodeGraph, NodeLink},
    components::{Camera, OrthographicCamera, PointLight, Transform},
    resources::Time,
    stats::FrameStats,
};

type Linked<'a> = (
    &'a NodeLink,
    Option<&'a mut Transform>,
    Option<&'a mut Camera>,
    Option<&'a mut OrthographicCamera>,
    Has<PointLight>,
);

/// Samples the playing clips at [`Time`] and updates the linked entities.
pub fn animate(
    time: Option<Res<Time>>,
    mut graph: ResMut<NodeGraph>,
    mut linked: Query<Linked>,
    mut stats: ResMut<FrameStats>,
    mut last: Local<Option<(f32, Vec<usize>)>>,
) {
    let start = Instant::now();
    let seconds = time.map_or(0.0, |t| t.seconds);
    let key = (seconds, graph.active.clone());
    if last.as_ref() == Some(&key) && !graph.is_changed() {
        stats.record("animation", start.elapsed(), "unchanged");
        return;
    }
    *last = Some(key);
    let pose = graph.pose(seconds);
    let weights = graph.pose_weights(seconds);
    if pose == graph.world && weights == graph.weights {
        stats.record("animation", start.elapsed(), format!("t = {seconds:.4} s: pose unchanged"));
        return;
    }
    if weights != graph.weights {
        graph.weights = weights;
    }
    if pose == graph.world {
        stats.record("animation", start.elapsed(), format!("t = {seconds:.4} s: morph weights changed"));
        return;
    }
    graph.world = pose;
    let mut moved = 0;
    for (link, transform, camera, orthographic, is_light) in &mut linked {
        let Some(node) = graph.world.get(link.node) else { continue };
        let t = Transform::from_affine(&(*node * link.offset));
        let mut changed = false;
        if let Some(mut c) = camera {
            changed |= c.set_if_neq(Camera::from_transform(&t, c.vfov_degrees));
        }
        if let Some(mut c) = orthographic {
            changed |= c.set_if_neq(OrthographicCamera::from_transform(&t, c.half_height));
        }
        if let Some(mut current) = transform {
            let t = if is_light { Transform::from_translation(t.translation) } else { t };
            changed |= current.set_if_neq(t);
        }
        moved += usize::from(changed);
    }
    stats.record("animation", start.elapsed(), format!("t = {seconds:.4} s: {moved} entities moved"));
}
