//! `ergohand pose`: the hand of a `reconstruct` folder in a pose, written as GLB, OBJ, VTK or
//! Gmsh.

use super::Voice;
use crate::error::{Error, Result};
use crate::io::{gltf::write_glb, obj::write_obj, Units};
use crate::pose::{
    gltf, quality, resolve_finger_contacts, resolve_finger_contacts_on, resolve_pose, volume_rig,
    IndividualHand, ResolveOptions, Skinning, VolumeOptions, WeightMethod,
};
use crate::validate::view_page::{view_html, ViewFrame, ViewPage, ViewRig, ViewTable};
use std::path::{Path, PathBuf};

/// What [`pose`] did.
#[derive(Clone, Debug)]
pub struct PoseSummary {
    /// One line per clamped angle and per angle changed to keep the digits apart, naming the
    /// joint.
    pub warnings: Vec<String>,
    /// The file written.
    pub written: std::path::PathBuf,
    /// The 3-D page beside it ([`view_page_path`]).
    pub view: std::path::PathBuf,
    /// Deepest finger-finger penetration of the written pose, mm.
    pub penetration_mm: f64,
}

/// Options of [`pose_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseOptions {
    /// Change the angles as little as needed to keep the digits from entering each other
    /// ([`resolve_finger_contacts`]); off: the angles exactly as given (after clamping).
    pub resolve_contacts: bool,
    /// Keep every finger segment's volume in the posed skin and tet mesh
    /// ([`crate::pose::volume_correction`]); off: dual-quaternion skinning alone. A GLB is skinned by its
    /// viewer and never corrected.
    pub preserve_volume: bool,
    /// The length unit of an `.obj` output (its header says it): millimetres by default, as
    /// every file of the toolkit; metres for viewers that take OBJ lengths as metres (Blender).
    pub obj_units: Units,
}

impl Default for PoseOptions {
    fn default() -> Self {
        PoseOptions {
            resolve_contacts: true,
            preserve_volume: true,
            obj_units: Units::Millimetres,
        }
    }
}

/// The change of largest magnitude, with its sign.
fn signed_worst(changes: &[(crate::anatomy::Link, f64)]) -> f64 {
    changes
        .iter()
        .map(|c| c.1)
        .max_by(|a, b| a.abs().total_cmp(&b.abs()))
        .unwrap_or(0.0)
}

/// [`pose_with`] the default options (contacts resolved, volumes kept).
pub fn pose(model_dir: &Path, pose_arg: &str, out_file: &Path) -> Result<PoseSummary> {
    pose_with(model_dir, pose_arg, out_file, &PoseOptions::default())
}

/// `ergohand pose OUT --pose POSE --out FILE`: load the hand of the `reconstruct` folder
/// `model_dir` ([`IndividualHand::load`], template weights), take the pose from `pose_arg` (a
/// built-in name of [`crate::pose::NAMED_POSES`] or a `POSE.toml` path), clamp it to the limits with a
/// warning per joint, and write `out_file` by its extension: `.glb` the skinned hand with the
/// pose on its joint nodes (a viewer shows it posed and can re-pose it), `.obj` the posed skin
/// (dual-quaternion skinning), mm; `.vtk` or `.msh` the posed tetrahedral mesh `OUT/tet.vtk`
/// (its nodes dual-quaternion skinned with [`crate::pose::tet_node_weights`]), mm. Baked outputs keep each
/// finger segment's volume ([`crate::pose::VolumeRig::pose`], unless `opts.preserve_volume` is off); an
/// `.obj` of a folder without `tet.vtk` is plain DQS, with a warning.
///
/// Unless `opts.resolve_contacts` is off, the angles then give way where the digits of this
/// hand would enter each other by more than 1 mm, on the skin the output has: LBS for `.glb`,
/// which viewers skin linearly, DQS for a plain `.obj`, DQS with the volume correction
/// otherwise ([`resolve_finger_contacts_on`]), with a warning per changed joint.
pub fn pose_with(
    model_dir: &Path,
    pose_arg: &str,
    out_file: &Path,
    opts: &PoseOptions,
) -> Result<PoseSummary> {
    pose_job(model_dir, pose_arg, out_file, opts, Voice::Command)
}

