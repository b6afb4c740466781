//! Sparse linear solves of the free-dof tangent with faer: the symbolic
//! factorisation is computed once per pattern and reused for every Newton
//! iteration; work memory is allocated once.
//!
//! Two factorisations: LU with partial pivoting (the robust baseline) and
//! LDLᵀ with a fill-reducing symmetric ordering (the tangent of a
//! hyperelastic law is symmetric). `docs/solver.md` has the measurements
//! that chose the default.
//!
//! **Dense unknowns and LU.** A floating tool's dof couples to every node
//! of the plies (its contact stencils), so its row and column of the
//! tangent are dense. LU with partial pivoting bounds its fill by the
//! Cholesky factor of `AᵀA`, which one dense row makes completely dense
//! (`n²` storage, `n³` work). The LU path therefore borders such unknowns
//! (`docs/solver.md`, "Dense unknowns"): with the sparse block `A` and the
//! `m` dense unknowns,
//!
//! ```text
//! [A B; C D] [x; y] = [f; g]:   S = D − C A⁻¹ B  (m × m),
//! y = S⁻¹ (g − C A⁻¹ f),   x = A⁻¹ (f − B y),
//! ```
//!
//! with `A` factorised by sparse LU and `S` by dense Gaussian elimination
//! with partial pivoting.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::sparse::linalg::cholesky::{LdltRef, SymbolicCholesky, factorize_symbolic_cholesky};
use faer::sparse::linalg::lu::{LuRef, NumericLu, SymbolicLu, factorize_symbolic_lu};
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

/// A column with more stored entries than this (and than
/// `DENSE_FRACTION` of the dimension) is bordered on the LU path.
const DENSE_MIN_ENTRIES: usize = 200;
/// See [`DENSE_MIN_ENTRIES`].
const DENSE_FRACTION: f64 = 0.1;

/// Where one entry of the full matrix goes in the bordered LU.
#[derive(Debug, Clone, Copy)]
enum Target {
    /// Slot in the values of the sparse block `A`.
    Sparse(usize),
    /// `B[i, j]`: row `i` of the sparse set, column `j` of the dense set
    /// (column-major `n_s × m`).
    Right(usize),
    /// `C[j, i]` (row-major `m × n_s`: row `j` of the dense set).
    Below(usize),
    /// `D[j, k]` (`m × m`, row-major).
    Corner(usize),
}

/// LU of the sparse block and the Schur complement of the dense unknowns.
struct Bordered {
    /// The dense unknowns.
    dense: Vec<usize>,
    /// The sparse unknowns in order.
    sparse: Vec<usize>,
    /// The sparse block (values refilled from the full matrix).
    block: SparseColMat<usize, f64>,
    /// Per entry of the full matrix: where it goes.
    targets: Vec<Target>,
    right: Vec<f64>,
    below: Vec<f64>,
    corner: Vec<f64>,
    /// `Z = A⁻¹ B` (column-major `n_s × m`).
    z: Vec<f64>,
    /// The Schur complement, factorised in place (row-major `m × m`), and
    /// its row permutation.
    schur: Vec<f64>,
    pivots: Vec<usize>,
    scratch: Vec<f64>,
}

