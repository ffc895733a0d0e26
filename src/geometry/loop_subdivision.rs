//! Loop subdivision of triangle meshes, with the stencil kept so that per-vertex attributes
//! (skin weights, colours, landmark indicators) follow the surface exactly as positions do.
//!
//! Reference: C. Loop, *Smooth Subdivision Surfaces Based on Triangles*, M.S. thesis, University
//! of Utah, 1987, with the boundary rules of Hoppe et al., *Piecewise Smooth Surface
//! Reconstruction*, SIGGRAPH 1994 (boundary curves are cubic B-splines); see also Zorin & Schröder,
//! *Subdivision for Modeling and Animation*, SIGGRAPH 2000 course notes, ch. 4.

use super::{Point, Topology, TriMesh, Vec3};
use std::f64::consts::PI;

/// The result of subdividing: the finer mesh, and for every one of its vertices the affine
/// combination of source-mesh vertices that produced it.
#[derive(Clone, Debug)]
pub struct Subdivision {
    /// The subdivided mesh.
    pub mesh: TriMesh,
    /// The stencil: for every vertex of `mesh`, the `(source vertex, weight)` pairs, sorted by
    /// source vertex; the weights are non-negative and sum to 1.
    pub stencil: Vec<Vec<(usize, f64)>>,
    /// Number of vertices of the source mesh, i.e. the length `apply` expects.
    pub source_vertices: usize,
}

impl Subdivision {
    /// Carry per-vertex attributes through the same stencil (linear; e.g. skin weights, colours):
    /// `out[i] = Σ w · values[j]` over `stencil[i]`. Positions themselves satisfy
    /// `mesh.vertices == apply(source.vertices)`.
    ///
    /// # Panics
    /// If `values.len() != self.source_vertices` (a programming error, not a data error).
    pub fn apply<T>(&self, values: &[T]) -> Vec<T>
    where
        T: Copy + Default + std::ops::Add<Output = T> + std::ops::Mul<f64, Output = T>,
    {
        assert_eq!(
            values.len(),
            self.source_vertices,
            "Subdivision::apply: one value per source vertex is needed"
        );
        self.stencil
            .iter()
            .map(|row| {
                row.iter()
                    .fold(T::default(), |acc, &(j, w)| acc + values[j] * w)
            })
            .collect()
    }

    /// Carry sparse weights (skinning) through the stencil: every source vertex has a list of
    /// `(influence, weight)`; for every new vertex the lists are blended with the stencil weights,
    /// entries below 1e-6 of the total are dropped, the `max` largest are kept (ties: lower
    /// influence index first) and renormalised to sum 1. The result is sorted by decreasing
    /// weight. A vertex whose sources carry no weight gets an empty list.
    ///
    /// # Panics
    /// If `values.len() != self.source_vertices`.
    pub fn apply_sparse(&self, values: &[Vec<(usize, f64)>], max: usize) -> Vec<Vec<(usize, f64)>> {
        assert_eq!(
            values.len(),
            self.source_vertices,
            "Subdivision::apply_sparse: one weight list per source vertex is needed"
        );
        let mut acc: Vec<(usize, f64)> = Vec::new();
        self.stencil
            .iter()
            .map(|row| {
                acc.clear();
                for &(j, w) in row {
                    for &(k, x) in &values[j] {
                        match acc.iter_mut().find(|(i, _)| *i == k) {
                            Some(e) => e.1 += w * x,
                            None => acc.push((k, w * x)),
                        }
                    }
                }
                let total: f64 = acc.iter().map(|e| e.1).sum();
                if total.is_nan() || total <= 0.0 {
                    return Vec::new();
                }
                let mut kept: Vec<(usize, f64)> = acc
                    .iter()
                    .copied()
                    .filter(|&(_, x)| x > 1e-6 * total)
                    .collect();
                kept.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
                kept.truncate(max);
                let s: f64 = kept.iter().map(|e| e.1).sum();
                if s.is_nan() || s <= 0.0 {
                    return Vec::new();
                }
                kept.iter_mut().for_each(|e| e.1 /= s);
                kept
            })
            .collect()
    }
}

