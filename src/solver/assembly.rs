//! Assembly of the residual, the energy and the tangent over a model's
//! terms. The sparsity pattern (free dofs only, CSC) is the union of every
//! term's stencils and is built once, with every stencil entry's slot in
//! it; each assembly lets every term evaluate its stencils (in parallel,
//! into the term's own buffers), then scatters serially in term and
//! stencil order (so the result does not depend on the thread count).

use std::time::Instant;

use faer::sparse::SymbolicSparseColMat;

use super::dofs::DofMap;
use crate::model::{Model, NO_SLOT, State, TermFailure};

/// Marks an entry that touches a constrained or unused dof.
const NONE: usize = usize::MAX;

/// One term's stencil layout and buffers.
struct TermBuffers {
    /// Dofs per stencil.
    size: usize,
    /// Per stencil entry: its global dof, or `NONE`.
    dofs: Vec<usize>,
    /// Per stencil matrix entry (column-major): its CSC slot, or `NONE`.
    slots: Vec<usize>,
    /// Residual contributions (`count × size`).
    force: Vec<f64>,
    /// Tangents (`count × size²`).
    tangent: Vec<f64>,
}

/// The global dofs of every stencil of a term, `count × size`, with `NONE`
/// for unused slots.
fn stencil_dofs(model: &Model, t: usize) -> (usize, Vec<usize>) {
    let term = &model.terms[t];
    let layout = term.stencils();
    let size = layout.size();
    let mut nodes = vec![NO_SLOT; layout.nodes];
    let mut extras = vec![NO_SLOT; layout.extras];
    let mut dofs = Vec::with_capacity(layout.count * size);
    for s in 0..layout.count {
        nodes.fill(NO_SLOT);
        extras.fill(NO_SLOT);
        term.stencil(s, &mut nodes, &mut extras);
        for &n in &nodes {
            for k in 0..3 {
                dofs.push(if n == NO_SLOT { NONE } else { 3 * n + k });
            }
        }
        for &x in &extras {
            dofs.push(if x == NO_SLOT {
                NONE
            } else {
                model.extra_dof(x)
            });
        }
    }
    (size, dofs)
}

/// Assembler for one model and one set of Dirichlet conditions.
pub struct Assembler {
    /// The dof split.
    pub dofs: DofMap,
    /// Symbolic structure of the free-dof tangent (CSC, sorted rows).
    pub symbolic: SymbolicSparseColMat<usize>,
    terms: Vec<TermBuffers>,
    /// Wall time spent in each term's evaluation \[s\], by term.
    pub term_seconds: Vec<(String, f64)>,
}

impl Assembler {
    /// Builds the pattern and the stencil slots of every term of `model`.
    pub fn new(model: &Model, dofs: DofMap) -> Self {
        let n = dofs.n_free();
        let layouts: Vec<(usize, Vec<usize>)> = (0..model.terms.len())
            .map(|t| stencil_dofs(model, t))
            .collect();
        let free = |d: usize| if d == NONE { None } else { dofs.free_index[d] };
        let mut columns: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (size, stencil_dofs) in &layouts {
            if *size == 0 {
                continue;
            }
            for stencil in stencil_dofs.chunks_exact(*size) {
                for &dj in stencil {
                    let Some(j) = free(dj) else { continue };
                    for &di in stencil {
                        if let Some(i) = free(di) {
                            columns[j].push(i);
                        }
                    }
                }
            }
        }
        let mut col_ptr = Vec::with_capacity(n + 1);
        let mut row_idx = Vec::new();
        col_ptr.push(0);
        for column in &mut columns {
            column.sort_unstable();
            column.dedup();
            row_idx.extend_from_slice(column);
            col_ptr.push(row_idx.len());
        }
        drop(columns);
        let terms = layouts
            .into_iter()
            .map(|(size, stencil_dofs)| {
                let count = stencil_dofs.len().checked_div(size).unwrap_or(0);
                let mut slots = vec![NONE; count * size * size];
                for (s, stencil) in stencil_dofs.chunks_exact(size.max(1)).enumerate() {
                    for (b, &dj) in stencil.iter().enumerate() {
                        let Some(j) = free(dj) else { continue };
                        let rows = &row_idx[col_ptr[j]..col_ptr[j + 1]];
                        for (a, &di) in stencil.iter().enumerate() {
                            if let Some(i) = free(di)
                                && let Ok(k) = rows.binary_search(&i)
                            {
                                slots[s * size * size + size * b + a] = col_ptr[j] + k;
                            }
                        }
                    }
                }
                TermBuffers {
                    size,
                    force: vec![0.0; count * size],
                    tangent: vec![0.0; count * size * size],
                    dofs: stencil_dofs,
                    slots,
                }
            })
            .collect();
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        Self {
            dofs,
            symbolic,
            terms,
            term_seconds: model
                .terms
                .iter()
                .map(|t| (t.name().to_string(), 0.0))
                .collect(),
        }
    }

