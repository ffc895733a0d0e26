//! The 22 caliper dimensions of the seed paper's Table 1, measured on a closed skin surface the
//! way the subject-format spec (section 1, "What each dimension measures") defines them.
//!
//! A caliper's jaws are perpendicular to the direction named, so a reading is the extent of the
//! surface's cross-section along that direction: the distance between the two jaw planes that
//! touch the section. The section is cut by [`crate::geometry::plane_section`]; the extent of a
//! polygon along a direction is that of its vertices (the convex hull's support), which the
//! jaws meet.
//!
//! Definitions and their sources:
//! - **Finger breadth and thickness** (`fingerN_{breadth,thickness}_{proximal,distal}`),
//!   Garrett 1971 ("The adult human hand", Hum. Factors 13(2): breadth and depth of each finger
//!   at its interphalangeal joints) and the seed paper's Table 1: at the PIP joint (thumb: IP)
//!   for `_proximal`, the DIP for `_distal`. The section plane goes through the joint centre,
//!   normal to the finger's long axis there, taken as the bisector of the directions of the two
//!   links meeting at the joint (from the neighbouring joint centres, or the fingertip for the
//!   last joint). Only the section loop enclosing the joint centre counts, so a neighbouring
//!   finger cut by the same plane does not. Breadth is the extent along the joint's flexion axis
//!   (its frame's x, projected into the plane: radial-ulnar), thickness along the perpendicular
//!   in-plane direction (dorsal-palmar).
//! - **Wrist breadth and thickness**, ISO 7250-1 / Garrett 1971: the forearm's section at the
//!   level of the styloids: the plane through the midpoint of the `WRIST_RAD` and `WRIST_ULN`
//!   landmarks, normal to the forearm axis (the wrist frame's z in the reference posture), the
//!   loop enclosing that midpoint; breadth along the styloid direction projected into the plane,
//!   thickness perpendicular to it in the plane.
//! - **Hand breadth, diagonal** (ISO 7250-1's hand breadth at the metacarpals, "metacarpale
//!   radiale to metacarpale ulnare"): the extent along the line from `I_MCP_LAT` to `L_MCP_LAT`
//!   of the palm's section by the plane holding that line and the palm's dorsal-palmar direction
//!   (the wrist frame's y), restricted to the loop holding the head of the third metacarpal
//!   (the `M_MCP` centre, projected into the plane). Where the thumb joins that loop (one of its
//!   bones crosses the plane inside it) only the part of the loop within
//!   [`BREADTH_BAND_MM`] of the landmarks' dorsal-palmar level counts: the first web space and
//!   the thumb lie palmar to the metacarpal heads, and the caliper's jaws rest on the heads.
//! - **Hand thickness at the 3rd metacarpal head** (Garrett 1971, "hand thickness at
//!   metacarpale III"): the plane through the `M_MCP` centre normal to the palm's long axis
//!   (wrist centre to `M_MCP` centre); the extent along the palm's dorsal-palmar direction of
//!   the part of that section's loop (the one enclosing the MC3 head) that lies within a
//!   caliper jaw's half-width, [`JAW_HALF_WIDTH_MM`], of the MC3 head along the radial-ulnar
//!   direction.

use crate::anatomy::{Dimension, Finger, Joint};
use crate::geometry::{plane_section, Plane, Point, SectionLoop, TriMesh, Vec3};
use crate::skeleton::Skeleton;
use std::collections::BTreeMap;

/// A measurement, or why it cannot be taken (a missing landmark, a section that does not
/// enclose the joint, ...).
pub type Measured = std::result::Result<f64, String>;

/// Half-width of a caliper jaw resting on the 3rd metacarpal head, mm (a sliding caliper's jaw
/// is about 10 mm wide).
pub(crate) const JAW_HALF_WIDTH_MM: f64 = 5.0;

/// Half-height of the band about the metacarpal landmarks' dorsal-palmar level kept for the
/// diagonal hand breadth when the thumb joins the palm's section, mm.
pub(crate) const BREADTH_BAND_MM: f64 = 5.0;

