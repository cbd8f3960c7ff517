//! Per-frame statistics: each system's wall time, rays by kind, BVH and buffer sizes.

use std::{fmt::Write, time::Duration};

use bevy_ecs::prelude::Resource;

use crate::{
    geometry::{
        TraversalCounts,
        accel::{AlphaCounts, BvhWork},
        wide_bvh::SahCost,
    },
    light::Term,
};

/// Rays traced, by kind.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RayCounts {
    /// Camera rays.
    pub primary: u64,
    /// Visibility rays of ambient-term lights (the ambient occluder).
    pub ao: u64,
    /// Shadow rays of all other lights.
    pub shadow: u64,
}

impl RayCounts {
    /// All rays.
    pub fn total(&self) -> u64 {
        self.primary + self.ao + self.shadow
    }

    /// Counts `n` shadow rays of a light with term `term`.
    #[inline]
    pub(crate) fn count(&mut self, term: Term, n: u64) {
        match term {
            Term::Ambient => self.ao += n,
            Term::Diffuse => self.shadow += n,
        }
    }

    /// Adds another count to this one.
    pub fn add(&mut self, other: &RayCounts) {
        self.primary += other.primary;
        self.ao += other.ao;
        self.shadow += other.shadow;
    }
}

/// A reading of the CPU's cycle counter (the time-stamp counter on x86_64, nanoseconds since
/// the first call elsewhere): only differences and ratios of readings mean anything. On x86_64
/// the counter is read once every earlier instruction has completed (LFENCE), so that work
/// issued before a reading is not counted after it: unfenced, a query's readings would take in
/// the tail of the arithmetic that made its rays.
#[inline(always)]
pub fn cycle_count() -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        crate::simd::fenced_timestamp()
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        static EPOCH: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();
        EPOCH.get_or_init(std::time::Instant::now).elapsed().as_nanos() as u64
    }
}

/// Cycles since the reading `start` of [`cycle_count`]; 0 if the counter read lower (a thread
/// moved to a core whose counter lags).
#[inline(always)]
pub fn cycles_since(start: u64) -> u64 {
    cycle_count().saturating_sub(start)
}

/// `rays` per `seconds`, in millions (0 for no time).
pub(crate) fn mrays_per_second(rays: u64, seconds: f64) -> f64 {
    if seconds > 0.0 { rays as f64 / seconds / 1e6 } else { 0.0 }
}

/// Whether the trace system times pixel `pixel` for [`TraceSplit`]: a fixed, evenly spread
/// sixteenth of the pixels (Fibonacci hashing), so reading the counter costs next to nothing.
#[inline(always)]
pub fn timed_pixel(pixel: u32) -> bool {
    pixel.wrapping_mul(0x9E37_79B9) >> 28 == 0
}

/// Whether the trace system also times each scene query of pixel `pixel`: a quarter of the
/// [`timed_pixel`]s, by the same hash. Every query's readings are fenced, and an eight-ray AO
/// packet query is short enough that timing each one in every timed pixel would slow the
/// kernel it measures; the queries' share of a term is taken in these pixels alone.
#[inline(always)]
pub fn query_timed_pixel(pixel: u32) -> bool {
    pixel.wrapping_mul(0x9E37_79B9) >> 26 == 0
}

/// Cycle counts over the pixels [`timed_pixel`] picks: whole pixels (camera rays, shading,
/// film) and the part spent in lights of each term (their sampling, shadow rays and sums);
/// over the pixels [`query_timed_pixel`] picks, each term's part and the part of that spent
/// in the scene queries of its shadow rays (BVH traversal and primitive tests). Their ratios
/// split the trace system's wall time by stage.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TraceSplit {
    /// Cycles of the timed pixels, start to end.
    pub pixels: u64,
    /// Cycles inside ambient-term lights (the ambient occluder: AO).
    pub ambient: u64,
    /// Cycles inside diffuse-term lights (direct light).
    pub diffuse: u64,
    /// Of `ambient`, the cycles where its rays' scene queries were timed.
    pub ambient_queried: u64,
    /// Of `diffuse`, the cycles where its rays' scene queries were timed.
    pub diffuse_queried: u64,
    /// Of `ambient_queried`, the cycles inside its rays' scene queries.
    pub ambient_queries: u64,
    /// Of `diffuse_queried`, the cycles inside its rays' scene queries.
    pub diffuse_queries: u64,
}

