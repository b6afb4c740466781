//! The explicit contact's broad phase (`docs/contact.md`, "Explicit path"):
//! a node is skipped only when the tool's clearance bound proves that the
//! query would cull it, so the results are the same, bit for bit, as
//! querying every node every increment.
//!
//! - The analytic shapes' clearance is a lower bound on the distance, and
//!   `clearance(x) − |x′ − x| > m` implies that `closest(x′, m)` is `None`;
//!   `closest_normal` answers what `closest` does, bit for bit.
//! - A contact term with the broad phase gives the same forces, outputs,
//!   energies and frequency bound as one without, over random node and
//!   tool motions (a floating tool's dof moving too).
//! - Batches of nodes proved far are skipped while the solver's motion
//!   bound says they cannot have come near, with the same results bit for
//!   bit, also when skipped nodes come back and press into the tool.
//! - A small explicit forming run (the hemisphere bench, coarse and short)
//!   is bit-identical with and without the broad phase (and its skipped
//!   batches).

use std::path::Path;
use std::sync::Arc;

use nalgebra::{Rotation3, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use ncform::case::forming::FormingCase;
use ncform::contact::{
    Cylinder, Placed, Placement, Plane, PlateWithHole, RigidSurface, Side, Sphere, SurfacePoint,
    Torus,
};
use ncform::model::{ContactOptions, Masses, State, Term, ToolContact};
use ncform::solver::explicit::ExplicitState;
use ncform::solver::solve_explicit;

fn random_unit(rng: &mut StdRng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let n = v.norm();
        if n > 0.1 && n <= 1.0 {
            return v / n;
        }
    }
}

fn random_placement(rng: &mut StdRng) -> Placement {
    let axis = random_unit(rng);
    let angle = rng.random_range(0.0..std::f64::consts::TAU);
    let origin = Vector3::new(
        rng.random_range(-20.0..20.0),
        rng.random_range(-20.0..20.0),
        rng.random_range(-20.0..20.0),
    );
    Placement::from_rotation(
        origin,
        &Rotation3::from_axis_angle(&nalgebra::Unit::new_normalize(axis), angle),
    )
    .unwrap()
}

/// Every analytic shape, placed at random.
fn shapes(rng: &mut StdRng) -> Vec<(&'static str, Arc<dyn RigidSurface>)> {
    let mut out: Vec<(&'static str, Arc<dyn RigidSurface>)> = Vec::new();
    let p = random_placement(rng);
    out.push(("plane", Arc::new(Placed::new(Plane::new(), p))));
    for side in [Side::Outside, Side::Inside] {
        let p = random_placement(rng);
        out.push((
            "sphere",
            Arc::new(Placed::new(Sphere::new(30.0, side).unwrap(), p)),
        ));
        let p = random_placement(rng);
        out.push((
            "cylinder",
            Arc::new(Placed::new(Cylinder::new(15.0, side).unwrap(), p)),
        ));
        let p = random_placement(rng);
        out.push((
            "torus",
            Arc::new(Placed::new(Torus::new(40.0, 8.0, side).unwrap(), p)),
        ));
    }
    for fillet in [5.0, 0.0] {
        let p = random_placement(rng);
        out.push((
            "plate",
            Arc::new(Placed::new(PlateWithHole::new(30.0, fillet).unwrap(), p)),
        ));
    }
    out
}

/// Requirement: `clearance(x) ≤ d(x)`; `clearance(x) − |x′ − x| > m`
/// (with a 1e-9 mm allowance for round-off) implies `closest(x′, m)` and
/// `closest_normal(x′, m)` are `None`; `closest_normal` is `closest`
/// without the Hessian, bit for bit.
#[test]
fn clearance_bounds_the_distance_and_proves_the_cull() {
    let mut rng = StdRng::seed_from_u64(0xb0a4d);
    for _ in 0..4 {
        for (name, shape) in shapes(&mut rng) {
            let mut culled = 0;
            for _ in 0..4000 {
                let x = Vector3::new(
                    rng.random_range(-80.0..80.0),
                    rng.random_range(-80.0..80.0),
                    rng.random_range(-80.0..80.0),
                );
                let c = shape.clearance(&x);
                if let Some(p) = shape.closest(&x, f64::INFINITY) {
                    assert!(
                        c <= p.distance + 1e-12,
                        "{name}: clearance {c} > distance {}",
                        p.distance
                    );
                }
                let scale = [0.01, 1.0, 20.0][rng.random_range(0..3)];
                let x2 = x + scale * rng.random_range(0.0..1.0) * random_unit(&mut rng);
                let m = rng.random_range(0.0..3.0);
                let full: Option<SurfacePoint> = shape.closest(&x2, m);
                let first = shape.closest_normal(&x2, m);
                assert_eq!(full.is_some(), first.is_some(), "{name}");
                if let (Some(p), Some(q)) = (full, first) {
                    assert_eq!(p.distance.to_bits(), q.distance.to_bits(), "{name}");
                    for k in 0..3 {
                        assert_eq!(p.normal[k].to_bits(), q.normal[k].to_bits(), "{name}");
                    }
                }
                if c - (x2 - x).norm() > m + 1e-9 {
                    culled += 1;
                    assert!(
                        full.is_none(),
                        "{name}: bound {c} at {x:?}, {x2:?} answered"
                    );
                }
            }
            assert!(culled > 5, "{name}: only {culled} points proved far");
        }
    }
}

/// A surface without a clearance (the trait's default, as a mesh tool).
struct NoClearance(Arc<dyn RigidSurface>);

impl RigidSurface for NoClearance {
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        self.0.closest(x, max_distance)
    }
}

