//! Analytic rigid tools: a local frame ([`Placement`]) and the shapes
//! defined in it ([`Plane`], [`Sphere`], [`Cylinder`], [`Torus`],
//! [`PlateWithHole`]), each answering the [`RigidSurface`] query with its
//! exact signed distance `d`, normal `∇d` and Hessian `∇²d`. See
//! `docs/tools.md`.
//!
//! Every shape but the sphere is a surface of revolution about the local z
//! axis. Its distance depends on the meridian coordinates
//! `(ρ, z) = (√(x² + y²), z)` only, and with the cylindrical basis
//! `e_ρ = (x, y, 0)/ρ`, `e_φ = (−y, x, 0)/ρ`, `e_z`:
//!
//! ```text
//! ∇d  = d_ρ e_ρ + d_z e_z
//! ∇²d = d_ρρ e_ρ⊗e_ρ + d_ρz (e_ρ⊗e_z + e_z⊗e_ρ) + d_zz e_z⊗e_z + (d_ρ/ρ) e_φ⊗e_φ   (tools §2)
//! ```
//!
//! the last term being the hoop curvature of the level sets. It is singular
//! on the axis `ρ = 0` unless `d_ρ = 0` there; see each shape for how the
//! axis is answered.

use nalgebra::{Matrix2, Matrix3, Rotation3, Vector2, Vector3};

use super::{RigidSurface, SurfaceNormal, SurfacePoint};

/// Relative size of the singular sets: a query closer than
/// `SINGULAR_FRACTION × (the shape's radius)` to a point or line where the
/// distance has no gradient (a sphere's centre, an axis) is answered `None`.
/// At `1e-12` the Hessian there would be `~1e12/R`, past any use, while
/// every point a contact search can meaningfully ask about is answered.
pub const SINGULAR_FRACTION: f64 = 1e-12;

/// Why a shape or a placement cannot be built.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ShapeError {
    /// A scalar parameter out of its range.
    #[error("{shape}: {parameter} = {}: expected {expected}", crate::config::readable_number(*.value))]
    Parameter {
        /// The shape (or tessellation) the parameter belongs to.
        shape: &'static str,
        /// The parameter's name.
        parameter: &'static str,
        /// The value given.
        value: f64,
        /// What the parameter must be.
        expected: String,
    },
    /// A direction (or point) of a placement out of its range.
    #[error(
        "placement: {parameter} = ({}, {}, {}): expected {expected}",
        crate::config::readable_number(.value[0]),
        crate::config::readable_number(.value[1]),
        crate::config::readable_number(.value[2])
    )]
    Direction {
        /// The parameter's name.
        parameter: &'static str,
        /// The vector given.
        value: [f64; 3],
        /// What the vector must be.
        expected: String,
    },
}

/// `value` if it is finite and positive, else the error naming it.
pub(crate) fn positive_finite(
    shape: &'static str,
    parameter: &'static str,
    value: f64,
) -> Result<f64, ShapeError> {
    finite_length(
        shape,
        parameter,
        value,
        value > 0.0,
        "a positive finite length [mm]",
    )
}

/// `value` if it is finite and not negative, else the error naming it.
pub(crate) fn non_negative_finite(
    shape: &'static str,
    parameter: &'static str,
    value: f64,
) -> Result<f64, ShapeError> {
    finite_length(
        shape,
        parameter,
        value,
        value >= 0.0,
        "a finite length >= 0 [mm]",
    )
}

/// `value` if it is finite and `allowed`, else the error naming it and
/// what was `expected`.
fn finite_length(
    shape: &'static str,
    parameter: &'static str,
    value: f64,
    allowed: bool,
    expected: &str,
) -> Result<f64, ShapeError> {
    if value.is_finite() && allowed {
        Ok(value)
    } else {
        Err(ShapeError::Parameter {
            shape,
            parameter,
            value,
            expected: expected.into(),
        })
    }
}

/// `true` when every component of `x` is finite.
pub(crate) fn all_finite(x: &Vector3<f64>) -> bool {
    x.iter().all(|c| c.is_finite())
}

