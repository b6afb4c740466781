//! A bounded Levenberg–Marquardt method on an exact Jacobian
//! (`docs/fit.md`, "The optimiser").
//!
//! Minimises `½ ‖r(θ)‖²` over a box `lower ≤ θ ≤ upper` in scaled
//! parameters `θ` (logarithms, or values over a scale). Each iteration
//! solves `(JᵀJ + λ diag(JᵀJ)) δ = −Jᵀr` (Marquardt's scaling, which makes
//! the step independent of the parameters' units) on the parameters not
//! held at a bound, projects `θ + δ` onto the box and accepts it when the
//! cost drops: the gain ratio `ρ` (actual over predicted reduction) then
//! lowers `λ` (by 3 for `ρ > ¾`), a rejected step raises it tenfold. A
//! parameter on a bound whose gradient pushes outwards is held there for the
//! step (an active set). A trial point where the model cannot be evaluated
//! (a forward run that does not converge) is a rejected step: the step
//! shrinks, the fit goes on.
//!
//! Written here rather than taken from the `levenberg-marquardt` crate
//! (MINPACK's `lmder`): that crate has no bounds and ends its run when a
//! residual evaluation fails, while a fit of forward FE runs must treat a
//! failed trial point as a step to shrink; with the exact Jacobian and a
//! handful of parameters, the few lines of a dense LM are the simpler,
//! more robust choice.

use nalgebra::{DMatrix, DVector};

/// What the model returns at a point: the weighted residual and its
/// Jacobian with respect to the scaled parameters.
pub struct Linearisation {
    /// `r` (dimensionless: each entry over its noise).
    pub residual: DVector<f64>,
    /// `J = ∂r/∂θ`, one column per parameter.
    pub jacobian: DMatrix<f64>,
}

/// Stopping rules and limits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmSettings {
    /// Iterations (accepted or rejected trial points) at most.
    pub max_iterations: usize,
    /// Stop when an accepted step lowers the cost by less than this
    /// fraction, or when the step is below this size in `θ`.
    pub tolerance: f64,
    /// Starting damping `λ`.
    pub initial_damping: f64,
    /// Stop when the data carry noise (`χ² ≥ ½ (n − p)`) and an accepted
    /// step lowers `χ² = 2 cost` by less than this: the parameters then
    /// move by less than about `√(change)` of their σ (a change of χ² by 1
    /// is a 1σ move), which no reader of the result can see. 0: off.
    pub chi2_change: f64,
}

impl Default for LmSettings {
    fn default() -> Self {
        Self {
            max_iterations: 50,
            tolerance: 1e-6,
            initial_damping: 1e-3,
            chi2_change: 0.01,
        }
    }
}

/// One iteration of the history.
#[derive(Debug, Clone, PartialEq)]
pub struct LmIteration {
    /// Iteration number (1-based; 0 is the start).
    pub iteration: usize,
    /// Cost `½ ‖r‖²` at the accepted point after this iteration.
    pub cost: f64,
    /// The damping `λ` used for the trial step.
    pub damping: f64,
    /// Size `‖δ‖` of the trial step in `θ` (0 at the start).
    pub step: f64,
    /// Whether the trial point was accepted.
    pub accepted: bool,
    /// The scaled parameters after the iteration.
    pub theta: Vec<f64>,
    /// Why a trial point could not be evaluated, if it could not.
    pub failure: Option<String>,
}

/// Why the iterations stopped.
#[derive(Debug, Clone, PartialEq)]
pub enum LmStop {
    /// The relative cost decrease of an accepted step fell below the
    /// tolerance, or (noisy data) its decrease of χ² below `chi2_change`.
    CostConverged,
    /// The step fell below the tolerance.
    StepConverged,
    /// The projected gradient vanished (every parameter at a bound, or zero).
    GradientConverged,
    /// The iteration limit.
    IterationLimit,
    /// The damping grew beyond any useful step (no decrease found).
    NoDecrease,
    /// The starting point could not be evaluated.
    StartFailed(String),
    /// Stopped on request (the best point so far is kept).
    Interrupted,
}

/// The result of a run of the optimiser.
pub struct LmResult {
    /// The best point found.
    pub theta: Vec<f64>,
    /// Its residual and Jacobian.
    pub at_best: Option<Linearisation>,
    /// The history, starting with iteration 0.
    pub history: Vec<LmIteration>,
    /// Why it stopped.
    pub stop: LmStop,
    /// Model evaluations (each one residual and Jacobian).
    pub evaluations: usize,
}

/// `½ ‖r‖²`.
pub fn cost(r: &DVector<f64>) -> f64 {
    0.5 * r.norm_squared()
}

