//! `ncform run CASE [--out DIR]`: runs an off-axis tension case with the
//! quasi-static solver and writes what a user looks at:
//!
//! - `force_displacement.csv` / `.png`: clamp force vs displacement;
//! - `mdz_strains.csv` / `.png`: E22, γ, E⊥ averaged over the MDZ;
//! - `vtu/*.vtu` and `oat.pvd`: the deformed specimen with per-element
//!   fields at the output displacements, for ParaView;
//! - `contours.png`: E22, γ, E⊥ on the deformed specimen (paper Fig. 4);
//! - `summary.json`: forces, steps, iterations, time split, completion.
//!
//! A solve that fails keeps everything up to the last converged step and
//! marks it incomplete.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Instant;

use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::case::{OatCase, OatModel};
use crate::post::contour::{ContourMap, write_contour_png};
use crate::post::csv::write_csv;
use crate::post::fields::{ElementFields, area_mean, element_fields};
use crate::post::plot::{Panel, Series, write_panels};
use crate::post::vtu::{Field, FieldData, PvdEntry, VtuPiece, write_pvd, write_vtu};
use crate::solver::newton::solve_quasi_static;
use crate::solver::{QuasiStaticResult, RunStatus, SolverTimings, StepRecord};

/// Displacements whose forces the summary always reports [mm].
pub const REPORTED_DISPLACEMENTS: [f64; 4] = [20.0, 40.0, 60.0, 80.0];

/// One row of the history: a converged step with its MDZ averages.
#[derive(Debug, Clone, Serialize)]
pub struct HistoryRow {
    /// Clamp displacement [mm].
    pub displacement: f64,
    /// Clamp force [N].
    pub force: f64,
    /// MDZ mean of E22.
    pub mdz_e22: f64,
    /// MDZ mean of γ [deg].
    pub mdz_shear_angle_deg: f64,
    /// MDZ mean of E⊥.
    pub mdz_e_perp: f64,
    /// Newton iterations of the step.
    pub iterations: usize,
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
    /// Completion details (reason when incomplete).
    pub status: RunStatus,
    /// Units of every number here.
    pub units: &'static str,
    /// Material set name and source.
    pub material: String,
    /// Nodes, triangles, unknowns, non-zeros.
    pub mesh: MeshSummary,
    /// `(displacement [mm], force [N])` at 20/40/60/80 mm (those reached).
    pub forces: Vec<(f64, f64)>,
    /// Converged steps.
    pub steps: usize,
    /// Newton iterations (all attempts).
    pub newton_iterations: usize,
    /// Numeric factorisations.
    pub factorisations: usize,
    /// Time split of the solve [s].
    pub timings: SolverTimings,
    /// Time writing outputs during and after the solve [s].
    pub output_seconds: f64,
    /// Wall time of the whole run [s].
    pub wall_seconds: f64,
    /// The step history.
    pub history: Vec<HistoryRow>,
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
    /// Tangent non-zeros.
    pub nonzeros: usize,
    /// Largest roving-to-edge angle [deg] (generated meshes).
    pub edge_deviation_deg: Option<f64>,
    /// Elements in the MDZ.
    pub mdz_elements: usize,
}

const UNITS: &str = "mm, N, MPa, tonne/mm^3, s; angles in degrees";

/// How progress is shown.
pub enum Progress {
    /// A bar on a terminal.
    Bar(ProgressBar),
    /// A line every tenth of the stroke (CI, pipes).
    Lines {
        /// Next displacement to report at.
        next: f64,
    },
    /// Nothing.
    Quiet,
}

impl Progress {
    /// A bar when stderr is a terminal, quiet lines otherwise.
    pub fn auto(total: f64) -> Self {
        if std::io::stderr().is_terminal() {
            let bar = ProgressBar::new((total * 1000.0).round() as u64);
            bar.set_style(
                ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:40} d = {msg}")
                    .expect("valid template"),
            );
            Progress::Bar(bar)
        } else {
            Progress::Lines { next: 0.0 }
        }
    }

    fn update(&mut self, record: &StepRecord, total: f64) {
        match self {
            Progress::Bar(bar) => {
                bar.set_position((record.load * 1000.0).round() as u64);
                bar.set_message(format!(
                    "{:.2} mm, F = {:.3} N, step {}, {} it",
                    record.load, record.reaction, record.step, record.iterations
                ));
            }
            Progress::Lines { next } => {
                if record.load + 1e-9 >= *next {
                    eprintln!(
                        "step {:4}: d = {:7.3} mm, F = {:10.4} N, {} iterations",
                        record.step, record.load, record.reaction, record.iterations
                    );
                    *next = record.load + 0.1 * total;
                }
            }
            Progress::Quiet => {}
        }
    }

    fn finish(&self) {
        if let Progress::Bar(bar) = self {
            bar.finish();
        }
    }
}

