//! `ncform fit` end to end on coarse copies of the shipped OATs
//! (`docs/fit.md`): recovery of a perturbed parameter set from noise-free
//! synthetic data, the Mahalanobis distance of a fit to noisy data under
//! the reported covariance, and the identifiability report with forces
//! alone and with the MDZ strains.

mod fit_common;

use fit_common::{TEN, truth, value_of, write_fit};
use ncform::fit::input::FitSpec;
use ncform::fit::run::fit;
use ncform::solver::CancelToken;

#[test]
fn noise_free_data_give_back_the_perturbed_set() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write_fit(dir.path(), &TEN, true, None, false);
    let spec = FitSpec::load(&path).expect("the fit file");
    let outcome = fit(&spec, |_, _| {}, &CancelToken::default()).expect("the fit");
    assert!(outcome.converged(), "{:?}", outcome.stop);
    let truth = truth();
    let id = outcome.identifiability.as_ref().expect("at the optimum");
    // Derived tolerance: the synthetic data carry the forward solves'
    // error; at the optimum the residual is that error (χ² = ‖r‖²), and a
    // residual of norm ‖r‖ moves the log-parameters by at most
    // ‖r‖/σ_min(J) (the Jacobian's conditioning). In relative terms for
    // log-scaled parameters; three times that for the linear model's
    // curvature, plus the optimiser's step tolerance.
    let smallest = id.singular_values.last().copied().expect("singular values");
    let bound = 3.0 * id.chi2.sqrt() / smallest + 1e-8;
    eprintln!(
        "χ² {:.3e}, σ_min {smallest:.3e}: relative bound {bound:.3e}",
        id.chi2
    );
    for p in &outcome.parameters {
        let expected = value_of(&truth, &p.key);
        let error = (p.value - expected).abs() / expected.abs();
        eprintln!(
            "{}: {} (truth {expected}), relative error {error:.2e}",
            p.key, p.value
        );
        assert!(
            error <= bound.max(1e-6),
            "{}: relative error {error:.3e} > {bound:.3e}",
            p.key
        );
    }
}

#[test]
fn noisy_data_stay_within_the_reported_uncertainty() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = write_fit(dir.path(), &TEN, true, Some(17), false);
    let spec = FitSpec::load(&path).expect("the fit file");
    let outcome = fit(&spec, |_, _| {}, &CancelToken::default()).expect("the fit");
    assert!(outcome.converged(), "{:?}", outcome.stop);
    let truth = truth();
    let id = outcome.identifiability.as_ref().expect("at the optimum");
    // Mahalanobis distance of the error under the reported covariance,
    // Cov_ij = σ_i σ_j ρ_ij, solved by Cholesky.
    let n = outcome.parameters.len();
    let cov = nalgebra::DMatrix::from_fn(n, n, |i, j| {
        outcome.parameters[i].sigma * outcome.parameters[j].sigma * id.correlation[i][j]
    });
    let error = nalgebra::DVector::from_fn(n, |i, _| {
        outcome.parameters[i].value - value_of(&truth, &outcome.parameters[i].key)
    });
    let chol = cov.cholesky().expect("a positive definite covariance");
    let distance = error.dot(&chol.solve(&error));
    // χ²₁₀ 99 % quantile: 23.209 (tables; scipy.stats.chi2.ppf(0.99, 10)).
    eprintln!("Mahalanobis distance {distance:.3} (99 % quantile of χ²₁₀: 23.209)");
    assert!(distance <= 23.209, "distance {distance}");
}

#[test]
fn forces_alone_leave_parameters_undetermined_and_strains_fix_them() {
    let dir = tempfile::tempdir().expect("temp dir");
    for (strains, expect_poor) in [(false, true), (true, false)] {
        // The report at the truth (the fit starts there; no iteration).
        let path = write_fit(dir.path(), &TEN, strains, None, true);
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
