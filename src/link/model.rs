//! The link structure model of one subject as data: every joint's centre, the axis of every
//! 1-DOF joint and its local frame in the global reference frame of the static reference trial,
//! the diagnostics of its estimation, and `link_model.json` (spec section 3) written from it.
//! [`super::estimate`] makes it from the trials; section 3.6 moves its hinges' centres onto the
//! skin ([`LinkModel::with_skin_centres`]).

use super::level_cues::{cue_weights, depth_weight};
use crate::anatomy::{Finger, Joint, Side};
use crate::error::Result;
use crate::geometry::{Point, Vec3};
use crate::skeleton::record::{joint_records, JointRecord};
use crate::skeleton::Skeleton;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// What the soft-tissue model found for a joint (in `diagnostics.sta` of `link_model.json`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct StaDiagnostics {
    /// Whether its centre was used (see [`choose`]).
    pub used: bool,
    /// The driver angles, `JOINT[k]` = the k-th principal angle coordinate of that joint.
    pub drivers: Vec<String>,
    /// Predicted SD of the centre (off the axis for a hinge), mm.
    pub centre_sd_mm: f64,
    /// RMS residual of the model and of the rigid SCoRE fit on the same frames, mm.
    pub rms_mm: f64,
    /// RMS residual of the rigid SCoRE fit on the same frames, mm.
    pub rigid_rms_mm: f64,
    /// Largest modelled slide of the centre per radian of a driver, in the parent's and the
    /// child's frame, mm/rad.
    pub max_slide_mm_per_rad: [f64; 2],
    /// Frames used.
    pub frames: usize,
}

/// One level cue of a hinge in `link_model.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LevelCueOffset {
    /// The cue's level minus the centre's, along the axis, mm.
    pub offset_mm: f64,
    /// Its weight in the centre's level.
    pub weight: f64,
}

/// A hinge's depth from the skin in `link_model.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DepthCueOffset {
    /// The skin's depth minus the centre's, along the joint frame's y (dorsal), mm.
    pub offset_mm: f64,
    /// Its weight in the centre's depth (the motion's is one minus it).
    pub weight: f64,
}

/// Diagnostics of one joint's estimate (the seed paper's Figures 8-9 and more).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointDiagnostics {
    /// The trial key the joint was estimated from.
    pub trial: String,
    /// Estimator of the centre: `score`, `bcls`, `sphere-ls` or `circle-on-axis`.
    pub estimator: String,
    /// Estimator of the axis (1-DOF): `sara` or `plane-normal`.
    pub axis_estimator: Option<String>,
    /// Frames in the trial.
    pub frames_total: usize,
    /// Frames used by the fit.
    pub frames_used: usize,
    /// Frames skipped for fewer than three visible parent markers.
    pub frames_skipped: usize,
    /// Frames dropped as registration outliers.
    pub frames_outliers: usize,
    /// Median residual of the parent registration, mm.
    pub registration_rms_mm: f64,
    /// Per child marker: mean distance to the centre, mm (Figure 9).
    pub marker_radius_mean: Vec<f64>,
    /// Per child marker: SD of that distance, mm (Figure 9).
    pub marker_radius_sd: Vec<f64>,
    /// RMS residual of the chosen fit, mm.
    pub fit_rms_mm: f64,
    /// How well the motion determines the estimate (ratio of principal spreads; 0 = not at all).
    pub condition: f64,
    /// Range of motion of the child relative to the parent, degrees.
    pub range_of_motion_deg: f64,
    /// Every estimator's centre (global frame), for comparison.
    pub alternatives: BTreeMap<String, [f64; 3]>,
    /// 1-DOF joints after the skin stage: how far section 3.6 moved the centre along the axis
    /// onto the skin's cross-section, mm (the centre before it is in `alternatives` as
    /// `motion`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub centre_shift_on_skin_mm: Option<f64>,
    /// Joints distal to a digit's first joint: how far the centre was moved by carrying it to
    /// the palm through the proximal links' held reference poses rather than their poses at the
    /// reference frame alone ([`held_reference_pose`]), mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub chain_shift_mm: Option<f64>,
    /// The soft-tissue artefact model's fit, when it could be made.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub sta: Option<StaDiagnostics>,
    /// The centre's uncertainty: the RMS distance of its block-bootstrap replicates from their
    /// mean (frames resampled in blocks of [`BOOTSTRAP_BLOCK_S`], [`LinkOptions::bootstrap`]
    /// draws), with a 1-DOF centre's level along its axis drawn from that level's standard
    /// error, mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub centre_sd_mm: Option<f64>,
    /// 1-DOF: the standard error of the centre's level along its axis from the spread of the
    /// level cues ([`LevelCue`]), mm.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub level_sd_mm: Option<f64>,
    /// 1-DOF: the level cues ([`LevelCue`]; after the skin stage also `skin-section`), each
    /// cue's offset from the centre along the axis and its weight in the centre's level
    /// ([`cue_weights`]).
    #[serde(skip_serializing_if = "BTreeMap::is_empty")]
    pub level_cues: BTreeMap<String, LevelCueOffset>,
    /// 1-DOF joints whose thickness a caliper gives, after the skin stage: the skin's depth
    /// of the centre and its weight ([`depth_weight`]).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub depth_cue: Option<DepthCueOffset>,
    /// Warnings about this joint.
    pub warnings: Vec<String>,
}

