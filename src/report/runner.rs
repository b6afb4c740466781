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

use super::estimate::SolverEstimate;
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
use crate::solver::newton::{
    ConvergedTangent, StepRecord, check_quasi_static, solve_quasi_static,
    solve_quasi_static_observed,
};
use crate::solver::{
    CancelToken, DofMap, ExplicitParameters, ExplicitRecord, ExplicitResult, ExplicitSetUp,
    ExplicitState, NewtonParameters, QuasiStaticResult, RunStatus, Snapshot, SolverTimings,
    set_up_explicit,
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
/// built and its solver set up ([`prepare`]), [`Report::record`] for every
/// recorded state, and either [`Report::end`] after the solve or
/// [`Report::fail`] on a set-up error (before `begin` when the case cannot
/// be built or set up).
pub trait Report: Send {
    /// The case is built and its solver set up; the solve starts next. An
    /// error here stops the run before the solve (the folder could not be
    /// prepared, say).
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

    /// Whether [`Report::tangent`] is wanted: the converged tangent at
    /// every step of a quasi-static OAT, at the cost of one assembly and
    /// one factorisation per step. Default: no.
    fn wants_tangent(&self) -> bool {
        false
    }

    /// At every converged step of a quasi-static OAT (after
    /// [`Report::record`]), when [`Report::wants_tangent`]: the step, the
    /// state and the tangent there, factorised, for sensitivities by direct
    /// differentiation (`docs/fit.md`).
    fn tangent(
        &mut self,
        _built: &Built,
        _step: &StepRecord,
        _snapshot: &Snapshot,
        _tangent: &mut ConvergedTangent,
    ) {
    }
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
    /// The explicit solver could not start, with the case file and which
    /// of its keys to change.
    #[error("{source_file}: {error}{hint}")]
    Explicit {
        /// The case file.
        source_file: String,
        /// Why (boxed: the variant stays small).
        error: Box<ExplicitError>,
        /// `; change …`: the case keys that set what failed (empty when
        /// no key does), from [`explicit_hint`].
        hint: String,
    },
}

impl RunError {
    /// The explicit solver's set-up `error` on the case `case`, with the
    /// hint of the keys to change.
    pub fn explicit(case: &Case, error: ExplicitError) -> Self {
        Self::explicit_of(case.source(), &ply_names(case), error)
    }

    /// [`RunError::explicit`] of a case file `source` whose plies are
    /// `plies` (none for an OAT).
    fn explicit_of(source: &str, plies: &[&str], error: ExplicitError) -> Self {
        let hint = explicit_hint(&error, plies).map_or_else(String::new, |h| format!("; {h}"));
        Self::Explicit {
            source_file: source.to_string(),
            error: Box::new(error),
            hint,
        }
    }
}

/// The plies of a case (none for an OAT).
fn ply_names(case: &Case) -> Vec<&str> {
    match case {
        Case::Oat(_) => Vec::new(),
        Case::Forming(c) => c.plies.iter().map(|p| p.name.as_str()).collect(),
    }
}

/// Which case keys set what made the explicit solver's set-up fail, for a
/// case whose plies are `plies` (none for an OAT): chosen from the error's
/// kind and the failing term's name (`membrane of <ply>`, `bending of
/// <ply>`, `contact with <tool>`, `contact of <ply> with <ply or tool>`:
/// the names the forming build gives them; `membrane`, `bending` of the
/// only ply, or of an OAT), or `None` when no key does.
pub fn explicit_hint(error: &ExplicitError, plies: &[&str]) -> Option<String> {
    use crate::solver::explicit::SetupError;
    match error {
        ExplicitError::Setting(setting) => Some(format!(
            "change explicit.{} (docs/cases.md, \"[explicit]\")",
            setting.name
        )),
        ExplicitError::TooManyIncrements { .. } => Some(
            "the keys: explicit.max_increments; explicit.duration or explicit.clamp_speed; explicit.time_step or explicit.safety_factor; explicit.mass_scaling_time_step, explicit.roving_mass_length; the plies' mesh element_size"
                .to_string(),
        ),
        ExplicitError::Term(failure) | ExplicitError::Setup(SetupError::Term(failure)) => {
            Some(term_hint(&failure.term, plies))
        }
        ExplicitError::Setup(SetupError::MassCoupling { .. }) => Some(
            "change the roving mass scaling: explicit.roving_mass_length, explicit.roving_mass_coupling (or explicit.mass_scaling_time_step)"
                .to_string(),
        ),
        ExplicitError::Setup(SetupError::MasslessNode { .. }) => Some(
            "give every node a triangle or hold it: the ply's mesh, or a [[boundary]] on the node"
                .to_string(),
        ),
        ExplicitError::Setup(SetupError::MasslessExtra { .. }) => {
            Some("give the floating tool a mass: [[tool]] mass or weight".to_string())
        }
        ExplicitError::Threads(_) => Some("change explicit.threads".to_string()),
        ExplicitError::StateSize { .. } => None,
    }
}

/// The keys that set the term `term` of a model whose plies are `plies`.
fn term_hint(term: &str, plies: &[&str]) -> String {
    let ply = match term {
        "membrane" | "bending" => plies.first().copied(),
        _ => term
            .strip_prefix("membrane of ")
            .or_else(|| term.strip_prefix("bending of ")),
    };
    if let Some(ply) = ply {
        return format!(
            "change the mass or stiffness of ply \"{ply}\": [[ply]] areal_mass, thickness or params (its parameter file), or explicit.mass_scaling_time_step"
        );
    }
    if term.starts_with("contact") {
        return format!(
            "change the settings of \"{term}\": [contact] offset, explicit_stiffness or explicit_pressure_stiffness, explicit_damping (and the plies' areal_mass, explicit.mass_scaling_time_step; [[ply_contact]] skin for ply-ply contact)"
        );
    }
    if term == "membrane" {
        return "change [material] areal_mass, thickness or params (its parameter file), or explicit.mass_scaling_time_step".to_string();
    }
    format!("change the settings of {term}")
}

/// The view of a prepared case that the reports get.
fn view_of<'a>(case: &'a Case, built: &'a PreparedModel) -> Built<'a> {
    match (built, case) {
        (PreparedModel::Oat(model), Case::Oat(case)) => Built::Oat { case, model },
        (PreparedModel::Forming(model, readout), Case::Forming(case)) => Built::Forming {
            case,
            model,
            readout,
        },
        _ => unreachable!("a prepared model is of its case's scenario"),
    }
}

/// A case made ready for its solve, with nothing written yet: built into
/// a model, its readout set up, and every check of the solver's set-up
/// passed (for the explicit solver the whole set-up stage, with its first
/// stable step and increment estimate; for the quasi-static one the dof
/// map and the linear solver). Made by [`prepare`], solved by
/// [`Prepared::solve`].
pub struct Prepared<'c> {
    case: &'c Case,
    built: PreparedModel,
    /// The model the solver drives (taken out of the built model).
    model: Model,
    dofs: DofMap,
    stage: Stage,
}

