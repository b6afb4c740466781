//! The rotation-free orthotropic bending element (S3/BST family).
//!
//! Each membrane triangle carries a curvature tensor computed from its own
//! three nodes and the three vertices opposite its edges in the edge
//! neighbours (a 6-node stencil). The curvature is the pull-back to the
//! reference fibre basis of a discrete shape operator built from hinge
//! measures `θ̂ = 2 sin(θ/2)` of the three edge dihedral angles (`2 sin θ`,
//! the measure of the mirror angle `2θ`, on clamped edges), divided by the
//! fibre stretches so that it measures the curvature `κ` along the current
//! *unit* rovings and stitching directions (the non-orthogonal material
//! frame of the sheared ply). The orthotropic bending law
//! `W = A0 ½ Δκᵀ D Δκ` thus follows the rovings and the stitching as the
//! ply shears, and an in-plane stretch or compression does not change the
//! bending energy of a given shape. See `docs/bending.md` for the
//! formulation, its derivation, the sign conventions and the limits.
//!
//! - [`topology`]: edge partners of a triangle mesh and hinge kinds;
//! - [`element`]: [`BendingElement`] (reference data) and the reference
//!   kernels (energy, curvature, force, exact tangent, frequency bound);
//! - [`explicit`]: [`BendingPass`], the three-phase force pass of the
//!   explicit solver that writes to each element's own three nodes only.
//!
//! Stencil slots: local `0, 1, 2` are the triangle's nodes (counter-clockwise
//! about its reference normal), local `3 + i` is the vertex of the
//! neighbouring triangle across edge `i`, the edge opposite node `i` (it
//! joins nodes `i + 1` and `i + 2` mod 3). Force vectors are node-major over
//! the six slots: `[x0, y0, z0, x1, …, z5]`.

pub mod element;
pub mod explicit;
pub mod topology;

pub use element::{BendingCurvature, BendingElement, BendingForce, BendingTangent};
pub use explicit::{BendingFailure, BendingPass, BendingScratch};
pub use topology::{BendingTopology, EdgePartner, TopologyError};

use nalgebra::{SMatrix, SVector};

/// Force vector over the 6-slot stencil (node-major, 18 values).
pub type StencilVector = SVector<f64, 18>;
/// Tangent over the 6-slot stencil (node-major, 18×18).
pub type StencilMatrix = SMatrix<f64, 18, 18>;

/// `1 + cos θ` at or below which an interior hinge counts as completely folded
/// (`|θ| ≥ π − 2·10⁻⁴`): the hinge measure `θ̂ = 2 sin(θ/2)` is singular
/// (its sign flips) at `θ = ±π`, and its derivative `1/cos(θ/2)`-scaled
/// terms grow without bound near it. Such a state is reported as
/// [`BendingError::FoldedHinge`] (docs/bending.md, "Limits").
pub const FOLD_LIMIT: f64 = 2.0e-8;

/// `cos θ` at or below which a clamped hinge counts as overturned
/// (`|θ| ≥ 90° − 0.0057°`): the clamped hinge measure `m_c = 2 sin θ` (the
/// measure of the angle `2θ` between the element and its mirror image
/// across the clamp plane) peaks at `θ = ±90°`, where the mirror angle is a
/// complete fold, and falls beyond, so the clamp would let go. The limit is
/// the fold limit of the mirror hinge, `1 + cos 2θ = 2 cos²θ ≤ FOLD_LIMIT`.
/// Such a state is reported as [`BendingError::OverturnedClamp`]
/// (docs/bending.md, "Free and clamped edges").
pub const CLAMP_LIMIT: f64 = 1.0e-4;

/// Relative area below which a triangle is degenerate:
/// `2A ≤ DEGENERATE_AREA · (longest edge)²`.
pub const DEGENERATE_AREA: f64 = 1e-12;

/// Shortest admissible in-plane projection of the (unit) fibre direction.
pub const MIN_FIBRE_PROJECTION: f64 = 1e-6;

/// What a hinge (an edge of the element) is (docs/bending.md, "Free and
/// clamped edges").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum HingeKind {
    /// A boundary edge without a hinge: contributes nothing.
    Free,
    /// An interior edge with a partner triangle; slot `3 + i` is a real node.
    Neighbour,
    /// A boundary edge on a clamp line: the partner is a fixed ghost vertex,
    /// the mirror image of the element's own opposite node across the edge
    /// line in the reference configuration, and the hinge measure is
    /// `2 sin θ` (the measure of the angle `2θ` between the element and its
    /// mirror image across the clamp plane), valid for `|θ| < 90°`.
    Clamped,
}

