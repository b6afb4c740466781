//! Tests of the polygonal tools of the tetrahedron bench
//! (`src/contact/pyramid.rs`, `docs/contact.md`, "Polygonal tools"): the
//! rounded pyramid punch and the plate with a polygonal opening — their
//! signed distance against an independent brute-force distance, `∇d` and
//! `∇²d` against finite differences near faces, edges, apex, fillet and the
//! opening's corners, the unit normal, the 1-Lipschitz distance, the cull,
//! the pyramid's symmetries, the opening that follows the punch, and the
//! tessellations.
//!
//! **Finite differences** as in `tests/tools.rs`: central differences with
//! step `h = 1e-4` mm have the truncation error `h²/6 · f'''` and the
//! round-off `δ/h`; the shapes are distances to points, lines and planes
//! whose derivatives we bound by `6/ℓ²` and `30/ℓ³` at the least distance
//! `ℓ ≥ 1 mm` from a centre of curvature (a core edge or vertex, a fillet
//! centre line), with `δ = 16 ε X` for coordinates of size `X`: the bounds
//! of [`gradient_tolerance`] and [`hessian_tolerance`] (~2e-8 and ~6e-8 at
//! `X = 300`). A stencil straddling a junction of two zones (where `∇²d`
//! jumps) would fail; random points fall within `h` of one with probability
//! about `1e-5` per point, and the medial planes inside the cores (where
//! `∇d` jumps) are not sampled.

use std::f64::consts::{PI, TAU};

use nalgebra::{Matrix3, Vector2, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use ncform::contact::{
    Placement, PlateWithPolygonHole, Pyramid, RigidSurface, SurfacePoint, punch_opening,
};

const EPS: f64 = f64::EPSILON;
/// Finite-difference step [mm] (module doc).
const STEP: f64 = 1e-4;
/// Least distance of a sampled point to a centre of curvature [mm].
const ELL: f64 = 1.0;
/// Coordinate size of the sampled points [mm].
const SIZE: f64 = 300.0;

/// The bench's punch: a regular tetrahedron (cos α = 1/3), r = 10 mm, core
/// height 130 mm, a base edge along x.
fn punch() -> Pyramid {
    Pyramid::new(3, (1.0_f64 / 3.0).acos(), 10.0, 130.0, 0.0).unwrap()
}

/// `h²/6 · 6/ℓ² + 16 ε X/h`.
fn gradient_tolerance() -> f64 {
    STEP * STEP / 6.0 * 6.0 / (ELL * ELL) + 16.0 * EPS * SIZE / STEP
}

/// `h²/6 · 30/ℓ³ + 16 ε X/(ℓ h)`.
fn hessian_tolerance() -> f64 {
    STEP * STEP / 6.0 * 30.0 / ELL.powi(3) + 16.0 * EPS * SIZE / (ELL * STEP)
}

fn answer(surface: &dyn RigidSurface, x: &Vector3<f64>) -> SurfacePoint {
    surface
        .closest(x, f64::INFINITY)
        .unwrap_or_else(|| panic!("no answer at {x:?}"))
}

fn max_abs(m: &Matrix3<f64>) -> f64 {
    m.iter().fold(0.0, |acc, v| acc.max(v.abs()))
}

/// Checks `∇d`, `∇²d` against central differences and the invariants
/// (unit normal, symmetric Hessian with the normal in its null space, to
/// `64 ε X/ℓ`); `closest_normal` bit-identical to `closest`.
fn check(surface: &dyn RigidSurface, x: &Vector3<f64>, label: &str) {
    let a = answer(surface, x);
    let g = Vector3::from_fn(|i, _| {
        let e = Vector3::ith(i, STEP);
        (answer(surface, &(x + e)).distance - answer(surface, &(x - e)).distance) / (2.0 * STEP)
    });
    let mut h = Matrix3::zeros();
    for i in 0..3 {
        let e = Vector3::ith(i, STEP);
        h.set_column(
            i,
            &((answer(surface, &(x + e)).normal - answer(surface, &(x - e)).normal) / (2.0 * STEP)),
        );
    }
    let eg = (g - a.normal).amax();
    let eh = max_abs(&(h - a.hessian));
    assert!(eg <= gradient_tolerance(), "{label}: ∇d at {x:?}: {eg:e}");
    assert!(eh <= hessian_tolerance(), "{label}: ∇²d at {x:?}: {eh:e}");
    let roundoff = 64.0 * EPS * SIZE / ELL;
    assert!((a.normal.norm() - 1.0).abs() <= roundoff, "{label}: |n|");
    assert!(max_abs(&(a.hessian - a.hessian.transpose())) <= roundoff);
    assert!((a.hessian * a.normal).amax() <= roundoff, "{label}: H n");
    let b = surface.closest_normal(x, f64::INFINITY).unwrap();
    assert_eq!(b.distance.to_bits(), a.distance.to_bits(), "{label}");
    assert_eq!(b.normal, a.normal, "{label}");
}

fn unit(rng: &mut StdRng) -> Vector3<f64> {
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

/// The sharp core's apex, base vertices and faces (triangles), in the
/// pyramid's local frame, built independently of the code from its
/// definition: apex (0, 0, r), base n-gon at z = r + h of inradius h cot α,
/// the faces' outward normals at the azimuths ψ − 90° + 360° k/n.
fn core_triangles(p: &Pyramid) -> Vec<[Vector3<f64>; 3]> {
    let (r, h, a, n) = (p.rounding_radius(), p.height(), p.face_angle(), p.sides());
    let apex = Vector3::new(0.0, 0.0, r);
    let circum = h / a.tan() / (PI / n as f64).cos();
    let vertex = |k: usize| {
        let phi = p.edge_azimuth() - 0.5 * PI + TAU * k as f64 / n as f64 + PI / n as f64;
        Vector3::new(circum * phi.cos(), circum * phi.sin(), r + h)
    };
    let centre = Vector3::new(0.0, 0.0, r + h);
    let mut t = Vec::new();
    for k in 0..n {
        t.push([apex, vertex(k), vertex(k + 1)]);
        t.push([centre, vertex(k + 1), vertex(k)]);
    }
    t
}

/// The distance from `p` to the triangle `t` (Ericson's closest point).
fn triangle_distance(p: &Vector3<f64>, t: &[Vector3<f64>; 3]) -> f64 {
    let (a, b, c) = (t[0], t[1], t[2]);
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (p - a).norm();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (p - b).norm();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).norm();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (p - c).norm();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).norm();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).norm();
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (p - (a + ab * v + ac * w)).norm()
}

