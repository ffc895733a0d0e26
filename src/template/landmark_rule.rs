//! The reproducible rule that picks the template's landmark vertices and dimension vertex pairs
//! (spec section 2; seed paper section 3.3 step 6 and Table 1).
//!
//! Two geometric primitives, both evaluated on the high-resolution template:
//! * **dorsal ray**: cast a ray from a point inside the hand (a joint centre, or a point along a
//!   bone) along a direction; the landmark is the vertex of the first face hit that is nearest
//!   to the hit point. Used for the markers a lab puts on the back of a joint, on a nail or on a
//!   bone (the joint markers, `PALM_*`, `*_NAIL`, `T_MC_*`), and along the distal phalanx's
//!   long axis for the optional fingertip markers (`*_TIP`).
//! * **caliper extreme**: among the vertices in a thin slab through a point, perpendicular to the
//!   link, and within a radius of it, the one furthest along a direction. A caliper's jaws touch
//!   exactly these extremes, so each dimension is the pair of opposite extremes (`*_breadth_*`
//!   along the joint's x axis, `*_thickness_*` along its dorsal y axis), and the lateral
//!   landmarks (`I_MCP_LAT`, `L_MCP_LAT`, `WRIST_RAD`, `WRIST_ULN`) are the extremes the
//!   dimensions `hand_breadth_diagonal` and `wrist_breadth` are measured between.
//!
//! Placement fractions along bones are given with each landmark below.

use super::spec::{HandSpec, SPEC_VERSION};
use crate::anatomy::{Dimension, Finger, Joint, Side};
use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::skeleton::Skeleton;
use std::collections::BTreeMap;

/// Half-thickness of the slab of a caliper extreme, mm: wide enough to hold vertices of the
/// subdivided template (median edge about 1.6 mm), thin enough to stay at the joint.
pub(crate) const SLAB_HALF_MM: f64 = 1.5;

/// Where a nail marker sits along the distal segment, as a share of the way from the distal
/// joint's centre to the fingertip's apex: the middle of the nail plate, which covers the
/// distal half to two thirds of the segment's back and ends a few millimetres short of the
/// apex (README, "The template hand").
pub(crate) const NAIL_FRACTION: f64 = 0.5;

/// First intersection of the ray `origin + t·dir` (t > 0) with the mesh (Möller & Trumbore
/// 1997); returns the face and the hit point.
pub fn ray_hit(mesh: &TriMesh, origin: &Point, dir: &Vec3) -> Option<(usize, Point)> {
    let mut best: Option<(f64, usize)> = None;
    for f in 0..mesh.n_faces() {
        let [a, b, c] = mesh.corners(f);
        let (e1, e2) = (b - a, c - a);
        let p = dir.cross(&e2);
        let det = e1.dot(&p);
        if det.abs() < 1e-14 {
            continue;
        }
        let inv = 1.0 / det;
        let s = origin - a;
        let u = s.dot(&p) * inv;
        if !(0.0..=1.0).contains(&u) {
            continue;
        }
        let q = s.cross(&e1);
        let v = dir.dot(&q) * inv;
        if v < 0.0 || u + v > 1.0 {
            continue;
        }
        let t = e2.dot(&q) * inv;
        if t > 1e-9 && best.is_none_or(|(bt, _)| t < bt) {
            best = Some((t, f));
        }
    }
    best.map(|(t, f)| (f, origin + dir * t))
}

/// The landmark vertex of a dorsal ray (see the module doc).
pub(crate) fn ray_vertex(mesh: &TriMesh, origin: &Point, dir: &Vec3) -> Option<usize> {
    let (f, hit) = ray_hit(mesh, origin, &dir.normalize())?;
    Some(nearest_corner(mesh, f, &hit))
}

/// The corner of face `f` nearest to `p`.
fn nearest_corner(mesh: &TriMesh, f: usize, p: &Point) -> usize {
    let distance = |v: usize| (mesh.vertices[v] - p).norm();
    let [a, b, c] = mesh.faces[f];
    [b, c].into_iter().fold(a, |best, v| {
        if distance(v) < distance(best) {
            v
        } else {
            best
        }
    })
}

/// The caliper extreme (see the module doc): the vertex within `radius` of `centre`, at most
/// [`SLAB_HALF_MM`] from the plane through `centre` normal to `normal`, for which `keep` holds
/// (so a neighbouring finger inside the radius is not measured), furthest along `dir`.
pub fn caliper_extreme(
    mesh: &TriMesh,
    centre: &Point,
    normal: &Vec3,
    radius: f64,
    dir: &Vec3,
    keep: &dyn Fn(usize) -> bool,
) -> Option<usize> {
    let n = normal.normalize();
    let d = dir.normalize();
    mesh.vertices
        .iter()
        .enumerate()
        .filter(|(i, p)| {
            let r = *p - centre;
            r.dot(&n).abs() <= SLAB_HALF_MM && r.norm() <= radius && keep(*i)
        })
        .max_by(|(_, p), (_, q)| (*p - centre).dot(&d).total_cmp(&(*q - centre).dot(&d)))
        .map(|(i, _)| i)
}

