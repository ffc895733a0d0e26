//! The tracker against motions made from known angles ([`super::fixture`]): markers placed on
//! the template's skeleton, moved by a smooth grasp, optionally with noise, gaps, a swapped
//! label or an occluded digit.

use super::fixture::{grasp_setup, grasp_states, motion_trial, static_markers, static_trial};
use super::*;
use crate::anatomy::{Finger, Side};
use crate::geometry::Point;

/// The solver without its temporal term: noise-free markers then determine every frame
/// exactly, so the exactness tests can hold it to rounding. The default's temporal bias has
/// its own bound ([`the_temporal_term_biases_noise_free_frames_by_microns`]).
fn exact() -> IkOptions {
    IkOptions {
        smoothness: 0.0,
        ..IkOptions::default()
    }
}

/// Largest centre error (mm) and angle error (deg) over solved frames, and the centre RMS.
fn errors(
    kin: &Kinematics,
    tracked: &Tracked,
    truth: &[HandState],
    skip: &[Joint],
) -> (f64, f64, f64) {
    let (mut worst_c, mut worst_a, mut ss, mut n) = (0.0f64, 0.0f64, 0.0, 0usize);
    for (f, t) in truth.iter().enumerate() {
        let Some(s) = &tracked.frames[f].state else {
            continue;
        };
        let (cs, ct) = (kin.centres(s), kin.centres(t));
        for j in Joint::ALL {
            let d = (cs[j.index()] - ct[j.index()]).norm();
            worst_c = worst_c.max(d);
            ss += d * d;
            n += 1;
            if skip.contains(&j) {
                continue;
            }
            for k in 0..kin.dof[j.index()] {
                let a = (s.angles[j.index()][k] - t.angles[j.index()][k])
                    .to_degrees()
                    .abs();
                worst_a = worst_a.max(a);
            }
        }
    }
    (worst_c, worst_a, (ss / n as f64).sqrt())
}

#[test]
fn noise_free_markers_give_back_the_angles_and_centres() {
    for side in [Side::Right, Side::Left] {
        let (kin, st, att, truth) = grasp_setup(side, 150);
        let motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 1);
        let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
        assert!(tracked.warnings.is_empty(), "{:?}", tracked.warnings);
        assert!(tracked.frames.iter().all(|f| f.state.is_some()));
        let (c, a, _) = errors(&kin, &tracked, &truth, &[]);
        assert!(
            c < 1e-6 && a < 1e-6,
            "{side}: centres {c:e} mm, angles {a:e} deg"
        );
        let worst_res = tracked
            .frames
            .iter()
            .flat_map(|f| f.residual_mm.iter().flatten())
            .fold(0.0f64, |m, r| m.max(*r));
        assert!(worst_res < 1e-6, "{worst_res}");
    }
}

#[test]
fn the_temporal_term_biases_noise_free_frames_by_microns() {
    // The constant-velocity prediction misses by the motion's acceleration, and the temporal
    // term pulls toward it with a weight far below the markers': the pull must stay a small
    // fraction of the markers' noise (tenths of a millimetre), not reach it.
    let (kin, st, att, truth) = grasp_setup(Side::Right, 150);
    let motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 1);
    let tracked = track_trial(&kin, &st, &motion, None, &IkOptions::default()).unwrap();
    let (c, a, _) = errors(&kin, &tracked, &truth, &[]);
    assert!(c < 0.01 && a < 0.05, "centres {c} mm, angles {a} deg");
    let (c0, a0, _) = errors(
        &kin,
        &track_trial(&kin, &st, &motion, None, &exact()).unwrap(),
        &truth,
        &[],
    );
    // And it is the temporal term that moves them: without it the frames are exact.
    assert!(c0 < 1e-6 && a0 < 1e-6 && c > c0, "{c0} {a0} {c}");
}

#[test]
fn the_static_trial_tracked_gives_the_models_own_centres() {
    let (kin, st, _, _) = grasp_setup(Side::Right, 1);
    let tracked = track_trial(&kin, &st, &st, None, &exact()).unwrap();
    for f in &tracked.frames {
        let c = kin.centres(f.state.as_ref().unwrap());
        for j in Joint::ALL {
            assert!((c[j.index()] - kin.skeleton.centre(j)).norm() < 1e-6, "{j}");
        }
    }
}

