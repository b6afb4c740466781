//! The bending term of a ply: rotation-free orthotropic bending of its
//! triangles, superposed on the membrane with shared nodes (paper
//! Section 3, "Bending behavior"; the element in `docs/theory.md` and
//! `docs/bending.md`). Each triangle's curvature comes from its own nodes
//! and the opposite vertices of its three edge neighbours (a 6-node
//! stencil), measured along the sheared material directions, with
//! `W = A0 ½ ΔKᵀ diag(B11, B22, B66) ΔK`.
//!
//! The quasi-static path evaluates the exact force and tangent per stencil;
//! the explicit path runs the three-phase pass that writes each triangle's
//! bending force on its own three nodes only
//! ([`crate::element::bending::BendingPass`]).

use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::Vector3;
use rayon::prelude::*;

use super::term::{
    FrequencyBound, Masses, NO_SLOT, State, Stencils, Term, TermEnergy, TermFailure,
};
use crate::element::bending::{
    BendingElement, BendingError, BendingPass, BendingScratch, BendingStiffness, BendingTopology,
    TopologyError,
};

/// Smallest run of elements one rayon task takes.
const ELEMENT_MIN_LEN: usize = 256;

/// Why a bending term cannot be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BendingSetupError {
    /// The mesh is not a manifold with consistent orientation.
    #[error("{0}")]
    Topology(#[from] TopologyError),
    /// A triangle or one of its hinges is degenerate.
    #[error("element {element}: {error}")]
    Element {
        /// Triangle index.
        element: usize,
        /// The cause.
        error: BendingError,
    },
}

/// The bending of one ply's triangles.
pub struct BendingTerm {
    name: String,
    stiffness: BendingStiffness,
    topology: BendingTopology,
    elements: Vec<BendingElement>,
    pass: BendingPass,
    scratch: BendingScratch,
    energies: Vec<f64>,
    /// Reference positions of every model node [mm].
    nodes: Vec<Vector3<f64>>,
}

