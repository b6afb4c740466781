//! Assembly and solvers. The solvers know nothing of OATs, forming benches
//! or of which force terms a model has: they see a [`crate::model::Model`]
//! (its terms' stencils, forces, tangents, frequency bounds, masses and
//! energies), Dirichlet conditions scaled by a load parameter `λ`, and
//! parameters.

pub mod amplitude;
pub mod assembly;
pub mod cancel;
pub mod dofs;
pub mod explicit;
pub mod linear;
pub mod newton;
pub mod status;

pub use amplitude::Amplitude;
pub use assembly::Assembler;
pub use cancel::CancelToken;
pub use dofs::{Dirichlet, DofMap};
pub use explicit::{
    ExplicitEstimate, ExplicitParameters, ExplicitRecord, ExplicitResult, ExplicitSetUp,
    ExplicitState, set_up_explicit, solve_explicit,
};
pub use linear::{LinearSolverKind, SparseSolver};
pub use newton::{
    ConvergedTangent, NewtonParameters, QuasiStaticResult, QuasiStaticSetupError, SolverTimings,
    Stabilisation, StabilisationRecord, StepRecord, check_quasi_static, solve_quasi_static,
    solve_quasi_static_observed,
};
pub use status::{RunStatus, Snapshot};
