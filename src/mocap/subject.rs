//! Subject folders: `subject.toml` (spec section 1) and the trials it names.
//!
//! The file is read with serde (`deny_unknown_fields` on every table with fixed keys; the keys of
//! `[trials]`, `[dimensions]` and `[labels]` are checked by hand against the spec's lists) and
//! every problem becomes one line naming the file, the key and its line, e.g.
//! `S01/subject.toml: unknown key 'marker_ofset_mm' at line 4 (expected one of name, hand, ...)`.
//!
//! Extensions beyond the spec: `hand` is accepted in any letter case; trial paths may also be
//! absolute (they are then used as they are; relative ones are taken relative to the folder).

use crate::anatomy::{Dimension, Finger, Side};
use crate::error::{Error, Result};
use crate::io::atomic::{read_bytes, write_atomic};
use crate::mocap::c3d::read_c3d_bytes;
use crate::mocap::trajectories::Trajectories;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// The file name of a subject's description inside its folder.
pub const SUBJECT_FILE: &str = "subject.toml";

/// Largest accepted `marker_offset_mm` (skin surface to marker centre), mm: a marker further
/// from the skin than this is not on a hand-sized plate.
pub(crate) const MAX_MARKER_OFFSET_MM: f64 = 30.0;

/// One of the seven trials of spec section 1, by its `[trials]` key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum TrialKind {
    /// `reference`: the static capture of all landmarks.
    Reference,
    /// `wrist`: circumduction of the hand about the wrist.
    Wrist,
    /// `thumb`, `index`, `middle`, `ring`, `little`: the finger's calibration motion.
    Finger(Finger),
}

impl TrialKind {
    /// All seven, in the spec's order.
    pub const ALL: [TrialKind; 7] = [
        TrialKind::Reference,
        TrialKind::Wrist,
        TrialKind::Finger(Finger::Thumb),
        TrialKind::Finger(Finger::Index),
        TrialKind::Finger(Finger::Middle),
        TrialKind::Finger(Finger::Ring),
        TrialKind::Finger(Finger::Little),
    ];

    /// The `[trials]` key: `reference`, `wrist`, `thumb`, ...
    pub fn key(self) -> &'static str {
        match self {
            TrialKind::Reference => "reference",
            TrialKind::Wrist => "wrist",
            TrialKind::Finger(f) => f.trial_name(),
        }
    }

    /// Position in [`TrialKind::ALL`] (the order `subject.toml` lists the trials in).
    pub fn order(self) -> usize {
        TrialKind::ALL
            .iter()
            .position(|k| *k == self)
            .unwrap_or(usize::MAX)
    }

    /// Parse a `[trials]` key.
    pub(crate) fn from_key(s: &str) -> Option<TrialKind> {
        TrialKind::ALL.into_iter().find(|k| k.key() == s)
    }
}

impl fmt::Display for TrialKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.key())
    }
}

/// A subject folder's description (`DIR/subject.toml`, spec section 1).
#[derive(Clone, Debug, PartialEq)]
pub struct Subject {
    /// The subject folder.
    pub dir: PathBuf,
    /// `name`.
    pub name: String,
    /// `hand`.
    pub hand: Side,
    /// `marker_offset_mm`: skin surface to marker centre, mm, in (0, 30].
    pub marker_offset_mm: f64,
    /// `reference_frame`: frame of the seated reference posture in every calibration trial.
    pub reference_frame: usize,
    /// `[trials]`: key -> path as written (relative to `dir` unless absolute).
    pub trials: BTreeMap<String, PathBuf>,
    /// `[dimensions]`: caliper measurements, mm.
    pub dimensions: BTreeMap<Dimension, f64>,
    /// `[labels]`: lab marker label -> spec name.
    pub labels: BTreeMap<String, String>,
    /// `[motions]` (optional): motion trial name -> path as written (relative to `dir` unless
    /// absolute), e.g. `grasp_bottle = "trials/grasp_bottle.c3d"`.
    pub motions: BTreeMap<String, PathBuf>,
}

