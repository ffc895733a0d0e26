//! Gates that stop a wrong input before it becomes a confident wrong hand: marker clouds of the
//! wrong size for a hand (a wrong `POINT:UNITS`), single absurd samples, a marker far from all
//! the others, and a static trial whose landmarks are of the other hand than `subject.toml`
//! declares.
//!
//! Every test works on robust statistics (medians and median absolute deviations), so a few bad
//! samples never move what the others are judged against.

use crate::anatomy::Side;
use crate::error::{Error, Result};
use crate::geometry::Point;

type Vector = nalgebra::Vector3<f64>;
use crate::io::Units;
use crate::mocap::trajectories::Trajectories;

/// Median distance of a trial's markers from their common centre that a hand can have, mm:
/// a hand spans 100-250 mm and its markers lie some 20-120 mm from their centre; the bounds
/// leave a factor of two on each side and exclude every wrong unit among m, cm, mm and in
/// (each at least 10 times off).
pub(crate) const HAND_MARKER_RADIUS_MM: (f64, f64) = (10.0, 250.0);

/// A marker whose median position lies further than this from the trial's marker centre is not
/// on the hand or forearm (mislabelled, or a coordinate off), mm.
pub(crate) const FAR_MARKER_MM: f64 = 600.0;

/// Least distance beyond a marker's median distance from its median position at which a sample
/// counts as an outlier, mm: larger than any motion of the calibration protocol moves a marker
/// about its median (wrist circumduction moves a fingertip marker some 150 mm).
pub const OUTLIER_FLOOR_MM: f64 = 300.0;

/// Outlier threshold in robust standard deviations (1.4826 x MAD) beyond the median distance.
pub(crate) const OUTLIER_MADS: f64 = 10.0;

/// Coordinate-wise median of `points` (`None` when empty).
fn median_point(points: &[Point]) -> Option<Point> {
    if points.is_empty() {
        return None;
    }
    let mut c = [0.0; 3];
    for (k, ck) in c.iter_mut().enumerate() {
        let mut v: Vec<f64> = points.iter().map(|p| p[k]).collect();
        *ck = median(&mut v);
    }
    Some(Point::new(c[0], c[1], c[2]))
}

/// Median of `v` (reordered); 0 for an empty slice.
pub(crate) fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_unstable_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The median position of every marker with a sample, as (label, position).
pub(crate) fn marker_medians(traj: &Trajectories) -> Vec<(&str, Point)> {
    traj.labels
        .iter()
        .zip(&traj.positions)
        .filter_map(|(l, t)| {
            let present: Vec<Point> = t.iter().flatten().copied().collect();
            median_point(&present).map(|p| (l.as_str(), p))
        })
        .collect()
}

/// Drop, per marker, the samples further from the marker's median position than its median
/// distance plus the larger of [`OUTLIER_MADS`] robust SDs and [`OUTLIER_FLOOR_MM`] (a robust
/// outlier test: median and MAD are moved by no single sample). Returns (marker, samples
/// dropped) for every marker that lost any.
pub fn drop_outliers(traj: &mut Trajectories) -> Vec<(String, usize)> {
    let mut dropped = Vec::new();
    for (label, track) in traj.labels.iter().zip(traj.positions.iter_mut()) {
        let present: Vec<Point> = track.iter().flatten().copied().collect();
        let Some(centre) = median_point(&present) else {
            continue;
        };
        let mut d: Vec<f64> = present.iter().map(|p| (p - centre).norm()).collect();
        let med = median(&mut d);
        let mut dev: Vec<f64> = d.iter().map(|x| (x - med).abs()).collect();
        let sd = 1.4826 * median(&mut dev);
        let limit = med + (OUTLIER_MADS * sd).max(OUTLIER_FLOOR_MM);
        let mut n = 0;
        for s in track.iter_mut() {
            if s.is_some_and(|p| (p - centre).norm() > limit) {
                *s = None;
                n += 1;
            }
        }
        if n > 0 {
            dropped.push((label.clone(), n));
        }
    }
    dropped
}