#[test]
fn noise_of_sigma_gives_centre_errors_of_the_order_of_sigma() {
    let (kin, st, att, truth) = grasp_setup(Side::Right, 300);
    for sd in [0.5, 1.0] {
        let motion = motion_trial(&kin, &att, &truth, 100.0, sd, 7);
        let tracked = track_trial(&kin, &st, &motion, None, &IkOptions::default()).unwrap();
        assert!(tracked.frames.iter().all(|f| f.state.is_some()));
        let (worst, _, rms) = errors(&kin, &tracked, &truth, &[]);
        eprintln!("noise sd {sd} mm: centre RMS {rms:.3} mm, worst {worst:.2} mm");
        assert!(rms < 1.5 * sd && rms > 0.05 * sd, "sd {sd}: rms {rms}");
    }
}

/// Drop a marker's sample.
fn drop_sample(t: &mut Trajectories, name: &str, f: usize) {
    let i = t.index_of(name).unwrap();
    t.positions[i][f] = None;
}

#[test]
fn gaps_and_a_swapped_label_lose_no_frame() {
    let (kin, st, att, truth) = grasp_setup(Side::Right, 200);
    let mut motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 3);
    let mut rng = crate::rng::Rng::new(11);
    // Gaps: about a fifth of all samples, keeping three palm markers and two per digit.
    for (f, state) in truth.iter().enumerate() {
        for m in &att.markers {
            if rng.uniform() < 0.2 {
                drop_sample(&mut motion, &m.name, f);
            }
        }
        let seen = |t: &Trajectories, n: &str| t.get(n, f).is_some();
        let palm: Vec<String> = att
            .markers
            .iter()
            .filter(|m| m.link == Link::Palm)
            .map(|m| m.name.clone())
            .collect();
        if palm.iter().filter(|n| seen(&motion, n)).count() < 3 {
            for n in &palm[..3] {
                let i = motion.index_of(n).unwrap();
                let p = kin.evaluate(state).links[Link::Palm.index()]
                    * att.markers[att.index_of(n).unwrap()].reference;
                motion.positions[i][f] = Some(p);
            }
        }
        for fi in Finger::ALL {
            let names: Vec<String> = att
                .markers
                .iter()
                .filter(|m| m.link.joint().and_then(Joint::finger) == Some(fi))
                .map(|m| m.name.clone())
                .collect();
            let mut k = 0;
            while names.iter().filter(|n| seen(&motion, n)).count() < 2 {
                let n = &names[k];
                let m = &att.markers[att.index_of(n).unwrap()];
                let p = kin.evaluate(state).links[m.link.index()] * m.reference;
                let i = motion.index_of(n).unwrap();
                motion.positions[i][f] = Some(p);
                k += 1;
            }
        }
    }
    // A swapped label: the index and middle nails trade names for 30 frames.
    let (a, b) = (
        motion.index_of("I_NAIL").unwrap(),
        motion.index_of("M_NAIL").unwrap(),
    );
    for f in 100..130 {
        let pa = motion.positions[a][f];
        motion.positions[a][f] = motion.positions[b][f];
        motion.positions[b][f] = pa;
    }
    let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
    assert!(
        tracked.frames.iter().all(|f| f.state.is_some()),
        "{:?}",
        tracked.warnings
    );
    // Centres: exact wherever the markers determine them, that is wherever no joint proximal
    // to the centre is held (a held joint keeps the last angles it had seen) or coupled. In a
    // frame with a one-marker finger, that marker (fitted under the coupling, which the
    // fixture's abduction does not obey) pulls the palm a little: microns, bounded apart.
    let (mut worst, mut worst_coupled) = (0.0f64, 0.0f64);
    for (f, t) in truth.iter().enumerate() {
        let fr = &tracked.frames[f];
        let one_marker_finger = fr.coupled.iter().any(|j| j.rank() == 0);
        let (cs, ct) = (kin.centres(fr.state.as_ref().unwrap()), kin.centres(t));
        for j in Joint::ALL {
            let mut p = j.parent().filter(|&p| p != Joint::Wrist);
            let mut determined = true;
            while let Some(pj) = p {
                // A coupled MCP (one marker on its finger) follows the coupling, not markers.
                determined &= !fr.held.contains(&pj) && !fr.coupled.contains(&pj);
                p = pj.parent().filter(|&p| p != Joint::Wrist);
            }
            if determined {
                let d = (cs[j.index()] - ct[j.index()]).norm();
                if one_marker_finger {
                    worst_coupled = worst_coupled.max(d);
                } else {
                    worst = worst.max(d);
                }
            }
        }
    }
    let c = worst;
    assert!(c < 1e-4, "worst centre error {c} mm");
    assert!(
        worst_coupled < 0.01,
        "worst centre error {worst_coupled} mm with a one-marker finger"
    );
    let ia = att.index_of("I_NAIL").unwrap();
    let ib = att.index_of("M_NAIL").unwrap();
    for f in 100..130 {
        let fr = &tracked.frames[f];
        for i in [ia, ib] {
            if fr.residual_mm[i].is_some() {
                assert!(fr.rejected.contains(&i), "frame {f}: {:?}", fr.rejected);
            }
        }
    }
    assert!(tracked
        .warnings
        .iter()
        .any(|w| w.contains("I_NAIL") && w.contains("outlier")));
}

