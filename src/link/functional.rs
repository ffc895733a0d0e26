//! Joint centres and axes from both segments' poses (functional methods, beyond the seed paper).
//!
//! * [`score_centre`]: SCoRE, symmetrical centre of rotation estimation. Ehrig, Taylor, Duda &
//!   Heller (2006), "A survey of formal methods for determining the centre of rotation of ball
//!   joints", J. Biomech. 39(15):2798-2809.
//! * [`sara_axis`]: SARA, symmetrical axis of rotation approach. Ehrig, Taylor, Duda & Heller
//!   (2007), "A survey of formal methods for determining functional joint axes", J. Biomech.
//!   40(10):2150-2157.
//!
//! Unlike the sphere and plane fits of [`super::sphere_fit`] and [`super::axis_fit`], which see
//! the child's markers in the parent's frame only, these use both segments' motion symmetrically,
//! so soft-tissue noise on the parent does not enter through a single registration.
//!
//! Pose convention: `parent[t]` and `child[t]` are the segments' poses at frame t, mapping
//! segment-local coordinates to world (lab) coordinates, `x_world = R(t) x_local + t(t)`, mm; e.g.
//! the Horn registration of a local marker template onto the segment's markers at frame t
//! ([`crate::geometry::absolute_orientation`] with the template as source). Both sequences must be
//! the same frames.

use super::sphere_fit::determined;
use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use nalgebra::{Isometry3, Matrix3, Matrix6, SymmetricEigen, Vector6};

/// A joint centre estimated by SCoRE.
#[derive(Clone, Debug, PartialEq)]
pub struct ScoreFit {
    /// The centre in world coordinates at frame 0: midpoint of the parent's and the child's
    /// estimate, `(T_p(0) c_p + T_c(0) c_c) / 2`, mm.
    pub centre: Point,
    /// The centre in the parent's local coordinates, c_p, mm.
    pub parent_local: Point,
    /// The centre in the child's local coordinates, c_c, mm.
    pub child_local: Point,
    /// Root mean square over frames of `|T_p(t) c_p - T_c(t) c_c|`, mm: 0 for an ideal ball joint.
    pub rms: f64,
    /// Smallest over largest eigenvalue of the 6x6 normal matrix: near 0 = the relative rotation
    /// does not determine the centre in some direction (e.g. along the axis of a hinge).
    pub condition: f64,
    /// Number of frames.
    pub n_frames: usize,
}

impl ScoreFit {
    /// The centre in world coordinates for a pair of segment poses (e.g. any other frame): the
    /// midpoint of the parent's and the child's estimate.
    pub(crate) fn centre_at(&self, parent: &Isometry3<f64>, child: &Isometry3<f64>) -> Point {
        Point::from(
            (parent * self.parent_local).coords * 0.5 + (child * self.child_local).coords * 0.5,
        )
    }
}

/// A joint axis estimated by SARA.
#[derive(Clone, Debug, PartialEq)]
pub struct SaraFit {
    /// A point on the axis in world coordinates at frame 0 (midpoint of the parent's and the
    /// child's estimate), mm. Which point of the line is arbitrary (the minimum-norm solution in
    /// the segments' local coordinates); project a point of interest onto the line.
    pub point: Point,
    /// Unit axis direction in world coordinates at frame 0. Sign arbitrary (deterministic); the
    /// caller orients it.
    pub axis: Vec3,
    /// The point in the parent's local coordinates, mm.
    pub point_parent_local: Point,
    /// The point in the child's local coordinates, mm.
    pub point_child_local: Point,
    /// Unit axis direction in the parent's local coordinates (same sign as `axis`).
    pub axis_parent_local: Vec3,
    /// Unit axis direction in the child's local coordinates (same sign as `axis`).
    pub axis_child_local: Vec3,
    /// Root mean square over frames of `|T_p(t) p_p - T_c(t) p_c|` for the two local points, mm.
    pub rms: f64,
    /// Second-smallest over largest eigenvalue of the 6x6 normal matrix: how well the motion
    /// determines the axis' position (near 0 = poorly).
    pub condition: f64,
    /// Smallest over second-smallest eigenvalue: near 0 = the relative motion is a rotation about
    /// one axis (a hinge); near 1 = it is not (the axis is then not meaningful).
    pub hinge_ratio: f64,
    /// Number of frames.
    pub n_frames: usize,
}