/// Loop's even-vertex weight for an interior vertex of valence `n` (Loop 1987, §3.2):
/// `β(n) = (1/n) (5/8 − (3/8 + 1/4 cos(2π/n))²)`; the vertex keeps `1 − nβ`.
///
/// Loop's original β rather than Warren's simplification (3/(8n)) because it gives the
/// smoother limit surface (bounded curvature at regular vertices, best-behaved at the
/// extraordinary ones) and has the closed-form limit position used in the tests.
pub(crate) fn loop_beta(n: usize) -> f64 {
    let n = n as f64;
    let c = 3.0 / 8.0 + 0.25 * (2.0 * PI / n).cos();
    (5.0 / 8.0 - c * c) / n
}

/// Loop (1987) subdivision, one level.
///
/// - Vertices: the `n` original vertices keep their indices `0..n` and are repositioned by the
///   even-vertex rule: interior `(1 − nβ) v + β Σ ring` with Loop's original β ([`loop_beta`]);
///   on a boundary (exactly two incident edges with one face each) the cubic B-spline rule
///   `3/4 v + 1/8 (a + b)` over the two boundary neighbours; any other configuration (a corner
///   of non-manifold edges, or a vertex used by no face) stays where it is.
/// - One new vertex per edge, appended in the order of [`Topology::edges`] (vertex `n + e` for
///   edge `e`): interior edge `3/8 (a + b) + 1/8 (c + d)` with `c`, `d` the opposite vertices
///   of its two faces; boundary and non-manifold edges take the midpoint `1/2 (a + b)`.
/// - Face `k = [a, b, c]` with edge vertices `ab`, `bc`, `ca` becomes faces `4k..4k+3`:
///   `[a, ab, ca]`, `[ab, b, bc]`, `[ca, bc, c]`, `[ab, bc, ca]` (corner children in corner
///   order, then the middle one), all with the parent's orientation.
///
/// Loop subdivision is approximating: original vertices move toward the limit surface.
/// Cost is linear in the mesh size (one [`Topology`] build).
pub fn loop_subdivide(mesh: &TriMesh) -> Subdivision {
    let topo = Topology::new(mesh);
    let n = mesh.n_vertices();
    let ne = topo.edges.len();

    // An edge is "sharp" for the even rule when it does not have exactly two faces.
    let sharp = |e: usize| topo.edge_faces[e].len() != 2;
    // Sharp edges at each vertex, as neighbours.
    let mut sharp_nbrs: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (e, &[a, b]) in topo.edges.iter().enumerate() {
        if sharp(e) {
            sharp_nbrs[a].push(b);
            sharp_nbrs[b].push(a);
        }
    }

    let mut stencil: Vec<Vec<(usize, f64)>> = Vec::with_capacity(n + ne);
    for (v, ring) in topo.vertex_rings.iter().enumerate() {
        let row = match (topo.vertex_faces[v].is_empty(), sharp_nbrs[v].as_slice()) {
            (false, []) => {
                let beta = loop_beta(ring.len());
                let mut row = Vec::with_capacity(ring.len() + 1);
                row.push((v, 1.0 - ring.len() as f64 * beta));
                row.extend(ring.iter().map(|&r| (r, beta)));
                row
            }
            (false, &[a, b]) => vec![(v, 0.75), (a, 0.125), (b, 0.125)],
            _ => vec![(v, 1.0)],
        };
        stencil.push(sorted(row));
    }
    for (e, &[a, b]) in topo.edges.iter().enumerate() {
        let row = if sharp(e) {
            vec![(a, 0.5), (b, 0.5)]
        } else {
            let opposite = |f: usize| {
                let t = topo.faces[f];
                t.into_iter().find(|&x| x != a && x != b).unwrap_or(a)
            };
            let fs = &topo.edge_faces[e];
            vec![
                (a, 0.375),
                (b, 0.375),
                (opposite(fs[0]), 0.125),
                (opposite(fs[1]), 0.125),
            ]
        };
        stencil.push(sorted(row));
    }

    let vertices = stencil
        .iter()
        .map(|row| {
            Point::from(row.iter().fold(Vec3::zeros(), |acc, &(j, w)| {
                acc + mesh.vertices[j].coords * w
            }))
        })
        .collect();

    let mut faces = Vec::with_capacity(4 * mesh.n_faces());
    for (f, &[a, b, c]) in mesh.faces.iter().enumerate() {
        let [ab, bc, ca] = topo.face_edges[f].map(|e| n + e);
        faces.push([a, ab, ca]);
        faces.push([ab, b, bc]);
        faces.push([ca, bc, c]);
        faces.push([ab, bc, ca]);
    }

    Subdivision {
        mesh: TriMesh { vertices, faces },
        stencil,
        source_vertices: n,
    }
}

