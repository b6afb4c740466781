//! The forming foundation on problems with known answers (docs/verification.md,
//! "Forming"): the shipped verification cases of `cases/verification/`,
//! coarse where they are meshed finely for the `verification/` suite, run
//! through the same case files and `ncform run` code path a user takes;
//! and the case-file errors of forming set-ups. Each test names the
//! requirement it checks and derives its tolerance.

use std::fs;
use std::path::{Path, PathBuf};

use ncform::case::SolverKind;
use ncform::case::forming::FormingCase;
use ncform::cli::form::{FormingSummary, run_forming};
use ncform::cli::run::Progress;
use ncform::solver::RunStatus;
use tempfile::TempDir;

/// A shipped verification case.
fn verification_case(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases/verification")
        .join(name)
}

/// `text` with each `(from, to)` replaced once; panics if `from` is absent.
fn edit(text: &str, edits: &[(&str, &str)]) -> String {
    let mut text = text.to_string();
    for (from, to) in edits {
        assert!(text.contains(from), "`{from}` not in the case text");
        text = text.replacen(from, to, 1);
    }
    text
}

/// Loads the case text `text` written next to the shipped cases (so that
/// relative paths resolve the same way).
fn load(text: &str, dir: &Path) -> FormingCase {
    let path = dir.join("case.toml");
    fs::write(&path, text).unwrap();
    FormingCase::from_toml_str(text, &path.display().to_string(), &verification_case(""))
        .unwrap_or_else(|e| panic!("{e}"))
}

/// Runs a case into a fresh folder; the run must complete.
fn run(case: &FormingCase) -> FormingSummary {
    let out = TempDir::new().unwrap();
    let summary = run_forming(case, out.path(), Progress::Quiet).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(summary.status, RunStatus::Complete, "{}", case.title);
    summary
}

fn shipped(name: &str) -> String {
    fs::read_to_string(verification_case(name)).unwrap()
}

// ---------------------------------------------------------------------------
// Blankholder at rest
// ---------------------------------------------------------------------------

/// The weight of the 1.7 kg blankholder [N].
const BLANKHOLDER_WEIGHT: f64 = 1.7e-3 * 9810.0;

/// Requirement: a floating blankholder lying on a ply on a fixed table
/// settles with the contact force on it equal to its weight, to 1e-6, and
/// stays there (quasi-static).
///
/// Tolerance: at a converged step the blankholder's dof is in equilibrium
/// to the Newton residual tolerance (1e-6 of the reactions, about 17 N
/// here): `|F − W| ≤ 1.7e-5 N ≈ 1e-6 W`. "Stays there": its displacement
/// is the contact's penetration, below the gap tolerance (1 % of the ply's
/// thickness, 3e-3 mm).
#[test]
fn blankholder_at_rest_quasi_static() {
    let dir = TempDir::new().unwrap();
    let case = load(&shipped("blankholder.toml"), dir.path());
    let summary = run(&case);
    for row in &summary.history {
        let holder = &row.tools[1];
        assert!(
            (holder.force - BLANKHOLDER_WEIGHT).abs() <= 1e-6 * BLANKHOLDER_WEIGHT,
            "λ = {}: contact force {} N, weight {BLANKHOLDER_WEIGHT} N",
            row.load,
            holder.force
        );
        assert!(
            holder.displacement.abs() <= 3e-3,
            "moved {}",
            holder.displacement
        );
    }
}

