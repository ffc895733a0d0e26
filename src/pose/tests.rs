//! Properties of posing on whole hands: the template and a simulated, reconstructed subject.

use super::*;
use crate::anatomy::{Joint, Link, Side};
use crate::geometry::{Point, Vec3};
use crate::skeleton::forward_kinematics::link_transforms;
use crate::skeleton::Pose;
use crate::synth::{simulate, Preset, SynthOptions};
use crate::template::{load_template, TemplateHand};

fn template_hand(side: Side) -> (TemplateHand, IndividualHand) {
    let t = load_template(side).unwrap();
    let h = IndividualHand::from_skin(
        &t,
        t.mesh.clone(),
        t.skeleton.clone(),
        WeightMethod::Template,
    )
    .unwrap();
    (t, h)
}

/// A simulated subject (3-s trials) reconstructed as `reconstruct` does.
fn simulated_hand(seed: u64, method: WeightMethod) -> IndividualHand {
    let s = simulate(&SynthOptions {
        duration_s: Some(3.0),
        voxel_mm: 2.0,
        ..SynthOptions::new(seed, Preset::Typical)
    })
    .unwrap();
    reconstructed_hand(&s, method)
}

/// A `typical` simulated subject with 30-s trials, and its true hand (true skin and skeleton,
/// template weights). Captured with the first capture model, against which these figures were
/// set: on the harder one the reconstructed hand's corrected fist penetrates about 6 mm (an open
/// problem of the skin fit under seated-posture offsets and landmark error).
fn subject_and_true_hand(
    seed: u64,
    t: &TemplateHand,
) -> (crate::synth::SyntheticSubject, IndividualHand) {
    let s = crate::synth::simulate_with(
        &SynthOptions {
            duration_s: Some(30.0),
            voxel_mm: 2.0,
            ..SynthOptions::new(seed, Preset::Typical)
        },
        &Preset::Typical.error_model().first_capture_model(),
    )
    .unwrap();
    let truth = IndividualHand::from_skin(
        t,
        s.true_skin.clone(),
        s.true_skeleton.clone(),
        WeightMethod::Template,
    )
    .unwrap();
    (s, truth)
}

/// The hand `reconstruct` makes of a simulated subject: link model from its trials, skin fitted
/// to its reference trial, section 3.6's centres.
fn reconstructed_hand(s: &crate::synth::SyntheticSubject, method: WeightMethod) -> IndividualHand {
    let model = crate::link::estimate::estimate_link_model_from(
        s.subject.hand,
        s.subject.reference_frame,
        &s.trials,
    )
    .unwrap();
    let t = load_template(s.subject.hand).unwrap();
    let fit = crate::skin::pipeline::fit_skin(
        &t,
        &s.trials["reference"],
        &s.subject.dimensions,
        s.subject.marker_offset_mm,
        Some(&model),
        &crate::skin::pipeline::SkinOptions::default(),
    )
    .unwrap();
    // The link model as `reconstruct` writes it (section 3.6 applied on the final skin).
    let model = fit.link_model.expect("a link model was given");
    IndividualHand::from_skin(&t, fit.high, model.skeleton, method).unwrap()
}

/// The set of links at and distal of `l`.
fn subtree(l: Link) -> Vec<usize> {
    Link::ALL
        .iter()
        .filter(|&&m| {
            let mut x = Some(m);
            while let Some(y) = x {
                if y == l {
                    return true;
                }
                x = y.parent();
            }
            false
        })
        .map(|m| m.index())
        .collect()
}

/// Zero angles reproduce the skin bit for bit, with either skinning, on the template and on a
/// reconstructed subject.
#[test]
fn rest_pose_is_the_identity() {
    let (_, h) = template_hand(Side::Right);
    let s = simulated_hand(71, WeightMethod::Template);
    for h in [&h, &s] {
        for m in [Skinning::Linear, Skinning::DualQuaternion] {
            let p = h.posed_skin(&Pose::zero(), m);
            assert_eq!(p.vertices, h.skin.vertices, "{}", m.name());
            assert_eq!(p.faces, h.skin.faces);
        }
    }
}

