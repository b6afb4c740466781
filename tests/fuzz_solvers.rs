//! Fuzz harness of short solver runs (`docs/fuzzing.md`): tiny cases —
//! a quasi-static and an explicit off-axis tension test and a coarse
//! quasi-static forming case — with numeric tokens of the case file or of
//! its parameter file replaced by extreme values, run to the end through
//! the same functions as `ncform run`. Asserted for every mutant: no panic,
//! an answer within [`BOUND`], no non-finite number in the returned summary,
//! a sound run folder (`fuzz_common::check_run_folder`: `status.json`
//! agreeing with the exit status, the manifest, whole files without
//! `null`/`NaN`/`inf`; known defects aside, `fuzz_common::FUZZ_KNOWN`), and
//! either a result or an error naming the case or parameter file.
//!
//! Work is capped through the seeds' own keys (`explicit.max_increments`,
//! `solver.max_wall_seconds`), whose lines are never mutated. The bounded
//! run draws [`DEFAULT_CASES`] mutants per seed; `NCFORM_FUZZ_CASES=N`
//! gives `N / 25` per seed (the reader harness's `N` per reader) and
//! `NCFORM_FUZZ_SEED` changes the seed.

mod fuzz_common;

use std::path::PathBuf;
use std::time::Duration;

use fuzz_common::{
    Failure, accepted_non_finite, cases_scaled, check_run_folder, guarded, known, mutate,
    quiet_panics, report, show,
};
use ncform::case::OatCase;
use ncform::case::forming::FormingCase;
use ncform::material::MaterialSpec;
use ncform::report::Progress;
use ncform::report::files::run_case;
use ncform::report::files::run_forming;

/// Mutants per seed in `cargo test`.
const DEFAULT_CASES: usize = 200;

/// A campaign's `NCFORM_FUZZ_CASES` (mutants per reader) divided by this
/// gives the runs per seed: one run costs about 25 reads.
const RUN_COST: usize = 25;

/// Longest one run may take. The seeds run in well under a second and cap
/// their own work (10 s of wall time for Newton, 20,000 increments); the
/// bound only turns a hang into a failure.
const BOUND: Duration = Duration::from_secs(120);

/// The specimen of both OAT seeds: 10 × 30 mm at 45°, 24 triangles.
macro_rules! tiny_specimen {
    () => {
        r#"[specimen]
width = 10.0
length = 30.0
bias_angle_deg = 45.0
[mesh]
nx = 2
ny = 6
[material]
params = "fabric.toml"
thickness = 0.3
areal_mass = 0.30
"#
    };
}

/// The tiny OAT, 3 mm quasi-static.
const OAT_QUASI_STATIC: &str = concat!(
    "title = \"tiny 45° OAT\"\n",
    tiny_specimen!(),
    r#"[loading]
displacement = 3.0
output_displacements = [1.0, 2.0]
[output]
mdz_size = 5.0
contour_displacement = 3.0
[solver]
initial_increment = 0.5
max_increment = 1.0
min_increment = 0.01
max_iterations = 25
residual_tolerance = 1e-6
max_wall_seconds = 10.0
"#
);

/// The tiny OAT, 1 mm in 10 ms explicit (about 2,000 increments).
const OAT_EXPLICIT: &str = concat!(
    "title = \"tiny explicit 45° OAT\"\nsolver = \"explicit\"\n",
    tiny_specimen!(),
    r#"[loading]
displacement = 1.0
output_displacements = [0.5]
[output]
mdz_size = 5.0
[explicit]
clamp_speed = 100.0
safety_factor = 0.9
kinetic_energy_warning = 0.5
max_increments = 20000
"#
);

/// A 20 × 20 mm ply of 32 triangles pulled over a plane with friction
/// under a dead load (the friction-patch check, coarse).
const FORMING: &str = r#"title = "tiny friction patch"
[solver]
residual_tolerance = 1e-8
initial_increment = 0.25
max_increment = 0.25
max_iterations = 40
max_wall_seconds = 10.0
[[ply]]
name = "patch"
params = "fabric.toml"
thickness = 0.3
fibre_angle_deg = 0.0
bending = false
[ply.mesh]
shape = "rectangle"
size = [20.0, 20.0]
centre = [0.0, 0.0, 0.15]
element_size = 5.0
[[tool]]
name = "slope"
shape = "plane"
origin = [0.0, 0.0, 0.0]
axis = [0.0, 0.0, 1.0]
friction = 0.3
extent = 30.0
[[load]]
nodes = "all"
force = [-0.995, 0.0, -9.95]
amplitude = "constant"
[[boundary]]
nodes = "right"
fix = ["x", "y"]
displacement = [0.5, 0.0, 0.0]
[output]
states = 2
"#;

