//! Assembly of the internal force, the energy and the tangent over a
//! membrane model. The sparsity pattern (free dofs only, CSC) and every
//! element's slots in it are built once; each assembly runs the element loop
//! in parallel with rayon into per-element buffers, then scatters serially
//! (so the result does not depend on the thread count).

use faer::sparse::SymbolicSparseColMat;
use rayon::prelude::*;

use super::dofs::DofMap;
use super::model::MembraneModel;
use crate::element::membrane::{ElementMatrix, ElementVector};
use crate::material::MaterialError;

/// Marks an element-matrix entry that touches a constrained dof.
const CONSTRAINED: usize = usize::MAX;

/// Why an element could not be evaluated.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ElementFailureKind {
    /// The law rejected the state (collapsed element or rovings, …).
    #[error("{0}")]
    Material(MaterialError),
    /// The triangle turned over in its plane (checked for planar models).
    #[error("the triangle is inverted (signed area ratio {orientation:e})")]
    Inverted {
        /// `(g1 × g2) · N0`.
        orientation: f64,
    },
}

/// The first element (lowest index) that failed, and why.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
#[error("element {element}: {kind}")]
pub struct ElementFailure {
    /// Element index.
    pub element: usize,
    /// The cause.
    pub kind: ElementFailureKind,
}

/// Per-element output of the parallel loop.
#[derive(Debug, Clone, Copy)]
struct ElementOutput {
    energy: f64,
    force: ElementVector,
    stiffness: ElementMatrix,
    failure: Option<ElementFailureKind>,
}

impl Default for ElementOutput {
    fn default() -> Self {
        Self {
            energy: 0.0,
            force: ElementVector::zeros(),
            stiffness: ElementMatrix::zeros(),
            failure: None,
        }
    }
}

/// Assembler for one model and one set of Dirichlet conditions.
pub struct Assembler {
    /// The dof split.
    pub dofs: DofMap,
    /// Symbolic structure of the free-dof tangent (CSC, sorted rows).
    pub symbolic: SymbolicSparseColMat<usize>,
    /// Per element: position of each of its 81 entries in the CSC values,
    /// or `CONSTRAINED`.
    slots: Vec<[usize; 81]>,
    /// Per element: its 9 global dofs.
    element_dofs: Vec<[usize; 9]>,
    /// Reject triangles that turn over in their plane.
    pub check_inversion: bool,
    outputs: Vec<ElementOutput>,
}

impl Assembler {
    /// Builds the pattern and the element slots.
    pub fn new(model: &MembraneModel, dofs: DofMap, check_inversion: bool) -> Self {
        let n = dofs.n_free();
        let element_dofs: Vec<[usize; 9]> = model
            .triangles
            .iter()
            .map(|t| std::array::from_fn(|i| 3 * t[i / 3] + i % 3))
            .collect();
        let mut columns: Vec<Vec<usize>> = vec![Vec::new(); n];
        for ed in &element_dofs {
            for &dj in ed {
                let Some(j) = dofs.free_index[dj] else {
                    continue;
                };
                for &di in ed {
                    if let Some(i) = dofs.free_index[di] {
                        columns[j].push(i);
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
        let slots = element_dofs
            .iter()
            .map(|ed| {
                let mut s = [CONSTRAINED; 81];
                for (b, &dj) in ed.iter().enumerate() {
                    let Some(j) = dofs.free_index[dj] else {
                        continue;
                    };
                    let rows = &row_idx[col_ptr[j]..col_ptr[j + 1]];
                    for (a, &di) in ed.iter().enumerate() {
                        if let Some(i) = dofs.free_index[di] {
                            let k = rows.binary_search(&i).expect("entry is in the pattern");
                            s[9 * b + a] = col_ptr[j] + k;
                        }
                    }
                }
                s
            })
            .collect();
        let symbolic = SymbolicSparseColMat::new_checked(n, n, col_ptr, None, row_idx);
        let outputs = vec![ElementOutput::default(); model.triangles.len()];
        Self {
            dofs,
            symbolic,
            slots,
            element_dofs,
            check_inversion,
            outputs,
        }
    }

    /// Number of stored non-zeros of the free-dof tangent.
    pub fn nnz(&self) -> usize {
        self.symbolic.row_idx().len()
    }

    fn run_elements(&mut self, model: &MembraneModel, u: &[f64], tangent: bool) {
        let check_inversion = self.check_inversion;
        self.outputs
            .par_iter_mut()
            .enumerate()
            .for_each(|(e, out)| {
                let x = model.element_displacements(e, u);
                let reference = &model.references[e];
                let result = if tangent {
                    reference
                        .force_tangent(&x, &model.material, model.thickness)
                        .map(|t| (t.kinematics, t.state, t.force, Some(t.stiffness)))
                } else {
                    reference
                        .force(&x, &model.material, model.thickness)
                        .map(|(k, s, f)| (k, s, f, None))
                };
                out.failure = None;
                match result {
                    Ok((kin, state, force, stiffness)) => {
                        if check_inversion && kin.orientation <= 0.0 {
                            out.failure = Some(ElementFailureKind::Inverted {
                                orientation: kin.orientation,
                            });
                            return;
                        }
                        out.energy = model.thickness * reference.area * state.energy;
                        out.force = force;
                        if let Some(k) = stiffness {
                            out.stiffness = k;
                        }
                    }
                    Err(err) => out.failure = Some(ElementFailureKind::Material(err)),
                }
            });
    }

    fn first_failure(&self) -> Result<(), ElementFailure> {
        match self.outputs.iter().position(|o| o.failure.is_some()) {
            Some(element) => Err(ElementFailure {
                element,
                kind: self.outputs[element].failure.expect("found"),
            }),
            None => Ok(()),
        }
    }

    /// Total energy `Σ t A0 W` [N·mm] and the internal force `internal`
    /// (all dofs, [N]) at displacement `u`.
    ///
    /// # Errors
    /// The lowest-index element that failed.
    pub fn force(
        &mut self,
        model: &MembraneModel,
        u: &[f64],
        internal: &mut [f64],
    ) -> Result<f64, ElementFailure> {
        self.run_elements(model, u, false);
        self.first_failure()?;
        internal.fill(0.0);
        let mut energy = 0.0;
        for (out, ed) in self.outputs.iter().zip(&self.element_dofs) {
            energy += out.energy;
            for (a, &d) in ed.iter().enumerate() {
                internal[d] += out.force[a];
            }
        }
        Ok(energy)
    }

    /// As [`Assembler::force`], and the free-dof tangent into `values`
    /// (CSC values of [`Assembler::symbolic`]).
    ///
    /// # Errors
    /// The lowest-index element that failed.
    pub fn force_tangent(
        &mut self,
        model: &MembraneModel,
        u: &[f64],
        internal: &mut [f64],
        values: &mut [f64],
    ) -> Result<f64, ElementFailure> {
        self.run_elements(model, u, true);
        self.first_failure()?;
        internal.fill(0.0);
        values.fill(0.0);
        let mut energy = 0.0;
        for ((out, ed), slots) in self.outputs.iter().zip(&self.element_dofs).zip(&self.slots) {
            energy += out.energy;
            for (a, &d) in ed.iter().enumerate() {
                internal[d] += out.force[a];
            }
            for (k, &slot) in slots.iter().enumerate() {
                if slot != CONSTRAINED {
                    // Column-major 9×9: entry (a, b) at 9 b + a.
                    values[slot] += out.stiffness[k];
                }
            }
        }
        Ok(energy)
    }
}
