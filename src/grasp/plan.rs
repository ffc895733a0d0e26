//! What a grasp type asks of the hand: its preshape and closed posture ([`grasp_plan`], degrees
//! within [`crate::skeleton::limits::joint_limits_deg`]), which joints close and in what order,
//! the pads that must touch, and the grasp frame a scene's approach places the wrist in.

use super::hand::PosableHand;
use super::scene::GraspType;
use crate::anatomy::{Finger, Joint, Link};
use crate::geometry::{Point, Vec3};
use crate::skeleton::limits::joint_limits_deg;
use crate::skeleton::Skeleton;
use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion};

/// Preshape and closed posture of a grasp type, radians, and which joints close.
#[derive(Clone, Debug, PartialEq)]
pub struct GraspPlan {
    /// Angles at `t = 0`.
    pub preshape: [[f64; 3]; 16],
    /// Angles at `t = 1`.
    pub closed: [[f64; 3]; 16],
    /// Joints that close.
    pub active: [bool; 16],
    /// Closing order within a digit: `true` wraps (only the most proximal joint still moving
    /// advances, so the proximal phalanx meets the part first and the finger curls onto it,
    /// as in a power grasp); `false` closes the digit's joints together (the fingertip leads,
    /// as in precision grasps).
    pub wrap: bool,
    /// Longest wrist travel (mm) along the grasp frame's palmar axis before closing, stopping
    /// when the palm touches ([`approach_to_contact`]); 0: the fingers close from the approach.
    pub approach_mm: f64,
    /// The links that hold the part in this grasp type and must touch it: the distal pads of
    /// the thumb and the closing fingers in precision grasps (Cutkosky 1989: precision grasps
    /// hold the part between the pads of the thumb and fingers, off the palm); the thumb's
    /// distal pad and the index's middle phalanx in the lateral grasp; empty for power grasps,
    /// which hold with whatever touches.
    pub pads: Vec<Link>,
    /// A pad that does not close: the part is placed against it and the thumb presses the part
    /// onto it (the lateral or key pinch: the thumb pad presses the part against the radial
    /// side of the flexed index's middle phalanx, Cutkosky 1989; Napier 1956).
    pub support: Option<Link>,
}

/// The plan of a grasp type (degrees chosen within the anatomical limits; the wrist stays put).
pub fn grasp_plan(kind: GraspType) -> GraspPlan {
    let mut pre = [[0.0; 3]; 16];
    let mut closed = [[0.0; 3]; 16];
    let mut active = [false; 16];
    let set = |a: &mut [[f64; 3]; 16], j: Joint, d: [f64; 3]| a[j.index()] = d;
    let tucked = [[60.0, 0.0, 0.0], [95.0, 0.0, 0.0], [60.0, 0.0, 0.0]];
    let fingers = [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little];
    type Plan = (
        [[f64; 3]; 3],
        [[f64; 3]; 3],
        Vec<Finger>,
        [[f64; 3]; 3],
        [[f64; 3]; 3],
    );
    let (thumb_pre, thumb_closed, closing, f_pre, f_closed): Plan = match kind {
        // The thumb waits extended and radially abducted in the plane of the palm (the CMC's
        // limits) while the palm comes in to the part, then wraps it: preshaped at [-20, 0, 0]
        // its proximal phalanx stood out of the palm and stopped the approach 10 mm short.
        GraspType::Power => (
            [[-25.0, -15.0, 0.0], [0.0; 3], [0.0; 3]],
            [[40.0, 55.0, 20.0], [55.0, 0.0, 0.0], [75.0, 0.0, 0.0]],
            fingers.to_vec(),
            [[0.0; 3]; 3],
            [[88.0, 0.0, 0.0], [105.0, 0.0, 0.0], [80.0, 0.0, 0.0]],
        ),
        // The closed posture brings the pads together, 40 mm off the palm: the thumb's distal
        // link ends within 4 mm of the midpoint of the index and middle distal links (a grid
        // search over the thumb's range for the template hand), their skins meet, and a part
        // between the pads is caught by all of them before t = 1 (`pads_meet_when_closed`).
        // The former closed posture (thumb [40, 58, 25], fingers [75, 70, 40]) curled the
        // thumb toward the wrist and the fingers into the palm: its pads stayed 40 mm apart
        // and a pen was held by the thenar and one fingertip.
        GraspType::Precision | GraspType::Pinch | GraspType::Tripod => (
            [[10.0, 50.0, 10.0], [0.0; 3], [0.0; 3]],
            [[35.0, 15.0, 30.0], [20.0, 0.0, 0.0], [0.0; 3]],
            match kind {
                GraspType::Precision => fingers.to_vec(),
                GraspType::Pinch => vec![Finger::Index],
                _ => vec![Finger::Index, Finger::Middle],
            },
            [[15.0, 0.0, 0.0], [10.0, 0.0, 0.0], [0.0; 3]],
            [[60.0, 0.0, 0.0], [50.0, 0.0, 0.0], [30.0, 0.0, 0.0]],
        ),
        // The key pinch: the index stands flexed (MCP 60, PIP 80, DIP 30) and still, the other
        // fingers curled, and the thumb adducts its pad onto the radial side of the index's
        // middle phalanx. The closed thumb posture is the one of a grid search over the thumb's
        // range (5 to 10° steps, template hand) whose distal link's centroid lies closest to
        // 8 mm radial of the middle phalanx's radial skin (their skins then meet,
        // `lateral_thumb_meets_the_index_side`); the preshape, from the same grid, opens the
        // thumb pad 25 mm straight away from it (off the line by 2 mm), room for a key or a
        // pen. The former plan (index curled to [80, 100, 70] and closing, thumb closing to
        // [40, -10, 10]) had no pads meeting: the pen was held by the thumb's proximal phalanx
        // and the index's proximal and distal ones, and dropped.
        GraspType::Lateral => (
            [[-5.0, 10.0, 0.0], [20.0, 0.0, 0.0], [30.0, 0.0, 0.0]],
            [[0.0, 5.0, 0.0], [40.0, 0.0, 0.0], [50.0, 0.0, 0.0]],
            vec![Finger::Index],
            [[60.0, 0.0, 0.0], [80.0, 0.0, 0.0], [30.0, 0.0, 0.0]],
            [[60.0, 0.0, 0.0], [80.0, 0.0, 0.0], [30.0, 0.0, 0.0]],
        ),
    };
    for (k, j) in Finger::Thumb.joints().into_iter().enumerate() {
        set(&mut pre, j, thumb_pre[k]);
        set(&mut closed, j, thumb_closed[k]);
        active[j.index()] = true;
    }
    for f in fingers {
        for (k, j) in f.joints().into_iter().enumerate() {
            if closing.contains(&f) {
                set(&mut pre, j, f_pre[k]);
                set(&mut closed, j, f_closed[k]);
                // The lateral grasp's index is the support: posed, not closed.
                active[j.index()] = kind != GraspType::Lateral;
            } else {
                set(&mut pre, j, tucked[k]);
                set(&mut closed, j, tucked[k]);
            }
        }
    }
    let clamp = |a: [[f64; 3]; 16]| {
        let mut out = a;
        for j in Joint::ALL {
            for (d, [lo, hi]) in joint_limits_deg(j).into_iter().enumerate() {
                out[j.index()][d] = a[j.index()][d].clamp(lo, hi).to_radians();
            }
        }
        out
    };
    GraspPlan {
        preshape: clamp(pre),
        closed: clamp(closed),
        active,
        wrap: kind == GraspType::Power,
        // A power grasp holds the part against the palm (Cutkosky 1989): the wrist comes in
        // until the palm touches. Precision grasps hold it with the fingertips, off the palm.
        approach_mm: if kind == GraspType::Power { 40.0 } else { 0.0 },
        pads: match kind {
            GraspType::Power => Vec::new(),
            GraspType::Lateral => vec![Link::TDist, Link::IMid],
            // The thumb with the index and middle (a precision grasp closes all four fingers
            // but is held by the first two; a pinch closes the index alone).
            _ => std::iter::once(Finger::Thumb)
                .chain(closing.iter().copied().take(2))
                .map(|f| digit_links(f)[2])
                .collect(),
        },
        support: (kind == GraspType::Lateral).then_some(Link::IMid),
    }
}

