//! The fit as a library entry point: [`fit`] runs the optimiser over the
//! tests of a [`FitSpec`] and returns a [`FitOutcome`] in memory; the
//! command line and the outputs ([`super::output`]) are its clients.

use std::time::Instant;

use nalgebra::DMatrix;

use super::evaluate::{
    Evaluation, ScaledParameter, TestRun, evaluate, material_at, quantity_index, scaled_parameters,
};
use super::identify::{Identifiability, RELATIVE_SIGMA_LIMIT, identifiability};
use super::input::{FitSpec, Scaling};
use super::measured::Quantity;
use super::optimise::{Linearisation, LmIteration, LmSettings, LmStop, minimise};
use crate::material::MaterialSpec;
use crate::solver::CancelToken;

/// Noise assumed for a strain curve that is not measured when the report
/// predicts what adding it would bring: typical DIC noise (a few 1e-3 in
/// strain, about 0.5° in shear angle; `docs/fit.md`).
pub fn assumed_noise(quantity: Quantity) -> f64 {
    match quantity {
        Quantity::Force => 0.01,
        Quantity::E22 | Quantity::EPerp => 0.003,
        Quantity::ShearAngle => 0.5,
    }
}

/// Condition numbers of the converged tangent above this make its
/// sensitivities unreliable: the relative error of a solve is about
/// `cond · ε`, and `1e-3 / ε ≈ 4.5e12` leaves a thousandth.
pub const CONDITION_LIMIT: f64 = 1e-3 / f64::EPSILON;

/// One parameter's result.
#[derive(Debug, Clone, PartialEq)]
pub struct FittedParameter {
    /// Key (`w6.c_ini`, `offset.oat30`).
    pub key: String,
    /// Fitted value.
    pub value: f64,
    /// Starting value.
    pub start: f64,
    /// 1σ (infinite when the data do not determine it).
    pub sigma: f64,
    /// Bounds.
    pub bounds: (f64, f64),
    /// Whether it ended on a bound.
    pub at_bound: bool,
}

/// Per test and quantity, how well the fit matches.
#[derive(Debug, Clone, PartialEq)]
pub struct Misfit {
    /// Test name.
    pub test: String,
    /// Quantity.
    pub quantity: Quantity,
    /// Points.
    pub points: usize,
    /// RMS of the weighted residual (in noise units).
    pub weighted_rms: f64,
    /// RMS of `sim − meas` in the quantity's unit.
    pub rms: f64,
    /// The measured data's resampling error bound, same unit.
    pub interpolation_error: f64,
}

/// The result of a fit, in memory.
pub struct FitOutcome {
    /// The parameters.
    pub parameters: Vec<FittedParameter>,
    /// The fitted material set (the starting set with the fitted values).
    pub material: Option<MaterialSpec>,
    /// Uncertainty and conditioning at the optimum.
    pub identifiability: Option<Identifiability>,
    /// Misfit per test and quantity.
    pub misfits: Vec<Misfit>,
    /// The optimiser's history.
    pub history: Vec<LmIteration>,
    /// Wall time at each history entry \[s\].
    pub elapsed: Vec<f64>,
    /// The parameters' values (their own units) at each history entry.
    pub values: Vec<Vec<f64>>,
    /// Why the optimiser stopped.
    pub stop: LmStop,
    /// Model evaluations.
    pub evaluations: usize,
    /// The runs at the start and at the optimum, per test.
    pub start_runs: Vec<TestRun>,
    /// The runs at the optimum.
    pub final_runs: Vec<TestRun>,
    /// Warnings: poorly determined parameters, weak combinations, bounds,
    /// ill-conditioned tangents; with what would help.
    pub warnings: Vec<String>,
    /// Total wall time \[s\].
    pub seconds: f64,
}

impl FitOutcome {
    /// The parameters' values at history entry `i` (empty beyond it).
    pub fn history_values(&self, i: usize) -> &[f64] {
        self.values.get(i).map_or(&[], |v| v.as_slice())
    }

    /// Whether the optimiser converged.
    pub fn converged(&self) -> bool {
        matches!(
            self.stop,
            LmStop::CostConverged | LmStop::StepConverged | LmStop::GradientConverged
        )
    }
}

