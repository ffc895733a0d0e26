//! Marching tetrahedra: the level set of a scalar field sampled on a regular grid, as a closed
//! 2-manifold triangle mesh (Doi & Koide 1991, on the Kuhn triangulation of the grid).
//!
//! [`Grid`] holds the samples (fractions of a voxel inside a surface, in units of `1 / FULL`);
//! [`isosurface`] extracts a level. The simulated CT scan ([`crate::synth::voxel_scan`]), the
//! procedural hand and the generated grasp parts all mesh their fields here.

use super::{Point, TriMesh};
use crate::error::{Error, Result};

/// Value of a voxel that lies wholly inside the surface; occupancy is stored in units of
/// `1 / FULL`, so the quantisation step is 1.5e-5 of a voxel (8 nm at 0.5 mm).
pub const FULL: u16 = u16::MAX;

/// A regular grid of partial-volume occupancies, x-major with z fastest.
///
/// Node `(i, j, k)` sits at `(first + (i, j, k)) * voxel_mm` in mm and carries the fraction of
/// the cube of side `voxel_mm` centred on it that lies inside the surface, in units of
/// `1 / FULL`. Grid nodes are on integer multiples of the voxel size, so the same surface scanned
/// twice at the same voxel size is sampled at the same points wherever it lies.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    /// Voxel edge length, mm.
    pub voxel_mm: f64,
    /// Lattice index (in voxels from the origin) of node `(0, 0, 0)`.
    pub first: [i64; 3],
    /// Number of nodes along x, y and z.
    pub dims: [usize; 3],
    /// Occupancy of every node, index `(i * dims[1] + j) * dims[2] + k`.
    pub values: Vec<u16>,
}

impl Grid {
    /// Linear index of node `(i, j, k)` in [`Grid::values`].
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (i * self.dims[1] + j) * self.dims[2] + k
    }

    /// Position of node `(i, j, k)`, mm.
    pub fn position(&self, i: usize, j: usize, k: usize) -> Point {
        let h = self.voxel_mm;
        Point::new(
            (self.first[0] + i as i64) as f64 * h,
            (self.first[1] + j as i64) as f64 * h,
            (self.first[2] + k as i64) as f64 * h,
        )
    }

    /// Fraction in [0, 1] of the voxel centred on node `(i, j, k)` that is inside the surface.
    pub fn fraction(&self, i: usize, j: usize, k: usize) -> f64 {
        self.values[self.index(i, j, k)] as f64 / FULL as f64
    }

    /// The volume the scan measures, mm³: the sum of the voxel fractions times the voxel volume.
    pub fn volume(&self) -> f64 {
        let sum: u64 = self.values.iter().map(|&v| v as u64).sum();
        sum as f64 / FULL as f64 * self.voxel_mm.powi(3)
    }
}

/// One edge of the Kuhn triangulation as seen from a cube: the cube corner it starts from (bit 0
/// = +x, bit 1 = +y, bit 2 = +z) and its direction (the corner offset to its other end, 1..=7).
type CubeEdge = (u8, u8);

/// What marching tetrahedra emits in one tetrahedron for one inside/outside pattern.
#[derive(Clone, Copy, Debug)]
enum TetCase {
    Empty,
    /// One triangle, outward-oriented.
    Triangle([CubeEdge; 3]),
    /// One quadrilateral, outward-oriented, its vertices in cyclic order.
    Quad([CubeEdge; 4]),
}

/// The six tetrahedra of the Kuhn (Freudenthal) triangulation of the unit cube, as cube corners,
/// each positively oriented. They all share the diagonal from corner 0 to corner 7 and split each
/// face of the cube along its diagonal from its lowest to its highest corner, so neighbouring
/// cubes agree and the whole grid is triangulated (Kuhn 1960, "Some combinatorial lemmas in
/// topology").
pub fn kuhn_tetrahedra() -> [[u8; 4]; 6] {
    let axes = [
        [0, 1, 2],
        [0, 2, 1],
        [1, 0, 2],
        [1, 2, 0],
        [2, 0, 1],
        [2, 1, 0],
    ];
    axes.map(|[a0, a1, _]| {
        let c1 = 1u8 << a0;
        let mut tet = [0u8, c1, c1 | (1 << a1), 7];
        let corner = |c: u8| [(c & 1) as i64, ((c >> 1) & 1) as i64, ((c >> 2) & 1) as i64];
        let [p0, p1, p2, p3] = tet.map(corner);
        let d = |p: [i64; 3]| [p[0] - p0[0], p[1] - p0[1], p[2] - p0[2]];
        let (u, v, w) = (d(p1), d(p2), d(p3));
        let det = u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0])
            + u[2] * (v[0] * w[1] - v[1] * w[0]);
        if det < 0 {
            tet.swap(2, 3);
        }
        tet
    })
}

