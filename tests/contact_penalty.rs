//! The explicit penalty per unit area (`docs/contact.md`, "Explicit path:
//! penalty with regularised friction"): with `explicit_pressure_stiffness`
//! a ply pressed by `δ` into a tool, or into another ply, carries the
//! pressure `k_p δ` whatever its mesh, while the default fraction of the
//! stability limit gives each node `c · 4m/Δt²`, which per unit area grows
//! as the stable step shrinks with the cells.

use std::sync::Arc;

use nalgebra::Vector3;

use ncform::contact::{Placed, Placement, Plane, RigidSurface};
use ncform::model::{
    ContactOptions, ExplicitPenalty, Masses, PlyContact, PlyContactOptions, PlySurface, State,
    Term, ToolContact,
};

/// The paper's areal mass, 0.30 kg/m² \[t/mm²\].
const AREAL_MASS: f64 = 0.30e-9;

/// A `size` × `size` mm square at height `z` in `cells` × `cells` squares,
/// each cut into two triangles: nodes, triangles and nodal areas (a third
/// of each adjacent triangle's area).
fn square(size: f64, cells: usize, z: f64) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>, Vec<f64>) {
    let h = size / cells as f64;
    let row = cells + 1;
    let nodes: Vec<Vector3<f64>> = (0..row * row)
        .map(|k| Vector3::new((k % row) as f64 * h, (k / row) as f64 * h, z))
        .collect();
    let mut triangles = Vec::new();
    for j in 0..cells {
        for i in 0..cells {
            let a = j * row + i;
            triangles.push([a, a + 1, a + row + 1]);
            triangles.push([a, a + row + 1, a + row]);
        }
    }
    let mut areas = vec![0.0; nodes.len()];
    for t in &triangles {
        for &n in t {
            areas[n] += h * h / 6.0;
        }
    }
    (nodes, triangles, areas)
}

/// The sum of the normal forces on a `cells` × `cells` ply of 40 × 40 mm
/// lying on the plane z = 0 (mid-surface offset 0.15 mm) and pressed
/// `depth` mm into it, with the penalty `penalty` and the stable step
/// `time_step` (no dashpot, so the force is the springs' alone) \[N\].
fn pressed_on_a_tool(cells: usize, penalty: ExplicitPenalty, time_step: f64, depth: f64) -> f64 {
    let (nodes, _, areas) = square(40.0, cells, 0.15);
    let n = nodes.len();
    let plane: Arc<dyn RigidSurface> = Arc::new(Placed::new(Plane::new(), Placement::identity()));
    let mut term = ToolContact::new(
        "contact with plane",
        plane,
        Vector3::new(0.0, 0.0, -1.0),
        0,
        n,
        (0..n).collect(),
        nodes,
        vec![0.15; n],
        areas.clone(),
        vec![100.0; n],
        ContactOptions {
            friction: 0.2,
            gap_tolerance: 1e-3,
            multiplier_tolerance: 1e-3,
            tangential_penalty_scale: 1.0,
            smoothing: Default::default(),
            explicit_stiffness: penalty,
            explicit_damping: 0.0,
            compaction: None,
        },
    );
    let masses = Masses {
        node: areas.iter().map(|a| AREAL_MASS * a).collect(),
        extra: vec![1.0],
    };
    let mut u = vec![0.0; 3 * n + 1];
    term.explicit_setup(&State::at(&u), &masses, time_step)
        .unwrap();
    for i in 0..n {
        u[3 * i + 2] = -depth;
    }
    let state = State {
        time_step,
        ..State::at(&u)
    };
    let mut forces = vec![0.0; 4 * (n + 1)];
    term.explicit_forces(&state, &mut forces).unwrap();
    term.node_contacts().iter().map(|c| c.normal_force).sum()
}

