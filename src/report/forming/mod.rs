//! The files of a forming run's folder (`docs/cases.md`, "Forming
//! outputs"), written as the states come:
//!
//! - `history.csv` / `reactions.png`: every tool's displacement and force,
//!   every boundary's reaction, per converged step (quasi-static) or
//!   history row (explicit), with the contact figures of each step
//!   ([`history`]);
//! - `vtu/*.vtu` and `forming.pvd`: every ply with its strain, invariant,
//!   stress, curvature and contact fields, and every tool, at the output
//!   states, for ParaView ([`states`]);
//! - `forming.csv` / `.png`, `outer_contour.csv` / `.png`, `maps/`: what is
//!   read on the blanks ([`readout`], [`maps`]);
//! - `energy.csv` / `energy.png` (explicit): internal, contact, kinetic,
//!   external work (motions and loads), damping, friction, balance;
//! - `summary.json`: status, forces at the outputs, contact and energy
//!   figures, work done, time split.
//!
//! A solve that fails keeps everything up to the last converged step (or
//! output) and marks it incomplete.

pub mod history;
pub mod maps;
pub mod readout;
pub mod states;

use crate::config::readable_number;
use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use self::history::{BlankRow, write_energy, write_forming_history, write_history};
use self::maps::{OutlineState, write_outer_contours};
use self::readout::Readout;
pub use self::states::file_stem;
use self::states::{ContactFields, contact_fields, write_ply_state, write_tool_vtu};
use super::folder::{ExitStatus, MissingOutput, Outputs, RunFolder};
pub use super::rows::FormingRow;
use super::runner::{Recorded, SolveTimings, Solved};
use super::{UNITS, io_err};
use crate::case::SolverKind;
use crate::case::forming::{FormingCase, ToolMotion};
use crate::case::forming_model::FormingModel;
use crate::post::vtu::{PvdEntry, write_pvd};
use crate::solver::explicit::{Energies, MassSummary};
use crate::solver::{ExplicitResult, RunStatus};

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
    #[serde(skip_serializing_if = "Option::is_none")]
    pub explicit: Option<ExplicitFigures>,
    /// Time split of the solve \[s\].
    pub timings: SolveTimings,
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
    /// The defect indicators' areas per ply (`docs/cases.md`, "Defect
    /// indicators").
    pub defects: DefectFigures,
    /// The history.
    pub history: Vec<FormingRow>,
}

/// The defect indicators of a forming run in `summary.json`: each ply's
/// thresholds, and its areas above them at every output state and at the
/// last one written \[mm², formed area\].
#[derive(Debug, Clone, Serialize)]
pub struct DefectFigures {
    /// Per ply: its name and thresholds.
    pub thresholds: Vec<(String, crate::post::defects::DefectThresholds)>,
    /// Per output state and ply, the areas.
    pub states: Vec<PlyDefectAreas>,
    /// Per ply, the areas at the last state written (the end of a complete
    /// run).
    #[serde(rename = "final")]
    pub last: Vec<PlyDefectAreas>,
}

/// One ply's defect areas at one output state.
#[derive(Debug, Clone, Serialize)]
pub struct PlyDefectAreas {
    /// The stroke \[mm\] (or `λ` without a stroke tool).
    pub stroke: f64,
    /// The ply.
    pub ply: String,
    /// The areas \[mm²\].
    #[serde(flatten)]
    pub areas: crate::post::defects::DefectAreas,
}

