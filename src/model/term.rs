//! The force-term interface both solvers drive.
//!
//! A model's total potential is a sum of terms (membrane, bending, contact,
//! body and dead loads). A term couples the dofs of *stencils*: groups of
//! node slots (three dofs each, `3 n + k`) and extra-dof slots (the dofs of
//! rigid bodies, numbered after the nodes). Each stencil has the same
//! shape within a term, so the solvers can lay out one buffer per term,
//! build the sparse pattern once, and gather nodal forces in a fixed order.
//!
//! Local dof order within a stencil: node slot 0 (x, y, z), node slot 1, …,
//! then the extra slots. A slot may be unused ([`NO_SLOT`]); its entries
//! are then ignored.
//!
//! Sign convention: a term contributes to the residual
//! `r = ∂Π/∂u = f_internal − f_external` (a load term writes `−f`).

use std::fmt;

/// Marks an unused node or extra slot of a stencil.
pub const NO_SLOT: usize = usize::MAX;

/// The shape of a term's stencils.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Stencils {
    /// Number of stencils.
    pub count: usize,
    /// Node slots per stencil (three dofs each).
    pub nodes: usize,
    /// Extra-dof slots per stencil (one dof each).
    pub extras: usize,
}

impl Stencils {
    /// Dofs per stencil: `3 nodes + extras`.
    pub fn size(&self) -> usize {
        3 * self.nodes + self.extras
    }
}

/// The state a term is evaluated at.
#[derive(Debug, Clone, Copy)]
pub struct State<'a> {
    /// Displacement of every dof: 3 per node, then the extra dofs \[mm\].
    pub u: &'a [f64],
    /// The load parameter `λ` the solver drives (a clamp or tool
    /// displacement \[mm\], or a load fraction).
    pub load: f64,
    /// `λ / λ_final` in `[0, 1]`: the fraction of the load programme, which
    /// ramped loads follow.
    pub load_fraction: f64,
    /// The time increment that led to this state \[s\] (explicit path; 0 on
    /// the quasi-static path and at the start).
    pub time_step: f64,
    /// An upper bound of the distance any node moved from the state of the
    /// previous force pass to this one \[mm\] (explicit path, measured by
    /// the node pass); `+∞` where it is not known (the start, the
    /// quasi-static path). A term may use it to skip nodes it has proved
    /// far (`docs/contact.md`, "Explicit path: batches proved far").
    pub motion: f64,
}

impl<'a> State<'a> {
    /// The displacement `u` at the start of the load programme
    /// (`λ = 0`).
    pub fn at(u: &'a [f64]) -> Self {
        Self {
            u,
            load: 0.0,
            load_fraction: 0.0,
            time_step: 0.0,
            motion: f64::INFINITY,
        }
    }
}

/// `distance` rounded up by a relative 10⁻¹² and 10⁻¹² mm: what the
/// bounds of nodes' motion (`State::motion` and the sums terms keep of it)
/// add so that they stay bounds under the round-off of the differences,
/// products and sums that form them \[mm\].
#[inline]
pub fn rounded_up(distance: f64) -> f64 {
    distance * (1.0 + 1e-12) + 1e-12
}

/// A term's energies [N·mm], by kind, for the energy balance.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct TermEnergy {
    /// Strain energy (membrane, bending).
    pub internal: f64,
    /// Elastic energy stored in contact penalties and friction springs.
    pub contact: f64,
    /// Work done on the model by the term's external forces (loads).
    pub external_work: f64,
    /// Energy dissipated (friction).
    pub dissipated: f64,
}

impl std::ops::AddAssign for TermEnergy {
    fn add_assign(&mut self, other: Self) {
        self.internal += other.internal;
        self.contact += other.contact;
        self.external_work += other.external_work;
        self.dissipated += other.dissipated;
    }
}

/// What an augmentation (a multiplier update between Newton solves at one
/// load) found, for the convergence test and the step report.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Augmentation {
    /// `true` when the term's constraints are satisfied to its tolerances
    /// at the state the multipliers were updated from.
    pub converged: bool,
    /// Largest penetration (negative gap) \[mm\].
    pub max_penetration: f64,
    /// `‖λ_new − λ_old‖ / max(‖λ_new‖, floor)`: the relative change of the
    /// multipliers.
    pub multiplier_change: f64,
    /// Active contacts (closed node–tool pairs).
    pub active: usize,
    /// Of those, pairs in slip.
    pub slipping: usize,
    /// The model's node of the largest penetration, if any node
    /// penetrates (for messages: [`crate::model::Model::describe_node`]).
    #[serde(skip)]
    pub deepest: Option<usize>,
}