/// One joint of the link model.
#[derive(Clone, Debug, PartialEq)]
pub struct JointEstimate {
    /// The joint.
    pub joint: Joint,
    /// Centre, mm, global reference frame.
    pub centre: Point,
    /// Unit axis of a 1-DOF joint, oriented so positive rotation flexes the child palmar.
    pub axis: Option<Vec3>,
    /// Diagnostics.
    pub diagnostics: JointDiagnostics,
}

/// The link structure model of a subject.
#[derive(Clone, Debug)]
pub struct LinkModel {
    /// Which hand.
    pub side: Side,
    /// Estimates, indexed by [`Joint::index`].
    pub joints: Vec<JointEstimate>,
    /// The skeleton (centres, frames, fingertips) in the global reference frame.
    pub skeleton: Skeleton,
    /// Every warning, each naming the trial and the joint or link.
    pub warnings: Vec<String>,
    /// Per link (`I_MCP-I_PIP`: MCP-PIP, PIP-DIP; thumb CMC-MCP, MCP-IP), the bootstrap SD of
    /// its length, mm (empty without a bootstrap, [`LinkOptions::bootstrap`]).
    pub length_sd_mm: BTreeMap<String, f64>,
}

/// The `link_model.json` document (spec section 3; `hand`, `warnings` and `link_lengths` are
/// extensions, optional for readers).
#[derive(Serialize)]
struct LinkModelFile<'a> {
    units: &'a str,
    frame: &'a str,
    hand: Side,
    joints: BTreeMap<String, JointRecord>,
    link_lengths: BTreeMap<String, LinkLength>,
    warnings: &'a [String],
}

/// A link's length between its joints' centres and its bootstrap SD, in `link_model.json`.
#[derive(Clone, Debug, PartialEq, Serialize, serde::Deserialize)]
pub(crate) struct LinkLength {
    /// Distance between the centres, mm.
    pub length_mm: f64,
    /// Bootstrap SD of that distance, mm.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sd_mm: Option<f64>,
}

impl LinkModel {
    /// The JSON text of `link_model.json`.
    pub fn to_json(&self) -> String {
        let mut joints = joint_records(&self.skeleton);
        for e in &self.joints {
            if let Some(r) = joints.get_mut(e.joint.name()) {
                r.diagnostics = Some(serde_json::to_value(&e.diagnostics).expect("serialisable"));
            }
        }
        let mut link_lengths = BTreeMap::new();
        for f in Finger::ALL {
            let js = f.joints();
            for k in 0..2 {
                let (a, b) = (js[k], js[k + 1]);
                let name = format!("{}-{}", a.name(), b.name());
                let length_mm = (self.skeleton.centre(a) - self.skeleton.centre(b)).norm();
                let sd_mm = self.length_sd_mm.get(&name).copied();
                link_lengths.insert(name, LinkLength { length_mm, sd_mm });
            }
        }
        serde_json::to_string_pretty(&LinkModelFile {
            units: "mm",
            frame: "reference",
            hand: self.side,
            joints,
            link_lengths,
            warnings: &self.warnings,
        })
        .expect("serialisable")
    }

