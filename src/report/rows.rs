//! The rows the runner hands to every report: what is measured on a
//! recorded state. An OAT's row holds the clamp displacement and force and
//! the MDZ means; a forming run's the tools' displacements and forces, the
//! boundaries' reactions, the probes, the stroke, the lifts, the draw-in
//! and the zone means (`docs/cases.md`, "Outputs", "Forming outputs").

use serde::Serialize;

use super::forming::readout::{Readout, ZoneValue};
use crate::case::forming::FormingCase;
use crate::case::forming_model::FormingModel;
pub use crate::case::measure::ToolRow;
use crate::solver::Snapshot;

/// Displacements whose forces the summary always reports \[mm\].
pub const REPORTED_DISPLACEMENTS: [f64; 4] = [20.0, 40.0, 60.0, 80.0];

/// One row of the history: a converged step with its MDZ averages.
#[derive(Debug, Clone, Serialize)]
pub struct HistoryRow {
    /// Clamp displacement \[mm\].
    pub displacement: f64,
    /// Clamp force \[N\].
    pub force: f64,
    /// MDZ mean of E22.
    pub mdz_e22: f64,
    /// MDZ mean of γ \[deg\].
    pub mdz_shear_angle_deg: f64,
    /// MDZ mean of E⊥.
    pub mdz_e_perp: f64,
    /// Newton iterations of the step (quasi-static).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// Time \[s\] (explicit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
    /// Time increments so far (explicit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub increments: Option<usize>,
}

/// One row of the history.
#[derive(Debug, Clone, Serialize)]
pub struct FormingRow {
    /// Programme fraction `λ`.
    pub load: f64,
    /// Time \[s\] (explicit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time: Option<f64>,
    /// Per tool.
    pub tools: Vec<ToolRow>,
    /// Per boundary condition: the total reaction force \[N\].
    pub reactions: Vec<[f64; 3]>,
    /// Per probe: the mean displacement of its nodes \[mm\].
    pub probes: Vec<[f64; 3]>,
    /// Newton iterations of the step (quasi-static).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub iterations: Option<usize>,
    /// Newton solves beyond the first (contact augmentations).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub augmentations: Option<usize>,
    /// Largest penetration after the step's last augmentation \[mm\].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub max_penetration: Option<f64>,
    /// Relative change of the contact multipliers in the last augmentation.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub multiplier_change: Option<f64>,
    /// Closed contacts (node–tool pairs), of which slipping.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contacts: Option<(usize, usize)>,
    /// Final residual norm of the step \[N\] (quasi-static).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub residual: Option<f64>,
    /// Time increments so far (explicit).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub increments: Option<usize>,
    /// The stroke \[mm\]: the displacement of the prescribed tool that
    /// moves farthest (`λ` without one).
    pub stroke: f64,
    /// Per floating tool, its lift: displacement against its direction \[mm\].
    pub lifts: Vec<f64>,
    /// Per ply, the draw-in at its edge midpoints and corners \[mm\]
    /// (`forming.draw_in_points` names them).
    pub draw_in: Vec<Vec<f64>>,
    /// Per zone of the case, the means over it.
    pub zones: Vec<ZoneValue>,
    /// Strain energy of the plies \[N·mm\] (quasi-static).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub internal_energy: Option<f64>,
    /// Energy dissipated by the viscous stabilisation and the inertia's
    /// backward Euler so far \[N·mm\] (quasi-static, `docs/solver.md`,
    /// "Stabilisation", "Inertia").
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stabilisation_energy: Option<f64>,
    /// Kinetic energy of the free dofs \[N·mm\] (quasi-static with
    /// `inertia_duration`; 0 without inertia).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub kinetic_energy: Option<f64>,
}

/// A history row at `load` from the state `snapshot`: what the built
/// model measures ([`crate::case::measure`]) and what is read on the
/// blanks; the solver-specific columns are left empty.
pub fn forming_row(
    case: &FormingCase,
    built: &FormingModel,
    readout: &Readout,
    load: f64,
    snapshot: &Snapshot,
) -> FormingRow {
    FormingRow {
        load,
        time: None,
        tools: built.tool_rows(snapshot),
        reactions: built.reactions(case, snapshot),
        probes: built.probe_means(snapshot.u),
        iterations: None,
        augmentations: None,
        max_penetration: None,
        multiplier_change: None,
        contacts: None,
        residual: None,
        increments: None,
        stroke: built.stroke(load, snapshot.u),
        lifts: built.lifts(snapshot.u),
        draw_in: readout.draw_in(snapshot.u),
        zones: readout.zones(case, built, snapshot.u),
        internal_energy: None,
        stabilisation_energy: None,
        kinetic_energy: None,
    }
}

impl FormingRow {
    /// The force of the stroke tool (of the first tool without one), for
    /// the progress line \[N\].
    pub fn stroke_force(&self, readout: &Readout) -> f64 {
        readout
            .stroke_tool
            .or((!self.tools.is_empty()).then_some(0))
            .map_or(0.0, |t| self.tools[t].force)
    }
}
