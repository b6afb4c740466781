//! Where the fibres of a formed ply point, per element (`docs/cases.md`,
//! "Orientation fields"; `docs/export.md`): the reference roving and
//! stitching directions `a₀`, `b₀`, the current ones
//! `a = F a₀ / |F a₀|` and `b = F b₀ / |F b₀|` (the fibres follow the
//! material, paper Eq. 3–7), the fibre angle in a design rosette and its
//! deviation from the ply's design angle, and the areal mass and thickness
//! that follow from the area change `J` (the same fibres over `J` times
//! the area). Reads a state, changes nothing.

use nalgebra::Vector3;

use crate::model::MembraneModel;

/// How a rosette's reference direction is laid on an element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RosetteRule {
    /// The rosette's direction projected onto the element's plane (the
    /// default of Abaqus' shells and of draping tools).
    Projected,
    /// The direction from the rosette's origin to the element's centroid,
    /// projected onto the element's plane (a polar rosette: meridians of a
    /// dome).
    Radial,
}

/// A design rosette: the reference from which fibre angles are measured,
/// about each element's current normal (node order).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Rosette {
    /// Origin \[mm\] (used by [`RosetteRule::Radial`]).
    pub origin: [f64; 3],
    /// Unit reference direction.
    pub direction: [f64; 3],
    /// How the reference is laid on an element.
    pub rule: RosetteRule,
    /// Unit direction used where the reference is within
    /// [`ROSETTE_DEGENERATE_DEG`] of the element's normal (or, radially,
    /// where the element's centroid is at the origin).
    pub fallback: [f64; 3],
}

impl Default for Rosette {
    /// The global x axis projected, falling back to the global z axis: on
    /// a flat blank in the xy-plane the angle is the case's
    /// `fibre_angle_deg`.
    fn default() -> Self {
        Self {
            origin: [0.0; 3],
            direction: [1.0, 0.0, 0.0],
            rule: RosetteRule::Projected,
            fallback: [0.0, 0.0, 1.0],
        }
    }
}

/// A reference direction closer than this to the element's normal \[deg\]
/// is degenerate and the fallback is used: 0.1°, Abaqus' rule for the
/// projected local axes of shells.
pub const ROSETTE_DEGENERATE_DEG: f64 = 0.1;

/// Which reference a fibre angle was measured from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RosetteUse {
    /// The rosette's direction (or the radial one).
    Direction = 0,
    /// Its fallback.
    Fallback = 1,
    /// Both degenerate: the angle is written as 0.
    Degenerate = 2,
}

/// The orientation fields of one element at one state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementOrientation {
    /// Unit reference roving direction `a₀` (global axes).
    pub a0: [f64; 3],
    /// Unit reference stitching direction `b₀` (global axes).
    pub b0: [f64; 3],
    /// Unit current roving direction `a = F a₀ / |F a₀|`.
    pub a: [f64; 3],
    /// Unit current stitching direction `b = F b₀ / |F b₀|`.
    pub b: [f64; 3],
    /// Unit current normal of the element (node order).
    pub normal: [f64; 3],
    /// The angle from the rosette's reference to `a` about `normal`,
    /// reduced to (−90°, 90°] (a fibre is a line) \[deg\].
    pub fibre_angle_deg: f64,
    /// `fibre_angle_deg` less the ply's design angle, reduced to
    /// (−90°, 90°] \[deg\].
    pub fibre_angle_deviation_deg: f64,
    /// Which reference was used.
    pub rosette: RosetteUse,
    /// Area ratio `J = |g₁ × g₂|` (current over reference area).
    pub area_ratio: f64,
}

/// An angle reduced to (−90°, 90°] \[deg\]: the angle of a line.
pub fn line_angle_deg(angle: f64) -> f64 {
    let r = angle.rem_euclid(180.0);
    if r > 90.0 { r - 180.0 } else { r }
}

/// The orientation fields of every element of `model` at displacement `u`
/// (all dofs), measured in `rosette` against the design angle
/// `design_angle_deg`. `None` for an element whose current area vanishes
/// (its directions are not defined).
pub fn element_orientations(
    model: &MembraneModel,
    u: &[f64],
    rosette: &Rosette,
    design_angle_deg: f64,
) -> Vec<Option<ElementOrientation>> {
    (0..model.triangles.len())
        .map(|e| {
            let reference = &model.references[e];
            let [g1, g2] = reference.deformation(&model.element_displacements(e, u));
            let frame = &reference.frame;
            let global = |v: nalgebra::Vector2<f64>| reference.e1 * v.x + reference.e2 * v.y;
            let (a0, b0) = (global(frame.a0), global(frame.b0));
            let a = (g1 * frame.a0.x + g2 * frame.a0.y).try_normalize(0.0)?;
            let b = (g1 * frame.b0.x + g2 * frame.b0.y).try_normalize(0.0)?;
            let area = g1.cross(&g2);
            let area_ratio = area.norm();
            let normal = area.try_normalize(0.0)?;
            let t = model.triangles[e];
            let centroid = (0..3)
                .map(|k| {
                    let n = t[k];
                    model.nodes[n] + Vector3::new(u[3 * n], u[3 * n + 1], u[3 * n + 2])
                })
                .sum::<Vector3<f64>>()
                / 3.0;
            let (angle, used) = rosette_angle(rosette, &centroid, &normal, &a);
            let all_finite = [a0, b0, a, b, normal]
                .iter()
                .all(|v| v.iter().all(|c| c.is_finite()))
                && angle.is_finite()
                && area_ratio.is_finite();
            all_finite.then(|| ElementOrientation {
                a0: a0.into(),
                b0: b0.into(),
                a: a.into(),
                b: b.into(),
                normal: normal.into(),
                fibre_angle_deg: angle,
                fibre_angle_deviation_deg: line_angle_deg(angle - design_angle_deg),
                rosette: used,
                area_ratio,
            })
        })
        .collect()
}

/// The angle of the fibre `a` from the rosette's reference on an element
/// of unit normal `normal` and centroid `centroid`, about the normal,
/// reduced to (−90°, 90°], and which reference was used.
pub fn rosette_angle(
    rosette: &Rosette,
    centroid: &Vector3<f64>,
    normal: &Vector3<f64>,
    a: &Vector3<f64>,
) -> (f64, RosetteUse) {
    let min_sin = ROSETTE_DEGENERATE_DEG.to_radians().sin();
    let project = |d: Vector3<f64>| {
        let len = d.norm();
        let p = d - normal * normal.dot(&d);
        (len > 0.0 && p.norm() > min_sin * len).then(|| p.normalize())
    };
    let direction = match rosette.rule {
        RosetteRule::Projected => Vector3::from(rosette.direction),
        RosetteRule::Radial => centroid - Vector3::from(rosette.origin),
    };
    let (reference, used) = match project(direction) {
        Some(r) => (r, RosetteUse::Direction),
        None => match project(Vector3::from(rosette.fallback)) {
            Some(r) => (r, RosetteUse::Fallback),
            None => return (0.0, RosetteUse::Degenerate),
        },
    };
    let angle = reference
        .cross(a)
        .dot(normal)
        .atan2(reference.dot(a))
        .to_degrees();
    (line_angle_deg(angle), used)
}
