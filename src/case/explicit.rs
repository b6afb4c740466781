//! The solver choice of a case file and the `[explicit]` table: how a user
//! asks for the explicit path and tunes it (`docs/cases.md`).

use serde::de::{self, Deserializer, MapAccess, Visitor};
use serde::{Deserialize, Serialize};
use toml::Spanned;

pub use crate::case::bounds::MAX_ROVING_MASS_LENGTH;
use crate::case::bounds::bound;
use crate::config::{ConfigError, TomlChecker};
use crate::element::RovingCoupling;
use crate::solver::NewtonParameters;
use crate::solver::explicit::{
    Amplitude, DEFAULT_MAX_INCREMENTS, ExplicitParameters, TimeStepControl,
};

/// Areal mass of the paper's fabric [kg/m²] (not in the paper; `docs/parameters.md`), the default for the
/// named parameter sets.
pub const DEFAULT_AREAL_MASS: f64 = 0.30;
/// `1 kg/m² = 1e-9 t/mm²`.
pub const KG_PER_M2_IN_T_PER_MM2: f64 = 1.0e-9;
/// Default mean clamp speed of an explicit OAT [mm/s]: slow enough for a
/// kinetic energy below 1 % of the internal energy from 10 % of the stroke
/// on, in the 45° cross-check (docs/explicit.md).
pub const DEFAULT_CLAMP_SPEED: f64 = 100.0;
/// Default number of history rows over the stroke of an explicit run.
pub const DEFAULT_HISTORY_ROWS: f64 = 160.0;
/// Most history rows `explicit.history_interval` may ask for (each row is
/// a line of every history CSV and an entry of `summary.json`).
pub const MAX_HISTORY_ROWS: f64 = 1.0e6;

/// The top-level `solver` key: a method name, or the `[solver]` table of
/// Newton knobs (which implies the quasi-static method).
#[derive(Debug, Clone, PartialEq)]
pub enum SolverChoice {
    /// `solver = "quasi-static"` or `solver = "explicit"`.
    Method(String),
    /// `[solver]` with Newton knobs.
    Newton(NewtonParameters),
}

impl<'de> Deserialize<'de> for SolverChoice {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        struct ChoiceVisitor;
        impl<'de> Visitor<'de> for ChoiceVisitor {
            type Value = SolverChoice;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("\"quasi-static\", \"explicit\" or a [solver] table of Newton knobs")
            }
            fn visit_str<E: de::Error>(self, v: &str) -> Result<SolverChoice, E> {
                Ok(SolverChoice::Method(v.to_string()))
            }
            fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<SolverChoice, A::Error> {
                NewtonParameters::deserialize(de::value::MapAccessDeserializer::new(map))
                    .map(SolverChoice::Newton)
            }
        }
        deserializer.deserialize_any(ChoiceVisitor)
    }
}

/// Which solver a case runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SolverKind {
    /// Newton with load stepping (`src/solver/newton.rs`).
    QuasiStatic,
    /// Central differences (`src/solver/explicit/`).
    Explicit,
}

/// The `[explicit]` table as written.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ExplicitRaw {
    pub(super) clamp_speed: Option<Spanned<f64>>,
    pub(super) duration: Option<Spanned<f64>>,
    pub(super) amplitude: Option<Spanned<String>>,
    pub(super) safety_factor: Option<Spanned<f64>>,
    pub(super) time_step: Option<Spanned<f64>>,
    pub(super) time_step_update_interval: Option<Spanned<i64>>,
    pub(super) mass_scaling_time_step: Option<Spanned<f64>>,
    pub(super) roving_mass_length: Option<Spanned<f64>>,
    pub(super) roving_mass_coupling: Option<Spanned<String>>,
    pub(super) damping: Option<Spanned<f64>>,
    pub(super) kinetic_energy_warning: Option<Spanned<f64>>,
    pub(super) energy_balance_warning: Option<Spanned<f64>>,
    pub(super) history_interval: Option<Spanned<f64>>,
    pub(super) threads: Option<Spanned<i64>>,
    pub(super) max_increments: Option<Spanned<i64>>,
}

