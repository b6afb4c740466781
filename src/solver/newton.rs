//! Quasi-static Newton solver with line search and adaptive load stepping.
//!
//! The load parameter `λ` scales the Dirichlet conditions
//! (`u[dof] = w λ`). Each step solves `r(u) = 0` on the free dofs, where `r`
//! is the internal force (no external loads), with the consistent tangent
//! factorised by faer. Globalisation:
//!
//! 1. the full Newton step is taken if the residual along the direction
//!    drops enough (`|r(u+du)·du| ≤ η |r(u)·du|`) or its norm decreases;
//! 2. otherwise a line search on `g(α) = r(u + α du)·du` (bisection with
//!    secant steps, within `[α_min, 1]`), which is the derivative of the
//!    energy along the direction;
//! 3. if `du` is not a descent direction of the energy (the tangent is
//!    indefinite where the k11 coupling softens), the tangent is shifted,
//!    `K + μ diag(K)`, with `μ` raised tenfold until it is (a
//!    Levenberg–Marquardt trust region);
//! 4. a step that does not converge in `max_iterations`, or meets an
//!    inverted or collapsed element, is cut back; easy steps grow again.
//!
//! Convergence: `‖r_free‖ ≤ max(residual_tolerance · ‖r_constrained‖,
//! force_floor)` (relative to the reaction forces, with an absolute floor)
//! and
//! `|du·r| ≤ energy_tolerance · |du₀·r₀|` (energy norm, relative to the
//! step's first iteration).
//!
//! Terms with multipliers (augmented-Lagrangian contact) are augmented
//! between Newton solves at the same load (Uzawa): after each converged
//! solve every such term updates its multipliers and says whether its
//! constraints hold to its tolerances; if not, Newton solves again from the
//! converged state, up to `max_augmentations` times. A step is accepted
//! when the residual, the gap and the change of the multipliers all pass;
//! the terms then commit their history (friction references). A failed
//! step restores the history of the last accepted step.
//!
//! Optionally a viscous (pseudo-dynamic) stabilisation adds
//! `(c/Δλ) M (u − u_n)` to the residual of the free dofs, with `c` fixed
//! or chosen from a target dissipation rate; its dissipated energy and the
//! model's internal energy are reported per step (`docs/solver.md`,
//! "Stabilisation"). Optionally the free dofs carry their inertia
//! (`inertia_duration`): each step is then one backward-Euler step of the
//! dynamics, `(M/h²)(u − u_n − h v_n)` added, its numerical dissipation
//! reported with the stabilisation's (`docs/solver.md`, "Inertia").
//! `NCFORM_NEWTON_TRACE` in the environment prints every
//! iteration, augmentation, failed attempt and accepted step to stderr.

use std::ops::ControlFlow;
use std::time::Instant;

use serde::{Deserialize, Serialize};

use super::amplitude::Amplitude;
use super::assembly::Assembler;
use super::cancel::CancelToken;
use super::dofs::DofMap;
use super::linear::{LinearSolverError, LinearSolverKind, SparseSolver};
use crate::model::{Augmentation, Masses, Model, State, TermFailure};

pub use super::status::{RunStatus, Snapshot};

/// Solver knobs, all with documented defaults (`docs/cases.md`).
#[derive(Debug, Clone, PartialEq, Deserialize, Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct NewtonParameters {
    /// First load increment [units of λ, mm for a clamp displacement]. Default 1.
    pub initial_increment: f64,
    /// Largest load increment. Default 5.
    pub max_increment: f64,
    /// Smallest load increment before the run gives up. Default 1e-4.
    pub min_increment: f64,
    /// Newton iterations per step before a cut-back. Default 25.
    pub max_iterations: usize,
    /// Residual tolerance relative to the reaction forces. Default 1e-6.
    pub residual_tolerance: f64,
    /// Energy-norm tolerance relative to the step's first iteration. Default 1e-12.
    pub energy_tolerance: f64,
    /// Absolute floor of the residual criterion \[N\]. Default 1e-9.
    pub force_floor: f64,
    /// A step converged in at most this many iterations grows the next one. Default 6.
    pub easy_iterations: usize,
    /// Growth factor after an easy step. Default 1.5.
    pub growth: f64,
    /// Cut-back factor after a failed step. Default 0.5.
    pub cutback: f64,
    /// Use the line search (disable only for diagnostics). Default true.
    pub line_search: bool,
    /// Predict each step by extrapolating the previous increment. Default true.
    pub extrapolate: bool,
    /// Sparse factorisation; unset (the default): LDLᵀ when every term's
    /// tangent is symmetric (measured 3–8× faster than LU on the OATs with
    /// identical results; `docs/solver.md`), LU otherwise (friction).
    pub linear_solver: Option<LinearSolverKind>,
    /// Newton solves per load step for the multipliers of augmented terms
    /// (contact) to converge, at most. Default 50.
    pub max_augmentations: usize,
    /// Viscous (pseudo-dynamic) stabilisation of the free dofs
    /// (`docs/solver.md`, "Stabilisation"). Default off.
    pub stabilisation: Stabilisation,
    /// Automatic stabilisation: the target rate of viscous dissipation per
    /// unit load parameter relative to the internal energy, `φ`
    /// (`c = φ E_int / ‖v‖²_M`). Default 1e-4.
    pub stabilisation_fraction: f64,
    /// Constant stabilisation: the damping factor `c` (a force per mass
    /// and displacement per unit λ: N/(mm·t) = 1/s² when λ is a programme
    /// fraction). Default 0.
    pub stabilisation_factor: f64,
    /// Warn when the dissipated energy exceeds this fraction of the
    /// internal energy. Default 0.01.
    pub stabilisation_limit: f64,
    /// Implicit dynamics: the programme's duration \[s\]. Set, the free
    /// dofs carry their inertia by backward Euler, `r + (M/h²)(u − u_n −
    /// h v_n)` with `h` the step's share of the duration
    /// (`docs/solver.md`, "Inertia"); its numerical dissipation counts
    /// with the stabilisation's. Default: none (static).
    pub inertia_duration: Option<f64>,
    /// Implicit dynamics: the programme's shape in time, the programme
    /// fraction `f = shape(t/T)` (the explicit path's amplitudes; the
    /// step's time is `h = T (τ(f_{n+1}) − τ(f_n))`). Default linear.
    pub inertia_amplitude: Amplitude,
    /// Stop (incomplete, keeping every converged step) when a step would
    /// start after this wall time \[s\]. Default: no limit.
    pub max_wall_seconds: Option<f64>,
    /// Stop (interrupted, keeping every converged step) before the next
    /// load step once this is cancelled. Not a case-file key.
    #[serde(skip)]
    pub cancel: CancelToken,
}

/// The viscous stabilisation of the quasi-static path
/// (`docs/solver.md`, "Stabilisation").
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Stabilisation {
    /// No stabilisation.
    #[default]
    Off,
    /// `c` from the target dissipation rate `stabilisation_fraction`,
    /// raised after failed attempts.
    Automatic,
    /// A fixed `c = stabilisation_factor`.
    Constant,
}

