//! The output contract of `ncform run` (docs/cases.md, "The run folder",
//! "Interrupts and write failures", "Exit codes"): one run per folder (an
//! earlier run moved aside, a foreign folder refused), `status.json`
//! written first as `running` and last with the manifest, every output
//! attempted when one fails, SIGINT/SIGTERM stopping at a safe point with
//! the results so far, and one exit code per meaning. The cases are coarse
//! (15 mm OAT elements, a 4 × 4 forming patch): each run takes well under a
//! second, the interrupted ones stop at the signal.

use std::collections::BTreeMap;
use std::fs;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

use ncform::case::OatCase;
use ncform::case::forming::FormingCase;
use ncform::report::Progress;
use ncform::report::files::{run_case, run_case_in, run_case_with};
use ncform::report::files::{run_forming_in, run_forming_with};
use ncform::report::folder::{ExitStatus, RunFolder, STATUS_FILE};
use ncform::solver::{CancelToken, RunStatus};
use serde_json::Value;
use tempfile::TempDir;

/// A coarse 45° OAT, quasi-static, to 5 mm with a VTU at 2.5 mm.
const OAT: &str = r#"title = "coarse 45° OAT"

[specimen]
width = 100.0
length = 300.0
bias_angle_deg = 45.0

[mesh]
element_size = 15.0

[loading]
displacement = 5.0
output_displacements = [2.5]
"#;

/// The same OAT with the explicit solver (writes `energy.csv` too).
fn explicit_oat() -> String {
    OAT.replace(
        "title = \"coarse 45° OAT\"",
        "title = \"coarse 45° OAT\"\nsolver = \"explicit\"",
    )
}

fn write(path: &Path, text: &str) -> PathBuf {
    fs::write(path, text).unwrap();
    path.to_path_buf()
}

fn oat(dir: &Path, name: &str, text: &str) -> OatCase {
    OatCase::load(&write(&dir.join(name), text)).unwrap_or_else(|e| panic!("{e}"))
}

/// A 20 × 20 mm ply on a plane, pulled by one edge (the friction patch of
/// cases/verification at 5 mm elements, two output states).
fn patch() -> FormingCase {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/verification/friction-patch.toml");
    let text =
        fs::read_to_string(&path)
            .unwrap()
            .replacen("element_size = 2.5", "element_size = 5.0", 1);
    FormingCase::from_toml_str(&text, &path.display().to_string(), path.parent().unwrap())
        .unwrap_or_else(|e| panic!("{e}"))
}

fn status(out: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(out.join(STATUS_FILE)).unwrap()).unwrap()
}

fn summary(out: &Path) -> Value {
    serde_json::from_str(&fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
}

/// Every file under `dir` (relative, `/`-separated) with its size.
fn files_under(dir: &Path) -> BTreeMap<String, u64> {
    let mut found = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in fs::read_dir(&d).unwrap() {
            let entry = entry.unwrap();
            let path = entry.path();
            if path.is_dir() {
                stack.push(path);
            } else {
                let rel = path
                    .strip_prefix(dir)
                    .unwrap()
                    .to_string_lossy()
                    .replace('\\', "/");
                found.insert(rel, entry.metadata().unwrap().len());
            }
        }
    }
    found
}

/// The manifest of `status.json`: path → bytes.
fn manifest(out: &Path) -> BTreeMap<String, u64> {
    status(out)["files"]
        .as_array()
        .unwrap()
        .iter()
        .map(|f| {
            (
                f["path"].as_str().unwrap().to_string(),
                f["bytes"].as_u64().unwrap(),
            )
        })
        .collect()
}

/// The manifest lists exactly the files present (status.json aside), with
/// their sizes.
fn assert_manifest_is_the_folder(out: &Path) {
    let mut present = files_under(out);
    assert!(present.remove(STATUS_FILE).is_some(), "no {STATUS_FILE}");
    assert_eq!(manifest(out), present, "manifest of {}", out.display());
}

