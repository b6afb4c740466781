//! Tests of the explicit dynamics solver (central differences, lumped
//! masses): frequencies against closed forms, the stability limit against
//! the exact eigenvalues of the discrete system, energy conservation and
//! dissipation against the modal bounds of the central-difference scheme,
//! thread-count independence, setting errors and the prescribed motion.
//!
//! Every tolerance is derived (in a comment at its use) from the scheme's
//! known error terms, the sampling of the outputs, the geometric
//! nonlinearity of the small amplitudes and round-off; none is fitted to a
//! result.
//!
//! Central-difference facts used throughout, for one mode `ẍ = −ω² x`
//! integrated with a constant step `Δt` and the synchronous velocity
//! `v_n = v_{n−½} + (Δt/2) a_n` the solver reports at outputs, with
//! `q = (ωΔt)²/4`:
//! - the samples are exactly `x_n = A cos(ω_h n Δt + φ)` with
//!   `ω_h = (2/Δt) asin(ωΔt/2)` (stable for `ωΔt ≤ 2`): the period is
//!   *shortened* by `≈ (ωΔt)²/24`;
//! - `H̃ = ½ v_n² + ½ ω² (1 − q) x_n²` is conserved exactly, so the energy
//!   `E = ½ v² + ½ ω² x²` stays in `[(1 − q) E0, E0]` from rest and in
//!   `[E0, E0/(1 − q)]` from a pure velocity;
//! - for `ωΔt > 2` the amplification factor is the root `|r| > 1` of
//!   `r + 1/r = 2 − (ωΔt)²`.
//!
//! With lumped masses and mass-proportional damping, the free dofs of a
//! linear model decouple into such modes (`M^{−½} K M^{−½} = Y Λ Yᵀ`), and
//! the scheme acts on each modal coordinate separately.

use nalgebra::{DMatrix, DVector, SymmetricEigen, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use ncform::element::{FibreTriangle, RovingCoupling};
use ncform::material::{Material, MaterialSpec, OrthotropicSvk};
use ncform::model::{MembraneModel, MembraneOptions, Model, State};
use ncform::solver::explicit::{
    Amplitude, ExplicitError, ExplicitSystem, SetupError, TimeStepControl,
};
use ncform::solver::{
    Dirichlet, DofMap, ExplicitParameters, ExplicitRecord, ExplicitResult, ExplicitState,
    RunStatus, Snapshot, solve_explicit,
};

/// Dry-fabric density [t/mm³] (1 g/cm³ = 1e-9 t/mm³).
const RHO: f64 = 1.0e-9;
/// Membrane thickness [mm].
const THICKNESS: f64 = 0.3;

fn svk(e1: f64, e2: f64, nu12: f64, g12: f64) -> Material {
    Material::OrthotropicSvk(OrthotropicSvk { e1, e2, nu12, g12 })
}

/// A moderately anisotropic SVK law: all four moduli matter.
fn svk_general() -> Material {
    svk(1000.0, 100.0, 0.3, 50.0)
}

/// A rectangular grid of `nx × ny` cells of `dx × dy` mm in the xy-plane,
/// every cell cut by its `/` diagonal into `(BL, BR, TR)` and
/// `(BL, TR, TL)`, rovings along x. Node `(i, j)` has index `i + j (nx + 1)`.
fn grid(nx: usize, ny: usize, dx: f64, dy: f64, material: Material) -> MembraneModel {
    let id = |i: usize, j: usize| i + j * (nx + 1);
    let mut nodes = Vec::new();
    for j in 0..=ny {
        for i in 0..=nx {
            nodes.push(Vector3::new(i as f64 * dx, j as f64 * dy, 0.0));
        }
    }
    let mut triangles = Vec::new();
    for j in 0..ny {
        for i in 0..nx {
            let (bl, br, tr, tl) = (id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1));
            triangles.push([bl, br, tr]);
            triangles.push([bl, tr, tl]);
        }
    }
    let fibres = vec![Vector3::x(); triangles.len()];
    MembraneModel::new(nodes, triangles, &fibres, material, THICKNESS).expect("model")
}

/// The solvers' model of a membrane: density [`RHO`], triangles checked
/// for turning over in their plane.
fn solver(model: &MembraneModel) -> Model {
    Model::membrane(
        model.clone(),
        MembraneOptions {
            check_inversion: true,
            density: Some(RHO),
            roving_mass_length: 0.0,
            roving_mass_coupling: RovingCoupling::Stretch,
        },
    )
}

/// The explicit system of a membrane with the model it drives, for the
/// stable-step estimate and the lumped masses.
struct System {
    model: Model,
    system: ExplicitSystem,
}

impl System {
    fn new(model: &MembraneModel, dofs: &DofMap, u: &[f64]) -> Self {
        let mut model = solver(model);
        let system = ExplicitSystem::new(&mut model, dofs, None, &State::at(u)).unwrap();
        Self { model, system }
    }

    /// The estimated critical step at `u` [s].
    fn critical_time_step(&self, u: &[f64]) -> f64 {
        self.system
            .critical_time_step(&self.model, &State::at(u))
            .unwrap()
    }
}

/// Fixes x and y of the nodes at `x = 0` and z everywhere (in-plane motion).
fn clamp_left_edge(model: &MembraneModel) -> DofMap {
    let mut conditions = Vec::new();
    for (n, x) in model.nodes.iter().enumerate() {
        if x.x == 0.0 {
            conditions.extend([Dirichlet::fixed(n, 0), Dirichlet::fixed(n, 1)]);
        }
        conditions.push(Dirichlet::fixed(n, 2));
    }
    DofMap::new(model.nodes.len(), &conditions)
}

/// Output times `k Δt`, `k = 1..=steps`, and a fixed-step setting a hair
/// above `Δt`, so that every step lands on an output with a length equal to
/// `Δt` up to the round-off of `k Δt` (~1e-16 k relative): the step stays
/// constant, as the modal results above assume.
fn every_step(dt: f64, steps: usize) -> (Vec<f64>, TimeStepControl) {
    let times = (1..=steps).map(|k| k as f64 * dt).collect();
    (
        times,
        TimeStepControl::Fixed {
            time_step: dt * (1.0 + 1e-9),
        },
    )
}

/// Undamped, unloaded run parameters on one thread (tests run in parallel).
fn parameters(duration: f64, time_step: TimeStepControl) -> ExplicitParameters {
    let mut params = ExplicitParameters::new(duration);
    params.time_step = time_step;
    params.threads = 1;
    params
}

/// Runs the solver and keeps the records and, for each output, the values
/// of the dofs `watch`.
fn run(
    model: &MembraneModel,
    dofs: &DofMap,
    params: &ExplicitParameters,
    final_load: f64,
    times: &[f64],
    state: &mut ExplicitState,
    watch: &[usize],
) -> (ExplicitResult, Vec<Vec<f64>>) {
    let mut watched = Vec::new();
    let result = solve_explicit(
        &mut solver(model),
        dofs,
        params,
        final_load,
        times,
        state,
        |_, s: &Snapshot| watched.push(watch.iter().map(|&d| s.u[d]).collect::<Vec<f64>>()),
    )
    .expect("the run starts");
    (result, watched)
}

/// Times where the linearly interpolated samples `(t_i, y_i)` cross zero.
fn zero_crossings(t: &[f64], y: &[f64]) -> Vec<f64> {
    let mut crossings = Vec::new();
    for i in 0..t.len() - 1 {
        let (a, b) = (y[i], y[i + 1]);
        if (a > 0.0 && b <= 0.0) || (a < 0.0 && b >= 0.0) {
            crossings.push(t[i] + (t[i + 1] - t[i]) * a / (a - b));
        }
    }
    crossings
}

/// Mean period from the first and last of `m + 1` zero crossings (two per
/// period): `2 (c_m − c_0) / m`.
fn period_from_crossings(crossings: &[f64]) -> f64 {
    let m = crossings.len() - 1;
    2.0 * (crossings[m] - crossings[0]) / m as f64
}

/// Relative error bound of that period for a sinusoid sampled every `δ`
/// radians with `m + 1` crossings. Each linearly interpolated root is off by
/// at most `δ² tan(δ)/8` rad: the interpolation error is
/// `≤ δ²/8 max|y''|`, `|y''| = |sin θ| ≤ sin δ` within `δ` of a root, and
/// `|y'| ≥ cos δ` there. Two crossings over `m/2` periods of `2π`.
fn sampling_error(delta: f64, m: usize) -> f64 {
    2.0 * (delta * delta * delta.tan() / 8.0) / (std::f64::consts::PI * m as f64)
}