/// Per free dof below this many times the mean non-zero nodal mass, the
/// stabilisation uses the mean (dofs without mass still get damped).
const STABILISATION_MIN_MASS: f64 = 1e-3;
/// Factor on the automatic damping after a failed attempt.
const STABILISATION_BOOST: f64 = 10.0;
/// Largest factor on the automatic damping.
const STABILISATION_MAX_BOOST: f64 = 1e3;
/// The first shift `μ` of `K + μ diag|K|` when the Newton direction does
/// not descend (docs/solver.md, "Newton", step 2).
const MIN_SHIFT: f64 = 1e-6;
/// The first shift tried when the line search finds no acceptable step
/// along the Newton direction (step 3): large enough to turn the direction
/// measurably towards the diagonal, each further try 100 times larger.
const LINE_SEARCH_SHIFT: f64 = 1e-4;
/// The largest shift: beyond it the direction is the diagonally scaled
/// steepest descent to within 10⁻³.
const MAX_SHIFT: f64 = 1e3;
/// From this fraction of the programme on, the dissipated-to-internal
/// energy ratio counts for the warning (the ply is nearly unstrained
/// before).
const STABILISATION_RATIO_FROM: f64 = 0.1;

impl Default for NewtonParameters {
    fn default() -> Self {
        Self {
            initial_increment: 1.0,
            max_increment: 5.0,
            min_increment: 1e-4,
            max_iterations: 25,
            residual_tolerance: 1e-6,
            energy_tolerance: 1e-12,
            force_floor: 1e-9,
            easy_iterations: 6,
            growth: 1.5,
            cutback: 0.5,
            line_search: true,
            extrapolate: true,
            linear_solver: None,
            max_augmentations: 50,
            stabilisation: Stabilisation::Off,
            stabilisation_fraction: 1e-4,
            stabilisation_factor: 0.0,
            stabilisation_limit: 0.01,
            inertia_duration: None,
            inertia_amplitude: Amplitude::Linear,
            max_wall_seconds: None,
            cancel: CancelToken::default(),
        }
    }
}

/// One converged load step.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StepRecord {
    /// Step number (1-based).
    pub step: usize,
    /// Load parameter λ at the end of the step.
    pub load: f64,
    /// Reaction `Σ w f_int` conjugate to λ [N for a displacement λ].
    pub reaction: f64,
    /// Total energy [N·mm].
    pub energy: f64,
    /// Newton iterations of the converged attempt (over all its
    /// augmentations).
    pub iterations: usize,
    /// Residual norms `‖r_free‖` of the converged attempt, one per iteration \[N\].
    pub residuals: Vec<f64>,
    /// Failed attempts before this step converged.
    pub cutbacks: usize,
    /// Newton solves of the converged attempt beyond the first (multiplier
    /// updates of augmented terms; 0 without contact).
    #[serde(skip_serializing_if = "is_zero")]
    pub augmentations: usize,
    /// The last augmentation report (gap, multiplier change, active and
    /// slipping contacts), `None` for a model without augmented terms.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub contact: Option<Augmentation>,
    /// Strain energy of the model (the terms' internal energies: membranes,
    /// bending) [N·mm].
    pub internal_energy: f64,
    /// The viscous stabilisation of the step, `None` when it is off.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stabilisation: Option<StabilisationRecord>,
}

/// What the viscous stabilisation and the inertia did in one step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct StabilisationRecord {
    /// The damping factor `c` of the step.
    pub factor: f64,
    /// Energy dissipated in the step, `(c/Δλ) Δuᵀ M Δu` plus, with
    /// inertia, backward Euler's `½ (v_{n+1} − v_n)ᵀ M (v_{n+1} − v_n)`
    /// [N·mm].
    pub dissipated: f64,
    /// Energy dissipated since the start [N·mm].
    pub dissipated_total: f64,
    /// Kinetic energy of the free dofs at the end of the step,
    /// `½ v_{n+1}ᵀ M v_{n+1}` (0 without inertia) [N·mm].
    pub kinetic: f64,
}

fn is_zero(n: &usize) -> bool {
    *n == 0
}

/// Wall-clock time spent in the parts of the solve \[s\].
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize)]
pub struct SolverTimings {
    /// Symbolic analysis (once).
    pub symbolic: f64,
    /// Assembly of force and tangent, including line-search evaluations.
    pub assembly: f64,
    /// Numeric factorisations.
    pub factorisation: f64,
    /// Triangular solves.
    pub solve: f64,
    /// Multiplier updates of augmented terms (contact).
    pub augmentation: f64,
}

/// Result of a quasi-static run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct QuasiStaticResult {
    /// Completion.
    pub status: RunStatus,
    /// Converged steps.
    pub steps: Vec<StepRecord>,
    /// Total Newton iterations, including failed attempts.
    pub newton_iterations: usize,
    /// Numeric factorisations.
    pub factorisations: usize,
    /// Time split.
    pub timings: SolverTimings,
    /// Number of free unknowns.
    pub unknowns: usize,
    /// Stored non-zeros of the tangent.
    pub nonzeros: usize,
    /// The factorisation used.
    pub linear_solver: LinearSolverKind,
    /// Newton solves beyond the first per step, summed over the run.
    pub augmentations: usize,
    /// Of the assembly time, the part each term took to evaluate \[s\].
    pub term_seconds: Vec<(String, f64)>,
    /// Strain energy at the last converged step [N·mm].
    pub internal_energy: f64,
    /// Energy dissipated by the viscous stabilisation over the run [N·mm]
    /// (0 when it is off).
    pub stabilisation_energy: f64,
    /// Largest ratio of the dissipated to the internal energy over the
    /// steps from 10 % of the programme on (0 when off).
    pub max_stabilisation_ratio: f64,
    /// Warnings (the stabilisation's dissipation above its limit).
    pub warnings: Vec<String>,
}

/// Why a quasi-static run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum QuasiStaticSetupError {
    /// The dof map or the state does not match the model.
    #[error("the dof map has {map} dofs and the state {state}, the model {model}")]
    DofCount {
        /// Dofs of the map.
        map: usize,
        /// Dofs of the state.
        state: usize,
        /// Dofs of the model.
        model: usize,
    },
    /// LDLᵀ asked for an unsymmetric tangent.
    #[error(
        "solver.linear_solver = \"ldlt\": expected a symmetric tangent, but friction makes this model's tangent unsymmetric; use \"lu\" or leave linear_solver unset"
    )]
    UnsymmetricLdlt,
    /// The symbolic factorisation failed.
    #[error(transparent)]
    Linear(#[from] LinearSolverError),
}

/// Why one attempt at a load step failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
enum AttemptError {
    #[error("{0}")]
    Term(#[from] TermFailure),
    #[error("{0}")]
    Linear(#[from] LinearSolverError),
    #[error(
        "no convergence in {iterations} iterations (residual {residual:.3e} N, reaction {reaction:.3e} N; largest residual {largest:.3e} N at {at})"
    )]
    NoConvergence {
        iterations: usize,
        residual: f64,
        reaction: f64,
        /// The largest residual component \[N\] and where it is
        /// ([`Model::describe_dof`]).
        largest: f64,
        at: String,
    },
    #[error("no descent direction even with a shifted tangent")]
    NoDescent,
    #[error(
        "non-finite forces (residual {residual:.3e} N, reaction {reaction:.3e} N, energy {energy:.3e} N·mm): the law or a term overflowed at this state"
    )]
    NonFinite {
        residual: f64,
        reaction: f64,
        energy: f64,
    },
    #[error("non-finite forces along the Newton step: the law or a term overflowed there")]
    NonFiniteTrial,
    #[error("the line search found no acceptable step")]
    LineSearch,
    #[error(
        "the contact multipliers did not converge in {augmentations} augmentations (penetration {penetration:.3e} mm{at}, multiplier change {change:.3e})"
    )]
    Augmentation {
        augmentations: usize,
        penetration: f64,
        /// ` at <node>` of the largest penetration, or empty.
        at: String,
        change: f64,
    },
    #[error("interrupted")]
    Interrupted,
}

