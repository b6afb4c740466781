//! Defect indicators of a formed ply, per element (`docs/cases.md`,
//! "Defect indicators"; `docs/forming.md`, "Wrinkles, gaps and waviness"):
//!
//! - **wrinkling**, primarily from the gap between the ply and the tool
//!   surface it lies on and the ply's principal curvatures (a ply off its
//!   tool *and* curved more than a bridging span is wrinkled; after Yu,
//!   Chen, Harper and Warrior, Compos. A 143, 2021);
//! - the membrane **tension-field** state from the principal membrane
//!   forces: taut (both > tolerance), wrinkled (only the larger), slack
//!   (neither). In-plane compaction across the rovings is a normal UD-NCF
//!   mode, so this state alone over-reports wrinkles and is reported
//!   beside the primary indicator, not as it;
//! - **fibre waviness** risk: a compressive line force along the rovings
//!   beyond a threshold (the roving strain itself, at `W4`'s 1000 MPa, is
//!   too small to read);
//! - **gapping**: the rovings move apart where `E⊥ = I11 − 1 > 0` (paper
//!   §3.2), the gap width estimated as `E⊥ × roving pitch` (not `E22`,
//!   positive in the ordinary roving slippage of mixed mode 2).
//!
//! Reads a state, changes nothing.

use nalgebra::{Matrix2, Vector2, Vector3};

use crate::material::MembraneMaterial;
use crate::model::MembraneModel;

/// The thresholds of the defect areas (`[defects]` of a forming case; the
/// reasons for the defaults are in `docs/cases.md`, "Defect indicators").
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct DefectThresholds {
    /// Gap to the tool above which a ply is off its tool \[mm\].
    pub tool_gap: f64,
    /// Largest principal curvature magnitude above which a ply off its tool
    /// is wrinkled rather than bridging \[1/mm\].
    pub curvature: f64,
    /// Principal membrane force below which a direction is slack \[N/mm\].
    pub slack_line_force: f64,
    /// Compressive line force along the rovings above which fibre waviness
    /// is a risk \[N/mm\].
    pub waviness_line_force: f64,
    /// Distance between neighbouring rovings \[mm\].
    pub roving_pitch: f64,
    /// Estimated gap width above which a ply is gapping \[mm\].
    pub gap_width: f64,
}

/// The default gap to the tool \[mm\] (two ply thicknesses of the paper's
/// 0.3 mm fabric: beyond the contact's penetration and the compaction
/// layer, a visible lift-off).
pub const DEFAULT_TOOL_GAP: f64 = 0.6;
/// The default curvature threshold \[1/mm\]: 1/(20 mm), above the curvature
/// of bridging spans and of the shipped punches (radius 50 mm, 0.02/mm)
/// and below that of a wrinkle of 1 mm amplitude over 25 mm
/// (`4π² A/λ² ≈ 0.063/mm`).
pub const DEFAULT_CURVATURE: f64 = 0.05;
/// The default slack line force \[N/mm\]: about twice the membrane force
/// the paper's ply's own weight causes over a 100 mm span
/// (`ρ t g L ≈ 4.4e-4 N/mm`).
pub const DEFAULT_SLACK_LINE_FORCE: f64 = 1.0e-3;
/// The default wavelength over which a compressed roving layer is taken
/// to buckle for the waviness threshold \[mm\] (about the stitch spacing
/// and roving pitch of a heavy-tow UD-NCF).
pub const DEFAULT_WAVINESS_WAVELENGTH: f64 = 10.0;
/// The default roving pitch \[mm\]: the paper's UD300 of 50K PX35 tows,
/// a tow's linear density (about 3.7 g/m) over the areal weight
/// (300 g/m²) is 12.3 mm.
pub const DEFAULT_ROVING_PITCH: f64 = 12.3;
/// The default gap width threshold \[mm\]: a choice, not a measured limit —
/// about one and a half ply thicknesses, from where a gap through the ply
/// shows as a resin channel in the part. Set it to the part's acceptance
/// limit.
pub const DEFAULT_GAP_WIDTH: f64 = 0.5;

