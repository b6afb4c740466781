//! The shape of a load programme in time, shared by the explicit solver
//! (`λ(t)`) and the quasi-static solver's inertia (a step's time from its
//! programme fraction).

use serde::{Deserialize, Serialize};

/// The shape of the prescribed motion over the run: the load parameter is
/// `λ(t) = λ_final · shape(t / T)` for `0 ≤ t ≤ T`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Amplitude {
    /// `shape(τ) = τ³ (10 − 15 τ + 6 τ²)`: zero velocity and acceleration at
    /// both ends (ABAQUS' `SMOOTH STEP`); peak rate 1.875 × the mean.
    SmoothStep,
    /// `shape(τ) = τ`: constant rate, with a velocity jump at the start.
    Linear,
    /// `shape(τ) = τ²`: constant acceleration from rest, the rate growing
    /// as `√λ` to twice the mean at the end — slow early, where the
    /// internal energy of a forming run is still small against the kinetic
    /// energy of the material set in motion (`docs/forming.md`).
    Quadratic,
}

impl Amplitude {
    /// `shape(τ)`, with `τ` clamped to `[0, 1]`.
    pub fn shape(self, tau: f64) -> f64 {
        let tau = tau.clamp(0.0, 1.0);
        match self {
            Amplitude::SmoothStep => tau * tau * tau * (10.0 + tau * (-15.0 + 6.0 * tau)),
            Amplitude::Linear => tau,
            Amplitude::Quadratic => tau * tau,
        }
    }

    /// The `τ ∈ [0, 1]` at which `shape(τ) = fraction` (both shapes rise
    /// monotonically), by bisection to round-off.
    pub fn inverse(self, fraction: f64) -> f64 {
        let fraction = fraction.clamp(0.0, 1.0);
        match self {
            Amplitude::Linear => fraction,
            Amplitude::Quadratic => fraction.sqrt(),
            Amplitude::SmoothStep => {
                let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
                for _ in 0..80 {
                    let mid = 0.5 * (lo + hi);
                    if self.shape(mid) < fraction {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            }
        }
    }

    /// The name used in case files.
    pub fn name(self) -> &'static str {
        match self {
            Amplitude::SmoothStep => "smooth-step",
            Amplitude::Linear => "linear",
            Amplitude::Quadratic => "quadratic",
        }
    }
}