enum Factorisation {
    Lu {
        symbolic: SymbolicLu<usize>,
        /// The factors, their storage kept from one factorisation to the
        /// next (a paper-size forming tangent's factors take hundreds of
        /// megabytes).
        numeric: NumericLu<usize, f64>,
        factorised: bool,
        /// Scratch of the numeric factorisation and of the solves.
        buffer: MemBuffer,
        bordered: Option<Box<Bordered>>,
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
            LinearSolverKind::Lu => {
                let bordered = Bordered::new(&pattern).map(Box::new);
                let symbolic = match &bordered {
                    Some(b) => factorize_symbolic_lu(b.block.symbolic(), Default::default()),
                    None => factorize_symbolic_lu(pattern.as_ref(), Default::default()),
                }
                .map_err(|e| other(&e))?;
                // The solves take the dense unknowns' columns at once
                // (`Z = A⁻¹ B`) or one right-hand side.
                let columns = bordered.as_ref().map_or(1, |b| b.dense.len().max(1));
                let par = faer::get_global_parallelism();
                let req = symbolic
                    .factorize_numeric_lu_scratch::<f64>(par, Default::default())
                    .or(symbolic.solve_in_place_scratch::<f64>(columns, par));
                Factorisation::Lu {
                    symbolic,
                    numeric: NumericLu::new(),
                    factorised: false,
                    buffer: MemBuffer::try_new(req).map_err(|e| other(&e))?,
                    bordered,
                }
            }
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
            Factorisation::Lu {
                symbolic,
                numeric,
                factorised,
                buffer,
                bordered,
            } => {
                *factorised = false;
                // The sparse block of the bordered matrix, or the matrix.
                if let Some(b) = bordered.as_deref_mut() {
                    b.split(self.matrix.val());
                }
                let sparse = bordered
                    .as_ref()
                    .map_or(self.matrix.as_ref(), |b| b.block.as_ref());
                let lu = symbolic
                    .factorize_numeric_lu(
                        numeric,
                        sparse,
                        faer::get_global_parallelism(),
                        MemStack::new(buffer),
                        Default::default(),
                    )
                    .map_err(|e| LinearSolverError::Singular(format!("{e:?}")))?;
                if let Some(b) = bordered.as_deref_mut() {
                    b.schur_complement(lu, buffer)?;
                }
                *factorised = true;
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
            Factorisation::Lu {
                symbolic,
                numeric,
                factorised,
                buffer,
                bordered,
            } => {
                if !*factorised {
                    return Err(LinearSolverError::Other("not factorised".into()));
                }
                let lu = LuRef::new_unchecked(symbolic, numeric);
                match bordered {
                    None => lu_solve(lu, MatMut::from_column_major_slice_mut(rhs, n, 1), buffer),
                    Some(b) => b.solve_in_place(lu, rhs, buffer),
                }
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

/// `rhs ← A⁻¹ rhs` (one or more columns) with the LU factors `lu`, in the
/// scratch `buffer`.
fn lu_solve(lu: LuRef<'_, usize, f64>, rhs: MatMut<'_, f64>, buffer: &mut MemBuffer) {
    lu.solve_in_place_with_conj(
        Conj::No,
        rhs,
        faer::get_global_parallelism(),
        MemStack::new(buffer),
    );
}

impl Bordered {
    /// Splits the unknowns of `pattern` into sparse and dense ones; `None`
    /// when no column is dense.
    fn new(pattern: &SymbolicSparseColMat<usize>) -> Option<Self> {
        let n = pattern.ncols();
        let col_ptr = pattern.col_ptr();
        let row_idx = pattern.row_idx();
        let threshold = DENSE_MIN_ENTRIES.max((DENSE_FRACTION * n as f64) as usize);
        let dense: Vec<usize> = (0..n)
            .filter(|&j| col_ptr[j + 1] - col_ptr[j] > threshold)
            .collect();
        if dense.is_empty() || dense.len() == n {
            return None;
        }
        let m = dense.len();
        // Each unknown's place in its block: `Ok(k)` the k-th sparse one,
        // `Err(k)` the k-th dense one.
        let mut slot: Vec<Result<usize, usize>> = Vec::with_capacity(n);
        let mut sparse = Vec::with_capacity(n - m);
        for j in 0..n {
            match dense.binary_search(&j) {
                Ok(k) => slot.push(Err(k)),
                Err(_) => {
                    slot.push(Ok(sparse.len()));
                    sparse.push(j);
                }
            }
        }
        let ns = sparse.len();
        // The sparse block's pattern and every entry's target.
        let mut targets = Vec::with_capacity(row_idx.len());
        let mut block_ptr = vec![0usize; ns + 1];
        let mut block_rows = Vec::new();
        for j in 0..n {
            for &i in &row_idx[col_ptr[j]..col_ptr[j + 1]] {
                let target = match (slot[i], slot[j]) {
                    (Ok(si), Ok(_)) => {
                        block_rows.push(si);
                        Target::Sparse(block_rows.len() - 1)
                    }
                    (Ok(si), Err(dj)) => Target::Right(dj * ns + si),
                    (Err(di), Ok(sj)) => Target::Below(di * ns + sj),
                    (Err(di), Err(dj)) => Target::Corner(di * m + dj),
                };
                targets.push(target);
            }
            if let Ok(sj) = slot[j] {
                block_ptr[sj + 1] = block_rows.len();
            }
        }
        let nnz = block_rows.len();
        let symbolic = SymbolicSparseColMat::new_checked(ns, ns, block_ptr, None, block_rows);
        Some(Self {
            dense,
            sparse,
            block: SparseColMat::new(symbolic, vec![0.0; nnz]),
            targets,
            right: vec![0.0; ns * m],
            below: vec![0.0; ns * m],
            corner: vec![0.0; m * m],
            z: vec![0.0; ns * m],
            schur: vec![0.0; m * m],
            pivots: vec![0; m],
            scratch: vec![0.0; ns.max(m)],
        })
    }

    /// Copies the full matrix's values into the blocks.
    fn split(&mut self, values: &[f64]) {
        self.right.fill(0.0);
        self.below.fill(0.0);
        self.corner.fill(0.0);
        let block = self.block.val_mut();
        for (&target, &v) in self.targets.iter().zip(values) {
            match target {
                Target::Sparse(k) => block[k] = v,
                Target::Right(k) => self.right[k] = v,
                Target::Below(k) => self.below[k] = v,
                Target::Corner(k) => self.corner[k] = v,
            }
        }
    }

    /// `Z = A⁻¹ B` and the factorised Schur complement `D − C Z`.
    fn schur_complement(
        &mut self,
        lu: LuRef<'_, usize, f64>,
        buffer: &mut MemBuffer,
    ) -> Result<(), LinearSolverError> {
        let ns = self.sparse.len();
        let m = self.dense.len();
        self.z.copy_from_slice(&self.right);
        lu_solve(
            lu,
            MatMut::from_column_major_slice_mut(&mut self.z, ns, m),
            buffer,
        );
        if !self.z.iter().all(|v| v.is_finite()) {
            return Err(LinearSolverError::Singular(
                "the sparse block of the bordered LU".into(),
            ));
        }
        for r in 0..m {
            let c_row = &self.below[r * ns..(r + 1) * ns];
            for k in 0..m {
                let z_col = &self.z[k * ns..(k + 1) * ns];
                let cz: f64 = c_row.iter().zip(z_col).map(|(a, b)| a * b).sum();
                self.schur[r * m + k] = self.corner[r * m + k] - cz;
            }
        }
        // Gaussian elimination with partial pivoting, in place.
        let a = &mut self.schur;
        let scale = a.iter().fold(0.0_f64, |s, v| s.max(v.abs()));
        for col in 0..m {
            let (p, best) = (col..m)
                .map(|r| (r, a[r * m + col].abs()))
                .fold((col, -1.0), |acc, x| if x.1 > acc.1 { x } else { acc });
            if best.is_nan() || best <= 1e-14 * scale || !best.is_finite() {
                return Err(LinearSolverError::Singular(
                    "the Schur complement of the dense unknowns".into(),
                ));
            }
            self.pivots[col] = p;
            if p != col {
                for k in 0..m {
                    a.swap(p * m + k, col * m + k);
                }
            }
            let pivot = a[col * m + col];
            for r in col + 1..m {
                let f = a[r * m + col] / pivot;
                a[r * m + col] = f;
                for k in col + 1..m {
                    a[r * m + k] -= f * a[col * m + k];
                }
            }
        }
        Ok(())
    }

    /// Solves the full system in place with the factorised blocks.
    fn solve_in_place(
        &mut self,
        lu: LuRef<'_, usize, f64>,
        rhs: &mut [f64],
        buffer: &mut MemBuffer,
    ) {
        let ns = self.sparse.len();
        let m = self.dense.len();
        // x' = A⁻¹ f.
        let x = &mut self.scratch[..ns];
        for (k, &j) in self.sparse.iter().enumerate() {
            x[k] = rhs[j];
        }
        lu_solve(lu, MatMut::from_column_major_slice_mut(x, ns, 1), buffer);
        // y = S⁻¹ (g − C x').
        let mut y: Vec<f64> = self
            .dense
            .iter()
            .enumerate()
            .map(|(r, &j)| {
                let c_row = &self.below[r * ns..(r + 1) * ns];
                rhs[j] - c_row.iter().zip(x.iter()).map(|(a, b)| a * b).sum::<f64>()
            })
            .collect();
        let a = &self.schur;
        for col in 0..m {
            y.swap(col, self.pivots[col]);
            for r in col + 1..m {
                y[r] -= a[r * m + col] * y[col];
            }
        }
        for col in (0..m).rev() {
            for k in col + 1..m {
                y[col] -= a[col * m + k] * y[k];
            }
            y[col] /= a[col * m + col];
        }
        // x = x' − Z y.
        for (k, &j) in self.sparse.iter().enumerate() {
            let zy: f64 = (0..m).map(|c| self.z[c * ns + k] * y[c]).sum();
            rhs[j] = x[k] - zy;
        }
        for (c, &j) in self.dense.iter().enumerate() {
            rhs[j] = y[c];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An unsymmetric tridiagonal matrix of `n` unknowns with one dense
    /// row and column (a floating tool's dof) at `dense`.
    fn bordered_matrix(n: usize, dense: usize) -> (SymbolicSparseColMat<usize>, Vec<f64>) {
        let mut col_ptr = vec![0];
        let mut rows = Vec::new();
        let mut values = Vec::new();
        for j in 0..n {
            for i in 0..n {
                let near = i.abs_diff(j) <= 1;
                if near || i == dense || j == dense {
                    rows.push(i);
                    values.push(if i == j {
                        4.0 + (j % 7) as f64
                    } else if i == dense || j == dense {
                        0.3 + 0.01 * ((i + 2 * j) % 11) as f64
                    } else {
                        -1.0 + 0.1 * ((i + j) % 3) as f64
                    });
                }
            }
            col_ptr.push(rows.len());
        }
        (
            SymbolicSparseColMat::new_checked(n, n, col_ptr, None, rows),
            values,
        )
    }

    /// The bordered LU solves a matrix with a dense row and column to
    /// round-off (the residual of `A x = b`).
    #[test]
    fn bordered_lu_solves_a_dense_row_and_column() {
        let n = 600;
        let (pattern, values) = bordered_matrix(n, 250);
        let mut solver = SparseSolver::new(LinearSolverKind::Lu, pattern.clone()).unwrap();
        assert!(matches!(
            &solver.factorisation,
            Factorisation::Lu {
                bordered: Some(_),
                ..
            }
        ));
        solver.values_mut().copy_from_slice(&values);
        solver.factorize().unwrap();
        let b: Vec<f64> = (0..n).map(|i| ((i * 37) % 17) as f64 - 8.0).collect();
        let mut x = b.clone();
        solver.solve_in_place(&mut x).unwrap();
        let error = residual(&pattern, &values, &x, &b);
        assert!(error < 1e-10, "residual {error}");
    }

    /// `‖A x − b‖∞` for the CSC matrix `(pattern, values)`.
    fn residual(
        pattern: &SymbolicSparseColMat<usize>,
        values: &[f64],
        x: &[f64],
        b: &[f64],
    ) -> f64 {
        let mut ax = vec![0.0; b.len()];
        for (j, xj) in x.iter().enumerate() {
            for k in pattern.col_ptr()[j]..pattern.col_ptr()[j + 1] {
                ax[pattern.row_idx()[k]] += values[k] * xj;
            }
        }
        ax.iter()
            .zip(b)
            .fold(0.0_f64, |m, (a, b)| m.max((a - b).abs()))
    }

    /// The LU keeps its factors' storage from one factorisation to the
    /// next: refactorised with other values (a pivot order that changes,
    /// too), it solves the new matrix exactly as a fresh solver does, bit
    /// for bit, with and without bordered dense unknowns.
    #[test]
    fn lu_refactorised_with_new_values_solves_as_a_fresh_one() {
        let n = 300;
        for dense in [Some(120), None] {
            // `dense = n`: no dense row, the tridiagonal part alone.
            let (pattern, values) = bordered_matrix(n, dense.unwrap_or(n));
            // Other values: the off-diagonal entries grown past the
            // diagonal's, so that partial pivoting picks other rows.
            let other: Vec<f64> = pattern
                .col_ptr()
                .windows(2)
                .enumerate()
                .flat_map(|(j, w)| (w[0]..w[1]).map(move |k| (j, k)))
                .map(|(j, k)| {
                    let i = pattern.row_idx()[k];
                    if i == j {
                        values[k]
                    } else {
                        7.0 * values[k] + 0.5
                    }
                })
                .collect();
            let b: Vec<f64> = (0..n).map(|i| ((i * 13) % 7) as f64 - 3.0).collect();
            let mut reused = SparseSolver::new(LinearSolverKind::Lu, pattern.clone()).unwrap();
            assert_eq!(
                matches!(
                    &reused.factorisation,
                    Factorisation::Lu {
                        bordered: Some(_),
                        ..
                    }
                ),
                dense.is_some()
            );
            reused.values_mut().copy_from_slice(&values);
            reused.factorize().unwrap();
            let mut x = b.clone();
            reused.solve_in_place(&mut x).unwrap();
            reused.values_mut().copy_from_slice(&other);
            reused.factorize().unwrap();
            let mut x = b.clone();
            reused.solve_in_place(&mut x).unwrap();
            let mut fresh = SparseSolver::new(LinearSolverKind::Lu, pattern.clone()).unwrap();
            fresh.values_mut().copy_from_slice(&other);
            fresh.factorize().unwrap();
            let mut y = b.clone();
            fresh.solve_in_place(&mut y).unwrap();
            assert_eq!(x, y, "dense unknown {dense:?}");
            let size = b.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
            assert!(
                residual(&pattern, &other, &x, &b) < 1e-10 * size,
                "dense unknown {dense:?}"
            );
        }
    }
}
