//! Explicit dynamics: central differences with lumped masses.
//!
//! The membrane `M ü + α M u̇ + f_int(u) = 0` with prescribed dofs
//! `u_d = p_d λ(t)` is integrated in leapfrog form,
//!
//! ```text
//! v_{n+½} = ((1 − α h/2) v_{n−½} + h M⁻¹ (−f_int(u_n))) / (1 + α h/2),   h = (Δt_{n−½} + Δt_{n+½})/2
//! u_{n+1} = u_n + Δt_{n+½} v_{n+½}
//! ```
//!
//! with `M` lumped from the element masses `ρ t A0 / 3` per node, `Δt` a
//! safety factor times the critical step bounded element by element from the
//! current tangent (or fixed), and `λ(t)` a smooth step or a ramp. Each step
//! makes two parallel passes: the element pass writes every triangle's force
//! into its own slot; the node pass gathers each node's force from its
//! triangles in a fixed order and updates the node. Nothing is scattered,
//! so no two tasks write the same place, and every sum has a fixed order:
//! results are the same, bit for bit, for any number of threads. The time
//! loop allocates nothing. See `docs/explicit.md`.
//!
//! Energies at every output: internal `Σ t A0 W`, kinetic `½ Σ m v²` of the
//! free dofs, external work `∫ R dλ` (trapezoidal, per step) with `R` the
//! generalised reaction, damping `∫ α m v² dt`; the balance error is
//! `IE + KE + D − W − (IE + KE)₀`.

mod chains;
mod params;
mod setup_error;
pub mod step;
pub mod system;

use std::ops::ControlFlow;
use std::time::Instant;

use serde::Serialize;

pub use super::amplitude::Amplitude;
pub use params::{DEFAULT_MAX_INCREMENTS, ExplicitParameters, SettingError, TimeStepControl};
pub use setup_error::SetupError;
pub use system::{MassSummary, NODE_BLOCK};

use super::dofs::DofMap;
use super::status::{RunStatus, Snapshot};
use crate::model::{FrequencyBound, Model, State, TermEnergy, TermFailure};
pub use system::{ExplicitSystem, Update};

/// Displacement and velocity of every dof (3 per node).
#[derive(Debug, Clone, PartialEq)]
pub struct ExplicitState {
    /// Displacement `u` \[mm\].
    pub u: Vec<f64>,
    /// Velocity [mm/s]: the initial velocity on entry, the last half-step
    /// velocity `v_{n−½}` on return.
    pub v: Vec<f64>,
}

impl ExplicitState {
    /// At rest in the reference configuration.
    pub fn at_rest(dofs: usize) -> Self {
        Self {
            u: vec![0.0; dofs],
            v: vec![0.0; dofs],
        }
    }
}

/// The energies at one instant [N·mm = mJ].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct Energies {
    /// Internal (strain) energy: membranes `Σ t A0 W` and bending.
    pub internal: f64,
    /// Elastic energy stored in contact penalties and friction springs.
    pub contact: f64,
    /// Kinetic energy `½ Σ m v²` of the free dofs.
    pub kinetic: f64,
    /// Kinetic energy `½ Σ m v²` of the nodes' prescribed dofs (clamps).
    /// Not in the balance (the prescribed motion supplies it, outside the
    /// reaction's work), but part of the body's motion: counted in
    /// [`Energies::kinetic_ratio`], so that a stroke too fast for the free
    /// nodes to follow is not read as quasi-static.
    pub driven_kinetic: f64,
    /// Work done on the model: by the prescribed motions, `∫ R dλ`, and by
    /// the loads (gravity, dead loads, weights), `∫ f·du`.
    pub external_work: f64,
    /// Of `external_work`, the part done by the loads.
    pub load_work: f64,
    /// Energy dissipated by the mass-proportional damping.
    pub damping: f64,
    /// Energy dissipated by friction.
    pub friction: f64,
    /// `IE + CE + KE + D + F − W − (IE + CE + KE)₀`: zero for an exact
    /// integration.
    pub balance_error: f64,
    /// `|balance_error|` over the largest of `W`, `IE + CE + KE + D + F`
    /// and `(IE + CE + KE)₀` (zero when all vanish).
    pub relative_balance_error: f64,
}

impl Energies {
    fn balance(&mut self, initial: f64) {
        let held = self.internal + self.contact + self.kinetic + self.damping + self.friction;
        self.balance_error = held - self.external_work - initial;
        let scale = self.external_work.abs().max(held).max(initial.abs());
        self.relative_balance_error = if scale > 0.0 {
            self.balance_error.abs() / scale
        } else {
            0.0
        };
    }

    /// `KE / (IE + CE)`: the kinetic energy of every node (free and
    /// driven) over the energy stored in the model (strain and contact
    /// springs), or 0 while nothing is stored; at most
    /// [`MAX_KINETIC_RATIO`] (a denormal stored energy under a finite
    /// kinetic one would give infinity).
    pub fn kinetic_ratio(&self) -> f64 {
        let stored = self.internal + self.contact;
        if stored > 0.0 {
            ((self.kinetic + self.driven_kinetic) / stored).min(MAX_KINETIC_RATIO)
        } else {
            0.0
        }
    }
}

