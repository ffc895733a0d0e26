//! Marker attachment: which link every marker of a motion trial rides on, and where on it.
//!
//! Input: the link model's skeleton (joint centres and frames in the reference frame of the
//! static trial) and the static reference trial. Output: per marker its link (spec section
//! 5) and its position in the reference posture, which is the static trial's mean position
//! of the marker: the link model is expressed in that trial's frame, with every joint angle
//! zero there, so the mean position *is* the marker in the link's rest pose. The same point
//! in the link's own frame (origin at the joint the link rotates about, axes that joint's
//! frame; the forearm uses the wrist's) is kept as the offset a report shows.
//!
//! Any pose of the link model then predicts every marker: `T_link * reference`, with
//! `T_link` from [`crate::skeleton::forward_kinematics::link_transforms`].
//!
//! The skin is not used: the static trial places each marker exactly, and the marker's slide
//! over the bone with flexion (spec section 5) is left to the robust weights of the inverse
//! kinematics rather than modelled.

use crate::anatomy::{arm_markers, palm_markers, Finger, Joint, Link};
use crate::geometry::{Point, Vec3};
use crate::mocap::trajectories::Trajectories;
use crate::skeleton::Skeleton;
use nalgebra::Isometry3;

/// One marker on its link.
#[derive(Clone, Debug, PartialEq)]
pub struct AttachedMarker {
    /// The spec name, e.g. `I_PIP`.
    pub name: String,
    /// The link it rides on.
    pub link: Link,
    /// Its position in the reference posture (static trial mean), mm, reference frame.
    pub reference: Point,
    /// The same point in the link's frame (origin at the link's joint, axes of its frame), mm.
    pub local: Vec3,
}

/// Every attached marker of a subject.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Attachment {
    /// In the order of [`crate::anatomy::landmark_names`], then forearm and plate markers.
    pub markers: Vec<AttachedMarker>,
}

/// The link the marker `name` rides on (spec section 5): a joint's dorsal marker on the link
/// proximal to the joint (the head of the proximal bone), a nail marker on the distal link,
/// `T_MC_1/2` on the thumb metacarpal, a fingertip marker (`I_TIP`, an extension of the
/// spec) on the distal link, the MCP laterals and `PALM_n` on the palm, the
/// styloids and `ARM_n` on the forearm, a plate marker `<LINK>_k` on its link. `None` for
/// anything else (`PART_n` and unknown names).
pub fn rides_on(name: &str) -> Option<Link> {
    if palm_markers().contains(&name) || name == "I_MCP_LAT" || name == "L_MCP_LAT" {
        return Some(Link::Palm);
    }
    if arm_markers().contains(&name) || name == "WRIST_RAD" || name == "WRIST_ULN" {
        return Some(Link::Arm);
    }
    if name == "T_MC_1" || name == "T_MC_2" {
        return Some(Link::TMeta);
    }
    if let Some(j) = Joint::from_name(name) {
        return Some(j.parent_link());
    }
    if let Some(f) = Finger::ALL
        .into_iter()
        .find(|f| name == f.nail_marker() || name == f.tip_marker())
    {
        return Some(f.links()[2]);
    }
    Link::ALL
        .into_iter()
        .find(|l| l.plate_markers().iter().any(|m| m == name))
}

/// The joint whose frame is a link's own (the forearm takes the wrist's).
fn frame_joint(link: Link) -> Joint {
    link.joint().unwrap_or(Joint::Wrist)
}

impl Attachment {
    /// Attach every marker of `static_trial` that rides on a link ([`rides_on`]) and has a
    /// valid sample: its mean position over the trial is its reference position. Markers
    /// that ride on nothing (`PART_n`) are left out.
    pub fn from_static(skeleton: &Skeleton, static_trial: &Trajectories) -> Attachment {
        let mut markers = Vec::new();
        for name in &static_trial.labels {
            let Some(link) = rides_on(name) else {
                continue;
            };
            let Some(p) = static_trial.mean_position(name, 0..static_trial.n_frames()) else {
                continue;
            };
            markers.push(AttachedMarker::new(skeleton, name, link, p));
        }
        let order = |n: &str| {
            crate::anatomy::landmark_names()
                .iter()
                .position(|l| *l == n)
                .unwrap_or(usize::MAX)
        };
        markers.sort_by(|a, b| {
            order(&a.name)
                .cmp(&order(&b.name))
                .then(a.name.cmp(&b.name))
        });
        Attachment { markers }
    }

    /// Index of marker `name`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.markers.iter().position(|m| m.name == name)
    }

    /// Every marker's position under the link transforms `t` (indexed by [`Link::index`]).
    pub fn predict(&self, t: &[Isometry3<f64>]) -> Vec<Point> {
        self.markers
            .iter()
            .map(|m| t[m.link.index()] * m.reference)
            .collect()
    }
}

impl AttachedMarker {
    /// A marker on `link` at `reference` (reference posture), its local offset from the
    /// skeleton.
    pub fn new(skeleton: &Skeleton, name: &str, link: Link, reference: Point) -> AttachedMarker {
        let jf = skeleton.joint(frame_joint(link));
        let local = jf.frame.inverse() * (reference - jf.centre);
        AttachedMarker {
            name: name.to_string(),
            link,
            reference,
            local,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn markers_ride_on_the_links_the_spec_names() {
        let cases = [
            ("I_PIP", Link::IProx),
            ("I_DIP", Link::IMid),
            ("I_MCP", Link::Palm),
            ("T_CMC", Link::Palm),
            ("T_MCP", Link::TMeta),
            ("T_IP", Link::TProx),
            ("WRIST", Link::Arm),
            ("WRIST_RAD", Link::Arm),
            ("ARM_2", Link::Arm),
            ("PALM_3", Link::Palm),
            ("L_MCP_LAT", Link::Palm),
            ("T_MC_2", Link::TMeta),
            ("T_NAIL", Link::TDist),
            ("R_NAIL", Link::RDist),
            ("I_TIP", Link::IDist),
            ("T_TIP", Link::TDist),
            ("M_MID_2", Link::MMid),
        ];
        for (n, l) in cases {
            assert_eq!(rides_on(n), Some(l), "{n}");
        }
        assert_eq!(rides_on("PART_1"), None);
        assert_eq!(rides_on("X_NAIL"), None);
        for n in crate::anatomy::landmark_names() {
            assert!(rides_on(n).is_some(), "{n}");
        }
    }
}
