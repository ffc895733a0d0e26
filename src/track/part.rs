//! The product's pose per frame: from its markers `PART_1..n` when the scene gives their
//! positions in the part's frame (`[part.markers]`, spec section 5), by Horn's closed-form
//! absolute orientation on the markers seen in the frame (three or more, not collinear); else
//! where the scene's `[part]` places it, in every frame. Short gaps, where too few of its
//! markers are seen, are filled by interpolating the pose between the frames either side
//! ([`fill_pose_gaps`]), as motion-capture software fills a marker's gap.

use crate::geometry::{absolute_orientation, Point};
use crate::mocap::trajectories::Trajectories;
use nalgebra::{Isometry3, Translation3};
use std::collections::BTreeMap;

/// The part's pose per frame (`None` where too few of its markers are seen) and the RMS
/// residual of its markers per frame (`None` without markers).
pub type PartPoses = (Vec<Option<Isometry3<f64>>>, Vec<Option<f64>>);

/// The part's pose (part frame -> lab) per frame, `None` where fewer than three of its
/// markers are seen (or they are collinear), and the fit's RMS residual per frame, mm.
pub fn part_poses(
    traj: &Trajectories,
    markers: &BTreeMap<String, Point>,
    placed: &Isometry3<f64>,
) -> PartPoses {
    let n = traj.n_frames();
    if markers.is_empty() {
        return (vec![Some(*placed); n], vec![None; n]);
    }
    let tracks: Vec<(&Point, usize)> = markers
        .iter()
        .filter_map(|(name, p)| traj.index_of(name).map(|i| (p, i)))
        .collect();
    let mut poses = Vec::with_capacity(n);
    let mut rms = Vec::with_capacity(n);
    for f in 0..n {
        let (mut src, mut dst) = (Vec::new(), Vec::new());
        for &(p, i) in &tracks {
            if let Some(o) = traj.positions[i][f].filter(|o| o.coords.iter().all(|x| x.is_finite()))
            {
                src.push(*p);
                dst.push(o);
            }
        }
        match (src.len() >= 3)
            .then(|| absolute_orientation(&src, &dst, None, false).ok())
            .flatten()
        {
            Some(r) => {
                poses.push(Some(r.isometry()));
                rms.push(Some(r.rms));
            }
            None => {
                poses.push(None);
                rms.push(None);
            }
        }
    }
    (poses, rms)
}

/// Fill every run of `None` of at most `max_gap` frames that has a pose on both sides, by
/// linear interpolation of the translation and spherical linear interpolation of the rotation
/// between the two (a part carried by the hand moves smoothly over a fraction of a second);
/// longer gaps and those at the ends stay `None`. Returns the frames filled.
pub fn fill_pose_gaps(poses: &mut [Option<Isometry3<f64>>], max_gap: usize) -> Vec<usize> {
    let mut filled = Vec::new();
    let mut last: Option<usize> = None;
    for f in 0..poses.len() {
        let Some(b) = poses[f] else { continue };
        if let Some(l) = last {
            let gap = f - l - 1;
            if gap > 0 && gap <= max_gap {
                let a = poses[l].expect("known");
                for (k, slot) in poses.iter_mut().enumerate().take(f).skip(l + 1) {
                    let t = (k - l) as f64 / (f - l) as f64;
                    let tr = a.translation.vector.lerp(&b.translation.vector, t);
                    let rot = a.rotation.slerp(&b.rotation, t);
                    *slot = Some(Isometry3::from_parts(Translation3::from(tr), rot));
                    filled.push(k);
                }
            }
        }
        last = Some(f);
    }
    filled
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn part_markers_give_the_part_pose_and_gaps_give_none() {
        let markers: BTreeMap<String, Point> = [
            ("PART_1", Point::new(0.0, 30.0, 180.0)),
            ("PART_2", Point::new(26.0, -15.0, 180.0)),
            ("PART_3", Point::new(-26.0, -15.0, 180.0)),
        ]
        .into_iter()
        .map(|(k, v)| (k.to_string(), v))
        .collect();
        let truth: Vec<Isometry3<f64>> = (0..5)
            .map(|f| {
                Isometry3::from_parts(
                    Translation3::new(f as f64, 100.0, -3.0 * f as f64),
                    UnitQuaternion::from_euler_angles(0.1 * f as f64, 0.2, -0.05 * f as f64),
                )
            })
            .collect();
        let labels: Vec<String> = markers.keys().cloned().collect();
        let positions = markers
            .values()
            .map(|p| {
                truth
                    .iter()
                    .enumerate()
                    .map(|(f, t)| (f != 3 || p.x <= 0.0).then(|| t * p))
                    .collect()
            })
            .collect();
        let traj = Trajectories::new(100.0, labels, positions, "grasp.c3d").unwrap();
        let (poses, rms) = part_poses(&traj, &markers, &Isometry3::identity());
        for f in 0..5 {
            if f == 3 {
                assert!(poses[f].is_none());
                continue;
            }
            let d = poses[f].unwrap().to_homogeneous() - truth[f].to_homogeneous();
            assert!(d.norm() < 1e-9, "{f}");
            assert!(rms[f].unwrap() < 1e-9);
        }
        // The one-frame gap is filled between its neighbours: a motion linear in the translation
        // and, about a fixed axis, in the angle, is reproduced exactly.
        let mut gappy = poses.clone();
        assert_eq!(fill_pose_gaps(&mut gappy, 0), Vec::<usize>::new());
        assert_eq!(fill_pose_gaps(&mut gappy, 1), vec![3]);
        let axis = nalgebra::Vector3::new(1.0, 2.0, -0.5).normalize();
        let line: Vec<Option<Isometry3<f64>>> = (0..6)
            .map(|f| {
                Some(Isometry3::from_parts(
                    Translation3::new(2.0 * f as f64, -1.0, 0.5 * f as f64),
                    UnitQuaternion::from_scaled_axis(axis * (0.2 * f as f64)),
                ))
            })
            .collect();
        let mut holed = line.clone();
        holed[2] = None;
        holed[3] = None;
        holed[5] = None;
        assert_eq!(fill_pose_gaps(&mut holed, 2), vec![2, 3]);
        assert!(holed[5].is_none(), "a gap at the end has no pose after it");
        for f in 2..4 {
            let d = holed[f].unwrap().to_homogeneous() - line[f].unwrap().to_homogeneous();
            assert!(d.norm() < 1e-12, "{f}: {d}");
        }
        let fixed = Isometry3::translation(1.0, 2.0, 3.0);
        let (p, _) = part_poses(&traj, &BTreeMap::new(), &fixed);
        assert!(p.iter().all(|p| *p == Some(fixed)));
    }
}
