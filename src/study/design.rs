//! Designs of experiments for parameter studies: where in factor space to
//! evaluate a case.
//!
//! Every design here is a pure function of its arguments. Random designs
//! take a `u64` seed and return the same points for the same seed on any
//! machine (the generator is `rand`'s `StdRng`, ChaCha12, whose stream is
//! fixed for the `rand` version pinned in `Cargo.lock`; the Sobol' points
//! come from `sobol_burley`, integer arithmetic only).
//!
//! Unit-cube designs ([`latin_hypercube`], [`monte_carlo`], [`saltelli`])
//! return coordinates strictly inside (0, 1), so they may be mapped through
//! any inverse CDF ([`Marginal::value`]) without producing infinities.
//! [`grid`] returns level indices, [`morris`] points on a p-level grid in
//! [0, 1]^d (including the faces).

use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{RngExt, SeedableRng};
use statrs::function::erf::{erfc, erfc_inv};

/// Why a design, or a marginal, cannot be built from the given arguments.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignError {
    /// A size argument (number of points, factors, trajectories …) is zero.
    #[error("{what} must be at least 1, got 0")]
    Empty {
        /// Which argument.
        what: &'static str,
    },
    /// A factor of a full-factorial grid has no levels.
    #[error("factor {factor} has 0 levels")]
    ZeroLevels {
        /// Index of the factor.
        factor: usize,
    },
    /// The design would have more points than allowed (or than `usize` holds).
    #[error(
        "the design has {} points, more than the limit of {limit}",
        .points.map_or_else(|| "more than usize::MAX".to_string(), |p| p.to_string())
    )]
    TooLarge {
        /// Number of points, `None` when it overflows `usize`.
        points: Option<usize>,
        /// The largest number allowed.
        limit: usize,
    },
    /// An argument is beyond what the underlying generator supports.
    #[error("{what} = {got} exceeds the supported maximum {max}")]
    Unsupported {
        /// Which argument.
        what: &'static str,
        /// Its value.
        got: usize,
        /// Largest value supported.
        max: usize,
    },
    /// A marginal distribution's parameters are not admissible.
    #[error("invalid marginal: {reason}")]
    InvalidMarginal {
        /// What is wrong with it.
        reason: String,
    },
    /// Morris designs need an even number of levels, at least 2.
    #[error("Morris designs need an even number of levels >= 2, got {levels}")]
    MorrisLevels {
        /// The number of levels given.
        levels: usize,
    },
    /// Two inputs that must agree in length do not.
    #[error("{what}: expected length {expected}, got {got}")]
    Length {
        /// Which input.
        what: String,
        /// Length required.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A unit-cube coordinate is not strictly inside (0, 1).
    #[error("unit-cube coordinate u[{row}][{col}] = {value} is not strictly inside (0, 1)")]
    UnitCoordinate {
        /// Row (point) index.
        row: usize,
        /// Column (factor) index.
        col: usize,
        /// The offending value.
        value: f64,
    },
    /// A mean or standard deviation is not finite, or a standard deviation is negative.
    #[error("{what}[{index}] = {value} is not admissible (must be finite{extra})")]
    Moment {
        /// `"mean"` or `"sd"`.
        what: &'static str,
        /// Factor index.
        index: usize,
        /// The offending value.
        value: f64,
        /// Further condition violated, e.g. `" and >= 0"`.
        extra: &'static str,
    },
    /// The correlation matrix is not a correlation matrix (entry out of
    /// [-1, 1], diagonal not 1, not symmetric, not finite).
    #[error("correlation matrix entry ({row}, {col}) = {value}: {reason}")]
    Correlation {
        /// Row of the offending entry.
        row: usize,
        /// Column of the offending entry.
        col: usize,
        /// Its value.
        value: f64,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The correlation matrix is not positive semi-definite.
    #[error(
        "correlation matrix is not positive semi-definite: Cholesky pivot ({index}, {index}) = \
         {pivot:e} (the leading {size}x{size} block is indefinite); smallest eigenvalue \
         {min_eigenvalue:e} < -{tolerance:e}"
    )]
    NotPositiveSemiDefinite {
        /// Diagonal entry at which the Cholesky factorisation broke down.
        index: usize,
        /// Size of the leading block that is indefinite (`index + 1`).
        size: usize,
        /// The non-positive pivot found there.
        pivot: f64,
        /// Smallest eigenvalue of the whole matrix.
        min_eigenvalue: f64,
        /// Tolerance on negative eigenvalues ([`EIGENVALUE_TOLERANCE`]).
        tolerance: f64,
    },
}

/// Eigenvalues of a correlation matrix within ±`EIGENVALUE_TOLERANCE` are
/// taken as rounding of a singular (semi-definite) matrix and set to zero by
/// [`correlated_normal`] when its Cholesky factorisation breaks down. A correlation matrix built from data in
/// double precision has eigenvalue errors of order d · 1e-16; 1e-10 leaves
/// several orders of margin while still rejecting any matrix that is
/// meaningfully indefinite.
pub const EIGENVALUE_TOLERANCE: f64 = 1e-10;

