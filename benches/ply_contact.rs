//! The ply–ply contact of the explicit path (`PlyContact`, docs/contact.md
//! "Ply–ply contact"), in two groups.
//!
//! Set-up: the [0°/90°] hemisphere bench's two plies in the flange. Two
//! 300 × 300 mm plies of 85 × 85 nodes (7,225 each, 14,112 triangles cut
//! along one diagonal), mid-surfaces 0.3 mm apart (0.3 mm thick each); the
//! upper ply has slid by (1.3, 0.7) mm and each of its nodes sits up to
//! ±0.2 mm off that in the plane (seeded), so a node lies anywhere over a
//! triangle of the other ply, as in the bench once the plies have slid.
//!
//! - `ply_pair_search`: the closest point of every node of the upper ply
//!   on the lower one over its candidate triangles (`closest_candidate`;
//!   Verlet lists of reach 0.55 mm and skin 1 mm as in the cases), the
//!   last triangle found as the hint. One thread.
//! - `ply_contact_node_cycles`: the whole term, both passes (every node of
//!   each ply against the other's triangles) with friction 0.336, the
//!   plies pressing 1–3 µm into each other and moving by up to ±2 µm in
//!   the plane each increment; one node-cycle is one node of one pass in
//!   one increment. On one and two threads.
//!
//! Run: `cargo bench --bench ply_contact`; criterion reports the median
//! throughput in nodes (searches or node-cycles) per second.

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use ncform::contact::ply_pair::{CandidateLists, closest_candidate, triangle_boxes};
use ncform::model::{Masses, State, Term};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

#[path = "common/threads.rs"]
mod threads;
use threads::on_one_and_two_threads;
#[path = "common/ply_stack.rs"]
mod ply_stack;
use ply_stack::ply_stack;

/// Nodes per side of a ply.
const SIDE: usize = 85;

/// Mid-surface distance of the plies (the sum of the half thicknesses)
/// \[mm\].
const OFFSET: f64 = 0.3;

/// Reach and skin of the candidate lists \[mm\]: the contact offset plus
/// the cull margin of the term, and the cases' default skin.
const REACH: f64 = OFFSET + 0.25;
const SKIN: f64 = 1.0;

/// A ply of `SIDE × SIDE` nodes at height `z`, slid by `shift` and each
/// node moved by up to `jitter` mm in the plane (seed `seed`); its
/// triangles, every cell cut along the same diagonal.
fn ply(z: f64, shift: [f64; 2], jitter: f64, seed: u64) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let mut rng = StdRng::seed_from_u64(seed);
    let h = 300.0 / (SIDE - 1) as f64;
    let nodes = (0..SIDE * SIDE)
        .map(|k| {
            let (i, j) = (k % SIDE, k / SIDE);
            let mut x = Vector3::new(
                -150.0 + i as f64 * h + shift[0],
                -150.0 + j as f64 * h + shift[1],
                z,
            );
            x.x += jitter * rng.random_range(-1.0..1.0);
            x.y += jitter * rng.random_range(-1.0..1.0);
            x
        })
        .collect();
    let mut triangles = Vec::new();
    for j in 0..SIDE - 1 {
        for i in 0..SIDE - 1 {
            let n = j * SIDE + i;
            triangles.push([n, n + 1, n + SIDE + 1]);
            triangles.push([n, n + SIDE + 1, n + SIDE]);
        }
    }
    (nodes, triangles)
}

fn search(criterion: &mut Criterion) {
    let (lower, triangles) = ply(0.15, [0.0; 2], 0.0, 1);
    let (upper, _) = ply(0.15 + OFFSET, [1.3, 0.7], 0.2, 2);
    let mut lists = CandidateLists::new(REACH, SKIN);
    lists.rebuild(&upper, &lower, &triangles);
    let mut boxes = vec![[0.0; 6]; triangles.len()];
    triangle_boxes(&lower, &triangles, &mut boxes);
    let one_by_one = |i: usize, hint: Option<u32>| {
        closest_candidate(&upper[i], lists.of(i), &lower, &triangles, &boxes, hint)
    };
    let hints: Vec<Option<u32>> = (0..upper.len())
        .map(|i| one_by_one(i, None).map(|(k, _, _)| k as u32))
        .collect();
    let candidates: usize = (0..upper.len()).map(|i| lists.of(i).len()).sum();
    println!(
        "candidate triangles per node: {:.2}",
        candidates as f64 / upper.len() as f64
    );
    let mut group = criterion.benchmark_group("ply_pair_search");
    group.throughput(Throughput::Elements(upper.len() as u64));
    group.bench_function("one_by_one", |b| {
        b.iter(|| {
            for (i, hint) in hints.iter().enumerate() {
                black_box(one_by_one(i, *hint));
            }
        });
    });
    group.finish();
}

fn node_cycles(criterion: &mut Criterion) {
    let (lower, triangles) = ply(0.15, [0.0; 2], 0.0, 1);
    let (upper, _) = ply(0.15 + OFFSET, [1.3, 0.7], 0.2, 2);
    let n = lower.len();
    let mut term = ply_stack(lower, upper, &triangles, OFFSET, SKIN);
    // Paper-size figures: a node of 12.8 mm² at 0.3 kg/m², a step of
    // 1.2 µs (the bench's order).
    let masses = Masses {
        node: vec![0.3e-9 * 12.8; 2 * n],
        extra: Vec::new(),
    };
    let time_step = 1.2e-6;
    term.explicit_setup(&State::at(&vec![0.0; 6 * n]), &masses, time_step)
        .expect("setup");
    // Two states a seeded motion apart, visited in turn: each node moved
    // by up to ±2 µm in the plane, the upper ply pressed 1 or 3 µm into
    // the lower one.
    let mut rng = StdRng::seed_from_u64(14_450);
    let states: Vec<Vec<f64>> = (0..2)
        .map(|s| {
            let press = if s == 0 { 1e-3 } else { 3e-3 };
            let mut u = vec![0.0; 6 * n];
            for (i, node) in u.chunks_exact_mut(3).enumerate() {
                node[0] = 2e-3 * rng.random_range(-1.0..1.0);
                node[1] = 2e-3 * rng.random_range(-1.0..1.0);
                if i >= n {
                    node[2] = -press;
                }
            }
            u
        })
        .collect();
    let mut out = vec![0.0; 6 * n];
    let mut group = criterion.benchmark_group("ply_contact_node_cycles");
    group.throughput(Throughput::Elements(2 * n as u64));
    on_one_and_two_threads(&mut group, "", &states, time_step, |state| {
        term.explicit_forces(state, &mut out).expect("forces");
        black_box(&out);
    });
    group.finish();
    let closed = [0, 1].map(|k| {
        term.node_contacts(k)
            .iter()
            .filter(|c| c.status != 0)
            .count()
    });
    let slipping = [0, 1].map(|k| {
        term.node_contacts(k)
            .iter()
            .filter(|c| c.status == 2)
            .count()
    });
    println!("closed pairs (each pass): {closed:?} of {n}; slipping: {slipping:?}");
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).without_plots();
    targets = search, node_cycles
}
criterion_main!(benches);
