//! Finger and wrist sections scaled to their calipers: an optional last step of the skin fit,
//! on the fine skin ([`super::pipeline::SkinOptions::section_scaling`]).
//!
//! The landmark fit meets each caliper through one vertex pair of the simplified template
//! (seed paper, section 3.5, equation 2), and the caliper rounds move the pair's length until a
//! caliper on the fitted skin reads the given value. On a finger a pair cannot get closer than
//! about a millimetre: a section has a handful of coarse vertices, and moving the pair by less
//! bends the skin into a bump instead of widening the finger (the rounds' finger slack). At the
//! wrist the pair runs between the styloid landmarks and the forearm's back, and on a hand
//! unlike the template the rounds can leave it a millimetre or more off. What is left is a
//! section too thin or too thick where a user's caliper reads it.
//!
//! Here the fine skin of each digit is scaled across its bone, anisotropically, by what a
//! caliper on it misses: at a section (the plane bisecting the two links at the joint, as
//! the spec measures) the breadth along the joint's axis by `given / measured`, the thickness
//! square to it likewise, about the dorsal skin (where the landmarks hold the surface: the
//! thickness a caliper misses is the palmar side's). Along the digit the scale is carried by
//! each link: interpolated between two sections, brought in smoothly from 1 over the first
//! half of a link that has a section at its end only (the proximal phalanx from the knuckle,
//! the thumb's from its MCP), so the palm and the web are not moved, and faded from the distal
//! section's back to 1 at the fingertip (the pulp is not the distal joint's section). Each
//! vertex moves by its skinning weights' blend of its links' displacements, so the seams follow
//! the template's own. The wrist's section ([`wrist_scaling`]) is scaled alike at the styloids'
//! plane, faded along the forearm and into the palm's base. The displacement changes neither
//! topology nor the order of the vertices: the skin stays homologous.

use crate::anatomy::{Dimension, Finger, Joint};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::skeleton::Skeleton;
use crate::template::LinkWeights;
use std::collections::BTreeMap;

/// A section's scale is held within this share of 1: a caliper that far from the skin is a
/// wrong reading or a section that did not measure, not a finger to reshape.
pub const MAX_SCALE_CHANGE: f64 = 0.15;

/// `given / measured` for dimension `d` from its caliper's miss (`measured - given`, by
/// dimension name), within [`MAX_SCALE_CHANGE`]; `None` when `d` is not given or not read.
fn caliper_scale(
    d: Dimension,
    misses: &BTreeMap<String, f64>,
    given: &BTreeMap<Dimension, f64>,
) -> Option<f64> {
    let value = *given.get(&d)?;
    let measured = value + misses.get(&d.name())?;
    (measured > 0.0 && value > 0.0)
        .then(|| (value / measured).clamp(1.0 - MAX_SCALE_CHANGE, 1.0 + MAX_SCALE_CHANGE))
}

/// Breadth and thickness scale per section joint: `given / measured` from the calipers'
/// misses (`measured - given`, by dimension name), within [`MAX_SCALE_CHANGE`].
pub fn section_scales(
    misses: &BTreeMap<String, f64>,
    given: &BTreeMap<Dimension, f64>,
) -> BTreeMap<Joint, [f64; 2]> {
    let mut out: BTreeMap<Joint, [f64; 2]> = BTreeMap::new();
    for &d in given.keys() {
        let Some(joint) = d.section_joint() else {
            continue;
        };
        let Some(s) = caliper_scale(d, misses, given) else {
            continue;
        };
        let k = match d {
            Dimension::BreadthProximal(_) | Dimension::BreadthDistal(_) => 0,
            _ => 1,
        };
        out.entry(joint).or_insert([1.0, 1.0])[k] = s;
    }
    out
}

/// The wrist's breadth and thickness scale, `given / measured` from the calipers' misses
/// within [`MAX_SCALE_CHANGE`] (1 for a dimension not given or not read); `None` when
/// neither is given and read.
pub fn wrist_scales(
    misses: &BTreeMap<String, f64>,
    given: &BTreeMap<Dimension, f64>,
) -> Option<[f64; 2]> {
    match (
        caliper_scale(Dimension::WristBreadth, misses, given),
        caliper_scale(Dimension::WristThickness, misses, given),
    ) {
        (None, None) => None,
        (b, t) => Some([b.unwrap_or(1.0), t.unwrap_or(1.0)]),
    }
}

