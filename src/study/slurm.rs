//! Slurm backend of `ncform sweep --slurm`: the points of a sweep run as
//! Slurm job arrays.
//!
//! Points are grouped into tasks (`points_per_task` each) and the tasks into
//! arrays of at most `MaxArraySize` tasks ([`plan`]). Each array gets a batch
//! script `DIR/slurm/array-<k>.sh` and a tasks file `DIR/slurm/array-<k>.tasks`
//! ([`write_array_script`]); task `t` reads line `t + 1` of the tasks file and
//! runs `ncform sweep DIR --points <its points>` in the allocation. Every
//! `sbatch` ([`submit`]) is recorded in `DIR/slurm/submissions.json`
//! ([`record_submission`]); [`point_states`] asks `squeue` (and `sacct` for
//! the tasks `squeue` no longer lists) what became of each recorded point.
//!
//! A point's `status.json` (written by the `--points` runner) is the truth
//! for complete/failed; Slurm's state only tells pending/running/killed.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt::Write as _;
use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde::{Deserialize, Serialize};

/// `MaxArraySize` of Slurm when `scontrol show config` does not name it.
pub const DEFAULT_MAX_ARRAY_SIZE: usize = 1001;

/// Errors of the Slurm backend: a command that could not run or failed, an
/// output that could not be read, or a file of the sweep folder.
#[derive(Debug, thiserror::Error)]
pub enum SlurmError {
    /// A Slurm command could not be started (not installed, not on `PATH`).
    #[error("could not run `{command}`: {source} (is Slurm installed and on PATH?)")]
    Spawn {
        /// The command line.
        command: String,
        /// Why it could not start.
        source: io::Error,
    },
    /// A Slurm command exited with a non-zero code.
    #[error("`{command}` exited with {code}: {stderr}")]
    Failed {
        /// The command line.
        command: String,
        /// Its exit code (`signal` when killed by one).
        code: String,
        /// Its standard error, trimmed.
        stderr: String,
    },
    /// A Slurm command's output is not what the backend expects.
    #[error("could not read the output of `{command}`: {output:?}")]
    Parse {
        /// The command line.
        command: String,
        /// The output in question.
        output: String,
    },
    /// Reading or writing a file of the sweep folder failed.
    #[error("{path}: {source}")]
    Io {
        /// The file or folder.
        path: PathBuf,
        /// The error.
        source: io::Error,
    },
    /// `DIR/slurm/submissions.json` is not a valid record.
    #[error("{path}: {source}")]
    Json {
        /// The file.
        path: PathBuf,
        /// The error.
        source: serde_json::Error,
    },
}

/// The Slurm options of `ncform sweep --slurm`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SlurmOptions {
    /// `--partition` of the jobs (the cluster's default when `None`).
    pub partition: Option<String>,
    /// `--time` limit of each array task (the partition's default when `None`).
    pub time: Option<String>,
    /// At most this many tasks of one array run at once (`--array=...%M`).
    pub max_parallel: Option<usize>,
    /// Points run one after another in one array task (at least 1).
    pub points_per_task: usize,
    /// `--cpus-per-task`; the task's `RAYON_NUM_THREADS` (at least 1).
    pub cpus_per_task: usize,
    /// Further `sbatch` options, each written as its own `#SBATCH` line.
    pub extra_args: Vec<String>,
}

impl Default for SlurmOptions {
    fn default() -> Self {
        SlurmOptions {
            partition: None,
            time: None,
            max_parallel: None,
            points_per_task: 1,
            cpus_per_task: 1,
            extra_args: Vec::new(),
        }
    }
}

/// Points grouped into tasks (`points_per_task` each, the last one shorter),
/// tasks split into arrays of at most `max_array_size` tasks.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayPlan {
    /// The arrays, each submitted as one job.
    pub arrays: Vec<PlannedArray>,
}

/// One job array of a plan.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PlannedArray {
    /// Task `t` of this array (array index `t`) runs these point indices.
    pub tasks: Vec<Vec<usize>>,
}

/// Groups `points` into tasks of `points_per_task` points (in the given
/// order, the last task shorter) and the tasks into arrays of at most
/// `max_array_size` tasks, so that every array index is below
/// `max_array_size`. Zero for either size counts as 1.
pub fn plan(points: &[usize], points_per_task: usize, max_array_size: usize) -> ArrayPlan {
    let tasks: Vec<Vec<usize>> = points
        .chunks(points_per_task.max(1))
        .map(<[usize]>::to_vec)
        .collect();
    let arrays = tasks
        .chunks(max_array_size.max(1))
        .map(|chunk| PlannedArray {
            tasks: chunk.to_vec(),
        })
        .collect();
    ArrayPlan { arrays }
}

