//! Tests of the rigid tool surfaces (`docs/tools.md`): the signed distance
//! `d`, its gradient (the normal) and its Hessian for every analytic shape
//! against closed forms and against finite differences, in the local frame
//! and through a placement; the C¹ junctions of the plate with hole; the
//! culling of far points; the tessellations; and the triangle-mesh tools
//! read back from STL and OBJ files.
//!
//! **Closed forms.** The reference answer is built from the closest point
//! `y`, the unit normal `n` there (towards the free side) and the principal
//! curvatures `κ_i` with directions `t_i` of the surface at `y` (positive
//! where it bends away from the free side), a different computation from
//! the code's: `d = ±|x − y|`, `∇d = n`, and
//! `∇²d = Σ_i κ_i/(1 + κ_i d) t_i⊗t_i` (the curvature of the parallel
//! surface at distance `d`). They agree up to round-off: every quantity is
//! a few dozen flops on coordinates of size `X`, each off by at most
//! `ε X`, so `d` to `64 ε X`, the normal to `64 ε X/ℓ` and the Hessian to
//! `64 ε X/ℓ²`, with `ℓ ≥ 1 mm` the sampled points' least distance to the
//! shape's centres of curvature (which also bounds `1/(1 + κ d)`).
//!
//! **Finite differences.** Central differences with step `h` have the
//! truncation error `h²/6 · f'''` and the round-off `δ/h` for values off by
//! `δ`. Along a line, the distance to a point at distance `ℓ` has
//! `|f'''| ≤ 1.16/ℓ²` and `|f''''| ≤ 3/ℓ³`; the shapes here are distances
//! to points, lines, circles and planes, and we bound their derivatives by
//! `6/ℓ²` and `30/ℓ³` (five to ten times those maxima, covering the two
//! curvature sources of a torus or fillet, `1/s` and `1/ρ`). `d` is off by
//! `δ_d = 16 ε X` and `∇d` by `16 ε X/ℓ`. With `h = 1e-4` mm (near the
//! optimum `(3δ/C)^(1/3) ≈ 1e-4` for `X = 300`, `ℓ = 1`) this gives the
//! tolerances of [`gradient_tolerance`] and [`hessian_tolerance`], ~2e-8
//! and ~6e-8. A stencil must not straddle a zone junction (where `∇²d`
//! jumps and the error becomes `O(h/r)`): points are sampled at least
//! `1e-3 mm ≫ h` from every junction.

use std::f64::consts::{FRAC_PI_2, PI, TAU};
use std::io::Write;
use std::path::{Path, PathBuf};