#[test]
fn an_occluded_digit_holds_its_angles_and_is_flagged() {
    let (kin, st, att, truth) = grasp_setup(Side::Right, 120);
    let mut motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 5);
    for f in 60..90 {
        for n in ["R_PIP", "R_DIP", "R_NAIL"] {
            drop_sample(&mut motion, n, f);
        }
    }
    let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
    assert!(tracked.frames.iter().all(|f| f.state.is_some()));
    let held = [Joint::RMcp, Joint::RPip, Joint::RDip];
    let before = tracked.frames[59].state.as_ref().unwrap().angles;
    for f in 60..90 {
        let fr = &tracked.frames[f];
        assert_eq!(fr.held, held, "frame {f}");
        let s = fr.state.as_ref().unwrap();
        for j in held {
            assert_eq!(s.angles[j.index()], before[j.index()], "frame {f} {j}");
        }
    }
    // Every other digit is as exact as ever, and the ring finger again after the gap.
    let (_, a, _) = errors(&kin, &tracked, &truth, &held);
    assert!(a < 1e-6, "{a}");
    let s = tracked.frames[100].state.as_ref().unwrap();
    for j in held {
        for k in 0..kin.dof[j.index()] {
            let d = (s.angles[j.index()][k] - truth[100].angles[j.index()][k]).abs();
            assert!(d < 1e-8, "{j} dof {k}: {d:e} rad");
        }
    }
    let file = tracked.motion_file(&kin, Vec::new());
    assert_eq!(
        file.joints["R_PIP"].held_frames,
        (60..90).collect::<Vec<_>>()
    );
    assert!(tracked
        .warnings
        .iter()
        .any(|w| w.contains("R_PIP") && w.contains("60-89")));
}

/// The ring finger of the fixture's grasp made to obey the coupling terms exactly: its MCP's
/// abduction and axial angles constant, its DIP flexion `k` times its PIP's (the fixture's
/// ratio, 45° over 75°).
fn coupled_ring_truth(n: usize) -> (Kinematics, Trajectories, Attachment, Vec<HandState>, f64) {
    let (kin, st, att, mut truth) = grasp_setup(Side::Right, n);
    let k = 45.0 / 75.0;
    let [mcp, pip, dip] = Finger::Ring.joints();
    for t in &mut truth {
        t.angles[mcp.index()][1] = 0.05;
        t.angles[mcp.index()][2] = 0.02;
        t.angles[dip.index()][0] = k * t.angles[pip.index()][0];
    }
    (kin, st, att, truth, k)
}

