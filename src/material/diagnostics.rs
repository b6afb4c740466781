//! Tangent diagnostics: finite-difference checks of `S` against `W` and of
//! `ℂ` against `S`, with an error bound derived from the step size, and a
//! sampler of states that covers every branch of the UD-NCF law.
//!
//! A tool as much as a test: `ncform material check` runs it on any
//! parameter set (after FEBio's tangent diagnostic).
//!
//! # The error bound
//! For `φ(s) = W(C + sD)` the central difference `d(h) = (φ(h) − φ(−h))/2h`
//! has truncation error `h² φ‴/6 + O(h⁴)` and round-off error at most
//! `ε/h`, `ε` the round-off of one evaluation of `φ`. Richardson's estimate
//! from two steps, `|d(h) − d(h/2)|`, is three times the truncation error of
//! `d(h/2)` to leading order, and itself carries at most `3ε/h` of
//! round-off. The accepted error of `d(h/2)` is therefore
//! `SAFETY · (|d(h) − d(h/2)| / 3 + 2ε/h) + ε_abs`, with `ε` estimated as
//! `ROUNDOFF_ULPS · u · (|W| + |S|·|C|)` (the invariants carry an absolute
//! error of order `u·|C|`, amplified by the stress) and `ε_abs = u ·` scale.
//! The same bound applies component-wise to `S(C + sD)` for the tangent.
//! Nothing in the bound uses the analytic derivative under test.

use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

use super::frame::{FibreFrame, Sym2};
use super::invariants::Invariants;
use super::law::{MembraneMaterial, Tangent};
use super::udncf::Branches;
use super::{Material, MaterialError};

/// Unit round-off of `f64`.
const UNIT_ROUNDOFF: f64 = f64::EPSILON / 2.0;
/// Round-off of one law evaluation, in units of `u·(|W| + |S||C|)`: the
/// law's sums have a few dozen terms.
pub const ROUNDOFF_ULPS: f64 = 64.0;
/// Factor on the leading-order error estimate (the `O(h⁴)` remainder and the
/// variation of `φ‴` across the stencil).
pub const SAFETY: f64 = 10.0;

/// The step `h = u^(1/3) · max(|C|, 1)`, which balances `h²` truncation
/// against `u/h` round-off.
pub fn fd_step(c: &Sym2) -> f64 {
    UNIT_ROUNDOFF.cbrt() * c.norm().max(1.0)
}

/// Result of one finite-difference check along a direction `D`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FdCheck {
    /// `|½ S:D − dW/ds|` (analytic vs finite difference).
    pub stress_error: f64,
    /// Accepted error for `stress_error` (see the module docs).
    pub stress_tolerance: f64,
    /// `‖½ ℂ:D − dS/ds‖` (analytic vs finite difference, Voigt components).
    pub tangent_error: f64,
    /// Accepted error for `tangent_error`.
    pub tangent_tolerance: f64,
    /// `|½ S:D|`, the size of the checked quantity.
    pub stress_scale: f64,
    /// `‖½ ℂ:D‖`, the size of the checked quantity.
    pub tangent_scale: f64,
}

impl FdCheck {
    /// Both errors within their tolerances.
    pub fn passed(&self) -> bool {
        self.stress_error <= self.stress_tolerance && self.tangent_error <= self.tangent_tolerance
    }
}

/// `A : B` for symmetric tensors in [`Sym2`] storage.
fn contract(a: &Sym2, b: &Sym2) -> f64 {
    super::frame::contract(a, b)
}

/// `ℂ : D` for `D` in [`Sym2`] storage (the tangent acts on engineering
/// strain, so the shear entry is doubled).
fn tangent_times(tangent: &Tangent, d: &Sym2) -> Sym2 {
    tangent * Sym2::new(d[0], d[1], 2.0 * d[2])
}