use nalgebra::{Matrix3, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use ncform::contact::{
    Cylinder, EdgeDefect, MeshOptions, MeshSurface, MeshToolError, Placed, Placement, Plane,
    PlateWithHole, RigidSurface, ShapeError, Side, Sphere, SurfacePoint, Tessellation, Torus,
};

const EPS: f64 = f64::EPSILON;
/// Finite-difference step [mm] (see the module doc).
const STEP: f64 = 1e-4;
/// Least distance of a sampled point to a centre of curvature or axis [mm].
const ELL: f64 = 1.0;
/// Least distance of a sampled point to a zone junction [mm] (≫ `STEP`).
const MARGIN: f64 = 1e-3;

/// Central-difference error bound on `∇d` at points with coordinates up to
/// `size` (module doc): `h²/6 · 6/ℓ² + 16 ε X/h`.
fn gradient_tolerance(size: f64) -> f64 {
    STEP * STEP / 6.0 * 6.0 / (ELL * ELL) + 16.0 * EPS * size / STEP
}

/// Central-difference error bound on `∇²d` from `∇d`: `h²/6 · 30/ℓ³ +
/// 16 ε X/(ℓ h)`.
fn hessian_tolerance(size: f64) -> f64 {
    STEP * STEP / 6.0 * 30.0 / ELL.powi(3) + 16.0 * EPS * size / (ELL * STEP)
}

fn answer(surface: &dyn RigidSurface, x: &Vector3<f64>) -> SurfacePoint {
    surface
        .closest(x, f64::INFINITY)
        .unwrap_or_else(|| panic!("no answer at {x:?}"))
}

fn fd_gradient(surface: &dyn RigidSurface, x: &Vector3<f64>) -> Vector3<f64> {
    Vector3::from_fn(|i, _| {
        let e = Vector3::ith(i, STEP);
        (answer(surface, &(x + e)).distance - answer(surface, &(x - e)).distance) / (2.0 * STEP)
    })
}

fn fd_hessian(surface: &dyn RigidSurface, x: &Vector3<f64>) -> Matrix3<f64> {
    let mut h = Matrix3::zeros();
    for i in 0..3 {
        let e = Vector3::ith(i, STEP);
        let column =
            (answer(surface, &(x + e)).normal - answer(surface, &(x - e)).normal) / (2.0 * STEP);
        h.set_column(i, &column);
    }
    h
}

fn max_abs<const R: usize, const C: usize>(m: &nalgebra::SMatrix<f64, R, C>) -> f64 {
    m.iter().fold(0.0, |acc, v| acc.max(v.abs()))
}

/// Checks `∇d` and `∇²d` of `surface` at `x` against central differences,
/// and the invariants of the answer (unit normal, symmetric Hessian with
/// the normal in its null space, to round-off `64 ε X/ℓ`).
/// Returns the errors of `∇d` and `∇²d` as fractions of their tolerances.
fn check_finite_differences(
    surface: &dyn RigidSurface,
    x: &Vector3<f64>,
    size: f64,
    label: &str,
) -> [f64; 2] {
    let a = answer(surface, x);
    let g = fd_gradient(surface, x);
    let h = fd_hessian(surface, x);
    let eg = max_abs(&(g - a.normal));
    let eh = max_abs(&(h - a.hessian));
    assert!(
        eg <= gradient_tolerance(size),
        "{label}: ∇d vs FD at {x:?}: {eg:e} > {:e}",
        gradient_tolerance(size)
    );
    assert!(
        eh <= hessian_tolerance(size),
        "{label}: ∇²d vs FD at {x:?}: {eh:e} > {:e}",
        hessian_tolerance(size)
    );
    let roundoff = 64.0 * EPS * size / ELL;
    assert!(
        (a.normal.norm() - 1.0).abs() <= roundoff,
        "{label}: |n| at {x:?}"
    );
    assert!(
        max_abs(&(a.hessian - a.hessian.transpose())) <= roundoff,
        "{label}: H symmetric"
    );
    assert!(
        max_abs(&(a.hessian * a.normal)) <= roundoff,
        "{label}: H n = 0 at {x:?}"
    );
    [eg / gradient_tolerance(size), eh / hessian_tolerance(size)]
}

/// The largest error fractions seen per label, printed at the end (run
/// with `--nocapture` to see them).
#[derive(Default)]
struct Worst(std::collections::BTreeMap<String, Vec<f64>>);

impl Worst {
    fn record(&mut self, label: &str, fractions: &[f64]) {
        let entry = self
            .0
            .entry(label.to_string())
            .or_insert_with(|| vec![0.0; fractions.len()]);
        for (w, f) in entry.iter_mut().zip(fractions) {
            *w = w.max(*f);
        }
    }

    fn print(&self, what: &str) {
        for (label, w) in &self.0 {
            eprintln!("{what} {label}: worst error / tolerance = {w:.3?}");
        }
    }
}

/// The reference answer from the closest point's normal, principal
/// directions and curvatures (module doc).
fn principal_answer(
    distance: f64,
    normal: Vector3<f64>,
    curvatures: &[(Vector3<f64>, f64)],
) -> SurfacePoint {
    let mut hessian = Matrix3::zeros();
    for (t, kappa) in curvatures {
        hessian += t * t.transpose() * (kappa / (1.0 + kappa * distance));
    }
    SurfacePoint {
        distance,
        normal,
        hessian,
    }
}

/// Returns the errors of `d`, `∇d`, `∇²d` as fractions of their
/// tolerances.
fn check_closed_form(
    surface: &dyn RigidSurface,
    x: &Vector3<f64>,
    expected: &SurfacePoint,
    size: f64,
    label: &str,
) -> [f64; 3] {
    let a = answer(surface, x);
    let (ed, en, eh) = (
        (a.distance - expected.distance).abs(),
        max_abs(&(a.normal - expected.normal)),
        max_abs(&(a.hessian - expected.hessian)),
    );
    let fractions = [
        ed / (64.0 * EPS * size),
        en / (64.0 * EPS * size / ELL),
        eh / (64.0 * EPS * size / (ELL * ELL)),
    ];
    assert!(
        ed <= 64.0 * EPS * size,
        "{label}: d at {x:?}: {} vs {} ",
        a.distance,
        expected.distance
    );
    assert!(
        en <= 64.0 * EPS * size / ELL,
        "{label}: n at {x:?}: {:?} vs {:?}",
        a.normal,
        expected.normal
    );
    assert!(
        eh <= 64.0 * EPS * size / (ELL * ELL),
        "{label}: H at {x:?}: {eh:e}\n{}\n{}",
        a.hessian,
        expected.hessian
    );
    fractions
}

fn random_point(rng: &mut StdRng, half: Vector3<f64>) -> Vector3<f64> {
    Vector3::new(
        rng.random_range(-half.x..half.x),
        rng.random_range(-half.y..half.y),
        rng.random_range(-half.z..half.z),
    )
}

/// Cylindrical basis `(e_ρ, e_φ)` at `x` (`ρ > 0`).
fn cylindrical(x: &Vector3<f64>) -> (f64, Vector3<f64>, Vector3<f64>) {
    let rho = x.x.hypot(x.y);
    (
        rho,
        Vector3::new(x.x / rho, x.y / rho, 0.0),
        Vector3::new(-x.y / rho, x.x / rho, 0.0),
    )
}

/// A point at meridian coordinates `(ρ, z)` and azimuth `φ`.
fn at_meridian(rho: f64, z: f64, phi: f64) -> Vector3<f64> {
    Vector3::new(rho * phi.cos(), rho * phi.sin(), z)
}

const SPHERE_RADIUS: f64 = 25.0;
const CYLINDER_RADIUS: f64 = 25.0;
const TORUS_MAJOR: f64 = 40.0;
const TORUS_MINOR: f64 = 10.0;
const OPENING: f64 = 40.0;
const FILLET: f64 = 8.0;

fn sides() -> [Side; 2] {
    [Side::Outside, Side::Inside]
}

fn side_sign(side: Side) -> f64 {
    match side {
        Side::Outside => 1.0,
        Side::Inside => -1.0,
    }
}

/// Closed form of the plate with hole by the nearest of its three features
/// (face, fillet arc, wall), independent of the code's zones: the distance,
/// normal and meridian curvature of the winner, and whether the meridian
/// point is inside the solid.
fn plate_reference(x: &Vector3<f64>) -> Option<SurfacePoint> {
    let (rho, e_rho, e_phi) = cylindrical(x);
    let p = Vector2::new(rho, x.z);
    let centre = Vector2::new(OPENING + FILLET, -FILLET);
    // (closest point, normal, meridian curvature)
    let face = (
        Vector2::new(rho.max(OPENING + FILLET), 0.0),
        Vector2::new(0.0, 1.0),
        0.0,
    );
    let wall = (
        Vector2::new(OPENING, x.z.min(-FILLET)),
        Vector2::new(-1.0, 0.0),
        0.0,
    );
    let q = p - centre;
    let arc = if q.x <= 0.0 && q.y >= 0.0 {
        let n = q.normalize();
        (centre + n * FILLET, n, 1.0 / FILLET)
    } else if (p - Vector2::new(OPENING, -FILLET)).norm()
        < (p - Vector2::new(OPENING + FILLET, 0.0)).norm()
    {
        (
            Vector2::new(OPENING, -FILLET),
            Vector2::new(-1.0, 0.0),
            1.0 / FILLET,
        )
    } else {
        (
            Vector2::new(OPENING + FILLET, 0.0),
            Vector2::new(0.0, 1.0),
            1.0 / FILLET,
        )
    };
    let mut features = [face, wall, arc];
    features.sort_by(|a, b| (p - a.0).norm().total_cmp(&(p - b.0).norm()));
    let [best, second, _] = features;
    // A tie (medial axis inside the plate) has no gradient: skip it.
    if ((p - second.0).norm() - (p - best.0).norm()).abs() < MARGIN
        && (best.1 - second.1).norm() > 1e-9
    {
        return None;
    }
    let inside = rho >= OPENING
        && x.z <= 0.0
        && !(rho < OPENING + FILLET && x.z > -FILLET && q.norm() > FILLET);
    let distance = if inside { -1.0 } else { 1.0 } * (p - best.0).norm();
    let (y, n2, kappa_meridian) = best;
    let normal = e_rho * n2.x + Vector3::z() * n2.y;
    let tangent = e_phi.cross(&normal);
    let kappa_hoop = n2.x / y.x;
    Some(principal_answer(
        distance,
        normal,
        &[(tangent, kappa_meridian), (e_phi, kappa_hoop)],
    ))
}

/// Requirement: every analytic shape's `d`, `∇d`, `∇²d` equal the closed
/// forms from the closest point and principal curvatures (module doc) at
/// random points on both sides (tools §3).
#[test]
fn analytic_shapes_match_closed_forms() {
    let mut rng = StdRng::seed_from_u64(7);
    let size = 100.0;
    let mut worst = Worst::default();
    let mut inside_count = [0usize; 5];
    let mut outside_count = [0usize; 5];
    let mut tally = |k: usize, d: f64| {
        if d < 0.0 {
            inside_count[k] += 1;
        } else {
            outside_count[k] += 1;
        }
    };
    for _ in 0..400 {
        // Plane: y = (x, y, 0), no curvature.
        let x = random_point(&mut rng, Vector3::new(50.0, 50.0, 30.0));
        let expected = principal_answer(x.z, Vector3::z(), &[]);
        worst.record(
            "plane",
            &check_closed_form(&Plane::new(), &x, &expected, size, "plane"),
        );
        tally(0, x.z);

        for side in sides() {
            let s = side_sign(side);
            // Sphere: y = R x/|x|, κ = ±1/R in every tangent direction.
            let sphere = Sphere::new(SPHERE_RADIUS, side).unwrap();
            let x = random_point(&mut rng, Vector3::new(60.0, 60.0, 60.0));
            if x.norm() >= ELL {
                let radial = x.normalize();
                let y = radial * SPHERE_RADIUS;
                let distance = s * (x - y).norm() * (x.norm() - SPHERE_RADIUS).signum();
                let t1 = radial.cross(&Vector3::new(0.3, -0.5, 0.8)).normalize();
                let t2 = radial.cross(&t1);
                let k = s / SPHERE_RADIUS;
                let expected = principal_answer(distance, radial * s, &[(t1, k), (t2, k)]);
                worst.record(
                    "sphere",
                    &check_closed_form(&sphere, &x, &expected, size, "sphere"),
                );
                tally(1, distance);
            }

            // Cylinder: y = R e_ρ + z e_z; κ = ±1/R along e_φ, 0 along z.
            let cylinder = Cylinder::new(CYLINDER_RADIUS, side).unwrap();
            let x = random_point(&mut rng, Vector3::new(60.0, 60.0, 60.0));
            let (rho, e_rho, e_phi) = cylindrical(&x);
            if rho >= ELL {
                let y = e_rho * CYLINDER_RADIUS + Vector3::z() * x.z;
                let distance = s * (x - y).norm() * (rho - CYLINDER_RADIUS).signum();
                let expected = principal_answer(
                    distance,
                    e_rho * s,
                    &[(e_phi, s / CYLINDER_RADIUS), (Vector3::z(), 0.0)],
                );
                worst.record(
                    "cylinder",
                    &check_closed_form(&cylinder, &x, &expected, size, "cylinder"),
                );
                tally(2, distance);
            }

            // Torus: y = c + r (x − c)/|x − c| with c = R e_ρ the core
            // point; κ = ±1/r along the meridian, n_ρ/ρ_y along e_φ.
            let torus = Torus::new(TORUS_MAJOR, TORUS_MINOR, side).unwrap();
            let x = random_point(&mut rng, Vector3::new(70.0, 70.0, 30.0));
            let (rho, e_rho, e_phi) = cylindrical(&x);
            let core = e_rho * TORUS_MAJOR;
            if rho >= ELL && (x - core).norm() >= ELL {
                let out = (x - core).normalize();
                let y = core + out * TORUS_MINOR;
                let distance = s * ((x - core).norm() - TORUS_MINOR);
                let normal = out * s;
                let meridian = e_phi.cross(&normal);
                let hoop = normal.dot(&e_rho) / y.dot(&e_rho);
                let expected = principal_answer(
                    distance,
                    normal,
                    &[(meridian, s / TORUS_MINOR), (e_phi, hoop)],
                );
                worst.record(
                    "torus",
                    &check_closed_form(&torus, &x, &expected, size, "torus"),
                );
                tally(3, distance);
            }
        }

        // Plate with hole: nearest feature (see plate_reference).
        let plate = PlateWithHole::new(OPENING, FILLET).unwrap();
        let x =
            random_point(&mut rng, Vector3::new(90.0, 90.0, 40.0)) + Vector3::new(0.0, 0.0, -5.0);
        let (rho, _, _) = cylindrical(&x);
        let centre_distance = Vector2::new(rho - OPENING - FILLET, x.z + FILLET).norm();
        if rho >= ELL
            && centre_distance >= ELL
            && let Some(expected) = plate_reference(&x)
        {
            worst.record(
                "plate with hole",
                &check_closed_form(&plate, &x, &expected, size, "plate with hole"),
            );
            tally(4, expected.distance);
        }
    }
    worst.print("closed form [d, n, H]");
    // Both sides were sampled, many times, for every shape.
    for k in 0..5 {
        assert!(
            inside_count[k] > 50 && outside_count[k] > 50,
            "shape {k}: {inside_count:?} {outside_count:?}"
        );
    }
}

/// Requirement: the plate's face-zone shortcut (a point at `ρ² ≥ (R_o +
/// r_f)²`, grown by a relative 10⁻⁹, is answered without `ρ`) answers
/// the face exactly where the face holds and leaves the fillet to the full
/// query: at in-plane distances from the fillet's outer edge of −1 mm to
/// +30 mm (down to 10⁻⁷ mm on either side), at 12 azimuths and heights
/// 0–3 mm over the face's plane (the free side, where contact is),
/// against the closed form of the nearest feature ([`plate_reference`],
/// to `64 ε` of the size, where it decides); on the face side
/// the distance is `z` to the last bit and the normal `e_z`, on the fillet
/// side the fillet's `|(u, z + r_f)| − r_f` and (from 10⁻⁶ mm into it) a
/// tilted normal; `closest`, `closest_normal` and `clearance` agree to the
/// bit.
#[test]
fn plate_face_shortcut_answers_the_face_only_on_it() {
    let plate = PlateWithHole::new(OPENING, FILLET).unwrap();
    let size = 100.0;
    let mut checked = [0usize; 3];
    for k in 0..12 {
        let phi = TAU * k as f64 / 12.0 + 0.1;
        for offset in [-1.0, -1e-3, -1e-7, 1e-7, 1e-3, 1.0, 30.0] {
            for z in [0.0, 0.15, 1.0, 3.0] {
                let rho = OPENING + FILLET + offset;
                let x = Vector3::new(rho * phi.cos(), rho * phi.sin(), z);
                let answer = plate.closest_normal(&x, f64::INFINITY).unwrap();
                let full = plate.closest(&x, f64::INFINITY).unwrap();
                assert_eq!(answer.distance.to_bits(), full.distance.to_bits());
                assert_eq!(answer.normal, full.normal);
                assert_eq!(plate.clearance(&x).to_bits(), answer.distance.to_bits());
                // Within 10⁻³ mm of the face–fillet junction the reference
                // declines (two features with different normals at once).
                if let Some(expected) = plate_reference(&x) {
                    check_closed_form(&plate, &x, &expected, size, "plate face shortcut");
                    checked[2] += 1;
                }
                let in_plane = Vector2::new(x.x, x.y).norm() - OPENING - FILLET;
                if in_plane > 64.0 * EPS * size {
                    assert_eq!(answer.distance.to_bits(), z.to_bits(), "face at {x:?}");
                    assert_eq!(answer.normal, Vector3::z(), "face normal at {x:?}");
                    assert_eq!(max_abs(&full.hessian), 0.0);
                    checked[0] += 1;
                } else {
                    let fillet = Vector2::new(in_plane, z + FILLET).norm() - FILLET;
                    assert!(
                        (answer.distance - fillet).abs() <= 64.0 * EPS * size,
                        "fillet at {x:?}: {} against {fillet}",
                        answer.distance
                    );
                    assert!(answer.normal.x != 0.0 || answer.normal.y != 0.0 || offset > -1e-6);
                    checked[1] += 1;
                }
            }
        }
    }
    assert!(
        checked[0] >= 12 * 4 * 4 && checked[1] >= 12 * 3 * 4 && checked[2] >= 12 * 5 * 4,
        "{checked:?}"
    );
}

/// The four zones of the plate with hole in the meridian plane, each
/// sampled at least `MARGIN` from its borders and `ELL` from the fillet
/// centre and the axis: `(name, ρ, z)`.
fn plate_zone_samples(rng: &mut StdRng, count: usize) -> Vec<(&'static str, f64, f64)> {
    let (ro, rf) = (OPENING, FILLET);
    let mut samples = Vec::new();
    while samples.len() < count {
        let zone = samples.len() % 4;
        let (name, rho, z) = match zone {
            0 => (
                "face",
                rng.random_range(ro + rf + MARGIN..ro + rf + 40.0),
                rng.random_range(-rf + MARGIN..20.0),
            ),
            1 => (
                "fillet",
                rng.random_range(ELL..ro + rf - MARGIN),
                rng.random_range(-rf + MARGIN..20.0),
            ),
            2 => (
                "wall",
                rng.random_range(ELL..ro + rf - MARGIN),
                rng.random_range(-30.0..-rf - MARGIN),
            ),
            _ => (
                "deep",
                rng.random_range(ro + rf + MARGIN..ro + rf + 40.0),
                rng.random_range(-40.0..-rf - MARGIN),
            ),
        };
        let centre_distance = Vector2::new(rho - ro - rf, z + rf).norm();
        let medial = (z - (ro - rho)).abs();
        if centre_distance >= ELL && (zone != 3 || medial >= MARGIN) {
            samples.push((name, rho, z));
        }
    }
    samples
}

/// Requirement: `∇d` is the gradient of `d` and `∇²d` the gradient of
/// `∇d` (central differences, module doc) at random points on both sides
/// of every shape, in all four zones of the plate with hole.
#[test]
fn analytic_shapes_pass_finite_differences() {
    let mut rng = StdRng::seed_from_u64(11);
    let size = 100.0;
    let mut worst = Worst::default();
    for _ in 0..100 {
        let x = random_point(&mut rng, Vector3::new(50.0, 50.0, 30.0));
        worst.record(
            "plane",
            &check_finite_differences(&Plane::new(), &x, size, "plane"),
        );
        for side in sides() {
            let sphere = Sphere::new(SPHERE_RADIUS, side).unwrap();
            let x = random_point(&mut rng, Vector3::new(60.0, 60.0, 60.0));
            if x.norm() >= ELL + STEP {
                worst.record(
                    "sphere",
                    &check_finite_differences(&sphere, &x, size, "sphere"),
                );
            }
            let cylinder = Cylinder::new(CYLINDER_RADIUS, side).unwrap();
            let x = random_point(&mut rng, Vector3::new(60.0, 60.0, 60.0));
            if x.x.hypot(x.y) >= ELL + STEP {
                worst.record(
                    "cylinder",
                    &check_finite_differences(&cylinder, &x, size, "cylinder"),
                );
            }
            let torus = Torus::new(TORUS_MAJOR, TORUS_MINOR, side).unwrap();
            let x = random_point(&mut rng, Vector3::new(70.0, 70.0, 30.0));
            let (rho, e_rho, _) = cylindrical(&x);
            if rho >= ELL + STEP && (x - e_rho * TORUS_MAJOR).norm() >= ELL + STEP {
                worst.record(
                    "torus",
                    &check_finite_differences(&torus, &x, size, "torus"),
                );
            }
        }
    }
    let plate = PlateWithHole::new(OPENING, FILLET).unwrap();
    for (zone, rho, z) in plate_zone_samples(&mut rng, 400) {
        let x = at_meridian(rho, z, rng.random_range(0.0..TAU));
        worst.record(zone, &check_finite_differences(&plate, &x, size, zone));
    }
    worst.print("finite differences [∇d, ∇²d]");
}

/// A rotation about a skew axis and a translation, used for the placed
/// checks.
fn skew_placement() -> Placement {
    Placement::new(
        Vector3::new(30.0, -20.0, 15.0),
        Vector3::new(1.0, 2.0, 3.0),
        Some(Vector3::new(0.0, 0.0, 1.0)),
    )
    .unwrap()
}

/// Requirement (tools §1): a placement is orthonormal and right-handed,
/// `to_world` inverts `to_local`, and the placed query in world
/// coordinates is the local one transformed (`d` unchanged, `n_w = R n`,
/// `H_w = R H Rᵀ`) and passes the finite-difference checks for every shape
/// and plate zone. Round-off: `64 ε X`.
#[test]
fn placed_shapes_answer_in_world_coordinates() {
    let placement = skew_placement();
    let r = placement.rotation();
    let size = 200.0;
    assert!(max_abs(&(r.transpose() * r - Matrix3::identity())) <= 8.0 * EPS);
    assert!((r.determinant() - 1.0).abs() <= 8.0 * EPS);
    assert!(max_abs(&(placement.axis() - Vector3::new(1.0, 2.0, 3.0).normalize())) <= 4.0 * EPS);
    // The reference (world z) projected: local x has no component along y ⟂.
    let mut rng = StdRng::seed_from_u64(13);
    let mut worst = Worst::default();
    for _ in 0..20 {
        let p = random_point(&mut rng, Vector3::new(50.0, 50.0, 50.0));
        assert!(max_abs(&(placement.to_local(&placement.to_world(&p)) - p)) <= 64.0 * EPS * size);
        let v = placement.vector_to_world(&p);
        assert!(max_abs(&(placement.vector_to_local(&v) - p)) <= 64.0 * EPS * size);
    }
    let shapes: Vec<(&str, Box<dyn RigidSurface>)> = vec![
        ("plane", Box::new(Plane::new())),
        (
            "sphere",
            Box::new(Sphere::new(SPHERE_RADIUS, Side::Outside).unwrap()),
        ),
        (
            "cylinder",
            Box::new(Cylinder::new(CYLINDER_RADIUS, Side::Inside).unwrap()),
        ),
        (
            "torus",
            Box::new(Torus::new(TORUS_MAJOR, TORUS_MINOR, Side::Outside).unwrap()),
        ),
    ];
    for (name, shape) in &shapes {
        let placed = Placed::new(shape.as_ref(), placement);
        for _ in 0..50 {
            let local = random_point(&mut rng, Vector3::new(60.0, 60.0, 30.0));
            let rho = local.x.hypot(local.y);
            let core = (local - Vector3::new(local.x, local.y, 0.0) * (TORUS_MAJOR / rho)).norm();
            if local.norm() < ELL + STEP || rho < ELL + STEP || core < ELL + STEP {
                continue;
            }
            let x = placement.to_world(&local);
            let (w, l) = (answer(&placed, &x), answer(shape.as_ref(), &local));
            assert!(
                (w.distance - l.distance).abs() <= 64.0 * EPS * size,
                "{name}: d"
            );
            assert!(
                max_abs(&(w.normal - r * l.normal)) <= 64.0 * EPS * size,
                "{name}: n"
            );
            assert!(
                max_abs(&(w.hessian - r * l.hessian * r.transpose())) <= 64.0 * EPS * size,
                "{name}: H"
            );
            worst.record(name, &check_finite_differences(&placed, &x, size, name));
        }
    }
    let plate = Placed::new(PlateWithHole::new(OPENING, FILLET).unwrap(), placement);
    for (zone, rho, z) in plate_zone_samples(&mut rng, 200) {
        let x = placement.to_world(&at_meridian(rho, z, rng.random_range(0.0..TAU)));
        worst.record(zone, &check_finite_differences(&plate, &x, size, zone));
    }
    worst.print("placed, finite differences [∇d, ∇²d]");
}

/// Requirement (tools §3.5): a blankholder is the plate turned upside down
/// by its placement (local z = world −z): the ply below its face has
/// `d = (face height) − z > 0` and the normal `−e_z`, the plate above it
/// is the solid, and the opening is free.
#[test]
fn blankholder_is_the_plate_turned_over() {
    let height = 12.0;
    let placement = Placement::new(Vector3::new(0.0, 0.0, height), -Vector3::z(), None).unwrap();
    let blankholder = Placed::new(PlateWithHole::new(OPENING, FILLET).unwrap(), placement);
    let tolerance = 64.0 * EPS * 100.0;
    for (x, expected) in [
        (Vector3::new(70.0, 5.0, height - 2.0), 2.0),
        (Vector3::new(-3.0, 80.0, height + 4.0), -4.0),
    ] {
        let a = answer(&blankholder, &x);
        assert!(
            (a.distance - expected).abs() <= tolerance,
            "d = {} at {x:?}",
            a.distance
        );
        assert!(max_abs(&(a.normal + Vector3::z())) <= tolerance);
    }
    // Inside the opening, above the face level: free, at R_o − ρ from the wall.
    let a = answer(&blankholder, &Vector3::new(10.0, 0.0, height + 30.0));
    assert!((a.distance - (OPENING - 10.0)).abs() <= tolerance);
}

/// Requirement (tools §3.5): the plate's `d` and `∇d` are continuous across
/// the face/fillet junction `ρ = R_o + r_f` and the fillet/wall junction
/// `z = −r_f`, while `∇²d` jumps there by the fillet's meridian curvature
/// `1/r_f` (so the two sides were really different zones). Across `2δ`,
/// `d` may change by `2δ |∇d|` and `∇d` by `2δ |∇²d| ≤ 2δ (1/ℓ + 1/ρ)`,
/// plus round-off `64 ε X/ℓ`.
#[test]
fn plate_with_hole_is_c1_at_its_junctions() {
    let plate = PlateWithHole::new(OPENING, FILLET).unwrap();
    let mut rng = StdRng::seed_from_u64(17);
    let delta = 1e-7;
    let size = 100.0;
    let mut worst = Worst::default();
    for k in 0..200 {
        let phi = rng.random_range(0.0..TAU);
        let (minus, plus) = if k % 2 == 0 {
            // Face/fillet: across ρ = R_o + r_f, z ∈ (−r_f + ℓ, 20).
            let z = rng.random_range(-FILLET + ELL..20.0);
            let rho = OPENING + FILLET;
            (
                at_meridian(rho - delta, z, phi),
                at_meridian(rho + delta, z, phi),
            )
        } else {
            // Fillet/wall: across z = −r_f, ρ ∈ (ℓ, R_o + r_f − ℓ).
            let rho = rng.random_range(ELL..OPENING + FILLET - ELL);
            (
                at_meridian(rho, -FILLET + delta, phi),
                at_meridian(rho, -FILLET - delta, phi),
            )
        };
        let (a, b) = (answer(&plate, &minus), answer(&plate, &plus));
        let roundoff = 64.0 * EPS * size / ELL;
        let d_tolerance = 2.0 * delta + roundoff;
        let n_tolerance = 2.0 * delta * (1.0 / ELL + 1.0 / ELL) + roundoff;
        let h_tolerance = 2.0 * delta * 30.0 / (ELL * ELL) + roundoff / ELL;
        let expected_jump = 1.0 / (FILLET + a.distance);
        worst.record(
            if k % 2 == 0 {
                "face/fillet"
            } else {
                "fillet/wall"
            },
            &[
                (a.distance - b.distance).abs() / d_tolerance,
                max_abs(&(a.normal - b.normal)) / n_tolerance,
                ((a.hessian - b.hessian).norm() - expected_jump).abs() / h_tolerance,
            ],
        );
        assert!(
            (a.distance - b.distance).abs() <= 2.0 * delta + roundoff,
            "d jumps at {minus:?}"
        );
        let jump = max_abs(&(a.normal - b.normal));
        assert!(
            jump <= 2.0 * delta * (1.0 / ELL + 1.0 / ELL) + roundoff,
            "∇d jumps by {jump:e} at {minus:?}"
        );
        // The meridian curvature of the fillet switches on across the
        // junction: its parallel-surface value κ/(1 + κ d) = 1/(r_f + d),
        // the hoop term being continuous (d_ρ is). The two Hessians are
        // 2δ apart, changing by ≤ 2δ · 30/ℓ² (module doc) besides the jump.
        let h_jump = (a.hessian - b.hessian).norm();
        let expected = 1.0 / (FILLET + a.distance);
        assert!(
            (h_jump - expected).abs() <= 2.0 * delta * 30.0 / (ELL * ELL) + roundoff / ELL,
            "Hessian jump {h_jump:e} at {minus:?}, expected {expected:e}"
        );
    }
    worst.print("junction [Δd, Δ∇d, Δ∇²d − 1/(r_f + d)]");
}

/// A culling case: the shape, a surface point, its free-side normal and
/// the depth available inside before a singular set (local coordinates).
type CullCase<'a> = (
    &'a str,
    &'a dyn RigidSurface,
    Vector3<f64>,
    Vector3<f64>,
    f64,
);