/// Ceiling of [`Energies::kinetic_ratio`]: far above any warning level,
/// and finite, so that summaries and CSVs never hold an infinity.
pub const MAX_KINETIC_RATIO: f64 = 1e300;

/// The state at one output instant.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ExplicitRecord {
    /// Time increments taken so far.
    pub increment: usize,
    /// Time \[s\].
    pub time: f64,
    /// Load parameter `λ(t)` (a clamp displacement, say) \[mm\].
    pub load: f64,
    /// Generalised reaction `R = Σ_d p_d f_int,d` (the clamp force) \[N\].
    pub reaction: f64,
    /// The time step in use \[s\].
    pub time_step: f64,
    /// Energies [N·mm].
    pub energies: Energies,
}

/// Wall-clock split of an explicit run \[s\].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct ExplicitTimings {
    /// Set-up: element data, adjacency, masses, mass scaling.
    pub setup: f64,
    /// Element passes (internal forces).
    pub element_pass: f64,
    /// Node passes (gather and update).
    pub node_pass: f64,
    /// Stable-step estimates.
    pub time_step_estimates: f64,
    /// Energies and reactions at outputs, and the caller's output work.
    pub outputs: f64,
}

/// Adds the terms' energies to `energies` (internal, contact, load work,
/// friction), leaving the solver's own parts.
fn add_term_energies(energies: &mut Energies, terms: TermEnergy) {
    energies.internal = terms.internal;
    energies.contact = terms.contact;
    energies.load_work = terms.external_work;
    energies.friction = terms.dissipated;
}

/// Result of an explicit run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExplicitResult {
    /// Completion.
    pub status: RunStatus,
    /// One record per output.
    pub records: Vec<ExplicitRecord>,
    /// Time increments.
    pub increments: usize,
    /// `increments × triangles` (the stencils of the model's largest term).
    pub element_cycles: u64,
    /// The estimated critical step at the start, before the safety factor \[s\].
    pub initial_critical_time_step: f64,
    /// Smallest and largest step taken \[s\] (outputs may shorten a step).
    pub time_step_range: (f64, f64),
    /// Smallest and largest stable step in use \[s\] (the safety factor
    /// times the estimates, or the fixed step): `time_step_range` without
    /// the steps shortened to land on an output.
    pub stable_step_range: (f64, f64),
    /// Steps shortened to land on an output time, and the shortest of them
    /// \[s\] (`∞` when none was).
    pub landing_steps: (usize, f64),
    /// Masses.
    pub mass: MassSummary,
    /// Largest `KE / IE` once `λ` passed 10 % of its final value.
    pub max_kinetic_ratio: f64,
    /// Largest relative energy-balance error over the outputs.
    pub max_relative_balance_error: f64,
    /// Warnings (a run that is not quasi-static, …).
    pub warnings: Vec<String>,
    /// Time split.
    pub timings: ExplicitTimings,
    /// Each term's share of the element passes: its name and wall time
    /// \[s\], in term order.
    pub term_seconds: Vec<(String, f64)>,
    /// What each term alone would allow as a step: its name and the
    /// central-difference limit `2/√ω²_t` of its own frequency bound at the
    /// start and at the last estimate \[s\] (`None`: the term bounds
    /// nothing), in term order. The step taken is the safety factor times
    /// the limit of the terms' combined bound, below the smallest of these
    /// (`docs/explicit.md`, "The stable time step").
    pub term_steps: Vec<TermStep>,
    /// rayon threads used.
    pub threads: usize,
}

/// The step a term alone would allow ([`ExplicitResult::term_steps`]).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct TermStep {
    /// The term's name.
    pub term: String,
    /// `true` when the term's stiffness is chosen from the stable step (a
    /// contact penalty at a fraction of the central-difference limit): its
    /// step follows the others' by construction and never sets it.
    pub from_step: bool,
    /// `2/√ω²_t` at the start \[s\]; left out when the term bounds nothing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub first: Option<f64>,
    /// `2/√ω²_t` at the last estimate \[s\]; left out when the term bounds
    /// nothing.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub last: Option<f64>,
}

impl ExplicitResult {
    /// Element-cycles per second over the element and node passes
    /// (`element_cycles / (element + node pass time)`; 0 before any pass).
    pub fn element_cycles_per_second(&self) -> f64 {
        let passes = self.timings.element_pass + self.timings.node_pass;
        if passes > 0.0 {
            self.element_cycles as f64 / passes
        } else {
            0.0
        }
    }
}

/// Why an explicit run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ExplicitError {
    /// A bad setting.
    #[error("explicit solver: {0}")]
    Setting(#[from] SettingError),
    /// The model cannot be integrated.
    #[error("explicit solver: {0}")]
    Setup(#[from] SetupError),
    /// A term fails at the initial state.
    #[error("explicit solver: initial state: {0}")]
    Term(#[from] TermFailure),
    /// The thread pool could not be built.
    #[error("explicit solver: cannot start the worker threads: {0}")]
    Threads(String),
    /// The run would take more increments than allowed.
    #[error(
        "explicit solver: the run needs about {estimated:.3e} increments (duration {duration:e} s over a time step of {time_step:.3e} s), more than explicit.max_increments = {limit}; raise the limit, shorten the duration, or coarsen the mesh or scale the mass for a larger step"
    )]
    TooManyIncrements {
        /// Estimated increments.
        estimated: f64,
        /// The limit.
        limit: usize,
        /// Duration of the run \[s\].
        duration: f64,
        /// The first time step \[s\].
        time_step: f64,
    },
    /// The state vectors do not match the model.
    #[error("explicit solver: state has {given} dofs, the model {expected}")]
    StateSize {
        /// Dofs of the model.
        expected: usize,
        /// Dofs of the state.
        given: usize,
    },
}

