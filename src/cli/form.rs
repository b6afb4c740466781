//! `ncform run CASE` for a forming case: builds the plies, tools and loads,
//! runs the quasi-static or the explicit solver over the load programme
//! and writes what a user looks at (`docs/cases.md`, "Forming outputs"):
//!
//! - `history.csv` / `reactions.png`: every tool's displacement and force,
//!   every boundary's reaction, per converged step (quasi-static) or
//!   history row (explicit), with the contact figures of each step;
//! - `vtu/*.vtu` and `forming.pvd`: every ply with its strain, invariant,
//!   stress, curvature and contact fields, and every tool, at the output
//!   states, for ParaView;
//! - `energy.csv` / `energy.png` (explicit): internal, contact, kinetic,
//!   external work (motions and loads), damping, friction, balance;
//! - `summary.json`: status, forces at the outputs, contact and energy
//!   figures, work done, time split.
//!
//! A solve that fails keeps everything up to the last converged step (or
//! output) and marks it incomplete.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::blank::{
    BlankRow, DicColumns, OutlineState, Readout, ZoneValue, dic_measures, write_forming_history,
    write_maps, write_outer_contours,
};
use super::io_err;
use super::run::Progress;
use super::run_folder::{ExitStatus, MissingOutput, Outputs, RunFolder};
use crate::case::SolverKind;
use crate::case::forming::{FormingCase, ToolMotion};
use crate::case::forming_model::FormingModel;
use crate::post::csv::write_csv;
use crate::post::fields::{FieldColumns, element_fields};
use crate::post::plot::{Panel, Series, write_panels};
use crate::post::vtu::{Field, FieldData, PvdEntry, VtuPiece, write_pvd, write_vtu};
use crate::solver::explicit::{Energies, ExplicitTimings, MassSummary};
use crate::solver::newton::solve_quasi_static;
use crate::solver::{
    CancelToken, DofMap, ExplicitRecord, ExplicitState, RunStatus, Snapshot, SolverTimings,
    solve_explicit,
};

const UNITS: &str = "mm, N, MPa, tonne/mm^3, s; angles in degrees";

/// One tool's state in a history row.
#[derive(Debug, Clone, Serialize)]
pub struct ToolRow {
    /// Displacement along its direction \[mm\].
    pub displacement: f64,
    /// Force of the plies on it along its direction, the force that
    /// drives or holds it (positive when the plies resist its motion) \[N\].
    pub force: f64,
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

/// The JSON summary of a forming run.
#[derive(Debug, Clone, Serialize)]
pub struct FormingSummary {
    /// Case file.
    pub case: String,
    /// Title.
    pub title: String,
    /// `true` when the programme's end was reached.
    pub complete: bool,
    /// Completion (reason when incomplete, load reached when interrupted).
    pub status: RunStatus,
    /// The outputs written before this summary that could not be written
    /// (`status.json` has the final list).
    pub outputs_missing: Vec<MissingOutput>,
    /// How the command ends (`docs/cases.md`, "Exit codes").
    pub exit_status: ExitStatus,
    /// The solver.
    pub solver: SolverKind,
    /// Units of every number here.
    pub units: &'static str,
    /// Plies: name, nodes, triangles.
    pub plies: Vec<PlySummary>,
    /// Tools: name and how they move.
    pub tools: Vec<String>,
    /// Free unknowns.
    pub unknowns: usize,
    /// Tangent non-zeros (quasi-static).
    pub nonzeros: usize,
    /// Converged steps (quasi-static) or history rows (explicit).
    pub steps: usize,
    /// Newton iterations (all attempts).
    pub newton_iterations: usize,
    /// Newton solves beyond the first per step, summed (augmentations).
    pub augmentations: usize,
    /// The explicit run's figures.
    pub explicit: Option<ExplicitFigures>,
    /// Time split of the solve \[s\].
    pub timings: Timings,
    /// Each term's wall time \[s\]: of the assembly (quasi-static) or of the
    /// element passes (explicit).
    pub term_seconds: Vec<(String, f64)>,
    /// Quasi-static: strain energy at the end, energy dissipated by the
    /// stabilisation and its largest ratio to the strain energy \[N·mm, -\].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stabilisation: Option<(f64, f64, f64)>,
    /// Time writing outputs \[s\].
    pub output_seconds: f64,
    /// Wall time of the whole run \[s\].
    pub wall_seconds: f64,
    /// What is read on the blanks.
    pub forming: FormingFigures,
    /// The history.
    pub history: Vec<FormingRow>,
}

/// What is read on the blanks, at the output states (`docs/forming.md`).
#[derive(Debug, Clone, Serialize)]
pub struct FormingFigures {
    /// The tool whose displacement is the stroke.
    pub stroke_tool: Option<String>,
    /// The floating tools whose lift is reported.
    pub floating_tools: Vec<String>,
    /// Per ply, its draw-in points: name and reference position \[mm\].
    pub draw_in_points: Vec<Vec<(String, [f64; 2])>>,
    /// The zones: name, ply, centre and size \[mm\].
    pub zones: Vec<(String, String, [f64; 2], [f64; 2])>,
    /// The history rows at the output states.
    pub states: Vec<FormingRow>,
    /// Per output state and ply, the area of each deformation mode.
    pub deformation_modes: Vec<ModeAreas>,
}

/// A ply's size.
#[derive(Debug, Clone, Serialize)]
pub struct PlySummary {
    /// Name.
    pub name: String,
    /// Nodes.
    pub nodes: usize,
    /// Triangles.
    pub triangles: usize,
}

/// Either solver's time split \[s\].
#[derive(Debug, Clone, Copy, Serialize)]
#[serde(untagged)]
pub enum Timings {
    /// Newton.
    QuasiStatic(SolverTimings),
    /// Explicit.
    Explicit(ExplicitTimings),
}

/// What an explicit forming run reports besides the history.
#[derive(Debug, Clone, Serialize)]
pub struct ExplicitFigures {
    /// Time increments.
    pub increments: usize,
    /// Duration \[s\].
    pub duration: f64,
    /// Estimated critical step at the start \[s\].
    pub initial_critical_time_step: f64,
    /// Smallest and largest step taken \[s\].
    pub time_step_range: (f64, f64),
    /// Masses.
    pub mass: MassSummary,
    /// Largest KE/IE from 10 % of the programme on.
    pub max_kinetic_ratio: f64,
    /// Largest relative energy-balance error.
    pub max_relative_balance_error: f64,
    /// Energies at the last output [N·mm].
    pub final_energies: Option<Energies>,
    /// Element cycles per second over the passes.
    pub element_cycles_per_second: f64,
    /// Worker threads.
    pub threads: usize,
    /// Warnings.
    pub warnings: Vec<String>,
}

/// What the output callbacks feed.
struct Sink<'a> {
    case: &'a FormingCase,
    built: &'a FormingModel,
    out: PathBuf,
    files: &'a mut Outputs,
    history: Vec<FormingRow>,
    pvd: Vec<PvdEntry>,
    written_states: usize,
    seconds: f64,
    readout: Readout,
    outline_states: Vec<OutlineState>,
    state_rows: Vec<FormingRow>,
    mode_states: Vec<ModeAreas>,
    /// The last converged state when it is not an output state.
    last: Option<LastState>,
    /// The model has contact between plies (its fields go into the VTUs).
    ply_contact: bool,
}

