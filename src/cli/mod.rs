//! The `ncform` command line's commands, written over readers and writers
//! so tests drive them without a process: `run` (argument handling over
//! [`crate::report::run`]), `check` (the dry run over
//! [`crate::report::prepare`]) and the `material` subcommands.

pub mod check;
pub mod export;
pub mod fit;
pub mod material_check;
pub mod material_curves;
pub mod material_eval;
pub mod run;
pub mod sweep;
