//! A template as data: a lab's own homologous hand model in a folder, used instead of the
//! embedded generic hand (`reconstruct --template DIR`), and recorded in the model folders made
//! from it so that `pose`, `grasp` and `validate` use the same one.
//!
//! The folder holds, per hand it serves:
//! * `right.glb` / `left.glb`: the surface as a skinned glTF binary in metres, with the WebXR
//!   hand joint names (`wrist`, `thumb-metacarpal`, ..., `pinky-finger-tip`; the convention of
//!   the generic hand, [`super::generic_hand`]), one closed 2-manifold skinned mesh;
//! * `template.toml` (optional): `subdivisions = N`, the Loop subdivision levels applied to the
//!   surface before use (default 0: the surface is used as it is);
//! * `template-spec.toml` (optional): the landmarks, dimension vertex pairs, palm landmarks and
//!   joint centres of the hand(s), in the format `ergohand template` writes, indices into the
//!   subdivided surface. A hand the file does not describe gets the spec the landmark rule
//!   derives ([`super::landmark_rule`]), said in the log.

use super::{dominant_links, landmark_rule, refine_base, HandSpec, TemplateHand};
use crate::anatomy::Side;
use crate::error::{Error, Result};
use crate::io::fingerprint::inputs_fingerprint;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The optional settings file of a template folder.
pub const SETTINGS_FILE: &str = "template.toml";
/// The optional spec file of a template folder.
pub const SPEC_FILE: &str = "template-spec.toml";

/// Where a template comes from.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TemplateSource {
    /// The generic hand embedded in the toolkit.
    GenericHand,
    /// A template folder, with the fingerprint of its files when it was read.
    Folder { dir: PathBuf, fnv1a: String },
}

