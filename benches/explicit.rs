//! Element-cycles per second of the explicit solver: one element-cycle is
//! the internal force of one triangle (the element pass) plus its share of
//! the gather-and-update node pass, i.e. one time step divided by the
//! number of triangles.
//!
//! Mesh: 14,400 triangles (150 × 300 mm, 60 × 120 cells of 2.5 mm, rovings
//! along y), the default parameter set. State: the homogeneous deformation
//! `F = [[0.9434, 0], [−0.3998, 1.0005]]` (I4 ≈ 1.001, I6 ≈ 0.40, i.e. about
//! 23° of shear, I8 ≈ 1.05, I11 ≈ 0.943) held on the boundary, plus a
//! seeded ±0.02 mm perturbation of the interior nodes: every triangle sits
//! in the middle branch of W6 and of W8 with the coupling k11 active, the
//! most expensive path of the force pass. The interior vibrates about that
//! state under the stable step, so the state stays representative.
//!
//! Run: `cargo bench --bench explicit`; criterion reports the median
//! throughput in elements (= element-cycles) per second, on 1 and 2 threads.

use std::hint::black_box;
use std::time::Instant;

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use ncform::material::MaterialSpec;
use ncform::mesh::generate::{GridPattern, GridResolution, OatSpecimen, oat_specimen};
use ncform::model::{MembraneModel, MembraneOptions, Model, State};
use ncform::solver::explicit::{ExplicitSystem, Update};
use ncform::solver::{Dirichlet, DofMap};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

const DENSITY: f64 = 1.0e-9;

/// The deformation of the benchmark state (x, y components).
fn homogeneous(x: &Vector3<f64>) -> [f64; 3] {
    let f = [[0.9434, 0.0], [-0.3998, 1.0005]];
    [
        (f[0][0] - 1.0) * x.x + f[0][1] * x.y,
        f[1][0] * x.x + (f[1][1] - 1.0) * x.y,
        0.0,
    ]
}

fn setup() -> (MembraneModel, Vec<Dirichlet>, Vec<f64>) {
    let generated = oat_specimen(&OatSpecimen {
        width: 150.0,
        length: 300.0,
        bias_angle_deg: 0.0,
        resolution: GridResolution::Counts { nx: 60, ny: 120 },
        pattern: GridPattern::RovingDiagonal,
    })
    .expect("mesh");
    let mesh = generated.mesh;
    assert_eq!(mesh.triangles.len(), 14_400);
    let material = MaterialSpec::named("schaefer2024").expect("set").material;
    let model = MembraneModel::new(
        mesh.nodes.clone(),
        mesh.triangles.clone(),
        &mesh.fibres,
        material,
        0.3,
    )
    .expect("model");
    let mut rng = StdRng::seed_from_u64(14_400);
    let mut u = vec![0.0; 3 * mesh.nodes.len()];
    let mut conditions = Vec::new();
    for (n, x) in mesh.nodes.iter().enumerate() {
        let target = homogeneous(x);
        let boundary = x.x.abs() < 1e-9
            || (x.x - 150.0).abs() < 1e-9
            || x.y.abs() < 1e-9
            || (x.y - 300.0).abs() < 1e-9;
        for k in 0..3 {
            if boundary || k == 2 {
                conditions.push(Dirichlet::driven(n, k, target[k]));
                u[3 * n + k] = target[k];
            } else {
                u[3 * n + k] = target[k] + rng.random_range(-0.02..0.02);
            }
        }
    }
    (model, conditions, u)
}

