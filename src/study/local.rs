//! Running a sweep's points in this process: one point
//! ([`run_point`], what a Slurm task and a local worker both do), and
//! `--jobs N` points at once, each on a thread pool of its own share of
//! the cores, with a progress line ([`run_points`]).
//!
//! The runs are the library's one runner with a run-folder report, as
//! `ncform run POINT/case.toml --out POINT/run` makes them: the point's
//! run folder is removed first, so a point killed half-way is rerun from
//! scratch into a clean folder. Running in-process, a sweep killed by
//! SIGKILL leaves no child behind; its points still marked `running` are
//! rerun by `--resume` (`docs/studies.md`, "Resuming").

use std::io::IsTerminal as _;
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use super::sweep::{
    Manifest, PointState, PointStatus, SweepError, binary_identity, clean_point, host_name,
    inputs_sha256, now, write_status,
};
use crate::case::Case;
use crate::report::{ExitStatus, FolderReport, FolderSummary, Progress, Report, prepare};
use crate::solver::{CancelToken, RunStatus};

/// Runs point `index` of the sweep in `dir` on the current thread pool:
/// cleans its folder, marks it running, runs its case into `run/`, and
/// records how it ended. A panic in the run is caught and recorded as a
/// failure.
///
/// # Errors
/// [`SweepError::Folder`] when the point's folder or status cannot be
/// written (the run's own failures are recorded, not returned).
pub fn run_point(
    dir: &Path,
    manifest: &Manifest,
    index: usize,
    cancel: &CancelToken,
) -> Result<PointStatus, SweepError> {
    let pdir = manifest.point_dir(dir, index);
    clean_point(&pdir)?;
    let case_path = pdir.join("case.toml");
    let (_, binary_sha256) = binary_identity();
    let slurm_job = match (
        std::env::var("SLURM_ARRAY_JOB_ID"),
        std::env::var("SLURM_ARRAY_TASK_ID"),
        std::env::var("SLURM_JOB_ID"),
    ) {
        (Ok(a), Ok(t), _) => Some(format!("{a}_{t}")),
        (_, _, Ok(j)) => Some(j),
        _ => None,
    };
    let mut status = PointStatus {
        state: PointState::Running,
        pid: std::process::id(),
        host: host_name(),
        slurm_job,
        started: now(),
        ended: None,
        wall_seconds: None,
        exit_code: None,
        error: None,
        inputs_sha256: inputs_sha256(&case_path)?,
        binary_sha256,
    };
    write_status(&pdir, &status)?;
    let start = Instant::now();
    let out = pdir.join("run");
    let ran = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        run_case(&case_path, &out, cancel)
    }));
    let (state, code, error) = match ran {
        Ok(Ok((exit, run_status))) => {
            let state = match exit {
                ExitStatus::Complete => PointState::Complete,
                ExitStatus::Interrupted => PointState::Interrupted,
                _ => PointState::Failed,
            };
            let error = match (&run_status, exit) {
                (_, ExitStatus::OutputsMissing) => Some(
                    "some outputs could not be written (run/status.json lists them)".to_string(),
                ),
                (
                    RunStatus::Incomplete {
                        reason,
                        load_reached,
                        ..
                    },
                    _,
                ) => Some(format!(
                    "the solve stopped early at load {load_reached}: {reason}"
                )),
                (RunStatus::Interrupted { .. }, _) => {
                    Some("interrupted by SIGINT/SIGTERM".to_string())
                }
                _ => None,
            };
            (state, exit.code(), error)
        }
        Ok(Err(message)) => (
            PointState::Failed,
            ExitStatus::BadInput.code(),
            Some(message),
        ),
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "a panic".into());
            (
                PointState::Failed,
                ExitStatus::BadInput.code(),
                Some(format!("internal error: {what}")),
            )
        }
    };
    status.state = state;
    status.exit_code = Some(code);
    status.error = error;
    status.ended = Some(now());
    status.wall_seconds = Some(start.elapsed().as_secs_f64());
    write_status(&pdir, &status)?;
    Ok(status)
}

/// Runs the case file `case` into the run folder `out`, as `ncform run`
/// does, quietly: the exit status and how the solve ended, or the error
/// message `ncform run` would print.
fn run_case(
    case: &Path,
    out: &Path,
    cancel: &CancelToken,
) -> Result<(ExitStatus, RunStatus), String> {
    let spec = Case::load(case).map_err(|e| e.to_string())?;
    let mut report = FolderReport::new(out);
    let prepared = match prepare(&spec) {
        Ok(p) => p,
        Err(e) => {
            report.fail(&e);
            return Err(e.to_string());
        }
    };
    prepared
        .solve(&mut report, &mut Progress::Quiet, cancel)
        .map_err(|e| e.to_string())?;
    match report.into_summary() {
        Some(FolderSummary::Oat(s)) => Ok((s.exit_status, s.status.clone())),
        Some(FolderSummary::Forming(s)) => Ok((s.exit_status, s.status.clone())),
        None => Err("the run ended without a summary".into()),
    }
}

