//! Closing the hand on the part: GraspIt's autograsp (Miller & Allen 2004, "GraspIt!", IEEE RAM
//! 11(4), section "Auto-grasp"), the approach to contact and the squeeze; the placement search
//! over wrist poses is [`super::placement`].
//!
//! Each grasp type has a preshape and a closed posture ([`grasp_plan`], degrees within
//! [`joint_limits_deg`]); every active joint moves along the straight line between the two in a
//! closing parameter `t ∈ [0, 1]`. Fingers close independently in steps of `t`; a step that
//! pushes a link deeper than `max_depth_mm` into the part is halved until it is shorter than
//! `min_step`; a link that touches (within the contact tolerance) stops its own joint and every
//! joint proximal to it in the digit, while the joints distal to it keep closing. A wrapping
//! plan ([`GraspPlan::wrap`], the power grasp) moves one joint of a digit at a time, proximal
//! first, each until its step would press a phalanx into the part (a touch within the tolerance
//! does not stop it): the proximal phalanx meets the part, then the middle one, then the
//! distal one, as fingers wrap a handle. Joints that reach their closed posture with their
//! link never touching are reported.

use super::collide::{has_core, Cores};
use super::contact::{ContactOptions, PartShape};
use super::hand::PosableHand;
use super::plan::{digit_links, grasp_frame, GraspPlan};
use crate::anatomy::{Finger, Joint, Link};
use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::Pose;
use nalgebra::{Isometry3, Translation3};

/// Default skin compression of the [`squeeze`], mm: the finger pulp is 3 to 5 mm of soft
/// tissue over the bone and a firm grip compresses it by about 1 to 2 mm (Serina, Mote &
/// Rempel 1997, fingertip force-displacement: about 1 N at 1 mm, several N at 2 mm).
pub const SQUEEZE_MM: f64 = 1.5;

/// How deep a wrapping digit's [`squeeze`] may press the phalanges a closing joint carries
/// (distal to its own), mm. The wrap leaves the distal phalanx touching last, so with every link
/// held to [`SQUEEZE_MM`] the fingertip reached it first and stopped the MCP and PIP, which left
/// the middle and proximal phalanges barely pressed; the fingertips' push, curled back over the
/// handle, slid it along the palm toward the wrist and out of the grip. Letting the carried pad
/// sink deeper (its pulp is the thickest, and firm grips compress it by 1 to 2 mm, Serina et al.
/// 1997) lets the proximal and middle phalanges be pressed too. The hold test counts no ball
/// deeper than the squeeze ([`super::hold`]), so the fingertip pushes no harder.
pub const WRAP_CARRIED_SQUEEZE_MM: f64 = 2.0;

/// Settings of [`autograsp`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutograspOptions {
    /// Closing step in `t`.
    pub step: f64,
    /// Steps are halved down to this before a penetrating link stops its chain.
    pub min_step: f64,
    /// Deepest penetration accepted, mm.
    pub max_depth_mm: f64,
    /// Contact detection (its tolerance decides "touching").
    pub contact: ContactOptions,
    /// Use every `stride`-th skin vertex for the closing checks (1 = all).
    pub stride: usize,
    /// How much further (mm) a closing phalanx may enter another finger's core than it was
    /// at the start of its closing (skin is soft, the cores are conservative).
    pub finger_allowance_mm: f64,
    /// Skin compression of the [`squeeze`] after contact, mm.
    pub squeeze_mm: f64,
    /// How deep a wrapping digit's [`squeeze`] may press the phalanges a closing joint
    /// carries, mm ([`WRAP_CARRIED_SQUEEZE_MM`]).
    pub wrap_carried_mm: f64,
}

impl Default for AutograspOptions {
    fn default() -> Self {
        AutograspOptions {
            step: 0.04,
            min_step: 0.005,
            max_depth_mm: 0.8,
            contact: ContactOptions::default(),
            stride: 1,
            finger_allowance_mm: 1.0,
            squeeze_mm: SQUEEZE_MM,
            wrap_carried_mm: WRAP_CARRIED_SQUEEZE_MM,
        }
    }
}

/// Result of [`autograsp`].
#[derive(Clone, Debug, PartialEq)]
pub struct Autograsp {
    /// The final posture (root = the approach).
    pub pose: Pose,
    /// Closing parameter reached by each joint.
    pub t: [f64; 16],
    /// Active joints whose link never touched the part (by name).
    pub untouched: Vec<String>,
    /// Links stopped by another finger before touching the part.
    pub collisions: Vec<FingerCollision>,
    /// Posture evaluations made.
    pub evaluations: usize,
    /// Wrist travel of the approach to contact ([`approach_to_contact`]), mm.
    pub approach_mm: f64,
}

/// Pose of the forearm that puts the hand's grasp frame at `approach` in the part's frame,
/// the part being at `part_pose` in the world.
pub fn root_for(
    hand: &dyn PosableHand,
    part_pose: &Isometry3<f64>,
    approach: &Isometry3<f64>,
) -> Isometry3<f64> {
    part_pose * approach * grasp_frame(hand).inverse()
}

pub(crate) fn pose_at(plan: &GraspPlan, t: &[f64; 16], root: Isometry3<f64>) -> Pose {
    let mut p = Pose {
        angles: plan.preshape,
        root,
    };
    for (j, tj) in t.iter().enumerate().take(16) {
        for d in 0..3 {
            p.angles[j][d] = plan.preshape[j][d] + tj * (plan.closed[j][d] - plan.preshape[j][d]);
        }
    }
    p
}

