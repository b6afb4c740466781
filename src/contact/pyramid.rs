//! Polygonal analytic tools: a rounded regular pyramid ([`Pyramid`], the
//! punch of the tetrahedron bench) and a plate with a rounded convex
//! polygonal opening and a filleted edge ([`PlateWithPolygonHole`], its
//! die and blankholder), each answering the [`RigidSurface`] query with its
//! exact signed distance `d`, normal `∇d` and Hessian `∇²d`
//! (`docs/contact.md`, "Polygonal tools").
//!
//! Both solids are Minkowski sums of a convex (or product) core with a
//! ball: the rounded pyramid is a sharp pyramid `K` grown by the rounding
//! radius `r`, so outside `K` its distance is `dist(x, K) − r` and its
//! faces, edges and apex are exactly the offset surfaces of the core's
//! faces, edges and vertices. With `c` the closest point of the core and
//! `ρ = |x − c|`:
//!
//! ```text
//! face:    ∇d = n (the face normal),    ∇²d = 0
//! edge:    ∇d = (x − c)/ρ,              ∇²d = (I − t⊗t − ∇d⊗∇d)/ρ   (t along the edge)
//! vertex:  ∇d = (x − c)/ρ,              ∇²d = (I − ∇d⊗∇d)/ρ
//! ```
//!
//! The edge's Hessian has the curvature across the edge only (the level
//! sets are cylinders about the edge line). Inside the core the distance is
//! the largest face-plane distance minus `r` (exact for a convex
//! polyhedron), flat.

use std::f64::consts::{PI, TAU};

use nalgebra::{Matrix2, Matrix3, Vector2, Vector3};

use super::surface::{
    FaceZone, Placement, SINGULAR_FRACTION, ShapeError, Sphere, all_finite, face_answer,
    face_point, non_negative_finite, positive_finite,
};
use super::tessellate::{Tessellation, divisions, plate_profile};
use super::{RigidSurface, SurfaceNormal, SurfacePoint};

/// Where the closest point of a core lies: the Hessian of its distance.
#[derive(Debug, Clone, Copy)]
enum Feature {
    /// On a face (or inside the core): `∇²d = 0`.
    Flat,
    /// On an edge with unit tangent `t`, at distance `ρ`.
    Line(Vector3<f64>, f64),
    /// At a vertex, at distance `ρ`.
    Point(f64),
}

impl Feature {
    #[inline]
    fn hessian(&self, normal: &Vector3<f64>) -> Matrix3<f64> {
        match *self {
            Feature::Flat => Matrix3::zeros(),
            Feature::Line(t, rho) => {
                (Matrix3::identity() - t * t.transpose() - normal * normal.transpose()) / rho
            }
            Feature::Point(rho) => (Matrix3::identity() - normal * normal.transpose()) / rho,
        }
    }
}

/// The closest point of the segment `a + τ t`, `τ ∈ [0, length]`, to `p`:
/// its distance², the point, and whether it is an end (a vertex).
#[inline]
fn segment_closest(
    p: &Vector3<f64>,
    a: &Vector3<f64>,
    t: &Vector3<f64>,
    length: f64,
) -> (f64, Vector3<f64>, bool) {
    let tau = (p - a).dot(t);
    let (tau, end) = if tau <= 0.0 {
        (0.0, true)
    } else if tau >= length {
        (length, true)
    } else {
        (tau, false)
    };
    let c = a + t * tau;
    ((p - c).norm_squared(), c, end)
}

