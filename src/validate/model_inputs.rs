//! What `validate` reads before it measures: the subject, the reconstruction's files
//! (`link_model.json`, `report.json`, `skin.obj`) and the subject's optional references
//! (`truth.json`, `reference.ply`), each checked once here so that the measuring code works on
//! values that are known to be sound.

use super::link_accuracy::{compare, read_truth, LinkAccuracy, TruthFile};
use super::subject_validation::References;
use crate::error::{Error, Result};
use crate::geometry::TriMesh;
use crate::io::{obj, ply, Units};
use crate::mocap::subject::Subject;
use crate::skeleton::record::JointRecord;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The 3-D page of the error map, beside `report.html`.
pub const VIEW_FILE: &str = "view.html";

/// Largest ratio between the bounding-box diagonals of `reference.ply` and `skin.obj` that a
/// reference of the same hand can have (a scan cut at another place of the forearm differs by
/// tens of percent, a wrong unit by 10 to 1000 times).
pub const REFERENCE_SCALE_RATIO: f64 = 3.0;

/// Check that the reference surface (read as mm) is the size of the reconstructed skin: the
/// ratio of their bounding-box diagonals within 1/[`REFERENCE_SCALE_RATIO`] to
/// [`REFERENCE_SCALE_RATIO`], else an error naming `path` and the unit its numbers look like
/// (the one of m, cm, in, mm that brings the ratio nearest 1).
pub fn check_reference_scale(reference: &TriMesh, skin: &TriMesh, path: &Path) -> Result<()> {
    let (r, s) = (reference.diagonal(), skin.diagonal());
    if !(r > 0.0 && s > 0.0) {
        return Ok(());
    }
    let ratio = r / s;
    if (1.0 / REFERENCE_SCALE_RATIO..=REFERENCE_SCALE_RATIO).contains(&ratio) {
        return Ok(());
    }
    // The reference's numbers, read in a unit u, should measure the skin's diagonal.
    let likely = Units::likely(r, s);
    Err(Error::input(
        path,
        format!(
            "the surface is {r:.3} mm across (read as mm) where skin.obj is {s:.1} mm; its \
             numbers look like {likely}: convert it to mm"
        ),
    ))
}

/// Everything `validate` measures from, read from one subject folder and one model folder.
pub(crate) struct ModelInputs {
    pub subject: Subject,
    pub references: References,
    /// `link_model.json`.
    pub model_path: PathBuf,
    /// The model's joints (`link_model.json`).
    pub joints: BTreeMap<String, JointRecord>,
    /// `truth.json` and the model's joints compared with it, when the subject has a truth.
    pub truth: Option<(TruthFile, LinkAccuracy)>,
    /// The warnings `reconstruct` wrote into `link_model.json`.
    pub warnings: Vec<String>,
    /// The bootstrap SD of each link length (`link_model.json`, `link_lengths.*.sd_mm`).
    pub link_length_sd_mm: BTreeMap<String, f64>,
    /// `report.json`'s `timings_s`, when the folder has a `report.json`.
    pub reconstruct_timings_s: BTreeMap<String, f64>,
    /// `skin.obj` and its path.
    pub skin: TriMesh,
    pub skin_path: PathBuf,
    /// `reference.ply`, checked to be the skin's size, when the subject has one.
    pub reference: Option<TriMesh>,
}

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not JSON: {e}")))
}

impl ModelInputs {
    /// Read the subject in `subject_dir` and the reconstruction in `model`; refuse a `report`
    /// folder that holds another run's files (see [`crate::io::output_paths::check_output_dir`]).
    pub(crate) fn read(subject_dir: &Path, model: &Path, report: &Path) -> Result<ModelInputs> {
        let truth_path = subject_dir.join("truth.json");
        let reference_path = subject_dir.join("reference.ply");
        let references = References {
            reference_ply: reference_path.exists(),
            truth_json: truth_path.exists(),
        };
        let subject = Subject::load(subject_dir)?;
        let inputs = crate::io::output_paths::Inputs::files(
            [
                subject.toml_path(),
                truth_path.clone(),
                reference_path.clone(),
            ]
            .into_iter()
            .chain(subject.trials.values().map(|p| subject.dir.join(p))),
        )
        .with_model(model);
        crate::io::output_paths::check_output_dir(
            report,
            &[
                "metrics.json",
                "report.html",
                "report.md",
                "error-map.png",
                VIEW_FILE,
            ],
            "--report",
            &inputs,
        )?;
        let model_path = model.join("link_model.json");
        let joints = super::link_accuracy::read_joints(&model_path)?;
        let truth = if references.truth_json {
            let truth = read_truth(&truth_path)?;
            let link = compare(&joints, &truth.joints);
            Some((truth, link))
        } else {
            None
        };
        let model_json = read_json(&model_path)?;
        let warnings = model_json["warnings"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|w| w.as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default();
        let link_length_sd_mm = model_json
            .get("link_lengths")
            .and_then(|l| l.as_object())
            .map(|l| {
                l.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.get("sd_mm")?.as_f64()?)))
                    .collect()
            })
            .unwrap_or_default();
        let recon = model.join("report.json");
        let reconstruct_timings_s = if recon.exists() {
            read_json(&recon)?["timings_s"]
                .as_object()
                .map(|o| {
                    o.iter()
                        .filter_map(|(k, v)| Some((k.clone(), v.as_f64()?)))
                        .collect()
                })
                .unwrap_or_default()
        } else {
            BTreeMap::new()
        };
        let skin_path = model.join("skin.obj");
        let skin = obj::read_obj(&skin_path, Units::Millimetres)?;
        let reference = if references.reference_ply {
            let r = ply::read_ply(&reference_path, Units::Millimetres)?.mesh;
            check_reference_scale(&r, &skin, &reference_path)?;
            Some(r)
        } else {
            None
        };
        Ok(ModelInputs {
            subject,
            references,
            model_path,
            joints,
            truth,
            warnings,
            link_length_sd_mm,
            reconstruct_timings_s,
            skin,
            skin_path,
            reference,
        })
    }
}
