//! A sweep's folder: the points a design places, one folder per point
//! holding the exact case it runs, the manifest `sweep.json`, and each
//! point's own `status.json` (`docs/studies.md`, "The sweep folder").
//!
//! ```text
//! DIR/sweep.json              design, factors, points, binary, hashes
//! DIR/points/0007/case.toml   the case of point 7 (runs alone: ncform run)
//! DIR/points/0007/params-*.toml  a parameter set edited through a key
//! DIR/points/0007/status.json pending → running → complete | failed | interrupted
//! DIR/points/0007/run/        the run folder of `ncform run`
//! ```
//!
//! A point's `status.json` is written only by the process that runs the
//! point (temporary file, then rename), so concurrent tasks never rewrite
//! a shared file. A point's run folder is removed before the point runs,
//! so a rerun never mixes with the outputs of a killed attempt.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

use crate::report::provenance::sha256_hex;

pub use crate::report::folder::now;

use super::design;
use super::keys::{CaseDocument, KeyError};
use super::spec::{Constraint, DesignKind, Levels, Response, SweepSpec};

/// The manifest's format name.
pub const FORMAT: &str = "ncform-sweep 1";

/// Why a sweep could not be planned, prepared, resumed or read.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SweepError {
    /// The sweep file.
    #[error("{0}")]
    Spec(#[from] super::spec::SpecError),
    /// A key refused by the case, naming the point and its values.
    #[error("{sweep}: point {index} ({values}): {error}")]
    Point {
        /// The sweep file.
        sweep: String,
        /// The point.
        index: usize,
        /// Its varied values.
        values: String,
        /// Why (boxed: the error type stays small).
        error: Box<KeyError>,
    },
    /// The design could not be made (sizes, seeds, a correlation matrix).
    #[error("{sweep}: design \"{design}\": {reason}")]
    Design {
        /// The sweep file.
        sweep: String,
        /// The design.
        design: &'static str,
        /// Why.
        reason: String,
    },
    /// The sweep folder cannot be used as asked.
    #[error("{path}: {reason}")]
    Folder {
        /// The folder or file.
        path: String,
        /// Why, and what to do.
        reason: String,
    },
}

/// A file or folder error.
fn folder_err(path: &Path, reason: impl std::fmt::Display) -> SweepError {
    SweepError::Folder {
        path: path.display().to_string(),
        reason: reason.to_string(),
    }
}

/// One point of a planned sweep.
#[derive(Debug, Clone)]
pub struct PlannedPoint {
    /// Its index (row of the design).
    pub index: usize,
    /// The varied keys and values, in factor order.
    pub values: Vec<(String, toml::Value)>,
    /// The case as edited for it.
    pub doc: CaseDocument,
}

/// What `collect` needs of a sensitivity design.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SensitivityDesign {
    /// Saltelli's scheme: base sample `n`, `d` factors.
    Sobol {
        /// Base sample.
        n: usize,
        /// Factors.
        d: usize,
    },
    /// Morris trajectories: the steps and each factor's range.
    Morris {
        /// (trajectory, from, to, factor, delta) of every step.
        steps: Vec<(usize, usize, usize, usize, f64)>,
        /// Each factor's hi − lo.
        scale: Vec<f64>,
    },
}

