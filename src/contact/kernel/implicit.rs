//! Augmented Lagrangian node-to-rigid-surface contact with Coulomb friction
//! (the Simo–Laursen / Alart–Curnier family), for the Newton solver.
//!
//! Per node–tool pair a state holds the multipliers `λ_N ≥ 0`, `λ_T` and
//! the slip reference `y_ref` (the relative position at the last converged
//! load step). With `g = d(y) − offset`, `P = I − n⊗n` at `y`,
//! `v = y − y_ref` and penalties `ε_N`, `ε_T` (doc Sec. "Implicit kernel"):
//!
//! ```text
//! t_N = ⟨λ_N − ε_N g⟩                        (Eq. I1, active on the closed side: ≥ 0)
//! Δs  = P v,   w = λ_T + ε_T v,   t* = P w   (Eq. I2: trial = P λ_T + ε_T Δs)
//! stick  |t*| ≤ μ t_N:  t_T = t*             (Eq. I3)
//! slip   |t*| > μ t_N:  t_T = μ t_N t*/|t*|
//! r_y = −t_N n + t_T                         (Eq. I4)
//! ```
//!
//! and the exact tangent `K = ∂r_y/∂y` (Eq. I5–I7):
//!
//! ```text
//! K_N  = ε_N n⊗n − t_N H
//! A    = ∂t*/∂y = ε_T P − (n·w) H − n ⊗ (H w)
//! stick: K = K_N + A
//! slip:  K = K_N − μ ε_N t̂ ⊗ n + (μ t_N/|t*|) (I − t̂⊗t̂) A,   t̂ = t*/|t*|
//! ```
//!
//! Between Newton solves the Uzawa update sets `λ_N ← t_N`, `λ_T ← t_T`
//! ([`ImplicitContactState::augment`]).

use nalgebra::{Matrix3, Vector3};

use super::{
    ContactError, ContactStatus, check_point, check_scalar, check_vector, finite_result,
    non_negative, positive,
};
use crate::contact::SurfacePoint;

/// Settings of the augmented Lagrangian contact of one ply–tool pair
/// (doc Sec. "Implicit kernel").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AugmentedLagrangian {
    normal_penalty: f64,
    tangential_penalty: f64,
    friction: f64,
    offset: f64,
    smoothing: Smoothing,
}

/// The widths over which the kernel rounds its two kinks (doc Sec.
/// "Smoothed kinks"): the normal law's open/closed switch and the friction
/// law's stick/slip switch, each replaced by a parabola that joins the two
/// straight branches with a continuous slope. Zero widths give the
/// non-smooth law exactly.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize)]
pub struct Smoothing {
    /// Gap width `δ_g` \[mm\] `≥ 0`: the normal force `t_N = s(λ_N − ε_N g)`
    /// with `s` the Macaulay bracket rounded over `|x| < ε_N δ_g` (Eq. S1):
    /// a node closer than `λ_N/ε_N + δ_g` to the surface carries a small
    /// force, and the converged gap of a lightly pressed node lies in
    /// `[0, δ_g]`.
    pub gap_width: f64,
    /// Relative width `δ_r ∈ [0, 1)` of the friction law's rounding: the
    /// friction force `μ t_N f(|t*|/(μ t_N))` with `f` the minimum
    /// `min(r, 1)` rounded over `|r − 1| < δ_r` (Eq. S2).
    pub friction_width: f64,
}

/// The Macaulay bracket `⟨x⟩` rounded over `|x| < w` (Eq. S1) and its
/// slope: `0` below `−w`, `(x + w)²/(4w)` inside, `x` above; `w = 0` is
/// the bracket itself (slope 1 at `x = 0`, the closed side).
#[inline]
fn rounded_bracket(x: f64, w: f64) -> (f64, f64) {
    if x >= w {
        (x, 1.0)
    } else if x <= -w {
        (0.0, 0.0)
    } else {
        let a = x + w;
        (a * a / (4.0 * w), a / (2.0 * w))
    }
}

