//! Joint centres with a linear model of the soft-tissue artefact (STA) of both marker clusters
//! (beyond the seed paper).
//!
//! SCoRE ([`super::functional::score_centre`]) assumes the joint centre is fixed in both
//! segments' marker (technical) frames. Marker plates on fingers and skin markers on the palm
//! slide over the bone as the joints flex, so the centre seen from each cluster moves with the
//! joint angles; every rigid-cluster estimator is biased by that, and by a different amount in
//! every session (new plates), which is what spoils the repeatability of link lengths.
//!
//! The model. The rigid component of a cluster's artefact is, to first order, a linear function
//! of the angles of the joints the segment spans: Camomilla, Cereatti, Chèze & Cappozzo (2013),
//! "A hip joint kinematics driven model for the generation of realistic thigh soft tissue
//! artefacts", J. Biomech. 46(3):625-630 (thigh cluster displacement linear in the hip angles);
//! Cappello, Cappozzo, La Palombara, Lucchetti & Leardini (1997), "Multiple anatomical landmark
//! calibration for optimal bone pose estimation", Hum. Mov. Sci. 16:259-274, and Cappello,
//! Stagni, Fantozzi & Leardini (2005), "Soft tissue artifact compensation in knee kinematics by
//! double anatomical landmark calibration", IEEE TBME 52(6):992-998 (landmarks in the cluster
//! frame interpolated linearly in the joint angle between calibrated postures); and Andersen,
//! Benoit, Damsgaard, Ramsey & Rasmussen (2010), "Do kinematic models reduce the effects of soft
//! tissue artefacts in skin marker-based motion analysis? An in vivo study of knee kinematics",
//! J. Biomech. 43(2):268-273 (a fixed joint centre alone does not remove STA). Here the centre in
//! each cluster's frame is allowed to move linearly with the driver angles theta(t) (zero at the
//! trial's reference frame):
//!
//! ```text
//! T_p(t) (c_p + E theta(t))  =  T_c(t) (c_c + D theta(t))      for every frame t,
//! ```
//!
//! solved by linear least squares in (c_p, c_c, E, D) once the poses T(t) and the angles theta(t)
//! come from the registrations ([`score_sta`]). With no drivers it *is* SCoRE's system. A rigid
//! slide of a cluster does not change its registered rotation, so the angles are unbiased by it.
//!
//! Assumptions (documented for real data): the artefact's rigid part is linear in the drivers
//! over the trial (no hysteresis, no dependence on velocity or muscle activity); its non-rigid
//! part is small (it only adds noise to the registrations); the drivers are the angles of the
//! joints at both ends of the two segments (the skin over a phalanx is pulled over both
//! knuckles), measured relative to the reference frame.
//!
//! Identifiability (measured on the `validation/` phantoms; README, "Link model"). A slide that
//! follows the joint's *own* angle is kinematically a shifted centre: to first order in the
//! angle, `(I - R) c` and `E theta - R D theta` are both linear in the rotation vector, so with
//! both clusters sliding the centre is only determined by third-order (curvature) terms of the
//! motion. Over a finger's 70-100° that direction is about 300 times weaker than the others,
//! and the small bias that rotation noise puts into the regressors (errors in variables: 1° of
//! registration noise shrinks `E[R]` by 1.5e-4) is amplified into centres 15-20 mm off on the
//! `typical` phantoms. No ridge weight helps: one strong enough to stop that gives back the rigid
//! estimate. So the model's drivers are only the *neighbouring* joints' angles that moved
//! separately from the joint's own (see `separable_drivers` in [`super::model`]): their slides
//! are seen in frames where the joint itself does not rotate and are not confounded with its
//! centre. Along a hinge's axis the centre is not determined at all. Safeguards: a Gaussian
//! prior on the slides (ridge regression, [`PRIOR_SLIDE_MM_PER_RAD`]), which leaves
//! well-determined directions alone and pulls undetermined ones (e.g. a common slide of both
//! clusters seen only through the difference) to "no slide", and the predicted standard
//! deviation of the centre (`centre_sd_mm`, from the regularised normal matrix and the fit's
//! residual), which the caller compares with a threshold before trusting the estimate (see
//! [`super::model::choose`]). The exact null direction of a hinge (along its axis) is left out
//! of both the solution (minimum norm) and `centre_sd_mm`.

