//! Repeatability of the link lengths, two ways:
//!
//! * trial repeats (the issue's and the seed paper's measure, section 4: "calibration motions
//!   ... five times"): within one session (plates where they are, the same soft-tissue slide and
//!   static trial) every calibration motion recorded again (`SynthOptions::trial_repeat` 1-N: a
//!   new realisation of the motion, seating, drift, noise and gaps); done in several sessions,
//!   since how repeatable a session is depends on where its plates sit;
//! * session repeats: the hand captured again with re-attached plates (`SynthOptions::repeat`
//!   1-N, each with one recording of a drawn motion, `trial_repeat` 1), and, as before, with the
//!   protocol's nominal motion (`trial_repeat` 0).
//!
//! For each, the SD of every finger's MCP-PIP and PIP-DIP lengths (thumb: CMC-MCP, MCP-IP) for
//! the model's centres and for every estimator alone (from each joint's `alternatives`, which
//! are in the parent link's pose at the reference frame alone, i.e. without the held reference
//! poses of `link::model`; the "SCoRE / SARA" row is thus the model before that correction). Then a profile of the index trial repeats of the first session: the same
//! plates re-simulated with one error source removed at a time, to show which error the
//! remaining SD comes from.
//!
//! ```sh
//! cargo run --release --example link_repeatability -- [--seed 51] [--repeats 5] \
//!     [--sessions 5] [--duration 40] [--out reports/link-repeatability.md]
//! ```
//!
//! `--duration 0` draws 40-80 s per trial as the suite does. Writes markdown to `--out` (and
//! stdout).

use ergohand::anatomy::{Finger, Joint, Side};
use ergohand::link::estimate::estimate_link_model_from;
use ergohand::link::LinkModel;
use ergohand::mocap::trajectories::Trajectories;
use ergohand::rng::Rng;
use ergohand::synth::capture::{simulate_trial, ErrorModel, MarkerDef, Recording};
use ergohand::synth::motion::{MotionVariation, Trial};
use ergohand::synth::{simulate, Preset, SynthOptions, SyntheticSubject, FRAME_RATE};
use nalgebra::{Isometry3, Point3};
use std::collections::BTreeMap;
use std::fmt::Write;

/// Estimators: the chosen centre, then each family alone as (3-DOF centre, 1-DOF centre). A
/// joint without the soft-tissue model (no separable driver) keeps the rigid estimator there.
const FAMILIES: [(&str, [&str; 2]); 5] = [
    ("model (rule's choice, held reference poses)", ["", ""]),
    ("SCoRE / SARA (rigid)", ["score", "sara"]),
    (
        "soft-tissue model (score-sta / sara-sta)",
        ["score-sta", "sara-sta"],
    ),
    (
        "bias-compensated sphere / circle on axis",
        ["bcls", "circle-on-axis"],
    ),
    (
        "plain sphere (the paper's) / circle on axis",
        ["sphere-ls", "circle-on-axis"],
    ),
];

/// Link lengths `[finger][segment]` of one model, per family.
type Lengths = Vec<[[Option<f64>; 2]; 5]>;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn sd(v: &[f64]) -> f64 {
    let m = mean(v);
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1).max(1) as f64).sqrt()
}

fn lengths(m: &LinkModel) -> Lengths {
    FAMILIES
        .iter()
        .map(|(_, names)| {
            let c = |j: Joint| {
                let e = &m.joints[j.index()];
                let name = names[usize::from(j.dof() == 1)];
                if name.is_empty() {
                    return Some(e.centre);
                }
                let alt = &e.diagnostics.alternatives;
                let p = alt
                    .get(name)
                    .or_else(|| alt.get(name.trim_end_matches("-sta")))?;
                Some(Point3::new(p[0], p[1], p[2]))
            };
            Finger::ALL.map(|f| {
                let js = f.joints();
                let (a, b, d) = (c(js[0]), c(js[1]), c(js[2]));
                [
                    a.zip(b).map(|(a, b)| (b - a).norm()),
                    b.zip(d).map(|(b, d)| (d - b).norm()),
                ]
            })
        })
        .collect()
}

fn true_lengths(s: &SyntheticSubject) -> [[f64; 2]; 5] {
    let t = |j: Joint| {
        let c = s.truth.joints[j.name()].centre;
        Point3::new(c[0], c[1], c[2])
    };
    Finger::ALL.map(|f| {
        let js = f.joints();
        [(t(js[1]) - t(js[0])).norm(), (t(js[2]) - t(js[1])).norm()]
    })
}

