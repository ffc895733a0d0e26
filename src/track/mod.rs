//! Tracking a captured grasp (spec section 5): a motion trial replayed with the subject's own
//! reconstructed link model.
//!
//! * [`attachment`]: each marker's link and its place on it, from the static trial.
//! * [`cluster_calibration`]: markers the static trial lacks (the forearm plate), attached from
//!   the motion's first second.
//! * [`kinematics`]: the link model moved by the palm's pose and the joint angles, with
//!   analytic derivatives.
//! * [`inverse_kinematics`]: the per-frame robust Levenberg-Marquardt fit.
//! * [`part`]: the product's pose per frame from its markers.
//! * [`keep_out`]: the frames whose skin reaches into the part solved again with terms that
//!   keep it out where the markers allow.
//! * [`contacts`]: the posed skin against the posed part, frame by frame, and the contact map
//!   over the trial.
//! * [`motion_file`]: the `motion.json` document.
//! * [`fixture`]: marker sets and motion trials made from known angles, for tests and the
//!   bench.
//!
//! [`track_trial`] runs them on trials in memory; the command (`ergohand track`) reads the
//! subject folder and the model folder and writes `motion.json`.

pub mod attachment;
pub mod cluster_calibration;
pub mod contacts;
pub mod fixture;
pub mod inverse_kinematics;
pub mod keep_out;
pub mod kinematics;
pub mod motion_file;
pub mod part;

pub use attachment::{rides_on, AttachedMarker, Attachment};
pub use contacts::{
    replay_contacts, replay_frames, ContactReplay, FrameContacts, PosedFrame, ReplayOptions,
};
pub use inverse_kinematics::{observations, ContactPlane, FrameSolution, IkOptions, Solver};
pub use keep_out::{keep_out_of_part, KeepOutOptions, KeepOutSummary};
pub use kinematics::{load_link_model, HandState, Kinematics};
pub use motion_file::{ContactRecord, JointTrack, MotionFile, PartPose, PartTrack};
pub use part::{fill_pose_gaps, part_poses, PartPoses};

use crate::anatomy::{Finger, Joint, Link};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh};
use crate::io::gltf::Scene;
use crate::mocap::trajectories::Trajectories;
use crate::pose::gltf::{animated_scene, MovingPart};
use crate::pose::IndividualHand;
use crate::skeleton::Pose;
use nalgebra::Isometry3;
use std::collections::BTreeMap;

/// Where the part is: its markers in its own frame (`[part.markers]`, may be empty) and the
/// scene's placement, used when there are no markers.
#[derive(Clone, Debug, PartialEq)]
pub struct PartSetup {
    pub markers: BTreeMap<String, Point>,
    pub placed: Isometry3<f64>,
}

/// A tracked trial.
#[derive(Clone, Debug)]
pub struct Tracked {
    /// The markers and their links.
    pub attachment: Attachment,
    /// One per frame.
    pub frames: Vec<FrameSolution>,
    /// The part's pose per frame, when a part was given (short gaps filled).
    pub part: Option<PartPoses>,
    /// Frames whose part pose was interpolated across a gap in its markers.
    pub part_filled: Vec<usize>,
    /// Frame rate, Hz.
    pub rate: f64,
    /// Warnings, each naming the trial and the markers, joints or frames.
    pub warnings: Vec<String>,
}

