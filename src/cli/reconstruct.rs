//! `ergohand reconstruct`: the stages of the seed paper run on one subject folder, and the
//! model folder they write (spec section 3).

use super::Voice;
use crate::error::{Error, Result};
use crate::io::output_paths::{check_output_dir, Inputs, MODEL_FILES};
use crate::io::{atomic, obj, Units};
use crate::skin::pipeline::{FitResolution, PriorChoice, SkinOptions};
use crate::template;
use std::path::Path;

/// The content fingerprint of a reconstruction's inputs ([`crate::reconstruct::inputs_fingerprint`])
/// with the template of the folder `template` (`None`: the generic hand).
pub fn reconstruct_fingerprint(
    subject: &crate::mocap::subject::Subject,
    opts: &SkinOptions,
    template: Option<&Path>,
) -> Result<String> {
    let source = template::template_source(template, subject.hand)?;
    crate::reconstruct::inputs_fingerprint(subject, opts, &source)
}

/// Skin options from the command line's values; an error naming `--centre-weight` unless it is
/// a finite weight >= 0.
pub fn skin_options(
    resolution: FitResolution,
    pose_template: bool,
    centre_weight: f64,
) -> Result<SkinOptions> {
    let centre_weight = non_negative(
        "--centre-weight",
        centre_weight,
        "a finite weight >= 0 (0 turns the centre terms off)",
    )?;
    Ok(SkinOptions {
        resolution,
        pose_template,
        centre_weight,
        ..SkinOptions::default()
    })
}

/// `--thumb-spacing`, checked: a finite spacing >= 0 mm.
pub fn thumb_spacing_option(mm: f64) -> Result<f64> {
    non_negative(
        "--thumb-spacing",
        mm,
        "a finite spacing >= 0 mm (0 keeps no extra vertices on the thumb)",
    )
}

/// `value` of the flag `flag` when it is finite and >= 0; else a one-line error naming the
/// flag and the value, asking for `want`.
fn non_negative(flag: &str, value: f64, want: &str) -> Result<f64> {
    if value.is_finite() && value >= 0.0 {
        Ok(value)
    } else {
        Err(Error::invalid(format!("{flag} {value}: give {want}")))
    }
}

/// The skin's shape prior from `--shape-prior`: when absent the one shipped with the generic
/// template on that template (none on another), none for `none`, the shipped one for `builtin`,
/// else the file (an error naming it when it is not a prior).
pub fn shape_prior_option(arg: Option<&Path>) -> Result<PriorChoice> {
    use crate::skin::shape_prior::ShapePrior;
    match arg {
        None => Ok(PriorChoice::Shipped),
        Some(p) if p == Path::new("none") => Ok(PriorChoice::None),
        Some(p) if p == Path::new("builtin") => Ok(PriorChoice::Given(ShapePrior::builtin())),
        Some(p) => Ok(PriorChoice::Given(std::sync::Arc::new(
            ShapePrior::from_json(&atomic::read_bytes(p)?, p)?,
        ))),
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

/// `ergohand reconstruct SUBJECT_DIR --out OUT --template DIR`: [`reconstruct_with`] from the
/// template folder `template` ([`crate::template::folder`]; `None`: the generic hand).
pub fn reconstruct_from(
    subject_dir: &Path,
    out: &Path,
    opts: &SkinOptions,
    template: Option<&Path>,
) -> Result<crate::link::LinkModel> {
    reconstruct_job(subject_dir, out, opts, template, None, Voice::Command).map(|r| r.link_model)
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
    reconstruct_job(subject_dir, out, opts, None, prepared, Voice::Command).map(|r| r.link_model)
}

/// [`reconstruct_prepared`], speaking with `voice`: the library's
/// [`crate::reconstruct::reconstruct`], its warnings logged, its files written; the whole
/// reconstruction returned (what `report.json` holds among it).
pub(crate) fn reconstruct_job(
    subject_dir: &Path,
    out: &Path,
    opts: &SkinOptions,
    template_dir: Option<&Path>,
    prepared: Option<&crate::tet::TemplateTet>,
    voice: Voice,
) -> Result<crate::reconstruct::Reconstruction> {
    let subject = crate::mocap::subject::Subject::load(subject_dir)?;
    let inputs = Inputs::files(
        std::iter::once(subject.toml_path())
            .chain(subject.trials.values().map(|p| subject.dir.join(p))),
    );
    check_output_dir(out, &MODEL_FILES, "--out", &inputs)?;
    if let Some(d) = template_dir {
        let inputs = Inputs::files([
            crate::template::folder::surface_file(d, subject.hand),
            d.join(crate::template::folder::SPEC_FILE),
            d.join(crate::template::folder::SETTINGS_FILE),
        ]);
        check_output_dir(out, &MODEL_FILES, "--out", &inputs)?;
    }
    let template = template::load_template_from(template_dir, subject.hand)?;
    log::log!(
        voice.info(),
        "reconstruct {} from {}: link model from 7 trials, skin, tetrahedral mesh (the \
         template's is cached after the first run), skinned hand",
        subject.name,
        template.source.describe()
    );
    let r = crate::reconstruct::reconstruct(&subject, &template, opts, prepared)?;
    for w in &r.report.warnings {
        log::log!(voice.warn(), "{w}");
    }
    write_model(&r, out)?;
    let t = &r.report.timings_s;
    log::log!(
        voice.info(),
        "link model: 16 joints in {:.2} s, {} warnings -> {}",
        t["link"],
        r.link_model.warnings.len(),
        out.join("link_model.json").display()
    );
    log::log!(
        voice.info(),
        "skin: {} + {} faces fitted in {:.2} s -> {}",
        r.skin.low.n_faces(),
        r.skin.high.n_faces(),
        t["skin"],
        out.join("skin.obj").display()
    );
    log::log!(
        voice.info(),
        "tet: {} nodes / {} tetrahedra, none inverted: {}, in {:.2} s -> {}",
        r.tet.n_nodes(),
        r.tet.n_tets(),
        r.tet.inverted_count() == 0,
        t["tet"],
        out.join("tet.vtk").display()
    );
    log::log!(
        voice.info(),
        "hand: skinned GLB in {:.2} s -> {}",
        t["hand"],
        out.join("hand.glb").display()
    );
    Ok(r)
}

/// The model folder (spec section 3): the seven files of [`MODEL_FILES`], each written to a
/// temporary file and renamed, `report.json` last.
fn write_model(r: &crate::reconstruct::Reconstruction, out: &Path) -> Result<()> {
    // One run's files, never a mix of two runs into the same folder.
    let _held = atomic::FolderLock::acquire(out)?;
    r.link_model.write(&out.join("link_model.json"))?;
    obj::write_obj(
        &out.join("skin_low.obj"),
        &r.skin.low,
        Units::Millimetres,
        None,
    )?;
    obj::write_obj(
        &out.join("skin.obj"),
        &r.skin.high,
        Units::Millimetres,
        None,
    )?;
    let groups = Some(&r.tet_groups);
    crate::io::vtk::write_vtk(&out.join("tet.vtk"), &r.tet, Units::Millimetres, groups)?;
    crate::io::gmsh::write_msh(&out.join("tet.msh"), &r.tet, Units::Millimetres, groups)?;
    let h = &r.hand;
    let scene = crate::pose::gltf::skinned_scene("hand", &h.skin, &h.weights, &h.skeleton, None);
    crate::io::gltf::write_glb(&out.join("hand.glb"), &scene, Units::Metres)?;
    let json = serde_json::to_string_pretty(&r.report).expect("serialisable");
    atomic::write_bytes_atomic(&out.join("report.json"), json.as_bytes())
}