/// Rotating one 1-DOF joint moves only the vertices weighted to its link and the links distal
/// of it; the vertices wholly on those links turn rigidly about the joint's axis (distance to
/// the axis line and position along it kept, turned by the joint angle).
#[test]
fn one_joint_moves_its_links_about_its_axis() {
    let (_, h) = template_hand(Side::Left);
    for (j, deg) in [(Joint::IPip, 70.0), (Joint::TIp, 40.0), (Joint::LDip, -8.0)] {
        let pose = Pose::zero().with_deg(j, [deg, 0.0, 0.0]);
        let moving = subtree(j.child_link());
        let jf = h.skeleton.joint(j);
        let (c, x) = (jf.centre, jf.x());
        let axial = |p: &Point| (p - c).dot(&x);
        let radial = |p: &Point| (p - c) - x * (p - c).dot(&x);
        for m in [Skinning::Linear, Skinning::DualQuaternion] {
            let posed = h.posed_skin(&pose, m);
            let (mut n_moved, mut n_rigid) = (0, 0);
            for (i, (p, q)) in h.skin.vertices.iter().zip(&posed.vertices).enumerate() {
                let w = &h.weights[i];
                let on_moving: f64 = w
                    .iter()
                    .filter(|(l, _)| moving.contains(l))
                    .map(|x| x.1)
                    .sum();
                if on_moving == 0.0 {
                    assert_eq!(p, q, "{j} {}: vertex {i} has no weight there", m.name());
                    continue;
                }
                n_moved += 1;
                if (on_moving - 1.0).abs() < 1e-12 {
                    n_rigid += 1;
                    assert!((axial(p) - axial(q)).abs() < 1e-9, "{j} vertex {i}");
                    let (r0, r1) = (radial(p), radial(q));
                    assert!((r0.norm() - r1.norm()).abs() < 1e-9, "{j} vertex {i}");
                    if r0.norm() > 1.0 {
                        // The turn, signed about x: flexion is right-handed about x for the
                        // frame's own x (x = y × z makes positive flexion palmar).
                        let ang = r0.cross(&r1).dot(&x).atan2(r0.dot(&r1)).to_degrees();
                        assert!((ang - deg).abs() < 1e-6, "{j} vertex {i}: {ang} deg");
                    }
                }
            }
            assert!(
                n_moved > 100 && n_rigid > 50,
                "{j}: {n_moved} moved, {n_rigid} rigid"
            );
        }
    }
}

/// For vertices bound to one link, LBS and DQS are the same rigid motion, in any pose.
#[test]
fn lbs_and_dqs_agree_for_single_link_vertices() {
    let (_, h) = template_hand(Side::Right);
    for name in NAMED_POSES {
        let pose = named_pose(name).unwrap();
        let (l, d) = (
            h.posed_skin(&pose, Skinning::Linear),
            h.posed_skin(&pose, Skinning::DualQuaternion),
        );
        let t = link_transforms(&h.skeleton, &pose);
        let mut n = 0;
        for (i, w) in h.weights.iter().enumerate() {
            if w.len() == 1 {
                n += 1;
                let want = t[w[0].0] * h.skin.vertices[i];
                assert!((l.vertices[i] - want).norm() < 1e-9, "{name} {i}");
                assert!((d.vertices[i] - want).norm() < 1e-9, "{name} {i}");
            }
        }
        assert!(n > 1000, "{n} single-link vertices");
    }
}

