//! The UD-NCF hyperelastic membrane law of Schäfer et al. (2024), Eq. (11):
//! `W = W4(I4) + W6(I6) + W8(I8, I11) + W11(I11)`, with the errata of
//! `docs/theory.md` applied.

use super::MaterialError;
use super::coupling::Coupling;
use super::frame::{FibreFrame, Sym2};
use super::generalized::{GeneralizedTerm, TermBranch};
use super::invariants::{InvariantLanes, Invariants};
use super::lanes::Real;
use super::law::{
    MembraneMaterial, StressState, Tangent, check_finite, stress_from_gradient,
    tangent_from_hessian,
};

/// Half-width of the band around the kinks `I8 = 1` and `I11 = 1` that counts
/// as the kink itself: 64 ulps, the round-off of the invariants of a rotated
/// `C = I`. Inside it the loading side is taken with `x = 0`.
pub const KINK_TOLERANCE: f64 = 64.0 * f64::EPSILON;

/// The UD-NCF law: four generalized terms and the coupling `k11`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UdNcf {
    /// `W4 = G4(|I4 − 1|)`: roving tension and compression.
    pub w4: GeneralizedTerm,
    /// `W6 = G6(|I6|)`: shear.
    pub w6: GeneralizedTerm,
    /// `W8 = k11(I11) G8(I8 − 1)` for `I8 ≥ 1`: stitching tension.
    pub w8: GeneralizedTerm,
    /// `W11 = G11(1 − I11)` for `I11 ≤ 1`: compaction across the rovings.
    pub w11: GeneralizedTerm,
    /// The coupling `k11(I11)` (Eq. 15, corrected).
    pub coupling: Coupling,
}

/// Everything the law computes at one point, in invariant space.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct UdNcfPoint {
    /// The pseudo-invariants.
    pub invariants: Invariants,
    /// Total energy `W` \[MPa\].
    pub energy: f64,
    /// Energy contributions `[W4, W6, W8, W11]` \[MPa\].
    pub contributions: [f64; 4],
    /// Total derivative `dW/d(I4, I6, I8)` \[MPa\].
    pub gradient: [f64; 3],
    /// Total second derivative `d²W/d(I4, I6, I8)²` \[MPa\]; zero unless asked.
    pub hessian: [[f64; 3]; 3],
}

/// The branch of every piece of the law at one state: which side of each
/// kink (`I4 = 1`, `I6 = 0`, `I8 = 1`, `I11 = 1`, each term's `x_t` and
/// `I_lock`) the state lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Branches {
    /// `I4 ≥ 1` (tension) or not.
    pub roving_tension: bool,
    /// Branch of W4 at `|I4 − 1|`.
    pub w4: TermBranch,
    /// `I6 ≥ 0` or not.
    pub positive_shear: bool,
    /// Branch of W6 at `|I6|`.
    pub w6: TermBranch,
    /// Branch of W8 at `I8 − 1`, `None` when `I8 < 1` (inactive).
    pub w8: Option<TermBranch>,
    /// Branch of W11 at `1 − I11`, `None` when `I11 > 1` (inactive).
    pub w11: Option<TermBranch>,
}

impl UdNcf {
    /// The branches at a state (for coverage counts and for keeping
    /// finite-difference stencils off the kinks).
    pub fn branches(&self, inv: &Invariants) -> Branches {
        Branches {
            roving_tension: inv.i4 >= 1.0,
            w4: self.w4.branch((inv.i4 - 1.0).abs()),
            positive_shear: inv.i6 >= 0.0,
            w6: self.w6.branch(inv.i6.abs()),
            w8: (inv.i8 >= 1.0 - KINK_TOLERANCE).then(|| self.w8.branch((inv.i8 - 1.0).max(0.0))),
            w11: (inv.i11 <= 1.0 + KINK_TOLERANCE)
                .then(|| self.w11.branch((1.0 - inv.i11).max(0.0))),
        }
    }

    /// Evaluates energy, gradient and (if `with_hessian`) Hessian in
    /// `p = (I4, I6, I8)`, applying the chain rule through `I11(p)`.
    ///
    /// # Errors
    /// Degenerate states (see [`Invariants::new`]).
    #[inline]
    pub fn evaluate(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
        with_hessian: bool,
    ) -> Result<UdNcfPoint, MaterialError> {
        Ok(self.evaluate_invariants(Invariants::new(c, frame)?, with_hessian))
    }