/// The values of family `k`, finger `fi`, segment `seg` over the runs.
fn values(runs: &[Lengths], k: usize, fi: usize, seg: usize) -> Vec<f64> {
    runs.iter().filter_map(|r| r[k][fi][seg]).collect()
}

fn header() -> String {
    let cols: Vec<String> = Finger::ALL
        .iter()
        .flat_map(|f| {
            let js = f.joints();
            [
                format!("{}-{}", js[0], js[1]),
                format!("{}-{}", js[1], js[2]),
            ]
        })
        .collect();
    format!(
        "| estimator | {} |\n|---|{}\n",
        cols.join(" | "),
        "---|".repeat(10)
    )
}

/// A table of SD (mean error against the truth) per family and link over `runs`.
fn table(runs: &[Lengths], truth: &[[f64; 2]; 5]) -> String {
    let mut md = header();
    for (k, (name, _)) in FAMILIES.iter().enumerate() {
        let cells: Vec<String> = (0..10)
            .map(|c| {
                let (fi, seg) = (c / 2, c % 2);
                let v = values(runs, k, fi, seg);
                if v.len() < 2 {
                    return "-".into();
                }
                format!("{:.2} ({:+.2})", sd(&v), mean(&v) - truth[fi][seg])
            })
            .collect();
        md.push_str(&format!("| {name} | {} |\n", cells.join(" | ")));
    }
    md
}

/// The index link lengths of a model whose index trial is replaced by `index`.
fn with_index(s: &SyntheticSubject, index: Trajectories) -> Result<Lengths, ergohand::Error> {
    let mut trials = s.trials.clone();
    trials.insert("index".into(), index);
    Ok(lengths(&estimate_link_model_from(Side::Right, 0, &trials)?))
}

/// One error source removed from the profile's re-simulated index trial.
#[derive(Clone, Copy, PartialEq)]
enum Ablation {
    None,
    NoNoise,
    NoSlide,
    NominalMotion,
    OnlyNoise,
    OnlySlide,
    CleanReference,
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seed: u64 = arg(&args, "--seed").map_or(Ok(51), |s| s.parse())?;
    let repeats: u32 = arg(&args, "--repeats").map_or(Ok(5), |s| s.parse())?;
    let sessions: u32 = arg(&args, "--sessions").map_or(Ok(5), |s| s.parse())?;
    let duration: f64 = arg(&args, "--duration").map_or(Ok(40.0), |s| s.parse())?;
    let out = arg(&args, "--out").unwrap_or_else(|| "reports/link-repeatability.md".into());
    let opts = |repeat: u32, trial_repeat: u32| SynthOptions {
        duration_s: (duration > 0.0).then_some(duration),
        voxel_mm: 2.0,
        repeat,
        trial_repeat,
        ..SynthOptions::new(seed, Preset::Typical)
    };
    let mut used: BTreeMap<String, usize> = BTreeMap::new();
    let mut run = |o: SynthOptions| -> Result<(SyntheticSubject, Lengths), ergohand::Error> {
        let s = simulate(&o)?;
        let m = estimate_link_model_from(Side::Right, 0, &s.trials)?;
        for e in &m.joints {
            *used.entry(e.diagnostics.estimator.clone()).or_default() += 1;
        }
        eprintln!("session {} take {} done", o.repeat, o.trial_repeat);
        let l = lengths(&m);
        Ok((s, l))
    };

    // Trial repeats in sessions 0..sessions.
    let mut trial_runs: Vec<Vec<Lengths>> = Vec::new();
    let mut first: Option<SyntheticSubject> = None;
    for session in 0..sessions {
        let mut v = Vec::new();
        for take in 1..=repeats {
            let (s, l) = run(opts(session, take))?;
            if session == 0 && take == 1 {
                first = Some(s);
            }
            v.push(l);
        }
        trial_runs.push(v);
    }
    let first = first.ok_or("--sessions and --repeats must be at least 1")?;
    let truth = true_lengths(&first);
    // Session repeats, with a drawn motion and with the nominal one.
    let mut session_runs = Vec::new();
    let mut nominal_runs = Vec::new();
    for session in 1..=repeats {
        session_runs.push(run(opts(session, 1))?.1);
        nominal_runs.push(run(opts(session, 0))?.1);
    }