/// The fibre-basis triangles of the model (what the explicit solver uses).
fn fibre_triangles(model: &MembraneModel) -> Vec<FibreTriangle> {
    model
        .references
        .iter()
        .map(|r| FibreTriangle::new(r, model.thickness))
        .collect()
}

/// The linear stiffness at `u = 0`, assembled (dense, all dofs) from central
/// differences of `FibreTriangle::internal_force` with a step of 1e-6 of the
/// element size. The force of the SVK law is a cubic polynomial in `u`, so
/// the truncation error is `h²/6 |f'''|`, relative `~(h/ℓ)² = 1e-12`; the
/// round-off is `ε_mach / (h/ℓ) ≈ 1e-10` relative.
fn stiffness(model: &MembraneModel) -> DMatrix<f64> {
    stiffness_at(model, &vec![0.0; 3 * model.nodes.len()])
}

/// [`stiffness`] at the displacements `u` (3 per node).
fn stiffness_at(model: &MembraneModel, at: &[f64]) -> DMatrix<f64> {
    let n = 3 * model.nodes.len();
    let mut k = DMatrix::zeros(n, n);
    for (e, tri) in fibre_triangles(model).iter().enumerate() {
        let size = model.references[e].area.sqrt();
        let h = 1e-6 * size;
        let nodes = model.triangles[e];
        for a in 0..3 {
            for c in 0..3 {
                let force = |s: f64| {
                    let mut u: [[f64; 3]; 3] =
                        std::array::from_fn(|b| std::array::from_fn(|d| at[3 * nodes[b] + d]));
                    u[a][c] += s;
                    tri.internal_force(&u, &model.material)
                        .expect("small strain")
                        .force
                };
                let (plus, minus) = (force(h), force(-h));
                for b in 0..3 {
                    for d in 0..3 {
                        k[(3 * nodes[b] + d, 3 * nodes[a] + c)] +=
                            (plus[3 * b + d] - minus[3 * b + d]) / (2.0 * h);
                    }
                }
            }
        }
    }
    0.5 * (&k + k.transpose())
}

/// Lumped nodal masses `Σ ρ t A0 / 3` [t].
fn lumped_masses(model: &MembraneModel) -> Vec<f64> {
    let mut m = vec![0.0; model.nodes.len()];
    for (t, r) in model.triangles.iter().zip(&model.references) {
        for &n in t {
            m[n] += RHO * model.thickness * r.area / 3.0;
        }
    }
    m
}

/// Modes of the free dofs of the linear model at `u = 0`.
struct Modes {
    /// Free dofs (global indices).
    free: Vec<usize>,
    /// `√m` per free dof.
    sqrt_mass: DVector<f64>,
    /// `ω_j²`, ascending.
    omega2: Vec<f64>,
    /// Columns: orthonormal eigenvectors of `M^{−½} K M^{−½}`.
    vectors: DMatrix<f64>,
}

impl Modes {
    fn new(model: &MembraneModel, dofs: &DofMap) -> Self {
        let k = stiffness(model);
        let masses = lumped_masses(model);
        let free = dofs.free.clone();
        let sqrt_mass =
            DVector::from_iterator(free.len(), free.iter().map(|&d| masses[d / 3].sqrt()));
        let a = DMatrix::from_fn(free.len(), free.len(), |i, j| {
            k[(free[i], free[j])] / (sqrt_mass[i] * sqrt_mass[j])
        });
        let eigen = SymmetricEigen::new(a);
        let mut order: Vec<usize> = (0..free.len()).collect();
        order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
        let omega2 = order.iter().map(|&i| eigen.eigenvalues[i]).collect();
        let vectors = DMatrix::from_fn(free.len(), free.len(), |r, c| {
            eigen.eigenvectors[(r, order[c])]
        });
        Self {
            free,
            sqrt_mass,
            omega2,
            vectors,
        }
    }

    fn omega_max(&self) -> f64 {
        self.omega2.last().expect("free dofs").sqrt()
    }

    /// Modal coordinates `Yᵀ M^{½} w` of the free dofs of a global vector.
    fn coordinates(&self, w: &[f64]) -> DVector<f64> {
        let scaled = DVector::from_iterator(
            self.free.len(),
            self.free
                .iter()
                .zip(self.sqrt_mass.iter())
                .map(|(&d, s)| s * w[d]),
        );
        self.vectors.transpose() * scaled
    }

    /// Energy per mode of a displacement (at rest): `½ ω_j² ξ_j²`.
    fn displacement_energies(&self, u: &[f64]) -> Vec<f64> {
        let xi = self.coordinates(u);
        self.omega2
            .iter()
            .zip(xi.iter())
            .map(|(w2, x)| 0.5 * w2 * x * x)
            .collect()
    }

    /// Energy per mode of a velocity (in the reference state): `½ η_j²`.
    fn velocity_energies(&self, v: &[f64]) -> Vec<f64> {
        self.coordinates(v).iter().map(|e| 0.5 * e * e).collect()
    }
}

/// `IE + KE` of a record.
fn mechanical(record: &ExplicitRecord) -> f64 {
    record.energies.internal + record.energies.kinetic
}

/// `Σ_j q_j/(1 − q_j) E_j0 / E0` with `q_j = (ω_j Δt)²/4`: the bound of
/// the relative balance error of an undamped vibration started from a pure
/// velocity with modal energies `energies` (module doc).
fn velocity_balance_bound(energies: &[f64], omega2: &[f64], dt: f64) -> f64 {
    let e0: f64 = energies.iter().sum();
    energies
        .iter()
        .zip(omega2)
        .map(|(e, w2)| {
            let q = w2 * dt * dt / 4.0;
            q / (1.0 - q) * e
        })
        .sum::<f64>()
        / e0
}

// ---------------------------------------------------------------------------
// 1. Single element, one free dof
// ---------------------------------------------------------------------------

/// Requirement: a triangle with one free dof vibrates at the frequency of
/// its element stiffness and lumped mass, with the central-difference
/// period shortening.
///
/// Triangle `(0,0), (a,0), (0,b)`, rovings along x; nodes 0 and 2 fixed,
/// node 1 free in x only. With `N1 = x/a`, a displacement `u` of node 1
/// gives `g1 = (1 + u/a) e_x`, `g2 = e_y`, so `E11 = u/a + ½(u/a)²`,
/// `E22 = E12 = 0`, `S11 = Q11 E11` and the internal force
/// `f = t A (1/a) S11 (1 + u/a)`: `k = t A Q11 / a²`. The lumped mass is
/// `m = ρ t A / 3`, so `ω² = k/m = 3 Q11 / (ρ a²)`, with
/// `Q11 = E1 / (1 − ν12² E2/E1)`.
#[test]
fn single_dof_triangle_vibrates_at_its_element_frequency() {
    let (a, b) = (10.0, 8.0);
    let (e1, e2, nu12) = (1000.0, 10.0, 0.3);
    let material = svk(e1, e2, nu12, 1.0);
    let nodes = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(a, 0.0, 0.0),
        Vector3::new(0.0, b, 0.0),
    ];
    let model = MembraneModel::new(nodes, vec![[0, 1, 2]], &[Vector3::x()], material, THICKNESS)
        .expect("model");
    let mut conditions = vec![Dirichlet::fixed(1, 1), Dirichlet::fixed(1, 2)];
    for n in [0, 2] {
        conditions.extend((0..3).map(|k| Dirichlet::fixed(n, k)));
    }
    let dofs = DofMap::new(3, &conditions);
    assert_eq!(dofs.free, vec![3]);

    let area = 0.5 * a * b;
    let q11 = e1 / (1.0 - nu12 * nu12 * e2 / e1);
    let k = THICKNESS * area * q11 / (a * a);
    let m = RHO * THICKNESS * area / 3.0;
    let omega = (k / m).sqrt();

    // Cross-check of k: central difference of the solver's element force.
    // Truncation h²/6 f''' ≈ (h/a)² k = 1e-8 k relative, round-off
    // ε_mach a/h = 1e-12: 1e-7 covers both.
    let tri = FibreTriangle::new(&model.references[0], THICKNESS);
    let h = 1e-4 * a;
    let force = |s: f64| {
        tri.internal_force(&[[0.0; 3], [s, 0.0, 0.0], [0.0; 3]], &model.material)
            .unwrap()
            .force[3]
    };
    let k_fd = (force(h) - force(-h)) / (2.0 * h);
    assert!(
        (k_fd / k - 1.0).abs() < 1e-7,
        "k: hand {k:e}, finite difference {k_fd:e}"
    );

    // ωΔt = 0.4: the central-difference period is shorter by
    // 1 − 0.2/asin(0.2) = 0.67 %, a hundred times the tolerance below.
    let dt = 0.4 / omega;
    let omega_h = 2.0 / dt * (omega * dt / 2.0).asin();
    let periods = 50.0;
    let steps = (periods * 2.0 * std::f64::consts::PI / (omega_h * dt)).ceil() as usize;
    let (times, control) = every_step(dt, steps);
    let params = parameters(steps as f64 * dt, control);
    let u0 = 1e-4; // u/a = 1e-5
    let mut state = ExplicitState::at_rest(9);
    state.u[3] = u0;
    let (result, watched) = run(&model, &dofs, &params, 0.0, &times, &mut state, &[3]);
    assert_eq!(result.status, RunStatus::Complete);
    let mut t = vec![0.0];
    let mut y = vec![u0];
    for (record, w) in result.records.iter().zip(&watched) {
        t.push(record.time);
        y.push(w[0]);
    }
    let crossings = zero_crossings(&t, &y);
    let measured = period_from_crossings(&crossings);
    let expected = 2.0 * std::f64::consts::PI / omega_h;
    let exact = 2.0 * std::f64::consts::PI / omega;
    // Tolerance: the sampling error of the crossings (δ = ω_h Δt), plus the
    // amplitude dependence of the frequency, ~(u0/a)² = 1e-10 (quadratic
    // and cubic terms of f(u) above), and round-off of the strain
    // ε_mach/(u0/a) ≈ 1e-11: 1e-9 covers the last two.
    let tol = sampling_error(omega_h * dt, crossings.len() - 1) + 1e-9;
    let error = measured / expected - 1.0;
    eprintln!(
        "single dof: ω = {omega:.6e} rad/s, ωΔt = 0.4, measured/expected − 1 = {error:.2e} (tol {tol:.2e}), measured/exact − 1 = {:.3e}",
        measured / exact - 1.0
    );
    assert!(
        error.abs() <= tol,
        "period {measured:e} s vs {expected:e} s"
    );
}