/// Buffers of the time loop, allocated once.
struct Buffers {
    forces: Vec<f64>,
    internal: Vec<f64>,
    partial: Vec<f64>,
    damping_partial: Vec<f64>,
    driven_partial: Vec<f64>,
    /// Per node block: the largest change of one displacement component
    /// in the last node pass.
    motion_partial: Vec<f64>,
}

impl Buffers {
    fn new(system: &ExplicitSystem, dofs: usize) -> Self {
        Self {
            forces: vec![0.0; system.force_len()],
            internal: vec![0.0; dofs],
            partial: vec![0.0; system.partials()],
            damping_partial: vec![0.0; system.partials()],
            driven_partial: vec![0.0; system.node_blocks()],
            motion_partial: vec![0.0; system.node_blocks()],
        }
    }
}

/// Integrates `model` from `state` over `[0, T]` with the prescribed dofs
/// of `dofs` following `λ(t) = final_load · shape(t/T)`, calling `on_output`
/// at each time of `output_times` (those in `(0, T]`, sorted; `T` is always
/// one) with the record and the state: [`set_up_explicit`] then
/// [`ExplicitSetUp::solve`].
///
/// # Errors
/// Bad settings or a model that cannot start; a run that fails on the way is
/// a result with [`RunStatus::Incomplete`] whose records stop at the last
/// output before the failure, and one stopped by `params.cancel` a result
/// with [`RunStatus::Interrupted`] whose last record is the state reached.
pub fn solve_explicit(
    model: &mut Model,
    dofs: &DofMap,
    params: &ExplicitParameters,
    final_load: f64,
    output_times: &[f64],
    state: &mut ExplicitState,
    on_output: impl FnMut(&ExplicitRecord, &Snapshot) + Send,
) -> Result<ExplicitResult, ExplicitError> {
    let set_up = set_up_explicit(model, dofs, params, final_load, output_times, state)?;
    set_up.solve(model, params, state, on_output)
}

/// The set-up stage of an explicit run, done and checked: the settings,
/// the system (masses, mass scaling, coupling chains), the terms set up
/// for it, the first stable step with the increment estimate and the
/// energies at `t = 0`, and the run's thread pool. Made by
/// [`set_up_explicit`] before anything is written, integrated by
/// [`ExplicitSetUp::solve`] on the same model and state.
pub struct ExplicitSetUp {
    pool: rayon::ThreadPool,
    stage: SetUpStage,
}

/// What [`ExplicitSetUp::estimate`] tells of a run before it starts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ExplicitEstimate {
    /// The estimated critical step at the start, before the safety factor \[s\].
    pub initial_critical_time_step: f64,
    /// The first time step in use (the safety factor times the critical
    /// step, or the fixed step) \[s\].
    pub time_step: f64,
    /// Duration of the run \[s\].
    pub duration: f64,
    /// Output times (history rows and states, `T` among them).
    pub outputs: usize,
    /// Estimated increments: `⌈duration / time_step⌉ + outputs` (one
    /// landing step per output), the figure checked against
    /// `max_increments`.
    pub increments: f64,
    /// Stencils of the model's largest term (triangles): one increment
    /// costs this many element-cycles.
    pub elements: usize,
}

impl ExplicitEstimate {
    /// `increments × elements`: the element-cycles of the run.
    pub fn element_cycles(&self) -> f64 {
        self.increments * self.elements as f64
    }
}

impl ExplicitSetUp {
    /// The work the run is expected to take, from its first stable step.
    pub fn estimate(&self) -> ExplicitEstimate {
        let stage = &self.stage;
        ExplicitEstimate {
            initial_critical_time_step: stage.initial_critical,
            time_step: stage.time_step,
            duration: stage.duration,
            outputs: stage.times.len(),
            increments: (stage.duration / stage.time_step).ceil() + stage.times.len() as f64,
            elements: stage.element_count,
        }
    }

    /// The masses of the system (with mass scaling).
    pub fn mass(&self) -> MassSummary {
        self.stage.system.mass
    }

    /// Integrates the run set up by [`set_up_explicit`]: `model`, `state`
    /// and `params` must be those it was set up with (the cancel token of
    /// `params` may differ); `on_output` as for [`solve_explicit`].
    ///
    /// # Errors
    /// A state whose size no longer matches the model
    /// ([`ExplicitError::StateSize`]); a run that fails on the way is a
    /// result, as for [`solve_explicit`].
    pub fn solve(
        self,
        model: &mut Model,
        params: &ExplicitParameters,
        state: &mut ExplicitState,
        mut on_output: impl FnMut(&ExplicitRecord, &Snapshot) + Send,
    ) -> Result<ExplicitResult, ExplicitError> {
        for given in [state.u.len(), state.v.len()] {
            if given != model.dofs() {
                return Err(ExplicitError::StateSize {
                    expected: model.dofs(),
                    given,
                });
            }
        }
        let Self { pool, stage } = self;
        pool.install(|| {
            let mut run = ExplicitRun::from_stage(stage, model, params, state);
            let status = loop {
                if let ControlFlow::Break(status) = run.increment(&mut on_output) {
                    break status;
                }
            };
            Ok(run.wind_down(status))
        })
    }
}