/// Largest base sample size of [`saltelli`]: `sobol_burley` supports 2^16
/// points per sequence.
pub const SALTELLI_MAX_N: usize = 1 << 16;

/// Largest number of factors of [`saltelli`]: the design uses 2d Sobol'
/// dimensions and `sobol_burley` provides 256.
pub const SALTELLI_MAX_FACTORS: usize = sobol_burley::NUM_DIMENSIONS as usize / 2;

/// Standard normal inverse CDF, Φ⁻¹(u) = −√2 erfc⁻¹(2u) (statrs' erfc⁻¹,
/// after Boost). −∞ at 0, +∞ at 1, NaN outside [0, 1] or for NaN.
fn normal_quantile(u: f64) -> f64 {
    if !(0.0..=1.0).contains(&u) {
        return f64::NAN;
    }
    -std::f64::consts::SQRT_2 * erfc_inv(2.0 * u)
}

/// Standard normal CDF, Φ(z) = erfc(−z/√2) / 2.
fn normal_cdf(z: f64) -> f64 {
    0.5 * erfc(-z / std::f64::consts::SQRT_2)
}

/// How one factor's values are drawn: maps a unit-cube coordinate u in
/// (0, 1) to a value by the inverse CDF of the distribution (inverse
/// transform sampling), so that a uniform design in u becomes a design with
/// these marginals.
#[derive(Debug, Clone, PartialEq)]
pub enum Marginal {
    /// Uniform on [lo, hi]: value = lo + u (hi − lo).
    Uniform {
        /// Lower bound.
        lo: f64,
        /// Upper bound (> lo).
        hi: f64,
    },
    /// Normal: value = mean + sd Φ⁻¹(u).
    Normal {
        /// Mean.
        mean: f64,
        /// Standard deviation (> 0).
        sd: f64,
    },
    /// Log-normal: value = exp(ln(median) + sigma_log Φ⁻¹(u)).
    LogNormal {
        /// Median (> 0) = exp of the mean of the logarithm.
        median: f64,
        /// Standard deviation of the logarithm (> 0).
        sigma_log: f64,
    },
    /// `inner` truncated to [lo, hi]: value = F⁻¹(F(lo) + u (F(hi) − F(lo)))
    /// with F the CDF of `inner` (inverse CDF restricted to [lo, hi]).
    Truncated {
        /// The distribution before truncation.
        inner: Box<Marginal>,
        /// Lower truncation bound.
        lo: f64,
        /// Upper truncation bound (> lo); [lo, hi] must carry probability
        /// mass of `inner`.
        hi: f64,
    },
}

impl Marginal {
    /// The value at unit-cube coordinate `u` (inverse transform sampling:
    /// the inverse CDF of the distribution at `u`). `u` should be in
    /// (0, 1); u = 0 or 1 gives the (possibly infinite) bounds of the
    /// support, and a `u` outside [0, 1] or NaN gives NaN. Assumes the
    /// marginal passed [`Marginal::validate`].
    pub fn value(&self, u: f64) -> f64 {
        if !(0.0..=1.0).contains(&u) {
            return f64::NAN;
        }
        match self {
            Marginal::Uniform { lo, hi } => lo + u * (hi - lo),
            Marginal::Normal { mean, sd } => mean + sd * normal_quantile(u),
            Marginal::LogNormal { median, sigma_log } => {
                (median.ln() + sigma_log * normal_quantile(u)).exp()
            }
            Marginal::Truncated { inner, lo, hi } => {
                let (flo, fhi) = (inner.cdf(*lo), inner.cdf(*hi));
                inner.value(flo + u * (fhi - flo)).clamp(*lo, *hi)
            }
        }
    }

    /// The cumulative distribution function at `x`: Uniform (x − lo)/(hi − lo)
    /// clamped to [0, 1]; Normal Φ((x − mean)/sd); LogNormal
    /// Φ((ln x − ln median)/sigma_log) for x > 0, else 0; Truncated
    /// (F(clamp(x)) − F(lo)) / (F(hi) − F(lo)).
    pub fn cdf(&self, x: f64) -> f64 {
        match self {
            Marginal::Uniform { lo, hi } => ((x - lo) / (hi - lo)).clamp(0.0, 1.0),
            Marginal::Normal { mean, sd } => normal_cdf((x - mean) / sd),
            Marginal::LogNormal { median, sigma_log } => {
                if x <= 0.0 {
                    0.0
                } else {
                    normal_cdf((x.ln() - median.ln()) / sigma_log)
                }
            }
            Marginal::Truncated { inner, lo, hi } => {
                let (flo, fhi) = (inner.cdf(*lo), inner.cdf(*hi));
                ((inner.cdf(x.clamp(*lo, *hi)) - flo) / (fhi - flo)).clamp(0.0, 1.0)
            }
        }
    }