fn finite_vector(parameter: &'static str, value: &Vector3<f64>) -> Result<(), ShapeError> {
    if all_finite(value) {
        Ok(())
    } else {
        Err(ShapeError::Direction {
            parameter,
            value: [value.x, value.y, value.z],
            expected: "finite components".into(),
        })
    }
}

/// A local frame: an origin and an orthonormal, right-handed rotation `R`
/// whose columns are the local x, y, z axes in world coordinates. A point
/// maps as `x_world = origin + R x_local`. Tools are defined in their local
/// frame and placed in the world with one of these (tools §1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Placement {
    origin: Vector3<f64>,
    rotation: Matrix3<f64>,
}

impl Default for Placement {
    fn default() -> Self {
        Self::identity()
    }
}

impl Placement {
    /// The world frame itself.
    pub fn identity() -> Self {
        Self {
            origin: Vector3::zeros(),
            rotation: Matrix3::identity(),
        }
    }

    /// The world axes moved to `origin` \[mm\].
    ///
    /// # Errors
    /// A non-finite origin.
    pub fn translation(origin: Vector3<f64>) -> Result<Self, ShapeError> {
        finite_vector("origin", &origin)?;
        Ok(Self {
            origin,
            rotation: Matrix3::identity(),
        })
    }

    /// The frame at `origin` \[mm\] whose local z is `axis` (normalised) and
    /// whose local x is `reference` projected on the plane normal to `axis`
    /// (normalised); local y = z × x. Without a reference, the world x axis
    /// is used, or the world y axis when `axis` is within ~26° of x
    /// (`|axis · x| > 0.9`).
    ///
    /// # Errors
    /// A non-finite origin, a zero or non-finite axis, or a reference
    /// (nearly) parallel to the axis (its projection shorter than 1e-6 of
    /// its length).
    pub fn new(
        origin: Vector3<f64>,
        axis: Vector3<f64>,
        reference: Option<Vector3<f64>>,
    ) -> Result<Self, ShapeError> {
        finite_vector("origin", &origin)?;
        let length = axis.norm();
        if !(length.is_finite() && length > 0.0) {
            return Err(ShapeError::Direction {
                parameter: "axis",
                value: [axis.x, axis.y, axis.z],
                expected: "a non-zero finite direction".into(),
            });
        }
        let z = axis / length;
        let reference = match reference {
            Some(r) => {
                finite_vector("reference", &r)?;
                r
            }
            None if z.x.abs() > 0.9 => Vector3::y(),
            None => Vector3::x(),
        };
        let projected = reference - z * reference.dot(&z);
        let projected_length = projected.norm();
        if projected_length.is_nan() || projected_length <= 1e-6 * reference.norm() {
            return Err(ShapeError::Direction {
                parameter: "reference",
                value: [reference.x, reference.y, reference.z],
                expected: format!(
                    "a direction not parallel to the axis ({}, {}, {})",
                    crate::config::readable_number(z.x),
                    crate::config::readable_number(z.y),
                    crate::config::readable_number(z.z)
                ),
            });
        }
        let x = projected / projected_length;
        let y = z.cross(&x);
        Ok(Self {
            origin,
            rotation: Matrix3::from_columns(&[x, y, z]),
        })
    }

    /// The frame at `origin` \[mm\] rotated by `rotation`.
    ///
    /// # Errors
    /// A non-finite origin or rotation.
    pub fn from_rotation(
        origin: Vector3<f64>,
        rotation: &Rotation3<f64>,
    ) -> Result<Self, ShapeError> {
        finite_vector("origin", &origin)?;
        let matrix = *rotation.matrix();
        if !matrix.iter().all(|c| c.is_finite()) {
            return Err(ShapeError::Direction {
                parameter: "rotation",
                value: [f64::NAN; 3],
                expected: "a finite rotation".into(),
            });
        }
        Ok(Self {
            origin,
            rotation: matrix,
        })
    }

    /// The same orientation at another origin \[mm\] (a tool moving without
    /// turning).
    ///
    /// # Errors
    /// A non-finite origin.
    pub fn with_origin(&self, origin: Vector3<f64>) -> Result<Self, ShapeError> {
        finite_vector("origin", &origin)?;
        Ok(Self {
            origin,
            rotation: self.rotation,
        })
    }