/// docs/cases.md "The run folder": a run into a folder with an earlier run
/// moves it aside whole (`<out>.previous`, then `.previous-2`) and leaves
/// only its own files, every one in the manifest.
#[test]
fn an_earlier_run_is_moved_aside_and_the_folder_holds_only_the_new_run() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("out");
    // First an explicit run (it writes energy.csv), then a quasi-static one.
    let first = oat(dir.path(), "explicit.toml", &explicit_oat());
    let s = run_case(&first, &out, Progress::Quiet).unwrap();
    assert_eq!(s.exit_status, ExitStatus::Complete);
    assert!(out.join("energy.csv").is_file());
    assert_manifest_is_the_folder(&out);
    let first_files = files_under(&out);

    let second = oat(dir.path(), "static.toml", OAT);
    let s = run_case(&second, &out, Progress::Quiet).unwrap();
    assert_eq!(s.exit_status, ExitStatus::Complete);
    let aside = dir.path().join("out.previous");
    assert_eq!(files_under(&aside), first_files, "the earlier run, whole");
    assert!(
        !out.join("energy.csv").exists(),
        "a file of the earlier run"
    );
    assert_manifest_is_the_folder(&out);
    assert_eq!(status(&out)["case"], second.source.as_str());
    assert_eq!(
        status(&out)["previous_run"],
        aside.display().to_string().as_str()
    );

    run_case(&second, &out, Progress::Quiet).unwrap();
    assert!(
        dir.path()
            .join("out.previous-2")
            .join(STATUS_FILE)
            .is_file()
    );
    assert_eq!(files_under(&aside), first_files, "earlier runs are kept");
    assert_manifest_is_the_folder(&out);
}

/// docs/cases.md "The run folder": a run from before status files (its
/// summary.json) is an earlier run too; a non-empty folder that is not a
/// run is refused and left as it was; an empty one is used.
#[test]
fn a_folder_that_is_not_a_run_is_refused_and_an_empty_one_used() {
    let dir = TempDir::new().unwrap();
    let case = oat(dir.path(), "case.toml", OAT);
    let foreign = dir.path().join("mine");
    fs::create_dir(&foreign).unwrap();
    write(&foreign.join("notes.txt"), "my notes");
    let err = run_case(&case, &foreign, Progress::Quiet)
        .expect_err("must refuse")
        .to_string();
    assert!(
        err.contains("not empty") && err.contains("notes.txt"),
        "{err}"
    );
    assert_eq!(files_under(&foreign).len(), 1, "the folder is untouched");
    assert!(!dir.path().join("mine.previous").exists());

    let empty = dir.path().join("empty");
    fs::create_dir(&empty).unwrap();
    run_case(&case, &empty, Progress::Quiet).unwrap();
    assert_manifest_is_the_folder(&empty);

    let legacy = dir.path().join("legacy");
    fs::create_dir(&legacy).unwrap();
    write(
        &legacy.join("summary.json"),
        r#"{"case": "old.toml", "status": {"status": "complete"}, "units": "mm"}"#,
    );
    run_case(&case, &legacy, Progress::Quiet).unwrap();
    assert!(dir.path().join("legacy.previous/summary.json").is_file());
    assert_manifest_is_the_folder(&legacy);

    let file = dir.path().join("a-file");
    write(&file, "x");
    let err = run_case(&case, &file, Progress::Quiet)
        .expect_err("must refuse")
        .to_string();
    assert!(err.contains("is a file"), "{err}");
}

/// docs/cases.md "status.json": written as `running` (case, pid, version,
/// start) when the folder is prepared, rewritten `complete` with the exit
/// code at the end; summary.json carries the same status.
#[test]
fn the_status_goes_from_running_to_complete() {
    let dir = TempDir::new().unwrap();
    let case = oat(dir.path(), "case.toml", OAT);
    let out = dir.path().join("out");
    let mut folder = RunFolder::prepare(&out, &case.source, &case.title, &["vtu"]).unwrap();
    let running = status(&out);
    assert_eq!(running["status"], "running");
    assert_eq!(running["pid"], std::process::id());
    assert_eq!(running["case"], case.source.as_str());
    assert_eq!(running["ncform_version"], env!("CARGO_PKG_VERSION"));
    assert!(running["started"].as_str().unwrap().ends_with('Z'));
    assert!(running.get("finished").is_none() && running.get("exit_code").is_none());
    // A folder whose run is still going on (this process) is an earlier
    // run, not a foreign folder.
    let s = run_case_in(&case, &mut folder, Progress::Quiet, &CancelToken::new()).unwrap();
    let done = status(&out);
    assert_eq!(done["status"], "complete");
    assert_eq!(done["exit_code"], 0);
    assert_eq!(done["outputs_complete"], true);
    assert_eq!(done["started"], running["started"]);
    assert!(done["finished"].is_string());
    assert_eq!(done["solve"]["status"], "complete");
    assert_eq!(summary(&out)["status"]["status"], "complete");
    assert_eq!(summary(&out)["exit_status"], "complete");
    assert!(s.outputs_missing.is_empty());
    assert_manifest_is_the_folder(&out);
}