/// Points near the features of the pyramid: offsets of 1 to 25 mm (so at
/// least `ℓ = 1 mm` from the core) from random points of its faces, lateral
/// edges, apex, base edges and base vertices.
fn pyramid_samples(
    rng: &mut StdRng,
    p: &Pyramid,
    count: usize,
) -> Vec<(&'static str, Vector3<f64>)> {
    let triangles = core_triangles(p);
    let n = p.sides();
    let mut out = Vec::new();
    while out.len() < count {
        let kind = out.len() % 5;
        let k = rng.random_range(0..n);
        let [apex, v0, v1] = triangles[2 * k];
        let (label, base) = match kind {
            0 => {
                let (s, t) = (rng.random_range(0.0..1.0), rng.random_range(0.0..1.0));
                let (s, t) = if s + t > 1.0 {
                    (1.0 - s, 1.0 - t)
                } else {
                    (s, t)
                };
                ("face", apex + (v0 - apex) * s + (v1 - apex) * t)
            }
            1 => (
                "lateral edge",
                apex + (v0 - apex) * rng.random_range(0.0..1.0),
            ),
            2 => ("apex", apex),
            3 => ("base edge", v0 + (v1 - v0) * rng.random_range(0.0..1.0)),
            _ => ("base vertex", v0),
        };
        let x = base + unit(rng) * rng.random_range(ELL + 1e-3..25.0);
        // Outside the core by at least ℓ (the brute force is for outside
        // points; inside the core the distance is flat).
        let core = triangles
            .iter()
            .map(|t| triangle_distance(&x, t))
            .fold(f64::INFINITY, f64::min);
        if core >= ELL && p.clearance(&x) > -p.rounding_radius() {
            out.push((label, x));
        }
    }
    out
}