    /// The local origin in world coordinates \[mm\].
    pub fn origin(&self) -> Vector3<f64> {
        self.origin
    }

    /// `R`: its columns are the local x, y, z axes in world coordinates.
    pub fn rotation(&self) -> &Matrix3<f64> {
        &self.rotation
    }

    /// The local z axis in world coordinates.
    pub fn axis(&self) -> Vector3<f64> {
        self.rotation.column(2).into_owned()
    }

    /// A world point in local coordinates: `Rᵀ (x − origin)`.
    #[inline]
    pub fn to_local(&self, x: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.tr_mul(&(x - self.origin))
    }

    /// A local point in world coordinates: `origin + R p`.
    #[inline]
    pub fn to_world(&self, p: &Vector3<f64>) -> Vector3<f64> {
        self.origin + self.rotation * p
    }

    /// A world vector (direction, displacement) in local coordinates: `Rᵀ v`.
    #[inline]
    pub fn vector_to_local(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rotation.tr_mul(v)
    }

    /// A local vector in world coordinates: `R v`.
    #[inline]
    pub fn vector_to_world(&self, v: &Vector3<f64>) -> Vector3<f64> {
        self.rotation * v
    }

    /// A surface query answered in local coordinates, in world
    /// coordinates: the distance is unchanged, `n_w = R n`,
    /// `H_w = R H Rᵀ` (`d_w(x) = d(Rᵀ(x − origin))`, tools §1).
    #[inline]
    pub fn surface_point_to_world(&self, local: &SurfacePoint) -> SurfacePoint {
        SurfacePoint {
            distance: local.distance,
            normal: self.rotation * local.normal,
            hessian: self.rotation * local.hessian * self.rotation.transpose(),
        }
    }
}

/// A shape placed in the world: the [`RigidSurface`] query in world
/// coordinates, through [`Placement::to_local`] and
/// [`Placement::surface_point_to_world`] (tools §1).
#[derive(Debug, Clone, PartialEq)]
pub struct Placed<S> {
    /// The shape, in its local frame.
    pub shape: S,
    /// Where the local frame is.
    pub placement: Placement,
}

impl<S> Placed<S> {
    /// `shape` placed by `placement`.
    pub fn new(shape: S, placement: Placement) -> Self {
        Self { shape, placement }
    }
}

impl<S: RigidSurface> RigidSurface for Placed<S> {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        let local = self.placement.to_local(x);
        self.shape
            .closest(&local, max_distance)
            .map(|point| self.placement.surface_point_to_world(&point))
    }

    /// The distance and `n_w = R n`, as [`RigidSurface::closest`] gives
    /// them, without rotating the Hessian.
    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        let local = self.placement.to_local(x);
        self.shape
            .closest_normal(&local, max_distance)
            .map(|point| SurfaceNormal {
                distance: point.distance,
                normal: self.placement.rotation * point.normal,
            })
    }

    /// The shape's clearance at the local point (a rigid placement keeps
    /// distances).
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        self.shape.clearance(&self.placement.to_local(x))
    }
}

/// A borrowed surface answers as the surface (so `Placed<&dyn RigidSurface>`
/// works).
impl<S: RigidSurface + ?Sized> RigidSurface for &S {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        (**self).closest(x, max_distance)
    }

    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        (**self).closest_normal(x, max_distance)
    }

    #[inline]
    fn closest_normals(
        &self,
        points: &[Vector3<f64>],
        max_distances: &[f64],
        out: &mut [Option<SurfaceNormal>],
    ) {
        (**self).closest_normals(points, max_distances, out);
    }

    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        (**self).clearance(x)
    }
}

/// A boxed surface answers as the surface (so `Placed<Box<dyn RigidSurface>>`
/// works).
impl<S: RigidSurface + ?Sized> RigidSurface for Box<S> {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        (**self).closest(x, max_distance)
    }

    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        (**self).closest_normal(x, max_distance)
    }

    #[inline]
    fn closest_normals(
        &self,
        points: &[Vector3<f64>],
        max_distances: &[f64],
        out: &mut [Option<SurfaceNormal>],
    ) {
        (**self).closest_normals(points, max_distances, out);
    }

    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        (**self).clearance(x)
    }
}

