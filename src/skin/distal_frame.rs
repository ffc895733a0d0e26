//! The last joint of every digit aimed along its distal phalanx, carried from the template by
//! homology.
//!
//! The calibration motion fixes a hinge's axis but not which way the link beyond it points: for
//! the PIP and MCP the next joint's centre gives that direction, but the distal phalanx ends in
//! no joint, and the only marker beyond the DIP sits on the nail, dorsal of the bone, so the
//! line from the DIP's centre to it leans 20-70° dorsally off the phalanx. What a distal frame's
//! z decides downstream is real: the fingertip (placed along z level with the skin's farthest
//! distal point) and the DIP's caliper section (normal to the bisector of the two links).
//!
//! The template knows its phalanges, and the fitted skin is homologous to it: the distal
//! region's vertices are the same vertices on both. The rotation that best carries the posed
//! template's distal region onto the fitted skin's (Horn's absolute orientation of the two
//! centred point sets, no scale) carries the template's distal z onto the subject's; it is then
//! made normal to the subject's hinge axis, which the calibration measured and which is kept.
//!
//! Where a lab placed the optional fingertip markers (`X_TIP`, on the apex, where the phalanx's
//! long axis leaves the skin), the line from the distal joint's centre to the marker is the
//! phalanx itself, and [`distal_frames_at_tips`] aims the frame along it instead: the homology
//! carries the template's fingertip, whose nail may sit otherwise over the bone than the
//! subject's.

use crate::anatomy::{Finger, Joint};
use crate::geometry::{absolute_orientation, Point, TriMesh};
use crate::skeleton::Skeleton;

/// Re-aim the last joint of every digit of `model` (T_IP, X_DIP) along the distal phalanx of
/// the fitted `skin`. `template` and `template_skin` are the template's skeleton and skin in
/// its own reference posture, in the subject's frame (pre-aligned, not posed: a posed
/// skeleton keeps a joint's frame on its parent link, while the distal region turns with the
/// child); `owner` is each vertex's dominant link (the template's); `skin` is homologous to
/// `template_skin`. Centres, axes and every other frame are kept; a digit whose distal region
/// has fewer than three vertices, or whose new z would lie along its axis, keeps its frame.
pub fn distal_frames_by_homology(
    model: &Skeleton,
    template: &Skeleton,
    template_skin: &TriMesh,
    skin: &TriMesh,
    owner: &[usize],
) -> Skeleton {
    let mut out = model.clone();
    for f in Finger::ALL {
        let j: Joint = f.joints()[2];
        let link = j.child_link().index();
        let (src, dst): (Vec<Point>, Vec<Point>) = owner
            .iter()
            .enumerate()
            .filter(|(_, &o)| o == link)
            .map(|(v, _)| (template_skin.vertices[v], skin.vertices[v]))
            .unzip();
        if src.len() < 3 {
            continue;
        }
        let Ok(reg) = absolute_orientation(&src, &dst, None, false) else {
            continue;
        };
        let t = template.joint(j);
        out.aim_long_axis(j, &(reg.rotation * t.z()), &(reg.rotation * t.y()));
    }
    out
}

/// Re-aim the last joint of each digit in `tips` (digit, its fingertip marker) from the
/// joint's centre at that point. The fingertip marker sits where the distal
/// phalanx's long axis leaves the skin, so this line is the phalanx itself, where the
/// homology of [`distal_frames_by_homology`] carries the template's fingertip shape (a nail
/// set higher or lower over the bone turns it). Axes and centres are kept; a point at the
/// centre, or along the axis, leaves the frame as it was.
pub fn distal_frames_at_tips(model: &Skeleton, tips: &[(Finger, Point)]) -> Skeleton {
    let mut out = model.clone();
    for &(f, p) in tips {
        let j: Joint = f.joints()[2];
        let long = p - model.centre(j);
        if long.norm() > 1e-6 {
            let dorsal = model.joint(j).y();
            out.aim_long_axis(j, &long.normalize(), &dorsal);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::skeleton::forward_kinematics::linear_blend;
    use crate::skeleton::forward_kinematics::{link_transforms, posed_skeleton};
    use crate::skeleton::Pose;
    use crate::template::{dominant_links, load_template};
    use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion};

    /// The template posed with its DIPs flexed and its whole hand moved, taken as a subject's
    /// reference posture: its distal phalanges point where the distal links' transforms carry
    /// the template's. A model whose distal z points elsewhere (here 50° dorsally) is re-aimed
    /// there; the axes and centres stay.
    #[test]
    fn a_posed_template_gives_back_its_own_distal_frames() {
        let t = load_template(Side::Right).unwrap();
        let mut pose = Pose::zero();
        for (k, f) in Finger::ALL.iter().enumerate() {
            pose = pose.with_deg(f.joints()[2], [10.0 + 6.0 * k as f64, 0.0, 0.0]);
        }
        let rigid = Isometry3::from_parts(
            Translation3::new(30.0, -12.0, 7.0),
            UnitQuaternion::from_euler_angles(0.3, -0.2, 0.5),
        );
        let tf: Vec<Isometry3<f64>> = link_transforms(&t.skeleton, &pose)
            .into_iter()
            .map(|x| rigid * x)
            .collect();
        let truth = posed_skeleton(&t.skeleton, &tf);
        let skin = TriMesh {
            vertices: linear_blend(&t.mesh.vertices, &t.weights, &tf),
            faces: t.mesh.faces.clone(),
        };
        // The model: each distal z swung 50° dorsally about its axis from where it should be.
        let mut model = truth.clone();
        for f in Finger::ALL {
            let j = f.joints()[2];
            let x = model.joint(j).x();
            let want = tf[j.child_link().index()].rotation * t.skeleton.joint(j).z();
            let swing = Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(x), -0.87);
            let dorsal = model.joint(j).y();
            assert!(model.aim_long_axis(j, &(swing * want), &dorsal));
        }
        let owner = dominant_links(&t.weights);
        let out = distal_frames_by_homology(&model, &t.skeleton, &t.mesh, &skin, &owner);
        for f in Finger::ALL {
            let j = f.joints()[2];
            let (o, m) = (out.joint(j), model.joint(j));
            let want = tf[j.child_link().index()].rotation * t.skeleton.joint(j).z();
            assert!(m.z().angle(&want).to_degrees() > 45.0);
            // LBS bends the skin near the DIP, so the region turns a little less than its bone.
            let err = o.z().angle(&want).to_degrees();
            assert!(err < 2.0, "{j}: {err:.2}°");
            assert!((o.x() - m.x()).norm() < 1e-12, "{j}: the axis moved");
            assert!(o.z().dot(&o.x()).abs() < 1e-12);
            assert_eq!(o.centre, m.centre);
        }
        let last = Finger::ALL.map(|f| f.joints()[2]);
        for j in Joint::ALL.iter().filter(|j| !last.contains(j)) {
            assert_eq!(out.joint(*j).frame, model.joint(*j).frame, "{j}");
        }
    }
}
