//! `ergohand`: a thin command line over the `ergohand` library (subject-format spec, section 4).

use clap::{Parser, Subcommand};
use ergohand::anatomy::Side;
use ergohand::cli;
use ergohand::skin::pipeline::FitResolution;
use ergohand::synth::{Body, Posture, Preset};
use std::path::PathBuf;
use std::process::ExitCode;

/// `--obj-units`: millimetres or metres only (the toolkit's unit and glTF's/Blender's).
fn parse_obj_units(s: &str) -> Result<ergohand::io::Units, String> {
    match s {
        "mm" => Ok(ergohand::io::Units::Millimetres),
        "m" => Ok(ergohand::io::Units::Metres),
        other => Err(format!("'{other}': expected mm or m")),
    }
}

#[derive(Parser)]
#[command(
    name = "ergohand",
    version,
    about = "Individual digital hands from motion-capture data (Endo, Tada & Mochimaru 2014)",
    long_about = None
)]
struct Cli {
    /// Print nothing but errors (no progress bars, no summaries, no warnings).
    #[arg(long, short, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// More detail on stderr: -v debug (also the jobs a command runs inside itself), -vv trace.
    /// RUST_LOG=LEVEL (off, error, warn, info, debug, trace) overrides -q and -v.
    #[arg(long, short, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
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
        /// A template folder to check and describe instead of the generic hand: its hands
        /// with their spec (the folder's, or derived by the landmark rule) and pictures.
        #[arg(long, value_name = "DIR")]
        template: Option<PathBuf>,
    },
    /// Write a simulated subject folder with reference.ply and truth.json.
    Synth {
        /// Seed: the same seed and options give byte-identical files.
        #[arg(long)]
        seed: u64,
        /// Output subject folder.
        #[arg(long)]
        out: PathBuf,
        /// Error model of the capture.
        #[arg(long, value_enum, default_value_t = Preset::Typical)]
        preset: Preset,
        /// Which hand.
        #[arg(long, value_enum, default_value_t = Side::Right)]
        hand: Side,
        /// Reference posture of the subject.
        #[arg(long, value_enum, default_value_t = Posture::Template)]
        posture: Posture,
        /// The true hand.
        #[arg(long, value_enum, default_value_t = Body::Template)]
        body: Body,
        /// Length of every calibration trial in seconds (default: drawn from 40-80 s).
        #[arg(long)]
        duration: Option<f64>,
        /// Length of each grasp motion trial in seconds (trials/grasp_*.c3d with
        /// truth_motion/grasp_*.json): reach, close, hold, lift, release.
        #[arg(long, default_value_t = ergohand::synth::grasp_motion::DEFAULT_MOTION_S)]
        motion_s: f64,
        /// Write no grasp motion trials (only the calibration trials).
        #[arg(long)]
        no_motions: bool,
        /// With --body procedural: the hand of this percentile of hand length and breadth
        /// (ANSUR II, with --sex) instead of a drawn one, e.g. 5, 50, 95.
        #[arg(long, requires = "sex")]
        percentile: Option<f64>,
        /// The sex whose anthropometry --percentile reads.
        #[arg(long, value_enum, requires = "percentile")]
        sex: Option<ergohand::synth::procedural::Sex>,
        /// Also write the optional fingertip markers T_TIP..L_TIP into the static reference
        /// trial (an extension of the spec; `reconstruct` fits the skin's fingertips to them).
        #[arg(long)]
        tip_markers: bool,
        /// The fingertip markers of --tip-markers, kept on through the grasp motion trials
        /// (`track` fits the distal links to them); implies --tip-markers.
        #[arg(long)]
        tip_markers_worn: bool,
        /// Replace a non-empty output folder.
        #[arg(long)]
        force: bool,
    },
    /// Reconstruct a subject: link model, skin, tetrahedral mesh, skinned hand.
    Reconstruct {
        subject_dir: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Mesh the skin's landmark fit runs on.
        #[arg(long, value_enum, default_value_t = FitResolution::Low)]
        fit_resolution: FitResolution,
        /// Fit the template as it stands instead of posing it onto the link model first
        /// (for comparison).
        #[arg(long)]
        no_template_posing: bool,
        /// Leave the fitted skin as the transfer gives it where it folds, instead of relaxing
        /// the fit's displacement there (for comparison).
        #[arg(long)]
        no_unfold: bool,
        /// Leave the fingers' and the wrist's sections as the caliper rounds give them, instead
        /// of scaling each finger across its bones and the wrist across the forearm until a
        /// caliper on the skin reads the given dimensions (for comparison: the rounds leave a
        /// finger up to 1 mm off).
        #[arg(long)]
        no_section_scaling: bool,
        /// The default (sections scaled to their calipers); kept so that older scripts run.
        #[arg(long, hide = true, conflicts_with = "no_section_scaling")]
        section_scaling: bool,
        /// Spacing of the vertices kept on the thumb's metacarpal when the template is
        /// simplified for the skin fit, mm: the quadrics leave that smooth stretch a few long
        /// faces, on which the fit can leave a lobe; 0 leaves the simplification to the
        /// quadrics alone (the paper).
        #[arg(long, value_name = "MM", default_value_t = ergohand::skin::pipeline::THUMB_METACARPAL_SPACING_MM)]
        thumb_spacing: f64,
        /// Weight of the joint-centre terms of the skin fit; 0 leaves them out.
        #[arg(long, default_value_t = ergohand::skin::pipeline::CENTRE_WEIGHT)]
        centre_weight: f64,
        /// Caliper rounds of the skin fit: re-fits that correct each dimension's vertex pair
        /// until a caliper on the skin (the spec's definition) reads the given value; 0 asks
        /// the pairs for the given values, as the paper does.
        #[arg(long, default_value_t = ergohand::skin::pipeline::CALIPER_ROUNDS)]
        caliper_rounds: usize,
        /// Shape prior of the skin fit for what no landmark or caliper reaches: `builtin` (the
        /// one shipped with the generic template; the default on that template, none on
        /// another), a file written by `ergohand shape-prior`, or `none` (the template's shape,
        /// as the paper).
        #[arg(long, value_name = "builtin|FILE|none")]
        shape_prior: Option<PathBuf>,
        /// A template folder (right.glb and/or left.glb, optional template-spec.toml and
        /// template.toml; see the README) instead of the embedded generic hand. The model
        /// records it; pose, grasp and validate use the same one.
        #[arg(long, value_name = "DIR")]
        template: Option<PathBuf>,
    },
    /// Train a skin shape prior from subjects whose true surface is known: each SUBJECT_DIR
    /// holds subject.toml, reference.ply (a CT or simulated reference) and MODEL/ made by
    /// `reconstruct --shape-prior none`. Prints the leave-one-out figures.
    ShapePrior {
        #[arg(required = true)]
        subject_dirs: Vec<PathBuf>,
        /// The reconstruction folder inside each subject folder.
        #[arg(long, default_value = "out")]
        model: String,
        /// The prior's JSON file.
        #[arg(long)]
        out: PathBuf,
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
        /// A track output folder (holding motion.json) to score against the subject's
        /// truth_motion/NAME.json (NAME: the folder's name, or the subject's only motion);
        /// repeatable. MODEL/motions/NAME/motion.json is scored without it.
        #[arg(long = "motion", value_name = "DIR")]
        motions: Vec<PathBuf>,
        /// A grasp output folder (holding grasp.json) to report in the grasp section;
        /// repeatable. Posed hands of MODEL (NAME.pose.json) are reported without it.
        #[arg(long = "grasp", value_name = "DIR")]
        grasps: Vec<PathBuf>,
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
        /// Length unit of an .obj output, stated in its header: mm (the toolkit's unit) or m
        /// (Blender's OBJ importer takes lengths as metres: a mm hand is ~200 m wide there).
        #[arg(long, value_parser = parse_obj_units, default_value = "mm", value_name = "mm|m")]
        obj_units: ergohand::io::Units,
    },
    /// Grasp and contact checks on a CAD part.
    Grasp {
        scene: PathBuf,
        #[arg(long)]
        model: Option<PathBuf>,
        /// Run the scene over many hands: reconstruct output folders, or folders of them (a
        /// batch output); writes OUT/NAME/ per hand and OUT/population.{json,md,html}.
        #[arg(long, num_args = 1.., value_name = "DIR", conflicts_with = "model")]
        models: Vec<PathBuf>,
        #[arg(long)]
        out: PathBuf,
    },
    /// Replay a motion trial of the subject (a [motions] entry of subject.toml) with its
    /// reconstructed link model: per-frame inverse kinematics on the markers, written as
    /// DIR/motion.json (joint centres in the lab frame, angles, marker residuals).
    Track {
        subject_dir: PathBuf,
        /// The subject's reconstruction folder (holding link_model.json).
        #[arg(long)]
        model: PathBuf,
        /// The motion's name in [motions] of subject.toml.
        #[arg(long)]
        motion: String,
        /// A scene file whose part the subject handles ([part.markers] to follow it).
        #[arg(long)]
        scene: Option<PathBuf>,
        /// Solve again the frames whose skin reaches more than MM into the scene's part, so
        /// that it does not where the markers allow (off by default: it costs joint accuracy
        /// where the reconstructed skin is too thick; see the README's Tracking section).
        #[arg(long, value_name = "MM", requires = "scene")]
        keep_out: Option<f64>,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
    },
    /// Reconstruct every subject folder of SUBJECTS_DIR (a sub-folder holding subject.toml) in
    /// parallel into OUT/<folder name>/, skipping subjects whose outputs were made from the same
    /// input content (and are newer); a failing subject is reported and skipped, the exit status
    /// is non-zero if any failed. With --track, then every motion of every subject is tracked.
    /// Summary in OUT/batch-summary.md and .json.
    Batch {
        subjects_dir: PathBuf,
        #[arg(long)]
        out: PathBuf,
        /// Threads, shared by the subjects running at once (default: the available cores; at
        /// most 2 per core and one per subject to do).
        #[arg(long)]
        jobs: Option<usize>,
        /// A template folder every subject is reconstructed from (as `reconstruct --template`).
        #[arg(long, value_name = "DIR")]
        template: Option<PathBuf>,
        /// Also track every motion trial ([motions] of each subject.toml) with its subject's
        /// reconstruction, as `track` does, into OUT/<folder name>/motions/<motion>/.
        #[arg(long)]
        track: bool,
        /// With --track: the scene whose part a motion handles, MOTION=SCENE.toml for one
        /// motion name or SCENE.toml for every other motion; repeatable. A motion without a
        /// scene is tracked without a part.
        #[arg(long, value_name = "[MOTION=]SCENE", requires = "track")]
        scene: Vec<String>,
        /// Shape prior of every subject's skin fit, as `reconstruct --shape-prior`; a subject
        /// reconstructed with another prior (or none) is redone.
        #[arg(long, value_name = "builtin|FILE|none")]
        shape_prior: Option<PathBuf>,
    },
}

