//! The `hemi` binary: see `hemi --help`.

use std::process::ExitCode;

use hemi::{HemiError, cli::console};

/// Exit statuses: 0 done, 1 the scene, a file or the render failed, 2 the command line was
/// wrong, 141 standard output was closed (see [`console`]).
fn main() -> ExitCode {
    match hemi::cli::run(std::env::args_os()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            console::note(&format!("hemi: error: {e}"));
            ExitCode::from(if matches!(e, HemiError::Usage(_)) { 2 } else { 1 })
        }
    }
}