    // Profile: the first session's index plates, the trial re-simulated per take with one
    // error source removed (no seating offset, which registration removes exactly).
    let defs: &[MarkerDef] = &first.markers["index"];
    let no_slide: Vec<MarkerDef> = defs
        .iter()
        .map(|d| MarkerDef {
            sta: vec![],
            ..d.clone()
        })
        .collect();
    let labels: Vec<String> = defs.iter().map(|d| d.name.clone()).collect();
    let frames = first.trials["index"].n_frames();
    let ablations = [
        (Ablation::None, "all errors"),
        (Ablation::NoNoise, "no marker noise"),
        (Ablation::NoSlide, "no soft-tissue slide"),
        (
            Ablation::NominalMotion,
            "the same (nominal) motion every take",
        ),
        (
            Ablation::OnlyNoise,
            "marker noise only (no slide, nominal motion)",
        ),
        (
            Ablation::OnlySlide,
            "soft-tissue slide only (no noise, drawn motion)",
        ),
        (
            Ablation::CleanReference,
            "all errors, but no marker noise in the reference frame (frame 0)",
        ),
    ];
    let mut profile: Vec<(&str, Vec<Lengths>)> = Vec::new();
    for (ab, label) in ablations {
        let mut err = Preset::Typical.error_model();
        if matches!(ab, Ablation::NoNoise | Ablation::OnlySlide) {
            err.noise_mm = 0.0;
        }
        let slide = !matches!(ab, Ablation::NoSlide | Ablation::OnlyNoise);
        let mut v = Vec::new();
        for take in 1..=repeats {
            let mut rng = Rng::new(seed).fork(&format!("profile-take-{take}"));
            let var = if matches!(ab, Ablation::NominalMotion | Ablation::OnlyNoise) {
                MotionVariation::NOMINAL
            } else {
                MotionVariation::draw(&mut rng.fork("motion"))
            };
            let sim = |err: &ErrorModel, rng: &mut Rng| {
                simulate_trial(
                    Trial::Finger(Finger::Index),
                    &first.true_skeleton,
                    if slide { defs } else { &no_slide },
                    frames,
                    FRAME_RATE,
                    err,
                    &Recording {
                        var,
                        ..Recording::nominal()
                    },
                    &Isometry3::identity(),
                    rng,
                )
            };
            // The same take without noise (noise has its own stream): its frame 0 replaces
            // the noisy one.
            let clean_ref = (ab == Ablation::CleanReference).then(|| {
                sim(
                    &ErrorModel {
                        noise_mm: 0.0,
                        ..err
                    },
                    &mut rng.clone(),
                )
            });
            let mut positions = sim(&err, &mut rng);
            if let Some(c) = clean_ref {
                for (p, q) in positions.iter_mut().zip(c) {
                    p[0] = q[0];
                }
            }
            let traj = Trajectories {
                frame_rate: FRAME_RATE,
                labels: labels.clone(),
                positions,
                source: "trials/index.c3d".into(),
            };
            v.push(with_index(&first, traj)?);
        }
        eprintln!("profile '{label}' done");
        profile.push((label, v));
    }

