//! Parameter studies: sweeps over case values (`docs/studies.md`).
//!
//! A sweep file ([`spec::SweepSpec`]) names a base case, a design
//! ([`design`]) and the keys it varies ([`keys`]); [`sweep::plan`] places
//! the points and checks every point's case before anything runs;
//! [`sweep::prepare`] writes one folder per point and the manifest; the
//! points run in this process ([`local`]) or as a Slurm job array
//! ([`slurm`], [`submit`]); [`collect`] gathers their results. The entry
//! points below are what the command line (`ncform sweep`, `ncform
//! collect`) and any other client call.

pub mod collect;
pub mod design;
pub mod keys;
pub mod local;
pub mod sensitivity;
pub mod slurm;
pub mod spec;
pub mod submit;
pub mod sweep;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::solver::CancelToken;
use sweep::{Manifest, Observed, SweepError, SweepLock, observe, observed_name};

/// How a sweep runs its points.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Points run at once (local). Default: one per core.
    pub jobs: Option<usize>,
    /// Threads of each point's run. Default: the cores shared among the
    /// jobs.
    pub threads: Option<usize>,
    /// Rerun complete points whose inputs or binary changed (else such
    /// points are refused).
    pub rerun_changed: bool,
    /// Leave failed points as they are on a resume (else they are rerun).
    pub skip_failed: bool,
    /// No progress line.
    pub quiet: bool,
    /// Submit to Slurm instead of running here.
    pub slurm: Option<slurm::SlurmOptions>,
    /// Prepare the folder (every point's case checked and written, the
    /// manifest) and run nothing.
    pub prepare_only: bool,
}

/// What a call of [`start`] or [`resume`] did.
#[derive(Debug, Clone, Default)]
pub struct SweepOutcome {
    /// The sweep folder.
    pub dir: PathBuf,
    /// Points in the sweep.
    pub points: usize,
    /// Points complete before this call.
    pub already_complete: usize,
    /// Points run (local) by this call and how they ended.
    pub batch: local::BatchOutcome,
    /// Points submitted to Slurm by this call, and the job ids.
    pub submitted: Vec<(u64, usize)>,
    /// Points left to Slurm tasks still pending or running.
    pub queued: usize,
}

/// The cores of this machine.
pub fn cores() -> usize {
    std::thread::available_parallelism().map_or(1, std::num::NonZero::get)
}

/// The jobs and threads a local sweep uses: by default one job per core,
/// each run on one thread (`docs/studies.md`, "Jobs and threads": more
/// points per hour than sharing the cores within each run).
pub fn jobs_and_threads(options: &RunOptions) -> (usize, usize) {
    let cores = cores();
    let jobs = options.jobs.unwrap_or(cores).max(1);
    let threads = options.threads.unwrap_or((cores / jobs).max(1)).max(1);
    (jobs, threads)
}

/// Plans the sweep file `sweep_file`, prepares its folder `out` (which must
/// not exist, or be empty) and runs or submits every point.
///
/// # Errors
/// The sweep file, a point's case (before anything is written), the
/// folder, or a Slurm command.
pub fn start(
    sweep_file: &Path,
    out: &Path,
    options: &RunOptions,
    cancel: &CancelToken,
) -> Result<SweepOutcome, SweepError> {
    let spec = spec::SweepSpec::load(sweep_file)?;
    let (points, sensitivity) = sweep::plan(&spec)?;
    let manifest = sweep::prepare(&spec, &points, sensitivity, out)?;
    if options.prepare_only {
        return Ok(SweepOutcome {
            dir: out.to_path_buf(),
            points: manifest.points.len(),
            ..SweepOutcome::default()
        });
    }
    go(out, &manifest, options, cancel)
}

/// Resumes the sweep in `dir`: runs (or submits) exactly the points that
/// are not complete and not queued in Slurm; a point killed while running
/// is rerun from scratch.
///
/// # Errors
/// The folder, a point whose inputs changed (without
/// [`RunOptions::rerun_changed`]), or a Slurm command.
pub fn resume(
    dir: &Path,
    options: &RunOptions,
    cancel: &CancelToken,
) -> Result<SweepOutcome, SweepError> {
    let manifest = Manifest::load(dir)?;
    go(dir, &manifest, options, cancel)
}

