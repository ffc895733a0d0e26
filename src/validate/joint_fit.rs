//! The data of the seed paper's Figures 8 and 9 (section 5.1): for every joint, the child
//! link's marker trajectories expressed in the parent's reference pose, relative to the fitted
//! centre and in the joint's frame, and the distribution of each marker's distance to the
//! centre.
//!
//! `link_model.json` keeps the centres, frames and the radius statistics, not the trajectories,
//! so they are computed again here from the subject's trials with the link module's own public
//! steps: the marker sets of [`crate::link::estimate::marker_sets`] and the per-frame registration
//! of equation 1 ([`crate::link::registration::register_parent`]). Validation reads the
//! pipeline's inputs and outputs; the pipeline never calls it.

use crate::anatomy::{palm_markers, Finger, Joint};
use crate::error::{Error, Result};
use crate::geometry::{absolute_orientation, Point, Vec3};
use crate::link::estimate::marker_sets;
use crate::link::registration::register_parent;
use crate::mocap::subject::{Subject, TrialKind};
use crate::mocap::trajectories::Trajectories;
use crate::skeleton::record::JointRecord;
use rayon::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// One child marker of a joint.
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerTrack {
    /// Marker name (`I_PROX_1`, `PALM_2`, ...).
    pub name: String,
    /// Positions relative to the joint centre in the joint's frame (x, y, z of the joint's
    /// frame rows: for a 1-DOF joint x is the axis, y dorsal, z along the child link), mm; one
    /// per frame in which the parent was registered and the marker seen.
    pub points: Vec<[f64; 3]>,
    /// Mean distance to the centre, mm (Figure 9).
    pub radius_mean: f64,
    /// SD of that distance, mm (Figure 9).
    pub radius_sd: f64,
}

impl MarkerTrack {
    /// Distance of every sample to the centre, mm.
    pub fn radii(&self) -> Vec<f64> {
        self.points.iter().map(norm).collect()
    }
}