    let index = Finger::Index as usize;
    let dur = if duration > 0.0 {
        format!("{duration}")
    } else {
        "40-80".into()
    };
    let mut md = String::new();
    writeln!(
        md,
        "# Link-length repeatability \n\nGenerated by `cargo run --release --example \
         link_repeatability -- --seed {seed} --repeats {repeats} --sessions {sessions} \
         --duration {duration}`: one simulated `typical` right hand (seed {seed}), trials of \
         {dur} s, CT voxel 2 mm. SD of each link length over the repeats (mm); in brackets the \
         mean error against the truth (mm). The seed paper: index 0.52 (MCP-PIP) and 0.92 \
         (PIP-DIP) mm on a real subject over five recordings of the calibration motions; the goal \
         is 0.3 mm. The rows `model (...)` are the link model as \
         `reconstruct` writes it: the rule's estimator, each centre carried to the palm through \
         the proximal links' held reference poses (`link::estimate::held_reference_pose`: the mean \
         relative pose over the held reference posture at the start of the trial, instead of \
         the single reference frame). The other rows are each estimator's centre as \
         `alternatives` stores it, in its parent link's pose at the reference frame alone: \
         `SCoRE / SARA (rigid)` is the model's estimator without that correction.\n\n\
         * **trial repeats** (the issue's and the paper's measure): in one session, the plates \
         where they are (same placement, same soft-tissue slide, same static trial), every \
         calibration motion recorded {repeats} times (`SynthOptions::trial_repeat` 1-{repeats}): \
         each take a new realisation of the motion (amplitudes 85-105 % of the protocol's, \
         periods 85-115 %, `synth::motion::MotionVariation`), new seating and drift of the hand, \
         new noise and gaps;\n\
         * **session repeats**: the plates re-attached for every repeat (`SynthOptions::repeat` \
         1-{repeats}: new plate placement and soft-tissue slide, new static trial), each with \
         one drawn motion (`trial_repeat` 1), and as in the previous version of this report \
         with the protocol's nominal motion (`trial_repeat` 0).\n"
    )?;
    writeln!(
        md,
        "## Index finger, every measure\n\n| estimator | measure | I_MCP-I_PIP SD | \
         I_PIP-I_DIP SD |\n|---|---|---|---|"
    )?;
    for (k, (name, _)) in FAMILIES.iter().enumerate() {
        let cell = |runs: &[Lengths], seg: usize| {
            let v = values(runs, k, index, seg);
            if v.len() < 2 {
                "-".to_string()
            } else {
                format!("{:.2} ({:+.2})", sd(&v), mean(&v) - truth[index][seg])
            }
        };
        // Trial repeats: per session, then the mean and the largest over sessions.
        let per_session: Vec<[f64; 2]> = trial_runs
            .iter()
            .map(|r| [0, 1].map(|seg| sd(&values(r, k, index, seg))))
            .collect();
        for (s, v) in per_session.iter().enumerate() {
            writeln!(
                md,
                "| {name} | trial repeats, session {s} | {:.2} ({:+.2}) | {:.2} ({:+.2}) |",
                v[0],
                mean(&values(&trial_runs[s], k, index, 0)) - truth[index][0],
                v[1],
                mean(&values(&trial_runs[s], k, index, 1)) - truth[index][1],
            )?;
        }
        let col = |seg: usize| per_session.iter().map(|v| v[seg]).collect::<Vec<_>>();
        let max = |v: Vec<f64>| v.into_iter().fold(0.0, f64::max);
        writeln!(
            md,
            "| {name} | **trial repeats, mean (max) over {sessions} sessions** | **{:.2}** ({:.2}) | \
             **{:.2}** ({:.2}) |",
            mean(&col(0)),
            max(col(0)),
            mean(&col(1)),
            max(col(1))
        )?;
        writeln!(
            md,
            "| {name} | session repeats, drawn motion | {} | {} |",
            cell(&session_runs, 0),
            cell(&session_runs, 1)
        )?;
        writeln!(
            md,
            "| {name} | session repeats, nominal motion | {} | {} |",
            cell(&nominal_runs, 0),
            cell(&nominal_runs, 1)
        )?;
    }
    writeln!(
        md,
        "\n## Trial repeats, session 0, every finger\n\n{}",
        table(&trial_runs[0], &truth)
    )?;
    writeln!(
        md,
        "## Session repeats (drawn motion), every finger\n\n{}",
        table(&session_runs, &truth)
    )?;
    writeln!(
        md,
        "## Session repeats (nominal motion, as before), every finger\n\n{}",
        table(&nominal_runs, &truth)
    )?;
    writeln!(
        md,
        "## Where the trial-repeat SD comes from (index, session 0)\n\nThe session-0 index \
         plates (their placement and soft-tissue slide) re-simulated {repeats} times with one \
         error source removed at a time (no seating offset; drift and gaps kept), the other \
         trials as simulated. SD over the takes, mm (mean error against the truth).\n\n\
         | errors | estimator | I_MCP-I_PIP | I_PIP-I_DIP |\n|---|---|---|---|"
    )?;
    for (label, runs) in &profile {
        for (k, (name, _)) in FAMILIES.iter().enumerate() {
            let cell = |seg: usize| {
                let v = values(runs, k, index, seg);
                format!("{:.2} ({:+.2})", sd(&v), mean(&v) - truth[index][seg])
            };
            writeln!(md, "| {label} | {name} | {} | {} |", cell(0), cell(1))?;
        }
    }
    writeln!(
        md,
        "\nEstimators picked over all simulated subjects and joints: {}.",
        used.iter()
            .map(|(k, v)| format!("`{k}` {v}"))
            .collect::<Vec<_>>()
            .join(", ")
    )?;
    print!("{md}");
    ergohand::io::atomic::write_bytes_atomic(std::path::Path::new(&out), md.as_bytes())?;
    Ok(())
}