#[test]
fn a_finger_with_one_marker_follows_the_coupling_and_is_flagged() {
    let (kin, st, att, truth, k) = coupled_ring_truth(120);
    let mut motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 5);
    // The ring finger closes while only its nail marker is seen.
    for f in 40..80 {
        for n in ["R_PIP", "R_DIP"] {
            drop_sample(&mut motion, n, f);
        }
    }
    let ring = [Joint::RPip, Joint::RDip];
    let gap_error = |opts: &IkOptions| -> (f64, Tracked) {
        let tracked = track_trial(&kin, &st, &motion, None, opts).unwrap();
        let mut worst = 0.0f64;
        for (fr, t) in tracked.frames[40..80].iter().zip(&truth[40..80]) {
            let s = fr.state.as_ref().unwrap();
            let (cs, ct) = (kin.centres(s), kin.centres(t));
            for j in ring {
                worst = worst.max((cs[j.index()] - ct[j.index()]).norm());
            }
        }
        (worst, tracked)
    };
    // With the coupling's own ratio and a light tie, the nail alone gives the finger back:
    // the truth obeys the terms, so they cost nothing there.
    let (light, tracked) = gap_error(&IkOptions {
        coupling_weight: 1.0,
        dip_pip_coupling: k,
        ..exact()
    });
    assert!(light < 0.05, "worst PIP/DIP centre error {light} mm");
    for f in 40..80 {
        let fr = &tracked.frames[f];
        assert!(
            fr.held.iter().all(|j| j.finger() != Some(Finger::Ring)),
            "frame {f}"
        );
        assert!(fr.coupled.contains(&Joint::RMcp) && fr.coupled.contains(&Joint::RDip));
    }
    let file = tracked.motion_file(&kin, Vec::new());
    assert_eq!(
        file.joints["R_MCP"].coupled_frames,
        (40..80).collect::<Vec<_>>()
    );
    assert!(tracked
        .warnings
        .iter()
        .any(|w| w.contains("R_MCP") && w.contains("40-79")));
    // The defaults (the literature's ratio, a firm tie to the last frame) still beat holding
    // the angles of the last frame with both markers, which is what the tracker did before.
    let (default, _) = gap_error(&IkOptions::default());
    let e59 = kin.centres(&truth[39]);
    let held = (40..80)
        .flat_map(|f| {
            let ct = kin.centres(&truth[f]);
            ring.map(|j| (e59[j.index()] - ct[j.index()]).norm())
        })
        .fold(0.0f64, f64::max);
    assert!(
        default < 0.5 * held,
        "coupled {default} mm against {held} mm held"
    );
}

/// A finger followed through its one marker by the coupling terms drifts from the truth where
/// the hand does not obey them; when its other markers come back they lie far from that
/// prediction, past the jump gate, but they fit the finger together, so they are taken back
/// (not rejected as jumps for the rest of the trial) and the finger is exact again.
#[test]
fn a_coupled_finger_takes_back_its_markers_when_they_return() {
    // The ring finger closes with a straight DIP, against the coupling's 2/3 of the PIP, while
    // only its nail is seen.
    let (kin, st, att, mut truth) = grasp_setup(Side::Right, 300);
    let [_, _, dip] = Finger::Ring.joints();
    for t in &mut truth {
        t.angles[dip.index()][0] = 0.0;
    }
    let mut motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 5);
    let back = 200;
    for f in 40..back {
        for n in ["R_PIP", "R_DIP"] {
            drop_sample(&mut motion, n, f);
        }
    }
    let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
    assert!(tracked.frames.iter().all(|f| f.state.is_some()));
    assert!(tracked.frames[back - 1].coupled.contains(&Joint::RDip));
    // Where the coupled finger puts the returning markers: past the gate.
    let e = kin.evaluate(tracked.frames[back - 1].state.as_ref().unwrap());
    let markers = ["R_PIP", "R_DIP"].map(|n| att.index_of(n).unwrap());
    let off = markers
        .iter()
        .map(|&i| {
            let m = &att.markers[i];
            (e.links[m.link.index()] * m.reference - motion.get(&m.name, back).unwrap()).norm()
        })
        .fold(0.0f64, f64::max);
    assert!(
        off > IkOptions::default().jump_mm,
        "the returning markers are only {off} mm from the coupled finger"
    );
    let mut worst = 0.0f64;
    for (f, t) in truth.iter().enumerate().skip(back + 5) {
        let fr = &tracked.frames[f];
        for i in markers {
            assert!(
                !fr.rejected.contains(&i),
                "frame {f}: {} rejected",
                att.markers[i].name
            );
        }
        let (cs, ct) = (kin.centres(fr.state.as_ref().unwrap()), kin.centres(t));
        for j in Finger::Ring.joints() {
            worst = worst.max((cs[j.index()] - ct[j.index()]).norm());
        }
    }
    assert!(
        worst < 1e-3,
        "ring centres {worst} mm off after the markers came back"
    );
}