/// One contact term on `nodes` nodes scattered about the plate's face, its
/// tool translating along z by dof 0 (floating: it has a mass).
fn term(surface: Arc<dyn RigidSurface>, reference: &[Vector3<f64>]) -> ToolContact {
    let n = reference.len();
    ToolContact::new(
        "contact",
        surface,
        Vector3::new(0.0, 0.0, -1.0),
        0,
        n,
        (0..n).collect(),
        reference.to_vec(),
        vec![0.15; n],
        vec![1.0; n],
        vec![100.0; n],
        ContactOptions {
            friction: 0.2,
            gap_tolerance: 1e-3,
            multiplier_tolerance: 1e-3,
            tangential_penalty_scale: 1.0,
            smoothing: Default::default(),
            explicit_stiffness: ncform::model::ExplicitPenalty::DEFAULT,
            explicit_damping: 0.2,
            compaction: None,
        },
    )
}

/// The plate of the contact tests: a round opening of radius 30 mm with a
/// 5 mm fillet, face at z = 0.
fn filleted_plate() -> Arc<dyn RigidSurface> {
    Arc::new(Placed::new(
        PlateWithHole::new(30.0, 5.0).unwrap(),
        Placement::identity(),
    ))
}

/// Two contact terms of `plate` on the nodes at `reference`: with the
/// broad phase (the default) and without.
fn with_and_without(
    plate: &Arc<dyn RigidSurface>,
    reference: &[Vector3<f64>],
) -> (ToolContact, ToolContact) {
    let with = term(plate.clone(), reference);
    let mut without = term(plate.clone(), reference);
    without.set_broad_phase(false);
    (with, without)
}

/// One explicit pass of every term of `terms` at `state`: the same forces,
/// per-node outputs, energies and frequency bound as the first's, bit for
/// bit.
fn assert_same_pass(terms: &mut [&mut ToolContact], state: &State, masses: &Masses, step: usize) {
    let size = 4 * (terms[0].nodes().len() + 1);
    let mut passes = Vec::new();
    for t in terms.iter_mut() {
        let mut f = vec![0.0; size];
        t.explicit_forces(state, &mut f).unwrap();
        let energy = t.energy(state).unwrap();
        let bound = t.frequency_bound(state, masses).unwrap();
        let bits = f
            .iter()
            .chain(&[energy.contact, energy.dissipated, bound.nodes, bound.extras])
            .map(|x| x.to_bits())
            .collect::<Vec<_>>();
        passes.push(bits);
    }
    for (t, pass) in terms.iter().zip(&passes).skip(1) {
        assert_eq!(pass, &passes[0], "step {step}");
        assert_eq!(t.node_contacts(), terms[0].node_contacts(), "step {step}");
    }
}

