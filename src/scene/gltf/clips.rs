//! Reading animations and choosing which play: exporters such as Blender's write one clip per
//! animated object (the camera, each light, each model), so the clips of such a file play
//! together by default, `SpawnOptions::animation` chooses any set of them, and a clip that
//! cannot be read costs only itself.

use ::gltf::animation::{Interpolation as GltfInterpolation, Property};

use super::*;
use crate::animation::{Channel, Interpolation, Keys};

impl GltfScene {
    /// Names of the animations that can be played, in file order.
    pub fn animation_names(&self) -> Vec<&str> {
        self.graph.clips.iter().map(|c| c.name.as_str()).collect()
    }

    /// How long the clips that `key` chooses ([`SpawnOptions::animation`]) play: the longest
    /// one's duration. `None` when none would play, or `key` is refused (spawning says why).
    pub fn animation_duration(&self, key: Option<&str>) -> Option<f32> {
        let chosen = self.select_clips(key).ok()?;
        chosen.iter().map(|&i| self.graph.clips[i].duration).reduce(f32::max)
    }

    /// The clips (indices into `graph.clips`) that `key` chooses: `all`, or a comma-separated
    /// list of names and file indices (a whole name wins over splitting it at its commas).
    /// Without a key: every clip when no two animate the same node, else the first. Clips that
    /// would drive the same property of a node are refused together, since neither can win.
    pub(super) fn select_clips(&self, key: Option<&str>) -> Result<Vec<usize>, String> {
        let clips = &self.graph.clips;
        let disjoint = || {
            let mut owner: HashMap<usize, usize> = HashMap::new();
            clips.iter().enumerate().all(|(i, c)| c.channels.iter().all(|ch| *owner.entry(ch.node).or_insert(i) == i))
        };
        let mut chosen: Vec<usize> = match key {
            None if disjoint() => (0..clips.len()).collect(),
            None => (0..clips.len().min(1)).collect(),
            Some(key) if clips.iter().any(|c| c.name == key) => {
                clips.iter().position(|c| c.name == key).into_iter().collect()
            }
            Some(key) => {
                let mut chosen = Vec::new();
                for part in key.split(',').map(str::trim) {
                    match part {
                        "all" => chosen.extend(0..clips.len()),
                        _ => chosen.push(self.find_clip(part)?),
                    }
                }
                chosen
            }
        };
        chosen.sort_unstable();
        chosen.dedup();
        let mut driver: HashMap<(usize, usize), usize> = HashMap::new();
        for &i in &chosen {
            for (node, property) in clips[i].targets() {
                let first = *driver.entry((node, property)).or_insert(i);
                if first != i {
                    let what = ["translation", "rotation", "scale", "morph weights"][property];
                    return Err(format!(
                        "animations '{}' and '{}' both drive the {what} of node '{}'; play one of them",
                        clips[first].name, clips[i].name, self.graph.nodes[node].name
                    ));
                }
            }
        }
        Ok(chosen)
    }

    /// One clip by file index or name; a clip that could not be read says why.
    fn find_clip(&self, key: &str) -> Result<usize, String> {
        let by_index = key.parse::<usize>().ok();
        let found = match by_index {
            Some(i) => self.clip_index.iter().position(|&f| f == i),
            None => self.graph.clips.iter().position(|c| c.name == key),
        };
        if let Some(i) = found {
            return Ok(i);
        }
        if let Some((_, _, why)) =
            self.refused_clips.iter().find(|(i, name, _)| by_index.map_or(name == key, |k| k == *i))
        {
            return Err(why.clone());
        }
        let names: Vec<String> = (self.clip_index.iter().zip(&self.graph.clips))
            .map(|(i, c)| format!("{i}: {}", c.name))
            .chain(self.refused_clips.iter().map(|(i, name, _)| format!("{i}: {name} (unplayable)")))
            .collect();
        if names.is_empty() {
            return Err(format!("no animation '{key}': the file has none"));
        }
        Err(format!("no animation '{key}' (available: {}, or all)", names.join(", ")))
    }
}

