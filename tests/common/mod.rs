//! Helpers shared by the command-line test binaries: run the built `ergohand` and read its
//! output as a user would.

#![allow(dead_code)] // each test binary uses its own subset

use std::process::{Command, Output};

/// Run the `ergohand` binary of this build with `args`.
pub fn ergohand(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ergohand"))
        .args(args)
        .output()
        .expect("the binary runs")
}

/// Its standard error as text.
pub fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The last stderr line is the error, one line, starting with `error:`.
pub fn error_line(o: &Output) -> String {
    let e = stderr(o);
    let line = e.lines().last().unwrap_or_default().to_string();
    assert!(line.starts_with("error: "), "stderr: {e}");
    line
}