/// Check that the markers of `traj`, read with `units` (the file's `POINT:UNITS`), are the size
/// of a hand: the median distance of the markers' median positions from their common centre
/// within [`HAND_MARKER_RADIUS_MM`] (else an error naming `POINT:UNITS` and the unit the values
/// look like), and no marker further than [`FAR_MARKER_MM`] from that centre (else an error
/// naming the marker). Errors name the file.
pub fn check_hand_scale(traj: &Trajectories, units: Units) -> Result<()> {
    let medians = marker_medians(traj);
    let pts: Vec<Point> = medians.iter().map(|m| m.1).collect();
    let Some(centre) = median_point(&pts) else {
        return Ok(());
    };
    let mut r: Vec<f64> = pts.iter().map(|p| (p - centre).norm()).collect();
    let r_med = median(&mut r);
    let (lo, hi) = HAND_MARKER_RADIUS_MM;
    if medians.len() >= 3 && !(lo..=hi).contains(&r_med) {
        // The unit under which the values would put the markers nearest a typical hand's
        // 50 mm, on a log scale.
        let raw = r_med / units.to_mm();
        let likely = Units::likely(raw, 50.0);
        return Err(Error::input(
            &traj.source,
            format!(
                "POINT:UNITS is '{units}' but then the markers lie a median {r_med:.3} mm from \
                 their centre, where a hand's lie {lo}-{hi} mm; the values look like {likely}: \
                 fix POINT:UNITS in the file"
            ),
        ));
    }
    for ((label, p), d) in medians.iter().zip(pts.iter().map(|p| (p - centre).norm())) {
        if d > FAR_MARKER_MM {
            return Err(Error::input(
                &traj.source,
                format!(
                    "marker '{label}' lies {d:.0} mm from the other markers' centre (at \
                     [{:.0}, {:.0}, {:.0}] mm), beyond any hand; mislabelled or a wrong coordinate",
                    p.x, p.y, p.z
                ),
            ));
        }
    }
    Ok(())
}

