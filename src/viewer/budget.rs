//! The frame budget: how many samples per pixel a frame traces, and at what internal
//! resolution, to keep the frame time near a target.
//!
//! The cost model is measured, not assumed: seconds per traced pixel sample (the trace
//! system's time over the samples it traced) and seconds per frame outside tracing, both
//! smoothed over recent frames. A still view renders at full resolution and takes as many
//! samples as fit; a moving one (camera, animation) first lowers the resolution by whole
//! factors until one sample per pixel fits, then fills what is left with samples.

use std::time::Duration;

/// Most samples per pixel one frame traces while the view moves (every moving frame is
/// thrown away by the next, so more buys little).
pub const MOVING_MAX_SPF: u32 = 8;
/// Most samples per pixel one frame of a still view traces.
pub const STILL_MAX_SPF: u32 = 256;
/// Largest resolution divisor while moving.
pub const MAX_SCALE: u32 = 8;

/// What one frame renders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FramePlan {
    /// Internal width.
    pub width: u32,
    /// Internal height.
    pub height: u32,
    /// Resolution divisor (1: full resolution).
    pub scale: u32,
    /// Samples per pixel this frame traces.
    pub spf: u32,
}

/// The measured cost model and the target.
#[derive(Clone, Debug)]
pub struct FrameBudget {
    /// Target frame time.
    pub target: Duration,
    /// Seconds per traced pixel sample (`None` until a frame has traced).
    pub secs_per_sample: Option<f64>,
    /// Seconds of a frame outside tracing (schedule, resolve, display, present).
    pub overhead: f64,
}

/// Weight of the newest frame in the smoothed costs.
const SMOOTHING: f64 = 0.3;

impl FrameBudget {
    /// A budget aiming at `target` per frame, with nothing measured yet.
    pub fn new(target: Duration) -> Self {
        FrameBudget { target, secs_per_sample: None, overhead: 0.0 }
    }

    /// Time left for tracing in one frame.
    fn trace_budget(&self) -> f64 {
        let target = self.target.as_secs_f64();
        (target - self.overhead).max(target * 0.25)
    }

    /// The plan for a frame of a `full` resolution view. `moving`: the view changes this frame
    /// (dynamic resolution allowed when `dynamic`); `remaining`: samples per pixel still to
    /// take; `fixed_spf`: samples per frame of a still view, when the user fixed them.
    pub fn plan(
        &self,
        full: (u32, u32),
        moving: bool,
        dynamic: bool,
        remaining: u32,
        fixed_spf: Option<u32>,
    ) -> FramePlan {
        let (w, h) = (full.0.max(1), full.1.max(1));
        let budget = self.trace_budget();
        let fit = |pixels: f64, cap: u32| -> u32 {
            match self.secs_per_sample {
                Some(c) if c > 0.0 => ((budget / (c * pixels)).floor() as u32).clamp(1, cap),
                // Nothing measured yet: one sample, so that the first frame comes fast.
                _ => 1,
            }
        };
        if !moving {
            let spf = fixed_spf.unwrap_or_else(|| fit(w as f64 * h as f64, STILL_MAX_SPF)).min(remaining.max(1));
            return FramePlan { width: w, height: h, scale: 1, spf };
        }
        let mut scale = 1;
        if let (true, Some(c)) = (dynamic, self.secs_per_sample) {
            while scale < MAX_SCALE && c * pixels_at(w, h, scale) > budget {
                scale += 1;
            }
        }
        let (sw, sh) = scaled(w, h, scale);
        FramePlan { width: sw, height: sh, scale, spf: fit(sw as f64 * sh as f64, MOVING_MAX_SPF) }
    }

    /// Takes in a frame's measurements: `pixels × spf` samples traced in `trace`, the whole
    /// frame in `frame`.
    pub fn observe(&mut self, pixels: usize, spf: u32, trace: Duration, frame: Duration) {
        let samples = pixels as f64 * spf as f64;
        if samples > 0.0 && trace > Duration::ZERO {
            let c = trace.as_secs_f64() / samples;
            self.secs_per_sample = Some(self.secs_per_sample.map_or(c, |old| old + SMOOTHING * (c - old)));
            let rest = frame.saturating_sub(trace).as_secs_f64();
            self.overhead += SMOOTHING * (rest - self.overhead);
        }
    }
}

/// The internal size at divisor `scale` (rounded up, at least one pixel).
pub fn scaled(w: u32, h: u32, scale: u32) -> (u32, u32) {
    (w.div_ceil(scale).max(1), h.div_ceil(scale).max(1))
}

fn pixels_at(w: u32, h: u32, scale: u32) -> f64 {
    let (sw, sh) = scaled(w, h, scale);
    sw as f64 * sh as f64
}
