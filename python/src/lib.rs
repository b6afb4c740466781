//! The extension module `ncform._ncform` behind the Python package
//! `ncform` (`python/ncform/__init__.py`): a case file edited by key
//! ([`PyCase`]), a run with the library's one runner into a run folder
//! ([`run_into`]: the interpreter lock released, Ctrl-C cancelling the
//! solve at its next safe point) and the run folder's CSV columns as
//! numpy arrays ([`read_csv`]).

use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::time::Duration;

use numpy::PyArray1;
use pyo3::IntoPyObjectExt;
use pyo3::create_exception;
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyList, PyString, PyTuple};

use ncform::case::Case;
use ncform::solver::CancelToken;

use ncform::study::keys::CaseDocument;

create_exception!(
    ncform,
    CaseError,
    PyValueError,
    "A case file that cannot be read, or a key that cannot be read or set; the message is what `ncform run` prints after `error: `."
);
create_exception!(
    ncform,
    RunError,
    PyRuntimeError,
    "A run that could not be set up (a mesh, a tool, the solver's set-up, the output folder); the message is what `ncform run` prints after `error: `."
);

/// How often the calling thread looks for signals (Ctrl-C) during a run.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// A case file, validated, with the key edits made to it.
#[pyclass(module = "ncform", name = "Case", frozen)]
struct PyCase {
    /// The case file as given.
    path: PathBuf,
    /// The case file as absolute path (to restore a pickled case in a
    /// process with another working directory).
    absolute: PathBuf,
    /// The state that can be edited.
    inner: std::sync::Mutex<Edited>,
}

/// A case document, its validated case and the edits that made it.
#[derive(Clone)]
struct Edited {
    doc: CaseDocument,
    case: Case,
    sets: Vec<(String, toml::Value)>,
}

impl PyCase {
    fn edited(&self) -> Edited {
        self.inner
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clone()
    }

    /// Reads and validates the case file `path` (the CLI's error message
    /// on failure).
    fn open(path: &Path) -> PyResult<Self> {
        let case = Case::load(path).map_err(|e| CaseError::new_err(e.to_string()))?;
        let doc = CaseDocument::load(path).map_err(|e| CaseError::new_err(e.to_string()))?;
        let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
        Ok(Self {
            path: path.to_path_buf(),
            absolute,
            inner: std::sync::Mutex::new(Edited {
                doc,
                case,
                sets: Vec::new(),
            }),
        })
    }

    fn apply(&self, key: &str, value: toml::Value) -> PyResult<()> {
        let mut edited = self.edited();
        edited
            .doc
            .set(key, value.clone())
            .map_err(|e| CaseError::new_err(e.to_string()))?;
        edited.case = edited
            .doc
            .case()
            .map_err(|e| CaseError::new_err(e.to_string()))?;
        edited.sets.push((key.to_string(), value));
        *self
            .inner
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner) = edited;
        Ok(())
    }
}

#[pymethods]
impl PyCase {
    /// `Case.load(path)`: the same as `ncform.load_case(path)`.
    #[staticmethod]
    fn load(path: PathBuf) -> PyResult<Self> {
        Self::open(&path)
    }

    /// The value of a case key (`loading.displacement`, `tool[1].mass`,
    /// `material.w6.s_ini`).
    fn get<'py>(&self, py: Python<'py>, key: &str) -> PyResult<Bound<'py, PyAny>> {
        let value = self
            .edited()
            .doc
            .get(key)
            .map_err(|e| CaseError::new_err(e.to_string()))?;
        to_python(py, &value)
    }

    /// Sets a case key to `value` (float, int, str, bool, list or dict);
    /// the case as edited must be valid, else `CaseError` and the case is
    /// unchanged.
    fn set(&self, key: &str, value: &Bound<'_, PyAny>) -> PyResult<()> {
        self.apply(key, to_toml(value)?)
    }

    /// The case file's text as edited.
    #[getter]
    fn text(&self) -> String {
        self.edited().doc.text()
    }

    /// Writes the case as edited (`case.toml`, with the parameter files it
    /// names) into `folder`; returns the case file's path.
    fn write(&self, folder: PathBuf) -> PyResult<PathBuf> {
        self.edited()
            .doc
            .write(&folder)
            .map(|(path, _inputs)| path)
            .map_err(|e| CaseError::new_err(e.to_string()))
    }

    /// The case file as given to `load_case`.
    #[getter]
    fn path(&self) -> PathBuf {
        self.path.clone()
    }

    /// The edits made, in order: `[(key, value), …]`.
    #[getter]
    fn sets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyList>> {
        let items = self
            .edited()
            .sets
            .iter()
            .map(|(k, v)| PyTuple::new(py, [k.into_bound_py_any(py)?, to_python(py, v)?]))
            .collect::<PyResult<Vec<_>>>()?;
        PyList::new(py, items)
    }

    /// The case's title.
    #[getter]
    fn title(&self) -> String {
        self.edited().case.title().to_string()
    }

    /// `"oat"` or `"forming"`.
    #[getter]
    fn kind(&self) -> &'static str {
        match self.edited().case {
            Case::Oat(_) => "oat",
            Case::Forming(_) => "forming",
        }
    }

    /// The case's warnings (unusual values, keys read but not used), as
    /// `ncform run` prints them after `warning: `.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.edited()
            .case
            .warnings()
            .iter()
            .map(ToString::to_string)
            .collect()
    }

    /// Pickling: the case file (as given and absolute) and the edits,
    /// replayed on unpickling (the case file must be readable there).
    fn __reduce__<'py>(slf: &Bound<'py, Self>) -> PyResult<Bound<'py, PyTuple>> {
        let py = slf.py();
        let this = slf.get();
        let restore = py.import("ncform._ncform")?.getattr("_restore_case")?;
        let args = (this.path.clone(), this.absolute.clone(), this.sets(py)?);
        PyTuple::new(py, [restore, args.into_bound_py_any(py)?])
    }

    fn __repr__(&self) -> String {
        let edited = self.edited();
        format!(
            "ncform.Case({:?}, title={:?}, edits={})",
            self.path.display().to_string(),
            edited.case.title(),
            edited.sets.len()
        )
    }
}

