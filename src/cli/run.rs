//! `ncform run CASE [--out DIR]`: runs an off-axis tension case with the
//! quasi-static or the explicit solver and writes what a user looks at:
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

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use super::io_err;
use super::run_folder::{ExitStatus, MissingOutput, Outputs, RunFolder};

use crate::case::{ExplicitSettings, OatCase, OatModel, SolverKind};
use crate::model::Model;
use crate::post::contour::{ContourMap, write_contour_png};
use crate::post::csv::write_csv;
use crate::post::fields::{ElementFields, FieldColumns, area_mean, element_fields};
use crate::post::plot::{Panel, Series, write_panels};
use crate::post::vtu::{Field, FieldData, PvdEntry, VtuPiece, write_pvd, write_vtu};
use crate::solver::explicit::{Energies, ExplicitTimings, MassSummary};
use crate::solver::newton::solve_quasi_static;
use crate::solver::{
    CancelToken, DofMap, ExplicitRecord, ExplicitState, QuasiStaticResult, RunStatus,
    SolverTimings, solve_explicit,
};

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
    pub timings: RunTimings,
    /// The explicit run's figures (`null` for quasi-static).
    pub explicit: Option<ExplicitSummary>,
    /// Time writing outputs during and after the solve \[s\].
    pub output_seconds: f64,
    /// Wall time of the whole run \[s\].
    pub wall_seconds: f64,
    /// The step history.
    pub history: Vec<HistoryRow>,
}

/// The time split of either solver \[s\].
#[derive(Debug, Clone, Copy, Serialize)]
#[serde(untagged)]
pub enum RunTimings {
    /// Newton: symbolic, assembly, factorisation, solve.
    QuasiStatic(SolverTimings),
    /// Explicit: set-up, element and node passes, step estimates, outputs.
    Explicit(ExplicitTimings),
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
    /// Smallest and largest step taken \[s\].
    pub time_step_range: (f64, f64),
    /// Masses \[t\], with what mass scaling added.
    pub mass: MassSummary,
    /// Largest KE/IE from 10 % of the stroke on.
    pub max_kinetic_ratio: f64,
    /// Largest relative energy-balance error.
    pub max_relative_balance_error: f64,
    /// Energies at the last output [N·mm].
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
    pub edge_deviation_deg: Option<f64>,
    /// Elements in the MDZ.
    pub mdz_elements: usize,
}

const UNITS: &str = "mm, N, MPa, tonne/mm^3, s; angles in degrees";

/// How progress is shown.
pub enum Progress {
    /// A bar on a terminal; `true` for a forming programme (fraction λ).
    Bar(ProgressBar, bool),
    /// A line every tenth of the stroke (CI, pipes).
    Lines {
        /// Next load to report at.
        next: f64,
        /// `true` for a forming programme (fraction λ).
        programme: bool,
    },
    /// Nothing.
    Quiet,
}

impl Progress {
    /// A bar when stderr is a terminal, quiet lines otherwise, for an OAT
    /// of stroke `total` \[mm\].
    pub fn auto(total: f64) -> Self {
        Self::with_kind(total, false)
    }

    /// As [`Progress::auto`] for a forming programme (`λ` from 0 to 1).
    pub fn auto_programme() -> Self {
        Self::with_kind(1.0, true)
    }

    fn with_kind(total: f64, programme: bool) -> Self {
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new((total * 1000.0).round() as u64);
            let template = if programme {
                "{spinner} [{elapsed_precise}] {bar:40} λ = {msg}"
            } else {
                "{spinner} [{elapsed_precise}] {bar:40} d = {msg}"
            };
            if let Ok(style) = ProgressStyle::with_template(template) {
                bar.set_style(style);
            }
            Progress::Bar(bar, programme)
        } else {
            Progress::Lines {
                next: 0.0,
                programme,
            }
        }
    }

    /// Shows the state at load `load` (a clamp displacement [mm], or the
    /// programme fraction) with force `reaction` and a solver-specific
    /// `detail`.
    pub(crate) fn update(&mut self, load: f64, reaction: f64, detail: &str, total: f64) {
        match self {
            Progress::Bar(bar, programme) => {
                bar.set_position((load * 1000.0).round() as u64);
                if *programme {
                    bar.set_message(format!("{load:.3}, F = {reaction:.3} N, {detail}"));
                } else {
                    bar.set_message(format!("{load:.2} mm, F = {reaction:.3} N, {detail}"));
                }
            }
            Progress::Lines { next, programme } => {
                if load + 1e-9 >= *next {
                    if *programme {
                        eprintln!("λ = {load:5.3}, F = {reaction:10.4} N, {detail}");
                    } else {
                        eprintln!("d = {load:7.3} mm, F = {reaction:10.4} N, {detail}");
                    }
                    *next = load + 0.1 * total;
                }
            }
            Progress::Quiet => {}
        }
    }

    pub(crate) fn finish(&self) {
        if let Progress::Bar(bar, _) = self {
            bar.finish();
        }
    }
}