/// docs/cases.md "status.json": a prepared folder given up without a final
/// status (what a panic unwinding through a run does) says `failed`, never
/// `running`.
#[test]
fn a_folder_given_up_is_marked_failed() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("out");
    let folder = RunFolder::prepare(&out, "case.toml", "t", &["vtu"]).unwrap();
    assert_eq!(status(&out)["status"], "running");
    drop(folder);
    let st = status(&out);
    assert_eq!(st["status"], "failed");
    assert_eq!(st["outputs_complete"], false);
    assert!(
        st["error"]
            .as_str()
            .unwrap()
            .contains("without a final status")
    );
    assert!(st.get("exit_code").is_none(), "{st}");
}

/// docs/cases.md "Interrupts and write failures": outputs that cannot be
/// written (here their paths are folders, made after the folder is
/// prepared) are listed as missing with the OS error; every other output
/// is written, the series lists only the VTU files that are there, and the
/// exit status says outputs are missing.
#[test]
fn a_write_failure_keeps_the_other_outputs_of_an_oat() {
    let dir = TempDir::new().unwrap();
    let case = oat(dir.path(), "case.toml", OAT);
    let out = dir.path().join("out");
    let mut folder = RunFolder::prepare(&out, &case.source, &case.title, &["vtu"]).unwrap();
    let blocked = ["force_displacement.csv", "vtu/oat_d002.500.vtu"];
    for b in blocked {
        fs::create_dir(out.join(b)).unwrap();
    }
    let s = run_case_in(&case, &mut folder, Progress::Quiet, &CancelToken::new()).unwrap();
    assert_eq!(s.status, RunStatus::Complete);
    assert_eq!(s.exit_status, ExitStatus::OutputsMissing);
    let st = status(&out);
    assert_eq!(st["status"], "complete");
    assert_eq!(st["outputs_complete"], false);
    assert_eq!(st["exit_code"], 5);
    let mut missing: Vec<&str> = st["missing"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["path"].as_str().unwrap())
        .collect();
    missing.sort_unstable();
    assert_eq!(missing, blocked);
    for m in st["missing"].as_array().unwrap() {
        assert!(
            m["error"].as_str().unwrap().contains("directory"),
            "the OS error: {m}"
        );
    }
    for kept in [
        "mdz_strains.csv",
        "force_displacement.png",
        "mdz_strains.png",
        "contours.png",
        "oat.pvd",
        "vtu/oat_d005.000.vtu",
        "summary.json",
    ] {
        assert!(out.join(kept).is_file(), "{kept}");
    }
    let pvd = fs::read_to_string(out.join("oat.pvd")).unwrap();
    assert!(pvd.contains("oat_d005.000.vtu") && !pvd.contains("oat_d002.500.vtu"));
    assert_eq!(
        summary(&out)["outputs_missing"].as_array().unwrap().len(),
        2
    );
    assert_manifest_is_the_folder(&out);
}

/// As above for a forming run: its history and one of its maps blocked.
#[test]
fn a_write_failure_keeps_the_other_outputs_of_a_forming_run() {
    let case = patch();
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("out");
    let mut folder = RunFolder::prepare(&out, &case.source, &case.title, &["vtu", "maps"]).unwrap();
    let blocked = ["history.csv", "maps/patch_0001.png"];
    for b in blocked {
        fs::create_dir(out.join(b)).unwrap();
    }
    let s = run_forming_in(&case, &mut folder, Progress::Quiet, &CancelToken::new()).unwrap();
    assert_eq!(s.status, RunStatus::Complete);
    assert_eq!(s.exit_status, ExitStatus::OutputsMissing);
    let mut missing: Vec<String> = s.outputs_missing.iter().map(|m| m.path.clone()).collect();
    missing.sort();
    assert_eq!(missing, blocked);
    for kept in [
        "reactions.png",
        "forming.pvd",
        "vtu/patch_0001.vtu",
        "maps/patch-dic_0001.png",
        "maps/patch_0002.png",
        "summary.json",
    ] {
        assert!(out.join(kept).is_file(), "{kept}");
    }
    assert_eq!(status(&out)["exit_code"], 5);
    assert_manifest_is_the_folder(&out);
}

