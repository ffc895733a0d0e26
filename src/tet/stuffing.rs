//! Isosurface stuffing (Labelle & Shewchuk 2007, "Isosurface stuffing: fast tetrahedral
//! meshes with good dihedral angles", ACM Trans. Graph. 26(3), article 57): a tetrahedral mesh
//! of the inside of a closed triangle surface, filled with body-centred cubic (BCC) lattice
//! tetrahedra whose boundary layer is cut and warped onto the surface.
//!
//! The steps, for a lattice of spacing `h` (the side of the cubes):
//! 1. **Lattice.** Black vertices on the cube corners, red ones at the cube centres. A BCC
//!    tetrahedron joins two red vertices across a cube face (a *long* edge, length `h`) with
//!    the two ends of one edge of that face (long, `h`); its other four edges are *short*
//!    (red-black, `h √3 / 2`). Each lattice vertex is classified inside (+), outside (-) or on
//!    the surface (0) by the sign of the signed distance to the surface (angle-weighted
//!    pseudo-normals, Bærentzen & Aanæs 2005), with a ray-parity vote where that distance is
//!    unavailable.
//! 2. **Cut points.** Every lattice edge with a + and a - end holds a cut point where it first
//!    crosses the surface from its + end, found by casting a ray along the edge, so that cut
//!    points lie on the input surface (to rounding).
//! 3. **Warp.** A vertex closer to a cut point on one of its edges than `α` times that edge's
//!    length (`α_long = 0.24999`, `α_short = 0.41189`, the paper's values for the uniform
//!    lattice, section 4) moves onto the nearest such cut point and becomes 0; the cut points
//!    on its edges disappear. Vertices are visited in lattice order (deterministic).
//! 4. **Stencils.** Each BCC tetrahedron with a + vertex and no - vertex is kept; one with both
//!    is replaced by the part of it on the + side: one tetrahedron (one + vertex), a pyramid
//!    split into two (two +, one 0, one -) or a prism split into three (two + and two -, or
//!    three + and one -). One with only 0 and - vertices is dropped; one with four 0 vertices
//!    is kept when its centroid is inside.
//!
//! **Deviation from the paper: quadrilateral diagonals.** L&S split the quadrilaterals of the
//! pyramid and prism stencils by a parity rule on the lattice colours, which their angle bound
//! proof relies on. Here each quadrilateral is split along the diagonal from its vertex with
//! the smallest global id (lattice vertices before cut points), and prisms by the matching rule
//! of Dompierre et al. (1999, "How to subdivide pyramids, prisms and hexahedra into
//! tetrahedra"): neighbours sharing a quadrilateral always agree and no prism is left
//! untriangulable, but the proven bounds (dihedral angles within 10.78°-164.83° for a smooth
//! surface sampled finely enough) do not carry over verbatim. Measured on the right template
//! hand at the default spacing (3 mm): dihedral angles within 6.9°-170.2°, radius-edge ratio
//! at most 2.66, no inverted element (at 3.5 mm: 17.3°-147.1°; at 2.5 mm: 7.5°-169.3°). The
//! worst elements sit where the surface bends sharply at the lattice scale (finger webs,
//! nail edges), where the paper's smoothness assumption fails as well. The figures are
//! reported for every run (`tet::TetReport`).
//!
//! After stuffing, the nodes of the boundary faces are projected onto their closest points on
//! the input surface (they are already on it up to rounding), so that they can be bound to it by
//! face and barycentric coordinates (see [`super::transfer`]).
//!
//! Orientation: every output tetrahedron is oriented from the *reference* positions of its
//! vertices (lattice vertices at their lattice positions, cut points on their lattice edges),
//! where the stencils are exact subdivisions of the BCC tetrahedron; warping can then show up as
//! an inverted element instead of being silently re-oriented.

use crate::error::{Error, Result};
use crate::geometry::closest_point::{AabbTree, PseudoNormals};
use crate::geometry::tet_mesh::{tet_signed_volume, TetMesh};
use crate::geometry::{Point, TriMesh, Vec3};
use rayon::prelude::*;
use std::collections::HashMap;

