//! Element kernels. They integrate any law behind
//! [`crate::material::MembraneMaterial`] and know nothing of a specific law,
//! of meshes or of solvers; they allocate nothing and do no I/O.

pub mod bending;
pub mod fibre_triangle;
pub mod membrane;

pub use bending::{
    BendingElement, BendingError, BendingPass, BendingStiffness, BendingTopology, HingeKind,
};
pub use fibre_triangle::FibreTriangle;
pub use membrane::{MembraneKinematics, MembraneReference, MembraneTangent};
