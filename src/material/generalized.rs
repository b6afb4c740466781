//! The generalized stress function of the law, paper Eq. (12), its derivative
//! and its exactly integrated energy (Appendix B, corrected: see
//! `docs/theory.md`).
//!
//! With `x_t = S_ini / C_ini`, `c = C_ini / ΔS_mid` and `y = x − x_t`:
//!
//! ```text
//! f(x) = C_ini x                                       x < x_t
//! f(x) = S_ini + (C_mid y + ΔS_mid)(1 − e^(−c y))      x ≥ x_t
//! f(x) += C_lock (x − I_lock)²                         x ≥ I_lock
//! ```
//!
//! `G(x) = ∫₀ˣ f` is the energy of one term; `f′` enters the consistent
//! tangent.
//!
//! The explicit solver's force pass evaluates `f` (and `G` where the coupling
//! needs it) over a [`super::lanes::Real`]: one point or several independent points
//! at once, the same expressions, branch-free, with `e^(−z)` from
//! [`decay_pair_lanes`] instead of the C library, so that several elements'
//! exponentials run side by side.

use super::lanes::{ROUND_TO_INTEGER, Real};

/// The middle branch of Eq. (12): the transition from the initial modulus
/// `C_ini` to the middle modulus `C_mid` over the stress range `ΔS_mid`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transition {
    /// Initial stress limit `S_ini` \[MPa\].
    pub s_ini: f64,
    /// Middle modulus `C_mid` \[MPa\].
    pub c_mid: f64,
    /// Stress range `ΔS_mid` of the transition \[MPa\].
    pub delta_s_mid: f64,
}

/// The lock branch of Eq. (12): `f += C_lock (x − I_lock)²` for `x ≥ I_lock`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lock {
    /// Lock modulus `C_lock` \[MPa\].
    pub c_lock: f64,
    /// Lock onset `I_lock` (same measure as `x`, dimensionless).
    pub i_lock: f64,
}

/// Which branch of Eq. (12) a point lies on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum TermBranch {
    /// `x < x_t`: `f = C_ini x`.
    Initial,
    /// `x_t ≤ x < I_lock`: the exponential transition to `C_mid`.
    Middle,
    /// `x ≥ I_lock` with `x < x_t`: the lock on the initial branch.
    InitialLocked,
    /// `x ≥ I_lock` and `x ≥ x_t`: the lock on the middle branch.
    MiddleLocked,
}

/// One term's generalized stress function `f(x)`, `x ≥ 0` (Eq. 12).
///
/// Construct with [`GeneralizedTerm::new`], which derives `x_t` and `c`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GeneralizedTerm {
    /// Initial modulus `C_ini` \[MPa\].
    pub c_ini: f64,
    /// Optional transition (middle) branch.
    pub transition: Option<Transition>,
    /// Optional lock branch.
    pub lock: Option<Lock>,
    /// Transition point `x_t = S_ini / C_ini` (infinite without a transition).
    x_t: f64,
    /// Exponent coefficient `c = C_ini / ΔS_mid` (zero without a transition).
    rate: f64,
    /// `(ΔS_mid / c, C_mid / c²)`, the quotients of the middle branch's
    /// energy, for the force pass (zero without a transition).
    energy_quotients: (f64, f64),
}

/// Value, slope and energy of a generalized term at one point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TermValue {
    /// Energy `G(x)` \[MPa\].
    pub energy: f64,
    /// Stress function `f(x) = G′(x)` \[MPa\].
    pub stress: f64,
    /// Modulus `f′(x)` \[MPa\].
    pub modulus: f64,
}

impl GeneralizedTerm {
    /// Builds the term and derives `x_t = S_ini / C_ini` and
    /// `c = C_ini / ΔS_mid`, the two choices that make `f` C¹ at `x_t`.
    /// Parameter ranges are checked by [`crate::material::params`], not here.
    pub fn new(c_ini: f64, transition: Option<Transition>, lock: Option<Lock>) -> Self {
        let (x_t, rate, energy_quotients) = match transition {
            Some(t) => {
                let c = c_ini / t.delta_s_mid;
                (t.s_ini / c_ini, c, (t.delta_s_mid / c, t.c_mid / (c * c)))
            }
            None => (f64::INFINITY, 0.0, (0.0, 0.0)),
        };
        Self {
            c_ini,
            transition,
            lock,
            x_t,
            rate,
            energy_quotients,
        }
    }

