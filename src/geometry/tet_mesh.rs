//! Tetrahedral meshes: volume, boundary, and element quality.
//!
//! Quality measures follow Shewchuk, "What is a good linear finite element?" (2002): the
//! dihedral angles (small ones spoil interpolation and conditioning, large ones the gradient
//! error) and the radius-edge ratio `R / l_min` (circumradius over shortest edge; `sqrt(6)/4 ≈
//! 0.612` for the regular tetrahedron, unbounded for slivers' cousins but not for slivers).

use crate::error::{Error, Result};
use crate::geometry::{Point, TriMesh, Vec3};
use rayon::prelude::*;
use serde::Serialize;

/// Named groups of a tetrahedral mesh for finite-element users: each tetrahedron's group
/// (a material region) and the boundary triangles (where loads and contact go), each with
/// its tetrahedron's group, as Gmsh's physical groups and VTK cell data carry them.
#[derive(Clone, Debug, PartialEq)]
pub struct TetGroups {
    /// Group names, indexed by group id.
    pub names: Vec<String>,
    /// Per tetrahedron, its group id (index into `names`).
    pub tet_group: Vec<u32>,
    /// The boundary: the faces of exactly one tetrahedron, wound counter-clockwise seen from
    /// outside that tetrahedron ([`TetMesh::boundary_faces_with_tets`]), each with that
    /// tetrahedron's group id; in tetrahedron order.
    pub boundary: Vec<([usize; 3], u32)>,
}

impl TetGroups {
    /// The groups of `mesh` with `tet_group` (one id per tetrahedron, each an index into
    /// `names`); the boundary is computed. Errors ([`Error::Invalid`]) on a count or an id out of
    /// range.
    pub fn new(mesh: &TetMesh, names: Vec<String>, tet_group: Vec<u32>) -> Result<TetGroups> {
        let g = TetGroups {
            boundary: mesh
                .boundary_faces_with_tets()
                .into_iter()
                .map(|(f, t)| (f, tet_group.get(t).copied().unwrap_or(0)))
                .collect(),
            names,
            tet_group,
        };
        g.check(mesh)?;
        Ok(g)
    }

    /// Whether these groups fit `mesh`: one id per tetrahedron, ids and boundary nodes in
    /// range (what a writer checks before it starts).
    pub fn check(&self, mesh: &TetMesh) -> Result<()> {
        if self.tet_group.len() != mesh.n_tets() {
            return Err(Error::invalid(format!(
                "tet groups: {} group ids for {} tetrahedra",
                self.tet_group.len(),
                mesh.n_tets()
            )));
        }
        let n = self.names.len() as u32;
        let bad_id = self
            .tet_group
            .iter()
            .chain(self.boundary.iter().map(|b| &b.1))
            .find(|&&g| g >= n);
        if let Some(g) = bad_id {
            return Err(Error::invalid(format!(
                "tet groups: group id {g}, but there are {n} names"
            )));
        }
        if let Some((f, _)) = self
            .boundary
            .iter()
            .find(|(f, _)| f.iter().any(|&v| v >= mesh.n_nodes()))
        {
            return Err(Error::invalid(format!(
                "tet groups: boundary face {f:?} names a node beyond the mesh's {}",
                mesh.n_nodes()
            )));
        }
        Ok(())
    }
}

/// A tetrahedral mesh in mm. Every tetrahedron `[a, b, c, d]` is positively oriented:
/// `(b - a) · ((c - a) × (d - a)) > 0` (checked by [`TetMesh::inverted_count`]).
#[derive(Clone, Debug, PartialEq)]
pub struct TetMesh {
    /// Node positions, mm.
    pub nodes: Vec<Point>,
    /// Tetrahedra as indices into `nodes`.
    pub tets: Vec<[usize; 4]>,
}

/// Minimum, median and maximum of a per-element measure.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Stats {
    /// Smallest value.
    pub min: f64,
    /// Median value (lower median for an even count).
    pub median: f64,
    /// Largest value.
    pub max: f64,
}

impl Stats {
    /// Statistics of `v` (all NaN for an empty slice; NaNs sort last).
    pub fn of(mut v: Vec<f64>) -> Stats {
        if v.is_empty() {
            return Stats {
                min: f64::NAN,
                median: f64::NAN,
                max: f64::NAN,
            };
        }
        v.sort_by(f64::total_cmp);
        Stats {
            min: v[0],
            median: v[(v.len() - 1) / 2],
            max: v[v.len() - 1],
        }
    }
}

