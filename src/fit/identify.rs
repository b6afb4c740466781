//! What the data determine: uncertainty, correlation and the weakly
//! determined parameter combinations from the Jacobian at the optimum
//! (`docs/fit.md`, "What the data determine").
//!
//! With the weighted residual `r_i = (sim_i − meas_i)/σ_i`, its Jacobian
//! `J_θ` in the scaled parameters `θ` and `D = diag(dp/dθ)`:
//!
//! ```text
//! J_θ = U Σ Vᵀ                                (singular values Σ)
//! Cov_θ ≈ s² V Σ⁻² Vᵀ,   s² = max(1, χ²/(n − p)),   χ² = ‖r‖²
//! Cov_p = D Cov_θ D      (σ of the parameter itself, not of its logarithm)
//! ```
//!
//! In logarithmic parameters a singular value `σ_k` means that the
//! combination `v_k` (a unit vector of log-parameters) is known to
//! `s/σ_k`: below `1/0.25 = 4` that is worse than about 25 % — the
//! threshold of a weak direction. The estimate treats the noise of
//! neighbouring points as independent and the model as exact: serially
//! correlated noise and model error make it optimistic.

use nalgebra::DMatrix;

/// The relative 1σ above which a parameter is called poorly determined.
pub const RELATIVE_SIGMA_LIMIT: f64 = 0.25;

/// Singular values below this (of the weighted Jacobian in scaled
/// parameters) mark a weakly determined combination: `1 /
/// RELATIVE_SIGMA_LIMIT`, the singular value at which a combination of
/// log-parameters is known to 25 %.
pub const WEAK_SINGULAR_VALUE: f64 = 1.0 / RELATIVE_SIGMA_LIMIT;

/// A weakly determined combination of parameters.
#[derive(Debug, Clone, PartialEq)]
pub struct WeakDirection {
    /// Its singular value.
    pub singular_value: f64,
    /// The right singular vector: `(parameter index, weight)`, the largest
    /// weights first, those below 0.1 left out.
    pub combination: Vec<(usize, f64)>,
}

/// Uncertainty and conditioning at the optimum.
#[derive(Debug, Clone, PartialEq)]
pub struct Identifiability {
    /// `χ² = ‖r‖²`.
    pub chi2: f64,
    /// Degrees of freedom `n − p`.
    pub dof: usize,
    /// The variance factor `s² = max(1, χ²/(n − p))`.
    pub variance_factor: f64,
    /// 1σ of every parameter (in its own unit); infinite where the data
    /// do not determine it at all.
    pub sigma: Vec<f64>,
    /// The correlation matrix of the parameters (0 where a σ is infinite).
    pub correlation: Vec<Vec<f64>>,
    /// The singular values of the weighted, scaled Jacobian, largest first.
    pub singular_values: Vec<f64>,
    /// The weakly determined combinations.
    pub weak: Vec<WeakDirection>,
}