/// Sets an explicit run up (see [`ExplicitSetUp`]): checks the settings
/// and the inputs, puts the prescribed dofs of `state` at `λ(0)`, builds
/// the system and sets the terms of `model` up, takes the first stable
/// step and refuses a run that would take more than
/// `params.max_increments`.
///
/// # Errors
/// Bad settings or a model that cannot start, as for [`solve_explicit`].
pub fn set_up_explicit(
    model: &mut Model,
    dofs: &DofMap,
    params: &ExplicitParameters,
    final_load: f64,
    output_times: &[f64],
    state: &mut ExplicitState,
) -> Result<ExplicitSetUp, ExplicitError> {
    params.validate()?;
    // The time loop runs on a worker of its own pool: its parallel passes
    // then start without waking a sleeping caller thread every pass.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(params.threads)
        .build()
        .map_err(|e| ExplicitError::Threads(e.to_string()))?;
    let stage =
        pool.install(|| SetUpStage::new(model, dofs, params, final_load, output_times, state))?;
    Ok(ExplicitSetUp { pool, stage })
}

/// The state of the terms at displacement `u`, load and programme
/// fraction, reached by a step `time_step` [s].
fn state_at(u: &[f64], (load, load_fraction): (f64, f64)) -> State<'_> {
    State {
        load,
        load_fraction,
        ..State::at(u)
    }
}

/// `λ(t) = final_load · shape(t/T)`.
fn load_at(params: &ExplicitParameters, final_load: f64, time: f64) -> f64 {
    final_load * params.load_fraction(time)
}

/// The step in use for an estimated critical step: `safety × critical`,
/// or the fixed step.
fn stable_step(control: TimeStepControl, safety: f64, critical: f64) -> f64 {
    match control {
        TimeStepControl::Stable { .. } => safety * critical,
        TimeStepControl::Fixed { time_step } => time_step,
    }
}

/// The state vectors and the dof map have the model's size, and every
/// term can be integrated explicitly.
fn check_inputs(model: &Model, dofs: &DofMap, state: &ExplicitState) -> Result<(), ExplicitError> {
    for given in [state.u.len(), state.v.len(), dofs.total] {
        if given != model.dofs() {
            return Err(ExplicitError::StateSize {
                expected: model.dofs(),
                given,
            });
        }
    }
    for term in &model.terms {
        term.validate_explicit()?;
    }
    Ok(())
}

/// The output times: those of `output_times` in `(0, duration)`, then
/// `duration`, sorted, without repeats.
fn output_schedule(output_times: &[f64], duration: f64) -> Vec<f64> {
    let mut times: Vec<f64> = output_times
        .iter()
        .copied()
        .filter(|t| *t > 0.0 && *t < duration)
        .collect();
    times.push(duration);
    times.sort_by(f64::total_cmp);
    times.dedup();
    times
}

/// The first time step from the estimated critical step, refused when it
/// is infinite or when the run would take more than `max_increments`.
fn first_time_step(
    params: &ExplicitParameters,
    safety: f64,
    initial_critical: f64,
    outputs: usize,
) -> Result<f64, ExplicitError> {
    let time_step = stable_step(params.time_step, safety, initial_critical);
    if !time_step.is_finite() {
        return Err(ExplicitError::Setting(SettingError {
            name: "time_step",
            value: "inf".into(),
            expected: "a stiff model (the estimated critical step is infinite)",
        }));
    }
    // Work estimate: one increment per step, plus one landing per output.
    let estimated = (params.duration / time_step).ceil() + outputs as f64;
    if estimated.is_nan() || estimated > params.max_increments as f64 {
        return Err(ExplicitError::TooManyIncrements {
            estimated,
            limit: params.max_increments,
            duration: params.duration,
            time_step,
        });
    }
    Ok(time_step)
}

/// The node pass's gather with the kinetic energies at `state` (velocity
/// `v` a half step `half_step` back) into `buffers`, and the terms'
/// energies: the kinetic energy of the free and of the driven dofs, the
/// damping over the half step and the terms' energies.
fn kinetic_and_terms(
    system: &ExplicitSystem,
    model: &mut Model,
    buffers: &mut Buffers,
    damping: f64,
    state: &State,
    v: &[f64],
    half_step: f64,
) -> Result<(f64, f64, f64, TermEnergy), TermFailure> {
    system.gather_with_kinetic(
        &buffers.forces,
        state.u,
        v,
        half_step,
        damping,
        &mut buffers.internal,
        &mut buffers.partial,
        &mut buffers.damping_partial,
        &mut buffers.driven_partial,
    );
    let kinetic: f64 = buffers.partial.iter().sum();
    let driven: f64 = buffers.driven_partial.iter().sum();
    let half_step_damping: f64 = buffers.damping_partial.iter().sum();
    let mut terms = TermEnergy::default();
    for term in &mut model.terms {
        terms += term.energy(state)?;
    }
    Ok((kinetic, driven, half_step_damping, terms))
}

