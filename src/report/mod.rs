//! Running a case and reporting its results: the floor between the case
//! files ([`crate::case`]) and the command line ([`crate::cli`]).
//!
//! One runner, [`run`], prepares a case ([`prepare`]: built, and every
//! check of its solver's set-up passed, before anything is written), then
//! drives either solver once over it and hands every recorded state — a converged quasi-static step or an
//! explicit output — to a [`Report`]. What a state becomes is the report's
//! business:
//!
//! - [`files::FolderReport`] writes a run folder (CSV, PNG, VTU/PVD,
//!   `summary.json`, `status.json`), with the OAT's files written by
//!   [`oat`] and a forming run's by [`forming`] (histories, states,
//!   readouts of the blank, maps);
//! - [`memory::MemoryReport`] keeps the history rows and the last state's
//!   fields as Rust values, writing nothing.
//!
//! What is measured on a state (clamp force and MDZ means of an OAT; tool
//! forces, reactions, probes, stroke, draw-in and zone means of a forming
//! run) is computed once, by the runner, and handed to every report alike
//! (`docs/architecture.md`).

pub mod energy;
pub mod estimate;
pub mod files;
pub mod folder;
pub mod forming;
pub mod json;
pub mod memory;
pub mod oat;
pub mod progress;
pub mod provenance;
pub mod rows;
mod runner;

pub use estimate::SolverEstimate;
pub use files::{FolderReport, FolderSummary};
pub use folder::{ExitStatus, RunFolder};
pub use progress::Progress;
pub use runner::{
    Built, Outcome, Prepared, Recorded, Report, RunError, SolveTimings, Solved, explicit_hint,
    prepare, run,
};

use std::path::Path;

use crate::solver::RunStatus;
use crate::solver::explicit::ExplicitRecord;

/// An output file that could not be written: its path and why.
#[derive(Debug, Clone, thiserror::Error)]
#[error("{path}: {error}")]
pub struct WriteError {
    /// The file.
    pub path: String,
    /// Why (the I/O or serialisation error).
    pub error: String,
}

/// The [`WriteError`] of `path`.
fn io_err(path: &Path, e: impl std::fmt::Display) -> WriteError {
    WriteError {
        path: path.display().to_string(),
        error: e.to_string(),
    }
}

/// What follows the load in the caption and the header of the last
/// converged state that a run which stopped early writes as one more
/// output state (`docs/cases.md`, "Incomplete runs and exit codes").
pub const LAST_STATE_NOTE: &str = " (last converged state)";

/// Units of every number a report writes.
pub(crate) const UNITS: &str = "mm, N, MPa, tonne/mm^3, s; angles in degrees";

/// `status: complete`, or where an incomplete run stopped and why, or
/// where an interrupted one stopped, with the load reached and the load
/// attempted written by `reached` and `attempted` (the output files'
/// header line).
pub(crate) fn status_line(
    status: &RunStatus,
    reached: impl Fn(f64) -> String,
    attempted: impl Fn(f64) -> String,
) -> String {
    match status {
        RunStatus::Complete => "status: complete".to_string(),
        RunStatus::Incomplete {
            load_reached,
            load_attempted,
            reason,
        } => format!(
            "status: INCOMPLETE - stopped at {}; the step to {} failed: {reason}",
            reached(*load_reached),
            attempted(*load_attempted)
        ),
        RunStatus::Interrupted { load_reached } => format!(
            "status: INTERRUPTED - stopped on request (SIGINT/SIGTERM) at {}",
            reached(*load_reached)
        ),
    }
}

/// The suffix of plot titles: nothing for a complete run, else
/// ` (INCOMPLETE)` or ` (INTERRUPTED)`.
pub(crate) fn plot_suffix(status: &RunStatus) -> &'static str {
    match status {
        RunStatus::Complete => "",
        RunStatus::Incomplete { .. } => " (INCOMPLETE)",
        RunStatus::Interrupted { .. } => " (INTERRUPTED)",
    }
}

/// The progress detail of an explicit output: time, increments, `KE/IE`.
pub(crate) fn explicit_progress(record: &ExplicitRecord) -> String {
    format!(
        "t = {:.4} s, {} increments, KE/IE = {:.2e}",
        record.time,
        record.increment,
        record.energies.kinetic_ratio()
    )
}