/// Lines whose numbers are the seeds' work caps: never mutated (a mutated
/// cap would be a request for long work, not bad input).
const CAPS: &[&str] = &["max_wall_seconds", "max_increments"];

/// The numeric tokens of `text` outside the cap lines, replaced as the
/// reader fuzz does (one to three extreme values).
fn mutate_numbers(text: &str, rng: &mut rand::rngs::StdRng) -> String {
    type Numbered<'a> = Vec<(usize, &'a str)>;
    let (caps, rest): (Numbered, Numbered) = text
        .lines()
        .enumerate()
        .partition(|(_, l)| CAPS.iter().any(|c| l.trim_start().starts_with(c)));
    let body: String = rest.iter().map(|(_, l)| format!("{l}\n")).collect();
    let (mutant, _) = mutate(body.as_bytes(), rng, true);
    let mut lines: Vec<String> = String::from_utf8(mutant)
        .expect("numbers-only mutants stay UTF-8")
        .lines()
        .map(str::to_string)
        .collect();
    // Put the cap lines back where they were.
    for (i, l) in caps {
        lines.insert(i.min(lines.len()), l.to_string());
    }
    lines.join("\n") + "\n"
}

/// Which solver path a seed takes.
#[derive(Clone, Copy)]
enum Kind {
    Oat,
    Forming,
}

/// Runs one mutant: the case text and the parameter text are written to
/// their own folder, loaded and run; returns what is wrong, if anything,
/// and whether the solver ran (the case was accepted).
fn check_run(
    kind: Kind,
    case_text: String,
    params_text: String,
    k: usize,
) -> (Option<String>, bool) {
    let dir = tempfile::tempdir().expect("a scratch folder");
    let case_path = dir.path().join(format!("case-{k}.toml"));
    let params_path = dir.path().join("fabric.toml");
    std::fs::write(&case_path, &case_text).unwrap();
    std::fs::write(&params_path, &params_text).unwrap();
    let out = dir.path().join("out");
    let names = |msg: &str| {
        msg.contains(&case_path.display().to_string())
            || msg.contains(&params_path.display().to_string())
    };
    let result = match kind {
        Kind::Oat => match OatCase::load(&case_path) {
            Err(e) => Err(e.to_string()),
            Ok(case) => run_case(&case, &out, Progress::Quiet)
                .map(|s| (format!("{s:?}"), s.exit_status.code()))
                .map_err(|e| e.to_string()),
        },
        Kind::Forming => match FormingCase::load(&case_path) {
            Err(e) => Err(e.to_string()),
            Ok(case) => run_forming(&case, &out, Progress::Quiet)
                .map(|s| (format!("{s:?}"), s.exit_status.code()))
                .map_err(|e| e.to_string()),
        },
    };
    let ran = result.is_ok();
    let exit = result.as_ref().map_or(1, |(_, code)| *code);
    let result = result.map(|(summary, _)| summary);
    // The run folder (`fuzz_common::check_run_folder`), outside the
    // known defects.
    let folder: Vec<String> = check_run_folder(&out, exit)
        .into_iter()
        .filter(|p| known(p.class, &p.detail).is_none())
        .map(|p| p.to_string())
        .collect();
    // Messages only: the summary's numbers are data, written in full.
    let text = match &result {
        Ok(summary) => fuzz_common::debug_strings(summary),
        Err(msg) => msg.clone(),
    };
    let input = format!("{case_text}{params_text}");
    if let Some(n) = fuzz_common::long_number(&text, input.as_bytes()) {
        let what = format!(
            "a message writes a {}-digit number: {}",
            n.len(),
            fuzz_common::clip(&text.replace(&n, "<HERE>"), 1500)
        );
        if known("long-number", &what).is_none() {
            return (Some(what), ran);
        }
    }
    let what = match result {
        Ok(summary) => accepted_non_finite(&summary)
            .map(|at| format!("a non-finite number in the summary: {at}"))
            .or_else(|| {
                (!folder.is_empty()).then(|| format!("the run folder: {}", folder.join("; ")))
            }),
        Err(_) if !folder.is_empty() => Some(format!("the run folder: {}", folder.join("; "))),
        Err(msg) if names(&msg) => None,
        Err(msg) => Some(format!(
            "error names neither the case nor the parameter file: {msg}"
        )),
    };
    (what, ran)
}

