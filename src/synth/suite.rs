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
    /// Length of a grasp motion trial, s (default: none, so that the suite's folders stay as
    /// they are unless an entry asks for one).
    #[serde(default)]
    motion_s: Option<f64>,
    /// Kept out of every choice of method or default: only scored (default false).
    #[serde(default)]
    held_out: bool,
}

/// One subject of a suite file.
#[derive(Clone, Debug, PartialEq)]
pub struct SuiteSubject {
    /// Its unique name (the folder under `subjects/`).
    pub name: String,
    /// How it is simulated.
    pub opts: SynthOptions,
    /// Held out of tuning: no method, parameter or default may be chosen by looking at its
    /// figures; it is only scored, so that the suite keeps an honest estimate.
    pub held_out: bool,
}

/// Read a suite file: `(name, options)` per subject, in file order; names must be unique.
pub fn read_suite(path: &Path) -> Result<Vec<(String, SynthOptions)>> {
    Ok(read_suite_subjects(path)?
        .into_iter()
        .map(|s| (s.name, s.opts))
        .collect())
}

/// Read a suite file with every subject's flags, in file order.
pub fn read_suite_subjects(path: &Path) -> Result<Vec<SuiteSubject>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse_suite(&text, path)
}

/// Parse a suite file's text (errors name `path`, the key and the line).
pub(crate) fn parse_suite(text: &str, path: &Path) -> Result<Vec<SuiteSubject>> {
    let file: SuiteFile = toml::from_str(text).map_err(|e| Error::toml(path, text, &e))?;
    let mut out: Vec<SuiteSubject> = Vec::new();
    for e in file.subject {
        if out.iter().any(|s| s.name == e.name) {
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
        o.motion_s = e.motion_s;
        out.push(SuiteSubject {
            name: e.name,
            opts: o,
            held_out: e.held_out,
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both bodies are covered alike: every preset, both hands and the varied posture, and
    /// each body keeps subjects held out of tuning.
    #[test]
    fn shipped_suite_covers_presets_hands_and_bodies() {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation/suite.toml");
        let suite = read_suite_subjects(&path).unwrap();
        assert!(suite.len() >= 16);
        for b in Body::ALL {
            let of: Vec<&SuiteSubject> = suite.iter().filter(|s| s.opts.body == b).collect();
            for p in Preset::ALL {
                assert!(of.iter().any(|s| s.opts.preset == p), "{b:?} {p:?}");
            }
            for h in [Side::Right, Side::Left] {
                assert!(of.iter().any(|s| s.opts.hand == h), "{b:?} {h}");
            }
            assert!(
                of.iter().any(|s| s.opts.posture == Posture::Varied),
                "{b:?}"
            );
            assert!(of.iter().any(|s| s.held_out), "{b:?} holds nothing out");
            assert!(
                of.iter().any(|s| !s.held_out),
                "{b:?} keeps nothing to tune on"
            );
        }
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