/// A rounded regular pyramid, apex down (the punch of the tetrahedron
/// bench): the Minkowski sum of a sharp regular `n`-gon pyramid `K` with a
/// ball of the rounding radius `r`, so that faces, edges and apex are
/// rounded alike (module doc).
///
/// Local frame: the solid's lowest point (the bottom of the rounded apex)
/// at the origin, the axis along `+z` (from the apex to the base), so that
/// the core's apex is at `(0, 0, r)` and its base, a regular `n`-gon, in the
/// plane `z = r + h` (`h` the core's height). Every lateral face makes the
/// angle `α` with the base plane (the regular tetrahedron: `n = 3`,
/// `cos α = 1/3`, `α ≈ 70.53°`); at the height `s` above the core's apex
/// the core's section is the `n`-gon of inradius `s·cot α`. One base edge
/// is parallel to the in-plane direction at the azimuth `ψ` from the local
/// x axis: the face whose outward normal points to the azimuth `ψ − 90°`
/// (for `ψ = 0`: the base edge on the `−y` side, along `x`; for `n = 3` a
/// vertex on `+y`, and the pyramid is mirror-symmetric about `x = 0`).
/// The ply is outside.
#[derive(Debug, Clone, PartialEq)]
pub struct Pyramid {
    sides: usize,
    face_angle: f64,
    radius: f64,
    height: f64,
    edge_azimuth: f64,
    /// Per face `k`: the horizontal unit direction `(cos φ_k, sin φ_k)` of
    /// its outward normal.
    face_dirs: Vec<Vector2<f64>>,
    /// Per face `k`: the outward unit normal `(sin α cos φ_k, sin α sin φ_k,
    /// −cos α)`.
    normals: Vec<Vector3<f64>>,
    /// Per lateral edge `k` (between faces `k` and `k + 1`, at the azimuth
    /// `φ_k + π/n`): its unit direction from the apex to the base.
    edges: Vec<Vector3<f64>>,
    /// The lateral edges' length `h/sin β`.
    edge_length: f64,
    /// Per lateral edge `k`: its base vertex, relative to the core's apex.
    vertices: Vec<Vector3<f64>>,
    /// Per face `k`: the unit direction of its base edge, from vertex
    /// `k − 1` to vertex `k`.
    base_dirs: Vec<Vector3<f64>>,
    /// The base edges' length.
    base_length: f64,
}

impl Pyramid {
    /// The rounded pyramid with `sides` `n ≥ 3` lateral faces at
    /// `face_angle` `α` \[rad\] to the base plane, rounding radius `r`
    /// \[mm\] (apex and every edge), core height `h` \[mm\] and one base
    /// edge along the azimuth `edge_azimuth` `ψ` \[rad\] (type doc).
    ///
    /// # Errors
    /// Fewer than 3 sides, a face angle outside `(0°, 90°)`, a radius or a
    /// height that is not positive and finite, a non-finite azimuth.
    pub fn new(
        sides: usize,
        face_angle: f64,
        radius: f64,
        height: f64,
        edge_azimuth: f64,
    ) -> Result<Self, ShapeError> {
        if sides < 3 {
            return Err(ShapeError::Parameter {
                shape: "pyramid",
                parameter: "sides",
                value: sides as f64,
                expected: "at least 3 lateral faces".into(),
            });
        }
        if !(face_angle.is_finite() && face_angle > 0.0 && face_angle < 0.5 * PI) {
            return Err(ShapeError::Parameter {
                shape: "pyramid",
                parameter: "face_angle",
                value: face_angle,
                expected: "an angle in (0, π/2) [rad] to the base plane".into(),
            });
        }
        let radius = positive_finite("pyramid", "rounding_radius", radius)?;
        let height = positive_finite("pyramid", "height", height)?;
        if !edge_azimuth.is_finite() {
            return Err(ShapeError::Parameter {
                shape: "pyramid",
                parameter: "edge_azimuth",
                value: edge_azimuth,
                expected: "a finite angle [rad]".into(),
            });
        }
        let (sin_a, cos_a) = face_angle.sin_cos();
        let cot_a = cos_a / sin_a;
        let half = PI / sides as f64;
        let circum = cot_a / half.cos(); // horizontal reach of an edge per unit height
        let phi = |k: usize| edge_azimuth - 0.5 * PI + TAU * k as f64 / sides as f64;
        let face_dirs: Vec<Vector2<f64>> = (0..sides)
            .map(|k| Vector2::new(phi(k).cos(), phi(k).sin()))
            .collect();
        let normals = face_dirs
            .iter()
            .map(|d| Vector3::new(sin_a * d.x, sin_a * d.y, -cos_a))
            .collect();
        let edge_vector = |k: usize| {
            let a = phi(k) + half;
            Vector3::new(circum * a.cos(), circum * a.sin(), 1.0)
        };
        let edge_length = height * edge_vector(0).norm();
        let edges: Vec<Vector3<f64>> = (0..sides).map(|k| edge_vector(k).normalize()).collect();
        let vertices: Vec<Vector3<f64>> = (0..sides).map(|k| edge_vector(k) * height).collect();
        let base_dirs = (0..sides)
            .map(|k| (vertices[k] - vertices[(k + sides - 1) % sides]).normalize())
            .collect();
        let base_length = 2.0 * height * cot_a * half.tan();
        Ok(Self {
            sides,
            face_angle,
            radius,
            height,
            edge_azimuth,
            face_dirs,
            normals,
            edges,
            edge_length,
            vertices,
            base_dirs,
            base_length,
        })
    }

