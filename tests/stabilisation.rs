//! The viscous stabilisation of the quasi-static solver (`docs/solver.md`,
//! "Stabilisation") on a problem with a closed-form answer: one node on a
//! linear spring whose anchor moves with the load parameter, damped by
//! `(c/Δλ) m (u − u_n)`. Each step is then the backward-Euler update
//!
//!     k (u − λ e) + (c m/Δλ) (u − u_n) = 0
//!     u = (k λ e + (c m/Δλ) u_n) / (k + c m/Δλ)
//!
//! and dissipates `(c m/Δλ) |u − u_n|²`.

use ncform::model::{Masses, Model, State, Stencils, Term, TermEnergy, TermFailure};
use ncform::solver::{
    Amplitude, DofMap, NewtonParameters, QuasiStaticResult, RunStatus, Stabilisation, StepRecord,
    solve_quasi_static,
};

/// Node 0 tied by a spring `k` to the anchor `λ e` and by a spring `k0`
/// to the origin, with mass `m`.
struct Spring {
    k: f64,
    k0: f64,
    m: f64,
    e: [f64; 3],
}

impl Term for Spring {
    fn name(&self) -> &str {
        "spring"
    }
    fn stencils(&self) -> Stencils {
        Stencils {
            count: 1,
            nodes: 1,
            extras: 0,
        }
    }
    fn stencil(&self, _s: usize, nodes: &mut [usize], _extras: &mut [usize]) {
        nodes[0] = 0;
    }
    fn evaluate(
        &mut self,
        state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        let mut energy = 0.0;
        for (i, f) in force.iter_mut().enumerate().take(3) {
            let d = state.u[i] - state.load * self.e[i];
            *f = self.k * d + self.k0 * state.u[i];
            energy += 0.5 * self.k * d * d + 0.5 * self.k0 * state.u[i] * state.u[i];
        }
        if let Some(t) = tangent {
            t.fill(0.0);
            for i in 0..3 {
                t[4 * i] = self.k + self.k0;
            }
        }
        Ok(energy)
    }
    fn lumped_masses(&self, masses: &mut Masses) -> f64 {
        masses.node[0] += self.m;
        self.m
    }
    fn energy(&mut self, state: &State) -> Result<TermEnergy, TermFailure> {
        let mut f = [0.0; 3];
        let internal = self.evaluate(state, &mut f, None)?;
        Ok(TermEnergy {
            internal,
            ..Default::default()
        })
    }
}

/// `spring` solved over `λ ∈ [0, 1]` in ten steps of 0.1, without
/// extrapolation, to round-off, with the constant stabilisation and the
/// rest of `params`; the run must complete. Returns the result and each
/// step's record with its displacements.
fn ten_steps(
    spring: Spring,
    params: NewtonParameters,
) -> (QuasiStaticResult, Vec<(StepRecord, Vec<f64>)>) {
    let mut model = Model::new(1);
    model.add(spring);
    let params = NewtonParameters {
        initial_increment: 0.1,
        max_increment: 0.1,
        growth: 1.0,
        extrapolate: false,
        residual_tolerance: 1e-12,
        force_floor: 1e-14,
        stabilisation: Stabilisation::Constant,
        ..params
    };
    let mut u = vec![0.0; 3];
    let mut records = Vec::new();
    let result = solve_quasi_static(
        &mut model,
        DofMap::with_total(3, &[]),
        &params,
        1.0,
        &[],
        &mut u,
        |record, snapshot| records.push((record.clone(), snapshot.u.to_vec())),
    )
    .unwrap();
    assert_eq!(result.status, RunStatus::Complete);
    assert_eq!(records.len(), 10);
    (result, records)
}

/// Requirement: with a constant factor the stabilised steps are the
/// backward-Euler updates above, each converged in one Newton iteration
/// (the force and tangent of the viscous term are consistent), and the
/// reported dissipation is `Σ (c m/Δλ) |Δu|²`.
///
/// Tolerance: the problem is linear, so one Newton step solves it to
/// round-off; 1e-12 relative.
#[test]
fn constant_stabilisation_is_backward_euler() {
    let (k, m, c) = (2.0, 0.5, 3.0);
    let e = [1.0, -0.5, 0.25];
    let (result, records) = ten_steps(
        Spring { k, k0: 0.0, m, e },
        NewtonParameters {
            stabilisation_factor: c,
            ..Default::default()
        },
    );
    let mut expected = [0.0; 3];
    let mut lambda = 0.0;
    let mut dissipated = 0.0;
    for (record, u) in &records {
        let step = record.load - lambda;
        lambda = record.load;
        let damping = c * m / step;
        let mut step_dissipation = 0.0;
        for i in 0..3 {
            let next = (k * lambda * e[i] + damping * expected[i]) / (k + damping);
            step_dissipation += damping * (next - expected[i]).powi(2);
            expected[i] = next;
            assert!((u[i] - next).abs() <= 1e-12 * next.abs().max(1e-3));
        }
        dissipated += step_dissipation;
        assert_eq!(record.iterations, 1, "λ = {lambda}");
        let s = record.stabilisation.unwrap();
        assert_eq!(s.factor, c);
        assert!((s.dissipated - step_dissipation).abs() <= 1e-12 * step_dissipation);
        assert!((s.dissipated_total - dissipated).abs() <= 1e-12 * dissipated);
        let internal: f64 = (0..3)
            .map(|i| 0.5 * k * (u[i] - lambda * e[i]).powi(2))
            .sum();
        assert!((record.internal_energy - internal).abs() <= 1e-12 * internal);
    }
    assert!((result.stabilisation_energy - dissipated).abs() <= 1e-12 * dissipated);
    // The lag behind the anchor is the damping: without it the spring
    // would sit on the anchor with no energy.
    assert!(result.internal_energy > 0.0);
}