// ---------------------------------------------------------------------------
// 2. Bar frequency
// ---------------------------------------------------------------------------

/// Requirement: a strip of triangles along the rovings vibrates axially as
/// a bar: first fixed-free mode `f = c / (4L)`, `c = √(E1/ρ)`, within the
/// dispersion of lumped-mass linear elements.
///
/// The free end of a one-row strip cut by diagonals has nodal masses in the
/// ratio 1 : 2 with equal axial stiffness, which makes it a 2D detail
/// (about 1/(3N) in ω² with small shear moduli). So the fixed-free bar of
/// length `L` is modelled by its mirror image: a strip of length `2L`
/// fixed axially at both ends, whose first mode `u = u0 sin(π x / 2L)` has
/// `u'(L) = 0`: each half is the fixed-free bar, `f = c/(4L)`. With every
/// y and z fixed and `ν12 = 0`, a displacement field that depends on x only
/// stays so (no shear, `E22 = 0`), and the strip is exactly the lumped-mass
/// chain with `h = 2.5 mm` (40 cells per bar of `L = 100 mm`), whose first
/// mode is the sampled `sin(π x/2L)` with `ω_h = (2c/h) sin(k h/2)`,
/// `k = π/(2L)`. With central differences `sin(ω_Δ Δt/2) = Cr sin(kh/2)`,
/// `Cr = cΔt/h`.
#[test]
fn strip_vibrates_as_a_fixed_free_bar() {
    let (l, cells_per_bar) = (100.0, 40);
    let h = l / cells_per_bar as f64;
    let e1 = 1000.0;
    let model = grid(2 * cells_per_bar, 1, h, h, svk(e1, 1.0, 0.0, 1.0));
    let mut conditions = Vec::new();
    for (n, x) in model.nodes.iter().enumerate() {
        conditions.extend([Dirichlet::fixed(n, 1), Dirichlet::fixed(n, 2)]);
        if x.x == 0.0 || x.x == 2.0 * l {
            conditions.push(Dirichlet::fixed(n, 0));
        }
    }
    let dofs = DofMap::new(model.nodes.len(), &conditions);
    let c = (e1 / RHO).sqrt();
    let k = std::f64::consts::PI / (2.0 * l);
    let omega = c * k;
    let omega_semi = 2.0 * c / h * (k * h / 2.0).sin();
    let courant = 0.5;
    let dt = courant * h / c;
    let omega_full = 2.0 / dt * (courant * (k * h / 2.0).sin()).asin();

    let u0 = 1e-3; // strain amplitude u0 k = 1.6e-5
    let mut state = ExplicitState::at_rest(dofs.total);
    for (n, x) in model.nodes.iter().enumerate() {
        if x.x > 0.0 && x.x < 2.0 * l {
            state.u[3 * n] = u0 * (k * x.x).sin();
        }
    }
    // The step must be stable: the estimate bounds the critical step from
    // below.
    let system = System::new(&model, &dofs, &state.u);
    assert!(dt < system.critical_time_step(&state.u));

    let periods = 10.0;
    let steps = (periods * 2.0 * std::f64::consts::PI / (omega_full * dt)).ceil() as usize;
    let (times, control) = every_step(dt, steps);
    let params = parameters(steps as f64 * dt, control);
    let middle = model
        .nodes
        .iter()
        .position(|x| x.x == l && x.y == 0.0)
        .unwrap();
    let (result, watched) = run(
        &model,
        &dofs,
        &params,
        0.0,
        &times,
        &mut state,
        &[3 * middle],
    );
    assert_eq!(result.status, RunStatus::Complete);
    let mut t = vec![0.0];
    let mut y = vec![u0];
    for (record, w) in result.records.iter().zip(&watched) {
        t.push(record.time);
        y.push(w[0]);
    }
    let crossings = zero_crossings(&t, &y);
    let measured = period_from_crossings(&crossings);
    let two_pi = 2.0 * std::f64::consts::PI;
    // (a) Against the fully discrete frequency. Tolerance: sampling of the
    // crossings (δ = ω Δt ≈ 0.02 rad: 3e-8) + amplitude dependence
    // (strain amplitude)² = 2.5e-10 + round-off of the strain
    // ε_mach/1.6e-5 ≈ 1e-11: 1e-9 covers the last two.
    let tol = sampling_error(omega_full * dt, crossings.len() - 1) + 1e-9;
    let error = measured / (two_pi / omega_full) - 1.0;
    // (b) Against the bar, f = c/(4L). The semi-discrete error is
    // 1 − sin(x)/x ≤ x²/6 with x = kh/2 (6.4e-5 here), the time
    // integration's (ω_h Δt)²/24 (1.6e-5; of opposite sign); their sum
    // bounds the distance to the continuum, plus (a)'s tolerance.
    let x = k * h / 2.0;
    let tol_bar = x * x / 6.0 + (omega_semi * dt).powi(2) / 24.0 + tol;
    let error_bar = measured / (two_pi / omega) - 1.0;
    eprintln!(
        "bar: f = {:.3} Hz, measured/discrete − 1 = {error:.2e} (tol {tol:.1e}), measured/(c/4L) − 1 = {error_bar:.3e} (tol {tol_bar:.2e}; predicted {:.3e})",
        omega / two_pi,
        omega / omega_full - 1.0
    );
    assert!(
        error.abs() <= tol,
        "period {measured:e} vs discrete {:e}",
        two_pi / omega_full
    );
    assert!(
        error_bar.abs() <= tol_bar,
        "period {measured:e} vs bar {:e}",
        two_pi / omega
    );
}

// ---------------------------------------------------------------------------
// 3. Stable step
// ---------------------------------------------------------------------------

/// 2 × 2 cells of 10 mm (8 triangles), left edge clamped, z fixed: 12 free
/// in-plane dofs; the centre node is interior, in all six triangles.
fn tiny_mesh() -> (MembraneModel, DofMap) {
    let model = grid(2, 2, 10.0, 10.0, svk_general());
    let dofs = clamp_left_edge(&model);
    assert_eq!(dofs.n_free(), 12);
    (model, dofs)
}

