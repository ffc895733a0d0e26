//! A tracked motion (`motion.json`, written by `track`) against a simulated subject's motion
//! truth (`truth_motion/NAME.json`): joint centres, fingertips, marker residuals, lost frames
//! and the contact areas of the hold.
//!
//! Every distance is taken per frame between the tracked and the true point in the lab frame,
//! over the frames the tracker solved, and summarised as a root mean square (RMS): over all
//! solved frames and joints, per joint, per group of joints by their degrees of freedom, per
//! digit's tip. A frame is *lost* when the tracker left it unsolved although the trial showed
//! at least three palm markers and at least two markers on every digit in it (what the
//! tracking goal asks to be solved). Contacts compare, per link, the mean contact area over
//! the hold phase (the truth's `hold`, the frames both the hand and the part were tracked) of
//! the tracked skin with that of the true skin over the same frames.
//!
//! Only files are read (the two JSON documents and the motion's trial for the markers seen):
//! `validate` never runs a stage.

use crate::anatomy::{Finger, Joint, Link};
use crate::error::{Error, Result};
use crate::mocap::subject::Subject;
use crate::synth::grasp_motion::MotionTruth;
use crate::track::{ContactRecord, MotionFile};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Markers of the palm a frame needs for the tracking goal.
pub const GOAL_PALM_MARKERS: usize = 3;
/// Markers per digit a frame needs for the tracking goal.
pub const GOAL_DIGIT_MARKERS: usize = 2;

/// An RMS with its largest single distance and the samples behind it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Rms {
    /// Root mean square, mm.
    pub rms_mm: f64,
    /// Largest distance, mm.
    pub max_mm: f64,
    /// Distances taken.
    pub samples: usize,
}

impl Rms {
    fn of(d: &[f64]) -> Option<Rms> {
        if d.is_empty() {
            return None;
        }
        Some(Rms {
            rms_mm: (d.iter().map(|x| x * x).sum::<f64>() / d.len() as f64).sqrt(),
            max_mm: d.iter().copied().fold(0.0, f64::max),
            samples: d.len(),
        })
    }
}

/// One joint's centre error over the solved frames.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointRms {
    /// Joint name.
    pub joint: String,
    /// The joint's degrees of freedom.
    pub dof: usize,
    /// Its errors.
    #[serde(flatten)]
    pub error: Rms,
}

/// One link's contact area in the hold, tracked against true.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LinkContact {
    /// Link name (`TOTAL` for the sum over links).
    pub link: String,
    /// Mean tracked area over the hold's frames, mm².
    pub tracked_mm2: f64,
    /// Mean true area over the same frames, mm².
    pub true_mm2: f64,
    /// `tracked / true` (`None` where the truth has no contact).
    pub ratio: Option<f64>,
    /// Deepest tracked penetration in the hold, mm.
    pub tracked_depth_mm: f64,
    /// Deepest true penetration in the hold, mm.
    pub true_depth_mm: f64,
}

/// The hold phase's contacts.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct HoldContacts {
    /// The hold's first and last frame (truth).
    pub first: usize,
    pub last: usize,
    /// Hold frames where both the hand and the part were tracked (the means are over these).
    pub frames: usize,
    /// Per link in contact in either (link order), then `TOTAL`.
    pub links: Vec<LinkContact>,
}

/// A tracked motion against its truth (`metrics.json`'s `motions`).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MotionAccuracy {
    /// The motion's name (`[motions]` key).
    pub motion: String,
    /// The tracked file read.
    pub file: PathBuf,
    /// Frames in the trial.
    pub frames: usize,
    /// Frames the tracker left unsolved.
    pub unsolved_frames: usize,
    /// Unsolved frames although at least three palm and two markers per digit were seen
    /// (`None`: the trial could not be read).
    pub lost_frames: Option<Vec<usize>>,
    /// Joint centres over all solved frames and joints.
    pub centre: Option<Rms>,
    /// Per joint.
    pub joints: Vec<JointRms>,
    /// The joint of largest RMS.
    pub worst_joint: Option<String>,
    /// Per group of joints by degrees of freedom (`"3"`, `"2"`, `"1"`).
    pub dof_groups: BTreeMap<String, Rms>,
    /// Fingertips over all solved frames and digits (`None`: a file has no tips).
    pub tip: Option<Rms>,
    /// Per digit letter.
    pub tips: BTreeMap<String, Rms>,
    /// Every marker residual of `motion.json` (fitted minus seen).
    pub marker_residual: Option<Rms>,
    /// Contact areas in the hold (`None`: either file has no contacts, or no hold).
    pub hold_contacts: Option<HoldContacts>,
}