/// Element quality of a tetrahedral mesh.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct TetQuality {
    /// Number of tetrahedra.
    pub n_tets: usize,
    /// Per tetrahedron, its smallest dihedral angle in degrees, negative for an inverted (or
    /// flat) tetrahedron, so that `min_dihedral_deg.min < 0` shows an inverted element (the
    /// unsigned angles of a mirrored tetrahedron are those of a good one).
    pub min_dihedral_deg: Stats,
    /// Per tetrahedron, its largest dihedral angle in degrees.
    pub max_dihedral_deg: Stats,
    /// Per tetrahedron, circumradius over shortest edge.
    pub radius_edge: Stats,
    /// Tetrahedra with a non-positive signed volume (inverted or flat).
    pub inverted: usize,
}

/// Signed volume of the tetrahedron `abcd`, positive when `d` is on the side of `abc` that
/// `(b - a) × (c - a)` points to.
#[inline]
pub fn tet_signed_volume(a: &Point, b: &Point, c: &Point, d: &Point) -> f64 {
    (b - a).dot(&(c - a).cross(&(d - a))) / 6.0
}

/// Signed volume of the element `tet` of a mesh whose nodes are `nodes` ([`tet_signed_volume`]
/// of its corners), for code that moves the nodes of a mesh it does not own.
#[inline]
pub(crate) fn element_signed_volume(nodes: &[Point], tet: &[usize; 4]) -> f64 {
    let [a, b, c, d] = tet.map(|i| nodes[i]);
    tet_signed_volume(&a, &b, &c, &d)
}

/// The six interior dihedral angles (radians) of tetrahedron `abcd`, at edges ab, ac, ad, bc,
/// bd, cd: `π` minus the angle between the outward normals of the two faces meeting there.
/// A degenerate tetrahedron yields NaN angles.
pub fn dihedral_angles(p: [Point; 4]) -> [f64; 6] {
    // Outward normal of the face opposite each corner: the corner lies behind it.
    let n: [Vec3; 4] = std::array::from_fn(|i| {
        let [a, b, c] = [(i + 1) % 4, (i + 2) % 4, (i + 3) % 4];
        let m = (p[b] - p[a]).cross(&(p[c] - p[a]));
        let s = if m.dot(&(p[i] - p[a])) > 0.0 {
            -1.0
        } else {
            1.0
        };
        let len = m.norm();
        s * m / len
    });
    // Edge (i, j) is shared by the faces opposite the two other corners k, l.
    const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];
    std::array::from_fn(|e| {
        let (i, j) = EDGES[e];
        let mut kl = (0..4).filter(|&x| x != i && x != j);
        let (k, l) = (kl.next().unwrap_or(0), kl.next().unwrap_or(0));
        std::f64::consts::PI - n[k].dot(&n[l]).clamp(-1.0, 1.0).acos()
    })
}

/// Circumradius over shortest edge of tetrahedron `abcd` (infinite for a flat one). The
/// circumcentre offset from `a` is `(|u|² v×w + |v|² w×u + |w|² u×v) / (2 u·(v×w))` with
/// `u, v, w` the edges from `a`.
pub(crate) fn radius_edge_ratio(p: [Point; 4]) -> f64 {
    let (u, v, w) = (p[1] - p[0], p[2] - p[0], p[3] - p[0]);
    let det = 2.0 * u.dot(&v.cross(&w));
    let o = (v.cross(&w) * u.norm_squared()
        + w.cross(&u) * v.norm_squared()
        + u.cross(&v) * w.norm_squared())
        / det;
    let mut lmin = f64::INFINITY;
    for i in 0..4 {
        for j in i + 1..4 {
            lmin = lmin.min((p[i] - p[j]).norm());
        }
    }
    if det == 0.0 {
        return f64::INFINITY;
    }
    o.norm() / lmin
}

