//! The kinematic hand: the link tree of the spec (section 2), joint centres with local frames,
//! forward kinematics from joint angles, and anatomical joint-angle limits.
//!
//! Conventions (the seed paper, section 3.1, and Grood & Suntay 1983 for the 3-DOF order):
//! * Every joint has a right-handed local frame in the reference posture, stored as a rotation
//!   whose columns are the local x, y, z axes in the reference (lab) frame:
//!   z runs along the child link toward the fingertip (distal), y points to the dorsal side of
//!   the link (for the thumb: toward its nail), x = y × z. For a 1-DOF joint x is its rotation axis.
//! * Angles are radians in the core (degrees only in files and on the command line).
//!   A 3-DOF joint takes `[flexion, abduction, axial rotation]`, applied as the intrinsic sequence
//!   x, y', z'' (roll, pitch, yaw): flexion about the proximal x axis, abduction about the floating
//!   y axis, axial rotation about the distal link's own axis. A 1-DOF joint takes `[angle, 0, 0]`.
//! * Signs mean the same motion on both hands: positive flexion moves the link palmar (this
//!   follows from x = y × z on either hand); positive abduction moves a finger away from the
//!   middle finger (middle finger and wrist: radial deviation; thumb CMC: palmar abduction, away
//!   from the palm plane); positive axial rotation is right-handed about z on the right hand and
//!   mirrored on the left. [`Skeleton::signs`] holds the resulting sign per joint and DOF.

pub mod forward_kinematics;
pub mod frames;
pub mod limits;
pub mod record;

pub use forward_kinematics::Pose;
pub use frames::{frame_from_axis, frame_from_long_axis};
pub use limits::{clamp_pose, joint_limits_deg, LimitViolation};

use crate::anatomy::{Finger, Joint, Side};
use crate::geometry::{Point, Vec3};
use nalgebra::Rotation3;
use serde::{Deserialize, Serialize};

/// A joint in the reference posture: where it is and how its local axes lie.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointFrame {
    /// Centre of rotation, mm, reference frame.
    pub centre: Point,
    /// Local axes as columns (x, y, z) in the reference frame; right-handed.
    pub frame: Rotation3<f64>,
}

impl JointFrame {
    /// Local x axis: the rotation axis of a 1-DOF joint, the flexion axis of a 3-DOF joint.
    pub fn x(&self) -> Vec3 {
        self.frame.matrix().column(0).into()
    }
    /// Local y axis (dorsal).
    pub fn y(&self) -> Vec3 {
        self.frame.matrix().column(1).into()
    }
    /// Local z axis (along the child link, distal).
    pub fn z(&self) -> Vec3 {
        self.frame.matrix().column(2).into()
    }
}

/// The kinematic skeleton of one hand in its reference posture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Skeleton {
    /// Which hand.
    pub side: Side,
    /// One frame per joint, indexed by [`Joint::index`].
    pub joints: Vec<JointFrame>,
    /// Distal end of each digit's last link (thumb first), mm: where the bone ends; used for the
    /// distal joints' long axes and for drawing.
    pub tips: [Point; 5],
}

impl Skeleton {
    /// The hand's anatomical directions at the wrist centre: dorsal (the wrist frame's y),
    /// distal (towards the middle MCP, square to dorsal) and radial (from the little to the
    /// index MCP, square to both), the same for either hand.
    pub fn hand_directions(&self) -> (Point, [Vec3; 3]) {
        let o = self.centre(Joint::Wrist);
        let dorsal = self.joint(Joint::Wrist).y().normalize();
        let d = self.centre(Joint::MMcp) - o;
        let distal = (d - dorsal * d.dot(&dorsal)).normalize();
        let r = self.centre(Joint::IMcp) - self.centre(Joint::LMcp);
        let radial = (r - dorsal * r.dot(&dorsal) - distal * r.dot(&distal)).normalize();
        (o, [dorsal, radial, distal])
    }