/// What is read on the blanks, at the output states (`docs/forming.md`).
#[derive(Debug, Clone, Serialize)]
pub struct FormingFigures {
    /// The tool whose displacement is the stroke.
    #[serde(skip_serializing_if = "Option::is_none")]
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

/// What an explicit forming run reports besides the history.
#[derive(Debug, Clone, Serialize)]
pub struct ExplicitFigures {
    /// Time increments.
    pub increments: usize,
    /// Duration \[s\].
    pub duration: f64,
    /// Estimated critical step at the start \[s\].
    pub initial_critical_time_step: f64,
    /// Smallest and largest step taken \[s\] (left out when the run took
    /// no increment).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_step_range: Option<(f64, f64)>,
    /// Masses.
    pub mass: MassSummary,
    /// Largest KE/IE from 10 % of the programme on.
    pub max_kinetic_ratio: f64,
    /// Largest relative energy-balance error.
    pub max_relative_balance_error: f64,
    /// Energies at the last output [N·mm].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_energies: Option<Energies>,
    /// Element cycles per second over the passes.
    pub element_cycles_per_second: f64,
    /// Worker threads.
    pub threads: usize,
    /// The step each term alone would allow, at the start and at the last
    /// estimate ([`crate::solver::explicit::TermStep`]): what sets the
    /// step.
    pub term_steps: Vec<crate::solver::explicit::TermStep>,
    /// Warnings.
    pub warnings: Vec<String>,
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

/// The files of a forming run's folder, written as the states come.
pub struct FormingFiles {
    out: PathBuf,
    history: Vec<FormingRow>,
    pvd: Vec<PvdEntry>,
    written_states: usize,
    seconds: f64,
    outline_states: Vec<OutlineState>,
    state_rows: Vec<FormingRow>,
    mode_states: Vec<ModeAreas>,
    defect_states: Vec<PlyDefectAreas>,
    /// The last converged state when it is not an output state.
    last: Option<LastState>,
    wall: Instant,
}

/// Where an output state goes and what it is: its number, load, note and
/// caption.
struct StateLabel<'a> {
    index: usize,
    load: f64,
    note: &'a str,
}

impl FormingFiles {
    /// The writer of a forming run's outputs into the folder `out`
    /// (prepared, with `vtu/` and `maps/`).
    pub fn new(out: &Path) -> Self {
        Self {
            out: out.to_path_buf(),
            history: Vec::new(),
            pvd: Vec::new(),
            written_states: 0,
            seconds: 0.0,
            outline_states: Vec::new(),
            state_rows: Vec::new(),
            mode_states: Vec::new(),
            defect_states: Vec::new(),
            last: None,
            wall: Instant::now(),
        }
    }

    /// Takes a recorded state: its VTU files and maps if it is an output
    /// state (otherwise it is kept as the last converged state, which a run
    /// that stops early writes too), and its history row.
    pub fn record(
        &mut self,
        case: &FormingCase,
        built: &FormingModel,
        readout: &Readout,
        state: &Recorded,
        files: &mut Outputs,
    ) {
        let Recorded::Forming { row, snapshot } = state else {
            return;
        };
        let clock = Instant::now();
        let load = row.load;
        let due = case.states.iter().filter(|s| **s <= load + 1e-9).count();
        let contact: Vec<ContactFields> = (0..built.plies.len())
            .map(|p| contact_fields(built, p, snapshot.model, Some(snapshot.u)))
            .collect();
        if due <= self.written_states {
            self.last = Some(LastState {
                load,
                u: snapshot.u.to_vec(),
                row: (*row).clone(),
                contact,
            });
        } else {
            self.written_states = due;
            self.last = None;
            let label = StateLabel {
                index: due,
                load,
                note: "",
            };
            self.write_state(
                (case, built, readout),
                &label,
                snapshot.u,
                row,
                &contact,
                files,
            );
        }
        self.history.push((*row).clone());
        self.seconds += clock.elapsed().as_secs_f64();
    }

    /// Writes the last converged state as one more output state when it is
    /// not one already: for a run that stopped early (incomplete or
    /// interrupted), the state it stopped at (`docs/cases.md`, "Incomplete
    /// runs and exit codes").
    fn write_last_state(
        &mut self,
        parts: (&FormingCase, &FormingModel, &Readout),
        files: &mut Outputs,
    ) {
        if let Some(last) = self.last.take() {
            let index = self.written_states + 1;
            self.written_states = index;
            let label = StateLabel {
                index,
                load: last.load,
                note: super::LAST_STATE_NOTE,
            };
            self.write_state(parts, &label, &last.u, &last.row, &last.contact, files);
        }
    }

