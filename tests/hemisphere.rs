//! The hemisphere forming bench (`docs/forming.md`), coarse: the shipped
//! cases `cases/hemisphere-0.toml` and `cases/hemisphere-45.toml` with a
//! coarser blank, run through the same code path as `ncform run`. The
//! paper-size runs are in `verification/` and `docs/benchmarks.md`.
//!
//! Each test names the requirement it checks and where its tolerance comes
//! from.

use std::fs;
use std::path::{Path, PathBuf};

use ncform::case::forming::FormingCase;
use ncform::report::Progress;
use ncform::report::files::run_forming;
use ncform::report::forming::FormingSummary;
use ncform::solver::RunStatus;
use tempfile::TempDir;

/// Cells per side of the coarse blank (the shipped case has 84).
const COARSE_CELLS: usize = 20;

fn cases_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("cases")
}

/// The shipped case `name` with a `cells × cells` blank and the edits.
fn coarse(name: &str, cells: usize, edits: &[(&str, &str)]) -> FormingCase {
    let mut text = fs::read_to_string(cases_dir().join(name)).unwrap();
    assert!(
        text.contains("cells = [84, 84]"),
        "no 84-cell blank in {name}"
    );
    // Every ply's blank.
    text = text.replace("cells = [84, 84]", &format!("cells = [{cells}, {cells}]"));
    for (from, to) in edits {
        assert!(text.contains(from), "`{from}` not in {name}");
        text = text.replacen(from, to, 1);
    }
    FormingCase::from_toml_str(&text, name, &cases_dir()).unwrap_or_else(|e| panic!("{e}"))
}

fn run(case: &FormingCase, out: &Path) -> FormingSummary {
    let summary = run_forming(case, out, Progress::Quiet).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(summary.status, RunStatus::Complete, "{}", case.title);
    summary
}

/// The outer contour of `outer_contour.csv`: reference and final
/// positions per boundary node (of the first ply).
fn final_contour(out: &Path) -> Vec<([f64; 2], [f64; 2])> {
    ply_contour(out, 1)
}

/// The outer contour of ply `ply` (1-based, the CSV's first column).
fn ply_contour(out: &Path, ply: usize) -> Vec<([f64; 2], [f64; 2])> {
    let text = fs::read_to_string(out.join("outer_contour.csv")).unwrap();
    let mut rows = Vec::new();
    for line in text.lines().filter(|l| !l.starts_with('#')).skip(1) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        let n = v.len();
        if v[0] as usize == ply {
            rows.push(([v[2], v[3]], [v[n - 2], v[n - 1]]));
        }
    }
    rows
}

/// The largest distance between the final position of a boundary node and
/// the mirror image of the final position of the node at its mirrored
/// reference position, over the nodes whose mirror is a node.
fn mirror_deviation(contour: &[([f64; 2], [f64; 2])], mirror: fn([f64; 2]) -> [f64; 2]) -> f64 {
    let mut worst: f64 = 0.0;
    let mut matched = 0;
    for (reference, formed) in contour {
        let target = mirror(*reference);
        if let Some((_, other)) = contour
            .iter()
            .find(|(r, _)| (r[0] - target[0]).abs() < 1e-6 && (r[1] - target[1]).abs() < 1e-6)
        {
            let image = mirror(*other);
            worst = worst.max((image[0] - formed[0]).hypot(image[1] - formed[1]));
            matched += 1;
        }
    }
    assert!(
        matched >= contour.len() / 2,
        "{matched} of {} nodes mirrored",
        contour.len()
    );
    worst
}

