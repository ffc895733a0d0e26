//! One subject's individual hand, the seed paper's pipeline as one stage: the trials read once,
//! the link model (section 3.4), the skin (3.5, with the template first posed onto the link
//! model), section 3.6 applied to the link model on the final skin, the tetrahedral mesh (3.7)
//! and the skinned hand.
//!
//! [`reconstruct`] returns everything a model folder holds (the spec's outputs) and what
//! `report.json` says of them ([`ReconstructReport`]); writing files is the caller's job.

use crate::anatomy::{Joint, Side};
use crate::error::{Error, Result};
use crate::geometry::tet_mesh::TetMesh;
use crate::link::{anthropometry, LinkModel};
use crate::mocap::subject::{Subject, TrialKind};
use crate::pose::{IndividualHand, WeightMethod};
use crate::skin::pipeline::{fit_skin, FitResolution, SkinFit, SkinOptions};
use crate::template::{TemplateHand, TemplateSource};
use crate::tet::{TemplateTet, TetReport};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

/// A subject's reconstruction: the spec's model folder in memory.
pub struct Reconstruction {
    /// The link model after section 3.6 (`link_model.json`).
    pub link_model: LinkModel,
    /// The fitted skin at both resolutions (`skin_low.obj`, `skin.obj`) and its residuals.
    pub skin: SkinFit,
    /// The subject's tetrahedral mesh (`tet.vtk`, `tet.msh`).
    pub tet: TetMesh,
    /// Its groups by link (each tetrahedron's dominant link, the boundary faces), which the
    /// tet files carry for finite-element users ([`crate::pose::quality::link_groups`]).
    pub tet_groups: crate::tet::TetGroups,
    /// The skinned individual hand (`hand.glb`).
    pub hand: IndividualHand,
    /// What `report.json` holds.
    pub report: ReconstructReport,
}

/// `report.json` of a model folder (spec section 3, with extensions).
#[derive(Clone, Debug, Serialize)]
pub struct ReconstructReport {
    pub subject: String,
    pub hand: Side,
    pub stages_run: Vec<&'static str>,
    pub stages_not_built: Vec<&'static str>,
    pub timings_s: BTreeMap<&'static str, f64>,
    /// Every stage's warnings: the link model's, the skin's, inverted tetrahedra.
    pub warnings: Vec<String>,
    pub skin: SkinSummary,
    pub tet: TetReport,
    /// [`inputs_fingerprint`] of the inputs the model was made from (an extension of the
    /// spec's outputs; `batch` compares it to decide what is up to date).
    pub inputs_fnv1a: String,
    /// The template the model was made from (an extension: `pose`, `grasp` and `validate`
    /// read the same one, [`crate::template::model_template`]).
    pub template: TemplateSource,
}

/// The skin stage's part of `report.json`.
#[derive(Clone, Debug, Serialize)]
pub struct SkinSummary {
    pub fit_resolution: FitResolution,
    pub template_posed: bool,
    pub centre_weight: f64,
    /// The shape prior used (`null`: none, the template's shape where nothing reaches).
    pub shape_prior: Option<String>,
    /// The subject's features as a shape prior reads them, by name (an extension:
    /// `shape-prior` trains on exactly what a fit will read).
    pub shape_prior_features: BTreeMap<String, f64>,
    /// Whether the fingers' sections were scaled to their calipers
    /// ([`SkinOptions::section_scaling`]).
    pub section_scaling: bool,
    pub iterations: usize,
    pub converged: bool,
    /// The template's posture found before the fit, degrees per joint `[flexion, abduction,
    /// axial]` (1-DOF joints: `[angle, 0, 0]`), relative to the template's reference posture.
    pub posture_deg: Option<BTreeMap<String, [f64; 3]>>,
    pub posture_direction_residual_deg: Option<BTreeMap<String, f64>>,
    pub landmark_residuals_mm: BTreeMap<String, f64>,
    /// The fit's caliper constraints: distance of each dimension's template vertex pair minus
    /// the given value, mm. Not the dimensions by their definitions (`validate` measures those).
    pub caliper_pair_residuals_mm: BTreeMap<String, f64>,
    /// Each dimension read on skin.obj by the spec's definition (sections at the link model's
    /// joints, landmarks under the static trial's markers) minus the given value, mm.
    pub caliper_residuals_mm: BTreeMap<String, f64>,
    /// Caliper rounds the skin fit took (re-fits correcting the pairs' lengths).
    pub caliper_rounds: usize,
    pub centre_residuals_mm: BTreeMap<String, f64>,
    /// Section 3.6: shift of each 1-DOF centre along its axis onto the skin, mm.
    pub section_3_6_shift_mm: BTreeMap<String, f64>,
    pub inverted_faces: usize,
    pub degenerate_faces: usize,
    /// Faces the fit folded and the skin stage relaxed (`inverted_faces` is what is left).
    pub unfolded_faces: usize,
}

