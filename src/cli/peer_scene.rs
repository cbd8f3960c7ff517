//! The peer renderers' scene format (`../shared/peers/scenes/*.json`): glTF meshes, a pinhole
//! camera, AO settings and point lights, rendered under their contract (pixel-centre primary
//! rays, two-sided geometric normals, cosine-weighted AO, Lambertian point lights with 1/d²).
//!
//! The scene file and its meshes must be regular files of at most [`MAX_FILE_BYTES`]. Mesh
//! paths are resolved against the scene file's folder and may lead out of it (the shared
//! scenes name `../../assets/…`); the meshes' own external buffers follow the
//! [`LoadOptions`] given to [`PeerScene::load_with`].

use std::path::{Path, PathBuf};

use bevy_ecs::prelude::World;
use glam::Vec3;
use serde::Deserialize;

use super::npy;
use crate::{
    components::{AmbientOccluder, Camera, PointLight, Transform},
    error::HemiError,
    resources::RenderSettings,
    scene::gltf::{self, LoadOptions, MAX_FILE_BYTES, SpawnOptions, buffers::read_file},
};

#[derive(Deserialize)]
#[serde(untagged)]
enum OneOrMany {
    One(String),
    Many(Vec<String>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraJson {
    eye: [f32; 3],
    target: [f32; 3],
    up: [f32; 3],
    vfov_deg: f32,
}

#[derive(Deserialize)]
struct AoJson {
    samples: u32,
    max_distance: Option<f32>,
    epsilon: Option<f32>,
}

#[derive(Deserialize)]
struct LightJson {
    position: [f32; 3],
    intensity: [f32; 3],
}

#[derive(Deserialize)]
struct SceneJson {
    name: String,
    mesh: OneOrMany,
    camera: CameraJson,
    width: u32,
    height: u32,
    ao: AoJson,
    #[serde(default)]
    point_lights: Vec<LightJson>,
    seed: u64,
}

/// A peer scene, read and checked.
#[derive(Clone, Debug, PartialEq)]
pub struct PeerScene {
    /// The JSON file.
    pub path: PathBuf,
    /// Scene name (names the reference files `refs/<name>.ao.npy`, `.hit.npy`).
    pub name: String,
    /// Mesh files, resolved against the JSON's folder.
    pub meshes: Vec<PathBuf>,
    /// The pinhole camera.
    pub camera: Camera,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Default AO samples per pixel.
    pub samples: u32,
    /// AO ray length (∞ when `null`).
    pub max_distance: f32,
    /// How far along the normal shadow and AO rays start (`ao.epsilon`; 0 when `null`): the
    /// renderer's [`RenderSettings::ray_offset`], which [`PeerScene::spawn`] sets.
    pub epsilon: f32,
    /// Point lights: position and radiant intensity per channel.
    pub lights: Vec<(Vec3, Vec3)>,
    /// The scene's seed.
    pub seed: u64,
    /// How the meshes are loaded by [`PeerScene::spawn`].
    pub load_options: LoadOptions,
}

impl PeerScene {
    /// Reads a scene file with the default [`LoadOptions`]; errors name the file and what is
    /// wrong.
    pub fn load(path: &Path) -> Result<Self, HemiError> {
        Self::load_with(path, &LoadOptions::default())
    }

    /// Reads a scene file (a regular file of at most [`MAX_FILE_BYTES`]) whose meshes will be
    /// loaded with `options`; errors name the file and what is wrong.
    pub fn load_with(path: &Path, options: &LoadOptions) -> Result<Self, HemiError> {
        let fail = |message: String| HemiError::Load { path: path.to_path_buf(), message };
        let bytes = read_file(path, MAX_FILE_BYTES).map_err(fail)?;
        Self::from_slice(&bytes, path, options)
    }

    /// Reads a scene file already in memory; `path` names it in errors and mesh paths are
    /// resolved against its folder.
    pub fn from_slice(bytes: &[u8], path: &Path, options: &LoadOptions) -> Result<Self, HemiError> {
        let fail = |message: String| HemiError::Load { path: path.to_path_buf(), message };
        let text = std::str::from_utf8(bytes).map_err(|e| fail(format!("not a peer scene: not UTF-8 text ({e})")))?;
        let json: SceneJson = serde_json::from_str(text).map_err(|e| fail(format!("not a peer scene: {e}")))?;
        let samples = json.ao.samples;
        if !(1..=RenderSettings::MAX_SPP).contains(&samples) {
            return Err(fail(format!(
                "ao.samples {samples} must be between 1 and {} (the --spp limit)",
                RenderSettings::MAX_SPP
            )));
        }
        let dir = path.parent().unwrap_or(Path::new("."));
        let meshes = match json.mesh {
            OneOrMany::One(m) => vec![m],
            OneOrMany::Many(ms) => ms,
        };
        let c = json.camera;
        let scene = PeerScene {
            path: path.to_path_buf(),
            name: json.name,
            meshes: meshes.iter().map(|m| dir.join(m)).collect(),
            camera: Camera { eye: c.eye.into(), target: c.target.into(), up: c.up.into(), vfov_degrees: c.vfov_deg },
            width: json.width,
            height: json.height,
            samples,
            max_distance: json.ao.max_distance.unwrap_or(f32::INFINITY),
            epsilon: json.ao.epsilon.unwrap_or(0.0),
            lights: json.point_lights.iter().map(|l| (l.position.into(), l.intensity.into())).collect(),
            seed: json.seed,
            load_options: *options,
        };
        scene.camera.validate().map_err(fail)?;
        if scene.max_distance.is_nan() || scene.max_distance <= 0.0 {
            return Err(fail(format!("ao.max_distance {} must be positive or null", scene.max_distance)));
        }
        if !(scene.epsilon.is_finite() && scene.epsilon >= 0.0) {
            return Err(fail(format!("ao.epsilon {} must be finite and non-negative, or null", scene.epsilon)));
        }
        if let Some((p, i)) =
            scene.lights.iter().find(|(p, i)| !p.is_finite() || !i.is_finite() || i.min_element() < 0.0)
        {
            return Err(fail(format!("point light at {p} with intensity {i} is not usable")));
        }
        Ok(scene)
    }

    /// Spawns meshes (as static geometry, albedo = baseColorFactor), camera, occluder and lights,
    /// and sets the world's [`RenderSettings::ray_offset`] (where it has settings) to the
    /// scene's `epsilon`. Returns the loaders' warnings.
    pub fn spawn(&self, world: &mut World) -> Result<Vec<String>, HemiError> {
        if let Some(mut settings) = world.get_resource_mut::<RenderSettings>() {
            settings.ray_offset = self.epsilon;
        }
        let mut warnings = Vec::new();
        for mesh in &self.meshes {
            let scene = gltf::load_with(mesh, &LoadOptions { geometry_only: true, ..self.load_options })?;
            warnings.extend(scene.warnings.iter().map(|w| format!("{}: {w}", mesh.display())));
            scene.spawn(world, &SpawnOptions { geometry_only: true, ..Default::default() })?;
        }
        world.spawn(self.camera);
        world.spawn(AmbientOccluder { max_distance: self.max_distance, ..Default::default() });
        for &(position, intensity) in &self.lights {
            world.spawn((
                PointLight { ls: 1.0, color: intensity, shadows: true, falloff: true },
                Transform::from_translation(position),
            ));
        }
        Ok(warnings)
    }

    /// Reference files beside the scenes: `<scenes>/../refs/<name>.ao.npy` and `.hit.npy`.
    pub fn reference_paths(&self) -> (PathBuf, PathBuf) {
        let refs = self.path.parent().unwrap_or(Path::new(".")).join("../refs");
        (refs.join(format!("{}.ao.npy", self.name)), refs.join(format!("{}.hit.npy", self.name)))
    }

    /// The reference AO and hit mask per pixel (row-major), checked against the scene's size.
    pub fn read_reference(&self) -> Result<(Vec<f32>, Vec<bool>), HemiError> {
        let (ao_path, hit_path) = self.reference_paths();
        let ao = npy::read_f32(&ao_path)?;
        let hit = npy::read_bool(&hit_path)?;
        let size = (self.height as usize, self.width as usize);
        if (ao.rows, ao.cols) != size || (hit.rows, hit.cols) != size {
            return Err(HemiError::Io {
                path: ao_path,
                message: format!("reference is {}x{}, the scene {}x{}", ao.cols, ao.rows, self.width, self.height),
            });
        }
        Ok((ao.data, hit.data))
    }
}
