//! The membrane-material trait and the assembly of `S` and `ℂ` for laws
//! written in the linear pseudo-invariants `p = (I4, I6, I8)`.
//!
//! For `W = W(p)` with `p` linear in `C` (`∂p_k/∂C = N_k`, `∂²p/∂C∂C = 0`):
//! `S = 2 Σ_k g_k N_k` and `ℂ = 4 Σ_kl H_kl N_k ⊗ N_l`, where `g = dW/dp`
//! and `H = d²W/dp dp` are total derivatives (Eq. 8–10; `docs/theory.md`).

use nalgebra::Matrix3;

use super::MaterialError;
use super::frame::{FibreFrame, Sym2};

/// The consistent tangent `ℂ = 2 ∂S/∂C = 4 ∂²W/∂C∂C` in Voigt storage:
/// `tangent[(a, b)] = ℂ_ijkl` with `a = (ij)`, `b = (kl)` in the order
/// `(11, 22, 12)`, so that `dS_a = Σ_b ℂ_ab dE_b` for the engineering strain
/// increment `[dE11, dE22, 2 dE12]`.
pub type Tangent = Matrix3<f64>;

/// Energy density and second Piola–Kirchhoff stress at a material point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StressState {
    /// Strain energy density `W` [MPa = N·mm/mm³].
    pub energy: f64,
    /// `S = 2 ∂W/∂C` \[MPa\] in [`Sym2`] storage.
    pub stress: Sym2,
}

/// A hyperelastic membrane law: energy, stress and consistent tangent at a
/// given `C` and fibre frame. The law knows nothing of elements or meshes.
pub trait MembraneMaterial: Send + Sync {
    /// `W(C)` \[MPa\].
    ///
    /// # Errors
    /// Degenerate states (non-finite `C`, `det C ≤ 0`, collapsed rovings).
    fn energy(&self, c: &Sym2, frame: &FibreFrame) -> Result<f64, MaterialError> {
        self.stress(c, frame).map(|s| s.energy)
    }

    /// `W` and `S = 2 ∂W/∂C`.
    ///
    /// # Errors
    /// As [`MembraneMaterial::energy`].
    fn stress(&self, c: &Sym2, frame: &FibreFrame) -> Result<StressState, MaterialError>;

    /// `S` alone, for `C` given in the fibre basis (`a0 = E1`, `b0 = E2`,
    /// so `C = [I4, I8, I6]`), with `S` in that basis: the explicit solver's
    /// force pass, which needs neither the energy nor a frame. The default
    /// goes through [`MembraneMaterial::stress`] with the aligned frame.
    ///
    /// # Errors
    /// As [`MembraneMaterial::energy`].
    #[inline]
    fn fibre_stress(&self, c: &Sym2) -> Result<Sym2, MaterialError> {
        self.stress(c, &FibreFrame::aligned()).map(|s| s.stress)
    }

    /// The transverse-tension coupling factor `k11(I11)` (Eq. 15 as
    /// corrected in `docs/theory.md`) that scales the stitching energy;
    /// 1 for a law without coupling. Reported as a result field.
    fn coupling_factor(&self, _i11: f64) -> f64 {
        1.0
    }

    /// `W`, `S` and `ℂ = 4 ∂²W/∂C∂C`.
    ///
    /// # Errors
    /// As [`MembraneMaterial::energy`].
    fn stress_tangent(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
    ) -> Result<(StressState, Tangent), MaterialError>;
}

/// `S = 2 Σ_k g_k N_k` for the gradient `g = dW/d(I4, I6, I8)` (Eq. 8).
#[inline]
pub fn stress_from_gradient(gradient: &[f64; 3], frame: &FibreFrame) -> Sym2 {
    2.0 * (gradient[0] * frame.n4 + gradient[1] * frame.n6 + gradient[2] * frame.n8)
}

/// `ℂ = 4 Σ_kl H_kl N_k ⊗ N_l` for the symmetric Hessian
/// `H = d²W/d(I4, I6, I8)²`; major and minor symmetric by construction.
#[inline]
pub fn tangent_from_hessian(hessian: &[[f64; 3]; 3], frame: &FibreFrame) -> Tangent {
    let n = frame.structural();
    let mut tangent = Tangent::zeros();
    for k in 0..3 {
        // Σ_l H_kl N_l, then the outer product with N_k.
        let row = hessian[k][0] * n[0] + hessian[k][1] * n[1] + hessian[k][2] * n[2];
        tangent += 4.0 * n[k] * row.transpose();
    }
    tangent
}

/// Rejects a non-finite energy or stress so that NaN never leaves a law.
#[inline]
pub(crate) fn check_finite(state: &StressState) -> Result<(), MaterialError> {
    if state.energy.is_finite() && state.stress.iter().all(|s| s.is_finite()) {
        Ok(())
    } else {
        Err(MaterialError::NonFiniteResponse)
    }
}