/// Requirement (RigidSurface contract): `None` on the free side beyond
/// `max_distance`, an answer within it, and always an answer inside the
/// tool, however deep, for every shape (placed, for the world-frame cull).
#[test]
fn far_points_are_culled_and_inside_points_answered() {
    let max = 2.0;
    let placement = skew_placement();
    let plate = PlateWithHole::new(OPENING, FILLET).unwrap();
    let sphere_out = Sphere::new(SPHERE_RADIUS, Side::Outside).unwrap();
    let sphere_in = Sphere::new(SPHERE_RADIUS, Side::Inside).unwrap();
    let cylinder = Cylinder::new(CYLINDER_RADIUS, Side::Outside).unwrap();
    let torus = Torus::new(TORUS_MAJOR, TORUS_MINOR, Side::Inside).unwrap();
    // (shape, a surface point, its free-side normal, the depth available
    // inside before a singular set) in local coordinates.
    let r = SPHERE_RADIUS;
    let cases: Vec<CullCase> = vec![
        (
            "plane",
            &Plane,
            Vector3::new(3.0, 4.0, 0.0),
            Vector3::z(),
            1e3,
        ),
        (
            "sphere outside",
            &sphere_out,
            Vector3::new(0.0, 0.0, r),
            Vector3::z(),
            0.9 * r,
        ),
        (
            "sphere inside",
            &sphere_in,
            Vector3::new(0.0, 0.0, r),
            -Vector3::z(),
            1e3,
        ),
        (
            "cylinder",
            &cylinder,
            Vector3::new(r, 0.0, 7.0),
            Vector3::x(),
            0.9 * r,
        ),
        (
            "torus inside",
            &torus,
            Vector3::new(TORUS_MAJOR + TORUS_MINOR, 0.0, 0.0),
            -Vector3::x(),
            100.0,
        ),
        (
            "plate face",
            &plate,
            Vector3::new(0.0, 70.0, 0.0),
            Vector3::z(),
            1e3,
        ),
        (
            "plate wall",
            &plate,
            Vector3::new(OPENING, 0.0, -30.0),
            -Vector3::x(),
            1e3,
        ),
    ];
    for (name, shape, y, n, depth) in cases {
        let placed = Placed::new(shape, placement);
        let world = |p: Vector3<f64>| placement.to_world(&p);
        assert!(
            placed.closest(&world(y + n * (1.5 * max)), max).is_none(),
            "{name}: not culled"
        );
        assert!(
            placed.closest(&world(y + n * (0.5 * max)), max).is_some(),
            "{name}: culled within"
        );
        let deep = placed.closest(&world(y - n * (0.5 * depth)), max);
        assert!(
            deep.is_some_and(|a| a.distance < -max),
            "{name}: deep inside not answered"
        );
    }
    // Inside the opening, far from the wall: free side, culled.
    assert!(plate.closest(&Vector3::new(5.0, 0.0, -50.0), max).is_none());
    // The singular sets answer None and a non-finite point too.
    assert!(
        sphere_out
            .closest(&Vector3::zeros(), f64::INFINITY)
            .is_none()
    );
    assert!(
        plate
            .closest(&Vector3::new(0.0, 0.0, 3.0), f64::INFINITY)
            .is_none()
    );
    assert!(
        Plane
            .closest(&Vector3::new(f64::NAN, 0.0, 0.0), f64::INFINITY)
            .is_none()
    );
}

