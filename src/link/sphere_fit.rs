//! Joint centres as the centre common to several markers' spheres (Endo et al. 2014, section 3.4).
//!
//! * [`common_sphere_centre`]: Gamage & Lasenby (2002), "New least squares solutions for
//!   estimating the average centre of rotation and the axis of rotation", J. Biomech. 35(1):87-93,
//!   equation 5 (the estimator the seed paper cites as its reference 10).
//! * [`common_sphere_centre_bias_compensated`]: Halvorsen (2003), "Bias compensated least squares
//!   estimate of the center of rotation", J. Biomech. 36(7):999-1008 (BCLS).
//! * [`circle_centre_on_axis`]: the same estimator in the plane normal to a known axis, for 1-DOF
//!   joints whose markers move on circles (the 3D centre is then undetermined along the axis).
//!
//! All three are linear: each track contributes its mean, its covariance and one third-moment
//! vector, accumulated in one pass (two, for numerical centring) over the samples.

use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use nalgebra::{Matrix2, Matrix3, SymmetricEigen, Vector2};

/// Ratio of smallest to largest eigenvalue below which a scatter matrix is treated as singular:
/// the data then do not determine the estimate at all (far below any real motion's condition,
/// far above rounding noise on exactly degenerate data).
pub(crate) const SINGULAR: f64 = 1e-10;

/// True when `lo / hi` (smallest over largest eigenvalue) is a usable condition: `hi` positive and
/// the ratio at least [`SINGULAR`]. NaN anywhere gives false, so non-finite systems are refused.
pub(crate) fn determined(lo: f64, hi: f64) -> bool {
    hi > 0.0 && lo / hi >= SINGULAR
}

/// Iteration cap for Halvorsen's noise-variance fixed point; it converges in a handful of steps
/// on real data, the cap only guarantees termination.
const MAX_NOISE_ITERATIONS: usize = 100;

/// A common centre fitted to several markers' trajectories.
#[derive(Clone, Debug, PartialEq)]
pub struct SphereFit {
    /// The common centre, mm, in the frame of the input points.
    pub centre: Point,
    /// Per track: mean distance of its samples from the centre, mm (for
    /// [`circle_centre_on_axis`]: mean distance from the axis, i.e. the circle radius).
    pub radii: Vec<f64>,
    /// Per track: standard deviation (divisor N) of those distances, mm.
    pub radius_sd: Vec<f64>,
    /// Root mean square of `|p - c| - r_k` over all samples, mm.
    pub rms: f64,
    /// Smallest over largest eigenvalue of the summed per-track covariance matrix the centre is
    /// solved with (bias corrected for BCLS): 1 = the motion determines the centre equally well
    /// in all directions, near 0 = poorly along the weakest direction (small range of motion, or
    /// coplanar trajectories). Estimates below 1e-10 are refused as singular.
    pub condition: f64,
    /// Number of samples over all tracks.
    pub n_samples: usize,
    /// Marker noise standard deviation, mm, the bias compensation assumed (given or estimated);
    /// 0 for the plain least squares estimators.
    pub noise_sd: f64,
}

/// Check that there is at least one track, no track is empty, every coordinate is finite and
/// there are at least `min_samples` samples; returns the sample count.
pub(crate) fn check_tracks(tracks: &[&[Point]], what: &str, min_samples: usize) -> Result<usize> {
    if tracks.is_empty() {
        return Err(Error::invalid(format!("{what}: no marker tracks given")));
    }
    let mut n = 0;
    for (k, track) in tracks.iter().enumerate() {
        if track.is_empty() {
            return Err(Error::invalid(format!(
                "{what}: marker track {k} has no samples; drop markers that were never seen"
            )));
        }
        if let Some(i) = track
            .iter()
            .position(|p| !p.coords.iter().all(|x| x.is_finite()))
        {
            return Err(Error::invalid(format!(
                "{what}: marker track {k} sample {i} is not finite; remove gaps before fitting"
            )));
        }
        n += track.len();
    }
    if n < min_samples {
        return Err(Error::invalid(format!(
            "{what}: only {n} samples over all tracks, need at least {min_samples}"
        )));
    }
    Ok(n)
}

