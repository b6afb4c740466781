//! Membrane material laws: pseudo-invariants, the generalized energy, the
//! UD-NCF law of Schäfer et al. (2024) with its consistent tangent, an
//! orthotropic St Venant–Kirchhoff law, parameter files, and the exact
//! derivatives of the stress with respect to the law's parameters.
//!
//! The laws know nothing of meshes or elements: they map `C` (2×2, in an
//! orthonormal reference frame) and a [`FibreFrame`] to `W`, `S` and `ℂ`.

pub mod coupling;
pub mod diagnostics;
pub mod frame;
pub mod generalized;
pub mod invariants;
pub mod lanes;
pub mod law;
pub mod params;
pub mod sensitivity;
pub mod svk;
pub mod udncf;

pub use coupling::Coupling;
pub use frame::{FibreFrame, Sym2};
pub use generalized::{GeneralizedTerm, Lock, TermBranch, Transition};
pub use invariants::Invariants;
pub use law::{MembraneMaterial, StressState, Tangent};
pub use params::{MaterialSpec, ParamsError};
pub use sensitivity::{CouplingParameter, LawParameter, TermName, TermParameter};
pub use svk::OrthotropicSvk;
pub use udncf::{Branches, UdNcf};

/// A state at which a law cannot be evaluated. Never replaced by NaN.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MaterialError {
    /// `C` has a NaN or infinite component.
    #[error("the right Cauchy-Green tensor C has a non-finite component")]
    NonFinite,
    /// `I4 = a0·C a0 ≤ 0`: the rovings have collapsed to zero length.
    #[error("collapsed rovings: I4 = a0·C·a0 = {i4:e} is not positive")]
    CollapsedRovings {
        /// The offending `I4`.
        i4: f64,
    },
    /// `det C ≤ 0`: an inverted or collapsed element.
    #[error("inverted or collapsed element: det C = {det:e} is not positive")]
    NonPositiveDeterminant {
        /// The offending `det C`.
        det: f64,
    },
    /// The state is admissible but the law overflowed (e.g. an extreme lock).
    #[error("the law's energy or stress overflowed at this state")]
    NonFiniteResponse,
}

/// A material law chosen at run time: static dispatch over the laws ncform
/// ships, so element loops stay monomorphic.
// One `Material` exists per run and is shared by reference, so the size
// difference between variants costs nothing; boxing would add an indirection
// to every evaluation.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Material {
    /// The UD-NCF law (Schäfer et al. 2024).
    UdNcf(UdNcf),
    /// The orthotropic St Venant–Kirchhoff cross-check law.
    OrthotropicSvk(OrthotropicSvk),
}

impl Material {
    /// `S` in the fibre basis from `C = [I4, I8, I6]` on lanes (one point
    /// or a SIMD batch), and the lanes the law accepts: each law's own lane
    /// form, the same arithmetic as its one-point
    /// [`MembraneMaterial::fibre_stress`].
    #[inline(always)]
    pub fn fibre_stress_lanes<V: lanes::Real>(&self, c: &[V; 3]) -> ([V; 3], V::Mask) {
        match self {
            Material::UdNcf(law) => law.fibre_stress_lanes(c),
            Material::OrthotropicSvk(law) => law.fibre_stress_lanes(c),
        }
    }
}

impl MembraneMaterial for Material {
    #[inline]
    fn stress(&self, c: &Sym2, frame: &FibreFrame) -> Result<StressState, MaterialError> {
        match self {
            Material::UdNcf(law) => law.stress(c, frame),
            Material::OrthotropicSvk(law) => law.stress(c, frame),
        }
    }

    #[inline(always)]
    fn fibre_stress(&self, c: &Sym2) -> Result<Sym2, MaterialError> {
        match self {
            Material::UdNcf(law) => law.fibre_stress(c),
            Material::OrthotropicSvk(law) => law.fibre_stress(c),
        }
    }

    fn coupling_factor(&self, i11: f64) -> f64 {
        match self {
            Material::UdNcf(law) => law.coupling_factor(i11),
            Material::OrthotropicSvk(law) => law.coupling_factor(i11),
        }
    }

    #[inline]
    fn stress_tangent(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
    ) -> Result<(StressState, Tangent), MaterialError> {
        match self {
            Material::UdNcf(law) => law.stress_tangent(c, frame),
            Material::OrthotropicSvk(law) => law.stress_tangent(c, frame),
        }
    }
}
