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
use ncform::report::Progress;
use ncform::report::files::run_forming;
use ncform::report::forming::FormingSummary;
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

/// The blankholder case with the explicit solver settling under
/// mass-proportional damping `α = 800/s` over 0.06 s, a
/// compliant layer `[ply.compaction]` of uncompacted thickness
/// `thickness` (the ply's mid-surface at half of it, the blankholder on
/// its top) and `contact` as the `[contact]` table.
fn compacted_blankholder(law: &str, thickness: f64, contact: &str) -> String {
    let half = 0.5 * thickness;
    let text = edit(
        &shipped("blankholder.toml"),
        &[
            (
                "[ply.mesh]",
                &format!("[ply.compaction]\nthickness = {thickness}\n{law}\n[ply.mesh]"),
            ),
            (
                "centre = [0.0, 0.0, 0.15]",
                &format!("centre = [0.0, 0.0, {half}]"),
            ),
            (
                "origin = [0.0, 0.0, 0.3]",
                &format!("origin = [0.0, 0.0, {thickness}]"),
            ),
            (
                "[output]",
                &format!("[explicit]\nduration = 0.06\ndamping = 800.0\n\n{contact}\n[output]"),
            ),
        ],
    );
    format!("solver = \"explicit\"\n{text}")
}

/// The compression `δ` [mm] of a layer `H` [mm] under the pressure `p`
/// [MPa] of Toll's law with `p_c`, `n` (Eq. C1 solved for `δ`,
/// `docs/theory.md`, "Compaction of the fabric layer").
fn toll_compression(layer: f64, pressure: f64, p_c: f64, n: f64) -> f64 {
    layer * (1.0 - (1.0 + pressure / p_c).powf(-1.0 / n))
}

/// Requirement: a blankholder lying on a ply with a compliant layer sinks
/// until the layer carries its weight: the ply's upper half-layer is
/// compressed by `δ_top` with `p(δ_top) = W/A` and the lower one by
/// `δ_bottom` with `p(δ_bottom) = (W + w)/A` (`w` the ply's own weight),
/// so the blankholder's displacement is `δ_top + δ_bottom` (Eq. C1; every
/// node of the flat ply has the same compression, its force proportional
/// to its area). The contact force on it equals its weight, the energy
/// balance closes.
///
/// Tolerance: the blankholder (1.7 kg) rides on the two half-layers in
/// series, `k = A f'/2 ≈ 625 N/mm` at this pressure (Eq. C2), so
/// `ω ≈ 600/s`; the damping `α = 800/s` gives `ζ = α/2ω ≈ 0.66` and a
/// decay `e^{−ζωt} = e^{−24}` over the 0.06 s: force and displacement are
/// at rest to far below 1e-6, which is the tolerance (the round-off of
/// summing 121 nodal forces is some 1e-14). The cap of the
/// law (the penalty per unit area, 50 N/mm³) is 400 times the layer's
/// tangent at this pressure (Eq. C2: 0.13 N/mm³), so no node
/// reaches the knee and Eq. C1 holds exactly.
#[test]
fn blankholder_sinks_into_a_compliant_layer_by_the_packing_law() {
    let dir = TempDir::new().unwrap();
    let (p_c, n, thickness) = (6.9e-4, 12.0, 0.5);
    let text = compacted_blankholder(
        &format!("pressure = {p_c}\nexponent = {n}"),
        thickness,
        "[contact]\nexplicit_pressure_stiffness = 50.0",
    );
    let case = load(&text, dir.path());
    let summary = run(&case);
    let last = summary.history.last().unwrap();
    let holder = &last.tools[1];
    let area = 100.0 * 100.0;
    let ply_weight = 0.30e-9 * area * 9810.0;
    let expected = toll_compression(0.5 * thickness, BLANKHOLDER_WEIGHT / area, p_c, n)
        + toll_compression(
            0.5 * thickness,
            (BLANKHOLDER_WEIGHT + ply_weight) / area,
            p_c,
            n,
        );
    assert!(
        (holder.displacement - expected).abs() <= 1e-6 * expected,
        "sank {} mm, the packing law gives {expected} mm",
        holder.displacement
    );
    assert!(
        (holder.force - BLANKHOLDER_WEIGHT).abs() <= 1e-6 * BLANKHOLDER_WEIGHT,
        "contact force {} N, weight {BLANKHOLDER_WEIGHT} N",
        holder.force
    );
    let figures = summary.explicit.as_ref().unwrap();
    assert!(
        figures.max_relative_balance_error <= 1e-3,
        "energy balance {}",
        figures.max_relative_balance_error
    );
}

