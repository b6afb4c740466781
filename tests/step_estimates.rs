//! The explicit run's stable-step re-estimates (`docs/explicit.md`,
//! "Stable step"): a term whose bound is below 5 % of the sum is refreshed
//! at every 10th re-estimate and enters the sum with twice its last bound
//! in between; growth past that margin is counted.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

use ncform::model::{Masses, Model, State, Stencils, Term, TermEnergy, TermFailure};
use ncform::solver::DofMap;
use ncform::solver::explicit::ExplicitSystem;
use ncform::solver::explicit::step::{REFRESH_EVERY, STALE_MARGIN, StepEstimator};

/// A term with a frequency bound the test sets, counting its evaluations.
struct Bound {
    name: &'static str,
    /// `ω²` [1/s²], as f64 bits.
    value: Arc<AtomicU64>,
    calls: Arc<AtomicUsize>,
    /// Whether its stiffness follows the step (a contact penalty).
    penalty: bool,
}

impl Term for Bound {
    fn name(&self) -> &str {
        self.name
    }
    fn stencils(&self) -> Stencils {
        Stencils {
            count: 1,
            nodes: 1,
            extras: 0,
        }
    }
    fn stencil(&self, _s: usize, nodes: &mut [usize], _extras: &mut [usize]) {
        nodes[0] = 0;
    }
    fn evaluate(
        &mut self,
        _state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        force.fill(0.0);
        if let Some(t) = tangent {
            t.fill(0.0);
        }
        Ok(0.0)
    }
    fn lumped_masses(&self, masses: &mut Masses) -> f64 {
        masses.node[0] += 1.0;
        1.0
    }
    fn stiffness_from_time_step(&self) -> bool {
        self.penalty
    }
    fn frequency_bound(&self, _state: &State, _masses: &Masses) -> Result<f64, TermFailure> {
        self.calls.fetch_add(1, Ordering::Relaxed);
        Ok(f64::from_bits(self.value.load(Ordering::Relaxed)))
    }
    fn energy(&mut self, _state: &State) -> Result<TermEnergy, TermFailure> {
        Ok(TermEnergy::default())
    }
}

/// The handles of one [`Bound`] term: its value and call count.
struct Handle {
    value: Arc<AtomicU64>,
    calls: Arc<AtomicUsize>,
}

impl Handle {
    fn set(&self, value: f64) {
        self.value.store(value.to_bits(), Ordering::Relaxed);
    }
    fn calls(&self) -> usize {
        self.calls.load(Ordering::Relaxed)
    }
}

fn add_bound(model: &mut Model, name: &'static str, value: f64) -> Handle {
    add_term(model, name, value, false)
}

fn add_term(model: &mut Model, name: &'static str, value: f64, penalty: bool) -> Handle {
    let handle = Handle {
        value: Arc::new(AtomicU64::new(value.to_bits())),
        calls: Arc::new(AtomicUsize::new(0)),
    };
    model.add(Bound {
        name,
        value: handle.value.clone(),
        calls: handle.calls.clone(),
        penalty,
    });
    handle
}

fn step(frequency_squared: f64) -> f64 {
    2.0 / frequency_squared.sqrt()
}

/// Requirement: a term at 1 % of the sum is evaluated once per
/// `REFRESH_EVERY` re-estimates and counts `STALE_MARGIN` times its last
/// bound in between; a term at 99 % is evaluated at every re-estimate and
/// a change of it shows at once. Exact: the steps are `2/√ω²` of sums of
/// the set values, computed the same way.
#[test]
fn a_small_term_is_refreshed_every_tenth_estimate_with_a_margin() {
    let mut model = Model::new(1);
    let stiff = add_bound(&mut model, "stiff", 99.0);
    let small = add_bound(&mut model, "small", 1.0);
    let u = vec![0.0; 3];
    let state = State::at(&u);
    let system =
        ExplicitSystem::new(&mut model, &DofMap::with_total(3, &[]), None, &state).unwrap();
    let (mut estimator, initial) = StepEstimator::new(&system, &model, &state).unwrap();
    assert_eq!(initial, step(100.0));
    assert_eq!((stiff.calls(), small.calls()), (1, 1));
    for k in 1..REFRESH_EVERY {
        if k == 5 {
            stiff.set(199.0);
        }
        let expected = if k < 5 { 99.0 } else { 199.0 } + STALE_MARGIN;
        assert_eq!(
            estimator.estimate(&system, &model, &state).unwrap(),
            step(expected)
        );
        assert_eq!((stiff.calls(), small.calls()), (1 + k, 1), "estimate {k}");
    }
    // The 10th re-estimate refreshes the small term.
    small.set(1.5);
    assert_eq!(
        estimator.estimate(&system, &model, &state).unwrap(),
        step(199.0 + 1.5)
    );
    assert_eq!(small.calls(), 2);
    assert!(estimator.growth().iter().all(|g| g.count == 0));
}

/// Requirement: a small term whose bound grew past the margin between two
/// refreshes is counted with its ratio; a term whose bound is zero (a
/// load) and a penalty term (contact, whose bound follows the contact set)
/// are evaluated every time, so that a bound appearing from zero or
/// jumping with the contact set is never missed.
#[test]
fn growth_past_the_margin_is_counted_and_zero_bounds_are_always_refreshed() {
    let mut model = Model::new(1);
    let _stiff = add_bound(&mut model, "stiff", 99.0);
    let small = add_bound(&mut model, "small", 1.0);
    let zero = add_bound(&mut model, "zero", 0.0);
    let penalty = add_term(&mut model, "penalty", 0.5, true);
    let u = vec![0.0; 3];
    let state = State::at(&u);
    let system =
        ExplicitSystem::new(&mut model, &DofMap::with_total(3, &[]), None, &state).unwrap();
    let (mut estimator, _) = StepEstimator::new(&system, &model, &state).unwrap();
    small.set(3.0);
    for _ in 0..REFRESH_EVERY {
        estimator.estimate(&system, &model, &state).unwrap();
    }
    assert_eq!(zero.calls(), 1 + REFRESH_EVERY);
    assert_eq!(penalty.calls(), 1 + REFRESH_EVERY);
    let growth = estimator.growth();
    assert_eq!(growth[0].count, 0);
    assert_eq!(growth[1].count, 1);
    assert_eq!(growth[1].largest_ratio, 3.0);
    // Once refreshed, the new bound is the reference.
    zero.set(5.0);
    assert_eq!(
        estimator.estimate(&system, &model, &state).unwrap(),
        step(99.0 + STALE_MARGIN * 3.0 + 5.0 + 0.5)
    );
}
