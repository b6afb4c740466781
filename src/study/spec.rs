//! The sweep file: a base case, a design, the factors it varies, the
//! values it fixes, and the responses and constraints that `collect`
//! reads (`docs/studies.md`, "The sweep file").

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::design::Marginal;

/// Why a sweep file cannot be used. Every message names the file and the
/// key.
#[derive(Debug, Clone, thiserror::Error)]
pub enum SpecError {
    /// The file cannot be read or is not TOML of the sweep's tables.
    #[error("{file}: {reason}")]
    Read {
        /// The sweep file.
        file: String,
        /// Why.
        reason: String,
    },
    /// A value that is missing, of the wrong kind or out of range.
    #[error("{file}: {key}: {reason}")]
    Invalid {
        /// The sweep file.
        file: String,
        /// The key (`vary[1].range`, `design`).
        key: String,
        /// What is wrong and what was expected.
        reason: String,
    },
}

/// The design that places the points (`docs/studies.md`, "Designs").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum DesignKind {
    /// Every combination of the factors' levels.
    Grid,
    /// The base case, then each factor through its levels with the others
    /// at the base case's values.
    OneAtATime,
    /// A Latin hypercube of `count` points (McKay 1979).
    Lhs,
    /// `count` independent random points.
    MonteCarlo,
    /// Saltelli's scheme for Sobol' indices: `count` × (factors + 2)
    /// points.
    Sobol,
    /// Morris' elementary effects: `count` trajectories of factors + 1
    /// points on a `levels`-level grid.
    Morris,
}

impl DesignKind {
    /// The name in the sweep file.
    pub fn name(self) -> &'static str {
        match self {
            DesignKind::Grid => "grid",
            DesignKind::OneAtATime => "one-at-a-time",
            DesignKind::Lhs => "lhs",
            DesignKind::MonteCarlo => "monte-carlo",
            DesignKind::Sobol => "sobol",
            DesignKind::Morris => "morris",
        }
    }

    /// Whether the design takes discrete levels (values, or a range with
    /// a count) rather than intervals and distributions.
    pub fn takes_levels(self) -> bool {
        matches!(self, DesignKind::Grid | DesignKind::OneAtATime)
    }
}

/// How a factor's values are given.
#[derive(Debug, Clone, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Levels {
    /// Listed values (any TOML type), for grid and one-at-a-time.
    Values(Vec<toml::Value>),
    /// `range = [lo, hi, n]`: n evenly spaced levels from lo to hi (grid,
    /// one-at-a-time), or `range = [lo, hi]`: the interval (sampling
    /// designs, uniform).
    Range {
        /// Lower end.
        lo: f64,
        /// Upper end.
        hi: f64,
        /// Levels, for the level designs.
        n: Option<usize>,
    },
    /// A distribution, for the sampling designs.
    Distribution(#[serde(skip)] Marginal, String),
}

impl Levels {
    /// The discrete levels (values, or the n levels of a range).
    pub fn discrete(&self) -> Option<Vec<toml::Value>> {
        match self {
            Levels::Values(v) => Some(v.clone()),
            Levels::Range { lo, hi, n: Some(n) } => Some(
                (0..*n)
                    .map(|i| {
                        let t = if *n == 1 {
                            0.0
                        } else {
                            i as f64 / (*n - 1) as f64
                        };
                        toml::Value::Float(lo + t * (hi - lo))
                    })
                    .collect(),
            ),
            _ => None,
        }
    }

    /// The marginal a unit-cube coordinate is mapped through.
    pub fn marginal(&self) -> Option<Marginal> {
        match self {
            Levels::Range { lo, hi, .. } => Some(Marginal::Uniform { lo: *lo, hi: *hi }),
            Levels::Distribution(m, _) => Some(m.clone()),
            Levels::Values(_) => None,
        }
    }
}

/// One varied key.
#[derive(Debug, Clone, Serialize)]
pub struct Factor {
    /// The case key (`tool[1].mass`, `material.w6.s_ini`).
    pub key: String,
    /// Its levels, interval or distribution.
    pub levels: Levels,
}