/// The integral of [`rounded_bracket`] from `−∞` (Eq. S3): `0` below
/// `−w`, `(x + w)³/(12w)` inside, `x²/2 + w²/6` above: the normal law's
/// potential is this over `ε_N`.
#[inline]
fn rounded_bracket_integral(x: f64, w: f64) -> f64 {
    if x >= w {
        0.5 * x * x + w * w / 6.0
    } else if x <= -w {
        0.0
    } else {
        let a = x + w;
        a * a * a / (12.0 * w)
    }
}

impl AugmentedLagrangian {
    /// Settings with normal penalty `ε_N` [N/mm] `> 0`, tangential penalty
    /// `ε_T` [N/mm] `> 0`, Coulomb coefficient `μ ≥ 0` (`0`: frictionless)
    /// and the mid-surface offset \[mm\] `≥ 0` (half the ply thickness).
    ///
    /// # Errors
    /// A setting that is not finite or out of its range.
    pub fn new(
        normal_penalty: f64,
        tangential_penalty: f64,
        friction: f64,
        offset: f64,
    ) -> Result<Self, ContactError> {
        Ok(Self {
            normal_penalty: positive("normal_penalty", normal_penalty)?,
            tangential_penalty: positive("tangential_penalty", tangential_penalty)?,
            friction: non_negative("friction", friction)?,
            offset: non_negative("offset", offset)?,
            smoothing: Smoothing::default(),
        })
    }

    /// The same settings with the kinks rounded over `smoothing` (doc Sec.
    /// "Smoothed kinks"; zero widths: the non-smooth law).
    ///
    /// # Errors
    /// A gap width that is negative or not finite, a friction width outside
    /// `[0, 1)`.
    pub fn with_smoothing(mut self, smoothing: Smoothing) -> Result<Self, ContactError> {
        non_negative("gap width", smoothing.gap_width)?;
        let w = smoothing.friction_width;
        if !(0.0..1.0).contains(&w) {
            return Err(ContactError::InvalidSetting {
                name: "friction width",
                value: w,
                expected: "0 ≤ δ_r < 1",
            });
        }
        self.smoothing = smoothing;
        Ok(self)
    }

    /// The rounding of the kinks.
    pub fn smoothing(&self) -> Smoothing {
        self.smoothing
    }

    /// Changes the mid-surface offset \[mm\] (half the ply thickness).
    ///
    /// # Errors
    /// An offset that is negative or not finite.
    pub fn set_offset(&mut self, offset: f64) -> Result<(), ContactError> {
        self.offset = non_negative("offset", offset)?;
        Ok(())
    }

    /// `ε_N` [N/mm].
    pub fn normal_penalty(&self) -> f64 {
        self.normal_penalty
    }

    /// `ε_T` [N/mm].
    pub fn tangential_penalty(&self) -> f64 {
        self.tangential_penalty
    }

    /// `μ`.
    pub fn friction(&self) -> f64 {
        self.friction
    }

    /// The mid-surface offset \[mm\].
    pub fn offset(&self) -> f64 {
        self.offset
    }

