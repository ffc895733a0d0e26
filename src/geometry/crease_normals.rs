//! Vertex normals for shading a CAD part: smooth across gentle bends, sharp at creases.
//!
//! A viewer shades a mesh by interpolating its vertex normals. Without normals, glTF viewers
//! shade every triangle flat (spec 3.7.2.1: "flat normals"), so a finely tessellated bottle
//! looks faceted; with one averaged normal per vertex, a box's corners are smeared into a
//! blob, because the normal at a corner is the mean of three perpendicular faces. The usual
//! answer (Blender's "auto smooth", three.js' `toCreasedNormals`) is to split each vertex into
//! one copy per *smooth fan* of its faces: two faces sharing an edge belong to one fan at that
//! edge's ends when the angle between their normals is at most the crease angle, and each
//! copy takes the angle-weighted normal (Thürmer & Wüthrich 1998) of its fan alone.
//!
//! The split only copies vertices (never moves or merges them), and returns for each new
//! vertex the one it copies, so per-vertex data (colours, attributes) follows by indexing.
//! Adjacency is by vertex index, so a triangle soup (no shared vertices) stays flat: weld it
//! first (the crate's STL reader does).

use super::{TriMesh, Vec3};
use std::collections::HashMap;

/// The crease angle of [`crease_normals`] for the crate's CAD parts, degrees: above the 30°
/// between neighbouring facets of a cylinder tessellated with 12 segments (the coarsest round
/// a CAD export normally gives), so rounds stay smooth, and below the 45° of a chamfer and
/// the 90° of a box edge, which stay sharp.
pub const DEFAULT_CREASE_DEG: f64 = 35.0;

/// A mesh split at its creases with its vertex normals.
#[derive(Clone, Debug, PartialEq)]
pub struct CreaseSplit {
    /// The input's faces on the split vertices (same faces, same order).
    pub mesh: TriMesh,
    /// Unit normal per split vertex (zero where every face of its fan has zero area).
    pub normals: Vec<Vec3>,
    /// Per split vertex, the input vertex it copies (`source[v] == v` for `v` below the
    /// input's vertex count).
    pub source: Vec<usize>,
}

impl CreaseSplit {
    /// Per-vertex data of the input carried to the split vertices.
    pub fn carry<T: Clone>(&self, values: &[T]) -> Vec<T> {
        self.source.iter().map(|&v| values[v].clone()).collect()
    }
}