    /// The number of lateral faces `n`.
    pub fn sides(&self) -> usize {
        self.sides
    }

    /// The lateral faces' angle `α` to the base plane \[rad\].
    pub fn face_angle(&self) -> f64 {
        self.face_angle
    }

    /// The rounding radius `r` of apex and edges \[mm\].
    pub fn rounding_radius(&self) -> f64 {
        self.radius
    }

    /// The core's height `h` \[mm\] (the solid reaches `z = h + 2r`).
    pub fn height(&self) -> f64 {
        self.height
    }

    /// The azimuth `ψ` of one base edge in the local frame \[rad\].
    pub fn edge_azimuth(&self) -> f64 {
        self.edge_azimuth
    }

    /// The azimuth of face `k`'s outward normal, `φ_k = ψ − π/2 + 2πk/n`
    /// \[rad\].
    pub fn face_azimuth(&self, k: usize) -> f64 {
        self.edge_azimuth - 0.5 * PI + TAU * (k % self.sides) as f64 / self.sides as f64
    }

    /// The lateral edges' elevation `β` above the base plane \[rad\]:
    /// `tan β = tan α · cos(π/n)`.
    pub fn edge_angle(&self) -> f64 {
        (self.face_angle.tan() * (PI / self.sides as f64).cos()).atan()
    }

    /// The solid's section by the plane `z = z_local` (above the rounded
    /// apex) approximated by a rounded `n`-gon `Q ⊕ disc(ρ_s)`: returns
    /// `(inradius of Q, ρ_s)` \[mm\], `Q` centred on the axis with the
    /// faces' azimuths. Its straight sides are exact (the traces of the
    /// offset faces, at the inradius `s·cot α + r/sin α`, `s = z − r`), and
    /// so is its outermost point at each corner, the vertex of the ellipse
    /// the edge's cylinder cuts (at `r/sin β` beyond the core's edge):
    /// `ρ_s = (r/(σ sin α) − r/sin β)/(1/σ − 1)`, `σ = cos(π/n)`,
    /// independent of the height. Between the two the arc lies slightly
    /// outside the true section (by up to 0.11 mm for the regular
    /// tetrahedron with `r = 10 mm`, measured in `tests/pyramid.rs`).
    ///
    /// # Errors
    /// A plane below the core's apex (`s ≤ 0`) or not below its base
    /// (`s ≥ h`), or a section too small for its corners.
    pub fn section(&self, z_local: f64) -> Result<(f64, f64), ShapeError> {
        let r = self.radius;
        let s = z_local - r;
        if !(s.is_finite() && s > 0.0 && s < self.height) {
            return Err(ShapeError::Parameter {
                shape: "pyramid section",
                parameter: "height above the tip",
                value: z_local,
                expected: format!(
                    "a plane cutting the punch's faces: between {} and {} mm above its tip",
                    crate::config::readable_number(r),
                    crate::config::readable_number(r + self.height)
                ),
            });
        }
        let (sin_a, cos_a) = self.face_angle.sin_cos();
        let sigma = (PI / self.sides as f64).cos();
        let face = s * cos_a / sin_a + r / sin_a;
        let corner = (r / (sigma * sin_a) - r / self.edge_angle().sin()) / (1.0 / sigma - 1.0);
        let inradius = face - corner;
        if !(inradius > 0.0 && corner >= 0.0) {
            return Err(ShapeError::Parameter {
                shape: "pyramid section",
                parameter: "height above the tip",
                value: z_local,
                expected: "a section larger than its rounded corners".into(),
            });
        }
        Ok((inradius, corner))
    }