/// Half-width of the slab about the styloids' plane scaled in full, mm: the section's own
/// skin, whose dorsal-most point the thickness is scaled about.
const WRIST_PLATEAU_MM: f64 = 5.0;

/// How far beyond [`WRIST_PLATEAU_MM`] the wrist's scale fades back to 1, proximally and
/// distally, mm: the forearm's section changes slowly, the palm's base meets the thenar.
const WRIST_FADE_MM: [f64; 2] = [40.0, 20.0];

/// The displacement of every vertex of `skin` that scales the wrist's section (the spec's: the
/// plane through the midpoint of the `WRIST_RAD` and `WRIST_ULN` skin points `landmarks`,
/// normal to the forearm axis, the wrist frame's z) by `scale` (breadth along the styloids'
/// line, thickness dorsal-palmar about the section's dorsal skin, where the `WRIST` marker
/// holds it), in full within [`WRIST_PLATEAU_MM`] of the plane, faded to 1 over
/// [`WRIST_FADE_MM`] beyond it along the axis and carried by each vertex's
/// skinning weight of the forearm and the palm (the thumb's bones do not move). Empty when a
/// styloid landmark is missing.
pub fn wrist_scaling(
    skin: &TriMesh,
    skeleton: &Skeleton,
    weights: &LinkWeights,
    landmarks: &BTreeMap<String, Point>,
    scale: [f64; 2],
) -> Vec<Vec3> {
    use crate::anatomy::Link;
    let (Some(r), Some(u)) = (landmarks.get("WRIST_RAD"), landmarks.get("WRIST_ULN")) else {
        return Vec::new();
    };
    let m = r + (u - r) * 0.5;
    let frame = skeleton.joint(Joint::Wrist);
    let z = frame.z();
    let Some(e) = ((r - u) - z * z.dot(&(r - u))).try_normalize(1e-9) else {
        return Vec::new();
    };
    let mut w = z.cross(&e);
    if w.dot(&frame.y()) < 0.0 {
        w = -w;
    }
    let (arm, palm) = (Link::Arm.index(), Link::Palm.index());
    let carried = |wt: &[(usize, f64)]| -> f64 {
        wt.iter()
            .filter(|(l, _)| *l == arm || *l == palm)
            .map(|(_, x)| x)
            .sum::<f64>()
            .clamp(0.0, 1.0)
    };
    let top = skin
        .vertices
        .iter()
        .zip(weights)
        .filter(|(p, wt)| z.dot(&(*p - m)).abs() < WRIST_PLATEAU_MM && carried(wt) >= 0.5)
        .map(|(p, _)| w.dot(&(p - m)))
        .fold(f64::NEG_INFINITY, f64::max);
    if !top.is_finite() {
        return Vec::new();
    }
    skin.vertices
        .iter()
        .zip(weights)
        .map(|(p, wt)| {
            let a = z.dot(&(p - m));
            let fade = if a < 0.0 {
                WRIST_FADE_MM[0]
            } else {
                WRIST_FADE_MM[1]
            };
            let k = smoothstep(1.0 - (a.abs() - WRIST_PLATEAU_MM).max(0.0) / fade) * carried(wt);
            if k == 0.0 {
                return Vec3::zeros();
            }
            let q = p - m - z * a;
            (e * ((scale[0] - 1.0) * e.dot(&q)) + w * ((scale[1] - 1.0) * (w.dot(&q) - top))) * k
        })
        .collect()
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
        /// Unit dorsal direction square to the link and to `u`.
        v: Vec3,
        /// The dorsal skin's height along `v` over the link.
        dorsal: DorsalProfile,
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
            let mut v = dir.cross(&u);
            if v.dot(&skeleton.joint(axis_joint).y()) < 0.0 {
                v = -v;
            }
            let link = links[r].index();
            let len = (end - start).norm();
            carriers.insert(
                link,
                Carrier {
                    start,
                    dir,
                    len,
                    u,
                    v,
                    dorsal: DorsalProfile::new(skin, weights, link, start, dir, v),
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
                // The thickness about the dorsal skin, where the landmarks hold it: what a
                // caliper's thickness misses is the palmar side's.
                let top = c.dorsal.at(along);
                d += (c.u * ((s[0] - 1.0) * c.u.dot(&q))
                    + c.v * ((s[1] - 1.0) * (c.v.dot(&q) - top)))
                    * weight;
            }
            d
        })
        .collect()
}