    /// Checks the parameters: finite bounds with lo < hi; finite mean and
    /// sd > 0; finite median > 0 and sigma_log > 0; for a truncation, a
    /// valid inner marginal and an interval carrying probability mass.
    pub fn validate(&self) -> Result<(), DesignError> {
        let bad = |reason: String| Err(DesignError::InvalidMarginal { reason });
        match self {
            Marginal::Uniform { lo, hi } | Marginal::Truncated { lo, hi, .. }
                if !(lo.is_finite() && hi.is_finite() && lo < hi) =>
            {
                bad(format!("bounds [{lo}, {hi}] must be finite with lo < hi"))
            }
            Marginal::Uniform { .. } => Ok(()),
            Marginal::Normal { mean, sd } => {
                if mean.is_finite() && sd.is_finite() && *sd > 0.0 {
                    Ok(())
                } else {
                    bad(format!(
                        "normal mean {mean} and sd {sd}: need finite mean and sd > 0"
                    ))
                }
            }
            Marginal::LogNormal { median, sigma_log } => {
                if median.is_finite() && *median > 0.0 && sigma_log.is_finite() && *sigma_log > 0.0
                {
                    Ok(())
                } else {
                    bad(format!(
                        "log-normal median {median} and sigma_log {sigma_log}: need both finite and > 0"
                    ))
                }
            }
            Marginal::Truncated { inner, lo, hi } => {
                inner.validate()?;
                if inner.cdf(*hi) - inner.cdf(*lo) > 0.0 {
                    Ok(())
                } else {
                    bad(format!(
                        "truncation [{lo}, {hi}] has no probability mass under the inner marginal"
                    ))
                }
            }
        }
    }
}

/// A full-factorial grid over factors with `counts[i]` levels each: every
/// combination of level indices, first factor slowest, last fastest (row k
/// is k written in the mixed radix `counts`). `counts = [3, 2]` gives
/// [0,0], [0,1], [1,0], [1,1], [2,0], [2,1].
///
/// Errors if there are no factors, any count is 0, or the product of the
/// counts overflows `usize` or exceeds `limit`.
pub fn grid(counts: &[usize], limit: usize) -> Result<Vec<Vec<usize>>, DesignError> {
    if counts.is_empty() {
        return Err(DesignError::Empty {
            what: "number of factors",
        });
    }
    if let Some(factor) = counts.iter().position(|&c| c == 0) {
        return Err(DesignError::ZeroLevels { factor });
    }
    let total = counts.iter().try_fold(1usize, |p, &c| p.checked_mul(c));
    let total = match total {
        Some(t) if t <= limit => t,
        points => return Err(DesignError::TooLarge { points, limit }),
    };
    let mut rows = Vec::with_capacity(total);
    let mut index = vec![0usize; counts.len()];
    for _ in 0..total {
        rows.push(index.clone());
        // Odometer increment, last factor fastest.
        for (i, &c) in index.iter_mut().zip(counts).rev() {
            *i += 1;
            if *i < c {
                break;
            }
            *i = 0;
        }
    }
    Ok(rows)
}

fn check_size(n: usize, d: usize) -> Result<(), DesignError> {
    if n == 0 {
        return Err(DesignError::Empty {
            what: "number of points",
        });
    }
    if d == 0 {
        return Err(DesignError::Empty {
            what: "number of factors",
        });
    }
    if n.checked_mul(d).is_none() {
        return Err(DesignError::TooLarge {
            points: None,
            limit: usize::MAX,
        });
    }
    Ok(())
}

/// A uniform draw strictly inside (0, 1): the centre of one of 2^53 equal
/// cells, (k + 1/2) 2^-53 with k uniform in 0..2^53.
fn open_unit(rng: &mut StdRng) -> f64 {
    ((rng.random::<u64>() >> 11) as f64 + 0.5) * (1.0 / (1u64 << 53) as f64)
}

/// Latin hypercube sample (McKay, Beckman & Conover 1979): `n` points in
/// (0, 1)^`d`. In every dimension, the interval is cut into `n` equal strata
/// [k/n, (k+1)/n) and each stratum holds exactly one point; the strata are
/// paired across dimensions by independent random permutations and each
/// point lies at a uniform random position within its stratum, (k + v)/n
/// with v = (j + 1/2) 2^-32, j uniform in 0..2^32 (so never on a stratum
/// face). Deterministic from `seed` (same seed, same points on any machine).
pub fn latin_hypercube(n: usize, d: usize, seed: u64) -> Result<Vec<Vec<f64>>, DesignError> {
    check_size(n, d)?;
    let mut rng = StdRng::seed_from_u64(seed);
    let mut points = vec![vec![0.0; d]; n];
    let mut strata: Vec<usize> = (0..n).collect();
    let nf = n as f64;
    for col in 0..d {
        strata.shuffle(&mut rng);
        for (point, &k) in points.iter_mut().zip(&strata) {
            let v = (rng.random::<u32>() as f64 + 0.5) / 4_294_967_296.0;
            // The clamp only bites for n > 2^19, where k + v may round to
            // k + 1 and the last stratum's point to 1.
            point[col] = ((k as f64 + v) / nf).clamp(f64::MIN_POSITIVE, 1.0 - f64::EPSILON / 2.0);
        }
    }
    Ok(points)
}

