//! Every set-up check before the run folder is touched, `ncform check`,
//! the resolved case with its provenance in every run folder, and the
//! forming `[output] maps` switch (docs/cases.md, "The run folder",
//! "Checking a case", "Forming cases"). The cases are coarse (15 mm OAT
//! elements, the friction patch at 5 mm): each run takes well under a
//! second.

use std::collections::BTreeMap;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use ncform::case::Case;
use ncform::material::MaterialSpec;
use ncform::report::estimate::{Estimate, ModelSize};
use ncform::report::provenance::{GIT_COMMIT, RESOLVED_CASE_FILE, sha256_hex};
use ncform::report::{SolverEstimate, prepare};
use serde_json::Value;
use tempfile::TempDir;

/// A coarse 45° OAT, explicit, to 5 mm with a VTU at 2.5 mm.
const OAT: &str = r#"title = "coarse explicit OAT"
solver = "explicit"

[specimen]
width = 100.0
length = 300.0
bias_angle_deg = 45.0

[mesh]
element_size = 15.0

[material]
params = "fabric.toml"
thickness = 0.3
areal_mass = 0.30

[loading]
displacement = 5.0
output_displacements = [2.5]
"#;

/// The friction patch of cases/verification at 5 mm elements, with `edit`
/// applied to its text (`(from, to)`), written into `dir`.
fn patch(dir: &Path, edit: (&str, &str)) -> PathBuf {
    let source =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/verification/friction-patch.toml");
    let text =
        fs::read_to_string(source)
            .unwrap()
            .replacen("element_size = 2.5", "element_size = 5.0", 1);
    assert!(text.contains(edit.0), "the patch has no '{}'", edit.0);
    let path = dir.join("patch.toml");
    fs::write(&path, text.replacen(edit.0, edit.1, 1)).unwrap();
    path
}

/// The OAT case with `edit` applied, and its parameter file, in `dir`.
fn oat(dir: &Path, edit: (&str, &str)) -> PathBuf {
    fs::write(
        dir.join("fabric.toml"),
        MaterialSpec::named_text("schaefer2024").unwrap(),
    )
    .unwrap();
    assert!(OAT.contains(edit.0), "the OAT has no '{}'", edit.0);
    let path = dir.join("oat.toml");
    fs::write(&path, OAT.replacen(edit.0, edit.1, 1)).unwrap();
    path
}

/// `ncform <args>` in `cwd`.
fn ncform(cwd: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_ncform"))
        .args(args)
        .current_dir(cwd)
        .output()
        .unwrap()
}

fn text_of(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

/// Every file under `dir` (relative, `/`-separated) with its content.
fn contents(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut found = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path
                    .strip_prefix(dir)
                    .unwrap()
                    .to_string_lossy()
                    .replace('\\', "/");
                found.insert(rel, fs::read(&path).unwrap());
            }
        }
    }
    found
}

/// The entries of `dir` (names).
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

/// A run whose solver cannot be set up fails naming the key to change,
/// with exit 1, and leaves the earlier run in its folder as it was: not
/// moved aside, not marked failed, no file added or changed.
fn assert_set_up_failure_leaves_the_earlier_run(
    dir: &Path,
    good: &Path,
    bad: &Path,
    keys: &[&str],
) {
    let out = dir.join("out");
    let first = ncform(
        dir,
        &["run", good.to_str().unwrap(), "--out", "out", "--quiet"],
    );
    assert_eq!(first.status.code(), Some(0), "{}", text_of(&first.stderr));
    let before = contents(&out);
    let before_entries = entries(dir);
    let failed = ncform(
        dir,
        &["run", bad.to_str().unwrap(), "--out", "out", "--quiet"],
    );
    let stderr = text_of(&failed.stderr);
    assert_eq!(failed.status.code(), Some(1), "{stderr}");
    for key in keys {
        assert!(stderr.contains(key), "the error names no '{key}': {stderr}");
    }
    assert_eq!(
        entries(dir),
        before_entries,
        "nothing moved aside or added beside"
    );
    assert!(contents(&out) == before, "the earlier run's files changed");
}

