//! Accuracy regression thresholds: the figures a reconstruction of a simulated subject
//! must not exceed, kept in `validation/thresholds.toml` and set from measured figures with a
//! documented margin (see the file's header). Used by `ergohand validate --suite` (the whole
//! suite, table `[subject.NAME]`) and by `tests/accuracy_regression.rs` (the CI subset, table
//! `[ci]`: a few suite subjects with shorter trials, so with thresholds of their own).
//!
//! The figures ([`FIGURES`]) are the seed paper's section 5 measures: skin-to-reference distance
//! (mean and max, section 5.2), caliper dimensions on the skin (5.1), joint centres and axes
//! against the truth (medians per joint class), plus the fit's landmark residuals and the
//! validity checks (no inverted skin face, no inverted tetrahedron).

use super::{DimensionAccuracy, LinkAccuracy, SurfaceError};
use crate::anatomy::Joint;
use crate::error::{Error, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::fmt;
use std::path::Path;

/// The thresholds file's name inside a suite folder.
pub const FILE: &str = "thresholds.toml";

/// Every figure checked: name (as in the thresholds file) and what it is.
pub(crate) const FIGURES: [(&str, &str); 9] = [
    (
        "skin_mean_mm",
        "mean distance of skin.obj to reference.ply, mm",
    ),
    (
        "skin_max_mm",
        "largest distance of skin.obj to reference.ply, mm",
    ),
    (
        "dimension_error_mm",
        "largest |caliper dimension on skin.obj - given|, mm",
    ),
    (
        "centre_3dof_median_mm",
        "median joint-centre error of the 3-DOF joints against truth.json, mm",
    ),
    (
        "centre_1dof_median_mm",
        "median joint-centre error of the 1-DOF joints against truth.json, mm",
    ),
    (
        "axis_median_deg",
        "median 1-DOF axis error against truth.json, degrees",
    ),
    (
        "landmark_residual_max_mm",
        "largest landmark residual of the skin fit (report.json), mm",
    ),
    (
        "inverted_faces",
        "skin faces turned over by the fit (report.json)",
    ),
    (
        "inverted_tets",
        "inverted tetrahedra of the subject's mesh (report.json)",
    ),
];

/// The measured figures of one subject, by [`FIGURES`] name.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Figures(pub BTreeMap<String, f64>);

impl Figures {
    /// The figures of a validated reconstruction: the comparisons made by `validate` and the
    /// residuals and checks of `MODEL/report.json`.
    pub fn measure(
        link: &LinkAccuracy,
        surface: &SurfaceError,
        dims: &DimensionAccuracy,
        model: &Path,
    ) -> Result<Figures> {
        let path = model.join("report.json");
        let text = std::fs::read_to_string(&path).map_err(|e| Error::io(&path, e))?;
        let report: serde_json::Value = serde_json::from_str(&text)
            .map_err(|e| Error::input(&path, format!("not JSON: {e}")))?;
        let field = |v: &serde_json::Value, name: &str| {
            v.as_f64()
                .ok_or_else(|| Error::input(&path, format!("no number '{name}'")))
        };
        let landmark = report["skin"]["landmark_residuals_mm"]
            .as_object()
            .ok_or_else(|| Error::input(&path, "no object 'skin.landmark_residuals_mm'"))?
            .values()
            .filter_map(serde_json::Value::as_f64)
            .fold(0.0, f64::max);
        let median_centre = |dof: usize| {
            median(
                link.joints
                    .iter()
                    .filter(|e| Joint::from_name(&e.joint).map(|j| j.dof()) == Some(dof))
                    .map(|e| e.centre_mm)
                    .collect(),
            )
        };
        let v = [
            ("skin_mean_mm", surface.mean_mm),
            ("skin_max_mm", surface.max_mm),
            (
                "dimension_error_mm",
                dims.dimensions
                    .iter()
                    .map(|d| (d.skin_mm - d.given_mm).abs())
                    .fold(0.0, f64::max),
            ),
            ("centre_3dof_median_mm", median_centre(3)),
            ("centre_1dof_median_mm", median_centre(1)),
            (
                "axis_median_deg",
                median(link.joints.iter().filter_map(|e| e.axis_deg).collect()),
            ),
            ("landmark_residual_max_mm", landmark),
            (
                "inverted_faces",
                field(&report["skin"]["inverted_faces"], "skin.inverted_faces")?,
            ),
            (
                "inverted_tets",
                field(&report["tet"]["inverted"], "tet.inverted")?,
            ),
        ];
        Ok(Figures(
            v.into_iter().map(|(k, x)| (k.to_string(), x)).collect(),
        ))
    }
}

/// Median (upper for an even count); NaN for none, which every check flags.
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Upper limits per figure ([`FIGURES`] names); a figure without a limit is not checked.
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(transparent)]
pub struct Limits(pub BTreeMap<String, f64>);