/// Per link: deepest penetration of its skin within the contact tolerance of the part or
/// inside it (mm, positive inside; `f64::MIN` when none is), and whether it touches (within
/// the tolerance or inside).
#[derive(Clone, Copy, Debug, PartialEq)]
struct LinkState {
    depth: f64,
    touches: bool,
}

/// The state of `link` posed by `t`, measured on every `opts.stride`-th of its vertices (those
/// written into `buf`); vertices the broad phase puts deep inside count as `search` deep.
fn link_state(
    hand: &dyn PosableHand,
    part: &PartShape,
    link: usize,
    t: &[Isometry3<f64>],
    opts: &AutograspOptions,
    buf: &mut Vec<Point>,
) -> LinkState {
    use super::contact::Probe;
    let stride = opts.stride.max(1);
    hand.pose_link_every(link, stride, t, buf);
    let mut s = LinkState {
        depth: f64::MIN,
        touches: false,
    };
    if buf.is_empty() || !link_near(part, buf, opts.contact.search_mm) {
        return s;
    }
    // Skin farther out than the tolerance neither touches nor presses: every depth it could
    // give is below the thresholds the closing compares with (all positive), so it is skipped
    // without its exact projection, about half of those the coarser broad phase lets through.
    let touch = (part.touch_grid.band >= opts.contact.tolerance_mm).then_some(&part.touch_grid);
    for p in buf.iter() {
        if touch.is_some_and(|g| g.zone(p) == super::broad::Zone::Outside) {
            continue;
        }
        match part.probe(p, opts.contact.search_mm) {
            Probe::Far => {}
            Probe::Deep => {
                s.depth = s.depth.max(opts.contact.search_mm);
                s.touches = true;
            }
            Probe::Hit(d, _, _) => {
                s.depth = s.depth.max(-d);
                if d <= opts.contact.tolerance_mm {
                    s.touches = true;
                }
            }
        }
    }
    s
}

/// Whether the bounding box of `pts` grown by `r` meets the part's.
fn link_near(part: &PartShape, pts: &[Point], r: f64) -> bool {
    let (mut lo, mut hi) = (pts[0], pts[0]);
    for p in pts {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    (0..3).all(|a| lo[a] - r <= part.hi[a] && hi[a] + r >= part.lo[a])
}

/// A finger stopped by another finger during [`autograsp`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct FingerCollision {
    /// The closing link that would have entered another finger.
    pub link: String,
    /// The link of the other finger.
    pub other: String,
}

/// Deepest link (index, depth in mm) more than [`START_DEPTH_MM`] inside the part with the
/// links at `tr`, where [`autograsp`] refuses to start; `touched` gets which links touch.
fn start_states(
    hand: &dyn PosableHand,
    part: &PartShape,
    tr: &[Isometry3<f64>],
    opts: &AutograspOptions,
    buf: &mut Vec<Point>,
    touched: &mut [bool; 17],
) -> Option<(usize, f64)> {
    let mut worst: Option<(usize, f64)> = None;
    for (l, slot) in touched.iter_mut().enumerate() {
        let s = link_state(hand, part, l, tr, opts, buf);
        *slot = s.touches;
        if s.depth > START_DEPTH_MM && worst.is_none_or(|w| s.depth > w.1) {
            worst = Some((l, s.depth));
        }
    }
    worst
}

/// Deepest a link may start inside the part for [`autograsp`] to close from there, mm.
pub const START_DEPTH_MM: f64 = 2.0;

/// Whether [`autograsp`] would start from `root` (no link more than [`START_DEPTH_MM`] inside
/// the part in the plan's preshape).
pub fn starts_clear(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    root: Isometry3<f64>,
    opts: &AutograspOptions,
) -> bool {
    let tr = link_transforms(hand.skeleton(), &pose_at(plan, &[0.0; 16], root));
    start_states(hand, part, &tr, opts, &mut Vec::new(), &mut [false; 17]).is_none()
}