/// Half-length of the stretch of a link whose skin gives the dorsal height at a point, mm:
/// a section's own skin, a few vertex rings of the fine template.
const DORSAL_WINDOW_MM: f64 = 3.0;

/// The dorsal skin's height along a link: the largest `v · (p - line)` of the vertices skinned
/// mostly to it within [`DORSAL_WINDOW_MM`] along the link of a point.
struct DorsalProfile {
    /// `(along, height)` of the link's vertices, by `along`.
    samples: Vec<(f64, f64)>,
}

impl DorsalProfile {
    fn new(
        skin: &TriMesh,
        weights: &LinkWeights,
        link: usize,
        start: Point,
        dir: Vec3,
        v: Vec3,
    ) -> DorsalProfile {
        let mut samples: Vec<(f64, f64)> = skin
            .vertices
            .iter()
            .zip(weights)
            .filter(|(_, w)| w.iter().any(|&(l, x)| l == link && x >= 0.5))
            .map(|(p, _)| {
                let along = (p - start).dot(&dir);
                (along, v.dot(&(p - start - dir * along)))
            })
            .collect();
        samples.sort_by(|a, b| a.0.total_cmp(&b.0));
        DorsalProfile { samples }
    }

    /// The height at `along`: the window's largest, or the nearest sample's beyond the link's
    /// skin; 0 (the link's line) for a link without skin.
    fn at(&self, along: f64) -> f64 {
        let s = &self.samples;
        let lo = s.partition_point(|x| x.0 < along - DORSAL_WINDOW_MM);
        let hi = s.partition_point(|x| x.0 <= along + DORSAL_WINDOW_MM);
        if lo < hi {
            return s[lo..hi]
                .iter()
                .map(|x| x.1)
                .fold(f64::NEG_INFINITY, f64::max);
        }
        match (lo.checked_sub(1).map(|i| s[i]), s.get(hi)) {
            (Some(a), Some(b)) => {
                if along - a.0 < b.0 - along {
                    a.1
                } else {
                    b.1
                }
            }
            (Some(a), None) => a.1,
            (None, Some(b)) => b.1,
            (None, None) => 0.0,
        }
    }
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
        // The thickness is scaled about the dorsal skin: each ring's dorsal-most vertex keeps
        // its height.
        for r in 0..3 {
            let (a, b) = (sk.centre(j[r]), sk.distal_end(j[r]));
            let dir = (b - a).normalize();
            let axis = sk.joint(j[r.max(1)]).x();
            let u = (axis - dir * axis.dot(&dir)).normalize();
            let mut w = dir.cross(&u);
            if w.dot(&sk.joint(j[r.max(1)]).y()) < 0.0 {
                w = -w;
            }
            for ring in 1 + 4 * r..1 + 4 * (r + 1) {
                let ids = ring * segments..(ring + 1) * segments;
                let centre = ids
                    .clone()
                    .fold(Vec3::zeros(), |c, i| c + skin.vertices[i].coords)
                    / segments as f64;
                let top = ids
                    .max_by(|&x, &y| {
                        let h = |i: usize| w.dot(&(skin.vertices[i].coords - centre));
                        h(x).total_cmp(&h(y))
                    })
                    .unwrap();
                assert!(
                    d[top].dot(&w).abs() < 1e-9,
                    "ring {ring}: {}",
                    d[top].dot(&w)
                );
            }
        }
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