#[test]
fn an_explicit_set_up_failure_leaves_the_earlier_run_untouched_and_names_the_key() {
    let dir = TempDir::new().unwrap();
    let good = oat(dir.path(), ("", ""));
    let bad_dir = dir.path().join("bad");
    fs::create_dir(&bad_dir).unwrap();
    // Far more increments than allowed: refused from the first stable step.
    let bad = oat(
        &bad_dir,
        ("[loading]", "[explicit]\nmax_increments = 10\n\n[loading]"),
    );
    assert_set_up_failure_leaves_the_earlier_run(
        dir.path(),
        &good,
        &bad,
        &[
            "explicit.max_increments",
            "explicit.duration",
            "explicit.mass_scaling_time_step",
        ],
    );
}

#[test]
fn a_term_failing_at_the_start_names_the_ply_and_its_keys() {
    let dir = TempDir::new().unwrap();
    let bad = patch(
        dir.path(),
        (
            "thickness = 0.3\n",
            "thickness = 0.3\nareal_mass = 1e-300\n",
        ),
    );
    // The explicit solver instead of the Newton knobs.
    let text = fs::read_to_string(&bad).unwrap();
    let (head, rest) = text.split_once("[solver]").unwrap();
    let (_, tail) = rest.split_once("[[ply]]").unwrap();
    fs::write(&bad, format!("solver = \"explicit\"\n{head}[[ply]]{tail}")).unwrap();
    let failed = ncform(
        dir.path(),
        &["run", "patch.toml", "--out", "out", "--quiet"],
    );
    let stderr = text_of(&failed.stderr);
    assert_eq!(failed.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("areal_mass"), "{stderr}");
    if stderr.contains("explicit solver") {
        // The solver's own message, with the hint of the case keys.
        assert!(
            stderr.contains("[[ply]]") && stderr.contains("\"patch\""),
            "{stderr}"
        );
    }
    assert!(
        !dir.path().join("out").exists(),
        "a folder was made for a case that cannot run"
    );
}

#[test]
fn a_quasi_static_set_up_failure_leaves_the_earlier_run_untouched() {
    let dir = TempDir::new().unwrap();
    let good = patch(dir.path(), ("", ""));
    let bad_dir = dir.path().join("bad");
    fs::create_dir(&bad_dir).unwrap();
    // LDLᵀ asked for a frictional (unsymmetric) tangent.
    let bad = patch(&bad_dir, ("[solver]", "[solver]\nlinear_solver = \"ldlt\""));
    assert_set_up_failure_leaves_the_earlier_run(dir.path(), &good, &bad, &["linear_solver"]);
}

#[test]
fn check_prints_the_estimate_and_touches_no_folder() {
    let dir = TempDir::new().unwrap();
    let case = oat(dir.path(), ("", ""));
    let before = entries(dir.path());
    let done = ncform(dir.path(), &["check", case.to_str().unwrap()]);
    let stdout = text_of(&done.stdout);
    assert_eq!(done.status.code(), Some(0), "{}", text_of(&done.stderr));
    assert!(stdout.contains("explicit solver"), "{stdout}");
    assert!(
        stdout.contains("estimate: about") && stdout.contains("increments"),
        "{stdout}"
    );
    assert!(stdout.contains("rough estimate"), "{stdout}");
    assert!(stdout.contains("estimate: outputs about"), "{stdout}");
    assert_eq!(entries(dir.path()), before, "check wrote something");

    // Bad input: exit 1, as run, and still nothing written.
    let bad = oat(
        dir.path(),
        ("[loading]", "[explicit]\nmax_increments = 10\n\n[loading]"),
    );
    let failed = ncform(dir.path(), &["check", bad.to_str().unwrap()]);
    assert_eq!(failed.status.code(), Some(1));
    assert!(text_of(&failed.stderr).contains("explicit.max_increments"));
    assert_eq!(entries(dir.path()), before, "check wrote something");
}