/// `levels` rounds of [`loop_subdivide`], with the stencils composed so that
/// [`Subdivision::apply`] maps attributes of the *original* mesh straight to the finest one.
/// `levels = 0` returns the mesh itself with the identity stencil.
pub fn loop_subdivide_n(mesh: &TriMesh, levels: usize) -> Subdivision {
    let n0 = mesh.n_vertices();
    let mut result = Subdivision {
        mesh: mesh.clone(),
        stencil: (0..n0).map(|v| vec![(v, 1.0)]).collect(),
        source_vertices: n0,
    };
    // Dense scratch accumulator over the original vertices, touched entries tracked, so that
    // composing costs O(stencil sizes) rather than O(n0) per row.
    let mut acc = vec![0.0; n0];
    let mut touched: Vec<usize> = Vec::new();
    for _ in 0..levels {
        let step = loop_subdivide(&result.mesh);
        let composed = step
            .stencil
            .iter()
            .map(|row| {
                for &(mid, w) in row {
                    for &(orig, x) in &result.stencil[mid] {
                        if acc[orig] == 0.0 {
                            touched.push(orig);
                        }
                        acc[orig] += w * x;
                    }
                }
                touched.sort_unstable();
                let out: Vec<(usize, f64)> = touched
                    .drain(..)
                    .map(|j| (j, std::mem::take(&mut acc[j])))
                    .filter(|&(_, x)| x != 0.0)
                    .collect();
                out
            })
            .collect();
        result = Subdivision {
            mesh: step.mesh,
            stencil: composed,
            source_vertices: n0,
        };
    }
    result
}

