//! The template's posture fitted to the subject's link model before the landmark fit, so
//! that the fit starts from the subject's posture.
//!
//! A subject never holds the reference posture exactly like the template: fingers spread or
//! closed by 5-15°, flexed by up to 20°, the thumb higher or lower. Sumner & Popović's
//! correspondence energy (section 3.5 of the seed paper) explains a rotated finger as a sheared
//! one, so the fit first rotates the template's links through its own skeleton and skinning
//! weights, and the landmark fit is left to explain shape only.
//!
//! # Method
//! Joint angles `θ` of the template's skeleton (every joint but the wrist: the template is
//! already aligned on the palm markers, so the palm does not move) minimise, by
//! Levenberg-Marquardt with a forward-difference Jacobian,
//!
//! `Σ_j ‖u_j(θ) − û_j‖² + Σ_{j 1-DOF} ‖x_j(θ) − x̂_j‖² + λ² ‖θ‖²`
//!
//! * `u_j`: unit direction of the link distal to joint `j`, posed template; `û_j` the same on
//!   the subject. Each link gives two: from joint `j`'s dorsal marker to the next joint's (or to
//!   the nail), and, with weight [`CENTRE_DIRECTION_WEIGHT`], from the estimated centre of `j`
//!   to the next centre (or to the nail marker). Directions, not positions: the subject's bones
//!   are longer or shorter than the template's, and that is shape. The template's markers move
//!   with its skin weights, as its skin will.
//! * `x_j`: the rotation axis of a 1-DOF joint; it fixes the axial rotation of the 3-DOF joint
//!   proximal to it (MCP, thumb CMC), which link directions alone leave free.
//! * `λ` ([`POSTURE_PRIOR`]) keeps an unobservable angle at the template's posture. A 3-DOF
//!   joint's axial rotation is observable only through a trusted hinge axis distal to it; with
//!   none (a small range of motion), its `λ` is [`AXIAL_PRIOR`], else the fit twists the bone
//!   by tens of degrees to explain a digit that points off the template's sideways (shape, which
//!   no hinge can follow) and the skinned template folds.
//!
//! The angles are then shrunk by [`POSTURE_DEADBAND_DEG`] toward the template's posture.
//!
//! All residuals are unit vectors differences, so one weight serves all: 1° of misfit costs
//! about 0.017 in every term.

use crate::anatomy::Joint;
use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use crate::skeleton::forward_kinematics::{blend_point, link_transforms, posed_skeleton};
use crate::skeleton::{Pose, Skeleton};
use nalgebra::{DMatrix, DVector, Isometry3};
use std::collections::BTreeMap;

/// `λ`, the pull of every angle toward the template's posture (per radian, against unit-vector
/// residuals): weak enough that a 20° posture is recovered to about 0.1°, strong enough to pin
/// a degree of freedom no residual sees.
pub(crate) const POSTURE_PRIOR: f64 = 0.01;

/// The pull toward the template's posture of a 3-DOF joint's axial rotation when no hinge axis
/// distal to it is trusted (per radian, as [`POSTURE_PRIOR`]): a twist then costs as much as a
/// misfit of the same angle in one link direction, so the fit no longer buys a few degrees of
/// direction with a large twist, and a digit whose links point off the template's sideways
/// keeps that as shape for the landmark fit.
pub(crate) const AXIAL_PRIOR: f64 = 1.0;

/// Every fitted angle is shrunk toward the template's posture by this much (soft threshold,
/// `θ ← sign θ · max(0, |θ| − δ)`), degrees: the estimate's noise floor. The link model's centres
/// and the markers over short distal phalanges (moved by a millimetre of skin) put a few
/// degrees of spurious posture on a subject held exactly like the template, and a fit started
/// from a posture a few degrees wrong ends further off than one started from the right posture
/// (README, "Skin": 0.77 against 0.49 mm mean on `typical-r1`), while real postures of 5-20°
/// keep all but 2° of their rotation, which the landmark fit absorbs.
pub(crate) const POSTURE_DEADBAND_DEG: f64 = 2.0;

/// Most Levenberg-Marquardt iterations.
const MAX_ITERATIONS: usize = 100;