/// Every point of the sweep `spec`, each case checked by the case parser:
/// an unknown key, a wrong type or a value out of range is refused here,
/// before anything runs, naming the point, the key and the value.
///
/// # Errors
/// [`SweepError::Point`], [`SweepError::Design`].
pub fn plan(
    spec: &SweepSpec,
) -> Result<(Vec<PlannedPoint>, Option<SensitivityDesign>), SweepError> {
    let sweep = spec.file.display().to_string();
    let design_err = |reason: String| SweepError::Design {
        sweep: sweep.clone(),
        design: spec.design.name(),
        reason,
    };
    let mut base = CaseDocument::load(&spec.case).map_err(|error| SweepError::Point {
        sweep: sweep.clone(),
        index: 0,
        values: "the base case".into(),
        error: Box::new(error),
    })?;
    for (key, value) in &spec.set {
        base.set(key, value.clone())
            .map_err(|error| SweepError::Point {
                sweep: sweep.clone(),
                index: 0,
                values: format!("[[set]] {key}"),
                error: Box::new(error),
            })?;
    }
    let keys: Vec<String> = spec
        .vary
        .iter()
        .map(|f| f.key.clone())
        .chain(spec.correlated.iter().flat_map(|c| c.keys.clone()))
        .collect();
    let mut sensitivity = None;
    let rows: Vec<Vec<toml::Value>> = match spec.design {
        DesignKind::Grid => {
            let levels: Vec<Vec<toml::Value>> = spec
                .vary
                .iter()
                .map(|f| f.levels.discrete().unwrap_or_default())
                .collect();
            let counts: Vec<usize> = levels.iter().map(Vec::len).collect();
            design::grid(&counts, spec.max_points)
                .map_err(|e| design_err(e.to_string()))?
                .into_iter()
                .map(|idx| {
                    idx.iter()
                        .enumerate()
                        .map(|(f, &i)| levels[f][i].clone())
                        .collect()
                })
                .collect()
        }
        DesignKind::OneAtATime => {
            let base_values = spec
                .vary
                .iter()
                .map(|f| {
                    base.get(&f.key).map_err(|error| SweepError::Point {
                        sweep: sweep.clone(),
                        index: 0,
                        values: format!("the base value of {}", f.key),
                        error: Box::new(error),
                    })
                })
                .collect::<Result<Vec<_>, _>>()?;
            let mut rows = vec![base_values.clone()];
            for (f, factor) in spec.vary.iter().enumerate() {
                for level in factor.levels.discrete().unwrap_or_default() {
                    if same_value(&level, &base_values[f]) {
                        continue;
                    }
                    let mut row = base_values.clone();
                    row[f] = level;
                    rows.push(row);
                }
            }
            rows
        }
        DesignKind::Lhs | DesignKind::MonteCarlo => {
            let n = spec.count.unwrap_or(1);
            let d = keys.len();
            let u = if spec.design == DesignKind::Lhs {
                design::latin_hypercube(n, d, spec.seed)
            } else {
                design::monte_carlo(n, d, spec.seed)
            }
            .map_err(|e| design_err(e.to_string()))?;
            let nv = spec.vary.len();
            let correlated = match &spec.correlated {
                None => vec![Vec::new(); n],
                Some(c) => {
                    let sub: Vec<Vec<f64>> = u.iter().map(|r| r[nv..].to_vec()).collect();
                    design::correlated_normal(&sub, &c.mean, &c.sd, &c.correlation)
                        .map_err(|e| design_err(e.to_string()))?
                }
            };
            u.iter()
                .zip(correlated)
                .map(|(row, corr)| {
                    spec.vary
                        .iter()
                        .enumerate()
                        .map(|(f, factor)| marginal_value(&factor.levels, row[f]))
                        .chain(corr.into_iter().map(toml::Value::Float))
                        .collect()
                })
                .collect()
        }
        DesignKind::Sobol => {
            let n = spec.count.unwrap_or(1);
            let d = spec.vary.len();
            let u = design::saltelli(n, d, spec.seed).map_err(|e| design_err(e.to_string()))?;
            sensitivity = Some(SensitivityDesign::Sobol { n, d });
            unit_rows_to_values(spec, &u)
        }
        DesignKind::Morris => {
            let r = spec.count.unwrap_or(1);
            let d = spec.vary.len();
            let m = design::morris(r, d, spec.levels, spec.seed)
                .map_err(|e| design_err(e.to_string()))?;
            sensitivity = Some(SensitivityDesign::Morris {
                steps: m
                    .steps
                    .iter()
                    .map(|s| (s.trajectory, s.from, s.to, s.factor, s.delta))
                    .collect(),
                scale: spec
                    .vary
                    .iter()
                    .map(|f| match f.levels {
                        Levels::Range { lo, hi, .. } => hi - lo,
                        _ => 1.0,
                    })
                    .collect(),
            });
            unit_rows_to_values(spec, &m.points)
        }
    };
    if rows.len() > spec.max_points {
        return Err(design_err(format!(
            "{} points, more than max_points = {}",
            rows.len(),
            spec.max_points
        )));
    }
    let points = rows
        .into_iter()
        .enumerate()
        .map(|(index, row)| {
            let values: Vec<(String, toml::Value)> = keys.iter().cloned().zip(row).collect();
            let mut doc = base.clone();
            let point_err = |error| SweepError::Point {
                sweep: sweep.clone(),
                index,
                values: values_text(&values),
                error: Box::new(error),
            };
            for (key, value) in &values {
                doc.set_unchecked(key, value).map_err(point_err)?;
            }
            doc.case().map_err(point_err)?;
            Ok(PlannedPoint { index, values, doc })
        })
        .collect::<Result<Vec<_>, SweepError>>()?;
    Ok((points, sensitivity))
}