/// Unpickles a case: the file `path` (or `absolute` when `path` is not the
/// same file from here) with `sets` replayed.
#[pyfunction]
fn _restore_case(
    path: PathBuf,
    absolute: PathBuf,
    sets: Vec<(String, Bound<'_, PyAny>)>,
) -> PyResult<PyCase> {
    let same = match (path.canonicalize(), absolute.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    let case = PyCase::open(if same { &path } else { &absolute })?;
    for (key, value) in sets {
        case.apply(&key, to_toml(&value)?)?;
    }
    Ok(case)
}

/// Reads and validates a case file; `CaseError` with the message of
/// `ncform run` when it cannot.
#[pyfunction]
fn load_case(path: PathBuf) -> PyResult<PyCase> {
    PyCase::open(&path)
}

/// A Python value as a TOML value.
fn to_toml(value: &Bound<'_, PyAny>) -> PyResult<toml::Value> {
    if value.is_instance_of::<PyBool>() {
        return Ok(toml::Value::Boolean(value.extract()?));
    }
    if value.is_instance_of::<PyInt>() {
        return Ok(toml::Value::Integer(value.extract()?));
    }
    if value.is_instance_of::<PyFloat>() {
        return Ok(toml::Value::Float(value.extract()?));
    }
    if value.is_instance_of::<PyString>() {
        return Ok(toml::Value::String(value.extract()?));
    }
    if value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>() {
        return value
            .try_iter()?
            .map(|item| to_toml(&item?))
            .collect::<PyResult<Vec<_>>>()
            .map(toml::Value::Array);
    }
    if let Ok(dict) = value.cast::<PyDict>() {
        let mut table = toml::Table::new();
        for (k, v) in dict.iter() {
            table.insert(k.extract::<String>()?, to_toml(&v)?);
        }
        return Ok(toml::Value::Table(table));
    }
    // numpy scalars and other numbers.
    if let Ok(x) = value.extract::<f64>() {
        return Ok(toml::Value::Float(x));
    }
    Err(PyTypeError::new_err(format!(
        "a case value is a float, int, str, bool, list or dict, not {}",
        value.get_type().name()?
    )))
}

/// A TOML value as a Python value (a date-time as its text).
fn to_python<'py>(py: Python<'py>, value: &toml::Value) -> PyResult<Bound<'py, PyAny>> {
    match value {
        toml::Value::String(s) => s.into_bound_py_any(py),
        toml::Value::Integer(i) => i.into_bound_py_any(py),
        toml::Value::Float(x) => x.into_bound_py_any(py),
        toml::Value::Boolean(b) => b.into_bound_py_any(py),
        toml::Value::Datetime(d) => d.to_string().into_bound_py_any(py),
        toml::Value::Array(items) => {
            let items = items
                .iter()
                .map(|v| to_python(py, v))
                .collect::<PyResult<Vec<_>>>()?;
            PyList::new(py, items)?.into_bound_py_any(py)
        }
        toml::Value::Table(table) => {
            let dict = PyDict::new(py);
            for (k, v) in table {
                dict.set_item(k, to_python(py, v)?)?;
            }
            dict.into_bound_py_any(py)
        }
    }
}