/// Every dimension of `skin` (a closed surface, mm) with the joints of `skeleton` and the
/// landmark skin points `landmarks` (spec names -> points on the skin: `WRIST_RAD`,
/// `WRIST_ULN`, `I_MCP_LAT`, `L_MCP_LAT` are read). All 22, each a value or the reason it
/// could not be measured. See the module documentation for the definitions.
pub fn measure_dimensions(
    skin: &TriMesh,
    skeleton: &Skeleton,
    landmarks: &BTreeMap<String, Point>,
) -> BTreeMap<Dimension, Measured> {
    let mut out = BTreeMap::new();
    let pair = |out: &mut BTreeMap<Dimension, Measured>,
                r: std::result::Result<(f64, f64), String>,
                b: Dimension,
                t: Dimension| {
        out.insert(b, r.clone().map(|x| x.0));
        out.insert(t, r.map(|x| x.1));
    };
    pair(
        &mut out,
        wrist_section(skin, skeleton, landmarks),
        Dimension::WristBreadth,
        Dimension::WristThickness,
    );
    out.insert(
        Dimension::HandBreadthDiagonal,
        hand_breadth_diagonal(skin, skeleton, landmarks),
    );
    out.insert(
        Dimension::HandThicknessMc3,
        hand_thickness_mc3(skin, skeleton),
    );
    for f in Finger::ALL {
        let mut sections = vec![(
            Dimension::BreadthProximal(f),
            Dimension::ThicknessProximal(f),
        )];
        if f != Finger::Thumb {
            sections.push((Dimension::BreadthDistal(f), Dimension::ThicknessDistal(f)));
        }
        for (breadth, thickness) in sections {
            let j = breadth.section_joint().expect("a finger dimension");
            pair(
                &mut out,
                finger_joint_section(skin, skeleton, j),
                breadth,
                thickness,
            );
        }
    }
    out
}

/// The closed loop of `loops` that encloses `q` (projected into `plane`); the innermost one
/// (smallest area) when several do.
pub(crate) fn enclosing_loop<'a>(
    loops: &'a [SectionLoop],
    plane: &Plane,
    q: &Point,
) -> Option<&'a SectionLoop> {
    loops
        .iter()
        .filter(|l| l.winding_number(plane, q) != 0)
        .min_by(|a, b| {
            let area = |l: &SectionLoop| l.signed_area(&plane.normal).abs();
            area(a).total_cmp(&area(b))
        })
}

/// Extent of a closed loop along `along`: `max − min` of `along · (p − origin)` over the loop,
/// optionally only over the part with `slab.0 · (p − origin)` within `[slab.1, slab.2]`
/// (segments are clipped at the slab's faces, so the clipped ends count). `None` when nothing
/// of the loop lies in the slab.
pub(crate) fn loop_extent(
    l: &SectionLoop,
    origin: &Point,
    along: &Vec3,
    slab: Option<(&Vec3, f64, f64)>,
) -> Option<f64> {
    let half_spaces: Vec<(Vec3, f64)> = match slab {
        None => Vec::new(),
        Some((dir, a, b)) => vec![(-dir, -a), (*dir, b)],
    };
    loop_extent_clipped(l, origin, along, &half_spaces)
}