/// Scratch of a run, allocated once.
struct Work {
    internal: Vec<f64>,
    trial_internal: Vec<f64>,
    trial: Vec<f64>,
    diag: Vec<f64>,
    diag_slots: Vec<usize>,
    /// Stabilisation and inertia: mass of every free dof \[t\], the free
    /// dofs at the last accepted step \[mm\], their velocities there
    /// \[mm/s\] (inertia) and the point the step's mass term pulls
    /// towards \[mm\].
    masses: Vec<f64>,
    previous: Vec<f64>,
    velocity: Vec<f64>,
    anchor: Vec<f64>,
}

/// Everything the step loop needs.
struct Newton<'a> {
    model: &'a mut Model,
    /// Load parameter and programme fraction of the step being solved.
    load: f64,
    load_fraction: f64,
    assembler: Assembler,
    solver: SparseSolver,
    params: &'a NewtonParameters,
    work: Work,
    timings: SolverTimings,
    iterations: usize,
    factorisations: usize,
    /// The coefficient `a` of the step's mass term `a M (u − anchor)`:
    /// `c/Δλ` of the stabilisation plus `1/h²` of the inertia (0: neither).
    mass_coefficient: f64,
}

/// `NCFORM_NEWTON_TRACE` set: print every iteration, augmentation and
/// failed attempt to stderr (diagnostics).
fn trace() -> bool {
    static TRACE: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *TRACE.get_or_init(|| std::env::var_os("NCFORM_NEWTON_TRACE").is_some())
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

impl Newton<'_> {
    fn free_residual(&self, internal: &[f64], out: &mut [f64]) {
        for (k, &d) in self.assembler.dofs.free.iter().enumerate() {
            out[k] = internal[d];
        }
    }

    fn reaction_norm(&self, internal: &[f64]) -> f64 {
        self.assembler
            .dofs
            .constrained
            .iter()
            .map(|c| internal[c.dof] * internal[c.dof])
            .sum::<f64>()
            .sqrt()
    }

    fn state<'u>(&self, u: &'u [f64]) -> State<'u> {
        State {
            load: self.load,
            load_fraction: self.load_fraction,
            ..State::at(u)
        }
    }

    fn assemble_tangent(&mut self, u: &[f64]) -> Result<f64, TermFailure> {
        let start = Instant::now();
        let state = self.state(u);
        let values = self.solver.values_mut();
        let result =
            self.assembler
                .force_tangent(self.model, &state, &mut self.work.internal, values);
        if self.mass_coefficient > 0.0 {
            let values = self.solver.values_mut();
            for (k, &d) in self.assembler.dofs.free.iter().enumerate() {
                let cm = self.mass_coefficient * self.work.masses[k];
                self.work.internal[d] += cm * (u[d] - self.work.anchor[k]);
                values[self.work.diag_slots[k]] += cm;
            }
        }
        self.timings.assembly += start.elapsed().as_secs_f64();
        result
    }

    fn assemble_force_into_trial(&mut self, u: &[f64]) -> Result<f64, TermFailure> {
        let start = Instant::now();
        let state = self.state(u);
        let result = self
            .assembler
            .force(self.model, &state, &mut self.work.trial_internal);
        if self.mass_coefficient > 0.0 {
            for (k, &d) in self.assembler.dofs.free.iter().enumerate() {
                let cm = self.mass_coefficient * self.work.masses[k];
                self.work.trial_internal[d] += cm * (u[d] - self.work.anchor[k]);
            }
        }
        self.timings.assembly += start.elapsed().as_secs_f64();
        result
    }

    fn factorize(&mut self) -> Result<(), LinearSolverError> {
        let start = Instant::now();
        let result = self.solver.factorize();
        self.factorisations += 1;
        self.timings.factorisation += start.elapsed().as_secs_f64();
        result
    }

    fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearSolverError> {
        let start = Instant::now();
        let result = self.solver.solve_in_place(rhs);
        self.timings.solve += start.elapsed().as_secs_f64();
        result
    }

    /// `g(α) = r(u + α du)·du` with `u + α du` written to `trial`.
    fn directional(&mut self, u: &[f64], du: &[f64], alpha: f64) -> Result<f64, AttemptError> {
        let mut trial = std::mem::take(&mut self.work.trial);
        trial.copy_from_slice(u);
        for (k, &d) in self.assembler.dofs.free.iter().enumerate() {
            trial[d] += alpha * du[k];
        }
        let result = self.assemble_force_into_trial(&trial);
        self.work.trial = trial;
        result?;
        let slope: f64 = self
            .assembler
            .dofs
            .free
            .iter()
            .enumerate()
            .map(|(k, &d)| self.work.trial_internal[d] * du[k])
            .sum();
        if slope.is_finite() {
            Ok(slope)
        } else {
            // An overflowed trial state is inadmissible, like one the terms
            // refuse: the line search shortens the step.
            Err(AttemptError::NonFiniteTrial)
        }
    }

    /// Line search on `g(α)`; returns the accepted α.
    fn line_search(&mut self, u: &[f64], du: &[f64], g0: f64) -> Result<f64, AttemptError> {
        const ETA: f64 = 0.5;
        const ALPHA_MIN: f64 = 1.0 / 64.0;
        // Bracket: g(0) = g0 < 0. Shrink α until the point is admissible.
        let mut alpha = 1.0;
        let g1 = loop {
            match self.directional(u, du, alpha) {
                Ok(g) => break g,
                Err(_) if alpha > ALPHA_MIN => alpha *= 0.5,
                Err(e) => return Err(e),
            }
        };
        if g1 <= -ETA * g0.abs() || g1.abs() <= ETA * g0.abs() {
            // Still descending, or the slope dropped enough: accept.
            return Ok(alpha);
        }
        // g changed sign in (0, α): Illinois (regula falsi) iterations.
        let (mut a_lo, mut g_lo) = (0.0, g0);
        let (mut a_hi, mut g_hi) = (alpha, g1);
        let mut best = alpha;
        for _ in 0..8 {
            // Regula falsi, kept 10 % inside the bracket; bisection if the
            // secant is not a number (g_hi = g_lo, or overflowed slopes).
            let secant = (a_lo * g_hi - a_hi * g_lo) / (g_hi - g_lo);
            let (lo, hi) = (a_lo + 0.1 * (a_hi - a_lo), a_hi - 0.1 * (a_hi - a_lo));
            let a = if secant.is_finite() {
                secant.max(lo).min(hi)
            } else {
                0.5 * (a_lo + a_hi)
            };
            let g = match self.directional(u, du, a) {
                Ok(g) => g,
                Err(_) => {
                    a_hi = a;
                    continue;
                }
            };
            best = a;
            if g.abs() <= ETA * g0.abs() {
                return Ok(a);
            }
            if g < 0.0 {
                a_lo = a;
                g_lo = g;
                g_hi *= 0.5;
            } else {
                a_hi = a;
                g_hi = g;
                g_lo *= 0.5;
            }
        }
        if best >= ALPHA_MIN {
            Ok(best)
        } else {
            Err(AttemptError::LineSearch)
        }
    }

    /// Solves `(K + μ diag K) du = −r`, raising μ until `du` descends:
    /// first `μ = 0` (the Newton direction), then from `MIN_SHIFT` on.
    fn descent_direction(&mut self, r: &[f64], du: &mut [f64]) -> Result<f64, AttemptError> {
        du.copy_from_slice(r);
        du.iter_mut().for_each(|v| *v = -*v);
        let plain = self
            .factorize()
            .and_then(|_| self.solve(du))
            .map(|_| du.iter().zip(r).map(|(a, b)| a * b).sum::<f64>());
        match plain {
            Ok(g0) if g0 < 0.0 => return Ok(g0),
            Ok(_) | Err(LinearSolverError::Singular(_)) | Err(LinearSolverError::NonFinite) => {}
            Err(e) => return Err(e.into()),
        }
        self.shifted_direction(r, du, MIN_SHIFT)
    }

    /// Solves `(K + μ diag K) du = −r` for `μ = first, 10 first, …` up to
    /// `MAX_SHIFT` until `du` descends (`r·du < 0`); the solver's values
    /// must hold the unshifted tangent `K`.
    fn shifted_direction(
        &mut self,
        r: &[f64],
        du: &mut [f64],
        first: f64,
    ) -> Result<f64, AttemptError> {
        // Shifted tangent: remember the diagonal, add μ |diag|.
        let values = self.solver.values_mut();
        for (k, &slot) in self.work.diag_slots.iter().enumerate() {
            self.work.diag[k] = values[slot];
        }
        let scale = self.work.diag.iter().fold(0.0_f64, |m, d| m.max(d.abs()));
        let mut mu = first;
        while mu <= MAX_SHIFT {
            let values = self.solver.values_mut();
            for (k, &slot) in self.work.diag_slots.iter().enumerate() {
                let d = self.work.diag[k];
                values[slot] = d + mu * d.abs().max(1e-6 * scale);
            }
            du.copy_from_slice(r);
            du.iter_mut().for_each(|v| *v = -*v);
            if self.factorize().is_ok() && self.solve(du).is_ok() {
                let g0: f64 = du.iter().zip(r).map(|(a, b)| a * b).sum();
                if g0 < 0.0 {
                    return Ok(g0);
                }
            }
            mu *= 10.0;
        }
        Err(AttemptError::NoDescent)
    }

    /// The line search's fallback (docs/solver.md, "Newton", step 3): when
    /// no acceptable step lies along the Newton direction, the directions
    /// of the shifted tangents `K + μ diag|K|` from `μ = 10⁻⁴, 10⁻², 1, 10²`
    /// on (each raised tenfold until it descends; each shorter and nearer
    /// the steepest descent of the energy) until one admits a step. Re-assembles the tangent at `u` first (the line
    /// search left the assembler at a trial state). Returns the step length
    /// along the direction written to `du`.
    fn shifted_line_search(
        &mut self,
        u: &[f64],
        r: &[f64],
        du: &mut [f64],
        energy_norm: &mut f64,
    ) -> Result<f64, AttemptError> {
        let mut first = LINE_SEARCH_SHIFT;
        while first <= MAX_SHIFT {
            self.assemble_tangent(u)?;
            let g0 = self.shifted_direction(r, du, first)?;
            match self.line_search(u, du, g0) {
                Ok(alpha) => {
                    *energy_norm = g0.abs();
                    if trace() {
                        eprintln!("  [newton] line search on the tangent shifted by {first:e}");
                    }
                    return Ok(alpha);
                }
                Err(AttemptError::LineSearch) => first *= 100.0,
                Err(e) => return Err(e),
            }
        }
        Err(AttemptError::LineSearch)
    }

    /// Newton iterations at a fixed load from the state `u` (updated in
    /// place). Returns iterations, residual history, energy, reaction vector.
    fn iterate(&mut self, u: &mut [f64]) -> Result<(usize, Vec<f64>, f64), AttemptError> {
        let n = self.assembler.dofs.n_free();
        let mut r = vec![0.0; n];
        let mut du = vec![0.0; n];
        let mut history = Vec::new();
        let mut first_energy_norm = None;
        let mut last_energy_norm = f64::INFINITY;
        let mut energy = self.assemble_tangent(u)?;
        for it in 0..=self.params.max_iterations {
            let internal = std::mem::take(&mut self.work.internal);
            self.free_residual(&internal, &mut r);
            let reaction = self.reaction_norm(&internal);
            self.work.internal = internal;
            let residual = norm(&r);
            // Overflowed forces would pass the relative test below
            // (∞ ≤ tol · ∞): never take them for an equilibrium.
            if !(residual.is_finite() && reaction.is_finite() && energy.is_finite()) {
                return Err(AttemptError::NonFinite {
                    residual,
                    reaction,
                    energy,
                });
            }
            history.push(residual);
            if trace() {
                eprintln!(
                    "  [newton] λ {:.6} it {it} ‖r‖ {residual:.3e} reaction {reaction:.3e}",
                    self.load
                );
            }
            // Relative to the reactions, but never below the absolute floor
            // (tiny loads, a first step of a ramped load: the round-off of
            // stiff terms sits above a relative bound there).
            let force_ok = residual
                <= (self.params.residual_tolerance * reaction).max(self.params.force_floor);
            let energy_ok = match first_energy_norm {
                None => true,
                Some(e0) => last_energy_norm <= self.params.energy_tolerance * e0,
            };
            if force_ok && (energy_ok || residual <= self.params.force_floor) {
                return Ok((it, history, energy));
            }
            if it == self.params.max_iterations {
                let (worst, largest) = r.iter().enumerate().fold((0, 0.0_f64), |(k, m), (j, v)| {
                    if v.abs() > m { (j, v.abs()) } else { (k, m) }
                });
                return Err(AttemptError::NoConvergence {
                    iterations: it,
                    residual,
                    reaction,
                    largest,
                    at: self.model.describe_dof(self.assembler.dofs.free[worst]),
                });
            }
            if self.params.cancel.is_cancelled() {
                return Err(AttemptError::Interrupted);
            }
            self.iterations += 1;
            let g0 = self.descent_direction(&r, &mut du)?;
            last_energy_norm = g0.abs();
            first_energy_norm.get_or_insert(g0.abs());
            let alpha = if self.params.line_search {
                match self.line_search(u, &du, g0) {
                    Ok(alpha) => alpha,
                    Err(AttemptError::LineSearch) => {
                        self.shifted_line_search(u, &r, &mut du, &mut last_energy_norm)?
                    }
                    Err(e) => return Err(e),
                }
            } else {
                1.0
            };
            for (k, &d) in self.assembler.dofs.free.iter().enumerate() {
                u[d] += alpha * du[k];
            }
            energy = self.assemble_tangent(u)?;
        }
        unreachable!("the loop returns at max_iterations")
    }
}

