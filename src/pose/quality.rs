//! Measures of a posed hand that the issue asks for: finger-finger self-penetration of the skin
//! and the volume change of each finger segment (on the tetrahedral mesh).

use crate::anatomy::{Finger, Link};
use crate::geometry::closest_point::{AabbTree, PseudoNormals};
use crate::geometry::tet_mesh::{tet_signed_volume, TetGroups};
use crate::geometry::{Point, TriMesh};
use crate::template::{dominant_links, LinkWeights};
use std::collections::HashMap;

/// The link a mesh element belongs to: the largest entry of the sum of its `corners`' weights;
/// a tie goes to the lower link index.
fn dominant_of(corners: &[usize], weights: &LinkWeights) -> usize {
    let mut acc = [0.0; 17];
    for &v in corners {
        for &(l, w) in &weights[v] {
            if l < acc.len() {
                acc[l] += w;
            }
        }
    }
    (0..acc.len())
        .max_by(|&a, &b| acc[a].total_cmp(&acc[b]).then(b.cmp(&a)))
        .unwrap_or(0)
}

/// The link each face belongs to: the largest entry of the sum of its corners' weights.
pub(crate) fn face_links(mesh: &TriMesh, weights: &LinkWeights) -> Vec<usize> {
    mesh.faces.iter().map(|f| dominant_of(f, weights)).collect()
}

/// The digit a link belongs to for penetration checks: the phalanges of each digit (the thumb
/// metacarpal is the thenar eminence, part of the palm here).
pub(crate) fn digit_of(l: usize) -> Option<Finger> {
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
    finger_penetration_where_facing(posed, weights, max_depth_mm, &[])
}

/// The faces of `posed` (the skin `rest` in a pose whose links turn by `rotations`, over
/// [`Link::ALL`]) that skinning turned over: more than 90° from the rest face carried by its
/// dominant link, or degenerate ([`crate::skin::unfold::turned_over`]).
pub fn turned_over_faces(
    rest: &TriMesh,
    weights: &LinkWeights,
    rotations: &[nalgebra::UnitQuaternion<f64>],
    posed: &TriMesh,
) -> Vec<bool> {
    use crate::skin::unfold::{bone_carried_normals, turned_over};
    let guard = bone_carried_normals(rest, &dominant_links(weights), rotations);
    (0..posed.n_faces())
        .map(|f| turned_over(&guard[f], &posed.face_cross(f)))
        .collect()
}

/// [`finger_penetration_where_facing`] of `posed`, the skin of `hand` in `pose`, skipping the
/// faces that skinning turned over ([`turned_over_faces`]). This is the measure `pose` keeps
/// the digits apart by: a crease folded through itself reads as a penetration as deep as the
/// distance to the fold, which no change of the angles can remove, and the resolver then
/// chased it instead of the digits that do meet.
pub fn posed_finger_penetration(
    hand: &super::IndividualHand,
    pose: &crate::skeleton::Pose,
    posed: &TriMesh,
    max_depth_mm: f64,
) -> Penetration {
    let rotations: Vec<_> =
        crate::skeleton::forward_kinematics::link_transforms(&hand.skeleton, pose)
            .iter()
            .map(|t| t.rotation)
            .collect();
    let turned = turned_over_faces(&hand.skin, &hand.weights, &rotations, posed);
    finger_penetration_where_facing(posed, &hand.weights, max_depth_mm, &turned)
}

