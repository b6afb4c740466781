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
pub use contact::{ContactOptions, ExplicitPenalty, NodeContact, PenaltyError, ToolContact};
pub use loads::{DeadLoad, LoadAmplitude, RigidBodyMass};
pub use membrane::{MembraneModel, MembraneOptions, MembraneTerm};
pub use ply_contact::{PlyContact, PlyContactError, PlyContactOptions, PlyNodeContact, PlySurface};
pub use term::{
    Augmentation, FrequencyBound, MassCoupling, MassScaling, Masses, NO_SLOT, State, Stencils,
    Term, TermEnergy, TermFailure, rounded_up,
};

/// A dof of a rigid body (a tool's translation along its axis).
#[derive(Debug, Clone, PartialEq)]
pub struct ExtraDof {
    /// What it is, for messages and outputs ("punch", "blankholder").
    pub name: String,
}

/// A run of consecutive nodes that a user knows by name (a ply, the OAT's
/// specimen): their labels and reference positions, for messages that say
/// where something happened ([`Model::describe_dof`]).
#[derive(Debug, Clone, PartialEq)]
pub struct NodeGroup {
    /// What the nodes are, as a message names them (`ply "ply-0"`).
    pub name: String,
    /// The model's index of the group's first node.
    pub first: usize,
    /// The nodes' external labels (a mesh file's, else 1-based indices).
    pub labels: Vec<i64>,
    /// The nodes' reference positions \[mm\].
    pub reference: Vec<nalgebra::Vector3<f64>>,
}

impl NodeGroup {
    /// The nodes of `mesh`, numbered from `first` in the model, with the
    /// mesh's labels and positions.
    pub fn of_mesh(name: impl Into<String>, first: usize, mesh: &crate::mesh::Mesh) -> Self {
        Self {
            name: name.into(),
            first,
            labels: (0..mesh.nodes.len()).map(|n| mesh.node_label(n)).collect(),
            reference: mesh.nodes.clone(),
        }
    }
}

/// Nodes, extra dofs and force terms.
pub struct Model {
    /// Number of nodes (dofs `3 n + k`, `k = 0, 1, 2` for x, y, z).
    pub nodes: usize,
    /// The extra dofs, numbered `3 nodes + i`.
    pub extras: Vec<ExtraDof>,
    /// The force terms, evaluated in this order.
    pub terms: Vec<Box<dyn Term>>,
    /// Named groups of nodes, for messages (may be empty).
    pub node_groups: Vec<NodeGroup>,
}

impl Model {
    /// A model of `nodes` nodes without terms.
    pub fn new(nodes: usize) -> Self {
        Self {
            nodes,
            extras: Vec::new(),
            terms: Vec::new(),
            node_groups: Vec::new(),
        }
    }

    /// A model made of one membrane (the off-axis tension test).
    pub fn membrane(membrane: MembraneModel, options: MembraneOptions) -> Self {
        let mut model = Self::new(membrane.nodes.len());
        model.add(MembraneTerm::new("membrane", membrane, options));
        model
    }

    /// Where dof `dof` is, for a message: `node 568 of ply "ply"
    /// (reference (-85.71, -57.14, 0.15) mm), y` for a node of a named group,
    /// `node 12 (index), x` for another node, `the blankholder's dof` for an
    /// extra dof.
    pub fn describe_dof(&self, dof: usize) -> String {
        const AXES: [&str; 3] = ["x", "y", "z"];
        if dof >= 3 * self.nodes {
            return match self.extras.get(dof - 3 * self.nodes) {
                Some(extra) => format!("the {}'s dof", extra.name),
                None => format!("dof {dof}"),
            };
        }
        format!("{}, {}", self.describe_node(dof / 3), AXES[dof % 3])
    }

    /// Where node `node` is, for a message: `node 568 of ply "ply"
    /// (reference (-85.71, -57.14, 0.15) mm)` for a node of a named group,
    /// `node 12 (index)` for another.
    pub fn describe_node(&self, node: usize) -> String {
        let group = self
            .node_groups
            .iter()
            .find(|g| node >= g.first && node - g.first < g.labels.len());
        match group {
            Some(g) => {
                let local = node - g.first;
                let x = g.reference.get(local).copied().unwrap_or_default();
                format!(
                    "node {} of {} (reference ({}, {}, {}) mm)",
                    g.labels[local],
                    g.name,
                    coordinate(x.x),
                    coordinate(x.y),
                    coordinate(x.z)
                )
            }
            None => format!("node {} (index)", node + 1),
        }
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

/// A node coordinate in a message: two decimals up to a kilometre, the
/// digits that matter beyond (a coordinate of 10¹⁸ mm would otherwise
/// print 22 digits).
fn coordinate(x: f64) -> String {
    if x.abs() < 1e6 {
        format!("{x:.2}")
    } else {
        crate::config::readable_number(x)
    }
}
