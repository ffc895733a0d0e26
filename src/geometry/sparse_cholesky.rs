//! Sparse Cholesky factorisation of a symmetric positive definite matrix, factorised once and
//! solved many times: the one faer call sequence shared by the landmark fit
//! ([`crate::skin::correspondence`]), the tetrahedral mesh's elastic solve ([`crate::tet`]) and
//! bone-heat weights ([`crate::pose::weights`]).
//!
//! faer's default fill-reducing ordering (AMD) and a *sequential* factorisation and solve: on the
//! two cores this runs on, faer's parallel sparse path is about 30x slower, and passing
//! `Par::Seq` locally leaves faer's global setting to the application.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::LltRegularization;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky};
use faer::sparse::{SparseColMat, Triplet};
use faer::{Conj, Mat, Par, Side};

/// Why a factorisation failed.
#[derive(Clone, Debug, PartialEq)]
pub enum CholeskyError {
    /// The triplets do not make a matrix (an index out of range) or the symbolic analysis
    /// failed; faer's message.
    Structure(String),
    /// The matrix is not positive definite (singular: some unknown is unconstrained); faer's
    /// message.
    NotPositiveDefinite(String),
}

/// `L Lᵀ` of an `n × n` matrix; `n = 0` is allowed and solves nothing.
pub struct SparseCholesky {
    symbolic: Option<SymbolicCholesky<usize>>,
    values: Vec<f64>,
}

impl SparseCholesky {
    /// Factorise the symmetric matrix whose lower triangle is `trip` (duplicates summed).
    pub fn new(
        n: usize,
        trip: &[Triplet<usize, usize, f64>],
    ) -> std::result::Result<Self, CholeskyError> {
        if n == 0 {
            return Ok(SparseCholesky {
                symbolic: None,
                values: Vec::new(),
            });
        }
        let structure = |e: &dyn std::fmt::Debug| CholeskyError::Structure(format!("{e:?}"));
        let k = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, trip)
            .map_err(|e| structure(&e))?;
        let symbolic = factorize_symbolic_cholesky(
            k.symbolic(),
            Side::Lower,
            Default::default(),
            Default::default(),
        )
        .map_err(|e| structure(&e))?;
        let mut values = vec![0.0; symbolic.len_val()];
        let mut mem = MemBuffer::new(
            symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default()),
        );
        symbolic
            .factorize_numeric_llt::<f64>(
                &mut values,
                k.as_ref(),
                Side::Lower,
                LltRegularization::default(),
                Par::Seq,
                MemStack::new(&mut mem),
                Default::default(),
            )
            .map_err(|e| CholeskyError::NotPositiveDefinite(format!("{e:?}")))?;
        Ok(SparseCholesky {
            symbolic: Some(symbolic),
            values,
        })
    }

    /// Overwrite `rhs` (one column per right-hand side) with `K⁻¹ rhs`.
    pub fn solve(&self, rhs: &mut Mat<f64>) {
        let Some(symbolic) = &self.symbolic else {
            return;
        };
        let mut mem = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq));
        LltRef::new(symbolic, &self.values).solve_in_place_with_conj(
            Conj::No,
            rhs.as_mut(),
            Par::Seq,
            MemStack::new(&mut mem),
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tridiagonal SPD system solved against its known solution; a singular one refused.
    #[test]
    fn solves_spd_and_refuses_singular() {
        let n = 50;
        let mut trip = Vec::new();
        for i in 0..n {
            trip.push(Triplet::new(i, i, 4.0));
            if i > 0 {
                trip.push(Triplet::new(i, i - 1, -1.0));
            }
        }
        let f = SparseCholesky::new(n, &trip).unwrap();
        let x: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).sin()).collect();
        let mut b = Mat::<f64>::zeros(n, 1);
        for i in 0..n {
            b[(i, 0)] = 4.0 * x[i]
                - if i > 0 { x[i - 1] } else { 0.0 }
                - if i + 1 < n { x[i + 1] } else { 0.0 };
        }
        f.solve(&mut b);
        for i in 0..n {
            assert!((b[(i, 0)] - x[i]).abs() < 1e-12);
        }
        let singular = [
            Triplet::new(0, 0, 1.0),
            Triplet::new(1, 0, 1.0),
            Triplet::new(1, 1, 1.0),
        ];
        assert!(matches!(
            SparseCholesky::new(2, &singular),
            Err(CholeskyError::NotPositiveDefinite(_))
        ));
        assert!(matches!(
            SparseCholesky::new(2, &[Triplet::new(5, 0, 1.0)]),
            Err(CholeskyError::Structure(_))
        ));
    }
}