/// `MaxArraySize` from `scontrol show config` ([`DEFAULT_MAX_ARRAY_SIZE`]
/// when scontrol does not say); array indices must be below it.
pub fn max_array_size() -> Result<usize, SlurmError> {
    let out = run(Command::new("scontrol").args(["show", "config"]))?;
    Ok(parse_max_array_size(&out).unwrap_or(DEFAULT_MAX_ARRAY_SIZE))
}

/// The `MaxArraySize = N` line of `scontrol show config`, if any.
pub fn parse_max_array_size(config: &str) -> Option<usize> {
    config.lines().find_map(|line| {
        let (key, value) = line.split_once('=')?;
        if key.trim() == "MaxArraySize" {
            value.trim().parse().ok()
        } else {
            None
        }
    })
}

/// The folder of the Slurm files of sweep folder `dir`: `DIR/slurm`.
pub fn slurm_dir(dir: &Path) -> PathBuf {
    dir.join("slurm")
}

/// Writes `DIR/slurm/array-<k>.sh` and `DIR/slurm/array-<k>.tasks` (line
/// `t + 1` holds the comma-separated point indices of task `t`) and returns
/// the script's path. The script runs
/// `ncform sweep DIR --points <line>` with the absolute paths of `ncform`
/// and `dir`, `RAYON_NUM_THREADS` from `SLURM_CPUS_PER_TASK`, and writes its
/// output to `DIR/slurm/array-<k>_<jobid>_<task>.out`.
pub fn write_array_script(
    dir: &Path,
    k: usize,
    array: &PlannedArray,
    opts: &SlurmOptions,
    ncform: &Path,
) -> Result<PathBuf, SlurmError> {
    let dir = absolute(dir)?;
    let ncform = absolute(ncform)?;
    let sdir = slurm_dir(&dir);
    fs::create_dir_all(&sdir).map_err(|source| SlurmError::Io {
        path: sdir.clone(),
        source,
    })?;
    let tasks_path = sdir.join(format!("array-{k}.tasks"));
    let script_path = sdir.join(format!("array-{k}.sh"));
    write_file(&tasks_path, &tasks_text(array))?;
    let text = script_text(&dir, k, array.tasks.len(), opts, &ncform, &tasks_path);
    write_file(&script_path, &text)?;
    Ok(script_path)
}

/// The tasks file of an array: one line per task, its points comma-separated.
pub fn tasks_text(array: &PlannedArray) -> String {
    let mut s = String::new();
    for task in &array.tasks {
        let line: Vec<String> = task.iter().map(usize::to_string).collect();
        s.push_str(&line.join(","));
        s.push('\n');
    }
    s
}

/// The batch script of array `k` with `n_tasks` tasks (see
/// [`write_array_script`]); `dir`, `ncform` and `tasks` should be absolute.
pub fn script_text(
    dir: &Path,
    k: usize,
    n_tasks: usize,
    opts: &SlurmOptions,
    ncform: &Path,
    tasks: &Path,
) -> String {
    let mut s = String::from("#!/bin/bash\n");
    let sbatch = |s: &mut String, option: &str| {
        let _ = writeln!(s, "#SBATCH {}", sbatch_quote(option));
    };
    sbatch(&mut s, "--job-name=ncform-sweep");
    let mut array = format!("--array=0-{}", n_tasks.saturating_sub(1));
    if let Some(m) = opts.max_parallel {
        let _ = write!(array, "%{}", m.max(1));
    }
    sbatch(&mut s, &array);
    sbatch(
        &mut s,
        &format!("--cpus-per-task={}", opts.cpus_per_task.max(1)),
    );
    let output = slurm_dir(dir).join(format!("array-{k}_%A_%a.out"));
    sbatch(&mut s, &format!("--output={}", output.display()));
    if let Some(p) = &opts.partition {
        sbatch(&mut s, &format!("--partition={p}"));
    }
    if let Some(t) = &opts.time {
        sbatch(&mut s, &format!("--time={t}"));
    }
    for arg in &opts.extra_args {
        sbatch(&mut s, arg);
    }
    s.push_str("set -euo pipefail\n");
    s.push_str("export RAYON_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-1}\"\n");
    let _ = writeln!(
        s,
        "points=$(sed -n \"$((SLURM_ARRAY_TASK_ID+1))p\" {})",
        shell_quote(&tasks.display().to_string())
    );
    let _ = writeln!(
        s,
        "exec {} sweep {} --points \"$points\"",
        shell_quote(&ncform.display().to_string()),
        shell_quote(&dir.display().to_string())
    );
    s
}