#[test]
fn the_estimate_counts_the_explicit_increments_from_the_first_step() {
    let dir = TempDir::new().unwrap();
    let case = Case::load(&oat(dir.path(), ("", ""))).unwrap();
    let prepared = prepare(&case).unwrap_or_else(|e| panic!("{e}"));
    let SolverEstimate::Explicit(e) = prepared.solver_estimate() else {
        panic!("an explicit case");
    };
    assert!(e.time_step > 0.0 && e.time_step <= e.initial_critical_time_step);
    assert_eq!(
        e.increments,
        (e.duration / e.time_step).ceil() + e.outputs as f64
    );
    // The run takes about as many increments as estimated (the step
    // changes on the way).
    let out = dir.path().join("out");
    let run = ncform(dir.path(), &["run", "oat.toml", "--out", "out"]);
    assert_eq!(run.status.code(), Some(0));
    assert!(
        text_of(&run.stderr).contains("estimate: about"),
        "run prints the estimate first"
    );
    let summary: Value =
        serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let taken = summary["explicit"]["increments"].as_f64().unwrap();
    assert!(
        taken > 0.5 * e.increments && taken < 2.0 * e.increments,
        "{taken} increments against {} estimated",
        e.increments
    );
}

#[test]
fn outputs_that_dwarf_the_solve_are_warned_of_with_the_keys() {
    let dir = TempDir::new().unwrap();
    let case = Case::load(&patch(dir.path(), ("", ""))).unwrap();
    let prepared = prepare(&case).unwrap_or_else(|e| panic!("{e}"));
    let small = prepared.estimate();
    assert_eq!(small.output_warning(), None, "a tiny run warned");
    // The same estimate at a paper-size mesh with 10,000 states.
    let model = ModelSize {
        elements: 14_112,
        nodes: 7_225,
        ..small.model
    };
    let big = Estimate::new(&case, small.solver, model);
    let mut many = case.clone();
    if let Case::Forming(c) = &mut many {
        c.states = (1..=10_000).map(|k| k as f64 / 1e4).collect();
    }
    let big_many = Estimate::new(&many, big.solver, model);
    let warning = big_many.output_warning().expect("a warning");
    assert!(warning.contains("maps = false"), "{warning}");
    assert!(big_many.output_bytes > 1e10, "{}", big_many.output_bytes);
}

