//! What a forming run reads on the blank (`src/post/forming.rs`): boundary
//! loops, the outer contour, draw-in, zone means and the 2D
//! image-correlation projection, on meshes whose answers are known exactly.

use nalgebra::Vector3;
use ncform::material::{Material, OrthotropicSvk};
use ncform::model::MembraneModel;
use ncform::post::forming::{
    boundary_displacement, boundary_loops, draw_in, draw_in_points, outer_boundary, polygon_area,
    projected_displacement, strain_measure, strain_measures, weighted_mean_std,
};

/// A grid of `nx × ny` cells of `h` mm centred on the origin, cells cut by
/// their `/` diagonal, node `(i, j)` at index `i + j (nx + 1)`; cells listed
/// in `holes` are left out.
fn grid(
    nx: usize,
    ny: usize,
    h: f64,
    holes: &[(usize, usize)],
) -> (Vec<[f64; 2]>, Vec<[usize; 3]>) {
    let id = |i: usize, j: usize| i + j * (nx + 1);
    let mut nodes = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            nodes.push([
                (i as f64 - 0.5 * nx as f64) * h,
                (j as f64 - 0.5 * ny as f64) * h,
            ]);
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            if holes.contains(&(i, j)) {
                continue;
            }
            let (bl, br, tr, tl) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([bl, br, tr]);
            triangles.push([bl, tr, tl]);
        }
    }
    (nodes, triangles)
}

fn membrane(nodes: &[[f64; 2]], triangles: &[[usize; 3]], fibre: Vector3<f64>) -> MembraneModel {
    let material = Material::OrthotropicSvk(OrthotropicSvk {
        e1: 1000.0,
        e2: 100.0,
        nu12: 0.3,
        g12: 50.0,
    });
    MembraneModel::new(
        nodes
            .iter()
            .map(|p| Vector3::new(p[0], p[1], 0.0))
            .collect(),
        triangles.to_vec(),
        &vec![fibre; triangles.len()],
        material,
        0.3,
    )
    .expect("model")
}

#[test]
fn a_grid_has_one_boundary_loop_counter_clockwise_through_every_edge_node() {
    let (nodes, triangles) = grid(4, 3, 10.0, &[]);
    let loops = boundary_loops(&triangles);
    assert_eq!(loops.len(), 1);
    assert_eq!(loops[0].len(), 2 * (4 + 3));
    let outer = outer_boundary(&nodes, &triangles).expect("outer");
    let points: Vec<[f64; 2]> = outer.iter().map(|&n| nodes[n]).collect();
    // The exact area of the 40 × 30 mm rectangle, counter-clockwise.
    assert!((polygon_area(&points) - 1200.0).abs() < 1e-9);
}

#[test]
fn the_outer_boundary_is_the_loop_around_the_largest_area_not_a_hole() {
    // A 5 × 5 grid with its centre cell cut out: two loops, the hole's with
    // 4 nodes; the outer one encloses the 50 × 50 mm square.
    let (nodes, triangles) = grid(5, 5, 10.0, &[(2, 2)]);
    let loops = boundary_loops(&triangles);
    assert_eq!(loops.len(), 2);
    assert_eq!(loops.iter().map(Vec::len).min(), Some(4));
    let outer = outer_boundary(&nodes, &triangles).expect("outer");
    assert_eq!(outer.len(), 20);
    let points: Vec<[f64; 2]> = outer.iter().map(|&n| nodes[n]).collect();
    assert!((polygon_area(&points) - 2500.0).abs() < 1e-9);
}

#[test]
fn draw_in_of_a_uniform_contraction_is_exact_at_midpoints_and_corners() {
    // u = −ε x: a point at distance r from the centre moves ε r inwards.
    // With an odd cell count the edge midpoints fall between two nodes and
    // are interpolated along the boundary segment.
    let (nodes, triangles) = grid(5, 3, 10.0, &[]);
    let outer = outer_boundary(&nodes, &triangles).expect("outer");
    let points = draw_in_points(&nodes, &outer);
    assert_eq!(points.len(), 8);
    let eps = 0.01;
    for p in &points {
        let d = boundary_displacement(p, &outer, |n| [-eps * nodes[n][0], -eps * nodes[n][1]]);
        let r = p.reference[0].hypot(p.reference[1]);
        let expected = eps * r;
        assert!(
            (draw_in(p, d) - expected).abs() < 1e-12,
            "{}: {} vs {expected}",
            p.name,
            draw_in(p, d)
        );
    }
    let names: Vec<&str> = points.iter().map(|p| p.name.as_str()).collect();
    assert!(names.contains(&"+x edge") && names.contains(&"-x-y corner"));
    let plus_x = points.iter().find(|p| p.name == "+x edge").expect("+x");
    assert_eq!(plus_x.reference, [25.0, 0.0]);
    // A rigid translation along +x draws the +x edge in and the −x edge out.
    let shift = |n: usize| {
        let _ = n;
        [2.0, 0.0]
    };
    let minus_x = points.iter().find(|p| p.name == "-x edge").expect("-x");
    assert!((draw_in(plus_x, boundary_displacement(plus_x, &outer, shift)) + 2.0).abs() < 1e-12);
    assert!((draw_in(minus_x, boundary_displacement(minus_x, &outer, shift)) - 2.0).abs() < 1e-12);
}

