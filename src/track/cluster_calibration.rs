//! Markers worn in a motion trial but not in the static trial (a technical cluster put on for
//! the motion, such as the forearm plate `ARM_1..3`), attached from the motion itself: the
//! calibrated anatomical markers of the same link fix its pose in the trial's first frames,
//! and each new marker's place on the link is the median of where those poses put it. This is
//! the calibration of a technical frame to an anatomical one of Cappozzo et al. (1995), "Position
//! and orientation in space of bones during movement: anatomical frame definition and
//! determination", Clinical Biomechanics 10(4), with the static trial's markers as the
//! anatomical frame.

use super::attachment::{AttachedMarker, Attachment};
use super::inverse_kinematics::{moved_by_held, observations, IkOptions, Solver};
use super::kinematics::Kinematics;
use crate::anatomy::Link;
use crate::geometry::Point;
use crate::mocap::trajectories::Trajectories;

/// Fewest frames in which a marker and its link's pose are both known for it to be attached.
pub const MIN_CALIBRATION_FRAMES: usize = 10;

/// Attach `new` (marker names of `motion` riding on a link, none of them attached yet) to
/// `attachment`: the first `window` frames of `motion` are tracked with the markers already
/// attached, and each new marker is attached at the component-wise median, over the solved
/// frames in which it is seen and its link's pose is determined (no joint between the palm and
/// the link held), of its position taken back to the reference posture. Returns the names
/// attached; a marker with fewer than [`MIN_CALIBRATION_FRAMES`] such frames is left out.
pub fn attach_from_motion(
    attachment: &mut Attachment,
    kin: &Kinematics,
    motion: &Trajectories,
    new: &[(String, Link)],
    window: usize,
    opts: &IkOptions,
) -> Vec<String> {
    if new.is_empty() {
        return Vec::new();
    }
    let obs = observations(attachment, motion);
    let window = window.min(obs.len());
    let frames = Solver::new(kin, attachment, opts.clone()).track(&obs[..window]);
    let mut attached = Vec::new();
    for (name, link) in new {
        let Some(col) = motion.index_of(name) else {
            continue;
        };
        let mut samples: Vec<Point> = Vec::new();
        for (f, sol) in frames.iter().enumerate() {
            let (Some(state), Some(p)) = (&sol.state, motion.positions[col][f]) else {
                continue;
            };
            if !p.coords.iter().all(|x| x.is_finite()) || moved_by_held(*link, &sol.held) {
                continue;
            }
            let t = kin.evaluate(state).links[link.index()];
            samples.push(t.inverse_transform_point(&p));
        }
        if samples.len() < MIN_CALIBRATION_FRAMES {
            continue;
        }
        let median = |k: usize| {
            let mut v: Vec<f64> = samples.iter().map(|p| p[k]).collect();
            v.sort_by(f64::total_cmp);
            let m = v.len() / 2;
            if v.len() % 2 == 1 {
                v[m]
            } else {
                0.5 * (v[m - 1] + v[m])
            }
        };
        let reference = Point::new(median(0), median(1), median(2));
        attachment
            .markers
            .push(AttachedMarker::new(&kin.skeleton, name, *link, reference));
        attached.push(name.clone());
    }
    attached
}