/// First, second and third moments of the tracks, after mapping every point through `map` and
/// shifting by the centroid of all mapped points (so squared norms stay small and the sums do not
/// cancel catastrophically for points far from the origin).
pub(crate) struct Moments {
    /// Centroid of all mapped samples; every other quantity is relative to it.
    pub origin: Vec3,
    /// Per track: sample count N_k.
    pub counts: Vec<usize>,
    /// Per track: mean m_k (relative to `origin`).
    pub means: Vec<Vec3>,
    /// Per track: covariance (1/N_k) sum (v - m_k)(v - m_k)^T.
    pub covariances: Vec<Matrix3<f64>>,
    /// Sum over tracks of the covariances (Gamage & Lasenby's A/2).
    pub scatter: Matrix3<f64>,
    /// Sum over tracks of (1/N_k) sum (v - m_k)|v|^2 (Gamage & Lasenby's b).
    pub rhs: Vec3,
}

/// Accumulate [`Moments`] of `tracks` mapped through `map` (identity for 3D fits, a projection for
/// the in-plane circle fit). Two passes over the samples, O(n).
pub(crate) fn moments(tracks: &[&[Point]], map: impl Fn(&Point) -> Vec3) -> Moments {
    let total: usize = tracks.iter().map(|t| t.len()).sum();
    let origin = tracks
        .iter()
        .flat_map(|t| t.iter())
        .fold(Vec3::zeros(), |acc, p| acc + map(p))
        / total.max(1) as f64;
    let mut m = Moments {
        origin,
        counts: Vec::with_capacity(tracks.len()),
        means: Vec::with_capacity(tracks.len()),
        covariances: Vec::with_capacity(tracks.len()),
        scatter: Matrix3::zeros(),
        rhs: Vec3::zeros(),
    };
    for track in tracks {
        let n = track.len().max(1) as f64;
        let mean = track
            .iter()
            .fold(Vec3::zeros(), |acc, p| acc + (map(p) - origin))
            / n;
        let mut cov = Matrix3::zeros();
        let mut b = Vec3::zeros();
        for p in track.iter() {
            let v = map(p) - origin;
            let d = v - mean;
            cov += d * d.transpose();
            b += d * v.norm_squared();
        }
        cov /= n;
        b /= n;
        m.scatter += cov;
        m.rhs += b;
        m.counts.push(track.len());
        m.means.push(mean);
        m.covariances.push(cov);
    }
    m
}

/// Eigen-decomposition of a symmetric 3x3 matrix with eigenvalues sorted ascending (columns of
/// the returned matrix are the matching unit eigenvectors).
pub(crate) fn sorted_eigen3(a: &Matrix3<f64>) -> ([f64; 3], Matrix3<f64>) {
    let eig = SymmetricEigen::new(*a);
    let mut idx = [0usize, 1, 2];
    idx.sort_by(|&i, &j| eig.eigenvalues[i].total_cmp(&eig.eigenvalues[j]));
    let vals = idx.map(|i| eig.eigenvalues[i]);
    let vecs = Matrix3::from_columns(&idx.map(|i| eig.eigenvectors.column(i).into_owned()));
    (vals, vecs)
}