fn norm(p: &[f64; 3]) -> f64 {
    (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt()
}

/// Every child marker of one joint.
#[derive(Clone, Debug, PartialEq)]
pub struct JointFit {
    /// The joint.
    pub joint: Joint,
    /// The trial it was estimated from.
    pub trial: String,
    /// The centre's estimator (from the diagnostics; empty when not recorded).
    pub estimator: String,
    /// Range of motion from the diagnostics, degrees (NaN when not recorded).
    pub range_of_motion_deg: f64,
    /// Whether the centre used is the one from motion alone (1-DOF joints after section 3.6,
    /// whose final centre was slid along the axis onto the skin's cross-section).
    pub centre_from_motion: bool,
    /// The centre's uncertainty from the link model's diagnostics (`centre_sd_mm`, a bootstrap
    /// SD), mm; `None` when not recorded (older files).
    pub centre_sd_mm: Option<f64>,
    /// The child markers.
    pub markers: Vec<MarkerTrack>,
}

impl JointFit {
    /// The marker farthest from the centre: the one the seed paper's Figure 8 shows.
    pub fn farthest(&self) -> Option<&MarkerTrack> {
        self.markers
            .iter()
            .max_by(|a, b| a.radius_mean.total_cmp(&b.radius_mean))
    }
}

fn v3(a: [f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// The trial of each joint, in [`Joint::ALL`] order of trials: wrist, then the fingers.
fn trials_and_joints() -> Vec<(TrialKind, Vec<Joint>)> {
    std::iter::once((TrialKind::Wrist, vec![Joint::Wrist]))
        .chain(
            Finger::ALL
                .iter()
                .map(|&f| (TrialKind::Finger(f), f.joints().to_vec())),
        )
        .collect()
}

/// The joint fits of a subject read from its folder against the joints table of its
/// `link_model.json` (`model_path` names it in errors).
pub fn joint_fits(
    subject: &Subject,
    joints: &BTreeMap<String, JointRecord>,
    model_path: &Path,
) -> Result<Vec<JointFit>> {
    let kinds: Vec<TrialKind> = TrialKind::ALL.to_vec();
    let loaded: Vec<Result<(String, Trajectories)>> = kinds
        .par_iter()
        .map(|&k| Ok((k.key().to_string(), subject.load_trial(k)?)))
        .collect();
    let trials = loaded.into_iter().collect::<Result<BTreeMap<_, _>>>()?;
    joint_fits_from(subject.reference_frame, &trials, joints, model_path)
}

/// [`joint_fits`] from trials in memory keyed as in `[trials]` (`reference`, `wrist`, ...),
/// `rf` the reference frame of the calibration trials.
pub(crate) fn joint_fits_from(
    rf: usize,
    trials: &BTreeMap<String, Trajectories>,
    joints: &BTreeMap<String, JointRecord>,
    model_path: &Path,
) -> Result<Vec<JointFit>> {
    let get = |k: TrialKind| {
        trials
            .get(k.key())
            .ok_or_else(|| Error::invalid(format!("the '{}' trial is missing", k.key())))
    };
    let reference = get(TrialKind::Reference)?;
    // The global frame is the static trial's: each calibration trial's reference frame is
    // carried onto it through the four palm markers, as the link model does (section 3.4).
    let palm = palm_markers();
    let reference_palm: Vec<Point> = palm
        .iter()
        .map(|n| {
            reference
                .mean_position(n, 0..reference.n_frames())
                .ok_or_else(|| {
                    Error::input(&reference.source, format!("landmark '{n}' has no sample"))
                })
        })
        .collect::<Result<_>>()?;
    let per_trial: Vec<Result<Vec<JointFit>>> = trials_and_joints()
        .par_iter()
        .map(|(kind, js)| -> Result<Vec<JointFit>> {
            let traj = get(*kind)?;
            traj.require_at(&palm, rf)?;
            let src: Vec<Point> = palm
                .iter()
                .map(|n| traj.get(n, rf).expect("checked"))
                .collect();
            let to_global = absolute_orientation(&src, &reference_palm, None, false)
                .map_err(|e| Error::input(&traj.source, format!("palm markers: {e}")))?;
            let to_local = to_global.inverse();
            js.iter()
                .map(|&j| joint_fit(traj, kind.key(), j, rf, &to_local, joints, model_path))
                .collect()
        })
        .collect();
    let mut out = Vec::new();
    for r in per_trial {
        out.extend(r?);
    }
    out.sort_by_key(|f| f.joint.index());
    Ok(out)
}

fn joint_fit(
    traj: &Trajectories,
    trial: &str,
    j: Joint,
    rf: usize,
    to_local: &crate::geometry::Registration,
    joints: &BTreeMap<String, JointRecord>,
    model_path: &Path,
) -> Result<JointFit> {
    let rec = joints
        .get(j.name())
        .ok_or_else(|| Error::input(model_path, format!("joint {j} is missing from 'joints'")))?;
    let diag = rec.diagnostics.as_ref();
    // A 1-DOF centre after section 3.6 sits where the skin's cross-section put it, along the
    // axis; the trajectories were fitted about the centre from motion, kept as `motion`.
    let motion = diag
        .and_then(|d| d.get("alternatives"))
        .and_then(|a| a.get("motion"))
        .and_then(|m| serde_json::from_value::<[f64; 3]>(m.clone()).ok());
    let centre_global = motion.unwrap_or(rec.centre);
    let centre = to_local.apply(&Point::from(v3(centre_global)));
    let rows = rec.frame.map(|r| to_local.apply_vector(&v3(r)).normalize());
    let (parent, child) = marker_sets(j);
    let parent: Vec<&str> = parent.iter().map(String::as_str).collect();
    let reg = register_parent(traj, &parent, rf);
    let markers = child
        .iter()
        .map(|name| {
            let points: Vec<[f64; 3]> = reg
                .express(traj, name)
                .iter()
                .map(|p| {
                    let d = p - centre;
                    [rows[0].dot(&d), rows[1].dot(&d), rows[2].dot(&d)]
                })
                .collect();
            let r: Vec<f64> = points.iter().map(norm).collect();
            let n = r.len().max(1) as f64;
            let mean = r.iter().sum::<f64>() / n;
            let sd = (r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / n).sqrt();
            MarkerTrack {
                name: name.clone(),
                points,
                radius_mean: mean,
                radius_sd: sd,
            }
        })
        .collect();
    let text = |k: &str| {
        diag.and_then(|d| d.get(k))
            .and_then(|v| v.as_str())
            .unwrap_or("")
            .to_string()
    };
    Ok(JointFit {
        joint: j,
        trial: trial.to_string(),
        estimator: text("estimator"),
        range_of_motion_deg: diag
            .and_then(|d| d.get("range_of_motion_deg"))
            .and_then(|v| v.as_f64())
            .unwrap_or(f64::NAN),
        centre_from_motion: motion.is_some(),
        centre_sd_mm: diag
            .and_then(|d| d.get("centre_sd_mm"))
            .and_then(|v| v.as_f64()),
        markers,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::estimate::estimate_link_model_from;
    use crate::synth::{simulate, Preset, SynthOptions};

    /// Recomputed from the trials, the per-marker radius statistics are the ones the link
    /// model stored in its diagnostics (the same registration and centre, reached through
    /// `link_model.json`'s global frame and back), and a clean hinge's markers keep their
    /// distance to the centre.
    #[test]
    fn recomputed_trajectories_match_the_model_diagnostics() {
        let s = simulate(&SynthOptions {
            duration_s: Some(6.0),
            voxel_mm: 2.0,
            ..SynthOptions::new(61, Preset::Clean)
        })
        .unwrap();
        let m =
            estimate_link_model_from(s.subject.hand, s.subject.reference_frame, &s.trials).unwrap();
        let json: serde_json::Value = serde_json::from_str(&m.to_json()).unwrap();
        let table: BTreeMap<String, JointRecord> =
            serde_json::from_value(json["joints"].clone()).unwrap();
        let fits = joint_fits_from(
            s.subject.reference_frame,
            &s.trials,
            &table,
            Path::new("link_model.json"),
        )
        .unwrap();
        assert_eq!(fits.len(), 16);
        for (f, e) in fits.iter().zip(&m.joints) {
            assert_eq!(f.joint, e.joint);
            assert_eq!(f.markers.len(), e.diagnostics.marker_radius_mean.len());
            for (k, t) in f.markers.iter().enumerate() {
                assert!(
                    (t.radius_mean - e.diagnostics.marker_radius_mean[k]).abs() < 1e-6,
                    "{} {}: {} vs {}",
                    f.joint,
                    t.name,
                    t.radius_mean,
                    e.diagnostics.marker_radius_mean[k]
                );
                assert!((t.radius_sd - e.diagnostics.marker_radius_sd[k]).abs() < 1e-6);
                assert!(t.points.len() > 100);
            }
            // Clean data: rigid plates, exact centres; every marker of a 3-DOF joint stays on
            // its sphere.
            if f.joint.dof() == 3 {
                assert!(f.farthest().unwrap().radius_sd < 1e-6, "{}", f.joint);
            }
        }
    }
}