/// Seeded random values in `[−amplitude, amplitude]` on the free dofs.
fn random_free(dofs: &DofMap, amplitude: f64, seed: u64) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut w = vec![0.0; dofs.total];
    for &d in &dofs.free {
        w[d] = amplitude * rng.random_range(-1.0..1.0);
    }
    w
}

/// Requirement: the estimated critical step is a lower bound of the exact
/// `2/ω_max` of the discrete system, and not a gross underestimate.
///
/// Lower limit: with `m_e` the element mass, the estimate is
/// `ω_est² = λmax(K_e)/(m_e/3) ≤ 3 tr(K_e)/m_e` (`K_e` is positive
/// semi-definite). The centre node is in six triangles, two of each of the
/// two shapes (one the other turned by 180°, the same `K_e`) in each of the
/// three vertex roles, so its x and y diagonal entries sum to `2 tr(K_e)`
/// over a mass `2 m_e`; the larger one is a Rayleigh quotient
/// `≥ tr(K_e)/(2 m_e)` of the assembled system. Hence
/// `ω_max²/ω_est² ≥ 1/6` and `Δt_est ≥ Δt_exact/√6 = 0.408 Δt_exact`.
#[test]
fn stable_step_estimate_bounds_the_exact_critical_step() {
    let (model, dofs) = tiny_mesh();
    let modes = Modes::new(&model, &dofs);
    let exact = 2.0 / modes.omega_max();
    let u = vec![0.0; dofs.total];
    let system = System::new(&model, &dofs, &u);
    // The solver's lumped masses are the ones used here (round-off).
    for (mine, theirs) in lumped_masses(&model).iter().zip(&system.system.masses.node) {
        assert!((mine - theirs).abs() <= 1e-14 * mine);
    }
    let estimate = system.critical_time_step(&u);
    eprintln!(
        "stable step: exact {exact:.4e} s, estimate {estimate:.4e} s, ratio {:.3}",
        estimate / exact
    );
    // The exact value carries the finite-difference error of K (1e-10).
    assert!(estimate <= exact * (1.0 + 1e-8), "{estimate:e} > {exact:e}");
    assert!(estimate >= exact / 6f64.sqrt(), "{estimate:e} ≪ {exact:e}");
}

/// Requirement: above the exact critical step the run blows up, below it
/// it stays bounded.
///
/// (b) At `Δt = 1.1 Δt_crit`, `ω_max Δt = 2.2`: `|r| = 2.43` per step, the
/// energy of the top mode grows by `r² = 5.9` per step. Starting from a
/// random displacement whose top mode holds a fraction `e_top` of the
/// energy, it exceeds `10⁶ E0` after `n` steps with
/// `e_top r^{2n} ≥ 10⁸` (a factor 100 for the O(1) constants of the
/// modal solution): the run takes that `n`, and must fail (an element turns
/// over or the law overflows) or show `IE + KE ≥ 10⁶ E0`.
///
/// (c) At `Δt = 0.9 Δt_crit`, over 3000 steps, from rest: every mode keeps
/// `E_j ∈ [(1 − q_j) E_j0, E_j0]`, so `IE + KE ≤ E0` and the balance error
/// `≤ Σ q_j E_j0 / E0`, plus the geometric nonlinearity (relative
/// `~ |∇u| ≤ 2e-6` here; 1e-5 allowed) and round-off.
#[test]
fn runs_blow_up_above_the_critical_step_and_not_below() {
    let (model, dofs) = tiny_mesh();
    let modes = Modes::new(&model, &dofs);
    let critical = 2.0 / modes.omega_max();
    // 1e-5 mm on 10 mm cells: |∇u| ≤ 2e-6.
    let u0 = random_free(&dofs, 1e-5, 3);
    let energies = modes.displacement_energies(&u0);
    let e0: f64 = energies.iter().sum();
    let nonlinear = 1e-5;

    // (b)
    let dt = 1.1 * critical;
    let s = (modes.omega_max() * dt).powi(2) - 2.0;
    let growth = ((s + (s * s - 4.0).sqrt()) / 2.0).powi(2);
    let e_top = energies.last().unwrap() / e0;
    let steps = ((1e8 / e_top).ln() / growth.ln()).ceil() as usize;
    eprintln!("unstable: e_top = {e_top:.3e}, growth {growth:.2}/step, {steps} steps");
    assert!(steps <= 100, "the random state barely excites the top mode");
    let (times, control) = every_step(dt, steps);
    let params = parameters(steps as f64 * dt, control);
    let mut state = ExplicitState {
        u: u0.clone(),
        v: vec![0.0; dofs.total],
    };
    let (result, _) = run(&model, &dofs, &params, 0.0, &times, &mut state, &[]);
    let largest = result.records.iter().map(mechanical).fold(0.0, f64::max);
    eprintln!(
        "unstable: status {:?}, largest energy {:.2e} E0",
        result.status,
        largest / e0
    );
    assert!(
        matches!(result.status, RunStatus::Incomplete { .. }) || largest >= 1e6 * e0,
        "no blow-up at 1.1 × the critical step: {:?}, max energy {:e} E0",
        result.status,
        largest / e0
    );

    // (c)
    let dt = 0.9 * critical;
    let steps = 3000;
    let (times, control) = every_step(dt, steps);
    let params = parameters(steps as f64 * dt, control);
    let mut state = ExplicitState {
        u: u0,
        v: vec![0.0; dofs.total],
    };
    let (result, _) = run(&model, &dofs, &params, 0.0, &times, &mut state, &[]);
    assert_eq!(result.status, RunStatus::Complete);
    assert_eq!(result.records.len(), steps);
    let bound: f64 = energies
        .iter()
        .zip(&modes.omega2)
        .map(|(e, w2)| w2 * dt * dt / 4.0 * e)
        .sum::<f64>()
        / e0;
    let largest = result.records.iter().map(mechanical).fold(0.0, f64::max);
    let worst = result.max_relative_balance_error;
    eprintln!(
        "stable: largest energy {:.6} E0, worst balance error {worst:.3e} (bound {bound:.3e})",
        largest / e0
    );
    assert!(
        largest <= e0 * (1.0 + nonlinear),
        "energy grew: {} E0",
        largest / e0
    );
    assert!(
        worst <= bound + nonlinear,
        "balance error {worst:e} > {bound:e}"
    );
}

// ---------------------------------------------------------------------------
// 4. Energy conservation
// ---------------------------------------------------------------------------

/// Requirement: an undamped free vibration conserves energy within the
/// central-difference bound, and no work is done when nothing is driven.
///
/// SVK, 4 × 2 cells of 5 mm, left edge clamped, started with a random
/// velocity (all 24 modes) at the production step `0.9 Δt_est`. From a
/// pure velocity each mode keeps `E_j ∈ [E_j0, E_j0/(1 − q_j)]`, so the
/// relative balance error is at most `Σ_j q_j/(1 − q_j) E_j0 / E0`
/// (`q_j = (ω_j Δt)²/4`), plus the geometric nonlinearity: displacements
/// `≤ v/ω_1` give `|∇u| ≲ 1e-6` (1e-5 allowed).
#[test]
fn undamped_vibration_conserves_energy_svk() {
    let model = grid(4, 2, 5.0, 5.0, svk_general());
    let dofs = clamp_left_edge(&model);
    let modes = Modes::new(&model, &dofs);
    let zero = vec![0.0; dofs.total];
    let system = System::new(&model, &dofs, &zero);
    let dt = 0.9 * system.critical_time_step(&zero);
    let omega_1 = modes.omega2[0].sqrt();
    // Velocity amplitude: 1e-6 mm of displacement in the slowest mode, over
    // a 5 mm cell: |∇u| ~ 1e-6 / 5 · (a few).
    let v0 = random_free(&dofs, 1e-6 * omega_1, 4);
    let energies = modes.velocity_energies(&v0);
    let e0: f64 = energies.iter().sum();
    let bound = velocity_balance_bound(&energies, &modes.omega2, dt);
    let steps = 4000;
    let (times, control) = every_step(dt, steps);
    let params = parameters(steps as f64 * dt, control);
    let mut state = ExplicitState { u: zero, v: v0 };
    // A non-zero final load: λ(t) moves, but no dof is driven.
    let (result, _) = run(&model, &dofs, &params, 1.0, &times, &mut state, &[]);
    assert_eq!(result.status, RunStatus::Complete);
    // The solver's initial energy, E − balance error, is the modal sum
    // (round-off of the eigen-decomposition, ~1e-12).
    let first = &result.records[0];
    let initial = mechanical(first) - first.energies.balance_error;
    assert!(
        (initial / e0 - 1.0).abs() < 1e-9,
        "E0 {initial:e} vs {e0:e}"
    );
    let worst = result.max_relative_balance_error;
    eprintln!(
        "energy (SVK): ω1Δt = {:.3}, ωmaxΔt = {:.3}, worst balance error {worst:.3e} (bound {bound:.3e})",
        omega_1 * dt,
        modes.omega_max() * dt
    );
    for record in &result.records {
        assert_eq!(record.energies.external_work, 0.0);
        assert_eq!(record.reaction, 0.0);
    }
    assert!(worst <= bound + 1e-5, "balance error {worst:e} > {bound:e}");
}

