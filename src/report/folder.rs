//! The output folder of `ncform run` (`docs/cases.md`, "The run folder"):
//! one run per folder, never mixed with another.
//!
//! - Before the solve the folder is prepared: an earlier ncform run in it
//!   (recognised by its `status.json`, or the `summary.json` of a run from
//!   before status files) is moved aside whole to `<out>.previous` (or
//!   `<out>.previous-2`, `-3`, …: nothing is deleted); a non-empty folder
//!   that is not an ncform run (or whose `status.json` is not an ncform
//!   run's, said with what is wrong with it) is refused; an empty or
//!   missing one is used. Preparations beside one another take turns (a
//!   lock on the folder holding them), and `status.json` is created
//!   exclusively: of two runs started at once on one folder, one is
//!   refused as a run still going on.
//! - `status.json` is written first as `running` (case, start time, pid,
//!   ncform version) and rewritten last as `complete`, `incomplete`,
//!   `interrupted` or `failed`, with the manifest: every file the run wrote
//!   (path relative to the folder, bytes) and every output it could not
//!   write, with the error. It is replaced atomically (written beside,
//!   then renamed), so a reader never sees half of it; when it cannot be
//!   rewritten, stderr says it is stale.
//! - Every output goes through [`Outputs::write`]: it is written under
//!   `<name>.partial` and renamed into place when complete, so a file
//!   under its real name is never half written; a write that fails leaves
//!   no file, is reported on stderr and listed as missing, and the run goes
//!   on with the others.
//!
//! The exit codes of the command line, one meaning each, are
//! [`ExitStatus`].

use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, SystemTime};

use serde::{Deserialize, Serialize};

use crate::solver::RunStatus;

/// The status file's name in the run folder.
pub const STATUS_FILE: &str = "status.json";

/// The `format` of a status file this version writes.
pub const STATUS_FORMAT: &str = "ncform-run-folder-1";

/// Earlier runs moved aside from one folder before the preparation gives
/// up (`<out>.previous`, `<out>.previous-2`, …).
const MAX_PREVIOUS: usize = 1000;

/// How a command ended: the process exit code, one meaning each
/// (`docs/cases.md`, "Exit codes").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ExitStatus {
    /// 0: the run is complete and every output is written.
    Complete,
    /// 1: bad input or a set-up error (case, parameter or mesh file, eval
    /// lines, an output folder that cannot be used); nothing was solved.
    BadInput,
    /// 2: a command-line usage error (clap's own code).
    Usage,
    /// 3: the solve stopped early; the results up to the last converged
    /// state are written and marked incomplete.
    Incomplete,
    /// 4: stopped by SIGINT or SIGTERM; the results up to the last state
    /// are written and marked interrupted.
    Interrupted,
    /// 5: some outputs could not be written (listed in `status.json` and on
    /// stderr); takes precedence over 3 and 4.
    OutputsMissing,
}

impl ExitStatus {
    /// The process exit code.
    pub fn code(self) -> u8 {
        match self {
            ExitStatus::Complete => 0,
            ExitStatus::BadInput => 1,
            ExitStatus::Usage => 2,
            ExitStatus::Incomplete => 3,
            ExitStatus::Interrupted => 4,
            ExitStatus::OutputsMissing => 5,
        }
    }

    /// The exit status of a run whose solve ended with `status` and which
    /// could not write `missing` outputs.
    pub fn of_run(status: &RunStatus, missing: usize) -> Self {
        if missing > 0 {
            return ExitStatus::OutputsMissing;
        }
        match status {
            RunStatus::Complete => ExitStatus::Complete,
            RunStatus::Incomplete { .. } => ExitStatus::Incomplete,
            RunStatus::Interrupted { .. } => ExitStatus::Interrupted,
        }
    }
}

/// A file the run wrote.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct WrittenFile {
    /// Path relative to the run folder, `/`-separated.
    pub path: String,
    /// Size \[bytes\].
    pub bytes: u64,
}

/// An output the run could not write.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct MissingOutput {
    /// Path relative to the run folder (or what could not be made).
    pub path: String,
    /// Why: the error, with the OS's message.
    pub error: String,
}