/// The cancel token stops both solvers at their first safe point: the
/// run is written and marked interrupted (in-process, no signal).
#[test]
fn a_cancelled_run_is_written_and_marked_interrupted() {
    let dir = TempDir::new().unwrap();
    let cancel = CancelToken::new();
    cancel.cancel();
    for (name, text) in [
        ("static.toml", OAT.to_string()),
        ("explicit.toml", explicit_oat()),
    ] {
        let case = oat(dir.path(), name, &text);
        let out = dir.path().join(format!("out-{name}"));
        let s = run_case_with(&case, &out, Progress::Quiet, &cancel).unwrap();
        assert!(
            matches!(s.status, RunStatus::Interrupted { .. }),
            "{name}: {:?}",
            s.status
        );
        assert_eq!(s.exit_status, ExitStatus::Interrupted);
        assert_eq!(status(&out)["status"], "interrupted");
        assert_eq!(status(&out)["exit_code"], 4);
        let csv = fs::read_to_string(out.join("force_displacement.csv")).unwrap();
        assert!(csv.contains("status: INTERRUPTED"), "{csv}");
        assert_manifest_is_the_folder(&out);
    }
    let out = dir.path().join("out-forming");
    let s = run_forming_with(&patch(), &out, Progress::Quiet, &cancel).unwrap();
    assert_eq!(s.status, RunStatus::Interrupted { load_reached: 0.0 });
    assert_eq!(status(&out)["status"], "interrupted");
    assert_manifest_is_the_folder(&out);
}

/// Every JSON and CSV file of the run folder `out` is free of `null`,
/// `NaN` and infinities (docs/cases.md, "summary.json": a figure that does
/// not apply or was never reached is left out; a value that cannot be
/// computed is an empty CSV field).
fn assert_no_null_or_non_finite(out: &Path) {
    for (rel, _) in files_under(out) {
        if !(rel.ends_with(".json") || rel.ends_with(".csv")) {
            continue;
        }
        let text = fs::read_to_string(out.join(&rel)).unwrap();
        let data: String = text
            .lines()
            .filter(|l| !l.starts_with('#'))
            .collect::<Vec<_>>()
            .join("\n");
        for token in ["null", "NaN", "nan", "inf", "not finite"] {
            let found = data
                .split(|c: char| !(c.is_alphanumeric() || c == '_' || c == ' '))
                .any(|word| word.split(' ').any(|w| w == token));
            assert!(!found, "{}: {rel} holds {token:?}:\n{text}", out.display());
        }
        if rel.ends_with(".json") {
            serde_json::from_str::<Value>(&text)
                .unwrap_or_else(|e| panic!("{rel} is not JSON: {e}"));
        }
    }
}

/// Runs that end before any state beyond the start — a quasi-static OAT and
/// forming run whose first step fails, explicit runs stopped before their
/// first increment — write no `null` and no non-finite number: the figures
/// they never computed (the explicit step range, say) are left out.
#[test]
fn runs_that_stop_at_once_write_no_null_and_no_non_finite_number() {
    let dir = TempDir::new().unwrap();
    // One Newton iteration per attempt and no cut-back below the first
    // step: the first step fails.
    let failing = "[solver]\nmax_iterations = 1\ninitial_increment = 1.0\nmin_increment = 0.9\n";
    let case = oat(dir.path(), "fails.toml", &format!("{OAT}\n{failing}"));
    let out = dir.path().join("out-fails");
    let s = run_case(&case, &out, Progress::Quiet).unwrap();
    assert!(
        matches!(s.status, RunStatus::Incomplete { .. }),
        "{:?}",
        s.status
    );
    assert_no_null_or_non_finite(&out);
    let cancel = CancelToken::new();
    cancel.cancel();
    let case = oat(dir.path(), "explicit.toml", &explicit_oat());
    let out = dir.path().join("out-explicit");
    let s = run_case_with(&case, &out, Progress::Quiet, &cancel).unwrap();
    assert!(
        matches!(s.status, RunStatus::Interrupted { .. }),
        "{:?}",
        s.status
    );
    assert_no_null_or_non_finite(&out);
    let summary = summary(&out);
    assert!(
        summary["explicit"]["increments"].as_u64().is_some(),
        "{summary}"
    );
    let mut forming = patch();
    forming.solver.max_iterations = 1;
    forming.solver.min_increment = forming.solver.initial_increment;
    let out = dir.path().join("out-forming-fails");
    let s = run_forming_with(&forming, &out, Progress::Quiet, &CancelToken::new()).unwrap();
    assert!(
        matches!(s.status, RunStatus::Incomplete { .. }),
        "{:?}",
        s.status
    );
    assert_no_null_or_non_finite(&out);
    let mut forming = patch();
    forming.solver_kind = ncform::case::SolverKind::Explicit;
    let out = dir.path().join("out-forming-explicit");
    let s = run_forming_with(&forming, &out, Progress::Quiet, &cancel).unwrap();
    assert!(
        matches!(s.status, RunStatus::Interrupted { .. }),
        "{:?}",
        s.status
    );
    assert_no_null_or_non_finite(&out);
}

