//! Section 3.6 of the seed paper: each 1-DOF joint centre moved onto the skin's cross-section.
//!
//! The calibration motion fixes a 1-DOF joint's axis as a line but not where along it the
//! centre lies (every point of the axis is an equally good centre of the circles the markers
//! move on). The paper places it at "the point on the axis closest to the two skin vertices at
//! the finger's edges" at that joint: the middle of the finger, where a bone's centre is.
//!
//! The two edge vertices are chosen once on the template, by the caliper rule of
//! [`crate::template::landmark_rule::joint_edge_pair`] (the extremes along the axis in the slab
//! normal to the link), and carried by homology: the same indices on the fitted skin. The point
//! of the line `c + t x` minimising the summed squared distances to `a` and `b` is the
//! projection of their midpoint, `t = x·((a + b)/2 − c)`.

use crate::anatomy::Joint;
use crate::error::Result;
use crate::geometry::{Point, TriMesh};
use crate::skeleton::Skeleton;
use crate::template::landmark_rule::joint_edge_pair;
use crate::template::{dominant_links, TemplateHand};
use std::collections::BTreeMap;

/// The edge vertex pair of every 1-DOF joint of the template, by joint name.
pub fn edge_pairs(template: &TemplateHand) -> Result<BTreeMap<Joint, [usize; 2]>> {
    let owner = dominant_links(&template.weights);
    Joint::ALL
        .iter()
        .filter(|j| j.dof() == 1)
        .map(|&j| {
            Ok((
                j,
                joint_edge_pair(&template.mesh, &template.skeleton, &owner, j)?,
            ))
        })
        .collect()
}

/// Move every 1-DOF centre of `model` along its axis to the point nearest to the fitted skin's
/// edge vertices there (`pairs` from [`edge_pairs`]; `skin` homologous to the template).
/// Returns the updated skeleton and, per joint, the signed shift along the axis in mm.
/// 3-DOF joints and every frame are left as they were (a 1-DOF frame's origin moves along its
/// own x axis, which leaves the frame valid).
pub fn centre_on_cross_section(
    model: &Skeleton,
    skin: &TriMesh,
    pairs: &BTreeMap<Joint, [usize; 2]>,
) -> (Skeleton, BTreeMap<String, f64>) {
    let mut out = model.clone();
    let mut shifts = BTreeMap::new();
    for (&j, &[a, b]) in pairs {
        let jf = model.joint(j);
        let x = jf.x();
        let mid = Point::from((skin.vertices[a].coords + skin.vertices[b].coords) / 2.0);
        let t = x.dot(&(mid - jf.centre));
        out.joints[j.index()].centre = jf.centre + x * t;
        shifts.insert(j.name().to_string(), t);
    }
    (out, shifts)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::geometry::Vec3;
    use crate::template::load_template;

    /// On the template itself, a centre slid along its axis comes back to the edge pair's
    /// midpoint level, the centre never leaves its axis line, and the pairs straddle the axis
    /// (one vertex on each side).
    #[test]
    fn centres_return_to_the_mid_level_and_stay_on_the_axis() {
        let t = load_template(Side::Right).unwrap();
        let pairs = edge_pairs(&t).unwrap();
        assert_eq!(pairs.len(), 10);
        let mut moved = t.skeleton.clone();
        for (&j, &[a, b]) in &pairs {
            let jf = t.skeleton.joint(j);
            let x = jf.x();
            let (sa, sb) = (
                x.dot(&(t.mesh.vertices[a] - jf.centre)),
                x.dot(&(t.mesh.vertices[b] - jf.centre)),
            );
            assert!(sa * sb < 0.0, "{j}: edge vertices on one side ({sa}, {sb})");
            moved.joints[j.index()].centre += x * 7.0;
        }
        let (back, shifts) = centre_on_cross_section(&moved, &t.mesh, &pairs);
        for (&j, &[a, b]) in &pairs {
            let jf = t.skeleton.joint(j);
            let c = back.centre(j);
            // On the axis line through the template's centre.
            let off: Vec3 = (c - jf.centre) - jf.x() * jf.x().dot(&(c - jf.centre));
            assert!(off.norm() < 1e-9, "{j} left its axis by {}", off.norm());
            let mid = (t.mesh.vertices[a].coords + t.mesh.vertices[b].coords) / 2.0;
            assert!(jf.x().dot(&(mid - c.coords)).abs() < 1e-9);
            assert!(
                (shifts[j.name()] - (jf.x().dot(&(mid - jf.centre.coords)) - 7.0)).abs() < 1e-9
            );
        }
    }
}