impl TraceSplit {
    /// Counts `cycles` spent in a light of term `term`, whose scene queries were timed
    /// ([`TraceSplit::add_queries`]) if `queries_timed`.
    #[inline]
    pub fn add_term(&mut self, term: Term, cycles: u64, queries_timed: bool) {
        let queried = if queries_timed { cycles } else { 0 };
        match term {
            Term::Ambient => {
                (self.ambient, self.ambient_queried) = (self.ambient + cycles, self.ambient_queried + queried)
            }
            Term::Diffuse => {
                (self.diffuse, self.diffuse_queried) = (self.diffuse + cycles, self.diffuse_queried + queried)
            }
        }
    }

    /// Counts `cycles` spent in the scene queries of a light of term `term`.
    #[inline]
    pub fn add_queries(&mut self, term: Term, cycles: u64) {
        match term {
            Term::Ambient => self.ambient_queries += cycles,
            Term::Diffuse => self.diffuse_queries += cycles,
        }
    }

    /// Adds another split's counts to this one.
    pub fn add(&mut self, other: &TraceSplit) {
        self.pixels += other.pixels;
        self.ambient += other.ambient;
        self.diffuse += other.diffuse;
        self.ambient_queried += other.ambient_queried;
        self.diffuse_queried += other.diffuse_queried;
        self.ambient_queries += other.ambient_queries;
        self.diffuse_queries += other.diffuse_queries;
    }

    /// Every count times `numerator / denominator` (rounded down): a part's share of counts
    /// taken over a whole.
    pub fn scaled(&self, numerator: u64, denominator: u64) -> TraceSplit {
        let share = |cycles: u64| cycles * numerator / denominator;
        TraceSplit {
            pixels: share(self.pixels),
            ambient: share(self.ambient),
            diffuse: share(self.diffuse),
            ambient_queried: share(self.ambient_queried),
            diffuse_queried: share(self.diffuse_queried),
            ambient_queries: share(self.ambient_queries),
            diffuse_queries: share(self.diffuse_queries),
        }
    }

    /// The share of `trace` (the trace system's wall time) spent in lights of `term`: its
    /// share of the timed pixels' cycles.
    pub fn time_of(&self, term: Term, trace: Duration) -> Duration {
        self.share(
            match term {
                Term::Ambient => self.ambient,
                Term::Diffuse => self.diffuse,
            },
            trace,
        )
    }

    /// The share of `trace` spent in the scene queries of lights of `term`: the term's share,
    /// times the queries' share of the term where they were timed.
    pub fn queries_time_of(&self, term: Term, trace: Duration) -> Duration {
        let (queries, queried) = match term {
            Term::Ambient => (self.ambient_queries, self.ambient_queried),
            Term::Diffuse => (self.diffuse_queries, self.diffuse_queried),
        };
        let part = if queried == 0 { 0.0 } else { (queries as f64 / queried as f64).min(1.0) };
        self.time_of(term, trace).mul_f64(part)
    }

    /// `cycles`' share of the timed pixels' cycles, as a part of `trace`.
    fn share(&self, cycles: u64, trace: Duration) -> Duration {
        if self.pixels == 0 { Duration::ZERO } else { trace.mul_f64((cycles as f64 / self.pixels as f64).min(1.0)) }
    }
}

