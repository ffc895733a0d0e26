//! Axes of 1-DOF joints as the normal common to the planes the markers move in (Endo et al. 2014,
//! section 3.4), after Gamage & Lasenby (2002), "New least squares solutions for estimating the
//! average centre of rotation and the axis of rotation", J. Biomech. 35(1):87-93.

use super::sphere_fit::{check_tracks, determined, moments, sorted_eigen3};
use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};

/// A rotation axis direction fitted to several markers' trajectories.
#[derive(Clone, Debug, PartialEq)]
pub struct AxisFit {
    /// Unit axis direction. Its sign carries no meaning: it is made deterministic (the component
    /// of largest magnitude is positive) but the caller orients it, e.g. so that flexion is a
    /// positive rotation about it.
    pub axis: Vec3,
    /// Root mean square distance of all samples from their own track's plane, mm.
    pub plane_rms: f64,
    /// Smallest over second-smallest eigenvalue of the summed covariance: near 0 = the motion
    /// lies in parallel planes (a hinge); near 1 = it does not define a plane (the axis is then
    /// meaningless, e.g. a 3-DOF joint or too little motion).
    pub condition: f64,
    /// Per track: signed position of its plane along `axis`, `axis . mean_k` (mm), i.e. the plane
    /// of track k is `{x : axis . x = offsets[k]}`.
    pub offsets: Vec<f64>,
    /// Number of samples over all tracks.
    pub n_samples: usize,
}

