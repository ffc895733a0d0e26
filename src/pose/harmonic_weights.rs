//! Skinning weights for the nodes of the tetrahedral mesh (the goal: "the same deformation
//! applied to the tetrahedral mesh's nodes").
//!
//! The boundary nodes of the template's tet mesh lie on the template surface (section 3.7), so
//! each takes the weights of its point there: the barycentric blend of its face's three vertex
//! weights. The interior nodes take the harmonic extension of those weights (the discrete
//! Laplace equation of the linear FEM with the boundary values held, solved with the tet
//! stage's prefactorised stiffness matrix), the volumetric counterpart of the smooth weights a
//! skin has: weights vary smoothly through the volume, every interior node follows the links
//! its surrounding skin follows, and a node deep in a finger moves with that finger alone
//! (Baran & Popović 2007 use the same Laplace equation on the surface, with bone heat as the
//! source; Jacobson et al. 2011, "Bounded biharmonic weights", section 3, on tet meshes).
//!
//! The weights are computed on the template's tet mesh and carried to every subject by
//! homology, like the skin's template weights ([`super::WeightMethod::Template`]).

use super::skinning::{SkinBinding, Skinning};
use crate::anatomy::Link;
use crate::error::Result;
use crate::geometry::{Point, TriMesh};
use crate::template::{LinkWeights, TemplateHand};
use crate::tet::{place_boundary_nodes, SurfaceBinding, TemplateTet};
use faer::Mat;
use nalgebra::Isometry3;

/// Weights below this (after the extension) are dropped and the rest renormalised, so a node
/// keeps only the links that move it noticeably (and LBS stays a short sum).
pub const MIN_WEIGHT: f64 = 1e-3;

/// Per node of `prepared.tet`, (link index over [`Link::ALL`], weight) summing to 1: boundary
/// nodes by the barycentric blend of `template`'s skin weights on their face, interior nodes by
/// harmonic extension (see the module documentation). The discrete Laplacian of a mesh with
/// obtuse dihedral angles does not keep the maximum principle exactly, so values are clamped
/// to `[0, 1]` before the renormalisation.
pub fn tet_node_weights(template: &TemplateHand, prepared: &TemplateTet) -> Result<LinkWeights> {
    let n_links = Link::ALL.len();
    let b = &prepared.binding;
    let mut held = Mat::<f64>::zeros(b.nodes.len(), n_links);
    for (r, (&f, bary)) in b.faces.iter().zip(&b.barycentric).enumerate() {
        for (&v, &beta) in template.mesh.faces[f].iter().zip(bary) {
            for &(l, w) in &template.weights[v] {
                held[(r, l)] += beta * w;
            }
        }
    }
    let u = prepared.solver.harmonic_extension(&held)?;
    Ok((0..u.nrows())
        .map(|node| {
            let mut w: Vec<(usize, f64)> = (0..n_links)
                .map(|l| (l, u[(node, l)].clamp(0.0, 1.0)))
                .filter(|&(_, x)| x >= MIN_WEIGHT)
                .collect();
            // Dominant link first, as the template's and bone heat's weights come.
            w.sort_by(|a, b| b.1.total_cmp(&a.1));
            let sum: f64 = w.iter().map(|x| x.1).sum();
            if sum > 0.0 {
                w.iter_mut().for_each(|x| x.1 /= sum);
            } else {
                // Cannot happen for weights that sum to 1 on the boundary (the extension of a
                // constant is that constant); kept total so a node is never left behind.
                let best = (0..n_links)
                    .max_by(|&a, &c| u[(node, a)].total_cmp(&u[(node, c)]))
                    .unwrap_or(0);
                w = vec![(best, 1.0)];
            }
            w
        })
        .collect())
}

/// The nodes of a tetrahedral mesh in a pose: every node skinned (`method`) with `weights`
/// (from [`tet_node_weights`]) by the links' `transforms`, then the boundary nodes of
/// `binding` placed on `posed_skin` at their face and barycentric coordinates (section 3.7's
/// boundary transfer), so the posed mesh's surface is the posed skin exactly rather than within
/// the ~0.1 mm by which skinning a blended weight differs from blending skinned vertices.
/// `posed_skin` must be the hand's skin posed with the same transforms and method.
pub fn pose_tet_nodes(
    rest_nodes: &[Point],
    weights: &LinkWeights,
    binding: &SurfaceBinding,
    posed_skin: &TriMesh,
    transforms: &[Isometry3<f64>],
    method: Skinning,
) -> Result<Vec<Point>> {
    let mut nodes =
        SkinBinding::new(rest_nodes, weights, transforms.len())?.apply(method, transforms);
    place_boundary_nodes(binding, posed_skin, &mut nodes)?;
    Ok(nodes)
}
