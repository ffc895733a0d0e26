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
//!    [`super::functional`] and, for the soft-tissue slide that neighbouring joints cause,
//!    [`super::sta_model`] (its drivers are the other joints' angles in the same trial), chosen
//!    by the rule of [`choose`];
//! 3. the trial's reference frame is carried to the global reference frame through the four palm
//!    markers (Horn), a joint beyond a digit's first is carried to the palm through the proximal
//!    links' poses averaged over the held reference posture ([`held_reference_pose`]) rather than
//!    through their noisy poses at the one reference frame, and the frames are built (module
//!    [`crate::skeleton`] conventions).

use super::axis_fit::common_plane_normal;
use super::functional::{block_normal_equations, sara_axis, sara_solve, score_centre, score_solve};
use super::level_cues::cue_weights;
use super::model::{JointDiagnostics, JointEstimate, LevelCueOffset, LinkModel, StaDiagnostics};
use super::registration::{register_parent, ParentRegistration};
use super::sphere_fit::{
    circle_centre_on_axis, common_sphere_centre, common_sphere_centre_bias_compensated,
};
use super::sta_model::{score_sta, StaFit, StaTerms, PRIOR_SLIDE_MM_PER_RAD};
use crate::anatomy::{arm_markers, palm_markers, Finger, Joint, Link, Side};
use crate::error::{Error, Result};
use crate::geometry::{absolute_orientation, Point, Registration, Vec3};
use crate::mocap::subject::{Subject, TrialKind};
use crate::mocap::trajectories::Trajectories;
use crate::skeleton::{frame_from_axis, frame_from_long_axis, JointFrame, Skeleton};
use nalgebra::{Isometry3, Rotation3, UnitQuaternion};
use std::collections::BTreeMap;

/// A 3-DOF joint whose child rotated less than this (degrees) is flagged: the centre is poorly
/// determined. The seed paper's calibration motions reach about 80° at the MCPs, 55° at the
/// thumb CMC and 60° at the wrist; a joint that moved less than about half of that gives
/// centres whose error grows quickly (Ehrig et al. 2006; `small-rom` in the suite).
pub(crate) const MIN_ROM_3DOF_DEG: f64 = 45.0;

/// A 1-DOF joint that flexed less than this (degrees) is flagged (the protocol reaches about
/// 100° at PIP, 70° at DIP and IP, 50° at the thumb MCP).
pub(crate) const MIN_ROM_1DOF_DEG: f64 = 45.0;

/// Below this ratio of the smallest to the largest principal spread, the child's motion is too
/// planar for a sphere fit (a hinge-like motion at a 3-DOF joint): flagged.
pub(crate) const MIN_SPHERE_CONDITION: f64 = 0.02;

/// A joint whose child moved less than this (degrees) relative to its parent is refused: the
/// trial is static for that joint and no centre can be estimated.
pub(crate) const MIN_ROM_HARD_DEG: f64 = 5.0;

/// Trials shorter than this are refused (seconds).
pub(crate) const MIN_TRIAL_S: f64 = 1.0;

/// The soft-tissue model's centre ([`super::sta_model`]) is used only when its predicted
/// standard deviation (off a hinge's axis) is at most this, mm; otherwise the slides and the
/// centre are confounded in this motion and the rigid estimator is kept (see [`choose`]).
pub(crate) const MAX_STA_CENTRE_SD_MM: f64 = 0.25;

/// Whether the soft-tissue model's centre may be chosen at all. Off: on the suite it lowered
/// the typical hands' mean centre error by only 0.06 mm (1.00 -> 0.94 mm, better on 7 of 8) but
/// raised the noisy hands' 1-DOF median from 2.5 to 3.1 mm, and it leaves the repeatability
/// where it was (README, "Link model"). It is always fitted and reported
/// (`diagnostics.sta`, `alternatives["score-sta"/"sara-sta"]`) so the choice can be revisited.
pub(crate) const STA_BY_DEFAULT: bool = false;

impl StaDiagnostics {
    fn new(fit: &StaFit, drivers: Vec<String>, used: bool) -> Self {
        let max = |v: &[Vec3]| v.iter().map(|d| d.norm()).fold(0.0, f64::max);
        StaDiagnostics {
            used,
            drivers,
            centre_sd_mm: fit.centre_sd_mm,
            rms_mm: fit.rms,
            rigid_rms_mm: fit.rigid_rms,
            max_slide_mm_per_rad: [max(&fit.parent_slide), max(&fit.child_slide)],
            frames: fit.n_frames,
        }
    }
}

/// A joint's estimate in its trial's reference frame, before the global transform.
struct LocalEstimate {
    centre: Point,
    axis: Option<Vec3>,
    /// 1-DOF: the point whose level along the axis the centre takes.
    near: Option<Point>,
    /// 1-DOF: the level cues by name, in the trial's reference frame.
    cues: Vec<(String, Point)>,
    /// Block-bootstrap replicates of the centre ([`bootstrap_centres`]), one per draw of the
    /// trial (`None` where a draw did not determine it).
    replicates: Vec<Option<Point>>,
    alternatives: Vec<(String, Point)>,
    diagnostics: JointDiagnostics,
    /// The child markers' tracks in the parent's frame, kept to measure their radii again
    /// about the centre the hinge's level moves.
    tracks: Vec<Vec<Point>>,
}

