//! The validation suite's list of simulated subjects (`validation/suite.toml`).

use super::{Body, Posture, Preset, SynthOptions};
use crate::anatomy::Side;
use crate::error::{Error, Result};
use serde::Deserialize;
use std::path::Path;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SuiteFile {
    subject: Vec<SuiteEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SuiteEntry {
    name: String,
    seed: u64,
    preset: Preset,
    #[serde(default)]
    hand: Option<Side>,
    #[serde(default)]
    posture: Option<Posture>,
    /// The true hand's body (default template).
    #[serde(default)]
    body: Option<Body>,
    #[serde(default)]
    duration_s: Option<f64>,
    #[serde(default)]
    voxel_mm: Option<f64>,
    #[serde(default)]
    marker_offset_mm: Option<f64>,
    /// Capture session of the same hand (repeatability studies; default 0).
    #[serde(default)]
    repeat: Option<u32>,
}

/// Read a suite file: `(name, options)` per subject, in file order; names must be unique.
pub fn read_suite(path: &Path) -> Result<Vec<(String, SynthOptions)>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_suite(&text, path)
}

/// Parse a suite file's text (errors name `path`, the key and the line).
pub fn parse_suite(text: &str, path: &Path) -> Result<Vec<(String, SynthOptions)>> {
    let file: SuiteFile = toml::from_str(text).map_err(|e| Error::toml(path, text, &e))?;
    let mut out: Vec<(String, SynthOptions)> = Vec::new();
    for e in file.subject {
        if out.iter().any(|(n, _)| *n == e.name) {
            return Err(Error::input(
                path,
                format!("subject name '{}' is used twice", e.name),
            ));
        }
        let mut o = SynthOptions::new(e.seed, e.preset);
        o.hand = e.hand.unwrap_or(o.hand);
        o.posture = e.posture.unwrap_or(o.posture);
        o.body = e.body.unwrap_or(o.body);
        o.duration_s = e.duration_s;
        o.voxel_mm = e.voxel_mm.unwrap_or(o.voxel_mm);
        o.marker_offset_mm = e.marker_offset_mm.unwrap_or(o.marker_offset_mm);
        o.repeat = e.repeat.unwrap_or(o.repeat);
        out.push((e.name, o));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_suite_covers_presets_and_hands() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/suite.toml");
        let suite = read_suite(&path).unwrap();
        assert!(suite.len() >= 8);
        for p in Preset::ALL {
            assert!(suite.iter().any(|(_, o)| o.preset == p), "{p:?}");
        }
        for h in [Side::Right, Side::Left] {
            assert!(suite.iter().any(|(_, o)| o.hand == h), "{h}");
        }
        assert!(suite.iter().any(|(_, o)| o.posture == Posture::Varied));
    }

    #[test]
    fn bad_suite_entries_are_named() {
        let p = Path::new("suite.toml");
        let e = parse_suite(
            "[[subject]]\nname = \"a\"\nseed = 1\npreset = \"typcal\"\n",
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("suite.toml") && e.contains("typcal"), "{e}");
        let e = parse_suite(
            "[[subject]]\nname = \"a\"\nseed = 1\npreset = \"clean\"\nseeed = 2\n",
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("seeed"), "{e}");
    }
}