/// The area of each deformation mode of one ply at one output state.
#[derive(Debug, Clone, Serialize)]
pub struct ModeAreas {
    /// The stroke \[mm\] (or `λ` without a stroke tool).
    pub stroke: f64,
    /// The ply.
    pub ply: String,
    /// Reference area \[mm²\] of the elements in mode 0 (near the
    /// reference state), 1 (`I11 < 1`, `I8 ≤ 1`: mixed-mode 1), 2
    /// (`I11 < 1`, `I8 > 1`: mixed-mode 2), 3 (`I11 ≥ 1`, `I8 > 1`) and 4
    /// (`I11 ≥ 1`, `I8 ≤ 1`), each to 0.1 %
    /// ([`crate::post::forming::deformation_mode`]).
    pub areas: [f64; crate::post::forming::MODES],
}

impl Sink<'_> {
    /// The force of the stroke tool in `row` (of the first tool without
    /// one), for the progress line.
    fn stroke_force(&self, row: &FormingRow) -> f64 {
        self.readout
            .stroke_tool
            .or((!row.tools.is_empty()).then_some(0))
            .map_or(0.0, |t| row.tools[t].force)
    }

    /// A history row at `load` from the state `snapshot`.
    fn row(&self, load: f64, snapshot: &Snapshot) -> FormingRow {
        let tools = self
            .built
            .tools
            .iter()
            .map(|t| {
                let mut force = snapshot.residual[t.dof];
                // The residual of a floating tool is its contact force less
                // its weight: add the weight back.
                if let ToolMotion::Floating { weight, .. } = t.spec.motion {
                    force += weight;
                }
                ToolRow {
                    displacement: snapshot.u[t.dof],
                    force,
                }
            })
            .collect();
        let reactions = self
            .case
            .boundaries
            .iter()
            .zip(&self.built.boundary_nodes)
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
            .collect();
        let probes = self
            .built
            .probe_nodes
            .iter()
            .map(|nodes| {
                let mut mean = [0.0; 3];
                for &n in nodes {
                    for (k, m) in mean.iter_mut().enumerate() {
                        *m += snapshot.u[3 * n + k];
                    }
                }
                mean.map(|m| m / nodes.len().max(1) as f64)
            })
            .collect();
        let stroke = self
            .readout
            .stroke_tool
            .map_or(load, |t| snapshot.u[self.built.tools[t].dof]);
        let lifts = self
            .readout
            .floating_tools
            .iter()
            .map(|&t| -snapshot.u[self.built.tools[t].dof])
            .collect();
        FormingRow {
            load,
            time: None,
            tools,
            reactions,
            probes,
            iterations: None,
            augmentations: None,
            max_penetration: None,
            multiplier_change: None,
            contacts: None,
            residual: None,
            increments: None,
            stroke,
            lifts,
            draw_in: self.readout.draw_in(snapshot.u),
            zones: self.readout.zones(self.case, self.built, snapshot.u),
            internal_energy: None,
            stabilisation_energy: None,
            kinetic_energy: None,
        }
    }

    /// Writes the VTU files of the state `snapshot` at `load` if it is an
    /// output state; otherwise keeps it as the last converged state, which
    /// a run that stops early writes too ([`Sink::write_last_state`]).
    fn states(&mut self, load: f64, snapshot: &Snapshot, row: &FormingRow) {
        let due = self
            .case
            .states
            .iter()
            .filter(|s| **s <= load + 1e-9)
            .count();
        let contact: Vec<ContactFields> = (0..self.built.plies.len())
            .map(|p| contact_fields(self.built, p, snapshot.model))
            .collect();
        if due <= self.written_states {
            self.last = Some(LastState {
                load,
                u: snapshot.u.to_vec(),
                row: row.clone(),
                contact,
            });
            return;
        }
        self.written_states = due;
        self.last = None;
        self.write_state(due, load, snapshot.u, row, &contact, "");
    }

    /// Writes the last converged state as one more output state when it is
    /// not one already: for a run that stopped early (incomplete or
    /// interrupted), the state it stopped at (`docs/cases.md`, "Incomplete
    /// runs and exit codes").
    fn write_last_state(&mut self) {
        if let Some(last) = self.last.take() {
            let index = self.written_states + 1;
            self.written_states = index;
            self.write_state(
                index,
                last.load,
                &last.u,
                &last.row,
                &last.contact,
                super::LAST_STATE_NOTE,
            );
        }
    }

    /// Writes output state number `index` (`u` at `load`; `note` follows
    /// the caption and the VTU files' load line).
    fn write_state(
        &mut self,
        index: usize,
        load: f64,
        u: &[f64],
        row: &FormingRow,
        contact: &[ContactFields],
        note: &str,
    ) {
        let plies = self.built.plies.len();
        self.outline_states.push(OutlineState {
            load,
            stroke: row.stroke,
            outlines: self.readout.outlines(u),
        });
        self.state_rows.push(row.clone());
        let caption = match self.readout.stroke_tool {
            Some(t) => format!(
                "{} {:.1} mm{note}",
                self.built.tools[t].spec.name, row.stroke
            ),
            None => format!("λ = {load:.3}{note}"),
        };
        for (t, tool) in self.built.tools.iter().enumerate() {
            let name = format!("tool-{}_{index:04}.vtu", file_stem(&tool.spec.name));
            let path = self.out.join("vtu").join(&name);
            let written = write_tool_vtu(&path, self.case, tool, u[tool.dof], load);
            // The series lists only the states that are there.
            if self.files.record(&path, written) {
                self.pvd.push(PvdEntry {
                    time: load,
                    file: format!("vtu/{name}"),
                    part: plies + t,
                });
            }
        }
        let tools = self.built.tools.len();
        for (p, ply) in self.built.plies.iter().enumerate() {
            let stem = file_stem(&ply.name);
            let name = format!("{stem}_{index:04}.vtu");
            let dic_name = format!("{stem}-dic_{index:04}.vtu");
            let path = self.out.join("vtu").join(&name);
            let dic_path = self.out.join("vtu").join(&dic_name);
            let maps = (
                self.out.join("maps").join(format!("{stem}_{index:04}.png")),
                self.out
                    .join("maps")
                    .join(format!("{stem}-dic_{index:04}.png")),
                self.out
                    .join("maps")
                    .join(format!("{stem}-modes_{index:04}.png")),
            );
            let written = write_ply_state(
                (&path, &dic_path, (&maps.0, &maps.1, &maps.2)),
                self.case,
                self.built,
                p,
                (u, &contact[p], self.ply_contact),
                (load, note),
                &caption,
                self.files,
            );
            if let Some(areas) = written.areas {
                self.mode_states.push(ModeAreas {
                    stroke: row.stroke,
                    ply: ply.name.clone(),
                    areas,
                });
            }
            if written.ply {
                self.pvd.push(PvdEntry {
                    time: load,
                    file: format!("vtu/{name}"),
                    part: p,
                });
            }
            if written.projection {
                self.pvd.push(PvdEntry {
                    time: load,
                    file: format!("vtu/{dic_name}"),
                    part: plies + tools + p,
                });
            }
        }
    }
}

