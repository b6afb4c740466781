//! Pseudo-invariants of the UD-NCF law, paper Eq. (3)–(7), and the first and
//! second derivatives of `I11` with respect to `p = (I4, I6, I8)` that the
//! stress (Eq. A.4–A.7) and the consistent tangent need.

use super::MaterialError;
use super::frame::{FibreFrame, Sym2, contract};
use super::lanes::Real;

/// The pseudo-invariants at one material point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Invariants {
    /// `I4 = a0·C a0`: squared stretch along the rovings (Eq. 3).
    pub i4: f64,
    /// `I6 = a0·C b0`: shear strain (Eq. 4).
    pub i6: f64,
    /// `I8 = b0·C b0`: squared stretch along the stitching (Eq. 5).
    pub i8: f64,
    /// `I11 = sqrt((I4 I8 − I6²)/I4)`: stretch perpendicular to the current
    /// rovings (Eq. 7).
    pub i11: f64,
}

/// The pseudo-invariants over a [`Real`]: of one point or of several
/// independent points at once (see [`Invariants`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InvariantLanes<V> {
    /// `I4` per lane.
    pub i4: V,
    /// `I6` per lane.
    pub i6: V,
    /// `I8` per lane.
    pub i8: V,
    /// `I11` per lane (meaningless on an inadmissible lane).
    pub i11: V,
    /// `1 / I4` per lane.
    pub inv_i4: V,
}

impl<V: Real> InvariantLanes<V> {
    /// [`Invariants::in_fibre_basis`] on lanes, `c = [C11, C22, C12]`: the
    /// invariants and, per lane, whether the state is admissible (finite
    /// `C`, `I4 > 0`, `det C > 0`, the same tests). `I11 = √(det C · (1/I4))`,
    /// with the reciprocal kept for the law.
    #[inline(always)]
    pub fn in_fibre_basis(c: &[V; 3]) -> (Self, V::Mask) {
        let [i4, i8, i6] = *c;
        let zero = i4.splat(0.0);
        let det = i4 * i8 - i6 * i6;
        let admissible =
            i4.is_finite() & i8.is_finite() & i6.is_finite() & i4.gt(zero) & det.gt(zero);
        let inv_i4 = i4.splat(1.0) / i4;
        let i11 = (det * inv_i4).sqrt();
        (
            Self {
                i4,
                i6,
                i8,
                i11,
                inv_i4,
            },
            admissible,
        )
    }
}

impl Invariants {
    /// Computes `I4, I6, I8, I11` from `C` in the frame's reference basis.
    ///
    /// # Errors
    /// Non-finite `C`, `I4 ≤ 0` (collapsed rovings) or `det C ≤ 0` (an
    /// inverted or collapsed element): never NaN.
    #[inline]
    pub fn new(c: &Sym2, frame: &FibreFrame) -> Result<Self, MaterialError> {
        if !(c[0].is_finite() && c[1].is_finite() && c[2].is_finite()) {
            return Err(MaterialError::NonFinite);
        }
        let i4 = contract(&frame.n4, c);
        let i6 = contract(&frame.n6, c);
        let i8 = contract(&frame.n8, c);
        // det C from the components (frame-independent round-off); it equals
        // I4 I8 − I6² because {a0, b0} is orthonormal.
        Self::checked(i4, i6, i8, c[0] * c[1] - c[2] * c[2])
    }

    /// The invariants with `I11 = √(det C / I4)`, or the error for
    /// collapsed rovings (`I4 ≤ 0`) or a non-positive `det C`.
    #[inline(always)]
    fn checked(i4: f64, i6: f64, i8: f64, det: f64) -> Result<Self, MaterialError> {
        if i4 <= 0.0 {
            return Err(MaterialError::CollapsedRovings { i4 });
        }
        if det <= 0.0 {
            return Err(MaterialError::NonPositiveDeterminant { det });
        }
        Ok(Self {
            i4,
            i6,
            i8,
            i11: (det / i4).sqrt(),
        })
    }

    /// The invariants of `C` given in the fibre basis (`a0 = E1`,
    /// `b0 = E2`): `I4 = C11`, `I8 = C22`, `I6 = C12`, with the checks of
    /// [`Invariants::new`].
    ///
    /// # Errors
    /// As [`Invariants::new`].
    #[inline(always)]
    pub fn in_fibre_basis(c: &Sym2) -> Result<Self, MaterialError> {
        if !(c[0].is_finite() && c[1].is_finite() && c[2].is_finite()) {
            return Err(MaterialError::NonFinite);
        }
        let (i4, i8, i6) = (c[0], c[1], c[2]);
        Self::checked(i4, i6, i8, i4 * i8 - i6 * i6)
    }

    /// `det C = I4 I11²` (equal to `I4 I8 − I6²`).
    pub fn det_c(&self) -> f64 {
        self.i4 * self.i11 * self.i11
    }

    /// `I10 = π/2 − arccos(I6 / sqrt(I4 I8))`: the shear angle γ12 \[rad\]
    /// (Eq. 6; output only).
    pub fn i10(&self) -> f64 {
        let cosine = (self.i6 / (self.i4 * self.i8).sqrt()).clamp(-1.0, 1.0);
        std::f64::consts::FRAC_PI_2 - cosine.acos()
    }

    /// Gradient `∂I11/∂p`, `p = (I4, I6, I8)` (Eq. A.5–A.7), via
    /// `J = I11² = I8 − I6²/I4`: `∂I11/∂p_k = J_,k / (2 I11)`.
    #[inline]
    pub fn i11_gradient(&self) -> [f64; 3] {
        let inv_i4 = 1.0 / self.i4;
        let r = self.i6 * inv_i4;
        let half_inv_i11 = 0.5 / self.i11;
        [r * r * half_inv_i11, -2.0 * r * half_inv_i11, half_inv_i11]
    }

    /// Hessian `∂²I11/∂p_k∂p_l = J_,kl / (2 I11) − J_,k J_,l / (4 I11³)`,
    /// with `J_,44 = −2 I6²/I4³`, `J_,46 = 2 I6/I4²`, `J_,66 = −2/I4` and all
    /// other second derivatives of `J` zero. See `docs/theory.md`.
    #[inline]
    pub fn i11_hessian(&self) -> [[f64; 3]; 3] {
        let inv_i4 = 1.0 / self.i4;
        let r = self.i6 * inv_i4;
        let dj = [r * r, -2.0 * r, 1.0];
        let d2j = [
            [-2.0 * r * r * inv_i4, 2.0 * r * inv_i4, 0.0],
            [2.0 * r * inv_i4, -2.0 * inv_i4, 0.0],
            [0.0, 0.0, 0.0],
        ];
        let a = 0.5 / self.i11;
        let b = a * a * a * 2.0; // 1/(4 I11³)
        let mut h = [[0.0; 3]; 3];
        for k in 0..3 {
            for l in 0..3 {
                h[k][l] = a * d2j[k][l] - b * dj[k] * dj[l];
            }
        }
        h
    }
}
