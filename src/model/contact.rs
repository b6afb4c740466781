//! Contact of a ply's nodes with one rigid tool, with Coulomb friction
//! (`docs/contact.md`). Node to surface: every node of the ply is checked
//! against the tool, its mid-surface offset by half the ply's thickness
//! (or a set offset). The tool translates along a fixed direction by its
//! own dof `q` (fixed at 0, prescribed, or free for a floating tool), so
//! each stencil is one node and the tool's dof, and the sparse pattern is
//! known before any contact closes.
//!
//! - Quasi-static path: augmented Lagrangian normal and tangential parts
//!   with the friction return map and the exact consistent tangent
//!   ([`crate::contact::kernel::AugmentedLagrangian`]); multipliers updated
//!   between Newton solves (Uzawa) until the penetration and the change of
//!   the multipliers are below their tolerances; friction references
//!   committed per accepted step.
//! - Explicit path: penalty normal force and an elastic–plastic friction
//!   spring ([`crate::contact::kernel::PenaltyContact`]) whose stiffness is
//!   a fraction of each node's central-difference limit; stored and
//!   dissipated energy in the balance.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use arrayvec::ArrayVec;
use nalgebra::{Matrix3, Vector3};
use rayon::prelude::*;

use super::term::{
    Augmentation, FrequencyBound, Masses, NO_SLOT, State, Stencils, Term, TermEnergy, TermFailure,
    rounded_up,
};
use crate::contact::kernel::{
    AugmentationNorms, AugmentedLagrangian, CompactionLaw, ContactError, ContactStatus,
    ImplicitContactState, ImplicitResponse, NodalCompaction, PenaltyBatch, PenaltyContact,
    PenaltyInput, PenaltyOutput, PenaltyState, Smoothing, couple_tool_translation, max_curvature,
    penalty_lanes_one_by_one, stable_penalty_stiffness,
};
use crate::contact::{RigidSurface, SurfaceNormal};

/// Nodes per task of the parallel node loops (a multiple of
/// [`PAIR_LANES`]).
const NODE_CHUNK: usize = 256;

/// Nodes per batch of the explicit pairs' state: the lanes of the penalty
/// kernel on AVX2 (`docs/contact.md`, "Explicit path: the pairs in lanes").
const PAIR_LANES: usize = 4;

/// Batches per task of the explicit node loop.
const CHUNK_BATCHES: usize = NODE_CHUNK / PAIR_LANES;

/// Distance beyond the offset within which a node is checked exactly
/// against the tool at every Newton evaluation [mm]; farther nodes are
/// open (the surface culls them). Large against one Newton iteration's
/// contact change.
const CULL_MARGIN: f64 = 1.0;

/// The explicit path's cull margin [mm]: a node farther than the offset
/// plus this is open without a query once the broad phase has proved it
/// (`docs/contact.md`, "Broad phase"). An open pair inside the band and one
/// beyond it give the same force and state bit for bit (zero force, the
/// spring released, the previous position moved on), so the margin only
/// has to exceed a node's motion relative to the tool within one increment
/// (the punch moves 2.4 µm per increment at its fastest in the benches)
/// for a pair that leaves the tool to be released by the kernel inside the
/// band. Smaller than a ply's thickness, so the plies that lie on the
/// other ply of a stack, not on the tool, are proved far and skipped.
const EXPLICIT_CULL_MARGIN: f64 = 0.1;

/// Round-off allowance of the explicit broad phase \[mm\], absolute part:
/// a node is skipped only when its clearance bound exceeds the cull
/// distance by this much. Far above the round-off of a distance query on
/// millimetre coordinates (~1e-13 mm), far below any contact scale.
const CLEARANCE_TOLERANCE: f64 = 1e-6;

/// The broad phase of one node against the tool (explicit path): the
/// relative position `centre` where the tool's clearance was last taken,
/// and `slack = clearance − cull distance − tolerance` there. While
/// `|y − centre| < slack` the node is farther than the cull distance from
/// the tool (the distance is 1-Lipschitz), so the query would answer
/// `None`: the node is open without asking (`docs/contact.md`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Clearance {
    centre: Vector3<f64>,
    slack: f64,
}

impl Clearance {
    /// No bound yet: the node is checked.
    const UNKNOWN: Self = Self {
        centre: Vector3::new(0.0, 0.0, 0.0),
        slack: f64::NEG_INFINITY,
    };

    /// `true` when `y` is certainly beyond the cull distance.
    #[inline]
    fn far(&self, y: &Vector3<f64>) -> bool {
        self.slack > 0.0 && (y - self.centre).norm_squared() < self.slack * self.slack
    }

    /// The bound from a clearance `clearance` at `y` for the cull distance
    /// `cull`.
    #[inline]
    fn at(y: &Vector3<f64>, clearance: f64, cull: f64) -> Self {
        let tolerance = CLEARANCE_TOLERANCE + 1e-12 * (y.amax() + clearance.abs());
        Self {
            centre: *y,
            slack: clearance - cull - tolerance,
        }
    }
}

/// The per-node figures a user sees (VTU fields).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct NodeContact {
    /// 0 open, 1 stick, 2 slip.
    pub status: u8,
    /// Normal force \[N\].
    pub normal_force: f64,
    /// Magnitude of the friction force \[N\].
    pub friction_force: f64,
    /// Gap of the mid-surface offset to the tool \[mm\] (∞ when far).
    pub gap: f64,
    /// Accumulated slip along the tool \[mm\].
    pub slip: f64,
}

