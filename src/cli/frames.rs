//! `--frames`: which frames of an animation a sequence holds. `all` and open ranges end with
//! the animation, so they are resolved once the scene is loaded.

/// The frames a `--frames` value names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Frames {
    /// Every frame of the animation: `all`.
    All,
    /// `A..B` (B excluded), `A..` (to the end of the animation) or `N` (`N..N+1`).
    Range(u32, Option<u32>),
}

impl Frames {
    /// The first frame.
    pub fn start(self) -> u32 {
        match self {
            Frames::All => 0,
            Frames::Range(a, _) => a,
        }
    }

    /// The range `start..end`; `animation_end` (frames in the animation, see [`frame_count`])
    /// ends `all` and open ranges. A message when there is no end or the range is empty.
    pub fn resolve(self, animation_end: Option<u32>) -> Result<(u32, u32), String> {
        let (start, end) = match (self, animation_end) {
            (Frames::Range(a, Some(b)), _) => (a, b),
            (Frames::All, Some(n)) => (0, n),
            (Frames::Range(a, None), Some(n)) => (a, n),
            (_, None) => return Err(format!("--frames {self}: the scene has no animation to end it; give START..END")),
        };
        if end <= start {
            return Err(format!("--frames {self} is empty ({start}..{end})"));
        }
        Ok((start, end))
    }
}

impl std::fmt::Display for Frames {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Frames::All => write!(f, "all"),
            Frames::Range(a, Some(b)) => write!(f, "{a}..{b}"),
            Frames::Range(a, None) => write!(f, "{a}.."),
        }
    }
}

/// Frames in an animation of `duration` seconds at `fps`: every f with f / fps ≤ duration,
/// floor(duration · fps) + 1 (the last key is shown). `None` if that does not fit a `u32`.
pub fn frame_count(duration: f32, fps: f64) -> Option<u32> {
    let n = (f64::from(duration.max(0.0)) * fps).floor() + 1.0;
    (n.is_finite() && n <= f64::from(u32::MAX)).then_some(n as u32)
}

/// Frames in the world's longest playing animation at `fps` (`None` without one); an error when the
/// count does not fit a `u32`.
pub fn animation_end(world: &bevy_ecs::world::World, fps: f64) -> Result<Option<u32>, String> {
    let graph = world.get_resource::<crate::animation::NodeGraph>();
    let longest = graph.and_then(|g| g.playing().max_by(|a, b| a.duration.total_cmp(&b.duration)));
    let Some(clip) = longest else { return Ok(None) };
    frame_count(clip.duration, fps)
        .map(Some)
        .ok_or_else(|| format!("animation '{}' of {} s has too many frames at --fps {fps}", clip.name, clip.duration))
}

/// Parses `all`, `N`, `A..` or `A..B`.
pub fn parse_frames(s: &str) -> Result<Frames, String> {
    let count = |v: &str| super::parse_count(v, "frame");
    if s.trim() == "all" {
        return Ok(Frames::All);
    }
    match s.split_once("..") {
        None => {
            let n = count(s).map_err(|e| format!("{e} (expected all, N, A.. or A..B)"))?;
            let end = n.checked_add(1).ok_or_else(|| format!("frame {n} is too large"))?;
            Ok(Frames::Range(n, Some(end)))
        }
        Some((a, b)) if b.trim().is_empty() => Ok(Frames::Range(count(a)?, None)),
        Some((a, b)) => {
            let (a, b) = (count(a)?, count(b)?);
            if b <= a {
                return Err(format!("frame range {a}..{b} is empty"));
            }
            Ok(Frames::Range(a, Some(b)))
        }
    }
}

/// Parses a closed range, `N` or `A..B`, for commands without a scene to end an open one.
pub fn parse_closed_frames(s: &str) -> Result<(u32, u32), String> {
    parse_frames(s)?.resolve(None).map_err(|_| format!("'{s}': expected N or START..END (no scene here to end it)"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_specs_parse_and_resolve() {
        assert_eq!(parse_frames("all"), Ok(Frames::All));
        assert_eq!(parse_frames("7"), Ok(Frames::Range(7, Some(8))));
        assert_eq!(parse_frames("3.."), Ok(Frames::Range(3, None)));
        assert_eq!(parse_frames("0..48"), Ok(Frames::Range(0, Some(48))));
        for bad in ["", "x", "5..5", "6..2", "-1..", "..4", "4294967295", "0..99999999999"] {
            assert!(parse_frames(bad).is_err(), "{bad}");
        }
        assert_eq!(Frames::All.resolve(Some(25)), Ok((0, 25)));
        assert_eq!(Frames::Range(10, None).resolve(Some(25)), Ok((10, 25)));
        assert!(Frames::Range(30, None).resolve(Some(25)).unwrap_err().contains("empty"));
        assert!(Frames::All.resolve(None).unwrap_err().contains("no animation"));
        assert_eq!(parse_closed_frames("2..4"), Ok((2, 4)));
        assert!(parse_closed_frames("all").is_err());
    }

    #[test]
    fn an_animation_has_a_frame_for_each_step_up_to_its_last_key() {
        // Fox's "Survey" clip: 3.4166667 s at 24 fps is frames 0..=82.
        assert_eq!(frame_count(3.416_666_7, 24.0), Some(83));
        assert_eq!(frame_count(1.0, 24.0), Some(25));
        assert_eq!(frame_count(0.0, 24.0), Some(1));
        assert_eq!(frame_count(1e30, 1e30), None);
    }
}
