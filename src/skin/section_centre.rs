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
//!
//! Nor does it fix the centre's depth below the back of the finger well: a plate whose skin
//! slides along the bone as the joint flexes moves the fitted centre dorsally or palmarly by
//! the slide per radian, which no motion tells from a deeper or shallower joint. Where a caliper
//! fixed the finger's thickness at the joint, the skin gives a second depth: the template's
//! centre written as an affine combination of the skin around it ([`centre_ring`]), carried by
//! homology onto the fitted skin ([`depth_offsets`]). It is off by the template's proportions
//! where the subject's differ; the link model weighs the two
//! ([`crate::link::LinkModel::with_skin_centres`]).

use crate::anatomy::{Dimension, Joint};
use crate::error::Result;
use crate::geometry::{Point, TriMesh, Vec3};
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

/// Vertices around joint `j` and affine weights reproducing its centre.
///
/// The ring: vertices of the two links the joint connects, in two slabs just proximal and
/// just distal of the joint's plane (normal to its link), within 16 mm of the centre, one per
/// 45° sector around the link's axis and slab (the nearest to the centre in that sector). Two
/// slabs make the points span 3-D, so the centre is an affine combination of them; the weights
/// are the affine ones closest to uniform, `w = w₀ + Aᵀ(AAᵀ)⁻¹(b − A w₀)` with `A` the rows of
/// the homogeneous coordinates, `b = (c, 1)`. `None` when fewer than six sectors are filled.
pub fn centre_ring(
    mesh: &TriMesh,
    owner: &[usize],
    sk: &Skeleton,
    j: Joint,
) -> Option<(Vec<usize>, Vec<f64>)> {
    let jf = sk.joint(j);
    let c = jf.centre;
    let (z, x, y) = (jf.z(), jf.x(), jf.y());
    let links = [j.parent_link().index(), j.child_link().index()];
    let mean_edge = {
        let f = &mesh.faces;
        let n = f.len().min(4000);
        let step = (f.len() / n.max(1)).max(1);
        let (mut s, mut k) = (0.0, 0);
        for face in f.iter().step_by(step) {
            s += (mesh.vertices[face[0]] - mesh.vertices[face[1]]).norm();
            k += 1;
        }
        s / k.max(1) as f64
    };
    let slab = mean_edge.max(1.0);
    let mut best: [Option<(f64, usize)>; 16] = [None; 16];
    for (v, p) in mesh.vertices.iter().enumerate() {
        if !links.contains(&owner[v]) {
            continue;
        }
        let d: Vec3 = p - c;
        let h = d.dot(&z);
        if h.abs() > slab || d.norm() > 16.0 {
            continue;
        }
        let level = usize::from(h >= 0.0);
        let ang = d.dot(&y).atan2(d.dot(&x));
        let sector =
            (((ang + std::f64::consts::PI) / (std::f64::consts::PI / 4.0)) as usize).min(7);
        let slot = &mut best[level * 8 + sector];
        let r = d.norm();
        if slot.is_none_or(|(rb, _)| r < rb) {
            *slot = Some((r, v));
        }
    }
    let verts: Vec<usize> = best.iter().flatten().map(|&(_, v)| v).collect();
    if verts.len() < 6 {
        return None;
    }
    let k = verts.len();
    let a = nalgebra::DMatrix::from_fn(4, k, |r, i| {
        if r < 3 {
            mesh.vertices[verts[i]][r]
        } else {
            1.0
        }
    });
    let w0 = nalgebra::DVector::from_element(k, 1.0 / k as f64);
    let b = nalgebra::DVector::from_vec(vec![c.x, c.y, c.z, 1.0]);
    let gram = &a * a.transpose();
    let lam = gram.cholesky()?.solve(&(b - &a * &w0));
    let w = w0 + a.transpose() * lam;
    Some((verts, w.iter().copied().collect()))
}

/// The hinges whose thickness one of `dimensions` gives (the PIP and DIP joints, the thumb's
/// IP), each with its [`centre_ring`] on `mesh` (the template, posed by `skeleton`; `owner` the
/// dominant link of each vertex). A hinge whose ring cannot be built is left out.
pub fn depth_rings<'a>(
    mesh: &TriMesh,
    owner: &[usize],
    skeleton: &Skeleton,
    dimensions: impl IntoIterator<Item = &'a Dimension>,
) -> BTreeMap<Joint, (Vec<usize>, Vec<f64>)> {
    dimensions
        .into_iter()
        .filter(|d| {
            matches!(
                d,
                Dimension::ThicknessProximal(_) | Dimension::ThicknessDistal(_)
            )
        })
        .filter_map(|d| d.section_joint())
        .filter_map(|j| centre_ring(mesh, owner, skeleton, j).map(|r| (j, r)))
        .collect()
}

/// Per hinge of `rings` ([`depth_rings`]): the ring's point on `skin` (homologous to the mesh
/// the rings were built on) minus the centre of `model`, along the joint frame's y (dorsal),
/// mm, by joint name: how much deeper (negative) or shallower the skin puts the centre.
pub fn depth_offsets(
    model: &Skeleton,
    skin: &TriMesh,
    rings: &BTreeMap<Joint, (Vec<usize>, Vec<f64>)>,
) -> BTreeMap<String, f64> {
    rings
        .iter()
        .map(|(&j, (verts, weights))| {
            let p: Vec3 = verts
                .iter()
                .zip(weights)
                .map(|(&v, w)| skin.vertices[v].coords * *w)
                .sum();
            let jf = model.joint(j);
            (j.name().to_string(), jf.y().dot(&(p - jf.centre.coords)))
        })
        .collect()
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