/// The warning for a posed tetrahedral mesh that keeps inverted elements after untangling: how
/// many and in which segments.
fn inverted_warning(posed: &crate::pose::VolumePose, n_tets: usize) -> Option<String> {
    (posed.untangle.inverted_after > 0).then(|| {
        format!(
            "{} of {n_tets} tetrahedra are inverted (negative volume) after untangling ({}): the \
             pose folds the skin through itself there; a finite-element solver will refuse the \
             mesh",
            posed.untangle.inverted_after,
            crate::pose::quality::describe_by_link(&posed.inverted_by_link),
        )
    })
}

/// [`pose_with`], speaking with `voice`.
pub(crate) fn pose_job(
    model_dir: &Path,
    pose_arg: &str,
    out_file: &Path,
    opts: &PoseOptions,
    voice: Voice,
) -> Result<PoseSummary> {
    let ext = out_file
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase);
    if !matches!(
        ext.as_deref(),
        Some("glb") | Some("obj") | Some("vtk") | Some("msh")
    ) {
        return Err(Error::input(
            out_file,
            "unknown output type: the file name must end in .glb or .obj (skin), .vtk or .msh \
             (tetrahedral mesh)",
        ));
    }
    crate::io::output_paths::check_output_file(
        out_file,
        "--out",
        &crate::io::output_paths::Inputs::files([PathBuf::from(pose_arg)]).with_model(model_dir),
    )?;
    let (pose, clamps) = resolve_pose(pose_arg)?;
    let mut warnings: Vec<String> = clamps.iter().map(|c| format!("{pose_arg}: {c}")).collect();
    let hand = IndividualHand::load(model_dir, WeightMethod::default())?;
    let method = if ext.as_deref() == Some("glb") {
        Skinning::Linear
    } else {
        Skinning::DualQuaternion
    };
    // The tetrahedral mesh is needed for a volume-kept skin and for a posed mesh; a skinned
    // .glb gets the kept-volume skin baked beside it when the folder has one.
    let glb = ext.as_deref() == Some("glb");
    let rig = if !opts.preserve_volume && matches!(ext.as_deref(), Some("obj") | Some("glb")) {
        // The plain DQS skin needs no tetrahedral mesh.
        None
    } else if glb && !model_dir.join("tet.vtk").exists() {
        None
    } else if ext.as_deref() == Some("obj") && !model_dir.join("tet.vtk").exists() {
        warnings.push(format!(
            "{}: no tet.vtk, so the segment volumes are not kept (dual-quaternion skinning \
             alone); re-run reconstruct to write it",
            model_dir.display()
        ));
        None
    } else {
        Some(volume_rig(&hand, model_dir)?)
    };
    let volume_opts = VolumeOptions::default();
    let (pose, resolved_depth_mm) = if opts.resolve_contacts {
        let resolve = ResolveOptions::default();
        // On the skin that is written: the volume correction swells the fingers at their
        // joints, which would push digits just set apart back into each other.
        let r = match &rig {
            Some(rig) if opts.preserve_volume && !glb => resolve_finger_contacts_on(
                &hand,
                &pose,
                |p| rig.corrected_skin(&hand, p, &volume_opts),
                &resolve,
            )?,
            _ => resolve_finger_contacts(&hand, &pose, method, &resolve),
        };
        warnings.extend(r.describe().into_iter().map(|w| format!("{pose_arg}: {w}")));
        (r.pose, Some(r.depth_after_mm))
    } else {
        (pose, None)
    };
    let baked = match rig {
        None => None,
        Some(rig) => {
            let posed = rig.pose(&hand, &pose, opts.preserve_volume, &volume_opts)?;
            let (unfolded, left) = posed.skin_unfolded;
            if unfolded > 0 {
                log::log!(
                    voice.info(),
                    "skinning turned {unfolded} skin faces over (a crease two bones pull apart); \
                     relaxed there, {left} left"
                );
            }
            if matches!(ext.as_deref(), Some("vtk") | Some("msh")) {
                let u = &posed.untangle;
                if u.inverted_before > 0 {
                    log::log!(
                        voice.info(),
                        "untangled the tetrahedral mesh: {} inverted elements, {} left, {} nodes \
                         moved (the boundary off the skin by up to {:.2} mm)",
                        u.inverted_before,
                        u.inverted_after,
                        u.nodes_moved,
                        u.max_boundary_move_mm
                    );
                }
                if let Some(w) = inverted_warning(&posed, rig.tets.len()) {
                    warnings.push(format!("{}: {w}", out_file.display()));
                }
            }
            log::log!(
                voice.info(),
                "{}",
                if opts.preserve_volume {
                    format!(
                    "segment volumes: worst finger segment {:+.1} % after the bulge correction \
                     ({} Newton steps; dual-quaternion skinning alone: {:.1} %)",
                    100.0 * signed_worst(&posed.volume_changes),
                    posed.correction.iterations,
                    100.0 * posed.correction.worst_before,
                )
                } else {
                    format!(
                        "segment volumes: worst finger segment {:+.1} % (dual-quaternion skinning \
                     alone)",
                        100.0 * signed_worst(&posed.volume_changes)
                    )
                }
            );
            Some((rig.tets, rig.labels, posed))
        }
    };
    // Measured on the skin as written: the resolver worked on that very skin (corrected when
    // the correction is on, else `method`'s), so its figure stands; with the angles kept, it
    // is measured here.
    let penetration_mm = resolved_depth_mm.unwrap_or_else(|| {
        let max_depth = ResolveOptions::default().max_depth_mm;
        match &baked {
            Some((_, _, p)) if !glb => {
                quality::posed_finger_penetration(&hand, &pose, &p.skin, max_depth)
            }
            _ => quality::posed_finger_penetration(
                &hand,
                &pose,
                &hand.posed_skin(&pose, method),
                max_depth,
            ),
        }
        .depth_mm
    });
    for w in &warnings {
        log::log!(voice.warn(), "{w}");
    }
    // Figures of the geometry the page shows as written (a .glb shows its viewer's skinning).
    let volume_note = baked
        .as_ref()
        .filter(|_| opts.preserve_volume && !glb)
        .map(|(_, _, b)| signed_worst(&b.volume_changes));
    let inverted = baked
        .as_ref()
        .filter(|_| matches!(ext.as_deref(), Some("vtk") | Some("msh")))
        .map(|(_, _, b)| b.untangle.inverted_after);
    let shown = match ext.as_deref() {
        Some("glb") => {
            let scene = gltf::skinned_scene(
                "hand",
                &hand.skin,
                &hand.weights,
                &hand.skeleton,
                Some(&pose),
            );
            write_glb(out_file, &scene, Units::Metres)?;
            if let Some((_, _, b)) = &baked {
                let path = baked_glb_path(out_file);
                write_glb(&path, &baked_scene(&b.skin), Units::Metres)?;
                log::log!(
                    voice.info(),
                    "{}: the skin as the toolkit poses it (dual-quaternion skinning with each \
                     finger segment's volume kept), baked",
                    path.display()
                );
            }
            Shown {
                skin: hand.posed_skin(&pose, Skinning::Linear).vertices,
                how: "linear blend skinning, as a glTF viewer shows the .glb",
            }
        }
        Some("vtk") | Some("msh") => {
            let (tets, labels, b) =
                baked.ok_or_else(|| Error::invalid("posed tet mesh missing"))?;
            let posed = crate::tet::TetMesh {
                nodes: b.nodes,
                tets,
            };
            // Each tetrahedron's link and the boundary faces, as an FE user needs them.
            let groups = quality::link_groups(&posed, &labels)?;
            if ext.as_deref() == Some("vtk") {
                crate::io::vtk::write_vtk(out_file, &posed, Units::Millimetres, Some(&groups))?;
            } else {
                crate::io::gmsh::write_msh(out_file, &posed, Units::Millimetres, Some(&groups))?;
            }
            Shown {
                skin: b.skin.vertices,
                how: if opts.preserve_volume {
                    "the skin of the posed tetrahedral mesh: dual-quaternion skinning with each \
                     finger segment's volume kept"
                } else {
                    "the skin of the posed tetrahedral mesh: dual-quaternion skinning"
                },
            }
        }
        _ => {
            let (posed, how) = match baked {
                Some((_, _, b)) => (
                    b.skin,
                    "dual-quaternion skinning with each finger segment's volume kept",
                ),
                None => (hand.posed_skin(&pose, method), "dual-quaternion skinning"),
            };
            write_obj(out_file, &posed, opts.obj_units, None)?;
            Shown {
                skin: posed.vertices,
                how,
            }
        }
    };
    let page_path = view_page_path(out_file);
    let page = pose_view_page(&PoseView {
        hand: &hand,
        pose: &pose,
        pose_arg,
        written: out_file,
        shown,
        resolved: opts.resolve_contacts,
        penetration_mm,
        worst_volume_change: volume_note,
        inverted_tets: inverted,
    });
    crate::io::atomic::write_bytes_atomic(&page_path, view_html(&page).as_bytes())?;
    log::log!(
        voice.info(),
        "pose {pose_arg}: {} -> {} (deepest finger-finger penetration {penetration_mm:.1} mm); \
         3-D view with joint sliders: {}",
        model_dir.display(),
        out_file.display(),
        page_path.display()
    );
    let summary = PoseSummary {
        warnings,
        written: out_file.to_path_buf(),
        view: page_path,
        penetration_mm,
    };
    write_pose_record(pose_arg, &summary)?;
    Ok(summary)
}

