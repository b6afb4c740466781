//! The generalized stress function of the law, paper Eq. (12), its derivative
//! and its exactly integrated energy (Appendix B, corrected: see
//! `docs/theory.md`).
//!
//! With `x_t = S_ini / C_ini`, `c = C_ini / ΔS_mid` and `y = x − x_t`:
//!
//! ```text
//! f(x) = C_ini x                                       x < x_t
//! f(x) = S_ini + (C_mid y + ΔS_mid)(1 − e^(−c y))      x ≥ x_t
//! f(x) += C_lock (x − I_lock)²                         x ≥ I_lock
//! ```
//!
//! `G(x) = ∫₀ˣ f` is the energy of one term; `f′` enters the consistent
//! tangent.

/// The middle branch of Eq. (12): the transition from the initial modulus
/// `C_ini` to the middle modulus `C_mid` over the stress range `ΔS_mid`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Initial stress limit `S_ini` [MPa].
    pub s_ini: f64,
    /// Middle modulus `C_mid` [MPa].
    pub c_mid: f64,
    /// Stress range `ΔS_mid` of the transition [MPa].
    pub delta_s_mid: f64,
}

/// The lock branch of Eq. (12): `f += C_lock (x − I_lock)²` for `x ≥ I_lock`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lock {
    /// Lock modulus `C_lock` [MPa].
    pub c_lock: f64,
    /// Lock onset `I_lock` (same measure as `x`, dimensionless).
    pub i_lock: f64,
}

/// Which branch of Eq. (12) a point lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum TermBranch {
    /// `x < x_t`: `f = C_ini x`.
    Initial,
    /// `x_t ≤ x < I_lock`: the exponential transition to `C_mid`.
    Middle,
    /// `x ≥ I_lock` with `x < x_t`: the lock on the initial branch.
    InitialLocked,
    /// `x ≥ I_lock` and `x ≥ x_t`: the lock on the middle branch.
    MiddleLocked,
}

/// One term's generalized stress function `f(x)`, `x ≥ 0` (Eq. 12).
///
/// Construct with [`GeneralizedTerm::new`], which derives `x_t` and `c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeneralizedTerm {
    /// Initial modulus `C_ini` [MPa].
    pub c_ini: f64,
    /// Optional transition (middle) branch.
    pub transition: Option<Transition>,
    /// Optional lock branch.
    pub lock: Option<Lock>,
    /// Transition point `x_t = S_ini / C_ini` (infinite without a transition).
    x_t: f64,
    /// Exponent coefficient `c = C_ini / ΔS_mid` (zero without a transition).
    rate: f64,
}

/// Value, slope and energy of a generalized term at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TermValue {
    /// Energy `G(x)` [MPa].
    pub energy: f64,
    /// Stress function `f(x) = G′(x)` [MPa].
    pub stress: f64,
    /// Modulus `f′(x)` [MPa].
    pub modulus: f64,
}

impl GeneralizedTerm {
    /// Builds the term and derives `x_t = S_ini / C_ini` and
    /// `c = C_ini / ΔS_mid`, the two choices that make `f` C¹ at `x_t`.
    /// Parameter ranges are checked by [`crate::material::params`], not here.
    pub fn new(c_ini: f64, transition: Option<Transition>, lock: Option<Lock>) -> Self {
        let (x_t, rate) = match transition {
            Some(t) => (t.s_ini / c_ini, c_ini / t.delta_s_mid),
            None => (f64::INFINITY, 0.0),
        };
        Self {
            c_ini,
            transition,
            lock,
            x_t,
            rate,
        }
    }

    /// A linear term `f = C_ini x` (no transition, no lock).
    pub fn linear(c_ini: f64) -> Self {
        Self::new(c_ini, None, None)
    }

    /// The transition point `x_t = S_ini / C_ini` (infinite without a transition).
    pub fn transition_point(&self) -> f64 {
        self.x_t
    }

    /// The branch of Eq. (12) at `x`, with the same one-sided convention as
    /// [`GeneralizedTerm::eval`] (a boundary belongs to the upper branch).
    pub fn branch(&self, x: f64) -> TermBranch {
        let locked = self.lock.is_some_and(|l| x >= l.i_lock);
        match (x < self.x_t, locked) {
            (true, false) => TermBranch::Initial,
            (false, false) => TermBranch::Middle,
            (true, true) => TermBranch::InitialLocked,
            (false, true) => TermBranch::MiddleLocked,
        }
    }