/// `key = value, …`.
pub fn values_text(values: &[(String, toml::Value)]) -> String {
    values
        .iter()
        .map(|(k, v)| format!("{k} = {v}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Whether two level values are the same (numbers compared as numbers).
fn same_value(a: &toml::Value, b: &toml::Value) -> bool {
    match (as_number(a), as_number(b)) {
        (Some(x), Some(y)) => x == y,
        _ => a == b,
    }
}

/// A TOML number as f64.
fn as_number(v: &toml::Value) -> Option<f64> {
    match v {
        toml::Value::Float(x) => Some(*x),
        toml::Value::Integer(i) => Some(*i as f64),
        _ => None,
    }
}

/// The values of the `[[vary]]` factors at each row of unit-cube
/// coordinates.
fn unit_rows_to_values(spec: &SweepSpec, rows: &[Vec<f64>]) -> Vec<Vec<toml::Value>> {
    rows.iter()
        .map(|row| {
            spec.vary
                .iter()
                .zip(row)
                .map(|(factor, &u)| marginal_value(&factor.levels, u))
                .collect()
        })
        .collect()
}

/// The value of a unit-cube coordinate `u` of a factor.
fn marginal_value(levels: &Levels, u: f64) -> toml::Value {
    toml::Value::Float(levels.marginal().map_or(u, |m| m.value(u)))
}

/// A point as the manifest lists it.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ManifestPoint {
    /// Its index.
    pub index: usize,
    /// Its folder, relative to the sweep folder.
    pub folder: String,
    /// The varied keys and values (JSON), in factor order.
    pub values: Vec<(String, serde_json::Value)>,
    /// SHA-256 of the point's inputs: its case file and every file it
    /// reads, in order.
    pub inputs_sha256: String,
}

/// `DIR/sweep.json`: what the sweep is and which points it has.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Manifest {
    /// [`FORMAT`].
    pub format: String,
    /// Units of every number of the sweep's files.
    pub units: String,
    /// The title.
    pub title: String,
    /// The sweep file, and its SHA-256.
    pub sweep_file: String,
    /// SHA-256 of the sweep file.
    pub sweep_sha256: String,
    /// The base case file.
    pub case: String,
    /// ncform's version.
    pub ncform_version: String,
    /// The binary that prepared the sweep.
    pub binary: String,
    /// Its SHA-256.
    pub binary_sha256: String,
    /// When the sweep was prepared (UTC, RFC 3339).
    pub created: String,
    /// The design.
    pub design: String,
    /// Its seed.
    pub seed: u64,
    /// Its count (points, base sample or trajectories), if any.
    pub count: Option<usize>,
    /// The varied keys, in column order.
    pub factors: Vec<String>,
    /// The values fixed for every point.
    pub fixed: Vec<(String, serde_json::Value)>,
    /// Responses `collect` reads.
    pub responses: Vec<Response>,
    /// Constraints `collect` judges.
    pub constraints: Vec<Constraint>,
    /// What a sensitivity analysis needs of the design.
    pub sensitivity: Option<SensitivityDesign>,
    /// The points.
    pub points: Vec<ManifestPoint>,
}

/// The manifest's file.
pub fn manifest_path(dir: &Path) -> PathBuf {
    dir.join("sweep.json")
}

impl Manifest {
    /// Reads `DIR/sweep.json`.
    ///
    /// # Errors
    /// [`SweepError::Folder`] when it is missing or not a sweep manifest.
    pub fn load(dir: &Path) -> Result<Self, SweepError> {
        let path = manifest_path(dir);
        let text = std::fs::read_to_string(&path).map_err(|e| {
            folder_err(
                &path,
                format!("{e}; expected a sweep folder made by ncform sweep"),
            )
        })?;
        let m: Manifest = serde_json::from_str(&text)
            .map_err(|e| folder_err(&path, format!("not a sweep manifest: {e}")))?;
        if m.format != FORMAT {
            return Err(folder_err(
                &path,
                format!("format \"{}\"; this ncform reads \"{FORMAT}\"", m.format),
            ));
        }
        Ok(m)
    }

    /// The folder of a point.
    pub fn point_dir(&self, dir: &Path, index: usize) -> PathBuf {
        dir.join(&self.points[index].folder)
    }
}

/// SHA-256 of a file's bytes, in hex.
fn file_sha256(path: &Path) -> std::io::Result<String> {
    std::fs::read(path).map(|bytes| sha256_hex(&bytes))
}

/// The running binary and its SHA-256 (computed once).
pub fn binary_identity() -> (String, String) {
    static ID: OnceLock<(String, String)> = OnceLock::new();
    ID.get_or_init(|| match std::env::current_exe() {
        Ok(exe) => {
            let hash = file_sha256(&exe).unwrap_or_else(|e| format!("unreadable: {e}"));
            (exe.display().to_string(), hash)
        }
        Err(e) => ("unknown".into(), format!("unknown: {e}")),
    })
    .clone()
}

/// SHA-256 over the point's case file and every file it reads: over each
/// file's name and the SHA-256 of its bytes. The hashes of files outside
/// the point's folder (meshes, tool drawings: shared by every point) are
/// computed once per process.
///
/// # Errors
/// [`SweepError::Folder`] when a file cannot be read.
pub fn inputs_sha256(case: &Path) -> Result<String, SweepError> {
    static SHARED: OnceLock<std::sync::Mutex<BTreeMap<PathBuf, String>>> = OnceLock::new();
    let doc = CaseDocument::load(case).map_err(|e| folder_err(case, e))?;
    let own = case.parent().map(Path::to_path_buf).unwrap_or_default();
    let own = std::fs::canonicalize(&own).unwrap_or(own);
    let mut hasher = Sha256::new();
    let mut files = vec![case.to_path_buf()];
    files.extend(doc.referenced_files());
    for f in files {
        let shared = !f.starts_with(&own) && f.is_absolute();
        let cached = shared
            .then(|| {
                SHARED
                    .get_or_init(Default::default)
                    .lock()
                    .ok()
                    .and_then(|m| m.get(&f).cloned())
            })
            .flatten();
        let hash = match cached {
            Some(h) => h,
            None => {
                let h = file_sha256(&f).map_err(|e| folder_err(&f, e))?;
                if let (true, Ok(mut m)) = (shared, SHARED.get_or_init(Default::default).lock()) {
                    m.insert(f.clone(), h.clone());
                }
                h
            }
        };
        hasher.update(
            f.file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default(),
        );
        hasher.update(hash.as_bytes());
    }
    Ok(hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect())
}

/// A `toml` value as JSON.
fn json_value(v: &toml::Value) -> serde_json::Value {
    serde_json::to_value(v).unwrap_or(serde_json::Value::Null)
}

/// Writes a file atomically: a temporary file beside it, then a rename.
///
/// # Errors
/// [`SweepError::Folder`].
pub fn write_atomic(path: &Path, text: &str) -> Result<(), SweepError> {
    let tmp = path.with_extension(format!("tmp-{}", std::process::id()));
    std::fs::write(&tmp, text).map_err(|e| folder_err(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| folder_err(path, e))
}

/// Prepares the sweep folder `dir` for the planned points: one folder per
/// point with its case, and the manifest. `dir` must not exist or be
/// empty.
///
/// # Errors
/// [`SweepError::Folder`].
pub fn prepare(
    spec: &SweepSpec,
    points: &[PlannedPoint],
    sensitivity: Option<SensitivityDesign>,
    dir: &Path,
) -> Result<Manifest, SweepError> {
    if dir.exists() {
        let empty = std::fs::read_dir(dir)
            .map_err(|e| folder_err(dir, e))?
            .next()
            .is_none();
        if !empty {
            return Err(folder_err(
                dir,
                "not empty; choose another --out, or resume the sweep in it with: ncform sweep DIR --resume",
            ));
        }
    }
    std::fs::create_dir_all(dir.join("points")).map_err(|e| folder_err(dir, e))?;
    let sweep_text = std::fs::read(&spec.file).map_err(|e| folder_err(&spec.file, e))?;
    let mut listed = Vec::with_capacity(points.len());
    for p in points {
        let folder = format!("points/{:04}", p.index);
        let (case, _) = p
            .doc
            .write(&dir.join(&folder))
            .map_err(|e| folder_err(&dir.join(&folder), e))?;
        listed.push(ManifestPoint {
            index: p.index,
            folder,
            values: p
                .values
                .iter()
                .map(|(k, v)| (k.clone(), json_value(v)))
                .collect(),
            inputs_sha256: inputs_sha256(&case)?,
        });
    }
    let (binary, binary_sha256) = binary_identity();
    let manifest = Manifest {
        format: FORMAT.into(),
        units: crate::report::UNITS.into(),
        title: spec.title.clone(),
        sweep_file: absolute(&spec.file),
        sweep_sha256: sha256_hex(&sweep_text),
        case: absolute(&spec.case),
        ncform_version: env!("CARGO_PKG_VERSION").into(),
        binary,
        binary_sha256,
        created: now(),
        design: spec.design.name().into(),
        seed: spec.seed,
        count: spec.count,
        factors: points
            .first()
            .map(|p| p.values.iter().map(|(k, _)| k.clone()).collect())
            .unwrap_or_default(),
        fixed: spec
            .set
            .iter()
            .map(|(k, v)| (k.clone(), json_value(v)))
            .collect(),
        responses: spec.responses.clone(),
        constraints: spec.constraints.clone(),
        sensitivity,
        points: listed,
    };
    let text = serde_json::to_string_pretty(&manifest).map_err(|e| folder_err(dir, e))?;
    write_atomic(&manifest_path(dir), &text)?;
    Ok(manifest)
}

/// The absolute path, as text.
fn absolute(p: &Path) -> String {
    std::fs::canonicalize(p)
        .unwrap_or_else(|_| p.to_path_buf())
        .display()
        .to_string()
}

/// Where a point is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PointState {
    /// Being run (or killed while running: see [`Observed`]).
    Running,
    /// Ran to its end with every output written.
    Complete,
    /// Could not be built, stopped early or lost outputs: its error and
    /// exit code are recorded.
    Failed,
    /// Stopped by SIGINT or SIGTERM.
    Interrupted,
}

/// A point's `status.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct PointStatus {
    /// The state.
    pub state: PointState,
    /// The process that ran it.
    pub pid: u32,
    /// The host it ran on.
    pub host: String,
    /// The Slurm job and task (`1234_5`), when run by Slurm.
    pub slurm_job: Option<String>,
    /// When it started (UTC).
    pub started: String,
    /// When it ended (UTC).
    pub ended: Option<String>,
    /// Wall time of the run \[s\].
    pub wall_seconds: Option<f64>,
    /// `ncform run`'s exit code for this run (0 complete, 1 bad input,
    /// 3 stopped early, 4 interrupted, 5 outputs missing).
    pub exit_code: Option<u8>,
    /// The error or why it stopped.
    pub error: Option<String>,
    /// SHA-256 of the inputs it ran.
    pub inputs_sha256: String,
    /// SHA-256 of the binary that ran it.
    pub binary_sha256: String,
}