/// Common normal of the planes several markers move in (Gamage & Lasenby 2002).
///
/// * `tracks`: one slice per marker of its positions (mm) in the parent's reference frame
///   (Endo et al. 2014, eq. 1); lengths may differ.
/// * Returns the unit `n` minimising `sum_k (1/N_k) sum_i (n . (v_ki - m_k))^2`, each marker
///   having its own plane offset: the eigenvector of the smallest eigenvalue of
///   `sum_k cov_k` (per-marker covariances, so each marker is weighted by `1/N_k` as in the
///   paper).
///
/// Errors (one line): no tracks, an empty track, a non-finite sample, fewer than 3 samples, or
/// motion that does not span a plane (static or along a line; second-smallest eigenvalue below
/// 1e-10 of the largest).
pub fn common_plane_normal(tracks: &[&[Point]]) -> Result<AxisFit> {
    const WHAT: &str = "axis fit";
    let n = check_tracks(tracks, WHAT, 3)?;
    let m = moments(tracks, |p| p.coords);
    let (vals, vecs) = sorted_eigen3(&m.scatter);
    if !determined(vals[1], vals[2]) {
        return Err(Error::invalid(format!(
            "{WHAT}: the markers do not move in a plane (static or along a line); check that \
             the trial moves the joint"
        )));
    }
    let mut axis: Vec3 = vecs.column(0).into_owned();
    if axis[axis.iamax()] < 0.0 {
        axis = -axis;
    }
    // From the samples rather than from axis^T cov axis, whose rounding (relative to the
    // in-plane variance) would dominate the square root for exact hinges.
    let sq: f64 = tracks
        .iter()
        .zip(&m.means)
        .map(|(track, mk)| {
            let offset = axis.dot(&(m.origin + mk));
            track
                .iter()
                .map(|p| (axis.dot(&p.coords) - offset).powi(2))
                .sum::<f64>()
        })
        .sum();
    Ok(AxisFit {
        axis,
        plane_rms: (sq / n as f64).sqrt(),
        condition: (vals[0].max(0.0) / vals[1]).min(1.0),
        offsets: m
            .means
            .iter()
            .map(|mk| axis.dot(&(m.origin + mk)))
            .collect(),
        n_samples: n,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::link::sphere_fit::plane_basis;
    use crate::rng::Rng;
    use proptest::prelude::*;

    /// Angle between two lines (sign-free), degrees, accurate near 0.
    fn line_angle_deg(a: &Vec3, b: &Vec3) -> f64 {
        a.normalize()
            .cross(&b.normalize())
            .norm()
            .asin()
            .to_degrees()
    }

    /// Markers turning about the line through `centre` along `axis` by a common angle per frame,
    /// each at its own radius and height; returns the tracks.
    fn hinge_tracks(rng: &mut Rng, centre: &Point, axis: &Vec3, frames: usize) -> Vec<Vec<Point>> {
        let (e1, e2) = plane_basis(axis);
        let angles: Vec<f64> = (0..frames).map(|_| rng.range(0.0, 1.6)).collect();
        [(22.0, -6.0, 0.3), (35.0, 2.0, 1.0), (28.0, 8.0, -0.4)]
            .iter()
            .map(|&(r, h, phase): &(f64, f64, f64)| {
                angles
                    .iter()
                    .map(|t| {
                        centre + axis * h + (e1 * (t + phase).cos() + e2 * (t + phase).sin()) * r
                    })
                    .collect()
            })
            .collect()
    }

    fn as_slices(tracks: &[Vec<Point>]) -> Vec<&[Point]> {
        tracks.iter().map(|t| t.as_slice()).collect()
    }

    #[test]
    fn exact_axis_without_noise() {
        for seed in 0..5 {
            let mut rng = Rng::new(seed);
            let axis = rng.unit_vector();
            let centre = Point::new(300.0, -120.0, 950.0);
            let mut tracks = hinge_tracks(&mut rng, &centre, &axis, 200);
            tracks[2].truncate(77);
            let fit = common_plane_normal(&as_slices(&tracks)).unwrap();
            assert!(line_angle_deg(&fit.axis, &axis) < 1e-9);
            assert!((fit.axis.norm() - 1.0).abs() < 1e-12);
            assert!(
                fit.plane_rms < 1e-9 && fit.condition < 1e-12,
                "{} {}",
                fit.plane_rms,
                fit.condition
            );
            // Offsets are the planes' heights along the axis (up to the common sign).
            let s = fit.axis.dot(&axis).signum();
            let base = axis.dot(&centre.coords);
            for (o, h) in fit.offsets.iter().zip([-6.0, 2.0, 8.0]) {
                assert!((s * o - (base + h)).abs() < 1e-9, "{o} vs {}", base + h);
            }
            assert_eq!(fit.n_samples, 477);
        }
    }

    #[test]
    fn axis_within_noise_bound() {
        let sd = 0.2;
        for seed in 10..30 {
            let mut rng = Rng::new(seed);
            let axis = rng.unit_vector();
            let clean = hinge_tracks(&mut rng, &Point::origin(), &axis, 300);
            let noisy: Vec<Vec<Point>> = clean
                .iter()
                .map(|t| t.iter().map(|p| p + rng.gauss3(sd)).collect())
                .collect();
            let fit = common_plane_normal(&as_slices(&noisy)).unwrap();
            // First-order tilt variance about in-plane direction j is sd^2 / (N lambda_j), with
            // lambda_j the clean in-plane scatter eigenvalues (per-sample, summed over markers).
            let (vals, _) = sorted_eigen3(&moments(&as_slices(&clean), |p| p.coords).scatter);
            let tilt = sd * (1.0 / (300.0 * vals[1]) + 1.0 / (300.0 * vals[2])).sqrt();
            let err = line_angle_deg(&fit.axis, &axis).to_radians();
            assert!(
                err < 6.0 * tilt,
                "seed {seed}: {err} rad vs bound {}",
                6.0 * tilt
            );
            // Plane residual: the out-of-plane noise component.
            assert!((fit.plane_rms - sd).abs() < 0.2 * sd, "{}", fit.plane_rms);
            assert!(fit.condition < 0.01);
        }
    }

    #[test]
    fn spherical_motion_has_condition_near_one() {
        let mut rng = Rng::new(3);
        let tracks: Vec<Vec<Point>> = (0..3)
            .map(|_| {
                let r = rng.range(20.0, 40.0);
                (0..400)
                    .map(|_| Point::from(rng.unit_vector() * r))
                    .collect()
            })
            .collect();
        let fit = common_plane_normal(&as_slices(&tracks)).unwrap();
        assert!(fit.condition > 0.5, "{}", fit.condition);
    }

    #[test]
    fn degenerate_inputs_are_errors() {
        let p = Point::new(1.0, 2.0, 3.0);
        let empty: &[Point] = &[];
        assert!(common_plane_normal(&[]).is_err());
        assert!(common_plane_normal(&[empty]).is_err());
        assert!(common_plane_normal(&[&[p, p]]).is_err());
        assert!(common_plane_normal(&[&[p; 20]]).is_err());
        let line: Vec<Point> = (0..10)
            .map(|i| Point::new(i as f64, 2.0 * i as f64, 0.0))
            .collect();
        assert!(common_plane_normal(&[&line, &line]).is_err());
        let mut inf = line.clone();
        inf[0].z = f64::INFINITY;
        let e = common_plane_normal(&[&inf]).unwrap_err().to_string();
        assert!(e.contains("track 0 sample 0"), "{e}");
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]
        #[test]
        fn never_panics_or_nan(
            pts in proptest::collection::vec((-1e3f64..1e3, -1e3f64..1e3, -1e3f64..1e3), 0..12),
            split in 0usize..12,
        ) {
            let pts: Vec<Point> = pts.into_iter().map(|(x, y, z)| Point::new(x, y, z)).collect();
            let s = split.min(pts.len());
            if let Ok(f) = common_plane_normal(&[&pts[..s], &pts[s..]]) {
                prop_assert!((f.axis.norm() - 1.0).abs() < 1e-9);
                prop_assert!(f.plane_rms.is_finite() && f.condition.is_finite());
                prop_assert!(f.offsets.iter().all(|o| o.is_finite()));
            }
        }
    }
}