/// Weight of the link directions taken from the estimated joint centres, relative to those
/// taken from the dorsal markers (1) and the 1-DOF axes (1). The centres are a millimetre or
/// two off (a few degrees over a phalanx); the markers a fifth of that.
pub(crate) const CENTRE_DIRECTION_WEIGHT: f64 = 0.3;

/// A landmark marker of the template, as it moves when the template is posed.
#[derive(Clone, Debug)]
pub struct SkinnedMarker {
    /// Marker centre in the reference posture (vertex plus marker radius along its normal).
    pub position: Point,
    /// The landmark vertex's skin weights over [`crate::anatomy::Link::ALL`].
    pub weights: Vec<(usize, f64)>,
}

/// What the template's posture is fitted to, in the reference frame.
#[derive(Clone, Debug)]
pub struct PostureTargets<'a> {
    /// The subject's estimated link model.
    pub subject: &'a Skeleton,
    /// The subject's landmark markers by name: at least every joint's (named after it) and the
    /// five nails.
    pub subject_markers: BTreeMap<String, Point>,
    /// The same markers on the template, in the frame of the template skeleton given to
    /// [`fit_posture`].
    pub template_markers: BTreeMap<String, SkinnedMarker>,
    /// Per joint ([`Joint::index`]): whether the link model trusts its estimate (no warning:
    /// enough range of motion, a well-conditioned fit). An untrusted joint's centre and axis
    /// are left out of the fit, and only the markers orient its link: a hinge axis estimated
    /// from too little motion can swing the proximal MCP's abduction by 10° and more.
    pub reliable: [bool; 16],
}

/// The fitted posture of the template.
#[derive(Clone, Debug)]
pub struct PostureFit {
    /// Joint angles relative to the template's reference posture (the wrist stays at zero).
    pub pose: Pose,
    /// Rigid motion of every link ([`crate::anatomy::Link::index`]) for `pose`.
    pub transforms: Vec<Isometry3<f64>>,
    /// The template skeleton in that posture.
    pub skeleton: Skeleton,
    /// Per joint: angle between the posed template's link direction and the subject's, from the
    /// dorsal markers, degrees.
    pub direction_residual_deg: BTreeMap<String, f64>,
    /// Per 1-DOF joint: angle between the posed template's axis and the subject's, degrees.
    pub axis_residual_deg: BTreeMap<String, f64>,
    /// Levenberg-Marquardt iterations used.
    pub iterations: usize,
}

/// The unknowns: (joint, degree of freedom) for every joint but the wrist.
fn unknowns() -> Vec<(Joint, usize)> {
    Joint::ALL
        .iter()
        .filter(|&&j| j != Joint::Wrist)
        .flat_map(|&j| (0..j.dof()).map(move |d| (j, d)))
        .collect()
}

fn pose_of(params: &[f64], unknowns: &[(Joint, usize)]) -> Pose {
    let mut pose = Pose::zero();
    for (&(j, d), &a) in unknowns.iter().zip(params) {
        pose.angles[j.index()][d] = a;
    }
    pose
}

/// The marker at the distal end of joint `j`'s link: the next joint's, or the nail.
fn distal_marker(j: Joint) -> String {
    let f = j.finger().expect("wrist excluded");
    match j.rank() {
        2 => f.nail_marker().to_string(),
        r => f.joints()[r + 1].name().to_string(),
    }
}

/// The point at the distal end of joint `j`'s link in a skeleton: the next joint's centre, or
/// (last link) the nail marker.
fn distal_centre(sk: &Skeleton, j: Joint, nail: Point) -> Point {
    let f = j.finger().expect("wrist excluded");
    match j.rank() {
        2 => nail,
        r => sk.centre(f.joints()[r + 1]),
    }
}

/// Per joint but the wrist: marker direction, centre direction and (1-DOF) axis.
type Features = Vec<(Joint, Vec3, Vec3, Option<Vec3>)>;

fn skinned(m: &SkinnedMarker, tf: &[Isometry3<f64>]) -> Point {
    blend_point(&m.position, &m.weights, tf)
}