    /// A linear term `f = C_ini x` (no transition, no lock).
    pub fn linear(c_ini: f64) -> Self {
        Self::new(c_ini, None, None)
    }

    /// The transition point `x_t = S_ini / C_ini` (infinite without a transition).
    pub fn transition_point(&self) -> f64 {
        self.x_t
    }

    /// The exponent coefficient `c = C_ini / ΔS_mid` of the middle branch
    /// (zero without a transition), the value [`GeneralizedTerm::eval`] uses.
    pub(super) fn rate(&self) -> f64 {
        self.rate
    }

    /// The branch of Eq. (12) at `x`, with the same one-sided convention as
    /// [`GeneralizedTerm::eval`] (a boundary belongs to the upper branch).
    pub fn branch(&self, x: f64) -> TermBranch {
        let locked = self.lock.is_some_and(|l| x >= l.i_lock);
        match (x < self.x_t, locked) {
            (true, false) => TermBranch::Initial,
            (false, false) => TermBranch::Middle,
            (true, true) => TermBranch::InitialLocked,
            (false, true) => TermBranch::MiddleLocked,
        }
    }

    /// `f(x)` alone at `x ≥ 0` (Eq. 12), the same value as
    /// [`GeneralizedTerm::eval`] gives, at the cost of one `expm1`.
    #[inline(always)]
    pub fn stress(&self, x: f64) -> f64 {
        let mut stress = if x < self.x_t {
            self.c_ini * x
        } else {
            let t = self
                .transition
                .expect("x_t is finite only with a transition");
            let y = x - self.x_t;
            let (_, one_minus_decay) = decay_pair(self.rate * y);
            t.s_ini + (t.c_mid * y + t.delta_s_mid) * one_minus_decay
        };
        if let Some(lock) = self.lock
            && x >= lock.i_lock
        {
            let d = x - lock.i_lock;
            stress += lock.c_lock * d * d;
        }
        stress
    }

    /// `(G(x), f(x))`: [`GeneralizedTerm::eval`] without `f′`.
    #[inline(always)]
    pub fn energy_stress(&self, x: f64) -> (f64, f64) {
        let value = self.eval(x);
        (value.energy, value.stress)
    }

    /// `f(x)`, `f′(x)` and `G(x)` at `x ≥ 0` (Eq. 12 and its integral).
    #[inline(always)]
    pub fn eval(&self, x: f64) -> TermValue {
        let mut value = if x < self.x_t {
            TermValue {
                energy: 0.5 * self.c_ini * x * x,
                stress: self.c_ini * x,
                modulus: self.c_ini,
            }
        } else {
            // x ≥ x_t implies a transition exists (x_t is infinite otherwise).
            let t = self
                .transition
                .expect("x_t is finite only with a transition");
            let c = self.rate;
            let y = x - self.x_t;
            let z = c * y;
            let (decay, one_minus_decay) = decay_pair(z);
            let amplitude = t.c_mid * y + t.delta_s_mid;
            TermValue {
                energy: 0.5 * self.c_ini * self.x_t * self.x_t
                    + (t.s_ini + t.delta_s_mid) * y
                    + 0.5 * t.c_mid * y * y
                    - t.delta_s_mid * one_minus_decay / c
                    - t.c_mid * one_minus_decay_times_one_plus(z, decay, one_minus_decay) / (c * c),
                stress: t.s_ini + amplitude * one_minus_decay,
                modulus: t.c_mid * one_minus_decay + amplitude * c * decay,
            }
        };
        if let Some(lock) = self.lock
            && x >= lock.i_lock
        {
            let d = x - lock.i_lock;
            value.energy += lock.c_lock * d * d * d / 3.0;
            value.stress += lock.c_lock * d * d;
            value.modulus += 2.0 * lock.c_lock * d;
        }
        value
    }

    /// [`GeneralizedTerm::stress`] on lanes: `f(x)` per lane, `x ≥ 0`.
    #[inline(always)]
    pub fn stress_lanes<V: Real>(&self, x: V) -> V {
        self.energy_stress_lanes_impl(x, false).1
    }

    /// [`GeneralizedTerm::energy_stress`] on lanes: `(G(x), f(x))` per lane,
    /// `x ≥ 0`.
    #[inline(always)]
    pub fn energy_stress_lanes<V: Real>(&self, x: V) -> (V, V) {
        self.energy_stress_lanes_impl(x, true)
    }