/// Writes one VTU of the deformed specimen.
fn write_state_vtu(
    path: &Path,
    case: &OatCase,
    built: &OatModel,
    u: &[f64],
    fields: &[ElementFields],
    (displacement, note): (f64, &str),
) -> Result<(), String> {
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
struct Snapshot {
    displacement: f64,
    u: Vec<f64>,
    fields: Vec<ElementFields>,
}

/// What the solvers' output callbacks feed: history rows, VTU states and
/// the contour snapshot, the same for both solvers.
struct OutputSink<'a> {
    case: &'a OatCase,
    built: &'a OatModel,
    out: PathBuf,
    files: &'a mut Outputs,
    history: Vec<HistoryRow>,
    pvd: Vec<PvdEntry>,
    snapshot: Option<Snapshot>,
    /// The last recorded state when it is not a VTU state: its
    /// displacement and `u`, written too if the run stops there.
    last: Option<(f64, Vec<f64>)>,
    seconds: f64,
    tolerance: f64,
}

impl<'a> OutputSink<'a> {
    fn new(case: &'a OatCase, built: &'a OatModel, files: &'a mut Outputs) -> Self {
        Self {
            case,
            built,
            out: files.root().to_path_buf(),
            files,
            history: Vec::new(),
            pvd: Vec::new(),
            snapshot: None,
            last: None,
            seconds: 0.0,
            tolerance: 1e-9 * case.displacement,
        }
    }

    /// Records the state `u` at clamp displacement `load` with force
    /// `reaction`; `row` fills the solver-specific columns.
    fn record(&mut self, load: f64, reaction: f64, u: &[f64], row: impl Fn(&mut HistoryRow)) {
        let start = Instant::now();
        let (case, built) = (self.case, self.built);
        let fields = match element_fields(&built.model, u) {
            Ok(f) => f,
            Err((e, err)) => {
                self.files.record_missing(
                    &format!("the state at d = {load} mm (history row, VTU, contours)"),
                    format!("element {e}: {err}"),
                );
                return;
            }
        };
        let mean =
            |f: fn(&ElementFields) -> f64| area_mean(&built.model, &built.mdz, |e| f(&fields[e]));
        let mut history_row = HistoryRow {
            displacement: load,
            force: reaction,
            mdz_e22: mean(|f| f.e22),
            mdz_shear_angle_deg: mean(|f| f.shear_angle_deg),
            mdz_e_perp: mean(|f| f.e_perp),
            iterations: None,
            time: None,
            increments: None,
        };
        row(&mut history_row);
        self.history.push(history_row);
        if case
            .output_displacements
            .iter()
            .any(|d| (d - load).abs() <= self.tolerance)
        {
            self.write_state(load, u, &fields, false);
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
            self.snapshot = Some(Snapshot {
                displacement: load,
                u: u.to_vec(),
                fields,
            });
        }
        self.seconds += start.elapsed().as_secs_f64();
    }