/// The hand whose landmarks `traj` (a static trial) holds, or `None` when the landmarks it
/// needs are missing or the test is not clear-cut.
///
/// The method: three directions from the landmarks, each independent of how a lab orders its
/// palm markers: distal (the mid-point of the MCP lateral landmarks `I_MCP_LAT`/`L_MCP_LAT`
/// minus that of the wrist's `WRIST_RAD`/`WRIST_ULN`), radial (`L_MCP_LAT` -> `I_MCP_LAT` plus
/// `WRIST_ULN` -> `WRIST_RAD`) and dorsal (the dorsal joint markers `WRIST` and `M_MCP` minus the
/// mid-points of the lateral pairs at their level: the lateral landmarks lie on the sides, the
/// joint markers on the back of the hand). With the palm down and the fingers pointing away, a
/// right hand's thumb is on the left, so (radial x distal) . dorsal is negative for a right
/// hand and positive for a left one (a mirror image flips the sign of a triple product).
pub fn landmark_chirality(traj: &Trajectories) -> Option<Side> {
    let medians = marker_medians(traj);
    let get = |name: &str| medians.iter().find(|m| m.0 == name).map(|m| m.1.coords);
    let (wr, wu, il, ll) = (
        get("WRIST_RAD")?,
        get("WRIST_ULN")?,
        get("I_MCP_LAT")?,
        get("L_MCP_LAT")?,
    );
    let (wrist, mcp) = (get("WRIST")?, get("M_MCP")?);
    let unit = |v: Vector| (v.norm() > 1e-9).then(|| v / v.norm());
    let distal = unit((il + ll) / 2.0 - (wr + wu) / 2.0)?;
    let radial = unit((il - ll) + (wr - wu))?;
    let dorsal = unit((wrist - (wr + wu) / 2.0) + (mcp - (il + ll) / 2.0))?;
    let t = radial.cross(&distal).dot(&dorsal);
    // Below 0.2 the three directions are too close to a plane to call.
    if t < -0.2 {
        Some(Side::Right)
    } else if t > 0.2 {
        Some(Side::Left)
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn traj(labels: &[&str], pts: Vec<Vec<Option<Point>>>) -> Trajectories {
        Trajectories::new(
            100.0,
            labels.iter().map(|s| s.to_string()).collect(),
            pts,
            "t.c3d",
        )
        .unwrap()
    }

    #[test]
    fn a_single_absurd_sample_is_dropped_and_motion_kept() {
        // A marker sweeping a 150 mm arc, one sample at 1e8 mm.
        let mut track: Vec<Option<Point>> = (0..400)
            .map(|f| {
                let a = f as f64 / 400.0 * std::f64::consts::PI;
                Some(Point::new(150.0 * a.cos(), 150.0 * a.sin(), 0.0))
            })
            .collect();
        track[123] = Some(Point::new(1e8, 0.0, 0.0));
        let mut t = traj(&["A", "B"], vec![track.clone(), track.clone()]);
        t.positions[1][123] = track[122];
        let dropped = drop_outliers(&mut t);
        assert_eq!(dropped, vec![("A".to_string(), 1)]);
        assert!(t.positions[0][123].is_none());
        let kept = t.positions[0].iter().flatten().count();
        assert_eq!(kept, 399);
    }

    /// A hand-sized cloud read in its own unit passes; the same numbers under a unit 10 or
    /// 1000 times off fail, naming POINT:UNITS and the unit they look like.
    #[test]
    fn wrong_units_and_far_markers_are_named() {
        let pts: Vec<Point> = (0..8)
            .map(|k| {
                let a = k as f64;
                Point::new(60.0 * a.cos(), 40.0 * a.sin(), 10.0 * a)
            })
            .collect();
        let labels: Vec<String> = (0..8).map(|k| format!("M{k}")).collect();
        let make = |scale: f64| {
            Trajectories::new(
                100.0,
                labels.clone(),
                pts.iter().map(|p| vec![Some(p * scale); 3]).collect(),
                "trial.c3d",
            )
            .unwrap()
        };
        check_hand_scale(&make(1.0), Units::Millimetres).unwrap();
        // mm values labelled m: read 1000 times too large.
        let e = check_hand_scale(&make(1000.0), Units::Metres)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("trial.c3d") && e.contains("POINT:UNITS is 'm'") && e.contains("like mm"),
            "{e}"
        );
        // m values labelled mm.
        let e = check_hand_scale(&make(0.001), Units::Millimetres)
            .unwrap_err()
            .to_string();
        assert!(e.contains("like m"), "{e}");
        // mm values labelled cm.
        let e = check_hand_scale(&make(10.0), Units::Centimetres)
            .unwrap_err()
            .to_string();
        assert!(e.contains("like mm"), "{e}");
        // One marker 5 m off: named, not blamed on the units.
        let mut t = make(1.0);
        for s in t.positions[3].iter_mut() {
            *s = s.map(|p| p + Vector::new(5000.0, 0.0, 0.0));
        }
        let e = check_hand_scale(&t, Units::Millimetres)
            .unwrap_err()
            .to_string();
        assert!(e.contains("'M3'") && !e.contains("POINT:UNITS"), "{e}");
    }

    /// Mirroring the landmarks flips the answer; the right hand in the geometry of the method's
    /// description (palm down, fingers along +y, thumb toward -x, dorsal +z).
    #[test]
    fn chirality_of_a_hand_and_its_mirror_image() {
        let names = [
            "WRIST_RAD",
            "WRIST_ULN",
            "I_MCP_LAT",
            "L_MCP_LAT",
            "WRIST",
            "M_MCP",
        ];
        let right = [
            Point::new(-25.0, 0.0, 0.0),
            Point::new(25.0, 0.0, 0.0),
            Point::new(-40.0, 90.0, 0.0),
            Point::new(40.0, 85.0, -3.0),
            Point::new(0.0, 0.0, 18.0),
            Point::new(0.0, 90.0, 15.0),
        ];
        let t = |pts: &[Point]| {
            traj(
                &names[..pts.len()],
                pts.iter().map(|p| vec![Some(*p)]).collect(),
            )
        };
        assert_eq!(landmark_chirality(&t(&right)), Some(Side::Right));
        let mirrored: Vec<Point> = right.iter().map(|p| Point::new(-p.x, p.y, p.z)).collect();
        assert_eq!(landmark_chirality(&t(&mirrored)), Some(Side::Left));
        // A rigid motion changes nothing.
        let iso = nalgebra::Isometry3::new(
            Vector::new(10.0, -400.0, 900.0),
            Vector::new(0.3, -1.2, 2.0),
        );
        let moved: Vec<Point> = right.iter().map(|p| iso * p).collect();
        assert_eq!(landmark_chirality(&t(&moved)), Some(Side::Right));
        assert_eq!(landmark_chirality(&t(&right[..5])), None);
    }
}