fn main() -> ExitCode {
    let args = match Cli::try_parse() {
        Ok(a) => a,
        Err(e) => return parse_error(e),
    };
    cli::logger::init(args.quiet, args.verbose);
    let result = match args.command {
        Command::Demo { out } => cli::demo(&out),
        Command::Template { out, template } => match template {
            Some(dir) => cli::template::template_from(&dir, &out).map(|_| ()),
            None => cli::template(&out, &[Side::Right, Side::Left]).map(|_| ()),
        },
        Command::Synth {
            seed,
            out,
            preset,
            hand,
            posture,
            body,
            duration,
            motion_s,
            no_motions,
            percentile,
            sex,
            tip_markers,
            tip_markers_worn,
            force,
        } => cli::percentile_hand(body, sex, percentile).and_then(|percentile_hand| {
            let opts = ergohand::synth::SynthOptions {
                percentile_hand,
                tip_markers: tip_markers || tip_markers_worn,
                tip_markers_worn,
                ..cli::synth_options(
                    seed,
                    preset,
                    hand,
                    posture,
                    body,
                    duration,
                    (!no_motions).then_some(motion_s),
                )
            };
            cli::synth(&opts, &out, force)
        }),
        Command::Reconstruct {
            subject_dir,
            out,
            fit_resolution,
            no_template_posing,
            no_unfold,
            no_section_scaling,
            section_scaling: _,
            centre_weight,
            thumb_spacing,
            caliper_rounds,
            shape_prior,
            template,
        } => cli::skin_options(fit_resolution, !no_template_posing, centre_weight)
            .and_then(|o| {
                Ok(ergohand::skin::pipeline::SkinOptions {
                    caliper_rounds,
                    shape_prior: cli::reconstruct::shape_prior_option(shape_prior.as_deref())?,
                    unfold: !no_unfold,
                    section_scaling: !no_section_scaling,
                    thumb_spacing_mm: cli::reconstruct::thumb_spacing_option(thumb_spacing)?,
                    ..o
                })
            })
            .and_then(|opts| {
                cli::reconstruct::reconstruct_from(&subject_dir, &out, &opts, template.as_deref())
            })
            .map(|_| ()),
        Command::ShapePrior {
            subject_dirs,
            model,
            out,
        } => cli::shape_prior(&subject_dirs, &model, &out).map(|_| ()),
        Command::Validate {
            subject_dir,
            report,
            suite: true,
            ..
        } => cli::validate_suite(&subject_dir, &report.unwrap_or_else(|| "reports".into())),
        Command::Validate {
            subject_dir,
            model,
            report,
            suite: false,
            motions,
            grasps,
        } => {
            let model = model.unwrap_or_else(|| subject_dir.join("out"));
            let report = report.unwrap_or_else(|| model.join("report"));
            cli::validate_with(&subject_dir, &model, &report, &motions, &grasps).map(|_| ())
        }
        Command::Pose {
            model,
            pose,
            out,
            keep_angles,
            plain_skinning,
            obj_units,
        } => cli::pose_with(
            &model,
            &pose.to_string_lossy(),
            &out,
            &cli::PoseOptions {
                resolve_contacts: !keep_angles,
                preserve_volume: !plain_skinning,
                obj_units,
            },
        )
        .map(|_| ()),
        Command::Grasp {
            scene,
            model,
            models,
            out,
        } => {
            if models.is_empty() {
                cli::grasp(&scene, model.as_deref(), &out).map(|_| ())
            } else {
                cli::grasp_population(&scene, &models, &out).map(|_| ())
            }
        }
        Command::Track {
            subject_dir,
            model,
            motion,
            scene,
            keep_out,
            out,
        } => cli::track(
            &subject_dir,
            &model,
            &motion,
            scene.as_deref(),
            keep_out,
            &out,
        )
        .map(|_| ()),
        Command::Batch {
            subjects_dir,
            out,
            jobs,
            template,
            track,
            scene,
            shape_prior,
        } => cli::batch::MotionScenes::parse(&scene).and_then(|scenes| {
            cli::batch(
                &subjects_dir,
                &out,
                &cli::batch::BatchOptions {
                    jobs,
                    template,
                    track: track.then_some(scenes),
                    skin: ergohand::skin::pipeline::SkinOptions {
                        shape_prior: cli::reconstruct::shape_prior_option(shape_prior.as_deref())?,
                        ..Default::default()
                    },
                },
            )
            .map(|_| ())
        }),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}

/// A command-line mistake: help and version as clap shows them; a wrong value of an option as
/// one line naming the option, the value and the values it takes (exit status 1, as every
/// other bad input); any other mistake as clap reports it.
fn parse_error(e: clap::Error) -> ExitCode {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if e.kind() != ErrorKind::InvalidValue {
        e.exit();
    }
    let get = |k| match e.get(k) {
        Some(ContextValue::String(s)) => s.clone(),
        Some(ContextValue::Strings(v)) => v.join(", "),
        _ => String::new(),
    };
    let option = get(ContextKind::InvalidArg);
    let option = option.split_whitespace().next().unwrap_or_default();
    eprintln!(
        "error: {option} {}: not one of {}",
        get(ContextKind::InvalidValue),
        get(ContextKind::ValidValue)
    );
    ExitCode::FAILURE
}
