//! The link structure model of one subject (seed paper section 3.4): every joint's centre, the
//! axis of every 1-DOF joint and an intuitive local frame, in the global reference frame of the
//! static reference trial, with diagnostics (`link_model.json`, spec section 3).
//!
//! Per joint, from the trial of its digit (the wrist trial for WRIST):
//! 1. the parent's markers are registered onto the trial's reference frame in every frame
//!    ([`super::registration`], equation 1): the four palm markers for CMC and MCP joints, the
//!    parent plate otherwise, the forearm markers for the wrist;
//! 2. the child markers' trajectories in that frame give the centre and, for 1-DOF joints, the
//!    axis, by the estimators of [`super::sphere_fit`], [`super::axis_fit`] and
//!    [`super::functional`], chosen by the rule of [`choose`];
//! 3. the trial's reference frame is carried to the global reference frame through the four palm
//!    markers (Horn), and the frames are built (module [`crate::skeleton`] conventions).

use super::axis_fit::common_plane_normal;
use super::functional::{sara_axis, score_centre};
use super::registration::{register_parent, ParentRegistration};
use super::sphere_fit::{
    circle_centre_on_axis, common_sphere_centre, common_sphere_centre_bias_compensated,
};
use crate::anatomy::{arm_markers, palm_markers, Finger, Joint, Link, Side};
use crate::error::{Error, Result};
use crate::geometry::{absolute_orientation, Point, Registration, Vec3};
use crate::mocap::subject::{Subject, TrialKind};
use crate::mocap::trajectories::Trajectories;
use crate::skeleton::record::{joint_records, JointRecord};
use crate::skeleton::{frame_from_axis, frame_from_long_axis, JointFrame, Skeleton};
use nalgebra::{Isometry3, Rotation3, UnitQuaternion};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::Path;

/// A 3-DOF joint whose child rotated less than this (degrees) is flagged: the centre is poorly
/// determined. The seed paper's calibration motions reach about 80° at the MCPs, 55° at the
/// thumb CMC and 60° at the wrist; a joint that moved less than about half of that gives
/// centres whose error grows quickly (Ehrig et al. 2006; `small-rom` in the suite).
pub const MIN_ROM_3DOF_DEG: f64 = 45.0;
/// A 1-DOF joint that flexed less than this (degrees) is flagged (the protocol reaches about
/// 100° at PIP, 70° at DIP and IP, 50° at the thumb MCP).
pub const MIN_ROM_1DOF_DEG: f64 = 45.0;
/// Below this ratio of the smallest to the largest principal spread, the child's motion is too
/// planar for a sphere fit (a hinge-like motion at a 3-DOF joint): flagged.
pub const MIN_SPHERE_CONDITION: f64 = 0.02;
/// A joint whose child moved less than this (degrees) relative to its parent is refused: the
/// trial is static for that joint and no centre can be estimated.
pub const MIN_ROM_HARD_DEG: f64 = 5.0;
/// Trials shorter than this are refused (seconds).
pub const MIN_TRIAL_S: f64 = 1.0;

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
    /// Every warning, each naming the trial and the joint.
    pub warnings: Vec<String>,
}

/// A joint's estimate in its trial's reference frame, before the global transform.
struct LocalEstimate {
    centre: Point,
    axis: Option<Vec3>,
    alternatives: Vec<(String, Point)>,
    diagnostics: JointDiagnostics,
}

/// The parent and child marker sets of a joint.
pub fn marker_sets(j: Joint) -> (Vec<String>, Vec<String>) {
    let strings = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
    match j {
        Joint::Wrist => (strings(&arm_markers()), strings(&palm_markers())),
        j => {
            let parent = match j.parent_link() {
                Link::Palm => strings(&palm_markers()),
                l => l.plate_markers().to_vec(),
            };
            (parent, j.child_link().plate_markers().to_vec())
        }
    }
}

/// Child poses in the parent's reference pose: for every frame where all child markers are
/// present, the rigid map from their reference-frame positions to that frame (Horn).
fn child_poses(expressed: &[Vec<Option<Point>>], reference: &[Point]) -> Vec<Isometry3<f64>> {
    expressed
        .iter()
        .filter_map(|row| {
            let pts: Option<Vec<Point>> = row.iter().copied().collect();
            let pts = pts?;
            absolute_orientation(reference, &pts, None, false)
                .ok()
                .map(|r| r.isometry())
        })
        .collect()
}

