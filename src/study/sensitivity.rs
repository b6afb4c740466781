//! Global sensitivity estimators on the outputs of the designs of
//! [`crate::study::design`]: Sobol' variance-based indices on a Saltelli
//! design, Morris elementary effects on a Morris design.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use crate::study::design::MorrisDesign;

/// Why sensitivity indices cannot be computed from the given outputs.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SensitivityError {
    /// A size argument is too small.
    #[error("{what} must be at least {min}, got {got}")]
    TooSmall {
        /// Which argument.
        what: &'static str,
        /// Smallest value allowed.
        min: usize,
        /// Value given.
        got: usize,
    },
    /// The number of outputs does not match the design.
    #[error("{what}: expected {expected} values, got {got}")]
    Length {
        /// Which input.
        what: &'static str,
        /// Length required by the design.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// An output is NaN or infinite (a failed point) where the estimator
    /// cannot do without it.
    #[error("output y[{row}] = {value} is not finite (failed point)")]
    NonFinite {
        /// Row of the design.
        row: usize,
        /// The value.
        value: f64,
    },
    /// The outputs of A and B do not vary, so no index is defined.
    #[error("the output variance over A and B is {variance}: indices are undefined")]
    ZeroVariance {
        /// The variance found.
        variance: f64,
    },
    /// A factor scale is not a finite positive number.
    #[error("scale[{factor}] = {value} must be finite and > 0")]
    Scale {
        /// Factor index.
        factor: usize,
        /// The value.
        value: f64,
    },
    /// A Morris step refers to a point or factor that is not in the design,
    /// or has a zero or non-finite step.
    #[error("Morris step {step} is inconsistent with the design: {reason}")]
    Step {
        /// Index into `MorrisDesign::steps`.
        step: usize,
        /// What is wrong.
        reason: String,
    },
}

/// Sobol' sensitivity indices with bootstrap 95 % confidence half-widths.
#[derive(Debug, Clone, PartialEq)]
pub struct SobolIndices {
    /// First-order indices S_i (Saltelli et al. 2010 estimator), per factor.
    pub first: Vec<f64>,
    /// Total-effect indices S_Ti (Jansen 1999 estimator), per factor.
    pub total: Vec<f64>,
    /// Bootstrap 95 % half-width of each `first` value (1.96 × bootstrap
    /// standard deviation).
    pub first_ci: Vec<f64>,
    /// Bootstrap 95 % half-width of each `total` value.
    pub total_ci: Vec<f64>,
    /// Output variance V, estimated over the 2n outputs of A and B.
    pub variance: f64,
}

/// Number of bootstrap resamples behind [`SobolIndices::first_ci`] and
/// [`SobolIndices::total_ci`] (200 gives the standard deviation of the
/// replicates to about 5 %).
pub const SOBOL_BOOTSTRAP_RESAMPLES: usize = 200;

/// Fixed seed of the bootstrap, so that [`sobol_indices`] is a pure function.
const SOBOL_BOOTSTRAP_SEED: u64 = 0x5a17_e111_2010_1999;

/// z of the two-sided 95 % normal interval.
const Z95: f64 = 1.959_963_984_540_054;

/// The estimators over the base-sample rows `rows` (indices into 0..n).
fn sobol_estimate(y: &[f64], n: usize, d: usize, rows: &[usize]) -> (Vec<f64>, Vec<f64>, f64) {
    let m = rows.len() as f64;
    let (fa, fb) = (&y[..n], &y[n..2 * n]);
    // V over the 2m outputs of A and B (population variance, as Saltelli 2010).
    let mean = rows.iter().map(|&k| fa[k] + fb[k]).sum::<f64>() / (2.0 * m);
    let variance = rows
        .iter()
        .map(|&k| (fa[k] - mean).powi(2) + (fb[k] - mean).powi(2))
        .sum::<f64>()
        / (2.0 * m);
    let mut first = Vec::with_capacity(d);
    let mut total = Vec::with_capacity(d);
    for i in 0..d {
        let fab = &y[(2 + i) * n..(3 + i) * n];
        let (mut s1, mut st) = (0.0, 0.0);
        for &k in rows {
            s1 += (fb[k] - mean) * (fab[k] - fa[k]);
            st += (fa[k] - fab[k]).powi(2);
        }
        first.push(s1 / m / variance);
        total.push(st / (2.0 * m) / variance);
    }
    (first, total, variance)
}

