//! Triangle meshes of the analytic tools for visualisation (written to
//! ParaView next to the ply): each shape draws the part of itself within an
//! extent it takes as parameters, in its local frame, with every triangle's
//! right-hand-rule normal pointing to the free side (where the ply is). See
//! `docs/tools.md` §5.
//!
//! The surfaces of revolution are drawn by revolving a polyline profile in
//! the meridian plane: with the profile run so that the free side is on its
//! left (the profile's tangent turned +90° in the `(ρ, z)` plane), the
//! triangles `(p_k(φ_j), p_{k+1}(φ_j), p_{k+1}(φ_{j+1}))` and
//! `(p_k(φ_j), p_{k+1}(φ_{j+1}), p_k(φ_{j+1}))` have normals
//! `∝ t_s × e_φ = −t_z e_ρ + t_ρ e_z`, that left normal.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use nalgebra::{Vector2, Vector3};

use super::surface::{
    Cylinder, Placement, Plane, PlateWithHole, ShapeError, Side, Sphere, Torus,
    non_negative_finite, positive_finite,
};

/// A triangle mesh of a tool surface: vertex positions \[mm\] and
/// counter-clockwise vertex triples (normal towards the free side).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tessellation {
    /// Vertex positions \[mm\].
    pub vertices: Vec<Vector3<f64>>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[usize; 3]>,
}