/// `NAME.pose.json` beside the posed hand `NAME.EXT`: what this run measured on it (the
/// validation report's pose section reads it from the model folder).
fn write_pose_record(pose_arg: &str, s: &PoseSummary) -> Result<()> {
    use crate::validate::grasp_pose_sections::{pose_record_path, PoseRecord};
    let record = PoseRecord {
        pose: pose_arg.to_string(),
        file: s
            .written
            .file_name()
            .map_or_else(String::new, |n| n.to_string_lossy().into_owned()),
        penetration_mm: s.penetration_mm,
        warnings: s.warnings.clone(),
    };
    let json = serde_json::to_string_pretty(&record).expect("serialisable");
    crate::io::atomic::write_bytes_atomic(&pose_record_path(&s.written), json.as_bytes())
}

/// The baked skin beside a skinned GLB: `fist.glb` -> `fist.baked.glb`.
pub(crate) fn baked_glb_path(out_file: &Path) -> PathBuf {
    out_file.with_extension("baked.glb")
}

/// A posed skin as a still glTF scene (one mesh, smooth normals).
fn baked_scene(skin: &crate::geometry::TriMesh) -> crate::io::gltf::Scene {
    crate::io::gltf::Scene {
        meshes: vec![crate::io::gltf::SceneMesh {
            name: "hand".into(),
            mesh: skin.clone(),
            normals: Some(skin.vertex_normals()),
            colors: None,
            skin: None,
            attributes: Vec::new(),
            morph_targets: Vec::new(),
        }],
        animations: Vec::new(),
    }
}

