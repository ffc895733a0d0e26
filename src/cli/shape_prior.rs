//! `ergohand shape-prior`: train a skin shape prior from subjects whose true surface is known
//! (a CT or a simulated reference), each reconstructed without a prior.

use crate::anatomy::{landmark_names, Side};
use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use crate::io::{atomic, obj, ply, Units};
use crate::mocap::subject::{Subject, TrialKind};
use crate::skin::shape_prior::{
    fill_and_smooth, normal_offsets, subject_features, train_shape_prior, JointLine, PriorSample,
    ShapePrior, SMOOTHING_PASSES,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Per template vertex of each hand: whether it belongs to the forearm (its dominant link),
/// which is scored nowhere: a reference is cut across the arm, and past the cut a ray meets the
/// reference's cap, not the arm's skin.
fn forearm_vertices() -> Result<Vec<(Side, Vec<bool>)>> {
    let arm = crate::anatomy::Link::Arm.index();
    [Side::Right, Side::Left]
        .into_iter()
        .map(|side| {
            let template = crate::template::load_template(side)?;
            let owners = crate::template::dominant_links(&template.weights);
            Ok((side, owners.into_iter().map(|o| o == arm).collect()))
        })
        .collect()
}

/// Each joint's centre and (hinges) axis from a `link_model.json`, in the reference trial's
/// frame.
fn link_model_joints(path: &Path) -> Result<BTreeMap<String, JointLine>> {
    Ok(crate::validate::link_accuracy::read_joints(path)?
        .into_iter()
        .map(|(name, j)| {
            let line = JointLine {
                centre: Point::from(j.centre),
                axis: j.axis.filter(|_| j.dof == 1).map(Vec3::from),
            };
            (name, line)
        })
        .collect())
}

/// The training sample of one subject: `DIR/subject.toml` (its dimensions),
/// `DIR/reference.ply` (its surface) and `DIR/MODEL/skin.obj` (its skin fitted without a
/// prior, which `DIR/MODEL/report.json` must say); `forearm` from [`forearm_vertices`].
fn prior_sample(dir: &Path, model: &str, forearm: &[(Side, Vec<bool>)]) -> Result<PriorSample> {
    let subject = Subject::load(dir)?;
    let report_path = dir.join(model).join("report.json");
    let report: serde_json::Value = serde_json::from_slice(&atomic::read_bytes(&report_path)?)
        .map_err(|e| Error::input(&report_path, format!("not JSON: {e}")))?;
    if !report["skin"]["shape_prior"].is_null() {
        return Err(Error::input(
            &report_path,
            "skin.shape_prior: the skin was fitted with a shape prior; reconstruct the training \
             subjects with --shape-prior none",
        ));
    }
    let skin_path = dir.join(model).join("skin.obj");
    let skin = obj::read_obj(&skin_path, Units::Millimetres)?;
    let forearm = &forearm
        .iter()
        .find(|(side, _)| *side == subject.hand)
        .expect("both hands")
        .1;
    if forearm.len() != skin.n_vertices() {
        return Err(Error::input(
            &skin_path,
            format!(
                "{} vertices: not a skin of the generic template ({})",
                skin.n_vertices(),
                forearm.len()
            ),
        ));
    }
    let reference = ply::read_ply(&dir.join("reference.ply"), Units::Millimetres)?.mesh;
    let raw = normal_offsets(&skin, &reference);
    let rings = skin.topology().vertex_rings;
    let features = match report["skin"]["shape_prior_features"].as_object() {
        Some(recorded) => recorded
            .iter()
            .map(|(name, v)| {
                v.as_f64().map(|v| (name.clone(), v)).ok_or_else(|| {
                    Error::input(
                        &report_path,
                        format!("skin.shape_prior_features.{name}: not a number"),
                    )
                })
            })
            .collect::<Result<BTreeMap<String, f64>>>()?,
        None => {
            // A model written before the fit recorded its features: read them from the written
            // link model, whose hinges the skin stage has moved, so they differ a little from
            // what a fit reads.
            log::warn!(
                "{}: no skin.shape_prior_features; the tissue depths are read from \
                 link_model.json instead (re-run reconstruct for the features a fit reads)",
                report_path.display()
            );
            let static_trial = subject.load_trial(TrialKind::Reference)?;
            subject_features(
                &subject.dimensions,
                &static_trial.mean_positions(&landmark_names()),
                &link_model_joints(&dir.join(model).join("link_model.json"))?,
                subject.marker_offset_mm,
            )
        }
    };
    Ok(PriorSample {
        name: subject.name.clone(),
        features,
        measured: raw
            .iter()
            .zip(forearm)
            .map(|(r, &arm)| r.is_some() && !arm)
            .collect(),
        offsets: fill_and_smooth(&raw, &rings, SMOOTHING_PASSES),
    })
}

/// `ergohand shape-prior SUBJECT_DIR... --model NAME --out FILE`: the samples of every subject
/// ([`prior_sample`]), the prior trained on them with its leave-one-out figures, written as
/// JSON. A subject that cannot be read is an error naming its file.
pub fn shape_prior(subjects: &[PathBuf], model: &str, out: &Path) -> Result<ShapePrior> {
    if out.is_dir() {
        return Err(Error::input(
            out,
            "--out is a folder; give the prior's file name, e.g. prior.json",
        ));
    }
    let forearm = forearm_vertices()?;
    let pb = super::progress(subjects.len() as u64, "subjects");
    let mut samples = Vec::new();
    for dir in subjects {
        samples.push(prior_sample(dir, model, &forearm)?);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let prior = train_shape_prior(&samples)?;
    let json = serde_json::to_string(&prior).expect("serialisable");
    atomic::write_bytes_atomic(out, json.as_bytes())?;
    if super::show_summaries() {
        println!("subject | offset RMS without prior (mm) | with, left out of training (mm)");
        for c in &prior.cross_validation {
            println!("{} | {:.2} | {:.2}", c.subject, c.without_mm, c.with_mm);
        }
        let n = prior.cross_validation.len() as f64;
        let mean = |f: fn(&crate::skin::shape_prior::CrossValidation) -> f64| {
            prior.cross_validation.iter().map(f).sum::<f64>() / n
        };
        println!(
            "mean | {:.2} | {:.2}   ({} modes, ridge {})",
            mean(|c| c.without_mm),
            mean(|c| c.with_mm),
            prior.modes.len(),
            prior.ridge
        );
    }
    log::info!("wrote {}", out.display());
    Ok(prior)
}
