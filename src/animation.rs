//! Node hierarchies, keyframe animation, skinning and morph targets: the data the animation
//! and deformation systems read. Sampling follows the glTF 2.0 rules (STEP, LINEAR with
//! quaternion slerp, CUBICSPLINE Hermite splines), and a time before the first or after the
//! last key holds the end value; each clip loops over its own duration.

use std::sync::Arc;

use bevy_ecs::prelude::{Component, Resource};
use glam::{Affine3A, Quat, Vec3, Vec4};

use crate::components::{Mesh, Transform};

/// How a channel interpolates between keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interpolation {
    /// Hold each key until the next.
    Step,
    /// Linear (slerp for rotations).
    Linear,
    /// Cubic Hermite spline with in/out tangents stored beside each key.
    CubicSpline,
}

/// The keyed values of one channel (for CUBICSPLINE: in-tangent, value, out-tangent per key).
#[derive(Clone, Debug, PartialEq)]
pub enum Keys {
    /// Node translations.
    Translation(Vec<Vec3>),
    /// Node rotations (unit quaternions).
    Rotation(Vec<Quat>),
    /// Node scales.
    Scale(Vec<Vec3>),
    /// Morph-target weights of a node's mesh, `targets` values per key (for CUBICSPLINE:
    /// `targets` in-tangents, values, then out-tangents per key).
    Weights {
        /// Weights per key, the node's number of morph targets.
        targets: usize,
        /// All values, key after key.
        values: Vec<f32>,
    },
}

/// One animated property of one node.
#[derive(Clone, Debug, PartialEq)]
pub struct Channel {
    /// Index into [`NodeGraph::nodes`].
    pub node: usize,
    /// Key times in seconds, non-decreasing.
    pub times: Vec<f32>,
    /// Key values.
    pub keys: Keys,
    /// Interpolation between keys.
    pub interpolation: Interpolation,
}

/// A named set of channels played together.
#[derive(Clone, Debug, PartialEq)]
pub struct Clip {
    /// Name (or `animation N`).
    pub name: String,
    /// Channels.
    pub channels: Vec<Channel>,
    /// Last key time of any channel.
    pub duration: f32,
}

/// Where key `t` falls: (key index, fraction to the next key, interval length). A time that
/// is not a number holds the first key; no input indexes outside `times` (an empty list
/// gives key 0, which its caller never has).
fn locate(times: &[f32], t: f32) -> (usize, f32, f32) {
    let (Some(&first), Some(&end)) = (times.first(), times.last()) else { return (0, 0.0, 0.0) };
    let last = times.len() - 1;
    if t.is_nan() || t <= first {
        return (0, 0.0, 0.0);
    }
    if t >= end {
        return (last, 0.0, 0.0);
    }
    // first < t < end, so 1 <= partition_point <= last; the clamp is for unsorted input.
    let k = times.partition_point(|&x| x <= t).clamp(1, last) - 1;
    let dt = times[k + 1] - times[k];
    let s = if dt > 0.0 { (t - times[k]) / dt } else { 0.0 };
    (k, s, dt)
}

/// Cubic Hermite spline between v0 and v1 with out-tangent of key 0 (`b0`) and in-tangent of
/// key 1 (`a1`), both already scaled by the interval length (glTF 2.0 Appendix C).
fn hermite<T>(v0: T, b0: T, a1: T, v1: T, s: f32) -> T
where
    T: std::ops::Mul<f32, Output = T> + std::ops::Add<Output = T>,
{
    let (s2, s3) = (s * s, s * s * s);
    v0 * (2.0 * s3 - 3.0 * s2 + 1.0) + b0 * (s3 - 2.0 * s2 + s) + v1 * (-2.0 * s3 + 3.0 * s2) + a1 * (s3 - s2)
}

impl Channel {
    /// Samples a vector channel at time `t`. A time exactly on a key gives that key's value
    /// bit for bit.
    fn sample_vec(&self, v: &[Vec3], t: f32) -> Vec3 {
        let (k, s, dt) = locate(&self.times, t);
        match self.interpolation {
            Interpolation::CubicSpline => {
                if s == 0.0 {
                    return v[3 * k + 1];
                }
                hermite(v[3 * k + 1], v[3 * k + 2] * dt, v[3 * (k + 1)] * dt, v[3 * (k + 1) + 1], s)
            }
            _ if s == 0.0 => v[k],
            Interpolation::Step => v[k],
            Interpolation::Linear => v[k].lerp(v[k + 1], s),
        }
    }