/// Bending stiffnesses `D = diag(B11, B22, B66)` [N·mm] acting on the
/// curvature change `[Δκ11, Δκ22, 2Δκ12]` on the current unit material
/// directions (docs/bending.md, "Energy and defaults").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BendingStiffness {
    /// `B11` [N·mm]: bending along the rovings (curvature `κ11`).
    pub b11: f64,
    /// `B22` [N·mm]: bending across the rovings (curvature `κ22`).
    pub b22: f64,
    /// `B66` [N·mm]: twist (acting on `2κ12`).
    pub b66: f64,
}

impl BendingStiffness {
    /// Paper value of `B11` [N·mm] (Schäfer et al., Compos. Part A 2024).
    pub const PAPER_B11: f64 = 4.06;
    /// Paper value of `B22` [N·mm] (Schäfer et al., Compos. Part A 2024).
    pub const PAPER_B22: f64 = 0.018;

    /// Validated stiffnesses: each finite and `≥ 0`.
    ///
    /// # Errors
    /// [`BendingError::InvalidStiffness`] naming the first bad parameter.
    pub fn new(b11: f64, b22: f64, b66: f64) -> Result<Self, BendingError> {
        for (name, value) in [("b11", b11), ("b22", b22), ("b66", b66)] {
            if !(value.is_finite() && value >= 0.0) {
                return Err(BendingError::InvalidStiffness { name, value });
            }
        }
        Ok(Self { b11, b22, b66 })
    }

    /// The paper's `B11 = 4.06`, `B22 = 0.018` N·mm and the assumption
    /// `B66 = B22` (the paper gives no twist stiffness; docs/bending.md,
    /// "Energy and defaults").
    pub fn paper() -> Self {
        Self {
            b11: Self::PAPER_B11,
            b22: Self::PAPER_B22,
            b66: Self::PAPER_B22,
        }
    }

    /// The diagonal `[B11, B22, B66]`.
    #[inline]
    pub fn diagonal(&self) -> [f64; 3] {
        [self.b11, self.b22, self.b66]
    }
}

impl Default for BendingStiffness {
    fn default() -> Self {
        Self::paper()
    }
}

/// Why a bending element cannot be set up or evaluated. Messages name the
/// parameter or edge, the value and what was expected.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum BendingError {
    /// The element's own triangle has (nearly) zero area.
    #[error("degenerate triangle: area {area:e} mm² is not positive (nodes collinear or repeated)")]
    Degenerate {
        /// The area \[mm²\].
        area: f64,
    },
    /// The fibre direction has no component in the triangle's plane.
    #[error("the fibre direction ({x}, {y}, {z}) is perpendicular to the triangle (or not finite)")]
    FibreOutOfPlane {
        /// Global x component.
        x: f64,
        /// Global y component.
        y: f64,
        /// Global z component.
        z: f64,
    },
    /// The partner (or ghost) triangle of a hinge has (nearly) zero area, so
    /// its normal, and the hinge angle, are undefined.
    #[error("degenerate hinge at edge {edge}: partner triangle area {area:e} mm² is not positive")]
    DegenerateHinge {
        /// Local edge index `0..3`.
        edge: usize,
        /// The partner triangle's area \[mm²\].
        area: f64,
    },
    /// An interior hinge is completely folded (`1 + cos θ ≤ FOLD_LIMIT`),
    /// where the hinge measure is singular.
    #[error(
        "hinge at edge {edge} is folded flat onto itself: 1 + cos θ = {one_plus_cos:e}, expected > {limit:e}",
        limit = FOLD_LIMIT
    )]
    FoldedHinge {
        /// Local edge index `0..3`.
        edge: usize,
        /// `1 + cos θ`.
        one_plus_cos: f64,
    },
    /// A clamped hinge is rotated to or past 90° about the clamp line
    /// (`cos θ ≤ CLAMP_LIMIT`), where its measure `2 sin θ` stops growing.
    #[error(
        "clamped hinge at edge {edge} is turned to or past 90° about the clamp line: cos θ = {cos:e}, expected > {limit:e}",
        limit = CLAMP_LIMIT
    )]
    OverturnedClamp {
        /// Local edge index `0..3`.
        edge: usize,
        /// `cos θ` against the fixed ghost triangle.
        cos: f64,
    },
    /// A node position is not finite.
    #[error("stencil slot {slot} has a non-finite position")]
    NonFinite {
        /// Slot `0..6`.
        slot: usize,
    },
    /// A lumped mass of a used stencil slot is not positive and finite.
    #[error("stencil slot {slot} has lumped mass {mass} t; expected a finite value > 0")]
    InvalidMass {
        /// Slot `0..6`.
        slot: usize,
        /// The mass given \[t\].
        mass: f64,
    },
    /// A bending stiffness is negative or not finite.
    #[error("bending stiffness {name} = {value} N·mm; expected a finite value ≥ 0")]
    InvalidStiffness {
        /// `b11`, `b22` or `b66`.
        name: &'static str,
        /// The value given.
        value: f64,
    },
}
