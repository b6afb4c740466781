//! Tests of the node-to-rigid-surface contact kernels
//! (`ncform::contact::kernel`, `docs/contact-kernels.md`): the augmented
//! Lagrangian kernel against its energy and central differences of its
//! residual, its Coulomb return map, the Uzawa iteration against the
//! closed-form rate, the tool-translation expansion, and the explicit
//! penalty kernel's energy balance, Coulomb bound and stiffness limit.
//!
//! The tools are exact signed-distance functions written here (plane,
//! sphere seen from outside and from inside a spherical cavity, cylinder),
//! so that the kernels are tested against geometry known in closed form.
//!
//! Tolerances (derived at their use):
//! - central differences with step `h` of a function analytic on a disc of
//!   radius `ℓ/2` around the point, bounded there by `4 M` (`M` the largest
//!   force scale reached within `ℓ`), have truncation error
//!   `h²/6 |f'''| ≤ h²/6 · 3! · 4M/(ℓ/2)³ = 32 (h/ℓ)² M/ℓ` (Cauchy estimate)
//!   and round-off error `δr/h` when each value carries an absolute error
//!   `δr`;
//! - `δr` is estimated as `16 ε_mach` times the sum of the magnitudes the
//!   evaluation adds up (positions enter through differences, so a penalty
//!   times a coordinate is one of them): a few tens of flops, each adding
//!   at most `ε_mach` of its operands.

use nalgebra::{Matrix3, Vector3, Vector4};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use ncform::contact::kernel::{
    AugmentationNorms, AugmentedLagrangian, ImplicitContactState, ImplicitResponse, PenaltyContact,
    PenaltyResponse, PenaltyState, Smoothing, max_curvature, stable_penalty_stiffness,
};
use ncform::contact::{
    ContactError, ContactStatus, RigidSurface, SurfacePoint, couple_tool_translation,
};

const EPS: f64 = f64::EPSILON;

// ---------------------------------------------------------------------------
// Exact tools
// ---------------------------------------------------------------------------

/// The shapes of the tests, with the closed-form signed distance.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Shape {
    /// `d = n·y − level`.
    Plane,
    /// `d = |y − c| − R`: a ball, free outside.
    SphereOutside,
    /// `d = R − |y − c|`: a spherical cavity, free inside.
    SphereInside,
    /// `d = |(I − e⊗e)(y − c)| − R`: a cylinder along `e`, free outside.
    Cylinder,
}

const SHAPES: [Shape; 4] = [
    Shape::Plane,
    Shape::SphereOutside,
    Shape::SphereInside,
    Shape::Cylinder,
];

/// A tool: shape, centre (or a point of the plane/axis), radius and an
/// orthonormal frame `[e1, e2, e3]` (`e3` = plane normal, sphere pole or
/// cylinder axis).
#[derive(Debug, Clone, Copy)]
struct Tool {
    shape: Shape,
    centre: Vector3<f64>,
    radius: f64,
    frame: [Vector3<f64>; 3],
}

fn random_unit(rng: &mut StdRng) -> Vector3<f64> {
    loop {
        let v = Vector3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let norm = v.norm();
        if norm > 0.1 && norm <= 1.0 {
            return v / norm;
        }
    }
}

fn frame_from(e3: Vector3<f64>) -> [Vector3<f64>; 3] {
    let helper = if e3.x.abs() < 0.6 {
        Vector3::x()
    } else {
        Vector3::y()
    };
    let e1 = e3.cross(&helper).normalize();
    let e2 = e3.cross(&e1);
    [e1, e2, e3]
}

impl Tool {
    fn random(shape: Shape, rng: &mut StdRng) -> Self {
        let centre = Vector3::new(
            rng.random_range(-100.0..100.0),
            rng.random_range(-100.0..100.0),
            rng.random_range(-100.0..100.0),
        );
        Self {
            shape,
            centre,
            radius: rng.random_range(20.0..100.0),
            frame: frame_from(random_unit(rng)),
        }
    }

    /// The exact answer at `y` (`None` on the centre or axis).
    fn query(&self, y: &Vector3<f64>) -> Option<SurfacePoint> {
        let rel = y - self.centre;
        match self.shape {
            Shape::Plane => Some(SurfacePoint {
                distance: self.frame[2].dot(&rel),
                normal: self.frame[2],
                hessian: Matrix3::zeros(),
            }),
            Shape::SphereOutside | Shape::SphereInside => {
                let r = rel.norm();
                if r == 0.0 {
                    return None;
                }
                let u = rel / r;
                let proj = (Matrix3::identity() - u * u.transpose()) / r;
                if self.shape == Shape::SphereOutside {
                    Some(SurfacePoint {
                        distance: r - self.radius,
                        normal: u,
                        hessian: proj,
                    })
                } else {
                    Some(SurfacePoint {
                        distance: self.radius - r,
                        normal: -u,
                        hessian: -proj,
                    })
                }
            }
            Shape::Cylinder => {
                let e = self.frame[2];
                let radial = rel - e.dot(&rel) * e;
                let r = radial.norm();
                if r == 0.0 {
                    return None;
                }
                let u = radial / r;
                Some(SurfacePoint {
                    distance: r - self.radius,
                    normal: u,
                    hessian: (Matrix3::identity() - e * e.transpose() - u * u.transpose()) / r,
                })
            }
        }
    }

    /// The point at surface coordinates `u` [mm] and signed distance `d`.
    fn at(&self, u: [f64; 2], d: f64) -> Vector3<f64> {
        let [e1, e2, e3] = self.frame;
        match self.shape {
            Shape::Plane => self.centre + u[0] * e1 + u[1] * e2 + d * e3,
            Shape::SphereOutside | Shape::SphereInside => {
                let dir = (e3 + (u[0] * e1 + u[1] * e2) / self.radius).normalize();
                let r = if self.shape == Shape::SphereOutside {
                    self.radius + d
                } else {
                    self.radius - d
                };
                self.centre + r * dir
            }
            Shape::Cylinder => {
                let angle = u[0] / self.radius;
                self.centre + u[1] * e3 + (self.radius + d) * (angle.cos() * e1 + angle.sin() * e2)
            }
        }
    }

    /// Distance to the centre or axis (the radius of curvature of the
    /// level set through `y`); `∞` for the plane.
    fn radius_at(&self, y: &Vector3<f64>) -> f64 {
        let rel = y - self.centre;
        match self.shape {
            Shape::Plane => f64::INFINITY,
            Shape::SphereOutside | Shape::SphereInside => rel.norm(),
            Shape::Cylinder => (rel - self.frame[2].dot(&rel) * self.frame[2]).norm(),
        }
    }

    /// The coordinate scale entering the round-off of `d`.
    fn size(&self) -> f64 {
        self.centre.norm() + self.radius
    }

    /// Largest `|d|` used for states (keeps away from the centre or axis).
    fn max_depth(&self) -> f64 {
        match self.shape {
            Shape::Plane => f64::INFINITY,
            _ => 0.5 * self.radius,
        }
    }
}

impl RigidSurface for Tool {
    fn closest(&self, x: &Vector3<f64>, max_distance: f64) -> Option<SurfacePoint> {
        self.query(x).filter(|p| p.distance <= max_distance)
    }
}

/// `10^U(a, b)`.
fn log_uniform(rng: &mut StdRng, a: f64, b: f64) -> f64 {
    10f64.powf(rng.random_range(a..b))
}

// ---------------------------------------------------------------------------
// Implicit kernel: random states and their finite-difference scales
// ---------------------------------------------------------------------------

/// One random implicit state: settings, state and position on a tool.
#[derive(Debug, Clone, Copy)]
struct ImplicitCase {
    law: AugmentedLagrangian,
    state: ImplicitContactState,
    y: Vector3<f64>,
    tool: Tool,
}

/// A random state of status `target` on `tool` (the status is steered by
/// the test's own formulas; the kernel's status is asserted separately):
/// `ε_N ∈ [1e2, 1e4]` N/mm, `ε_T ∈ [0.1, 1] ε_N`, `μ ∈ [0.05, 1]`, offset
/// `∈ [0, 0.3]` mm; open states lie `1e-3..1` mm beyond the kink, active
/// ones `1e-3..0.2` mm inside it (`t_N = ε_N δ`, `λ_N ∈ [0, 2 t_N]`); the
/// trial force is `0.05..0.9` (stick) or `1.1..20` (slip) times `μ t_N`,
/// made of a random 3D `λ_T` (with a normal component, to exercise the
/// re-projection) and a random `y − y_ref`.
fn random_case(
    rng: &mut StdRng,
    tool: &Tool,
    target: ContactStatus,
    mu: Option<f64>,
) -> ImplicitCase {
    loop {
        let eps_n = log_uniform(rng, 2.0, 4.0);
        let eps_t = eps_n * rng.random_range(0.1..1.0);
        let offset = rng.random_range(0.0..0.3);
        let friction = mu.unwrap_or_else(|| rng.random_range(0.05..1.0));
        let (lambda_n, gap) = if target == ContactStatus::Open {
            let lambda = rng.random_range(0.0..200.0);
            (lambda, lambda / eps_n + log_uniform(rng, -3.0, 0.0))
        } else {
            let t_n = eps_n * log_uniform(rng, -3.0, 0.2f64.log10());
            let lambda = rng.random_range(0.0..2.0) * t_n;
            (lambda, (lambda - t_n) / eps_n)
        };
        let d = gap + offset;
        if d.abs() > tool.max_depth() {
            continue;
        }
        let y = tool.at(
            [rng.random_range(-20.0..20.0), rng.random_range(-20.0..20.0)],
            d,
        );
        let Some(point) = tool.query(&y) else {
            continue;
        };
        let n = point.normal;
        let t_n = (lambda_n - eps_n * (point.distance - offset)).max(0.0);
        let raw_lambda = random_unit(rng) * rng.random_range(0.0..1.0);
        let raw_motion = random_unit(rng) * log_uniform(rng, -2.0, 0.0);
        let w = raw_lambda + eps_t * raw_motion;
        let raw_trial = w - n.dot(&w) * n;
        let scale = match target {
            _ if friction == 0.0 => 1.0,
            ContactStatus::Open => 1.0,
            ContactStatus::Stick => rng.random_range(0.05..0.9) * friction * t_n / raw_trial.norm(),
            ContactStatus::Slip => rng.random_range(1.1..20.0) * friction * t_n / raw_trial.norm(),
        };
        if !scale.is_finite() || scale <= 0.0 {
            continue;
        }
        let law = AugmentedLagrangian::new(eps_n, eps_t, friction, offset).expect("valid settings");
        let state = ImplicitContactState::with_multipliers(
            &(y - scale * raw_motion),
            lambda_n,
            &(scale * raw_lambda),
        );
        return ImplicitCase {
            law,
            state,
            y,
            tool: *tool,
        };
    }
}

/// The finite-difference step, tolerance and kink band of a state
/// (module doc): `ℓ` is the radius over which the active branch of `r_y`
/// stays analytic, `min(ρ, |t*|/(ε_T + 2|w|κ), 10 mm)` with `ρ` the
/// distance to the centre/axis (`κ = 1/ρ`) and the second term (slip only)
/// the scale of the slip direction `t*/|t*|`; `h` minimises the
/// tolerance below (`h/ℓ = (δr/(64 M))^(1/3)`); the state is
/// outside the kink band if both kinks are farther than `2 h` (the
/// distances are bounds from the gradient at the centre, which varies by a
/// relative `O(h/ℓ)` over the stencil, so a factor 2 keeps the stencil
/// `±h` on one branch; the test also asserts the status at every stencil
/// point and that `ℓ ≥ 1e-3` mm): the normal kink at distance
/// `|λ_N − ε_N g|/ε_N`, the stick–slip kink at `||t*| − μ t_N| / (ε_T +
/// 2|w|κ + μ ε_N)` (a bound on the gradient of `|t*| − μ t_N`).
#[derive(Debug, Clone, Copy)]
struct FdScales {
    h: f64,
    ell: f64,
    /// Force scale `M` reached within `ℓ` [N].
    force_scale: f64,
    /// Absolute round-off `δr` of one residual evaluation [N].
    round_off: f64,
    band_ok: bool,
}

