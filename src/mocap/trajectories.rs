//! Marker trajectories: the labelled 3D marker positions of one trial, in millimetres in the lab
//! frame, with gaps. Every later stage (link model, skin fit) reads its markers through this type.
//!
//! Marker names are the canonical names of the subject-format spec
//! (`shared/spec/subject-format.md`, section 2) once the readers have applied a subject's
//! `[labels]` mapping; a missing sample (a C3D residual below zero or non-finite coordinates,
//! spec section 2) is `None`.

use crate::anatomy::{arm_markers, landmark_names, tip_marker_names, Link};
use crate::error::{Error, Result};
use crate::geometry::Point;
use std::collections::BTreeMap;
use std::ops::Range;
use std::path::PathBuf;

/// The marker data of one trial.
#[derive(Clone, Debug, PartialEq)]
pub struct Trajectories {
    /// Sampling rate, Hz (C3D `POINT:RATE`).
    pub frame_rate: f64,
    /// Canonical (spec) names, after the `[labels]` mapping; unique.
    pub labels: Vec<String>,
    /// `positions[marker][frame]`, mm, lab frame; `None` = missing sample.
    pub positions: Vec<Vec<Option<Point>>>,
    /// The file the data came from, named in every error about it.
    pub source: PathBuf,
}

impl Trajectories {
    /// Build and check a trajectory set: one track per label, every track as long as the first,
    /// at least one frame, a finite positive frame rate and unique labels. Errors name `source`.
    pub fn new(
        frame_rate: f64,
        labels: Vec<String>,
        positions: Vec<Vec<Option<Point>>>,
        source: impl Into<PathBuf>,
    ) -> Result<Trajectories> {
        let source = source.into();
        if !(frame_rate.is_finite() && frame_rate > 0.0) {
            return Err(Error::input(
                &source,
                format!("frame rate {frame_rate} Hz is not a positive number"),
            ));
        }
        if labels.len() != positions.len() {
            return Err(Error::input(
                &source,
                format!(
                    "{} marker labels for {} marker tracks",
                    labels.len(),
                    positions.len()
                ),
            ));
        }
        let n = positions.first().map_or(0, Vec::len);
        if n == 0 {
            return Err(Error::input(&source, "the trial has no frames"));
        }
        if let Some((i, t)) = positions.iter().enumerate().find(|(_, t)| t.len() != n) {
            return Err(Error::input(
                &source,
                format!(
                    "marker '{}' has {} frames, the others {n}",
                    labels[i],
                    t.len()
                ),
            ));
        }
        check_unique_labels(&labels).map_err(|m| Error::input(&source, m))?;
        Ok(Trajectories {
            frame_rate,
            labels,
            positions,
            source,
        })
    }

    /// Number of frames (0 for a set without markers).
    pub fn n_frames(&self) -> usize {
        self.positions.first().map_or(0, Vec::len)
    }