/// Validate the pose sequences and accumulate the normal equations of
/// `sum_t |R_p(t) x_p + t_p(t) - R_c(t) x_c - t_c(t)|^2` in `x = (x_p, x_c)`:
/// `N = sum_t A_t^T A_t`, `g = sum_t A_t^T (t_c - t_p)`, `A_t = [R_p(t), -R_c(t)]`. Only the
/// difference of translations enters, so far-away lab coordinates cost no precision.
fn normal_equations(
    what: &str,
    parent: &[Isometry3<f64>],
    child: &[Isometry3<f64>],
) -> Result<(Matrix6<f64>, Vector6<f64>)> {
    if parent.len() != child.len() {
        return Err(Error::invalid(format!(
            "{what}: {} parent poses but {} child poses; pass the same frames for both",
            parent.len(),
            child.len()
        )));
    }
    if parent.len() < 2 {
        return Err(Error::invalid(format!(
            "{what}: {} frames, need at least 2 (and real motion)",
            parent.len()
        )));
    }
    let finite = |p: &Isometry3<f64>| {
        p.translation.vector.iter().all(|x| x.is_finite())
            && p.rotation.coords.iter().all(|x| x.is_finite())
    };
    for (t, (p, c)) in parent.iter().zip(child).enumerate() {
        if !finite(p) {
            return Err(Error::invalid(format!(
                "{what}: parent pose at frame {t} is not finite"
            )));
        }
        if !finite(c) {
            return Err(Error::invalid(format!(
                "{what}: child pose at frame {t} is not finite"
            )));
        }
    }
    let mut n = Matrix6::zeros();
    let mut g = Vector6::zeros();
    for (p, c) in parent.iter().zip(child) {
        accumulate(p, c, &mut n, &mut g);
    }
    Ok((n, g))
}

/// Add one frame's terms `A^T A` and `A^T (t_c - t_p)`, `A = [R_p, -R_c]`, to `n` and `g`.
fn accumulate(p: &Isometry3<f64>, c: &Isometry3<f64>, n: &mut Matrix6<f64>, g: &mut Vector6<f64>) {
    let rp: Matrix3<f64> = p.rotation.to_rotation_matrix().into_inner();
    let rc: Matrix3<f64> = c.rotation.to_rotation_matrix().into_inner();
    let cross = rp.transpose() * rc;
    let d = c.translation.vector - p.translation.vector;
    let mut block = Matrix6::identity();
    block.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-cross));
    block
        .fixed_view_mut::<3, 3>(3, 0)
        .copy_from(&(-cross.transpose()));
    *n += block;
    let (gp, gc) = (rp.transpose() * d, rc.transpose() * d);
    *g += Vector6::new(gp.x, gp.y, gp.z, -gc.x, -gc.y, -gc.z);
}

/// Eigenpairs of a symmetric 6x6 matrix, eigenvalues descending.
fn sorted_eigen6(n: &Matrix6<f64>) -> ([f64; 6], Matrix6<f64>) {
    let eig = SymmetricEigen::new((n + n.transpose()) * 0.5);
    let mut idx = [0usize, 1, 2, 3, 4, 5];
    idx.sort_by(|&i, &j| eig.eigenvalues[j].total_cmp(&eig.eigenvalues[i]));
    let vals = idx.map(|i| eig.eigenvalues[i]);
    let vecs = Matrix6::from_columns(&idx.map(|i| eig.eigenvectors.column(i).into_owned()));
    (vals, vecs)
}

/// Root mean square of `|T_p(t) x_p - T_c(t) x_c|` over frames.
fn pair_rms(parent: &[Isometry3<f64>], child: &[Isometry3<f64>], xp: &Point, xc: &Point) -> f64 {
    let ss: f64 = parent
        .iter()
        .zip(child)
        .map(|(p, c)| ((p * xp) - (c * xc)).norm_squared())
        .sum();
    (ss / parent.len() as f64).sqrt()
}

