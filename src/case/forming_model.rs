//! The model of a forming case: what [`FormingCase::build`] returns (the
//! build step itself lives with the case, in `case/forming/build.rs`).
//! Field-by-field documentation of the case: `docs/cases.md`, "Forming
//! cases"; of the model: `docs/model.md`.
//!
//! [`FormingCase::build`]: super::forming::FormingCase::build

pub use super::forming::build::{BuiltPly, BuiltTool, FormingModel};