    /// The shared query: the distance, normal and closest feature of the
    /// core, or `None` as [`RigidSurface::closest`].
    #[inline]
    fn query(&self, x: &Vector3<f64>, max_distance: f64) -> Option<(f64, Vector3<f64>, Feature)> {
        if !all_finite(x) {
            return None;
        }
        let r = self.radius;
        let p = Vector3::new(x.x, x.y, x.z - r);
        // The face whose sector holds the point: the largest horizontal
        // component along a face normal (module doc: by the mirror planes
        // through the axis and the edges, the closest point of the core is
        // in that sector).
        let mut k = 0;
        let mut reach = f64::NEG_INFINITY;
        for (j, d) in self.face_dirs.iter().enumerate() {
            let v = d.x * p.x + d.y * p.y;
            if v > reach {
                reach = v;
                k = j;
            }
        }
        let (sin_a, cos_a) = self.face_angle.sin_cos();
        let face = sin_a * reach - cos_a * p.z;
        let top = p.z - self.height;
        let plane = face.max(top);
        // d ≥ (largest face-plane distance) − r: the cheap cull.
        if plane - r > max_distance {
            return None;
        }
        if plane <= 0.0 {
            // Inside the core: the nearest face plane.
            let normal = if face >= top {
                self.normals[k]
            } else {
                Vector3::z()
            };
            return Some((plane - r, normal, Feature::Flat));
        }
        let cot_a = cos_a / sin_a;
        let half_tan = (PI / self.sides as f64).tan();
        if face > 0.0 {
            let n = &self.normals[k];
            let q = p - n * face;
            let d = &self.face_dirs[k];
            let across = -d.y * q.x + d.x * q.y;
            if q.z >= 0.0 && q.z <= self.height && across.abs() <= q.z * cot_a * half_tan {
                return Some((face - r, *n, Feature::Flat));
            }
        }
        if top > 0.0 && reach <= self.height * cot_a {
            return Some((top - r, Vector3::z(), Feature::Flat));
        }
        // The edges of the sector: lateral edges k − 1 and k, base edge k.
        let n = self.sides;
        let before = (k + n - 1) % n;
        let origin = Vector3::zeros();
        let candidates = [
            (origin, self.edges[before], self.edge_length),
            (origin, self.edges[k], self.edge_length),
            (self.vertices[before], self.base_dirs[k], self.base_length),
        ];
        let mut best = (f64::INFINITY, Vector3::zeros(), Feature::Flat);
        for (a, t, length) in candidates {
            let (d2, c, end) = segment_closest(&p, &a, &t, length);
            if d2 < best.0 {
                best = (
                    d2,
                    c,
                    if end {
                        Feature::Point(0.0)
                    } else {
                        Feature::Line(t, 0.0)
                    },
                );
            }
        }
        let rho = best.0.sqrt();
        if rho <= SINGULAR_FRACTION * r || rho - r > max_distance {
            return None;
        }
        let normal = (p - best.1) / rho;
        let feature = match best.2 {
            Feature::Line(t, _) => Feature::Line(t, rho),
            _ => Feature::Point(rho),
        };
        Some((rho - r, normal, feature))
    }

    /// The closed surface drawn for the output: the unit sphere of
    /// directions (`segments` around) mapped by the inverse Gauss map,
    /// `ω ↦ support_K(ω) + r ω` (each direction to the point of the solid
    /// whose outward normal it is), so that faces, edges and apex are drawn
    /// with the right normals.
    ///
    /// # Errors
    /// Fewer than 3 segments.
    pub fn tessellate(&self, segments: usize) -> Result<Tessellation, ShapeError> {
        let sphere = Sphere::new(1.0, super::Side::Outside)?;
        let mut mesh = sphere.tessellate(PI, segments)?;
        let apex = Vector3::new(0.0, 0.0, self.radius);
        for v in &mut mesh.vertices {
            let w = *v;
            let mut support = apex;
            let mut best = 0.0;
            for c in &self.vertices {
                let s = w.dot(c);
                if s > best {
                    best = s;
                    support = apex + c;
                }
            }
            *v = support + w * self.radius;
        }
        Ok(mesh)
    }
}

impl RigidSurface for Pyramid {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        let (distance, normal, feature) = self.query(x, max_distance)?;
        Some(SurfacePoint {
            distance,
            normal,
            hessian: feature.hessian(&normal),
        })
    }

    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        let (distance, normal, _) = self.query(x, max_distance)?;
        Some(SurfaceNormal { distance, normal })
    }

    /// The exact signed distance (1-Lipschitz: the distance to a convex
    /// set minus a constant outside the core, the largest face-plane
    /// distance inside, continuous across).
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        self.query(x, f64::INFINITY)
            .map_or(f64::NEG_INFINITY, |(d, _, _)| d)
    }
}