/// Posing a second point set (as the tet mesh's nodes will be) with the skin's weights carried
/// to it gives the same motion as the skin: here the skin's own vertices offset inward along
/// their normals, weighted as their vertex, move with it and stay at the same depth under a
/// pure rigid root motion.
#[test]
fn any_point_set_is_posed_by_the_same_functions() {
    let (_, h) = template_hand(Side::Right);
    let n = h.skin.vertex_normals();
    let inner: Vec<Point> = h
        .skin
        .vertices
        .iter()
        .zip(&n)
        .map(|(p, n)| p - n * 1.0)
        .collect();
    let iso = nalgebra::Isometry3::new(Vec3::new(3.0, 4.0, 5.0), Vec3::new(0.1, 0.2, 0.3));
    let pose = Pose {
        root: iso,
        ..Pose::zero()
    };
    let t = link_transforms(&h.skeleton, &pose);
    let a = linear_blend(&inner, &h.weights, &t).unwrap();
    let b = dual_quaternion(&inner, &h.weights, &t).unwrap();
    for i in 0..inner.len() {
        let want = iso * inner[i];
        assert!((a[i] - want).norm() < 1e-9 && (b[i] - want).norm() < 1e-9);
    }
}

/// Deepest penetration of one digit into another by volume, independent of any surface normal:
/// a vertex of `skin` (digit by its dominant link in `weights`) inside a tetrahedron of another
/// digit's segment (`labels`, the posed `nodes` of `tets`), its depth the distance to that
/// digit's skin faces.
fn volumetric_penetration(
    skin: &crate::geometry::TriMesh,
    weights: &crate::template::LinkWeights,
    nodes: &[Point],
    tets: &[[usize; 4]],
    labels: &[usize],
) -> (
    f64,
    Option<(crate::anatomy::Finger, crate::anatomy::Finger)>,
) {
    use crate::anatomy::Finger;
    use crate::geometry::closest_point::AabbTree;
    use crate::geometry::tet_mesh::tet_signed_volume;
    let dom = crate::template::dominant_links(weights);
    let face_digit: Vec<Option<Finger>> = quality::face_links(skin, weights)
        .iter()
        .map(|&l| quality::digit_of(l))
        .collect();
    let mut worst = (0.0, None);
    for b in Finger::ALL {
        let mine: Vec<&[usize; 4]> = tets
            .iter()
            .zip(labels)
            .filter(|(_, &l)| quality::digit_of(l) == Some(b))
            .map(|(t, _)| t)
            .collect();
        let surface = crate::geometry::TriMesh {
            vertices: skin.vertices.clone(),
            faces: skin
                .faces
                .iter()
                .zip(&face_digit)
                .filter(|(_, d)| **d == Some(b))
                .map(|(f, _)| *f)
                .collect(),
        };
        if mine.is_empty() || surface.faces.is_empty() {
            continue;
        }
        let tree = AabbTree::new(&surface);
        let inside = |p: &Point| {
            mine.iter().any(|t| {
                let [a, b2, c, d] = t.map(|i| nodes[i]);
                let v = tet_signed_volume(&a, &b2, &c, &d);
                v > 0.0
                    && [
                        tet_signed_volume(p, &b2, &c, &d),
                        tet_signed_volume(&a, p, &c, &d),
                        tet_signed_volume(&a, &b2, p, &d),
                        tet_signed_volume(&a, &b2, &c, p),
                    ]
                    .iter()
                    .all(|&x| x >= 0.0)
            })
        };
        for (v, p) in skin.vertices.iter().enumerate() {
            let Some(a) = quality::digit_of(dom[v]) else {
                continue;
            };
            if a == b {
                continue;
            }
            let Some(c) = tree.closest_point(p) else {
                continue;
            };
            if c.distance > worst.0 && inside(p) {
                worst = (c.distance, Some((a, b)));
            }
        }
    }
    worst
}