use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, SymmetricEigen};

/// Prior SD of a cluster's slide per radian of a driver angle, mm/rad (the ridge of
/// [`score_sta`]): about 3 mm over a 60° motion, a few millimetres being what marker plates and
/// skin markers over a flexing joint slide (thigh clusters, over larger motions and more soft
/// tissue, reach 10-30 mm: Camomilla et al. 2013). Only directions the data do not determine
/// feel it; it was not tuned on the phantoms.
pub const PRIOR_SLIDE_MM_PER_RAD: f64 = 3.0;

/// Floor of the residual SD used to weigh the prior, mm: clean data (residual 0) would otherwise
/// make the ridge vanish and near-null directions unstable.
const MIN_RESIDUAL_SD_MM: f64 = 0.01;

/// Which clusters' slides the model has (the constants are always there).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StaTerms {
    /// The parent cluster's slide (E).
    pub parent: bool,
    /// The child cluster's slide (D).
    pub child: bool,
}

impl StaTerms {
    /// Both clusters slide.
    pub const BOTH: StaTerms = StaTerms {
        parent: true,
        child: true,
    };
    /// Only the child's cluster slides with this driver (e.g. a joint at the child segment's
    /// far end; the cluster of the other segment does not span it).
    pub const CHILD: StaTerms = StaTerms {
        parent: false,
        child: true,
    };
    /// Only the parent's cluster slides with this driver.
    pub const PARENT: StaTerms = StaTerms {
        parent: true,
        child: false,
    };
}

/// A joint centre estimated with the linear soft-tissue artefact model.
#[derive(Clone, Debug, PartialEq)]
pub struct StaFit {
    /// The centre in the parent's local coordinates at zero driver angles, c_p, mm.
    pub parent_local: Point,
    /// The centre in the child's local coordinates at zero driver angles, c_c, mm.
    pub child_local: Point,
    /// Per driver, how the centre moves in the parent's local frame, mm per unit of the driver
    /// (the negative of the parent cluster's slide): the columns of E.
    pub parent_slide: Vec<Vec3>,
    /// Per driver, the same in the child's local frame: the columns of D.
    pub child_slide: Vec<Vec3>,
    /// Root mean square over frames of the residual of the model, mm.
    pub rms: f64,
    /// Root mean square of the rigid (SCoRE) residual at the same frames, mm, for comparison.
    pub rigid_rms: f64,
    /// Predicted standard deviation of `parent_local` in its worst direction (apart from the
    /// free axis, if any), mm: residual SD times the root of the largest eigenvalue of that
    /// block of the inverse regularised normal matrix.
    pub centre_sd_mm: f64,
    /// Number of frames.
    pub n_frames: usize,
}