/// Requirement: the automatic factor leaves the first step unstabilised
/// and then targets `dD/dλ ≈ φ E_int`; without stabilisation nothing is
/// dissipated and no record is written.
///
/// Tolerance: on this problem the automatic factor's damping is tiny
/// against `k` (φ = 1e-4), so the dissipated fraction is of order `φ`;
/// 1e-3 bounds it with margin.
#[test]
fn automatic_stabilisation_dissipates_a_small_fraction() {
    let run = |stabilisation| {
        let mut model = Model::new(1);
        model.add(Spring {
            k: 2.0,
            k0: 1.0,
            m: 0.5,
            e: [1.0, 0.0, 0.0],
        });
        let params = NewtonParameters {
            initial_increment: 0.1,
            max_increment: 0.1,
            stabilisation,
            ..Default::default()
        };
        let mut u = vec![0.0; 3];
        let mut records = Vec::new();
        let result = solve_quasi_static(
            &mut model,
            DofMap::with_total(3, &[]),
            &params,
            1.0,
            &[],
            &mut u,
            |record, _| records.push(record.clone()),
        )
        .unwrap();
        (result, records)
    };
    let (result, records) = run(Stabilisation::Automatic);
    assert_eq!(result.status, RunStatus::Complete);
    assert_eq!(records[0].stabilisation.unwrap().factor, 0.0);
    assert!(records[1].stabilisation.unwrap().factor > 0.0);
    assert!(result.stabilisation_energy > 0.0);
    assert!(result.stabilisation_energy < 1e-3 * result.internal_energy);
    assert!(result.warnings.is_empty());
    let (plain, records) = run(Stabilisation::Off);
    assert_eq!(plain.stabilisation_energy, 0.0);
    assert!(records.iter().all(|r| r.stabilisation.is_none()));
}

/// Requirement: with `inertia_duration = T` each step is backward Euler
/// on `m ü + c m u̇_λ + k (u − λ e) = 0` with the step's time
/// `h = T (τ(λ_{n+1}) − τ(λ_n))` (`τ` the inverse of the programme's
/// shape: `λ` for a linear one, `√λ` for a quadratic one):
///
///     (m/h²)(u − u_n − h v_n) + (c m/Δλ)(u − u_n) + k (u − λ e) = 0,
///     v_{n+1} = (u − u_n)/h,
///
/// from the second step on (the first is static and leaves the node at
/// rest), converged in one Newton iteration (force and tangent of the mass
/// term consistent, viscous and inertial terms combined); the step's reported
/// dissipation is the viscous `(c m/Δλ)|Δu|²` plus backward Euler's
/// `½ m |v_{n+1} − v_n|²`, and its kinetic energy `½ m |v_{n+1}|²`.
///
/// Tolerance: the problem is linear, so one Newton step solves it to
/// round-off; 1e-12 relative.
#[test]
fn inertia_is_backward_euler_dynamics() {
    inertia_run(Amplitude::Linear, |f| f);
    inertia_run(Amplitude::Quadratic, f64::sqrt);
}

/// The run of [`inertia_is_backward_euler_dynamics`] with the programme
/// `f = shape(t/T)`, `tau` the inverse of `shape`.
fn inertia_run(amplitude: Amplitude, tau: fn(f64) -> f64) {
    let (k, m, c, duration) = (2.0, 0.5, 0.3, 1.5);
    let e = [1.0, -0.5, 0.25];
    let (result, records) = ten_steps(
        Spring { k, k0: 0.0, m, e },
        NewtonParameters {
            stabilisation_factor: c,
            inertia_duration: Some(duration),
            inertia_amplitude: amplitude,
            ..Default::default()
        },
    );
    let (mut expected, mut velocity) = ([0.0; 3], [0.0; 3]);
    let mut lambda = 0.0;
    let mut dissipated = 0.0;
    for (record, u) in &records {
        let step = record.load - lambda;
        // The first step is static: the dynamics starts from rest there.
        let h = duration * (tau(record.load) - tau(lambda));
        lambda = record.load;
        let inertia = if record.step == 1 { 0.0 } else { m / (h * h) };
        let damping = c * m / step;
        let (mut step_dissipation, mut kinetic) = (0.0, 0.0);
        for i in 0..3 {
            let next = (k * lambda * e[i]
                + inertia * (expected[i] + h * velocity[i])
                + damping * expected[i])
                / (k + inertia + damping);
            let v = if record.step == 1 {
                0.0
            } else {
                (next - expected[i]) / h
            };
            step_dissipation +=
                damping * (next - expected[i]).powi(2) + 0.5 * m * (v - velocity[i]).powi(2);
            kinetic += 0.5 * m * v * v;
            expected[i] = next;
            velocity[i] = v;
            assert!((u[i] - next).abs() <= 1e-12 * next.abs().max(1e-3));
        }
        dissipated += step_dissipation;
        assert_eq!(record.iterations, 1, "λ = {lambda}");
        let s = record.stabilisation.unwrap();
        assert!((s.dissipated - step_dissipation).abs() <= 1e-12 * step_dissipation);
        assert!((s.dissipated_total - dissipated).abs() <= 1e-12 * dissipated);
        assert!((s.kinetic - kinetic).abs() <= 1e-12 * kinetic);
    }
    assert!((result.stabilisation_energy - dissipated).abs() <= 1e-12 * dissipated);
    // The inertia weighs: m/h² = 22 against k = 2, so a solver that
    // dropped it (or took h = Δλ) would miss the recursion above.
    assert!(
        records
            .iter()
            .any(|(r, _)| r.stabilisation.unwrap().kinetic > 1e-3)
    );
}
