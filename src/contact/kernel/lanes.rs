//! The explicit penalty law ([`PenaltyContact::update_trusted`] followed by
//! [`normal_dashpot`], Eq. E1–E7 of `docs/contact-kernels.md`) on `W`
//! node–tool pairs side by side, one per lane of a [`Real`]: four pairs in
//! one AVX2 register, or one pair in an `f64`. The branches (open, stick,
//! slip) become lane selects; each lane repeats the one-pair arithmetic
//! operation for operation (the same sums in the same order, no fused
//! multiply-add), so every pair gets the same bits as from the one-pair
//! kernel.
//!
//! The pairs' state lives in [`PenaltyBatch`]es, field by field with one
//! lane per pair, the layout the kernel loads and stores without a
//! transpose (`docs/contact.md`, "Explicit path: the pairs in lanes").
//!
//! [`PenaltyContact::update_trusted`]: super::PenaltyContact::update_trusted
//! [`normal_dashpot`]: super::normal_dashpot

use nalgebra::Vector3;

use super::{NodalCompaction, PenaltyContact, PenaltyState};
use crate::material::lanes::Real;

/// The settings and the state of `W` node–tool pairs of the explicit
/// penalty law, field by field (`spring[c][w]`: component `c` of pair
/// `w`'s spring). [`penalty_lanes`] updates the state in place.
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(32))]
pub struct PenaltyBatch<const W: usize> {
    /// `k_N` [N/mm].
    pub normal_stiffness: [f64; W],
    /// `k_T` [N/mm].
    pub tangential_stiffness: [f64; W],
    /// `μ`.
    pub friction: [f64; W],
    /// The mid-surface offset \[mm\].
    pub offset: [f64; W],
    /// The normal dashpot `c` [N·s/mm].
    pub dashpot: [f64; W],
    /// The elastic tangential spring `s_e` \[mm\].
    pub spring: [[f64; W]; 3],
    /// The relative position at the last increment \[mm\].
    pub previous_position: [[f64; W]; 3],
    /// The status code (0 open, 1 stick, 2 slip).
    pub status: [f64; W],
    /// Stored normal energy [N·mm].
    pub normal_energy: [f64; W],
    /// Stored tangential energy [N·mm].
    pub tangential_energy: [f64; W],
    /// Work dissipated by friction and re-projection [N·mm].
    pub dissipated: [f64; W],
    /// Accumulated plastic slip \[mm\].
    pub slip_length: [f64; W],
    /// Work dissipated by the normal dashpot [N·mm].
    pub damped_energy: [f64; W],
    /// The dashpot's force on the node at the last increment \[N\].
    pub damped_force: [[f64; W]; 3],
}

/// What [`penalty_lanes`] needs of `W` pairs besides their state: the
/// relative positions and the tool's answers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyInput<const W: usize> {
    /// The relative position `y` \[mm\].
    pub position: [[f64; W]; 3],
    /// The tool's signed distance \[mm\]; `+∞` where the query culled the
    /// pair (the one-pair kernel's `None`).
    pub distance: [f64; W],
    /// The tool's unit normal; zero where culled.
    pub normal: [[f64; W]; 3],
}

/// What [`penalty_lanes`] gives of `W` pairs besides their new state.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyOutput<const W: usize> {
    /// The residual `r_y` with the dashpot \[N\].
    pub residual: [[f64; W]; 3],
    /// The normal force \[N\].
    pub normal_force: [f64; W],
    /// The magnitude of the friction force \[N\].
    pub friction_force: [f64; W],
    /// The gap \[mm\] (`+∞` where culled).
    pub gap: [f64; W],
}

impl<const W: usize> Default for PenaltyInput<W> {
    fn default() -> Self {
        Self {
            position: [[0.0; W]; 3],
            distance: [f64::INFINITY; W],
            normal: [[0.0; W]; 3],
        }
    }
}

