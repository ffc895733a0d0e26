//! Skinning weights of the individual skin, per vertex over [`Link::ALL`].
//!
//! Two sources:
//! * [`template_weights`]: the template's weights carried over by homology. The fitted skin has
//!   the template's vertices in the same order (seed paper section 3.5), so vertex `i` of the
//!   skin is the same anatomical point as vertex `i` of the template and keeps its weights.
//!   These are the artist's weights of the generic hand, smoothed by the Loop stencils.
//! * [`bone_heat_weights`]: computed on the individual's own geometry and joint centres by bone
//!   heat diffusion (Baran & Popović 2007, "Automatic rigging and animation of 3D characters",
//!   ACM TOG 26(3), section 4): for each link `l`, solve `(−Δ + H) w_l = H p_l` on the surface.
//!
//! The default ([`WeightMethod::default`]) is the template's weights: see the module
//! documentation of [`crate::pose`] for the measurements behind that choice.

use crate::anatomy::{Finger, Joint, Link};
use crate::error::{Error, Result};
use crate::geometry::closest_point::AabbTree;
use crate::geometry::sparse_cholesky::{CholeskyError, SparseCholesky};
use crate::geometry::{Point, TriMesh, Vec3};
use crate::skeleton::Skeleton;
use crate::template::{LinkWeights, TemplateHand};
use faer::sparse::Triplet;
use faer::Mat;

/// Where the weights of an individual hand come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum WeightMethod {
    /// The template's weights by homology ([`template_weights`]).
    #[default]
    Template,
    /// Bone heat diffusion on the individual skin ([`bone_heat_weights`]).
    BoneHeat,
}

impl WeightMethod {
    /// `"template"` or `"heat"`.
    pub fn name(self) -> &'static str {
        match self {
            WeightMethod::Template => "template",
            WeightMethod::BoneHeat => "heat",
        }
    }
}

/// The template's weights for a skin homologous to it. Errors when `skin` does not have the
/// template's vertex count and faces (it is then not homologous and the weights do not apply).
pub fn template_weights(template: &TemplateHand, skin: &TriMesh) -> Result<LinkWeights> {
    if skin.n_vertices() != template.mesh.n_vertices() || skin.faces != template.mesh.faces {
        return Err(Error::invalid(format!(
            "the skin ({} vertices, {} faces) is not homologous to the {} template ({} vertices, \
             {} faces): template weights do not apply; fit it with the skin stage first",
            skin.n_vertices(),
            skin.n_faces(),
            template.side,
            template.mesh.n_vertices(),
            template.mesh.n_faces()
        )));
    }
    Ok(template.weights.clone())
}

/// A bone segment of a link: the heat source of [`bone_heat_weights`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BoneSegment {
    /// Index in [`Link::ALL`].
    pub link: usize,
    /// Proximal end, mm.
    pub a: Point,
    /// Distal end, mm.
    pub b: Point,
}

impl BoneSegment {
    /// Closest point of the segment to `p`.
    pub fn closest(&self, p: &Point) -> Point {
        let d = self.b - self.a;
        let t = ((p - self.a).dot(&d) / d.norm_squared().max(1e-300)).clamp(0.0, 1.0);
        self.a + d * t
    }
}

/// The bones of the skeleton as segments (Baran & Popović's skeleton "bones"): each digit link
/// from its joint centre to the next joint or the tip; the palm as four segments from the wrist
/// centre to the index..little MCPs (one segment would leave the radial and ulnar palm far from
/// any bone); the forearm from the wrist centre proximally, along the wrist frame's −z, to the
/// most proximal point of `skin`.
pub fn bone_segments(sk: &Skeleton, skin: &TriMesh) -> Vec<BoneSegment> {
    let mut out = Vec::new();
    let w = sk.centre(Joint::Wrist);
    let z = sk.joint(Joint::Wrist).z();
    let back = skin
        .vertices
        .iter()
        .map(|v| -(v - w).dot(&z))
        .fold(1.0, f64::max);
    out.push(BoneSegment {
        link: Link::Arm.index(),
        a: w,
        b: w - z * back,
    });
    for j in [Joint::IMcp, Joint::MMcp, Joint::RMcp, Joint::LMcp] {
        out.push(BoneSegment {
            link: Link::Palm.index(),
            a: w,
            b: sk.centre(j),
        });
    }
    for f in Finger::ALL {
        for j in f.joints() {
            out.push(BoneSegment {
                link: j.child_link().index(),
                a: sk.centre(j),
                b: sk.distal_end(j),
            });
        }
    }
    out
}

