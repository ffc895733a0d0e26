//! The command line's one logger: every `log` record of the library to stderr, one line each.
//!
//! Levels: `-q` errors only, the default info (status lines and warnings), `-v` debug, `-vv`
//! trace; a level name in `RUST_LOG` (`off`, `error`, `warn`, `info`, `debug`, `trace`)
//! overrides the flags, as in other Rust tools. Warnings and errors carry a `warning:` /
//! `error:` prefix, status lines none, so the command's stderr reads as plain sentences.

use log::{Level, LevelFilter, Log, Metadata, Record};
use std::io::Write;

/// Writes records to stderr.
struct StderrLogger;

impl Log for StderrLogger {
    fn enabled(&self, metadata: &Metadata) -> bool {
        metadata.level() <= log::max_level()
    }

    fn log(&self, record: &Record) {
        if !self.enabled(record.metadata()) {
            return;
        }
        let prefix = match record.level() {
            Level::Error => "error: ",
            Level::Warn => "warning: ",
            Level::Info => "",
            Level::Debug => "debug: ",
            Level::Trace => "trace: ",
        };
        // One write per line, so lines from parallel subjects do not interleave; a closed
        // stderr is no reason to fail the command.
        let line = format!("{prefix}{}\n", record.args());
        let _ = std::io::stderr().lock().write_all(line.as_bytes());
    }

    fn flush(&self) {
        let _ = std::io::stderr().flush();
    }
}

/// The level the flags ask for: `quiet` errors only, else info raised by one step per
/// `verbose` (`-v` debug, `-vv` trace); a level name in `rust_log` (the `RUST_LOG` variable)
/// overrides both. An unknown name is ignored (and reported by [`init`]).
pub fn level(quiet: bool, verbose: u8, rust_log: Option<&str>) -> LevelFilter {
    if let Some(l) = rust_log.and_then(|s| s.trim().parse::<LevelFilter>().ok()) {
        return l;
    }
    match (quiet, verbose) {
        (true, _) => LevelFilter::Error,
        (false, 0) => LevelFilter::Info,
        (false, 1) => LevelFilter::Debug,
        (false, _) => LevelFilter::Trace,
    }
}

/// Install the stderr logger at [`level`] of the flags and `RUST_LOG`. Once per process; a
/// second call only changes the level.
pub fn init(quiet: bool, verbose: u8) {
    let rust_log = std::env::var("RUST_LOG").ok();
    let filter = level(quiet, verbose, rust_log.as_deref());
    static LOGGER: StderrLogger = StderrLogger;
    let _ = log::set_logger(&LOGGER);
    log::set_max_level(filter);
    if let Some(v) = rust_log.filter(|v| v.trim().parse::<LevelFilter>().is_err()) {
        log::warn!(
            "RUST_LOG={v}: not a level name (off, error, warn, info, debug, trace); ignored"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_and_rust_log_give_the_level() {
        assert_eq!(level(true, 0, None), LevelFilter::Error);
        assert_eq!(level(true, 2, None), LevelFilter::Error);
        assert_eq!(level(false, 0, None), LevelFilter::Info);
        assert_eq!(level(false, 1, None), LevelFilter::Debug);
        assert_eq!(level(false, 3, None), LevelFilter::Trace);
        assert_eq!(level(true, 0, Some("debug")), LevelFilter::Debug);
        assert_eq!(level(false, 2, Some("WARN")), LevelFilter::Warn);
        assert_eq!(level(false, 0, Some("off")), LevelFilter::Off);
        assert_eq!(level(true, 0, Some("ergohand=debug")), LevelFilter::Error);
    }
}