/// Requirement: constructors reject bad parameters with an error naming
/// the parameter and its value.
#[test]
fn constructors_reject_bad_parameters() {
    let message = |e: ShapeError| e.to_string();
    let e = message(Sphere::new(-1.0, Side::Outside).unwrap_err());
    assert!(e.contains("radius") && e.contains("-1"), "{e}");
    let e = message(Cylinder::new(f64::NAN, Side::Outside).unwrap_err());
    assert!(e.contains("radius = nan"), "{e}");
    let e = message(Torus::new(10.0, 12.0, Side::Outside).unwrap_err());
    assert!(
        e.contains("minor_radius") && e.contains("12") && e.contains("major radius 10"),
        "{e}"
    );
    let e = message(PlateWithHole::new(0.0, 5.0).unwrap_err());
    assert!(e.contains("opening_radius") && e.contains('0'), "{e}");
    let e = message(PlateWithHole::new(40.0, -2.0).unwrap_err());
    assert!(e.contains("fillet_radius") && e.contains("-2"), "{e}");
    let e = message(Placement::new(Vector3::zeros(), Vector3::zeros(), None).unwrap_err());
    assert!(e.contains("axis"), "{e}");
    let e = message(
        Placement::new(Vector3::zeros(), Vector3::z(), Some(Vector3::z() * 2.0)).unwrap_err(),
    );
    assert!(e.contains("reference") && e.contains("parallel"), "{e}");
    let e = message(Placement::translation(Vector3::new(0.0, f64::INFINITY, 0.0)).unwrap_err());
    assert!(e.contains("origin"), "{e}");
    let plate = PlateWithHole::new(40.0, 8.0).unwrap();
    let e = message(plate.tessellate(45.0, 10.0, 32).unwrap_err());
    assert!(e.contains("outer_radius") && e.contains("48"), "{e}");
    let e = message(
        Sphere::new(1.0, Side::Outside)
            .unwrap()
            .tessellate(PI, 2)
            .unwrap_err(),
    );
    assert!(e.contains("segments"), "{e}");
}

