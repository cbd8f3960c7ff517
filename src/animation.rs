//! Node hierarchies, keyframe animation and skinning: the data the animation and skinning
//! systems read. Sampling follows the glTF 2.0 rules (STEP, LINEAR with quaternion slerp,
//! CUBICSPLINE Hermite splines), and a time before the first or after the last key holds the
//! end value; clips loop over their duration.

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
}

impl Clip {
    /// Poses `locals` (indexed like [`NodeGraph::nodes`]) at time `t`, looping over the clip.
    pub fn apply(&self, t: f32, locals: &mut [Transform]) {
        let t = if self.duration > 0.0 && t > self.duration { t.rem_euclid(self.duration) } else { t };
        for ch in &self.channels {
            let Some(local) = locals.get_mut(ch.node) else { continue };
            match &ch.keys {
                Keys::Translation(v) => local.translation = ch.sample_vec(v, t),
                Keys::Rotation(q) => local.rotation = ch.sample_quat(q, t),
                Keys::Scale(v) => local.scale = ch.sample_vec(v, t),
            }
        }
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
    /// The clip that plays (`None`: the rest pose).
    pub active: Option<usize>,
    /// Current world transform of every node (written by the animation system).
    pub world: Vec<Affine3A>,
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

    /// World transforms of every node at time `t` under the active clip.
    pub fn pose(&self, t: f32) -> Vec<Affine3A> {
        let mut locals: Vec<Transform> = self.nodes.iter().map(|n| n.rest).collect();
        if let Some(clip) = self.active.and_then(|i| self.clips.get(i)) {
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
        let joints: Vec<Affine3A> = self
            .joints
            .iter()
            .zip(&self.inverse_bind)
            .map(|(&j, ibm)| world.get(j).copied().unwrap_or(Affine3A::IDENTITY) * *ibm)
            .collect();
        self.rest
            .positions
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
