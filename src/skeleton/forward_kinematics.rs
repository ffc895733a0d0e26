//! Forward kinematics: the rigid motion of every link for a set of joint angles.
//!
//! Every joint centre and frame is known in the reference posture, so the motion of a link is
//! the product, down its chain, of rotations about the joints' reference centres:
//! `T_child = T_parent · Tr(c) · F · R(θ) · Fᵀ · Tr(-c)`, with `F` the joint frame and `R(θ)`
//! the local rotation (module [`crate::skeleton`] for the angle conventions). At zero angles
//! every transform is the identity, so the reference posture is reproduced exactly: this is the
//! form linear-blend and dual-quaternion skinning consume directly.

use super::Skeleton;
use crate::anatomy::{Joint, Link};
use crate::geometry::{Point, Vec3};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

/// Joint angles of a posture, radians, plus where the forearm is.
#[derive(Clone, Debug, PartialEq)]
pub struct Pose {
    /// Per joint ([`Joint::index`]): `[flexion, abduction, axial]`; 1-DOF joints use `[θ, 0, 0]`.
    pub angles: [[f64; 3]; 16],
    /// Rigid motion of the forearm (the root link) from the reference posture.
    pub root: Isometry3<f64>,
}

impl Default for Pose {
    fn default() -> Self {
        Pose {
            angles: [[0.0; 3]; 16],
            root: Isometry3::identity(),
        }
    }
}

impl Pose {
    /// The reference posture: every angle zero, forearm in place.
    pub fn zero() -> Self {
        Self::default()
    }

    /// Set one joint's angles in degrees (the unit of pose files); extra DOFs of a 1-DOF joint
    /// are ignored.
    pub fn with_deg(mut self, j: Joint, deg: [f64; 3]) -> Self {
        let mut a = deg.map(f64::to_radians);
        if j.dof() == 1 {
            a[1] = 0.0;
            a[2] = 0.0;
        }
        self.angles[j.index()] = a;
        self
    }

    /// Every joint's angles in degrees, in [`Joint::ALL`] order (as [`Pose::with_deg`] each),
    /// with the forearm at `root`.
    pub fn from_deg(angles: &[[f64; 3]], root: Isometry3<f64>) -> Self {
        let mut pose = Joint::ALL
            .iter()
            .zip(angles)
            .fold(Pose::zero(), |p, (j, a)| p.with_deg(*j, *a));
        pose.root = root;
        pose
    }
}

/// The rotation of joint `j` in reference coordinates, `F · Rx(θ₀) · Ry(θ₁) · Rz(θ₂) · Fᵀ`,
/// computed as `Rot(x_w, θ₀) · Rot(y_w, θ₁) · Rot(z_w, θ₂)` about the frame's axes in the
/// reference frame (the same product), so that zero angles give the identity exactly.
pub fn joint_rotation(sk: &Skeleton, j: Joint, angles: &[f64; 3]) -> UnitQuaternion<f64> {
    let jf = sk.joint(j);
    let s = sk.signs(j);
    let about = |axis: Vec3, a: f64| {
        UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_unchecked(axis), a)
    };
    let flex = about(jf.x(), s[0] * angles[0]);
    if j.dof() == 3 {
        flex * about(jf.y(), s[1] * angles[1]) * about(jf.z(), s[2] * angles[2])
    } else {
        flex
    }
}

/// Rigid motion (reference posture -> posed) of every link, indexed by [`Link::index`].
pub fn link_transforms(sk: &Skeleton, pose: &Pose) -> Vec<Isometry3<f64>> {
    let mut t = vec![Isometry3::identity(); Link::ALL.len()];
    t[Link::Arm.index()] = pose.root;
    for j in Joint::ALL {
        let c = sk.centre(j).coords;
        let r = joint_rotation(sk, j, &pose.angles[j.index()]);
        // Rotation about c: p -> c + r (p - c).
        let about = Isometry3::from_parts(Translation3::from(c - r * c), r);
        t[j.child_link().index()] = t[j.parent_link().index()] * about;
    }
    t
}