/// Mean and SD of each track's distance to `centre` (the seed paper's Figure 9).
fn marker_radii(tracks: &[Vec<Point>], centre: &Point) -> (Vec<f64>, Vec<f64>) {
    tracks
        .iter()
        .map(|t| {
            let d: Vec<f64> = t.iter().map(|p| (p - centre).norm()).collect();
            let n = d.len().max(1) as f64;
            let m = d.iter().sum::<f64>() / n;
            let sd = (d.iter().map(|x| (x - m).powi(2)).sum::<f64>() / n).sqrt();
            (m, sd)
        })
        .unzip()
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

/// A joint's motion in one trial: the parent's registration and, per frame, the child's pose in
/// the parent's reference pose.
struct JointMotion {
    reg: ParentRegistration,
    /// Per frame (aligned with the trial), the child's pose, `None` where it cannot be had.
    poses: Vec<Option<Isometry3<f64>>>,
    /// The child markers' reference-frame positions.
    reference: Vec<Point>,
    /// The parent markers' reference-frame positions.
    parent_reference: Vec<Point>,
}

/// Register the parent and the child of joint `j` in every frame of `traj` (equation 1). Each
/// segment's registration onto the reference frame is made once per trial (`segments`, keyed by
/// link) and shared by the two joints it belongs to: the child's pose in the parent's reference
/// pose is `T_p(t) T_c(t)^-1`, which is exactly Horn's fit of the child's reference markers onto
/// its markers expressed in the parent's reference pose (rigid least squares commutes with rigid
/// maps of either point set), at a third fewer fits.
fn joint_motion(
    traj: &Trajectories,
    j: Joint,
    rf: usize,
    segments: &mut BTreeMap<Link, ParentRegistration>,
) -> Result<JointMotion> {
    let (parent, child) = marker_sets(j);
    let parent_refs: Vec<&str> = parent.iter().map(String::as_str).collect();
    let child_refs: Vec<&str> = child.iter().map(String::as_str).collect();
    let all: Vec<&str> = parent_refs.iter().chain(&child_refs).copied().collect();
    traj.require_at(&all, rf)?;
    let pl = j.parent_link();
    let cl = j.child_link();
    for (l, names) in [(pl, &parent_refs), (cl, &child_refs)] {
        segments
            .entry(l)
            .or_insert_with(|| register_parent(traj, names, rf));
    }
    let reg = segments[&pl].clone();
    let poses = reg
        .frames
        .iter()
        .zip(&segments[&cl].frames)
        .map(|(p, c)| Some(p.as_ref()?.isometry() * c.as_ref()?.isometry().inverse()))
        .collect();
    let at_rf = |names: &[&str]| -> Vec<Point> {
        names
            .iter()
            .map(|n| traj.get(n, rf).expect("checked by require_at"))
            .collect()
    };
    Ok(JointMotion {
        reg,
        poses,
        reference: at_rf(&child_refs),
        parent_reference: at_rf(&parent_refs),
    })
}

/// Smallest RMS (over the trial) of a driver angle for it to enter the soft-tissue model,
/// radians (5°): directions a joint did not really move in carry only noise.
const MIN_DRIVER_RMS_RAD: f64 = 0.087;

/// The angle coordinates of a joint's motion, per frame (radians, zero at the reference frame):
/// the rotation vectors of the child's poses projected on their principal directions whose RMS
/// exceeds [`MIN_DRIVER_RMS_RAD`] (flexion for a hinge; flexion and abduction for a
/// circumducted MCP). Uncentred, so every coordinate is zero at the reference frame.
fn joint_angles(poses: &[Option<Isometry3<f64>>]) -> Vec<Option<Vec<f64>>> {
    let rv: Vec<Option<Vec3>> = poses
        .iter()
        .map(|p| p.map(|p| p.rotation.scaled_axis()))
        .collect();
    let (mut m, mut n) = (nalgebra::Matrix3::<f64>::zeros(), 0usize);
    for v in rv.iter().flatten() {
        m += v * v.transpose();
        n += 1;
    }
    if n == 0 {
        return rv.iter().map(|_| None).collect();
    }
    let eig = (m / n as f64).symmetric_eigen();
    let mut dirs: Vec<(f64, Vec3)> = (0..3)
        .filter(|&i| eig.eigenvalues[i] > MIN_DRIVER_RMS_RAD * MIN_DRIVER_RMS_RAD)
        .map(|i| (eig.eigenvalues[i], eig.eigenvectors.column(i).into_owned()))
        .collect();
    dirs.sort_by(|a, b| b.0.total_cmp(&a.0));
    rv.iter()
        .map(|v| v.map(|v| dirs.iter().map(|(_, d)| d.dot(&v)).collect()))
        .collect()
}

/// A neighbour's angle coordinate enters the soft-tissue model only if the joint's own angles
/// explain less than this fraction of it (uncentred R² of a least-squares fit over the frames).
pub(crate) const MAX_DRIVER_R2: f64 = 0.5;

/// The columns of `drivers` that may enter the soft-tissue model of the joint whose own angles
/// are `own`: not its own angles (a slide that follows a joint's own angle is kinematically a
/// shifted centre, see [`super::sta_model`]), and only the neighbours' angles that moved
/// separately from them in the trial ([`MAX_DRIVER_R2`]); in the seed paper's protocol the MCP
/// circumduction and the distal flexion are separate, but PIP and DIP flex together.
fn separable_drivers(drivers: &[Option<Vec<f64>>], own: std::ops::Range<usize>) -> Vec<usize> {
    let rows: Vec<&Vec<f64>> = drivers.iter().flatten().collect();
    let width = rows.first().map_or(0, |r| r.len());
    let k = own.len();
    // Normal matrix of the own angles, and their products with every column.
    let mut oo = nalgebra::DMatrix::<f64>::zeros(k, k);
    let mut oc = nalgebra::DMatrix::<f64>::zeros(k, width);
    let mut cc = vec![0.0; width];
    for r in &rows {
        for (a, ia) in own.clone().enumerate() {
            for (b, ib) in own.clone().enumerate() {
                oo[(a, b)] += r[ia] * r[ib];
            }
            for (c, &x) in r.iter().enumerate() {
                oc[(a, c)] += r[ia] * x;
            }
        }
        for (acc, &x) in cc.iter_mut().zip(r.iter()) {
            *acc += x * x;
        }
    }
    // Inverse of the own angles' normal matrix (pseudo-inverse; none when the joint has no
    // angle coordinate that moved, and then nothing is explained by it).
    let inv = if k == 0 {
        oo
    } else {
        let eig = oo.symmetric_eigen();
        let hi = eig.eigenvalues.max();
        let mut inv = nalgebra::DMatrix::<f64>::zeros(k, k);
        for (v, &l) in eig.eigenvectors.column_iter().zip(eig.eigenvalues.iter()) {
            if l > hi * 1e-12 {
                inv += v * v.transpose() / l;
            }
        }
        inv
    };
    (0..width)
        .filter(|c| !own.contains(c))
        .filter(|&c| {
            let explained = if k == 0 {
                0.0
            } else {
                let v = oc.column(c);
                (v.transpose() * &inv * v)[0]
            };
            cc[c] > 0.0 && explained / cc[c] < MAX_DRIVER_R2
        })
        .collect()
}

/// The drivers of joint `j`'s soft-tissue model among the joints of its trial: the joints at
/// both ends of its parent and child segments (the skin of a segment is pulled over the joints
/// it spans): the parent's proximal joint, `j`, and the child's distal joint(s).
fn driver_joints(j: Joint, trial_joints: &[Joint]) -> Vec<Joint> {
    trial_joints
        .iter()
        .copied()
        .filter(|&k| k == j || Some(k) == j.parent() || k.parent() == Some(j))
        .collect()
}

/// The rule that picks the estimator, in order of preference (the first that succeeds), as
/// measured on the `validation/` phantoms (README, "Link model"): for a 3-DOF joint SCoRE with
/// the linear soft-tissue model of both clusters (`score-sta`, [`super::sta_model`]), then plain
/// SCoRE (Ehrig 2006), which uses the child's whole rigid motion, then the bias-compensated sphere
/// fit (Halvorsen 2003), then the plain one (Gamage & Lasenby 2002); for a 1-DOF joint SARA's
/// axis (Ehrig 2007) or the common plane normal, and as centre the soft-tissue model's point on
/// that axis (`sara-sta`), SARA's axis line, then the common circle centre on the axis (Gamage &
/// Lasenby 2002). The soft-tissue model is fitted only with drivers that moved separately from
/// the joint itself (`separable_drivers`; none for the wrist, the DIPs and the thumb IP in the
/// seed paper's protocol, which then keep the rigid estimators) and taken only when its
/// predicted centre SD is at most [`MAX_STA_CENTRE_SD_MM`] and the joint has no range-of-motion
/// or planarity warning, and only while [`STA_BY_DEFAULT`] is on (it is off: see there). A 1-DOF centre's position along its axis is not determined by any
/// motion: it is taken level with the joint's dorsal landmark, and section 3.6 later moves it
/// onto the skin's cross-section.
pub fn choose(dof: usize) -> (&'static [&'static str], Option<&'static [&'static str]>) {
    if dof == 3 {
        (&["score-sta", "score", "bcls", "sphere-ls"], None)
    } else {
        (
            &["sara-sta", "sara", "circle-on-axis"],
            Some(&["sara", "plane-normal"]),
        )
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
/// `cues` are points whose mean projection on a 1-DOF joint's axis fixes the centre along the
/// axis, which no motion determines (the level cues of [`LevelCue`], in the trial's reference
/// frame; none: the level of the plates).
#[allow(clippy::too_many_arguments)]
fn estimate_local(
    traj: &Trajectories,
    trial: &str,
    j: Joint,
    cues: &[Point],
    motion: &JointMotion,
    drivers: &[Option<Vec<f64>>],
    nb_cols: &[usize],
    col_terms: &[StaTerms],
    driver_names: Vec<String>,
) -> Result<LocalEstimate> {
    let fail = |msg: String| Error::input(&traj.source, format!("joint {j}: {msg}"));
    if traj.duration_s() < MIN_TRIAL_S {
        return Err(fail(format!(
            "the trial lasts {:.2} s, shorter than {MIN_TRIAL_S} s: record the calibration motion",
            traj.duration_s()
        )));
    }
    let (_, child) = marker_sets(j);
    let child_refs: Vec<&str> = child.iter().map(String::as_str).collect();
    let reg: &ParentRegistration = &motion.reg;
    let tracks: Vec<Vec<Point>> = child_refs.iter().map(|n| reg.express(traj, n)).collect();
    let track_refs: Vec<&[Point]> = tracks.iter().map(Vec::as_slice).collect();
    let reference = &motion.reference;
    // The reference frame's own registration is the identity (up to round-off); its child
    // positions are the child's local frame.
    let poses: Vec<Isometry3<f64>> = motion.poses.iter().flatten().copied().collect();
    if poses.len() < 10 {
        return Err(fail(format!(
            "only {} frames have every parent and child marker; the trial cannot determine the joint",
            poses.len()
        )));
    }
    let identity = vec![Isometry3::identity(); poses.len()];
    // The frames where the soft-tissue model's drivers are known too.
    let (sta_poses, sta_drivers): (Vec<Isometry3<f64>>, Vec<Vec<f64>>) = motion
        .poses
        .iter()
        .zip(drivers)
        .filter_map(|(p, d)| Some(((*p)?, d.clone()?)))
        .unzip();
    let sta_identity = vec![Isometry3::identity(); sta_poses.len()];
    let nb_drivers: Vec<Vec<f64>> = sta_drivers
        .iter()
        .map(|row| nb_cols.iter().map(|&c| row[c]).collect())
        .collect();
    let driver_names: Vec<String> = nb_cols.iter().map(|&c| driver_names[c].clone()).collect();
    let nb_terms: Vec<StaTerms> = nb_cols.iter().map(|&c| col_terms[c]).collect();
    // The soft-tissue model about a free centre (3-DOF, SCoRE's) or a hinge axis (1-DOF,
    // SARA's). Without a separable driver it would be SCoRE's own system: not fitted.
    let fit_sta = |axis: Option<Vec3>| {
        if nb_cols.is_empty() {
            Err(Error::invalid("no separable driver"))
        } else {
            score_sta(
                &sta_identity,
                &sta_poses,
                &nb_drivers,
                axis,
                &nb_terms,
                PRIOR_SLIDE_MM_PER_RAD,
            )
        }
    };

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

    let mut sta_diag = None;
    let mut level_sd = None;
    let mut near_out = None;
    // Whether the soft-tissue model's centre may be picked (the rule of [`choose`]).
    let sta_eligible = |fit: &StaFit, warned: bool| -> bool {
        STA_BY_DEFAULT && !warned && fit.centre_sd_mm <= MAX_STA_CENTRE_SD_MM
    };
    let pick = |alternatives: &[(String, Point)], sta_ok: bool| {
        centres_rule
            .iter()
            .filter(|name| sta_ok || !name.ends_with("-sta"))
            .find_map(|name| alternatives.iter().find(|(n, _)| n == name))
            .cloned()
    };

    if j.dof() == 3 {
        let score = score_centre(&identity, &poses);
        let sta = fit_sta(None);
        let bcls = common_sphere_centre_bias_compensated(&track_refs, None);
        let ls = common_sphere_centre(&track_refs);
        if let Ok(s) = &sta {
            alternatives.push(("score-sta".into(), s.parent_local));
        }
        if let Ok(s) = &score {
            alternatives.push(("score".into(), s.parent_local));
        }
        if let Ok(s) = &bcls {
            alternatives.push(("bcls".into(), s.centre));
        }
        if let Ok(s) = &ls {
            alternatives.push(("sphere-ls".into(), s.centre));
        }
        condition = ls.as_ref().map(|s| s.condition).unwrap_or(0.0);
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
        let sta_ok = sta
            .as_ref()
            .is_ok_and(|s| sta_eligible(s, !warnings.is_empty()));
        let picked = pick(&alternatives, sta_ok).ok_or_else(|| {
            fail(format!(
                "no estimator could determine the centre ({}); is the trial static?",
                ls.as_ref().err().map(|e| e.to_string()).unwrap_or_default()
            ))
        })?;
        estimator = picked.0;
        centre = picked.1;
        fit_rms = match (estimator.as_str(), &sta, &score, &bcls, &ls) {
            ("score-sta", Ok(s), _, _, _) => s.rms,
            ("score", _, Ok(s), _, _) => s.rms,
            ("bcls", _, _, Ok(s), _) => s.rms,
            (_, _, _, _, Ok(s)) => s.rms,
            _ => f64::NAN,
        };
        if let Ok(s) = &sta {
            sta_diag = Some(StaDiagnostics::new(s, driver_names, sta_ok));
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
        // Along the axis: the mean level of the cues (the joint's dorsal landmark, which a lab
        // puts over the middle of the joint, and the plates, on the dorsal midline of their
        // links; see `LevelCue`); the projection on the axis is linear, so the mean point's.
        let near = mean(cues).unwrap_or_else(|| {
            mean(&[
                mean(&motion.parent_reference).expect("non-empty"),
                mean(reference).expect("non-empty"),
            ])
            .expect("non-empty")
        });
        level_sd = Some(level_standard_error(cues, &a));
        near_out = Some(near);
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
        let circle = circle_centre_on_axis(&track_refs, &a, &near)
            .map_err(|e| fail(format!("circle centre: {e}")))?;
        let sta = fit_sta(Some(a));
        // The point of a line through `p` along the axis level with `near`.
        let level_on = |p: Point| p + a * (near - p).dot(&a);
        if let Ok(s) = &sta {
            alternatives.push(("sara-sta".into(), level_on(s.parent_local)));
        }
        alternatives.push(("circle-on-axis".into(), circle.centre));
        if let Ok(s) = &sara {
            alternatives.push(("sara".into(), level_on(s.point_parent_local)));
        }
        if let Ok(s) = common_sphere_centre(&track_refs) {
            alternatives.push(("sphere-ls".into(), s.centre));
        }
        let sta_ok = sta
            .as_ref()
            .is_ok_and(|s| sta_eligible(s, !warnings.is_empty()));
        let picked = pick(&alternatives, sta_ok).expect("the circle centre is always there");
        estimator = picked.0;
        centre = picked.1;
        fit_rms = match (estimator.as_str(), &sta, &sara) {
            ("sara-sta", Ok(s), _) => s.rms,
            ("sara", _, Ok(s)) => s.rms,
            _ => circle.rms,
        };
        if let Ok(p) = &plane {
            fit_rms = fit_rms.max(p.plane_rms);
        }
        if let Ok(s) = &sta {
            sta_diag = Some(StaDiagnostics::new(s, driver_names, sta_ok));
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
    let (rmean, rsd) = marker_radii(&tracks, &centre);
    Ok(LocalEstimate {
        centre,
        axis,
        near: near_out,
        cues: Vec::new(),
        replicates: Vec::new(),
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
            chain_shift_mm: None,
            sta: sta_diag,
            centre_sd_mm: None,
            level_sd_mm: level_sd,
            level_cues: BTreeMap::new(),
            depth_cue: None,
            warnings: warnings.clone(),
        },
        tracks,
    })
}

/// Assumed SD of a landmark's placement along the skin off its anatomical point, mm: palpation
/// by eye and touch is millimetre work (the spec: "expect a few mm" for the palm markers).
/// Used only for the level's uncertainty when a single cue gives it.
pub(crate) const LANDMARK_SD_MM: f64 = 1.0;

/// Length of the blocks of frames the bootstrap resamples, seconds: longer than the
/// correlation of marker noise and gaps, short enough for tens of blocks per trial.
pub const BOOTSTRAP_BLOCK_S: f64 = 1.0;

/// Block-bootstrap replicates of a joint's centre in its trial's reference frame (Künsch 1989):
/// the trial's frames cut into blocks of `block` frames, every draw of `draws` (block indices,
/// shared by the joints of a trial so that link lengths are drawn coherently) sums those
/// blocks' SCoRE (3-DOF) or SARA (1-DOF) normal equations and solves them; a hinge's centre is
/// then put level with `near` along the drawn axis, moved along it by `shift`. `None` for a
/// draw that does not determine the centre.
fn bootstrap_centres(
    poses: &[Option<Isometry3<f64>>],
    block: usize,
    draws: &[Vec<usize>],
    hinge: Option<(Point, f64)>,
) -> Vec<Option<Point>> {
    let n_blocks = poses.len().div_ceil(block.max(1));
    let (child, block_of): (Vec<Isometry3<f64>>, Vec<usize>) = poses
        .iter()
        .enumerate()
        .filter_map(|(f, p)| Some(((*p)?, f / block.max(1))))
        .unzip();
    let parent = vec![Isometry3::identity(); child.len()];
    let Ok(blocks) = block_normal_equations(&parent, &child, &block_of, n_blocks) else {
        return draws.iter().map(|_| None).collect();
    };
    draws
        .iter()
        .map(|draw| {
            let (mut n, mut g) = (nalgebra::Matrix6::zeros(), nalgebra::Vector6::zeros());
            for &b in draw {
                n += blocks[b].0;
                g += blocks[b].1;
            }
            match hinge {
                None => score_solve(&n, &g).map(|(x, _)| Point::new(x[0], x[1], x[2])),
                Some((near, shift)) => {
                    sara_solve(&n, &g).map(|(p, a)| p + a * ((near - p).dot(&a) + shift))
                }
            }
        })
        .collect()
}

/// A link whose length's bootstrap SD exceeds this (mm) is named in a warning: the seed
/// paper's repeatability of the index links was 0.52 and 0.92 mm SD.
pub const MAX_LENGTH_SD_MM: f64 = 1.0;

/// Sample SD; `None` with fewer than two values.
fn sample_sd(v: &[f64]) -> Option<f64> {
    if v.len() < 2 {
        return None;
    }
    let m = v.iter().sum::<f64>() / v.len() as f64;
    Some((v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt())
}

/// The RMS distance of the replicates (those that exist) from their mean; `None` with fewer
/// than two.
fn replicate_sd(points: &[Option<Point>]) -> Option<f64> {
    let ps: Vec<Point> = points.iter().flatten().copied().collect();
    if ps.len() < 2 {
        return None;
    }
    let m = mean(&ps)?;
    let ss: f64 = ps.iter().map(|p| (p - m).norm_squared()).sum();
    Some((ss / (ps.len() - 1) as f64).sqrt())
}

/// How long after the reference frame the calibration protocol holds the reference posture,
/// seconds: each trial starts seated still (seed paper section 3.3).
pub(crate) const HELD_S: f64 = 1.0;

/// Largest turn of a child link (relative to its parent) between the start and the end of
/// what is taken as the held reference posture, degrees, each end averaged over a fifth of it:
/// above what marker noise fakes on finger plates, below any calibration motion.
pub(crate) const HELD_DEG: f64 = 3.0;

/// The mean of rigid poses, rotations averaged as quaternions and the images of `pivot`
/// apart (to first order the mean map near `pivot`, whatever the lab coordinates' origin).
fn mean_pose(poses: &[Isometry3<f64>], pivot: &Point) -> Isometry3<f64> {
    let (mut q, mut p) = (nalgebra::Vector4::<f64>::zeros(), Vec3::zeros());
    for pose in poses {
        let c = pose.rotation.coords;
        q += if c.w < 0.0 { -c } else { c };
        p += (pose * pivot).coords;
    }
    let r = UnitQuaternion::from_quaternion(nalgebra::Quaternion::from(q));
    let p = p / poses.len() as f64;
    Isometry3::from_parts(nalgebra::Translation3::from(p - r * pivot.coords), r)
}

/// The child's pose in the parent's reference pose while the reference posture is held: the
/// mean of `poses` (child in parent, per frame; the gaps skipped) over the frames from `rf` on,
/// for at most [`HELD_S`], halved until the child turns less than [`HELD_DEG`] between the
/// first and the last fifth of them. `None` if that leaves fewer than ten frames. `pivot` is a
/// point near the joints concerned (the child's reference markers).
///
/// Each link's reference pose is its markers at the single frame `rf`, noise included: a
/// finger plate's (three markers about 10 mm from its centre, 0.2 mm noise) is off by about a
/// degree, which moves the next joint's centre, estimated in that link's reference pose, by a
/// few tenths of a millimetre relative to the previous joint's, differently in every recording.
/// While the posture is held the true relative pose does not change, so the mean over those
/// frames estimates the reference frame's own error, and [`chain_held_poses`] undoes it.
fn held_reference_pose(
    poses: &[Option<Isometry3<f64>>],
    rf: usize,
    rate: f64,
    pivot: &Point,
) -> Option<Isometry3<f64>> {
    let n = (HELD_S * rate).round() as usize;
    let frames: Vec<Isometry3<f64>> = poses.iter().skip(rf).take(n).flatten().copied().collect();
    let mut len = frames.len();
    while len >= 10 {
        let w = &frames[..len];
        let k = len / 5;
        let (a, b) = (mean_pose(&w[..k], pivot), mean_pose(&w[len - k..], pivot));
        if (a.inverse() * b).rotation.angle() <= HELD_DEG.to_radians() {
            return Some(mean_pose(w, pivot));
        }
        len /= 2;
    }
    None
}

/// Per joint, the map from its parent link's reference coordinates to the palm's (for the
/// wrist, the forearm's): the product of the held poses ([`held_reference_pose`], indexed by
/// [`Joint::index`]) of the joints between the palm and that link; the identity for the joints
/// on the palm and forearm, and where a held pose is missing.
fn chain_held_poses(held: &[Option<Isometry3<f64>>]) -> Vec<Isometry3<f64>> {
    fn chain(j: Joint, held: &[Option<Isometry3<f64>>]) -> Isometry3<f64> {
        match j.parent() {
            None | Some(Joint::Wrist) => Isometry3::identity(),
            Some(p) => chain(p, held) * held[p.index()].unwrap_or_else(Isometry3::identity),
        }
    }
    Joint::ALL.iter().map(|&j| chain(j, held)).collect()
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

/// Where a hinge's centre is placed along its axis, which no motion determines: the mean level
/// of the chosen cues, each a point on the dorsal midline of the digit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelCue {
    /// The joint's dorsal landmark of the static trial (the first link model).
    Landmark,
    /// The centroids of the parent's and the child's plates at the reference frame.
    Plates,
    /// The centroid of the parent's plate at the reference frame.
    ParentPlate,
    /// The centroid of the child's plate at the reference frame.
    ChildPlate,
    /// The landmark and the child's plate.
    LandmarkAndChildPlate,
    /// The landmark and both plates' centroids, equally weighted: three independent placements
    /// on the digit's dorsal midline, so a landmark placed off its point (about a millimetre
    /// along the skin) moves the level a third as much.
    LandmarkAndPlates,
}

/// Choices of the link model's estimation. The default is the method the README's "Link
/// model" documents; the others exist to measure what each part contributes
/// (`examples/link_centres.rs`).
#[derive(Clone, Debug, PartialEq)]
pub struct LinkOptions {
    /// Where a hinge's centre lies along its axis.
    pub level: LevelCue,
    /// Block-bootstrap draws for the centres' and link lengths' uncertainties (0: none).
    pub bootstrap: usize,
}

impl Default for LinkOptions {
    fn default() -> Self {
        LinkOptions {
            level: LevelCue::LandmarkAndPlates,
            bootstrap: 50,
        }
    }
}

impl LinkOptions {
    /// The option set called `name`: `default`; `first` (the first link model's method: the
    /// landmark's level, no bootstrap); `landmark`, `plates`, `parent-plate`, `child-plate`,
    /// `landmark-child` (the default with those level cues).
    pub fn named(name: &str) -> Option<LinkOptions> {
        let d = LinkOptions::default();
        Some(match name {
            "default" => d,
            "first" => LinkOptions {
                level: LevelCue::Landmark,
                bootstrap: 0,
            },
            "landmark" => LinkOptions {
                level: LevelCue::Landmark,
                ..d
            },
            "plates" => LinkOptions {
                level: LevelCue::Plates,
                ..d
            },
            "parent-plate" => LinkOptions {
                level: LevelCue::ParentPlate,
                ..d
            },
            "child-plate" => LinkOptions {
                level: LevelCue::ChildPlate,
                ..d
            },
            "landmark-child" => LinkOptions {
                level: LevelCue::LandmarkAndChildPlate,
                ..d
            },
            _ => return None,
        })
    }
}

/// Reconstruct the link model of a subject from its trials.
pub fn estimate_link_model(subject: &Subject) -> Result<LinkModel> {
    estimate_link_model_with(subject, &LinkOptions::default())
}

/// [`estimate_link_model`] with the choices of `opts`.
pub fn estimate_link_model_with(subject: &Subject, opts: &LinkOptions) -> Result<LinkModel> {
    let (trials, mut warnings) = subject.load_trials()?;
    let mut model =
        estimate_link_model_from_with(subject.hand, subject.reference_frame, &trials, opts)?;
    warnings.append(&mut model.warnings);
    model.warnings = warnings;
    Ok(model)
}

/// [`estimate_link_model`] from trials already in memory, keyed as in `[trials]` of
/// `subject.toml` (`reference`, `wrist`, `thumb`, ...), `rf` the reference frame.
pub fn estimate_link_model_from(
    hand: Side,
    rf: usize,
    trials: &BTreeMap<String, Trajectories>,
) -> Result<LinkModel> {
    estimate_link_model_from_with(hand, rf, trials, &LinkOptions::default())
}

/// Seed of the bootstrap's draws (forked per trial and joint by name): the same trials give
/// the same uncertainties.
const BOOTSTRAP_SEED: u64 = 0x6c69_6e6b;

/// [`estimate_link_model_from`] with the choices of `opts`.
pub(crate) fn estimate_link_model_from_with(
    hand: Side,
    rf: usize,
    trials: &BTreeMap<String, Trajectories>,
    opts: &LinkOptions,
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
    // Per joint: the estimate, its trial's transform to the global frame, the child plate and
    // the held reference pose (`held_reference_pose`).
    type Local = (
        LocalEstimate,
        Registration,
        Vec<Point>,
        Option<Isometry3<f64>>,
    );
    let mut locals: Vec<Option<Local>> = (0..Joint::ALL.len()).map(|_| None).collect();
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
    type Estimated = Vec<(Joint, Local)>;
    let per_trial: Vec<Result<Estimated>> = trials
        .par_iter()
        .map(|(kind, joints)| -> Result<Estimated> {
            let traj = get(*kind)?;
            let g = to_global(traj, rf, &reference_palm)?;
            let mut out = Vec::new();
            let mut segments = BTreeMap::new();
            let motions: Vec<JointMotion> = joints
                .iter()
                .map(|&j| joint_motion(traj, j, rf, &mut segments))
                .collect::<Result<_>>()?;
            let angles: Vec<Vec<Option<Vec<f64>>>> =
                motions.iter().map(|m| joint_angles(&m.poses)).collect();
            // The bootstrap's draws of blocks, shared by the trial's joints.
            let mut rng = crate::rng::Rng::new(BOOTSTRAP_SEED).fork(kind.key());
            let block = ((BOOTSTRAP_BLOCK_S * traj.frame_rate).round() as usize).max(1);
            let n_blocks = traj.n_frames().div_ceil(block);
            let draws: Vec<Vec<usize>> = (0..opts.bootstrap)
                .map(|_| (0..n_blocks).map(|_| rng.below(n_blocks)).collect())
                .collect();
            for (&j, motion) in joints.iter().zip(&motions) {
                let cues: Vec<(String, Point)> = if j.dof() == 1 {
                    let lm = g.inverse().apply(&landmark(j.name())?);
                    let plates = [
                        mean(&motion.parent_reference).expect("a plate has markers"),
                        mean(&motion.reference).expect("a plate has markers"),
                    ];
                    let (names, points): (Vec<&str>, Vec<Point>) = match opts.level {
                        LevelCue::Landmark => (vec!["landmark"], vec![lm]),
                        LevelCue::Plates => (vec!["parent-plate", "child-plate"], plates.to_vec()),
                        LevelCue::ParentPlate => (vec!["parent-plate"], vec![plates[0]]),
                        LevelCue::ChildPlate => (vec!["child-plate"], vec![plates[1]]),
                        LevelCue::LandmarkAndChildPlate => {
                            (vec!["landmark", "child-plate"], vec![lm, plates[1]])
                        }
                        LevelCue::LandmarkAndPlates => (
                            vec!["landmark", "parent-plate", "child-plate"],
                            vec![lm, plates[0], plates[1]],
                        ),
                    };
                    names.iter().map(|n| n.to_string()).zip(points).collect()
                } else {
                    Vec::new()
                };
                let cue_points: Vec<Point> = cues.iter().map(|c| c.1).collect();
                // The soft-tissue model's drivers: the angles of the joints at both ends of
                // j's two segments, per frame (`None` where one of them is unknown).
                let ks: Vec<usize> = driver_joints(j, joints)
                    .iter()
                    .map(|k| joints.iter().position(|x| x == k).expect("in the trial"))
                    .collect();
                let mut names = Vec::new();
                // Which cluster slides with each driver: the one on the segment that spans
                // both j and that joint (the parent's for j's parent joint, the child's for
                // j's child joint).
                let mut col_terms = Vec::new();
                for &k in &ks {
                    let width = angles[k].iter().flatten().map(Vec::len).next().unwrap_or(0);
                    names.extend((0..width).map(|c| format!("{}[{c}]", joints[k])));
                    let terms = if Some(joints[k]) == j.parent() {
                        StaTerms::PARENT
                    } else if joints[k].parent() == Some(j) {
                        StaTerms::CHILD
                    } else {
                        StaTerms::BOTH
                    };
                    col_terms.extend((0..width).map(|_| terms));
                }
                let drivers: Vec<Option<Vec<f64>>> = (0..traj.n_frames())
                    .map(|f| {
                        let mut row = Vec::new();
                        for &k in &ks {
                            row.extend_from_slice(angles[k][f].as_ref()?);
                        }
                        Some(row)
                    })
                    .collect();
                let own = ks
                    .iter()
                    .position(|&k| joints[k] == j)
                    .expect("j drives itself");
                let own_cols = {
                    let before: usize = ks[..own]
                        .iter()
                        .map(|&k| angles[k].iter().flatten().map(Vec::len).next().unwrap_or(0))
                        .sum();
                    let w = angles[ks[own]]
                        .iter()
                        .flatten()
                        .map(Vec::len)
                        .next()
                        .unwrap_or(0);
                    before..before + w
                };
                let nb_cols = separable_drivers(&drivers, own_cols);
                let mut est = estimate_local(
                    traj,
                    kind.key(),
                    j,
                    &cue_points,
                    motion,
                    &drivers,
                    &nb_cols,
                    &col_terms,
                    names,
                )?;
                // The level's own uncertainty is added once the cues' weights are known.
                est.replicates =
                    bootstrap_centres(&motion.poses, block, &draws, est.near.map(|n| (n, 0.0)));
                est.cues = cues;
                // The child plate's reference positions, for the dorsal direction of the frames.
                let (_, child) = marker_sets(j);
                let plate: Vec<Point> = child
                    .iter()
                    .filter_map(|n| traj.get(n, rf))
                    .map(|p| g.apply(&p))
                    .collect();
                let pivot = mean(&motion.reference).expect("a plate has markers");
                let held = held_reference_pose(&motion.poses, rf, traj.frame_rate, &pivot);
                out.push((j, (est, g, plate, held)));
            }
            Ok(out)
        })
        .collect();
    for r in per_trial {
        for (j, local) in r? {
            locals[j.index()] = Some(local);
        }
    }

    // The hinges' levels: the cues weighted by their error variances, estimated over all hinges
    // of the subject (`cue_weights`); the bootstrap replicates follow the centre and get the
    // level's own uncertainty.
    let offsets: Vec<Vec<f64>> = locals
        .iter()
        .flatten()
        .filter_map(|(est, ..)| {
            let a = est.axis?;
            Some(
                est.cues
                    .iter()
                    .map(|(_, p)| (p - est.centre).dot(&a))
                    .collect(),
            )
        })
        .collect();
    if let Some((weights, variances)) = cue_weights(&offsets) {
        let level_sd = weights
            .iter()
            .zip(&variances)
            .map(|(w, v)| w * w * v)
            .sum::<f64>()
            .sqrt();
        for (j, (est, ..)) in Joint::ALL
            .iter()
            .zip(locals.iter_mut())
            .filter_map(|(j, l)| Some((j, l.as_mut()?)))
        {
            let Some(a) = est.axis else { continue };
            let t: Vec<f64> = est
                .cues
                .iter()
                .map(|(_, p)| (p - est.centre).dot(&a))
                .collect();
            if t.len() != weights.len() {
                continue;
            }
            let shift: f64 = t.iter().zip(&weights).map(|(t, w)| t * w).sum();
            est.centre += a * shift;
            (
                est.diagnostics.marker_radius_mean,
                est.diagnostics.marker_radius_sd,
            ) = marker_radii(&est.tracks, &est.centre);
            let mut rng = crate::rng::Rng::new(BOOTSTRAP_SEED).fork(j.name());
            for r in est.replicates.iter_mut().flatten() {
                *r += a * (shift + rng.gauss(0.0, level_sd));
            }
            est.diagnostics.level_sd_mm = Some(level_sd);
            est.diagnostics.level_cues = est
                .cues
                .iter()
                .zip(t.iter().zip(&weights))
                .map(|((name, _), (t, w))| {
                    (
                        name.clone(),
                        LevelCueOffset {
                            offset_mm: t - shift,
                            weight: *w,
                        },
                    )
                })
                .collect();
        }
    }
    let chains = chain_held_poses(
        &locals
            .iter()
            .map(|l| l.as_ref().and_then(|(_, _, _, held)| *held))
            .collect::<Vec<_>>(),
    );
    let mut joints = Vec::with_capacity(Joint::ALL.len());
    let mut warnings = Vec::new();
    let mut plates = Vec::new();
    let mut all_replicates: Vec<Vec<Option<Point>>> = Vec::new();
    for ((j, l), chain) in Joint::ALL.iter().zip(locals).zip(chains) {
        let (mut est, g, plate, _) = l.expect("every joint belongs to a trial");
        let chained = j.parent().is_some_and(|p| p != Joint::Wrist);
        // Into the global frame: through the held poses to the palm (a hinge's centre staying
        // level with its cues along the axis), then the trial's transform.
        let axis = est.axis;
        let carry = |c: Point| -> Point {
            let mut shift = Vec3::zeros();
            if chained {
                shift = chain * c - c;
                if let Some(a) = axis {
                    shift -= a * a.dot(&shift);
                }
            }
            g.apply(&(c + shift))
        };
        let replicates: Vec<Option<Point>> = est.replicates.iter().map(|r| r.map(&carry)).collect();
        let global = carry(est.centre);
        if chained {
            est.diagnostics.chain_shift_mm = Some((global - g.apply(&est.centre)).norm());
            if let Some(a) = est.axis {
                est.axis = Some((chain.rotation * a).normalize());
            }
        }
        est.diagnostics.centre_sd_mm = replicate_sd(&replicates);
        all_replicates.push(replicates);
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
            centre: global,
            axis: est.axis.map(|a| g.apply_vector(&a).normalize()),
            diagnostics: d,
        });
        plates.push(plate);
    }

    // The link lengths' uncertainties: per digit, the lengths between consecutive joints'
    // replicates of the same draw.
    let mut length_sd_mm = BTreeMap::new();
    for f in Finger::ALL {
        let js = f.joints();
        for k in 0..2 {
            let (a, b) = (js[k], js[k + 1]);
            let lengths: Vec<f64> = all_replicates[a.index()]
                .iter()
                .zip(&all_replicates[b.index()])
                .filter_map(|(p, q)| Some((p.as_ref()? - q.as_ref()?).norm()))
                .collect();
            let Some(sd) = sample_sd(&lengths) else {
                continue;
            };
            let name = format!("{}-{}", a.name(), b.name());
            if sd > MAX_LENGTH_SD_MM {
                warnings.push(format!(
                    "{} trial: link {name}: length uncertainty {sd:.2} mm (bootstrap SD) exceeds \
                     {MAX_LENGTH_SD_MM} mm; repeat the calibration motion",
                    joints[b.index()].diagnostics.trial
                ));
            }
            length_sd_mm.insert(name, sd);
        }
    }

    // Fingertips: the nail landmarks stand in for the ends of the distal links.
    let mut tips = [Point::origin(); 5];
    for f in Finger::ALL {
        tips[f as usize] = landmark(f.nail_marker())?;
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
        length_sd_mm,
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

/// The standard error of the mean level of `cues` along `axis`: their projections' sample SD
/// over the square root of their number; with fewer than two cues, [`LANDMARK_SD_MM`] (one
/// landmark placed by palpation) over the root of their number.
fn level_standard_error(cues: &[Point], axis: &Vec3) -> f64 {
    let n = cues.len();
    if n < 2 {
        return LANDMARK_SD_MM / (n.max(1) as f64).sqrt();
    }
    let t: Vec<f64> = cues.iter().map(|c| c.coords.dot(axis)).collect();
    let m = t.iter().sum::<f64>() / n as f64;
    let var = t.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
    (var / n as f64).sqrt()
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
            // 1-DOF: 5 mm since the simulator's seated postures scatter about the static one
            // (the distal centres are carried to the static trial by the proximal links' poses
            // in the seated second).
            let bound = if j.dof() == 3 { 2.5 } else { 5.0 };
            assert!(e.centre_mm < bound, "{}: {:.2} mm", e.joint, e.centre_mm);
            if let Some(a) = e.axis_deg {
                assert!(a < 4.0, "{}: {a:.2} deg", e.joint);
            }
        }
    }

    /// The index MCP-PIP and PIP-DIP lengths of the model of a typical seed-51 hand with 40 s
    /// trials, in the session and recording `repeat` and `trial_repeat`, and the true ones.
    fn index_lengths(repeat: u32, trial_repeat: u32) -> ([f64; 2], [f64; 2]) {
        let s = simulate(&SynthOptions {
            duration_s: Some(40.0),
            voxel_mm: 2.0,
            repeat,
            trial_repeat,
            ..SynthOptions::new(51, Preset::Typical)
        })
        .unwrap();
        let m = estimate_link_model_from(Side::Right, 0, &s.trials).unwrap();
        let t = |j: Joint| {
            let c = s.truth.joints[j.name()].centre;
            Point::new(c[0], c[1], c[2])
        };
        let c = |j: Joint| m.joints[j.index()].centre;
        let (a, b, d) = (Joint::IMcp, Joint::IPip, Joint::IDip);
        (
            [(c(b) - c(a)).norm(), (c(d) - c(b)).norm()],
            [(t(b) - t(a)).norm(), (t(d) - t(b)).norm()],
        )
    }

    /// Mean and sample SD.
    fn mean_sd(v: &[f64]) -> (f64, f64) {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64;
        (m, var.sqrt())
    }

    /// Five simulated sessions of one typical hand (new plates, noise, soft-tissue slide, gaps
    /// and static trial each time): the SD of the index link lengths. Re-attached plates are
    /// not what the seed paper (0.52 and 0.92 mm) and the goal (0.3 mm) measure (that is
    /// `index_link_lengths_repeat_over_trial_repeats`); the method reaches about 1.0 and 1.9 mm
    /// here (`reports/link-repeatability.md`): what remains is each placement's slide with the
    /// joints' own angles, which no motion tells from a shifted centre
    /// ([`super::super::sta_model`]). A regression guard at that level.
    #[test]
    fn index_link_lengths_are_repeatable() {
        let lengths: Vec<[f64; 2]> = (1..=5).map(|repeat| index_lengths(repeat, 0).0).collect();
        let sd = |k: usize| mean_sd(&lengths.iter().map(|l| l[k]).collect::<Vec<_>>()).1;
        let (sd1, sd2) = (sd(0), sd(1));
        eprintln!("index link length SD over 5 sessions: MCP-PIP {sd1:.3} mm, PIP-DIP {sd2:.3} mm; {lengths:?}");
        assert!(sd1 < 1.6 && sd2 < 2.4, "{sd1} {sd2}");
    }

    /// The repeatability: the index trial of one session recorded five times (the plates
    /// where they are; each take a new realisation of the motion, seating, drift, noise and
    /// gaps, `SynthOptions::trial_repeat`), as the seed paper measured it (0.52 and 0.92 mm):
    /// the SD of the MCP-PIP and PIP-DIP lengths is at most 0.3 mm, and their mean stays within
    /// the accuracy the method has against the truth. Without the proximal links' held
    /// reference poses (`held_reference_pose`) the SD is about 0.35 and 0.45 mm, from the noise
    /// of the plates' reference frame (`reports/link-repeatability.md`).
    #[test]
    fn index_link_lengths_repeat_over_trial_repeats() {
        let runs: Vec<([f64; 2], [f64; 2])> = (1..=5).map(|take| index_lengths(0, take)).collect();
        for (k, truth) in runs[0].1.into_iter().enumerate() {
            let (m, sd) = mean_sd(&runs.iter().map(|r| r.0[k]).collect::<Vec<_>>());
            eprintln!(
                "index link {k} over 5 trial repeats: {m:.2} ± {sd:.3} mm (truth {truth:.2})"
            );
            assert!(sd <= 0.3, "link {k}: SD {sd} mm");
            assert!((m - truth).abs() < 2.5, "link {k}: {m} vs {truth}");
        }
    }

    /// The chain composes the held poses of the joints between a joint and the palm, parent
    /// first, and is the identity for the joints on the palm and forearm.
    #[test]
    fn held_poses_chain_along_each_digit() {
        let mut held = vec![None; Joint::ALL.len()];
        let turn = |deg: f64, x: f64| {
            Some(Isometry3::new(
                Vec3::new(x, 0.0, 0.0),
                Vec3::z() * deg.to_radians(),
            ))
        };
        held[Joint::Wrist.index()] = turn(30.0, 100.0);
        held[Joint::IMcp.index()] = turn(90.0, 0.0);
        held[Joint::IPip.index()] = turn(0.0, 1.0);
        held[Joint::TCmc.index()] = turn(0.0, 8.0);
        let c = chain_held_poses(&held);
        let at = |j: Joint| c[j.index()] * Point::new(1.0, 0.0, 0.0);
        let near = |p: Point, q: [f64; 3]| (p - Point::new(q[0], q[1], q[2])).norm() < 1e-12;
        assert!(near(at(Joint::Wrist), [1.0, 0.0, 0.0]));
        assert!(near(at(Joint::IMcp), [1.0, 0.0, 0.0]));
        assert!(near(at(Joint::IPip), [0.0, 1.0, 0.0]));
        // The PIP's shift is applied in the proximal link's coordinates, then the MCP's turn.
        assert!(near(at(Joint::IDip), [0.0, 2.0, 0.0]));
        assert!(near(at(Joint::TIp), [9.0, 0.0, 0.0]));
        assert!(near(at(Joint::MDip), [1.0, 0.0, 0.0]));
    }

    /// Held still at the reference frame, the held pose is the mean of the child's poses until
    /// the motion starts; a child that turns at once has none.
    #[test]
    fn held_reference_pose_averages_the_still_frames() {
        let still = |k: usize| {
            Isometry3::new(
                Vec3::new(if k.is_multiple_of(2) { 0.1 } else { -0.1 }, 0.2, 0.0),
                Vec3::x() * 0.01f64.to_radians(),
            )
        };
        let mut poses: Vec<Option<Isometry3<f64>>> = (0..40).map(|k| Some(still(k))).collect();
        poses[5] = None;
        poses.extend(
            (0..200).map(|k| Some(Isometry3::rotation(Vec3::x() * (0.1 + k as f64 * 0.01)))),
        );
        let o = Point::origin();
        let h = held_reference_pose(&poses, 0, 100.0, &o).unwrap();
        // The first 99 frames (the gap skipped) turn, the first 49 too (their last fifth moves),
        // the first 24 are still: frames 0-24 without the gap at 5, 13 at +0.1 and 11 at -0.1.
        assert!((h.translation.vector - Vec3::new(0.2 / 24.0, 0.2, 0.0)).norm() < 1e-12);
        assert!((h.rotation.angle() - 0.01f64.to_radians()).abs() < 1e-12);
        assert!(held_reference_pose(&poses[40..], 0, 100.0, &o).is_none());
    }

    /// Ground truth on simulated typical sessions: where the soft-tissue model is fitted, its
    /// centres are about as close to the truth as the rigid estimators' (within 10 % on the
    /// mean), its diagnostics name the drivers, and the joints without a separable driver
    /// (wrist, DIPs, thumb IP in this protocol) keep the rigid estimators. Against the first
    /// capture model the soft-tissue model was the closer of the two; against the present one
    /// (plates that spin, seated postures off the static one) it is not (README, "Simulated
    /// subjects").
    #[test]
    fn soft_tissue_model_against_truth() {
        let (mut sta, mut rigid) = (Vec::new(), Vec::new());
        for repeat in 0..3 {
            let s = simulate(&SynthOptions {
                duration_s: Some(40.0),
                voxel_mm: 2.0,
                repeat,
                ..SynthOptions::new(41, Preset::Typical)
            })
            .unwrap();
            let m = estimate_link_model_from(Side::Right, 0, &s.trials).unwrap();
            for e in &m.joints {
                let d = &e.diagnostics;
                let t = s.truth.joints[e.joint.name()].centre;
                let t = Point::new(t[0], t[1], t[2]);
                let err = |name: &str| {
                    let p = d.alternatives[name];
                    let mut v = Point::new(p[0], p[1], p[2]) - t;
                    if let Some(a) = e.axis {
                        v -= a * a.dot(&v);
                    }
                    v.norm()
                };
                if e.joint == Joint::Wrist || e.joint.rank() == 2 {
                    assert!(d.sta.is_none(), "{}: {:?}", e.joint, d.sta);
                    assert!(!d.estimator.ends_with("-sta"));
                    continue;
                }
                let st = d.sta.as_ref().expect("a neighbour moved on its own");
                assert!(!st.drivers.is_empty(), "{}: {st:?}", e.joint);
                assert!(st.rms_mm <= st.rigid_rms_mm + 1e-9);
                assert_eq!(st.used, d.estimator.ends_with("-sta"));
                let (a, b) = if e.joint.dof() == 3 {
                    ("score-sta", "score")
                } else {
                    ("sara-sta", "sara")
                };
                sta.push(err(a));
                rigid.push(err(b));
            }
        }
        let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
        eprintln!(
            "soft-tissue model {:.3} mm, rigid {:.3} mm",
            mean(&sta),
            mean(&rigid)
        );
        assert!(mean(&sta) < 1.1 * mean(&rigid), "{sta:?} vs {rigid:?}");
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
