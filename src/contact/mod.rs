//! Rigid tools and contact: the surfaces a ply can touch (analytic shapes
//! and triangle meshes), and the node-to-surface contact and friction
//! kernels. A surface answers one question, "where is this point relative
//! to me": its signed distance, the distance's gradient (the unit normal)
//! and its Hessian (the curvature of the level sets), which is what the
//! consistent contact tangent needs. See `docs/contact.md`.

pub mod kernel;
pub mod mesh_tool;
pub mod surface;
pub mod tessellate;

pub use kernel::{ContactError, ContactStatus, ToolCoupled, couple_tool_translation};
pub use mesh_tool::{EdgeDefect, MeshOptions, MeshSurface, MeshToolError};
pub use surface::{
    Cylinder, Placed, Placement, Plane, PlateWithHole, ShapeError, Side, Sphere, Torus,
};
pub use tessellate::Tessellation;

use nalgebra::{Matrix3, Vector3};

/// A point's relation to a rigid surface, in the surface's own frame.
///
/// With `d(x)` the signed distance from the surface, positive on the free
/// side (where the ply may be) and negative inside the tool:
/// `normal = ∇d` (unit, pointing away from the tool) and
/// `hessian = ∇²d` (symmetric, with `normal` in its null space; zero for a
/// plane or a flat facet, `(I − n⊗n)/ρ` at distance `ρ` from a sphere's
/// centre).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfacePoint {
    /// Signed distance `d` \[mm\]: > 0 on the free side.
    pub distance: f64,
    /// `∇d`: the unit outward normal of the surface at the closest point.
    pub normal: Vector3<f64>,
    /// `∇²d` [1/mm].
    pub hessian: Matrix3<f64>,
}

/// A rigid surface in its own frame.
pub trait RigidSurface: Send + Sync {
    /// The point `x` \[mm\] relative to the surface; `None` when `x` lies on
    /// the free side farther than `max_distance` from the surface (the
    /// cheap cull of far nodes) or where the distance has no gradient (a
    /// sphere's centre, say). A point inside the tool is always answered.
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint>;
}
