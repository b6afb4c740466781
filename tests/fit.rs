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