/// The file as serde sees it; values are spanned so that validation errors can give the line.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSubject {
    name: Spanned<String>,
    hand: Spanned<String>,
    marker_offset_mm: Spanned<f64>,
    #[serde(default)]
    reference_frame: Option<Spanned<i64>>,
    #[serde(default)]
    trials: BTreeMap<Spanned<String>, Spanned<String>>,
    #[serde(default)]
    dimensions: BTreeMap<Spanned<String>, Spanned<f64>>,
    #[serde(default)]
    labels: BTreeMap<Spanned<String>, Spanned<String>>,
    #[serde(default)]
    motions: BTreeMap<Spanned<String>, Spanned<String>>,
}

impl Subject {
    /// Read and validate `dir/subject.toml`.
    pub fn load(dir: &Path) -> Result<Subject> {
        let path = dir.join(SUBJECT_FILE);
        let bytes = read_bytes(&path)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            Error::input(
                &path,
                format!("not UTF-8 text (byte {})", e.utf8_error().valid_up_to()),
            )
        })?;
        Subject::from_toml_str(&text, dir)
    }

    /// Parse and validate the text of a `subject.toml` for the folder `dir`; errors name
    /// `dir/subject.toml`, the key and its line.
    pub(crate) fn from_toml_str(text: &str, dir: &Path) -> Result<Subject> {
        let file = dir.join(SUBJECT_FILE);
        let raw: RawSubject = toml::from_str(text).map_err(|e| toml_error(&file, text, &e))?;
        let at = |span: std::ops::Range<usize>| line_of(text, span.start);
        let fail = |msg: String| Error::input(&file, msg);

        let name = raw.name.get_ref().trim().to_string();
        if name.is_empty() {
            return Err(fail(format!(
                "key 'name' at line {} is empty",
                at(raw.name.span())
            )));
        }
        let hand = match raw.hand.get_ref().to_ascii_lowercase().as_str() {
            "right" => Side::Right,
            "left" => Side::Left,
            other => {
                return Err(fail(format!(
                    "key 'hand' at line {} is '{other}' (expected \"right\" or \"left\")",
                    at(raw.hand.span())
                )))
            }
        };
        let offset = *raw.marker_offset_mm.get_ref();
        if !(offset.is_finite() && offset > 0.0 && offset <= MAX_MARKER_OFFSET_MM) {
            return Err(fail(format!(
                "key 'marker_offset_mm' at line {} is {offset} (expected a distance in mm in \
                 (0, {MAX_MARKER_OFFSET_MM}])",
                at(raw.marker_offset_mm.span())
            )));
        }
        let reference_frame = match &raw.reference_frame {
            None => 0,
            Some(r) => usize::try_from(*r.get_ref()).map_err(|_| {
                fail(format!(
                    "key 'reference_frame' at line {} is {} (expected a frame index >= 0)",
                    at(r.span()),
                    r.get_ref()
                ))
            })?,
        };

        let mut trials = BTreeMap::new();
        for (k, v) in &raw.trials {
            if TrialKind::from_key(k.get_ref()).is_none() {
                return Err(fail(format!(
                    "unknown [trials] key '{}' at line {} (expected one of {})",
                    k.get_ref(),
                    at(k.span()),
                    TrialKind::ALL.map(TrialKind::key).join(", ")
                )));
            }
            if v.get_ref().trim().is_empty() {
                return Err(fail(format!(
                    "[trials] key '{}' at line {} has an empty path",
                    k.get_ref(),
                    at(v.span())
                )));
            }
            trials.insert(k.get_ref().clone(), PathBuf::from(v.get_ref()));
        }

        let mut dimensions = BTreeMap::new();
        for (k, v) in &raw.dimensions {
            let key = k.get_ref();
            let line = at(v.span());
            let dim = Dimension::from_name(key).ok_or_else(|| {
                fail(format!(
                    "unknown [dimensions] key '{key}' at line {} (expected one of the 22 of the \
                     spec, e.g. wrist_breadth, finger2_breadth_distal; finger1 has no _distal)",
                    at(k.span())
                ))
            })?;
            let value = *v.get_ref();
            let (lo, hi) = dim.plausible_range_mm();
            if !value.is_finite() || value <= 0.0 {
                return Err(fail(format!(
                    "dimension '{key}' at line {line} is {value} (expected a positive length in mm)"
                )));
            }
            if value < lo || value > hi {
                return Err(fail(format!(
                    "dimension '{key}' at line {line} is {value} mm, absurd for a hand \
                     (plausible {lo} to {hi} mm): did you give metres/inches?"
                )));
            }
            dimensions.insert(dim, value);
        }

        let mut labels = BTreeMap::new();
        let mut targets: BTreeMap<&str, (&str, usize)> = BTreeMap::new();
        for (k, v) in &raw.labels {
            let (key, target) = (k.get_ref().as_str(), v.get_ref().as_str());
            let line = at(k.span());
            if key.is_empty() || key.trim() != key {
                return Err(fail(format!(
                    "[labels] key '{key}' at line {line} is empty or has leading/trailing blanks \
                     (C3D labels are compared trimmed)"
                )));
            }
            if target.trim().is_empty() {
                return Err(fail(format!(
                    "[labels] '{key}' at line {line} maps to an empty name"
                )));
            }
            if let Some((other, other_line)) = targets.insert(target, (key, line)) {
                return Err(fail(format!(
                    "[labels] '{other}' (line {other_line}) and '{key}' (line {line}) both map \
                     to '{target}'"
                )));
            }
            labels.insert(key.to_string(), target.to_string());
        }

        let mut motions = BTreeMap::new();
        for (k, v) in &raw.motions {
            let key = k.get_ref();
            if key.trim().is_empty() || key.trim() != key {
                return Err(fail(format!(
                    "[motions] key '{key}' at line {} is empty or has leading/trailing blanks",
                    at(k.span())
                )));
            }
            if v.get_ref().trim().is_empty() {
                return Err(fail(format!(
                    "[motions] key '{key}' at line {} has an empty path",
                    at(v.span())
                )));
            }
            motions.insert(key.clone(), PathBuf::from(v.get_ref()));
        }

        Ok(Subject {
            dir: dir.to_path_buf(),
            name,
            hand,
            marker_offset_mm: offset,
            reference_frame,
            trials,
            dimensions,
            labels,
            motions,
        })
    }

    /// `dir/subject.toml`.
    pub fn toml_path(&self) -> PathBuf {
        self.dir.join(SUBJECT_FILE)
    }

    /// The text of `subject.toml` in the spec's layout; [`Subject::from_toml_str`] of it gives
    /// back an equal `Subject`. Deterministic: tables in the spec's key order.
    pub(crate) fn to_toml_string(&self) -> String {
        let mut s = String::new();
        s.push_str(&format!("name = {}\n", quote(&self.name)));
        s.push_str(&format!("hand = {}\n", quote(self.hand.as_str())));
        s.push_str(&format!(
            "marker_offset_mm = {}\n",
            float(self.marker_offset_mm)
        ));
        s.push_str(&format!("reference_frame = {}\n", self.reference_frame));
        s.push_str("\n[trials]\n");
        let mut keys: Vec<&String> = self.trials.keys().collect();
        keys.sort_by_key(|k| TrialKind::from_key(k).map_or(usize::MAX, TrialKind::order));
        for k in keys {
            s.push_str(&format!(
                "{} = {}\n",
                quote(k),
                quote(&self.trials[k].to_string_lossy())
            ));
        }
        s.push_str("\n[dimensions]\n");
        for (d, v) in &self.dimensions {
            s.push_str(&format!("{} = {}\n", d.name(), float(*v)));
        }
        s.push_str("\n[labels]\n");
        for (k, v) in &self.labels {
            s.push_str(&format!("{} = {}\n", quote(k), quote(v)));
        }
        // Written only when there are motions, so that a folder without them reads byte for
        // byte as before.
        if !self.motions.is_empty() {
            s.push_str("\n[motions]\n");
            for (k, v) in &self.motions {
                s.push_str(&format!("{} = {}\n", quote(k), quote(&v.to_string_lossy())));
            }
        }
        s
    }

    /// Write `dir/subject.toml` atomically.
    pub fn save(&self) -> Result<()> {
        let text = self.to_toml_string();
        write_atomic(&self.toml_path(), |w| w.write_all(text.as_bytes()))
    }

    /// The path of a trial: `dir` joined with its `[trials]` entry. The error names the missing
    /// key.
    /// The error of a `[trials]` entry `key` whose file `path` does not exist.
    pub fn trial_not_found(&self, key: &str, path: &Path) -> Error {
        Error::input(
            path,
            format!(
                "file not found (named by [trials] key '{key}' in {})",
                self.toml_path().display()
            ),
        )
    }

    pub(crate) fn trial_path(&self, kind: TrialKind) -> Result<PathBuf> {
        match self.trials.get(kind.key()) {
            Some(p) => Ok(self.dir.join(p)),
            None => Err(Error::input(
                self.toml_path(),
                format!(
                    "no [trials] key '{k}' (add e.g. {k} = \"trials/{k}.c3d\")",
                    k = kind.key()
                ),
            )),
        }
    }

    /// The path of the motion trial `name`: `dir` joined with its `[motions]` entry. The error
    /// names the missing key.
    pub fn motion_path(&self, name: &str) -> Result<PathBuf> {
        match self.motions.get(name) {
            Some(p) => Ok(self.dir.join(p)),
            None => {
                let hint = if self.motions.is_empty() {
                    format!("there is no [motions] table; add e.g. {name} = \"trials/{name}.c3d\"")
                } else {
                    let known: Vec<&str> = self.motions.keys().map(String::as_str).collect();
                    format!("the motions are {}", known.join(", "))
                };
                Err(Error::input(
                    self.toml_path(),
                    format!("no [motions] key '{name}' ({hint})"),
                ))
            }
        }
    }

    /// Read the motion trial `name` with the subject's `[labels]` mapping.
    pub fn load_motion(&self, name: &str) -> Result<Trajectories> {
        let path = self.motion_path(name)?;
        let bytes = std::fs::read(&path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                Error::input(
                    &path,
                    format!(
                        "file not found (named by [motions] key '{name}' in {})",
                        self.toml_path().display()
                    ),
                )
            } else {
                Error::io(&path, e)
            }
        })?;
        read_c3d_bytes(&bytes, &self.labels, &path)
    }

    /// Read a trial with the subject's `[labels]` mapping. For a calibration trial (not the
    /// reference trial) `reference_frame` must be one of its frames.
    pub fn load_trial(&self, kind: TrialKind) -> Result<Trajectories> {
        let path = self.trial_path(kind)?;
        let bytes = std::fs::read(&path).map_err(|e| {
            if e.kind() == std::io::ErrorKind::NotFound {
                self.trial_not_found(kind.key(), &path)
            } else {
                Error::io(&path, e)
            }
        })?;
        let traj = read_c3d_bytes(&bytes, &self.labels, &path).map_err(|e| {
            e.named_by(format_args!(
                "[trials] key '{}' in {}",
                kind.key(),
                self.toml_path().display()
            ))
        })?;
        // A hand's size, whatever the file's POINT:UNITS says, and no marker far off.
        if let Some(units) = crate::mocap::c3d::point_units(&bytes) {
            crate::mocap::plausibility::check_hand_scale(&traj, units)?;
        }
        if kind == TrialKind::Reference {
            let found = crate::mocap::plausibility::landmark_chirality(&traj);
            if let Some(side) = found.filter(|s| *s != self.hand) {
                return Err(Error::input(
                    self.toml_path(),
                    format!(
                        "hand = \"{}\" but the landmarks of the static trial {} are those of a \
                         {side} hand (lateral wrist and MCP landmarks against the dorsal WRIST and \
                         M_MCP markers); fix `hand`",
                        self.hand,
                        path.display()
                    ),
                ));
            }
        }
        if kind != TrialKind::Reference && self.reference_frame >= traj.n_frames() {
            return Err(Error::input(
                &path,
                format!(
                    "reference_frame {} (subject.toml) is beyond the trial's {} frames",
                    self.reference_frame,
                    traj.n_frames()
                ),
            ));
        }
        Ok(traj)
    }

    /// Every trial of `[trials]` read once ([`Subject::load_trial`]), keyed by its `[trials]`
    /// key, with absurd single samples dropped before any fit sees them
    /// ([`crate::mocap::plausibility::drop_outliers`]), and a warning per marker that lost
    /// samples, naming the file.
    pub fn load_trials(&self) -> Result<(BTreeMap<String, Trajectories>, Vec<String>)> {
        let mut trials = BTreeMap::new();
        let mut warnings = Vec::new();
        for kind in TrialKind::ALL {
            let mut t = self.load_trial(kind)?;
            for (marker, n) in crate::mocap::plausibility::drop_outliers(&mut t) {
                warnings.push(format!(
                    "{}: marker {marker}: {n} samples dropped as outliers (more than {} mm \
                     beyond the marker's usual distance from its median position)",
                    t.source.display(),
                    crate::mocap::plausibility::OUTLIER_FLOOR_MM
                ));
            }
            trials.insert(kind.key().to_string(), t);
        }
        Ok((trials, warnings))
    }
}