    /// Samples a rotation channel at time `t` (shortest-arc slerp; splines renormalised).
    fn sample_quat(&self, q: &[Quat], t: f32) -> Quat {
        let (k, s, dt) = locate(&self.times, t);
        match self.interpolation {
            Interpolation::CubicSpline => {
                if s == 0.0 {
                    return q[3 * k + 1];
                }
                let [v0, b0, a1, v1] =
                    [q[3 * k + 1], q[3 * k + 2] * dt, q[3 * (k + 1)] * dt, q[3 * (k + 1) + 1]].map(Vec4::from);
                Quat::from_vec4(hermite(v0, b0, a1, v1, s)).normalize()
            }
            _ if s == 0.0 => q[k],
            Interpolation::Step => q[k],
            Interpolation::Linear => q[k].slerp(q[k + 1], s),
        }
    }

    /// Samples a weights channel of `n` targets at time `t` into `out` (`v` holds whole keys,
    /// so every index below is in range when `out` has `n` entries).
    fn sample_weights(&self, v: &[f32], n: usize, t: f32, out: &mut [f32]) {
        let (k, s, dt) = locate(&self.times, t);
        for (j, w) in out.iter_mut().enumerate().take(n) {
            *w = match self.interpolation {
                Interpolation::CubicSpline => {
                    let at = |key: usize, part: usize| v[(3 * key + part) * n + j];
                    if s == 0.0 {
                        at(k, 1)
                    } else {
                        hermite(at(k, 1), at(k, 2) * dt, at(k + 1, 0) * dt, at(k + 1, 1), s)
                    }
                }
                _ if s == 0.0 => v[k * n + j],
                Interpolation::Step => v[k * n + j],
                Interpolation::Linear => v[k * n + j] * (1.0 - s) + v[(k + 1) * n + j] * s,
            };
        }
    }

    /// Whether the keys hold as many values as the times and interpolation ask for.
    fn is_whole(&self) -> bool {
        let per_key = if self.interpolation == Interpolation::CubicSpline { 3 } else { 1 };
        let keys = self.times.len() * per_key;
        match &self.keys {
            Keys::Translation(v) | Keys::Scale(v) => v.len() == keys,
            Keys::Rotation(q) => q.len() == keys,
            Keys::Weights { targets, values } => values.len() == keys * targets,
        }
    }
}

impl Clip {
    /// The time within the clip that scene time `t` shows (clips loop).
    fn local_time(&self, t: f32) -> f32 {
        if self.duration > 0.0 && t > self.duration { t.rem_euclid(self.duration) } else { t }
    }

    /// Poses `locals` (indexed like [`NodeGraph::nodes`]) at time `t`, looping over the clip.
    pub fn apply(&self, t: f32, locals: &mut [Transform]) {
        let t = self.local_time(t);
        for ch in &self.channels {
            let Some(local) = locals.get_mut(ch.node) else { continue };
            match &ch.keys {
                Keys::Translation(v) if ch.is_whole() => local.translation = ch.sample_vec(v, t),
                Keys::Rotation(q) if ch.is_whole() => local.rotation = ch.sample_quat(q, t),
                Keys::Scale(v) if ch.is_whole() => local.scale = ch.sample_vec(v, t),
                _ => {}
            }
        }
    }

    /// Sets the morph weights of the nodes it animates (`weights` indexed like
    /// [`NodeGraph::nodes`]) at time `t`; a channel whose target count differs from the
    /// node's is skipped.
    pub fn apply_weights(&self, t: f32, weights: &mut [Vec<f32>]) {
        let t = self.local_time(t);
        for ch in &self.channels {
            if let (Keys::Weights { targets, values }, Some(w)) = (&ch.keys, weights.get_mut(ch.node))
                && w.len() == *targets
                && ch.is_whole()
            {
                ch.sample_weights(values, *targets, t, w);
            }
        }
    }