impl TemplateSource {
    /// One line for logs and reports.
    pub fn describe(&self) -> String {
        match self {
            TemplateSource::GenericHand => "the embedded generic hand".into(),
            TemplateSource::Folder { dir, .. } => format!("template folder {}", dir.display()),
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Settings {
    #[serde(default)]
    subdivisions: usize,
}

/// The spec file of a folder: either hand may be absent.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FolderSpec {
    right: Option<HandSpec>,
    left: Option<HandSpec>,
}

/// The text of a folder's `template-spec.toml` describing `hands` (one per side at most).
pub fn folder_spec_toml(hands: &[&HandSpec]) -> String {
    #[derive(Serialize)]
    struct Out<'a> {
        #[serde(skip_serializing_if = "Option::is_none")]
        right: Option<&'a HandSpec>,
        #[serde(skip_serializing_if = "Option::is_none")]
        left: Option<&'a HandSpec>,
    }
    let find = |side| hands.iter().find(|h| h.side == side).copied();
    let out = Out {
        right: find(Side::Right),
        left: find(Side::Left),
    };
    "# Template spec of a template folder: vertex indices into the surface after the \
     subdivisions of template.toml.\n# Written by `ergohand template --template DIR`; review \
     the pictures, edit an index if the rule chose badly.\n\n"
        .to_string()
        + &toml::to_string(&out).expect("spec serialises")
}

/// Most Loop subdivision levels a folder may ask for (each multiplies the faces by four).
const MAX_SUBDIVISIONS: usize = 3;

/// The surface file of `side` in a template folder.
pub fn surface_file(dir: &Path, side: Side) -> PathBuf {
    dir.join(format!("{side}.glb"))
}

/// The fingerprint of the files of `dir` that make its template of `side` (surface, settings,
/// spec: those present).
pub(crate) fn folder_fingerprint(dir: &Path, side: Side) -> Result<String> {
    let files: Vec<PathBuf> = [
        surface_file(dir, side),
        dir.join(SETTINGS_FILE),
        dir.join(SPEC_FILE),
    ]
    .into_iter()
    .filter(|p| p.is_file())
    .collect();
    inputs_fingerprint(&files, "template folder")
}

/// The source of the template of `side` that `dir` gives (a folder, with its fingerprint now;
/// `None`: the generic hand), without reading the surface.
pub fn template_source(dir: Option<&Path>, side: Side) -> Result<TemplateSource> {
    match dir {
        None => Ok(TemplateSource::GenericHand),
        Some(d) => {
            let dir = std::path::absolute(d).map_err(|e| Error::io(d, e))?;
            let fnv1a = folder_fingerprint(&dir, side)?;
            Ok(TemplateSource::Folder { dir, fnv1a })
        }
    }
}

/// Read the template of `side` from the folder `dir` (see the module documentation). Errors
/// name the file and the item: a missing surface, a surface that is not a skinned hand with
/// the WebXR joints, a settings or spec file that does not parse, a spec that does not fit the
/// surface.
pub fn load_folder_template(dir: &Path, side: Side) -> Result<TemplateHand> {
    let dir = std::path::absolute(dir).map_err(|e| Error::io(dir, e))?;
    if !dir.is_dir() {
        return Err(Error::input(
            &dir,
            "--template: not a folder; give a folder holding right.glb and/or left.glb \
             (a skinned hand, WebXR joint names) and optionally template-spec.toml",
        ));
    }
    let fnv1a = folder_fingerprint(&dir, side)?;
    let glb = surface_file(&dir, side);
    if !glb.is_file() {
        return Err(Error::input(
            &glb,
            format!(
                "file not found: a template folder for a {side} hand holds {side}.glb (a \
                 skinned hand in metres with the WebXR joint names)"
            ),
        ));
    }
    let settings_path = dir.join(SETTINGS_FILE);
    let subdivisions = if settings_path.is_file() {
        let text = read_text(&settings_path)?;
        let s: Settings =
            toml::from_str(&text).map_err(|e| Error::toml(&settings_path, &text, &e))?;
        if s.subdivisions > MAX_SUBDIVISIONS {
            return Err(Error::input(
                &settings_path,
                format!(
                    "subdivisions = {}: at most {MAX_SUBDIVISIONS} (each level quadruples the faces)",
                    s.subdivisions
                ),
            ));
        }
        s.subdivisions
    } else {
        0
    };
    let bytes = crate::io::atomic::read_bytes(&glb)?;
    let base = super::generic_hand::base_hand_from_glb(&bytes, side, &glb)?;
    let (mesh, weights) = refine_base(&base, subdivisions);
    mesh.check_closed_manifold()
        .map_err(|e| Error::input(&glb, format!("the surface is not closed: {e}")))?;
    let spec_path = dir.join(SPEC_FILE);
    let given = if spec_path.is_file() {
        let text = read_text(&spec_path)?;
        let s: FolderSpec =
            toml::from_str(&text).map_err(|e| Error::toml(&spec_path, &text, &e))?;
        match side {
            Side::Right => s.right,
            Side::Left => s.left,
        }
    } else {
        None
    };
    let spec = match given {
        Some(spec) => {
            spec.check(&mesh, &spec_path)?;
            spec
        }
        None => {
            log::info!(
                "{}: no [{side}] spec in {SPEC_FILE}; landmarks, dimension pairs and joint \
                 centres derived by the landmark rule (`ergohand template --template {} --out \
                 DIR` writes them for review)",
                dir.display(),
                dir.display()
            );
            let spec = landmark_rule::derive_hand_spec(
                &mesh,
                &base.skeleton,
                side,
                &dominant_links(&weights),
                &base.metacarpal_bases,
            )
            .map_err(|e| e.in_file(&glb))?;
            spec.check(&mesh, &glb)?;
            spec
        }
    };
    Ok(TemplateHand {
        side,
        skeleton: base.skeleton.clone(),
        mesh,
        weights,
        base,
        spec,
        source: TemplateSource::Folder { dir, fnv1a },
    })
}

fn read_text(path: &Path) -> Result<String> {
    String::from_utf8(crate::io::atomic::read_bytes(path)?)
        .map_err(|_| Error::input(path, "not UTF-8 text"))
}

/// The template a model folder was made from: the `template` that `report.json` records
/// (the embedded generic hand when the report names none, as in folders made before templates
/// were data), read again and checked against the fingerprint recorded. Errors name
/// `report.json` when the folder's template changed or is gone.
pub fn model_template(model_dir: &Path, side: Side) -> Result<TemplateHand> {
    let report = model_dir.join("report.json");
    let source = if report.is_file() {
        let text = read_text(&report)?;
        let v: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::input(&report, format!("not JSON: {e}")))?;
        match v.get("template") {
            None | Some(serde_json::Value::Null) => TemplateSource::GenericHand,
            Some(t) => serde_json::from_value(t.clone())
                .map_err(|e| Error::input(&report, format!("field 'template': {e}")))?,
        }
    } else {
        TemplateSource::GenericHand
    };
    match &source {
        TemplateSource::GenericHand => super::load_template(side),
        TemplateSource::Folder { dir, fnv1a } => {
            let now = folder_fingerprint(dir, side).map_err(|_| {
                Error::input(
                    &report,
                    format!(
                        "field 'template': the template folder {} cannot be read; restore it \
                         or re-run reconstruct",
                        dir.display()
                    ),
                )
            })?;
            if &now != fnv1a {
                return Err(Error::input(
                    &report,
                    format!(
                        "field 'template': the template folder {} changed since this model was \
                         made (fingerprint {now}, recorded {fnv1a}); re-run reconstruct",
                        dir.display()
                    ),
                ));
            }
            load_folder_template(dir, side)
        }
    }
}