/// Checks a tessellation of `surface`: every vertex on the surface (`|d|`
/// within round-off `64 ε X`), every triangle's normal towards the free
/// side at its centroid, and the closure (through the mesh tool's check)
/// when `closed` (turned outward first for a shape with the ply inside,
/// which a closed mesh tool does not model).
fn check_tessellation(surface: &dyn RigidSurface, mesh: &Tessellation, closed: bool, label: &str) {
    check_tessellation_side(surface, mesh, closed, false, label)
}

fn check_tessellation_side(
    surface: &dyn RigidSurface,
    mesh: &Tessellation,
    closed: bool,
    ply_inside: bool,
    label: &str,
) {
    let size = 100.0;
    assert!(!mesh.triangles.is_empty(), "{label}: empty");
    for v in &mesh.vertices {
        if let Some(a) = surface.closest(v, f64::INFINITY) {
            assert!(
                a.distance.abs() <= 64.0 * EPS * size,
                "{label}: vertex {v:?} at d = {:e}",
                a.distance
            );
        }
    }
    for t in &mesh.triangles {
        let [a, b, c] = t.map(|i| mesh.vertices[i]);
        let normal = (b - a).cross(&(c - a));
        let centroid = (a + b + c) / 3.0;
        let q = answer(surface, &centroid);
        assert!(
            normal.dot(&q.normal) > 0.0,
            "{label}: triangle {t:?} faces the tool"
        );
    }
    let tool = MeshSurface::from_triangles(
        label,
        &mesh.vertices,
        &mesh.triangles,
        &MeshOptions {
            require_closed: closed,
            flip_normals: ply_inside,
            ..MeshOptions::default()
        },
    );
    let tool = tool.unwrap_or_else(|e| panic!("{label}: {e}"));
    assert_eq!(tool.is_closed(), closed, "{label}: closure");
}

/// Requirement (tools §5): each shape's tessellation lies on it, faces the
/// ply, and is closed when the shape is drawn whole (sphere, torus).
#[test]
fn tessellations_lie_on_their_shapes() {
    let segments = 24;
    let m = Plane.tessellate(30.0, 4).unwrap();
    assert_eq!(m.triangles.len(), 32);
    check_tessellation(&Plane, &m, false, "plane");
    for side in sides() {
        let inside = side == Side::Inside;
        let sphere = Sphere::new(SPHERE_RADIUS, side).unwrap();
        let m = sphere.tessellate(PI, segments).unwrap();
        check_tessellation_side(&sphere, &m, true, inside, "sphere");
        let m = sphere.tessellate(FRAC_PI_2, segments).unwrap();
        check_tessellation_side(&sphere, &m, false, inside, "hemisphere");
        let cylinder = Cylinder::new(CYLINDER_RADIUS, side).unwrap();
        let m = cylinder.tessellate(-20.0, 35.0, segments).unwrap();
        check_tessellation_side(&cylinder, &m, false, inside, "cylinder");
        let torus = Torus::new(TORUS_MAJOR, TORUS_MINOR, side).unwrap();
        let m = torus.tessellate(segments).unwrap();
        check_tessellation_side(&torus, &m, true, inside, "torus");
    }
    let plate = PlateWithHole::new(OPENING, FILLET).unwrap();
    check_tessellation(
        &plate,
        &plate.tessellate(90.0, 20.0, segments).unwrap(),
        false,
        "plate",
    );
    let sharp = PlateWithHole::new(OPENING, 0.0).unwrap();
    let m = sharp.tessellate(90.0, 0.0, segments).unwrap();
    check_tessellation(&sharp, &m, false, "sharp plate");
    // A placed tessellation is the placed shape's.
    let placement = skew_placement();
    let placed = Placed::new(plate, placement);
    let m = plate
        .tessellate(90.0, 20.0, segments)
        .unwrap()
        .to_world(&placement);
    check_tessellation(&placed, &m, false, "placed plate");
}

// ----------------------------------------------------------------------
// Mesh tools.

/// The cube `[−a, a]³`, 12 outward triangles.
fn cube(a: f64) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let vertices = (0..8)
        .map(|i| {
            Vector3::new(
                if i & 1 == 0 { -a } else { a },
                if i & 2 == 0 { -a } else { a },
                if i & 4 == 0 { -a } else { a },
            )
        })
        .collect();
    // Quads (counter-clockwise from outside) split along a diagonal.
    let quads = [
        [0, 2, 3, 1], // z = −a
        [4, 5, 7, 6], // z = +a
        [0, 1, 5, 4], // y = −a
        [2, 6, 7, 3], // y = +a
        [0, 4, 6, 2], // x = −a
        [1, 3, 7, 5], // x = +a
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    (vertices, triangles)
}

/// The icosahedron subdivided `levels` times, vertices on the sphere of
/// `radius`, triangles outward.
fn icosphere(radius: f64, levels: usize) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut vertices: Vec<Vector3<f64>> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Vector3::new(x, y, z).normalize() * radius)
    .collect();
    let mut triangles: Vec<[usize; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: usize, b: usize, vertices: &mut Vec<Vector3<f64>>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                vertices.push(((vertices[a] + vertices[b]) / 2.0).normalize() * radius);
                vertices.len() - 1
            })
        };
        let mut finer = Vec::new();
        for [a, b, c] in triangles {
            let ab = midpoint(a, b, &mut vertices);
            let bc = midpoint(b, c, &mut vertices);
            let ca = midpoint(c, a, &mut vertices);
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    // Orient outward (the list above is, but do not rely on it).
    for tri in &mut triangles {
        let [a, b, c] = tri.map(|i| vertices[i]);
        if (b - a).cross(&(c - a)).dot(&(a + b + c)) < 0.0 {
            tri.swap(1, 2);
        }
    }
    (vertices, triangles)
}