/// The rule that picks the estimator, in order of preference (the first that succeeds), as
/// measured on the `validation/` phantoms (README, "Link model"): for a 3-DOF joint SCoRE
/// (Ehrig 2006), which uses the child's whole rigid motion, then the bias-compensated sphere fit
/// (Halvorsen 2003), then the plain one (Gamage & Lasenby 2002); for a 1-DOF joint SARA's axis
/// and axis line (Ehrig 2007), then the common plane normal and the common circle centre on it
/// (Gamage & Lasenby 2002). A 1-DOF centre's position along its axis is not determined by any
/// motion: it is taken level with the joint's dorsal landmark, and section 3.6 later moves it
/// onto the skin's cross-section.
pub fn choose(dof: usize) -> (&'static [&'static str], Option<&'static [&'static str]>) {
    if dof == 3 {
        (&["score", "bcls", "sphere-ls"], None)
    } else {
        (&["sara", "circle-on-axis"], Some(&["sara", "plane-normal"]))
    }
}

fn mean(points: &[Point]) -> Option<Point> {
    if points.is_empty() {
        return None;
    }
    Some(Point::from(
        points.iter().map(|p| p.coords).sum::<Vec3>() / points.len() as f64,
    ))
}

/// Estimate joint `j` from `traj` (whose key is `trial`) in that trial's reference frame.
/// `level` is a point whose projection on a 1-DOF joint's axis fixes the centre along the axis,
/// which no motion determines: the joint's dorsal landmark, in the trial's reference frame.
fn estimate_local(
    traj: &Trajectories,
    trial: &str,
    j: Joint,
    rf: usize,
    level: Option<Point>,
) -> Result<LocalEstimate> {
    let fail = |msg: String| Error::input(&traj.source, format!("joint {j}: {msg}"));
    let (parent, child) = marker_sets(j);
    let parent_refs: Vec<&str> = parent.iter().map(String::as_str).collect();
    let child_refs: Vec<&str> = child.iter().map(String::as_str).collect();
    let all: Vec<&str> = parent_refs.iter().chain(&child_refs).copied().collect();
    traj.require_at(&all, rf)?;
    if traj.duration_s() < MIN_TRIAL_S {
        return Err(fail(format!(
            "the trial lasts {:.2} s, shorter than {MIN_TRIAL_S} s: record the calibration motion",
            traj.duration_s()
        )));
    }
    let reg: ParentRegistration = register_parent(traj, &parent_refs, rf);
    let tracks: Vec<Vec<Point>> = child_refs.iter().map(|n| reg.express(traj, n)).collect();
    let track_refs: Vec<&[Point]> = tracks.iter().map(Vec::as_slice).collect();
    let expressed = reg.express_frames(traj, &child_refs);
    let reference: Vec<Point> = child_refs
        .iter()
        .map(|n| traj.get(n, rf).expect("checked by require_at"))
        .collect();
    // The reference frame's own registration is the identity (up to round-off); its child
    // positions are the child's local frame.
    let poses = child_poses(&expressed, &reference);
    if poses.len() < 10 {
        return Err(fail(format!(
            "only {} frames have every parent and child marker; the trial cannot determine the joint",
            poses.len()
        )));
    }
    let identity = vec![Isometry3::identity(); poses.len()];

    let mut alternatives: Vec<(String, Point)> = Vec::new();
    let mut warnings = Vec::new();
    let (centres_rule, axis_rule) = choose(j.dof());
    let mut axis = None;
    let mut axis_estimator = None;
    let mut condition;
    let mut fit_rms;
    let centre;
    let estimator;
    let rom;

    if j.dof() == 3 {
        let score = score_centre(&identity, &poses);
        let bcls = common_sphere_centre_bias_compensated(&track_refs, None);
        let ls = common_sphere_centre(&track_refs);
        if let Ok(s) = &score {
            alternatives.push(("score".into(), s.parent_local));
        }
        if let Ok(s) = &bcls {
            alternatives.push(("bcls".into(), s.centre));
        }
        if let Ok(s) = &ls {
            alternatives.push(("sphere-ls".into(), s.centre));
        }
        let picked = centres_rule
            .iter()
            .find_map(|name| alternatives.iter().find(|(n, _)| n == name))
            .cloned()
            .ok_or_else(|| {
                fail(format!(
                    "no estimator could determine the centre ({}); is the trial static?",
                    ls.as_ref().err().map(|e| e.to_string()).unwrap_or_default()
                ))
            })?;
        estimator = picked.0;
        centre = picked.1;
        condition = ls.as_ref().map(|s| s.condition).unwrap_or(0.0);
        fit_rms = match (estimator.as_str(), &score, &bcls, &ls) {
            ("score", Ok(s), _, _) => s.rms,
            ("bcls", _, Ok(s), _) => s.rms,
            (_, _, _, Ok(s)) => s.rms,
            _ => f64::NAN,
        };
        rom = poses
            .iter()
            .map(|p| p.rotation.angle().to_degrees())
            .fold(0.0, f64::max);
        if condition < MIN_SPHERE_CONDITION {
            warnings.push(format!(
                "{trial} trial, joint {j}: the motion is nearly planar (condition {condition:.3}); the centre is poorly determined across that plane"
            ));
        }
        if rom < MIN_ROM_3DOF_DEG {
            warnings.push(format!(
                "{trial} trial, joint {j}: range of motion {rom:.0}° is below {MIN_ROM_3DOF_DEG}°; the centre is unreliable — repeat the circumduction with larger motion"
            ));
        }
    } else {
        let sara = sara_axis(&identity, &poses);
        let plane = common_plane_normal(&track_refs);
        let rule = axis_rule.expect("1-DOF joints have an axis rule");
        let mut axes: Vec<(&str, Vec3, f64, f64)> = Vec::new();
        if let Ok(s) = &sara {
            axes.push(("sara", s.axis_parent_local, s.rms, s.condition));
        }
        if let Ok(p) = &plane {
            axes.push(("plane-normal", p.axis, p.plane_rms, p.condition));
        }
        let (name, a, _, cond) = rule
            .iter()
            .find_map(|name| axes.iter().find(|x| x.0 == *name))
            .copied()
            .ok_or_else(|| {
                fail(format!(
                    "no estimator could determine the axis ({}); is the trial static?",
                    plane
                        .as_ref()
                        .err()
                        .map(|e| e.to_string())
                        .unwrap_or_default()
                ))
            })?;
        axis_estimator = Some(name.to_string());
        condition = cond;
        // Along the axis: the level of the joint's dorsal landmark, which a lab puts over the
        // middle of the joint; without it, the level of the plates (on the dorsal midline).
        let near = level.unwrap_or_else(|| {
            let parent_ref: Vec<Point> = parent_refs
                .iter()
                .map(|n| traj.get(n, rf).expect("checked by require_at"))
                .collect();
            mean(&[
                mean(&parent_ref).expect("non-empty"),
                mean(&reference).expect("non-empty"),
            ])
            .expect("non-empty")
        });
        let circle = circle_centre_on_axis(&track_refs, &a, &near)
            .map_err(|e| fail(format!("circle centre: {e}")))?;
        alternatives.push(("circle-on-axis".into(), circle.centre));
        if let Ok(s) = &sara {
            // The point of SARA's axis line level with `near`.
            let p = s.point_parent_local + a * (near - s.point_parent_local).dot(&a);
            alternatives.push(("sara".into(), p));
        }
        if let Ok(s) = common_sphere_centre(&track_refs) {
            alternatives.push(("sphere-ls".into(), s.centre));
        }
        let picked = centres_rule
            .iter()
            .find_map(|name| alternatives.iter().find(|(n, _)| n == name))
            .cloned()
            .expect("the circle centre is always there");
        estimator = picked.0;
        centre = picked.1;
        fit_rms = match (estimator.as_str(), &sara) {
            ("sara", Ok(s)) => s.rms,
            _ => circle.rms,
        };
        // Signed flexion angle of each pose about the axis; range = max - min.
        let angles: Vec<f64> = poses
            .iter()
            .map(|p| {
                let q: UnitQuaternion<f64> = p.rotation;
                2.0 * q.imag().dot(&a).atan2(q.w)
            })
            .collect();
        let (lo, hi) = angles
            .iter()
            .fold((f64::MAX, f64::MIN), |(lo, hi), x| (lo.min(*x), hi.max(*x)));
        rom = (hi - lo).to_degrees();
        axis = Some(a);
        if rom < MIN_ROM_1DOF_DEG {
            warnings.push(format!(
                "{trial} trial, joint {j}: range of motion {rom:.0}° is below {MIN_ROM_1DOF_DEG}°; the axis is unreliable — repeat the flexion with larger motion"
            ));
        }
        if let Ok(p) = &plane {
            fit_rms = fit_rms.max(p.plane_rms);
        }
    }
    if rom < MIN_ROM_HARD_DEG {
        return Err(fail(format!(
            "the child link moved only {rom:.1}° relative to its parent: the trial is static for this joint; record the calibration motion"
        )));
    }
    if reg.used() * 2 < traj.n_frames() {
        warnings.push(format!(
            "{trial} trial, joint {j}: only {} of {} frames could be registered",
            reg.used(),
            traj.n_frames()
        ));
    }
    if !condition.is_finite() {
        condition = 0.0;
    }
    let (rmean, rsd): (Vec<f64>, Vec<f64>) = tracks
        .iter()
        .map(|t| {
            let d: Vec<f64> = t.iter().map(|p| (p - centre).norm()).collect();
            let n = d.len().max(1) as f64;
            let m = d.iter().sum::<f64>() / n;
            let sd = (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt();
            (m, sd)
        })
        .unzip();
    Ok(LocalEstimate {
        centre,
        axis,
        alternatives,
        diagnostics: JointDiagnostics {
            trial: trial.to_string(),
            estimator,
            axis_estimator,
            frames_total: traj.n_frames(),
            frames_used: poses.len(),
            frames_skipped: reg.skipped,
            frames_outliers: reg.outliers,
            registration_rms_mm: reg.median_rms_mm,
            marker_radius_mean: rmean,
            marker_radius_sd: rsd,
            fit_rms_mm: fit_rms,
            condition,
            range_of_motion_deg: rom,
            alternatives: BTreeMap::new(),
            centre_shift_on_skin_mm: None,
            warnings: warnings.clone(),
        },
    })
}

/// The transform from a trial's reference frame to the global reference frame (the static
/// trial), through the four palm markers (section 3.4).
fn to_global(traj: &Trajectories, rf: usize, reference_palm: &[Point]) -> Result<Registration> {
    let names = palm_markers();
    traj.require_at(&names, rf)?;
    let src: Vec<Point> = names
        .iter()
        .map(|n| traj.get(n, rf).expect("checked"))
        .collect();
    absolute_orientation(&src, reference_palm, None, false).map_err(|e| {
        Error::input(
            &traj.source,
            format!("palm markers at the reference frame: {e}"),
        )
    })
}

/// Reconstruct the link model of a subject from its trials.
pub fn estimate_link_model(subject: &Subject) -> Result<LinkModel> {
    let mut trials = BTreeMap::new();
    for kind in TrialKind::ALL {
        trials.insert(kind.key().to_string(), subject.load_trial(kind)?);
    }
    estimate_link_model_from(subject.hand, subject.reference_frame, &trials)
}

/// [`estimate_link_model`] from trials already in memory, keyed as in `[trials]` of
/// `subject.toml` (`reference`, `wrist`, `thumb`, ...), `rf` the reference frame.
pub fn estimate_link_model_from(
    hand: Side,
    rf: usize,
    trials: &BTreeMap<String, Trajectories>,
) -> Result<LinkModel> {
    let get = |kind: TrialKind| -> Result<&Trajectories> {
        trials
            .get(kind.key())
            .ok_or_else(|| Error::invalid(format!("the '{}' trial is missing", kind.key())))
    };
    let reference = get(TrialKind::Reference)?;
    let landmark = |name: &str| -> Result<Point> {
        reference.require(&[name])?;
        reference
            .mean_position(name, 0..reference.n_frames())
            .ok_or_else(|| {
                Error::input(
                    &reference.source,
                    format!("landmark '{name}' has no valid sample"),
                )
            })
    };
    let reference_palm: Vec<Point> = palm_markers()
        .iter()
        .map(|n| landmark(n))
        .collect::<Result<_>>()?;
    let mut locals: Vec<Option<(LocalEstimate, Registration, Vec<Point>)>> =
        (0..Joint::ALL.len()).map(|_| None).collect();
    let trials: Vec<(TrialKind, Vec<Joint>)> =
        std::iter::once((TrialKind::Wrist, vec![Joint::Wrist]))
            .chain(
                Finger::ALL
                    .iter()
                    .map(|&f| (TrialKind::Finger(f), f.joints().to_vec())),
            )
            .collect();
    // Trials are independent: estimate them in parallel (results are collected in trial
    // order, so the model does not depend on the thread count; the first error in that order
    // is reported).
    use rayon::prelude::*;
    type Estimated = Vec<(Joint, LocalEstimate, Registration, Vec<Point>)>;
    let per_trial: Vec<Result<Estimated>> = trials
        .par_iter()
        .map(|(kind, joints)| -> Result<Estimated> {
            let traj = get(*kind)?;
            let g = to_global(traj, rf, &reference_palm)?;
            let mut out = Vec::new();
            for &j in joints {
                let level = if j.dof() == 1 {
                    Some(g.inverse().apply(&landmark(j.name())?))
                } else {
                    None
                };
                let est = estimate_local(traj, kind.key(), j, rf, level)?;
                // The child plate's reference positions, for the dorsal direction of the frames.
                let (_, child) = marker_sets(j);
                let plate: Vec<Point> = child
                    .iter()
                    .filter_map(|n| traj.get(n, rf))
                    .map(|p| g.apply(&p))
                    .collect();
                out.push((j, est, g, plate));
            }
            Ok(out)
        })
        .collect();
    for r in per_trial {
        for (j, est, g, plate) in r? {
            locals[j.index()] = Some((est, g, plate));
        }
    }

    let mut joints = Vec::with_capacity(Joint::ALL.len());
    let mut warnings = Vec::new();
    let mut plates = Vec::new();
    for (j, l) in Joint::ALL.iter().zip(locals) {
        let (est, g, plate) = l.expect("every joint belongs to a trial");
        let mut d = est.diagnostics;
        d.alternatives = est
            .alternatives
            .iter()
            .map(|(n, p)| {
                let q = g.apply(p);
                (n.clone(), [q.x, q.y, q.z])
            })
            .collect();
        warnings.extend(d.warnings.iter().cloned());
        joints.push(JointEstimate {
            joint: *j,
            centre: g.apply(&est.centre),
            axis: est.axis.map(|a| g.apply_vector(&a).normalize()),
            diagnostics: d,
        });
        plates.push(plate);
    }

    // Fingertips: the nail landmarks stand in for the ends of the distal links.
    let mut tips = [Point::origin(); 5];
    for f in Finger::ALL {
        tips[f as usize] = landmark(&format!("{}_NAIL", f.letter()))?;
    }
    let skeleton = build_skeleton(hand, &joints, tips, &reference_palm, &plates)
        .map_err(|e| e.in_file(&reference.source))?;
    // Orient each 1-DOF axis as its frame's x (positive flexion palmar).
    for (e, jf) in joints.iter_mut().zip(&skeleton.joints) {
        if e.axis.is_some() {
            e.axis = Some(jf.x());
        }
    }
    Ok(LinkModel {
        side: hand,
        joints,
        skeleton,
        warnings,
    })
}

/// Frames per the conventions of [`crate::skeleton`]: z toward the next joint (or the nail),
/// y dorsal (the palm's dorsal normal for the wrist and finger MCPs; toward the child plate
/// otherwise: plates sit on the dorsal side), x = y × z; a 1-DOF joint's x is its fitted axis,
/// its sign chosen to agree with y × z.
fn build_skeleton(
    side: Side,
    joints: &[JointEstimate],
    tips: [Point; 5],
    palm: &[Point],
    plates: &[Vec<Point>],
) -> Result<Skeleton> {
    let mut sk = Skeleton {
        side,
        joints: joints
            .iter()
            .map(|e| JointFrame {
                centre: e.centre,
                frame: Rotation3::identity(),
            })
            .collect(),
        tips,
    };
    // The palm's dorsal normal: the normal of the palm markers' plane, on their side of the
    // MCP joint centres (the markers sit on the back of the hand).
    let pc = mean(palm).expect("four palm markers");
    let cov = palm
        .iter()
        .map(|p| (p - pc) * (p - pc).transpose())
        .sum::<nalgebra::Matrix3<f64>>();
    let eig = cov.symmetric_eigen();
    let mut n: Vec3 = eig.eigenvectors.column(eig.eigenvalues.imin()).into();
    let mcps =
        [Joint::IMcp, Joint::MMcp, Joint::RMcp, Joint::LMcp].map(|j| joints[j.index()].centre);
    let mc = mean(&mcps).expect("four MCPs");
    if (pc - mc).dot(&n) < 0.0 {
        n = -n;
    }
    for e in joints {
        let j = e.joint;
        let c = e.centre;
        let z = sk.distal_end(j) - c;
        let dorsal = match (j, j.parent_link()) {
            (Joint::Wrist, _) | (_, Link::Palm) if j != Joint::TCmc => n,
            _ => mean(&plates[j.index()]).map(|p| p - c).unwrap_or(n),
        };
        let frame = match e.axis {
            Some(a) => {
                let want = dorsal.cross(&z);
                let a = if a.dot(&want) < 0.0 { -a } else { a };
                frame_from_axis(&a, &z)
            }
            None => frame_from_long_axis(&z, &dorsal),
        }
        .map_err(|m| Error::invalid(format!("joint {j}: {m}")))?;
        sk.joints[j.index()].frame = frame;
    }
    Ok(sk)
}

/// The `link_model.json` document (spec section 3).
#[derive(Serialize)]
struct LinkModelFile<'a> {
    units: &'a str,
    frame: &'a str,
    hand: Side,
    joints: BTreeMap<String, JointRecord>,
    warnings: &'a [String],
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
        serde_json::to_string_pretty(&LinkModelFile {
            units: "mm",
            frame: "reference",
            hand: self.side,
            joints,
            warnings: &self.warnings,
        })
        .expect("serialisable")
    }

    /// Section 3.6 of the seed paper applied: every 1-DOF centre replaced by the one of
    /// `skeleton` (from [`crate::skin::section_centre::centre_on_cross_section`]) with its
    /// shift recorded in the diagnostics; the centre from motion alone is kept among the
    /// alternatives as `motion`.
    pub fn with_skin_centres(
        mut self,
        skeleton: &Skeleton,
        shifts: &BTreeMap<String, f64>,
    ) -> Self {
        for e in &mut self.joints {
            if let Some(&t) = shifts.get(e.joint.name()) {
                let c = e.centre;
                e.diagnostics
                    .alternatives
                    .insert("motion".into(), [c.x, c.y, c.z]);
                e.diagnostics.centre_shift_on_skin_mm = Some(t);
                e.centre = skeleton.centre(e.joint);
            }
        }
        self.skeleton = skeleton.clone();
        self
    }

    /// Write `link_model.json` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::atomic::write_bytes_atomic(path, self.to_json().as_bytes())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::{simulate, Preset, SynthOptions};
    use crate::validate::link_accuracy::compare;

    fn subject(seed: u64, preset: Preset, duration: f64) -> crate::synth::SyntheticSubject {
        simulate(&SynthOptions {
            duration_s: Some(duration),
            voxel_mm: 2.0,
            ..SynthOptions::new(seed, preset)
        })
        .unwrap()
    }

    /// Error-free data: every 3-DOF centre and every 1-DOF axis line is exact; a 1-DOF centre's
    /// position along its axis comes from the dorsal landmark (not from motion) and is within
    /// a couple of millimetres.
    #[test]
    fn clean_subject_is_recovered_exactly() {
        for (seed, hand) in [(31, Side::Right), (32, Side::Left)] {
            let mut o = SynthOptions::new(seed, Preset::Clean);
            o.hand = hand;
            o.duration_s = Some(20.0);
            o.voxel_mm = 2.0;
            let s = simulate(&o).unwrap();
            let m = estimate_link_model_from(hand, 0, &s.trials).unwrap();
            for e in &m.joints {
                let t = &s.truth.joints[e.joint.name()];
                let c = Point::new(t.centre[0], t.centre[1], t.centre[2]);
                match (e.axis, t.axis) {
                    (None, None) => {
                        assert!(
                            (e.centre - c).norm() < 1e-6,
                            "{hand} {}: {:e}",
                            e.joint,
                            (e.centre - c).norm()
                        )
                    }
                    (Some(a), Some(ta)) => {
                        let ta = Vec3::new(ta[0], ta[1], ta[2]);
                        assert!(a.cross(&ta).norm() < 1e-8, "{hand} {} axis", e.joint);
                        let d = e.centre - c;
                        let perp = d - ta * d.dot(&ta);
                        assert!(
                            perp.norm() < 1e-6,
                            "{hand} {} off the axis line by {:e}",
                            e.joint,
                            perp.norm()
                        );
                        assert!(
                            d.norm() < 2.5,
                            "{hand} {} along the axis {}",
                            e.joint,
                            d.norm()
                        );
                        // Oriented: positive rotation flexes palmar, i.e. x = y × z.
                        let jf = m.skeleton.joint(e.joint);
                        assert!((jf.y().cross(&jf.z()) - jf.x()).norm() < 1e-9);
                    }
                    _ => panic!("{}: DOF mismatch", e.joint),
                }
                assert!(
                    e.diagnostics.warnings.is_empty(),
                    "{:?}",
                    e.diagnostics.warnings
                );
            }
        }
    }

    /// The accuracy on a typical subject stays within what the current method reaches (see the
    /// README's link-model table); a regression guard, not the goal.
    #[test]
    fn typical_subject_accuracy_guard() {
        let s = subject(41, Preset::Typical, 40.0);
        let m = estimate_link_model_from(Side::Right, 0, &s.trials).unwrap();
        let model = crate::skeleton::record::joint_records(&m.skeleton);
        let acc = compare(&model, &s.truth.joints);
        for e in &acc.joints {
            let j = Joint::from_name(&e.joint).unwrap();
            let bound = if j.dof() == 3 { 2.5 } else { 4.0 };
            assert!(e.centre_mm < bound, "{}: {:.2} mm", e.joint, e.centre_mm);
            if let Some(a) = e.axis_deg {
                assert!(a < 4.0, "{}: {a:.2} deg", e.joint);
            }
        }
    }

    /// Five simulated sessions of one typical hand (new plates, noise, soft-tissue slide and gaps
    /// each time): the SD of the index link lengths. The seed paper measured 0.52 mm (MCP-PIP)
    /// and 0.92 mm (PIP-DIP) on a real subject and issue 4 asks for 0.3 mm; today's method
    /// reaches about 1.2 and 1.9 mm on this subject (README, "Link model"), so this is a
    /// regression guard at that level, not the goal.
    #[test]
    fn index_link_lengths_are_repeatable() {
        let lengths: Vec<(f64, f64)> = (1..=5)
            .map(|repeat| {
                let s = simulate(&SynthOptions {
                    duration_s: Some(40.0),
                    voxel_mm: 2.0,
                    repeat,
                    ..SynthOptions::new(51, Preset::Typical)
                })
                .unwrap();
                let m = estimate_link_model_from(Side::Right, 0, &s.trials).unwrap();
                let c = |j: Joint| m.joints[j.index()].centre;
                (
                    (c(Joint::IPip) - c(Joint::IMcp)).norm(),
                    (c(Joint::IDip) - c(Joint::IPip)).norm(),
                )
            })
            .collect();
        let sd = |v: Vec<f64>| {
            let m = v.iter().sum::<f64>() / v.len() as f64;
            (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
        };
        let sd1 = sd(lengths.iter().map(|l| l.0).collect());
        let sd2 = sd(lengths.iter().map(|l| l.1).collect());
        eprintln!("index link length SD over 5 sessions: MCP-PIP {sd1:.3} mm, PIP-DIP {sd2:.3} mm; {lengths:?}");
        assert!(sd1 < 1.6 && sd2 < 2.4, "{sd1} {sd2}");
    }

    #[test]
    fn small_range_of_motion_warns_and_static_trials_fail() {
        let s = subject(42, Preset::SmallRom, 20.0);
        let m = estimate_link_model_from(Side::Right, 0, &s.trials).unwrap();
        assert!(
            m.warnings.iter().any(|w| w.contains("range of motion")),
            "{:?}",
            m.warnings
        );

        // A static index trial: every frame the reference frame.
        let mut trials = s.trials.clone();
        let t = trials.get_mut("index").unwrap();
        for track in t.positions.iter_mut() {
            let p0 = track[0];
            track.iter_mut().for_each(|p| *p = p0);
        }
        let e = estimate_link_model_from(Side::Right, 0, &trials)
            .unwrap_err()
            .to_string();
        assert!(e.contains("index") && e.contains("I_MCP"), "{e}");

        // A trial shorter than a second.
        let mut trials = s.trials.clone();
        let t = trials.get_mut("ring").unwrap();
        t.positions.iter_mut().for_each(|tr| tr.truncate(50));
        let e = estimate_link_model_from(Side::Right, 0, &trials)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("ring") && e.contains("R_MCP") && e.contains("shorter"),
            "{e}"
        );
    }
}
