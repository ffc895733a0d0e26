//! The cross-section of a closed triangle mesh with a plane, as closed polylines (loops): what a
//! saw cut through the surface would show, and what a caliper's jaws close on.
//!
//! Method: every vertex is classified by the sign of its distance to the plane, with the
//! consistent rule "on the plane counts as above" (a symbolic perturbation of the plane by an
//! infinitesimal step against its normal). Under that rule no vertex lies *on* the plane, so every
//! face is cut by exactly zero or two of its edges, every cut edge is shared by exactly two cut
//! faces of a closed 2-manifold, and the cuts chain into closed loops without special cases for
//! vertices, edges or faces lying in the plane. A cut point is the exact intersection of its edge
//! with the plane (a vertex in the plane is its own cut point), so the loops lie in the plane;
//! consecutive repeats (several cut edges ending at one vertex in the plane) are dropped.
//! Each face's segment runs from the edge where its boundary enters the region below the plane to
//! the edge where it leaves it, so every loop is oriented the same way: counter-clockwise seen
//! from the normal's side for the outer boundary of a solid's section (faces counter-clockwise
//! from outside), clockwise for a hole.

use super::{Point, TriMesh, Vec3};
use std::collections::HashMap;

/// A plane through `point` with unit `normal`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// A point of the plane, mm.
    pub point: Point,
    /// Unit normal.
    pub normal: Vec3,
}

impl Plane {
    /// The plane through `point` normal to `normal` (normalised); `None` for a zero normal.
    pub fn new(point: Point, normal: Vec3) -> Option<Plane> {
        Some(Plane {
            point,
            normal: normal.try_normalize(1e-12)?,
        })
    }

    /// Signed distance of `p`, positive on the normal's side.
    pub fn distance(&self, p: &Point) -> f64 {
        (p - self.point).dot(&self.normal)
    }

    /// Two unit in-plane directions `(u, v)` with `u × v = normal`, `u` along `hint` projected
    /// into the plane (any in-plane direction when `hint` is along the normal).
    pub fn basis(&self, hint: &Vec3) -> (Vec3, Vec3) {
        let n = self.normal;
        let u = (hint - n * hint.dot(&n))
            .try_normalize(1e-9)
            .unwrap_or_else(|| {
                let a = if n.x.abs() < 0.9 {
                    Vec3::x()
                } else {
                    Vec3::y()
                };
                a.cross(&n).normalize()
            });
        (u, n.cross(&u))
    }
}

/// One polyline of a section: a closed loop (the last point connects to the first), or an open
/// chain where the mesh has a boundary or is not 2-manifold.
#[derive(Clone, Debug, PartialEq)]
pub struct SectionLoop {
    /// The points, in the plane, mm.
    pub points: Vec<Point>,
    /// Closed (the usual case on a closed 2-manifold mesh).
    pub closed: bool,
}

impl SectionLoop {
    /// Signed area about `normal` (counter-clockwise seen from the normal's side is positive),
    /// mm². Meaningful for closed loops.
    pub fn signed_area(&self, normal: &Vec3) -> f64 {
        let p = &self.points;
        let Some(o) = p.first() else { return 0.0 };
        let mut s = Vec3::zeros();
        for i in 1..p.len().saturating_sub(1) {
            s += (p[i] - o).cross(&(p[i + 1] - o));
        }
        0.5 * s.dot(normal)
    }

    /// Length of the polyline (closing segment included for a closed loop), mm.
    pub fn perimeter(&self) -> f64 {
        let p = &self.points;
        let mut l: f64 = p.windows(2).map(|w| (w[1] - w[0]).norm()).sum();
        if self.closed && p.len() > 1 {
            l += (p[0] - p[p.len() - 1]).norm();
        }
        l
    }