/// The page beside a pose output: `fist.glb` -> `fist.view.html`.
pub(crate) fn view_page_path(out_file: &Path) -> PathBuf {
    out_file.with_extension("view.html")
}

/// The skin as the written output has it, and how it was posed.
struct Shown {
    skin: Vec<crate::geometry::Point>,
    how: &'static str,
}

/// What the pose's page shows.
struct PoseView<'a> {
    hand: &'a IndividualHand,
    pose: &'a crate::skeleton::Pose,
    pose_arg: &'a str,
    written: &'a Path,
    shown: Shown,
    resolved: bool,
    penetration_mm: f64,
    worst_volume_change: Option<f64>,
    inverted_tets: Option<usize>,
}

/// The 3-D page of a pose: the hand as written, and joint sliders that pose it again with the
/// toolkit's dual-quaternion skinning.
fn pose_view_page(v: &PoseView) -> ViewPage {
    use crate::anatomy::Joint;
    use crate::skeleton::forward_kinematics::{link_transforms, posed_skeleton};
    let pose_name = Path::new(v.pose_arg).file_stem().map_or_else(
        || v.pose_arg.to_string(),
        |n| n.to_string_lossy().into_owned(),
    );
    let file_name = v
        .written
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let deg = |a: f64| a.to_degrees();
    let angles_deg = v.pose.angles.map(|a| a.map(deg));
    let posed = posed_skeleton(&v.hand.skeleton, &link_transforms(&v.hand.skeleton, v.pose));
    let (origin, [dorsal, radial, distal]) = posed.hand_directions();
    let mut facts = vec![
        ("pose".to_string(), v.pose_arg.to_string()),
        ("written".to_string(), file_name.clone()),
        (
            "angles".to_string(),
            if v.resolved {
                "clamped to the limits, then given way where the digits would enter each other"
            } else {
                "as given, clamped to the limits"
            }
            .to_string(),
        ),
        (
            "deepest finger-finger penetration".to_string(),
            format!("{:.1} mm", v.penetration_mm),
        ),
    ];
    if let Some(w) = v.worst_volume_change {
        facts.push((
            "worst finger segment volume change".to_string(),
            format!("{:+.1} %", 100.0 * w),
        ));
    }
    if let Some(n) = v.inverted_tets {
        facts.push(("inverted tetrahedra".to_string(), n.to_string()));
    }
    let fmt_angle = |j: Joint, k: usize| {
        if k < j.dof() {
            format!("{:.1}", angles_deg[j.index()][k])
        } else {
            String::new()
        }
    };
    ViewPage {
        title: format!("pose: {pose_name} ({file_name})"),
        kind: "pose",
        glbs: vec![],
        part_nodes: vec![],
        legend: None,
        facts,
        tables: vec![ViewTable {
            title: "joint angles as written (degrees)".into(),
            columns: ["joint", "flexion", "abduction", "axial"]
                .map(String::from)
                .to_vec(),
            rows: Joint::ALL
                .iter()
                .map(|&j| {
                    vec![
                        j.name().to_string(),
                        fmt_angle(j, 0),
                        fmt_angle(j, 1),
                        fmt_angle(j, 2),
                    ]
                })
                .collect(),
        }],
        frame: Some(ViewFrame {
            origin,
            dorsal,
            radial,
            distal,
        }),
        // From the thumb's side the flexion of every finger shows.
        view: Some("radial"),
        part_opacity: None,
        rig: Some(ViewRig {
            rest: v.hand.skin.clone(),
            weights: v.hand.weights.clone(),
            skeleton: v.hand.skeleton.clone(),
            root: v.pose.root,
            angles_deg,
            shown: v.shown.skin.clone(),
            shown_label: format!("{file_name} as written: {}", v.shown.how),
            live_label: "the sliders' angles, dual-quaternion skinned by the toolkit's own \
                         skinning (as `ergohand pose --keep-angles --plain-skinning` writes an \
                         .obj: without the segment-volume correction and without keeping the \
                         digits apart)"
                .to_string(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::pose::{named_pose, read_pose_file};
    use crate::template::load_template;

    /// A posed mesh that keeps inverted elements is never silent: the warning gives the count
    /// and the segments; a clean one gets none.
    #[test]
    fn inverted_elements_left_by_untangling_are_warned_with_count_and_segments() {
        use crate::anatomy::Link;
        use crate::geometry::TriMesh;
        use crate::pose::volume_correction::VolumeCorrection;
        let mut posed = crate::pose::VolumePose {
            skin: TriMesh {
                vertices: Vec::new(),
                faces: Vec::new(),
            },
            nodes: Vec::new(),
            correction: VolumeCorrection {
                amplitude: Vec::new(),
                iterations: 0,
                worst_before: 0.0,
                worst_after: 0.0,
            },
            volume_changes: Vec::new(),
            untangle: Default::default(),
            inverted_by_link: Vec::new(),
            skin_unfolded: (0, 0),
        };
        assert_eq!(inverted_warning(&posed, 100), None);
        posed.untangle.inverted_after = 3;
        posed.inverted_by_link = vec![(Link::LMid, 2), (Link::RProx, 1)];
        let w = inverted_warning(&posed, 100).unwrap();
        assert!(w.starts_with("3 of 100 tetrahedra are inverted"), "{w}");
        assert!(w.contains("2 in L_MID, 1 in R_PROX"), "{w}");
    }

    /// `ergohand pose` end to end on a `reconstruct`-style folder holding the template: a built-in
    /// pose to GLB (read back: skinned, joints posed) and a pose file to OBJ (the DQS posed skin),
    /// a clamped angle warned by joint, and a bad output extension refused.
    #[test]
    fn pose_command_writes_glb_and_obj() {
        let t = load_template(Side::Right).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let doc = serde_json::json!({
            "units": "mm", "frame": "reference", "hand": "right",
            "joints": crate::skeleton::record::joint_records(&t.skeleton),
        });
        std::fs::write(dir.path().join("link_model.json"), doc.to_string()).unwrap();
        crate::io::obj::write_obj(
            &dir.path().join("skin.obj"),
            &t.mesh,
            crate::io::Units::Millimetres,
            None,
        )
        .unwrap();
        let glb = dir.path().join("fist.glb");
        // The angles exactly as given: the viewer's LBS reproduces the library's.
        let exact = PoseOptions {
            resolve_contacts: false,
            ..PoseOptions::default()
        };
        let s = pose_with(dir.path(), "fist", &glb, &exact).unwrap();
        assert!(s.warnings.is_empty());
        let scene = crate::io::gltf::read_gltf(&glb, crate::io::Units::Metres).unwrap();
        let viewer = crate::pose::gltf::viewer_positions(&scene.meshes[0]).unwrap();
        let h = IndividualHand::load(dir.path(), WeightMethod::Template).unwrap();
        let lbs = h.posed_skin(&named_pose("fist").unwrap(), Skinning::Linear);
        for (a, b) in viewer.iter().zip(&lbs.vertices) {
            assert!((a - b).norm() < 5e-3);
        }
        // By default the digits give way, each change named.
        let s = pose(dir.path(), "fist", &dir.path().join("fist2.glb")).unwrap();
        assert!(s.penetration_mm <= 1.0, "{s:?}");
        assert!(s.warnings.iter().all(|w| w.contains("apart")), "{s:?}");
        let pose_file = dir.path().join("p.toml");
        std::fs::write(&pose_file, "I_PIP = 150\nM_MCP = [30, 0, 0]\n").unwrap();
        let obj = dir.path().join("p.obj");
        let s = pose(dir.path(), pose_file.to_str().unwrap(), &obj).unwrap();
        // The clamp, and the missing tet mesh: the skin is then plain DQS.
        assert_eq!(s.warnings.len(), 2, "{s:?}");
        assert!(s.warnings[0].contains("I_PIP") && s.warnings[0].contains("p.toml"));
        assert!(s.warnings[1].contains("tet.vtk"), "{s:?}");
        let posed = crate::io::obj::read_obj(&obj, crate::io::Units::Millimetres).unwrap();
        let (want, _) = read_pose_file(&pose_file).unwrap();
        let dqs = h.posed_skin(&want, Skinning::DualQuaternion);
        assert_eq!(posed.faces, dqs.faces);
        for (a, b) in posed.vertices.iter().zip(&dqs.vertices) {
            assert!((a - b).norm() < 1e-3, "OBJ precision");
        }
        // In metres for Blender: the header says so, the numbers are a thousandth, and the
        // crate's reader takes the header's word over the unit it is told.
        let metres = dir.path().join("p_m.obj");
        let in_m = PoseOptions {
            obj_units: Units::Metres,
            ..PoseOptions::default()
        };
        pose_with(dir.path(), pose_file.to_str().unwrap(), &metres, &in_m).unwrap();
        let text = std::fs::read_to_string(&metres).unwrap();
        assert!(text.lines().nth(1).unwrap().starts_with("# units: m "));
        let back = crate::io::obj::read_obj(&metres, Units::Millimetres).unwrap();
        let raw = crate::io::obj::read_obj_bytes(
            text.replacen("# units: m", "# units unknown", 1).as_bytes(),
            Units::Millimetres,
            &metres,
        )
        .unwrap();
        for ((a, b), r) in back.vertices.iter().zip(&posed.vertices).zip(&raw.vertices) {
            assert!((a - b).norm() < 1e-6);
            assert!((r.coords * 1000.0 - b.coords).norm() < 1e-6);
        }
        let e = pose(dir.path(), "fist", &dir.path().join("x.stl"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.stl") && e.contains(".glb"), "{e}");
    }
}
