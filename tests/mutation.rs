//! A seeded mutation test of the glTF and peer-scene loaders: a few thousand files made from
//! the shared assets by changing numbers, indices, counts, strides, URIs and keys of their
//! JSON, and by flipping bytes of GLB files, each loaded and spawned in a child process (this
//! test binary run again) whose address space is limited to [`MEMORY_LIMIT`]. Every file
//! must give a one-line error naming it, or a scene that spawns; no panic, no abort, no
//! runaway allocation. The seed is fixed; `HEMI_MUTANTS=N` changes how many files are made.

use std::{
    io::{BufRead, BufReader, Write},
    path::{Path, PathBuf},
    process::{Command, Stdio},
    time::{Duration, Instant},
};

use hemi::{
    bevy_ecs::world::World,
    cli::peer_scene::PeerScene,
    scene::gltf::{self, SpawnOptions},
};
use serde_json::{Value, json};

/// The child's address-space limit.
const MEMORY_LIMIT: u64 = 2 << 30;

/// Mutated files made by default.
const DEFAULT_MUTANTS: usize = 3000;

/// Files each child loads.
const BATCH: usize = 250;

/// The environment variable naming a child's list of files.
const LIST_VAR: &str = "HEMI_MUTATION_LIST";

/// SplitMix64: a small, fixed, seedable generator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }

    fn pick<'a, T>(&mut self, items: &'a [T]) -> &'a T {
        &items[self.below(items.len())]
    }
}

fn shared() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared")
}

/// Small glTF files whose JSON is mutated (external buffers are copied beside the mutants).
const GLTF: &[&str] = &[
    "Box/glTF/Box.gltf",
    "Box/glTF-Embedded/Box.gltf",
    "BoxAnimated/glTF/BoxAnimated.gltf",
    "SimpleSkin/glTF/SimpleSkin.gltf",
    "SimpleSparseAccessor/glTF/SimpleSparseAccessor.gltf",
    "AnimatedCube/glTF/AnimatedCube.gltf",
    "TriangleWithoutIndices/glTF/TriangleWithoutIndices.gltf",
    "Cameras/glTF/Cameras.gltf",
    "AnimatedTriangle/glTF/AnimatedTriangle.gltf",
    "SimpleMeshes/glTF/SimpleMeshes.gltf",
    "MeshPrimitiveModes/glTF/MeshPrimitiveModes.gltf",
    "MultipleScenes/glTF/MultipleScenes.gltf",
];

/// Small GLB files whose bytes are flipped, or whose JSON chunk is mutated.
const GLB: &[&str] = &[
    "Box/glTF-Binary/Box.glb",
    "BoxAnimated/glTF-Binary/BoxAnimated.glb",
    "SimpleInstancing/glTF-Binary/SimpleInstancing.glb",
    "NegativeScaleTest/glTF-Binary/NegativeScaleTest.glb",
];

/// Peer scenes with small meshes (their mesh paths made absolute).
const PEERS: &[&str] = &["cornell.json", "many_spheres.json", "sphere_plane.json"];

/// Every path to a number, string or container in `v`, as JSON pointers.
fn pointers(v: &Value, at: String, out: &mut Vec<String>) {
    match v {
        Value::Object(map) => {
            for (k, x) in map {
                // Megabytes of base64 are not worth mutating character by character.
                pointers(x, format!("{at}/{}", k.replace('~', "~0").replace('/', "~1")), out);
            }
        }
        Value::Array(items) => {
            for (i, x) in items.iter().enumerate() {
                pointers(x, format!("{at}/{i}"), out);
            }
        }
        _ => {}
    }
    out.push(at);
}

