//! Fuzz harness of the readers (`docs/fuzzing.md`): mutants of the
//! repository's real inputs — case files, parameter files, the sample
//! `.inp`/`.msh` meshes, STL/OBJ tool meshes, `material eval` lines — go
//! through the library's readers, each in its own thread with a panic
//! catcher and a time bound. Asserted for every mutant: no panic, an answer
//! within [`BOUND`], either a result with no non-finite number in what was
//! read or an error that names the file (and, for case and parameter files,
//! the key or the line).
//!
//! The bounded run of `cargo test` draws [`DEFAULT_CASES`] mutants per
//! reader from a fixed seed; `NCFORM_FUZZ_CASES=N` raises the count and
//! `NCFORM_FUZZ_SEED=S` changes the seed (the campaign of
//! `docs/fuzzing.md`). The regression tests at the end pin the defects the
//! fuzzing and the hand-made failures found.

mod fuzz_common;

use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;

use fuzz_common::{
    Failure, accepted_non_finite, ascii_stl, binary_stl, cases, guarded, mutate, obj, quiet_panics,
    report, show,
};
use ncform::case::OatCase;
use ncform::case::forming::{FormingCase, is_forming};
use ncform::cli::material_eval;
use ncform::contact::mesh_tool::{MeshOptions, MeshSurface};
use ncform::material::MaterialSpec;
use ncform::mesh::{inp, msh};

/// Mutants per reader in `cargo test`.
const DEFAULT_CASES: usize = 1000;

/// Longest a reader may take on one mutant. Generous (a 2-core machine
/// shared with other builds): the readers take milliseconds, a hang takes
/// forever; no result depends on how fast the machine is.
const BOUND: Duration = Duration::from_secs(20);

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn read(path: &Path) -> Vec<u8> {
    std::fs::read(path).unwrap_or_else(|e| panic!("read {}: {e}", path.display()))
}

/// The `.toml` files of a folder of the repository, sorted.
fn tomls(folder: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(repo().join(folder))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    v.sort();
    v
}

fn is_params(text: &str) -> bool {
    text.lines().any(|l| l.trim_start().starts_with("law"))
}

/// Whether an error message names a place in the file: a line
/// (`file:12:`, `line 12`), or a key (`key = value`, `[table]`).
fn names_place(msg: &str) -> bool {
    let has_line_number = msg
        .match_indices(':')
        .any(|(i, _)| msg[i + 1..].starts_with(|c: char| c.is_ascii_digit()));
    has_line_number || msg.contains("line ") || msg.contains(" = ") || msg.contains('[')
}

/// What is wrong with an error message for `input`: it must name `file`,
/// a place where `place` (a key or a line), and print numbers short.
fn bad_message(msg: &str, file: &str, place: bool, input: &[u8]) -> Option<String> {
    if !msg.contains(file) {
        Some(format!("error does not name the file: {msg}"))
    } else if place && !names_place(msg) {
        Some(format!("error names neither key nor line: {msg}"))
    } else {
        fuzz_common::long_number(msg, input)
            .map(|n| format!("error writes a {}-digit number: {msg}", n.len()))
    }
}

/// How a reader's mutants are drawn.
#[derive(Clone, Copy)]
enum Draw {
    /// Any byte operator ([`mutate`]).
    Any,
    /// Extreme numbers only.
    Numbers,
    /// Wrong value types, moved keys, scaled numbers
    /// ([`fuzz_common::mutate_types`]).
    Types,
}

/// A seed input and the name it is read under.
struct Seed {
    name: String,
    bytes: Vec<u8>,
}

/// Runs `count` mutants spread over `seeds` through `check`, which gets
/// the mutant's bytes and the seed's name and returns what is wrong, if
/// anything; collects the failures.
fn campaign(
    reader: &str,
    seeds: &[Seed],
    count: usize,
    draw: Draw,
    check: impl Fn(Vec<u8>, String, usize) -> Option<String> + Send + Sync + Clone + 'static,
) -> (Vec<Failure>, usize) {
    quiet_panics();
    assert!(!seeds.is_empty(), "{reader}: no seed inputs");
    let mut failures = Vec::new();
    for k in 0..count {
        let seed = &seeds[k % seeds.len()];
        let mut rng = fuzz_common::rng_for(reader, k);
        let (mutant, operators) = match draw {
            Draw::Any => mutate(&seed.bytes, &mut rng, false),
            Draw::Numbers => mutate(&seed.bytes, &mut rng, true),
            Draw::Types => fuzz_common::mutate_types(&seed.bytes, &mut rng),
        };
        let input = mutant.clone();
        let name = seed.name.clone();
        let f = check.clone();
        let outcome = guarded(BOUND, move || f(input, name, k));
        let what = match outcome {
            Ok(None) => continue,
            Ok(Some(what)) => what,
            Err(what) => what,
        };
        failures.push(Failure {
            reader: format!("{reader} ({})", seed.name),
            case: k,
            operators,
            what,
            input: show(&mutant),
        });
    }
    (failures, count)
}

