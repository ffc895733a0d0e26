//! Which simulator made a subject folder: a stamp (`synth-stamp.json`) beside the suite's
//! generated subjects, so that a folder made by an older simulator, or with other options, is
//! made again instead of being scored as if it were current.

use super::SynthOptions;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The simulator's revision. Raise it with every change that alters what [`super::simulate`]
/// produces for the same options (body, capture model, calipers, scan).
pub(crate) const REVISION: u32 = 6;

/// The stamp's file name inside a subject folder.
pub const FILE: &str = "synth-stamp.json";

#[derive(Serialize, Deserialize, PartialEq)]
struct Stamp {
    revision: u32,
    options: SynthOptions,
}

/// Whether `dir` holds a subject made by this revision of the simulator with `opts`.
pub fn is_current(dir: &Path, opts: &SynthOptions) -> bool {
    let Ok(text) = std::fs::read_to_string(dir.join(FILE)) else {
        return false;
    };
    let want = Stamp {
        revision: REVISION,
        options: opts.clone(),
    };
    serde_json::from_str::<Stamp>(&text).is_ok_and(|s| s == want) && dir.join("truth.json").exists()
}

/// Stamp `dir` as made by this revision with `opts`.
pub fn write(dir: &Path, opts: &SynthOptions) -> Result<()> {
    let stamp = Stamp {
        revision: REVISION,
        options: opts.clone(),
    };
    let json = serde_json::to_string_pretty(&stamp)
        .map_err(|e| Error::invalid(format!("synth stamp: {e}")))?;
    crate::io::atomic::write_bytes_atomic(&dir.join(FILE), json.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::Preset;

    #[test]
    fn a_stamp_is_current_only_for_its_options_and_revision() {
        let d = tempfile::tempdir().unwrap();
        let opts = SynthOptions::new(5, Preset::Typical);
        assert!(!is_current(d.path(), &opts), "no stamp");
        write(d.path(), &opts).unwrap();
        assert!(!is_current(d.path(), &opts), "no truth.json beside it");
        std::fs::write(d.path().join("truth.json"), "{}").unwrap();
        assert!(is_current(d.path(), &opts));
        assert!(!is_current(
            d.path(),
            &SynthOptions::new(6, Preset::Typical)
        ));
        let old = serde_json::json!({"revision": REVISION - 1, "options": opts});
        std::fs::write(d.path().join(FILE), old.to_string()).unwrap();
        assert!(!is_current(d.path(), &opts), "older simulator");
    }
}