// ---------------------------------------------------------------------------
// The binary: signals and exit codes
// ---------------------------------------------------------------------------

/// The longest an interrupted run may take to stop and write its results;
/// a run that does not stop is killed and the test fails (no hang).
const STOP_BOUND: Duration = Duration::from_secs(120);

/// Starts `ncform run case --out out` with stderr piped; returns the child
/// and a channel of its stderr lines.
fn spawn(case: &Path, out: &Path) -> (Child, mpsc::Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_ncform"))
        .arg("run")
        .arg(case)
        .arg("--out")
        .arg(out)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (send, lines) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if send.send(line).is_err() {
                break;
            }
        }
    });
    (child, lines)
}

/// Waits for `child` within [`STOP_BOUND`], killing it past that.
fn wait(child: &mut Child) -> Option<i32> {
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            return status.code();
        }
        if start.elapsed() > STOP_BOUND {
            child.kill().unwrap();
            panic!("ncform did not stop within {STOP_BOUND:?} of the signal");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs `case` and sends `signal` once the run has reported progress past
/// the start (a progress line at d > 0); returns the exit code and stderr.
fn interrupt(case: &Path, out: &Path, signal: &str) -> (Option<i32>, String) {
    let (mut child, lines) = spawn(case, out);
    let mut seen = Vec::new();
    loop {
        let line = lines.recv_timeout(STOP_BOUND).unwrap_or_else(|_| {
            let _ = child.kill();
            panic!("no progress from ncform: {}", seen.join("\n"))
        });
        let past_start = line.starts_with("d = ") && !line.starts_with("d =   0.000");
        seen.push(line);
        if past_start {
            break;
        }
    }
    let sent = Command::new("kill")
        .arg(format!("-{signal}"))
        .arg(child.id().to_string())
        .status()
        .unwrap();
    assert!(sent.success());
    let code = wait(&mut child);
    seen.extend(lines.try_iter());
    (code, seen.join("\n"))
}

/// The last data row of a CSV written by ncform (after the `#` preamble and
/// the header).
fn last_row(path: &Path) -> Vec<f64> {
    let text = fs::read_to_string(path).unwrap();
    let line = text
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .last()
        .expect("a data row");
    line.split(',').map(|v| v.trim().parse().unwrap()).collect()
}

/// docs/cases.md "Interrupts and write failures": SIGINT or SIGTERM in the
/// middle of a run (explicit: stopped within an increment; quasi-static:
/// before the next load step or Newton iteration) exits with 4, and
/// status.json and summary.json say interrupted at the last state, which is
/// the last row of the written history and the last VTU state.
#[test]
fn a_signal_stops_the_run_and_the_results_up_to_there_are_written() {
    let dir = TempDir::new().unwrap();
    // Long runs if not interrupted: the explicit one at 0.05 mm/s (about a
    // minute of increments, above the default increment limit, hence the
    // raised one), the quasi-static one in 5e-4 mm steps.
    let explicit = write(
        &dir.path().join("explicit.toml"),
        &format!(
            "{}\n[explicit]\nclamp_speed = 0.05\nhistory_interval = 0.01\nmax_increments = 100000000\n",
            explicit_oat()
        ),
    );
    let quasi_static = write(
        &dir.path().join("static.toml"),
        &format!(
            "{OAT}\n[solver]\ninitial_increment = 5e-4\nmax_increment = 5e-4\nextrapolate = false\n"
        ),
    );
    for (case, signal) in [(&explicit, "INT"), (&quasi_static, "TERM")] {
        let out = dir.path().join(format!("out-{signal}"));
        let (code, stderr) = interrupt(case, &out, signal);
        assert_eq!(code, Some(4), "{stderr}");
        assert!(stderr.contains("marked interrupted"), "{stderr}");
        let st = status(&out);
        assert_eq!(st["status"], "interrupted", "{st}");
        assert_eq!(st["exit_code"], 4);
        let reached = st["solve"]["load_reached"].as_f64().unwrap();
        assert!(reached > 0.0 && reached < 5.0, "{reached}");
        let s = summary(&out);
        assert_eq!(s["status"]["status"], "interrupted");
        assert_eq!(s["status"]["load_reached"], st["solve"]["load_reached"]);
        assert_eq!(s["exit_status"], "interrupted");
        let row = last_row(&out.join("force_displacement.csv"));
        assert_eq!(row[0], reached, "the last history row is the state reached");
        assert!(row[1].is_finite() && row[1] > 0.0, "{row:?}");
        // The state reached is written as the last VTU state, marked
        // (docs/cases.md, "Incomplete runs and exit codes"), unless it is
        // the output state at 2.5 mm.
        if reached != 2.5 {
            let name = format!("oat_d{reached:07.3}-last.vtu");
            let vtu = fs::read_to_string(out.join("vtu").join(&name))
                .unwrap_or_else(|e| panic!("{name}: {e}"));
            assert!(
                vtu.contains(&format!(
                    "clamp displacement {reached} mm (last converged state)"
                )),
                "{name} is not marked"
            );
            let pvd = fs::read_to_string(out.join("oat.pvd")).unwrap();
            assert!(pvd.contains(&format!("file=\"vtu/{name}\"")), "{pvd}");
        }
        assert!(out.join("force_displacement.png").is_file());
        assert_manifest_is_the_folder(&out);
    }
}

/// docs/cases.md "Exit codes": 1 bad input (a case file, a foreign output
/// folder), 2 usage, 3 incomplete; each with its message on stderr.
#[test]
fn exit_codes_have_one_meaning_each() {
    let dir = TempDir::new().unwrap();
    let ncform = env!("CARGO_BIN_EXE_ncform");
    let run = |args: &[&std::ffi::OsStr]| {
        let output = Command::new(ncform).args(args).output().unwrap();
        (
            output.status.code(),
            String::from_utf8_lossy(&output.stderr).into_owned(),
        )
    };
    let bad = write(
        &dir.path().join("bad.toml"),
        &OAT.replace("width = 100.0", "width = -1.0"),
    );
    let incomplete = write(
        &dir.path().join("incomplete.toml"),
        &format!(
            "{OAT}\n[solver]\nmax_iterations = 1\nmin_increment = 0.5\ninitial_increment = 5.0\n"
        ),
    );
    let foreign = dir.path().join("foreign");
    fs::create_dir(&foreign).unwrap();
    write(&foreign.join("data.csv"), "1,2\n");
    let out = dir.path().join("out");
    let (code, err) = run(&[
        "run".as_ref(),
        bad.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("specimen.width = -1"), "{err}");
    assert!(!out.exists(), "bad input writes nothing");
    let (code, err) = run(&["run".as_ref(), "--no-such-flag".as_ref()]);
    assert_eq!(code, Some(2), "{err}");
    let (code, err) = run(&[
        "run".as_ref(),
        incomplete.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--quiet".as_ref(),
    ]);
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("marked incomplete"), "{err}");
    assert_eq!(status(&out)["status"], "incomplete");
    assert_eq!(status(&out)["exit_code"], 3);
    let (code, err) = run(&[
        "run".as_ref(),
        incomplete.as_os_str(),
        "--out".as_ref(),
        foreign.as_os_str(),
    ]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("not empty"), "{err}");
}

/// docs/cases.md "The run folder": an output is written under
/// `<name>.partial` and renamed into place when whole; a write that fails
/// part-way (here a writer that writes some bytes and then fails, and a VTU
/// folder replaced by a file) leaves no file under the real name and no
/// partial file, is listed as missing, and `status.json` still records the
/// final status.
#[test]
fn a_write_failing_part_way_leaves_no_file_under_its_name() {
    let dir = TempDir::new().unwrap();
    let case = oat(dir.path(), "case.toml", OAT);
    let out = dir.path().join("out");
    let mut folder = RunFolder::prepare(&out, &case.source, &case.title, &["vtu"]).unwrap();
    let half = out.join("half.json");
    let written = folder.outputs_mut().write(&half, |p| {
        fs::write(p, "{\"half\": ")?;
        Err(std::io::Error::new(
            std::io::ErrorKind::StorageFull,
            "no space left (simulated)",
        ))
    });
    assert!(!written);
    assert!(!half.exists(), "a half file under the real name");
    assert!(!out.join("half.json.partial").exists(), "the partial file");
    // The VTU folder replaced by a file: every VTU write fails.
    fs::remove_dir(out.join("vtu")).unwrap();
    fs::write(out.join("vtu"), "not a folder").unwrap();
    let s = run_case_in(&case, &mut folder, Progress::Quiet, &CancelToken::new()).unwrap();
    assert_eq!(s.status, RunStatus::Complete);
    assert_eq!(s.exit_status, ExitStatus::OutputsMissing);
    let st = status(&out);
    assert_eq!(st["status"], "complete");
    assert_eq!(st["exit_code"], 5);
    let missing: Vec<&str> = st["missing"]
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["path"].as_str().unwrap())
        .collect();
    for m in ["half.json", "vtu/oat_d002.500.vtu", "vtu/oat_d005.000.vtu"] {
        assert!(missing.contains(&m), "{m} missing in {missing:?}");
    }
    let present = files_under(&out);
    assert!(
        present
            .keys()
            .all(|f| !f.ends_with(".partial") && !f.ends_with(".tmp")),
        "{present:?}"
    );
    fs::remove_file(out.join("vtu")).unwrap();
    assert_manifest_is_the_folder(&out);
    // The files written are whole: summary.json is JSON.
    assert_eq!(
        summary(&out)["outputs_missing"].as_array().unwrap().len(),
        3
    );
}

