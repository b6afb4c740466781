//! A sweep's points as Slurm job arrays: planned into tasks and arrays
//! below the cluster's `MaxArraySize`, written as scripts, submitted, and
//! recorded, so that `--status` and `--resume` ask Slurm only about the
//! job ids this sweep submitted (`docs/studies.md`, "Slurm").

use std::collections::BTreeSet;
use std::path::Path;

use super::slurm::{self, SlurmOptions, TaskState};
use super::sweep::{Manifest, PointState, SweepError, read_status};

/// A Slurm error as a sweep error on the folder `dir`.
fn slurm_err(dir: &Path, e: impl std::fmt::Display) -> SweepError {
    SweepError::Folder {
        path: dir.display().to_string(),
        reason: format!("Slurm: {e}"),
    }
}

/// The points of the sweep in `dir` that a Slurm task this sweep
/// submitted still has pending or running (none when nothing was
/// submitted: no Slurm command is run then).
///
/// # Errors
/// A Slurm query that fails.
pub fn queued(dir: &Path, manifest: &Manifest) -> Result<BTreeSet<usize>, SweepError> {
    let submissions = slurm::load_submissions(dir).map_err(|e| slurm_err(dir, e))?;
    if submissions.is_empty() {
        return Ok(BTreeSet::new());
    }
    let states = slurm::point_states(dir).map_err(|e| slurm_err(dir, e))?;
    Ok(states
        .into_iter()
        .filter(|(index, state)| {
            matches!(state, TaskState::Pending | TaskState::Running)
                && *index < manifest.points.len()
                && read_status(&manifest.point_dir(dir, *index))
                    .is_none_or(|s| !matches!(s.state, PointState::Complete | PointState::Failed))
        })
        .map(|(index, _)| index)
        .collect())
}

/// Submits the points `todo` of the sweep in `dir` as job arrays (packed
/// `points_per_task` to a task, split below `MaxArraySize`), records each
/// submission ([`slurm::submit_points`]), and returns the job ids with
/// their point counts.
///
/// # Errors
/// A script that cannot be written, or `sbatch` failing.
pub fn submit_points(
    dir: &Path,
    todo: &[usize],
    options: &SlurmOptions,
) -> Result<Vec<(u64, usize)>, SweepError> {
    if todo.is_empty() {
        return Ok(Vec::new());
    }
    let exe = std::env::current_exe()
        .map_err(|e| slurm_err(dir, format!("cannot find the ncform binary: {e}")))?;
    let submitted =
        slurm::submit_points(dir, todo, options, &exe).map_err(|e| slurm_err(dir, e))?;
    Ok(submitted
        .iter()
        .map(|s| (s.job_id, s.tasks.iter().map(Vec::len).sum()))
        .collect())
}