/// The run's state as `status.json` says.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum FolderStatus {
    /// The run is going on (or was killed without a chance to say so:
    /// then `pid` is no longer running).
    Running,
    /// The solve reached its end.
    Complete,
    /// The solve stopped early (`solve` says where and why).
    Incomplete,
    /// Stopped on SIGINT/SIGTERM.
    Interrupted,
    /// A set-up error after the folder was prepared (`error`).
    Failed,
}

/// The content of `status.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct StatusFile {
    /// [`STATUS_FORMAT`].
    pub format: String,
    /// The run's state.
    pub status: FolderStatus,
    /// `true` when every output was written (`missing` is empty).
    pub outputs_complete: bool,
    /// The exit code of the command (absent while running).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub exit_code: Option<u8>,
    /// The ncform version that made the run.
    pub ncform_version: String,
    /// The case file.
    pub case: String,
    /// The case title.
    pub title: String,
    /// Process id of the run.
    pub pid: u32,
    /// Start time (RFC 3339, UTC).
    pub started: String,
    /// End time (RFC 3339, UTC; absent while running).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub finished: Option<String>,
    /// How the solve ended: `complete`, or `incomplete` with the last
    /// converged load, the load attempted and the reason, or `interrupted`
    /// with the load reached (absent while running or on a set-up error).
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub solve: Option<serde_json::Value>,
    /// The set-up error of a failed run.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub error: Option<String>,
    /// Where the earlier run in this folder was moved.
    #[serde(skip_serializing_if = "Option::is_none", default)]
    pub previous_run: Option<String>,
    /// The manifest: every file the run wrote, `status.json` aside.
    pub files: Vec<WrittenFile>,
    /// Every output that could not be written, and why.
    pub missing: Vec<MissingOutput>,
}

/// The name an output is written under before it is complete:
/// `<name>.partial`, beside it.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut partial = path.as_os_str().to_os_string();
    partial.push(".partial");
    PathBuf::from(partial)
}

/// Writes the file `path` whole or not at all: `write` writes it under
/// [`partial_path`], which is renamed to `path` only when the write
/// succeeded; on a failure the partial file is removed (if that fails too
/// it is left, said on stderr: its name says it is partial), so a file
/// under its real name is always complete. Returns its size.
///
/// # Errors
/// The error of `write` or of the rename, naming `path` (not the partial
/// name).
// A String error: it is the text the manifest records for the missing
// output (`MissingOutput::error`), made from whatever error type the
// writer has.
pub fn write_whole<E: std::fmt::Display>(
    path: &Path,
    write: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<u64, String> {
    let partial = partial_path(path);
    let named = |e: std::io::Error| format!("{}: {e}", path.display());
    let result = write(&partial)
        // The writers name the file they were given: the message names
        // the output.
        .map_err(|e| {
            e.to_string()
                .replace(&partial.display().to_string(), &path.display().to_string())
        })
        .and_then(|()| std::fs::metadata(&partial).map_err(named))
        .and_then(|meta| {
            std::fs::rename(&partial, path)
                .map(|()| meta.len())
                .map_err(named)
        });
    if result.is_err() {
        remove_partial(&partial);
    }
    result
}

/// Removes the partial file `partial` of a failed write, if there is one
/// (a folder of that name is not ncform's: it is left); a removal that
/// fails is said on stderr.
fn remove_partial(partial: &Path) {
    if std::fs::symlink_metadata(partial).is_ok_and(|m| m.is_dir()) {
        return;
    }
    match std::fs::remove_file(partial) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => eprintln!(
            "warning: the partial file {} of a failed write could not be removed ({e}); it is not an output",
            partial.display()
        ),
        _ => {}
    }
}

/// What a run wrote and what it could not, under its folder.
#[derive(Debug, Clone)]
pub struct Outputs {
    root: PathBuf,
    files: BTreeMap<String, u64>,
    missing: Vec<MissingOutput>,
}

impl Outputs {
    /// A record of the outputs under `root`.
    pub fn new(root: &Path) -> Self {
        Self {
            root: root.to_path_buf(),
            files: BTreeMap::new(),
            missing: Vec::new(),
        }
    }

    /// The folder.
    pub fn root(&self) -> &Path {
        &self.root
    }