    /// The (node, property) pairs the clip drives, property 0–3 being translation, rotation,
    /// scale and weights.
    pub fn targets(&self) -> impl Iterator<Item = (usize, usize)> + '_ {
        self.channels.iter().map(|ch| {
            let property = match ch.keys {
                Keys::Translation(_) => 0,
                Keys::Rotation(_) => 1,
                Keys::Scale(_) => 2,
                Keys::Weights { .. } => 3,
            };
            (ch.node, property)
        })
    }
}

/// A node of a loaded hierarchy.
#[derive(Clone, Debug, PartialEq)]
pub struct Node {
    /// Name (or `node N`).
    pub name: String,
    /// Parent, always earlier in [`NodeGraph::nodes`].
    pub parent: Option<usize>,
    /// Local transform when no animation drives it.
    pub rest: Transform,
    /// Morph weights when no animation drives them, one per morph target of the node's mesh
    /// (empty without morph targets).
    pub weights: Vec<f32>,
}

/// A node hierarchy with its animations: the animation system poses it from [`Time`] and
/// writes the world placement of every entity linked to a node.
///
/// [`Time`]: crate::resources::Time
#[derive(Resource, Clone, Debug, Default, PartialEq)]
pub struct NodeGraph {
    /// Nodes, parents before children.
    pub nodes: Vec<Node>,
    /// Animation clips.
    pub clips: Vec<Clip>,
    /// The clips that play together, indices into `clips` (none: the rest pose).
    pub active: Vec<usize>,
    /// Current world transform of every node (written by the animation system).
    pub world: Vec<Affine3A>,
    /// Current morph weights of every node (written by the animation system).
    pub weights: Vec<Vec<f32>>,
}

impl NodeGraph {
    /// For every node, whether some clip can move it (a channel targets it or an ancestor).
    pub fn animated(&self) -> Vec<bool> {
        let mut animated = vec![false; self.nodes.len()];
        for ch in self.clips.iter().flat_map(|c| &c.channels) {
            if let Some(a) = animated.get_mut(ch.node) {
                *a = true;
            }
        }
        for i in 0..self.nodes.len() {
            if let Some(p) = self.nodes[i].parent {
                animated[i] |= animated[p];
            }
        }
        animated
    }

    /// The clips that play, in order.
    pub fn playing(&self) -> impl Iterator<Item = &Clip> {
        self.active.iter().filter_map(|&i| self.clips.get(i))
    }

    /// For every node, whether some clip animates its morph weights.
    pub fn morphing(&self) -> Vec<bool> {
        let mut morphing = vec![false; self.nodes.len()];
        for ch in self.clips.iter().flat_map(|c| &c.channels) {
            if let (Keys::Weights { .. }, Some(m)) = (&ch.keys, morphing.get_mut(ch.node)) {
                *m = true;
            }
        }
        morphing
    }

    /// Morph weights of every node at time `t` under the playing clips.
    pub fn pose_weights(&self, t: f32) -> Vec<Vec<f32>> {
        let mut weights: Vec<Vec<f32>> = self.nodes.iter().map(|n| n.weights.clone()).collect();
        for clip in self.playing() {
            clip.apply_weights(t, &mut weights);
        }
        weights
    }

    /// World transforms of every node at time `t` under the playing clips.
    pub fn pose(&self, t: f32) -> Vec<Affine3A> {
        let mut locals: Vec<Transform> = self.nodes.iter().map(|n| n.rest).collect();
        for clip in self.playing() {
            clip.apply(t, &mut locals);
        }
        let mut world: Vec<Affine3A> = Vec::with_capacity(self.nodes.len());
        for (node, local) in self.nodes.iter().zip(&locals) {
            let m = Affine3A::from_scale_rotation_translation(local.scale, local.rotation, local.translation);
            world.push(match node.parent {
                Some(p) => world[p] * m,
                None => m,
            });
        }
        world
    }
}

/// Makes an entity follow a node of the [`NodeGraph`]: its `Transform` (or its camera) is the
/// node's world transform times `offset`.
#[derive(Component, Clone, Copy, Debug, PartialEq)]
pub struct NodeLink {
    /// Index into [`NodeGraph::nodes`].
    pub node: usize,
    /// Extra transform after the node's (e.g. one `EXT_mesh_gpu_instancing` instance).
    pub offset: Affine3A,
}

/// Up to four (joint slot, weight) pairs per vertex.
pub type Influences = Arc<Vec<[(u16, f32); 4]>>;