/// Extent of a closed loop along `along` over the part of it inside every half-space
/// `n · (p − origin) <= h` of `half_spaces` (segments clipped at their faces, so the clipped
/// ends count). `None` when nothing of the loop is inside.
pub(crate) fn loop_extent_clipped(
    l: &SectionLoop,
    origin: &Point,
    along: &Vec3,
    half_spaces: &[(Vec3, f64)],
) -> Option<f64> {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let mut take = |p: &Point| {
        let s = along.dot(&(p - origin));
        lo = lo.min(s);
        hi = hi.max(s);
    };
    let n = l.points.len();
    'segments: for i in 0..n {
        let (p, q) = (l.points[i], l.points[(i + 1) % n]);
        // Clip the segment p + t (q − p), t in [0, 1], to every half-space.
        let (mut t0, mut t1) = (0.0_f64, 1.0_f64);
        for (dir, h) in half_spaces {
            let (hp, hq) = (dir.dot(&(p - origin)), dir.dot(&(q - origin)));
            let dh = hq - hp;
            if dh.abs() < 1e-15 {
                if hp > *h {
                    continue 'segments;
                }
            } else {
                let t = (h - hp) / dh;
                if dh > 0.0 {
                    t1 = t1.min(t);
                } else {
                    t0 = t0.max(t);
                }
            }
            if t0 > t1 {
                continue 'segments;
            }
        }
        take(&(p + (q - p) * t0));
        take(&(p + (q - p) * t1));
    }
    (hi >= lo).then_some(hi - lo)
}

/// Breadth and thickness of the section of `skin` by `plane`: the loop enclosing `inside`, its
/// extent along `breadth` projected into the plane, and along the in-plane perpendicular to
/// that. Errors say what is wrong (no section, nothing enclosing `inside`).
pub(crate) fn section_breadth_thickness(
    skin: &TriMesh,
    plane: &Plane,
    inside: &Point,
    breadth: &Vec3,
) -> std::result::Result<(f64, f64), String> {
    let loops = plane_section(skin, plane);
    if loops.is_empty() {
        return Err("the section plane misses the skin".into());
    }
    let l = enclosing_loop(&loops, plane, inside).ok_or_else(|| {
        format!(
            "no closed section loop encloses the reference point ({} loops)",
            loops.len()
        )
    })?;
    let (u, v) = plane.basis(breadth);
    let o = plane.point;
    let b = loop_extent(l, &o, &u, None).unwrap_or(0.0);
    let t = loop_extent(l, &o, &v, None).unwrap_or(0.0);
    Ok((b, t))
}

/// Breadth and thickness of the finger at `joint` (a PIP, DIP or the thumb's IP): see the
/// module documentation.
pub(crate) fn finger_joint_section(
    skin: &TriMesh,
    skeleton: &Skeleton,
    joint: Joint,
) -> std::result::Result<(f64, f64), String> {
    let f = joint
        .finger()
        .ok_or_else(|| format!("{joint} is not a finger joint"))?;
    let rank = f
        .joints()
        .iter()
        .position(|&j| j == joint)
        .expect("a digit's joint");
    if rank == 0 {
        return Err(format!("{joint} is the digit's first joint"));
    }
    let c = skeleton.centre(joint);
    let prev = skeleton.centre(f.joints()[rank - 1]);
    let next = skeleton.distal_end(joint);
    let (d1, d2) = (
        (c - prev).try_normalize(1e-9),
        (next - c).try_normalize(1e-9),
    );
    let (Some(d1), Some(d2)) = (d1, d2) else {
        return Err(format!("{joint}: a link meeting the joint has zero length"));
    };
    let plane = Plane::new(c, d1 + d2).ok_or_else(|| {
        format!("{joint}: the two links meeting the joint point back onto each other")
    })?;
    let at = |e: String| format!("at {joint}: {e}");
    let loops = plane_section(skin, &plane);
    if loops.is_empty() {
        return Err(at("the section plane misses the skin".into()));
    }
    let l = enclosing_loop(&loops, &plane, &c).ok_or_else(|| {
        at(format!(
            "no closed section loop encloses the joint ({} loops)",
            loops.len()
        ))
    })?;
    // A finger touching this one (a flexed neighbour, the thumb against the index) joins its
    // section loop; the caliper's jaws close on this finger alone, so the loop is cut where it
    // pinches between this joint and each other digit's bone crossing inside it.
    let half_spaces: Vec<(Vec3, f64)> = other_digit_crossings(skeleton, f, &plane)
        .into_iter()
        .filter(|x| l.winding_number(&plane, x) != 0)
        .filter_map(|x| {
            let n = (x - c).try_normalize(1e-9)?;
            let across = plane.normal.cross(&n);
            Some((n, pinch(l, &c, &n, &across, n.dot(&(x - c)))))
        })
        .collect();
    let (u, v) = plane.basis(&skeleton.joint(joint).x());
    let b = loop_extent_clipped(l, &c, &u, &half_spaces);
    let t = loop_extent_clipped(l, &c, &v, &half_spaces);
    match (b, t) {
        (Some(b), Some(t)) => Ok((b, t)),
        _ => Err(at(
            "nothing of the section is nearer this finger than another".into(),
        )),
    }
}