/// The content fingerprint ([`crate::io::fingerprint`]) of a reconstruction's inputs:
/// `subject.toml`, every trial it names, the skin options and the template (its folder's
/// fingerprint).
pub fn inputs_fingerprint(
    subject: &Subject,
    opts: &SkinOptions,
    template: &TemplateSource,
) -> Result<String> {
    // A missing trial is named by its key here already, as reading it would.
    for (key, p) in &subject.trials {
        let path = subject.dir.join(p);
        if !path.exists() {
            return Err(subject.trial_not_found(key, &path));
        }
    }
    let files: Vec<PathBuf> = std::iter::once(subject.toml_path())
        .chain(subject.trials.values().map(|p| subject.dir.join(p)))
        .collect();
    // The generic hand adds nothing, so that its fingerprints stay those of before.
    let settings = match template {
        TemplateSource::GenericHand => format!("{opts:?}"),
        t => format!("{opts:?} {t:?}"),
    };
    crate::io::fingerprint::inputs_fingerprint(&files, &settings)
}

/// Reconstruct `subject`'s hand from `template` (of the subject's hand) with the skin options
/// `opts`. `prepared` is the template's section 3.7 work done beforehand (a batch prepares one
/// per hand and shares it); with `None` it is prepared here, on a second thread while the link
/// model and the skin are fitted.
///
/// Errors: those of every stage (a trial that cannot be read, a landmark never seen, ...), a
/// template or a prepared template of the other hand. A suspect result (inverted faces or
/// tetrahedra, a landmark far from its marker) is not an error: it is in the warnings.
pub fn reconstruct(
    subject: &Subject,
    template: &TemplateHand,
    opts: &SkinOptions,
    prepared: Option<&TemplateTet>,
) -> Result<Reconstruction> {
    let other_hand = |what: &str, side: Side| {
        Error::invalid(format!(
            "{}: a {} hand, but the {what} is of the {side} hand",
            subject.dir.display(),
            subject.hand
        ))
    };
    if template.skeleton.side != subject.hand {
        return Err(other_hand("template", template.skeleton.side));
    }
    if let Some(p) = prepared {
        if p.side != subject.hand {
            return Err(other_hand("prepared tetrahedral template", p.side));
        }
        return stages(subject, template, opts, || Ok((Prepared::Shared(p), 0.0)));
    }
    // Section 3.7's template-only work (tet mesh from the cache, binding, factorisation) needs
    // nothing of the subject: it runs on a second thread while the link model and the skin are
    // fitted.
    std::thread::scope(|scope| {
        let handle = scope.spawn(|| {
            let t = Instant::now();
            TemplateTet::prepare(template, None).map(|p| (p, t.elapsed()))
        });
        let joined = || {
            let (p, d) = handle
                .join()
                .map_err(|_| Error::invalid("tet: the template preparation thread panicked"))??;
            Ok((Prepared::Own(Box::new(p)), d.as_secs_f64()))
        };
        stages(subject, template, opts, joined)
    })
}

/// The template's prepared tet stage, shared by a batch or made for one subject.
enum Prepared<'a> {
    Shared(&'a TemplateTet),
    Own(Box<TemplateTet>),
}

impl std::ops::Deref for Prepared<'_> {
    type Target = TemplateTet;
    fn deref(&self) -> &Self::Target {
        match self {
            Prepared::Shared(p) => p,
            Prepared::Own(p) => p,
        }
    }
}

