//! Joint-centre and axis errors of a `link_model.json` against a simulated subject's
//! `truth.json` (both spec section 3), and the link lengths of both.

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
pub fn compare(
    model: &BTreeMap<String, JointRecord>,
    truth: &BTreeMap<String, JointRecord>,
) -> LinkAccuracy {
    let joints = Joint::ALL
        .iter()
        .map(|j| {
            let (m, t) = (&model[j.name()], &truth[j.name()]);
            let axis_deg = match (m.axis, t.axis) {
                (Some(a), Some(b)) => Some(
                    v(a).angle(&v(b))
                        .to_degrees()
                        .min(180.0 - v(a).angle(&v(b)).to_degrees()),
                ),
                _ => None,
            };
            JointError {
                joint: j.name().to_string(),
                centre_mm: (v(m.centre) - v(t.centre)).norm(),
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
pub fn link_lengths(joints: &BTreeMap<String, JointRecord>) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    for f in Finger::ALL {
        let js = f.joints();
        for k in 0..2 {
            let (a, b) = (js[k].name(), js[k + 1].name());
            if let (Some(ja), Some(jb)) = (joints.get(a), joints.get(b)) {
                out.insert(format!("{a}-{b}"), (v(ja.centre) - v(jb.centre)).norm());
            }
        }
    }
    out
}

/// Compare `link_model.json` at `model` with `truth.json` at `truth`.
pub fn link_accuracy(model: &Path, truth: &Path) -> Result<LinkAccuracy> {
    Ok(compare(&read_joints(model)?, &read_joints(truth)?))
}
