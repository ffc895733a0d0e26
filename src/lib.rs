//! # ergohand
//!
//! Individual digital hands from motion-capture data, after Endo, Tada & Mochimaru (2014),
//! "Reconstructing individual hand models from motion capture data", J. Comput. Des. Eng. 1(1).
//!
//! The data flows one way, one module per stage of the method:
//! [`mocap`] (subject folders, C3D trials) -> link model -> skin -> tet -> pose -> grasp,
//! with validation reading the outputs; [`reconstruct`] runs the stages from the trials to the
//! skinned hand for one subject. Underneath sit [`geometry`] (meshes, Horn's absolute
//! orientation, Loop subdivision), [`io`] (mesh formats), [`skeleton`] (the link tree, joint
//! frames, forward kinematics and limits) and [`template`] (the generic hand and its spec).
//! [`skin`] makes the template homologous to the subject; [`measure`] takes the caliper
//! dimensions on any skin by their definitions. [`synth`] simulates subjects with
//! ground truth, as a lab and a CT scanner would produce them.
//!
//! All lengths are millimetres in f64; units are converted at the edges (readers and writers).

pub mod anatomy;
pub mod cli;
pub mod error;
pub mod geometry;
pub mod grasp;
pub mod io;
pub mod link;
pub mod measure;
pub mod mocap;
pub mod pose;
pub mod reconstruct;
pub mod render;
pub mod rng;
pub mod skeleton;
pub mod skin;
pub mod synth;
pub mod template;
pub mod tet;
pub mod track;
pub mod validate;

pub use error::{Error, Result};