/// Joint centre by SCoRE with a linear soft-tissue artefact model of both clusters (module doc).
///
/// * `parent`, `child`: segment poses (local -> world) per frame, as for
///   [`super::functional::score_centre`].
/// * `drivers[t]`: the driver angles at frame t (radians, zero at the reference frame), the
///   same number `m` for every frame; `m = 0` gives SCoRE's solution.
/// * `free_axis`: for a hinge, its unit axis in the parent's local frame; the centre's component
///   along it is not determined (minimum-norm solution) and not counted in `centre_sd_mm`.
/// * `slides`: per driver, which clusters slide with it (the others' slides are zero).
/// * `prior_slide`: prior SD of the slides, mm per unit of a driver ([`PRIOR_SLIDE_MM_PER_RAD`]
///   for angles in radians); `f64::INFINITY` for no prior (plain least squares).
///
/// The normal equations (size 6 + 6m) are accumulated in one O(n m^2) pass from the Kronecker
/// structure `A_t = [R_p ⊗ phi^T, -R_c ⊗ phi^T]`, `phi = (1, theta)`, and solved by a symmetric
/// eigen-decomposition (pseudo-inverse below 1e-12 of the largest eigenvalue).
///
/// Errors (one line): different lengths, fewer frames than unknowns, non-finite input, or a
/// system that determines nothing.
pub fn score_sta(
    parent: &[Isometry3<f64>],
    child: &[Isometry3<f64>],
    drivers: &[Vec<f64>],
    free_axis: Option<Vec3>,
    slides: &[StaTerms],
    prior_slide: f64,
) -> Result<StaFit> {
    const WHAT: &str = "SCoRE with soft-tissue model";
    let n = parent.len();
    if child.len() != n || drivers.len() != n {
        return Err(Error::invalid(format!(
            "{WHAT}: {} parent poses, {} child poses and {} driver rows; pass the same frames",
            n,
            child.len(),
            drivers.len()
        )));
    }
    let m = drivers.first().map_or(0, Vec::len);
    if slides.len() != m {
        return Err(Error::invalid(format!(
            "{WHAT}: {} slide terms for {m} drivers",
            slides.len()
        )));
    }
    let q = m + 1;
    let k = 6 * q;
    if prior_slide.is_nan() || prior_slide <= 0.0 {
        return Err(Error::invalid(format!(
            "{WHAT}: the prior SD of the slides must be positive, got {prior_slide}"
        )));
    }
    if n < k + 2 {
        return Err(Error::invalid(format!(
            "{WHAT}: {n} frames for {k} unknowns; record a longer trial"
        )));
    }
    let finite_pose = |p: &Isometry3<f64>| {
        p.translation.vector.iter().all(|x| x.is_finite())
            && p.rotation.coords.iter().all(|x| x.is_finite())
    };
    for (t, ((row, p), c)) in drivers.iter().zip(parent).zip(child).enumerate() {
        if row.len() != m || row.iter().any(|x| !x.is_finite()) {
            return Err(Error::invalid(format!(
                "{WHAT}: driver row {t} has {} values (expected {m}) or is not finite",
                row.len()
            )));
        }
        if !finite_pose(p) || !finite_pose(c) {
            return Err(Error::invalid(format!(
                "{WHAT}: pose at frame {t} is not finite"
            )));
        }
    }
    // Unknown order: parent block (3 x q, column-major: component fastest), then child block.
    // Residual r_t = R_p U_p phi - R_c U_c phi - (t_c - t_p).
    let mut pp = DMatrix::<f64>::zeros(q, q); // sum phi phi^T
    let mut cross = vec![Matrix3::<f64>::zeros(); q * q]; // sum phi_a phi_b R_p^T R_c
    let mut gp = DMatrix::<f64>::zeros(3, q);
    let mut gc = DMatrix::<f64>::zeros(3, q);
    let mut dd = 0.0;
    let mut phi = vec![1.0; q];
    for ((row, p), c) in drivers.iter().zip(parent).zip(child) {
        phi[1..].copy_from_slice(row);
        let rp: Matrix3<f64> = p.rotation.to_rotation_matrix().into_inner();
        let rc: Matrix3<f64> = c.rotation.to_rotation_matrix().into_inner();
        let mt = rp.transpose() * rc;
        let d = c.translation.vector - p.translation.vector;
        let (dp, dc) = (rp.transpose() * d, rc.transpose() * d);
        dd += d.norm_squared();
        for (a, &fa) in phi.iter().enumerate() {
            for (b, &fb) in phi.iter().enumerate() {
                pp[(a, b)] += fa * fb;
                cross[a * q + b] += mt * (fa * fb);
            }
            for (i, (&xp, &xc)) in dp.iter().zip(dc.iter()).enumerate() {
                gp[(i, a)] += xp * fa;
                gc[(i, a)] -= xc * fa;
            }
        }
    }
    let idx = |block: usize, comp: usize, a: usize| block * 3 * q + a * 3 + comp;
    let mut nm = DMatrix::<f64>::zeros(k, k);
    let mut g = DVector::<f64>::zeros(k);
    for a in 0..q {
        for b in 0..q {
            let c = &cross[a * q + b];
            for i in 0..3 {
                nm[(idx(0, i, a), idx(0, i, b))] += pp[(a, b)];
                nm[(idx(1, i, a), idx(1, i, b))] += pp[(a, b)];
                for jj in 0..3 {
                    nm[(idx(0, i, a), idx(1, jj, b))] -= c[(i, jj)];
                    nm[(idx(1, jj, b), idx(0, i, a))] -= c[(i, jj)];
                }
            }
        }
        for i in 0..3 {
            g[idx(0, i, a)] = gp[(i, a)];
            g[idx(1, i, a)] = gc[(i, a)];
        }
    }
    let rigid_fit = |x: &DVector<f64>| -> f64 {
        // Residual sum of squares from the normal equations: |Ax - d|^2 = x'Nx - 2g'x + d'd.
        (x.dot(&(&nm * x)) - 2.0 * g.dot(x) + dd).max(0.0)
    };
    // The rigid (SCoRE) solution on the constants alone, for the residual scale and comparison.
    let const_idx: Vec<usize> = (0..2)
        .flat_map(|b| (0..3).map(move |i| idx(b, i, 0)))
        .collect();
    let n6 = DMatrix::from_fn(6, 6, |r, c| nm[(const_idx[r], const_idx[c])]);
    let g6 = DVector::from_fn(6, |r, _| g[const_idx[r]]);
    let x6 = pseudo_solve(&n6, &g6).ok_or_else(|| {
        Error::invalid(format!(
            "{WHAT}: the relative motion does not determine a centre (no rotation between the \
             segments)"
        ))
    })?;
    let mut x_rigid = DVector::zeros(k);
    for (r, &i) in const_idx.iter().enumerate() {
        x_rigid[i] = x6[r];
    }
    let rigid_ss = rigid_fit(&x_rigid);
    let rigid_rms = (rigid_ss / n as f64).sqrt();
    // Ridge on the slides: weight sigma^2 / prior^2 per coefficient, sigma from the rigid fit
    // per coordinate (an upper bound of the model's residual, so the prior is, if anything, too
    // weak rather than too strong where the data speak).
    let sigma = (rigid_ss / (3 * n).saturating_sub(6).max(1) as f64)
        .sqrt()
        .max(MIN_RESIDUAL_SD_MM);
    let lambda = (sigma / prior_slide).powi(2);
    // The unknowns in the model: the constants, and the slides of the clusters in `terms`.
    let active: Vec<usize> = (0..k)
        .filter(|&u| {
            let (block, a) = (u / (3 * q), (u % (3 * q)) / 3);
            a == 0 || (block == 0 && slides[a - 1].parent) || (block == 1 && slides[a - 1].child)
        })
        .collect();
    let ka = active.len();
    let mut nr = DMatrix::from_fn(ka, ka, |r, c| nm[(active[r], active[c])]);
    let ga = DVector::from_fn(ka, |r, _| g[active[r]]);
    for (r, &u) in active.iter().enumerate() {
        if (u % (3 * q)) / 3 > 0 {
            nr[(r, r)] += lambda;
        }
    }
    let eig = SymmetricEigen::new((&nr + nr.transpose()) * 0.5);
    let hi = eig.eigenvalues.max();
    if !(hi > 0.0 && hi.is_finite()) {
        return Err(Error::invalid(format!("{WHAT}: the system is empty")));
    }
    // Pseudo-inverse: the hinge's null direction (its axis in both frames) carries no
    // information and stays out of the solution and of the SD.
    let keep: Vec<usize> = (0..ka)
        .filter(|&i| eig.eigenvalues[i] >= hi * 1e-12)
        .collect();
    let solve = |rhs: &DVector<f64>| -> DVector<f64> {
        let mut y = DVector::zeros(ka);
        for &i in &keep {
            let v = eig.eigenvectors.column(i);
            y += v * (v.dot(rhs) / eig.eigenvalues[i]);
        }
        y
    };
    let mut xa = solve(&ga);
    // One step of iterative refinement: the slides' small eigenvalues amplify round-off.
    let r = &ga - &nr * &xa;
    xa += solve(&r);
    let mut x = DVector::zeros(k);
    for (r, &u) in active.iter().enumerate() {
        x[u] = xa[r];
    }
    // Inverse-normal block of c_p (without the free axis).
    let mut cov = Matrix3::<f64>::zeros();
    let cp_rows: Vec<usize> = (0..3)
        .map(|i| {
            active
                .iter()
                .position(|&u| u == idx(0, i, 0))
                .expect("constant")
        })
        .collect();
    for &i in &keep {
        let v = eig.eigenvectors.column(i);
        let vp = Vec3::new(v[cp_rows[0]], v[cp_rows[1]], v[cp_rows[2]]);
        let vp = match free_axis {
            Some(a) => vp - a * a.dot(&vp),
            None => vp,
        };
        cov += vp * vp.transpose() / eig.eigenvalues[i];
    }
    let ss = rigid_fit(&x);
    let rms = (ss / n as f64).sqrt();
    let dof = (3 * n).saturating_sub(ka).max(1) as f64;
    let resid_sd = (ss / dof).sqrt();
    let centre_sd_mm = resid_sd * cov.symmetric_eigenvalues().max().max(0.0).sqrt();
    let col = |b: usize, a: usize| Vec3::new(x[idx(b, 0, a)], x[idx(b, 1, a)], x[idx(b, 2, a)]);
    let parent_local = Point::from(col(0, 0));
    let child_local = Point::from(col(1, 0));
    let fit = StaFit {
        parent_local,
        child_local,
        parent_slide: (1..q).map(|a| col(0, a)).collect(),
        child_slide: (1..q).map(|a| col(1, a)).collect(),
        rms,
        rigid_rms,
        centre_sd_mm,
        n_frames: n,
    };
    if !fit
        .parent_local
        .coords
        .iter()
        .chain(fit.child_local.coords.iter())
        .all(|v| v.is_finite())
    {
        return Err(Error::invalid(format!(
            "{WHAT}: the solution is not finite"
        )));
    }
    Ok(fit)
}

