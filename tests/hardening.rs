//! Regression tests of the numeric guards and work limits
//! (`docs/robustness.md`): values that overflow the law, absurd settings
//! and estimates of work are refused or end the run incomplete with a
//! message — never a panic, an abort, a hang or a non-finite result.

use std::fs;
use std::path::{Path, PathBuf};
use std::sync::mpsc;
use std::thread;
use std::time::Duration;

use ncform::case::OatCase;
use ncform::case::forming::FormingCase;
use ncform::cli::material_curves::write_curves;
use ncform::material::{GeneralizedTerm, Material, MaterialSpec, OrthotropicSvk, Transition};
use ncform::post::plot::{Panel, Series, write_panels};
use ncform::report::Progress;
use ncform::report::files::run_case;
use ncform::report::oat::RunSummary;
use ncform::solver::RunStatus;
use serde_json::Value;
use tempfile::TempDir;

/// A coarse 45° OAT: 100 × 300 mm, 20 mm elements, pulled to 40 mm.
const BASE: &str = r#"title = "coarse 45° OAT"

[specimen]
width = 100.0
length = 300.0
bias_angle_deg = 45.0

[mesh]
element_size = 20.0

[material]
params = "schaefer2024"

[loading]
displacement = 40.0
"#;

/// The same, explicit, with the paper fabric's areal mass.
fn explicit_base(extra: &str) -> String {
    BASE.replace(
        "params = \"schaefer2024\"",
        "params = \"schaefer2024\"\nareal_mass = 0.30",
    )
    .replace("title =", "solver = \"explicit\"\ntitle =")
        + "\n[explicit]\n"
        + extra
}

fn edit(base: &str, from: &str, to: &str) -> String {
    assert!(base.contains(from), "`{from}` not in the case text");
    base.replacen(from, to, 1)
}

fn write(path: &Path, text: &str) -> PathBuf {
    fs::write(path, text).unwrap();
    path.to_path_buf()
}

fn load(dir: &Path, text: &str) -> Result<OatCase, String> {
    let path = write(&dir.join("case.toml"), text);
    OatCase::load(&path).map_err(|e| e.to_string())
}

fn assert_mentions(msg: &str, parts: &[&str]) {
    for p in parts {
        assert!(msg.contains(p), "message `{msg}` lacks `{p}`");
    }
}

/// Runs `f` on a thread and fails the test if it takes longer than
/// `seconds` (a hang is a failure, not a stuck CI job).
fn within<T: Send + 'static>(seconds: u64, f: impl FnOnce() -> T + Send + 'static) -> T {
    let (tx, rx) = mpsc::channel();
    thread::spawn(move || {
        let _ = tx.send(f());
    });
    rx.recv_timeout(Duration::from_secs(seconds))
        .unwrap_or_else(|_| panic!("did not finish within {seconds} s"))
}

/// Every number in `value` is finite (JSON has no NaN or inf: serde_json
/// writes them as `null`, which is caught here too).
fn assert_finite_json(value: &Value, path: &str) {
    match value {
        Value::Null => panic!("null (a non-finite number?) at {path}"),
        Value::Number(n) => assert!(n.as_f64().is_some_and(f64::is_finite), "{path}: {n}"),
        Value::Array(items) => {
            for (i, v) in items.iter().enumerate() {
                assert_finite_json(v, &format!("{path}[{i}]"));
            }
        }
        Value::Object(map) => {
            for (k, v) in map {
                // Optional settings and absent figures are legitimately null.
                if !v.is_null() {
                    assert_finite_json(v, &format!("{path}.{k}"));
                }
            }
        }
        _ => {}
    }
}

fn run(case: OatCase, out: PathBuf) -> Result<RunSummary, String> {
    within(120, move || {
        run_case(&case, &out, Progress::Quiet).map_err(|e| e.to_string())
    })
}

/// A parameter file: the named default set with one line replaced.
fn params_file(dir: &Path, from: &str, to: &str) -> PathBuf {
    let text = MaterialSpec::named_text("schaefer2024").unwrap();
    write(&dir.join("fabric.toml"), &edit(text, from, to))
}

