//! Validation: reads a reconstruction's outputs and a subject's references (`truth.json`,
//! `reference.ply`) and measures the errors. It only reads files the pipeline wrote; it never
//! calls back into the stages.

pub mod dimension_accuracy;
pub mod link_accuracy;
pub mod surface_error;
pub mod thresholds;

pub use dimension_accuracy::{dimension_accuracy, DimensionAccuracy};
pub use link_accuracy::{link_accuracy, JointError, LinkAccuracy};
pub use surface_error::{surface_error, SurfaceError};