/// Track `motion` with the model `kin`, its markers attached from `static_trial`.
///
/// Errors (naming the file and the markers): the static trial attaches fewer than three palm
/// markers, or the motion trial carries fewer than three of the attached palm markers.
/// Frames that cannot be solved are not errors: they are `None`, named in one warning.
pub fn track_trial(
    kin: &Kinematics,
    static_trial: &Trajectories,
    motion: &Trajectories,
    part: Option<&PartSetup>,
    opts: &IkOptions,
) -> Result<Tracked> {
    let mut attachment = Attachment::from_static(&kin.skeleton, static_trial);
    let palm: Vec<&str> = attachment
        .markers
        .iter()
        .filter(|m| m.link == Link::Palm)
        .map(|m| m.name.as_str())
        .collect();
    if palm.len() < 3 {
        return Err(Error::input(
            &static_trial.source,
            format!(
                "only {} palm markers ({}) to attach; tracking needs three of PALM_1..4, the \
                 MCP markers, T_CMC, I_MCP_LAT, L_MCP_LAT",
                palm.len(),
                palm.join(", ")
            ),
        ));
    }
    let in_motion: Vec<&str> = palm
        .iter()
        .copied()
        .filter(|n| {
            motion
                .track(n)
                .is_some_and(|t| t.iter().any(Option::is_some))
        })
        .collect();
    if in_motion.len() < 3 {
        return Err(Error::input(
            &motion.source,
            format!(
                "only {} palm markers with samples ({}); tracking needs three of {}",
                in_motion.len(),
                in_motion.join(", "),
                palm.join(", ")
            ),
        ));
    }
    let mut warnings = Vec::new();
    // Markers on a link that the static trial lacks: attached from the motion's first second
    // by the markers that are attached.
    let new: Vec<(String, Link)> = motion
        .labels
        .iter()
        .filter(|l| attachment.index_of(l).is_none())
        .filter(|l| !(part.is_some_and(|p| p.markers.contains_key(*l))))
        .filter_map(|l| rides_on(l).map(|link| (l.clone(), link)))
        .collect();
    let window = (motion.frame_rate.max(1.0)).round() as usize;
    cluster_calibration::attach_from_motion(&mut attachment, kin, motion, &new, window, opts);
    let ignored: Vec<&str> = motion
        .labels
        .iter()
        .map(String::as_str)
        .filter(|l| attachment.index_of(l).is_none())
        .filter(|l| !(part.is_some_and(|p| p.markers.contains_key(*l))))
        .collect();
    if !ignored.is_empty() {
        warnings.push(format!(
            "{}: markers {} are not attached (not in the static trial {} nor seen with their \
             link's pose in the motion's first second, or on no link) and are ignored",
            motion.source.display(),
            ignored.join(", "),
            static_trial.source.display()
        ));
    }
    let obs = observations(&attachment, motion);
    let solver = Solver::new(kin, &attachment, opts.clone());
    let frames = solver.track(&obs);

    let unsolved: Vec<usize> = (0..frames.len())
        .filter(|&f| frames[f].state.is_none())
        .collect();
    if !unsolved.is_empty() {
        warnings.push(format!(
            "{}: {} of {} frames could not be solved (fewer than {} palm markers seen, or no \
             fit within {} mm) and are null: frames {}",
            motion.source.display(),
            unsolved.len(),
            frames.len(),
            opts.min_palm_markers,
            opts.max_rms_mm,
            ranges(&unsolved)
        ));
    }
    for j in Joint::ALL {
        let held: Vec<usize> = (0..frames.len())
            .filter(|&f| frames[f].state.is_some() && frames[f].held.contains(&j))
            .collect();
        if !held.is_empty() {
            warnings.push(format!(
                "{}: joint {j} held at its previous angles for want of markers distal to it \
                 in {} frames: {}",
                motion.source.display(),
                held.len(),
                ranges(&held)
            ));
        }
    }
    for j in Joint::ALL {
        let coupled: Vec<usize> = (0..frames.len())
            .filter(|&f| frames[f].state.is_some() && frames[f].coupled.contains(&j))
            .collect();
        if !coupled.is_empty() {
            let how = if j.rank() == 2 {
                format!(
                    "followed its PIP (DIP-PIP coupling {:.2})",
                    opts.dip_pip_coupling
                )
            } else {
                "kept its abduction and axial angles (one marker on the finger)".to_string()
            };
            warnings.push(format!(
                "{}: joint {j} {how} for want of markers in {} frames: {}",
                motion.source.display(),
                coupled.len(),
                ranges(&coupled)
            ));
        }
    }
    for (i, m) in attachment.markers.iter().enumerate() {
        let rej: Vec<usize> = (0..frames.len())
            .filter(|&f| frames[f].rejected.contains(&i))
            .collect();
        if !rej.is_empty() {
            warnings.push(format!(
                "{}: marker {} rejected as an outlier (a swapped label or a stray sample) in {} \
                 frames: {}",
                motion.source.display(),
                m.name,
                rej.len(),
                ranges(&rej)
            ));
        }
    }
    let mut part = part.map(|p| part_poses(motion, &p.markers, &p.placed));
    let mut part_filled = Vec::new();
    if let Some((poses, _)) = part.as_mut() {
        let max_gap = (opts.part_gap_s * motion.frame_rate).floor() as usize;
        part_filled = fill_pose_gaps(poses, max_gap);
        if !part_filled.is_empty() {
            warnings.push(format!(
                "{}: the part's pose interpolated across gaps of up to {} s in its markers in \
                 {} frames: {}",
                motion.source.display(),
                opts.part_gap_s,
                part_filled.len(),
                ranges(&part_filled)
            ));
        }
    }
    Ok(Tracked {
        part_filled,
        attachment,
        frames,
        part,
        rate: motion.frame_rate,
        warnings,
    })
}

impl Tracked {
    /// The hand's pose per frame for skinning ([`Kinematics::pose`]), `None` where unsolved.
    pub fn poses(&self, kin: &Kinematics) -> Vec<Option<Pose>> {
        self.frames
            .iter()
            .map(|f| f.state.as_ref().map(|s| kin.pose(s)))
            .collect()
    }

    /// The trial as an animated glTF scene ([`animated_scene`]): `hand`'s skin (in the static
    /// trial's lab frame, as the link model `kin`) moved by the pose of every solved frame,
    /// and, when the part was tracked and `part_mesh` (in the part's own frame) is given, the
    /// part moved by its pose per frame.
    pub fn animated_scene(
        &self,
        kin: &Kinematics,
        hand: &IndividualHand,
        part_mesh: Option<&TriMesh>,
    ) -> Result<Scene> {
        let part = match (part_mesh, &self.part) {
            (Some(mesh), Some((poses, _))) => Some(MovingPart {
                name: "part",
                mesh,
                poses,
            }),
            _ => None,
        };
        animated_scene(
            "hand",
            &hand.skin,
            &hand.weights,
            &hand.skeleton,
            &self.poses(kin),
            self.rate,
            part,
        )
    }