    /// `path` relative to the folder, `/`-separated.
    fn relative(&self, path: &Path) -> String {
        let rel = path.strip_prefix(&self.root).unwrap_or(path);
        rel.components()
            .map(|c| c.as_os_str().to_string_lossy())
            .collect::<Vec<_>>()
            .join("/")
    }

    /// Writes the output `path` whole or not at all ([`write_whole`]) and
    /// records it: its size when written, else a missing output, reported
    /// on stderr. Returns whether it was written.
    pub fn write<E: std::fmt::Display>(
        &mut self,
        path: &Path,
        write: impl FnOnce(&Path) -> Result<(), E>,
    ) -> bool {
        let rel = self.relative(path);
        match write_whole(path, write) {
            Ok(bytes) => {
                self.missing.retain(|m| m.path != rel);
                self.files.insert(rel, bytes);
                true
            }
            Err(error) => {
                eprintln!("error: output not written: {error}");
                self.files.remove(&rel);
                self.missing.push(MissingOutput { path: rel, error });
                false
            }
        }
    }

    /// Writes `value` as JSON ([`super::json::json_text`]: no `null`,
    /// a non-finite number written as a named string) to `path`, whole or
    /// not at all like [`Outputs::write`]; a value that was not finite is
    /// said on the error stream, naming the file.
    pub fn write_json<T: serde::Serialize + ?Sized>(&mut self, path: &Path, value: &T) -> bool {
        self.write(path, |p| {
            let (text, not_finite) =
                super::json::json_text(value).map_err(|e| super::io_err(path, e))?;
            if not_finite > 0 {
                eprintln!(
                    "warning: {}: {not_finite} figure(s) could not be computed (not finite); written as \"{}\"",
                    path.display(),
                    super::json::NOT_FINITE
                );
            }
            std::fs::write(p, text).map_err(|e| super::io_err(path, e))
        })
    }

    /// Records an output that could not be made at all (`what`: its path
    /// relative to the folder, or what it is), reported on stderr.
    pub fn record_missing(&mut self, what: &str, error: String) {
        eprintln!("error: output not written: {what}: {error}");
        self.missing.push(MissingOutput {
            path: what.to_string(),
            error,
        });
    }

    /// The files written so far.
    pub fn files(&self) -> Vec<WrittenFile> {
        self.files
            .iter()
            .map(|(path, bytes)| WrittenFile {
                path: path.clone(),
                bytes: *bytes,
            })
            .collect()
    }

    /// The outputs that could not be written so far.
    pub fn missing(&self) -> &[MissingOutput] {
        &self.missing
    }
}

/// A prepared run folder: `status.json` says `running`; every output is
/// recorded in [`RunFolder::outputs`].
#[derive(Debug)]
pub struct RunFolder {
    status: StatusFile,
    outputs: Outputs,
    /// The folder's key in the folders this process holds.
    held: PathBuf,
}

/// The current time in RFC 3339 (UTC, seconds): the times of the run
/// folder's and a sweep's status files.
pub fn now() -> String {
    humantime::format_rfc3339_seconds(SystemTime::now()).to_string()
}

