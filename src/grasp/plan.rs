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
    /// advances, until it presses its phalanx into the part, so the proximal phalanx meets the
    /// part first and the finger curls onto it, as in a power grasp; see
    /// [`super::autograsp::autograsp`]); `false` closes the digit's joints together (the
    /// fingertip leads, as in precision grasps).
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
    /// Links whose skin the approach to contact may press into the part by this much (mm):
    /// soft tissue that gives way under the part, as the thenar eminence does when a handle is
    /// pressed into the palm ([`approach_to_contact`]).
    pub give_mm: Vec<(Link, f64)>,
}

impl GraspPlan {
    /// How far the approach may press `link`'s skin into the part, mm ([`GraspPlan::give_mm`];
    /// 0 for a link not named there).
    pub fn give(&self, link: usize) -> f64 {
        self.give_mm
            .iter()
            .find(|(l, _)| l.index() == link)
            .map_or(0.0, |g| g.1)
    }
}

/// How far a power grasp's approach may press the thenar eminence (the skin of the thumb's
/// metacarpal) into the part, mm. The thenar stands proud of the palm and, rigid, stopped the
/// approach with the palm still off a bottle's side; its soft tissue is the thickest of the
/// palm's and gives way under a handle. Of 2, 3 and 4 mm on the template's bottle grasp, the
/// least that lets its palm meet the bottle (README, "Grasps that wrap").
pub const THENAR_GIVE_MM: f64 = 3.0;

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
        give_mm: if kind == GraspType::Power {
            vec![(Link::TMeta, THENAR_GIVE_MM)]
        } else {
            Vec::new()
        },
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

/// A digit's distal pad: the most palmar skin point of the pulp of its distal link (between 30
/// and 75 % of the link's length from its joint) in the rest posture, with the link's palmar
/// direction as its outward normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pad {
    /// The distal link.
    pub link: Link,
    /// The pad point, rest posture, mm.
    pub point: Point,
    /// Outward normal of the pad (palmar of the link), rest posture.
    pub normal: Vec3,
}

impl Pad {
    /// The pad moved with its link by `transforms`
    /// ([`crate::skeleton::forward_kinematics::link_transforms`]).
    pub fn posed(&self, transforms: &[Isometry3<f64>]) -> (Point, Vec3) {
        let t = &transforms[self.link.index()];
        (t * self.point, t.rotation * self.normal)
    }
}

/// The distal pad of digit `f` of `hand` ([`Pad`]); `None` when its distal link has no skin
/// in the pulp.
pub fn distal_pad(hand: &dyn PosableHand, f: Finger) -> Option<Pad> {
    let sk = hand.skeleton();
    let j = f.joints()[2];
    let frame = sk.joint(j);
    let c = frame.centre;
    let (along, palmar) = (frame.z(), -frame.y());
    let length = (sk.tips[f as usize] - c).dot(&along);
    let link = j.child_link();
    let mesh = hand.rest_mesh();
    hand.link_vertices()[link.index()]
        .iter()
        .map(|&i| mesh.vertices[i])
        .filter(|v| {
            let s = (v - c).dot(&along);
            s >= 0.3 * length && s <= 0.75 * length
        })
        .max_by(|a, b| (a - c).dot(&palmar).total_cmp(&(b - c).dot(&palmar)))
        .map(|point| Pad {
            link,
            point,
            normal: palmar,
        })
}

/// How far from opposition the thumb's pad may turn, as a length: `OPPOSITION_MM · (1 + cos)`
/// of the angle between the pads' normals is added to the pads' distance (30° off opposition
/// counts as 2.7 mm, a right angle as 20 mm). Within the friction cone (μ = 0.5: 27°) a pinch
/// holds; beyond, the squeezed part slips out between the pads.
const OPPOSITION_MM: f64 = 20.0;