/// Validated explicit settings of a case.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExplicitSettings {
    /// Duration of the stroke \[s\] (`displacement / clamp_speed`).
    pub duration: f64,
    /// Mean clamp speed [mm/s].
    pub clamp_speed: f64,
    /// The shape of the clamp motion.
    pub amplitude: Amplitude,
    /// Time-step control.
    pub time_step: TimeStepControl,
    /// Mass-scaling target step \[s\].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub mass_scaling_time_step: Option<f64>,
    /// Roving mass scaling length `ℓ` \[mm\] (0: off; `docs/explicit.md`).
    pub roving_mass_length: f64,
    /// Which relative motion of the roving edges' nodes the roving masses
    /// weigh on (`"stretch"`, the default, or `"full"`).
    pub roving_mass_coupling: RovingCoupling,
    /// Mass-proportional damping `α` [1/s].
    pub damping: f64,
    /// KE/IE warning level.
    pub kinetic_energy_warning: f64,
    /// Energy-balance warning level.
    pub energy_balance_warning: f64,
    /// Clamp displacement between history rows \[mm\].
    pub history_interval: f64,
    /// Worker threads (0: all).
    pub threads: usize,
    /// Most time increments the run may take.
    pub max_increments: usize,
}

impl ExplicitSettings {
    /// Validates the table for a stroke of `displacement` [mm]; `None`
    /// gives the defaults.
    ///
    /// # Errors
    /// A value out of range, or both `clamp_speed` and `duration`, naming
    /// the file, line, key and value.
    pub(super) fn from_raw(
        raw: Option<&ExplicitRaw>,
        check: &TomlChecker,
        displacement: f64,
    ) -> Result<Self, ConfigError> {
        let empty = ExplicitRaw::default();
        let raw = raw.unwrap_or(&empty);
        let positive =
            |v: &Spanned<f64>, key: &str, what: &str| check.range(v, key, |x| x > 0.0, what);
        let clamp_speed = clamp_speed(raw, check, displacement)?;
        let amplitude = match &raw.amplitude {
            None => Amplitude::SmoothStep,
            Some(a) => check.choice(
                a,
                "explicit.amplitude",
                &[
                    ("smooth-step", Amplitude::SmoothStep),
                    ("linear", Amplitude::Linear),
                    ("quadratic", Amplitude::Quadratic),
                ],
            )?,
        };
        let time_step = time_step(raw, check)?;
        let bounded = |v: &Spanned<f64>, key: &str| bound(key).spanned(check, v, key);
        let mass_scaling_time_step = raw
            .mass_scaling_time_step
            .as_ref()
            .map(|v| bounded(v, "explicit.mass_scaling_time_step"))
            .transpose()?;
        let roving_mass_length = match &raw.roving_mass_length {
            None => 0.0,
            Some(v) => bounded(v, "explicit.roving_mass_length")?,
        };
        let roving_mass_coupling = match &raw.roving_mass_coupling {
            None => RovingCoupling::Stretch,
            Some(c) => check.choice(
                c,
                "explicit.roving_mass_coupling",
                &[
                    ("stretch", RovingCoupling::Stretch),
                    ("full", RovingCoupling::Full),
                ],
            )?,
        };
        let damping = match &raw.damping {
            None => 0.0,
            Some(v) => bounded(v, "explicit.damping")?,
        };
        if let (Some(v), true) = (&raw.damping, roving_mass_length > 0.0 && damping > 0.0) {
            return Err(check.invalid(
                check.line_of(v),
                "explicit.damping",
                crate::config::readable_number(damping),
                "0 with explicit.roving_mass_length (the damping is mass-proportional with the lumped mass only)",
            ));
        }
        let kinetic_energy_warning = match &raw.kinetic_energy_warning {
            None => 0.01,
            Some(v) => positive(v, "explicit.kinetic_energy_warning", "a fraction > 0")?,
        };
        let energy_balance_warning = match &raw.energy_balance_warning {
            None => 0.01,
            Some(v) => positive(v, "explicit.energy_balance_warning", "a fraction > 0")?,
        };
        let history_interval = match &raw.history_interval {
            None => displacement / DEFAULT_HISTORY_ROWS,
            Some(v) => check.range(
                v,
                "explicit.history_interval",
                |x| x >= displacement / MAX_HISTORY_ROWS && x <= displacement,
                &format!(
                    "a clamp displacement in [{:e}, {displacement}] mm (at most {MAX_HISTORY_ROWS:e} history rows)",
                    displacement / MAX_HISTORY_ROWS
                ),
            )?,
        };
        let max_increments = match &raw.max_increments {
            None => DEFAULT_MAX_INCREMENTS,
            Some(n) => check.count(n, "explicit.max_increments", 1..=1_000_000_000_000)?,
        };
        let threads = match &raw.threads {
            None => 0,
            Some(n) => check.count(n, "explicit.threads", 0..=1_000_000)?,
        };
        Ok(Self {
            duration: displacement / clamp_speed,
            clamp_speed,
            amplitude,
            time_step,
            mass_scaling_time_step,
            roving_mass_length,
            roving_mass_coupling,
            damping,
            kinetic_energy_warning,
            energy_balance_warning,
            history_interval,
            threads,
            max_increments,
        })
    }