/// Linear-blend skinning data of a mesh entity: its `TriangleMesh` holds `rest` deformed by
/// the joints' current world transforms (in world space, with an identity `Transform`).
#[derive(Component, Clone, Debug)]
pub struct Skin {
    /// Joint nodes, indices into [`NodeGraph::nodes`].
    pub joints: Vec<usize>,
    /// Inverse bind matrix of each joint.
    pub inverse_bind: Vec<Affine3A>,
    /// Up to four (joint slot, weight) pairs per vertex of `rest`.
    pub influences: Influences,
    /// The undeformed mesh.
    pub rest: Arc<Mesh>,
}

impl Skin {
    /// The rest vertices deformed by the joints' world transforms `world`.
    pub fn deform(&self, world: &[Affine3A]) -> Vec<Vec3> {
        self.deform_points(world, &self.rest.positions)
    }

    /// `points` (one per vertex of `rest`, e.g. the morphed rest pose) deformed by the
    /// joints' world transforms `world`.
    pub fn deform_points(&self, world: &[Affine3A], points: &[Vec3]) -> Vec<Vec3> {
        let joints: Vec<Affine3A> = self
            .joints
            .iter()
            .zip(&self.inverse_bind)
            .map(|(&j, ibm)| world.get(j).copied().unwrap_or(Affine3A::IDENTITY) * *ibm)
            .collect();
        points
            .iter()
            .zip(self.influences.iter())
            .map(|(&p, inf)| {
                let mut sum = Vec3::ZERO;
                let mut total = 0.0;
                for &(j, w) in inf {
                    if w != 0.0
                        && let Some(m) = joints.get(j as usize)
                    {
                        sum += m.transform_point3(p) * w;
                        total += w;
                    }
                }
                if total > 0.0 { sum / total } else { p }
            })
            .collect()
    }
}

/// Morph targets of a mesh entity: its `TriangleMesh` holds `rest` plus each target's
/// position offsets times the node's current weight (before skinning, as glTF orders them).
/// Shading uses geometric normals, so a target's NORMAL offsets have nothing to move and are
/// not read.
#[derive(Component, Clone, Debug)]
pub struct Morph {
    /// The node whose weights apply, an index into [`NodeGraph::nodes`].
    pub node: usize,
    /// Position offsets per target, one per vertex of `rest` (empty: the target moves none).
    pub targets: Arc<Vec<Vec<Vec3>>>,
    /// The undeformed mesh.
    pub rest: Arc<Mesh>,
}

impl Morph {
    /// The rest vertices moved by the targets under `weights`.
    pub fn deform(&self, weights: &[f32]) -> Vec<Vec3> {
        morph(&self.rest.positions, &self.targets, weights)
    }
}

