//! The one runner: builds a case, drives its solver once and hands every
//! recorded state to a [`Report`] (`docs/architecture.md`).
//!
//! A recorded state is a converged quasi-static step or an explicit output
//! time. What is measured on it is computed here, once, for every report:
//! for an OAT the clamp force and the element fields with their MDZ means
//! ([`HistoryRow`]); for a forming run the tools' displacements and forces,
//! the boundaries' reactions, the probes, the stroke, the lifts, the
//! draw-in and the zone means ([`FormingRow`]).

use serde::Serialize;

use super::forming::readout::Readout;
use super::progress::Progress;
use super::rows::{FormingRow, HistoryRow, REPORTED_DISPLACEMENTS, forming_row};
use crate::case::forming::FormingCase;
use crate::case::forming_model::FormingModel;
use crate::case::{Case, OatCase, OatModel, SolverKind};
use crate::material::MaterialError;
use crate::model::Model;
use crate::post::fields::{ElementFields, area_mean, element_fields};
use crate::solver::explicit::{ExplicitError, ExplicitTimings};
use crate::solver::newton::solve_quasi_static;
use crate::solver::{
    CancelToken, DofMap, ExplicitRecord, ExplicitResult, ExplicitState, NewtonParameters,
    QuasiStaticResult, RunStatus, Snapshot, SolverTimings, solve_explicit,
};

/// A case built into a model, as the reports see it during a run.
pub enum Built<'a> {
    /// An off-axis tension test.
    Oat {
        /// The case.
        case: &'a OatCase,
        /// Its mesh, membrane, clamps, zones and MDZ.
        model: &'a OatModel,
    },
    /// A forming set-up.
    Forming {
        /// The case.
        case: &'a FormingCase,
        /// Its plies and tools (the model the solver drives is in each
        /// state's [`Snapshot`]).
        model: &'a FormingModel,
        /// What is read on the blanks.
        readout: &'a Readout,
    },
}

/// One recorded state, with what was measured on it.
pub enum Recorded<'a> {
    /// An OAT state.
    Oat {
        /// The history row: clamp displacement and force, MDZ means.
        row: &'a HistoryRow,
        /// Displacement of every dof \[mm\].
        u: &'a [f64],
        /// The fields of every element.
        fields: &'a [ElementFields],
    },
    /// An OAT state whose element fields cannot be evaluated (an element
    /// the law refuses): no row.
    OatUnreadable {
        /// The clamp displacement \[mm\].
        load: f64,
        /// The element (mesh order).
        element: usize,
        /// Why.
        error: MaterialError,
    },
    /// A forming state.
    Forming {
        /// The history row.
        row: &'a FormingRow,
        /// The solver's state: displacement, residual, model.
        snapshot: &'a Snapshot<'a>,
    },
}

/// What a run reports to: the files of a run folder, values in memory, or
/// anything else. The runner calls [`Report::begin`] once the case is
/// built, [`Report::record`] for every recorded state, and either
/// [`Report::end`] after the solve or [`Report::fail`] on a set-up error.
pub trait Report: Send {
    /// The case is built; the solve starts next. An error here stops the
    /// run before the solve (the folder could not be prepared, say).
    ///
    /// # Errors
    /// Whatever keeps the report from taking the run.
    fn begin(&mut self, built: &Built) -> Result<(), RunError>;

    /// A recorded state: a converged quasi-static step or an explicit
    /// output.
    fn record(&mut self, built: &Built, state: &Recorded);

    /// The solve ended (complete, stopped early or interrupted) with
    /// `solved`.
    fn end(&mut self, built: &Built, solved: &Solved);

    /// The run failed before or while setting up the solve.
    fn fail(&mut self, error: &RunError);
}

/// Either solver's time split \[s\].
#[derive(Debug, Clone, Copy, Serialize)]
#[serde(untagged)]
pub enum SolveTimings {
    /// Newton: symbolic, assembly, factorisation, solve.
    QuasiStatic(SolverTimings),
    /// Explicit: set-up, element and node passes, step estimates, outputs.
    Explicit(ExplicitTimings),
}