/// [`finger_penetration`] where the entered digit's surface faces the way its bone carries it:
/// a closest point on a face touching a vertex of a face in `turned` (e.g. from
/// [`turned_over_faces`]; empty: none) is skipped, as at the digit's rim, because the sign of a
/// surface folded through itself means nothing (a vertex just outside reads as deep inside).
pub fn finger_penetration_where_facing(
    posed: &TriMesh,
    weights: &LinkWeights,
    max_depth_mm: f64,
    turned: &[bool],
) -> Penetration {
    let mut unreliable = vec![false; posed.n_vertices()];
    for (f, _) in turned.iter().enumerate().filter(|(_, &t)| t) {
        for &u in &posed.faces[f] {
            unreliable[u] = true;
        }
    }
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
            if sub.faces[c.face].iter().any(|&u| rim[u] || unreliable[u]) {
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

/// The finger segment (link index over [`Link::ALL`]) each tetrahedron belongs to: the largest
/// entry of the sum of its four nodes' weights (`node_weights`, e.g. from
/// [`super::tet_node_weights`]); a tie goes to the lower link index. A segment is then a fixed set of tetrahedra, i.e. a fixed
/// piece of tissue, whatever the pose does to it.
pub fn tet_segments(tets: &[[usize; 4]], node_weights: &LinkWeights) -> Vec<usize> {
    tets.iter().map(|q| dominant_of(q, node_weights)).collect()
}
/// The finite-element groups of a tetrahedral mesh by link: one group per link of
/// [`Link::ALL`] (named by [`Link::name`], e.g. `I_PROX`; the id is the index), each
/// tetrahedron in its segment (`labels` from [`tet_segments`]) and each boundary face in its
/// tetrahedron's.
pub fn link_groups(
    mesh: &crate::tet::TetMesh,
    labels: &[usize],
) -> crate::error::Result<TetGroups> {
    TetGroups::new(
        mesh,
        Link::ALL.iter().map(|l| l.name().to_string()).collect(),
        labels.iter().map(|&l| l as u32).collect(),
    )
}

/// Where a tetrahedral mesh is inverted: per segment (`labels` from [`tet_segments`]), the
/// count of elements whose signed volume is not positive, as (link, count), most first.
pub fn inverted_by_link(
    nodes: &[Point],
    tets: &[[usize; 4]],
    labels: &[usize],
) -> Vec<(Link, usize)> {
    let mut count = vec![0usize; Link::ALL.len()];
    for (t, &l) in tets.iter().zip(labels) {
        let [a, b, c, d] = t.map(|i| nodes[i]);
        if tet_signed_volume(&a, &b, &c, &d) <= 0.0 {
            count[l] += 1;
        }
    }
    let mut out: Vec<(Link, usize)> = Link::ALL
        .iter()
        .zip(count)
        .filter(|e| e.1 > 0)
        .map(|(l, n)| (*l, n))
        .collect();
    out.sort_by_key(|e| std::cmp::Reverse(e.1));
    out
}

/// `inverted_by_link`'s result as "12 in PALM, 3 in I_MID" (the first four, then "...").
pub fn describe_by_link(by_link: &[(Link, usize)]) -> String {
    let mut s: Vec<String> = by_link
        .iter()
        .take(4)
        .map(|(l, n)| format!("{n} in {l}"))
        .collect();
    if by_link.len() > 4 {
        s.push("...".into());
    }
    s.join(", ")
}

/// Volume of each segment of a tetrahedral mesh with nodes `nodes`: the sum of the signed
/// volumes of its tetrahedra (`labels` from [`tet_segments`]), over `n_links` links. Being a
/// sum over the same tetrahedra in every pose, it measures the volume of the same tissue (a
/// Lagrangian measure): it is invariant under any rigid motion and changes exactly as the
/// skinning compresses or stretches that tissue, without the closing caps a surface measure of
/// an open piece of skin needs (a cone to the bone, say, whose cap changes with the joint angle
/// where the tissue does not: on the template in `fist` such a proxy read L_PROX +23 % where
/// the tissue lost 4 %).
pub fn segment_volumes(
    nodes: &[Point],
    tets: &[[usize; 4]],
    labels: &[usize],
    n_links: usize,
) -> Vec<f64> {
    let mut vol = vec![0.0; n_links];
    for (q, &l) in tets.iter().zip(labels) {
        vol[l] += crate::geometry::tet_mesh::tet_signed_volume(
            &nodes[q[0]],
            &nodes[q[1]],
            &nodes[q[2]],
            &nodes[q[3]],
        );
    }
    vol
}

/// Relative volume change (posed / rest − 1) of each finger segment (the 14 phalanges and the
/// thumb metacarpal) from [`segment_volumes`] at rest and posed, as (link, change).
pub fn finger_volume_changes(rest: &[f64], posed: &[f64]) -> Vec<(Link, f64)> {
    Link::ALL
        .iter()
        .filter(|l| is_finger_segment(l.index()))
        .filter(|l| rest[l.index()] > 0.0)
        .map(|&l| (l, posed[l.index()] / rest[l.index()] - 1.0))
        .collect()
}

/// Whether link `l` is a finger segment (a phalanx or the thumb metacarpal), the segments whose
/// volume is kept.
pub fn is_finger_segment(l: usize) -> bool {
    Link::ALL
        .get(l)
        .and_then(|l| l.joint())
        .and_then(|j| j.finger())
        .is_some()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::geometry::Vec3;
    use crate::template::load_template;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};

    /// Two unit cubes side by side, each cut into the six Kuhn tetrahedra, the nodes at x = 0
    /// and 1 weighted to link 1 and those at x = 2 to link 2.
    fn two_cubes() -> (Vec<Point>, Vec<[usize; 4]>, LinkWeights) {
        let mut nodes = Vec::new();
        for x in 0..3 {
            for y in 0..2 {
                for z in 0..2 {
                    nodes.push(Point::new(x as f64, y as f64, z as f64));
                }
            }
        }
        // Cube corner c has bit 0 for x, bit 1 for y, bit 2 for z.
        let id = |x: usize, c: u8| {
            (x + (c & 1) as usize) * 4 + ((c >> 1) & 1) as usize * 2 + ((c >> 2) & 1) as usize
        };
        let tets = (0..2)
            .flat_map(|x| {
                crate::geometry::marching_tetrahedra::kuhn_tetrahedra().map(|t| t.map(|c| id(x, c)))
            })
            .collect();
        let weights = nodes
            .iter()
            .map(|p| vec![(if p.x < 1.5 { 1 } else { 2 }, 1.0)])
            .collect();
        (nodes, tets, weights)
    }

    /// Segment volumes are the volumes of their tetrahedra (each Kuhn tetrahedron 1/6, all
    /// oriented positively). In the second cube a tetrahedron's chain from (1,0,0) to (2,1,1)
    /// steps in x first, second or third: only the two that step in x first have more nodes at
    /// x = 2, and a tie goes to the lower link, so link 1 has 6 + 4 tetrahedra (10/6) and link 2
    /// has 2 (2/6). A rigid motion keeps the volumes, a uniform scaling by `s` multiplies them
    /// by `s³`. In the reference posture no digit is inside another.
    #[test]
    fn segment_volumes_are_lagrangian_and_rest_has_no_penetration() {
        let (nodes, tets, weights) = two_cubes();
        let labels = tet_segments(&tets, &weights);
        let v0 = segment_volumes(&nodes, &tets, &labels, 3);
        assert!((v0[1] - 10.0 / 6.0).abs() < 1e-12, "{v0:?}");
        assert!((v0[2] - 2.0 / 6.0).abs() < 1e-12, "{v0:?}");
        let iso = Isometry3::from_parts(
            Translation3::new(10.0, -20.0, 5.0),
            UnitQuaternion::from_axis_angle(&Vector3::y_axis(), 0.7),
        );
        let moved: Vec<Point> = nodes.iter().map(|p| iso * p).collect();
        let scaled: Vec<Point> = nodes.iter().map(|p| Point::from(p.coords * 1.3)).collect();
        let vm = segment_volumes(&moved, &tets, &labels, 3);
        let vs = segment_volumes(&scaled, &tets, &labels, 3);
        for l in 1..3 {
            assert!((vm[l] - v0[l]).abs() < 1e-12, "{vm:?}");
            assert!((vs[l] / v0[l] - 1.3f64.powi(3)).abs() < 1e-12, "{vs:?}");
        }
        let t = load_template(Side::Right).unwrap();
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

    /// A patch of the index finger turned over in place (its vertices mirrored through a plane
    /// that holds the surface normal, which keeps them where they are and reverses every face
    /// there, as a crease that skinning folds through itself does) and a middle-finger vertex
    /// 1 mm outside it: the plain measure reads middle-finger vertices as inside the index,
    /// because the folded faces' normals point into the finger; the measure that skips
    /// turned-over faces (found from the rest skin) does not. A real penetration (the middle
    /// finger pushed into the index) reads about the same with both.
    #[test]
    fn a_surface_turned_over_in_place_is_no_penetration() {
        let t = load_template(Side::Right).unwrap();
        let dom = dominant_links(&t.weights);
        let normals = t.mesh.vertex_normals();
        let index_mid = Link::IMid.index();
        let toward = (t.skeleton.centre(crate::anatomy::Joint::MPip)
            - t.skeleton.centre(crate::anatomy::Joint::IPip))
        .normalize();
        let q = (0..t.mesh.n_vertices())
            .filter(|&v| dom[v] == index_mid)
            .max_by(|&a, &b| normals[a].dot(&toward).total_cmp(&normals[b].dot(&toward)))
            .unwrap();
        let (qp, n) = (t.mesh.vertices[q], normals[q].normalize());
        let b = n
            .cross(&toward)
            .try_normalize(1e-9)
            .unwrap_or_else(|| n.cross(&Vec3::z()).normalize());
        let patch: Vec<usize> = (0..t.mesh.n_vertices())
            .filter(|&v| dom[v] == index_mid && (t.mesh.vertices[v] - qp).norm() < 3.0)
            .collect();
        let mut folded = t.mesh.clone();
        for &v in &patch {
            let p = folded.vertices[v];
            folded.vertices[v] = p - b * (2.0 * (p - qp).dot(&b));
        }
        // The middle finger's vertex nearest that point, moved there (a short move: the
        // fingers lie side by side).
        let target = qp + n * 1.0;
        let middle = [Link::MProx, Link::MMid, Link::MDist].map(|l| l.index());
        let outside = (0..t.mesh.n_vertices())
            .filter(|&v| middle.contains(&dom[v]))
            .min_by(|&a, &b| {
                let d = |v: usize| (t.mesh.vertices[v] - target).norm();
                d(a).total_cmp(&d(b))
            })
            .unwrap();
        folded.vertices[outside] = target;
        let rotations = vec![nalgebra::UnitQuaternion::identity(); Link::ALL.len()];
        let turned = turned_over_faces(&t.mesh, &t.weights, &rotations, &folded);
        let n_turned = turned.iter().filter(|&&x| x).count();
        assert!(n_turned >= 4, "{n_turned} faces turned");
        let middle_in_index = |p: &Penetration| {
            p.by_pair
                .iter()
                .find(|((a, b), _)| (*a, *b) == (Finger::Middle, Finger::Index))
                .map(|(_, d)| *d)
        };
        let plain = finger_penetration(&folded, &t.weights, 12.0);
        // Read inside, and deeper than the vertex moved there: the folded faces' normals make
        // the middle finger's vertices facing them read as inside by their whole distance.
        let depth = middle_in_index(&plain).expect("the plain measure reads it inside");
        assert!(depth > 1.0, "{plain:?}");
        let facing = finger_penetration_where_facing(&folded, &t.weights, 12.0, &turned);
        assert!(
            middle_in_index(&facing).is_none_or(|d| d < 0.5),
            "{facing:?}"
        );

        let shift = t.skeleton.centre(crate::anatomy::Joint::IMcp)
            - t.skeleton.centre(crate::anatomy::Joint::MMcp);
        let mut pushed = t.mesh.clone();
        for (v, p) in pushed.vertices.iter_mut().enumerate() {
            if middle.contains(&dom[v]) {
                *p += shift * 0.6;
            }
        }
        // Only the faces the push tears at the finger's base turn over.
        let turned = turned_over_faces(&t.mesh, &t.weights, &rotations, &pushed);
        assert!(turned.iter().filter(|&&x| x).count() < t.mesh.n_faces() / 100);
        let plain = finger_penetration(&pushed, &t.weights, 12.0);
        let facing = finger_penetration_where_facing(&pushed, &t.weights, 12.0, &turned);
        assert!(plain.depth_mm > 2.0, "{plain:?}");
        assert!(
            (facing.depth_mm - plain.depth_mm).abs() < 0.5,
            "{plain:?} {facing:?}"
        );
        assert!(facing.by_pair.iter().all(|((a, b), _)| matches!(
            (a, b),
            (Finger::Middle, Finger::Index) | (Finger::Index, Finger::Middle)
        )));
    }
}
