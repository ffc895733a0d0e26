//! Simulated grasp motion trials with truth (subject-format spec, section 5): the true hand
//! reaches for a shipped part, closes on it in a power grasp, holds it, lifts it and sets it
//! down, and lets go, captured with the skin markers of the static trial, the palm and forearm
//! markers and markers on the part, under the capture's error model; the truth is every joint
//! centre in the lab frame per frame, and the part's pose.
//!
//! Phases, as fractions of the trial: reach 0-0.22 (hand open, moving to the part), close
//! 0.22-0.40, hold 0.40-0.50, lift 0.50-0.80 (up 80 mm by 0.62, held, set down by 0.78; the part
//! moves with the hand), release 0.80-1 (the digits open by 0.90, the hand withdraws from 0.86).
//!
//! The closure is found, not scripted: each digit flexes in stages (a finger: the MCP with the
//! PIP and DIP following, then the PIP with the DIP coupled at two thirds of it, then the DIP
//! alone; the thumb: the CMC opposing with the MCP and IP following, then the MCP and IP) until
//! one of its moving links is pressed 1 mm into the part: the true skin of the link (its
//! vertices by dominant weight, posed by linear blend skinning) against the part's exact signed
//! distance function. The palm comes in until its skin (thenar and hypothenar included) is
//! pressed as far. So the true hand touches the part with its soft tissue pressed about a
//! millimetre (a rigid skin stands for it) and reaches no deeper; the true skin's contacts and
//! the fingertips are added to the truth by [`super::true_contacts`].

use super::capture::{MarkerDef, StaDriver};
use super::ErrorModel;
use crate::anatomy::{Finger, Joint, Link, Side};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::grasp::hand::{PosableHand, SkinnedHand};
use crate::grasp::parts::Part;
use crate::grasp::scene::{parse_scene, Scene};
use crate::mocap::trajectories::Trajectories;
use crate::rng::Rng;
use crate::skeleton::forward_kinematics::{link_transforms, posed_skeleton};
use crate::skeleton::{Pose, Skeleton};
use nalgebra::{Isometry3, Matrix3, Rotation3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// Default length of a grasp trial, s.
pub const DEFAULT_MOTION_S: f64 = 4.0;
/// Allowed lengths of a grasp trial, s.
pub const MOTION_S_RANGE: (f64, f64) = (1.0, 60.0);

/// A grasp the simulator can perform: a shipped scene (embedded, so that the simulator needs no
/// files) and its part's exact signed distance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GraspTask {
    /// The motion's name (`[motions]` key, file stem).
    pub name: &'static str,
    /// The shipped scene file's name (`scenes/NAME`).
    pub scene_file: &'static str,
    /// Its text.
    pub scene_text: &'static str,
    /// Its part.
    pub part: Part,
    /// Where the simulated person puts the right hand's grasp frame in the part's frame:
    /// translation (mm) and rotation (degrees, as a scene's `approach`). The person's own, not
    /// the scene's, which may leave the approach to the placement search.
    pub approach: ([f64; 3], [f64; 3]),
}

/// The grasp trials `synth` writes.
pub const GRASP_TASKS: [GraspTask; 1] = [GraspTask {
    name: "grasp_bottle",
    scene_file: "bottle.toml",
    scene_text: include_str!("../../scenes/bottle.toml"),
    part: Part::Bottle,
    approach: crate::grasp::parts::BOTTLE_SIDE_APPROACH,
}];

/// Phase boundaries as fractions of the trial: (name, start, end).
pub const PHASES: [(&str, f64, f64); 5] = [
    ("reach", 0.0, 0.22),
    ("close", 0.22, 0.40),
    ("hold", 0.40, 0.50),
    ("lift", 0.50, 0.80),
    ("release", 0.80, 1.0),
];

/// How high the part is lifted, mm.
const LIFT_MM: f64 = 80.0;
/// A link's skin (and the palm's) stops closing when pressed this far into the part, mm
/// (negative: inside): the soft tissue of a holding hand gives about a millimetre, as the grasp
/// stage's squeeze assumes, and a rigid skin pressed that far stands for it.
const STOP_MM: f64 = -1.0;

/// The errors of a grasp trial beyond those of the calibration trials' model: occlusion grows as
/// the hand closes (the digits hide each other and the part hides the palmar side), and a few
/// labels are swapped where closed digits bring markers together.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GraspErrors {
    /// Fraction of frames a marker is hidden for with the hand open.
    pub gap_open: f64,
    /// The same for a digit's marker with the hand closed on the part (the part markers get half
    /// the increase; palm and forearm markers keep `gap_open`).
    pub gap_closed: f64,
    /// Number of label swaps (pairs of neighbouring digits' markers exchanged for 3-12 frames).
    pub swaps: usize,
}

impl GraspErrors {
    /// From the capture's error model: the calibration trials' gap fraction with the hand open,
    /// six times it (at most 30 %) closed, and two swaps when the model has any error at all.
    /// An assumption of the simulator, after the common experience that grasps lose markers far
    /// more than free motions, not a measured distribution.
    pub fn from_model(err: &ErrorModel) -> GraspErrors {
        GraspErrors {
            gap_open: err.gap_fraction,
            gap_closed: (6.0 * err.gap_fraction).min(0.3),
            swaps: if err.noise_mm > 0.0 || err.gap_fraction > 0.0 {
                2
            } else {
                0
            },
        }
    }
}

/// One joint's truth over the trial.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointTrack {
    /// The true centre per frame, mm, lab frame.
    pub centre: Vec<[f64; 3]>,
    /// The joint's angles per frame relative to the subject's reference posture, degrees
    /// (`[flexion, abduction, axial]`, the skeleton's conventions).
    pub angles_deg: Vec<[f64; 3]>,
}

/// The part's true pose over the trial: `x_lab = rotation · x_part + position`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartTrack {
    /// The shipped scene the part and its markers come from (`scenes/NAME`).
    pub scene: String,
    /// Origin of the part's frame per frame, mm, lab frame.
    pub position: Vec<[f64; 3]>,
    /// Rotation per frame, 3x3 rows.
    pub rotation: Vec<[[f64; 3]; 3]>,
    /// The part markers in the part's frame, mm (the scene's `[part.markers]`).
    pub markers: BTreeMap<String, [f64; 3]>,
}

/// A phase of the motion: frames `first..=last`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Phase {
    /// reach, close, hold, lift or release.
    pub name: String,
    /// First frame.
    pub first: usize,
    /// Last frame.
    pub last: usize,
}

/// A swap of two labels over frames `first..=last`: the file's track of `markers[0]` holds the
/// second marker's positions there, and the other way round.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LabelSwap {
    /// The two labels.
    pub markers: [String; 2],
    /// First frame.
    pub first: usize,
    /// Last frame.
    pub last: usize,
}

