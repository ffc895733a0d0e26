//! `ergohand validate SUBJECT_DIR --model OUT --report DIR`: everything measured on one
//! reconstruction against its subject, written as `DIR/metrics.json`, the pictures
//! and charts (PNG and SVG) beside it, the error map as a vertex-coloured GLB, and the person's
//! report `report.html` (self-contained) and `report.md` (linking the pictures).
//!
//! Both references are optional (subject-format spec, section 1): a real subject has no
//! `truth.json` and may have no `reference.ply`. What needs a missing reference is skipped —
//! `null` in `metrics.json`, one sentence in the report saying why — and everything else (the
//! caliper dimensions of `subject.toml`, the joint fits of the seed paper's Figures 8-9, the
//! model's link lengths, runtimes, warnings) is reported as for a simulated subject.

use super::dimension_accuracy::{dimension_accuracy, DimensionAccuracy};
use super::error_map::{
    colour_scale_top, error_map, error_map_glb, hand_directions, render_error_views, ErrorMap,
};
use super::joint_fit::{joint_fits, JointFit};
use super::joint_fit_plots::{joint_fit_figures, radius_figure};
use super::link_accuracy::{link_lengths, LinkAccuracy};
use super::model_inputs::ModelInputs;
pub use super::model_inputs::VIEW_FILE;
pub use super::model_inputs::{check_reference_scale, REFERENCE_SCALE_RATIO};
use super::subject_validation::{JointFitSummary, ReportFigures, SubjectValidation};
use super::surface_regions::{model_regions, surface_regions, SurfaceRegions};
use super::view_page::{view_html, ViewFrame};
use crate::anatomy::landmark_names;
use crate::error::Result;
use crate::io::atomic::write_bytes_atomic;
use crate::measure::landmarks_on_skin;
use crate::mocap::subject::TrialKind;
use crate::skeleton::record::skeleton_from_records;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Measure the reconstruction in `model` (a `reconstruct` folder) against the subject in
/// `subject_dir` (with `truth.json` and `reference.ply` when it has them: each is optional,
/// and what needs a missing one is skipped) and write the report into `report`.
pub fn validate_subject(
    subject_dir: &Path,
    model: &Path,
    report: &Path,
) -> Result<(SubjectValidation, ReportFigures)> {
    validate_subject_with(subject_dir, model, report, &[], &[])
}

/// [`validate_subject`], with the tracked motions of the folders `motions` scored against the
/// subject's motion truths as well as those found in `model/motions/NAME/`
/// ([`super::motion_accuracy::subject_motions`]), and the grasp output folders `grasps` (and
/// the posed hands of the model folder, `NAME.pose.json`) reported as written.
pub fn validate_subject_with(
    subject_dir: &Path,
    model: &Path,
    report: &Path,
    motions: &[PathBuf],
    grasps: &[PathBuf],
) -> Result<(SubjectValidation, ReportFigures)> {
    let mut timings: Vec<(String, f64)> = Vec::new();
    let mut t = Instant::now();
    let mut lap = |name: &str, t: &mut Instant| {
        timings.push((name.to_string(), t.elapsed().as_secs_f64()));
        *t = Instant::now();
    };
    let mut inputs = ModelInputs::read(subject_dir, model, report)?;
    // The other commands' outputs are read before any work: a bad one stops the run early.
    let grasp_sections = grasps
        .iter()
        .map(|g| super::grasp_pose_sections::read_grasp_section(g))
        .collect::<Result<Vec<_>>>()?;
    let poses = super::grasp_pose_sections::model_poses(model)?;
    lap("read inputs", &mut t);

    let measured = measure(&mut inputs, model)?;
    lap(
        if measured.map.is_some() {
            "error map (both directions) and joint trajectories"
        } else {
            "joint trajectories"
        },
        &mut t,
    );

    let _held = crate::io::atomic::FolderLock::acquire(report)?;
    let map_pictures = match &measured.map {
        Some(map) => {
            let p = error_map_pictures(
                &inputs.subject.name,
                map,
                &inputs.skin,
                &inputs.joints,
                &inputs.model_path,
                report,
            )?;
            lap("error map pictures and GLB", &mut t);
            Some(p)
        }
        None => None,
    };
    let page_map = map_pictures
        .as_ref()
        .map(|p| (p.glb.clone(), p.top, p.frame));
    let (figures, thumbnail_png, top) = charts(&measured, map_pictures, report)?;
    lap("charts (PNG and SVG)", &mut t);
    let motions = super::motion_accuracy::subject_motions(subject_dir, model, motions)?;
    if !motions.is_empty() {
        lap("tracked motions", &mut t);
    }

    let mut v = summary(inputs, measured, &figures, thumbnail_png, top);
    v.motions = motions;
    v.grasps = grasp_sections;
    v.poses = poses;
    // The report's own time goes into the report: write it last, after measuring.
    let html = super::report_html::subject_html(&v, &figures, report);
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
    // The 3-D page of the error map; none without a reference surface (nothing to colour).
    let page = report.join(VIEW_FILE);
    match page_map {
        Some((glb, top, frame)) => {
            let html = view_html(&super::pages::validate_page(&v, glb, top, frame));
            write_bytes_atomic(&page, html.as_bytes())?;
        }
        None if page.is_file() => {
            std::fs::remove_file(&page).map_err(|e| crate::error::Error::io(&page, e))?
        }
        None => {}
    }
    Ok((v, figures))
}

