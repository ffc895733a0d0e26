//! `ergohand validate SUBJECT_DIR --model OUT --report DIR`: everything measured on one
//! reconstruction against its subject (issue 9), written as `DIR/metrics.json`, the pictures
//! and charts (PNG and SVG) beside it, the error map as a vertex-coloured GLB, and the person's
//! report `report.html` (self-contained) and `report.md` (linking the pictures).

use super::charts::Figure;
use super::dimension_accuracy::{dimension_accuracy, DimensionAccuracy};
use super::error_map::{
    colour_scale_top, error_map, hand_directions, render_error_views, write_error_map_glb,
};
use super::joint_fit::{joint_fits, JointFit};
use super::joint_fit_plots::{joint_fit_figures, radius_figure};
use super::link_accuracy::{compare, read_joints, LinkAccuracy};
use super::surface_error::SurfaceError;
use crate::anatomy::Side;
use crate::error::{Error, Result};
use crate::io::atomic::write_bytes_atomic;
use crate::io::{obj, ply, Units};
use crate::mocap::subject::Subject;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

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
    /// Every child marker.
    pub markers: Vec<MarkerRadius>,
}

impl JointFitSummary {
    fn of(f: &JointFit) -> Self {
        JointFitSummary {
            joint: f.joint.name().to_string(),
            dof: f.joint.dof(),
            trial: f.trial.clone(),
            estimator: f.estimator.clone(),
            range_of_motion_deg: f.range_of_motion_deg,
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

/// Everything `validate` measured on one subject (`metrics.json`).
#[derive(Clone, Debug, Serialize)]
pub struct SubjectValidation {
    /// Subject name (`subject.toml`).
    pub subject: String,
    /// Which hand.
    pub hand: Side,
    /// Joint centres, axes and link lengths against `truth.json`.
    pub link: LinkAccuracy,
    /// `skin.obj`'s vertices to `reference.ply`'s surface.
    pub surface: SurfaceError,
    /// `reference.ply`'s vertices (every `reference_stride`-th) to `skin.obj`'s surface.
    pub surface_reverse: SurfaceError,
    /// Vertices of the reference surface.
    pub reference_vertices: usize,
    /// Stride of the reference vertices measured.
    pub reference_stride: usize,
    /// Top of the error map's colour scale, mm.
    pub colour_scale_top_mm: f64,
    /// The caliper dimensions measured on `skin.obj`.
    pub dimensions: DimensionAccuracy,
    /// The seed paper's Figures 8-9 in numbers.
    pub joint_fits: Vec<JointFitSummary>,
    /// `reconstruct`'s stage timings (`report.json`), s.
    pub reconstruct_timings_s: BTreeMap<String, f64>,
    /// This command's stage timings, s, in order.
    pub validate_timings_s: Vec<(String, f64)>,
    /// The link model's warnings.
    pub warnings: Vec<String>,
    /// Files written beside `metrics.json` (names).
    pub files: Vec<String>,
    /// The error map at thumbnail size (PNG), for the suite's index.
    #[serde(skip)]
    pub thumbnail_png: Vec<u8>,
}

/// Pictures and charts of a report, in the order the report shows them.
#[derive(Clone, Debug)]
pub struct ReportFigures {
    /// The coloured skin, four views (PNG bytes and file).
    pub error_map: (PathBuf, Vec<u8>),
    /// Histograms of both distance directions.
    pub distances: Figure,
    /// Centre and axis errors per joint.
    pub joint_errors: Figure,
    /// Figure 8, per digit.
    pub fits: Vec<Figure>,
    /// Figure 9.
    pub radii: Figure,
}

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not JSON: {e}")))
}

/// Measure the reconstruction in `model` (a `reconstruct` folder) against the subject in
/// `subject_dir` (with `truth.json` and `reference.ply`) and write the report into `report`.
pub fn validate_subject(
    subject_dir: &Path,
    model: &Path,
    report: &Path,
) -> Result<(SubjectValidation, ReportFigures)> {
    let mut timings: Vec<(String, f64)> = Vec::new();
    let mut t = Instant::now();
    let mut lap = |name: &str, t: &mut Instant| {
        timings.push((name.to_string(), t.elapsed().as_secs_f64()));
        *t = Instant::now();
    };
    let truth_path = subject_dir.join("truth.json");
    if !truth_path.exists() {
        return Err(Error::input(
            &truth_path,
            "missing: only simulated subjects carry truth.json, which validate compares against",
        ));
    }
    let subject = Subject::load(subject_dir)?;
    let model_path = model.join("link_model.json");
    let joints = read_joints(&model_path)?;
    let truth_text = std::fs::read_to_string(&truth_path).map_err(|e| Error::io(&truth_path, e))?;
    let truth: crate::synth::Truth = serde_json::from_str(&truth_text)
        .map_err(|e| Error::input(&truth_path, format!("not a truth file: {e}")))?;
    let link = compare(&joints, &read_joints(&truth_path)?);
    let model_json = read_json(&model_path)?;
    let warnings: Vec<String> = model_json["warnings"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|w| w.as_str().map(String::from))
                .collect()
        })
        .unwrap_or_default();
    let recon = model.join("report.json");
    let reconstruct_timings_s: BTreeMap<String, f64> = if recon.exists() {
        read_json(&recon)?["timings_s"]
            .as_object()
            .map(|o| {
                o.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.as_f64()?)))
                    .collect()
            })
            .unwrap_or_default()
    } else {
        BTreeMap::new()
    };
    let skin_path = model.join("skin.obj");
    let skin = obj::read_obj(&skin_path, Units::Millimetres)?;
    let reference = ply::read_ply(&subject_dir.join("reference.ply"), Units::Millimetres)?.mesh;
    lap("read inputs", &mut t);

    // The two largest jobs are independent: the distances (reference.ply has about 1.7 M
    // faces) and the trajectories (seven trials read again).
    let (map, fits) = rayon::join(
        || error_map(&skin, &reference),
        || joint_fits(&subject, &joints, &model_path),
    );
    let fits = fits?;
    drop(reference);
    let dimensions = dimension_accuracy(
        &skin,
        &skin_path,
        subject.hand,
        &subject.dimensions,
        Some(&truth.dimensions),
    )?;
    lap("error map (both directions) and joint trajectories", &mut t);

    std::fs::create_dir_all(report).map_err(|e| Error::io(report, e))?;
    let top = colour_scale_top(&map.skin_to_reference);
    let dirs = hand_directions(&joints, &model_path)?;
    let title = format!(
        "{}: distance of skin.obj to reference.ply (mean {:.2} mm, 95th percentile {:.2} mm, max {:.2} mm)",
        subject.name,
        map.skin_to_reference_stats.mean_mm,
        map.skin_to_reference_stats.p95_mm,
        map.skin_to_reference_stats.max_mm
    );
    let views = render_error_views(&skin, &map.skin_to_reference, dirs, top, &title, 300, 4)?;
    let map_png = views.to_png()?;
    let map_path = report.join("error-map.png");
    write_bytes_atomic(&map_path, &map_png)?;
    let thumb = render_error_views(&skin, &map.skin_to_reference, dirs, top, "", 100, 2)?;
    let thumbnail_png = thumb.to_png()?;
    write_bytes_atomic(&report.join("error-map-small.png"), &thumbnail_png)?;
    write_error_map_glb(
        &report.join("error-map.glb"),
        &skin,
        &map.skin_to_reference,
        top,
    )?;
    lap("error map pictures and GLB", &mut t);

    let distances = super::distance_plots::distance_histograms(&map, report)?;
    let joint_errors = super::joint_error_plots::joint_error_figure(&link, report)?;
    let fit_figures = joint_fit_figures(&fits, report)?;
    let radii = radius_figure(&fits, report)?;
    lap("charts (PNG and SVG)", &mut t);

    let figures = ReportFigures {
        error_map: (map_path, map_png),
        distances,
        joint_errors,
        fits: fit_figures,
        radii,
    };
    let mut files: Vec<String> = vec![
        "metrics.json".into(),
        "report.html".into(),
        "report.md".into(),
        "error-map.png".into(),
        "error-map-small.png".into(),
        "error-map.glb".into(),
    ];
    for f in [&figures.distances, &figures.joint_errors]
        .into_iter()
        .chain(&figures.fits)
        .chain(std::iter::once(&figures.radii))
    {
        for p in [&f.png, &f.svg] {
            files.push(p.file_name().unwrap_or_default().to_string_lossy().into());
        }
    }
    let mut v = SubjectValidation {
        subject: subject.name.clone(),
        hand: subject.hand,
        link,
        surface: map.skin_to_reference_stats.clone(),
        surface_reverse: map.reference_to_skin_stats.clone(),
        reference_vertices: map.reference_vertices,
        reference_stride: map.reference_stride,
        colour_scale_top_mm: top,
        dimensions,
        joint_fits: fits.iter().map(JointFitSummary::of).collect(),
        reconstruct_timings_s,
        validate_timings_s: Vec::new(),
        warnings,
        files,
        thumbnail_png,
    };
    // The report's own time goes into the report: write it last, after measuring.
    let html = super::report_html::subject_html(&v, &figures);
    let md = super::report_md::subject_markdown(&v, &figures);
    lap("report.html and report.md", &mut t);
    v.validate_timings_s = timings;
    let html = html.replace(
        super::report_html::RUNTIME_PLACEHOLDER,
        &super::report_html::runtime_html(&v),
    );
    let md = md.replace(
        super::report_md::RUNTIME_PLACEHOLDER,
        &super::report_md::runtime_markdown(&v),
    );
    write_bytes_atomic(&report.join("report.html"), html.as_bytes())?;
    write_bytes_atomic(&report.join("report.md"), md.as_bytes())?;
    let json = serde_json::to_string_pretty(&v).expect("serialisable");
    write_bytes_atomic(&report.join("metrics.json"), json.as_bytes())?;
    Ok((v, figures))
}
