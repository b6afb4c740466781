//! The fit file of `ncform fit` (TOML): the starting parameter set, the
//! free parameters with their bounds, the optimiser's knobs and the
//! tests — an OAT case each, with its measured files, their noise, an
//! optional displacement offset and the schedule of displacements the
//! fit compares at. Everything is checked here, before any simulation
//! runs; every error names the file, the line or key, the value and what
//! was expected. Key-by-key documentation: `docs/fit.md`, "The fit file".

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use serde::Deserialize;
use toml::Spanned;

use super::measured::{MeasuredCurve, MeasuredQuantity, Noise, Quantity, read_measured};
use crate::case::SolverKind;
use crate::case::forming::is_forming;
use crate::case::oat::{OatCase, load_params};
use crate::config::{ConfigError, TomlChecker, parse_toml, readable_number};
use crate::material::MaterialSpec;
use crate::material::params::{PARAMETER_MAX, PARAMETER_MIN};

pub use super::error::FitInputError;

/// How the optimiser moves a free parameter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scaling {
    /// In `ln p`: the bounds are both positive (`lower > 0`).
    Log,
    /// In `p`: the range includes 0 (`coupling.k_min`, `coupling.s11`,
    /// `c_mid`, `c_lock` may be 0).
    Linear,
}

/// A parameter the fit varies.
#[derive(Debug, Clone, PartialEq)]
pub struct FreeParameter {
    /// The key as a parameter file gives it (`w6.c_ini`).
    pub key: String,
    /// The starting set's value (MPa for moduli and stresses, `-` for
    /// `coupling.k_min`, `coupling.e11`, `i_lock`).
    pub start: f64,
    /// Lower bound, same unit.
    pub lower: f64,
    /// Upper bound, same unit.
    pub upper: f64,
    /// How the optimiser moves it.
    pub scaling: Scaling,
    /// 1-based line of the key in the fit file's `free` list.
    pub line: usize,
}

/// A test's displacement offset `δ` \[mm\] (slack): the simulated clamp
/// displacement `d` corresponds to the measured `d + δ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OffsetSpec {
    /// Whether the fit varies `δ` (else it stays at `start`).
    pub free: bool,
    /// Starting (or fixed) value \[mm\].
    pub start: f64,
    /// Lower bound \[mm\] (`start` for a fixed offset).
    pub lower: f64,
    /// Upper bound \[mm\] (`start` for a fixed offset).
    pub upper: f64,
}

/// One `[[test]]`: an OAT case, its measured data resampled to the
/// schedule.
#[derive(Debug, Clone)]
pub struct TestSpec {
    /// The test's name (default: the case file's stem), unique in the fit.
    pub name: String,
    /// The case file.
    pub case_path: PathBuf,
    /// The case, validated, with its material replaced by the fit's
    /// starting set ([`FitSpec::start`]).
    pub case: OatCase,
    /// The simulated clamp displacements the fit compares at \[mm\],
    /// increasing, in `(0, case.displacement]`.
    pub schedule: Vec<f64>,
    /// The measured quantities at the schedule, in the order of
    /// [`Quantity::ALL`]; the force always.
    pub measured: Vec<MeasuredQuantity>,
    /// The displacement offset (`None`: `δ = 0`).
    pub offset: Option<OffsetSpec>,
    /// The measured files (one per replicate specimen).
    pub measured_files: Vec<PathBuf>,
    /// 1-based line of the test's `case` key in the fit file.
    pub line: usize,
}

impl TestSpec {
    /// The measured data of `quantity`, if the test has it.
    pub fn quantity(&self, quantity: Quantity) -> Option<&MeasuredQuantity> {
        self.measured.iter().find(|m| m.quantity == quantity)
    }
}

/// The optimiser's and the forward solves' knobs (`[fit]`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitOptions {
    /// Schedule points per test when the test gives no `displacements`
    /// (default [`DEFAULT_POINTS`]).
    pub points: usize,
    /// Optimiser iterations (default [`DEFAULT_MAX_ITERATIONS`]).
    pub max_iterations: usize,
    /// Relative cost change or step size that stops the optimiser \[-\]
    /// (default [`DEFAULT_TOLERANCE`]).
    pub tolerance: f64,
    /// Residual tolerance of the forward solves in fit mode, relative to
    /// the reaction forces \[-\] (default [`DEFAULT_NEWTON_TOLERANCE`]).
    pub newton_tolerance: f64,
}

/// Default `[fit] points`.
pub const DEFAULT_POINTS: usize = 20;
/// Default `[fit] max_iterations`.
pub const DEFAULT_MAX_ITERATIONS: usize = 50;
/// Default `[fit] tolerance`.
pub const DEFAULT_TOLERANCE: f64 = 1e-6;
/// Default `[fit] newton_tolerance`.
pub const DEFAULT_NEWTON_TOLERANCE: f64 = 1e-9;
/// Default bound factor of a positive parameter: `[start/1000,
/// start·1000]`, within its admissible range.
pub const DEFAULT_BOUND_FACTOR: f64 = 1000.0;
/// Default half-width of a test's offset bounds, relative to the case's
/// final clamp displacement: `start ± 0.05·displacement`.
pub const DEFAULT_OFFSET_FRACTION: f64 = 0.05;

impl Default for FitOptions {
    fn default() -> Self {
        Self {
            points: DEFAULT_POINTS,
            max_iterations: DEFAULT_MAX_ITERATIONS,
            tolerance: DEFAULT_TOLERANCE,
            newton_tolerance: DEFAULT_NEWTON_TOLERANCE,
        }
    }
}