    /// The `motion.json` document (contacts as given; fingertips those of `kin`'s skeleton
    /// carried by the distal links).
    pub fn motion_file(&self, kin: &Kinematics, contacts: Vec<ContactRecord>) -> MotionFile {
        let n = self.frames.len();
        let mut joints = BTreeMap::new();
        let centres: Vec<Option<[Point; 16]>> = self
            .frames
            .iter()
            .map(|f| f.state.as_ref().map(|s| kin.centres(s)))
            .collect();
        for j in Joint::ALL {
            let dof = kin.dof[j.index()];
            let track = JointTrack {
                centre: centres
                    .iter()
                    .map(|c| c.map(|c| [c[j.index()].x, c[j.index()].y, c[j.index()].z]))
                    .collect(),
                angles_deg: self
                    .frames
                    .iter()
                    .map(|f| {
                        f.state.as_ref().map(|s| {
                            s.angles[j.index()][..dof]
                                .iter()
                                .map(|a| a.to_degrees())
                                .collect()
                        })
                    })
                    .collect(),
                held_frames: (0..n)
                    .filter(|&f| self.frames[f].state.is_some() && self.frames[f].held.contains(&j))
                    .collect(),
                coupled_frames: (0..n)
                    .filter(|&f| {
                        self.frames[f].state.is_some() && self.frames[f].coupled.contains(&j)
                    })
                    .collect(),
            };
            joints.insert(j.name().to_string(), track);
        }
        let posed_tips: Vec<Option<[Point; 5]>> = self
            .frames
            .iter()
            .map(|f| {
                f.state.as_ref().map(|s| {
                    let t = kin.evaluate(s);
                    crate::skeleton::forward_kinematics::posed_tips(&kin.skeleton, &t.links)
                })
            })
            .collect();
        let tips = Finger::ALL
            .iter()
            .map(|&d| {
                let track = posed_tips
                    .iter()
                    .map(|t| t.map(|t| t[d as usize].coords.into()))
                    .collect();
                (d.letter().to_string(), track)
            })
            .collect();
        let mut marker_residual_mm = BTreeMap::new();
        let mut rejected_frames = BTreeMap::new();
        for (i, m) in self.attachment.markers.iter().enumerate() {
            marker_residual_mm.insert(
                m.name.clone(),
                self.frames.iter().map(|f| f.residual_mm[i]).collect(),
            );
            let rej: Vec<usize> = (0..n)
                .filter(|&f| self.frames[f].rejected.contains(&i))
                .collect();
            if !rej.is_empty() {
                rejected_frames.insert(m.name.clone(), rej);
            }
        }
        let part = self.part.as_ref().map(|(poses, rms)| PartTrack {
            source: if rms.iter().any(Option::is_some) || poses.iter().any(Option::is_none) {
                "markers".into()
            } else {
                "scene".into()
            },
            pose: poses
                .iter()
                .map(|p| p.as_ref().map(PartPose::from_isometry))
                .collect(),
            filled_frames: self.part_filled.clone(),
            marker_rms_mm: if rms.iter().any(Option::is_some) {
                rms.clone()
            } else {
                Vec::new()
            },
        });
        MotionFile {
            units: "mm".into(),
            rate: self.rate,
            frames: n,
            frame: "lab".into(),
            joints,
            tips,
            marker_residual_mm,
            contacts,
            unsolved_frames: (0..n).filter(|&f| self.frames[f].state.is_none()).collect(),
            rejected_frames,
            part,
            warnings: self.warnings.clone(),
        }
    }
}

impl ContactReplay {
    /// The `motion.json` contact records: per frame, one per link in contact, in link order.
    pub fn records(&self) -> Vec<ContactRecord> {
        let mut out = Vec::new();
        for (f, fc) in self.frames.iter().enumerate() {
            let Some(fc) = fc else { continue };
            for l in Link::ALL {
                let a = fc.link_area_mm2[l.index()];
                if a > 0.0 {
                    out.push(ContactRecord {
                        frame: f,
                        link: l.name().to_string(),
                        area_mm2: a,
                        depth_mm: fc.link_depth_mm[l.index()],
                    });
                }
            }
        }
        out
    }
}

/// `"3-7, 12, 20-21"`: sorted frame indices as ranges, at most 12 shown.
pub fn ranges(frames: &[usize]) -> String {
    let mut parts: Vec<String> = Vec::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            frames[i].to_string()
        } else {
            format!("{}-{}", frames[i], frames[j])
        });
        i = j + 1;
    }
    let more = parts.len().saturating_sub(12);
    parts.truncate(12);
    if more > 0 {
        parts.push(format!("... ({more} more)"));
    }
    parts.join(", ")
}

#[cfg(test)]
mod tests;