/// Requirement: the explicit [0°] run is quasi-static and balanced — the
/// kinetic energy below 5 % of the internal energy from 10 % of the stroke
/// on and the energy-balance error below 1 % (the required limits, which the
/// case's warning levels also use) — and no warning is raised; its outer
/// contour is mirror-symmetric about both blank axes within 1 mm (the
/// required limit; the bench is symmetric, the mesh's cut diagonals are not,
/// so the deviation measures the mesh's bias); the draw-in is positive at
/// every edge midpoint and corner, and larger at the midpoints (the
/// blank's corners are held in the flange) — and the written outputs exist.
#[test]
fn hemisphere_0_explicit_is_quasi_static_balanced_and_symmetric() {
    let case = coarse("hemisphere-0.toml", COARSE_CELLS, &[]);
    let out = TempDir::new().unwrap();
    let summary = run(&case, out.path());
    let explicit = summary.explicit.as_ref().unwrap();
    // The shipped roving mass scaling, as the summary reports it.
    assert_eq!(explicit.mass.coupling_form, "stretch");
    assert_eq!(explicit.mass.coupled_nodes, 21 * 21);
    assert!(
        explicit.max_kinetic_ratio < 0.05,
        "KE/IE {}",
        explicit.max_kinetic_ratio
    );
    assert!(
        explicit.max_relative_balance_error < 0.01,
        "balance {}",
        explicit.max_relative_balance_error
    );
    assert!(explicit.warnings.is_empty(), "{:?}", explicit.warnings);
    let contour = final_contour(out.path());
    let about_x = mirror_deviation(&contour, |p| [p[0], -p[1]]);
    let about_y = mirror_deviation(&contour, |p| [-p[0], p[1]]);
    assert!(about_x < 1.0 && about_y < 1.0, "{about_x} {about_y}");
    let last = summary.forming.states.last().unwrap();
    let draw_in = &last.draw_in[0];
    for d in draw_in {
        assert!(*d > 0.0, "{draw_in:?}");
    }
    assert!(
        draw_in[..4]
            .iter()
            .all(|m| draw_in[4..].iter().all(|c| m > c)),
        "{draw_in:?}"
    );
    for file in [
        "forming.csv",
        "forming.png",
        "outer_contour.csv",
        "outer_contour.png",
        "maps/ply_0005.png",
        "maps/ply-dic_0005.png",
        "vtu/ply-dic_0005.vtu",
        "energy.csv",
        "summary.json",
    ] {
        assert!(out.path().join(file).exists(), "{file}");
    }
    let header = fs::read_to_string(out.path().join("forming.csv")).unwrap();
    assert!(header.lines().any(|l| l.starts_with("# units: mm, N")));
}

/// Requirement: the [45°] contour is mirror-symmetric about the rovings'
/// diagonal x = y within 1 mm (the required limit; the mesh, cut along that
/// diagonal, has the symmetry too, so only round-off and the explicit
/// dynamics' growth of asymmetry remain).
#[test]
fn hemisphere_45_explicit_contour_is_symmetric_about_the_rovings() {
    let case = coarse("hemisphere-45.toml", COARSE_CELLS, &[]);
    let out = TempDir::new().unwrap();
    let summary = run(&case, out.path());
    assert!(summary.explicit.as_ref().unwrap().max_kinetic_ratio < 0.05);
    let contour = final_contour(out.path());
    let about_diagonal = mirror_deviation(&contour, |p| [p[1], p[0]]);
    assert!(about_diagonal < 1.0, "{about_diagonal}");
}

/// Requirement (two plies, ply–ply contact): the explicit [0°/90°] run
/// completes with its energy balance within 1 % (the required limit, the
/// case's warning level; ply–ply contact's stored and dissipated energy
/// in the balance), and both plies draw in at every edge midpoint.
///
/// Not asserted, because it does not hold on a mesh this coarse: the
/// required kinetic energy below 5 % of the internal energy. With the
/// shipped roving mass scaling the two plies burst on coarse meshes (KE/IE
/// at most 23.4 % at 20 cells, 11.0 % at 24, 16.6 % at 30; the case's
/// warning reports it) and stay below 5 % from 42 cells on (4.13 % at 42,
/// 96 s; 3.56 % at 84, checked by `verification/full_validation.py`;
/// `docs/verification.md`). Nor the contours' mirror symmetry about the
/// blank axes, which the bursts break.
#[test]
fn hemisphere_0_90_explicit_is_balanced_and_draws_in() {
    let case = coarse("hemisphere-0-90.toml", COARSE_CELLS, &[]);
    let out = TempDir::new().unwrap();
    let summary = run(&case, out.path());
    let explicit = summary.explicit.as_ref().unwrap();
    assert!(
        explicit.max_relative_balance_error < 0.01,
        "balance {}",
        explicit.max_relative_balance_error
    );
    let last = summary.forming.states.last().unwrap();
    for draw_in in &last.draw_in {
        assert!(draw_in[..4].iter().all(|d| *d > 0.0), "{draw_in:?}");
    }
}

/// The punch force of each history row against its stroke.
fn force_curve(summary: &FormingSummary) -> Vec<(f64, f64)> {
    summary
        .history
        .iter()
        .map(|r| (r.stroke, r.tools[2].force))
        .collect()
}