/// Requirement: the same for the UD-NCF law, whose stiffness changes along
/// the motion (kinks at `I8 = 1` and `I11 = 1`, shear softening).
///
/// 4 × 4 cells of 5 mm, random velocity: displacements `~ v/ω` give
/// `|∇u| ~ 1e-4` in the stiff roving modes and `~ 1e-2` in the soft shear
/// modes. Fixed `Δt = 0.1 Δt_est(0)`; at every output the stable-step
/// estimate `Δt_est(u)` is taken again, and `q = (Δt / min Δt_est)²` bounds
/// `(ω Δt)²/4` of every local mode (`ω ≤ 2/Δt_est`). The linear bound
/// `q/(1 − q)` is applied with a factor 2 for the change of the local
/// frequencies along the motion.
#[test]
fn undamped_vibration_conserves_energy_udncf() {
    let material = MaterialSpec::named("schaefer2024").unwrap().material;
    let model = grid(4, 4, 5.0, 5.0, material);
    let dofs = clamp_left_edge(&model);
    let zero = vec![0.0; dofs.total];
    let system = System::new(&model, &dofs, &zero);
    let estimate = system.critical_time_step(&zero);
    let dt = 0.1 * estimate;
    // v/ω_max ≈ v Δt_est/2 = 1e-4 × 5 mm.
    let v0 = random_free(&dofs, 1e-4 * 5.0 * 2.0 / estimate, 5);
    let steps = 3000;
    let (times, control) = every_step(dt, steps);
    let params = parameters(steps as f64 * dt, control);
    let mut state = ExplicitState { u: zero, v: v0 };
    let mut smallest = estimate;
    let result = solve_explicit(
        &mut solver(&model),
        &dofs,
        &params,
        0.0,
        &times,
        &mut state,
        |_, s| {
            smallest = smallest.min(system.critical_time_step(s.u));
        },
    )
    .unwrap();
    assert_eq!(result.status, RunStatus::Complete);
    let q = (dt / smallest).powi(2);
    let bound = 2.0 * q / (1.0 - q);
    let worst = result.max_relative_balance_error;
    eprintln!(
        "energy (UD-NCF): min Δt_est/Δt_est(0) = {:.3}, worst balance error {worst:.3e} (bound {bound:.3e})",
        smallest / estimate
    );
    for record in &result.records {
        assert_eq!(record.energies.external_work, 0.0);
    }
    assert!(worst <= bound, "balance error {worst:e} > {bound:e}");
}

// ---------------------------------------------------------------------------
// 5. Damping
// ---------------------------------------------------------------------------

/// Requirement: with mass-proportional damping `α` the mechanical energy
/// decays at the rate `α` and the dissipated energy accounts for the loss.
///
/// SVK, 4 × 2 cells of 5 mm, left edge clamped, from rest in the shape of
/// the first mode; `α = 0.1 ω_1` (damping ratio `α/2ω_j ≤ 5 %`), over 6
/// periods of mode 1 (`α T = 3.8`), at `Δt = 0.9 Δt_est`.
///
/// Decay: per mode `d ln E_j/dt = −α (1 + osc)` with `osc = 2 KE/E − 1`,
/// whose integral over any interval is at most `1/(2 ω_j)` in size for
/// light damping, plus `O(ζ²) α T`; so `E(T) e^{αT}/E0` lies within
/// `e^{±2α/ω_1}` (the factor 2 of margin covers the `ζ²` terms and the
/// step's `(αΔt)²` change of the rate), times `1 − Σ_j q_j E_j0/E0` below
/// for the shadow-energy oscillation.
///
/// Balance: per mode (unit modal mass, constant step), with the solver's
/// update, its output velocity `v_n = v_{n−½} + (Δt/2)(a_n − α v_{n−½})` and
/// its dissipation `Σ α v̄² h` (`v̄` the mean of the two half-step
/// velocities), the staggered energy `½ v_{n+½}² + ½ ω² x_n x_{n+1}` plus the
/// dissipation is exactly constant, and the balance error at an output is
/// `(Δt²/8)(ω² x_n + α v_{n−½})² − (Δt²/8) ω² x_0 (ω² x_0 + α v̄_0)` once
/// the reported damping energy includes the half step from `t_{n−½}` to the
/// output `t_n` (as the kinetic energy does; without it the error has a
/// first-order term `−½ α Δt v_{n−½}²`). From rest `|x_n| ≤ x_0` and
/// `|v_{n±½}| ≤ ω x_0`, so per mode
/// `|error| ≤ E_j0 q_j ((1 + a_j)² + 1 + a_j)`, `a_j = α/ω_j`,
/// `q_j = (ω_j Δt)²/4`. Plus the geometric nonlinearity, `|∇u| ≤ 1e-5`
/// (1e-4 allowed).
#[test]
fn damping_dissipates_the_energy_lost() {
    let model = grid(4, 2, 5.0, 5.0, svk_general());
    let dofs = clamp_left_edge(&model);
    let modes = Modes::new(&model, &dofs);
    let zero = vec![0.0; dofs.total];
    let system = System::new(&model, &dofs, &zero);
    let dt = 0.9 * system.critical_time_step(&zero);
    let omega_1 = modes.omega2[0].sqrt();
    let alpha = 0.1 * omega_1;
    // The first mode, `M^{−½} y_1`, scaled to 2e-5 mm at most: then the
    // q-terms are small (ω_1 Δt ≈ 0.06) and so is the bound.
    let mut u0 = vec![0.0; dofs.total];
    for (i, &d) in modes.free.iter().enumerate() {
        u0[d] = modes.vectors[(i, 0)] / modes.sqrt_mass[i];
    }
    let largest = u0.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    u0.iter_mut().for_each(|x| *x *= 2e-5 / largest);
    let energies = modes.displacement_energies(&u0);
    let e0: f64 = energies.iter().sum();
    let bound = energies
        .iter()
        .zip(&modes.omega2)
        .map(|(e, w2)| {
            let q = w2 * dt * dt / 4.0;
            let a = alpha / w2.sqrt();
            e * q * ((1.0 + a).powi(2) + 1.0 + a)
        })
        .sum::<f64>()
        / e0;
    let nonlinear = 1e-4;
    let duration = 6.0 * 2.0 * std::f64::consts::PI / omega_1;
    let steps = (duration / dt).ceil() as usize;
    let (times, control) = every_step(dt, steps);
    let mut params = parameters(steps as f64 * dt, control);
    params.damping = alpha;
    let mut state = ExplicitState { u: u0, v: zero };
    let (result, _) = run(&model, &dofs, &params, 0.0, &times, &mut state, &[]);
    assert_eq!(result.status, RunStatus::Complete);
    let last = result.records.last().unwrap();
    // Σ q_j E_j0 / E0: the shadow-energy dip of E(T) below H̃ (from rest).
    let q_mean = energies
        .iter()
        .zip(&modes.omega2)
        .map(|(e, w2)| w2 * dt * dt / 4.0 * e)
        .sum::<f64>()
        / e0;
    let decay = mechanical(last) / e0 * (alpha * last.time).exp();
    let envelope = (2.0 * alpha / omega_1).exp();
    let worst = result.max_relative_balance_error;
    eprintln!(
        "damping: αΔt = {:.2e}, E(T)/E0 = {:.4e}, E(T) e^(αT)/E0 = {decay:.4} (envelope {:.3}..{envelope:.3}), D/E0 = {:.4}, worst balance error {worst:.3e} (bound {bound:.3e})",
        alpha * dt,
        mechanical(last) / e0,
        (1.0 - q_mean) / envelope,
        last.energies.damping / e0
    );
    assert!(
        decay <= envelope * (1.0 + nonlinear),
        "decays too slowly: {decay}"
    );
    assert!(
        decay >= (1.0 - q_mean) / envelope - nonlinear,
        "decays too fast: {decay}"
    );
    // The dissipated energy is the loss, up to the balance error.
    assert!(last.energies.damping > 0.9 * e0);
    assert!(
        worst <= bound + nonlinear,
        "balance error {worst:e} > {bound:e}"
    );
    for pair in result.records.windows(2) {
        assert!(pair[1].energies.damping >= pair[0].energies.damping);
    }
}