/// The cotangent Laplacian of `mesh` (Pinkall & Polthier 1993; Meyer et al. 2003) as the lower
/// triangle of the positive semi-definite stiffness matrix `L` (`L_ij = −½(cot α + cot β)`,
/// `L_ii = −Σ_j L_ij`), and the barycentric lumped mass (a third of the adjacent face areas)
/// per vertex. Cotangents of near-degenerate triangles are clamped to ±1e4.
pub(crate) fn cotangent_laplacian(mesh: &TriMesh) -> (Vec<Triplet<usize, usize, f64>>, Vec<f64>) {
    let mut trip = Vec::with_capacity(mesh.n_faces() * 9);
    let mut mass = vec![0.0; mesh.n_vertices()];
    for f in &mesh.faces {
        let p = f.map(|i| mesh.vertices[i]);
        let area2 = (p[1] - p[0]).cross(&(p[2] - p[0])).norm();
        if area2 <= 1e-300 {
            continue;
        }
        for k in 0..3 {
            mass[f[k]] += area2 / 6.0;
            // The angle at corner k is opposite edge (i, j).
            let (i, j) = (f[(k + 1) % 3], f[(k + 2) % 3]);
            let (u, v) = (p[(k + 1) % 3] - p[k], p[(k + 2) % 3] - p[k]);
            let cot = (u.dot(&v) / area2).clamp(-1e4, 1e4);
            let w = 0.5 * cot;
            trip.push(Triplet::new(i.max(j), i.min(j), -w));
            trip.push(Triplet::new(i, i, w));
            trip.push(Triplet::new(j, j, w));
        }
    }
    (trip, mass)
}

/// Options of [`bone_heat_weights`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeatOptions {
    /// Heat constant `c` of Baran & Popović (they use 1).
    pub c: f64,
    /// Weights below this are dropped before the top `max_links` are kept and renormalised.
    pub min_weight: f64,
    /// Links kept per vertex (glTF carries 4).
    pub max_links: usize,
}

impl Default for HeatOptions {
    fn default() -> Self {
        HeatOptions {
            c: 1.0,
            min_weight: 0.01,
            max_links: 4,
        }
    }
}

/// Bone heat diffusion weights (Baran & Popović 2007, section 4) on `skin` for the bones of
/// `sk` ([`bone_segments`]).
///
/// Per vertex `j`, `d_j` is the distance to the nearest bone segment whose connecting straight
/// line stays inside the skin (a ray cast against the skin: "visible"); `H_jj = c / d_j²` and
/// `p_j` is the indicator of that bone's link; a vertex that sees no bone gets `H_jj = 0` and
/// takes its weights from diffusion alone. The equation `−Δ w_l + H w_l = H p_l` with the
/// cotangent Laplacian `Δ = −M⁻¹ L` is multiplied by the lumped mass `M` to the symmetric
/// positive definite `(L + M H) w_l = M H p_l`, factorised once by faer's sparse Cholesky and
/// solved for all links. The weights of a vertex sum to 1 by linearity (`Σ_l p_l = 1`); the
/// result keeps the `max_links` largest above `min_weight`, renormalised.
///
/// Errors when no vertex sees a bone (the skeleton is outside the skin) or the factorisation
/// fails (a connected component of the skin that sees no bone).
pub fn bone_heat_weights(skin: &TriMesh, sk: &Skeleton, opts: &HeatOptions) -> Result<LinkWeights> {
    let n = skin.n_vertices();
    let bones = bone_segments(sk, skin);
    let tree = AabbTree::new(skin);
    let scale = skin.diagonal().max(1.0);
    // Nearest visible bone per vertex.
    let mut heat = vec![0.0; n];
    let mut link = vec![usize::MAX; n];
    let mut order: Vec<(f64, usize)> = Vec::with_capacity(bones.len());
    for (i, v) in skin.vertices.iter().enumerate() {
        order.clear();
        order.extend(
            bones
                .iter()
                .enumerate()
                .map(|(k, b)| ((b.closest(v) - v).norm(), k)),
        );
        order.sort_by(|a, b| a.0.total_cmp(&b.0));
        for &(d, k) in order.iter().take(4) {
            let q = bones[k].closest(v);
            let dir: Vec3 = q - v;
            // The ray leaves the vertex's own faces at t ≈ 0; anything hit later is in the way.
            let t_min = 1e-6 * scale / d.max(1e-9);
            let visible = d < 1e-9 || tree.ray_cast(v, &dir, t_min.min(0.5), 1.0 - 1e-9).is_none();
            if visible {
                heat[i] = opts.c / (d * d).max(1e-12);
                link[i] = bones[k].link;
                break;
            }
        }
    }
    if link.iter().all(|&l| l == usize::MAX) {
        return Err(Error::invalid(
            "bone heat weights: no skin vertex sees a bone; the skeleton lies outside the skin",
        ));
    }
    let (mut trip, mass) = cotangent_laplacian(skin);
    for i in 0..n {
        trip.push(Triplet::new(i, i, mass[i] * heat[i]));
    }
    let factor = SparseCholesky::new(n, &trip).map_err(|e| {
        let (CholeskyError::Structure(e) | CholeskyError::NotPositiveDefinite(e)) = e;
        Error::invalid(format!(
            "bone heat weights: the heat system could not be factorised ({e}); every part of \
             the skin must see a bone"
        ))
    })?;
    let n_links = Link::ALL.len();
    let mut rhs = Mat::<f64>::zeros(n, n_links);
    for i in 0..n {
        if link[i] != usize::MAX {
            rhs[(i, link[i])] = mass[i] * heat[i];
        }
    }
    factor.solve(&mut rhs);
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let mut w: Vec<(usize, f64)> = (0..n_links)
            .map(|l| (l, rhs[(i, l)]))
            .filter(|x| x.1.is_finite() && x.1 >= opts.min_weight)
            .collect();
        w.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        w.truncate(opts.max_links.max(1));
        let s: f64 = w.iter().map(|x| x.1).sum();
        if w.is_empty() || s <= 0.0 {
            // Diffusion reached nowhere near this vertex: follow its nearest bone rigidly.
            let l = if link[i] != usize::MAX {
                link[i]
            } else {
                nearest_link(&bones, &skin.vertices[i])
            };
            out.push(vec![(l, 1.0)]);
            continue;
        }
        for x in &mut w {
            x.1 /= s;
        }
        out.push(w);
    }
    Ok(out)
}