impl<const W: usize> Default for PenaltyOutput<W> {
    fn default() -> Self {
        Self {
            residual: [[0.0; W]; 3],
            normal_force: [0.0; W],
            friction_force: [0.0; W],
            gap: [0.0; W],
        }
    }
}

impl<const W: usize> PenaltyBatch<W> {
    /// `W` pairs, lane `w` with the settings `laws[w]` and `dashpots[w]`
    /// and the state `states[w]` (dashpot at rest).
    pub fn new(
        laws: &[PenaltyContact; W],
        dashpots: &[f64; W],
        states: &[PenaltyState; W],
    ) -> Self {
        let component = |f: &dyn Fn(&PenaltyState) -> Vector3<f64>, c: usize| {
            std::array::from_fn(|w| f(&states[w])[c])
        };
        Self {
            normal_stiffness: laws.map(|l| l.normal_stiffness()),
            tangential_stiffness: laws.map(|l| l.tangential_stiffness()),
            friction: laws.map(|l| l.friction()),
            offset: laws.map(|l| l.offset()),
            dashpot: *dashpots,
            spring: std::array::from_fn(|c| component(&|s| s.spring, c)),
            previous_position: std::array::from_fn(|c| component(&|s| s.previous_position, c)),
            status: states.map(|s| f64::from(s.status.code())),
            normal_energy: states.map(|s| s.normal_energy),
            tangential_energy: states.map(|s| s.tangential_energy),
            dissipated: states.map(|s| s.dissipated),
            slip_length: states.map(|s| s.slip_length),
            damped_energy: [0.0; W],
            damped_force: [[0.0; W]; 3],
        }
    }

    /// Lane `w` as a one-lane batch.
    #[inline(always)]
    pub fn lane(&self, w: usize) -> PenaltyBatch<1> {
        let one = |a: &[f64; W]| [a[w]];
        let three = |a: &[[f64; W]; 3]| [[a[0][w]], [a[1][w]], [a[2][w]]];
        PenaltyBatch {
            normal_stiffness: one(&self.normal_stiffness),
            tangential_stiffness: one(&self.tangential_stiffness),
            friction: one(&self.friction),
            offset: one(&self.offset),
            dashpot: one(&self.dashpot),
            spring: three(&self.spring),
            previous_position: three(&self.previous_position),
            status: one(&self.status),
            normal_energy: one(&self.normal_energy),
            tangential_energy: one(&self.tangential_energy),
            dissipated: one(&self.dissipated),
            slip_length: one(&self.slip_length),
            damped_energy: one(&self.damped_energy),
            damped_force: three(&self.damped_force),
        }
    }

    /// Lane `w`'s state from the one-lane batch `one` (the settings are
    /// kept).
    #[inline(always)]
    pub fn set_lane(&mut self, w: usize, one: &PenaltyBatch<1>) {
        for c in 0..3 {
            self.spring[c][w] = one.spring[c][0];
            self.previous_position[c][w] = one.previous_position[c][0];
            self.damped_force[c][w] = one.damped_force[c][0];
        }
        self.status[w] = one.status[0];
        self.normal_energy[w] = one.normal_energy[0];
        self.tangential_energy[w] = one.tangential_energy[0];
        self.dissipated[w] = one.dissipated[0];
        self.slip_length[w] = one.slip_length[0];
        self.damped_energy[w] = one.damped_energy[0];
    }

    /// `true` when lane `w` is open with its spring released: the pair
    /// the contact loops settle without the kernel while the tool culls it.
    #[inline(always)]
    pub fn released(&self, w: usize) -> bool {
        self.status[w] == 0.0
            && self.spring[0][w] == 0.0
            && self.spring[1][w] == 0.0
            && self.spring[2][w] == 0.0
    }
}

impl<const W: usize> PenaltyInput<W> {
    /// Lane `w` as a one-lane input.
    #[inline(always)]
    pub fn lane(&self, w: usize) -> PenaltyInput<1> {
        PenaltyInput {
            position: [0, 1, 2].map(|c| [self.position[c][w]]),
            distance: [self.distance[w]],
            normal: [0, 1, 2].map(|c| [self.normal[c][w]]),
        }
    }
}