fn io_err(path: &Path, e: impl std::fmt::Display) -> String {
    format!("{}: {e}", path.display())
}

/// Writes one VTU of the deformed specimen.
fn write_state_vtu(
    path: &Path,
    case: &OatCase,
    built: &OatModel,
    u: &[f64],
    fields: &[ElementFields],
    displacement: f64,
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
    let column = |f: fn(&ElementFields) -> f64| fields.iter().map(f).collect::<Vec<f64>>();
    let e22 = column(|f| f.e22);
    let gamma = column(|f| f.shear_angle_deg);
    let e_perp = column(|f| f.e_perp);
    let i4 = column(|f| f.i4);
    let i6 = column(|f| f.i6);
    let i8 = column(|f| f.i8);
    let i11 = column(|f| f.i11);
    let k11 = column(|f| f.k11);
    let w = column(|f| f.energy_density);
    let stress: Vec<[f64; 3]> = fields.iter().map(|f| f.stress_xy).collect();
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
        cell_fields: vec![
            Field { name: "E22", data: FieldData::Scalar(&e22) },
            Field { name: "shear_angle_deg", data: FieldData::Scalar(&gamma) },
            Field { name: "E_perp", data: FieldData::Scalar(&e_perp) },
            Field { name: "I4", data: FieldData::Scalar(&i4) },
            Field { name: "I6", data: FieldData::Scalar(&i6) },
            Field { name: "I8", data: FieldData::Scalar(&i8) },
            Field { name: "I11", data: FieldData::Scalar(&i11) },
            Field { name: "k11", data: FieldData::Scalar(&k11) },
            Field { name: "energy_density", data: FieldData::Scalar(&w) },
            Field { name: "S", data: FieldData::SymTensor2(&stress) },
            Field { name: "zone", data: FieldData::Int(&zone) },
            Field { name: "mdz", data: FieldData::Int(&in_mdz) },
        ],
        comment: vec![
            format!("ncform: {} ({})", case.title, case.source),
            format!("clamp displacement {displacement} mm"),
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

/// Runs a case and writes its outputs into `out`. Returns the summary; a
/// solve that stopped early is `complete = false` with its reason.
///
/// # Errors
/// Set-up failures (case, mesh) and I/O errors, as messages naming the file.
pub fn run_case(case: &OatCase, out: &Path, mut progress: Progress) -> Result<RunSummary, String> {
    let wall = Instant::now();
    let built = case.build()?;
    std::fs::create_dir_all(out.join("vtu")).map_err(|e| io_err(out, e))?;
    let dofs = OatCase::dofs(&built);
    let mut u = vec![0.0; dofs.total];
    let mut stops: Vec<f64> = case.output_displacements.clone();
    stops.extend(
        REPORTED_DISPLACEMENTS
            .iter()
            .filter(|d| **d <= case.displacement),
    );
    let mut history: Vec<HistoryRow> = Vec::new();
    let mut pvd: Vec<PvdEntry> = Vec::new();
    let mut output_seconds = 0.0;
    let mut io_error: Option<String> = None;
    let mut snapshot: Option<Snapshot> = None;
    let tolerance = 1e-9 * case.displacement;

    let result: QuasiStaticResult = solve_quasi_static(
        &built.model,
        dofs,
        true,
        &case.solver,
        case.displacement,
        &stops,
        &mut u,
        |record, u| {
            let start = Instant::now();
            progress.update(record, case.displacement);
            let fields = match element_fields(&built.model, u) {
                Ok(f) => f,
                Err((e, err)) => {
                    io_error.get_or_insert(format!("element {e}: {err}"));
                    return;
                }
            };
            let mean = |f: fn(&ElementFields) -> f64| {
                area_mean(&built.model, &built.mdz, |e| f(&fields[e]))
            };
            history.push(HistoryRow {
                displacement: record.load,
                force: record.reaction,
                mdz_e22: mean(|f| f.e22),
                mdz_shear_angle_deg: mean(|f| f.shear_angle_deg),
                mdz_e_perp: mean(|f| f.e_perp),
                iterations: record.iterations,
            });
            if case
                .output_displacements
                .iter()
                .any(|d| (d - record.load).abs() <= tolerance)
            {
                let name = format!("oat_d{:07.3}.vtu", record.load);
                let path = out.join("vtu").join(&name);
                if let Err(e) = write_state_vtu(&path, case, &built, u, &fields, record.load) {
                    io_error.get_or_insert(e);
                }
                pvd.push(PvdEntry {
                    time: record.load,
                    file: format!("vtu/{name}"),
                });
            }
            if record.load <= case.contour_displacement + tolerance {
                snapshot = Some(Snapshot {
                    displacement: record.load,
                    u: u.to_vec(),
                    fields,
                });
            }
            output_seconds += start.elapsed().as_secs_f64();
        },
    )?;
    progress.finish();
    if let Some(e) = io_error {
        return Err(e);
    }
    let start = Instant::now();
    write_pvd(
        &out.join("oat.pvd"),
        &pvd,
        &[
            format!("ncform: {} ({})", case.title, case.source),
            "time = clamp displacement [mm]; units: mm, N, MPa".into(),
        ],
    )
    .map_err(|e| io_err(&out.join("oat.pvd"), e))?;
    write_histories(case, out, &history, &result.status)?;
    if let Some(snap) = &snapshot {
        write_contours(&built, out, snap)?;
    }
    output_seconds += start.elapsed().as_secs_f64();

    let forces = REPORTED_DISPLACEMENTS
        .iter()
        .filter_map(|d| {
            history
                .iter()
                .find(|h| (h.displacement - d).abs() <= tolerance)
                .map(|h| (*d, h.force))
        })
        .collect();
    let summary = RunSummary {
        case: case.source.clone(),
        title: case.title.clone(),
        complete: result.status == RunStatus::Complete,
        status: result.status.clone(),
        units: UNITS,
        material: format!("{} ({})", case.material.name, case.material.source),
        mesh: MeshSummary {
            nodes: built.mesh.nodes.len(),
            triangles: built.mesh.triangles.len(),
            unknowns: result.unknowns,
            nonzeros: result.nonzeros,
            edge_deviation_deg: built.edge_deviation_deg,
            mdz_elements: built.mdz.len(),
        },
        forces,
        steps: result.steps.len(),
        newton_iterations: result.newton_iterations,
        factorisations: result.factorisations,
        timings: result.timings,
        output_seconds,
        wall_seconds: wall.elapsed().as_secs_f64(),
        history,
    };
    let path = out.join("summary.json");
    let text = serde_json::to_string_pretty(&summary).map_err(|e| io_err(&path, e))?;
    std::fs::write(&path, text + "\n").map_err(|e| io_err(&path, e))?;
    Ok(summary)
}

fn status_line(status: &RunStatus) -> String {
    match status {
        RunStatus::Complete => "status: complete".to_string(),
        RunStatus::Incomplete {
            load_reached,
            load_attempted,
            reason,
        } => format!(
            "status: INCOMPLETE - stopped at d = {load_reached} mm; the step to {load_attempted} mm failed: {reason}"
        ),
    }
}

fn write_histories(
    case: &OatCase,
    out: &Path,
    history: &[HistoryRow],
    status: &RunStatus,
) -> Result<(), String> {
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
    write_csv(
        &path,
        &preamble("clamp force vs clamp displacement"),
        &["displacement [mm]", "force [N]", "iterations [-]"],
        &history
            .iter()
            .map(|h| vec![h.displacement, h.force, h.iterations as f64])
            .collect::<Vec<_>>(),
    )
    .map_err(|e| io_err(&path, e))?;
    let path = out.join("mdz_strains.csv");
    write_csv(
        &path,
        &preamble("strains averaged over the main deformation zone (E22 = I8-1, gamma = I10, E_perp = I11-1)"),
        &["displacement [mm]", "E22 [-]", "shear_angle [deg]", "E_perp [-]"],
        &history
            .iter()
            .map(|h| vec![h.displacement, h.mdz_e22, h.mdz_shear_angle_deg, h.mdz_e_perp])
            .collect::<Vec<_>>(),
    )
    .map_err(|e| io_err(&path, e))?;
    let series = |label: &str, f: fn(&HistoryRow) -> f64| Series {
        label: label.to_string(),
        points: std::iter::once((0.0, 0.0))
            .chain(history.iter().map(|h| (h.displacement, f(h))))
            .collect(),
    };
    let suffix = if matches!(status, RunStatus::Complete) {
        ""
    } else {
        " (INCOMPLETE)"
    };
    write_panels(
        &out.join("force_displacement.png"),
        &[Panel {
            title: format!("{}{suffix}", case.title),
            x_label: "clamp displacement [mm]".into(),
            y_label: "force [N]".into(),
            series: vec![series("force", |h| h.force)],
        }],
        (1, 1),
        (900, 650),
    )?;
    write_panels(
        &out.join("mdz_strains.png"),
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
}

fn write_contours(built: &OatModel, out: &Path, snap: &Snapshot) -> Result<(), String> {
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
    write_contour_png(&out.join("contours.png"), &maps, (1800, 1100))
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