impl FdScales {
    /// The scales from `ℓ`, `M` and `δr`, with the step that minimises
    /// truncation + round-off, `32 (h/ℓ)² M/ℓ + δr/h`: `h/ℓ = (δr/(64
    /// M))^(1/3)`, kept within `[1e-8, 1e-3]`; the state is usable when the
    /// nearest point where the law's derivative jumps (`kink`, mm) is at
    /// least `2 h` away and `ℓ ≥ 1e-3` mm.
    fn new(ell: f64, force_scale: f64, round_off: f64, kink: f64) -> Self {
        let h = ell * (round_off / (64.0 * force_scale)).cbrt().clamp(1e-8, 1e-3);
        Self {
            h,
            ell,
            force_scale,
            round_off,
            band_ok: kink >= 2.0 * h && ell >= 1e-3,
        }
    }

    /// Tolerance on an entry of `K` against the central difference:
    /// truncation `32 (h/ℓ)² M/ℓ`, round-off of the difference `δr/h`,
    /// round-off of `K` itself `32 ε M/ℓ` (`‖K‖ ≲ 2 M/ℓ`).
    fn tangent_tolerance(&self) -> f64 {
        let ratio = self.h / self.ell;
        32.0 * ratio * ratio * self.force_scale / self.ell
            + self.round_off / self.h
            + 32.0 * EPS * self.force_scale / self.ell
    }
}

fn implicit_scales(case: &ImplicitCase, extra_position: f64) -> FdScales {
    let law = &case.law;
    let state = &case.state;
    let point = case.tool.query(&case.y).expect("off the centre");
    let n = point.normal;
    let gap = point.distance - law.offset();
    let trial_normal = state.normal_multiplier - law.normal_penalty() * gap;
    let t_n = trial_normal.max(0.0);
    let w =
        state.tangential_multiplier + law.tangential_penalty() * (case.y - state.slip_reference);
    let trial = w - n.dot(&w) * n;
    let rho = case.tool.radius_at(&case.y);
    let kappa = 1.0 / rho;
    let active = trial_normal >= 0.0;
    let friction = law.friction();
    let slip = active && friction > 0.0 && trial.norm() > friction * t_n;
    let slip_scale = if slip {
        trial.norm() / (law.tangential_penalty() + 2.0 * w.norm() * kappa)
    } else {
        f64::INFINITY
    };
    let ell = rho.min(slip_scale).min(10.0);
    let penalties = law.normal_penalty() + law.tangential_penalty();
    let lambda_t = state.tangential_multiplier.norm();
    let force_scale = t_n + state.normal_multiplier + w.norm() + lambda_t + penalties * ell;
    let slip_amplification = if slip {
        friction * t_n / trial.norm()
    } else {
        0.0
    };
    let round_off = 16.0
        * EPS
        * (penalties
            * (case.y.norm() + state.slip_reference.norm() + case.tool.size() + extra_position)
            + state.normal_multiplier
            + t_n
            + lambda_t
            + w.norm() * (1.0 + slip_amplification));
    let normal_kink = trial_normal.abs() / law.normal_penalty();
    let friction_kink = if active && friction > 0.0 {
        (trial.norm() - friction * t_n).abs()
            / (law.tangential_penalty() + 2.0 * w.norm() * kappa + friction * law.normal_penalty())
    } else {
        f64::INFINITY
    };
    FdScales::new(ell, force_scale, round_off, normal_kink.min(friction_kink))
}

fn evaluate(case: &ImplicitCase, y: &Vector3<f64>) -> ImplicitResponse {
    let point = case.tool.query(y).expect("off the centre");
    case.law
        .evaluate(&case.state, y, Some(&point))
        .expect("finite state")
}

/// Central differences of `r_y` at `case.y` with step `h`: the Jacobian and
/// whether every stencil point kept the centre's status.
fn fd_tangent(case: &ImplicitCase, h: f64, status: ContactStatus) -> (Matrix3<f64>, bool) {
    let mut jacobian = Matrix3::zeros();
    let mut same = true;
    for j in 0..3 {
        let mut plus = case.y;
        let mut minus = case.y;
        plus[j] += h;
        minus[j] -= h;
        let step = plus[j] - minus[j];
        let rp = evaluate(case, &plus);
        let rm = evaluate(case, &minus);
        same &= rp.status == status && rm.status == status;
        jacobian.set_column(j, &((rp.residual - rm.residual) / step));
    }
    (jacobian, same)
}

/// Central differences of `f` at `y` with step `h` in each coordinate.
fn central_gradient(y: &Vector3<f64>, h: f64, f: impl Fn(&Vector3<f64>) -> f64) -> Vector3<f64> {
    let mut gradient = Vector3::zeros();
    for j in 0..3 {
        let mut plus = *y;
        let mut minus = *y;
        plus[j] += h;
        minus[j] -= h;
        gradient[j] = (f(&plus) - f(&minus)) / (plus[j] - minus[j]);
    }
    gradient
}

fn max_abs_vector(v: &Vector3<f64>) -> f64 {
    v.iter().fold(0.0f64, |a, b| a.max(b.abs()))
}

fn max_abs(m: &Matrix3<f64>) -> f64 {
    m.iter().fold(0.0f64, |a, b| a.max(b.abs()))
}

/// Statistics of one family of finite-difference checks.
#[derive(Debug, Default)]
struct Tally {
    accepted: usize,
    rejected_in_band: usize,
    worst_ratio: f64,
    /// States at which a deliberately wrong tangent fails the same check.
    flagged: usize,
    /// States at which that wrong tangent was examined.
    examined: usize,
}

impl Tally {
    /// Asserts `|K − FD| ≤ tol` entrywise at the state `case` (`label`
    /// names the family) and counts the state.
    fn accept(
        &mut self,
        label: &str,
        tangent: &Matrix3<f64>,
        fd: &Matrix3<f64>,
        tol: f64,
        case: &ImplicitCase,
    ) {
        let error = max_abs(&(tangent - fd));
        assert!(
            error <= tol,
            "{label}: |K − FD| = {error:e} > {tol:e}\nK = {tangent}\nFD = {fd}\n{case:?}"
        );
        self.worst_ratio = self.worst_ratio.max(error / tol);
        self.accepted += 1;
    }

    /// Asserts that the deliberately wrong tangent failed the check at
    /// ≥ 90 % of the states where it was examined (if any).
    fn assert_power(&self, label: &str) {
        if self.examined > 0 {
            assert!(
                self.flagged * 10 >= self.examined * 9,
                "{label}: weak test ({} of {} flagged)",
                self.flagged,
                self.examined
            );
        }
    }
}

// ---------------------------------------------------------------------------
// Implicit kernel: tangent and residual against finite differences
// ---------------------------------------------------------------------------

/// Eq. I5–I7 (`docs/contact-kernels.md`, "Consistent tangent"): `K`
/// equals the central differences of `r_y` at 1,000 random states in each
/// status (open, stick, slip) on each tool (plane, sphere from outside and
/// inside, cylinder), with random penalties, multipliers, references and
/// `μ`. States within `2 h` of a kink are redrawn (`FdScales`), and every
/// stencil point must keep the centre's status.
///
/// Power of the test (asserted): on the curved tools, dropping the
/// curvature term `−t_N H` from `K` fails the same check at ≥ 90 % of the
/// active states; in slip, the symmetric variant `½(K + Kᵀ)` fails it at
/// ≥ 90 % of the states (it is not the consistent tangent).
#[test]
fn tangent_matches_central_differences_in_every_status() {
    let mut rng = StdRng::seed_from_u64(0xC0_47AC7);
    for shape in SHAPES {
        for target in [
            ContactStatus::Open,
            ContactStatus::Stick,
            ContactStatus::Slip,
        ] {
            let mut tally = Tally::default();
            let mut symmetric = Tally::default();
            while tally.accepted < 1000 {
                let tool = Tool::random(shape, &mut rng);
                let case = random_case(&mut rng, &tool, target, None);
                let scales = implicit_scales(&case, 0.0);
                if !scales.band_ok {
                    tally.rejected_in_band += 1;
                    continue;
                }
                let response = evaluate(&case, &case.y);
                assert_eq!(response.status, target, "{shape:?}: status of {case:?}");
                let (fd, same) = fd_tangent(&case, scales.h, target);
                assert!(
                    same,
                    "{shape:?} {target:?}: the stencil crossed a kink: {case:?}"
                );
                let tol = scales.tangent_tolerance();
                tally.accept(
                    &format!("{shape:?} {target:?}"),
                    &response.tangent,
                    &fd,
                    tol,
                    &case,
                );
                let point = tool.query(&case.y).expect("off the centre");
                if shape != Shape::Plane && target != ContactStatus::Open {
                    let wrong = response.tangent + response.normal_force * point.hessian;
                    tally.examined += 1;
                    if max_abs(&(wrong - fd)) > tol {
                        tally.flagged += 1;
                    }
                }
                if target == ContactStatus::Slip {
                    symmetric.examined += 1;
                    if max_abs(&(response.symmetric_tangent() - fd)) > tol {
                        symmetric.flagged += 1;
                    }
                }
            }
            println!(
                "{shape:?} {target:?}: {} states, {} redrawn near a kink, max |K − FD|/tol = {:.3e}; \
                 curvature term detected {}/{}, symmetric variant rejected {}/{}",
                tally.accepted,
                tally.rejected_in_band,
                tally.worst_ratio,
                tally.flagged,
                tally.examined,
                symmetric.flagged,
                symmetric.examined
            );
            tally.assert_power(&format!("{shape:?} {target:?}"));
            if symmetric.examined > 0 {
                assert!(
                    symmetric.flagged * 10 >= symmetric.examined * 9,
                    "{shape:?}: the symmetric variant passes as consistent"
                );
            }
        }
    }
}

/// The frictionless potential (doc Sec. "Normal part"):
/// `Π = ⟨λ_N − ε_N g⟩² / (2 ε_N)`, whose gradient is `r_y = −t_N n`;
/// on a plane in stick the tangential part adds
/// `λ_T·P v + ½ ε_T |P v|²` (`v = y − y_ref`, `P` constant), whose gradient
/// is `t* = P (λ_T + ε_T v)`. Computed from the test's own distance.
fn potential(case: &ImplicitCase, y: &Vector3<f64>, with_stick: bool) -> f64 {
    let point = case.tool.query(y).expect("off the centre");
    let law = &case.law;
    let trial =
        case.state.normal_multiplier - law.normal_penalty() * (point.distance - law.offset());
    let normal = 0.5 * trial.max(0.0).powi(2) / law.normal_penalty();
    if !with_stick {
        return normal;
    }
    let n = point.normal;
    let v = y - case.state.slip_reference;
    let pv = v - n.dot(&v) * n;
    normal
        + case.state.tangential_multiplier.dot(&pv)
        + 0.5 * law.tangential_penalty() * pv.norm_squared()
}