/// Version of the stuffing algorithm; part of the cache key, so bump it whenever the output
/// for the same input changes.
pub const ALGORITHM_VERSION: u32 = 1;

/// Warp threshold for long (axis-parallel, length `h`) lattice edges (L&S 2007, section 4).
pub(crate) const ALPHA_LONG: f64 = 0.24999;
/// Warp threshold for short (red-black, length `h √3 / 2`) lattice edges (L&S 2007).
pub(crate) const ALPHA_SHORT: f64 = 0.41189;
/// Default lattice spacing for the template hand, mm: 157,145 tetrahedra and 31,519 nodes
/// (9,361 on the boundary) on the right template, with several lattice cells across a finger
/// so that fingers hold interior nodes; the tet volume is 0.36 % below the surface's.
pub(crate) const DEFAULT_SPACING_MM: f64 = 3.0;

/// Most lattice vertices accepted (a guard against a spacing far too small for the surface).
const MAX_LATTICE_VERTICES: usize = 40_000_000;

/// Parameters of [`isosurface_stuffing`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StuffingParams {
    /// Lattice spacing `h` (cube side), mm.
    pub spacing: f64,
    /// Warp threshold on long edges (fraction of the edge length).
    pub alpha_long: f64,
    /// Warp threshold on short edges (fraction of the edge length).
    pub alpha_short: f64,
}

impl Default for StuffingParams {
    fn default() -> Self {
        StuffingParams {
            spacing: DEFAULT_SPACING_MM,
            alpha_long: ALPHA_LONG,
            alpha_short: ALPHA_SHORT,
        }
    }
}

impl StuffingParams {
    /// Default thresholds with spacing `h` mm.
    pub fn with_spacing(h: f64) -> Self {
        StuffingParams {
            spacing: h,
            ..Default::default()
        }
    }
}

/// The BCC lattice: black vertices `(i, j, k)`, `0 <= i <= n[0]` etc. at `origin + h (i, j, k)`,
/// then red vertices at the centres of the `n[0] n[1] n[2]` cubes.
struct Lattice {
    origin: Point,
    h: f64,
    n: [usize; 3],
    n_black: usize,
}

impl Lattice {
    fn black(&self, i: usize, j: usize, k: usize) -> usize {
        i + (self.n[0] + 1) * (j + (self.n[1] + 1) * k)
    }
    fn red(&self, i: usize, j: usize, k: usize) -> usize {
        self.n_black + i + self.n[0] * (j + self.n[1] * k)
    }
    fn len(&self) -> usize {
        self.n_black + self.n[0] * self.n[1] * self.n[2]
    }
    fn position(&self, id: usize) -> Point {
        let (c, off) = if id < self.n_black {
            let (nx, ny) = (self.n[0] + 1, self.n[1] + 1);
            ([id % nx, (id / nx) % ny, id / (nx * ny)], 0.0)
        } else {
            let r = id - self.n_black;
            let (nx, ny) = (self.n[0], self.n[1]);
            ([r % nx, (r / nx) % ny, r / (nx * ny)], 0.5)
        };
        self.origin + Vec3::new(c[0] as f64 + off, c[1] as f64 + off, c[2] as f64 + off) * self.h
    }
}

/// A cut point: on lattice edge `(a, b)` (`a` inside) at parameter `t` from `a`.
#[derive(Clone, Copy, Debug)]
struct Cut {
    a: usize,
    b: usize,
    long: bool,
    t: f64,
    point: Point,
}