    /// Index of marker `name` in `labels` / `positions`.
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.labels.iter().position(|l| l == name)
    }

    /// The whole track of marker `name`.
    pub fn track(&self, name: &str) -> Option<&[Option<Point>]> {
        self.index_of(name).map(|i| self.positions[i].as_slice())
    }

    /// Position of `name` at `frame`; `None` when the marker, the frame or the sample is missing.
    pub fn get(&self, name: &str, frame: usize) -> Option<Point> {
        self.track(name)?.get(frame).copied().flatten()
    }

    /// Check that every marker of `names` is in the trial and has at least one valid sample.
    /// The error names the trial file and the FIRST marker (in the order of `names`) that fails.
    pub fn require(&self, names: &[&str]) -> Result<()> {
        for name in names {
            match self.track(name) {
                None => {
                    return Err(Error::input(
                        &self.source,
                        format!(
                            "marker '{name}' is missing (the trial has {} markers{}); label it in \
                             the capture software or map the lab's label to it in [labels] of \
                             subject.toml",
                            self.labels.len(),
                            label_preview(&self.labels)
                        ),
                    ))
                }
                Some(t) if t.iter().all(Option::is_none) => {
                    return Err(Error::input(
                        &self.source,
                        format!(
                            "marker '{name}' has no valid sample in any of the {} frames",
                            t.len()
                        ),
                    ))
                }
                Some(_) => {}
            }
        }
        Ok(())
    }

    /// Check that every marker of `names` is present and visible in `frame`: the reference frame
    /// of a calibration trial, where every registration of the seed paper's equation 1 is
    /// anchored (a marker occluded there cannot be registered). The error names the trial file,
    /// the marker and the frame.
    pub fn require_at(&self, names: &[&str], frame: usize) -> Result<()> {
        self.require(names)?;
        for name in names {
            if self.get(name, frame).is_none() {
                return Err(Error::input(
                    &self.source,
                    format!(
                        "marker '{name}' is missing in the reference frame {frame}; choose another \
                         reference_frame in subject.toml or fill the gap in the capture software"
                    ),
                ));
            }
        }
        Ok(())
    }

    /// Mean of the valid samples of `name` over `frames` (clamped to the trial), the static-trial
    /// rule of spec section 2 ("one frame is enough; more are averaged"). `None` when the marker
    /// is absent or has no valid sample in the range.
    pub fn mean_position(&self, name: &str, frames: Range<usize>) -> Option<Point> {
        let track = self.track(name)?;
        let end = frames.end.min(track.len());
        let start = frames.start.min(end);
        let (sum, count) = track[start..end]
            .iter()
            .flatten()
            .fold((nalgebra::Vector3::zeros(), 0usize), |(s, c), p| {
                (s + p.coords, c + 1)
            });
        (count > 0).then(|| Point::from(sum / count as f64))
    }

    /// [`Self::mean_position`] over the whole trial of each of `names` that has a valid sample:
    /// the static trial's markers as the skin fit and the calipers read them.
    pub fn mean_positions(&self, names: &[&str]) -> BTreeMap<String, Point> {
        names
            .iter()
            .filter_map(|n| Some((n.to_string(), self.mean_position(n, 0..self.n_frames())?)))
            .collect()
    }

    /// Fraction of the frames in which `name` is valid (0 when the marker is absent).
    pub fn valid_fraction(&self, name: &str) -> f64 {
        match self.track(name) {
            Some(t) if !t.is_empty() => {
                t.iter().filter(|p| p.is_some()).count() as f64 / t.len() as f64
            }
            _ => 0.0,
        }
    }

    /// Length of the recording, s: `n_frames / frame_rate` (each frame stands for one sampling
    /// interval).
    pub fn duration_s(&self) -> f64 {
        self.n_frames() as f64 / self.frame_rate
    }
}

/// `Ok` when no label occurs twice; else a message naming the label.
fn check_unique_labels(labels: &[String]) -> std::result::Result<(), String> {
    let mut seen = BTreeMap::new();
    for (i, l) in labels.iter().enumerate() {
        if let Some(j) = seen.insert(l.as_str(), i) {
            return Err(format!(
                "marker label '{l}' occurs twice (markers {} and {})",
                j + 1,
                i + 1
            ));
        }
    }
    Ok(())
}

/// `": A, B, C, ..."` for an error message, at most eight names.
fn label_preview(labels: &[String]) -> String {
    if labels.is_empty() {
        return String::new();
    }
    let shown: Vec<&str> = labels.iter().take(8).map(String::as_str).collect();
    let more = if labels.len() > 8 { ", ..." } else { "" };
    format!(": {}{more}", shown.join(", "))
}