fn point(p: &[f64; 3]) -> nalgebra::Point3<f64> {
    nalgebra::Point3::new(p[0], p[1], p[2])
}

/// Score `tracked` against `truth` (the motion `name`; `file` names the tracked file in
/// messages), with `seen` the markers seen per frame (`None`: not known). Errors, naming
/// `file`: a different number of frames, a joint of the truth missing.
pub fn motion_accuracy(
    name: &str,
    file: &Path,
    tracked: &MotionFile,
    truth: &MotionTruth,
    seen: Option<&[Vec<String>]>,
) -> Result<MotionAccuracy> {
    let n = truth.frames;
    if tracked.frames != n {
        return Err(Error::input(
            file,
            format!(
                "field 'frames' is {} but truth_motion/{name}.json has {n}: not a tracking of \
                 this motion",
                tracked.frames
            ),
        ));
    }
    let unsolved: std::collections::BTreeSet<usize> =
        tracked.unsolved_frames.iter().copied().collect();
    let mut all = Vec::new();
    let mut joints = Vec::new();
    let mut groups: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for j in Joint::ALL {
        let Some(t) = truth.joints.get(j.name()) else {
            continue;
        };
        let m = tracked
            .joints
            .get(j.name())
            .ok_or_else(|| Error::input(file, format!("joint {j}: missing from 'joints'")))?;
        let d: Vec<f64> = (0..n)
            .filter(|f| !unsolved.contains(f))
            .filter_map(|f| {
                let a = m.centre.get(f).copied().flatten()?;
                Some((point(&a) - point(&t.centre[f])).norm())
            })
            .collect();
        all.extend_from_slice(&d);
        groups
            .entry(j.dof().to_string())
            .or_default()
            .extend_from_slice(&d);
        if let Some(error) = Rms::of(&d) {
            joints.push(JointRms {
                joint: j.name().to_string(),
                dof: j.dof(),
                error,
            });
        }
    }
    let worst_joint = joints
        .iter()
        .max_by(|a, b| a.error.rms_mm.total_cmp(&b.error.rms_mm))
        .map(|j| j.joint.clone());
    let mut tip_all = Vec::new();
    let mut tips = BTreeMap::new();
    for f in Finger::ALL {
        let k = f.letter();
        let (Some(m), Some(t)) = (tracked.tips.get(k), truth.tips.get(k)) else {
            continue;
        };
        let d: Vec<f64> = (0..n)
            .filter(|i| !unsolved.contains(i))
            .filter_map(|i| {
                let a = m.get(i).copied().flatten()?;
                Some((point(&a) - point(t.get(i)?)).norm())
            })
            .collect();
        tip_all.extend_from_slice(&d);
        if let Some(r) = Rms::of(&d) {
            tips.insert(k.to_string(), r);
        }
    }
    let residuals: Vec<f64> = tracked
        .marker_residual_mm
        .values()
        .flatten()
        .flatten()
        .copied()
        .collect();
    let lost_frames = seen.map(|seen| {
        unsolved
            .iter()
            .copied()
            .filter(|&f| seen.get(f).is_some_and(|s| goal_markers_seen(s, truth)))
            .collect()
    });
    let hold_contacts = hold_contacts(tracked, truth, &unsolved);
    Ok(MotionAccuracy {
        motion: name.to_string(),
        file: file.to_path_buf(),
        frames: n,
        unsolved_frames: unsolved.len(),
        lost_frames,
        centre: Rms::of(&all),
        joints,
        worst_joint,
        dof_groups: groups
            .into_iter()
            .filter_map(|(k, d)| Rms::of(&d).map(|r| (k, r)))
            .collect(),
        tip: Rms::of(&tip_all),
        tips,
        marker_residual: Rms::of(&residuals),
        hold_contacts,
    })
}

