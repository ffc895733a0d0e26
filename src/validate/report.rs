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

use super::dimension_accuracy::dimension_accuracy;
use super::error_map::{
    colour_scale_top, error_map, hand_directions, render_error_views, write_error_map_glb,
};
use super::joint_fit::joint_fits;
use super::joint_fit_plots::{joint_fit_figures, radius_figure};
use super::link_accuracy::{compare, link_lengths, read_joints, read_truth};
use super::subject_validation::{JointFitSummary, References, ReportFigures, SubjectValidation};
use super::surface_regions::{model_regions, surface_regions, SurfaceRegions};
use crate::anatomy::landmark_names;
use crate::error::{Error, Result};
use crate::geometry::TriMesh;
use crate::io::atomic::write_bytes_atomic;
use crate::io::{obj, ply, Units};
use crate::measure::landmarks_on_skin;
use crate::mocap::subject::Subject;
use crate::mocap::subject::TrialKind;
use crate::skeleton::record::skeleton_from_records;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

fn read_json(path: &Path) -> Result<serde_json::Value> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not JSON: {e}")))
}

/// Largest ratio between the bounding-box diagonals of `reference.ply` and `skin.obj` that a
/// reference of the same hand can have (a scan cut at another place of the forearm differs by
/// tens of percent, a wrong unit by 10 to 1000 times).
pub const REFERENCE_SCALE_RATIO: f64 = 3.0;

/// Check that the reference surface (read as mm) is the size of the reconstructed skin: the
/// ratio of their bounding-box diagonals within 1/[`REFERENCE_SCALE_RATIO`] to
/// [`REFERENCE_SCALE_RATIO`], else an error naming `path` and the unit its numbers look like
/// (the one of m, cm, in, mm that brings the ratio nearest 1).
pub fn check_reference_scale(reference: &TriMesh, skin: &TriMesh, path: &Path) -> Result<()> {
    let (r, s) = (reference.diagonal(), skin.diagonal());
    if !(r > 0.0 && s > 0.0) {
        return Ok(());
    }
    let ratio = r / s;
    if (1.0 / REFERENCE_SCALE_RATIO..=REFERENCE_SCALE_RATIO).contains(&ratio) {
        return Ok(());
    }
    // The reference's numbers, read in a unit u, should measure the skin's diagonal.
    let likely = Units::likely(r, s);
    Err(Error::input(
        path,
        format!(
            "the surface is {r:.3} mm across (read as mm) where skin.obj is {s:.1} mm; its \
             numbers look like {likely}: convert it to mm"
        ),
    ))
}