fn nearest_link(bones: &[BoneSegment], p: &Point) -> usize {
    bones
        .iter()
        .min_by(|a, b| {
            (a.closest(p) - p)
                .norm_squared()
                .total_cmp(&(b.closest(p) - p).norm_squared())
        })
        .map(|b| b.link)
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::anatomy::Side;
    use crate::template::{dominant_links, load_template};

    /// The cotangent Laplacian annihilates constants and reproduces the mean-curvature identity
    /// `L x = 2 H n A` on a sphere: `Σ_i (L x)_i · x_i / |x_i| ≈ 2 · area / r` (here checked
    /// as the integral of 2/r over the sphere to within the discretisation).
    #[test]
    fn cotangent_laplacian_properties() {
        let r = 10.0;
        let m = crate::geometry::mesh::tests::icosphere(r, 3);
        let (trip, mass) = cotangent_laplacian(&m);
        let n = m.n_vertices();
        let mut lx = vec![Vec3::zeros(); n];
        let mut row_sum = vec![0.0; n];
        for t in &trip {
            let (i, j, v) = (t.row, t.col, t.val);
            row_sum[i] += v;
            lx[i] += m.vertices[j].coords * v;
            if i != j {
                row_sum[j] += v;
                lx[j] += m.vertices[i].coords * v;
            }
        }
        assert!(row_sum.iter().all(|s| s.abs() < 1e-9));
        let area: f64 = mass.iter().sum();
        assert!((area - m.area()).abs() < 1e-9 * area);
        let integral: f64 = (0..n)
            .map(|i| lx[i].dot(&m.vertices[i].coords.normalize()))
            .sum();
        let want = 2.0 * m.area() / r;
        assert!(
            (integral - want).abs() < 0.02 * want,
            "{integral} vs {want}"
        );
    }

    /// On the template, heat weights are a partition of unity, and each vertex's dominant link
    /// mostly agrees with the artist's: fingers by segment, the palm as the palm.
    #[test]
    fn heat_weights_on_the_template_follow_the_links() {
        let t = load_template(Side::Right).unwrap();
        let w = bone_heat_weights(&t.mesh, &t.skeleton, &HeatOptions::default()).unwrap();
        assert_eq!(w.len(), t.mesh.n_vertices());
        for x in &w {
            assert!(!x.is_empty() && x.len() <= 4);
            assert!((x.iter().map(|a| a.1).sum::<f64>() - 1.0).abs() < 1e-9);
        }
        let (a, b) = (dominant_links(&w), dominant_links(&t.weights));
        let agree = a.iter().zip(&b).filter(|(x, y)| x == y).count() as f64 / a.len() as f64;
        assert!(agree > 0.75, "dominant link agreement {agree:.3}");
        // Fingertips belong to their distal links.
        for (f, l) in [(Finger::Index, Link::IDist), (Finger::Little, Link::LDist)] {
            let tip = t.skeleton.tips[f as usize];
            let v = (0..t.mesh.n_vertices())
                .min_by(|&i, &j| {
                    (t.mesh.vertices[i] - tip)
                        .norm()
                        .total_cmp(&(t.mesh.vertices[j] - tip).norm())
                })
                .unwrap();
            assert_eq!(a[v], l.index(), "{f:?}");
        }
    }

    #[test]
    fn template_weights_need_homology() {
        let t = load_template(Side::Left).unwrap();
        assert_eq!(template_weights(&t, &t.mesh).unwrap(), t.weights);
        let e = template_weights(&t, &crate::geometry::mesh::tests::icosphere(5.0, 1)).unwrap_err();
        assert!(e.to_string().contains("not homologous"), "{e}");
    }
}
