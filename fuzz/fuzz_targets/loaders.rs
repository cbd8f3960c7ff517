//! The glTF and peer-scene loaders on arbitrary bytes: they must return an error of one line
//! or a scene that spawns, never panic, abort or allocate without bound (libFuzzer's
//! `-rss_limit_mb` and `-malloc_limit_mb` catch the last).
//!
//! The first byte picks the loader (even: glTF/GLB, odd: peer scene); the rest is the file.
//! Seed the corpus from the shared assets with `fuzz/seed.sh`, then from the repository root:
//! `cargo +nightly fuzz run loaders -- -rss_limit_mb=2048 -malloc_limit_mb=1024 -timeout=10`.
#![no_main]

use std::path::Path;

use hemi::{
    cli::peer_scene::PeerScene,
    bevy_ecs::world::World,
    scene::{
        gltf::{self, LoadOptions, SpawnOptions},
    },
};
use libfuzzer_sys::fuzz_target;

fn one_line(e: &hemi::HemiError) {
    let text = e.to_string();
    assert!(!text.contains('\n'), "error of more than one line: {text}");
}

fuzz_target!(|data: &[u8]| {
    let Some((&kind, bytes)) = data.split_first() else { return };
    let options = LoadOptions::default();
    let mut world = World::new();
    if kind % 2 == 0 {
        match gltf::from_slice(bytes, Path::new("corpus/input.gltf"), &options) {
            Ok(scene) => {
                for time in [0.0, 0.5, 1e30] {
                    if let Err(e) = scene.spawn(&mut World::new(), &SpawnOptions { time, ..Default::default() }) {
                        one_line(&e);
                    }
                }
            }
            Err(e) => one_line(&e),
        }
    } else {
        match PeerScene::from_slice(bytes, Path::new("corpus/input.json"), &options) {
            Ok(scene) => {
                if let Err(e) = scene.spawn(&mut world) {
                    one_line(&e);
                }
            }
            Err(e) => one_line(&e),
        }
    }
});