/// Wall time one system spent in this frame.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemTime {
    /// The system's stage name (its file name under `systems/`).
    pub name: &'static str,
    /// Wall time of its body.
    pub time: Duration,
    /// What it did (e.g. "rebuilt", "skipped: unchanged").
    pub note: String,
    /// The process's peak resident set size while it ran, in bytes, when measured (see
    /// [`FrameStats::measure_memory`]).
    pub peak_rss: Option<u64>,
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
    /// Nodes of the wide trees traversal uses (`bvh_width` children each).
    pub bvh_wide_nodes: usize,
    /// Children per node of the trees traversal uses (8 with AVX, else 4).
    pub bvh_width: usize,
    /// Rays per packet in occlusion runs (16 with AVX-512, 8 with AVX, 0: rays traced alone).
    pub packet_lanes: usize,
    /// Primitives in the BVH's leaves (triangles + spheres; a triangle that spatial splits put
    /// in several leaves once per leaf).
    pub bvh_prims: usize,
    /// Bytes of BVH nodes and primitives.
    pub bvh_bytes: usize,
    /// Triangles the BVH stores (each shared mesh once).
    pub bvh_triangles: usize,
    /// The largest BLAS's primitive slots and [`SahCost`] where the BVH was built or refit this
    /// frame.
    pub bvh_sah: Option<(usize, SahCost)>,
    /// Bytes of the accumulation, frame and image buffers.
    pub buffer_bytes: usize,
    /// Samples rejected because they were NaN or infinite (should stay 0).
    pub nonfinite_samples: u64,
    /// How the trace system's time divides between AO, direct light and the rest (measured
    /// where [`FrameStats::time_split`] says).
    pub trace_split: TraceSplit,
    /// What the trace system's BVH queries did (all 0 unless built with the feature `counters`).
    pub traversal: TraversalCounts,
    /// What the alpha-tested meshes' queries did (all 0 in a scene without them).
    pub alpha: AlphaCounts,
    /// What restarted accumulation this frame (`Transform of entity 4v0 changed`); `None`
    /// when the frame added to the samples before it.
    pub reset: Option<String>,
    /// Whether each system's peak resident set size is measured (two reads of `/proc` per
    /// system, so only when asked for: [`crate::Renderer::measure_memory`]).
    pub measure_memory: bool,
    /// Whether the trace system splits its time by stage into [`FrameStats::trace_split`] (all
    /// 0 otherwise; only when asked for: [`crate::Renderer::time_split`]).
    pub time_split: bool,
    /// The process's peak resident set size between the previous frame and this one (on the
    /// first frame: since the process started, the scene's loading included), when measured.
    pub peak_rss_before: Option<u64>,
}

impl FrameStats {
    /// Records a system's time.
    pub fn record(&mut self, name: &'static str, time: Duration, note: impl Into<String>) {
        let peak_rss = if self.measure_memory { take_peak_rss() } else { None };
        self.systems.push(SystemTime { name, time, note: note.into(), peak_rss });
    }

    /// Bytes of the BVH per triangle it stores (`None` without triangles).
    pub fn bvh_bytes_per_triangle(&self) -> Option<f64> {
        (self.bvh_triangles > 0).then(|| self.bvh_bytes as f64 / self.bvh_triangles as f64)
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
        mrays_per_second(self.rays.total(), self.time_of("trace").as_secs_f64())
    }

    /// AO rays per second of the trace system's wall time, in millions: a conservative AO
    /// throughput (the trace time also holds primary and shadow rays and shading).
    pub fn ao_mrays_per_second(&self) -> f64 {
        mrays_per_second(self.rays.ao, self.time_of("trace").as_secs_f64())
    }

    /// The trace system's wall time spent in lights of `term` (see [`TraceSplit`]).
    pub fn trace_time_of(&self, term: Term) -> Duration {
        self.trace_split.time_of(term, self.time_of("trace"))
    }

    /// The trace system's wall time spent in the scene queries of lights of `term`.
    pub fn queries_time_of(&self, term: Term) -> Duration {
        self.trace_split.queries_time_of(term, self.time_of("trace"))
    }

    /// AO rays per second of the trace system's time spent in the ambient occluder (sampling,
    /// AO rays and sums, as [`TraceSplit`] measures it), in millions: the AO kernel alone.
    pub fn ao_kernel_mrays_per_second(&self) -> f64 {
        mrays_per_second(self.rays.ao, self.trace_time_of(Term::Ambient).as_secs_f64())
    }