/// Mutants of one seed: even numbers mutate the case, odd ones the
/// parameter file. Returns the failures, the count and how many mutants
/// were accepted and solved.
fn campaign(name: &str, kind: Kind, case_text: &'static str) -> (Vec<Failure>, usize, usize) {
    quiet_panics();
    let params = MaterialSpec::named_text("schaefer2024").unwrap();
    let count = cases_scaled(DEFAULT_CASES, RUN_COST);
    let mut failures = Vec::new();
    let mut solved = 0;
    for k in 0..count {
        let mut rng = fuzz_common::rng_for(name, k);
        let (case_text, params_text) = if k.is_multiple_of(2) {
            (mutate_numbers(case_text, &mut rng), params.to_string())
        } else {
            (case_text.to_string(), mutate_numbers(params, &mut rng))
        };
        let (c, p) = (case_text.clone(), params_text.clone());
        let what = match guarded(BOUND, move || check_run(kind, c, p, k)) {
            Ok((None, ran)) => {
                solved += usize::from(ran);
                continue;
            }
            Ok((Some(what), _)) | Err(what) => what,
        };
        let shown = if k.is_multiple_of(2) {
            case_text
        } else {
            params_text
        };
        failures.push(Failure {
            reader: name.to_string(),
            case: k,
            operators: vec![fuzz_common::Operator::ExtremeNumber],
            what,
            input: show(shown.as_bytes()),
        });
    }
    (failures, count, solved)
}

/// Reports the failures, and fails if fewer than a fifth of the mutants
/// reached the solver (the harness would then test only the input
/// checks).
fn finish(name: &str, (failures, count, solved): (Vec<Failure>, usize, usize)) {
    eprintln!(
        "{name}: {count} mutants, {solved} solved, {} failures",
        failures.len()
    );
    report(&failures, count);
    assert!(
        5 * solved >= count,
        "{name}: only {solved} of {count} mutants reached the solver"
    );
}

/// The seeds run as they are: a check that the harness exercises the
/// solvers and not only their input checks.
#[test]
fn seeds_run_to_the_end() {
    let params = MaterialSpec::named_text("schaefer2024")
        .unwrap()
        .to_string();
    for (kind, text) in [
        (Kind::Oat, OAT_QUASI_STATIC),
        (Kind::Oat, OAT_EXPLICIT),
        (Kind::Forming, FORMING),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let case: PathBuf = dir.path().join("case.toml");
        std::fs::write(&case, text).unwrap();
        std::fs::write(dir.path().join("fabric.toml"), &params).unwrap();
        let out = dir.path().join("out");
        let (complete, exit) = match kind {
            Kind::Oat => {
                let s = run_case(&OatCase::load(&case).unwrap(), &out, Progress::Quiet).unwrap();
                (s.complete, s.exit_status.code())
            }
            Kind::Forming => {
                let s =
                    run_forming(&FormingCase::load(&case).unwrap(), &out, Progress::Quiet).unwrap();
                (s.complete, s.exit_status.code())
            }
        };
        assert!(complete, "the seed {text} did not run to the end");
        let problems: Vec<String> = check_run_folder(&out, exit)
            .into_iter()
            .filter(|p| known(p.class, &p.detail).is_none())
            .map(|p| p.to_string())
            .collect();
        assert!(
            problems.is_empty(),
            "the seed {text}: its run folder: {problems:#?}"
        );
    }
}

/// Property: mutated quasi-static OAT runs never panic, hang or report a
/// non-finite number, and fail only with a message naming their file.
#[test]
fn fuzz_quasi_static_oat() {
    finish(
        "oat-quasi-static",
        campaign("oat-quasi-static", Kind::Oat, OAT_QUASI_STATIC),
    );
}

/// As [`fuzz_quasi_static_oat`], for the explicit solver.
#[test]
fn fuzz_explicit_oat() {
    finish(
        "oat-explicit",
        campaign("oat-explicit", Kind::Oat, OAT_EXPLICIT),
    );
}

/// As [`fuzz_quasi_static_oat`], for a quasi-static forming run with
/// contact and friction.
#[test]
fn fuzz_forming() {
    finish("forming", campaign("forming", Kind::Forming, FORMING));
}