/// docs/cases.md "The run folder": a `status.json` that cannot be rewritten
/// at the end (here its rename is blocked by a folder at
/// `status.json.tmp`) makes the exit status 5; the file left says
/// `running` (stderr says it is stale), the folder blocking it is left.
#[test]
fn a_status_that_cannot_be_rewritten_makes_the_exit_status_5() {
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("out");
    let mut folder = RunFolder::prepare(&out, "case.toml", "title", &[]).unwrap();
    let blocker = out.join(format!("{STATUS_FILE}.tmp"));
    fs::create_dir(&blocker).unwrap();
    write(&blocker.join("inside"), "x");
    assert_eq!(
        folder.finish(&RunStatus::Complete),
        ExitStatus::OutputsMissing
    );
    drop(folder);
    assert_eq!(status(&out)["status"], "running");
    assert!(blocker.join("inside").is_file(), "not ncform's to remove");
}

/// docs/cases.md "The run folder": two runs preparing one new folder at the
/// same moment: one gets it, the other is refused as "a run still going
/// on" (never a file-system error, never a folder taken by both).
#[test]
fn of_two_runs_preparing_one_folder_at_once_one_is_refused() {
    for round in 0..200 {
        let dir = TempDir::new().unwrap();
        let out = dir.path().join("out");
        let barrier = std::sync::Arc::new(std::sync::Barrier::new(2));
        let racers: Vec<_> = (0..2)
            .map(|_| {
                let (out, barrier) = (out.clone(), barrier.clone());
                std::thread::spawn(move || {
                    barrier.wait();
                    RunFolder::prepare(&out, "case.toml", "title", &["vtu"])
                })
            })
            .collect();
        let results: Vec<_> = racers.into_iter().map(|r| r.join().unwrap()).collect();
        let won = results.iter().filter(|r| r.is_ok()).count();
        assert_eq!(won, 1, "round {round}: {results:?}");
        let refusal = results.iter().find_map(|r| r.as_ref().err()).unwrap();
        assert!(
            refusal.to_string().contains("holds a run still going on"),
            "round {round}: {refusal}"
        );
        assert_eq!(status(&out)["status"], "running");
        assert!(!dir.path().join("out.previous").exists(), "round {round}");
    }
}

