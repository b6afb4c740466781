//! The files of an off-axis tension test's run folder
//! (`docs/cases.md`, "Outputs"):
//!
//! - `force_displacement.csv` / `.png`: clamp force vs displacement;
//! - `mdz_strains.csv` / `.png`: E22, γ, E⊥ averaged over the MDZ;
//! - `vtu/*.vtu` and `oat.pvd`: the deformed specimen with per-element
//!   fields at the output displacements, for ParaView;
//! - `contours.png`: E22, γ, E⊥ on the deformed specimen (paper Fig. 4);
//! - `summary.json`: forces, steps, iterations, time split, completion;
//! - `energy.csv` / `.png` (explicit): internal, kinetic, external work,
//!   damping and the energy balance error.
//!
//! A solve that fails keeps everything up to the last converged step (or
//! output) and marks it incomplete.

use std::path::{Path, PathBuf};
use std::time::Instant;

use serde::Serialize;

use super::folder::{ExitStatus, MissingOutput, Outputs, RunFolder};
use super::rows::{HistoryRow, REPORTED_DISPLACEMENTS};
use super::runner::{Recorded, SolveTimings, Solved};
use super::{UNITS, io_err};

use crate::case::{ExplicitSettings, OatCase, OatModel, SolverKind};
use crate::post::contour::{ContourMap, write_contour_png};
use crate::post::csv::write_csv;
use crate::post::fields::{ElementFields, FieldColumns, element_fields};
use crate::post::plot::{Panel, PlotError, Series, write_panels};
use crate::post::vtu::{Field, FieldData, PvdEntry, VtuPiece, write_pvd, write_vtu};
use crate::solver::explicit::{Energies, MassSummary};
use crate::solver::{ExplicitRecord, RunStatus};

/// The JSON summary of a run.
#[derive(Debug, Clone, Serialize)]
pub struct RunSummary {
    /// Case file.
    pub case: String,
    /// Case title.
    pub title: String,
    /// `true` when the final displacement was reached.
    pub complete: bool,
    /// Completion details (reason when incomplete, load reached when
    /// interrupted).
    pub status: RunStatus,
    /// The outputs written before this summary that could not be written
    /// (`status.json` has the final list).
    pub outputs_missing: Vec<MissingOutput>,
    /// How the command ends (`docs/cases.md`, "Exit codes").
    pub exit_status: ExitStatus,
    /// The solver that ran.
    pub solver: SolverKind,
    /// Units of every number here.
    pub units: &'static str,
    /// Material set name and source.
    pub material: String,
    /// Nodes, triangles, unknowns, non-zeros.
    pub mesh: MeshSummary,
    /// `(displacement [mm], force [N])` at 20/40/60/80 mm (those reached).
    pub forces: Vec<(f64, f64)>,
    /// History rows: converged steps (quasi-static) or outputs (explicit).
    pub steps: usize,
    /// Newton iterations (all attempts; 0 for explicit).
    pub newton_iterations: usize,
    /// Numeric factorisations (0 for explicit).
    pub factorisations: usize,
    /// Time split of the solve \[s\].
    pub timings: SolveTimings,
    /// The explicit run's figures (`null` for quasi-static).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub explicit: Option<ExplicitSummary>,
    /// Time writing outputs during and after the solve \[s\].
    pub output_seconds: f64,
    /// Wall time of the whole run \[s\].
    pub wall_seconds: f64,
    /// The step history.
    pub history: Vec<HistoryRow>,
}

/// What an explicit run reports besides the common outputs.
#[derive(Debug, Clone, Serialize)]
pub struct ExplicitSummary {
    /// The settings used.
    pub settings: ExplicitSettings,
    /// Density [t/mm³].
    pub density: f64,
    /// Time increments.
    pub increments: usize,
    /// `increments × triangles`.
    pub element_cycles: u64,
    /// Element cycles per second of the element and node passes.
    pub element_cycles_per_second: f64,
    /// Worker threads.
    pub threads: usize,
    /// Estimated critical step at the start, before the safety factor \[s\].
    pub initial_critical_time_step: f64,
    /// Smallest and largest step taken \[s\] (left out when the run took
    /// no increment).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub time_step_range: Option<(f64, f64)>,
    /// Masses \[t\], with what mass scaling added.
    pub mass: MassSummary,
    /// Largest KE/IE from 10 % of the stroke on.
    pub max_kinetic_ratio: f64,
    /// Largest relative energy-balance error.
    pub max_relative_balance_error: f64,
    /// Energies at the last output [N·mm].
    #[serde(skip_serializing_if = "Option::is_none")]
    pub final_energies: Option<Energies>,
    /// Warnings (not quasi-static, …).
    pub warnings: Vec<String>,
}