/// Where a loop joining two fingers pinches between them: along the in-plane direction `n` from
/// `origin` (this finger's joint) to the other finger's bone at distance `length`, the level
/// `t` in the middle half of that span at which the loop's chord along `across` (in-plane,
/// perpendicular to `n`) is shortest (the
/// contact between the two fingers). For two equal fingers it is the perpendicular bisector.
pub fn pinch(l: &SectionLoop, origin: &Point, n: &Vec3, across: &Vec3, length: f64) -> f64 {
    let steps = 40;
    let chord = |t: f64| -> f64 {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let m = l.points.len();
        for i in 0..m {
            let (p, q) = (l.points[i], l.points[(i + 1) % m]);
            let (hp, hq) = (n.dot(&(p - origin)), n.dot(&(q - origin)));
            if (hp - t) * (hq - t) <= 0.0 && hp != hq {
                let x = p + (q - p) * ((t - hp) / (hq - hp));
                let s = across.dot(&(x - origin));
                lo = lo.min(s);
                hi = hi.max(s);
            }
        }
        if hi >= lo {
            hi - lo
        } else {
            f64::INFINITY
        }
    };
    (0..=steps)
        .map(|k| length * (0.25 + 0.5 * k as f64 / steps as f64))
        .min_by(|a, b| chord(*a).total_cmp(&chord(*b)))
        .unwrap_or(length / 2.0)
}

/// Where the bones of every digit but `f` (metacarpal of the thumb, phalanges to the tips)
/// cross `plane`.
fn other_digit_crossings(skeleton: &Skeleton, f: Finger, plane: &Plane) -> Vec<Point> {
    let mut out = Vec::new();
    for g in Finger::ALL.into_iter().filter(|&g| g != f) {
        let j = g.joints();
        let mut chain: Vec<Point> = j.iter().map(|&k| skeleton.centre(k)).collect();
        chain.push(skeleton.distal_end(j[j.len() - 1]));
        for w in chain.windows(2) {
            let (p, q) = (w[0], w[1]);
            let (dp, dq) = (plane.distance(&p), plane.distance(&q));
            if (dp >= 0.0) != (dq >= 0.0) {
                out.push(p + (q - p) * (dp / (dp - dq)));
            }
        }
    }
    out
}

fn landmark(landmarks: &BTreeMap<String, Point>, name: &str) -> std::result::Result<Point, String> {
    landmarks
        .get(name)
        .copied()
        .ok_or_else(|| format!("landmark {name} is missing"))
}

/// Wrist breadth and thickness: see the module documentation.
pub(crate) fn wrist_section(
    skin: &TriMesh,
    skeleton: &Skeleton,
    landmarks: &BTreeMap<String, Point>,
) -> std::result::Result<(f64, f64), String> {
    let (r, u) = (
        landmark(landmarks, "WRIST_RAD")?,
        landmark(landmarks, "WRIST_ULN")?,
    );
    let m = r + (u - r) * 0.5;
    let plane = Plane::new(m, skeleton.joint(Joint::Wrist).z()).expect("unit frame axis");
    section_breadth_thickness(skin, &plane, &m, &(r - u))
        .map_err(|e| format!("at the styloids: {e}"))
}