fn svk_file(dir: &Path, e1: &str, g12: &str) -> PathBuf {
    write(
        &dir.join("svk.toml"),
        &format!(
            "law = \"orthotropic-svk\"\n[svk]\ne1 = {e1}\ne2 = 5.0\nnu12 = 0.3\ng12 = {g12}\n"
        ),
    )
}

/// The default set with `w6.c_mid` = 1.7e308, built in code: a parameter
/// file refuses magnitudes above 1e12 (`docs/parameters.md`), and these
/// tests check the solvers' own guards behind that check.
fn overflowing_udncf() -> MaterialSpec {
    let mut spec = MaterialSpec::default_set();
    let Material::UdNcf(law) = &mut spec.material else {
        panic!("the default set is a UD-NCF law");
    };
    let w6 = law.w6;
    let transition = w6.transition.map(|t| Transition {
        c_mid: 1.7e308,
        ..t
    });
    law.w6 = GeneralizedTerm::new(w6.c_ini, transition, w6.lock);
    spec.source = "fabric.toml".into();
    spec
}

/// An SVK law built in code (see [`overflowing_udncf`]).
fn svk_spec(e1: f64, g12: f64) -> MaterialSpec {
    MaterialSpec {
        name: "svk".into(),
        description: String::new(),
        source: "svk.toml".into(),
        material: Material::OrthotropicSvk(OrthotropicSvk {
            e1,
            e2: 5.0,
            nu12: 0.3,
            g12,
        }),
    }
}

fn incomplete_reason(summary: &RunSummary) -> &str {
    match &summary.status {
        RunStatus::Incomplete { reason, .. } => reason,
        other => panic!("expected an incomplete run, got {other:?}"),
    }
}

/// A modulus near f64::MAX (accepted by the parameter checks) overflows the
/// shear stress part-way: the line search must not panic on a NaN bracket,
/// the step must not be taken as converged, and the run stops incomplete
/// with finite results up to the last converged step.
#[test]
fn an_overflowing_law_ends_the_run_incomplete_with_finite_results() {
    let dir = TempDir::new().unwrap();
    params_file(dir.path(), "c_mid = 0.01", "c_mid = 1.7e308");
    let from_file = load(
        dir.path(),
        &edit(
            BASE,
            "params = \"schaefer2024\"",
            "params = \"fabric.toml\"",
        ),
    )
    .unwrap_err();
    assert_mentions(&from_file, &["fabric.toml", "w6.c_mid = 1.7e308"]);
    let mut case = load(dir.path(), BASE).unwrap();
    case.material = overflowing_udncf();
    let out = dir.path().join("out");
    let summary = run(case, out.clone()).expect("a set-up that runs");
    assert!(!summary.complete);
    assert_mentions(incomplete_reason(&summary), &["non-finite"]);
    let text = fs::read_to_string(out.join("summary.json")).unwrap();
    assert_finite_json(
        &serde_json::from_str::<Value>(&text).unwrap()["history"],
        "history",
    );
    let csv = fs::read_to_string(out.join("force_displacement.csv")).unwrap();
    let rows: Vec<&str> = csv
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .collect();
    assert!(!rows.is_empty(), "the converged steps are kept");
    for row in rows {
        for cell in row.split(',') {
            let x: f64 = cell
                .parse()
                .unwrap_or_else(|_| panic!("`{cell}` in `{row}`"));
            assert!(
                x.is_finite(),
                "non-finite `{cell}` in force_displacement.csv"
            );
        }
    }
}

/// An SVK law stiff enough to overflow the forces at the first step: no
/// step is accepted (∞ ≤ tol·∞ is not convergence).
#[test]
fn overflowed_forces_are_never_a_converged_step() {
    let dir = TempDir::new().unwrap();
    svk_file(dir.path(), "50.0", "1e300");
    let from_file = load(
        dir.path(),
        &edit(BASE, "params = \"schaefer2024\"", "params = \"svk.toml\""),
    )
    .unwrap_err();
    assert_mentions(&from_file, &["svk.toml", "svk.g12 = 1e300"]);
    let mut case = load(dir.path(), BASE).unwrap();
    case.material = svk_spec(50.0, 1e300);
    let summary = run(case, dir.path().join("out")).expect("a set-up that runs");
    assert_eq!(summary.steps, 0, "an overflowed step was accepted");
    assert_mentions(incomplete_reason(&summary), &["non-finite"]);
}