/// Checks `S` against finite differences of `W` and `ℂ` against finite
/// differences of `S` at `C` along the direction `D` (both in [`Sym2`]
/// storage), with step [`fd_step`] and the bound of the module docs.
///
/// # Errors
/// When the law rejects `C` or a stencil point.
pub fn fd_check<M: MembraneMaterial + ?Sized>(
    material: &M,
    c: &Sym2,
    frame: &FibreFrame,
    d: &Sym2,
) -> Result<FdCheck, MaterialError> {
    let h = fd_step(c);
    let (state, tangent) = material.stress_tangent(c, frame)?;
    let analytic_ds = 0.5 * contract(&state.stress, d);
    let analytic_dc = 0.5 * tangent_times(&tangent, d);

    let eval = |s: f64| material.stress(&(c + s * d), frame);
    let mut dw = [0.0; 2];
    let mut ds = [Sym2::zeros(); 2];
    let mut size_w: f64 = state.energy.abs();
    let mut size_s: f64 = state.stress.norm();
    for (k, step) in [h, 0.5 * h].into_iter().enumerate() {
        let plus = eval(step)?;
        let minus = eval(-step)?;
        size_w = size_w.max(plus.energy.abs()).max(minus.energy.abs());
        size_s = size_s.max(plus.stress.norm()).max(minus.stress.norm());
        dw[k] = (plus.energy - minus.energy) / (2.0 * step);
        ds[k] = (plus.stress - minus.stress) / (2.0 * step);
    }
    let c_norm = c.norm().max(1.0);
    let eps_w = ROUNDOFF_ULPS * UNIT_ROUNDOFF * (size_w + size_s * c_norm);
    let eps_s = ROUNDOFF_ULPS * UNIT_ROUNDOFF * (size_s + tangent.norm() * c_norm);
    let h2 = 0.5 * h;
    let stress_tolerance = SAFETY * ((dw[0] - dw[1]).abs() / 3.0 + 2.0 * eps_w / h2)
        + UNIT_ROUNDOFF * analytic_ds.abs();
    let tangent_tolerance = SAFETY * ((ds[0] - ds[1]).norm() / 3.0 + 2.0 * eps_s / h2)
        + UNIT_ROUNDOFF * analytic_dc.norm();
    Ok(FdCheck {
        stress_error: (analytic_ds - dw[1]).abs(),
        stress_tolerance,
        tangent_error: (analytic_dc - ds[1]).norm(),
        tangent_tolerance,
        stress_scale: analytic_ds.abs(),
        tangent_scale: analytic_dc.norm(),
    })
}

/// The branches of the law at `C` (`None` for a law without kinks, or an
/// inadmissible `C`).
pub fn branches_at(material: &Material, c: &Sym2, frame: &FibreFrame) -> Option<Branches> {
    match material {
        Material::UdNcf(law) => Invariants::new(c, frame).ok().map(|inv| law.branches(&inv)),
        Material::OrthotropicSvk(_) => None,
    }
}

/// True when the whole stencil of [`fd_check`] (`C ± h D`, `C ± h/2 D`)
/// stays on the branches of `C`: a stencil across a kink measures a mix of
/// two one-sided derivatives, so such states are skipped, not failed.
pub fn stencil_on_one_branch(material: &Material, c: &Sym2, frame: &FibreFrame, d: &Sym2) -> bool {
    let h = fd_step(c);
    let here = branches_at(material, c, frame);
    [-h, -0.5 * h, 0.5 * h, h]
        .iter()
        .all(|s| branches_at(material, &(c + *s * d), frame) == here)
}

/// Ranges of the sampled invariants (in the fibre frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleRanges {
    /// `I4 ∈ [1 − d, 1 + d]`.
    pub i4_deviation: f64,
    /// `I6 ∈ [−m, m]`.
    pub i6_max: f64,
    /// `I8 ∈ [lo, hi]`.
    pub i8: (f64, f64),
    /// States with `I11 < i11_min` are redrawn.
    pub i11_min: f64,
}

impl Default for SampleRanges {
    /// Wide enough to reach every branch of the named sets: `|I4 − 1| ≤
    /// 0.05`, `|I6| ≤ 0.9` (64° of trellis shear), `I8 ∈ [0.6, 1.6]`,
    /// `I11 ≥ 0.3` (past the reconstructed W11 lock at 0.6).
    fn default() -> Self {
        Self {
            i4_deviation: 0.05,
            i6_max: 0.9,
            i8: (0.6, 1.6),
            i11_min: 0.3,
        }
    }
}