/// A converged load step: Newton solves and augmentations.
struct Solved {
    iterations: usize,
    residuals: Vec<f64>,
    energy: f64,
    augmentations: usize,
    contact: Option<Augmentation>,
}

impl Newton<'_> {
    /// Newton solves at the current load from `u` (updated in place),
    /// updating the multipliers of augmented terms between them until
    /// every term's constraints hold.
    fn solve_with_augmentations(&mut self, u: &mut [f64]) -> Result<Solved, AttemptError> {
        let mut iterations = 0;
        let mut residuals = Vec::new();
        for augmentations in 0..=self.params.max_augmentations {
            let (its, history, energy) = self.iterate(u)?;
            iterations += its;
            residuals.extend(history);
            let clock = Instant::now();
            let state = self.state(u);
            let report = self.model.augment(&state);
            self.timings.augmentation += clock.elapsed().as_secs_f64();
            match report {
                None => {
                    return Ok(Solved {
                        iterations,
                        residuals,
                        energy,
                        augmentations,
                        contact: None,
                    });
                }
                Some(r) if r.converged => {
                    return Ok(Solved {
                        iterations,
                        residuals,
                        energy,
                        augmentations,
                        contact: Some(r),
                    });
                }
                Some(r) if augmentations == self.params.max_augmentations => {
                    return Err(AttemptError::Augmentation {
                        augmentations,
                        penetration: r.max_penetration,
                        at: r
                            .deepest
                            .map(|n| format!(" at {}", self.model.describe_node(n)))
                            .unwrap_or_default(),
                        change: r.multiplier_change,
                    });
                }
                Some(r) => {
                    if trace() {
                        eprintln!(
                            "  [augment] {augmentations}: pen {:.3e} change {:.3e} active {} slip {}",
                            r.max_penetration, r.multiplier_change, r.active, r.slipping
                        );
                    }
                }
            }
        }
        unreachable!("the loop returns at max_augmentations")
    }
}