/// The built model of either scenario.
enum PreparedModel {
    Oat(Box<OatModel>),
    Forming(Box<FormingModel>, Box<Readout>),
}

/// The solver's part of a prepared run.
enum Stage {
    QuasiStatic {
        params: NewtonParameters,
        final_load: f64,
        stops: Vec<f64>,
    },
    Explicit {
        params: Box<ExplicitParameters>,
        set_up: Box<ExplicitSetUp>,
        state: ExplicitState,
        final_load: f64,
    },
}

impl Prepared<'_> {
    /// The case.
    pub fn case(&self) -> &Case {
        self.case
    }

    /// What the solver expects the run to take.
    pub fn solver_estimate(&self) -> SolverEstimate {
        match &self.stage {
            Stage::Explicit { set_up, .. } => SolverEstimate::Explicit(set_up.estimate()),
            Stage::QuasiStatic {
                params,
                final_load,
                stops,
            } => {
                let steps = |increment: f64| {
                    let n = (final_load / increment).ceil();
                    if n.is_finite() {
                        n as usize
                    } else {
                        usize::MAX
                    }
                };
                SolverEstimate::QuasiStatic {
                    min_steps: steps(params.max_increment).max(stops.len()),
                    initial_steps: steps(params.initial_increment).max(stops.len()),
                    unknowns: self.dofs.n_free(),
                }
            }
        }
    }

    /// The run's estimate: the solver's work, a rough run time and the
    /// size of the outputs ([`super::estimate`]).
    pub fn estimate(&self) -> super::estimate::Estimate {
        let (nodes, elements, plies, tools, ply_contacts) = match (&self.built, self.case) {
            (PreparedModel::Oat(m), _) => (m.mesh.nodes.len(), m.mesh.triangles.len(), 0, 0, 0),
            (PreparedModel::Forming(m, _), case) => (
                m.plies.iter().map(|p| p.mesh.nodes.len()).sum(),
                m.plies.iter().map(|p| p.mesh.triangles.len()).sum(),
                m.plies.len(),
                m.tools.len(),
                match case {
                    Case::Forming(c) => c.ply_contacts.len(),
                    Case::Oat(_) => 0,
                },
            ),
        };
        super::estimate::Estimate::new(
            self.case,
            self.solver_estimate(),
            super::estimate::ModelSize {
                nodes,
                elements,
                plies,
                tools,
                ply_contacts,
                terms: self.model.terms.len(),
            },
        )
    }

    /// Begins `report` (the folder is prepared there) and solves, handing
    /// every recorded state to `report`; progress on `progress`; stops at
    /// the solver's next safe point once `cancel` is cancelled.
    ///
    /// # Errors
    /// A report that cannot begin, or a solver that cannot finish its
    /// set-up (the quasi-static symbolic factorisation): [`Report::fail`]
    /// is called for the latter.
    pub fn solve(
        self,
        report: &mut impl Report,
        progress: &mut Progress,
        cancel: &CancelToken,
    ) -> Result<Outcome, RunError> {
        let Prepared {
            case,
            built,
            mut model,
            dofs,
            stage,
        } = self;
        let view = view_of(case, &built);
        report.begin(&view)?;
        let solved = match &view {
            Built::Oat { case, model: built } => {
                let mut recorder = OatRecorder {
                    built,
                    view: &view,
                    report,
                };
                solve_oat(
                    case,
                    &mut model,
                    dofs,
                    stage,
                    &mut recorder,
                    progress,
                    cancel,
                )
            }
            Built::Forming { .. } => {
                solve_forming(&view, &mut model, dofs, stage, report, progress, cancel)
            }
        };
        progress.finish();
        let solved = reported(report, solved)?;
        report.end(&view, &solved);
        Ok(Outcome { solved })
    }
}

