//! Element-cycles per second of the explicit bending pass
//! (`BendingPass::add_forces`, docs/bending.md "Explicit three-phase
//! scheme"): one element-cycle is the bending force of one triangle, i.e.
//! one call of the three phases divided by the number of triangles.
//!
//! Mesh: 14,400 triangles (150 × 300 mm, 60 × 120 cells of 2.5 mm, each
//! cut along one diagonal), rovings along y, all edges free, paper
//! stiffness. State: the blank bent onto a cylinder of radius 100 mm about
//! the y-axis plus a seeded ±0.05 mm perturbation of every node, so every
//! hinge is bent and every element in a general state.
//!
//! Run: `cargo bench --bench bending`; criterion reports the median
//! throughput in elements (= element-cycles) per second on one thread, for
//! the whole pass and for each phase alone.

// Index loops mirror the indices of the formulas (nodes, edges, components).
#![allow(clippy::needless_range_loop)]

use std::hint::black_box;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use ncform::element::bending::{BendingElement, BendingPass, BendingStiffness, BendingTopology};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

fn setup() -> (BendingPass, Vec<f64>) {
    let (nx, ny, h) = (60, 120, 2.5);
    let id = |i: usize, j: usize| i + j * (nx + 1);
    let mut nodes = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            nodes.push(Vector3::new(i as f64 * h, j as f64 * h, 0.0));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (bl, br, tr, tl) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([bl, br, tr]);
            triangles.push([bl, tr, tl]);
        }
    }
    assert_eq!(triangles.len(), 14_400);
    let topology = BendingTopology::new(&triangles, nodes.len()).expect("topology");
    let kinds = topology.free_hinge_kinds();
    let fibre = Vector3::y();
    let elements: Vec<BendingElement> = (0..triangles.len())
        .map(|e| {
            let stencil = topology.stencil(e);
            let x = std::array::from_fn(|s| nodes[stencil[s].unwrap_or(triangles[e][0])]);
            BendingElement::new(&x, kinds[e], &fibre).expect("element")
        })
        .collect();
    let stiffness = BendingStiffness::paper();
    let pass = BendingPass::new(&nodes, &topology, &elements, &stiffness).expect("pass");
    let radius = 100.0;
    let mut rng = StdRng::seed_from_u64(14_400);
    let mut u = vec![0.0; 3 * nodes.len()];
    for (n, p) in nodes.iter().enumerate() {
        let phi = (p.x - 75.0) / radius;
        let target = Vector3::new(75.0 + radius * phi.sin(), p.y, radius * (1.0 - phi.cos()));
        for c in 0..3 {
            u[3 * n + c] = target[c] - p[c] + rng.random_range(-0.05..0.05);
        }
    }
    (pass, u)
}

fn element_cycles(criterion: &mut Criterion) {
    let (pass, u) = setup();
    let count = pass.element_count();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut scratch = pass.scratch();
    let mut forces = vec![[0.0; 9]; count];
    // Fill the scratch once, so that each phase alone reads a valid state.
    pass.add_forces(&u, &mut scratch, &mut forces)
        .expect("forces");
    let mut group = criterion.benchmark_group("bending_element_cycles");
    group.throughput(Throughput::Elements(count as u64));
    group.bench_function("all_phases_1_thread", |b| {
        pool.install(|| {
            b.iter(|| {
                pass.add_forces(black_box(&u), &mut scratch, &mut forces)
                    .expect("forces")
            })
        })
    });
    let pool2 = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("pool");
    group.bench_function("all_phases_2_threads", |b| {
        pool2.install(|| {
            b.iter(|| {
                pass.add_forces(black_box(&u), &mut scratch, &mut forces)
                    .expect("forces")
            })
        })
    });
    let mut flush = vec![0.0f64; 8 << 20];
    group.bench_function("all_phases_1_thread_cold", |b| {
        pool.install(|| {
            b.iter_batched(
                || {
                    for (i, x) in flush.iter_mut().enumerate() {
                        *x += i as f64;
                    }
                },
                |_| {
                    pass.add_forces(black_box(&u), &mut scratch, &mut forces)
                        .expect("forces")
                },
                criterion::BatchSize::PerIteration,
            )
        })
    });
    // Each phase alone, serially over all batches (where the time goes).
    let batches = pass.batch_count();
    group.bench_function("phase1_geometry", |b| {
        b.iter(|| {
            pass.geometry(
                0,
                black_box(&u),
                &mut scratch.geometry,
                &mut scratch.normals,
            );
            pass.ghost_normals(&u, &mut scratch.ghosts);
        })
    });
    group.bench_function("phase2_moments", |b| {
        b.iter(|| {
            pass.moments::<true>(
                0,
                &scratch.geometry,
                &scratch.normals,
                &scratch.ghosts,
                &mut scratch.hinges[..batches],
                &mut scratch.moments,
                &mut forces,
            )
            .expect("moments")
        })
    });
    group.bench_function("phase3_hinge_forces", |b| {
        b.iter(|| {
            pass.hinge_forces(
                0,
                &scratch.geometry,
                &scratch.normals,
                &scratch.ghosts,
                &scratch.hinges,
                &scratch.moments,
                &mut forces,
            )
        })
    });
    group.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().without_plots();
    targets = element_cycles
}
criterion_main!(benches);