/// Drives `λ` from 0 to `final_load`, landing exactly on every value in
/// `stops` (sorted, within (0, final_load]); calls `on_step` after every
/// converged step with the record and the state.
///
/// `u` must hold the initial displacement (usually zeros, one per dof of
/// `model`).
///
/// # Errors
/// Only set-up failures ([`QuasiStaticSetupError`]: a dof map or state
/// that does not fit the model, the symbolic factorisation, a symmetric
/// solver asked for an unsymmetric tangent); a failed solve is a result with
/// [`RunStatus::Incomplete`], one stopped by `params.cancel` (before a load
/// step or a Newton iteration; the step in progress is dropped) a result
/// with [`RunStatus::Interrupted`].
pub fn solve_quasi_static(
    model: &mut Model,
    dofs: DofMap,
    params: &NewtonParameters,
    final_load: f64,
    stops: &[f64],
    u: &mut [f64],
    mut on_step: impl FnMut(&StepRecord, &Snapshot),
) -> Result<QuasiStaticResult, QuasiStaticSetupError> {
    solve_quasi_static_observed(
        model,
        dofs,
        params,
        final_load,
        stops,
        u,
        false,
        |record, snapshot, _| on_step(record, snapshot),
    )
}

/// [`solve_quasi_static`], handing `on_step` also, when `with_tangent`,
/// the tangent at every converged state, assembled there again and
/// factorised once ([`ConvergedTangent`]; `None` otherwise): what direct
/// differentiation needs, `K du/dp = −∂R/∂p` with one back-substitution
/// per parameter (`docs/fit.md`, "Sensitivities"). One assembly and one
/// factorisation per converged step on top of the solve; the
/// factorisations are counted in the result.
///
/// # Errors
/// As [`solve_quasi_static`].
#[allow(clippy::too_many_arguments)]
pub fn solve_quasi_static_observed(
    model: &mut Model,
    dofs: DofMap,
    params: &NewtonParameters,
    final_load: f64,
    stops: &[f64],
    u: &mut [f64],
    with_tangent: bool,
    mut on_step: impl FnMut(&StepRecord, &Snapshot, Option<&mut ConvergedTangent>),
) -> Result<QuasiStaticResult, QuasiStaticSetupError> {
    let mut run = QuasiStaticRun::set_up(model, dofs, params, final_load, stops, u)?;
    let status = loop {
        if let ControlFlow::Break(status) = run.step(&mut on_step, with_tangent) {
            break status;
        }
    };
    Ok(run.wind_down(status))
}

/// The tangent `K = ∂r/∂u` at a converged state, assembled there and
/// factorised once: solves with it on the free dofs, and products with
/// the whole tangent of every term's stencils (constrained rows too, for
/// the reactions' sensitivities).
pub struct ConvergedTangent<'s> {
    solver: &'s mut SparseSolver,
    assembler: &'s Assembler,
    timings: &'s mut SolverTimings,
    factorised: Result<(), LinearSolverError>,
}

impl ConvergedTangent<'_> {
    /// The free dofs, in the order of the vectors [`ConvergedTangent::solve`]
    /// takes.
    pub fn free_dofs(&self) -> &[usize] {
        &self.assembler.dofs.free
    }

    /// The constrained dofs with their displacement per unit load.
    pub fn constrained(&self) -> &[super::Dirichlet] {
        &self.assembler.dofs.constrained
    }

    /// Solves `K_ff x = rhs` in place (free dofs, in the order of
    /// [`ConvergedTangent::free_dofs`]).
    ///
    /// # Errors
    /// A singular tangent (the factorisation failed) or a non-finite
    /// solution.
    pub fn solve(&mut self, rhs: &mut [f64]) -> Result<(), LinearSolverError> {
        self.factorised.clone()?;
        let start = Instant::now();
        let result = self.solver.solve_in_place(rhs);
        self.timings.solve += start.elapsed().as_secs_f64();
        result
    }

    /// `out = K_ff x` on the free dofs (the factorised matrix).
    pub fn multiply_free(&self, x: &[f64], out: &mut [f64]) {
        let matrix = self.solver.matrix.as_ref();
        let (col_ptr, row_idx, values) = (
            matrix.symbolic().col_ptr(),
            matrix.symbolic().row_idx(),
            matrix.val(),
        );
        out.fill(0.0);
        for (j, xj) in x.iter().enumerate() {
            for k in col_ptr[j]..col_ptr[j + 1] {
                out[row_idx[k]] += values[k] * xj;
            }
        }
    }

    /// `‖K_ff‖₁`, the largest column sum of absolute values.
    pub fn norm_one(&self) -> f64 {
        let matrix = self.solver.matrix.as_ref();
        let col_ptr = matrix.symbolic().col_ptr();
        let values = matrix.val();
        (0..col_ptr.len() - 1)
            .map(|j| {
                values[col_ptr[j]..col_ptr[j + 1]]
                    .iter()
                    .map(|v| v.abs())
                    .sum::<f64>()
            })
            .fold(0.0, f64::max)
    }

    /// `out = K x` over every dof, free and constrained, from the terms'
    /// stencil tangents at the converged state (`x`, `out`: all dofs):
    /// the rows of the constrained dofs give `dr_c = K_cf dx_f + K_cc dx_c`.
    pub fn multiply_all(&self, x: &[f64], out: &mut [f64]) {
        self.assembler.tangent_product(x, out);
    }
}

/// The checks of [`solve_quasi_static`]'s set-up that need no matrix: the
/// dof map and the state fit the model, and the linear solver asked for
/// fits its tangent (LDLᵀ needs a symmetric one). What remains of the
/// set-up (the symbolic factorisation) runs with the solve.
///
/// # Errors
/// As [`solve_quasi_static`]'s set-up, but for the factorisation.
pub fn check_quasi_static(
    model: &Model,
    dofs: &DofMap,
    params: &NewtonParameters,
    u: &[f64],
) -> Result<(), QuasiStaticSetupError> {
    if dofs.total != model.dofs() || u.len() != model.dofs() {
        return Err(QuasiStaticSetupError::DofCount {
            map: dofs.total,
            state: u.len(),
            model: model.dofs(),
        });
    }
    choose_linear_solver(params.linear_solver, model.symmetric()).map(|_| ())
}

/// The factorisation asked for, or by default LDLᵀ for a symmetric
/// tangent and LU otherwise; LDLᵀ asked for an unsymmetric one is refused.
fn choose_linear_solver(
    asked: Option<LinearSolverKind>,
    symmetric: bool,
) -> Result<LinearSolverKind, QuasiStaticSetupError> {
    match asked {
        None if symmetric => Ok(LinearSolverKind::Ldlt),
        None => Ok(LinearSolverKind::Lu),
        Some(LinearSolverKind::Ldlt) if !symmetric => Err(QuasiStaticSetupError::UnsymmetricLdlt),
        Some(kind) => Ok(kind),
    }
}