    /// The expressions of [`GeneralizedTerm::eval`] per lane (with the
    /// operands of `+` and `×` in either order, which changes no bit, and the
    /// energy's divisions by the constants `c`, `c²` as products with their
    /// quotients, a round-off difference), each branch evaluated only when
    /// some lane lies on it and then selected; the energy (zero unless
    /// `with_energy`) only on request.
    #[inline(always)]
    fn energy_stress_lanes_impl<V: Real>(&self, x: V, with_energy: bool) -> (V, V) {
        let zero = x.splat(0.0);
        let mut stress = x * self.c_ini;
        let mut energy = if with_energy {
            x * (0.5 * self.c_ini) * x
        } else {
            zero
        };
        if let Some(t) = self.transition {
            let middle = x.ge(x.splat(self.x_t));
            if V::any(middle) {
                // y ≥ 0 on the middle lanes; the others are discarded.
                let y = (x - self.x_t).max(zero);
                let c = self.rate;
                let z = y * c;
                let (decay, one_minus_decay) = decay_pair_lanes(z);
                let amplitude = y * t.c_mid + t.delta_s_mid;
                stress = V::select(middle, amplitude * one_minus_decay + t.s_ini, stress);
                if with_energy {
                    let tail = one_minus_decay_times_one_plus_lanes(z, decay, one_minus_decay);
                    let middle_energy = y * (t.s_ini + t.delta_s_mid)
                        + 0.5 * self.c_ini * self.x_t * self.x_t
                        + y * (0.5 * t.c_mid) * y
                        - one_minus_decay * self.energy_quotients.0
                        - tail * self.energy_quotients.1;
                    energy = V::select(middle, middle_energy, energy);
                }
            }
        }
        if let Some(lock) = self.lock {
            let locked = x.ge(x.splat(lock.i_lock));
            if V::any(locked) {
                let d = x - lock.i_lock;
                stress = V::select(locked, stress + d * lock.c_lock * d, stress);
                if with_energy {
                    energy = V::select(locked, energy + d * lock.c_lock * d * d / 3.0, energy);
                }
            }
        }
        (energy, stress)
    }
}

/// `(e^(−z), 1 − e^(−z))` for `z ≥ 0` from one transcendental call, each to
/// a few ulps: above `ln 2`, `e^(−z) ≤ ½` and `1 − e^(−z)` loses nothing;
/// below, `expm1` gives `1 − e^(−z) ≤ ½` and `e^(−z) = 1 − that` is exact
/// to round-off.
#[inline(always)]
pub(super) fn decay_pair(z: f64) -> (f64, f64) {
    if z > std::f64::consts::LN_2 {
        let decay = (-z).exp();
        (decay, 1.0 - decay)
    } else {
        let one_minus_decay = -(-z).exp_m1();
        (1.0 - one_minus_decay, one_minus_decay)
    }
}

/// `1 − e^(−z)(1 + z)` for `z ≥ 0` without cancellation at small `z`:
/// the series `Σ_{n≥2} (−1)ⁿ (n−1) zⁿ / n!` below 0.1, the closed form
/// `(1 − e^(−z)) − z e^(−z)` above, from the pair of [`decay_pair`].
#[inline]
pub(super) fn one_minus_decay_times_one_plus(z: f64, decay: f64, one_minus_decay: f64) -> f64 {
    if z < 0.1 {
        // Terms n = 2..=9; the first omitted term is below 1e-10 · z²/2.
        let mut term = z * z / 2.0; // zⁿ/n! for n = 2
        let mut sum = term;
        let mut sign = -1.0;
        for n in 3..=9 {
            term *= z / n as f64;
            sum += sign * (n - 1) as f64 * term;
            sign = -sign;
        }
        sum
    } else {
        one_minus_decay - z * decay
    }
}

/// `ln 2` split as in fdlibm (`0x3fe62e42fee00000`): the high part has 21
/// trailing zero bits, so `k · LN2_HI` is exact for `|k| < 2²¹`.
const LN2_HI: f64 = 0.693_147_180_369_123_8;
/// `ln 2 − LN2_HI` (`0x3dea39ef35793c76`).
const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
/// Beyond this `e^(−z) < 3.4e−308` is returned as 0.
const DECAY_FLUSH: f64 = 708.0;