/// A die or blankholder with a polygonal opening: a plate, working face
/// `z = 0`, solid below, whose opening is a convex polygon `Q` rounded by
/// the corner radius `ρ_o` (the opening `O = Q ⊕ disc(ρ_o)`), and whose edge
/// around the opening is rounded by the fillet radius `r_f`.
///
/// The solid is the Minkowski sum of a core with a ball of radius `r_f`:
/// the core is the half-space `z ≤ −r_f` minus the opening grown by `r_f`
/// (`H = Q ⊕ disc(ρ_o + r_f)`). With `u` the in-plane signed distance to
/// `H` (`u = sd_Q − ρ_o − r_f`, `sd_Q` the signed distance to the
/// polygon, exact inside and outside a convex polygon), the distance
/// depends on `(u, z)` as that of [`super::PlateWithHole`] on `(ρ − R_o −
/// r_f, z)`:
///
/// ```text
/// fillet  u <  0, z > −r_f:  d = |(u, z + r_f)| − r_f
/// face    u ≥  0, z > −r_f:  d = z
/// wall    u <  0, z ≤ −r_f:  d = −u − r_f
/// deep    u ≥  0, z ≤ −r_f:  d = max(z, −u − r_f)   (inside the plate)
/// ```
///
/// and with `g = ∇sd_Q` (in-plane, unit) and `∇²sd_Q` (zero on the side of
/// an edge, `(I − g⊗g)/δ` at the distance `δ` from a vertex of `Q`):
/// `∇d = d_u g + d_z e_z`, `∇²d = d_uu g⊗g + d_uz (g⊗e_z + e_z⊗g) +
/// d_zz e_z⊗e_z + d_u ∇²sd_Q`. Within `SINGULAR_FRACTION (ρ_o + r_f)` of a
/// vertex of `Q` (inside the opening, at least `ρ_o` from the plate) the
/// answer is `None`.
#[derive(Debug, Clone, PartialEq)]
pub struct PlateWithPolygonHole {
    /// The polygon's vertices, counter-clockwise.
    vertices: Vec<Vector2<f64>>,
    /// Per edge `i` (from vertex `i` to `i + 1`): unit tangent.
    tangents: Vec<Vector2<f64>>,
    /// Per edge: outward unit normal.
    normals: Vec<Vector2<f64>>,
    /// Per edge: its length.
    lengths: Vec<f64>,
    /// Per edge: `normal · vertex`.
    offsets: Vec<f64>,
    corner_radius: f64,
    fillet_radius: f64,
    /// Beyond `max_v |v| + ρ_o + r_f`, in-plane, a point above `z = −r_f`
    /// is certainly in the face zone (`u ≥ 0`: the distance to the convex
    /// `Q` is at least `|p| − max_v |v|`).
    face_zone: FaceZone,
}

/// The in-plane signed distance to a convex polygon: value, unit
/// gradient, and the distance to the closest vertex when that is the
/// closest point (for the Hessian `(I − g⊗g)/δ`).
#[derive(Debug, Clone, Copy)]
struct PolygonDistance {
    value: f64,
    gradient: Vector2<f64>,
    vertex: Option<f64>,
}