#[test]
fn a_forearm_plate_missing_from_the_static_trial_is_attached_from_the_motion() {
    let (kin, _, att, truth) = grasp_setup(Side::Right, 150);
    let mut markers = static_markers(&kin.skeleton);
    let plate: Vec<(String, Point)> = ["ARM_1", "ARM_2", "ARM_3"]
        .map(|n| (n.to_string(), markers.remove(n).unwrap()))
        .to_vec();
    let st = static_trial(&markers, 3);
    // The motion is made with the whole attachment, so it carries the plate.
    let motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 3);
    let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
    for (name, at) in &plate {
        let m = &tracked.attachment.markers[tracked.attachment.index_of(name).unwrap()];
        assert_eq!(m.link, Link::Arm);
        assert!((m.reference - at).norm() < 1e-6, "{name}: {}", m.reference);
    }
    assert!(
        tracked.warnings.iter().all(|w| !w.contains("not attached")),
        "{:?}",
        tracked.warnings
    );
    // The forearm is then solved from the plate as well: hidden wrist markers hold nothing.
    let (c, a, _) = errors(&kin, &tracked, &truth, &[]);
    assert!(c < 1e-4 && a < 1e-4, "{c} mm, {a} deg");
}

#[test]
fn frames_without_three_palm_markers_are_null_and_named_once() {
    let (kin, st, att, truth) = grasp_setup(Side::Right, 40);
    let mut motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 5);
    let palm: Vec<String> = att
        .markers
        .iter()
        .filter(|m| m.link == Link::Palm)
        .map(|m| m.name.clone())
        .collect();
    for f in 10..13 {
        for n in &palm[2..] {
            drop_sample(&mut motion, n, f);
        }
    }
    let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
    let unsolved: Vec<usize> = (0..40)
        .filter(|&f| tracked.frames[f].state.is_none())
        .collect();
    assert_eq!(unsolved, [10, 11, 12]);
    let w: Vec<&String> = tracked
        .warnings
        .iter()
        .filter(|w| w.contains("could not be solved"))
        .collect();
    assert_eq!(w.len(), 1);
    assert!(w[0].contains("10-12"), "{}", w[0]);
    let (c, _, _) = errors(&kin, &tracked, &truth, &[]);
    assert!(c < 1e-6, "{c}");
    let file = tracked.motion_file(&kin, Vec::new());
    let json: serde_json::Value = serde_json::from_str(&file.to_json()).unwrap();
    assert!(json["joints"]["I_PIP"]["centre"][11].is_null());
    assert_eq!(
        json["joints"]["I_PIP"]["angles_deg"][0]
            .as_array()
            .unwrap()
            .len(),
        1
    );
    assert_eq!(
        json["joints"]["I_MCP"]["angles_deg"][0]
            .as_array()
            .unwrap()
            .len(),
        3
    );
    assert_eq!(json["frames"], 40);
    assert_eq!(json["frame"], "lab");
    assert_eq!(json["units"], "mm");
}

#[test]
fn too_few_palm_markers_in_the_trial_is_an_error_naming_it() {
    let (kin, st, att, truth) = grasp_setup(Side::Right, 5);
    let motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 5);
    let keep: Vec<usize> = (0..motion.labels.len())
        .filter(|&i| {
            att.markers[att.index_of(&motion.labels[i]).unwrap()].link != Link::Palm
                || motion.labels[i] == "PALM_1"
        })
        .collect();
    let t = Trajectories::new(
        100.0,
        keep.iter().map(|&i| motion.labels[i].clone()).collect(),
        keep.iter().map(|&i| motion.positions[i].clone()).collect(),
        "trials/grasp.c3d",
    )
    .unwrap();
    let e = track_trial(&kin, &st, &t, None, &IkOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("grasp.c3d") && e.contains("PALM_1") && e.contains("palm markers"),
        "{e}"
    );
}

