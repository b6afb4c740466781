//! Command implementations behind the `ncform` binary, written over
//! readers and writers so tests drive them without a process.

mod energy;
pub mod form;
pub mod material_check;
pub mod material_curves;
pub mod material_eval;
pub mod run;