/// Factors drawn jointly from the correlated normal distribution a fit
/// reports (`fit.json`: values, σ and the correlation matrix).
#[derive(Debug, Clone, Serialize)]
pub struct Correlated {
    /// The fit's `fit.json`.
    pub fit: PathBuf,
    /// The case keys, in the fit's parameter order of those used.
    pub keys: Vec<String>,
    /// Means (the fitted values).
    pub mean: Vec<f64>,
    /// Standard deviations (σ × `scale`).
    pub sd: Vec<f64>,
    /// The correlation matrix of those parameters.
    pub correlation: Vec<Vec<f64>>,
}

/// A value read from each point's results for `collect`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Response {
    /// The column name.
    pub name: String,
    /// Where: a `summary.json` path, or a history column at a load.
    pub source: ResponseSource,
}

/// Where a response is read.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ResponseSource {
    /// A path into `summary.json` (`forces[1][1]`, `defects.final.…`).
    Summary(String),
    /// A column of the run's history CSV at a value of another column
    /// (linear interpolation): the column, the abscissa column, the value.
    History {
        /// The column read.
        column: String,
        /// The column it is read at (default the first).
        at_column: Option<String>,
        /// The value of that column.
        at: f64,
    },
}

/// A pass/fail limit on a response or result column.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Constraint {
    /// The column (a response's name or a result's).
    pub column: String,
    /// Feasible only at or above.
    pub min: Option<f64>,
    /// Feasible only at or below.
    pub max: Option<f64>,
}