/// Requirement: past the knee, where the law's tangent reaches the
/// penalty (here 0.05 N/mm³ per unit area, below the layer's 0.06 N/mm³
/// at the start), the layer goes on linearly with the penalty (Eq. C3):
/// `δ = δ* + (p − p(δ*))/k` with `δ*` from Eq. C2 — the knee at zero
/// here, since the law starts stiffer than the cap, so `δ = p/k`, the
/// linear penalty of the paper's model.
///
/// Tolerance: the two springs in series, `k A/2 = 250 N/mm` under 1.7 kg,
/// `ω ≈ 380/s`, `ζ = 800/(2·380) ≈ 1.05`: the slower mode decays as
/// `e^{−ω(ζ−√(ζ²−1))t} ≈ e^{−17}` over the 0.06 s, below the 1e-6 kept.
#[test]
fn a_layer_stiffer_than_the_penalty_is_the_linear_penalty() {
    let dir = TempDir::new().unwrap();
    let (p_c, n, thickness, k) = (1e-3, 15.0, 0.5, 0.05);
    let text = compacted_blankholder(
        &format!("pressure = {p_c}\nexponent = {n}"),
        thickness,
        &format!("[contact]\nexplicit_pressure_stiffness = {k}"),
    );
    let case = load(&text, dir.path());
    let summary = run(&case);
    let holder = &summary.history.last().unwrap().tools[1];
    let area = 100.0 * 100.0;
    let ply_weight = 0.30e-9 * area * 9810.0;
    let expected = (2.0 * BLANKHOLDER_WEIGHT + ply_weight) / area / k;
    assert!(
        (holder.displacement - expected).abs() <= 1e-6 * expected,
        "sank {} mm, the linear penalty gives {expected} mm",
        holder.displacement
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
            Err(e) => e.to_string(),
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
        (
            edit(
                &base,
                &[(
                    "[output]",
                    "[contact]\ntangential_penalty_scale = 0.0\n\n[output]",
                )],
            ),
            vec!["contact.tangential_penalty_scale", "0", "a ratio > 0"],
        ),
        (
            edit(
                &base,
                &[(
                    "[output]",
                    "[contact]\nnormal_smoothing = -0.01\n\n[output]",
                )],
            ),
            vec!["contact.normal_smoothing", "-0.01", "a gap width ≥ 0 mm"],
        ),
        (
            edit(
                &base,
                &[(
                    "[output]",
                    "[contact]\nfriction_smoothing = 1.0\n\n[output]",
                )],
            ),
            vec![
                "contact.friction_smoothing",
                "1",
                "a fraction in [0, 1) of the friction limit",
            ],
        ),
        (
            edit(
                &base,
                &[(
                    "[output]",
                    "[contact]\nexplicit_pressure_stiffness = -2.0\n\n[output]",
                )],
            ),
            vec![
                "contact.explicit_pressure_stiffness",
                "-2",
                "a stiffness per unit area",
            ],
        ),
        (
            edit(
                &base,
                &[(
                    "[output]",
                    "[contact]\nexplicit_stiffness = 0.1\nexplicit_pressure_stiffness = 2.0\n\n[output]",
                )],
            ),
            vec![
                "contact.explicit_pressure_stiffness",
                "either contact.explicit_stiffness",
                "not both",
            ],
        ),
        (
            edit(
                &base,
                &[(
                    "[ply.mesh]",
                    "[ply.compaction]\nexponent = 10.0\n[ply.mesh]",
                )],
            ),
            vec![
                "ply[0].compaction.pressure",
                "(missing)",
                "pressure scale p_c",
            ],
        ),
        (
            edit(
                &base,
                &[(
                    "[ply.mesh]",
                    "[ply.compaction]\npressure = 1e-3\nexponent = 1.0\n[ply.mesh]",
                )],
            ),
            vec!["ply[0].compaction.exponent", "1", "> 1"],
        ),
        (
            edit(
                &base,
                &[(
                    "[ply.mesh]",
                    "[ply.compaction]\npressure = 1e-3\nexponent = 10.0\nthickness = -0.5\n[ply.mesh]",
                )],
            ),
            vec!["ply[0].compaction.thickness", "-0.5", "> 0 mm"],
        ),
        (
            edit(
                &base,
                &[(
                    "[ply.mesh]",
                    "[ply.compaction]\npressure = 1e-3\nexponent = 10.0\nstiffness = 1.0\n[ply.mesh]",
                )],
            ),
            vec!["stiffness", "pressure", "exponent"],
        ),
        (
            // The blankholder case is quasi-static.
            edit(
                &base,
                &[(
                    "[ply.mesh]",
                    "[ply.compaction]\npressure = 1e-3\nexponent = 10.0\n[ply.mesh]",
                )],
            ),
            vec!["compaction", "explicit solver", "augmented Lagrangian"],
        ),
    ];
    for (text, parts) in cases {
        let msg = case_error(&text);
        assert_mentions(&msg, &parts);
        assert!(msg.contains("case.toml"), "no file in `{msg}`");
    }

    // A mesh tool that must be closed but is an open sheet: the message
    // names the case, the tool, the STL file and an edge of the hole.
    let dir = TempDir::new().unwrap();
    let stl = dir.path().join("sheet.stl");
    fs::write(
        &stl,
        "solid sheet\n facet normal 0 0 1\n  outer loop\n   vertex -60 -60 0\n   vertex 60 -60 0\n   vertex 60 60 0\n  endloop\n endfacet\nendsolid sheet\n",
    )
    .unwrap();
    // (A mesh tool takes neither the plane's axis nor its drawn extent.)
    let text = edit(
        &base,
        &[
            (
                "name = \"table\"\nshape = \"plane\"",
                "name = \"table\"\nshape = \"mesh\"\nfile = \"sheet.stl\"",
            ),
            (
                "axis = [0.0, 0.0, 1.0]        # the free side (the ply) is above\n",
                "",
            ),
            ("extent = 60.0\n", ""),
        ],
    );
    let path = dir.path().join("case.toml");
    fs::write(&path, &text).unwrap();
    let msg = match FormingCase::load(&path).unwrap().build() {
        Err(e) => e.to_string(),
        Ok(_) => panic!("an open STL with closed = true should be rejected"),
    };
    assert_mentions(&msg, &["case.toml", "tool \"table\"", "sheet.stl"]);
}