/// What the solve hands to the reports at its end.
#[derive(Debug, Clone)]
pub struct Solved {
    /// How it ended.
    pub status: RunStatus,
    /// Free unknowns.
    pub unknowns: usize,
    /// Tangent non-zeros (0 for explicit: no matrix).
    pub nonzeros: usize,
    /// Newton iterations (all attempts; 0 for explicit).
    pub newton_iterations: usize,
    /// Numeric factorisations (0 for explicit).
    pub factorisations: usize,
    /// Newton solves beyond the first per step, summed (augmentations).
    pub augmentations: usize,
    /// Time split of the solve.
    pub timings: SolveTimings,
    /// Each term's wall time \[s\]: of the assembly (quasi-static) or of
    /// the element passes (explicit).
    pub term_seconds: Vec<(String, f64)>,
    /// Quasi-static: strain energy at the end, energy dissipated by the
    /// stabilisation and its largest ratio to the strain energy
    /// \[N·mm, -\].
    pub stabilisation: Option<(f64, f64, f64)>,
    /// Quasi-static warnings (the stabilisation's dissipation).
    pub warnings: Vec<String>,
    /// The explicit run's result (records, masses, energies, warnings)
    /// and its duration \[s\].
    pub explicit: Option<(ExplicitResult, f64)>,
}

/// What [`run`] returns: the end of the solve.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// The solve's figures, as the reports saw them.
    pub solved: Solved,
}

