//! Indexed triangle mesh in f64 millimetres.
//!
//! Shapes are kept apart from queries (as in parry): [`TriMesh`] owns vertices and faces and
//! answers cheap per-element questions; connectivity lives in [`super::Topology`] (with [`TriMesh::topology`]), built on
//! demand, so a mesh that is only transformed or written never pays for it.

use super::{Point, Vec3};
use crate::error::{Error, Result};
use nalgebra::{Isometry3, Matrix4};
use std::collections::HashMap;

/// An indexed triangle mesh; faces are counter-clockwise seen from outside.
#[derive(Clone, Debug, PartialEq)]
pub struct TriMesh {
    /// Vertex positions in mm.
    pub vertices: Vec<Point>,
    /// Triangles as indices into `vertices`.
    pub faces: Vec<[usize; 3]>,
}

impl TriMesh {
    /// A mesh from vertices and faces; fails when a face names a vertex that does not exist,
    /// repeats a vertex, or a coordinate is not finite.
    pub fn new(vertices: Vec<Point>, faces: Vec<[usize; 3]>) -> Result<Self> {
        if let Some(i) = vertices
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(Error::invalid(format!(
                "vertex {i} has a non-finite coordinate"
            )));
        }
        for (fi, f) in faces.iter().enumerate() {
            if let Some(&v) = f.iter().find(|&&v| v >= vertices.len()) {
                return Err(Error::invalid(format!(
                    "face {fi} names vertex {v}, but the mesh has {} vertices",
                    vertices.len()
                )));
            }
            if f[0] == f[1] || f[1] == f[2] || f[0] == f[2] {
                return Err(Error::invalid(format!("face {fi} repeats a vertex: {f:?}")));
            }
        }
        Ok(TriMesh { vertices, faces })
    }

    /// Number of vertices.
    pub fn n_vertices(&self) -> usize {
        self.vertices.len()
    }

    /// Number of faces.
    pub fn n_faces(&self) -> usize {
        self.faces.len()
    }

    /// The three corners of face `f`.
    #[inline]
    pub fn corners(&self, f: usize) -> [Point; 3] {
        let [a, b, c] = self.faces[f];
        [self.vertices[a], self.vertices[b], self.vertices[c]]
    }

    /// Twice-area vector of face `f` (cross product of two edges): its direction is the normal.
    #[inline]
    pub fn face_cross(&self, f: usize) -> Vec3 {
        let [a, b, c] = self.corners(f);
        (b - a).cross(&(c - a))
    }

    /// Unit normal of every face (zero for a degenerate face).
    pub fn face_normals(&self) -> Vec<Vec3> {
        (0..self.faces.len())
            .map(|f| {
                self.face_cross(f)
                    .try_normalize(0.0)
                    .unwrap_or_else(Vec3::zeros)
            })
            .collect()
    }

    /// Area of every face, mm².
    pub fn face_areas(&self) -> Vec<f64> {
        (0..self.faces.len())
            .map(|f| 0.5 * self.face_cross(f).norm())
            .collect()
    }

    /// Total surface area, mm².
    pub fn area(&self) -> f64 {
        self.face_areas().iter().sum()
    }

    /// Unit vertex normals, weighted by the incident angle of each face (Thürmer & Wüthrich
    /// 1998), which unlike area weighting does not depend on how a region is triangulated.
    pub fn vertex_normals(&self) -> Vec<Vec3> {
        let mut n = vec![Vec3::zeros(); self.vertices.len()];
        for f in 0..self.faces.len() {
            let fnorm = match self.face_cross(f).try_normalize(0.0) {
                Some(v) => v,
                None => continue,
            };
            let idx = self.faces[f];
            let p = self.corners(f);
            for k in 0..3 {
                let e1 = p[(k + 1) % 3] - p[k];
                let e2 = p[(k + 2) % 3] - p[k];
                let angle = e1.angle(&e2);
                if angle.is_finite() {
                    n[idx[k]] += fnorm * angle;
                }
            }
        }
        n.into_iter()
            .map(|v| v.try_normalize(0.0).unwrap_or_else(Vec3::zeros))
            .collect()
    }

    /// Signed enclosed volume, mm³ (divergence theorem); positive for a closed mesh with
    /// outward-facing triangles. Meaningless for an open mesh.
    pub fn signed_volume(&self) -> f64 {
        self.faces
            .iter()
            .map(|&[a, b, c]| {
                let (a, b, c) = (self.vertices[a], self.vertices[b], self.vertices[c]);
                a.coords.dot(&b.coords.cross(&c.coords))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Centroid of the vertices.
    pub fn vertex_centroid(&self) -> Point {
        let s: Vec3 = self.vertices.iter().map(|p| p.coords).sum();
        Point::from(s / self.vertices.len().max(1) as f64)
    }

    /// Axis-aligned bounding box `(min, max)`; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Point, Point)> {
        let first = *self.vertices.first()?;
        Some(
            self.vertices
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }

    /// Length of the bounding-box diagonal, mm (0 for an empty mesh).
    pub fn diagonal(&self) -> f64 {
        self.bounds()
            .map(|(lo, hi)| (hi - lo).norm())
            .unwrap_or(0.0)
    }

    /// Merge vertices closer than `tol` (mm) and drop faces that collapse; returns the welded
    /// mesh and, for every input vertex, its index in the welded mesh.
    ///
    /// Vertices are bucketed on a grid of cell `tol` and compared with the 27 neighbouring
    /// cells, so the cost is linear; the first vertex of a cluster (in input order) is kept, which
    /// makes the result independent of hashing order. `tol = 0` welds exact duplicates only
    /// (the split texture seams of a glTF export).
    pub fn weld(&self, tol: f64) -> (TriMesh, Vec<usize>) {
        let cell = if tol > 0.0 { tol } else { 1.0 };
        let key = |p: &Point| {
            (
                (p.x / cell).floor() as i64,
                (p.y / cell).floor() as i64,
                (p.z / cell).floor() as i64,
            )
        };
        let mut grid: HashMap<(i64, i64, i64), Vec<usize>> = HashMap::new();
        let mut remap = Vec::with_capacity(self.vertices.len());
        let mut kept: Vec<Point> = Vec::new();
        for p in &self.vertices {
            let (kx, ky, kz) = key(p);
            let mut found = None;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(list) = grid.get(&(
                            kx.saturating_add(dx),
                            ky.saturating_add(dy),
                            kz.saturating_add(dz),
                        )) {
                            for &j in list {
                                let d = (kept[j] - p).norm();
                                if d <= tol {
                                    found = Some(j);
                                    break 'search;
                                }
                            }
                        }
                    }
                }
            }
            let j = found.unwrap_or_else(|| {
                kept.push(*p);
                grid.entry((kx, ky, kz)).or_default().push(kept.len() - 1);
                kept.len() - 1
            });
            remap.push(j);
        }
        let faces = self
            .faces
            .iter()
            .map(|f| [remap[f[0]], remap[f[1]], remap[f[2]]])
            .filter(|f| f[0] != f[1] && f[1] != f[2] && f[0] != f[2])
            .collect();
        (
            TriMesh {
                vertices: kept,
                faces,
            },
            remap,
        )
    }

    /// Apply a rigid transform to every vertex.
    pub fn transformed(&self, iso: &Isometry3<f64>) -> TriMesh {
        TriMesh {
            vertices: self.vertices.iter().map(|p| iso * p).collect(),
            faces: self.faces.clone(),
        }
    }

    /// Apply an affine 4x4 transform; faces are flipped when it mirrors, so they stay outward.
    pub fn affine_transformed(&self, m: &Matrix4<f64>) -> TriMesh {
        let mirror = m.fixed_view::<3, 3>(0, 0).determinant() < 0.0;
        TriMesh {
            vertices: self
                .vertices
                .iter()
                .map(|p| Point::from_homogeneous(m * p.to_homogeneous()).unwrap_or(*p))
                .collect(),
            faces: if mirror {
                self.faces.iter().map(|&[a, b, c]| [a, c, b]).collect()
            } else {
                self.faces.clone()
            },
        }
    }

    /// Multiply every coordinate by `s` (e.g. metres to millimetres).
    pub fn scaled(&self, s: f64) -> TriMesh {
        TriMesh {
            vertices: self.vertices.iter().map(|p| p * s).collect(),
            faces: self.faces.clone(),
        }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    /// Unit-scaled axis-aligned box `[0,a]x[0,b]x[0,c]` with outward faces.
    pub fn cuboid(a: f64, b: f64, c: f64) -> TriMesh {
        let v = |x: f64, y: f64, z: f64| Point::new(x * a, y * b, z * c);
        let vertices = vec![
            v(0., 0., 0.),
            v(1., 0., 0.),
            v(1., 1., 0.),
            v(0., 1., 0.),
            v(0., 0., 1.),
            v(1., 0., 1.),
            v(1., 1., 1.),
            v(0., 1., 1.),
        ];
        let faces = vec![
            [0, 2, 1],
            [0, 3, 2],
            [4, 5, 6],
            [4, 6, 7],
            [0, 1, 5],
            [0, 5, 4],
            [1, 2, 6],
            [1, 6, 5],
            [2, 3, 7],
            [2, 7, 6],
            [3, 0, 4],
            [3, 4, 7],
        ];
        TriMesh::new(vertices, faces).unwrap()
    }

    /// Torus about z (major radius `big`, minor `small`), `n` x `m` quads split in two:
    /// closed, genus one, faces counter-clockwise from outside.
    pub fn torus(big: f64, small: f64, n: usize, m: usize) -> TriMesh {
        let mut v = Vec::new();
        for i in 0..n {
            let a = i as f64 / n as f64 * std::f64::consts::TAU;
            for j in 0..m {
                let b = j as f64 / m as f64 * std::f64::consts::TAU;
                let r = big + small * b.cos();
                v.push(Point::new(r * a.cos(), r * a.sin(), small * b.sin()));
            }
        }
        let id = |i: usize, j: usize| (i % n) * m + (j % m);
        let mut f = Vec::new();
        for i in 0..n {
            for j in 0..m {
                let (p, q, r, s) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
                f.extend([[p, q, r], [p, r, s]]);
            }
        }
        TriMesh::new(v, f).unwrap()
    }

    /// Open planar grid of `k x k` squares on the plane through `origin` spanned by `u`, `v`:
    /// vertex `(i, j)` at index `j (k + 1) + i`, each square split along its `(i, j)`-`(i+1, j+1)`
    /// diagonal.
    pub fn grid(k: usize, origin: Point, u: Vec3, v: Vec3) -> TriMesh {
        let mut vertices = Vec::new();
        for j in 0..=k {
            for i in 0..=k {
                vertices.push(origin + u * i as f64 + v * j as f64);
            }
        }
        let id = |i: usize, j: usize| j * (k + 1) + i;
        let mut faces = Vec::new();
        for j in 0..k {
            for i in 0..k {
                faces.push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                faces.push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        TriMesh::new(vertices, faces).unwrap()
    }

    /// Icosahedron subdivided `level` times (each triangle into four), projected on a sphere.
    pub fn icosphere(radius: f64, level: usize) -> TriMesh {
        let t = (1.0 + 5f64.sqrt()) / 2.0;
        let mut v: Vec<Vec3> = [
            [-1., t, 0.],
            [1., t, 0.],
            [-1., -t, 0.],
            [1., -t, 0.],
            [0., -1., t],
            [0., 1., t],
            [0., -1., -t],
            [0., 1., -t],
            [t, 0., -1.],
            [t, 0., 1.],
            [-t, 0., -1.],
            [-t, 0., 1.],
        ]
        .iter()
        .map(|p| Vec3::new(p[0], p[1], p[2]).normalize())
        .collect();
        let mut f: Vec<[usize; 3]> = vec![
            [0, 11, 5],
            [0, 5, 1],
            [0, 1, 7],
            [0, 7, 10],
            [0, 10, 11],
            [1, 5, 9],
            [5, 11, 4],
            [11, 10, 2],
            [10, 7, 6],
            [7, 1, 8],
            [3, 9, 4],
            [3, 4, 2],
            [3, 2, 6],
            [3, 6, 8],
            [3, 8, 9],
            [4, 9, 5],
            [2, 4, 11],
            [6, 2, 10],
            [8, 6, 7],
            [9, 8, 1],
        ];
        for _ in 0..level {
            let mut mid: HashMap<(usize, usize), usize> = HashMap::new();
            let mut next = Vec::with_capacity(f.len() * 4);
            for &[a, b, c] in &f {
                let mut m = |p: usize, q: usize| {
                    *mid.entry((p.min(q), p.max(q))).or_insert_with(|| {
                        v.push((v[p] + v[q]).normalize());
                        v.len() - 1
                    })
                };
                let (ab, bc, ca) = (m(a, b), m(b, c), m(c, a));
                next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
            }
            f = next;
        }
        TriMesh::new(v.iter().map(|p| Point::from(p * radius)).collect(), f).unwrap()
    }

    #[test]
    fn cuboid_measures() {
        let m = cuboid(2.0, 3.0, 4.0);
        assert!((m.signed_volume() - 24.0).abs() < 1e-12);
        assert!((m.area() - 2.0 * (6.0 + 8.0 + 12.0)).abs() < 1e-12);
        m.check_closed_manifold().unwrap();
        let n = m.vertex_normals();
        let expect = Vec3::new(-1.0, -1.0, -1.0).normalize();
        assert!((n[0] - expect).norm() < 1e-12);
    }

    #[test]
    fn mirrored_transform_keeps_volume_positive() {
        let m = cuboid(1.0, 2.0, 3.0);
        let mirror = Matrix4::new_nonuniform_scaling(&Vec3::new(-1.0, 1.0, 1.0));
        let mm = m.affine_transformed(&mirror);
        assert!((mm.signed_volume() - 6.0).abs() < 1e-12);
    }

    #[test]
    fn weld_merges_split_seams() {
        let m = cuboid(1.0, 1.0, 1.0);
        // Split every face into its own three vertices, as a glTF exporter does at seams.
        let mut vertices = Vec::new();
        let mut faces = Vec::new();
        for f in &m.faces {
            let base = vertices.len();
            for &v in f {
                vertices.push(m.vertices[v]);
            }
            faces.push([base, base + 1, base + 2]);
        }
        let split = TriMesh::new(vertices, faces).unwrap();
        assert!(split.check_closed_manifold().is_err());
        let (welded, remap) = split.weld(0.0);
        assert_eq!(welded.n_vertices(), 8);
        assert_eq!(remap.len(), 36);
        welded.check_closed_manifold().unwrap();
        assert!((welded.signed_volume() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn new_rejects_bad_indices_and_nan() {
        let p = vec![
            Point::origin(),
            Point::new(1., 0., 0.),
            Point::new(0., 1., 0.),
        ];
        assert!(TriMesh::new(p.clone(), vec![[0, 1, 3]]).is_err());
        assert!(TriMesh::new(p.clone(), vec![[0, 1, 1]]).is_err());
        let mut q = p;
        q[1].x = f64::NAN;
        assert!(TriMesh::new(q, vec![[0, 1, 2]]).is_err());
    }
}