/// The compressive line force along the rovings at which a layer of
/// bending stiffness `b11` \[N·mm\] buckles over `wavelength` \[mm\]
/// (Euler, both ends clamped: `4π² B₁₁ / λ²`) \[N/mm\]: the default
/// waviness threshold.
pub fn euler_line_force(b11: f64, wavelength: f64) -> f64 {
    4.0 * std::f64::consts::PI.powi(2) * b11 / (wavelength * wavelength)
}

/// The membrane tension-field state of an element.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TensionField {
    /// Both principal membrane forces above the slack force.
    Taut = 0,
    /// Only the larger one above it.
    Wrinkled = 1,
    /// Neither.
    Slack = 2,
}

/// The defect indicators of one element at one state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ElementDefects {
    /// Gap from the element (mean of its nodes) to the nearest tool that
    /// acts on the ply \[mm\]; `None` where no tool acts on it.
    pub tool_gap: Option<f64>,
    /// Principal curvatures `κ₁ ≥ κ₂` of the ply surface \[1/mm\], signed
    /// about the element's normal (node order).
    pub curvatures: [f64; 2],
    /// Principal membrane forces `n₁ ≥ n₂` (Cauchy stress times the
    /// thickness) \[N/mm\].
    pub line_forces: [f64; 2],
    /// Membrane force along the current rovings `a·n·a` \[N/mm\].
    pub fibre_line_force: f64,
    /// The tension-field state.
    pub tension_field: TensionField,
    /// Estimated gap width between rovings `max(E⊥, 0) × pitch` \[mm\].
    pub gap_width: f64,
    /// Off its tool and curved beyond the thresholds (or, on a ply no tool
    /// acts on, curved beyond the threshold).
    pub wrinkled: bool,
    /// Gap width at or above the threshold.
    pub gapping: bool,
    /// Compressive line force along the rovings at or above the threshold.
    pub waviness_risk: bool,
}

impl ElementDefects {
    /// The largest principal curvature magnitude \[1/mm\].
    pub fn max_curvature(&self) -> f64 {
        self.curvatures[0].abs().max(self.curvatures[1].abs())
    }

    /// One class for a map: 0 none, 1 wrinkled, 2 gapping, 3 waviness
    /// risk, the first that applies in that order.
    pub fn class(&self) -> u8 {
        if self.wrinkled {
            1
        } else if self.gapping {
            2
        } else if self.waviness_risk {
            3
        } else {
            0
        }
    }
}

/// The names of [`ElementDefects::class`]'s values.
pub const DEFECT_CLASSES: [&str; 4] = ["none", "wrinkled", "gapping", "waviness risk"];