    /// Section 3.6 of the seed paper applied, as one more level cue: every 1-DOF centre that
    /// `skeleton` (from [`crate::skin::section_centre::centre_on_cross_section`]) moved along
    /// its axis onto the skin's cross-section takes the weighted mean level of the motion's cues
    /// ([`LevelCue`]) and that cross-section (`skin-section`), the weights from all those
    /// hinges by [`cue_weights`]: the landmark, the plates and the fitted skin are each off the
    /// joint's mid-level by about a millimetre for independent reasons (palpation, plate
    /// placement, the skin fit), so their weighted mean is closer than any of them (README,
    /// "Link model"). The skin stage's shift is recorded in the diagnostics
    /// (`centre_shift_on_skin_mm`) and the centre from motion alone kept among the alternatives
    /// as `motion`.
    ///
    /// `depths` (from [`crate::skin::section_centre::depth_offsets`], by joint name) are the
    /// skin's depths of the hinges whose thickness a caliper fixed, relative to `skeleton`'s
    /// centres along their frames' y: each such centre moves that way by the skin's weight of
    /// its depth, one weight per hand from all of them ([`depth_weight`]), so that a plate's
    /// slide along its bone, which the motion reads as a deeper or shallower joint, is held by
    /// the finger's thickness (diagnostics `depth_cue`). Frames keep their axes, as along the
    /// axis. The skeleton becomes `skeleton` with these centres.
    pub fn with_skin_centres(
        mut self,
        skeleton: &Skeleton,
        shifts: &BTreeMap<String, f64>,
        depths: &BTreeMap<String, f64>,
    ) -> Self {
        let mut skeleton = skeleton.clone();
        let moved: Vec<usize> = (0..self.joints.len())
            .filter(|&k| {
                let e = &self.joints[k];
                e.axis.is_some() && shifts.contains_key(e.joint.name())
            })
            .collect();
        // Per moved hinge: its cues' offsets from the centre along the axis, the section's last.
        let offsets: Vec<Vec<f64>> = moved
            .iter()
            .map(|&k| {
                let e = &self.joints[k];
                let a = e.axis.expect("a hinge");
                let mut t: Vec<f64> = e
                    .diagnostics
                    .level_cues
                    .values()
                    .map(|c| c.offset_mm)
                    .collect();
                t.push((skeleton.centre(e.joint) - e.centre).dot(&a));
                t
            })
            .collect();
        let weights = cue_weights(&offsets);
        for (&k, t) in moved.iter().zip(&offsets) {
            let e = &mut self.joints[k];
            let a = e.axis.expect("a hinge");
            let c = e.centre;
            e.diagnostics
                .alternatives
                .insert("motion".into(), [c.x, c.y, c.z]);
            e.diagnostics.centre_shift_on_skin_mm = Some(shifts[e.joint.name()]);
            // Without weights (too few hinges), the section alone, as the seed paper.
            let (w, var) = match &weights {
                Some((w, v)) if w.len() == t.len() => (w.clone(), v.clone()),
                _ => {
                    let mut w = vec![0.0; t.len()];
                    w[t.len() - 1] = 1.0;
                    (w, Vec::new())
                }
            };
            let shift: f64 = t.iter().zip(&w).map(|(t, w)| t * w).sum();
            e.centre = c + a * shift;
            skeleton.joints[e.joint.index()].centre = e.centre;
            let names: Vec<String> = e
                .diagnostics
                .level_cues
                .keys()
                .cloned()
                .chain(std::iter::once("skin-section".to_string()))
                .collect();
            e.diagnostics.level_cues = names
                .into_iter()
                .zip(t.iter().zip(&w))
                .map(|(name, (t, w))| {
                    (
                        name,
                        LevelCueOffset {
                            offset_mm: t - shift,
                            weight: *w,
                        },
                    )
                })
                .collect();
            if !var.is_empty() {
                let sd = w.iter().zip(&var).map(|(w, v)| w * w * v).sum::<f64>();
                e.diagnostics.level_sd_mm = Some(sd.sqrt());
            }
        }
        // The depth: one weight for the hand's hinges that have both depths.
        let deep: Vec<(usize, &'static str, f64)> = (0..self.joints.len())
            .filter_map(|k| {
                let e = &self.joints[k];
                let d = *depths.get(e.joint.name())?;
                (e.axis.is_some() && d.is_finite()).then(|| (k, e.joint.kind(), d))
            })
            .collect();
        let cues: Vec<(&str, f64)> = deep.iter().map(|&(_, kind, d)| (kind, d)).collect();
        if let Some(w) = depth_weight(&cues) {
            for &(k, _, d) in &deep {
                let e = &mut self.joints[k];
                let y = skeleton.joint(e.joint).y();
                e.centre += y * (w.skin * d);
                skeleton.joints[e.joint.index()].centre = e.centre;
                e.diagnostics.depth_cue = Some(DepthCueOffset {
                    offset_mm: d * (1.0 - w.skin),
                    weight: w.skin,
                });
            }
        }
        self.skeleton = skeleton;
        self
    }

    /// Write `link_model.json` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::atomic::write_bytes_atomic(path, self.to_json().as_bytes())
    }
}