/// Runs `sbatch --parsable SCRIPT` and returns the job id; prints sbatch's
/// usual `Submitted batch job N` line (and any warnings of sbatch) to
/// standard error.
pub fn submit(script: &Path) -> Result<u64, SlurmError> {
    let mut cmd = Command::new("sbatch");
    cmd.arg("--parsable").arg(script);
    let command = describe(&cmd);
    let output = cmd.output().map_err(|source| SlurmError::Spawn {
        command: command.clone(),
        source,
    })?;
    let stderr = String::from_utf8_lossy(&output.stderr).trim().to_string();
    if !output.status.success() {
        return Err(failed(command, &output.status, stderr));
    }
    if !stderr.is_empty() {
        eprintln!("{stderr}");
    }
    let stdout = String::from_utf8_lossy(&output.stdout);
    let id = parse_job_id(&stdout).ok_or_else(|| SlurmError::Parse {
        command,
        output: stdout.to_string(),
    })?;
    eprintln!("Submitted batch job {id}");
    Ok(id)
}

/// The job id of `sbatch --parsable`'s output: `1234` or `1234;cluster`.
pub fn parse_job_id(stdout: &str) -> Option<u64> {
    let line = stdout.lines().map(str::trim).find(|l| !l.is_empty())?;
    line.split(';').next()?.trim().parse().ok()
}

/// A record of one submitted array, kept in `DIR/slurm/submissions.json`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Submission {
    /// Slurm's job id of the array.
    pub job_id: u64,
    /// `k` of `DIR/slurm/array-<k>.sh`.
    pub array: usize,
    /// Task `t` (array index `t`) ran these point indices.
    pub tasks: Vec<Vec<usize>>,
    /// When it was submitted, RFC 3339 UTC.
    pub submitted: String,
}

/// The path of the submission record of sweep folder `dir`.
pub fn submissions_path(dir: &Path) -> PathBuf {
    slurm_dir(dir).join("submissions.json")
}

/// The recorded submissions of sweep folder `dir`, oldest first (none when
/// the record does not exist).
pub fn load_submissions(dir: &Path) -> Result<Vec<Submission>, SlurmError> {
    let path = submissions_path(dir);
    match fs::read_to_string(&path) {
        Ok(text) => serde_json::from_str(&text).map_err(|source| SlurmError::Json { path, source }),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(Vec::new()),
        Err(source) => Err(SlurmError::Io { path, source }),
    }
}

/// Appends `s` to `DIR/slurm/submissions.json`, written atomically (a
/// temporary file beside it, then renamed over it).
pub fn record_submission(dir: &Path, s: &Submission) -> Result<(), SlurmError> {
    let mut all = load_submissions(dir)?;
    all.push(s.clone());
    let path = submissions_path(dir);
    let sdir = slurm_dir(dir);
    fs::create_dir_all(&sdir).map_err(|source| SlurmError::Io {
        path: sdir.clone(),
        source,
    })?;
    let mut text = serde_json::to_string_pretty(&all).map_err(|source| SlurmError::Json {
        path: path.clone(),
        source,
    })?;
    text.push('\n');
    let tmp = sdir.join(format!("submissions.json.tmp-{}", std::process::id()));
    write_file(&tmp, &text)?;
    fs::rename(&tmp, &path).map_err(|source| SlurmError::Io { path, source })
}

/// Plans, writes and submits `points` of sweep folder `dir` as job arrays
/// and records each submission: [`max_array_size`], [`plan`], then per array
/// [`write_array_script`], [`submit`] and [`record_submission`]. The arrays
/// are numbered on from the highest recorded one, so a resubmission never
/// overwrites the scripts of an earlier one. Returns the new submissions.
pub fn submit_points(
    dir: &Path,
    points: &[usize],
    opts: &SlurmOptions,
    ncform: &Path,
) -> Result<Vec<Submission>, SlurmError> {
    if points.is_empty() {
        return Ok(Vec::new());
    }
    let max = max_array_size()?;
    let first = load_submissions(dir)?
        .iter()
        .map(|s| s.array + 1)
        .max()
        .unwrap_or(0);
    let mut done = Vec::new();
    for (i, array) in plan(points, opts.points_per_task, max)
        .arrays
        .into_iter()
        .enumerate()
    {
        let k = first + i;
        let script = write_array_script(dir, k, &array, opts, ncform)?;
        let job_id = submit(&script)?;
        let s = Submission {
            job_id,
            array: k,
            tasks: array.tasks,
            submitted: crate::report::folder::now(),
        };
        record_submission(dir, &s)?;
        done.push(s);
    }
    Ok(done)
}

/// What Slurm says of one array task (and so of each of its points).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TaskState {
    /// Waiting in the queue (also requeued or held).
    Pending,
    /// Holding an allocation: running, configuring, completing, suspended.
    Running,
    /// Ended with exit code 0.
    Completed,
    /// Ended otherwise: the Slurm state (FAILED, OUT_OF_MEMORY, NODE_FAIL,
    /// PREEMPTED, BOOT_FAIL, DEADLINE, ...).
    Failed(String),
    /// Cancelled (`scancel`).
    Cancelled,
    /// Killed at its time limit.
    Timeout,
    /// Slurm no longer knows the task: not in `squeue`, and `sacct` does not
    /// list it (or there is no accounting storage). Not running.
    Unknown,
}

