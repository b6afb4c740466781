//! The fit's speed and the honesty of its uncertainties (`docs/fit.md`,
//! `docs/benchmarks.md`).
//!
//! ```text
//! cargo bench --bench fit -- sensitivity [RUNS]   forward run alone vs with sensitivities
//! cargo bench --bench fit -- example              the shipped ten-parameter example
//! cargo bench --bench fit -- coverage [SEEDS]     coverage of the reported intervals
//! ```
//!
//! `sensitivity` runs each shipped OAT (full size, the example's
//! 16-point schedule, Newton tolerance 1e-9) RUNS times (default 3)
//! alone and with the ten parameters' sensitivities, interleaved, and
//! prints the medians and their ratio. `example` runs `cases/fit/fit.toml`
//! and prints the time, the evaluations and the error of every parameter
//! against `cases/fit/truth.toml` in units of its reported σ. `coverage`
//! fits noisy synthetic data on coarse meshes for SEEDS seeds (default
//! 100) and counts how often the truth lies within the reported 1σ and 2σ
//! of each parameter and within the χ²₁₀ 90 % and 99 % ellipsoids.

#[path = "../tests/fit_common/mod.rs"]
mod fit_common;

use std::path::Path;
use std::time::Instant;

use fit_common::{Data, TEN, mahalanobis, truth, value_of, write_fit};
use ncform::case::{Case, OatCase};
use ncform::fit::evaluate::LawSensitivity;
use ncform::fit::input::FitSpec;
use ncform::fit::run::fit;
use ncform::fit::sensitivity::SensitivityReport;
use ncform::material::{LawParameter, Material, MaterialSpec};
use ncform::report::memory::MemoryReport;
use ncform::report::{Progress, Report, run};
use ncform::solver::CancelToken;

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Wall time of one run of `case` into `report` \[s\], and its factorisations.
fn timed(case: &OatCase, report: &mut impl Report) -> (f64, usize) {
    let clock = Instant::now();
    let outcome = run(
        &Case::Oat(case.clone()),
        report,
        &mut Progress::Quiet,
        &CancelToken::default(),
    )
    .expect("the run");
    (clock.elapsed().as_secs_f64(), outcome.solved.factorisations)
}

fn sensitivity(runs: usize) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let spec = MaterialSpec::default_set();
    let Material::UdNcf(law) = spec.material else {
        unreachable!("the default set is ud-ncf")
    };
    let parameters: Vec<LawParameter> = TEN
        .iter()
        .map(|k| LawParameter::from_key(k).expect("a law key"))
        .collect();
    for angle in [30, 45, 60] {
        let path = root.join(format!("cases/oat{angle}.toml"));
        let mut case = OatCase::load(&path).expect("the shipped case");
        let schedule: Vec<f64> = (1..=16)
            .map(|k| case.displacement * k as f64 / 16.0)
            .collect();
        case.output_displacements = schedule.clone();
        case.solver.residual_tolerance = 1e-9;
        let (mut alone, mut with) = (Vec::new(), Vec::new());
        let (mut f_alone, mut f_with) = (0, 0);
        for _ in 0..runs {
            let (t, f) = timed(&case, &mut MemoryReport::new());
            alone.push(t);
            f_alone = f;
            let sensitivity = LawSensitivity {
                law,
                parameters: parameters.clone(),
            };
            let mut report = SensitivityReport::new(schedule.clone(), &sensitivity);
            let (t, f) = timed(&case, &mut report);
            with.push(t);
            f_with = f;
        }
        let (a, w) = (median(alone.clone()), median(with.clone()));
        println!(
            "OAT {angle}°: alone {a:.2} s {alone:.2?} ({f_alone} factorisations); with 10 sensitivities {w:.2} s {with:.2?} ({f_with} factorisations); ratio {:.2}",
            w / a
        );
    }
}

fn example() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let spec = FitSpec::load(&root.join("cases/fit/fit.toml")).expect("the example");
    let truth = MaterialSpec::load(&root.join("cases/fit/truth.toml").display().to_string())
        .expect("the truth");
    let clock = Instant::now();
    let outcome = fit(
        &spec,
        |it, t| eprintln!("iteration {} cost {:.6e} ({t:.1} s)", it.iteration, it.cost),
        &CancelToken::default(),
    )
    .expect("the fit");
    println!(
        "example: {:.1} s, {} evaluations, {} iterations, converged {} ({:?})",
        clock.elapsed().as_secs_f64(),
        outcome.evaluations,
        outcome.history.len().saturating_sub(1),
        outcome.converged(),
        outcome.stop
    );
    for p in &outcome.parameters {
        let t = value_of(&truth, &p.key);
        println!(
            "{:<16} start {:<10.4e} fitted {:<10.4e} truth {:<10.4e} σ {:<9.2e} ({:>5.1} %)  error {:+.2} σ",
            p.key,
            p.start,
            p.value,
            t,
            p.sigma,
            100.0 * p.sigma / p.value.abs(),
            (p.value - t) / p.sigma
        );
    }
    for w in &outcome.warnings {
        println!("warning: {w}");
    }
}

fn coverage(seeds: u64) {
    let truth = truth();
    let (mut one, mut two, mut total) = (0usize, 0usize, 0usize);
    let (mut q90, mut q99, mut fits) = (0usize, 0usize, 0usize);
    let clock = Instant::now();
    for seed in 1..=seeds {
        let dir = tempfile::tempdir().expect("temp dir");
        let path = write_fit(
            dir.path(),
            &TEN,
            Data {
                strains: true,
                seed: Some(1000 + seed),
                start_at_truth: false,
                dense: true,
            },
        );
        let spec = FitSpec::load(&path).expect("the fit file");
        let outcome = fit(&spec, |_, _| {}, &CancelToken::default()).expect("the fit");
        if !outcome.converged() {
            println!("seed {seed}: not converged ({:?})", outcome.stop);
            continue;
        }
        fits += 1;
        for p in &outcome.parameters {
            let z = ((p.value - value_of(&truth, &p.key)) / p.sigma).abs();
            one += usize::from(z <= 1.0);
            two += usize::from(z <= 2.0);
            total += 1;
        }
        let d = mahalanobis(&outcome, &truth);
        // χ²₁₀ quantiles: 90 % 15.987, 99 % 23.209.
        q90 += usize::from(d <= 15.987);
        q99 += usize::from(d <= 23.209);
    }
    let pct = |a: usize, b: usize| 100.0 * a as f64 / b.max(1) as f64;
    println!(
        "coverage over {fits} fits ({:.0} s): within 1σ {:.1} % (nominal 68.3), within 2σ {:.1} % (95.4); Mahalanobis within χ²₁₀ 90 % {:.1} % (90), 99 % {:.1} % (99)",
        clock.elapsed().as_secs_f64(),
        pct(one, total),
        pct(two, total),
        pct(q90, fits),
        pct(q99, fits)
    );
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let number =
        |i: usize, default: u64| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    match args.first().map(String::as_str) {
        Some("sensitivity") => sensitivity(number(1, 3) as usize),
        Some("example") => example(),
        Some("coverage") => coverage(number(1, 100)),
        _ => eprintln!(
            "usage: cargo bench --bench fit -- sensitivity [RUNS] | example | coverage [SEEDS]"
        ),
    }
}