    /// AO rays per second of the trace system's time spent in their scene queries (BVH
    /// traversal and primitive tests, without the occluder's sampling and sums), in millions.
    pub fn ao_query_mrays_per_second(&self) -> f64 {
        mrays_per_second(self.rays.ao, self.queries_time_of(Term::Ambient).as_secs_f64())
    }

    /// This frame as JSON (the `--stats-json` record of one frame; `traversal` only when built
    /// with the feature `counters`).
    pub fn to_json(&self) -> serde_json::Value {
        let systems: Vec<serde_json::Value> = self
            .systems
            .iter()
            .map(|s| {
                let mut system =
                    serde_json::json!({ "name": s.name, "ms": s.time.as_secs_f64() * 1e3, "note": s.note });
                if let Some(peak) = s.peak_rss {
                    system["peak_rss_bytes"] = peak.into();
                }
                system
            })
            .collect();
        let mut json = serde_json::json!({
            "frame": self.frame,
            "spp": self.spp,
            "samples_traced": self.samples_traced,
            "ms": self.total_time().as_secs_f64() * 1e3,
            "systems": systems,
            "rays": { "primary": self.rays.primary, "ao": self.rays.ao, "shadow": self.rays.shadow },
            "mrays_per_s": self.mrays_per_second(),
            "ao_mrays_per_s": self.ao_mrays_per_second(),
            "ao_kernel_mrays_per_s": self.ao_kernel_mrays_per_second(),
            "ao_query_mrays_per_s": self.ao_query_mrays_per_second(),
            "trace_split": {
                "ao_ms": self.trace_time_of(Term::Ambient).as_secs_f64() * 1e3,
                "direct_ms": self.trace_time_of(Term::Diffuse).as_secs_f64() * 1e3,
                "ao_queries_ms": self.queries_time_of(Term::Ambient).as_secs_f64() * 1e3,
                "direct_queries_ms": self.queries_time_of(Term::Diffuse).as_secs_f64() * 1e3,
            },
            "bvh": {
                "blas_built": self.bvh_work.blas_built,
                "blas_refit": self.bvh_work.blas_refit,
                "tlas_built": self.bvh_work.tlas_built,
                "nodes": self.bvh_nodes,
                "wide_nodes": self.bvh_wide_nodes,
                "width": self.bvh_width,
                "packet_lanes": self.packet_lanes,
                "prims": self.bvh_prims,
                "bytes": self.bvh_bytes,
                "triangles": self.bvh_triangles,
                "bytes_per_triangle": self.bvh_bytes_per_triangle(),
                "largest_blas": self.bvh_sah.map(|(slots, sah)| serde_json::json!({
                    "prims": slots, "sah_inner": sah.inner, "sah_leaves": sah.leaves, "sah": sah.total(),
                })),
            },
            "buffer_bytes": self.buffer_bytes,
            "nonfinite_samples": self.nonfinite_samples,
        });
        if let Some(peak) = self.peak_rss_before {
            json["peak_rss_before_bytes"] = peak.into();
        }
        if TraversalCounts::ENABLED {
            json["traversal"] = serde_json::json!(self.traversal);
        }
        if self.alpha.rays > 0 {
            json["alpha"] = serde_json::json!(self.alpha);
        }
        json
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
            if sys.name == "trace" && self.trace_split.pixels > 0 {
                let trace = self.time_of("trace").as_secs_f64() * 1e3;
                let ms = |d: Duration| d.as_secs_f64() * 1e3;
                let (ao, direct) = (ms(self.trace_time_of(Term::Ambient)), ms(self.trace_time_of(Term::Diffuse)));
                let _ = writeln!(
                    s,
                    "    of which     AO {ao:.1} ms ({:.2} Mrays/s; its rays' queries {:.1} ms, {:.2} Mrays/s), direct light {direct:.1} ms (queries {:.1} ms), camera rays and the rest {:.1} ms",
                    self.ao_kernel_mrays_per_second(),
                    ms(self.queries_time_of(Term::Ambient)),
                    self.ao_query_mrays_per_second(),
                    ms(self.queries_time_of(Term::Diffuse)),
                    trace - ao - direct
                );
            }
        }
        let r = &self.rays;
        let _ = writeln!(
            s,
            "  rays: {} primary, {} ao, {} shadow; bvh: {} {}-wide nodes (collapsed from {} binary){}, {} prims, {:.1} MiB{}{}; buffers {:.1} MiB",
            r.primary,
            r.ao,
            r.shadow,
            self.bvh_wide_nodes,
            self.bvh_width,
            self.bvh_nodes,
            if self.packet_lanes > 0 { format!(", {}-ray packets", self.packet_lanes) } else { String::new() },
            self.bvh_prims,
            self.bvh_bytes as f64 / (1 << 20) as f64,
            self.bvh_bytes_per_triangle().map_or(String::new(), |b| format!(", {b:.1} B per triangle")),
            if self.bvh_built { " (built)" } else { "" },
            self.buffer_bytes as f64 / (1 << 20) as f64,
        );
        if let Some((slots, sah)) = self.bvh_sah {
            let _ = writeln!(
                s,
                "  largest BLAS: {slots} prims, SAH {:.3} (inner nodes {:.3}, leaves {:.3})",
                sah.total(),
                sah.inner,
                sah.leaves
            );
        }
        if let Some(line) = self.peak_rss_line() {
            let _ = writeln!(s, "  {line}");
        }
        if TraversalCounts::ENABLED {
            let _ = writeln!(s, "  {}", traversal_line(&self.traversal, r.total()));
        }
        if self.alpha.rays > 0 {
            let a = &self.alpha;
            let _ = writeln!(
                s,
                "  alpha-tested meshes: {} rays reached them, {} candidate hits tested, {} cut out",
                a.rays, a.candidates, a.cut
            );
        }
        if self.nonfinite_samples > 0 {
            let _ = writeln!(s, "  warning: {} NaN/Inf samples were dropped", self.nonfinite_samples);
        }
        s
    }
}

