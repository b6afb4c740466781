//! Element kernels. They integrate any law behind
//! [`crate::material::MembraneMaterial`] and know nothing of a specific law,
//! of meshes or of solvers; they allocate nothing and do no I/O.

pub mod bending;
pub mod fibre_batch;
pub mod fibre_triangle;
pub mod membrane;

pub use bending::{
    BendingElement, BendingError, BendingPass, BendingStiffness, BendingTopology, HingeKind,
};
pub use fibre_batch::FibreMesh;
pub use fibre_triangle::{FibreTriangle, RovingCoupling, RovingMass};
pub use membrane::{MembraneKinematics, MembraneReference, MembraneTangent};

use crate::material::MaterialError;

/// Why a membrane triangle could not be evaluated.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum ElementFailureKind {
    /// The law rejected the state (collapsed element or rovings, …).
    #[error("{0}")]
    Material(MaterialError),
    /// The triangle turned over in its plane (checked for planar models).
    #[error("the triangle is inverted (signed area ratio {orientation:e})")]
    Inverted {
        /// `(g1 × g2) · N0`.
        orientation: f64,
    },
}