// ---------------------------------------------------------------------------
// 6. Threads
// ---------------------------------------------------------------------------

fn record_bits(r: &ExplicitRecord) -> Vec<u64> {
    let e = &r.energies;
    let mut bits = vec![r.increment as u64];
    bits.extend(
        [
            r.time,
            r.load,
            r.reaction,
            r.time_step,
            e.internal,
            e.kinetic,
            e.external_work,
            e.damping,
            e.balance_error,
            e.relative_balance_error,
        ]
        .map(f64::to_bits),
    );
    bits
}

/// Requirement: results do not depend on the number of threads, bit for
/// bit. 30 × 20 cells (1200 triangles, 651 nodes: more than one element
/// task of 512 and three node blocks of 256), UD-NCF, driven edge, random
/// initial velocity, damping, default stable step with its updates,
/// outputs at irregular times (shortened steps).
#[test]
fn results_do_not_depend_on_the_thread_count() {
    let material = MaterialSpec::named("schaefer2024").unwrap().material;
    let model = grid(30, 20, 2.0, 2.0, material);
    let mut conditions = Vec::new();
    for (n, x) in model.nodes.iter().enumerate() {
        if x.x == 0.0 {
            conditions.extend([Dirichlet::fixed(n, 0), Dirichlet::fixed(n, 1)]);
        }
        if x.x == 60.0 {
            conditions.extend([Dirichlet::driven(n, 0, 1.0), Dirichlet::fixed(n, 1)]);
        }
        conditions.push(Dirichlet::fixed(n, 2));
    }
    let dofs = DofMap::new(model.nodes.len(), &conditions);
    let zero = vec![0.0; dofs.total];
    let system = System::new(&model, &dofs, &zero);
    let estimate = system.critical_time_step(&zero);
    let v0 = random_free(&dofs, 1e-4 * 2.0 * 2.0 / estimate, 6);
    let duration = 250.0 * estimate;
    let times: Vec<f64> = [0.13, 0.3, 0.5, 0.77, 0.9].map(|f| f * duration).to_vec();
    let runs: Vec<(ExplicitResult, ExplicitState)> = [1, 2]
        .map(|threads| {
            let mut params = ExplicitParameters::new(duration);
            params.threads = threads;
            params.damping = 1e3;
            let mut state = ExplicitState {
                u: zero.clone(),
                v: v0.clone(),
            };
            let result = solve_explicit(
                &mut solver(&model),
                &dofs,
                &params,
                0.05,
                &times,
                &mut state,
                |_, _| {},
            )
            .unwrap();
            assert_eq!(result.status, RunStatus::Complete);
            assert_eq!(result.threads, threads);
            (result, state)
        })
        .into();
    let (one, two) = (&runs[0], &runs[1]);
    assert!(one.0.increments > 200);
    assert_eq!(one.0.records.len(), times.len() + 1);
    assert_eq!(one.0.records.len(), two.0.records.len());
    for (a, b) in one.0.records.iter().zip(&two.0.records) {
        assert_eq!(record_bits(a), record_bits(b), "{a:?} vs {b:?}");
    }
    let bits = |w: &[f64]| w.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&one.1.u), bits(&two.1.u));
    assert_eq!(bits(&one.1.v), bits(&two.1.v));
    assert_eq!(
        one.0.initial_critical_time_step.to_bits(),
        two.0.initial_critical_time_step.to_bits()
    );
}

// ---------------------------------------------------------------------------
// 7. Errors
// ---------------------------------------------------------------------------

/// Requirement: bad settings and models are rejected before the run, with
/// the setting's name and value.
#[test]
fn bad_settings_and_models_give_clear_errors() {
    let (model, dofs) = tiny_mesh();
    let run_with = |params: &ExplicitParameters, state: &mut ExplicitState| {
        solve_explicit(
            &mut solver(&model),
            &dofs,
            params,
            0.0,
            &[],
            state,
            |_, _| {},
        )
    };
    let base = parameters(1e-5, TimeStepControl::Fixed { time_step: 1e-7 });
    let mut cases: Vec<(ExplicitParameters, &str, &str)> = Vec::new();
    let mut p = base;
    p.duration = 0.0;
    cases.push((p, "duration", "0"));
    let mut p = base;
    p.time_step = TimeStepControl::Fixed { time_step: 0.0 };
    cases.push((p, "time_step", "0"));
    let mut p = base;
    p.time_step = TimeStepControl::Stable {
        safety_factor: 1.5,
        update_interval: 10,
    };
    cases.push((p, "safety_factor", "1.5"));
    let mut p = base;
    p.damping = -0.5;
    cases.push((p, "damping", "-0.5"));
    for (params, name, value) in cases {
        let mut state = ExplicitState::at_rest(dofs.total);
        match run_with(&params, &mut state) {
            Err(err @ ExplicitError::Setting(_)) => {
                let ExplicitError::Setting(setting) = &err else {
                    unreachable!()
                };
                assert_eq!(setting.name, name);
                assert_eq!(setting.value, value);
                let text = err.to_string();
                assert!(
                    text.contains(&format!("{name} = {value}")),
                    "message: {text}"
                );
            }
            other => panic!("{name} = {value}: {other:?}"),
        }
    }

    // A non-positive density: named with its value.
    let negative = Model::membrane(
        model.clone(),
        MembraneOptions {
            check_inversion: true,
            density: Some(-1e-9),
            roving_mass_length: 0.0,
            roving_mass_coupling: RovingCoupling::Stretch,
        },
    );
    let mut state = ExplicitState::at_rest(dofs.total);
    let err = solve_explicit(
        &mut { negative },
        &dofs,
        &base,
        0.0,
        &[],
        &mut state,
        |_, _| {},
    )
    .unwrap_err();
    assert!(
        matches!(err, ExplicitError::Term(_)) && err.to_string().contains("density = -0.000000001"),
        "{err}"
    );

    // A state of the wrong length, for u and for v.
    let params = base;
    let mut state = ExplicitState::at_rest(dofs.total - 1);
    assert!(matches!(
        run_with(&params, &mut state),
        Err(ExplicitError::StateSize { expected, given }) if expected == dofs.total && given == dofs.total - 1
    ));
    let mut state = ExplicitState::at_rest(dofs.total);
    state.v.push(0.0);
    assert!(matches!(
        run_with(&params, &mut state),
        Err(ExplicitError::StateSize { given, .. }) if given == dofs.total + 1
    ));

    // A node that no triangle uses, with a free dof (x; y and z fixed).
    let mut nodes = model.nodes.clone();
    nodes.push(Vector3::new(50.0, 50.0, 0.0));
    let lonely = nodes.len() - 1;
    let fibres = vec![Vector3::x(); model.triangles.len()];
    let bigger = MembraneModel::new(
        nodes,
        model.triangles.clone(),
        &fibres,
        model.material,
        THICKNESS,
    )
    .unwrap();
    let mut conditions = dofs.constrained.clone();
    conditions.extend([Dirichlet::fixed(lonely, 1), Dirichlet::fixed(lonely, 2)]);
    let bigger_dofs = DofMap::new(bigger.nodes.len(), &conditions);
    let mut state = ExplicitState::at_rest(bigger_dofs.total);
    let err = solve_explicit(
        &mut solver(&bigger),
        &bigger_dofs,
        &params,
        0.0,
        &[],
        &mut state,
        |_, _| {},
    )
    .unwrap_err();
    assert_eq!(
        err,
        ExplicitError::Setup(SetupError::MasslessNode { node: lonely })
    );
    assert!(err.to_string().contains(&format!("node {lonely}")), "{err}");
}

// ---------------------------------------------------------------------------
// 8. Prescribed motion
// ---------------------------------------------------------------------------

