//! Per-frame statistics: each system's wall time, rays by kind, BVH and buffer sizes.

use std::{fmt::Write, time::Duration};

use bevy_ecs::prelude::Resource;

use crate::{geometry::accel::BvhWork, shading::RayCounts};

/// Wall time one system spent in this frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemTime {
    /// The system's stage name (its file name under `systems/`).
    pub name: &'static str,
    /// Wall time of its body.
    pub time: Duration,
    /// What it did (e.g. "rebuilt", "skipped: unchanged").
    pub note: String,
}

/// What the last frame did and cost. Reset at the start of every frame.
#[derive(Resource, Clone, Debug, Default)]
pub struct FrameStats {
    /// Frame number since the renderer was created.
    pub frame: u64,
    /// Systems that ran, in order.
    pub systems: Vec<SystemTime>,
    /// Rays traced this frame.
    pub rays: RayCounts,
    /// Samples per pixel traced this frame.
    pub samples_traced: u32,
    /// Samples per pixel accumulated after this frame.
    pub spp: u32,
    /// Whether any BVH was built or refit this frame.
    pub bvh_built: bool,
    /// Which BVHs were built or refit this frame.
    pub bvh_work: BvhWork,
    /// BVH nodes (binary, as built).
    pub bvh_nodes: usize,
    /// Children per node of the trees traversal uses (8 with AVX, else 4).
    pub bvh_width: usize,
    /// Rays per packet in occlusion runs (16 with AVX-512, 8 with AVX, 0: rays traced alone).
    pub packet_lanes: usize,
    /// Primitives in the BVH (triangles + spheres).
    pub bvh_prims: usize,
    /// Bytes of BVH nodes and primitives.
    pub bvh_bytes: usize,
    /// Bytes of the accumulation, frame and image buffers.
    pub buffer_bytes: usize,
    /// Samples rejected because they were NaN or infinite (should stay 0).
    pub nonfinite_samples: u64,
}

impl FrameStats {
    /// Records a system's time.
    pub fn record(&mut self, name: &'static str, time: Duration, note: impl Into<String>) {
        self.systems.push(SystemTime { name, time, note: note.into() });
    }

    /// Time of the named system this frame (zero if it did not run).
    pub fn time_of(&self, name: &str) -> Duration {
        self.systems.iter().filter(|s| s.name == name).map(|s| s.time).sum()
    }

    /// Sum of all systems' times.
    pub fn total_time(&self) -> Duration {
        self.systems.iter().map(|s| s.time).sum()
    }

    /// Rays per second of the trace system, in millions.
    pub fn mrays_per_second(&self) -> f64 {
        let t = self.time_of("trace").as_secs_f64();
        if t > 0.0 { self.rays.total() as f64 / t / 1e6 } else { 0.0 }
    }

    /// AO rays per second of the trace system's wall time, in millions: a conservative AO
    /// throughput (the trace time also holds primary and shadow rays and shading).
    pub fn ao_mrays_per_second(&self) -> f64 {
        let t = self.time_of("trace").as_secs_f64();
        if t > 0.0 { self.rays.ao as f64 / t / 1e6 } else { 0.0 }
    }

    /// This frame as JSON (the `--stats-json` record of one frame).
    pub fn to_json(&self) -> serde_json::Value {
        let systems: Vec<serde_json::Value> = self
            .systems
            .iter()
            .map(|s| serde_json::json!({ "name": s.name, "ms": s.time.as_secs_f64() * 1e3, "note": s.note }))
            .collect();
        serde_json::json!({
            "frame": self.frame,
            "spp": self.spp,
            "samples_traced": self.samples_traced,
            "ms": self.total_time().as_secs_f64() * 1e3,
            "systems": systems,
            "rays": { "primary": self.rays.primary, "ao": self.rays.ao, "shadow": self.rays.shadow },
            "mrays_per_s": self.mrays_per_second(),
            "ao_mrays_per_s": self.ao_mrays_per_second(),
            "bvh": {
                "blas_built": self.bvh_work.blas_built,
                "blas_refit": self.bvh_work.blas_refit,
                "tlas_built": self.bvh_work.tlas_built,
                "nodes": self.bvh_nodes,
                "width": self.bvh_width,
                "packet_lanes": self.packet_lanes,
                "prims": self.bvh_prims,
                "bytes": self.bvh_bytes,
            },
            "buffer_bytes": self.buffer_bytes,
            "nonfinite_samples": self.nonfinite_samples,
        })
    }

    /// A human-readable table of this frame.
    pub fn table(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(
            s,
            "frame {:>4}  spp {:>5} (+{})  {:.2} ms  {:.2} Mrays/s",
            self.frame,
            self.spp,
            self.samples_traced,
            self.total_time().as_secs_f64() * 1e3,
            self.mrays_per_second()
        );
        for sys in &self.systems {
            let _ = writeln!(s, "  {:<12} {:>10.3} ms  {}", sys.name, sys.time.as_secs_f64() * 1e3, sys.note);
        }
        let r = &self.rays;
        let _ = writeln!(
            s,
            "  rays: {} primary, {} ao, {} shadow; bvh: {} nodes ({}-wide{}), {} prims, {:.1} MiB{}; buffers {:.1} MiB",
            r.primary,
            r.ao,
            r.shadow,
            self.bvh_nodes,
            self.bvh_width,
            if self.packet_lanes > 0 { format!(", {}-ray packets", self.packet_lanes) } else { String::new() },
            self.bvh_prims,
            self.bvh_bytes as f64 / (1 << 20) as f64,
            if self.bvh_built { " (built)" } else { "" },
            self.buffer_bytes as f64 / (1 << 20) as f64,
        );
        if self.nonfinite_samples > 0 {
            let _ = writeln!(s, "  warning: {} NaN/Inf samples were dropped", self.nonfinite_samples);
        }
        s
    }
}