/// Solve the (bias-compensated) Gamage-Lasenby normal equations in `dim` (2 or 3) dimensions:
/// `2 (S - s2 F I) c = b - 2 s2 sum_k f_k m_k`, with `S = sum_k cov_k`, `f_k = (N_k - 1) / N_k`
/// and `F = sum_k f_k`; `s2 = 0` is plain least squares. Returns the centre relative to
/// `m.origin` and the condition (smallest / largest eigenvalue of the corrected matrix), or
/// `None` when that matrix is singular or (after over-correction) not positive definite.
fn solve_centre(m: &Moments, s2: f64, dim: usize) -> Option<(Vec3, f64)> {
    let f: Vec<f64> = m
        .counts
        .iter()
        .map(|&n| (n as f64 - 1.0).max(0.0) / n.max(1) as f64)
        .collect();
    let f_sum: f64 = f.iter().sum();
    let mut a = m.scatter - Matrix3::identity() * (s2 * f_sum);
    let mut b = m.rhs;
    for (fk, mk) in f.iter().zip(&m.means) {
        b -= mk * (2.0 * s2 * fk);
    }
    if dim == 2 {
        let a2: Matrix2<f64> = a.fixed_view::<2, 2>(0, 0).into_owned();
        let b2 = Vector2::new(b.x, b.y);
        let eig = SymmetricEigen::new(a2);
        let (lo, hi) = (eig.eigenvalues.min(), eig.eigenvalues.max());
        if !determined(lo, hi) {
            return None;
        }
        let mut c = Vector2::zeros();
        for (v, lambda) in eig.eigenvectors.column_iter().zip(eig.eigenvalues.iter()) {
            c += v * (v.dot(&b2) / (2.0 * lambda));
        }
        return Some((Vec3::new(c.x, c.y, 0.0), lo / hi));
    }
    a = (a + a.transpose()) * 0.5;
    let (vals, vecs) = sorted_eigen3(&a);
    if !determined(vals[0], vals[2]) {
        return None;
    }
    let mut c = Vec3::zeros();
    for (v, lambda) in vecs.column_iter().zip(vals) {
        c += v * (v.dot(&b) / (2.0 * lambda));
    }
    Some((c, vals[0] / vals[2]))
}

/// Per-track mean and sd of `|map(p) - centre|` and the overall rms about the per-track means.
fn radial_stats(
    tracks: &[&[Point]],
    map: impl Fn(&Point) -> Vec3,
    centre: &Vec3,
) -> (Vec<f64>, Vec<f64>, f64) {
    let mut radii = Vec::with_capacity(tracks.len());
    let mut sds = Vec::with_capacity(tracks.len());
    let (mut sq, mut n_all) = (0.0, 0usize);
    for track in tracks {
        let n = track.len().max(1) as f64;
        let r = track.iter().map(|p| (map(p) - centre).norm()).sum::<f64>() / n;
        let ss: f64 = track
            .iter()
            .map(|p| ((map(p) - centre).norm() - r).powi(2))
            .sum();
        radii.push(r);
        sds.push((ss / n).sqrt());
        sq += ss;
        n_all += track.len();
    }
    (radii, sds, (sq / n_all.max(1) as f64).sqrt())
}

/// Halvorsen's (2003) noise-variance estimate from the spread of squared distances: with
/// isotropic noise of variance s2, `|p - c|^2 - mean_k |p - c|^2` has variance about
/// `4 r_k^2 s2`, so `s2 = sum_k sum_i (u_i^2 - mean u^2)^2 / (4 mean u^2) / N` (tracks pooled by
/// sample count). `centre` is in original coordinates.
fn halvorsen_noise_variance(tracks: &[&[Point]], centre: &Point) -> f64 {
    let (mut acc, mut n_all) = (0.0, 0usize);
    for track in tracks {
        let n = track.len() as f64;
        let mean_u2 = track
            .iter()
            .map(|p| (p - centre).norm_squared())
            .sum::<f64>()
            / n;
        if mean_u2 > 0.0 {
            let ss: f64 = track
                .iter()
                .map(|p| ((p - centre).norm_squared() - mean_u2).powi(2))
                .sum();
            acc += ss / (4.0 * mean_u2);
        }
        n_all += track.len();
    }
    acc / n_all.max(1) as f64
}

fn singular_sphere(what: &str) -> Error {
    Error::invalid(format!(
        "{what}: the motion does not determine a centre (markers static, collinear or all in one \
         plane); record a wider range of motion, or use circle_centre_on_axis for a 1-DOF joint"
    ))
}