/// docs/cases.md "The run folder": a folder whose `status.json` is not an
/// ncform run's is refused with what is wrong with that file.
#[test]
fn a_foreign_status_file_is_refused_saying_what_is_wrong() {
    let dir = TempDir::new().unwrap();
    let case = oat(dir.path(), "case.toml", OAT);
    let out = dir.path().join("out");
    fs::create_dir(&out).unwrap();
    for (content, says) in [
        (Some("status: fine\n"), "it is not JSON"),
        (Some(""), "it is not JSON"),
        (
            Some(r#"{"format": "other-tool-3", "status": "done"}"#),
            "its format is 'other-tool-3'",
        ),
        (Some(r#"{"status": "done"}"#), "has no \"format\""),
        (
            Some(r#"{"format": "ncform-run-folder-1", "status": 3}"#),
            "not in the format it names",
        ),
        (None, "cannot be read"),
    ] {
        let path = out.join(STATUS_FILE);
        if path.is_file() {
            fs::remove_file(&path).unwrap();
        }
        match content {
            Some(text) => write(&path, text),
            None => {
                fs::create_dir(&path).unwrap();
                path.clone()
            }
        };
        let err = run_case(&case, &out, Progress::Quiet)
            .expect_err("must refuse")
            .to_string();
        assert!(
            err.contains("not an ncform run's") && err.contains(says),
            "{says}: {err}"
        );
        assert!(!err.contains("no status.json"), "{err}");
        assert!(!dir.path().join("out.previous").exists());
        if content.is_none() {
            fs::remove_dir(&path).unwrap();
        }
    }
}

/// docs/cases.md "Interrupts and write failures": under a file-size limit
/// (`ulimit -f`) the writes past it fail with EFBIG (SIGXFSZ is ignored,
/// it does not kill the run): exit code 5, a `status.json` with the final
/// status and the outputs not written, no truncated file under a real
/// name. The case is cases/oat45.toml at 15 mm elements (a run of a
/// second).
#[test]
fn a_file_size_limit_leaves_outputs_missing_not_truncated() {
    let dir = TempDir::new().unwrap();
    let shipped = Path::new(env!("CARGO_MANIFEST_DIR")).join("cases/oat45.toml");
    let text = fs::read_to_string(shipped).unwrap();
    let coarse = text.replacen("element_size = 2.7", "element_size = 15.0", 1);
    assert_ne!(coarse, text, "the mesh line of cases/oat45.toml");
    let case = write(&dir.path().join("oat45.toml"), &coarse);
    let out = dir.path().join("out");
    let run = Command::new("sh")
        .arg("-c")
        .arg(r#"ulimit -f 64; exec "$0" run --quiet --out "$1" "$2""#)
        .arg(env!("CARGO_BIN_EXE_ncform"))
        .arg(&out)
        .arg(&case)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(5), "{stderr}");
    let st = status(&out);
    assert_eq!(st["status"], "complete", "{st}");
    assert_eq!(st["exit_code"], 5);
    let missing = st["missing"].as_array().unwrap();
    assert!(!missing.is_empty());
    for m in missing {
        assert!(
            m["error"].as_str().unwrap().contains("too large"),
            "EFBIG: {m}"
        );
    }
    assert!(stderr.contains("output not written"), "{stderr}");
    // Every file present is whole: listed in the manifest with its size,
    // no partial or temporary file left.
    assert_manifest_is_the_folder(&out);
    for m in missing {
        let path = out.join(m["path"].as_str().unwrap());
        assert!(!path.exists(), "{}", path.display());
    }
}

/// As above on a folder holding an earlier (finished) run: one run moves it
/// aside and takes the folder, the other is refused; the run going on is
/// never moved aside.
#[test]
fn of_two_runs_replacing_an_earlier_run_at_once_one_is_refused() {
    for round in 0..100 {
        let dir = TempDir::new().unwrap();
        let out = dir.path().join("out");
        RunFolder::prepare(&out, "old.toml", "old", &[])
            .unwrap()
            .finish(&RunStatus::Complete);
        let barrier = std::sync::Arc::new(std::sync::Barrier::new(2));
        let racers: Vec<_> = (0..2)
            .map(|_| {
                let (out, barrier) = (out.clone(), barrier.clone());
                std::thread::spawn(move || {
                    barrier.wait();
                    RunFolder::prepare(&out, "case.toml", "title", &["vtu"])
                })
            })
            .collect();
        let results: Vec<_> = racers.into_iter().map(|r| r.join().unwrap()).collect();
        let won = results.iter().filter(|r| r.is_ok()).count();
        assert_eq!(won, 1, "round {round}: {results:?}");
        let refusal = results.iter().find_map(|r| r.as_ref().err()).unwrap();
        assert!(
            refusal.to_string().contains("holds a run still going on"),
            "round {round}: {refusal}"
        );
        assert_eq!(status(&out)["status"], "running");
        assert_eq!(status(&out)["case"], "case.toml");
        let aside = dir.path().join("out.previous");
        assert_eq!(status(&aside)["case"], "old.toml", "round {round}");
        assert!(!dir.path().join("out.previous-2").exists(), "round {round}");
    }
}
