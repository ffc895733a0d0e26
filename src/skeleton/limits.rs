//! Anatomical joint-angle limits.
//!
//! Active ranges of motion of healthy adults, rounded outward: finger joints after Hume et al.
//! (1990, J. Hand Surg. 15A:240) and the AAOS normal values (Greene & Heckman 1994); wrist after
//! Ryu et al. (1991, J. Hand Surg. 16A:409); thumb CMC after Cooney et al. (1981, J. Bone Joint
//! Surg. 63A:1371). Negative flexion is extension (hyperextension for PIP/DIP); abduction is
//! away from the middle finger (see [`crate::skeleton`]).

use super::Pose;
use crate::anatomy::{Finger, Joint};

/// `[min, max]` in degrees for `[flexion, abduction, axial]` of joint `j` (1-DOF joints: the
/// last two are `[0, 0]`).
pub fn joint_limits_deg(j: Joint) -> [[f64; 2]; 3] {
    match (j, j.finger(), j.rank()) {
        (Joint::Wrist, _, _) => [[-70.0, 80.0], [-30.0, 20.0], [-10.0, 10.0]],
        (_, Some(Finger::Thumb), 0) => [[-25.0, 45.0], [-15.0, 60.0], [-30.0, 30.0]],
        (_, Some(Finger::Thumb), 1) => [[-10.0, 60.0], [0.0, 0.0], [0.0, 0.0]],
        (_, Some(Finger::Thumb), _) => [[-20.0, 85.0], [0.0, 0.0], [0.0, 0.0]],
        (_, Some(Finger::Middle), 0) => [[-30.0, 90.0], [-15.0, 15.0], [-15.0, 15.0]],
        (_, Some(_), 0) => [[-30.0, 90.0], [-10.0, 25.0], [-15.0, 15.0]],
        (_, Some(_), 1) => [[-5.0, 110.0], [0.0, 0.0], [0.0, 0.0]],
        _ => [[-10.0, 85.0], [0.0, 0.0], [0.0, 0.0]],
    }
}

/// A joint angle that was outside its limit.
#[derive(Clone, Debug, PartialEq)]
pub struct LimitViolation {
    /// The joint.
    pub joint: Joint,
    /// 0 flexion, 1 abduction, 2 axial.
    pub dof: usize,
    /// The requested angle, degrees.
    pub requested_deg: f64,
    /// The angle used, degrees.
    pub clamped_deg: f64,
}

impl std::fmt::Display for LimitViolation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        const DOF: [&str; 3] = ["flexion", "abduction", "axial rotation"];
        write!(
            f,
            "{} {} {:.1} deg is outside its anatomical range; clamped to {:.1} deg",
            self.joint, DOF[self.dof], self.requested_deg, self.clamped_deg
        )
    }
}

/// Clamp every angle of `pose` to its joint's limits; returns the clamped pose and what was
/// changed (for the warning that names the joint).
pub fn clamp_pose(pose: &Pose) -> (Pose, Vec<LimitViolation>) {
    let mut out = pose.clone();
    let mut v = Vec::new();
    for j in Joint::ALL {
        for (d, [lo, hi]) in joint_limits_deg(j).into_iter().enumerate() {
            let deg = pose.angles[j.index()][d].to_degrees();
            let c = deg.clamp(lo, hi);
            // A tolerance keeps round-off of degree/radian conversion from warning.
            if (c - deg).abs() > 1e-9 {
                out.angles[j.index()][d] = c.to_radians();
                v.push(LimitViolation {
                    joint: j,
                    dof: d,
                    requested_deg: deg,
                    clamped_deg: c,
                });
            }
        }
    }
    (out, v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn limits_contain_zero_and_clamp_names_the_joint() {
        for j in Joint::ALL {
            for (d, [lo, hi]) in joint_limits_deg(j).into_iter().enumerate() {
                assert!(lo <= 0.0 && 0.0 <= hi, "{j} dof {d}");
                if j.dof() == 1 && d > 0 {
                    assert_eq!((lo, hi), (0.0, 0.0));
                }
            }
        }
        let pose = Pose::zero()
            .with_deg(Joint::IPip, [150.0, 0.0, 0.0])
            .with_deg(Joint::MMcp, [45.0, 5.0, 0.0]);
        let (c, v) = clamp_pose(&pose);
        assert_eq!(v.len(), 1);
        assert_eq!(v[0].joint, Joint::IPip);
        assert!((c.angles[Joint::IPip.index()][0].to_degrees() - 110.0).abs() < 1e-9);
        assert_eq!(
            c.angles[Joint::MMcp.index()],
            pose.angles[Joint::MMcp.index()]
        );
        assert!(v[0].to_string().contains("I_PIP"));
    }
}