/// Why an output folder cannot take a run. The messages name the folder
/// and say what to do.
#[derive(Debug, Clone, thiserror::Error)]
pub enum FolderError {
    /// `--out` names a file.
    #[error("output folder '{0}' is a file, not a folder; choose another --out")]
    IsAFile(String),
    /// A folder with other files and no ncform run.
    #[error(
        "output folder '{folder}' is not empty ('{entry}', …) and holds no ncform run (no {STATUS_FILE}); ncform never deletes files it did not write: choose another --out, or empty the folder"
    )]
    Foreign {
        /// The folder.
        folder: String,
        /// One of its entries.
        entry: String,
    },
    /// A folder whose `status.json` is not an ncform run's.
    #[error(
        "output folder '{folder}' holds a {STATUS_FILE} that is not an ncform run's: {problem}; ncform never deletes files it did not write: choose another --out, or remove that file"
    )]
    ForeignStatus {
        /// The folder.
        folder: String,
        /// What is wrong with the file.
        problem: String,
    },
    /// A run still going on in the folder.
    #[error(
        "output folder '{folder}' holds a run still going on (process {pid}, {STATUS_FILE} says running); wait for it or choose another --out"
    )]
    StillRunning {
        /// The folder.
        folder: String,
        /// The process of the run.
        pid: u32,
    },
    /// The earlier run could not be moved aside.
    #[error(
        "output folder '{folder}' holds an earlier run that could not be moved aside to '{aside}': {error}"
    )]
    NotMovedAside {
        /// The folder.
        folder: String,
        /// Where it was to go.
        aside: String,
        /// Why it could not.
        error: String,
    },
    /// The earlier run cannot be moved aside from a path without a name.
    #[error(
        "output folder '{0}' holds an earlier run, which cannot be moved aside from a path without a folder name; give --out a named folder"
    )]
    Unnamed(String),
    /// Every name for an earlier run beside the folder is taken.
    #[error(
        "output folder '{folder}': {MAX_PREVIOUS} earlier runs are already moved aside beside it ('{name}.previous*'); delete some or choose another --out"
    )]
    TooManyPrevious {
        /// The folder.
        folder: String,
        /// Its name.
        name: String,
    },
    /// A file-system error on the folder, a subfolder or its status file.
    #[error("output folder '{folder}': {error}")]
    Io {
        /// The folder (or subfolder).
        folder: String,
        /// The error.
        error: String,
    },
}

/// What an existing folder holds.
enum Existing {
    /// Nothing: use it.
    Empty,
    /// An earlier ncform run, with the pid of a run still marked running.
    Run { running_pid: Option<u32> },
    /// Something else: refuse.
    Foreign(String),
    /// A `status.json` that is not an ncform run's: what is wrong with it.
    ForeignStatus(String),
}

/// Attempts at reading a `status.json` that is empty or ends early (a run
/// preparing the folder at the same moment is writing it), 10 ms apart.
const STATUS_READS: usize = 50;