/// The quality figures in `fist`: finger-finger penetration of the skin and the
/// volume change of each finger segment (the tissue of the tet mesh, [`quality::segment_volumes`])
/// for both weight sources and both skinnings, and for DQS with the segment-volume correction
/// ([`volume_correction`]), on the template as an individual hand and on a reconstructed
/// subject (its own tet mesh, deformed from the template's). Asserted, for the defaults
/// (template weights, DQS, corrected) on both hands: every finger segment within 5 % of its
/// rest volume (the goal), the correction reaching its 0.5 % tolerance, and the digits
/// apart within the resolver's 1 mm on the corrected skin when the contacts are resolved on
/// that skin, as `pose` does, and within the 2 mm by volume (a skin vertex inside
/// another digit's tetrahedra), which no surface normal decides. Zero angles need no correction and
/// reproduce the reference skin exactly.
#[test]
fn fist_quality_figures() {
    use crate::tet::TemplateTet;
    let fist = named_pose("fist").unwrap();
    let t = load_template(Side::Right).unwrap();
    let prepared = TemplateTet::prepare(&t, None).unwrap();
    let mut hands = Vec::new();
    for method in [WeightMethod::Template, WeightMethod::BoneHeat] {
        let h = IndividualHand::from_skin(&t, t.mesh.clone(), t.skeleton.clone(), method).unwrap();
        hands.push(("template", method, h));
    }
    // Seed 72's true hand and the hand reconstructed from its 30-s trials (the 3-s trials of
    // `simulated_hand` give axes tilted enough to fold a fist's fingers through themselves).
    let (s, truth) = subject_and_true_hand(72, &t);
    hands.push(("true subject", WeightMethod::Template, truth));
    hands.push((
        "reconstructed subject",
        WeightMethod::Template,
        reconstructed_hand(&s, WeightMethod::Template),
    ));
    let opts = VolumeOptions::default();
    for (who, method, h) in &hands {
        // The fist as `pose` makes it: the digits kept apart by a few degrees where this hand's
        // would enter each other.
        let pose = crate::pose::resolve_finger_contacts(
            h,
            &fist,
            Skinning::DualQuaternion,
            &crate::pose::ResolveOptions::default(),
        )
        .pose;
        // The node weights follow the hand's skin weights, as the rig's do the template's.
        let mut weighted = t.clone();
        weighted.weights = h.weights.clone();
        let rest = if *who == "template" {
            prepared.tet.nodes.clone()
        } else {
            prepared.deform(&h.skin).unwrap().0.nodes
        };
        let rig = VolumeRig::new(&weighted, &prepared, rest).unwrap();
        // With the correction, `pose` keeps the digits apart on the corrected skin.
        let kept_pose = crate::pose::resolve_finger_contacts_on(
            h,
            &fist,
            |p| rig.corrected_skin(h, p, &opts),
            &crate::pose::ResolveOptions::default(),
        )
        .unwrap()
        .pose;
        let n = Link::ALL.len();
        let tr = link_transforms(&h.skeleton, &pose);
        let lbs = SkinBinding::new(&rig.rest_nodes, &rig.node_weights, n)
            .unwrap()
            .linear(&tr);
        let lbs_changes = quality::finger_volume_changes(
            &rig.rest_volumes,
            &quality::segment_volumes(&lbs, &rig.tets, &rig.labels, n),
        );
        let plain = rig.pose(h, &pose, false, &opts).unwrap();
        let kept = rig.pose(h, &kept_pose, true, &opts).unwrap();
        for (name, skin, changes) in [
            ("lbs", h.posed_skin(&pose, Skinning::Linear), &lbs_changes),
            ("dqs", plain.skin.clone(), &plain.volume_changes),
            ("dqs + volume", kept.skin.clone(), &kept.volume_changes),
        ] {
            let pen = quality::finger_penetration(&skin, &h.weights, 12.0);
            let worst = changes
                .iter()
                .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
                .unwrap();
            let mean = changes.iter().map(|x| x.1.abs()).sum::<f64>() / changes.len() as f64;
            let within = changes.iter().filter(|x| x.1.abs() <= 0.05).count();
            eprintln!(
                "fist {who} {} weights, {name}: penetration {:.2} mm {:?}; volume change mean |{:.1}|%, worst {} {:+.1}%, {within}/{} segments within 5%",
                method.name(),
                pen.depth_mm,
                pen.pair,
                100.0 * mean,
                worst.0,
                100.0 * worst.1,
                changes.len()
            );
            if *method == WeightMethod::default() && name == "dqs + volume" {
                assert_eq!(within, changes.len(), "{who}: {changes:?}");
                assert!(
                    kept.correction.worst_after <= 0.01,
                    "{who}: {:?}",
                    kept.correction
                );
                // The resolver's tolerance, on the skin it resolved, as it measures it.
                let resolved = quality::posed_finger_penetration(h, &kept_pose, &skin, 12.0);
                assert!(
                    resolved.depth_mm <= crate::pose::ResolveOptions::default().tolerance_mm,
                    "{who}: {resolved:?}"
                );
                // And by volume (the goal: no digit more than 2 mm inside another).
                let by_volume =
                    volumetric_penetration(&skin, &h.weights, &kept.nodes, &rig.tets, &rig.labels);
                eprintln!(
                    "fist {who}: by volume {by_volume:?}, plain {:.2} mm",
                    pen.depth_mm
                );
                assert!(by_volume.0 <= 2.0, "{who}: {by_volume:?}");
            }
        }
        if *method == WeightMethod::default() {
            // Plain DQS does lose tissue in a fist (see volume_correction's derivation).
            assert!(
                plain.correction.worst_before > 0.05,
                "{who}: {:?}",
                plain.correction
            );
            let zero = rig.pose(h, &Pose::zero(), true, &opts).unwrap();
            assert_eq!(zero.correction.iterations, 0);
            assert_eq!(zero.skin.vertices, h.skin.vertices);
        }
    }
}

