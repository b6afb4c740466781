//! Fibre frame of a membrane material point and the structural tensors
//! `∂I/∂C` of the linear pseudo-invariants (paper Eq. A.1–A.3).

use nalgebra::{Vector2, Vector3};

/// A symmetric 2×2 tensor stored as its tensor components `[T11, T22, T12]`
/// (no factor 2 on the shear entry). Used for `C`, `E` and `S`.
pub type Sym2 = Vector3<f64>;

/// Double contraction `A : B` of two symmetric tensors in [`Sym2`] storage.
#[inline]
pub fn contract(a: &Sym2, b: &Sym2) -> f64 {
    a[0] * b[0] + a[1] * b[1] + 2.0 * a[2] * b[2]
}

/// The identity tensor in [`Sym2`] storage.
pub fn identity() -> Sym2 {
    Sym2::new(1.0, 1.0, 0.0)
}

/// The roving direction `a0`, the stitching direction `b0` (`a0` turned by
/// +90° in the reference plane) and the structural tensors
/// `N4 = a0⊗a0`, `N6 = ½(a0⊗b0 + b0⊗a0)`, `N8 = b0⊗b0` (Eq. A.1–A.3, with the
/// symmetric form of A.2: erratum 3 in `docs/theory.md`).
///
/// Built once per element or material point; all vectors are in the same
/// orthonormal reference frame as `C`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FibreFrame {
    /// Unit roving direction `a0`.
    pub a0: Vector2<f64>,
    /// Unit stitching direction `b0 = R(+90°) a0`.
    pub b0: Vector2<f64>,
    /// `∂I4/∂C = a0⊗a0` in [`Sym2`] storage.
    pub n4: Sym2,
    /// `∂I6/∂C = ½(a0⊗b0 + b0⊗a0)` in [`Sym2`] storage.
    pub n6: Sym2,
    /// `∂I8/∂C = b0⊗b0` in [`Sym2`] storage.
    pub n8: Sym2,
}

impl FibreFrame {
    /// The frame whose rovings make the angle `angle_rad` with the first
    /// reference axis: `a0 = (cos θ, sin θ)`, `b0 = (−sin θ, cos θ)`.
    pub fn from_angle(angle_rad: f64) -> Self {
        let (s, c) = angle_rad.sin_cos();
        Self::from_unit(Vector2::new(c, s))
    }

    /// The frame with the rovings along the first reference axis:
    /// `a0 = E1`, `b0 = E2`, so that `C = [I4, I8, I6]`.
    pub fn aligned() -> Self {
        Self::from_unit(Vector2::new(1.0, 0.0))
    }

    /// The frame of a roving direction given as any non-zero vector; `None`
    /// for a zero or non-finite vector.
    pub fn from_direction(direction: Vector2<f64>) -> Option<Self> {
        let norm = direction.norm();
        if !(norm.is_finite() && norm > 0.0) {
            return None;
        }
        Some(Self::from_unit(direction / norm))
    }

    fn from_unit(a0: Vector2<f64>) -> Self {
        let b0 = Vector2::new(-a0.y, a0.x);
        Self {
            a0,
            b0,
            n4: Sym2::new(a0.x * a0.x, a0.y * a0.y, a0.x * a0.y),
            n6: Sym2::new(a0.x * b0.x, a0.y * b0.y, 0.5 * (a0.x * b0.y + a0.y * b0.x)),
            n8: Sym2::new(b0.x * b0.x, b0.y * b0.y, b0.x * b0.y),
        }
    }

    /// The structural tensors `[N4, N6, N8]`, ordered like the invariants
    /// `p = (I4, I6, I8)`.
    #[inline]
    pub fn structural(&self) -> [&Sym2; 3] {
        [&self.n4, &self.n6, &self.n8]
    }
}
