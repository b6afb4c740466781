//! Penalty node-to-rigid-surface contact with a regularised Coulomb law
//! (an elastic–plastic tangential spring), for the central-difference
//! solver.
//!
//! Per node–tool pair the state holds the elastic tangential spring `s_e`
//! (world frame, tangent to the last plane) and the previous relative
//! position `y_prev`. A call with the new `y` (doc Sec. "Explicit kernel"):
//!
//! ```text
//! g = d − offset,  p = ⟨−g⟩,  f_N = k_N p                 (Eq. E1, contact iff g < 0)
//! Δs = P (y − y_prev),  s̄ = P s_e                         (Eq. E2, P = I − n⊗n at y)
//! t* = k_T (s̄ + Δs)
//! stick |t*| ≤ μ f_N:  t = t*,  s_e ← s̄ + Δs,  Δs_p = 0    (Eq. E3)
//! slip  |t*| > μ f_N:  t = μ f_N t*/|t*|,  s_e ← t/k_T,  Δs_p = (t* − t)/k_T
//! r_y = −f_c = −f_N n + t                                 (Eq. E4)
//! ```
//!
//! Energy bookkeeping (Eq. E5–E7): stored `E = ½ k_N p² + ½ k_T |s_e|²`;
//! the call dissipates
//!
//! ```text
//! D = ½ k_T (n·s_e,old)²  +  ½ (k_T s̄ + t)·Δs_p
//! ```
//!
//! (the spring energy lost by the re-projection, and the plastic slip times
//! the trapezoidal mean of the old and new friction force). With the work
//! the solver integrates by the trapezoidal rule, `W = Σ ½ (r_n + r_{n+1})·Δy`,
//! `W = ΔE + D` holds exactly on a plane and up to `½ (n·t_old)(n·Δy)`
//! plus the `O(|Δy|³)` quadrature error of the normal force per step on a
//! curved tool. When the contact opens the spring is released through the
//! same slip formula with `f_N = 0` and the state is reset.

use nalgebra::{Matrix3, Vector3};

use super::compaction::NodalCompaction;
use super::{
    ContactError, ContactStatus, check_point, check_scalar, check_vector, finite_result,
    non_negative, positive,
};
use crate::contact::{SurfaceNormal, SurfacePoint};

/// The central-difference limit for one contact spring on a node of mass
/// `mass` \[t\] (doc Sec. "Stiffness limit"): `k = c · 4 m / Δt²` [N/mm] for
/// the time step `time_step` \[s\] and a fraction `c = fraction ∈ (0, 1]`.
/// One spring `k` on a mass `m` is stable for `ω Δt ≤ 2`, i.e.
/// `k ≤ 4 m/Δt²`; the node's other stiffness (the membrane) needs the rest:
/// with the step at `s · 2/ω_membrane`, `c ≤ 1 − s²` keeps the sum stable.
///
/// # Errors
/// A mass or step that is not positive and finite, or `c ∉ (0, 1]`.
pub fn stable_penalty_stiffness(
    mass: f64,
    time_step: f64,
    fraction: f64,
) -> Result<f64, ContactError> {
    let mass = positive("mass", mass)?;
    let time_step = positive("time_step", time_step)?;
    if !(fraction > 0.0 && fraction <= 1.0) {
        return Err(ContactError::InvalidSetting {
            name: "fraction",
            value: fraction,
            expected: "a value in (0, 1]",
        });
    }
    let stiffness = fraction * 4.0 * mass / (time_step * time_step);
    if stiffness.is_finite() && stiffness > 0.0 {
        Ok(stiffness)
    } else {
        Err(ContactError::InvalidSetting {
            name: "time_step",
            value: time_step,
            expected: "a step for which c·4m/Δt² is finite and > 0",
        })
    }
}

/// The largest `|κ|` of a surface Hessian `H` [1/mm] with the normal in its
/// null space (the [`SurfacePoint`] contract): its two other eigenvalues
/// are `(tr H ± √(2‖H‖² − (tr H)²))/2` (`‖·‖` Frobenius), so
/// `max |κ| = (|tr H| + √(2‖H‖² − (tr H)²))/2` (doc Sec. "Frequency bound").
#[inline]
pub fn max_curvature(hessian: &Matrix3<f64>) -> f64 {
    let trace = hessian.trace();
    let spread = (2.0 * hessian.norm_squared() - trace * trace).max(0.0);
    0.5 * (trace.abs() + spread.sqrt())
}