/// Linear interpolation of `curve` (increasing x) at `x`.
fn interpolate(curve: &[(f64, f64)], x: f64) -> f64 {
    let k = curve.partition_point(|p| p.0 < x).clamp(1, curve.len() - 1);
    let ((x0, y0), (x1, y1)) = (curve[k - 1], curve[k]);
    if x1 == x0 {
        y1
    } else {
        y0 + (y1 - y0) * (x - x0) / (x1 - x0)
    }
}

/// The cross-check's measures of an explicit run `e` against a
/// quasi-static run `q` (output folders `out_e`, `out_q`), asserted within
/// the required limits: the punch force within 3 % RMS of the peak, the
/// final outer contours within 1 mm RMS.
struct Agreement {
    /// RMS over the quasi-static rows of the explicit punch force
    /// (interpolated at their depths) minus the quasi-static one \[N\].
    force_rms: f64,
    /// The quasi-static run's largest punch force \[N\].
    peak: f64,
    /// RMS distance of the final outer contours, node by node \[mm\].
    contour_rms: f64,
}

fn assert_agreement(
    e: &FormingSummary,
    q: &FormingSummary,
    out_e: &Path,
    out_q: &Path,
) -> Agreement {
    let (fe, fq) = (force_curve(e), force_curve(q));
    let peak = fq.iter().fold(0.0f64, |m, p| m.max(p.1));
    let force_rms = (fq
        .iter()
        .map(|&(x, f)| (interpolate(&fe, x) - f).powi(2))
        .sum::<f64>()
        / fq.len() as f64)
        .sqrt();
    let (ce, cq) = (final_contour(out_e), final_contour(out_q));
    assert_eq!(ce.len(), cq.len());
    let contour_rms = (ce
        .iter()
        .zip(&cq)
        .map(|(a, b)| (a.1[0] - b.1[0]).powi(2) + (a.1[1] - b.1[1]).powi(2))
        .sum::<f64>()
        / ce.len() as f64)
        .sqrt();
    assert!(
        force_rms < 0.03 * peak,
        "force RMS {force_rms} N against peak {peak} N"
    );
    assert!(contour_rms < 1.0, "contour RMS {contour_rms} mm");
    Agreement {
        force_rms,
        peak,
        contour_rms,
    }
}

/// Requirement: the explicit [0°] run agrees with the quasi-static one —
/// punch force within 3 % RMS of the peak force, outer contour within 1 mm
/// RMS at the final depth, zone shear within 1.5° at every output depth
/// (the required limits for the paper-size cross-check, applied here to a
/// 12 × 12-cell blank pushed 20 mm, the depth the coarse quasi-static path
/// reaches in seconds). The explicit punch follows the shipped programme's
/// speed (depth 75 mm · (t / T)², T the case's `duration`), so it reaches
/// 20 mm after T · √(20/75).
#[test]
fn hemisphere_0_explicit_agrees_with_quasi_static() {
    let text = fs::read_to_string(cases_dir().join("hemisphere-0.toml")).unwrap();
    let shipped_line = text
        .lines()
        .find(|l| l.starts_with("duration = "))
        .expect("the case sets its duration");
    let shipped: f64 = shipped_line["duration = ".len()..]
        .split('#')
        .next()
        .and_then(|v| v.trim().parse().ok())
        .expect("a number");
    let duration = format!("duration = {}", shipped * (20.0f64 / 75.0).sqrt());
    let shallow = [("displacement = 75.0", "displacement = 20.0")];
    let explicit = coarse(
        "hemisphere-0.toml",
        12,
        &[shallow[0], (shipped_line, duration.as_str())],
    );
    let quasi_static = coarse(
        "hemisphere-0.toml",
        12,
        &[
            shallow[0],
            // The default solver; the [solver] table takes the step sizes.
            ("solver = \"explicit\"", ""),
            (
                "[gravity]",
                "[solver]\ninitial_increment = 0.05\nmax_increment = 0.1\n\n[gravity]",
            ),
        ],
    );
    let (out_e, out_q) = (TempDir::new().unwrap(), TempDir::new().unwrap());
    let e = run(&explicit, out_e.path());
    let q = run(&quasi_static, out_q.path());
    let Agreement {
        force_rms: rms,
        peak,
        contour_rms,
    } = assert_agreement(&e, &q, out_e.path(), out_q.path());
    assert_eq!(e.forming.states.len(), q.forming.states.len());
    let mut worst_zone: f64 = 0.0;
    for (a, b) in e.forming.states.iter().zip(&q.forming.states) {
        for (za, zb) in a.zones.iter().zip(&b.zones) {
            let d = (za.shear_angle_mean - zb.shear_angle_mean).abs();
            worst_zone = worst_zone.max(d);
            assert!(
                d < 1.5,
                "{} mm: {} vs {}",
                b.stroke,
                za.shear_angle_mean,
                zb.shear_angle_mean
            );
        }
    }
    eprintln!(
        "explicit vs quasi-static to 20 mm: force RMS {:.2} % of the peak {peak:.3} N, contour RMS {contour_rms:.3} mm, zone shear within {worst_zone:.3} deg",
        100.0 * rms / peak
    );
}