/// Common centre of several markers' spheres, each with its own radius, by linear least squares
/// (Gamage & Lasenby 2002, eq. 5).
///
/// * `tracks`: one slice per marker of its positions (mm), already in the parent link's
///   reference frame (Endo et al. 2014, eq. 1); lengths may differ (gaps removed).
/// * Returns the centre `c` solving `2 (sum_k cov_k) c = sum_k b_k` with
///   `cov_k = mean_i (v_ki - m_k)(v_ki - m_k)^T` and `b_k = mean_i (v_ki - m_k)|v_ki|^2`: the
///   minimiser of `sum_k (1/N_k) sum_i (|v_ki - c|^2 - r_k^2)^2` over `c` and all `r_k`. As in the
///   paper each marker is weighted by `1/N_k`, so a marker with gaps counts as much as one
///   without; with equal lengths this is the plain least squares over all samples.
///
/// The estimate is biased towards the markers when the noise is not small against the range of
/// motion (Halvorsen 2003); see [`common_sphere_centre_bias_compensated`].
///
/// Errors (one line): no tracks, an empty track, a non-finite sample, fewer than 4 samples, or a
/// singular scatter matrix (condition below 1e-10: static, collinear or coplanar trajectories).
pub fn common_sphere_centre(tracks: &[&[Point]]) -> Result<SphereFit> {
    const WHAT: &str = "sphere fit";
    let n = check_tracks(tracks, WHAT, 4)?;
    let m = moments(tracks, |p| p.coords);
    let (c, condition) = solve_centre(&m, 0.0, 3).ok_or_else(|| singular_sphere(WHAT))?;
    let centre = Point::from(m.origin + c);
    let (radii, radius_sd, rms) = radial_stats(tracks, |p| p.coords, &centre.coords);
    Ok(SphereFit {
        centre,
        radii,
        radius_sd,
        rms,
        condition,
        n_samples: n,
        noise_sd: 0.0,
    })
}

/// Bias-compensated common sphere centre, BCLS (Halvorsen 2003, in
/// the multi-marker form of Gamage & Lasenby 2002).
///
/// With isotropic marker noise of variance s2, the expected per-track covariance gains
/// `f_k s2 I` and `b_k` gains `2 f_k s2 m_k`, `f_k = (N_k - 1)/N_k`. Subtracting both,
/// `2 (sum_k cov_k - s2 sum_k f_k I) c = sum_k (b_k - 2 s2 f_k m_k)`, removes the bias of
/// [`common_sphere_centre`], which grows as the range of motion shrinks. (Halvorsen writes the
/// correction as `b - 2 s2 sum_k (m_k - c)` solved iteratively in c; it is the same equation.)
///
/// * `noise_sd`: the marker noise standard deviation (mm) if known. When `None` it is estimated
///   as Halvorsen does: start from the plain estimate, set `s2` from the spread of the squared
///   distances to the current centre (`var(|p - c|^2) ~ 4 r^2 s2`, pooled over tracks by sample
///   count), re-solve, and repeat until the centre moves by less than 1e-12 of the data's extent
///   (at most 100 rounds).
/// * Returns the centre with `noise_sd` set to the value used; `condition` is that of the
///   corrected matrix.
///
/// Errors as [`common_sphere_centre`], plus: `noise_sd` negative or not finite, or a noise
/// level so large against the motion that the corrected matrix is no longer positive definite.
pub fn common_sphere_centre_bias_compensated(
    tracks: &[&[Point]],
    noise_sd: Option<f64>,
) -> Result<SphereFit> {
    const WHAT: &str = "bias-compensated sphere fit";
    if let Some(sd) = noise_sd {
        if !(sd.is_finite() && sd >= 0.0) {
            return Err(Error::invalid(format!(
                "{WHAT}: noise_sd {sd} mm must be finite and non-negative"
            )));
        }
    }
    let n = check_tracks(tracks, WHAT, 4)?;
    let m = moments(tracks, |p| p.coords);
    let too_noisy = |s2: f64| {
        Error::invalid(format!(
            "{WHAT}: marker noise (sd {:.3} mm) is as large as the motion's extent, so the \
             centre is undetermined; record a wider range of motion",
            s2.sqrt()
        ))
    };
    let (c, condition, s2) = match noise_sd {
        Some(sd) => {
            let s2 = sd * sd;
            let (c, cond) = solve_centre(&m, 0.0, 3)
                .ok_or_else(|| singular_sphere(WHAT))
                .and_then(|_| solve_centre(&m, s2, 3).ok_or_else(|| too_noisy(s2)))?;
            (c, cond, s2)
        }
        None => {
            let (mut c, mut cond) =
                solve_centre(&m, 0.0, 3).ok_or_else(|| singular_sphere(WHAT))?;
            let scale = m.scatter.trace().sqrt().max(f64::MIN_POSITIVE);
            let mut s2 = 0.0;
            for _ in 0..MAX_NOISE_ITERATIONS {
                s2 = halvorsen_noise_variance(tracks, &Point::from(m.origin + c));
                let (c_new, cond_new) = solve_centre(&m, s2, 3).ok_or_else(|| too_noisy(s2))?;
                let step = (c_new - c).norm();
                c = c_new;
                cond = cond_new;
                if step <= 1e-12 * scale {
                    break;
                }
            }
            (c, cond, s2)
        }
    };
    let centre = Point::from(m.origin + c);
    let (radii, radius_sd, rms) = radial_stats(tracks, |p| p.coords, &centre.coords);
    Ok(SphereFit {
        centre,
        radii,
        radius_sd,
        rms,
        condition,
        n_samples: n,
        noise_sd: s2.sqrt(),
    })
}

