//! The library entry point (`docs/architecture.md`): a case loaded with
//! `Case::load` and run with `report::run` into an in-memory report gives
//! the force curve that `ncform run` writes, value for value — the command
//! line is one client of the same runner, and nothing is computed twice.
//!
//! Requirement: the OAT's `force_displacement.csv` and a coarse
//! hemisphere's `forming.csv` (stroke and punch force) equal the in-memory
//! rows exactly (the CSV files hold every value with round-trip precision,
//! so equality is the only tolerance that follows from the writer; the run
//! is deterministic for a given thread count, and both runs here use the
//! same machine and thread pool size).

use std::path::{Path, PathBuf};
use std::process::Command;

use ncform::case::Case;
use ncform::report::memory::MemoryReport;
use ncform::report::{Progress, run};
use ncform::solver::CancelToken;
use tempfile::TempDir;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

/// The numeric rows of a CSV written by ncform (`#` comments, a header).
fn csv_rows(path: &Path) -> (Vec<String>, Vec<Vec<f64>>) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines
        .next()
        .expect("a header line")
        .split(',')
        .map(str::to_string)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|v| v.parse().expect("a number")).collect())
        .collect();
    (header, rows)
}

/// Runs the `ncform` binary on `case` into a fresh folder of `dir`.
fn cli_run(case: &Path, dir: &TempDir) -> PathBuf {
    let out = dir.path().join("out");
    let status = Command::new(env!("CARGO_BIN_EXE_ncform"))
        .args(["run", case.to_str().unwrap(), "--quiet", "--out"])
        .arg(&out)
        .status()
        .expect("ncform runs");
    assert!(status.success(), "ncform run {}: {status}", case.display());
    out
}

/// Runs `case` from code into a memory report.
fn memory_run(case: &Case) -> MemoryReport {
    let mut report = MemoryReport::new();
    run(case, &mut report, &mut Progress::Quiet, &CancelToken::new())
        .unwrap_or_else(|e| panic!("{e}"));
    report
}

#[test]
fn an_oat_run_in_memory_gives_the_command_line_force_curve() {
    let path = repo("cases/oat45.toml");
    let case = Case::load(&path).unwrap();
    let memory = memory_run(&case);
    assert!(memory.error.is_none());
    assert!(memory.oat_rows.len() >= 4, "a history of steps");
    let dir = TempDir::new().unwrap();
    let out = cli_run(&path, &dir);
    let (header, rows) = csv_rows(&out.join("force_displacement.csv"));
    assert_eq!(header[..2], ["displacement [mm]", "force [N]"]);
    let written: Vec<(f64, f64)> = rows.iter().map(|r| (r[0], r[1])).collect();
    assert_eq!(memory.force_curve(None), written);
    // The MDZ means are there too, as mdz_strains.csv has them.
    let (_, strains) = csv_rows(&out.join("mdz_strains.csv"));
    let in_memory: Vec<[f64; 4]> = memory
        .oat_rows
        .iter()
        .map(|r| {
            [
                r.displacement,
                r.mdz_e22,
                r.mdz_shear_angle_deg,
                r.mdz_e_perp,
            ]
        })
        .collect();
    let on_disk: Vec<[f64; 4]> = strains.iter().map(|r| [r[0], r[1], r[2], r[3]]).collect();
    assert_eq!(in_memory, on_disk);
    // The last state's fields, one per element of the specimen.
    let last = memory.last_state.as_ref().expect("a last state");
    assert_eq!(last.load, 80.0);
    let Case::Oat(oat) = &case else {
        panic!("an OAT")
    };
    let triangles = oat.build().unwrap().mesh.triangles.len();
    assert_eq!(last.fields.len(), 1);
    assert_eq!(last.fields[0].len(), triangles);
}

#[test]
fn a_hemisphere_run_in_memory_gives_the_command_line_punch_force() {
    // The shipped [0°] hemisphere, coarse and short (the same edit as
    // verification/same_outputs.py's quick set).
    let text = std::fs::read_to_string(repo("cases/hemisphere-0.toml")).unwrap();
    let text = text
        .replace("cells = [84, 84]", "cells = [16, 16]")
        .replace("displacement = 75.0", "displacement = 15.0")
        .replace("duration = 0.44", "duration = 0.06");
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("hemisphere-coarse.toml");
    std::fs::write(&path, &text).unwrap();
    let case = Case::load(&path).unwrap();
    let memory = memory_run(&case);
    let out = cli_run(&path, &dir);
    let (header, rows) = csv_rows(&out.join("forming.csv"));
    assert_eq!(header[..2], ["punch displacement [mm]", "punch force [N]"]);
    let written: Vec<(f64, f64)> = rows.iter().map(|r| (r[0], r[1])).collect();
    let Case::Forming(forming) = &case else {
        panic!("a forming case")
    };
    let stroke_tool = forming.build().unwrap().stroke_tool();
    assert_eq!(stroke_tool, Some(2), "the punch is the stroke tool");
    let curve = memory.force_curve(stroke_tool);
    assert_eq!(curve, written);
    assert!(
        curve.last().unwrap().0 > 14.9,
        "the punch reached its stroke"
    );
    let last = memory.last_state.as_ref().expect("a last state");
    assert_eq!(last.fields.len(), 1, "one ply");
    assert_eq!(last.fields[0].len(), 2 * 16 * 16);
}

/// The command line reads a case only through `Case::load`: a case file
/// that is not UTF-8 is refused with its line and byte (before, the binary
/// read the text itself to tell the scenario and said only that the stream
/// was not UTF-8), exit 1, and no output folder.
#[test]
fn the_command_line_reads_cases_through_the_library() {
    let dir = TempDir::new().unwrap();
    let path = dir.path().join("bad.toml");
    let mut bytes = b"title = \"x\"\n[specimen]\nwidth = 1".to_vec();
    bytes.push(0xff);
    std::fs::write(&path, &bytes).unwrap();
    let out = dir.path().join("out");
    let done = Command::new(env!("CARGO_BIN_EXE_ncform"))
        .args(["run", path.to_str().unwrap(), "--quiet", "--out"])
        .arg(&out)
        .output()
        .expect("ncform runs");
    assert_eq!(done.status.code(), Some(1));
    let stderr = String::from_utf8_lossy(&done.stderr);
    assert!(
        stderr.contains("bad.toml") && stderr.contains("line 3, byte 10: not UTF-8 text"),
        "{stderr}"
    );
    assert!(!out.exists(), "no folder for a case that cannot be read");
}