/// Minimum-norm solution of a symmetric positive semi-definite system (eigenvalues below 1e-10
/// of the largest dropped); `None` when nothing is determined.
fn pseudo_solve(n: &DMatrix<f64>, g: &DVector<f64>) -> Option<DVector<f64>> {
    let eig = SymmetricEigen::new((n + n.transpose()) * 0.5);
    let hi = eig.eigenvalues.max();
    if !(hi > 0.0 && hi.is_finite()) {
        return None;
    }
    let mut x = DVector::zeros(g.len());
    let mut used = 0;
    for (v, &l) in eig.eigenvectors.column_iter().zip(eig.eigenvalues.iter()) {
        if l >= hi * 1e-10 {
            x += v * (v.dot(g) / l);
            used += 1;
        }
    }
    (used >= 5).then_some(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::functional::{sara_axis, score_centre};
    use crate::rng::Rng;
    use nalgebra::{Translation3, UnitQuaternion};

    /// A joint whose centre moves linearly with the drivers in both segments' frames, exactly
    /// the module's model: parent poses wander about the lab; the child's pose relative to the
    /// parent is `rel[t] R0` with the translation that keeps
    /// `T_p (c_p + E theta) = T_c (c_c + D theta)`. Drivers: the rotation vector's components
    /// (3-DOF) or the hinge angle, plus one more angle that varies on its own.
    struct Case {
        parent: Vec<Isometry3<f64>>,
        child: Vec<Isometry3<f64>>,
        drivers: Vec<Vec<f64>>,
        c_p: Point,
        c_c: Point,
    }

    fn case(seed: u64, hinge: Option<Vec3>, e: &[Vec3], d: &[Vec3]) -> Case {
        let mut rng = Rng::new(seed);
        let n = 400;
        let c_p = Point::new(12.0, -5.0, 30.0);
        let c_c = Point::new(-3.0, 8.0, -25.0);
        let r0 = UnitQuaternion::from_euler_angles(0.2, -0.4, 1.1);
        let (mut parent, mut child, mut drivers) = (vec![], vec![], vec![]);
        for t in 0..n {
            let tp = Isometry3::from_parts(
                Translation3::new(
                    rng.range(200.0, 600.0),
                    rng.range(-300.0, 300.0),
                    rng.range(800.0, 1200.0),
                ),
                rng.rotation(),
            );
            let s = t as f64 / n as f64 * std::f64::consts::TAU * 3.0;
            let (rel, mut theta) = match hinge {
                Some(a) => {
                    let ang = 0.8 * (1.0 - s.cos());
                    (UnitQuaternion::from_scaled_axis(a * ang), vec![ang])
                }
                None => {
                    let w = Vec3::new(0.7 * (1.0 - s.cos()), 0.35 * s.sin(), 0.1 * (0.5 * s).sin());
                    (UnitQuaternion::from_scaled_axis(w), vec![w.x, w.y, w.z])
                }
            };
            // A neighbouring joint's angle, moving on its own schedule.
            theta.push(0.6 * (1.0 - (1.7 * s).cos()));
            let lin = |cols: &[Vec3]| -> Vec3 {
                cols.iter().zip(&theta).map(|(c, th)| c * *th).sum::<Vec3>()
            };
            let cp_t = c_p.coords + lin(e);
            let cc_t = c_c.coords + lin(d);
            let rot = rel * r0;
            let m = Isometry3::from_parts(Translation3::from(cp_t - rot * cc_t), rot);
            parent.push(tp);
            child.push(tp * m);
            drivers.push(theta);
        }
        Case {
            parent,
            child,
            drivers,
            c_p,
            c_c,
        }
    }

    #[test]
    fn ball_joint_with_linear_artefact_is_recovered_exactly() {
        let e = [
            Vec3::new(1.0, -0.5, 0.3),
            Vec3::new(-0.4, 0.8, 0.2),
            Vec3::new(0.3, 0.2, -0.6),
            Vec3::new(0.5, 0.0, 0.4),
        ];
        let d = [
            Vec3::new(-0.7, 0.2, 1.1),
            Vec3::new(0.3, 0.3, -0.2),
            Vec3::new(0.0, -0.9, 0.4),
            Vec3::new(-0.6, 0.5, 0.0),
        ];
        let c = case(3, None, &e, &d);
        let fit = score_sta(
            &c.parent,
            &c.child,
            &c.drivers,
            None,
            &[StaTerms::BOTH; 4],
            f64::INFINITY,
        )
        .unwrap();
        assert!(
            (fit.parent_local - c.c_p).norm() < 1e-8,
            "{:?}",
            fit.parent_local
        );
        assert!((fit.child_local - c.c_c).norm() < 1e-8);
        // (The slides themselves are determined only up to a common slide of both clusters
        // along the rotation vector, which R w = w makes invisible.)
        assert!(fit.rms < 1e-8);
        // The rigid SCoRE is biased by the same artefact.
        let rigid = score_centre(&c.parent, &c.child).unwrap();
        assert!((rigid.parent_local - c.c_p).norm() > 0.1);
        assert!(fit.rigid_rms > 0.1);
    }

    /// Only the child's cluster slides: the child-only model recovers everything exactly, and
    /// its default prior moves the centre by a few micrometres at most.
    #[test]
    fn child_only_artefact_is_recovered_exactly() {
        let d = [
            Vec3::new(-0.7, 0.2, 1.1),
            Vec3::new(0.3, 0.3, -0.2),
            Vec3::new(0.0, -0.9, 0.4),
            Vec3::new(-0.6, 0.5, 0.0),
        ];
        let c = case(8, None, &[Vec3::zeros(); 4], &d);
        let fit = score_sta(
            &c.parent,
            &c.child,
            &c.drivers,
            None,
            &[StaTerms::CHILD; 4],
            f64::INFINITY,
        )
        .unwrap();
        assert!((fit.parent_local - c.c_p).norm() < 1e-8);
        assert!((fit.child_local - c.c_c).norm() < 1e-8);
        for (k, (got, want)) in fit.child_slide.iter().zip(&d).enumerate() {
            assert!((got - want).norm() < 1e-7, "D[{k}]");
        }
        assert!(fit.parent_slide.iter().all(|s| *s == Vec3::zeros()));
        let reg = score_sta(
            &c.parent,
            &c.child,
            &c.drivers,
            None,
            &[StaTerms::CHILD; 4],
            PRIOR_SLIDE_MM_PER_RAD,
        )
        .unwrap();
        assert!((reg.parent_local - c.c_p).norm() < 0.01);
    }

    #[test]
    fn hinge_with_linear_artefact_is_recovered_off_its_axis() {
        let a = Vec3::new(0.2, 0.9, -0.3).normalize();
        // Slides with a component along the axis too (undetermined, like the centre's).
        let e = [Vec3::new(1.0, -0.5, 0.3), Vec3::new(0.5, 0.0, 0.4)];
        let d = [Vec3::new(-0.7, 0.2, 1.1), Vec3::new(0.0, -0.9, 0.4)];
        let c = case(4, Some(a), &e, &d);
        let fit = score_sta(
            &c.parent,
            &c.child,
            &c.drivers,
            Some(a),
            &[StaTerms::BOTH; 2],
            f64::INFINITY,
        )
        .unwrap();
        let off = |p: &Point| (p - c.c_p).cross(&a).norm();
        assert!(off(&fit.parent_local) < 1e-7, "{}", off(&fit.parent_local));
        assert!(fit.rms < 1e-8);
        let rigid = sara_axis(&c.parent, &c.child).unwrap();
        assert!(off(&rigid.point_parent_local) > 0.1);
    }

    /// Without artefact, the model's centre is SCoRE's (exactly, also with drivers present:
    /// the zero slides fit the data exactly, so the prior does not move them), and with no
    /// drivers at all the system is SCoRE's own.
    #[test]
    fn without_artefact_it_is_score() {
        let zero = [Vec3::zeros(); 4];
        let c = case(5, None, &zero, &zero);
        let score = score_centre(&c.parent, &c.child).unwrap();
        assert!((score.parent_local - c.c_p).norm() < 1e-9);
        let fit = score_sta(
            &c.parent,
            &c.child,
            &c.drivers,
            None,
            &[StaTerms::BOTH; 4],
            PRIOR_SLIDE_MM_PER_RAD,
        )
        .unwrap();
        assert!((fit.parent_local - score.parent_local).norm() < 1e-7);
        assert!(fit.parent_slide.iter().all(|s| s.norm() < 1e-6));
        // Real data with no drivers: SCoRE's system exactly, noise included.
        let mut rng = Rng::new(9);
        let noisy: Vec<_> = c
            .child
            .iter()
            .map(|p| {
                Isometry3::from_parts(
                    Translation3::from(p.translation.vector + rng.gauss3(0.3)),
                    p.rotation,
                )
            })
            .collect();
        let none: Vec<Vec<f64>> = vec![vec![]; c.parent.len()];
        let score = score_centre(&c.parent, &noisy).unwrap();
        let fit = score_sta(&c.parent, &noisy, &none, None, &[], PRIOR_SLIDE_MM_PER_RAD).unwrap();
        assert!((fit.parent_local - score.parent_local).norm() < 1e-9);
        assert!((fit.child_local - score.child_local).norm() < 1e-9);
        assert!((fit.rms - score.rms).abs() < 1e-9 && (fit.rigid_rms - fit.rms).abs() < 1e-9);
    }

    /// The predicted SD tracks the real scatter: over 40 noisy replicates of a ball joint with
    /// artefact, the centre's spread is within a factor of two of `centre_sd_mm`.
    #[test]
    fn centre_sd_predicts_the_scatter() {
        let e = [
            Vec3::new(1.0, -0.5, 0.3),
            Vec3::zeros(),
            Vec3::zeros(),
            Vec3::new(0.5, 0.0, 0.4),
        ];
        let d = [
            Vec3::new(-0.7, 0.2, 1.1),
            Vec3::zeros(),
            Vec3::zeros(),
            Vec3::zeros(),
        ];
        let c = case(6, None, &e, &d);
        let mut rng = Rng::new(10);
        let mut errs = Vec::new();
        let mut sds = Vec::new();
        for _ in 0..40 {
            let noisy: Vec<_> = c
                .child
                .iter()
                .map(|p| {
                    Isometry3::from_parts(
                        Translation3::from(p.translation.vector + rng.gauss3(0.2)),
                        p.rotation,
                    )
                })
                .collect();
            let fit = score_sta(
                &c.parent,
                &noisy,
                &c.drivers,
                None,
                &[StaTerms::BOTH; 4],
                PRIOR_SLIDE_MM_PER_RAD,
            )
            .unwrap();
            errs.push(fit.parent_local - c.c_p);
            sds.push(fit.centre_sd_mm);
        }
        // Largest per-axis RMS error against the mean predicted worst-direction SD.
        let worst = (0..3)
            .map(|i| (errs.iter().map(|e| e[i] * e[i]).sum::<f64>() / errs.len() as f64).sqrt())
            .fold(0.0, f64::max);
        let sd = sds.iter().sum::<f64>() / sds.len() as f64;
        assert!(
            worst < 2.0 * sd && worst > 0.25 * sd,
            "scatter {worst} vs predicted {sd}"
        );
    }

    /// Why the joint's own angle is not a driver: both clusters sliding with a hinge's angle
    /// look like a shifted centre, and 1° of registration noise (errors in the regressors) is
    /// enough to throw the model's centre far off, while the rigid fit stays within about the
    /// slide.
    #[test]
    fn own_angle_slides_are_confounded_with_the_centre() {
        let a = Vec3::new(0.2, 0.9, -0.3).normalize();
        let e = [Vec3::new(1.0, -0.5, 0.3), Vec3::zeros()];
        let d = [Vec3::new(-0.7, 0.2, 1.1), Vec3::zeros()];
        let c = case(12, Some(a), &e, &d);
        let mut rng = Rng::new(13);
        let sd = 1f64.to_radians();
        let noisy: Vec<_> = c
            .child
            .iter()
            .map(|p| {
                let jitter = UnitQuaternion::from_scaled_axis(rng.gauss3(sd));
                Isometry3::from_parts(p.translation, p.rotation * jitter)
            })
            .collect();
        let own: Vec<Vec<f64>> = c.drivers.iter().map(|r| r[..1].to_vec()).collect();
        let off = |p: &Point| (p - c.c_p).cross(&a).norm();
        let fit = score_sta(
            &c.parent,
            &noisy,
            &own,
            Some(a),
            &[StaTerms::BOTH; 1],
            PRIOR_SLIDE_MM_PER_RAD,
        )
        .unwrap();
        let rigid = sara_axis(&c.parent, &noisy).unwrap();
        let (e_sta, e_rigid) = (off(&fit.parent_local), off(&rigid.point_parent_local));
        assert!(
            e_rigid < 2.5 && e_sta > 2.0 * e_rigid,
            "model {e_sta} mm, rigid {e_rigid} mm"
        );
    }

    #[test]
    fn bad_input_is_an_error() {
        let c = case(7, None, &[], &[]);
        let d2: Vec<Vec<f64>> = c.drivers.iter().map(|d| d[..2].to_vec()).collect();
        assert!(score_sta(
            &c.parent,
            &c.child[1..],
            &d2[1..],
            None,
            &[StaTerms::BOTH; 2],
            3.0
        )
        .is_err());
        let mut bad = d2.clone();
        bad[5] = vec![f64::NAN, 0.0];
        let e = score_sta(&c.parent, &c.child, &bad, None, &[StaTerms::BOTH; 2], 3.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("driver row 5"), "{e}");
        assert!(score_sta(
            &c.parent[..10],
            &c.child[..10],
            &d2[..10],
            None,
            &[StaTerms::BOTH; 2],
            3.0
        )
        .is_err());
        assert!(score_sta(&c.parent, &c.child, &d2, None, &[StaTerms::BOTH; 2], 0.0).is_err());
        let still: Vec<_> = c
            .parent
            .iter()
            .map(|p| p * Isometry3::translation(1.0, 2.0, 3.0))
            .collect();
        assert!(score_sta(&c.parent, &still, &d2, None, &[StaTerms::BOTH; 2], 3.0).is_err());
    }
}