/// Which side of a closed shape the ply is on (its free side, where the
/// distance is positive).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Side {
    /// The ply is outside the shape (a punch): the tool is the solid.
    #[default]
    Outside,
    /// The ply is inside the shape (a cavity): the tool is everything
    /// around it.
    Inside,
}

impl Side {
    /// `+1` outside, `−1` inside: the factor on the outside distance.
    #[inline]
    fn sign(self) -> f64 {
        match self {
            Side::Outside => 1.0,
            Side::Inside => -1.0,
        }
    }
}

/// The signed distance of a surface of revolution in its meridian plane:
/// `d(ρ, z)`, its gradient `(d_ρ, d_z)` and Hessian.
#[derive(Debug, Clone, Copy)]
struct Meridian {
    distance: f64,
    gradient: Vector2<f64>,
    hessian: Matrix2<f64>,
}

impl Meridian {
    fn scaled(self, sign: f64) -> Self {
        Self {
            distance: sign * self.distance,
            gradient: sign * self.gradient,
            hessian: sign * self.hessian,
        }
    }
}

/// The distance to a point `q` (meridian offset from a centre, `s = |q| > 0`)
/// minus `radius`: `d = s − radius`, `∇d = q/s`, `∇²d = (I − ∇d⊗∇d)/s`.
#[inline]
fn circle_meridian(q: Vector2<f64>, radius: f64) -> Meridian {
    let s = q.norm();
    let g = q / s;
    Meridian {
        distance: s - radius,
        gradient: g,
        hessian: (Matrix2::identity() - g * g.transpose()) / s,
    }
}

/// The 3-D answer of a surface of revolution at `x` (`ρ > 0`) from its
/// meridian answer (module doc, tools §2).
#[inline]
fn revolve(x: &Vector3<f64>, rho: f64, m: &Meridian) -> SurfacePoint {
    let e_rho = Vector3::new(x.x / rho, x.y / rho, 0.0);
    let e_phi = Vector3::new(-x.y / rho, x.x / rho, 0.0);
    let e_z = Vector3::z();
    let normal = revolve_normal(x, rho, &m.gradient);
    let h = &m.hessian;
    let rho_z = e_rho * e_z.transpose();
    let hessian = e_rho * e_rho.transpose() * h[(0, 0)]
        + (rho_z + rho_z.transpose()) * h[(0, 1)]
        + e_z * e_z.transpose() * h[(1, 1)]
        + e_phi * e_phi.transpose() * (m.gradient.x / rho);
    SurfacePoint {
        distance: m.distance,
        normal,
        hessian,
    }
}

/// The normal `d_ρ e_ρ + d_z e_z` of a surface of revolution at `x`
/// (`ρ > 0`), the one [`revolve`] gives.
#[inline]
fn revolve_normal(x: &Vector3<f64>, rho: f64, gradient: &Vector2<f64>) -> Vector3<f64> {
    let e_rho = Vector3::new(x.x / rho, x.y / rho, 0.0);
    e_rho * gradient.x + Vector3::z() * gradient.y
}

/// The distance and normal of [`revolve`] without its Hessian.
#[inline]
fn revolve_distance_normal(x: &Vector3<f64>, rho: f64, m: &Meridian) -> SurfaceNormal {
    SurfaceNormal {
        distance: m.distance,
        normal: revolve_normal(x, rho, &m.gradient),
    }
}

/// A clearance for non-finite points: none (never culled by a broad
/// phase).
#[inline]
fn finite_or_none(distance: f64) -> f64 {
    if distance.is_finite() {
        distance
    } else {
        f64::NEG_INFINITY
    }
}

/// The plane `z = 0` of the local frame, free side `z > 0`:
/// `d = z`, `∇d = e_z`, `∇²d = 0` (tools §3.1).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Plane;

impl Plane {
    /// The plane `z = 0`.
    pub fn new() -> Self {
        Self
    }
}