/// One change to a JSON document.
fn mutate_json(v: &mut Value, rng: &mut Rng) {
    let mut all = Vec::new();
    pointers(v, String::new(), &mut all);
    let at = rng.pick(&all).clone();
    let target = if at.is_empty() { &mut *v } else { v.pointer_mut(&at).unwrap() };
    let numbers = [
        json!(0),
        json!(1),
        json!(-1),
        json!(2),
        json!(3),
        json!(4),
        json!(7),
        json!(255),
        json!(65535),
        json!(1u64 << 28),
        json!(1u64 << 31),
        json!(u32::MAX),
        json!(u64::MAX),
        json!(1e39),
        json!(-1e39),
        json!(3.4e38),
        json!(1e-45),
        json!(0.5),
    ];
    let strings = [
        json!("../../../../etc/passwd"),
        json!("/dev/zero"),
        json!("/proc/self/mem"),
        json!("%2e%2e/%2e%2e/x.bin"),
        json!("file:///etc/passwd"),
        json!("data:application/octet-stream;base64,AAAA"),
        json!("data:,"),
        json!(""),
        json!("nonexistent.bin"),
        json!("CUBICSPLINE"),
        json!("STEP"),
        json!("rotation"),
        json!("weights"),
        json!("MAT4"),
        json!("VEC2"),
        json!("perspective"),
        json!("orthographic"),
        json!("spot"),
    ];
    match target {
        Value::Number(n) => {
            *target = match rng.below(4) {
                0 => rng.pick(&numbers).clone(),
                1 => json!(rng.below(24)),
                2 => json!(n.as_f64().unwrap_or(0.0) * 2.0 + 1.0),
                _ => json!(n.as_i64().unwrap_or(0) - 1),
            }
        }
        Value::String(_) => *target = rng.pick(&strings).clone(),
        Value::Bool(b) => *b = !*b,
        Value::Null => *target = rng.pick(&numbers).clone(),
        Value::Array(items) => match rng.below(4) {
            0 if !items.is_empty() => {
                let i = rng.below(items.len());
                items.remove(i);
            }
            1 if !items.is_empty() => {
                let x = items[rng.below(items.len())].clone();
                items.push(x);
            }
            2 => items.push(rng.pick(&numbers).clone()),
            _ => *target = rng.pick(&numbers).clone(),
        },
        Value::Object(map) => {
            let keys = [
                "byteStride",
                "count",
                "byteOffset",
                "bufferView",
                "sparse",
                "node",
                "children",
                "rotation",
                "scale",
                "matrix",
                "skin",
                "mesh",
                "camera",
                "indices",
                "mode",
            ];
            match rng.below(3) {
                0 if !map.is_empty() => {
                    let k = map.keys().nth(rng.below(map.len())).unwrap().clone();
                    map.remove(&k);
                }
                1 => {
                    let sparse = json!({"count": rng.pick(&numbers).clone(),
                        "indices": {"bufferView": rng.below(4), "componentType": 5125},
                        "values": {"bufferView": rng.below(4)}});
                    map.insert("sparse".into(), sparse);
                }
                _ => {
                    let value = match rng.below(3) {
                        0 => json!([rng.below(4), rng.below(4)]),
                        1 => json!([0.0, 0.0, 0.0, 0.0]),
                        _ => rng.pick(&numbers).clone(),
                    };
                    map.insert(rng.pick(&keys).to_string(), value);
                }
            }
        }
    }
}

/// The JSON chunk and the rest of a GLB.
fn split_glb(glb: &[u8]) -> (Value, Vec<u8>) {
    let len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    (serde_json::from_slice(&glb[20..20 + len]).unwrap(), glb[20 + len..].to_vec())
}

