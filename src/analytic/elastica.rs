//! The heavy elastica: a clamped strip bending under its own weight with
//! large deflections (the cantilever bending test of Peirce, 1930), solved
//! by shooting from the free end. See `docs/references.md` §1.
//!
//! A strip of bending stiffness `B` [N·mm, per mm of width], areal weight
//! `q` [N/mm², i.e. N per mm of length per mm of width] and length `L` \[mm\]
//! is clamped at `s = 0` with the slope `θ0` below the horizontal and free at
//! `s = L`; gravity acts along −z. With `θ(s)` the slope angle *below* the
//! horizontal, the strip runs along `x' = cos θ`, `z' = −sin θ` and the
//! bending moment at `s` is the moment of the weight of the part beyond
//! `s` about `s`:
//!
//! ```text
//! B θ'(s) = M(s) = q ∫_s^L (x(σ) − x(s)) dσ          (M > 0 curls the strip down)
//! B θ''   = −q (L − s) cos θ,   θ(0) = θ0,   θ'(L) = 0
//! ```
//!
//! (differentiate the moment: `M' = −q (L − s) x'`). In the unit length
//! `ŝ = s/L` the problem has one parameter, `λ = q L³ / B = (L/c)³` with
//! `c = (B/q)^(1/3)` Peirce's bending length.
//!
//! **Method.** With `τ = 1 − ŝ` (from the tip), `k = dθ/dŝ` and the angle
//! from the downward vertical `φ = π/2 − θ`:
//!
//! ```text
//! dφ/dτ = k,   dk/dτ = λ τ sin φ,   dX/dτ = sin φ,   dZ/dτ = cos φ
//! φ(0) = φ_tip,  k(0) = 0,  X(0) = Z(0) = 0
//! ```
//!
//! is integrated with fixed-step classical RK4 from the tip (`τ = 0`) to
//! the clamp (`τ = 1`), and the unknown tip angle is found by bisection on
//! `φ(τ = 1) = φ0 = π/2 − θ0` in the bracket `φ_tip ∈ [0, φ0]`. Then
//! `δ = L Z(1)` (tip deflection, positive down), `x_tip = L X(1)` and
//! `M(0) = B k(1)/L`. Shooting on `φ` rather than `θ` keeps the full
//! relative precision of a tip that hangs nearly vertical: `φ_tip` falls
//! like `exp(−c (L/c)^{3/2})` (3e-4 at `L/c = 6`, 4.5e-9 at 10), far below
//! the resolution of `θ` near `π/2`.
//!
//! The bracket is always valid and the root unique for `0 ≤ θ0 < π/2`: at
//! `φ_tip = 0` the strip hangs straight down (`φ ≡ 0 < φ0`); at
//! `φ_tip = φ0` it curls on past `φ0` (`k > 0` while `sin φ > 0`); and two
//! trial shots keep their order, `φ_B(τ) > φ_A(τ)` for all `τ`, while both
//! stay in `[0, π]` (the difference `D` obeys
//! `D'' = λ τ (sin φ_B − sin φ_A) > 0` for `φ_A < φ_B ≤ π/2`, the range up
//! to the clamp for `θ0 ≥ 0`). A shot that passes `φ0` before the clamp is
//! therefore "too high" without being integrated further, which keeps every
//! shot inside `[0, π)` and the bisection monotone at any `λ`.
//!
//! [`HeavyCantilever::solve`] doubles the step count until the Richardson
//! estimates `|δ_2N − δ_N| / 15` and `|x_2N − x_N| / 15` of the fourth-order
//! scheme are below a tenth of [`TARGET_ERROR`] of `δ` and of `x_tip`, and
//! returns the `2N` solution.

use std::f64::consts::FRAC_PI_2;

/// Relative accuracy of the tip deflection and of the tip's horizontal
/// position that [`HeavyCantilever::solve`] guarantees (estimated by step
/// doubling).
pub const TARGET_ERROR: f64 = 1e-10;

/// Richardson estimates must be below this fraction of [`TARGET_ERROR`]:
/// a margin of 10 for the estimate itself being approximate.
const ESTIMATE_MARGIN: f64 = 0.1;