impl FrameStats {
    /// The `--stats` line of peak resident set sizes: before the frame, then by system.
    fn peak_rss_line(&self) -> Option<String> {
        let mib = |b: u64| b as f64 / (1 << 20) as f64;
        let systems = self.systems.iter().filter_map(|s| s.peak_rss.map(|p| format!("{} {:.1}", s.name, mib(p))));
        let all: Vec<String> = self
            .peak_rss_before
            .map(|p| format!("before the frame {:.1}", mib(p)))
            .into_iter()
            .chain(systems)
            .collect();
        (!all.is_empty()).then(|| format!("peak RSS (MiB): {}", all.join(", ")))
    }
}

/// The process's peak resident set size since the last call (or since it started), in bytes,
/// and a fresh start for the next: Linux's `VmHWM`, reset through `/proc/self/clear_refs`.
/// `None` where the system offers neither.
pub fn take_peak_rss() -> Option<u64> {
    let peak = peak_rss_in(&std::fs::read_to_string("/proc/self/status").ok()?)?;
    // 5 sets the peak to the current resident set size (Linux 4.0 and later).
    std::fs::write("/proc/self/clear_refs", "5").ok()?;
    Some(peak)
}

/// The `VmHWM` of a `/proc/PID/status` text, in bytes.
fn peak_rss_in(status: &str) -> Option<u64> {
    let kib = status.lines().find_map(|l| l.strip_prefix("VmHWM:"))?.trim().strip_suffix("kB")?.trim();
    kib.parse::<u64>().ok().map(|k| k * 1024)
}

