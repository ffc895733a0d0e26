//! What `validate` measured on one subject ([`SubjectValidation`], written as `metrics.json`)
//! and the pictures of its report ([`ReportFigures`]): the data the report's renderers
//! (`report_html`, `report_md`, `report_tables`, `suite_index`) read, apart from the job that
//! measures it ([`super::report::validate_subject`]).

use super::charts::Figure;
use super::dimension_accuracy::DimensionAccuracy;
use super::joint_fit::JointFit;
use super::link_accuracy::LinkAccuracy;
use super::motion_accuracy::MotionAccuracy;
use super::surface_error::SurfaceError;
use super::surface_regions::SurfaceRegions;
use crate::anatomy::Side;
use crate::error::{Error, Result};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One child marker's distance to its joint centre (the seed paper's Figure 9).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MarkerRadius {
    /// Marker name.
    pub marker: String,
    /// Mean, mm.
    pub mean_mm: f64,
    /// SD, mm.
    pub sd_mm: f64,
    /// Samples.
    pub frames: usize,
}

/// Per joint: how its centre was fitted and how well the markers kept their distance to it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointFitSummary {
    /// Joint name.
    pub joint: String,
    /// 1 or 3.
    pub dof: usize,
    /// The trial it came from.
    pub trial: String,
    /// The centre's estimator.
    pub estimator: String,
    /// Range of motion, degrees.
    pub range_of_motion_deg: f64,
    /// The centre's bootstrap SD from `link_model.json`, mm (`null` when not recorded).
    pub centre_sd_mm: Option<f64>,
    /// Every child marker.
    pub markers: Vec<MarkerRadius>,
}

impl JointFitSummary {
    /// The summary of one joint's fit.
    pub fn of(f: &JointFit) -> Self {
        JointFitSummary {
            joint: f.joint.name().to_string(),
            dof: f.joint.dof(),
            trial: f.trial.clone(),
            estimator: f.estimator.clone(),
            range_of_motion_deg: f.range_of_motion_deg,
            centre_sd_mm: f.centre_sd_mm,
            markers: f
                .markers
                .iter()
                .map(|m| MarkerRadius {
                    marker: m.name.clone(),
                    mean_mm: m.radius_mean,
                    sd_mm: m.radius_sd,
                    frames: m.points.len(),
                })
                .collect(),
        }
    }
}

/// Which optional references the subject folder held (subject-format spec, section 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct References {
    /// `reference.ply`, the CT-like reference skin surface.
    pub reference_ply: bool,
    /// `truth.json`, the ground truth of a simulated subject.
    pub truth_json: bool,
}

/// Everything `validate` measured on one subject (`metrics.json`). Fields that need a
/// reference the subject lacks are `None` (`null` in the JSON): `link` without `truth.json`;
/// `surface`, `surface_regions`, `surface_reverse`, `reference_vertices`, `reference_stride`
/// and `colour_scale_top_mm` without `reference.ply`.
#[derive(Clone, Debug, Serialize)]
pub struct SubjectValidation {
    /// Subject name (`subject.toml`).
    pub subject: String,
    /// Which hand.
    pub hand: Side,
    /// The references found in the subject folder.
    pub references: References,
    /// Joint centres, axes and link lengths against `truth.json` (`None`: no truth).
    pub link: Option<LinkAccuracy>,
    /// The model's own link lengths (`link_model.json`), mm: known for every subject.
    pub link_lengths_mm: BTreeMap<String, f64>,
    /// The link lengths' bootstrap SDs from `link_model.json` (`link_lengths.*.sd_mm`), mm;
    /// empty for a file without them.
    pub link_length_sd_mm: BTreeMap<String, f64>,
    /// `skin.obj`'s vertices to `reference.ply`'s surface (`None`: no reference).
    pub surface: Option<SurfaceError>,
    /// `surface` per anatomical region of the skin, and over the hand distal of the wrist
    /// (`None`: no reference).
    pub surface_regions: Option<SurfaceRegions>,
    /// `reference.ply`'s vertices (every `reference_stride`-th) to `skin.obj`'s surface.
    pub surface_reverse: Option<SurfaceError>,
    /// Vertices of the reference surface.
    pub reference_vertices: Option<usize>,
    /// Stride of the reference vertices measured.
    pub reference_stride: Option<usize>,
    /// Top of the error map's colour scale, mm.
    pub colour_scale_top_mm: Option<f64>,
    /// The caliper dimensions measured on `skin.obj` by their definitions.
    pub dimensions: DimensionAccuracy,
    /// The seed paper's Figures 8-9 in numbers.
    pub joint_fits: Vec<JointFitSummary>,
    /// `reconstruct`'s stage timings (`report.json`), s.
    pub reconstruct_timings_s: BTreeMap<String, f64>,
    /// This command's stage timings, s, in order.
    pub validate_timings_s: Vec<(String, f64)>,
    /// The link model's warnings.
    pub warnings: Vec<String>,
    /// Tracked motions against their truth (`truth_motion/NAME.json`); absent when none was
    /// found.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub motions: Vec<MotionAccuracy>,
    /// The grasps given with `--grasp`, as their `grasp.json` says.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub grasps: Vec<super::grasp_pose_sections::GraspSection>,
    /// The posed hands of the model folder, as their `NAME.pose.json` says.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub poses: Vec<super::grasp_pose_sections::PoseRecord>,
    /// Files written beside `metrics.json` (names).
    pub files: Vec<String>,
    /// The error map at thumbnail size (PNG), for the suite's index (`None`: no reference).
    #[serde(skip)]
    pub thumbnail_png: Option<Vec<u8>>,
}

impl SubjectValidation {
    /// The comparisons against both references, for the callers that need a simulated
    /// subject's (`validate --suite`, the accuracy thresholds, the demo). Errors name
    /// `subject_dir` and the missing file.
    pub fn against_references(&self, subject_dir: &Path) -> Result<(&LinkAccuracy, &SurfaceError)> {
        match (&self.link, &self.surface) {
            (Some(l), Some(s)) => Ok((l, s)),
            (None, _) => Err(Error::input(
                subject_dir.join("truth.json"),
                "missing: needed here to compare the link model with the truth",
            )),
            (_, None) => Err(Error::input(
                subject_dir.join("reference.ply"),
                "missing: needed here to compare the skin with the reference surface",
            )),
        }
    }
}

/// Pictures and charts of a report, in the order the report shows them.
#[derive(Clone, Debug)]
pub struct ReportFigures {
    /// The coloured skin, four views (PNG bytes and file); `None` without `reference.ply`.
    pub error_map: Option<(PathBuf, Vec<u8>)>,
    /// Histograms of both distance directions; `None` without `reference.ply`.
    pub distances: Option<Figure>,
    /// Centre and axis errors per joint; `None` without `truth.json`.
    pub joint_errors: Option<Figure>,
    /// Figure 8, per digit.
    pub fits: Vec<Figure>,
    /// Figure 9.
    pub radii: Figure,
}