/// Mesh size figures.
#[derive(Debug, Clone, Serialize)]
pub struct MeshSummary {
    /// Nodes.
    pub nodes: usize,
    /// Triangles.
    pub triangles: usize,
    /// Free unknowns.
    pub unknowns: usize,
    /// Tangent non-zeros (0 for explicit: no matrix).
    pub nonzeros: usize,
    /// Largest roving-to-edge angle \[deg\] (generated meshes).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub edge_deviation_deg: Option<f64>,
    /// Elements in the MDZ.
    pub mdz_elements: usize,
}

/// Writes one VTU of the deformed specimen.
fn write_state_vtu(
    path: &Path,
    case: &OatCase,
    built: &OatModel,
    u: &[f64],
    fields: &[ElementFields],
    (displacement, note): (f64, &str),
) -> Result<(), crate::report::WriteError> {
    let mesh = &built.mesh;
    let points: Vec<[f64; 3]> = mesh
        .nodes
        .iter()
        .enumerate()
        .map(|(n, x)| [x.x + u[3 * n], x.y + u[3 * n + 1], x.z + u[3 * n + 2]])
        .collect();
    let displacement_field: Vec<[f64; 3]> = (0..mesh.nodes.len())
        .map(|n| [u[3 * n], u[3 * n + 1], u[3 * n + 2]])
        .collect();
    let columns = FieldColumns::new(fields);
    let zone: Vec<i32> = built.zones.iter().map(|z| z.index()).collect();
    let mut in_mdz = vec![0; mesh.triangles.len()];
    for &e in &built.mdz {
        in_mdz[e] = 1;
    }
    let piece = VtuPiece {
        points: &points,
        triangles: &mesh.triangles,
        point_fields: vec![Field {
            name: "displacement",
            data: FieldData::Vector3(&displacement_field),
        }],
        cell_fields: {
            let mut fields = columns.cell_fields();
            fields.push(Field { name: "zone", data: FieldData::Int(&zone) });
            fields.push(Field { name: "mdz", data: FieldData::Int(&in_mdz) });
            fields
        },
        comment: vec![
            format!("ncform: {} ({})", case.title, case.source),
            format!("clamp displacement {displacement} mm{note}"),
            "units: mm, N, MPa; shear_angle_deg in degrees; E22 = I8-1, E_perp = I11-1 (paper Section 4)".into(),
            "S: second Piola-Kirchhoff stress [MPa] in global x-y axes (xx, yy, xy); zone: 0 = A, 1 = B, 2 = C; mdz: 1 in the main deformation zone".into(),
        ],
    };
    write_vtu(path, &piece).map_err(|e| io_err(path, e))
}

/// The state kept for the contour pictures.
struct ContourState {
    displacement: f64,
    u: Vec<f64>,
    fields: Vec<ElementFields>,
}

/// The files of an OAT's run folder, written as the states come: VTU
/// states during the solve; the series, the histories, the contours, the
/// energies and the summary at its end.
pub struct OatFiles {
    out: PathBuf,
    history: Vec<HistoryRow>,
    pvd: Vec<PvdEntry>,
    contour: Option<ContourState>,
    /// The last recorded state when it is not a VTU state: its
    /// displacement and `u`, written too if the run stops there.
    last: Option<(f64, Vec<f64>)>,
    seconds: f64,
    tolerance: f64,
    wall: Instant,
}

impl OatFiles {
    /// The writer of `case`'s outputs into the folder `out` (prepared).
    pub fn new(case: &OatCase, out: &Path) -> Self {
        Self {
            out: out.to_path_buf(),
            history: Vec::new(),
            pvd: Vec::new(),
            contour: None,
            last: None,
            seconds: 0.0,
            tolerance: 1e-9 * case.displacement,
            wall: Instant::now(),
        }
    }