/// Runs `case` with the library's one runner into the run folder `out`
/// (as `ncform run CASE --out OUT`), on `threads` worker threads (a rayon
/// pool of its own, and the explicit solver's threads; the default: all
/// cores), with the estimate and progress on stderr unless `quiet`.
///
/// The solve runs on a worker thread with the interpreter lock released;
/// the calling thread looks for signals every 50 ms, and on Ctrl-C
/// cancels the solve, waits for it to stop at its next safe point and
/// raises `KeyboardInterrupt`.
#[pyfunction]
#[pyo3(signature = (case, out, threads=None, quiet=true))]
fn run_into(
    py: Python<'_>,
    case: &Bound<'_, PyCase>,
    out: PathBuf,
    threads: Option<usize>,
    quiet: bool,
) -> PyResult<()> {
    let mut spec = case.get().edited().case;
    let pool = match threads {
        Some(0) => return Err(PyValueError::new_err("threads: at least 1")),
        Some(n) => {
            match &mut spec {
                Case::Oat(c) => c.explicit.threads = n,
                Case::Forming(c) => c.explicit.threads = n,
            }
            Some(
                rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| RunError::new_err(format!("cannot start {n} threads: {e}")))?,
            )
        }
        None => None,
    };
    let cancel = CancelToken::new();
    let (done, finished) = mpsc::channel::<()>();
    let worker = std::thread::Builder::new()
        .name("ncform-run".into())
        .spawn(move || {
            let job = || solve_into(&spec, &out, quiet, &cancel);
            let result = match pool {
                Some(pool) => pool.install(job),
                None => job(),
            };
            let _ = done.send(());
            result
        })
        .map_err(|e| RunError::new_err(format!("cannot start the run's thread: {e}")))?;
    let mut finished = finished;
    loop {
        let (waited, receiver) = py.detach(move || (finished.recv_timeout(SIGNAL_POLL), finished));
        finished = receiver;
        if !matches!(waited, Err(mpsc::RecvTimeoutError::Timeout)) {
            break;
        }
        if let Err(signal) = py.check_signals() {
            cancel.cancel();
            let _ = py.detach(|| worker.join());
            return Err(signal);
        }
    }
    match py.detach(|| worker.join()) {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(RunError::new_err(e)),
        Err(_) => Err(PyRuntimeError::new_err("the run panicked (see stderr)")),
    }
}

/// What `ncform run` does after reading the case
/// ([`ncform::cli::run::run_into_folder`]).
fn solve_into(spec: &Case, out: &Path, quiet: bool, cancel: &CancelToken) -> Result<(), String> {
    ncform::cli::run::run_into_folder(spec, out, quiet, cancel)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The columns of a CSV file that ncform writes (`#` comment lines, one
/// header line, numbers; an empty cell is NaN), as `{name: numpy array}`
/// in file order; the numbers are parsed from the file's digits.
#[pyfunction]
fn read_csv<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyDict>> {
    let text = std::fs::read_to_string(&path)
        .map_err(|e| PyValueError::new_err(format!("{}: {e}", path.display())))?;
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.starts_with('#') && !l.trim().is_empty());
    let names: Vec<&str> = match lines.next() {
        Some((_, header)) => header.split(',').collect(),
        None => Vec::new(),
    };
    let mut columns: Vec<Vec<f64>> = vec![Vec::new(); names.len()];
    for (n, line) in lines {
        let cells: Vec<&str> = line.split(',').collect();
        if cells.len() != names.len() {
            return Err(PyValueError::new_err(format!(
                "{}:{}: {} values for {} columns",
                path.display(),
                n + 1,
                cells.len(),
                names.len()
            )));
        }
        for (column, cell) in columns.iter_mut().zip(cells) {
            let cell = cell.trim();
            let x = if cell.is_empty() {
                f64::NAN
            } else {
                cell.parse().map_err(|_| {
                    PyValueError::new_err(format!(
                        "{}:{}: not a number: {cell:?}",
                        path.display(),
                        n + 1
                    ))
                })?
            };
            column.push(x);
        }
    }
    let dict = PyDict::new(py);
    for (name, column) in names.into_iter().zip(columns) {
        dict.set_item(name, PyArray1::from_vec(py, column))?;
    }
    Ok(dict)
}

/// The module `ncform._ncform`.
#[pymodule]
fn _ncform(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyCase>()?;
    m.add_function(wrap_pyfunction!(load_case, m)?)?;
    m.add_function(wrap_pyfunction!(run_into, m)?)?;
    m.add_function(wrap_pyfunction!(read_csv, m)?)?;
    m.add_function(wrap_pyfunction!(_restore_case, m)?)?;
    m.add("CaseError", m.py().get_type::<CaseError>())?;
    m.add("RunError", m.py().get_type::<RunError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