#[test]
fn a_two_dof_mcp_model_is_respected() {
    let sk = crate::template::load_template(Side::Right)
        .unwrap()
        .skeleton;
    let mut dof = Joint::ALL.map(|j| j.dof());
    for f in &Finger::ALL[1..] {
        dof[f.joints()[0].index()] = 2;
    }
    let kin = Kinematics::new(sk.clone(), dof);
    let st = static_trial(&static_markers(&sk), 1);
    let att = Attachment::from_static(&sk, &st);
    let mut truth = grasp_states(60, 100.0, Isometry3::identity());
    for s in &mut truth {
        for f in &Finger::ALL[1..] {
            s.angles[f.joints()[0].index()][2] = 0.0;
        }
    }
    let motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 1);
    let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
    let (c, a, _) = errors(&kin, &tracked, &truth, &[]);
    assert!(c < 1e-6 && a < 1e-6, "{c} {a}");
    let file = tracked.motion_file(&kin, Vec::new());
    assert_eq!(
        file.joints["M_MCP"].angles_deg[0].as_ref().unwrap().len(),
        2
    );
}

#[test]
fn ranges_read_as_ranges() {
    assert_eq!(ranges(&[1, 2, 3, 7, 9, 10]), "1-3, 7, 9-10");
    assert_eq!(ranges(&[]), "");
}

/// A one-sided plane term on a point of the index's distal phalanx, asking it 2.5 mm along
/// the direction the PIP's flexion moves it, is met to within 0.05 mm when weighted far above
/// the markers; the digit moves, not the palm (its markers keep their fit to 0.2 mm, where
/// the point moves 2.5 mm), and the same
/// refine without the term gives back the frame's state.
#[test]
fn a_plane_term_moves_its_point_and_the_markers_hold_the_rest() {
    let (kin, st, att, truth) = grasp_setup(Side::Right, 40);
    let motion = motion_trial(&kin, &att, &truth, 100.0, 0.0, 1);
    let tracked = track_trial(&kin, &st, &motion, None, &exact()).unwrap();
    let att = &tracked.attachment;
    let obs = observations(att, &motion);
    let solver = Solver::new(&kin, att, exact());
    let f = 30;
    let sol = &tracked.frames[f];
    let s = sol.state.as_ref().unwrap();
    let e = kin.evaluate(s);
    let (pip, dist) = (Joint::IPip, Link::IDist);
    let p = e.centres[Joint::IDip.index()]
        + (e.centres[Joint::IDip.index()] - e.centres[pip.index()]) * 0.3;
    let n = e.axes[pip.index()][0]
        .cross(&(p - e.centres[pip.index()]))
        .normalize();
    let plane = ContactPlane {
        link: dist.index(),
        reference: e.links[dist.index()].inverse() * p,
        on_part: p + n * 3.0,
        normal: n,
        allowance_mm: 0.5,
    };
    let (same, _) = solver.refine(sol, s, &obs[f], &[plane], 0.0).unwrap();
    let moved = |a: &HandState| {
        let (ca, cs) = (kin.centres(a), kin.centres(s));
        (0..16).map(|j| (ca[j] - cs[j]).norm()).fold(0.0, f64::max)
    };
    assert!(moved(&same) < 1e-6, "{}", moved(&same));

    let (out, res) = solver.refine(sol, s, &obs[f], &[plane], 1e5).unwrap();
    let q = kin.evaluate(&out).links[dist.index()] * plane.reference;
    let short = n.dot(&(q - plane.on_part)) + plane.allowance_mm;
    assert!(short > -0.05, "{short} mm short of the plane");
    for (i, m) in att.markers.iter().enumerate() {
        if m.link == Link::Palm {
            let r = res[i].unwrap();
            assert!(r < 0.2, "{} {r}", m.name);
        }
    }
    assert!(moved(&out) > 1.0, "{}", moved(&out));
}
