//! The procedural hand's skeleton: anatomical joint centres and frames of a right hand in its
//! neutral (straight) posture, and its own relaxed reference posture.
//!
//! Body frame (right hand; the left hand is its mirror image, see [`super::mirror`]): origin at
//! the wrist's centre of rotation (the head of the capitate, taken level with the distal wrist
//! crease), +Y distal along the 3rd metacarpal, +Z dorsal, so the radial side (the thumb) is -X
//! and the wrist frame's x = y × z points radially, as the skeleton conventions require.
//!
//! Layout (after Buchholz, Armstrong & Goldstein 1992 for lengths; the transverse and
//! longitudinal arches after Kapandji, *The Physiology of the Joints*, vol. 1):
//! * carpometacarpal joints of II-V on a shallow arc distal of the wrist, the metacarpals
//!   diverging to heads on a wider arc (the middle head most distal and most dorsal, index and
//!   little heads a few mm palmar: the transverse arch);
//! * fingers fanning from the heads (index radial, ring and little ulnar);
//! * the thumb's carpometacarpal joint radial and palmar of the index base, its metacarpal
//!   pointing distally, radially and palmarly, and the thumb rotated 80-100° about its own long
//!   axis relative to the fingers (its nail faces radially, a little palmar);
//! * 1-DOF axes (PIP, DIP, thumb MCP and IP) tilted 2-7° from the perpendicular to the bone so
//!   that a flexing finger turns toward the scaphoid (the convergence of flexed fingers), plus a
//!   twist of 0.7-1.5° (opposite on a digit's two hinges), so no two axes are parallel.

use super::proportions::Proportions;
use crate::anatomy::{Finger, Joint, Side};
use crate::geometry::{Point, Vec3};
use crate::rng::Rng;
use crate::skeleton::{frame_from_axis, frame_from_long_axis, JointFrame, Pose, Skeleton};
use nalgebra::{Rotation3, Unit, UnitQuaternion};

/// The skeleton of a neutral right hand and what the skin and landmarks need besides it.
#[derive(Clone, Debug)]
pub struct BodySkeleton {
    /// Joint frames in the neutral posture (straight digits), right hand.
    pub skeleton: Skeleton,
    /// Carpometacarpal joints (metacarpal bases) of the index, middle, ring and little fingers.
    pub metacarpal_bases: [Point; 4],
    /// The scaphoid's position, toward which flexed fingers converge.
    pub scaphoid: Point,
}

/// Fraction of hand breadth of the MCP centres across the palm (x), index to little; the palm's
/// radial and ulnar edges at the heads are at -0.40 and +0.60 (so the breadth is the hand
/// breadth), the middle ray on x = 0.
const MCP_X: [f64; 4] = [-0.25, 0.0, 0.225, 0.42];
/// Metacarpal bases: x as a fraction of hand breadth, y as a fraction of hand length.
const BASE_X: [f64; 4] = [-0.13, 0.0, 0.11, 0.21];
/// MCP and base depths (z, mm at hand breadth 90): the transverse arch.
const MCP_Z: [f64; 4] = [-3.0, 0.0, -2.0, -5.0];
const BASE_Z: [f64; 4] = [-2.0, 0.0, -1.0, -3.0];
/// Finger directions in the palm plane, degrees from +Y toward the ulnar side (+X).
const FAN_DEG: [f64; 4] = [-8.0, 0.0, 7.0, 14.0];