/// The settings of the optimiser for `spec`.
pub fn settings(spec: &FitSpec) -> LmSettings {
    LmSettings {
        max_iterations: spec.options.max_iterations,
        tolerance: spec.options.tolerance,
        ..LmSettings::default()
    }
}

/// Fits the free parameters of `spec` to its measured tests; `progress`
/// sees every iteration with the elapsed time \[s\]; `cancel` stops the
/// fit before its next iteration, keeping the best point so far.
///
/// # Errors
/// A free key that is not a law parameter (refused by the input checks
/// first).
pub fn fit(
    spec: &FitSpec,
    mut progress: impl FnMut(&LmIteration, f64),
    cancel: &CancelToken,
) -> Result<FitOutcome, String> {
    let clock = Instant::now();
    let parameters = scaled_parameters(spec)?;
    let start: Vec<f64> = parameters.iter().map(|p| p.theta(p.start)).collect();
    let lower: Vec<f64> = parameters.iter().map(|p| p.theta(p.lower)).collect();
    let upper: Vec<f64> = parameters.iter().map(|p| p.theta(p.upper)).collect();
    let mut start_runs: Option<Vec<TestRun>> = None;
    let mut best: Option<(Vec<f64>, Evaluation)> = None;
    let mut elapsed = Vec::new();
    let result = minimise(
        &start,
        &lower,
        &upper,
        &settings(spec),
        |theta| {
            let evaluation = evaluate(spec, &parameters, theta)?;
            if start_runs.is_none() {
                start_runs = Some(evaluation.runs.clone());
            }
            let lin = Linearisation {
                residual: evaluation.residual.clone(),
                jacobian: evaluation.jacobian.clone(),
            };
            let better = best
                .as_ref()
                .is_none_or(|(_, b)| evaluation.residual.norm() < b.residual.norm());
            if better {
                best = Some((theta.to_vec(), evaluation));
            }
            Ok(lin)
        },
        |iteration| {
            let t = clock.elapsed().as_secs_f64();
            elapsed.push(t);
            progress(iteration, t);
        },
        || cancel.is_cancelled(),
    );
    let mut outcome = FitOutcome {
        parameters: Vec::new(),
        material: None,
        identifiability: None,
        misfits: Vec::new(),
        values: result
            .history
            .iter()
            .map(|it| {
                parameters
                    .iter()
                    .zip(&it.theta)
                    .map(|(p, &t)| p.value(t))
                    .collect()
            })
            .collect(),
        history: result.history,
        elapsed,
        stop: result.stop.clone(),
        evaluations: result.evaluations,
        start_runs: start_runs.unwrap_or_default(),
        final_runs: Vec::new(),
        warnings: Vec::new(),
        seconds: 0.0,
    };
    let theta = result.theta;
    // The evaluation at the optimum (the accepted point is the best one).
    let evaluation = match best {
        Some((t, e)) if t == theta => Some(e),
        Some(_) => evaluate(spec, &parameters, &theta).ok(),
        None => None,
    };
    outcome.parameters = parameters
        .iter()
        .zip(&theta)
        .map(|(p, &t)| {
            let value = p.value(t);
            FittedParameter {
                key: p.key.clone(),
                value,
                start: p.start,
                sigma: f64::NAN,
                bounds: (p.lower, p.upper),
                at_bound: at_bound(p, t),
            }
        })
        .collect();
    // Nothing fitted, nothing to hand on: no parameter file then.
    if !matches!(result.stop, LmStop::StartFailed(_)) {
        outcome.material = material_at(spec, &parameters, &theta).ok();
    }
    if let LmStop::StartFailed(why) = &result.stop {
        outcome.warnings.push(format!(
            "the fit could not start: the forward runs at the starting parameters failed: {why}"
        ));
    }
    if let Some(evaluation) = evaluation {
        report(spec, &parameters, &theta, &evaluation, &mut outcome);
        outcome.final_runs = evaluation.runs;
    }
    outcome.seconds = clock.elapsed().as_secs_f64();
    Ok(outcome)
}

/// `dp/dθ` of every parameter at `theta`.
fn value_derivatives(parameters: &[ScaledParameter], theta: &[f64]) -> Vec<f64> {
    parameters
        .iter()
        .zip(theta)
        .map(|(p, &t)| p.derivative(t))
        .collect()
}