    /// The law at given invariants: energy, gradient and, if
    /// `with_hessian`, the Hessian (zero otherwise).
    ///
    /// Partial derivatives at fixed `I11` are collected first
    /// (`W_,k`, `W_,kl`, `W_,11`, `W_,1111`, `W_,8 11`), then
    /// `g_k = W_,k + W_,11 I11_,k` and
    /// `H_kl = W_,kl + W_,k11 I11_,l + W_,l11 I11_,k + W_,1111 I11_,k I11_,l
    /// + W_,11 I11_,kl` (Eq. A.4–A.7).
    #[inline]
    pub fn evaluate_invariants(&self, inv: Invariants, with_hessian: bool) -> UdNcfPoint {
        let mut gradient = [0.0; 3];
        let mut hessian = [[0.0; 3]; 3];
        // Partial derivatives with respect to I11 at fixed (I4, I6, I8).
        let mut w_11 = 0.0;
        let mut w_11_11 = 0.0;
        let mut w_8_11 = 0.0;

        // W4 = G4(|I4 − 1|): dW4/dI4 = sgn(I4 − 1) f4 (erratum 2).
        let d4 = inv.i4 - 1.0;
        let t4 = self.w4.eval(d4.abs());
        gradient[0] = t4.stress.copysign(d4);
        hessian[0][0] = t4.modulus;

        // W6 = G6(|I6|).
        let t6 = self.w6.eval(inv.i6.abs());
        gradient[1] = t6.stress.copysign(inv.i6);
        hessian[1][1] = t6.modulus;

        // W11 = G11(1 − I11) for I11 ≤ 1: dW11/dI11 = −f11 (erratum 2).
        // At the kinks I11 = 1 and I8 = 1 the loading side is taken: W, S
        // are the same on both sides there, and the tangent then keeps the
        // initial stiffnesses, so the undeformed state has a regular tangent.
        let mut w11 = 0.0;
        if inv.i11 <= 1.0 + KINK_TOLERANCE {
            let t11 = self.w11.eval((1.0 - inv.i11).max(0.0));
            w11 = t11.energy;
            w_11 -= t11.stress;
            w_11_11 += t11.modulus;
        }

        // W8 = k11(I11) G8(I8 − 1) for I8 ≥ 1, coupled to I11.
        let mut w8 = 0.0;
        if inv.i8 >= 1.0 - KINK_TOLERANCE {
            let t8 = self.w8.eval((inv.i8 - 1.0).max(0.0));
            let k = self.coupling.eval(inv.i11);
            w8 = k.k * t8.energy;
            gradient[2] = k.k * t8.stress;
            hessian[2][2] = k.k * t8.modulus;
            w_11 += k.dk * t8.energy;
            w_11_11 += k.d2k * t8.energy;
            w_8_11 = k.dk * t8.stress;
        }

        // Chain rule through I11(I4, I6, I8) (Eq. A.4–A.7).
        let di11 = inv.i11_gradient();
        for k in 0..3 {
            gradient[k] += w_11 * di11[k];
        }
        if with_hessian {
            let d2i11 = inv.i11_hessian();
            for k in 0..3 {
                for l in 0..3 {
                    hessian[k][l] += w_11_11 * di11[k] * di11[l] + w_11 * d2i11[k][l];
                }
                // Mixed term W_,8 11: only k = 8 (index 2) depends on I11.
                hessian[2][k] += w_8_11 * di11[k];
                hessian[k][2] += w_8_11 * di11[k];
            }
        } else {
            hessian = [[0.0; 3]; 3];
        }

        let contributions = [t4.energy, t6.energy, w8, w11];
        UdNcfPoint {
            invariants: inv,
            energy: contributions.iter().sum(),
            contributions,
            gradient,
            hessian,
        }
    }
}

impl UdNcf {
    /// [`MembraneMaterial::fibre_stress`] over a [`Real`] (one point, or
    /// several independent points at once): `c = [C11, C22, C12]` in the
    /// fibre basis to `S = [S11, S22, S12]` in that basis and, per lane,
    /// whether the state is admissible and the stress finite (where
    /// `fibre_stress` returns `Ok`, with the same `S` bit for bit); the
    /// stress of a rejected lane is meaningless.
    #[inline(always)]
    pub(crate) fn fibre_stress_lanes<V: Real>(&self, c: &[V; 3]) -> ([V; 3], V::Mask) {
        let (inv, admissible) = InvariantLanes::in_fibre_basis(c);
        let stress = self.stress_of_lanes(&inv);
        let finite = stress[0].is_finite() & stress[1].is_finite() & stress[2].is_finite();
        (stress, admissible & finite)
    }

