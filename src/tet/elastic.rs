//! Interior nodes of a tetrahedral mesh by elastic equilibrium with the boundary held (seed
//! paper section 3.7, step 3, where the paper let a Bullet soft body settle).
//!
//! The energy is volumetric as-rigid-as-possible (Sorkine & Alexa 2007, "As-rigid-as-possible
//! surface modeling", in its per-element FEM form, e.g. Chao et al. 2010, "A simple
//! geometric model for elastic deformations"): `E(x) = Σ_t V_t |F_t(x) - R_t|²_F`, with `F_t` the
//! deformation gradient of the linear tetrahedron `t` (rest volume `V_t`) and `R_t` the rotation
//! nearest to it. It is minimised by local/global alternation:
//! * **local**: `R_t` = the rotation of the polar decomposition of `F_t` (SVD, reflection
//!   removed);
//! * **global**: `K x = b(R)`, `K_ij = Σ_t V_t ∇φ_i · ∇φ_j` the linear-FEM (cotangent)
//!   Laplacian and `b_i = Σ_t V_t R_t ∇φ_i`, over the free nodes with the boundary nodes as
//!   Dirichlet values. `K` restricted to the free nodes never changes, so faer's sparse
//!   Cholesky factorises it once.
//!
//! The initial guess is the harmonic map (`R = 0`): for an interior node `Σ_t V_t ∇φ_i = 0`, so
//! the FEM Laplacian reproduces every affine map of the boundary exactly; and an affine map
//! `x ↦ A x + c` is a fixed point of the iteration too (all `R_t` equal, `b_i = R Σ_t V_t ∇φ_i =
//! 0`). Hence a rigid motion and a uniform scaling of the boundary carry the interior along
//! exactly (to the solver's rounding), as a homogeneous deformation is also the equilibrium of a
//! continuum elastic body.

use crate::error::{Error, Result};
use crate::geometry::sparse_cholesky::{CholeskyError, SparseCholesky};
use crate::geometry::tet_mesh::TetMesh;
use crate::geometry::{Point, Vec3};
use faer::sparse::Triplet;
use faer::Mat;
use nalgebra::Matrix3;
use rayon::prelude::*;
use serde::Serialize;

/// Options of [`ElasticSolver::solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ArapOptions {
    /// Most local/global iterations after the harmonic initial guess.
    pub max_iterations: usize,
    /// Stop when no node moves more than this in an iteration, mm.
    pub tolerance_mm: f64,
}

impl Default for ArapOptions {
    fn default() -> Self {
        ArapOptions {
            max_iterations: 100,
            tolerance_mm: 1e-4,
        }
    }
}

/// How a solve went.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ElasticStats {
    /// Local/global iterations run.
    pub iterations: usize,
    /// Largest node move in the last iteration, mm.
    pub last_change_mm: f64,
    /// Whether the last change fell below the tolerance.
    pub converged: bool,
    /// ARAP energy `Σ V_t |F_t - R_t|²` at the result, mm³.
    pub energy: f64,
}

/// The prefactorised volumetric ARAP problem of one rest mesh and one set of held nodes.
pub struct ElasticSolver {
    tets: Vec<[usize; 4]>,
    /// Per tetrahedron: rest volume and the gradients of its four hat functions.
    volume: Vec<f64>,
    grad: Vec<[Vec3; 4]>,
    /// Per node: its index among the free nodes, or `usize::MAX` when held.
    free_index: Vec<usize>,
    fixed: Vec<usize>,
    n_free: usize,
    factor: SparseCholesky,
}