/// The settings with which the quasi-static path passes the flange's
/// loss of stability to the full depth (`docs/solver.md`, "Forming: the
/// hemisphere to full depth"): the contact's kinks rounded, the automatic
/// viscous stabilisation, 60 iterations per attempt and steps down to
/// 1e-6 of the stroke.
const FULL_DEPTH_CONTACT: &str = "[contact]\nnormal_smoothing = 0.02\nfriction_smoothing = 0.2\n\n";
const FULL_DEPTH_SOLVER: &str =
    "[solver]\nstabilisation = \"automatic\"\nmax_iterations = 60\nmin_increment = 1e-6\n\n";

/// Requirement: the quasi-static path reaches the full depth (75 mm) with
/// the settings above, its viscous dissipation below 1 % of the internal
/// energy (the required bound), and agrees with the explicit run of the
/// same 12 × 12-cell blank: punch force within 3 % RMS of the peak, outer
/// contour within 1 mm RMS at 75 mm (the required limits). The zone shear
/// angles are compared to 20 mm in
/// `hemisphere_0_explicit_agrees_with_quasi_static`; deeper, a 20 mm zone
/// window on 25 mm cells averages one or two elements, which the two paths
/// shear differently once the flange wrinkles (measured 2.1° apart at
/// 60 mm here, 0.5° on 24 × 24 cells: `docs/solver.md`).
#[test]
fn hemisphere_0_quasi_static_reaches_full_depth_and_agrees_with_explicit() {
    let pair = FullDepthPair::run(FULL_DEPTH_SOLVER);
    eprintln!(
        "quasi-static to 75 mm ({} steps, dissipated {:.3} % of the internal energy) against explicit: force RMS {:.2} % of the peak {:.3} N, contour RMS {:.3} mm",
        pair.quasi_static.history.len(),
        100.0 * pair.dissipation_ratio,
        100.0 * pair.agreement.force_rms / pair.agreement.peak,
        pair.agreement.peak,
        pair.agreement.contour_rms
    );
}

/// The explicit and the quasi-static run (with `solver_settings` and the
/// rounded kinks) of the 12 × 12-cell [0°] blank, checked for what both
/// full-depth recipes must give: the quasi-static run reaches 75 mm, its
/// dissipation (viscous or inertial) below 1 % of the internal energy
/// (the required bound), and the two agree (`assert_agreement`: punch
/// force within 3 % RMS of the peak, outer contour within 1 mm RMS at
/// 75 mm; the required limits).
struct FullDepthPair {
    quasi_static: FormingSummary,
    dissipation_ratio: f64,
    agreement: Agreement,
}

impl FullDepthPair {
    fn run(solver_settings: &str) -> Self {
        let explicit = coarse("hemisphere-0.toml", 12, &[]);
        let settings = format!("{FULL_DEPTH_CONTACT}{solver_settings}[gravity]");
        let quasi_static = coarse(
            "hemisphere-0.toml",
            12,
            &[
                ("solver = \"explicit\"", ""),
                ("[gravity]", settings.as_str()),
            ],
        );
        let (out_e, out_q) = (TempDir::new().unwrap(), TempDir::new().unwrap());
        let e = run(&explicit, out_e.path());
        let q = run(&quasi_static, out_q.path());
        let last = q.history.last().unwrap();
        assert!(
            (last.stroke - 75.0).abs() < 1e-9,
            "reached {} mm",
            last.stroke
        );
        let (internal, dissipated, ratio) = q.stabilisation.unwrap();
        assert!(internal > 0.0 && dissipated > 0.0);
        assert!(ratio < 0.01, "dissipated/internal up to {ratio}");
        let agreement = assert_agreement(&e, &q, out_e.path(), out_q.path());
        Self {
            quasi_static: q,
            dissipation_ratio: ratio,
            agreement,
        }
    }
}