/// Radius (mm) of the neighbourhood a caliper extreme may come from: a finger is at most about
/// 12 mm in radius, the palm at the 3rd metacarpal head 20 mm thick, the wrist 45 mm wide.
fn caliper_radius(j: Joint) -> f64 {
    match j {
        Joint::Wrist => 45.0,
        _ => 14.0,
    }
}

/// Derive the whole spec of one template hand by the rule of this module. `owner` is the link
/// (index into [`Link::ALL`]) that dominates each vertex's skin weights: a caliper at a joint
/// only touches vertices of the two links the joint connects.
pub fn derive_hand_spec(
    mesh: &TriMesh,
    sk: &Skeleton,
    side: Side,
    owner: &[usize],
    metacarpal_bases: &[Point; 4],
) -> Result<HandSpec> {
    let at = |j: Joint| {
        let (a, b) = (j.parent_link().index(), j.child_link().index());
        move |v: usize| owner[v] == a || owner[v] == b
    };
    let err = |what: &str| Error::invalid(format!("template landmark rule: no vertex for {what}"));
    let mut landmarks: BTreeMap<String, usize> = BTreeMap::new();
    let palm_dorsal = sk.joint(Joint::Wrist).y();
    let mut put = |name: &str, v: Option<usize>| -> Result<()> {
        landmarks.insert(name.to_string(), v.ok_or_else(|| err(name))?);
        Ok(())
    };

    // Joint markers: over the dorsal side of every joint.
    for j in Joint::ALL {
        let jf = sk.joint(j);
        put(j.name(), ray_vertex(mesh, &jf.centre, &jf.y()))?;
    }
    // Palm markers over the heads (20 % of the way from the MCP to the metacarpal's base) and
    // the bases (85 %) of the 2nd and 5th metacarpals, cast along the palm's dorsal normal.
    let palm_long = sk.joint(Joint::Wrist).z();
    for (name, mcp, base, t) in [
        ("PALM_1", Joint::IMcp, metacarpal_bases[0], 0.2),
        ("PALM_2", Joint::LMcp, metacarpal_bases[3], 0.2),
        ("PALM_3", Joint::IMcp, metacarpal_bases[0], 0.85),
        ("PALM_4", Joint::LMcp, metacarpal_bases[3], 0.85),
    ] {
        let origin = sk.centre(mcp) + (base - sk.centre(mcp)) * t;
        put(name, ray_vertex(mesh, &origin, &palm_dorsal))?;
    }
    // Per digit, where the distal phalanx's long axis, from the distal joint's centre through
    // the skeleton's tip, leaves the skin: the optional fingertip marker's place, and the far
    // end of the segment a nail marker is placed along. The nail: the middle of the nail plate,
    // over the dorsal side at NAIL_FRACTION of the way from the joint to that apex. The
    // skeleton's tip is no measure of the segment: a template's tip joint may stand anywhere
    // inside the pulp (the generic hand's about halfway to the apex).
    for f in Finger::ALL {
        let dj = f.joints()[2];
        let c = sk.centre(dj);
        let (face, apex) = ray_hit(mesh, &c, &(sk.tips[f as usize] - c).normalize())
            .ok_or_else(|| err(f.tip_marker()))?;
        put(f.tip_marker(), Some(nearest_corner(mesh, face, &apex)))?;
        let origin = c + (apex - c) * NAIL_FRACTION;
        put(
            f.nail_marker(),
            ray_vertex(mesh, &origin, &sk.joint(dj).y()),
        )?;
    }
    // Two markers on the thumb metacarpal, at 1/3 and 2/3 of it, dorsal.
    let (cmc, mcp) = (sk.centre(Joint::TCmc), sk.centre(Joint::TMcp));
    for (k, t) in [(1, 1.0 / 3.0), (2, 2.0 / 3.0)] {
        let origin = cmc + (mcp - cmc) * t;
        put(
            &format!("T_MC_{k}"),
            ray_vertex(mesh, &origin, &sk.joint(Joint::TCmc).y()),
        )?;
    }
    // Laterals: the caliper extremes of the hand breadth and of the wrist breadth.
    let radial_dir = {
        let r = sk.centre(Joint::IMcp) - sk.centre(Joint::LMcp);
        (r - palm_dorsal * r.dot(&palm_dorsal)).normalize()
    };
    let wrist = sk.joint(Joint::Wrist);
    let wrist_radial = (radial_dir - wrist.z() * radial_dir.dot(&wrist.z())).normalize();
    for (name, j, dir, radius) in [
        ("I_MCP_LAT", Joint::IMcp, radial_dir, 14.0),
        ("L_MCP_LAT", Joint::LMcp, -radial_dir, 14.0),
        ("WRIST_RAD", Joint::Wrist, wrist_radial, 45.0),
        ("WRIST_ULN", Joint::Wrist, -wrist_radial, 45.0),
    ] {
        let jf = sk.joint(j);
        put(
            name,
            caliper_extreme(mesh, &jf.centre, &jf.z(), radius, &dir, &at(j)),
        )?;
    }

    // Dimensions: pairs of opposite caliper extremes.
    let mut dimensions: BTreeMap<String, [usize; 2]> = BTreeMap::new();
    for d in Dimension::all() {
        let pair = match d {
            Dimension::WristBreadth => [landmarks["WRIST_RAD"], landmarks["WRIST_ULN"]],
            Dimension::HandBreadthDiagonal => [landmarks["I_MCP_LAT"], landmarks["L_MCP_LAT"]],
            Dimension::WristThickness => extremes(mesh, sk, Joint::Wrist, &palm_dorsal, &at)?,
            Dimension::HandThicknessMc3 => {
                // Across the palm at the 3rd metacarpal head: the slab is normal to the palm's
                // long axis, so it cuts the palm rather than the proximal phalanx.
                let c = sk.centre(Joint::MMcp);
                let keep = at(Joint::MMcp);
                let hi = caliper_extreme(mesh, &c, &palm_long, 22.0, &palm_dorsal, &keep);
                let lo = caliper_extreme(mesh, &c, &palm_long, 22.0, &-palm_dorsal, &keep);
                [
                    hi.ok_or_else(|| err(&d.name()))?,
                    lo.ok_or_else(|| err(&d.name()))?,
                ]
            }
            Dimension::BreadthProximal(f) | Dimension::BreadthDistal(f) => {
                let j = dimension_joint(d, f);
                extremes(mesh, sk, j, &sk.joint(j).x(), &at)?
            }
            Dimension::ThicknessProximal(f) | Dimension::ThicknessDistal(f) => {
                let j = dimension_joint(d, f);
                extremes(mesh, sk, j, &sk.joint(j).y(), &at)?
            }
        };
        dimensions.insert(d.name(), pair);
    }

    let palm = ["PALM_1", "PALM_2", "PALM_3", "PALM_4"].map(|n| landmarks[n]);
    let joint_centres = Joint::ALL
        .iter()
        .map(|&j| (j.name().to_string(), sk.centre(j).coords.into()))
        .collect();
    Ok(HandSpec {
        version: SPEC_VERSION,
        side,
        vertices: mesh.n_vertices(),
        faces: mesh.n_faces(),
        landmarks,
        palm,
        dimensions,
        joint_centres,
    })
}