/// Whether the markers `seen` in a frame (names) include at least [`GOAL_PALM_MARKERS`] on
/// the palm and [`GOAL_DIGIT_MARKERS`] on every digit (by the truth's `marker_links`).
pub fn goal_markers_seen(seen: &[String], truth: &MotionTruth) -> bool {
    let mut palm = 0;
    let mut digit = [0usize; 5];
    for m in seen {
        let Some(link) = truth.marker_links.get(m).and_then(|l| Link::from_name(l)) else {
            continue;
        };
        if link == Link::Palm {
            palm += 1;
        } else if let Some(f) = link.joint().and_then(|j| j.finger()) {
            digit[f as usize] += 1;
        }
    }
    palm >= GOAL_PALM_MARKERS && digit.iter().all(|&c| c >= GOAL_DIGIT_MARKERS)
}

/// Per link, the mean contact area over the hold's frames that both documents have contacts
/// for (solved, and the part's pose known where the tracked file has a part), and the deepest
/// penetration there.
fn hold_contacts(
    tracked: &MotionFile,
    truth: &MotionTruth,
    unsolved: &std::collections::BTreeSet<usize>,
) -> Option<HoldContacts> {
    let true_records = truth.contacts.as_ref()?;
    let hold = truth.phases.iter().find(|p| p.name == "hold")?;
    let part_known = |f: usize| {
        tracked
            .part
            .as_ref()
            .is_none_or(|p| p.pose.get(f).is_some_and(Option::is_some))
    };
    let frames: Vec<usize> = (hold.first..=hold.last)
        .filter(|f| !unsolved.contains(f) && part_known(*f))
        .collect();
    if frames.is_empty() {
        return None;
    }
    let sum = |records: &[ContactRecord]| {
        let mut area = [0.0; 17];
        let mut depth = [0.0f64; 17];
        for r in records {
            if frames.binary_search(&r.frame).is_err() {
                continue;
            }
            if let Some(l) = Link::from_name(&r.link) {
                area[l.index()] += r.area_mm2;
                depth[l.index()] = depth[l.index()].max(r.depth_mm);
            }
        }
        (area.map(|a| a / frames.len() as f64), depth)
    };
    let (ta, td) = sum(&tracked.contacts);
    let (ra, rd) = sum(true_records);
    let ratio = |a: f64, b: f64| (b > 0.0).then(|| a / b);
    let mut links: Vec<LinkContact> = Link::ALL
        .iter()
        .filter(|l| ta[l.index()] > 0.0 || ra[l.index()] > 0.0)
        .map(|l| {
            let i = l.index();
            LinkContact {
                link: l.name().to_string(),
                tracked_mm2: ta[i],
                true_mm2: ra[i],
                ratio: ratio(ta[i], ra[i]),
                tracked_depth_mm: td[i],
                true_depth_mm: rd[i],
            }
        })
        .collect();
    let (st, sr): (f64, f64) = (ta.iter().sum(), ra.iter().sum());
    links.push(LinkContact {
        link: "TOTAL".into(),
        tracked_mm2: st,
        true_mm2: sr,
        ratio: ratio(st, sr),
        tracked_depth_mm: td.iter().copied().fold(0.0, f64::max),
        true_depth_mm: rd.iter().copied().fold(0.0, f64::max),
    });
    Some(HoldContacts {
        first: hold.first,
        last: hold.last,
        frames: frames.len(),
        links,
    })
}

/// Read `truth_motion/NAME.json`. Errors name the file.
pub fn read_motion_truth(path: &Path) -> Result<MotionTruth> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not a motion truth: {e}")))
}

/// Read a tracked `motion.json`. Errors name the file.
pub fn read_motion_file(path: &Path) -> Result<MotionFile> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    serde_json::from_str(&text).map_err(|e| Error::input(path, format!("not a motion.json: {e}")))
}

