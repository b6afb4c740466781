//! The transverse tension – compaction coupling `k11(I11)`, paper Eq. (15)
//! corrected (erratum 1 in `docs/theory.md`): the exponent acts on the
//! compaction `1 − I11`, not on the constant `I11⁰`.
//!
//! ```text
//! k11(I11) = (1 − k_min) exp(−s11 (1 − I11)^e11) + k_min    I11 < 1
//! k11(I11) = 1                                               I11 ≥ 1
//! ```

use super::generalized::decay_lanes;
use super::lanes::Real;

/// Parameters of the coupling `k11` (Eq. 15, corrected).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Coupling {
    /// Lower bound `k_min ∈ [0, 1]` of `k11` at full compaction.
    pub k_min: f64,
    /// Intensity `s11 ≥ 0`.
    pub s11: f64,
    /// Onset exponent `e11 ≥ 1` (C¹ at `I11 = 1` for `e11 > 1`).
    pub e11: f64,
}

/// `k11` and its first two derivatives with respect to `I11`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CouplingValue {
    /// `k11(I11)`.
    pub k: f64,
    /// `dk11/dI11`.
    pub dk: f64,
    /// `d²k11/dI11²`.
    pub d2k: f64,
}

impl Coupling {
    /// `k11`, `k11′` and `k11″` at `I11` (one-sided from `I11 ≥ 1` at 1).
    ///
    /// With `u = 1 − I11` and `q = s11 u^e11`: `k′ = (1 − k_min) e^(−q) q′`,
    /// `k″ = (1 − k_min) e^(−q) (q′² − q″)`, `q′ = s11 e11 u^(e11−1)`,
    /// `q″ = s11 e11 (e11 − 1) u^(e11−2)`.
    #[inline(always)]
    pub fn eval(&self, i11: f64) -> CouplingValue {
        if i11 >= 1.0 {
            return CouplingValue {
                k: 1.0,
                dk: 0.0,
                d2k: 0.0,
            };
        }
        let u = 1.0 - i11;
        let e = self.e11;
        // u^(e−2) computed once; u > 0 here.
        let u_em2 = if e == 2.0 { 1.0 } else { u.powf(e - 2.0) };
        let u_em1 = u_em2 * u;
        let q = self.s11 * u_em1 * u;
        let dq = self.s11 * e * u_em1;
        let d2q = self.s11 * e * (e - 1.0) * u_em2;
        let scaled = (1.0 - self.k_min) * (-q).exp();
        CouplingValue {
            k: scaled + self.k_min,
            dk: scaled * dq,
            d2k: scaled * (dq * dq - d2q),
        }
    }

    /// `(k11, k11′)` per lane: the expressions of [`Coupling::eval`] without
    /// `k11″` (operands of `×` in either order), with `e^(−q)` from
    /// [`decay_lanes`]; `(1, 0)` on the lanes with `I11 ≥ 1`.
    #[inline(always)]
    pub fn value_slope_lanes<V: Real>(&self, i11: V) -> (V, V) {
        let one = i11.splat(1.0);
        let zero = i11.splat(0.0);
        let active = i11.lt(one);
        if !V::any(active) {
            return (one, zero);
        }
        // u = 1 − I11 > 0 on the active lanes (as −(I11 − 1), the same
        // value); the others take u = 1 and are discarded.
        let u = V::select(active, -(i11 - 1.0), one);
        let e = self.e11;
        let u_em2 = if e == 2.0 {
            one
        } else {
            u.map(|u| u.powf(e - 2.0))
        };
        let u_em1 = u_em2 * u;
        let q = u_em1 * self.s11 * u;
        let dq = u_em1 * (self.s11 * e);
        let scaled = decay_lanes(q) * (1.0 - self.k_min);
        (
            V::select(active, scaled + self.k_min, one),
            V::select(active, scaled * dq, zero),
        )
    }
}