impl<const W: usize> PenaltyOutput<W> {
    /// Lane `w` from the one-lane output `one`.
    #[inline(always)]
    pub fn set_lane(&mut self, w: usize, one: &PenaltyOutput<1>) {
        for c in 0..3 {
            self.residual[c][w] = one.residual[c][0];
        }
        self.normal_force[w] = one.normal_force[0];
        self.friction_force[w] = one.friction_force[0];
        self.gap[w] = one.gap[0];
    }
}

/// `a · b` as nalgebra forms it for 3-vectors: `(a₀b₀ + a₁b₁) + a₂b₂`.
#[inline(always)]
fn dot<V: Real>(a: &[V; 3], b: &[V; 3]) -> V {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `|a|²` as nalgebra forms it: `0 + ((a₀² + a₁²) + a₂²)`.
#[inline(always)]
fn norm_squared<V: Real>(zero: V, a: &[V; 3]) -> V {
    zero + dot(a, a)
}

/// `Σ aᵢ` as nalgebra forms it: `((0 + a₀) + a₁) + a₂`.
#[inline(always)]
fn sum<V: Real>(zero: V, a: &[V; 3]) -> V {
    zero + a[0] + a[1] + a[2]
}

/// One increment of the explicit penalty law with the normal dashpot on
/// the `W` pairs of `batch`, at their relative positions and the tool's
/// answers `input`, for the time step `time_step` \[s\]: Eq. E1–E7
/// (`docs/contact-kernels.md`) as [`PenaltyContact::update_trusted`]
/// followed by [`normal_dashpot`] compute them, lane by lane with the same
/// bits. With `laws`, lane `w`'s normal force and energy are those of the
/// compliant layer `laws[w]` (Eq. C1–C4 of [`super::compaction`], one lane
/// at a time), as a [`PenaltyContact`] with that law computes them. Every lane's state is updated in `batch` and its force and
/// figures written to `output`; the returned bits mark the lanes whose
/// response is not finite (the one-pair kernel rejects those).
///
/// [`PenaltyContact::update_trusted`]: super::PenaltyContact::update_trusted
/// [`normal_dashpot`]: super::normal_dashpot
#[inline(always)]
pub fn penalty_lanes<V: Real<Array = [f64; W]>, const W: usize>(
    ctx: V,
    batch: &mut PenaltyBatch<W>,
    input: &PenaltyInput<W>,
    output: &mut PenaltyOutput<W>,
    time_step: f64,
    laws: Option<&[NodalCompaction; W]>,
) -> u32 {
    let zero = ctx.splat(0.0);
    let vector = |a: &[[f64; W]; 3]| [ctx.load(a[0]), ctx.load(a[1]), ctx.load(a[2])];
    let k_n = ctx.load(batch.normal_stiffness);
    let k_t = ctx.load(batch.tangential_stiffness);
    let friction = ctx.load(batch.friction);
    let y = vector(&input.position);
    let previous = vector(&batch.previous_position);
    let spring = vector(&batch.spring);
    let normal = vector(&input.normal);
    let motion = [y[0] - previous[0], y[1] - previous[1], y[2] - previous[2]];
    let gap = ctx.load(input.distance) - ctx.load(batch.offset);

    // Eq. E2 (with n = 0, i.e. P = I, when culled).
    let spring_normal = dot(&normal, &spring);
    let spring_projected = [
        spring[0] - spring_normal * normal[0],
        spring[1] - spring_normal * normal[1],
        spring[2] - spring_normal * normal[2],
    ];
    let projection_loss = k_t * 0.5 * spring_normal * spring_normal;
    let normal_motion = dot(&normal, &motion);
    let slip_increment = [
        motion[0] - normal_motion * normal[0],
        motion[1] - normal_motion * normal[1],
        motion[2] - normal_motion * normal[2],
    ];
    let trial = [
        k_t * (spring_projected[0] + slip_increment[0]),
        k_t * (spring_projected[1] + slip_increment[1]),
        k_t * (spring_projected[2] + slip_increment[2]),
    ];
    let old_force = [
        k_t * spring_projected[0],
        k_t * spring_projected[1],
        k_t * spring_projected[2],
    ];

    // Closed (Eq. E1, E3): stick or slip.
    let closed = gap.lt(zero);
    let penetration = -gap;
    let (normal_force, law_energy) = match laws {
        None => (k_n * penetration, None),
        Some(laws) => {
            let compression = penetration.store();
            let responses: [(f64, f64); W] =
                std::array::from_fn(|w| laws[w].force_and_energy(compression[w]));
            (
                ctx.load(responses.map(|r| r.0)),
                Some(ctx.load(responses.map(|r| r.1))),
            )
        }
    };
    let limit = friction * normal_force;
    let trial_norm = norm_squared(zero, &trial).sqrt();
    let stick = closed & friction.gt(zero) & trial_norm.le(limit);
    let moving = trial_norm.gt(zero);
    let mut force = [zero; 3];
    let mut next_spring = [zero; 3];
    let mut plastic = [zero; 3];
    for c in 0..3 {
        let direction = V::select(moving, trial[c] / trial_norm, zero);
        let slip_force = limit * direction;
        force[c] = V::select(stick, trial[c], slip_force);
        next_spring[c] = V::select(
            stick,
            spring_projected[c] + slip_increment[c],
            slip_force / k_t,
        );
        plastic[c] = V::select(stick, zero, (trial[c] - slip_force) / k_t);
    }
    let mean_force = [
        old_force[0] + force[0],
        old_force[1] + force[1],
        old_force[2] + force[2],
    ];
    let closed_dissipated = projection_loss + dot(&mean_force, &plastic) * 0.5;
    // Open (Eq. E7): the spring released as a slip with f_N = 0.
    let released = [trial[0] / k_t, trial[1] / k_t, trial[2] / k_t];
    let open_dissipated = projection_loss + dot(&old_force, &released) * 0.5;

    // The response: zero where open.
    let normal_force = V::select(closed, normal_force, zero);
    let mut residual = [zero; 3];
    for c in 0..3 {
        force[c] = V::select(closed, force[c], zero);
        next_spring[c] = V::select(closed, next_spring[c], zero);
        plastic[c] = V::select(closed, plastic[c], zero);
        residual[c] = force[c] - normal_force * normal[c];
    }
    let dissipated = V::select(closed, closed_dissipated, open_dissipated);
    let normal_energy = V::select(
        closed,
        law_energy.unwrap_or_else(|| normal_force * 0.5 * penetration),
        zero,
    );
    let tangential_energy = V::select(closed, k_t * 0.5 * norm_squared(zero, &next_spring), zero);
    let slip_length = ctx.load(batch.slip_length) + norm_squared(zero, &plastic).sqrt();
    let total_dissipated = ctx.load(batch.dissipated) + dissipated;
    let friction_force = V::select(stick, trial_norm, norm_squared(zero, &force).sqrt());
    let status = V::select(
        closed,
        V::select(stick, ctx.splat(1.0), ctx.splat(2.0)),
        zero,
    );

    // The finiteness probe of `update_trusted`, term by term.
    let finite_gap = V::select(gap.abs().ge(ctx.splat(f64::INFINITY)), zero, gap);
    let probe = sum(zero, &residual)
        + sum(zero, &next_spring)
        + sum(zero, &normal)
        + sum(zero, &y)
        + dissipated
        + normal_energy
        + tangential_energy
        + slip_length
        + total_dissipated
        + finite_gap;
    let failed = V::bits(!probe.is_finite());

    // The normal dashpot on the approach velocity while in contact, never
    // pulling the node onto the tool.
    let dashpot = ctx.load(batch.dashpot);
    let damping = closed & ctx.splat(time_step).gt(zero) & dashpot.gt(zero);
    let approach = -normal_motion;
    let damping_force = (dashpot * approach / time_step).max(-normal_force);
    let mut damped_force = [zero; 3];
    for c in 0..3 {
        damped_force[c] = V::select(damping, damping_force * normal[c], zero);
    }
    let previous_damped = vector(&batch.damped_force);
    let mean_damped = [
        previous_damped[0] + damped_force[0],
        previous_damped[1] + damped_force[1],
        previous_damped[2] + damped_force[2],
    ];
    let damped_energy = ctx.load(batch.damped_energy) - dot(&mean_damped, &motion) * 0.5;

    for c in 0..3 {
        batch.spring[c] = next_spring[c].store();
        batch.previous_position[c] = y[c].store();
        batch.damped_force[c] = damped_force[c].store();
        output.residual[c] = (residual[c] - damped_force[c]).store();
    }
    batch.status = status.store();
    batch.normal_energy = normal_energy.store();
    batch.tangential_energy = tangential_energy.store();
    batch.dissipated = total_dissipated.store();
    batch.slip_length = slip_length.store();
    batch.damped_energy = damped_energy.store();
    output.normal_force = normal_force.store();
    output.friction_force = friction_force.store();
    output.gap = gap.store();
    failed
}

/// [`penalty_lanes`] on each lane of `batch` by itself, as `f64` (any
/// CPU): the same bits as the four-lane call.
pub fn penalty_lanes_one_by_one<const W: usize>(
    batch: &mut PenaltyBatch<W>,
    input: &PenaltyInput<W>,
    output: &mut PenaltyOutput<W>,
    time_step: f64,
    laws: Option<&[NodalCompaction; W]>,
) -> u32 {
    let mut failed = 0;
    for w in 0..W {
        let mut one = batch.lane(w);
        let mut out = PenaltyOutput::<1>::default();
        let law = laws.map(|l| [l[w]]);
        failed |= penalty_lanes(
            0.0_f64,
            &mut one,
            &input.lane(w),
            &mut out,
            time_step,
            law.as_ref(),
        ) << w;
        batch.set_lane(w, &one);
        output.set_lane(w, &out);
    }
    failed
}

#[cfg(test)]
mod tests {
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    use super::*;
    use crate::contact::SurfaceNormal;
    use crate::contact::kernel::{ContactStatus, normal_dashpot};

    /// A random pair: a state that has stuck, slipped or opened, a tool
    /// answer that is closed, open or culled, and a dashpot that is on or
    /// off; `(law, dashpot, state, damped, y, point)`.
    #[allow(clippy::type_complexity)]
    fn random_pair(
        rng: &mut StdRng,
        compaction: bool,
    ) -> (
        PenaltyContact,
        f64,
        PenaltyState,
        (f64, Vector3<f64>),
        Vector3<f64>,
        Option<SurfaceNormal>,
    ) {
        let v = |rng: &mut StdRng, scale: f64| {
            Vector3::new(
                scale * rng.random_range(-1.0..1.0),
                scale * rng.random_range(-1.0..1.0),
                scale * rng.random_range(-1.0..1.0),
            )
        };
        let y = v(rng, 10.0);
        // Springs and steps from 0.1 nm to 1 µm: both closed laws occur.
        let spring_scale = 10.0_f64.powf(rng.random_range(-7.0..-3.0));
        let spring = v(rng, spring_scale);
        let step_scale = 10.0_f64.powf(rng.random_range(-7.0..-3.0));
        let step = v(rng, step_scale);
        let previous = y - step;
        let normal = v(rng, 1.0).normalize();
        let damped_force = v(rng, 0.1);
        let k = 10.0_f64.powf(rng.random_range(1.0..4.0));
        let friction = [0.0, 0.147, 0.336][rng.random_range(0..3)];
        let mut law =
            PenaltyContact::new(k, k * rng.random_range(0.5..1.5), friction, 0.15).unwrap();
        if compaction {
            // A soft layer whose knee lies within the sampled penetrations
            // (a few nm to 10 µm) or beyond them.
            let layer = crate::contact::kernel::CompactionLaw::new(
                10.0_f64.powf(rng.random_range(-4.0..-1.0)),
                rng.random_range(2.0..12.0),
            )
            .unwrap();
            let nodal = NodalCompaction::new(&layer, rng.random_range(1.0..20.0), 0.15, k).unwrap();
            law = law.with_compaction(nodal);
        }
        let dashpot = if rng.random_range(0.0..1.0) < 0.2 {
            0.0
        } else {
            rng.random_range(0.0..1e-3)
        };
        let status = [
            ContactStatus::Open,
            ContactStatus::Stick,
            ContactStatus::Slip,
        ][rng.random_range(0..3)];
        let state = PenaltyState {
            spring: if status == ContactStatus::Open && rng.random_range(0.0..1.0) < 0.5 {
                Vector3::zeros()
            } else {
                spring
            },
            previous_position: previous,
            status,
            normal_energy: rng.random_range(0.0..1e-3),
            tangential_energy: rng.random_range(0.0..1e-3),
            dissipated: rng.random_range(0.0..1.0),
            slip_length: rng.random_range(0.0..5.0),
        };
        let point = match rng.random_range(0..4) {
            0 => None,
            // Open but answered.
            1 => Some(SurfaceNormal {
                distance: 0.15 + rng.random_range(0.0..0.1),
                normal,
            }),
            // Closed, from a few nm to 10 µm deep.
            _ => Some(SurfaceNormal {
                distance: 0.15 - 10.0_f64.powf(rng.random_range(-6.0..-2.0)),
                normal,
            }),
        };
        let damped = (rng.random_range(0.0..1.0), damped_force);
        (law, dashpot, state, damped, y, point)
    }

    /// Requirement: the lanes give every pair the bits of the one-pair
    /// kernel and dashpot (state, residual, outputs, dashpot record), for
    /// every kind of pair mixed in one batch, on four AVX2 lanes where the
    /// CPU has them and one `f64` lane at a time.
    #[test]
    fn lanes_repeat_the_one_pair_kernel_bit_for_bit() {
        let mut rng = StdRng::seed_from_u64(4_096);
        let time_step = 1.2e-6;
        let mut stuck = 0;
        let mut slipped = 0;
        for round in 0..2_000 {
            let compaction = round % 2 == 1;
            let pairs: [_; 4] = std::array::from_fn(|_| random_pair(&mut rng, compaction));
            let laws = pairs.each_ref().map(|p| p.0);
            let layers = laws.map(|l| l.compaction().copied());
            let layers = compaction.then(|| layers.map(|l| l.unwrap()));
            let dashpots = pairs.each_ref().map(|p| p.1);
            let states = pairs.each_ref().map(|p| p.2);
            let mut batch = PenaltyBatch::new(&laws, &dashpots, &states);
            let mut input = PenaltyInput::<4>::default();
            for (w, p) in pairs.iter().enumerate() {
                batch.damped_energy[w] = p.3.0;
                for c in 0..3 {
                    batch.damped_force[c][w] = p.3.1[c];
                    input.position[c][w] = p.4[c];
                }
                if let Some(point) = &p.5 {
                    input.distance[w] = point.distance;
                    for c in 0..3 {
                        input.normal[c][w] = point.normal[c];
                    }
                }
            }
            let mut expected = batch;
            let mut expected_output = PenaltyOutput::<4>::default();
            for (w, (law, dashpot, state, damped, y, point)) in pairs.iter().enumerate() {
                let (mut state, mut damped) = (*state, *damped);
                let motion = y - state.previous_position;
                let r = law.update_trusted(&mut state, y, point.as_ref()).unwrap();
                let residual =
                    r.residual - normal_dashpot(*dashpot, &r, &motion, time_step, &mut damped);
                let mut one = PenaltyBatch::new(&[*law], &[*dashpot], &[state]);
                one.damped_energy = [damped.0];
                one.damped_force = [0, 1, 2].map(|c| [damped.1[c]]);
                expected.set_lane(w, &one);
                expected_output.set_lane(
                    w,
                    &PenaltyOutput {
                        residual: [0, 1, 2].map(|c| [residual[c]]),
                        normal_force: [r.normal_force],
                        friction_force: [r.tangential_force.norm()],
                        gap: [r.gap],
                    },
                );
                stuck += usize::from(r.status == ContactStatus::Stick);
                slipped += usize::from(r.status == ContactStatus::Slip);
            }
            let bits = |b: &PenaltyBatch<4>, o: &PenaltyOutput<4>| {
                let mut all = Vec::new();
                for a in [
                    b.status,
                    b.normal_energy,
                    b.tangential_energy,
                    b.dissipated,
                    b.slip_length,
                    b.damped_energy,
                    o.normal_force,
                    o.friction_force,
                    o.gap,
                ]
                .iter()
                .chain(b.spring.iter())
                .chain(b.previous_position.iter())
                .chain(b.damped_force.iter())
                .chain(o.residual.iter())
                {
                    all.extend(a.iter().map(|x| x.to_bits()));
                }
                all
            };
            let want = bits(&expected, &expected_output);

            let mut one_by_one = batch;
            let mut output = PenaltyOutput::<4>::default();
            let failed = penalty_lanes_one_by_one(
                &mut one_by_one,
                &input,
                &mut output,
                time_step,
                layers.as_ref(),
            );
            assert_eq!(failed, 0);
            assert_eq!(bits(&one_by_one, &output), want);

            #[cfg(target_arch = "x86_64")]
            if let Some(simd) = pulp::x86::V3::try_new() {
                struct Run<'a> {
                    simd: pulp::x86::V3,
                    batch: &'a mut PenaltyBatch<4>,
                    input: &'a PenaltyInput<4>,
                    output: &'a mut PenaltyOutput<4>,
                    time_step: f64,
                    layers: Option<&'a [NodalCompaction; 4]>,
                }
                impl pulp::WithSimd for Run<'_> {
                    type Output = u32;
                    #[inline(always)]
                    fn with_simd<S: pulp::Simd>(self, _: S) -> u32 {
                        let ctx = crate::material::lanes::x86::F64x4::new(self.simd, [0.0; 4]);
                        penalty_lanes(
                            ctx,
                            self.batch,
                            self.input,
                            self.output,
                            self.time_step,
                            self.layers,
                        )
                    }
                }
                let mut simd_batch = batch;
                let mut simd_output = PenaltyOutput::<4>::default();
                let failed = <pulp::x86::V3 as pulp::Simd>::vectorize(
                    simd,
                    Run {
                        simd,
                        batch: &mut simd_batch,
                        input: &input,
                        output: &mut simd_output,
                        time_step,
                        layers: layers.as_ref(),
                    },
                );
                assert_eq!(failed, 0);
                assert_eq!(bits(&simd_batch, &simd_output), want);
            }
        }
        // The mix covers both closed laws.
        assert!(
            stuck > 200 && slipped > 200,
            "{stuck} stuck, {slipped} slipped"
        );
    }

    /// Requirement: a lane whose response is not finite is flagged, as
    /// the one-pair kernel rejects it, and only that lane.
    #[test]
    fn a_non_finite_lane_is_flagged_alone() {
        let law = PenaltyContact::new(100.0, 100.0, 0.2, 0.15).unwrap();
        let state = PenaltyState::new(&Vector3::zeros());
        let mut batch = PenaltyBatch::new(&[law; 4], &[0.0; 4], &[state; 4]);
        let mut input = PenaltyInput::<4>::default();
        input.position[1][2] = f64::NAN;
        let mut output = PenaltyOutput::default();
        let failed = penalty_lanes_one_by_one(&mut batch, &input, &mut output, 1e-6, None);
        assert_eq!(failed, 0b100);
        let mut one = state;
        let mut y = Vector3::zeros();
        y[1] = f64::NAN;
        assert!(law.update_trusted(&mut one, &y, None).is_err());
    }
}