/// The features of the posed template.
fn features(
    template: &Skeleton,
    markers: &BTreeMap<String, SkinnedMarker>,
    tf: &[Isometry3<f64>],
) -> Features {
    Joint::ALL
        .iter()
        .filter(|&&j| j != Joint::Wrist)
        .map(|&j| {
            let mj = skinned(&markers[j.name()], tf);
            let md = skinned(&markers[&distal_marker(j)], tf);
            let c = tf[j.parent_link().index()] * template.centre(j);
            let e = match j.rank() {
                2 => md,
                _ => tf[j.child_link().index()] * distal_centre(template, j, md),
            };
            let x = (j.dof() == 1)
                .then(|| tf[j.parent_link().index()].rotation * template.joint(j).x());
            (j, (md - mj).normalize(), (e - c).normalize(), x)
        })
        .collect()
}

/// Fit the template's joint angles to the subject's link directions and 1-DOF axes (module
/// documentation). `template` must already be in the subject's reference frame (pre-aligned on
/// the palm markers), as must `targets.template_nails`.
///
/// Errors: a subject link of zero length (two estimated centres, or a centre and a nail marker,
/// coincide), or a non-finite input.
pub fn fit_posture(template: &Skeleton, targets: &PostureTargets) -> Result<PostureFit> {
    let unk = unknowns();
    let sub = targets.subject;
    for j in Joint::ALL.iter().filter(|&&j| j != Joint::Wrist) {
        for n in [j.name().to_string(), distal_marker(*j)] {
            if !targets.subject_markers.contains_key(&n)
                || !targets.template_markers.contains_key(&n)
            {
                return Err(Error::invalid(format!(
                    "posture fit: marker {n} is missing from the targets"
                )));
            }
        }
    }
    let unit = |d: Vec3, what: &str| -> Result<Vec3> {
        d.try_normalize(1e-9)
            .filter(|u| u.iter().all(|c| c.is_finite()))
            .ok_or_else(|| {
                Error::invalid(format!(
                    "posture fit: {what} has zero or non-finite length (two points coincide)"
                ))
            })
    };
    // Targets, once.
    let mut goal: Vec<(Vec3, Option<Vec3>, Option<Vec3>)> = Vec::new();
    for &j in Joint::ALL.iter().filter(|&&j| j != Joint::Wrist) {
        let dm = targets.subject_markers[&distal_marker(j)];
        let um = unit(
            dm - targets.subject_markers[j.name()],
            &format!("the subject's markers of the link distal to joint {j}"),
        )?;
        let uc = unit(
            distal_centre(sub, j, dm) - sub.centre(j),
            &format!("the subject's link distal to joint {j}"),
        )?;
        let x = (j.dof() == 1 && targets.reliable[j.index()]).then(|| {
            let xs = sub.joint(j).x();
            // Axis signs are a convention of each skeleton; align them to the template's.
            if xs.dot(&template.joint(j).x()) < 0.0 {
                -xs
            } else {
                xs
            }
        });
        // An untrusted centre (its own or the next one) gives no direction.
        let next_ok = match j.rank() {
            2 => true,
            r => targets.reliable[j.finger().expect("digit").joints()[r + 1].index()],
        };
        let uc = (targets.reliable[j.index()] && next_ok).then_some(uc);
        goal.push((um, uc, x));
    }
    // A 3-DOF joint's axial rotation is seen only through a hinge axis distal to it; with none
    // of them trusted, link directions along a nearly straight digit leave it free, and the fit
    // can twist the bone by tens of degrees to gain a few degrees of direction elsewhere.
    let prior: Vec<f64> = unk
        .iter()
        .map(|&(j, d)| {
            let axis_seen = || {
                j.finger().is_some_and(|f| {
                    f.joints().iter().any(|&k| {
                        k.rank() > j.rank() && k.dof() == 1 && targets.reliable[k.index()]
                    })
                })
            };
            if j.dof() == 3 && d == 2 && !axis_seen() {
                AXIAL_PRIOR
            } else {
                POSTURE_PRIOR
            }
        })
        .collect();
    let residuals = |params: &[f64]| -> DVector<f64> {
        let tf = link_transforms(template, &pose_of(params, &unk));
        let feats = features(template, &targets.template_markers, &tf);
        let mut r = Vec::with_capacity(feats.len() * 9 + params.len());
        for ((_, um, uc, x), (gm, gc, gx)) in feats.iter().zip(&goal) {
            r.extend((um - gm).iter());
            // Untrusted terms stay in the vector as zeros, so its length never changes.
            match gc {
                Some(gc) => r.extend((uc - gc).iter().map(|v| v * CENTRE_DIRECTION_WEIGHT)),
                None => r.extend([0.0; 3]),
            }
            match (x, gx) {
                (Some(x), Some(gx)) => r.extend((x - gx).iter()),
                (Some(_), None) => r.extend([0.0; 3]),
                _ => {}
            }
        }
        r.extend(params.iter().zip(&prior).map(|(a, w)| w * a));
        DVector::from_vec(r)
    };

    let n = unk.len();
    let mut params = vec![0.0; n];
    let mut r = residuals(&params);
    let mut cost = r.norm_squared();
    let mut lambda = 1e-3;
    let mut iterations = 0;
    while iterations < MAX_ITERATIONS {
        iterations += 1;
        let h = 1e-7;
        let mut jac = DMatrix::zeros(r.len(), n);
        for k in 0..n {
            let mut p = params.clone();
            p[k] += h;
            let rk = residuals(&p);
            jac.set_column(k, &((rk - &r) / h));
        }
        let jt = jac.transpose();
        let g = &jt * &r;
        let hess = &jt * &jac;
        let mut improved = false;
        for _ in 0..20 {
            let mut a = hess.clone();
            for k in 0..n {
                a[(k, k)] += lambda * (hess[(k, k)] + 1e-9);
            }
            let Some(step) = a.cholesky().map(|c| c.solve(&(-&g))) else {
                lambda *= 10.0;
                continue;
            };
            let trial: Vec<f64> = params.iter().zip(step.iter()).map(|(p, s)| p + s).collect();
            let rt = residuals(&trial);
            let ct = rt.norm_squared();
            if ct < cost {
                let small = step.amax() < 1e-10;
                params = trial;
                r = rt;
                cost = ct;
                lambda = (lambda / 3.0).max(1e-12);
                improved = !small;
                break;
            }
            lambda *= 4.0;
        }
        if !improved {
            break;
        }
    }

    // Soft threshold at the noise floor (module documentation).
    let dead = POSTURE_DEADBAND_DEG.to_radians();
    for p in params.iter_mut() {
        *p = p.signum() * (p.abs() - dead).max(0.0);
    }
    let pose = pose_of(&params, &unk);
    let tf = link_transforms(template, &pose);
    let feats = features(template, &targets.template_markers, &tf);
    let angle = |a: &Vec3, b: &Vec3| a.angle(b).to_degrees();
    let mut direction_residual_deg = BTreeMap::new();
    let mut axis_residual_deg = BTreeMap::new();
    for ((j, um, _, x), (gm, _, gx)) in feats.iter().zip(&goal) {
        direction_residual_deg.insert(j.name().to_string(), angle(um, gm));
        if let (Some(x), Some(gx)) = (x, gx) {
            axis_residual_deg.insert(j.name().to_string(), angle(x, gx));
        }
    }
    Ok(PostureFit {
        skeleton: posed_skeleton(template, &tf),
        pose,
        transforms: tf,
        direction_residual_deg,
        axis_residual_deg,
        iterations,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::{Finger, Side};
    use crate::template::load_template;

    /// The template's joint and nail markers, as the skin stage builds them.
    fn markers(t: &crate::template::TemplateHand) -> BTreeMap<String, SkinnedMarker> {
        let normals = t.mesh.vertex_normals();
        t.spec
            .landmarks
            .iter()
            .map(|(n, &v)| {
                (
                    n.clone(),
                    SkinnedMarker {
                        position: t.mesh.vertices[v] + normals[v] * 4.0,
                        weights: t.weights[v].clone(),
                    },
                )
            })
            .collect()
    }

    /// Posing the template by known angles and fitting its own posed skeleton recovers the
    /// angles (the prior biases them by far less than a tenth of a degree).
    #[test]
    fn recovers_a_known_posture() {
        let t = load_template(Side::Right).unwrap();
        let mut truth = Pose::zero();
        for (k, f) in Finger::ALL[1..].iter().enumerate() {
            let [mcp, pip, dip] = f.joints();
            let s = if k % 2 == 0 { 1.0 } else { -1.0 };
            truth = truth
                .with_deg(mcp, [12.0 + 2.0 * k as f64, s * 9.0, s * 4.0])
                .with_deg(pip, [15.0 - k as f64, 0.0, 0.0])
                .with_deg(dip, [6.0, 0.0, 0.0]);
        }
        truth = truth
            .with_deg(Joint::TCmc, [-14.0, 12.0, 5.0])
            .with_deg(Joint::TMcp, [8.0, 0.0, 0.0])
            .with_deg(Joint::TIp, [10.0, 0.0, 0.0]);
        let tf = link_transforms(&t.skeleton, &truth);
        let subject = posed_skeleton(&t.skeleton, &tf);
        let tm = markers(&t);
        let sm = tm
            .iter()
            .map(|(n, m)| (n.clone(), skinned(m, &tf)))
            .collect();
        let fit = fit_posture(
            &t.skeleton,
            &PostureTargets {
                subject: &subject,
                subject_markers: sm,
                template_markers: tm,
                reliable: [true; 16],
            },
        )
        .unwrap();
        for j in Joint::ALL {
            for d in 0..j.dof() {
                let (a, b) = (
                    fit.pose.angles[j.index()][d].to_degrees(),
                    truth.angles[j.index()][d].to_degrees(),
                );
                // The dead band shrinks every angle by up to its width.
                let expect = b.signum() * (b.abs() - POSTURE_DEADBAND_DEG).max(0.0);
                assert!(
                    (a - expect).abs() < 0.2,
                    "{j} dof {d}: fitted {a:.3}, expected {expect:.3}"
                );
            }
        }
        // Up to three shrunk joints along a digit: at most 2 x 3 dead bands of residual direction.
        assert!(fit
            .direction_residual_deg
            .values()
            .all(|r| *r < 6.0 * POSTURE_DEADBAND_DEG));
    }

    /// The template's posture fitted to its own skeleton with the subject markers `sm`.
    fn fit_to_itself(
        t: &crate::template::TemplateHand,
        sm: BTreeMap<String, Point>,
        tm: BTreeMap<String, SkinnedMarker>,
        reliable: [bool; 16],
    ) -> PostureFit {
        fit_posture(
            &t.skeleton,
            &PostureTargets {
                subject: &t.skeleton,
                subject_markers: sm,
                template_markers: tm,
                reliable,
            },
        )
        .unwrap()
    }

    /// A thumb whose distal phalanx points sideways (shape: its IP and nail markers moved along
    /// the hinge axes, where no hinge of the thumb can follow), with the thumb's hinge axes
    /// untrusted as after a small range of motion: the metacarpal is not twisted to explain it.
    /// With the common prior alone the fit twists it by tens of degrees and flexes the IP to
    /// swing the nail sideways.
    #[test]
    fn an_untrusted_thumb_is_not_twisted_to_explain_its_shape() {
        let t = load_template(Side::Right).unwrap();
        let tm = markers(&t);
        let mut sm: BTreeMap<String, Point> =
            tm.iter().map(|(n, m)| (n.clone(), m.position)).collect();
        let side = t.skeleton.joint(Joint::TIp).x();
        for (n, mm) in [("T_IP", 4.0), ("T_NAIL", 12.0)] {
            *sm.get_mut(n).unwrap() += side * mm;
        }
        let mut reliable = [true; 16];
        reliable[Joint::TMcp.index()] = false;
        reliable[Joint::TIp.index()] = false;
        let fit = fit_to_itself(&t, sm, tm, reliable);
        let twist = fit.pose.angles[Joint::TCmc.index()][2].to_degrees();
        let ip = fit.pose.angles[Joint::TIp.index()][0].to_degrees();
        assert!(twist.abs() < 10.0, "metacarpal twisted {twist:.1}°");
        assert!(ip.abs() < 10.0, "IP flexed {ip:.1}°");
        // The fingers, whose markers did not move, stay put.
        for f in &Finger::ALL[1..] {
            for j in f.joints() {
                assert!(fit.pose.angles[j.index()].iter().all(|a| a.abs() < 1e-6));
            }
        }
    }

    /// The template fitted to itself stays in its posture.
    #[test]
    fn template_to_itself_is_the_identity() {
        let t = load_template(Side::Left).unwrap();
        let tm = markers(&t);
        let sm = tm.iter().map(|(n, m)| (n.clone(), m.position)).collect();
        let fit = fit_to_itself(&t, sm, tm, [true; 16]);
        assert!(fit.pose.angles.iter().flatten().all(|a| a.abs() < 1e-9));
    }
}
