//! Connectivity of a triangle mesh: unique edges, the faces on each edge, face neighbours across
//! edges and vertex one-rings, with the closed / 2-manifold / orientation checks built on them.

use super::TriMesh;
use crate::error::{Error, Result};
use std::collections::HashMap;

/// Edge and face connectivity of a [`TriMesh`].
#[derive(Clone, Debug)]
pub struct Topology {
    /// Unique undirected edges `[a, b]` with `a < b`, in order of first appearance.
    pub edges: Vec<[usize; 2]>,
    /// Faces incident to each edge (1 on a boundary, 2 inside a manifold, more if non-manifold).
    pub edge_faces: Vec<Vec<usize>>,
    /// For every face, the index of its edge `(f[k], f[k+1])` for k = 0, 1, 2.
    pub face_edges: Vec<[usize; 3]>,
    /// For every face and each of its edges `(f[k], f[k+1])`, the face across it (if exactly one).
    pub face_neighbours: Vec<[Option<usize>; 3]>,
    /// Vertex one-rings: the sorted neighbours of every vertex.
    pub vertex_rings: Vec<Vec<usize>>,
    /// Faces incident to every vertex.
    pub vertex_faces: Vec<Vec<usize>>,
    /// The faces, copied from the mesh, for orientation queries.
    pub faces: Vec<[usize; 3]>,
}

impl Topology {
    /// Build the connectivity of `mesh` in O(faces).
    pub fn new(mesh: &TriMesh) -> Self {
        let nv = mesh.n_vertices();
        let mut index: HashMap<(usize, usize), usize> = HashMap::with_capacity(mesh.n_faces() * 2);
        let mut edges = Vec::new();
        let mut edge_faces: Vec<Vec<usize>> = Vec::new();
        let mut face_edges = Vec::with_capacity(mesh.n_faces());
        let mut vertex_faces = vec![Vec::new(); nv];
        for (fi, f) in mesh.faces.iter().enumerate() {
            let mut fe = [0; 3];
            for k in 0..3 {
                let (a, b) = (f[k], f[(k + 1) % 3]);
                let key = (a.min(b), a.max(b));
                let e = *index.entry(key).or_insert_with(|| {
                    edges.push([key.0, key.1]);
                    edge_faces.push(Vec::with_capacity(2));
                    edges.len() - 1
                });
                edge_faces[e].push(fi);
                fe[k] = e;
                vertex_faces[f[k]].push(fi);
            }
            face_edges.push(fe);
        }
        let face_neighbours = face_edges
            .iter()
            .enumerate()
            .map(|(fi, fe)| {
                fe.map(|e| {
                    let fs = &edge_faces[e];
                    if fs.len() == 2 {
                        Some(if fs[0] == fi { fs[1] } else { fs[0] })
                    } else {
                        None
                    }
                })
            })
            .collect();
        let mut vertex_rings = vec![Vec::new(); nv];
        for &[a, b] in &edges {
            vertex_rings[a].push(b);
            vertex_rings[b].push(a);
        }
        for r in &mut vertex_rings {
            r.sort_unstable();
        }
        Topology {
            edges,
            edge_faces,
            face_edges,
            face_neighbours,
            vertex_rings,
            vertex_faces,
            faces: mesh.faces.clone(),
        }
    }

    /// Edges with a single incident face.
    pub fn boundary_edges(&self) -> Vec<[usize; 2]> {
        self.edges
            .iter()
            .zip(&self.edge_faces)
            .filter(|(_, f)| f.len() == 1)
            .map(|(e, _)| *e)
            .collect()
    }

    /// Euler characteristic V - E + F over the vertices that are used by a face.
    pub fn euler_characteristic(&self) -> i64 {
        let v = self.vertex_faces.iter().filter(|f| !f.is_empty()).count() as i64;
        let f = self.face_edges.len() as i64;
        v - self.edges.len() as i64 + f
    }

    /// Connected components of faces (across shared edges); returns a component id per face
    /// and the number of components.
    pub fn face_components(&self) -> (Vec<usize>, usize) {
        let n = self.face_edges.len();
        let mut comp = vec![usize::MAX; n];
        let mut count = 0;
        let mut stack = Vec::new();
        for start in 0..n {
            if comp[start] != usize::MAX {
                continue;
            }
            comp[start] = count;
            stack.push(start);
            while let Some(f) = stack.pop() {
                for &e in &self.face_edges[f] {
                    for &g in &self.edge_faces[e] {
                        if comp[g] == usize::MAX {
                            comp[g] = count;
                            stack.push(g);
                        }
                    }
                }
            }
            count += 1;
        }
        (comp, count)
    }

    /// Error unless every edge has exactly two faces that traverse it in opposite directions
    /// (closed, edge-manifold, consistently oriented) and every vertex's faces form a single fan
    /// (vertex-manifold). The message names the first offending edge or vertex.
    pub fn check_closed_manifold(&self) -> Result<()> {
        for (e, fs) in self.edge_faces.iter().enumerate() {
            let [a, b] = self.edges[e];
            match fs.len() {
                1 => {
                    return Err(Error::invalid(format!(
                        "mesh is open: edge ({a}, {b}) has only one face"
                    )))
                }
                2 => {}
                n => {
                    return Err(Error::invalid(format!(
                        "mesh is not 2-manifold: edge ({a}, {b}) has {n} faces"
                    )))
                }
            }
        }
        // Orientation: the two faces of an edge must traverse it in opposite directions.
        for (e, fs) in self.edge_faces.iter().enumerate() {
            let [a, b] = self.edges[e];
            let forward = |f: usize| {
                let t = self.faces[f];
                (0..3).any(|k| t[k] == a && t[(k + 1) % 3] == b)
            };
            if forward(fs[0]) == forward(fs[1]) {
                return Err(Error::invalid(format!(
                    "mesh is not consistently oriented: faces {} and {} run edge ({a}, {b}) the same way",
                    fs[0], fs[1]
                )));
            }
        }
        // Vertex manifoldness: the faces around a vertex must be one fan, i.e. connected through
        // edges incident to that vertex.
        for (v, faces) in self.vertex_faces.iter().enumerate() {
            if faces.len() < 2 {
                continue;
            }
            let mut seen = vec![false; faces.len()];
            let mut stack = vec![0];
            seen[0] = true;
            let mut reached = 1;
            while let Some(i) = stack.pop() {
                let f = faces[i];
                for k in 0..3 {
                    let e = self.face_edges[f][k];
                    if !self.edges[e].contains(&v) {
                        continue;
                    }
                    for &g in &self.edge_faces[e] {
                        if let Some(j) = faces.iter().position(|&x| x == g) {
                            if !seen[j] {
                                seen[j] = true;
                                reached += 1;
                                stack.push(j);
                            }
                        }
                    }
                }
            }
            if reached != faces.len() {
                return Err(Error::invalid(format!(
                    "mesh is not 2-manifold at vertex {v}: its faces form more than one fan"
                )));
            }
        }
        Ok(())
    }
}

/// Connectivity questions asked of a mesh, answered by its [`Topology`] (kept here so that the
/// mesh type does not depend on its connectivity).
impl TriMesh {
    /// Edge and face connectivity (see [`Topology`]).
    pub fn topology(&self) -> Topology {
        Topology::new(self)
    }

    /// Error unless the mesh is closed, 2-manifold (edges and vertices) and consistently oriented;
    /// the message names the first offending edge or vertex.
    pub fn check_closed_manifold(&self) -> Result<()> {
        self.topology().check_closed_manifold()
    }
}