/// The principal curvatures `κ₁ ≥ κ₂` \[1/mm\] of each triangle of a
/// surface given by `points` and `triangles`: a quadric
/// `z = c₀ + c₁x + c₂y + c₃x² + c₄xy + c₅y²` fitted by least squares, in
/// the triangle's own frame (origin at its centroid, `z` along its normal
/// of node order), to the nodes of every triangle that shares a node with
/// it (its one-ring), and the eigenvalues of the quadric's shape operator
/// at the centroid, `W = I⁻¹ II` (first and second fundamental forms).
/// A quadric fit is exact on quadratic surfaces, so the estimate is
/// consistent on irregular meshes (a per-triangle hinge or normal
/// difference estimate is not). Signed about the normal: a sphere of
/// radius `R` meshed with normals outward gives `−1/R` twice, a cylinder
/// `−1/R` and 0. Zero for a degenerate triangle or a one-ring too small to
/// fit (fewer than six nodes, or all on a line).
pub fn principal_curvatures(points: &[[f64; 3]], triangles: &[[usize; 3]]) -> Vec<[f64; 2]> {
    let p = |n: usize| Vector3::from(points[n]);
    let mut touching: Vec<Vec<usize>> = vec![Vec::new(); points.len()];
    for (f, t) in triangles.iter().enumerate() {
        for &n in t {
            if let Some(list) = touching.get_mut(n) {
                list.push(f);
            }
        }
    }
    triangles
        .iter()
        .map(|t| {
            let (x0, x1, x2) = (p(t[0]), p(t[1]), p(t[2]));
            let Some(n) = (x1 - x0).cross(&(x2 - x0)).try_normalize(0.0) else {
                return [0.0; 2];
            };
            let Some(e1) = (x1 - x0).try_normalize(0.0) else {
                return [0.0; 2];
            };
            let e2 = n.cross(&e1);
            let centre = (x0 + x1 + x2) / 3.0;
            let mut ring: Vec<usize> = t
                .iter()
                .flat_map(|&v| touching[v].iter().flat_map(|&f| triangles[f]))
                .collect();
            ring.sort_unstable();
            ring.dedup();
            if ring.len() < 6 {
                return [0.0; 2];
            }
            // Normal equations of the fit, scaled by the triangle's size so
            // that they stay well conditioned.
            let h = (x1 - x0).norm().max((x2 - x0).norm());
            let mut ata = nalgebra::Matrix6::<f64>::zeros();
            let mut atb = nalgebra::Vector6::<f64>::zeros();
            for &v in &ring {
                let d = (p(v) - centre) / h;
                let (x, y, z) = (d.dot(&e1), d.dot(&e2), d.dot(&n));
                let row = nalgebra::Vector6::new(1.0, x, y, x * x, x * y, y * y);
                ata += row * row.transpose();
                atb += row * z;
            }
            let Some(c) = ata.cholesky().map(|ch| ch.solve(&atb)) else {
                return [0.0; 2];
            };
            // Back to mm: z/h as a function of x/h.
            let (zx, zy) = (c[1], c[2]);
            let (zxx, zxy, zyy) = (2.0 * c[3] / h, c[4] / h, 2.0 * c[5] / h);
            let first = Matrix2::new(1.0 + zx * zx, zx * zy, zx * zy, 1.0 + zy * zy);
            let second = Matrix2::new(zxx, zxy, zxy, zyy) / (1.0 + zx * zx + zy * zy).sqrt();
            let Some(inverse) = first.try_inverse() else {
                return [0.0; 2];
            };
            let w = inverse * second;
            let (mean, det) = (0.5 * w.trace(), w.determinant());
            let root = (mean * mean - det).max(0.0).sqrt();
            let k = [mean + root, mean - root];
            if k.iter().all(|v| v.is_finite()) {
                k
            } else {
                [0.0; 2]
            }
        })
        .collect()
}

/// The membrane forces of element `e` of `model` at `u`: the principal
/// ones `n₁ ≥ n₂` and the one along the current rovings \[N/mm\], from the
/// second Piola–Kirchhoff stress `S` of the law: `n = t F S Fᵀ / J`, whose
/// principal values are `t eig(S C) / J` (`F S Fᵀ` and `S FᵀF` share their
/// eigenvalues), and `a·n·a = t (Fᵀa)·S(Fᵀa) / J`. `None` where the law
/// rejects the state or the element has collapsed.
pub fn membrane_line_forces(model: &MembraneModel, e: usize, u: &[f64]) -> Option<([f64; 2], f64)> {
    let reference = &model.references[e];
    let kin = reference.kinematics(&model.element_displacements(e, u));
    let [g1, g2] = kin.g;
    let j = g1.cross(&g2).norm();
    if !(j > 0.0 && j.is_finite()) {
        return None;
    }
    let state = model.material.stress(&kin.c, &reference.frame).ok()?;
    let s = state.stress;
    let s = Matrix2::new(s[0], s[2], s[2], s[1]);
    let c = Matrix2::new(kin.c[0], kin.c[2], kin.c[2], kin.c[1]);
    let sc = s * c;
    let scale = model.thickness / j;
    let (mean, det) = (0.5 * sc.trace(), sc.determinant());
    let root = (mean * mean - det).max(0.0).sqrt();
    let principal = [scale * (mean + root), scale * (mean - root)];
    let frame = &reference.frame;
    let a = (g1 * frame.a0.x + g2 * frame.a0.y).try_normalize(0.0)?;
    let fa = Vector2::new(g1.dot(&a), g2.dot(&a));
    let along = scale * fa.dot(&(s * fa));
    (principal.iter().all(|v| v.is_finite()) && along.is_finite()).then_some((principal, along))
}