/// First-order and total Sobol' indices from the outputs `y` of a
/// [`crate::study::design::saltelli`]`(n, d, _)` design, in that order
/// (A, B, AB_0 … AB_{d−1}; len n (d + 2)). With f_A, f_B, f_ABi the
/// outputs of the blocks and V the variance of the 2n outputs of A and B:
///
/// * first order (Saltelli et al. 2010, Table 2 (b)):
///   S_i = (1/n) Σ_j (f_B(j) − f̄) (f_ABi(j) − f_A(j)) / V, with f̄ the mean
///   of the A and B outputs. Centring f_B (as SALib does) keeps the
///   estimator consistent — Σ (f_ABi − f_A) / n → 0 — and stops its
///   variance growing with the square of the output's mean;
/// * total effect (Jansen 1999): S_Ti = (1/(2n)) Σ_j (f_A(j) − f_ABi(j))² / V.
///
/// Confidence half-widths: a bootstrap over the n base rows (rows of A, B
/// and every AB_i resampled together, [`SOBOL_BOOTSTRAP_RESAMPLES`]
/// resamples from a fixed seed, V re-estimated each time), 1.96 × the
/// standard deviation of the replicates (normal bootstrap interval, as in
/// SALib). The bootstrap treats the points as independent, so for a
/// (scrambled) Sobol' design it overstates the error: the interval is
/// conservative.
///
/// Skips nothing: a NaN or infinite output (a failed point) is an error
/// naming its row. A constant output (V = 0) is an error. Requires n ≥ 2.
pub fn sobol_indices(y: &[f64], n: usize, d: usize) -> Result<SobolIndices, SensitivityError> {
    if n < 2 {
        return Err(SensitivityError::TooSmall {
            what: "base sample size n",
            min: 2,
            got: n,
        });
    }
    if d < 1 {
        return Err(SensitivityError::TooSmall {
            what: "number of factors d",
            min: 1,
            got: d,
        });
    }
    let expected = d
        .checked_add(2)
        .and_then(|k| k.checked_mul(n))
        .unwrap_or(usize::MAX);
    if y.len() != expected {
        return Err(SensitivityError::Length {
            what: "y (n (d + 2) outputs)",
            expected,
            got: y.len(),
        });
    }
    if let Some(row) = y.iter().position(|v| !v.is_finite()) {
        return Err(SensitivityError::NonFinite { row, value: y[row] });
    }
    let all: Vec<usize> = (0..n).collect();
    let (first, total, variance) = sobol_estimate(y, n, d, &all);
    if variance.is_nan() || variance <= 0.0 {
        return Err(SensitivityError::ZeroVariance { variance });
    }
    let mut rng = StdRng::seed_from_u64(SOBOL_BOOTSTRAP_SEED);
    let mut rows = vec![0usize; n];
    let (mut sum1, mut sq1) = (vec![0.0; d], vec![0.0; d]);
    let (mut sumt, mut sqt) = (vec![0.0; d], vec![0.0; d]);
    let mut used = 0usize;
    for _ in 0..SOBOL_BOOTSTRAP_RESAMPLES {
        rows.iter_mut().for_each(|k| *k = rng.random_range(0..n));
        let (f, t, v) = sobol_estimate(y, n, d, &rows);
        if v.is_nan() || v <= 0.0 {
            // A resample of identical outputs: no replicate (only possible
            // for tiny n).
            continue;
        }
        used += 1;
        for i in 0..d {
            sum1[i] += f[i];
            sq1[i] += f[i] * f[i];
            sumt[i] += t[i];
            sqt[i] += t[i] * t[i];
        }
    }
    let half_width = |sum: &[f64], sq: &[f64]| -> Vec<f64> {
        if used < 2 {
            return vec![f64::NAN; d];
        }
        let b = used as f64;
        sum.iter()
            .zip(sq)
            .map(|(s, q)| Z95 * ((q - s * s / b) / (b - 1.0)).max(0.0).sqrt())
            .collect()
    };
    Ok(SobolIndices {
        first_ci: half_width(&sum1, &sq1),
        total_ci: half_width(&sumt, &sqt),
        first,
        total,
        variance,
    })
}