/// Build the neutral skeleton of a right hand with proportions `p`; `rng` draws the thumb's
/// rotation, the axis tilts and small positional jitter.
pub fn build_skeleton(p: &Proportions, rng: &mut Rng) -> crate::Result<BodySkeleton> {
    let (hl, hb) = (p.hand_length, p.hand_breadth);
    let zs = hb / 90.0;
    let seg = |f: Finger| p.segments[f as usize];
    let mut centres = [Point::origin(); 16];
    let mut tips = [Point::origin(); 5];
    let mut bases = [Point::origin(); 4];
    // The carpal part of the middle ray: what hand length leaves after the ray's segments.
    let carpal = (hl - p.middle_ray()).max(0.05 * hl);
    for (k, f) in Finger::ALL[1..].iter().enumerate() {
        let s = seg(*f);
        let base_y = carpal + [-0.005, 0.0, 0.005, 0.002][k] * hl;
        let base = Point::new(BASE_X[k] * hb, base_y, BASE_Z[k] * zs);
        // The head sits at MCP_X across the palm, one metacarpal length from the base.
        let dx = MCP_X[k] * hb - base.x;
        let dz = (MCP_Z[k] - BASE_Z[k]) * zs;
        let dy = (s[0] * s[0] - dx * dx - dz * dz).max(1.0).sqrt();
        let mcp = base + Vec3::new(dx, dy, dz) + rng.gauss3(0.5);
        let fan = (FAN_DEG[k] + rng.gauss(0.0, 1.5)).to_radians();
        let dir = Vec3::new(fan.sin(), fan.cos(), 0.0);
        let [jm, jp, jd] = f.joints();
        centres[jm.index()] = mcp;
        centres[jp.index()] = mcp + dir * s[1];
        centres[jd.index()] = centres[jp.index()] + dir * s[2];
        // The distal bone ends inside the pulp: the skin tip lies a pulp's length beyond it.
        tips[*f as usize] = centres[jd.index()] + dir * (s[3] - pulp_length(p, *f));
        bases[k] = base;
    }
    // Thumb: CMC radial-palmar of the index base; metacarpal distally, radially and palmarly.
    let cmc = Point::new(-0.20 * hb, carpal + 0.005 * hl, -0.28 * p.wrist_thickness);
    let t_dir = (Vec3::new(-0.58, 0.76, -0.26) + rng.gauss3(0.04)).normalize();
    let s = seg(Finger::Thumb);
    let t_mcp = cmc + t_dir * s[0];
    // The thumb's phalanges continue the metacarpal bent 10° further toward the index (the
    // relaxed thumb's column is not straight even at zero angles).
    let t_phal = Rotation3::from_axis_angle(&Vec3::z_axis(), -10f64.to_radians()) * t_dir;
    centres[Joint::TCmc.index()] = cmc;
    centres[Joint::TMcp.index()] = t_mcp;
    centres[Joint::TIp.index()] = t_mcp + t_phal * s[1];
    tips[0] = centres[Joint::TIp.index()] + t_phal * (s[3] - pulp_length(p, Finger::Thumb));
    // The thumb's dorsal direction: the fingers' dorsal (+Z) made perpendicular to its
    // metacarpal, then turned about it by 80-100° so the nail faces radially.
    let roll = rng.range(80.0, 100.0).to_radians();
    let z0 = (Vec3::z() - t_dir * t_dir.z).normalize();
    let turned = |a: f64| UnitQuaternion::from_axis_angle(&Unit::new_normalize(t_dir), a) * z0;
    let thumb_dorsal = [turned(roll), turned(-roll)]
        .into_iter()
        .min_by(|a, b| a.x.total_cmp(&b.x))
        .expect("two candidates");

    let scaphoid = Point::new(-0.12 * hb, 0.01 * hl, -0.1 * p.wrist_thickness);
    let mut sk = Skeleton {
        side: Side::Right,
        joints: vec![
            JointFrame {
                centre: Point::origin(),
                frame: Rotation3::identity(),
            };
            16
        ],
        tips,
    };
    for j in Joint::ALL {
        sk.joints[j.index()].centre = centres[j.index()];
    }
    for j in Joint::ALL {
        let long = sk.distal_end(j) - sk.centre(j);
        let dorsal = if j.finger() == Some(Finger::Thumb) {
            thumb_dorsal
        } else {
            Vec3::z()
        };
        let nominal = frame_from_long_axis(&long, &dorsal)
            .map_err(|e| crate::Error::invalid(format!("procedural skeleton, joint {j}: {e}")))?;
        let frame = if j.dof() == 3 {
            nominal
        } else {
            let x = nominal.matrix().column(0).into_owned();
            let y = nominal.matrix().column(1).into_owned();
            let z = nominal.matrix().column(2).into_owned();
            // Tilt toward convergence: the flexing bone swings toward the scaphoid.
            let f = j.finger().expect("1-DOF joints are on digits");
            let magnitude = match f {
                Finger::Thumb => rng.range(2.0, 5.0),
                Finger::Index => rng.range(2.0, 4.0),
                Finger::Middle => rng.range(2.0, 4.0),
                Finger::Ring => rng.range(3.0, 6.0),
                Finger::Little => rng.range(4.0, 7.0),
            }
            .to_radians();
            // PIP/IP and DIP twist opposite ways, so a digit's two hinges are never parallel.
            let twist_sign = if j.rank() == 1 { 1.0 } else { -1.0 };
            let twist = (twist_sign * rng.range(0.7, 1.5)).to_radians();
            let toward = scaphoid - sk.centre(j);
            let lateral = toward - z * toward.dot(&z) - y * toward.dot(&y);
            let pick = |sign: f64| {
                let axis = (x + z * (sign * magnitude).tan() + y * twist.tan()).normalize();
                // Where the bone's end goes under a 90° flexion about this axis.
                let q = UnitQuaternion::from_axis_angle(
                    &Unit::new_normalize(axis),
                    0.5 * std::f64::consts::PI,
                );
                (axis, (q * z).dot(&lateral))
            };
            let (a, b) = (pick(1.0), pick(-1.0));
            let axis = if a.1 >= b.1 { a.0 } else { b.0 };
            frame_from_axis(&axis, &long).map_err(|e| {
                crate::Error::invalid(format!("procedural skeleton, joint {j}: {e}"))
            })?
        };
        sk.joints[j.index()].frame = frame;
    }
    Ok(BodySkeleton {
        skeleton: sk,
        metacarpal_bases: bases,
        scaphoid,
    })
}

/// Skin beyond the distal bone's end along the digit (the pulp), mm.
pub fn pulp_length(p: &Proportions, f: Finger) -> f64 {
    // About a third of the distal thickness (Garrett 1971's fingertip soft tissue, 4-6 mm).
    0.3 * p.sections[f as usize][3] + 0.5
}