/// A validated fit file.
#[derive(Debug, Clone)]
pub struct FitSpec {
    /// The fit file.
    pub source: PathBuf,
    /// Title (default: the fit file's stem).
    pub title: String,
    /// The starting parameter set (law `ud-ncf`); every test's case runs
    /// with it in place of its own.
    pub start: MaterialSpec,
    /// The free parameters, in the order of `free`.
    pub free: Vec<FreeParameter>,
    /// The tests, in file order.
    pub tests: Vec<TestSpec>,
    /// The knobs of `[fit]`.
    pub options: FitOptions,
    /// Warnings to print before the fit (unusual values of the cases,
    /// cases whose own `params` the fit replaces, noise of quantities not
    /// measured, schedules shortened by a strain column).
    pub warnings: Vec<String>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FitRaw {
    title: Option<Spanned<String>>,
    params: Spanned<String>,
    free: Spanned<Vec<Spanned<String>>>,
    bounds: Option<BTreeMap<Spanned<String>, Spanned<Vec<f64>>>>,
    fit: Option<OptionsRaw>,
    #[serde(default)]
    test: Vec<TestRaw>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OptionsRaw {
    points: Option<Spanned<i64>>,
    max_iterations: Option<Spanned<i64>>,
    tolerance: Option<Spanned<f64>>,
    newton_tolerance: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct TestRaw {
    name: Option<Spanned<String>>,
    case: Spanned<String>,
    measured: Spanned<toml::Value>,
    noise: Option<Spanned<NoiseRaw>>,
    offset: Option<Spanned<OffsetRaw>>,
    displacements: Option<Spanned<Vec<f64>>>,
    quantities: Option<Spanned<Vec<Spanned<String>>>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct NoiseRaw {
    force: Option<Spanned<toml::Value>>,
    #[serde(rename = "E22")]
    e22: Option<Spanned<f64>>,
    shear_angle: Option<Spanned<f64>>,
    #[serde(rename = "E_perp")]
    e_perp: Option<Spanned<f64>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct OffsetRaw {
    free: Option<Spanned<bool>>,
    start: Option<Spanned<f64>>,
    bounds: Option<Spanned<Vec<f64>>>,
}

/// The admissible range of a `ud-ncf` parameter: `(lower, lower
/// excluded, upper)`, by the key's last part.
fn admissible(key: &str) -> (f64, bool, f64) {
    match key.rsplit('.').next().unwrap_or(key) {
        "c_mid" | "c_lock" | "s11" => (0.0, false, PARAMETER_MAX),
        "k_min" => (0.0, false, 1.0),
        "e11" => (1.0, false, PARAMETER_MAX),
        // c_ini, s_ini, delta_s_mid, i_lock
        _ => (0.0, true, PARAMETER_MAX),
    }
}

/// The admissible range as a message writes it: `(0, 1e12]`, `[0, 1]`.
fn admissible_text(key: &str) -> String {
    let (lo, open, hi) = admissible(key);
    format!(
        "{}{}, {}]",
        if open { "(" } else { "[" },
        readable_number(lo),
        if hi >= 1e6 {
            format!("{hi:e}")
        } else {
            readable_number(hi)
        }
    )
}

/// Whether `x` is in the admissible range of `key` (and, when not 0, of
/// a magnitude of at least [`PARAMETER_MIN`]).
fn is_admissible(key: &str, x: f64) -> bool {
    let (lo, open, hi) = admissible(key);
    x.is_finite()
        && (if open { x > lo } else { x >= lo })
        && x <= hi
        && (x == 0.0 || x.abs() >= PARAMETER_MIN)
}

/// The default bounds of `key` starting at `start`: `[0, 1]` for
/// `coupling.k_min`, `[1, max(100, 10·start)]` for `coupling.e11`, else
/// `[start/1000, start·1000]` within the admissible range; `None` for a
/// start of 0 (no scale to take a range from).
fn default_bounds(key: &str, start: f64) -> Option<(f64, f64)> {
    let (lo, _, hi) = admissible(key);
    match key.rsplit('.').next().unwrap_or(key) {
        "k_min" => Some((0.0, 1.0)),
        "e11" => Some((1.0, (10.0 * start).clamp(100.0, hi))),
        _ if start > 0.0 => Some((
            (start / DEFAULT_BOUND_FACTOR).max(lo).max(PARAMETER_MIN),
            (start * DEFAULT_BOUND_FACTOR).min(hi),
        )),
        _ => None,
    }
}

impl FitSpec {
    /// Reads and validates a fit file; relative paths in it are taken
    /// from its folder.
    ///
    /// # Errors
    /// As [`FitSpec::from_toml_str`], or an unreadable file.
    pub fn load(path: &Path) -> Result<FitSpec, FitInputError> {
        let source = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| ConfigError::NotFound {
            requested: format!("fit file '{source}'"),
            reason: e.to_string(),
        })?;
        let text = crate::config::utf8_text(bytes, &source)?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        Self::from_toml_str(&text, path, &base)
    }

    /// Parses and validates a fit file's `text`: `source` names it in
    /// messages, relative paths are taken from `base_dir`. Reads the
    /// starting set, every test's case and measured files, and resamples
    /// the measured data to the schedules.
    ///
    /// # Errors
    /// The first problem found, naming the file, the line or key, the
    /// value and what was expected (`docs/fit.md`, "What is refused").
    pub fn from_toml_str(
        text: &str,
        source: &Path,
        base_dir: &Path,
    ) -> Result<FitSpec, FitInputError> {
        let name = source.display().to_string();
        let raw: FitRaw = parse_toml(text, &name)?;
        let check = TomlChecker::new(text, &name);
        let title = match &raw.title {
            Some(t) => check.one_line(t, "title")?,
            None => source
                .file_stem()
                .map_or_else(|| name.clone(), |s| s.to_string_lossy().into_owned()),
        };
        let start = load_params(&check, &raw.params, "params", base_dir)?;
        if start.law_name() != "ud-ncf" {
            return Err(check
                .invalid(
                    check.line_of(&raw.params),
                    "params",
                    format!("\"{}\"", raw.params.get_ref()),
                    &format!(
                        "a parameter set of law \"ud-ncf\": fit supports law ud-ncf (this set is law \"{}\")",
                        start.law_name()
                    ),
                )
                .into());
        }
        let options = fit_options(&check, raw.fit.as_ref())?;
        let free = free_parameters(&check, &raw, &start)?;
        if raw.test.is_empty() {
            return Err(check
                .missing(
                    "[[test]]",
                    "at least one [[test]] table: an OAT case and its measured data",
                )
                .into());
        }
        let mut warnings = Vec::new();
        let mut tests: Vec<TestSpec> = Vec::with_capacity(raw.test.len());
        for (index, t) in raw.test.iter().enumerate() {
            let test = test_spec(&check, t, index, &start, base_dir, &options, &mut warnings)?;
            if let Some(other) = tests.iter().find(|o| o.name == test.name) {
                let line = t.name.as_ref().map_or(test.line, |n| check.line_of(n));
                return Err(check
                    .invalid(
                        line,
                        &format!("test[{index}].name"),
                        format!("\"{}\"", test.name),
                        &format!(
                            "a name no other test has (the test of line {} has it; give name = \"…\")",
                            other.line
                        ),
                    )
                    .into());
            }
            tests.push(test);
        }
        if free.is_empty() && !tests.iter().any(|t| t.offset.is_some_and(|o| o.free)) {
            return Err(check
                .invalid(
                    check.line_of(&raw.free),
                    "free",
                    "[]".into(),
                    "at least one parameter to fit (or a test with offset.free = true)",
                )
                .into());
        }
        warnings.splice(
            0..0,
            check.take_warnings().into_iter().map(|w| w.to_string()),
        );
        Ok(FitSpec {
            source: source.to_path_buf(),
            title,
            start,
            free,
            tests,
            options,
            warnings,
        })
    }
}

/// The `[fit]` table with its defaults.
fn fit_options(check: &TomlChecker, raw: Option<&OptionsRaw>) -> Result<FitOptions, ConfigError> {
    let mut options = FitOptions::default();
    let Some(raw) = raw else {
        return Ok(options);
    };
    if let Some(p) = &raw.points {
        options.points = check.count(p, "fit.points", 1..=10_000)?;
    }
    if let Some(n) = &raw.max_iterations {
        options.max_iterations = check.count(n, "fit.max_iterations", 1..=100_000)?;
    }
    let fraction = |v: &Spanned<f64>, key: &str| {
        check.range(
            v,
            key,
            |x| x > 0.0 && x < 1.0,
            "a relative tolerance in (0, 1)",
        )
    };
    if let Some(t) = &raw.tolerance {
        options.tolerance = fraction(t, "fit.tolerance")?;
    }
    if let Some(t) = &raw.newton_tolerance {
        options.newton_tolerance = fraction(t, "fit.newton_tolerance")?;
    }
    Ok(options)
}

/// The `free` list with the `[bounds]` table: keys of the starting set,
/// each once; bounds given or by default, containing the start.
fn free_parameters(
    check: &TomlChecker,
    raw: &FitRaw,
    start: &MaterialSpec,
) -> Result<Vec<FreeParameter>, ConfigError> {
    let values = start.parameter_values();
    let keys: Vec<&str> = values.iter().map(|(k, _)| k.as_str()).collect();
    let mut free: Vec<FreeParameter> = Vec::new();
    for key in raw.free.get_ref() {
        let line = check.line_of(key);
        let name = key.get_ref();
        let Some(&(_, value)) = values.iter().find(|(k, _)| k == name) else {
            let (term, part) = name.split_once('.').unwrap_or((name, ""));
            let note = if ["w4", "w6", "w8", "w11"].contains(&term)
                && ["s_ini", "c_mid", "delta_s_mid", "c_lock", "i_lock"].contains(&part)
            {
                format!(
                    " ({term} of the starting set {} has no {}: give a parameter file that has it to fit it)",
                    start.name,
                    if part.ends_with("lock") {
                        "lock (c_lock, i_lock)"
                    } else {
                        "transition (s_ini, c_mid, delta_s_mid)"
                    }
                )
            } else {
                String::new()
            };
            return Err(check.invalid(
                line,
                "free",
                format!("\"{name}\""),
                &format!(
                    "a parameter of the starting set {} (law ud-ncf){note}: one of {}",
                    start.name,
                    keys.join(", ")
                ),
            ));
        };
        if let Some(first) = free.iter().find(|f| &f.key == name) {
            return Err(check.invalid(
                line,
                "free",
                format!("\"{name}\""),
                &format!("each key once (it is also at line {})", first.line),
            ));
        }
        let given = raw
            .bounds
            .as_ref()
            .and_then(|b| b.iter().find(|(k, _)| k.get_ref() == name));
        let (lower, upper) = match given {
            Some((_, b)) => given_bounds(check, name, b, value)?,
            None => default_bounds(name, value).ok_or_else(|| {
                check.invalid(
                    line,
                    "free",
                    format!("\"{name}\""),
                    &format!(
                        "bounds for {name} in [bounds]: its start is 0, which gives no scale for the default range [start/1000, start·1000] (admissible: {})",
                        admissible_text(name)
                    ),
                )
            })?,
        };
        free.push(FreeParameter {
            key: name.clone(),
            start: value,
            lower,
            upper,
            scaling: if lower > 0.0 {
                Scaling::Log
            } else {
                Scaling::Linear
            },
            line,
        });
    }
    if let Some(bounds) = &raw.bounds
        && let Some((key, v)) = bounds
            .iter()
            .find(|(k, _)| !free.iter().any(|f| &f.key == k.get_ref()))
    {
        return Err(check.invalid(
            check.line_of(key),
            &format!("bounds.\"{}\"", key.get_ref()),
            shown_list(v.get_ref()),
            "bounds of a key listed in free",
        ));
    }
    Ok(free)
}

/// Given bounds `[lower, upper]` of `key`: finite, increasing, admissible,
/// containing the start.
fn given_bounds(
    check: &TomlChecker,
    key: &str,
    b: &Spanned<Vec<f64>>,
    start: f64,
) -> Result<(f64, f64), ConfigError> {
    let line = check.line_of(b);
    let name = format!("bounds.\"{key}\"");
    let shown = format!(
        "[{}]",
        b.get_ref()
            .iter()
            .map(|&x| readable_number(x))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let &[lower, upper] = b.get_ref().as_slice() else {
        return Err(check.invalid(line, &name, shown, "[lower, upper]: two numbers"));
    };
    if !(lower.is_finite() && upper.is_finite() && lower < upper) {
        return Err(check.invalid(
            line,
            &name,
            shown,
            "[lower, upper]: finite numbers, lower < upper",
        ));
    }
    if !(is_admissible(key, lower) && is_admissible(key, upper)) {
        return Err(check.invalid(
            line,
            &name,
            shown,
            &format!(
                "bounds within {key}'s admissible range {} (non-zero values of magnitude ≥ {PARAMETER_MIN:e})",
                admissible_text(key)
            ),
        ));
    }
    if !(lower <= start && start <= upper) {
        return Err(check.invalid(
            line,
            &name,
            shown,
            &format!(
                "bounds that contain the start {key} = {} of the starting set: a bound that excludes the start leaves the optimiser no admissible start",
                readable_number(start)
            ),
        ));
    }
    Ok((lower, upper))
}

/// A list of numbers as a message writes it.
fn shown_list(values: &[f64]) -> String {
    format!(
        "[{}]",
        values
            .iter()
            .map(|&x| readable_number(x))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// The `offset` of a test: free by default, start 0, bounds `start ±
/// 0.05·displacement` by default; finite, containing the start.
fn offset_spec(
    check: &TomlChecker,
    raw: &Spanned<OffsetRaw>,
    key: &str,
    displacement: f64,
) -> Result<OffsetSpec, ConfigError> {
    let o = raw.get_ref();
    let free = o.free.as_ref().is_none_or(|f| *f.get_ref());
    let start = match &o.start {
        None => 0.0,
        Some(s) => check.range(
            s,
            &format!("{key}.start"),
            |x| x.abs() < displacement,
            &format!(
                "an offset [mm] smaller in magnitude than the case's final clamp displacement {} mm",
                readable_number(displacement)
            ),
        )?,
    };
    let (lower, upper) = match (&o.bounds, free) {
        (Some(b), _) => {
            let line = check.line_of(b);
            let shown = shown_list(b.get_ref());
            let &[lower, upper] = b.get_ref().as_slice() else {
                return Err(check.invalid(
                    line,
                    &format!("{key}.bounds"),
                    shown,
                    "[lower, upper] [mm]: two numbers",
                ));
            };
            if !(lower.is_finite() && upper.is_finite() && lower < upper) {
                return Err(check.invalid(
                    line,
                    &format!("{key}.bounds"),
                    shown,
                    "[lower, upper] [mm]: finite numbers, lower < upper",
                ));
            }
            if !(lower <= start && start <= upper) {
                return Err(check.invalid(
                    line,
                    &format!("{key}.bounds"),
                    shown,
                    &format!(
                        "bounds that contain the offset's start {} mm (a bound that excludes the start)",
                        readable_number(start)
                    ),
                ));
            }
            if !free {
                return Err(check.invalid(
                    line,
                    &format!("{key}.bounds"),
                    shown,
                    "no bounds for a fixed offset (free = false): it stays at start",
                ));
            }
            (lower, upper)
        }
        (None, true) => {
            let half = DEFAULT_OFFSET_FRACTION * displacement;
            (start - half, start + half)
        }
        (None, false) => (start, start),
    };
    Ok(OffsetSpec {
        free,
        start,
        lower,
        upper,
    })
}

/// The file names of a test's `measured` key: a string or a non-empty
/// list of strings, each once.
fn measured_names(
    check: &TomlChecker,
    raw: &Spanned<toml::Value>,
    key: &str,
) -> Result<Vec<String>, ConfigError> {
    let line = check.line_of(raw);
    let expected = "a measured file (a string) or a list of them, one per replicate specimen";
    let names = match raw.get_ref() {
        toml::Value::String(s) => vec![s.clone()],
        toml::Value::Array(a) if !a.is_empty() => a
            .iter()
            .map(|v| match v {
                toml::Value::String(s) => Ok(s.clone()),
                other => Err(check.invalid(line, key, other.to_string(), expected)),
            })
            .collect::<Result<Vec<_>, _>>()?,
        other => return Err(check.invalid(line, key, other.to_string(), expected)),
    };
    for (i, n) in names.iter().enumerate() {
        if names[..i].contains(n) {
            return Err(check.invalid(
                line,
                key,
                format!("\"{n}\""),
                "each file once (a file given twice would count as two specimens)",
            ));
        }
    }
    Ok(names)
}

/// The noise of a test's quantities as given (`noise` table).
fn noise_given(
    check: &TomlChecker,
    raw: Option<&Spanned<NoiseRaw>>,
    key: &str,
) -> Result<BTreeMap<Quantity, (Noise, usize)>, ConfigError> {
    let mut out = BTreeMap::new();
    let Some(raw) = raw else {
        return Ok(out);
    };
    let n = raw.get_ref();
    if let Some(f) = &n.force {
        let line = check.line_of(f);
        let k = format!("{key}.force");
        let expected_number = "a number ≥ 0 [N] or [-] (finite)";
        let number = |v: &toml::Value, k: &str| -> Result<f64, ConfigError> {
            let x = match v {
                toml::Value::Float(x) => *x,
                toml::Value::Integer(i) => *i as f64,
                other => return Err(check.invalid(line, k, other.to_string(), expected_number)),
            };
            if x.is_finite() && x >= 0.0 {
                Ok(x)
            } else {
                Err(check.invalid(line, k, readable_number(x), expected_number))
            }
        };
        let noise = match f.get_ref() {
            toml::Value::Table(t) => {
                if let Some(unknown) = t.keys().find(|k| *k != "relative" && *k != "absolute") {
                    return Err(check.invalid(
                        line,
                        &format!("{k}.{unknown}"),
                        t[unknown].to_string(),
                        "no such key: force noise takes only: relative, absolute",
                    ));
                }
                let get = |name: &str| {
                    t.get(name)
                        .map_or(Ok(0.0), |v| number(v, &format!("{k}.{name}")))
                };
                Noise {
                    relative: get("relative")?,
                    absolute: get("absolute")?,
                }
            }
            v @ (toml::Value::Float(_) | toml::Value::Integer(_)) => Noise {
                relative: 0.0,
                absolute: number(v, &k)?,
            },
            other => {
                return Err(check.invalid(
                    line,
                    &k,
                    other.to_string(),
                    "a number (absolute noise [N]) or a table { relative, absolute }",
                ));
            }
        };
        if noise.relative == 0.0 && noise.absolute == 0.0 {
            return Err(check.invalid(
                line,
                &k,
                f.get_ref().to_string(),
                "a noise > 0: relative [-] and absolute [N] not both 0",
            ));
        }
        out.insert(Quantity::Force, (noise, line));
    }
    for (q, v) in [
        (Quantity::E22, &n.e22),
        (Quantity::ShearAngle, &n.shear_angle),
        (Quantity::EPerp, &n.e_perp),
    ] {
        if let Some(v) = v {
            let absolute = check.range(
                v,
                &format!("{key}.{}", q.name()),
                |x| x > 0.0,
                &format!("a noise > 0 [{}]", q.unit()),
            )?;
            out.insert(
                q,
                (
                    Noise {
                        relative: 0.0,
                        absolute,
                    },
                    check.line_of(v),
                ),
            );
        }
    }
    Ok(out)
}

/// The quantities a test fits (`quantities`): each a name of
/// [`Quantity::name`], each once, at least one; `None` when the key is
/// not given (every measured quantity).
fn quantities_given(
    check: &TomlChecker,
    raw: Option<&Spanned<Vec<Spanned<String>>>>,
    key: &str,
) -> Result<Option<Vec<Quantity>>, ConfigError> {
    let Some(raw) = raw else {
        return Ok(None);
    };
    let names = Quantity::ALL.map(|q| q.name()).join(", ");
    if raw.get_ref().is_empty() {
        return Err(check.invalid(
            check.line_of(raw),
            key,
            "[]".into(),
            &format!("at least one quantity to fit, of: {names}"),
        ));
    }
    let mut out: Vec<Quantity> = Vec::with_capacity(raw.get_ref().len());
    for name in raw.get_ref() {
        let line = check.line_of(name);
        let value = format!("\"{}\"", name.get_ref());
        let Some(q) = Quantity::ALL
            .into_iter()
            .find(|q| q.name() == name.get_ref().as_str())
        else {
            return Err(check.invalid(
                line,
                key,
                value,
                &format!("one of the quantities {names} (exactly so spelt)"),
            ));
        };
        if out.contains(&q) {
            return Err(check.invalid(line, key, value, "each quantity once"));
        }
        out.push(q);
    }
    Ok(Some(out))
}

/// One `[[test]]`.
fn test_spec(
    check: &TomlChecker,
    raw: &TestRaw,
    index: usize,
    start: &MaterialSpec,
    base_dir: &Path,
    options: &FitOptions,
    warnings: &mut Vec<String>,
) -> Result<TestSpec, FitInputError> {
    let key = |k: &str| format!("test[{index}].{k}");
    let case_line = check.line_of(&raw.case);
    let case_value = format!("\"{}\"", raw.case.get_ref());
    let case_path = base_dir.join(raw.case.get_ref());
    let (text, case_source, case_base) = crate::config::read_case_file(&case_path)
        .map_err(|e| check.referenced(case_line, &key("case"), &case_value, e))?;
    if is_forming(&text) {
        return Err(check
            .invalid(
                case_line,
                &key("case"),
                case_value,
                &format!(
                    "an off-axis tension test case ([specimen], [loading]): {case_source} is a forming case ([[ply]]), which the fit does not take"
                ),
            )
            .into());
    }
    let mut case = OatCase::from_toml_str(&text, &case_source, &case_base)
        .map_err(|e| check.referenced(case_line, &key("case"), &case_value, e))?;
    if case.solver_kind != SolverKind::QuasiStatic {
        return Err(check
            .invalid(
                case_line,
                &key("case"),
                case_value,
                &format!(
                    "an OAT case run by the quasi-static solver: the fit needs the quasi-static path, and {case_source} sets solver = \"explicit\" (remove that line for the fit)"
                ),
            )
            .into());
    }
    warnings.extend(case.warnings.iter().map(|w| w.to_string()));
    if case.material.material != start.material {
        warnings.push(format!(
            "{}:{case_line}: {} = {case_value}: the case's own parameters ({}) differ from the fit's params ({}); the fit runs the case with the fit's parameters in place of its own",
            check.source,
            key("case"),
            case.material.source,
            start.source
        ));
    }
    case.material = start.clone();
    let name = match &raw.name {
        Some(n) => {
            let name = check.one_line(n, &key("name"))?;
            if name.trim().is_empty() {
                return Err(check
                    .invalid(
                        check.line_of(n),
                        &key("name"),
                        "\"\"".into(),
                        "a non-empty name",
                    )
                    .into());
            }
            name
        }
        None => case_path.file_stem().map_or_else(
            || format!("test{index}"),
            |s| s.to_string_lossy().into_owned(),
        ),
    };
    let offset = raw
        .offset
        .as_ref()
        .map(|o| offset_spec(check, o, &key("offset"), case.displacement))
        .transpose()?;
    let (lo, hi) = offset.map_or((0.0, 0.0), |o| (o.lower, o.upper));
    let delta0 = offset.map_or(0.0, |o| o.start);
    let measured_line = check.line_of(&raw.measured);
    let names = measured_names(check, &raw.measured, &key("measured"))?;
    let mut curves: Vec<MeasuredCurve> = Vec::with_capacity(names.len());
    let mut measured_files = Vec::with_capacity(names.len());
    for file_name in &names {
        let path = base_dir.join(file_name);
        let refer = |cause: FitInputError| FitInputError::Referenced {
            fit: check.source.to_string(),
            line: measured_line,
            key: key("measured"),
            value: format!("\"{file_name}\""),
            cause: Box::new(cause),
        };
        let curve = read_measured(&path, case.bias_angle_deg).map_err(refer)?;
        check_rows(&curve, &case, lo.min(0.0)).map_err(refer)?;
        curves.push(curve);
        measured_files.push(path);
    }
    let noise_key = key("noise");
    let noise = noise_given(check, raw.noise.as_ref(), &noise_key)?;
    let noise_line = raw.noise.as_ref().map_or(case_line, |n| check.line_of(n));
    let quantities_key = key("quantities");
    let listed = quantities_given(check, raw.quantities.as_ref(), &quantities_key)?;
    // The quantities measured and fitted, their replicates' curves.
    let mut per_quantity: Vec<(Quantity, Vec<_>)> = Vec::new();
    for q in Quantity::ALL {
        let list: Vec<_> = curves.iter().filter_map(|c| c.curve(q)).collect();
        let wanted = listed.as_ref().is_none_or(|l| l.contains(&q));
        if let (Some(l), Some(raw_list)) = (&listed, &raw.quantities)
            && l.contains(&q)
            && list.is_empty()
        {
            let line = raw_list
                .get_ref()
                .iter()
                .find(|n| n.get_ref().as_str() == q.name())
                .map_or(check.line_of(raw_list), |n| check.line_of(n));
            return Err(check
                .invalid(
                    line,
                    &quantities_key,
                    format!("\"{}\"", q.name()),
                    &format!(
                        "quantities the measured files have: none of {} has the column {}{}",
                        shown_names(&names),
                        q.column(),
                        if q == Quantity::Force {
                            ""
                        } else {
                            " (or the DIC columns)"
                        }
                    ),
                )
                .into());
        }
        if wanted && !list.is_empty() {
            per_quantity.push((q, list));
        }
    }
    for (q, list) in &per_quantity {
        if list.len() < 2 && !noise.contains_key(q) {
            return Err(check
                .invalid(
                    noise_line,
                    &format!("{noise_key}.{}", q.name()),
                    "(missing)".into(),
                    &format!(
                        "a noise for {} [{}]: {} has the column {}{} and one specimen gives no scatter; give {noise_key}.{} or the files of more specimens",
                        q.name(),
                        q.unit(),
                        list[0].file.display(),
                        q.column(),
                        if curves.iter().any(|c| c.column(*q).is_some_and(|c| c.from_dic)) {
                            " (from the DIC columns)"
                        } else {
                            ""
                        },
                        q.name()
                    ),
                )
                .into());
        }
    }
    for (q, (_, line)) in &noise {
        if per_quantity.iter().any(|(p, _)| p == q) {
            continue;
        }
        let reason = if listed.as_ref().is_some_and(|l| !l.contains(q)) {
            format!("{} is not in {quantities_key}", q.name())
        } else {
            format!("no measured file of the test has {}", q.column())
        };
        warnings.push(format!(
            "{}:{line}: {noise_key}.{}: {reason}; the noise is ignored",
            check.source,
            q.name(),
        ));
    }
    // The range where every quantity of every replicate has values.
    let range_of = |list: &[super::measured::ReplicateCurve]| {
        list.iter()
            .fold((f64::NEG_INFINITY, f64::INFINITY), |(a, b), c| {
                let (first, last) = c.range();
                (a.max(first), b.min(last))
            })
    };
    let (mut first, mut last) = (f64::NEG_INFINITY, f64::INFINITY);
    for (_, list) in &per_quantity {
        let (a, b) = range_of(list);
        first = first.max(a);
        last = last.min(b);
    }
    let force_last = per_quantity
        .iter()
        .find(|(q, _)| *q == Quantity::Force)
        .map_or(last, |(_, l)| range_of(l).1);
    let schedule = match &raw.displacements {
        Some(list) => {
            let list_line = check.line_of(list);
            let values = list.get_ref();
            let k = key("displacements");
            if values.is_empty() {
                return Err(check
                    .invalid(list_line, &k, "[]".into(), "at least one displacement [mm]")
                    .into());
            }
            for (i, &d) in values.iter().enumerate() {
                let problem = if !(d.is_finite() && d > 0.0 && d <= case.displacement) {
                    Some(format!(
                        "displacements in (0, {}] mm (the case's final clamp displacement)",
                        readable_number(case.displacement)
                    ))
                } else if i > 0 && d <= values[i - 1] {
                    Some("displacements in increasing order, none repeated".to_string())
                } else if d + lo < first || d + hi > last {
                    Some(format!(
                        "displacements whose measured displacement d + offset (offset in [{}, {}] mm) lies in [{}, {}] mm, where every measured file has every quantity",
                        readable_number(lo),
                        readable_number(hi),
                        readable_number(first),
                        readable_number(last)
                    ))
                } else {
                    None
                };
                if let Some(expected) = problem {
                    return Err(check
                        .invalid(list_line, &k, readable_number(d), &expected)
                        .into());
                }
            }
            values.clone()
        }
        None => {
            let d_end = case.displacement.min(last - hi);
            let n = options.points;
            // From d_end/n, or from where the offset's lower bound still
            // finds measured data, evenly to d_end.
            let d_start = (d_end / n as f64).max(first - lo);
            let schedule: Vec<f64> = if n == 1 {
                vec![d_end]
            } else {
                (0..n)
                    .map(|k| d_start + (d_end - d_start) * k as f64 / (n - 1) as f64)
                    .collect()
            };
            let covered = if n == 1 {
                d_end + lo >= first
            } else {
                d_start < d_end
            };
            if !(d_end > 0.0 && covered) {
                return Err(check
                    .invalid(
                        measured_line,
                        &key("measured"),
                        shown_names(&names),
                        &format!(
                            "measured data covering the default schedule of {n} points up to {} mm (with the offset in [{}, {}] mm): every file has every quantity only in [{}, {}] mm; give {} or other offset bounds",
                            readable_number(d_end),
                            readable_number(lo),
                            readable_number(hi),
                            readable_number(first),
                            readable_number(last),
                            key("displacements")
                        ),
                    )
                    .into());
            }
            if last < force_last && last - hi < case.displacement {
                warnings.push(format!(
                    "{}:{measured_line}: {}: a strain column ends at {} mm, before the force ({} mm): the schedule ends at {} mm; leave the column out of {} to fit the force further",
                    check.source,
                    key("measured"),
                    readable_number(last),
                    readable_number(force_last),
                    readable_number(d_end),
                    key("quantities")
                ));
            }
            schedule
        }
    };
    let mut measured = Vec::with_capacity(per_quantity.len());
    for (q, list) in per_quantity {
        let noise = noise.get(&q).map(|(n, _)| *n);
        let m = MeasuredQuantity::new(q, list, &schedule, delta0, noise).ok_or_else(|| {
            check.invalid(
                measured_line,
                &key("measured"),
                shown_names(&names),
                &format!("{} measured over the whole schedule", q.column()),
            )
        })?;
        measured.push(m);
    }
    Ok(TestSpec {
        name,
        case_path,
        case,
        schedule,
        measured,
        offset,
        measured_files,
        line: case_line,
    })
}

/// File names as the fit file lists them.
fn shown_names(names: &[String]) -> String {
    format!(
        "[{}]",
        names
            .iter()
            .map(|n| format!("\"{n}\""))
            .collect::<Vec<_>>()
            .join(", ")
    )
}

/// The rows of a measured file against the case: no displacement below
/// `lowest` (0, or the offset's lower bound when that is negative) and
/// none beyond the case's final clamp displacement.
fn check_rows(curve: &MeasuredCurve, case: &OatCase, lowest: f64) -> Result<(), FitInputError> {
    let file = curve.path.display().to_string();
    for (&d, &line) in curve.displacement.iter().zip(&curve.lines) {
        if d < lowest {
            return Err(FitInputError::Cell {
                file,
                line,
                column: super::measured::DISPLACEMENT_COLUMN.into(),
                value: readable_number(d),
                expected: if lowest < 0.0 {
                    format!(
                        "expected a displacement ≥ {} mm (the offset's lower bound)",
                        readable_number(lowest)
                    )
                } else {
                    "expected a displacement ≥ 0 mm (or an offset whose bounds allow it)".into()
                },
            });
        }
        if d > case.displacement {
            return Err(FitInputError::Cell {
                file,
                line,
                column: super::measured::DISPLACEMENT_COLUMN.into(),
                value: readable_number(d),
                expected: format!(
                    "beyond the case's final clamp displacement {} mm ({} [loading] displacement); raise it or trim the file",
                    readable_number(case.displacement),
                    case.source
                ),
            });
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    const ROOT: &str = env!("CARGO_MANIFEST_DIR");

    /// A folder with the shipped OAT cases and two replicate files.
    fn folder() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        for case in [
            "oat30.toml",
            "oat45.toml",
            "oat60.toml",
            "oat45-explicit.toml",
            "hemisphere-0.toml",
        ] {
            std::fs::copy(format!("{ROOT}/cases/{case}"), dir.path().join(case)).unwrap();
        }
        write(dir.path(), "a.csv", &replicate(0.0, 80.0));
        write(dir.path(), "b.csv", &replicate(0.1, 80.0));
        dir
    }

    /// Rows every 2 mm up to `last`: force `0.04 d + shift` (plus a
    /// curvature), `E22 = 0.001 d + shift/10`.
    fn replicate(shift: f64, last: f64) -> String {
        let mut text = String::from("# specimen\ndisplacement [mm],force [N],E22 [-]\n");
        let mut d = 0.0;
        while d <= last {
            text.push_str(&format!(
                "{d},{},{}\n",
                0.04 * d + 1e-4 * d * d + shift,
                0.001 * d + shift / 10.0
            ));
            d += 2.0;
        }
        text
    }

    fn write(dir: &Path, name: &str, text: &str) {
        std::fs::write(dir.join(name), text).unwrap();
    }

    const GOOD: &str = r#"title = "test fit"
params = "schaefer2024"
free = ["w6.c_ini", "coupling.k_min"]

[[test]]
case = "oat30.toml"
measured = ["a.csv", "b.csv"]
noise = { force = { relative = 0.02, absolute = 0.01 } }
"#;

    fn load(dir: &Path, text: &str) -> Result<FitSpec, FitInputError> {
        write(dir, "fit.toml", text);
        FitSpec::load(&dir.join("fit.toml"))
    }

    fn refused(dir: &Path, text: &str) -> String {
        match load(dir, text) {
            Ok(_) => panic!("accepted:\n{text}"),
            Err(e) => e.to_string(),
        }
    }

    /// 1-based line of the first line of `text` holding `needle`.
    fn line(text: &str, needle: &str) -> usize {
        text.lines().position(|l| l.contains(needle)).unwrap() + 1
    }

    #[test]
    fn a_good_file_with_two_replicates() {
        let dir = folder();
        let spec = load(dir.path(), GOOD).unwrap();
        assert_eq!(spec.title, "test fit");
        assert_eq!(spec.options, FitOptions::default());
        assert!(spec.warnings.is_empty(), "{:?}", spec.warnings);
        let [c_ini, k_min] = &spec.free[..] else {
            panic!("{:?}", spec.free)
        };
        assert_eq!((c_ini.key.as_str(), c_ini.start), ("w6.c_ini", 0.14));
        assert!((c_ini.lower - 0.14e-3).abs() < 1e-15 && (c_ini.upper - 140.0).abs() < 1e-12);
        assert_eq!(c_ini.scaling, Scaling::Log);
        assert_eq!(c_ini.line, 3);
        assert_eq!(
            (k_min.lower, k_min.upper, k_min.scaling),
            (0.0, 1.0, Scaling::Linear)
        );
        let test = &spec.tests[0];
        assert_eq!(test.name, "oat30");
        assert_eq!(test.line, 6);
        assert_eq!(test.case.material, spec.start);
        assert_eq!(test.measured_files.len(), 2);
        assert_eq!(test.schedule.len(), 20);
        for (k, d) in test.schedule.iter().enumerate() {
            assert!((d - 4.0 * (k + 1) as f64).abs() < 1e-12);
        }
        let force = test.quantity(Quantity::Force).unwrap();
        assert_eq!(force.replicates, 2);
        // At d = 4: replicates 0.16 + 0.0016 and 0.1 more.
        let mean = 0.04 * 4.0 + 1e-4 * 16.0 + 0.05;
        assert!((force.values[0] - mean).abs() < 1e-12);
        let s = 0.1 / 2.0_f64.sqrt();
        let model = 0.02 * mean + 0.01;
        let sigma = (model * model / 2.0 + s * s / 2.0).sqrt();
        assert!((force.sigma[0] - sigma).abs() < 1e-12);
        // Rows every 2 mm, bins [d − 2, d + 2): the rows d − 2 and d, whose
        // line passes through the row at d: no curvature error, c = 1.
        assert!(force.interpolation_error < 1e-15);
        // E22 without noise, from the scatter: s/√2 = 0.01/2.
        let e22 = test.quantity(Quantity::E22).unwrap();
        assert!((e22.sigma[0] - 0.005).abs() < 1e-12);
        assert!(e22.interpolation_error < 1e-15);
        assert!(e22.sigma.iter().all(|&s| s >= e22.sigma_floor && s > 0.0));
        assert!(test.quantity(Quantity::ShearAngle).is_none());
    }

    #[test]
    fn several_tests_with_dic_data_and_a_short_strain_column() {
        let dir = folder();
        // OAT45: one specimen with DIC strains (uniaxial stretch along y).
        let mut dic = String::from("displacement [mm],force [N],Exx [-],Eyy [-],Exy [-]\n");
        for k in 0..=40 {
            let d = 2.0 * f64::from(k);
            dic.push_str(&format!(
                "{d},{},0,{},0\n",
                0.03 * d,
                0.5 * ((1.0 + d / 300.0).powi(2) - 1.0)
            ));
        }
        write(dir.path(), "dic45.csv", &dic);
        // OAT60: two specimens, the second's E22 ends at 50 mm.
        let mut short = String::from("displacement [mm],force [N],E22 [-]\n");
        for k in 0..=40 {
            let d = 2.0 * f64::from(k);
            let e22 = if d <= 50.0 {
                format!("{}", 0.001 * d)
            } else {
                String::new()
            };
            short.push_str(&format!("{d},{},{e22}\n", 0.02 * d));
        }
        write(dir.path(), "short60.csv", &short);
        let text = GOOD.to_string()
            + "\n[[test]]\nname = \"forty-five\"\ncase = \"oat45.toml\"\nmeasured = \"dic45.csv\"\n"
            + "noise = { force = 0.01, E22 = 0.002, shear_angle = 0.3, E_perp = 0.002 }\n"
            + "\n[[test]]\ncase = \"oat60.toml\"\nmeasured = [\"a.csv\", \"short60.csv\"]\n"
            + "noise = { force = 0.01 }\n";
        let spec = load(dir.path(), &text).unwrap();
        let names: Vec<&str> = spec.tests.iter().map(|t| t.name.as_str()).collect();
        assert_eq!(names, ["oat30", "forty-five", "oat60"]);
        let dic = &spec.tests[1];
        assert_eq!(dic.measured.len(), 4);
        let shear = dic.quantity(Quantity::ShearAngle).unwrap();
        let d = dic.schedule[9];
        let [_, expected, _] = crate::fit::measured::dic_to_measures(
            0.0,
            0.5 * ((1.0 + d / 300.0).powi(2) - 1.0),
            0.0,
            45.0,
        )
        .unwrap();
        assert!(
            (shear.values[9] - expected).abs() < 1e-4,
            "{} vs {expected}",
            shear.values[9]
        );
        // Two rows per bin, one at the point: the fit passes through it.
        assert!(shear.interpolation_error < 1e-12);
        let sixty = &spec.tests[2];
        assert_eq!(sixty.schedule.last(), Some(&50.0));
        let e22 = sixty.quantity(Quantity::E22).unwrap();
        assert_eq!(e22.replicates, 2);
        assert!(
            spec.warnings
                .iter()
                .any(|w| w.contains("test[2].measured: a strain column ends at 50 mm")),
            "{:?}",
            spec.warnings
        );
    }

    #[test]
    fn knobs_offset_and_explicit_schedule() {
        let dir = folder();
        let text = GOOD.to_string()
            + "offset = { free = true, start = 0.5, bounds = [-2.0, 2.0] }\n"
            + "displacements = [10.0, 20.0, 30.0]\n"
            + "[fit]\npoints = 5\nmax_iterations = 7\ntolerance = 1e-5\nnewton_tolerance = 1e-10\n";
        let spec = load(dir.path(), &text).unwrap();
        assert_eq!(
            spec.options,
            FitOptions {
                points: 5,
                max_iterations: 7,
                tolerance: 1e-5,
                newton_tolerance: 1e-10
            }
        );
        let test = &spec.tests[0];
        assert_eq!(test.schedule, vec![10.0, 20.0, 30.0]);
        assert_eq!(
            test.offset,
            Some(OffsetSpec {
                free: true,
                start: 0.5,
                lower: -2.0,
                upper: 2.0
            })
        );
        let force = test.quantity(Quantity::Force).unwrap();
        // Measured at 10.5 mm: the bin [5.5, 15.5) holds the rows 6 … 14,
        // whose linear fit of d² is 8 + 20 d − 100 (118 at 10.5, 110.25
        // true); the bound ½·f″·|fit of (d − 10.5)² at 10.5| = ½·2e-4·7.75
        // is that error exactly.
        let quadratic = 1e-4 * 118.0;
        assert!((force.values[0] - (0.04 * 10.5 + quadratic + 0.05)).abs() < 1e-12);
        assert!((force.interpolation_error - 1e-4 * 7.75).abs() < 1e-12);
        // The default schedule stops where the offset's upper bound still
        // finds measured data: 80 − 4 (default bounds ±0.05·80).
        let text = GOOD.to_string() + "offset = {}\n";
        let spec = load(dir.path(), &text).unwrap();
        let test = &spec.tests[0];
        assert_eq!(test.offset.map(|o| (o.lower, o.upper)), Some((-4.0, 4.0)));
        assert!((test.schedule[19] - 76.0).abs() < 1e-12);
        // … and starts where its lower bound still does: 0 + 4 mm.
        assert!((test.schedule[0] - 4.0).abs() < 1e-12);
        // With a free offset, an empty free list is accepted.
        let text = GOOD.replace(r#"free = ["w6.c_ini", "coupling.k_min"]"#, "free = []")
            + "offset = { free = true }\n";
        assert!(load(dir.path(), &text).unwrap().free.is_empty());
    }

    #[test]
    fn refuses_unknown_keys_listing_the_allowed_ones() {
        let dir = folder();
        let m = refused(dir.path(), &GOOD.replace("title", "titel"));
        assert!(
            m.contains("titel") && m.contains("params") && m.contains("line 1"),
            "{m}"
        );
        let m = refused(dir.path(), &(GOOD.to_string() + "scale = 2\n"));
        assert!(m.contains("scale") && m.contains("measured"), "{m}");
        let m = refused(
            dir.path(),
            &GOOD.replace("relative = 0.02", "relativ = 0.02"),
        );
        assert!(
            m.contains("relativ") && m.contains("relative, absolute"),
            "{m}"
        );
        let m = refused(
            dir.path(),
            &GOOD.replace("noise = {", "noise = { e22 = 0.1,"),
        );
        assert!(m.contains("e22") && m.contains("E22"), "{m}");
        let m = refused(dir.path(), &(GOOD.to_string() + "[fit]\npoint = 5\n"));
        assert!(m.contains("point") && m.contains("newton_tolerance"), "{m}");
    }

    #[test]
    fn refuses_free_keys_the_start_does_not_have() {
        let dir = folder();
        for (key, note) in [
            ("w6.c_inni", ""),
            ("svk.e1", ""),
            ("w6.c_lock", "has no lock"),
        ] {
            let text = GOOD.replace("\"coupling.k_min\"", &format!("\"{key}\""));
            let m = refused(dir.path(), &text);
            assert!(
                m.starts_with(&format!(
                    "{}:3: free = \"{key}\": expected a parameter of the starting set schaefer2024",
                    dir.path().join("fit.toml").display()
                )),
                "{m}"
            );
            assert!(m.contains("w8.delta_s_mid, ") && m.contains(note), "{m}");
        }
        let text = GOOD.replace("\"coupling.k_min\"", "\n  \"w6.c_ini\"");
        let m = refused(dir.path(), &text);
        assert!(
            m.contains(":4: free = \"w6.c_ini\": expected each key once (it is also at line 3)"),
            "{m}"
        );
        let text = GOOD.replace(r#"free = ["w6.c_ini", "coupling.k_min"]"#, "free = []");
        let m = refused(dir.path(), &text);
        assert!(
            m.contains(":3: free = []: expected at least one parameter"),
            "{m}"
        );
    }

    #[test]
    fn refuses_a_start_of_another_law() {
        let dir = folder();
        write(
            dir.path(),
            "svk.toml",
            "law = \"orthotropic-svk\"\n[svk]\ne1 = 100.0\ne2 = 1.0\nnu12 = 0.1\ng12 = 0.5\n",
        );
        let m = refused(
            dir.path(),
            &GOOD.replace("\"schaefer2024\"", "\"svk.toml\""),
        );
        assert!(m.contains(":2: params = \"svk.toml\": expected a parameter set of law \"ud-ncf\": fit supports law ud-ncf"), "{m}");
    }

    #[test]
    fn refuses_bad_bounds() {
        let dir = folder();
        let with = |b: &str| GOOD.to_string() + "[bounds]\n" + b + "\n";
        let m = refused(dir.path(), &with("\"w6.c_ini\" = [0.5, 10.0]"));
        assert!(m.contains(":10: bounds.\"w6.c_ini\" = [0.5, 10]: expected bounds that contain the start w6.c_ini = 0.14"), "{m}");
        assert!(m.contains("bound that excludes the start"), "{m}");
        let m = refused(dir.path(), &with("\"w6.c_ini\" = [1.0, 0.1]"));
        assert!(m.contains("lower < upper"), "{m}");
        let m = refused(dir.path(), &with("\"w6.c_ini\" = [0.0, 1.0]"));
        assert!(m.contains("admissible range (0, 1e12]"), "{m}");
        let m = refused(dir.path(), &with("\"coupling.k_min\" = [0.0, 2.0]"));
        assert!(m.contains("admissible range [0, 1]"), "{m}");
        let m = refused(dir.path(), &with("\"w8.c_ini\" = [0.1, 10.0]"));
        assert!(
            m.contains(
                ":10: bounds.\"w8.c_ini\" = [0.1, 10]: expected bounds of a key listed in free"
            ),
            "{m}"
        );
        let m = refused(dir.path(), &with("\"w6.c_ini\" = [0.1]"));
        assert!(m.contains("two numbers"), "{m}");
        let spec = load(dir.path(), &with("\"coupling.k_min\" = [0.1, 0.9]")).unwrap();
        assert_eq!(
            (spec.free[1].lower, spec.free[1].scaling),
            (0.1, Scaling::Log)
        );
    }

    #[test]
    fn refuses_a_forming_case_an_explicit_case_and_passes_on_case_errors() {
        let dir = folder();
        let fit = dir.path().join("fit.toml").display().to_string();
        let m = refused(dir.path(), &GOOD.replace("oat30.toml", "hemisphere-0.toml"));
        assert!(m.starts_with(&format!("{fit}:6: test[0].case = \"hemisphere-0.toml\": expected an off-axis tension test case")), "{m}");
        assert!(m.contains("forming case"), "{m}");
        let m = refused(
            dir.path(),
            &GOOD.replace("oat30.toml", "oat45-explicit.toml"),
        );
        assert!(
            m.contains(":6: test[0].case = \"oat45-explicit.toml\"") && m.contains("quasi-static"),
            "{m}"
        );
        let m = refused(dir.path(), &GOOD.replace("oat30.toml", "oat99.toml"));
        assert!(
            m.starts_with(&format!(
                "{fit}:6: test[0].case = \"oat99.toml\": case file"
            )),
            "{m}"
        );
        let broken = std::fs::read_to_string(dir.path().join("oat30.toml"))
            .unwrap()
            .replace("width = 100.0", "width = -1.0");
        write(dir.path(), "broken.toml", &broken);
        let m = refused(dir.path(), &GOOD.replace("oat30.toml", "broken.toml"));
        assert!(
            m.contains(":6: test[0].case = \"broken.toml\": ")
                && m.contains("broken.toml:8: specimen.width = -1"),
            "{m}"
        );
    }

    #[test]
    fn warns_when_the_case_has_other_parameters() {
        let dir = folder();
        let other = std::fs::read_to_string(dir.path().join("oat45.toml"))
            .unwrap()
            .replace(
                "params = \"schaefer2024\"",
                "params = \"schaefer2024-printed\"",
            );
        write(dir.path(), "printed.toml", &other);
        let spec = load(dir.path(), &GOOD.replace("oat30.toml", "printed.toml")).unwrap();
        assert_eq!(spec.warnings.len(), 1, "{:?}", spec.warnings);
        assert!(
            spec.warnings[0].contains("differ from the fit's params"),
            "{:?}",
            spec.warnings
        );
        assert_eq!(spec.tests[0].case.material, spec.start);
        assert_eq!(spec.tests[0].case.bias_angle_deg, 45.0);
    }

    #[test]
    fn quantities_select_what_is_fitted() {
        let dir = folder();
        // One specimen with force and E22, a noise for the force alone.
        let one = GOOD.replace("[\"a.csv\", \"b.csv\"]", "\"a.csv\"");
        let forces = one.clone() + "quantities = [\"force\"]\n";
        let spec = load(dir.path(), &forces).unwrap();
        let test = &spec.tests[0];
        assert_eq!(test.measured.len(), 1);
        assert!(test.quantity(Quantity::Force).is_some());
        assert!(test.quantity(Quantity::E22).is_none());
        assert!(spec.warnings.is_empty(), "{:?}", spec.warnings);
        // A noise for a quantity left out is ignored, with a warning.
        let text = forces.replace("absolute = 0.01 }", "absolute = 0.01 }, E22 = 0.002");
        let spec = load(dir.path(), &text).unwrap();
        assert!(
            spec.warnings.len() == 1
                && spec.warnings[0].contains("test[0].noise.E22: E22 is not in test[0].quantities"),
            "{:?}",
            spec.warnings
        );
        // Listed, E22 needs its noise; the default is every quantity.
        let m = refused(
            dir.path(),
            &(one.clone() + "quantities = [\"force\", \"E22\"]\n"),
        );
        assert!(m.contains("test[0].noise.E22 = (missing)"), "{m}");
        let spec = load(dir.path(), GOOD).unwrap();
        assert_eq!(spec.tests[0].measured.len(), 2);
        // Unknown, unmeasured, repeated, none.
        let m = refused(
            dir.path(),
            &(one.clone() + "quantities = [\"force\", \"shear\"]\n"),
        );
        assert!(
            m.contains(":9: test[0].quantities = \"shear\": expected one of the quantities force, E22, shear_angle, E_perp"),
            "{m}"
        );
        let m = refused(
            dir.path(),
            &(one.clone() + "quantities = [\"force\", \"shear_angle\"]\n"),
        );
        assert!(
            m.contains(":9: test[0].quantities = \"shear_angle\": expected quantities the measured files have: none of")
                && m.contains("shear_angle [deg]"),
            "{m}"
        );
        let m = refused(
            dir.path(),
            &(one.clone() + "quantities = [\"force\", \"force\"]\n"),
        );
        assert!(m.contains("\"force\": expected each quantity once"), "{m}");
        let m = refused(dir.path(), &(one.clone() + "quantities = []\n"));
        assert!(m.contains("test[0].quantities = []"), "{m}");
        // A short strain column does not shorten a forces-only schedule.
        let mut short = String::from("displacement [mm],force [N],E22 [-]\n");
        for k in 0..=40 {
            let d = 2.0 * f64::from(k);
            let e22 = if d <= 50.0 {
                format!("{}", 0.001 * d)
            } else {
                String::new()
            };
            short.push_str(&format!("{d},{},{e22}\n", 0.02 * d));
        }
        write(dir.path(), "short.csv", &short);
        let text = forces.replace("\"a.csv\"", "\"short.csv\"");
        let spec = load(dir.path(), &text).unwrap();
        assert_eq!(spec.tests[0].schedule.last(), Some(&80.0));
        let text = text.replace("quantities = [\"force\"]\n", "");
        assert!(refused(dir.path(), &text).contains("test[0].noise.E22 = (missing)"));
    }

    #[test]
    fn refuses_missing_noise_and_warns_of_unused_noise() {
        let dir = folder();
        let one = GOOD.replace("[\"a.csv\", \"b.csv\"]", "\"a.csv\"");
        let m = refused(dir.path(), &one);
        assert!(
            m.contains(":8: test[0].noise.E22 = (missing): expected a noise for E22 [-]"),
            "{m}"
        );
        let text = one.replace(
            "absolute = 0.01 }",
            "absolute = 0.01 }, E22 = 0.002, shear_angle = 0.5",
        );
        let spec = load(dir.path(), &text).unwrap();
        assert_eq!(spec.warnings.len(), 1);
        assert!(
            spec.warnings[0].contains("test[0].noise.shear_angle")
                && spec.warnings[0].contains("ignored"),
            "{:?}",
            spec.warnings
        );
        let e22 = spec.tests[0].quantity(Quantity::E22).unwrap();
        assert!(e22.sigma.iter().all(|&s| (s - 0.002).abs() < 1e-15));
        let m = refused(
            dir.path(),
            &GOOD.replace(
                "relative = 0.02, absolute = 0.01",
                "relative = 0, absolute = 0",
            ),
        );
        assert!(
            m.contains(":8: test[0].noise.force = ") && m.contains("not both 0"),
            "{m}"
        );
        let m = refused(
            dir.path(),
            &GOOD.replace("relative = 0.02", "relative = -0.02"),
        );
        assert!(m.contains("test[0].noise.force.relative = -0.02"), "{m}");
        let m = refused(dir.path(), &one.replace("} }", "}, E22 = 0.0 }"));
        assert!(
            m.contains(":8: test[0].noise.E22 = 0: expected a noise > 0 [-]"),
            "{m}"
        );
        // A plain number is the absolute force noise [N].
        let text = one.replace(
            "{ relative = 0.02, absolute = 0.01 } }",
            "0.05, E22 = 0.001 }",
        );
        let spec = load(dir.path(), &text).unwrap();
        let force = spec.tests[0].quantity(Quantity::Force).unwrap();
        assert_eq!(
            force.noise,
            Some(super::super::measured::Noise {
                relative: 0.0,
                absolute: 0.05
            })
        );
        assert!(force.sigma.iter().all(|&s| (s - 0.05).abs() < 1e-15));
    }

    #[test]
    fn refuses_measured_rows_beyond_the_case_or_below_the_offset() {
        let dir = folder();
        write(dir.path(), "b.csv", &replicate(0.1, 96.0));
        let m = refused(dir.path(), GOOD);
        let b = dir.path().join("b.csv").display().to_string();
        let case = dir.path().join("oat30.toml").display().to_string();
        // Row 82 mm is the 42nd data row: line 2 + 42.
        assert!(m.contains(":7: test[0].measured = \"b.csv\": "), "{m}");
        assert!(
            m.ends_with(&format!("{b}:44: displacement [mm] = 82: beyond the case's final clamp displacement 80 mm ({case} [loading] displacement); raise it or trim the file")),
            "{m}"
        );
        let mut shifted = String::from("displacement [mm],force [N]\n");
        for d in [-3.0, -1.0, 0.0, 10.0, 80.0] {
            shifted.push_str(&format!("{d},{}\n", 0.04 * d));
        }
        write(dir.path(), "b.csv", &shifted);
        let m = refused(dir.path(), GOOD);
        assert!(m.ends_with("b.csv:2: displacement [mm] = -3: expected a displacement ≥ 0 mm (or an offset whose bounds allow it)"), "{m}");
        let m = refused(
            dir.path(),
            &(GOOD.to_string() + "offset = { bounds = [-2.0, 2.0] }\n"),
        );
        assert!(m.ends_with("b.csv:2: displacement [mm] = -3: expected a displacement ≥ -2 mm (the offset's lower bound)"), "{m}");
        let noise = GOOD.replace("} }", "}, E22 = 0.001 }");
        let spec = load(dir.path(), &(noise + "offset = { bounds = [-4.0, 0.0] }\n")).unwrap();
        assert_eq!(spec.tests[0].schedule.last(), Some(&80.0));
    }

    #[test]
    fn refuses_bad_explicit_schedules_and_offsets() {
        let dir = folder();
        let with = |s: &str| GOOD.to_string() + s + "\n";
        let m = refused(dir.path(), &with("displacements = [10.0, 5.0]"));
        assert!(
            m.contains(":9: test[0].displacements = 5: expected displacements in increasing order"),
            "{m}"
        );
        let m = refused(dir.path(), &with("displacements = [10.0, 90.0]"));
        assert!(
            m.contains("test[0].displacements = 90: expected displacements in (0, 80] mm"),
            "{m}"
        );
        let m = refused(dir.path(), &with("displacements = [0.0, 10.0]"));
        assert!(m.contains("test[0].displacements = 0:"), "{m}");
        write(dir.path(), "b.csv", &replicate(0.1, 60.0));
        let m = refused(dir.path(), &with("displacements = [10.0, 70.0]"));
        assert!(
            m.contains(
                "test[0].displacements = 70: expected displacements whose measured displacement"
            ) && m.contains("[0, 60] mm"),
            "{m}"
        );
        // Without displacements, the schedule ends at the shorter file.
        let spec = load(dir.path(), GOOD).unwrap();
        assert_eq!(spec.tests[0].schedule.last(), Some(&60.0));
        let m = refused(
            dir.path(),
            &with("offset = { start = 3.0, bounds = [-1.0, 2.0] }"),
        );
        assert!(m.contains(":9: test[0].offset.bounds = [-1, 2]: expected bounds that contain the offset's start 3 mm"), "{m}");
        let m = refused(
            dir.path(),
            &with("offset = { free = false, bounds = [-1.0, 2.0] }"),
        );
        assert!(m.contains("no bounds for a fixed offset"), "{m}");
        let m = refused(dir.path(), &with("offset = { start = nan }"));
        assert!(m.contains("test[0].offset.start = nan"), "{m}");
    }

    #[test]
    fn refuses_bad_knobs_duplicate_names_and_no_test() {
        let dir = folder();
        let m = refused(dir.path(), &(GOOD.to_string() + "[fit]\npoints = 0\n"));
        assert!(
            m.contains(":10: fit.points = 0: expected a count in 1..=10000"),
            "{m}"
        );
        let m = refused(dir.path(), &(GOOD.to_string() + "[fit]\ntolerance = 0.0\n"));
        assert!(
            m.contains("fit.tolerance = 0: expected a relative tolerance in (0, 1)"),
            "{m}"
        );
        let twice = GOOD.to_string()
            + "\n[[test]]\ncase = \"oat30.toml\"\nmeasured = [\"a.csv\", \"b.csv\"]\n";
        let m = refused(dir.path(), &twice);
        assert!(
            m.contains(&format!(
                ":{}: test[1].name = \"oat30\": expected a name no other test has",
                line(&twice, "case") + 5
            )),
            "{m}"
        );
        let m = refused(dir.path(), &GOOD[..GOOD.find("[[test]]").unwrap()]);
        assert!(
            m.contains("[[test]] = (missing): expected at least one [[test]]"),
            "{m}"
        );
        let m = refused(
            dir.path(),
            &GOOD.replace("\"a.csv\", \"b.csv\"", "\"a.csv\", \"a.csv\""),
        );
        assert!(
            m.contains("test[0].measured = \"a.csv\": expected each file once"),
            "{m}"
        );
        let m = refused(dir.path(), &GOOD.replace("[\"a.csv\", \"b.csv\"]", "[]"));
        assert!(m.contains("test[0].measured = []"), "{m}");
        let m = refused(dir.path(), &GOOD.replace("\"b.csv\"", "\"c.csv\""));
        assert!(
            m.contains(":7: test[0].measured = \"c.csv\": ") && m.contains("c.csv: "),
            "{m}"
        );
    }
}