/// Settings of one ply–tool contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactOptions {
    /// Coulomb coefficient `μ ≥ 0`.
    pub friction: f64,
    /// Largest accepted penetration after augmentation \[mm\].
    pub gap_tolerance: f64,
    /// Largest accepted relative change of the multipliers per
    /// augmentation.
    pub multiplier_tolerance: f64,
    /// Ratio `ε_T/ε_N` of the tangential (stick) penalty to the normal
    /// penalty of each node (docs/contact.md, "The automatic penalty").
    pub tangential_penalty_scale: f64,
    /// The rounding of the augmented Lagrangian's kinks on the
    /// quasi-static path (docs/contact.md, "Smoothed kinks"; zero widths:
    /// none).
    pub smoothing: Smoothing,
    /// How each node's explicit penalty stiffness is chosen.
    pub explicit_stiffness: ExplicitPenalty,
    /// Explicit normal contact damping as a fraction of the critical
    /// damping `2 √(k_N m)` of each node's penalty spring.
    pub explicit_damping: f64,
    /// The ply's compliant layer on the explicit path: the normal force of
    /// Toll's packing law over the offset's layer (`docs/theory.md`,
    /// "Compaction of the fabric layer") in place of the linear penalty,
    /// its tangent capped at the penalty; `None`: the linear penalty.
    pub compaction: Option<CompactionLaw>,
}

/// How the explicit path chooses each node's penalty stiffness
/// `k_N = k_T` (docs/contact.md, "Explicit path: penalty with regularised
/// friction").
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ExplicitPenalty {
    /// A fraction `c ∈ (0, 1]` of the node's central-difference limit,
    /// `k = c · 4 m / Δt²` with `Δt` the stable step of the rest of the
    /// model: the contact lowers the step by at most `√(1 + c)`. Per unit
    /// area this grows as the cells shrink (`∝ 1/Δt²`).
    StableFraction(f64),
    /// A stiffness per unit area `k_p > 0` \[N/mm³ = MPa/mm\]:
    /// `k = k_p · A_n` with `A_n` the node's tributary area, the same
    /// pressure per penetration on every mesh. The stable-step estimate
    /// counts it like any spring.
    PerArea(f64),
}

impl ExplicitPenalty {
    /// The default: `StableFraction(0.1)`.
    pub const DEFAULT: Self = Self::StableFraction(0.1);

    /// The stiffness \[N/mm\] of a node of mass `mass` \[t\] and tributary
    /// area `area` \[mm²\] at the stable step `time_step` \[s\] of the rest
    /// of the model.
    ///
    /// # Errors
    /// A fraction outside (0, 1], a per-area stiffness or an area that is
    /// not positive, or a stiffness that is not finite.
    pub fn stiffness(&self, mass: f64, area: f64, time_step: f64) -> Result<f64, PenaltyError> {
        match *self {
            Self::StableFraction(c) => Ok(stable_penalty_stiffness(mass, time_step, c)?),
            Self::PerArea(k_p) => {
                let k = k_p * area;
                if k_p > 0.0 && area > 0.0 && k.is_finite() {
                    Ok(k)
                } else {
                    Err(PenaltyError::PerArea {
                        pressure_stiffness: k_p,
                        area,
                    })
                }
            }
        }
    }
}

/// Why [`ExplicitPenalty::stiffness`] gives no stiffness.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PenaltyError {
    /// A fraction of the stable limit that is out of range, or a mass or
    /// step for which the stiffness is not finite.
    #[error(transparent)]
    StableFraction(#[from] ContactError),
    /// A per-area stiffness or a nodal area that is not positive, or a
    /// product that is not finite.
    #[error(
        "penalty {pressure_stiffness} N/mm³ on a nodal area {area} mm²: expected both positive"
    )]
    PerArea {
        /// The stiffness per unit area \[N/mm³\].
        pressure_stiffness: f64,
        /// The node's tributary area \[mm²\].
        area: f64,
    },
}

/// The contact of a set of ply nodes with one rigid tool.
pub struct ToolContact {
    name: String,
    surface: Arc<dyn RigidSurface>,
    direction: Vector3<f64>,
    extra: usize,
    model_nodes: usize,
    nodes: Vec<usize>,
    reference: Vec<Vector3<f64>>,
    offsets: Vec<f64>,
    areas: Vec<f64>,
    penalties: Vec<f64>,
    options: ContactOptions,
    implicit: Vec<ImplicitContactState>,
    responses: Vec<ImplicitResponse>,
    springs: Vec<PenaltyContact>,
    /// The explicit pairs' settings and state, [`PAIR_LANES`] nodes per
    /// batch in node order (the last batch padded with copies of the last
    /// node, never written back to the outputs): the penalty springs, the
    /// normal dashpots `c = ζ 2 √(k_N m)` [N·s/mm], and per node the
    /// energy dissipated by the dashpot [N·mm] and its force at the last
    /// increment \[N\] (the dissipation is the trapezoidal work
    /// `−½ (F_{n−1} + F_n)·Δy`, the rule the solver's balance follows).
    pairs: Vec<PenaltyBatch<PAIR_LANES>>,
    /// The compliant layer's law of each pair, in the batches' order
    /// (empty: the linear penalty).
    layers: Vec<[NodalCompaction; PAIR_LANES]>,
    /// Per node: the explicit broad phase's bound.
    clearances: Vec<Clearance>,
    /// Whether the explicit path uses the broad phase (on by default; off
    /// queries every node every increment, for comparisons).
    broad_phase: bool,
    /// Explicit path: an upper bound of the distance any node has moved
    /// relative to the tool since the explicit set-up \[mm\] (the sum of
    /// the solver's per-increment [`State::motion`] and the tool's own
    /// motion).
    travelled: f64,
    /// The tool's dof at the last explicit force pass \[mm\] (NaN before
    /// the first).
    last_tool_position: f64,
    /// Per batch of [`PAIR_LANES`] nodes: while `travelled` stays below
    /// this value, every node of the batch is certainly beyond the cull
    /// distance and its pair released, and the batch is skipped
    /// (`docs/contact.md`, "Explicit path: batches proved far"); `−∞`:
    /// visit.
    deadlines: Vec<f64>,
    partials: Vec<f64>,
    outputs: Vec<NodeContact>,
    /// Friction work of the accepted quasi-static steps [N·mm].
    dissipated: f64,
    /// Force of the plies on the tool along its direction at the last
    /// evaluation [N] (`∂Π/∂q`).
    tool_force: f64,
}

