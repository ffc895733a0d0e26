//! Joint-centre and axis errors of a `link_model.json` against a simulated subject's
//! `truth.json` (both spec section 3), and the link lengths of both. `truth.json` is read as the
//! spec defines it (joints with `centre` and `axis`, `dimensions`); everything a simulator adds
//! beyond that is optional (spec section 3, last paragraph).

use crate::anatomy::{Finger, Joint};
use crate::error::{Error, Result};
use crate::skeleton::record::JointRecord;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Deserialize)]
struct JointsFile {
    joints: BTreeMap<String, JointRecord>,
}

/// Read the `joints` table of a `link_model.json` or `truth.json`.
pub fn read_joints(path: &Path) -> Result<BTreeMap<String, JointRecord>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let f: JointsFile = serde_json::from_str(&text)
        .map_err(|e| Error::input(path, format!("not a joints file: {e}")))?;
    for j in Joint::ALL {
        if !f.joints.contains_key(j.name()) {
            return Err(Error::input(
                path,
                format!("joint {j} is missing from 'joints'"),
            ));
        }
    }
    Ok(f.joints)
}

/// A joint of `truth.json` as the spec defines it: a centre and, for 1-DOF joints, an axis.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct TruthJoint {
    /// Centre, mm, reference frame.
    pub centre: [f64; 3],
    /// Unit rotation axis (1-DOF joints); absent or `null` for 3-DOF joints.
    #[serde(default)]
    pub axis: Option<[f64; 3]>,
}

/// What `validate` reads of `truth.json`: the spec's `joints` (centre, axis) and `dimensions`
/// (name -> mm; may be absent). Any other field is ignored.
#[derive(Clone, Debug, PartialEq, Deserialize)]
pub struct TruthFile {
    /// True joint centres and axes.
    pub joints: BTreeMap<String, TruthJoint>,
    /// Error-free values of the dimensions, mm.
    #[serde(default)]
    pub dimensions: BTreeMap<String, f64>,
}

/// Read `truth.json` at `path`: every joint of the spec must be there (the error names the file
/// and the joint); extensions beyond the spec are optional.
pub fn read_truth(path: &Path) -> Result<TruthFile> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let t: TruthFile = serde_json::from_str(&text)
        .map_err(|e| Error::input(path, format!("not a truth file: {e}")))?;
    for j in Joint::ALL {
        let Some(r) = t.joints.get(j.name()) else {
            return Err(Error::input(
                path,
                format!("joint {j} is missing from 'joints'"),
            ));
        };
        if j.dof() == 1 && r.axis.is_none() {
            return Err(Error::input(
                path,
                format!("joint {j}: a 1-DOF joint needs its 'axis'"),
            ));
        }
    }
    Ok(t)
}

/// A joint's centre and axis, from either table.
pub trait CentreAxis {
    /// Centre, mm.
    fn centre(&self) -> [f64; 3];
    /// Unit axis of a 1-DOF joint.
    fn axis(&self) -> Option<[f64; 3]>;
}

impl CentreAxis for JointRecord {
    fn centre(&self) -> [f64; 3] {
        self.centre
    }
    fn axis(&self) -> Option<[f64; 3]> {
        self.axis
    }
}

impl CentreAxis for TruthJoint {
    fn centre(&self) -> [f64; 3] {
        self.centre
    }
    fn axis(&self) -> Option<[f64; 3]> {
        self.axis
    }
}

/// Error of one joint.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct JointError {
    /// Joint name.
    pub joint: String,
    /// Distance between estimated and true centres, mm.
    pub centre_mm: f64,
    /// Angle between estimated and true axes (1-DOF joints), degrees, sign ignored.
    pub axis_deg: Option<f64>,
}

/// Errors of every joint, and the link lengths (MCP-PIP, PIP-DIP; thumb CMC-MCP, MCP-IP).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LinkAccuracy {
    /// Per joint, in [`Joint::ALL`] order.
    pub joints: Vec<JointError>,
    /// Link length name (`I_MCP-I_PIP`) -> (estimated, true), mm.
    pub link_lengths: BTreeMap<String, (f64, f64)>,
}

fn v(a: [f64; 3]) -> nalgebra::Vector3<f64> {
    nalgebra::Vector3::new(a[0], a[1], a[2])
}

/// Compare two `joints` tables.
pub fn compare<T: CentreAxis>(
    model: &BTreeMap<String, JointRecord>,
    truth: &BTreeMap<String, T>,
) -> LinkAccuracy {
    let joints = Joint::ALL
        .iter()
        .map(|j| {
            let (m, t) = (&model[j.name()], &truth[j.name()]);
            let axis_deg = match (m.axis, t.axis()) {
                (Some(a), Some(b)) => Some(
                    v(a).angle(&v(b))
                        .to_degrees()
                        .min(180.0 - v(a).angle(&v(b)).to_degrees()),
                ),
                _ => None,
            };
            JointError {
                joint: j.name().to_string(),
                centre_mm: (v(m.centre) - v(t.centre())).norm(),
                axis_deg,
            }
        })
        .collect();
    let true_lengths = link_lengths(truth);
    let link_lengths = link_lengths(model)
        .into_iter()
        .filter_map(|(k, m)| Some((k.clone(), (m, *true_lengths.get(&k)?))))
        .collect();
    LinkAccuracy {
        joints,
        link_lengths,
    }
}

/// Link lengths of one `joints` table: the distance between consecutive joint centres of each
/// digit (MCP-PIP, PIP-DIP; thumb CMC-MCP, MCP-IP), keyed `I_MCP-I_PIP`, mm. Joints missing
/// from the table are skipped ([`read_joints`] guarantees all of them).
pub fn link_lengths<T: CentreAxis>(joints: &BTreeMap<String, T>) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    for f in Finger::ALL {
        let js = f.joints();
        for k in 0..2 {
            let (a, b) = (js[k].name(), js[k + 1].name());
            if let (Some(ja), Some(jb)) = (joints.get(a), joints.get(b)) {
                out.insert(format!("{a}-{b}"), (v(ja.centre()) - v(jb.centre())).norm());
            }
        }
    }
    out
}

/// Compare `link_model.json` at `model` with `truth.json` at `truth`.
pub fn link_accuracy(model: &Path, truth: &Path) -> Result<LinkAccuracy> {
    Ok(compare(&read_joints(model)?, &read_truth(truth)?.joints))
}
