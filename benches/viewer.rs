//! The viewer's frame rate without a window: `hemi view`'s frames (the same `Viewer` the
//! window drives, minus presenting) in real time at 640×360 on 2 threads (`HEMI_BENCH_THREADS`
//! to change). Prints a markdown table: frames per second orbiting the built-in scene at full
//! resolution and with dynamic resolution, Sponza orbiting, the Fox playing its animation;
//! time from loading to the first frame; and input-to-frame latency (an orbit drag handed in
//! just before a frame: the frame that follows shows it).
//!
//! Run with `cargo bench --bench viewer` (assets from `../shared/assets`, or
//! `HEMI_ASSETS`).

use std::{
    path::PathBuf,
    time::{Duration, Instant},
};

use glam::Vec2;
use hemi::{
    prelude::*,
    viewer::{Button, InputEvent, SceneSource, Viewer, ViewerOptions},
};

fn assets() -> PathBuf {
    std::env::var_os("HEMI_ASSETS")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/assets"))
}

struct Case {
    name: &'static str,
    scene: Option<&'static str>,
    dynamic: bool,
    turntable: bool,
    play: bool,
}

fn main() {
    // `cargo test --benches` runs this with --bench absent: nothing to measure then.
    if !std::env::args().any(|a| a == "--bench") {
        return;
    }
    let threads: usize = std::env::var("HEMI_BENCH_THREADS").ok().and_then(|t| t.parse().ok()).unwrap_or(2);
    let seconds: f64 = std::env::var("HEMI_BENCH_SECONDS").ok().and_then(|t| t.parse().ok()).unwrap_or(4.0);
    let cases = [
        Case { name: "built-in, orbiting, full resolution", scene: None, dynamic: false, turntable: true, play: false },
        Case {
            name: "built-in, orbiting, dynamic resolution",
            scene: None,
            dynamic: true,
            turntable: true,
            play: false,
        },
        Case {
            name: "Sponza, orbiting, dynamic resolution",
            scene: Some("SponzaDabrovic/sponza.gltf"),
            dynamic: true,
            turntable: true,
            play: false,
        },
        Case {
            name: "Fox, playing, dynamic resolution",
            scene: Some("Fox/glTF-Binary/Fox.glb"),
            dynamic: true,
            turntable: false,
            play: true,
        },
    ];
    println!("640x360, {threads} threads, target 33 ms, {seconds} s each\n");
    println!("| case | fps | full-res frames | mean res | spf | load s | first frame s | latency ms (mean / max) |");
    println!("|---|---:|---:|---:|---:|---:|---:|---:|");
    for case in &cases {
        let start = Instant::now();
        let path = case.scene.map(|s| assets().join(s));
        let source = match SceneSource::open(path.as_deref(), None, None, |_| {}) {
            Ok(s) => s,
            Err(e) => {
                println!("| {} | skipped: {e} |", case.name);
                continue;
            }
        };
        let renderer = source.renderer(RenderSettings::default(), |_| {}).unwrap().with_threads(threads).unwrap();
        let options = ViewerOptions {
            size: (640, 360),
            dynamic_resolution: case.dynamic,
            turntable: case.turntable.then_some(10.0),
            play: case.play,
            ..Default::default()
        };
        let mut v = Viewer::new(renderer, source.name(), options).unwrap();
        let load = start.elapsed().as_secs_f64();
        v.frame(Duration::ZERO).unwrap();
        let first = start.elapsed().as_secs_f64();
        // Real time: each frame stands for the wall time since the previous one.
        let mut last = Instant::now();
        let t0 = last;
        while t0.elapsed().as_secs_f64() < seconds {
            let now = Instant::now();
            v.frame(now - last).unwrap();
            last = now;
        }
        let frames = &v.records()[1..];
        let fps = frames.len() as f64 / t0.elapsed().as_secs_f64();
        let full = frames.iter().filter(|f| f.scale == 1).count() as f64 / frames.len().max(1) as f64;
        let mean_w = frames.iter().map(|f| f.width as f64).sum::<f64>() / frames.len().max(1) as f64;
        let mean_h = frames.iter().map(|f| f.height as f64).sum::<f64>() / frames.len().max(1) as f64;
        let spf = frames.iter().map(|f| f.spf as f64).sum::<f64>() / frames.len().max(1) as f64;
        // Latency: a drag handed in, then frames until one shows it (always the next one).
        let mut latencies = Vec::new();
        for k in 0..10 {
            let at = Instant::now();
            v.handle(InputEvent::ButtonDown(Button::Left));
            v.handle(InputEvent::CursorMoved(Vec2::new(100.0, 100.0)));
            v.handle(InputEvent::CursorMoved(Vec2::new(100.0 + 5.0 * (k + 1) as f32, 100.0)));
            v.handle(InputEvent::ButtonUp(Button::Left));
            let now = Instant::now();
            let moved = v.frame(now - last).unwrap().reset;
            last = now;
            assert!(moved, "the frame after the input shows it");
            latencies.push(at.elapsed().as_secs_f64() * 1e3);
        }
        let mean_latency = latencies.iter().sum::<f64>() / latencies.len() as f64;
        let max_latency = latencies.iter().copied().fold(0.0, f64::max);
        println!(
            "| {} | {fps:.1} | {:.0} % | {mean_w:.0}x{mean_h:.0} | {spf:.1} | {load:.2} | {first:.2} | {mean_latency:.0} / {max_latency:.0} |",
            case.name,
            full * 100.0
        );
    }
}
