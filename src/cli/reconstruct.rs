//! `ergohand reconstruct`: the stages of the seed paper run on one subject folder, and the
//! model folder they write (spec section 3).

use super::{create_dir, Voice};
use crate::anatomy::Side;
use crate::error::{Error, Result};
use crate::io::output_paths::{check_output_dir, Inputs, MODEL_FILES};
use crate::io::{atomic, obj, Units};
use crate::skin::pipeline::{FitResolution, SkinOptions};
use crate::template;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What `reconstruct` writes in `report.json`.
#[derive(serde::Serialize)]
struct ReconstructReport {
    subject: String,
    hand: Side,
    stages_run: Vec<&'static str>,
    stages_not_built: Vec<&'static str>,
    timings_s: std::collections::BTreeMap<&'static str, f64>,
    warnings: Vec<String>,
    skin: SkinSummary,
    tet: crate::tet::TetReport,
    /// [`reconstruct_fingerprint`] of the inputs this folder was made from (an extension of
    /// the spec's outputs; `batch` compares it to decide what is up to date).
    inputs_fnv1a: String,
}

/// The content fingerprint ([`crate::io::fingerprint`]) of a reconstruction's inputs:
/// `subject.toml`, every trial it names, and the skin options.
pub fn reconstruct_fingerprint(
    subject: &crate::mocap::subject::Subject,
    opts: &SkinOptions,
) -> Result<String> {
    let files: Vec<PathBuf> = std::iter::once(subject.toml_path())
        .chain(subject.trials.values().map(|p| subject.dir.join(p)))
        .collect();
    crate::io::fingerprint::inputs_fingerprint(&files, &format!("{opts:?}"))
}

/// The skin stage's part of `report.json`.
#[derive(serde::Serialize)]
struct SkinSummary {
    fit_resolution: crate::skin::pipeline::FitResolution,
    template_posed: bool,
    centre_weight: f64,
    /// The shape prior used (`null`: none, the template's shape where nothing reaches).
    shape_prior: Option<String>,
    iterations: usize,
    converged: bool,
    /// The template's posture found before the fit, degrees per joint `[flexion, abduction,
    /// axial]` (1-DOF joints: `[angle, 0, 0]`), relative to the template's reference posture.
    posture_deg: Option<std::collections::BTreeMap<String, [f64; 3]>>,
    posture_direction_residual_deg: Option<std::collections::BTreeMap<String, f64>>,
    landmark_residuals_mm: std::collections::BTreeMap<String, f64>,
    /// The fit's caliper constraints: distance of each dimension's template vertex pair minus
    /// the given value, mm. Not the dimensions by their definitions (`validate` measures those).
    caliper_pair_residuals_mm: std::collections::BTreeMap<String, f64>,
    /// Each dimension read on skin.obj by the spec's definition (sections at the link model's
    /// joints, landmarks under the static trial's markers) minus the given value, mm.
    caliper_residuals_mm: std::collections::BTreeMap<String, f64>,
    /// Caliper rounds the skin fit took (re-fits correcting the pairs' lengths).
    caliper_rounds: usize,
    centre_residuals_mm: std::collections::BTreeMap<String, f64>,
    /// Section 3.6: shift of each 1-DOF centre along its axis onto the skin, mm.
    section_3_6_shift_mm: std::collections::BTreeMap<String, f64>,
    inverted_faces: usize,
    degenerate_faces: usize,
}

/// Skin options from the command line's values; an error naming `--centre-weight` unless it is
/// a finite weight >= 0.
pub fn skin_options(
    resolution: FitResolution,
    pose_template: bool,
    centre_weight: f64,
) -> Result<SkinOptions> {
    if !(centre_weight.is_finite() && centre_weight >= 0.0) {
        return Err(Error::invalid(format!(
            "--centre-weight {centre_weight}: give a finite weight >= 0 (0 turns the centre terms off)"
        )));
    }
    Ok(SkinOptions {
        resolution,
        pose_template,
        centre_weight,
        ..SkinOptions::default()
    })
}