/// `truth_motion/NAME.json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionTruth {
    /// Always "mm".
    pub units: String,
    /// Always "lab": the lab frame of the trial (that of the static trial).
    pub frame: String,
    /// Frame rate, Hz.
    pub rate: f64,
    /// Number of frames.
    pub frames: usize,
    /// Every joint of the link model, by name.
    pub joints: BTreeMap<String, JointTrack>,
    /// The part's pose.
    pub part: PartTrack,
    /// The motion's phases.
    pub phases: Vec<Phase>,
    /// The closed grasp's angles relative to the reference posture, degrees, by joint.
    pub grasp_deg: BTreeMap<String, [f64; 3]>,
    /// Per link of the digits: the smallest signed distance of its true skin from the part in
    /// the held grasp, mm (negative inside; a link that closed on the part is pressed about
    /// 1 mm in).
    pub grasp_clearance_mm: BTreeMap<String, f64>,
    /// Which link each marker rides (the part markers: `PART`).
    pub marker_links: BTreeMap<String, String>,
    /// Label swaps written into the trial.
    pub label_swaps: Vec<LabelSwap>,
    /// Per digit letter (`T`, `I`, `M`, `R`, `L`): the distal link's end per frame, mm, lab
    /// frame, defined as the model defines it ([`super::true_contacts`]). Optional on input.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub tips: BTreeMap<String, Vec<[f64; 3]>>,
    /// The true skin's contacts with the part, the records of `motion.json` (per frame, one per
    /// link in contact, [`super::true_contacts`]); `None` when not computed.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub contacts: Option<Vec<crate::track::ContactRecord>>,
}

/// A simulated grasp trial in memory.
#[derive(Clone, Debug)]
pub struct GraspTrial {
    /// The motion's name.
    pub name: String,
    /// The captured markers (lab frame, mm), labels in a fixed order (see `simulate_grasp`).
    pub trajectories: Trajectories,
    /// The truth.
    pub truth: MotionTruth,
    /// The skin markers' definitions (for tests).
    pub markers: Vec<MarkerDef>,
    /// The optional markers' definitions ([`GraspInputs::extra`]).
    pub extra: Vec<MarkerDef>,
    /// The forearm's rigid motion per frame (the pose's root).
    pub root: Vec<Isometry3<f64>>,
    /// The part's true pose per frame (part frame -> lab).
    pub part: Vec<Isometry3<f64>>,
    /// Joint angles per frame relative to the reference posture, degrees, [`Joint::ALL`] order.
    pub angles: Vec<Vec<[f64; 3]>>,
    /// Visibility per marker (trajectory order) per frame before swaps (for tests).
    pub visible: Vec<Vec<bool>>,
}

/// The read, checked scene of a task.
pub fn task_scene(task: &GraspTask) -> Result<Scene> {
    parse_scene(task.scene_text, Path::new(task.scene_file))
}

/// Which link a landmark marker rides (spec section 5): a joint's dorsal marker the link
/// proximal to the joint, a nail or a fingertip marker (an extension of the spec) the distal
/// link, the thumb metacarpal's two markers `T_META`, the MCP laterals and palm markers `PALM`,
/// the styloids `ARM`.
pub fn landmark_link(name: &str) -> Option<Link> {
    if let Some(j) = Joint::from_name(name) {
        return Some(j.parent_link());
    }
    Some(match name {
        "T_NAIL" => Link::TDist,
        "I_NAIL" => Link::IDist,
        "M_NAIL" => Link::MDist,
        "R_NAIL" => Link::RDist,
        "L_NAIL" => Link::LDist,
        "T_MC_1" | "T_MC_2" => Link::TMeta,
        "I_MCP_LAT" | "L_MCP_LAT" | "PALM_1" | "PALM_2" | "PALM_3" | "PALM_4" => Link::Palm,
        "WRIST_RAD" | "WRIST_ULN" | "ARM_1" | "ARM_2" | "ARM_3" => Link::Arm,
        _ => return Finger::from_tip_marker(name).map(|f| f.links()[2]),
    })
}

/// The joint whose flexion slides the skin under a landmark marker, and the slide's scale
/// relative to the skin range: the dorsal skin over a knuckle is stretched over it as the joint
/// flexes (the most), over the thumb metacarpal by the MCP, at a nail or a fingertip by the DIP
/// (little), at the MCP laterals by their MCP, at the styloids by the wrist.
fn landmark_driver(name: &str) -> (Joint, f64) {
    if let Some(j) = Joint::from_name(name) {
        return (j, 2.0);
    }
    let j = match name {
        "T_NAIL" => Joint::TIp,
        "I_NAIL" => Joint::IDip,
        "M_NAIL" => Joint::MDip,
        "R_NAIL" => Joint::RDip,
        "L_NAIL" => Joint::LDip,
        "T_MC_1" | "T_MC_2" => Joint::TMcp,
        "I_MCP_LAT" => Joint::IMcp,
        "L_MCP_LAT" => Joint::LMcp,
        _ => match Finger::from_tip_marker(name) {
            Some(f) => f.joints()[2],
            None => Joint::Wrist,
        },
    };
    // The nail is stiff, and the pulp at the fingertip's end is held by its fibrous septa.
    let stiff = name.ends_with("_NAIL") || name.ends_with("_TIP");
    (j, if stiff { 0.5 } else { 1.0 })
}

/// The definition of a landmark's skin marker for a grasp trial: at `position` (its placed
/// centre in the reference posture), on its link, sliding by `range` mm (times the driver's
/// scale) over 90° of its driving joint's flexion, along the skin (tangent to `normal`) in a
/// random direction. An assumption of the simulator, as the calibration trials' skin slide.
pub fn landmark_marker(
    name: &str,
    position: Point,
    normal: &Vec3,
    range: (f64, f64),
    rng: &mut Rng,
) -> Option<MarkerDef> {
    let link = landmark_link(name)?;
    let (joint, scale) = landmark_driver(name);
    let v = rng.unit_vector();
    let dir = (v - normal * v.dot(normal))
        .try_normalize(1e-9)
        .unwrap_or_else(Vec3::x);
    let size = rng.range(range.0, range.1) * scale;
    Some(MarkerDef {
        name: name.to_string(),
        link,
        position,
        sta: vec![StaDriver {
            joint,
            dof: 0,
            range_deg: 90.0,
            slide: dir * size,
            spin: Vec3::zeros(),
        }],
        sta_centre: position,
    })
}

fn smooth(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// `smooth` of `u` over `[a, b]`.
fn ramp(u: f64, a: f64, b: f64) -> f64 {
    smooth((u - a) / (b - a))
}

/// How closed the hand is at fraction `u` of the trial, 0-1.
pub fn closure(u: f64) -> f64 {
    ramp(u, 0.22, 0.40) * (1.0 - ramp(u, 0.80, 0.90))
}

/// How far the part is lifted at fraction `u`, 0-1.
fn lifted(u: f64) -> f64 {
    ramp(u, 0.50, 0.62) * (1.0 - ramp(u, 0.68, 0.78))
}

/// Put digit `fi` of `angles` at `s` along its closing line: its joints at `s` times their
/// `closed` angles (0 the reference posture, 1 closed), degrees.
fn close_digit_to(angles: &mut [[f64; 3]; 16], closed: &[[f64; 3]; 16], fi: Finger, s: f64) {
    for j in fi.joints().map(|j| j.index()) {
        angles[j] = closed[j].map(|v| v * s);
    }
}

/// The true skin of the digits and the part, for the closing.
struct Closer<'a> {
    sk: &'a Skeleton,
    hand: &'a SkinnedHand,
    root: Isometry3<f64>,
    part_inv: Isometry3<f64>,
    part: Part,
}