    /// Residual `r_y`, consistent tangent `K = ∂r_y/∂y` and outputs of the
    /// pair at the relative position `y` \[mm\] (Eq. I1–I7 of the module
    /// doc). `point` is the surface's answer at `y`; `None` (the node
    /// farther than the surface's cull distance) gives an open contact
    /// with `gap = ∞`.
    ///
    /// Degenerate cases (doc Sec. "Degenerate cases"): the contact is active
    /// when `λ_N − ε_N g ≥ 0` (closed side of the kink, `t_N = 0` there);
    /// `t* = 0` is stick; `μ = 0` is frictionless (status `Slip`, no
    /// tangential terms, symmetric `K`).
    ///
    /// # Errors
    /// A non-finite `y`, surface answer or state, a negative `λ_N`, a
    /// non-unit normal, or a response that overflows.
    pub fn evaluate(
        &self,
        state: &ImplicitContactState,
        y: &Vector3<f64>,
        point: Option<&SurfacePoint>,
    ) -> Result<ImplicitResponse, ContactError> {
        check_vector("relative position", y)?;
        state.check()?;
        let Some(point) = point else {
            return Ok(ImplicitResponse::open(f64::INFINITY, Vector3::zeros()));
        };
        check_point(point)?;
        let n = point.normal;
        let hessian = &point.hessian;
        let gap = point.distance - self.offset;
        let trial_normal = state.normal_multiplier - self.normal_penalty * gap;
        // Eq. I1 with the bracket rounded over ε_N δ_g (Eq. S1); open below
        // −ε_N δ_g, and without rounding on the open side only (x = 0 is
        // closed, as in "Degenerate cases").
        let normal_width = self.normal_penalty * self.smoothing.gap_width;
        if trial_normal < 0.0 && trial_normal <= -normal_width {
            return Ok(ImplicitResponse::open(gap, n));
        }
        let (normal_force, normal_slope) = rounded_bracket(trial_normal, normal_width);
        let normal_potential =
            rounded_bracket_integral(trial_normal, normal_width) / self.normal_penalty;
        // ∂t_N/∂y = −ε_N s′ n.
        let normal_stiffness = self.normal_penalty * normal_slope;
        let nn = n * n.transpose();
        let projector = Matrix3::identity() - nn;
        let relative = y - state.slip_reference;
        let slip_increment = projector * relative;
        // Eq. I5: normal part.
        let mut tangent = normal_stiffness * nn - normal_force * hessian;
        let (status, tangential_force) = if self.friction == 0.0 {
            (ContactStatus::Slip, Vector3::zeros())
        } else {
            // Eq. I2: t* = P w, w = λ_T + ε_T v; A = ∂t*/∂y (Eq. I6).
            let w = state.tangential_multiplier + self.tangential_penalty * relative;
            let w_normal = n.dot(&w);
            let trial = w - w_normal * n;
            let trial_tangent = self.tangential_penalty * projector
                - w_normal * hessian
                - n * (hessian * w).transpose();
            let limit = self.friction * normal_force;
            let trial_norm = trial.norm();
            let band = self.smoothing.friction_width;
            if trial_norm <= (1.0 - band) * limit {
                tangent += trial_tangent;
                (ContactStatus::Stick, trial)
            } else if trial_norm >= (1.0 + band) * limit {
                // trial_norm > limit ≥ 0: the division is safe.
                let direction = trial / trial_norm;
                let ratio = limit / trial_norm;
                let spread = Matrix3::identity() - direction * direction.transpose();
                tangent += -(self.friction * normal_stiffness) * direction * n.transpose()
                    + ratio * spread * trial_tangent;
                (ContactStatus::Slip, limit * direction)
            } else {
                // Eq. S2, inside the band (so band > 0, limit > 0 and
                // trial_norm > 0): t_T = L f(r) t̂ with r = |t*|/L and
                // f(r) = r − (r − 1 + δ_r)²/(4δ_r);
                // ∂t_T/∂y = (f − r f′) t̂ ⊗ ∂L/∂y + f′ t̂ ⊗ t̂ A
                //           + (L f/|t*|)(I − t̂⊗t̂) A,  ∂L/∂y = −μ ε_N s′ n.
                let direction = trial / trial_norm;
                let r = trial_norm / limit;
                let a = r - 1.0 + band;
                let f = r - a * a / (4.0 * band);
                let slope = 1.0 - a / (2.0 * band);
                let spread = Matrix3::identity() - direction * direction.transpose();
                let along = direction * direction.transpose();
                tangent += -((f - r * slope) * self.friction * normal_stiffness)
                    * direction
                    * n.transpose()
                    + slope * along * trial_tangent
                    + (limit * f / trial_norm) * spread * trial_tangent;
                let status = if r <= 1.0 {
                    ContactStatus::Stick
                } else {
                    ContactStatus::Slip
                };
                (status, (limit * f) * direction)
            }
        };
        let residual = tangential_force - normal_force * n;
        finite_result("residual", residual.iter())?;
        finite_result("tangent", tangent.iter())?;
        finite_result("slip increment", slip_increment.iter())?;
        Ok(ImplicitResponse {
            status,
            gap,
            normal_force,
            normal_potential,
            tangential_force,
            slip_increment,
            normal: n,
            residual,
            tangent,
        })
    }
}

