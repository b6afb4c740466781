//! The explicit run's stable-step re-estimates (`docs/explicit.md`,
//! "Stable step"): a term whose bound is below 5 % of the sum is refreshed
//! at every 10th re-estimate and enters the sum with twice its last bound
//! in between; growth past that margin is counted.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, AtomicUsize, Ordering};

use ncform::model::{
    FrequencyBound, Masses, Model, State, Stencils, Term, TermEnergy, TermFailure,
};
use ncform::solver::DofMap;
use ncform::solver::explicit::ExplicitSystem;
use ncform::solver::explicit::step::{REFRESH_EVERY, STALE_MARGIN, StepEstimator};

/// The evaluation of a term without force or energy: zeros.
fn no_force(force: &mut [f64], tangent: Option<&mut [f64]>) -> Result<f64, TermFailure> {
    force.fill(0.0);
    if let Some(t) = tangent {
        t.fill(0.0);
    }
    Ok(0.0)
}

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
        no_force(force, tangent)
    }
    fn lumped_masses(&self, masses: &mut Masses) -> f64 {
        masses.node[0] += 1.0;
        1.0
    }
    fn stiffness_from_time_step(&self) -> bool {
        self.penalty
    }
    fn frequency_bound(
        &self,
        _state: &State,
        _masses: &Masses,
    ) -> Result<FrequencyBound, TermFailure> {
        self.calls.fetch_add(1, Ordering::Relaxed);
        Ok(FrequencyBound::nodes(f64::from_bits(
            self.value.load(Ordering::Relaxed),
        )))
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

/// A term with a fixed positive semi-definite stiffness on given nodes and
/// (optionally) the model's extra dof 0, in mass-scaled coordinates (the
/// model's masses are all 1): its bound is the exact largest eigenvalue of
/// its node block and of its extra block.
struct Block {
    name: &'static str,
    nodes: Vec<usize>,
    extra: bool,
    /// The stiffness on the term's dofs (its nodes' x, y, z in order, then
    /// the extra dof).
    stiffness: nalgebra::DMatrix<f64>,
    penalty: bool,
}

impl Block {
    /// The global dof of each of the term's local dofs in a model of
    /// `nodes` nodes.
    fn dofs(&self, nodes: usize) -> Vec<usize> {
        let mut dofs: Vec<usize> = self
            .nodes
            .iter()
            .flat_map(|n| [3 * n, 3 * n + 1, 3 * n + 2])
            .collect();
        if self.extra {
            dofs.push(3 * nodes);
        }
        dofs
    }
}

impl Term for Block {
    fn name(&self) -> &str {
        self.name
    }
    fn stencils(&self) -> Stencils {
        Stencils {
            count: 1,
            nodes: self.nodes.len(),
            extras: usize::from(self.extra),
        }
    }
    fn stencil(&self, _s: usize, nodes: &mut [usize], extras: &mut [usize]) {
        nodes.copy_from_slice(&self.nodes);
        if self.extra {
            extras[0] = 0;
        }
    }
    fn evaluate(
        &mut self,
        _state: &State,
        force: &mut [f64],
        tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        no_force(force, tangent)
    }
    fn stiffness_from_time_step(&self) -> bool {
        self.penalty
    }
    fn frequency_bound(
        &self,
        _state: &State,
        _masses: &Masses,
    ) -> Result<FrequencyBound, TermFailure> {
        let n = 3 * self.nodes.len();
        let largest = |m: nalgebra::DMatrix<f64>| {
            m.symmetric_eigenvalues()
                .iter()
                .fold(0.0_f64, |a, b| a.max(*b))
        };
        Ok(FrequencyBound {
            nodes: largest(self.stiffness.view((0, 0), (n, n)).into_owned()),
            extras: if self.extra {
                largest(self.stiffness.view((n, n), (1, 1)).into_owned())
            } else {
                0.0
            },
        })
    }
    fn energy(&mut self, _state: &State) -> Result<TermEnergy, TermFailure> {
        Ok(TermEnergy::default())
    }
}

/// Unit masses on every node and on the extra dof.
struct UnitMasses;

impl Term for UnitMasses {
    fn name(&self) -> &str {
        "masses"
    }
    fn stencils(&self) -> Stencils {
        Stencils {
            count: 0,
            nodes: 1,
            extras: 0,
        }
    }
    fn stencil(&self, _s: usize, _nodes: &mut [usize], _extras: &mut [usize]) {}
    fn evaluate(
        &mut self,
        _state: &State,
        _force: &mut [f64],
        _tangent: Option<&mut [f64]>,
    ) -> Result<f64, TermFailure> {
        Ok(0.0)
    }
    fn lumped_masses(&self, masses: &mut Masses) -> f64 {
        masses.node.fill(1.0);
        masses.extra.fill(1.0);
        (masses.node.len() + masses.extra.len()) as f64
    }
    fn has_stiffness(&self) -> bool {
        false
    }
    fn energy(&mut self, _state: &State) -> Result<TermEnergy, TermFailure> {
        Ok(TermEnergy::default())
    }
}

/// A random positive semi-definite `n × n` matrix `R Rᵀ · scale` from a
/// linear congruential generator (entries of `R` in [−1, 1)).
fn random_psd(n: usize, scale: f64, seed: &mut u64) -> nalgebra::DMatrix<f64> {
    let r = nalgebra::DMatrix::from_fn(n, n, |_, _| {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    });
    &r * r.transpose() * scale
}

/// Requirement: the combined bound of the terms' bounds is at least the
/// exact `λmax` of the assembled mass-scaled stiffness, for two plies
/// (nodes 0–2 and 3–5, each with a term of its own stiffness), a floating
/// tool's dof in contact with each ply (penalty terms on one ply and the
/// tool), and a penalty between the plies that spans both; and it is never
/// above the plain sum of the terms' bounds (Weyl). Random stiffnesses over
/// four decades of relative size, so that each block dominates in some
/// draws: a combination that grouped the term spanning the plies, or left
/// out the coupling to the tool's dof, falls below the exact value there.
/// With the two plies alike and no tool and no spanning term, the bound is
/// one ply's (the plies are decoupled blocks): the grouping is used.
#[test]
fn the_combined_bound_covers_two_plies_and_a_floating_tool() {
    let nodes = 6;
    let ply_a = vec![0, 1, 2];
    let ply_b = vec![3, 4, 5];
    let both: Vec<usize> = (0..6).collect();
    let mut seed = 7;
    let mut tightest = f64::INFINITY;
    for draw in 0..300 {
        let scale =
            |k: usize| 10f64.powf(4.0 * ((draw * 7919 + k * 104_729) % 97) as f64 / 97.0 - 2.0);
        let layout: [(&'static str, &Vec<usize>, bool, bool); 5] = [
            ("membrane A", &ply_a, false, false),
            ("membrane B", &ply_b, false, false),
            ("tool on A", &ply_a, true, true),
            ("tool on B", &ply_b, true, true),
            ("ply–ply", &both, false, true),
        ];
        let mut model = Model::new(nodes);
        model.add_extra("tool");
        model.add(UnitMasses);
        let mut assembled = nalgebra::DMatrix::<f64>::zeros(3 * nodes + 1, 3 * nodes + 1);
        for (k, (name, term_nodes, extra, penalty)) in layout.into_iter().enumerate() {
            let size = 3 * term_nodes.len() + usize::from(extra);
            let factor = scale(k);
            let block = Block {
                name,
                nodes: term_nodes.clone(),
                extra,
                stiffness: random_psd(size, factor, &mut seed),
                penalty,
            };
            let dofs = block.dofs(nodes);
            for (i, &gi) in dofs.iter().enumerate() {
                for (j, &gj) in dofs.iter().enumerate() {
                    assembled[(gi, gj)] += block.stiffness[(i, j)];
                }
            }
            model.add(block);
        }
        let u = vec![0.0; 3 * nodes + 1];
        let state = State::at(&u);
        let system = ExplicitSystem::new(
            &mut model,
            &DofMap::with_total(3 * nodes + 1, &[]),
            None,
            &state,
        )
        .unwrap();
        let bounds = system.term_bounds(&model, &state, true).unwrap();
        let combined = system.combined_frequency(&bounds);
        let exact = assembled
            .symmetric_eigenvalues()
            .iter()
            .fold(0.0_f64, |a, b| a.max(*b));
        let weyl: f64 = bounds.iter().map(|b| b.total()).sum();
        // Round-off of a 19 × 19 eigenvalue problem: 1e-12 relative.
        assert!(
            combined >= exact * (1.0 - 1e-12),
            "draw {draw}: combined {combined} below the exact {exact}"
        );
        assert!(
            combined <= weyl,
            "draw {draw}: {combined} above Weyl's {weyl}"
        );
        tightest = tightest.min(combined / exact);
    }
    assert!(tightest < 1.5, "never within 1.5 of the exact: {tightest}");

    // Two alike plies, decoupled: the bound is one ply's.
    let mut model = Model::new(nodes);
    model.add(UnitMasses);
    let own = random_psd(9, 1.0, &mut seed);
    let contact = random_psd(9, 0.1, &mut seed);
    for (name, term_nodes, stiffness, penalty) in [
        ("membrane A", &ply_a, &own, false),
        ("membrane B", &ply_b, &own, false),
        ("contact A", &ply_a, &contact, true),
        ("contact B", &ply_b, &contact, true),
    ] {
        model.add(Block {
            name,
            nodes: term_nodes.clone(),
            extra: false,
            stiffness: stiffness.clone(),
            penalty,
        });
    }
    let u = vec![0.0; 3 * nodes];
    let state = State::at(&u);
    let system = ExplicitSystem::new(
        &mut model,
        &DofMap::with_total(3 * nodes, &[]),
        None,
        &state,
    )
    .unwrap();
    let bounds = system.term_bounds(&model, &state, true).unwrap();
    let one_ply = bounds[1].nodes + bounds[3].nodes;
    assert_eq!(system.combined_frequency(&bounds), one_ply);
}