/// Why a run could not be made. The messages are what `ncform run`
/// prints after `error: `.
#[derive(Debug, Clone, thiserror::Error)]
pub enum RunError {
    /// The case could not be built into a model (a mesh, a node set, a
    /// tool), naming the case file and the item.
    #[error("{0}")]
    Build(#[from] crate::case::BuildError),
    /// The blank's readout could not be set up (a ply without a boundary,
    /// a zone without an element), naming the case file and the item.
    #[error("{0}")]
    Readout(#[from] super::forming::readout::ReadoutError),
    /// The output folder could not be prepared, naming the path.
    #[error("{0}")]
    Folder(#[from] super::folder::FolderError),
    /// A report ended without the summary its caller asked for.
    #[error("the run ended without a summary of the kind asked for ({0})")]
    NoSummary(&'static str),
    /// The explicit OAT has no mass: `material.areal_mass` is needed.
    #[error("{source_file}: the explicit solver needs material.areal_mass")]
    NoMass {
        /// The case file.
        source_file: String,
    },
    /// The quasi-static solver could not be set up.
    #[error("{0}")]
    QuasiStatic(#[from] crate::solver::newton::QuasiStaticSetupError),
    /// The explicit solver could not start, with the case file.
    #[error("{source_file}: {error}")]
    Explicit {
        /// The case file.
        source_file: String,
        /// Why.
        error: ExplicitError,
    },
}

/// Runs `case` once with its solver, reporting to `report`; progress on
/// `progress`; stops at the solver's next safe point once `cancel` is
/// cancelled (the states up to there are reported, the run is
/// [`RunStatus::Interrupted`]).
///
/// # Errors
/// A case that cannot be built, a report that cannot begin, or a solver
/// that cannot be set up ([`Report::fail`] is called for the first and
/// the last). A solve that stops early is not an error: its status says
/// where and why.
pub fn run(
    case: &Case,
    report: &mut impl Report,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Outcome, RunError> {
    match case {
        Case::Oat(case) => run_oat(case, report, progress, cancel),
        Case::Forming(case) => run_forming(case, report, progress, cancel),
    }
}

/// `result`, with its error handed to `report` first.
fn reported<T>(report: &mut impl Report, result: Result<T, RunError>) -> Result<T, RunError> {
    if let Err(e) = &result {
        report.fail(e);
    }
    result
}

fn run_oat(
    case: &OatCase,
    report: &mut impl Report,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Outcome, RunError> {
    let built = reported(report, case.build().map_err(RunError::Build))?;
    let view = Built::Oat {
        case,
        model: &built,
    };
    report.begin(&view)?;
    let dofs = OatCase::dofs(&built);
    let mut model = case.solver_model(&built);
    let mut stops: Vec<f64> = case.output_displacements.clone();
    stops.extend(
        REPORTED_DISPLACEMENTS
            .iter()
            .filter(|d| **d <= case.displacement),
    );
    let mut recorder = OatRecorder {
        built: &built,
        view: &view,
        report,
    };
    let solved = match case.solver_kind {
        SolverKind::QuasiStatic => oat_quasi_static(
            case,
            &mut model,
            dofs,
            &stops,
            &mut recorder,
            progress,
            cancel,
        ),
        SolverKind::Explicit => oat_explicit(
            case,
            &mut model,
            &dofs,
            &stops,
            &mut recorder,
            progress,
            cancel,
        ),
    };
    progress.finish();
    let solved = reported(report, solved)?;
    report.end(&view, &solved);
    Ok(Outcome { solved })
}

/// Turns the OAT solver's states into history rows for the report.
struct OatRecorder<'a, 'b, R: Report> {
    built: &'a OatModel,
    view: &'a Built<'b>,
    report: &'a mut R,
}

impl<R: Report> OatRecorder<'_, '_, R> {
    /// Records the state `u` at clamp displacement `load` with force
    /// `reaction`; `row` fills the solver-specific columns.
    fn record(&mut self, load: f64, reaction: f64, u: &[f64], row: impl Fn(&mut HistoryRow)) {
        let built = self.built;
        let fields = match element_fields(&built.model, u) {
            Ok(f) => f,
            Err((element, error)) => {
                self.report.record(
                    self.view,
                    &Recorded::OatUnreadable {
                        load,
                        element,
                        error,
                    },
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
        self.report.record(
            self.view,
            &Recorded::Oat {
                row: &history_row,
                u,
                fields: &fields,
            },
        );
    }
}

/// The Newton parameters of a case with the run's cancel token.
fn newton_parameters(solver: &NewtonParameters, cancel: &CancelToken) -> NewtonParameters {
    NewtonParameters {
        cancel: *cancel,
        ..solver.clone()
    }
}

/// The figures of a quasi-static solve.
fn quasi_static_solved(result: QuasiStaticResult) -> Solved {
    Solved {
        status: result.status,
        unknowns: result.unknowns,
        nonzeros: result.nonzeros,
        newton_iterations: result.newton_iterations,
        factorisations: result.factorisations,
        augmentations: result.augmentations,
        timings: SolveTimings::QuasiStatic(result.timings),
        term_seconds: result.term_seconds,
        stabilisation: Some((
            result.internal_energy,
            result.stabilisation_energy,
            result.max_stabilisation_ratio,
        )),
        warnings: result.warnings,
        explicit: None,
    }
}

/// The figures of an explicit solve of `unknowns` free dofs over
/// `duration` \[s\].
fn explicit_solved(result: ExplicitResult, unknowns: usize, duration: f64) -> Solved {
    Solved {
        status: result.status.clone(),
        unknowns,
        nonzeros: 0,
        newton_iterations: 0,
        factorisations: 0,
        augmentations: 0,
        timings: SolveTimings::Explicit(result.timings),
        term_seconds: result.term_seconds.clone(),
        stabilisation: None,
        warnings: Vec::new(),
        explicit: Some((result, duration)),
    }
}

fn oat_quasi_static<R: Report>(
    case: &OatCase,
    model: &mut Model,
    dofs: DofMap,
    stops: &[f64],
    recorder: &mut OatRecorder<R>,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Solved, RunError> {
    let mut u = vec![0.0; dofs.total];
    let params = newton_parameters(&case.solver, cancel);
    let result = solve_quasi_static(
        model,
        dofs,
        &params,
        case.displacement,
        stops,
        &mut u,
        |record, snapshot| {
            let detail = format!("step {}, {} iterations", record.step, record.iterations);
            progress.update(record.load, record.reaction, &detail, case.displacement);
            recorder.record(record.load, record.reaction, snapshot.u, |row| {
                row.iterations = Some(record.iterations);
            });
        },
    )
    .map_err(RunError::QuasiStatic)?;
    Ok(quasi_static_solved(result))
}

fn oat_explicit<R: Report>(
    case: &OatCase,
    model: &mut Model,
    dofs: &DofMap,
    stops: &[f64],
    recorder: &mut OatRecorder<R>,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Solved, RunError> {
    if case.density.is_none() {
        return Err(RunError::NoMass {
            source_file: case.source.clone(),
        });
    }
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
            recorder.record(record.load, record.reaction, snapshot.u, |row| {
                row.time = Some(record.time);
                row.increments = Some(record.increment);
            });
        },
    )
    .map_err(|error| RunError::Explicit {
        source_file: case.source.clone(),
        error,
    })?;
    Ok(explicit_solved(result, dofs.n_free(), params.duration))
}

fn run_forming(
    case: &FormingCase,
    report: &mut impl Report,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Outcome, RunError> {
    let built = case.build().map_err(RunError::Build).and_then(|built| {
        Readout::new(case, &built)
            .map(|readout| (built, readout))
            .map_err(RunError::from)
    });
    let (mut built, readout) = reported(report, built)?;
    let dofs = built.dofs();
    let mut model = std::mem::replace(&mut built.model, Model::new(0));
    let view = Built::Forming {
        case,
        model: &built,
        readout: &readout,
    };
    report.begin(&view)?;
    let solved = match case.solver_kind {
        SolverKind::QuasiStatic => {
            forming_quasi_static(&view, &mut model, dofs, report, progress, cancel)
        }
        SolverKind::Explicit => {
            forming_explicit(&view, &mut model, &dofs, report, progress, cancel)
        }
    };
    progress.finish();
    let solved = reported(report, solved)?;
    report.end(&view, &solved);
    Ok(Outcome { solved })
}

/// The case, model and readout of a forming view.
fn forming_parts<'a>(view: &'a Built<'a>) -> (&'a FormingCase, &'a FormingModel, &'a Readout) {
    match view {
        Built::Forming {
            case,
            model,
            readout,
        } => (case, model, readout),
        Built::Oat { .. } => unreachable!("a forming run's view is a forming view"),
    }
}

fn forming_quasi_static(
    view: &Built,
    model: &mut Model,
    dofs: DofMap,
    report: &mut impl Report,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Solved, RunError> {
    let (case, built, readout) = forming_parts(view);
    let mut u = vec![0.0; dofs.total];
    let params = newton_parameters(&case.solver, cancel);
    let result = solve_quasi_static(
        model,
        dofs,
        &params,
        1.0,
        &case.states,
        &mut u,
        |record, snapshot| {
            let mut row = forming_row(case, built, readout, record.load, snapshot);
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
            let detail = format!(
                "step {}, {} iterations, {} augmentations",
                record.step, record.iterations, record.augmentations
            );
            progress.update(record.load, row.stroke_force(readout), &detail, 1.0);
            report.record(
                view,
                &Recorded::Forming {
                    row: &row,
                    snapshot,
                },
            );
        },
    )
    .map_err(RunError::QuasiStatic)?;
    Ok(quasi_static_solved(result))
}

fn forming_explicit(
    view: &Built,
    model: &mut Model,
    dofs: &DofMap,
    report: &mut impl Report,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Solved, RunError> {
    let (case, built, readout) = forming_parts(view);
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
        |record: &ExplicitRecord, snapshot| {
            let mut row = forming_row(case, built, readout, record.load, snapshot);
            row.time = Some(record.time);
            row.increments = Some(record.increment);
            let detail = super::explicit_progress(record);
            progress.update(record.load, row.stroke_force(readout), &detail, 1.0);
            report.record(
                view,
                &Recorded::Forming {
                    row: &row,
                    snapshot,
                },
            );
        },
    )
    .map_err(|error| RunError::Explicit {
        source_file: case.source.clone(),
        error,
    })?;
    Ok(explicit_solved(result, dofs.n_free(), params.duration))
}
