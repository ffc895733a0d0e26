//! The command jobs: one file per `ergohand` subcommand, each reading the command's arguments,
//! checking its outputs, running the library's stages and writing the command's files. They
//! are library functions so that tests and other programs can call them; `src/main.rs` only
//! parses arguments, sets up the [`logger`] and calls these. No stage imports this module.
//!
//! Jobs speak through the `log` facade (status lines at info, warnings at warn); a command's
//! documented stdout output (the tables of `validate`, the demo's summary) is printed here,
//! when info is on.

pub mod args;
pub mod batch;
pub mod demo;
pub mod grasp;
pub mod logger;
pub mod pose;
pub mod reconstruct;
pub mod shape_prior;
pub mod synth;
pub mod template;
pub mod track;
pub mod validate;

pub use batch::batch;
pub use demo::{default_subject_options, demo};
pub use grasp::{grasp, grasp_population};
pub use pose::{pose, pose_with, PoseOptions, PoseSummary};
pub use reconstruct::{
    reconstruct, reconstruct_fingerprint, reconstruct_prepared, reconstruct_with, skin_options,
};
pub use shape_prior::shape_prior;
pub use synth::{percentile_hand, synth, synth_options};
pub use template::{template, TemplateOutputs};
pub use track::{track, TrackSummary};
pub use validate::{validate, validate_suite, validate_with, Validation};

use crate::error::{Error, Result};
use std::path::Path;

/// How loud a job speaks. A command's own job logs its status lines at info and its warnings
/// at warn; a job run inside another (the demo's or a suite's reconstruction, a batch's
/// subjects) one level lower, at debug, so that it does not break into the caller's progress
/// bar or summary: `-v` shows it. The nested job's warnings stay in the files it writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Voice {
    /// The command's own job.
    Command,
    /// A job run by another job.
    Nested,
}

impl Voice {
    /// The level of status lines.
    pub fn info(self) -> log::Level {
        match self {
            Voice::Command => log::Level::Info,
            Voice::Nested => log::Level::Debug,
        }
    }

    /// The level of warnings.
    pub fn warn(self) -> log::Level {
        match self {
            Voice::Command => log::Level::Warn,
            Voice::Nested => log::Level::Debug,
        }
    }
}

/// Whether a command prints its summaries (stdout tables, the demo's summary): when info is
/// logged, i.e. not under `--quiet` (and not in a program that installed no logger).
pub fn show_summaries() -> bool {
    log::log_enabled!(log::Level::Info)
}

/// A progress bar for long work, shown when info is logged ([`show_summaries`]).
pub fn progress(len: u64, what: &str) -> indicatif::ProgressBar {
    if !show_summaries() {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(len);
    pb.set_style(
        indicatif::ProgressStyle::with_template("{msg:>12} [{bar:30}] {pos}/{len} {elapsed}")
            .expect("static template")
            .progress_chars("=> "),
    );
    pb.set_message(what.to_string());
    pb
}

fn create_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))
}