impl TaskState {
    /// Pending or running: the point must not be submitted again.
    pub fn is_active(&self) -> bool {
        matches!(self, TaskState::Pending | TaskState::Running)
    }

    /// The state of a Slurm state name (`%T` of squeue, `State` of sacct,
    /// e.g. `CANCELLED by 0`).
    pub fn from_slurm(state: &str) -> TaskState {
        let word = state.split_whitespace().next().unwrap_or("");
        let word = word.trim_end_matches('+');
        match word {
            "PENDING" | "REQUEUED" | "REQUEUE_FED" | "REQUEUE_HOLD" | "RESV_DEL_HOLD" => {
                TaskState::Pending
            }
            "RUNNING" | "CONFIGURING" | "COMPLETING" | "SUSPENDED" | "RESIZING" | "SIGNALING"
            | "STAGE_OUT" | "STOPPED" => TaskState::Running,
            "COMPLETED" => TaskState::Completed,
            "CANCELLED" => TaskState::Cancelled,
            "TIMEOUT" => TaskState::Timeout,
            "FAILED" | "OUT_OF_MEMORY" | "NODE_FAIL" | "PREEMPTED" | "BOOT_FAIL" | "DEADLINE"
            | "SPECIAL_EXIT" => TaskState::Failed(word.to_string()),
            _ => TaskState::Unknown,
        }
    }
}

impl std::fmt::Display for TaskState {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            TaskState::Pending => f.write_str("pending"),
            TaskState::Running => f.write_str("running"),
            TaskState::Completed => f.write_str("completed"),
            TaskState::Failed(s) => write!(f, "failed ({})", s.to_lowercase()),
            TaskState::Cancelled => f.write_str("cancelled"),
            TaskState::Timeout => f.write_str("timeout"),
            TaskState::Unknown => f.write_str("unknown"),
        }
    }
}

/// One array task: (job id of the array, array index).
pub type TaskId = (u64, usize);

/// The array tasks and their states in `squeue -h -r -o "%i %T"` output
/// (lines `JOBID_TASK STATE`). Lines of jobs that are no arrays are skipped;
/// unexpanded ranges (`JOBID_[3-7%2]`) are expanded.
pub fn parse_squeue(output: &str) -> BTreeMap<TaskId, TaskState> {
    let mut map = BTreeMap::new();
    for line in output.lines() {
        let mut parts = line.split_whitespace();
        let (Some(id), Some(state)) = (parts.next(), parts.next()) else {
            continue;
        };
        let state = TaskState::from_slurm(state);
        for task in expand_task_id(id) {
            map.insert(task, state.clone());
        }
    }
    map
}

/// The array tasks and their states in `sacct -n -X -P -o JobID,State`
/// output (lines `JOBID_TASK|STATE`, e.g. `12_3|CANCELLED by 0`, and for
/// tasks not yet started `12_[4-9]|PENDING`).
pub fn parse_sacct(output: &str) -> BTreeMap<TaskId, TaskState> {
    let mut map = BTreeMap::new();
    for line in output.lines() {
        let Some((id, state)) = line.trim().split_once('|') else {
            continue;
        };
        let state = TaskState::from_slurm(state.trim());
        for task in expand_task_id(id.trim()) {
            map.insert(task, state.clone());
        }
    }
    map
}

/// The tasks named by a Slurm job id `J_T` or `J_[a-b,c%M]`; none for a
/// job that is no array or an id that cannot be read.
pub fn expand_task_id(id: &str) -> Vec<TaskId> {
    let Some((job, task)) = id.split_once('_') else {
        return Vec::new();
    };
    let Ok(job) = job.parse::<u64>() else {
        return Vec::new();
    };
    if let Ok(t) = task.parse::<usize>() {
        return vec![(job, t)];
    }
    let Some(inner) = task.strip_prefix('[').and_then(|s| s.strip_suffix(']')) else {
        return Vec::new();
    };
    let inner = inner.split('%').next().unwrap_or("");
    let mut tasks = Vec::new();
    for part in inner.split(',') {
        let range = part.split(':').next().unwrap_or(""); // a step `a-b:s` is not written by us
        match range.split_once('-') {
            Some((a, b)) => {
                if let (Ok(a), Ok(b)) = (a.parse::<usize>(), b.parse::<usize>()) {
                    tasks.extend((a..=b).map(|t| (job, t)));
                }
            }
            None => {
                if let Ok(t) = range.parse::<usize>() {
                    tasks.push((job, t));
                }
            }
        }
    }
    tasks
}

