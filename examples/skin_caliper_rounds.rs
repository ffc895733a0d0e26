//! The skin fit with and without caliper rounds on simulated subjects, measured the way a user
//! would: the skin's distance to the CT-like reference over the hand distal of the wrist, and
//! the 22 dimensions read off the skin by the spec's definitions (at the link model's joints
//! after section 3.6, landmarks under the static trial's markers) against the given calipers
//! and against the truth.
//!
//! `cargo run --release --example skin_caliper_rounds -- SUBJECT_DIR... [--rounds N]`

use ergohand::anatomy::Dimension;
use ergohand::geometry::closest_point::AabbTree;
use ergohand::io::{ply, Units};
use ergohand::measure::{landmarks_on_skin, measure_dimensions};
use ergohand::mocap::subject::{Subject, TrialKind};
use ergohand::skin::pipeline::{fit_skin, SkinOptions};
use ergohand::skin::section_centre::{centre_on_cross_section, edge_pairs};
use ergohand::template::load_template;
use ergohand::validate::surface_regions::{hand_regions, Region};
use std::path::PathBuf;
use std::time::Instant;

fn main() -> ergohand::error::Result<()> {
    let mut dirs = Vec::new();
    let mut rounds = vec![0, ergohand::skin::pipeline::CALIPER_ROUNDS];
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        if a == "--rounds" {
            let v = args.next().expect("--rounds N[,N...]");
            rounds = v.split(',').map(|x| x.parse().expect("a count")).collect();
        } else {
            dirs.push(PathBuf::from(a));
        }
    }
    println!(
        "| subject | rounds | skin mean / p95 / max, distal of wrist (mm) | palmar palm / thenar / tips mean (mm) | dims vs given mean / mean|e| / max|e| | dims vs truth mean|e| / max|e| | skin s |"
    );
    println!("|---|---|---|---|---|---|---|");
    for dir in dirs {
        let subject = Subject::load(&dir)?;
        let truth: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("truth.json")).unwrap())
                .unwrap();
        let reference = ply::read_ply(&dir.join("reference.ply"), Units::Millimetres)?.mesh;
        let tree = AabbTree::new(&reference);
        let template = load_template(subject.hand)?;
        let pairs = edge_pairs(&template)?;
        let regions = hand_regions(subject.hand)?;
        let model = ergohand::link::estimate_link_model(&subject)?;
        let trial = subject.load_trial(TrialKind::Reference)?;
        let markers = trial.mean_positions(&ergohand::anatomy::landmark_names());
        for &r in &rounds {
            let opts = SkinOptions {
                caliper_rounds: r,
                ..SkinOptions::default()
            };
            let t0 = Instant::now();
            let fit = fit_skin(
                &template,
                &trial,
                &subject.dimensions,
                subject.marker_offset_mm,
                Some(&model),
                &opts,
            )?;
            let secs = t0.elapsed().as_secs_f64();
            let d: Vec<f64> = tree
                .distances(&fit.high.vertices)
                .into_iter()
                .map(|x| x.unwrap_or(f64::INFINITY))
                .collect();
            let pick = |keep: &dyn Fn(Region) -> bool| -> Vec<f64> {
                d.iter()
                    .zip(&regions)
                    .filter(|(_, r)| keep(**r))
                    .map(|(x, _)| *x)
                    .collect()
            };
            let mut hand = pick(&|r| r != Region::Wrist);
            hand.sort_by(f64::total_cmp);
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len().max(1) as f64;
            let (centred, _) = centre_on_cross_section(&model.skeleton, &fit.high, &pairs);
            let measured =
                measure_dimensions(&fit.high, &centred, &landmarks_on_skin(&fit.high, &markers));
            let (mut eg, mut et) = (Vec::new(), Vec::new());
            for (dim, m) in &measured {
                let Ok(m) = m else { continue };
                if let Some(g) = subject.dimensions.get(dim) {
                    eg.push(m - g);
                }
                if let Some(t) = truth["dimensions"][Dimension::name(*dim)].as_f64() {
                    et.push(m - t);
                }
            }
            let amax = |v: &[f64]| v.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
            let amean = |v: &[f64]| v.iter().map(|x| x.abs()).sum::<f64>() / v.len().max(1) as f64;
            println!(
                "| {} | {} ({}) | {:.2} / {:.2} / {:.2} | {:.2} / {:.2} / {:.2} | {:+.2} / {:.2} / {:.2} | {:.2} / {:.2} | {:.2} |",
                subject.name,
                r,
                fit.caliper_rounds,
                mean(&hand),
                hand[hand.len() * 95 / 100],
                hand.last().copied().unwrap_or(f64::NAN),
                mean(&pick(&|r| r == Region::PalmarPalm)),
                mean(&pick(&|r| r == Region::Thenar)),
                mean(&pick(&|r| r == Region::Fingertips)),
                mean(&eg),
                amean(&eg),
                amax(&eg),
                amean(&et),
                amax(&et),
                secs
            );
        }
    }
    Ok(())
}