/// The stages of [`reconstruct`]; `prepared_tet` hands over (or waits for) the template's
/// prepared tet stage and the seconds its preparation took.
fn stages<'p>(
    subject: &Subject,
    template: &TemplateHand,
    opts: &SkinOptions,
    prepared_tet: impl FnOnce() -> Result<(Prepared<'p>, f64)>,
) -> Result<Reconstruction> {
    // Fingerprinted before anything is read, so the record never claims newer inputs.
    let inputs_fnv1a = inputs_fingerprint(subject, opts, &template.source)?;
    let t0 = Instant::now();
    let (trials, trial_warnings) = subject.load_trials()?;
    let motion = crate::link::estimate::estimate_link_model_from(
        subject.hand,
        subject.reference_frame,
        &trials,
    )?;
    let t_link = t0.elapsed().as_secs_f64();
    log::debug!("{}: link model in {t_link:.2} s", subject.name);
    // A hand no human has is refused before the skin is fitted to it.
    let who = subject.dir.display().to_string();
    let motion_proportions = anthropometry::hand_proportions(&motion.skeleton);
    anthropometry::check_link_proportions(&motion_proportions, &who)?;

    let t1 = Instant::now();
    let skin = fit_skin(
        template,
        &trials[TrialKind::Reference.key()],
        &subject.dimensions,
        subject.marker_offset_mm,
        Some(&motion),
        opts,
    )?;
    // Section 3.6, applied by the skin stage to the link model on its final skin.
    let mut link_model = skin
        .link_model
        .clone()
        .ok_or_else(|| Error::invalid("skin: no section 3.6 link model returned"))?;
    let final_proportions = anthropometry::hand_proportions(&link_model.skeleton);
    anthropometry::check_skin_size(&skin.high, &final_proportions, &who)?;
    let proportions = anthropometry::check_link_proportions(&final_proportions, &who)?;
    // The model's warnings: the trials' (samples dropped) before the estimation's, then the
    // proportions'.
    link_model.warnings = trial_warnings
        .into_iter()
        .chain(link_model.warnings)
        .chain(proportions)
        .collect();
    let mut warnings = link_model.warnings.clone();
    warnings.extend(skin.warnings.iter().cloned());
    let t_skin = t1.elapsed().as_secs_f64();
    log::debug!("{}: skin in {t_skin:.2} s", subject.name);

    let t2 = Instant::now();
    let (template_tet, t_prepare) = prepared_tet()?;
    let (tet, tet_report) = template_tet.deform(&skin.high)?;
    // What `pose` reuses instead of preparing the template's tet stage again: the node weights
    // of the template's tet mesh, stored in the tet cache beside the mesh itself.
    let nodes = template_tet.tet.n_nodes();
    let node_weights = match crate::pose::cached_tet_node_weights(template, nodes) {
        Some(w) => w,
        None => {
            let w = crate::pose::tet_node_weights(template, &template_tet)?;
            crate::pose::store_tet_node_weights(template, &w);
            w
        }
    };
    let labels = crate::pose::quality::tet_segments(&tet.tets, &node_weights);
    let tet_groups = crate::pose::quality::link_groups(&tet, &labels)?;
    let t_tet = t2.elapsed().as_secs_f64();
    // An inverted element is a suspect model: said, with where, never only counted.
    let inverted_tets = tet_report.inverted;
    if inverted_tets > 0 {
        let by_link = crate::pose::quality::inverted_by_link(&tet.nodes, &tet.tets, &labels);
        warnings.push(format!(
            "tet.vtk: {inverted_tets} of {} tetrahedra are inverted (negative volume) after \
             untangling ({}); the skin folds there, where the template could not follow the \
             subject",
            tet.n_tets(),
            crate::pose::quality::describe_by_link(&by_link),
        ));
    }
    if tet_report.untangle.max_boundary_move_mm > 0.0 {
        log::debug!(
            "{}: tet: {} inverted elements untangled to {}, the boundary moved by up to {:.2} mm",
            subject.name,
            tet_report.untangle.inverted_before,
            tet_report.untangle.inverted_after,
            tet_report.untangle.max_boundary_move_mm
        );
    }

    let t3 = Instant::now();
    let hand = IndividualHand::from_skin(
        template,
        skin.high.clone(),
        link_model.skeleton.clone(),
        WeightMethod::default(),
    )?;
    let t_hand = t3.elapsed().as_secs_f64();

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
        template: template.source.clone(),
        warnings,
        skin: skin_summary(&skin, opts),
    };
    Ok(Reconstruction {
        link_model,
        skin,
        tet,
        tet_groups,
        hand,
        report,
    })
}

/// The skin stage's part of `report.json`.
fn skin_summary(skin: &SkinFit, opts: &SkinOptions) -> SkinSummary {
    SkinSummary {
        fit_resolution: opts.resolution,
        template_posed: skin.posture.is_some(),
        centre_weight: opts.centre_weight,
        shape_prior: skin.shape_prior.clone(),
        shape_prior_features: skin.prior_features.clone(),
        section_scaling: opts.section_scaling,
        iterations: skin.iterations,
        converged: skin.converged,
        posture_deg: skin.posture.as_ref().map(|p| {
            Joint::ALL
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
        section_3_6_shift_mm: skin.section_shifts_mm.clone(),
        inverted_faces: skin.inverted_faces,
        degenerate_faces: skin.degenerate_faces,
        unfolded_faces: skin.unfolded_faces,
    }
}