/// Posed joint centres, indexed by [`Joint::index`].
pub fn posed_centres(sk: &Skeleton, transforms: &[Isometry3<f64>]) -> Vec<Point> {
    Joint::ALL
        .iter()
        .map(|&j| transforms[j.parent_link().index()] * sk.centre(j))
        .collect()
}

/// Posed fingertips (thumb first).
pub fn posed_tips(sk: &Skeleton, transforms: &[Isometry3<f64>]) -> [Point; 5] {
    let mut out = sk.tips;
    for (i, f) in crate::anatomy::Finger::ALL.iter().enumerate() {
        out[i] = transforms[f.links()[2].index()] * sk.tips[i];
    }
    out
}

/// A skeleton rebuilt after a rigid posture change: each joint's frame rotated with the link on
/// its parent side (where a joint's axes live), centres moved likewise.
pub fn posed_skeleton(sk: &Skeleton, transforms: &[Isometry3<f64>]) -> Skeleton {
    let mut out = sk.clone();
    for j in Joint::ALL {
        let t = transforms[j.parent_link().index()];
        out.joints[j.index()] = super::JointFrame {
            centre: t * sk.centre(j),
            frame: t.rotation.to_rotation_matrix() * sk.joint(j).frame,
        };
    }
    for f in crate::anatomy::Finger::ALL {
        out.tips[f as usize] = transforms[f.links()[2].index()] * sk.tips[f as usize];
    }
    // A 3-DOF joint's frame follows the child link's long axis in the new posture (its centre is
    // what the truth records; the frame only orients reports).
    for j in Joint::ALL {
        if j.dof() == 3 {
            let z = out.distal_end(j) - out.centre(j);
            if let Ok(fr) = super::frame_from_long_axis(&z, &out.joint(j).y()) {
                out.joints[j.index()].frame = fr;
            }
        }
    }
    out
}

/// Linear blend skinning of one point: `Σ_l w_l T_l p` over its `(link, weight)` pairs (the
/// weights of a point are expected to sum to one).
pub fn blend_point(p: &Point, weights: &[(usize, f64)], transforms: &[Isometry3<f64>]) -> Point {
    let mut acc = Vec3::zeros();
    for &(l, w) in weights {
        acc += (transforms[l] * p).coords * w;
    }
    Point::from(acc)
}

