//! Settings of the explicit solver and their validation.

use serde::Serialize;

use super::super::amplitude::Amplitude;
use super::super::cancel::CancelToken;

/// How the time step is chosen.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum TimeStepControl {
    /// `safety_factor × 2/ω_max`, with `ω_max` bounded element by element
    /// from the current tangent (see
    /// [`crate::element::FibreTriangle::max_frequency_squared`]) and
    /// re-estimated every `update_interval` steps.
    Stable {
        /// Fraction of the estimated critical step, in `(0, 1]`.
        safety_factor: f64,
        /// Steps between two estimates, at least 1.
        update_interval: usize,
    },
    /// A fixed step \[s\], whatever the stability estimate says (for studies
    /// of the stability limit; the estimate is still reported).
    Fixed {
        /// The step \[s\].
        time_step: f64,
    },
}

/// Everything the explicit solver needs besides the model and the loading.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ExplicitParameters {
    /// Duration `T` of the prescribed motion \[s\].
    pub duration: f64,
    /// Shape of the prescribed motion.
    pub amplitude: Amplitude,
    /// Time-step choice.
    pub time_step: TimeStepControl,
    /// Mass scaling: elements whose stable step is below this target \[s\]
    /// get their density raised so that it reaches it. `None`: no scaling.
    pub mass_scaling_target: Option<f64>,
    /// Mass-proportional damping coefficient `α` [1/s]: a force `−α m v` on
    /// every free dof. Zero: undamped.
    pub damping: f64,
    /// Warn when the kinetic energy exceeds this fraction of the internal
    /// energy (checked once `λ` passes 10 % of its final value).
    pub kinetic_energy_warning: f64,
    /// Warn when the relative energy-balance error (against the largest
    /// energy of the balance, normally the external work) exceeds this.
    pub energy_balance_warning: f64,
    /// Worker threads; 0 takes rayon's default (all cores, or
    /// `RAYON_NUM_THREADS`). Results do not depend on it.
    pub threads: usize,
    /// Most time increments a run may take: a run whose first stable step
    /// already asks for more is refused before it starts, one that reaches
    /// it later stops there, incomplete, with its results so far.
    pub max_increments: usize,
    /// Stop (interrupted, after an output of the state reached) at the next
    /// time increment once this is cancelled. Not a case-file key.
    #[serde(skip)]
    pub cancel: CancelToken,
}

/// Default of [`ExplicitParameters::max_increments`]: 25 times the
/// increments of the largest bench (the paper-size [0°/90°] hemisphere,
/// about 400,000; `docs/history.md`).
pub const DEFAULT_MAX_INCREMENTS: usize = 10_000_000;

impl ExplicitParameters {
    /// Defaults for a run of duration `duration` \[s\]: smooth step, safety factor 0.9 updated every 100 steps, no
    /// mass scaling, no damping, warnings at KE > 1 % of IE and at an
    /// energy-balance error above 1 %, all cores.
    pub fn new(duration: f64) -> Self {
        Self {
            duration,
            amplitude: Amplitude::SmoothStep,
            time_step: TimeStepControl::Stable {
                safety_factor: 0.9,
                update_interval: 100,
            },
            mass_scaling_target: None,
            damping: 0.0,
            kinetic_energy_warning: 0.01,
            energy_balance_warning: 0.01,
            threads: 0,
            max_increments: DEFAULT_MAX_INCREMENTS,
            cancel: CancelToken::default(),
        }
    }

    /// Checks every setting.
    ///
    /// # Errors
    /// The first bad setting, by name, with its value and what was expected.
    pub fn validate(&self) -> Result<(), SettingError> {
        let positive = |name: &'static str, value: f64| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(SettingError {
                    name,
                    value: format!("{value}"),
                    expected: "a finite number > 0",
                })
            }
        };
        positive("duration", self.duration)?;
        match self.time_step {
            TimeStepControl::Stable {
                safety_factor,
                update_interval,
            } => {
                if !(safety_factor > 0.0 && safety_factor <= 1.0) {
                    return Err(SettingError {
                        name: "safety_factor",
                        value: format!("{safety_factor}"),
                        expected: "a factor in (0, 1]",
                    });
                }
                if update_interval == 0 {
                    return Err(SettingError {
                        name: "time_step_update_interval",
                        value: "0".into(),
                        expected: "at least 1 step",
                    });
                }
            }
            TimeStepControl::Fixed { time_step } => positive("time_step", time_step)?,
        }
        if let Some(target) = self.mass_scaling_target {
            positive("mass_scaling_time_step", target)?;
        }
        if !(self.damping.is_finite() && self.damping >= 0.0) {
            return Err(SettingError {
                name: "damping",
                value: format!("{}", self.damping),
                expected: "a finite number ≥ 0 [1/s]",
            });
        }
        positive("kinetic_energy_warning", self.kinetic_energy_warning)?;
        positive("energy_balance_warning", self.energy_balance_warning)?;
        Ok(())
    }

    /// `λ(t) / λ_final`.
    pub fn load_fraction(&self, time: f64) -> f64 {
        self.amplitude.shape(time / self.duration)
    }

    /// The time at which `λ(t) / λ_final = fraction`.
    pub fn time_of_load_fraction(&self, fraction: f64) -> f64 {
        self.duration * self.amplitude.inverse(fraction)
    }
}

/// A bad explicit setting.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{name} = {value}: expected {expected}")]
pub struct SettingError {
    /// The setting (its case-file key).
    pub name: &'static str,
    /// The value given.
    pub value: String,
    /// What was expected.
    pub expected: &'static str,
}
