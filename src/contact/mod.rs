//! Rigid tools and contact: the surfaces a ply can touch (analytic shapes,
//! round and polygonal, and triangle meshes), and the node-to-surface
//! contact and friction kernels. A surface answers one question, "where is this point relative
//! to me": its signed distance, the distance's gradient (the unit normal)
//! and its Hessian (the curvature of the level sets), which is what the
//! consistent contact tangent needs. See `docs/contact.md`.

pub mod kernel;
pub mod mesh_tool;
pub mod ply_pair;
pub mod pyramid;
pub mod surface;
pub mod tessellate;

pub use kernel::{ContactError, ContactStatus, ToolCoupled, couple_tool_translation};
pub use mesh_tool::{EdgeDefect, MeshOptions, MeshSurface, MeshToolError};
pub use pyramid::{PlateWithPolygonHole, Pyramid, punch_opening};
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

/// The first-order part of a [`SurfacePoint`]: the signed distance and the
/// normal, without the Hessian (what the explicit contact force needs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceNormal {
    /// Signed distance `d` \[mm\]: > 0 on the free side.
    pub distance: f64,
    /// `∇d`: the unit outward normal.
    pub normal: Vector3<f64>,
}

impl From<&SurfacePoint> for SurfaceNormal {
    #[inline]
    fn from(point: &SurfacePoint) -> Self {
        Self {
            distance: point.distance,
            normal: point.normal,
        }
    }
}

/// A rigid surface in its own frame.
pub trait RigidSurface: Send + Sync {
    /// The point `x` \[mm\] relative to the surface; `None` when `x` lies on
    /// the free side farther than `max_distance` from the surface (the
    /// cheap cull of far nodes) or where the distance has no gradient (a
    /// sphere's centre, say). A point inside the tool is always answered.
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint>;

    /// [`RigidSurface::closest`] without the Hessian: `Some` exactly when
    /// `closest(x, max_distance)` is, with the same distance and normal,
    /// bit for bit. The default takes them from `closest`; the analytic
    /// shapes skip the Hessian (and its rotation into the world frame).
    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        self.closest(x, max_distance)
            .map(|point| SurfaceNormal::from(&point))
    }

    /// [`RigidSurface::closest_normal`] of every point `points[k]` with
    /// `max_distances[k]`, into `out[k]` (the three slices of one length),
    /// with the same answers bit for bit. One call per batch of a contact
    /// loop: behind a `dyn RigidSurface` the default loop is compiled for
    /// the concrete shape, so the batch costs one dynamic call, not one per
    /// point, and the shape's query is inlined into a tight loop.
    #[inline]
    fn closest_normals(
        &self,
        points: &[Vector3<f64>],
        max_distances: &[f64],
        out: &mut [Option<SurfaceNormal>],
    ) {
        debug_assert!(points.len() == max_distances.len() && points.len() == out.len());
        for ((x, max_distance), answer) in points.iter().zip(max_distances).zip(out) {
            *answer = self.closest_normal(x, *max_distance);
        }
    }

    /// A lower bound `c ≤ d(x)` \[mm\] on the signed distance at `x`, for a
    /// broad phase (`docs/contact.md`, "Explicit path"): a surface that
    /// answers a finite value promises that its distance is 1-Lipschitz,
    /// `|d(x) − d(x′)| ≤ |x − x′|`, and that `closest(x′, m)` is `None`
    /// whenever `d(x′) > m`; so `c − |x′ − x| > m` (up to round-off)
    /// means `closest(x′, m)` is `None`. The default, `−∞`, promises
    /// nothing (the broad phase then checks the point every time): a mesh
    /// tool, whose inside and open sheets are answered by other rules.
    /// Cheap: the distance only.
    #[inline]
    fn clearance(&self, _x: &Vector3<f64>) -> f64 {
        f64::NEG_INFINITY
    }
}