/// Requirement: the same set-up with the explicit solver settles (with
/// mass-proportional damping) to a contact force equal to the weight and
/// stays at rest, with the energy balance closed.
///
/// Tolerance: the blankholder bounces on the penalty springs of its contact
/// with the ply; damping `α` makes the motion decay as `e^{−αt/2}`. With
/// `α = 2000/s` over `T = 0.02 s` the start-up oscillation (the sudden
/// weight: up to `W`) is down to `e^{−20} W = 2e-9 W` at the end, so
/// `|F − W| ≤ 1e-6 W` holds with a wide margin and the displacement at the
/// last two outputs agrees to `1e-6` of the final penetration. The balance
/// error of a damped central-difference run is second order in the step
/// (`docs/explicit.md`): below 1e-3 of the work done.
#[test]
fn blankholder_at_rest_explicit() {
    let dir = TempDir::new().unwrap();
    let text = edit(
        &shipped("blankholder.toml"),
        &[(
            "[output]",
            "solver = \"explicit\"\n[explicit]\nduration = 0.02\ndamping = 2000.0\n\n[output]",
        )],
    );
    // `solver` must be a top-level key: move it above the tables.
    let text = text.replace("solver = \"explicit\"\n[explicit]", "[explicit]");
    let text = format!("solver = \"explicit\"\n{text}");
    let case = load(&text, dir.path());
    assert_eq!(case.solver_kind, SolverKind::Explicit);
    let summary = run(&case);
    let last = summary.history.last().unwrap();
    let before = &summary.history[summary.history.len() - 2];
    let holder = &last.tools[1];
    assert!(
        (holder.force - BLANKHOLDER_WEIGHT).abs() <= 1e-6 * BLANKHOLDER_WEIGHT,
        "contact force {} N, weight {BLANKHOLDER_WEIGHT} N",
        holder.force
    );
    let settled = holder.displacement;
    assert!(
        (before.tools[1].displacement - settled).abs() <= 1e-6 * settled.abs(),
        "still moving: {} then {settled}",
        before.tools[1].displacement
    );
    let figures = summary.explicit.as_ref().unwrap();
    assert!(
        figures.max_relative_balance_error <= 1e-3,
        "energy balance {}",
        figures.max_relative_balance_error
    );
}

// ---------------------------------------------------------------------------
// Friction patch
// ---------------------------------------------------------------------------

/// `tan α` of the slope and `μ` of the friction patch case.
const TAN_ALPHA: f64 = 0.1;
const MU: f64 = 0.3;
const WEIGHT: f64 = 10.0;

/// Requirement: a patch pulled up a slope under a dead weight slides when
/// the friction force reaches `μ N`: the pull at full slip is
/// `F = G (sin α + μ cos α)`, to 1e-6.
///
/// Tolerance: in slip the return map gives every node `|t_T| = μ t_N`
/// exactly (round-off); the pull balances the friction and the weight's
/// slope component to the Newton residual tolerance of the case (1e-10 of
/// the reactions, 1e-9 N): far below 1e-6 of `F ≈ 4 N`.
#[test]
fn friction_patch_slides_at_mu_n() {
    let dir = TempDir::new().unwrap();
    let case = load(&shipped("friction-patch.toml"), dir.path());
    let summary = run(&case);
    let (sin, cos) = {
        let alpha = TAN_ALPHA.atan();
        (alpha.sin(), alpha.cos())
    };
    let expected = WEIGHT * (sin + MU * cos);
    let last = summary.history.last().unwrap();
    let nodes = case_nodes(&summary);
    assert_eq!(last.contacts, Some((nodes, nodes)), "every node slips");
    let pull = last.reactions[0][0];
    assert!(
        (pull - expected).abs() <= 1e-6 * expected,
        "pull {pull} N, G (sin α + μ cos α) = {expected} N"
    );
    // The normal force on the slope is G cos α.
    let normal = last.tools[0].force;
    assert!(
        (normal - WEIGHT * cos).abs() <= 1e-6 * WEIGHT,
        "normal {normal} N"
    );
}

fn case_nodes(summary: &FormingSummary) -> usize {
    summary.plies.iter().map(|p| p.nodes).sum()
}