/// A stencil row sorted by source vertex with repeated vertices merged (a vertex can appear
/// twice as "opposite" when a face pair is degenerate).
fn sorted(mut row: Vec<(usize, f64)>) -> Vec<(usize, f64)> {
    row.sort_by_key(|e| e.0);
    let mut out: Vec<(usize, f64)> = Vec::with_capacity(row.len());
    for (j, w) in row {
        match out.last_mut() {
            Some(last) if last.0 == j => last.1 += w,
            _ => out.push((j, w)),
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::{cuboid, grid};

    /// Regular icosahedron with unit circumradius, outward CCW faces.
    fn icosahedron() -> TriMesh {
        let m = crate::geometry::mesh::tests::icosphere(1.0, 0);
        assert!(m.signed_volume() > 0.0);
        m
    }

    /// Largest angle (radians) between the normals of two faces sharing an edge.
    fn max_dihedral(m: &TriMesh) -> f64 {
        let n = m.face_normals();
        let t = m.topology();
        t.edge_faces
            .iter()
            .map(|fs| n[fs[0]].angle(&n[fs[1]]))
            .fold(0.0, f64::max)
    }

    #[test]
    fn closed_mesh_counts_and_topology() {
        for m in [icosahedron(), cuboid(1.0, 2.0, 3.0)] {
            let t = m.topology();
            let s = loop_subdivide(&m);
            assert_eq!(s.mesh.n_vertices(), m.n_vertices() + t.edges.len());
            assert_eq!(s.mesh.n_faces(), 4 * m.n_faces());
            s.mesh.check_closed_manifold().unwrap();
            assert_eq!(
                s.mesh.topology().euler_characteristic(),
                t.euler_characteristic()
            );
            assert!(s.mesh.signed_volume() > 0.0, "orientation kept outward");
            // Children of face k are 4k..4k+3 and touch only that face's vertices and edges.
            for (k, &[a, b, c]) in m.faces.iter().enumerate() {
                assert_eq!(s.mesh.faces[4 * k][0], a);
                assert_eq!(s.mesh.faces[4 * k + 1][1], b);
                assert_eq!(s.mesh.faces[4 * k + 2][2], c);
            }
            // Edge vertex n+e lies on edge e's stencil.
            for (e, &[a, b]) in t.edges.iter().enumerate() {
                let row = &s.stencil[m.n_vertices() + e];
                assert!(row
                    .iter()
                    .any(|&(j, w)| j == a && (w - 0.375).abs() < 1e-15));
                assert!(row
                    .iter()
                    .any(|&(j, w)| j == b && (w - 0.375).abs() < 1e-15));
            }
        }
    }

    #[test]
    fn stencils_are_convex_and_reproduce_positions() {
        let m = icosahedron();
        let s = loop_subdivide_n(&m, 3);
        for row in &s.stencil {
            let sum: f64 = row.iter().map(|e| e.1).sum();
            assert!((sum - 1.0).abs() < 1e-12);
            assert!(row.iter().all(|e| e.1 > 0.0));
        }
        let p = s.apply(&m.vertices.iter().map(|p| p.coords).collect::<Vec<_>>());
        for (a, b) in p.iter().zip(&s.mesh.vertices) {
            assert!((a - b.coords).norm() < 1e-12);
        }
        let open = grid(3, Point::origin(), Vec3::x(), Vec3::y());
        for row in &loop_subdivide(&open).stencil {
            assert!((row.iter().map(|e| e.1).sum::<f64>() - 1.0).abs() < 1e-15);
        }
    }

    #[test]
    fn planar_mesh_stays_planar_and_open_boundary_behaves() {
        let u = Vec3::new(1.0, 0.5, 0.2);
        let v = Vec3::new(-0.3, 1.0, 0.7);
        let normal = u.cross(&v).normalize();
        let origin = Point::new(3.0, -2.0, 5.0);
        let m = grid(4, origin, u, v);
        let t = m.topology();
        let s = loop_subdivide_n(&m, 2);
        for p in &s.mesh.vertices {
            assert!((p - origin).dot(&normal).abs() < 1e-12);
        }
        // Counts still hold on an open mesh; Euler characteristic of a disc is 1.
        let one = loop_subdivide(&m);
        assert_eq!(one.mesh.n_vertices(), m.n_vertices() + t.edges.len());
        assert_eq!(one.mesh.topology().euler_characteristic(), 1);
        assert_eq!(
            one.mesh.topology().boundary_edges().len(),
            2 * t.boundary_edges().len()
        );
        // Boundary rule: a vertex in the middle of a straight boundary side stays on that side
        // and, the side being uniformly sampled, does not move at all (B-spline of a line).
        let mid_bottom = 2; // (i=2, j=0)
        assert!((one.mesh.vertices[mid_bottom] - m.vertices[mid_bottom]).norm() < 1e-12);
    }

    #[test]
    fn icosahedron_converges_to_closed_form_limit() {
        let m = icosahedron();
        // Limit position of a valence-n vertex (Loop 1987; Hoppe et al. 1994):
        // v∞ = (1 − nχ) v + χ Σ ring, χ = 1 / (3/(8β) + n). For the icosahedron the five
        // neighbours of a unit vertex sum to 5 (v·r) v with v·r = 1/√5, so |v∞| is closed-form.
        let beta = loop_beta(5);
        let chi = 1.0 / (3.0 / (8.0 * beta) + 5.0);
        let r_inf = 1.0 - 5.0 * chi * (1.0 - 1.0 / 5f64.sqrt());
        // The (vertex, ring mean) pair contracts with eigenvalue 5/8 − nβ per level.
        let lambda = 5.0 / 8.0 - 5.0 * beta;
        let mut err_prev = 1.0 - r_inf;
        // Convergence toward a smooth surface: the largest angle between neighbouring face
        // normals and the largest move of a surviving vertex both shrink every level (the
        // limit is not a sphere, so the radial spread itself does not go to zero).
        let mut crease_prev = max_dihedral(&m);
        let mut move_prev = f64::INFINITY;
        let mut vol_prev = m.signed_volume();
        let mut mesh = m.clone();
        for _ in 0..5 {
            let next = loop_subdivide(&mesh).mesh;
            let moved = (0..mesh.n_vertices())
                .map(|i| (next.vertices[i] - mesh.vertices[i]).norm())
                .fold(0.0, f64::max);
            assert!(moved < 0.5 * move_prev, "{moved} {move_prev}");
            move_prev = moved;
            mesh = next;
            let err = mesh.vertices[0].coords.norm() - r_inf;
            assert!((err / err_prev - lambda).abs() < 1e-9, "{err} {err_prev}");
            err_prev = err;
            let crease = max_dihedral(&mesh);
            assert!(crease < 0.75 * crease_prev, "{crease} {crease_prev}");
            crease_prev = crease;
            let vol = mesh.signed_volume();
            assert!(vol < vol_prev, "Loop shrinks a convex control mesh");
            vol_prev = vol;
        }
        // The limit surface lies inside the control polyhedron (convex combinations) and
        // contains the ball through the limit of the original vertices' smallest radius.
        let normals = m.face_normals();
        for p in &mesh.vertices {
            for (f, n) in m.faces.iter().zip(&normals) {
                assert!((p - m.vertices[f[0]]).dot(n) <= 1e-12);
            }
        }
        let r_min = mesh
            .vertices
            .iter()
            .map(|p| p.coords.norm())
            .fold(f64::INFINITY, f64::min);
        let ball_in = 4.0 / 3.0 * PI * (r_min * 0.99).powi(3);
        assert!(vol_prev > ball_in && vol_prev < m.signed_volume());
    }

    #[test]
    fn attributes_constant_and_linear() {
        let m = grid(
            3,
            Point::new(1.0, 2.0, 0.0),
            Vec3::x() * 2.0,
            Vec3::y() * 1.5,
        );
        let s = loop_subdivide_n(&m, 2);
        let c = s.apply(&vec![3.25_f64; m.n_vertices()]);
        assert!(c.iter().all(|&x| (x - 3.25).abs() < 1e-12));
        // A linear function of position: f(p) = 2x − 3y + 7. Subdividing its samples must give
        // f at the subdivided positions, interior and boundary alike.
        let f = |p: &Point| 2.0 * p.x - 3.0 * p.y + 7.0;
        let vals: Vec<f64> = m.vertices.iter().map(f).collect();
        for (x, p) in s.apply(&vals).iter().zip(&s.mesh.vertices) {
            assert!((x - f(p)).abs() < 1e-10);
        }
    }

    #[test]
    fn sparse_weights_blend_and_renormalise() {
        let m = icosahedron();
        // Vertex 0 fully bound to bone 7, every other to bone 2 (0.6) and bone 4 (0.4).
        let w: Vec<Vec<(usize, f64)>> = (0..m.n_vertices())
            .map(|v| {
                if v == 0 {
                    vec![(7, 1.0)]
                } else {
                    vec![(2, 0.6), (4, 0.4)]
                }
            })
            .collect();
        let s = loop_subdivide(&m);
        let out = s.apply_sparse(&w, 4);
        let dense7 = s.apply(
            &(0..m.n_vertices())
                .map(|v| if v == 0 { 1.0 } else { 0.0 })
                .collect::<Vec<f64>>(),
        );
        for (i, list) in out.iter().enumerate() {
            assert!((list.iter().map(|e| e.1).sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(list.windows(2).all(|p| p[0].1 >= p[1].1));
            let w7 = list.iter().find(|e| e.0 == 7).map_or(0.0, |e| e.1);
            assert!((w7 - dense7[i]).abs() < 1e-12);
        }
        // Keeping one influence: the largest, at weight 1.
        let one = s.apply_sparse(&w, 1);
        assert_eq!(one[0], vec![(7, 1.0)]);
        assert_eq!(one[5], vec![(2, 1.0)]);
    }

    #[test]
    fn composed_stencil_matches_sequential_application() {
        let m = cuboid(2.0, 1.0, 1.0);
        let vals: Vec<f64> = (0..m.n_vertices()).map(|v| (v * v) as f64).collect();
        let s1 = loop_subdivide(&m);
        let s2 = loop_subdivide(&s1.mesh);
        let seq = s2.apply(&s1.apply(&vals));
        let both = loop_subdivide_n(&m, 2);
        assert_eq!(both.mesh, s2.mesh);
        for (a, b) in seq.iter().zip(both.apply(&vals)) {
            assert!((a - b).abs() < 1e-12);
        }
        let zero = loop_subdivide_n(&m, 0);
        assert_eq!(zero.mesh, m);
        assert_eq!(zero.apply(&vals), vals);
    }
}