impl ElasticSolver {
    /// Precompute gradients and factorise the free block of the FEM Laplacian of `rest`, with
    /// the nodes `fixed` held. Errors (one line) when a rest tetrahedron is flat or inverted,
    /// a held node does not exist, or the free block is singular (a free part not attached to
    /// any held node).
    pub fn new(rest: &TetMesh, fixed: &[usize]) -> Result<Self> {
        let n = rest.n_nodes();
        if fixed.is_empty() {
            return Err(Error::invalid(
                "elastic solve: no held node, so the equilibrium is not unique",
            ));
        }
        let mut free_index = vec![0usize; n];
        for &v in fixed {
            if v >= n {
                return Err(Error::invalid(format!(
                    "held node {v} does not exist (the tet mesh has {n} nodes)"
                )));
            }
            free_index[v] = usize::MAX;
        }
        let mut n_free = 0;
        for f in free_index.iter_mut() {
            if *f != usize::MAX {
                *f = n_free;
                n_free += 1;
            }
        }
        let mut volume = Vec::with_capacity(rest.n_tets());
        let mut grad = Vec::with_capacity(rest.n_tets());
        for t in 0..rest.n_tets() {
            let [a, b, c, d] = rest.corners(t);
            let dm = Matrix3::from_columns(&[b - a, c - a, d - a]);
            let v = dm.determinant() / 6.0;
            let inv = dm.try_inverse().filter(|_| v > 0.0).ok_or_else(|| {
                Error::invalid(format!(
                    "rest tetrahedron {t} is flat or inverted (volume {v:e} mm³)"
                ))
            })?;
            // Rows of Dm⁻¹ are the gradients of the hat functions of corners 1..3.
            let g1 = inv.row(0).transpose();
            let g2 = inv.row(1).transpose();
            let g3 = inv.row(2).transpose();
            volume.push(v);
            grad.push([-(g1 + g2 + g3), g1, g2, g3]);
        }
        let mut trip = Vec::new();
        for (t, tet) in rest.tets.iter().enumerate() {
            for a in 0..4 {
                let i = free_index[tet[a]];
                if i == usize::MAX {
                    continue;
                }
                for b in 0..4 {
                    let j = free_index[tet[b]];
                    if j == usize::MAX || j < i {
                        continue;
                    }
                    let k = volume[t] * grad[t][a].dot(&grad[t][b]);
                    // Lower triangle: row >= column.
                    trip.push(Triplet::new(j, i, k));
                }
            }
        }
        let factor = SparseCholesky::new(n_free, &trip).map_err(|e| match e {
            CholeskyError::Structure(e) => {
                Error::invalid(format!("elastic solve: sparse Cholesky failed: {e}"))
            }
            CholeskyError::NotPositiveDefinite(_) => Error::invalid(
                "elastic solve: the stiffness matrix is singular (a part of the tet mesh \
                 touches no held node)",
            ),
        })?;
        Ok(ElasticSolver {
            tets: rest.tets.clone(),
            volume,
            grad,
            free_index,
            fixed: fixed.to_vec(),
            n_free,
            factor,
        })
    }

    /// The held nodes, in the order [`Self::solve`] expects their positions.
    pub fn fixed(&self) -> &[usize] {
        &self.fixed
    }

    /// Node positions at equilibrium with the held nodes at `held` (one per
    /// [`Self::fixed`], same order). Errors when the count differs or a position is not
    /// finite.
    pub fn solve(&self, held: &[Point], opts: &ArapOptions) -> Result<(Vec<Point>, ElasticStats)> {
        if held.len() != self.fixed.len() {
            return Err(Error::invalid(format!(
                "elastic solve: {} held positions given for {} held nodes",
                held.len(),
                self.fixed.len()
            )));
        }
        if let Some(i) = held
            .iter()
            .position(|p| !p.coords.iter().all(|c| c.is_finite()))
        {
            return Err(Error::invalid(format!(
                "elastic solve: held position {i} (node {}) is not finite",
                self.fixed[i]
            )));
        }
        let n = self.free_index.len();
        let mut x = vec![Point::origin(); n];
        for (&v, p) in self.fixed.iter().zip(held) {
            x[v] = *p;
        }
        let mut rotations = vec![Matrix3::zeros(); self.tets.len()];
        self.global_step(&mut x, &rotations);
        let mut stats = ElasticStats {
            iterations: 0,
            last_change_mm: 0.0,
            converged: self.n_free == 0,
            energy: 0.0,
        };
        while !stats.converged && stats.iterations < opts.max_iterations {
            self.local_step(&x, &mut rotations);
            let before = x.clone();
            self.global_step(&mut x, &rotations);
            stats.iterations += 1;
            stats.last_change_mm = x
                .iter()
                .zip(&before)
                .map(|(a, b)| (a - b).norm())
                .fold(0.0, f64::max);
            stats.converged = stats.last_change_mm < opts.tolerance_mm;
        }
        self.local_step(&x, &mut rotations);
        stats.energy = (0..self.tets.len())
            .map(|t| {
                self.volume[t] * (self.deformation_gradient(&x, t) - rotations[t]).norm_squared()
            })
            .sum();
        Ok((x, stats))
    }