/// Scales of the closing fingers' closed posture tried by [`fit_thumb_to_pads`] (each joint's
/// closed angle times the scale, from the hand's reference posture).
const FINGER_SCALES: [f64; 6] = [0.4, 0.55, 0.7, 0.85, 1.0, 1.15];

/// The thumb's closed posture of a precision plan fitted to `hand` (its own link model and
/// skin), so that its distal pad meets the closing fingers' pads face to face: the thumb pad's
/// point on the midpoint of the fingers' pad points (the index's alone in a pinch) and its
/// normal against theirs. The closing fingers' closed posture is scaled too (a finger curled
/// too far turns its pad toward the wrist, where no thumb can face it): for each scale, a grid
/// over the thumb's range (10° steps) then a pattern search to 0.6°, on forward kinematics of
/// the pad points only; a light pull toward the plan's own posture (0.1 mm per degree) decides
/// between equally good postures. Plans without pads (power) or with a support (lateral) are
/// returned as they are.
pub fn fit_thumb_to_pads(plan: &GraspPlan, hand: &dyn PosableHand) -> GraspPlan {
    if plan.pads.len() < 2 || plan.pads[0] != Link::TDist || plan.support.is_some() {
        return plan.clone();
    }
    let Some(thumb) = distal_pad(hand, Finger::Thumb) else {
        return plan.clone();
    };
    let fingers: Vec<Pad> = plan.pads[1..]
        .iter()
        .filter_map(|l| distal_pad(hand, l.joint()?.finger()?))
        .collect();
    if fingers.len() + 1 != plan.pads.len() {
        return plan.clone();
    }
    let mut best: Option<(f64, GraspPlan)> = None;
    for scale in FINGER_SCALES {
        let mut out = plan.clone();
        for f in Finger::ALL
            .into_iter()
            .filter(|f| *f != Finger::Thumb && plan.active[f.joints()[0].index()])
        {
            for j in f.joints() {
                out.closed[j.index()] = plan.closed[j.index()].map(|a| a * scale);
            }
        }
        let cost = fit_thumb(&mut out, hand, &thumb, &fingers);
        if best.as_ref().is_none_or(|b| cost < b.0) {
            best = Some((cost, out));
        }
    }
    best.map(|b| b.1).unwrap_or_else(|| plan.clone())
}

/// [`fit_thumb_to_pads`] for one closed posture of the fingers: the thumb's closed angles of
/// `plan` replaced by the best found; returns its cost (mm²).
fn fit_thumb(plan: &mut GraspPlan, hand: &dyn PosableHand, thumb: &Pad, fingers: &[Pad]) -> f64 {
    let sk = hand.skeleton();
    let closed = crate::skeleton::Pose {
        angles: plan.closed,
        root: Isometry3::identity(),
    };
    let tr = crate::skeleton::forward_kinematics::link_transforms(sk, &closed);
    let (target, facing) = pads_target(fingers, &tr);
    let joints = Finger::Thumb.joints();
    // The thumb's five degrees of freedom: CMC flexion, abduction, axial rotation, MCP, IP.
    let dofs: [(Joint, usize); 5] = [
        (joints[0], 0),
        (joints[0], 1),
        (joints[0], 2),
        (joints[1], 0),
        (joints[2], 0),
    ];
    let limits: Vec<[f64; 2]> = dofs.iter().map(|&(j, d)| joint_limits_deg(j)[d]).collect();
    let start: Vec<f64> = dofs
        .iter()
        .map(|&(j, d)| plan.closed[j.index()][d].to_degrees())
        .collect();
    let mut pose = closed.clone();
    let mut cost = |x: &[f64]| {
        for (k, &(j, d)) in dofs.iter().enumerate() {
            pose.angles[j.index()][d] = x[k].to_radians();
        }
        let t = crate::skeleton::forward_kinematics::link_transforms(sk, &pose);
        let (p, n) = thumb.posed(&t);
        let pull: f64 = x
            .iter()
            .zip(&start)
            .map(|(a, b)| (0.1 * (a - b)).powi(2))
            .sum();
        (p - target).norm_squared() + (OPPOSITION_MM * (1.0 + n.dot(&facing))).powi(2) + pull
    };
    let mut best = (cost(&start), start.clone());
    let grid = |k: usize| {
        let [lo, hi] = limits[k];
        let n = ((hi - lo) / 10.0).floor() as usize;
        (0..=n).map(move |i| lo + 10.0 * i as f64)
    };
    for a in grid(0) {
        for b in grid(1) {
            for c in grid(2) {
                for m in grid(3) {
                    for i in grid(4).filter(|&i| (0.0..=60.0).contains(&i)) {
                        let x = [a, b, c, m, i];
                        let f = cost(&x);
                        if f < best.0 {
                            best = (f, x.to_vec());
                        }
                    }
                }
            }
        }
    }
    let mut step = 5.0;
    while step > 0.6 {
        let mut moved = false;
        for k in 0..5 {
            for s in [-step, step] {
                let mut x = best.1.clone();
                x[k] = (x[k] + s).clamp(limits[k][0], limits[k][1]);
                let f = cost(&x);
                if f < best.0 - 1e-12 {
                    best = (f, x);
                    moved = true;
                }
            }
        }
        if !moved {
            step /= 2.0;
        }
    }
    for (k, &(j, d)) in dofs.iter().enumerate() {
        plan.closed[j.index()][d] = best.1[k].to_radians();
    }
    best.0
}