// ---------------------------------------------------------------------------
// Capstan
// ---------------------------------------------------------------------------

/// The case text run with the explicit solver: the `[solver]` table of
/// Newton knobs dropped, `solver = "explicit"` and `[explicit]` added.
fn explicit(text: &str, settings: &str) -> String {
    let mut out = String::from("solver = \"explicit\"\n");
    let mut skipping = false;
    for line in text.lines() {
        if line.trim() == "[solver]" {
            skipping = true;
            continue;
        }
        if skipping && (line.starts_with('[') || line.trim().is_empty()) {
            skipping = false;
        }
        if !skipping {
            out.push_str(line);
            out.push('\n');
        }
    }
    out.push_str("\n[explicit]\n");
    out.push_str(settings);
    out.push('\n');
    out
}

/// `T_pull / T_hold` of every history row of a capstan run.
fn capstan_ratios(summary: &FormingSummary) -> Vec<(f64, f64)> {
    summary
        .history
        .iter()
        .map(|row| (row.load, row.reactions[1][2] / row.reactions[0][2]))
        .collect()
}

/// Requirement (Euler–Eytelwein): a pre-wrapped strip pulled over a fixed
/// cylinder at full slip carries `T_pull / T_hold = e^{μθ}` (θ = π,
/// μ = 0.336), within 0.5 %, at every step; the augmented-Lagrangian gap
/// stays below its tolerance.
///
/// Tolerance: the ratio is exact for any law and stretch on a smooth
/// cylinder; the discretisation moves it by the chord error of the
/// faceted strip (`(h/R)²/24 ≈ 1e-4` of the wrap angle with h = 2.5 mm) and
/// the augmented-Lagrangian slip (tolerance 1e-3 of the multipliers): the
/// required 0.5 % is well above both.
#[test]
fn capstan_quasi_static_gives_exp_mu_theta() {
    let dir = TempDir::new().unwrap();
    let case = load(&shipped("capstan.toml"), dir.path());
    let summary = run(&case);
    let exact = (0.336 * std::f64::consts::PI).exp();
    for (load, ratio) in capstan_ratios(&summary) {
        assert!(
            (ratio / exact - 1.0).abs() <= 5e-3,
            "λ = {load}: T_pull/T_hold = {ratio}, e^(μπ) = {exact}"
        );
    }
    let gap_tolerance = 0.01 * 0.3;
    for row in &summary.history {
        let (closed, slipping) = row.contacts.unwrap();
        assert_eq!(closed, slipping, "λ = {}: full slip", row.load);
        assert!(
            row.max_penetration.unwrap() <= gap_tolerance,
            "λ = {}: penetration {:?} mm above the gap tolerance {gap_tolerance} mm",
            row.load,
            row.max_penetration
        );
    }
}