/// Whether `name` is a marker name of the subject-format spec (section 2): a landmark of the
/// reference trial, a palm or forearm marker, or a plate marker `<LINK>_1..3` of any link.
pub fn is_spec_marker_name(name: &str) -> bool {
    if landmark_names().contains(&name)
        || tip_marker_names().contains(&name)
        || arm_markers().contains(&name)
    {
        return true;
    }
    Link::ALL
        .iter()
        .any(|l| l.plate_markers().iter().any(|m| m == name))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64, z: f64) -> Option<Point> {
        Some(Point::new(x, y, z))
    }

    fn sample() -> Trajectories {
        Trajectories::new(
            100.0,
            vec!["PALM_1".into(), "I_NAIL".into()],
            vec![
                vec![p(1.0, 2.0, 3.0), None, p(3.0, 4.0, 5.0), p(5.0, 0.0, 1.0)],
                vec![None, None, None, None],
            ],
            "S01/trials/reference.c3d",
        )
        .unwrap()
    }

    #[test]
    fn accessors() {
        let t = sample();
        assert_eq!(t.n_frames(), 4);
        assert_eq!(t.index_of("I_NAIL"), Some(1));
        assert_eq!(t.index_of("nope"), None);
        assert_eq!(t.get("PALM_1", 2), p(3.0, 4.0, 5.0));
        assert_eq!(t.get("PALM_1", 1), None);
        assert_eq!(t.get("PALM_1", 99), None);
        assert_eq!(t.track("I_NAIL").unwrap().len(), 4);
        assert_eq!(t.valid_fraction("PALM_1"), 0.75);
        assert_eq!(t.valid_fraction("I_NAIL"), 0.0);
        assert_eq!(t.valid_fraction("absent"), 0.0);
        assert!((t.duration_s() - 0.04).abs() < 1e-12);
    }

    #[test]
    fn mean_skips_gaps_and_clamps() {
        let t = sample();
        // frames 0..3: samples (1,2,3) and (3,4,5); the gap does not count.
        assert_eq!(t.mean_position("PALM_1", 0..3), p(2.0, 3.0, 4.0));
        assert_eq!(t.mean_position("PALM_1", 1..2), None);
        assert_eq!(t.mean_position("PALM_1", 3..1000), p(5.0, 0.0, 1.0));
        assert_eq!(t.mean_position("PALM_1", 10..20), None);
        assert_eq!(t.mean_position("I_NAIL", 0..4), None);
    }

    #[test]
    fn require_names_file_and_first_missing_marker() {
        let t = sample();
        assert!(t.require(&["PALM_1"]).is_ok());
        let e = t
            .require(&["PALM_1", "PALM_2", "PALM_3"])
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("S01/trials/reference.c3d: "), "{e}");
        assert!(e.contains("'PALM_2'") && !e.contains("PALM_3"), "{e}");
        assert!(!e.contains('\n'));
        let e = t.require(&["I_NAIL"]).unwrap_err().to_string();
        assert!(
            e.contains("'I_NAIL'") && e.contains("no valid sample"),
            "{e}"
        );
    }

    #[test]
    fn new_rejects_inconsistent_data() {
        let ok = || vec![vec![p(0.0, 0.0, 0.0)], vec![None]];
        let labels = || vec!["A".to_string(), "B".to_string()];
        assert!(Trajectories::new(0.0, labels(), ok(), "f.c3d").is_err());
        assert!(Trajectories::new(f64::NAN, labels(), ok(), "f.c3d").is_err());
        assert!(Trajectories::new(50.0, vec!["A".into()], ok(), "f.c3d").is_err());
        let e = Trajectories::new(50.0, vec!["A".into(), "A".into()], ok(), "f.c3d")
            .unwrap_err()
            .to_string();
        assert!(e.contains("'A' occurs twice"), "{e}");
        let ragged = vec![vec![None, None], vec![None]];
        let e = Trajectories::new(50.0, labels(), ragged, "f.c3d")
            .unwrap_err()
            .to_string();
        assert!(e.contains("marker 'B'"), "{e}");
        assert!(Trajectories::new(50.0, labels(), vec![vec![], vec![]], "f.c3d").is_err());
    }

    #[test]
    fn spec_names() {
        for n in [
            "PALM_1",
            "PALM_4",
            "ARM_3",
            "I_PROX_1",
            "T_META_3",
            "WRIST_RAD",
            "L_DIP",
            "M_TIP",
        ] {
            assert!(is_spec_marker_name(n), "{n}");
        }
        for n in ["PALM_5", "I_PROX_4", "palm_1", "LHand1", "X_TIP", ""] {
            assert!(!is_spec_marker_name(n), "{n}");
        }
    }

    #[test]
    fn require_at_names_marker_and_frame() {
        let p = |x: f64| Some(Point::new(x, 0.0, 0.0));
        let t = Trajectories::new(
            100.0,
            vec!["PALM_1".into(), "PALM_2".into()],
            vec![vec![p(1.0), p(2.0)], vec![None, p(3.0)]],
            "trials/index.c3d",
        )
        .unwrap();
        t.require_at(&["PALM_1", "PALM_2"], 1).unwrap();
        let e = t
            .require_at(&["PALM_1", "PALM_2"], 0)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("trials/index.c3d") && e.contains("PALM_2") && e.contains("frame 0"),
            "{e}"
        );
        let e = t.require_at(&["PALM_3"], 0).unwrap_err().to_string();
        assert!(e.contains("PALM_3"), "{e}");
    }
}