/// Where the thumb's pad should meet the fingers' `fingers` pads posed by `transforms`: the
/// mean of their points, and the mean of their normals (unit), which the thumb's pad faces.
fn pads_target(fingers: &[Pad], transforms: &[Isometry3<f64>]) -> (Point, Vec3) {
    let (mut target, mut facing) = (Vec3::zeros(), Vec3::zeros());
    for p in fingers {
        let (q, n) = p.posed(transforms);
        target += q.coords;
        facing += n;
    }
    (
        Point::from(target / fingers.len() as f64),
        facing.normalize(),
    )
}

/// How a precision plan's closed posture puts `hand`'s thumb pad on the fingers' pads (what
/// [`fit_thumb_to_pads`] fits): its distance from their target point (mm) and the angle of its
/// normal from facing them (degrees, 0 face to face). `None` for a plan without pads beyond the
/// thumb's, or a digit without a pad.
pub fn pad_meeting(hand: &dyn PosableHand, plan: &GraspPlan) -> Option<(f64, f64)> {
    let thumb = distal_pad(hand, Finger::Thumb)?;
    let fingers = plan
        .pads
        .get(1..)
        .filter(|p| !p.is_empty())?
        .iter()
        .map(|l| distal_pad(hand, l.joint()?.finger()?))
        .collect::<Option<Vec<Pad>>>()?;
    let closed = crate::skeleton::Pose {
        angles: plan.closed,
        root: Isometry3::identity(),
    };
    let tr = crate::skeleton::forward_kinematics::link_transforms(hand.skeleton(), &closed);
    let (target, facing) = pads_target(&fingers, &tr);
    let (t, n) = thumb.posed(&tr);
    Some((
        (t - target).norm(),
        (-n.dot(&facing)).clamp(-1.0, 1.0).acos().to_degrees(),
    ))
}

