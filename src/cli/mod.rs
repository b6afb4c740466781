//! Command implementations behind the `ncform` binary, written over
//! readers and writers so tests drive them without a process.

mod blank;
mod energy;
pub mod form;
pub mod material_check;
pub mod material_curves;
pub mod material_eval;
pub mod run;
pub mod run_folder;

use std::path::Path;

use crate::solver::RunStatus;
use crate::solver::explicit::ExplicitRecord;

/// An I/O error message that names the path.
fn io_err(path: &Path, e: impl std::fmt::Display) -> String {
    format!("{}: {e}", path.display())
}

/// What follows the load in the caption and the header of the last
/// converged state that a run which stopped early writes as one more
/// output state (`docs/cases.md`, "Incomplete runs and exit codes").
pub(crate) const LAST_STATE_NOTE: &str = " (last converged state)";

/// `status: complete`, or where an incomplete run stopped and why, or
/// where an interrupted one stopped, with the load reached and the load
/// attempted written by `reached` and `attempted` (the output files'
/// header line).
fn status_line(
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
fn plot_suffix(status: &RunStatus) -> &'static str {
    match status {
        RunStatus::Complete => "",
        RunStatus::Incomplete { .. } => " (INCOMPLETE)",
        RunStatus::Interrupted { .. } => " (INTERRUPTED)",
    }
}

/// The progress detail of an explicit output: time, increments, `KE/IE`.
fn explicit_progress(record: &ExplicitRecord) -> String {
    format!(
        "t = {:.4} s, {} increments, KE/IE = {:.2e}",
        record.time,
        record.increment,
        record.energies.kinetic_ratio()
    )
}