/// Settings of the explicit penalty contact of one ply–tool pair (doc Sec.
/// "Explicit kernel").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyContact {
    normal_stiffness: f64,
    tangential_stiffness: f64,
    friction: f64,
    offset: f64,
    /// The compliant layer's law in place of the linear normal spring
    /// ([`super::compaction`]); `None`: `f_N = k_N p`.
    compaction: Option<NodalCompaction>,
}

impl PenaltyContact {
    /// Settings with normal stiffness `k_N` [N/mm] `> 0`, tangential
    /// (stick) stiffness `k_T` [N/mm] `> 0`, Coulomb coefficient `μ ≥ 0`
    /// and the mid-surface offset \[mm\] `≥ 0`.
    ///
    /// # Errors
    /// A setting that is not finite or out of its range.
    pub fn new(
        normal_stiffness: f64,
        tangential_stiffness: f64,
        friction: f64,
        offset: f64,
    ) -> Result<Self, ContactError> {
        Ok(Self {
            normal_stiffness: positive("normal_stiffness", normal_stiffness)?,
            tangential_stiffness: positive("tangential_stiffness", tangential_stiffness)?,
            friction: non_negative("friction", friction)?,
            offset: non_negative("offset", offset)?,
            compaction: None,
        })
    }

    /// The same settings with the normal force of the compliant layer
    /// `compaction` (Eq. C1–C4 of [`super::compaction`]) in place of
    /// `k_N p`; its tangent is capped at `k_N`, so the frequency bound
    /// below still holds.
    pub fn with_compaction(mut self, compaction: NodalCompaction) -> Self {
        self.compaction = Some(compaction);
        self
    }

    /// The compliant layer's law, if any.
    pub fn compaction(&self) -> Option<&NodalCompaction> {
        self.compaction.as_ref()
    }

    /// The normal force \[N\] and stored normal energy [N·mm] at the
    /// penetration `penetration > 0` \[mm\]: `k_N p` and `½ k_N p²`, or the
    /// compliant layer's (Eq. C1–C4).
    #[inline(always)]
    pub fn normal_response(&self, penetration: f64) -> (f64, f64) {
        match &self.compaction {
            Some(c) => c.force_and_energy(penetration),
            None => {
                let normal_force = self.normal_stiffness * penetration;
                (normal_force, 0.5 * normal_force * penetration)
            }
        }
    }

    /// Settings with `k_N = k_T = c · 4 m/Δt²` from
    /// [`stable_penalty_stiffness`] (the two springs act on orthogonal
    /// directions, so each may take the fraction `c`).
    ///
    /// # Errors
    /// As [`stable_penalty_stiffness`] and [`PenaltyContact::new`].
    pub fn from_stable_step(
        mass: f64,
        time_step: f64,
        fraction: f64,
        friction: f64,
        offset: f64,
    ) -> Result<Self, ContactError> {
        let stiffness = stable_penalty_stiffness(mass, time_step, fraction)?;
        Self::new(stiffness, stiffness, friction, offset)
    }

    /// Changes the mid-surface offset \[mm\].
    ///
    /// # Errors
    /// An offset that is negative or not finite.
    pub fn set_offset(&mut self, offset: f64) -> Result<(), ContactError> {
        self.offset = non_negative("offset", offset)?;
        Ok(())
    }

    /// `k_N` [N/mm].
    pub fn normal_stiffness(&self) -> f64 {
        self.normal_stiffness
    }

    /// `k_T` [N/mm].
    pub fn tangential_stiffness(&self) -> f64 {
        self.tangential_stiffness
    }

    /// `μ`.
    pub fn friction(&self) -> f64 {
        self.friction
    }

