//! The link model alone (no skin stage) against simulated subjects' truth: per joint the centre
//! error, split for 1-DOF joints into the part off the true axis line and the part along it,
//! the axis error and the link lengths; and the subjects to study it on, made with the capture
//! error model switched off one source at a time.
//!
//! ```sh
//! # subjects: ROOT/CONFIG-SEED (a trailing L on a seed is a left hand)
//! cargo run --release --example link_centres -- --make ROOT --seeds 301,302L \
//!     --body procedural --configs all,-plate,-posture [--duration 20]
//! # scores: every subject folder given (its truth.json), the link model of each option set
//! cargo run --release --example link_centres -- DIR... [--options first-frame,default] [--joints]
//! ```
//!
//! Configurations: `all` is the `typical` preset; `-SOURCE` is `all` without one source:
//! `noise`, `plate` (plate slide), `spin`, `palm` (palm marker slide), `skin` (forearm marker
//! slide), `gaps`, `seat` (re-seating), `drift`, `posture` (seated posture off the static one),
//! `landmark` (landmark placement). A score line gives the medians over the joints of the 3-DOF
//! and 1-DOF centre errors, the 1-DOF errors off and along the axis, the axis error, the median
//! and largest link-length error and the worst joint, mm and degrees; `ALL` lines pool the
//! subjects given (median of the per-joint errors over all of them). Where `truth.json` has the
//! true joints' frames (`synth` writes them), each line also gives the 1-DOF errors' RMS along
//! the true axis (x), dorsal (y) and along the link (z), and the `ALL` lines split them by kind.

use ergohand::anatomy::Joint;
use ergohand::link::estimate::{estimate_link_model_with, LinkOptions};
use ergohand::mocap::subject::Subject;
use ergohand::skeleton::record::{joint_records, JointRecord};
use ergohand::synth::capture::ErrorModel;
use ergohand::synth::{self, Body, Preset, SynthOptions};
use ergohand::validate::link_accuracy::{link_lengths, read_truth};
use nalgebra::{Matrix3, Vector3};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

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

/// The `typical` error model without the source `config` names (`all`: none removed).
fn error_model(config: &str) -> ErrorModel {
    let all = Preset::Typical.error_model();
    match config.trim_start_matches('-') {
        "noise" => ErrorModel {
            noise_mm: 0.0,
            ..all
        },
        "plate" => ErrorModel {
            plate_sta_mm: (0.0, 0.0),
            ..all
        },
        "spin" => ErrorModel {
            plate_spin_deg: (0.0, 0.0),
            ..all
        },
        "palm" => ErrorModel {
            palm_sta_mm: (0.0, 0.0),
            ..all
        },
        "skin" => ErrorModel {
            skin_sta_mm: (0.0, 0.0),
            ..all
        },
        "gaps" => ErrorModel {
            gap_fraction: 0.0,
            ..all
        },
        "seat" => ErrorModel {
            seat: (0.0, 0.0),
            ..all
        },
        "drift" => ErrorModel {
            drift: (0.0, 0.0),
            ..all
        },
        "posture" => ErrorModel {
            seated_posture_sd_deg: 0.0,
            ..all
        },
        "landmark" => ErrorModel {
            landmark_sd_mm: 0.0,
            ..all
        },
        "all" => all,
        other => panic!("unknown configuration {other}"),
    }
}

/// The option sets by name (`default` is [`LinkOptions::default`]).
fn options(name: &str) -> LinkOptions {
    LinkOptions::named(name).unwrap_or_else(|| panic!("unknown option set {name}"))
}

/// Per joint: (joint, centre error, off-axis part, along-axis part, axis error in degrees, the
/// error in the true joint's frame: along its axis, dorsal, along the link).
type Row = (Joint, f64, f64, f64, Option<f64>, Option<Vector3<f64>>);

/// The true joints' frames (rows x, y, z) from `truth.json`: `synth` writes its joints as
/// [`JointRecord`]s, frames included, beside the spec's centres and axes, which is all
/// `read_truth` takes. Empty for a truth without them.
fn truth_frames(path: &Path) -> BTreeMap<String, Matrix3<f64>> {
    #[derive(serde::Deserialize)]
    struct Records {
        joints: BTreeMap<String, JointRecord>,
    }
    std::fs::read_to_string(path)
        .ok()
        .and_then(|text| serde_json::from_str::<Records>(&text).ok())
        .map(|r| {
            r.joints
                .into_iter()
                .map(|(name, j)| (name, Matrix3::from(j.frame).transpose()))
                .collect()
        })
        .unwrap_or_default()
}

fn score(
    dir: &Path,
    opts: &LinkOptions,
) -> Result<(Vec<Row>, Vec<f64>), Box<dyn std::error::Error>> {
    let subject = Subject::load(dir)?;
    let truth = read_truth(&dir.join("truth.json"))?;
    let frames = truth_frames(&dir.join("truth.json"));
    let model = estimate_link_model_with(&subject, opts)?;
    let records = joint_records(&model.skeleton);
    if std::env::var_os("LINK_CENTRES_CUES").is_some() {
        let d = &model.joints[Joint::IPip.index()].diagnostics;
        let w: Vec<String> = d
            .level_cues
            .iter()
            .map(|(k, c)| format!("{k} {:.2}", c.weight))
            .collect();
        eprintln!(
            "{}: I_PIP level weights {w:?}, level SD {:.2}, centre SD {:.2}",
            dir.display(),
            d.level_sd_mm.unwrap_or(f64::NAN),
            d.centre_sd_mm.unwrap_or(f64::NAN)
        );
    }
    let v = |a: [f64; 3]| Vector3::new(a[0], a[1], a[2]);
    let rows = Joint::ALL
        .iter()
        .map(|&j| {
            let (m, t) = (&records[j.name()], &truth.joints[j.name()]);
            let d = v(m.centre) - v(t.centre);
            let (off, along) = match t.axis {
                Some(a) => {
                    let a = v(a).normalize();
                    let al = a.dot(&d);
                    ((d - a * al).norm(), al)
                }
                None => (d.norm(), 0.0),
            };
            let axis = match (m.axis, t.axis) {
                (Some(a), Some(b)) => {
                    let g = v(a).angle(&v(b)).to_degrees();
                    Some(g.min(180.0 - g))
                }
                _ => None,
            };
            let comp = frames.get(j.name()).map(|f| f * d);
            (j, d.norm(), off, along, axis, comp)
        })
        .collect();
    let truth_lengths = link_lengths(&truth.joints);
    let lengths = link_lengths(&records)
        .into_iter()
        .map(|(k, l)| (l - truth_lengths[&k]).abs())
        .collect();
    Ok((rows, lengths))
}