/// The skin's shape prior from `--shape-prior`: none when absent or `none`, the shipped one
/// for `builtin`, else the file (an error naming it when it is not a prior).
pub fn shape_prior_option(
    arg: Option<&Path>,
) -> Result<Option<std::sync::Arc<crate::skin::shape_prior::ShapePrior>>> {
    use crate::skin::shape_prior::ShapePrior;
    match arg {
        None => Ok(None),
        Some(p) if p == Path::new("none") => Ok(None),
        Some(p) if p == Path::new("builtin") => Ok(Some(ShapePrior::builtin())),
        Some(p) => Ok(Some(std::sync::Arc::new(ShapePrior::from_json(
            &atomic::read_bytes(p)?,
            p,
        )?))),
    }
}

/// `ergohand reconstruct SUBJECT_DIR --out OUT` with the default skin options.
pub fn reconstruct(subject_dir: &Path, out: &Path) -> Result<crate::link::LinkModel> {
    reconstruct_with(subject_dir, out, &SkinOptions::default())
}

/// `ergohand reconstruct SUBJECT_DIR --out OUT`: the pipeline of the seed paper: the link
/// model (section 3.4), the skin (3.5, with the template first posed onto the link model and
/// joint-centre terms), section 3.6 applied to the link model, the tetrahedral mesh (3.7) and
/// the skinned hand; writes the seven files of [`MODEL_FILES`] (`link_model.json`,
/// `skin_low.obj`, `skin.obj`, `tet.vtk`, `tet.msh`, `hand.glb`, `report.json`). Nothing is
/// written unless every stage succeeds.
pub fn reconstruct_with(
    subject_dir: &Path,
    out: &Path,
    opts: &SkinOptions,
) -> Result<crate::link::LinkModel> {
    reconstruct_prepared(subject_dir, out, opts, None)
}

/// [`reconstruct_with`] with the template's section 3.7 work done beforehand: a batch prepares
/// one [`crate::tet::TemplateTet`] per hand and shares it. With `None` it is prepared here, on a
/// second thread while the link model and the skin are fitted. A prepared template of the other
/// hand is an error naming the subject.
pub fn reconstruct_prepared(
    subject_dir: &Path,
    out: &Path,
    opts: &SkinOptions,
    prepared: Option<&crate::tet::TemplateTet>,
) -> Result<crate::link::LinkModel> {
    reconstruct_job(subject_dir, out, opts, prepared, Voice::Command)
}

/// [`reconstruct_prepared`], speaking with `voice`.
pub(crate) fn reconstruct_job(
    subject_dir: &Path,
    out: &Path,
    opts: &SkinOptions,
    prepared: Option<&crate::tet::TemplateTet>,
    voice: Voice,
) -> Result<crate::link::LinkModel> {
    let t0 = Instant::now();
    let subject = crate::mocap::subject::Subject::load(subject_dir)?;
    let inputs = Inputs::files(
        std::iter::once(subject.toml_path())
            .chain(subject.trials.values().map(|p| subject.dir.join(p))),
    );
    check_output_dir(out, &MODEL_FILES, "--out", &inputs)?;
    let template = template::load_template(subject.hand)?;
    if let Some(p) = prepared {
        if p.side != subject.hand {
            return Err(Error::invalid(format!(
                "{}: a {} hand, but the prepared tetrahedral template is of the {} hand",
                subject_dir.display(),
                subject.hand,
                p.side
            )));
        }
        let shared = || Ok((TetSource::Shared(p), 0.0));
        return reconstruct_stages(&subject, &template, shared, out, opts, voice, t0);
    }
    // Section 3.7's template-only work (tet mesh from the cache, binding, factorisation) needs
    // nothing of the subject: it runs on a second thread while the link model and the skin are
    // fitted.
    std::thread::scope(|scope| {
        let handle = scope.spawn(|| {
            let t = Instant::now();
            crate::tet::TemplateTet::prepare(&template, None).map(|p| (p, t.elapsed()))
        });
        let joined = || {
            let (p, d) = handle
                .join()
                .map_err(|_| Error::invalid("tet: the template preparation thread panicked"))??;
            Ok((TetSource::Own(Box::new(p)), d.as_secs_f64()))
        };
        reconstruct_stages(&subject, &template, joined, out, opts, voice, t0)
    })
}

