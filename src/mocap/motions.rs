//! Motion trials of a subject folder (spec section 5): the `[motions]` table of
//! `subject.toml` (name -> C3D path, relative to the folder) and reading one of them.
//!
//! The table is read from the file on its own (the rest of `subject.toml` is
//! [`Subject`]'s), so that the description of a subject stays what the calibration stages
//! need.

use crate::error::{Error, Result};
use crate::mocap::c3d::read_c3d_bytes;
use crate::mocap::subject::Subject;
use crate::mocap::trajectories::Trajectories;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Only the `[motions]` table; every other key is [`Subject`]'s to check.
#[derive(Deserialize)]
struct RawMotions {
    #[serde(default)]
    motions: BTreeMap<String, String>,
}

/// `[motions]` of `subject`'s `subject.toml`: name -> path as written. Errors name the file
/// and the key.
pub fn motion_paths(subject: &Subject) -> Result<BTreeMap<String, PathBuf>> {
    let path = subject.toml_path();
    let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
    motion_paths_from_str(&text, subject)
}

/// [`motion_paths`] of the text of `subject.toml`.
pub fn motion_paths_from_str(text: &str, subject: &Subject) -> Result<BTreeMap<String, PathBuf>> {
    let path = subject.toml_path();
    let raw: RawMotions = toml::from_str(text).map_err(|e| Error::toml(&path, text, &e))?;
    let mut out = BTreeMap::new();
    for (k, v) in raw.motions {
        if k.trim().is_empty() || v.trim().is_empty() {
            return Err(Error::input(
                &path,
                format!("[motions] key '{k}' has an empty name or path"),
            ));
        }
        out.insert(k, PathBuf::from(v));
    }
    Ok(out)
}

/// Read the motion trial `name` of `[motions]` with the subject's `[labels]` mapping. Errors
/// name `subject.toml` and the missing name (listing the motions there are), or the trial
/// file. No hand-scale check: a motion trial may carry markers on the product, away from the
/// hand.
pub fn load_motion(subject: &Subject, name: &str) -> Result<Trajectories> {
    let motions = motion_paths(subject)?;
    let Some(rel) = motions.get(name) else {
        let known: Vec<&str> = motions.keys().map(String::as_str).collect();
        let hint = if known.is_empty() {
            format!("there is no [motions] table; add e.g. {name} = \"trials/{name}.c3d\"")
        } else {
            format!("the motions are {}", known.join(", "))
        };
        return Err(Error::input(
            subject.toml_path(),
            format!("no [motions] key '{name}' ({hint})"),
        ));
    };
    let path = subject.dir.join(rel);
    let bytes = std::fs::read(&path).map_err(|e| {
        if e.kind() == std::io::ErrorKind::NotFound {
            Error::input(
                &path,
                format!(
                    "file not found (named by [motions] key '{name}' in {})",
                    subject.toml_path().display()
                ),
            )
        } else {
            Error::io(&path, e)
        }
    })?;
    read_c3d_bytes(&bytes, &subject.labels, &path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    #[test]
    fn motions_table_is_read_and_a_missing_name_is_named() {
        let text = "name = \"A\"\nhand = \"right\"\nmarker_offset_mm = 4\n\n[motions]\n\
                    grasp_bottle = \"trials/grasp_bottle.c3d\"\n";
        let s = Subject::from_toml_str(text, Path::new("S01")).unwrap();
        let m = motion_paths_from_str(text, &s).unwrap();
        assert_eq!(m["grasp_bottle"], PathBuf::from("trials/grasp_bottle.c3d"));
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("subject.toml"), text).unwrap();
        let s = Subject::load(dir.path()).unwrap();
        let e = load_motion(&s, "pour").unwrap_err().to_string();
        assert!(
            e.contains("subject.toml") && e.contains("'pour'") && e.contains("grasp_bottle"),
            "{e}"
        );
        let e = load_motion(&s, "grasp_bottle").unwrap_err().to_string();
        assert!(
            e.contains("grasp_bottle.c3d") && e.contains("not found"),
            "{e}"
        );
        let bad = text.replace("\"trials/grasp_bottle.c3d\"", "3");
        assert!(Subject::from_toml_str(&bad, Path::new("S01")).is_err());
    }
}