/// Requirement: a driven dof follows `λ(t) = λ_final shape(t/T)`: at every
/// output it equals `p λ` (the solver sets it, exactly), and `λ` equals the
/// smooth step `10τ³ − 15τ⁴ + 6τ⁵` evaluated here independently. Round-off:
/// each of the two evaluations rounds about 4 times, each rounding at most
/// `ε` of the largest partial sum, `≤ τ³ (10 + 15τ + 6τ²)` (the terms' sizes,
/// not their sum, which cancels to 7× less near `τ = 0.8`): allowed
/// `8 ε τ³ (10 + 15τ + 6τ²) |λ_final|`.
#[test]
fn driven_dofs_follow_the_smooth_step() {
    let model = grid(4, 2, 5.0, 5.0, svk_general());
    let mut conditions = Vec::new();
    let mut driven = Vec::new();
    for (n, x) in model.nodes.iter().enumerate() {
        if x.x == 0.0 {
            conditions.extend([Dirichlet::fixed(n, 0), Dirichlet::fixed(n, 1)]);
        }
        if x.x == 20.0 {
            // Stretch along x; shear the top corner along y as well.
            driven.push((3 * n, 1.0));
            if x.y == 10.0 {
                driven.push((3 * n + 1, 0.25));
            } else {
                conditions.push(Dirichlet::fixed(n, 1));
            }
        }
        conditions.push(Dirichlet::fixed(n, 2));
    }
    conditions.extend(
        driven
            .iter()
            .map(|&(d, p)| Dirichlet::driven(d / 3, d % 3, p)),
    );
    let dofs = DofMap::new(model.nodes.len(), &conditions);
    let modes = Modes::new(&model, &dofs);
    // Slow: 20 periods of the first mode.
    let duration = 20.0 * 2.0 * std::f64::consts::PI / modes.omega2[0].sqrt();
    let final_load = 0.05;
    // τ_k = k/40 exactly, so the last output is T itself.
    let times: Vec<f64> = (1..=40).map(|k| k as f64 / 40.0 * duration).collect();
    let mut params = ExplicitParameters::new(duration);
    params.threads = 1;
    assert_eq!(params.amplitude, Amplitude::SmoothStep);
    let mut state = ExplicitState::at_rest(dofs.total);
    let watch: Vec<usize> = driven.iter().map(|&(d, _)| d).collect();
    let (result, watched) = run(
        &model, &dofs, &params, final_load, &times, &mut state, &watch,
    );
    assert_eq!(result.status, RunStatus::Complete);
    assert_eq!(result.records.len(), times.len());
    for ((record, values), &time) in result.records.iter().zip(&watched).zip(&times) {
        assert_eq!(record.time, time);
        let tau = time / duration;
        assert_eq!(record.load, final_load * Amplitude::SmoothStep.shape(tau));
        let smooth = tau * tau * tau * (10.0 - 15.0 * tau + 6.0 * tau * tau);
        let round_off =
            8.0 * f64::EPSILON * tau.powi(3) * (10.0 + 15.0 * tau + 6.0 * tau * tau) * final_load;
        assert!(
            (record.load - final_load * smooth).abs() <= round_off,
            "λ({tau}) = {} vs {}",
            record.load,
            final_load * smooth
        );
        for (&(_, p), &u) in driven.iter().zip(values) {
            assert_eq!(u, p * record.load);
        }
    }
    assert_eq!(result.records.last().unwrap().load, final_load);
    // The motion does work on the membrane.
    assert!(result.records.last().unwrap().energies.external_work > 0.0);
}

// ---------------------------------------------------------------------------
// Roving mass scaling: coupling masses along the rovings
// ---------------------------------------------------------------------------

/// The membrane with roving mass scaling length `length` [mm] and the
/// coupling form `coupling` as the case builds it.
fn solver_with_roving_mass(model: &MembraneModel, length: f64, coupling: RovingCoupling) -> Model {
    Model::membrane(
        model.clone(),
        MembraneOptions {
            check_inversion: true,
            density: Some(RHO),
            roving_mass_length: length,
            roving_mass_coupling: coupling,
        },
    )
}

/// The mass matrix of the free dofs with roving mass scaling length
/// `length`, assembled here from its definition (`docs/explicit.md`): the
/// lumped masses plus, per triangle, `κ ρ t A0/3 (e_i − e_j)(e_i − e_j)ᵀ`
/// on its edge along the rovings (found from the reference geometry: the
/// edge whose direction is x), `κ = 3 (ℓ/L)²` with `L` that edge's
/// length, on every component (`Full`) or `⊗ d dᵀ` with `d` the edge's
/// direction at the displacements `u` (`Stretch`); the block of the free
/// dofs.
fn coupled_mass(
    model: &MembraneModel,
    dofs: &DofMap,
    length: f64,
    coupling: RovingCoupling,
    u: &[f64],
) -> DMatrix<f64> {
    let lumped = lumped_masses(model);
    let n = 3 * model.nodes.len();
    let mut m = DMatrix::zeros(n, n);
    for d in 0..n {
        m[(d, d)] = lumped[d / 3];
    }
    for (t, r) in model.triangles.iter().zip(&model.references) {
        let edge = (0..3)
            .map(|a| (t[a], t[(a + 1) % 3]))
            .find(|&(i, j)| (model.nodes[i].y - model.nodes[j].y).abs() < 1e-12)
            .expect("every grid triangle has an edge along x");
        let (i, j) = edge;
        let edge_length = (model.nodes[i] - model.nodes[j]).norm();
        let kappa = 3.0 * (length / edge_length).powi(2);
        let mu = kappa * RHO * model.thickness * r.area / 3.0;
        let current = (model.nodes[j] - model.nodes[i])
            + Vector3::from_fn(|k, _| u[3 * j + k] - u[3 * i + k]);
        let d = current.normalize();
        for (na, sa) in [(i, 1.0), (j, -1.0)] {
            for (nb, sb) in [(i, 1.0), (j, -1.0)] {
                for k in 0..3 {
                    for l in 0..3 {
                        let weight = match coupling {
                            RovingCoupling::Full => f64::from(k == l),
                            RovingCoupling::Stretch => d[k] * d[l],
                        };
                        m[(3 * na + k, 3 * nb + l)] += mu * sa * sb * weight;
                    }
                }
            }
        }
    }
    DMatrix::from_fn(dofs.free.len(), dofs.free.len(), |r, c| {
        m[(dofs.free[r], dofs.free[c])]
    })
}

/// Modes of `K y = ω² M y` on the free dofs for a full mass matrix `M =
/// L Lᵀ`: `L⁻¹ K L⁻ᵀ = Y Λ Yᵀ`, modal coordinates `Yᵀ Lᵀ w`.
struct CoupledModes {
    free: Vec<usize>,
    l_transpose: DMatrix<f64>,
    omega2: Vec<f64>,
    vectors: DMatrix<f64>,
}

impl CoupledModes {
    fn new(model: &MembraneModel, dofs: &DofMap, mass: DMatrix<f64>) -> Self {
        Self::at(model, dofs, mass, &vec![0.0; dofs.total])
    }

    /// The modes about the displacements `u`.
    fn at(model: &MembraneModel, dofs: &DofMap, mass: DMatrix<f64>, u: &[f64]) -> Self {
        let k = stiffness_at(model, u);
        let free = dofs.free.clone();
        let k_free = DMatrix::from_fn(free.len(), free.len(), |i, j| k[(free[i], free[j])]);
        let l = mass.cholesky().expect("positive definite mass").l();
        let l_inv = l.clone().try_inverse().expect("regular");
        let a = &l_inv * k_free * l_inv.transpose();
        let eigen = SymmetricEigen::new(0.5 * (&a + a.transpose()));
        let mut order: Vec<usize> = (0..free.len()).collect();
        order.sort_by(|&i, &j| eigen.eigenvalues[i].total_cmp(&eigen.eigenvalues[j]));
        Self {
            omega2: order.iter().map(|&i| eigen.eigenvalues[i]).collect(),
            vectors: DMatrix::from_fn(free.len(), free.len(), |r, c| {
                eigen.eigenvectors[(r, order[c])]
            }),
            l_transpose: l.transpose(),
            free,
        }
    }

    fn omega_max(&self) -> f64 {
        self.omega2.last().expect("free dofs").sqrt()
    }

    /// Energy per mode of a velocity: `½ η_j²`, `η = Yᵀ Lᵀ v`.
    fn velocity_energies(&self, v: &[f64]) -> Vec<f64> {
        let w = DVector::from_iterator(self.free.len(), self.free.iter().map(|&d| v[d]));
        let eta = self.vectors.transpose() * (&self.l_transpose * w);
        eta.iter().map(|e| 0.5 * e * e).collect()
    }
}

