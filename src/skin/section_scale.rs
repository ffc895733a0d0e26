//! Finger sections scaled to their calipers: an optional last step of the skin fit, on the fine
//! skin ([`super::pipeline::SkinOptions::section_scaling`]).
//!
//! The landmark fit meets each caliper through one vertex pair of the simplified template
//! (seed paper, section 3.5, equation 2), and the caliper rounds move the pair's length until a
//! caliper on the fitted skin reads the given value. On a finger a pair cannot get closer than
//! about a millimetre: a section has a handful of coarse vertices, and moving the pair by less
//! bends the skin into a bump instead of widening the finger (the rounds' finger slack). What
//! is left is a finger a millimetre or more too thin or too thick where a user's caliper reads
//! it.
//!
//! Here the fine skin of each digit is scaled across its bone, anisotropically, by what a
//! caliper on it misses: at a section (the plane bisecting the two links at the joint, as
//! the spec measures) the breadth along the joint's axis by `given / measured`, the thickness
//! square to it likewise. Along the digit the scale is carried by each link: interpolated
//! between two sections, brought in smoothly from 1 over the first half of a link that has a
//! section at its end only (the proximal phalanx from the knuckle, the thumb's from its MCP), so
//! the palm and the web are not moved, and faded from the distal section's back to 1 at the
//! fingertip (the pulp is not the distal joint's section). Each vertex moves by its skinning weights' blend of its links'
//! displacements, so the seams follow the template's own. The displacement is a scaling about
//! the link's line and changes neither topology nor the order of the vertices: the skin stays
//! homologous.

use crate::anatomy::{Dimension, Finger, Joint};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::skeleton::Skeleton;
use crate::template::LinkWeights;
use std::collections::BTreeMap;

/// A section's scale is held within this share of 1: a caliper that far from the skin is a
/// wrong reading or a section that did not measure, not a finger to reshape.
pub const MAX_SCALE_CHANGE: f64 = 0.15;

/// Breadth and thickness scale per section joint: `given / measured` from the calipers'
/// misses (`measured - given`, by dimension name), within [`MAX_SCALE_CHANGE`].
pub fn section_scales(
    misses: &BTreeMap<String, f64>,
    given: &BTreeMap<Dimension, f64>,
) -> BTreeMap<Joint, [f64; 2]> {
    let mut out: BTreeMap<Joint, [f64; 2]> = BTreeMap::new();
    for (d, &value) in given {
        let Some(joint) = d.section_joint() else {
            continue;
        };
        let Some(miss) = misses.get(&d.name()) else {
            continue;
        };
        let measured = value + miss;
        if measured <= 0.0 || value <= 0.0 {
            continue;
        }
        let s = (value / measured).clamp(1.0 - MAX_SCALE_CHANGE, 1.0 + MAX_SCALE_CHANGE);
        let k = match d {
            Dimension::BreadthProximal(_) | Dimension::BreadthDistal(_) => 0,
            _ => 1,
        };
        out.entry(joint).or_insert([1.0, 1.0])[k] = s;
    }
    out
}

/// Smooth step from 0 at `x = 0` to 1 at `x = 1`.
fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

