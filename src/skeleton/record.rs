//! The `joints` table shared by `link_model.json` and `truth.json` (subject-format spec,
//! section 3): name -> parent, DOF, centre, axis (1-DOF only) and frame rows.

use super::Skeleton;
use crate::anatomy::Joint;
use crate::error::{Error, Result};
use crate::geometry::{Point, Vec3};
use nalgebra::{Matrix3, Rotation3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// One joint as written to JSON.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JointRecord {
    /// Parent joint name (`null` for the wrist).
    pub parent: Option<String>,
    /// 3 or 1.
    pub dof: usize,
    /// Centre, mm, reference frame.
    pub centre: [f64; 3],
    /// Unit rotation axis of a 1-DOF joint (the first row of `frame`), `null` for 3-DOF.
    pub axis: Option<[f64; 3]>,
    /// Local axes x, y, z as rows.
    pub frame: [[f64; 3]; 3],
    /// Stage-specific diagnostics (fit residuals, ranges of motion, ...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub diagnostics: Option<serde_json::Value>,
}

/// The `joints` table of a skeleton.
pub fn joint_records(sk: &Skeleton) -> BTreeMap<String, JointRecord> {
    Joint::ALL
        .iter()
        .map(|&j| {
            let jf = sk.joint(j);
            let rows = |v: Vec3| [v.x, v.y, v.z];
            (
                j.name().to_string(),
                JointRecord {
                    parent: j.parent().map(|p| p.name().to_string()),
                    dof: j.dof(),
                    centre: [jf.centre.x, jf.centre.y, jf.centre.z],
                    axis: (j.dof() == 1).then(|| rows(jf.x())),
                    frame: [rows(jf.x()), rows(jf.y()), rows(jf.z())],
                    diagnostics: None,
                },
            )
        })
        .collect()
}

/// Centre and frame of `joint` from a `joints` table read from `path` (errors name both).
pub fn record_frame(
    table: &BTreeMap<String, JointRecord>,
    joint: Joint,
    path: &Path,
) -> Result<(Point, Rotation3<f64>)> {
    let r = table
        .get(joint.name())
        .ok_or_else(|| Error::input(path, format!("joint {joint} is missing from 'joints'")))?;
    let f = r.frame;
    let m = Matrix3::new(
        f[0][0], f[1][0], f[2][0], f[0][1], f[1][1], f[2][1], f[0][2], f[1][2], f[2][2],
    );
    if (m.transpose() * m - Matrix3::identity()).norm() > 1e-6 || m.determinant() < 0.0 {
        return Err(Error::input(
            path,
            format!("joint {joint}: 'frame' is not a right-handed orthonormal basis"),
        ));
    }
    Ok((
        Point::new(r.centre[0], r.centre[1], r.centre[2]),
        Rotation3::from_matrix_unchecked(m),
    ))
}

/// The skeleton of a `joints` table read from `path` (`link_model.json`, or a `truth.json`
/// with frames): every joint's centre and frame ([`record_frame`]; errors name the file and the
/// joint). The files carry no fingertips, so each digit's tip is put along its last joint's z
/// (the distal link's direction) at the length of the link before it; only that direction is
/// read by the caliper definitions ([`crate::measure::caliper`]).
pub fn skeleton_from_records(
    table: &BTreeMap<String, JointRecord>,
    side: crate::anatomy::Side,
    path: &Path,
) -> Result<Skeleton> {
    let joints = Joint::ALL
        .iter()
        .map(|&j| {
            record_frame(table, j, path).map(|(centre, frame)| super::JointFrame { centre, frame })
        })
        .collect::<Result<Vec<_>>>()?;
    let mut tips = [Point::origin(); 5];
    for f in crate::anatomy::Finger::ALL {
        let [_, prev, last] = f.joints();
        let (p, l) = (&joints[prev.index()], &joints[last.index()]);
        tips[f as usize] = l.centre + l.z() * (l.centre - p.centre).norm();
    }
    Ok(Skeleton { side, joints, tips })
}

/// The parts of `link_model.json` a reader of the model needs.
#[derive(Deserialize)]
struct LinkModelFile {
    hand: Option<crate::anatomy::Side>,
    joints: BTreeMap<String, JointRecord>,
}

/// `link_model.json` (spec section 3) from its `text`, read from `path`: the skeleton of its
/// hand and joints table (fingertips as [`skeleton_from_records`] extrapolates them) and the
/// table itself, for the fields beyond the skeleton (each joint's `dof`). Errors name `path`
/// and the field or joint: not a link model, no `hand`, a joint missing, a centre not finite.
pub fn parse_link_model(
    text: &str,
    path: &Path,
) -> Result<(Skeleton, BTreeMap<String, JointRecord>)> {
    let file: LinkModelFile = serde_json::from_str(text)
        .map_err(|e| Error::input(path, format!("not a link model: {e}")))?;
    let side = file.hand.ok_or_else(|| {
        Error::input(
            path,
            "field 'hand' (\"right\" or \"left\") is missing; re-run reconstruct",
        )
    })?;
    let skeleton = skeleton_from_records(&file.joints, side, path)?;
    for j in Joint::ALL {
        if !skeleton.centre(j).coords.iter().all(|x| x.is_finite()) {
            return Err(Error::input(
                path,
                format!("joint {j}: 'centre' is not finite"),
            ));
        }
    }
    Ok((skeleton, file.joints))
}