/// The state of one node–tool pair between calls (doc Sec. "Uzawa update,
/// commit and restore").
///
/// `normal_multiplier`, `tangential_multiplier` are the working multipliers
/// the next [`AugmentedLagrangian::evaluate`] uses; a copy of both as they
/// were at the last [`commit`](Self::commit) is kept for
/// [`restore`](Self::restore). The slip reference changes only at commit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitContactState {
    /// `λ_N ≥ 0` \[N\].
    pub normal_multiplier: f64,
    /// `λ_T` \[N\] (world frame; re-projected on the current tangent plane
    /// when used).
    pub tangential_multiplier: Vector3<f64>,
    /// `y_ref` \[mm\]: the relative position at the last converged step.
    pub slip_reference: Vector3<f64>,
    committed_normal: f64,
    committed_tangential: Vector3<f64>,
}

impl ImplicitContactState {
    /// A fresh pair at the relative position `y` \[mm\]: zero multipliers,
    /// `y_ref = y`.
    pub fn new(y: &Vector3<f64>) -> Self {
        Self::with_multipliers(y, 0.0, &Vector3::zeros())
    }

    /// A pair with given multipliers (a restart, say); they are also the
    /// committed values.
    pub fn with_multipliers(
        slip_reference: &Vector3<f64>,
        normal_multiplier: f64,
        tangential_multiplier: &Vector3<f64>,
    ) -> Self {
        Self {
            normal_multiplier,
            tangential_multiplier: *tangential_multiplier,
            slip_reference: *slip_reference,
            committed_normal: normal_multiplier,
            committed_tangential: *tangential_multiplier,
        }
    }

    fn check(&self) -> Result<(), ContactError> {
        check_scalar("normal multiplier", self.normal_multiplier)?;
        if self.normal_multiplier < 0.0 {
            return Err(ContactError::InvalidInput {
                name: "normal multiplier",
                value: self.normal_multiplier,
                expected: "λ_N ≥ 0",
            });
        }
        check_vector("tangential multiplier", &self.tangential_multiplier)?;
        check_vector("slip reference", &self.slip_reference)
    }

    /// The Uzawa update between Newton solves (Eq. U1):
    /// `λ_N ← t_N`, `λ_T ← t_T` (tangent to the current plane) from the
    /// `response` of [`AugmentedLagrangian::evaluate`] at the converged
    /// Newton state of this pair. An open response sets both to zero.
    /// Returns what a convergence test needs.
    pub fn augment(&mut self, response: &ImplicitResponse) -> AugmentationReport {
        let normal_change = (response.normal_force - self.normal_multiplier).abs();
        let tangential_change = (response.tangential_force - self.tangential_multiplier).norm();
        self.normal_multiplier = response.normal_force;
        self.tangential_multiplier = response.tangential_force;
        AugmentationReport {
            penetration: (-response.gap).max(0.0),
            normal_change,
            tangential_change,
            normal_multiplier: self.normal_multiplier,
            tangential_multiplier: self.tangential_multiplier.norm(),
        }
    }

    /// Accepts a converged load step at the relative position `y` \[mm\]:
    /// `y_ref ← y` (the slip of the next step counts from here) and the
    /// working multipliers become the committed ones (kept as the next
    /// step's start). Call it after the last [`augment`](Self::augment), so
    /// that the multipliers are the converged forces.
    pub fn commit(&mut self, y: &Vector3<f64>) {
        self.slip_reference = *y;
        self.committed_normal = self.normal_multiplier;
        self.committed_tangential = self.tangential_multiplier;
    }

    /// Undoes a failed load step: the multipliers go back to their values
    /// at the last commit (`y_ref` never changed during the step).
    pub fn restore(&mut self) {
        self.normal_multiplier = self.committed_normal;
        self.tangential_multiplier = self.committed_tangential;
    }

    /// The multipliers `(λ_N, λ_T)` at the last commit.
    pub fn committed_multipliers(&self) -> (f64, Vector3<f64>) {
        (self.committed_normal, self.committed_tangential)
    }
}

