//! Untangling by the regularised Winslow functional (Garanzha, Kaporin, Kudryavtseva, Protais,
//! Ray & Sokolov 2021, "Foldover-free maps in 50 lines of code", ACM ToG 40(4)).
//!
//! Each element's Jacobian `J` maps its reference shape to its current one; the energy
//!
//! `E_ε = Σ_t w_t [ tr(JᵀJ) / χ(det J, ε)^{2/3} + (det J² + 1) / χ(det J, ε) ]`,
//! `χ(D, ε) = (D + √(ε² + D²)) / 2`,
//!
//! is finite for inverted elements (`χ > 0` for every `D` when `ε > 0`) and tends to a barrier
//! as `ε → 0`. Minimising it for a decreasing sequence of `ε` (the paper's rule) drives every
//! determinant positive together, without the local minima of a penalty on the negative volumes
//! alone: an element moves out of the way of its neighbours because their shape, not only
//! their sign, is in the cost. The minimiser is L-BFGS over the free nodes, the others held.
//!
//! The reference shape of an element is the regular tetrahedron of its reference volume, so a
//! mesh needs no rest positions, only rest volumes.

use super::elastic::cofactor;
use crate::geometry::tet_mesh::element_signed_volume;
use crate::geometry::{Point, Vec3};
use nalgebra::Matrix3;

/// `χ(D, ε)` of the module documentation and its derivative in `D`.
fn chi(d: f64, eps: f64) -> (f64, f64) {
    let r = (eps * eps + d * d).sqrt();
    (0.5 * (d + r), 0.5 * (1.0 + d / r))
}

/// The inverse edge matrix of the regular tetrahedron of volume `volume` (edges as columns from
/// its first corner), positively oriented.
fn regular_inverse(volume: f64) -> Matrix3<f64> {
    let e = Matrix3::new(
        1.0,
        0.5,
        0.5,
        0.0,
        3f64.sqrt() / 2.0,
        3f64.sqrt() / 6.0,
        0.0,
        0.0,
        (2.0f64 / 3.0).sqrt(),
    );
    // The unit-edge regular tetrahedron's volume is `det e / 6 = 1 / (6√2)`.
    let scale = (volume.abs().max(1e-300) / e.determinant() * 6.0).cbrt();
    (e * scale).try_inverse().unwrap_or_else(Matrix3::identity)
}

/// The problem of the module documentation on the elements `elems` of `tets`, the nodes
/// `free` moving (the others held at `nodes`).
struct Problem<'a> {
    tets: &'a [[usize; 4]],
    elems: Vec<usize>,
    /// Per element of `elems`: its reference shape's inverse edge matrix and weight.
    shape: Vec<(Matrix3<f64>, f64)>,
    /// Node -> its column among the free nodes (`usize::MAX` when held).
    column: Vec<usize>,
    free: Vec<usize>,
}

impl Problem<'_> {
    fn edge_matrix(&self, nodes: &[Point], t: usize) -> Matrix3<f64> {
        let [a, b, c, d] = self.tets[t].map(|i| nodes[i]);
        Matrix3::from_columns(&[b - a, c - a, d - a])
    }

    fn min_det(&self, nodes: &[Point]) -> f64 {
        self.elems
            .iter()
            .zip(&self.shape)
            .map(|(&t, (s, _))| (self.edge_matrix(nodes, t) * s).determinant())
            .fold(f64::INFINITY, f64::min)
    }

    /// The energy at `nodes` and, if `grad` is given, its gradient over the free nodes.
    fn energy(&self, nodes: &[Point], eps: f64, mut grad: Option<&mut [f64]>) -> f64 {
        if let Some(g) = grad.as_deref_mut() {
            g.fill(0.0);
        }
        let mut e = 0.0;
        for (&t, (s, w)) in self.elems.iter().zip(&self.shape) {
            let j = self.edge_matrix(nodes, t) * s;
            let det = j.determinant();
            let (c, dc) = chi(det, eps);
            let c23 = c.powf(2.0 / 3.0);
            let f = j.norm_squared() / c23;
            let g = (det * det + 1.0) / c;
            e += w * (f + g);
            let Some(grad) = grad.as_deref_mut() else {
                continue;
            };
            let k = cofactor(&j);
            let df = j * (2.0 / c23) - k * (f * dc * 2.0 / (3.0 * c));
            let dg = k * ((2.0 * det - g * dc) / c);
            // J = E S: ∂/∂E = ∂/∂J Sᵀ; E's columns are corners 1..3 minus corner 0.
            let de = (df + dg) * s.transpose() * *w;
            let tet = self.tets[t];
            for (corner, &v) in tet.iter().enumerate() {
                let col = self.column[v];
                if col == usize::MAX {
                    continue;
                }
                let d: Vec3 = if corner == 0 {
                    -(de.column(0) + de.column(1) + de.column(2))
                } else {
                    de.column(corner - 1).into()
                };
                for a in 0..3 {
                    grad[3 * col + a] += d[a];
                }
            }
        }
        e
    }

    fn set(&self, nodes: &mut [Point], x: &[f64]) {
        for (k, &v) in self.free.iter().enumerate() {
            nodes[v] = Point::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]);
        }
    }
}