/// Requirement: the pyramid's signed distance is `dist(x, K) − r` exactly
/// (against the brute-force distance to the core's triangles, to
/// `64 ε X`), and `∇d`, `∇²d` pass finite differences near every feature;
/// the normal is unit; `closest_normal` is bit-identical.
#[test]
fn pyramid_distance_normal_hessian_are_exact() {
    let mut rng = StdRng::seed_from_u64(3);
    for p in [
        punch(),
        Pyramid::new(4, 50_f64.to_radians(), 6.0, 80.0, 0.3).unwrap(),
    ] {
        let triangles = core_triangles(&p);
        for (label, x) in pyramid_samples(&mut rng, &p, 500) {
            let brute = triangles
                .iter()
                .map(|t| triangle_distance(&x, t))
                .fold(f64::INFINITY, f64::min)
                - p.rounding_radius();
            let d = answer(&p, &x).distance;
            assert!(
                (d - brute).abs() <= 64.0 * EPS * SIZE,
                "{label} at {x:?}: {d} vs {brute}"
            );
            check(&p, &x, label);
        }
        // Inside the core: the nearest face plane minus r, flat.
        let inside = Vector3::new(0.0, 0.0, p.rounding_radius() + 0.5 * p.height());
        let a = answer(&p, &inside);
        assert!(a.distance < -p.rounding_radius());
        assert_eq!(a.hessian, Matrix3::zeros());
    }
}

/// Requirement: the pyramid is symmetric under its mirror planes (for
/// ψ = 0 and n = 3: x = 0, and the planes at ±120° to it) and its
/// rotations by 120°: the distance equal and the normal and Hessian
/// mapped, to round-off `64 ε X`.
#[test]
fn pyramid_is_symmetric() {
    let p = punch();
    let mut rng = StdRng::seed_from_u64(5);
    let mirror_x = Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, 1.0));
    let turn = |a: f64| Matrix3::new(a.cos(), -a.sin(), 0.0, a.sin(), a.cos(), 0.0, 0.0, 0.0, 1.0);
    let maps = [
        mirror_x,
        turn(TAU / 3.0) * mirror_x * turn(-TAU / 3.0),
        turn(TAU / 3.0),
        turn(-TAU / 3.0),
    ];
    let tolerance = 64.0 * EPS * SIZE;
    for (_, x) in pyramid_samples(&mut rng, &p, 200) {
        let a = answer(&p, &x);
        for m in &maps {
            let b = answer(&p, &(m * x));
            assert!((a.distance - b.distance).abs() <= tolerance, "{x:?}");
            assert!((m * a.normal - b.normal).amax() <= tolerance, "{x:?}");
            assert!(max_abs(&(m * a.hessian * m.transpose() - b.hessian)) <= tolerance);
        }
    }
}

/// The die of the bench: the opening that follows the punch at 95 mm
/// depth, 3 mm clearance, 5 mm fillet (`cases/tetrahedron-0.toml`).
fn die() -> (PlateWithPolygonHole, Vec<Vector2<f64>>, f64) {
    let p = punch();
    let start = Placement::new(Vector3::new(0.0, 0.0, 0.3), Vector3::z(), None).unwrap();
    let plate = Placement::new(Vector3::zeros(), Vector3::z(), None).unwrap();
    let (polygon, corner) = punch_opening(
        &p,
        &start,
        &Vector3::new(0.0, 0.0, -95.0),
        &plate,
        &Vector3::zeros(),
        3.0,
    )
    .unwrap();
    (
        PlateWithPolygonHole::new(&polygon, corner, 5.0).unwrap(),
        polygon,
        corner,
    )
}

/// Points near the plate's fillet, wall, face, the opening's corners and
/// deep in it, at least `ℓ = 1 mm` from the fillet's centre line, the
/// corners' axes and off the medial planes.
fn plate_samples(rng: &mut StdRng, count: usize) -> Vec<(&'static str, Vector3<f64>)> {
    let (plate, polygon, corner) = die();
    let rf = plate.fillet_radius();
    let m = polygon.len();
    let mut out = Vec::new();
    while out.len() < count {
        let i = rng.random_range(0..m);
        let (a, b) = (polygon[i], polygon[(i + 1) % m]);
        let t = (b - a).normalize();
        let nu = Vector2::new(t.y, -t.x);
        let corner_sample = out.len() % 2 == 0;
        // The in-plane distance w from Q and the direction.
        let (label, base, dir) = if corner_sample {
            let n0 = {
                let c = polygon[(i + m - 1) % m];
                let t0 = (a - c).normalize();
                Vector2::new(t0.y, -t0.x)
            };
            let a0 = n0.y.atan2(n0.x);
            let a1 = nu.y.atan2(nu.x);
            let mut span = a1 - a0;
            if span < 0.0 {
                span += TAU;
            }
            let phi = a0 + span * rng.random_range(0.0..1.0);
            ("opening corner", a, Vector2::new(phi.cos(), phi.sin()))
        } else {
            ("opening side", a + (b - a) * rng.random_range(0.0..1.0), nu)
        };
        let w = rng.random_range(0.0..corner + rf + 20.0);
        let z = rng.random_range(-25.0..15.0);
        let q = base + dir * w;
        let x = Vector3::new(q.x, q.y, z);
        // Away from the fillet's centre line, the corner's axis (w = 0 at
        // a corner) and the deep zone's medial plane.
        let u = w - corner - rf;
        let centre = Vector2::new(u, z + rf).norm();
        let medial = (z - (-u - rf)).abs();
        let label = if u < 0.0 && z > -rf {
            if corner_sample {
                "fillet at a corner"
            } else {
                "fillet"
            }
        } else {
            label
        };
        if centre >= ELL && (!corner_sample || w >= ELL) && !(u >= 0.0 && z <= -rf && medial < 1e-3)
        {
            out.push((label, x));
        }
    }
    out
}