/// Joint centre by SCoRE (Ehrig et al. 2006): the point fixed in both
/// segments, found as the `c_p` (parent-local) and `c_c` (child-local) minimising
/// `sum_t |T_p(t) c_p - T_c(t) c_c|^2`.
///
/// * `parent`, `child`: segment poses (local -> world) per frame, same frames (see the module
///   doc for the convention).
/// * Returns both local points, the world centre at frame 0 and the fit's rms and condition.
///   The linear least squares in 6 unknowns is solved through its 6x6 normal equations
///   (`sum_t [I, -R_p^T R_c; -R_c^T R_p, I]`), accumulated in one O(n) pass.
///
/// Errors (one line): different sequence lengths, fewer than 2 frames, a non-finite pose, or a
/// singular system (condition below 1e-10): no relative rotation, or rotation about a single
/// axis, for which the centre is undetermined along the axis (use [`sara_axis`]).
pub fn score_centre(parent: &[Isometry3<f64>], child: &[Isometry3<f64>]) -> Result<ScoreFit> {
    const WHAT: &str = "SCoRE centre";
    let (n, g) = normal_equations(WHAT, parent, child)?;
    let (x, condition) = score_solve(&n, &g).ok_or_else(|| {
        Error::invalid(format!(
            "{WHAT}: the relative motion does not determine a centre (no rotation, or rotation \
             about one axis only); move the joint in more directions, or use sara_axis for a hinge"
        ))
    })?;
    finish_score(parent, child, &x, condition)
}

/// SCoRE's least-squares solution `(c_p, c_c)` of its normal equations `n x = g` (as
/// accumulated by [`block_normal_equations`], summed), and the system's condition (smallest
/// over largest eigenvalue); `None` when the system is singular (see [`score_centre`]).
pub fn score_solve(n: &Matrix6<f64>, g: &Vector6<f64>) -> Option<(Vector6<f64>, f64)> {
    let (vals, vecs) = sorted_eigen6(n);
    if !determined(vals[5], vals[0]) {
        return None;
    }
    let mut x = Vector6::zeros();
    for (v, lambda) in vecs.column_iter().zip(vals) {
        x += v * (v.dot(g) / lambda);
    }
    Some((x, vals[5] / vals[0]))
}

/// SARA's solution of its normal equations `n x = g` (the one [`sara_axis`] takes): a point on the axis and the axis'
/// unit direction, both in the parent's local coordinates (the direction's sign arbitrary);
/// `None` when the five largest eigenvalues do not determine the point (see [`sara_axis`]).
pub fn sara_solve(n: &Matrix6<f64>, g: &Vector6<f64>) -> Option<(Point, Vec3)> {
    let (vals, vecs) = sorted_eigen6(n);
    if !determined(vals[4], vals[0]) {
        return None;
    }
    let mut x = Vector6::zeros();
    for (v, lambda) in vecs.column_iter().zip(vals).take(5) {
        x += v * (v.dot(g) / lambda);
    }
    let null = vecs.column(5);
    let ap = Vec3::new(null[0], null[1], null[2]).try_normalize(1e-9)?;
    Some((Point::new(x[0], x[1], x[2]), ap))
}

/// The normal equations of [`score_centre`] and [`sara_axis`] summed per block of frames:
/// frame `t` adds to block `block_of[t]` (`n_blocks` blocks; a block may stay empty). A block
/// bootstrap (Künsch 1989) then draws blocks with replacement and solves the sum of the drawn
/// blocks' equations ([`score_solve`], [`sara_solve`]) at no further cost per frame. Errors as
/// [`score_centre`]'s input checks, or a block index out of range.
pub fn block_normal_equations(
    parent: &[Isometry3<f64>],
    child: &[Isometry3<f64>],
    block_of: &[usize],
    n_blocks: usize,
) -> Result<Vec<(Matrix6<f64>, Vector6<f64>)>> {
    normal_equations("block normal equations", parent, child)?;
    if block_of.len() != parent.len() || block_of.iter().any(|&b| b >= n_blocks) {
        return Err(Error::invalid(format!(
            "block normal equations: {} block indices for {} frames, each below {n_blocks}",
            block_of.len(),
            parent.len()
        )));
    }
    let mut out = vec![(Matrix6::zeros(), Vector6::zeros()); n_blocks];
    for ((p, c), &b) in parent.iter().zip(child).zip(block_of) {
        let (n, g) = &mut out[b];
        accumulate(p, c, n, g);
    }
    Ok(out)
}