/// Largest step count [`HeavyCantilever::solve`] tries.
pub const MAX_STEPS: usize = 1 << 22;

/// Why a cantilever cannot be set up or solved. Messages name the parameter,
/// the value and what is allowed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ElasticaError {
    /// A non-positive, non-finite or out-of-range input.
    #[error("heavy cantilever: {parameter} = {value} is invalid; expected {expected}")]
    InvalidParameter {
        /// The parameter (`bending_stiffness`, `areal_weight`, ...).
        parameter: &'static str,
        /// The value as given.
        value: f64,
        /// What is allowed.
        expected: &'static str,
    },
    /// A tip-angle bracket in which the shooting residual does not change
    /// sign.
    #[error(
        "heavy cantilever: the tip-angle bracket [{lower}, {upper}] rad does not enclose the solution: its lower end shoots {lower_side} the clamp angle and its upper end {upper_side}; expected below and above (a bracket inside [θ0, π/2] around the tip angle)"
    )]
    NoSignChange {
        /// Lower end of the bracket \[rad\].
        lower: f64,
        /// Upper end of the bracket \[rad\].
        upper: f64,
        /// Where the shot from `lower` lands: `below` or `above`.
        lower_side: &'static str,
        /// Where the shot from `upper` lands: `below` or `above`.
        upper_side: &'static str,
    },
    /// Step doubling did not reach the target accuracy.
    #[error(
        "heavy cantilever: the tip deflection did not converge to {target:e} (relative) within {steps} RK4 steps; last estimate {estimate:e}"
    )]
    NotConverged {
        /// Steps of the last attempt.
        steps: usize,
        /// Relative error estimate of the last attempt.
        estimate: f64,
        /// The target.
        target: f64,
    },
}

/// A clamped heavy strip (the inputs of the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeavyCantilever {
    /// Bending stiffness `B` per unit width [N·mm].
    pub bending_stiffness: f64,
    /// Areal weight `q` [N/mm²] (areal mass × g).
    pub areal_weight: f64,
    /// Overhang length `L` \[mm\].
    pub length: f64,
    /// Clamp slope `θ0` below the horizontal \[rad\], in `[0, π/2)`.
    pub clamp_angle: f64,
}

/// The solution of [`HeavyCantilever::solve`] (lengths in mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CantileverSolution {
    /// Tip deflection `δ` below the clamp, positive down \[mm\].
    pub tip_deflection: f64,
    /// Horizontal distance of the tip from the clamp, `x(L) − x(0)` \[mm\].
    pub tip_x: f64,
    /// Slope at the tip `θ(L)` below the horizontal \[rad\].
    pub tip_angle: f64,
    /// The same as the angle from the downward vertical, `π/2 − θ(L)`
    /// \[rad\], with full relative precision when the tip hangs nearly
    /// vertical (the shooting parameter).
    pub tip_angle_from_vertical: f64,
    /// Clamp moment `M(0) = B θ'(0)` per unit width [N·mm/mm].
    pub clamp_moment: f64,
    /// RK4 steps over the length.
    pub steps: usize,
    /// Estimated relative error of `tip_deflection` and `tip_x`, the larger
    /// of the two (step doubling; NaN for [`HeavyCantilever::solve_fixed`],
    /// which does not estimate it).
    pub error_estimate: f64,
}

/// A point of the deflected strip (relative to the clamp, z up) [mm, rad].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ShapePoint {
    /// Arc length from the clamp \[mm\].
    pub arc_length: f64,
    /// Horizontal position `x(s) − x(0)` \[mm\].
    pub x: f64,
    /// Vertical position `z(s) − z(0)` \[mm\] (negative: below the clamp).
    pub z: f64,
    /// Slope `θ(s)` below the horizontal \[rad\].
    pub angle: f64,
}

/// The state `[φ, k, X, Z]` of the sweep from the tip (`φ = π/2 − θ`).
type State = [f64; 4];

/// How a shot from the tip ends.
enum Shot {
    /// `φ` passed `φ0` before the clamp: `φ_tip` is too large.
    Past,
    /// The shot reached the clamp with this state; `φ(1) ≤ φ0` means
    /// `φ_tip` is too small (or right).
    AtClamp(State),
}