/// A fibre-dominated SVK law (the rovings 100 times stiffer than the
/// rest), where roving mass scaling is meant to act.
fn svk_rovings() -> Material {
    svk(1000.0, 10.0, 0.3, 5.0)
}

/// Requirement: with roving mass scaling the estimated critical step
/// still bounds the exact `2/ω_max` of `K y = ω² M y` with the coupled
/// mass matrix from below (the element-by-element bound holds for any
/// split of `M` into element shares, and the solver's shares sum to the
/// matrix assembled here), and the coupling masses lengthen it. Both
/// forms at rest; the stretch form also at a homogeneous state stretched
/// 0.2 % along the rovings, sheared by 0.1 and turned 30° out of its
/// plane, where the roving direction is no axis (`c12 ≠ 0`, `c11 ≠ 1`,
/// a tensile stress in the geometric part).
///
/// Bounds used: the estimate ≤ exact up to the 1e-10 finite-difference
/// error of `K`; the same `1/√6` lower limit as the lumped case
/// (`stable_step_estimate_bounds_the_exact_critical_step`: the argument
/// uses only the trace of `K_e` over the node masses, which the coupling
/// masses only raise).
#[test]
fn roving_mass_step_bounds_the_exact_critical_step() {
    let model = grid(4, 2, 5.0, 5.0, svk_rovings());
    let dofs = clamp_left_edge(&model);
    let rest = vec![0.0; dofs.total];
    // x ↦ R (I + G) x: stretch, shear, a turn about the y axis.
    let (c, s) = (30f64.to_radians().cos(), 30f64.to_radians().sin());
    let turn = nalgebra::Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c);
    let strain = nalgebra::Matrix3::new(1.002, 0.1, 0.0, 0.0, 0.999, 0.0, 0.0, 0.0, 1.0);
    let deformed: Vec<f64> = model
        .nodes
        .iter()
        .flat_map(|x| {
            let y = turn * strain * x - x;
            [y.x, y.y, y.z]
        })
        .collect();
    // ℓ = 5 √(10/3) mm: κ = 10 on the 5 mm roving edges.
    let length = 5.0 * (10.0_f64 / 3.0).sqrt();
    for (coupling, u) in [
        (RovingCoupling::Full, &rest),
        (RovingCoupling::Stretch, &rest),
        (RovingCoupling::Stretch, &deformed),
    ] {
        let mass = |length: f64| coupled_mass(&model, &dofs, length, coupling, u);
        let lumped = CoupledModes::at(&model, &dofs, mass(0.0), u);
        let coupled = CoupledModes::at(&model, &dofs, mass(length), u);
        let estimate = |length: f64| {
            let mut m = solver_with_roving_mass(&model, length, coupling);
            let system = ExplicitSystem::new(&mut m, &dofs, None, &State::at(u)).unwrap();
            system.critical_time_step(&m, &State::at(u)).unwrap()
        };
        let (est_lumped, est_coupled) = (estimate(0.0), estimate(length));
        let (exact_lumped, exact_coupled) = (2.0 / lumped.omega_max(), 2.0 / coupled.omega_max());
        let deformed_state = u.iter().any(|x| *x != 0.0);
        eprintln!(
            "roving mass {coupling:?} (deformed: {deformed_state}) ℓ = {length:.3} mm (κ = 10): exact step {exact_lumped:.4e} → {exact_coupled:.4e} s (×{:.2}), estimate {est_lumped:.4e} → {est_coupled:.4e} s (×{:.2})",
            exact_coupled / exact_lumped,
            est_coupled / est_lumped
        );
        assert!(est_coupled <= exact_coupled * (1.0 + 1e-8));
        assert!(est_coupled >= exact_coupled / 6f64.sqrt());
        // The coupling masses only add mass: no step gets shorter.
        assert!(exact_coupled >= exact_lumped * (1.0 - 1e-10));
        assert!(est_coupled > est_lumped);
    }
}

/// Requirement: with roving mass scaling the undamped vibration keeps its
/// energy, with the kinetic energy `½ vᵀ M v` of the coupled mass.
///
/// As `undamped_vibration_conserves_energy_svk`, with the modes of the
/// coupled mass: from a pure velocity each mode keeps
/// `E_j ∈ [E_j0, E_j0/(1 − q_j)]`, so the balance error is at most
/// `Σ q_j/(1 − q_j) E_j0 / E0`, plus 1e-5 for the geometric nonlinearity.
/// The solver's initial kinetic energy must be `½ v0ᵀ M v0` (the modal
/// sum, to the round-off of the decomposition): without the couplings'
/// part it would be off by the coupled share.
#[test]
fn undamped_vibration_conserves_energy_with_roving_mass() {
    for coupling in [RovingCoupling::Full, RovingCoupling::Stretch] {
        vibration_with_roving_mass(coupling);
    }
}

fn vibration_with_roving_mass(coupling: RovingCoupling) {
    let model = grid(4, 2, 5.0, 5.0, svk_rovings());
    let dofs = clamp_left_edge(&model);
    let length = 5.0 * (10.0_f64 / 3.0).sqrt();
    let zero = vec![0.0; dofs.total];
    let modes = CoupledModes::new(
        &model,
        &dofs,
        coupled_mass(&model, &dofs, length, coupling, &zero),
    );
    let mut m = solver_with_roving_mass(&model, length, coupling);
    let system = ExplicitSystem::new(&mut m, &dofs, None, &State::at(&zero)).unwrap();
    assert!(system.has_mass_couplings());
    let dt = 0.9 * system.critical_time_step(&m, &State::at(&zero)).unwrap();
    let omega_1 = modes.omega2[0].sqrt();
    let v0 = random_free(&dofs, 1e-6 * omega_1, 4);
    let energies = modes.velocity_energies(&v0);
    let e0: f64 = energies.iter().sum();
    let bound = velocity_balance_bound(&energies, &modes.omega2, dt);
    let steps = 4000;
    let (times, control) = every_step(dt, steps);
    let params = parameters(steps as f64 * dt, control);
    let lumped: f64 = {
        let m = lumped_masses(&model);
        dofs.free
            .iter()
            .map(|&d| 0.5 * m[d / 3] * v0[d].powi(2))
            .sum()
    };
    let mut state = ExplicitState { u: zero, v: v0 };
    let result = solve_explicit(
        &mut solver_with_roving_mass(&model, length, coupling),
        &dofs,
        &params,
        0.0,
        &times,
        &mut state,
        |_, _: &Snapshot| {},
    )
    .expect("the run starts");
    assert_eq!(result.status, RunStatus::Complete);
    let first = &result.records[0];
    let initial = mechanical(first) - first.energies.balance_error;
    assert!(
        (initial / e0 - 1.0).abs() < 1e-9,
        "E0 {initial:e} vs ½ v0ᵀ M v0 = {e0:e}"
    );
    // The couplings carry a visible share of the random velocity's energy.
    assert!(e0 > 1.05 * lumped, "coupled {e0:e} vs lumped {lumped:e}");
    let worst = result.max_relative_balance_error;
    eprintln!(
        "energy (roving mass {coupling:?}, ℓ = {length:.3} mm): ωmaxΔt = {:.3}, worst balance error {worst:.3e} (bound {bound:.3e})",
        modes.omega_max() * dt
    );
    assert!(worst <= bound + 1e-5, "balance error {worst:e} > {bound:e}");
}

/// Requirement: roving mass scaling on a mesh without an edge along the
/// rovings in every triangle is refused, naming the triangle.
#[test]
fn roving_mass_needs_an_edge_along_the_rovings() {
    let nodes = vec![
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(10.0, 3.0, 0.0),
        Vector3::new(2.0, 8.0, 0.0),
    ];
    let model = MembraneModel::new(
        nodes,
        vec![[0, 1, 2]],
        &[Vector3::x()],
        svk_rovings(),
        THICKNESS,
    )
    .expect("model");
    let dofs = DofMap::new(3, &[]);
    let params = parameters(
        1e-6,
        TimeStepControl::Stable {
            safety_factor: 0.9,
            update_interval: 100,
        },
    );
    let err = solve_explicit(
        &mut solver_with_roving_mass(&model, 5.0, RovingCoupling::Stretch),
        &dofs,
        &params,
        0.0,
        &[],
        &mut ExplicitState::at_rest(9),
        |_, _: &Snapshot| {},
    )
    .expect_err("no roving edge");
    let text = err.to_string();
    assert!(
        text.contains("element 0") && text.contains("along the rovings"),
        "{text}"
    );
}