/// A scratch folder for mutants that must be files.
fn scratch() -> &'static Path {
    static DIR: std::sync::OnceLock<tempfile::TempDir> = std::sync::OnceLock::new();
    DIR.get_or_init(|| tempfile::tempdir().unwrap()).path()
}

fn write_scratch(name: &str, bytes: &[u8]) -> PathBuf {
    let path = scratch().join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

// ------------------------------------------------------------ case files

/// A small OAT case on the sample Gmsh mesh, so that mesh-file errors are
/// fuzzed through a case (relative to `cases/`).
const OAT_ON_MESH_FILE: &str = r#"title = "45° OAT on the sample Gmsh mesh"
[specimen]
width = 100.0
length = 300.0
bias_angle_deg = 45.0
[mesh]
file = "meshes/square.msh"
fixed_clamp_set = "bottom"
moving_clamp_set = "top"
[material]
params = "materials/schaefer2024.toml"
thickness = 0.3
[loading]
displacement = 80.0
output_displacements = [20.0, 40.0]
"#;

fn case_seeds() -> Vec<Seed> {
    let mut seeds: Vec<Seed> = tomls("cases")
        .into_iter()
        .chain(tomls("cases/verification"))
        .filter_map(|p| {
            let bytes = read(&p);
            let text = String::from_utf8(bytes.clone()).ok()?;
            (!is_params(&text)).then(|| Seed {
                name: p.display().to_string(),
                bytes,
            })
        })
        .collect();
    seeds.push(Seed {
        name: repo()
            .join("cases/oat-on-mesh-file.toml")
            .display()
            .to_string(),
        bytes: OAT_ON_MESH_FILE.as_bytes().to_vec(),
    });
    seeds
}

/// Forming cases whose model is small enough to build for every mutant
/// (the verification problems); the paper-size benches are parsed and
/// checked only.
fn cheap_to_build(name: &str) -> bool {
    name.contains("verification")
}

/// Reads one case-file mutant the way `ncform run` does (a non-UTF-8 file
/// through `load`, else parse, check and, where cheap, build the model)
/// and says what is wrong with the outcome.
fn check_case(bytes: Vec<u8>, name: String, k: usize) -> Option<String> {
    let path = PathBuf::from(&name);
    let base = path.parent().unwrap().to_path_buf();
    let Ok(text) = String::from_utf8(bytes.clone()) else {
        // Not UTF-8: the file reader must refuse it, naming the file.
        let file = write_scratch(&format!("case-{k}.toml"), &bytes);
        let shown = file.display().to_string();
        return match OatCase::load(&file) {
            Ok(_) => Some("a non-UTF-8 case file was accepted".into()),
            Err(e) => bad_message(&e.to_string(), &shown, true, &bytes),
        };
    };
    let config_error = |e: &dyn std::fmt::Display| bad_message(&e.to_string(), &name, true, &bytes);
    let build_error = |msg: String| bad_message(&msg, &name, false, &bytes);
    if is_forming(&text) {
        let case = match FormingCase::from_toml_str(&text, &name, &base) {
            Ok(case) => case,
            Err(e) => return config_error(&e),
        };
        if let Some(at) = accepted_non_finite(&format!("{case:?}")) {
            return Some(format!("a non-finite value was accepted: {at}"));
        }
        if !cheap_to_build(&name) {
            return None;
        }
        match case.build() {
            Ok(model) => {
                let finite = model.nodes.iter().all(|x| x.iter().all(|c| c.is_finite()));
                (!finite).then(|| "the built model has non-finite nodes".to_string())
            }
            Err(msg) => build_error(msg.to_string()),
        }
    } else {
        let case = match OatCase::from_toml_str(&text, &name, &base) {
            Ok(case) => case,
            Err(e) => return config_error(&e),
        };
        if let Some(at) = accepted_non_finite(&format!("{case:?}")) {
            return Some(format!("a non-finite value was accepted: {at}"));
        }
        match case.build() {
            Ok(model) => {
                let finite = model
                    .mesh
                    .nodes
                    .iter()
                    .all(|x| x.iter().all(|c| c.is_finite()));
                (!finite).then(|| "the built mesh has non-finite nodes".to_string())
            }
            Err(msg) => build_error(msg.to_string()),
        }
    }
}

/// Property: every case-file mutant is read, checked and (where cheap)
/// built without a panic or a hang, and is either accepted with finite
/// values or refused with a message naming the case file and the key or
/// line.
#[test]
fn fuzz_case_files() {
    let seeds = case_seeds();
    let (failures, n) = campaign("case", &seeds, cases(DEFAULT_CASES), Draw::Any, check_case);
    report(&failures, n);
}

/// As [`fuzz_case_files`], with only numeric tokens replaced by extreme
/// values: these pass the TOML parser and reach the value checks and the
/// generators.
#[test]
fn fuzz_case_values() {
    let seeds = case_seeds();
    let (failures, n) = campaign(
        "case-values",
        &seeds,
        cases(DEFAULT_CASES),
        Draw::Numbers,
        check_case,
    );
    report(&failures, n);
}

/// As [`fuzz_case_files`], with values of the wrong type (a number where
/// a string, an array or a table is expected and the other way round, an
/// integer for a float, a bool), keys moved to other tables and numbers
/// scaled far from the seed's.
#[test]
fn fuzz_case_types() {
    let seeds = case_seeds();
    let (failures, n) = campaign(
        "case-types",
        &seeds,
        cases(DEFAULT_CASES),
        Draw::Types,
        check_case,
    );
    report(&failures, n);
}

// ------------------------------------------------------- parameter files

fn param_seeds() -> Vec<Seed> {
    tomls("cases/materials")
        .into_iter()
        .chain(tomls("cases/verification"))
        .filter_map(|p| {
            let bytes = read(&p);
            let text = String::from_utf8(bytes.clone()).ok()?;
            is_params(&text).then(|| Seed {
                name: p.display().to_string(),
                bytes,
            })
        })
        .collect()
}

fn check_params(bytes: Vec<u8>, name: String, k: usize) -> Option<String> {
    let (result, shown) = match String::from_utf8(bytes.clone()) {
        Ok(text) => (MaterialSpec::from_toml_str(&text, &name), name),
        Err(_) => {
            let file = write_scratch(&format!("params-{k}.toml"), &bytes);
            let shown = file.display().to_string();
            (MaterialSpec::load(&shown), shown)
        }
    };
    match result {
        Ok(spec) => accepted_non_finite(&format!("{:?}", spec.material))
            .map(|at| format!("a non-finite parameter was accepted: {at}")),
        Err(e) => bad_message(&e.to_string(), &shown, true, &bytes),
    }
}

/// Property: parameter-file mutants are accepted with finite values or
/// refused naming the file and the key or line.
#[test]
fn fuzz_parameter_files() {
    let (failures, n) = campaign(
        "params",
        &param_seeds(),
        cases(DEFAULT_CASES),
        Draw::Any,
        check_params,
    );
    report(&failures, n);
}

/// As [`fuzz_parameter_files`], with wrong value types, moved keys and
/// scaled numbers ([`fuzz_case_types`]).
#[test]
fn fuzz_parameter_types() {
    let (failures, n) = campaign(
        "params-types",
        &param_seeds(),
        cases(DEFAULT_CASES),
        Draw::Types,
        check_params,
    );
    report(&failures, n);
}

// ---------------------------------------------------------------- meshes

fn check_mesh(bytes: Vec<u8>, name: String, k: usize) -> Option<String> {
    let ext = if name.ends_with(".inp") { "inp" } else { "msh" };
    let file = write_scratch(&format!("mesh-{k}.{ext}"), &bytes);
    let shown = file.display().to_string();
    let result = if ext == "inp" {
        inp::read_inp(&file)
    } else {
        msh::read_msh(&file)
    };
    match result {
        Ok(mesh) => {
            if let Err(e) = mesh.check() {
                return Some(format!("a mesh that fails its own check was returned: {e}"));
            }
            let finite = mesh.nodes.iter().all(|x| x.iter().all(|c| c.is_finite()));
            (!finite).then(|| "non-finite node coordinates were accepted".to_string())
        }
        Err(e) => bad_message(&e.to_string(), &shown, false, &bytes),
    }
}

fn mesh_seed(file: &str) -> Vec<Seed> {
    let path = repo().join("cases/meshes").join(file);
    vec![Seed {
        name: path.display().to_string(),
        bytes: read(&path),
    }]
}

/// Property: Abaqus `.inp` mutants are read as checked meshes or refused
/// naming the file.
#[test]
fn fuzz_inp() {
    let (failures, n) = campaign(
        "inp",
        &mesh_seed("square.inp"),
        cases(DEFAULT_CASES),
        Draw::Any,
        check_mesh,
    );
    report(&failures, n);
}

/// Property: Gmsh `.msh` mutants are read as checked meshes or refused
/// naming the file.
#[test]
fn fuzz_msh() {
    let (failures, n) = campaign(
        "msh",
        &mesh_seed("square.msh"),
        cases(DEFAULT_CASES),
        Draw::Any,
        check_mesh,
    );
    report(&failures, n);
}

// ----------------------------------------------------------- tool meshes

fn check_tool(bytes: Vec<u8>, name: String, k: usize) -> Option<String> {
    let ext = name.rsplit('.').next().unwrap();
    let file = write_scratch(&format!("tool-{k}.{ext}"), &bytes);
    let shown = file.display().to_string();
    let options = MeshOptions {
        require_closed: k.is_multiple_of(2),
        ..MeshOptions::default()
    };
    match MeshSurface::from_file(&file, &options) {
        Ok(surface) => {
            let t = surface.tessellation();
            let finite = t.vertices.iter().all(|x| x.iter().all(|c| c.is_finite()));
            (!finite).then(|| "non-finite tool vertices were accepted".to_string())
        }
        Err(e) => bad_message(&e.to_string(), &shown, false, &bytes),
    }
}

/// Property: STL (binary, ASCII) and OBJ mutants give a finite tool or an
/// error naming the file; never a panic or an abort.
#[test]
fn fuzz_tool_meshes() {
    let seeds = vec![
        Seed {
            name: "cube-binary.stl".into(),
            bytes: binary_stl(),
        },
        Seed {
            name: "cube-ascii.stl".into(),
            bytes: ascii_stl(),
        },
        Seed {
            name: "cube.obj".into(),
            bytes: obj(),
        },
    ];
    let (failures, n) = campaign("tool", &seeds, cases(DEFAULT_CASES), Draw::Any, check_tool);
    report(&failures, n);
}

// ------------------------------------------------------------ eval lines

const EVAL_LINES: &str = r#"{"C": [[1.0, 0.0], [0.0, 1.0]], "fiber_angle_deg": 0.0}
{"C": [[1.1, 0.2], [0.2, 0.95]], "fiber_angle_deg": 45.0}

{"C": [[1.02, -0.05], [-0.05, 1.3]], "fiber_angle_deg": -30.0}
{"C": [[0.9, 0.1], [0.1, 1.0]], "fiber_angle_deg": 90.0}
"#;

fn check_eval(bytes: Vec<u8>, name: String, _k: usize) -> Option<String> {
    let material = MaterialSpec::default_set().material;
    let mut out = Vec::new();
    let mut err = Vec::new();
    let summary = match material_eval::run(&material, bytes.as_slice(), &mut out, &mut err, &name) {
        Ok(s) => s,
        Err(e) => return Some(format!("I/O error on in-memory streams: {e}")),
    };
    let expected = bytes
        .split(|&b| b == b'\n')
        .enumerate()
        .filter(|(i, l)| {
            // The last piece after a final newline is no line.
            !(l.is_empty() && *i == bytes.split(|&b| b == b'\n').count() - 1)
                && std::str::from_utf8(l).map_or(true, |s| !s.trim().is_empty())
        })
        .count();
    let text = String::from_utf8(out).expect("eval writes UTF-8");
    let lines: Vec<&str> = text.lines().collect();
    if lines.len() != expected || summary.answered + summary.failed != expected {
        return Some(format!(
            "{} answers ({:?}) for {expected} non-blank lines",
            lines.len(),
            summary
        ));
    }
    for l in &lines {
        let v: serde_json::Value = match serde_json::from_str(l) {
            Ok(v) => v,
            Err(e) => return Some(format!("answer is not JSON ({e}): {l}")),
        };
        if l.contains("null") {
            return Some(format!("answer has a non-finite number: {l}"));
        }
        if v.get("error").is_some() && v.get("line").and_then(|n| n.as_u64()).is_none() {
            return Some(format!("an error answer without its line: {l}"));
        }
    }
    let errors = String::from_utf8_lossy(&err);
    if let Some(n) = fuzz_common::long_number(&errors, &bytes) {
        return Some(format!("an error writes the {}-digit number {n}", n.len()));
    }
    if let Some(l) = errors.lines().find(|l| !l.starts_with(&format!("{name}:"))) {
        return Some(format!("error message does not name the input: {l}"));
    }
    None
}

/// Property: every non-blank line of a mutated `material eval` input gets
/// exactly one answer — a finite result or `{"line": n, "error": …}` —
/// and every error message names the input and the line.
#[test]
fn fuzz_eval_lines() {
    let seeds = vec![Seed {
        name: "stdin".into(),
        bytes: EVAL_LINES.as_bytes().to_vec(),
    }];
    let (failures, n) = campaign("eval", &seeds, cases(DEFAULT_CASES), Draw::Any, check_eval);
    report(&failures, n);
}

// ------------------------------------------------- regression tests

/// Regression: a `$Nodes` header claiming 2³² nodes aborted the process
/// (it reserved memory for them); now it is refused at its line.
#[test]
fn msh_huge_node_count_is_refused_at_its_line() {
    let text = String::from_utf8(read(&repo().join("cases/meshes/square.msh"))).unwrap();
    let bad = text.replacen("9 65 1 65", "9 4294967296 1 65", 1);
    assert_ne!(bad, text, "the sample mesh's $Nodes header changed");
    let line = bad.lines().position(|l| l == "9 4294967296 1 65").unwrap() + 1;
    let e = msh::parse_msh(&bad, "huge.msh").unwrap_err().to_string();
    assert!(e.starts_with(&format!("huge.msh:{line}:")), "{e}");
    assert!(e.contains("4294967296 nodes"), "{e}");
}

/// Regression: a physical tag of `i64::MIN` overflowed `abs` (a panic in
/// debug builds).
#[test]
fn msh_most_negative_physical_tag_is_refused() {
    let text = String::from_utf8(read(&repo().join("cases/meshes/square.msh"))).unwrap();
    let bad = text.replacen(
        "1 0 0 0 100 0 0 1 1 2 1 -2",
        "1 0 0 0 100 0 0 1 -9223372036854775808 2 1 -2",
        1,
    );
    assert_ne!(bad, text);
    let e = msh::parse_msh(&bad, "tag.msh").unwrap_err().to_string();
    assert!(e.contains("tag.msh:") && e.contains("physical tag"), "{e}");
}

/// Regression: a `GENERATE` increment that steps past `i64::MAX`
/// overflowed (a panic in debug builds); the range now ends there.
#[test]
fn inp_generate_overflow_ends_the_range() {
    let text = "*NODE\n1, 0, 0\n2, 1, 0\n3, 0, 1\n*ELEMENT, TYPE=S3\n1, 1, 2, 3\n\
                *NSET, NSET=n, GENERATE\n1, 9223372036854775807, 9223372036854775807\n";
    let mesh = inp::parse_inp(text, "big.inp").unwrap();
    assert_eq!(mesh.node_set("n").unwrap(), &[0]);
}

/// Regression: the duplicate-node message of `.inp` printed a Rust array.
#[test]
fn inp_repeated_node_message_lists_the_ids() {
    let text = "*NODE\n1, 0, 0\n2, 1, 0\n*ELEMENT, TYPE=S3\n7, 1, 2, 2\n";
    let e = inp::parse_inp(text, "rep.inp").unwrap_err().to_string();
    assert!(e.contains("element 7 with nodes 1, 2, 2"), "{e}");
}

/// Regression: one non-UTF-8 byte stopped `material eval` for all later
/// lines; now that line is answered with an error and the rest evaluated.
#[test]
fn eval_non_utf8_line_is_answered_and_later_lines_go_on() {
    let material = MaterialSpec::default_set().material;
    let mut input = Vec::new();
    input.extend_from_slice(b"{\"C\": [[1.0, 0.0], [0.0, 1.0]], \"fiber_angle_deg\": \xff}\n");
    input.extend_from_slice(EVAL_LINES.lines().next().unwrap().as_bytes());
    input.push(b'\n');
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let s =
        material_eval::run(&material, input.as_slice(), &mut out, &mut err, "in.jsonl").unwrap();
    assert_eq!((s.answered, s.failed), (1, 1));
    let text = String::from_utf8(out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    let first: serde_json::Value = serde_json::from_str(lines[0]).unwrap();
    assert_eq!(first["line"], 1);
    assert!(first["error"].as_str().unwrap().contains("not UTF-8"));
    let second: serde_json::Value = serde_json::from_str(lines[1]).unwrap();
    assert!(second["W"].is_number());
    assert!(String::from_utf8(err).unwrap().starts_with("in.jsonl:1: "));
}

/// A `C` large enough to overflow the law is an error for that line, not
/// a `null` (JSON's spelling of NaN/inf) in the answer.
#[test]
fn eval_overflowing_c_is_an_error_not_null() {
    let material = MaterialSpec::default_set().material;
    for c in ["1e300", "1e200", "1e160"] {
        let line = format!(r#"{{"C": [[{c}, 0.0], [0.0, {c}]], "fiber_angle_deg": 0.0}}"#);
        let e = material_eval::eval_line(&material, &line);
        assert!(e.is_err(), "C = {c}: {e:?}");
    }
}

/// Regression: absurd parameter values (a huge `w6.c_mid` reached the
/// line search as a NaN bound) are refused naming the file, the key and the value,
/// printed short.
#[test]
fn params_absurd_values_name_file_key_and_value() {
    let text = String::from_utf8(read(&repo().join("cases/materials/schaefer2024.toml"))).unwrap();
    for (from, to, key, shown) in [
        ("c_mid = 0.01", "c_mid = 1e308", "w6.c_mid", "1e308"),
        (
            "delta_s_mid = 0.005",
            "delta_s_mid = 1e-300",
            "w6.delta_s_mid",
            "1e-300",
        ),
        ("c_ini = 1000.0", "c_ini = 1e20", "w4.c_ini", "1e20"),
    ] {
        let bad = text.replacen(from, to, 1);
        assert_ne!(bad, text, "{from} not in the sample set");
        let e = MaterialSpec::from_toml_str(&bad, "p.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("p.toml:") && e.contains(&format!("{key} = {shown}:")),
            "{e}"
        );
        assert!(e.contains("1e12"), "{e}");
    }
    let svk = "law = \"orthotropic-svk\"\n[svk]\ne1 = 1e300\ne2 = 10.0\nnu12 = 0.3\ng12 = 3.0\n";
    let e = MaterialSpec::from_toml_str(svk, "svk.toml")
        .unwrap_err()
        .to_string();
    assert!(e.contains("svk.e1 = 1e300:"), "{e}");
}

/// Regression: generator errors named neither the case file nor the key
/// and printed Rust enum names or 300-digit numbers.
#[test]
fn generator_errors_name_case_file_and_key() {
    let oat = String::from_utf8(read(&repo().join("cases/oat45.toml"))).unwrap();
    let base = repo().join("cases");
    let bad = oat.replacen("element_size = 2.7", "element_size = 0.01", 1);
    assert_ne!(bad, oat, "the OAT case's element size changed");
    let case = OatCase::from_toml_str(&bad, "x.toml", &base).unwrap();
    let e = case.build().unwrap_err().to_string();
    assert!(
        e.starts_with("x.toml: [mesh] element_size = 0.01: expected"),
        "{e}"
    );
    let bad = oat.replacen("width = 100.0", "width = 1e300", 1);
    assert_ne!(bad, oat);
    let e = match OatCase::from_toml_str(&bad, "x.toml", &base) {
        Ok(case) => case.build().unwrap_err().to_string(),
        Err(e) => e.to_string(),
    };
    assert!(e.starts_with("x.toml:"), "{e}");
    assert!(!e.contains("0000000000"), "a long number in {e}");
    let bad = oat
        .replacen("bias_angle_deg = 45.0", "bias_angle_deg = 0.0", 1)
        .replacen("[mesh]", "[mesh]\npattern = \"both-diagonals\"", 1);
    let case = OatCase::from_toml_str(&bad, "x.toml", &base).unwrap();
    let e = case.build().unwrap_err().to_string();
    assert!(
        e.starts_with("x.toml: [mesh] pattern = \"both-diagonals\": expected"),
        "{e}"
    );
    assert!(!e.contains("Diagonal"), "a Rust enum name in {e}");
}

/// Regression: mesh-file errors of a case named only the mesh file.
#[test]
fn mesh_file_errors_name_case_file_and_key() {
    let base = repo().join("cases");
    let bad = OAT_ON_MESH_FILE.replacen("\"top\"", "\"nosuchset\"", 1);
    let case = OatCase::from_toml_str(&bad, "x.toml", &base).unwrap();
    let e = case.build().unwrap_err().to_string();
    assert!(
        e.starts_with("x.toml: mesh.moving_clamp_set = \"nosuchset\": "),
        "{e}"
    );
    let mut file = tempfile::Builder::new().suffix(".msh").tempfile().unwrap();
    file.write_all(b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n9 4294967296 1 65\n")
        .unwrap();
    let text =
        OAT_ON_MESH_FILE.replacen("meshes/square.msh", &file.path().display().to_string(), 1);
    let case = OatCase::from_toml_str(&text, "x.toml", &base).unwrap();
    let e = case.build().unwrap_err().to_string();
    assert!(e.starts_with("x.toml: mesh.file = \""), "{e}");
    assert!(
        e.contains(":5: found `4294967296 nodes in the header`"),
        "{e}"
    );
}

/// Regression: tool meshes that are empty, truncated, claim 2³² facets,
/// hold NaN vertices or degenerate triangles, or index missing vertices
/// are refused naming the file; none panics.
#[test]
fn tool_mesh_failures_name_the_file() {
    let mut huge = binary_stl();
    huge[80..84].copy_from_slice(&u32::MAX.to_le_bytes());
    let mut nan = binary_stl();
    nan[84 + 12..84 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    let mut degenerate = binary_stl();
    // Facet 1's third vertex onto its first.
    let (a, c) = (84 + 12, 84 + 12 + 24);
    let first: Vec<u8> = degenerate[a..a + 12].to_vec();
    degenerate[c..c + 12].copy_from_slice(&first);
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.stl", Vec::new(), "no triangles"),
        (
            "short.stl",
            binary_stl()[..100].to_vec(),
            "declares 12 facets",
        ),
        ("huge.stl", huge, "declares 4294967295 facets"),
        ("nan.stl", nan, "non-finite coordinate NaN"),
        ("degenerate.stl", degenerate, "is degenerate"),
        (
            "index.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n".to_vec(),
            "obj",
        ),
        (
            "nanv.obj",
            b"v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n".to_vec(),
            "line 1",
        ),
    ];
    for (name, bytes, expected) in cases {
        let path = write_scratch(name, &bytes);
        let shown = path.display().to_string();
        let e = MeshSurface::from_file(&path, &MeshOptions::default())
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(&shown), "{name}: {e}");
        assert!(
            e.to_lowercase().contains(&expected.to_lowercase()),
            "{name}: expected `{expected}` in {e}"
        );
    }
    let e = MeshSurface::from_file(
        &write_scratch("s.stl", &binary_stl()),
        &MeshOptions {
            scale: 1e300,
            ..MeshOptions::default()
        },
    )
    .unwrap_err()
    .to_string();
    assert!(e.contains("1e300") || e.contains("inf"), "{e}");
}

/// Regression: forming-case numbers that are finite one by one but whose
/// derived values are not — a displacement vector's length, a ply's
/// density, a floating tool's weight — were accepted as `inf`.
#[test]
fn forming_derived_values_that_overflow_are_refused_at_their_key() {
    let base = repo().join("cases/verification");
    let read_case = |file: &str| String::from_utf8(read(&base.join(file))).unwrap();
    let patch = read_case("friction-patch.toml");
    let holder = read_case("blankholder.toml");
    for (text, from, to, key) in [
        (
            &patch,
            "displacement = [0.5, 0.0, 0.0]",
            "displacement = [0.5, -1e308, 1e308]",
            "displacement = [0.5, -1e308, 1e308]: expected three numbers [x, y, z] whose length is finite",
        ),
        (
            &holder,
            "thickness = 0.3",
            "thickness = 5e-324",
            "thickness = 5e-324: expected a thickness for which the density",
        ),
        (
            &holder,
            "mass = 1.7 ",
            "mass = 1e308 ",
            "mass = 1e308: expected a mass whose weight",
        ),
    ] {
        let bad = text.replacen(from, to, 1);
        assert_ne!(&bad, text, "{from} not in the verification case");
        let e = FormingCase::from_toml_str(&bad, "f.toml", &base)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("f.toml:") && e.contains(key), "{e}");
    }
}

/// Regression: an OAT density (`thickness = 5e-324`) and an explicit
/// stroke time (`clamp_speed = 5e-324`, `duration = 1e-308`) that are
/// infinite although every value given is finite are refused at their key.
#[test]
fn oat_derived_values_that_overflow_are_refused_at_their_key() {
    let base = repo().join("cases");
    let text = String::from_utf8(read(&base.join("oat45-explicit.toml"))).unwrap();
    for (from, to, key) in [
        (
            "thickness = 0.3 ",
            "thickness = 5e-324 ",
            "material.thickness = 5e-324: expected a thickness for which the density",
        ),
        (
            "clamp_speed = 100.0 ",
            "clamp_speed = 5e-324 ",
            "explicit.clamp_speed = 5e-324: expected a value for which the stroke of 80 mm",
        ),
        (
            "clamp_speed = 100.0 ",
            "duration = 1e-308 ",
            "explicit.duration = 1e-308: expected a value for which the stroke of 80 mm",
        ),
    ] {
        let bad = text.replacen(from, to, 1);
        assert_ne!(bad, text, "{from} not in the explicit OAT case");
        let e = OatCase::from_toml_str(&bad, "o.toml", &base)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("o.toml:") && e.contains(key), "{e}");
    }
}

/// Regression: messages wrote `1e308` and `5e-324` out in full — the TOML
/// parser's "expected i64" quote, the OAT output-displacement check, the
/// name of a generated blank.
#[test]
fn messages_write_extreme_numbers_short() {
    let base = repo().join("cases");
    let oat = String::from_utf8(read(&base.join("oat45.toml"))).unwrap();
    let patch = String::from_utf8(read(&base.join("verification/friction-patch.toml"))).unwrap();
    let bad_oat = oat.replacen(
        "output_displacements = [20.0, 40.0, 60.0]",
        "output_displacements = [20.0, 40.0, 1e308]",
        1,
    );
    let bad_cells = patch.replacen("element_size = 2.5", "cells = [4, 1e308]", 1);
    let bad_size = patch.replacen("size = [20.0, 20.0]", "size = [5e-324, 20.0]", 1);
    for (bad, expected) in [
        (&bad_oat, "loading.output_displacements = 1e308"),
        (&bad_cells, "floating point `1e308`"),
        (&bad_size, "generated 5e-324 x 20 mm blank"),
    ] {
        let e = if is_forming(bad) {
            match FormingCase::from_toml_str(bad, "c.toml", &base.join("verification")) {
                Ok(case) => case.build().map(|_| ()).unwrap_err().to_string(),
                Err(e) => e.to_string(),
            }
        } else {
            OatCase::from_toml_str(bad, "c.toml", &base)
                .map(|_| ())
                .unwrap_err()
                .to_string()
        };
        assert!(e.contains(expected), "`{expected}` not in {e}");
        assert!(
            fuzz_common::long_number(&e, bad.as_bytes()).is_none(),
            "{e}"
        );
    }
}

/// Regression (found by the campaign): a key with an escaped newline made
/// a two-line error message, the second line naming no input.
#[test]
fn eval_error_for_a_key_with_a_newline_is_one_line() {
    let material = MaterialSpec::default_set().material;
    let input = b"{\"C\": [[1.0, 0.0], [0.0, 1.0]], \"fiber_\\ngle_deg\": 0.0}\n";
    let (mut out, mut err) = (Vec::new(), Vec::new());
    material_eval::run(&material, input.as_slice(), &mut out, &mut err, "in.jsonl").unwrap();
    let err = String::from_utf8(err).unwrap();
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.starts_with("in.jsonl:1: ") && err.contains("fiber_\\ngle_deg"),
        "{err}"
    );
}