impl ToolContact {
    /// Contact of the model nodes `nodes` (reference positions
    /// `reference`, mid-surface offsets `offsets` \[mm\], nodal areas `areas`
    /// \[mm²\], augmented-Lagrangian penalties `penalties` [N/mm]) with the
    /// tool `surface` (world frame, at `q = 0`) translating along the unit
    /// `direction` by extra dof `extra` of a model of `model_nodes` nodes.
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        name: impl Into<String>,
        surface: Arc<dyn RigidSurface>,
        direction: Vector3<f64>,
        extra: usize,
        model_nodes: usize,
        nodes: Vec<usize>,
        reference: Vec<Vector3<f64>>,
        offsets: Vec<f64>,
        areas: Vec<f64>,
        penalties: Vec<f64>,
        options: ContactOptions,
    ) -> Self {
        let n = nodes.len();
        let implicit = reference.iter().map(ImplicitContactState::new).collect();
        Self {
            name: name.into(),
            surface,
            direction,
            extra,
            model_nodes,
            implicit,
            responses: vec![ImplicitResponse::default_open(); n],
            springs: Vec::new(),
            pairs: Vec::new(),
            layers: Vec::new(),
            clearances: vec![Clearance::UNKNOWN; n],
            broad_phase: true,
            travelled: 0.0,
            last_tool_position: f64::NAN,
            deadlines: Vec::new(),
            partials: vec![0.0; n.div_ceil(NODE_CHUNK)],
            outputs: vec![
                NodeContact {
                    gap: f64::INFINITY,
                    ..Default::default()
                };
                n
            ],
            nodes,
            reference,
            offsets,
            areas,
            penalties,
            options,
            dissipated: 0.0,
            tool_force: 0.0,
        }
    }

    /// The model nodes this term checks.
    pub fn nodes(&self) -> &[usize] {
        &self.nodes
    }

    /// The nodal areas \[mm²\] (for contact pressures).
    pub fn areas(&self) -> &[f64] {
        &self.areas
    }

    /// The per-node figures of the last evaluation.
    pub fn node_contacts(&self) -> &[NodeContact] {
        &self.outputs
    }

    /// The tool's extra dof (index among the extras).
    pub fn extra(&self) -> usize {
        self.extra
    }

    /// Force of the plies on the tool along its direction at the last
    /// evaluation \[N\]: the force that drives or holds it, positive when the
    /// plies resist its motion.
    pub fn tool_force(&self) -> f64 {
        self.tool_force
    }

    /// Turns the explicit broad phase on (the default) or off. Off, every
    /// node is queried against the tool every increment; the results are
    /// the same bit for bit (the broad phase skips only nodes the query
    /// would cull), so this is for tests and timings.
    pub fn set_broad_phase(&mut self, on: bool) {
        self.broad_phase = on;
        self.clearances.fill(Clearance::UNKNOWN);
        self.deadlines.fill(f64::NEG_INFINITY);
    }

    /// Nodes whose explicit broad-phase bound holds them beyond the cull
    /// distance at their last bound (skipped until they have moved that
    /// far relative to the tool).
    pub fn bounded_far(&self) -> usize {
        self.clearances.iter().filter(|c| c.slack > 0.0).count()
    }

    /// Batches of [`PAIR_LANES`] nodes that the next explicit pass skips
    /// unless the nodes have moved: every node certainly beyond the cull
    /// distance, every pair released (`docs/contact.md`, "Explicit path:
    /// batches proved far").
    pub fn batches_proved_far(&self) -> usize {
        self.deadlines
            .iter()
            .filter(|d| **d > self.travelled)
            .count()
    }

    /// Whether node slot `i` lies in a batch that the next explicit pass
    /// skips unless the nodes have moved ([`ToolContact::batches_proved_far`]).
    pub fn node_proved_far(&self, i: usize) -> bool {
        self.deadlines
            .get(i / PAIR_LANES)
            .is_some_and(|d| *d > self.travelled)
    }

    /// The gap of each of the term's nodes to the tool at `u` \[mm\]: the
    /// signed distance of the node's mid-surface position to the surface
    /// less the node's offset (half the ply's contact thickness), whatever
    /// its distance (no cull); `+∞` where the surface has no answer (a
    /// sphere's centre). For the defect indicators of the outputs
    /// (`docs/cases.md`, "Defect indicators"), not the hot path.
    pub fn node_gaps(&self, u: &[f64]) -> Vec<f64> {
        (0..self.nodes.len())
            .map(|i| {
                self.surface
                    .closest_normal(&self.relative(i, u), f64::MAX)
                    .map_or(f64::INFINITY, |p| p.distance - self.offsets[i])
            })
            .collect()
    }

    /// The relative position `y = x − q d` of node slot `i` at `u`.
    #[inline]
    fn relative(&self, i: usize, u: &[f64]) -> Vector3<f64> {
        let n = self.nodes[i];
        let q = u[3 * self.model_nodes + self.extra];
        self.reference[i] + Vector3::new(u[3 * n], u[3 * n + 1], u[3 * n + 2]) - q * self.direction
    }

    fn failure(&self, i: usize, reason: String) -> TermFailure {
        TermFailure {
            term: self.name.clone(),
            what: "node",
            index: self.nodes[i],
            reason,
        }
    }

    fn kernel(&self, i: usize) -> Result<AugmentedLagrangian, TermFailure> {
        AugmentedLagrangian::new(
            self.penalties[i],
            self.penalties[i] * self.options.tangential_penalty_scale,
            self.options.friction,
            self.offsets[i],
        )
        .and_then(|k| k.with_smoothing(self.options.smoothing))
        .map_err(|e| self.failure(i, e.to_string()))
    }

    /// Every node's implicit response at `u` into `self.responses`.
    fn respond(&mut self, u: &[f64]) -> Result<(), TermFailure> {
        let first_failure = AtomicUsize::new(usize::MAX);
        let this = &*self;
        // A String error: it is the reason of the `TermFailure` built below.
        let responses: Vec<Result<ImplicitResponse, String>> = (0..self.nodes.len())
            .into_par_iter()
            .with_min_len(NODE_CHUNK)
            .map(|i| {
                let y = this.relative(i, u);
                let cull = this.offsets[i]
                    + CULL_MARGIN
                    + this.options.smoothing.gap_width
                    + this.implicit[i].normal_multiplier / this.penalties[i];
                let point = this.surface.closest(&y, cull);
                let kernel = this.kernel(i).map_err(|f| f.reason)?;
                kernel
                    .evaluate(&this.implicit[i], &y, point.as_ref())
                    .map_err(|e| {
                        first_failure.fetch_min(i, Ordering::Relaxed);
                        e.to_string()
                    })
            })
            .collect();
        for (i, r) in responses.into_iter().enumerate() {
            match r {
                Ok(r) => self.responses[i] = r,
                Err(reason) => return Err(self.failure(i, reason)),
            }
        }
        Ok(())
    }
}