impl BendingTerm {
    /// Bending of the triangles `triangles` (model node indices) of a ply
    /// with global fibre directions `fibres`, in a model whose nodes have
    /// the reference positions `nodes`; boundary edges whose two nodes are
    /// both `clamped` get a fixed rotation.
    ///
    /// # Errors
    /// A non-manifold or inconsistently oriented mesh, a degenerate
    /// triangle or hinge, a fibre perpendicular to a triangle.
    pub fn new(
        name: impl Into<String>,
        nodes: &[Vector3<f64>],
        triangles: &[[usize; 3]],
        fibres: &[Vector3<f64>],
        clamped: &[bool],
        stiffness: BendingStiffness,
    ) -> Result<Self, BendingSetupError> {
        let topology = BendingTopology::new(triangles, nodes.len())?;
        let kinds = topology.hinge_kinds(clamped)?;
        let elements = (0..triangles.len())
            .map(|e| {
                let stencil = topology.stencil(e);
                let first = stencil[0].unwrap_or(0);
                let x: [Vector3<f64>; 6] =
                    std::array::from_fn(|s| nodes[stencil[s].unwrap_or(first)]);
                BendingElement::new(&x, kinds[e], &fibres[e])
                    .map_err(|error| BendingSetupError::Element { element: e, error })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let pass = BendingPass::new(nodes, &topology, &elements, &stiffness)?;
        let scratch = pass.scratch();
        Ok(Self {
            name: name.into(),
            stiffness,
            energies: vec![0.0; triangles.len()],
            elements,
            pass,
            scratch,
            topology,
            nodes: nodes.to_vec(),
        })
    }

    /// The stiffness.
    pub fn stiffness(&self) -> BendingStiffness {
        self.stiffness
    }

    /// The curvature change `ΔK = [ΔK11, ΔK22, 2ΔK12]` [1/mm] of every
    /// triangle at `u`, in the reference fibre basis (for result fields).
    ///
    /// # Errors
    /// The lowest-index triangle that cannot be evaluated.
    pub fn curvatures(&self, u: &[f64]) -> Result<Vec<[f64; 3]>, TermFailure> {
        (0..self.elements.len())
            .map(|e| {
                self.elements[e]
                    .curvature(&self.positions(e, u))
                    .map(|c| [c.change[0], c.change[1], c.change[2]])
                    .map_err(|err| self.failure(e, err.to_string()))
            })
            .collect()
    }

    /// Current positions of the six slots of triangle `e`.
    fn positions(&self, e: usize, u: &[f64]) -> [Vector3<f64>; 6] {
        let stencil = self.topology.stencil(e);
        let first = stencil[0].unwrap_or(0);
        std::array::from_fn(|s| {
            let n = stencil[s].unwrap_or(first);
            self.nodes[n] + Vector3::new(u[3 * n], u[3 * n + 1], u[3 * n + 2])
        })
    }

    fn failure(&self, e: usize, reason: String) -> TermFailure {
        TermFailure {
            term: self.name.clone(),
            what: "element",
            index: e,
            reason,
        }
    }
}

impl Term for BendingTerm {
    fn name(&self) -> &str {
        &self.name
    }

    fn stencils(&self) -> Stencils {
        Stencils {
            count: self.elements.len(),
            nodes: 6,
            extras: 0,
        }
    }

    fn stencil(&self, s: usize, nodes: &mut [usize], _extras: &mut [usize]) {
        for (slot, n) in nodes.iter_mut().zip(self.topology.stencil(s)) {
            *slot = n.unwrap_or(NO_SLOT);
        }
    }

    /// Energy, force and exact tangent of every triangle's 6-node stencil,
    /// in parallel.
    fn evaluate(
        &mut self,
        state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let mut energies = std::mem::take(&mut self.energies);
        let this = &*self;
        let u = state.u;
        let fail = |e: usize| {
            first_failure.fetch_min(e, Ordering::Relaxed);
        };
        match tangent {
            Some(tangent) => energies
                .par_iter_mut()
                .zip(force.par_chunks_mut(18))
                .zip(tangent.par_chunks_mut(324))
                .enumerate()
                .with_min_len(ELEMENT_MIN_LEN)
                .for_each(|(e, ((w, f), k))| {
                    match this.elements[e].force_tangent(&this.positions(e, u), &this.stiffness) {
                        Ok(t) => {
                            *w = t.energy;
                            f.copy_from_slice(t.force.as_slice());
                            k.copy_from_slice(t.stiffness.as_slice());
                        }
                        Err(_) => fail(e),
                    }
                }),
            None => energies
                .par_iter_mut()
                .zip(force.par_chunks_mut(18))
                .enumerate()
                .with_min_len(ELEMENT_MIN_LEN)
                .for_each(|(e, (w, f))| {
                    match this.elements[e].force(&this.positions(e, u), &this.stiffness) {
                        Ok(t) => {
                            *w = t.energy;
                            f.copy_from_slice(t.force.as_slice());
                        }
                        Err(_) => fail(e),
                    }
                }),
        }
        self.energies = energies;
        match first_failure.into_inner() {
            usize::MAX => Ok(self.energies.iter().sum()),
            e => {
                let reason = match self.elements[e].energy(&self.positions(e, u), &self.stiffness) {
                    Err(err) => err.to_string(),
                    Ok(_) => "the bending force is not finite".to_string(),
                };
                Err(self.failure(e, reason))
            }
        }
    }

    /// Each triangle's own three nodes: the three-phase pass writes there.
    fn explicit_stencils(&self) -> Stencils {
        Stencils {
            count: self.elements.len(),
            nodes: 3,
            extras: 0,
        }
    }

    fn explicit_stencil(&self, s: usize, nodes: &mut [usize], _extras: &mut [usize]) {
        nodes.copy_from_slice(&self.topology.triangles[s]);
    }

    fn explicit_forces(&mut self, state: &State, out: &mut [f64]) -> Result<(), TermFailure> {
        let (forces, rest) = out.as_chunks_mut::<9>();
        rest.fill(0.0);
        self.pass
            .write_forces(state.u, &mut self.scratch, forces)
            .map_err(|f| {
                let reason = match self.elements[f.element]
                    .energy(&self.positions(f.element, state.u), &self.stiffness)
                {
                    Err(err) => err.to_string(),
                    Ok(_) => "the bending force is not finite".to_string(),
                };
                self.failure(f.element, reason)
            })
    }

    /// A node-row (Gershgorin) bound of `λmax(M⁻¹ K_bending)`: with the
    /// element block bounds `β_ab ≥ ‖(K_e)_ab‖₂`
    /// ([`BendingElement::block_bounds`]), each node's row of
    /// `M^{-½} K M^{-½}` sums to at most `Σ_e Σ_b β_ab/√(m_n m_b)` over the
    /// stencils at the node, and `λmax` is at most the largest row
    /// (`docs/bending.md`, "Frequency bound", "Node rows").
    fn frequency_bound(
        &self,
        state: &State,
        masses: &Masses,
    ) -> Result<FrequencyBound, TermFailure> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let mass_of = |n: usize| masses.node[n];
        // Per element and slot: Σ_b min(β_ab, β_ba)/√m_b.
        let element_rows: Vec<[f64; 6]> = (0..self.elements.len())
            .into_par_iter()
            .with_min_len(ELEMENT_MIN_LEN)
            .map(|e| {
                let stencil = self.topology.stencil(e);
                let inverse_roots: [f64; 6] =
                    std::array::from_fn(|s| stencil[s].map_or(0.0, |n| 1.0 / mass_of(n).sqrt()));
                if stencil
                    .iter()
                    .flatten()
                    .any(|&n| !(mass_of(n) > 0.0 && mass_of(n).is_finite()))
                {
                    first_failure.fetch_min(e, Ordering::Relaxed);
                    return [0.0; 6];
                }
                match self.elements[e].block_bounds(&self.positions(e, state.u), &self.stiffness) {
                    Ok(beta) => std::array::from_fn(|a| {
                        (0..6)
                            .map(|b| beta[a][b].min(beta[b][a]) * inverse_roots[b])
                            .sum()
                    }),
                    Err(_) => {
                        first_failure.fetch_min(e, Ordering::Relaxed);
                        [0.0; 6]
                    }
                }
            })
            .collect();
        if let e @ 0..usize::MAX = first_failure.into_inner() {
            return Err(self.failure(e, "no frequency bound at this state".into()));
        }
        let mut node_rows = vec![0.0; masses.node.len()];
        for (e, rows) in element_rows.iter().enumerate() {
            for (slot, node) in self.topology.stencil(e).iter().enumerate() {
                if let Some(n) = node {
                    node_rows[*n] += rows[slot];
                }
            }
        }
        Ok(FrequencyBound::nodes(
            node_rows
                .iter()
                .zip(&masses.node)
                .filter(|(row, _)| **row > 0.0)
                .map(|(row, m)| row / m.sqrt())
                .fold(0.0, f64::max),
        ))
    }

    fn energy(&mut self, state: &State) -> Result<TermEnergy, TermFailure> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let mut energies = std::mem::take(&mut self.energies);
        let this = &*self;
        energies
            .par_iter_mut()
            .enumerate()
            .with_min_len(ELEMENT_MIN_LEN)
            .for_each(|(e, w)| {
                match this.elements[e].energy(&this.positions(e, state.u), &this.stiffness) {
                    Ok(v) => *w = v,
                    Err(_) => {
                        first_failure.fetch_min(e, Ordering::Relaxed);
                    }
                }
            });
        self.energies = energies;
        match first_failure.into_inner() {
            usize::MAX => Ok(TermEnergy {
                internal: self.energies.iter().sum(),
                ..Default::default()
            }),
            e => Err(self.failure(e, "the bending energy cannot be evaluated".into())),
        }
    }
}
