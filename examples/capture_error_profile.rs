//! The link model's error by capture-error source: simulated `typical` subjects captured with
//! the error model switched on one source at a time, reconstructed and compared with their
//! truth as `ergohand validate` does.
//!
//! Configurations: `base` is `typical` without the sources added to the simulator after the
//! first link model (no palm marker slide, no plate spin, seated posture = static posture,
//! landmarks on their points, labels in order, re-seating 1.5 mm / 1°); `palm`, `spin`,
//! `posture`, `seat`, `landmark`, `shuffle` each add one of them at its `typical` size; `all`
//! is the `typical` preset.
//!
//! ```sh
//! cargo run --release --example capture_error_profile -- [--seeds 101,102,103L] \
//!     [--duration 0] [--only NAME,NAME] [--out profile.tsv]
//! ```
//!
//! A seed with a trailing `L` is a left hand. `--duration 0` draws 40-80 s per trial as the
//! suite does. Prints one row per configuration and seed (tab-separated, appended to `--out`):
//! medians of the 3-DOF and 1-DOF centre errors (mm) and of the axis errors (deg), the median
//! and largest link-length error (mm), and the worst joint.

use ergohand::cli;
use ergohand::synth::capture::ErrorModel;
use ergohand::synth::{self, Preset, SynthOptions};
use ergohand::validate::link_accuracy::link_accuracy;
use std::io::Write;

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The configurations, in table order.
const CONFIGS: [&str; 8] = [
    "base", "palm", "spin", "posture", "seat", "landmark", "shuffle", "all",
];

/// The error model of a configuration.
fn error_model(config: &str) -> ErrorModel {
    let all = Preset::Typical.error_model();
    let base = all.first_capture_model();
    match config {
        "palm" => ErrorModel {
            palm_sta_mm: all.palm_sta_mm,
            ..base
        },
        "spin" => ErrorModel {
            plate_spin_deg: all.plate_spin_deg,
            ..base
        },
        "posture" => ErrorModel {
            seated_posture_sd_deg: all.seated_posture_sd_deg,
            ..base
        },
        "seat" => ErrorModel {
            seat: all.seat,
            ..base
        },
        "landmark" => ErrorModel {
            landmark_sd_mm: all.landmark_sd_mm,
            ..base
        },
        "shuffle" => ErrorModel {
            shuffle_labels: true,
            ..base
        },
        "all" => all,
        _ => base,
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let seeds = arg(&args, "--seeds").unwrap_or_else(|| "101,102,103L".into());
    let duration: f64 = arg(&args, "--duration")
        .map(|s| s.parse())
        .transpose()?
        .unwrap_or(0.0);
    let out = arg(&args, "--out");
    let only = arg(&args, "--only");
    let tmp = tempfile::tempdir()?;
    for config in CONFIGS {
        if let Some(o) = &only {
            if !o.split(',').any(|c| c == config) {
                continue;
            }
        }
        for s in seeds.split(',') {
            let left = s.ends_with('L');
            let seed: u64 = s.trim_end_matches('L').parse()?;
            let mut opts = SynthOptions::new(seed, Preset::Typical);
            if left {
                opts.hand = ergohand::anatomy::Side::Left;
            }
            opts.voxel_mm = 2.0;
            opts.duration_s = (duration > 0.0).then_some(duration);
            let subject = synth::simulate_with(&opts, &error_model(config))?;
            let sdir = tmp.path().join(format!("{config}-{s}"));
            synth::write_subject(&sdir, &subject, false)?;
            let model = sdir.join("out");
            cli::reconstruct(&sdir, &model)?;
            let acc = link_accuracy(&model.join("link_model.json"), &sdir.join("truth.json"))?;
            let by_dof = |dof: usize| {
                median(
                    acc.joints
                        .iter()
                        .filter(|e| {
                            ergohand::anatomy::Joint::from_name(&e.joint).map(|j| j.dof())
                                == Some(dof)
                        })
                        .map(|e| e.centre_mm)
                        .collect(),
                )
            };
            let axis = median(acc.joints.iter().filter_map(|e| e.axis_deg).collect());
            let lengths: Vec<f64> = acc
                .link_lengths
                .values()
                .map(|(e, t)| (e - t).abs())
                .collect();
            let worst = acc
                .joints
                .iter()
                .max_by(|a, b| a.centre_mm.total_cmp(&b.centre_mm))
                .map(|e| format!("{} {:.2}", e.joint, e.centre_mm))
                .unwrap_or_default();
            let row = format!(
                "{config}\t{s}\t{:.2}\t{:.2}\t{:.2}\t{:.2}\t{:.2}\t{worst}",
                by_dof(3),
                by_dof(1),
                axis,
                median(lengths.clone()),
                lengths.iter().cloned().fold(0.0, f64::max),
            );
            println!("{row}");
            if let Some(path) = &out {
                let mut f = std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(path)?;
                writeln!(f, "{row}")?;
            }
            std::fs::remove_dir_all(&sdir)?;
        }
    }
    Ok(())
}