    /// The solver parameters.
    pub fn parameters(&self) -> ExplicitParameters {
        ExplicitParameters {
            duration: self.duration,
            amplitude: self.amplitude,
            time_step: self.time_step,
            mass_scaling_target: self.mass_scaling_time_step,
            damping: self.damping,
            kinetic_energy_warning: self.kinetic_energy_warning,
            energy_balance_warning: self.energy_balance_warning,
            threads: self.threads,
            max_increments: self.max_increments,
            cancel: crate::solver::CancelToken::default(),
        }
    }
}

/// `explicit.clamp_speed` or `explicit.duration` (not both) as the mean
/// clamp speed [mm/s] over a stroke of `displacement` [mm], checked to give
/// a finite, positive duration.
fn clamp_speed(
    raw: &ExplicitRaw,
    check: &TomlChecker,
    displacement: f64,
) -> Result<f64, ConfigError> {
    let clamp_speed = match (&raw.clamp_speed, &raw.duration) {
        (Some(_), Some(d)) => {
            return Err(check.invalid(
                check.line_of(d),
                "explicit.duration",
                crate::config::readable_number(*d.get_ref()),
                "either explicit.clamp_speed or explicit.duration, not both",
            ));
        }
        (Some(v), None) => {
            check.range(v, "explicit.clamp_speed", |x| x > 0.0, "a speed > 0 mm/s")?
        }
        (None, Some(d)) => {
            displacement / bound("explicit.duration").spanned(check, d, "explicit.duration")?
        }
        (None, None) => DEFAULT_CLAMP_SPEED,
    };
    // Each value may be finite and the quotient not (1e-308 s for an
    // 80 mm stroke, 5e-324 mm/s, or a stroke of 5e-324 mm).
    let duration = displacement / clamp_speed;
    if !(clamp_speed.is_finite() && duration.is_finite() && duration > 0.0) {
        let (key, line, value) = match (&raw.duration, &raw.clamp_speed) {
            (Some(d), _) => ("explicit.duration", check.line_of(d), *d.get_ref()),
            (None, Some(v)) => ("explicit.clamp_speed", check.line_of(v), *v.get_ref()),
            (None, None) => ("explicit.clamp_speed", 0, clamp_speed),
        };
        return Err(check.invalid(
            line,
            key,
            crate::config::readable_number(value),
            &format!(
                "a value for which the stroke of {} mm takes a finite, positive time \
                 (duration = stroke / clamp_speed)",
                crate::config::readable_number(displacement)
            ),
        ));
    }
    Ok(clamp_speed)
}

/// `explicit.time_step` (fixed) or `explicit.safety_factor` and
/// `explicit.time_step_update_interval` (stable), not both.
fn time_step(raw: &ExplicitRaw, check: &TomlChecker) -> Result<TimeStepControl, ConfigError> {
    Ok(match (&raw.time_step, &raw.safety_factor) {
        (Some(dt), Some(_)) => {
            return Err(check.invalid(
                check.line_of(dt),
                "explicit.time_step",
                crate::config::readable_number(*dt.get_ref()),
                "either explicit.time_step (fixed) or explicit.safety_factor (stable), not both",
            ));
        }
        (Some(dt), None) => TimeStepControl::Fixed {
            time_step: bound("explicit.time_step").spanned(check, dt, "explicit.time_step")?,
        },
        (None, safety) => TimeStepControl::Stable {
            safety_factor: match safety {
                None => 0.9,
                Some(s) => check.range(
                    s,
                    "explicit.safety_factor",
                    |x| x > 0.0 && x <= 1.0,
                    "a factor in (0, 1]",
                )?,
            },
            update_interval: match &raw.time_step_update_interval {
                None => 100,
                Some(n) => check.count(n, "explicit.time_step_update_interval", 1..=1_000_000)?,
            },
        },
    })
}