/// Requirement: without the pull the friction holds the patch on the slope
/// (`tan α = 0.1 < μ = 0.3`): every node sticks and the patch does not
/// move, to 1e-6 of the element size.
///
/// Tolerance: augmented-Lagrangian stick allows a slip of
/// `Δλ/ε_T` per augmentation; the multipliers converge to 1e-6 (the case's
/// tolerance) of `|λ_T| ≈ 1.2e-2 N` with `ε_T ≈ 1.2e3 N/mm`: the mean
/// displacement is below `1e-8·1.2e-2/1.2e3 ≈ 1e-13 mm` in principle; we
/// allow 1e-6 × 2.5 mm.
#[test]
fn friction_patch_sticks_below_the_limit() {
    let dir = TempDir::new().unwrap();
    let text = shipped("friction-patch.toml");
    let start = text.find("# The uphill edge").unwrap();
    let end = text.find("[contact]").unwrap();
    let text = format!(
        "{}[[probe]]\nnodes = \"all\"\n\n{}",
        &text[..start],
        &text[end..]
    );
    let case = load(&text, dir.path());
    let summary = run(&case);
    let nodes = case_nodes(&summary);
    for row in &summary.history {
        assert_eq!(
            row.contacts,
            Some((nodes, 0)),
            "λ = {}: all stick",
            row.load
        );
        let moved = row.probes[0];
        assert!(
            moved.iter().all(|m| m.abs() <= 2.5e-6),
            "λ = {}: the patch moved {moved:?} mm",
            row.load
        );
    }
}

// ---------------------------------------------------------------------------
// Case-file errors
// ---------------------------------------------------------------------------

/// Loads `text` expecting an error; returns the message.
fn case_error(text: &str) -> String {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("case.toml");
    fs::write(&path, text).unwrap();
    match FormingCase::load(&path) {
        Err(e) => e.to_string(),
        Ok(case) => match case.build() {
            Err(e) => e,
            Ok(_) => panic!("the case should be rejected:\n{text}"),
        },
    }
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message `{msg}` lacks `{p}`");
    }
}

/// Requirement (docs/cases.md): bad forming input names the file, the
/// line or key, the value and what was expected; it never panics.
#[test]
fn bad_forming_cases_name_key_value_and_expectation() {
    let base = shipped("blankholder.toml");
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            edit(&base, &[("mass = 1.7 ", "# no mass ")]),
            vec!["tool[1].mass", "(missing)", "a floating tool needs a mass"],
        ),
        (
            edit(
                &base,
                &[("friction = 0.147\nextent", "friction = -0.1\nextent")],
            ),
            vec!["tool[0].friction", "-0.1", "≥ 0"],
        ),
        (
            edit(&base, &[("shape = \"plane\"", "shape = \"cone\"")]),
            vec!["tool[0].shape", "\"cone\"", "\"plane\", \"sphere\""],
        ),
        (
            edit(
                &base,
                &[("origin = [0.0, 0.0, 0.3]", "origin = [0.0, 0.0, 0.1]")],
            ),
            vec![
                "tool \"blankholder\" starts inside ply \"ply\"",
                "0.0500 mm inside",
            ],
        ),
        (
            edit(
                &base,
                &[(
                    "direction = [0.0, 0.0, -1.0]",
                    "direction = [0.0, 0.0, 0.0]",
                )],
            ),
            vec!["tool[1].direction", "[0, 0, 0]", "a non-zero direction"],
        ),
        (
            edit(&base, &[("element_size = 10.0", "element_size = -1.0")]),
            vec!["ply[0].mesh.element_size", "-1", "a length > 0 mm"],
        ),
        (
            edit(&base, &[("size = [100.0, 100.0]", "size = [100.0]")]),
            vec!["ply[0].mesh.size", "two lengths > 0 mm"],
        ),
        (
            edit(&base, &[("g = 9810.0", "g = 9810.0\nspeed = 1.0")]),
            vec!["unknown field `speed`"],
        ),
    ];
    for (text, parts) in cases {
        let msg = case_error(&text);
        assert_mentions(&msg, &parts);
        assert!(msg.contains("case.toml"), "no file in `{msg}`");
    }
}