impl Augmentation {
    /// Combines the reports of two terms: converged only if both are.
    pub fn merge(self, other: Self) -> Self {
        let deepest = if other.max_penetration > self.max_penetration {
            other.deepest
        } else {
            self.deepest
        };
        Self {
            converged: self.converged && other.converged,
            max_penetration: self.max_penetration.max(other.max_penetration),
            multiplier_change: self.multiplier_change.max(other.multiplier_change),
            active: self.active + other.active,
            slipping: self.slipping + other.slipping,
            deepest,
        }
    }
}

/// Lumped masses of the explicit solver \[t\], written by the terms that
/// carry mass.
#[derive(Debug, Clone, PartialEq)]
pub struct Masses {
    /// Per node (all three dofs share it).
    pub node: Vec<f64>,
    /// Per extra dof.
    pub extra: Vec<f64>,
}

/// A term's bound of `λmax` of its mass-scaled stiffness
/// `S = M^{-1/2} K_term M^{-1/2}` [1/s²], split by the kind of dof
/// (`docs/explicit.md`, "The stable time step"): `nodes` bounds the block
/// on node dofs, `extras` the block on extra dofs (a floating tool's
/// translation), and the coupling block `C` between them obeys
/// `‖C‖² ≤ nodes · extras`. The term's whole `λmax(S)` is then at most
/// `nodes + extras` ([`FrequencyBound::total`]). A term without extra
/// dofs has `extras = 0`.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrequencyBound {
    /// Bound of the node-dof block [1/s²].
    pub nodes: f64,
    /// Bound of the extra-dof block [1/s²].
    pub extras: f64,
}

impl FrequencyBound {
    /// A bound on node dofs only.
    pub fn nodes(nodes: f64) -> Self {
        Self { nodes, extras: 0.0 }
    }

    /// `nodes + extras`: the largest eigenvalue of
    /// `[[nodes, √(nodes·extras)], [√(nodes·extras), extras]]`, which
    /// bounds the term's whole `λmax(S)` (Rayleigh quotient on the two
    /// blocks) [1/s²].
    pub fn total(&self) -> f64 {
        self.nodes + self.extras
    }

    /// Both parts times `factor`.
    pub fn scaled(&self, factor: f64) -> Self {
        Self {
            nodes: factor * self.nodes,
            extras: factor * self.extras,
        }
    }
}

/// A coupling mass between two nodes added to the lumped mass matrix
/// (roving mass scaling, `docs/explicit.md`): `mass (e_a − e_b)(e_a −
/// e_b)ᵀ ⊗ I3` on every component of their relative motion, or, with
/// `stretch`, `mass (e_a − e_b)(e_a − e_b)ᵀ ⊗ d dᵀ` on its component
/// along the pair's *current* direction `d = (x_b − x_a)/|x_b − x_a|`
/// only (the rate of stretch of the segment). Either leaves rigid
/// translations' kinetic energy unchanged; the stretch form also leaves
/// the segment's rotation and every motion across it unchanged.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassCoupling {
    /// The two nodes.
    pub nodes: [usize; 2],
    /// The coupling mass \[t\].
    pub mass: f64,
    /// With the stretch form: the reference vector `X_b − X_a` from the
    /// first node to the second \[mm\] (the current one is this plus the
    /// displacement difference); `None` for the form on all components.
    pub stretch: Option<[f64; 3]>,
}

/// What mass scaling did to one term \[t\].
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct MassScaling {
    /// Physical mass of the term.
    pub physical: f64,
    /// Mass added.
    pub added: f64,
    /// Elements whose density was raised.
    pub scaled_elements: usize,
}

/// Why a term could not be evaluated: the term, the stencil (element,
/// node, …) and the cause.
#[derive(Debug, Clone, PartialEq)]
pub struct TermFailure {
    /// The term's name.
    pub term: String,
    /// What a stencil of this term is ("element", "node", …).
    pub what: &'static str,
    /// Lowest index of the failing stencils.
    pub index: usize,
    /// The cause.
    pub reason: String,
}

impl fmt::Display for TermFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} {} {}: {}",
            self.term, self.what, self.index, self.reason
        )
    }
}

impl std::error::Error for TermFailure {}

/// One contribution to the model: its energy, forces and tangent at a
/// state (quasi-static path), and for the explicit path its nodal forces,
/// a bound on its highest frequency, its masses and its energies. Neither
/// solver knows which terms exist: they call these methods only.
pub trait Term: Send + Sync + std::any::Any {
    /// A short name for messages and reports ("membrane", "contact punch").
    fn name(&self) -> &str;

    /// The stencil shape.
    fn stencils(&self) -> Stencils;

    /// The node and extra indices of stencil `s` ([`NO_SLOT`] for an unused
    /// slot); `nodes.len()` and `extras.len()` are those of
    /// [`Term::stencils`].
    fn stencil(&self, s: usize, nodes: &mut [usize], extras: &mut [usize]);