/// A point's status file.
pub fn status_path(point_dir: &Path) -> PathBuf {
    point_dir.join("status.json")
}

/// A point's status, if it has one.
pub fn read_status(point_dir: &Path) -> Option<PointStatus> {
    let text = std::fs::read_to_string(status_path(point_dir)).ok()?;
    serde_json::from_str(&text).ok()
}

/// Writes a point's status atomically.
///
/// # Errors
/// [`SweepError::Folder`].
pub fn write_status(point_dir: &Path, status: &PointStatus) -> Result<(), SweepError> {
    let text = serde_json::to_string_pretty(status).map_err(|e| folder_err(point_dir, e))?;
    write_atomic(&status_path(point_dir), &text)
}

/// This host's name.
pub fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|s| s.trim().to_string())
        .or_else(|_| std::env::var("HOSTNAME"))
        .unwrap_or_else(|_| "unknown".into())
}

/// What a point's folder says, checked against its inputs and the binary.
#[derive(Debug, Clone, PartialEq)]
pub enum Observed {
    /// Never started.
    Pending,
    /// Complete, and its inputs and binary are those it ran with.
    Complete,
    /// Complete, but its inputs or the binary changed since (what).
    Changed(String),
    /// Failed, with its error.
    Failed(String),
    /// Interrupted by a signal.
    Interrupted,
    /// Its status says running: killed, or still running elsewhere (a
    /// Slurm task: the job id).
    Running(Option<String>),
}

