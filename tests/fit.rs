//! `ncform fit` end to end on coarse copies of the shipped OATs
//! (`docs/fit.md`): recovery of a perturbed parameter set from noise-free
//! synthetic data, the Mahalanobis distance of a fit to noisy data under
//! the reported covariance, and the identifiability report with forces
//! alone and with the MDZ strains.

mod fit_common;

use fit_common::{Data, TEN, mahalanobis, truth, value_of, write_fit};
use ncform::fit::evaluate::scaled_parameters;
use ncform::fit::input::FitSpec;
use ncform::fit::run::fit;
use ncform::solver::CancelToken;

#[test]
fn noise_free_data_give_back_the_perturbed_set() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write_fit(
        dir.path(),
        &TEN,
        Data {
            strains: true,
            seed: None,
            start_at_truth: false,
            dense: false,
        },
    );
    let spec = FitSpec::load(&path).expect("the fit file");
    let outcome = fit(&spec, |_, _| {}, &CancelToken::default()).expect("the fit");
    assert!(outcome.converged(), "{:?}", outcome.stop);
    let truth = truth();
    let id = outcome.identifiability.as_ref().expect("at the optimum");
    // Derived tolerance, in the scaled parameters θ (logarithms, or values
    // over a scale): the synthetic data and the fit's forward runs carry
    // the forward solves' error δr (in noise units); it moves θ by
    // ‖J⁺ δr‖ ≤ ‖P δr‖/σ_min(J), P the projection on J's range. At the
    // optimum the residual is the rest of δr, ‖(1 − P) δr‖ = ‖r‖; for an
    // error spread over n = 144 entries the part in a p = 10 dimensional
    // range is about √(p/(n − p)) ≈ 0.27 of that, so ‖r‖/σ_min bounds the
    // move with a margin of about 3.7. Plus the optimiser's stopping step
    // (`tolerance` on ‖δθ‖ relative to ‖θ‖).
    let parameters = scaled_parameters(&spec).expect("the parameters");
    let smallest = id.singular_values.last().copied().expect("singular values");
    let theta_norm = parameters
        .iter()
        .map(|p| p.theta(value_of(&truth, &p.key)).powi(2))
        .sum::<f64>()
        .sqrt();
    let tolerance = spec.options.tolerance;
    let bound = id.chi2.sqrt() / smallest + tolerance * (theta_norm + tolerance);
    eprintln!(
        "χ² {:.3e}, σ_min {smallest:.3e}: bound on |Δθ| {bound:.3e}",
        id.chi2
    );
    for (p, fitted) in parameters.iter().zip(&outcome.parameters) {
        let expected = value_of(&truth, &p.key);
        let error = (p.theta(fitted.value) - p.theta(expected)).abs();
        eprintln!(
            "{}: {} (truth {expected}), |Δθ| {error:.2e}",
            p.key, fitted.value
        );
        assert!(error <= bound, "{}: |Δθ| {error:.3e} > {bound:.3e}", p.key);
    }
}

#[test]
fn noisy_data_stay_within_the_reported_uncertainty() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write_fit(
        dir.path(),
        &TEN,
        Data {
            strains: true,
            seed: Some(17),
            start_at_truth: false,
            dense: true,
        },
    );
    let spec = FitSpec::load(&path).expect("the fit file");
    let outcome = fit(&spec, |_, _| {}, &CancelToken::default()).expect("the fit");
    assert!(outcome.converged(), "{:?}", outcome.stop);
    let truth = truth();
    let distance = mahalanobis(&outcome, &truth);
    // χ²₁₀ 99 % quantile: 23.209 (tables; scipy.stats.chi2.ppf(0.99, 10)).
    eprintln!("Mahalanobis distance {distance:.3} (99 % quantile of χ²₁₀: 23.209)");
    assert!(distance <= 23.209, "distance {distance}");
}

#[test]
fn forces_alone_leave_parameters_undetermined_and_strains_fix_them() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (strains, expect_poor) in [(false, true), (true, false)] {
        // The report at the truth (the fit starts there; no iteration).
        let path = write_fit(
            dir.path(),
            &TEN,
            Data {
                strains,
                seed: None,
                start_at_truth: true,
                dense: true,
            },
        );
        let mut spec = FitSpec::load(&path).expect("the fit file");
        spec.options.max_iterations = 0;
        let outcome = fit(&spec, |_, _| {}, &CancelToken::default()).expect("the fit");
        let poor: Vec<&String> = outcome
            .warnings
            .iter()
            .filter(|w| w.contains("poorly determined"))
            .collect();
        eprintln!("strains {strains}: {:#?}", outcome.warnings);
        assert_eq!(!poor.is_empty(), expect_poor, "strains {strains}: {poor:?}");
    }
}