/// The load stops: those of `stops` in `(0, final_load)`, then
/// `final_load`, sorted, without repeats.
fn load_stops(stops: &[f64], final_load: f64) -> Vec<f64> {
    let mut stops: Vec<f64> = stops
        .iter()
        .copied()
        .filter(|s| *s > 0.0 && *s < final_load)
        .collect();
    stops.push(final_load);
    stops.sort_by(f64::total_cmp);
    stops.dedup();
    stops
}

impl<'a> Newton<'a> {
    /// The Newton solver of `model` at `λ = 0`: the assembler and the
    /// symbolic factorisation (timed from `start`), the scratch, and the
    /// masses and last accepted free dofs (`u`) of the mass term.
    fn new(
        model: &'a mut Model,
        dofs: DofMap,
        params: &'a NewtonParameters,
        linear_solver: LinearSolverKind,
        u: &[f64],
        start: Instant,
    ) -> Result<Self, LinearSolverError> {
        let assembler = Assembler::new(model, dofs);
        let solver = SparseSolver::new(linear_solver, assembler.symbolic.clone())?;
        let symbolic_time = start.elapsed().as_secs_f64();
        let n_total = assembler.dofs.total;
        let n_free = assembler.dofs.n_free();
        // Diagonal slots of the free-dof matrix, for the shifted tangent.
        let symbolic = &assembler.symbolic;
        let diag_slots: Vec<usize> = (0..n_free)
            .map(|j| {
                let col = &symbolic.row_idx()[symbolic.col_ptr()[j]..symbolic.col_ptr()[j + 1]];
                symbolic.col_ptr()[j] + col.binary_search(&j).unwrap_or(0)
            })
            .collect();
        let masses = stabilisation_masses(model, &assembler.dofs);
        let previous: Vec<f64> = assembler.dofs.free.iter().map(|&d| u[d]).collect();
        Ok(Newton {
            model,
            load: 0.0,
            load_fraction: 0.0,
            assembler,
            solver,
            params,
            work: Work {
                internal: vec![0.0; n_total],
                trial_internal: vec![0.0; n_total],
                trial: vec![0.0; n_total],
                diag: vec![0.0; n_free],
                diag_slots,
                velocity: vec![0.0; n_free],
                anchor: previous.clone(),
                masses,
                previous,
            },
            timings: SolverTimings {
                symbolic: symbolic_time,
                ..Default::default()
            },
            iterations: 0,
            factorisations: 0,
            mass_coefficient: 0.0,
        })
    }
}

/// A load step being solved: its target and increment, and its mass
/// term (the damping factor `c`, `c/Δλ`, and the step's time `h`, 0
/// without inertia).
struct StepPlan {
    target: f64,
    step_increment: f64,
    factor: f64,
    viscous: f64,
    step_time: f64,
}

/// The working state of a quasi-static run: the Newton solver, and the
/// load loop's running values that [`QuasiStaticRun::step`] advances.
struct QuasiStaticRun<'a> {
    newton: Newton<'a>,
    params: &'a NewtonParameters,
    final_load: f64,
    /// The caller's displacement: the last accepted state.
    u: &'a mut [f64],
    /// The state of the step being solved.
    trial_u: Vec<f64>,
    /// Load stops in `(0, final_load]`, sorted, `final_load` last.
    stops: Vec<f64>,
    /// Loads closer than this are the same.
    tiny: f64,
    /// A mass term (viscous, inertial or both) is on: its energies are
    /// recorded and its dissipation checked against the limit.
    regularised: bool,
    start: Instant,
    linear_solver: LinearSolverKind,
    nonzeros: usize,
    load: f64,
    /// The next step's increment.
    increment: f64,
    /// `Δλ` of the last accepted step (`None` before the first); its
    /// `Δu` of every dof is `delta`.
    last_increment: Option<f64>,
    delta: Vec<f64>,
    steps: Vec<StepRecord>,
    /// Failed attempts since the last accepted step.
    cutbacks: usize,
    total_augmentations: usize,
    /// The factor on the automatic damping, raised after a failed
    /// attempt.
    boost: f64,
    internal_energy: f64,
    dissipated_total: f64,
    max_ratio: f64,
}

impl<'a> QuasiStaticRun<'a> {
    /// Set-up stage: checks the sizes, chooses the factorisation, builds
    /// the Newton solver (assembler, symbolic factorisation, masses) and
    /// the load stops, and takes the strain energy at the start.
    fn set_up(
        model: &'a mut Model,
        dofs: DofMap,
        params: &'a NewtonParameters,
        final_load: f64,
        stops: &[f64],
        u: &'a mut [f64],
    ) -> Result<Self, QuasiStaticSetupError> {
        let start = Instant::now();
        if dofs.total != model.dofs() || u.len() != model.dofs() {
            return Err(QuasiStaticSetupError::DofCount {
                map: dofs.total,
                state: u.len(),
                model: model.dofs(),
            });
        }
        let linear_solver = choose_linear_solver(params.linear_solver, model.symmetric())?;
        let n_total = dofs.total;
        let newton = Newton::new(model, dofs, params, linear_solver, u, start)?;
        let nonzeros = newton.assembler.nnz();
        let trial_u = u.to_vec();
        let start_state = newton.state(u);
        let internal_energy = internal_energy_of(newton.model, &start_state);
        Ok(Self {
            newton,
            params,
            final_load,
            u,
            trial_u,
            stops: load_stops(stops, final_load),
            tiny: 1e-12 * final_load.abs().max(1.0),
            regularised: params.stabilisation != Stabilisation::Off
                || params.inertia_duration.is_some(),
            start,
            linear_solver,
            nonzeros,
            load: 0.0,
            increment: params.initial_increment.min(final_load),
            last_increment: None,
            delta: vec![0.0; n_total],
            steps: Vec::new(),
            cutbacks: 0,
            total_augmentations: 0,
            boost: 1.0,
            internal_energy,
            dissipated_total: 0.0,
            max_ratio: 0.0,
        })
    }