impl HeavyCantilever {
    /// A cantilever, validated: `B`, `q`, `L` finite and > 0, `θ0` in
    /// `[0, π/2)` (a clamp at or past vertical leaves the strip hanging
    /// straight, and the bracket and monotonicity argument of the module
    /// doc needs `θ0 ≥ 0`).
    pub fn new(
        bending_stiffness: f64,
        areal_weight: f64,
        length: f64,
        clamp_angle: f64,
    ) -> Result<Self, ElasticaError> {
        let positive = |parameter: &'static str, value: f64, expected: &'static str| {
            if value.is_finite() && value > 0.0 {
                Ok(())
            } else {
                Err(ElasticaError::InvalidParameter {
                    parameter,
                    value,
                    expected,
                })
            }
        };
        positive(
            "bending_stiffness",
            bending_stiffness,
            "a finite bending stiffness > 0 N·mm",
        )?;
        positive(
            "areal_weight",
            areal_weight,
            "a finite areal weight > 0 N/mm²",
        )?;
        positive("length", length, "a finite length > 0 mm")?;
        if !(clamp_angle.is_finite() && (0.0..FRAC_PI_2).contains(&clamp_angle)) {
            return Err(ElasticaError::InvalidParameter {
                parameter: "clamp_angle",
                value: clamp_angle,
                expected: "an angle in [0, π/2) rad below the horizontal",
            });
        }
        let cantilever = Self {
            bending_stiffness,
            areal_weight,
            length,
            clamp_angle,
        };
        let lambda = cantilever.load_parameter();
        if !(lambda.is_finite() && lambda > 0.0) {
            return Err(ElasticaError::InvalidParameter {
                parameter: "areal_weight",
                value: areal_weight,
                expected: "q L³ / B finite and > 0 (the inputs over- or underflow)",
            });
        }
        Ok(cantilever)
    }

    /// Peirce's bending length `c = (B/q)^(1/3)` \[mm\].
    pub fn bending_length(&self) -> f64 {
        (self.bending_stiffness / self.areal_weight).cbrt()
    }

    /// The load parameter `λ = q L³ / B = (L/c)³` (dimensionless).
    pub fn load_parameter(&self) -> f64 {
        self.areal_weight * self.length.powi(3) / self.bending_stiffness
    }

    /// Small-deflection (Euler–Bernoulli) tip deflection of a horizontally
    /// clamped strip, `q L⁴ / (8 B)` \[mm\]. The exact `δ` of `θ0 = 0` is
    /// `(q L⁴/8B) (1 − λ²/80 + 549 λ⁴/1971200 − …)`, see
    /// `docs/references.md` §1.
    pub fn small_deflection_tip(&self) -> f64 {
        self.areal_weight * self.length.powi(4) / (8.0 * self.bending_stiffness)
    }

    /// Solves to [`TARGET_ERROR`] (relative, in `δ` and `x_tip`) by step
    /// doubling from `max(64, 32 √λ)` steps.
    ///
    /// # Errors
    /// [`ElasticaError::NotConverged`] if [`MAX_STEPS`] is not enough (not
    /// seen for `L/c` up to 10).
    pub fn solve(&self) -> Result<CantileverSolution, ElasticaError> {
        let lambda = self.load_parameter();
        let mut steps = (32.0 * lambda.sqrt()).ceil().max(64.0) as usize;
        let bracket = [0.0, FRAC_PI_2 - self.clamp_angle];
        let mut coarse = self.solve_vertical(steps, bracket)?;
        let mut estimate = f64::NAN;
        while steps <= MAX_STEPS / 2 {
            steps *= 2;
            let fine = self.solve_vertical(steps, bracket)?;
            estimate = ((fine.tip_deflection - coarse.tip_deflection) / fine.tip_deflection)
                .abs()
                .max(((fine.tip_x - coarse.tip_x) / fine.tip_x).abs())
                / 15.0;
            if estimate <= ESTIMATE_MARGIN * TARGET_ERROR {
                return Ok(CantileverSolution {
                    error_estimate: estimate,
                    ..fine
                });
            }
            coarse = fine;
        }
        Err(ElasticaError::NotConverged {
            steps,
            estimate,
            target: TARGET_ERROR,
        })
    }