/// Requirement: the explicit capstan (penalty contact with the
/// regularised friction law) agrees with the quasi-static one within 1 %
/// once the pull has built up, and its energy balance with contact and
/// friction closes within 1 % of the work done.
///
/// Tolerance (1 %): the explicit ratio differs from the quasi-static one by
/// the inertia of the strip (kinetic energy below a few per cent of the
/// strain energy at 20 ms), the penalty's penetration (a radius change,
/// which does not enter `e^{μθ}`) and the friction spring's elastic slip
/// (`μ f_N / k_T`, far below the slide of the held end from 10 % of the
/// pull on).
#[test]
fn capstan_explicit_agrees_with_quasi_static() {
    let dir = TempDir::new().unwrap();
    let text = shipped("capstan.toml");
    let quasi = capstan_ratios(&run(&load(&text, dir.path())));
    let summary = run(&load(&explicit(&text, "duration = 0.02"), dir.path()));
    let figures = summary.explicit.as_ref().unwrap();
    assert!(
        figures.max_relative_balance_error <= 1e-2,
        "energy balance {}",
        figures.max_relative_balance_error
    );
    let energies = figures.final_energies.unwrap();
    assert!(energies.friction > 0.0, "friction dissipates");
    let mut compared = 0;
    for (load, ratio) in capstan_ratios(&summary) {
        if load < 0.1 {
            continue;
        }
        // The quasi-static ratio, linearly interpolated in λ.
        let i = quasi
            .iter()
            .position(|(l, _)| *l >= load - 1e-9)
            .unwrap_or(quasi.len() - 1);
        let reference = if i == 0 {
            quasi[0].1
        } else {
            let (l0, r0) = quasi[i - 1];
            let (l1, r1) = quasi[i];
            r0 + (r1 - r0) * (load - l0) / (l1 - l0)
        };
        assert!(
            (ratio / reference - 1.0).abs() <= 1e-2,
            "λ = {load}: explicit {ratio}, quasi-static {reference}"
        );
        compared += 1;
    }
    assert!(compared > 50, "{compared} outputs compared");
}