    /// The gradient of [`UdNcf::evaluate_invariants`] on lanes, as
    /// `S = 2 (g4 N4 + g6 N6 + g8 N8)` in the fibre basis: the same
    /// expressions (operands of `+` and `×` in either order), a branch taken
    /// where any lane needs it and selected per lane; the energy of W8 only
    /// where the coupling needs it (`I8 ≥ 1`, `I11 < 1`), and the chain rule
    /// through `I11` written out:
    /// `∂I11/∂(I4, I6, I8) = (r², −2r, 1) / (2 I11)`, `r = I6 · (1/I4)`.
    #[inline(always)]
    fn stress_of_lanes<V: Real>(&self, inv: &InvariantLanes<V>) -> [V; 3] {
        let InvariantLanes {
            i4,
            i6,
            i8,
            i11,
            inv_i4,
        } = *inv;
        let zero = i4.splat(0.0);
        let one = i4.splat(1.0);
        let d4 = i4 - 1.0;
        let mut g4 = self.w4.stress_lanes(d4.abs()).copysign(d4);
        let mut g6 = self.w6.stress_lanes(i6.abs()).copysign(i6);
        let mut g8 = zero;
        let mut w_11 = zero;
        let compacted = i11.le(i11.splat(1.0 + KINK_TOLERANCE));
        if V::any(compacted) {
            // 1 − I11 as −(I11 − 1): the same value.
            let f11 = self.w11.stress_lanes((-(i11 - 1.0)).max(zero));
            w_11 = V::select(compacted, -f11, zero);
        }
        let stretched = i8.ge(i8.splat(1.0 - KINK_TOLERANCE));
        if V::any(stretched) {
            let x8 = (i8 - 1.0).max(zero);
            let coupled = stretched & i11.lt(one);
            let stress8 = if V::any(coupled) {
                let (energy8, stress8) = self.w8.energy_stress_lanes(x8);
                let (k, dk) = self.coupling.value_slope_lanes(i11);
                w_11 = V::select(coupled, w_11 + dk * energy8, w_11);
                V::select(coupled, k * stress8, stress8)
            } else {
                self.w8.stress_lanes(x8)
            };
            g8 = V::select(stretched, stress8, zero);
        }
        let chained = w_11.ne(zero);
        if V::any(chained) {
            let r = i6 * inv_i4;
            let h = w_11 * 0.5 / i11;
            g4 = V::select(chained, g4 + r * r * h, g4);
            g6 = V::select(chained, g6 - r * 2.0 * h, g6);
            g8 = V::select(chained, g8 + h, g8);
        }
        // S = 2 (g4 N4 + g6 N6 + g8 N8) with N4 = E1⊗E1, N8 = E2⊗E2,
        // N6 = sym(E1⊗E2).
        [g4 * 2.0, g8 * 2.0, g6]
    }
}

impl MembraneMaterial for UdNcf {
    /// `k11(I11)` of the coupling (Eq. 15, corrected).
    fn coupling_factor(&self, i11: f64) -> f64 {
        self.coupling.eval(i11).k
    }

    #[inline]
    fn stress(&self, c: &Sym2, frame: &FibreFrame) -> Result<StressState, MaterialError> {
        let point = self.evaluate(c, frame, false)?;
        let state = StressState {
            energy: point.energy,
            stress: stress_from_gradient(&point.gradient, frame),
        };
        check_finite(&state)?;
        Ok(state)
    }

    /// The force pass's path: the stress of [`UdNcf::evaluate_invariants`]
    /// without the energy, as the one-lane case of
    /// `UdNcf::fibre_stress_lanes` (so the same bits as every lane of the
    /// batched pass); a rejected state is diagnosed by
    /// [`Invariants::in_fibre_basis`].
    #[inline(always)]
    fn fibre_stress(&self, c: &Sym2) -> Result<Sym2, MaterialError> {
        let ([s11, s22, s12], accepted) = self.fibre_stress_lanes(&[c[0], c[1], c[2]]);
        if accepted {
            return Ok(Sym2::new(s11, s22, s12));
        }
        Invariants::in_fibre_basis(c)?;
        Err(MaterialError::NonFiniteResponse)
    }

    #[inline]
    fn stress_tangent(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
    ) -> Result<(StressState, Tangent), MaterialError> {
        let point = self.evaluate(c, frame, true)?;
        let state = StressState {
            energy: point.energy,
            stress: stress_from_gradient(&point.gradient, frame),
        };
        check_finite(&state)?;
        let tangent = tangent_from_hessian(&point.hessian, frame);
        if tangent.iter().all(|v| v.is_finite()) {
            Ok((state, tangent))
        } else {
            Err(MaterialError::NonFiniteResponse)
        }
    }
}