impl Tessellation {
    /// The same mesh with every vertex mapped by
    /// [`Placement::to_world`] (a rotation keeps the orientation).
    pub fn to_world(&self, placement: &Placement) -> Self {
        Self {
            vertices: self
                .vertices
                .iter()
                .map(|v| placement.to_world(v))
                .collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// The mesh with every triangle's orientation reversed.
    fn flipped(mut self) -> Self {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
        self
    }
}

/// Smallest number of segments around a circle: a triangle.
const MIN_SEGMENTS: usize = 3;

fn check_segments(shape: &'static str, segments: usize) -> Result<usize, ShapeError> {
    if segments >= MIN_SEGMENTS {
        Ok(segments)
    } else {
        Err(ShapeError::Parameter {
            shape,
            parameter: "segments",
            value: segments as f64,
            expected: format!("at least {MIN_SEGMENTS} segments around a circle"),
        })
    }
}

/// Divisions of a straight profile piece of `length` so that its pieces
/// are no longer than `step` (at least one, at most
/// [`MAX_PROFILE_DIVISIONS`]: the tessellation only draws the tool, and a
/// slender one — a 10⁻³⁰ mm radius, say — must not ask for more pieces
/// than memory holds).
pub(crate) fn divisions(length: f64, step: f64) -> usize {
    let pieces = (length / step).ceil();
    if pieces.is_nan() {
        1
    } else {
        (pieces as usize).clamp(1, MAX_PROFILE_DIVISIONS)
    }
}

/// Most pieces of one straight profile piece of a drawn tool.
pub const MAX_PROFILE_DIVISIONS: usize = 1000;

/// The profile `(w, z)` of a plate's working surface across the edge of
/// its opening, `w` measured outwards from the opening's axis (a round
/// plate) or edge (a polygonal one), free side on the left: the wall at
/// `w = r_o` from `z = −r_f − wall_length` up to `z = −r_f` in `wall.1`
/// pieces (none without a wall), the fillet of radius `r_f` about
/// `(r_o + r_f, −r_f)` from angle π to π/2 in `arc` pieces (its ends
/// exact), and the face `z = 0` out to `w = r_o + r_f + face.0` in `face.1`
/// pieces. `radii = (r_o, r_f)`.
pub(crate) fn plate_profile(
    radii: (f64, f64),
    wall: (f64, usize),
    arc: usize,
    face: (f64, usize),
) -> Vec<Vector2<f64>> {
    let (ro, rf) = radii;
    let mut profile = Vec::new();
    if wall.0 > 0.0 {
        let n = wall.1;
        for k in 0..n {
            profile.push(Vector2::new(ro, -rf - wall.0 * (n - k) as f64 / n as f64));
        }
    }
    for k in 0..=arc {
        let a = if arc == 0 {
            PI
        } else {
            PI - FRAC_PI_2 * k as f64 / arc as f64
        };
        profile.push(if k == arc {
            Vector2::new(ro + rf, 0.0)
        } else if k == 0 {
            Vector2::new(ro, -rf)
        } else {
            Vector2::new(ro + rf + rf * a.cos(), -rf + rf * a.sin())
        });
    }
    let n = face.1;
    for k in 1..=n {
        profile.push(Vector2::new(ro + rf + face.0 * k as f64 / n as f64, 0.0));
    }
    profile
}

/// Revolves the meridian profile `(ρ, z)` (free side on its left; a point
/// with `ρ == 0` becomes one pole vertex) into `segments` sectors about the
/// z axis; a `closed` profile joins its last point to its first.
fn revolve_profile(profile: &[Vector2<f64>], closed: bool, segments: usize) -> Tessellation {
    let mut mesh = Tessellation::default();
    // Index of each profile point's first vertex and whether it is a pole.
    let mut rings = Vec::with_capacity(profile.len());
    for p in profile {
        let start = mesh.vertices.len();
        if p.x == 0.0 {
            mesh.vertices.push(Vector3::new(0.0, 0.0, p.y));
            rings.push((start, true));
        } else {
            for j in 0..segments {
                let phi = TAU * j as f64 / segments as f64;
                mesh.vertices
                    .push(Vector3::new(p.x * phi.cos(), p.x * phi.sin(), p.y));
            }
            rings.push((start, false));
        }
    }
    let vertex = |(start, pole): (usize, bool), j: usize| {
        if pole { start } else { start + j % segments }
    };
    let pieces = if closed {
        profile.len()
    } else {
        profile.len().saturating_sub(1)
    };
    for k in 0..pieces {
        let (lower, upper) = (rings[k], rings[(k + 1) % profile.len()]);
        for j in 0..segments {
            let a = vertex(lower, j);
            let d = vertex(lower, j + 1);
            let b = vertex(upper, j);
            let c = vertex(upper, j + 1);
            if !lower.1 && !upper.1 {
                mesh.triangles.push([a, b, c]);
                mesh.triangles.push([a, c, d]);
            } else if lower.1 && !upper.1 {
                mesh.triangles.push([a, b, c]);
            } else if !lower.1 && upper.1 {
                mesh.triangles.push([a, b, d]);
            }
        }
    }
    mesh
}

impl Plane {
    /// The square `|x|, |y| ≤ half_size` \[mm\] of the plane, cut into
    /// `divisions × divisions` cells of two triangles each, normal `+z`.
    ///
    /// # Errors
    /// A half-size that is not positive and finite, zero divisions.
    pub fn tessellate(&self, half_size: f64, divisions: usize) -> Result<Tessellation, ShapeError> {
        let half_size = positive_finite("plane tessellation", "half_size", half_size)?;
        if divisions == 0 {
            return Err(ShapeError::Parameter {
                shape: "plane tessellation",
                parameter: "divisions",
                value: 0.0,
                expected: "at least 1 division per side".into(),
            });
        }
        let n = divisions;
        let step = 2.0 * half_size / n as f64;
        let mut mesh = Tessellation::default();
        for j in 0..=n {
            for i in 0..=n {
                mesh.vertices.push(Vector3::new(
                    -half_size + i as f64 * step,
                    -half_size + j as f64 * step,
                    0.0,
                ));
            }
        }
        let id = |i: usize, j: usize| i + j * (n + 1);
        for j in 0..n {
            for i in 0..n {
                mesh.triangles
                    .push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
                mesh.triangles
                    .push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
            }
        }
        Ok(mesh)
    }
}

impl Sphere {
    /// The cap of the sphere from its top `(0, 0, R)` down to the polar
    /// angle `polar_angle` from `+z` (`π/2` a hemisphere `z ≥ 0`, `π` the
    /// whole sphere), `segments` around, as many rings as keep the cells
    /// about square.
    ///
    /// # Errors
    /// A polar angle outside `(0, π]`, fewer than 3 segments.
    pub fn tessellate(
        &self,
        polar_angle: f64,
        segments: usize,
    ) -> Result<Tessellation, ShapeError> {
        if !(polar_angle > 0.0 && polar_angle <= PI) {
            return Err(ShapeError::Parameter {
                shape: "sphere tessellation",
                parameter: "polar_angle",
                value: polar_angle,
                expected: "an angle in (0, π] [rad] from the +z pole".into(),
            });
        }
        let segments = check_segments("sphere tessellation", segments)?;
        let rings = divisions(polar_angle, TAU / segments as f64);
        let r = self.radius();
        let profile: Vec<Vector2<f64>> = (0..=rings)
            .map(|k| {
                let theta = polar_angle * k as f64 / rings as f64;
                if k == 0 {
                    Vector2::new(0.0, r)
                } else if k == rings && polar_angle == PI {
                    Vector2::new(0.0, -r)
                } else {
                    Vector2::new(r * theta.sin(), r * theta.cos())
                }
            })
            .collect();
        let mesh = revolve_profile(&profile, false, segments);
        Ok(match self.side() {
            Side::Outside => mesh,
            Side::Inside => mesh.flipped(),
        })
    }
}

impl Cylinder {
    /// The cylinder between `z_min` and `z_max` \[mm\], `segments` around,
    /// as many rows as keep the cells about square.
    ///
    /// # Errors
    /// Non-finite bounds, `z_min ≥ z_max`, fewer than 3 segments.
    pub fn tessellate(
        &self,
        z_min: f64,
        z_max: f64,
        segments: usize,
    ) -> Result<Tessellation, ShapeError> {
        if !(z_min.is_finite() && z_max.is_finite() && z_min < z_max) {
            return Err(ShapeError::Parameter {
                shape: "cylinder tessellation",
                parameter: "z_max",
                value: z_max,
                expected: format!(
                    "a finite bound above z_min = {} mm",
                    crate::config::readable_number(z_min)
                ),
            });
        }
        let segments = check_segments("cylinder tessellation", segments)?;
        let r = self.radius();
        let rows = divisions(z_max - z_min, TAU * r / segments as f64);
        // Free side outside: run down the wall (left normal +e_ρ).
        let profile: Vec<Vector2<f64>> = (0..=rows)
            .map(|k| Vector2::new(r, z_max - (z_max - z_min) * k as f64 / rows as f64))
            .collect();
        let mesh = revolve_profile(&profile, false, segments);
        Ok(match self.side() {
            Side::Outside => mesh,
            Side::Inside => mesh.flipped(),
        })
    }
}

impl Torus {
    /// The whole torus, `segments` around the axis and around the tube.
    ///
    /// # Errors
    /// Fewer than 3 segments.
    pub fn tessellate(&self, segments: usize) -> Result<Tessellation, ShapeError> {
        let segments = check_segments("torus tessellation", segments)?;
        let (big, small) = (self.major_radius(), self.minor_radius());
        // Clockwise about the tube's centre: the left normal points out of
        // the tube.
        let profile: Vec<Vector2<f64>> = (0..segments)
            .map(|k| {
                let t = TAU * k as f64 / segments as f64;
                Vector2::new(big + small * t.cos(), -small * t.sin())
            })
            .collect();
        let mesh = revolve_profile(&profile, true, segments);
        Ok(match self.side() {
            Side::Outside => mesh,
            Side::Inside => mesh.flipped(),
        })
    }
}

impl PlateWithHole {
    /// The working surface: the wall of the opening from
    /// `z = −r_f − wall_length` up to `z = −r_f`, the fillet, and the face
    /// as an annulus out to `outer_radius` \[mm\]; `segments` around and
    /// `⌈segments/4⌉` pieces along the quarter-circle fillet (one point when
    /// `r_f = 0`).
    ///
    /// # Errors
    /// An outer radius not beyond the fillet (`> R_o + r_f`) or not finite,
    /// a negative or non-finite wall length, fewer than 3 segments.
    pub fn tessellate(
        &self,
        outer_radius: f64,
        wall_length: f64,
        segments: usize,
    ) -> Result<Tessellation, ShapeError> {
        let (ro, rf) = (self.opening_radius(), self.fillet_radius());
        if !(outer_radius.is_finite() && outer_radius > ro + rf) {
            return Err(ShapeError::Parameter {
                shape: "plate with hole tessellation",
                parameter: "outer_radius",
                value: outer_radius,
                expected: format!(
                    "a finite radius beyond the fillet, R_o + r_f = {} mm",
                    crate::config::readable_number(ro + rf)
                ),
            });
        }
        let wall_length =
            non_negative_finite("plate with hole tessellation", "wall_length", wall_length)?;
        let segments = check_segments("plate with hole tessellation", segments)?;
        let step = TAU * ro / segments as f64;
        let face = outer_radius - ro - rf;
        let profile = plate_profile(
            (ro, rf),
            (wall_length, divisions(wall_length, step)),
            if rf > 0.0 { segments.div_ceil(4) } else { 0 },
            (face, divisions(face, step)),
        );
        Ok(revolve_profile(&profile, false, segments))
    }
}