/// GraspIt autograsp from `root` (see the module documentation), with finger-finger
/// collisions: a closing step that would push a phalanx's skin more than
/// [`AutograspOptions::finger_allowance_mm`] further into another finger's core
/// ([`Cores`]) than at the start of its closing is refused like a step into the part, and
/// the link stops there. Errors when the hand starts inside the part (naming the deepest
/// link).
pub fn autograsp(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    root: Isometry3<f64>,
    opts: &AutograspOptions,
) -> Result<Autograsp> {
    let sk = hand.skeleton();
    let cores = Cores::new(hand);
    let mut t = [0.0; 16];
    let mut buf = Vec::new();
    let mut evaluations = 1;
    let tr = link_transforms(sk, &pose_at(plan, &t, root));
    let mut touched = [false; 17];
    let worst = start_states(hand, part, &tr, opts, &mut buf, &mut touched);
    if let Some((l, d)) = worst {
        // The broad phase only bounds deep points: measure the deepest exactly for the message.
        hand.pose_link(l, &tr, &mut buf);
        let exact = buf
            .iter()
            .filter(|p| part.probe(p, opts.contact.search_mm) == super::contact::Probe::Deep)
            .map(|p| part.distance(p))
            .fold(d, f64::max);
        return Err(Error::invalid(format!(
            "grasp.approach: the hand starts inside the part: link {} is {exact:.1} mm deep at the approach; move the approach away from the part",
            Link::ALL[l].name()
        )));
    }
    let (root, approach_mm) = approach_to_contact(hand, part, plan, root, opts);
    if approach_mm > 0.0 {
        let tr = link_transforms(sk, &pose_at(plan, &t, root));
        for (l, slot) in touched.iter_mut().enumerate() {
            *slot = link_state(hand, part, l, &tr, opts, &mut buf).touches;
        }
    }
    let mut collisions = Vec::new();
    for f in Finger::ALL {
        let joints = f.joints();
        let dl = digit_links(f);
        let mut moving: Vec<bool> = joints.iter().map(|j| plan.active[j.index()]).collect();
        if !moving.iter().any(|&m| m) {
            continue;
        }
        // A link touching already in the preshape stops its chain.
        for k in 0..3 {
            if touched[dl[k].index()] {
                for m in moving.iter_mut().take(k + 1) {
                    *m = false;
                }
            }
        }
        // Finger-finger baseline: how far each phalanx is inside other fingers' cores now.
        let tr = link_transforms(sk, &pose_at(plan, &t, root));
        let posed_cores = cores.posed(&tr);
        let mut baseline = [0.0; 3];
        for k in 0..3 {
            if has_core(dl[k]) {
                hand.pose_link(dl[k].index(), &tr, &mut buf);
                baseline[k] = cores.penetration(&posed_cores, f, &buf).0;
            }
        }
        let mut depth: [f64; 3] = std::array::from_fn(|k| {
            link_state(hand, part, dl[k].index(), &tr, opts, &mut buf).depth
        });
        let mut dt = opts.step;
        let mut guard = 0;
        while moving.iter().any(|&m| m) && guard < 10_000 {
            guard += 1;
            let mut t2 = t;
            let lead = moving.iter().position(|&m| m).unwrap_or(0);
            for k in 0..3 {
                if moving[k] && (!plan.wrap || k == lead) {
                    t2[joints[k].index()] = (t[joints[k].index()] + dt).min(1.0);
                }
            }
            let tr = link_transforms(sk, &pose_at(plan, &t2, root));
            evaluations += 1;
            let posed_cores = cores.posed(&tr);
            let mut st = [LinkState {
                depth: f64::MIN,
                touches: false,
            }; 3];
            let mut blocked: Option<(usize, Option<usize>)> = None;
            for k in 0..3 {
                st[k] = link_state(hand, part, dl[k].index(), &tr, opts, &mut buf);
                // Only a step that takes the link deeper than allowed, and deeper than it
                // already was (the approach may press the thenar in), is refused.
                if st[k].depth > opts.max_depth_mm.max(depth[k] + 1e-6) {
                    blocked = Some((k, None));
                }
                if has_core(dl[k]) && !buf.is_empty() {
                    let (d, other) = cores.penetration(&posed_cores, f, &buf);
                    if d > baseline[k] + opts.finger_allowance_mm {
                        blocked = Some((k, other));
                    }
                }
            }
            if let Some((k, other)) = blocked {
                if dt > opts.min_step {
                    dt *= 0.5;
                    continue;
                }
                // Cannot get closer without passing through: the chain up to k stops here.
                // When k is already still, the skin it dominates is pushed by the blend of the
                // distal joints still moving: the next of them stops too. A wrapping digit
                // moved its lead joint alone: that joint stops, and the next one leads.
                let last = if plan.wrap {
                    lead
                } else if moving[..=k].iter().any(|&m| m) {
                    k
                } else {
                    (k + 1..3).find(|&m| moving[m]).unwrap_or(2)
                };
                for m in moving.iter_mut().take(last + 1) {
                    *m = false;
                }
                match other {
                    None => touched[dl[k].index()] = true,
                    Some(o) => collisions.push(FingerCollision {
                        link: dl[k].name().to_string(),
                        other: Link::ALL[o].name().to_string(),
                    }),
                }
                dt = opts.step;
                continue;
            }
            t = t2;
            for k in 0..3 {
                depth[k] = st[k].depth;
                // A wrapping digit's lead joint closes on past the first touch until its step
                // would press a phalanx in: when the proximal phalanx meets the part, the skin
                // of the middle one beside the joint is within the tolerance too, and stopping
                // there left the fingers straight with hooked tips.
                if st[k].touches {
                    touched[dl[k].index()] = true;
                    if !plan.wrap {
                        for m in moving.iter_mut().take(k + 1) {
                            *m = false;
                        }
                    }
                }
            }
            for k in 0..3 {
                if moving[k] && t[joints[k].index()] >= 1.0 {
                    moving[k] = false;
                }
            }
            dt = opts.step;
        }
    }
    let untouched = Joint::ALL
        .iter()
        .filter(|j| plan.active[j.index()] && !touched[j.child_link().index()])
        .map(|j| j.name().to_string())
        .collect();
    Ok(Autograsp {
        pose: pose_at(plan, &t, root),
        t,
        untouched,
        collisions,
        evaluations,
        approach_mm,
    })
}