/// The explicit system of `model` at the start state (masses, mass
/// scaling; no damping with coupling masses), then every term set up for
/// it: terms whose stiffness follows the step (penalties) pick it from the
/// step of the others, then count in the estimate.
fn build_system(
    model: &mut Model,
    dofs: &DofMap,
    params: &ExplicitParameters,
    safety: f64,
    start: &State,
) -> Result<ExplicitSystem, ExplicitError> {
    let system = ExplicitSystem::new(
        model,
        dofs,
        params.mass_scaling_target.map(|t| (t, safety)),
        start,
    )?;
    if system.has_mass_couplings() && params.damping > 0.0 {
        return Err(ExplicitError::Setting(SettingError {
            name: "damping",
            value: crate::config::readable_number(params.damping),
            expected: "0 with coupling masses (roving mass scaling)",
        }));
    }
    let without_penalties = system.critical_time_step_of(model, start, false)?;
    for term in &mut model.terms {
        term.explicit_setup(start, &system.masses, without_penalties)?;
    }
    Ok(system)
}

/// The energies at `t = 0`, where the velocity is `v_0` itself (no half
/// step): kinetic, and the terms'.
fn initial_energies(
    system: &ExplicitSystem,
    model: &mut Model,
    buffers: &mut Buffers,
    damping: f64,
    start: &State,
    v: &[f64],
) -> Result<Energies, TermFailure> {
    let mut energies = Energies::default();
    let (kinetic, driven, _, terms) =
        kinetic_and_terms(system, model, buffers, damping, start, v, 0.0)?;
    energies.kinetic = kinetic;
    energies.driven_kinetic = driven;
    add_term_energies(&mut energies, terms);
    Ok(energies)
}

/// The working state of an explicit run: what the set-up stage
/// ([`SetUpStage`]) builds once, and the time loop's running values that
/// [`ExplicitRun::increment`] advances.
struct ExplicitRun<'a> {
    model: &'a mut Model,
    params: &'a ExplicitParameters,
    final_load: f64,
    /// The caller's displacement and velocity.
    u: &'a mut [f64],
    v: &'a mut [f64],
    system: ExplicitSystem,
    estimator: step::StepEstimator,
    buffers: Buffers,
    /// Output times in `(0, T]`, sorted, `T` last.
    times: Vec<f64>,
    /// Safety factor on the critical step (1 for a fixed step).
    safety: f64,
    /// Increments between two stable-step estimates (never, for a fixed
    /// step).
    update_interval: usize,
    initial_critical: f64,
    /// Stencils of the model's largest term.
    element_count: usize,
    /// The energies at `t = 0`: the base of every reported record.
    initial_energies: Energies,
    /// `IE + CE + KE` at `t = 0`.
    initial_energy: f64,
    /// The loads' work at `t = 0`.
    initial_load_work: f64,
    /// From this `|λ|` on, the kinetic ratio counts.
    ke_check_from: f64,
    term_seconds: Vec<f64>,
    timings: ExplicitTimings,
    /// The stable step in use.
    time_step: f64,
    time: f64,
    load: f64,
    reaction: f64,
    /// `∫ R dλ` so far.
    driven_work: f64,
    /// Damping dissipation up to `t_{n−½}`.
    damping_energy: f64,
    previous_step: f64,
    increments: usize,
    next_output: usize,
    last_output_load: f64,
    step_range: (f64, f64),
    stable_range: (f64, f64),
    landing_steps: (usize, f64),
    max_kinetic_ratio: f64,
    max_balance: f64,
    records: Vec<ExplicitRecord>,
    warnings: Vec<String>,
}

/// What the set-up stage builds once, before the time loop: the owned
/// part of an [`ExplicitRun`].
struct SetUpStage {
    final_load: f64,
    duration: f64,
    system: ExplicitSystem,
    estimator: step::StepEstimator,
    buffers: Buffers,
    times: Vec<f64>,
    safety: f64,
    update_interval: usize,
    initial_critical: f64,
    element_count: usize,
    energies: Energies,
    timings: ExplicitTimings,
    time_step: f64,
    reaction: f64,
    load: f64,
}