/// A converged state that is not an output state: kept until the next one
/// replaces it, to be written if the run stops there.
struct LastState {
    load: f64,
    u: Vec<f64>,
    row: FormingRow,
    contact: Vec<ContactFields>,
}

/// A file-name stem from a ply or tool name.
fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// One tool's VTU at its displacement `q` along its direction.
fn write_tool_vtu(
    path: &Path,
    case: &FormingCase,
    tool: &crate::case::forming_model::BuiltTool,
    q: f64,
    load: f64,
) -> Result<(), String> {
    let shift = q * tool.direction;
    let points: Vec<[f64; 3]> = tool
        .drawing
        .vertices
        .iter()
        .map(|v| [v.x + shift.x, v.y + shift.y, v.z + shift.z])
        .collect();
    let piece = VtuPiece {
        points: &points,
        triangles: &tool.drawing.triangles,
        point_fields: vec![],
        cell_fields: vec![],
        comment: vec![
            format!(
                "ncform: {} ({}), tool \"{}\"",
                case.title, case.source, tool.spec.name
            ),
            format!("programme fraction {load}; tool displacement {q} mm along its direction"),
            format!("units: {UNITS}"),
        ],
    };
    write_vtu(path, &piece).map_err(|e| io_err(path, e))
}

/// Per node of ply `p`, the contact figures summed (forces, slip) or
/// combined (status: the largest, gap: the smallest) over every tool, and
/// likewise over every ply–ply contact.
struct ContactFields {
    status: Vec<i32>,
    normal_force: Vec<f64>,
    pressure: Vec<f64>,
    friction_force: Vec<f64>,
    slip: Vec<f64>,
    /// Contact with other plies: status (0 open, 1 stick, 2 slip), the
    /// node's own normal force [N] and the mid-surface gap [mm] (largest
    /// status, summed forces, smallest gap over the ply contacts).
    ply_status: Vec<i32>,
    ply_normal_force: Vec<f64>,
    ply_gap: Vec<f64>,
}