/// Orthonormal basis (e1, e2) of the plane normal to the unit vector `a`.
pub(crate) fn plane_basis(a: &Vec3) -> (Vec3, Vec3) {
    // Cross with the coordinate axis least aligned with `a`, so the result is well conditioned.
    let i = a.iamin();
    let mut helper = Vec3::zeros();
    helper[i] = 1.0;
    let e1 = a.cross(&helper).normalize();
    let e2 = a.cross(&e1);
    (e1, e2)
}

/// Centre of a 1-DOF joint: the common centre of the circles its markers move on, placed on the
/// axis line at the point closest to `near` (Gamage & Lasenby 2002, eq. 5, in two dimensions).
///
/// Markers of a hinge move on circles in parallel planes; a 3D sphere fit is then undetermined
/// along the axis (its scatter matrix is singular in that direction). So every sample is
/// projected onto the plane normal to `axis`, the common circle centre is fitted there with the
/// planar Gamage-Lasenby equations (the circles' centres coincide in projection: they all lie on
/// the axis), and the axis line through that centre is where the joint is. Which point of the
/// line is the joint centre the motion cannot tell; this returns the one closest to `near` (e.g.
/// the sphere-fit estimate, or a point between the finger's edge landmarks, which is how the
/// seed paper refines it in section 3.6).
///
/// * `tracks`: marker positions (mm) in the parent's reference frame, as for
///   [`common_sphere_centre`]; `axis`: the joint axis direction (any length but zero, e.g. from
///   [`crate::link::axis_fit::common_plane_normal`]); `near`: a point (mm) fixing the position
///   along the axis.
/// * Returns a [`SphereFit`] whose `radii`, `radius_sd` and `rms` are in-plane (distances from
///   the axis, i.e. circle radii) and whose `condition` is that of the 2x2 in-plane scatter.
///
/// Errors: the track errors of [`common_sphere_centre`], fewer than 3 samples, a zero or
/// non-finite axis or non-finite `near`, or projected motion that is static or along a line.
pub fn circle_centre_on_axis(tracks: &[&[Point]], axis: &Vec3, near: &Point) -> Result<SphereFit> {
    const WHAT: &str = "circle fit on axis";
    let len = axis.norm();
    if !(len.is_finite() && len > 0.0) {
        return Err(Error::invalid(format!(
            "{WHAT}: axis ({}, {}, {}) must be finite and non-zero",
            axis.x, axis.y, axis.z
        )));
    }
    if !near.coords.iter().all(|x| x.is_finite()) {
        return Err(Error::invalid(format!(
            "{WHAT}: `near` point is not finite"
        )));
    }
    let n = check_tracks(tracks, WHAT, 3)?;
    let a = axis / len;
    let (e1, e2) = plane_basis(&a);
    let project = |p: &Point| {
        let d = p - near;
        Vec3::new(d.dot(&e1), d.dot(&e2), 0.0)
    };
    let m = moments(tracks, project);
    let (c, condition) = solve_centre(&m, 0.0, 2).ok_or_else(|| {
        Error::invalid(format!(
            "{WHAT}: the markers' motion about the axis does not determine a circle centre \
             (static, or along a line); check the axis and the trial"
        ))
    })?;
    let c2 = m.origin + c;
    let centre = near + e1 * c2.x + e2 * c2.y;
    let (radii, radius_sd, rms) = radial_stats(tracks, project, &c2);
    Ok(SphereFit {
        centre,
        radii,
        radius_sd,
        rms,
        condition,
        n_samples: n,
        noise_sd: 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;
    use nalgebra::UnitQuaternion;
    use proptest::prelude::*;

    /// Markers rigidly attached to a child segment rotating about `centre`: marker k sits at
    /// `centre + R_t o_k`, with the rotation vectors of R_t uniform in a cube of half-width
    /// `max_angle` (rad). Returns the noise-free tracks and the offsets o_k.
    fn rotating_markers(
        rng: &mut Rng,
        centre: &Point,
        offsets: &[Vec3],
        frames: usize,
        max_angle: f64,
    ) -> Vec<Vec<Point>> {
        let rotations: Vec<UnitQuaternion<f64>> = (0..frames)
            .map(|_| {
                UnitQuaternion::from_scaled_axis(Vec3::new(
                    rng.range(-max_angle, max_angle),
                    rng.range(-max_angle, max_angle),
                    rng.range(-max_angle, max_angle),
                ))
            })
            .collect();
        offsets
            .iter()
            .map(|o| rotations.iter().map(|r| centre + r * o).collect())
            .collect()
    }

    fn offsets(rng: &mut Rng, k: usize) -> Vec<Vec3> {
        // Markers on one segment: roughly along +x from the joint, 30-60 mm away.
        (0..k)
            .map(|_| {
                let d = (Vec3::new(1.0, 0.0, 0.0) + rng.gauss3(0.3)).normalize();
                d * rng.range(30.0, 60.0)
            })
            .collect()
    }

    fn as_slices(tracks: &[Vec<Point>]) -> Vec<&[Point]> {
        tracks.iter().map(|t| t.as_slice()).collect()
    }

    #[test]
    fn exact_centre_full_sphere_different_radii_and_lengths() {
        let mut rng = Rng::new(1);
        let centre = Point::new(812.0, -340.5, 1210.25); // far from the origin on purpose
        let offs = offsets(&mut rng, 4);
        let mut tracks = rotating_markers(&mut rng, &centre, &offs, 300, std::f64::consts::PI);
        tracks[1].truncate(120); // gaps removed: different lengths
        tracks[3].drain(0..250);
        let fit = common_sphere_centre(&as_slices(&tracks)).unwrap();
        assert!((fit.centre - centre).norm() < 1e-9, "{:?}", fit.centre);
        for (r, o) in fit.radii.iter().zip(&offs) {
            assert!((r - o.norm()).abs() < 1e-9);
        }
        assert!(fit.rms < 1e-9 && fit.radius_sd.iter().all(|&s| s < 1e-9));
        assert_eq!(fit.n_samples, 300 + 120 + 300 + 50);
        assert!(fit.condition > 0.05 && fit.condition <= 1.0);
        // Without noise the bias compensation must not move the centre.
        let bc = common_sphere_centre_bias_compensated(&as_slices(&tracks), None).unwrap();
        assert!((bc.centre - centre).norm() < 1e-9 && bc.noise_sd < 1e-6);
    }

    #[test]
    fn exact_centre_partial_caps() {
        for (seed, deg) in [(2u64, 20.0f64), (3, 10.0), (4, 5.0)] {
            let mut rng = Rng::new(seed);
            let centre = Point::new(rng.range(-50.0, 50.0), 20.0, -7.0);
            let offs = offsets(&mut rng, 3);
            let tracks = rotating_markers(&mut rng, &centre, &offs, 200, deg.to_radians());
            let fit = common_sphere_centre(&as_slices(&tracks)).unwrap();
            assert!(
                (fit.centre - centre).norm() < 1e-9,
                "cap {deg} deg: {}",
                (fit.centre - centre).norm()
            );
            // Smaller caps determine the centre less well.
            assert!(fit.condition < 0.1);
        }
    }

    /// Lower bound on the centre's covariance for geometric sphere fitting with isotropic noise
    /// of variance s2 (Cramer-Rao, radii as nuisance parameters): s2 (sum_k sum_i (u - u_k)(u -
    /// u_k)^T)^-1 with u the unit directions from the centre. Returns its trace's square root.
    fn crlb_sd(tracks: &[Vec<Point>], centre: &Point, sd: f64) -> f64 {
        let mut info = Matrix3::zeros();
        for t in tracks {
            let us: Vec<Vec3> = t.iter().map(|p| (p - centre).normalize()).collect();
            let mean = us.iter().sum::<Vec3>() / us.len() as f64;
            for u in &us {
                info += (u - mean) * (u - mean).transpose();
            }
        }
        (info.try_inverse().unwrap().trace()).sqrt() * sd
    }

    #[test]
    fn bias_compensation_beats_plain_least_squares_on_small_caps() {
        let sd = 0.2;
        let trials = 50;
        let (mut err_ls, mut err_bc) = (0.0, 0.0);
        for trial in 0..trials {
            let mut rng = Rng::new(100 + trial);
            let centre = Point::new(rng.range(-30.0, 30.0), rng.range(-30.0, 30.0), 0.0);
            let offs = offsets(&mut rng, 4);
            let clean = rotating_markers(&mut rng, &centre, &offs, 200, 20f64.to_radians());
            let noisy: Vec<Vec<Point>> = clean
                .iter()
                .map(|t| t.iter().map(|p| p + rng.gauss3(sd)).collect())
                .collect();
            let ls = common_sphere_centre(&as_slices(&noisy)).unwrap();
            let bc = common_sphere_centre_bias_compensated(&as_slices(&noisy), None).unwrap();
            let known =
                common_sphere_centre_bias_compensated(&as_slices(&noisy), Some(sd)).unwrap();
            let e_ls = (ls.centre - centre).norm();
            let e_bc = (bc.centre - centre).norm();
            err_ls += e_ls;
            err_bc += e_bc;

            // Bounds from the noise model. LS: its first-order expectation is the solution of the
            // noise-inflated normal equations built from the clean points; it may deviate from
            // that by the estimator's spread, bounded here by 6 CRLB standard deviations.
            let spread = crlb_sd(&clean, &centre, sd);
            let m0 = moments(&as_slices(&clean), |p| p.coords);
            let (c_expect, _) = solve_centre(&m0, -sd * sd, 3).unwrap();
            let ls_expect = Point::from(m0.origin + c_expect);
            assert!(
                (ls.centre - ls_expect).norm() < 6.0 * spread,
                "trial {trial}: LS {} from its expected biased value, bound {}",
                (ls.centre - ls_expect).norm(),
                6.0 * spread
            );
            // BCLS is unbiased to first order: within 6 CRLB sds of the truth.
            assert!(
                e_bc < 6.0 * spread,
                "trial {trial}: BCLS error {e_bc}, bound {}",
                6.0 * spread
            );
            assert!((known.centre - centre).norm() < 6.0 * spread);
            // The estimated noise is the simulated one (radial component only, so within 20%).
            assert!((bc.noise_sd - sd).abs() < 0.2 * sd, "noise {}", bc.noise_sd);
        }
        let (err_ls, err_bc) = (err_ls / trials as f64, err_bc / trials as f64);
        assert!(
            err_bc < 0.75 * err_ls,
            "mean error BCLS {err_bc} vs LS {err_ls}"
        );
    }

    #[test]
    fn circle_centre_on_known_axis() {
        let mut rng = Rng::new(7);
        let axis = rng.unit_vector();
        let centre = Point::new(40.0, -12.0, 5.0);
        let (e1, e2) = plane_basis(&axis);
        // Three markers on circles at different heights along the axis, partial arcs.
        let tracks: Vec<Vec<Point>> = [(25.0, -4.0), (32.0, 3.0), (18.0, 9.0)]
            .iter()
            .map(|&(r, h): &(f64, f64)| {
                let phase = rng.range(0.0, 6.0);
                (0..150)
                    .map(|i| {
                        let t = phase + 1.5 * i as f64 / 149.0;
                        centre + axis * h + (e1 * t.cos() + e2 * t.sin()) * r
                    })
                    .collect()
            })
            .collect();
        let near = centre + axis * 7.5 + e1 * 3.0 - e2 * 2.0;
        let fit = circle_centre_on_axis(&as_slices(&tracks), &(axis * 3.0), &near).unwrap();
        let expect = centre + axis * 7.5; // the axis point closest to `near`
        assert!(
            (fit.centre - expect).norm() < 1e-9,
            "{}",
            (fit.centre - expect).norm()
        );
        for (r, want) in fit.radii.iter().zip([25.0, 32.0, 18.0]) {
            assert!((r - want).abs() < 1e-9);
        }
        assert!(fit.rms < 1e-9);
        // The same data are singular for the 3D sphere fit only if coplanar; one circle is.
        assert!(common_sphere_centre(&[tracks[0].as_slice()]).is_err());
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let p = Point::new(1.0, 2.0, 3.0);
        let empty: &[Point] = &[];
        assert!(common_sphere_centre(&[]).is_err());
        assert!(common_sphere_centre(&[empty]).is_err());
        assert!(common_sphere_centre(&[&[p, p, p]]).is_err()); // < 4 samples
        assert!(common_sphere_centre(&[&[p; 10]]).is_err()); // static
        let line: Vec<Point> = (0..10).map(|i| Point::new(i as f64, 0.0, 0.0)).collect();
        assert!(common_sphere_centre(&[&line]).is_err());
        let mut nan = line.clone();
        nan[4].y = f64::NAN;
        let e = common_sphere_centre(&[&line, &nan])
            .unwrap_err()
            .to_string();
        assert!(e.contains("track 1 sample 4"), "{e}");
        assert!(common_sphere_centre_bias_compensated(&[&line], Some(-1.0)).is_err());
        assert!(common_sphere_centre_bias_compensated(&[&line], Some(f64::NAN)).is_err());
        let z = Vec3::zeros();
        assert!(circle_centre_on_axis(&[&line], &z, &p).is_err());
        assert!(circle_centre_on_axis(&[&line], &Vec3::x(), &p).is_err()); // projects to a point
        assert!(circle_centre_on_axis(&[&line], &Vec3::z(), &p).is_err()); // projects to a line
                                                                           // A huge assumed noise cannot be compensated.
        let mut rng = Rng::new(9);
        let offs = offsets(&mut rng, 2);
        let tracks = rotating_markers(&mut rng, &p, &offs, 50, 0.3);
        let r = common_sphere_centre_bias_compensated(&as_slices(&tracks), Some(100.0));
        assert!(r.is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        /// Arbitrary small point sets: an error or a finite result, never a panic or NaN.
        #[test]
        fn never_panics_or_nan(
            pts in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3, -1e3f64..1e3), 0..12),
            split in 0usize..12,
            sd in proptest::option::of(0.0f64..5.0),
        ) {
            let pts: Vec<Point> = pts.into_iter().map(|(x, y, z)| Point::new(x, y, z)).collect();
            let s = split.min(pts.len());
            let tracks = [&pts[..s], &pts[s..]];
            let check = |r: Result<SphereFit>| {
                if let Ok(f) = r {
                    assert!(f.centre.coords.iter().all(|x| x.is_finite()));
                    assert!(f.rms.is_finite() && f.condition.is_finite() && f.noise_sd.is_finite());
                    assert!(f.radii.iter().chain(&f.radius_sd).all(|x| x.is_finite()));
                }
            };
            check(common_sphere_centre(&tracks));
            check(common_sphere_centre_bias_compensated(&tracks, sd));
            check(circle_centre_on_axis(&tracks, &Vec3::new(0.3, -1.0, 0.2), &Point::origin()));
        }
    }
}
