//! `motion.json` (spec section 5): joint centres in the lab frame per frame (null where the
//! frame is unsolved), joint angles in degrees, each marker's residual, and contacts; with
//! extensions a reader may ignore: the fingertips, the unsolved frames, the frames each joint
//! was held or coupled and each marker rejected, the part's pose and the warnings.

use crate::anatomy::Joint;
use crate::error::Result;
use nalgebra::Isometry3;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// One joint over the trial.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointTrack {
    /// Centre, mm, lab frame, per frame (null: unsolved).
    pub centre: Vec<Option<[f64; 3]>>,
    /// Angles, degrees, per frame: `[flexion, abduction, axial]` for 3 DOF, `[flexion,
    /// abduction]` for 2, `[angle]` for a hinge; zero in the static trial's posture.
    pub angles_deg: Vec<Option<Vec<f64>>>,
    /// Frames whose angles were held from the frame before for want of markers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub held_frames: Vec<usize>,
    /// Frames whose angles followed the hand's coupling for want of markers (a DIP following
    /// its PIP; an MCP keeping its abduction and axial angles).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub coupled_frames: Vec<usize>,
}

/// One contact of a link with the part in one frame.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ContactRecord {
    /// Frame index.
    pub frame: usize,
    /// Link name, e.g. `I_DIST`.
    pub link: String,
    /// Skin area in contact, mm².
    pub area_mm2: f64,
    /// Deepest penetration, mm.
    pub depth_mm: f64,
}

/// The part's pose in one frame: translation, mm, and rotation as a unit quaternion
/// `[w, x, y, z]`, part frame -> lab.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartPose {
    pub translation_mm: [f64; 3],
    pub rotation_wxyz: [f64; 4],
}

impl PartPose {
    /// From an isometry.
    pub fn from_isometry(t: &Isometry3<f64>) -> PartPose {
        let v = t.translation.vector;
        let q = t.rotation.quaternion();
        PartPose {
            translation_mm: [v.x, v.y, v.z],
            rotation_wxyz: [q.w, q.i, q.j, q.k],
        }
    }
}

/// The part over the trial.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PartTrack {
    /// `markers` (from `PART_n` by Horn's method) or `scene` (where the scene places it).
    pub source: String,
    /// Pose per frame (null where too few of its markers are seen).
    pub pose: Vec<Option<PartPose>>,
    /// Frames whose pose was interpolated across a gap in the part's markers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub filled_frames: Vec<usize>,
    /// RMS residual of the marker fit per frame, mm.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub marker_rms_mm: Vec<Option<f64>>,
}

/// The `motion.json` document.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MotionFile {
    /// `"mm"`.
    pub units: String,
    /// Frame rate, Hz.
    pub rate: f64,
    /// Number of frames.
    pub frames: usize,
    /// `"lab"`: the trial's frame.
    pub frame: String,
    /// Per joint name.
    pub joints: BTreeMap<String, JointTrack>,
    /// Per digit letter (`T`, `I`, `M`, `R`, `L`): the distal link's end (the model's
    /// fingertip), mm, lab frame, per frame (null: unsolved). Optional on input.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub tips: BTreeMap<String, Vec<Option<[f64; 3]>>>,
    /// Per marker, per frame: fitted minus seen distance, mm (null: not seen or unsolved).
    pub marker_residual_mm: BTreeMap<String, Vec<Option<f64>>>,
    /// Contacts of the posed skin with the part.
    pub contacts: Vec<ContactRecord>,
    /// Frames that could not be solved.
    #[serde(default)]
    pub unsolved_frames: Vec<usize>,
    /// Per marker: frames where it was seen but rejected as an outlier.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub rejected_frames: BTreeMap<String, Vec<usize>>,
    /// The part, when a scene was given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub part: Option<PartTrack>,
    /// What the tracker warned about.
    #[serde(default)]
    pub warnings: Vec<String>,
}

impl MotionFile {
    /// The JSON text.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("serialisable")
    }

    /// Write atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        crate::io::atomic::write_bytes_atomic(path, self.to_json().as_bytes())
    }

    /// The centres of `joint` as read back.
    pub fn centres(&self, joint: Joint) -> Option<&[Option<[f64; 3]>]> {
        self.joints.get(joint.name()).map(|t| t.centre.as_slice())
    }
}