#[test]
fn every_run_folder_holds_the_resolved_case_and_the_hashes_of_its_inputs() {
    let dir = TempDir::new().unwrap();
    let case = oat(dir.path(), ("", ""));
    let done = ncform(dir.path(), &["run", "oat.toml", "--out", "out", "--quiet"]);
    assert_eq!(done.status.code(), Some(0), "{}", text_of(&done.stderr));
    let out = dir.path().join("out");
    let resolved: Value =
        serde_json::from_str(&fs::read_to_string(out.join(RESOLVED_CASE_FILE)).unwrap()).unwrap();
    let provenance = &resolved["provenance"];
    assert_eq!(provenance["ncform_version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(provenance["git_commit"], GIT_COMMIT);
    assert!(!GIT_COMMIT.is_empty());
    let inputs = provenance["inputs"].as_array().unwrap();
    let hash_of = |role: &str| {
        inputs
            .iter()
            .find(|i| i["role"] == role)
            .unwrap_or_else(|| panic!("no input '{role}': {inputs:?}"))["sha256"]
            .as_str()
            .unwrap()
            .to_string()
    };
    assert_eq!(hash_of("case file"), sha256_hex(&fs::read(&case).unwrap()));
    assert_eq!(
        hash_of("parameter file"),
        sha256_hex(&fs::read(dir.path().join("fabric.toml")).unwrap())
    );
    // SHA-256 itself: the empty input's known digest.
    assert_eq!(
        sha256_hex(b""),
        "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"
    );
    // Defaults filled in.
    let c = &resolved["case"];
    assert_eq!(c["scenario"], "oat");
    assert_eq!(c["explicit"]["max_increments"], 10_000_000);
    assert!(c["explicit"]["duration"].as_f64().unwrap() > 0.0, "{c}");
    assert_eq!(c["displacement"], 5.0);
    // In the manifest like every output.
    let status: Value =
        serde_json::from_str(&fs::read_to_string(out.join("status.json")).unwrap()).unwrap();
    assert!(
        status["files"]
            .as_array()
            .unwrap()
            .iter()
            .any(|f| f["path"] == RESOLVED_CASE_FILE),
        "{status}"
    );
}

#[test]
fn maps_can_be_switched_off() {
    let dir = TempDir::new().unwrap();
    let on = patch(dir.path(), ("", ""));
    let done = ncform(
        dir.path(),
        &["run", on.to_str().unwrap(), "--out", "on", "--quiet"],
    );
    assert_eq!(done.status.code(), Some(0), "{}", text_of(&done.stderr));
    let pngs = |out: &Path| {
        contents(out)
            .keys()
            .filter(|k| k.starts_with("maps/"))
            .count()
    };
    let vtus = |out: &Path| contents(out).keys().filter(|k| k.ends_with(".vtu")).count();
    let on_out = dir.path().join("on");
    assert!(pngs(&on_out) > 0, "the maps are on by default");

    let off = patch(dir.path(), ("[output]", "[output]\nmaps = false"));
    let done = ncform(
        dir.path(),
        &["run", off.to_str().unwrap(), "--out", "off", "--quiet"],
    );
    assert_eq!(done.status.code(), Some(0), "{}", text_of(&done.stderr));
    let off_out = dir.path().join("off");
    assert_eq!(pngs(&off_out), 0, "maps written with maps = false");
    assert!(!off_out.join("maps").exists(), "an empty maps/ folder");
    assert_eq!(
        vtus(&off_out),
        vtus(&on_out),
        "the fields are written all the same"
    );
    let resolved: Value =
        serde_json::from_str(&fs::read_to_string(off_out.join(RESOLVED_CASE_FILE)).unwrap())
            .unwrap();
    assert_eq!(resolved["case"]["output"]["maps"], false);
}

#[test]
fn the_explicit_set_up_hints_name_the_keys_of_what_failed() {
    use ncform::model::TermFailure;
    use ncform::report::explicit_hint;
    use ncform::solver::explicit::{ExplicitError, SetupError};
    let term = |name: &str| {
        ExplicitError::Term(TermFailure {
            term: name.into(),
            what: "node",
            index: 0,
            reason: "c·4m/Δt² overflows".into(),
        })
    };
    let hint = |error: &ExplicitError, plies: &[&str]| explicit_hint(error, plies).unwrap();
    let contact = hint(&term("contact with table"), &["ply"]);
    assert!(
        contact.contains("[contact] offset") && contact.contains("explicit_stiffness"),
        "{contact}"
    );
    let ply = hint(&term("bending of upper"), &["lower", "upper"]);
    assert!(
        ply.contains("ply \"upper\"") && ply.contains("areal_mass"),
        "{ply}"
    );
    let only = hint(&term("membrane"), &["blank"]);
    assert!(only.contains("ply \"blank\""), "{only}");
    let oat = hint(&term("membrane"), &[]);
    assert!(oat.contains("[material] areal_mass"), "{oat}");
    let coupling = ExplicitError::Setup(SetupError::MassCoupling {
        node: 0,
        reason: "a cycle".into(),
    });
    assert!(hint(&coupling, &["ply"]).contains("explicit.roving_mass_length"));
    let massless = ExplicitError::Setup(SetupError::MasslessNode { node: 3 });
    assert!(hint(&massless, &["ply"]).contains("[[boundary]]"));
}