/// `1/n!` for `n = 2..=13`: the Taylor coefficients of `(e^r − 1 − r)/r²`.
const EXPM1_TAYLOR: [f64; 12] = [
    1.0 / 2.0,
    1.0 / 6.0,
    1.0 / 24.0,
    1.0 / 120.0,
    1.0 / 720.0,
    1.0 / 5_040.0,
    1.0 / 40_320.0,
    1.0 / 362_880.0,
    1.0 / 3_628_800.0,
    1.0 / 39_916_800.0,
    1.0 / 479_001_600.0,
    1.0 / 6_227_020_800.0,
];

/// `decay_pair` on lanes, branch-free: `(e^(−z), 1 − e^(−z))` for
/// `z ≥ 0`, each within an ulp or so of the C library's (NaN stays NaN).
///
/// With `k = round(−z / ln 2)`, `r = −z − k ln 2` (`|r| ≤ ln 2 / 2`, the
/// Cody–Waite reduction with fdlibm's split of `ln 2`), `p = e^r − 1` from
/// its Taylor series to `r¹³` (truncation below `4e−18`, a fiftieth of an
/// ulp of `p`; Estrin's scheme) and `s = 2^k` built from the bits of `k`:
///
/// ```text
/// e^(−z) = s + s p,      1 − e^(−z) = (1 − s) − s p
/// ```
///
/// For `z ≤ ln 2` (where `decay_pair` uses `expm1`), `k ∈ {0, −1}`, so
/// `1 − s` is exact and the second form has no cancellation; for larger `z`
/// it is `1 − e^(−z) ≥ ½` to round-off. Beyond `z = 708`, `e^(−z)` is 0.
#[inline(always)]
pub fn decay_pair_lanes<V: Real>(z: V) -> (V, V) {
    let flush = z.splat(DECAY_FLUSH);
    let flushed = z.gt(flush);
    let x = V::select(flushed, -flush, -z);
    let shifted = x * std::f64::consts::LOG2_E + ROUND_TO_INTEGER;
    let k = shifted - ROUND_TO_INTEGER;
    let r = (x - k * LN2_HI) - k * LN2_LO;
    let c = &EXPM1_TAYLOR;
    let r2 = r * r;
    let r4 = r2 * r2;
    let pair = |i: usize| r * c[i + 1] + c[i];
    let low = pair(2) * r2 + pair(0);
    let mid = pair(6) * r2 + pair(4);
    let high = pair(10) * r2 + pair(8);
    let q = (high * r4 + mid) * r4 + low;
    let p = r2 * q + r;
    let s = shifted.exp2_of_shifted();
    let sp = s * p;
    let decay = V::select(flushed, z.splat(0.0), s + sp);
    // 1 − s as −(s − 1): the same value.
    let one_minus_decay = -(s - 1.0) - sp;
    (decay, one_minus_decay)
}

/// `e^(−z)` on lanes for `z ≥ 0` (see [`decay_pair_lanes`]).
#[inline(always)]
pub fn decay_lanes<V: Real>(z: V) -> V {
    decay_pair_lanes(z).0
}