    /// `out = K x` over every dof (free and constrained) from the stencil
    /// tangents of the last [`Assembler::force_tangent`] (`x`, `out`: all
    /// dofs): each term's stencil matrices times `x`, summed into `out`.
    pub fn tangent_product(&self, x: &[f64], out: &mut [f64]) {
        out.fill(0.0);
        for buffers in &self.terms {
            let size = buffers.size;
            if size == 0 {
                continue;
            }
            for (tangent, dofs) in buffers
                .tangent
                .chunks_exact(size * size)
                .zip(buffers.dofs.chunks_exact(size))
            {
                // Column-major by stencil: entry (a, b) at `size * b + a`,
                // as the slots are laid out.
                for (b, &db) in dofs.iter().enumerate() {
                    if db == NONE {
                        continue;
                    }
                    let xb = x[db];
                    if xb == 0.0 {
                        continue;
                    }
                    for (a, &da) in dofs.iter().enumerate() {
                        if da != NONE {
                            out[da] += tangent[size * b + a] * xb;
                        }
                    }
                }
            }
        }
    }

    /// Number of stored non-zeros of the free-dof tangent.
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    /// Total potential `Σ Π_term` [N·mm] and the residual `internal` (all
    /// dofs, \[N\]: `f_int − f_ext`) at `state`.
    ///
    /// # Errors
    /// The first term (in order) that failed, at its lowest-index stencil.
    pub fn force(
        &mut self,
        model: &mut Model,
        state: &State,
        internal: &mut [f64],
    ) -> Result<f64, TermFailure> {
        internal.fill(0.0);
        let mut energy = 0.0;
        for ((term, buffers), seconds) in model
            .terms
            .iter_mut()
            .zip(&mut self.terms)
            .zip(&mut self.term_seconds)
        {
            let clock = Instant::now();
            energy += term.evaluate(state, &mut buffers.force, None)?;
            seconds.1 += clock.elapsed().as_secs_f64();
            for (f, &d) in buffers.force.iter().zip(&buffers.dofs) {
                if d != NONE {
                    internal[d] += f;
                }
            }
        }
        Ok(energy)
    }

    /// As [`Assembler::force`], and the free-dof tangent into `values`
    /// (CSC values of [`Assembler::symbolic`]).
    ///
    /// # Errors
    /// The first term (in order) that failed, at its lowest-index stencil.
    pub fn force_tangent(
        &mut self,
        model: &mut Model,
        state: &State,
        internal: &mut [f64],
        values: &mut [f64],
    ) -> Result<f64, TermFailure> {
        internal.fill(0.0);
        values.fill(0.0);
        let mut energy = 0.0;
        for ((term, buffers), seconds) in model
            .terms
            .iter_mut()
            .zip(&mut self.terms)
            .zip(&mut self.term_seconds)
        {
            let clock = Instant::now();
            energy += term.evaluate(state, &mut buffers.force, Some(&mut buffers.tangent))?;
            seconds.1 += clock.elapsed().as_secs_f64();
            let size = buffers.size;
            if size == 0 {
                continue;
            }
            for ((force, dofs), (tangent, slots)) in buffers
                .force
                .chunks_exact(size)
                .zip(buffers.dofs.chunks_exact(size))
                .zip(
                    buffers
                        .tangent
                        .chunks_exact(size * size)
                        .zip(buffers.slots.chunks_exact(size * size)),
                )
            {
                for (f, &d) in force.iter().zip(dofs) {
                    if d != NONE {
                        internal[d] += f;
                    }
                }
                for (k, &slot) in tangent.iter().zip(slots) {
                    if slot != NONE {
                        values[slot] += k;
                    }
                }
            }
        }
        Ok(energy)
    }
}
