//! The `hemi` binary: see `hemi --help`.

use std::process::ExitCode;

use hemi::HemiError;

fn main() -> ExitCode {
    match hemi::cli::run(std::env::args_os()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("hemi: error: {e}");
            ExitCode::from(if matches!(e, HemiError::Usage(_)) { 2 } else { 1 })
        }
    }
}