/// Requirement: the plate's `∇d`, `∇²d` pass finite differences at the
/// fillet, wall, face and the opening's corners; its distance at points
/// where it is known in closed form (above the face, on the fillet's
/// bisector, at the opening's centre).
#[test]
fn plate_distance_normal_hessian_are_exact() {
    let (plate, polygon, corner) = die();
    let mut rng = StdRng::seed_from_u64(7);
    for (label, x) in plate_samples(&mut rng, 800) {
        check(&plate, &x, label);
    }
    // Closed forms: above the face far from the opening, d = z.
    let far = Vector3::new(0.0, 150.0, 2.5);
    assert!((answer(&plate, &far).distance - 2.5).abs() < 1e-12);
    // The opening's centre, below the fillet: the distance to the nearest
    // wall, the inradius of Q plus the corner radius.
    let inradius = (polygon[0] + polygon[1]).norm() / 2.0;
    let centre = Vector3::new(0.0, 0.0, -30.0);
    let d = answer(&plate, &centre).distance;
    assert!((d - (inradius + corner)).abs() < 1e-9, "{d}");
    // A point 45° above the fillet centre of a side, at 2 mm from it.
    let (a, b) = (polygon[0], polygon[1]);
    let t = (b - a).normalize();
    let nu = Vector2::new(t.y, -t.x);
    let mid = (a + b) / 2.0 + nu * (corner + 5.0);
    let offset = Vector2::new(-1.0, 1.0).normalize() * 2.0;
    let q = mid + nu * offset.x;
    let x = Vector3::new(q.x, q.y, -5.0 + offset.y);
    assert!((answer(&plate, &x).distance - (2.0 - 5.0)).abs() < 1e-12);
}

/// Requirement: both distances are 1-Lipschitz, `clearance` is the
/// distance (so a lower bound), and `closest(x, m)` is `None` exactly
/// when the point is farther than `m` on the free side.
#[test]
fn distances_are_lipschitz_and_culled_exactly() {
    let (plate, _, _) = die();
    let p = punch();
    let mut rng = StdRng::seed_from_u64(9);
    let surfaces: [(&str, &dyn RigidSurface, Vector3<f64>); 2] = [
        ("pyramid", &p, Vector3::new(0.0, 0.0, 60.0)),
        ("plate", &plate, Vector3::new(0.0, 0.0, -5.0)),
    ];
    for (label, s, centre) in surfaces {
        for _ in 0..4000 {
            let x = centre + unit(&mut rng) * rng.random_range(0.0..120.0);
            let y = x + unit(&mut rng) * rng.random_range(0.0..10.0);
            let (dx, dy) = (answer(s, &x).distance, answer(s, &y).distance);
            assert!(
                (dx - dy).abs() <= (x - y).norm() * (1.0 + 1e-12) + 1e-12,
                "{label}: {dx} {dy} at {x:?} {y:?}"
            );
            assert_eq!(s.clearance(&x).to_bits(), dx.to_bits(), "{label}");
            for m in [dx - 1e-9, dx + 1e-9, dx - 3.0, dx + 3.0, 0.0] {
                assert_eq!(s.closest(&x, m).is_none(), dx > m, "{label}: m {m} d {dx}");
                assert_eq!(s.closest_normal(&x, m).is_none(), dx > m, "{label}");
            }
        }
    }
}