impl RigidSurface for Plane {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        if !all_finite(x) || x.z > max_distance {
            return None;
        }
        Some(SurfacePoint {
            distance: x.z,
            normal: Vector3::z(),
            hessian: Matrix3::zeros(),
        })
    }

    /// `d = z` (1-Lipschitz).
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        if all_finite(x) {
            x.z
        } else {
            f64::NEG_INFINITY
        }
    }
}

/// A sphere of radius `R` centred at the local origin (tools §3.2):
/// outside, `d = |x| − R`, `∇d = x/|x|`, `∇²d = (I − n⊗n)/|x|`; inside, all
/// three change sign. The centre is singular (`None` within
/// `SINGULAR_FRACTION · R` of it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    radius: f64,
    side: Side,
}

impl Sphere {
    /// A sphere of `radius` \[mm\] with the ply on `side`.
    ///
    /// # Errors
    /// A radius that is not positive and finite.
    pub fn new(radius: f64, side: Side) -> Result<Self, ShapeError> {
        Ok(Self {
            radius: positive_finite("sphere", "radius", radius)?,
            side,
        })
    }

    /// The radius `R` \[mm\].
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The side the ply is on.
    pub fn side(&self) -> Side {
        self.side
    }
}

impl Sphere {
    /// The query both [`RigidSurface`] answers share: `|x|`, the side's
    /// sign, the distance and the unit radial direction, or `None` as
    /// [`RigidSurface::closest`].
    #[inline]
    fn radial_query(
        &self,
        x: &Vector3<f64>,
        max_distance: f64,
    ) -> Option<(f64, f64, f64, Vector3<f64>)> {
        let r = x.norm();
        if !r.is_finite() {
            return None;
        }
        let sign = self.side.sign();
        let distance = sign * (r - self.radius);
        if distance > max_distance || r <= SINGULAR_FRACTION * self.radius {
            return None;
        }
        Some((r, sign, distance, x / r))
    }
}

impl RigidSurface for Sphere {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        let (r, sign, distance, n) = self.radial_query(x, max_distance)?;
        Some(SurfacePoint {
            distance,
            normal: n * sign,
            hessian: (Matrix3::identity() - n * n.transpose()) * (sign / r),
        })
    }

    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        let (_, sign, distance, n) = self.radial_query(x, max_distance)?;
        Some(SurfaceNormal {
            distance,
            normal: n * sign,
        })
    }

    /// `±(|x| − R)` (1-Lipschitz).
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        finite_or_none(self.side.sign() * (x.norm() - self.radius))
    }
}

/// An infinite circular cylinder of radius `R` about the local z axis
/// (tools §3.3): outside, `d = ρ − R`, `∇d = e_ρ`, `∇²d = e_φ⊗e_φ/ρ`;
/// inside, all three change sign. The axis is singular (`None` within
/// `SINGULAR_FRACTION · R` of it).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cylinder {
    radius: f64,
    side: Side,
}

impl Cylinder {
    /// A cylinder of `radius` \[mm\] with the ply on `side`.
    ///
    /// # Errors
    /// A radius that is not positive and finite.
    pub fn new(radius: f64, side: Side) -> Result<Self, ShapeError> {
        Ok(Self {
            radius: positive_finite("cylinder", "radius", radius)?,
            side,
        })
    }

    /// The radius `R` \[mm\].
    pub fn radius(&self) -> f64 {
        self.radius
    }

    /// The side the ply is on.
    pub fn side(&self) -> Side {
        self.side
    }
}

/// The distance `ρ = √(x² + y²)` \[mm\] of a point from the local z axis.
/// Not `hypot`: the coordinates are finite lengths in mm, far from
/// overflow, and the library `hypot` costs about as much as the rest of a
/// query.
#[inline]
fn radial(x: &Vector3<f64>) -> f64 {
    (x.x * x.x + x.y * x.y).sqrt()
}

