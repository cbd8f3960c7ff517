//! The camera for a file without one: it keeps the whole scene in view, over every frame that
//! is rendered when those are known (a sequence), so animated parts do not leave the image.

use super::*;
use crate::animation::morph;

/// The most poses sampled to frame an animation: a sequence longer than this is sampled at
/// evenly spaced frames (its first and last included).
pub const MAX_FRAMING_POSES: usize = 256;

/// Vertices posed in all, summed over the sampled poses, beyond which fewer poses are taken
/// (at least the first and last), so framing stays a small part of loading a large rig.
const FRAMING_VERTEX_BUDGET: usize = 1 << 24;

/// A 40° camera looking at the centre of `bounds` from the front-right and a little above
/// (the model's front is +Z in glTF), far enough back that the bounding sphere fits the view.
pub fn framing_camera((lo, hi): (Vec3, Vec3)) -> Camera {
    let center = (lo + hi) * 0.5;
    let radius = ((hi - lo).length() * 0.5).max(1e-6);
    let vfov: f32 = 40.0;
    let distance = radius / (vfov.to_radians() * 0.5).sin() * 1.05;
    let dir = Vec3::new(0.45, 0.35, 1.0).normalize();
    Camera::look_at(center + dir * distance, center, vfov)
}

/// The smallest box holding both.
pub(super) fn union(a: Option<(Vec3, Vec3)>, b: Option<(Vec3, Vec3)>) -> Option<(Vec3, Vec3)> {
    match (a, b) {
        (Some((lo, hi)), Some((l, h))) => Some((lo.min(l), hi.max(h))),
        (a, b) => a.or(b),
    }
}

/// At most `count` of `times`, evenly spaced, the first and last included.
fn sample_times(times: &[f32], count: usize) -> Vec<f32> {
    let (n, count) = (times.len(), count.max(2));
    if n <= count {
        return times.to_vec();
    }
    (0..count).map(|i| times[i * (n - 1) / (count - 1)]).collect()
}

impl GltfScene {
    /// Bounds of the parts that animation can move (meshes under animated nodes, skinned or
    /// morphing meshes), posed by `graph`'s playing clips at each of `times` (sampled as
    /// [`MAX_FRAMING_POSES`] says). Static parts are the same at every time and left out.
    pub(super) fn moving_bounds(&self, graph: &NodeGraph, times: &[f32]) -> Option<(Vec3, Vec3)> {
        let (animated, morphing) = (graph.animated(), graph.morphing());
        let moving: Vec<&Placement> =
            self.placements.iter().filter(|p| animated[p.node] || p.skin.is_some() || morphing[p.node]).collect();
        let vertices: usize = moving
            .iter()
            .map(|p| p.offsets.len() * self.meshes[p.mesh].iter().map(|m| m.mesh.positions.len()).sum::<usize>())
            .sum();
        if vertices == 0 || times.is_empty() {
            return None;
        }
        let poses = (FRAMING_VERTEX_BUDGET / vertices).min(MAX_FRAMING_POSES);
        let mut bounds = None;
        let mut grow = |q: Vec3| {
            if q.is_finite() {
                bounds = union(bounds, Some((q, q)));
            }
        };
        for t in sample_times(times, poses) {
            let (world, weights) = (graph.pose(t), graph.pose_weights(t));
            for placement in &moving {
                let node_weights = weights.get(placement.node).map_or(&[][..], Vec::as_slice);
                for prim in &self.meshes[placement.mesh] {
                    let points = morph(&prim.mesh.positions, &prim.targets, node_weights);
                    match (placement.skin.map(|s| &self.skins[s]), &prim.influences) {
                        (Some(skin), Some(influences)) => {
                            let skin = Skin {
                                joints: skin.joints.clone(),
                                inverse_bind: skin.inverse_bind.clone(),
                                influences: influences.clone(),
                                rest: prim.mesh.clone(),
                            };
                            skin.deform_points(&world, &points).into_iter().for_each(&mut grow);
                        }
                        _ => {
                            for offset in &placement.offsets {
                                let m = world[placement.node] * *offset;
                                points.iter().for_each(|&p| grow(m.transform_point3(p)));
                            }
                        }
                    }
                }
            }
        }
        bounds
    }
}