impl PlateWithPolygonHole {
    /// The plate whose opening is the convex polygon `polygon` (local
    /// `(x, y)` \[mm\], counter-clockwise, at least 3 vertices) rounded by
    /// `corner_radius` `ρ_o ≥ 0`, its edge rounded by `fillet_radius`
    /// `r_f ≥ 0` \[mm\].
    ///
    /// # Errors
    /// Fewer than 3 vertices, non-finite coordinates, an edge shorter than
    /// 1e-9 mm, a polygon that is not strictly convex and counter-clockwise,
    /// negative or non-finite radii, or both radii zero.
    pub fn new(
        polygon: &[Vector2<f64>],
        corner_radius: f64,
        fillet_radius: f64,
    ) -> Result<Self, ShapeError> {
        let shape = "plate with polygon hole";
        let m = polygon.len();
        if m < 3 {
            return Err(ShapeError::Parameter {
                shape,
                parameter: "polygon",
                value: m as f64,
                expected: "at least 3 vertices".into(),
            });
        }
        non_negative_finite(shape, "corner_radius", corner_radius)?;
        non_negative_finite(shape, "fillet_radius", fillet_radius)?;
        if corner_radius + fillet_radius <= 0.0 {
            return Err(ShapeError::Parameter {
                shape,
                parameter: "fillet_radius",
                value: fillet_radius,
                expected: "a length > 0 [mm] when the corner radius is 0".into(),
            });
        }
        let mut tangents = Vec::with_capacity(m);
        let mut normals = Vec::with_capacity(m);
        let mut lengths = Vec::with_capacity(m);
        let mut offsets = Vec::with_capacity(m);
        for i in 0..m {
            let (a, b) = (polygon[i], polygon[(i + 1) % m]);
            let e = b - a;
            let length = e.norm();
            if !(length.is_finite() && length > 1e-9) {
                return Err(ShapeError::Parameter {
                    shape,
                    parameter: "polygon edge length",
                    value: length,
                    expected: "finite vertices, no two consecutive ones closer than 1e-9 mm".into(),
                });
            }
            let t = e / length;
            let n = Vector2::new(t.y, -t.x);
            tangents.push(t);
            normals.push(n);
            lengths.push(length);
            offsets.push(n.dot(&a));
        }
        for i in 0..m {
            let (t0, t1) = (tangents[i], tangents[(i + 1) % m]);
            if t0.x * t1.y - t0.y * t1.x <= 1e-12 {
                return Err(ShapeError::Parameter {
                    shape,
                    parameter: "polygon vertex",
                    value: ((i + 1) % m) as f64,
                    expected: "a strictly convex polygon, counter-clockwise".into(),
                });
            }
        }
        let farthest = polygon.iter().fold(0.0_f64, |r, v| r.max(v.norm()));
        Ok(Self {
            vertices: polygon.to_vec(),
            tangents,
            normals,
            lengths,
            offsets,
            corner_radius,
            fillet_radius,
            face_zone: FaceZone::new(farthest + corner_radius + fillet_radius, fillet_radius),
        })
    }

    /// The opening's polygon `Q` (counter-clockwise) \[mm\].
    pub fn polygon(&self) -> &[Vector2<f64>] {
        &self.vertices
    }

    /// The opening's corner radius `ρ_o` \[mm\].
    pub fn corner_radius(&self) -> f64 {
        self.corner_radius
    }

    /// The fillet radius `r_f` \[mm\].
    pub fn fillet_radius(&self) -> f64 {
        self.fillet_radius
    }

    /// The signed distance to `Q` at the in-plane point `p`.
    #[inline]
    fn polygon_distance(&self, p: &Vector2<f64>) -> PolygonDistance {
        let mut worst = f64::NEG_INFINITY;
        let mut edge = 0;
        for (i, (n, h)) in self.normals.iter().zip(&self.offsets).enumerate() {
            let v = n.dot(p) - h;
            if v > worst {
                worst = v;
                edge = i;
            }
        }
        if worst <= 0.0 {
            return PolygonDistance {
                value: worst,
                gradient: self.normals[edge],
                vertex: None,
            };
        }
        // Outside: an edge's strip or a vertex's wedge.
        for i in 0..self.vertices.len() {
            let v = self.normals[i].dot(p) - self.offsets[i];
            if v > 0.0 {
                let tau = self.tangents[i].dot(&(p - self.vertices[i]));
                if tau >= 0.0 && tau <= self.lengths[i] {
                    return PolygonDistance {
                        value: v,
                        gradient: self.normals[i],
                        vertex: None,
                    };
                }
            }
        }
        let mut best = (f64::INFINITY, Vector2::zeros());
        for q in &self.vertices {
            let e = p - q;
            let d2 = e.norm_squared();
            if d2 < best.0 {
                best = (d2, e);
            }
        }
        let delta = best.0.sqrt();
        PolygonDistance {
            value: delta,
            gradient: best.1 / delta,
            vertex: Some(delta),
        }
    }

    /// The `(u, z)` distance of the four zones (type doc): value, gradient
    /// `(d_u, d_z)`, Hessian.
    #[inline]
    fn section(&self, u: f64, z: f64) -> (f64, Vector2<f64>, Matrix2<f64>) {
        let rf = self.fillet_radius;
        let face = (z, Vector2::new(0.0, 1.0), Matrix2::zeros());
        let wall = (-u - rf, Vector2::new(-1.0, 0.0), Matrix2::zeros());
        match (u < 0.0, z > -rf) {
            (true, true) => {
                let q = Vector2::new(u, z + rf);
                let s = q.norm();
                let g = q / s;
                (s - rf, g, (Matrix2::identity() - g * g.transpose()) / s)
            }
            (false, true) => face,
            (true, false) => wall,
            (false, false) => {
                if z >= -u - rf {
                    face
                } else {
                    wall
                }
            }
        }
    }

