//! `ncform sweep` and `ncform collect`: argument handling over the
//! library's study entry points ([`crate::study`]): a new sweep, a resume,
//! the status, a Slurm task's points, and the collection of results
//! (`docs/studies.md`).

use std::path::{Path, PathBuf};

use super::run::say;
use crate::report::ExitStatus;

/// A line on stdout, formatted; a closed pipe is not a failure ([`say`]).
macro_rules! say_fmt {
    ($($arg:tt)*) => {
        say(&format!($($arg)*))
    };
}
use crate::solver::CancelToken;
use crate::study::{self, RunOptions, SweepOutcome, slurm::SlurmOptions};

/// What `ncform sweep` does with its argument.
#[derive(Debug, Clone)]
pub enum SweepAction {
    /// A sweep file to plan, prepare into `out` and run.
    Start {
        /// The sweep file.
        sweep: PathBuf,
        /// The sweep folder.
        out: PathBuf,
    },
    /// Resume the sweep folder.
    Resume(PathBuf),
    /// Print the status of the sweep folder.
    Status(PathBuf),
    /// Run these points of the sweep folder (a Slurm task).
    Points(PathBuf, Vec<usize>),
}

/// Parses `--points 3,4,5` (ranges `3-7` too).
///
/// # Errors
/// A message naming the item that is not an index.
pub fn parse_points(list: &str) -> Result<Vec<usize>, String> {
    let mut out = Vec::new();
    for item in list.split(',').map(str::trim).filter(|s| !s.is_empty()) {
        let bad = || format!("--points: '{item}' is not a point index or a range like 3-7");
        match item.split_once('-') {
            Some((a, b)) => {
                let (a, b): (usize, usize) =
                    (a.parse().map_err(|_| bad())?, b.parse().map_err(|_| bad())?);
                if a > b {
                    return Err(bad());
                }
                out.extend(a..=b);
            }
            None => out.push(item.parse().map_err(|_| bad())?),
        }
    }
    Ok(out)
}

/// Runs `ncform sweep`: prints what was done on stdout, progress on
/// stderr; the exit status is 0 when every point is complete (or, with
/// Slurm, submitted or queued), 3 when a point failed, 4 when interrupted.
///
/// # Errors
/// The message after `error: ` (exit 1).
pub fn sweep_command(
    action: &SweepAction,
    options: &RunOptions,
    cancel: &CancelToken,
) -> Result<ExitStatus, String> {
    let outcome = match action {
        SweepAction::Status(dir) => {
            say(study::status(dir).map_err(|e| e.to_string())?.trim_end());
            return Ok(ExitStatus::Complete);
        }
        SweepAction::Points(dir, points) => {
            let batch = study::run_listed(dir, points, cancel).map_err(|e| e.to_string())?;
            say_fmt!(
                "points {:?}: {} complete, {} failed, {} interrupted",
                points,
                batch.complete,
                batch.failed,
                batch.interrupted
            );
            return Ok(batch_exit(&batch));
        }
        SweepAction::Start { sweep, out } => {
            if options.slurm.is_none() && !options.quiet && !options.prepare_only {
                let (jobs, threads) = study::jobs_and_threads(options);
                eprintln!("sweep: {jobs} point(s) at once, {threads} thread(s) each");
            }
            let outcome = study::start(sweep, out, options, cancel).map_err(|e| e.to_string())?;
            if options.prepare_only {
                say_fmt!(
                    "{}: {} points prepared; run them with: ncform sweep {} --resume",
                    outcome.dir.display(),
                    outcome.points,
                    outcome.dir.display()
                );
                return Ok(ExitStatus::Complete);
            }
            outcome
        }
        SweepAction::Resume(dir) => {
            study::resume(dir, options, cancel).map_err(|e| e.to_string())?
        }
    };
    Ok(say_outcome(&outcome))
}

/// Prints what a start or resume did and returns the exit status.
fn say_outcome(o: &SweepOutcome) -> ExitStatus {
    let dir = o.dir.display();
    if !o.submitted.is_empty() || o.queued > 0 {
        for (job, n) in &o.submitted {
            say_fmt!("submitted Slurm job {job}: {n} point(s)");
        }
        say_fmt!(
            "{dir}: {} points, {} complete, {} queued in Slurm earlier, {} submitted now; follow with: ncform sweep {dir} --status",
            o.points,
            o.already_complete,
            o.queued,
            o.submitted.iter().map(|s| s.1).sum::<usize>()
        );
        return ExitStatus::Complete;
    }
    let b = &o.batch;
    say_fmt!(
        "{dir}: {} points: {} complete before, {} run now: {} complete, {} failed, {} interrupted",
        o.points,
        o.already_complete,
        b.complete + b.failed + b.interrupted,
        b.complete,
        b.failed,
        b.interrupted
    );
    if b.failed > 0 {
        eprintln!(
            "{} point(s) failed: see ncform sweep {dir} --status",
            b.failed
        );
    }
    if b.interrupted > 0 {
        eprintln!("interrupted: continue with ncform sweep {dir} --resume");
    }
    batch_exit(b)
}

/// 4 when interrupted, 3 when a point failed, else 0.
fn batch_exit(b: &study::local::BatchOutcome) -> ExitStatus {
    if b.interrupted > 0 {
        ExitStatus::Interrupted
    } else if b.failed > 0 {
        ExitStatus::Incomplete
    } else {
        ExitStatus::Complete
    }
}

/// The Slurm options of the command line.
#[allow(clippy::too_many_arguments)]
pub fn slurm_options(
    partition: Option<String>,
    time: Option<String>,
    max_parallel: Option<usize>,
    points_per_task: usize,
    cpus_per_task: usize,
    extra_args: Vec<String>,
) -> SlurmOptions {
    SlurmOptions {
        partition,
        time,
        max_parallel,
        points_per_task,
        cpus_per_task,
        extra_args,
    }
}

/// Runs `ncform collect DIR`: writes `results.csv`, the plots and (for a
/// sensitivity design) `sensitivity.json`; prints what it wrote.
///
/// # Errors
/// The message after `error: ` (exit 1).
pub fn collect_command(dir: &Path) -> Result<ExitStatus, String> {
    let c = study::collect::collect(dir).map_err(|e| e.to_string())?;
    let complete = c.rows.iter().filter(|r| r.status == "complete").count();
    say_fmt!(
        "{}: {} points ({} complete), {} result columns",
        dir.display(),
        c.rows.len(),
        complete,
        c.columns.len()
    );
    if let Some(text) = &c.sensitivity {
        say(text.trim_end());
    }
    for w in &c.written {
        say_fmt!("wrote {}", w.display());
    }
    Ok(ExitStatus::Complete)
}