    /// Takes a recorded state: its history row, its VTU at an output
    /// displacement (else it is kept as the last state), its contour
    /// snapshot; a state whose fields cannot be evaluated is recorded as
    /// a missing output.
    pub fn record(
        &mut self,
        case: &OatCase,
        built: &OatModel,
        state: &Recorded,
        files: &mut Outputs,
    ) {
        let start = Instant::now();
        match state {
            Recorded::Oat { row, u, fields } => {
                let load = row.displacement;
                self.history.push((*row).clone());
                if case
                    .output_displacements
                    .iter()
                    .any(|d| (d - load).abs() <= self.tolerance)
                {
                    self.write_state(case, built, (load, u, fields), false, files);
                    self.last = None;
                } else {
                    match &mut self.last {
                        Some((d, kept)) if kept.len() == u.len() => {
                            *d = load;
                            kept.copy_from_slice(u);
                        }
                        last => *last = Some((load, u.to_vec())),
                    }
                }
                if load <= case.contour_displacement + self.tolerance {
                    self.contour = Some(ContourState {
                        displacement: load,
                        u: u.to_vec(),
                        fields: fields.to_vec(),
                    });
                }
            }
            Recorded::OatUnreadable {
                load,
                element,
                error,
            } => files.record_missing(
                &format!("the state at d = {load} mm (history row, VTU, contours)"),
                format!("element {element}: {error}"),
            ),
            Recorded::Forming { .. } => {}
        }
        self.seconds += start.elapsed().as_secs_f64();
    }

    /// The VTU of the state `u` at `load`, listed in the series if written:
    /// `oat_dNNN.NNN.vtu`, or with `last`, `oat_dNNN.NNN-last.vtu` marked
    /// [`super::LAST_STATE_NOTE`] in its header (its own name: the
    /// displacement of a last step shorter than 0.5 µm would print as the
    /// output state's).
    fn write_state(
        &mut self,
        case: &OatCase,
        built: &OatModel,
        (load, u, fields): (f64, &[f64], &[ElementFields]),
        last: bool,
        files: &mut Outputs,
    ) {
        let (suffix, note) = if last {
            ("-last", super::LAST_STATE_NOTE)
        } else {
            ("", "")
        };
        let name = format!("oat_d{load:07.3}{suffix}.vtu");
        let path = self.out.join("vtu").join(&name);
        // The series lists only the states that are there.
        if files.write(&path, |p| {
            write_state_vtu(p, case, built, u, fields, (load, note))
        }) {
            self.pvd.push(PvdEntry {
                time: load,
                file: format!("vtu/{name}"),
                part: 0,
            });
        }
    }

    /// Writes what comes at the end of the solve, each file attempted
    /// whatever became of the others: the energies (explicit), the last
    /// recorded state's VTU when the run stopped early and it is not a VTU
    /// state already (`docs/cases.md`, "Incomplete runs and exit codes"),
    /// the series, the histories, the contours; then the summary, and
    /// `status.json` with the exit status. Returns the summary.
    pub fn finish(
        &mut self,
        case: &OatCase,
        built: &OatModel,
        solved: &Solved,
        folder: &mut RunFolder,
    ) -> RunSummary {
        let explicit = solved
            .explicit
            .as_ref()
            .map(|(result, _)| explicit_summary(case, result));
        if let Some((result, _)) = &solved.explicit {
            let out = self.out.clone();
            write_energy(
                case,
                &out,
                &result.records,
                &solved.status,
                folder.outputs_mut(),
            );
        }
        self.write_end_files(case, built, &solved.status, folder.outputs_mut());
        if let Some(explicit) = &explicit {
            for warning in &explicit.warnings {
                eprintln!("warning: {warning}");
            }
        }
        let mut summary = self.summary(case, built, solved, explicit, folder);
        let path = self.out.join("summary.json");
        folder.outputs_mut().write_json(&path, &summary);
        summary.exit_status = folder.finish(&solved.status);
        summary.outputs_missing = folder.outputs().missing().to_vec();
        summary
    }

    /// The last state (when the run stopped early), the series, the
    /// histories and the contours.
    fn write_end_files(
        &mut self,
        case: &OatCase,
        built: &OatModel,
        status: &RunStatus,
        files: &mut Outputs,
    ) {
        let start = Instant::now();
        if *status != RunStatus::Complete
            && let Some((load, u)) = self.last.take()
        {
            // The state was recorded, so its fields evaluate.
            if let Ok(fields) = element_fields(&built.model, &u) {
                self.write_state(case, built, (load, &u, &fields), true, files);
            }
        }
        let out = self.out.clone();
        let path = out.join("oat.pvd");
        files.write(&path, |p| {
            write_pvd(
                p,
                &self.pvd,
                &[
                    format!("ncform: {} ({})", case.title, case.source),
                    "time = clamp displacement [mm]; units: mm, N, MPa".into(),
                ],
            )
            .map_err(|e| io_err(&path, e))
        });
        write_histories(case, &out, &self.history, status, case.solver_kind, files);
        if let Some(snap) = &self.contour {
            let path = out.join("contours.png");
            files.write(&path, |p| write_contours(built, p, snap));
        }
        self.seconds += start.elapsed().as_secs_f64();
    }