    /// An elliptic forearm tube through the wrist, its styloid landmarks at the breadth's
    /// ends: scaled to given values it reads them on the spec's caliper, its dorsal skin at
    /// the section keeps its height, and neither the thumb's skin nor the forearm beyond the
    /// fade moves.
    #[test]
    fn a_scaled_wrist_reads_the_given_calipers() {
        use crate::measure::caliper::wrist_section;
        let template = crate::template::load_template(crate::anatomy::Side::Right).unwrap();
        let sk = &template.skeleton;
        let frame = sk.joint(Joint::Wrist);
        let (e, y, z) = (frame.x(), frame.y(), frame.z());
        let c = sk.centre(Joint::Wrist);
        let (ra, rb, segments) = (28.0, 19.0, 32);
        let levels: Vec<f64> = (0..21).map(|k| -77.5 + 5.0 * k as f64).collect();
        let mut vertices = Vec::new();
        let mut weights: LinkWeights = Vec::new();
        for &a in &levels {
            let link = if a > 12.0 {
                Link::TMeta
            } else if a < 0.0 {
                Link::Arm
            } else {
                Link::Palm
            };
            for k in 0..segments {
                let t = k as f64 / segments as f64 * std::f64::consts::TAU;
                vertices.push(c + z * a + e * (ra * t.cos()) + y * (rb * t.sin()));
                weights.push(vec![(link.index(), 1.0)]);
            }
        }
        let mut faces = Vec::new();
        for r in 0..levels.len() - 1 {
            for k in 0..segments {
                let (a, b) = (r * segments + k, r * segments + (k + 1) % segments);
                faces.push([a, b, b + segments]);
                faces.push([a, b + segments, a + segments]);
            }
        }
        let skin = TriMesh { vertices, faces };
        // The styloids on the rings either side of the plane through the wrist's centre.
        let at = |ring: usize, k: usize| ring * segments + k;
        let (rad, uln) = ([at(15, 0), at(16, 0)], [at(15, 16), at(16, 16)]);
        let landmarks_of = |m: &TriMesh| -> BTreeMap<String, Point> {
            let mid =
                |v: [usize; 2]| m.vertices[v[0]] + (m.vertices[v[1]] - m.vertices[v[0]]) * 0.5;
            [
                ("WRIST_RAD".to_string(), mid(rad)),
                ("WRIST_ULN".to_string(), mid(uln)),
            ]
            .into()
        };
        let before = wrist_section(&skin, sk, &landmarks_of(&skin)).unwrap();
        assert!((before.0 - 2.0 * ra).abs() < 0.01 && (before.1 - 2.0 * rb).abs() < 0.1);
        let given: BTreeMap<Dimension, f64> = [
            (Dimension::WristBreadth, before.0 * 1.05),
            (Dimension::WristThickness, before.1 * 0.96),
        ]
        .into();
        let misses: BTreeMap<String, f64> = given
            .iter()
            .map(|(d, v)| {
                let m = if *d == Dimension::WristBreadth {
                    before.0
                } else {
                    before.1
                };
                (d.name(), m - v)
            })
            .collect();
        let scale = wrist_scales(&misses, &given).unwrap();
        let d = wrist_scaling(&skin, sk, &weights, &landmarks_of(&skin), scale);
        let mut after = skin.clone();
        for (p, x) in after.vertices.iter_mut().zip(&d) {
            *p += x;
        }
        let (b, t) = wrist_section(&after, sk, &landmarks_of(&after)).unwrap();
        assert!((b - given[&Dimension::WristBreadth]).abs() < 0.05, "{b}");
        assert!((t - given[&Dimension::WristThickness]).abs() < 0.05, "{t}");
        // The dorsal-most vertex of the section's rings keeps its height.
        for ring in [15, 16] {
            let top = at(ring, segments / 4);
            assert!(d[top].dot(&y).abs() < 1e-9, "{}", d[top].dot(&y));
        }
        for (i, x) in d.iter().enumerate() {
            let a = levels[i / segments];
            // The thumb's bone and the forearm beyond the plateau and the fade stay.
            if !(-(WRIST_PLATEAU_MM + WRIST_FADE_MM[0])..=12.0).contains(&a) {
                assert!(x.norm() < 1e-12, "level {a}: moved {}", x.norm());
            }
            // Nothing moves along the forearm.
            assert!(x.dot(&z).abs() < 1e-9);
        }
        assert_eq!(wrist_scales(&misses, &BTreeMap::new()), None);
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