/// `positions` plus each target's offsets times its weight (a zero weight adds nothing).
pub fn morph(positions: &[Vec3], targets: &[Vec<Vec3>], weights: &[f32]) -> Vec<Vec3> {
    let mut out = positions.to_vec();
    for (target, &w) in targets.iter().zip(weights) {
        if w != 0.0 {
            for (p, d) in out.iter_mut().zip(target) {
                *p += *d * w;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn channel(interpolation: Interpolation, times: Vec<f32>, v: Vec<Vec3>) -> Channel {
        Channel { node: 0, times, keys: Keys::Translation(v), interpolation }
    }

    #[test]
    fn keys_are_exact_and_linear_step_interpolate() {
        let v = vec![Vec3::new(0.1, 0.2, 0.3), Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.0, 0.0, 7.0)];
        let lin = channel(Interpolation::Linear, vec![0.0, 1.0, 3.0], v.clone());
        for (k, &t) in [0.0f32, 1.0, 3.0].iter().enumerate() {
            assert_eq!(lin.sample_vec(&v, t), v[k]);
        }
        assert_eq!(lin.sample_vec(&v, 2.0), (v[1] + v[2]) * 0.5);
        assert_eq!(lin.sample_vec(&v, -5.0), v[0]);
        assert_eq!(lin.sample_vec(&v, 9.0), v[2]);
        let step = channel(Interpolation::Step, vec![0.0, 1.0, 3.0], v.clone());
        assert_eq!(step.sample_vec(&v, 2.9), v[1]);
    }

    #[test]
    fn times_that_are_not_numbers_or_out_of_order_never_index_outside_the_keys() {
        let v = vec![Vec3::X, Vec3::Y, Vec3::Z];
        let lin = channel(Interpolation::Linear, vec![0.0, 1.0, 3.0], v.clone());
        assert_eq!(lin.sample_vec(&v, f32::NAN), v[0]);
        assert_eq!(lin.sample_vec(&v, f32::INFINITY), v[2]);
        assert_eq!(lin.sample_vec(&v, f32::NEG_INFINITY), v[0]);
        assert_eq!(locate(&[], 1.0), (0, 0.0, 0.0));
        // Unsorted keys (the loader refuses them, a hand-built channel may not).
        for t in [0.5, 1.5, 2.5, 5.0] {
            let (k, _, _) = locate(&[1.0, 0.0, 3.0, 2.0], t);
            assert!(k <= 3, "{t}: {k}");
        }
        let clip = Clip { name: "c".into(), channels: vec![lin], duration: 3.0 };
        let mut locals = vec![Transform::IDENTITY];
        for t in [f32::NAN, f32::INFINITY, f32::MAX, -f32::MAX] {
            clip.apply(t, &mut locals);
            assert!(locals[0].translation.is_finite(), "{t}");
        }
    }

    #[test]
    fn cubic_spline_hits_keys_and_follows_tangents() {
        // Keys 0 → 1 over one second with zero tangents: smoothstep.
        let v = vec![Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ZERO, Vec3::ONE, Vec3::ZERO];
        let c = channel(Interpolation::CubicSpline, vec![0.0, 1.0], v.clone());
        assert_eq!(c.sample_vec(&v, 1.0), Vec3::ONE);
        assert!((c.sample_vec(&v, 0.5) - Vec3::splat(0.5)).length() < 1e-6);
        assert!((c.sample_vec(&v, 0.25) - Vec3::splat(0.15625)).length() < 1e-6);
    }

    #[test]
    fn weights_interpolate_per_target_and_short_channels_are_skipped() {
        let keys = Keys::Weights { targets: 2, values: vec![0.0, 1.0, 1.0, 0.0, 0.5, 0.5] };
        let weights = Channel { node: 0, times: vec![0.0, 1.0, 3.0], keys, interpolation: Interpolation::Linear };
        let mut clip = Clip { name: "w".into(), channels: vec![weights], duration: 3.0 };
        let mut w = vec![vec![9.0, 9.0]];
        clip.apply_weights(0.25, &mut w);
        assert_eq!(w[0], [0.25, 0.75]);
        clip.apply_weights(2.0, &mut w);
        assert_eq!(w[0], [0.75, 0.25]);
        clip.channels[0].interpolation = Interpolation::Step;
        clip.apply_weights(2.0, &mut w);
        assert_eq!(w[0], [1.0, 0.0]);
        // A node with another number of targets, or keys that do not fill the times, is left alone.
        let mut three = vec![vec![9.0; 3]];
        clip.apply_weights(2.0, &mut three);
        assert_eq!(three[0], [9.0; 3]);
        clip.channels[0].times.push(4.0);
        let mut untouched = vec![vec![9.0; 2]];
        clip.apply_weights(2.0, &mut untouched);
        assert_eq!(untouched[0], [9.0; 2]);
        assert_eq!(
            morph(&[Vec3::ZERO, Vec3::X], &[vec![Vec3::Y, Vec3::Z], vec![]], &[0.5, 1.0]),
            [Vec3::new(0.0, 0.5, 0.0), Vec3::new(1.0, 0.0, 0.5)]
        );
    }

    #[test]
    fn rotations_slerp_the_short_way_and_clips_loop() {
        let q = vec![Quat::IDENTITY, Quat::from_rotation_y(1.0)];
        let clip = Clip {
            name: "spin".into(),
            channels: vec![Channel {
                node: 0,
                times: vec![0.0, 2.0],
                keys: Keys::Rotation(q.clone()),
                interpolation: Interpolation::Linear,
            }],
            duration: 2.0,
        };
        let mut locals = vec![Transform::IDENTITY];
        clip.apply(1.0, &mut locals);
        assert!(locals[0].rotation.angle_between(Quat::from_rotation_y(0.5)) < 1e-5);
        clip.apply(3.0, &mut locals);
        assert!(locals[0].rotation.angle_between(Quat::from_rotation_y(0.5)) < 1e-5, "loops");
    }
}