/// How a batch of points ended.
#[derive(Debug, Clone, Default)]
pub struct BatchOutcome {
    /// Points complete.
    pub complete: usize,
    /// Points failed.
    pub failed: usize,
    /// Points interrupted, or not started because of the interrupt.
    pub interrupted: usize,
}

/// Runs the points `todo` of the sweep in `dir`, `jobs` at a time, each on
/// a thread pool of `threads` threads, until done or `cancel` (the points
/// running then stop at their next safe point and are marked
/// interrupted; the others are not started). Shows a progress line on
/// stderr unless `quiet`: points done, failed, running, and the time left
/// estimated from the points done so far.
///
/// # Errors
/// [`SweepError::Folder`] when a point's folder cannot be written, or a
/// thread pool cannot be made.
pub fn run_points(
    dir: &Path,
    manifest: &Manifest,
    todo: &[usize],
    jobs: usize,
    threads: usize,
    cancel: &CancelToken,
    quiet: bool,
) -> Result<BatchOutcome, SweepError> {
    let next = AtomicUsize::new(0);
    let state = Mutex::new(Progressing {
        outcome: BatchOutcome::default(),
        running: 0,
        seconds: Vec::new(),
        total: todo.len(),
        start: Instant::now(),
        tty: std::io::stderr().is_terminal(),
    });
    let first_error: Mutex<Option<SweepError>> = Mutex::new(None);
    let jobs = jobs.clamp(1, todo.len().max(1));
    std::thread::scope(|scope| {
        for _ in 0..jobs {
            scope.spawn(|| {
                let pool = match rayon::ThreadPoolBuilder::new()
                    .num_threads(threads.max(1))
                    .build()
                {
                    Ok(p) => p,
                    Err(e) => {
                        lock(&first_error).get_or_insert(SweepError::Folder {
                            path: dir.display().to_string(),
                            reason: format!("cannot make a thread pool: {e}"),
                        });
                        return;
                    }
                };
                loop {
                    if cancel.is_cancelled() || lock(&first_error).is_some() {
                        return;
                    }
                    let k = next.fetch_add(1, Ordering::SeqCst);
                    let Some(&index) = todo.get(k) else {
                        return;
                    };
                    lock(&state).running += 1;
                    let result = pool.install(|| run_point(dir, manifest, index, cancel));
                    let mut s = lock(&state);
                    s.running -= 1;
                    match result {
                        Ok(status) => {
                            s.seconds.push(status.wall_seconds.unwrap_or(0.0));
                            match status.state {
                                PointState::Complete => s.outcome.complete += 1,
                                PointState::Interrupted | PointState::Running => {
                                    s.outcome.interrupted += 1
                                }
                                PointState::Failed => s.outcome.failed += 1,
                            }
                            if !quiet {
                                s.show(index, &status, jobs);
                            }
                        }
                        Err(e) => {
                            lock(&first_error).get_or_insert(e);
                        }
                    }
                }
            });
        }
    });
    if let Some(e) = lock(&first_error).take() {
        return Err(e);
    }
    let mut s = lock(&state);
    if !quiet && s.tty {
        eprintln!();
    }
    let started = s.outcome.complete + s.outcome.failed + s.outcome.interrupted;
    s.outcome.interrupted += todo.len().saturating_sub(started);
    Ok(s.outcome.clone())
}

/// The lock's contents (a poisoned lock's too: a worker's panic is caught
/// in [`run_point`], so the counts stay whole).
fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The progress of a batch.
struct Progressing {
    outcome: BatchOutcome,
    running: usize,
    seconds: Vec<f64>,
    total: usize,
    start: Instant,
    tty: bool,
}

impl Progressing {
    /// The progress line after point `index` ended with `status`.
    fn show(&self, index: usize, status: &PointStatus, jobs: usize) {
        let done = self.outcome.complete + self.outcome.failed + self.outcome.interrupted;
        let left = self.total - done;
        let mean = self.seconds.iter().sum::<f64>() / self.seconds.len().max(1) as f64;
        let eta = (left as f64 * mean / jobs as f64).round() as u64;
        let line = format!(
            "sweep: {done}/{} done ({} failed), {} running, about {} left; point {index:04} {} in {:.1} s",
            self.total,
            self.outcome.failed,
            self.running,
            humantime::format_duration(std::time::Duration::from_secs(eta)),
            match status.state {
                PointState::Complete => "complete",
                PointState::Failed => "FAILED",
                _ => "interrupted",
            },
            status.wall_seconds.unwrap_or(0.0),
        );
        if self.tty {
            eprint!("\r\x1b[2K{line}");
        } else {
            eprintln!("{line}");
        }
        let _ = self.start;
    }
}