/// The procedural body's own reference posture: a relaxed hand lying palm down, fingers
/// slightly flexed (MCP 4-12°, PIP 8-18°, DIP 3-10°, more toward the little finger as in a
/// resting cascade), thumb MCP and IP 5-15°.
pub fn relaxed_posture(rng: &mut Rng) -> Pose {
    let mut pose = Pose::zero();
    for (k, f) in Finger::ALL[1..].iter().enumerate() {
        let more = k as f64 * 2.0;
        let [mcp, pip, dip] = f.joints();
        pose = pose
            .with_deg(mcp, [rng.range(4.0, 10.0) + more, 0.0, 0.0])
            .with_deg(pip, [rng.range(8.0, 15.0) + more, 0.0, 0.0])
            .with_deg(dip, [rng.range(3.0, 10.0), 0.0, 0.0]);
    }
    pose.with_deg(Joint::TMcp, [rng.range(5.0, 15.0), 0.0, 0.0])
        .with_deg(Joint::TIp, [rng.range(5.0, 15.0), 0.0, 0.0])
}

/// The sum of two postures, joint by joint (forearm placement from `a`).
pub fn add_postures(a: &Pose, b: &Pose) -> Pose {
    let mut out = a.clone();
    for (o, x) in out.angles.iter_mut().zip(&b.angles) {
        for k in 0..3 {
            o[k] += x[k];
        }
    }
    out
}

/// Fingers cannot pass through each other: where the posture brings two neighbouring fingers
/// (beyond the web, a third along the proximal phalanx, to the tips) closer than their half
/// breadths at the PIP plus 0.5 mm, the MCP abduction of both is scaled back toward the neutral
/// fan, by 20 % a step, until they are apart (at most 20 steps). Where it brings the thumb (the
/// distal half of its metacarpal and its phalanges) that close to any finger's phalanges, every
/// angle of the thumb's three joints is scaled back toward its neutral opposition the same way.
pub fn keep_fingers_apart(bs: &BodySkeleton, p: &Proportions, pose: &Pose) -> Pose {
    use crate::skeleton::forward_kinematics::{link_transforms, posed_skeleton};
    let mut pose = pose.clone();
    for _ in 0..20 {
        let posed = posed_skeleton(&bs.skeleton, &link_transforms(&bs.skeleton, &pose));
        let samples = |f: Finger| -> Vec<Point> {
            let [m, pi, d] = f.joints().map(|j| posed.centre(j));
            let tip = posed.tips[f as usize];
            let mut out = Vec::new();
            for (a, b, from) in [(m, pi, 1.0 / 3.0), (pi, d, 0.0), (d, tip, 0.0)] {
                for k in 0..6 {
                    let t = from + (1.0 - from) * k as f64 / 5.0;
                    out.push(a + (b - a) * t);
                }
            }
            out
        };
        let mut clash = Vec::new();
        for pair in Finger::ALL[1..].windows(2) {
            let (a, b) = (pair[0], pair[1]);
            let need = 0.5 * (p.sections[a as usize][0] + p.sections[b as usize][0]) + 0.5;
            let (sa, sb) = (samples(a), samples(b));
            let closest = sa
                .iter()
                .flat_map(|x| sb.iter().map(move |y| (x - y).norm()))
                .fold(f64::INFINITY, f64::min);
            if closest < need {
                clash.extend([a, b]);
            }
        }
        // The thumb against every finger: its metacarpal's distal half and phalanges, against
        // each finger's phalanges from the MCP.
        let thumb: Vec<Point> = {
            let [cmc, mcp, ip] = Finger::Thumb.joints().map(|j| posed.centre(j));
            let tip = posed.tips[Finger::Thumb as usize];
            let mut out = Vec::new();
            for (a, b, from) in [(cmc, mcp, 0.5), (mcp, ip, 0.0), (ip, tip, 0.0)] {
                for k in 0..6 {
                    let t = from + (1.0 - from) * k as f64 / 5.0;
                    out.push(a + (b - a) * t);
                }
            }
            out
        };
        let thumb_clash = Finger::ALL[1..].iter().any(|&f| {
            let need = 0.5 * (p.sections[0][0] + p.sections[f as usize][0]) + 0.5;
            let [m, pi, d] = f.joints().map(|j| posed.centre(j));
            let tip = posed.tips[f as usize];
            let mut bone = Vec::new();
            for (a, b) in [(m, pi), (pi, d), (d, tip)] {
                for k in 0..6 {
                    bone.push(a + (b - a) * (k as f64 / 5.0));
                }
            }
            thumb
                .iter()
                .any(|x| bone.iter().any(|y| (x - y).norm() < need))
        });
        if clash.is_empty() && !thumb_clash {
            break;
        }
        for f in clash {
            pose.angles[f.joints()[0].index()][1] *= 0.8;
        }
        if thumb_clash {
            // Back toward the thumb's neutral opposition, every joint of it.
            for j in Finger::Thumb.joints() {
                for a in &mut pose.angles[j.index()] {
                    *a *= 0.8;
                }
            }
        }
    }
    pose
}