/// The history rows of an explicit run are bounded where the key enters
/// (before: `history_interval = 1e-9` aborted on the allocation).
#[test]
fn explicit_history_rows_are_bounded() {
    let dir = TempDir::new().unwrap();
    let err = load(dir.path(), &explicit_base("history_interval = 1e-9\n")).unwrap_err();
    assert_mentions(
        &err,
        &[
            "case.toml:",
            "explicit.history_interval = 1e-9",
            "history rows",
        ],
    );
}

/// A time step that asks for more increments than the limit is refused
/// before the run starts, naming the key that raises the limit; a run that
/// reaches the limit later stops there, incomplete, with what it computed.
#[test]
fn explicit_work_is_estimated_and_limited() {
    let dir = TempDir::new().unwrap();
    let case = load(dir.path(), &explicit_base("time_step = 1e-12\n")).unwrap();
    let err = run(case, dir.path().join("tiny-step")).unwrap_err();
    assert_mentions(&err, &["increments", "explicit.max_increments"]);

    let case = load(dir.path(), &explicit_base("max_increments = 0\n")).unwrap_err();
    assert_mentions(&case, &["explicit.max_increments = 0"]);

    // Half the increments the coarse run takes: refused at once if the
    // first step's estimate already exceeds it, else stopped at the limit.
    let case = load(dir.path(), &explicit_base("")).unwrap();
    let full = run(case, dir.path().join("full")).unwrap();
    let increments = full.explicit.as_ref().unwrap().increments;
    assert!(full.complete);
    let limit = increments / 2;
    let case = load(
        dir.path(),
        &explicit_base(&format!(
            "max_increments = {limit}\ntime_step_update_interval = 1\n"
        )),
    )
    .unwrap();
    match run(case, dir.path().join("limited")) {
        // The estimate from the first step already exceeds the limit.
        Err(e) => assert_mentions(&e, &["explicit.max_increments"]),
        Ok(s) => {
            assert!(!s.complete);
            assert_mentions(incomplete_reason(&s), &["explicit.max_increments"]);
            assert!(s.explicit.as_ref().unwrap().increments <= limit);
        }
    }
}

/// Absurd strokes and meshes are refused where the value enters.
#[test]
fn absurd_displacements_and_meshes_are_refused() {
    let dir = TempDir::new().unwrap();
    let err = load(
        dir.path(),
        &edit(BASE, "displacement = 40.0", "displacement = 1e9"),
    )
    .unwrap_err();
    assert_mentions(&err, &["loading.displacement = 1000000000", "free length"]);

    // One cell across a 1 µm wide 45° strip would be 600,000 triangles.
    let case = load(dir.path(), &edit(BASE, "width = 100.0", "width = 1e-3")).unwrap();
    let err = within(30, move || case.build().err().map(|e| e.to_string()))
        .expect("the mesh must be refused");
    assert_mentions(
        &err,
        &["[mesh] element_size = 20", "triangles", "nx and ny"],
    );
}

/// Clamp sets of a mesh file must be non-empty and disjoint.
#[test]
fn clamp_sets_must_be_non_empty_and_disjoint() {
    let dir = TempDir::new().unwrap();
    let sample = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/meshes/square.inp");
    let mesh = fs::read_to_string(sample).unwrap() + "*NSET, NSET=empty\n";
    write(&dir.path().join("square.inp"), &mesh);
    let with_sets = |sets: &str| {
        edit(
            BASE,
            "element_size = 20.0",
            &format!("file = \"square.inp\"\n{sets}"),
        )
    };
    let case = load(dir.path(), &with_sets("moving_clamp_set = \"all\"")).unwrap();
    let Err(err) = case.build().map_err(|e| e.to_string()) else {
        panic!("overlapping clamps accepted")
    };
    assert_mentions(&err, &["case.toml", "both sets", "\"all\""]);
    match load(dir.path(), &with_sets("fixed_clamp_set = \"empty\"")) {
        Err(e) => assert_mentions(&e, &["empty"]),
        Ok(case) => {
            let Err(err) = case.build().map_err(|e| e.to_string()) else {
                panic!("an empty clamp accepted")
            };
            assert_mentions(&err, &["mesh.fixed_clamp_set = \"empty\"", "is empty"]);
        }
    }
}

