//! Checks of a command's output paths, made before any work so that a wrong `--out` costs
//! nothing and never overwrites an input.
//!
//! A path is refused when
//! - an existing ancestor of it is a file, not a folder (the folder cannot be made);
//! - it is an existing folder where a file is written, or an existing file where a folder is;
//! - it is one of the command's inputs (the same file, through any link or spelling: compared
//!   by device and inode on Unix, by canonical path elsewhere), or lies in a model folder under
//!   the name of one of that folder's own files ([`MODEL_FILES`]).

use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

/// The files `reconstruct` writes into its `--out` folder (spec section 3 and its extensions):
/// the model that `pose`, `validate` and `grasp` read.
pub const MODEL_FILES: [&str; 7] = [
    "link_model.json",
    "skin_low.obj",
    "skin.obj",
    "tet.vtk",
    "tet.msh",
    "hand.glb",
    "report.json",
];

/// What a command reads: files, and model folders whose [`MODEL_FILES`] are inputs whether or
/// not they exist yet.
#[derive(Clone, Debug, Default)]
pub struct Inputs {
    /// Files read (missing ones are ignored: nothing can be overwritten there).
    pub files: Vec<PathBuf>,
    /// `reconstruct` folders read.
    pub model_dirs: Vec<PathBuf>,
}

impl Inputs {
    /// The inputs of a command reading `files`.
    pub fn files(files: impl IntoIterator<Item = PathBuf>) -> Self {
        Inputs {
            files: files.into_iter().collect(),
            model_dirs: Vec::new(),
        }
    }

    /// Add a model folder: its [`MODEL_FILES`] are inputs.
    pub fn with_model(mut self, dir: &Path) -> Self {
        self.model_dirs.push(dir.to_path_buf());
        self
    }

    /// Which input `path` is, if any: a description for the error.
    fn clash(&self, path: &Path) -> Option<String> {
        for dir in &self.model_dirs {
            let name = path.file_name().and_then(|n| n.to_str());
            if let (Some(name), Some(parent)) = (name, path.parent()) {
                let parent = if parent.as_os_str().is_empty() {
                    Path::new(".")
                } else {
                    parent
                };
                if MODEL_FILES.contains(&name) && same_place(parent, dir) {
                    return Some(format!("the model's own {name} (in {})", dir.display()));
                }
            }
        }
        self.files
            .iter()
            .find(|f| same_place(path, f))
            .map(|f| format!("an input of this command ({})", f.display()))
    }
}

/// Check that `path` can be written as a file by a command reading `inputs`; `flag` is the
/// option that named it (for the message).
pub fn check_output_file(path: &Path, flag: &str, inputs: &Inputs) -> Result<()> {
    if path.is_dir() {
        return Err(Error::input(
            path,
            format!("{flag} names a folder; give a file name"),
        ));
    }
    let parent = path.parent().unwrap_or(Path::new(""));
    check_ancestors(parent, path, flag)?;
    if let Some(what) = inputs.clash(path) {
        return Err(Error::input(
            path,
            format!("{flag} would overwrite {what}; choose another output"),
        ));
    }
    Ok(())
}

/// Check that `dir` can be made (or is) a folder into which `files` are written by a command
/// reading `inputs`; `flag` is the option that named it.
pub fn check_output_dir(dir: &Path, files: &[&str], flag: &str, inputs: &Inputs) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::input(
            dir,
            format!("{flag} names an existing file; give a folder"),
        ));
    }
    check_ancestors(dir, dir, flag)?;
    for f in files {
        let path = dir.join(f);
        if path.is_dir() {
            return Err(Error::input(
                &path,
                format!("is a folder where {flag} would write a file"),
            ));
        }
        if let Some(what) = inputs.clash(&path) {
            return Err(Error::input(
                &path,
                format!("{flag} would overwrite {what}; choose another output folder"),
            ));
        }
    }
    Ok(())
}

/// The nearest existing ancestor of `dir` (itself included) must be a folder; `named` is the
/// path the user gave, named in the error.
fn check_ancestors(dir: &Path, named: &Path, flag: &str) -> Result<()> {
    for a in dir.ancestors() {
        if a.as_os_str().is_empty() {
            break;
        }
        if let Ok(m) = std::fs::metadata(a) {
            if !m.is_dir() {
                return Err(Error::input(
                    named,
                    format!(
                        "{flag} cannot be made: {} is a file, not a folder",
                        a.display()
                    ),
                ));
            }
            break;
        }
    }
    Ok(())
}

/// Whether `a` and `b` are the same existing file or folder.
fn same_place(a: &Path, b: &Path) -> bool {
    let (Ok(ma), Ok(mb)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        ma.dev() == mb.dev() && ma.ino() == mb.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (ma, mb);
        matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refuses_inputs_model_files_and_wrong_kinds() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let model = d.join("model");
        std::fs::create_dir(&model).unwrap();
        std::fs::write(model.join("skin.obj"), "v 0 0 0\n").unwrap();
        let pose = d.join("pose.toml");
        std::fs::write(&pose, "").unwrap();
        let inputs = Inputs::files([pose.clone()]).with_model(&model);

        // The model's skin, through another spelling of the same path.
        let spelled = model.join("..").join("model").join("skin.obj");
        let e = check_output_file(&spelled, "--out", &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("skin.obj") && e.contains("model's own"), "{e}");
        // A model file not written yet is the model's all the same.
        let e = check_output_file(&model.join("tet.msh"), "--out", &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("tet.msh"), "{e}");
        // A hard link to an input is that input.
        let link = d.join("link.toml");
        std::fs::hard_link(&pose, &link).unwrap();
        let e = check_output_file(&link, "--out", &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("an input"), "{e}");
        // A folder where a file goes, a file where a folder goes, a file as an ancestor.
        assert!(check_output_file(&model, "--out", &inputs).is_err());
        assert!(check_output_dir(&pose, &["a.json"], "--out", &inputs).is_err());
        let e = check_output_file(&pose.join("x/y.obj"), "--out", &inputs)
            .unwrap_err()
            .to_string();
        assert!(e.contains("is a file, not a folder"), "{e}");
        // A folder output whose file would overwrite the model's.
        assert!(check_output_dir(&model, &["skin.obj"], "--out", &inputs).is_err());
        // What is fine: a new file in the model folder under another name, a new nested folder.
        check_output_file(&model.join("fist.obj"), "--out", &inputs).unwrap();
        check_output_dir(&d.join("a/b/c"), &["grasp.json"], "--out", &inputs).unwrap();
        check_output_file(Path::new("fist.obj"), "--out", &inputs).unwrap();
    }
}
