//! `ergohand shape-prior`: train a skin shape prior from subjects whose true surface is known
//! (a CT or a simulated reference), each reconstructed without a prior.

use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use crate::io::{atomic, obj, ply, Units};
use crate::mocap::subject::Subject;
use crate::skin::shape_prior::{
    fill_and_smooth, normal_offsets, subject_features, train_shape_prior, JointLine, PriorSample,
    ShapePrior, SMOOTHING_PASSES,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The landmark markers' mean positions over the static reference trial (the skin fit's
/// targets).
fn static_markers(subject: &Subject) -> Result<BTreeMap<String, Point>> {
    let t = subject.load_trial(crate::mocap::subject::TrialKind::Reference)?;
    Ok(crate::anatomy::landmark_names()
        .into_iter()
        .filter_map(|n| Some((n.to_string(), t.mean_position(n, 0..t.n_frames())?)))
        .collect())
}

/// Each joint's centre and (hinges) axis from a `link_model.json`, in the reference trial's
/// frame.
fn link_model_joints(path: &Path) -> Result<BTreeMap<String, JointLine>> {
    let v: serde_json::Value = serde_json::from_slice(&atomic::read_bytes(path)?)
        .map_err(|e| Error::input(path, format!("not JSON: {e}")))?;
    let vec3 = |x: &serde_json::Value| -> Option<Vec3> {
        let a = x.as_array()?;
        if a.len() != 3 {
            return None;
        }
        Some(Vec3::new(a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?))
    };
    let joints = v["joints"]
        .as_object()
        .ok_or_else(|| Error::input(path, "joints: missing"))?;
    joints
        .iter()
        .map(|(name, j)| {
            let centre = vec3(&j["centre"]).ok_or_else(|| {
                Error::input(path, format!("joints.{name}.centre: not 3 numbers"))
            })?;
            let axis = if j["dof"].as_u64() == Some(1) {
                vec3(&j["axis"])
            } else {
                None
            };
            Ok((
                name.clone(),
                JointLine {
                    centre: Point::from(centre),
                    axis,
                },
            ))
        })
        .collect()
}

/// The training sample of one subject: `DIR/subject.toml` (its dimensions),
/// `DIR/reference.ply` (its surface) and `DIR/MODEL/skin.obj` (its skin fitted without a
/// prior, which `DIR/MODEL/report.json` must say).
pub fn prior_sample(dir: &Path, model: &str) -> Result<PriorSample> {
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
    let skin = obj::read_obj(&dir.join(model).join("skin.obj"), Units::Millimetres)?;
    let reference = ply::read_ply(&dir.join("reference.ply"), Units::Millimetres)?.mesh;
    let raw = normal_offsets(&skin, &reference);
    let rings = skin.topology().vertex_rings;
    // The forearm is scored nowhere: a reference is cut across it, and past the cut a ray meets
    // the reference's cap, not the arm's skin.
    let template = crate::template::load_template(subject.hand)?;
    if template.mesh.n_vertices() != skin.n_vertices() {
        return Err(Error::input(
            dir.join(model).join("skin.obj"),
            format!(
                "{} vertices: not a skin of the generic template ({})",
                skin.n_vertices(),
                template.mesh.n_vertices()
            ),
        ));
    }
    let owners = crate::template::dominant_links(&template.weights);
    let arm = crate::anatomy::Link::Arm.index();
    let features = subject_features(
        &subject.dimensions,
        &static_markers(&subject)?,
        &link_model_joints(&dir.join(model).join("link_model.json"))?,
        subject.marker_offset_mm,
    );
    Ok(PriorSample {
        name: subject.name.clone(),
        features,
        measured: raw
            .iter()
            .zip(&owners)
            .map(|(r, &o)| r.is_some() && o != arm)
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
    let pb = super::progress(subjects.len() as u64, "subjects");
    let mut samples = Vec::new();
    for dir in subjects {
        samples.push(prior_sample(dir, model)?);
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
