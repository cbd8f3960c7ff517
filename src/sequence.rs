//! Numbered frame sequences on disk: output paths, which frames are already complete (for
//! `--skip-existing`), and the progress of a sequence (`hemi status`).

use std::{
    collections::HashMap,
    ffi::OsString,
    path::{Path, PathBuf},
};

use crate::film::is_complete_image;

/// Widest zero-padded frame number a placeholder may ask for.
const MAX_WIDTH: usize = 32;

/// The frame-number placeholder at the start of `s`, as (its length, the width to pad to):
/// `{}` (no padding), `{:0N}` (N digits, N ≤ 32), or a run of N `#` (Blender's N digits).
fn placeholder_at(s: &str) -> Option<(usize, usize)> {
    if s.starts_with("{}") {
        return Some((2, 0));
    }
    if let Some(rest) = s.strip_prefix("{:0") {
        let digits = rest.bytes().take_while(u8::is_ascii_digit).count();
        let width = rest[..digits].parse::<usize>().ok().filter(|&w| w <= MAX_WIDTH)?;
        return rest[digits..].starts_with('}').then_some((3 + digits + 1, width));
    }
    let hashes = s.bytes().take_while(|&b| b == b'#').count();
    (hashes > 0 && hashes <= MAX_WIDTH).then_some((hashes, hashes))
}

/// The output path of `frame`: every placeholder (`{}`, `{:0N}`, a run of N `#`) becomes
/// the frame number, zero-padded to its width; `None` when the pattern holds none.
pub fn frame_path(pattern: &Path, frame: u32) -> Option<PathBuf> {
    let s = pattern.to_str()?;
    let mut out = String::with_capacity(s.len() + 8);
    let (mut rest, mut found) = (s, false);
    while let Some(c) = rest.chars().next() {
        match placeholder_at(rest) {
            Some((len, width)) => {
                out.push_str(&format!("{frame:0width$}"));
                rest = &rest[len..];
                found = true;
            }
            None => {
                out.push(c);
                rest = &rest[c.len_utf8()..];
            }
        }
    }
    found.then(|| PathBuf::from(out))
}

/// Where one frame of a sequence stands.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum FrameState {
    /// The file is there and decodes completely.
    Done,
    /// No complete file, but a hidden temporary file `.NAME.*.tmp` beside it: a render is
    /// writing it, or one was killed while writing it.
    Partial(PathBuf),
    /// Neither (or a file that does not decode, which atomic writing never leaves).
    Missing,
}

/// One frame's state.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameStatus {
    /// Frame number.
    pub frame: u32,
    /// Its output path.
    pub path: PathBuf,
    /// Where it stands.
    pub state: FrameState,
}

/// The state of every frame of `start..end` written under `pattern`; with `size`, a frame is
/// done only at that size. Each folder is listed once, for the temporary files.
pub fn frame_states(pattern: &Path, (start, end): (u32, u32), size: Option<(u32, u32)>) -> Option<Vec<FrameStatus>> {
    let mut temporaries: HashMap<PathBuf, Vec<OsString>> = HashMap::new();
    let mut list = Vec::with_capacity(end.saturating_sub(start) as usize);
    for frame in start..end {
        let path = frame_path(pattern, frame)?;
        let state = if is_complete_image(&path, size) {
            FrameState::Done
        } else {
            let dir = match path.parent() {
                Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
                _ => PathBuf::from("."),
            };
            let names = temporaries.entry(dir.clone()).or_insert_with(|| {
                std::fs::read_dir(&dir)
                    .map(|entries| entries.filter_map(|e| e.ok().map(|e| e.file_name())).collect())
                    .unwrap_or_default()
            });
            let name = path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
            let prefix = format!(".{name}.");
            let temporary = names.iter().find(|n| {
                let n = n.to_string_lossy();
                n.starts_with(&prefix) && n.ends_with(".tmp")
            });
            match temporary {
                Some(t) => FrameState::Partial(dir.join(t)),
                None => FrameState::Missing,
            }
        };
        list.push(FrameStatus { frame, path, state });
    }
    Some(list)
}

