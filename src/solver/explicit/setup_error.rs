//! Why a model cannot be integrated explicitly: the error of the set-up
//! of [`super::ExplicitSystem`] and of its coupling-mass chains.

use crate::model::TermFailure;

/// Why a model cannot be integrated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SetupError {
    /// A node with a free dof carries no mass (no element touches it).
    #[error(
        "node {node} has a free dof but no mass: no triangle uses it (constrain it or remove it)"
    )]
    MasslessNode {
        /// Node index.
        node: usize,
    },
    /// An extra dof (a floating rigid body) is free but has no mass.
    #[error("the dof of {name} is free but has no mass (give the rigid body a mass)")]
    MasslessExtra {
        /// The extra dof's name.
        name: String,
    },
    /// A term fails at the initial state.
    #[error("initial state: {0}")]
    Term(TermFailure),
    /// The terms' coupling masses cannot be solved by chains.
    #[error("coupling masses at node {node}: {reason}")]
    MassCoupling {
        /// The node.
        node: usize,
        /// What is wrong.
        reason: String,
    },
}