    /// The shared query: distance, normal and the pieces of the Hessian,
    /// or `None` as [`RigidSurface::closest`].
    #[inline]
    #[allow(clippy::type_complexity)]
    fn query(
        &self,
        x: &Vector3<f64>,
        max_distance: f64,
    ) -> Option<(
        f64,
        Vector3<f64>,
        PolygonDistance,
        Vector2<f64>,
        Matrix2<f64>,
    )> {
        // d ≥ z in every zone (as for the round plate): the cheap cull.
        if !all_finite(x) || x.z > max_distance {
            return None;
        }
        let p = Vector2::new(x.x, x.y);
        let poly = self.polygon_distance(&p);
        let grown = self.corner_radius + self.fillet_radius;
        if poly
            .vertex
            .is_some_and(|delta| delta <= SINGULAR_FRACTION * grown)
        {
            return None;
        }
        let u = poly.value - grown;
        let (distance, gradient, hessian) = self.section(u, x.z);
        if distance > max_distance {
            return None;
        }
        let g = poly.gradient;
        let normal = Vector3::new(gradient.x * g.x, gradient.x * g.y, gradient.y);
        Some((distance, normal, poly, gradient, hessian))
    }

    /// The working surface drawn for the output: the wall of the opening
    /// from `z = −r_f − wall_length` up to `z = −r_f`, the fillet and the
    /// face out to `outer` \[mm\] beyond the opening's edge; `segments`
    /// around a full turn of the corners (at least one piece per corner)
    /// and `⌈segments/4⌉` pieces along the fillet.
    ///
    /// # Errors
    /// An outer width that is not positive and finite, a negative or
    /// non-finite wall length, fewer than 3 segments.
    pub fn tessellate(
        &self,
        outer: f64,
        wall_length: f64,
        segments: usize,
    ) -> Result<Tessellation, ShapeError> {
        let shape = "plate with polygon hole tessellation";
        let outer = positive_finite(shape, "outer", outer)?;
        let wall_length = non_negative_finite(shape, "wall_length", wall_length)?;
        if segments < 3 {
            return Err(ShapeError::Parameter {
                shape,
                parameter: "segments",
                value: segments as f64,
                expected: "at least 3 segments around".into(),
            });
        }
        let (ro, rf) = (self.corner_radius, self.fillet_radius);
        // The profile (w, z): w the in-plane distance from Q; free side on
        // the left when run up the wall, over the fillet, out the face.
        let step = (TAU * (ro + rf).max(1.0) / segments as f64).max(1.0);
        let profile = plate_profile(
            (ro, rf),
            (wall_length, divisions(wall_length, step)),
            if rf > 0.0 { segments.div_ceil(4) } else { 0 },
            (outer, divisions(outer, 4.0 * step)),
        );
        // The outline of Q: (base point, outward normal), counter-clockwise;
        // each vertex's arc of normals from the previous edge's to the next.
        let m = self.vertices.len();
        let mut outline: Vec<(Vector2<f64>, Vector2<f64>)> = Vec::new();
        for i in 0..m {
            let n0 = self.normals[(i + m - 1) % m];
            let n1 = self.normals[i];
            let turn = n0.x * n1.y - n0.y * n1.x;
            let angle = turn.atan2(n0.dot(&n1));
            let pieces = ((angle / TAU * segments as f64).ceil() as usize).max(1);
            for j in 0..=pieces {
                let a = n0.y.atan2(n0.x) + angle * j as f64 / pieces as f64;
                outline.push((self.vertices[i], Vector2::new(a.cos(), a.sin())));
            }
        }
        let mut mesh = Tessellation::default();
        let rows = profile.len();
        for (base, normal) in &outline {
            for w in &profile {
                let q = base + normal * w.x;
                mesh.vertices.push(Vector3::new(q.x, q.y, w.y));
            }
        }
        let columns = outline.len();
        let id = |j: usize, k: usize| (j % columns) * rows + k;
        for j in 0..columns {
            for k in 0..rows - 1 {
                let (a, b) = (id(j, k), id(j, k + 1));
                let (c, d) = (id(j + 1, k + 1), id(j + 1, k));
                mesh.triangles.push([a, b, c]);
                mesh.triangles.push([a, c, d]);
            }
        }
        Ok(mesh)
    }
}