/// Eq. I1, I4: `r_y = ∂Π/∂y` by central differences of the potential, at
/// 1,000 frictionless states (`μ = 0`) open and active on each tool, and at
/// 1,000 stick states on the plane (where stick has the potential above).
///
/// Tolerance: truncation `32 (h/ℓ)² Π_M/ℓ` with `Π_M = (t_N + ε_N ℓ)²/(2ε_N)
/// + (|λ_T| + ε_T(|v| + ℓ))(|v| + ℓ)` (the potential's scale within `ℓ`),
/// round-off `δΠ/h` with `δΠ = 16 ε (Π_M + (t_N + |w|)(|y| + |y_ref| + size))`,
/// plus the residual's own round-off `δr`.
#[test]
fn residual_is_the_gradient_of_the_potential() {
    let mut rng = StdRng::seed_from_u64(0x9077);
    let families: Vec<(Shape, ContactStatus, Option<f64>)> = SHAPES
        .iter()
        .flat_map(|&s| {
            [
                (s, ContactStatus::Open, Some(0.0)),
                (s, ContactStatus::Slip, Some(0.0)),
            ]
        })
        .chain([(Shape::Plane, ContactStatus::Stick, None)])
        .collect();
    for (shape, target, mu) in families {
        let with_stick = target == ContactStatus::Stick;
        // A frictionless active contact reports `Slip`.
        let mut accepted = 0;
        let mut rejected = 0;
        let mut worst = 0.0f64;
        while accepted < 1000 {
            let tool = Tool::random(shape, &mut rng);
            let case = random_case(&mut rng, &tool, target, mu);
            let scales = implicit_scales(&case, 0.0);
            if !scales.band_ok {
                rejected += 1;
                continue;
            }
            let response = evaluate(&case, &case.y);
            assert_eq!(response.status, target, "{shape:?}");
            let law = &case.law;
            let ell = scales.ell;
            let h = scales.h;
            let w = case.state.tangential_multiplier
                + law.tangential_penalty() * (case.y - case.state.slip_reference);
            let v = (case.y - case.state.slip_reference).norm();
            let potential_scale = (response.normal_force + law.normal_penalty() * ell).powi(2)
                / (2.0 * law.normal_penalty())
                + if with_stick {
                    (case.state.tangential_multiplier.norm() + law.tangential_penalty() * (v + ell))
                        * (v + ell)
                } else {
                    0.0
                };
            let potential_round_off = 16.0
                * EPS
                * (potential_scale
                    + (response.normal_force + if with_stick { w.norm() } else { 0.0 })
                        * (case.y.norm() + case.state.slip_reference.norm() + tool.size()));
            let ratio = h / ell;
            let tol = 32.0 * ratio * ratio * potential_scale / ell
                + potential_round_off / h
                + scales.round_off;
            let gradient = central_gradient(&case.y, h, |y| potential(&case, y, with_stick));
            let error = max_abs_vector(&(gradient - response.residual));
            assert!(
                error <= tol,
                "{shape:?} {target:?}: |∂Π/∂y − r| = {error:e} > {tol:e}: {case:?}"
            );
            worst = worst.max(error / tol);
            accepted += 1;
        }
        println!(
            "potential {shape:?} {target:?} μ={mu:?}: {accepted} states, {rejected} redrawn, max error/tol = {worst:.3e}"
        );
    }
}

/// Doc Sec. "Tool translation": the expansion to `(x, q)` with
/// `y = x − q a` equals central differences in all four dofs (the tool's
/// translation `q` included), at 250 random states per status and tool with
/// a random unit axis and `q ∈ [−50, 50]` mm. Same tolerance as the 3×3
/// check, the round-off of `y = x − q a` adding `|x| + |q|` to the
/// position scale.
#[test]
fn tool_translation_expansion_matches_central_differences() {
    let mut rng = StdRng::seed_from_u64(0x4D0F);
    let mut worst = 0.0f64;
    for shape in SHAPES {
        for target in [
            ContactStatus::Open,
            ContactStatus::Stick,
            ContactStatus::Slip,
        ] {
            let mut accepted = 0;
            while accepted < 250 {
                let tool = Tool::random(shape, &mut rng);
                let case = random_case(&mut rng, &tool, target, None);
                let axis = random_unit(&mut rng);
                let q = rng.random_range(-50.0..50.0);
                let x = case.y + q * axis;
                let scales = implicit_scales(&case, x.norm() + q.abs());
                if !scales.band_ok {
                    continue;
                }
                let coupled = |dofs: &Vector4<f64>| {
                    let y = Vector3::new(dofs[0], dofs[1], dofs[2]) - dofs[3] * axis;
                    let r = evaluate(&case, &y);
                    (
                        couple_tool_translation(&axis, &r.residual, &r.tangent),
                        r.status,
                    )
                };
                let centre = Vector4::new(x.x, x.y, x.z, q);
                let (at_centre, status) = coupled(&centre);
                assert_eq!(status, target);
                let h = scales.h;
                let tol = scales.tangent_tolerance();
                for j in 0..4 {
                    let mut plus = centre;
                    let mut minus = centre;
                    plus[j] += h;
                    minus[j] -= h;
                    let (rp, sp) = coupled(&plus);
                    let (rm, sm) = coupled(&minus);
                    assert!(sp == target && sm == target, "stencil crossed a kink");
                    let column = (rp.residual - rm.residual) / (plus[j] - minus[j]);
                    for i in 0..4 {
                        let error = (at_centre.tangent[(i, j)] - column[i]).abs();
                        assert!(
                            error <= tol,
                            "{shape:?} {target:?}: K4[{i},{j}] off by {error:e} > {tol:e}"
                        );
                        worst = worst.max(error / tol);
                    }
                }
                // The tool row is −a·r_y: the reaction on the tool.
                let r_y = Vector3::new(
                    at_centre.residual[0],
                    at_centre.residual[1],
                    at_centre.residual[2],
                );
                assert_eq!(at_centre.residual[3], -axis.dot(&r_y));
                accepted += 1;
            }
        }
    }
    println!("4-dof expansion: max error/tol = {worst:.3e}");
}

// ---------------------------------------------------------------------------
// Implicit kernel: the Coulomb return map
// ---------------------------------------------------------------------------

/// Eq. I3 (doc Sec. "Return map"): in slip `|t_T| = μ t_N` to round-off
/// (`t_T = μ t_N t*/|t*|`, the norm and the division each add ≤ 2 ε, so
/// 4 ε relative) and the friction force on the node `−t_T` opposes the
/// slip: with `λ_T = 0` the trial is `ε_T Δs`, so `t_T/|t_T|` equals
/// `Δs/|Δs|` up to the round-off of the two projections, `16 ε (|v|/|Δs|)`;
/// in stick `t_T` equals the test's own `P (λ_T + ε_T v)` within
/// `16 ε |w|` and stays below the limit. 1,000 states per status and tool.
#[test]
fn return_map_limits_and_directions() {
    let mut rng = StdRng::seed_from_u64(0x5119);
    for shape in SHAPES {
        for target in [ContactStatus::Stick, ContactStatus::Slip] {
            for k in 0..1000 {
                let tool = Tool::random(shape, &mut rng);
                let mut case = random_case(&mut rng, &tool, target, None);
                let zero_multiplier = k % 2 == 0 && target == ContactStatus::Slip;
                if zero_multiplier {
                    // Re-aim the reference so that λ_T = 0 gives the same trial.
                    let point = tool.query(&case.y).expect("off the centre");
                    let n = point.normal;
                    let lt = case.state.tangential_multiplier;
                    let shift = (lt - n.dot(&lt) * n) / case.law.tangential_penalty();
                    case.state.slip_reference -= shift;
                    case.state.tangential_multiplier = Vector3::zeros();
                }
                let response = evaluate(&case, &case.y);
                let limit = case.law.friction() * response.normal_force;
                let force = response.tangential_force;
                match response.status {
                    ContactStatus::Slip => {
                        assert!(
                            (force.norm() - limit).abs() <= 4.0 * EPS * limit,
                            "{shape:?}: |t_T| = {} vs μ t_N = {limit}",
                            force.norm()
                        );
                        if zero_multiplier {
                            let ds = response.slip_increment;
                            let v = (case.y - case.state.slip_reference).norm();
                            let gap = (force / force.norm() - ds / ds.norm()).norm();
                            assert!(
                                gap <= 16.0 * EPS * (1.0 + v / ds.norm()),
                                "direction off by {gap:e}"
                            );
                            assert!(
                                response.force().dot(&ds) < 0.0,
                                "friction does not oppose the slip"
                            );
                        }
                    }
                    ContactStatus::Stick => {
                        let point = tool.query(&case.y).expect("off the centre");
                        let n = point.normal;
                        let w = case.state.tangential_multiplier
                            + case.law.tangential_penalty() * (case.y - case.state.slip_reference);
                        let expected = w - n.dot(&w) * n;
                        assert!((force - expected).norm() <= 16.0 * EPS * w.norm());
                        assert!(force.norm() <= limit);
                    }
                    ContactStatus::Open => panic!("{shape:?}: unexpectedly open"),
                }
                assert_eq!(response.status, target);
            }
        }
    }
}

/// Doc Sec. "Return map": the stick → slip transition sits exactly at
/// `|t*| = μ t_N`. On the plane `z = 0` with `ε_N = ε_T = 4`, `μ = ½`,
/// `λ_N = 2`, `g = 0` and `y − y_ref = (s, 0, 0)`, every number is exact in
/// binary: `t_N = 2`, `μ t_N = 1`, `t* = (4 s, 0, 0)`. At `s = ¼` the
/// trial is exactly at the limit and the state sticks; one ulp above it
/// slips, with the same force (continuity) and the slip tangent; one ulp
/// below it sticks.
#[test]
fn stick_slip_transition_at_the_coulomb_limit() {
    let tool = Tool {
        shape: Shape::Plane,
        centre: Vector3::zeros(),
        radius: 1.0,
        frame: [Vector3::x(), Vector3::y(), Vector3::z()],
    };
    let law = AugmentedLagrangian::new(4.0, 4.0, 0.5, 0.0).unwrap();
    let state = ImplicitContactState::with_multipliers(&Vector3::zeros(), 2.0, &Vector3::zeros());
    let at = |s: f64| {
        let y = Vector3::new(s, 0.0, 0.0);
        law.evaluate(&state, &y, tool.query(&y).as_ref()).unwrap()
    };
    let exact = at(0.25);
    assert_eq!(exact.status, ContactStatus::Stick);
    assert_eq!(exact.tangential_force, Vector3::new(1.0, 0.0, 0.0));
    let above = at(f64::from_bits(0.25f64.to_bits() + 1));
    assert_eq!(above.status, ContactStatus::Slip);
    assert_eq!(above.tangential_force, Vector3::new(1.0, 0.0, 0.0));
    let below = at(f64::from_bits(0.25f64.to_bits() - 1));
    assert_eq!(below.status, ContactStatus::Stick);
    assert!(below.tangential_force.x < 1.0);
    // Stick: K = ε_N e_z⊗e_z + ε_T P; slip: the limit / |t*| ≈ 1 scales the
    // tangential ε_T only across the slip direction, and the normal force
    // couples in through −μ ε_N t̂⊗n.
    let stick = Matrix3::from_diagonal(&Vector3::new(4.0, 4.0, 4.0));
    assert_eq!(exact.tangent, stick);
    let mut slip = Matrix3::from_diagonal(&Vector3::new(0.0, 4.0, 4.0));
    slip[(0, 2)] = -0.5 * 4.0;
    assert!((above.tangent - slip).abs().max() <= 4.0 * 4.0 * EPS);
}

/// Doc Sec. "Degenerate cases": at the kink `λ_N − ε_N g = 0` the closed
/// side is taken (status not open, zero force, the normal stiffness `ε_N
/// n⊗n` present); `t* = 0` sticks with zero friction force and the stick
/// tangent; `μ = 0` is frictionless: status `Slip`, no friction, `K`
/// exactly symmetric and equal to its symmetric variant. Exact binary data
/// on the plane `z = 0`.
#[test]
fn degenerate_cases_follow_the_documented_convention() {
    let tool = Tool {
        shape: Shape::Plane,
        centre: Vector3::zeros(),
        radius: 1.0,
        frame: [Vector3::x(), Vector3::y(), Vector3::z()],
    };
    let y = Vector3::new(0.0, 0.0, 0.5);
    let point = tool.query(&y);
    // λ_N − ε_N g = 2 − 4·0.5 = 0 exactly.
    let law = AugmentedLagrangian::new(4.0, 8.0, 0.3, 0.0).unwrap();
    let state = ImplicitContactState::with_multipliers(&y, 2.0, &Vector3::zeros());
    let kink = law.evaluate(&state, &y, point.as_ref()).unwrap();
    assert_eq!(kink.status, ContactStatus::Stick);
    assert_eq!(kink.normal_force, 0.0);
    assert_eq!(kink.residual, Vector3::zeros());
    assert_eq!(
        kink.tangent,
        Matrix3::from_diagonal(&Vector3::new(8.0, 8.0, 4.0))
    );
    // t* = 0 with a positive normal force: stick, no friction force.
    let pressed = ImplicitContactState::with_multipliers(&y, 6.0, &Vector3::zeros());
    let zero_trial = law.evaluate(&pressed, &y, point.as_ref()).unwrap();
    assert_eq!(zero_trial.status, ContactStatus::Stick);
    assert_eq!(zero_trial.tangential_force, Vector3::zeros());
    assert_eq!(zero_trial.residual, Vector3::new(0.0, 0.0, -4.0));
    // Frictionless on a sphere with a tangential multiplier left over.
    let mut rng = StdRng::seed_from_u64(7);
    for _ in 0..100 {
        let sphere = Tool::random(Shape::SphereOutside, &mut rng);
        let case = random_case(&mut rng, &sphere, ContactStatus::Slip, Some(0.0));
        let mut state = case.state;
        state.tangential_multiplier = random_unit(&mut rng) * 10.0;
        let response = case
            .law
            .evaluate(&state, &case.y, sphere.query(&case.y).as_ref())
            .unwrap();
        assert_eq!(response.status, ContactStatus::Slip);
        assert_eq!(response.tangential_force, Vector3::zeros());
        assert_eq!(response.tangent, response.tangent.transpose());
        assert_eq!(response.symmetric_tangent(), response.tangent);
    }
    // Culled node: open, infinite gap, nothing else.
    let far = law.evaluate(&state, &y, None).unwrap();
    assert_eq!(far.status, ContactStatus::Open);
    assert_eq!(far.gap, f64::INFINITY);
    assert_eq!(far.tangent, Matrix3::zeros());
}