/// Reads the status file `path`: `Ok(None)` when there is none, else the
/// file, or what is wrong with it (unreadable, not JSON, not ncform's
/// format).
// A String error: it is the "what is wrong" part of
// `FolderError::ForeignStatus`'s message.
fn read_status(path: &Path) -> Result<Option<StatusFile>, String> {
    for attempt in 1..=STATUS_READS {
        let text = match std::fs::read_to_string(path) {
            Ok(text) => text,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(format!("it cannot be read ({e})")),
        };
        let value = match serde_json::from_str::<serde_json::Value>(&text) {
            Ok(value) => value,
            Err(e) if e.is_eof() && attempt < STATUS_READS => {
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
            Err(e) => return Err(format!("it is not JSON ({e})")),
        };
        let format = value.get("format").and_then(serde_json::Value::as_str);
        if format != Some(STATUS_FORMAT) {
            return Err(match format {
                Some(f) => format!(
                    "its format is '{f}', not '{STATUS_FORMAT}' (another program's, or another ncform version's)"
                ),
                None => format!("it has no \"format\": \"{STATUS_FORMAT}\""),
            });
        }
        return serde_json::from_value::<StatusFile>(value)
            .map(Some)
            .map_err(|e| format!("it is not in the format it names ({e})"));
    }
    unreachable!("the last attempt returns")
}

/// Looks at the folder `out` (which exists and is a directory).
fn inspect(out: &Path) -> Result<Existing, FolderError> {
    let mut entries = std::fs::read_dir(out)
        .map_err(|e| FolderError::Io {
            folder: out.display().to_string(),
            error: e.to_string(),
        })?
        .filter_map(Result::ok);
    let Some(first) = entries.next() else {
        return Ok(Existing::Empty);
    };
    let status = read_status(&out.join(STATUS_FILE));
    if let Ok(Some(status)) = &status {
        let running_pid = (status.status == FolderStatus::Running).then_some(status.pid);
        return Ok(Existing::Run { running_pid });
    }
    // A run from before status files: its summary.json names the case,
    // the status and the units.
    if let Ok(text) = std::fs::read_to_string(out.join("summary.json"))
        && let Ok(serde_json::Value::Object(summary)) = serde_json::from_str(&text)
        && ["case", "status", "units"]
            .iter()
            .all(|k| summary.contains_key(*k))
    {
        return Ok(Existing::Run { running_pid: None });
    }
    if let Err(problem) = status {
        return Ok(Existing::ForeignStatus(problem));
    }
    Ok(Existing::Foreign(
        first.file_name().to_string_lossy().into_owned(),
    ))
}

/// The folders this process holds a run in (a [`RunFolder`] not yet
/// dropped), as made absolute by [`held_key`]; a folder appears once per
/// holder (or preparer).
static HELD: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// The key of the folder `out` in [`HELD`].
fn held_key(out: &Path) -> PathBuf {
    std::fs::canonicalize(out).unwrap_or_else(|_| out.to_path_buf())
}

/// Marks `key` held by this process.
fn hold(key: &Path) {
    HELD.lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(key.to_path_buf());
}

/// Gives one hold of `key` up.
fn release(key: &Path) {
    let mut held = HELD.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(k) = held.iter().position(|h| h == key) {
        held.swap_remove(k);
    }
}

/// `true` when the run `pid` in the folder `out` is going on: another
/// process `pid` is running (Linux: `/proc/<pid>`; elsewhere unknown,
/// taken as not running), or `pid` is this process and it holds the
/// folder (another thread's run).
fn run_alive(pid: u32, out: &Path) -> bool {
    if pid == std::process::id() {
        let key = held_key(out);
        HELD.lock()
            .unwrap_or_else(|e| e.into_inner())
            .contains(&key)
    } else {
        Path::new("/proc").join(pid.to_string()).is_dir()
    }
}

/// Waits for and takes an exclusive lock (`flock`) on the folder holding
/// `out` (made if missing), released when the returned handle is dropped
/// (or the process ends). Best effort: `None` when it cannot be had — the
/// exclusive creation of `status.json` still keeps two runs apart.
fn lock_parent(out: &Path) -> Option<std::fs::File> {
    #[cfg(unix)]
    {
        use std::os::fd::AsRawFd;
        let parent = out
            .parent()
            .filter(|p| !p.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::create_dir_all(parent).ok()?;
        let dir = std::fs::File::open(parent).ok()?;
        // SAFETY: flock on the descriptor of a file this function holds
        // open.
        let locked = unsafe { libc::flock(dir.as_raw_fd(), libc::LOCK_EX) } == 0;
        locked.then_some(dir)
    }
    #[cfg(not(unix))]
    {
        let _ = out;
        None
    }
}

/// Attempts at preparing a folder in which a run appears at the moment it
/// is prepared, before the preparation gives up.
const PREPARE_ATTEMPTS: usize = 5;

/// The first free `<out>.previous`, `<out>.previous-2`, … beside `out`.
fn previous_path(out: &Path) -> Result<PathBuf, FolderError> {
    let name = out
        .file_name()
        .ok_or_else(|| FolderError::Unnamed(out.display().to_string()))?;
    for k in 1..=MAX_PREVIOUS {
        let mut candidate = name.to_os_string();
        if k == 1 {
            candidate.push(".previous");
        } else {
            candidate.push(format!(".previous-{k}"));
        }
        let path = out.with_file_name(candidate);
        if std::fs::symlink_metadata(&path).is_err() {
            return Ok(path);
        }
    }
    Err(FolderError::TooManyPrevious {
        folder: out.display().to_string(),
        name: name.to_string_lossy().into_owned(),
    })
}

/// Writes `text` to `path` atomically: into a file beside it, then renamed.
fn write_atomic(path: &Path, text: &str) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_os_string();
    tmp.push(".tmp");
    let tmp = PathBuf::from(tmp);
    let result = std::fs::write(&tmp, text).and_then(|()| std::fs::rename(&tmp, path));
    if result.is_err() {
        remove_partial(&tmp);
    }
    result
}

/// Creates the status file `path` with `status`, failing with
/// `AlreadyExists` when there is one; a file left half written is removed.
fn create_status(path: &Path, status: &StatusFile) -> std::io::Result<()> {
    let (text, _) = super::json::json_text(status).map_err(std::io::Error::other)?;
    let mut file = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(path)?;
    file.write_all(text.as_bytes()).inspect_err(|_| {
        drop(file);
        remove_partial(path);
    })
}

impl RunFolder {
    /// Prepares `out` for a run of the case file `case` titled `title`:
    /// moves an earlier run aside (said on stderr), refuses a folder with
    /// other files, creates `out` and its `subdirs`, and writes
    /// `status.json` as `running`.
    ///
    /// # Errors
    /// A folder that is not empty and holds no ncform run, a run still
    /// going on in it, or a file-system error, naming the path.
    pub fn prepare(
        out: &Path,
        case: &str,
        title: &str,
        subdirs: &[&str],
    ) -> Result<Self, FolderError> {
        // Preparations beside one another take turns: the inspection, the
        // move aside and the creation of status.json are one step.
        let _turn = lock_parent(out);
        for _ in 0..PREPARE_ATTEMPTS {
            if let Some(folder) = Self::try_prepare(out, case, title, subdirs)? {
                return Ok(folder);
            }
        }
        Err(FolderError::Io {
            folder: out.display().to_string(),
            error: format!(
                "cannot write {STATUS_FILE}: another run took the folder at the same moment, {PREPARE_ATTEMPTS} times"
            ),
        })
    }

    /// One attempt at [`RunFolder::prepare`]: `None` when another run
    /// created `status.json` between the inspection of the folder and the
    /// creation of this run's (the next attempt inspects it again).
    fn try_prepare(
        out: &Path,
        case: &str,
        title: &str,
        subdirs: &[&str],
    ) -> Result<Option<Self>, FolderError> {
        let mut previous_run = None;
        match std::fs::metadata(out) {
            Ok(meta) if !meta.is_dir() => {
                return Err(FolderError::IsAFile(out.display().to_string()));
            }
            Ok(_) => match inspect(out)? {
                Existing::Empty => {}
                Existing::Foreign(entry) => {
                    return Err(FolderError::Foreign {
                        folder: out.display().to_string(),
                        entry,
                    });
                }
                Existing::ForeignStatus(problem) => {
                    return Err(FolderError::ForeignStatus {
                        folder: out.display().to_string(),
                        problem,
                    });
                }
                Existing::Run {
                    running_pid: Some(pid),
                } if run_alive(pid, out) => {
                    return Err(FolderError::StillRunning {
                        folder: out.display().to_string(),
                        pid,
                    });
                }
                Existing::Run { .. } => {
                    let aside = previous_path(out)?;
                    std::fs::rename(out, &aside).map_err(|e| FolderError::NotMovedAside {
                        folder: out.display().to_string(),
                        aside: aside.display().to_string(),
                        error: e.to_string(),
                    })?;
                    eprintln!(
                        "note: the earlier run in {} was moved to {}",
                        out.display(),
                        aside.display()
                    );
                    previous_run = Some(aside.display().to_string());
                }
            },
            Err(_) => {}
        }
        std::fs::create_dir_all(out).map_err(|e| FolderError::Io {
            folder: out.display().to_string(),
            error: e.to_string(),
        })?;
        let status = StatusFile {
            format: STATUS_FORMAT.into(),
            status: FolderStatus::Running,
            outputs_complete: true,
            exit_code: None,
            ncform_version: env!("CARGO_PKG_VERSION").into(),
            case: case.into(),
            title: title.into(),
            pid: std::process::id(),
            started: now(),
            finished: None,
            solve: None,
            error: None,
            previous_run,
            files: Vec::new(),
            missing: Vec::new(),
        };
        // Held before status.json says running, so that another thread of
        // this process sees the run as going on as soon as it is there.
        let held = held_key(out);
        hold(&held);
        // Creating status.json is the one exclusive step: of two runs
        // preparing the folder at once, one creates it, the other finds it.
        match create_status(&out.join(STATUS_FILE), &status) {
            Ok(()) => {}
            Err(e) => {
                release(&held);
                if e.kind() == std::io::ErrorKind::AlreadyExists {
                    return Ok(None);
                }
                return Err(FolderError::Io {
                    folder: out.display().to_string(),
                    error: format!("cannot write {STATUS_FILE}: {e}"),
                });
            }
        }
        let mut folder = Self {
            status,
            outputs: Outputs::new(out),
            held,
        };
        for dir in subdirs.iter().map(|d| out.join(d)) {
            if let Err(e) = std::fs::create_dir_all(&dir) {
                let error = FolderError::Io {
                    folder: dir.display().to_string(),
                    error: e.to_string(),
                };
                folder.fail(&error.to_string());
                return Err(error);
            }
        }
        Ok(Some(folder))
    }

    /// The folder.
    pub fn path(&self) -> &Path {
        self.outputs.root()
    }

    /// Where the earlier run was moved, if there was one.
    pub fn previous_run(&self) -> Option<&str> {
        self.status.previous_run.as_deref()
    }

    /// The record of the outputs.
    pub fn outputs(&self) -> &Outputs {
        &self.outputs
    }

    /// The record of the outputs, to add to.
    pub fn outputs_mut(&mut self) -> &mut Outputs {
        &mut self.outputs
    }

    fn write_status(&self) -> std::io::Result<()> {
        let (text, _) = super::json::json_text(&self.status).map_err(std::io::Error::other)?;
        write_atomic(&self.path().join(STATUS_FILE), &text)
    }

    /// Rewrites `status.json` with the end of the solve, `solve`, the
    /// manifest and the missing outputs; returns the exit status. A
    /// `status.json` that cannot be written is reported on stderr and
    /// makes the exit status [`ExitStatus::OutputsMissing`].
    pub fn finish(&mut self, solve: &RunStatus) -> ExitStatus {
        self.status.status = match solve {
            RunStatus::Complete => FolderStatus::Complete,
            RunStatus::Incomplete { .. } => FolderStatus::Incomplete,
            RunStatus::Interrupted { .. } => FolderStatus::Interrupted,
        };
        self.status.solve = serde_json::to_value(solve).ok();
        let exit = ExitStatus::of_run(solve, self.outputs.missing.len());
        self.close(exit)
    }

    /// Rewrites `status.json` as `failed` with the set-up error `error`
    /// (the exit status is [`ExitStatus::BadInput`]).
    pub fn fail(&mut self, error: &str) {
        self.status.status = FolderStatus::Failed;
        self.status.error = Some(error.to_string());
        self.close(ExitStatus::BadInput);
    }

    /// Says on stderr that `status.json` could not be rewritten with the
    /// end of the run (`error`), so that it is stale: it still says
    /// `running`, for a process that has ended.
    fn say_stale(&self, error: &std::io::Error) {
        let ended = serde_json::to_value(self.status.status)
            .ok()
            .and_then(|v| v.as_str().map(String::from))
            .unwrap_or_default();
        eprintln!(
            "error: output not written: {}: {error}; that file is stale: it still says running (process {}), but the run ended {ended}",
            self.path().join(STATUS_FILE).display(),
            self.status.pid,
        );
    }

    fn close(&mut self, exit: ExitStatus) -> ExitStatus {
        self.status.outputs_complete = self.outputs.missing.is_empty();
        self.status.exit_code = Some(exit.code());
        self.status.finished = Some(now());
        self.status.files = self.outputs.files();
        self.status.missing = self.outputs.missing.clone();
        match self.write_status() {
            Ok(()) => exit,
            Err(e) => {
                self.say_stale(&e);
                if exit == ExitStatus::BadInput {
                    exit
                } else {
                    ExitStatus::OutputsMissing
                }
            }
        }
    }
}

/// A folder dropped while its status still says `running` — a panic
/// unwinding through the run (a bug), or a caller that neither finished
/// nor failed it — is marked `failed` with what was written, so that
/// `running` only ever means a run going on or killed.
impl Drop for RunFolder {
    fn drop(&mut self) {
        if self.status.status == FolderStatus::Running {
            self.mark_failed();
        }
        release(&self.held);
    }
}

impl RunFolder {
    /// Marks the folder `failed` when it is dropped while running.
    fn mark_failed(&mut self) {
        let panicking = std::thread::panicking();
        self.status.status = FolderStatus::Failed;
        self.status.error = Some(if panicking {
            "ncform stopped on an internal error (a panic: a bug in ncform; please report it with the case file); the files listed are those written before it".into()
        } else {
            "the run ended without a final status".into()
        });
        self.status.exit_code = panicking.then_some(101);
        self.status.outputs_complete = false;
        self.status.finished = Some(now());
        self.status.files = self.outputs.files();
        self.status.missing = self.outputs.missing.clone();
        if let Err(e) = self.write_status() {
            self.say_stale(&e);
        }
    }
}