/// Whether `θ` lies on a bound of `p` (to a millionth of its scale).
fn at_bound(p: &ScaledParameter, theta: f64) -> bool {
    let (lo, hi) = (p.theta(p.lower), p.theta(p.upper));
    let tiny = 1e-6 * (1.0 + theta.abs());
    theta <= lo + tiny || theta >= hi - tiny
}

/// The σ, correlation, misfits and warnings at the optimum.
fn report(
    spec: &FitSpec,
    parameters: &[ScaledParameter],
    theta: &[f64],
    evaluation: &Evaluation,
    outcome: &mut FitOutcome,
) {
    let dp = value_derivatives(parameters, theta);
    let chi2 = evaluation.residual.norm_squared();
    let id = identifiability(&evaluation.jacobian, chi2, &dp);
    for (p, s) in outcome.parameters.iter_mut().zip(&id.sigma) {
        p.sigma = *s;
    }
    // Misfits per test and quantity.
    for (t, test) in spec.tests.iter().enumerate() {
        for measured in &test.measured {
            let entries: Vec<usize> = evaluation
                .rows
                .iter()
                .enumerate()
                .filter(|(_, (rt, q, _))| *rt == t && *q == measured.quantity)
                .map(|(i, _)| i)
                .collect();
            let count = entries.len().max(1) as f64;
            let weighted = entries
                .iter()
                .map(|&i| evaluation.residual[i].powi(2))
                .sum::<f64>();
            let q = quantity_index(measured.quantity);
            let run = &evaluation.runs[t];
            let unit = entries
                .iter()
                .map(|&i| {
                    let (_, _, k) = evaluation.rows[i];
                    let sim = run.points[k].values[q];
                    let meas = measured.values.get(k).copied().unwrap_or(sim);
                    (sim - meas).powi(2)
                })
                .sum::<f64>();
            outcome.misfits.push(Misfit {
                test: test.name.clone(),
                quantity: measured.quantity,
                points: entries.len(),
                weighted_rms: (weighted / count).sqrt(),
                rms: (unit / count).sqrt(),
                interpolation_error: measured.interpolation_error,
            });
        }
    }
    outcome.warnings.extend(warnings(
        spec,
        parameters,
        theta,
        evaluation,
        &id,
        &outcome.parameters,
    ));
    outcome.identifiability = Some(id);
}

/// The warnings of the identifiability report, each with what would help.
fn warnings(
    spec: &FitSpec,
    parameters: &[ScaledParameter],
    theta: &[f64],
    evaluation: &Evaluation,
    id: &Identifiability,
    fitted: &[FittedParameter],
) -> Vec<String> {
    let mut out = Vec::new();
    let poor: Vec<usize> = fitted
        .iter()
        .enumerate()
        .filter(|(_, p)| {
            // A NaN or infinite σ is poorly determined too.
            p.sigma.is_nan() || p.sigma > RELATIVE_SIGMA_LIMIT * p.value.abs()
        })
        .map(|(i, _)| i)
        .collect();
    let advice = if poor.is_empty() {
        String::new()
    } else {
        what_would_help(spec, parameters, theta, evaluation, &poor)
    };
    for &i in &poor {
        let p = &fitted[i];
        let relative = if p.sigma.is_finite() {
            format!(
                "1σ = {:.3e} = {:.0} % of its value",
                p.sigma,
                100.0 * p.sigma / p.value.abs()
            )
        } else {
            "not determined at all".to_string()
        };
        out.push(format!(
            "{}: poorly determined by these data ({relative}; limit {:.0} %){advice}",
            p.key,
            100.0 * RELATIVE_SIGMA_LIMIT
        ));
    }
    for weak in &id.weak {
        let combination: Vec<String> = weak
            .combination
            .iter()
            .map(|(i, w)| format!("{w:+.2}·{}", log_name(&parameters[*i])))
            .collect();
        out.push(format!(
            "a weakly determined combination (singular value {:.3} < {:.0}): {} — the data fix it only to about {:.0} %",
            weak.singular_value,
            super::identify::WEAK_SINGULAR_VALUE,
            combination.join(" "),
            100.0 * id.variance_factor.sqrt() / weak.singular_value.max(1e-300)
        ));
    }
    for p in fitted.iter().filter(|p| p.at_bound) {
        out.push(format!(
            "{} = {} ended on a bound of [{}, {}]: the data push it beyond; widen the bound in [bounds] if the value is physical, or fix the parameter",
            p.key, p.value, p.bounds.0, p.bounds.1
        ));
    }
    for (test, run) in spec.tests.iter().zip(&evaluation.runs) {
        let ill: Vec<String> = run
            .points
            .iter()
            .filter(|pt| pt.condition.is_some_and(|c| c > CONDITION_LIMIT))
            .map(|pt| {
                format!(
                    "{} mm (condition {:.1e})",
                    pt.displacement,
                    pt.condition.unwrap_or(0.0)
                )
            })
            .collect();
        if !ill.is_empty() {
            out.push(format!(
                "test {}: the tangent is ill-conditioned at {} (above {CONDITION_LIMIT:.1e}): the run nears a limit point there and its sensitivities are unreliable; end the schedule before it",
                test.name,
                ill.join(", ")
            ));
        }
    }
    out
}