impl ImplicitResponse {
    /// An open response (no force), for initial buffers.
    fn default_open() -> Self {
        Self {
            status: ContactStatus::Open,
            gap: f64::INFINITY,
            normal_force: 0.0,
            normal_potential: 0.0,
            tangential_force: Vector3::zeros(),
            slip_increment: Vector3::zeros(),
            normal: Vector3::zeros(),
            residual: Vector3::zeros(),
            tangent: Matrix3::zeros(),
        }
    }
}

impl Term for ToolContact {
    fn name(&self) -> &str {
        &self.name
    }

    fn stencils(&self) -> Stencils {
        Stencils {
            count: self.nodes.len(),
            nodes: 1,
            extras: 1,
        }
    }

    fn stencil(&self, s: usize, nodes: &mut [usize], extras: &mut [usize]) {
        nodes[0] = self.nodes[s];
        extras[0] = self.extra;
    }

    /// The augmented-Lagrangian residual and consistent tangent of every
    /// node against the tool, expanded to the node's dofs and the tool's
    /// (`∂/∂q = −d·∂/∂y`). Returns the normal potential
    /// `Σ ⟨λ_N − ε_N g⟩² / (2 ε_N)`.
    fn evaluate(
        &mut self,
        state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        self.respond(state.u)?;
        let mut potential = 0.0;
        let mut tool_force = 0.0;
        let mut tangent = tangent;
        for (i, r) in self.responses.iter().enumerate() {
            let coupled = couple_tool_translation(&self.direction, &r.residual, &r.tangent);
            force[4 * i..4 * i + 4].copy_from_slice(coupled.residual.as_slice());
            if let Some(k) = tangent.as_deref_mut() {
                k[16 * i..16 * i + 16].copy_from_slice(coupled.tangent.as_slice());
            }
            tool_force += coupled.residual[3];
            potential += r.normal_potential;
            let out = &mut self.outputs[i];
            out.status = r.status.code();
            out.normal_force = r.normal_force;
            out.friction_force = r.tangential_force.norm();
            out.gap = r.gap;
        }
        self.tool_force = tool_force;
        Ok(potential)
    }

    fn symmetric(&self) -> bool {
        self.options.friction == 0.0
    }

    /// Uzawa: `λ_N ← t_N`, `λ_T ← t_T` at the converged state; converged
    /// when the largest penetration is within the gap tolerance and the
    /// multipliers changed by less than their tolerance.
    fn augment(&mut self, state: &State) -> Option<Augmentation> {
        if self.respond(state.u).is_err() {
            return Some(Augmentation::default());
        }
        let mut norms = AugmentationNorms::default();
        let (mut active, mut slipping) = (0, 0);
        let mut deepest = None;
        for ((s, r), &node) in self
            .implicit
            .iter_mut()
            .zip(&self.responses)
            .zip(&self.nodes)
        {
            let report = s.augment(r);
            if report.penetration > norms.max_penetration {
                deepest = Some(node);
            }
            norms.add(&report);
            match r.status {
                ContactStatus::Open => {}
                ContactStatus::Stick => active += 1,
                ContactStatus::Slip => {
                    active += 1;
                    slipping += 1;
                }
            }
        }
        let change = if norms.multiplier_squared > 0.0 {
            norms.relative_change()
        } else {
            0.0
        };
        Some(Augmentation {
            converged: norms.max_penetration <= self.options.gap_tolerance
                && change <= self.options.multiplier_tolerance,
            max_penetration: norms.max_penetration,
            multiplier_change: change,
            active,
            slipping,
            deepest,
        })
    }