/// A title heads every output file: one line only, in OAT and forming cases.
#[test]
fn multi_line_titles_are_refused() {
    let dir = TempDir::new().unwrap();
    let err = load(
        dir.path(),
        &edit(
            BASE,
            "title = \"coarse 45° OAT\"",
            "title = \"line one\\nline two\"",
        ),
    )
    .unwrap_err();
    assert_mentions(&err, &["case.toml:1:", "title", "one line"]);

    let forming = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/verification/capstan.toml");
    let text = fs::read_to_string(&forming).unwrap();
    let text = match text.find("title = ") {
        Some(_) => {
            let line = text.lines().find(|l| l.starts_with("title = ")).unwrap();
            text.replacen(line, "title = \"a\\rb\"", 1)
        }
        None => format!("title = \"a\\rb\"\n{text}"),
    };
    let path = write(&dir.path().join("forming.toml"), &text);
    let Err(err) = FormingCase::load(&path) else {
        panic!("a two-line forming title accepted")
    };
    let err = err.to_string();
    assert_mentions(&err, &["forming.toml:", "title", "one line"]);
}

/// A stroke far too fast for the fabric to follow is flagged as not
/// quasi-static: the clamp nodes' kinetic energy counts (before, only the
/// free nodes did, and they had not yet moved: KE/IE read 0 %).
#[test]
fn a_stroke_too_fast_to_follow_is_not_quasi_static() {
    let dir = TempDir::new().unwrap();
    let case = load(dir.path(), &explicit_base("duration = 1e-9\n")).unwrap();
    let summary = run(case, dir.path().join("out")).unwrap();
    let figures = summary.explicit.as_ref().unwrap();
    assert!(
        figures.max_kinetic_ratio > 1.0,
        "KE/IE {}",
        figures.max_kinetic_ratio
    );
    assert!(
        figures
            .warnings
            .iter()
            .any(|w| w.contains("not quasi-static")),
        "{:?}",
        figures.warnings
    );
}

/// A vanishing areal mass, whose element frequencies overflowed (before:
/// a panic in a worker; then a refusal naming the element at set-up), is
/// refused where it enters, with its range (`docs/cases.md`, "Ranges").
#[test]
fn an_overflowing_element_frequency_is_named() {
    let dir = TempDir::new().unwrap();
    let text = explicit_base("").replace("areal_mass = 0.30", "areal_mass = 1e-300");
    let err = load(dir.path(), &text).unwrap_err();
    assert_mentions(
        &err,
        &["material.areal_mass = 1e-300", "[1e-4, 1000] kg/m²"],
    );
}

/// `material curves` refuses a set that overflows in the plotted range and
/// writes nothing (before: exit 0 with inf in the CSVs).
#[test]
fn material_curves_refuse_an_overflowing_set() {
    let dir = TempDir::new().unwrap();
    let spec = overflowing_udncf();
    let out = dir.path().join("curves");
    let err = write_curves(&spec, &out).unwrap_err();
    assert_mentions(
        &err.to_string(),
        &["fabric.toml", "[w6]", "nothing written"],
    );
    assert!(!out.exists());
}

/// Plots of values up to ±f64::MAX, and of infinities, finish.
#[test]
fn plots_of_extreme_values_finish() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("extreme.png");
    let panel = Panel {
        title: "extreme".into(),
        x_label: "x".into(),
        y_label: "y".into(),
        series: vec![Series {
            label: "s".into(),
            points: vec![
                (0.0, -f64::MAX),
                (1.0, f64::MAX),
                (2.0, f64::INFINITY),
                (f64::NAN, 0.0),
            ],
        }],
    };
    let written = path.clone();
    within(30, move || {
        write_panels(&written, &[panel], (1, 1), (400, 300))
    })
    .unwrap();
    assert!(path.exists());
}

/// A forming case in `cases/verification/` with one line replaced, written
/// next to the original (its relative paths stay valid) and loaded.
fn forming_variant(dir: &Path, case: &str, from: &str, to: &str) -> Result<FormingCase, String> {
    let source = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("cases/verification")
        .join(case);
    let text = edit(&fs::read_to_string(&source).unwrap(), from, to);
    let path = write(&dir.join(case), &text);
    FormingCase::load(&path).map_err(|e| e.to_string())
}