/// Prepares `case` for its solve without writing anything: builds it,
/// sets its readout up and runs every check of its solver's set-up (see
/// [`Prepared`]), so that a case that cannot run fails here, before a run
/// folder is touched.
///
/// # Errors
/// A case that cannot be built, a readout that cannot be set up, a solver
/// that cannot be set up ([`RunError::Explicit`] with a hint naming the
/// case key to change, [`RunError::QuasiStatic`], [`RunError::NoMass`]).
pub fn prepare(case: &Case) -> Result<Prepared<'_>, RunError> {
    match case {
        Case::Oat(oat) => {
            let built = oat.build().map_err(RunError::Build)?;
            let dofs = OatCase::dofs(&built);
            let mut model = oat.solver_model(&built);
            let stage = match oat.solver_kind {
                SolverKind::QuasiStatic => {
                    let mut stops: Vec<f64> = oat.output_displacements.clone();
                    stops.extend(
                        REPORTED_DISPLACEMENTS
                            .iter()
                            .filter(|d| **d <= oat.displacement),
                    );
                    quasi_static_stage(&model, &dofs, &oat.solver, oat.displacement, stops)?
                }
                SolverKind::Explicit => {
                    if oat.density.is_none() {
                        return Err(RunError::NoMass {
                            source_file: oat.source.clone(),
                        });
                    }
                    let params = oat.explicit.parameters();
                    let total = oat.displacement;
                    // History rows every `history_interval`, plus the VTU
                    // and reported displacements, as times of the clamp
                    // amplitude.
                    let interval = oat.explicit.history_interval;
                    let rows = (total / interval).round().max(1.0) as usize;
                    let mut displacements: Vec<f64> =
                        (1..=rows).map(|k| total * k as f64 / rows as f64).collect();
                    displacements.extend_from_slice(&oat.output_displacements);
                    displacements.extend(REPORTED_DISPLACEMENTS.iter().filter(|d| **d <= total));
                    let times: Vec<f64> = displacements
                        .iter()
                        .map(|d| params.time_of_load_fraction(d / total))
                        .collect();
                    explicit_stage(case, &mut model, &dofs, params, total, &times)?
                }
            };
            Ok(Prepared {
                case,
                built: PreparedModel::Oat(Box::new(built)),
                model,
                dofs,
                stage,
            })
        }
        Case::Forming(forming) => {
            let mut built = forming.build().map_err(RunError::Build)?;
            let readout = Readout::new(forming, &built)?;
            let dofs = built.dofs();
            let mut model = std::mem::replace(&mut built.model, Model::new(0));
            let stage = match forming.solver_kind {
                SolverKind::QuasiStatic => {
                    quasi_static_stage(&model, &dofs, &forming.solver, 1.0, forming.states.clone())?
                }
                SolverKind::Explicit => {
                    let params = forming.explicit.parameters();
                    let rows = forming.history_rows;
                    let mut fractions: Vec<f64> =
                        (1..=rows).map(|k| k as f64 / rows as f64).collect();
                    fractions.extend_from_slice(&forming.states);
                    let times: Vec<f64> = fractions
                        .iter()
                        .map(|f| params.time_of_load_fraction(*f))
                        .collect();
                    explicit_stage(case, &mut model, &dofs, params, 1.0, &times)?
                }
            };
            Ok(Prepared {
                case,
                built: PreparedModel::Forming(Box::new(built), Box::new(readout)),
                model,
                dofs,
                stage,
            })
        }
    }
}