/// 1-based line of byte `offset` in `text`.
fn line_of(text: &str, offset: usize) -> usize {
    let end = offset.min(text.len());
    text.as_bytes()[..end]
        .iter()
        .filter(|&&b| b == b'\n')
        .count()
        + 1
}

/// The key written on the line holding byte `offset` (`key = value`), unquoted.
fn key_on_line(text: &str, offset: usize) -> Option<String> {
    let line = text.lines().nth(line_of(text, offset) - 1)?;
    let (key, _) = line.split_once('=')?;
    let key = key.trim().trim_matches(|c| c == '"' || c == '\'');
    (!key.is_empty() && !key.starts_with('[')).then(|| key.to_string())
}

/// One line from a TOML/serde error: file, key, line, what was expected.
fn toml_error(file: &Path, text: &str, e: &toml::de::Error) -> Error {
    let msg = e
        .message()
        .lines()
        .map(str::trim)
        .collect::<Vec<_>>()
        .join("; ");
    let line = e.span().map(|s| line_of(text, s.start));
    let at = line.map_or(String::new(), |l| format!(" at line {l}"));
    let unquote = |s: &str| s.replace('`', "");
    if let Some(rest) = msg.strip_prefix("unknown field `") {
        if let Some((key, tail)) = rest.split_once('`') {
            let expected = tail.trim_start_matches(", expected ");
            return Error::input(
                file,
                format!("unknown key '{key}'{at} (expected {})", unquote(expected)),
            );
        }
    }
    if let Some(rest) = msg.strip_prefix("missing field `") {
        let key = rest.split('`').next().unwrap_or(rest);
        return Error::input(
            file,
            format!("missing key '{key}' (spec section 1 lists the keys of subject.toml)"),
        );
    }
    match e.span().and_then(|s| key_on_line(text, s.start)) {
        Some(key) => Error::input(file, format!("key '{key}'{at}: {msg}")),
        None => Error::input(file, format!("{msg}{at}")),
    }
}