// ---------------------------------------------------------------------------
// Indentation
// ---------------------------------------------------------------------------

/// Indentation force [N] of the clamped SVK membrane (R = 100, t = 0.3,
/// E = 10, ν = 0.3) by a sphere of radius 40 at 10, 20, 30 and 40 mm, from
/// the independent axisymmetric shooting solution of
/// `verification/reference_indentation.py` (accurate to ~1e-9 relative):
/// `python3 verification/reference_indentation.py`.
const INDENTATION_REFERENCE: [(f64, f64); 4] = [
    (10.0, 4.184343952e-01),
    (20.0, 3.847059252e+00),
    (30.0, 1.437831949e+01),
    (40.0, 3.676670687e+01),
];

/// The sphere's force at depth `d` of a run (linear interpolation).
fn sphere_force(summary: &FormingSummary, d: f64) -> f64 {
    let rows: Vec<(f64, f64)> = summary
        .history
        .iter()
        .map(|r| (r.tools[0].displacement, r.tools[0].force))
        .collect();
    let i = rows.iter().position(|(x, _)| *x >= d - 1e-9).unwrap();
    if i == 0 || (rows[i].0 - d).abs() <= 1e-9 {
        return rows[i].1;
    }
    let ((x0, f0), (x1, f1)) = (rows[i - 1], rows[i]);
    f0 + (f1 - f0) * (d - x0) / (x1 - x0)
}

/// Requirement: the force on a frictionless sphere indenting a clamped
/// circular membrane follows the axisymmetric solution within 1 % (coarse
/// mesh: 4 mm elements), and the augmented-Lagrangian gap stays below its
/// tolerance.
///
/// Tolerance (1 %): the membrane's discretisation error at h = 4 mm (the
/// fine run of `verification/` at 2 mm is within 0.2 %, so the coarse error
/// is about 4× that, h²) plus the Newton tolerance (1e-8).
#[test]
fn indentation_follows_the_axisymmetric_solution() {
    let dir = TempDir::new().unwrap();
    fs::copy(
        verification_case("svk-e10.toml"),
        dir.path().join("svk-e10.toml"),
    )
    .unwrap();
    let case = load(&shipped("indentation.toml"), dir.path());
    let summary = run(&case);
    for (d, reference) in INDENTATION_REFERENCE {
        let f = sphere_force(&summary, d);
        assert!(
            (f / reference - 1.0).abs() <= 1e-2,
            "d = {d} mm: F = {f} N, reference {reference} N"
        );
    }
    for row in &summary.history {
        assert!(
            row.max_penetration.unwrap() <= 0.01 * 0.3,
            "λ = {}",
            row.load
        );
    }
}

/// Requirement: the explicit indentation agrees with the quasi-static one
/// within 1 % where the indentation is quasi-static (30 and 40 mm).
///
/// Tolerance (1 %): the difference comes from the penalty's penetration
/// (with the penalty at the stability limit, `f/k ≈ 0.03 mm` of 40 mm: a
/// depth error of 0.1 %, 0.3 % in force since `F ~ d³`) and the inertia and
/// damping forces of the moving membrane, which the smooth step brings to
/// zero at the end. At small depths the slack membrane's force (`~ d³`) is
/// below those dynamic forces, so they are not compared.
#[test]
fn indentation_explicit_agrees_with_quasi_static() {
    let dir = TempDir::new().unwrap();
    fs::copy(
        verification_case("svk-e10.toml"),
        dir.path().join("svk-e10.toml"),
    )
    .unwrap();
    let text = shipped("indentation.toml");
    let quasi = run(&load(&text, dir.path()));
    let stiff = edit(
        &text,
        &[("offset = 0.0", "offset = 0.0\nexplicit_stiffness = 1.0")],
    );
    let dynamic = run(&load(
        &explicit(&stiff, "duration = 0.2\ndamping = 200.0"),
        dir.path(),
    ));
    for d in [30.0, 40.0] {
        let (a, b) = (sphere_force(&dynamic, d), sphere_force(&quasi, d));
        assert!(
            (a / b - 1.0).abs() <= 1e-2,
            "d = {d} mm: explicit {a} N, quasi-static {b} N"
        );
    }
}