/// Exploration aid (not a check): `EXPLORE_POSES=dir cargo test --lib pose::tests::explore --
/// --ignored --nocapture` poses the template and a reconstructed subject in every `*.toml` of
/// the folder and each named pose, prints the quality figures per link and digit pair, and
/// renders palmar, radial and dorsal views to `dir/NAME-WHO.png`.
#[test]
#[ignore]
fn explore() {
    use crate::render::{compose_grid, render_mesh, View};
    let Ok(dir) = std::env::var("EXPLORE_POSES") else {
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    let mut poses: Vec<(String, Pose)> = NAMED_POSES
        .iter()
        .map(|n| (n.to_string(), named_pose(n).unwrap()))
        .collect();
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    for f in files {
        let (p, v) = read_pose_file(&f).unwrap();
        for x in v {
            eprintln!("{}: {x}", f.display());
        }
        poses.push((f.file_stem().unwrap().to_string_lossy().into_owned(), p));
    }
    let (_, th) = template_hand(Side::Right);
    let mut hands = vec![("template".to_string(), th)];
    if std::env::var("EXPLORE_SUBJECT").is_ok() {
        hands.push(("subject".into(), simulated_hand(72, WeightMethod::Template)));
        hands.push((
            "subject-heat".into(),
            simulated_hand(72, WeightMethod::BoneHeat),
        ));
    }
    for (who, h) in &hands {
        let dom = crate::template::dominant_links(&h.weights);
        let colours: Vec<[u8; 3]> = dom
            .iter()
            .map(|&l| {
                let f = Link::ALL[l].joint().and_then(|j| j.finger());
                match f {
                    None => [200, 200, 200],
                    Some(f) => crate::render::viridis(f as usize as f64 / 4.0),
                }
            })
            .collect();
        let w = h.skeleton.joint(Joint::Wrist);
        for (name, pose) in &poses {
            for sk in [Skinning::Linear, Skinning::DualQuaternion] {
                let posed = h.posed_skin(pose, sk);
                let pen = quality::finger_penetration(&posed, &h.weights, 12.0);
                eprintln!(
                    "{who} {name} {}: pen {:.2} {:?} n={} | {:?}",
                    sk.name(),
                    pen.depth_mm,
                    pen.pair,
                    pen.n_vertices,
                    pen.by_pair,
                );
                if sk == Skinning::DualQuaternion {
                    let scene =
                        gltf::skinned_scene("hand", &h.skin, &h.weights, &h.skeleton, Some(pose));
                    crate::io::gltf::write_glb(
                        &dir.join(format!("{name}-{who}.glb")),
                        &scene,
                        crate::io::Units::Metres,
                    )
                    .unwrap();
                    let views = [
                        View::along(w.y(), w.z()),
                        View::along(w.x(), w.z()),
                        View::along(-w.y(), w.z()),
                    ];
                    let imgs: Vec<_> = views
                        .iter()
                        .map(|v| {
                            render_mesh(
                                &posed,
                                Some(&colours),
                                &(*v).fit_mesh(&posed, 0.05),
                                400,
                                400,
                            )
                        })
                        .collect();
                    compose_grid(&imgs, 3)
                        .save_png(dir.join(format!("{name}-{who}.png")))
                        .unwrap();
                }
            }
        }
    }
}

/// The requirement "the same deformation applied to the tetrahedral mesh's nodes": the template's
/// tet mesh posed with [`tet_node_weights`] reproduces the rest mesh at zero angles, keeps its
/// surface on the posed skin (each boundary node at the same barycentric point of the posed
/// skin face it is bound to, before the exact placement within the skinning's blend error),
/// leaves every node without weight on the index distal link in place when only the index
/// DIP bends, and inverts almost no element (those at the palmar creases, where the skin
/// itself folds in a fist).
#[test]
fn tet_nodes_follow_the_skin() {
    use crate::pose::{pose_tet_nodes, tet_node_weights};
    use crate::tet::{isosurface_stuffing, StuffingParams, TemplateTet, TetMesh};
    let (t, h) = template_hand(Side::Right);
    let tet = isosurface_stuffing(&t.mesh, &StuffingParams::default()).unwrap();
    let prepared = TemplateTet::from_mesh(&t, tet).unwrap();
    let w = tet_node_weights(&t, &prepared).unwrap();
    assert_eq!(w.len(), prepared.tet.n_nodes());
    for (i, wi) in w.iter().enumerate() {
        let s: f64 = wi.iter().map(|x| x.1).sum();
        assert!(
            (s - 1.0).abs() < 1e-12 && wi.iter().all(|x| x.1 > 0.0),
            "node {i}"
        );
    }
    let zero = link_transforms(&h.skeleton, &Pose::zero());
    let rest = dual_quaternion(&prepared.tet.nodes, &w, &zero).unwrap();
    assert_eq!(rest, prepared.tet.nodes);
    let b = &prepared.binding;
    let l = Link::ALL.iter().position(|&l| l == Link::IDist).unwrap();
    let mut dip = Pose::zero();
    dip.angles[Joint::IDip.index()][0] = 60f64.to_radians();
    let bent =
        dual_quaternion(&prepared.tet.nodes, &w, &link_transforms(&h.skeleton, &dip)).unwrap();
    let mut moved = 0;
    for (i, wi) in w.iter().enumerate() {
        if wi.iter().any(|x| x.0 == l) {
            moved += usize::from(bent[i] != prepared.tet.nodes[i]);
        } else {
            assert_eq!(bent[i], prepared.tet.nodes[i], "node {i} moved");
        }
    }
    assert!(moved > 200, "{moved} nodes follow the index DIP");
    for name in ["fist", "power-grasp", "pinch"] {
        let pose = named_pose(name).unwrap();
        let tr = link_transforms(&h.skeleton, &pose);
        let skin = h.posed_skin(&pose, Skinning::DualQuaternion);
        let skinned = dual_quaternion(&prepared.tet.nodes, &w, &tr).unwrap();
        let nodes = pose_tet_nodes(
            &prepared.tet.nodes,
            &w,
            b,
            &skin,
            &tr,
            Skinning::DualQuaternion,
        )
        .unwrap();
        let mut blend_error: f64 = 0.0;
        for (k, &v) in b.nodes.iter().enumerate() {
            let f = t.mesh.faces[b.faces[k]];
            let on_skin = (0..3).fold(Point::origin(), |acc, j| {
                acc + skin.vertices[f[j]].coords * b.barycentric[k][j]
            });
            blend_error = blend_error.max((skinned[v] - on_skin).norm());
            assert!((nodes[v] - on_skin).norm() < 1e-9, "{name}: node {v}");
        }
        let posed = TetMesh {
            nodes: nodes.clone(),
            tets: prepared.tet.tets.clone(),
        };
        let inverted = posed.inverted_count();
        eprintln!(
            "tet {name}: skinned boundary within {blend_error:.3} mm of the posed skin, \
             {inverted} of {} tetrahedra inverted",
            posed.n_tets()
        );
        assert!(blend_error < 0.5, "{name}: {blend_error} mm");
        assert!(
            inverted * 1000 < posed.n_tets(),
            "{name}: {inverted} inverted"
        );
    }
}

/// The fist goal on individual hands. The built-in `fist` is a set of angles; on a
/// broader or differently built hand the same angles close digits into each other, even on
/// the *true* hand of a simulated subject (seeds 2 and 72: the curled index enters the thumb
/// lying alongside it by about 12 mm; seed 72 also the ring the middle by about 7 mm), so
/// this is not a reconstruction error. [`resolve_finger_contacts`] brings the true and the
/// reconstructed hands of both subjects within the 2 mm by changing no angle by more
/// than 15° (the thumb's MCP at its limit, the index unbends at its MCP), and leaves a pose
/// without contacts alone.
#[test]
fn fist_contacts_resolved_on_individual_hands() {
    let fist = named_pose("fist").unwrap();
    let t = load_template(Side::Right).unwrap();
    let opts = crate::pose::ResolveOptions::default();
    for seed in [2u64, 72] {
        let (s, truth) = subject_and_true_hand(seed, &t);
        let recon = reconstructed_hand(&s, WeightMethod::Template);
        for (who, h) in [("true", &truth), ("reconstructed", &recon)] {
            for sk in [Skinning::DualQuaternion, Skinning::Linear] {
                let r = crate::pose::resolve_finger_contacts(h, &fist, sk, &opts);
                let largest = r
                    .changes_deg
                    .iter()
                    .flat_map(|(_, d)| d.iter().map(|x| x.abs()))
                    .fold(0.0, f64::max);
                eprintln!(
                    "seed {seed} {who} hand, {}: fist penetration {:.2} -> {:.2} mm in {} rounds, \
                     largest change {largest:.1}°",
                    sk.name(),
                    r.depth_before_mm,
                    r.depth_after_mm,
                    r.iterations
                );
                assert!(r.depth_after_mm <= 2.0, "seed {seed} {who}: {r:?}");
                assert!(largest <= 15.0, "seed {seed} {who}: {:?}", r.changes_deg);
                // The least penetrating pose met is returned: stopping after fewer rounds is
                // never less deep, and the depth reported is the returned pose's own.
                let mut previous = r.depth_before_mm;
                for rounds in 0..=r.iterations {
                    let cut = crate::pose::ResolveOptions {
                        max_iterations: rounds,
                        ..opts
                    };
                    let rk = crate::pose::resolve_finger_contacts(h, &fist, sk, &cut);
                    assert!(
                        rk.depth_after_mm <= previous,
                        "seed {seed} {who}: {rounds} rounds {} mm, fewer {previous} mm",
                        rk.depth_after_mm
                    );
                    previous = rk.depth_after_mm;
                }
                let again = crate::pose::resolve_finger_contacts(h, &r.pose, sk, &opts);
                assert_eq!(again.depth_before_mm, r.depth_after_mm);
                if r.depth_after_mm <= opts.tolerance_mm {
                    assert!(again.changes_deg.is_empty() && again.iterations == 0);
                }
            }
        }
    }
}