/// What [`measure`] found.
struct Measured {
    /// The skin's distances to the reference and back, when the subject has a reference.
    map: Option<ErrorMap>,
    regions: Option<SurfaceRegions>,
    fits: Vec<JointFit>,
    dimensions: DimensionAccuracy,
    link: Option<LinkAccuracy>,
}

/// The measurements: distances and their regions, the joint fits of the trials, the calipers on
/// the skin and the joint centres against the truth. The reference surface is dropped from
/// `inputs` once measured (it is the largest thing held).
fn measure(inputs: &mut ModelInputs, model: &Path) -> Result<Measured> {
    let reference = inputs.reference.take();
    let (skin, subject) = (&inputs.skin, &inputs.subject);
    // The two largest jobs are independent: the distances (reference.ply has about 1.7 M
    // faces) and the trajectories (seven trials read again).
    let (map, fits) = rayon::join(
        || reference.as_ref().map(|r| error_map(skin, r)),
        || joint_fits(subject, &inputs.joints, &inputs.model_path),
    );
    let fits = fits?;
    drop(reference);
    let regions = map
        .as_ref()
        .map(|m| -> Result<SurfaceRegions> {
            surface_regions(
                &m.skin_to_reference,
                Some((&m.reference_to_skin, &m.reference_nearest_skin_vertex)),
                &model_regions(model, subject.hand)?,
                &inputs.skin_path,
            )
        })
        .transpose()?;
    // The calipers on the skin: the model's joints, and the landmarks where the static trial's
    // markers meet the skin.
    let skeleton = skeleton_from_records(&inputs.joints, subject.hand, &inputs.model_path)?;
    let reference_trial = subject.load_trial(TrialKind::Reference)?;
    let markers = reference_trial.mean_positions(&landmark_names());
    let dimensions = dimension_accuracy(
        skin,
        &skeleton,
        &landmarks_on_skin(skin, &markers),
        &subject.dimensions,
        inputs.truth.as_ref().map(|t| &t.0.dimensions),
    );
    let link = inputs.truth.take().map(|t| t.1);
    Ok(Measured {
        map,
        regions,
        fits,
        dimensions,
        link,
    })
}

/// The charts in `report` (PNG and SVG) and the figures the report shows; with the error map's
/// thumbnail and colour-scale top when there is a map.
fn charts(
    measured: &Measured,
    map_pictures: Option<ErrorMapPictures>,
    report: &Path,
) -> Result<(ReportFigures, Option<Vec<u8>>, Option<f64>)> {
    let distances = measured
        .map
        .as_ref()
        .map(|m| super::distance_plots::distance_histograms(m, report))
        .transpose()?;
    let joint_errors = measured
        .link
        .as_ref()
        .map(|l| super::joint_error_plots::joint_error_figure(l, report))
        .transpose()?;
    let fit_figures = joint_fit_figures(&measured.fits, report)?;
    let radii = radius_figure(&measured.fits, report)?;
    let (error_map_png, thumbnail_png, top) = match map_pictures {
        Some(p) => (Some(p.picture), Some(p.thumbnail_png), Some(p.top)),
        None => (None, None, None),
    };
    let figures = ReportFigures {
        error_map: error_map_png,
        distances,
        joint_errors,
        fits: fit_figures,
        radii,
    };
    Ok((figures, thumbnail_png, top))
}