/// Inside test by ray parity, majority of three rays in fixed, generic directions: the fallback
/// where the pseudo-normal signed distance is unavailable.
fn inside_by_parity(tree: &AabbTree, p: &Point) -> bool {
    const DIRS: [[f64; 3]; 3] = [
        [0.577_350_3, 0.577_350_2, 0.577_350_4],
        [-0.267_261_2, 0.534_522_5, 0.801_783_7],
        [0.801_783_7, -0.267_261_2, -0.534_522_5],
    ];
    let mut votes = 0;
    for d in DIRS {
        let dir = Vec3::from(d);
        let (mut t, mut n) = (0.0, 0usize);
        while let Some(hit) = tree.ray_cast(p, &dir, t, f64::INFINITY) {
            n += 1;
            t = hit.t;
            if n > 1_000_000 {
                break;
            }
        }
        votes += n % 2;
    }
    votes >= 2
}

/// Tetrahedral mesh of the inside of the closed, outward-oriented `surface` by isosurface
/// stuffing (Labelle & Shewchuk 2007; see the module doc for the steps and the one deviation).
/// Boundary nodes lie on `surface` (projected onto their closest points).
///
/// Errors (one line) when the surface is empty or not finite, the parameters are out of range
/// (`spacing > 0`, `0 < α < 0.5`), the lattice would exceed 40 million vertices, or no
/// tetrahedron is produced (surface smaller than the spacing, or not closed).
pub fn isosurface_stuffing(surface: &TriMesh, params: &StuffingParams) -> Result<TetMesh> {
    let h = params.spacing;
    if !(h.is_finite() && h > 0.0) {
        return Err(Error::invalid(format!(
            "stuffing spacing {h} mm: must be finite and > 0"
        )));
    }
    for (name, a) in [
        ("alpha_long", params.alpha_long),
        ("alpha_short", params.alpha_short),
    ] {
        if !(a > 0.0 && a < 0.5) {
            return Err(Error::invalid(format!(
                "stuffing {name} = {a}: must be in (0, 0.5)"
            )));
        }
    }
    if surface.faces.is_empty() {
        return Err(Error::invalid("stuffing: the surface has no faces"));
    }
    let surface = TriMesh::new(surface.vertices.clone(), surface.faces.clone())?;
    let (lo, hi) = surface
        .bounds()
        .ok_or_else(|| Error::invalid("stuffing: the surface has no vertices"))?;
    // Two cells of padding: the outer lattice layers are outside, so every + vertex is
    // surrounded by lattice tetrahedra.
    let origin = lo - Vec3::repeat(2.0 * h);
    let mut n = [0usize; 3];
    let mut total = 1.0f64;
    for a in 0..3 {
        let cells = ((hi[a] - lo[a]) / h).ceil() + 4.0;
        total *= cells + 1.0;
        n[a] = cells as usize;
    }
    if 2.0 * total > MAX_LATTICE_VERTICES as f64 {
        return Err(Error::invalid(format!(
            "stuffing spacing {h} mm is too small for a surface of {:.1} x {:.1} x {:.1} mm \
             (over {} lattice vertices): use a larger spacing",
            hi.x - lo.x,
            hi.y - lo.y,
            hi.z - lo.z,
            MAX_LATTICE_VERTICES
        )));
    }
    let lat = Lattice {
        origin,
        h,
        n,
        n_black: (n[0] + 1) * (n[1] + 1) * (n[2] + 1),
    };
    let tree = AabbTree::new(&surface);
    let normals = PseudoNormals::new(&surface);

    // 1. Signed distance (negative inside) and sign (+1 inside) of every lattice vertex.
    let f: Vec<f64> = (0..lat.len())
        .into_par_iter()
        .map(|id| {
            let p = lat.position(id);
            match tree.signed_distance(&normals, &p) {
                Some(d) if d.is_finite() => d,
                _ => {
                    let d = tree.distance(&p).filter(|d| d.is_finite()).unwrap_or(h);
                    if inside_by_parity(&tree, &p) {
                        -d
                    } else {
                        d
                    }
                }
            }
        })
        .collect();
    let mut sign: Vec<i8> = f
        .iter()
        .map(|&d| {
            if d < 0.0 {
                1
            } else if d > 0.0 {
                -1
            } else {
                0
            }
        })
        .collect();

    // 2. Cut points on the lattice edges with a + and a - end.
    let mut edges: Vec<(usize, usize, bool)> = Vec::new();
    let mut push = |a: usize, b: usize, long: bool| {
        if sign[a] * sign[b] < 0 {
            let (a, b) = if sign[a] > 0 { (a, b) } else { (b, a) };
            edges.push((a, b, long));
        }
    };
    let [nx, ny, nz] = n;
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                let v = lat.black(i, j, k);
                if i < nx {
                    push(v, lat.black(i + 1, j, k), true);
                }
                if j < ny {
                    push(v, lat.black(i, j + 1, k), true);
                }
                if k < nz {
                    push(v, lat.black(i, j, k + 1), true);
                }
                if i < nx && j < ny && k < nz {
                    let r = lat.red(i, j, k);
                    for c in 0..8 {
                        push(
                            r,
                            lat.black(i + (c & 1), j + ((c >> 1) & 1), k + (c >> 2)),
                            false,
                        );
                    }
                    if i + 1 < nx {
                        push(r, lat.red(i + 1, j, k), true);
                    }
                    if j + 1 < ny {
                        push(r, lat.red(i, j + 1, k), true);
                    }
                    if k + 1 < nz {
                        push(r, lat.red(i, j, k + 1), true);
                    }
                }
            }
        }
    }
    let cuts: Vec<Cut> = edges
        .par_iter()
        .map(|&(a, b, long)| {
            let (pa, pb) = (lat.position(a), lat.position(b));
            let dir = pb - pa;
            // A little beyond the ends, so a surface through an end (to rounding) is found.
            if let Some(hit) = tree.ray_cast(&pa, &dir, -1e-9, 1.0 + 1e-9) {
                return Cut {
                    a,
                    b,
                    long,
                    t: hit.t.clamp(0.0, 1.0),
                    point: hit.point,
                };
            }
            // No crossing found (the signs came from the parity fallback or rounding): the
            // linear zero of the distance, pulled onto the surface.
            let t = f[a] / (f[a] - f[b]);
            let t = if t.is_finite() {
                t.clamp(0.0, 1.0)
            } else {
                0.5
            };
            let q = pa + dir * t;
            let point = tree.closest_point(&q).map(|c| c.point).unwrap_or(q);
            Cut {
                a,
                b,
                long,
                t,
                point,
            }
        })
        .collect();

    // 3. Warp, in lattice order.
    let mut incident: Vec<Vec<u32>> = vec![Vec::new(); lat.len()];
    for (c, cut) in cuts.iter().enumerate() {
        incident[cut.a].push(c as u32);
        incident[cut.b].push(c as u32);
    }
    let mut warped: HashMap<usize, Point> = HashMap::new();
    for v in 0..lat.len() {
        if sign[v] == 0 || incident[v].is_empty() {
            continue;
        }
        let mut best: Option<(f64, usize)> = None;
        for &c in &incident[v] {
            let cut = &cuts[c as usize];
            let other = if cut.a == v { cut.b } else { cut.a };
            if sign[other] == 0 {
                continue; // the cut vanished when `other` was warped
            }
            let frac = if cut.a == v { cut.t } else { 1.0 - cut.t };
            let alpha = if cut.long {
                params.alpha_long
            } else {
                params.alpha_short
            };
            if frac < alpha && best.is_none_or(|(b, _)| frac < b) {
                best = Some((frac, c as usize));
            }
        }
        if let Some((_, c)) = best {
            warped.insert(v, cuts[c].point);
            sign[v] = 0;
        }
    }
    let cut_of: HashMap<(usize, usize), usize> = cuts
        .iter()
        .enumerate()
        .filter(|(_, c)| sign[c.a] != 0 && sign[c.b] != 0)
        .map(|(i, c)| ((c.a.min(c.b), c.a.max(c.b)), i))
        .collect();

    // 4. Stencils, over the BCC tetrahedra: pairs of adjacent cube centres and the four edges
    //    of the face between them. Global ids: lattice vertices, then cut points.
    let nl = lat.len();
    let reference = |g: usize| -> Point {
        if g < nl {
            lat.position(g)
        } else {
            let c = &cuts[g - nl];
            let (pa, pb) = (lat.position(c.a), lat.position(c.b));
            pa + (pb - pa) * c.t
        }
    };
    let actual = |g: usize| -> Point {
        if g < nl {
            warped.get(&g).copied().unwrap_or_else(|| lat.position(g))
        } else {
            cuts[g - nl].point
        }
    };
    let cut = |a: usize, b: usize| -> usize { nl + cut_of[&(a.min(b), a.max(b))] };
    let mut out: Vec<[usize; 4]> = Vec::new();
    let mut emit = |mut t: [usize; 4]| {
        let [a, b, c, d] = t.map(reference);
        if tet_signed_volume(&a, &b, &c, &d) < 0.0 {
            t.swap(2, 3);
        }
        out.push(t);
    };
    for axis in 0..3 {
        let (b, c) = ((axis + 1) % 3, (axis + 2) % 3);
        for k in 0..nz {
            for j in 0..ny {
                for i in 0..nx {
                    let idx = [i, j, k];
                    if idx[axis] + 1 >= n[axis] {
                        continue;
                    }
                    let r1 = lat.red(i, j, k);
                    let mut nb = idx;
                    nb[axis] += 1;
                    let r2 = lat.red(nb[0], nb[1], nb[2]);
                    let corner = |db: usize, dc: usize| {
                        let mut q = idx;
                        q[axis] += 1;
                        q[b] += db;
                        q[c] += dc;
                        lat.black(q[0], q[1], q[2])
                    };
                    let ring = [corner(0, 0), corner(1, 0), corner(1, 1), corner(0, 1)];
                    for e in 0..4 {
                        let tet = [r1, r2, ring[e], ring[(e + 1) % 4]];
                        stencil(tet, &sign, &cut, &mut emit, &|t: [usize; 4]| {
                            let s: Vec3 = t.iter().map(|&g| actual(g).coords).sum();
                            let centre = Point::from(s / 4.0);
                            match tree.signed_distance(&normals, &centre) {
                                Some(d) if d.is_finite() => d < 0.0,
                                _ => inside_by_parity(&tree, &centre),
                            }
                        });
                    }
                }
            }
        }
    }
    if out.is_empty() {
        return Err(Error::invalid(format!(
            "stuffing produced no tetrahedron: the surface ({} faces) is thinner than the \
             spacing {h} mm or not closed",
            surface.n_faces()
        )));
    }

    // Compact to the used nodes, in global-id order.
    let mut new_id = vec![usize::MAX; nl + cuts.len()];
    for t in &out {
        for &g in t {
            new_id[g] = 0;
        }
    }
    let mut nodes = Vec::new();
    for (g, id) in new_id.iter_mut().enumerate() {
        if *id == 0 {
            *id = nodes.len();
            nodes.push(actual(g));
        }
    }
    let tets: Vec<[usize; 4]> = out.iter().map(|t| t.map(|g| new_id[g])).collect();
    let mut mesh = TetMesh { nodes, tets };

    // Boundary nodes exactly onto the surface.
    let boundary = mesh.boundary_nodes();
    let projected: Vec<Point> = boundary
        .par_iter()
        .map(|&v| {
            let p = mesh.nodes[v];
            tree.closest_point(&p).map(|c| c.point).unwrap_or(p)
        })
        .collect();
    for (&v, p) in boundary.iter().zip(projected) {
        mesh.nodes[v] = p;
    }
    Ok(mesh)
}