/// What one [`AugmentedLagrangian::evaluate`] gives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImplicitResponse {
    /// Open, stick or slip.
    pub status: ContactStatus,
    /// `g = d − offset` \[mm\] (`∞` when the surface culled the node).
    pub gap: f64,
    /// `t_N ≥ 0` \[N\] (Eq. I1).
    pub normal_force: f64,
    /// The normal law's potential \[N·mm\], whose derivative in `y` is the
    /// normal part of `r_y`: `t_N²/(2ε_N)` without rounding, Eq. S3 with.
    pub normal_potential: f64,
    /// `t_T` \[N\], tangent to the current plane, along the slip: the force
    /// on the node is `−t_T` (Eq. I3).
    pub tangential_force: Vector3<f64>,
    /// `Δs = P (y − y_ref)` \[mm\] (zero when open).
    pub slip_increment: Vector3<f64>,
    /// The surface normal `n` at `y` (zero when culled).
    pub normal: Vector3<f64>,
    /// `r_y = −f_c = −t_N n + t_T` \[N\] (Eq. I4).
    pub residual: Vector3<f64>,
    /// The consistent tangent `K = ∂r_y/∂y` [N/mm] (Eq. I5–I7),
    /// unsymmetric with friction.
    pub tangent: Matrix3<f64>,
}

impl ImplicitResponse {
    fn open(gap: f64, normal: Vector3<f64>) -> Self {
        Self {
            status: ContactStatus::Open,
            gap,
            normal_force: 0.0,
            normal_potential: 0.0,
            tangential_force: Vector3::zeros(),
            slip_increment: Vector3::zeros(),
            normal,
            residual: Vector3::zeros(),
            tangent: Matrix3::zeros(),
        }
    }

    /// The contact force on the node `f_c = t_N n − t_T = −r_y` \[N\].
    pub fn force(&self) -> Vector3<f64> {
        -self.residual
    }

    /// `½ (K + Kᵀ)`: the tangent with its skew-symmetric part dropped, for
    /// a solver that needs a symmetric matrix (doc Sec. "Symmetric
    /// variant"). NOT the consistent tangent: with friction it costs the
    /// quadratic convergence of Newton's method. Equal to `K` when
    /// frictionless or open.
    pub fn symmetric_tangent(&self) -> Matrix3<f64> {
        0.5 * (self.tangent + self.tangent.transpose())
    }
}

/// What one [`ImplicitContactState::augment`] reports for a convergence
/// test (doc Sec. "Uzawa update, commit and restore").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AugmentationReport {
    /// `⟨−g⟩` \[mm\]: the penetration at the evaluated state (0 if open).
    pub penetration: f64,
    /// `|λ_N,new − λ_N,old|` \[N\].
    pub normal_change: f64,
    /// `|λ_T,new − λ_T,old|` \[N\].
    pub tangential_change: f64,
    /// `λ_N,new` \[N\].
    pub normal_multiplier: f64,
    /// `|λ_T,new|` \[N\].
    pub tangential_multiplier: f64,
}

/// Accumulates [`AugmentationReport`]s over all pairs: the largest
/// penetration and the norms of the multiplier change and of the new
/// multipliers (normal and tangential together, both in N).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct AugmentationNorms {
    /// `max ⟨−g⟩` \[mm\].
    pub max_penetration: f64,
    /// `Σ (Δλ_N² + |Δλ_T|²)` \[N²\].
    pub change_squared: f64,
    /// `Σ (λ_N² + |λ_T|²)` \[N²\] of the new multipliers.
    pub multiplier_squared: f64,
}

impl AugmentationNorms {
    /// Adds one pair's report.
    pub fn add(&mut self, report: &AugmentationReport) {
        self.max_penetration = self.max_penetration.max(report.penetration);
        self.change_squared += report.normal_change * report.normal_change
            + report.tangential_change * report.tangential_change;
        self.multiplier_squared += report.normal_multiplier * report.normal_multiplier
            + report.tangential_multiplier * report.tangential_multiplier;
    }

    /// `‖Δλ‖ / ‖λ‖` (0 when both are zero, `∞` when only `‖λ‖` is): the
    /// usual augmentation test compares it with a tolerance, together with
    /// [`max_penetration`](Self::max_penetration) against a gap tolerance.
    pub fn relative_change(&self) -> f64 {
        if self.change_squared == 0.0 {
            0.0
        } else if self.multiplier_squared == 0.0 {
            f64::INFINITY
        } else {
            (self.change_squared / self.multiplier_squared).sqrt()
        }
    }
}
