//! Link structure model estimators (Endo, Tada & Mochimaru 2014, section 3.4).
//!
//! For every frame of a finger's calibration trial the parent link's markers are registered onto
//! their reference-frame positions (Horn 1987, the paper's equation 1), which expresses the child
//! link's markers in the parent's reference pose. The joint centre is then the centre common to
//! the spheres those trajectories lie on, and for a 1-DOF joint the axis is the normal common to
//! the planes they move in (Gamage & Lasenby 2002). This module holds the estimators as pure
//! math on point sets and segment poses; reading trials and naming joints happens elsewhere.
//!
//! * [`sphere_fit`]: common sphere centre, plain (Gamage & Lasenby 2002) and bias compensated
//!   (Halvorsen 2003), and the common circle centre on a known axis for 1-DOF joints.
//! * [`axis_fit`]: common plane normal (Gamage & Lasenby 2002).
//! * [`functional`]: estimators using both segments' poses, SCoRE (Ehrig et al. 2006) and SARA
//!   (Ehrig et al. 2007), beyond the paper.
//! * [`sta_model`]: SCoRE with a linear model of the clusters' soft-tissue artefact in the joint
//!   angles (Camomilla et al. 2013, Cappello et al. 1997/2005), beyond the paper.
//! * [`registration`]: equation 1, the per-frame registration of the parent's markers.
//! * [`estimate`]: the whole link model of a subject from its trials, with diagnostics.
//! * [`level_cues`]: a hinge's level along its axis weighted over several cues, and its depth
//!   from the motion and the skin.
//! * [`model`]: the link model as data, and `link_model.json`.
//! * [`anthropometry`]: the link model's proportions against published anthropometry (a
//!   plausibility gate).

pub mod anthropometry;
pub mod axis_fit;
pub mod estimate;
pub mod functional;
pub mod level_cues;
pub mod model;
pub mod registration;
pub mod sphere_fit;
pub mod sta_model;

pub use estimate::estimate_link_model;
pub use model::{JointEstimate, LinkModel};