/// Marching-tetrahedra cases of a positively oriented tetrahedron `tet` (cube corners), indexed
/// by the mask of its inside vertices (bit q = vertex q). With (a, b, c, d) an even permutation
/// of the vertices, face (b, c, d) faces away from a, so one inside vertex a gives the triangle
/// (ab, ac, ad), one outside vertex a the reverse (ab, ad, ac), and inside a, b the quad
/// (ac, ad, bd, bc); all then face from inside to outside (Doi & Koide 1991, "An efficient method
/// of triangulating equi-valued surfaces by using tetrahedral cells").
fn tet_cases(tet: [u8; 4]) -> [TetCase; 16] {
    let edge = |p: usize, q: usize| -> CubeEdge {
        let (cp, cq) = (tet[p], tet[q]);
        // Kuhn simplices are chains: one corner's bits are a subset of the other's.
        let lo = if cp & cq == cp { cp } else { cq };
        (lo, cp ^ cq)
    };
    let mut perms = Vec::new();
    for a in 0..4 {
        for b in 0..4 {
            for c in 0..4 {
                for d in 0..4 {
                    let p = [a, b, c, d];
                    let distinct = (0..4).all(|i| (i + 1..4).all(|j| p[i] != p[j]));
                    let inversions = (0..4)
                        .flat_map(|i| (i + 1..4).map(move |j| (i, j)))
                        .filter(|&(i, j)| p[i] > p[j])
                        .count();
                    if distinct && inversions % 2 == 0 {
                        perms.push(p);
                    }
                }
            }
        }
    }
    let mut cases = [TetCase::Empty; 16];
    for (mask, case) in cases.iter_mut().enumerate() {
        let inside = |q: usize| mask >> q & 1 == 1;
        let n_in = (0..4).filter(|&q| inside(q)).count();
        *case = match n_in {
            1 | 3 => {
                let lone = (0..4).find(|&q| inside(q) == (n_in == 1)).unwrap_or(0);
                let [a, b, c, d] = *perms.iter().find(|p| p[0] == lone).unwrap_or(&[0, 1, 2, 3]);
                if n_in == 1 {
                    TetCase::Triangle([edge(a, b), edge(a, c), edge(a, d)])
                } else {
                    TetCase::Triangle([edge(a, b), edge(a, d), edge(a, c)])
                }
            }
            2 => {
                let [a, b, c, d] = *perms
                    .iter()
                    .find(|p| inside(p[0]) && inside(p[1]))
                    .unwrap_or(&[0, 1, 2, 3]);
                TetCase::Quad([edge(a, c), edge(a, d), edge(b, d), edge(b, c)])
            }
            _ => TetCase::Empty,
        };
    }
    cases
}

/// No vertex yet on this edge.
const NO_VERTEX: u32 = u32::MAX;

