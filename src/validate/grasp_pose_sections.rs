//! The report's grasp and pose sections: what `grasp` wrote into its folders (`grasp.json`,
//! `contact_map.png`) and what `pose` wrote beside its posed hands in the model folder
//! (`NAME.pose.json`), read back and shown as written. Nothing here is measured again.

use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// One grasp's figures, from its `grasp.json`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GraspSection {
    /// The grasp's output folder.
    pub folder: String,
    pub scene: String,
    pub grasp_type: String,
    pub force_closure: bool,
    pub epsilon: f64,
    pub holds: bool,
    /// Gravity directions held, of those tried.
    pub directions_held: usize,
    pub directions: usize,
    pub total_contact_area_mm2: f64,
    pub max_penetration_mm: f64,
    /// Contact area per link, mm² (links that touch).
    pub contact_area_mm2: BTreeMap<String, f64>,
    /// Whether the folder has a `view.html`.
    pub view_page: bool,
    /// `contact_map.png`'s bytes, when the folder has one.
    #[serde(skip)]
    pub contact_png: Option<Vec<u8>>,
}

/// Read the grasp output folder `dir`: its `grasp.json` (an error names the file and the
/// field) and its `contact_map.png` if there.
pub fn read_grasp_section(dir: &Path) -> Result<GraspSection> {
    let path = dir.join("grasp.json");
    let text = std::fs::read_to_string(&path).map_err(|e| {
        Error::input(
            &path,
            format!("--grasp: cannot read it ({e}); give a grasp output folder"),
        )
    })?;
    let v: serde_json::Value =
        serde_json::from_str(&text).map_err(|e| Error::input(&path, format!("not JSON: {e}")))?;
    let field = |k: &str| -> Result<&serde_json::Value> {
        v.get(k)
            .ok_or_else(|| Error::input(&path, format!("field '{k}' is missing")))
    };
    let num = |k: &str| -> Result<f64> {
        field(k)?
            .as_f64()
            .ok_or_else(|| Error::input(&path, format!("field '{k}' is not a number")))
    };
    let flag = |k: &str| -> Result<bool> {
        field(k)?
            .as_bool()
            .ok_or_else(|| Error::input(&path, format!("field '{k}' is not true or false")))
    };
    let text_of = |k: &str| -> Result<String> {
        Ok(field(k)?
            .as_str()
            .ok_or_else(|| Error::input(&path, format!("field '{k}' is not a string")))?
            .to_string())
    };
    let trials = field("hold_test")?
        .get("trials")
        .and_then(|t| t.as_array())
        .ok_or_else(|| Error::input(&path, "field 'hold_test.trials' is not a list"))?;
    let directions_held = trials
        .iter()
        .filter(|t| t.get("holds").and_then(|h| h.as_bool()) == Some(true))
        .count();
    let areas = field("contact_area_mm2")?
        .as_object()
        .ok_or_else(|| Error::input(&path, "field 'contact_area_mm2' is not a table"))?;
    let mut contact_area_mm2 = BTreeMap::new();
    for (link, a) in areas {
        let a = a.as_f64().ok_or_else(|| {
            Error::input(
                &path,
                format!("field 'contact_area_mm2.{link}' is not a number"),
            )
        })?;
        if a > 0.0 {
            contact_area_mm2.insert(link.clone(), a);
        }
    }
    let png = dir.join("contact_map.png");
    let contact_png = if png.is_file() {
        Some(std::fs::read(&png).map_err(|e| Error::io(&png, e))?)
    } else {
        None
    };
    Ok(GraspSection {
        folder: dir.display().to_string(),
        scene: text_of("scene")?,
        grasp_type: text_of("grasp_type")?,
        force_closure: flag("force_closure")?,
        epsilon: num("epsilon")?,
        holds: flag("holds")?,
        directions_held,
        directions: trials.len(),
        total_contact_area_mm2: num("total_contact_area_mm2")?,
        max_penetration_mm: num("max_penetration_mm")?,
        contact_area_mm2,
        view_page: dir.join("view.html").is_file(),
        contact_png,
    })
}

/// What `pose` writes beside a posed hand (`NAME.pose.json` for `NAME.glb|obj|vtk|msh`): the
/// figures it measured on the hand it wrote.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PoseRecord {
    /// The pose asked for (a built-in name or a POSE.toml).
    pub pose: String,
    /// The posed hand's file name, beside the record.
    pub file: String,
    /// Deepest finger-finger penetration of the written pose, mm.
    pub penetration_mm: f64,
    /// Angles clamped to their limits or changed to keep the digits apart, one line each.
    pub warnings: Vec<String>,
}

/// The suffix of a pose record's file name.
pub const POSE_RECORD_SUFFIX: &str = ".pose.json";