    /// The summary of the run (its exit status as the outputs so far say).
    fn summary(
        &mut self,
        case: &OatCase,
        built: &OatModel,
        solved: &Solved,
        explicit: Option<ExplicitSummary>,
        folder: &RunFolder,
    ) -> RunSummary {
        let missing = folder.outputs().missing();
        RunSummary {
            case: case.source.clone(),
            title: case.title.clone(),
            complete: solved.status == RunStatus::Complete,
            outputs_missing: missing.to_vec(),
            exit_status: ExitStatus::of_run(&solved.status, missing.len()),
            status: solved.status.clone(),
            solver: case.solver_kind,
            units: UNITS,
            material: format!("{} ({})", case.material.name, case.material.source),
            mesh: MeshSummary {
                nodes: built.mesh.nodes.len(),
                triangles: built.mesh.triangles.len(),
                unknowns: solved.unknowns,
                nonzeros: solved.nonzeros,
                edge_deviation_deg: built.edge_deviation_deg,
                mdz_elements: built.mdz.len(),
            },
            forces: self.reported_forces(),
            steps: self.history.len(),
            newton_iterations: solved.newton_iterations,
            factorisations: solved.factorisations,
            timings: solved.timings,
            explicit,
            output_seconds: self.seconds,
            wall_seconds: self.wall.elapsed().as_secs_f64(),
            history: std::mem::take(&mut self.history),
        }
    }

    /// Forces at the reported displacements that were reached.
    fn reported_forces(&self) -> Vec<(f64, f64)> {
        REPORTED_DISPLACEMENTS
            .iter()
            .filter_map(|d| {
                self.history
                    .iter()
                    .find(|h| (h.displacement - d).abs() <= self.tolerance)
                    .map(|h| (*d, h.force))
            })
            .collect()
    }
}

/// The summary's figures of an explicit run.
fn explicit_summary(case: &OatCase, result: &crate::solver::ExplicitResult) -> ExplicitSummary {
    ExplicitSummary {
        settings: case.explicit.clone(),
        // The runner refuses an explicit OAT without a density.
        density: case.density.unwrap_or(0.0),
        increments: result.increments,
        element_cycles: result.element_cycles,
        element_cycles_per_second: result.element_cycles_per_second(),
        threads: result.threads,
        initial_critical_time_step: result.initial_critical_time_step,
        time_step_range: (result.increments > 0).then_some(result.time_step_range),
        mass: result.mass,
        max_kinetic_ratio: result.max_kinetic_ratio,
        max_relative_balance_error: result.max_relative_balance_error,
        final_energies: result.records.last().map(|r| r.energies),
        warnings: result.warnings.clone(),
    }
}

/// `energy.csv` and `energy.png`: the energy history of an explicit run.
fn write_energy(
    case: &OatCase,
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
            "balance error = internal + kinetic + damping - external work - initial energy; relative to the largest of those".to_string(),
            format!("units: {UNITS}; energies in N*mm (= mJ)"),
        ],
        records,
        status,
        &super::energy::EnergyAxis {
            header: "displacement [mm]",
            label: "clamp displacement [mm]",
            value: |r| r.load,
        },
        false,
        files,
    );
}

/// The status line of the file headers, in clamp displacements.
fn status_line(status: &RunStatus) -> String {
    super::status_line(status, |d| format!("d = {d} mm"), |d| format!("{d} mm"))
}