    /// The VTU of the state `u` at `load`, listed in the series if written:
    /// `oat_dNNN.NNN.vtu`, or with `last`, `oat_dNNN.NNN-last.vtu` marked
    /// [`super::LAST_STATE_NOTE`] in its header (its own name: the displacement of
    /// a last step shorter than 0.5 µm would print as the output state's).
    fn write_state(&mut self, load: f64, u: &[f64], fields: &[ElementFields], last: bool) {
        let (suffix, note) = if last {
            ("-last", super::LAST_STATE_NOTE)
        } else {
            ("", "")
        };
        let name = format!("oat_d{load:07.3}{suffix}.vtu");
        let path = self.out.join("vtu").join(&name);
        let written = write_state_vtu(&path, self.case, self.built, u, fields, (load, note));
        // The series lists only the states that are there.
        if self.files.record(&path, written) {
            self.pvd.push(PvdEntry {
                time: load,
                file: format!("vtu/{name}"),
                part: 0,
            });
        }
    }

    /// Writes the PVD, the histories and the contour maps, each attempted
    /// whatever became of the others; a run that stopped early first writes
    /// its last recorded state's VTU when that is not a VTU state already
    /// (`docs/cases.md`, "Incomplete runs and exit codes").
    fn finish(&mut self, status: &RunStatus, solver: SolverKind) {
        let start = Instant::now();
        if *status != RunStatus::Complete
            && let Some((load, u)) = self.last.take()
        {
            // The state was recorded, so its fields evaluate.
            if let Ok(fields) = element_fields(&self.built.model, &u) {
                self.write_state(load, &u, &fields, true);
            }
        }
        let case = self.case;
        let out = self.out.clone();
        let path = out.join("oat.pvd");
        let written = write_pvd(
            &path,
            &self.pvd,
            &[
                format!("ncform: {} ({})", case.title, case.source),
                "time = clamp displacement [mm]; units: mm, N, MPa".into(),
            ],
        )
        .map_err(|e| io_err(&path, e));
        self.files.record(&path, written);
        write_histories(case, &out, &self.history, status, solver, self.files);
        if let Some(snap) = &self.snapshot {
            let path = out.join("contours.png");
            let written = write_contours(self.built, &path, snap);
            self.files.record(&path, written);
        }
        self.seconds += start.elapsed().as_secs_f64();
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

/// What each solver hands back to the summary.
struct SolveReport {
    status: RunStatus,
    unknowns: usize,
    nonzeros: usize,
    newton_iterations: usize,
    factorisations: usize,
    timings: RunTimings,
    explicit: Option<ExplicitSummary>,
}

/// Runs a case and writes its outputs into the folder `out`, prepared
/// as a run folder after the set-up ([`RunFolder::prepare`]: an earlier
/// run moved aside, a foreign folder refused). Returns the summary; a
/// solve that stopped early is `complete = false` with its reason.
///
/// # Errors
/// Set-up failures (case, mesh, output folder) as messages naming the
/// file; nothing is written then, or `status.json` says `failed` when the
/// folder was prepared.
pub fn run_case(case: &OatCase, out: &Path, progress: Progress) -> Result<RunSummary, String> {
    run_case_with(case, out, progress, &CancelToken::default())
}

/// As [`run_case`], stopping at the solver's next safe point once `cancel`
/// is cancelled (the results up to there are written and marked
/// interrupted).
///
/// # Errors
/// As [`run_case`].
pub fn run_case_with(
    case: &OatCase,
    out: &Path,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<RunSummary, String> {
    let built = case.build().map_err(|e| e.to_string())?;
    let mut folder = RunFolder::prepare(out, &case.source, &case.title, &["vtu"])?;
    run_built(case, &built, &mut folder, progress, cancel)
}

/// As [`run_case_with`] into a folder already prepared (a test can then
/// put things in the way of the outputs).
///
/// # Errors
/// As [`run_case`]; `status.json` then says `failed`.
pub fn run_case_in(
    case: &OatCase,
    folder: &mut RunFolder,
    progress: Progress,
    cancel: &CancelToken,
) -> Result<RunSummary, String> {
    let built = folder.failed_on_error(case.build().map_err(|e| e.to_string()))?;
    run_built(case, &built, folder, progress, cancel)
}

/// The run of a built case into a prepared folder; a set-up error is
/// written to `status.json` as `failed`.
fn run_built(
    case: &OatCase,
    built: &OatModel,
    folder: &mut RunFolder,
    mut progress: Progress,
    cancel: &CancelToken,
) -> Result<RunSummary, String> {
    let wall = Instant::now();
    let dofs = OatCase::dofs(built);
    let mut model = case.solver_model(built);
    let mut stops: Vec<f64> = case.output_displacements.clone();
    stops.extend(
        REPORTED_DISPLACEMENTS
            .iter()
            .filter(|d| **d <= case.displacement),
    );
    let out = folder.path().to_path_buf();
    let mut sink = OutputSink::new(case, built, folder.outputs_mut());
    let report = match case.solver_kind {
        SolverKind::QuasiStatic => run_quasi_static(
            case,
            &mut model,
            dofs,
            &stops,
            &mut sink,
            &mut progress,
            cancel,
        ),
        SolverKind::Explicit => run_explicit(
            case,
            &mut model,
            &dofs,
            &stops,
            &mut sink,
            &mut progress,
            cancel,
        ),
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
    sink.finish(&report.status, case.solver_kind);
    if let Some(explicit) = &report.explicit {
        for warning in &explicit.warnings {
            eprintln!("warning: {warning}");
        }
    }
    let forces = sink.reported_forces();
    let steps = sink.history.len();
    let output_seconds = sink.seconds;
    let history = std::mem::take(&mut sink.history);
    let mut summary = RunSummary {
        case: case.source.clone(),
        title: case.title.clone(),
        complete: report.status == RunStatus::Complete,
        outputs_missing: folder.outputs().missing().to_vec(),
        exit_status: ExitStatus::of_run(&report.status, folder.outputs().missing().len()),
        status: report.status.clone(),
        solver: case.solver_kind,
        units: UNITS,
        material: format!("{} ({})", case.material.name, case.material.source),
        mesh: MeshSummary {
            nodes: built.mesh.nodes.len(),
            triangles: built.mesh.triangles.len(),
            unknowns: report.unknowns,
            nonzeros: report.nonzeros,
            edge_deviation_deg: built.edge_deviation_deg,
            mdz_elements: built.mdz.len(),
        },
        forces,
        steps,
        newton_iterations: report.newton_iterations,
        factorisations: report.factorisations,
        timings: report.timings,
        explicit: report.explicit,
        output_seconds,
        wall_seconds: wall.elapsed().as_secs_f64(),
        history,
    };
    let path = out.join("summary.json");
    let written = serde_json::to_string_pretty(&summary)
        .map_err(|e| io_err(&path, e))
        .and_then(|text| std::fs::write(&path, text + "\n").map_err(|e| io_err(&path, e)));
    folder.outputs_mut().record(&path, written);
    summary.exit_status = folder.finish(&report.status);
    summary.outputs_missing = folder.outputs().missing().to_vec();
    Ok(summary)
}

fn run_quasi_static(
    case: &OatCase,
    model: &mut Model,
    dofs: DofMap,
    stops: &[f64],
    sink: &mut OutputSink,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<SolveReport, String> {
    let mut u = vec![0.0; dofs.total];
    let params = crate::solver::NewtonParameters {
        cancel: *cancel,
        ..case.solver.clone()
    };
    let result: QuasiStaticResult = solve_quasi_static(
        model,
        dofs,
        &params,
        case.displacement,
        stops,
        &mut u,
        |record, snapshot| {
            let detail = format!("step {}, {} iterations", record.step, record.iterations);
            progress.update(record.load, record.reaction, &detail, case.displacement);
            sink.record(record.load, record.reaction, snapshot.u, |row| {
                row.iterations = Some(record.iterations);
            });
        },
    )?;
    Ok(SolveReport {
        status: result.status,
        unknowns: result.unknowns,
        nonzeros: result.nonzeros,
        newton_iterations: result.newton_iterations,
        factorisations: result.factorisations,
        timings: RunTimings::QuasiStatic(result.timings),
        explicit: None,
    })
}

fn run_explicit(
    case: &OatCase,
    model: &mut Model,
    dofs: &DofMap,
    stops: &[f64],
    sink: &mut OutputSink,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<SolveReport, String> {
    let density = case.density.ok_or_else(|| {
        format!(
            "{}: the explicit solver needs material.areal_mass",
            case.source
        )
    })?;
    let mut params = case.explicit.parameters();
    params.cancel = *cancel;
    let total = case.displacement;
    // History rows every `history_interval`, plus the VTU and reported
    // displacements, as times of the clamp amplitude.
    let interval = case.explicit.history_interval;
    let rows = (total / interval).round().max(1.0) as usize;
    let mut displacements: Vec<f64> = (1..=rows).map(|k| total * k as f64 / rows as f64).collect();
    displacements.extend_from_slice(stops);
    let times: Vec<f64> = displacements
        .iter()
        .map(|d| params.time_of_load_fraction(d / total))
        .collect();
    let mut state = ExplicitState::at_rest(dofs.total);
    let result = solve_explicit(
        model,
        dofs,
        &params,
        total,
        &times,
        &mut state,
        |record, snapshot| {
            let detail = super::explicit_progress(record);
            progress.update(record.load, record.reaction, &detail, total);
            sink.record(record.load, record.reaction, snapshot.u, |row| {
                row.time = Some(record.time);
                row.increments = Some(record.increment);
            });
        },
    )
    .map_err(|e| format!("{}: {e}", case.source))?;
    write_energy(case, &sink.out, &result.records, &result.status, sink.files);
    Ok(SolveReport {
        status: result.status.clone(),
        unknowns: dofs.n_free(),
        nonzeros: 0,
        newton_iterations: 0,
        factorisations: 0,
        timings: RunTimings::Explicit(result.timings),
        explicit: Some(ExplicitSummary {
            settings: case.explicit.clone(),
            density,
            increments: result.increments,
            element_cycles: result.element_cycles,
            element_cycles_per_second: result.element_cycles_per_second(),
            threads: result.threads,
            initial_critical_time_step: result.initial_critical_time_step,
            time_step_range: result.time_step_range,
            mass: result.mass,
            max_kinetic_ratio: result.max_kinetic_ratio,
            max_relative_balance_error: result.max_relative_balance_error,
            final_energies: result.records.last().map(|r| r.energies),
            warnings: result.warnings,
        }),
    })
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
    let written = write_csv(
        &path,
        &preamble(match solver {
            SolverKind::QuasiStatic => "clamp force vs clamp displacement (quasi-static)",
            SolverKind::Explicit => "clamp force vs clamp displacement (explicit dynamics)",
        }),
        &header,
        &rows,
    )
    .map_err(|e| io_err(&path, e));
    files.record(&path, written);
    let path = out.join("mdz_strains.csv");
    let written = write_csv(
        &path,
        &preamble("strains averaged over the main deformation zone (E22 = I8-1, gamma = I10, E_perp = I11-1)"),
        &["displacement [mm]", "E22 [-]", "shear_angle [deg]", "E_perp [-]"],
        &history
            .iter()
            .map(|h| vec![h.displacement, h.mdz_e22, h.mdz_shear_angle_deg, h.mdz_e_perp])
            .collect::<Vec<_>>(),
    )
    .map_err(|e| io_err(&path, e));
    files.record(&path, written);
    let series = |label: &str, f: fn(&HistoryRow) -> f64| Series {
        label: label.to_string(),
        points: std::iter::once((0.0, 0.0))
            .chain(history.iter().map(|h| (h.displacement, f(h))))
            .collect(),
    };
    let suffix = super::plot_suffix(status);
    let path = out.join("force_displacement.png");
    let written = write_panels(
        &path,
        &[Panel {
            title: format!("{}{suffix}", case.title),
            x_label: "clamp displacement [mm]".into(),
            y_label: "force [N]".into(),
            series: vec![series("force", |h| h.force)],
        }],
        (1, 1),
        (900, 650),
    );
    files.record(&path, written);
    let path = out.join("mdz_strains.png");
    let written = write_panels(
        &path,
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
    );
    files.record(&path, written);
}

/// `contours.png` at `path`.
fn write_contours(built: &OatModel, path: &Path, snap: &Snapshot) -> Result<(), String> {
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

/// The output folder for a case when none is given: `out/<case stem>`.
pub fn default_out_dir(case_path: &Path) -> PathBuf {
    let stem = case_path
        .file_stem()
        .and_then(|s| s.to_str())
        .unwrap_or("run");
    PathBuf::from("out").join(stem)
}
