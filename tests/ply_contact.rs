//! Ply–ply contact with Coulomb friction (docs/contact.md, "Ply–ply
//! contact") on problems with known answers: the closest-point and
//! candidate-list geometry against brute force, a ply pulled out between
//! two plies under a dead weight (`cases/verification/ply-pull-out.toml`),
//! a stack pressed flat by a floating plate, and the case-file rules. Each
//! test names the requirement it checks and derives its tolerance.

use std::fs;
use std::path::{Path, PathBuf};

use nalgebra::Vector3;
use ncform::case::forming::FormingCase;
use ncform::contact::ply_pair::{
    CandidateLists, closest_candidate, closest_on_triangle, triangle_boxes,
};
use ncform::model::{Masses, PlyContact, State, Term};
use ncform::report::Progress;
use ncform::report::files::run_forming;
use ncform::report::forming::FormingSummary;
use ncform::solver::RunStatus;
use tempfile::TempDir;

#[path = "../benches/common/ply_stack.rs"]
mod ply_stack;
use ply_stack::ply_stack;

fn verification_case(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases/verification")
        .join(name)
}

fn edit(text: &str, edits: &[(&str, &str)]) -> String {
    let mut text = text.to_string();
    for (from, to) in edits {
        assert!(text.contains(from), "`{from}` not in the case text");
        text = text.replace(from, to);
    }
    text
}

fn load(text: &str, dir: &Path) -> Result<FormingCase, String> {
    let path = dir.join("case.toml");
    fs::write(&path, text).unwrap();
    FormingCase::from_toml_str(text, &path.display().to_string(), &verification_case(""))
        .map_err(|e| e.to_string())
}

fn run(case: &FormingCase) -> FormingSummary {
    let out = TempDir::new().unwrap();
    let summary = run_forming(case, out.path(), Progress::Quiet).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(summary.status, RunStatus::Complete, "{}", case.title);
    summary
}

/// A small deterministic generator (xorshift), so the geometry checks are
/// reproducible without a dependency.
struct Random(u64);

impl Random {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }

    fn vector(&mut self, scale: f64) -> Vector3<f64> {
        Vector3::new(
            scale * (2.0 * self.next() - 1.0),
            scale * (2.0 * self.next() - 1.0),
            scale * (2.0 * self.next() - 1.0),
        )
    }
}

