//! Motion trials made from known angles, for the tests and the bench: a plausible static
//! marker set on a skeleton (every landmark of spec section 2 a few millimetres dorsal of its
//! bone), a smooth grasp (the hand travels and turns while the digits close), and the
//! trajectories the markers then draw, with optional noise.
//!
//! Everything here is independent of the solver: the markers are placed by geometry on the
//! skeleton and moved by [`Kinematics::evaluate`]'s link transforms, which are checked against
//! the skeleton's own forward kinematics.

use super::attachment::Attachment;
use super::kinematics::{HandState, Kinematics};
use crate::anatomy::{landmark_names, Finger, Joint, Side};
use crate::geometry::{Point, Vec3};
use crate::mocap::trajectories::Trajectories;
use crate::rng::Rng;
use crate::skeleton::Skeleton;
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use std::collections::BTreeMap;

/// Every landmark of the static trial plus `ARM_1..3`, placed on `sk` in its reference
/// posture: joint markers dorsal of the head of the proximal bone, nails over the distal
/// phalanx, `PALM_n` over the metacarpal heads and bases, the laterals and styloids to the
/// sides.
pub fn static_markers(sk: &Skeleton) -> BTreeMap<String, Point> {
    let m = if sk.side == Side::Right { 1.0 } else { -1.0 };
    let w = sk.joint(Joint::Wrist);
    let (cw, xw, yw, zw) = (w.centre, w.x(), w.y(), w.z());
    let mut out = BTreeMap::new();
    let mut put = |n: &str, p: Point| {
        out.insert(n.to_string(), p);
    };
    for j in &Joint::ALL[1..] {
        let f = sk.joint(*j);
        put(j.name(), f.centre + f.y() * 10.0 - f.z() * 2.0);
    }
    put("WRIST", cw + yw * 12.0 - zw * 5.0);
    put("WRIST_RAD", cw + xw * (25.0 * m) - zw * 10.0);
    put("WRIST_ULN", cw - xw * (25.0 * m) - zw * 10.0 + yw * 3.0);
    for (k, dx) in [(1, 12.0), (2, -12.0), (3, 0.0)] {
        put(
            &format!("ARM_{k}"),
            cw - zw * (60.0 + 10.0 * k as f64) + yw * 15.0 + xw * (dx * m),
        );
    }
    let (i, l) = (sk.centre(Joint::IMcp), sk.centre(Joint::LMcp));
    put("PALM_1", i + yw * 12.0 - zw * 8.0);
    put("PALM_2", l + yw * 12.0 - zw * 8.0);
    put("PALM_3", cw + (i - cw) * 0.3 + yw * 14.0);
    put("PALM_4", cw + (l - cw) * 0.3 + yw * 14.0);
    put("I_MCP_LAT", i + xw * (12.0 * m));
    put("L_MCP_LAT", l - xw * (12.0 * m));
    for f in Finger::ALL {
        let d = sk.joint(f.joints()[2]);
        let tip = sk.tips[f as usize];
        put(f.nail_marker(), tip - d.z() * 4.0 + d.y() * 7.0);
    }
    let (c, mcp) = (sk.joint(Joint::TCmc), sk.centre(Joint::TMcp));
    put("T_MC_1", c.centre + (mcp - c.centre) * 0.35 + c.y() * 9.0);
    put(
        "T_MC_2",
        c.centre + (mcp - c.centre) * 0.65 + c.y() * 9.0 + c.x() * 3.0,
    );
    debug_assert!(landmark_names().iter().all(|n| out.contains_key(*n)));
    out
}

/// A static trial of `frames` identical frames holding `markers`.
pub fn static_trial(markers: &BTreeMap<String, Point>, frames: usize) -> Trajectories {
    let labels: Vec<String> = markers.keys().cloned().collect();
    let positions = markers.values().map(|p| vec![Some(*p); frames]).collect();
    Trajectories::new(100.0, labels, positions, "trials/reference.c3d").expect("well formed")
}