/// Requirement: with a penalty per unit area `k_p` a ply pressed `δ` into a
/// tool carries `k_p δ A` on a coarse and on a fine mesh (stable steps in
/// the ratio of their cells, as the solver's would be), while the fraction
/// of the stability limit carries `(Δt_coarse/Δt_fine)²` = 16 times more on
/// the mesh with cells four times smaller.
///
/// Tolerance: 1e-12 relative, the round-off of summing a few hundred nodal
/// forces (the relation is exact in real arithmetic).
#[test]
fn a_penalty_per_unit_area_presses_every_mesh_alike() {
    let (k_p, depth, area) = (2.0, 1e-3, 1600.0);
    let coarse_step = 4e-6;
    for (cells, time_step) in [(4, coarse_step), (16, coarse_step / 4.0)] {
        let force = pressed_on_a_tool(cells, ExplicitPenalty::PerArea(k_p), time_step, depth);
        let expected = k_p * depth * area;
        assert!(
            (force / expected - 1.0).abs() <= 1e-12,
            "{cells} cells: {force} N, k_p δ A = {expected} N"
        );
    }
    let fraction = ExplicitPenalty::StableFraction(0.1);
    let coarse = pressed_on_a_tool(4, fraction, coarse_step, depth);
    let fine = pressed_on_a_tool(16, fraction, coarse_step / 4.0, depth);
    // Each node: c · 4 m/Δt² with m = ρ_A A_n, so the sum is c 4 ρ_A A δ/Δt².
    let expected = |step: f64| 0.1 * 4.0 * AREAL_MASS * area * depth / (step * step);
    for (force, step) in [(coarse, coarse_step), (fine, coarse_step / 4.0)] {
        assert!(
            (force / expected(step) - 1.0).abs() <= 1e-12,
            "{force} N against {} N",
            expected(step)
        );
    }
    assert!((fine / coarse - 16.0).abs() <= 1e-9, "{fine} / {coarse}");
}

/// Requirement: with a penalty per unit area two plies pressed `δ` into
/// each other carry `k_p δ A` between them (each ply's nodes take half,
/// the two passes together the whole), on a coarse and on a fine mesh.
///
/// Tolerance: 1e-9 relative: each node's penetration is the difference of
/// millimetre coordinates (round-off 1e-16 mm) against `δ` = 1e-3 mm.
#[test]
fn two_plies_pressed_together_carry_the_per_area_pressure() {
    let (k_p, depth, area) = (2.0, 1e-3, 1600.0);
    for (cells, time_step) in [(4, 4e-6), (16, 1e-6)] {
        let ply = |name: &str, z: f64, offset: usize| {
            let (reference, triangles, _) = square(40.0, cells, z);
            PlySurface {
                name: name.into(),
                nodes: (0..reference.len()).map(|k| k + offset).collect(),
                reference,
                triangles,
                thickness: 0.3,
            }
        };
        let lower = ply("lower", 0.15, 0);
        let count = lower.nodes.len();
        let upper = ply("upper", 0.45, count);
        let areas: Vec<f64> = square(40.0, cells, 0.0).2;
        let mut term = PlyContact::new(
            "contact of lower with upper",
            lower,
            upper,
            PlyContactOptions {
                friction: 0.3,
                explicit_stiffness: ExplicitPenalty::PerArea(k_p),
                explicit_damping: 0.0,
                skin: 1.0,
                compaction: None,
            },
        )
        .unwrap();
        let masses = Masses {
            node: areas.iter().chain(&areas).map(|a| AREAL_MASS * a).collect(),
            extra: Vec::new(),
        };
        let mut u = vec![0.0; 6 * count];
        term.explicit_setup(&State::at(&u), &masses, time_step)
            .unwrap();
        for i in count..2 * count {
            u[3 * i + 2] = -depth;
        }
        let state = State {
            time_step,
            ..State::at(&u)
        };
        let mut forces = vec![0.0; 6 * count];
        term.explicit_forces(&state, &mut forces).unwrap();
        let (lower_force, upper_force) = (term.normal_force(0), term.normal_force(1));
        let expected = k_p * depth * area;
        for (half, which) in [(lower_force, "lower"), (upper_force, "upper")] {
            assert!(
                (half / (0.5 * expected) - 1.0).abs() <= 1e-9,
                "{cells} cells, {which} ply's nodes: {half} N, k_p δ A / 2 = {} N",
                0.5 * expected
            );
        }
        // The upper ply is pushed up by the whole pressure.
        let up: f64 = (count..2 * count).map(|i| forces[3 * i + 2]).sum();
        assert!(
            (-up / expected - 1.0).abs() <= 1e-9,
            "{cells} cells: force on the upper ply {up} N, expected −{expected} N (a residual)"
        );
    }
}