    /// `λ / λ_final` in `[0, 1]` (1 for a zero final load).
    fn fraction(&self, load: f64) -> f64 {
        if self.final_load != 0.0 {
            (load / self.final_load).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }

    /// Step stage, one load step: the target (the increment, shortened to
    /// land on the next stop), the mass term, the Newton solves, then the
    /// accepted state and its output, or a cut-back. Breaks with the run's
    /// status.
    fn step(
        &mut self,
        on_step: &mut impl FnMut(&StepRecord, &Snapshot, Option<&mut ConvergedTangent>),
        with_tangent: bool,
    ) -> ControlFlow<RunStatus> {
        if self.load >= self.final_load - self.tiny {
            return ControlFlow::Break(RunStatus::Complete);
        }
        let next_stop = self
            .stops
            .iter()
            .copied()
            .find(|s| *s > self.load + self.tiny)
            .unwrap_or(self.final_load);
        let target = (self.load + self.increment).min(next_stop);
        let step_increment = target - self.load;
        if self.params.cancel.is_cancelled() {
            return ControlFlow::Break(RunStatus::Interrupted {
                load_reached: self.load,
            });
        }
        if let Some(budget) = self.params.max_wall_seconds
            && self.start.elapsed().as_secs_f64() > budget
        {
            return ControlFlow::Break(RunStatus::Incomplete {
                load_reached: self.load,
                load_attempted: target,
                reason: format!(
                    "the wall-time budget of {budget} s (solver.max_wall_seconds) ran out"
                ),
            });
        }
        let plan = self.plan(target, step_increment);
        match self.solve_step(&plan) {
            Ok(solved) => {
                let (iterations, augmentations) = (solved.iterations, solved.augmentations);
                let (reaction, stabilisation) = self.accept(&plan, augmentations);
                self.output(
                    &plan,
                    reaction,
                    stabilisation,
                    solved,
                    on_step,
                    with_tangent,
                );
                self.next_increment(&plan, iterations, augmentations);
                ControlFlow::Continue(())
            }
            Err(err) => self.cut_back(&plan, err),
        }
    }

    /// The step's load and its mass term (`docs/solver.md`,
    /// "Stabilisation", "Inertia"): the damping factor, the step's time,
    /// the coefficient `a` and the anchor of `a M (u − anchor)`.
    fn plan(&mut self, target: f64, step_increment: f64) -> StepPlan {
        let params = self.params;
        self.newton.load = target;
        self.newton.load_fraction = self.fraction(target);
        // The damping factor of this step (`docs/solver.md`, "Stabilisation").
        let factor = match params.stabilisation {
            Stabilisation::Off => 0.0,
            Stabilisation::Constant => params.stabilisation_factor,
            Stabilisation::Automatic => match self.last_increment {
                Some(previous) => {
                    // ‖v‖²_M with v the last step's Δu/Δλ.
                    let v2 = mass_norm_squared(
                        &self.newton.assembler.dofs.free,
                        &self.newton.work.masses,
                        &self.delta,
                    ) / (previous * previous);
                    if v2 > 0.0 && self.internal_energy > 0.0 {
                        self.boost * params.stabilisation_fraction * self.internal_energy / v2
                    } else {
                        0.0
                    }
                }
                None => 0.0,
            },
        };
        let viscous = if step_increment > 0.0 {
            factor / step_increment
        } else {
            0.0
        };
        // Inertia (`docs/solver.md`, "Inertia"): the step's time `h` and
        // backward Euler's `1/h²`, none in the first step (static: the ply
        // settles under gravity at rest, as the automatic stabilisation
        // leaves it unstabilised; the dynamics starts from rest there).
        // The one mass term `a M (u − anchor)`, `a = a_v + a_i`, pulls
        // towards `u_n + (a_i/a) h v_n`.
        let step_time = match (params.inertia_duration, self.last_increment) {
            (Some(duration), Some(_)) => {
                let tau = |f: f64| params.inertia_amplitude.inverse(f);
                duration * (tau(self.fraction(target)) - tau(self.fraction(self.load)))
            }
            _ => 0.0,
        };
        let inertial = if step_time > 0.0 {
            1.0 / (step_time * step_time)
        } else {
            0.0
        };
        let newton = &mut self.newton;
        newton.mass_coefficient = viscous + inertial;
        let lead = if newton.mass_coefficient > 0.0 {
            inertial / newton.mass_coefficient * step_time
        } else {
            0.0
        };
        for k in 0..newton.work.anchor.len() {
            newton.work.anchor[k] = newton.work.previous[k] + lead * newton.work.velocity[k];
        }
        StepPlan {
            target,
            step_increment,
            factor,
            viscous,
            step_time,
        }
    }

    /// The step's Newton solves: from the extrapolated predictor when
    /// there is one, then, if that fails, from the last accepted state.
    fn solve_step(&mut self, plan: &StepPlan) -> Result<Solved, AttemptError> {
        let extrapolate = self.params.extrapolate && self.last_increment.is_some();
        let mut result = self.attempt(plan, extrapolate);
        if extrapolate && result.is_err() {
            result = self.attempt(plan, false);
        }
        result
    }

    /// One attempt at the step into `trial_u`: from the history of the
    /// last accepted step, the prescribed values at the target and the
    /// free dofs extrapolated (or not), then Newton solves, augmenting
    /// between them.
    fn attempt(&mut self, plan: &StepPlan, extrapolate: bool) -> Result<Solved, AttemptError> {
        // Every attempt starts from the history of the last accepted step.
        self.newton.model.restore();
        self.trial_u.copy_from_slice(self.u);
        for c in &self.newton.assembler.dofs.constrained {
            self.trial_u[c.dof] = c.per_unit_load * plan.target;
        }
        if extrapolate && let Some(previous) = self.last_increment {
            let ratio = plan.step_increment / previous;
            for &d in &self.newton.assembler.dofs.free {
                self.trial_u[d] += ratio * self.delta[d];
            }
        }
        self.newton.solve_with_augmentations(&mut self.trial_u)
    }

    /// The converged step becomes the state: the terms commit their
    /// history; the reaction, backward Euler's velocities and the
    /// energies of the mass term and of the strain follow. Returns the
    /// reaction and the stabilisation record (none when no mass term).
    fn accept(
        &mut self,
        plan: &StepPlan,
        augmentations: usize,
    ) -> (f64, Option<StabilisationRecord>) {
        for ((delta, trial), u) in self.delta.iter_mut().zip(&self.trial_u).zip(self.u.iter()) {
            *delta = trial - u;
        }
        self.u.copy_from_slice(&self.trial_u);
        let newton = &mut self.newton;
        let state = newton.state(self.u);
        newton.model.commit(&state);
        let reaction: f64 = newton
            .assembler
            .dofs
            .constrained
            .iter()
            .map(|c| c.per_unit_load * newton.work.internal[c.dof])
            .sum();
        self.load = plan.target;
        self.total_augmentations += augmentations;
        // Backward Euler's velocities, its numerical dissipation and the
        // kinetic energy (inertia only).
        let (mut inertial_dissipation, mut kinetic) = (0.0, 0.0);
        let free = &newton.assembler.dofs.free;
        if plan.step_time > 0.0 {
            for (k, &d) in free.iter().enumerate() {
                let v = self.delta[d] / plan.step_time;
                let m = newton.work.masses[k];
                inertial_dissipation += 0.5 * m * (v - newton.work.velocity[k]).powi(2);
                kinetic += 0.5 * m * v * v;
                newton.work.velocity[k] = v;
            }
        }
        for (k, &d) in free.iter().enumerate() {
            newton.work.previous[k] = self.u[d];
        }
        let stabilisation = self.regularised.then(|| {
            let dissipated = plan.viscous
                * mass_norm_squared(free, &newton.work.masses, &self.delta)
                + inertial_dissipation;
            self.dissipated_total += dissipated;
            StabilisationRecord {
                factor: plan.factor,
                dissipated,
                dissipated_total: self.dissipated_total,
                kinetic,
            }
        });
        self.internal_energy = internal_energy_of(newton.model, &state);
        if stabilisation.is_some()
            && self.fraction(self.load) >= STABILISATION_RATIO_FROM
            && self.internal_energy > 0.0
        {
            self.max_ratio = self
                .max_ratio
                .max(self.dissipated_total / self.internal_energy);
        }
        self.boost = (self.boost / 2.0).max(1.0);
        (reaction, stabilisation)
    }

    /// Output stage: the step's record, handed to `on_step` with the
    /// state, then kept.
    fn output(
        &mut self,
        plan: &StepPlan,
        reaction: f64,
        stabilisation: Option<StabilisationRecord>,
        solved: Solved,
        on_step: &mut impl FnMut(&StepRecord, &Snapshot, Option<&mut ConvergedTangent>),
        with_tangent: bool,
    ) {
        let (load, internal_energy) = (self.load, self.internal_energy);
        if trace() {
            let kinetic = stabilisation.map_or(0.0, |s| s.kinetic);
            eprintln!(
                "[step] λ {load:.6} reaction {reaction:.6e} E_int {internal_energy:.6e} D {:.6e} c {:.3e} KE {kinetic:.3e}",
                self.dissipated_total, plan.factor
            );
        }
        let record = StepRecord {
            step: self.steps.len() + 1,
            load,
            reaction,
            energy: solved.energy,
            iterations: solved.iterations,
            residuals: solved.residuals,
            cutbacks: self.cutbacks,
            augmentations: solved.augmentations,
            contact: solved.contact,
            internal_energy,
            stabilisation,
        };
        if with_tangent {
            // The tangent at the accepted state, assembled again (the
            // solver's copy may be shifted or from a trial point), into
            // the line search's scratch so that the residual stays.
            let newton = &mut self.newton;
            let mut scratch = std::mem::take(&mut newton.work.trial_internal);
            let start = Instant::now();
            let state = newton.state(self.u);
            let assembled = newton.assembler.force_tangent(
                newton.model,
                &state,
                &mut scratch,
                newton.solver.values_mut(),
            );
            newton.timings.assembly += start.elapsed().as_secs_f64();
            newton.work.trial_internal = scratch;
            let factorised = match assembled {
                Ok(_) => newton.factorize(),
                Err(failure) => Err(LinearSolverError::Other(failure.to_string())),
            };
            let Newton {
                model,
                assembler,
                solver,
                work,
                timings,
                ..
            } = newton;
            let mut tangent = ConvergedTangent {
                solver,
                assembler,
                timings,
                factorised,
            };
            on_step(
                &record,
                &Snapshot {
                    u: self.u,
                    residual: &work.internal,
                    model,
                },
                Some(&mut tangent),
            );
        } else {
            on_step(
                &record,
                &Snapshot {
                    u: self.u,
                    residual: &self.newton.work.internal,
                    model: self.newton.model,
                },
                None,
            );
        }
        self.steps.push(record);
    }

    /// After an accepted step: the next increment, grown after an easy
    /// step, never shrunk by a step shortened to land on a stop.
    fn next_increment(&mut self, plan: &StepPlan, iterations: usize, augmentations: usize) {
        self.cutbacks = 0;
        self.last_increment = Some(plan.step_increment);
        let params = self.params;
        if iterations <= params.easy_iterations * (1 + augmentations) {
            self.increment = (self.increment * params.growth).min(params.max_increment);
        }
        // A step shortened to land on a stop does not shrink the next.
        self.increment = self
            .increment
            .max(plan.step_increment.min(params.max_increment));
    }

    /// After a failed step: the terms' history restored, the increment
    /// cut back (and the automatic damping raised); the run stops below
    /// the smallest increment or on a stop request.
    fn cut_back(&mut self, plan: &StepPlan, err: AttemptError) -> ControlFlow<RunStatus> {
        if trace() {
            eprintln!(
                "[newton] λ {:.6} (Δλ {:.3e}) failed: {err}",
                plan.target, plan.step_increment
            );
        }
        self.newton.model.restore();
        if err == AttemptError::Interrupted {
            return ControlFlow::Break(RunStatus::Interrupted {
                load_reached: self.load,
            });
        }
        self.cutbacks += 1;
        if self.params.stabilisation == Stabilisation::Automatic {
            self.boost = (self.boost * STABILISATION_BOOST).min(STABILISATION_MAX_BOOST);
        }
        self.increment = plan.step_increment * self.params.cutback;
        if self.increment < self.params.min_increment {
            return ControlFlow::Break(RunStatus::Incomplete {
                load_reached: self.load,
                load_attempted: plan.target,
                reason: err.to_string(),
            });
        }
        ControlFlow::Continue(())
    }

    /// Wind-down stage: the warning of a stabilisation that dissipated
    /// beyond its limit, and the result.
    fn wind_down(self, status: RunStatus) -> QuasiStaticResult {
        let mut warnings = Vec::new();
        if self.regularised && self.max_ratio > self.params.stabilisation_limit {
            warnings.push(format!(
                "the stabilisation dissipated up to {:.3} % of the internal energy (limit {} %; docs/solver.md, \"Stabilisation\", \"Inertia\")",
                100.0 * self.max_ratio,
                100.0 * self.params.stabilisation_limit
            ));
        }
        let newton = self.newton;
        QuasiStaticResult {
            status,
            steps: self.steps,
            newton_iterations: newton.iterations,
            factorisations: newton.factorisations,
            timings: newton.timings,
            unknowns: newton.assembler.dofs.n_free(),
            nonzeros: self.nonzeros,
            linear_solver: self.linear_solver,
            augmentations: self.total_augmentations,
            term_seconds: newton.assembler.term_seconds.clone(),
            internal_energy: self.internal_energy,
            stabilisation_energy: self.dissipated_total,
            max_stabilisation_ratio: self.max_ratio,
            warnings,
        }
    }
}

/// The strain energy of the model: the sum of its terms' internal
/// energies (membranes, bending) at `state`; 0 where a term cannot be
/// evaluated.
fn internal_energy_of(model: &mut Model, state: &State) -> f64 {
    model
        .terms
        .iter_mut()
        .map(|t| t.energy(state).map_or(0.0, |e| e.internal))
        .sum()
}

/// The mass of every free dof for the stabilisation: the terms' lumped
/// masses (`Term::lumped_masses`), with dofs lighter than
/// `STABILISATION_MIN_MASS` times the mean non-zero nodal mass raised to
/// that mean (a model without masses gets unit masses).
fn stabilisation_masses(model: &Model, dofs: &DofMap) -> Vec<f64> {
    let mut masses = Masses {
        node: vec![0.0; model.nodes],
        extra: vec![0.0; model.extras.len()],
    };
    for t in &model.terms {
        t.lumped_masses(&mut masses);
    }
    let massive: Vec<f64> = masses.node.iter().copied().filter(|m| *m > 0.0).collect();
    let mean = if massive.is_empty() {
        1.0
    } else {
        massive.iter().sum::<f64>() / massive.len() as f64
    };
    dofs.free
        .iter()
        .map(|&d| {
            let m = if d < 3 * model.nodes {
                masses.node[d / 3]
            } else {
                masses.extra[d - 3 * model.nodes]
            };
            if m < STABILISATION_MIN_MASS * mean {
                mean
            } else {
                m
            }
        })
        .collect()
}
/// `Σ m_k Δu_k²` over the free dofs (`masses` in the order of `free`):
/// the mass norm of an increment (`docs/solver.md`, "Stabilisation").
fn mass_norm_squared(free: &[usize], masses: &[f64], delta: &[f64]) -> f64 {
    free.iter()
        .zip(masses)
        .map(|(&d, m)| m * delta[d] * delta[d])
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The set-up messages read as they did when they were Strings.
    #[test]
    fn setup_errors_keep_their_wording() {
        let error = QuasiStaticSetupError::DofCount {
            map: 9,
            state: 6,
            model: 9,
        };
        assert_eq!(
            error.to_string(),
            "the dof map has 9 dofs and the state 6, the model 9"
        );
        assert_eq!(
            QuasiStaticSetupError::UnsymmetricLdlt.to_string(),
            "solver.linear_solver = \"ldlt\": expected a symmetric tangent, but friction makes this model's tangent unsymmetric; use \"lu\" or leave linear_solver unset"
        );
        let linear = LinearSolverError::NonFinite;
        assert_eq!(
            QuasiStaticSetupError::from(linear.clone()).to_string(),
            linear.to_string()
        );
    }
}