    /// `f(x)` alone at `x ≥ 0` (Eq. 12), the same value as
    /// [`GeneralizedTerm::eval`] gives, at the cost of one `expm1`.
    #[inline(always)]
    pub fn stress(&self, x: f64) -> f64 {
        let mut stress = if x < self.x_t {
            self.c_ini * x
        } else {
            let t = self
                .transition
                .expect("x_t is finite only with a transition");
            let y = x - self.x_t;
            let (_, one_minus_decay) = decay_pair(self.rate * y);
            t.s_ini + (t.c_mid * y + t.delta_s_mid) * one_minus_decay
        };
        if let Some(lock) = self.lock
            && x >= lock.i_lock
        {
            let d = x - lock.i_lock;
            stress += lock.c_lock * d * d;
        }
        stress
    }

    /// `(G(x), f(x))`: [`GeneralizedTerm::eval`] without `f′`.
    #[inline(always)]
    pub fn energy_stress(&self, x: f64) -> (f64, f64) {
        let value = self.eval(x);
        (value.energy, value.stress)
    }

    /// `f(x)`, `f′(x)` and `G(x)` at `x ≥ 0` (Eq. 12 and its integral).
    #[inline(always)]
    pub fn eval(&self, x: f64) -> TermValue {
        let mut value = if x < self.x_t {
            TermValue {
                energy: 0.5 * self.c_ini * x * x,
                stress: self.c_ini * x,
                modulus: self.c_ini,
            }
        } else {
            // x ≥ x_t implies a transition exists (x_t is infinite otherwise).
            let t = self
                .transition
                .expect("x_t is finite only with a transition");
            let c = self.rate;
            let y = x - self.x_t;
            let z = c * y;
            let (decay, one_minus_decay) = decay_pair(z);
            let amplitude = t.c_mid * y + t.delta_s_mid;
            TermValue {
                energy: 0.5 * self.c_ini * self.x_t * self.x_t
                    + (t.s_ini + t.delta_s_mid) * y
                    + 0.5 * t.c_mid * y * y
                    - t.delta_s_mid * one_minus_decay / c
                    - t.c_mid * one_minus_decay_times_one_plus(z, decay, one_minus_decay) / (c * c),
                stress: t.s_ini + amplitude * one_minus_decay,
                modulus: t.c_mid * one_minus_decay + amplitude * c * decay,
            }
        };
        if let Some(lock) = self.lock
            && x >= lock.i_lock
        {
            let d = x - lock.i_lock;
            value.energy += lock.c_lock * d * d * d / 3.0;
            value.stress += lock.c_lock * d * d;
            value.modulus += 2.0 * lock.c_lock * d;
        }
        value
    }
}

/// `(e^(−z), 1 − e^(−z))` for `z ≥ 0` from one transcendental call, each to
/// a few ulps: above `ln 2`, `e^(−z) ≤ ½` and `1 − e^(−z)` loses nothing;
/// below, `expm1` gives `1 − e^(−z) ≤ ½` and `e^(−z) = 1 − that` is exact
/// to round-off.
#[inline(always)]
fn decay_pair(z: f64) -> (f64, f64) {
    if z > std::f64::consts::LN_2 {
        let decay = (-z).exp();
        (decay, 1.0 - decay)
    } else {
        let one_minus_decay = -(-z).exp_m1();
        (1.0 - one_minus_decay, one_minus_decay)
    }
}

/// `1 − e^(−z)(1 + z)` for `z ≥ 0` without cancellation at small `z`:
/// the series `Σ_{n≥2} (−1)ⁿ (n−1) zⁿ / n!` below 0.1, the closed form
/// `(1 − e^(−z)) − z e^(−z)` above, from the pair of [`decay_pair`].
#[inline]
fn one_minus_decay_times_one_plus(z: f64, decay: f64, one_minus_decay: f64) -> f64 {
    if z < 0.1 {
        // Terms n = 2..=9; the first omitted term is below 1e-10 · z²/2.
        let mut term = z * z / 2.0; // zⁿ/n! for n = 2
        let mut sum = term;
        let mut sign = -1.0;
        for n in 3..=9 {
            term *= z / n as f64;
            sum += sign * (n - 1) as f64 * term;
            sign = -sign;
        }
        sum
    } else {
        one_minus_decay - z * decay
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn series_matches_closed_form_where_both_are_accurate() {
        for &z in &[0.02_f64, 0.05, 0.0999] {
            let closed = 1.0 - (-z).exp() * (1.0 + z);
            let (decay, one_minus_decay) = decay_pair(z);
            let series = one_minus_decay_times_one_plus(z, decay, one_minus_decay);
            // The closed form loses about eps/z² relative accuracy here.
            assert!((closed - series).abs() <= 1e-12 * series.abs().max(1e-300) / (z * z));
        }
    }
}
