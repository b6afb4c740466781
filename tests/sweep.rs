//! `ncform sweep` and `ncform collect` as a user runs them: a 3 × 2 grid
//! on the 45° OAT (W6 s_ini × the end displacement) killed with SIGKILL
//! half-way, resumed and collected; every point equals a direct `ncform
//! run` of its case; a SIGTERM'd sweep resumes too; bad keys and values are
//! refused before anything runs (`docs/studies.md`).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn ncform() -> &'static str {
    env!("CARGO_BIN_EXE_ncform")
}

/// `ncform ARGS…`, run to its end: exit status, stdout, stderr.
fn ncform_with(args: &[&str]) -> std::process::Output {
    Command::new(ncform()).args(args).output().unwrap()
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A 3 × 2 grid on the 45° OAT at element size `h` (coarse, so the test
/// is quick, but with points long enough to be killed half-way).
fn sweep_file(dir: &Path, h: f64, extra: &str) -> PathBuf {
    let case = repo().join("cases/oat45.toml");
    let text = format!(
        r#"title = "test grid"
case = "{}"
design = "grid"
[[set]]
key = "mesh.element_size"
value = {h}
[[set]]
key = "loading.output_displacements"
value = []
[[vary]]
key = "material.w6.s_ini"
values = [0.012, 0.018, 0.024]
[[vary]]
key = "loading.displacement"
values = [40.0, 60.0]
{extra}
"#,
        case.display()
    );
    let path = dir.join("grid.toml");
    std::fs::write(&path, text).unwrap();
    path
}

fn status_of(point: &Path) -> Option<String> {
    let text = std::fs::read_to_string(point.join("status.json")).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).ok()?;
    v["state"].as_str().map(str::to_string)
}

fn points(dir: &Path) -> Vec<PathBuf> {
    (0..6).map(|i| dir.join(format!("points/{i:04}"))).collect()
}

/// Waits until one point is complete and another running, or `limit`.
fn wait_half_way(dir: &Path, limit: Duration) -> bool {
    let start = Instant::now();
    while start.elapsed() < limit {
        let states: Vec<Option<String>> = points(dir).iter().map(|p| status_of(p)).collect();
        let complete = states
            .iter()
            .filter(|s| s.as_deref() == Some("complete"))
            .count();
        let running = states
            .iter()
            .filter(|s| s.as_deref() == Some("running"))
            .count();
        if complete >= 1 && running >= 1 {
            return true;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    false
}

/// The results.csv rows as maps of column → cell.
fn results(dir: &Path) -> Vec<std::collections::BTreeMap<String, String>> {
    let text = std::fs::read_to_string(dir.join("results.csv")).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_string)
        .collect();
    lines
        .map(|l| {
            header
                .iter()
                .cloned()
                .zip(l.split(',').map(str::to_string))
                .collect()
        })
        .collect()
}

/// The last force of a run folder's force_displacement.csv.
fn final_force(run: &Path) -> f64 {
    let text = std::fs::read_to_string(run.join("force_displacement.csv")).unwrap();
    let line = text.lines().rfind(|l| !l.starts_with('#')).unwrap();
    let header = text.lines().find(|l| !l.starts_with('#')).unwrap();
    let col = header
        .split(',')
        .position(|h| h.trim() == "force [N]")
        .unwrap();
    line.split(',').nth(col).unwrap().trim().parse().unwrap()
}

/// Starts the 3 × 2 grid (element size 4 mm, one point at a time) in a
/// child process and waits until one point is complete and another
/// running: the temporary folder, the sweep folder, the child, and whether
/// that moment came.
fn start_half_way() -> (tempfile::TempDir, PathBuf, std::process::Child, bool) {
    let tmp = tempfile::tempdir().unwrap();
    let sweep = sweep_file(tmp.path(), 4.0, "");
    let dir = tmp.path().join("out");
    let child = Command::new(ncform())
        .args([
            "sweep",
            sweep.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
            "--jobs",
            "1",
            "--quiet",
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let half_way = wait_half_way(&dir, Duration::from_secs(120));
    (tmp, dir, child, half_way)
}

#[test]
fn a_killed_sweep_resumes_and_equals_direct_runs() {
    let (tmp, dir, mut child, half_way) = start_half_way();
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    assert!(half_way, "no point was complete while another ran");
    let killed: Vec<PathBuf> = points(&dir)
        .into_iter()
        .filter(|p| status_of(p).as_deref() == Some("running"))
        .collect();
    assert_eq!(killed.len(), 1, "one point was running when killed");
    // The status names the killed point as running-but-not-running.
    let out = ncform_with(&["sweep", dir.to_str().unwrap(), "--status"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains("killed"), "{text}");

    let out = ncform_with(&[
        "sweep",
        dir.to_str().unwrap(),
        "--resume",
        "--jobs",
        "1",
        "--quiet",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for p in points(&dir) {
        assert_eq!(
            status_of(&p).as_deref(),
            Some("complete"),
            "{}",
            p.display()
        );
        // One run folder per point: no `.previous` pile-up, no partial
        // outputs of the killed attempt.
        let names: Vec<String> = std::fs::read_dir(&p)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert!(
            names
                .iter()
                .all(|n| !n.contains("previous") && !n.contains(".tmp-")),
            "{names:?}"
        );
        let run_status = std::fs::read_to_string(p.join("run/status.json")).unwrap();
        assert!(run_status.contains("\"complete\""), "{run_status}");
    }
    // A second resume runs nothing.
    let out = ncform_with(&["sweep", dir.to_str().unwrap(), "--resume", "--quiet"]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("6 complete before, 0 run now"));

    let out = ncform_with(&["collect", dir.to_str().unwrap()]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = results(&dir);
    assert_eq!(rows.len(), 6);
    for (i, row) in rows.iter().enumerate() {
        // The point's case, run directly, gives the same final force. Both
        // are the same deterministic quasi-static solve (sequential
        // factorisation), so 1e-9 relative allows only for the CSV's
        // printing.
        let direct = tmp.path().join(format!("direct-{i}"));
        let case = dir.join(format!("points/{i:04}/case.toml"));
        let st = Command::new(ncform())
            .args([
                "run",
                case.to_str().unwrap(),
                "--out",
                direct.to_str().unwrap(),
                "--quiet",
            ])
            .stdout(Stdio::null())
            .status()
            .unwrap();
        assert!(st.success());
        let swept: f64 = row["force_final [N]"].parse().unwrap();
        let f = final_force(&direct);
        assert!(
            ((swept - f) / f).abs() < 1e-9,
            "point {i}: sweep {swept} N, direct {f} N"
        );
    }
    // The force rises with the shear parameter at each end displacement.
    for d in ["40.0", "60.0"] {
        let forces: Vec<f64> = rows
            .iter()
            .filter(|r| r["loading.displacement"] == d)
            .map(|r| r["force_final [N]"].parse().unwrap())
            .collect();
        assert_eq!(forces.len(), 3);
        assert!(
            forces[0] < forces[1] && forces[1] < forces[2],
            "at {d} mm: {forces:?}"
        );
    }
    assert!(dir.join("plots/force_final_N.png").is_file());
    assert!(dir.join("plots/force_final_N-map.png").is_file());
}

#[test]
fn a_terminated_sweep_marks_its_point_interrupted_and_resumes() {
    let (_tmp, dir, child, half_way) = start_half_way();
    // SIGTERM, as a scheduler's time limit sends first.
    // SAFETY: kill(2) on the child's pid.
    unsafe { libc::kill(child.id() as i32, libc::SIGTERM) };
    let out = child.wait_with_output().unwrap();
    assert!(half_way);
    let states: Vec<Option<String>> = points(&dir).iter().map(|p| status_of(p)).collect();
    if out.status.code() == Some(4) {
        assert!(
            states.iter().any(|s| s.as_deref() == Some("interrupted")),
            "{states:?}"
        );
        assert!(
            states.iter().any(Option::is_none),
            "points after the interrupt are not started: {states:?}"
        );
    }
    let out = ncform_with(&["sweep", dir.to_str().unwrap(), "--resume", "--quiet"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for p in points(&dir) {
        assert_eq!(status_of(&p).as_deref(), Some("complete"));
    }
}

#[test]
fn bad_keys_and_values_are_refused_before_anything_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let cases = [
        (
            "[[vary]]\nkey = \"loading.displacment\"\nvalues = [30.0]\n",
            "displacment",
        ),
        (
            "[[vary]]\nkey = \"material.thickness\"\nvalues = [\"thick\"]\n",
            "material.thickness",
        ),
        (
            "[[vary]]\nkey = \"material.w6.c_mid\"\nvalues = [-1.0]\n",
            "c_mid",
        ),
        ("[[vary]]\nkey = \"tool[1].mass\"\nvalues = [1.0]\n", "tool"),
        (
            "[[set]]\nkey = \"specimen.length\"\nvalue = 50.0\n",
            "loading.displacement",
        ),
    ];
    for (i, (extra, named)) in cases.iter().enumerate() {
        let sub = tmp.path().join(format!("c{i}"));
        std::fs::create_dir_all(&sub).unwrap();
        let sweep = sweep_file(&sub, 10.0, extra);
        let dir = sub.join("out");
        let out = ncform_with(&[
            "sweep",
            sweep.to_str().unwrap(),
            "--out",
            dir.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(err.contains(named), "case {i}: {err}");
        assert!(!dir.exists(), "case {i}: the folder was made");
    }
}

/// The points of a prepared sweep: each point's values by key.
fn prepared(dir: &Path) -> Vec<std::collections::BTreeMap<String, f64>> {
    let m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("sweep.json")).unwrap()).unwrap();
    m["points"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            p["values"]
                .as_array()
                .unwrap()
                .iter()
                .map(|kv| (kv[0].as_str().unwrap().to_string(), kv[1].as_f64().unwrap()))
                .collect()
        })
        .collect()
}

fn prepare(tmp: &Path, name: &str, body: &str) -> PathBuf {
    let case = repo().join("cases/oat45.toml");
    let sweep = tmp.join(format!("{name}.toml"));
    std::fs::write(
        &sweep,
        format!(
            "case = \"{}\"\n{body}\n[[set]]\nkey = \"mesh.element_size\"\nvalue = 10.0\n[[set]]\nkey = \"loading.output_displacements\"\nvalue = []\n",
            case.display()
        ),
    )
    .unwrap();
    let dir = tmp.join(name);
    let out = ncform_with(&[
        "sweep",
        sweep.to_str().unwrap(),
        "--out",
        dir.to_str().unwrap(),
        "--prepare-only",
    ]);
    assert!(
        out.status.success(),
        "{name}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}

#[test]
fn each_design_places_its_points() {
    let tmp = tempfile::tempdir().unwrap();
    let two = "[[vary]]\nkey = \"material.w6.s_ini\"\nrange = [0.012, 0.024]\n[[vary]]\nkey = \"material.thickness\"\nrange = [0.2, 0.4]\n";
    // Latin hypercube: one point per stratum of each factor.
    let p = prepared(&prepare(
        tmp.path(),
        "lhs",
        &format!("design = \"lhs\"\ncount = 8\n{two}"),
    ));
    assert_eq!(p.len(), 8);
    let mut strata: Vec<usize> = p
        .iter()
        .map(|v| ((v["material.thickness"] - 0.2) / 0.2 * 8.0).floor() as usize)
        .collect();
    strata.sort_unstable();
    assert_eq!(strata, (0..8).collect::<Vec<_>>());
    // Sobol': n (d + 2) points; Morris: r (d + 1).
    assert_eq!(
        prepared(&prepare(
            tmp.path(),
            "sobol",
            &format!("design = \"sobol\"\ncount = 4\n{two}")
        ))
        .len(),
        16
    );
    assert_eq!(
        prepared(&prepare(
            tmp.path(),
            "morris",
            &format!("design = \"morris\"\ncount = 3\n{two}")
        ))
        .len(),
        9
    );
    // One at a time: the base case, then each factor's other levels.
    let oat = "design = \"one-at-a-time\"\n[[vary]]\nkey = \"material.w6.s_ini\"\nvalues = [0.012, 0.018, 0.024]\n[[vary]]\nkey = \"material.thickness\"\nvalues = [0.2, 0.3]\n";
    let p = prepared(&prepare(tmp.path(), "oat", oat));
    assert_eq!(p.len(), 1 + 2 + 1, "{p:?}");
    assert_eq!(
        (p[0]["material.w6.s_ini"], p[0]["material.thickness"]),
        (0.018, 0.3)
    );
}

#[test]
fn a_fits_correlated_parameters_are_sampled_with_their_correlation() {
    let tmp = tempfile::tempdir().unwrap();
    // A fit's report: two parameters, 10 % σ, correlation 0.8.
    let fit = serde_json::json!({
        "parameters": {
            "w6.s_ini": {"value": 0.018, "sigma": 0.0018},
            "w6.c_ini": {"value": 0.14, "sigma": 0.014},
        },
        "parameter_order": ["w6.s_ini", "w6.c_ini"],
        "correlation": [[1.0, 0.8], [0.8, 1.0]],
    });
    std::fs::write(tmp.path().join("fit.json"), fit.to_string()).unwrap();
    let n = 400;
    let p = prepared(&prepare(
        tmp.path(),
        "robust",
        &format!("design = \"lhs\"\ncount = {n}\n[correlated]\nfit = \"fit.json\"\n"),
    ));
    assert_eq!(p.len(), n);
    let xs: Vec<f64> = p.iter().map(|v| v["material.w6.s_ini"]).collect();
    let ys: Vec<f64> = p.iter().map(|v| v["material.w6.c_ini"]).collect();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (mx, my) = (mean(&xs), mean(&ys));
    let cov = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (x - mx) * (y - my))
        .sum::<f64>();
    let vx = xs.iter().map(|x| (x - mx).powi(2)).sum::<f64>();
    let vy = ys.iter().map(|y| (y - my).powi(2)).sum::<f64>();
    let r = cov / (vx * vy).sqrt();
    // The sample correlation's standard error is (1 - ρ²)/√n = 0.018 at
    // n = 400: within 3 of them.
    assert!(
        (r - 0.8).abs() < 3.0 * (1.0 - 0.64) / (n as f64).sqrt(),
        "r = {r}"
    );
    // Means within 4 standard errors of the fitted values.
    assert!(
        (mx - 0.018).abs() < 4.0 * 0.0018 / (n as f64).sqrt(),
        "{mx}"
    );
    // Each point's parameter file carries its values.
    let text = std::fs::read_to_string(tmp.path().join("robust/points/0000/params-material.toml"))
        .unwrap();
    assert!(
        text.contains(&format!("s_ini = {}", p[0]["material.w6.s_ini"])),
        "{text}"
    );
}