/// The latest recorded task of each point: later submissions win, so a
/// resubmitted point is judged by its resubmission.
pub fn latest_tasks(subs: &[Submission]) -> BTreeMap<usize, TaskId> {
    let mut map = BTreeMap::new();
    for s in subs {
        for (t, points) in s.tasks.iter().enumerate() {
            for &p in points {
                map.insert(p, (s.job_id, t));
            }
        }
    }
    map
}

/// The state of each point from its latest task: `squeue` first, then
/// `sacct`, else [`TaskState::Unknown`].
pub fn combine_states(
    latest: &BTreeMap<usize, TaskId>,
    squeue: &BTreeMap<TaskId, TaskState>,
    sacct: &BTreeMap<TaskId, TaskState>,
) -> BTreeMap<usize, TaskState> {
    latest
        .iter()
        .map(|(&p, task)| {
            let state = squeue
                .get(task)
                .or_else(|| sacct.get(task))
                .cloned()
                .unwrap_or(TaskState::Unknown);
            (p, state)
        })
        .collect()
}

/// The Slurm state of each point of sweep folder `dir` that has a recorded
/// submission (its latest one): one `squeue -h -r -j IDS -o "%i %T"` call,
/// then at most one `sacct -n -X -P -j IDS -o JobID,State` call for the jobs
/// of the tasks squeue no longer lists.
///
/// Without accounting storage (no slurmdbd) `sacct` fails; its error is
/// then ignored and every task that squeue does not list is
/// [`TaskState::Unknown`]: not pending or running. The point's `status.json`
/// then tells whether it completed; a point neither complete nor active
/// is to be run again.
pub fn point_states(dir: &Path) -> Result<BTreeMap<usize, TaskState>, SlurmError> {
    let subs = load_submissions(dir)?;
    let latest = latest_tasks(&subs);
    if latest.is_empty() {
        return Ok(BTreeMap::new());
    }
    let jobs: BTreeSet<u64> = latest.values().map(|&(j, _)| j).collect();
    let squeue = parse_squeue(&squeue_output(&jobs)?);
    let missing: BTreeSet<u64> = latest
        .values()
        .filter(|t| !squeue.contains_key(t))
        .map(|&(j, _)| j)
        .collect();
    let sacct = if missing.is_empty() {
        BTreeMap::new()
    } else {
        let mut cmd = Command::new("sacct");
        cmd.args([
            "-n",
            "-X",
            "-P",
            "-j",
            &join_ids(&missing),
            "-o",
            "JobID,State",
        ]);
        // No accounting storage: sacct fails; fall back to "not running".
        run(&mut cmd).map(|o| parse_sacct(&o)).unwrap_or_default()
    };
    Ok(combine_states(&latest, &squeue, &sacct))
}

/// The points of `points` to submit again on `--resume`: neither in
/// `complete` (their `status.json` says complete) nor pending or running
/// in `states` (from [`point_states`]). Points without a recorded
/// submission count as not running.
pub fn points_to_resubmit(
    points: &[usize],
    complete: &BTreeSet<usize>,
    states: &BTreeMap<usize, TaskState>,
) -> Vec<usize> {
    points
        .iter()
        .copied()
        .filter(|p| !complete.contains(p) && !states.get(p).is_some_and(TaskState::is_active))
        .collect()
}

/// `squeue -h -r -j IDS -o "%i %T"`; an empty listing when squeue says the
/// job ids are invalid (all of them have left its memory).
fn squeue_output(jobs: &BTreeSet<u64>) -> Result<String, SlurmError> {
    let mut cmd = Command::new("squeue");
    cmd.args(["-h", "-r", "-j", &join_ids(jobs), "-o", "%i %T"]);
    match run(&mut cmd) {
        Ok(out) => Ok(out),
        Err(SlurmError::Failed { stderr, .. }) if stderr.contains("Invalid job id") => {
            Ok(String::new())
        }
        Err(e) => Err(e),
    }
}

fn join_ids(ids: &BTreeSet<u64>) -> String {
    ids.iter().map(u64::to_string).collect::<Vec<_>>().join(",")
}

/// Runs a command; its standard output, or a typed error naming it.
fn run(cmd: &mut Command) -> Result<String, SlurmError> {
    let command = describe(cmd);
    let output = cmd.output().map_err(|source| SlurmError::Spawn {
        command: command.clone(),
        source,
    })?;
    if !output.status.success() {
        let stderr = String::from_utf8_lossy(&output.stderr).trim().to_string();
        return Err(failed(command, &output.status, stderr));
    }
    Ok(String::from_utf8_lossy(&output.stdout).into_owned())
}

fn failed(command: String, status: &std::process::ExitStatus, stderr: String) -> SlurmError {
    let code = status
        .code()
        .map_or_else(|| "a signal".to_string(), |c| format!("exit code {c}"));
    SlurmError::Failed {
        command,
        code,
        stderr,
    }
}

