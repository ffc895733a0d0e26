//! Carrying the boundary of the template's tetrahedral mesh to a subject (seed paper section
//! 3.7, step 2): each boundary node lies on the template surface, so it is bound by the face
//! holding it and its barycentric coordinates there, and re-placed at the same barycentric
//! point of the same face of the fitted skin (homologous to the template: same faces).
//!
//! This is equation 3 of the paper (`ṽ = ᵂT_f̃ (ᵂT_f)⁻¹ v`, see [`crate::skin::transfer`]) for
//! points *on* the face: the offset from the face is zero, so only the in-plane (barycentric)
//! part of the frame remains, and it is exact whatever the face's deformation.

use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::tet_mesh::TetMesh;
use crate::geometry::{Point, TriMesh};
use rayon::prelude::*;

/// Boundary nodes of a tetrahedral mesh bound to a triangle surface by face and barycentric
/// coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceBinding {
    /// The bound (boundary) nodes, ascending.
    pub nodes: Vec<usize>,
    /// Per bound node, the surface face holding its closest point.
    pub faces: Vec<usize>,
    /// Per bound node, barycentric coordinates of that point on the face.
    pub barycentric: Vec<[f64; 3]>,
    /// Largest distance from a bound node to the surface, mm (0 up to rounding when the nodes
    /// were projected onto the surface, as [`super::isosurface_stuffing`] does).
    pub max_distance: f64,
    surface_faces: Vec<[usize; 3]>,
    n_surface_vertices: usize,
}

/// Bind the boundary nodes of `tet` to `surface` by closest point (AABB tree, Ericson 2005,
/// 5.1.5). Errors when the surface has no faces.
pub fn bind_boundary(tet: &TetMesh, surface: &TriMesh) -> Result<SurfaceBinding> {
    if surface.faces.is_empty() {
        return Err(Error::invalid(
            "cannot bind the tet boundary: the surface has no faces",
        ));
    }
    let nodes = tet.boundary_nodes();
    let tree = AabbTree::new(surface);
    let found: Vec<(usize, [f64; 3], f64)> = nodes
        .par_iter()
        .map(|&v| {
            tree.closest_point(&tet.nodes[v])
                .map(|c| (c.face, c.barycentric, c.distance))
                .ok_or_else(|| {
                    Error::invalid(format!(
                        "tet boundary node {v} has no closest point on the surface"
                    ))
                })
        })
        .collect::<Result<_>>()?;
    Ok(SurfaceBinding {
        faces: found.iter().map(|x| x.0).collect(),
        barycentric: found.iter().map(|x| x.1).collect(),
        max_distance: found.iter().map(|x| x.2).fold(0.0, f64::max),
        nodes,
        surface_faces: surface.faces.clone(),
        n_surface_vertices: surface.n_vertices(),
    })
}

/// Move the bound nodes of `nodes` (a whole node array of the bound tet mesh) onto `deformed`
/// ([`place_boundary`]); the other nodes stay.
pub fn place_boundary_nodes(
    binding: &SurfaceBinding,
    deformed: &TriMesh,
    nodes: &mut [Point],
) -> Result<()> {
    for (&v, p) in binding.nodes.iter().zip(place_boundary(binding, deformed)?) {
        nodes[v] = p;
    }
    Ok(())
}

/// Positions of the bound nodes on `deformed` (the bound surface with moved vertices: same
/// vertex count, same faces), in the order of [`SurfaceBinding::nodes`]. Errors (one line)
/// when `deformed` is not homologous to the bound surface.
pub fn place_boundary(binding: &SurfaceBinding, deformed: &TriMesh) -> Result<Vec<Point>> {
    if deformed.n_vertices() != binding.n_surface_vertices
        || deformed.faces != binding.surface_faces
    {
        return Err(Error::invalid(format!(
            "the fitted skin ({} vertices, {} faces) is not homologous to the template surface \
             the tet mesh is bound to ({} vertices, {} faces, same face list)",
            deformed.n_vertices(),
            deformed.n_faces(),
            binding.n_surface_vertices,
            binding.surface_faces.len()
        )));
    }
    if let Some(i) = deformed
        .vertices
        .iter()
        .position(|p| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(Error::invalid(format!(
            "fitted skin vertex {i} has a non-finite coordinate"
        )));
    }
    Ok(binding
        .faces
        .iter()
        .zip(&binding.barycentric)
        .map(|(&f, w)| {
            let [a, b, c] = deformed.corners(f);
            Point::from(a.coords * w[0] + b.coords * w[1] + c.coords * w[2])
        })
        .collect())
}