/// Linear blend skinning of every point by its weights ([`blend_point`]). The fast, checked
/// form for posing many times is `crate::pose::SkinBinding`.
pub fn linear_blend(
    points: &[Point],
    weights: &[Vec<(usize, f64)>],
    transforms: &[Isometry3<f64>],
) -> Vec<Point> {
    points
        .iter()
        .zip(weights)
        .map(|(p, w)| blend_point(p, w, transforms))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::{Finger, Side};
    use crate::skeleton::frames::frame_from_long_axis;
    use crate::skeleton::JointFrame;

    /// A schematic hand of straight digits, so that expected motions can be worked out by hand.
    /// Lab axes as in the generic-hand template: fingers along -Y, dorsal +X, and on the right
    /// hand the thumb toward -Z (mirrored in Z for the left).
    pub(crate) fn schematic(side: Side) -> Skeleton {
        let m = if side == Side::Right { 1.0 } else { -1.0 };
        let distal = Vec3::new(0.0, -1.0, 0.0);
        let dorsal = Vec3::new(1.0, 0.0, 0.0);
        let mut centres = [Point::origin(); 16];
        let mut tips = [Point::origin(); 5];
        for f in Finger::ALL {
            let zoff = m * (f as i32 as f64 - 2.0) * 20.0;
            let base = Point::new(0.0, -80.0, zoff);
            for (k, j) in f.joints().iter().enumerate() {
                centres[j.index()] = base + distal * (k as f64 * 30.0);
            }
            tips[f as usize] = base + distal * 85.0;
        }
        let mut sk = Skeleton {
            side,
            joints: vec![
                JointFrame {
                    centre: Point::origin(),
                    frame: nalgebra::Rotation3::identity()
                };
                16
            ],
            tips,
        };
        for j in Joint::ALL {
            sk.joints[j.index()].centre = centres[j.index()];
        }
        // The thumb's nail faces radially (toward -Z on the right hand) and somewhat dorsally.
        let thumb_dorsal = Vec3::new(0.5, 0.0, -0.87 * m);
        for j in Joint::ALL {
            let z = sk.distal_end(j) - sk.centre(j);
            let d = if j.finger() == Some(Finger::Thumb) {
                thumb_dorsal
            } else {
                dorsal
            };
            sk.joints[j.index()].frame = frame_from_long_axis(&z, &d).unwrap();
        }
        sk
    }

    #[test]
    fn zero_pose_is_identity() {
        let sk = schematic(Side::Right);
        let t = link_transforms(&sk, &Pose::zero());
        for ti in &t {
            assert!((ti.to_homogeneous() - nalgebra::Matrix4::identity()).norm() < 1e-15);
        }
        let c = posed_centres(&sk, &t);
        for j in Joint::ALL {
            assert_eq!(c[j.index()], sk.centre(j));
        }
    }

    #[test]
    fn pip_flexion_rotates_the_distal_links_palmar_about_its_axis() {
        for side in [Side::Right, Side::Left] {
            let sk = schematic(side);
            let pose = Pose::zero().with_deg(Joint::IPip, [90.0, 0.0, 0.0]);
            let t = link_transforms(&sk, &pose);
            let c = posed_centres(&sk, &t);
            // The PIP stays; the DIP swings 30 mm palmar (-X), keeping its distance.
            let pip = sk.centre(Joint::IPip);
            assert!((c[Joint::IPip.index()] - pip).norm() < 1e-12);
            let dip = c[Joint::IDip.index()];
            assert!(
                (dip - (pip + Vec3::new(-30.0, 0.0, 0.0))).norm() < 1e-9,
                "{side}: {dip}"
            );
            // Links proximal of the joint do not move.
            assert!(
                (t[Link::IProx.index()].to_homogeneous() - nalgebra::Matrix4::identity()).norm()
                    < 1e-15
            );
            // Other fingers do not move.
            assert!(
                (c[Joint::MDip.index()] - sk.centre(Joint::MDip)).norm() < 1e-15,
                "{side}"
            );
        }
    }

    #[test]
    fn abduction_spreads_fingers_on_both_hands() {
        for side in [Side::Right, Side::Left] {
            let sk = schematic(side);
            let pose = Pose::zero()
                .with_deg(Joint::IMcp, [0.0, 20.0, 0.0])
                .with_deg(Joint::LMcp, [0.0, 20.0, 0.0]);
            let t = link_transforms(&sk, &pose);
            let tips = posed_tips(&sk, &t);
            let middle_z = sk.tips[Finger::Middle as usize].z;
            let spread = |f: Finger| {
                (tips[f as usize].z - middle_z).abs() - (sk.tips[f as usize].z - middle_z).abs()
            };
            assert!(spread(Finger::Index) > 5.0, "{side}");
            assert!(spread(Finger::Little) > 5.0, "{side}");
        }
    }

    #[test]
    fn left_is_the_mirror_of_right() {
        let (r, l) = (schematic(Side::Right), schematic(Side::Left));
        let pose = Pose::zero()
            .with_deg(Joint::Wrist, [20.0, 10.0, 5.0])
            .with_deg(Joint::MMcp, [40.0, -10.0, 8.0])
            .with_deg(Joint::TCmc, [10.0, 30.0, -12.0])
            .with_deg(Joint::MPip, [60.0, 0.0, 0.0]);
        let (tr, tl) = (link_transforms(&r, &pose), link_transforms(&l, &pose));
        let (pr, pl) = (posed_tips(&r, &tr), posed_tips(&l, &tl));
        for i in 0..5 {
            let mirrored = Point::new(pl[i].x, pl[i].y, -pl[i].z);
            assert!((pr[i] - mirrored).norm() < 1e-9, "digit {i}");
        }
    }
}