/// GraspIt's approach to contact (Miller & Allen 2004: the hand moves along its approach
/// direction until it touches the object, then the fingers close): the hand in the plan's
/// preshape moves from `root` along the palmar axis of its [`grasp_frame`] by at most
/// [`GraspPlan::approach_mm`], in steps of 2 mm halved down to 1/16 mm before any step that
/// would take a link deeper into the part than `max_depth_mm` (or deeper than it was at
/// `root`, or than the plan lets it give way, [`GraspPlan::give_mm`]), and stops as soon as
/// the palm touches. Without it the palm stays where the approach
/// put it and a power grasp wraps the fingers round the part with the palm off it: the
/// thenar and the fingers then push the part away from the palm and nothing opposes them.
/// Returns the new root and the distance travelled, mm.
pub fn approach_to_contact(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    root: Isometry3<f64>,
    opts: &AutograspOptions,
) -> (Isometry3<f64>, f64) {
    if plan.approach_mm <= 0.0 {
        return (root, 0.0);
    }
    let sk = hand.skeleton();
    let axis = (root * grasp_frame(hand)).rotation * Vec3::z();
    let mut buf = Vec::new();
    let mut states = |s: f64| -> [LinkState; 17] {
        let r = Translation3::from(axis * s) * root;
        let tr = link_transforms(sk, &pose_at(plan, &[0.0; 16], r));
        std::array::from_fn(|l| link_state(hand, part, l, &tr, opts, &mut buf))
    };
    let palm = Link::Palm.index();
    let start = states(0.0);
    if start[palm].touches {
        return (root, 0.0);
    }
    let (mut s, mut step) = (0.0, 2.0);
    while s < plan.approach_mm && step >= 1.0 / 16.0 {
        let s2 = (s + step).min(plan.approach_mm);
        let st = states(s2);
        if st
            .iter()
            .zip(&start)
            .enumerate()
            .any(|(l, (a, b))| a.depth > opts.max_depth_mm.max(b.depth + 1e-6).max(plan.give(l)))
        {
            step *= 0.5;
            continue;
        }
        s = s2;
        if st[palm].touches {
            break;
        }
    }
    (Translation3::from(axis * s) * root, s)
}

/// A hand closed on the part from one approach with the default [`AutograspOptions`]: the
/// [`autograsp`] and the [`squeeze`] after it (the squeezed pose and what the squeeze did).
#[derive(Clone, Debug, PartialEq)]
pub struct Closing {
    /// The autograsp.
    pub autograsp: Autograsp,
    /// The posture after the squeeze.
    pub pose: Pose,
    /// What the squeeze did.
    pub squeeze: Squeeze,
}

/// What [`squeeze`] did.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Squeeze {
    /// Skin compression aimed at, mm ([`AutograspOptions::squeeze_mm`]).
    pub target_mm: f64,
    /// Per link of a squeezed digit touching the part: its deepest skin vertex inside the part
    /// after the squeeze, mm.
    pub depth_mm: std::collections::BTreeMap<String, f64>,
    /// Joints that moved, with the closing parameter gained.
    pub closed_further: std::collections::BTreeMap<String, f64>,
}

/// The squeeze after the autograsp: the joints of each digit that touches the part keep
/// closing until its skin is compressed by [`AutograspOptions::squeeze_mm`].
///
/// GraspIt closes to contact and then applies joint torques in its dynamics engine (Miller &
/// Allen 2004, "Dynamics"); the contact force then comes from the torque. Our hand is kinematic
/// in rapier, so the kinematic equivalent is used: the finger pulp is a soft layer (the soft
/// finger contact of Mason & Salisbury 1985 and Ciocarlie, Lackner & Allen 2007, whose normal
/// force grows with the compression of the pad), and each touching digit is closed a little
/// further until its skin sits `squeeze_mm` inside the part. rapier's soft contact turns that
/// overlap into the normal force that lets friction hold the part ([`super::hold`]); a grasp
/// that only touches has no normal force and holds nothing.
///
/// Per digit, in rounds, each active joint with a touching link at or distal to it advances by
/// `step` in `t` (halved down to `min_step`, then it stops) as long as no link of the digit
/// goes deeper than `squeeze_mm` (or than it already was), no phalanx enters another finger's
/// core ([`Cores`]) beyond the autograsp's allowance, and `t ≤ 1`. In a wrapping plan
/// ([`GraspPlan::wrap`]) the links a joint carries, distal to its own, may go as deep as
/// [`AutograspOptions::wrap_carried_mm`]. Deterministic.
pub fn squeeze(
    hand: &dyn PosableHand,
    part: &PartShape,
    plan: &GraspPlan,
    g: &Autograsp,
    opts: &AutograspOptions,
) -> (Pose, [f64; 16], Squeeze) {
    let sk = hand.skeleton();
    let cores = Cores::new(hand);
    let root = g.pose.root;
    let mut t = g.t;
    let mut buf = Vec::new();
    let mut report = Squeeze {
        target_mm: opts.squeeze_mm,
        depth_mm: Default::default(),
        closed_further: Default::default(),
    };
    for f in Finger::ALL {
        let joints = f.joints();
        let dl = digit_links(f);
        if !joints.iter().any(|j| plan.active[j.index()]) {
            continue;
        }
        let tr = link_transforms(sk, &pose_at(plan, &t, root));
        let posed_cores = cores.posed(&tr);
        let mut baseline = [0.0; 3];
        let mut st = [LinkState {
            depth: f64::MIN,
            touches: false,
        }; 3];
        for k in 0..3 {
            st[k] = link_state(hand, part, dl[k].index(), &tr, opts, &mut buf);
            if has_core(dl[k]) && !buf.is_empty() {
                baseline[k] = cores.penetration(&posed_cores, f, &buf).0;
            }
        }
        let start = st;
        let mut moving: [bool; 3] = std::array::from_fn(|k| {
            plan.active[joints[k].index()]
                && t[joints[k].index()] < 1.0
                && (k..3).any(|m| st[m].touches)
        });
        let mut dt = [opts.step; 3];
        let mut guard = 0;
        while moving.iter().any(|&m| m) && guard < 10_000 {
            guard += 1;
            for k in 0..3 {
                if !moving[k] {
                    continue;
                }
                let j = joints[k].index();
                let mut t2 = t;
                t2[j] = (t[j] + dt[k]).min(1.0);
                let tr = link_transforms(sk, &pose_at(plan, &t2, root));
                let posed_cores = cores.posed(&tr);
                let mut next = st;
                let mut refused = false;
                for m in k..3 {
                    next[m] = link_state(hand, part, dl[m].index(), &tr, opts, &mut buf);
                    // A wrapping joint presses its own phalanx; those it carries may sink a
                    // little deeper (see WRAP_CARRIED_SQUEEZE_MM).
                    let target = if plan.wrap && m > k {
                        opts.squeeze_mm.max(opts.wrap_carried_mm)
                    } else {
                        opts.squeeze_mm
                    };
                    let deepest = target.max(start[m].depth);
                    if next[m].depth > deepest {
                        refused = true;
                    }
                    if has_core(dl[m]) && !buf.is_empty() {
                        let (d, _) = cores.penetration(&posed_cores, f, &buf);
                        if d > baseline[m] + opts.finger_allowance_mm {
                            refused = true;
                        }
                    }
                }
                if refused {
                    if dt[k] > opts.min_step {
                        dt[k] *= 0.5;
                    } else {
                        moving[k] = false;
                    }
                    continue;
                }
                t = t2;
                st = next;
                if t[j] >= 1.0 {
                    moving[k] = false;
                }
            }
        }
        for k in 0..3 {
            let j = joints[k];
            let gained = t[j.index()] - g.t[j.index()];
            if gained > 0.0 {
                report.closed_further.insert(j.name().to_string(), gained);
            }
            if st[k].touches {
                report
                    .depth_mm
                    .insert(dl[k].name().to_string(), st[k].depth.max(0.0));
            }
        }
    }
    (pose_at(plan, &t, root), t, report)
}