/// The `hemi status` report: a line per frame (`done`, `partial`, `missing`) and a summary
/// line; with whether every frame is done.
pub fn status_report(states: &[FrameStatus]) -> (String, bool) {
    let mut out = String::new();
    let (mut done, mut partial, mut missing) = (0, 0, 0);
    for s in states {
        let line = match &s.state {
            FrameState::Done => {
                done += 1;
                format!("{:>6}  done     {}\n", s.frame, s.path.display())
            }
            FrameState::Partial(t) => {
                partial += 1;
                format!("{:>6}  partial  {} (temporary file {})\n", s.frame, s.path.display(), t.display())
            }
            FrameState::Missing => {
                missing += 1;
                format!("{:>6}  missing  {}\n", s.frame, s.path.display())
            }
        };
        out.push_str(&line);
    }
    let all = done == states.len();
    out.push_str(&format!(
        "{} frames: {done} done, {partial} partial, {missing} missing{}\n",
        states.len(),
        if all { " (complete)" } else { "" }
    ));
    (out, all)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write_png(path: &Path, w: u32, h: u32) {
        image::RgbImage::new(w, h).save(path).unwrap();
    }

    #[test]
    fn placeholders_take_the_frame_number_at_their_width() {
        let at = |p: &str, f: u32| frame_path(Path::new(p), f).map(|p| p.to_string_lossy().into_owned());
        assert_eq!(at("f_{:04}.png", 7).as_deref(), Some("f_0007.png"));
        assert_eq!(at("f_{}.png", 7).as_deref(), Some("f_7.png"));
        assert_eq!(at("f_{:06}.exr", 123).as_deref(), Some("f_000123.exr"));
        assert_eq!(at("f_{:02}.png", 12345).as_deref(), Some("f_12345.png"));
        assert_eq!(at("out/####.png", 42).as_deref(), Some("out/0042.png"));
        assert_eq!(at("a#b.png", 3).as_deref(), Some("a3b.png"));
        assert_eq!(at("{:03}/f_{:03}.png", 5).as_deref(), Some("005/f_005.png"));
        assert_eq!(at("é_{:02}.png", 1).as_deref(), Some("é_01.png"));
        for none in ["f.png", "f_{:4}.png", "f_{:0x}.png", "f_{:099}.png", "{x}.png"] {
            assert_eq!(at(none, 1), None, "{none}");
        }
    }

    #[test]
    fn frames_are_done_partial_or_missing() {
        let dir = tempfile::tempdir().unwrap();
        let pattern = dir.path().join("f_{:04}.png");
        write_png(&dir.path().join("f_0000.png"), 4, 3);
        std::fs::write(dir.path().join(".f_0001.png.Ab12Cd.tmp"), b"half").unwrap();
        // A truncated file under the final name (which atomic writes never leave) is not done.
        let mut bytes = Vec::new();
        image::RgbImage::new(4, 3).write_to(&mut std::io::Cursor::new(&mut bytes), image::ImageFormat::Png).unwrap();
        std::fs::write(dir.path().join("f_0002.png"), &bytes[..bytes.len() / 2]).unwrap();
        write_png(&dir.path().join("f_0003.png"), 4, 3);
        let states = frame_states(&pattern, (0, 5), Some((4, 3))).unwrap();
        let kinds: Vec<&str> = states
            .iter()
            .map(|s| match s.state {
                FrameState::Done => "done",
                FrameState::Partial(_) => "partial",
                FrameState::Missing => "missing",
            })
            .collect();
        assert_eq!(kinds, ["done", "partial", "missing", "done", "missing"]);
        // A wrong size is not done either.
        assert_eq!(frame_states(&pattern, (0, 1), Some((5, 3))).unwrap()[0].state, FrameState::Missing);
        let (text, all) = status_report(&states);
        assert!(!all);
        assert!(text.ends_with("5 frames: 2 done, 1 partial, 2 missing\n"), "{text}");
        assert!(text.contains(".f_0001.png.Ab12Cd.tmp"), "{text}");
        let (text, all) = status_report(&states[..1]);
        assert!(all, "{text}");
        assert!(frame_states(Path::new("no-placeholder.png"), (0, 1), None).is_none());
    }
}