fn write_binary_stl(path: &Path, vertices: &[Vector3<f64>], triangles: &[[usize; 3]]) {
    let facets: Vec<stl_io::Triangle> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|i| vertices[i]);
            let n = (b - a).cross(&(c - a)).normalize();
            let v = |p: Vector3<f64>| stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32]);
            stl_io::Triangle {
                normal: stl_io::Normal::new([n.x as f32, n.y as f32, n.z as f32]),
                vertices: [v(a), v(b), v(c)],
            }
        })
        .collect();
    let mut file = std::fs::File::create(path).unwrap();
    stl_io::write_stl(&mut file, facets.iter()).unwrap();
}

fn write_ascii_stl(path: &Path, vertices: &[Vector3<f64>], triangles: &[[usize; 3]]) {
    let mut text = String::from("solid test\n");
    for t in triangles {
        let [a, b, c] = t.map(|i| vertices[i]);
        let n = (b - a).cross(&(c - a)).normalize();
        text += &format!("  facet normal {} {} {}\n    outer loop\n", n.x, n.y, n.z);
        for p in [a, b, c] {
            // As f32, like a real ASCII STL (and like the binary one).
            text += &format!(
                "      vertex {} {} {}\n",
                p.x as f32, p.y as f32, p.z as f32
            );
        }
        text += "    endloop\n  endfacet\n";
    }
    text += "endsolid test\n";
    std::fs::write(path, text).unwrap();
}

fn write_obj(path: &Path, vertices: &[Vector3<f64>], triangles: &[[usize; 3]]) {
    let mut text = String::from("# test mesh\no tool\n");
    for v in vertices {
        text += &format!("v {} {} {}\n", v.x, v.y, v.z);
    }
    for t in triangles {
        text += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    std::fs::write(path, text).unwrap();
}

/// Exact signed distance to the box `[−a, a]³` with its gradient and
/// Hessian (outside: distance to the nearest face, edge or corner; inside:
/// to the nearest face), or `None` on an inside tie.
fn box_distance(x: &Vector3<f64>, a: f64) -> Option<SurfacePoint> {
    let q = x.map(|c| c.abs() - a);
    let outside = q.map(|c| c.max(0.0));
    let count = outside.iter().filter(|&&c| c > 0.0).count();
    if count > 0 {
        let d = outside.norm();
        let n = outside.component_mul(&x.map(f64::signum)) / d;
        let hessian = match count {
            1 => Matrix3::zeros(),
            2 => {
                let axis = (0..3).find(|&i| outside[i] == 0.0).unwrap();
                let t = Vector3::ith(axis, 1.0);
                (Matrix3::identity() - t * t.transpose() - n * n.transpose()) / d
            }
            _ => (Matrix3::identity() - n * n.transpose()) / d,
        };
        return Some(SurfacePoint {
            distance: d,
            normal: n,
            hessian,
        });
    }
    let mut order = [0, 1, 2];
    order.sort_by(|&i, &j| q[j].total_cmp(&q[i]));
    if q[order[0]] - q[order[1]] < 1e-6 {
        return None;
    }
    let i = order[0];
    Some(SurfacePoint {
        distance: q[i],
        normal: Vector3::ith(i, x[i].signum()),
        hessian: Matrix3::zeros(),
    })
}

fn read(path: &Path, options: &MeshOptions) -> MeshSurface {
    MeshSurface::from_file(path, options).unwrap_or_else(|e| panic!("{e}"))
}

fn temp_path(dir: &tempfile::TempDir, name: &str) -> PathBuf {
    dir.path().join(name)
}

/// Requirement (tools §4): a cube written as binary STL, ASCII STL and OBJ
/// reads back closed, and its signed distance, normal and Hessian (faces,
/// edges, corners; outside and inside) are the box's exact ones. The
/// vertices `±10` are exact in f32 and f64, so only round-off `64 ε X`
/// separates them; the normal and Hessian near an edge or corner at
/// distance `r` carry `64 ε X/r` and `64 ε X/r²` (`r ≥ 0.1` sampled).
#[test]
fn cube_files_give_the_exact_box_distance() {
    let dir = tempfile::tempdir().unwrap();
    let a = 10.0;
    let (vertices, triangles) = cube(a);
    let paths = [
        temp_path(&dir, "cube_binary.stl"),
        temp_path(&dir, "cube_ascii.STL"),
        temp_path(&dir, "cube.obj"),
    ];
    write_binary_stl(&paths[0], &vertices, &triangles);
    write_ascii_stl(&paths[1], &vertices, &triangles);
    write_obj(&paths[2], &vertices, &triangles);
    let size = 30.0;
    let mut rng = StdRng::seed_from_u64(19);
    for path in &paths {
        let tool = read(
            path,
            &MeshOptions {
                require_closed: true,
                ..MeshOptions::default()
            },
        );
        assert!(tool.is_closed());
        assert_eq!(tool.tessellation().triangles.len(), 12);
        assert_eq!(tool.tessellation().vertices.len(), 8);
        // Culling (RigidSurface contract): beyond max_distance outside,
        // None; within, an answer; deep inside (10 mm ≫ 1 mm), an answer.
        assert!(tool.closest(&Vector3::new(1.0, 2.0, 11.5), 1.0).is_none());
        assert!(tool.closest(&Vector3::new(30.0, 30.0, 30.0), 1.0).is_none());
        assert!(tool.closest(&Vector3::new(1.0, 2.0, 10.5), 1.0).is_some());
        let deep = tool.closest(&Vector3::new(0.5, -0.25, 0.0), 1.0);
        assert!(
            deep.is_some_and(|p| (p.distance + 9.5).abs() <= 64.0 * EPS * 30.0),
            "{deep:?}"
        );
        let mut checked = [0usize; 4];
        let mut worst = Worst::default();
        while checked.iter().sum::<usize>() < 600 {
            let x = random_point(&mut rng, Vector3::new(2.0 * a, 2.0 * a, 2.0 * a));
            let Some(expected) = box_distance(&x, a) else {
                continue;
            };
            let beyond = x.iter().filter(|c| c.abs() > a).count();
            // Distance to the nearest edge or corner, for the round-off.
            let r = expected.distance.abs();
            if beyond >= 2 && r < 0.1 {
                continue;
            }
            let got = answer(&tool, &x);
            let tol = 64.0 * EPS * size;
            assert!(
                (got.distance - expected.distance).abs() <= tol,
                "{path:?}: d at {x:?}: {} vs {}",
                got.distance,
                expected.distance
            );
            assert!(
                max_abs(&(got.normal - expected.normal)) <= tol / r.min(1.0),
                "{path:?}: n at {x:?}"
            );
            assert!(
                max_abs(&(got.hessian - expected.hessian)) <= tol / r.min(1.0).powi(2),
                "{path:?}: H at {x:?}\n{}\n{}",
                got.hessian,
                expected.hessian
            );
            let zone = if expected.distance < 0.0 { 0 } else { beyond };
            checked[zone] += 1;
            worst.record(
                ["inside", "face", "edge", "corner"][zone],
                &[
                    (got.distance - expected.distance).abs() / tol,
                    max_abs(&(got.normal - expected.normal)) / (tol / r.min(1.0)),
                    max_abs(&(got.hessian - expected.hessian)) / (tol / r.min(1.0).powi(2)),
                ],
            );
        }
        worst.print(&format!("{:?} [d, n, H]", path.file_name().unwrap()));
        // Inside, on faces, at edges and at corners all sampled.
        assert!(checked.iter().all(|&c| c > 20), "{checked:?}");
    }
}

/// Requirement (tools §4): an icosphere of radius `R` (vertices on the
/// sphere) read from binary STL and OBJ has, everywhere, the sphere's
/// signed distance to within the faceting error: the mesh lies between
/// the sphere and the radius `R − s`, `s = R − min_T (n_T · a_T)` (each
/// facet's plane distance from the centre), so both distance functions
/// differ by at most `s`, plus the f32 rounding of STL vertices
/// (`√3 · ½ ulp(R)`) and round-off. Outside that band the signs agree.
#[test]
fn icosphere_files_approximate_the_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let radius = 20.0;
    let (vertices, triangles) = icosphere(radius, 3);
    assert_eq!(triangles.len(), 1280);
    let sagitta = radius
        - triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| vertices[i]);
                (b - a).cross(&(c - a)).normalize().dot(&a)
            })
            .fold(f64::INFINITY, f64::min);
    // ~0.09 mm at this refinement (small against R, as the band must be).
    assert!(sagitta > 0.0 && sagitta < 0.1, "sagitta {sagitta}");
    let f32_rounding = 3f64.sqrt() * 0.5 * (radius as f32).next_up_ulp();
    let stl = temp_path(&dir, "sphere.stl");
    let obj = temp_path(&dir, "sphere.obj");
    write_binary_stl(&stl, &vertices, &triangles);
    write_obj(&obj, &vertices, &triangles);
    let sphere = Sphere::new(radius, Side::Outside).unwrap();
    let mut rng = StdRng::seed_from_u64(23);
    for (path, rounding) in [(&stl, f32_rounding), (&obj, 0.0)] {
        let tool = read(
            path,
            &MeshOptions {
                require_closed: true,
                ..MeshOptions::default()
            },
        );
        let tolerance = sagitta + rounding + 64.0 * EPS * 50.0;
        let mut worst = 0.0f64;
        for _ in 0..2000 {
            let x = random_point(&mut rng, Vector3::new(40.0, 40.0, 40.0));
            if x.norm() < ELL {
                continue;
            }
            let (got, exact) = (answer(&tool, &x).distance, answer(&sphere, &x).distance);
            worst = worst.max((got - exact).abs());
            assert!(
                (got - exact).abs() <= tolerance,
                "{path:?} at {x:?}: {got} vs {exact}"
            );
            if exact.abs() > tolerance {
                assert_eq!(got.signum(), exact.signum(), "{path:?}: sign at {x:?}");
            }
        }
        eprintln!("{path:?}: worst |d_mesh − d_sphere| = {worst:e}, bound {tolerance:e}");
    }
}