/// The `iso` level set (a fraction in (0, 1)) of a [`Grid`], by marching tetrahedra.
///
/// Method: every cube of eight nodes with nodes on both sides of the level is split into the six
/// Kuhn tetrahedra ([`kuhn_tetrahedra`]); in each, the level set of the linear interpolant of
/// its four values is a triangle or a quadrilateral (split along its shorter diagonal) with
/// vertices on the tetrahedron's edges, placed by linear interpolation (Doi & Koide 1991). As the
/// tetrahedra triangulate the grid and a node is never on the level (a value equal to it counts
/// as inside: symbolic perturbation), the result is the level set of a piecewise-linear function
/// and therefore a closed 2-manifold when all boundary nodes are outside; each triangle faces
/// from the inside (values above `iso`) outwards. Vertices are shared through their grid edge
/// and numbered in scan order (x-major, then y, then z), so the output is deterministic.
///
/// Errors: `iso` outside (0, 1), a malformed grid, or an inside node on the grid boundary.
pub fn isosurface(grid: &Grid, iso: f64) -> Result<TriMesh> {
    if !(iso > 0.0 && iso < 1.0) {
        return Err(Error::invalid(format!(
            "isosurface: level {iso} is not a fraction strictly between 0 and 1"
        )));
    }
    let [nx, ny, nz] = grid.dims;
    if nx < 2
        || ny < 2
        || nz < 2
        || nx.checked_mul(ny).and_then(|n| n.checked_mul(nz)) != Some(grid.values.len())
    {
        return Err(Error::invalid(format!(
            "isosurface: a grid of {nx} x {ny} x {nz} nodes cannot hold {} values (each side needs 2 or more nodes)",
            grid.values.len()
        )));
    }
    if !(grid.voxel_mm.is_finite() && grid.voxel_mm > 0.0) {
        return Err(Error::invalid(format!(
            "isosurface: voxel size {} mm is not a positive number",
            grid.voxel_mm
        )));
    }
    let level = iso * FULL as f64;
    let inside = |v: u16| v as f64 >= level;
    let values = &grid.values;
    for i in 0..nx {
        for j in 0..ny {
            let on_side = i == 0 || i == nx - 1 || j == 0 || j == ny - 1;
            for k in 0..nz {
                if (on_side || k == 0 || k == nz - 1) && inside(values[grid.index(i, j, k)]) {
                    return Err(Error::invalid(format!(
                        "isosurface: boundary node ({i}, {j}, {k}) is inside the level; pad the grid with outside nodes"
                    )));
                }
            }
        }
    }

    // Per column (i, j): 0 all outside, 1 all inside, 2 mixed; cubes between four columns in the
    // same uniform state cannot straddle the level and are skipped wholesale.
    let column_state: Vec<u8> = values
        .chunks(nz)
        .map(|col| {
            let n_in = col.iter().filter(|&&v| inside(v)).count();
            match n_in {
                0 => 0,
                n if n == nz => 1,
                _ => 2,
            }
        })
        .collect();

    let tets = kuhn_tetrahedra();
    let cases: Vec<[TetCase; 16]> = tets.iter().map(|&t| tet_cases(t)).collect();
    let (sx, sy) = (ny * nz, nz);
    let corner_offset =
        |c: u8| (c & 1) as usize * sx + ((c >> 1) & 1) as usize * sy + ((c >> 2) & 1) as usize;
    let offsets: [usize; 8] = std::array::from_fn(|c| corner_offset(c as u8));
    let h = grid.voxel_mm;

    // Vertex of each edge whose start node lies in the cube slab's lower x plane (`lower`) and
    // upper x plane (`upper`); slot (j * nz + k) * 8 + direction.
    let mut lower = vec![NO_VERTEX; ny * nz * 8];
    let mut upper = vec![NO_VERTEX; ny * nz * 8];
    let mut vertices: Vec<Point> = Vec::new();
    let mut faces: Vec<[usize; 3]> = Vec::new();
    let vertex_of = |lower: &mut [u32],
                     upper: &mut [u32],
                     vertices: &mut Vec<Point>,
                     (i, j, k): (usize, usize, usize),
                     (c, dir): CubeEdge|
     -> usize {
        let (di, dj, dk) = (
            (c & 1) as usize,
            ((c >> 1) & 1) as usize,
            ((c >> 2) & 1) as usize,
        );
        let slot = ((j + dj) * nz + k + dk) * 8 + dir as usize;
        let table = if di == 1 { upper } else { lower };
        if table[slot] == NO_VERTEX {
            let (a, b) = (
                (i + di, j + dj, k + dk),
                (dir & 1, (dir >> 1) & 1, (dir >> 2) & 1),
            );
            let va = values[grid.index(a.0, a.1, a.2)] as f64;
            let vb = values[grid.index(a.0 + b.0 as usize, a.1 + b.1 as usize, a.2 + b.2 as usize)]
                as f64;
            let t = (level - va) / (vb - va);
            let pa = grid.position(a.0, a.1, a.2);
            let step = nalgebra::Vector3::new(b.0 as f64, b.1 as f64, b.2 as f64) * h;
            table[slot] = vertices.len() as u32;
            vertices.push(pa + step * t);
        }
        table[slot] as usize
    };

    for i in 0..nx - 1 {
        for j in 0..ny - 1 {
            let states = [
                column_state[i * ny + j],
                column_state[i * ny + j + 1],
                column_state[(i + 1) * ny + j],
                column_state[(i + 1) * ny + j + 1],
            ];
            if states[0] != 2 && states.iter().all(|&s| s == states[0]) {
                continue;
            }
            for k in 0..nz - 1 {
                let base = grid.index(i, j, k);
                let mut mask = 0u8;
                for (c, off) in offsets.iter().enumerate() {
                    if inside(values[base + off]) {
                        mask |= 1 << c;
                    }
                }
                if mask == 0 || mask == 0xff {
                    continue;
                }
                for (t, tet) in tets.iter().enumerate() {
                    let m = tet
                        .iter()
                        .enumerate()
                        .fold(0usize, |m, (q, &c)| m | (((mask >> c) & 1) as usize) << q);
                    match cases[t][m] {
                        TetCase::Empty => {}
                        TetCase::Triangle(edges) => {
                            let f = edges.map(|e| {
                                vertex_of(&mut lower, &mut upper, &mut vertices, (i, j, k), e)
                            });
                            faces.push(f);
                        }
                        TetCase::Quad(edges) => {
                            let q = edges.map(|e| {
                                vertex_of(&mut lower, &mut upper, &mut vertices, (i, j, k), e)
                            });
                            let d02 = (vertices[q[0]] - vertices[q[2]]).norm_squared();
                            let d13 = (vertices[q[1]] - vertices[q[3]]).norm_squared();
                            if d02 <= d13 {
                                faces.push([q[0], q[1], q[2]]);
                                faces.push([q[0], q[2], q[3]]);
                            } else {
                                faces.push([q[1], q[2], q[3]]);
                                faces.push([q[1], q[3], q[0]]);
                            }
                        }
                    }
                }
            }
        }
        // Edges starting in the upper plane become the next slab's lower-plane edges; those
        // along x are created only from the next slab, so every slot of it is still unset there.
        std::mem::swap(&mut lower, &mut upper);
        upper.fill(NO_VERTEX);
    }
    TriMesh::new(vertices, faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Vec3;
    use std::collections::HashMap;

    #[test]
    fn tet_table_is_a_consistent_triangulation() {
        // Kuhn tetrahedra: positive, volume 1/6 each, and every face not on the cube's surface
        // is shared by exactly two of them with opposite orientation.
        let tets = kuhn_tetrahedra();
        let corner =
            |c: u8| Vec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64);
        let mut faces: HashMap<[u8; 3], i32> = HashMap::new();
        for t in &tets {
            let p = t.map(corner);
            let det = (p[1] - p[0]).cross(&(p[2] - p[0])).dot(&(p[3] - p[0]));
            assert!((det - 1.0).abs() < 1e-12, "tet {t:?} has det {det}");
            for skip in 0..4 {
                let mut f: Vec<u8> = (0..4).filter(|&q| q != skip).map(|q| t[q]).collect();
                f.sort();
                *faces.entry([f[0], f[1], f[2]]).or_default() += 1;
            }
        }
        let on_cube_surface = |f: &[u8; 3]| {
            (0..3).any(|axis| {
                let bits: Vec<u8> = f.iter().map(|c| (c >> axis) & 1).collect();
                bits.iter().all(|&b| b == bits[0])
            })
        };
        for (f, n) in &faces {
            assert_eq!(*n, if on_cube_surface(f) { 1 } else { 2 }, "face {f:?}");
        }
    }

    #[test]
    fn tet_cases_face_outwards() {
        // For every case, the emitted surface's normal must point from inside to outside
        // vertices: check against the gradient of the linear interpolant with values 1 / 0.
        let corner =
            |c: u8| Vec3::new((c & 1) as f64, ((c >> 1) & 1) as f64, ((c >> 2) & 1) as f64);
        let pos = |(c, d): CubeEdge| (corner(c) + corner(c ^ d)) / 2.0;
        for tet in kuhn_tetrahedra() {
            let cases = tet_cases(tet);
            for (mask, case) in cases.iter().enumerate().take(15).skip(1) {
                let normal = match *case {
                    TetCase::Triangle(e) => {
                        let p = e.map(pos);
                        (p[1] - p[0]).cross(&(p[2] - p[0]))
                    }
                    TetCase::Quad(e) => {
                        let p = e.map(pos);
                        (p[2] - p[0]).cross(&(p[3] - p[1]))
                    }
                    TetCase::Empty => panic!("mask {mask} is a crossing case"),
                };
                let centre_in: Vec3 = (0..4)
                    .filter(|q| mask >> q & 1 == 1)
                    .map(|q| corner(tet[q]))
                    .sum::<Vec3>()
                    / mask.count_ones() as f64;
                let centre_out: Vec3 = (0..4)
                    .filter(|q| mask >> q & 1 == 0)
                    .map(|q| corner(tet[q]))
                    .sum::<Vec3>()
                    / (4 - mask.count_ones()) as f64;
                assert!(
                    normal.dot(&(centre_out - centre_in)) > 0.0,
                    "tet {tet:?} mask {mask}"
                );
            }
        }
    }
}