/// The CI subset: suite subjects re-simulated with shorter trials.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CiSubset {
    /// Length of every calibration trial, s (replaces the suite's).
    pub duration_s: f64,
    /// Voxel size of the CT-like reference, mm (default: the suite's).
    #[serde(default)]
    pub voxel_mm: Option<f64>,
    /// Limits per suite subject name; these subjects make the subset.
    pub subject: BTreeMap<String, Limits>,
}

/// `validation/thresholds.toml`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Thresholds {
    /// Limits of a suite subject without a table of its own.
    pub default: Limits,
    /// Limits per suite subject (each figure given replaces the default's).
    #[serde(default)]
    pub subject: BTreeMap<String, Limits>,
    /// The CI subset.
    pub ci: CiSubset,
}

/// A figure worse than its threshold.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Regression {
    /// The subject.
    pub subject: String,
    /// The figure's name.
    pub figure: String,
    /// Its value (NaN when it could not be measured).
    pub value: f64,
    /// The threshold.
    pub threshold: f64,
}

impl fmt::Display for Regression {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: {} = {:.4} is worse than its threshold {}",
            self.subject, self.figure, self.value, self.threshold
        )
    }
}

impl Thresholds {
    /// Read and check a thresholds file: every figure name must be one of [`FIGURES`] and every
    /// limit finite; errors name the file, the table and the key.
    pub fn load(path: &Path) -> Result<Thresholds> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
        Thresholds::parse(&text, path)
    }

    /// [`Thresholds::load`] from text.
    pub fn parse(text: &str, path: &Path) -> Result<Thresholds> {
        let t: Thresholds = toml::from_str(text).map_err(|e| Error::toml(path, text, &e))?;
        let tables = std::iter::once(("default".to_string(), &t.default))
            .chain(t.subject.iter().map(|(k, v)| (format!("subject.{k}"), v)))
            .chain(
                t.ci.subject
                    .iter()
                    .map(|(k, v)| (format!("ci.subject.{k}"), v)),
            );
        for (table, limits) in tables {
            for (k, x) in &limits.0 {
                if !FIGURES.iter().any(|(n, _)| n == k) {
                    let names: Vec<&str> = FIGURES.iter().map(|(n, _)| *n).collect();
                    return Err(Error::input(
                        path,
                        format!(
                            "[{table}]: unknown figure '{k}' (expected one of {})",
                            names.join(", ")
                        ),
                    ));
                }
                if !x.is_finite() {
                    return Err(Error::input(
                        path,
                        format!("[{table}] {k}: give a finite threshold"),
                    ));
                }
            }
        }
        if !(t.ci.duration_s.is_finite() && t.ci.duration_s > 0.0) {
            return Err(Error::input(
                path,
                "[ci] duration_s: give a positive length in s",
            ));
        }
        Ok(t)
    }

    /// The limits of suite subject `name`: the default's, with its own table's on top.
    pub(crate) fn suite_limits(&self, name: &str) -> Limits {
        let mut l = self.default.clone();
        if let Some(own) = self.subject.get(name) {
            l.0.extend(own.0.iter().map(|(k, v)| (k.clone(), *v)));
        }
        l
    }
}

/// The figures of `subject` worse than `limits` (a figure above its threshold, or not measured
/// although a threshold is set).
pub fn check(subject: &str, figures: &Figures, limits: &Limits) -> Vec<Regression> {
    limits
        .0
        .iter()
        .filter_map(|(k, &threshold)| {
            let value = figures.0.get(k).copied().unwrap_or(f64::NAN);
            (value.is_nan() || value > threshold).then(|| Regression {
                subject: subject.to_string(),
                figure: k.clone(),
                value,
                threshold,
            })
        })
        .collect()
}

/// One line listing `regressions` (at most five, then a count), for an error.
pub fn describe(regressions: &[Regression]) -> String {
    let mut s = regressions
        .iter()
        .take(5)
        .map(Regression::to_string)
        .collect::<Vec<_>>()
        .join("; ");
    if regressions.len() > 5 {
        s.push_str(&format!("; and {} more", regressions.len() - 5));
    }
    s
}