/// What the folder of point `index` says.
pub fn observe(dir: &Path, manifest: &Manifest, index: usize) -> Observed {
    let pdir = manifest.point_dir(dir, index);
    let Some(status) = read_status(&pdir) else {
        return Observed::Pending;
    };
    match status.state {
        PointState::Running => Observed::Running(status.slurm_job),
        PointState::Failed => Observed::Failed(status.error.unwrap_or_default()),
        PointState::Interrupted => Observed::Interrupted,
        PointState::Complete => {
            let (_, binary) = binary_identity();
            let inputs = inputs_sha256(&pdir.join("case.toml")).unwrap_or_else(|e| e.to_string());
            if inputs != status.inputs_sha256 {
                Observed::Changed("its inputs changed since it ran".into())
            } else if binary != status.binary_sha256 {
                Observed::Changed("it ran with another ncform binary".into())
            } else {
                Observed::Complete
            }
        }
    }
}

/// Groups point indices by what their folders say: `(complete, changed,
/// failed, interrupted, running, pending)`.
pub type Tally = BTreeMap<&'static str, Vec<usize>>;

/// The name of an observed state in `--status` and `results.csv`.
pub fn observed_name(o: &Observed) -> &'static str {
    match o {
        Observed::Pending => "pending",
        Observed::Complete => "complete",
        Observed::Changed(_) => "changed",
        Observed::Failed(_) => "failed",
        Observed::Interrupted => "interrupted",
        Observed::Running(_) => "running",
    }
}