/// The template's prepared tet stage, shared by a batch or made for one subject.
enum TetSource<'a> {
    Shared(&'a crate::tet::TemplateTet),
    Own(Box<crate::tet::TemplateTet>),
}

impl std::ops::Deref for TetSource<'_> {
    type Target = crate::tet::TemplateTet;
    fn deref(&self) -> &Self::Target {
        match self {
            TetSource::Shared(p) => p,
            TetSource::Own(p) => p,
        }
    }
}

/// The stages of [`reconstruct_prepared`] after loading; `prepared_tet` hands over (or waits
/// for) the template's prepared tet stage and the seconds its preparation took.
fn reconstruct_stages<'p>(
    subject: &crate::mocap::subject::Subject,
    template: &template::TemplateHand,
    prepared_tet: impl FnOnce() -> Result<(TetSource<'p>, f64)>,
    out: &Path,
    opts: &SkinOptions,
    voice: Voice,
    t0: Instant,
) -> Result<crate::link::LinkModel> {
    log::log!(
        voice.info(),
        "reconstruct {}: link model from 7 trials",
        subject.name
    );
    // Fingerprinted before anything is read, so the record never claims newer inputs.
    let inputs_fnv1a = reconstruct_fingerprint(subject, opts)?;
    let model = crate::link::estimate_link_model(subject)?;
    let t_link = t0.elapsed().as_secs_f64();
    for w in &model.warnings {
        log::log!(voice.warn(), "{w}");
    }
    let t1 = Instant::now();
    let reference = subject.load_trial(crate::mocap::subject::TrialKind::Reference)?;
    let skin = crate::skin::pipeline::fit_skin(
        template,
        &reference,
        &subject.dimensions,
        subject.marker_offset_mm,
        Some(&model),
        opts,
    )?;
    // Section 3.6: 1-DOF centres onto the skin's cross-section.
    let pairs = crate::skin::section_centre::edge_pairs(template)?;
    let (centred, shifts) =
        crate::skin::section_centre::centre_on_cross_section(&model.skeleton, &skin.high, &pairs);
    let model = model.with_skin_centres(&centred, &shifts);
    let t_skin = t1.elapsed().as_secs_f64();
    for w in &skin.warnings {
        log::log!(voice.warn(), "{w}");
    }
    // Section 3.7: the template's tetrahedral mesh (cached) carried to the subject.
    let t2 = Instant::now();
    log::log!(
        voice.info(),
        "tet: template tetrahedral mesh (cached after the first run), elastic deformation"
    );
    let (template_tet, t_prepare) = prepared_tet()?;
    let (tet, tet_report) = template_tet.deform(&skin.high)?;
    let t_tet = t2.elapsed().as_secs_f64();
    // The skinned individual hand.
    let t3 = Instant::now();
    let hand = crate::pose::IndividualHand::from_skin(
        template,
        skin.high.clone(),
        model.skeleton.clone(),
        crate::pose::WeightMethod::default(),
    )?;
    let scene =
        crate::pose::gltf::skinned_scene("hand", &hand.skin, &hand.weights, &hand.skeleton, None);
    let t_hand = t3.elapsed().as_secs_f64();
    create_dir(out)?;
    model.write(&out.join("link_model.json"))?;
    obj::write_obj(
        &out.join("skin_low.obj"),
        &skin.low,
        Units::Millimetres,
        None,
    )?;
    obj::write_obj(&out.join("skin.obj"), &skin.high, Units::Millimetres, None)?;
    crate::io::vtk::write_vtk(&out.join("tet.vtk"), &tet, Units::Millimetres)?;
    crate::io::gmsh::write_msh(&out.join("tet.msh"), &tet, Units::Millimetres)?;
    crate::io::gltf::write_glb(&out.join("hand.glb"), &scene, Units::Metres)?;
    let mut warnings = model.warnings.clone();
    warnings.extend(skin.warnings.iter().cloned());
    // An inverted element is a suspect model: said loudly, never only counted.
    let inverted_tets = tet.inverted_count();
    if inverted_tets > 0 {
        let w = format!(
            "tet.vtk: {inverted_tets} of {} tetrahedra are inverted (negative volume); the skin may fold where the template could not follow the subject",
            tet.n_tets()
        );
        log::log!(voice.warn(), "{w}");
        warnings.push(w);
    }
    let report = ReconstructReport {
        subject: subject.name.clone(),
        hand: subject.hand,
        stages_run: vec!["link", "skin", "section 3.6", "tet", "hand"],
        stages_not_built: vec![],
        timings_s: [
            ("link", t_link),
            ("skin", t_skin),
            ("tet", t_tet),
            ("tet_template_prepare_parallel", t_prepare),
            ("hand", t_hand),
        ]
        .into_iter()
        .collect(),
        tet: tet_report,
        inputs_fnv1a,
        warnings,
        skin: SkinSummary {
            fit_resolution: opts.resolution,
            template_posed: skin.posture.is_some(),
            centre_weight: opts.centre_weight,
            shape_prior: opts.shape_prior.as_ref().map(|p| p.summary()),
            iterations: skin.iterations,
            converged: skin.converged,
            posture_deg: skin.posture.as_ref().map(|p| {
                crate::anatomy::Joint::ALL
                    .iter()
                    .map(|j| {
                        (
                            j.name().to_string(),
                            p.pose.angles[j.index()].map(f64::to_degrees),
                        )
                    })
                    .collect()
            }),
            posture_direction_residual_deg: skin
                .posture
                .as_ref()
                .map(|p| p.direction_residual_deg.clone()),
            landmark_residuals_mm: skin.landmark_residuals_mm.clone(),
            caliper_pair_residuals_mm: skin.dimension_residuals_mm.clone(),
            caliper_residuals_mm: skin.caliper_residuals_mm.clone(),
            caliper_rounds: skin.caliper_rounds,
            centre_residuals_mm: skin.centre_residuals_mm.clone(),
            section_3_6_shift_mm: shifts,
            inverted_faces: skin.inverted_faces,
            degenerate_faces: skin.degenerate_faces,
        },
    };
    let json = serde_json::to_string_pretty(&report).expect("serialisable");
    atomic::write_bytes_atomic(&out.join("report.json"), json.as_bytes())?;
    log::log!(
        voice.info(),
        "link model: 16 joints in {:.2} s, {} warnings -> {}",
        t_link,
        model.warnings.len(),
        out.join("link_model.json").display()
    );
    log::log!(
        voice.info(),
        "skin: {} + {} faces fitted in {:.2} s -> {}",
        skin.low.n_faces(),
        skin.high.n_faces(),
        t_skin,
        out.join("skin.obj").display()
    );
    log::log!(
        voice.info(),
        "tet: {} nodes / {} tetrahedra, none inverted: {}, in {:.2} s -> {}",
        tet.n_nodes(),
        tet.n_tets(),
        tet.inverted_count() == 0,
        t_tet,
        out.join("tet.vtk").display()
    );
    log::log!(
        voice.info(),
        "hand: skinned GLB in {:.2} s -> {}",
        t_hand,
        out.join("hand.glb").display()
    );
    Ok(model)
}