/// `validate --suite`: the suite's figures against `path` (a suite folder's
/// `thresholds.toml`); an error naming every regressed subject and figure. A suite without a
/// thresholds file is not checked.
pub fn check_suite(path: &Path, figures: &[(String, Figures)]) -> Result<()> {
    if !path.exists() {
        return Ok(());
    }
    let t = Thresholds::load(path)?;
    let r: Vec<Regression> = figures
        .iter()
        .flat_map(|(name, f)| check(name, f, &t.suite_limits(name)))
        .collect();
    if r.is_empty() {
        return Ok(());
    }
    Err(Error::input(
        path,
        format!("{} accuracy regressions: {}", r.len(), describe(&r)),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn figs(pairs: &[(&str, f64)]) -> Figures {
        Figures(pairs.iter().map(|(k, v)| (k.to_string(), *v)).collect())
    }

    #[test]
    fn a_figure_above_its_threshold_is_named() {
        let limits = Limits(
            [("skin_mean_mm", 0.6), ("inverted_tets", 0.0)]
                .iter()
                .map(|(k, v)| (k.to_string(), *v))
                .collect(),
        );
        assert!(check(
            "s",
            &figs(&[("skin_mean_mm", 0.6), ("inverted_tets", 0.0)]),
            &limits
        )
        .is_empty());
        let r = check(
            "s",
            &figs(&[("skin_mean_mm", 0.61), ("inverted_tets", 1.0)]),
            &limits,
        );
        assert_eq!(r.len(), 2);
        assert!(
            r[1].to_string().contains("s: skin_mean_mm = 0.6100"),
            "{}",
            r[1]
        );
        assert_eq!(r[0].figure, "inverted_tets");
        // Not measured, or NaN: flagged.
        let r = check("s", &figs(&[("skin_mean_mm", f64::NAN)]), &limits);
        assert_eq!(r.len(), 2);
    }

    #[test]
    fn subject_tables_override_the_default() {
        let text = "[default]\nskin_mean_mm = 1.0\nskin_max_mm = 5.0\n[subject.a]\nskin_mean_mm = 0.5\n[ci]\nduration_s = 10\n[ci.subject.a]\nskin_mean_mm = 0.7\n";
        let t = Thresholds::parse(text, Path::new("t.toml")).unwrap();
        assert_eq!(t.suite_limits("a").0["skin_mean_mm"], 0.5);
        assert_eq!(t.suite_limits("a").0["skin_max_mm"], 5.0);
        assert_eq!(t.suite_limits("b").0["skin_mean_mm"], 1.0);
        assert_eq!(t.ci.subject["a"].0["skin_mean_mm"], 0.7);
        let bad = text.replace("[subject.a]\nskin_mean_mm", "[subject.a]\nskin_mean");
        let e = Thresholds::parse(&bad, Path::new("t.toml"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.toml") && e.contains("subject.a") && e.contains("skin_mean"),
            "{e}"
        );
    }

    #[test]
    fn shipped_thresholds_cover_the_suite() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation");
        let t = Thresholds::load(&dir.join(FILE)).unwrap();
        let suite = crate::synth::suite::read_suite(&dir.join("suite.toml")).unwrap();
        let names: Vec<&str> = suite.iter().map(|(n, _)| n.as_str()).collect();
        for n in t.subject.keys().chain(t.ci.subject.keys()) {
            assert!(names.contains(&n.as_str()), "{n} is not a suite subject");
        }
        for n in &names {
            assert_eq!(t.suite_limits(n).0.len(), FIGURES.len(), "{n}");
        }
        for l in t.ci.subject.values() {
            assert_eq!(l.0.len(), FIGURES.len());
        }
    }

    #[test]
    fn check_suite_reports_regressions_in_one_line() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join(FILE);
        assert!(
            check_suite(&p, &[("a".into(), figs(&[]))]).is_ok(),
            "no file: no check"
        );
        std::fs::write(
            &p,
            "[default]\nskin_max_mm = 3.0\n[ci]\nduration_s = 5\nsubject = {}\n",
        )
        .unwrap();
        let ok = [("a".to_string(), figs(&[("skin_max_mm", 2.0)]))];
        assert!(check_suite(&p, &ok).is_ok());
        let bad = [("b".to_string(), figs(&[("skin_max_mm", 3.5)]))];
        let e = check_suite(&p, &bad).unwrap_err().to_string();
        assert!(
            !e.contains('\n') && e.contains("b: skin_max_mm") && e.contains(FILE),
            "{e}"
        );
    }
}
