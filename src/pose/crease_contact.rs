//! Skin pressed against skin at a flexed joint's crease.
//!
//! Where a finger's PIP or DIP bends hard (a fist's PIPs at 100°), skinning swings the palmar
//! skin of the distal phalanx into that of the proximal one: near the crease the two sheets pass
//! through each other, and no tetrahedral mesh whose boundary lies on that skin can keep every
//! element positive. A real finger's pads meet and flatten against each other. As in skinning
//! with contact (Vaillant et al. 2013, "Implicit skinning: real-time skin deformation with
//! contact modeling", where the skin of two parts stops on the surface where they meet), each
//! flexed joint gets a contact surface, here its bisector plane: through the joint's centre,
//! halfway between the two bones, so containing the hinge's axis. The skin near the joint on
//! the side it bends toward is kept on its own side of that plane, a small gap apart: a vertex
//! that lies distal of the joint's rest bisector plane on the distal side, the others on the
//! proximal side.
//!
//! Inputs: the posed points (skin vertices or tetrahedral nodes), their rest positions and link
//! weights, the rest skeleton and the pose's link transforms. Only joints bent more than
//! [`MIN_BEND_DEG`] beyond their rest bend, and points within [`REACH_FRACTION`] of the shorter
//! bone from the joint's centre, on the side the joint bends toward, mostly weighted to the
//! joint's two bones, are touched; anything else is left exactly where skinning put it.

use crate::anatomy::{Joint, Link};
use crate::geometry::{Point, Vec3};
use crate::skeleton::Skeleton;
use crate::template::LinkWeights;
use nalgebra::Isometry3;

/// A joint bent less than this beyond its rest bend leaves its pads apart, degrees.
pub const MIN_BEND_DEG: f64 = 30.0;

/// Vertices closer to the joint's centre than this fraction of the shorter of its two bones
/// can meet the other side's pad.
pub const REACH_FRACTION: f64 = 0.75;

/// Half the gap kept between the two pads, mm: each side stops this far from the plane.
pub const HALF_GAP_MM: f64 = 0.05;

/// The joints whose pads meet when they flex: the fingers' PIPs and DIPs, whose two pads are
/// phalanges alike. An MCP presses a phalanx into the palm, whose pad is thick and far from
/// the joint: no plane through the joint stands for that. The thumb's metacarpal carries the
/// thenar eminence, which runs into the palm, so its MCP has no phalanx pad on the proximal
/// side either.
fn crease_joints() -> impl Iterator<Item = Joint> {
    Joint::ALL.into_iter().filter(|&j| {
        j.rank() >= 1
            && j.finger()
                .is_some_and(|f| f != crate::anatomy::Finger::Thumb)
    })
}

/// The angle between the two bones at `c`, from the straight line (0 when `to_parent` and
/// `to_child` are opposite), radians.
fn bend(to_parent: &Vec3, to_child: &Vec3) -> f64 {
    (-to_parent.dot(to_child)).clamp(-1.0, 1.0).acos()
}