/// The identifiability of `p` parameters from the weighted Jacobian
/// `jacobian` (`n × p`, in scaled parameters), the residual's `chi2` and
/// `dp/dθ` per parameter.
pub fn identifiability(jacobian: &DMatrix<f64>, chi2: f64, dp_dtheta: &[f64]) -> Identifiability {
    let (n, p) = jacobian.shape();
    let dof = n.saturating_sub(p);
    let variance_factor = if dof > 0 {
        (chi2 / dof as f64).max(1.0)
    } else {
        1.0
    };
    let svd = jacobian.clone().svd(false, true);
    let v_t = svd.v_t.unwrap_or_else(|| DMatrix::identity(p, p));
    let mut order: Vec<usize> = (0..svd.singular_values.len()).collect();
    order.sort_by(|a, b| svd.singular_values[*b].total_cmp(&svd.singular_values[*a]));
    let singular_values: Vec<f64> = order.iter().map(|&k| svd.singular_values[k]).collect();
    let largest = singular_values.first().copied().unwrap_or(0.0);
    // Singular values at round-off of the largest carry no information.
    let cutoff = largest * 1e-13 * (n.max(p) as f64);
    let mut cov_theta = DMatrix::<f64>::zeros(p, p);
    let mut undetermined = vec![false; p];
    for &k in &order {
        let s = svd.singular_values[k];
        let row = v_t.row(k);
        if s <= cutoff {
            for i in 0..p {
                if row[i].abs() > 1e-8 {
                    undetermined[i] = true;
                }
            }
            continue;
        }
        let w = variance_factor / (s * s);
        for i in 0..p {
            for j in 0..p {
                cov_theta[(i, j)] += w * row[i] * row[j];
            }
        }
    }
    let sigma: Vec<f64> = (0..p)
        .map(|i| {
            if undetermined[i] || p > n {
                f64::INFINITY
            } else {
                cov_theta[(i, i)].sqrt() * dp_dtheta[i].abs()
            }
        })
        .collect();
    let correlation = (0..p)
        .map(|i| {
            (0..p)
                .map(|j| {
                    let d = (cov_theta[(i, i)] * cov_theta[(j, j)]).sqrt();
                    if i == j {
                        1.0
                    } else if d > 0.0 && sigma[i].is_finite() && sigma[j].is_finite() {
                        (cov_theta[(i, j)] / d).clamp(-1.0, 1.0)
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect();
    let weak = order
        .iter()
        .filter(|&&k| svd.singular_values[k] < WEAK_SINGULAR_VALUE)
        .map(|&k| {
            let row = v_t.row(k);
            let mut combination: Vec<(usize, f64)> = (0..p)
                .map(|i| (i, row[i]))
                .filter(|(_, w)| w.abs() >= 0.1)
                .collect();
            combination.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
            // A sign convention: the largest weight positive.
            if combination.first().is_some_and(|(_, w)| *w < 0.0) {
                combination.iter_mut().for_each(|(_, w)| *w = -*w);
            }
            WeakDirection {
                singular_value: svd.singular_values[k],
                combination,
            }
        })
        .collect();
    Identifiability {
        chi2,
        dof,
        variance_factor,
        sigma,
        correlation,
        singular_values,
        weak,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn linear_regression_gives_the_textbook_covariance() {
        // y = a + b x with unit noise at x = 0..5: Cov = (XᵀX)⁻¹ exactly.
        let xs = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0];
        let j = DMatrix::from_fn(6, 2, |i, k| if k == 0 { 1.0 } else { xs[i] });
        let id = identifiability(&j, 4.0, &[1.0, 1.0]);
        let (sx, sxx, n) = (15.0_f64, 55.0_f64, 6.0_f64);
        let det = n * sxx - sx * sx;
        assert!((id.sigma[0] - (sxx / det).sqrt()).abs() < 1e-12);
        assert!((id.sigma[1] - (n / det).sqrt()).abs() < 1e-12);
        let rho = -sx / (sxx * n).sqrt();
        assert!((id.correlation[0][1] - rho).abs() < 1e-12);
        // χ²/dof = 1 < 1: s² = 1.
        assert_eq!(id.variance_factor, 1.0);
        assert_eq!(id.dof, 4);
    }

    #[test]
    fn a_parameter_the_data_do_not_touch_is_undetermined_and_weak() {
        let j = DMatrix::from_row_slice(3, 2, &[10.0, 0.0, 20.0, 0.0, 30.0, 0.0]);
        let id = identifiability(&j, 1.0, &[1.0, 1.0]);
        assert!(id.sigma[0].is_finite());
        assert!(id.sigma[1].is_infinite());
        assert_eq!(id.weak.len(), 1);
        assert_eq!(id.weak[0].combination[0].0, 1);
    }

    #[test]
    fn sigma_is_of_the_parameter_not_of_its_logarithm() {
        // θ = ln p, dp/dθ = p = 2: σ_p = 2 σ_θ.
        let j = DMatrix::from_row_slice(2, 1, &[1.0, 1.0]);
        let id = identifiability(&j, 0.0, &[2.0]);
        assert!((id.sigma[0] - 2.0 / 2f64.sqrt()).abs() < 1e-12);
    }
}