/// Diagonal hand breadth, metacarpale radiale to metacarpale ulnare: see the module
/// documentation.
pub fn hand_breadth_diagonal(
    skin: &TriMesh,
    skeleton: &Skeleton,
    landmarks: &BTreeMap<String, Point>,
) -> Measured {
    let (a, b) = (
        landmark(landmarks, "I_MCP_LAT")?,
        landmark(landmarks, "L_MCP_LAT")?,
    );
    let u = (b - a)
        .try_normalize(1e-9)
        .ok_or("I_MCP_LAT and L_MCP_LAT coincide")?;
    let dorsal = skeleton.joint(Joint::Wrist).y();
    let plane = Plane::new(a, u.cross(&dorsal))
        .ok_or("the line I_MCP_LAT-L_MCP_LAT is along the palm's dorsal direction")?;
    // In-plane: u along the line, w dorsal-palmar.
    let w = plane.normal.cross(&u);
    let loops = plane_section(skin, &plane);
    let mc3 = skeleton.centre(Joint::MMcp);
    let l = enclosing_loop(&loops, &plane, &mc3)
        .ok_or("no closed section loop through the metacarpal landmarks holds the MC3 head")?;
    // Does a thumb bone cross the plane inside this loop?
    let t = Finger::Thumb.joints();
    let bones = [
        (skeleton.centre(t[0]), skeleton.centre(t[1])),
        (skeleton.centre(t[1]), skeleton.centre(t[2])),
        (skeleton.centre(t[2]), skeleton.distal_end(t[2])),
    ];
    let thumb_joins = bones.iter().any(|(p, q)| {
        let (dp, dq) = (plane.distance(p), plane.distance(q));
        if (dp >= 0.0) == (dq >= 0.0) {
            return false;
        }
        let x = p + (q - p) * (dp / (dp - dq));
        l.winding_number(&plane, &x) != 0
    });
    let slab = thumb_joins.then(|| {
        let (ha, hb) = (0.0_f64, w.dot(&(b - a)));
        (
            &w,
            ha.min(hb) - BREADTH_BAND_MM,
            ha.max(hb) + BREADTH_BAND_MM,
        )
    });
    loop_extent(l, &a, &u, slab).ok_or_else(|| "the palm's section is empty".into())
}