impl Closer<'_> {
    /// The smallest signed distance from the part of the true skin of `links` (each link's
    /// vertices by their dominant weight, posed by linear blend skinning) at `angles` (degrees).
    fn clearance(&self, angles: &[[f64; 3]; 16], links: &[Link]) -> f64 {
        let pose = Pose::from_deg(angles, self.root);
        let tf = link_transforms(self.sk, &pose);
        let mut posed = Vec::new();
        links
            .iter()
            .map(|&l| {
                self.hand.pose_link(l.index(), &tf, &mut posed);
                posed
                    .iter()
                    .map(|p| self.part.sdf(&(self.part_inv * p)))
                    .fold(f64::INFINITY, f64::min)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// Step `angles` by `step` (which returns false at the stage's limit) until one of `links`
    /// is pressed [`STOP_MM`] into the part; the last posture before that is kept. Returns
    /// whether a link touched.
    fn flex_until(
        &self,
        angles: &mut [[f64; 3]; 16],
        links: &[Link],
        mut step: impl FnMut(&mut [[f64; 3]; 16], usize) -> bool,
    ) -> bool {
        if self.clearance(angles, links) <= STOP_MM {
            return true;
        }
        for k in 1..2000 {
            let mut next = *angles;
            if !step(&mut next, k) {
                return false;
            }
            if self.clearance(&next, links) <= STOP_MM {
                return true;
            }
            *angles = next;
        }
        false
    }

    /// The fingers of the power grasp closed from `a` (angles relative to the reference
    /// posture, degrees; the thumb's are kept).
    fn close_fingers(&self, mut a: [[f64; 3]; 16]) -> [[f64; 3]; 16] {
        for f in &Finger::ALL[1..] {
            let [mcp, pip, dip] = f.joints().map(|j| j.index());
            let [prox, mid, dist] = f.links();
            // The DIP follows the PIP at two thirds of its flexion, less where the distal link
            // would reach into the part (down to 10° of extension); `false` if even that does.
            let fit_dip = |x: &mut [[f64; 3]; 16]| -> bool {
                let mut d = x[pip][0] * 2.0 / 3.0;
                loop {
                    x[dip][0] = d;
                    if self.clearance(x, &[dist]) > STOP_MM {
                        return true;
                    }
                    d -= 2.0;
                    if d < -10.0 {
                        return false;
                    }
                }
            };
            // The PIP follows the MCP at half its flexion, less where the middle link (or the
            // distal one, fitted as above) would reach into the part, down to 10° of extension.
            let fit_pip = |x: &mut [[f64; 3]; 16]| -> bool {
                let mut p = x[mcp][0] / 2.0;
                loop {
                    x[pip][0] = p;
                    if fit_dip(x) && self.clearance(x, &[mid]) > STOP_MM {
                        return true;
                    }
                    p -= 2.0;
                    if p < -10.0 {
                        return false;
                    }
                }
            };
            // The MCP, 0.5° steps, until the proximal link touches: the phalanges distal to it
            // wrap the part without stopping it, as in a cylindrical grasp.
            self.flex_until(&mut a, &[prox], |x, k| {
                x[mcp][0] = 0.5 * k as f64;
                x[mcp][0] <= 90.0 && fit_pip(x)
            });
            // Then the PIP until the middle link touches, then the DIP alone.
            let p0 = a[pip][0];
            self.flex_until(&mut a, &[mid], |x, k| {
                x[pip][0] = p0 + 0.5 * k as f64;
                x[pip][0] <= 100.0 && fit_dip(x)
            });
            let d0 = a[dip][0];
            self.flex_until(&mut a, &[dist], |x, k| {
                x[dip][0] = d0 + 0.5 * k as f64;
                x[dip][0] <= 80.0
            });
        }
        a
    }

    /// The thumb of the power grasp, the fingers at their reference posture: angles relative
    /// to it, degrees.
    fn close_thumb(&self) -> [[f64; 3]; 16] {
        let mut a = [[0.0; 3]; 16];
        // The thumb: of the postures of a grid (CMC flexion -20..40°, palmar abduction
        // -20..50°, MCP 0..50° with the IP at 1.2 times it), those clear of the part whose
        // distal link touches it, the one nearest the opposition (CMC 20°, 40°); if none touches,
        // the clear one whose distal link comes nearest.
        let [cmc, mcp, ip] = Finger::Thumb.joints().map(|j| j.index());
        let [meta, prox, dist] = Finger::Thumb.links();
        let mut best: Option<(bool, f64, [[f64; 3]; 16])> = None;
        for fl in (0..=12).map(|k| -20.0 + 5.0 * k as f64) {
            for ab in (0..=14).map(|k| -20.0 + 5.0 * k as f64) {
                for m in (0..=10).map(|k| 5.0 * k as f64) {
                    let mut x = a;
                    x[cmc] = [fl, ab, 0.0];
                    x[mcp][0] = m;
                    x[ip][0] = (1.2 * m).min(70.0);
                    let (cp, cd) = (
                        self.clearance(&x, &[meta, prox]),
                        self.clearance(&x, &[dist]),
                    );
                    if cp < STOP_MM || cd < STOP_MM {
                        continue;
                    }
                    let touches = cd <= STOP_MM + 1.5;
                    let score = if touches {
                        (fl - 20.0).hypot(ab - 40.0) + 0.1 * m
                    } else {
                        cd
                    };
                    let better = match &best {
                        None => true,
                        Some((t, s, _)) => (touches && !t) || (touches == *t && score < *s),
                    };
                    if better {
                        best = Some((touches, score, x));
                    }
                }
            }
        }
        if let Some((_, _, x)) = best {
            a = x;
        }
        a
    }
}

/// The grasp frame of a hand (as [`crate::grasp::plan::grasp_frame`], from its skeleton and skin
/// alone: the true skin carries no link labels, so every vertex near the palm's centre line
/// counts).
fn grasp_frame(sk: &Skeleton, skin: &TriMesh) -> Isometry3<f64> {
    crate::grasp::plan::palm_grasp_frame(sk, skin.vertices.iter())
}

/// The task's approach for `side`: given for a right hand; a left hand takes its mirror image
/// through the part's x = 0 plane (the shipped grasp parts are symmetric about it), with the
/// grasp frame's x flipped to keep it right-handed.
fn approach_for(task: &GraspTask, side: Side) -> Isometry3<f64> {
    let a = crate::grasp::scene::pose_from(task.approach.0, task.approach.1);
    if side == Side::Right {
        return a;
    }
    let s = Matrix3::from_diagonal(&Vec3::new(-1.0, 1.0, 1.0));
    let r = s * a.rotation.to_rotation_matrix().into_inner() * s;
    let t = s * a.translation.vector;
    Isometry3::from_parts(
        Translation3::from(t),
        UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(r)),
    )
}

/// Inputs of [`simulate_grasp`] that come from the simulated subject.
pub struct GraspInputs<'a> {
    /// The true skeleton in the reference posture, lab frame.
    pub skeleton: &'a Skeleton,
    /// The true skin in the reference posture, lab frame, bound to `skeleton` for posing
    /// ([`super::true_contacts::true_skinned_hand`]).
    pub hand: &'a SkinnedHand,
    /// The skin, palm and forearm markers, placed as for the static trial.
    pub markers: Vec<MarkerDef>,
    /// Optional skin markers (the fingertip markers, an extension of the spec), simulated from
    /// draws of their own so that the other markers' tracks are the same with or without them.
    pub extra: Vec<MarkerDef>,
}