/// L-BFGS iterations at most per value of `ε`.
const LBFGS_ITERATIONS: usize = 200;

/// The first `ε` (see [`untangle_winslow`]).
const INITIAL_EPS: f64 = 0.1;

/// Values of `ε` at most.
const EPS_ROUNDS: usize = 30;

/// Move the nodes `free` of the mesh of `tets` (the other nodes held) so that every element
/// around them has a positive volume, by the ε-continuation of the module documentation.
/// `reference` gives each element's reference volume (its absolute value is used). Stops as
/// soon as every element around the free nodes is positive; returns whether it got there.
pub fn untangle_winslow(
    nodes: &mut [Point],
    tets: &[[usize; 4]],
    free: &[usize],
    reference: &[f64],
) -> bool {
    let n = nodes.len();
    let mut column = vec![usize::MAX; n];
    for (k, &v) in free.iter().enumerate() {
        column[v] = k;
    }
    let elems: Vec<usize> = (0..tets.len())
        .filter(|&t| tets[t].iter().any(|&v| column[v] != usize::MAX))
        .collect();
    let total: f64 = elems
        .iter()
        .map(|&t| reference[t].abs())
        .sum::<f64>()
        .max(1e-300);
    let shape = elems
        .iter()
        .map(|&t| (regular_inverse(reference[t]), reference[t].abs() / total))
        .collect();
    let p = Problem {
        tets,
        elems,
        shape,
        column,
        free: free.to_vec(),
    };
    let positive = |nodes: &[Point]| {
        p.elems
            .iter()
            .all(|&t| element_signed_volume(nodes, &tets[t]) > 0.0)
    };
    let already = positive(nodes);
    if free.is_empty() || already {
        return already;
    }
    let mut x: Vec<f64> = free
        .iter()
        .flat_map(|&v| [nodes[v].x, nodes[v].y, nodes[v].z])
        .collect();
    let mut detmin = p.min_det(nodes);
    // The regularisation starts where an element is a tenth of its reference volume (the
    // penalty's target): smaller, the energy is a near-barrier from the first step and L-BFGS
    // crawls; the paper's rule then brings it down.
    let mut eps = INITIAL_EPS.max(0.2 * -detmin.min(0.0));
    for _ in 0..EPS_ROUNDS {
        let before = p.energy(nodes, eps, None);
        lbfgs(&p, nodes, &mut x, eps);
        p.set(nodes, &x);
        if positive(nodes) {
            return true;
        }
        let after = p.energy(nodes, eps, None);
        detmin = p.min_det(nodes);
        // The paper's update: ε follows the smallest determinant down, faster when the energy
        // fell little.
        let sigma = (1.0 - after / before).max(0.1);
        let mu = (1.0 - sigma) * chi(detmin, eps).0;
        eps = if detmin < mu {
            2.0 * (mu * (mu - detmin)).sqrt()
        } else {
            1e-10
        };
    }
    positive(nodes)
}