/// The model of the benchmark: the membrane alone, or with bending and the
/// contact of every node with a plane tool under the blank (its
/// mid-surface half a thickness above the plane, perturbed by ±0.02 mm:
/// about half the nodes press into the tool, with friction).
fn model_of(membrane: MembraneModel, forming: bool) -> Model {
    use ncform::contact::{Placed, Placement, Plane};
    use ncform::element::BendingStiffness;
    use ncform::model::{BendingTerm, ContactOptions, ToolContact};
    use std::sync::Arc;

    let nodes = membrane.nodes.clone();
    let triangles = membrane.triangles.clone();
    let fibres: Vec<Vector3<f64>> = membrane
        .references
        .iter()
        .map(|r| r.e1 * r.frame.a0.x + r.e2 * r.frame.a0.y)
        .collect();
    let mut model = Model::membrane(
        membrane,
        MembraneOptions {
            check_inversion: true,
            density: Some(DENSITY),
            roving_mass_length: 0.0,
            roving_mass_coupling: ncform::element::RovingCoupling::Stretch,
        },
    );
    if forming {
        let clamped = vec![false; nodes.len()];
        model.add(
            BendingTerm::new(
                "bending",
                &nodes,
                &triangles,
                &fibres,
                &clamped,
                BendingStiffness::paper(),
            )
            .expect("bending"),
        );
        let extra = model.add_extra("table");
        let plane = Placed::new(
            Plane::new(),
            Placement::translation(Vector3::new(0.0, 0.0, -0.15)).expect("placement"),
        );
        let count = nodes.len();
        model.add(ToolContact::new(
            "contact with the table",
            Arc::new(plane),
            Vector3::z(),
            extra,
            count,
            (0..count).collect(),
            nodes.clone(),
            vec![0.15; count],
            vec![6.25; count],
            vec![1200.0; count],
            ContactOptions {
                friction: 0.147,
                gap_tolerance: 3e-3,
                multiplier_tolerance: 1e-3,
                tangential_penalty_scale: 1.0,
                smoothing: Default::default(),
                explicit_stiffness: ncform::model::ExplicitPenalty::DEFAULT,
                explicit_damping: 0.2,
                compaction: None,
            },
        ));
    }
    model
}

fn run_group(criterion: &mut Criterion, group_name: &str, forming: bool) {
    let (membrane, mut conditions, mut u0) = setup();
    let triangles = membrane.triangles.len();
    let nodes = membrane.nodes.len();
    let mut model = model_of(membrane, forming);
    if forming {
        // The table is fixed; the perturbation in z reaches into it.
        conditions.push(Dirichlet::dof(model.extra_dof(0), 0.0));
        let mut rng = StdRng::seed_from_u64(7);
        for n in 0..nodes {
            u0[3 * n + 2] = rng.random_range(-0.02..0.02);
        }
        conditions.retain(|c| c.dof % 3 != 2 || c.dof >= 3 * nodes);
        u0.push(0.0);
    }
    let dofs = DofMap::with_total(model.dofs(), &conditions);
    let system = ExplicitSystem::new(&mut model, &dofs, None, &State::at(&u0)).expect("system");
    let without = system
        .critical_time_step_of(&model, &State::at(&u0), false)
        .expect("stable step");
    for term in &mut model.terms {
        term.explicit_setup(&State::at(&u0), &system.masses, without)
            .expect("set-up");
    }
    let critical = system
        .critical_time_step(&model, &State::at(&u0))
        .expect("stable step");
    let time_step = 0.9 * critical;
    let mut group = criterion.benchmark_group(group_name);
    group.throughput(Throughput::Elements(triangles as u64));
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        let mut u = u0.clone();
        let mut v = vec![0.0; u.len()];
        let mut forces = vec![0.0; system.force_len()];
        let mut partial = vec![0.0; system.partials()];
        let mut motion_partial = vec![0.0; system.node_blocks()];
        let mut seconds = vec![0.0; model.terms.len()];
        pool.install(|| {
            system
                .element_forces(&mut model, &State::at(&u), &mut forces, &mut seconds)
                .expect("forces")
        });
        group.bench_function(format!("{threads}_threads"), |b| {
            // The whole batch runs inside the pool, as the solver's loop does.
            b.iter_custom(|iterations| {
                pool.install(|| {
                    let start = Instant::now();
                    for _ in 0..iterations {
                        let motion = system.update(
                            &forces,
                            &mut u,
                            &mut v,
                            &mut partial,
                            &mut motion_partial,
                            Update {
                                velocity_step: time_step,
                                time_step,
                                damping: 0.0,
                                load_next: 1.0,
                            },
                        );
                        let state = State {
                            time_step,
                            motion,
                            ..State::at(black_box(&u))
                        };
                        system
                            .element_forces(&mut model, &state, &mut forces, &mut seconds)
                            .expect("forces");
                    }
                    start.elapsed()
                })
            })
        });
    }
    group.finish();
}

fn element_cycles(criterion: &mut Criterion) {
    run_group(criterion, "explicit_element_cycles", false);
}

/// Membrane + bending + frictional contact with one tool.
fn forming_element_cycles(criterion: &mut Criterion) {
    run_group(criterion, "explicit_element_cycles_forming", true);
}

criterion_group! {
    name = benches;
    // No HTML plots: the numbers are what we quote.
    config = Criterion::default().without_plots();
    targets = element_cycles, forming_element_cycles
}
criterion_main!(benches);
