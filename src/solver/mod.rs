//! Assembly and solvers. The solver knows nothing of OATs or forming
//! benches: it sees a membrane model, Dirichlet conditions scaled by a load
//! parameter `λ`, and parameters.

pub mod assembly;
pub mod dofs;
pub mod explicit;
pub mod linear;
pub mod model;
pub mod newton;

pub use assembly::{Assembler, ElementFailure};
pub use dofs::{Dirichlet, DofMap};
pub use explicit::{
    ExplicitParameters, ExplicitRecord, ExplicitResult, ExplicitState, solve_explicit,
};
pub use linear::{LinearSolverKind, SparseSolver};
pub use model::MembraneModel;
pub use newton::{
    NewtonParameters, QuasiStaticResult, RunStatus, SolverTimings, StepRecord, solve_quasi_static,
};