/// Split `mesh`'s vertices at edges whose faces' normals differ by more than `crease_deg`
/// degrees (see the [module documentation](self)), with angle-weighted normals per copy.
///
/// A face of zero area has no normal: it joins the fan of its first neighbour at each corner
/// and adds no weight. An edge with more than two faces (non-manifold) is a crease. A vertex
/// no face uses is kept as is with a zero normal. `crease_deg >= 180` gives the plain smooth
/// normals of [`TriMesh::vertex_normals`] on the same vertices; `crease_deg < 0` gives flat
/// shading (one copy per corner).
pub fn crease_normals(mesh: &TriMesh, crease_deg: f64) -> CreaseSplit {
    let nf = mesh.faces.len();
    let face_n: Vec<Option<Vec3>> = (0..nf)
        .map(|f| mesh.face_cross(f).try_normalize(0.0))
        .collect();
    let cos_crease = crease_deg.to_radians().cos();
    // Union-find over corners (3 f + k).
    let mut parent: Vec<usize> = (0..3 * nf).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    let mut edges: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
    for (f, face) in mesh.faces.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (face[k], face[(k + 1) % 3]);
            edges.entry((a.min(b), a.max(b))).or_default().push(f);
        }
    }
    let corner_of = |f: usize, v: usize| -> usize {
        let k = mesh.faces[f].iter().position(|&x| x == v).unwrap_or(0);
        3 * f + k
    };
    let mut attached = vec![false; 3 * nf];
    // Sorted keys keep the first-neighbour rule for zero-area faces deterministic.
    let mut keys: Vec<_> = edges.keys().copied().collect();
    keys.sort_unstable();
    for key in keys {
        let list = &edges[&key];
        if crease_deg < 0.0 || list.len() != 2 {
            continue;
        }
        let (f, g) = (list[0], list[1]);
        let smooth = match (face_n[f], face_n[g]) {
            (Some(n), Some(m)) => n.dot(&m) >= cos_crease || crease_deg >= 180.0,
            _ => true,
        };
        if !smooth {
            continue;
        }
        for v in [key.0, key.1] {
            let (cf, cg) = (corner_of(f, v), corner_of(g, v));
            let degenerate_side =
                (face_n[f].is_none() && attached[cf]) || (face_n[g].is_none() && attached[cg]);
            if degenerate_side {
                continue;
            }
            let (rf, rg) = (find(&mut parent, cf), find(&mut parent, cg));
            if rf != rg {
                parent[rf] = rg;
            }
            attached[cf] = true;
            attached[cg] = true;
        }
    }
    // One vertex per corner class: the first class of a vertex (in face order) keeps the
    // vertex's index, further ones are appended, so a mesh without creases comes back with
    // its own numbering and unused vertices stay where they were.
    let nv = mesh.n_vertices();
    let mut class_vertex: HashMap<usize, usize> = HashMap::new();
    let mut claimed = vec![false; nv];
    let mut source: Vec<usize> = (0..nv).collect();
    let mut faces = Vec::with_capacity(nf);
    let mut sums: Vec<Vec3> = vec![Vec3::zeros(); nv];
    for (f, face) in mesh.faces.iter().enumerate() {
        let p = mesh.corners(f);
        let mut out = [0usize; 3];
        for k in 0..3 {
            let root = find(&mut parent, 3 * f + k);
            let v = *class_vertex.entry(root).or_insert_with(|| {
                let orig = face[k];
                if std::mem::replace(&mut claimed[orig], true) {
                    source.push(orig);
                    sums.push(Vec3::zeros());
                    source.len() - 1
                } else {
                    orig
                }
            });
            if let Some(n) = face_n[f] {
                let angle = (p[(k + 1) % 3] - p[k]).angle(&(p[(k + 2) % 3] - p[k]));
                if angle.is_finite() {
                    sums[v] += n * angle;
                }
            }
            out[k] = v;
        }
        faces.push(out);
    }
    let vertices = source.iter().map(|&v| mesh.vertices[v]).collect();
    CreaseSplit {
        mesh: TriMesh { vertices, faces },
        normals: sums
            .into_iter()
            .map(|s| s.try_normalize(0.0).unwrap_or_else(Vec3::zeros))
            .collect(),
        source,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::{cuboid, icosphere};
    use crate::geometry::Point;
    use std::f64::consts::TAU;

    /// A closed cylinder about z: radius `r`, height `h`, `n` side quads split in two, each
    /// cap a fan around a centre vertex; faces counter-clockwise from outside.
    fn cylinder(r: f64, h: f64, n: usize) -> TriMesh {
        let mut v = Vec::new();
        for z in [0.0, h] {
            for i in 0..n {
                let a = i as f64 / n as f64 * TAU;
                v.push(Point::new(r * a.cos(), r * a.sin(), z));
            }
        }
        v.push(Point::new(0.0, 0.0, 0.0));
        v.push(Point::new(0.0, 0.0, h));
        let (bottom, top) = (2 * n, 2 * n + 1);
        let mut f = Vec::new();
        for i in 0..n {
            let j = (i + 1) % n;
            f.push([i, j, n + j]);
            f.push([i, n + j, n + i]);
            f.push([bottom, j, i]);
            f.push([top, n + i, n + j]);
        }
        TriMesh::new(v, f).unwrap()
    }

    #[test]
    fn a_box_stays_a_box() {
        let cube = cuboid(10.0, 20.0, 30.0);
        let s = crease_normals(&cube, DEFAULT_CREASE_DEG);
        // Every corner of a box is shared by three faces at 90°: three copies each.
        assert_eq!(s.mesh.n_vertices(), 24);
        assert_eq!(s.mesh.n_faces(), 12);
        let face_n = s.mesh.face_normals();
        for (f, face) in s.mesh.faces.iter().enumerate() {
            for &v in face {
                assert!((s.normals[v] - face_n[f]).norm() < 1e-12);
                assert_eq!(s.mesh.vertices[v], cube.vertices[s.source[v]]);
            }
        }
        // The same surface: the volume and the area are the input's.
        assert!((s.mesh.signed_volume() - 6000.0).abs() < 1e-9);
        // Carried per-vertex data follows the copies.
        let ids: Vec<usize> = (0..8).collect();
        assert_eq!(s.carry(&ids), s.source);
        assert_eq!(s.source[..8], ids[..]);
    }

    #[test]
    fn a_cylinder_is_smooth_on_its_side_and_sharp_at_its_rims() {
        let n = 96;
        let cyl = cylinder(15.0, 40.0, n);
        let s = crease_normals(&cyl, DEFAULT_CREASE_DEG);
        // Each rim vertex splits into a side copy and a cap copy; the cap centres stay one.
        assert_eq!(s.mesh.n_vertices(), 4 * n + 2);
        let mut side = 0;
        for (v, p) in s.mesh.vertices.iter().enumerate() {
            let radial = Vec3::new(p.x, p.y, 0.0).normalize();
            let nz = s.normals[v].z;
            if nz.abs() > 0.5 {
                // A cap copy: the cap's axis exactly.
                assert!((nz.abs() - 1.0).abs() < 1e-12);
                continue;
            }
            side += 1;
            let angle = s.normals[v].angle(&radial).to_degrees();
            assert!(angle < 1.0, "side vertex {v} off radial by {angle}°");
        }
        assert_eq!(side, 2 * n);
        // The facets of a 12-segment cylinder are 30° apart: still smooth at the default.
        let coarse = crease_normals(&cylinder(15.0, 40.0, 12), DEFAULT_CREASE_DEG);
        assert_eq!(coarse.mesh.n_vertices(), 4 * 12 + 2);
    }

    #[test]
    fn limits_are_smooth_and_flat_shading() {
        let sphere = icosphere(10.0, 2);
        let smooth = crease_normals(&sphere, 180.0);
        assert_eq!(smooth.mesh, sphere);
        for (a, b) in smooth.normals.iter().zip(sphere.vertex_normals()) {
            assert!((a - b).norm() < 1e-12);
        }
        let flat = crease_normals(&sphere, -1.0);
        assert_eq!(flat.mesh.n_vertices(), 3 * sphere.n_faces());
    }
}
