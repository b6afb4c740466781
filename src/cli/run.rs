//! `ncform run CASE [--out DIR] [--quiet]`: argument handling over the
//! library's runner ([`crate::report::run`]) with a run-folder report
//! ([`crate::report::FolderReport`]): the case prepared first (every
//! set-up check before the folder is touched), its estimate on stderr
//! (not with `--quiet`; a warning when the outputs would dwarf the solve
//! always), progress on stderr, one summary line on stdout, what is not as asked on stderr, and the exit status
//! (`docs/cases.md`, "Exit codes").

use std::io::Write as _;
use std::path::{Path, PathBuf};

use crate::case::Case;
use crate::report::{ExitStatus, FolderReport, FolderSummary, Progress, Report, RunError, prepare};
use crate::solver::{CancelToken, RunStatus};

/// Why `ncform run` could not run: a case file that cannot be read, or a
/// run that could not be set up. The message follows `error: `.
#[derive(Debug, thiserror::Error)]
pub enum RunCommandError {
    /// The case file (reading, parsing, validation).
    #[error("{0}")]
    Case(#[from] crate::config::ConfigError),
    /// The run (building, the output folder, the solver's set-up).
    #[error("{0}")]
    Run(#[from] RunError),
}

/// How a load is written in a message: `d = 20 mm`, `programme fraction
/// 0.5`.
type LoadText = fn(f64) -> String;

/// A line on stdout. A closed pipe (`ncform run … | head -1`) is not a
/// failure of the command: the results are on disk, so the error is
/// dropped instead of panicking as `println!` does.
pub(crate) fn say(line: &str) {
    let _ = writeln!(std::io::stdout(), "{line}");
}

/// Runs the case file `case` into `out` (default `out/<case stem>`), with
/// progress unless `quiet`, stopping at the next safe point once `cancel`
/// is cancelled; prints the summary line and what is not as asked.
///
/// # Errors
/// A case that cannot be read or built, an output folder that cannot be
/// prepared, a solver that cannot be set up (exit 1).
pub fn run_command(
    case: &Path,
    out: Option<PathBuf>,
    quiet: bool,
    cancel: &CancelToken,
) -> Result<ExitStatus, RunCommandError> {
    let spec = Case::load(case)?;
    for w in spec.warnings() {
        eprintln!("warning: {w}");
    }
    let out = out.unwrap_or_else(|| default_out_dir(case));
    let Some(summary) = run_into_folder(&spec, &out, quiet, cancel)? else {
        return Ok(ExitStatus::BadInput);
    };
    let (work, forces, wall_seconds, status, exit_status) = match &summary {
        FolderSummary::Oat(s) => oat_lines(s),
        FolderSummary::Forming(s) => forming_lines(s),
    };
    report_line(spec.title(), &work, wall_seconds, &forces, &out);
    let loads: (LoadText, LoadText) = match &spec {
        Case::Oat(_) => (|d| format!("d = {d} mm"), |d| format!("{d} mm")),
        Case::Forming(_) => (
            |load| format!("programme fraction {load}"),
            |load| load.to_string(),
        ),
    };
    say_exit(&status, exit_status, loads.0, loads.1);
    Ok(exit_status)
}

/// What `ncform run` does with a case read: every set-up check before the
/// folder `out` is touched, the estimate on stderr (not when `quiet`; the
/// warning when the outputs would dwarf the solve always), then the solve
/// into a run folder with progress unless `quiet`. Returns the folder's
/// summary (`None` when the run ended without one).
///
/// # Errors
/// A set-up error (the folder's `status.json` records it).
pub fn run_into_folder(
    spec: &Case,
    out: &Path,
    quiet: bool,
    cancel: &CancelToken,
) -> Result<Option<FolderSummary>, RunError> {
    let mut progress = match (spec, quiet) {
        (_, true) => Progress::Quiet,
        (Case::Oat(c), false) => Progress::auto(c.displacement),
        (Case::Forming(_), false) => Progress::auto_programme(),
    };
    let mut report = FolderReport::new(out);
    // Every set-up check before the folder is touched; then the estimate.
    let prepared = prepare(spec).inspect_err(|e| report.fail(e))?;
    let estimate = prepared.estimate();
    if !quiet {
        for line in estimate.lines() {
            eprintln!("{line}");
        }
    }
    if let Some(warning) = estimate.output_warning() {
        eprintln!("warning: {warning}");
    }
    prepared.solve(&mut report, &mut progress, cancel)?;
    Ok(report.into_summary())
}

/// An OAT's work line, its forces at the reported displacements, the wall
/// time, the status and the exit status.
fn oat_lines(
    s: &crate::report::oat::RunSummary,
) -> (String, Vec<String>, f64, RunStatus, ExitStatus) {
    let forces = s
        .forces
        .iter()
        .map(|(d, f)| format!("{f:.3} N at {d} mm"))
        .collect();
    let work = match &s.explicit {
        None => format!(
            "{} steps, {} Newton iterations",
            s.steps, s.newton_iterations
        ),
        Some(e) => format!(
            "explicit: {} increments, {:.1} M element-cycles/s on {} threads, max KE/IE {} %, energy balance {:.1e}",
            e.increments,
            e.element_cycles_per_second / 1e6,
            e.threads,
            percent(e.max_kinetic_ratio),
            e.max_relative_balance_error
        ),
    };
    (
        work,
        forces,
        s.wall_seconds,
        s.status.clone(),
        s.exit_status,
    )
}

/// `ratio` as a percentage with the digits that matter: two decimals up
/// to 10⁴ %, three significant digits in exponent form above (a run far
/// from quasi-static has a ratio of up to 10³⁰⁰).
fn percent(ratio: f64) -> String {
    let p = 100.0 * ratio;
    if p.abs() < 1e4 {
        format!("{p:.2}")
    } else {
        format!("{p:.2e}")
    }
}

/// A forming run's work line, every tool's last force, the wall time, the
/// status and the exit status.
fn forming_lines(
    s: &crate::report::forming::FormingSummary,
) -> (String, Vec<String>, f64, RunStatus, ExitStatus) {
    let work = match &s.explicit {
        None => format!(
            "{} steps, {} Newton iterations, {} augmentations",
            s.steps, s.newton_iterations, s.augmentations
        ),
        Some(e) => format!(
            "explicit: {} increments, max KE/IE {} %, energy balance {:.1e}",
            e.increments,
            percent(e.max_kinetic_ratio),
            e.max_relative_balance_error
        ),
    };
    let forces = s
        .history
        .last()
        .map(|row| {
            s.tools
                .iter()
                .zip(&row.tools)
                .map(|(name, t)| format!("{name}: {:.4} N at {:.3} mm", t.force, t.displacement))
                .collect()
        })
        .unwrap_or_default();
    (
        work,
        forces,
        s.wall_seconds,
        s.status.clone(),
        s.exit_status,
    )
}

/// The run's one-line summary (title, work, wall time, the last forces)
/// and where its results are.
fn report_line(title: &str, work: &str, wall_seconds: f64, forces: &[String], out: &Path) {
    let forces = if forces.is_empty() {
        String::new()
    } else {
        format!("; {}", forces.join(", "))
    };
    say(&format!("{title}: {work}, {wall_seconds:.2} s{forces}"));
    say(&format!("results in {}", out.display()));
}

/// Says on stderr what is not as asked, with the load reached and the
/// load attempted written by `reached` and `attempted`.
fn say_exit(
    status: &RunStatus,
    exit_status: ExitStatus,
    reached: impl Fn(f64) -> String,
    attempted: impl Fn(f64) -> String,
) {
    match status {
        RunStatus::Complete => {}
        RunStatus::Incomplete {
            load_reached,
            load_attempted,
            reason,
        } => eprintln!(
            "error: the solve failed in the step from {} to {}: {reason}; results up to {} are written and marked incomplete",
            reached(*load_reached),
            attempted(*load_attempted),
            reached(*load_reached)
        ),
        RunStatus::Interrupted { load_reached } => eprintln!(
            "interrupted: results up to {} are written and marked interrupted",
            reached(*load_reached)
        ),
    }
    if exit_status == ExitStatus::OutputsMissing {
        eprintln!("error: some outputs could not be written (listed above and in status.json)");
    }
}

/// The output folder for a case when none is given: `out/<case stem>`.
pub fn default_out_dir(case_path: &Path) -> PathBuf {
    let stem = case_path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("run");
    PathBuf::from("out").join(stem)
}
