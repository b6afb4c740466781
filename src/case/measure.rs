//! What is measured on a state of a built forming model, defined once for
//! every report (`docs/cases.md`, "Forming outputs"): each tool's
//! displacement and force, each boundary's reaction, each probe's mean
//! displacement, the stroke and the floating tools' lift. Each is read
//! from a solver [`Snapshot`]: the displacement `u` and the residual
//! `f_int − f_ext` of every dof (the reaction at a constrained one).

use serde::Serialize;

use super::forming::{FormingCase, ToolMotion};
use super::forming_model::FormingModel;
use crate::solver::Snapshot;

/// One tool's state.
#[derive(Debug, Clone, Serialize)]
pub struct ToolRow {
    /// Displacement along its direction \[mm\].
    pub displacement: f64,
    /// Force of the plies on it along its direction, the force that
    /// drives or holds it (positive when the plies resist its motion) \[N\].
    pub force: f64,
}

impl FormingModel {
    /// The stroke tool: the prescribed tool that moves farthest (the first
    /// of equals), whose displacement is the stroke; `None` when no tool
    /// is prescribed.
    pub fn stroke_tool(&self) -> Option<usize> {
        self.tools
            .iter()
            .enumerate()
            .filter_map(|(i, t)| match t.spec.motion {
                ToolMotion::Prescribed { displacement, .. } => Some((i, displacement.abs())),
                _ => None,
            })
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map(|(i, _)| i)
    }

    /// The floating tools, whose lift is reported.
    pub fn floating_tools(&self) -> Vec<usize> {
        self.tools
            .iter()
            .enumerate()
            .filter(|(_, t)| matches!(t.spec.motion, ToolMotion::Floating { .. }))
            .map(|(i, _)| i)
            .collect()
    }

    /// The stroke at load `load` and displacement `u`: the stroke tool's
    /// displacement \[mm\], or the programme fraction `λ` without one.
    pub fn stroke(&self, load: f64, u: &[f64]) -> f64 {
        self.stroke_tool().map_or(load, |t| u[self.tools[t].dof])
    }

    /// Each floating tool's lift: its displacement against its direction
    /// \[mm\], in the order of [`FormingModel::floating_tools`].
    pub fn lifts(&self, u: &[f64]) -> Vec<f64> {
        self.floating_tools()
            .iter()
            .map(|&t| -u[self.tools[t].dof])
            .collect()
    }

    /// Each tool's displacement and force at `snapshot`. The residual of a
    /// floating tool's dof is its contact force less its weight: the
    /// weight is added back, so that its force is what the plies bear.
    pub fn tool_rows(&self, snapshot: &Snapshot) -> Vec<ToolRow> {
        self.tools
            .iter()
            .map(|t| {
                let mut force = snapshot.residual[t.dof];
                if let ToolMotion::Floating { weight, .. } = t.spec.motion {
                    force += weight;
                }
                ToolRow {
                    displacement: snapshot.u[t.dof],
                    force,
                }
            })
            .collect()
    }

    /// Per boundary condition of `case`, the total reaction force \[N\]:
    /// the residual summed over its nodes' fixed components.
    pub fn reactions(&self, case: &FormingCase, snapshot: &Snapshot) -> Vec<[f64; 3]> {
        case.boundaries
            .iter()
            .zip(&self.boundary_nodes)
            .map(|(b, nodes)| {
                let mut r = [0.0; 3];
                for &n in nodes {
                    for (k, rk) in r.iter_mut().enumerate() {
                        if b.fixed[k] {
                            *rk += snapshot.residual[3 * n + k];
                        }
                    }
                }
                r
            })
            .collect()
    }

    /// Per probe, the mean displacement of its nodes \[mm\].
    pub fn probe_means(&self, u: &[f64]) -> Vec<[f64; 3]> {
        self.probe_nodes
            .iter()
            .map(|nodes| {
                let mut mean = [0.0; 3];
                for &n in nodes {
                    for (k, m) in mean.iter_mut().enumerate() {
                        *m += u[3 * n + k];
                    }
                }
                mean.map(|m| m / nodes.len().max(1) as f64)
            })
            .collect()
    }
}