    /// The harmonic extension of scalar fields given on the held nodes: per column `k` of
    /// `held` (one row per [`Self::fixed`] node, same order), the values `u` at every node that
    /// solve `K u = 0` on the free nodes with `u = held` on the held ones (the discrete Laplace
    /// equation of the linear FEM, with the same prefactorised `K`). Used to carry skinning
    /// weights from the surface into the volume; like the positions, an affine field is
    /// reproduced exactly. Returns one row per node. Errors when the row count differs.
    pub fn harmonic_extension(&self, held: &Mat<f64>) -> Result<Mat<f64>> {
        if held.nrows() != self.fixed.len() {
            return Err(Error::invalid(format!(
                "harmonic extension: {} held rows given for {} held nodes",
                held.nrows(),
                self.fixed.len()
            )));
        }
        let k = held.ncols();
        let n = self.free_index.len();
        let mut row_of_fixed = vec![usize::MAX; n];
        for (r, &v) in self.fixed.iter().enumerate() {
            row_of_fixed[v] = r;
        }
        let mut rhs = Mat::<f64>::zeros(self.n_free, k);
        self.for_each_free_corner(|t, a, i| {
            for (node, kab) in self.held_couplings(t, a) {
                let r = row_of_fixed[node];
                for c in 0..k {
                    rhs[(i, c)] -= kab * held[(r, c)];
                }
            }
        });
        self.factor.solve(&mut rhs);
        let mut out = Mat::<f64>::zeros(n, k);
        for node in 0..n {
            let (src, row) = match (self.free_index[node], row_of_fixed[node]) {
                (usize::MAX, r) => (held, r),
                (i, _) => (&rhs, i),
            };
            for c in 0..k {
                out[(node, c)] = src[(row, c)];
            }
        }
        Ok(out)
    }

    /// Calls `visit(t, a, i)` for every corner `a` of every tetrahedron `t` whose node is free
    /// (row `i` of the reduced system): the rows a right-hand side is assembled on.
    fn for_each_free_corner(&self, mut visit: impl FnMut(usize, usize, usize)) {
        for (t, tet) in self.tets.iter().enumerate() {
            for (a, &node) in tet.iter().enumerate() {
                let i = self.free_index[node];
                if i != usize::MAX {
                    visit(t, a, i);
                }
            }
        }
    }