// ---------------------------------------------------------------------------
// Cantilevers
// ---------------------------------------------------------------------------

/// The areal weight of the paper's fabric, 0.30 kg/m² under 9.81 m/s²
/// [N/mm²].
const AREAL_WEIGHT: f64 = 0.30e-9 * 9810.0;

fn cantilever(name: &str, stiffness: f64, length: f64) {
    let dir = TempDir::new().unwrap();
    let case = load(&shipped(name), dir.path());
    let summary = run(&case);
    let tip = -summary.history.last().unwrap().probes[0][2];
    let exact =
        ncform::analytic::elastica::HeavyCantilever::new(stiffness, AREAL_WEIGHT, length, 0.0)
            .unwrap()
            .solve()
            .unwrap()
            .tip_deflection;
    assert!(
        (tip / exact - 1.0).abs() <= 1e-2,
        "{name}: tip deflection {tip} mm, elastica {exact} mm"
    );
}

/// Requirement (Peirce's cantilever): a strip along the rovings (B11 =
/// 4.06 N·mm, L = 150 mm) clamped horizontally and bent by its own weight
/// (0.30 kg/m²) has the tip deflection of the large-deflection elastica
/// within 1 %; the elastica is solved independently by shooting
/// (`src/analytic/elastica.rs`).
///
/// Tolerance (1 %): the element converges at second order with the
/// clamped edge (`docs/bending.md`): `(h/L)² ≈ 7e-5` at 120 cells, plus
/// the rovings' stretch (`q L/(E t) ≈ 1e-6`) and the Newton tolerance.
#[test]
fn cantilever_along_the_rovings_follows_the_elastica() {
    cantilever("cantilever-rovings.toml", 4.06, 150.0);
}

/// Requirement: the same across the rovings (B22 = 0.018 N·mm,
/// L = 30 mm, bending length 18 mm).
///
/// Tolerance (1 %): as along the rovings, `(h/L)²` at 48 cells is 4e-4.
#[test]
fn cantilever_across_the_rovings_follows_the_elastica() {
    cantilever("cantilever-transverse.toml", 0.018, 30.0);
}

// ---------------------------------------------------------------------------
// The assembled forming tangent
// ---------------------------------------------------------------------------

/// Richardson estimate of a central difference: `d(h/2)` and the accepted
/// error `10 (|d(h) − d(h/2)|/3 + 2 ε/h)` with `ε = 64 u |f|` (as in
/// `tests/solver.rs`).
fn central_difference(
    mut f: impl FnMut(f64) -> nalgebra::DVector<f64>,
    h: f64,
) -> (nalgebra::DVector<f64>, f64) {
    let d1 = (f(h) - f(-h)) / (2.0 * h);
    let half = (f(0.5 * h), f(-0.5 * h));
    let scale = f(0.0).norm().max(half.0.norm());
    let d2 = (half.0 - half.1) / h;
    let eps = 64.0 * f64::EPSILON * scale;
    let tol = 10.0 * ((&d1 - &d2).norm() / 3.0 + 2.0 * eps / (0.5 * h));
    (d2, tol)
}