/// A parsed sweep file.
#[derive(Debug, Clone, Serialize)]
pub struct SweepSpec {
    /// The sweep file.
    pub file: PathBuf,
    /// The title (default: the file's stem).
    pub title: String,
    /// The base case file.
    pub case: PathBuf,
    /// The design.
    pub design: DesignKind,
    /// Seed of the random designs.
    pub seed: u64,
    /// Points (lhs, monte-carlo), base sample (sobol) or trajectories
    /// (morris).
    pub count: Option<usize>,
    /// Grid levels of a Morris design.
    pub levels: usize,
    /// Values fixed for every point, in order.
    pub set: Vec<(String, toml::Value)>,
    /// The varied factors, in order.
    pub vary: Vec<Factor>,
    /// Factors drawn from a fit's correlated distribution.
    pub correlated: Option<Correlated>,
    /// Responses read by `collect`.
    pub responses: Vec<Response>,
    /// Constraints judged by `collect`.
    pub constraints: Vec<Constraint>,
    /// The most points the design may make.
    pub max_points: usize,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSweep {
    title: Option<String>,
    case: Option<String>,
    design: Option<String>,
    seed: Option<i64>,
    count: Option<i64>,
    levels: Option<i64>,
    max_points: Option<i64>,
    #[serde(default)]
    set: Vec<RawSet>,
    #[serde(default)]
    vary: Vec<RawVary>,
    correlated: Option<RawCorrelated>,
    #[serde(default)]
    response: Vec<RawResponse>,
    #[serde(default)]
    constraint: Vec<RawConstraint>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSet {
    key: String,
    value: toml::Value,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawVary {
    key: String,
    values: Option<Vec<toml::Value>>,
    range: Option<Vec<f64>>,
    distribution: Option<String>,
    mean: Option<f64>,
    sd: Option<f64>,
    median: Option<f64>,
    sigma_log: Option<f64>,
    lo: Option<f64>,
    hi: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawCorrelated {
    fit: String,
    prefix: Option<String>,
    parameters: Option<Vec<String>>,
    scale: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawResponse {
    name: String,
    summary: Option<String>,
    history: Option<String>,
    at_column: Option<String>,
    at: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawConstraint {
    column: String,
    min: Option<f64>,
    max: Option<f64>,
}

/// The largest number of points a sweep makes unless `max_points` says
/// otherwise.
pub const DEFAULT_MAX_POINTS: usize = 100_000;

impl SweepSpec {
    /// Reads and checks the sweep file `path` (the keys it varies are
    /// checked against the case later, point by point, by
    /// [`super::sweep::plan`]).
    ///
    /// # Errors
    /// [`SpecError`] naming the file and the key.
    pub fn load(path: &Path) -> Result<Self, SpecError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SpecError::Read {
            file: file.clone(),
            reason: format!("cannot read the sweep file: {e}"),
        })?;
        let raw: RawSweep = toml::from_str(&text).map_err(|e| SpecError::Read {
            file: file.clone(),
            reason: e.to_string().trim().replace('\n', " "),
        })?;
        let base = path.parent().unwrap_or(Path::new(".")).to_path_buf();
        let invalid = |key: &str, reason: String| SpecError::Invalid {
            file: file.clone(),
            key: key.to_string(),
            reason,
        };
        let case = raw.case.ok_or_else(|| {
            invalid(
                "case",
                "missing; expected the base case file, relative to the sweep file".into(),
            )
        })?;
        let case = base.join(case);
        if !case.is_file() {
            return Err(invalid(
                "case",
                format!("'{}' is not a readable file", case.display()),
            ));
        }
        let design = match raw.design.as_deref().unwrap_or("grid") {
            "grid" => DesignKind::Grid,
            "one-at-a-time" => DesignKind::OneAtATime,
            "lhs" => DesignKind::Lhs,
            "monte-carlo" => DesignKind::MonteCarlo,
            "sobol" => DesignKind::Sobol,
            "morris" => DesignKind::Morris,
            other => {
                return Err(invalid(
                    "design",
                    format!(
                        "\"{other}\"; expected \"grid\", \"one-at-a-time\", \"lhs\", \"monte-carlo\", \"sobol\" or \"morris\""
                    ),
                ));
            }
        };
        let seed = match raw.seed {
            None => 1,
            Some(s) if s >= 0 => s as u64,
            Some(s) => return Err(invalid("seed", format!("{s}; expected a whole number ≥ 0"))),
        };
        let positive = |key: &str, v: Option<i64>| -> Result<Option<usize>, SpecError> {
            match v {
                None => Ok(None),
                Some(n) if n >= 1 => Ok(Some(n as usize)),
                Some(n) => Err(invalid(key, format!("{n}; expected a whole number ≥ 1"))),
            }
        };
        let count = positive("count", raw.count)?;
        let levels = positive("levels", raw.levels)?.unwrap_or(4);
        let max_points = positive("max_points", raw.max_points)?.unwrap_or(DEFAULT_MAX_POINTS);
        if matches!(
            design,
            DesignKind::Lhs | DesignKind::MonteCarlo | DesignKind::Sobol | DesignKind::Morris
        ) && count.is_none()
        {
            return Err(invalid(
                "count",
                format!(
                    "missing; design \"{}\" needs a count (points for lhs and monte-carlo, the base sample for sobol, trajectories for morris)",
                    design.name()
                ),
            ));
        }
        if design == DesignKind::Morris && (levels < 2 || levels % 2 == 1) {
            return Err(invalid(
                "levels",
                format!("{levels}; expected an even number ≥ 2"),
            ));
        }
        let set = raw
            .set
            .into_iter()
            .map(|s| (s.key, s.value))
            .collect::<Vec<_>>();
        let mut vary = Vec::new();
        for (i, v) in raw.vary.into_iter().enumerate() {
            let key = |k: &str| format!("vary[{i}].{k}");
            let levels =
                vary_levels(&v, design, &key).map_err(|(k, reason)| invalid(&k, reason))?;
            if vary.iter().any(|f: &Factor| f.key == v.key) {
                return Err(invalid(
                    &key("key"),
                    format!("\"{}\" is varied twice", v.key),
                ));
            }
            vary.push(Factor { key: v.key, levels });
        }
        let correlated = match raw.correlated {
            None => None,
            Some(c) => Some(correlated(&c, &base).map_err(|(k, reason)| invalid(&k, reason))?),
        };
        if let Some(c) = &correlated {
            if !matches!(design, DesignKind::Lhs | DesignKind::MonteCarlo) {
                return Err(invalid(
                    "correlated",
                    format!(
                        "design \"{}\" draws no samples; expected design = \"lhs\" or \"monte-carlo\"",
                        design.name()
                    ),
                ));
            }
            if let Some(k) = c.keys.iter().find(|k| vary.iter().any(|f| &f.key == *k)) {
                return Err(invalid(
                    "correlated",
                    format!("\"{k}\" is also in a [[vary]] table"),
                ));
            }
        }
        if vary.is_empty() && correlated.is_none() {
            return Err(invalid(
                "vary",
                "no [[vary]] table; expected at least one factor".into(),
            ));
        }
        let responses = raw
            .response
            .into_iter()
            .enumerate()
            .map(|(i, r)| {
                let source = match (r.summary, r.history, r.at) {
                    (Some(s), None, None) => ResponseSource::Summary(s),
                    (None, Some(column), Some(at)) => ResponseSource::History {
                        column,
                        at_column: r.at_column,
                        at,
                    },
                    _ => {
                        return Err(invalid(
                            &format!("response[{i}]"),
                            "expected either summary = \"a.summary.path\" or history = \"column\" with at = value".into(),
                        ));
                    }
                };
                Ok(Response {
                    name: r.name,
                    source,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let constraints = raw
            .constraint
            .into_iter()
            .enumerate()
            .map(|(i, c)| {
                if c.min.is_none() && c.max.is_none() {
                    return Err(invalid(
                        &format!("constraint[{i}]"),
                        "neither min nor max; expected at least one".into(),
                    ));
                }
                Ok(Constraint {
                    column: c.column,
                    min: c.min,
                    max: c.max,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let title = raw.title.unwrap_or_else(|| {
            path.file_stem()
                .map_or_else(|| "sweep".into(), |s| s.to_string_lossy().into_owned())
        });
        Ok(Self {
            file: path.to_path_buf(),
            title,
            case,
            design,
            seed,
            count,
            levels,
            set,
            vary,
            correlated,
            responses,
            constraints,
            max_points,
        })
    }
}

/// A `[[vary]]` table's levels for `design`, or the key and what is
/// wrong.
fn vary_levels(
    v: &RawVary,
    design: DesignKind,
    key: &dyn Fn(&str) -> String,
) -> Result<Levels, (String, String)> {
    let given = [
        v.values.is_some(),
        v.range.is_some(),
        v.distribution.is_some(),
    ]
    .iter()
    .filter(|&&b| b)
    .count();
    if given != 1 {
        return Err((
            key("key"),
            format!(
                "\"{}\": expected exactly one of values = [...], range = [lo, hi, n] or distribution = \"...\"",
                v.key
            ),
        ));
    }
    let finite = |k: &str, x: Option<f64>| -> Result<f64, (String, String)> {
        match x {
            Some(x) if x.is_finite() => Ok(x),
            Some(x) => Err((key(k), format!("{x}; expected a finite number"))),
            None => Err((
                key(k),
                format!(
                    "missing for distribution \"{}\"",
                    v.distribution.as_deref().unwrap_or("")
                ),
            )),
        }
    };
    let levels = if let Some(values) = &v.values {
        if values.is_empty() {
            return Err((key("values"), "empty; expected at least one value".into()));
        }
        Levels::Values(values.clone())
    } else if let Some(range) = &v.range {
        let (lo, hi, n) = match range.as_slice() {
            [lo, hi] => (*lo, *hi, None),
            [lo, hi, n] if *n >= 1.0 && n.fract() == 0.0 => (*lo, *hi, Some(*n as usize)),
            _ => {
                return Err((
                    key("range"),
                    format!(
                        "{range:?}; expected [lo, hi, n] with n a whole number ≥ 1, or [lo, hi]"
                    ),
                ));
            }
        };
        if !lo.is_finite() || !hi.is_finite() || lo > hi {
            return Err((
                key("range"),
                format!("[{lo}, {hi}]: expected finite lo ≤ hi"),
            ));
        }
        Levels::Range { lo, hi, n }
    } else {
        let name = v.distribution.clone().unwrap_or_default();
        let m = match name.as_str() {
            "uniform" => Marginal::Uniform {
                lo: finite("lo", v.lo)?,
                hi: finite("hi", v.hi)?,
            },
            "normal" => Marginal::Normal {
                mean: finite("mean", v.mean)?,
                sd: finite("sd", v.sd)?,
            },
            "lognormal" => Marginal::LogNormal {
                median: finite("median", v.median)?,
                sigma_log: finite("sigma_log", v.sigma_log)?,
            },
            other => {
                return Err((
                    key("distribution"),
                    format!("\"{other}\"; expected \"uniform\", \"normal\" or \"lognormal\""),
                ));
            }
        };
        m.validate()
            .map_err(|e| (key("distribution"), e.to_string()))?;
        Levels::Distribution(m, name)
    };
    match (&levels, design.takes_levels()) {
        (Levels::Values(_), true) | (Levels::Range { n: Some(_), .. }, true) => {}
        (Levels::Range { n: None, .. }, true) | (Levels::Distribution(..), true) => {
            return Err((
                key("range"),
                format!(
                    "design \"{}\" takes levels; expected values = [...] or range = [lo, hi, n]",
                    design.name()
                ),
            ));
        }
        (Levels::Values(_), false) => {
            return Err((
                key("values"),
                format!(
                    "design \"{}\" samples intervals; expected range = [lo, hi] or a distribution",
                    design.name()
                ),
            ));
        }
        (Levels::Distribution(..), false) if design == DesignKind::Morris => {
            return Err((
                key("distribution"),
                "a Morris design takes range = [lo, hi]".into(),
            ));
        }
        _ => {}
    }
    Ok(levels)
}

#[derive(Deserialize)]
struct FitJsonParameter {
    value: f64,
    sigma: f64,
}

#[derive(Deserialize)]
struct FitJson {
    parameters: std::collections::BTreeMap<String, FitJsonParameter>,
    parameter_order: Vec<String>,
    correlation: Vec<Vec<f64>>,
}

/// The `[correlated]` table: the fit's values, σ and correlation for the
/// parameters chosen, as case keys (`prefix` + `.` + the fit's key).
fn correlated(c: &RawCorrelated, base: &Path) -> Result<Correlated, (String, String)> {
    let path = base.join(&c.fit);
    let text = std::fs::read_to_string(&path).map_err(|e| {
        (
            "correlated.fit".to_string(),
            format!(
                "'{}': {e}; expected a fit.json written by ncform fit",
                path.display()
            ),
        )
    })?;
    let fit: FitJson = serde_json::from_str(&text).map_err(|e| {
        (
            "correlated.fit".to_string(),
            format!(
                "'{}': {e}; expected a fit.json written by ncform fit",
                path.display()
            ),
        )
    })?;
    let n = fit.parameter_order.len();
    if fit.correlation.len() != n || fit.correlation.iter().any(|r| r.len() != n) {
        return Err((
            "correlated.fit".into(),
            format!(
                "'{}': the correlation matrix is not {n} × {n} (did the fit converge?)",
                path.display()
            ),
        ));
    }
    let chosen = c
        .parameters
        .clone()
        .unwrap_or_else(|| fit.parameter_order.clone());
    let mut index = Vec::new();
    for p in &chosen {
        let i = fit
            .parameter_order
            .iter()
            .position(|q| q == p)
            .ok_or_else(|| {
                (
                    "correlated.parameters".to_string(),
                    format!(
                        "\"{p}\" is not a parameter of the fit ({})",
                        fit.parameter_order.join(", ")
                    ),
                )
            })?;
        index.push(i);
    }
    let scale = c.scale.unwrap_or(1.0);
    if !(scale.is_finite() && scale > 0.0) {
        return Err((
            "correlated.scale".into(),
            format!("{scale}; expected a number > 0"),
        ));
    }
    let prefix = c.prefix.clone().unwrap_or_else(|| "material".into());
    let mut mean = Vec::new();
    let mut sd = Vec::new();
    for p in &chosen {
        let q = &fit.parameters[p];
        if !(q.sigma.is_finite() && q.sigma >= 0.0) {
            return Err((
                "correlated.fit".into(),
                format!(
                    "parameter {p} has σ = {}; the fit does not determine it",
                    q.sigma
                ),
            ));
        }
        mean.push(q.value);
        sd.push(q.sigma * scale);
    }
    let correlation = index
        .iter()
        .map(|&i| index.iter().map(|&j| fit.correlation[i][j]).collect())
        .collect();
    Ok(Correlated {
        fit: path,
        keys: chosen.iter().map(|p| format!("{prefix}.{p}")).collect(),
        mean,
        sd,
        correlation,
    })
}