impl Cylinder {
    /// `ρ` and the meridian at `x`, or `None` as [`RigidSurface::closest`].
    #[inline]
    fn meridian_query(&self, x: &Vector3<f64>, max_distance: f64) -> Option<(f64, Meridian)> {
        if !all_finite(x) {
            return None;
        }
        let rho = radial(x);
        let sign = self.side.sign();
        let distance = sign * (rho - self.radius);
        if distance > max_distance || rho <= SINGULAR_FRACTION * self.radius {
            return None;
        }
        let meridian = Meridian {
            distance,
            gradient: Vector2::new(sign, 0.0),
            hessian: Matrix2::zeros(),
        };
        Some((rho, meridian))
    }
}

impl RigidSurface for Cylinder {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        let (rho, meridian) = self.meridian_query(x, max_distance)?;
        Some(revolve(x, rho, &meridian))
    }

    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        let (rho, meridian) = self.meridian_query(x, max_distance)?;
        Some(revolve_distance_normal(x, rho, &meridian))
    }

    /// `±(ρ − R)` (1-Lipschitz).
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        finite_or_none(self.side.sign() * (radial(x) - self.radius))
    }
}

/// A ring torus about the local z axis: the points at distance `r` (minor
/// radius) from the circle of radius `R` (major radius) in the plane
/// `z = 0` (tools §3.4). Outside (the ply outside the tube),
/// `d = s − r` with `s = |(ρ − R, z)|` the distance to that circle; inside,
/// `d = r − s`. The core circle (`s < SINGULAR_FRACTION · r`) and the axis
/// (`ρ < SINGULAR_FRACTION · R`, where the closest point is a whole circle)
/// are singular: `None`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Torus {
    major_radius: f64,
    minor_radius: f64,
    side: Side,
}

impl Torus {
    /// A torus of `major_radius` `R` and `minor_radius` `r` \[mm\] with the
    /// ply on `side`.
    ///
    /// # Errors
    /// Radii that are not positive and finite, or `r ≥ R` (a horn or
    /// spindle torus, whose tube crosses the axis: `s − r` is then not its
    /// signed distance inside).
    pub fn new(major_radius: f64, minor_radius: f64, side: Side) -> Result<Self, ShapeError> {
        let major_radius = positive_finite("torus", "major_radius", major_radius)?;
        let minor_radius = positive_finite("torus", "minor_radius", minor_radius)?;
        if minor_radius >= major_radius {
            return Err(ShapeError::Parameter {
                shape: "torus",
                parameter: "minor_radius",
                value: minor_radius,
                expected: format!(
                    "less than the major radius {} mm",
                    crate::config::readable_number(major_radius)
                ),
            });
        }
        Ok(Self {
            major_radius,
            minor_radius,
            side,
        })
    }

    /// The major radius `R` \[mm\] (the tube's centre circle).
    pub fn major_radius(&self) -> f64 {
        self.major_radius
    }

    /// The minor radius `r` \[mm\] (the tube's radius).
    pub fn minor_radius(&self) -> f64 {
        self.minor_radius
    }

    /// The side the ply is on.
    pub fn side(&self) -> Side {
        self.side
    }
}

impl Torus {
    /// `ρ` and the meridian at `x`, or `None` as [`RigidSurface::closest`].
    #[inline]
    fn meridian_query(&self, x: &Vector3<f64>, max_distance: f64) -> Option<(f64, Meridian)> {
        if !all_finite(x) {
            return None;
        }
        let rho = radial(x);
        let q = Vector2::new(rho - self.major_radius, x.z);
        let s = q.norm();
        let sign = self.side.sign();
        if sign * (s - self.minor_radius) > max_distance
            || rho <= SINGULAR_FRACTION * self.major_radius
            || s <= SINGULAR_FRACTION * self.minor_radius
        {
            return None;
        }
        Some((rho, circle_meridian(q, self.minor_radius).scaled(sign)))
    }
}

impl RigidSurface for Torus {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        let (rho, meridian) = self.meridian_query(x, max_distance)?;
        Some(revolve(x, rho, &meridian))
    }

    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        let (rho, meridian) = self.meridian_query(x, max_distance)?;
        Some(revolve_distance_normal(x, rho, &meridian))
    }

    /// `±(s − r)`, `s` the distance to the core circle (1-Lipschitz).
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        let q = Vector2::new(radial(x) - self.major_radius, x.z);
        finite_or_none(self.side.sign() * (q.norm() - self.minor_radius))
    }
}