/// One animation's channels (its name is set by the caller). Any error refuses this clip
/// alone; channels of nodes outside the scene are left out.
pub(super) fn read_clip(
    animation: &::gltf::Animation,
    buffers: &Data,
    graph_index: &[Option<usize>],
    nodes: &[Node],
    warnings: &mut Vec<String>,
) -> Result<Clip, String> {
    let mut channels = Vec::new();
    let mut duration: f32 = 0.0;
    for ch in animation.channels() {
        let target = ch.target().node();
        let Some(node) = graph_index[target.index()] else { continue };
        let ch_label = format!("channel {} ({} of {})", ch.index(), property_name(ch.target().property()), {
            label("node", target.index(), target.name())
        });
        let sampler = ch.sampler();
        let times = accessors::floats::<f32>(&sampler.input(), Dimensions::Scalar, buffers)
            .map_err(|e| format!("{ch_label} input {e}"))?;
        if times.iter().any(|t| !t.is_finite()) || times.windows(2).any(|w| w[1] < w[0]) {
            return Err(format!("{ch_label}: key times must be finite and non-decreasing"));
        }
        let interpolation = match sampler.interpolation() {
            GltfInterpolation::Step => Interpolation::Step,
            GltfInterpolation::Linear => Interpolation::Linear,
            GltfInterpolation::CubicSpline => Interpolation::CubicSpline,
        };
        let cubic = interpolation == Interpolation::CubicSpline;
        // Values per key: a spline keeps an in-tangent and an out-tangent beside each value.
        let per_key = if cubic { 3 } else { 1 };
        let output = sampler.output();
        let out_err = |e: String| format!("{ch_label} output {e}");
        let vec3 = || -> Result<Vec<Vec3>, String> {
            let v: Vec<Vec3> = accessors::floats::<[f32; 3]>(&output, Dimensions::Vec3, buffers)
                .map_err(out_err)?
                .into_iter()
                .map(Vec3::from)
                .collect();
            match v.iter().position(|x| !x.is_finite()) {
                Some(i) => Err(format!("{ch_label} output value {i} is not finite ({})", v[i])),
                None => Ok(v),
            }
        };
        let keys = match ch.target().property() {
            Property::Translation => Keys::Translation(vec3()?),
            Property::Scale => Keys::Scale(vec3()?),
            Property::Rotation => {
                let raw = accessors::quats(&output, buffers).map_err(out_err)?;
                let mut keys = Vec::with_capacity(raw.len());
                for (i, q) in raw.into_iter().enumerate() {
                    let q = Quat::from_array(q);
                    if !q.is_finite() {
                        return Err(format!("{ch_label} output value {i}: quaternion {q} is not finite"));
                    }
                    // A spline's in- and out-tangents (all but the middle of each three) are
                    // not rotations: they stay as they are, zero included, and only the
                    // interpolated value is normalised.
                    if cubic && i % 3 != 1 {
                        keys.push(q);
                        continue;
                    }
                    if q.length() <= 1e-6 {
                        let key = i / per_key;
                        return Err(format!("{ch_label} key {key}: quaternion {q} is zero and cannot be normalised"));
                    }
                    keys.push(q.normalize());
                }
                Keys::Rotation(keys)
            }
            Property::MorphTargetWeights => {
                let targets = nodes[node].weights.len();
                if targets == 0 {
                    warnings.push(format!(
                        "{}: {ch_label}: the node's mesh has no morph targets; channel ignored",
                        label("animation", animation.index(), animation.name())
                    ));
                    continue;
                }
                let values = accessors::floats::<f32>(&output, Dimensions::Scalar, buffers).map_err(out_err)?;
                if let Some(i) = values.iter().position(|x| !x.is_finite()) {
                    return Err(format!("{ch_label} output value {i} is not finite ({})", values[i]));
                }
                Keys::Weights { targets, values }
            }
        };
        let (values, per_value) = match &keys {
            Keys::Translation(v) | Keys::Scale(v) => (v.len(), 1),
            Keys::Rotation(q) => (q.len(), 1),
            Keys::Weights { targets, values } => (values.len(), *targets),
        };
        let expected = times.len() * per_key * per_value;
        if values != expected {
            let what = match (cubic, per_value) {
                (false, 1) => String::new(),
                (true, 1) => " (in-tangent, value, out-tangent per key)".into(),
                (false, n) => format!(" ({n} weights per key)"),
                (true, n) => format!(" ({n} in-tangents, values and out-tangents per key)"),
            };
            return Err(format!(
                "{ch_label}: {values} output values for {} keys; expected {expected}{what}",
                times.len()
            ));
        }
        duration = duration.max(*times.last().unwrap_or(&0.0));
        channels.push(Channel { node, times, keys, interpolation });
    }
    Ok(Clip { name: String::new(), channels, duration })
}

fn property_name(p: Property) -> &'static str {
    match p {
        Property::Translation => "translation",
        Property::Rotation => "rotation",
        Property::Scale => "scale",
        Property::MorphTargetWeights => "weights",
    }
}