impl SetUpStage {
    /// Set-up stage: checks the inputs, puts the prescribed dofs at
    /// `λ(0)`, builds the system (masses, mass scaling), sets the terms
    /// up, and takes the first stable step and the energies at `t = 0`.
    fn new(
        model: &mut Model,
        dofs: &DofMap,
        params: &ExplicitParameters,
        final_load: f64,
        output_times: &[f64],
        state: &mut ExplicitState,
    ) -> Result<Self, ExplicitError> {
        let start = Instant::now();
        check_inputs(model, dofs, state)?;
        let (safety, update_interval) = match params.time_step {
            TimeStepControl::Stable {
                safety_factor,
                update_interval,
            } => (safety_factor, update_interval),
            TimeStepControl::Fixed { .. } => (1.0, usize::MAX),
        };
        let u = state.u.as_mut_slice();
        let v = state.v.as_slice();
        // Every prescribed dof at λ(0) (fixed ones at zero), whatever the
        // initial state says.
        for c in &dofs.constrained {
            u[c.dof] = c.per_unit_load * load_at(params, final_load, 0.0);
        }
        let start_state = state_at(
            u,
            (load_at(params, final_load, 0.0), params.load_fraction(0.0)),
        );
        let system = build_system(model, dofs, params, safety, &start_state)?;
        let mut buffers = Buffers::new(&system, dofs.total);
        let times = output_schedule(output_times, params.duration);
        // The set-up pass counts in the set-up time, not in the terms' shares.
        system.element_forces(
            model,
            &start_state,
            &mut buffers.forces,
            &mut vec![0.0; model.terms.len()],
        )?;
        let (estimator, initial_critical) = step::StepEstimator::new(&system, model, &start_state)?;
        let time_step = first_time_step(params, safety, initial_critical, times.len())?;
        let timings = ExplicitTimings {
            setup: start.elapsed().as_secs_f64(),
            ..Default::default()
        };
        let element_count = model
            .terms
            .iter()
            .map(|t| t.explicit_stencils().count)
            .max()
            .unwrap_or(0);
        let reaction = system.reaction(&buffers.forces);
        let energies = initial_energies(
            &system,
            model,
            &mut buffers,
            params.damping,
            &start_state,
            v,
        )?;
        Ok(Self {
            final_load,
            duration: params.duration,
            system,
            estimator,
            buffers,
            times,
            safety,
            update_interval,
            initial_critical,
            element_count,
            energies,
            timings,
            time_step,
            reaction,
            load: load_at(params, final_load, 0.0),
        })
    }
}

impl<'a> ExplicitRun<'a> {
    /// The run from its set-up stage, on the model and state it was set
    /// up with.
    fn from_stage(
        stage: SetUpStage,
        model: &'a mut Model,
        params: &'a ExplicitParameters,
        state: &'a mut ExplicitState,
    ) -> Self {
        let SetUpStage {
            final_load,
            duration: _,
            system,
            estimator,
            buffers,
            times,
            safety,
            update_interval,
            initial_critical,
            element_count,
            energies,
            timings,
            time_step,
            reaction,
            load,
        } = stage;
        let term_seconds = vec![0.0; model.terms.len()];
        Self {
            initial_energy: energies.internal + energies.contact + energies.kinetic,
            initial_load_work: energies.load_work,
            initial_energies: energies,
            records: Vec::with_capacity(times.len()),
            warnings: Vec::new(),
            time: 0.0,
            load,
            reaction,
            driven_work: 0.0,
            damping_energy: 0.0,
            previous_step: 0.0,
            increments: 0,
            next_output: 0,
            last_output_load: load,
            step_range: (f64::INFINITY, 0.0),
            stable_range: (f64::INFINITY, 0.0),
            landing_steps: (0, f64::INFINITY),
            max_kinetic_ratio: 0.0,
            max_balance: 0.0,
            ke_check_from: 0.1 * final_load.abs(),
            model,
            params,
            final_load,
            u: state.u.as_mut_slice(),
            v: state.v.as_mut_slice(),
            system,
            estimator,
            buffers,
            times,
            safety,
            update_interval,
            initial_critical,
            element_count,
            term_seconds,
            timings,
            time_step,
        }
    }

    /// Step stage, one time increment: the node pass to the next time
    /// (landing exactly on the next output time) and the element pass
    /// there, the output stage when the increment lands on an output or a
    /// stop is requested, and a new stable-step estimate every
    /// `update_interval` increments. Breaks with the run's status.
    fn increment(
        &mut self,
        on_output: &mut impl FnMut(&ExplicitRecord, &Snapshot),
    ) -> ControlFlow<RunStatus> {
        let Some(&target) = self.times.get(self.next_output) else {
            return ControlFlow::Break(RunStatus::Complete);
        };
        if self.increments >= self.params.max_increments {
            // The step shrank below the estimate made at the start.
            return ControlFlow::Break(RunStatus::Incomplete {
                load_reached: self.last_output_load,
                load_attempted: load_at(self.params, self.final_load, target),
                reason: format!(
                    "the increment limit explicit.max_increments = {} is reached at t = {:.6e} s (time step {:.3e} s)",
                    self.params.max_increments, self.time, self.time_step
                ),
            });
        }
        let (dt, lands, load_next, motion) = self.node_pass(target);
        let now = (load_next, self.params.load_fraction(self.time));
        self.element_pass(dt, motion, now)?;

        // On a stop request the state reached is output as a last record.
        let interrupted = self.params.cancel.is_cancelled();
        if lands || interrupted {
            self.output(dt, lands, now, on_output)?;
        }
        // (A stop request at the last output comes too late to stop anything.)
        if interrupted && self.next_output < self.times.len() {
            return ControlFlow::Break(RunStatus::Interrupted {
                load_reached: self.last_output_load,
            });
        }
        if self.increments.is_multiple_of(self.update_interval) {
            self.refresh_time_step(now)?;
        }
        ControlFlow::Continue(())
    }