/// Requirement: the assembled tangent of a forming model — membrane,
/// bending (6-node stencils) and frictional contact with a tool (node and
/// tool dofs, unsymmetric slip terms) — is the derivative of the assembled
/// residual, in slip (the capstan strip pulled on from a converged state)
/// and in stick (the patch held on the slope), within the Richardson bound.
#[test]
fn assembled_forming_tangent_matches_finite_differences() {
    use nalgebra::DVector;
    use ncform::model::State;
    use ncform::solver::{Assembler, NewtonParameters, solve_quasi_static};
    use rand::rngs::StdRng;
    use rand::{RngExt, SeedableRng};

    let dir = TempDir::new().unwrap();
    let capstan = edit(
        &shipped("capstan.toml"),
        &[("bending = false", "bending = true")],
    );
    let text = shipped("friction-patch.toml");
    let start = text.find("# The uphill edge").unwrap();
    let end = text.find("[contact]").unwrap();
    let stick = format!("{}{}", &text[..start], &text[end..]);
    for (name, text, perturbation, status) in [
        ("capstan, slip", capstan.as_str(), 1e-3, 2u8),
        ("patch, stick", stick.as_str(), 1e-7, 1u8),
    ] {
        let case = load(text, dir.path());
        let mut built = case.build().unwrap();
        let dofs = built.dofs();
        let mut u = vec![0.0; dofs.total];
        let params = NewtonParameters {
            max_increment: 0.25,
            ..case.solver.clone()
        };
        let result = solve_quasi_static(
            &mut built.model,
            dofs.clone(),
            &params,
            0.25,
            &[],
            &mut u,
            |_, _| {},
        )
        .unwrap();
        assert_eq!(result.status, RunStatus::Complete, "{name}");
        // A state next to the converged one.
        let mut rng = StdRng::seed_from_u64(3);
        for &d in &dofs.free {
            u[d] += perturbation * rng.random_range(-1.0..1.0);
        }
        let model = &mut built.model;
        let mut assembler = Assembler::new(model, dofs.clone());
        let mut internal = vec![0.0; dofs.total];
        let mut values = vec![0.0; assembler.nnz()];
        let state = State {
            load: 0.25,
            load_fraction: 0.25,
            ..State::at(&u)
        };
        assembler
            .force_tangent(model, &state, &mut internal, &mut values)
            .unwrap();
        let contacts: Vec<u8> = model
            .terms_of::<ncform::model::ToolContact>()
            .flat_map(|t| t.node_contacts().iter().map(|c| c.status))
            .filter(|s| *s > 0)
            .collect();
        // The random perturbation turns a few sliding nodes back into stick;
        // most must be in the status under test.
        let share =
            contacts.iter().filter(|s| **s == status).count() as f64 / contacts.len().max(1) as f64;
        assert!(
            !contacts.is_empty() && share >= 0.8,
            "{name}: statuses {contacts:?}"
        );
        let n = dofs.n_free();
        let (col_ptr, row_idx) = (assembler.symbolic.col_ptr(), assembler.symbolic.row_idx());
        for _ in 0..3 {
            let v: Vec<f64> = (0..n).map(|_| rng.random_range(-1.0..1.0)).collect();
            let mut kv = vec![0.0; n];
            for j in 0..n {
                for k in col_ptr[j]..col_ptr[j + 1] {
                    kv[row_idx[k]] += values[k] * v[j];
                }
            }
            let residual = |s: f64| {
                let model = &mut *model;
                let mut w = u.clone();
                for (k, &d) in dofs.free.iter().enumerate() {
                    w[d] += s * v[k];
                }
                let mut f = vec![0.0; dofs.total];
                let state = State {
                    load: 0.25,
                    load_fraction: 0.25,
                    ..State::at(&w)
                };
                Assembler::new(model, dofs.clone())
                    .force(model, &state, &mut f)
                    .unwrap();
                DVector::from_iterator(n, dofs.free.iter().map(|&d| f[d]))
            };
            let (fd, tol) = central_difference(residual, 0.1 * perturbation.min(1e-5));
            let error = (DVector::from_vec(kv) - &fd).norm();
            assert!(
                error <= tol.max(1e-9 * fd.norm()),
                "{name}: |Kv − FD| = {error:e}, tolerance {tol:e}, |FD| = {:e}",
                fd.norm()
            );
        }
    }
}