    /// The mid-surface offset \[mm\].
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// The frequency bound `ω²` [1/s²] of one contact spring on a node of
    /// mass `mass` \[t\] (doc Sec. "Frequency bound"):
    ///
    /// ```text
    /// ω² = ( max(k_N, k_T) + C_μ κ (k_N p + 2 |t|) ) / m,   C_μ = ((√(μ² + 4) + μ)/2)²
    /// ```
    ///
    /// with the penetration `p = ⟨−g⟩` \[mm\], the friction force `|t|` \[N\]
    /// and `κ` = [`max_curvature`] of the tool at the node [1/mm]. It
    /// bounds the spectral radius of the contact stiffness `∂r_y/∂y` over
    /// `m`: `max(k_N, k_T)` is that of the flat part, the curvature terms
    /// (rotation of the normal and of the spring) perturb it by at most
    /// `C_μ κ (k_N p + |t| + 2 k_T |n·Δy|)` (Bauer–Fike; `C_μ` is the
    /// condition number of the slip part's eigenvectors), and `2|t|` covers
    /// the step's normal motion while `k_T |n·Δy| ≤ |t|/2`. For a fresh
    /// contact pass zeros: `max(k_N, k_T)/m`.
    ///
    /// # Errors
    /// A mass that is not positive and finite, or a negative or non-finite
    /// penetration, force or curvature.
    pub fn frequency_squared(
        &self,
        mass: f64,
        penetration: f64,
        friction_force: f64,
        curvature: f64,
    ) -> Result<f64, ContactError> {
        let mass = positive("mass", mass)?;
        let penetration = non_negative("penetration", penetration)?;
        let friction_force = non_negative("friction_force", friction_force)?;
        let curvature = non_negative("curvature", curvature)?;
        let mu = self.friction;
        let condition = (0.5 * ((mu * mu + 4.0).sqrt() + mu)).powi(2);
        let stiffness = self.normal_stiffness.max(self.tangential_stiffness)
            + condition * curvature * (self.normal_stiffness * penetration + 2.0 * friction_force);
        Ok(stiffness / mass)
    }

    /// Advances the pair to the relative position `y` \[mm\] (Eq. E1–E7 of
    /// the module doc): force, status, energies and dissipation of the
    /// call. `point` is the surface's answer at `y`; `None` (culled: far
    /// on the free side) is open with `gap = ∞`, and a spring left from a
    /// contact is then released with `P = I`. On error the state is left
    /// unchanged.
    ///
    /// # Errors
    /// A non-finite `y`, surface answer or state, a non-unit normal, or a
    /// response that overflows.
    pub fn update(
        &self,
        state: &mut PenaltyState,
        y: &Vector3<f64>,
        point: Option<&SurfacePoint>,
    ) -> Result<PenaltyResponse, ContactError> {
        check_vector("relative position", y)?;
        state.check()?;
        if let Some(point) = point {
            check_point(point)?;
        }
        let step = self.respond(state, y, point.map(SurfaceNormal::from).as_ref());
        let response = &step.response;
        finite_result("residual", response.residual.iter())?;
        finite_result("tangential spring", response.next_spring.iter())?;
        finite_result(
            "energy",
            [
                response.dissipated,
                response.normal_energy,
                response.tangential_energy,
            ]
            .iter(),
        )?;
        finite_result(
            "accumulated slip",
            [step.slip_length, step.dissipated].iter(),
        )?;
        Ok(step.commit(state, y))
    }

    /// [`PenaltyContact::update`] for the time loop, from the first-order
    /// surface answer ([`crate::contact::RigidSurface::closest_normal`]):
    /// the same response and state, bit for bit, without the input checks.
    /// The caller vouches for its inputs where they enter: `state` as left
    /// by this kernel (or [`PenaltyState::new`] at a finite position) and
    /// `point` from a surface that keeps the [`SurfacePoint`] contract
    /// (finite, unit normal; checked in debug builds). The outputs are
    /// still checked, by one sum: a non-finite `y`, distance or normal, or
    /// an overflow, is an error and leaves the state unchanged.
    ///
    /// # Errors
    /// [`ContactError::NonFiniteResult`] when any output (or input) is not
    /// finite.
    #[inline]
    pub fn update_trusted(
        &self,
        state: &mut PenaltyState,
        y: &Vector3<f64>,
        point: Option<&SurfaceNormal>,
    ) -> Result<PenaltyResponse, ContactError> {
        debug_assert!(point.is_none_or(|p| (p.normal.norm() - 1.0).abs() <= 1e-6));
        let step = self.respond(state, y, point);
        let r = &step.response;
        // Non-finite values (NaN, ±∞) survive a sum; finite ones overflow
        // it only where the response itself is out of range.
        let probe = r.residual.sum()
            + r.next_spring.sum()
            + r.normal.sum()
            + y.sum()
            + r.dissipated
            + r.normal_energy
            + r.tangential_energy
            + step.slip_length
            + step.dissipated
            + if r.gap.is_infinite() { 0.0 } else { r.gap };
        if !probe.is_finite() {
            return Err(ContactError::NonFiniteResult { name: "response" });
        }
        Ok(step.commit(state, y))
    }