/// `ln(key)` for a log-scaled parameter, the key over its scale otherwise.
fn log_name(p: &ScaledParameter) -> String {
    match p.scaling {
        Scaling::Log => format!("ln {}", p.key),
        Scaling::Linear => format!("{}/{:.3}", p.key, p.scale),
    }
}

/// What adding a strain curve that is not fitted would bring: for every
/// (test, quantity) not measured, the σ of the poorly determined
/// parameters with those rows added (assumed noise [`assumed_noise`]),
/// from the sensitivities the runs computed anyway; the best candidate.
fn what_would_help(
    spec: &FitSpec,
    parameters: &[ScaledParameter],
    theta: &[f64],
    evaluation: &Evaluation,
    poor: &[usize],
) -> String {
    let dp = value_derivatives(parameters, theta);
    let chi2 = evaluation.residual.norm_squared();
    let n = parameters.len();
    // The worst relative σ of the poorly determined parameters with the
    // rows of `added` (test, quantity) appended at the assumed noise.
    let worst_with = |added: &[(usize, Quantity)]| -> f64 {
        let mut rows: Vec<Vec<f64>> = (0..evaluation.jacobian.nrows())
            .map(|i| evaluation.jacobian.row(i).iter().copied().collect())
            .collect();
        for &(t, quantity) in added {
            let q = quantity_index(quantity);
            let noise = assumed_noise(quantity);
            for point in &evaluation.runs[t].points {
                let mut row = vec![0.0; n];
                let mut law_index = 0;
                for (c, p) in parameters.iter().enumerate() {
                    if p.law.is_some() {
                        row[c] = point.derivatives[q][law_index] * dp[c] / noise;
                        law_index += 1;
                    }
                }
                rows.push(row);
            }
        }
        let j = DMatrix::from_fn(rows.len(), n, |i, k| rows[i][k]);
        let id = identifiability(&j, chi2, &dp);
        poor.iter()
            .map(|&i| id.sigma[i] / parameters[i].value(theta[i]).abs())
            .fold(0.0, f64::max)
    };
    let missing: Vec<(usize, Quantity)> = spec
        .tests
        .iter()
        .enumerate()
        .flat_map(|(t, test)| {
            Quantity::ALL
                .into_iter()
                .filter(move |q| *q != Quantity::Force && test.quantity(*q).is_none())
                .map(move |q| (t, q))
        })
        .collect();
    let mut best: Option<(f64, String)> = None;
    for &(t, quantity) in &missing {
        let worst = worst_with(&[(t, quantity)]);
        if best.as_ref().is_none_or(|(w, _)| worst < *w) {
            best = Some((
                worst,
                format!(
                    "; adding the {} curve of test {} (noise {} per point; predicted here) would bring the worst of these to {:.0} %",
                    quantity.name(),
                    spec.tests[t].name,
                    assumed_noise(quantity),
                    100.0 * worst
                ),
            ));
        }
    }
    if missing.len() > 1
        && let Some((single, text)) = &best
        && *single > RELATIVE_SIGMA_LIMIT
    {
        let all = worst_with(&missing);
        if all < *single {
            best = Some((
                all,
                format!(
                    "{text}; adding every missing MDZ strain curve ({} curves) would bring it to {:.0} %",
                    missing.len(),
                    100.0 * all
                ),
            ));
        }
    }
    match best {
        Some((worst, text)) if worst.is_finite() => text,
        _ => "; more tests (another angle) or a longer schedule would help".to_string(),
    }
}