    /// Friction references move to the converged positions; the step's
    /// friction work `Σ t_T·Δs` and slip are accumulated.
    fn commit(&mut self, state: &State) {
        for i in 0..self.nodes.len() {
            let y = self.relative(i, state.u);
            let r = &self.responses[i];
            if r.status != ContactStatus::Open {
                self.dissipated += r.tangential_force.dot(&r.slip_increment);
                self.outputs[i].slip += r.slip_increment.norm();
            }
            self.implicit[i].commit(&y);
        }
    }

    fn restore(&mut self) {
        for s in &mut self.implicit {
            s.restore();
        }
    }

    // --- explicit path ---------------------------------------------------

    /// One stencil per node (its own force) and one for the tool's dof,
    /// whose value the term reduces itself in node-chunk order.
    fn explicit_stencils(&self) -> Stencils {
        Stencils {
            count: self.nodes.len() + 1,
            nodes: 1,
            extras: 1,
        }
    }

    fn explicit_stencil(&self, s: usize, nodes: &mut [usize], extras: &mut [usize]) {
        if s < self.nodes.len() {
            nodes[0] = self.nodes[s];
            extras[0] = NO_SLOT;
        } else {
            nodes[0] = NO_SLOT;
            extras[0] = self.extra;
        }
    }

    fn stiffness_from_time_step(&self) -> bool {
        true
    }

    /// Penalties `k = c · 4 m/Δt²` from each node's mass and the step of
    /// the rest of the model; states at the current positions.
    fn explicit_setup(
        &mut self,
        state: &State,
        masses: &Masses,
        time_step: f64,
    ) -> Result<(), TermFailure> {
        let n = self.nodes.len();
        let mut springs = Vec::with_capacity(n);
        let mut dashpots = Vec::with_capacity(n);
        let mut nodal_layers = Vec::new();
        for i in 0..n {
            let m = masses.node[self.nodes[i]];
            let stiffness = self
                .options
                .explicit_stiffness
                .stiffness(m, self.areas[i], time_step)
                .map_err(|e| self.failure(i, e.to_string()))?;
            let mut spring =
                PenaltyContact::new(stiffness, stiffness, self.options.friction, self.offsets[i])
                    .map_err(|e| self.failure(i, e.to_string()))?;
            if let Some(law) = &self.options.compaction {
                let layer = NodalCompaction::new(law, self.areas[i], self.offsets[i], stiffness)
                    .map_err(|e| self.failure(i, e.to_string()))?;
                spring = spring.with_compaction(layer);
                nodal_layers.push(layer);
            }
            let critical = 2.0 * (spring.normal_stiffness() * m).sqrt();
            springs.push(spring);
            dashpots.push(self.options.explicit_damping * critical);
        }
        self.pairs = (0..n.div_ceil(PAIR_LANES))
            .map(|b| {
                let node = |w: usize| (b * PAIR_LANES + w).min(n - 1);
                PenaltyBatch::new(
                    &std::array::from_fn(|w| springs[node(w)]),
                    &std::array::from_fn(|w| dashpots[node(w)]),
                    &std::array::from_fn(|w| PenaltyState::new(&self.relative(node(w), state.u))),
                )
            })
            .collect();
        // Padded like the pairs: the last batch repeats the last node.
        self.layers = if nodal_layers.len() == n {
            (0..n.div_ceil(PAIR_LANES))
                .map(|b| std::array::from_fn(|w| nodal_layers[(b * PAIR_LANES + w).min(n - 1)]))
                .collect()
        } else {
            Vec::new()
        };
        self.springs = springs;
        self.clearances.fill(Clearance::UNKNOWN);
        self.deadlines = vec![f64::NEG_INFINITY; self.pairs.len()];
        self.travelled = 0.0;
        self.last_tool_position = f64::NAN;
        Ok(())
    }