fn write_histories(
    case: &OatCase,
    out: &Path,
    history: &[HistoryRow],
    status: &RunStatus,
    solver: SolverKind,
    files: &mut Outputs,
) {
    let preamble = |what: &str| {
        vec![
            format!("ncform run: {what}"),
            format!("case: {} ({})", case.title, case.source),
            format!(
                "material: {} ({})",
                case.material.name, case.material.source
            ),
            status_line(status),
            format!("units: {UNITS}"),
        ]
    };
    let path = out.join("force_displacement.csv");
    let (header, rows): (Vec<&str>, Vec<Vec<f64>>) = match solver {
        SolverKind::QuasiStatic => (
            vec!["displacement [mm]", "force [N]", "iterations [-]"],
            history
                .iter()
                .map(|h| vec![h.displacement, h.force, h.iterations.unwrap_or(0) as f64])
                .collect(),
        ),
        SolverKind::Explicit => (
            vec![
                "displacement [mm]",
                "force [N]",
                "time [s]",
                "increments [-]",
            ],
            history
                .iter()
                .map(|h| {
                    vec![
                        h.displacement,
                        h.force,
                        h.time.unwrap_or(0.0),
                        h.increments.unwrap_or(0) as f64,
                    ]
                })
                .collect(),
        ),
    };
    files.write(&path, |p| {
        write_csv(
            p,
            &preamble(match solver {
                SolverKind::QuasiStatic => "clamp force vs clamp displacement (quasi-static)",
                SolverKind::Explicit => "clamp force vs clamp displacement (explicit dynamics)",
            }),
            &header,
            &rows,
        )
        .map_err(|e| io_err(&path, e))
    });
    let path = out.join("mdz_strains.csv");
    files.write(&path, |p| write_csv(
        p,
        &preamble("strains averaged over the main deformation zone (E22 = I8-1, gamma = I10, E_perp = I11-1)"),
        &["displacement [mm]", "E22 [-]", "shear_angle [deg]", "E_perp [-]"],
        &history
            .iter()
            .map(|h| vec![h.displacement, h.mdz_e22, h.mdz_shear_angle_deg, h.mdz_e_perp])
            .collect::<Vec<_>>(),
    )
    .map_err(|e| io_err(&path, e)));
    let series = |label: &str, f: fn(&HistoryRow) -> f64| Series {
        label: label.to_string(),
        points: std::iter::once((0.0, 0.0))
            .chain(history.iter().map(|h| (h.displacement, f(h))))
            .collect(),
    };
    let suffix = super::plot_suffix(status);
    let path = out.join("force_displacement.png");
    files.write(&path, |p| {
        write_panels(
            p,
            &[Panel {
                title: format!("{}{suffix}", case.title),
                x_label: "clamp displacement [mm]".into(),
                y_label: "force [N]".into(),
                series: vec![series("force", |h| h.force)],
            }],
            (1, 1),
            (900, 650),
        )
    });
    let path = out.join("mdz_strains.png");
    files.write(&path, |p| {
        write_panels(
            p,
            &[
                Panel {
                    title: format!("MDZ E22{suffix}"),
                    x_label: "clamp displacement [mm]".into(),
                    y_label: "E22 = I8 - 1 [-]".into(),
                    series: vec![series("E22", |h| h.mdz_e22)],
                },
                Panel {
                    title: "MDZ shear angle".into(),
                    x_label: "clamp displacement [mm]".into(),
                    y_label: "shear angle [deg]".into(),
                    series: vec![series("gamma", |h| h.mdz_shear_angle_deg)],
                },
                Panel {
                    title: "MDZ E_perp".into(),
                    x_label: "clamp displacement [mm]".into(),
                    y_label: "E_perp = I11 - 1 [-]".into(),
                    series: vec![series("E_perp", |h| h.mdz_e_perp)],
                },
            ],
            (1, 3),
            (1800, 550),
        )
    });
}

/// `contours.png` at `path`.
fn write_contours(built: &OatModel, path: &Path, snap: &ContourState) -> Result<(), PlotError> {
    let points: Vec<[f64; 2]> = built
        .mesh
        .nodes
        .iter()
        .enumerate()
        .map(|(n, x)| [x.x + snap.u[3 * n], x.y + snap.u[3 * n + 1]])
        .collect();
    // Clamp-corner elements carry singular strains; a 0.5–99.5 % percentile
    // range keeps them from washing out the map (they saturate instead).
    type Pick = fn(&ElementFields) -> f64;
    let quantities: [(&str, &str, Pick); 3] = [
        ("E22", "E22 = I8 - 1 [-]", |f| f.e22),
        ("shear angle", "shear angle [deg]", |f| f.shear_angle_deg),
        ("E_perp", "E_perp = I11 - 1 [-]", |f| f.e_perp),
    ];
    let values: Vec<Vec<f64>> = quantities
        .iter()
        .map(|(_, _, pick)| snap.fields.iter().map(pick).collect())
        .collect();
    let maps: Vec<ContourMap> = quantities
        .iter()
        .zip(&values)
        .map(|((name, label, _), v)| ContourMap {
            title: format!("{name} at d = {} mm", snap.displacement),
            points: &points,
            triangles: &built.mesh.triangles,
            values: v,
            label: format!("{label} (0.5-99.5 % range)"),
            range: percentile_range(v, 0.005),
        })
        .collect();
    write_contour_png(path, &maps, (1800, 1100))
}

/// The `[q, 1 − q]` quantiles of the finite values, or `None` when they are
/// all equal (the writer then picks a range).
pub fn percentile_range(values: &[f64], q: f64) -> Option<(f64, f64)> {
    let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    if sorted.is_empty() {
        return None;
    }
    sorted.sort_by(f64::total_cmp);
    let at = |p: f64| sorted[((sorted.len() - 1) as f64 * p).round() as usize];
    let (lo, hi) = (at(q), at(1.0 - q));
    (hi > lo).then_some((lo, hi))
}
