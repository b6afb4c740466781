//! Node-cycles per second of the explicit tool contact
//! (`ToolContact::explicit_forces`, docs/contact.md "Explicit path"): one
//! node-cycle is the contact force of one ply node against one tool in one
//! increment (broad phase, query, penalty kernel with friction, dashpot).
//!
//! Set-up: the hemisphere bench's flange. A 300 × 300 mm ply of 85 × 85
//! nodes (7,225; mid-surface at z = 0.15 mm, 0.3 mm thick) between the die
//! (a plate with a round opening R 80 mm, 5 mm fillet, face at z = 0) and
//! the floating blankholder (the same plate turned over, face at
//! z = 0.3 mm), the paper's friction 0.147. Every increment the nodes move
//! by a seeded motion of up to ±2 µm in the plane and press 1–3 µm into
//! both tools, so every node outside the opening is closed on both tools,
//! some sticking and some slipping, and the nodes over the opening are
//! open (the broad phase proves most of them far).
//!
//! A second group, the punch: a sphere R 75 mm over the same nodes, the
//! inner ones (within 60 mm of the axis) lying on its cap and pressing
//! 1–3 µm into it, the outer ones 20 mm below the cap's rim, where the
//! broad phase proves them far — the hemisphere bench's punch in mid-stroke,
//! where most of a tool's cost is visiting nodes that are not in contact;
//! and the same punch 10 mm back up (`_far`), every pair proved far.
//!
//! Run: `cargo bench --bench contact`; criterion reports the median
//! throughput in node-cycles per second (of the two tools together in the
//! first group), on one and on two threads.

use std::hint::black_box;
use std::sync::Arc;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use ncform::contact::{Placed, Placement, PlateWithHole, RigidSurface, Side, Sphere};
use ncform::model::{ContactOptions, Masses, State, Term, ToolContact};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

#[path = "common/threads.rs"]
mod threads;
use threads::on_one_and_two_threads;

/// Nodes per side of the ply.
const SIDE: usize = 85;

/// The ply's reference nodes, mid-surface at z = 0.15 mm.
fn ply_nodes() -> Vec<Vector3<f64>> {
    let h = 300.0 / (SIDE - 1) as f64;
    (0..SIDE * SIDE)
        .map(|k| {
            let (i, j) = (k % SIDE, k / SIDE);
            Vector3::new(-150.0 + i as f64 * h, -150.0 + j as f64 * h, 0.15)
        })
        .collect()
}

/// The contact of every ply node with `surface`, translating along z by
/// extra dof `extra`.
fn tool(name: &str, surface: Arc<dyn RigidSurface>, extra: usize) -> ToolContact {
    tool_at(name, surface, extra, ply_nodes())
}