/// The part of one BCC tetrahedron `g` (lattice ids) on the + side, as tetrahedra passed to
/// `emit` (orientation is fixed there). `cut(a, b)` is the global id of the cut point on edge
/// `ab`; `inside(t)` decides a tetrahedron with four 0 vertices.
fn stencil(
    g: [usize; 4],
    sign: &[i8],
    cut: &impl Fn(usize, usize) -> usize,
    emit: &mut impl FnMut([usize; 4]),
    inside: &impl Fn([usize; 4]) -> bool,
) {
    let (mut p, mut m, mut z) = (Vec::new(), Vec::new(), Vec::new());
    for &v in &g {
        match sign[v] {
            1 => p.push(v),
            -1 => m.push(v),
            _ => z.push(v),
        }
    }
    match (p.len(), m.len()) {
        (0, 0) => {
            if inside(g) {
                emit(g)
            }
        }
        (0, _) => {}
        (_, 0) => emit(g),
        (1, _) => {
            // One + vertex: the corner tetrahedron at it.
            let mut t = [p[0]; 4];
            let rest: Vec<usize> = z
                .iter()
                .copied()
                .chain(m.iter().map(|&x| cut(p[0], x)))
                .collect();
            t[1..].copy_from_slice(&rest);
            emit(t);
        }
        (2, 1) => {
            // Pyramid: apex the 0 vertex, base on the face p0 p1 m.
            let q = [p[0], p[1], cut(p[1], m[0]), cut(p[0], m[0])];
            pyramid(z[0], q, emit);
        }
        (2, 2) => {
            let v = [
                p[0],
                cut(p[0], m[0]),
                cut(p[0], m[1]),
                p[1],
                cut(p[1], m[0]),
                cut(p[1], m[1]),
            ];
            prism(v, emit);
        }
        (3, 1) => {
            let v = [
                p[0],
                p[1],
                p[2],
                cut(p[0], m[0]),
                cut(p[1], m[0]),
                cut(p[2], m[0]),
            ];
            prism(v, emit);
        }
        _ => unreachable!("a tetrahedron has four vertices"),
    }
}

