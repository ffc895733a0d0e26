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
//! * [`volume_correction`]: keeping each finger segment's volume under DQS.
//!
//! # Defaults and why
//! Weights: the template's, carried by homology ([`WeightMethod::Template`]). They are the
//! artist's weights of the generic hand, painted for exactly this mesh, with the joint creases
//! and the wrist band; bone heat on the skin ([`WeightMethod::BoneHeat`]) is available. Measured
//! in `fist` (contacts resolved as `pose` does) by `tests::fist_quality_figures`; volume change
//! of the 15 finger segments is that of their tissue in the tetrahedral mesh
//! ([`quality::segment_volumes`]):
//!
//! | hand, weights, skinning | finger-finger penetration | segments within 5 % | mean abs. change | worst |
//! | --- | --- | --- | --- | --- |
//! | template, template, LBS | 0.00 mm | 6 / 15 | 9.7 % | M_PROX −21.9 % |
//! | template, template, DQS | 0.00 mm | 12 / 15 | 4.5 % | M_PROX −18.1 % |
//! | template, template, DQS + volume | 0.66 mm | 15 / 15 | 0.1 % | L_PROX −0.3 % |
//! | template, heat, DQS | 0.63 mm | 10 / 15 | 5.8 % | M_PROX −19.7 % |
//! | template, heat, DQS + volume | 2.22 mm | 15 / 15 | 0.1 % | M_PROX −0.2 % |
//! | seed 72 true hand, template, DQS + volume | 0.72 mm | 15 / 15 | 0.1 % | L_PROX −0.3 % |
//! | seed 72 reconstructed (30-s trials), DQS | 0.64 mm | 5 / 15 | 7.4 % | M_PROX −20.8 % |
//! | seed 72 reconstructed (30-s trials), DQS + volume | 1.90 mm | 15 / 15 | 0.1 % | R_PROX −0.3 % |
//!
//! Dual-quaternion skinning alone loses the proximal phalanges' tissue in a fist because the
//! joints' axes lie dorsal of the fingers' cross-sections (derivation in [`volume_correction`]);
//! the correction, on by default for baked outputs (`.obj`, `.vtk`, `.msh`; `--plain-skinning`
//! turns it off), swells the blended band around each joint just enough to keep every segment's
//! volume. Template weights keep the fingers apart better than heat weights.
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
pub mod volume_correction;
pub mod weights;

pub use contact_resolve::{
    resolve_finger_contacts, resolve_finger_contacts_on, ResolveOptions, Resolved,
};
pub use hand::IndividualHand;
pub use harmonic_weights::{pose_tet_nodes, tet_node_weights};
pub use pose_file::{named_pose, parse_pose_toml, read_pose_file, resolve_pose, NAMED_POSES};
pub use skinning::{dual_quaternion, linear_blend, SkinBinding, Skinning, SparseWeights};
pub use volume_correction::{VolumeOptions, VolumePose, VolumeRig};
pub use weights::{bone_heat_weights, template_weights, HeatOptions, WeightMethod};

use crate::cli::Log;
use crate::error::{Error, Result};
use crate::io::{gltf::write_glb, obj::write_obj, Units};
use std::path::{Path, PathBuf};

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
    /// Keep every finger segment's volume in the posed skin and tet mesh
    /// ([`volume_correction`]); off: dual-quaternion skinning alone. A GLB is skinned by its
    /// viewer and never corrected.
    pub preserve_volume: bool,
}

impl Default for PoseOptions {
    fn default() -> Self {
        PoseOptions {
            resolve_contacts: true,
            preserve_volume: true,
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
/// (its nodes dual-quaternion skinned with [`tet_node_weights`]), mm. Baked outputs keep each
/// finger segment's volume ([`VolumeRig::pose`], unless `opts.preserve_volume` is off); an
/// `.obj` of a folder without `tet.vtk` is plain DQS, with a warning.
///
/// Unless `opts.resolve_contacts` is off, the angles then give way where the digits of this
/// hand would enter each other by more than 1 mm, on the skin the output has: LBS for `.glb`,
/// which viewers skin linearly, DQS for a plain `.obj`, DQS with the volume correction
/// otherwise ([`resolve_finger_contacts_on`]), with a warning per changed joint.
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
    // The tetrahedral mesh is needed for a volume-kept skin and for a posed mesh.
    let rig = if ext.as_deref() == Some("glb") {
        None
    } else if !opts.preserve_volume && ext.as_deref() == Some("obj") {
        // The plain DQS skin needs no tetrahedral mesh.
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
            Some(rig) if opts.preserve_volume => resolve_finger_contacts_on(
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
            log.info(if opts.preserve_volume {
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
            });
            Some((rig.tets, posed))
        }
    };
    // Measured on the skin as written: the resolver worked on that very skin (corrected when
    // the correction is on, else `method`'s), so its figure stands; with the angles kept, it
    // is measured here.
    let penetration_mm = resolved_depth_mm.unwrap_or_else(|| {
        let max_depth = ResolveOptions::default().max_depth_mm;
        match &baked {
            Some((_, p)) => quality::finger_penetration(&p.skin, &hand.weights, max_depth),
            None => quality::finger_penetration(
                &hand.posed_skin(&pose, method),
                &hand.weights,
                max_depth,
            ),
        }
        .depth_mm
    });
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
            let (tets, b) = baked.ok_or_else(|| Error::invalid("posed tet mesh missing"))?;
            let posed = crate::tet::TetMesh {
                nodes: b.nodes,
                tets,
            };
            if ext.as_deref() == Some("vtk") {
                crate::io::vtk::write_vtk(out_file, &posed, Units::Millimetres)?;
            } else {
                crate::io::gmsh::write_msh(out_file, &posed, Units::Millimetres)?;
            }
        }
        _ => {
            let posed = match baked {
                Some((_, b)) => b.skin,
                None => hand.posed_skin(&pose, method),
            };
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

/// The [`VolumeRig`] of the `reconstruct` folder `model_dir`: its tetrahedral mesh
/// (`tet.vtk`, homologous to the template's) with the template's node weights. Errors naming
/// `tet.vtk` when it is missing or not homologous to the template's tet mesh (made by another
/// version or other stuffing parameters: re-run reconstruct).
pub fn volume_rig(hand: &IndividualHand, model_dir: &Path) -> Result<VolumeRig> {
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
    VolumeRig::new(&template, &prepared, tet.nodes)
}

#[cfg(test)]
mod tests;
