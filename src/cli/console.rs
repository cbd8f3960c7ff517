//! Writing to the terminal without ever panicking: `println!` and `eprintln!` panic when the
//! stream is closed or full. A closed standard output (`hemi … | head -1`) ends the program
//! quietly with the status a process killed by SIGPIPE has (141), as shell users expect of
//! a pipeline's producer; any other failure to write it is a one-line error. Standard error
//! is best effort: if it cannot be written there is nowhere left to say so.

use std::io::{ErrorKind, Write};

use crate::error::HemiError;

/// The exit status of a program whose standard output was closed under it: 128 + SIGPIPE.
pub const BROKEN_PIPE_STATUS: u8 = 141;

/// Writes `text` to standard output. Ends the process with [`BROKEN_PIPE_STATUS`] when the
/// reader has gone; other failures (a full disk behind a redirect) are errors.
pub fn out(text: &str) -> Result<(), HemiError> {
    let mut stdout = std::io::stdout().lock();
    match stdout.write_all(text.as_bytes()).and_then(|()| stdout.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::BrokenPipe => std::process::exit(BROKEN_PIPE_STATUS.into()),
        Err(e) => Err(HemiError::Io { path: "standard output".into(), message: format!("cannot write: {e}") }),
    }
}

/// Writes a line to standard error, ignoring failure.
pub fn note(line: &str) {
    let mut stderr = std::io::stderr().lock();
    let _ = writeln!(stderr, "{line}");
}

/// Writes `text` to standard error as it is (no newline), ignoring failure.
pub fn note_raw(text: &str) {
    let mut stderr = std::io::stderr().lock();
    let _ = stderr.write_all(text.as_bytes()).and_then(|()| stderr.flush());
}