fn join_glb(json: &Value, rest: &[u8]) -> Vec<u8> {
    let mut text = serde_json::to_vec(json).unwrap();
    while !text.len().is_multiple_of(4) {
        text.push(b' ');
    }
    let mut out = b"glTF".to_vec();
    out.extend(2u32.to_le_bytes());
    out.extend(((20 + text.len() + rest.len()) as u32).to_le_bytes());
    out.extend((text.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(&text);
    out.extend(rest);
    out
}

/// Writes the mutants into `dir` and returns their paths.
fn make_mutants(dir: &Path, count: usize) -> Vec<PathBuf> {
    let mut rng = Rng(0x4E4D_4954_4845);
    let mut files = Vec::new();
    let assets = shared().join("assets");
    // Sources: (kind, name, bytes, folder of external files).
    let mut gltfs = Vec::new();
    for (i, rel) in GLTF.iter().enumerate() {
        let path = assets.join(rel);
        let folder = dir.join(format!("gltf{i}"));
        std::fs::create_dir_all(&folder).unwrap();
        for entry in std::fs::read_dir(path.parent().unwrap()).unwrap() {
            let entry = entry.unwrap().path();
            if entry.extension().is_some_and(|e| e == "bin") {
                std::fs::copy(&entry, folder.join(entry.file_name().unwrap())).unwrap();
            }
        }
        gltfs.push((serde_json::from_slice::<Value>(&std::fs::read(&path).unwrap()).unwrap(), folder));
    }
    let glbs: Vec<Vec<u8>> = GLB.iter().map(|rel| std::fs::read(assets.join(rel)).unwrap()).collect();
    let mut peers = Vec::new();
    for name in PEERS {
        let path = shared().join("peers/scenes").join(name);
        let mut v: Value = serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap();
        let mesh = path.parent().unwrap().join(v["mesh"].as_str().unwrap()).canonicalize().unwrap();
        v["mesh"] = json!(mesh.to_str().unwrap());
        peers.push(v);
    }
    let glb_dir = dir.join("glb");
    let peer_dir = dir.join("peer");
    std::fs::create_dir_all(&glb_dir).unwrap();
    std::fs::create_dir_all(&peer_dir).unwrap();
    for n in 0..count {
        let changes = 1 + rng.below(3);
        let path = match n % 10 {
            0..=4 => {
                let (source, folder) = &gltfs[rng.below(gltfs.len())];
                let mut v = source.clone();
                for _ in 0..changes {
                    mutate_json(&mut v, &mut rng);
                }
                let path = folder.join(format!("m{n:05}.gltf"));
                std::fs::write(&path, serde_json::to_vec(&v).unwrap()).unwrap();
                path
            }
            5..=6 => {
                let mut bytes = glbs[rng.below(glbs.len())].clone();
                for _ in 0..changes * 2 {
                    let at = rng.below(bytes.len());
                    bytes[at] = match rng.below(4) {
                        0 => bytes[at] ^ (1 << rng.below(8)),
                        1 => 0xff,
                        2 => 0,
                        _ => rng.next() as u8,
                    };
                }
                if rng.below(8) == 0 {
                    bytes.truncate(rng.below(bytes.len()));
                }
                let path = glb_dir.join(format!("m{n:05}.glb"));
                std::fs::write(&path, bytes).unwrap();
                path
            }
            7..=8 => {
                let (mut v, rest) = split_glb(&glbs[rng.below(glbs.len())]);
                for _ in 0..changes {
                    mutate_json(&mut v, &mut rng);
                }
                let path = glb_dir.join(format!("m{n:05}.glb"));
                std::fs::write(&path, join_glb(&v, &rest)).unwrap();
                path
            }
            _ => {
                let mut v = peers[rng.below(peers.len())].clone();
                for _ in 0..changes {
                    mutate_json(&mut v, &mut rng);
                }
                let path = peer_dir.join(format!("m{n:05}.json"));
                std::fs::write(&path, serde_json::to_vec(&v).unwrap()).unwrap();
                path
            }
        };
        files.push(path);
    }
    files
}

/// Loads (and spawns) one file: `Ok(None)` when it loads, `Ok(Some(error))` when it is
/// refused properly, `Err` when it fails in a way that is not allowed.
fn check(path: &Path) -> Result<Option<String>, String> {
    let name = path.display().to_string();
    let error = |e: hemi::HemiError, file: &str| {
        let text = e.to_string();
        if text.lines().count() != 1 || !text.contains(file) {
            return Err(format!("not one line naming the file: {text:?}"));
        }
        Ok(Some(text))
    };
    if path.extension().is_some_and(|e| e == "json") {
        match PeerScene::load(path) {
            Ok(peer) => match peer.spawn(&mut World::new()) {
                Ok(_) => Ok(None),
                // Errors in a mesh name the mesh.
                Err(e) => error(e, ""),
            },
            Err(e) => error(e, &name),
        }
    } else {
        match gltf::load(path) {
            Ok(scene) => match scene.spawn(&mut World::new(), &SpawnOptions::default()) {
                Ok(()) => Ok(None),
                Err(e) => error(e, &name),
            },
            Err(e) => error(e, &name),
        }
    }
}

#[cfg(target_os = "linux")]
fn limit_memory() {
    let limit = libc::rlimit { rlim_cur: MEMORY_LIMIT, rlim_max: MEMORY_LIMIT };
    // SAFETY: setrlimit reads the struct it is given and changes only this process's limit.
    let rc = unsafe { libc::setrlimit(libc::RLIMIT_AS, &limit) };
    assert_eq!(rc, 0, "setrlimit failed");
}

#[cfg(not(target_os = "linux"))]
fn limit_memory() {}

/// The child: loads the files listed in `HEMI_MUTATION_LIST`, one line of output per file.
/// Run on its own (without the variable) it does nothing.
#[test]
fn mutation_child() {
    let Ok(list) = std::env::var(LIST_VAR) else { return };
    limit_memory();
    let list = std::fs::read_to_string(list).unwrap();
    let mut out = std::io::stdout().lock();
    for (i, line) in list.lines().enumerate() {
        writeln!(out, "start {i}").unwrap();
        out.flush().unwrap();
        match check(Path::new(line)) {
            Ok(None) => writeln!(out, "loaded {i}").unwrap(),
            Ok(Some(e)) => writeln!(out, "refused {i} {e}").unwrap(),
            Err(e) => writeln!(out, "bad {i} {e}").unwrap(),
        }
    }
    writeln!(out, "done").unwrap();
}

#[test]
fn mutated_files_fail_in_one_line_or_load() {
    let count = std::env::var("HEMI_MUTANTS").ok().and_then(|n| n.parse().ok()).unwrap_or(DEFAULT_MUTANTS);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join("hemi-mutants");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let start = Instant::now();
    let files = make_mutants(&dir, count);
    let mut failures = Vec::new();
    let (mut loaded, mut refused) = (0, Vec::new());
    for (b, batch) in files.chunks(BATCH).enumerate() {
        let list = dir.join(format!("batch{b}.txt"));
        let text: Vec<String> = batch.iter().map(|p| p.display().to_string()).collect();
        std::fs::write(&list, text.join("\n")).unwrap();
        let mut child = Command::new(std::env::current_exe().unwrap())
            .args(["--exact", "mutation_child", "--nocapture", "--test-threads=1", "-q"])
            .env(LIST_VAR, &list)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (mut current, mut done) = (None, false);
        for line in BufReader::new(child.stdout.take().unwrap()).lines().map_while(Result::ok) {
            if let Some(i) = line.strip_prefix("start ") {
                current = i.parse::<usize>().ok();
            } else if let Some(rest) = line.strip_prefix("bad ") {
                let (i, why) = rest.split_once(' ').unwrap();
                failures.push(format!("{}: {why}", batch[i.parse::<usize>().unwrap()].display()));
            } else if line.starts_with("loaded ") {
                loaded += 1;
            } else if let Some(rest) = line.strip_prefix("refused ") {
                refused.push(rest.split_once(' ').map_or("", |r| r.1).to_string());
            } else if line == "done" {
                done = true;
            }
        }
        let deadline = Instant::now() + Duration::from_secs(60);
        let status = loop {
            if let Some(s) = child.try_wait().unwrap() {
                break s;
            }
            if Instant::now() > deadline {
                child.kill().unwrap();
                break child.wait().unwrap();
            }
            std::thread::sleep(Duration::from_millis(10));
        };
        if !done || !status.success() {
            let mut stderr = String::new();
            std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut stderr).unwrap();
            let file = current.map_or("?".into(), |i| batch[i].display().to_string());
            let tail: Vec<&str> = stderr.lines().rev().take(4).collect();
            failures.push(format!("{file}: the loader died ({status}): {}", tail.join(" | ")));
        }
    }
    assert!(failures.is_empty(), "{} of {count} files failed:\n{}", failures.len(), failures.join("\n"));
    eprintln!(
        "{count} mutated files in {:.1} s: {loaded} loaded, {} refused",
        start.elapsed().as_secs_f64(),
        refused.len()
    );
    if std::env::var_os("HEMI_MUTANTS_SHOW").is_some() {
        for e in &refused {
            eprintln!("{e}");
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