/// The joint a finger dimension is measured at: PIP (thumb: IP) for proximal, DIP for distal.
pub(crate) fn dimension_joint(d: Dimension, f: Finger) -> Joint {
    match d {
        Dimension::BreadthDistal(_) | Dimension::ThicknessDistal(_) => f.joints()[2],
        _ if f == Finger::Thumb => Joint::TIp,
        _ => f.joints()[1],
    }
}

/// The two vertices at the edges of the digit at a 1-DOF joint `j`: the caliper extremes along
/// its rotation axis (the breadth pair of the dimensions where one is measured there). The seed
/// paper's section 3.6 moves the joint centre onto the axis point nearest to them.
pub fn joint_edge_pair(
    mesh: &TriMesh,
    sk: &Skeleton,
    owner: &[usize],
    j: Joint,
) -> Result<[usize; 2]> {
    let at = |j: Joint| {
        let (a, b) = (j.parent_link().index(), j.child_link().index());
        move |v: usize| owner[v] == a || owner[v] == b
    };
    extremes(mesh, sk, j, &sk.joint(j).x(), &at)
}

/// Opposite caliper extremes at joint `j` along `dir`, in the slab normal to the joint's link.
fn extremes<K: Fn(usize) -> bool>(
    mesh: &TriMesh,
    sk: &Skeleton,
    j: Joint,
    dir: &Vec3,
    at: &dyn Fn(Joint) -> K,
) -> Result<[usize; 2]> {
    let jf = sk.joint(j);
    let r = caliper_radius(j);
    let keep = at(j);
    let a = caliper_extreme(mesh, &jf.centre, &jf.z(), r, dir, &keep);
    let b = caliper_extreme(mesh, &jf.centre, &jf.z(), r, &-dir, &keep);
    match (a, b) {
        (Some(a), Some(b)) if a != b => Ok([a, b]),
        _ => Err(Error::invalid(format!(
            "template landmark rule: no caliper pair at joint {j}"
        ))),
    }
}