    /// The response at `y` and the state's new running sums (Eq. E1–E7),
    /// not yet written to the state.
    #[inline(always)]
    fn respond(
        &self,
        state: &PenaltyState,
        y: &Vector3<f64>,
        point: Option<&SurfaceNormal>,
    ) -> PenaltyStep {
        let k_t = self.tangential_stiffness;
        let motion = y - state.previous_position;
        let (gap, normal) = match point {
            Some(p) => (p.distance - self.offset, p.normal),
            None => (f64::INFINITY, Vector3::zeros()),
        };
        // Eq. E2 (with n = 0, i.e. P = I, when culled).
        let spring_normal = normal.dot(&state.spring);
        let spring_projected = state.spring - spring_normal * normal;
        let projection_loss = 0.5 * k_t * spring_normal * spring_normal;
        let slip_increment = motion - normal.dot(&motion) * normal;
        let trial = k_t * (spring_projected + slip_increment);
        let old_force = k_t * spring_projected;

        let response = if gap < 0.0 {
            let penetration = -gap;
            let (normal_force, normal_energy) = self.normal_response(penetration);
            let limit = self.friction * normal_force;
            let trial_norm = trial.norm();
            let (status, force, spring, plastic) = if self.friction > 0.0 && trial_norm <= limit {
                let spring = spring_projected + slip_increment;
                (ContactStatus::Stick, trial, spring, Vector3::zeros())
            } else {
                // Frictionless, or beyond the limit (trial_norm > 0).
                let direction = if trial_norm > 0.0 {
                    trial / trial_norm
                } else {
                    Vector3::zeros()
                };
                let force = limit * direction;
                let plastic = (trial - force) / k_t;
                (ContactStatus::Slip, force, force / k_t, plastic)
            };
            // Eq. E6: projection loss + plastic slip × mean friction force.
            let dissipated = projection_loss + 0.5 * (old_force + force).dot(&plastic);
            PenaltyResponse {
                status,
                gap,
                normal_force,
                tangential_force: force,
                slip_increment,
                plastic_slip: plastic,
                normal,
                residual: force - normal_force * normal,
                dissipated,
                next_spring: spring,
                normal_energy,
                tangential_energy: 0.5 * k_t * spring.norm_squared(),
            }
        } else {
            // Open: release the spring as a slip with f_N = 0 (Eq. E7).
            let plastic = trial / k_t;
            let dissipated = projection_loss + 0.5 * old_force.dot(&plastic);
            PenaltyResponse {
                status: ContactStatus::Open,
                gap,
                normal_force: 0.0,
                tangential_force: Vector3::zeros(),
                slip_increment: Vector3::zeros(),
                plastic_slip: Vector3::zeros(),
                normal,
                residual: Vector3::zeros(),
                dissipated,
                next_spring: Vector3::zeros(),
                normal_energy: 0.0,
                tangential_energy: 0.0,
            }
        };
        PenaltyStep {
            slip_length: state.slip_length + response.plastic_slip.norm(),
            dissipated: state.dissipated + response.dissipated,
            response,
        }
    }
}

/// A response with the state's new running sums, before they are written.
struct PenaltyStep {
    response: PenaltyResponse,
    slip_length: f64,
    dissipated: f64,
}

impl PenaltyStep {
    /// Writes the step into `state` (now at `y`) and gives the response.
    #[inline]
    fn commit(self, state: &mut PenaltyState, y: &Vector3<f64>) -> PenaltyResponse {
        let response = self.response;
        state.spring = response.next_spring;
        state.previous_position = *y;
        state.status = response.status;
        state.normal_energy = response.normal_energy;
        state.tangential_energy = response.tangential_energy;
        state.dissipated = self.dissipated;
        state.slip_length = self.slip_length;
        response
    }
}

/// The state of one node–tool pair of the explicit kernel.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyState {
    /// The elastic tangential spring `s_e` \[mm\] (world frame, tangent to
    /// the last plane; zero when open).
    pub spring: Vector3<f64>,
    /// `y_prev` \[mm\]: the relative position of the last call.
    pub previous_position: Vector3<f64>,
    /// The status of the last call.
    pub status: ContactStatus,
    /// `½ k_N ⟨−g⟩²` [N·mm] at the last call.
    pub normal_energy: f64,
    /// `½ k_T |s_e|²` [N·mm] at the last call.
    pub tangential_energy: f64,
    /// The friction work dissipated since the pair was created [N·mm].
    pub dissipated: f64,
    /// The accumulated plastic slip length `Σ |Δs_p|` \[mm\] (the sliding
    /// distance; elastic stick motion is not counted).
    pub slip_length: f64,
}