/// Requirement: the broad phase never misses a contact. Two terms, one
/// with and one without the broad phase, follow the same random motions
/// of 600 nodes about a filleted plate (steps of up to 0.05 mm, jumps of up
/// to 4 mm, some nodes pressed into the tool) and of the tool's own dof
/// (a floating tool: steps and jumps too); every increment their forces,
/// per-node outputs, energies and frequency bounds are the same bit for
/// bit. The test also checks that the broad phase skipped nodes, and a
/// surface without a clearance (the default) gives the same again.
#[test]
fn broad_phase_never_misses_a_contact() {
    let mut rng = StdRng::seed_from_u64(7381);
    let n = 600;
    let reference: Vec<Vector3<f64>> = (0..n)
        .map(|_| {
            Vector3::new(
                rng.random_range(-60.0..60.0),
                rng.random_range(-60.0..60.0),
                rng.random_range(0.0..6.0),
            )
        })
        .collect();
    let plate = filleted_plate();
    let (mut with, mut without) = with_and_without(&plate, &reference);
    let mut default = term(Arc::new(NoClearance(plate)), &reference);
    let masses = Masses {
        node: vec![1e-6; n],
        extra: vec![1.7e-3],
    };
    let dt = 1e-6;
    let mut u = vec![0.0; 3 * n + 1];
    for t in [&mut with, &mut without, &mut default] {
        t.explicit_setup(&State::at(&u), &masses, dt).unwrap();
    }
    let mut skipped = 0;
    let mut closed = 0;
    for step in 0..400 {
        for i in 0..n {
            let jump = rng.random_range(0.0..1.0) < 0.01;
            let size = if jump { 4.0 } else { 0.05 };
            for k in 0..3 {
                u[3 * i + k] += size * rng.random_range(-1.0..1.0);
            }
            // Keep the nodes about the face (z from −0.5 to 8 mm).
            let z = reference[i].z + u[3 * i + 2] + u[3 * n];
            if !(-0.5..=8.0).contains(&z) {
                u[3 * i + 2] = rng.random_range(-0.3..6.0) - reference[i].z - u[3 * n];
            }
        }
        let jump = step % 50 == 49;
        u[3 * n] += if jump { 3.0 } else { 0.02 } * rng.random_range(-1.0..1.0);
        let state = State {
            time_step: dt,
            ..State::at(&u)
        };
        assert_same_pass(
            &mut [&mut with, &mut without, &mut default],
            &state,
            &masses,
            step,
        );
        skipped += with.bounded_far();
        closed += with
            .node_contacts()
            .iter()
            .filter(|c| c.status != 0)
            .count();
        assert_eq!(default.bounded_far(), 0);
    }
    assert!(
        skipped > 400 * n / 4,
        "the broad phase held only {skipped} node-steps far"
    );
    assert!(closed > 400 * n / 50, "only {closed} closed node-steps");
}