/// Removes what an earlier attempt left in a point's folder (its run
/// folder, any `run.previous*` beside it, a status file), keeping the
/// case and its parameter files.
///
/// # Errors
/// [`SweepError::Folder`].
pub fn clean_point(point_dir: &Path) -> Result<(), SweepError> {
    let entries = std::fs::read_dir(point_dir).map_err(|e| folder_err(point_dir, e))?;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name == "run"
            || name.starts_with("run.previous")
            || name == "status.json"
            || name.contains(".tmp-")
        {
            let path = entry.path();
            let removed = if path.is_dir() {
                std::fs::remove_dir_all(&path)
            } else {
                std::fs::remove_file(&path)
            };
            removed
                .map_err(|e| folder_err(&path, format!("cannot remove an earlier attempt: {e}")))?;
        }
    }
    Ok(())
}

/// An exclusive lock on a sweep folder, held while a local sweep runs it,
/// so that a second `ncform sweep DIR` refuses instead of running the same
/// points. Released when dropped (or when the process dies).
#[derive(Debug)]
pub struct SweepLock {
    _file: std::fs::File,
}

impl SweepLock {
    /// Takes the lock on `dir`.
    ///
    /// # Errors
    /// [`SweepError::Folder`] when another process holds it.
    pub fn take(dir: &Path) -> Result<Self, SweepError> {
        let path = dir.join(".sweep.lock");
        let file = std::fs::OpenOptions::new()
            .create(true)
            .truncate(false)
            .write(true)
            .open(&path)
            .map_err(|e| folder_err(&path, e))?;
        #[cfg(unix)]
        {
            use std::os::fd::AsRawFd as _;
            // SAFETY: flock on a file descriptor this function owns.
            let r = unsafe { libc::flock(file.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
            if r != 0 {
                return Err(folder_err(
                    dir,
                    "another ncform sweep is running this folder; wait for it or stop it first",
                ));
            }
        }
        Ok(Self { _file: file })
    }
}
