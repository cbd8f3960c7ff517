//! Errors hemi reports instead of panicking.

use std::{fmt, path::PathBuf};

/// Everything that can stop a render, each with a one-line message.
#[derive(Debug)]
pub enum HemiError {
    /// The scene holds an entity or setting that cannot be rendered.
    InvalidScene(String),
    /// A file could not be read or written.
    Io {
        /// The file concerned.
        path: PathBuf,
        /// What went wrong.
        message: String,
    },
    /// A scene file is malformed or unsupported.
    Load {
        /// The file concerned.
        path: PathBuf,
        /// What is wrong, naming the element.
        message: String,
    },
    /// A command-line argument is unusable.
    Usage(String),
    /// Work that is not finished, e.g. frames of a sequence still missing (`hemi status`).
    Incomplete(String),
    /// Something in the scene changed in every one of `frames` frames in a row (a system that
    /// moves an entity each frame, say), so accumulation restarted each time and a render to a
    /// sample count would never finish.
    KeepsChanging {
        /// Frames in a row that restarted accumulation.
        frames: u32,
        /// What changed in the last of them: `Transform of entity 4v0 changed`.
        what: String,
    },
    /// A window could not be opened or shown (no display).
    Window(String),
}

impl fmt::Display for HemiError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HemiError::InvalidScene(m) => write!(f, "invalid scene: {m}"),
            HemiError::Io { path, message } | HemiError::Load { path, message } => {
                write!(f, "{}: {message}", path.display())
            }
            HemiError::Usage(m) | HemiError::Incomplete(m) | HemiError::Window(m) => write!(f, "{m}"),
            HemiError::KeepsChanging { frames, what } => write!(
                f,
                "the scene never settles: accumulation restarted in each of {frames} frames in a row (last: {what})"
            ),
        }
    }
}

impl std::error::Error for HemiError {}