fn describe(cmd: &Command) -> String {
    let mut s = cmd.get_program().to_string_lossy().into_owned();
    for a in cmd.get_args() {
        s.push(' ');
        s.push_str(&shell_quote(&a.to_string_lossy()));
    }
    s
}

fn absolute(path: &Path) -> Result<PathBuf, SlurmError> {
    std::path::absolute(path).map_err(|source| SlurmError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn write_file(path: &Path, text: &str) -> Result<(), SlurmError> {
    fs::write(path, text).map_err(|source| SlurmError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// `s` as one word of bash: as is when plain, else in single quotes.
fn shell_quote(s: &str) -> String {
    let plain = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+=:,%@".contains(c));
    if plain {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', r"'\''"))
    }
}

/// An `#SBATCH` option in double quotes when it holds white space (sbatch
/// reads those quotes itself).
fn sbatch_quote(s: &str) -> String {
    if s.chars().any(char::is_whitespace) {
        format!("\"{}\"", s.replace('"', "\\\""))
    } else {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Submits a fake `ncform` (a script that records its arguments) as a
    /// job array to a running cluster (`SLURM_CONF`), then asks
    /// [`point_states`] until no task is active.
    #[test]
    #[ignore = "needs a running Slurm cluster: SLURM_CONF of verification/slurm.sh"]
    fn live_cluster_submit_and_states() {
        use std::os::unix::fs::PermissionsExt;
        let tmp = tempfile::tempdir().unwrap();
        let fake = tmp.path().join("fake-ncform");
        fs::write(
            &fake,
            "#!/bin/bash\necho \"$RAYON_NUM_THREADS $*\" > \"$2/ran-$SLURM_ARRAY_TASK_ID\"\n",
        )
        .unwrap();
        fs::set_permissions(&fake, fs::Permissions::from_mode(0o755)).unwrap();
        let opts = SlurmOptions {
            points_per_task: 2,
            max_parallel: Some(1),
            ..SlurmOptions::default()
        };
        let subs = submit_points(tmp.path(), &[0, 1, 2, 3, 4], &opts, &fake).unwrap();
        assert_eq!(subs.len(), 1);
        assert_eq!(subs[0].tasks, vec![vec![0, 1], vec![2, 3], vec![4]]);
        assert_eq!(load_submissions(tmp.path()).unwrap(), subs);
        let first = point_states(tmp.path()).unwrap();
        assert_eq!(first.len(), 5);
        eprintln!("right after sbatch: {first:?}");
        let t0 = std::time::Instant::now();
        let last = loop {
            let s = point_states(tmp.path()).unwrap();
            if !s.values().any(TaskState::is_active) {
                break s;
            }
            assert!(t0.elapsed().as_secs() < 120, "still active: {s:?}");
            std::thread::sleep(std::time::Duration::from_millis(500));
        };
        eprintln!("after {:?}: {last:?}", t0.elapsed());
        let dir = std::path::absolute(tmp.path()).unwrap();
        for (t, points) in ["0,1", "2,3", "4"].iter().enumerate() {
            let ran = fs::read_to_string(tmp.path().join(format!("ran-{t}"))).unwrap();
            assert_eq!(
                ran.trim(),
                format!("1 sweep {} --points {points}", dir.display())
            );
        }
    }

    #[test]
    fn plan_splits_into_tasks_and_arrays() {
        let points: Vec<usize> = (0..2500).collect();
        let p = plan(&points, 3, 1001);
        // 2500 points / 3 = 834 tasks (the last with 1 point): one array.
        assert_eq!(p.arrays.len(), 1);
        assert_eq!(p.arrays[0].tasks.len(), 834);
        assert_eq!(p.arrays[0].tasks[0], vec![0, 1, 2]);
        assert_eq!(p.arrays[0].tasks[833], vec![2499]);

        let p = plan(&points, 1, 1001);
        let sizes: Vec<usize> = p.arrays.iter().map(|a| a.tasks.len()).collect();
        assert_eq!(sizes, vec![1001, 1001, 498]);
        assert!(sizes.iter().all(|&n| n <= 1001));
        assert_eq!(p.arrays[1].tasks[0], vec![1001]);
        assert_eq!(p.arrays[2].tasks[497], vec![2499]);
        // Every point exactly once, in order.
        let all: Vec<usize> = p
            .arrays
            .iter()
            .flat_map(|a| a.tasks.iter().flatten().copied())
            .collect();
        assert_eq!(all, points);

        let p = plan(&points, 3, 100);
        assert_eq!(p.arrays.len(), 9);
        assert!(p.arrays.iter().all(|a| a.tasks.len() <= 100));
        assert_eq!(p.arrays[8].tasks.len(), 34);

        let p = plan(&[7, 3, 9], 2, 1);
        assert_eq!(
            p.arrays,
            vec![
                PlannedArray {
                    tasks: vec![vec![7, 3]]
                },
                PlannedArray {
                    tasks: vec![vec![9]]
                }
            ]
        );
        assert!(plan(&[], 3, 1001).arrays.is_empty());
        assert_eq!(plan(&[1, 2], 0, 0).arrays.len(), 2);
    }

    #[test]
    fn max_array_size_from_scontrol() {
        let config = "Configuration data as of 2026-12-06T22:00:00\n\
                      MailType                = (null)\n\
                      MaxArraySize            = 40001\n\
                      MaxJobCount             = 10000\n";
        assert_eq!(parse_max_array_size(config), Some(40001));
        assert_eq!(parse_max_array_size("MaxJobCount = 10\n"), None);
    }

    #[test]
    fn script_text_has_options_and_body() {
        let opts = SlurmOptions {
            partition: Some("debug".into()),
            time: Some("00:30:00".into()),
            max_parallel: Some(4),
            points_per_task: 2,
            cpus_per_task: 8,
            extra_args: vec!["--mem=4G".into(), "--account=fem lab".into()],
        };
        let dir = Path::new("/data/sweep");
        let s = script_text(
            dir,
            2,
            5,
            &opts,
            Path::new("/opt/bin/ncform"),
            &dir.join("slurm/array-2.tasks"),
        );
        let lines: Vec<&str> = s.lines().collect();
        assert_eq!(lines[0], "#!/bin/bash");
        for want in [
            "#SBATCH --job-name=ncform-sweep",
            "#SBATCH --array=0-4%4",
            "#SBATCH --cpus-per-task=8",
            "#SBATCH --output=/data/sweep/slurm/array-2_%A_%a.out",
            "#SBATCH --partition=debug",
            "#SBATCH --time=00:30:00",
            "#SBATCH --mem=4G",
            "#SBATCH \"--account=fem lab\"",
            "export RAYON_NUM_THREADS=\"${SLURM_CPUS_PER_TASK:-1}\"",
            "points=$(sed -n \"$((SLURM_ARRAY_TASK_ID+1))p\" /data/sweep/slurm/array-2.tasks)",
            "exec /opt/bin/ncform sweep /data/sweep --points \"$points\"",
        ] {
            assert!(lines.contains(&want), "missing {want:?} in\n{s}");
        }
        // All #SBATCH lines come before the first command.
        let last_sbatch = lines
            .iter()
            .rposition(|l| l.starts_with("#SBATCH"))
            .unwrap();
        let first_cmd = lines.iter().position(|l| l.starts_with("set ")).unwrap();
        assert!(last_sbatch < first_cmd);

        let s = script_text(
            Path::new("/my sweep"),
            0,
            1,
            &SlurmOptions::default(),
            Path::new("/opt/it's/ncform"),
            Path::new("/my sweep/slurm/array-0.tasks"),
        );
        assert!(s.contains("#SBATCH --array=0-0\n"));
        assert!(s.contains("#SBATCH --cpus-per-task=1\n"));
        assert!(!s.contains("--partition") && !s.contains("--time"));
        assert!(s.contains("#SBATCH \"--output=/my sweep/slurm/array-0_%A_%a.out\"\n"));
        assert!(s.contains("exec '/opt/it'\\''s/ncform' sweep '/my sweep' --points \"$points\"\n"));
    }

    #[test]
    fn write_array_script_writes_script_and_tasks() {
        let tmp = tempfile::tempdir().unwrap();
        let array = PlannedArray {
            tasks: vec![vec![0, 1], vec![2]],
        };
        let script = write_array_script(
            tmp.path(),
            3,
            &array,
            &SlurmOptions::default(),
            Path::new("/usr/bin/ncform"),
        )
        .unwrap();
        assert_eq!(script, tmp.path().join("slurm/array-3.sh"));
        let tasks = fs::read_to_string(tmp.path().join("slurm/array-3.tasks")).unwrap();
        assert_eq!(tasks, "0,1\n2\n");
        let text = fs::read_to_string(&script).unwrap();
        assert!(text.contains("#SBATCH --array=0-1\n"));
    }

    #[test]
    fn job_id_of_sbatch_parsable() {
        assert_eq!(parse_job_id("1234\n"), Some(1234));
        assert_eq!(parse_job_id("1234;cluster\n"), Some(1234));
        assert_eq!(parse_job_id("\n 77 \n"), Some(77));
        assert_eq!(parse_job_id("Submitted batch job 5\n"), None);
        assert_eq!(parse_job_id(""), None);
    }

    #[test]
    fn submissions_append_atomically() {
        let tmp = tempfile::tempdir().unwrap();
        assert!(load_submissions(tmp.path()).unwrap().is_empty());
        let a = Submission {
            job_id: 11,
            array: 0,
            tasks: vec![vec![0], vec![1]],
            submitted: crate::report::folder::now(),
        };
        let b = Submission {
            job_id: 12,
            array: 1,
            tasks: vec![vec![1]],
            submitted: "2026-12-06T22:00:00Z".into(),
        };
        record_submission(tmp.path(), &a).unwrap();
        record_submission(tmp.path(), &b).unwrap();
        assert_eq!(load_submissions(tmp.path()).unwrap(), vec![a.clone(), b]);
        assert!(a.submitted.ends_with('Z') && a.submitted.contains('T'));
        let names: Vec<String> = fs::read_dir(tmp.path().join("slurm"))
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(names, vec!["submissions.json".to_string()]);
        fs::write(submissions_path(tmp.path()), "not json").unwrap();
        assert!(matches!(
            load_submissions(tmp.path()),
            Err(SlurmError::Json { .. })
        ));
    }

    #[test]
    fn squeue_output_parsed() {
        let out = "41_0 RUNNING\n41_1 PENDING\n41_2 COMPLETING\n42_[3-5%2] PENDING\n43 RUNNING\n\n";
        let m = parse_squeue(out);
        assert_eq!(m[&(41, 0)], TaskState::Running);
        assert_eq!(m[&(41, 1)], TaskState::Pending);
        assert_eq!(m[&(41, 2)], TaskState::Running);
        assert_eq!(m[&(42, 3)], TaskState::Pending);
        assert_eq!(m[&(42, 5)], TaskState::Pending);
        assert_eq!(m.len(), 6);
    }

    #[test]
    fn sacct_output_parsed() {
        let out = "50_0|COMPLETED\n50_1|CANCELLED by 0\n50_2|TIMEOUT\n50_3|FAILED\n\
                   50_4|OUT_OF_MEMORY\n50_[5-6,8]|PENDING\n50_7|NODE_FAIL\n51|COMPLETED\n";
        let m = parse_sacct(out);
        assert_eq!(m[&(50, 0)], TaskState::Completed);
        assert_eq!(m[&(50, 1)], TaskState::Cancelled);
        assert_eq!(m[&(50, 2)], TaskState::Timeout);
        assert_eq!(m[&(50, 3)], TaskState::Failed("FAILED".into()));
        assert_eq!(m[&(50, 4)], TaskState::Failed("OUT_OF_MEMORY".into()));
        assert_eq!(m[&(50, 5)], TaskState::Pending);
        assert_eq!(m[&(50, 6)], TaskState::Pending);
        assert_eq!(m[&(50, 8)], TaskState::Pending);
        assert_eq!(m[&(50, 7)], TaskState::Failed("NODE_FAIL".into()));
        assert_eq!(m.len(), 9);
        assert_eq!(TaskState::from_slurm("BOGUS"), TaskState::Unknown);
        assert!(TaskState::Pending.is_active() && !TaskState::Cancelled.is_active());
    }

    #[test]
    fn resubmit_neither_complete_nor_active() {
        let complete: BTreeSet<usize> = [0, 4].into();
        let states: BTreeMap<usize, TaskState> = [
            (0, TaskState::Completed),
            (1, TaskState::Running),
            (2, TaskState::Cancelled),
            (3, TaskState::Pending),
            (4, TaskState::Unknown),
            (5, TaskState::Unknown),
            (6, TaskState::Completed), // Slurm done, but status.json not complete
        ]
        .into();
        assert_eq!(
            points_to_resubmit(&[0, 1, 2, 3, 4, 5, 6, 7], &complete, &states),
            vec![2, 5, 6, 7]
        );
    }

    #[test]
    fn point_states_prefer_squeue_then_sacct_then_unknown() {
        let subs = vec![
            Submission {
                job_id: 60,
                array: 0,
                tasks: vec![vec![0, 1], vec![2, 3], vec![4]],
                submitted: String::new(),
            },
            // Point 4 resubmitted: judged by job 61.
            Submission {
                job_id: 61,
                array: 1,
                tasks: vec![vec![4]],
                submitted: String::new(),
            },
        ];
        let latest = latest_tasks(&subs);
        assert_eq!(latest[&1], (60, 0));
        assert_eq!(latest[&3], (60, 1));
        assert_eq!(latest[&4], (61, 0));
        let squeue = parse_squeue("61_0 PENDING\n");
        let sacct = parse_sacct("60_0|COMPLETED\n60_2|CANCELLED by 0\n");
        let s = combine_states(&latest, &squeue, &sacct);
        assert_eq!(s[&0], TaskState::Completed);
        assert_eq!(s[&1], TaskState::Completed);
        assert_eq!(s[&2], TaskState::Unknown);
        assert_eq!(s[&3], TaskState::Unknown);
        assert_eq!(s[&4], TaskState::Pending);
    }
}