/// Requirement: the opening follows the punch: its straight sides lie the
/// clearance (3 mm) outside the punch's section at the die plane at full
/// depth, and measured in the plane along the opening's inward normal the
/// gap to the punch stays between 3 mm and 3.2 mm all around: the
/// section's corners are arcs of the edges' ellipses, approximated by
/// circles through the ellipses' vertices that stay outside them
/// (`Pyramid::section`; measured 3.000 … 3.108 mm, printed with
/// `--nocapture`).
#[test]
fn opening_follows_the_punch_section_with_the_clearance() {
    let (plate, polygon, corner) = die();
    let p = punch();
    // The punch at full depth: its tip at z = 0.3 − 95.
    let tip = Vector3::new(0.0, 0.0, 0.3 - 95.0);
    let punch_d = |q: Vector2<f64>| answer(&p, &(Vector3::new(q.x, q.y, 0.0) - tip)).distance;
    let m = polygon.len();
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for i in 0..m {
        let (a, b) = (polygon[i], polygon[(i + 1) % m]);
        let t = (b - a).normalize();
        let nu = Vector2::new(t.y, -t.x);
        let c = polygon[(i + m - 1) % m];
        let t0 = (a - c).normalize();
        let n0 = Vector2::new(t0.y, -t0.x);
        let mut points = Vec::new();
        for j in 0..=50 {
            let phi = n0.y.atan2(n0.x) + {
                let mut span = nu.y.atan2(nu.x) - n0.y.atan2(n0.x);
                if span < 0.0 {
                    span += TAU;
                }
                span
            } * j as f64
                / 50.0;
            let dir = Vector2::new(phi.cos(), phi.sin());
            points.push((a + dir * corner, dir));
        }
        for j in 1..10 {
            points.push((a + (b - a) * (j as f64 / 10.0) + nu * corner, nu));
        }
        for (edge, dir) in points {
            // On the opening's edge the plate's wall is at d = 0 below the
            // fillet.
            let wall = answer(&plate, &Vector3::new(edge.x, edge.y, -20.0)).distance;
            assert!(wall.abs() < 1e-9);
            // Bisect the in-plane gap: the punch's d along −dir.
            let (mut g0, mut g1) = (0.0, 20.0);
            assert!(punch_d(edge) > 0.0 && punch_d(edge - dir * g1) < 0.0);
            for _ in 0..60 {
                let g = 0.5 * (g0 + g1);
                if punch_d(edge - dir * g) > 0.0 {
                    g0 = g;
                } else {
                    g1 = g;
                }
            }
            lo = lo.min(g0);
            hi = hi.max(g0);
        }
    }
    eprintln!("in-plane gap between the opening and the punch: {lo:.4} … {hi:.4} mm");
    assert!(lo > 3.0 - 1e-6 && hi < 3.2, "{lo} {hi}");
}

/// Requirement: the tessellations lie on their surfaces (|d| at every
/// vertex below 1e-9 mm) and every triangle that is not a sliver has its
/// normal on the free side (positive against the surface normal at its
/// centroid). The pyramid is drawn through its inverse Gauss map
/// (`Pyramid::tessellate`): a triangle of directions straddling a rounded
/// edge becomes a sliver along that edge (2 of 2,208 at 48 segments, width
/// under 1 % of their length), which may fold: of the slivers (twice the area below 1 % of the
/// longest side squared; the edges' strips are slivers too) at most 1 %
/// of all triangles may be folded.
#[test]
fn tessellations_lie_on_the_surfaces_facing_the_ply() {
    let (plate, _, _) = die();
    let p = punch();
    let drawings = [
        (
            "pyramid",
            &p as &dyn RigidSurface,
            p.tessellate(48).unwrap(),
        ),
        ("plate", &plate, plate.tessellate(100.0, 15.0, 48).unwrap()),
    ];
    for (label, s, mesh) in drawings {
        assert!(!mesh.triangles.is_empty());
        for v in &mesh.vertices {
            assert!(answer(s, v).distance.abs() < 1e-9, "{label}: {v:?}");
        }
        let mut checked = 0;
        let mut folded = 0;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.vertices[i]);
            let normal = (b - a).cross(&(c - a));
            let longest = (b - a).norm().max((c - b).norm()).max((a - c).norm());
            let centroid = (a + b + c) / 3.0;
            let n = answer(s, &centroid).normal;
            if normal.norm() < 1e-2 * longest * longest {
                if normal.dot(&n) <= 0.0 {
                    folded += 1;
                }
                continue;
            }
            assert!(normal.dot(&n) > 0.0, "{label}: triangle {t:?}");
            checked += 1;
        }
        assert!(
            folded * 100 <= mesh.triangles.len(),
            "{label}: {folded} folded"
        );
        assert!(checked > 0);
    }
}