impl RigidSurface for PlateWithPolygonHole {
    #[inline]
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        if self.face_zone.contains(x) && all_finite(x) {
            return face_point(x, max_distance);
        }
        let (distance, normal, poly, gradient, h) = self.query(x, max_distance)?;
        let g = Vector3::new(poly.gradient.x, poly.gradient.y, 0.0);
        let e_z = Vector3::z();
        let gz = g * e_z.transpose();
        let mut hessian = g * g.transpose() * h[(0, 0)]
            + (gz + gz.transpose()) * h[(0, 1)]
            + e_z * e_z.transpose() * h[(1, 1)];
        if let Some(delta) = poly.vertex {
            hessian += (Matrix3::identity() - e_z * e_z.transpose() - g * g.transpose())
                * (gradient.x / delta);
        }
        Some(SurfacePoint {
            distance,
            normal,
            hessian,
        })
    }

    #[inline]
    fn closest_normal(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfaceNormal> {
        if self.face_zone.contains(x) && all_finite(x) {
            return face_answer(x, max_distance);
        }
        let (distance, normal, _, _, _) = self.query(x, max_distance)?;
        Some(SurfaceNormal { distance, normal })
    }

    /// The distance of the four zones: continuous, and of unit gradient in
    /// each zone (`sd_Q` is 1-Lipschitz in the plane), so 1-Lipschitz.
    #[inline]
    fn clearance(&self, x: &Vector3<f64>) -> f64 {
        if !all_finite(x) {
            return f64::NEG_INFINITY;
        }
        if self.face_zone.contains(x) {
            return x.z;
        }
        let p = Vector2::new(x.x, x.y);
        let u = self.polygon_distance(&p).value - (self.corner_radius + self.fillet_radius);
        self.section(u, x.z).0
    }
}

/// The opening of a plate that follows a [`Pyramid`] punch: the punch's
/// section by the plate's plane at the punch's full stroke (approximated
/// as in [`Pyramid::section`]) grown by `clearance`, as the polygon `Q`
/// (counter-clockwise, in the plate's local `(x, y)`) and the corner radius
/// `ρ_s + clearance` to give [`PlateWithPolygonHole::new`].
///
/// `punch` places the pyramid at its start, `stroke` is its displacement
/// at full depth \[mm\], `plate` the plate's frame and `section_at` a point
/// of the plane (normal to the plate's axis) where the section is taken
/// (the plate's origin for its own face).
///
/// # Errors
/// A punch axis not parallel to the plate's axis (to 1e-9), a plane that
/// does not cut the punch's faces at full depth ([`Pyramid::section`]), a
/// negative or non-finite clearance.
pub fn punch_opening(
    punch: &Pyramid,
    punch_placement: &Placement,
    stroke: &Vector3<f64>,
    plate: &Placement,
    section_at: &Vector3<f64>,
    clearance: f64,
) -> Result<(Vec<Vector2<f64>>, f64), ShapeError> {
    let clearance = non_negative_finite("punch opening", "clearance", clearance)?;
    let axis = punch_placement.axis();
    let plate_axis = plate.axis();
    if axis.dot(&plate_axis).abs() < 1.0 - 1e-9 {
        return Err(ShapeError::Direction {
            parameter: "axis",
            value: [plate_axis.x, plate_axis.y, plate_axis.z],
            expected: format!(
                "parallel to the punch's axis ({}, {}, {})",
                crate::config::readable_number(axis.x),
                crate::config::readable_number(axis.y),
                crate::config::readable_number(axis.z)
            ),
        });
    }
    let tip = punch_placement.origin() + stroke;
    let above = (section_at - tip).dot(&axis);
    let (inradius, corner) = punch.section(above)?;
    let n = punch.sides();
    let circumradius = inradius / (PI / n as f64).cos();
    let mut polygon: Vec<Vector2<f64>> = (0..n)
        .map(|k| {
            let a = punch.face_azimuth(k) + PI / n as f64;
            let local = Vector3::new(circumradius * a.cos(), circumradius * a.sin(), above);
            let world = tip + punch_placement.vector_to_world(&local);
            let p = plate.to_local(&world);
            Vector2::new(p.x, p.y)
        })
        .collect();
    let area: f64 = (0..n)
        .map(|i| {
            let (a, b) = (polygon[i], polygon[(i + 1) % n]);
            a.x * b.y - a.y * b.x
        })
        .sum();
    if area < 0.0 {
        polygon.reverse();
    }
    Ok((polygon, corner + clearance))
}