/// Minimises `½ ‖r(θ)‖²` over `lower ≤ θ ≤ upper` from `start` (projected
/// onto the box); `model` returns the linearisation or why it cannot;
/// `on_iteration` sees every iteration (progress); `interrupted` is asked
/// before each iteration and stops the run when it says so.
pub fn minimise(
    start: &[f64],
    lower: &[f64],
    upper: &[f64],
    settings: &LmSettings,
    mut model: impl FnMut(&[f64]) -> Result<Linearisation, String>,
    mut on_iteration: impl FnMut(&LmIteration),
    interrupted: impl Fn() -> bool,
) -> LmResult {
    let n = start.len();
    let project = |theta: &mut [f64]| {
        for i in 0..n {
            theta[i] = theta[i].clamp(lower[i], upper[i]);
        }
    };
    let mut theta = start.to_vec();
    project(&mut theta);
    let mut evaluations = 1;
    let mut current = match model(&theta) {
        Ok(l) => l,
        Err(why) => {
            return LmResult {
                theta,
                at_best: None,
                history: Vec::new(),
                stop: LmStop::StartFailed(why),
                evaluations,
            };
        }
    };
    let mut current_cost = cost(&current.residual);
    let mut history = vec![LmIteration {
        iteration: 0,
        cost: current_cost,
        damping: settings.initial_damping,
        step: 0.0,
        accepted: true,
        theta: theta.clone(),
        failure: None,
    }];
    on_iteration(&history[0]);
    let mut damping = settings.initial_damping;
    let mut stop = LmStop::IterationLimit;
    for iteration in 1..=settings.max_iterations {
        if interrupted() {
            stop = LmStop::Interrupted;
            break;
        }
        let j = &current.jacobian;
        let gradient = j.transpose() * &current.residual;
        let normal = j.transpose() * j;
        // Active set: a parameter on a bound whose descent direction
        // (−gradient) points out of the box.
        let tiny = |i: usize| 1e-12 * (1.0 + theta[i].abs());
        let free: Vec<usize> = (0..n)
            .filter(|&i| {
                let at_lower = theta[i] <= lower[i] + tiny(i) && gradient[i] > 0.0;
                let at_upper = theta[i] >= upper[i] - tiny(i) && gradient[i] < 0.0;
                !(at_lower || at_upper)
            })
            .collect();
        let projected_gradient = free.iter().map(|&i| gradient[i].abs()).fold(0.0, f64::max);
        if free.is_empty() || projected_gradient <= 1e-14 * (1.0 + current_cost) {
            stop = LmStop::GradientConverged;
            break;
        }
        let m = free.len();
        let mut a = DMatrix::zeros(m, m);
        let mut b = DVector::zeros(m);
        for (p, &i) in free.iter().enumerate() {
            b[p] = -gradient[i];
            for (q, &k) in free.iter().enumerate() {
                a[(p, q)] = normal[(i, k)];
            }
        }
        // Marquardt's scaling, floored so that a parameter the data do not
        // touch still gets a finite step.
        let diagonal_scale = (0..m).map(|p| a[(p, p)]).fold(0.0, f64::max);
        let mut delta = vec![0.0; n];
        let solved = {
            let mut damped = a.clone();
            for p in 0..m {
                damped[(p, p)] += damping * a[(p, p)].max(1e-12 * diagonal_scale.max(1e-300));
            }
            damped.cholesky().map(|c| c.solve(&b))
        };
        let Some(step_free) = solved else {
            damping *= 10.0;
            let it = LmIteration {
                iteration,
                cost: current_cost,
                damping,
                step: 0.0,
                accepted: false,
                theta: theta.clone(),
                failure: Some("the damped normal equations are singular".into()),
            };
            on_iteration(&it);
            history.push(it);
            continue;
        };
        let mut trial = theta.clone();
        for (p, &i) in free.iter().enumerate() {
            trial[i] += step_free[p];
        }
        project(&mut trial);
        for i in 0..n {
            delta[i] = trial[i] - theta[i];
        }
        let step_norm = delta.iter().map(|d| d * d).sum::<f64>().sqrt();
        let theta_norm = theta.iter().map(|t| t * t).sum::<f64>().sqrt();
        if step_norm <= settings.tolerance * (theta_norm + settings.tolerance) {
            stop = LmStop::StepConverged;
            break;
        }
        // Predicted reduction of the projected step by the linear model.
        let d = DVector::from_vec(delta.clone());
        let jd = j * &d;
        let predicted = -(gradient.dot(&d) + 0.5 * jd.norm_squared());
        evaluations += 1;
        let (accepted, failure) = match model(&trial) {
            Ok(next) => {
                let next_cost = cost(&next.residual);
                let rho = if predicted > 0.0 {
                    (current_cost - next_cost) / predicted
                } else {
                    -1.0
                };
                if next_cost < current_cost && rho > 1e-4 {
                    let decrease = (current_cost - next_cost) / current_cost.max(1e-300);
                    theta = trial;
                    current = next;
                    current_cost = next_cost;
                    damping = if rho > 0.75 {
                        (damping / 3.0).max(1e-12)
                    } else if rho < 0.25 {
                        damping * 2.0
                    } else {
                        damping
                    };
                    let it = LmIteration {
                        iteration,
                        cost: current_cost,
                        damping,
                        step: step_norm,
                        accepted: true,
                        theta: theta.clone(),
                        failure: None,
                    };
                    on_iteration(&it);
                    history.push(it);
                    let dof = current.residual.len().saturating_sub(n) as f64;
                    let noisy = 2.0 * current_cost >= 0.5 * dof && dof > 0.0;
                    let chi2_drop = 2.0 * (history[history.len() - 2].cost - current_cost);
                    if decrease < settings.tolerance || (noisy && chi2_drop < settings.chi2_change)
                    {
                        stop = LmStop::CostConverged;
                        break;
                    }
                    continue;
                }
                (false, None)
            }
            Err(why) => (false, Some(why)),
        };
        damping *= 10.0;
        let it = LmIteration {
            iteration,
            cost: current_cost,
            damping,
            step: step_norm,
            accepted,
            theta: theta.clone(),
            failure,
        };
        on_iteration(&it);
        history.push(it);
        if damping > 1e12 {
            stop = LmStop::NoDecrease;
            break;
        }
    }
    LmResult {
        theta,
        at_best: Some(current),
        history,
        stop,
        evaluations,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rosenbrock as least squares: r = (10 (y − x²), 1 − x).
    fn rosenbrock(t: &[f64]) -> Result<Linearisation, String> {
        let (x, y) = (t[0], t[1]);
        Ok(Linearisation {
            residual: DVector::from_vec(vec![10.0 * (y - x * x), 1.0 - x]),
            jacobian: DMatrix::from_row_slice(2, 2, &[-20.0 * x, 10.0, -1.0, 0.0]),
        })
    }

    #[test]
    fn finds_the_minimum_of_rosenbrock() {
        let result = minimise(
            &[-1.2, 1.0],
            &[-5.0, -5.0],
            &[5.0, 5.0],
            &LmSettings {
                max_iterations: 200,
                tolerance: 1e-12,
                ..Default::default()
            },
            rosenbrock,
            |_| {},
            || false,
        );
        // The minimum (1, 1) is exact; the tolerance 1e-12 on the step
        // leaves about 1e-6 on x (cost ~ (x−1)²).
        assert!((result.theta[0] - 1.0).abs() < 1e-6, "{:?}", result.theta);
        assert!((result.theta[1] - 1.0).abs() < 1e-6, "{:?}", result.theta);
    }

    #[test]
    fn stops_on_a_bound_that_excludes_the_minimum() {
        // Minimum at (1, 1) but x ≤ 0.5: the constrained optimum is x = 0.5,
        // y = 0.25 (r1 = 0 there).
        let result = minimise(
            &[-1.2, 1.0],
            &[-5.0, -5.0],
            &[0.5, 5.0],
            &LmSettings {
                max_iterations: 200,
                tolerance: 1e-12,
                ..Default::default()
            },
            rosenbrock,
            |_| {},
            || false,
        );
        assert!((result.theta[0] - 0.5).abs() < 1e-9, "{:?}", result.theta);
        assert!((result.theta[1] - 0.25).abs() < 1e-6, "{:?}", result.theta);
    }

    #[test]
    fn a_failed_trial_point_shrinks_the_step() {
        // The model refuses x > 0.9: the fit must still reach x ≤ 0.9 best.
        let mut refused = 0;
        let result = minimise(
            &[-1.2, 1.0],
            &[-5.0, -5.0],
            &[5.0, 5.0],
            &LmSettings {
                max_iterations: 200,
                tolerance: 1e-10,
                ..Default::default()
            },
            |t| {
                if t[0] > 0.9 {
                    refused += 1;
                    Err("refused".into())
                } else {
                    rosenbrock(t)
                }
            },
            |_| {},
            || false,
        );
        assert!(refused > 0);
        assert!(
            result.theta[0] <= 0.9 && result.theta[0] > 0.8,
            "{:?}",
            result.theta
        );
    }
}