    /// Winding number of the loop about `q` (projected into `plane`): nonzero when the loop
    /// encloses it. Closed loops only (an open chain gives 0).
    pub fn winding_number(&self, plane: &Plane, q: &Point) -> i32 {
        if !self.closed || self.points.len() < 3 {
            return 0;
        }
        let (u, v) = plane.basis(&Vec3::x());
        let to2 = |p: &Point| {
            let d = p - q;
            (d.dot(&u), d.dot(&v))
        };
        // Sunday's crossing rule for the winding number.
        let mut w = 0;
        let n = self.points.len();
        for i in 0..n {
            let (x0, y0) = to2(&self.points[i]);
            let (x1, y1) = to2(&self.points[(i + 1) % n]);
            let cross = x0 * y1 - x1 * y0;
            if y0 <= 0.0 {
                if y1 > 0.0 && cross > 0.0 {
                    w += 1;
                }
            } else if y1 <= 0.0 && cross < 0.0 {
                w -= 1;
            }
        }
        w
    }
}

/// The section of `mesh` with `plane`, as loops (see the module documentation for the rule at
/// vertices on the plane). A closed 2-manifold mesh gives only closed loops; nothing is lost on
/// another mesh, whose broken chains come back open.
pub fn plane_section(mesh: &TriMesh, plane: &Plane) -> Vec<SectionLoop> {
    let above: Vec<bool> = mesh
        .vertices
        .iter()
        .map(|p| plane.distance(p) >= 0.0)
        .collect();
    let key = |a: usize, b: usize| if a < b { (a, b) } else { (b, a) };
    let cut_point = |a: usize, b: usize| -> Point {
        // `a` above (distance >= 0), `b` below (< 0): the denominator is positive.
        let (pa, pb) = (mesh.vertices[a], mesh.vertices[b]);
        let (da, db) = (plane.distance(&pa), plane.distance(&pb));
        let t = da / (da - db);
        pa + (pb - pa) * t
    };
    // Per cut face: (entry edge, exit edge), walking the face's boundary counter-clockwise; the
    // boundary enters the region below at the entry edge and leaves it at the exit edge.
    let mut segments: Vec<((usize, usize), (usize, usize))> = Vec::new();
    for f in &mesh.faces {
        let mut entry = None;
        let mut exit = None;
        for k in 0..3 {
            let (a, b) = (f[k], f[(k + 1) % 3]);
            match (above[a], above[b]) {
                (true, false) => entry = Some(key(a, b)),
                (false, true) => exit = Some(key(a, b)),
                _ => {}
            }
        }
        if let (Some(en), Some(ex)) = (entry, exit) {
            segments.push((en, ex));
        }
    }
    let point_of = |(a, b): (usize, usize)| {
        if above[a] {
            cut_point(a, b)
        } else {
            cut_point(b, a)
        }
    };
    // A face's exit edge is its neighbour's entry edge (the neighbour walks it the other way).
    let mut by_entry: HashMap<(usize, usize), usize> = HashMap::with_capacity(segments.len());
    let mut has_predecessor = vec![false; segments.len()];
    for (i, s) in segments.iter().enumerate() {
        by_entry.insert(s.0, i);
    }
    for s in &segments {
        if let Some(&j) = by_entry.get(&s.1) {
            has_predecessor[j] = true;
        }
    }
    let mut used = vec![false; segments.len()];
    let mut loops = Vec::new();
    // Open chains first (from segments nobody leads into), then the closed loops.
    let starts: Vec<usize> = (0..segments.len())
        .filter(|&i| !has_predecessor[i])
        .chain(0..segments.len())
        .collect();
    for start in starts {
        if used[start] {
            continue;
        }
        let mut pts = vec![point_of(segments[start].0)];
        let mut i = start;
        let closed = loop {
            used[i] = true;
            let exit = segments[i].1;
            match by_entry.get(&exit) {
                Some(&j) if j == start => break true,
                Some(&j) if !used[j] => {
                    pts.push(point_of(exit));
                    i = j;
                }
                _ => {
                    pts.push(point_of(exit));
                    break false;
                }
            }
        };
        pts.dedup_by(|a, b| (*a - *b).norm() <= 1e-12);
        if closed && pts.len() > 1 && (pts[0] - pts[pts.len() - 1]).norm() <= 1e-12 {
            pts.pop();
        }
        if pts.len() >= 2 {
            loops.push(SectionLoop {
                points: pts,
                closed,
            });
        }
    }
    loops
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::geometry::mesh::tests::{cuboid, icosphere, torus};
    use std::f64::consts::PI;

    fn plane(p: [f64; 3], n: [f64; 3]) -> Plane {
        Plane::new(Point::new(p[0], p[1], p[2]), Vec3::new(n[0], n[1], n[2])).unwrap()
    }

    /// A right prism over the counter-clockwise polygon `outline` (x, y), with a ring of
    /// vertices at every height of `levels` (ascending) and fan caps at both ends: closed,
    /// 2-manifold, faces counter-clockwise from outside.
    pub(crate) fn prism(outline: &[(f64, f64)], levels: &[f64]) -> TriMesh {
        let n = outline.len();
        let mut v: Vec<Point> = Vec::new();
        for &z in levels {
            v.extend(outline.iter().map(|&(x, y)| Point::new(x, y, z)));
        }
        let (cx, cy) = outline.iter().fold((0.0, 0.0), |(a, b), &(x, y)| {
            (a + x / n as f64, b + y / n as f64)
        });
        let (bottom, top) = (v.len(), v.len() + 1);
        v.push(Point::new(cx, cy, levels[0]));
        v.push(Point::new(cx, cy, levels[levels.len() - 1]));
        let mut f = Vec::new();
        let last = (levels.len() - 1) * n;
        for i in 0..n {
            let j = (i + 1) % n;
            for l in 0..levels.len() - 1 {
                let (a, b) = (l * n + i, l * n + j);
                f.push([a, b, b + n]);
                f.push([a, b + n, a + n]);
            }
            f.push([bottom, j, i]);
            f.push([top, last + i, last + j]);
        }
        TriMesh::new(v, f).unwrap()
    }

    /// A box cut through its middle is a rectangle, also when the plane holds a whole ring of
    /// vertices and edges, or a diagonal plane holds four vertical edges: one closed loop with
    /// the closed-form area and perimeter. A plane touching a face from outside cuts nothing
    /// (the rule treats its vertices as above, i.e. the plane as just off the solid).
    #[test]
    fn box_sections_are_rectangles_even_through_vertices() {
        let rect = [(0.0, 0.0), (2.0, 0.0), (2.0, 3.0), (0.0, 3.0)];
        let b = prism(&rect, &[0.0, 1.0, 2.5, 4.0]);
        b.check_closed_manifold().unwrap();
        let d = 13f64.sqrt();
        for (p, n, area, perimeter) in [
            ([0.0, 0.0, 1.7], [0.0, 0.0, 1.0], 6.0, 10.0),
            // A whole ring of vertices and edges in the plane, both normal directions.
            ([0.0, 0.0, 2.5], [0.0, 0.0, 1.0], 6.0, 10.0),
            ([0.0, 0.0, 2.5], [0.0, 0.0, -1.0], 6.0, 10.0),
            ([0.0, 0.0, 1.0], [0.0, 0.0, 1.0], 6.0, 10.0),
            // A diagonal plane through the vertical edges at (0,0) and (2,3): a d x 4 rectangle.
            ([0.0, 0.0, 0.0], [3.0, -2.0, 0.0], d * 4.0, 2.0 * (d + 4.0)),
            ([0.0, 0.0, 0.0], [-3.0, 2.0, 0.0], d * 4.0, 2.0 * (d + 4.0)),
            // Through the vertical edge x = 2, y = 0 and across: a triangle-free oblique cut.
            (
                [2.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                2f64.sqrt() * 2.0 * 4.0,
                2.0 * (2.0 * 2f64.sqrt() + 4.0),
            ),
        ] {
            let pl = plane(p, n);
            let loops = plane_section(&b, &pl);
            assert_eq!(loops.len(), 1, "{p:?} {n:?}: {loops:?}");
            let l = &loops[0];
            assert!(l.closed);
            assert!(
                (l.signed_area(&pl.normal) - area).abs() < 1e-9,
                "{p:?} {n:?}: {}",
                l.signed_area(&pl.normal)
            );
            assert!((l.perimeter() - perimeter).abs() < 1e-9, "{p:?} {n:?}");
            assert!(l.points.iter().all(|q| pl.distance(q).abs() < 1e-12));
        }
        // Touching the bottom face from outside, or missing the box: nothing.
        assert!(plane_section(&b, &plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0])).is_empty());
        assert!(plane_section(&b, &plane([0.0, 0.0, 5.0], [0.0, 0.0, 1.0])).is_empty());
        // The whole cube mesh, cut through its middle.
        let cube = cuboid(2.0, 3.0, 4.0);
        let pl = plane([0.0, 0.0, 1.7], [0.0, 0.0, 1.0]);
        let loops = plane_section(&cube, &pl);
        assert_eq!(loops.len(), 1);
        assert!((loops[0].signed_area(&pl.normal) - 6.0).abs() < 1e-9);
    }

    /// A sphere of radius R cut at height h is a circle of radius √(R² − h²): the inscribed
    /// polygon's perimeter and area are below the circle's by at most the chord error.
    #[test]
    fn sphere_section_is_the_circle_within_the_discretisation() {
        let r = 10.0;
        let s = icosphere(r, 4);
        // The icosphere's edges are at most about R·1.1/2⁴; a chord of length c deviates from
        // the sphere by c²/(8R), so the section circle is met to that.
        let sag = (r * 1.2 / 16.0f64).powi(2) / (8.0 * r) * 2.0;
        for (h, n) in [
            (0.0, [0.0, 0.0, 1.0]),
            (3.3, [1.0, 2.0, 2.0]),
            (-7.1, [0.0, 1.0, 0.0]),
        ] {
            let nn = Vec3::new(n[0], n[1], n[2]).normalize();
            let pl = Plane::new(Point::from(nn * h), nn).unwrap();
            let loops = plane_section(&s, &pl);
            assert_eq!(loops.len(), 1);
            let rc = (r * r - h * h).sqrt();
            let l = &loops[0];
            for q in &l.points {
                let d = (q - Point::from(nn * h)).norm();
                assert!(d <= rc + 1e-9 && d >= rc - sag * r / rc, "{h}: {d} vs {rc}");
            }
            let (a, p) = (l.signed_area(&nn), l.perimeter());
            assert!(a > 0.0, "counter-clockwise seen from the normal");
            let (ac, pc) = (PI * rc * rc, 2.0 * PI * rc);
            assert!(a < ac && a > ac * 0.99, "{h}: area {a} vs {ac}");
            assert!(p < pc && p > pc * 0.995, "{h}: perimeter {p} vs {pc}");
        }
    }

    /// A torus cut through its axis gives two loops (the two tube sections, circles of the
    /// minor radius centred at ±R), cut across the axis at mid-height two concentric circles,
    /// the inner one a hole (clockwise).
    #[test]
    fn torus_gives_two_loops() {
        let (rb, rs) = (20.0, 5.0);
        let t = torus(rb, rs, 96, 48);
        let pl = plane([0.0, 0.0, 0.0], [0.0, 1.0, 0.0]);
        let loops = plane_section(&t, &pl);
        assert_eq!(loops.len(), 2);
        let mut centres: Vec<f64> = loops
            .iter()
            .map(|l| l.points.iter().map(|p| p.x).sum::<f64>() / l.points.len() as f64)
            .collect();
        centres.sort_by(f64::total_cmp);
        assert!((centres[0] + rb).abs() < 0.05 && (centres[1] - rb).abs() < 0.05);
        for l in &loops {
            assert!(l.closed);
            let a = l.signed_area(&pl.normal);
            assert!((a - PI * rs * rs).abs() < PI * rs * rs * 0.01, "{a}");
            let c = Point::new(if l.points[0].x > 0.0 { rb } else { -rb }, 0.0, 0.0);
            assert_eq!(l.winding_number(&pl, &c), 1);
            assert_eq!(l.winding_number(&pl, &Point::origin()), 0);
        }
        // Across the axis (the plane holds a whole ring of vertices).
        let pl = plane([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let loops = plane_section(&t, &pl);
        assert_eq!(loops.len(), 2);
        let mut areas: Vec<f64> = loops.iter().map(|l| l.signed_area(&pl.normal)).collect();
        areas.sort_by(f64::total_cmp);
        let (ri, ro) = (rb - rs, rb + rs);
        assert!(
            (areas[0] + PI * ri * ri).abs() < PI * ri * ri * 0.01,
            "{areas:?}"
        );
        assert!(
            (areas[1] - PI * ro * ro).abs() < PI * ro * ro * 0.01,
            "{areas:?}"
        );
    }
}