/// [`grasp_plan`] of `kind` fitted to `hand` ([`fit_thumb_to_pads`] for the precision types).
pub fn grasp_plan_for(kind: GraspType, hand: &dyn PosableHand) -> GraspPlan {
    fit_thumb_to_pads(&grasp_plan(kind), hand)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::grasp::RigidHand;
    use crate::skeleton::forward_kinematics::{link_transforms, posed_skeleton};
    use crate::skeleton::Pose;

    /// The template as a hand whose reference posture is another one: every link moved by the
    /// posture `deg`, the skin rigidly with its dominant link, the joint frames re-made in the
    /// new posture (as a reconstruction from another subject's static trial makes them).
    fn re_referenced(deg: &[(Joint, [f64; 3])]) -> RigidHand {
        let h = RigidHand::template(Side::Right).unwrap();
        let pose = deg.iter().fold(Pose::zero(), |p, &(j, d)| p.with_deg(j, d));
        let tr = link_transforms(&h.skeleton, &pose);
        let mut mesh = h.mesh.clone();
        for (v, &l) in mesh.vertices.iter_mut().zip(&h.links) {
            *v = tr[l] * *v;
        }
        RigidHand::new(posed_skeleton(&h.skeleton, &tr), mesh, h.links.clone()).unwrap()
    }

    /// On the template the fitted precision plans put the thumb's pad on the fingers' pads
    /// (within 4 mm) and turn it further toward them than the plan's posture does.
    #[test]
    fn fitted_pads_meet_on_the_template() {
        let h = RigidHand::template(Side::Right).unwrap();
        for kind in [GraspType::Tripod, GraspType::Pinch, GraspType::Precision] {
            let plan = grasp_plan(kind);
            let fitted = fit_thumb_to_pads(&plan, &h);
            let (d0, a0) = pad_meeting(&h, &plan).unwrap();
            let (d, a) = pad_meeting(&h, &fitted).unwrap();
            assert!(
                d < 4.0,
                "{kind:?}: thumb pad {d:.1} mm from the fingers' pads"
            );
            assert!(
                a < a0 - 10.0,
                "{kind:?}: opposition {a:.0}° (plan {a0:.0}°)"
            );
            assert!(
                d <= d0 + 1.0,
                "{kind:?}: {d:.1} mm against the plan's {d0:.1}"
            );
            // The preshape is kept: the part still has room between the pads.
            assert_eq!(fitted.preshape, plan.preshape);
        }
        let power = grasp_plan(GraspType::Power);
        assert_eq!(fit_thumb_to_pads(&power, &h), power);
        let lateral = grasp_plan(GraspType::Lateral);
        assert_eq!(fit_thumb_to_pads(&lateral, &h), lateral);
    }

    /// A hand whose reference posture differs from the template's (thumb flexed and abducted,
    /// fingers bent) gets the same angles of the plan as a different posture: the plan's pads
    /// end centimetres apart, the fitted ones meet as on the template, within the joint limits.
    #[test]
    fn the_fit_follows_the_hands_own_reference_posture() {
        let h = re_referenced(&[
            (Joint::TCmc, [25.0, 20.0, -15.0]),
            (Joint::TMcp, [20.0, 0.0, 0.0]),
            (Joint::IMcp, [25.0, 0.0, 0.0]),
            (Joint::IPip, [20.0, 0.0, 0.0]),
            (Joint::MMcp, [25.0, 0.0, 0.0]),
            (Joint::MPip, [20.0, 0.0, 0.0]),
        ]);
        let plan = grasp_plan(GraspType::Tripod);
        let fitted = fit_thumb_to_pads(&plan, &h);
        let (d0, _) = pad_meeting(&h, &plan).unwrap();
        let (d, a) = pad_meeting(&h, &fitted).unwrap();
        assert!(
            d0 > 10.0,
            "the plan's pads are {d0:.1} mm apart on this hand"
        );
        // Within a pad's half-width (the template's own fit: 3.2 mm, 52°).
        assert!(
            d < 5.0,
            "fitted: thumb pad {d:.1} mm from the fingers' pads"
        );
        assert!(a < 60.0, "fitted: opposition {a:.0}°");
        for j in Joint::ALL {
            for (x, [lo, hi]) in fitted.closed[j.index()].iter().zip(joint_limits_deg(j)) {
                let x = x.to_degrees();
                assert!(x >= lo - 1e-9 && x <= hi + 1e-9, "{}: {x}", j.name());
            }
        }
    }
}