/// The in-plane distance from `p` to the convex polygon `q` (zero inside),
/// by its edges as segments: independent of the plate's code.
fn polygon_distance_brute(q: &[Vector2<f64>], p: &Vector2<f64>) -> f64 {
    let m = q.len();
    let inside = (0..m).all(|i| {
        let (a, b) = (q[i], q[(i + 1) % m]);
        let e = b - a;
        e.x * (p.y - a.y) - e.y * (p.x - a.x) >= 0.0
    });
    if inside {
        return 0.0;
    }
    (0..m)
        .map(|i| {
            let (a, b) = (q[i], q[(i + 1) % m]);
            let e = b - a;
            let t = ((p - a).dot(&e) / e.norm_squared()).clamp(0.0, 1.0);
            (p - (a + e * t)).norm()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Requirement: the plate's face-zone shortcut (a point farther in-plane
/// than the opening's farthest vertex plus both radii is answered
/// without the polygon) gives the face's answer exactly where the face
/// holds and leaves every other point to the full query: on rays through
/// the opening's corners (where the shortcut's circle touches the grown
/// opening) and sides, at in-plane distances from the grown opening's
/// edge of −1 mm to +30 mm (down to 10⁻⁷ mm), for heights over the fillet
/// and the face. Where the independent in-plane distance `u` to the grown
/// opening is positive the distance is `z` to the last bit and the normal
/// `e_z`; where it is negative the fillet's distance `|(u, z + r_f)| −
/// r_f`, which exceeds `z` (to its round-off, `8 ε` of the coordinates).
/// `closest`, `closest_normal` and `clearance` agree to the bit.
#[test]
fn plate_face_shortcut_answers_the_face_only_on_it() {
    let (plate, polygon, corner) = die();
    let rf = plate.fillet_radius();
    let grown = corner + rf;
    let m = polygon.len();
    let mut checked = [0usize; 2];
    for i in 0..m {
        let (a, b) = (polygon[i], polygon[(i + 1) % m]);
        let t = (b - a).normalize();
        let side_normal = Vector2::new(t.y, -t.x);
        // Outwards from the corner along its position vector (the
        // direction in which the shortcut's circle meets the grown
        // opening) and from the side's midpoint along its normal.
        let radial = a.normalize();
        for (base, dir) in [(a, radial), ((a + b) / 2.0, side_normal)] {
            for offset in [-1.0, -1e-3, -1e-7, 1e-7, 1e-3, 1.0, 30.0] {
                for z in [-4.9, -1.0, 0.15, 3.0] {
                    let q = base + dir * (grown + offset);
                    let x = Vector3::new(q.x, q.y, z);
                    let u = polygon_distance_brute(&polygon, &q) - grown;
                    let answer = plate.closest_normal(&x, f64::INFINITY).unwrap();
                    let full = plate.closest(&x, f64::INFINITY).unwrap();
                    assert_eq!(answer.distance.to_bits(), full.distance.to_bits());
                    assert_eq!(answer.normal, full.normal);
                    assert_eq!(plate.clearance(&x).to_bits(), answer.distance.to_bits());
                    let roundoff = 8.0 * EPS * SIZE;
                    if u > roundoff {
                        assert_eq!(answer.distance.to_bits(), z.to_bits(), "face at {x:?}");
                        assert_eq!(answer.normal, Vector3::z(), "face normal at {x:?}");
                        assert_eq!(max_abs(&full.hessian), 0.0);
                        checked[0] += 1;
                    } else if u < -roundoff {
                        let fillet = Vector2::new(u, z + rf).norm() - rf;
                        assert!(
                            (answer.distance - fillet).abs() <= roundoff,
                            "fillet at {x:?}: {} against {fillet}",
                            answer.distance
                        );
                        assert!(answer.distance > z - roundoff);
                        checked[1] += 1;
                    }
                }
            }
        }
    }
    assert!(checked[0] > 40 && checked[1] > 40, "{checked:?}");
}