/// `f32`'s distance to the next float up from a value, as f64.
trait Ulp {
    fn next_up_ulp(self) -> f64;
}

impl Ulp for f32 {
    fn next_up_ulp(self) -> f64 {
        f64::from(f32::from_bits(self.to_bits() + 1) - self)
    }
}

/// Requirement (tools §4): `require_closed` rejects a cube with a missing
/// triangle (open edge), a flipped triangle (inconsistent edge) and an
/// extra triangle on an edge (non-manifold), naming the file and an edge
/// of the defect; an inside-out cube is rejected unless `flip_normals`.
#[test]
fn open_and_bad_meshes_are_rejected_when_closure_is_required() {
    let dir = tempfile::tempdir().unwrap();
    let (vertices, triangles) = cube(10.0);
    let closed = MeshOptions {
        require_closed: true,
        ..MeshOptions::default()
    };
    let corner = |i: usize| {
        let v = vertices[i];
        [v.x, v.y, v.z]
    };

    let mut missing = triangles.clone();
    let removed = missing.remove(5);
    let path = temp_path(&dir, "open.stl");
    write_binary_stl(&path, &vertices, &missing);
    match MeshSurface::from_file(&path, &closed) {
        Err(
            e @ MeshToolError::NotClosed {
                defect: EdgeDefect::Open,
                a,
                b,
                ..
            },
        ) => {
            assert!(e.to_string().contains("open.stl"), "{e}");
            let ends: Vec<[f64; 3]> = removed.iter().map(|&i| corner(i)).collect();
            assert!(
                ends.contains(&a) && ends.contains(&b),
                "{e}: not an edge of the hole"
            );
        }
        other => panic!("open cube: {other:?}"),
    }
    // Without the requirement the open cube is accepted, as open.
    assert!(!read(&path, &MeshOptions::default()).is_closed());

    let mut flipped = triangles.clone();
    flipped[3].swap(1, 2);
    let path = temp_path(&dir, "flipped.obj");
    write_obj(&path, &vertices, &flipped);
    match MeshSurface::from_file(&path, &closed) {
        Err(
            e @ MeshToolError::NotClosed {
                defect: EdgeDefect::Inconsistent,
                ..
            },
        ) => {
            assert!(e.to_string().contains("flipped.obj"), "{e}")
        }
        other => panic!("flipped triangle: {other:?}"),
    }

    let mut extra = triangles.clone();
    let mut verts = vertices.clone();
    verts.push(Vector3::new(0.0, 0.0, 30.0));
    extra.push([4, 5, 8]);
    let path = temp_path(&dir, "fin.stl");
    write_ascii_stl(&path, &verts, &extra);
    match MeshSurface::from_file(&path, &closed) {
        Err(MeshToolError::NotClosed {
            defect: EdgeDefect::NonManifold { triangles: 3 },
            ..
        }) => {}
        other => panic!("fin: {other:?}"),
    }

    let inverted: Vec<[usize; 3]> = triangles.iter().map(|t| [t[0], t[2], t[1]]).collect();
    let path = temp_path(&dir, "inverted.stl");
    write_binary_stl(&path, &vertices, &inverted);
    match MeshSurface::from_file(&path, &MeshOptions::default()) {
        Err(e @ MeshToolError::InsideOut { .. }) => assert!(e.to_string().contains("inverted.stl")),
        other => panic!("inverted: {other:?}"),
    }
    let fixed = read(
        &path,
        &MeshOptions {
            flip_normals: true,
            ..closed
        },
    );
    let a = answer(&fixed, &Vector3::new(0.0, 0.0, 12.0));
    assert!((a.distance - 2.0).abs() <= 64.0 * EPS * 30.0);
}

/// Requirement (tools §4): an open mesh is one-sided: `d` has the sign of
/// the side of the closest feature's oriented normal, exact for the square
/// `[−5, 5]² × {0}` (normal `+z`): `d = z` above and below it, the
/// distance to its border (with the line-distance Hessian) beyond it;
/// behind it beyond `max_distance`, `None`. `scale` converts metres to mm.
#[test]
fn open_square_is_one_sided() {
    let dir = tempfile::tempdir().unwrap();
    let half = 0.005; // metres
    let vertices = vec![
        Vector3::new(-half, -half, 0.0),
        Vector3::new(half, -half, 0.0),
        Vector3::new(half, half, 0.0),
        Vector3::new(-half, half, 0.0),
    ];
    let triangles = vec![[0, 1, 2], [0, 2, 3]];
    let path = temp_path(&dir, "square.obj");
    write_obj(&path, &vertices, &triangles);
    let tool = read(
        &path,
        &MeshOptions {
            scale: 1000.0,
            ..MeshOptions::default()
        },
    );
    assert!(!tool.is_closed());
    let tol = 64.0 * EPS * 20.0;
    for (x, d) in [
        (Vector3::new(1.0, 2.0, 3.0), 3.0),
        (Vector3::new(-4.0, 1.0, -2.5), -2.5),
    ] {
        let a = tool.closest(&x, 10.0).unwrap();
        assert!((a.distance - d).abs() <= tol, "{x:?}: {}", a.distance);
        assert!(max_abs(&(a.normal - Vector3::z())) <= tol);
        assert!(max_abs(&a.hessian) == 0.0);
    }
    assert!(tool.closest(&Vector3::new(1.0, 2.0, -3.0), 1.0).is_none());
    assert!(tool.closest(&Vector3::new(1.0, 2.0, 3.0), 1.0).is_none());
    // Beyond the border x = 5 mm, above the sheet: distance to the line.
    let x = Vector3::new(8.0, 1.0, 4.0);
    let a = tool.closest(&x, 10.0).unwrap();
    let n = Vector3::new(3.0, 0.0, 4.0) / 5.0;
    let t = Vector3::y();
    assert!((a.distance - 5.0).abs() <= tol);
    assert!(max_abs(&(a.normal - n)) <= tol);
    let h = (Matrix3::identity() - t * t.transpose() - n * n.transpose()) / 5.0;
    assert!(max_abs(&(a.hessian - h)) <= tol);
    // The mesh tool's FD check on that edge zone (ℓ = 5 mm ≥ ELL).
    let fractions = check_finite_differences(&tool, &x, 20.0, "square edge");
    eprintln!("finite differences [∇d, ∇²d] square edge: {fractions:.3?}");
    // Beyond the border, behind the sheet: d = −5, ∇d = −(x − p)/r, and
    // the line-distance Hessian divided by the signed d.
    let x = Vector3::new(8.0, 1.0, -4.0);
    let a = tool.closest(&x, 10.0).unwrap();
    let n = -Vector3::new(3.0, 0.0, -4.0) / 5.0;
    assert!(
        (a.distance + 5.0).abs() <= tol,
        "behind the border: {}",
        a.distance
    );
    assert!(max_abs(&(a.normal - n)) <= tol);
    let h = (Matrix3::identity() - t * t.transpose() - n * n.transpose()) / -5.0;
    assert!(max_abs(&(a.hessian - h)) <= tol);
    let fractions = check_finite_differences(&tool, &x, 20.0, "square edge, behind");
    eprintln!("finite differences [∇d, ∇²d] square edge behind: {fractions:.3?}");
}

fn expect_error(path: &Path, check: impl Fn(&MeshToolError) -> bool) {
    match MeshSurface::from_file(path, &MeshOptions::default()) {
        Err(e) => {
            let name = path.file_name().unwrap().to_string_lossy().to_string();
            assert!(e.to_string().contains(&name), "{e} does not name {name}");
            assert!(check(&e), "unexpected error for {name}: {e}");
            eprintln!("{e}");
        }
        Ok(tool) => panic!("{path:?} was accepted: {tool:?}"),
    }
}