fn contact_fields(built: &FormingModel, p: usize, model: &crate::model::Model) -> ContactFields {
    let ply = &built.plies[p];
    let count = ply.mesh.nodes.len();
    let mut c = ContactFields {
        status: vec![0; count],
        normal_force: vec![0.0; count],
        pressure: vec![0.0; count],
        friction_force: vec![0.0; count],
        slip: vec![0.0; count],
        ply_status: vec![0; count],
        ply_normal_force: vec![0.0; count],
        ply_gap: vec![f64::INFINITY; count],
    };
    for term in model.terms_of::<crate::model::PlyContact>() {
        for k in 0..2 {
            for (&node, contact) in term.ply_nodes(k).iter().zip(term.node_contacts(k)) {
                let Some(n) = node.checked_sub(ply.node_offset).filter(|n| *n < count) else {
                    continue;
                };
                c.ply_status[n] = c.ply_status[n].max(contact.status as i32);
                c.ply_normal_force[n] += contact.normal_force;
                c.ply_gap[n] = c.ply_gap[n].min(contact.gap);
            }
        }
    }
    // VTU readers take finite values: a node far from every other ply
    // shows gap -1 (documented).
    for g in &mut c.ply_gap {
        if !g.is_finite() {
            *g = -1.0;
        }
    }
    for term in model.terms_of::<crate::model::ToolContact>() {
        for ((&node, contact), area) in term
            .nodes()
            .iter()
            .zip(term.node_contacts())
            .zip(term.areas())
        {
            let Some(n) = node.checked_sub(ply.node_offset).filter(|n| *n < count) else {
                continue;
            };
            c.status[n] = c.status[n].max(contact.status as i32);
            c.normal_force[n] += contact.normal_force;
            if *area > 0.0 {
                c.pressure[n] += contact.normal_force / area;
            }
            c.friction_force[n] += contact.friction_force;
            c.slip[n] += contact.slip;
        }
    }
    c
}

/// What [`write_ply_state`] wrote.
struct PlyState {
    /// The reference area of each deformation mode (`None` when the
    /// state's fields could not be evaluated).
    areas: Option<[f64; crate::post::forming::MODES]>,
    /// The ply's VTU is written.
    ply: bool,
    /// The VTU of its projection is written.
    projection: bool,
}