fn finish_score(
    parent: &[Isometry3<f64>],
    child: &[Isometry3<f64>],
    x: &Vector6<f64>,
    condition: f64,
) -> Result<ScoreFit> {
    let parent_local = Point::new(x[0], x[1], x[2]);
    let child_local = Point::new(x[3], x[4], x[5]);
    let fit = ScoreFit {
        centre: Point::origin(),
        parent_local,
        child_local,
        rms: pair_rms(parent, child, &parent_local, &child_local),
        condition,
        n_frames: parent.len(),
    };
    Ok(ScoreFit {
        centre: fit.centre_at(&parent[0], &child[0]),
        ..fit
    })
}

/// Joint axis by SARA (Ehrig et al. 2007): the line fixed in both segments.
///
/// The SCoRE system `sum_t |T_p(t) x_p - T_c(t) x_c|^2` of a hinge has a one-dimensional null
/// space: moving `(x_p, x_c)` along `(a_p, a_c)`, the axis direction in both local frames,
/// leaves every residual unchanged (`R_p a_p = R_c a_c` for all t). SARA takes that direction
/// as the eigenvector of the smallest eigenvalue of the 6x6 normal matrix (the smallest right
/// singular vector of the stacked `[R_p(t), -R_c(t)]`), and a point on the axis as the least
/// squares solution restricted to the other five eigenvectors.
///
/// * `parent`, `child`: segment poses (local -> world) per frame, same frames.
/// * Returns the axis (world at frame 0 and in both local frames), a point on it, the rms of
///   the two local points' world distance, the position `condition` and the `hinge_ratio`.
///
/// Errors (one line): different lengths, fewer than 2 frames, a non-finite pose, or a system
/// whose five largest eigenvalues do not determine the point (no relative rotation).
pub fn sara_axis(parent: &[Isometry3<f64>], child: &[Isometry3<f64>]) -> Result<SaraFit> {
    const WHAT: &str = "SARA axis";
    let (n, g) = normal_equations(WHAT, parent, child)?;
    let (vals, vecs) = sorted_eigen6(&n);
    if !determined(vals[4], vals[0]) {
        return Err(Error::invalid(format!(
            "{WHAT}: the relative motion does not determine an axis (no rotation between the \
             segments); check the trial and the segment poses"
        )));
    }
    let mut x = Vector6::zeros();
    for (v, lambda) in vecs.column_iter().zip(vals).take(5) {
        x += v * (v.dot(&g) / lambda);
    }
    let null = vecs.column(5);
    let ap = Vec3::new(null[0], null[1], null[2]);
    let ac = Vec3::new(null[3], null[4], null[5]);
    // For a hinge |a_p| = |a_c| = 1/sqrt(2); both are needed in the world direction below.
    if !(ap.norm() > 1e-6 && ac.norm() > 1e-6) {
        return Err(Error::invalid(format!(
            "{WHAT}: the motion's null direction is not an axis common to both segments; the \
             relative motion is not a rotation about a fixed axis"
        )));
    }
    let (mut ap, mut ac) = (ap.normalize(), ac.normalize());
    let world = parent[0].rotation * ap + child[0].rotation * ac;
    let mut axis = if world.norm() > 1e-6 {
        world.normalize()
    } else {
        parent[0].rotation * ap
    };
    if axis[axis.iamax()] < 0.0 {
        axis = -axis;
        ap = -ap;
        ac = -ac;
    }
    let pp = Point::new(x[0], x[1], x[2]);
    let pc = Point::new(x[3], x[4], x[5]);
    let point = Point::from(((parent[0] * pp).coords + (child[0] * pc).coords) * 0.5);
    Ok(SaraFit {
        point,
        axis,
        point_parent_local: pp,
        point_child_local: pc,
        axis_parent_local: ap,
        axis_child_local: ac,
        rms: pair_rms(parent, child, &pp, &pc),
        condition: vals[4] / vals[0],
        hinge_ratio: (vals[5].max(0.0) / vals[4]).min(1.0),
        n_frames: parent.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use nalgebra::{Translation3, UnitQuaternion};
    use proptest::prelude::*;

    /// Random parent poses wandering about the lab.
    fn parent_poses(rng: &mut Rng, frames: usize) -> Vec<Isometry3<f64>> {
        (0..frames)
            .map(|_| {
                Isometry3::from_parts(
                    Translation3::new(
                        rng.range(200.0, 600.0),
                        rng.range(-300.0, 300.0),
                        rng.range(800.0, 1200.0),
                    ),
                    rng.rotation(),
                )
            })
            .collect()
    }

    /// Child poses for a joint at `c_p` (parent-local) with relative rotations `rel[t]`:
    /// T_c = T_p * Rot(about c_p, rel) * T_0, with T_0 the child-local -> parent-local offset
    /// at zero rotation. The centre in the child's frame is then T_0^-1 c_p.
    fn child_poses(
        parent: &[Isometry3<f64>],
        rel: &[UnitQuaternion<f64>],
        c_p: &Point,
        t0: &Isometry3<f64>,
    ) -> Vec<Isometry3<f64>> {
        parent
            .iter()
            .zip(rel)
            .map(|(tp, r)| {
                let about = Isometry3::from_parts(Translation3::from(c_p.coords), *r)
                    * Isometry3::translation(-c_p.x, -c_p.y, -c_p.z);
                tp * about * t0
            })
            .collect()
    }

    fn offset() -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(35.0, 4.0, -2.0),
            UnitQuaternion::from_euler_angles(0.2, -0.4, 1.1),
        )
    }

    #[test]
    fn score_recovers_ball_joint_centre() {
        let mut rng = Rng::new(11);
        let parent = parent_poses(&mut rng, 150);
        let rel: Vec<_> = (0..150)
            .map(|_| {
                UnitQuaternion::from_scaled_axis(Vec3::new(
                    rng.range(-0.6, 0.6),
                    rng.range(-0.6, 0.6),
                    rng.range(-0.6, 0.6),
                ))
            })
            .collect();
        let c_p = Point::new(12.0, -5.0, 30.0);
        let t0 = offset();
        let child = child_poses(&parent, &rel, &c_p, &t0);
        let fit = score_centre(&parent, &child).unwrap();
        assert!((fit.parent_local - c_p).norm() < 1e-9);
        assert!((fit.child_local - t0.inverse() * c_p).norm() < 1e-9);
        assert!((fit.centre - parent[0] * c_p).norm() < 1e-9);
        assert!((fit.centre_at(&parent[7], &child[7]) - parent[7] * c_p).norm() < 1e-9);
        assert!(fit.rms < 1e-9 && fit.condition > 1e-3 && fit.n_frames == 150);
    }

    /// The blocks' normal equations sum to the whole sequence's: solved, they give SCoRE's
    /// and SARA's own answers (a hinge's axis line: its direction and a point on it), and a
    /// block drawn twice weighs its frames twice (the ball joint stays exact, being exact in
    /// every frame).
    #[test]
    fn block_equations_sum_to_the_whole() {
        let (parent, child, c_p, a_p) = hinge(5);
        let block_of: Vec<usize> = (0..parent.len()).map(|t| t / 7).collect();
        let n_blocks = parent.len().div_ceil(7);
        let blocks = block_normal_equations(&parent, &child, &block_of, n_blocks).unwrap();
        let (mut n, mut g) = (Matrix6::zeros(), Vector6::zeros());
        for (bn, bg) in &blocks {
            n += bn;
            g += bg;
        }
        let (p, a) = sara_solve(&n, &g).unwrap();
        let fit = sara_axis(&parent, &child).unwrap();
        assert!(a.cross(&fit.axis_parent_local).norm() < 1e-9);
        assert!(a.cross(&a_p).norm() < 1e-9);
        let off = (p - c_p) - a_p * (p - c_p).dot(&a_p);
        assert!(off.norm() < 1e-9, "{}", off.norm());

        let mut rng = Rng::new(12);
        let parent = parent_poses(&mut rng, 90);
        let rel: Vec<_> = (0..90)
            .map(|_| UnitQuaternion::from_scaled_axis(rng.gauss3(0.5)))
            .collect();
        let c = Point::new(3.0, -9.0, 25.0);
        let child = child_poses(&parent, &rel, &c, &offset());
        let block_of: Vec<usize> = (0..90).map(|t| t / 10).collect();
        let blocks = block_normal_equations(&parent, &child, &block_of, 9).unwrap();
        let (mut n, mut g) = (Matrix6::zeros(), Vector6::zeros());
        for b in [0, 0, 3, 8, 8, 8, 5, 2, 1] {
            n += blocks[b].0;
            g += blocks[b].1;
        }
        let (x, _) = score_solve(&n, &g).unwrap();
        assert!((Point::new(x[0], x[1], x[2]) - c).norm() < 1e-9);
        assert!(block_normal_equations(&parent, &child, &block_of, 8).is_err());
    }

    fn hinge(seed: u64) -> (Vec<Isometry3<f64>>, Vec<Isometry3<f64>>, Point, Vec3) {
        let mut rng = Rng::new(seed);
        let parent = parent_poses(&mut rng, 120);
        let a_p = rng.unit_vector();
        let rel: Vec<_> = (0..120)
            .map(|_| UnitQuaternion::from_scaled_axis(a_p * rng.range(-0.2, 1.4)))
            .collect();
        let c_p = Point::new(-8.0, 22.0, 14.0);
        let child = child_poses(&parent, &rel, &c_p, &offset());
        (parent, child, c_p, a_p)
    }

    #[test]
    fn sara_recovers_hinge_axis() {
        for seed in 20..25 {
            let (parent, child, c_p, a_p) = hinge(seed);
            let fit = sara_axis(&parent, &child).unwrap();
            let t0 = offset();
            let line_dist = |p: &Point, c: &Point, a: &Vec3| (p - c).cross(a).norm();
            assert!(fit.axis_parent_local.cross(&a_p).norm() < 1e-9);
            assert!(fit.axis_child_local.cross(&(t0.inverse() * a_p)).norm() < 1e-9);
            assert!(fit.axis.cross(&(parent[0] * a_p)).norm() < 1e-9);
            assert!((fit.axis.norm() - 1.0).abs() < 1e-12);
            // Same sign in every frame.
            assert!((parent[0] * fit.axis_parent_local - fit.axis).norm() < 1e-9);
            assert!((child[0] * fit.axis_child_local - fit.axis).norm() < 1e-9);
            assert!(line_dist(&fit.point_parent_local, &c_p, &a_p) < 1e-9);
            assert!(line_dist(&fit.point, &(parent[0] * c_p), &(parent[0] * a_p)) < 1e-9);
            assert!(fit.rms < 1e-9 && fit.hinge_ratio < 1e-12 && fit.condition > 1e-4);
            // The same motion is singular for SCoRE: the centre slides along the axis.
            assert!(score_centre(&parent, &child).is_err());
        }
    }

    /// First-order standard deviation of SARA's parent-local axis under child rotation noise
    /// `R_c -> R_c exp(delta)`, delta isotropic with sd `sd` per component. With the clean null
    /// vector x0 = (a_p, a_c) (unit), the perturbation is dN x0 = sum_t A_t^T R_c (delta_t x a_c),
    /// so dx = -sum_{i<6} v_i (v_i . dN x0) / lambda_i and
    /// E(v_i . dN x0)^2 = sd^2 sum_t v_i^T A_t^T R_c (|a_c|^2 I - a_c a_c^T) R_c^T A_t v_i.
    /// The unit a_p moves by about |dx| / |a_p| = sqrt(2) |dx|.
    fn sara_axis_sd(parent: &[Isometry3<f64>], child: &[Isometry3<f64>], sd: f64) -> f64 {
        let (n0, _) = normal_equations("test", parent, child).unwrap();
        let (vals, vecs) = sorted_eigen6(&n0);
        let a_c = Vec3::new(vecs[(3, 5)], vecs[(4, 5)], vecs[(5, 5)]);
        let proj = Matrix3::identity() * a_c.norm_squared() - a_c * a_c.transpose();
        let mut var = 0.0;
        for (v, lambda) in vecs.column_iter().zip(vals).take(5) {
            let (vp, vc) = (Vec3::new(v[0], v[1], v[2]), Vec3::new(v[3], v[4], v[5]));
            let mut e2 = 0.0;
            for (p, c) in parent.iter().zip(child) {
                // A_t v = R_p v_p - R_c v_c, so v^T A_t^T R_c = (R_c^T (R_p v_p - R_c v_c))^T.
                let u = c.rotation.inverse() * (p.rotation * vp - c.rotation * vc);
                e2 += (u.transpose() * proj * u)[0];
            }
            var += sd * sd * e2 / (lambda * lambda);
        }
        (2.0 * var).sqrt()
    }

    #[test]
    fn noisy_hinge_axis_within_bound() {
        for seed in 30..40 {
            let (parent, child, _c_p, a_p) = hinge(seed);
            let mut rng = Rng::new(seed + 1000);
            let sd = 0.2f64.to_radians();
            let noisy: Vec<_> = child
                .iter()
                .map(|c| {
                    let jitter = UnitQuaternion::from_scaled_axis(rng.gauss3(sd));
                    Isometry3::from_parts(c.translation, c.rotation * jitter)
                })
                .collect();
            let fit = sara_axis(&parent, &noisy).unwrap();
            let bound = 6.0 * sara_axis_sd(&parent, &child, sd);
            let err = fit.axis_parent_local.cross(&a_p).norm();
            assert!(err < bound, "seed {seed}: {err} rad vs bound {bound}");
            assert!(fit.hinge_ratio < 0.01);
        }
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let mut rng = Rng::new(5);
        let parent = parent_poses(&mut rng, 10);
        // The child rigidly attached: no relative motion.
        let child: Vec<_> = parent.iter().map(|p| p * offset()).collect();
        assert!(score_centre(&parent, &child).is_err());
        assert!(sara_axis(&parent, &child).is_err());
        assert!(score_centre(&parent, &child[..9]).is_err());
        assert!(score_centre(&parent[..1], &child[..1]).is_err());
        assert!(sara_axis(&[], &[]).is_err());
        let mut bad = child.clone();
        bad[3].translation.vector.x = f64::NAN;
        let e = sara_axis(&parent, &bad).unwrap_err().to_string();
        assert!(e.contains("child pose at frame 3"), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]
        /// Arbitrary pose pairs: an error or a finite result, never a panic or NaN.
        #[test]
        fn never_panics_or_nan(
            poses in proptest::collection::vec(
                ((-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0), (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0),
                 (-500.0f64..500.0, -500.0f64..500.0, -500.0f64..500.0)),
                0..8),
        ) {
            let parent: Vec<_> = poses.iter().map(|(r, _, t)| Isometry3::from_parts(
                Translation3::new(t.0, t.1, t.2),
                UnitQuaternion::from_scaled_axis(Vec3::new(r.0, r.1, r.2)))).collect();
            let child: Vec<_> = poses.iter().map(|(_, r, t)| Isometry3::from_parts(
                Translation3::new(t.2, t.0, t.1),
                UnitQuaternion::from_scaled_axis(Vec3::new(r.0, r.1, r.2)))).collect();
            if let Ok(f) = score_centre(&parent, &child) {
                prop_assert!(f.centre.coords.iter().chain(f.parent_local.coords.iter()).all(|x| x.is_finite()));
                prop_assert!(f.rms.is_finite() && f.condition.is_finite());
            }
            if let Ok(f) = sara_axis(&parent, &child) {
                prop_assert!(f.point.coords.iter().all(|x| x.is_finite()));
                prop_assert!((f.axis.norm() - 1.0).abs() < 1e-9);
                prop_assert!(f.rms.is_finite() && f.condition.is_finite() && f.hinge_ratio.is_finite());
            }
        }
    }
}