/// A TOML basic string (TOML 1.0, "Basic strings": escape `"`, `\` and control characters).
fn quote(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

/// A finite f64 as a TOML float that parses back to the same value (Rust's shortest round-trip
/// formatting, with a `.0` where it would otherwise read as an integer).
fn float(v: f64) -> String {
    let s = format!("{v:?}");
    if s.contains(['.', 'e', 'E']) || !v.is_finite() {
        s
    } else {
        format!("{s}.0")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point;
    use crate::mocap::c3d::write_c3d;
    use proptest::prelude::*;

    #[test]
    fn motions_are_optional_read_and_written_back() {
        let dir = Path::new("/s");
        let base = "name = \"S\"\nhand = \"right\"\nmarker_offset_mm = 4.0\n";
        let plain = Subject::from_toml_str(base, dir).unwrap();
        assert!(plain.motions.is_empty());
        assert!(!plain.to_toml_string().contains("[motions]"));
        let text = format!("{base}[motions]\ngrasp_bottle = \"trials/grasp_bottle.c3d\"\n");
        let s = Subject::from_toml_str(&text, dir).unwrap();
        assert_eq!(
            s.motion_path("grasp_bottle").unwrap(),
            PathBuf::from("/s/trials/grasp_bottle.c3d")
        );
        assert_eq!(Subject::from_toml_str(&s.to_toml_string(), dir).unwrap(), s);
        let e = s.motion_path("pour").unwrap_err().to_string();
        assert!(e.contains("subject.toml") && e.contains("pour"), "{e}");
        let e = Subject::from_toml_str(&format!("{base}[motions]\ngrasp = \" \"\n"), dir)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("[motions]") && e.contains("grasp") && e.contains("line 5"),
            "{e}"
        );
    }

    /// The example of spec section 1 (all 22 dimensions, one label).
    const EXAMPLE: &str = r#"name = "S01"
hand = "right"                 # or "left"
marker_offset_mm = 4.0         # s_i: skin surface to marker centre
reference_frame = 0

[trials]                       # paths relative to the folder
reference = "trials/reference.c3d"
wrist  = "trials/wrist.c3d"
thumb  = "trials/thumb.c3d"
index  = "trials/index.c3d"
middle = "trials/middle.c3d"
ring   = "trials/ring.c3d"
little = "trials/little.c3d"

[dimensions]
wrist_breadth = 56.0
wrist_thickness = 38.5
hand_breadth_diagonal = 90.0
hand_thickness_mc3 = 27
finger1_breadth_proximal = 21.0
finger1_thickness_proximal = 19.0
finger2_breadth_proximal = 19.5
finger2_thickness_proximal = 17.0
finger3_breadth_proximal = 20.0
finger3_thickness_proximal = 17.5
finger4_breadth_proximal = 18.5
finger4_thickness_proximal = 16.0
finger5_breadth_proximal = 16.5
finger5_thickness_proximal = 14.0
finger2_breadth_distal = 16.0
finger2_thickness_distal = 13.5
finger3_breadth_distal = 16.5
finger3_thickness_distal = 14.0
finger4_breadth_distal = 15.5
finger4_thickness_distal = 13.0
finger5_breadth_distal = 14.0
finger5_thickness_distal = 11.5

[labels]
"LHand1" = "PALM_1"
"#;

    fn parse(text: &str) -> Result<Subject> {
        Subject::from_toml_str(text, Path::new("S01"))
    }

    /// The one-line error of `text`, checked to name S01/subject.toml.
    fn err(text: &str) -> String {
        let e = parse(text).unwrap_err().to_string();
        assert!(e.starts_with("S01/subject.toml: "), "{e}");
        assert!(!e.contains('\n'), "{e}");
        e
    }

    #[test]
    fn spec_example_parses() {
        let s = parse(EXAMPLE).unwrap();
        assert_eq!(s.name, "S01");
        assert_eq!(s.hand, Side::Right);
        assert_eq!(s.marker_offset_mm, 4.0);
        assert_eq!(s.reference_frame, 0);
        assert_eq!(s.trials.len(), 7);
        assert_eq!(s.trials["ring"], PathBuf::from("trials/ring.c3d"));
        assert_eq!(s.dimensions.len(), 22);
        assert_eq!(s.dimensions[&Dimension::HandThicknessMc3], 27.0);
        assert_eq!(s.dimensions[&Dimension::BreadthDistal(Finger::Index)], 16.0);
        assert_eq!(s.labels["LHand1"], "PALM_1");
        assert_eq!(
            s.trial_path(TrialKind::Finger(Finger::Ring)).unwrap(),
            Path::new("S01/trials/ring.c3d")
        );
    }

    #[test]
    fn defaults_and_minimal_file() {
        let s = parse("name = \"A\"\nhand = \"Left\"\nmarker_offset_mm = 30\n").unwrap();
        assert_eq!(s.hand, Side::Left);
        assert_eq!(s.reference_frame, 0);
        assert!(s.trials.is_empty() && s.dimensions.is_empty() && s.labels.is_empty());
        let e = s.trial_path(TrialKind::Wrist).unwrap_err().to_string();
        assert!(
            e.starts_with("S01/subject.toml: ") && e.contains("'wrist'"),
            "{e}"
        );
    }

    #[test]
    fn toml_round_trip_and_save_load() {
        let mut s = parse(EXAMPLE).unwrap();
        s.reference_frame = 12;
        s.marker_offset_mm = 0.1 + 0.2; // not exactly representable in decimal
        s.name = "Ünïcode \"quoted\" \\ name".into();
        s.labels.insert("S01:weird label".into(), "I_NAIL".into());
        s.trials
            .insert("wrist".into(), PathBuf::from("/abs/wrist.c3d"));
        let text = s.to_toml_string();
        assert_eq!(parse(&text).unwrap(), s);
        // Deterministic.
        assert_eq!(text, s.to_toml_string());

        let dir = tempfile::tempdir().unwrap();
        s.dir = dir.path().to_path_buf();
        s.save().unwrap();
        assert_eq!(Subject::load(dir.path()).unwrap(), s);
        // An absolute trial path is used as it is.
        assert_eq!(
            s.trial_path(TrialKind::Wrist).unwrap(),
            Path::new("/abs/wrist.c3d")
        );
    }

    #[test]
    fn unknown_key_names_key_line_and_choices() {
        let text = EXAMPLE.replace("marker_offset_mm = 4.0", "marker_ofset_mm = 4.0");
        let e = err(&text);
        assert!(
            e.contains("unknown key 'marker_ofset_mm' at line 3")
                && e.contains("expected one of name, hand"),
            "{e}"
        );
        let e = err(&EXAMPLE.replace("[labels]", "[labels]\n[extra]\nx = 1"));
        assert!(e.contains("unknown key 'extra'"), "{e}");
    }

    #[test]
    fn bad_values_name_the_item() {
        let cases: [(&str, &str, &[&str]); 12] = [
            (
                "hand = \"right\"",
                "hand = \"rigth\"",
                &["'hand'", "line 2", "rigth"],
            ),
            ("hand = \"right\"", "hand = 1", &["'hand'", "line 2"]),
            (
                "marker_offset_mm = 4.0",
                "marker_offset_mm = 0.0",
                &["'marker_offset_mm'", "line 3"],
            ),
            (
                "marker_offset_mm = 4.0",
                "marker_offset_mm = 31",
                &["'marker_offset_mm'"],
            ),
            (
                "marker_offset_mm = 4.0",
                "marker_offset_mm = \"four\"",
                &["'marker_offset_mm'", "line 3"],
            ),
            (
                "reference_frame = 0",
                "reference_frame = -2",
                &["'reference_frame'", "line 4"],
            ),
            (
                "wrist_breadth = 56.0",
                "wrist_breadth = 0.056",
                &["'wrist_breadth'", "line 16", "absurd", "metres/inches"],
            ),
            (
                "wrist_breadth = 56.0",
                "wrist_breadth = -56.0",
                &["'wrist_breadth'", "positive"],
            ),
            (
                "wrist_breadth = 56.0",
                "wrist_breadth = nan",
                &["'wrist_breadth'"],
            ),
            (
                "wrist_breadth = 56.0",
                "finger1_breadth_distal = 15.0",
                &["'finger1_breadth_distal'", "line 16"],
            ),
            (
                "ring   = \"trials/ring.c3d\"",
                "rnig = \"trials/ring.c3d\"",
                &["'rnig'", "line 12", "reference, wrist"],
            ),
            (
                "\"LHand1\" = \"PALM_1\"",
                "\"LHand1\" = \"PALM_1\"\n\"LH1\" = \"PALM_1\"",
                &["'LHand1'", "'LH1'", "'PALM_1'"],
            ),
        ];
        for (from, to, wants) in cases {
            assert!(EXAMPLE.contains(from), "{from}");
            let e = err(&EXAMPLE.replacen(from, to, 1));
            for w in wants {
                assert!(e.contains(w), "{to}: missing {w} in {e}");
            }
        }
        let e = err(&EXAMPLE.replace("hand = \"right\"                 # or \"left\"\n", ""));
        assert!(e.contains("missing key 'hand'"), "{e}");
        assert!(err("name = ").contains("line 1"));
    }

    #[test]
    fn missing_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let e = Subject::load(dir.path()).unwrap_err().to_string();
        assert!(e.contains("subject.toml"), "{e}");
        let mut s = parse(EXAMPLE).unwrap();
        s.dir = dir.path().to_path_buf();
        let e = s
            .load_trial(TrialKind::Finger(Finger::Index))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("trials/index.c3d") && e.contains("'index'"),
            "{e}"
        );
        assert!(!e.contains('\n'));
    }

    #[test]
    fn load_trial_applies_labels_and_checks_reference_frame() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("trials")).unwrap();
        let mut s = parse(EXAMPLE).unwrap();
        s.dir = dir.path().to_path_buf();
        let t = Trajectories::new(
            100.0,
            vec!["LHand1".into(), "Sub:PALM_2".into()],
            vec![vec![Some(Point::new(1.0, 2.0, 3.0)); 4], vec![None; 4]],
            "x",
        )
        .unwrap();
        write_c3d(&dir.path().join("trials/index.c3d"), &t).unwrap();
        let got = s.load_trial(TrialKind::Finger(Finger::Index)).unwrap();
        assert_eq!(got.labels, ["PALM_1", "PALM_2"]);
        assert_eq!(got.get("PALM_1", 3), Some(Point::new(1.0, 2.0, 3.0)));
        s.reference_frame = 4;
        let e = s
            .load_trial(TrialKind::Finger(Finger::Index))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("reference_frame 4") && e.contains("index.c3d"),
            "{e}"
        );
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(256))]

        #[test]
        fn mutated_toml_never_panics(
            cut in 0usize..2000,
            edits in proptest::collection::vec((0usize..2000, any::<char>()), 0..6)
        ) {
            let mut chars: Vec<char> = EXAMPLE.chars().collect();
            for (at, c) in edits {
                let n = chars.len();
                chars[at % n] = c;
            }
            chars.truncate(cut);
            let text: String = chars.into_iter().collect();
            match parse(&text) {
                Ok(s) => prop_assert_eq!(parse(&s.to_toml_string()).unwrap(), s),
                Err(e) => {
                    let e = e.to_string();
                    prop_assert!(e.starts_with("S01/subject.toml: ") && !e.contains('\n'), "{}", e);
                }
            }
        }
    }
}