    /// Writes output state number `label.index` (`u` at `label.load`;
    /// `label.note` follows the caption and the VTU files' load line): the
    /// tools' VTUs, then each ply's VTU, projection and maps.
    fn write_state(
        &mut self,
        (case, built, readout): (&FormingCase, &FormingModel, &Readout),
        label: &StateLabel,
        u: &[f64],
        row: &FormingRow,
        contact: &[ContactFields],
        files: &mut Outputs,
    ) {
        let StateLabel { index, load, note } = *label;
        let plies = built.plies.len();
        self.outline_states.push(OutlineState {
            load,
            stroke: row.stroke,
            outlines: readout.outlines(u),
        });
        self.state_rows.push(row.clone());
        let caption = match readout.stroke_tool {
            Some(t) => format!("{} {:.1} mm{note}", built.tools[t].spec.name, row.stroke),
            None => format!("λ = {load:.3}{note}"),
        };
        for (t, tool) in built.tools.iter().enumerate() {
            let name = format!("tool-{}_{index:04}.vtu", file_stem(&tool.spec.name));
            let path = self.out.join("vtu").join(&name);
            // The series lists only the states that are there.
            if files.write(&path, |p| write_tool_vtu(p, case, tool, u[tool.dof], load)) {
                self.pvd.push(PvdEntry {
                    time: load,
                    file: format!("vtu/{name}"),
                    part: plies + t,
                });
            }
        }
        let ply_contact = !case.ply_contacts.is_empty();
        let tools = built.tools.len();
        for (p, ply) in built.plies.iter().enumerate() {
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
                case,
                built,
                p,
                (u, &contact[p], ply_contact),
                (load, note),
                &caption,
                files,
            );
            if let Some(areas) = written.defects {
                self.defect_states.push(PlyDefectAreas {
                    stroke: row.stroke,
                    ply: ply.name.clone(),
                    areas,
                });
            }
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

    /// Writes what comes at the end of the solve, each file attempted
    /// whatever became of the others — the last state when the run stopped
    /// early, the series, the histories, the outer contours, the energies
    /// (explicit) — then the summary, and `status.json` with the exit
    /// status. Returns the summary.
    pub fn finish(
        &mut self,
        case: &FormingCase,
        built: &FormingModel,
        readout: &Readout,
        solved: &Solved,
        folder: &mut RunFolder,
    ) -> FormingSummary {
        for w in &solved.warnings {
            eprintln!("warning: {w}");
        }
        let output_clock = Instant::now();
        self.write_end_files((case, built, readout), solved, folder.outputs_mut());
        self.seconds += output_clock.elapsed().as_secs_f64();
        let explicit = solved
            .explicit
            .as_ref()
            .map(|(result, duration)| explicit_figures(result, *duration));
        if let Some(figures) = &explicit {
            for warning in &figures.warnings {
                eprintln!("warning: {warning}");
            }
        }
        let mut summary = self.summary(case, built, readout, solved, explicit, folder);
        let path = self.out.join("summary.json");
        folder.outputs_mut().write_json(&path, &summary);
        summary.exit_status = folder.finish(&solved.status);
        summary.outputs_missing = folder.outputs().missing().to_vec();
        summary
    }

    /// The last state (when the run stopped early), the series, the
    /// histories, the outer contours and the energies.
    fn write_end_files(
        &mut self,
        (case, built, readout): (&FormingCase, &FormingModel, &Readout),
        solved: &Solved,
        files: &mut Outputs,
    ) {
        let out = self.out.clone();
        let out = out.as_path();
        if solved.status != RunStatus::Complete {
            self.write_last_state((case, built, readout), files);
        }
        let path = out.join("forming.pvd");
        files.write(&path, |p| write_pvd(
            p,
            &self.pvd,
            &[
                format!("ncform: {} ({})", case.title, case.source),
                "time = programme fraction (0 to 1); parts: the plies, then the tools, then each ply projected on the blank plane (2D image-correlation view); units: mm, N, MPa".into(),
            ],
        )
        .map_err(|e| io_err(&path, e)));
        write_history(case, built, out, &self.history, &solved.status, files);
        let stroke_label = readout.stroke_tool.map_or_else(
            || "programme fraction".to_string(),
            |t| format!("{} displacement", built.tools[t].spec.name),
        );
        let labels = (&solved.status, stroke_label.as_str());
        write_outer_contours(
            case,
            built,
            readout,
            &self.outline_states,
            out,
            labels,
            files,
        );
        let blank_rows: Vec<BlankRow> = self
            .history
            .iter()
            .map(|h| BlankRow {
                stroke: h.stroke,
                force: readout.stroke_tool.map_or(0.0, |t| h.tools[t].force),
                lifts: h.lifts.clone(),
                draw_in: h.draw_in.clone(),
                zones: h.zones.clone(),
            })
            .collect();
        write_forming_history(case, built, readout, &blank_rows, out, labels, files);
        if let Some((result, _)) = &solved.explicit {
            write_energy(case, out, &result.records, &solved.status, files);
        }
    }

    /// The summary of the run (its exit status as the outputs so far say).
    fn summary(
        &mut self,
        case: &FormingCase,
        built: &FormingModel,
        readout: &Readout,
        solved: &Solved,
        explicit: Option<ExplicitFigures>,
        folder: &RunFolder,
    ) -> FormingSummary {
        let missing = folder.outputs().missing().to_vec();
        FormingSummary {
            case: case.source.clone(),
            title: case.title.clone(),
            complete: solved.status == RunStatus::Complete,
            exit_status: ExitStatus::of_run(&solved.status, missing.len()),
            outputs_missing: missing,
            status: solved.status.clone(),
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
                            format!("prescribed, {} mm", readable_number(displacement))
                        }
                        ToolMotion::Floating { mass, weight, .. } => {
                            format!(
                                "floating, {} kg, {} N",
                                readable_number(mass / crate::case::forming::KG_IN_T),
                                readable_number(weight)
                            )
                        }
                    };
                    format!("{} ({motion})", t.spec.name)
                })
                .collect(),
            unknowns: solved.unknowns,
            nonzeros: solved.nonzeros,
            steps: self.history.len(),
            newton_iterations: solved.newton_iterations,
            augmentations: solved.augmentations,
            explicit,
            timings: solved.timings,
            term_seconds: solved.term_seconds.clone(),
            stabilisation: solved.stabilisation,
            output_seconds: self.seconds,
            wall_seconds: self.wall.elapsed().as_secs_f64(),
            forming: FormingFigures {
                stroke_tool: readout
                    .stroke_tool
                    .map(|t| built.tools[t].spec.name.clone()),
                floating_tools: readout
                    .floating_tools
                    .iter()
                    .map(|&t| built.tools[t].spec.name.clone())
                    .collect(),
                draw_in_points: readout
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
                states: std::mem::take(&mut self.state_rows),
                deformation_modes: std::mem::take(&mut self.mode_states),
            },
            defects: {
                let states = std::mem::take(&mut self.defect_states);
                let last = built
                    .plies
                    .iter()
                    .filter_map(|ply| states.iter().rev().find(|d| d.ply == ply.name).cloned())
                    .collect();
                DefectFigures {
                    thresholds: built
                        .plies
                        .iter()
                        .zip(&case.plies)
                        .map(|(ply, spec)| (ply.name.clone(), case.defects.thresholds(spec)))
                        .collect(),
                    states,
                    last,
                }
            },
            history: std::mem::take(&mut self.history),
        }
    }
}

/// The summary's figures of an explicit run of `duration` \[s\].
fn explicit_figures(result: &ExplicitResult, duration: f64) -> ExplicitFigures {
    ExplicitFigures {
        increments: result.increments,
        duration,
        initial_critical_time_step: result.initial_critical_time_step,
        time_step_range: (result.increments > 0).then_some(result.time_step_range),
        mass: result.mass,
        max_kinetic_ratio: result.max_kinetic_ratio,
        max_relative_balance_error: result.max_relative_balance_error,
        final_energies: result.records.last().map(|r| r.energies),
        element_cycles_per_second: result.element_cycles_per_second(),
        threads: result.threads,
        term_steps: result.term_steps.clone(),
        warnings: result.warnings.clone(),
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