/// Simulate the grasp `task` with the true hand of `inp`: `duration_s` seconds at `rate` Hz,
/// noise `err.noise_mm` on every marker, the markers' skin slide, gaps and swaps by `gerr`, every
/// draw from `rng`. Labels: the skin markers in `inp.markers` order, the optional ones in
/// `inp.extra` order, then `PART_1`..`PART_n`.
pub fn simulate_grasp(
    task: &GraspTask,
    inp: GraspInputs,
    duration_s: f64,
    rate: f64,
    err: &ErrorModel,
    gerr: &GraspErrors,
    rng: &Rng,
) -> Result<GraspTrial> {
    if !(duration_s.is_finite() && (MOTION_S_RANGE.0..=MOTION_S_RANGE.1).contains(&duration_s)) {
        return Err(Error::invalid(format!(
            "motion trial length {duration_s} s is outside {}-{} s",
            MOTION_S_RANGE.0, MOTION_S_RANGE.1
        )));
    }
    let scene = task_scene(task)?;
    if scene.part_markers.is_empty() {
        return Err(Error::input(
            &scene.path,
            "part.markers: the simulated grasp needs markers on the part",
        ));
    }
    let sk = inp.skeleton;
    let part_pose = scene.part_pose;
    let approach = approach_for(task, sk.side);
    let g = grasp_frame(sk, inp.hand.rest_mesh());
    // The hand's rigid motion that puts its grasp frame at the scene's approach.
    let at_approach = part_pose * approach * g.inverse();
    // Bring the palm in along its normal, from 15 mm back, until its skin is pressed as far
    // into the part as a closing link's: first the palm's skin (every vertex the palm and the
    // thumb's metacarpal carry, by their dominant weights), the thumb at its reference
    // posture; then, the thumb closed there, again with the whole thumb, so that the palm, the
    // thenar or the thumb meets the part. The fingers close last.
    let palmar = at_approach.rotation * g.rotation * Vec3::z();
    let inv = part_pose.inverse();
    let palm_and_thumb = [Link::Palm, Link::TMeta, Link::TProx, Link::TDist];
    let place = |angles: &[[f64; 3]; 16], links: &[Link]| -> Result<f64> {
        let pose = Pose::from_deg(angles, at_approach);
        let tf = link_transforms(sk, &pose);
        let mut skin = Vec::new();
        let mut posed = Vec::new();
        for l in links {
            inp.hand.pose_link(l.index(), &tf, &mut posed);
            skin.extend_from_slice(&posed);
        }
        let min_sdf = |d: f64| {
            skin.iter()
                .map(|v| task.part.sdf(&(inv * (v + palmar * d))))
                .fold(f64::INFINITY, f64::min)
        };
        let mut d = -15.0;
        while min_sdf(d) < STOP_MM {
            d -= 5.0;
            if d < -100.0 {
                return Err(Error::invalid(format!(
                    "{}: the approach puts the hand inside the part",
                    task.name
                )));
            }
        }
        while d < 60.0 && min_sdf(d + 0.5) >= STOP_MM {
            d += 0.5;
        }
        Ok(d)
    };
    let root_at = |d: f64| Translation3::from(palmar * d) * at_approach;
    let closer_at = |d: f64| Closer {
        sk,
        hand: inp.hand,
        root: root_at(d),
        part_inv: inv,
        part: task.part,
    };
    let d0 = place(&[[0.0; 3]; 16], &palm_and_thumb[..2])?;
    let thumb = closer_at(d0).close_thumb();
    let d = place(&thumb, &palm_and_thumb)?;
    let grasp_root = root_at(d);
    let closer = closer_at(d);
    let closed = closer.close_fingers(thumb);
    log::debug!(
        "{}: palm brought {d0:.1} mm in, then {d:.1} mm with the thumb closed",
        task.name
    );
    let digit_links: Vec<Link> = Finger::ALL
        .iter()
        .flat_map(|f| f.links())
        .filter(|l| *l != Link::TMeta)
        .collect();
    let grasp_clearance_mm: BTreeMap<String, f64> = digit_links
        .iter()
        .map(|&l| (l.name().to_string(), closer.clearance(&closed, &[l])))
        .collect();
    log::debug!(
        "{}: palm {d:.1} mm from the approach, clearances {:?}",
        task.name,
        grasp_clearance_mm
    );

    // The hand's path: from 60 mm back off the palm and 50 mm up, turned 20° about the vertical
    // through the wrist, to the grasp; it withdraws 60 mm back and 30 mm up, turned back 10°.
    let wrist = sk.centre(Joint::Wrist);
    let offset = |back: f64, up: f64, deg: f64| {
        let w = grasp_root * wrist;
        let turn = UnitQuaternion::from_axis_angle(&Vec3::z_axis(), deg.to_radians());
        let about = Isometry3::from_parts(Translation3::from(w.coords - turn * w.coords), turn);
        Translation3::from(-palmar * back + Vec3::z() * up) * about * grasp_root
    };
    // Per digit, the point of its closing line (0 reference, 1 closed) from which on the rest
    // of the line is clear of the part at the grasp (5 % steps, then 1 %): a digit closing on
    // the straight line from the reference posture would otherwise cross the part on the way
    // (the thumb above all).
    let ahead: [f64; 5] = Finger::ALL.map(|fi| {
        let links = fi.links();
        let clear = |s: f64| {
            let mut x = closed;
            close_digit_to(&mut x, &closed, fi, s);
            closer.clearance(&x, &links) > STOP_MM
        };
        let Some(k) = (0..20).rev().find(|&k| !clear(k as f64 / 20.0)) else {
            return 0.0;
        };
        let (mut lo, mut hi) = (k as f64 / 20.0, (k + 1) as f64 / 20.0);
        while hi - lo > 0.01 {
            let mid = 0.5 * (lo + hi);
            if clear(mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        hi
    });
    let start = offset(60.0, 50.0, 20.0);
    let end = offset(60.0, 30.0, -10.0);
    let n = (duration_s * rate).round() as usize;
    let mut root = Vec::with_capacity(n);
    let mut part = Vec::with_capacity(n);
    let mut angles = Vec::with_capacity(n);
    for f in 0..n {
        let u = f as f64 / n as f64;
        let lift = Translation3::from(Vec3::z() * LIFT_MM * lifted(u));
        let r = if u < 0.22 {
            start.lerp_slerp(&grasp_root, ramp(u, 0.0, 0.22))
        } else if u < 0.86 {
            lift * grasp_root
        } else {
            grasp_root.lerp_slerp(&end, ramp(u, 0.86, 1.0))
        };
        root.push(r);
        part.push(lift * part_pose);
        let c = closure(u);
        // Each digit moves on the straight line from the reference posture to its closed
        // one, but never through the part: at least as closed as `ahead` asks, so that it
        // shapes round the part while the hand reaches and stays round it until the hand
        // withdraws. The wrist closes with `c` alone.
        let pre = ramp(u, 0.05, 0.22) * (1.0 - ramp(u, 0.86, 1.0));
        let mut a = closed.map(|d| d.map(|x| x * c));
        for (&fi, s_min) in Finger::ALL.iter().zip(ahead) {
            close_digit_to(&mut a, &closed, fi, c.max(s_min * pre));
        }
        angles.push(a.to_vec());
    }

    // The markers, frame by frame.
    let defs = inp.markers;
    let part_markers: Vec<(String, Point)> = {
        let mut v: Vec<(String, Point)> = scene
            .part_markers
            .iter()
            .map(|(k, p)| (k.clone(), *p))
            .collect();
        v.sort_by_key(|(k, _)| k[5..].parse::<u32>().unwrap_or(u32::MAX));
        v
    };
    let extra = inp.extra;
    let mut labels: Vec<String> = defs.iter().chain(&extra).map(|d| d.name.clone()).collect();
    labels.extend(part_markers.iter().map(|(k, _)| k.clone()));
    // Track index of the m-th marker of the main order (skin markers, then the part's).
    let main_track = |m: usize| if m < defs.len() { m } else { m + extra.len() };
    let mut noise = rng.fork("noise");
    let mut extra_noise = rng.fork("noise-optional-markers");
    let mut positions: Vec<Vec<Option<Point>>> = vec![Vec::with_capacity(n); labels.len()];
    let mut joints: BTreeMap<String, JointTrack> = Joint::ALL
        .iter()
        .map(|j| {
            (
                j.name().to_string(),
                JointTrack {
                    centre: Vec::with_capacity(n),
                    angles_deg: Vec::with_capacity(n),
                },
            )
        })
        .collect();
    for f in 0..n {
        let pose = Pose::from_deg(&angles[f], root[f]);
        let tf = link_transforms(sk, &pose);
        let posed = posed_skeleton(sk, &tf);
        for j in Joint::ALL {
            let t = joints.get_mut(j.name()).expect("every joint");
            t.centre.push(posed.centre(j).coords.into());
            t.angles_deg.push(angles[f][j.index()]);
        }
        for (m, d) in defs.iter().enumerate() {
            let p = tf[d.link.index()] * d.displaced(&angles[f]) + noise.gauss3(err.noise_mm);
            positions[m].push(Some(p));
        }
        for (k, (_, p)) in part_markers.iter().enumerate() {
            positions[main_track(defs.len() + k)]
                .push(Some(part[f] * p + noise.gauss3(err.noise_mm)));
        }
        for (k, d) in extra.iter().enumerate() {
            let p = tf[d.link.index()] * d.displaced(&angles[f]) + extra_noise.gauss3(err.noise_mm);
            positions[defs.len() + k].push(Some(p));
        }
    }

    // Gaps: each marker starts a gap of 0.05-0.3 s at a visible frame with the probability that
    // hides its current fraction of frames; a digit's fraction grows with the closure. The first
    // 0.1 s stays visible so that a tracker can start.
    let mut gap_rng = rng.fork("gaps");
    let mut extra_gap_rng = rng.fork("gaps-optional-markers");
    let mut visible = vec![Vec::new(); labels.len()];
    let order = (0..defs.len() + part_markers.len())
        .map(main_track)
        .chain(defs.len()..defs.len() + extra.len());
    for m in order {
        let is_extra = (defs.len()..defs.len() + extra.len()).contains(&m);
        let growth = if m >= defs.len() + extra.len() {
            0.5
        } else if m < defs.len() && matches!(defs[m].link, Link::Palm | Link::Arm) {
            0.0
        } else {
            1.0
        };
        let gap_rng = if is_extra {
            &mut extra_gap_rng
        } else {
            &mut gap_rng
        };
        let mut vis = vec![true; n];
        let mean_len = 0.175 * rate;
        let mut f = (0.1 * rate).ceil() as usize;
        while f < n {
            let frac = gerr.gap_open
                + (gerr.gap_closed - gerr.gap_open) * growth * closure(f as f64 / n as f64);
            if frac > 0.0 && gap_rng.uniform() < frac / mean_len {
                let len = (gap_rng.range(0.05, 0.3) * rate).round().max(1.0) as usize;
                for v in vis.iter_mut().skip(f).take(len) {
                    *v = false;
                }
                f += len;
            } else {
                f += 1;
            }
        }
        visible[m] = vis;
    }
    for (track, vis) in positions.iter_mut().zip(&visible) {
        for (p, v) in track.iter_mut().zip(vis) {
            if !v {
                *p = None;
            }
        }
    }

    // Swaps: the same marker of two neighbouring fingers (closed fingers lie side by side),
    // exchanged for 3-12 frames in the close, hold or lift phases.
    let mut swap_rng = rng.fork("swaps");
    let mut label_swaps = Vec::new();
    let kinds = ["PIP", "DIP", "NAIL"];
    let pairs = [("I", "M"), ("M", "R"), ("R", "L")];
    let index_of = |s: &str| labels.iter().position(|l| l == s);
    let mut tries = 0;
    while label_swaps.len() < gerr.swaps && tries < 100 {
        tries += 1;
        let kind = kinds[swap_rng.below(kinds.len())];
        let (a, b) = pairs[swap_rng.below(pairs.len())];
        let (na, nb) = (format!("{a}_{kind}"), format!("{b}_{kind}"));
        let (Some(ia), Some(ib)) = (index_of(&na), index_of(&nb)) else {
            continue;
        };
        let len = 3 + swap_rng.below(10);
        let lo = (0.25 * n as f64) as usize;
        let hi = ((0.75 * n as f64) as usize).saturating_sub(len);
        if hi <= lo {
            break;
        }
        let first = lo + swap_rng.below(hi - lo);
        let last = first + len - 1;
        let clash = label_swaps.iter().any(|s: &LabelSwap| {
            s.markers.iter().any(|m| *m == na || *m == nb) && first <= s.last && s.first <= last
        });
        if clash {
            continue;
        }
        // The two tracks exchange their samples over the swap's frames.
        let (lo, hi) = (ia.min(ib), ia.max(ib));
        let (head, tail) = positions.split_at_mut(hi);
        head[lo][first..=last].swap_with_slice(&mut tail[0][first..=last]);
        label_swaps.push(LabelSwap {
            markers: [na, nb],
            first,
            last,
        });
    }

    let frame_of = |u: f64| ((u * n as f64).round() as usize).min(n);
    let phases = PHASES
        .iter()
        .map(|&(name, a, b)| Phase {
            name: name.to_string(),
            first: frame_of(a),
            last: frame_of(b).saturating_sub(1),
        })
        .collect();
    let mut marker_links: BTreeMap<String, String> = defs
        .iter()
        .chain(&extra)
        .map(|d| (d.name.clone(), d.link.name().to_string()))
        .collect();
    for (k, _) in &part_markers {
        marker_links.insert(k.clone(), "PART".into());
    }
    let truth = MotionTruth {
        units: "mm".into(),
        frame: "lab".into(),
        rate,
        frames: n,
        joints,
        part: PartTrack {
            scene: format!("scenes/{}", task.scene_file),
            position: part.iter().map(|p| p.translation.vector.into()).collect(),
            rotation: part
                .iter()
                .map(|p| {
                    let m = p.rotation.to_rotation_matrix().into_inner();
                    [0, 1, 2].map(|r| [m[(r, 0)], m[(r, 1)], m[(r, 2)]])
                })
                .collect(),
            markers: part_markers
                .iter()
                .map(|(k, p)| (k.clone(), p.coords.into()))
                .collect(),
        },
        phases,
        grasp_deg: Joint::ALL
            .iter()
            .map(|j| (j.name().to_string(), closed[j.index()]))
            .collect(),
        grasp_clearance_mm,
        marker_links,
        label_swaps,
        tips: BTreeMap::new(),
        contacts: None,
    };
    let trajectories =
        Trajectories::new(rate, labels, positions, format!("trials/{}.c3d", task.name))?;
    Ok(GraspTrial {
        name: task.name.to_string(),
        trajectories,
        truth,
        markers: defs,
        extra,
        root,
        part,
        angles,
        visible,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::absolute_orientation;
    use crate::synth::{simulate, simulate_with, write_subject, Preset, SynthOptions};
    use crate::synth::{SyntheticSubject, FRAME_RATE};
    use std::sync::OnceLock;

    fn opts(seed: u64, preset: Preset) -> SynthOptions {
        SynthOptions {
            duration_s: Some(2.0),
            voxel_mm: 2.0,
            motion_s: Some(3.0),
            ..SynthOptions::new(seed, preset)
        }
    }

    /// No error at all: no noise, no skin slide, no gaps, no swaps.
    fn clean() -> &'static SyntheticSubject {
        static S: OnceLock<SyntheticSubject> = OnceLock::new();
        S.get_or_init(|| simulate(&opts(41, Preset::Clean)).unwrap())
    }

    fn typical() -> &'static SyntheticSubject {
        static S: OnceLock<SyntheticSubject> = OnceLock::new();
        S.get_or_init(|| simulate(&opts(42, Preset::Typical)).unwrap())
    }

    fn p(a: &[f64; 3]) -> Point {
        Point::new(a[0], a[1], a[2])
    }

    fn part_pose(t: &MotionTruth, f: usize) -> Isometry3<f64> {
        let r = t.part.rotation[f];
        let m = Matrix3::from_fn(|i, j| r[i][j]);
        Isometry3::from_parts(
            Translation3::from(p(&t.part.position[f]).coords),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m)),
        )
    }

    /// The truth's centres against closed forms of the joints' rotations: the palm's joints
    /// move rigidly with the forearm (the wrist does not move in the grasp), every bone keeps
    /// its length, and the angle between a finger's proximal and middle bones is the
    /// reference angle turned by the PIP's flexion about the PIP's axis (Rodrigues), whatever
    /// the MCP does.
    #[test]
    fn truth_centres_follow_the_joint_rotations_in_closed_form() {
        let s = clean();
        let m = &s.motions["grasp_bottle"];
        let t = &m.truth;
        assert_eq!((t.rate, t.frames), (FRAME_RATE, 300));
        assert_eq!(t.joints.len(), s.truth.joints.len());
        let reference = |j: Joint| p(&s.truth.joints[j.name()].centre);
        let at = |j: Joint, f: usize| p(&t.joints[j.name()].centre[f]);
        for f in (0..t.frames).step_by(7) {
            let root = m.root[f];
            for j in [
                Joint::Wrist,
                Joint::TCmc,
                Joint::IMcp,
                Joint::MMcp,
                Joint::LMcp,
            ] {
                assert!((root * reference(j) - at(j, f)).norm() < 1e-9, "{j} {f}");
            }
            for fi in &Finger::ALL[1..] {
                let [mcp, pip, dip] = fi.joints();
                for (a, b) in [(mcp, pip), (pip, dip)] {
                    let l0 = (reference(b) - reference(a)).norm();
                    assert!(((at(b, f) - at(a, f)).norm() - l0).abs() < 1e-9);
                }
                let axis = s.truth.joints[pip.name()]
                    .axis
                    .map(|a| Vec3::new(a[0], a[1], a[2]));
                let axis = axis.expect("a PIP has an axis");
                let (u0, v0) = (
                    reference(pip) - reference(mcp),
                    reference(dip) - reference(pip),
                );
                let th = t.joints[pip.name()].angles_deg[f][0].to_radians();
                let v = v0 * th.cos()
                    + axis.cross(&v0) * th.sin()
                    + axis * axis.dot(&v0) * (1.0 - th.cos());
                let (u1, v1) = (at(pip, f) - at(mcp, f), at(dip, f) - at(pip, f));
                let want = u0.normalize().dot(&v.normalize());
                let got = u1.normalize().dot(&v1.normalize());
                assert!(
                    (want - got).abs() < 1e-9,
                    "{pip} frame {f}: {want} vs {got}"
                );
            }
        }
        // The fingers really close: each flexes by more than 45° over its three joints in the
        // hold (from a reference posture that may flex a joint already).
        let hold = &t.phases[2];
        assert_eq!(hold.name, "hold");
        for fi in &Finger::ALL[1..] {
            let a: f64 = fi
                .joints()
                .iter()
                .map(|j| t.joints[j.name()].angles_deg[hold.first][0])
                .sum();
            assert!(a > 45.0, "{fi:?} flexes {a}°");
        }
    }

    /// Without noise or skin slide every marker keeps its place on its link: its distances to
    /// the true centres riding that link stay constant, and the palm's markers move with the
    /// palm's joint centres as one rigid body.
    #[test]
    fn clean_markers_ride_their_links() {
        let s = clean();
        let m = &s.motions["grasp_bottle"];
        let (tr, t) = (&m.trajectories, &m.truth);
        assert!(t.label_swaps.is_empty());
        let at = |j: Joint, f: usize| p(&t.joints[j.name()].centre[f]);
        let palm_joints = [
            Joint::TCmc,
            Joint::IMcp,
            Joint::MMcp,
            Joint::RMcp,
            Joint::LMcp,
        ];
        for (k, label) in tr.labels.iter().enumerate() {
            let link = &t.marker_links[label];
            assert!(
                tr.positions[k].iter().all(Option::is_some),
                "{label} has gaps"
            );
            let Some(link) = Link::from_name(link) else {
                continue;
            };
            // The centres on the link: the joint it turns about and the joints at its far end.
            let mut on: Vec<Joint> = Joint::ALL
                .iter()
                .filter(|j| j.child_link() == link || j.parent_link() == link)
                .copied()
                .collect();
            if link == Link::Arm {
                continue; // only the wrist's centre rides the forearm: see the palm test
            }
            if link == Link::Palm {
                on = palm_joints.to_vec();
            }
            let d0: Vec<f64> = on
                .iter()
                .map(|&j| (tr.get(label, 0).unwrap() - at(j, 0)).norm())
                .collect();
            for f in (0..t.frames).step_by(5) {
                let x = tr.get(label, f).unwrap();
                for (j, d) in on.iter().zip(&d0) {
                    assert!(((x - at(*j, f)).norm() - d).abs() < 1e-6, "{label} {j} {f}");
                }
                if link == Link::Palm {
                    let from: Vec<Point> = palm_joints.iter().map(|&j| at(j, 0)).collect();
                    let to: Vec<Point> = palm_joints.iter().map(|&j| at(j, f)).collect();
                    let reg = absolute_orientation(&from, &to, None, false).unwrap();
                    let moved = reg.apply(&tr.get(label, 0).unwrap());
                    assert!((moved - x).norm() < 1e-6, "{label} frame {f}");
                }
            }
        }
    }

    /// Horn's registration of the scene's part markers onto the captured ones recovers the
    /// part's true pose to the noise's level, through the lift.
    #[test]
    fn part_markers_give_the_part_pose() {
        let s = typical();
        let m = &s.motions["grasp_bottle"];
        let (tr, t) = (&m.trajectories, &m.truth);
        let names: Vec<&String> = t.part.markers.keys().collect();
        assert!(names.len() >= 3);
        let (mut errors, mut n, mut lifted_mm) = (Vec::new(), 0, 0.0f64);
        for f in 0..t.frames {
            let (mut from, mut to) = (Vec::new(), Vec::new());
            for k in &names {
                if let Some(x) = tr.get(k, f) {
                    from.push(p(&t.part.markers[*k]));
                    to.push(x);
                }
            }
            if from.len() < 3 {
                continue;
            }
            n += 1;
            let reg = absolute_orientation(&from, &to, None, false).unwrap();
            let truth = part_pose(t, f);
            lifted_mm = lifted_mm.max(truth.translation.vector.z - t.part.position[0][2]);
            // Over the part's body: its base centre and a point on its side.
            for q in [Point::new(0.0, 0.0, 0.0), Point::new(30.0, 0.0, 100.0)] {
                errors.push((reg.apply(&q) - truth * q).norm());
            }
        }
        assert!(n > t.frames / 2, "{n}");
        // 0.2 mm noise on 3-4 markers some 40 mm apart, read up to 200 mm away from them.
        errors.sort_by(f64::total_cmp);
        let (median, worst) = (errors[errors.len() / 2], errors[errors.len() - 1]);
        assert!(median < 1.0 && worst < 6.0, "{median} {worst}");
        assert!((lifted_mm - LIFT_MM).abs() < 1e-6, "{lifted_mm}");
    }

    /// In the hold the true skin touches the part with every phalanx of at least three fingers
    /// and reaches no deeper into it than the closing presses it (1 mm, and the bottle's mesh
    /// lies within 0.3 mm of its exact shape): the truth's contacts, which
    /// [`truth_contacts_are_the_posed_true_skin_probed_against_the_part`] checks against a
    /// vertex-by-vertex probe, are read per link.
    #[test]
    fn the_hand_holds_the_part_without_reaching_into_it() {
        for s in [clean(), typical()] {
            let t = &s.motions["grasp_bottle"].truth;
            let records = t.contacts.as_ref().expect("contacts computed");
            let hold = &t.phases[2];
            for f in [hold.first, (hold.first + hold.last) / 2, hold.last] {
                let at = |l: Link| records.iter().find(|r| r.frame == f && r.link == l.name());
                for r in records.iter().filter(|r| r.frame == f) {
                    assert!(
                        r.depth_mm < -STOP_MM + 0.3,
                        "frame {f} {}: {}",
                        r.link,
                        r.depth_mm
                    );
                }
                let wrapped = Finger::ALL[1..]
                    .iter()
                    .filter(|fi| {
                        fi.links()
                            .iter()
                            .all(|&l| at(l).is_some_and(|r| r.area_mm2 > 0.0))
                    })
                    .count();
                assert!(wrapped >= 3, "frame {f}: {wrapped} fingers wrap the part");
            }
        }
    }

    /// Gaps grow as the hand closes; the swaps exchange exactly the named tracks over the named
    /// frames; the clean model has neither.
    #[test]
    fn gaps_grow_with_closure_and_swaps_exchange_tracks() {
        let s = typical();
        let m = &s.motions["grasp_bottle"];
        let t = &m.truth;
        let hidden = |first: usize, last: usize| {
            let mut h = (0usize, 0usize);
            for (k, label) in m.trajectories.labels.iter().enumerate() {
                let link = &t.marker_links[label];
                if matches!(link.as_str(), "PALM" | "ARM" | "PART") {
                    continue;
                }
                for f in first..=last {
                    h.0 += usize::from(!m.visible[k][f]);
                    h.1 += 1;
                }
            }
            h.0 as f64 / h.1 as f64
        };
        let (reach, held) = (
            hidden(t.phases[0].first, t.phases[0].last),
            hidden(t.phases[2].first, t.phases[3].last),
        );
        assert!(held > 2.0 * reach && held > 0.08, "{reach} {held}");
        assert_eq!(t.label_swaps.len(), 2);

        // The same trial without swaps: equal but for the swapped stretches, where the two
        // tracks are exchanged.
        let tasks = &GRASP_TASKS[0];
        let err = Preset::Typical.error_model();
        let mut gerr = GraspErrors::from_model(&err);
        let weights = crate::template::load_template(s.subject.hand)
            .unwrap()
            .weights;
        let hand = crate::synth::true_contacts::true_skinned_hand(
            s.subject.hand,
            &s.true_skin,
            &s.true_skeleton,
            weights,
        )
        .unwrap();
        let inputs = || GraspInputs {
            skeleton: &s.true_skeleton,
            hand: &hand,
            markers: m.markers.clone(),
            extra: m.extra.clone(),
        };
        let rng = Rng::new(42).fork("motion-grasp_bottle");
        let again = simulate_grasp(tasks, inputs(), 3.0, FRAME_RATE, &err, &gerr, &rng).unwrap();
        assert_eq!(again.trajectories, m.trajectories, "not deterministic");
        gerr.swaps = 0;
        let plain = simulate_grasp(tasks, inputs(), 3.0, FRAME_RATE, &err, &gerr, &rng).unwrap();
        let (a, b) = (&m.trajectories, &plain.trajectories);
        let swapped = |label: &str, f: usize| {
            t.label_swaps.iter().find_map(|s| {
                let i = s.markers.iter().position(|x| x == label)?;
                (s.first..=s.last)
                    .contains(&f)
                    .then(|| s.markers[1 - i].clone())
            })
        };
        let mut exchanged = 0;
        for label in &a.labels {
            for f in 0..a.n_frames() {
                match swapped(label, f) {
                    Some(other) => {
                        assert_eq!(a.get(label, f), b.get(&other, f), "{label} {f}");
                        exchanged += 1;
                    }
                    None => assert_eq!(a.get(label, f), b.get(label, f), "{label} {f}"),
                }
            }
        }
        assert!(exchanged >= 2 * 2 * 3, "{exchanged}");
        assert_eq!(
            GraspErrors::from_model(&Preset::Clean.error_model()).swaps,
            0
        );
    }

    /// Through the files: `[motions]` names the trial, the C3D reads back to the float's
    /// precision with its gaps, the truth file reads back equal; without `motion_s` nothing of
    /// it is written and the calibration trials are the same.
    #[test]
    fn the_motion_round_trips_through_the_folder() {
        let s = typical();
        let dir = tempfile::tempdir().unwrap();
        write_subject(dir.path(), s, true).unwrap();
        let subj = crate::mocap::subject::Subject::load(dir.path()).unwrap();
        let read = subj.load_motion("grasp_bottle").unwrap();
        let mem = &s.motions["grasp_bottle"].trajectories;
        assert_eq!(read.n_frames(), mem.n_frames());
        assert_eq!(read.frame_rate, FRAME_RATE);
        for label in &mem.labels {
            for f in 0..mem.n_frames() {
                match (mem.get(label, f), read.get(label, f)) {
                    (Some(x), Some(y)) => assert!((x - y).norm() < 1e-3, "{label} {f}"),
                    (x, y) => assert_eq!(x.is_some(), y.is_some(), "{label} {f}"),
                }
            }
        }
        let text = std::fs::read_to_string(dir.path().join("truth_motion/grasp_bottle.json"));
        let truth: MotionTruth = serde_json::from_str(&text.unwrap()).unwrap();
        let want = &s.motions["grasp_bottle"].truth;
        assert_eq!((truth.rate, truth.frames), (want.rate, want.frames));
        assert_eq!(
            (&truth.phases, &truth.label_swaps),
            (&want.phases, &want.label_swaps)
        );
        for (j, track) in &want.joints {
            for (a, b) in track.centre.iter().zip(&truth.joints[j].centre) {
                assert!((p(a) - p(b)).norm() < 1e-9, "{j}");
            }
        }

        let without = simulate_with(
            &SynthOptions {
                motion_s: None,
                ..s.truth.synth.clone()
            },
            &Preset::Typical.error_model(),
        )
        .unwrap();
        assert!(without.motions.is_empty() && without.subject.motions.is_empty());
        assert_eq!(without.trials, s.trials);
        let json = serde_json::to_string(&without.truth).unwrap();
        assert!(!json.contains("motion_s"));
    }

    #[test]
    fn bad_lengths_are_refused() {
        let e = simulate(&SynthOptions {
            motion_s: Some(0.2),
            ..opts(1, Preset::Clean)
        })
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("motion trial length") && !e.contains('\n'),
            "{e}"
        );
    }

    /// The truth's fingertips are the true skeleton's forward kinematics: per digit, the point
    /// of the rest distal phalanx (from the DIP centre toward the skeleton's tip, normal to the
    /// hinge axis) level with the farthest skin vertex the template's weights give
    /// the distal link, moved by that link's true transform (from the trial's forearm motion
    /// and angles); it keeps its rest distance from the truth's DIP centre in every frame.
    #[test]
    fn truth_tips_are_the_true_skeletons_forward_kinematics() {
        let s = clean();
        let m = &s.motions["grasp_bottle"];
        let t = &m.truth;
        let template = crate::template::load_template(s.subject.hand).unwrap();
        let dom = crate::template::dominant_links(&template.weights);
        let sk = &s.true_skeleton;
        for f in Finger::ALL {
            let dip = f.joints()[2];
            let l = f.links()[2];
            let (c, x) = (sk.centre(dip), sk.joint(dip).x());
            let bone = sk.tips[f as usize] - c;
            let z = (bone - x * bone.dot(&x)).normalize();
            let reach = s
                .true_skin
                .vertices
                .iter()
                .zip(&dom)
                .filter(|(_, d)| **d == l.index())
                .map(|(v, _)| (v - c).dot(&z))
                .fold(f64::MIN, f64::max);
            assert!(reach > 10.0, "{f:?}: {reach}");
            let rest_tip = c + z * reach;
            assert_eq!(t.tips[f.letter()].len(), t.frames);
            for fr in (0..t.frames).step_by(13) {
                let pose = Pose::from_deg(&m.angles[fr], m.root[fr]);
                let want = link_transforms(sk, &pose)[l.index()] * rest_tip;
                let got = p(&t.tips[f.letter()][fr]);
                assert!((got - want).norm() < 1e-9, "{f:?} frame {fr}");
                let dc = p(&t.joints[dip.name()].centre[fr]);
                assert!((((got - dc).norm()) - (rest_tip - c).norm()).abs() < 1e-9);
            }
        }
    }

    /// The truth's contacts are those of the true skin posed afresh in each frame (the
    /// template's weights by the skeleton's own linear blend) and probed vertex
    /// by vertex against the bottle's mesh at its true pose: every vertex within 1 mm of the
    /// part or inside it counts its rest area for its dominant link. The mesh is the bottle:
    /// its signed distance agrees with the exact one of the shape there to the 2 mm grid the
    /// mesh is made on (the grid rounds the shape's edges: at the cap's rim, where a thumb
    /// reaching over the top touches, the two differ by more than half of it). Nothing touches
    /// while the hand is 60 mm back in the reach, and the hold has contacts.
    #[test]
    fn truth_contacts_are_the_posed_true_skin_probed_against_the_part() {
        use crate::grasp::contact::{vertex_areas, PartShape, Probe};
        let s = clean();
        let m = &s.motions["grasp_bottle"];
        let t = &m.truth;
        let records = t.contacts.as_ref().expect("contacts computed");
        let template = crate::template::load_template(s.subject.hand).unwrap();
        let dom = crate::template::dominant_links(&template.weights);
        let areas = vertex_areas(&s.true_skin);
        let (mesh, _) = crate::grasp::parts::clean_part(&Part::Bottle.mesh().unwrap());
        let part = PartShape::with_band(mesh, 1.0).unwrap().0;
        let grid = Part::Bottle.voxel_mm();
        let hold = t.phases.iter().find(|p| p.name == "hold").unwrap();
        let frames = [0, 5, hold.first, (hold.first + hold.last) / 2, hold.last];
        for &fr in &frames {
            let pose = Pose::from_deg(&m.angles[fr], m.root[fr]);
            let tf = link_transforms(&s.true_skeleton, &pose);
            let posed = crate::skeleton::forward_kinematics::linear_blend(
                &s.true_skin.vertices,
                &template.weights,
                &tf,
            );
            let to_part = m.part[fr].inverse();
            let mut area = [0.0; 17];
            let mut depth = [0.0f64; 17];
            for (i, v) in posed.iter().enumerate() {
                let q = to_part * v;
                let d = match part.probe(&q, f64::INFINITY) {
                    Probe::Hit(d, _, _) => d,
                    _ => continue,
                };
                if d <= 1.0 {
                    area[dom[i]] += areas[i];
                    depth[dom[i]] = depth[dom[i]].max(-d);
                    let exact = Part::Bottle.sdf(&q);
                    assert!((exact - d).abs() < grid, "vertex {i}: {d} against {exact}");
                }
            }
            for l in Link::ALL {
                let got = records.iter().find(|r| r.frame == fr && r.link == l.name());
                let (a, d) = got.map_or((0.0, 0.0), |r| (r.area_mm2, r.depth_mm));
                assert!(
                    (a - area[l.index()]).abs() < 1e-6,
                    "frame {fr} {l}: {a} against {}",
                    area[l.index()]
                );
                assert!((d - depth[l.index()]).abs() < 1e-6, "frame {fr} {l}");
            }
            let total: f64 = area.iter().sum();
            if fr < 10 {
                assert_eq!(total, 0.0, "frame {fr}: the hand is still far");
            } else {
                assert!(total > 100.0, "frame {fr}: {total} mm² in the hold");
            }
        }
    }
}