/// Requirement: the closest point of a triangle is the minimiser of the
/// distance over the triangle, its weights are barycentric, and it lies
/// inside the face exactly when all weights are positive.
///
/// Tolerance: a dense sampling of the triangle (every point of a 200-step
/// barycentric grid) can only find points at least as far as the true
/// minimiser, up to round-off (1e-12 mm on unit-size coordinates).
#[test]
fn closest_point_on_a_triangle_is_the_minimiser() {
    let mut random = Random(0x9e37_79b9_7f4a_7c15);
    for _ in 0..200 {
        let (a, b, c) = (random.vector(1.0), random.vector(1.0), random.vector(1.0));
        let p = random.vector(2.0);
        let found = closest_on_triangle(&p, &a, &b, &c);
        let w = found.weights;
        assert!(w.iter().all(|x| *x >= 0.0) && (w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let rebuilt = w[0] * a + w[1] * b + w[2] * c;
        assert!((rebuilt - found.point).norm() < 1e-12);
        assert_eq!(found.on_face, w.iter().all(|x| *x > 0.0));
        let d = (p - found.point).norm();
        let steps = 200;
        for i in 0..=steps {
            for j in 0..=steps - i {
                let (u, v) = (i as f64 / steps as f64, j as f64 / steps as f64);
                let q = a + u * (b - a) + v * (c - a);
                assert!((p - q).norm() >= d - 1e-12, "a sample is closer");
            }
        }
    }
}

/// A flat square mesh `n × n` cells of size `h`, split along one diagonal.
fn grid(n: usize, h: f64, z: f64) -> (Vec<Vector3<f64>>, Vec<[usize; 3]>) {
    let mut nodes = Vec::new();
    for j in 0..=n {
        for i in 0..=n {
            nodes.push(Vector3::new(i as f64 * h, j as f64 * h, z));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..n {
        for i in 0..n {
            let k = j * (n + 1) + i;
            triangles.push([k, k + 1, k + n + 2]);
            triangles.push([k, k + n + 2, k + n + 1]);
        }
    }
    (nodes, triangles)
}

/// Requirement: the Verlet lists built with the refitted tree hold every
/// triangle within `reach + skin` of each node (so nothing within `reach`
/// is missed while nodes move less than half the skin), after the surface
/// has moved and the tree was refitted, and the closest candidate is the
/// closest triangle of all.
///
/// Tolerance: exact (a list either holds a triangle or not; the closest
/// point is compared with the brute-force minimum to round-off, 1e-12 mm).
#[test]
fn candidate_lists_hold_every_triangle_within_reach() {
    let (surface0, triangles) = grid(12, 2.5, 0.0);
    let mut random = Random(42);
    let nodes: Vec<Vector3<f64>> = (0..300)
        .map(|_| {
            Vector3::new(
                30.0 * random.next(),
                30.0 * random.next(),
                random.next() - 0.3,
            )
        })
        .collect();
    let (reach, skin) = (0.55, 1.0);
    let mut lists = CandidateLists::new(reach, skin);
    for round in 0..3 {
        // The surface waves and drifts between rounds (the tree is refitted).
        let surface: Vec<Vector3<f64>> = surface0
            .iter()
            .map(|x| {
                x + Vector3::new(
                    0.7 * round as f64,
                    0.0,
                    0.4 * round as f64 * (0.3 * x.x).sin(),
                )
            })
            .collect();
        lists.rebuild(&nodes, &surface, &triangles);
        for (i, x) in nodes.iter().enumerate() {
            let list = lists.of(i);
            let mut best = f64::INFINITY;
            for (k, t) in triangles.iter().enumerate() {
                let p = closest_on_triangle(x, &surface[t[0]], &surface[t[1]], &surface[t[2]]);
                let d = (x - p.point).norm();
                best = best.min(d);
                if d <= reach + skin {
                    assert!(
                        list.binary_search(&(k as u32)).is_ok(),
                        "round {round}: node {i}: triangle {k} at {d} mm not listed"
                    );
                }
            }
            let mut boxes = vec![[0.0; 6]; triangles.len()];
            triangle_boxes(&surface, &triangles, &mut boxes);
            if let Some((_, p, _)) = closest_candidate(x, list, &surface, &triangles, &boxes, None)
            {
                let d = (x - p.point).norm();
                if best <= reach + skin {
                    assert!((d - best).abs() < 1e-12, "node {i}: {d} vs {best}");
                }
            }
        }
    }
    assert_eq!(lists.builds(), 3);
}

/// Two plies of 12 × 12 cells of 2 mm, their mid-surfaces 0.3 mm apart
/// (touching), as a [`PlyContact`] set up for the explicit path.
fn stacked_plies() -> PlyContact {
    let (lower, triangles) = grid(12, 2.0, 0.0);
    let (upper, _) = grid(12, 2.0, 0.3);
    let n = lower.len();
    let mut term = ply_stack(lower, upper, &triangles, 0.3, 1.0);
    let masses = Masses {
        node: vec![1e-9; 2 * n],
        extra: Vec::new(),
    };
    term.explicit_setup(&State::at(&vec![0.0; 6 * n]), &masses, 1e-6)
        .expect("set-up");
    term
}

/// Requirement: the candidate lists are rebuilt at the same increments,
/// and every force is the same, whether the term looks at every node's
/// motion at every increment (no motion bound: `State::motion = ∞`) or
/// skips that while the solver's bound of the nodes' motion, summed since
/// the last build, proves no node has moved half the skin; and the
/// shortcut is not idle (it fails the test when the bound is too small).
///
/// Set-up: the upper ply slides by 0.04 mm an increment in x while
/// pressed 2 µm into the lower one, 60 increments (2.4 mm: several
/// rebuilds at a 1 mm skin). Tolerance: exact (the same decisions give the
/// same bits).
#[test]
fn list_rebuilds_follow_the_motion_bound_exactly() {
    let slide = 0.04;
    let n = 13 * 13;
    let mut with_bound = stacked_plies();
    let mut without = stacked_plies();
    let mut too_small = stacked_plies();
    let (mut a, mut b, mut c) = (vec![0.0; 6 * n], vec![0.0; 6 * n], vec![0.0; 6 * n]);
    let mut u = vec![0.0; 6 * n];
    for step in 1..=60 {
        for node in u[3 * n..].chunks_exact_mut(3) {
            node[0] = slide * step as f64;
            node[2] = -2e-3;
        }
        // The solver's bound: √3 times the largest component change.
        let motion = slide * 3f64.sqrt() * (1.0 + 1e-12);
        let state = |motion: f64| State {
            time_step: 1e-6,
            motion,
            ..State::at(&u)
        };
        with_bound
            .explicit_forces(&state(motion), &mut a)
            .expect("forces");
        without
            .explicit_forces(&state(f64::INFINITY), &mut b)
            .expect("forces");
        too_small
            .explicit_forces(&state(1e-3), &mut c)
            .expect("forces");
        assert_eq!(a, b, "increment {step}: forces");
        assert_eq!(
            with_bound.list_builds(),
            without.list_builds(),
            "increment {step}: list builds"
        );
    }
    assert!(without.list_builds() >= 2 + 4, "{}", without.list_builds());
    // A bound that is not one (1 µm against 40 µm of motion) misses the
    // rebuilds: the shortcut is what decides when it proves anything.
    assert!(too_small.list_builds() < without.list_builds());
}

/// `μ` of the pull-out case (the paper's ply–ply friction) and the dead
/// weight on the upper ply [N].
const MU: f64 = 0.336;
const WEIGHT: f64 = 10.0;

/// Requirement: a ply pulled out between two plies under a dead weight
/// slides at a pull force equal to μ times the normal force on each face,
/// `F = 2 μ W`; the plies above and below hold `μ W` each in their plane
/// and the lower one carries `W`; the energy balance closes within 1 % of
/// the work and the friction dissipates the work `F · 2 mm`. Each
/// interface shows it on its own in the VTU fields of the last state
/// (`docs/contact.md`, "Outputs"): the friction dissipated at the nodes of
/// both sides of one interface adds up to `μ W · 2 mm`, the middle ply's
/// nodes slid the 2 mm on each of its neighbours, and the merged fields are
/// the interfaces' sum (force) and largest (status).
///
/// Tolerances: over the sliding phase (λ from 0.2, when the slip has
/// spread over the ply, to 0.9) the mean pull is within 0.5 % of `2 μ W`
/// and every history row within 2 %. The pull differs from `2 μ W` by the
/// inertia of the middle ply (`m a ≤ 2.4e-7 t · 5.8 · 2 mm / (0.02 s)²
/// ≈ 7e-3 N`, 0.1 % of F, at the smooth-step's largest acceleration) and
/// by the vibration of the weight on the penalty springs, which the
/// contact damping settles; the per-row band covers that vibration (it is
/// an oscillation about the mean, measured below 1 % at element_size
/// 2.5 mm). The vertical reaction is `W` to the same vibration (0.5 %).
/// Per interface: the friction dissipation within 2 % of `μ W · 2 mm` (the
/// 1 % of the whole friction energy's check below, plus the normal
/// dashpots' share, which that energy holds and the fields do not, itself
/// within that check's 1 %); the middle ply's median slip on each
/// neighbour within 2 % of the 2 mm pull (the elastic stick before the
/// slide and the ply's stretch, below 1e-3 mm, are far inside; the 2 %
/// covers the nodes at the plies' edges, which leave the other ply);
/// the merged force equal to the sum to round-off (1e-12 relative).
#[test]
fn pull_out_between_two_plies_slides_at_twice_mu_w() {
    let dir = TempDir::new().unwrap();
    let text = fs::read_to_string(verification_case("ply-pull-out.toml")).unwrap();
    let case = load(&text, dir.path()).unwrap();
    let out = TempDir::new().unwrap();
    let summary = run_forming(&case, out.path(), Progress::Quiet).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(summary.status, RunStatus::Complete);
    let exact = 2.0 * MU * WEIGHT;
    let sliding: Vec<_> = summary
        .history
        .iter()
        .filter(|r| r.load >= 0.2 && r.load <= 0.9)
        .collect();
    assert!(sliding.len() > 50, "{} rows", sliding.len());
    let mut mean = [0.0; 4];
    for row in &sliding {
        // Boundaries: 0 the lower ply, 1 the upper ply, 2 the pulled edge.
        let pull = row.reactions[2][0];
        assert!(
            (pull / exact - 1.0).abs() <= 0.02,
            "λ = {}: pull {pull} N, 2 μ W = {exact} N",
            row.load
        );
        mean[0] += pull;
        mean[1] += -row.reactions[0][0];
        mean[2] += -row.reactions[1][0];
        mean[3] += row.reactions[0][2];
    }
    for m in &mut mean {
        *m /= sliding.len() as f64;
    }
    assert!(
        (mean[0] / exact - 1.0).abs() <= 5e-3,
        "mean pull {}",
        mean[0]
    );
    for (name, value) in [("lower", mean[1]), ("upper", mean[2])] {
        assert!(
            (value / (MU * WEIGHT) - 1.0).abs() <= 5e-3,
            "{name} ply's in-plane reaction {value} N, μ W = {}",
            MU * WEIGHT
        );
    }
    assert!(
        (mean[3] / WEIGHT - 1.0).abs() <= 5e-3,
        "lower ply's vertical reaction {} N",
        mean[3]
    );
    let figures = summary.explicit.as_ref().unwrap();
    assert!(
        figures.max_relative_balance_error <= 1e-2,
        "energy balance {}",
        figures.max_relative_balance_error
    );
    let energies = figures.final_energies.unwrap();
    // Friction work of the slide: F times the 2 mm pull, less the elastic
    // stretch of the ply (below 1e-3 mm here), within the 0.5 % of F.
    assert!(
        (energies.friction / (exact * 2.0) - 1.0).abs() <= 1e-2,
        "friction dissipated {} N·mm, F · 2 mm = {}",
        energies.friction,
        exact * 2.0
    );

    // Per interface, at the last state.
    let last = |ply: &str| {
        let mut files: Vec<PathBuf> = fs::read_dir(out.path().join("vtu"))
            .unwrap()
            .map(|e| e.unwrap().path())
            .filter(|p| {
                let name = p.file_name().unwrap().to_string_lossy().to_string();
                name.starts_with(&format!("{ply}_")) && name.ends_with(".vtu")
            })
            .collect();
        files.sort();
        fs::read_to_string(files.last().unwrap()).unwrap()
    };
    let (lower, middle, upper) = (last("lower"), last("middle"), last("upper"));
    let interface_work = MU * WEIGHT * 2.0;
    for (own, other, own_name, other_name) in [
        (&middle, &lower, "middle", "lower"),
        (&middle, &upper, "middle", "upper"),
    ] {
        let dissipated: f64 = point_array(
            own,
            &format!("ply_contact_friction_dissipation[{other_name}]"),
        )
        .iter()
        .chain(&point_array(
            other,
            &format!("ply_contact_friction_dissipation[{own_name}]"),
        ))
        .sum();
        assert!(
            (dissipated / interface_work - 1.0).abs() <= 2e-2,
            "interface {own_name}/{other_name}: {dissipated} N·mm dissipated, μ W · 2 mm = {interface_work}"
        );
        let status = point_array(own, &format!("ply_contact_status[{other_name}]"));
        let mut slips: Vec<f64> = point_array(own, &format!("ply_contact_slip[{other_name}]"))
            .into_iter()
            .zip(&status)
            .filter(|(_, s)| **s > 0.0)
            .map(|(slip, _)| slip)
            .collect();
        assert!(slips.len() > 10, "{} nodes in contact", slips.len());
        slips.sort_by(f64::total_cmp);
        let median = slips[slips.len() / 2];
        assert!(
            (median / 2.0 - 1.0).abs() <= 2e-2,
            "middle ply's median slip on {other_name}: {median} mm"
        );
    }
    let merged = point_array(&middle, "ply_contact_normal_force");
    let parts = [
        point_array(&middle, "ply_contact_normal_force[lower]"),
        point_array(&middle, "ply_contact_normal_force[upper]"),
    ];
    for (n, m) in merged.iter().enumerate() {
        let sum = parts[0][n] + parts[1][n];
        assert!(
            (m - sum).abs() <= 1e-12 * (1.0 + sum.abs()),
            "node {n}: {m} against {sum}"
        );
    }
    let merged = point_array(&middle, "ply_contact_status");
    for (n, m) in merged.iter().enumerate() {
        assert_eq!(*m, parts_status(&middle, n), "node {n}");
    }
}

/// The largest of the middle ply's per-interface statuses at node `n`.
fn parts_status(vtu: &str, n: usize) -> f64 {
    ["lower", "upper"]
        .iter()
        .map(|o| point_array(vtu, &format!("ply_contact_status[{o}]"))[n])
        .fold(0.0, f64::max)
}

/// The values of the point array `name` of an ASCII VTU.
fn point_array(vtu: &str, name: &str) -> Vec<f64> {
    let tag = format!("Name=\"{name}\"");
    let start = vtu.find(&tag).unwrap_or_else(|| panic!("no array {name}"));
    let body = &vtu[start..];
    let body = &body[body.find('>').unwrap() + 1..];
    let body = &body[..body.find("</DataArray>").unwrap()];
    body.split_whitespace()
        .map(|v| v.parse::<f64>().unwrap())
        .collect()
}

/// The stack: two 30 × 30 mm plies on a fixed plane, pressed by a dead
/// load of 19.62 N spread over the upper ply, the mean displacement of each
/// ply probed.
const STACK: &str = r#"
title = "Two plies pressed flat"
solver = "explicit"

[[ply]]
name = "lower"
params = "schaefer2024"
thickness = 0.3
areal_mass = 0.30
bending = false
[ply.mesh]
shape = "rectangle"
size = [30.0, 30.0]
centre = [0.0, 0.0, 0.15]
element_size = 3.0

[[ply]]
name = "upper"
params = "schaefer2024"
thickness = 0.3
areal_mass = 0.30
fibre_angle_deg = 90.0
bending = false
[ply.mesh]
shape = "rectangle"
size = [30.0, 30.0]
centre = [0.0, 0.0, 0.45]
element_size = 2.0

[[ply_contact]]
plies = ["lower", "upper"]
friction = 0.336

[[tool]]
name = "table"
shape = "plane"
origin = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
friction = 0.147
extent = 40.0

[[load]]
ply = "upper"
nodes = "all"
force = [0.0, 0.0, -19.62]
amplitude = "constant"

[[boundary]]
ply = "lower"
nodes = "left"
fix = ["x", "y"]

[[boundary]]
ply = "upper"
nodes = "left"
fix = ["x", "y"]

[[probe]]
ply = "lower"
nodes = "all"

[[probe]]
ply = "upper"
nodes = "all"

[explicit]
duration = 0.01

[output]
states = 1
history = 20
"#;

/// Requirement: a stack pressed flat keeps its plies apart by the contact
/// gap — their mid-surfaces stay `(t_A + t_B)/2 = 0.3 mm` apart — and the
/// load goes through both plies to the table (meshes of different sizes,
/// rovings crossed, so no node lies over another).
///
/// Tolerances: the separation within 1 % of the offset (3e-3 mm, the gap
/// tolerance the quasi-static tool contact accepts by default); the
/// penalty's own penetration under 19.6 N spread over about 200 nodes is
/// far below it. The table's force within 1 % of the load once the
/// sudden load's vibration has been damped by the contact dashpots (the
/// second half of the run: about 20 periods of the stack on its penalty
/// springs at 20 % of critical damping).
#[test]
fn stack_pressed_flat_keeps_the_plies_apart_by_the_gap() {
    let dir = TempDir::new().unwrap();
    let case = load(STACK, dir.path()).unwrap();
    let summary = run(&case);
    let weight = 19.62;
    let last = summary.history.last().unwrap();
    let separation = 0.3 + last.probes[1][2] - last.probes[0][2];
    assert!(
        (separation - 0.3).abs() <= 3e-3,
        "mid-surfaces {separation} mm apart, expected 0.3 mm"
    );
    // Both plies stay on the table (the lower mid-surface 0.15 mm above it).
    assert!(
        last.probes[0][2].abs() <= 3e-3,
        "lower ply moved {:?}",
        last.probes[0]
    );
    for row in summary.history.iter().filter(|r| r.load >= 0.5) {
        assert!(
            (row.tools[0].force / weight - 1.0).abs() <= 1e-2,
            "λ = {}: table force {} N, load {weight} N",
            row.load,
            row.tools[0].force
        );
    }
}

/// Requirement: the case file says where ply–ply contact cannot go: on the
/// quasi-static path, between a ply and itself, between unknown plies, or
/// twice between the same pair; and plies that start overlapping are
/// refused with the node and the distance.
#[test]
fn ply_contact_case_errors_name_the_key() {
    let dir = TempDir::new().unwrap();
    let quasi = edit(
        STACK,
        &[("solver = \"explicit\"", "solver = \"quasi-static\"")],
    );
    let e = load(&quasi, dir.path()).unwrap_err();
    assert!(
        e.contains("ply_contact") && e.contains("quasi-static"),
        "{e}"
    );
    let same = edit(
        STACK,
        &[(
            "plies = [\"lower\", \"upper\"]",
            "plies = [\"lower\", \"lower\"]",
        )],
    );
    let e = load(&same, dir.path()).unwrap_err();
    assert!(
        e.contains("ply_contact[0].plies") && e.contains("two different plies"),
        "{e}"
    );
    let unknown = edit(
        STACK,
        &[(
            "plies = [\"lower\", \"upper\"]",
            "plies = [\"lower\", \"top\"]",
        )],
    );
    let e = load(&unknown, dir.path()).unwrap_err();
    assert!(
        e.contains("\"top\"") && e.contains("one of the plies"),
        "{e}"
    );
    let twice = edit(
        STACK,
        &[(
            "[[ply_contact]]\nplies = [\"lower\", \"upper\"]\nfriction = 0.336\n",
            "[[ply_contact]]\nplies = [\"lower\", \"upper\"]\nfriction = 0.336\n\n[[ply_contact]]\nplies = [\"upper\", \"lower\"]\nfriction = 0.2\n",
        )],
    );
    let e = load(&twice, dir.path()).unwrap_err();
    assert!(
        e.contains("ply_contact[1].plies") && e.contains("no other"),
        "{e}"
    );
    let negative = edit(STACK, &[("friction = 0.336", "friction = -0.1")]);
    let e = load(&negative, dir.path()).unwrap_err();
    assert!(
        e.contains("ply_contact[0].friction") && e.contains("-0.1"),
        "{e}"
    );
    // Overlapping plies: the run refuses at set-up, naming the plies.
    let overlap = edit(
        STACK,
        &[("centre = [0.0, 0.0, 0.45]", "centre = [0.0, 0.0, 0.2]")],
    );
    let case = load(&overlap, dir.path()).unwrap();
    let out = TempDir::new().unwrap();
    let e = match run_forming(&case, out.path(), Progress::Quiet) {
        Err(e) => e.to_string(),
        Ok(s) => format!("{:?}: {:?}", s.status, s.explicit.map(|e| e.warnings)),
    };
    assert!(e.contains("overlap") && e.contains("\"upper\""), "{e}");
}

/// The names of the terms of a case's model, in order.
fn term_names(case: &FormingCase) -> Vec<String> {
    let built = case.build().unwrap_or_else(|e| panic!("{e}"));
    built
        .model
        .terms
        .iter()
        .map(|t| t.name().to_string())
        .collect()
}

/// Requirement: `[[tool]] plies` gives a tool a contact term with the
/// plies it names only; left out, every ply, so the model is the one it
/// was before the key (the same terms in the same order).
#[test]
fn a_tool_has_contact_terms_with_its_plies_only() {
    let dir = TempDir::new().unwrap();
    let default = term_names(&load(STACK, dir.path()).unwrap());
    let with_table = |list: &str| {
        edit(
            STACK,
            &[(
                "extent = 40.0\n",
                &format!("extent = 40.0\nplies = {list}\n"),
            )],
        )
    };
    let every = term_names(&load(&with_table("[\"upper\", \"lower\"]"), dir.path()).unwrap());
    assert_eq!(every, default);
    let lower_term = "contact of lower with table";
    let upper_term = "contact of upper with table";
    assert!(
        default.iter().any(|n| n == lower_term) && default.iter().any(|n| n == upper_term),
        "{default:?}"
    );
    let lower = term_names(&load(&with_table("[\"lower\"]"), dir.path()).unwrap());
    let expected: Vec<String> = default
        .iter()
        .filter(|n| *n != upper_term)
        .cloned()
        .collect();
    assert_eq!(lower, expected);
    let upper = term_names(&load(&with_table("[\"upper\"]"), dir.path()).unwrap());
    assert!(
        upper.iter().any(|n| n == upper_term) && !upper.iter().any(|n| n == lower_term),
        "{upper:?}"
    );
}

/// Requirement: a ply a tool does not touch is not pushed by it. The
/// stack of [`STACK`] with the table touching the upper ply only: the
/// load pushes the upper ply down onto the lower one, which has nothing
/// under it and goes through the table, while the upper ply comes to rest
/// on the table (its mid-surface half a thickness above it, 0.3 mm below
/// where it started) and carries the whole load to it. The resolved case
/// names the table's ply.
///
/// Tolerances: the upper ply's rest within 1 % of the 0.3 mm it drops
/// and the table's force at the end within 1 % of the load (as the stack
/// pressed flat above); the lower ply only has to be clearly below the
/// table (its mid-surface more than a thickness below where it started).
#[test]
fn a_ply_the_tool_does_not_touch_goes_through_it() {
    let dir = TempDir::new().unwrap();
    let text = edit(
        STACK,
        &[("extent = 40.0\n", "extent = 40.0\nplies = [\"upper\"]\n")],
    );
    let case = load(&text, dir.path()).unwrap();
    let out = TempDir::new().unwrap();
    let summary = run_forming(&case, out.path(), Progress::Quiet).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(summary.status, RunStatus::Complete);
    let last = summary.history.last().unwrap();
    assert!(
        (last.tools[0].force / 19.62 - 1.0).abs() <= 1e-2,
        "table force {} N, load 19.62 N",
        last.tools[0].force
    );
    assert!(
        (last.probes[1][2] + 0.3).abs() <= 3e-3,
        "upper ply moved {:?}, expected 0.3 mm down onto the table",
        last.probes[1]
    );
    assert!(
        last.probes[0][2] < -0.3,
        "lower ply moved {:?}, expected through the table",
        last.probes[0]
    );
    let resolved: serde_json::Value =
        serde_json::from_str(&fs::read_to_string(out.path().join("case.resolved.json")).unwrap())
            .unwrap();
    assert_eq!(
        resolved["case"]["tools"][0]["plies"],
        serde_json::json!(["upper"]),
        "{}",
        resolved["case"]["tools"]
    );
}

/// Requirement: the shipped stacks of four and eight plies
/// (`docs/forming.md`, "Stacks of four and eight plies") are laid up as
/// documented: the fibre angles from the die up, mid-surfaces 0.3 mm apart
/// from 0.15 mm, one `[[ply_contact]]` per pair of neighbours (μ = 0.336)
/// and no other, the die touching the bottom ply, the blankholder and the
/// punch the top ply, resting on its top face; the coarse copy of each
/// builds (the paper-size models build in `ncform check`).
#[test]
fn shipped_stacks_pair_neighbours_and_tools_with_their_plies() {
    use ncform::case::forming::{PlyMesh, ToolShape};
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for (file, angles) in [
        ("hemisphere-0-90-90-0.toml", &[0.0, 90.0, 90.0, 0.0][..]),
        (
            "hemisphere-0-45-90-m45-s.toml",
            &[0.0, 45.0, 90.0, -45.0, -45.0, 90.0, 45.0, 0.0][..],
        ),
    ] {
        let path = root.join("cases").join(file);
        let case = FormingCase::load(&path).unwrap_or_else(|e| panic!("{e}"));
        let n = angles.len();
        let got: Vec<f64> = case.plies.iter().map(|p| p.fibre_angle_deg).collect();
        assert_eq!(got, angles, "{file}");
        for (k, ply) in case.plies.iter().enumerate() {
            let PlyMesh::Rectangle { centre, .. } = &ply.mesh else {
                panic!("{file}: ply {k} is not a rectangle")
            };
            assert!(
                (centre.z - (0.15 + 0.3 * k as f64)).abs() < 1e-12,
                "{file}: ply {k} at z = {}",
                centre.z
            );
        }
        let pairs: Vec<[usize; 2]> = case.ply_contacts.iter().map(|c| c.plies).collect();
        let neighbours: Vec<[usize; 2]> = (0..n - 1).map(|k| [k, k + 1]).collect();
        assert_eq!(pairs, neighbours, "{file}");
        assert!(case.ply_contacts.iter().all(|c| c.friction == 0.336));
        let tool = |name: &str| case.tools.iter().find(|t| t.name == name).unwrap();
        assert_eq!(tool("die").plies, vec![0], "{file}");
        assert_eq!(tool("blankholder").plies, vec![n - 1], "{file}");
        assert_eq!(tool("punch").plies, vec![n - 1], "{file}");
        let top = 0.3 * n as f64;
        assert!((tool("blankholder").origin.z - top).abs() < 1e-12, "{file}");
        let ToolShape::Sphere { radius } = tool("punch").shape else {
            panic!("{file}: the punch is not a sphere")
        };
        assert!(
            (tool("punch").origin.z - radius - top).abs() < 1e-9,
            "{file}"
        );
        let coarse = fs::read_to_string(&path)
            .unwrap()
            .replace("cells = [84, 84]", "cells = [8, 8]");
        let dir = TempDir::new().unwrap();
        let small = load(&coarse, dir.path()).unwrap();
        small.build().unwrap_or_else(|e| panic!("{file}: {e}"));
    }
}