/// A smooth grasp of `n` frames at `rate` Hz: the palm travels about 80 mm and turns about
/// 30 degrees, the wrist flexes and deviates, every digit closes from open toward a power
/// grasp (all angles within the anatomical ranges), with `phase` shifting the digits' timing.
pub fn grasp_states(n: usize, rate: f64, start: Isometry3<f64>) -> Vec<HandState> {
    (0..n)
        .map(|f| {
            let t = f as f64 / rate;
            // 0 -> 1 -> 0 over 4 s.
            let s = 0.5 - 0.5 * (std::f64::consts::PI * t / 2.0).cos();
            let palm = Isometry3::from_parts(
                Translation3::new(40.0 * s, -25.0 * s, 60.0 * (0.7 * t).sin()),
                UnitQuaternion::from_euler_angles(0.3 * s, -0.2 * (0.9 * t).sin(), 0.25 * s),
            ) * start;
            let mut st = HandState::at(palm);
            st.angles[0] = [
                (25.0 * s).to_radians(),
                (-8.0 * (1.1 * t).sin()).to_radians(),
                0.0,
            ];
            for (k, fi) in Finger::ALL.iter().enumerate() {
                let ph = (s * (1.0 + 0.1 * k as f64)).min(1.0);
                let [a, b, c] = fi.joints();
                if *fi == Finger::Thumb {
                    st.angles[a.index()] = [
                        (20.0 * ph).to_radians(),
                        (35.0 * ph).to_radians(),
                        (10.0 * ph).to_radians(),
                    ];
                    st.angles[b.index()][0] = (35.0 * ph).to_radians();
                    st.angles[c.index()][0] = (40.0 * ph).to_radians();
                } else {
                    let spread = 6.0 * (1.0 - ph) * (0.8 * t + k as f64).cos();
                    st.angles[a.index()] = [
                        (60.0 * ph - 5.0).to_radians(),
                        spread.to_radians(),
                        (4.0 * ph).to_radians(),
                    ];
                    st.angles[b.index()][0] = (75.0 * ph).to_radians();
                    st.angles[c.index()][0] = (45.0 * ph).to_radians();
                }
            }
            st
        })
        .collect()
}

/// The markers of `att` drawn by `states` (every marker seen), with Gaussian noise of `sd` mm
/// per coordinate drawn from `seed`.
pub fn motion_trial(
    kin: &Kinematics,
    att: &Attachment,
    states: &[HandState],
    rate: f64,
    sd: f64,
    seed: u64,
) -> Trajectories {
    let mut rng = Rng::new(seed);
    let mut positions: Vec<Vec<Option<Point>>> =
        vec![Vec::with_capacity(states.len()); att.markers.len()];
    for s in states {
        let e = kin.evaluate(s);
        for (i, p) in att.predict(&e.links).into_iter().enumerate() {
            let noise: Vec3 = if sd > 0.0 {
                rng.gauss3(sd)
            } else {
                Vec3::zeros()
            };
            positions[i].push(Some(p + noise));
        }
    }
    let labels = att.markers.iter().map(|m| m.name.clone()).collect();
    Trajectories::new(rate, labels, positions, "trials/grasp.c3d").expect("well formed")
}

/// Where the fixture's grasps start: the palm elsewhere in the lab than in the static trial,
/// and turned, so that no test passes by the reference posture's identity.
pub fn lab_start() -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(150.0, -40.0, 220.0),
        UnitQuaternion::from_euler_angles(0.2, 0.9, -0.4),
    )
}

/// The template's link model of `side` with every joint's own DOF, its static trial (3
/// frames), the markers attached from it, and the true states of a grasp of `n` frames at
/// 100 Hz from [`lab_start`].
pub fn grasp_setup(side: Side, n: usize) -> (Kinematics, Trajectories, Attachment, Vec<HandState>) {
    let sk = crate::template::load_template(side)
        .expect("the shipped template loads")
        .skeleton;
    let kin = Kinematics::full(sk.clone());
    let st = static_trial(&static_markers(&sk), 3);
    let att = Attachment::from_static(&sk, &st);
    (kin, st, att, grasp_states(n, 100.0, lab_start()))
}