/// `skin` (posed by `transforms` of `skeleton` from `rest`, with per-vertex `weights`) kept on
/// its own side of every flexed joint's bisector plane (see the module documentation). A
/// vertex's side is the one it has at rest, of the rest bisector plane: at the bottom of a
/// crease the weights are blended half and half and would split one pad between the two
/// sides. Returns the number of vertices moved.
pub fn separate_creases(
    skin: &mut [Point],
    rest: &[Point],
    weights: &LinkWeights,
    skeleton: &Skeleton,
    transforms: &[Isometry3<f64>],
) -> usize {
    let mut moved = vec![false; skin.len()];
    for j in crease_joints() {
        let Some(parent_joint) = j.parent() else {
            continue;
        };
        let (parent, child) = (j.parent_link(), j.child_link());
        let rest_c = skeleton.centre(j);
        let rest_p = skeleton.centre(parent_joint);
        let rest_d = skeleton.distal_end(j);
        let (len_p, len_d) = ((rest_p - rest_c).norm(), (rest_d - rest_c).norm());
        if len_p <= 0.0 || len_d <= 0.0 {
            continue;
        }
        let tc = &transforms[child.index()];
        let c = tc * rest_c;
        let p = transforms[parent.index()] * rest_p;
        let d = tc * rest_d;
        let (u, v) = ((p - c) / len_p, (d - c) / len_d);
        let (rest_u, rest_v) = ((rest_p - rest_c) / len_p, (rest_d - rest_c) / len_d);
        let rest_bend = bend(&rest_u, &rest_v);
        let Some(rest_normal) = (rest_v - rest_u).try_normalize(1e-9) else {
            continue;
        };
        if bend(&u, &v) - rest_bend < MIN_BEND_DEG.to_radians() {
            continue;
        }
        // Toward the inside of the bend, and the plane's normal toward the child.
        let (Some(inward), Some(normal)) =
            ((u + v).try_normalize(1e-9), (v - u).try_normalize(1e-9))
        else {
            continue;
        };
        let reach = REACH_FRACTION * len_p.min(len_d);
        for (i, x) in skin.iter_mut().enumerate() {
            let r = *x - c;
            if r.norm() > reach || r.dot(&inward) <= 0.0 {
                continue;
            }
            let w = |l: Link| {
                weights[i]
                    .iter()
                    .filter(|(k, _)| *k == l.index())
                    .map(|(_, w)| w)
                    .sum::<f64>()
            };
            if w(parent) + w(child) < 0.5 {
                continue;
            }
            let s = r.dot(&normal);
            let shift = if (rest[i] - rest_c).dot(&rest_normal) > 0.0 {
                (HALF_GAP_MM - s).max(0.0)
            } else {
                -(s + HALF_GAP_MM).max(0.0)
            };
            if shift != 0.0 {
                *x += normal * shift;
                moved[i] = true;
            }
        }
    }
    moved.iter().filter(|&&m| m).count()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::pose::dual_quaternion;
    use crate::skeleton::forward_kinematics::link_transforms;
    use crate::skeleton::Pose;
    use crate::template::load_template;

    /// The template's skin with only the middle finger's PIP flexed: the pads near the PIP end
    /// on their own sides of the bisector plane (computed here from the posed bones), each moved
    /// along the plane's normal only; nothing else moves; the open hand is left as it is.
    #[test]
    fn a_flexed_pip_keeps_its_pads_on_their_sides_and_nothing_else_moves() {
        let t = load_template(Side::Right).unwrap();
        let open = Pose::zero();
        let tr = link_transforms(&t.skeleton, &open);
        let mut skin = dual_quaternion(&t.mesh.vertices, &t.weights, &tr).unwrap();
        let before = skin.clone();
        let rest = &t.mesh.vertices;
        assert_eq!(
            separate_creases(&mut skin, rest, &t.weights, &t.skeleton, &tr),
            0
        );
        assert_eq!(skin, before);

        let pose = Pose::zero().with_deg(Joint::MPip, [110.0, 0.0, 0.0]);
        let tr = link_transforms(&t.skeleton, &pose);
        let mut skin = dual_quaternion(&t.mesh.vertices, &t.weights, &tr).unwrap();
        let before = skin.clone();
        let moved = separate_creases(&mut skin, rest, &t.weights, &t.skeleton, &tr);
        assert!(moved > 0);
        // The plane, independently of the function: the posed PIP, MCP and DIP centres.
        let sk = &t.skeleton;
        let c = tr[Link::MMid.index()] * sk.centre(Joint::MPip);
        let p = tr[Link::MProx.index()] * sk.centre(Joint::MMcp);
        let d = tr[Link::MMid.index()] * sk.centre(Joint::MDip);
        let (u, v) = ((p - c).normalize(), (d - c).normalize());
        let normal = (v - u).normalize();
        let rest_c = sk.centre(Joint::MPip);
        let rest_normal = (sk.centre(Joint::MDip) - rest_c).normalize()
            - (sk.centre(Joint::MMcp) - rest_c).normalize();
        let inward = (u + v).normalize();
        let reach = REACH_FRACTION * (p - c).norm().min((d - c).norm());
        let weight = |i: usize, l: Link| -> f64 {
            t.weights[i]
                .iter()
                .filter(|(k, _)| *k == l.index())
                .map(|(_, w)| w)
                .sum()
        };
        let mut checked = 0;
        for (i, (a, b)) in skin.iter().zip(&before).enumerate() {
            let shift = a - b;
            // Any move is along the plane's normal.
            assert!(
                shift.cross(&normal).norm() < 1e-9,
                "vertex {i} moved off the normal"
            );
            let r = b - c;
            let (wp, wc) = (weight(i, Link::MProx), weight(i, Link::MMid));
            let near = r.norm() <= reach && r.dot(&inward) > 0.0 && wp + wc >= 0.5;
            if !near {
                assert_eq!(a, b, "vertex {i} is not at the crease but moved");
                continue;
            }
            let s = (a - c).dot(&normal);
            if (rest[i] - rest_c).dot(&rest_normal) > 0.0 {
                assert!(s >= HALF_GAP_MM - 1e-9, "distal pad vertex {i} at {s} mm");
            } else {
                assert!(
                    s <= -HALF_GAP_MM + 1e-9,
                    "proximal pad vertex {i} at {s} mm"
                );
            }
            checked += 1;
        }
        assert!(checked >= moved);
    }
}