/// Runs or submits the points of `manifest` that need it.
fn go(
    dir: &Path,
    manifest: &Manifest,
    options: &RunOptions,
    cancel: &CancelToken,
) -> Result<SweepOutcome, SweepError> {
    let _lock = SweepLock::take(dir)?;
    let queued = submit::queued(dir, manifest)?;
    let mut todo = Vec::new();
    let mut changed = Vec::new();
    let mut already_complete = 0;
    for p in &manifest.points {
        if queued.contains(&p.index) {
            continue;
        }
        match observe(dir, manifest, p.index) {
            Observed::Complete => already_complete += 1,
            Observed::Changed(why) => {
                if options.rerun_changed {
                    todo.push(p.index);
                } else {
                    changed.push(format!("point {:04}: {why}", p.index));
                }
            }
            Observed::Failed(_) if options.skip_failed => {}
            _ => todo.push(p.index),
        }
    }
    if !changed.is_empty() {
        return Err(SweepError::Folder {
            path: dir.display().to_string(),
            reason: format!(
                "{} complete point(s) would not be the same today ({}{}); rerun them with --rerun-changed, or start a new sweep",
                changed.len(),
                changed
                    .iter()
                    .take(3)
                    .cloned()
                    .collect::<Vec<_>>()
                    .join("; "),
                if changed.len() > 3 { "; …" } else { "" }
            ),
        });
    }
    let mut outcome = SweepOutcome {
        dir: dir.to_path_buf(),
        points: manifest.points.len(),
        already_complete,
        queued: queued.len(),
        ..SweepOutcome::default()
    };
    if let Some(slurm) = &options.slurm {
        outcome.submitted = submit::submit_points(dir, &todo, slurm)?;
        return Ok(outcome);
    }
    let (jobs, threads) = jobs_and_threads(options);
    outcome.batch = local::run_points(dir, manifest, &todo, jobs, threads, cancel, options.quiet)?;
    Ok(outcome)
}

/// Runs the listed points of the sweep in `dir` one after another on this
/// process's thread pool: what a Slurm array task does
/// (`ncform sweep DIR --points 3,4,5`).
///
/// # Errors
/// The folder, or an index that is not a point of the sweep.
pub fn run_listed(
    dir: &Path,
    points: &[usize],
    cancel: &CancelToken,
) -> Result<local::BatchOutcome, SweepError> {
    let manifest = Manifest::load(dir)?;
    if let Some(&bad) = points.iter().find(|&&i| i >= manifest.points.len()) {
        return Err(SweepError::Folder {
            path: dir.display().to_string(),
            reason: format!(
                "point {bad}: the sweep has points 0 to {}",
                manifest.points.len().saturating_sub(1)
            ),
        });
    }
    let mut outcome = local::BatchOutcome::default();
    for &index in points {
        if cancel.is_cancelled() {
            outcome.interrupted += 1;
            continue;
        }
        let status = local::run_point(dir, &manifest, index, cancel)?;
        match status.state {
            sweep::PointState::Complete => outcome.complete += 1,
            sweep::PointState::Failed => outcome.failed += 1,
            _ => outcome.interrupted += 1,
        }
    }
    Ok(outcome)
}

/// What `ncform sweep DIR --status` prints: the counts of points by
/// state, then every point that is not complete with why.
///
/// # Errors
/// The folder.
pub fn status(dir: &Path) -> Result<String, SweepError> {
    let manifest = Manifest::load(dir)?;
    let queued = submit::queued(dir, &manifest)?;
    let mut counts: std::collections::BTreeMap<&str, usize> = Default::default();
    let mut lines = String::new();
    for p in &manifest.points {
        let observed = observe(dir, &manifest, p.index);
        let name = match (&observed, queued.contains(&p.index)) {
            (Observed::Complete, _) => "complete",
            (_, true) => "queued",
            (o, false) => observed_name(o),
        };
        *counts.entry(name).or_default() += 1;
        if name != "complete" {
            let why = match &observed {
                Observed::Failed(e) | Observed::Changed(e) => format!(": {e}"),
                Observed::Running(Some(job)) if name == "queued" => format!(" (Slurm {job})"),
                Observed::Running(_) if name != "queued" => {
                    ": marked running but not running (killed); --resume reruns it".into()
                }
                _ => String::new(),
            };
            let _ = writeln!(lines, "  {:04} {name}{why}  ({})", p.index, point_values(p));
        }
    }
    let mut out = format!("{}: {} points", manifest.title, manifest.points.len());
    for (name, n) in &counts {
        let _ = write!(out, ", {n} {name}");
    }
    out.push('\n');
    out.push_str(&lines);
    Ok(out)
}

/// `key = value, …` of a manifest point.
fn point_values(p: &sweep::ManifestPoint) -> String {
    p.values
        .iter()
        .map(|(k, v)| format!("{k} = {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}