impl TetMesh {
    /// A mesh from nodes and tetrahedra; fails (one line, naming the item) when a tetrahedron
    /// names a node that does not exist or repeats one, or a coordinate is not finite.
    /// Orientation is not checked here (see [`TetMesh::inverted_count`]).
    pub fn new(nodes: Vec<Point>, tets: Vec<[usize; 4]>) -> Result<Self> {
        if let Some(i) = nodes
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(Error::invalid(format!(
                "tet mesh node {i} has a non-finite coordinate"
            )));
        }
        for (t, tet) in tets.iter().enumerate() {
            if let Some(&v) = tet.iter().find(|&&v| v >= nodes.len()) {
                return Err(Error::invalid(format!(
                    "tetrahedron {t} names node {v}, but the mesh has {} nodes",
                    nodes.len()
                )));
            }
            for i in 0..4 {
                for j in i + 1..4 {
                    if tet[i] == tet[j] {
                        return Err(Error::invalid(format!(
                            "tetrahedron {t} repeats node {}: {tet:?}",
                            tet[i]
                        )));
                    }
                }
            }
        }
        Ok(TetMesh { nodes, tets })
    }

    /// Number of nodes.
    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }

    /// Number of tetrahedra.
    pub fn n_tets(&self) -> usize {
        self.tets.len()
    }

    /// The four corners of tetrahedron `t`.
    #[inline]
    pub fn corners(&self, t: usize) -> [Point; 4] {
        self.tets[t].map(|i| self.nodes[i])
    }

    /// Signed volume of tetrahedron `t`, mm³.
    pub fn tet_volume(&self, t: usize) -> f64 {
        let [a, b, c, d] = self.corners(t);
        tet_signed_volume(&a, &b, &c, &d)
    }

    /// Total signed volume, mm³.
    pub fn volume(&self) -> f64 {
        (0..self.n_tets()).map(|t| self.tet_volume(t)).sum()
    }

    /// Tetrahedra whose signed volume is not positive.
    pub fn inverted_count(&self) -> usize {
        (0..self.n_tets())
            .filter(|&t| self.tet_volume(t) <= 0.0)
            .count()
    }

    /// Boundary faces: the faces that belong to exactly one tetrahedron, oriented outward
    /// (counter-clockwise seen from outside, as [`TriMesh`] expects), in a deterministic order
    /// (by tetrahedron, then by the corner each face is opposite).
    pub(crate) fn boundary_faces(&self) -> Vec<[usize; 3]> {
        self.boundary_faces_with_tets()
            .into_iter()
            .map(|(f, _)| f)
            .collect()
    }

    /// [`Self::boundary_faces`] with the tetrahedron each face belongs to.
    pub fn boundary_faces_with_tets(&self) -> Vec<([usize; 3], usize)> {
        // Face opposite corner i of a positive tet, wound so its normal points away from i.
        const FACES: [[usize; 3]; 4] = [[1, 2, 3], [0, 3, 2], [0, 1, 3], [0, 2, 1]];
        // Sort the sorted-corner keys of all faces: a face is on the boundary when its key
        // occurs once (faster than hashing 4 t faces).
        let mut keys: Vec<([usize; 3], u32)> = Vec::with_capacity(4 * self.tets.len());
        for (t, tet) in self.tets.iter().enumerate() {
            for (i, f) in FACES.iter().enumerate() {
                let mut k = f.map(|c| tet[c]);
                k.sort_unstable();
                keys.push((k, (4 * t + i) as u32));
            }
        }
        keys.par_sort_unstable();
        let mut single: Vec<u32> = Vec::new();
        let mut i = 0;
        while i < keys.len() {
            let mut j = i + 1;
            while j < keys.len() && keys[j].0 == keys[i].0 {
                j += 1;
            }
            if j == i + 1 {
                single.push(keys[i].1);
            }
            i = j;
        }
        single.sort_unstable();
        single
            .into_iter()
            .map(|id| {
                let (t, i) = (id as usize / 4, id as usize % 4);
                (FACES[i].map(|c| self.tets[t][c]), t)
            })
            .collect()
    }

    /// The boundary surface as a triangle mesh over all nodes (interior nodes unreferenced).
    pub fn boundary_mesh(&self) -> TriMesh {
        TriMesh {
            vertices: self.nodes.clone(),
            faces: self.boundary_faces(),
        }
    }

    /// Sorted indices of the nodes on a boundary face.
    pub fn boundary_nodes(&self) -> Vec<usize> {
        let mut on = vec![false; self.nodes.len()];
        for f in self.boundary_faces() {
            for v in f {
                on[v] = true;
            }
        }
        (0..on.len()).filter(|&i| on[i]).collect()
    }

    /// Dihedral-angle and radius-edge statistics, and the inverted count.
    pub fn quality(&self) -> TetQuality {
        let per: Vec<(f64, f64, f64)> = (0..self.n_tets())
            .map(|t| {
                let p = self.corners(t);
                let a = dihedral_angles(p);
                let lo = a.iter().copied().fold(f64::INFINITY, f64::min).to_degrees();
                let lo = if tet_signed_volume(&p[0], &p[1], &p[2], &p[3]) > 0.0 {
                    lo
                } else {
                    -lo
                };
                let hi = a.iter().copied().fold(0.0, f64::max).to_degrees();
                (lo, hi, radius_edge_ratio(p))
            })
            .collect();
        TetQuality {
            n_tets: self.n_tets(),
            min_dihedral_deg: Stats::of(per.iter().map(|x| x.0).collect()),
            max_dihedral_deg: Stats::of(per.iter().map(|x| x.1).collect()),
            radius_edge: Stats::of(per.iter().map(|x| x.2).collect()),
            inverted: self.inverted_count(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn regular() -> [Point; 4] {
        [
            Point::new(1.0, 1.0, 1.0),
            Point::new(1.0, -1.0, -1.0),
            Point::new(-1.0, 1.0, -1.0),
            Point::new(-1.0, -1.0, 1.0),
        ]
    }

    #[test]
    fn regular_tet_closed_forms() {
        let p = regular();
        // Dihedral angle of the regular tetrahedron: arccos(1/3).
        for a in dihedral_angles(p) {
            assert!((a - (1.0f64 / 3.0).acos()).abs() < 1e-12);
        }
        assert!((radius_edge_ratio(p) - 6f64.sqrt() / 4.0).abs() < 1e-12);
        // Edge 2√2: volume a³/(6√2) = 8/3.
        let v = tet_signed_volume(&p[0], &p[1], &p[2], &p[3]).abs();
        assert!((v - 8.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn corner_tet_right_angles() {
        let p = [
            Point::origin(),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
        ];
        let a = dihedral_angles(p).map(f64::to_degrees);
        // At the three axis edges the faces are coordinate planes: 90°.
        for x in &a[..3] {
            assert!((x - 90.0).abs() < 1e-9);
        }
        // At the far edges: between a coordinate plane and x+y+z=1, arccos(1/√3).
        for x in &a[3..] {
            assert!((x - (1.0 / 3f64.sqrt()).acos().to_degrees()).abs() < 1e-9);
        }
    }

    /// A mirrored tetrahedron has the same unsigned angles as a good one; the quality's
    /// smallest dihedral angle carries the sign of its volume, so an inverted element shows.
    #[test]
    fn an_inverted_tet_has_a_negative_min_dihedral() {
        let nodes = vec![
            Point::origin(),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
        ];
        let far = (1.0 / 3f64.sqrt()).acos().to_degrees();
        let good = TetMesh::new(nodes.clone(), vec![[0, 1, 2, 3]])
            .unwrap()
            .quality();
        assert!((good.min_dihedral_deg.min - far).abs() < 1e-9);
        let bad = TetMesh::new(nodes, vec![[0, 2, 1, 3]]).unwrap().quality();
        assert_eq!(bad.inverted, 1);
        assert!((bad.min_dihedral_deg.min + far).abs() < 1e-9);
        assert!((bad.max_dihedral_deg.max - 90.0).abs() < 1e-9);
    }

    #[test]
    fn two_tets_boundary_and_volume() {
        let m = TetMesh::new(
            vec![
                Point::origin(),
                Point::new(1.0, 0.0, 0.0),
                Point::new(0.0, 1.0, 0.0),
                Point::new(0.0, 0.0, 1.0),
                Point::new(0.0, 0.0, -1.0),
            ],
            vec![[0, 1, 2, 3], [0, 2, 1, 4]],
        )
        .unwrap();
        assert_eq!(m.inverted_count(), 0);
        assert!((m.volume() - 2.0 / 6.0).abs() < 1e-15);
        let b = m.boundary_faces();
        assert_eq!(b.len(), 6);
        // The boundary encloses the same volume, outward oriented.
        assert!((m.boundary_mesh().signed_volume() - m.volume()).abs() < 1e-15);
        assert_eq!(m.boundary_nodes(), vec![0, 1, 2, 3, 4]);
        assert!(TetMesh::new(m.nodes.clone(), vec![[0, 1, 1, 2]]).is_err());
        assert!(TetMesh::new(m.nodes.clone(), vec![[0, 1, 2, 9]]).is_err());
    }
}
