//! Closed-form absolute orientation with unit quaternions.
//!
//! Horn, B. K. P. (1987). "Closed-form solution of absolute orientation using unit quaternions."
//! J. Opt. Soc. Am. A 4(4), 629-642. The seed paper (Endo et al. 2014, section 3.4, equation 1)
//! calls it the "landmark transform algorithm" and uses it to register a parent link's markers
//! onto their reference-frame positions in every frame of a calibration trial.

use super::{Point, Vec3};
use crate::error::{Error, Result};
use nalgebra::{Isometry3, Matrix3, Matrix4, Quaternion, Translation3, UnitQuaternion};

/// A similarity transform `p -> s R p + t` found by [`absolute_orientation`], with its fit residual.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Registration {
    /// Rotation R.
    pub rotation: UnitQuaternion<f64>,
    /// Translation t, mm.
    pub translation: Vec3,
    /// Scale s (exactly 1 unless scale was asked for).
    pub scale: f64,
    /// Weighted root-mean-square distance between the transformed source and the target, mm.
    pub rms: f64,
}

impl Registration {
    /// Map a point from the source frame to the target frame.
    #[inline]
    pub fn apply(&self, p: &Point) -> Point {
        Point::from(self.rotation * p.coords * self.scale + self.translation)
    }

    /// Map a direction (rotation only).
    #[inline]
    pub fn apply_vector(&self, v: &Vec3) -> Vec3 {
        self.rotation * v
    }

    /// The rigid part (rotation and translation) as an isometry; exact when `scale == 1`.
    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(Translation3::from(self.translation), self.rotation)
    }

    /// Homogeneous 4x4 matrix of the full similarity.
    pub fn to_matrix(&self) -> Matrix4<f64> {
        let mut m = Matrix4::identity();
        m.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&(self.rotation.to_rotation_matrix().matrix() * self.scale));
        m.fixed_view_mut::<3, 1>(0, 3).copy_from(&self.translation);
        m
    }

    /// The inverse transform (target to source); the residual is carried over unchanged.
    pub fn inverse(&self) -> Registration {
        let rinv = self.rotation.inverse();
        Registration {
            rotation: rinv,
            translation: -(rinv * self.translation) / self.scale,
            scale: 1.0 / self.scale,
            rms: self.rms,
        }
    }
}