/// The implicit-dynamic settings (`docs/solver.md`, "Inertia" and
/// "Forming: the hemisphere to full depth"): the contact's kinks rounded,
/// the free dofs' inertia over a programme of 2 s starting from rest
/// (quadratic amplitude), no viscous stabilisation.
const INERTIA_SOLVER: &str = "[solver]\nmax_iterations = 60\nmin_increment = 1e-6\ninertia_duration = 2.0\ninertia_amplitude = \"quadratic\"\n\n";

/// Requirement: with inertia instead of the viscous stabilisation the
/// quasi-static path reaches the full depth, its numerical dissipation
/// below 1 % of the internal energy (the bound on a stabilisation) and
/// its kinetic energy below 5 % of the internal energy from 10 % of the
/// stroke on (the explicit path's bound: the programme is slow enough to
/// be quasi-static), and agrees with the explicit run of the same 12 × 12
/// blank: punch force within 3 % RMS of the peak, outer contour within
/// 1 mm RMS at 75 mm (the required limits).
#[test]
fn hemisphere_0_implicit_dynamic_reaches_full_depth_and_agrees_with_explicit() {
    let pair = FullDepthPair::run(INERTIA_SOLVER);
    let mut kinetic_ratio: f64 = 0.0;
    for row in pair.quasi_static.history.iter().filter(|r| r.load >= 0.1) {
        let (kinetic, internal) = (row.kinetic_energy.unwrap(), row.internal_energy.unwrap());
        kinetic_ratio = kinetic_ratio.max(kinetic / internal);
    }
    assert!(
        kinetic_ratio < 0.05,
        "kinetic/internal up to {kinetic_ratio}"
    );
    eprintln!(
        "implicit dynamics to 75 mm ({} steps, dissipated {:.3} %, kinetic up to {:.3} % of the internal energy) against explicit: force RMS {:.2} % of the peak {:.3} N, contour RMS {:.3} mm",
        pair.quasi_static.history.len(),
        100.0 * pair.dissipation_ratio,
        100.0 * kinetic_ratio,
        100.0 * pair.agreement.force_rms / pair.agreement.peak,
        pair.agreement.peak,
        pair.agreement.contour_rms
    );
}

/// Requirement (`docs/cases.md`, "Forming outputs"): an explicit run
/// stopped between two outputs — here by the cancel token, as SIGINT
/// stops it, once the first of two output states is on disk — writes the
/// state it reached as one more output state, marked, with its maps, and
/// as the last state of the contour and of `summary.json`.
#[test]
fn an_interrupted_explicit_run_writes_the_state_it_reached() {
    let case = coarse(
        "hemisphere-0.toml",
        COARSE_CELLS,
        &[("states = 5", "states = 2")],
    );
    let dir = TempDir::new().unwrap();
    let out = dir.path().join("out");
    let cancel = ncform::solver::CancelToken::new();
    let summary = std::thread::scope(|scope| {
        let run = scope.spawn(|| {
            ncform::report::files::run_forming_with(&case, &out, Progress::Quiet, &cancel)
                .unwrap_or_else(|e| panic!("{e}"))
        });
        // The first output state (half the stroke) is written during the
        // solve; the second is half a run later (1.5 s on the 2-core
        // machine), against a poll of 1 ms: the token stops the run
        // between the two unless the poll is starved for that long.
        let first = out.join("vtu").join("ply_0001.vtu");
        while !first.exists() && !run.is_finished() {
            std::thread::sleep(std::time::Duration::from_millis(1));
        }
        cancel.cancel();
        run.join().unwrap()
    });
    let RunStatus::Interrupted { load_reached } = summary.status else {
        panic!("expected an interrupted run: {:?}", summary.status);
    };
    assert!(
        load_reached > 0.5 && load_reached < 1.0,
        "stopped at {load_reached}"
    );
    let states = &summary.forming.states;
    assert_eq!(states.len(), 2, "{states:?}");
    assert_eq!(states[1].load, load_reached);
    assert_eq!(
        states[1].stroke,
        summary.history.last().unwrap().stroke,
        "the last state is the last history row"
    );
    let vtu = fs::read_to_string(out.join("vtu/ply_0002.vtu")).unwrap();
    assert!(vtu.contains(&format!(
        "programme fraction {load_reached} (last converged state)"
    )));
    for map in ["ply_0002.png", "ply-dic_0002.png", "ply-modes_0002.png"] {
        assert!(out.join("maps").join(map).is_file(), "{map}");
    }
}
