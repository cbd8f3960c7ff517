//! Which animations play: exporters such as Blender's write one clip per animated object (the
//! camera, each light, each model), so the clips of such a file play together by default, and
//! `SpawnOptions::animation` chooses any set of them.

use super::*;

impl GltfScene {
    /// Names of the animations that can be played, in file order.
    pub fn animation_names(&self) -> Vec<&str> {
        self.graph.clips.iter().map(|c| c.name.as_str()).collect()
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
