//! Posing the individual hand (issue 7): skinning weights on the individual skin, linear blend
//! and dual-quaternion skinning of any point set, joint angles from pose files and built-in
//! poses, and the skinned hand as glTF.
//!
//! * [`hand`]: [`IndividualHand`] (skin, skeleton, weights) loaded from a `reconstruct` folder
//!   or assembled in memory.
//! * [`weights`]: the template's weights by homology, or bone heat diffusion on the individual.
//! * [`skinning`]: LBS and DQS with [`skeleton::forward_kinematics::link_transforms`]
//!   (crate::skeleton::forward_kinematics::link_transforms), for the skin or a tet mesh's nodes.
//! * [`pose_file`]: `POSE.toml` and the named poses.
//! * [`gltf`]: the skinned hand as a glTF scene, optionally posed by its joint nodes.
//! * [`quality`]: self-penetration and segment-volume measures.
//!
//! # Defaults and why
//! Weights: the template's, carried by homology ([`WeightMethod::Template`]). They are the
//! artist's weights of the generic hand, painted for exactly this mesh, with the joint creases
//! and the wrist band; bone heat on the skin ([`WeightMethod::BoneHeat`]) is available. Measured
//! in `fist` on the template as the individual hand (`tests::fist_quality_figures`):
//!
//! | weights, skinning | finger-finger penetration | finger segments within 5 % volume | mean abs. change | worst |
//! | --- | --- | --- | --- | --- |
//! | template, LBS | 1.10 mm | 11 / 15 | 4.2 % | L_PROX +20 % |
//! | template, DQS | 1.15 mm | 8 / 15 | 6.3 % | L_PROX +23 % |
//! | heat, LBS | 1.33 mm | 7 / 15 | 6.3 % | I_MID −13 % |
//! | heat, DQS | 5.03 mm | 9 / 15 | 5.7 % | L_MID +19 % |
//!
//! Template weights keep the fingers apart in the fist with either skinning; heat weights let
//! the thumb enter the index by 5 mm under DQS. Segment volume is the proxy of
//! [`quality::segment_volumes`] (each link's faces closed by cones to its bone's midpoint).
//!
//! Skinning of files: dual quaternions ([`Skinning::DualQuaternion`]), which do not collapse a
//! joint's cross-section; grasp search uses the LBS fast path ([`SkinBinding::linear_into`],
//! about 2,900 poses/s including forward kinematics for the 18,514-vertex skin on a loaded
//! 2-core machine, `benches/pose.rs`). A GLB is skinned by the viewer, which is LBS by the
//! glTF specification.
//!
//! [`skeleton::forward_kinematics::link_transforms`]: crate::skeleton::forward_kinematics::link_transforms

pub mod contact_resolve;
pub mod gltf;
pub mod hand;
pub mod harmonic_weights;
pub mod pose_file;
pub mod quality;
pub mod skinning;
pub mod weights;

pub use contact_resolve::{resolve_finger_contacts, ResolveOptions, Resolved};
pub use hand::IndividualHand;
pub use harmonic_weights::{pose_tet_nodes, tet_node_weights};
pub use pose_file::{named_pose, parse_pose_toml, read_pose_file, resolve_pose, NAMED_POSES};
pub use skinning::{dual_quaternion, linear_blend, SkinBinding, Skinning, SparseWeights};
pub use weights::{bone_heat_weights, template_weights, HeatOptions, WeightMethod};

use crate::cli::Log;
use crate::error::{Error, Result};
use crate::io::{gltf::write_glb, obj::write_obj, Units};
use std::path::Path;

/// What [`pose_command`] did.
#[derive(Clone, Debug)]
pub struct PoseSummary {
    /// One line per clamped angle and per angle changed to keep the digits apart, naming the
    /// joint.
    pub warnings: Vec<String>,
    /// The file written.
    pub written: std::path::PathBuf,
    /// Deepest finger-finger penetration of the written pose, mm.
    pub penetration_mm: f64,
}

/// Options of [`pose_command_with`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PoseOptions {
    /// Change the angles as little as needed to keep the digits from entering each other
    /// ([`resolve_finger_contacts`]); off: the angles exactly as given (after clamping).
    pub resolve_contacts: bool,
}

impl Default for PoseOptions {
    fn default() -> Self {
        PoseOptions {
            resolve_contacts: true,
        }
    }
}

/// [`pose_command_with`] the default options (contacts resolved).
pub fn pose_command(
    model_dir: &Path,
    pose_arg: &str,
    out_file: &Path,
    log: &Log,
) -> Result<PoseSummary> {
    pose_command_with(model_dir, pose_arg, out_file, &PoseOptions::default(), log)
}