/// The displacement of every vertex of `skin` (skinned to `skeleton`'s links by `weights`, per
/// vertex `(link index, weight)`) that scales each digit's sections by `scales` (per section
/// joint: breadth along the joint's axis, thickness square to it), carried along the digit as
/// the module documentation says. Vertices of no digit's phalanges do not move.
pub fn section_scaling(
    skin: &TriMesh,
    skeleton: &Skeleton,
    weights: &LinkWeights,
    scales: &BTreeMap<Joint, [f64; 2]>,
) -> Vec<Vec3> {
    // Per link index: its start, unit direction, length and the scale profile along it.
    struct Carrier {
        start: Point,
        dir: Vec3,
        len: f64,
        u: Vec3,
        v: Vec3,
        /// Scale at the start and at the end, and whether the start's is brought in (1 at
        /// the start, the end's value from the middle on).
        at_start: [f64; 2],
        at_end: [f64; 2],
        ramp: bool,
    }
    let mut carriers: BTreeMap<usize, Carrier> = BTreeMap::new();
    for f in Finger::ALL {
        let joints = f.joints();
        let links = f.links();
        for r in 0..3 {
            let here = scales.get(&joints[r]).copied();
            let next = if r < 2 {
                scales.get(&joints[r + 1]).copied()
            } else {
                None
            };
            let (at_start, at_end, ramp) = match (here, next) {
                (Some(a), Some(b)) => (a, b, false),
                (None, Some(b)) => ([1.0, 1.0], b, true),
                (Some(a), None) if r < 2 => (a, a, false),
                (Some(a), None) => (a, [1.0, 1.0], false),
                (None, None) => continue,
            };
            let start = skeleton.centre(joints[r]);
            let end = skeleton.distal_end(joints[r]);
            let Some(dir) = (end - start).try_normalize(1e-9) else {
                continue;
            };
            // The axis of the section this link's scale comes from (the end's when it is
            // brought in, else the start's), square to the link.
            let axis_joint = if ramp { joints[r + 1] } else { joints[r] };
            let x = skeleton.joint(axis_joint).x();
            let Some(u) = (x - dir * x.dot(&dir)).try_normalize(1e-9) else {
                continue;
            };
            carriers.insert(
                links[r].index(),
                Carrier {
                    start,
                    dir,
                    len: (end - start).norm(),
                    u,
                    v: dir.cross(&u),
                    at_start,
                    at_end,
                    ramp,
                },
            );
        }
    }
    skin.vertices
        .iter()
        .zip(weights)
        .map(|(p, w)| {
            let mut d = Vec3::zeros();
            for &(link, weight) in w {
                let Some(c) = carriers.get(&link) else {
                    continue;
                };
                let along = (p - c.start).dot(&c.dir);
                let t = (along / c.len).clamp(0.0, 1.0);
                let s: [f64; 2] = if c.ramp {
                    let k = smoothstep(2.0 * t);
                    [1.0 + (c.at_end[0] - 1.0) * k, 1.0 + (c.at_end[1] - 1.0) * k]
                } else {
                    [
                        c.at_start[0] + (c.at_end[0] - c.at_start[0]) * t,
                        c.at_start[1] + (c.at_end[1] - c.at_start[1]) * t,
                    ]
                };
                let q = p - c.start - c.dir * along;
                d += (c.u * ((s[0] - 1.0) * c.u.dot(&q)) + c.v * ((s[1] - 1.0) * c.v.dot(&q)))
                    * weight;
            }
            d
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Link;
    use crate::measure::caliper::finger_joint_section;

    /// A straight finger as a tube of elliptic sections along the index's three links: the
    /// section scaled to given values reads them on a caliper, the palm does not move.
    #[test]
    fn a_scaled_tube_reads_the_given_calipers() {
        let template = crate::template::load_template(crate::anatomy::Side::Right).unwrap();
        let sk = &template.skeleton;
        let f = Finger::Index;
        let (j, links) = (f.joints(), f.links());
        // An elliptic tube around the index's bones, each ring skinned to its link; a palm ring
        // behind the knuckle skinned to the palm.
        let (ra, rb) = (9.0, 7.5);
        let mut vertices = Vec::new();
        let mut weights: LinkWeights = Vec::new();
        let mut faces = Vec::new();
        let segments = 24;
        let mut rings = 0;
        let mut ring_at = |centre: Point, dir: Vec3, x: Vec3, link: usize| {
            let u = (x - dir * x.dot(&dir)).normalize();
            let v = dir.cross(&u);
            for k in 0..segments {
                let a = k as f64 / segments as f64 * std::f64::consts::TAU;
                vertices.push(centre + u * (ra * a.cos()) + v * (rb * a.sin()));
                weights.push(vec![(link, 1.0)]);
            }
            rings += 1;
        };
        let mcp = sk.centre(j[0]);
        let dir0 = (sk.centre(j[1]) - mcp).normalize();
        ring_at(
            mcp - dir0 * 8.0,
            dir0,
            sk.joint(j[1]).x(),
            Link::Palm.index(),
        );
        for r in 0..3 {
            let (a, b) = (sk.centre(j[r]), sk.distal_end(j[r]));
            let dir = (b - a).normalize();
            let axis = sk.joint(j[r.max(1)]).x();
            for t in [0.0, 0.25, 0.5, 0.75] {
                ring_at(a + (b - a) * t, dir, axis, links[r].index());
            }
        }
        for r in 0..rings - 1 {
            for k in 0..segments {
                let (a, b) = (r * segments + k, r * segments + (k + 1) % segments);
                let (c, d) = (a + segments, b + segments);
                faces.push([a, b, d]);
                faces.push([a, d, c]);
            }
        }
        let skin = TriMesh { vertices, faces };
        let before = finger_joint_section(&skin, sk, j[1]).unwrap();
        let given: BTreeMap<Dimension, f64> = [
            (Dimension::BreadthProximal(f), before.0 * 1.08),
            (Dimension::ThicknessProximal(f), before.1 * 0.95),
        ]
        .into();
        let misses: BTreeMap<String, f64> = [
            (
                Dimension::BreadthProximal(f).name(),
                before.0 - given[&Dimension::BreadthProximal(f)],
            ),
            (
                Dimension::ThicknessProximal(f).name(),
                before.1 - given[&Dimension::ThicknessProximal(f)],
            ),
        ]
        .into();
        let scales = section_scales(&misses, &given);
        let d = section_scaling(&skin, sk, &weights, &scales);
        let mut after = skin.clone();
        for (p, x) in after.vertices.iter_mut().zip(&d) {
            *p += x;
        }
        let (b, t) = finger_joint_section(&after, sk, j[1]).unwrap();
        assert!(
            (b - given[&Dimension::BreadthProximal(f)]).abs() < 0.05,
            "{b}"
        );
        assert!(
            (t - given[&Dimension::ThicknessProximal(f)]).abs() < 0.05,
            "{t}"
        );
        // The palm's ring and the knuckle's do not move.
        for (i, x) in d.iter().enumerate().take(2 * segments) {
            assert!(x.norm() < 1e-12, "vertex {i} moved {}", x.norm());
        }
        // No displacement along a link.
        for (i, x) in d.iter().enumerate() {
            let link = weights[i][0].0;
            if let Some(r) = links.iter().position(|l| l.index() == link) {
                let dir = (sk.distal_end(j[r]) - sk.centre(j[r])).normalize();
                assert!(x.dot(&dir).abs() < 1e-9);
            }
        }
    }

    /// Misses become `given / measured`, held within the limit; palm dimensions carry no
    /// section.
    #[test]
    fn scales_are_given_over_measured_within_the_limit() {
        let f = Finger::Ring;
        let given: BTreeMap<Dimension, f64> = [
            (Dimension::BreadthDistal(f), 16.0),
            (Dimension::ThicknessDistal(f), 14.0),
            (Dimension::HandThicknessMc3, 30.0),
        ]
        .into();
        let misses: BTreeMap<String, f64> = [
            (Dimension::BreadthDistal(f).name(), -1.0),
            (Dimension::ThicknessDistal(f).name(), 10.0),
            (Dimension::HandThicknessMc3.name(), 2.0),
        ]
        .into();
        let s = section_scales(&misses, &given);
        assert_eq!(s.len(), 1);
        let [b, t] = s[&f.joints()[2]];
        assert!((b - 16.0 / 15.0).abs() < 1e-12);
        assert!((t - (1.0 - MAX_SCALE_CHANGE)).abs() < 1e-12);
    }
}