/// Morris elementary-effect statistics per factor.
#[derive(Debug, Clone, PartialEq)]
pub struct MorrisEffects {
    /// Mean of the elementary effects (Morris 1991); NaN when `count` is 0.
    pub mu: Vec<f64>,
    /// Mean of their absolute values (Campolongo, Cariboni & Saltelli 2007);
    /// NaN when `count` is 0.
    pub mu_star: Vec<f64>,
    /// Sample standard deviation (n − 1 denominator) of the effects (Morris
    /// 1991); NaN when `count` < 2.
    pub sigma: Vec<f64>,
    /// Number of elementary effects behind each factor's statistics.
    pub count: Vec<usize>,
}

/// Morris elementary effects: per factor μ (Morris 1991), μ* (mean of |EE|,
/// Campolongo et al. 2007) and σ, from the design's steps and the outputs
/// `y` (one per design point). For a step from point a to point b changing
/// factor i by δ (unit-cube coordinates), EE = (y_b − y_a) / (δ scale[i]);
/// with `scale[i]` = hi_i − lo_i, the factor's physical range, the effects
/// are derivatives in output units per physical unit (use 1.0 for effects
/// per unit-cube step).
///
/// A failed point is given as NaN (any non-finite y counts as failed): the
/// steps touching it are skipped and `count` reports how many effects each
/// factor kept.
pub fn morris_effects(
    design: &MorrisDesign,
    y: &[f64],
    scale: &[f64],
) -> Result<MorrisEffects, SensitivityError> {
    let points = design.points.len();
    if y.len() != points {
        return Err(SensitivityError::Length {
            what: "y (one output per design point)",
            expected: points,
            got: y.len(),
        });
    }
    let d = design.points.first().map_or(0, Vec::len);
    if scale.len() != d {
        return Err(SensitivityError::Length {
            what: "scale (one per factor)",
            expected: d,
            got: scale.len(),
        });
    }
    if let Some(factor) = scale.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
        return Err(SensitivityError::Scale {
            factor,
            value: scale[factor],
        });
    }
    let mut effects: Vec<Vec<f64>> = vec![Vec::new(); d];
    for (index, s) in design.steps.iter().enumerate() {
        let bad = |reason: String| {
            Err(SensitivityError::Step {
                step: index,
                reason,
            })
        };
        if s.from >= points || s.to >= points {
            return bad(format!("points {} -> {} of {points}", s.from, s.to));
        }
        if s.factor >= d {
            return bad(format!("factor {} of {d}", s.factor));
        }
        if !(s.delta.is_finite() && s.delta != 0.0) {
            return bad(format!("step delta {}", s.delta));
        }
        let (ya, yb) = (y[s.from], y[s.to]);
        if ya.is_finite() && yb.is_finite() {
            effects[s.factor].push((yb - ya) / (s.delta * scale[s.factor]));
        }
    }
    let mut out = MorrisEffects {
        mu: Vec::with_capacity(d),
        mu_star: Vec::with_capacity(d),
        sigma: Vec::with_capacity(d),
        count: Vec::with_capacity(d),
    };
    for ee in &effects {
        let k = ee.len() as f64;
        let mu = ee.iter().sum::<f64>() / k;
        out.mu.push(mu);
        out.mu_star
            .push(ee.iter().map(|e| e.abs()).sum::<f64>() / k);
        out.sigma.push(if ee.len() < 2 {
            f64::NAN
        } else {
            (ee.iter().map(|e| (e - mu).powi(2)).sum::<f64>() / (k - 1.0)).sqrt()
        });
        out.count.push(ee.len());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::study::design::{Marginal, morris, saltelli};
    use std::f64::consts::PI;

    /// Maps unit-cube rows to physical values through uniform marginals.
    fn physical(points: &[Vec<f64>], m: &[Marginal]) -> Vec<Vec<f64>> {
        points
            .iter()
            .map(|p| p.iter().zip(m).map(|(&u, m)| m.value(u)).collect())
            .collect()
    }

    fn ishigami(x: &[f64]) -> f64 {
        let (a, b) = (7.0, 0.1);
        x[0].sin() + a * x[1].sin().powi(2) + b * x[2].powi(4) * x[0].sin()
    }

    /// |est − exact| < max(3 ci, 0.02): `ci` is a 1.96 σ bootstrap
    /// half-width, so 3 ci ≈ 5.9 σ (a false failure for another seed is then
    /// very unlikely; the bootstrap treats the Sobol' points as independent
    /// and so overstates the error of a QMC design, making this
    /// conservative). The 0.02 floor serves indices whose replicate spread
    /// is tiny (ST of a weak factor, ci ≈ 0.002) against the estimator's
    /// O(1/n) bias and the ±5 % noise of a 200-resample σ; it is well below
    /// the gaps a wrong estimator would show (0.13 between S1_0 and S1_1 of
    /// Ishigami, 0.048 for the weakest linear factor). The intervals are
    /// also bounded (`max_ci`) so the test cannot pass on wide intervals.
    fn check(what: &str, est: &[f64], ci: &[f64], exact: &[f64], max_ci: f64) {
        for i in 0..exact.len() {
            let tol = (3.0 * ci[i]).max(0.02);
            assert!(
                (est[i] - exact[i]).abs() < tol,
                "{what}[{i}] = {} ± {}, exact {}",
                est[i],
                ci[i],
                exact[i]
            );
            assert!(ci[i] < max_ci, "{what}[{i}]: ci {} too wide", ci[i]);
        }
    }

    #[test]
    fn sobol_ishigami() {
        let (n, d) = (8192, 3);
        let m = vec![Marginal::Uniform { lo: -PI, hi: PI }; 3];
        let x = physical(&saltelli(n, d, 42).unwrap(), &m);
        let y: Vec<f64> = x.iter().map(|p| ishigami(p)).collect();
        let s = sobol_indices(&y, n, d).unwrap();
        // Analytic values (Ishigami & Homma 1990; Saltelli et al. 2008):
        // V = a²/8 + b π⁴/5 + b² π⁸/18 + 1/2 = 13.8446, V1 = (1 + b π⁴/5)²/2,
        // V2 = a²/8, V13 = b² π⁸ (1/18 − 1/50).
        let (a, b) = (7.0f64, 0.1f64);
        let v1 = 0.5 * (1.0 + b * PI.powi(4) / 5.0).powi(2);
        let v2 = a * a / 8.0;
        let v13 = b * b * PI.powi(8) * (1.0 / 18.0 - 1.0 / 50.0);
        let v = v1 + v2 + v13;
        assert!((v - 13.8446).abs() < 1e-4);
        let first = [v1 / v, v2 / v, 0.0];
        let total = [(v1 + v13) / v, v2 / v, v13 / v];
        assert!((first[0] - 0.3139).abs() < 1e-4 && (total[2] - 0.2437).abs() < 1e-4);
        // Sample variance of 2n outputs: relative SE ≈ sqrt(2/(2n)) · sqrt(kurtosis excess
        // + 2)/√2 < 5 %; 10 % is generous.
        assert!((s.variance - v).abs() < 0.1 * v, "V = {}", s.variance);
        check("S1", &s.first, &s.first_ci, &first, 0.05);
        check("ST", &s.total, &s.total_ci, &total, 0.05);
    }

    #[test]
    fn sobol_linear_model() {
        let (n, d) = (4096, 3);
        let c = [1.0, -2.0, 0.5];
        let m = vec![
            Marginal::Uniform { lo: 0.0, hi: 1.0 },
            Marginal::Uniform { lo: 10.0, hi: 12.0 },
            Marginal::Uniform { lo: -3.0, hi: 1.0 },
        ];
        let x = physical(&saltelli(n, d, 7).unwrap(), &m);
        let y: Vec<f64> = x
            .iter()
            .map(|p| p.iter().zip(&c).map(|(x, c)| x * c).sum())
            .collect();
        // Var(c_i X_i) = c_i² (hi − lo)² / 12; additive, so S1 = ST.
        let width = [1.0, 2.0, 4.0];
        let vi: Vec<f64> = (0..3).map(|i| (c[i] * width[i]).powi(2) / 12.0).collect();
        let sum: f64 = vi.iter().sum();
        let exact: Vec<f64> = vi.iter().map(|v| v / sum).collect();
        let s = sobol_indices(&y, n, d).unwrap();
        check("S1", &s.first, &s.first_ci, &exact, 0.05);
        check("ST", &s.total, &s.total_ci, &exact, 0.05);
    }

    #[test]
    fn sobol_errors() {
        let (n, d) = (8, 2);
        let mut y: Vec<f64> = (0..n * (d + 2)).map(|k| k as f64).collect();
        assert!(matches!(
            sobol_indices(&y[1..], n, d),
            Err(SensitivityError::Length { .. })
        ));
        y[13] = f64::NAN;
        assert!(matches!(
            sobol_indices(&y, n, d),
            Err(SensitivityError::NonFinite { row: 13, .. })
        ));
        let flat = vec![1.0; n * (d + 2)];
        assert!(matches!(
            sobol_indices(&flat, n, d),
            Err(SensitivityError::ZeroVariance { .. })
        ));
    }

    #[test]
    fn morris_linear_is_exact() {
        let (r, d) = (20, 3);
        let c = [3.0, -0.25, 0.0];
        let lo = [1.0, -50.0, 0.0];
        let hi = [2.0, 150.0, 1e-3];
        let design = morris(r, d, 4, 9).unwrap();
        let scale: Vec<f64> = (0..d).map(|i| hi[i] - lo[i]).collect();
        let y: Vec<f64> = design
            .points
            .iter()
            .map(|p| (0..d).map(|i| c[i] * (lo[i] + p[i] * scale[i])).sum())
            .collect();
        let e = morris_effects(&design, &y, &scale).unwrap();
        for (i, &ci) in c.iter().enumerate() {
            // Linear: every EE equals c_i up to rounding of y (|y| ≲ 40,
            // ε |y| / (Δ · range) ≪ 1e-12).
            assert!(
                (e.mu_star[i] - ci.abs()).abs() < 1e-12,
                "{i}: {}",
                e.mu_star[i]
            );
            assert!((e.mu[i] - ci).abs() < 1e-12);
            assert!(e.sigma[i] < 1e-12);
            assert_eq!(e.count[i], r);
        }
    }

    #[test]
    fn morris_interaction_and_failed_points() {
        let (r, d) = (30, 2);
        let design = morris(r, d, 4, 1).unwrap();
        let mut y: Vec<f64> = design.points.iter().map(|p| p[0] * p[1]).collect();
        let e = morris_effects(&design, &y, &[1.0, 1.0]).unwrap();
        // ∂(x0 x1)/∂x0 = x1 varies across trajectories: σ > 0. The EE take
        // values in {x1} ⊂ {0, 1/3, 2/3, 1}, so σ is far from rounding.
        assert!(e.sigma[0] > 0.1 && e.sigma[1] > 0.1, "{:?}", e.sigma);
        // A failed interior point (middle of trajectory 0) removes its two steps.
        y[1] = f64::NAN;
        let e = morris_effects(&design, &y, &[1.0, 1.0]).unwrap();
        let touched: Vec<usize> = design
            .steps
            .iter()
            .filter(|s| s.from == 1 || s.to == 1)
            .map(|s| s.factor)
            .collect();
        assert_eq!(touched.len(), 2);
        for i in 0..d {
            let lost = touched.iter().filter(|&&f| f == i).count();
            assert_eq!(e.count[i], r - lost);
        }
        assert!(morris_effects(&design, &y[1..], &[1.0, 1.0]).is_err());
        assert!(matches!(
            morris_effects(&design, &y, &[1.0, 0.0]),
            Err(SensitivityError::Scale { factor: 1, .. })
        ));
    }
}