/// A slender drawn tool (a cylinder of 1e-30 mm radius) builds without
/// asking for more drawing pieces than memory holds (before: a capacity
/// overflow panic); an absurd drawn extent is refused at its key.
#[test]
fn drawn_tools_stay_bounded() {
    let dir = TempDir::new().unwrap();
    let case = forming_variant(
        dir.path(),
        "capstan.toml",
        "radius = 50.0",
        "radius = 1e-30",
    )
    .unwrap();
    within(60, move || case.build().map(|_| ()))
        .unwrap_or_else(|e| panic!("the slender cylinder should build: {e}"));
    let err = forming_variant(
        dir.path(),
        "capstan.toml",
        "extent = 20.0",
        "extent = 1e308",
    )
    .unwrap_err();
    assert_mentions(&err, &["capstan.toml:", "extent = 1e308", "(0, 1e6]"]);
}

/// KE/IE stays finite when the stored energy is denormal (found by the
/// solver fuzz: `max_kinetic_ratio: inf`).
#[test]
fn the_kinetic_ratio_is_finite_over_a_denormal_internal_energy() {
    let energies = ncform::solver::explicit::Energies {
        internal: 5e-324,
        kinetic: 1.0,
        ..Default::default()
    };
    let ratio = energies.kinetic_ratio();
    assert!(ratio.is_finite() && ratio > 1.0, "{ratio}");
}

/// `material curves`: a set that cannot be drawn is bad input (exit 1), a
/// folder that cannot be written is a write failure (exit 5), as the
/// documented exit codes say.
#[test]
fn material_curves_exit_codes_tell_bad_input_from_write_failures() {
    let dir = TempDir::new().unwrap();
    let curves = |params: &str, out: &Path| {
        std::process::Command::new(env!("CARGO_BIN_EXE_ncform"))
            .args(["material", "curves", "--params", params, "--out"])
            .arg(out)
            .output()
            .unwrap()
    };
    let svk = svk_file(dir.path(), "50.0", "1.0");
    let bad = curves(&svk.display().to_string(), &dir.path().join("a"));
    assert_eq!(
        bad.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&bad.stderr)
    );
    // A file where the folder should be: the folder cannot be made, even
    // by root.
    let blocked = write(&dir.path().join("blocked"), "not a folder");
    let failed = curves("schaefer2024", &blocked);
    assert_eq!(
        failed.status.code(),
        Some(5),
        "{}",
        String::from_utf8_lossy(&failed.stderr)
    );
    assert!(String::from_utf8_lossy(&failed.stderr).contains("blocked"));
}

/// A stroke in 1e-308 s: the clamp nodes' kinetic energy overflows; the
/// run stops incomplete instead of reporting an infinite energy (found by
/// the solver fuzz at seed 11).
#[test]
fn an_overflowing_kinetic_energy_ends_the_run_incomplete() {
    let dir = TempDir::new().unwrap();
    let case = load(dir.path(), &explicit_base("clamp_speed = 1e308\n")).unwrap();
    match run(case, dir.path().join("out")) {
        Err(e) => assert_mentions(&e, &["clamp_speed"]),
        Ok(summary) => {
            assert!(!summary.complete);
            assert_mentions(incomplete_reason(&summary), &["kinetic energy overflows"]);
            let json = serde_json::to_value(&summary).unwrap();
            assert_finite_json(&json["history"], "history");
            let last = &json["explicit"]["final_energies"];
            if !last.is_null() {
                assert_finite_json(last, "explicit.final_energies");
            }
            let ratio = summary.explicit.as_ref().unwrap().max_kinetic_ratio;
            assert!(ratio.is_finite(), "max_kinetic_ratio {ratio}");
        }
    }
}

/// Requirement: a closed stdout (`ncform material params | head -0`) is
/// not a panic: the command still succeeds (its output has nowhere to go;
/// a run's results are on disk). The pipe's read end is closed before the
/// process starts, so every write fails with a broken pipe.
#[test]
fn a_closed_stdout_is_not_a_panic() {
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_ncform"))
        .args(["material", "params"])
        .stdout(writer)
        .stderr(std::process::Stdio::piped())
        .output()
        .expect("ncform starts");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        output.status.success() && !stderr.contains("panicked"),
        "status {:?}, stderr {stderr}",
        output.status
    );
}