    /// The node pass of one increment: the step `Δt` (the stable step, or
    /// what remains to the output time `target`) and every node moved to
    /// `t + Δt`, with the damping dissipated. Returns `Δt`, whether it
    /// lands on `target`, `λ(t + Δt)` and the largest displacement change.
    fn node_pass(&mut self, target: f64) -> (f64, bool, f64, f64) {
        // Land exactly on the next output time.
        let remaining = target - self.time;
        let (dt, lands) = if remaining <= self.time_step {
            (remaining, true)
        } else {
            (self.time_step, false)
        };
        let time_next = if lands { target } else { self.time + dt };
        let load_next = load_at(self.params, self.final_load, time_next);
        let clock = Instant::now();
        let motion = self.system.update(
            &self.buffers.forces,
            self.u,
            self.v,
            &mut self.buffers.partial,
            &mut self.buffers.motion_partial,
            Update {
                velocity_step: 0.5 * (self.previous_step + dt),
                time_step: dt,
                damping: self.params.damping,
                load_next,
            },
        );
        if self.params.damping > 0.0 {
            self.damping_energy += self.buffers.partial.iter().sum::<f64>();
        }
        self.timings.node_pass += clock.elapsed().as_secs_f64();
        self.time = time_next;
        self.previous_step = dt;
        self.increments += 1;
        let time_step = self.time_step;
        self.step_range = (self.step_range.0.min(dt), self.step_range.1.max(dt));
        self.stable_range = (
            self.stable_range.0.min(time_step),
            self.stable_range.1.max(time_step),
        );
        if dt < time_step {
            self.landing_steps = (self.landing_steps.0 + 1, self.landing_steps.1.min(dt));
        }
        (dt, lands, load_next, motion)
    }

    /// The element pass at the new state (`now`: its load and programme
    /// fraction, reached by a step `dt`), then the reaction and its work
    /// over the increment (trapezoidal).
    fn element_pass(&mut self, dt: f64, motion: f64, now: (f64, f64)) -> ControlFlow<RunStatus> {
        let clock = Instant::now();
        let pass = self.system.element_forces(
            self.model,
            &State {
                time_step: dt,
                motion,
                ..state_at(self.u, now)
            },
            &mut self.buffers.forces,
            &mut self.term_seconds,
        );
        self.timings.element_pass += clock.elapsed().as_secs_f64();
        let load_next = now.0;
        if let Err(failure) = pass {
            return ControlFlow::Break(RunStatus::Incomplete {
                load_reached: self.last_output_load,
                load_attempted: load_next,
                reason: format!(
                    "time increment {} (t = {:.6e} s, load {load_next:.6}): {failure}",
                    self.increments, self.time
                ),
            });
        }
        let new_reaction = self.system.reaction(&self.buffers.forces);
        self.driven_work += 0.5 * (self.reaction + new_reaction) * (load_next - self.load);
        self.reaction = new_reaction;
        self.load = load_next;
        ControlFlow::Continue(())
    }

    /// Output stage: the energies at `t_n` (the kinetic energy from the
    /// last half-step velocity, the terms', the work and dissipation so
    /// far), their checks, the record and the caller's `on_output`; `lands`
    /// says whether this is the output time (not a stop request's).
    fn output(
        &mut self,
        dt: f64,
        lands: bool,
        now: (f64, f64),
        on_output: &mut impl FnMut(&ExplicitRecord, &Snapshot),
    ) -> ControlFlow<RunStatus> {
        let clock = Instant::now();
        let parts = kinetic_and_terms(
            &self.system,
            self.model,
            &mut self.buffers,
            self.params.damping,
            &state_at(self.u, now),
            self.v,
            0.5 * dt,
        );
        let (kinetic, driven, half_step_damping, terms) = match parts {
            Ok(parts) => parts,
            Err(failure) => {
                return ControlFlow::Break(RunStatus::Incomplete {
                    load_reached: self.last_output_load,
                    load_attempted: self.load,
                    reason: format!("output at t = {:.6e} s: {failure}", self.time),
                });
            }
        };
        if !(kinetic.is_finite() && driven.is_finite()) {
            // Velocities whose ½ m v² overflows (a stroke in 1e-308 s):
            // no state worth reporting lies beyond the last output.
            return ControlFlow::Break(RunStatus::Incomplete {
                load_reached: self.last_output_load,
                load_attempted: self.load,
                reason: format!(
                    "output at t = {:.6e} s: the kinetic energy overflows (free nodes {kinetic:.3e}, driven nodes {driven:.3e} N·mm): the motion is far too fast; lower the loading speed",
                    self.time
                ),
            });
        }
        // The reported energies are at t_n: the running damping sum
        // reaches t_{n−½}, the last half step is added for the report.
        let mut reported = self.initial_energies;
        reported.kinetic = kinetic;
        reported.driven_kinetic = driven;
        add_term_energies(&mut reported, terms);
        reported.load_work -= self.initial_load_work;
        reported.external_work = self.driven_work + reported.load_work;
        reported.damping = self.damping_energy + half_step_damping;
        reported.balance(self.initial_energy);
        self.check_energies(&reported);
        let record = ExplicitRecord {
            increment: self.increments,
            time: self.time,
            load: self.load,
            reaction: self.reaction,
            time_step: self.time_step,
            energies: reported,
        };
        self.records.push(record);
        on_output(
            &record,
            &Snapshot {
                u: self.u,
                residual: &self.buffers.internal,
                model: self.model,
            },
        );
        self.last_output_load = self.load;
        self.next_output += usize::from(lands);
        self.timings.outputs += clock.elapsed().as_secs_f64();
        ControlFlow::Continue(())
    }