/// Where the plan's pads meet, in the [`grasp_frame`], from the closed posture: the mean of
/// the centroids of the [`GraspPlan::pads`] links' skin; with a [`GraspPlan::support`], the
/// support's skin vertex nearest the mean centroid of the other pads (where the thumb pad lands
/// on it). `None` for a plan without pads.
pub fn pad_point(hand: &dyn PosableHand, plan: &GraspPlan) -> Option<Vec3> {
    if plan.pads.is_empty() {
        return None;
    }
    let tr = link_transforms(
        hand.skeleton(),
        &pose_at(plan, &[1.0; 16], grasp_frame(hand).inverse()),
    );
    let mut buf = Vec::new();
    let mut centroid = |l: Link| {
        hand.pose_link(l.index(), &tr, &mut buf);
        buf.iter().map(|p| p.coords).sum::<Vec3>() / buf.len().max(1) as f64
    };
    let pressing: Vec<Link> = plan
        .pads
        .iter()
        .copied()
        .filter(|&l| Some(l) != plan.support)
        .collect();
    let mean = pressing.iter().map(|&l| centroid(l)).sum::<Vec3>() / pressing.len().max(1) as f64;
    let Some(s) = plan.support else {
        return Some(mean);
    };
    hand.pose_link(s.index(), &tr, &mut buf);
    buf.iter()
        .map(|p| p.coords)
        .min_by(|a, b| (a - mean).norm().total_cmp(&(b - mean).norm()))
}