/// `ergohand pose OUT --pose POSE --out FILE`: load the hand of the `reconstruct` folder
/// `model_dir` ([`IndividualHand::load`], template weights), take the pose from `pose_arg` (a
/// built-in name of [`NAMED_POSES`] or a `POSE.toml` path), clamp it to the limits with a
/// warning per joint, and write `out_file` by its extension: `.glb` the skinned hand with the
/// pose on its joint nodes (a viewer shows it posed and can re-pose it), `.obj` the posed skin
/// (dual-quaternion skinning), mm; `.vtk` or `.msh` the posed tetrahedral mesh `OUT/tet.vtk`
/// (its nodes dual-quaternion skinned with [`tet_node_weights`]), mm.
///
/// Unless `opts.resolve_contacts` is off, the angles then give way where the digits of this
/// hand would enter each other by more than 1 mm ([`resolve_finger_contacts`], with the
/// skinning the output uses: LBS for `.glb`, which viewers skin linearly, DQS otherwise), with
/// a warning per changed joint.
pub fn pose_command_with(
    model_dir: &Path,
    pose_arg: &str,
    out_file: &Path,
    opts: &PoseOptions,
    log: &Log,
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
    let (pose, clamps) = resolve_pose(pose_arg)?;
    let mut warnings: Vec<String> = clamps.iter().map(|c| format!("{pose_arg}: {c}")).collect();
    let hand = IndividualHand::load(model_dir, WeightMethod::default())?;
    let method = if ext.as_deref() == Some("glb") {
        Skinning::Linear
    } else {
        Skinning::DualQuaternion
    };
    let (pose, penetration_mm) = if opts.resolve_contacts {
        let r = resolve_finger_contacts(&hand, &pose, method, &ResolveOptions::default());
        warnings.extend(r.describe().into_iter().map(|w| format!("{pose_arg}: {w}")));
        (r.pose, r.depth_after_mm)
    } else {
        let pen = quality::finger_penetration(
            &hand.posed_skin(&pose, method),
            &hand.weights,
            ResolveOptions::default().max_depth_mm,
        );
        (pose, pen.depth_mm)
    };
    for w in &warnings {
        log.warn(w);
    }
    match ext.as_deref() {
        Some("glb") => {
            let scene = gltf::skinned_scene(
                "hand",
                &hand.skin,
                &hand.weights,
                &hand.skeleton,
                Some(&pose),
            );
            write_glb(out_file, &scene, Units::Metres)?;
        }
        Some("vtk") | Some("msh") => {
            let posed = posed_tet(&hand, model_dir, &pose)?;
            if ext.as_deref() == Some("vtk") {
                crate::io::vtk::write_vtk(out_file, &posed, Units::Millimetres)?;
            } else {
                crate::io::gmsh::write_msh(out_file, &posed, Units::Millimetres)?;
            }
        }
        _ => {
            let posed = hand.posed_skin(&pose, Skinning::DualQuaternion);
            write_obj(out_file, &posed, Units::Millimetres, None)?;
        }
    }
    log.info(format!(
        "pose {pose_arg}: {} -> {} (deepest finger-finger penetration {penetration_mm:.1} mm)",
        model_dir.display(),
        out_file.display()
    ));
    Ok(PoseSummary {
        warnings,
        written: out_file.to_path_buf(),
        penetration_mm,
    })
}

/// The tetrahedral mesh of the `reconstruct` folder `model_dir` (`tet.vtk`, homologous to the
/// template's) in `pose`: its nodes dual-quaternion skinned with [`tet_node_weights`] through
/// `hand`'s skeleton. Errors naming `tet.vtk` when it is not homologous to the template's tet
/// mesh (made by another version or other stuffing parameters: re-run reconstruct).
pub fn posed_tet(
    hand: &IndividualHand,
    model_dir: &Path,
    pose: &crate::skeleton::Pose,
) -> Result<crate::tet::TetMesh> {
    let path = model_dir.join("tet.vtk");
    let tet = crate::io::vtk::read_vtk(&path, Units::Millimetres)?;
    let template = crate::template::load_template(hand.side)?;
    let prepared = crate::tet::TemplateTet::prepare(&template, None)?;
    if tet.n_nodes() != prepared.tet.n_nodes() || tet.tets != prepared.tet.tets {
        return Err(Error::input(
            &path,
            format!(
                "{} nodes / {} tetrahedra, not homologous to the {} template's tet mesh ({} / {}); \
                 re-run reconstruct",
                tet.n_nodes(),
                tet.n_tets(),
                hand.side,
                prepared.tet.n_nodes(),
                prepared.tet.n_tets()
            ),
        ));
    }
    let weights = tet_node_weights(&template, &prepared)?;
    let t = crate::skeleton::forward_kinematics::link_transforms(&hand.skeleton, pose);
    let skin = hand.posed_skin(pose, Skinning::DualQuaternion);
    let nodes = pose_tet_nodes(
        &tet.nodes,
        &weights,
        &prepared.binding,
        &skin,
        &t,
        Skinning::DualQuaternion,
    )?;
    Ok(crate::tet::TetMesh {
        nodes,
        tets: tet.tets,
    })
}

#[cfg(test)]
mod tests;