/// Hand thickness at the head of the 3rd metacarpal: see the module documentation.
pub fn hand_thickness_mc3(skin: &TriMesh, skeleton: &Skeleton) -> Measured {
    let c = skeleton.centre(Joint::MMcp);
    let plane = Plane::new(c, c - skeleton.centre(Joint::Wrist))
        .ok_or("the wrist and MC3 head coincide")?;
    let (y, r) = plane.basis(&skeleton.joint(Joint::Wrist).y());
    let loops = plane_section(skin, &plane);
    let l = enclosing_loop(&loops, &plane, &c)
        .ok_or("no closed section loop at the MC3 head encloses it")?;
    loop_extent(l, &c, &y, Some((&r, -JAW_HALF_WIDTH_MM, JAW_HALF_WIDTH_MM)))
        .ok_or_else(|| "the section has nothing within a jaw's width of the MC3 head".into())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::plane_section::tests::prism;
    use crate::template::load_template;
    use nalgebra::{Isometry3, Translation3, UnitQuaternion};
    use std::f64::consts::PI;

    /// An elliptic cylinder along z (semi-axes `a` along x, `b` along y), `n` vertices per ring
    /// at equal parametric angles starting at `phase`.
    fn elliptic_cylinder(a: f64, b: f64, n: usize, phase: f64, x0: f64) -> TriMesh {
        let outline: Vec<(f64, f64)> = (0..n)
            .map(|k| {
                let t = phase + 2.0 * PI * k as f64 / n as f64;
                (x0 + a * t.cos(), b * t.sin())
            })
            .collect();
        prism(&outline, &[-20.0, -5.0, 0.0, 5.0, 20.0])
    }

    /// An elliptic cylinder's section is an inscribed polygon with vertices on the ellipse at
    /// parametric steps of 2π/n: along any direction its extent is within a factor cos(π/n) of
    /// the ellipse's, 2√(a² cos² α + b² sin² α) (the support of an ellipse). The bound holds at
    /// every angle and phase, through a ring of vertices and between rings, and under a rigid
    /// motion of everything.
    #[test]
    fn elliptic_cylinder_gives_the_closed_form_breadth_and_thickness() {
        let (a, b, n) = (9.0, 6.5, 64);
        let bound = (PI / n as f64).cos();
        let motion = Isometry3::from_parts(
            Translation3::new(30.0, -12.0, 7.0),
            UnitQuaternion::from_euler_angles(0.3, -1.1, 2.0),
        );
        for phase in [0.0, 0.05, 0.9] {
            let cyl = elliptic_cylinder(a, b, n, phase, 0.0);
            for z in [0.0, 2.5, -5.0] {
                for alpha in [0.0, 0.3, PI / 4.0, 1.3] {
                    let dir = Vec3::new(alpha.cos(), alpha.sin(), 0.0);
                    let support = |c: f64, s: f64| 2.0 * (a * a * c * c + b * b * s * s).sqrt();
                    let (eb, et) = (
                        support(alpha.cos(), alpha.sin()),
                        support(alpha.sin(), alpha.cos()),
                    );
                    let centre = Point::new(0.0, 0.0, z);
                    let plane = Plane::new(centre, Vec3::z()).unwrap();
                    let (br, th) = section_breadth_thickness(&cyl, &plane, &centre, &dir).unwrap();
                    for (m, e) in [(br, eb), (th, et)] {
                        assert!(
                            m <= e + 1e-9 && m >= e * bound,
                            "{phase} {z} {alpha}: {m} vs {e}"
                        );
                    }
                    // Moved rigidly with its plane, point and direction: the same readings.
                    let moved = cyl.transformed(&motion);
                    let plane_m = Plane::new(motion * centre, motion.rotation * Vec3::z()).unwrap();
                    let (bm, tm) = section_breadth_thickness(
                        &moved,
                        &plane_m,
                        &(motion * centre),
                        &(motion.rotation * dir),
                    )
                    .unwrap();
                    assert!((bm - br).abs() < 1e-9 && (tm - th).abs() < 1e-9);
                }
            }
        }
    }

    /// A box's section along its edges reads its sides exactly; turned by α in the plane, the
    /// extent of a w x h rectangle is w cos α + h sin α.
    #[test]
    fn box_gives_its_sides() {
        let (w, h) = (14.0, 9.0);
        let bx = prism(
            &[(-7.0, -4.5), (7.0, -4.5), (7.0, 4.5), (-7.0, 4.5)],
            &[-10.0, 0.0, 10.0],
        );
        for alpha in [0.0_f64, 0.2, 1.0] {
            let dir = Vec3::new(alpha.cos(), alpha.sin(), 0.0);
            for z in [0.0, 3.0] {
                let c = Point::new(0.5, -0.5, z);
                let plane = Plane::new(c, Vec3::z()).unwrap();
                let (br, th) = section_breadth_thickness(&bx, &plane, &c, &dir).unwrap();
                assert!((br - (w * alpha.cos() + h * alpha.sin())).abs() < 1e-9);
                assert!((th - (w * alpha.sin() + h * alpha.cos())).abs() < 1e-9);
            }
        }
        // Slab: within ±2 of x = 0 the box's extent along y is still its height; a slab off the
        // box holds nothing.
        let c = Point::origin();
        let plane = Plane::new(c, Vec3::z()).unwrap();
        let l = plane_section(&bx, &plane).remove(0);
        let y = Vec3::y();
        assert!((loop_extent(&l, &c, &y, Some((&Vec3::x(), -2.0, 2.0))).unwrap() - h).abs() < 1e-9);
        assert!(
            (loop_extent(&l, &c, &Vec3::x(), Some((&Vec3::x(), -2.0, 2.0))).unwrap() - 4.0).abs()
                < 1e-9
        );
        assert!(loop_extent(&l, &c, &y, Some((&Vec3::x(), 8.0, 9.0))).is_none());
    }

    /// Two fingers side by side, 0.5 mm apart, in one mesh: each one's calipers read its own
    /// section, exactly as when it is alone.
    #[test]
    fn a_neighbouring_finger_does_not_disturb_the_reading() {
        let alone = elliptic_cylinder(8.0, 6.0, 48, 0.1, 0.0);
        let other = elliptic_cylinder(9.0, 7.0, 48, 0.0, 8.0 + 0.5 + 9.0);
        let mut both = alone.clone();
        let k = both.vertices.len();
        both.vertices.extend(other.vertices.iter().copied());
        both.faces
            .extend(other.faces.iter().map(|f| [f[0] + k, f[1] + k, f[2] + k]));
        let c = Point::new(0.0, 0.0, 1.0);
        // Tilted a little, as a finger's bisector plane is.
        let plane = Plane::new(c, Vec3::new(0.05, 0.1, 1.0)).unwrap();
        let one = section_breadth_thickness(&alone, &plane, &c, &Vec3::x()).unwrap();
        let two = section_breadth_thickness(&both, &plane, &c, &Vec3::x()).unwrap();
        assert_eq!(one, two);
        assert_eq!(plane_section(&both, &plane).len(), 2);
        // Far from the first finger, the second's section is read.
        let c2 = Point::new(17.5, 0.0, 1.0);
        let (b2, _) = section_breadth_thickness(&both, &plane, &c2, &Vec3::x()).unwrap();
        assert!(b2 > 17.5 && b2 < 18.5, "{b2}");
    }

    /// Two fingers pressed together (two ellipses of different sizes overlapping, one section
    /// loop): the loop cut where it pinches reads the first finger alone, up to the contact:
    /// breadth from its far side to the x where the two ellipses cross, thickness 2 b₁; and the
    /// other way round for the second finger.
    #[test]
    fn a_touching_finger_is_cut_off_where_the_loop_pinches() {
        let (a1, b1, a2, b2) = (8.0, 6.5, 10.5, 8.0);
        let x2 = a1 + a2 - 1.5;
        let inside = |x: f64, y: f64, x0: f64, a: f64, b: f64| {
            ((x - x0) / a).powi(2) + (y / b).powi(2) < 1.0
        };
        // Where the two outlines cross: b₁²(1 − x²/a₁²) = b₂²(1 − (x − x₂)²/a₂²), by bisection.
        let g =
            |x: f64| b1 * b1 * (1.0 - (x / a1).powi(2)) - b2 * b2 * (1.0 - ((x - x2) / a2).powi(2));
        let (mut lo, mut hi) = (x2 - a2, a1);
        for _ in 0..100 {
            let m = (lo + hi) / 2.0;
            if (g(m) > 0.0) == (g(lo) > 0.0) {
                lo = m;
            } else {
                hi = m;
            }
        }
        let x_contact = lo;
        let mid = x_contact;
        let mut pts: Vec<(f64, f64)> = Vec::new();
        for k in 0..1440 {
            let t = 2.0 * PI * k as f64 / 1440.0;
            let p = (a1 * t.cos(), b1 * t.sin());
            if !inside(p.0, p.1, x2, a2, b2) {
                pts.push(p);
            }
            let q = (x2 + a2 * t.cos(), b2 * t.sin());
            if !inside(q.0, q.1, 0.0, a1, b1) {
                pts.push(q);
            }
        }
        pts.sort_by(|p, q| (p.1).atan2(p.0 - mid).total_cmp(&(q.1).atan2(q.0 - mid)));
        let fused = prism(&pts, &[-10.0, 0.0, 10.0]);
        let c = Point::origin();
        let plane = Plane::new(c, Vec3::z()).unwrap();
        let loops = plane_section(&fused, &plane);
        assert_eq!(loops.len(), 1, "the fingers share one loop");
        let l = &loops[0];
        let whole = loop_extent(l, &c, &Vec3::x(), None).unwrap();
        assert!((whole - (x2 + a2 + a1)).abs() < 0.01, "{whole}");
        let step = x2 / 2.0 / 40.0;
        let t = pinch(l, &c, &Vec3::x(), &Vec3::y(), x2);
        assert!(
            (t - x_contact).abs() <= step,
            "pinch {t} vs contact {x_contact}"
        );
        let cut = [(Vec3::x(), t)];
        let breadth = loop_extent_clipped(l, &c, &Vec3::x(), &cut).unwrap();
        let thickness = loop_extent_clipped(l, &c, &Vec3::y(), &cut).unwrap();
        assert!(
            (breadth - (a1 + x_contact)).abs() <= step + 0.01,
            "{breadth}"
        );
        assert!((thickness - 2.0 * b1).abs() < 0.01, "{thickness}");
        // From the other finger: its own breadth up to the contact, its own thickness.
        let x = Point::new(x2, 0.0, 0.0);
        let t2 = pinch(l, &x, &-Vec3::x(), &Vec3::y(), x2);
        let back = [(-Vec3::x(), t2)];
        let b2_read = loop_extent_clipped(l, &x, &Vec3::x(), &back).unwrap();
        let t2_read = loop_extent_clipped(l, &x, &Vec3::y(), &back).unwrap();
        assert!(
            (b2_read - (x2 + a2 - x_contact)).abs() <= step + 0.01,
            "{b2_read}"
        );
        assert!((t2_read - 2.0 * b2).abs() < 0.01, "{t2_read}");
    }

    /// On both templates every dimension is measured and plausible, and a rigid motion of skin,
    /// skeleton and landmarks together leaves every reading unchanged.
    #[test]
    fn template_dimensions_are_plausible_and_invariant_to_rigid_motion() {
        for side in [crate::anatomy::Side::Right, crate::anatomy::Side::Left] {
            let t = load_template(side).unwrap();
            let lm = t.landmark_points();
            let dims = measure_dimensions(&t.mesh, &t.skeleton, &lm);
            assert_eq!(dims.len(), 22);
            for (d, m) in &dims {
                let v = m.as_ref().unwrap_or_else(|e| panic!("{side} {d}: {e}"));
                let (lo, hi) = d.plausible_range_mm();
                assert!((lo..hi).contains(v), "{side} {d}: {v:.2} mm");
            }
            let motion = Isometry3::from_parts(
                Translation3::new(-120.0, 40.0, 300.0),
                UnitQuaternion::from_euler_angles(2.0, 0.4, -0.7),
            );
            let skin = t.mesh.transformed(&motion);
            let sk = crate::skeleton::forward_kinematics::posed_skeleton(
                &t.skeleton,
                &vec![motion; crate::anatomy::Link::ALL.len()],
            );
            let lm2 = lm.iter().map(|(k, p)| (k.clone(), motion * p)).collect();
            let moved = measure_dimensions(&skin, &sk, &lm2);
            for (d, m) in &dims {
                let (x, y) = (m.as_ref().unwrap(), moved[d].as_ref().unwrap());
                assert!((x - y).abs() < 1e-6, "{side} {d}: {x} vs {y}");
            }
        }
    }

    /// A missing landmark is named; the finger dimensions do not need landmarks.
    #[test]
    fn missing_landmarks_are_named() {
        let t = load_template(crate::anatomy::Side::Right).unwrap();
        let dims = measure_dimensions(&t.mesh, &t.skeleton, &BTreeMap::new());
        let e = dims[&Dimension::WristBreadth].as_ref().unwrap_err();
        assert!(e.contains("WRIST_RAD"), "{e}");
        let e = dims[&Dimension::HandBreadthDiagonal].as_ref().unwrap_err();
        assert!(e.contains("I_MCP_LAT"), "{e}");
        assert!(dims[&Dimension::HandThicknessMc3].is_ok());
        assert!(dims[&Dimension::BreadthDistal(Finger::Ring)].is_ok());
    }
}
