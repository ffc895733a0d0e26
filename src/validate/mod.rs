//! Validation: reads a reconstruction's outputs and a subject's references (`truth.json`,
//! `reference.ply`) and measures the errors, then writes the report a person reads
//! (`report.html`, `report.md`, pictures and charts). It reads the files the pipeline wrote and
//! may call the stages' public functions on the subject's inputs (the joint trajectories are
//! recomputed by the link module's registration); the pipeline never calls it. It also draws
//! what a tracked trial's reader looks at (`motion_contact_map`, `motion_plots`,
//! `motion_report`), from the tracking's results, for the `track` command to write, and the 3-D
//! page of an output (`view_page`).

pub mod charts;
pub mod dimension_accuracy;
pub mod distance_plots;
pub mod error_map;
pub mod grasp_picture;
pub mod grasp_pose_sections;
pub mod joint_error_plots;
pub mod joint_fit;
pub mod joint_fit_plots;
pub mod link_accuracy;
mod model_inputs;
pub mod motion_accuracy;
pub mod motion_contact_map;
pub mod motion_plots;
pub mod motion_report;
pub mod pages;
pub mod population_report;
pub mod report;
pub mod report_html;
pub mod report_md;
pub mod report_tables;
pub mod subject_validation;
pub mod suite_index;
pub mod surface_error;
pub mod surface_regions;
pub mod tet_quality;
pub mod thresholds;
pub mod view_page;

pub use dimension_accuracy::{dimension_accuracy, DimensionAccuracy};
pub use link_accuracy::{link_accuracy, JointError, LinkAccuracy};
pub use report::{validate_subject, validate_subject_with};
pub use subject_validation::SubjectValidation;
pub use surface_error::{surface_error, SurfaceError};
