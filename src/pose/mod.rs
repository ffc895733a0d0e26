//! Posing the individual hand: skinning weights on the individual skin, linear blend
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
//! and the wrist band, and they keep the fingers apart better than bone heat on the skin
//! ([`WeightMethod::BoneHeat`], available).
//!
//! Dual-quaternion skinning alone loses the proximal phalanges' tissue in a fist because the
//! joints' axes lie dorsal of the fingers' cross-sections (derivation in [`volume_correction`]);
//! the correction, on by default for baked outputs (`.obj`, `.vtk`, `.msh`; `--plain-skinning`
//! turns it off), swells the blended band around each joint just enough to keep every segment's
//! volume, measured as the tissue of the tetrahedral mesh ([`quality::segment_volumes`]).
//! `tests::fist_quality_figures` measures both choices in `fist`; the figures are in the
//! README ("Posing").
//!
//! Skinning of files: dual quaternions ([`Skinning::DualQuaternion`]), which do not collapse a
//! joint's cross-section; grasp search uses the LBS fast path ([`SkinBinding::linear_into`],
//! timed by `benches/pose.rs`). A GLB is skinned by the viewer, which is LBS by the glTF
//! specification.
//!
//! [`skeleton::forward_kinematics::link_transforms`]: crate::skeleton::forward_kinematics::link_transforms

pub mod contact_resolve;
pub mod gltf;
pub mod hand;
pub mod harmonic_weights;
pub mod pose_file;
pub mod quality;
pub mod skinned_template;
pub mod skinning;
pub mod volume_correction;
pub mod weights;

pub use contact_resolve::{
    resolve_finger_contacts, resolve_finger_contacts_on, ResolveOptions, Resolved,
};
pub use hand::IndividualHand;
pub use harmonic_weights::{
    cached_tet_node_weights, pose_tet_nodes, store_tet_node_weights, tet_node_weights,
};
pub use pose_file::{named_pose, parse_pose_toml, read_pose_file, resolve_pose, NAMED_POSES};
pub use skinning::{dual_quaternion, linear_blend, SkinBinding, Skinning, SparseWeights};
pub use volume_correction::{volume_rig, VolumeOptions, VolumePose, VolumeRig};
pub use weights::{bone_heat_weights, template_weights, HeatOptions, WeightMethod};

#[cfg(test)]
mod tests;