fn summary(label: &str, rows: &[Row], lengths: &[f64]) -> String {
    let by = |dof: usize, k: usize| {
        median(
            rows.iter()
                .filter(|r| r.0.dof() == dof)
                .map(|r| [r.1, r.2, r.3.abs()][k])
                .collect(),
        )
    };
    let axis = median(rows.iter().filter_map(|r| r.4).collect());
    let worst = rows
        .iter()
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map(|r| format!("{} {:.2}", r.0, r.1))
        .unwrap_or_default();
    format!(
        "{label}\t3dof {:.2}\t1dof {:.2} (off {:.2} along {:.2})\taxis {:.2}\tlen {:.2} max {:.2}\tworst {worst}{}",
        by(3, 0),
        by(1, 0),
        by(1, 1),
        by(1, 2),
        axis,
        median(lengths.to_vec()),
        lengths.iter().cloned().fold(0.0, f64::max),
        components(rows.iter().filter(|r| r.0.dof() == 1))
            .map(|c| format!("\t1dof rms x {:.2} y {:.2} z {:.2}", c.x, c.y, c.z))
            .unwrap_or_default(),
    )
}

/// RMS of the rows' errors in their true joints' frames (x along the axis, y dorsal, z along
/// the link), `None` when a row has no true frame.
fn components<'a>(rows: impl Iterator<Item = &'a Row>) -> Option<Vector3<f64>> {
    let c: Vec<Vector3<f64>> = rows.map(|r| r.5).collect::<Option<_>>()?;
    if c.is_empty() {
        return None;
    }
    let ms = c.iter().map(|v| v.component_mul(v)).sum::<Vector3<f64>>() / c.len() as f64;
    Some(ms.map(f64::sqrt))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    if let Some(root) = arg(&args, "--make") {
        let seeds = arg(&args, "--seeds").unwrap_or_else(|| "301,302L".into());
        let body: Body = arg(&args, "--body")
            .unwrap_or_else(|| "procedural".into())
            .parse()?;
        let duration: f64 = arg(&args, "--duration")
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(20.0);
        let configs = arg(&args, "--configs").unwrap_or_else(|| "all".into());
        for config in configs.split(',') {
            for s in seeds.split(',') {
                let dir = PathBuf::from(&root).join(format!("{config}-{s}"));
                if dir.join("truth.json").exists() {
                    continue;
                }
                let mut opts = SynthOptions::new(s.trim_end_matches('L').parse()?, Preset::Typical);
                if s.ends_with('L') {
                    opts.hand = ergohand::anatomy::Side::Left;
                }
                opts.body = body;
                opts.voxel_mm = 2.0;
                opts.duration_s = (duration > 0.0).then_some(duration);
                let subject = synth::simulate_with(&opts, &error_model(config))?;
                synth::write_subject(&dir, &subject, false)?;
                eprintln!("made {}", dir.display());
            }
        }
        return Ok(());
    }
    let names = arg(&args, "--options").unwrap_or_else(|| "default".into());
    let per_joint = args.iter().any(|a| a == "--joints");
    let dirs: Vec<PathBuf> = args[1..]
        .iter()
        .enumerate()
        .filter(|(i, a)| !a.starts_with("--") && (*i == 0 || !args[*i].starts_with("--options")))
        .map(|(_, a)| PathBuf::from(a))
        .filter(|p| p.join("subject.toml").exists())
        .collect();
    for name in names.split(',') {
        let opts = options(name);
        let (mut all_rows, mut all_lengths) = (Vec::new(), Vec::new());
        for dir in &dirs {
            let (rows, lengths) = score(dir, &opts)?;
            let label = format!("{name}\t{}", dir.file_name().unwrap().to_string_lossy());
            println!("{}", summary(&label, &rows, &lengths));
            if per_joint {
                for r in &rows {
                    println!(
                        "    {:6} {:5.2} off {:5.2} along {:5.2} axis {}",
                        r.0.name(),
                        r.1,
                        r.2,
                        r.3,
                        r.4.map(|a| format!("{a:.2}")).unwrap_or_default()
                    );
                }
            }
            all_rows.extend(rows);
            all_lengths.extend(lengths);
        }
        println!(
            "{}",
            summary(&format!("{name}\tALL"), &all_rows, &all_lengths)
        );
        // Among the hinges the kinds `MCP` and `IP` are the thumb's alone.
        for kind in ["PIP", "DIP", "MCP", "IP"] {
            let of_kind = all_rows
                .iter()
                .filter(|r| r.0.dof() == 1 && r.0.kind() == kind);
            if let Some(c) = components(of_kind) {
                println!(
                    "{name}\tALL {kind}\t1dof rms x {:.2} y {:.2} z {:.2}",
                    c.x, c.y, c.z
                );
            }
        }
    }
    Ok(())
}