/// The record's path for the posed hand `out_file`: `NAME.pose.json` beside `NAME.EXT`.
pub fn pose_record_path(out_file: &Path) -> PathBuf {
    let stem = out_file
        .file_stem()
        .map_or_else(|| "pose".into(), |s| s.to_string_lossy().into_owned());
    out_file.with_file_name(format!("{stem}{POSE_RECORD_SUFFIX}"))
}

/// Every pose record in the model folder `model`, by file name; an unreadable one is an
/// error naming it.
pub fn model_poses(model: &Path) -> Result<Vec<PoseRecord>> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(model)
        .map_err(|e| Error::io(model, e))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.is_file()
                && p.file_name()
                    .is_some_and(|n| n.to_string_lossy().ends_with(POSE_RECORD_SUFFIX))
        })
        .collect();
    paths.sort();
    paths
        .iter()
        .map(|p| {
            let text = std::fs::read_to_string(p).map_err(|e| Error::io(p, e))?;
            serde_json::from_str(&text).map_err(|e| Error::input(p, format!("{e}")))
        })
        .collect()
}

/// `to` as a link from the folder `from`: relative when both resolve on disk (a report moved
/// with its outputs keeps its links), else `to` as given.
pub fn relative_link(from: &Path, to: &Path) -> String {
    let (Ok(a), Ok(b)) = (from.canonicalize(), to.canonicalize()) else {
        return to.display().to_string();
    };
    let (a, b): (Vec<_>, Vec<_>) = (a.components().collect(), b.components().collect());
    let common = a.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let mut parts: Vec<String> = std::iter::repeat_n("..".to_string(), a.len() - common).collect();
    parts.extend(
        b[common..]
            .iter()
            .map(|c| c.as_os_str().to_string_lossy().into_owned()),
    );
    parts.join("/")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn links_are_relative_between_existing_folders() {
        let dir = tempfile::tempdir().unwrap();
        let (r, g) = (dir.path().join("out/report"), dir.path().join("grasp/a b"));
        std::fs::create_dir_all(&r).unwrap();
        std::fs::create_dir_all(&g).unwrap();
        assert_eq!(relative_link(&r, &g), "../../grasp/a b");
        assert_eq!(
            relative_link(&r, &r.join("x")),
            r.join("x").display().to_string()
        );
    }

    #[test]
    fn a_pose_record_sits_beside_its_hand_and_is_found_in_the_model_folder() {
        let dir = tempfile::tempdir().unwrap();
        assert_eq!(
            pose_record_path(&dir.path().join("fist.glb")),
            dir.path().join("fist.pose.json")
        );
        let r = PoseRecord {
            pose: "fist".into(),
            file: "fist.glb".into(),
            penetration_mm: 0.4,
            warnings: vec!["fist: L_PIP flexion changed".into()],
        };
        std::fs::write(
            dir.path().join("fist.pose.json"),
            serde_json::to_string(&r).unwrap(),
        )
        .unwrap();
        std::fs::write(dir.path().join("report.json"), "{}").unwrap();
        assert_eq!(model_poses(dir.path()).unwrap(), vec![r]);
        std::fs::write(dir.path().join("bad.pose.json"), "{").unwrap();
        let e = model_poses(dir.path()).unwrap_err().to_string();
        assert!(e.contains("bad.pose.json"), "{e}");
    }

    #[test]
    fn a_grasp_folder_is_read_as_written_and_a_bad_one_named() {
        let dir = tempfile::tempdir().unwrap();
        let g = serde_json::json!({
            "scene": "bottle.toml", "grasp_type": "power", "force_closure": true,
            "epsilon": 0.031, "holds": false,
            "hold_test": {"trials": [{"holds": true}, {"holds": false}, {"holds": true}]},
            "total_contact_area_mm2": 250.0, "max_penetration_mm": 0.8,
            "contact_area_mm2": {"PALM": 200.0, "T_DIST": 50.0, "I_MID": 0.0}
        });
        std::fs::write(dir.path().join("grasp.json"), g.to_string()).unwrap();
        let s = read_grasp_section(dir.path()).unwrap();
        assert_eq!((s.directions_held, s.directions), (2, 3));
        assert_eq!(s.contact_area_mm2.len(), 2, "untouched links left out");
        assert!(s.contact_png.is_none() && !s.view_page);
        let mut bad = g.clone();
        bad["epsilon"] = "high".into();
        std::fs::write(dir.path().join("grasp.json"), bad.to_string()).unwrap();
        let e = read_grasp_section(dir.path()).unwrap_err().to_string();
        assert!(e.contains("grasp.json") && e.contains("'epsilon'"), "{e}");
        let e = read_grasp_section(&dir.path().join("none"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("grasp.json") && e.contains("--grasp"), "{e}");
    }
}