/// A die or blankholder: a flat plate, working face `z = 0`, solid below,
/// with a round opening of radius `R_o` about the z axis whose edge is
/// rounded by a fillet of radius `r_f` (tools §3.5).
///
/// In the meridian plane the solid is `{ρ ≥ R_o, z ≤ 0}` with its corner
/// rounded about the fillet centre `c = (R_o + r_f, −r_f)`; `d` is the
/// signed distance to it, positive above the face and inside the opening.
/// Four zones:
///
/// ```text
/// fillet  ρ <  R_o + r_f, z > −r_f:  d = |(ρ, z) − c| − r_f
/// face    ρ ≥  R_o + r_f, z > −r_f:  d = z
/// wall    ρ <  R_o + r_f, z ≤ −r_f:  d = R_o − ρ
/// deep    ρ ≥  R_o + r_f, z ≤ −r_f:  d = max(z, R_o − ρ)   (inside the plate)
/// ```
///
/// `d` and `∇d` are continuous across the face/fillet and fillet/wall
/// junctions (C¹); `∇²d` jumps there (the fillet's curvature starts), and
/// `∇d` jumps across the deep zone's medial plane `z = R_o − ρ` (inside the
/// solid, where the face is chosen on a tie). The revolved 3-D answer adds
/// the hoop term `(d_ρ/ρ) e_φ⊗e_φ`. On the axis (`ρ < SINGULAR_FRACTION ·
/// R_o`) the closest point is a whole circle and `d` has a conical kink:
/// `None`. There `d ≥ R_o > 0` (free side), so no contact is lost.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlateWithHole {
    opening_radius: f64,
    fillet_radius: f64,
    /// Beyond `R_o + r_f`, in-plane, a point above `z = −r_f` is
    /// certainly in the face zone.
    face_zone: FaceZone,
}

impl PlateWithHole {
    /// A plate with an opening of `opening_radius` `R_o` \[mm\] whose edge is
    /// rounded by `fillet_radius` `r_f` \[mm\] (`0` for a sharp edge, whose
    /// distance is then C¹ on the free side only).
    ///
    /// # Errors
    /// An opening radius that is not positive and finite, a fillet radius
    /// that is negative or not finite.
    pub fn new(opening_radius: f64, fillet_radius: f64) -> Result<Self, ShapeError> {
        let opening_radius = positive_finite("plate with hole", "opening_radius", opening_radius)?;
        let fillet_radius = non_negative_finite("plate with hole", "fillet_radius", fillet_radius)?;
        Ok(Self {
            opening_radius,
            fillet_radius,
            face_zone: FaceZone::new(opening_radius + fillet_radius, fillet_radius),
        })
    }

    /// The opening radius `R_o` \[mm\].
    pub fn opening_radius(&self) -> f64 {
        self.opening_radius
    }

    /// The fillet radius `r_f` \[mm\].
    pub fn fillet_radius(&self) -> f64 {
        self.fillet_radius
    }

    /// The meridian signed distance (the four zones of the type's doc).
    #[inline]
    fn meridian(&self, rho: f64, z: f64) -> Meridian {
        let (ro, rf) = (self.opening_radius, self.fillet_radius);
        let centre_rho = ro + rf;
        let face = Meridian {
            distance: z,
            gradient: Vector2::new(0.0, 1.0),
            hessian: Matrix2::zeros(),
        };
        let wall = Meridian {
            distance: ro - rho,
            gradient: Vector2::new(-1.0, 0.0),
            hessian: Matrix2::zeros(),
        };
        match (rho < centre_rho, z > -rf) {
            // ρ − c_ρ < 0 strictly: the offset from the centre is non-zero.
            (true, true) => circle_meridian(Vector2::new(rho - centre_rho, z + rf), rf),
            (false, true) => face,
            (true, false) => wall,
            (false, false) => {
                if z >= ro - rho {
                    face
                } else {
                    wall
                }
            }
        }
    }
}