/// Plain Monte Carlo sample: `n` independent uniform points in (0, 1)^`d`,
/// each coordinate (k + 1/2) 2^-53 with k uniform in 0..2^53, drawn row by
/// row from `seed`.
pub fn monte_carlo(n: usize, d: usize, seed: u64) -> Result<Vec<Vec<f64>>, DesignError> {
    check_size(n, d)?;
    let mut rng = StdRng::seed_from_u64(seed);
    Ok((0..n)
        .map(|_| (0..d).map(|_| open_unit(&mut rng)).collect())
        .collect())
}

/// A factor F with F Fᵀ = `corr`: the Cholesky factor when `corr` is
/// positive definite; otherwise, when its smallest eigenvalue is
/// ≥ −[`EIGENVALUE_TOLERANCE`] (semi-definite up to rounding), the
/// factor Q diag(√λ) from the eigen-decomposition (nalgebra's
/// `SymmetricEigen`), with eigenvalues in ±[`EIGENVALUE_TOLERANCE`] set to
/// zero. Else the error names the Cholesky pivot at which it broke down.
fn correlation_factor(corr: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, DesignError> {
    let d = corr.len();
    let mut l = vec![vec![0.0; d]; d];
    let mut failed = None;
    'outer: for j in 0..d {
        let pivot = corr[j][j] - l[j][..j].iter().map(|x| x * x).sum::<f64>();
        if pivot <= 0.0 || !pivot.is_finite() {
            failed = Some((j, pivot));
            break 'outer;
        }
        let ljj = pivot.sqrt();
        l[j][j] = ljj;
        for i in j + 1..d {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            l[i][j] = (corr[i][j] - s) / ljj;
        }
    }
    let Some((index, pivot)) = failed else {
        return Ok(l);
    };
    let m = nalgebra::DMatrix::from_fn(d, d, |i, j| corr[i][j]);
    let eig = nalgebra::SymmetricEigen::new(m);
    let min_eigenvalue = eig
        .eigenvalues
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    if min_eigenvalue.is_nan() || min_eigenvalue < -EIGENVALUE_TOLERANCE {
        return Err(DesignError::NotPositiveSemiDefinite {
            index,
            size: index + 1,
            pivot,
            min_eigenvalue,
            tolerance: EIGENVALUE_TOLERANCE,
        });
    }
    // Eigenvalues within ±tolerance are rounding of exact zeros: set them to
    // zero, so that e.g. perfectly correlated factors come out equal to
    // rounding (a kept 1e-16 would leave a 1e-8 component along its vector).
    let root: Vec<f64> = eig
        .eigenvalues
        .iter()
        .map(|&x| {
            if x > EIGENVALUE_TOLERANCE {
                x.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    Ok((0..d)
        .map(|i| (0..d).map(|k| eig.eigenvectors[(i, k)] * root[k]).collect())
        .collect())
}

/// Correlated normal sample: `u.len()` points of d = `mean.len()` values
/// with means `mean`, standard deviations `sd` and correlation matrix `corr`
/// (Gaussian copula by inverse transform). Built on a unit-cube design `u`
/// (n × d, strictly inside (0, 1), e.g. from [`latin_hypercube`] or
/// [`monte_carlo`]): z = Φ⁻¹(u), x = mean + diag(sd) L z, with L L ᵀ = corr.
///
/// `corr` must be d × d, finite, symmetric (to 1e-12), with unit diagonal
/// (to 1e-12) and entries in [−1, 1]. L is its Cholesky factor; a matrix
/// that is only positive *semi*-definite (a zero or tiny negative pivot,
/// e.g. perfectly correlated factors) falls back to the eigen-decomposition
/// corr = Q Λ Qᵀ with eigenvalues within ±[`EIGENVALUE_TOLERANCE`] set to
/// zero and L = Q Λ^½ (no jitter is added, so the correlation is
/// reproduced to within that tolerance). A matrix with a more negative
/// eigenvalue is an error naming the Cholesky pivot (diagonal entry) at
/// which the factorisation broke down.
pub fn correlated_normal(
    u: &[Vec<f64>],
    mean: &[f64],
    sd: &[f64],
    corr: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>, DesignError> {
    let d = mean.len();
    check_size(u.len(), d)?;
    let length = |what: &str, expected: usize, got: usize| {
        if expected == got {
            Ok(())
        } else {
            Err(DesignError::Length {
                what: what.to_string(),
                expected,
                got,
            })
        }
    };
    length("sd", d, sd.len())?;
    length("corr (rows)", d, corr.len())?;
    for (i, row) in corr.iter().enumerate() {
        length(&format!("corr row {i}"), d, row.len())?;
    }
    for (i, row) in u.iter().enumerate() {
        length(&format!("u row {i}"), d, row.len())?;
        if let Some(col) = row.iter().position(|x| !(*x > 0.0 && *x < 1.0)) {
            return Err(DesignError::UnitCoordinate {
                row: i,
                col,
                value: row[col],
            });
        }
    }
    for (index, &value) in mean.iter().enumerate() {
        if !value.is_finite() {
            return Err(DesignError::Moment {
                what: "mean",
                index,
                value,
                extra: "",
            });
        }
    }
    for (index, &value) in sd.iter().enumerate() {
        if !(value.is_finite() && value >= 0.0) {
            return Err(DesignError::Moment {
                what: "sd",
                index,
                value,
                extra: " and >= 0",
            });
        }
    }
    const SYMMETRY: f64 = 1e-12;
    for (i, row) in corr.iter().enumerate() {
        for (j, &value) in row.iter().enumerate() {
            let reason = if !value.is_finite() {
                Some("not finite")
            } else if i == j && (value - 1.0).abs() > SYMMETRY {
                Some("diagonal must be 1")
            } else if value.abs() > 1.0 + SYMMETRY {
                Some("outside [-1, 1]")
            } else if (value - corr[j][i]).abs() > SYMMETRY {
                Some("not symmetric")
            } else {
                None
            };
            if let Some(reason) = reason {
                return Err(DesignError::Correlation {
                    row: i,
                    col: j,
                    value,
                    reason,
                });
            }
        }
    }
    let l = correlation_factor(corr)?;
    Ok(u.iter()
        .map(|row| {
            let z: Vec<f64> = row.iter().map(|&x| normal_quantile(x)).collect();
            (0..d)
                .map(|i| mean[i] + sd[i] * l[i].iter().zip(&z).map(|(a, b)| a * b).sum::<f64>())
                .collect()
        })
        .collect())
}

/// Saltelli (2010) sampling for Sobol' indices: base sample size `n` (a
/// power of two keeps the Sobol' net balanced; any n ≥ 1 is accepted), `d`
/// factors. Returns the n (d + 2) unit-cube points in the order A (n rows),
/// B (n rows), then for i in 0..d: AB_i (n rows, A with column i taken from
/// B), as [`crate::study::sensitivity::sobol_indices`] expects.
///
/// A and B are the first and last d dimensions of one 2d-dimensional
/// Sobol' sequence (Sobol' 1967), Owen-scrambled and index-shuffled from
/// `seed` by `sobol_burley` (Burley 2020, "Practical hash-based Owen
/// scrambling"). Being scrambled, its first point is not the origin and
/// none is skipped. The crate returns f32 values k 2^-23; each is moved to
/// the centre of its cell, (k + 1/2) 2^-23, so every coordinate is strictly
/// inside (0, 1). The 64-bit seed is folded to the crate's 32-bit seed
/// (upper half XOR lower half). Limits: n ≤ [`SALTELLI_MAX_N`],
/// d ≤ [`SALTELLI_MAX_FACTORS`].
pub fn saltelli(n: usize, d: usize, seed: u64) -> Result<Vec<Vec<f64>>, DesignError> {
    check_size(n, d)?;
    if n > SALTELLI_MAX_N {
        return Err(DesignError::Unsupported {
            what: "base sample size n",
            got: n,
            max: SALTELLI_MAX_N,
        });
    }
    if d > SALTELLI_MAX_FACTORS {
        return Err(DesignError::Unsupported {
            what: "number of factors d",
            got: d,
            max: SALTELLI_MAX_FACTORS,
        });
    }
    let seed32 = (seed ^ (seed >> 32)) as u32;
    let half_cell = 0.5 / (1u32 << 23) as f64;
    let sobol: Vec<Vec<f64>> = (0..n as u32)
        .map(|k| {
            (0..2 * d as u32)
                .map(|dim| f64::from(sobol_burley::sample(k, dim, seed32)) + half_cell)
                .collect()
        })
        .collect();
    let a = sobol.iter().map(|p| p[..d].to_vec());
    let b = sobol.iter().map(|p| p[d..].to_vec());
    let mut points = Vec::with_capacity(n * (d + 2));
    points.extend(a);
    points.extend(b);
    for i in 0..d {
        points.extend(sobol.iter().map(|p| {
            let mut row = p[..d].to_vec();
            row[i] = p[d + i];
            row
        }));
    }
    Ok(points)
}

/// One step of a Morris trajectory: the move from design point `from` to
/// design point `to` (row indices into [`MorrisDesign::points`]), which
/// changes only factor `factor`, by `delta` = points[to][factor] −
/// points[from][factor] (±Δ).
#[derive(Debug, Clone, PartialEq)]
pub struct MorrisStep {
    /// Trajectory index, 0..r.
    pub trajectory: usize,
    /// Row of the point before the step.
    pub from: usize,
    /// Row of the point after the step.
    pub to: usize,
    /// The factor that changes.
    pub factor: usize,
    /// The signed change of that factor, in unit-cube coordinates.
    pub delta: f64,
}

/// A Morris (1991) elementary-effects design: `points` in trajectory order
/// (r (d + 1) rows in [0, 1]^d) and the r d one-factor steps between them.
#[derive(Debug, Clone, PartialEq)]
pub struct MorrisDesign {
    /// The design points, trajectory after trajectory, d + 1 each.
    pub points: Vec<Vec<f64>>,
    /// The steps, trajectory after trajectory, d each, in the order taken.
    pub steps: Vec<MorrisStep>,
}

/// Morris (1991) elementary-effects design: `r` trajectories of d + 1
/// points on the p-level grid {0, 1/(p−1), …, 1}^d (p = `levels`, even),
/// with step Δ = p / (2 (p − 1)). Per trajectory, from `seed`: a random base
/// point x* with every coordinate on a level ≤ 1 − Δ, a random direction
/// per factor (each factor moves between x*_i and x*_i + Δ, upwards or
/// downwards) and a random order of the factors; the trajectory starts at
/// the corner given by the directions and changes one factor per step
/// (Morris 1991, randomised orientation matrix B*). Every point lies on the
/// grid and every factor changes exactly once per trajectory.
pub fn morris(r: usize, d: usize, levels: usize, seed: u64) -> Result<MorrisDesign, DesignError> {
    if r == 0 {
        return Err(DesignError::Empty {
            what: "number of trajectories",
        });
    }
    if d == 0 {
        return Err(DesignError::Empty {
            what: "number of factors",
        });
    }
    if levels < 2 || !levels.is_multiple_of(2) {
        return Err(DesignError::MorrisLevels { levels });
    }
    let total = r.checked_mul(d + 1).and_then(|t| t.checked_mul(d));
    if total.is_none() {
        return Err(DesignError::TooLarge {
            points: None,
            limit: usize::MAX,
        });
    }
    let top = (levels - 1) as f64;
    let half = levels / 2; // Δ in grid levels: Δ = half / (p − 1).
    let mut rng = StdRng::seed_from_u64(seed);
    let mut points = Vec::with_capacity(r * (d + 1));
    let mut steps = Vec::with_capacity(r * d);
    let mut order: Vec<usize> = (0..d).collect();
    for trajectory in 0..r {
        // Level index of the base point (0..half) and the direction per factor.
        let base: Vec<usize> = (0..d).map(|_| rng.random_range(0..half)).collect();
        let up: Vec<bool> = (0..d).map(|_| rng.random::<bool>()).collect();
        order.shuffle(&mut rng);
        let mut level: Vec<usize> = (0..d)
            .map(|i| if up[i] { base[i] } else { base[i] + half })
            .collect();
        let to_point = |level: &[usize]| level.iter().map(|&k| k as f64 / top).collect::<Vec<_>>();
        points.push(to_point(&level));
        for &factor in &order {
            level[factor] = if up[factor] {
                base[factor] + half
            } else {
                base[factor]
            };
            let to = points.len();
            let point = to_point(&level);
            let delta = point[factor] - points[to - 1][factor];
            points.push(point);
            steps.push(MorrisStep {
                trajectory,
                from: to - 1,
                to,
                factor,
                delta,
            });
        }
    }
    Ok(MorrisDesign { points, steps })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_order_and_limit() {
        let g = grid(&[3, 2], 6).unwrap();
        let expected: Vec<Vec<usize>> = vec![
            vec![0, 0],
            vec![0, 1],
            vec![1, 0],
            vec![1, 1],
            vec![2, 0],
            vec![2, 1],
        ];
        assert_eq!(g, expected);
        assert_eq!(
            grid(&[3, 2], 5),
            Err(DesignError::TooLarge {
                points: Some(6),
                limit: 5
            })
        );
        assert_eq!(
            grid(&[3, 0, 2], 100),
            Err(DesignError::ZeroLevels { factor: 1 })
        );
        assert_eq!(
            grid(&[usize::MAX, 2], usize::MAX),
            Err(DesignError::TooLarge {
                points: None,
                limit: usize::MAX
            })
        );
        assert!(grid(&[], 10).is_err());
    }

    #[test]
    fn latin_hypercube_one_point_per_stratum_and_seeded() {
        let (n, d) = (97, 4);
        let p = latin_hypercube(n, d, 7).unwrap();
        assert_eq!(p.len(), n);
        for col in 0..d {
            let mut seen = vec![0usize; n];
            for row in &p {
                let u = row[col];
                assert!(u > 0.0 && u < 1.0);
                seen[(u * n as f64).floor() as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1), "column {col}: {seen:?}");
        }
        assert_eq!(p, latin_hypercube(n, d, 7).unwrap());
        assert_ne!(p, latin_hypercube(n, d, 8).unwrap());
        assert!(latin_hypercube(0, 2, 1).is_err());
        assert!(latin_hypercube(2, 0, 1).is_err());
    }

    #[test]
    fn monte_carlo_in_open_cube_and_seeded() {
        let p = monte_carlo(1000, 3, 1).unwrap();
        assert!(p.iter().flatten().all(|&u| u > 0.0 && u < 1.0));
        assert_eq!(p, monte_carlo(1000, 3, 1).unwrap());
        assert_ne!(p, monte_carlo(1000, 3, 2).unwrap());
        // Mean of 3000 U(0,1) draws: SE = sqrt(1/12 / 3000) = 0.0053; 4 SE.
        let mean = p.iter().flatten().sum::<f64>() / 3000.0;
        assert!((mean - 0.5).abs() < 4.0 * 0.0053, "{mean}");
    }

    #[test]
    fn marginals_map_quantiles() {
        let u = Marginal::Uniform { lo: 2.0, hi: 6.0 };
        assert_eq!(u.value(0.25), 3.0);
        let n = Marginal::Normal {
            mean: 10.0,
            sd: 2.0,
        };
        // Φ⁻¹(0.975) = 1.959963984540054 (tables); statrs' erfc⁻¹ is
        // accurate to a few ulp, hence 1e-12.
        assert!((n.value(0.975) - (10.0 + 2.0 * 1.959963984540054)).abs() < 1e-12);
        assert!((n.value(0.5) - 10.0).abs() < 1e-12);
        let ln = Marginal::LogNormal {
            median: 3.0,
            sigma_log: 0.5,
        };
        assert!((ln.value(0.5) - 3.0).abs() < 1e-12);
        assert!((ln.value(0.975) - (3.0f64.ln() + 0.5 * 1.959963984540054).exp()).abs() < 1e-12);
        let t = Marginal::Truncated {
            inner: Box::new(n.clone()),
            lo: 9.0,
            hi: 14.0,
        };
        t.validate().unwrap();
        for k in 1..100 {
            let x = t.value(k as f64 / 100.0);
            assert!((9.0..=14.0).contains(&x));
            // Round trip through the truncated CDF; 1e-9 allows for the
            // relative error of erfc near the tails.
            assert!((t.cdf(x) - k as f64 / 100.0).abs() < 1e-9);
        }
        assert!(u.value(1.5).is_nan());
        assert!(Marginal::Uniform { lo: 1.0, hi: 1.0 }.validate().is_err());
        assert!(
            Marginal::Normal {
                mean: 0.0,
                sd: -1.0
            }
            .validate()
            .is_err()
        );
        assert!(
            Marginal::LogNormal {
                median: 0.0,
                sigma_log: 1.0
            }
            .validate()
            .is_err()
        );
        let empty = Marginal::Truncated {
            inner: Box::new(Marginal::Uniform { lo: 0.0, hi: 1.0 }),
            lo: 2.0,
            hi: 3.0,
        };
        assert!(empty.validate().is_err());
    }

    fn sample_correlation(x: &[Vec<f64>], i: usize, j: usize) -> f64 {
        let n = x.len() as f64;
        let mi = x.iter().map(|r| r[i]).sum::<f64>() / n;
        let mj = x.iter().map(|r| r[j]).sum::<f64>() / n;
        let (mut sij, mut sii, mut sjj) = (0.0, 0.0, 0.0);
        for r in x {
            sij += (r[i] - mi) * (r[j] - mj);
            sii += (r[i] - mi).powi(2);
            sjj += (r[j] - mj).powi(2);
        }
        sij / (sii * sjj).sqrt()
    }

    #[test]
    fn correlated_normal_reproduces_correlation() {
        let n = 20_000;
        let corr = vec![
            vec![1.0, 0.6, -0.3],
            vec![0.6, 1.0, 0.2],
            vec![-0.3, 0.2, 1.0],
        ];
        let mean = [1.0, -2.0, 50.0];
        let sd = [0.5, 2.0, 10.0];
        for u in [
            monte_carlo(n, 3, 11).unwrap(),
            latin_hypercube(n, 3, 12).unwrap(),
        ] {
            let x = correlated_normal(&u, &mean, &sd, &corr).unwrap();
            for i in 0..3 {
                // Mean within 4 standard errors sd/√n.
                let m = x.iter().map(|r| r[i]).sum::<f64>() / n as f64;
                assert!(
                    (m - mean[i]).abs() < 4.0 * sd[i] / (n as f64).sqrt(),
                    "mean {i}: {m}"
                );
                for (j, &rho) in corr[i].iter().enumerate().skip(i + 1) {
                    // Large-sample SE of a normal sample correlation: (1 − ρ²)/√n.
                    let se = (1.0 - rho * rho) / (n as f64).sqrt();
                    let r = sample_correlation(&x, i, j);
                    assert!(
                        (r - rho).abs() < 3.0 * se,
                        "({i},{j}): {r} vs {rho}, se {se}"
                    );
                }
            }
        }
    }

    #[test]
    fn correlated_normal_rejects_indefinite_and_accepts_semidefinite() {
        let u = monte_carlo(100, 3, 1).unwrap();
        let (mean, sd) = ([0.0; 3], [1.0; 3]);
        // ρ01 = ρ12 = 0.9 forces ρ02 ≥ 0.62; −0.9 is impossible.
        let bad = vec![
            vec![1.0, 0.9, -0.9],
            vec![0.9, 1.0, 0.9],
            vec![-0.9, 0.9, 1.0],
        ];
        match correlated_normal(&u, &mean, &sd, &bad) {
            Err(DesignError::NotPositiveSemiDefinite {
                index,
                min_eigenvalue,
                ..
            }) => {
                assert_eq!(index, 2);
                assert!(min_eigenvalue < -0.5);
            }
            other => panic!("{other:?}"),
        }
        // Factors 0 and 1 perfectly correlated: singular, semi-definite.
        let singular = vec![
            vec![1.0, 1.0, 0.3],
            vec![1.0, 1.0, 0.3],
            vec![0.3, 0.3, 1.0],
        ];
        let x = correlated_normal(&u, &mean, &sd, &singular).unwrap();
        for r in &x {
            // The eigen factor reproduces x0 = x1 to rounding (1e-12 for |x| < ~5).
            assert!((r[0] - r[1]).abs() < 1e-12, "{r:?}");
        }
        let asym = vec![
            vec![1.0, 0.5, 0.0],
            vec![0.4, 1.0, 0.0],
            vec![0.0, 0.0, 1.0],
        ];
        assert!(matches!(
            correlated_normal(&u, &mean, &sd, &asym),
            Err(DesignError::Correlation { row: 0, col: 1, .. })
        ));
        let mut edge = u.clone();
        edge[5][1] = 1.0;
        assert!(matches!(
            correlated_normal(&edge, &mean, &sd, &singular),
            Err(DesignError::UnitCoordinate { row: 5, col: 1, .. })
        ));
    }

    #[test]
    fn saltelli_layout() {
        let (n, d) = (64, 3);
        let p = saltelli(n, d, 5).unwrap();
        assert_eq!(p.len(), n * (d + 2));
        assert!(p.iter().flatten().all(|&u| u > 0.0 && u < 1.0));
        let (a, b) = (&p[..n], &p[n..2 * n]);
        for i in 0..d {
            let ab = &p[(2 + i) * n..(3 + i) * n];
            for k in 0..n {
                for j in 0..d {
                    assert_eq!(ab[k][j], if j == i { b[k][j] } else { a[k][j] });
                }
            }
        }
        // The first 2^m points of a (scrambled) Sobol' sequence are a
        // (0, m, 1)-net in each dimension: exactly one point per 1/n stratum.
        for j in 0..d {
            let mut seen = vec![0; n];
            for row in a {
                seen[(row[j] * n as f64) as usize] += 1;
            }
            assert!(seen.iter().all(|&c| c == 1));
        }
        assert_eq!(p, saltelli(n, d, 5).unwrap());
        assert_ne!(p, saltelli(n, d, 6).unwrap());
        assert!(saltelli(SALTELLI_MAX_N + 1, 2, 0).is_err());
        assert!(saltelli(8, SALTELLI_MAX_FACTORS + 1, 0).is_err());
    }

    #[test]
    fn morris_trajectories_on_grid() {
        let (r, d, p) = (10, 5, 4);
        let m = morris(r, d, p, 3).unwrap();
        assert_eq!(m.points.len(), r * (d + 1));
        assert_eq!(m.steps.len(), r * d);
        let delta = p as f64 / (2.0 * (p as f64 - 1.0));
        for x in m.points.iter().flatten() {
            let level = x * (p - 1) as f64;
            assert!((level - level.round()).abs() < 1e-12 && (0.0..=1.0).contains(x));
        }
        for t in 0..r {
            let steps: Vec<&MorrisStep> = m.steps.iter().filter(|s| s.trajectory == t).collect();
            let mut factors: Vec<usize> = steps.iter().map(|s| s.factor).collect();
            factors.sort();
            assert_eq!(factors, (0..d).collect::<Vec<_>>());
            for s in steps {
                assert_eq!(s.to, s.from + 1);
                assert!((s.delta.abs() - delta).abs() < 1e-15);
                for j in 0..d {
                    let change = m.points[s.to][j] - m.points[s.from][j];
                    assert_eq!(change, if j == s.factor { s.delta } else { 0.0 });
                }
            }
        }
        assert_eq!(m, morris(r, d, p, 3).unwrap());
        assert_ne!(m, morris(r, d, p, 4).unwrap());
        assert_eq!(
            morris(2, 2, 3, 0),
            Err(DesignError::MorrisLevels { levels: 3 })
        );
    }
}