/// How the pressing pads close onto a plan's [`GraspPlan::support`] (grasp frame, mm): from the
/// centroid of the pressing pads' skin in the preshape to their centroid in the closed
/// posture, where they meet the support; its length is the grasp's opening, the thickest part
/// that fits between them. `None` without a support.
pub fn press_travel(hand: &dyn PosableHand, plan: &GraspPlan) -> Option<Vec3> {
    plan.support?;
    let centroid = |t: f64| {
        let tr = link_transforms(
            hand.skeleton(),
            &pose_at(plan, &[t; 16], grasp_frame(hand).inverse()),
        );
        let mut buf = Vec::new();
        let mut sum = Vec3::zeros();
        let mut n = 0;
        for &l in plan.pads.iter().filter(|&&l| Some(l) != plan.support) {
            hand.pose_link(l.index(), &tr, &mut buf);
            sum += buf.iter().map(|p| p.coords).sum::<Vec3>();
            n += buf.len();
        }
        sum / n.max(1) as f64
    };
    Some(centroid(1.0) - centroid(0.0))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::grasp::contact::{contacts, vertex_areas};
    use crate::grasp::hand::RigidHand;
    use crate::grasp::parts::Part;
    use crate::grasp::placement::*;
    use crate::grasp::plan::*;
    use crate::grasp::scene::GraspType;
    use crate::skeleton::clamp_pose;
    use std::sync::OnceLock;

    fn hand() -> &'static RigidHand {
        static H: OnceLock<RigidHand> = OnceLock::new();
        H.get_or_init(|| RigidHand::template(Side::Right).unwrap())
    }

    fn bottle() -> &'static PartShape {
        static P: OnceLock<PartShape> = OnceLock::new();
        P.get_or_init(|| PartShape::new(Part::Bottle.mesh().unwrap()).unwrap().0)
    }

    fn side_approach() -> Isometry3<f64> {
        crate::grasp::scene::pose_from([0.0, -36.0, 90.0], [-90.0, -90.0, 0.0])
    }

    #[test]
    fn plans_are_within_limits() {
        for g in [
            GraspType::Power,
            GraspType::Precision,
            GraspType::Pinch,
            GraspType::Tripod,
            GraspType::Lateral,
        ] {
            let p = grasp_plan(g);
            for a in [p.preshape, p.closed] {
                let (_, v) = clamp_pose(&Pose {
                    angles: a,
                    root: Isometry3::identity(),
                });
                assert!(v.is_empty(), "{g:?}: {v:?}");
            }
        }
    }

    /// Closest approach of two links' posed skins, mm (0 when they overlap at a vertex).
    fn skin_gap(h: &RigidHand, a: Link, b: Link, tr: &[Isometry3<f64>]) -> f64 {
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        h.pose_link(a.index(), tr, &mut pa);
        h.pose_link(b.index(), tr, &mut pb);
        pa.iter()
            .flat_map(|p| pb.iter().map(move |q| (p - q).norm()))
            .fold(f64::MAX, f64::min)
    }

    /// The precision plans close the thumb's pad onto the fingers' pads: far apart in the
    /// preshape (room for a part), meeting in the closed posture (a part between them is
    /// caught by every pad before the end of the closing).
    #[test]
    fn pads_meet_when_closed() {
        let h = hand();
        for g in [GraspType::Precision, GraspType::Pinch, GraspType::Tripod] {
            let plan = grasp_plan(g);
            let fingers = if g == GraspType::Pinch { 1 } else { 2 };
            assert_eq!(plan.pads.len(), 1 + fingers, "{g:?}");
            assert_eq!(plan.pads[0], Link::TDist);
            for t in [0.0, 1.0] {
                let tr = link_transforms(
                    &h.skeleton,
                    &pose_at(&plan, &[t; 16], Isometry3::identity()),
                );
                for &l in &plan.pads[1..] {
                    let d = skin_gap(h, Link::TDist, l, &tr);
                    if t == 0.0 {
                        assert!(
                            d > 60.0,
                            "{g:?} preshape: T_DIST {} mm from {}",
                            d,
                            l.name()
                        );
                    } else {
                        assert!(d < 1.0, "{g:?} closed: T_DIST {} mm from {}", d, l.name());
                    }
                }
            }
        }
        assert!(grasp_plan(GraspType::Power).pads.is_empty());
    }

    /// The lateral plan closes the thumb pad onto the radial side of the still index's middle
    /// phalanx: 20 mm and more apart in the preshape, meeting in the closed posture, the thumb
    /// on the index's radial side (toward the index MCP from the middle MCP); its pad point
    /// lies on that phalanx's skin and the pads close onto it.
    #[test]
    fn lateral_thumb_meets_the_index_side() {
        let h = hand();
        let plan = grasp_plan(GraspType::Lateral);
        assert_eq!(plan.pads, vec![Link::TDist, Link::IMid]);
        assert_eq!(plan.support, Some(Link::IMid));
        assert!(Finger::Index
            .joints()
            .iter()
            .all(|j| !plan.active[j.index()]));
        let sk = &h.skeleton;
        let radial = (sk.centre(Joint::IMcp) - sk.centre(Joint::MMcp)).normalize();
        let centroid = |l: Link, tr: &[Isometry3<f64>]| {
            let mut buf = Vec::new();
            h.pose_link(l.index(), tr, &mut buf);
            buf.iter().map(|p| p.coords).sum::<Vec3>() / buf.len() as f64
        };
        for t in [0.0, 1.0] {
            let tr = link_transforms(sk, &pose_at(&plan, &[t; 16], Isometry3::identity()));
            let d = skin_gap(h, Link::TDist, Link::IMid, &tr);
            if t == 0.0 {
                assert!(d > 20.0, "preshape: {d} mm");
            } else {
                assert!(d < 1.0, "closed: {d} mm");
                let side = radial.dot(&(centroid(Link::TDist, &tr) - centroid(Link::IMid, &tr)));
                assert!(side > 5.0, "thumb {side} mm radial of the index");
            }
        }
        // The pad point is a vertex of the support's closed skin, and the thumb closes toward
        // it (in the grasp frame).
        let pad = pad_point(h, &plan).unwrap();
        let tr = link_transforms(sk, &pose_at(&plan, &[1.0; 16], grasp_frame(h).inverse()));
        let mut buf = Vec::new();
        h.pose_link(Link::IMid.index(), &tr, &mut buf);
        assert!(buf.iter().any(|p| (p.coords - pad).norm() < 1e-9));
        let travel = press_travel(h, &plan).unwrap();
        assert!(travel.norm() > 20.0, "opens {} mm", travel.norm());
        let press = travel.normalize();
        let thumb0 = {
            let tr = link_transforms(sk, &pose_at(&plan, &[0.0; 16], grasp_frame(h).inverse()));
            centroid(Link::TDist, &tr)
        };
        let to_pad = (pad - thumb0).normalize();
        assert!(press.dot(&to_pad) > 0.8, "{press} vs {to_pad}");
    }

    /// A support placement puts the pad point on the part's surface on the line through the
    /// centre of mass along the closing direction: for the bottle seen from its side, with the
    /// thumb closing along the grasp frame's x, on its cylindrical wall, 30 mm from its axis.
    #[test]
    fn support_placement_rests_the_part_on_the_support() {
        let part = bottle();
        let pad = Vec3::new(-20.0, 40.0, 30.0);
        let a = support_placement(part, &Vec3::x(), 0.7, &pad, &Vec3::x()).unwrap();
        let at = a * Point::from(pad);
        let com = part.centre_of_mass;
        let off = at - com;
        let press = a.rotation * Vec3::x();
        // On the far side of the centre of mass along the closing direction, on the line.
        assert!((off - press * off.dot(&press)).norm() < 1e-6, "{off}");
        assert!(off.dot(&press) > 0.0);
        let r = off.x.hypot(off.y);
        assert!((r - 30.0).abs() < 1.0, "{r} mm from the axis");
        assert!(part.distance(&at).abs() < 0.1, "{}", part.distance(&at));
    }

    /// Seen from the side of the bottle (a solid of revolution about z), the chord through its
    /// centre of mass is centred on the axis: the pad point lands on the centre of mass, and
    /// the grasp frame looks along the search direction.
    #[test]
    fn pad_placement_puts_the_pad_point_mid_part() {
        let part = bottle();
        let pad = Vec3::new(14.0, 50.0, 40.0);
        for (dir, roll) in [(Vec3::x(), 0.3), (Vec3::new(-1.0, 1.0, 0.0), 2.0)] {
            let a = pad_placement(part, &dir, roll, &pad).unwrap();
            let at = a * Point::from(pad);
            assert!(
                (at - part.centre_of_mass).norm() < 0.5,
                "{at} vs {}",
                part.centre_of_mass
            );
            let z = a.rotation * Vec3::z();
            assert!((z + dir.normalize()).norm() < 1e-9, "{z}");
        }
    }

    #[test]
    fn grasp_frame_faces_palmar_from_the_palm() {
        let h = hand();
        let g = grasp_frame(h);
        let z = g.rotation * Vec3::z();
        // The palm skin lies behind the frame's origin, none of it in front by more than 1 mm.
        let palm: Vec<&Point> = h
            .mesh
            .vertices
            .iter()
            .zip(&h.links)
            .filter(|(_, &l)| l == Link::Palm.index())
            .map(|(p, _)| p)
            .collect();
        let near: Vec<f64> = palm
            .iter()
            .filter(|p| {
                let r = **p - Point::from(g.translation.vector);
                (r - z * z.dot(&r)).norm() < 10.0
            })
            .map(|p| z.dot(&(**p - Point::from(g.translation.vector))))
            .collect();
        assert!(!near.is_empty());
        assert!(near.iter().all(|&d| d < 1.0), "{near:?}");
        assert!(near.iter().any(|&d| d > -3.0));
    }

    #[test]
    fn power_grasp_of_bottle_touches_without_passing_through() {
        let h = hand();
        let part = bottle();
        let root = root_for(h, &Isometry3::identity(), &side_approach());
        let opts = AutograspOptions::default();
        let g = autograsp(h, part, &grasp_plan(GraspType::Power), root, &opts).unwrap();
        let mut pts = Vec::new();
        h.pose_vertices(&g.pose, &mut pts);
        let c = contacts(part, &pts, &h.links, &vertex_areas(&h.mesh), &opts.contact);
        // The palm is placed by the approach, not closed: allow half a millimetre beyond the
        // closing bound, and beyond the plan's give where the approach presses soft tissue in.
        let plan = grasp_plan(GraspType::Power);
        for l in Link::ALL {
            let bound = opts.max_depth_mm.max(plan.give(l.index())) + 0.5;
            let d = c.link_depth_mm[l.index()];
            assert!(d <= bound, "{}: {d} mm deep", l.name());
        }
        // Every finger's distal link wraps onto the bottle, and touched joints are not reported.
        let touching: Vec<&str> = Link::ALL
            .iter()
            .filter(|l| c.touches(l.index()))
            .map(|l| l.name())
            .collect();
        assert!(touching.len() >= 5, "{touching:?}");
        for j in &g.untouched {
            let l = Joint::from_name(j).unwrap().child_link();
            assert!(!c.touches(l.index()), "{j} reported untouched but touches");
        }
    }

    /// The power approach brings the palm onto the bottle by pressing the thenar in, within
    /// the plan's give; a plan whose thenar does not give way is stopped by it with the palm
    /// still off the bottle.
    #[test]
    fn the_thenar_gives_way_so_that_the_palm_meets_the_part() {
        let h = hand();
        let part = bottle();
        let opts = AutograspOptions::default();
        // The power grasp of scenes/bottle.toml.
        let approach = crate::grasp::scene::pose_from(
            crate::grasp::parts::BOTTLE_SIDE_APPROACH.0,
            crate::grasp::parts::BOTTLE_SIDE_APPROACH.1,
        );
        let root = root_for(h, &Isometry3::identity(), &approach);
        let at = |plan: &GraspPlan| {
            let (r, s) = approach_to_contact(h, part, plan, root, &opts);
            let tr = link_transforms(h.skeleton(), &pose_at(plan, &[0.0; 16], r));
            let mut buf = Vec::new();
            let mut depth = |l: Link| {
                h.pose_link(l.index(), &tr, &mut buf);
                buf.iter()
                    .map(|p| match part.probe(p, 20.0) {
                        crate::grasp::contact::Probe::Hit(d, _, _) => -d,
                        crate::grasp::contact::Probe::Deep => 20.0,
                        crate::grasp::contact::Probe::Far => -20.0,
                    })
                    .fold(f64::MIN, f64::max)
            };
            (s, depth(Link::Palm), depth(Link::TMeta))
        };
        let plan = grasp_plan(GraspType::Power);
        assert_eq!(plan.give(Link::TMeta.index()), THENAR_GIVE_MM);
        let (travel, palm, thenar) = at(&plan);
        assert!(palm >= -opts.contact.tolerance_mm, "palm {palm} mm deep");
        assert!(thenar <= THENAR_GIVE_MM + 1e-9, "{thenar}");
        let stiff = GraspPlan {
            give_mm: Vec::new(),
            ..plan
        };
        let (short, palm_off, thenar_stiff) = at(&stiff);
        assert!(palm_off < -opts.contact.tolerance_mm, "{palm_off}");
        assert!(thenar_stiff <= opts.max_depth_mm + 1e-9, "{thenar_stiff}");
        assert!(short < travel, "{short} {travel}");
    }

    /// The closing's fine broad phase skips only skin that can change nothing: with a touch
    /// grid that lets every point through (a 100 mm band), the power grasp's closings of the
    /// bottle from two approaches, coarse and fine, and their squeezes are the same to the bit,
    /// while the fine grid puts most of the closed hand's skin outside.
    #[test]
    fn skipping_skin_beyond_the_tolerance_changes_no_closing() {
        use crate::grasp::broad::{NearGrid, Zone};
        let h = hand();
        let part = bottle();
        let mut open = PartShape::new(Part::Bottle.mesh().unwrap()).unwrap().0;
        open.touch_grid = NearGrid::new(&part.mesh, 100.0, part.closed);
        // The bottle grasp of synth's grasp trials, and the hand further round the bottle.
        let approaches = [
            crate::grasp::scene::pose_from(
                crate::grasp::parts::BOTTLE_SIDE_APPROACH.0,
                crate::grasp::parts::BOTTLE_SIDE_APPROACH.1,
            ),
            side_approach(),
        ];
        let plan = grasp_plan(GraspType::Power);
        let coarse = AutograspOptions {
            step: 0.1,
            min_step: 0.05,
            max_depth_mm: 2.0,
            stride: 4,
            ..AutograspOptions::default()
        };
        for approach in approaches {
            for opts in [AutograspOptions::default(), coarse] {
                let root = root_for(h, &Isometry3::identity(), &approach);
                let fast = autograsp(h, part, &plan, root, &opts).unwrap();
                let all = autograsp(h, &open, &plan, root, &opts).unwrap();
                assert_eq!(fast, all);
                assert_eq!(
                    squeeze(h, part, &plan, &fast, &opts),
                    squeeze(h, &open, &plan, &all, &opts)
                );
                let mut pts = Vec::new();
                h.pose_vertices(&fast.pose, &mut pts);
                let outside = pts
                    .iter()
                    .filter(|p| part.touch_grid.zone(p) == Zone::Outside)
                    .count();
                assert!(outside * 2 > pts.len(), "{outside} of {}", pts.len());
            }
        }
    }

    #[test]
    fn hand_inside_the_part_is_an_error() {
        let h = hand();
        let inside = crate::grasp::scene::pose_from([0.0, 0.0, 90.0], [-90.0, -90.0, 0.0]);
        let root = root_for(h, &Isometry3::identity(), &inside);
        let e = autograsp(
            h,
            bottle(),
            &grasp_plan(GraspType::Power),
            root,
            &AutograspOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("starts inside the part"), "{e}");
    }

    /// The template's power grasp of the bottle from the side: with the carried phalanges
    /// allowed to sink to 2 mm, the squeeze presses the fingers' middle phalanges deeper than
    /// with every link held to the squeeze's 1.5 mm, and no finger link goes deeper than 2 mm.
    #[test]
    fn a_wrapping_squeeze_presses_the_middle_phalanges_too() {
        let h = hand();
        let plan = grasp_plan(GraspType::Power);
        let root = root_for(h, &Isometry3::identity(), &side_approach());
        let held = AutograspOptions {
            wrap_carried_mm: SQUEEZE_MM,
            ..AutograspOptions::default()
        };
        let carried = AutograspOptions::default();
        let g = autograsp(h, bottle(), &plan, root, &carried).unwrap();
        let depth = |opts: &AutograspOptions| squeeze(h, bottle(), &plan, &g, opts).2.depth_mm;
        let (before, after) = (depth(&held), depth(&carried));
        let mids = ["I_MID", "M_MID", "R_MID", "L_MID"];
        let sum = |d: &std::collections::BTreeMap<String, f64>| -> f64 {
            mids.iter().map(|l| d.get(*l).copied().unwrap_or(0.0)).sum()
        };
        assert!(sum(&after) > sum(&before) + 0.5, "{before:?}\n{after:?}");
        for f in [Finger::Index, Finger::Middle, Finger::Ring, Finger::Little] {
            for l in digit_links(f) {
                let d = after.get(l.name()).copied().unwrap_or(0.0);
                assert!(d <= WRAP_CARRIED_SQUEEZE_MM + 1e-9, "{}: {d}", l.name());
            }
        }
    }

    #[test]
    fn far_approach_reports_every_active_joint_untouched() {
        let h = hand();
        let far = crate::grasp::scene::pose_from([0.0, -400.0, 90.0], [-90.0, -90.0, 0.0]);
        let root = root_for(h, &Isometry3::identity(), &far);
        let plan = grasp_plan(GraspType::Pinch);
        let g = autograsp(h, bottle(), &plan, root, &AutograspOptions::default()).unwrap();
        let active = plan.active.iter().filter(|&&a| a).count();
        assert_eq!(g.untouched.len(), active);
        // Every active joint closes fully, unless its digit was stopped by another finger:
        // the pinch closes the thumb's pad onto the index's, so they meet in the air.
        let stopped: Vec<Finger> = g
            .collisions
            .iter()
            .filter_map(|c| Link::from_name(&c.link)?.joint()?.finger())
            .collect();
        for j in Joint::ALL {
            let free = j.finger().is_none_or(|f| !stopped.contains(&f));
            if plan.active[j.index()] && free {
                assert_eq!(g.t[j.index()], 1.0, "{}: {:?}", j.name(), g.collisions);
            }
        }
        assert!(stopped
            .iter()
            .all(|&f| f == Finger::Thumb || f == Finger::Index));
    }
}