impl PenaltyState {
    /// A fresh, open pair at the relative position `y` \[mm\].
    pub fn new(y: &Vector3<f64>) -> Self {
        Self {
            spring: Vector3::zeros(),
            previous_position: *y,
            status: ContactStatus::Open,
            normal_energy: 0.0,
            tangential_energy: 0.0,
            dissipated: 0.0,
            slip_length: 0.0,
        }
    }

    /// The stored contact energy `½ k_N ⟨−g⟩² + ½ k_T |s_e|²` [N·mm]
    /// (Eq. E5) at the last call.
    pub fn stored_energy(&self) -> f64 {
        self.normal_energy + self.tangential_energy
    }

    fn check(&self) -> Result<(), ContactError> {
        check_vector("tangential spring", &self.spring)?;
        check_vector("previous position", &self.previous_position)?;
        check_scalar("dissipated work", self.dissipated)?;
        check_scalar("slip length", self.slip_length)
    }
}

/// What one [`PenaltyContact::update`] gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyResponse {
    /// Open, stick or slip.
    pub status: ContactStatus,
    /// `g = d − offset` \[mm\] (`∞` when culled).
    pub gap: f64,
    /// `f_N = k_N ⟨−g⟩` \[N\].
    pub normal_force: f64,
    /// The friction force `t` \[N\] (tangent, along the slip; the force on
    /// the node is `−t`); `|t| ≤ μ f_N`.
    pub tangential_force: Vector3<f64>,
    /// `Δs = P (y − y_prev)` \[mm\] (zero when open).
    pub slip_increment: Vector3<f64>,
    /// The plastic slip `Δs_p` \[mm\] of the call (zero in stick and open).
    pub plastic_slip: Vector3<f64>,
    /// The surface normal at `y` (zero when culled).
    pub normal: Vector3<f64>,
    /// `r_y = −f_c = −f_N n + t` \[N\]: the solver adds `−r_y` to the node's
    /// force.
    pub residual: Vector3<f64>,
    /// The energy dissipated by this call [N·mm] (Eq. E6–E7).
    pub dissipated: f64,
    /// `½ k_N ⟨−g⟩²` [N·mm] after the call.
    pub normal_energy: f64,
    /// `½ k_T |s_e|²` [N·mm] after the call.
    pub tangential_energy: f64,
    next_spring: Vector3<f64>,
}

impl PenaltyResponse {
    /// The contact force on the node `f_c = f_N n − t = −r_y` \[N\].
    pub fn force(&self) -> Vector3<f64> {
        -self.residual
    }

    /// The stored energy after the call [N·mm].
    pub fn stored_energy(&self) -> f64 {
        self.normal_energy + self.tangential_energy
    }
}

/// The normal dashpot of a penalty pair for the explicit path
/// (`docs/contact.md`, "Explicit path"): while the pair penetrates
/// (`response.gap < 0`), the force `c · (−n·Δy)/Δt` along the normal on
/// the approach velocity, never pulling the node onto the surface (at
/// least `−f_N`); `Δy = motion` over the step `time_step` \[s\] with the
/// dashpot `c` [N·s/mm]. Returns the dashpot's force on the node (to be
/// subtracted from the residual) and adds its dissipation, the
/// trapezoidal work `−½ (F_{n−1} + F_n)·Δy`, to `dissipated` (energy
/// \[N·mm\], the last force \[N\]).
#[inline]
pub fn normal_dashpot(
    dashpot: f64,
    response: &PenaltyResponse,
    motion: &Vector3<f64>,
    time_step: f64,
    dissipated: &mut (f64, Vector3<f64>),
) -> Vector3<f64> {
    let mut force_vector = Vector3::zeros();
    if response.gap < 0.0 && time_step > 0.0 && dashpot > 0.0 {
        let approach = -response.normal.dot(motion);
        let force = (dashpot * approach / time_step).max(-response.normal_force);
        force_vector = force * response.normal;
    }
    let (energy, previous) = dissipated;
    *energy -= 0.5 * (*previous + force_vector).dot(motion);
    *previous = force_vector;
    force_vector
}