    /// Per node: the broad phase (a node certainly beyond the cull
    /// distance is open without a query), else the first-order query
    /// ([`RigidSurface::closest_normals`], one call per chunk); the
    /// penalty kernel and the normal dashpot on [`PAIR_LANES`] nodes at a
    /// time ([`crate::contact::kernel::penalty_lanes`]), skipped for the
    /// batches whose nodes are all culled and released; the force on the
    /// tool's dof reduced in node order per chunk.
    fn explicit_forces(&mut self, state: &State, out: &mut [f64]) -> Result<(), TermFailure> {
        let u = state.u;
        let n = self.nodes.len();
        let first_failure = AtomicUsize::new(usize::MAX);
        let (node_out, tool_out) = out.split_at_mut(4 * n);
        let surface = &*self.surface;
        let direction = self.direction;
        let broad_phase = self.broad_phase;
        let (nodes, reference, offsets) = (&self.nodes, &self.reference, &self.offsets);
        let dt = state.time_step;
        let q = u[3 * self.model_nodes + self.extra];
        // How far the nodes may have moved relative to the tool since the
        // last pass: the solver's bound plus the tool's own motion.
        let step_motion = state.motion + (q - self.last_tool_position).abs() * direction.norm();
        self.last_tool_position = q;
        if broad_phase && step_motion.is_finite() {
            self.travelled += rounded_up(step_motion);
        } else {
            self.deadlines.fill(f64::NEG_INFINITY);
        }
        let travelled = self.travelled;
        let layers = &self.layers;
        node_out
            .par_chunks_mut(4 * NODE_CHUNK)
            .zip(self.pairs.par_chunks_mut(CHUNK_BATCHES))
            .zip(self.outputs.par_chunks_mut(NODE_CHUNK))
            .zip(self.clearances.par_chunks_mut(NODE_CHUNK))
            .zip(self.deadlines.par_chunks_mut(CHUNK_BATCHES))
            .zip(self.partials.par_iter_mut())
            .enumerate()
            .for_each(
                |(chunk, (((((f, pairs), outputs), clearances), deadlines), partial))| {
                    let first = chunk * NODE_CHUNK;
                    // Batches proved far at an earlier pass and not yet moved
                    // that far: nothing to do, nothing changes.
                    let skipped: u64 = deadlines
                        .iter()
                        .enumerate()
                        .fold(0, |mask, (b, d)| mask | (u64::from(*d > travelled) << b));
                    if skipped == u64::MAX >> (u64::BITS as usize - deadlines.len()) {
                        *partial = 0.0;
                        return;
                    }
                    // Phase 1: relative positions; the broad phase picks the
                    // nodes to query (the lists are filled, never cleared: no
                    // work for the nodes it proves far).
                    let mut inputs = [PenaltyInput::<PAIR_LANES>::default(); CHUNK_BATCHES];
                    let mut queried = ArrayVec::<usize, NODE_CHUNK>::new();
                    let mut points = ArrayVec::<Vector3<f64>, NODE_CHUNK>::new();
                    let mut culls = ArrayVec::<f64, NODE_CHUNK>::new();
                    for (j, clearance) in clearances.iter().enumerate() {
                        if skipped >> (j / PAIR_LANES) & 1 == 1 {
                            continue;
                        }
                        let i = first + j;
                        let node = nodes[i];
                        let y = reference[i]
                            + Vector3::new(u[3 * node], u[3 * node + 1], u[3 * node + 2])
                            - q * direction;
                        let input = &mut inputs[j / PAIR_LANES];
                        for c in 0..3 {
                            input.position[c][j % PAIR_LANES] = y[c];
                        }
                        if !(broad_phase && clearance.far(&y)) {
                            queried.push(j);
                            points.push(y);
                            culls.push(offsets[i] + EXPLICIT_CULL_MARGIN);
                        }
                    }
                    // Phase 2: one batch query of the tool; the bounds; the
                    // answers into the kernel's input (culled: +∞, no normal).
                    let mut answers: ArrayVec<Option<SurfaceNormal>, NODE_CHUNK> =
                        points.iter().map(|_| None).collect();
                    surface.closest_normals(&points, &culls, &mut answers);
                    for (((j, y), cull), answer) in
                        queried.iter().zip(&points).zip(&culls).zip(&answers)
                    {
                        // A culled node gets a new bound here; an answered one
                        // is within the cull distance, where a bound would prove
                        // nothing, so it keeps its last (still true) one.
                        if broad_phase && answer.is_none() {
                            clearances[*j] = Clearance::at(y, surface.clearance(y), *cull);
                        }
                        if let Some(p) = answer {
                            let input = &mut inputs[j / PAIR_LANES];
                            input.distance[j % PAIR_LANES] = p.distance;
                            for c in 0..3 {
                                input.normal[c][j % PAIR_LANES] = p.normal[c];
                            }
                        }
                    }
                    // Phase 3: the kernel on the batches with a pair to update
                    // (a pair culled and released stays so, its previous
                    // position moved on); forces and outputs in node order, the
                    // force on the tool summed in node order.
                    let first_batch = chunk * CHUNK_BATCHES;
                    let kernel = KernelChunk {
                        layers: (!layers.is_empty())
                            .then(|| &layers[first_batch..first_batch + pairs.len()]),
                        pairs,
                        inputs: &inputs,
                        forces: f,
                        outputs,
                        direction,
                        time_step: dt,
                        skipped,
                    };
                    let (failure, sum, settled) = kernel.run();
                    if let Some(j) = failure {
                        first_failure.fetch_min(first + j, Ordering::Relaxed);
                    }
                    *partial = sum;
                    // The batches settled without the kernel (every pair culled
                    // and released): skipped until the nodes may have moved as
                    // far as the closest of them is from the cull distance.
                    for (b, deadline) in deadlines.iter_mut().enumerate() {
                        if skipped >> b & 1 == 1 {
                            continue;
                        }
                        *deadline = f64::NEG_INFINITY;
                        if !broad_phase || settled >> b & 1 == 0 {
                            continue;
                        }
                        let lanes = (clearances.len() - b * PAIR_LANES).min(PAIR_LANES);
                        let budget = (0..lanes).fold(f64::INFINITY, |least, w| {
                            let c = &clearances[b * PAIR_LANES + w];
                            let y = Vector3::new(
                                inputs[b].position[0][w],
                                inputs[b].position[1][w],
                                inputs[b].position[2][w],
                            );
                            let room = c.slack - (y - c.centre).norm() - CLEARANCE_TOLERANCE;
                            if room >= least { least } else { room }
                        });
                        if budget > 0.0 {
                            *deadline = travelled + budget;
                        }
                    }
                },
            );
        if let Some(i) = Some(first_failure.into_inner()).filter(|i| *i != usize::MAX) {
            return Err(self.failure(i, "the contact kernel rejected the state".into()));
        }
        let reaction = self.partials.iter().fold(0.0, |s, p| s + p);
        tool_out[..3].fill(0.0);
        tool_out[3] = reaction;
        self.tool_force = reaction;
        Ok(())
    }