    /// The frame of `j`.
    pub fn joint(&self, j: Joint) -> &JointFrame {
        &self.joints[j.index()]
    }

    /// Centre of `j`, mm.
    pub fn centre(&self, j: Joint) -> Point {
        self.joints[j.index()].centre
    }

    /// Turn joint `j`'s frame so that its z points along `long`: a hinge keeps its axis (x) and
    /// only turns about it; a joint of more freedom takes `dorsal` for y. Returns false, with the
    /// frame left as it was, when `long` is degenerate (zero, or along the hinge axis).
    pub fn aim_long_axis(&mut self, j: Joint, long: &Vec3, dorsal: &Vec3) -> bool {
        let jf = self.joint(j);
        let frame = if j.dof() == 1 {
            frame_from_axis(&jf.x(), long)
        } else {
            frame_from_long_axis(long, dorsal)
        };
        match frame {
            Ok(frame) => {
                self.joints[j.index()].frame = frame;
                true
            }
            Err(_) => false,
        }
    }

    /// The point at the distal end of `j`'s child link: the next joint of the digit, or the tip.
    /// For the wrist: the middle finger's MCP (the palm's long axis, as in the WebXR convention).
    pub fn distal_end(&self, j: Joint) -> Point {
        match j {
            Joint::Wrist => self.centre(Joint::MMcp),
            j => {
                let f = j.finger().expect("non-wrist joints belong to a digit");
                match j.rank() {
                    2 => self.tips[f as usize],
                    r => self.centre(f.joints()[r + 1]),
                }
            }
        }
    }

    /// Sign of each DOF so that positive angles mean the anatomical motion described in the
    /// module documentation, on either hand.
    pub fn signs(&self, j: Joint) -> [f64; 3] {
        let mirror = match self.side {
            Side::Right => 1.0,
            Side::Left => -1.0,
        };
        // On a right hand, x = dorsal × distal points radially (palm down, fingers away: thumb on
        // the left), so +abduction (toward +x) is radial; on a left hand it is ulnar.
        let radial = mirror;
        let abduction = match j.finger() {
            None | Some(Finger::Index) | Some(Finger::Middle) => radial,
            Some(Finger::Ring) | Some(Finger::Little) => -radial,
            Some(Finger::Thumb) => {
                // Palmar abduction: toward the palmar side of the hand, i.e. against the palm's
                // dorsal normal (the wrist frame's y).
                // A thumb lying flat in the palm plane has no palmar side to its x axis; there
                // abduction falls back to the mirror convention of the fingers.
                let toward = self.joint(j).x().dot(&self.joint(Joint::Wrist).y());
                if toward.abs() < 0.2 {
                    mirror
                } else if toward < 0.0 {
                    1.0
                } else {
                    -1.0
                }
            }
        };
        [1.0, abduction, mirror]
    }

    /// Every joint as (joint, centre), in [`Joint::ALL`] order.
    pub fn centres(&self) -> Vec<(Joint, Point)> {
        Joint::ALL.iter().map(|&j| (j, self.centre(j))).collect()
    }

    /// Rebuild every joint frame from the joint centres, the tips and a dorsal direction hint per
    /// joint (see [`frame_from_long_axis`]): z along the link, y toward the hint.
    pub fn from_centres(
        side: Side,
        centres: &[Point; 16],
        tips: [Point; 5],
        dorsal: &[Vec3; 16],
    ) -> crate::Result<Skeleton> {
        let mut sk = Skeleton {
            side,
            joints: centres
                .iter()
                .map(|&c| JointFrame {
                    centre: c,
                    frame: Rotation3::identity(),
                })
                .collect(),
            tips,
        };
        for j in Joint::ALL {
            let z = sk.distal_end(j) - sk.centre(j);
            sk.joints[j.index()].frame = frame_from_long_axis(&z, &dorsal[j.index()])
                .map_err(|e| crate::Error::invalid(format!("joint {j}: {e}")))?;
        }
        Ok(sk)
    }
}
