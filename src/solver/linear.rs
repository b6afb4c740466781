//! Sparse linear solves of the free-dof tangent with faer: the symbolic
//! factorisation is computed once per pattern and reused for every Newton
//! iteration; work memory is allocated once.
//!
//! Two factorisations: LU with partial pivoting (the robust baseline) and
//! LDLᵀ with a fill-reducing symmetric ordering (the tangent of a
//! hyperelastic law is symmetric). `docs/solver.md` has the measurements
//! that chose the default.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::solvers::Solve;
use faer::sparse::linalg::cholesky::{LdltRef, SymbolicCholesky, factorize_symbolic_cholesky};
use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
use faer::sparse::{SparseColMat, SymbolicSparseColMat};
use faer::{Conj, MatMut, Par, Side};

/// Which factorisation to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LinearSolverKind {
    /// Sparse LU with partial pivoting.
    Lu,
    /// Sparse LDLᵀ (no pivoting) after an AMD ordering.
    Ldlt,
}

/// Why a factorisation or solve failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LinearSolverError {
    /// The matrix is singular (or numerically so for LDLᵀ).
    #[error("the tangent is singular ({0})")]
    Singular(String),
    /// The solution has non-finite entries.
    #[error("the linear solve produced non-finite values")]
    NonFinite,
    /// Out of memory or another faer error.
    #[error("linear solver: {0}")]
    Other(String),
}

enum Factorisation {
    Lu {
        symbolic: SymbolicLu<usize>,
        numeric: Option<Lu<usize, f64>>,
    },
    Ldlt {
        symbolic: SymbolicCholesky<usize>,
        l_values: Vec<f64>,
        factorised: bool,
        buffer: MemBuffer,
    },
}

/// A sparse matrix with a fixed pattern and its reusable factorisation.
pub struct SparseSolver {
    /// The matrix (its values are refilled by assembly).
    pub matrix: SparseColMat<usize, f64>,
    factorisation: Factorisation,
}

impl SparseSolver {
    /// Symbolic analysis of `pattern` for the chosen factorisation.
    ///
    /// # Errors
    /// faer's symbolic errors (out of memory).
    pub fn new(
        kind: LinearSolverKind,
        pattern: SymbolicSparseColMat<usize>,
    ) -> Result<Self, LinearSolverError> {
        let other = |e: &dyn std::fmt::Debug| LinearSolverError::Other(format!("{e:?}"));
        let factorisation = match kind {
            LinearSolverKind::Lu => Factorisation::Lu {
                symbolic: SymbolicLu::try_new(pattern.as_ref()).map_err(|e| other(&e))?,
                numeric: None,
            },
            LinearSolverKind::Ldlt => {
                let symbolic = factorize_symbolic_cholesky(
                    pattern.as_ref(),
                    Side::Upper,
                    Default::default(),
                    Default::default(),
                )
                .map_err(|e| other(&e))?;
                let par = Par::Seq;
                let req = symbolic
                    .factorize_numeric_ldlt_scratch::<f64>(par, Default::default())
                    .or(symbolic.solve_in_place_scratch::<f64>(1, par));
                let buffer = MemBuffer::try_new(req).map_err(|e| other(&e))?;
                Factorisation::Ldlt {
                    l_values: vec![0.0; symbolic.len_val()],
                    symbolic,
                    factorised: false,
                    buffer,
                }
            }
        };
        let nnz = pattern.row_idx().len();
        Ok(Self {
            matrix: SparseColMat::new(pattern, vec![0.0; nnz]),
            factorisation,
        })
    }

    /// The matrix values (CSC order of the pattern), for assembly.
    pub fn values_mut(&mut self) -> &mut [f64] {
        self.matrix.val_mut()
    }

    /// Numeric factorisation of the current values.
    ///
    /// # Errors
    /// A singular matrix.
    pub fn factorize(&mut self) -> Result<(), LinearSolverError> {
        match &mut self.factorisation {
            Factorisation::Lu { symbolic, numeric } => {
                *numeric = None;
                let lu = Lu::try_new_with_symbolic(symbolic.clone(), self.matrix.as_ref())
                    .map_err(|e| LinearSolverError::Singular(format!("{e:?}")))?;
                *numeric = Some(lu);
            }
            Factorisation::Ldlt {
                symbolic,
                l_values,
                factorised,
                buffer,
            } => {
                *factorised = false;
                symbolic
                    .factorize_numeric_ldlt::<f64>(
                        l_values,
                        self.matrix.as_ref(),
                        Side::Upper,
                        Default::default(),
                        Par::Seq,
                        MemStack::new(buffer),
                        Default::default(),
                    )
                    .map_err(|e| LinearSolverError::Singular(format!("{e:?}")))?;
                *factorised = true;
            }
        }
        Ok(())
    }

    /// Solves `A x = rhs` in place with the last factorisation.
    ///
    /// # Errors
    /// No factorisation, or a non-finite solution (a numerically singular
    /// matrix).
    ///
    /// # Panics
    /// If `rhs.len()` is not the matrix dimension.
    pub fn solve_in_place(&mut self, rhs: &mut [f64]) -> Result<(), LinearSolverError> {
        let n = rhs.len();
        match &mut self.factorisation {
            Factorisation::Lu { numeric, .. } => {
                let lu = numeric
                    .as_ref()
                    .ok_or_else(|| LinearSolverError::Other("not factorised".into()))?;
                lu.solve_in_place(MatMut::from_column_major_slice_mut(rhs, n, 1));
            }
            Factorisation::Ldlt {
                symbolic,
                l_values,
                factorised,
                buffer,
            } => {
                if !*factorised {
                    return Err(LinearSolverError::Other("not factorised".into()));
                }
                LdltRef::new(symbolic, l_values).solve_in_place_with_conj(
                    Conj::No,
                    MatMut::from_column_major_slice_mut(rhs, n, 1),
                    Par::Seq,
                    MemStack::new(buffer),
                );
            }
        }
        if rhs.iter().all(|v| v.is_finite()) {
            Ok(())
        } else {
            Err(LinearSolverError::NonFinite)
        }
    }
}
