//! The discretised body both solvers drive: the nodes of one or more plies
//! (three displacement dofs each), the dofs of rigid bodies (a tool's
//! translation along its axis, numbered after the nodes), and a list of
//! force terms ([`Term`]): membrane and bending of each ply, contact with
//! tools, body and dead loads, rigid-body masses. The solvers see only the
//! [`Term`] interface; which terms exist is the case layer's business
//! (`docs/model.md`).

pub mod bending;
pub mod contact;
pub mod loads;
pub mod membrane;
pub mod ply_contact;
pub mod term;

pub use bending::{BendingSetupError, BendingTerm};
pub use contact::{ContactOptions, ExplicitPenalty, NodeContact, ToolContact};
pub use loads::{DeadLoad, LoadAmplitude, RigidBodyMass};
pub use membrane::{MembraneModel, MembraneOptions, MembraneTerm};
pub use ply_contact::{PlyContact, PlyContactOptions, PlyNodeContact, PlySurface};
pub use term::{
    Augmentation, FrequencyBound, MassCoupling, MassScaling, Masses, NO_SLOT, State, Stencils,
    Term, TermEnergy, TermFailure,
};

/// A dof of a rigid body (a tool's translation along its axis).
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraDof {
    /// What it is, for messages and outputs ("punch", "blankholder").
    pub name: String,
}

/// Nodes, extra dofs and force terms.
pub struct Model {
    /// Number of nodes (dofs `3 n + k`, `k = 0, 1, 2` for x, y, z).
    pub nodes: usize,
    /// The extra dofs, numbered `3 nodes + i`.
    pub extras: Vec<ExtraDof>,
    /// The force terms, evaluated in this order.
    pub terms: Vec<Box<dyn Term>>,
}

impl Model {
    /// A model of `nodes` nodes without terms.
    pub fn new(nodes: usize) -> Self {
        Self {
            nodes,
            extras: Vec::new(),
            terms: Vec::new(),
        }
    }

    /// A model made of one membrane (the off-axis tension test).
    pub fn membrane(membrane: MembraneModel, options: MembraneOptions) -> Self {
        let mut model = Self::new(membrane.nodes.len());
        model.add(MembraneTerm::new("membrane", membrane, options));
        model
    }

    /// Adds an extra dof; returns its index among the extras.
    pub fn add_extra(&mut self, name: impl Into<String>) -> usize {
        self.extras.push(ExtraDof { name: name.into() });
        self.extras.len() - 1
    }

    /// The global dof of extra `index`.
    pub fn extra_dof(&self, index: usize) -> usize {
        3 * self.nodes + index
    }

    /// Adds a term.
    pub fn add(&mut self, term: impl Term + 'static) {
        self.terms.push(Box::new(term));
    }

    /// Total number of dofs.
    pub fn dofs(&self) -> usize {
        3 * self.nodes + self.extras.len()
    }

    /// The first term of type `T`, if any (for outputs that need a term's
    /// own data, such as a membrane's triangles).
    pub fn term<T: Term + 'static>(&self) -> Option<&T> {
        self.terms
            .iter()
            .find_map(|t| (t.as_ref() as &dyn std::any::Any).downcast_ref::<T>())
    }

    /// Every term of type `T`, in order.
    pub fn terms_of<T: Term + 'static>(&self) -> impl Iterator<Item = &T> {
        self.terms
            .iter()
            .filter_map(|t| (t.as_ref() as &dyn std::any::Any).downcast_ref::<T>())
    }

    /// Every term of type `T`, in order, mutably (to change a term's
    /// settings after the model is built).
    pub fn terms_of_mut<T: Term + 'static>(&mut self) -> impl Iterator<Item = &mut T> {
        self.terms
            .iter_mut()
            .filter_map(|t| (t.as_mut() as &mut dyn std::any::Any).downcast_mut::<T>())
    }

    /// `true` when every term's tangent is symmetric.
    pub fn symmetric(&self) -> bool {
        self.terms.iter().all(|t| t.symmetric())
    }

    /// Merged augmentation report of every term that augments, `None` when
    /// none does.
    pub fn augment(&mut self, state: &State) -> Option<Augmentation> {
        self.terms
            .iter_mut()
            .filter_map(|t| t.augment(state))
            .reduce(Augmentation::merge)
    }

    /// Commits every term's history at a converged load step.
    pub fn commit(&mut self, state: &State) {
        for t in &mut self.terms {
            t.commit(state);
        }
    }

    /// Restores every term's history to the last commit.
    pub fn restore(&mut self) {
        for t in &mut self.terms {
            t.restore();
        }
    }
}