/// One ply at an output state: its VTU (with the image-correlation fields
/// beside the true ones), the VTU of its projection on the blank plane, and
/// its maps (`paths`: ply VTU, projection VTU, the three map PNGs), each
/// recorded in `files` whatever became of the others.
#[allow(clippy::too_many_arguments)]
fn write_ply_state(
    paths: (&Path, &Path, (&Path, &Path, &Path)),
    case: &FormingCase,
    built: &FormingModel,
    p: usize,
    (u, contact, ply_contact): (&[f64], &ContactFields, bool),
    (load, note): (f64, &str),
    caption: &str,
    files: &mut Outputs,
) -> PlyState {
    let (path, dic_path, map_paths) = paths;
    let ply = &built.plies[p];
    let offset = ply.node_offset;
    let count = ply.mesh.nodes.len();
    let points = ply.deformed_positions(u);
    let displacement: Vec<[f64; 3]> = (0..count)
        .map(|n| {
            let g = offset + n;
            [u[3 * g], u[3 * g + 1], u[3 * g + 2]]
        })
        .collect();
    let fields = match element_fields(&ply.membrane, u) {
        Ok(fields) => fields,
        Err((e, err)) => {
            files.record_missing(
                &format!(
                    "the VTU files and maps of ply \"{}\" at programme fraction {load}",
                    ply.name
                ),
                format!("element {}: {err}", ply.mesh.element_label(e)),
            );
            return PlyState {
                areas: None,
                ply: false,
                projection: false,
            };
        }
    };
    let dic = dic_measures(built, p, u);
    let dic_columns = DicColumns::new(&dic);
    let dic_fields = || {
        vec![
            Field {
                name: "dic_shear_angle_deg",
                data: FieldData::Scalar(&dic_columns.shear_angle_deg),
            },
            Field {
                name: "dic_E22",
                data: FieldData::Scalar(&dic_columns.e22),
            },
            Field {
                name: "dic_E_perp",
                data: FieldData::Scalar(&dic_columns.e_perp),
            },
            Field {
                name: "dic_valid",
                data: FieldData::Int(&dic_columns.valid),
            },
        ]
    };
    let columns = FieldColumns::new(&fields);
    let modes: Vec<u8> = fields
        .iter()
        .map(|f| crate::post::forming::deformation_mode(f.i8, f.i11))
        .collect();
    let mode_codes: Vec<i32> = modes.iter().map(|m| i32::from(*m)).collect();
    let areas: Vec<f64> = ply.membrane.references.iter().map(|r| r.area).collect();
    let mut cell_fields = columns.cell_fields();
    cell_fields.extend(dic_fields());
    cell_fields.push(Field {
        name: "deformation_mode",
        data: FieldData::Int(&mode_codes),
    });
    let dic_note = "dic_*: gamma, E22, E_perp recomputed on the mesh projected on the blank plane (2D image correlation, docs/forming.md); 0 where dic_valid = 0 (projected triangle turned over)";
    let mut point_fields = vec![
        Field {
            name: "displacement",
            data: FieldData::Vector3(&displacement),
        },
        Field {
            name: "contact_status",
            data: FieldData::Int(&contact.status),
        },
        Field {
            name: "contact_pressure",
            data: FieldData::Scalar(&contact.pressure),
        },
        Field {
            name: "contact_normal_force",
            data: FieldData::Scalar(&contact.normal_force),
        },
        Field {
            name: "friction_force",
            data: FieldData::Scalar(&contact.friction_force),
        },
        Field {
            name: "slip",
            data: FieldData::Scalar(&contact.slip),
        },
    ];
    if ply_contact {
        point_fields.extend([
            Field {
                name: "ply_contact_status",
                data: FieldData::Int(&contact.ply_status),
            },
            Field {
                name: "ply_contact_normal_force",
                data: FieldData::Scalar(&contact.ply_normal_force),
            },
            Field {
                name: "ply_contact_gap",
                data: FieldData::Scalar(&contact.ply_gap),
            },
        ]);
    }
    let piece = VtuPiece {
        points: &points,
        triangles: &ply.mesh.triangles,
        point_fields,
        cell_fields,
        comment: vec![
            format!(
                "ncform: {} ({}), ply \"{}\"",
                case.title, case.source, ply.name
            ),
            format!("programme fraction {load}{note}"),
            format!("units: {UNITS}; E22 = I8-1, E_perp = I11-1 (paper Section 4)"),
            "S: second Piola-Kirchhoff stress [MPa] in the reference global x-y axes (xx, yy, xy)"
                .into(),
            dic_note.into(),
            "deformation_mode (to 0.1 %): 0 near the reference state, 1 I11<1 & I8<=1 (mixed-mode 1), 2 I11<1 & I8>1 (mixed-mode 2), 3 I11>=1 & I8>1, 4 I11>=1 & I8<=1 (docs/forming.md)".into(),
        ],
    };
    let ply_written = files.record(path, write_vtu(path, &piece).map_err(|e| io_err(path, e)));
    let projected: Vec<[f64; 3]> = ply
        .mesh
        .nodes
        .iter()
        .zip(&points)
        .map(|(x, q)| [q[0], q[1], x.z])
        .collect();
    let dic_piece = VtuPiece {
        points: &projected,
        triangles: &ply.mesh.triangles,
        point_fields: vec![Field {
            name: "displacement",
            data: FieldData::Vector3(&displacement),
        }],
        cell_fields: dic_fields(),
        comment: vec![
            format!(
                "ncform: {} ({}), ply \"{}\", projected on the blank plane",
                case.title, case.source, ply.name
            ),
            format!("programme fraction {load}{note}"),
            format!("units: {UNITS}"),
            dic_note.into(),
        ],
    };
    let projection = files.record(
        dic_path,
        write_vtu(dic_path, &dic_piece).map_err(|e| io_err(dic_path, e)),
    );
    write_maps(
        (case, built, p),
        u,
        &fields,
        &dic,
        &modes,
        map_paths,
        caption,
        files,
    );
    PlyState {
        areas: Some(crate::post::forming::mode_areas(&modes, &areas)),
        ply: ply_written,
        projection,
    }
}

/// Runs a forming case and writes its outputs into the folder `out`,
/// prepared as a run folder after the set-up ([`RunFolder::prepare`]: an
/// earlier run moved aside, a foreign folder refused).
///
/// # Errors
/// Set-up failures (case, meshes, tools, output folder), naming the file;
/// nothing is written then, or `status.json` says `failed` when the folder
/// was prepared.
pub fn run_forming(
    case: &FormingCase,
    out: &Path,
    progress: Progress,
) -> Result<FormingSummary, String> {
    run_forming_with(case, out, progress, &CancelToken::default())
}