/// The command writes every output of a converged fit, and a fit whose
/// forward runs fail at the start writes what it has, says why and exits
/// "incomplete" (3).
#[test]
fn the_command_writes_its_outputs_and_a_failed_start_says_why() {
    use ncform::cli::fit::fit_command;
    use ncform::report::ExitStatus;
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write_fit(
        dir.path(),
        &["w6.c_ini", "w8.c_ini"],
        Data {
            strains: true,
            seed: Some(3),
            start_at_truth: false,
            dense: false,
        },
    );
    let out = dir.path().join("out");
    let status =
        fit_command(&path, Some(out.clone()), true, &CancelToken::default()).expect("the fit runs");
    assert_eq!(status, ExitStatus::Complete);
    for file in [
        "fitted.toml",
        "fit.json",
        "fit.csv",
        "fit_curves.csv",
        "fit_oat30.png",
        "fit_oat45.png",
        "fit_oat60.png",
        "correlation.png",
        "status.json",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    // fitted.toml is a parameter file a case uses unchanged.
    let fitted =
        ncform::material::MaterialSpec::load(&out.join("fitted.toml").display().to_string())
            .expect("fitted.toml reads back");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fit.json")).expect("fit.json"))
            .expect("valid JSON");
    let value = json["parameters"]["w6.c_ini"]["value"]
        .as_f64()
        .expect("a value");
    assert_eq!(value_of(&fitted, "w6.c_ini"), value);

    // Forward runs that cannot converge: one Newton iteration per step and
    // no cut-back below the first increment.
    for angle in fit_common::ANGLES {
        let case = dir.path().join(format!("oat{angle}.toml"));
        let text = std::fs::read_to_string(&case).expect("case");
        std::fs::write(
            &case,
            format!("{text}\n[solver]\nmax_iterations = 1\nmin_increment = 1.0\n"),
        )
        .expect("write");
    }
    let out = dir.path().join("failed");
    let status =
        fit_command(&path, Some(out.clone()), true, &CancelToken::default()).expect("the fit runs");
    assert_eq!(status, ExitStatus::Incomplete);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("fit.json")).expect("fit.json"))
            .expect("valid JSON");
    let warnings = json["warnings"].to_string();
    assert!(warnings.contains("could not start"), "{warnings}");
    assert!(!out.join("fitted.toml").exists());
    let status_json = std::fs::read_to_string(out.join("status.json")).expect("status.json");
    assert!(status_json.contains("StartFailed"), "{status_json}");
}

/// A free displacement offset (slack at the start of a test) is found:
/// measured rows written 1 mm late (`d_meas = d_sim + 1`), the fit frees
/// the offset and W6's initial modulus and recovers δ within 3 of its
/// reported σ (a sign error would put it 2 mm, some twenty σ, away).
#[test]
fn a_free_offset_is_recovered() {
    let dir = tempfile::tempdir().expect("temp dir");
    let angle = 45.0;
    std::fs::write(
        dir.path().join("oat45.toml"),
        fit_common::coarse_case(angle),
    )
    .expect("write");
    let start = ncform::material::MaterialSpec::default_set();
    let rows = fit_common::synthetic(dir.path(), angle, &start, &fit_common::dense_rows());
    let slack = 1.0;
    let mut csv = String::from("# synthetic, 1 mm of slack\ndisplacement [mm],force [N]\n");
    for r in rows.iter().filter(|r| r[0] + slack <= fit_common::STROKE) {
        csv.push_str(&format!("{},{}\n", r[0] + slack, r[1]));
    }
    std::fs::write(dir.path().join("oat45.csv"), csv).expect("write");
    let schedule: Vec<f64> = (1..=11).map(|k| 5.0 * k as f64).collect();
    let text = format!(
        "title = \"offset\"\nparams = \"schaefer2024\"\nfree = [\"w6.c_ini\"]\n[fit]\nmax_iterations = 40\n\n[[test]]\ncase = \"oat45.toml\"\nmeasured = \"oat45.csv\"\nnoise = {{ force = {{ relative = 0.02, absolute = 0.01 }} }}\noffset = {{ free = true, start = 0.0, bounds = [-2.0, 2.0] }}\ndisplacements = {schedule:?}\n"
    );
    let path = dir.path().join("fit.toml");
    std::fs::write(&path, text).expect("write");
    let spec = FitSpec::load(&path).expect("the fit file");
    let outcome = fit(&spec, |_, _| {}, &CancelToken::default()).expect("the fit");
    assert!(outcome.converged(), "{:?}", outcome.stop);
    let offset = outcome
        .parameters
        .iter()
        .find(|p| p.key.starts_with("offset."))
        .expect("the offset is a fitted parameter");
    eprintln!("offset {} ± {}", offset.value, offset.sigma);
    assert!(
        (offset.value - slack).abs() <= 3.0 * offset.sigma,
        "offset {} ± {} (slack {slack})",
        offset.value,
        offset.sigma
    );
}