/// The top-level `solver` key: a method name or a `[solver]` table of
/// Newton knobs (quasi-static).
pub(super) fn solver_choice(
    choice: Option<Spanned<SolverChoice>>,
    check: &TomlChecker,
) -> Result<(SolverKind, NewtonParameters), ConfigError> {
    Ok(match choice {
        None => (SolverKind::QuasiStatic, NewtonParameters::default()),
        Some(choice) => {
            let line = check.line_of(&choice);
            match choice.into_inner() {
                SolverChoice::Newton(p) => (SolverKind::QuasiStatic, p),
                SolverChoice::Method(m) => match m.as_str() {
                    "quasi-static" => (SolverKind::QuasiStatic, NewtonParameters::default()),
                    "explicit" => (SolverKind::Explicit, NewtonParameters::default()),
                    other => {
                        return Err(check.invalid(
                            line,
                            "solver",
                            format!("\"{other}\""),
                            "\"quasi-static\", \"explicit\" or a [solver] table of Newton knobs",
                        ));
                    }
                },
            }
        }
    })
}

/// Checks the Newton knobs of a `[solver]` table against their bounds
/// ([`crate::case::bounds`]); the knobs carry no span, so their lines are
/// looked up in the `[solver]` table's text.
pub(super) fn validate_solver(
    p: &NewtonParameters,
    check: &TomlChecker,
) -> Result<(), ConfigError> {
    let line = |key: &str| check.line_of_key("solver", key);
    let bad = |key: &str, value: String, expected: &str| {
        check.invalid(line(key), &format!("solver.{key}"), value, expected)
    };
    let bounded = |key: &str, v: f64| {
        let full = format!("solver.{key}");
        bound(&full).check(check, v, line(key), &full).map(|_| ())
    };
    bounded("initial_increment", p.initial_increment)?;
    bounded("max_increment", p.max_increment)?;
    bounded("min_increment", p.min_increment)?;
    bounded("residual_tolerance", p.residual_tolerance)?;
    bounded("energy_tolerance", p.energy_tolerance)?;
    let pos = |key: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(bad(key, crate::config::readable_number(v), "a number > 0"))
        }
    };
    pos("force_floor", p.force_floor)?;
    if p.min_increment > p.max_increment {
        return Err(bad(
            "min_increment",
            crate::config::readable_number(p.min_increment),
            "at most max_increment",
        ));
    }
    bounded("growth", p.growth)?;
    if !(p.cutback > 0.0 && p.cutback < 1.0) {
        return Err(bad(
            "cutback",
            crate::config::readable_number(p.cutback),
            "a factor in (0, 1)",
        ));
    }
    if p.max_iterations == 0 {
        return Err(bad("max_iterations", "0".into(), "at least 1"));
    }
    pos("stabilisation_fraction", p.stabilisation_fraction)?;
    if let Some(t) = p.max_wall_seconds {
        bounded("max_wall_seconds", t)?;
    }
    if let Some(t) = p.inertia_duration {
        bounded("inertia_duration", t)?;
    }
    pos("stabilisation_limit", p.stabilisation_limit)?;
    if !(p.stabilisation_factor.is_finite() && p.stabilisation_factor >= 0.0) {
        return Err(bad(
            "stabilisation_factor",
            crate::config::readable_number(p.stabilisation_factor),
            "a number ≥ 0",
        ));
    }
    Ok(())
}

/// Warns about an `[explicit]` table in a case the quasi-static solver
/// runs: the table is read and checked in every case, so that switching
/// solvers is a one-line change (`docs/cases.md`), but none of it is used.
pub(super) fn unused_explicit_table(
    check: &TomlChecker,
    kind: SolverKind,
    raw: Option<&ExplicitRaw>,
) {
    if kind == SolverKind::QuasiStatic && raw.is_some() {
        let keys = check.keys_of_table("explicit");
        check.warn(
            check.line_of_header("explicit"),
            "[explicit]",
            if keys.is_empty() {
                "(an empty table)".into()
            } else {
                format!("(keys {})", keys.join(", "))
            },
            String::new(),
            "the quasi-static solver runs this case and does not use the [explicit] table \
             (it is checked, so that solver = \"explicit\" is a one-line change)",
        );
    }
}