#[test]
fn weighted_mean_and_standard_deviation() {
    let (mean, std) = weighted_mean_std([(1.0, 1.0), (3.0, 5.0)]);
    assert!((mean - 4.0).abs() < 1e-15);
    // Variance: (1·9 + 3·1)/4 = 3.
    assert!((std - 3f64.sqrt()).abs() < 1e-15);
    assert_eq!(weighted_mean_std([]), (0.0, 0.0));
}

/// Nodal displacements (3 per node) of the rigid rotation by `theta` about
/// the x axis: `(x, y, 0) → (x, y cos θ, y sin θ)`.
fn tilted(nodes: &[[f64; 2]], theta: f64) -> Vec<f64> {
    nodes
        .iter()
        .flat_map(|p| [0.0, p[1] * (theta.cos() - 1.0), p[1] * theta.sin()])
        .collect()
}

#[test]
fn the_projection_of_a_tilted_sheet_shows_the_strain_of_its_foreshortening() {
    // A rigid tilt leaves the true measures at zero; projected on the
    // blank plane the sheet is foreshortened by cos θ across the rovings
    // (along x): I8 = cos²θ, I11 = cos θ, γ = 0 exactly.
    let (nodes, triangles) = grid(3, 3, 10.0, &[]);
    let model = membrane(&nodes, &triangles, Vector3::x());
    let theta = 40f64.to_radians();
    let u = tilted(&nodes, theta);
    for m in strain_measures(&model, &u) {
        let m = m.expect("defined");
        assert!(m.shear_angle_deg.abs() < 1e-9 && m.e22.abs() < 1e-12 && m.e_perp.abs() < 1e-12);
    }
    let projected = projected_displacement(&u, 0..nodes.len());
    for m in strain_measures(&model, &projected) {
        let m = m.expect("defined");
        assert!(m.shear_angle_deg.abs() < 1e-9, "{m:?}");
        assert!((m.e22 - (theta.cos().powi(2) - 1.0)).abs() < 1e-12, "{m:?}");
        assert!((m.e_perp - (theta.cos() - 1.0)).abs() < 1e-12, "{m:?}");
    }
}

#[test]
fn a_projected_triangle_turned_over_has_no_measure() {
    // Tilted past 90° the projection of the sheet is mirrored: no measure.
    let (nodes, triangles) = grid(2, 2, 10.0, &[]);
    let model = membrane(&nodes, &triangles, Vector3::x());
    let projected = projected_displacement(&tilted(&nodes, 120f64.to_radians()), 0..nodes.len());
    assert!((0..triangles.len()).all(|e| strain_measure(&model, e, &projected).is_none()));
}

/// Requirement: the deformation-mode map classifies an element by the
/// signs of `I8 − 1` and `I11 − 1` (the paper's Fig. 2d), on homogeneous
/// states whose invariants are known in closed form (`docs/theory.md`):
/// roving slip `F = I + g a0⊗b0` gives `I8 = 1 + g²`, `I11 = 1`
/// (transverse tension, mode 3); trellis shear gives `I8 = 1`,
/// `I11 = cos γ` (mixed-mode 1: compaction, the stitching not stretched);
/// the two together give `I8 > 1`, `I11 < 1` (mixed-mode 2); and the
/// reference state is mode 0. Areas add up per mode.
///
/// Tolerance: exact (a classification); the states are chosen far from
/// the 0.1 % band.
#[test]
fn deformation_modes_follow_the_signs_of_i8_and_i11() {
    use ncform::post::forming::{deformation_mode, mode_areas};
    let g: f64 = 0.2;
    let gamma: f64 = 0.5;
    assert_eq!(deformation_mode(1.0, 1.0), 0);
    assert_eq!(deformation_mode(1.0 + g * g, 1.0), 3);
    assert_eq!(deformation_mode(1.0, gamma.cos()), 1);
    assert_eq!(deformation_mode(1.0 - 0.05, gamma.cos()), 1);
    assert_eq!(deformation_mode(1.0 + g * g, gamma.cos()), 2);
    assert_eq!(deformation_mode(0.9, 1.05), 4);
    // Within 0.1 % of the reference: near the reference state.
    assert_eq!(deformation_mode(1.0 + 5e-4, 1.0 - 5e-4), 0);
    let areas = mode_areas(&[0, 1, 1, 2, 3, 4], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
    assert_eq!(areas, [1.0, 5.0, 4.0, 5.0, 6.0]);
}