    /// The held corners `b` of tetrahedron `t` with their stiffness coupling to corner `a`,
    /// `K_ab = V ∇N_a · ∇N_b` (the linear FEM Laplacian's entry): (held node, `K_ab`). A held
    /// node's known position moves to the right-hand side of the free row as `−K_ab x_b`.
    fn held_couplings(&self, t: usize, a: usize) -> impl Iterator<Item = (usize, f64)> + '_ {
        let (v, g, tet) = (self.volume[t], &self.grad[t], self.tets[t]);
        (0..4)
            .filter(move |&b| self.free_index[tet[b]] == usize::MAX)
            .map(move |b| (tet[b], v * g[a].dot(&g[b])))
    }

    fn deformation_gradient(&self, x: &[Point], t: usize) -> Matrix3<f64> {
        let tet = self.tets[t];
        let g = &self.grad[t];
        (0..4).fold(Matrix3::zeros(), |f, a| {
            f + x[tet[a]].coords * g[a].transpose()
        })
    }

    /// Local step: per tetrahedron, the rotation nearest to its deformation gradient.
    fn local_step(&self, x: &[Point], rotations: &mut [Matrix3<f64>]) {
        rotations.par_iter_mut().enumerate().for_each(|(t, r)| {
            *r = nearest_rotation(&self.deformation_gradient(x, t));
        });
    }

    /// Global step: solve for the free nodes with the rotations fixed.
    fn global_step(&self, x: &mut [Point], rotations: &[Matrix3<f64>]) {
        if self.n_free == 0 {
            return;
        }
        let mut rhs = Mat::<f64>::zeros(self.n_free, 3);
        self.for_each_free_corner(|t, a, i| {
            let mut b_i = rotations[t] * self.grad[t][a] * self.volume[t];
            for (node, kab) in self.held_couplings(t, a) {
                b_i -= x[node].coords * kab;
            }
            for c in 0..3 {
                rhs[(i, c)] += b_i[c];
            }
        });
        self.factor.solve(&mut rhs);
        for (v, &i) in self.free_index.iter().enumerate() {
            if i != usize::MAX {
                x[v] = Point::new(rhs[(i, 0)], rhs[(i, 1)], rhs[(i, 2)]);
            }
        }
    }
}

/// The rotation nearest to `f` in the Frobenius norm (the rotation of its polar
/// decomposition).
///
/// For `det f > 0` (every element that is not inverted) it is the orthogonal polar factor, found
/// by Higham's scaled Newton iteration (Higham 1986, "Computing the polar decomposition — with
/// applications", SIAM J. Sci. Stat. Comput. 7(4), eq. 3.1 and the Frobenius-norm scaling of
/// section 3.3): `X ← (γ X + γ⁻¹ X⁻ᵀ) / 2`, `γ = (|X⁻¹|_F / |X|_F)^½`. It converges
/// quadratically, in about six steps from a cold start and in one when `f` is already a rotation
/// (so rigid motions stay exact), and is about 15x cheaper than a 3x3 SVD, which was two thirds
/// of the ARAP solve. (Warm-starting from the last iteration's rotation would not help: the
/// iteration commutes with rotations, so its step count depends on the stretch alone.)
/// Inverted or nearly flat elements, and any that do not converge, fall back to
/// [`nearest_rotation_svd`].
pub(crate) fn nearest_rotation(f: &Matrix3<f64>) -> Matrix3<f64> {
    let scale = f.norm_squared();
    let det = f.determinant();
    // Relative to |f|³, so the test does not depend on the units.
    // NaN entries fail this test too, and go to the SVD's own handling.
    if det.is_nan() || det <= 1e-10 * scale * scale.sqrt() {
        return nearest_rotation_svd(f);
    }
    let mut x = *f;
    let mut d = det;
    for _ in 0..MAX_POLAR_STEPS {
        // X⁻ᵀ = cof(X) / det X: no general inverse needed for a 3x3.
        let cof = cofactor(&x);
        // Higham's (1,2)-norm-free scaling with Frobenius norms, γ = (|X⁻¹| / |X|)^½: square
        // roots only, and it reaches the same few steps as the determinant scaling.
        let gamma = (cof.norm() / (d * x.norm())).sqrt();
        let next = (x * gamma + cof / (d * gamma)) * 0.5;
        let change = (next - x).norm_squared();
        x = next;
        // Quadratic convergence: a step of 1e-8 leaves an error of order 1e-16 behind it.
        if change < 1e-16 {
            return x;
        }
        d = x.determinant();
        if d.is_nan() || d <= 0.0 {
            break;
        }
    }
    nearest_rotation_svd(f)
}

/// Newton steps [`nearest_rotation`] allows before it falls back to the SVD: a well-shaped
/// element converges in 4-8.
const MAX_POLAR_STEPS: usize = 30;