/// [`one_minus_decay_times_one_plus`] on lanes: the series where some lane
/// has `z < 0.1`, the closed form elsewhere.
#[inline(always)]
fn one_minus_decay_times_one_plus_lanes<V: Real>(z: V, decay: V, one_minus_decay: V) -> V {
    let closed = one_minus_decay - z * decay;
    let small = z.lt(z.splat(0.1));
    if !V::any(small) {
        return closed;
    }
    let mut term = z * z / 2.0;
    let mut sum = term;
    let mut sign = -1.0;
    for n in 3..=9 {
        term = term * (z / n as f64);
        sum = sum + term * (sign * (n - 1) as f64);
        sign = -sign;
    }
    V::select(small, sum, closed)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `|a − b|` in ulps of `b`.
    fn ulps(a: f64, b: f64) -> f64 {
        if a == b {
            return 0.0;
        }
        let ulp = f64::from_bits(b.abs().to_bits() + 1) - b.abs();
        (a - b).abs() / ulp
    }

    /// `f` on the four values through the AVX2 lanes, where the CPU has them.
    fn on_avx2(
        values: [f64; 4],
        f: impl Fn(crate::material::lanes::x86::F64x4) -> crate::material::lanes::x86::F64x4,
    ) -> Option<[f64; 4]> {
        let simd = pulp::x86::V3::try_new()?;
        Some(f(crate::material::lanes::x86::F64x4::new(simd, values)).store())
    }

    #[test]
    fn ln2_is_split_as_in_fdlibm() {
        assert_eq!(LN2_HI.to_bits(), 0x3fe6_2e42_fee0_0000);
        assert_eq!(LN2_LO.to_bits(), 0x3dea_39ef_3579_3c76);
    }

    #[test]
    fn lane_exponentials_match_the_c_library_to_a_few_ulps() {
        // Dense near 0 and ln 2, then geometric up to the flush.
        let mut zs: Vec<f64> = (0..=20_000).map(|i| i as f64 * 1e-4).collect();
        zs.extend((0..=4000).map(|i| 1e-300 * 10f64.powf(i as f64 * 0.0757)));
        zs.extend((0..=2000).map(|i| 2.0 + i as f64 * 0.353));
        zs.extend([0.0, 707.9, 708.0, 708.1, 710.0, f64::INFINITY]);
        let mut worst = (0.0_f64, 0.0_f64);
        for &z in &zs {
            let (decay, one_minus_decay) = decay_pair_lanes(z);
            let (d, o) = decay_pair(z);
            if d > 1e-300 {
                worst.0 = worst.0.max(ulps(decay, d));
            } else {
                assert!(decay.abs() <= 1e-300, "e^(-{z})");
            }
            worst.1 = worst.1.max(ulps(one_minus_decay, o));
        }
        eprintln!("worst ulps of e^(-z), 1 - e^(-z): {worst:?}");
        assert!(worst.0 <= 4.0 && worst.1 <= 4.0, "worst ulps {worst:?}");
        assert_eq!(decay_pair_lanes(0.0), (1.0, 0.0));
        assert_eq!(decay_pair_lanes(f64::INFINITY), (0.0, 1.0));
        let nan = decay_pair_lanes(f64::NAN);
        assert!(nan.0.is_nan() && nan.1.is_nan());
        // The AVX2 lanes repeat the f64 path bit for bit.
        for chunk in zs.chunks_exact(4) {
            let values = [chunk[0], chunk[1], chunk[2], chunk[3]];
            let (Some(decay), Some(one_minus_decay)) = (
                on_avx2(values, |z| decay_pair_lanes(z).0),
                on_avx2(values, |z| decay_pair_lanes(z).1),
            ) else {
                return;
            };
            for l in 0..4 {
                let (d, o) = decay_pair_lanes(values[l]);
                assert_eq!(
                    (decay[l].to_bits(), one_minus_decay[l].to_bits()),
                    (d.to_bits(), o.to_bits())
                );
            }
        }
    }

    #[test]
    fn lane_terms_repeat_the_scalar_expressions() {
        let term = GeneralizedTerm::new(
            1.5,
            Some(Transition {
                s_ini: 0.1,
                c_mid: 3.0,
                delta_s_mid: 0.2,
            }),
            Some(Lock {
                c_lock: 4.0,
                i_lock: 0.4,
            }),
        );
        // Around x_t (z < 0.1: the series), the middle branch and the lock.
        for i in 0..500 {
            let values: [f64; 4] = std::array::from_fn(|l| (4 * i + l) as f64 * 5e-4);
            for &x in &values {
                let (energy, stress) = term.energy_stress_lanes(x);
                let value = term.eval(x);
                assert_eq!(term.stress_lanes(x), stress);
                assert!(ulps(stress, value.stress) <= 8.0, "f({x})");
                assert!(
                    (energy - value.energy).abs() <= 16.0 * f64::EPSILON * value.energy,
                    "G({x})"
                );
            }
            let (Some(energy), Some(stress)) = (
                on_avx2(values, |x| term.energy_stress_lanes(x).0),
                on_avx2(values, |x| term.stress_lanes(x)),
            ) else {
                return;
            };
            for l in 0..4 {
                let (e, f) = term.energy_stress_lanes(values[l]);
                assert_eq!(
                    (energy[l].to_bits(), stress[l].to_bits()),
                    (e.to_bits(), f.to_bits())
                );
            }
        }
    }

    #[test]
    fn series_matches_closed_form_where_both_are_accurate() {
        for &z in &[0.02_f64, 0.05, 0.0999] {
            let closed = 1.0 - (-z).exp() * (1.0 + z);
            let (decay, one_minus_decay) = decay_pair(z);
            let series = one_minus_decay_times_one_plus(z, decay, one_minus_decay);
            // The closed form loses about eps/z² relative accuracy here.
            assert!((closed - series).abs() <= 1e-12 * series.abs().max(1e-300) / (z * z));
        }
    }
}