/// Doc Sec. "Errors": non-finite positions, surface answers and states, a
/// negative `λ_N`, a non-unit normal and bad settings are errors naming the
/// input; an overflowing response is `NonFiniteResult`, never NaN.
#[test]
fn bad_inputs_are_errors() {
    let plane = SurfacePoint {
        distance: -0.1,
        normal: Vector3::z(),
        hessian: Matrix3::zeros(),
    };
    let y = Vector3::new(1.0, 2.0, -0.1);
    let law = AugmentedLagrangian::new(100.0, 50.0, 0.3, 0.0).unwrap();
    let state = ImplicitContactState::new(&y);
    let input = |r: Result<ImplicitResponse, ContactError>, name: &str| match r {
        Err(ContactError::InvalidInput { name: n, .. }) => assert_eq!(n, name),
        other => panic!("expected an error on {name}, got {other:?}"),
    };
    input(
        law.evaluate(&state, &Vector3::new(f64::NAN, 0.0, 0.0), Some(&plane)),
        "relative position",
    );
    let mut bad = plane;
    bad.distance = f64::NAN;
    input(law.evaluate(&state, &y, Some(&bad)), "surface distance");
    let mut bad = plane;
    bad.normal.x = f64::INFINITY;
    input(law.evaluate(&state, &y, Some(&bad)), "surface normal");
    let mut bad = plane;
    bad.hessian[(1, 2)] = f64::NAN;
    input(law.evaluate(&state, &y, Some(&bad)), "surface hessian");
    let mut bad = plane;
    bad.normal = Vector3::new(0.0, 0.0, 1.1);
    assert!(matches!(
        law.evaluate(&state, &y, Some(&bad)),
        Err(ContactError::NormalNotUnit { .. })
    ));
    let mut bad_state = state;
    bad_state.normal_multiplier = -1.0;
    input(
        law.evaluate(&bad_state, &y, Some(&plane)),
        "normal multiplier",
    );
    let mut bad_state = state;
    bad_state.tangential_multiplier.y = f64::NAN;
    input(
        law.evaluate(&bad_state, &y, Some(&plane)),
        "tangential multiplier",
    );
    let mut bad_state = state;
    bad_state.slip_reference.z = f64::NEG_INFINITY;
    input(law.evaluate(&bad_state, &y, Some(&plane)), "slip reference");
    for (args, name) in [
        ((0.0, 1.0, 0.1, 0.0), "normal_penalty"),
        ((1.0, -1.0, 0.1, 0.0), "tangential_penalty"),
        ((1.0, 1.0, f64::NAN, 0.0), "friction"),
        ((1.0, 1.0, 0.1, -0.1), "offset"),
    ] {
        match AugmentedLagrangian::new(args.0, args.1, args.2, args.3) {
            Err(ContactError::InvalidSetting { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: {other:?}"),
        }
        match PenaltyContact::new(args.0, args.1, args.2, args.3) {
            Err(ContactError::InvalidSetting { .. }) => {}
            other => panic!("{name}: {other:?}"),
        }
    }
    // Overflow: ε_N g beyond f64.
    let huge = AugmentedLagrangian::new(1e300, 1e300, 0.3, 0.0).unwrap();
    let mut deep = plane;
    deep.distance = -1e300;
    assert!(matches!(
        huge.evaluate(&state, &y, Some(&deep)),
        Err(ContactError::NonFiniteResult { .. })
    ));
    // Explicit kernel: the same checks, and the state is left unchanged.
    let penalty = PenaltyContact::new(100.0, 50.0, 0.3, 0.0).unwrap();
    let mut explicit_state = PenaltyState::new(&y);
    penalty
        .update(&mut explicit_state, &y, Some(&plane))
        .unwrap();
    let before = explicit_state;
    let mut bad = plane;
    bad.hessian[(0, 0)] = f64::NAN;
    assert!(
        penalty
            .update(&mut explicit_state, &(y * 1.01), Some(&bad))
            .is_err()
    );
    assert!(
        penalty
            .update(
                &mut explicit_state,
                &Vector3::new(0.0, f64::NAN, 0.0),
                Some(&plane)
            )
            .is_err()
    );
    let huge = PenaltyContact::new(1e300, 1e300, 0.3, 0.0).unwrap();
    assert!(matches!(
        huge.update(&mut explicit_state, &y, Some(&deep)),
        Err(ContactError::NonFiniteResult { .. })
    ));
    assert_eq!(explicit_state, before);
    for (m, dt, c) in [
        (0.0, 1e-6, 0.5),
        (1.0, f64::NAN, 0.5),
        (1.0, 1e-6, 1.5),
        (1.0, 1e-6, 0.0),
    ] {
        assert!(matches!(
            stable_penalty_stiffness(m, dt, c),
            Err(ContactError::InvalidSetting { .. })
        ));
    }
    assert!(penalty.frequency_squared(0.0, 0.0, 0.0, 0.0).is_err());
    assert!(penalty.frequency_squared(1.0, -1.0, 0.0, 0.0).is_err());
}

// ---------------------------------------------------------------------------
// Implicit kernel: the smoothed kinks (Eq. S1–S3)
// ---------------------------------------------------------------------------

/// Which rounded band a smoothed state is drawn in.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Band {
    /// Inside the normal law's band `|λ_N − ε_N g| < ε_N δ_g`.
    Normal,
    /// Inside the friction law's band `||t*| − μ t_N| < δ_r μ t_N` (and
    /// the normal band, half of the time).
    Friction,
}

/// A random active state of `random_case` with its kinks rounded so that
/// it lies in `band`: the gap width `δ_g` is `1.2..5` times `|x|/ε_N`
/// (`x = λ_N − ε_N g`; half of the states have `λ_N` lowered by `2x`, so
/// that `x < 0`: the side the non-smooth law leaves open); the friction
/// width `δ_r` is `1.2..3` times `|r − 1|` (`r = |t*|/(μ t_N)`, drawn
/// again when that is not below 1). `None` when the draw cannot be put in
/// the band.
fn smoothed_case(rng: &mut StdRng, tool: &Tool, band: Band) -> Option<ImplicitCase> {
    let target = if rng.random_bool(0.5) {
        ContactStatus::Stick
    } else {
        ContactStatus::Slip
    };
    let mu = if band == Band::Normal && rng.random_bool(0.3) {
        Some(0.0)
    } else {
        None
    };
    let mut case = random_case(rng, tool, target, mu);
    let law = case.law;
    let point = tool.query(&case.y)?;
    let mut x =
        case.state.normal_multiplier - law.normal_penalty() * (point.distance - law.offset());
    if rng.random_bool(0.5) && case.state.normal_multiplier >= 2.0 * x {
        case.state.normal_multiplier -= 2.0 * x;
        x = -x;
    }
    let normal_width = if band == Band::Normal || rng.random_bool(0.5) {
        x.abs() * rng.random_range(1.2..5.0)
    } else {
        0.0
    };
    let gap_width = normal_width / law.normal_penalty();
    let friction_width = if band == Band::Friction {
        let (t_n, _) = rounded(x, normal_width);
        let w = case.state.tangential_multiplier
            + law.tangential_penalty() * (case.y - case.state.slip_reference);
        let trial = w - point.normal.dot(&w) * point.normal;
        let r = trial.norm() / (law.friction() * t_n);
        let width = (r - 1.0).abs() * rng.random_range(1.2..3.0);
        if !(width > 0.0 && width < 1.0) {
            return None;
        }
        width
    } else {
        0.0
    };
    case.law = law
        .with_smoothing(Smoothing {
            gap_width,
            friction_width,
        })
        .expect("valid widths");
    Some(case)
}

/// The test's own rounded bracket (Eq. S1): value and slope.
fn rounded(x: f64, w: f64) -> (f64, f64) {
    if x >= w {
        (x, 1.0)
    } else if x <= -w {
        (0.0, 0.0)
    } else {
        ((x + w).powi(2) / (4.0 * w), (x + w) / (2.0 * w))
    }
}

/// `FdScales` of a smoothed state: as `implicit_scales`, with `t_N` the
/// rounded force, `ℓ` also at most `t_N/(ε_N s′)` (the scale over which the
/// friction limit `μ t_N` changes) when friction acts and at most the width
/// of the band the state is in (over which the slope runs through its
/// range, so the rounded law's second derivative is `1/width` times the
/// straight one's slope), and the kinks
/// replaced by the band edges, where the second derivative jumps: the
/// normal edges `x = ±ε_N δ_g` at `|x ∓ ε_N δ_g|/ε_N`, the friction edges
/// `|t*| = (1 ± δ_r) μ t_N` at `||t*| − (1 ± δ_r) μ t_N| / (ε_T + 2|w|κ +
/// (1 + δ_r) μ ε_N s′)`. The status may change inside a band (it is stick
/// for `|t*| ≤ μ t_N`), where the law is smooth, so only the edges count.
fn smoothed_scales(case: &ImplicitCase) -> FdScales {
    let law = &case.law;
    let state = &case.state;
    let smoothing = law.smoothing();
    let point = case.tool.query(&case.y).expect("off the centre");
    let n = point.normal;
    let x = state.normal_multiplier - law.normal_penalty() * (point.distance - law.offset());
    let normal_width = law.normal_penalty() * smoothing.gap_width;
    let (t_n, slope) = rounded(x, normal_width);
    let w =
        state.tangential_multiplier + law.tangential_penalty() * (case.y - state.slip_reference);
    let trial = w - n.dot(&w) * n;
    let rho = case.tool.radius_at(&case.y);
    let kappa = 1.0 / rho;
    let friction = law.friction();
    let band = smoothing.friction_width;
    let limit = friction * t_n;
    let sliding = friction > 0.0 && trial.norm() > (1.0 - band) * limit;
    let slip_scale = if sliding {
        trial.norm() / (law.tangential_penalty() + 2.0 * w.norm() * kappa)
    } else {
        f64::INFINITY
    };
    let limit_scale = if friction > 0.0 && slope > 0.0 {
        t_n / (law.normal_penalty() * slope)
    } else {
        f64::INFINITY
    };
    // Inside a band the slope changes by its whole range over the band's
    // width: `δ_g` for the normal law, `2 δ_r μ t_N / G` for the friction
    // law (`G` the gradient bound of the friction edges below).
    let friction_gradient = law.tangential_penalty()
        + 2.0 * w.norm() * kappa
        + (1.0 + band) * friction * law.normal_penalty() * slope;
    let normal_band_scale = if x.abs() < normal_width {
        smoothing.gap_width
    } else {
        f64::INFINITY
    };
    let friction_band_scale = if friction > 0.0 && (trial.norm() - limit).abs() < band * limit {
        2.0 * band * limit / friction_gradient
    } else {
        f64::INFINITY
    };
    let ell = rho
        .min(slip_scale)
        .min(limit_scale)
        .min(normal_band_scale)
        .min(friction_band_scale)
        .min(10.0);
    let penalties = law.normal_penalty() + law.tangential_penalty();
    let lambda_t = state.tangential_multiplier.norm();
    let force_scale = t_n + state.normal_multiplier + w.norm() + lambda_t + penalties * ell;
    let round_off = 16.0
        * EPS
        * (penalties * (case.y.norm() + state.slip_reference.norm() + case.tool.size())
            + state.normal_multiplier
            + t_n
            + lambda_t
            + 2.0 * w.norm());
    let normal_edge =
        ((x - normal_width).abs().min((x + normal_width).abs())) / law.normal_penalty();
    let friction_edge = if friction > 0.0 {
        let m = trial.norm();
        ((m - (1.0 - band) * limit).abs()).min((m - (1.0 + band) * limit).abs()) / friction_gradient
    } else {
        f64::INFINITY
    };
    FdScales::new(ell, force_scale, round_off, normal_edge.min(friction_edge))
}

/// Eq. S1–S2 with the tangent of Eq. I5–I7 carried through the rounding
/// (`docs/contact-kernels.md`, "Smoothed kinks"): `K` equals the central
/// differences of `r_y` at 500 states inside the normal band and 500
/// inside the friction band on each tool (`smoothed_case`), with the
/// tolerance of `tangent_matches_central_differences_in_every_status`
/// (`smoothed_scales`). In the friction band the friction force is below
/// both `|t*|` and `μ t_N` (`f(r) ≤ min(r, 1)`).
///
/// Power (asserted): the non-smooth normal stiffness `ε_N n⊗n` in place of
/// `ε_N s′ n⊗n` fails the same check at ≥ 90 % of the normal-band states
/// with `s′ < 0.9`; the slip tangent of Eq. I7 in place of the friction
/// band's fails it at ≥ 90 % of the friction-band states.
#[test]
fn smoothed_tangent_matches_central_differences() {
    let mut rng = StdRng::seed_from_u64(0x5_0007);
    for shape in SHAPES {
        for band in [Band::Normal, Band::Friction] {
            let mut tally = Tally::default();
            while tally.accepted < 500 {
                let tool = Tool::random(shape, &mut rng);
                let Some(case) = smoothed_case(&mut rng, &tool, band) else {
                    continue;
                };
                let scales = smoothed_scales(&case);
                if !scales.band_ok {
                    tally.rejected_in_band += 1;
                    continue;
                }
                let response = evaluate(&case, &case.y);
                assert_ne!(response.status, ContactStatus::Open, "{case:?}");
                // The status may change inside a band, where the law is
                // smooth: only the differences are used.
                let (jacobian, _) = fd_tangent(&case, scales.h, response.status);
                let tol = scales.tangent_tolerance();
                tally.accept(
                    &format!("{shape:?} {band:?}"),
                    &response.tangent,
                    &jacobian,
                    tol,
                    &case,
                );
                let law = &case.law;
                let point = tool.query(&case.y).expect("off the centre");
                let x = case.state.normal_multiplier
                    - law.normal_penalty() * (point.distance - law.offset());
                let (t_n, slope) = rounded(x, law.normal_penalty() * law.smoothing().gap_width);
                if band == Band::Friction {
                    let n = point.normal;
                    let hessian = point.hessian;
                    let w = case.state.tangential_multiplier
                        + law.tangential_penalty() * (case.y - case.state.slip_reference);
                    let trial_vector = w - n.dot(&w) * n;
                    let trial = trial_vector.norm();
                    let friction_force = response.tangential_force.norm();
                    let limit = law.friction() * t_n;
                    let bound = trial.min(limit);
                    assert!(
                        friction_force <= bound * (1.0 + 4.0 * EPS),
                        "{shape:?}: |t_T| = {friction_force} above min(|t*|, μ t_N) = {bound}"
                    );
                    // Eq. I7's slip tangent at the same state, in place of
                    // the band's.
                    let projector = Matrix3::identity() - n * n.transpose();
                    let a = law.tangential_penalty() * projector
                        - n.dot(&w) * hessian
                        - n * (hessian * w).transpose();
                    let direction = trial_vector / trial;
                    let slip = law.normal_penalty() * slope * n * n.transpose()
                        - t_n * hessian
                        - (law.friction() * law.normal_penalty() * slope)
                            * direction
                            * n.transpose()
                        + (limit / trial)
                            * (Matrix3::identity() - direction * direction.transpose())
                            * a;
                    tally.examined += 1;
                    if max_abs(&(slip - jacobian)) > tol {
                        tally.flagged += 1;
                    }
                }
                if band == Band::Normal && slope < 0.9 {
                    let n = point.normal;
                    let wrong =
                        response.tangent + law.normal_penalty() * (1.0 - slope) * n * n.transpose();
                    tally.examined += 1;
                    if max_abs(&(wrong - jacobian)) > tol {
                        tally.flagged += 1;
                    }
                }
            }
            println!(
                "smoothed {shape:?} {band:?}: {} states, {} redrawn near a band edge, max |K − FD|/tol = {:.3e}; \
                 wrong tangent rejected {}/{}",
                tally.accepted,
                tally.rejected_in_band,
                tally.worst_ratio,
                tally.flagged,
                tally.examined
            );
            tally.assert_power(&format!("{shape:?} {band:?}"));
        }
    }
}

/// Eq. S3: the kernel's `normal_potential` is the potential of the rounded
/// normal law: its central differences equal `r_y = −t_N n` at 500
/// frictionless states in the normal band on each tool. Tolerance as in
/// `residual_is_the_gradient_of_the_potential`, with `Π_M = (t_N + ε_N
/// ℓ)²/(2 ε_N) + ε_N δ_g²/6` (Eq. S3's constant).
#[test]
fn smoothed_residual_is_the_gradient_of_its_potential() {
    let mut rng = StdRng::seed_from_u64(0x5_9077);
    for shape in SHAPES {
        let mut accepted = 0;
        let mut worst = 0.0f64;
        while accepted < 500 {
            let tool = Tool::random(shape, &mut rng);
            let Some(mut case) = smoothed_case(&mut rng, &tool, Band::Normal) else {
                continue;
            };
            let law = case.law;
            case.law = AugmentedLagrangian::new(
                law.normal_penalty(),
                law.tangential_penalty(),
                0.0,
                law.offset(),
            )
            .and_then(|l| l.with_smoothing(law.smoothing()))
            .expect("valid");
            let scales = smoothed_scales(&case);
            if !scales.band_ok {
                continue;
            }
            let response = evaluate(&case, &case.y);
            let (ell, h) = (scales.ell, scales.h);
            let eps_n = law.normal_penalty();
            let width = law.smoothing().gap_width;
            let potential_scale = (response.normal_force + eps_n * ell).powi(2) / (2.0 * eps_n)
                + eps_n * width * width / 6.0;
            let potential_round_off = 16.0
                * EPS
                * (potential_scale + response.normal_force * (case.y.norm() + tool.size()));
            let ratio = h / ell;
            let tol = 32.0 * ratio * ratio * potential_scale / ell
                + potential_round_off / h
                + scales.round_off;
            let gradient = central_gradient(&case.y, h, |y| evaluate(&case, y).normal_potential);
            let error = max_abs_vector(&(gradient - response.residual));
            assert!(
                error <= tol,
                "{shape:?}: |∂Π/∂y − r| = {error:e} > {tol:e}: {case:?}"
            );
            worst = worst.max(error / tol);
            accepted += 1;
        }
        println!("smoothed potential {shape:?}: {accepted} states, max error/tol = {worst:.3e}");
    }
}

/// Eq. S1 at its edges and without width: the rounded force and its slope
/// are continuous at `x = ±ε_N δ_g` (within `4 ε` of the force scale over a
/// step of `10⁻⁹` of the width, the slope within `10⁻⁸`); zero widths give
/// the non-smooth kernel's response bit for bit at 1,000 random states.
#[test]
fn smoothed_law_is_continuous_and_reduces_to_the_plain_one() {
    let mut rng = StdRng::seed_from_u64(0x5_C0);
    for (eps_n, gap_width) in [(1200.0, 0.02), (100.0, 0.5), (1e4, 1e-4)] {
        let law = AugmentedLagrangian::new(eps_n, eps_n, 0.0, 0.0)
            .and_then(|l| {
                l.with_smoothing(Smoothing {
                    gap_width,
                    friction_width: 0.0,
                })
            })
            .unwrap();
        let plane = Tool {
            shape: Shape::Plane,
            centre: Vector3::zeros(),
            radius: 1.0,
            frame: frame_from(Vector3::z()),
        };
        let width = eps_n * gap_width;
        let force_at = |x: f64| {
            // x = λ_N − ε_N g with λ_N = 0: g = −x/ε_N.
            let y = Vector3::new(0.3, -0.2, -x / eps_n);
            let state = ImplicitContactState::new(&y);
            let r = law.evaluate(&state, &y, plane.query(&y).as_ref()).unwrap();
            (r.normal_force, r.tangent[(2, 2)] / eps_n)
        };
        for edge in [-width, width] {
            let delta = 1e-9 * width;
            let (below, slope_below) = force_at(edge - delta);
            let (above, slope_above) = force_at(edge + delta);
            assert!(
                (above - below).abs() <= 4.0 * delta + 4.0 * EPS * width,
                "force jumps at {edge}: {below} → {above}"
            );
            assert!(
                (slope_above - slope_below).abs() <= 1e-8,
                "slope jumps at {edge}: {slope_below} → {slope_above}"
            );
        }
        assert_eq!(force_at(-1.0001 * width).0, 0.0);
        assert!(force_at(-0.9999 * width).0 > 0.0);
    }
    for shape in SHAPES {
        for target in [
            ContactStatus::Open,
            ContactStatus::Stick,
            ContactStatus::Slip,
        ] {
            for _ in 0..250 / 3 + 1 {
                let tool = Tool::random(shape, &mut rng);
                let case = random_case(&mut rng, &tool, target, None);
                let zero = case.law.with_smoothing(Smoothing::default()).unwrap();
                let point = tool.query(&case.y);
                let plain = case
                    .law
                    .evaluate(&case.state, &case.y, point.as_ref())
                    .unwrap();
                let smoothed = zero.evaluate(&case.state, &case.y, point.as_ref()).unwrap();
                assert_eq!(plain, smoothed);
                let expected =
                    0.5 * plain.normal_force * plain.normal_force / case.law.normal_penalty();
                assert_eq!(plain.normal_potential, expected);
            }
        }
    }
}

/// Eq. S1 under the Uzawa iteration (doc Sec. "Smoothed kinks"): the node
/// of `uzawa_converges_at_the_predicted_rate` pressed by `F` through a
/// spring `k` that is unloaded on the plane converges to the fixed point
/// of the rounded law, `t_N = λ_N = F + k g` with `s(λ_N − ε_N g) = λ_N`:
/// a gap `g ∈ [0, δ_g]`, zero when `F ≥ ε_N δ_g` (the straight branch),
/// positive below, where the node hovers on the rounded force. The gap is
/// compared with the root of that equation found by bisection here; loads
/// from deep inside the band to beyond it. Tolerances: `1e4` floors of
/// `uzawa_converges_at_the_predicted_rate` on the force, that over
/// `k + ε_N s′` on the gap.
#[test]
fn smoothed_uzawa_converges_to_a_gap_within_the_width() {
    let (k, k_t) = (100.0, 50.0);
    let (eps_n, eps_t, mu) = (300.0, 50.0, 0.4);
    let gap_width = 0.05;
    let width = eps_n * gap_width;
    for force in [0.1, 3.0, 40.0] {
        let law = AugmentedLagrangian::new(eps_n, eps_t, mu, 0.0)
            .and_then(|l| {
                l.with_smoothing(Smoothing {
                    gap_width,
                    friction_width: 0.2,
                })
            })
            .unwrap();
        let problem = one_node(0x5_02A7A, k, k_t, &law, force, 0.3 * mu * force);
        let mut state = ImplicitContactState::new(&problem.start);
        let mut y = problem.start;
        let mut response = None;
        for _ in 0..60 {
            let (solved, r) = problem.solve(&law, &state, y);
            y = solved;
            state.augment(&r);
            response = Some(r);
        }
        let response = response.unwrap();
        // φ(g) = s(F + k g − ε_N g) − (F + k g): φ(0) ≥ 0 (s(x) ≥ x), and
        // φ(δ_g) < 0 unless F ≥ ε_N δ_g, where g = 0 is the root.
        let phi = |g: f64| rounded(force + k * g - eps_n * g, width).0 - (force + k * g);
        let expected_gap = if force >= width {
            0.0
        } else {
            let (mut low, mut high) = (0.0, gap_width);
            assert!(phi(low) >= 0.0 && phi(high) < 0.0);
            for _ in 0..200 {
                let mid = 0.5 * (low + high);
                if phi(mid) >= 0.0 {
                    low = mid
                } else {
                    high = mid
                }
            }
            0.5 * (low + high)
        };
        let (_, slope) = rounded(force + k * expected_gap - eps_n * expected_gap, width);
        let gap_round_off = 16.0 * EPS * (problem.start.norm() + problem.tool.size());
        println!(
            "smoothed Uzawa, F = {force} N: t_N = {}, gap {:e} (expected {expected_gap:e}, width {gap_width})",
            response.normal_force, response.gap
        );
        assert!(
            (response.normal_force - (force + k * response.gap)).abs() <= 1e4 * problem.floor,
            "equilibrium: t_N = {} against F + k g = {}",
            response.normal_force,
            force + k * response.gap
        );
        assert!((state.normal_multiplier - response.normal_force).abs() <= 1e4 * problem.floor);
        assert!(
            (response.gap - expected_gap).abs()
                <= 1e4 * problem.floor / (k + eps_n * slope) + gap_round_off,
            "gap {} vs {expected_gap}",
            response.gap
        );
        assert!(response.gap >= -gap_round_off && response.gap <= gap_width);
    }
}

// ---------------------------------------------------------------------------
// Implicit kernel: the Uzawa iteration
// ---------------------------------------------------------------------------

/// Solves `K_s y − f + r_y(y) = 0` by Newton's method with the kernel's
/// consistent tangent, from `y`, until `|r| ≤ tolerance`.
fn newton(
    law: &AugmentedLagrangian,
    state: &ImplicitContactState,
    tool: &Tool,
    spring: &Matrix3<f64>,
    external: &Vector3<f64>,
    mut y: Vector3<f64>,
    tolerance: f64,
) -> (Vector3<f64>, ImplicitResponse) {
    for _ in 0..50 {
        let response = law.evaluate(state, &y, tool.query(&y).as_ref()).unwrap();
        let residual = spring * y - external + response.residual;
        if residual.norm() <= tolerance {
            return (y, response);
        }
        let step = (spring + response.tangent)
            .lu()
            .solve(&residual)
            .expect("regular system");
        y -= step;
    }
    panic!("Newton did not converge");
}

/// The one-node problem of the Uzawa tests: a node on a random plane,
/// held by a spring `K_s = k n⊗n + k_t P` anchored so that it is unloaded
/// at `start` (on the plane, offset 0), loaded by `−F n + F_T t1`.
struct OneNode {
    tool: Tool,
    t1: Vector3<f64>,
    spring: Matrix3<f64>,
    external: Vector3<f64>,
    start: Vector3<f64>,
    /// Newton's stopping residual: the round-off floor of
    /// `K_s y − f + r_y` is `(k + k_t + ε_N + ε_T)(|y| + size) ε` plus
    /// `ε F`; 64 × that.
    newton_tolerance: f64,
    /// The resulting error of a multiplier: Newton's residual over the
    /// spring `k`, times `k + ε_N` (the stiffness the residual divides
    /// into), i.e. `tolerance (1 + ε_N/k)`.
    floor: f64,
}

impl OneNode {
    /// Newton's solution of the node's equilibrium from `y` (`newton` with
    /// the problem's spring, load and tolerance).
    fn solve(
        &self,
        law: &AugmentedLagrangian,
        state: &ImplicitContactState,
        y: Vector3<f64>,
    ) -> (Vector3<f64>, ImplicitResponse) {
        newton(
            law,
            state,
            &self.tool,
            &self.spring,
            &self.external,
            y,
            self.newton_tolerance,
        )
    }
}

fn one_node(
    seed: u64,
    k: f64,
    k_t: f64,
    law: &AugmentedLagrangian,
    force: f64,
    pull: f64,
) -> OneNode {
    let mut rng = StdRng::seed_from_u64(seed);
    let tool = Tool::random(Shape::Plane, &mut rng);
    let [t1, _, n] = tool.frame;
    let spring = k * n * n.transpose() + k_t * (Matrix3::identity() - n * n.transpose());
    let start = tool.at([3.0, -2.0], 0.0);
    let external = -force * n + pull * t1 + spring * start;
    let stiffness = k + k_t + law.normal_penalty() + law.tangential_penalty();
    let newton_tolerance = 64.0 * EPS * (force + pull + stiffness * (start.norm() + tool.size()));
    OneNode {
        tool,
        t1,
        spring,
        external,
        start,
        newton_tolerance,
        floor: newton_tolerance * (1.0 + law.normal_penalty() / k),
    }
}

/// Doc Sec. "Uzawa rate": a node pressed onto a plane by `F` through a
/// linear spring `k` (normal) and pulled along it by `F_T < μ F` through a
/// spring `k_t`. With every Newton solve exact, the normal equation
/// `k g + F − (λ − ε_N g) = 0` gives `g = (λ − F)/(k + ε_N)` and
/// `t_N = (k λ + ε_N F)/(k + ε_N)`: the multiplier error `e = λ − F`
/// contracts by exactly `k/(k + ε_N)` per augmentation (a stiff penalty
/// converges fast); in stick the tangential equation gives the same with
/// `k_t/(k_t + ε_T)`. Asserted per augmentation while the error is above
/// `1e4` times the round-off floor `δλ` (`OneNode::floor`), the ratio
/// within `2 (1 + ρ) δλ/|e|` (each error off by `δλ`), the gap within
/// `δλ/(k + ε_N)` plus the round-off of `d`.
#[test]
fn uzawa_converges_at_the_predicted_rate() {
    let (k, k_t) = (100.0, 50.0);
    let (eps_n, eps_t, mu) = (300.0, 50.0, 0.4);
    let (force, pull) = (10.0, 0.3 * 0.4 * 10.0);
    let law = AugmentedLagrangian::new(eps_n, eps_t, mu, 0.0).unwrap();
    let problem = one_node(0x02A7A, k, k_t, &law, force, pull);
    let mut state = ImplicitContactState::new(&problem.start);
    let rate_n = k / (k + eps_n);
    let rate_t = k_t / (k_t + eps_t);
    let floor = problem.floor;
    let gap_round_off = 16.0 * EPS * (problem.start.norm() + problem.tool.size());
    let (mut error_n, mut error_t) = (-force, -pull);
    let mut y = problem.start;
    let mut norms = AugmentationNorms::default();
    let mut checked = 0;
    for augmentation in 0..40 {
        let (solved, response) = problem.solve(&law, &state, y);
        y = solved;
        assert_eq!(
            response.status,
            ContactStatus::Stick,
            "augmentation {augmentation}"
        );
        let predicted_gap = error_n / (k + eps_n);
        assert!(
            (response.gap - predicted_gap).abs() <= floor / (k + eps_n) + gap_round_off,
            "gap {} vs {predicted_gap}",
            response.gap
        );
        norms = AugmentationNorms::default();
        norms.add(&state.augment(&response));
        let new_error_n = state.normal_multiplier - force;
        let new_error_t = state.tangential_multiplier.dot(&problem.t1) - pull;
        if error_n.abs() > 1e4 * floor {
            let ratio = new_error_n / error_n;
            let tol = 2.0 * (1.0 + rate_n) * floor / error_n.abs();
            assert!(
                (ratio - rate_n).abs() <= tol,
                "normal rate {ratio} vs {rate_n}"
            );
            checked += 1;
        }
        if error_t.abs() > 1e4 * floor {
            let ratio = new_error_t / error_t;
            let tol = 2.0 * (1.0 + rate_t) * floor / error_t.abs();
            assert!(
                (ratio - rate_t).abs() <= tol,
                "tangential rate {ratio} vs {rate_t}"
            );
            checked += 1;
        }
        error_n = new_error_n;
        error_t = new_error_t;
    }
    println!("Uzawa: {checked} rates checked, floor δλ = {floor:e} N");
    assert!(checked >= 10);
    // After 40 augmentations both errors are at the floor (ρ^40 < 1e-12).
    assert!((state.normal_multiplier - force).abs() <= 1e4 * floor);
    assert!((state.tangential_multiplier - pull * problem.t1).norm() <= 1e4 * floor);
    assert!(norms.max_penetration <= 1e4 * floor / (k + eps_n) + gap_round_off);
    assert!(norms.relative_change() <= 1e4 * floor / force);
    // Commit keeps the converged multipliers and moves the reference;
    // restore after a later (failed) change goes back to them.
    state.commit(&y);
    assert_eq!(state.slip_reference, y);
    let kept = (state.normal_multiplier, state.tangential_multiplier);
    state.normal_multiplier = 123.0;
    state.tangential_multiplier = Vector3::new(1.0, 2.0, 3.0);
    state.restore();
    assert_eq!((state.normal_multiplier, state.tangential_multiplier), kept);
    assert_eq!(state.committed_multipliers(), kept);
}

/// Doc Sec. "Uzawa rate", sliding: pulled by `F_T = 2 μ F`, the node slides
/// until its spring holds `F_T − μ F`: the augmented solution converges to
/// `t_N = F`, `t_T = μ F` along the pull, and the tangential displacement
/// `(F_T − μ F)/k_t`; after 40 augmentations (normal error contracted by
/// `(k/(k + ε_N))^40 < 1e-24`) each within `1e4` floors. In every slip
/// solve `|t_T| = μ t_N` to `4 ε`.
#[test]
fn uzawa_converges_in_slip() {
    let (k, k_t) = (100.0, 50.0);
    let (eps_n, eps_t, mu) = (300.0, 200.0, 0.4);
    let (force, pull) = (10.0, 2.0 * 0.4 * 10.0);
    let law = AugmentedLagrangian::new(eps_n, eps_t, mu, 0.0).unwrap();
    let problem = one_node(0x5_11D, k, k_t, &law, force, pull);
    let mut state = ImplicitContactState::new(&problem.start);
    let floor = problem.floor;
    let mut y = problem.start;
    for _ in 0..40 {
        let (solved, response) = problem.solve(&law, &state, y);
        y = solved;
        assert_eq!(response.status, ContactStatus::Slip);
        assert!(
            (response.tangential_force.norm() - mu * response.normal_force).abs()
                <= 4.0 * EPS * mu * response.normal_force
        );
        state.augment(&response);
    }
    assert!((state.normal_multiplier - force).abs() <= 1e4 * floor);
    assert!((state.tangential_multiplier - mu * force * problem.t1).norm() <= 1e4 * floor);
    let slid = (y - problem.start).dot(&problem.t1);
    let expected = (pull - mu * force) / k_t;
    let round_off = 16.0 * EPS * (problem.start.norm() + problem.tool.size());
    assert!(
        (slid - expected).abs() <= 1e4 * floor / k_t + round_off,
        "slid {slid} vs {expected}"
    );
}

// ---------------------------------------------------------------------------
// Explicit kernel
// ---------------------------------------------------------------------------

/// A path through waypoints `(u, d)` on a tool, `steps` straight steps of
/// the parameters per leg, mapped through `Tool::at`.
fn path_on(tool: &Tool, waypoints: &[([f64; 2], f64)], steps: usize) -> Vec<Vector3<f64>> {
    let mut path = vec![tool.at(waypoints[0].0, waypoints[0].1)];
    for leg in waypoints.windows(2) {
        let ((u0, d0), (u1, d1)) = (leg[0], leg[1]);
        for i in 1..=steps {
            let s = i as f64 / steps as f64;
            let u = [u0[0] + s * (u1[0] - u0[0]), u0[1] + s * (u1[1] - u0[1])];
            path.push(tool.at(u, d0 + s * (d1 - d0)));
        }
    }
    path
}

/// The energy bookkeeping of one prescribed path.
#[derive(Debug, Default)]
struct Cycle {
    /// `W = Σ ½ (r_n + r_{n+1})·Δy` [N·mm]: the work the node does against
    /// the contact force, by the solver's trapezoidal rule.
    work: f64,
    stored_start: f64,
    stored_end: f64,
    dissipated: f64,
    /// Bound of the quadrature defect at steps whose chord may cross
    /// `g = 0`: `k_N |Δy|²/8` (a kinked quadratic, trapezoidal rule).
    crossing_bound: f64,
    /// Bound of the trapezoidal defect of the smooth normal energy:
    /// `k_N (3κ + 3 p κ²) |Δy|³ / 12`.
    smooth_bound: f64,
    /// Bound of the tangential defect `½ (n·t_n)(n·Δy)`:
    /// `½ κ |Δy| |t_n| |n·Δy|`.
    tangential_bound: f64,
    /// Round-off: `32 ε Σ [(|r_n| + |r_{n+1}|)(|y_n| + |y_{n+1}| + size +
    /// offset) + E_n + E_{n+1} + |D_n|]`.
    round_off: f64,
    statuses: Vec<ContactStatus>,
    responses: Vec<PenaltyResponse>,
    final_state: Option<PenaltyState>,
}

impl Cycle {
    fn defect(&self) -> f64 {
        self.work - (self.stored_end - self.stored_start + self.dissipated)
    }
}

/// Runs the explicit kernel along `path` and checks at every call that the
/// friction force stays within `μ f_N` (4 ε relative: the norm and the
/// direction's division), that it equals `μ f_N` in slip, and that it
/// opposes the plastic slip (`t·Δs_p ≥ 0`).
fn run_cycle(law: &PenaltyContact, tool: &Tool, path: &[Vector3<f64>]) -> Cycle {
    let mut state = PenaltyState::new(&path[0]);
    let first = law
        .update(&mut state, &path[0], tool.query(&path[0]).as_ref())
        .unwrap();
    let mut cycle = Cycle {
        stored_start: state.stored_energy(),
        ..Cycle::default()
    };
    let mut previous = first;
    let offset = law.offset();
    for pair in path.windows(2) {
        let (y0, y1) = (pair[0], pair[1]);
        let point = tool.query(&y1);
        let response = law.update(&mut state, &y1, point.as_ref()).unwrap();
        let dy = y1 - y0;
        cycle.work += 0.5 * (previous.residual + response.residual).dot(&dy);
        let length = dy.norm();
        // Curvature bound along the chord: 1/(min radius − |Δy|).
        let kappa = 1.0 / (tool.radius_at(&y0).min(tool.radius_at(&y1)) - length);
        let sagitta = kappa * length * length / 8.0;
        let (g0, g1) = (previous.gap, response.gap);
        let clear_open = g0 > sagitta && g1 > sagitta;
        let clear_closed = g0 < -sagitta && g1 < -sagitta;
        if !clear_open && !clear_closed {
            cycle.crossing_bound += law.normal_stiffness() * length * length / 8.0;
        }
        let penetration = (-g0).max(-g1).max(0.0) + length;
        cycle.smooth_bound += law.normal_stiffness()
            * (3.0 * kappa + 3.0 * penetration * kappa * kappa)
            * length.powi(3)
            / 12.0;
        let n1 = response.normal;
        cycle.tangential_bound +=
            0.5 * kappa * length * previous.tangential_force.norm() * n1.dot(&dy).abs();
        cycle.round_off += 32.0
            * EPS
            * ((previous.residual.norm() + response.residual.norm())
                * (y0.norm() + y1.norm() + tool.size() + offset)
                + previous.stored_energy()
                + response.stored_energy()
                + response.dissipated.abs());
        cycle.dissipated += response.dissipated;
        let limit = law.friction() * response.normal_force;
        let friction = response.tangential_force.norm();
        assert!(
            friction <= limit * (1.0 + 4.0 * EPS),
            "|t| = {friction} > μ f_N = {limit}"
        );
        if response.status == ContactStatus::Slip {
            assert!((friction - limit).abs() <= 4.0 * EPS * limit);
            assert!(response.tangential_force.dot(&response.plastic_slip) >= 0.0);
        }
        cycle.statuses.push(response.status);
        cycle.responses.push(response);
        previous = response;
    }
    cycle.stored_end = state.stored_energy();
    // The state sums the same per-call values in the same order.
    assert_eq!(state.dissipated, cycle.dissipated);
    cycle.final_state = Some(state);
    cycle
}

fn count(cycle: &Cycle, status: ContactStatus) -> usize {
    cycle.statuses.iter().filter(|&&s| s == status).count()
}

/// Eq. E5–E7 (doc Sec. "Energy bookkeeping"), on a plane with every
/// opening and closing landing exactly on a sample (binary-exact path on
/// `z = offset`): press, slide, slide while pressing deeper, reverse while
/// releasing, a small stick excursion and back, lift off, move away. The
/// trapezoidal work equals stored + dissipated to round-off (the plane has
/// no quadrature defect: the normal energy is quadratic in `y`, the spring
/// update linear), the spring is released at lift-off, and each status
/// occurs.
#[test]
fn plane_cycle_closes_the_energy_balance_to_round_off() {
    let tool = Tool {
        shape: Shape::Plane,
        centre: Vector3::zeros(),
        radius: 1.0,
        frame: [Vector3::x(), Vector3::y(), Vector3::z()],
    };
    let offset = 0.125;
    let delta = 1.0 / 256.0;
    let law = PenaltyContact::new(1000.0, 500.0, 0.3, offset).unwrap();
    let waypoints = [
        ([0.0, 0.0], offset + 0.0625),
        ([0.0, 0.0], offset),
        ([0.0, 0.0], offset - delta),
        ([0.5, 0.0], offset - delta),
        ([0.5, 0.25], offset - 2.0 * delta),
        ([0.25, 0.25], offset - delta),
        ([0.25 + 1.0 / 1024.0, 0.25], offset - delta),
        ([0.25, 0.25], offset - delta),
        ([0.25, 0.25], offset),
        ([0.25, 0.25], offset + 0.0625),
    ];
    let path = path_on(&tool, &waypoints, 64);
    let cycle = run_cycle(&law, &tool, &path);
    let defect = cycle.defect();
    println!(
        "plane cycle: W = {:.6e}, D = {:.6e}, defect = {defect:.3e}, round-off bound {:.3e}",
        cycle.work, cycle.dissipated, cycle.round_off
    );
    assert!(defect.abs() <= cycle.round_off);
    assert!(cycle.dissipated > 0.0);
    assert_eq!(cycle.stored_end, 0.0);
    assert_eq!(cycle.final_state.unwrap().spring, Vector3::zeros());
    assert!(count(&cycle, ContactStatus::Stick) > 0 && count(&cycle, ContactStatus::Slip) > 0);
    // The first slide (calls 128..192, +x by 0.5 from a relaxed spring):
    // the spring takes up μ f_N/k_T = 0.3·1000 δ/500 elastically, the rest
    // is plastic slip, each increment along +x (round-off 16 ε per call of
    // the coordinates, |y| ≤ 1).
    let first_slide: f64 = cycle.responses[128..192]
        .iter()
        .map(|r| r.plastic_slip.norm())
        .sum();
    let take_up = 0.3 * 1000.0 * delta / 500.0;
    assert!(
        (first_slide - (0.5 - take_up)).abs() <= 16.0 * EPS * 64.0,
        "plastic slip {first_slide}"
    );
}

/// Eq. E5–E7 on a tilted plane with openings and closings between samples:
/// the only defect is the trapezoidal rule across the kink of the normal
/// energy, at most `k_N |Δg|²/8` per crossing step (`½ k p_in g_out`, with
/// `p_in + g_out = |Δg| ≤ |Δy|`), plus round-off. Repeated for 20 random
/// planes, settings and depths.
#[test]
fn tilted_plane_cycles_close_up_to_the_crossing_defect() {
    let mut rng = StdRng::seed_from_u64(0x71_17);
    for _ in 0..20 {
        let tool = Tool::random(Shape::Plane, &mut rng);
        let offset = rng.random_range(0.0..0.3);
        let k_n = log_uniform(&mut rng, 2.0, 4.0);
        let law = PenaltyContact::new(
            k_n,
            k_n * rng.random_range(0.1..1.0),
            rng.random_range(0.05..0.8),
            offset,
        )
        .unwrap();
        let delta = rng.random_range(0.005..0.05);
        let start = rng.random_range(0.01..0.05);
        let waypoints = [
            ([0.0, 0.0], offset + start),
            ([0.0, 0.0], offset - delta),
            ([1.0, 0.3], offset - delta),
            ([0.2, 0.9], offset - 0.5 * delta),
            ([0.21, 0.9], offset - 0.5 * delta),
            ([0.2, 0.9], offset - 0.5 * delta),
            ([0.2, 0.9], offset + start * 1.37),
        ];
        let cycle = run_cycle(&law, &tool, &path_on(&tool, &waypoints, 50));
        let bound = cycle.crossing_bound + cycle.round_off;
        assert!(
            cycle.defect().abs() <= bound,
            "defect {:e} > {bound:e}",
            cycle.defect()
        );
        assert_eq!(cycle.stored_end, 0.0);
    }
}

/// Eq. E5–E7 on curved tools (spheres from both sides, cylinders): closed
/// cycles along curved paths (press, slide, slide while pressing, reverse,
/// stick excursion, lift off). The defect stays within the derived bounds:
/// crossing steps, the `O(|Δy|³)` trapezoidal error of the smooth normal
/// energy, and the tangential `½ (n·t_n)(n·Δy)` per step, plus round-off.
/// Checked at 25 and 100 steps per leg (defects and bounds printed: the
/// bound shrinks with the step, the defect stays far below it).
#[test]
fn curved_cycles_close_within_the_derived_defect() {
    let mut rng = StdRng::seed_from_u64(0xC_0FE);
    for shape in [Shape::SphereOutside, Shape::SphereInside, Shape::Cylinder] {
        for trial in 0..10 {
            let tool = Tool::random(shape, &mut rng);
            let offset = rng.random_range(0.0..0.3);
            let k_n = log_uniform(&mut rng, 2.0, 4.0);
            let law = PenaltyContact::new(
                k_n,
                k_n * rng.random_range(0.1..1.0),
                rng.random_range(0.05..0.8),
                offset,
            )
            .unwrap();
            let delta = rng.random_range(0.005..0.05);
            let length = rng.random_range(1.0..5.0);
            let waypoints = [
                ([0.0, 0.0], offset + 0.03),
                ([0.0, 0.0], offset - delta),
                ([length, 0.0], offset - delta),
                ([length, 0.5 * length], offset - 2.0 * delta),
                ([0.5 * length, 0.5 * length], offset - delta),
                ([0.5 * length + 0.01, 0.5 * length], offset - delta),
                ([0.5 * length, 0.5 * length], offset - delta),
                ([0.5 * length, 0.5 * length], offset + 0.041),
            ];
            let mut defects = Vec::new();
            for steps in [25, 100] {
                let cycle = run_cycle(&law, &tool, &path_on(&tool, &waypoints, steps));
                let bound = cycle.crossing_bound
                    + cycle.smooth_bound
                    + cycle.tangential_bound
                    + cycle.round_off;
                let defect = cycle.defect();
                assert!(
                    defect.abs() <= bound,
                    "{shape:?}: defect {defect:e} > bound {bound:e} ({cycle:?})"
                );
                assert_eq!(cycle.stored_end, 0.0);
                assert!(count(&cycle, ContactStatus::Slip) > 0);
                defects.push((defect, bound, cycle.dissipated));
            }
            if trial == 0 {
                println!(
                    "{shape:?}: (defect, bound, dissipated) at 25 and 100 steps per leg: {defects:?}"
                );
            }
        }
    }
}

/// Doc Sec. "Explicit kernel": stick returns the node elastically. Pressed
/// onto a plane and moved tangentially out and back below the slip limit,
/// the node sticks throughout, the friction force is `k_T` times the
/// tangential displacement from the press point (the spring is linear on a
/// plane), nothing is dissipated and the spring is back to zero at the
/// start point — all to round-off `16 ε (steps) k_T |y|`.
#[test]
fn stick_returns_the_node_elastically() {
    let mut rng = StdRng::seed_from_u64(0x57_1C);
    for _ in 0..20 {
        let tool = Tool::random(Shape::Plane, &mut rng);
        let k_n = log_uniform(&mut rng, 2.0, 4.0);
        let k_t = k_n * rng.random_range(0.1..1.0);
        let mu = rng.random_range(0.05..0.8);
        let law = PenaltyContact::new(k_n, k_t, mu, 0.1).unwrap();
        let delta = 0.02;
        let reach = 0.9 * mu * k_n * delta / k_t;
        let angle: f64 = rng.random_range(0.0..std::f64::consts::TAU);
        let aim = [reach * angle.cos(), reach * angle.sin()];
        let waypoints = [
            ([0.0, 0.0], 0.1 + 0.01),
            ([0.0, 0.0], 0.1 - delta),
            (aim, 0.1 - delta),
            ([0.0, 0.0], 0.1 - delta),
        ];
        let steps = 40;
        let path = path_on(&tool, &waypoints, steps);
        let cycle = run_cycle(&law, &tool, &path);
        let press = path[steps];
        let round_off = 16.0 * EPS * (3 * steps) as f64 * k_t * (press.norm() + tool.size());
        let n = tool.frame[2];
        for (response, y) in cycle.responses[steps..].iter().zip(&path[steps + 1..]) {
            assert_eq!(response.status, ContactStatus::Stick);
            let shift = y - press;
            let expected = k_t * (shift - n.dot(&shift) * n);
            assert!((response.tangential_force - expected).norm() <= round_off);
        }
        let end = cycle.responses.last().unwrap();
        assert!(end.tangential_force.norm() <= round_off);
        assert!(cycle.dissipated.abs() <= round_off * reach);
    }
}

/// Central differences of a node of mass `m` on the plane `z = 0`, pushed
/// down by `F`, from rest at `z0` (`z_{−1} = z_0`): the positions and the
/// first step at which the contact is open.
fn bounce(
    law: &PenaltyContact,
    mass: f64,
    dt: f64,
    force: f64,
    z0: f64,
    steps: usize,
) -> (Vec<f64>, Option<usize>) {
    let tool = Tool {
        shape: Shape::Plane,
        centre: Vector3::zeros(),
        radius: 1.0,
        frame: [Vector3::x(), Vector3::y(), Vector3::z()],
    };
    let mut z = vec![z0, z0];
    let mut state = PenaltyState::new(&Vector3::new(0.0, 0.0, z0));
    let mut open_at = None;
    for n in 1..steps {
        let y = Vector3::new(0.0, 0.0, z[n]);
        let response = law.update(&mut state, &y, tool.query(&y).as_ref()).unwrap();
        if response.status == ContactStatus::Open && open_at.is_none() {
            open_at = Some(n);
        }
        let acceleration = (response.force().z - force) / mass;
        z.push(2.0 * z[n] - z[n - 1] + dt * dt * acceleration);
    }
    (z, open_at)
}

/// Doc Sec. "Stiffness limit": with `k = c · 4m/Δt²` a node of mass `m`
/// pushed onto a plane by `F` and released from rest `δ` below its
/// equilibrium `−F/k` follows the central-difference solution of
/// `ë = −ω² e` exactly, `e_n = −δ cos((n + ½)θ)/cos(θ/2)` with
/// `cos θ = 1 − ω²Δt²/2` and `ω² = frequency_squared = k/m` (the penalty
/// force is linear while in contact): bounded for `c = 0.95` (amplitude
/// `δ/√(1−c)`, the node never leaves). With `c = 1.05`, beyond the limit,
/// the amplitude grows by `|r| = 1.1 + √0.21` per step (`r + 1/r = 2 −
/// 4c`) from `|A| = 2.79 δ`, and the node leaves the tool within
/// `ln(|z_eq|/δ)/ln|r| + 3` steps. Trajectory tolerance: per-step
/// round-off `4 ε (|z| + Δt² |a|)` propagated by the recurrence (growth
/// `n / sin θ`).
#[test]
fn penalty_stiffness_respects_the_central_difference_limit() {
    let (mass, dt, force) = (1e-6, 1e-6, 10.0);
    let law = PenaltyContact::from_stable_step(mass, dt, 0.95, 0.3, 0.0).unwrap();
    let k = law.normal_stiffness();
    assert_eq!(k, stable_penalty_stiffness(mass, dt, 0.95).unwrap());
    assert!((k - 0.95 * 4.0 * mass / (dt * dt)).abs() <= 4.0 * EPS * k);
    let omega2 = law.frequency_squared(mass, 0.0, 0.0, 0.0).unwrap();
    assert_eq!(omega2, k / mass);
    let theta = (1.0 - omega2 * dt * dt / 2.0).acos();
    let equilibrium = -force / k;
    let delta = 0.1 * (force / k) * (1.0 - 0.95f64).sqrt();
    let (z, open_at) = bounce(&law, mass, dt, force, equilibrium - delta, 2000);
    assert_eq!(open_at, None);
    for (index, zn) in z.iter().enumerate() {
        let n = index as f64 - 1.0;
        let predicted = -delta * ((n + 0.5) * theta).cos() / (theta / 2.0).cos();
        let per_step = 4.0 * EPS * (zn.abs() + (force + k * zn.abs()) * dt * dt / mass);
        let tol = (index as f64 + 1.0) * per_step / theta.sin();
        assert!((zn - equilibrium - predicted).abs() <= tol, "step {index}");
    }
    let beyond = PenaltyContact::new(1.05 * 4.0 * mass / (dt * dt), 1.0, 0.3, 0.0).unwrap();
    let growth = 1.1 + 0.21f64.sqrt();
    let equilibrium_beyond = -force / beyond.normal_stiffness();
    let predicted = ((equilibrium_beyond.abs() / delta).ln() / growth.ln()).ceil() as usize + 3;
    let (_, open_at) = bounce(&beyond, mass, dt, force, equilibrium_beyond - delta, 200);
    let open_at = open_at.expect("the node leaves the tool");
    assert!(
        open_at <= predicted,
        "left after {open_at} steps, predicted ≤ {predicted}"
    );
}

/// Doc Sec. "Frequency bound": the eigenvalues of the explicit contact
/// stiffness `∂r_y/∂y` (central differences of the kernel's residual from
/// a frozen state) stay below `m ω²` of `frequency_squared(m, p, |t|, κ)`
/// plus the step's own normal-motion term `2 C_μ κ k_T |n·Δy|` (see the
/// doc) plus the finite-difference error `C_μ ‖E_fd‖₂ ≤ 3 C_μ · 3 tol`
/// (Bauer–Fike with the eigenvector condition `C_μ`; `‖E_fd‖₂ ≤ 3 max
/// |entry|`), at 300 stick and 300 slip states on each curved tool.
/// `max_curvature` is checked against `1/ρ`.
#[test]
fn frequency_bound_covers_the_contact_stiffness() {
    let mut rng = StdRng::seed_from_u64(0xF_2E9);
    for shape in [Shape::SphereOutside, Shape::SphereInside, Shape::Cylinder] {
        for target in [ContactStatus::Stick, ContactStatus::Slip] {
            let mut done = 0;
            let mut worst = 0.0f64;
            while done < 300 {
                let tool = Tool::random(shape, &mut rng);
                let k_n = log_uniform(&mut rng, 2.0, 4.0);
                let k_t = k_n * rng.random_range(0.1..1.0);
                let mu = rng.random_range(0.05..1.0);
                let law = PenaltyContact::new(k_n, k_t, mu, 0.1).unwrap();
                let depth = rng.random_range(0.005..0.05);
                let u = [rng.random_range(-10.0..10.0), rng.random_range(-10.0..10.0)];
                let y = tool.at(u, 0.1 - depth);
                let point = tool.query(&y).unwrap();
                let n = point.normal;
                let ratio = if target == ContactStatus::Stick {
                    rng.random_range(0.1..0.9)
                } else {
                    rng.random_range(1.1..3.0)
                };
                let tangent = {
                    let v = random_unit(&mut rng);
                    (v - n.dot(&v) * n).normalize()
                };
                // A frozen state: spring s (tangent) and a small step Δy.
                let dy = random_unit(&mut rng) * 1e-4;
                let trial_length = ratio * mu * k_n * depth / k_t;
                let spring = tangent * trial_length - (dy - n.dot(&dy) * n);
                let frozen = PenaltyState {
                    spring,
                    previous_position: y - dy,
                    ..PenaltyState::new(&(y - dy))
                };
                let at = |x: &Vector3<f64>| {
                    let mut state = frozen;
                    law.update(&mut state, x, tool.query(x).as_ref()).unwrap()
                };
                let centre = at(&y);
                if centre.status != target {
                    continue;
                }
                // max_curvature takes √(2‖H‖² − tr²), which carries the
                // round-off 8 ε (2‖H‖² + tr²) of its argument into
                // √(8 ε (2‖H‖² + tr²))/2 when the two curvatures are equal.
                let kappa = max_curvature(&point.hessian);
                let rho = tool.radius_at(&y);
                let (frob2, trace) = (point.hessian.norm_squared(), point.hessian.trace());
                let kappa_tol = 0.5 * (8.0 * EPS * (2.0 * frob2 + trace * trace)).sqrt()
                    + 8.0 * EPS * trace.abs();
                assert!(
                    (kappa - 1.0 / rho).abs() <= kappa_tol,
                    "κ = {kappa} vs 1/ρ = {}",
                    1.0 / rho
                );
                // FD: ℓ = min(ρ, |t*|/(k_T + 2|w|κ)); h = 1e-6 ℓ.
                let w = k_t * (spring + dy);
                let ell = rho
                    .min(k_t * trial_length / (k_t + 2.0 * w.norm() * kappa))
                    .min(10.0);
                let h = 1e-6 * ell;
                let mut jacobian = Matrix3::zeros();
                let mut same = true;
                for j in 0..3 {
                    let (mut plus, mut minus) = (y, y);
                    plus[j] += h;
                    minus[j] -= h;
                    let (rp, rm) = (at(&plus), at(&minus));
                    same &= rp.status == target && rm.status == target;
                    jacobian.set_column(j, &((rp.residual - rm.residual) / (plus[j] - minus[j])));
                }
                if !same {
                    continue;
                }
                let force_scale = centre.normal_force + w.norm() + (k_n + k_t) * ell;
                let fd_tol = 32.0 * (h / ell).powi(2) * force_scale / ell
                    + 16.0 * EPS * (k_n + k_t) * (y.norm() + tool.size()) / h;
                let c_mu = if target == ContactStatus::Slip {
                    (((mu * mu + 4.0f64).sqrt() + mu) / 2.0).powi(2)
                } else {
                    1.0
                };
                let bound = mass_free_bound(&law, depth, centre.tangential_force.norm(), kappa)
                    + 2.0 * c_mu * kappa * k_t * n.dot(&dy).abs()
                    + 3.0 * c_mu * 3.0 * fd_tol;
                let radius = jacobian
                    .complex_eigenvalues()
                    .iter()
                    .fold(0.0f64, |a, e| a.max(e.norm()));
                assert!(
                    radius <= bound,
                    "{shape:?} {target:?}: spectral radius {radius} > {bound}"
                );
                worst = worst.max(radius / bound);
                done += 1;
            }
            println!(
                "frequency bound {shape:?} {target:?}: max spectral radius / bound = {worst:.6}"
            );
        }
    }
}

/// `m ω²` from `frequency_squared` with a unit mass.
fn mass_free_bound(law: &PenaltyContact, penetration: f64, friction: f64, kappa: f64) -> f64 {
    law.frequency_squared(1.0, penetration, friction, kappa)
        .unwrap()
}

/// Frictionless explicit contact (`μ = 0`): status `Slip` whenever in
/// contact, no friction force, no dissipation, and the accumulated slip
/// is the tangential path length (here a straight slide of known length on
/// a plane, within `16 ε` per step of the coordinates).
#[test]
fn frictionless_explicit_contact_slides_freely() {
    let mut rng = StdRng::seed_from_u64(0xF1);
    let tool = Tool::random(Shape::Plane, &mut rng);
    let law = PenaltyContact::new(1000.0, 500.0, 0.0, 0.1).unwrap();
    let waypoints = [
        ([0.0, 0.0], 0.1),
        ([0.0, 0.0], 0.09),
        ([2.0, 1.0], 0.09),
        ([2.0, 1.0], 0.2),
    ];
    let cycle = run_cycle(&law, &tool, &path_on(&tool, &waypoints, 40));
    for r in &cycle.responses {
        assert_eq!(r.tangential_force, Vector3::zeros());
        if r.gap < 0.0 {
            assert_eq!(r.status, ContactStatus::Slip);
        }
    }
    assert_eq!(cycle.dissipated, 0.0);
    let slid = cycle.final_state.unwrap().slip_length;
    let expected = 5.0f64.sqrt();
    assert!((slid - expected).abs() <= 16.0 * EPS * 120.0 * (tool.size() + 3.0));
}
