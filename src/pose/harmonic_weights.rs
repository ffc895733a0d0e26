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
pub(crate) const MIN_WEIGHT: f64 = 1e-3;

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

/// The node weights of `template`'s tetrahedral mesh as a file of the tet cache
/// ([`crate::tet::cache`]): they depend on the template alone, and computing them takes the
/// elastic stiffness factorisation, so `reconstruct` stores them ([`store_tet_node_weights`])
/// and `pose` reads them ([`cached_tet_node_weights`]) instead of preparing the template's
/// tetrahedral stage again. Layout (little-endian): magic `ERGOWTS\0`, the template tet mesh's
/// cache key `u64`, node count `u64`, per node a link count `u8` and that many (link `u8`,
/// weight `f64`).
fn weights_path(template: &TemplateHand) -> Option<(std::path::PathBuf, u64)> {
    let key = crate::tet::cache::cache_key(&template.mesh, &crate::tet::StuffingParams::default());
    let dir = crate::tet::cache::default_cache_dir()?;
    Some((dir.join(format!("tet-weights-{key:016x}.bin")), key))
}

const WEIGHTS_MAGIC: &[u8; 8] = b"ERGOWTS\0";

fn encode_weights(w: &LinkWeights, key: u64) -> Vec<u8> {
    let mut b = Vec::with_capacity(24 + w.len() * 20);
    b.extend_from_slice(WEIGHTS_MAGIC);
    b.extend_from_slice(&key.to_le_bytes());
    b.extend_from_slice(&(w.len() as u64).to_le_bytes());
    for node in w {
        b.push(node.len() as u8);
        for &(l, x) in node {
            b.push(l as u8);
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    b
}

/// `None` unless everything checks out: magic, key, node count, link indices, finite weights
/// summing to 1, no byte left over.
fn decode_weights(b: &[u8], key: u64, nodes: usize) -> Option<LinkWeights> {
    if b.len() < 24 || &b[..8] != WEIGHTS_MAGIC {
        return None;
    }
    let word = |i: usize| u64::from_le_bytes(b[i..i + 8].try_into().unwrap_or([0; 8]));
    if word(8) != key || word(16) != nodes as u64 {
        return None;
    }
    let mut at = 24;
    let mut out = Vec::with_capacity(nodes);
    for _ in 0..nodes {
        let n = *b.get(at)? as usize;
        at += 1;
        let mut node = Vec::with_capacity(n);
        for _ in 0..n {
            let l = *b.get(at)? as usize;
            let x = f64::from_le_bytes(b.get(at + 1..at + 9)?.try_into().ok()?);
            if l >= Link::ALL.len() || !x.is_finite() {
                return None;
            }
            node.push((l, x));
            at += 9;
        }
        if n == 0 || (node.iter().map(|x| x.1).sum::<f64>() - 1.0).abs() > 1e-9 {
            return None;
        }
        out.push(node);
    }
    (at == b.len()).then_some(out)
}

/// Store the node weights of `template`'s tetrahedral mesh in the tet cache (atomically; a
/// cache that cannot be written is skipped, as for the mesh itself).
pub fn store_tet_node_weights(template: &TemplateHand, weights: &LinkWeights) {
    if let Some((path, key)) = weights_path(template) {
        if let Some(dir) = path.parent() {
            let _ = std::fs::create_dir_all(dir);
        }
        let _ = crate::io::atomic::write_bytes_atomic(&path, &encode_weights(weights, key));
    }
}

/// The node weights of `template`'s tetrahedral mesh of `nodes` nodes from the tet cache, when
/// a valid entry is there.
pub fn cached_tet_node_weights(template: &TemplateHand, nodes: usize) -> Option<LinkWeights> {
    let (path, key) = weights_path(template)?;
    decode_weights(&std::fs::read(path).ok()?, key, nodes)
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The cache file gives back the weights bit for bit, and refuses another template's key,
    /// another node count, and every truncation or a weight that no longer sums to 1.
    #[test]
    fn cached_weights_round_trip_and_refuse_what_does_not_check_out() {
        let w: LinkWeights = vec![
            vec![(0, 1.0)],
            vec![(3, 0.625), (4, 0.375)],
            vec![(Link::ALL.len() - 1, 0.1), (2, 0.2), (1, 0.7)],
        ];
        let b = encode_weights(&w, 7);
        assert_eq!(decode_weights(&b, 7, 3), Some(w.clone()));
        assert_eq!(decode_weights(&b, 8, 3), None);
        assert_eq!(decode_weights(&b, 7, 2), None);
        for cut in 0..b.len() {
            assert_eq!(decode_weights(&b[..cut], 7, 3), None, "cut at {cut}");
        }
        let mut longer = b.clone();
        longer.push(0);
        assert_eq!(decode_weights(&longer, 7, 3), None);
        // The second node's first weight 0.625 -> 0.5: its weights sum to 0.875.
        let mut bad = b.clone();
        let at = 24 + 10 + 2;
        bad[at..at + 8].copy_from_slice(&0.5f64.to_le_bytes());
        assert_eq!(decode_weights(&bad, 7, 3), None);
        let mut link = b.clone();
        link[24 + 10 + 1] = Link::ALL.len() as u8;
        assert_eq!(decode_weights(&link, 7, 3), None);
    }
}
