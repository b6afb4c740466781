//! Orthotropic St Venant–Kirchhoff membrane, plane stress: `S = Q : E` in the
//! fibre frame, `E = ½(C − I)`. A cross-check law for comparisons with other
//! solvers; written in the same invariants as the UD-NCF law, since
//! `E_aa = (I4 − 1)/2`, `E_bb = (I8 − 1)/2`, `E_ab = I6/2`.

use super::MaterialError;
use super::frame::{FibreFrame, Sym2};
use super::invariants::{InvariantLanes, Invariants};
use super::lanes::Real;
use super::law::{
    MembraneMaterial, StressState, Tangent, check_finite, stress_from_gradient,
    tangent_from_hessian,
};

/// Orthotropic plane-stress St Venant–Kirchhoff law.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrthotropicSvk {
    /// Young's modulus along the rovings `E1` \[MPa\].
    pub e1: f64,
    /// Young's modulus along the stitching `E2` \[MPa\].
    pub e2: f64,
    /// Major Poisson ratio `ν12` (`ν21 = ν12 E2/E1`).
    pub nu12: f64,
    /// In-plane shear modulus `G12` \[MPa\].
    pub g12: f64,
}

impl OrthotropicSvk {
    /// The plane-stress stiffness `(Q11, Q22, Q12, Q66)` \[MPa\]:
    /// `Q11 = E1/(1 − ν12ν21)`, `Q22 = E2/(1 − ν12ν21)`,
    /// `Q12 = ν12 E2/(1 − ν12ν21)`, `Q66 = G12`.
    pub fn plane_stress_stiffness(&self) -> (f64, f64, f64, f64) {
        let nu21 = self.nu12 * self.e2 / self.e1;
        let d = 1.0 - self.nu12 * nu21;
        (self.e1 / d, self.e2 / d, self.nu12 * self.e2 / d, self.g12)
    }

    /// Energy, gradient and Hessian in `p = (I4, I6, I8)`:
    /// `W = ⅛[Q11 (I4−1)² + 2 Q12 (I4−1)(I8−1) + Q22 (I8−1)²] + ½ G12 I6²`.
    fn evaluate(&self, c: &Sym2, frame: &FibreFrame) -> Result<(f64, [f64; 3]), MaterialError> {
        let inv = Invariants::new(c, frame)?;
        let (q11, q22, q12, q66) = self.plane_stress_stiffness();
        let d4 = inv.i4 - 1.0;
        let d8 = inv.i8 - 1.0;
        let energy = 0.125 * (q11 * d4 * d4 + 2.0 * q12 * d4 * d8 + q22 * d8 * d8)
            + 0.5 * q66 * inv.i6 * inv.i6;
        let gradient = [
            0.25 * (q11 * d4 + q12 * d8),
            q66 * inv.i6,
            0.25 * (q12 * d4 + q22 * d8),
        ];
        Ok((energy, gradient))
    }

    /// `S` in the fibre basis from `C = [I4, I8, I6]` on lanes, and the
    /// admissible lanes (finite `C`, `I4 > 0`, `det C > 0`, finite `S`):
    /// `S = 2 (g4 N4 + g6 N6 + g8 N8) = [2 g4, 2 g8, g6]` with the gradient
    /// of [`OrthotropicSvk::evaluate`]. The one-point path
    /// ([`MembraneMaterial::fibre_stress`]) is this on `f64`, so the batched
    /// force pass repeats it bit for bit.
    #[inline(always)]
    pub(crate) fn fibre_stress_lanes<V: Real>(&self, c: &[V; 3]) -> ([V; 3], V::Mask) {
        let (inv, admissible) = InvariantLanes::in_fibre_basis(c);
        let (q11, q22, q12, q66) = self.plane_stress_stiffness();
        let d4 = inv.i4 - 1.0;
        let d8 = inv.i8 - 1.0;
        let g4 = (d4 * q11 + d8 * q12) * 0.25;
        let g8 = (d4 * q12 + d8 * q22) * 0.25;
        let stress = [g4 * 2.0, g8 * 2.0, inv.i6 * q66];
        let finite = stress[0].is_finite() & stress[1].is_finite() & stress[2].is_finite();
        (stress, admissible & finite)
    }

    /// The constant Hessian `H44 = Q11/4`, `H48 = Q12/4`, `H88 = Q22/4`,
    /// `H66 = G12`.
    fn hessian(&self) -> [[f64; 3]; 3] {
        let (q11, q22, q12, q66) = self.plane_stress_stiffness();
        [
            [0.25 * q11, 0.0, 0.25 * q12],
            [0.0, q66, 0.0],
            [0.25 * q12, 0.0, 0.25 * q22],
        ]
    }
}

impl MembraneMaterial for OrthotropicSvk {
    fn stress(&self, c: &Sym2, frame: &FibreFrame) -> Result<StressState, MaterialError> {
        let (energy, gradient) = self.evaluate(c, frame)?;
        let state = StressState {
            energy,
            stress: stress_from_gradient(&gradient, frame),
        };
        check_finite(&state)?;
        Ok(state)
    }

    /// `OrthotropicSvk::fibre_stress_lanes` on one point.
    #[inline(always)]
    fn fibre_stress(&self, c: &Sym2) -> Result<Sym2, MaterialError> {
        let ([s11, s22, s12], accepted) = self.fibre_stress_lanes(&[c[0], c[1], c[2]]);
        if accepted {
            return Ok(Sym2::new(s11, s22, s12));
        }
        Invariants::in_fibre_basis(c)?;
        Err(MaterialError::NonFiniteResponse)
    }

    fn stress_tangent(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
    ) -> Result<(StressState, Tangent), MaterialError> {
        let state = self.stress(c, frame)?;
        Ok((state, tangent_from_hessian(&self.hessian(), frame)))
    }
}
