//! `ncform fit FIT.toml --out DIR`: argument handling over
//! [`crate::fit::run::fit`] and [`crate::fit::output::write_outputs`]
//! (`docs/fit.md`).

use std::path::{Path, PathBuf};

use crate::fit::input::{FitInputError, FitSpec};
use crate::fit::optimise::LmStop;
use crate::fit::output::write_outputs;
use crate::fit::run::fit;
use crate::report::folder::FolderError;
use crate::report::{ExitStatus, RunFolder};
use crate::solver::{CancelToken, RunStatus};

/// Why `ncform fit` could not run.
#[derive(Debug, thiserror::Error)]
pub enum FitCommandError {
    /// The fit file, a case or a measured file was refused.
    #[error(transparent)]
    Input(#[from] FitInputError),
    /// The output folder cannot take the fit.
    #[error(transparent)]
    Folder(#[from] FolderError),
    /// The fit could not be set up.
    #[error("{0}")]
    Fit(String),
}

/// The default output folder: `out/<fit file stem>`.
fn default_out_dir(fit_file: &Path) -> PathBuf {
    let stem = fit_file
        .file_stem()
        .map_or_else(|| "fit".to_string(), |s| s.to_string_lossy().into_owned());
    PathBuf::from("out").join(stem)
}

/// Runs the fit of `fit_file` into `out` (default `out/<stem>`), with a
/// progress line per iteration unless `quiet`; prints the parameters, their
/// σ and the warnings. A fit that stops early (iteration limit, no
/// decrease, interrupted) writes what it has and says why (exit 2 or 3).
///
/// # Errors
/// Bad input (every check runs before any simulation), a folder that
/// cannot take the fit.
pub fn fit_command(
    fit_file: &Path,
    out: Option<PathBuf>,
    quiet: bool,
    cancel: &CancelToken,
) -> Result<ExitStatus, FitCommandError> {
    let spec = FitSpec::load(fit_file)?;
    for w in &spec.warnings {
        eprintln!("warning: {w}");
    }
    let out = out.unwrap_or_else(|| default_out_dir(fit_file));
    let mut folder = RunFolder::prepare(&out, &fit_file.display().to_string(), &spec.title, &[])?;
    let points: usize = spec
        .tests
        .iter()
        .map(|t| t.schedule.len() * t.measured.len())
        .sum();
    if !quiet {
        eprintln!(
            "fit {}: {} free parameters, {} tests, {points} residuals",
            spec.title,
            spec.free.len(),
            spec.tests.len()
        );
    }
    let outcome = match fit(
        &spec,
        |it, elapsed| {
            if !quiet {
                eprintln!(
                    "iteration {:3}  cost {:.6e}  λ {:.1e}  step {:.2e}  {}  {:.1} s{}",
                    it.iteration,
                    it.cost,
                    it.damping,
                    it.step,
                    if it.accepted { "accepted" } else { "rejected" },
                    elapsed,
                    it.failure
                        .as_ref()
                        .map_or(String::new(), |f| format!("  ({f})"))
                );
            }
        },
        cancel,
    ) {
        Ok(outcome) => outcome,
        Err(e) => {
            folder.fail(&e);
            return Err(FitCommandError::Fit(e));
        }
    };
    write_outputs(&spec, &outcome, folder.outputs_mut());
    println!(
        "{:<24} {:>14} {:>14} {:>12} {:>8}",
        "parameter", "start", "fitted", "1 sigma", "sigma %"
    );
    for p in &outcome.parameters {
        let (sigma, relative) = if p.sigma.is_finite() {
            (
                format!("{:.3e}", p.sigma),
                format!("{:.1}", 100.0 * p.sigma / p.value.abs()),
            )
        } else {
            ("-".to_string(), "-".to_string())
        };
        println!(
            "{:<24} {:>14.6e} {:>14.6e} {sigma:>12} {relative:>8}{}",
            p.key,
            p.start,
            p.value,
            if p.at_bound { "  at a bound" } else { "" }
        );
    }
    if let Some(id) = &outcome.identifiability {
        println!(
            "chi2 = {:.4e} over {} degrees of freedom; {} evaluations, {:.1} s",
            id.chi2, id.dof, outcome.evaluations, outcome.seconds
        );
    }
    for w in &outcome.warnings {
        eprintln!("warning: {w}");
    }
    println!("results in {}", out.display());
    let status = match &outcome.stop {
        _ if outcome.converged() => RunStatus::Complete,
        LmStop::Interrupted => RunStatus::Interrupted { load_reached: 0.0 },
        stop => RunStatus::Incomplete {
            load_reached: 0.0,
            load_attempted: 0.0,
            reason: format!("the optimiser stopped without converging: {stop:?}"),
        },
    };
    if !outcome.converged() {
        eprintln!(
            "the fit did not converge ({:?}); the outputs hold its best point",
            outcome.stop
        );
    }
    Ok(folder.finish(&status))
}