/// As [`run_forming`], stopping at the solver's next safe point once
/// `cancel` is cancelled (the results up to there are written and marked
/// interrupted).
///
/// # Errors
/// As [`run_forming`].
pub fn run_forming_with(
    case: &FormingCase,
    out: &Path,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<FormingSummary, String> {
    let built = case.build().map_err(|e| e.to_string())?;
    let readout = Readout::new(case, &built)?;
    let mut folder = RunFolder::prepare(out, &case.source, &case.title, &["vtu", "maps"])?;
    run_built(case, built, readout, &mut folder, (progress, cancel))
}

/// As [`run_forming_with`] into a folder already prepared (with `vtu/` and
/// `maps/`; a test can then put things in the way of the outputs).
///
/// # Errors
/// As [`run_forming`]; `status.json` then says `failed`.
pub fn run_forming_in(
    case: &FormingCase,
    folder: &mut RunFolder,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<FormingSummary, String> {
    let built = case
        .build()
        .map_err(|e| e.to_string())
        .and_then(|built| Readout::new(case, &built).map(|readout| (built, readout)));
    let (built, readout) = folder.failed_on_error(built)?;
    run_built(case, built, readout, folder, (progress, cancel))
}

/// The run of a built case into a prepared folder; a set-up error is
/// written to `status.json` as `failed`.
fn run_built(
    case: &FormingCase,
    mut built: FormingModel,
    readout: Readout,
    folder: &mut RunFolder,
    (mut progress, cancel): (Progress, &CancelToken),
) -> Result<FormingSummary, String> {
    let wall = Instant::now();
    let out = folder.path().to_path_buf();
    let out = out.as_path();
    let dofs = built.dofs();
    let mut model = std::mem::replace(&mut built.model, crate::model::Model::new(0));
    let mut sink = Sink {
        case,
        built: &built,
        out: out.to_path_buf(),
        files: folder.outputs_mut(),
        history: Vec::new(),
        pvd: Vec::new(),
        written_states: 0,
        seconds: 0.0,
        readout,
        outline_states: Vec::new(),
        state_rows: Vec::new(),
        mode_states: Vec::new(),
        last: None,
        ply_contact: model
            .terms_of::<crate::model::PlyContact>()
            .next()
            .is_some(),
    };
    let report = match case.solver_kind {
        SolverKind::QuasiStatic => {
            run_quasi_static(case, &mut model, dofs, &mut sink, &mut progress, cancel)
        }
        SolverKind::Explicit => {
            run_explicit(case, &mut model, &dofs, &mut sink, &mut progress, cancel)
        }
    };
    progress.finish();
    // (A match, not `failed_on_error`: the sink still borrows the folder.)
    let report = match report {
        Ok(report) => report,
        Err(e) => {
            folder.fail(&e);
            return Err(e);
        }
    };
    let output_clock = Instant::now();
    if report.status != RunStatus::Complete {
        sink.write_last_state();
    }
    let path = out.join("forming.pvd");
    let written = write_pvd(
        &path,
        &sink.pvd,
        &[
            format!("ncform: {} ({})", case.title, case.source),
            "time = programme fraction (0 to 1); parts: the plies, then the tools, then each ply projected on the blank plane (2D image-correlation view); units: mm, N, MPa".into(),
        ],
    )
    .map_err(|e| io_err(&path, e));
    sink.files.record(&path, written);
    write_history(case, &built, out, &sink.history, &report.status, sink.files);
    let stroke_label = sink.readout.stroke_tool.map_or_else(
        || "programme fraction".to_string(),
        |t| format!("{} displacement", built.tools[t].spec.name),
    );
    write_outer_contours(
        case,
        &built,
        &sink.readout,
        &sink.outline_states,
        out,
        (&report.status, &stroke_label),
        sink.files,
    );
    let blank_rows: Vec<BlankRow> = sink
        .history
        .iter()
        .map(|h| BlankRow {
            stroke: h.stroke,
            force: sink.readout.stroke_tool.map_or(0.0, |t| h.tools[t].force),
            lifts: h.lifts.clone(),
            draw_in: h.draw_in.clone(),
            zones: h.zones.clone(),
        })
        .collect();
    write_forming_history(
        case,
        &built,
        &sink.readout,
        &blank_rows,
        out,
        (&report.status, &stroke_label),
        sink.files,
    );
    if let Some(records) = &report.records {
        write_energy(case, out, records, &report.status, sink.files);
    }
    sink.seconds += output_clock.elapsed().as_secs_f64();
    if let Some(figures) = &report.explicit {
        for warning in &figures.warnings {
            eprintln!("warning: {warning}");
        }
    }
    let missing = sink.files.missing().to_vec();
    let mut summary = FormingSummary {
        case: case.source.clone(),
        title: case.title.clone(),
        complete: report.status == RunStatus::Complete,
        exit_status: ExitStatus::of_run(&report.status, missing.len()),
        outputs_missing: missing,
        status: report.status.clone(),
        solver: case.solver_kind,
        units: UNITS,
        plies: built
            .plies
            .iter()
            .map(|p| PlySummary {
                name: p.name.clone(),
                nodes: p.mesh.nodes.len(),
                triangles: p.mesh.triangles.len(),
            })
            .collect(),
        tools: built
            .tools
            .iter()
            .map(|t| {
                let motion = match t.spec.motion {
                    ToolMotion::Fixed => "fixed".to_string(),
                    ToolMotion::Prescribed { displacement, .. } => {
                        format!("prescribed, {displacement} mm")
                    }
                    ToolMotion::Floating { mass, weight, .. } => {
                        format!(
                            "floating, {} kg, {weight} N",
                            mass / crate::case::forming::KG_IN_T
                        )
                    }
                };
                format!("{} ({motion})", t.spec.name)
            })
            .collect(),
        unknowns: report.unknowns,
        nonzeros: report.nonzeros,
        steps: sink.history.len(),
        newton_iterations: report.newton_iterations,
        augmentations: report.augmentations,
        explicit: report.explicit,
        timings: report.timings,
        term_seconds: report.term_seconds,
        stabilisation: report.stabilisation,
        output_seconds: sink.seconds,
        wall_seconds: wall.elapsed().as_secs_f64(),
        forming: FormingFigures {
            stroke_tool: sink
                .readout
                .stroke_tool
                .map(|t| built.tools[t].spec.name.clone()),
            floating_tools: sink
                .readout
                .floating_tools
                .iter()
                .map(|&t| built.tools[t].spec.name.clone())
                .collect(),
            draw_in_points: sink
                .readout
                .points()
                .iter()
                .map(|points| {
                    points
                        .iter()
                        .map(|p| (p.name.clone(), p.reference))
                        .collect()
                })
                .collect(),
            zones: case
                .zones
                .iter()
                .map(|z| {
                    (
                        z.zone.name.clone(),
                        built.plies[z.ply].name.clone(),
                        z.zone.centre,
                        z.zone.size,
                    )
                })
                .collect(),
            states: std::mem::take(&mut sink.state_rows),
            deformation_modes: std::mem::take(&mut sink.mode_states),
        },
        history: std::mem::take(&mut sink.history),
    };
    drop(sink);
    let path = out.join("summary.json");
    let written = serde_json::to_string_pretty(&summary)
        .map_err(|e| io_err(&path, e))
        .and_then(|text| std::fs::write(&path, text + "\n").map_err(|e| io_err(&path, e)));
    folder.outputs_mut().record(&path, written);
    summary.exit_status = folder.finish(&report.status);
    summary.outputs_missing = folder.outputs().missing().to_vec();
    Ok(summary)
}

/// What either solver hands back.
struct Report {
    status: RunStatus,
    unknowns: usize,
    nonzeros: usize,
    newton_iterations: usize,
    augmentations: usize,
    timings: Timings,
    explicit: Option<ExplicitFigures>,
    records: Option<Vec<ExplicitRecord>>,
    term_seconds: Vec<(String, f64)>,
    stabilisation: Option<(f64, f64, f64)>,
}

fn run_quasi_static(
    case: &FormingCase,
    model: &mut crate::model::Model,
    dofs: DofMap,
    sink: &mut Sink,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Report, String> {
    let mut u = vec![0.0; dofs.total];
    let params = crate::solver::NewtonParameters {
        cancel: *cancel,
        ..case.solver.clone()
    };
    let result = solve_quasi_static(
        model,
        dofs,
        &params,
        1.0,
        &case.states,
        &mut u,
        |record, snapshot| {
            let clock = Instant::now();
            let mut row = sink.row(record.load, snapshot);
            row.iterations = Some(record.iterations);
            row.augmentations = Some(record.augmentations);
            row.residual = record.residuals.last().copied();
            row.internal_energy = Some(record.internal_energy);
            row.stabilisation_energy = record.stabilisation.map(|s| s.dissipated_total);
            row.kinetic_energy = record.stabilisation.map(|s| s.kinetic);
            if let Some(c) = &record.contact {
                row.max_penetration = Some(c.max_penetration);
                row.multiplier_change = Some(c.multiplier_change);
                row.contacts = Some((c.active, c.slipping));
            }
            let force = sink.stroke_force(&row);
            let detail = format!(
                "step {}, {} iterations, {} augmentations",
                record.step, record.iterations, record.augmentations
            );
            progress.update(record.load, force, &detail, 1.0);
            sink.states(record.load, snapshot, &row);
            sink.history.push(row);
            sink.seconds += clock.elapsed().as_secs_f64();
        },
    )?;
    result
        .warnings
        .iter()
        .for_each(|w| eprintln!("warning: {w}"));
    Ok(Report {
        status: result.status,
        unknowns: result.unknowns,
        nonzeros: result.nonzeros,
        newton_iterations: result.newton_iterations,
        augmentations: result.augmentations,
        timings: Timings::QuasiStatic(result.timings),
        explicit: None,
        records: None,
        term_seconds: result.term_seconds,
        stabilisation: Some((
            result.internal_energy,
            result.stabilisation_energy,
            result.max_stabilisation_ratio,
        )),
    })
}

fn run_explicit(
    case: &FormingCase,
    model: &mut crate::model::Model,
    dofs: &DofMap,
    sink: &mut Sink,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Report, String> {
    let mut params = case.explicit.parameters();
    params.cancel = *cancel;
    let rows = case.history_rows;
    let mut fractions: Vec<f64> = (1..=rows).map(|k| k as f64 / rows as f64).collect();
    fractions.extend_from_slice(&case.states);
    let times: Vec<f64> = fractions
        .iter()
        .map(|f| params.time_of_load_fraction(*f))
        .collect();
    let mut state = ExplicitState::at_rest(dofs.total);
    let result = solve_explicit(
        model,
        dofs,
        &params,
        1.0,
        &times,
        &mut state,
        |record, snapshot| {
            let mut row = sink.row(record.load, snapshot);
            row.time = Some(record.time);
            row.increments = Some(record.increment);
            let force = sink.stroke_force(&row);
            let detail = super::explicit_progress(record);
            progress.update(record.load, force, &detail, 1.0);
            sink.states(record.load, snapshot, &row);
            sink.history.push(row);
        },
    )
    .map_err(|e| format!("{}: {e}", case.source))?;
    Ok(Report {
        status: result.status.clone(),
        unknowns: dofs.n_free(),
        nonzeros: 0,
        newton_iterations: 0,
        augmentations: 0,
        timings: Timings::Explicit(result.timings),
        explicit: Some(ExplicitFigures {
            increments: result.increments,
            duration: params.duration,
            initial_critical_time_step: result.initial_critical_time_step,
            time_step_range: result.time_step_range,
            mass: result.mass,
            max_kinetic_ratio: result.max_kinetic_ratio,
            max_relative_balance_error: result.max_relative_balance_error,
            final_energies: result.records.last().map(|r| r.energies),
            element_cycles_per_second: result.element_cycles_per_second(),
            threads: result.threads,
            warnings: result.warnings.clone(),
        }),
        term_seconds: result.term_seconds,
        records: Some(result.records),
        stabilisation: None,
    })
}

/// The status line of the file headers, in programme fractions.
pub(super) fn status_line(status: &RunStatus) -> String {
    super::status_line(
        status,
        |load| format!("programme fraction {load}"),
        |load| load.to_string(),
    )
}

/// `history.csv` and `reactions.png`.
fn write_history(
    case: &FormingCase,
    built: &FormingModel,
    out: &Path,
    history: &[FormingRow],
    status: &RunStatus,
    files: &mut Outputs,
) {
    let mut header: Vec<String> = vec!["programme fraction [-]".into(), "time [s]".into()];
    for t in &built.tools {
        header.push(format!("{} displacement [mm]", t.spec.name));
        header.push(format!("{} force [N]", t.spec.name));
    }
    for (i, b) in case.boundaries.iter().enumerate() {
        for axis in ["x", "y", "z"] {
            header.push(format!(
                "boundary {} ({}) reaction {axis} [N]",
                i + 1,
                b.nodes
            ));
        }
    }
    for (i, p) in case.probes.iter().enumerate() {
        for axis in ["x", "y", "z"] {
            header.push(format!(
                "probe {} ({}) displacement {axis} [mm]",
                i + 1,
                p.nodes
            ));
        }
    }
    for h in [
        "iterations [-]",
        "augmentations [-]",
        "max penetration [mm]",
        "multiplier change [-]",
        "closed contacts [-]",
        "slipping contacts [-]",
        "residual [N]",
        "internal energy [N*mm]",
        "stabilisation energy [N*mm]",
        "kinetic energy [N*mm]",
    ] {
        header.push(h.into());
    }
    let rows: Vec<Vec<f64>> = history
        .iter()
        .map(|h| {
            let mut row = vec![h.load, h.time.unwrap_or(0.0)];
            for t in &h.tools {
                row.extend([t.displacement, t.force]);
            }
            for r in &h.reactions {
                row.extend(r);
            }
            for p in &h.probes {
                row.extend(p);
            }
            let (closed, slipping) = h.contacts.unwrap_or((0, 0));
            row.extend([
                h.iterations.unwrap_or(0) as f64,
                h.augmentations.unwrap_or(0) as f64,
                h.max_penetration.unwrap_or(0.0),
                h.multiplier_change.unwrap_or(0.0),
                closed as f64,
                slipping as f64,
                h.residual.unwrap_or(0.0),
                h.internal_energy.unwrap_or(0.0),
                h.stabilisation_energy.unwrap_or(0.0),
                h.kinetic_energy.unwrap_or(0.0),
            ]);
            row
        })
        .collect();
    let path = out.join("history.csv");
    let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
    let written = write_csv(
        &path,
        &[
            "ncform run: forming history (tools, boundary reactions, contact)".to_string(),
            format!("case: {} ({})", case.title, case.source),
            status_line(status),
            "tool force: force of the plies on the tool along its direction (what drives or holds it; positive when the plies resist its motion)".into(),
            format!("units: {UNITS}"),
        ],
        &header_refs,
        &rows,
    )
    .map_err(|e| io_err(&path, e));
    files.record(&path, written);
    let suffix = super::plot_suffix(status);
    let mut panels = Vec::new();
    for (i, t) in built.tools.iter().enumerate() {
        panels.push(Panel {
            title: format!("{}{suffix}", t.spec.name),
            x_label: format!("{} displacement [mm]", t.spec.name),
            y_label: "force [N]".into(),
            series: vec![Series {
                label: "force".into(),
                points: history
                    .iter()
                    .map(|h| (h.tools[i].displacement, h.tools[i].force))
                    .collect(),
            }],
        });
    }
    for (i, b) in case.boundaries.iter().enumerate() {
        panels.push(Panel {
            title: format!("boundary {} ({}){suffix}", i + 1, b.nodes),
            x_label: "programme fraction [-]".into(),
            y_label: "reaction [N]".into(),
            series: ["x", "y", "z"]
                .iter()
                .enumerate()
                .map(|(k, axis)| Series {
                    label: (*axis).into(),
                    points: history
                        .iter()
                        .map(|h| (h.load, h.reactions[i][k]))
                        .collect(),
                })
                .collect(),
        });
    }
    if panels.is_empty() {
        return;
    }
    let cols = panels.len().min(3);
    let rows = panels.len().div_ceil(cols);
    let path = out.join("reactions.png");
    let written = write_panels(
        &path,
        &panels,
        (rows, cols),
        (600 * cols as u32, 500 * rows as u32),
    );
    files.record(&path, written);
}

/// `energy.csv` and `energy.png` of an explicit run.
fn write_energy(
    case: &FormingCase,
    out: &Path,
    records: &[ExplicitRecord],
    status: &RunStatus,
    files: &mut Outputs,
) {
    super::energy::write_energy(
        out,
        &[
            "ncform run: energy history of the explicit solver".to_string(),
            format!("case: {} ({})", case.title, case.source),
            status_line(status),
            "balance error = internal + contact + kinetic + damping + friction - external work - initial energy; relative to the largest of those".into(),
            format!("units: {UNITS}; energies in N*mm (= mJ)"),
        ],
        records,
        status,
        &super::energy::EnergyAxis {
            header: "programme fraction [-]",
            label: "time [s]",
            value: |r| r.time,
        },
        true,
        files,
    );
}