    /// The energy checks of an output: a warning the first time the
    /// balance error, or (from 10 % of the final load on) the kinetic
    /// ratio, passes its level; the largest of each so far.
    fn check_energies(&mut self, reported: &Energies) {
        let params = self.params;
        let (load, time) = (self.load, self.time);
        if reported.relative_balance_error > params.energy_balance_warning
            && self.max_balance <= params.energy_balance_warning
        {
            self.warnings.push(format!(
                "energy balance: the error is {} % of the largest energy at load {load:.4} (t = {time:.4e} s), above the {} % warning level; lower the time step (safety_factor) or the contact stiffness",
                percent(reported.relative_balance_error),
                percent(params.energy_balance_warning)
            ));
        }
        self.max_balance = self.max_balance.max(reported.relative_balance_error);
        if load.abs() >= self.ke_check_from && self.final_load != 0.0 {
            let ratio = reported.kinetic_ratio();
            if ratio > params.kinetic_energy_warning
                && self.max_kinetic_ratio <= params.kinetic_energy_warning
            {
                self.warnings.push(format!(
                    "not quasi-static: kinetic energy {:.3e} N·mm is {} % of the internal energy at load {load:.4} (t = {time:.4e} s), above the {} % warning level; lower the loading speed or the mass scaling",
                    reported.kinetic + reported.driven_kinetic,
                    percent(ratio),
                    percent(params.kinetic_energy_warning)
                ));
            }
            self.max_kinetic_ratio = self.max_kinetic_ratio.max(ratio);
        }
    }

    /// A new stable-step estimate at the state reached (`now`: its load
    /// and programme fraction).
    fn refresh_time_step(&mut self, now: (f64, f64)) -> ControlFlow<RunStatus> {
        let clock = Instant::now();
        match self
            .estimator
            .estimate(&self.system, self.model, &state_at(self.u, now))
        {
            Ok(critical) => {
                self.time_step = stable_step(self.params.time_step, self.safety, critical);
            }
            Err(failure) => {
                return ControlFlow::Break(RunStatus::Incomplete {
                    load_reached: self.last_output_load,
                    load_attempted: self.load,
                    reason: format!("stable-step estimate at t = {:.6e} s: {failure}", self.time),
                });
            }
        }
        self.timings.time_step_estimates += clock.elapsed().as_secs_f64();
        ControlFlow::Continue(())
    }

    /// Wind-down stage: a warning for every term whose frequency bound
    /// grew past its margin between refreshes, and the result.
    fn wind_down(mut self, status: RunStatus) -> ExplicitResult {
        for (term, growth) in self.model.terms.iter().zip(self.estimator.growth()) {
            if growth.count > 0 {
                self.warnings.push(format!(
                    "stable-step estimate: the frequency bound of '{}' grew {} time(s) past {} times its last refreshed value between refreshes (at most {:.2} times; refreshed every {} estimates, docs/explicit.md \"The stable time step\"): the step may have left the safety factor's margin; lower time_step_update_interval",
                    term.name(),
                    growth.count,
                    step::STALE_MARGIN,
                    growth.largest_ratio,
                    step::REFRESH_EVERY,
                ));
            }
        }
        let increments = self.increments;
        let limit =
            |b: &FrequencyBound| Some(system::critical_step(b.total())).filter(|s| s.is_finite());
        let term_steps = self
            .model
            .terms
            .iter()
            .zip(self.estimator.first_and_last())
            .map(|(term, (first, last))| TermStep {
                term: term.name().to_string(),
                from_step: term.stiffness_from_time_step(),
                first: limit(first),
                last: limit(last),
            })
            .collect();
        ExplicitResult {
            status,
            records: self.records,
            increments,
            element_cycles: increments as u64 * self.element_count as u64,
            initial_critical_time_step: self.initial_critical,
            time_step_range: if increments > 0 {
                self.step_range
            } else {
                (0.0, 0.0)
            },
            stable_step_range: if increments > 0 {
                self.stable_range
            } else {
                (0.0, 0.0)
            },
            landing_steps: self.landing_steps,
            mass: self.system.mass,
            max_kinetic_ratio: self.max_kinetic_ratio,
            max_relative_balance_error: self.max_balance,
            warnings: self.warnings,
            timings: self.timings,
            term_seconds: self
                .model
                .terms
                .iter()
                .map(|t| t.name().to_string())
                .zip(self.term_seconds)
                .collect(),
            term_steps,
            threads: rayon::current_num_threads(),
        }
    }
}

/// A fraction as a percentage for a warning: two decimals, or three
/// significant digits in exponent form below 0.01 % and beyond a million
/// per cent (an exploding run's ratio is not written out in 32 digits, a
/// tiny warning level not as 0.00).
fn percent(fraction: f64) -> String {
    let p = 100.0 * fraction;
    if p == 0.0 || (0.01..1e6).contains(&p.abs()) {
        format!("{p:.2}")
    } else {
        format!("{p:.3e}")
    }
}