/// A reproducible sampler of material states `(C, fibre angle)`.
///
/// Draws `(I4, I6, I8)` uniformly in the ranges, keeps states with
/// `I11 ≥ i11_min`, builds `C` in the fibre basis and rotates it into the
/// reference frame by a fibre angle uniform in `[0°, 180°)`.
pub struct StateSampler {
    rng: StdRng,
    ranges: SampleRanges,
}

impl StateSampler {
    /// A sampler with a fixed seed.
    pub fn new(seed: u64, ranges: SampleRanges) -> Self {
        Self {
            rng: StdRng::seed_from_u64(seed),
            ranges,
        }
    }

    /// The next state: `C` in the reference frame and the fibre angle \[rad\].
    pub fn sample(&mut self) -> (Sym2, f64) {
        let r = self.ranges;
        loop {
            let i4 = 1.0 + self.rng.random_range(-r.i4_deviation..=r.i4_deviation);
            let i6 = self.rng.random_range(-r.i6_max..=r.i6_max);
            let i8 = self.rng.random_range(r.i8.0..=r.i8.1);
            let j = i8 - i6 * i6 / i4;
            if j < r.i11_min * r.i11_min {
                continue;
            }
            let angle = self.rng.random_range(0.0..std::f64::consts::PI);
            return (c_from_invariants(i4, i6, i8, angle), angle);
        }
    }

    /// A random symmetric direction with components in `[−1, 1]`, normalised.
    pub fn direction(&mut self) -> Sym2 {
        let d = Sym2::new(
            self.rng.random_range(-1.0..=1.0),
            self.rng.random_range(-1.0..=1.0),
            self.rng.random_range(-1.0..=1.0),
        );
        d / d.norm().max(f64::MIN_POSITIVE)
    }
}

/// `C` in the reference frame whose components in the fibre basis
/// `{a0, b0}` (rovings at `angle` rad) are `[[I4, I6], [I6, I8]]`:
/// `C = I4 a0⊗a0 + I6 (a0⊗b0 + b0⊗a0) + I8 b0⊗b0`.
pub fn c_from_invariants(i4: f64, i6: f64, i8: f64, angle: f64) -> Sym2 {
    let frame = FibreFrame::from_angle(angle);
    i4 * frame.n4 + 2.0 * i6 * frame.n6 + i8 * frame.n8
}

/// A UD-NCF parameter set for tests: every term with a transition and a
/// lock, moduli of order one and a non-integer coupling exponent, so that no
/// term hides under the 1000 MPa roving modulus and k11″ is exercised away
/// from `e11 = 2`. Parse with `MaterialSpec::from_toml_str`.
pub const BALANCED_TEST_SET: &str = r#"
law = "ud-ncf"
name = "balanced-test"
[w4]
c_ini = 2.0
s_ini = 0.02
c_mid = 0.5
delta_s_mid = 0.01
c_lock = 30.0
i_lock = 0.03
[w6]
c_ini = 1.0
s_ini = 0.1
c_mid = 0.2
delta_s_mid = 0.05
c_lock = 5.0
i_lock = 0.6
[w8]
c_ini = 1.5
s_ini = 0.1
c_mid = 3.0
delta_s_mid = 0.2
c_lock = 4.0
i_lock = 0.4
[w11]
c_ini = 0.8
s_ini = 0.05
c_mid = 2.0
delta_s_mid = 0.1
c_lock = 10.0
i_lock = 0.5
[coupling]
k_min = 0.3
s11 = 6.0
e11 = 2.5
"#;

/// An orthotropic SVK parameter set for tests (`E1 = 50`, `E2 = 5`,
/// `ν12 = 0.3`, `G12 = 1` MPa).
pub const SVK_TEST_SET: &str = r#"
law = "orthotropic-svk"
[svk]
e1 = 50.0
e2 = 5.0
nu12 = 0.3
g12 = 1.0
"#;