/// Split the pyramid with apex `a` over the quadrilateral `q` (cyclic) along the diagonal from
/// the quadrilateral's smallest id.
fn pyramid(a: usize, q: [usize; 4], emit: &mut impl FnMut([usize; 4])) {
    if q[0].min(q[2]) < q[1].min(q[3]) {
        emit([a, q[0], q[1], q[2]]);
        emit([a, q[0], q[2], q[3]]);
    } else {
        emit([a, q[1], q[2], q[3]]);
        emit([a, q[1], q[3], q[0]]);
    }
}

/// Split the prism `v` (`v[0..3]` one end, `v[i + 3]` joined to `v[i]`) into three
/// tetrahedra, every quadrilateral split along the diagonal from its smallest id (Dompierre et
/// al. 1999, section 3.2).
fn prism(v: [usize; 6], emit: &mut impl FnMut([usize; 4])) {
    let m = (0..6).min_by_key(|&i| v[i]).unwrap_or(0);
    // Rotate (and flip the ends if needed) so the smallest id is v[0].
    let (r, flip) = (m % 3, m >= 3);
    let w: [usize; 6] = std::array::from_fn(|i| {
        let end = (i >= 3) != flip;
        v[(i % 3 + r) % 3 + if end { 3 } else { 0 }]
    });
    if w[1].min(w[5]) < w[2].min(w[4]) {
        emit([w[0], w[1], w[2], w[5]]);
        emit([w[0], w[1], w[5], w[4]]);
    } else {
        emit([w[0], w[1], w[2], w[4]]);
        emit([w[0], w[4], w[2], w[5]]);
    }
    emit([w[0], w[4], w[5], w[3]]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::{cuboid, icosphere};

    fn check_on_surface(mesh: &TetMesh, surface: &TriMesh, tol: f64) {
        let tree = AabbTree::new(surface);
        for v in mesh.boundary_nodes() {
            let d = tree.distance(&mesh.nodes[v]).unwrap();
            assert!(d < tol, "boundary node {v} is {d} mm off the surface");
        }
    }

    /// A cube whose sides are whole numbers of lattice cells is filled exactly: its faces lie on
    /// lattice planes, so the stencils reproduce it (volume to rounding).
    #[test]
    fn cube_volume_exact() {
        for (side, h, offset) in [
            (12.0, 2.0, Vec3::zeros()),
            (12.0, 3.0, Vec3::new(3.3, -1.7, 0.45)),
            (10.0, 2.5, Vec3::new(-100.0, 20.25, 7.0)),
        ] {
            let mut cube = cuboid(side, side, side);
            for p in &mut cube.vertices {
                *p += offset;
            }
            let m = isosurface_stuffing(&cube, &StuffingParams::with_spacing(h)).unwrap();
            let exact = side * side * side;
            assert!(
                ((m.volume() - exact) / exact).abs() < 1e-9,
                "side {side} h {h}: volume {} vs {exact}",
                m.volume()
            );
            assert_eq!(m.inverted_count(), 0);
            check_on_surface(&m, &cube, 1e-9);
            // The boundary is a closed surface enclosing the same volume.
            let b = m.boundary_mesh();
            assert!(((b.signed_volume() - exact) / exact).abs() < 1e-9);
            // There are interior nodes.
            assert!(m.boundary_nodes().len() < m.n_nodes());
        }
    }

    /// A sphere: boundary on the surface, volume close to the polyhedron's (chords cut off
    /// only slivers of order h²/r), no inverted element, all dihedral angles in a sane range,
    /// and the same output twice.
    #[test]
    fn sphere_quality_and_determinism() {
        let s = icosphere(10.0, 4);
        let m = isosurface_stuffing(&s, &StuffingParams::with_spacing(2.0)).unwrap();
        let v = s.signed_volume();
        let rel = (m.volume() - v) / v;
        assert!(rel < 0.0 && rel > -0.03, "relative volume error {rel}");
        check_on_surface(&m, &s, 1e-9);
        let q = m.quality();
        assert_eq!(q.inverted, 0);
        assert!(q.min_dihedral_deg.min > 5.0, "{q:?}");
        assert!(q.max_dihedral_deg.max < 175.0, "{q:?}");
        // Interior tets are BCC tets: min dihedral 60°, max 90°.
        assert!((q.min_dihedral_deg.median - 60.0).abs() < 1e-6);
        let again = isosurface_stuffing(&s, &StuffingParams::with_spacing(2.0)).unwrap();
        assert_eq!(m, again);
        // Boundary faces enclose the tets' volume (closed, outward).
        assert!((m.boundary_mesh().signed_volume() - m.volume()).abs() < 1e-9 * v);
    }

    /// The ray-parity fallback agrees with the pseudo-normal sign away from the surface.
    #[test]
    fn parity_fallback_agrees_with_signed_distance() {
        let s = icosphere(10.0, 3);
        let tree = AabbTree::new(&s);
        let normals = PseudoNormals::new(&s);
        let mut rng = crate::rng::Rng::new(3);
        let mut checked = 0;
        for _ in 0..400 {
            let p = Point::from(rng.gauss3(8.0));
            let d = tree.signed_distance(&normals, &p).unwrap();
            if d.abs() > 0.05 {
                assert_eq!(inside_by_parity(&tree, &p), d < 0.0, "{p:?} {d}");
                checked += 1;
            }
        }
        assert!(checked > 300);
    }

    #[test]
    fn bad_parameters_are_errors() {
        let c = cuboid(1.0, 1.0, 1.0);
        for p in [
            StuffingParams::with_spacing(0.0),
            StuffingParams::with_spacing(f64::NAN),
            StuffingParams::with_spacing(1e-4),
            StuffingParams {
                alpha_long: 0.6,
                ..Default::default()
            },
        ] {
            let e = isosurface_stuffing(&c, &p).unwrap_err().to_string();
            assert!(!e.contains('\n'), "{e}");
        }
        let empty = TriMesh {
            vertices: vec![],
            faces: vec![],
        };
        assert!(isosurface_stuffing(&empty, &Default::default()).is_err());
        // Much thinner than the spacing: nothing inside.
        assert!(isosurface_stuffing(&c, &StuffingParams::with_spacing(10.0)).is_err());
    }
}