    /// `max_n ω_n²` of the contact springs on the node dofs (with the
    /// tool's curvature and the current forces, `docs/contact-kernels.md`),
    /// and for a floating tool `Σ_n ω_n² m_n / M` on its dof: each spring
    /// `H_n` acts on `y_n = x_n − q d`, so the node block is block-diagonal
    /// (`‖H_n‖/m_n ≤ ω_n²`), the tool's block is `Σ_n dᵀH_n d / M`, and the
    /// coupling block's squared norm `Σ_n |H_n d|²/(m_n M)` is at most the
    /// product of the two ([`FrequencyBound`]). The curvature counts only
    /// where the node presses into the tool (`p > 0` or `|t| > 0`): there
    /// the tool is queried again at the node's last relative position (the
    /// one [`Term::explicit_forces`] saw, so the same answer), which keeps
    /// the Hessian out of the force pass.
    fn frequency_bound(
        &self,
        _state: &State,
        masses: &Masses,
    ) -> Result<FrequencyBound, TermFailure> {
        if self.springs.is_empty() {
            return Ok(FrequencyBound::default());
        }
        let node_bound = |i: usize| {
            let o = &self.outputs[i];
            let penetration = if o.gap < 0.0 { -o.gap } else { 0.0 };
            let curvature = if penetration > 0.0 || o.friction_force > 0.0 {
                let batch = &self.pairs[i / PAIR_LANES];
                let w = i % PAIR_LANES;
                let y = Vector3::new(
                    batch.previous_position[0][w],
                    batch.previous_position[1][w],
                    batch.previous_position[2][w],
                );
                self.surface
                    .closest(&y, self.offsets[i] + EXPLICIT_CULL_MARGIN)
                    .map_or(0.0, |p| max_curvature(&p.hessian))
            } else {
                0.0
            };
            self.springs[i].frequency_squared(
                masses.node[self.nodes[i]],
                penetration,
                o.friction_force,
                curvature,
            )
        };
        // Per node in parallel; the maximum and the tool's sum then in node
        // order (the same sum on any number of threads).
        let first_failure = AtomicUsize::new(usize::MAX);
        let bounds: Vec<f64> = (0..self.nodes.len())
            .into_par_iter()
            .with_min_len(NODE_CHUNK)
            .map(|i| {
                node_bound(i).unwrap_or_else(|_| {
                    first_failure.fetch_min(i, Ordering::Relaxed);
                    0.0
                })
            })
            .collect();
        if let Some(i) = Some(first_failure.into_inner()).filter(|i| *i != usize::MAX) {
            let reason = node_bound(i)
                .err()
                .map_or_else(String::new, |e| e.to_string());
            return Err(self.failure(i, reason));
        }
        let nodes = bounds.iter().fold(0.0_f64, |m, b| m.max(*b));
        let tool_mass = masses.extra[self.extra];
        let extras = if tool_mass > 0.0 {
            bounds
                .iter()
                .zip(&self.nodes)
                .fold(0.0, |sum, (b, n)| sum + b * masses.node[*n])
                / tool_mass
        } else {
            0.0
        };
        Ok(FrequencyBound { nodes, extras })
    }

    fn energy(&mut self, _state: &State) -> Result<TermEnergy, TermFailure> {
        if self.springs.is_empty() {
            // Quasi-static: the normal potential and the committed friction
            // work.
            let contact = self
                .responses
                .iter()
                .zip(&self.penalties)
                .map(|(r, e)| 0.5 * r.normal_force * r.normal_force / e)
                .sum();
            return Ok(TermEnergy {
                contact,
                dissipated: self.dissipated,
                ..Default::default()
            });
        }
        // Node by node in node order, as the one-pair state sums them.
        let (contact, dissipated) = (0..self.nodes.len()).fold((0.0, 0.0), |(e, d), i| {
            let (batch, w) = (&self.pairs[i / PAIR_LANES], i % PAIR_LANES);
            (
                e + (batch.normal_energy[w] + batch.tangential_energy[w]),
                d + batch.dissipated[w] + batch.damped_energy[w],
            )
        });
        Ok(TermEnergy {
            contact,
            dissipated,
            ..Default::default()
        })
    }
}

/// The batches of one node chunk for the explicit penalty kernel: the
/// pairs' state and the kernel's input, and where the nodes' forces and
/// outputs go.
struct KernelChunk<'a> {
    pairs: &'a mut [PenaltyBatch<PAIR_LANES>],
    /// The compliant layer's laws of the batches (`None`: linear).
    layers: Option<&'a [[NodalCompaction; PAIR_LANES]]>,
    inputs: &'a [PenaltyInput<PAIR_LANES>],
    forces: &'a mut [f64],
    outputs: &'a mut [NodeContact],
    direction: Vector3<f64>,
    time_step: f64,
    /// Bit `b`: batch `b` is skipped (nothing read, nothing written).
    skipped: u64,
}

