//! Measures of a posed skin that the issue asks for: finger-finger self-penetration and the
//! volume change of each finger segment.

use crate::anatomy::{Finger, Link};
use crate::geometry::closest_point::{AabbTree, PseudoNormals};
use crate::geometry::{Point, TriMesh};
use crate::skeleton::Skeleton;
use crate::template::{dominant_links, LinkWeights};
use nalgebra::Isometry3;
use std::collections::HashMap;

/// The link each face belongs to: the largest entry of the sum of its corners' weights.
pub fn face_links(mesh: &TriMesh, weights: &LinkWeights) -> Vec<usize> {
    mesh.faces
        .iter()
        .map(|f| {
            let mut acc = [0.0; 17];
            for &v in f {
                for &(l, w) in &weights[v] {
                    if l < acc.len() {
                        acc[l] += w;
                    }
                }
            }
            (0..acc.len())
                .max_by(|&a, &b| acc[a].total_cmp(&acc[b]).then(b.cmp(&a)))
                .unwrap_or(0)
        })
        .collect()
}

/// The digit a link belongs to for penetration checks: the phalanges of each digit (the thumb
/// metacarpal is the thenar eminence, part of the palm here).
fn digit_of(l: usize) -> Option<Finger> {
    let link = *Link::ALL.get(l)?;
    if link == Link::TMeta {
        return None;
    }
    link.joint().and_then(|j| j.finger())
}

/// Deepest finger-finger penetration of a posed skin.
#[derive(Clone, Debug, PartialEq)]
pub struct Penetration {
    /// Depth, mm (0 when no digit enters another).
    pub depth_mm: f64,
    /// The digit whose vertex is deepest inside, and the digit it is inside of.
    pub pair: Option<(Finger, Finger)>,
    /// Vertices of one digit found inside another.
    pub n_vertices: usize,
    /// Deepest penetration per (inside digit, entered digit) pair that has any, mm.
    pub by_pair: Vec<((Finger, Finger), f64)>,
    /// Per entry of `by_pair`, where its deepest vertex is.
    pub deepest: Vec<PenetrationPoint>,
}

/// The deepest vertex of one digit inside another.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PenetrationPoint {
    /// The vertex inside.
    pub vertex: usize,
    /// Its closest point on the entered digit's surface.
    pub surface_point: Point,
    /// The entered digit's outward (pseudo-)normal there.
    pub normal: nalgebra::Vector3<f64>,
    /// The link (index over [`Link::ALL`]) of the entered digit's face there.
    pub surface_link: usize,
}

/// Finger-finger self-penetration of `posed` (a skin with `weights`, vertex order and faces of
/// the rest skin): each digit's surface (the faces of its phalanges, [`face_links`]) is taken
/// alone, and every vertex of another digit that lies behind it (signed distance by the
/// angle-weighted pseudo-normal of the closest feature, Bærentzen & Aanæs 2005) counts with
/// that distance as its depth. Closest points on a face touching the digit's open rim (its
/// base, where it joins the palm) are skipped: there the sign of an open surface means nothing.
/// Depths beyond `max_depth_mm` are not penetrations but the far side of the finger (a vertex
/// cannot be deeper inside a finger than its radius).
pub fn finger_penetration(
    posed: &TriMesh,
    weights: &LinkWeights,
    max_depth_mm: f64,
) -> Penetration {
    let dom = dominant_links(weights);
    let fl = face_links(posed, weights);
    let mut best = Penetration {
        depth_mm: 0.0,
        pair: None,
        n_vertices: 0,
        by_pair: Vec::new(),
        deepest: Vec::new(),
    };
    for b in Finger::ALL {
        let (faces, sub_links): (Vec<[usize; 3]>, Vec<usize>) = posed
            .faces
            .iter()
            .zip(&fl)
            .filter(|(_, &l)| digit_of(l) == Some(b))
            .map(|(f, &l)| (*f, l))
            .unzip();
        if faces.is_empty() {
            continue;
        }
        let sub = TriMesh {
            vertices: posed.vertices.clone(),
            faces,
        };
        // Rim: vertices of edges used by one face only.
        let mut edges: HashMap<(usize, usize), u32> = HashMap::new();
        for f in &sub.faces {
            for k in 0..3 {
                let (x, y) = (f[k], f[(k + 1) % 3]);
                *edges.entry((x.min(y), x.max(y))).or_default() += 1;
            }
        }
        let mut rim = vec![false; sub.n_vertices()];
        for (&(x, y), &n) in &edges {
            if n == 1 {
                rim[x] = true;
                rim[y] = true;
            }
        }
        let normals = PseudoNormals::new(&sub);
        let tree = AabbTree::new(&sub);
        for (v, p) in posed.vertices.iter().enumerate() {
            let a = match digit_of(dom[v]) {
                Some(a) if a != b => a,
                _ => continue,
            };
            let Some(c) = tree.closest_point(p) else {
                continue;
            };
            if !c.distance.is_finite() || c.distance > max_depth_mm {
                continue;
            }
            if sub.faces[c.face].iter().any(|&u| rim[u]) {
                continue;
            }
            let n = normals.of(&sub, c.face, c.feature);
            if (p - c.point).dot(&n) < 0.0 {
                best.n_vertices += 1;
                let here = PenetrationPoint {
                    vertex: v,
                    surface_point: c.point,
                    normal: n,
                    surface_link: sub_links[c.face],
                };
                match best.by_pair.iter().position(|x| x.0 == (a, b)) {
                    Some(k) if best.by_pair[k].1 < c.distance => {
                        best.by_pair[k].1 = c.distance;
                        best.deepest[k] = here;
                    }
                    Some(_) => {}
                    None => {
                        best.by_pair.push(((a, b), c.distance));
                        best.deepest.push(here);
                    }
                }
                if c.distance > best.depth_mm {
                    best.depth_mm = c.distance;
                    best.pair = Some((a, b));
                }
            }
        }
    }
    best
}