/// Find the rotation, translation and (optionally) scale that best map `source` onto `target`
/// in the weighted least-squares sense (Horn 1987, sections 2-5).
///
/// * `weights`: one non-negative weight per pair, or `None` for equal weights.
/// * `with_scale`: also estimate a scale factor, with Horn's symmetric formula (section 2.D),
///   which gives the exact inverse when source and target are swapped.
///
/// The optimal rotation is the unit eigenvector of the largest eigenvalue of Horn's symmetric
/// 4x4 matrix N built from the cross-covariance of the centred point sets (section 4).
///
/// Errors when the sets differ in length, fewer than three pairs carry weight, a weight is
/// negative or not finite, or the weighted source points are collinear (the rotation about
/// their line is then undetermined).
pub fn absolute_orientation(
    source: &[Point],
    target: &[Point],
    weights: Option<&[f64]>,
    with_scale: bool,
) -> Result<Registration> {
    if source.len() != target.len() {
        return Err(Error::invalid(format!(
            "registration needs matched points: {} source vs {} target",
            source.len(),
            target.len()
        )));
    }
    let n = source.len();
    let w: Vec<f64> = match weights {
        Some(w) if w.len() != n => {
            return Err(Error::invalid(format!(
                "registration has {} weights for {n} points",
                w.len()
            )))
        }
        Some(w) => w.to_vec(),
        None => vec![1.0; n],
    };
    if let Some(i) = w.iter().position(|x| !x.is_finite() || *x < 0.0) {
        return Err(Error::invalid(format!(
            "registration weight {i} is negative or not finite"
        )));
    }
    let active = w.iter().filter(|&&x| x > 0.0).count();
    if active < 3 {
        return Err(Error::invalid(format!(
            "registration needs at least 3 points, got {active}"
        )));
    }
    let wsum: f64 = w.iter().sum();
    let centroid = |pts: &[Point]| -> Vec3 {
        pts.iter()
            .zip(&w)
            .map(|(p, wi)| p.coords * *wi)
            .sum::<Vec3>()
            / wsum
    };
    let (cs, ct) = (centroid(source), centroid(target));

    let mut m = Matrix3::zeros();
    let (mut ss, mut st) = (0.0, 0.0);
    let mut scatter = Matrix3::zeros();
    for ((p, q), wi) in source.iter().zip(target).zip(&w) {
        let a = p.coords - cs;
        let b = q.coords - ct;
        m += a * b.transpose() * *wi;
        scatter += a * a.transpose() * *wi;
        ss += wi * a.norm_squared();
        st += wi * b.norm_squared();
    }
    // Collinearity: the weighted source scatter must have two non-negligible principal values.
    let eig = scatter.symmetric_eigenvalues();
    let mut ev = [eig[0], eig[1], eig[2]];
    ev.sort_by(|a, b| b.total_cmp(a));
    if ev[0].is_nan() || ev[0] <= 0.0 || ev[1] <= 1e-12 * ev[0] {
        return Err(Error::invalid(
            "registration points are collinear (or coincide): the rotation is undetermined",
        ));
    }

    // Horn's N matrix (equation 26 with S = M).
    let (sxx, sxy, sxz) = (m[(0, 0)], m[(0, 1)], m[(0, 2)]);
    let (syx, syy, syz) = (m[(1, 0)], m[(1, 1)], m[(1, 2)]);
    let (szx, szy, szz) = (m[(2, 0)], m[(2, 1)], m[(2, 2)]);
    #[rustfmt::skip]
    let nmat = Matrix4::new(
        sxx + syy + szz, syz - szy,        szx - sxz,        sxy - syx,
        syz - szy,       sxx - syy - szz,  sxy + syx,        szx + sxz,
        szx - sxz,       sxy + syx,       -sxx + syy - szz,  syz + szy,
        sxy - syx,       szx + sxz,        syz + szy,       -sxx - syy + szz,
    );
    let se = nmat.symmetric_eigen();
    let imax = se.eigenvalues.imax();
    let q = se.eigenvectors.column(imax);
    let rotation = UnitQuaternion::from_quaternion(Quaternion::new(q[0], q[1], q[2], q[3]));

    let scale = if with_scale { (st / ss).sqrt() } else { 1.0 };
    let translation = ct - rotation * cs * scale;
    let reg = Registration {
        rotation,
        translation,
        scale,
        rms: 0.0,
    };
    let sse: f64 = source
        .iter()
        .zip(target)
        .zip(&w)
        .map(|((p, q), wi)| wi * (reg.apply(p) - q).norm_squared())
        .sum();
    Ok(Registration {
        rms: (sse / wsum).sqrt(),
        ..reg
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Deterministic pseudo-random numbers for tests (SplitMix64), no extra dependency.
    fn rng(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s = s.wrapping_add(0x9E3779B97F4A7C15);
            let mut z = s;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    fn gaussian(u: &mut impl FnMut() -> f64) -> f64 {
        let (a, b) = (u().max(1e-300), u());
        (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
    }

    fn known() -> Registration {
        Registration {
            rotation: UnitQuaternion::from_euler_angles(0.3, -1.1, 2.4),
            translation: Vec3::new(12.0, -40.0, 7.5),
            scale: 1.0,
            rms: 0.0,
        }
    }

    #[test]
    fn exact_transform_recovered() {
        let mut u = rng(1);
        let src: Vec<Point> = (0..10)
            .map(|_| Point::new(u() * 100.0, u() * 100.0, u() * 100.0))
            .collect();
        let t = known();
        let dst: Vec<Point> = src.iter().map(|p| t.apply(p)).collect();
        let r = absolute_orientation(&src, &dst, None, false).unwrap();
        assert!(r.rotation.angle_to(&t.rotation) < 1e-12);
        assert!((r.translation - t.translation).norm() < 1e-10);
        assert!(r.rms < 1e-10);
        // The inverse maps back.
        let inv = r.inverse();
        for (p, q) in src.iter().zip(&dst) {
            assert!((inv.apply(q) - p).norm() < 1e-10);
        }
    }

    /// With isotropic noise sigma on both point sets, the rotation error of a least-squares fit
    /// has standard deviation about sigma*sqrt(2) / (sqrt(n) * spread); the translation error
    /// about sigma*sqrt(2/n). Assert within 5 standard deviations.
    #[test]
    fn noisy_transform_within_noise_bound() {
        let mut u = rng(7);
        let n = 200;
        let sigma = 0.3;
        let src: Vec<Point> = (0..n)
            .map(|_| Point::new(u() * 80.0 - 40.0, u() * 80.0 - 40.0, u() * 80.0 - 40.0))
            .collect();
        let t = known();
        let noisy = |p: &Point, u: &mut dyn FnMut() -> f64| {
            let mut g = || {
                let (a, b) = (u().max(1e-300), u());
                (-2.0 * a.ln()).sqrt() * (std::f64::consts::TAU * b).cos()
            };
            p + Vec3::new(g(), g(), g()) * sigma
        };
        let dst: Vec<Point> = src.iter().map(|p| noisy(&t.apply(p), &mut u)).collect();
        let srcn: Vec<Point> = src.iter().map(|p| noisy(p, &mut u)).collect();
        let r = absolute_orientation(&srcn, &dst, None, false).unwrap();
        // Spread: rms distance from the centroid of a uniform cube of side 80 is 80/2 = 40.
        let spread = 40.0;
        let rot_sd = sigma * 2f64.sqrt() / ((n as f64).sqrt() * spread);
        let trans_sd = sigma * (2.0 / n as f64).sqrt();
        assert!(r.rotation.angle_to(&t.rotation) < 5.0 * rot_sd * 3f64.sqrt());
        // Translation is coupled to rotation error times the centroid offset (here the centroid
        // sits near the origin), so the bound stays the pure-noise one.
        assert!((r.translation - t.translation).norm() < 5.0 * trans_sd * 3f64.sqrt() + 0.05);
        // The residual estimates the noise: E[rms^2] = 2 sigma^2 * 3 (1 - 6/(3n)).
        let expect = (2.0 * 3.0f64).sqrt() * sigma;
        assert!(
            (r.rms - expect).abs() < 0.1 * expect,
            "rms {} vs {}",
            r.rms,
            expect
        );
        let _ = gaussian(&mut u);
    }

    #[test]
    fn weights_ignore_an_outlier() {
        let mut u = rng(3);
        let src: Vec<Point> = (0..6)
            .map(|_| Point::new(u() * 50.0, u() * 50.0, u() * 50.0))
            .collect();
        let t = known();
        let mut dst: Vec<Point> = src.iter().map(|p| t.apply(p)).collect();
        dst[5] += Vec3::new(30.0, 0.0, 0.0);
        let w = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0];
        let r = absolute_orientation(&src, &dst, Some(&w), false).unwrap();
        assert!(r.rotation.angle_to(&t.rotation) < 1e-10);
        assert!(r.rms < 1e-9);
    }

    #[test]
    fn scale_is_recovered_and_symmetric() {
        let mut u = rng(11);
        let src: Vec<Point> = (0..8)
            .map(|_| Point::new(u() * 50.0, u() * 50.0, u() * 50.0))
            .collect();
        let t = Registration {
            scale: 1.37,
            ..known()
        };
        let dst: Vec<Point> = src.iter().map(|p| t.apply(p)).collect();
        let r = absolute_orientation(&src, &dst, None, true).unwrap();
        assert!((r.scale - 1.37).abs() < 1e-12);
        let back = absolute_orientation(&dst, &src, None, true).unwrap();
        assert!((back.scale * r.scale - 1.0).abs() < 1e-12);
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let p = |x: f64| Point::new(x, 2.0 * x, -x);
        let line = [p(0.0), p(1.0), p(2.0), p(5.0)];
        let e = absolute_orientation(&line, &line, None, false).unwrap_err();
        assert!(e.to_string().contains("collinear"), "{e}");
        let two = [p(0.0), Point::new(1.0, 0.0, 0.0)];
        let e = absolute_orientation(&two, &two, None, false).unwrap_err();
        assert!(e.to_string().contains("at least 3"), "{e}");
        assert!(absolute_orientation(&line[..3], &line, None, false).is_err());
    }

    #[test]
    fn reflection_is_never_returned() {
        // A mirrored target: the best proper rotation is returned, never a reflection.
        let src = [
            Point::new(0.0, 0.0, 0.0),
            Point::new(10.0, 0.0, 0.0),
            Point::new(0.0, 10.0, 0.0),
            Point::new(0.0, 0.0, 10.0),
        ];
        let dst: Vec<Point> = src.iter().map(|p| Point::new(-p.x, p.y, p.z)).collect();
        let r = absolute_orientation(&src, &dst, None, false).unwrap();
        let det = r.rotation.to_rotation_matrix().matrix().determinant();
        assert!((det - 1.0).abs() < 1e-12);
        assert!(r.rms > 1.0);
    }
}