/// Requirement (tools §4): unreadable or bad files give an error naming
/// the file (and the facet or line): missing, empty, garbage, truncated,
/// NaN coordinates, malformed text, degenerate triangles, wrong extension,
/// bad scale.
#[test]
fn bad_files_are_reported() {
    let dir = tempfile::tempdir().unwrap();
    expect_error(&temp_path(&dir, "missing.stl"), |e| {
        matches!(e, MeshToolError::Io { .. })
    });
    for name in ["empty.stl", "empty.obj"] {
        let path = temp_path(&dir, name);
        std::fs::write(&path, b"").unwrap();
        expect_error(&path, |e| matches!(e, MeshToolError::Empty { .. }));
    }
    // A binary STL with no facets.
    let path = temp_path(&dir, "nofacets.stl");
    write_binary_stl(&path, &[], &[]);
    expect_error(&path, |e| matches!(e, MeshToolError::Empty { .. }));
    // Random bytes.
    let mut rng = StdRng::seed_from_u64(29);
    let garbage: Vec<u8> = (0..1000).map(|_| rng.random_range(0..=255u8)).collect();
    for name in ["garbage.stl", "garbage.obj"] {
        let path = temp_path(&dir, name);
        let mut bytes = garbage.clone();
        bytes[0] = b'#';
        bytes[1] = 0xff; // not UTF-8 either
        std::fs::write(&path, &bytes).unwrap();
        expect_error(&path, |e| matches!(e, MeshToolError::Format { .. }));
    }
    // A truncated binary STL.
    let (vertices, triangles) = cube(10.0);
    let path = temp_path(&dir, "truncated.stl");
    write_binary_stl(&path, &vertices, &triangles);
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 30]).unwrap();
    expect_error(
        &path,
        |e| matches!(e, MeshToolError::Format { location, .. } if location == "header"),
    );
    // NaN in a binary STL: facet 4.
    let mut nan_vertices = vertices.clone();
    nan_vertices.push(Vector3::new(f64::NAN, 0.0, 0.0));
    let mut nan_triangles = triangles.clone();
    nan_triangles[3] = [0, 1, 8];
    let path = temp_path(&dir, "nan.stl");
    write_binary_stl(&path, &nan_vertices, &nan_triangles);
    expect_error(
        &path,
        |e| matches!(e, MeshToolError::NonFinite { location, .. } if location == "facet 4"),
    );
    // NaN in an ASCII STL: the reader rejects it, in facet 4.
    let path = temp_path(&dir, "nan_ascii.stl");
    write_ascii_stl(&path, &nan_vertices, &nan_triangles);
    expect_error(
        &path,
        |e| matches!(e, MeshToolError::Format { location, .. } if location == "facet 4"),
    );
    // Malformed ASCII STL: facet 2 lacks `outer loop`.
    let path = temp_path(&dir, "malformed.stl");
    write_ascii_stl(&path, &vertices, &triangles[..2]);
    let text = std::fs::read_to_string(&path).unwrap();
    let second = text.match_indices("outer loop").nth(1).unwrap().0;
    let broken = format!("{}outer lop{}", &text[..second], &text[second + 10..]);
    std::fs::write(&path, broken).unwrap();
    expect_error(
        &path,
        |e| matches!(e, MeshToolError::Format { location, .. } if location == "facet 2"),
    );
    // NaN in an OBJ: the `v` line (line 2 + 9th vertex = line 11).
    let path = temp_path(&dir, "nan.obj");
    write_obj(&path, &nan_vertices, &nan_triangles);
    expect_error(
        &path,
        |e| matches!(e, MeshToolError::NonFinite { location, .. } if location == "line 11"),
    );
    // Malformed OBJ position on line 5.
    let path = temp_path(&dir, "malformed.obj");
    write_obj(&path, &vertices, &triangles);
    let mut lines: Vec<String> = std::fs::read_to_string(&path)
        .unwrap()
        .lines()
        .map(String::from)
        .collect();
    lines[4] = "v 1.0 abc 2.0".into();
    std::fs::write(&path, lines.join("\n")).unwrap();
    expect_error(
        &path,
        |e| matches!(e, MeshToolError::Format { location, .. } if location == "line 5"),
    );
    // A degenerate (collinear) triangle, number 2.
    let path = temp_path(&dir, "degenerate.obj");
    let mut file = std::fs::File::create(&path).unwrap();
    writeln!(file, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 2 4").unwrap();
    drop(file);
    expect_error(&path, |e| {
        matches!(e, MeshToolError::Degenerate { triangle: 2, .. })
    });
    // Wrong extension, bad scale.
    let path = temp_path(&dir, "tool.step");
    std::fs::write(&path, b"ISO-10303-21;").unwrap();
    expect_error(&path, |e| matches!(e, MeshToolError::UnknownFormat { .. }));
    let path = temp_path(&dir, "cube.obj");
    write_obj(&path, &vertices, &triangles);
    let e = MeshSurface::from_file(
        &path,
        &MeshOptions {
            scale: 0.0,
            ..MeshOptions::default()
        },
    )
    .unwrap_err();
    assert!(
        matches!(
            e,
            MeshToolError::Option {
                option: "scale",
                ..
            }
        ),
        "{e}"
    );
}

/// Requirement: a query with a finite `max_distance` answers exactly when
/// the unbounded query finds the point within it — the cheap rejections
/// (the plate's "above the face" test, the cull distance of every shape)
/// never drop a point that is close enough, nor keep one that is not.
/// Points from the four zones of the plate and from above and below it,
/// bounds from −1 to 10 mm.
#[test]
fn bounded_queries_agree_with_unbounded_ones() {
    let mut rng = StdRng::seed_from_u64(41);
    let plate = PlateWithHole::new(OPENING, FILLET).unwrap();
    let sphere = Sphere::new(40.0, Side::Outside).unwrap();
    let cylinder = Cylinder::new(30.0, Side::Outside).unwrap();
    let torus = Torus::new(TORUS_MAJOR, TORUS_MINOR, Side::Outside).unwrap();
    let shapes: [(&str, &dyn RigidSurface); 4] = [
        ("plate with hole", &plate),
        ("sphere", &sphere),
        ("cylinder", &cylinder),
        ("torus", &torus),
    ];
    let mut checked = 0;
    for _ in 0..4000 {
        let x = random_point(&mut rng, Vector3::new(120.0, 120.0, 30.0));
        let bound = rng.random_range(-1.0..10.0);
        for (name, shape) in shapes {
            let Some(full) = shape.closest(&x, f64::INFINITY) else {
                continue;
            };
            let bounded = shape.closest(&x, bound);
            assert_eq!(
                bounded.is_some(),
                full.distance <= bound,
                "{name} at {x:?}: distance {} mm, bound {bound} mm",
                full.distance
            );
            if let Some(point) = bounded {
                assert_eq!(point, full, "{name} at {x:?}");
            }
            checked += 1;
        }
    }
    assert!(checked > 10_000, "only {checked} queries compared");
}

/// The batch query answers what the point query answers, bit for bit, for
/// every analytic shape, placed and behind a `Box<dyn RigidSurface>` (the
/// way the explicit contact loop holds its tool), culled points included.
#[test]
fn batch_queries_repeat_point_queries() {
    let mut rng = StdRng::seed_from_u64(43);
    let placement = skew_placement();
    let shapes: Vec<(&str, Box<dyn RigidSurface>)> = vec![
        (
            "plate with hole",
            Box::new(Placed::new(
                PlateWithHole::new(OPENING, FILLET).unwrap(),
                placement,
            )),
        ),
        (
            "sphere",
            Box::new(Placed::new(
                Sphere::new(40.0, Side::Outside).unwrap(),
                skew_placement(),
            )),
        ),
        (
            "cylinder",
            Box::new(Cylinder::new(30.0, Side::Outside).unwrap()),
        ),
        (
            "torus",
            Box::new(Torus::new(TORUS_MAJOR, TORUS_MINOR, Side::Outside).unwrap()),
        ),
    ];
    let points: Vec<Vector3<f64>> = (0..500)
        .map(|_| random_point(&mut rng, Vector3::new(120.0, 120.0, 30.0)))
        .collect();
    let bounds: Vec<f64> = (0..points.len())
        .map(|_| rng.random_range(-1.0..10.0))
        .collect();
    for (name, shape) in &shapes {
        let mut batch = vec![None; points.len()];
        shape.closest_normals(&points, &bounds, &mut batch);
        let mut answered = 0;
        for ((x, bound), answer) in points.iter().zip(&bounds).zip(&batch) {
            assert_eq!(*answer, shape.closest_normal(x, *bound), "{name} at {x:?}");
            answered += usize::from(answer.is_some());
        }
        // Both kinds of answer are compared: some points within the bound,
        // some culled.
        assert!(
            answered > 0 && answered < points.len(),
            "{name}: {answered} of {} answered",
            points.len()
        );
    }
}