/// Volume of each link's segment of a skin: the faces of the link ([`face_links`]) closed by
/// cones to an interior point `o` (the midpoint of the link's bone, moved by the link's
/// transform), `Σ (a−o)·((b−o)×(c−o)) / 6`. Cone triangles through `o` add no volume, so this is
/// exactly the volume of the segment's surface region closed by fans to `o`; it is invariant
/// under a rigid motion of the segment and changes only as its skin deforms. Indexed by
/// [`Link::ALL`]; 0 for links without faces.
pub fn segment_volumes(
    mesh: &TriMesh,
    face_link: &[usize],
    sk: &Skeleton,
    transforms: &[Isometry3<f64>],
) -> Vec<f64> {
    let mut vol = vec![0.0; Link::ALL.len()];
    let centre: Vec<Point> = Link::ALL
        .iter()
        .map(|l| match l.joint() {
            Some(j) => {
                let c = sk.centre(j);
                transforms[l.index()] * (c + (sk.distal_end(j) - c) * 0.5)
            }
            None => transforms[l.index()] * sk.centre(crate::anatomy::Joint::Wrist),
        })
        .collect();
    for (f, &l) in mesh.faces.iter().zip(face_link) {
        let o = centre[l];
        let [a, b, c] = f.map(|i| mesh.vertices[i] - o);
        vol[l] += a.dot(&b.cross(&c)) / 6.0;
    }
    vol
}

/// Relative volume change (posed / rest − 1) of each finger segment (the 14 phalanges and the
/// thumb metacarpal), as (link, change); see [`segment_volumes`].
pub fn finger_volume_changes(
    rest: &TriMesh,
    posed: &TriMesh,
    weights: &LinkWeights,
    sk: &Skeleton,
    transforms: &[Isometry3<f64>],
) -> Vec<(Link, f64)> {
    let fl = face_links(rest, weights);
    let id = vec![Isometry3::identity(); Link::ALL.len()];
    let v0 = segment_volumes(rest, &fl, sk, &id);
    let v1 = segment_volumes(posed, &fl, sk, transforms);
    Link::ALL
        .iter()
        .filter(|l| l.joint().and_then(|j| j.finger()).is_some())
        .filter(|l| v0[l.index()] > 0.0)
        .map(|&l| (l, v1[l.index()] / v0[l.index()] - 1.0))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::skeleton::forward_kinematics::link_transforms;
    use crate::skeleton::Pose;
    use crate::template::load_template;
    use nalgebra::{Translation3, UnitQuaternion, Vector3};

    /// A rigid motion of the whole hand changes no segment volume, and in the reference
    /// posture no digit is inside another.
    #[test]
    fn rigid_motion_keeps_volumes_and_rest_has_no_penetration() {
        let t = load_template(Side::Right).unwrap();
        let iso = Isometry3::from_parts(
            Translation3::new(10.0, -20.0, 5.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.7),
        );
        let pose = Pose {
            root: iso,
            ..Pose::zero()
        };
        let tr = link_transforms(&t.skeleton, &pose);
        let moved = t.mesh.transformed(&iso);
        for (l, c) in finger_volume_changes(&t.mesh, &moved, &t.weights, &t.skeleton, &tr) {
            assert!(c.abs() < 1e-9, "{l}: {c}");
        }
        let p = finger_penetration(&t.mesh, &t.weights, 12.0);
        assert!(p.depth_mm < 0.5, "{p:?}");
    }

    /// A digit pushed sideways into its neighbour is found, with a depth of the order of the
    /// push beyond the gap between them.
    #[test]
    fn a_finger_pushed_into_its_neighbour_is_found() {
        let t = load_template(Side::Right).unwrap();
        let dom = dominant_links(&t.weights);
        let middle = [Link::MProx, Link::MMid, Link::MDist].map(|l| l.index());
        // Push the middle finger toward the index by the spacing of their MCPs: it then lies
        // about where the index finger is.
        let shift = t.skeleton.centre(crate::anatomy::Joint::IMcp)
            - t.skeleton.centre(crate::anatomy::Joint::MMcp);
        let mut moved = t.mesh.clone();
        for (v, p) in moved.vertices.iter_mut().enumerate() {
            if middle.contains(&dom[v]) {
                *p += shift * 0.6;
            }
        }
        let pen = finger_penetration(&moved, &t.weights, 12.0);
        eprintln!("{pen:?}");
        assert!(pen.depth_mm > 2.0, "{pen:?}");
        assert!(
            pen.by_pair.iter().all(|((a, b), _)| {
                matches!(
                    (a, b),
                    (Finger::Middle, Finger::Index) | (Finger::Index, Finger::Middle)
                )
            }),
            "{pen:?}"
        );
    }
}