/// Memory of [`lbfgs`].
const LBFGS_MEMORY: usize = 8;

/// Minimise `p`'s energy at `eps` over `x` (the free nodes' coordinates) by L-BFGS with a
/// backtracking (Armijo) line search; `nodes` holds the held nodes and is left at `x`.
fn lbfgs(p: &Problem, nodes: &mut [Point], x: &mut [f64], eps: f64) {
    let m = x.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(u, v)| u * v).sum::<f64>();
    let mut g = vec![0.0; m];
    p.set(nodes, x);
    let mut f = p.energy(nodes, eps, Some(&mut g));
    let mut history: Vec<(Vec<f64>, Vec<f64>, f64)> = Vec::new();
    let mut g_new = vec![0.0; m];
    for _ in 0..LBFGS_ITERATIONS {
        // Two-loop recursion for the direction.
        let mut q: Vec<f64> = g.iter().map(|v| -v).collect();
        let mut alphas = Vec::with_capacity(history.len());
        for (s, y, rho) in history.iter().rev() {
            let a = rho * dot(s, &q);
            for (qi, yi) in q.iter_mut().zip(y) {
                *qi -= a * yi;
            }
            alphas.push(a);
        }
        let gamma = history
            .last()
            .map(|(s, y, _)| dot(s, y) / dot(y, y))
            .unwrap_or_else(|| 1.0 / dot(&g, &g).sqrt().max(1e-300));
        for qi in q.iter_mut() {
            *qi *= gamma;
        }
        for ((s, y, rho), a) in history.iter().zip(alphas.iter().rev()) {
            let b = rho * dot(y, &q);
            for (qi, si) in q.iter_mut().zip(s) {
                *qi += (a - b) * si;
            }
        }
        let mut slope = dot(&g, &q);
        if slope >= 0.0 {
            // Not a descent direction: restart from the gradient.
            history.clear();
            let norm = dot(&g, &g).sqrt().max(1e-300);
            q = g.iter().map(|v| -v / norm).collect();
            slope = dot(&g, &q);
        }
        let mut step = 1.0;
        let mut trial = vec![0.0; m];
        let mut accepted = None;
        for _ in 0..40 {
            for k in 0..m {
                trial[k] = x[k] + step * q[k];
            }
            p.set(nodes, &trial);
            let ft = p.energy(nodes, eps, Some(&mut g_new));
            if ft.is_finite() && ft <= f + 1e-4 * step * slope {
                accepted = Some(ft);
                break;
            }
            step *= 0.5;
        }
        let Some(ft) = accepted else {
            p.set(nodes, x);
            return;
        };
        let s: Vec<f64> = (0..m).map(|k| trial[k] - x[k]).collect();
        let y: Vec<f64> = (0..m).map(|k| g_new[k] - g[k]).collect();
        let sy = dot(&s, &y);
        x.copy_from_slice(&trial);
        std::mem::swap(&mut g, &mut g_new);
        let converged = (f - ft).abs() <= 1e-12 * f.abs().max(1.0);
        f = ft;
        if sy > 1e-300 {
            history.push((s, y, 1.0 / sy));
            if history.len() > LBFGS_MEMORY {
                history.remove(0);
            }
        }
        if converged {
            break;
        }
    }
    p.set(nodes, x);
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cube of 5 x 5 x 5 nodes 1 mm apart cut into Kuhn tetrahedra, the 27 nodes off its faces
    /// moved at random (seeded) by up to 0.9 mm along each axis, which inverts some of
    /// their elements: the nodes, the elements and the moved nodes.
    fn scrambled_cube(seed: u64) -> (Vec<Point>, Vec<[usize; 4]>, Vec<usize>) {
        let k = 5;
        let id = |i: usize, j: usize, l: usize| (i * k + j) * k + l;
        let mut nodes = Vec::new();
        for i in 0..k {
            for j in 0..k {
                for l in 0..k {
                    nodes.push(Point::new(i as f64, j as f64, l as f64));
                }
            }
        }
        let mut tets = Vec::new();
        for i in 0..k - 1 {
            for j in 0..k - 1 {
                for l in 0..k - 1 {
                    let c = |b: u8| {
                        let b = usize::from(b);
                        id(i + (b & 1), j + ((b >> 1) & 1), l + ((b >> 2) & 1))
                    };
                    for t in crate::geometry::marching_tetrahedra::kuhn_tetrahedra() {
                        tets.push(t.map(c));
                    }
                }
            }
        }
        let interior: Vec<usize> = (0..nodes.len())
            .filter(|&v| {
                let p = nodes[v];
                [p.x, p.y, p.z]
                    .iter()
                    .all(|c| *c > 0.5 && *c < (k - 1) as f64 - 0.5)
            })
            .collect();
        let mut rng = crate::rng::Rng::new(seed);
        for &v in &interior {
            for a in 0..3 {
                nodes[v].coords[a] += rng.range(-0.9, 0.9);
            }
        }
        (nodes, tets, interior)
    }

    /// The energy's gradient against central differences, on a mesh with an inverted element.
    #[test]
    fn gradient_matches_differences() {
        let mut nodes = vec![
            Point::new(0.0, 0.0, 0.0),
            Point::new(1.0, 0.0, 0.0),
            Point::new(0.0, 1.0, 0.0),
            Point::new(0.0, 0.0, 1.0),
            Point::new(0.3, 0.2, -0.4),
        ];
        let tets = vec![[0, 1, 2, 3], [4, 2, 1, 3]];
        let reference = [1.0 / 6.0, 0.2];
        let p = Problem {
            tets: &tets,
            elems: vec![0, 1],
            shape: reference
                .iter()
                .map(|v| (regular_inverse(*v), 1.0))
                .collect(),
            column: vec![0, usize::MAX, 1, usize::MAX, 2],
            free: vec![0, 2, 4],
        };
        for eps in [0.1, 1.0] {
            let mut g = vec![0.0; 9];
            p.energy(&nodes, eps, Some(&mut g));
            for (k, &v) in p.free.iter().enumerate() {
                for a in 0..3 {
                    let h = 1e-6;
                    let x0 = nodes[v].coords[a];
                    nodes[v].coords[a] = x0 + h;
                    let up = p.energy(&nodes, eps, None);
                    nodes[v].coords[a] = x0 - h;
                    let down = p.energy(&nodes, eps, None);
                    nodes[v].coords[a] = x0;
                    let fd = (up - down) / (2.0 * h);
                    assert!(
                        (fd - g[3 * k + a]).abs() <= 1e-5 * fd.abs().max(1.0),
                        "eps {eps} node {v} axis {a}: {fd} vs {}",
                        g[3 * k + a]
                    );
                }
            }
        }
    }

    /// The scrambled cube's inverted elements come back positive with its faces held, and the
    /// held nodes do not move.
    #[test]
    fn scrambled_interior_of_a_cube_is_untangled() {
        let (mut nodes, tets, interior) = scrambled_cube(7);
        let reference = vec![1.0 / 6.0; tets.len()];
        let inverted = tets
            .iter()
            .filter(|t| element_signed_volume(&nodes, t) <= 0.0)
            .count();
        assert!(inverted >= 10, "the scramble inverts elements ({inverted})");
        let before = nodes.clone();
        assert!(untangle_winslow(&mut nodes, &tets, &interior, &reference));
        assert!(tets.iter().all(|t| element_signed_volume(&nodes, t) > 0.0));
        for v in 0..nodes.len() {
            if !interior.contains(&v) {
                assert_eq!(nodes[v], before[v]);
            }
        }
    }

    /// The reference shape is the regular tetrahedron of the given volume: its own edge matrix
    /// maps to the identity, and a regular tetrahedron of that volume has determinant one.
    #[test]
    fn the_reference_shape_has_the_reference_volume() {
        let s = regular_inverse(2.5);
        assert!((s.determinant() - 1.0 / (6.0 * 2.5)).abs() < 1e-12);
    }
}