/// The contact of the nodes at `reference` with `surface`, translating
/// along z by extra dof `extra`.
fn tool_at(
    name: &str,
    surface: Arc<dyn RigidSurface>,
    extra: usize,
    reference: Vec<Vector3<f64>>,
) -> ToolContact {
    let n = reference.len();
    ToolContact::new(
        name,
        surface,
        Vector3::new(0.0, 0.0, -1.0),
        extra,
        n,
        (0..n).collect(),
        reference,
        vec![0.15; n],
        vec![(300.0 / (SIDE - 1) as f64).powi(2); n],
        vec![100.0; n],
        ContactOptions {
            friction: 0.147,
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

fn plate(origin: f64, axis: f64) -> Arc<dyn RigidSurface> {
    Arc::new(Placed::new(
        PlateWithHole::new(80.0, 5.0).expect("plate"),
        Placement::new(
            Vector3::new(0.0, 0.0, origin),
            Vector3::new(0.0, 0.0, axis),
            None,
        )
        .expect("placement"),
    ))
}

/// Two states of `n` nodes and `extras` tool dofs: each node moved in the
/// plane by a seeded amount of up to ±2 µm (seed `seed`), the tools' dofs
/// set by `tools(state, dofs)`.
fn two_states(
    n: usize,
    extras: usize,
    seed: u64,
    tools: impl Fn(usize, &mut [f64]),
) -> Vec<Vec<f64>> {
    let mut rng = StdRng::seed_from_u64(seed);
    (0..2)
        .map(|s| {
            let mut v = vec![0.0; 3 * n + extras];
            for i in 0..n {
                v[3 * i] = 2e-3 * rng.random_range(-1.0..1.0);
                v[3 * i + 1] = 2e-3 * rng.random_range(-1.0..1.0);
            }
            tools(s, &mut v[3 * n..]);
            v
        })
        .collect()
}

fn node_cycles(criterion: &mut Criterion) {
    let n = SIDE * SIDE;
    let mut die = tool("die", plate(0.0, 1.0), 0);
    let mut blankholder = tool("blankholder", plate(0.3, -1.0), 1);
    // Paper-size figures: a node of 12.8 mm² at 0.3 kg/m², a step of
    // 1.2 µs (the bench's order).
    let masses = Masses {
        node: vec![0.3e-9 * 12.8; n],
        extra: vec![0.0, 1.7e-3],
    };
    let time_step = 1.2e-6;
    let mut u = vec![0.0; 3 * n + 2];
    for term in [&mut die, &mut blankholder] {
        term.explicit_setup(&State::at(&u), &masses, time_step)
            .expect("setup");
    }
    // Two states a seeded motion apart, visited in turn: the in-plane
    // motion alternates so the nodes stay put on average, the pressing
    // alternates between 1 and 3 µm. The die's dof stays 0; the
    // blankholder's sits 1 or 3 µm low (it moves along −z): both tools
    // press into the ply.
    let states = two_states(n, 2, 7_225, |s, tools| {
        let press = if s == 0 { 1e-3 } else { 3e-3 };
        tools[0] = -press;
        tools[1] = press;
    });
    u.clone_from(&states[0]);
    let mut out = vec![0.0; 4 * (n + 1)];
    let mut group = criterion.benchmark_group("tool_contact_node_cycles");
    group.throughput(Throughput::Elements(2 * n as u64));
    on_one_and_two_threads(&mut group, "", &states, time_step, |state| {
        die.explicit_forces(state, &mut out).expect("die");
        black_box(&out);
        blankholder
            .explicit_forces(state, &mut out)
            .expect("blankholder");
        black_box(&out);
    });
    group.finish();
    let closed =
        [&die, &blankholder].map(|t| t.node_contacts().iter().filter(|c| c.status != 0).count());
    let slipping =
        [&die, &blankholder].map(|t| t.node_contacts().iter().filter(|c| c.status == 2).count());
    println!("closed pairs (die, blankholder): {closed:?} of {n} each; slipping: {slipping:?}");
}

/// Punch radius \[mm\] and the radius of the cap the ply lies on \[mm\].
const PUNCH_RADIUS: f64 = 75.0;
const CAP_RADIUS: f64 = 60.0;

fn punch_node_cycles(criterion: &mut Criterion) {
    // The sphere's centre at the origin, the ply below it: a node within
    // the cap on the sphere one offset out, the others 20 mm below the
    // cap's rim.
    let rim = -(PUNCH_RADIUS * PUNCH_RADIUS - CAP_RADIUS * CAP_RADIUS).sqrt();
    let reference: Vec<Vector3<f64>> = ply_nodes()
        .iter()
        .map(|x| {
            let r2 = x.x * x.x + x.y * x.y;
            let z = if r2 <= CAP_RADIUS * CAP_RADIUS {
                -((PUNCH_RADIUS + 0.15).powi(2) - r2).sqrt()
            } else {
                rim - 20.0
            };
            Vector3::new(x.x, x.y, z)
        })
        .collect();
    let n = reference.len();
    let sphere: Arc<dyn RigidSurface> =
        Arc::new(Sphere::new(PUNCH_RADIUS, Side::Outside).expect("sphere"));
    let mut punch = tool_at("punch", sphere, 0, reference);
    let masses = Masses {
        node: vec![0.3e-9 * 12.8; n],
        extra: vec![0.0],
    };
    let time_step = 1.2e-6;
    let mut u = vec![0.0; 3 * n + 1];
    punch
        .explicit_setup(&State::at(&u), &masses, time_step)
        .expect("setup");
    // Two states a seeded motion apart: in-plane motion of ±2 µm, the
    // punch's dof (along −z) 1 or 3 µm into the cap.
    let states = two_states(n, 1, 75, |s, tools| {
        tools[0] = if s == 0 { 1e-3 } else { 3e-3 };
    });
    // The punch 10 mm back up: every pair open and proved far (the
    // stroke's start, and the flange at any time).
    let far_states: Vec<Vec<f64>> = states
        .iter()
        .map(|v| {
            let mut v = v.clone();
            v[3 * n] -= 10.0;
            v
        })
        .collect();
    u.clone_from(&states[0]);
    let mut out = vec![0.0; 4 * (n + 1)];
    let mut group = criterion.benchmark_group("punch_contact_node_cycles");
    group.throughput(Throughput::Elements(n as u64));
    on_one_and_two_threads(&mut group, "", &states, time_step, |state| {
        punch.explicit_forces(state, &mut out).expect("punch");
        black_box(&out);
    });
    let closed = punch
        .node_contacts()
        .iter()
        .filter(|c| c.status != 0)
        .count();
    on_one_and_two_threads(&mut group, "_far", &far_states, time_step, |state| {
        punch.explicit_forces(state, &mut out).expect("punch");
        black_box(&out);
    });
    group.finish();
    let far_closed = punch
        .node_contacts()
        .iter()
        .filter(|c| c.status != 0)
        .count();
    println!("closed pairs (punch): {closed} of {n}; 10 mm back: {far_closed}");
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).without_plots();
    targets = node_cycles, punch_node_cycles
}
criterion_main!(benches);