    /// Solves with `steps` RK4 steps and bisection on the tip angle in
    /// `bracket = [lower, upper]` (rad, `θ_tip`; the bisection itself runs
    /// on `φ_tip = π/2 − θ_tip` down to adjacent floating-point numbers).
    ///
    /// # Errors
    /// `steps == 0`, a bracket that is not finite and increasing, or one in
    /// which the shooting residual does not change sign.
    pub fn solve_fixed(
        &self,
        steps: usize,
        bracket: [f64; 2],
    ) -> Result<CantileverSolution, ElasticaError> {
        if steps == 0 {
            return Err(ElasticaError::InvalidParameter {
                parameter: "steps",
                value: 0.0,
                expected: "at least one RK4 step",
            });
        }
        let [lower, upper] = bracket;
        if !(lower.is_finite() && upper.is_finite() && lower < upper) {
            return Err(ElasticaError::InvalidParameter {
                parameter: "bracket",
                value: if lower.is_finite() { upper } else { lower },
                expected: "a finite tip-angle bracket [lower, upper] with lower < upper",
            });
        }
        self.solve_vertical(steps, [FRAC_PI_2 - upper, FRAC_PI_2 - lower])
            .map_err(|e| match e {
                ElasticaError::NoSignChange {
                    lower_side,
                    upper_side,
                    ..
                } => ElasticaError::NoSignChange {
                    lower: bracket[0],
                    upper: bracket[1],
                    // the lower tip angle is the upper φ, and "φ(1) ≤ φ0"
                    // (φ_tip small) is "θ(1) ≥ θ0" (above the clamp angle)
                    lower_side: upper_side,
                    upper_side: lower_side,
                },
                other => other,
            })
    }

    /// [`Self::solve_fixed`] with the bracket given for `φ_tip = π/2 − θ_tip`
    /// (`[small, large]`). Bisection runs down to adjacent floating-point
    /// numbers of `φ_tip`.
    fn solve_vertical(
        &self,
        steps: usize,
        bracket: [f64; 2],
    ) -> Result<CantileverSolution, ElasticaError> {
        let [mut small, mut large] = bracket;
        let lambda = self.load_parameter();
        let phi0 = FRAC_PI_2 - self.clamp_angle;
        // The clamp state of a shot that ends at or below φ0 (φ_tip not
        // too large), else None.
        let short = |phi_tip: f64| match self.shoot(phi_tip, lambda, steps) {
            Shot::AtClamp(y) if y[0] <= phi0 => Some(y),
            _ => None,
        };
        // In the words of θ: a shot ending at φ(1) ≤ φ0 lands at or above
        // the clamp angle θ0.
        let side = |y: &Option<State>| if y.is_some() { "above" } else { "below" };
        let at_small = short(small);
        let at_large = short(large);
        let (small_side, large_side) = (side(&at_small), side(&at_large));
        // Bisection down to adjacent floating-point numbers (≤ ~1100
        // halvings even for a root in the subnormal range; ~60–90 in
        // practice). The small end always falls short and keeps its state.
        let (Some(mut y), None) = (at_small, at_large) else {
            return Err(ElasticaError::NoSignChange {
                lower: small,
                upper: large,
                lower_side: small_side,
                upper_side: large_side,
            });
        };
        for _ in 0..1200 {
            let mid = 0.5 * (small + large);
            if mid <= small || mid >= large {
                break;
            }
            match short(mid) {
                Some(state) => {
                    small = mid;
                    y = state;
                }
                None => large = mid,
            }
        }
        let l = self.length;
        Ok(CantileverSolution {
            tip_deflection: l * y[3],
            tip_x: l * y[2],
            tip_angle: FRAC_PI_2 - small,
            tip_angle_from_vertical: small,
            clamp_moment: self.bending_stiffness * y[1] / l,
            steps,
            error_estimate: f64::NAN,
        })
    }