    /// The term's potential energy [N·mm] at `state`, its residual
    /// contribution per stencil into `force` (`count × size`, local dof
    /// order) and, if asked, its tangent `∂r/∂u` per stencil into `tangent`
    /// (`count × size²`, column-major per stencil). Every entry is written
    /// (zeros where the term does not act).
    ///
    /// # Errors
    /// The lowest-index stencil that cannot be evaluated.
    fn evaluate(
        &mut self,
        state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure>;

    /// `true` when the tangent is symmetric (a symmetric factorisation may
    /// be used).
    fn symmetric(&self) -> bool {
        true
    }

    /// Between two Newton solves at one load: update the multipliers from
    /// the converged `state`. `None` when the term has nothing to augment.
    fn augment(&mut self, _state: &State) -> Option<Augmentation> {
        None
    }

    /// A load step converged at `state`: its history (friction reference,
    /// multipliers) becomes the start of the next step.
    fn commit(&mut self, _state: &State) {}

    /// A load step failed: return to the state of the last commit.
    fn restore(&mut self) {}

    // --- explicit path ---------------------------------------------------

    /// Checks what the explicit path needs of this term (a mass density,
    /// say) before anything is built.
    ///
    /// # Errors
    /// What is missing or out of range, by name and value.
    fn validate_explicit(&self) -> Result<(), TermFailure> {
        Ok(())
    }

    /// The stencil shape of the explicit force buffer (by default that of
    /// [`Term::stencils`]).
    fn explicit_stencils(&self) -> Stencils {
        self.stencils()
    }

    /// The slots of explicit stencil `s` (by default [`Term::stencil`]).
    fn explicit_stencil(&self, s: usize, nodes: &mut [usize], extras: &mut [usize]) {
        self.stencil(s, nodes, extras);
    }

    /// Adds the term's lumped masses \[t\] (after any mass scaling) and
    /// returns its physical mass \[t\].
    fn lumped_masses(&self, _masses: &mut Masses) -> f64 {
        0.0
    }

    /// Adds the term's coupling masses (in any order; repeated pairs add
    /// up); none by default.
    fn mass_couplings(&self, _out: &mut Vec<MassCoupling>) {}

    /// Raises the term's mass where its own stable step at `state` is below
    /// `target` (mass scaling); `safety` is the step's safety factor.
    ///
    /// # Errors
    /// A stencil that cannot be evaluated.
    fn scale_masses(
        &mut self,
        _state: &State,
        _target: f64,
        _safety: f64,
    ) -> Result<MassScaling, TermFailure> {
        Ok(MassScaling::default())
    }

    /// Called once before the time loop with the lumped masses and the
    /// stable step of the model without this term's stiffness \[s\] (a
    /// penalty term picks its stiffness from them).
    ///
    /// # Errors
    /// A setting that cannot be met.
    fn explicit_setup(
        &mut self,
        _state: &State,
        _masses: &Masses,
        _time_step: f64,
    ) -> Result<(), TermFailure> {
        Ok(())
    }

    /// `true` when the term's stiffness was chosen from the stable step in
    /// [`Term::explicit_setup`] (it is then left out of the step estimate
    /// that feeds the set-up).
    fn stiffness_from_time_step(&self) -> bool {
        false
    }

    /// The residual contribution per explicit stencil into `out`
    /// (`count × size` of [`Term::explicit_stencils`]), once per time
    /// increment; history (friction springs, load work) advances here. By
    /// default [`Term::evaluate`] without tangent.
    ///
    /// # Errors
    /// The lowest-index stencil that cannot be evaluated.
    fn explicit_forces(&mut self, state: &State, out: &mut [f64]) -> Result<(), TermFailure> {
        self.evaluate(state, out, None).map(|_| ())
    }

    /// `false` when the term has no stiffness, so that its
    /// [`Term::frequency_bound`] is always zero (loads, masses): the
    /// explicit step estimate then does not treat the nodes it touches as
    /// coupled.
    fn has_stiffness(&self) -> bool {
        true
    }

    /// Upper bounds of `λmax(M⁻¹ K_term)` [1/s²] at `state` with the
    /// lumped masses `masses`, split by the kind of dof
    /// ([`FrequencyBound`]): the explicit solver combines the terms' bounds
    /// into a bound of the model's `ω²_max` (`docs/explicit.md`, "The
    /// stable time step"). Zero for a term without stiffness.
    ///
    /// # Errors
    /// The lowest-index stencil that cannot be evaluated.
    fn frequency_bound(
        &self,
        _state: &State,
        _masses: &Masses,
    ) -> Result<FrequencyBound, TermFailure> {
        Ok(FrequencyBound::default())
    }

    /// The term's energies at `state` (explicit outputs).
    ///
    /// # Errors
    /// The lowest-index stencil that cannot be evaluated.
    fn energy(&mut self, state: &State) -> Result<TermEnergy, TermFailure>;
}
