//! Spawning a loaded glTF scene into a world: meshes placed by their nodes, lights, the
//! camera (the file's, or one framing the scene), the node graph and its animation.

use super::*;
use crate::animation::Morph;

impl GltfScene {
    /// Number of triangles the default scene places (each mesh counted once per node and
    /// per GPU instance that uses it), as `SOURCES.md`'s "scene" column counts them.
    pub fn scene_triangle_count(&self) -> usize {
        self.placements
            .iter()
            .map(|p| p.offsets.len() * self.meshes[p.mesh].iter().map(|m| m.mesh.triangle_count()).sum::<usize>())
            .sum()
    }

    /// Spawns the scene into `world`: mesh instances, lights, the chosen camera (or one that
    /// frames the scene when the file has none), a default ambient occluder when the world has
    /// none, the [`NodeGraph`] and [`Time`].
    pub fn spawn(&self, world: &mut World, options: &SpawnOptions) -> Result<(), HemiError> {
        let fail = |message: String| HemiError::Load { path: self.path.clone(), message };
        if !options.time.is_finite() {
            return Err(HemiError::Usage(format!("scene time {} s is not a finite number", options.time)));
        }
        let mut graph = self.graph.clone();
        graph.active = self.select_clips(options.animation.as_deref()).map_err(fail)?;
        graph.world = graph.pose(options.time);
        graph.weights = graph.pose_weights(options.time);
        let camera = match &options.camera {
            None => self.cameras.first(),
            Some(key) => Some(choose(&self.cameras, key, |c| c.index, |c| &c.name).ok_or_else(|| {
                let names: Vec<String> = self.cameras.iter().map(|c| format!("{}: {}", c.index, c.name)).collect();
                fail(format!("no camera '{key}' (available: {})", list(&names)))
            })?),
        };

        let mut bounds: Option<(Vec3, Vec3)> = None;
        // Names primitive `k` of placement `p` in messages.
        let what = |p: usize, k: usize| {
            let placement = &self.placements[p];
            let prim = self.labels.get(placement.mesh).and_then(|l| l.get(k)).map_or("a mesh", String::as_str);
            format!("{prim} at node '{}'", graph.nodes[placement.node].name)
        };
        // The placed vertex farthest from the origin: (distance, placement, primitive, vertex, where).
        let mut farthest = (-1.0f32, 0, 0, 0, Vec3::ZERO);
        let mut grow = |mesh: &Mesh, m: &Affine3A, (p, k): (usize, usize)| -> Result<(), String> {
            for (i, v) in mesh.positions.iter().enumerate() {
                let q = m.transform_point3(*v);
                if !q.is_finite() {
                    return Err(format!("{}: vertex {i} {v} is not finite once placed ({q})", what(p, k)));
                }
                bounds = Some(bounds.map_or((q, q), |(lo, hi)| (lo.min(q), hi.max(q))));
                if q.abs().max_element() > farthest.0 {
                    farthest = (q.abs().max_element(), p, k, i, q);
                }
            }
            Ok(())
        };
        let animated = graph.animated();
        let morphing = graph.morphing();
        for (pi, placement) in self.placements.iter().enumerate() {
            let node_world = graph.world[placement.node];
            let node_name = &graph.nodes[placement.node].name;
            let skin = placement.skin.map(|s| &self.skins[s]);
            for (k, prim) in self.meshes[placement.mesh].iter().enumerate() {
                let name = Name::new(format!("{node_name}/{k}"));
                let morph = (!prim.targets.is_empty()).then(|| Morph {
                    node: placement.node,
                    targets: prim.targets.clone(),
                    rest: prim.mesh.clone(),
                });
                let morphed = morph.as_ref().map(|m| m.deform(&graph.weights[placement.node]));
                if let (Some(skin), Some(influences), false) = (skin, &prim.influences, options.geometry_only) {
                    // Skinned: vertices in world space, the node's own transform ignored (glTF).
                    let skin = Skin {
                        joints: skin.joints.clone(),
                        inverse_bind: skin.inverse_bind.clone(),
                        influences: influences.clone(),
                        rest: prim.mesh.clone(),
                    };
                    let positions = match &morphed {
                        Some(points) => skin.deform_points(&graph.world, points),
                        None => skin.deform(&graph.world),
                    };
                    let posed = Mesh { positions, indices: prim.mesh.indices.clone() };
                    grow(&posed, &Affine3A::IDENTITY, (pi, k)).map_err(fail)?;
                    let mut entity = world.spawn((
                        TriangleMesh(Arc::new(posed)),
                        Deforming { rest: prim.mesh.clone() },
                        skin,
                        Transform::IDENTITY,
                        prim.material,
                        name,
                    ));
                    if let Some(morph) = morph {
                        entity.insert(morph);
                    }
                    if let Some(surface) = &prim.surface {
                        entity.insert(surface.clone());
                    }
                    continue;
                }
                // A morph whose weights never change is a mesh like any other.
                let mesh = match morphed {
                    Some(positions) => Arc::new(Mesh { positions, indices: prim.mesh.indices.clone() }),
                    None => prim.mesh.clone(),
                };
                let deforming = morph.filter(|_| morphing[placement.node] && !options.geometry_only);
                for offset in &placement.offsets {
                    let m = node_world * *offset;
                    grow(&mesh, &m, (pi, k)).map_err(fail)?;
                    let mut entity = world.spawn((
                        TriangleMesh(mesh.clone()),
                        Transform::from_affine(&m),
                        prim.material,
                        name.clone(),
                    ));
                    // Peer scenes (geometry only) keep the peers' contract: plain matte surfaces.
                    if !options.geometry_only {
                        if let Some(surface) = &prim.surface {
                            entity.insert(surface.clone());
                        }
                        entity.insert(NodeLink { node: placement.node, offset: *offset });
                        if animated[placement.node] {
                            entity.insert(Dynamic);
                        }
                    }
                    if let Some(morph) = &deforming {
                        entity.insert((Deforming { rest: prim.mesh.clone() }, morph.clone()));
                    }
                }
            }
        }
        if options.geometry_only {
            return Ok(());
        }
        for &(node, light) in &self.lights {
            let t = Transform::from_affine(&graph.world[node]);
            let mut entity = world.spawn((
                t,
                NodeLink { node, offset: Affine3A::IDENTITY },
                Name::new(graph.nodes[node].name.clone()),
            ));
            match light {
                GltfLight::Point(l) => entity.insert(l),
                GltfLight::Spot(l) => entity.insert(l),
                GltfLight::Directional(l) => entity.insert(l),
            };
        }
        match camera {
            Some(c) => {
                let t = Transform::from_affine(&graph.world[c.node]);
                let link = NodeLink { node: c.node, offset: Affine3A::IDENTITY };
                match c.projection {
                    Projection::Perspective(vfov) => world.spawn((Camera::from_transform(&t, vfov), link)),
                    Projection::Orthographic(h) => world.spawn((OrthographicCamera::from_transform(&t, h), link)),
                };
            }
            None => {
                let bounds = framing::union(bounds, self.moving_bounds(&graph, &options.framing_times));
                let camera = framing_camera(bounds.unwrap_or((Vec3::splat(-1.0), Vec3::ONE)));
                if !(camera.eye.is_finite() && camera.target.is_finite()) {
                    let (_, p, k, i, q) = farthest;
                    return Err(fail(format!(
                        "the file has no camera and the scene is too large to frame ({}: vertex {i} lies at {q})",
                        what(p, k)
                    )));
                }
                world.spawn(camera);
            }
        }
        if world.query::<&AmbientOccluder>().iter(world).next().is_none() {
            world.spawn(AmbientOccluder::default());
        }
        world.insert_resource(Time { seconds: options.time });
        world.insert_resource(graph);
        Ok(())
    }
}

fn list(names: &[String]) -> String {
    if names.is_empty() { "none".into() } else { names.join(", ") }
}