/// The `--stats` line of `counts` over `rays` rays (all kinds): totals and per ray.
pub(crate) fn traversal_line(counts: &TraversalCounts, rays: u64) -> String {
    let per_ray = |n: u64| if rays > 0 { n as f64 / rays as f64 } else { 0.0 };
    let c = counts;
    format!(
        "traversal: {} packet node tests, {} packet triangle tests, {} rays gone on alone; one ray at a time: {} node tests, {} leaf tests, {} triangle-packet tests; per ray: {:.3}, {:.3}, {:.3}; {:.3}, {:.3}, {:.3}",
        c.packet_node_tests,
        c.packet_triangle_tests,
        c.lone_rays,
        c.node_tests,
        c.leaf_tests,
        c.triangle_packet_tests,
        per_ray(c.packet_node_tests),
        per_ray(c.packet_triangle_tests),
        per_ray(c.lone_rays),
        per_ray(c.node_tests),
        per_ray(c.leaf_tests),
        per_ray(c.triangle_packet_tests),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_peak_rss_is_read_in_bytes_from_vm_hwm() {
        let status = "Name:\themi\nVmPeak:\t  812344 kB\nVmHWM:\t  113664 kB\nVmRSS:\t   85000 kB\n";
        assert_eq!(peak_rss_in(status), Some(113_664 * 1024));
        assert_eq!(peak_rss_in("VmRSS:\t 85000 kB\n"), None);
    }

    #[test]
    fn the_peak_rss_since_the_last_take_covers_a_buffer_touched_and_freed_in_between() {
        // Only this test takes the peak in this process: other tests only add to it.
        let Some(_) = take_peak_rss() else {
            eprintln!("skipped: no /proc/self/status or clear_refs here");
            return;
        };
        let size = 64 << 20;
        let buffer = std::hint::black_box(vec![1u8; size]);
        assert_eq!(buffer.iter().step_by(4096).map(|&b| b as usize).sum::<usize>(), size / 4096);
        drop(buffer);
        // The resident set now is well under the buffer (it was freed), so a reading of the
        // current size instead of the peak would fail here.
        let peak = take_peak_rss().unwrap();
        assert!(peak >= size as u64, "peak {peak} after a buffer of {size}");
    }

    /// How many pixels `picked` picks in each 16 × 16 tile of a 512 × 512 image.
    fn picked_per_tile(picked: impl Fn(u32) -> bool) -> Vec<u32> {
        let width = 512;
        let mut per_tile = vec![0u32; 32 * 32];
        for pixel in (0..width * width).filter(|&p| picked(p)) {
            per_tile[((pixel / width / 16) * 32 + pixel % width / 16) as usize] += 1;
        }
        per_tile
    }

    #[test]
    fn a_sixteenth_of_every_tile_is_timed() {
        let per_tile = picked_per_tile(timed_pixel);
        // 16 of each tile's 256 pixels on average.
        assert_eq!(per_tile.iter().sum::<u32>(), 16_385);
        assert!(per_tile.iter().all(|&n| (12..=20).contains(&n)), "{per_tile:?}");
    }

    #[test]
    fn a_quarter_of_the_timed_pixels_time_their_queries() {
        for pixel in (0..512 * 512).filter(|&p| query_timed_pixel(p)) {
            assert!(timed_pixel(pixel), "pixel {pixel}'s queries are timed, the pixel is not");
        }
        let per_tile = picked_per_tile(query_timed_pixel);
        // 4 of each tile's 256 pixels on average.
        assert_eq!(per_tile.iter().sum::<u32>(), 4_096);
        assert!(per_tile.iter().all(|&n| (2..=6).contains(&n)), "{per_tile:?}");
    }

    #[test]
    fn terms_get_their_share_of_the_trace_time() {
        let split = TraceSplit {
            pixels: 400,
            ambient: 300,
            diffuse: 40,
            ambient_queried: 30,
            diffuse_queried: 10,
            ambient_queries: 20,
            diffuse_queries: 2,
        };
        let trace = Duration::from_millis(200);
        assert_eq!(split.time_of(Term::Ambient, trace), Duration::from_millis(150));
        assert_eq!(split.time_of(Term::Diffuse, trace), Duration::from_millis(20));
        assert_eq!(split.queries_time_of(Term::Ambient, trace), Duration::from_millis(100));
        assert_eq!(split.queries_time_of(Term::Diffuse, trace), Duration::from_millis(4));
        assert_eq!(TraceSplit::default().time_of(Term::Ambient, trace), Duration::ZERO);
        assert_eq!(TraceSplit::default().queries_time_of(Term::Ambient, trace), Duration::ZERO);
    }
}