impl PlateWithHole {
    /// `ρ` and the meridian at `x`, or `None` as [`RigidSurface::closest`].
    #[inline]
    fn meridian_query(&self, x: &Vector3<f64>, max_distance: f64) -> Option<(f64, Meridian)> {
        // The signed distance is never below z (it is z on the face, at
        // the fillet |(ρ − c_ρ, z + r_f)| − r_f ≥ z, max(z, R_o − ρ) ≥ z at the
        // wall): the cheap rejection of the nodes lifted off a die or a
        // blankholder.
        if !all_finite(x) || x.z > max_distance {
            return None;
        }
        let rho = radial(x);
        let meridian = self.meridian(rho, x.z);
        if meridian.distance > max_distance || rho <= SINGULAR_FRACTION * self.opening_radius {
            return None;
        }
        Some((rho, meridian))
    }
}

/// Relative margin on a squared radius within which the face-zone
/// shortcut of the plates ([`PlateWithHole`],
/// [`super::PlateWithPolygonHole`]) leaves the decision to the full
/// query: far above the rounding of a square or a square root (10⁻¹⁶),
/// far below any length of the benches (10⁻⁹ on the square is
/// 5·10⁻¹⁰ on the radius, 43 pm on a radius of 85 mm).
const FACE_ZONE_MARGIN: f64 = 1e-9;

/// The part of a plate's face zone (the flange of a blank, most of the
/// nodes pressed against a die or a blankholder) that is decided on the
/// squared in-plane radius, without the opening's geometry or a square
/// root: `z > −r_f` and `x² + y² ≥ R²(1 + FACE_ZONE_MARGIN)`, with `R` a
/// radius beyond which every in-plane point is on the face side of the
/// fillet. The margin keeps the decision on the face side of the rounding
/// of `ρ`, so that a point it accepts is one the full query puts on the
/// face.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct FaceZone {
    fillet_radius: f64,
    radius_squared: f64,
}

impl FaceZone {
    /// The zone beyond the in-plane radius `radius` \[mm\] of a plate with
    /// fillet radius `fillet_radius` \[mm\].
    pub(crate) fn new(radius: f64, fillet_radius: f64) -> Self {
        Self {
            fillet_radius,
            radius_squared: radius * radius * (1.0 + FACE_ZONE_MARGIN),
        }
    }

    /// `true` where `x` (plate frame) is certainly in the face zone.
    #[inline]
    pub(crate) fn contains(&self, x: &Vector3<f64>) -> bool {
        x.z > -self.fillet_radius && x.x * x.x + x.y * x.y >= self.radius_squared
    }
}

/// [`face_answer`] with the face's Hessian, zero.
#[inline]
pub(crate) fn face_point(x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
    face_answer(x, max_distance).map(|a| SurfacePoint {
        distance: a.distance,
        normal: a.normal,
        hessian: Matrix3::zeros(),
    })
}

/// The face zone's answer of a plate: the distance `z` and the normal
/// `e_z` (the full query gives `d_ρ e_ρ + d_z e_z` with `d_ρ = 0`,
/// `d_z = 1`: the same up to the sign of zero components).
#[inline]
pub(crate) fn face_answer(x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
    (x.z <= max_distance).then(|| SurfaceNormal {
        distance: x.z,
        normal: Vector3::z(),
    })
}

impl RigidSurface for PlateWithHole {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        if self.face_zone.contains(x) && all_finite(x) {
            return face_point(x, max_distance);
        }
        let (rho, meridian) = self.meridian_query(x, max_distance)?;
        Some(revolve(x, rho, &meridian))
    }

    /// In the face zone ([`FaceZone`]) without the square
    /// root and the radial unit vector.
    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        if self.face_zone.contains(x) && all_finite(x) {
            return face_answer(x, max_distance);
        }
        let (rho, meridian) = self.meridian_query(x, max_distance)?;
        Some(revolve_distance_normal(x, rho, &meridian))
    }

    /// The meridian distance of the four zones: continuous, and of unit
    /// gradient in each zone, so 1-Lipschitz (and `ρ` is 1-Lipschitz in
    /// `x`).
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        if !all_finite(x) {
            return f64::NEG_INFINITY;
        }
        if self.face_zone.contains(x) {
            return x.z;
        }
        self.meridian(radial(x), x.z).distance
    }
}
