//! Case files (TOML) → a runnable model. Only this layer knows what an
//! off-axis tension test is; the solver sees a membrane and Dirichlet
//! conditions. Field-by-field documentation: `docs/cases.md`.

pub mod bounds;
pub mod error;
pub mod explicit;
pub mod forming;
pub mod forming_model;
pub mod measure;
pub mod oat;
pub mod scenario;

pub use error::BuildError;
pub use explicit::{ExplicitSettings, SolverKind};
pub use oat::{OatCase, OatModel, Zone};
pub use scenario::Case;