/// `metrics.json`'s content (the report's runtimes are added by the caller, last).
fn summary(
    inputs: ModelInputs,
    measured: Measured,
    figures: &ReportFigures,
    thumbnail_png: Option<Vec<u8>>,
    top: Option<f64>,
) -> SubjectValidation {
    let mut files: Vec<String> = vec![
        "metrics.json".into(),
        "report.html".into(),
        "report.md".into(),
    ];
    if measured.map.is_some() {
        files.extend(
            [
                "error-map.png",
                "error-map-small.png",
                "error-map.glb",
                VIEW_FILE,
            ]
            .map(String::from),
        );
    }
    for f in figures
        .distances
        .iter()
        .chain(&figures.joint_errors)
        .chain(&figures.fits)
        .chain(std::iter::once(&figures.radii))
    {
        for p in [&f.png, &f.svg] {
            files.push(p.file_name().unwrap_or_default().to_string_lossy().into());
        }
    }
    let map = measured.map.as_ref();
    SubjectValidation {
        subject: inputs.subject.name.clone(),
        hand: inputs.subject.hand,
        references: inputs.references,
        link: measured.link,
        link_lengths_mm: link_lengths(&inputs.joints),
        link_length_sd_mm: inputs.link_length_sd_mm,
        surface: map.map(|m| m.skin_to_reference_stats.clone()),
        surface_regions: measured.regions,
        surface_reverse: map.map(|m| m.reference_to_skin_stats.clone()),
        reference_vertices: map.map(|m| m.reference_vertices),
        reference_stride: map.map(|m| m.reference_stride),
        colour_scale_top_mm: top,
        dimensions: measured.dimensions,
        joint_fits: measured.fits.iter().map(JointFitSummary::of).collect(),
        reconstruct_timings_s: inputs.reconstruct_timings_s,
        validate_timings_s: Vec::new(),
        warnings: inputs.warnings,
        motions: Vec::new(),
        grasps: Vec::new(),
        poses: Vec::new(),
        files,
        thumbnail_png,
    }
}

/// What [`error_map_pictures`] made.
struct ErrorMapPictures {
    /// `error-map.png`: file and PNG bytes.
    picture: (PathBuf, Vec<u8>),
    /// `error-map-small.png`'s bytes.
    thumbnail_png: Vec<u8>,
    /// Top of the colour scale, mm.
    top: f64,
    /// `error-map.glb`'s bytes.
    glb: Vec<u8>,
    /// The hand's frame (wrist centre; dorsal, radial, distal) for the 3-D page's views.
    frame: ViewFrame,
}

/// The error map's pictures in `report`: `error-map.png` (four views, with the statistics in
/// the title), `error-map-small.png` (the suite's thumbnail) and `error-map.glb` (the skin
/// with vertex colours).
fn error_map_pictures(
    name: &str,
    map: &ErrorMap,
    skin: &crate::geometry::TriMesh,
    joints: &BTreeMap<String, crate::skeleton::record::JointRecord>,
    model_path: &Path,
    report: &Path,
) -> Result<ErrorMapPictures> {
    let top = colour_scale_top(&map.skin_to_reference);
    let dirs = hand_directions(joints, model_path)?;
    let title = format!(
        "{}: distance of skin.obj to reference.ply (mean {:.2} mm, 95th percentile {:.2} mm, max {:.2} mm)",
        name,
        map.skin_to_reference_stats.mean_mm,
        map.skin_to_reference_stats.p95_mm,
        map.skin_to_reference_stats.max_mm
    );
    let views = render_error_views(skin, &map.skin_to_reference, dirs, top, &title, 300, 4)?;
    let map_png = views.to_png()?;
    let map_path = report.join("error-map.png");
    write_bytes_atomic(&map_path, &map_png)?;
    let thumb = render_error_views(skin, &map.skin_to_reference, dirs, top, "", 100, 2)?;
    let thumbnail_png = thumb.to_png()?;
    write_bytes_atomic(&report.join("error-map-small.png"), &thumbnail_png)?;
    let glb = error_map_glb(skin, &map.skin_to_reference, top)?;
    write_bytes_atomic(&report.join("error-map.glb"), &glb)?;
    let wrist = joints
        .get(crate::anatomy::Joint::Wrist.name())
        .map_or([0.0; 3], |w| w.centre);
    Ok(ErrorMapPictures {
        picture: (map_path, map_png),
        thumbnail_png,
        top,
        glb,
        frame: ViewFrame {
            origin: crate::geometry::Point::new(wrist[0], wrist[1], wrist[2]),
            dorsal: dirs.0,
            radial: dirs.2,
            distal: dirs.1,
        },
    })
}