/// The markers seen per frame in the motion `name`'s trial of `subject` (`None` when it
/// cannot be read).
fn markers_seen(subject: &Subject, name: &str) -> Option<Vec<Vec<String>>> {
    let t = subject.load_motion(name).ok()?;
    let n = t.positions.first().map_or(0, Vec::len);
    Some(
        (0..n)
            .map(|f| {
                t.labels
                    .iter()
                    .zip(&t.positions)
                    .filter(|(_, p)| p[f].is_some())
                    .map(|(l, _)| l.clone())
                    .collect()
            })
            .collect(),
    )
}

/// Every tracked motion of the subject in `subject_dir` that has a truth
/// (`truth_motion/NAME.json`), scored: the tracked file is `DIR/motion.json` for a folder of
/// `explicit` (the motion whose name is the folder's, or the subject's only motion truth), else
/// `model/motions/NAME/motion.json` where it exists. Errors, naming the file or folder: an
/// explicit folder without `motion.json` or matching no motion truth, a file that does not
/// read.
pub fn subject_motions(
    subject_dir: &Path,
    model: &Path,
    explicit: &[PathBuf],
) -> Result<Vec<MotionAccuracy>> {
    let truth_dir = subject_dir.join("truth_motion");
    let mut names: Vec<String> = match std::fs::read_dir(&truth_dir) {
        Ok(rd) => rd
            .filter_map(|e| e.ok())
            .filter_map(|e| {
                let p = e.path();
                (p.extension().is_some_and(|x| x == "json"))
                    .then(|| p.file_stem()?.to_str().map(String::from))
                    .flatten()
            })
            .collect(),
        Err(_) => Vec::new(),
    };
    names.sort();
    let mut pairs: BTreeMap<String, PathBuf> = BTreeMap::new();
    for name in &names {
        let p = model.join("motions").join(name).join("motion.json");
        if p.is_file() {
            pairs.insert(name.clone(), p);
        }
    }
    for dir in explicit {
        let file = dir.join("motion.json");
        if !file.is_file() {
            return Err(Error::input(
                &file,
                "file not found: --motion must be a track output folder",
            ));
        }
        let own = dir
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|n| names.iter().any(|m| m == n));
        let name = match (own, names.as_slice()) {
            (Some(n), _) => n.to_string(),
            (None, [only]) => only.clone(),
            _ => {
                return Err(Error::input(
                    dir,
                    format!(
                        "--motion: the folder's name matches no motion truth in {} ({}); name \
                         the folder after its motion",
                        truth_dir.display(),
                        if names.is_empty() {
                            "none there".to_string()
                        } else {
                            names.join(", ")
                        }
                    ),
                ))
            }
        };
        pairs.insert(name, file);
    }
    if pairs.is_empty() {
        return Ok(Vec::new());
    }
    let subject = Subject::load(subject_dir).ok();
    pairs
        .iter()
        .map(|(name, file)| {
            let truth = read_motion_truth(&truth_dir.join(format!("{name}.json")))?;
            let tracked = read_motion_file(file)?;
            let seen = subject.as_ref().and_then(|s| markers_seen(s, name));
            motion_accuracy(name, file, &tracked, &truth, seen.as_deref())
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::synth::grasp_motion::{JointTrack, PartTrack, Phase};
    use crate::track::motion_file;

    const N: usize = 40;

    /// A motion truth of `N` frames: joints and tips on distinct curves, a hold over frames
    /// 10-19 with contacts on two links, every marker's link.
    fn truth() -> MotionTruth {
        let at = |k: usize, f: usize| {
            let (k, f) = (k as f64, f as f64);
            [10.0 * k + f, 3.0 * k - 0.5 * f, (0.1 * f + k).sin() * 20.0]
        };
        let joints = Joint::ALL
            .iter()
            .enumerate()
            .map(|(k, j)| {
                (
                    j.name().to_string(),
                    JointTrack {
                        centre: (0..N).map(|f| at(k, f)).collect(),
                        angles_deg: vec![[0.0; 3]; N],
                    },
                )
            })
            .collect();
        let tips = Finger::ALL
            .iter()
            .enumerate()
            .map(|(k, d)| {
                (
                    d.letter().to_string(),
                    (0..N).map(|f| at(k + 20, f)).collect(),
                )
            })
            .collect();
        let mut contacts = Vec::new();
        for f in 8..22 {
            contacts.push(ContactRecord {
                frame: f,
                link: "T_DIST".into(),
                area_mm2: 100.0 + f as f64,
                depth_mm: 0.5,
            });
            contacts.push(ContactRecord {
                frame: f,
                link: "PALM".into(),
                area_mm2: 300.0,
                depth_mm: 0.0,
            });
        }
        let mut marker_links = BTreeMap::new();
        for (m, l) in [
            ("PALM_1", "PALM"),
            ("PALM_2", "PALM"),
            ("PALM_3", "PALM"),
            ("T_MC_1", "T_META"),
            ("T_NAIL", "T_DIST"),
            ("I_PIP", "I_PROX"),
            ("I_NAIL", "I_DIST"),
            ("M_PIP", "M_PROX"),
            ("M_NAIL", "M_DIST"),
            ("R_PIP", "R_PROX"),
            ("R_NAIL", "R_DIST"),
            ("L_PIP", "L_PROX"),
            ("L_NAIL", "L_DIST"),
        ] {
            marker_links.insert(m.to_string(), l.to_string());
        }
        MotionTruth {
            units: "mm".into(),
            frame: "lab".into(),
            rate: 100.0,
            frames: N,
            joints,
            part: PartTrack {
                scene: "scenes/bottle.toml".into(),
                position: vec![[0.0; 3]; N],
                rotation: vec![[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]; N],
                markers: BTreeMap::new(),
            },
            phases: vec![Phase {
                name: "hold".into(),
                first: 10,
                last: 19,
            }],
            grasp_deg: BTreeMap::new(),
            grasp_clearance_mm: BTreeMap::new(),
            marker_links,
            label_swaps: Vec::new(),
            tips,
            contacts: Some(contacts),
        }
    }

    /// The truth written as a tracked `motion.json`, every point moved by `shift`, the
    /// contact areas scaled by `scale`, residuals `residual` mm.
    fn tracked_as(t: &MotionTruth, shift: [f64; 3], scale: f64, residual: f64) -> MotionFile {
        let mv = |p: &[f64; 3]| Some([p[0] + shift[0], p[1] + shift[1], p[2] + shift[2]]);
        MotionFile {
            units: "mm".into(),
            rate: t.rate,
            frames: t.frames,
            frame: "lab".into(),
            joints: t
                .joints
                .iter()
                .map(|(k, j)| {
                    (
                        k.clone(),
                        motion_file::JointTrack {
                            centre: j.centre.iter().map(mv).collect(),
                            angles_deg: vec![Some(vec![0.0]); t.frames],
                            held_frames: Vec::new(),
                            coupled_frames: Vec::new(),
                        },
                    )
                })
                .collect(),
            tips: t
                .tips
                .iter()
                .map(|(k, v)| (k.clone(), v.iter().map(mv).collect()))
                .collect(),
            marker_residual_mm: BTreeMap::from([(
                "PALM_1".to_string(),
                vec![Some(residual); t.frames],
            )]),
            contacts: t
                .contacts
                .clone()
                .unwrap()
                .into_iter()
                .map(|mut r| {
                    r.area_mm2 *= scale;
                    r
                })
                .collect(),
            unsolved_frames: Vec::new(),
            rejected_frames: BTreeMap::new(),
            part: None,
            warnings: Vec::new(),
        }
    }

    fn score(m: &MotionFile, t: &MotionTruth) -> MotionAccuracy {
        motion_accuracy("grasp_bottle", Path::new("motion.json"), m, t, None).unwrap()
    }

    /// The truth scored against itself: every distance 0, every area ratio 1.
    #[test]
    fn a_motion_equal_to_the_truth_scores_zero_and_ratio_one() {
        let t = truth();
        let a = score(&tracked_as(&t, [0.0; 3], 1.0, 0.0), &t);
        assert_eq!(a.centre.unwrap().rms_mm, 0.0);
        assert_eq!(a.centre.unwrap().samples, 16 * N);
        assert_eq!(a.tip.unwrap().rms_mm, 0.0);
        assert_eq!(a.tips.len(), 5);
        assert_eq!(a.joints.len(), 16);
        let h = a.hold_contacts.unwrap();
        assert_eq!((h.first, h.last, h.frames), (10, 19, 10));
        assert_eq!(h.links.len(), 3);
        for l in &h.links {
            assert!((l.ratio.unwrap() - 1.0).abs() < 1e-12, "{}", l.link);
        }
        // The hold's mean: frames 10-19 only (the records run over 8-21).
        let thumb = h.links.iter().find(|l| l.link == "T_DIST").unwrap();
        assert!((thumb.true_mm2 - 114.5).abs() < 1e-9);
        assert_eq!(a.unsolved_frames, 0);
    }

    /// Every point shifted by a known vector: the RMS of every joint, group and tip is its
    /// length; areas scaled by 1.5 give ratio 1.5; the residual RMS is the residual.
    #[test]
    fn a_shifted_motion_scores_the_shift() {
        let t = truth();
        let shift = [1.0, -2.0, 2.0];
        let a = score(&tracked_as(&t, shift, 1.5, 0.7), &t);
        for r in a
            .joints
            .iter()
            .map(|j| j.error)
            .chain(a.dof_groups.values().copied())
            .chain(a.tips.values().copied())
            .chain([a.centre.unwrap(), a.tip.unwrap()])
        {
            assert!((r.rms_mm - 3.0).abs() < 1e-9 && (r.max_mm - 3.0).abs() < 1e-9);
        }
        let dofs: std::collections::BTreeSet<String> =
            Joint::ALL.iter().map(|j| j.dof().to_string()).collect();
        assert_eq!(
            a.dof_groups
                .keys()
                .cloned()
                .collect::<std::collections::BTreeSet<_>>(),
            dofs
        );
        assert!((a.marker_residual.unwrap().rms_mm - 0.7).abs() < 1e-12);
        for l in &a.hold_contacts.unwrap().links {
            assert!((l.ratio.unwrap() - 1.5).abs() < 1e-12, "{}", l.link);
        }
    }

    /// Unsolved frames are left out of every RMS; a frame is lost only where three palm
    /// markers and two per digit were seen; another frame count is an error naming the file.
    #[test]
    fn unsolved_frames_are_lost_only_where_the_goal_markers_were_seen() {
        let t = truth();
        let mut m = tracked_as(&t, [0.0; 3], 1.0, 0.0);
        for f in [3, 12] {
            for j in m.joints.values_mut() {
                j.centre[f] = Some([1e6; 3]);
            }
        }
        m.unsolved_frames = vec![3, 12];
        let all: Vec<String> = t.marker_links.keys().cloned().collect();
        let mut seen = vec![all.clone(); N];
        seen[3].retain(|m| m != "PALM_2");
        // Frame 12 sees everything.
        let a = motion_accuracy("g", Path::new("m.json"), &m, &t, Some(&seen)).unwrap();
        assert_eq!(a.centre.unwrap().rms_mm, 0.0);
        assert_eq!(a.centre.unwrap().samples, 16 * (N - 2));
        assert_eq!(a.lost_frames, Some(vec![12]));
        assert_eq!(a.unsolved_frames, 2);
        assert_eq!(a.hold_contacts.as_ref().unwrap().frames, 9);
        // A digit with one marker seen does not meet the goal either.
        let mut one = all.clone();
        one.retain(|m| m != "R_NAIL");
        assert!(!goal_markers_seen(&one, &t) && goal_markers_seen(&all, &t));
        m.frames = N + 1;
        let e = motion_accuracy("g", Path::new("m.json"), &m, &t, None)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("m.json") && e.contains("frames") && !e.contains('\n'),
            "{e}"
        );
    }
}
