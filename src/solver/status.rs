//! What both solvers hand back besides their own records: how a run ended
//! and what a step or output callback sees of the state.

use serde::Serialize;

use crate::model::Model;

/// How a run ended.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "status", rename_all = "lowercase")]
pub enum RunStatus {
    /// Reached the final load.
    Complete,
    /// Stopped early; results up to `load_reached` are valid.
    Incomplete {
        /// Last converged load.
        load_reached: f64,
        /// The load of the step that failed.
        load_attempted: f64,
        /// Why the last attempt failed.
        reason: String,
    },
    /// Stopped on request (the parameters' cancel token) at a safe point;
    /// results up to `load_reached` are valid.
    Interrupted {
        /// The load of the last converged step or output.
        load_reached: f64,
    },
}

/// What a step or output callback sees: the converged displacement, the
/// residual of every dof (the reaction at a constrained one, \[N\]) and the
/// model (for terms' own outputs: contact forces, say).
pub struct Snapshot<'a> {
    /// Displacement of every dof \[mm\].
    pub u: &'a [f64],
    /// `f_int − f_ext` of every dof \[N\].
    pub residual: &'a [f64],
    /// The model at this state.
    pub model: &'a Model,
}