/// Requirement: skipping the batches proved far changes nothing. Two
/// terms, one with the broad phase and one without, follow 640 nodes on a
/// grid over the plate's face: each node drifts in the plane (up to
/// 0.01 mm a step) and towards the face at its own speed (up to 0.01 mm a
/// step), bouncing back when it presses 0.05 mm into it, while the
/// floating tool's dof oscillates — steps of an explicit run's kind,
/// below the 0.1 mm cull margin. The states carry the motion bound the
/// solver measures (the largest node motion of the step). Every step
/// the forces, outputs, energies and frequency bounds are the same bit
/// for bit; batches were skipped, and nodes of skipped batches later
/// pressed into the tool (the resumed path is exercised).
#[test]
fn skipped_batches_change_nothing() {
    let mut rng = StdRng::seed_from_u64(9120);
    let side = 32;
    let n = side * 20;
    let reference: Vec<Vector3<f64>> = (0..n)
        .map(|i| {
            Vector3::new(
                -60.0 + 120.0 * (i % side) as f64 / (side - 1) as f64,
                -60.0 + 120.0 * (i / side) as f64 / 19.0,
                rng.random_range(0.4..4.0),
            )
        })
        .collect();
    let (mut with, mut without) = with_and_without(&filleted_plate(), &reference);
    let masses = Masses {
        node: vec![1e-6; n],
        extra: vec![1.7e-3],
    };
    let dt = 1e-6;
    let mut u = vec![0.0; 3 * n + 1];
    for t in [&mut with, &mut without] {
        t.explicit_setup(&State::at(&u), &masses, dt).unwrap();
    }
    let mut sink: Vec<f64> = (0..n).map(|_| rng.random_range(0.0..0.01)).collect();
    let mut proved_far = 0;
    let mut skipped_once = vec![false; n];
    let mut came_back = 0;
    for step in 0..600 {
        let mut motion = 0.0_f64;
        for i in 0..n {
            let before = [u[3 * i], u[3 * i + 1], u[3 * i + 2]];
            u[3 * i] += 0.007 * rng.random_range(-1.0..1.0);
            u[3 * i + 1] += 0.007 * rng.random_range(-1.0..1.0);
            let z = reference[i].z + u[3 * i + 2] + u[3 * n];
            if z < 0.1 {
                sink[i] = -sink[i].abs();
            } else if z > 4.0 {
                sink[i] = sink[i].abs();
            }
            u[3 * i + 2] -= sink[i];
            let moved = (0..3)
                .map(|k| (u[3 * i + k] - before[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            motion = motion.max(moved);
        }
        u[3 * n] = 0.02 * (step as f64 * 0.05).sin();
        let state = State {
            time_step: dt,
            motion: motion * (1.0 + 1e-12) + 1e-12,
            ..State::at(&u)
        };
        assert_same_pass(&mut [&mut with, &mut without], &state, &masses, step);
        assert_eq!(without.batches_proved_far(), 0);
        proved_far += with.batches_proved_far();
        for (i, c) in with.node_contacts().iter().enumerate() {
            if c.status != 0 && skipped_once[i] {
                came_back += 1;
                skipped_once[i] = false;
            }
        }
        for (i, skipped) in skipped_once.iter_mut().enumerate() {
            *skipped |= with.node_proved_far(i);
        }
    }
    assert!(
        proved_far > 600 * n / 4 / 10,
        "only {proved_far} batch-steps proved far"
    );
    assert!(
        came_back > 20,
        "only {came_back} skipped nodes came back into contact"
    );
}

/// Output times of the forming run.
fn times_len() -> usize {
    20
}

/// Requirement: an explicit forming run (the hemisphere bench, 200
/// triangles, a floating blankholder, a moving punch, friction, bending,
/// gravity) is the same bit for bit with and without the broad phase: the
/// final state and every output record.
#[test]
fn explicit_forming_run_is_bit_identical_without_the_broad_phase() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("cases/hemisphere-0.toml")).unwrap();
    assert!(text.contains("cells = [84, 84]"));
    // A short stroke: the case's duration line, whatever its value.
    let text = text
        .replace("cells = [84, 84]", "cells = [10, 10]")
        .lines()
        .map(|l| {
            if l.starts_with("duration = ") {
                "duration = 0.05"
            } else {
                l
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    let case = FormingCase::from_toml_str(&text, "hemisphere-coarse.toml", &root.join("cases"))
        .unwrap_or_else(|e| panic!("{e}"));
    let run = |broad_phase: bool| {
        let mut built = case.build().unwrap();
        let mut terms = 0;
        for t in built.model.terms_of_mut::<ToolContact>() {
            t.set_broad_phase(broad_phase);
            terms += 1;
        }
        assert_eq!(terms, 3);
        let dofs = built.dofs();
        let params = case.explicit.parameters();
        let times: Vec<f64> = (1..=times_len())
            .map(|k| params.time_of_load_fraction(k as f64 / times_len() as f64))
            .collect();
        let mut state = ExplicitState::at_rest(dofs.total);
        let result = solve_explicit(
            &mut built.model,
            &dofs,
            &params,
            1.0,
            &times,
            &mut state,
            |_, _| {},
        )
        .unwrap();
        (result, state)
    };
    let (a, sa) = run(true);
    let (b, sb) = run(false);
    assert_eq!(a.increments, b.increments);
    assert!(a.increments > 1000, "{} increments", a.increments);
    assert_eq!(a.records, b.records);
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&sa.u), bits(&sb.u));
    assert_eq!(bits(&sa.v), bits(&sb.v));
    // The smallest step taken is a step shortened to land on an output
    // (the 20 asked for and the end time, which the solver always adds),
    // not a collapse of the stable step (docs/explicit.md).
    let (landings, shortest) = a.landing_steps;
    assert!(
        (1..=times_len() + 1).contains(&landings),
        "{landings} landings, steps {:?}, stable {:?}, {} increments",
        a.time_step_range,
        a.stable_step_range,
        a.increments
    );
    assert_eq!(a.time_step_range.0, shortest.min(a.stable_step_range.0));
    assert!(a.stable_step_range.0 > 0.5 * a.stable_step_range.1);
    // What sets the step (`term_steps`): the combined bound is at least
    // each term's and at most their sum (Weyl), so the critical step at
    // the start lies between the smallest term step over √(terms with a
    // bound) and the smallest term step (round-off: 1e-12 relative).
    assert_eq!(a.term_steps.len(), a.term_seconds.len());
    let firsts: Vec<f64> = a.term_steps.iter().filter_map(|s| s.first).collect();
    let smallest = firsts.iter().fold(f64::INFINITY, |m, s| m.min(*s));
    assert!(firsts.iter().all(|s| *s > 0.0 && s.is_finite()));
    assert!(
        a.initial_critical_time_step <= smallest * (1.0 + 1e-12)
            && a.initial_critical_time_step
                >= smallest / (firsts.len() as f64).sqrt() * (1.0 - 1e-12),
        "critical {} against the term steps {:?}",
        a.initial_critical_time_step,
        a.term_steps
    );
    // The punch went down: contact did happen.
    let last = a.records.last().unwrap();
    assert!(last.energies.friction > 0.0 && last.energies.internal > 0.0);
}