    /// The deflected shape at the arc lengths `arc_lengths` (mm from the
    /// clamp, any order, each in `[0, L]`), for a `solution` of this
    /// cantilever: the solution's sweep from the tip repeated on its own grid
    /// (so the tip and the clamp are exactly the solution's), each point
    /// reached by a partial RK4 step from the grid point before it.
    ///
    /// # Errors
    /// An arc length outside `[0, L]` or not finite.
    pub fn shape(
        &self,
        solution: &CantileverSolution,
        arc_lengths: &[f64],
    ) -> Result<Vec<ShapePoint>, ElasticaError> {
        let l = self.length;
        if let Some(&bad) = arc_lengths
            .iter()
            .find(|s| !(s.is_finite() && (0.0..=l).contains(*s)))
        {
            return Err(ElasticaError::InvalidParameter {
                parameter: "arc_length",
                value: bad,
                expected: "arc lengths in [0, L] mm from the clamp",
            });
        }
        let lambda = self.load_parameter();
        let steps = solution.steps.max(1);
        let h = 1.0 / steps as f64;
        // Stations τ = 1 − s/L in increasing order, and which request each is.
        let mut order: Vec<usize> = (0..arc_lengths.len()).collect();
        order.sort_by(|&a, &b| arc_lengths[b].total_cmp(&arc_lengths[a]));
        let mut states: Vec<State> = vec![[0.0; 4]; arc_lengths.len()];
        // The solution's own grid (bit-identical to its shot), with a partial
        // step from the last grid point to each station.
        let mut y: State = [solution.tip_angle_from_vertical, 0.0, 0.0, 0.0];
        let mut done = 0usize;
        for &i in &order {
            let target = 1.0 - arc_lengths[i] / l;
            let full = ((target * steps as f64).floor() as usize).min(steps);
            while done < full {
                y = rk4_step(y, done as f64 * h, h, lambda);
                done += 1;
            }
            let rest = target - done as f64 * h;
            states[i] = if rest > 0.0 && done < steps {
                rk4_step(y, done as f64 * h, rest, lambda)
            } else {
                y
            };
        }
        while done < steps {
            y = rk4_step(y, done as f64 * h, h, lambda);
            done += 1;
        }
        let clamp = y;
        Ok(arc_lengths
            .iter()
            .zip(&states)
            .map(|(&s, y)| ShapePoint {
                arc_length: s,
                x: l * (clamp[2] - y[2]),
                z: -l * (clamp[3] - y[3]),
                angle: FRAC_PI_2 - y[0],
            })
            .collect())
    }

    /// One shot from the tip with `steps` equal RK4 steps.
    fn shoot(&self, phi_tip: f64, lambda: f64, steps: usize) -> Shot {
        let h = 1.0 / steps as f64;
        let phi0 = FRAC_PI_2 - self.clamp_angle;
        let mut y: State = [phi_tip, 0.0, 0.0, 0.0];
        for i in 0..steps {
            y = rk4_step(y, i as f64 * h, h, lambda);
            if y[0] > phi0 && i + 1 < steps {
                return Shot::Past;
            }
        }
        Shot::AtClamp(y)
    }
}

/// The right-hand side `d[φ, k, X, Z]/dτ = [k, λ τ sin φ, sin φ, cos φ]`.
#[inline]
fn rhs(tau: f64, y: &State, lambda: f64) -> State {
    let (sin, cos) = y[0].sin_cos();
    [y[1], lambda * tau * sin, sin, cos]
}

/// One classical RK4 step of length `h` from `tau`.
#[inline]
fn rk4_step(y: State, tau: f64, h: f64, lambda: f64) -> State {
    let add = |a: &State, b: &State, f: f64| {
        [
            a[0] + f * b[0],
            a[1] + f * b[1],
            a[2] + f * b[2],
            a[3] + f * b[3],
        ]
    };
    let k1 = rhs(tau, &y, lambda);
    let k2 = rhs(tau + 0.5 * h, &add(&y, &k1, 0.5 * h), lambda);
    let k3 = rhs(tau + 0.5 * h, &add(&y, &k2, 0.5 * h), lambda);
    let k4 = rhs(tau + h, &add(&y, &k3, h), lambda);
    let mut out = y;
    for j in 0..4 {
        out[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
    }
    out
}