/// The quasi-static stage after its checks.
fn quasi_static_stage(
    model: &Model,
    dofs: &DofMap,
    params: &NewtonParameters,
    final_load: f64,
    stops: Vec<f64>,
) -> Result<Stage, RunError> {
    check_quasi_static(model, dofs, params, &vec![0.0; dofs.total])?;
    Ok(Stage::QuasiStatic {
        params: params.clone(),
        final_load,
        stops,
    })
}

/// The explicit stage: the solver's set-up stage done on `model`, its
/// error with the case file and the key to change.
fn explicit_stage(
    case: &Case,
    model: &mut Model,
    dofs: &DofMap,
    params: ExplicitParameters,
    final_load: f64,
    times: &[f64],
) -> Result<Stage, RunError> {
    let mut state = ExplicitState::at_rest(dofs.total);
    let set_up = set_up_explicit(model, dofs, &params, final_load, times, &mut state)
        .map_err(|error| RunError::explicit(case, error))?;
    Ok(Stage::Explicit {
        params: Box::new(params),
        set_up: Box::new(set_up),
        state,
        final_load,
    })
}

/// Runs `case` once with its solver, reporting to `report`; progress on
/// `progress`; stops at the solver's next safe point once `cancel` is
/// cancelled (the states up to there are reported, the run is
/// [`RunStatus::Interrupted`]): [`prepare`], then [`Prepared::solve`].
/// Every set-up check runs before [`Report::begin`], so a case that
/// cannot run leaves an output folder as it was.
///
/// # Errors
/// A case that cannot be built or its solver set up ([`Report::fail`] is
/// called, before [`Report::begin`]), a report that cannot begin. A
/// solve that stops early is not an error: its status says where and why.
pub fn run(
    case: &Case,
    report: &mut impl Report,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Outcome, RunError> {
    let prepared = reported(report, prepare(case))?;
    prepared.solve(report, progress, cancel)
}

/// `result`, with its error handed to `report` first.
fn reported<T>(report: &mut impl Report, result: Result<T, RunError>) -> Result<T, RunError> {
    if let Err(e) = &result {
        report.fail(e);
    }
    result
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

/// Solves a prepared OAT.
fn solve_oat<R: Report>(
    case: &OatCase,
    model: &mut Model,
    dofs: DofMap,
    stage: Stage,
    recorder: &mut OatRecorder<R>,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Solved, RunError> {
    match stage {
        Stage::QuasiStatic {
            params,
            final_load,
            stops,
        } => {
            let mut u = vec![0.0; dofs.total];
            let params = newton_parameters(&params, cancel);
            let with_tangent = recorder.report.wants_tangent();
            let result = solve_quasi_static_observed(
                model,
                dofs,
                &params,
                final_load,
                &stops,
                &mut u,
                with_tangent,
                |record, snapshot, tangent| {
                    let detail = format!("step {}, {} iterations", record.step, record.iterations);
                    progress.update(record.load, record.reaction, &detail, final_load);
                    recorder.record(record.load, record.reaction, snapshot.u, |row| {
                        row.iterations = Some(record.iterations);
                    });
                    if let Some(tangent) = tangent {
                        recorder
                            .report
                            .tangent(recorder.view, record, snapshot, tangent);
                    }
                },
            )
            .map_err(RunError::QuasiStatic)?;
            Ok(quasi_static_solved(result))
        }
        Stage::Explicit {
            mut params,
            set_up,
            mut state,
            final_load,
        } => {
            params.cancel = *cancel;
            let result = set_up
                .solve(model, &params, &mut state, |record, snapshot| {
                    let detail = super::explicit_progress(record);
                    progress.update(record.load, record.reaction, &detail, final_load);
                    recorder.record(record.load, record.reaction, snapshot.u, |row| {
                        row.time = Some(record.time);
                        row.increments = Some(record.increment);
                    });
                })
                .map_err(|error| RunError::explicit_of(&case.source, &[], error))?;
            Ok(explicit_solved(result, dofs.n_free(), params.duration))
        }
    }
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

/// Solves a prepared forming case.
fn solve_forming(
    view: &Built,
    model: &mut Model,
    dofs: DofMap,
    stage: Stage,
    report: &mut impl Report,
    progress: &mut Progress,
    cancel: &CancelToken,
) -> Result<Solved, RunError> {
    let (case, built, readout) = forming_parts(view);
    match stage {
        Stage::QuasiStatic {
            params,
            final_load,
            stops,
        } => {
            let mut u = vec![0.0; dofs.total];
            let params = newton_parameters(&params, cancel);
            let result = solve_quasi_static(
                model,
                dofs,
                &params,
                final_load,
                &stops,
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
        Stage::Explicit {
            mut params,
            set_up,
            mut state,
            final_load: _,
        } => {
            params.cancel = *cancel;
            let result = set_up
                .solve(
                    model,
                    &params,
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
                .map_err(|error| {
                    let plies: Vec<&str> = case.plies.iter().map(|p| p.name.as_str()).collect();
                    RunError::explicit_of(&case.source, &plies, error)
                })?;
            Ok(explicit_solved(result, dofs.n_free(), params.duration))
        }
    }
}