impl KernelChunk<'_> {
    /// The kernel on the batches with a pair to update, four lanes at once
    /// where the CPU has AVX2, else one at a time (the same bits either
    /// way): the lowest chunk-local node index of a pair the kernel
    /// rejected, the force on the tool's dof `−Σ d·r` in node order, and
    /// the mask of the batches settled without the kernel.
    fn run(self) -> (Option<usize>, f64, u64) {
        #[cfg(target_arch = "x86_64")]
        if let Some(simd) = pulp::x86::V3::try_new() {
            return <pulp::x86::V3 as pulp::Simd>::vectorize(
                simd,
                Avx2Kernel { simd, chunk: self },
            );
        }
        self.batches(OneByOne)
    }

    /// `kernel` on every batch with a pair that is not culled and released
    /// (the others only move their previous position on; the skipped ones
    /// are left as they are), then each node's force and outputs.
    #[inline(always)]
    fn batches(self, mut kernel: impl PairKernel) -> (Option<usize>, f64, u64) {
        let mut first_failure = None;
        let mut sum = 0.0;
        let mut settled = 0_u64;
        let mut result = PenaltyOutput::<PAIR_LANES>::default();
        for (b, (((batch, input), forces), outputs)) in self
            .pairs
            .iter_mut()
            .zip(self.inputs)
            .zip(self.forces.chunks_mut(4 * PAIR_LANES))
            .zip(self.outputs.chunks_mut(PAIR_LANES))
            .enumerate()
        {
            if self.skipped >> b & 1 == 1 {
                continue;
            }
            let mut active = 0_u32;
            for w in 0..outputs.len() {
                if !(input.distance[w] == f64::INFINITY && batch.released(w)) {
                    active |= 1 << w;
                }
            }
            if active == 0 {
                batch.previous_position = input.position;
                settled |= 1 << b;
            } else {
                let layer = self.layers.map(|l| &l[b]);
                let failed =
                    kernel.apply(batch, input, &mut result, self.time_step, layer) & active;
                if failed != 0 && first_failure.is_none() {
                    first_failure = Some(b * PAIR_LANES + failed.trailing_zeros() as usize);
                }
            }
            for (w, (fi, o)) in forces
                .chunks_exact_mut(4)
                .zip(outputs.iter_mut())
                .enumerate()
            {
                if active & (1 << w) == 0 {
                    fi.fill(0.0);
                    o.status = 0;
                    o.normal_force = 0.0;
                    o.friction_force = 0.0;
                    continue;
                }
                let residual = Vector3::new(
                    result.residual[0][w],
                    result.residual[1][w],
                    result.residual[2][w],
                );
                fi[..3].copy_from_slice(residual.as_slice());
                fi[3] = 0.0;
                sum -= self.direction.dot(&residual);
                o.status = batch.status[w] as u8;
                o.normal_force = result.normal_force[w];
                o.friction_force = result.friction_force[w];
                o.gap = result.gap[w];
                o.slip = batch.slip_length[w];
            }
        }
        (first_failure, sum, settled)
    }
}

/// The penalty kernel on one batch of pairs, as [`KernelChunk::batches`]
/// calls it. A trait with an always-inlined method, not a closure: a
/// closure's body is compiled as a function of its own, without the
/// x86-64-v3 features of the function that calls it, so the SIMD
/// operations in it would become calls (`docs/benchmarks.md`, "Where the
/// time goes").
trait PairKernel {
    /// [`penalty_lanes`] or [`penalty_lanes_one_by_one`] on `batch`.
    fn apply(
        &mut self,
        batch: &mut PenaltyBatch<PAIR_LANES>,
        input: &PenaltyInput<PAIR_LANES>,
        output: &mut PenaltyOutput<PAIR_LANES>,
        time_step: f64,
        layer: Option<&[NodalCompaction; PAIR_LANES]>,
    ) -> u32;
}

/// The kernel one lane at a time.
struct OneByOne;

impl PairKernel for OneByOne {
    #[inline(always)]
    fn apply(
        &mut self,
        batch: &mut PenaltyBatch<PAIR_LANES>,
        input: &PenaltyInput<PAIR_LANES>,
        output: &mut PenaltyOutput<PAIR_LANES>,
        time_step: f64,
        layer: Option<&[NodalCompaction; PAIR_LANES]>,
    ) -> u32 {
        penalty_lanes_one_by_one(batch, input, output, time_step, layer)
    }
}

/// The kernel on four AVX2 lanes.
#[cfg(target_arch = "x86_64")]
struct FourLanes(crate::material::lanes::x86::F64x4);

#[cfg(target_arch = "x86_64")]
impl PairKernel for FourLanes {
    #[inline(always)]
    fn apply(
        &mut self,
        batch: &mut PenaltyBatch<PAIR_LANES>,
        input: &PenaltyInput<PAIR_LANES>,
        output: &mut PenaltyOutput<PAIR_LANES>,
        time_step: f64,
        layer: Option<&[NodalCompaction; PAIR_LANES]>,
    ) -> u32 {
        crate::contact::kernel::penalty_lanes(self.0, batch, input, output, time_step, layer)
    }
}

/// [`KernelChunk::batches`] on four AVX2 lanes, as a `pulp` operation: the
/// kernel is inlined into pulp's function compiled for x86-64-v3.
#[cfg(target_arch = "x86_64")]
struct Avx2Kernel<'a> {
    simd: pulp::x86::V3,
    chunk: KernelChunk<'a>,
}

#[cfg(target_arch = "x86_64")]
impl pulp::WithSimd for Avx2Kernel<'_> {
    type Output = (Option<usize>, f64, u64);

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) -> (Option<usize>, f64, u64) {
        let ctx = crate::material::lanes::x86::F64x4::new(self.simd, [0.0; PAIR_LANES]);
        self.chunk.batches(FourLanes(ctx))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The messages read as they did when they were Strings.
    #[test]
    fn penalty_errors_keep_their_wording() {
        let error = ExplicitPenalty::PerArea(-2.0)
            .stiffness(1.0, 0.25, 1e-6)
            .unwrap_err();
        assert_eq!(
            error.to_string(),
            "penalty -2 N/mm³ on a nodal area 0.25 mm²: expected both positive"
        );
        let error = ExplicitPenalty::StableFraction(1.5)
            .stiffness(1.0, 0.25, 1e-6)
            .unwrap_err();
        let kernel = stable_penalty_stiffness(1.0, 1e-6, 1.5).unwrap_err();
        assert_eq!(error.to_string(), kernel.to_string());
    }
}