/// The cofactor matrix of `m` (`det m · m⁻ᵀ`, `∂ det m / ∂ m`; defined for singular `m` too).
pub(crate) fn cofactor(m: &Matrix3<f64>) -> Matrix3<f64> {
    let c0 = m.column(1).cross(&m.column(2));
    let c1 = m.column(2).cross(&m.column(0));
    let c2 = m.column(0).cross(&m.column(1));
    Matrix3::from_columns(&[c0, c1, c2])
}

/// The rotation nearest to `f` by its SVD: `U Vᵀ`, with the last singular vector flipped when
/// that would be a reflection (the inverted-element case of Irving et al. 2004, "Invertible
/// finite elements for robust simulation of large deformation").
pub(crate) fn nearest_rotation_svd(f: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = f.svd(true, true);
    let (Some(mut u), Some(v_t)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    if (u * v_t).determinant() < 0.0 {
        // nalgebra sorts singular values descending: flip the smallest's vector.
        let s = svd.singular_values;
        let k = (0..3).min_by(|&a, &b| s[a].total_cmp(&s[b])).unwrap_or(2);
        u.column_mut(k).neg_mut();
    }
    u * v_t
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mesh::tests::icosphere;
    use crate::rng::Rng;
    use crate::tet::stuffing::{isosurface_stuffing, StuffingParams};
    use nalgebra::{Isometry3, Translation3};

    fn ball() -> (TetMesh, Vec<usize>) {
        let m =
            isosurface_stuffing(&icosphere(10.0, 3), &StuffingParams::with_spacing(2.5)).unwrap();
        let b = m.boundary_nodes();
        assert!(b.len() < m.n_nodes());
        (m, b)
    }

    fn max_err(a: &[Point], b: &[Point]) -> f64 {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).norm())
            .fold(0.0, f64::max)
    }

    #[test]
    fn rigid_motion_moves_interior_rigidly() {
        let (m, b) = ball();
        let solver = ElasticSolver::new(&m, &b).unwrap();
        let mut rng = Rng::new(5);
        for _ in 0..3 {
            let iso = Isometry3::from_parts(Translation3::from(rng.gauss3(50.0)), rng.rotation());
            let held: Vec<Point> = b.iter().map(|&v| iso * m.nodes[v]).collect();
            let (x, stats) = solver.solve(&held, &ArapOptions::default()).unwrap();
            let want: Vec<Point> = m.nodes.iter().map(|p| iso * p).collect();
            assert!(max_err(&x, &want) < 1e-9, "{}", max_err(&x, &want));
            assert!(stats.converged && stats.energy < 1e-12, "{stats:?}");
        }
    }

    #[test]
    fn uniform_scaling_scales_interior() {
        let (m, b) = ball();
        let solver = ElasticSolver::new(&m, &b).unwrap();
        let c = Point::new(3.0, -2.0, 7.0);
        for s in [0.7, 1.35] {
            let f = |p: &Point| c + (p - c) * s;
            let held: Vec<Point> = b.iter().map(|&v| f(&m.nodes[v])).collect();
            let (x, _) = solver.solve(&held, &ArapOptions::default()).unwrap();
            let want: Vec<Point> = m.nodes.iter().map(f).collect();
            assert!(
                max_err(&x, &want) < 1e-9,
                "scale {s}: {}",
                max_err(&x, &want)
            );
        }
    }

    /// A non-affine boundary deformation (a twist about z and a bulge): the iterations lower the
    /// ARAP energy below the harmonic guess's, converge, and invert nothing.
    #[test]
    fn bent_boundary_settles() {
        let (m, b) = ball();
        let solver = ElasticSolver::new(&m, &b).unwrap();
        let f = |p: &Point| {
            let a = 0.03 * p.z;
            let (s, c) = a.sin_cos();
            Point::new(
                c * p.x - s * p.y,
                s * p.x + c * p.y,
                p.z * (1.0 + 0.002 * p.x * p.x),
            )
        };
        let held: Vec<Point> = b.iter().map(|&v| f(&m.nodes[v])).collect();
        let harmonic = ArapOptions {
            max_iterations: 0,
            ..Default::default()
        };
        let (_, h) = solver.solve(&held, &harmonic).unwrap();
        let (x, s) = solver.solve(&held, &ArapOptions::default()).unwrap();
        assert!(s.converged && s.iterations > 1, "{s:?}");
        assert!(s.energy < h.energy, "{} vs harmonic {}", s.energy, h.energy);
        let out = TetMesh {
            nodes: x,
            tets: m.tets.clone(),
        };
        assert_eq!(out.inverted_count(), 0);
        for (&v, p) in b.iter().zip(&held) {
            assert_eq!(out.nodes[v], *p);
        }
    }

    /// The Newton polar factor agrees with the SVD's nearest rotation on random, stretched,
    /// nearly flat and inverted matrices, and returns a rotation exactly when given one.
    #[test]
    fn newton_polar_matches_svd() {
        let mut rng = Rng::new(11);
        for k in 0..2000 {
            let r = rng.rotation().to_rotation_matrix().into_inner();
            let q = rng.rotation().to_rotation_matrix().into_inner();
            let s = match k % 4 {
                0 => Matrix3::from_diagonal(&Vec3::new(1.0, 1.0, 1.0)),
                1 => Matrix3::from_diagonal(&Vec3::new(
                    rng.range(0.2, 5.0),
                    rng.range(0.2, 5.0),
                    rng.range(0.2, 5.0),
                )),
                2 => Matrix3::from_diagonal(&Vec3::new(3.0, 1.0, 1e-7)),
                _ => Matrix3::from_diagonal(&Vec3::new(2.0, 0.5, -0.3)),
            };
            let f = r * s * q.transpose() * rng.range(0.01, 100.0);
            let a = nearest_rotation(&f);
            let b = nearest_rotation_svd(&f);
            assert!((a - b).norm() < 1e-9, "case {k}: {a} vs {b}");
            assert!((a.transpose() * a - Matrix3::identity()).norm() < 1e-12);
            assert!((a.determinant() - 1.0).abs() < 1e-12);
        }
        let r = Rng::new(3).rotation().to_rotation_matrix().into_inner();
        assert!((nearest_rotation(&r) - r).norm() < 1e-15);
    }

    /// An affine scalar field on the boundary extends to the same affine field inside (the FEM
    /// Laplacian's linear precision), column by column.
    #[test]
    fn harmonic_extension_reproduces_affine_fields() {
        let (m, b) = ball();
        let solver = ElasticSolver::new(&m, &b).unwrap();
        let f = |p: &Point, c: usize| match c {
            0 => 1.0,
            1 => 0.3 * p.x - 0.2 * p.y + 0.05 * p.z + 2.0,
            _ => -p.z,
        };
        let held = Mat::<f64>::from_fn(b.len(), 3, |r, c| f(&m.nodes[b[r]], c));
        let u = solver.harmonic_extension(&held).unwrap();
        for (v, p) in m.nodes.iter().enumerate() {
            for c in 0..3 {
                assert!((u[(v, c)] - f(p, c)).abs() < 1e-9, "node {v} column {c}");
            }
        }
        assert!(solver
            .harmonic_extension(&Mat::<f64>::zeros(b.len() + 1, 1))
            .is_err());
    }

    #[test]
    fn bad_input_is_an_error() {
        let (m, b) = ball();
        assert!(ElasticSolver::new(&m, &[m.n_nodes()]).is_err());
        assert!(ElasticSolver::new(&m, &[]).is_err());
        let solver = ElasticSolver::new(&m, &b).unwrap();
        assert!(solver.solve(&[], &ArapOptions::default()).is_err());
        let mut held: Vec<Point> = b.iter().map(|&v| m.nodes[v]).collect();
        held[3].x = f64::NAN;
        assert!(solver.solve(&held, &ArapOptions::default()).is_err());
    }
}