/// The defect indicators of element `e` from its parts: the gap to the
/// tool (`None`: no tool acts on the ply), the principal curvatures, the
/// membrane forces ([`membrane_line_forces`]), `E⊥` and the thresholds.
pub fn element_defects(
    tool_gap: Option<f64>,
    curvatures: [f64; 2],
    (line_forces, fibre_line_force): ([f64; 2], f64),
    e_perp: f64,
    thresholds: &DefectThresholds,
) -> ElementDefects {
    let tension_field = if line_forces[1] > thresholds.slack_line_force {
        TensionField::Taut
    } else if line_forces[0] > thresholds.slack_line_force {
        TensionField::Wrinkled
    } else {
        TensionField::Slack
    };
    let gap_width = e_perp.max(0.0) * thresholds.roving_pitch;
    let curved = curvatures[0].abs().max(curvatures[1].abs()) > thresholds.curvature;
    let off_tool = tool_gap.is_none_or(|g| g > thresholds.tool_gap);
    ElementDefects {
        tool_gap,
        curvatures,
        line_forces,
        fibre_line_force,
        tension_field,
        gap_width,
        wrinkled: curved && off_tool,
        gapping: gap_width >= thresholds.gap_width,
        waviness_risk: -fibre_line_force >= thresholds.waviness_line_force,
    }
}

/// The areas of a ply above the thresholds at one state \[mm², current
/// area\] (`summary.json` `defects`).
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct DefectAreas {
    /// Off its tool and curved beyond the thresholds (the primary wrinkle
    /// indicator).
    pub wrinkled_area: f64,
    /// Off its tool by more than the gap threshold (wrinkled or bridging).
    pub off_tool_area: f64,
    /// Curved beyond the curvature threshold.
    pub curved_area: f64,
    /// Tension-field state "wrinkled" (one principal membrane force only
    /// above the slack force: includes in-plane compaction).
    pub tension_wrinkled_area: f64,
    /// Tension-field state "slack".
    pub slack_area: f64,
    /// Estimated gap between rovings at or above the gap-width threshold.
    pub gapping_area: f64,
    /// Compressive line force along the rovings at or above the threshold.
    pub waviness_risk_area: f64,
    /// The largest estimated gap width \[mm\].
    pub max_gap_width: f64,
    /// The largest gap to the tool \[mm\] (0 without a tool).
    pub max_tool_gap: f64,
    /// The ply's current area \[mm²\].
    pub area: f64,
}

/// The areas of `defects` weighted by the elements' current `areas`
/// \[mm²\], against `thresholds`.
pub fn defect_areas(
    defects: &[ElementDefects],
    areas: &[f64],
    thresholds: &DefectThresholds,
) -> DefectAreas {
    let mut sums = DefectAreas::default();
    for (d, &a) in defects.iter().zip(areas) {
        sums.area += a;
        let gap = d.tool_gap.unwrap_or(0.0);
        let add = |on: bool, to: &mut f64| {
            if on {
                *to += a;
            }
        };
        add(d.wrinkled, &mut sums.wrinkled_area);
        add(gap > thresholds.tool_gap, &mut sums.off_tool_area);
        add(
            d.max_curvature() > thresholds.curvature,
            &mut sums.curved_area,
        );
        add(
            d.tension_field == TensionField::Wrinkled,
            &mut sums.tension_wrinkled_area,
        );
        add(d.tension_field == TensionField::Slack, &mut sums.slack_area);
        add(d.gapping, &mut sums.gapping_area);
        add(d.waviness_risk, &mut sums.waviness_risk_area);
        sums.max_gap_width = sums.max_gap_width.max(d.gap_width);
        sums.max_tool_gap = sums.max_tool_gap.max(gap);
    }
    sums
}
