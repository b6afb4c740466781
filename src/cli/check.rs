//! `ncform check CASE`: a dry run, as a solver's data check. The case is
//! read, built and made ready for its solver — every check of the solver's
//! set-up passed, as `ncform run` does before it touches its output folder
//! ([`crate::report::prepare`]) — and its estimate printed: the solver's
//! work (explicit increments from the first stable step, the duration and
//! the outputs; quasi-static load steps from the load stepping), a rough
//! run time and the size of the outputs (`docs/cases.md`, "Checking a
//! case"). Nothing is written and no folder is touched. The exit codes are
//! `run`'s for bad input: 0 ready to run, 1 bad input or set-up error.

use std::io::Write;
use std::path::Path;

use crate::case::{Case, SolverKind};
use crate::report::{ExitStatus, Prepared, prepare};

use super::run::RunCommandError;

/// What `check` prints on `out` for a prepared case: what the case is, its
/// warnings (unusual values, keys read but not used), the estimate, and
/// the warning when its outputs would dwarf the solve (also on `out`: the
/// check's whole answer is its report).
///
/// # Errors
/// Only a failed write to `out`.
pub fn write_check(prepared: &Prepared, mut out: impl Write) -> std::io::Result<()> {
    let case = prepared.case();
    let estimate = prepared.estimate();
    let scenario = match case {
        Case::Oat(_) => "off-axis tension test",
        Case::Forming(_) => "forming",
    };
    let solver = match case.solver_kind() {
        SolverKind::QuasiStatic => "quasi-static",
        SolverKind::Explicit => "explicit",
    };
    let m = estimate.model;
    let count =
        |n: usize, one: &str, many: &str| format!("{n} {}", if n == 1 { one } else { many });
    let plies = if m.plies > 0 {
        format!(
            ", {}, {}",
            count(m.plies, "ply", "plies"),
            count(m.tools, "tool", "tools")
        )
    } else {
        String::new()
    };
    writeln!(
        out,
        "{} ({}): {scenario}, {solver} solver; {} nodes, {} triangles{plies}, {} model terms",
        case.title(),
        case.source(),
        m.nodes,
        m.elements,
        m.terms
    )?;
    for warning in case.warnings() {
        writeln!(out, "warning: {warning}")?;
    }
    for line in estimate.lines() {
        writeln!(out, "{line}")?;
    }
    if let Some(warning) = estimate.output_warning() {
        writeln!(out, "warning: {warning}")?;
    }
    writeln!(
        out,
        "check: the case is ready to run: it reads, builds and passes every set-up check of its solver (nothing was written)"
    )
}

/// Checks the case file `case`: reads, builds and prepares it, prints
/// [`write_check`] on stdout.
///
/// # Errors
/// A case that cannot be read or built, or whose solver cannot be set up
/// (exit 1, as `run`).
pub fn check_command(case: &Path) -> Result<ExitStatus, RunCommandError> {
    let spec = Case::load(case)?;
    let prepared = prepare(&spec)?;
    // A closed pipe (`ncform check … | head -1`) is not a failure.
    let _ = write_check(&prepared, std::io::stdout().lock());
    Ok(ExitStatus::Complete)
}