/// The hand's grasp frame in the reference posture: origin on the palmar skin below the palm's
/// centre, z out of the palm (palmar), y from the wrist toward the middle finger, x = y × z.
pub fn grasp_frame(hand: &dyn PosableHand) -> Isometry3<f64> {
    let links = hand.vertex_link();
    let palm = hand
        .rest_mesh()
        .vertices
        .iter()
        .zip(links)
        .filter(|(_, &l)| l == Link::Palm.index())
        .map(|(v, _)| v);
    palm_grasp_frame(hand.skeleton(), palm)
}

/// [`grasp_frame`] of the skeleton `sk` whose palm skin is `palm_skin`: the origin goes to the
/// furthest of these points along the palmar direction within 15 mm of the palm's centre line.
pub(crate) fn palm_grasp_frame<'a>(
    sk: &Skeleton,
    palm_skin: impl Iterator<Item = &'a Point>,
) -> Isometry3<f64> {
    let palmar = -sk.joint(Joint::Wrist).y();
    let mcp = [Joint::IMcp, Joint::MMcp, Joint::RMcp, Joint::LMcp];
    let centre = Point::from(
        (mcp.iter().map(|&j| sk.centre(j).coords).sum::<Vec3>() / 4.0
            + sk.centre(Joint::Wrist).coords)
            / 2.0,
    );
    let along = sk.centre(Joint::MMcp) - sk.centre(Joint::Wrist);
    let y = (along - palmar * palmar.dot(&along)).normalize();
    let x = y.cross(&palmar);
    let mut depth = 0.0f64;
    for v in palm_skin {
        let r = v - centre;
        let lateral = r - palmar * palmar.dot(&r);
        if lateral.norm() < 15.0 {
            depth = depth.max(palmar.dot(&r));
        }
    }
    let rot = Rotation3::from_basis_unchecked(&[x, y, palmar]);
    Isometry3::from_parts(
        Translation3::from((centre + palmar * depth).coords),
        UnitQuaternion::from_rotation_matrix(&rot),
    )
}

/// The closing targets of the active joints, degrees, by joint name.
pub fn plan_deg(plan: &GraspPlan) -> Vec<(String, [f64; 3])> {
    Joint::ALL
        .iter()
        .filter(|j| plan.active[j.index()])
        .map(|j| {
            (
                j.name().to_string(),
                plan.closed[j.index()].map(f64::to_degrees),
            )
        })
        .collect()
}

/// The digit's links (thumb: metacarpal, proximal, distal).
pub(crate) fn digit_links(f: Finger) -> [Link; 3] {
    let j = f.joints();
    [j[0].child_link(), j[1].child_link(), j[2].child_link()]
}