/// Measure the reconstruction in `model` (a `reconstruct` folder) against the subject in
/// `subject_dir` (with `truth.json` and `reference.ply` when it has them: each is optional,
/// and what needs a missing one is skipped) and write the report into `report`.
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
    let reference_path = subject_dir.join("reference.ply");
    let references = References {
        reference_ply: reference_path.exists(),
        truth_json: truth_path.exists(),
    };
    let subject = Subject::load(subject_dir)?;
    let inputs = crate::io::output_paths::Inputs::files(
        [
            subject.toml_path(),
            truth_path.clone(),
            reference_path.clone(),
        ]
        .into_iter()
        .chain(subject.trials.values().map(|p| subject.dir.join(p))),
    )
    .with_model(model);
    crate::io::output_paths::check_output_dir(
        report,
        &["metrics.json", "report.html", "report.md", "error-map.png"],
        "--report",
        &inputs,
    )?;
    let model_path = model.join("link_model.json");
    let joints = read_joints(&model_path)?;
    let truth = if references.truth_json {
        let truth = read_truth(&truth_path)?;
        let link = compare(&joints, &truth.joints);
        Some((truth, link))
    } else {
        None
    };
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
    let reference = if references.reference_ply {
        let r = ply::read_ply(&reference_path, Units::Millimetres)?.mesh;
        check_reference_scale(&r, &skin, &reference_path)?;
        Some(r)
    } else {
        None
    };
    lap("read inputs", &mut t);

    // The two largest jobs are independent: the distances (reference.ply has about 1.7 M
    // faces) and the trajectories (seven trials read again).
    let (map, fits) = rayon::join(
        || reference.as_ref().map(|r| error_map(&skin, r)),
        || joint_fits(&subject, &joints, &model_path),
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
                &skin_path,
            )
        })
        .transpose()?;
    // The calipers on the skin: the model's joints, and the landmarks where the static trial's
    // markers meet the skin.
    let skeleton = skeleton_from_records(&joints, subject.hand, &model_path)?;
    let reference_trial = subject.load_trial(TrialKind::Reference)?;
    let markers = reference_trial.mean_positions(&landmark_names());
    let dimensions = dimension_accuracy(
        &skin,
        &skeleton,
        &landmarks_on_skin(&skin, &markers),
        &subject.dimensions,
        truth.as_ref().map(|t| &t.0.dimensions),
    );
    let link = truth.map(|t| t.1);
    lap(
        if map.is_some() {
            "error map (both directions) and joint trajectories"
        } else {
            "joint trajectories"
        },
        &mut t,
    );

    std::fs::create_dir_all(report).map_err(|e| Error::io(report, e))?;
    let mut files: Vec<String> = vec![
        "metrics.json".into(),
        "report.html".into(),
        "report.md".into(),
    ];
    let mut map_pictures = None;
    if let Some(map) = &map {
        map_pictures = Some(error_map_pictures(
            &subject.name,
            map,
            &skin,
            &joints,
            &model_path,
            report,
        )?);
        files.extend(["error-map.png", "error-map-small.png", "error-map.glb"].map(String::from));
        lap("error map pictures and GLB", &mut t);
    }

    let distances = map
        .as_ref()
        .map(|m| super::distance_plots::distance_histograms(m, report))
        .transpose()?;
    let joint_errors = link
        .as_ref()
        .map(|l| super::joint_error_plots::joint_error_figure(l, report))
        .transpose()?;
    let fit_figures = joint_fit_figures(&fits, report)?;
    let radii = radius_figure(&fits, report)?;
    lap("charts (PNG and SVG)", &mut t);

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
    let mut v = SubjectValidation {
        subject: subject.name.clone(),
        hand: subject.hand,
        references,
        link,
        link_lengths_mm: link_lengths(&joints),
        link_length_sd_mm: model_json
            .get("link_lengths")
            .and_then(|l| l.as_object())
            .map(|l| {
                l.iter()
                    .filter_map(|(k, v)| Some((k.clone(), v.get("sd_mm")?.as_f64()?)))
                    .collect()
            })
            .unwrap_or_default(),
        surface: map.as_ref().map(|m| m.skin_to_reference_stats.clone()),
        surface_regions: regions,
        surface_reverse: map.as_ref().map(|m| m.reference_to_skin_stats.clone()),
        reference_vertices: map.as_ref().map(|m| m.reference_vertices),
        reference_stride: map.as_ref().map(|m| m.reference_stride),
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

/// What [`error_map_pictures`] made.
struct ErrorMapPictures {
    /// `error-map.png`: file and PNG bytes.
    picture: (PathBuf, Vec<u8>),
    /// `error-map-small.png`'s bytes.
    thumbnail_png: Vec<u8>,
    /// Top of the colour scale, mm.
    top: f64,
}

/// The error map's pictures in `report`: `error-map.png` (four views, with the statistics in
/// the title), `error-map-small.png` (the suite's thumbnail) and `error-map.glb` (the skin
/// with vertex colours).
fn error_map_pictures(
    name: &str,
    map: &super::error_map::ErrorMap,
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
    write_error_map_glb(
        &report.join("error-map.glb"),
        skin,
        &map.skin_to_reference,
        top,
    )?;
    Ok(ErrorMapPictures {
        picture: (map_path, map_png),
        thumbnail_png,
        top,
    })
}
