//! `ergohand`: a thin command line over the `ergohand` library (subject-format spec, section 4).

use clap::{Parser, Subcommand};
use ergohand::anatomy::Side;
use ergohand::cli;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "ergohand",
    version,
    about = "Individual digital hands from motion-capture data (Endo, Tada & Mochimaru 2014)",
    long_about = None
)]
struct Cli {
    /// Print nothing but errors (no progress bars, no summaries).
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate the default subject, reconstruct, validate, pose and grasp; needs no input.
    Demo {
        /// Where to write everything.
        #[arg(long, default_value = "demo-out")]
        out: PathBuf,
    },
    /// Write the high-resolution template meshes, the template spec and pictures of them.
    Template {
        /// Output folder (created if missing).
        #[arg(long)]
        out: PathBuf,
    },
    /// Write a simulated subject folder with reference.ply and truth.json.
    Synth {
        /// Seed: the same seed and options give byte-identical files.
        #[arg(long)]
        seed: u64,
        /// Output subject folder.
        #[arg(long)]
        out: PathBuf,
        /// Error model: typical, small-rom, noisy or clean.
        #[arg(long, default_value = "typical")]
        preset: String,
        /// Which hand: right or left.
        #[arg(long, default_value = "right")]
        hand: String,
        /// Reference posture: template (the template's own) or varied (issue 10's variation).
        #[arg(long, default_value = "template")]
        posture: String,
        /// The true hand: template (the template deformed by its own skeleton, which the
        /// template can always reach) or procedural (an anatomical hand independent of it).
        #[arg(long, default_value = "template")]
        body: String,
        /// Length of every calibration trial in seconds (default: drawn from 40-80 s).
        #[arg(long)]
        duration: Option<f64>,
        /// Replace a non-empty output folder.
        #[arg(long)]
        force: bool,
    },
    /// Reconstruct a subject: link model, skin, tetrahedral mesh, skinned hand.
    Reconstruct {
        subject_dir: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Mesh the skin's landmark fit runs on: `low` (the ~1,000-face QEM mesh, the paper's
        /// way, then transferred) or `full` (the 37,024-face template directly).
        #[arg(long, default_value = "low")]
        fit_resolution: String,
        /// Fit the template as it stands instead of posing it onto the link model first
        /// (issue 10, step 2; for comparison).
        #[arg(long)]
        no_template_posing: bool,
        /// Weight of the joint-centre terms of the skin fit (issue 10, step 3); 0 leaves them out.
        #[arg(long, default_value_t = ergohand::skin::pipeline::CENTRE_WEIGHT)]
        centre_weight: f64,
        /// Caliper rounds of the skin fit: re-fits that correct each dimension's vertex pair
        /// until a caliper on the skin (the spec's definition) reads the given value; 0 asks
        /// the pairs for the given values, as the paper does.
        #[arg(long, default_value_t = ergohand::skin::pipeline::CALIPER_ROUNDS)]
        caliper_rounds: usize,
    },
    /// Compare a reconstruction with reference.ply / truth.json (each optional) and the
    /// caliper dimensions, and write a report.
    Validate {
        /// The subject folder (truth.json and reference.ply used when present), or with
        /// --suite the suite folder
        /// (holding suite.toml).
        subject_dir: PathBuf,
        /// The reconstruction folder (default: SUBJECT_DIR/out).
        #[arg(long)]
        model: Option<PathBuf>,
        /// Where to write metrics.json (default: MODEL/report; with --suite: reports/).
        #[arg(long)]
        report: Option<PathBuf>,
        /// Run every subject of SUBJECT_DIR/suite.toml, generating missing ones under
        /// SUBJECT_DIR/subjects/.
        #[arg(long)]
        suite: bool,
    },
    /// Pose a reconstructed hand.
    Pose {
        model: PathBuf,
        /// A POSE.toml file, or a built-in pose: open, fist, power-grasp, pinch, tripod.
        #[arg(long)]
        pose: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Use the angles exactly as given (after clamping to the limits), even where the
        /// digits then enter each other; by default they give way by a few degrees.
        #[arg(long)]
        keep_angles: bool,
        /// Dual-quaternion skinning alone for .obj/.vtk/.msh, without the correction that keeps
        /// each finger segment's volume (a skinned .glb is never corrected).
        #[arg(long)]
        plain_skinning: bool,
    },
    /// Grasp and contact checks on a CAD part.
    Grasp {
        scene: PathBuf,
        #[arg(long)]
        model: Option<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Reconstruct every subject folder of SUBJECTS_DIR (a sub-folder holding subject.toml) in
    /// parallel into OUT/<folder name>/, skipping subjects whose outputs were made from the same
    /// input content (and are newer); a failing subject is reported and skipped, the exit status is non-zero if any
    /// failed. Summary in OUT/batch-summary.md and .json.
    Batch {
        subjects_dir: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Threads, shared by the subjects running at once (default: the available cores; at
        /// most 2 per core and one per subject to do).
        #[arg(long)]
        jobs: Option<usize>,
    },
}

fn main() -> ExitCode {
    let args = Cli::parse();
    let log = cli::Log::new(args.quiet);
    let result = match args.command {
        Command::Demo { out } => cli::demo(&out, &log),
        Command::Template { out } => {
            cli::template(&out, &[Side::Right, Side::Left], &log).map(|_| ())
        }
        Command::Synth {
            seed,
            out,
            preset,
            hand,
            posture,
            body,
            duration,
            force,
        } => cli::synth_options(seed, &preset, &hand, &posture, &body, duration)
            .and_then(|opts| cli::synth(&opts, &out, force, &log)),
        Command::Reconstruct {
            subject_dir,
            out,
            fit_resolution,
            no_template_posing,
            centre_weight,
            caliper_rounds,
        } => cli::skin_options(&fit_resolution, !no_template_posing, centre_weight)
            .map(|o| ergohand::skin::pipeline::SkinOptions {
                caliper_rounds,
                ..o
            })
            .and_then(|opts| cli::reconstruct_with(&subject_dir, &out, &opts, &log))
            .map(|_| ()),
        Command::Validate {
            subject_dir,
            report,
            suite: true,
            ..
        } => cli::validate_suite(
            &subject_dir,
            &report.unwrap_or_else(|| "reports".into()),
            &log,
        ),
        Command::Validate {
            subject_dir,
            model,
            report,
            suite: false,
        } => {
            let model = model.unwrap_or_else(|| subject_dir.join("out"));
            let report = report.unwrap_or_else(|| model.join("report"));
            cli::validate(&subject_dir, &model, &report, &log).map(|_| ())
        }
        Command::Pose {
            model,
            pose,
            out,
            keep_angles,
            plain_skinning,
        } => cli::pose(
            &model,
            &pose.to_string_lossy(),
            &out,
            keep_angles,
            plain_skinning,
            &log,
        ),
        Command::Grasp { scene, model, out } => {
            ergohand::grasp::grasp_command(&scene, model.as_deref(), &out, log.quiet()).map(|r| {
                log.info(format!(
                    "grasp: force closure {}, epsilon {:.4}, volume {:.3e}, holds {}, contact {:.0} mm²; wrote {}",
                    r.force_closure, r.epsilon, r.volume, r.holds, r.total_contact_area_mm2, out.display()
                ))
            })
        }
        Command::Batch {
            subjects_dir,
            out,
            jobs,
        } => ergohand::batch::batch_command(
            &subjects_dir,
            &out,
            &ergohand::batch::BatchOptions {
                jobs,
                ..Default::default()
            },
            &log,
        )
        .map(|_| ()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
