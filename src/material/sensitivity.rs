//! Exact derivatives of the stress with respect to the law's parameters,
//! `∂S/∂p` at fixed `C`, for direct-differentiation sensitivities
//! (`K du/dp = −∂R/∂p` at a converged state).
//!
//! The law (`docs/theory.md` §2–§5) is
//! `W = G4(|I4 − 1|) + G6(|I6|) + k11(I11) G8(I8 − 1)[I8 ≥ 1] + G11(1 − I11)[I11 ≤ 1]`
//! and `S = 2 Σ_k g_k N_k` with `g = dW/d(I4, I6, I8)` the total derivative
//! through `I11(I4, I6, I8)`. A parameter enters `g` only through one term's
//! `f = G′` and `G` (the generalized stress function of Eq. 12) or through
//! the coupling's `k11` and `k11′` (Eq. 15, corrected), so
//! `∂g/∂p` follows from [`GeneralizedTerm::parameter_derivative`] and
//! [`Coupling::parameter_derivative`] with exactly the branch and kink
//! conventions of [`UdNcf::evaluate_invariants`]: the derivatives are those of
//! the function the code evaluates, on the branch it takes.
//!
//! The formulas and their numerics are derived in `docs/theory.md` §12.
//!
//! Parameters are named by [`LawParameter`], whose keys are those of a
//! parameter file (`w6.c_ini`, `coupling.k_min`, see
//! [`super::MaterialSpec::parameter_values`]).

use std::fmt;

use super::MaterialError;
use super::coupling::{Coupling, CouplingValue};
use super::frame::{FibreFrame, Sym2};
use super::generalized::{
    GeneralizedTerm, Lock, TermValue, Transition, decay_pair, one_minus_decay_times_one_plus,
};
use super::invariants::Invariants;
use super::law::stress_from_gradient;
use super::udncf::{KINK_TOLERANCE, UdNcf};

/// One of the four generalized terms of the UD-NCF law (Eq. 11).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TermName {
    /// `W4 = G4(|I4 − 1|)`: roving tension and compression.
    W4,
    /// `W6 = G6(|I6|)`: shear.
    W6,
    /// `W8 = k11(I11) G8(I8 − 1)`: stitching tension.
    W8,
    /// `W11 = G11(1 − I11)`: compaction across the rovings.
    W11,
}

/// A parameter of one generalized term, Eq. 12 (`docs/theory.md` §2.1).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TermParameter {
    /// Initial modulus `C_ini` \[MPa\].
    CIni,
    /// Initial stress limit `S_ini` \[MPa\] (transition only).
    SIni,
    /// Middle modulus `C_mid` \[MPa\] (transition only).
    CMid,
    /// Transition stress range `ΔS_mid` \[MPa\] (transition only).
    DeltaSMid,
    /// Lock modulus `C_lock` \[MPa\] (lock only).
    CLock,
    /// Lock onset `I_lock` (lock only).
    ILock,
}

/// A parameter of the coupling `k11(I11)`, Eq. 15 as corrected in
/// `docs/theory.md` §3.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum CouplingParameter {
    /// Lower bound `k_min` of `k11`.
    KMin,
    /// Intensity `s11`.
    S11,
    /// Onset exponent `e11`.
    E11,
}

/// A parameter of the UD-NCF law: one term's (Eq. 12) or the coupling's
/// (Eq. 15). Its [`LawParameter::key`] is the parameter-file key.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LawParameter {
    /// A parameter of one generalized term.
    Term(TermName, TermParameter),
    /// A parameter of the coupling `k11`.
    Coupling(CouplingParameter),
}

impl TermName {
    /// The four terms in the order of a parameter file.
    pub const ALL: [TermName; 4] = [TermName::W4, TermName::W6, TermName::W8, TermName::W11];

    /// The term's table name in a parameter file (`w4`, `w6`, `w8`, `w11`).
    pub fn key(&self) -> &'static str {
        match self {
            TermName::W4 => "w4",
            TermName::W6 => "w6",
            TermName::W8 => "w8",
            TermName::W11 => "w11",
        }
    }

    /// The term of `law` this name denotes.
    pub fn term<'a>(&self, law: &'a UdNcf) -> &'a GeneralizedTerm {
        match self {
            TermName::W4 => &law.w4,
            TermName::W6 => &law.w6,
            TermName::W8 => &law.w8,
            TermName::W11 => &law.w11,
        }
    }

    fn term_mut<'a>(&self, law: &'a mut UdNcf) -> &'a mut GeneralizedTerm {
        match self {
            TermName::W4 => &mut law.w4,
            TermName::W6 => &mut law.w6,
            TermName::W8 => &mut law.w8,
            TermName::W11 => &mut law.w11,
        }
    }
}

impl TermParameter {
    /// The six term parameters in the order of a parameter file.
    pub const ALL: [TermParameter; 6] = [
        TermParameter::CIni,
        TermParameter::SIni,
        TermParameter::CMid,
        TermParameter::DeltaSMid,
        TermParameter::CLock,
        TermParameter::ILock,
    ];

    /// The key inside a term's table (`c_ini`, `s_ini`, `c_mid`,
    /// `delta_s_mid`, `c_lock`, `i_lock`).
    pub fn key(&self) -> &'static str {
        match self {
            TermParameter::CIni => "c_ini",
            TermParameter::SIni => "s_ini",
            TermParameter::CMid => "c_mid",
            TermParameter::DeltaSMid => "delta_s_mid",
            TermParameter::CLock => "c_lock",
            TermParameter::ILock => "i_lock",
        }
    }

    /// The parameter's value in `term`, `None` when the term has no
    /// transition (`s_ini`, `c_mid`, `delta_s_mid`) or no lock (`c_lock`,
    /// `i_lock`).
    pub fn value(&self, term: &GeneralizedTerm) -> Option<f64> {
        match self {
            TermParameter::CIni => Some(term.c_ini),
            TermParameter::SIni => term.transition.map(|t| t.s_ini),
            TermParameter::CMid => term.transition.map(|t| t.c_mid),
            TermParameter::DeltaSMid => term.transition.map(|t| t.delta_s_mid),
            TermParameter::CLock => term.lock.map(|l| l.c_lock),
            TermParameter::ILock => term.lock.map(|l| l.i_lock),
        }
    }

    /// `term` with this parameter set to `value` (and `x_t`, `c` derived
    /// anew), `None` when the term does not have the parameter. Not
    /// validated: see [`super::MaterialSpec::with_parameters`] for that.
    pub fn with_value(&self, term: &GeneralizedTerm, value: f64) -> Option<GeneralizedTerm> {
        let mut c_ini = term.c_ini;
        let mut transition: Option<Transition> = term.transition;
        let mut lock: Option<Lock> = term.lock;
        match self {
            TermParameter::CIni => c_ini = value,
            TermParameter::SIni => transition.as_mut()?.s_ini = value,
            TermParameter::CMid => transition.as_mut()?.c_mid = value,
            TermParameter::DeltaSMid => transition.as_mut()?.delta_s_mid = value,
            TermParameter::CLock => lock.as_mut()?.c_lock = value,
            TermParameter::ILock => lock.as_mut()?.i_lock = value,
        }
        Some(GeneralizedTerm::new(c_ini, transition, lock))
    }
}

impl CouplingParameter {
    /// The three coupling parameters in the order of a parameter file.
    pub const ALL: [CouplingParameter; 3] = [
        CouplingParameter::KMin,
        CouplingParameter::S11,
        CouplingParameter::E11,
    ];

    /// The key inside the `[coupling]` table (`k_min`, `s11`, `e11`).
    pub fn key(&self) -> &'static str {
        match self {
            CouplingParameter::KMin => "k_min",
            CouplingParameter::S11 => "s11",
            CouplingParameter::E11 => "e11",
        }
    }

    /// The parameter's value in `coupling`.
    pub fn value(&self, coupling: &Coupling) -> f64 {
        match self {
            CouplingParameter::KMin => coupling.k_min,
            CouplingParameter::S11 => coupling.s11,
            CouplingParameter::E11 => coupling.e11,
        }
    }
}

impl LawParameter {
    /// Every parameter the UD-NCF law can have (27), in the order of
    /// [`super::MaterialSpec::parameter_values`]: per term `c_ini`, `s_ini`,
    /// `c_mid`, `delta_s_mid`, `c_lock`, `i_lock`, then the coupling.
    pub fn all() -> impl Iterator<Item = LawParameter> {
        TermName::ALL
            .into_iter()
            .flat_map(|t| {
                TermParameter::ALL
                    .into_iter()
                    .map(move |p| LawParameter::Term(t, p))
            })
            .chain(
                CouplingParameter::ALL
                    .into_iter()
                    .map(LawParameter::Coupling),
            )
    }

    /// The parameters `law` has (a term's transition and lock parameters
    /// only when it has them), in the order of
    /// [`super::MaterialSpec::parameter_values`].
    pub fn of_law(law: &UdNcf) -> Vec<LawParameter> {
        Self::all().filter(|p| p.value(law).is_some()).collect()
    }

    /// The parameter of a parameter-file key (`w6.c_ini`, `w8.delta_s_mid`,
    /// `w11.i_lock`, `coupling.k_min`), `None` for any other text.
    pub fn from_key(key: &str) -> Option<LawParameter> {
        let (table, name) = key.split_once('.')?;
        if table == "coupling" {
            return CouplingParameter::ALL
                .into_iter()
                .find(|p| p.key() == name)
                .map(LawParameter::Coupling);
        }
        let term = TermName::ALL.into_iter().find(|t| t.key() == table)?;
        let parameter = TermParameter::ALL.into_iter().find(|p| p.key() == name)?;
        Some(LawParameter::Term(term, parameter))
    }

    /// The parameter-file key: `table.key`, as
    /// [`super::MaterialSpec::parameter_values`] lists it.
    pub fn key(&self) -> String {
        match self {
            LawParameter::Term(t, p) => format!("{}.{}", t.key(), p.key()),
            LawParameter::Coupling(p) => format!("coupling.{}", p.key()),
        }
    }

    /// The parameter's value in `law`; `None` when the term has no
    /// transition (for `s_ini`, `c_mid`, `delta_s_mid`) or no lock (for
    /// `c_lock`, `i_lock`).
    pub fn value(&self, law: &UdNcf) -> Option<f64> {
        match self {
            LawParameter::Term(t, p) => p.value(t.term(law)),
            LawParameter::Coupling(p) => Some(p.value(&law.coupling)),
        }
    }

    /// `law` with this parameter set to `value`, `None` when the law does
    /// not have the parameter. Not validated (a finite-difference or
    /// line-search helper); [`super::MaterialSpec::with_parameters`] applies
    /// the parameter-file rules.
    pub fn with_value(&self, law: &UdNcf, value: f64) -> Option<UdNcf> {
        let mut out = *law;
        match self {
            LawParameter::Term(t, p) => {
                let term = t.term_mut(&mut out);
                *term = p.with_value(term, value)?;
            }
            LawParameter::Coupling(p) => match p {
                CouplingParameter::KMin => out.coupling.k_min = value,
                CouplingParameter::S11 => out.coupling.s11 = value,
                CouplingParameter::E11 => out.coupling.e11 = value,
            },
        }
        Some(out)
    }
}

impl fmt::Display for LawParameter {
    /// The parameter-file key, as [`LawParameter::key`].
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LawParameter::Term(t, p) => write!(f, "{}.{}", t.key(), p.key()),
            LawParameter::Coupling(p) => write!(f, "coupling.{}", p.key()),
        }
    }
}

/// `γ(3, z) = ∫₀ᶻ t² e^(−t) dt = 2 − e^(−z)(z² + 2z + 2)` for `z ≥ 0`,
/// without cancellation: below 1 the series
/// `Σ_{k≥0} (−1)ᵏ z^(k+3) / ((k+3) k!)` (terms k = 0..=18; the first omitted
/// is below 3e−18 of the sum), above it `2 (1 − e^(−z)(1+z)) − z² e^(−z)`
/// from the pair of `decay_pair` (cancellation by at most a factor 3.3 there).
#[inline]
fn lower_gamma3(z: f64, decay: f64, tail: f64) -> f64 {
    if z < 1.0 {
        let mut power = z * z * z; // z^(k+3)/k! for k = 0
        let mut sum = power / 3.0;
        let mut sign = -1.0;
        for k in 1..=18 {
            power *= z / k as f64;
            sum += sign * power / (k + 3) as f64;
            sign = -sign;
        }
        sum
    } else {
        2.0 * tail - z * z * decay
    }
}

impl GeneralizedTerm {
    /// `(∂G/∂p, ∂f/∂p)` at fixed `x ≥ 0`: the exact derivative of the
    /// term's energy `G` and stress function `f` (Eq. 12 and its integral,
    /// `docs/theory.md` §2) with respect to one parameter, on the branch
    /// [`GeneralizedTerm::eval`] takes at `x` (`x < x_t` initial, a boundary
    /// belongs to the upper branch; the lock from `x ≥ I_lock`).
    ///
    /// On the middle branch, with `x_t = S_ini/C_ini`, `a = ΔS_mid/C_ini`,
    /// `m = C_mid/C_ini`, `y = x − x_t`, `z = y/a`, `E1 = 1 − e^(−z)`,
    /// `E2 = 1 − e^(−z)(1+z)`, `E4 = γ(3, z)` (all computed without
    /// cancellation) the derivatives, including the moves of `x_t` and `c`,
    /// are
    ///
    /// ```text
    /// ∂f/∂S_ini  = E1 − m (E1 + z e^(−z))        ∂G/∂S_ini  = a (z E1 − E2 − m z E1)
    /// ∂f/∂C_ini  = m x_t E1 + (1 + m z) e^(−z) x  ∂G/∂C_ini  = ½x_t² + a x_t E1 + a² E2 + m (a x_t z E1 + a² E4)
    /// ∂f/∂C_mid  = y E1                           ∂G/∂C_mid  = a² (½ z² E1 − ½ E4)
    /// ∂f/∂ΔS_mid = E2 − m z² e^(−z)               ∂G/∂ΔS_mid = a (z E2 − (1 + m) E4)
    /// ```
    ///
    /// (each `∂G/∂p = ∫₀ˣ ∂f/∂p`, `f` being continuous at `x_t`); on the
    /// initial branch only `C_ini` acts, `(½x², x)`; the lock adds
    /// `(d³/3, d²)` for `C_lock` and `(−C_lock d², −2 C_lock d)` for
    /// `I_lock`, `d = x − I_lock ≥ 0`. A parameter the term does not have,
    /// or one that does not act on the branch, gives `(0, 0)`. Derivation:
    /// `docs/theory.md` §12.
    pub fn parameter_derivative(&self, x: f64, p: TermParameter) -> (f64, f64) {
        match p {
            TermParameter::CLock | TermParameter::ILock => {
                let Some(lock) = self.lock else {
                    return (0.0, 0.0);
                };
                if x < lock.i_lock {
                    return (0.0, 0.0);
                }
                let d = x - lock.i_lock;
                if p == TermParameter::CLock {
                    (d * d * d / 3.0, d * d)
                } else {
                    (-lock.c_lock * d * d, -2.0 * lock.c_lock * d)
                }
            }
            TermParameter::CIni
            | TermParameter::SIni
            | TermParameter::CMid
            | TermParameter::DeltaSMid => {
                let x_t = self.transition_point();
                let transition = match self.transition {
                    Some(t) if x >= x_t => t,
                    // The initial branch (always, without a transition).
                    _ => {
                        return if p == TermParameter::CIni {
                            (0.5 * x * x, x)
                        } else {
                            (0.0, 0.0)
                        };
                    }
                };
                self.middle_parameter_derivative(x, x_t, transition, p)
            }
        }
    }

    /// The middle branch of [`GeneralizedTerm::parameter_derivative`] for
    /// `C_ini`, `S_ini`, `C_mid`, `ΔS_mid` at `x ≥ x_t`.
    #[inline]
    fn middle_parameter_derivative(
        &self,
        x: f64,
        x_t: f64,
        t: Transition,
        p: TermParameter,
    ) -> (f64, f64) {
        let y = x - x_t;
        let z = self.rate() * y;
        let (decay, e1) = decay_pair(z);
        let e2 = one_minus_decay_times_one_plus(z, decay, e1);
        let a = t.delta_s_mid / self.c_ini;
        let m = t.c_mid / self.c_ini;
        match p {
            TermParameter::SIni => (a * (z * e1 - e2 - m * z * e1), e1 - m * (e1 + z * decay)),
            TermParameter::CIni => {
                let e4 = lower_gamma3(z, decay, e2);
                (
                    0.5 * x_t * x_t
                        + a * x_t * e1
                        + a * a * e2
                        + m * (a * x_t * z * e1 + a * a * e4),
                    m * x_t * e1 + (1.0 + m * z) * decay * x,
                )
            }
            TermParameter::CMid => {
                let e4 = lower_gamma3(z, decay, e2);
                (a * a * 0.5 * (z * z * e1 - e4), y * e1)
            }
            TermParameter::DeltaSMid => {
                let e4 = lower_gamma3(z, decay, e2);
                (a * (z * e2 - (1.0 + m) * e4), e2 - m * z * z * decay)
            }
            TermParameter::CLock | TermParameter::ILock => (0.0, 0.0),
        }
    }
}

impl Coupling {
    /// `(∂k11/∂p, ∂k11′/∂p)` at fixed `I11`: the exact derivative of the
    /// coupling (Eq. 15 corrected, `docs/theory.md` §3) and of its slope
    /// `k11′ = dk11/dI11` (the `dk` of [`Coupling::eval`]) with respect to
    /// one parameter; `(0, 0)` for `I11 ≥ 1`, where `k11 = 1`.
    ///
    /// With `u = 1 − I11`, `q = s11 u^e11`, `q′ = s11 e11 u^(e11−1)` and
    /// `s = (1 − k_min) e^(−q)`:
    ///
    /// ```text
    /// k_min: (1 − e^(−q),      −e^(−q) q′)
    /// s11:   (−s u^e11,         s e11 u^(e11−1) (1 − q))
    /// e11:   (−s q ln u,        s (s11 u^(e11−1) (1 + e11 ln u) − q′ q ln u))
    /// ```
    pub fn parameter_derivative(&self, i11: f64, p: CouplingParameter) -> (f64, f64) {
        if i11 >= 1.0 {
            return (0.0, 0.0);
        }
        let u = 1.0 - i11;
        let e = self.e11;
        let u_em2 = if e == 2.0 { 1.0 } else { u.powf(e - 2.0) };
        let u_em1 = u_em2 * u;
        let u_e = u_em1 * u;
        let q = self.s11 * u_e;
        let dq = self.s11 * e * u_em1;
        let decay = (-q).exp();
        let scaled = (1.0 - self.k_min) * decay;
        match p {
            CouplingParameter::KMin => (-(-q).exp_m1(), -decay * dq),
            CouplingParameter::S11 => (-scaled * u_e, scaled * e * u_em1 * (1.0 - q)),
            CouplingParameter::E11 => {
                let ln_u = u.ln();
                (
                    -scaled * q * ln_u,
                    scaled * (self.s11 * u_em1 * (1.0 + e * ln_u) - dq * q * ln_u),
                )
            }
        }
    }
}

/// What [`UdNcf::evaluate_invariants`] computes at one state and every
/// parameter derivative reuses: the terms' arguments on the branch taken,
/// W8's value and the coupling (where W8 is active), and `∂I11/∂p`.
#[derive(Debug, Clone, Copy)]
struct SensitivityState {
    /// `I4 − 1` (its sign gives the sign of `g4`).
    d4: f64,
    /// `I6` (its sign gives the sign of `g6`).
    i6: f64,
    /// `I11`.
    i11: f64,
    /// `x` of W11 when W11 is active (`I11 ≤ 1` within the kink band).
    x11: Option<f64>,
    /// `x` of W8, `G8`, `f8` and the coupling when W8 is active
    /// (`I8 ≥ 1` within the kink band).
    w8: Option<(f64, TermValue, CouplingValue)>,
    /// `∂I11/∂(I4, I6, I8)`.
    di11: [f64; 3],
}

impl UdNcf {
    /// The state's shared part, with the branch conventions of
    /// [`UdNcf::evaluate_invariants`] (the kink bands of [`KINK_TOLERANCE`]).
    #[inline]
    fn sensitivity_state(&self, inv: &Invariants) -> SensitivityState {
        let x11 = (inv.i11 <= 1.0 + KINK_TOLERANCE).then(|| (1.0 - inv.i11).max(0.0));
        let w8 = (inv.i8 >= 1.0 - KINK_TOLERANCE).then(|| {
            let x8 = (inv.i8 - 1.0).max(0.0);
            (x8, self.w8.eval(x8), self.coupling.eval(inv.i11))
        });
        SensitivityState {
            d4: inv.i4 - 1.0,
            i6: inv.i6,
            i11: inv.i11,
            x11,
            w8,
            di11: inv.i11_gradient(),
        }
    }

    /// `∂g/∂p` at a prepared state.
    #[inline]
    fn gradient_derivative_at(&self, state: &SensitivityState, p: LawParameter) -> [f64; 3] {
        let mut dg = [0.0; 3];
        // ∂W_,11/∂p: W_,11 = −f11 + k11′ G8 (partial in I11 at fixed I4, I6, I8).
        let mut dw_11 = 0.0;
        match p {
            LawParameter::Term(TermName::W4, tp) => {
                let (_, df) = self.w4.parameter_derivative(state.d4.abs(), tp);
                // g4 = sgn(I4 − 1) f4, the sign as copysign takes it.
                dg[0] = if state.d4.is_sign_negative() { -df } else { df };
            }
            LawParameter::Term(TermName::W6, tp) => {
                let (_, df) = self.w6.parameter_derivative(state.i6.abs(), tp);
                dg[1] = if state.i6.is_sign_negative() { -df } else { df };
            }
            LawParameter::Term(TermName::W11, tp) => {
                if let Some(x11) = state.x11 {
                    dw_11 = -self.w11.parameter_derivative(x11, tp).1;
                }
            }
            LawParameter::Term(TermName::W8, tp) => {
                if let Some((x8, _, k)) = state.w8 {
                    let (d_energy, d_stress) = self.w8.parameter_derivative(x8, tp);
                    dg[2] = k.k * d_stress;
                    dw_11 = k.dk * d_energy;
                }
            }
            LawParameter::Coupling(cp) => {
                if let Some((_, t8, _)) = state.w8 {
                    let (dk, d_slope) = self.coupling.parameter_derivative(state.i11, cp);
                    dg[2] = dk * t8.stress;
                    dw_11 = d_slope * t8.energy;
                }
            }
        }
        // The chain rule through I11, as evaluate_invariants applies it.
        for (dg_k, di11_k) in dg.iter_mut().zip(state.di11) {
            *dg_k += dw_11 * di11_k;
        }
        dg
    }

    /// `∂g/∂p` at fixed invariants: the exact derivative, with respect to the
    /// law parameter `p`, of the gradient `g = dW/d(I4, I6, I8)` that
    /// [`UdNcf::evaluate_invariants`] returns (total derivatives through
    /// `I11`, Eq. A.4–A.7; `docs/theory.md` §5), on the branches it takes
    /// (including its kink bands at `I8 = 1` and `I11 = 1`). Zero for a
    /// parameter the law does not have.
    pub fn gradient_parameter_derivative(&self, inv: &Invariants, p: LawParameter) -> [f64; 3] {
        self.gradient_derivative_at(&self.sensitivity_state(inv), p)
    }

    /// `∂S/∂p = 2 Σ_k (∂g_k/∂p) N_k` at fixed `C` (Eq. 8 differentiated in
    /// the parameter `p`; the structural tensors do not depend on it), in
    /// the frame's reference basis like `S`.
    ///
    /// # Errors
    /// Degenerate states as [`Invariants::new`];
    /// [`MaterialError::NonFiniteResponse`] when the derivative overflows.
    pub fn stress_parameter_derivative(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
        p: LawParameter,
    ) -> Result<Sym2, MaterialError> {
        let inv = Invariants::new(c, frame)?;
        let ds = stress_from_gradient(&self.gradient_parameter_derivative(&inv, p), frame);
        if ds.iter().all(|v| v.is_finite()) {
            Ok(ds)
        } else {
            Err(MaterialError::NonFiniteResponse)
        }
    }

    /// [`UdNcf::stress_parameter_derivative`] for several parameters at one
    /// state: `out[i] = ∂S/∂params[i]`, with the invariants, W8 and the
    /// coupling evaluated once; no allocation. Pairs are taken as
    /// `params.iter().zip(out)`: give slices of equal length (entries of
    /// `out` beyond `params.len()` are left as they are).
    ///
    /// # Errors
    /// As [`UdNcf::stress_parameter_derivative`]; on error the contents of
    /// `out` are unspecified.
    pub fn stress_parameter_derivatives(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
        params: &[LawParameter],
        out: &mut [Sym2],
    ) -> Result<(), MaterialError> {
        let inv = Invariants::new(c, frame)?;
        let state = self.sensitivity_state(&inv);
        for (&p, ds) in params.iter().zip(out.iter_mut()) {
            *ds = stress_from_gradient(&self.gradient_derivative_at(&state, p), frame);
            if !ds.iter().all(|v| v.is_finite()) {
                return Err(MaterialError::NonFiniteResponse);
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    //! Every analytic derivative against central differences of the code's
    //! own evaluation (`GeneralizedTerm::eval`, `Coupling::eval`,
    //! `UdNcf::evaluate_invariants`), with a tolerance derived per check.
    //!
    //! The central difference `D(h) = (F(p+h) − F(p−h)) / (2h)` has the
    //! truncation `T(h) = (h²/6) F‴ + O(h⁴)` and the round-off
    //! `R(h) ≤ 2 m ε σ / (2h)` when each evaluation of `F` is within
    //! `m ε σ`, `σ` the sum of the magnitudes of the summands `F` is built
    //! from (not `|F|`: the middle branch's energy cancels between its
    //! terms) and `m = 16` roundings (each operation of `eval` rounds once,
    //! about a dozen of them reach the result; `exp` and `powf` are within
    //! an ulp). Richardson: `D(h) − D(h/2) = (3/4)(h²/6) F‴`, so
    //! `(4/3)|D(h) − D(h/2)| = (h²/6)|F‴| = T(h) = 4 T(h/2)` bounds the
    //! truncation of the finer estimate four times over. The check is
    //! `|analytic − D(h/2)| ≤ 2 (T_est + R(h/2)) + 8 ε |analytic|`; the
    //! factor 2 covers the `O(h⁴)` rest and the round-off inside the
    //! Richardson difference, the ulps the analytic value's own rounding.
    //! The step starts at `10⁻⁵ |p|` (about `ε^(1/3)`, where truncation and
    //! round-off balance) and is divided by 4 until `p ± h` and `p ± h/2`
    //! all leave every branch as it is at `p` (moving `S_ini`, `C_ini` or
    //! `I_lock` moves `x_t` or the lock onset), which is then asserted.
    //!
    //! A wrong derivative fails: in the interior of a branch the tolerance
    //! is about `10⁻⁹` of the derivative's scale, and the negative tests
    //! below show that the checker refuses the derivative that forgets the
    //! move of `x_t`, the coupling's `e11` slope without its `1 +` term, and
    //! the gradient without the chain rule through `I11`.

    use std::collections::BTreeSet;

    use super::*;
    use crate::material::generalized::TermBranch;
    use crate::material::udncf::Branches;
    use crate::material::{Material, MaterialSpec, MembraneMaterial};

    const EPS: f64 = f64::EPSILON;
    /// Roundings that reach one evaluation of `F` (see the module comment).
    const ROUNDINGS: f64 = 16.0;

    /// A stiff set: every term with a transition and a lock, a stiff W8,
    /// `e11 = 1.5` (so `u^(e11−2)` is singular at `I11 = 1`).
    const STIFF: &str = r#"
law = "ud-ncf"
name = "stiff"
[w4]
c_ini = 1000.0
s_ini = 20.0
c_mid = 300.0
delta_s_mid = 5.0
c_lock = 5e4
i_lock = 0.05
[w6]
c_ini = 0.5
s_ini = 0.05
c_mid = 0.05
delta_s_mid = 0.02
c_lock = 20.0
i_lock = 0.3
[w8]
c_ini = 50.0
s_ini = 1.0
c_mid = 5.0
delta_s_mid = 0.5
c_lock = 1000.0
i_lock = 0.08
[w11]
c_ini = 0.2
s_ini = 0.02
c_mid = 0.05
delta_s_mid = 0.1
c_lock = 30.0
i_lock = 0.3
[coupling]
k_min = 0.1
s11 = 4.0
e11 = 1.5
"#;

    /// A slow set: locks before `x_t` (the locked initial branch), slow
    /// transitions (small `z`, the series), `c_mid = 0`, `e11 = 1` (a slope
    /// jump of `k11` at `I11 = 1`).
    const SLOW: &str = r#"
law = "ud-ncf"
name = "slow"
[w4]
c_ini = 200.0
[w6]
c_ini = 0.1
s_ini = 0.05
c_mid = 0.0
delta_s_mid = 1.0
c_lock = 2.0
i_lock = 0.2
[w8]
c_ini = 2.0
s_ini = 0.1
c_mid = 0.5
delta_s_mid = 3.0
[w11]
c_ini = 0.05
s_ini = 0.01
c_mid = 0.02
delta_s_mid = 0.05
c_lock = 5.0
i_lock = 0.1
[coupling]
k_min = 0.7
s11 = 25.0
e11 = 1.0
"#;

    fn law_of(spec: &MaterialSpec) -> UdNcf {
        match spec.material {
            Material::UdNcf(law) => law,
            Material::OrthotropicSvk(_) => panic!("not a UD-NCF set"),
        }
    }

    fn laws() -> Vec<(String, UdNcf)> {
        let mut out = Vec::new();
        for name in ["schaefer2024", "schaefer2024-printed"] {
            let spec = MaterialSpec::named(name).expect("named set");
            out.push((name.to_string(), law_of(&spec)));
        }
        for (name, text) in [("stiff", STIFF), ("slow", SLOW)] {
            let spec = MaterialSpec::from_toml_str(text, name).expect("valid test set");
            out.push((name.to_string(), law_of(&spec)));
        }
        out
    }

    /// SplitMix64: a seeded, dependency-free generator for the states.
    struct Rng(u64);

    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^= z >> 31;
            (z >> 11) as f64 / (1u64 << 53) as f64
        }

        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.uniform()
        }
    }

    /// The first step: `10⁻⁵ |p|`, divided by 4 until `p ± h`, `p ± h/2`
    /// keep the branch (`same(v)`); the four are then asserted.
    fn step(p0: f64, same: impl Fn(f64) -> bool) -> f64 {
        let mut h = if p0 == 0.0 { 1e-8 } else { 1e-5 * p0.abs() };
        for _ in 0..200 {
            assert!(
                p0 + 0.25 * h != p0 - 0.25 * h,
                "no step keeps the branch at p = {p0}: the state sits on a switch"
            );
            if [p0 + h, p0 - h, p0 + 0.5 * h, p0 - 0.5 * h]
                .iter()
                .all(|&v| same(v))
            {
                for v in [p0 + h, p0 - h, p0 + 0.5 * h, p0 - 0.5 * h] {
                    assert!(same(v), "the stencil at {v} leaves the branch of {p0}");
                }
                return h;
            }
            h *= 0.25;
        }
        panic!("no step keeps the branch at p = {p0}");
    }

    /// `D(h)` from `value(p) = (F, σ)` with the actual step `(p+h) − (p−h)`
    /// (exact by Sterbenz), and its round-off bound `2 m ε σ / step`.
    fn difference(p0: f64, h: f64, value: &dyn Fn(f64) -> (f64, f64)) -> (f64, f64) {
        let (plus, minus) = (p0 + h, p0 - h);
        let ((fp, sp), (fm, sm)) = (value(plus), value(minus));
        let width = plus - minus;
        (
            (fp - fm) / width,
            2.0 * ROUNDINGS * EPS * sp.max(sm) / width,
        )
    }

    /// Checks `analytic` against `D(h/2)` with the derived tolerance (module
    /// comment); `Err` with the numbers when it is outside.
    fn check(
        analytic: f64,
        p0: f64,
        h: f64,
        value: &dyn Fn(f64) -> (f64, f64),
    ) -> Result<(), String> {
        let (coarse, _) = difference(p0, h, value);
        let (fine, round_off) = difference(p0, 0.5 * h, value);
        let truncation = 4.0 / 3.0 * (coarse - fine).abs();
        let tolerance = 2.0 * (truncation + round_off) + 8.0 * EPS * analytic.abs();
        let error = (analytic - fine).abs();
        if error <= tolerance {
            Ok(())
        } else {
            Err(format!(
                "analytic {analytic:e}, D(h/2) {fine:e}, D(h) {coarse:e}, error {error:e} > \
                 tolerance {tolerance:e} (truncation {truncation:e}, round-off {round_off:e}, h {h:e})"
            ))
        }
    }

    /// `(1 − e^(−z), 1 − e^(−z)(1+z))`, plain, for the scales.
    fn tails(z: f64) -> (f64, f64) {
        let decay = (-z).exp();
        ((1.0 - decay).max(0.0), (1.0 - decay * (1.0 + z)).max(0.0))
    }

    /// `σ` of `G(x)`: the sum of the magnitudes of the summands `eval`
    /// adds (the middle branch's energy cancels between them).
    fn energy_scale(term: &GeneralizedTerm, x: f64) -> f64 {
        let mut scale = match term.transition {
            Some(t) if x >= term.transition_point() => {
                let x_t = term.transition_point();
                let c = term.c_ini / t.delta_s_mid;
                let y = x - x_t;
                let (e1, e2) = tails(c * y);
                0.5 * term.c_ini * x_t * x_t
                    + (t.s_ini + t.delta_s_mid) * y
                    + 0.5 * t.c_mid.abs() * y * y
                    + t.delta_s_mid * e1 / c
                    + t.c_mid.abs() * e2 / (c * c)
            }
            _ => 0.5 * term.c_ini.abs() * x * x,
        };
        if let Some(l) = term.lock
            && x >= l.i_lock
        {
            let d = x - l.i_lock;
            scale += l.c_lock.abs() * d * d * d / 3.0;
        }
        scale
    }

    /// `σ` of `f(x)`.
    fn stress_scale(term: &GeneralizedTerm, x: f64) -> f64 {
        let mut scale = match term.transition {
            Some(t) if x >= term.transition_point() => {
                let y = x - term.transition_point();
                let (e1, _) = tails(term.c_ini / t.delta_s_mid * y);
                t.s_ini + (t.c_mid.abs() * y + t.delta_s_mid) * e1
            }
            _ => term.c_ini.abs() * x,
        };
        if let Some(l) = term.lock
            && x >= l.i_lock
        {
            let d = x - l.i_lock;
            scale += l.c_lock.abs() * d * d;
        }
        scale
    }

    /// The switches of a term: `x_t` and `I_lock` where they exist.
    fn switches(term: &GeneralizedTerm) -> Vec<f64> {
        let mut out = Vec::new();
        if term.transition.is_some() {
            out.push(term.transition_point());
        }
        if let Some(l) = term.lock {
            out.push(l.i_lock);
        }
        out
    }

    /// The branches a term can take on `x ≥ 0`.
    fn reachable(term: &GeneralizedTerm) -> BTreeSet<TermBranch> {
        let x_t = term.transition_point();
        let mut out = BTreeSet::from([TermBranch::Initial]);
        if term.transition.is_some() && term.lock.is_none_or(|l| x_t < l.i_lock) {
            out.insert(TermBranch::Middle);
        }
        if let Some(l) = term.lock {
            if l.i_lock < x_t {
                out.insert(TermBranch::InitialLocked);
            }
            if term.transition.is_some() {
                out.insert(TermBranch::MiddleLocked);
            }
        }
        out
    }

    /// Distances from a switch for the states placed next to it.
    const NEAR: [f64; 4] = [1e-9, 1e-7, 1e-5, 1e-3];

    /// `x` values for one term: a grid and random points over two and a
    /// half times its largest switch, and points within `δ` of each switch.
    fn term_points(term: &GeneralizedTerm, rng: &mut Rng) -> Vec<f64> {
        let top = 2.5 * switches(term).into_iter().fold(0.05_f64, f64::max);
        let mut xs: Vec<f64> = (0..=60).map(|i| top * i as f64 / 60.0).collect();
        xs.extend((0..60).map(|_| rng.range(0.0, top)));
        for s in switches(term) {
            for delta in NEAR {
                let d = delta * s.max(1e-2);
                xs.push(s + d);
                if s > d {
                    xs.push(s - d);
                }
            }
        }
        // Points on a switch (or within rounding of one, as a grid point
        // may land) are left out: any step moves the switch across x.
        let sw = switches(term);
        xs.retain(|x| sw.iter().all(|s| (x - s).abs() >= 1e-10 * s.max(1e-2)));
        xs
    }

    #[test]
    fn term_derivatives_match_central_differences_on_every_branch() {
        let mut rng = Rng(0x5eed_0001);
        let mut checks = 0usize;
        for (set, law) in laws() {
            for name in TermName::ALL {
                let term = *name.term(&law);
                let mut seen = BTreeSet::new();
                for x in term_points(&term, &mut rng) {
                    let branch = term.branch(x);
                    seen.insert(branch);
                    for tp in TermParameter::ALL {
                        let (d_energy, d_stress) = term.parameter_derivative(x, tp);
                        let Some(p0) = tp.value(&term) else {
                            assert_eq!((d_energy, d_stress), (0.0, 0.0), "{set} {name:?} {tp:?}");
                            continue;
                        };
                        let at = |v: f64| tp.with_value(&term, v).expect("the term has it");
                        let h = step(p0, |v| at(v).branch(x) == branch);
                        let energy = |v: f64| {
                            let t = at(v);
                            (t.eval(x).energy, energy_scale(&t, x))
                        };
                        let stress = |v: f64| {
                            let t = at(v);
                            (t.eval(x).stress, stress_scale(&t, x))
                        };
                        let context = format!("{set} {name:?} {tp:?} x = {x:e} ({branch:?})");
                        check(d_energy, p0, h, &energy)
                            .unwrap_or_else(|e| panic!("∂G: {context}: {e}"));
                        check(d_stress, p0, h, &stress)
                            .unwrap_or_else(|e| panic!("∂f: {context}: {e}"));
                        checks += 2;
                    }
                }
                assert_eq!(seen, reachable(&term), "{set} {name:?}: branches covered");
            }
        }
        eprintln!("{checks} term derivative checks");
    }

    #[test]
    fn term_derivatives_are_continuous_across_the_switches() {
        // At a switch the upper branch's formula applies; the derivatives of
        // f and G are continuous there, so the value at the switch equals the
        // one a hair below to within the hair.
        for (set, law) in laws() {
            for name in TermName::ALL {
                let term = *name.term(&law);
                for s in switches(&term) {
                    for tp in TermParameter::ALL {
                        let at = term.parameter_derivative(s, tp);
                        let below = term.parameter_derivative(s * (1.0 - 1e-12), tp);
                        let scale = 1.0 + at.0.abs().max(at.1.abs());
                        assert!(
                            (at.0 - below.0).abs() <= 1e-9 * scale
                                && (at.1 - below.1).abs() <= 1e-9 * scale,
                            "{set} {name:?} {tp:?} at {s}: {at:?} vs {below:?}"
                        );
                    }
                }
            }
        }
    }

    /// `I11` values: a grid over `(0.05, 1.2)` and points within `δ` of 1.
    fn i11_points() -> Vec<f64> {
        let mut out: Vec<f64> = (0..=46).map(|i| 0.05 + 0.025 * i as f64).collect();
        for delta in NEAR {
            out.extend([1.0 - delta, 1.0 + delta]);
        }
        out.push(1.0);
        out
    }

    /// `σ` of `k11` and `k11′`: `e^(−q)` is within `q ε` relative.
    fn coupling_scales(c: &Coupling, i11: f64) -> (f64, f64) {
        let v = c.eval(i11);
        let q = if i11 < 1.0 {
            c.s11 * (1.0 - i11).powf(c.e11)
        } else {
            0.0
        };
        (
            (v.k - c.k_min).abs() * (1.0 + q) + c.k_min.abs(),
            v.dk.abs() * (1.0 + q),
        )
    }

    fn coupling_with(c: &Coupling, p: CouplingParameter, v: f64) -> Coupling {
        let mut out = *c;
        match p {
            CouplingParameter::KMin => out.k_min = v,
            CouplingParameter::S11 => out.s11 = v,
            CouplingParameter::E11 => out.e11 = v,
        }
        out
    }

    #[test]
    fn coupling_derivatives_match_central_differences() {
        let mut checks = 0usize;
        for (set, law) in laws() {
            let coupling = law.coupling;
            for i11 in i11_points() {
                for cp in CouplingParameter::ALL {
                    let p0 = cp.value(&coupling);
                    let (dk, d_slope) = coupling.parameter_derivative(i11, cp);
                    if i11 >= 1.0 {
                        assert_eq!((dk, d_slope), (0.0, 0.0));
                    }
                    // The branch I11 < 1 does not depend on the parameters.
                    let h = step(p0, |_| true);
                    let value = |v: f64| {
                        let c = coupling_with(&coupling, cp, v);
                        (c.eval(i11).k, coupling_scales(&c, i11).0)
                    };
                    let slope = |v: f64| {
                        let c = coupling_with(&coupling, cp, v);
                        (c.eval(i11).dk, coupling_scales(&c, i11).1)
                    };
                    let context = format!("{set} {cp:?} I11 = {i11}");
                    check(dk, p0, h, &value).unwrap_or_else(|e| panic!("∂k: {context}: {e}"));
                    check(d_slope, p0, h, &slope).unwrap_or_else(|e| panic!("∂k′: {context}: {e}"));
                    checks += 2;
                }
            }
        }
        eprintln!("{checks} coupling derivative checks");
    }

    /// The invariants of `C = [I4, I8, I6]` in the fibre basis, if admissible.
    fn invariants(i4: f64, i6: f64, i8: f64) -> Option<Invariants> {
        Invariants::in_fibre_basis(&Sym2::new(i4, i8, i6)).ok()
    }

    /// `I8` giving `I11` at `(I4, I6)`: `I8 = I11² + I6²/I4`.
    fn i8_for(i4: f64, i6: f64, i11: f64) -> f64 {
        i11 * i11 + i6 * i6 / i4
    }

    fn top(term: &GeneralizedTerm) -> f64 {
        2.5 * switches(term)
            .into_iter()
            .filter(|s| *s < 5.0)
            .fold(0.05_f64, f64::max)
    }

    /// States for one law: random ones over every branch of every term and
    /// ones within `δ` of each switch (`x_t`, `I_lock`, `I4 = 1`, `I6 = 0`,
    /// `I8 = 1`, `I11 = 1`), including the kink bands.
    fn states(law: &UdNcf, rng: &mut Rng) -> Vec<Invariants> {
        let mut out = Vec::new();
        let (top4, top6) = (top(&law.w4).min(0.9), top(&law.w6).min(0.95));
        let (top8, top11) = (top(&law.w8), top(&law.w11).min(0.9));
        for n in 0..600 {
            let i4 = if rng.uniform() < 0.5 {
                1.0 + rng.range(0.0, top4)
            } else {
                1.0 - rng.range(0.0, top4)
            };
            let i6 = rng.range(-top6, top6);
            let i8 = if n % 2 == 0 {
                1.0 + rng.range(-0.2, top8)
            } else {
                i8_for(i4, i6, 1.0 - rng.range(-0.2, top11))
            };
            out.extend(invariants(i4, i6, i8));
        }
        let near = |s: f64| {
            let mut xs = Vec::new();
            for delta in NEAR {
                let d = delta * s.max(1e-2);
                xs.push(s + d);
                if s > d || s == 0.0 {
                    xs.push(s - d);
                }
            }
            xs
        };
        let with_zero = |term: &GeneralizedTerm| {
            let mut s = switches(term);
            s.push(0.0);
            s.into_iter().flat_map(near).collect::<Vec<_>>()
        };
        for x in with_zero(&law.w4) {
            out.extend(invariants(1.0 + x, 0.05, 1.01));
            out.extend(invariants(1.0 - x, 0.05, 1.01));
        }
        for x in with_zero(&law.w6) {
            out.extend(invariants(1.002, x, 1.013));
            out.extend(invariants(1.002, -x, 1.013));
        }
        for x in with_zero(&law.w8) {
            out.extend(invariants(1.001, 0.123, 1.0 + x));
            out.extend(invariants(0.983, -0.4, 1.0 + x));
        }
        for x in with_zero(&law.w11) {
            out.extend(invariants(1.001, 0.31, i8_for(1.001, 0.31, 1.0 - x)));
            out.extend(invariants(0.99, -0.05, i8_for(0.99, -0.05, 1.0 - x)));
        }
        // Inside the kink bands (within KINK_TOLERANCE of I8 = 1, I11 = 1).
        for k in [-40.0, -10.0, 0.0, 10.0, 40.0] {
            out.extend(invariants(1.0, 0.0, 1.0 + k * EPS));
            out.extend(invariants(1.01, 0.0, 1.0 + k * EPS));
            out.extend(invariants(1.0, 1e-9, 1.0 + k * EPS));
        }
        out
    }

    /// `σ` of each component of `g` at `inv`: the summands of
    /// `evaluate_invariants` (the terms' `f`, `k11 f8`, and the chain
    /// `(f11 + |k11′| G8)|∂I11/∂p_k|`), the coupling within `(1 + q) ε`.
    fn gradient_scales(law: &UdNcf, inv: &Invariants) -> [f64; 3] {
        let mut base = [
            stress_scale(&law.w4, (inv.i4 - 1.0).abs()),
            stress_scale(&law.w6, inv.i6.abs()),
            0.0,
        ];
        let mut chain = 0.0;
        if inv.i11 <= 1.0 + KINK_TOLERANCE {
            chain += stress_scale(&law.w11, (1.0 - inv.i11).max(0.0));
        }
        if inv.i8 >= 1.0 - KINK_TOLERANCE {
            let x8 = (inv.i8 - 1.0).max(0.0);
            let (k, dk) = coupling_scales(&law.coupling, inv.i11);
            base[2] = k * stress_scale(&law.w8, x8);
            chain += dk * energy_scale(&law.w8, x8);
        }
        let di11 = inv.i11_gradient();
        std::array::from_fn(|k| base[k] + chain * di11[k].abs())
    }

    /// Every reachable branch of every piece of the law occurs in `seen`.
    fn assert_covered(set: &str, law: &UdNcf, seen: &BTreeSet<Branches>) {
        let project = |f: &dyn Fn(&Branches) -> Option<TermBranch>| -> BTreeSet<TermBranch> {
            seen.iter().filter_map(f).collect()
        };
        assert_eq!(project(&|b| Some(b.w4)), reachable(&law.w4), "{set} w4");
        assert_eq!(project(&|b| Some(b.w6)), reachable(&law.w6), "{set} w6");
        assert_eq!(project(&|b| b.w8), reachable(&law.w8), "{set} w8");
        // W11 acts on x = 1 − I11 < 1: a lock at or beyond 1 never engages.
        let mut w11 = reachable(&law.w11);
        if law.w11.lock.is_some_and(|l| l.i_lock >= 1.0) {
            w11.retain(|b| matches!(b, TermBranch::Initial | TermBranch::Middle));
        }
        assert_eq!(project(&|b| b.w11), w11, "{set} w11");
        for f in [
            |b: &Branches| b.roving_tension,
            |b: &Branches| b.positive_shear,
            |b: &Branches| b.w8.is_some(),
            |b: &Branches| b.w11.is_some(),
        ] {
            assert_eq!(
                seen.iter().map(f).collect::<BTreeSet<_>>().len(),
                2,
                "{set}"
            );
        }
    }

    #[test]
    fn gradient_derivatives_match_central_differences_at_every_branch_and_switch() {
        let mut rng = Rng(0x5eed_0002);
        let mut checks = 0usize;
        for (set, law) in laws() {
            let params = LawParameter::of_law(&law);
            let mut seen = BTreeSet::new();
            for inv in states(&law, &mut rng) {
                let branches = law.branches(&inv);
                seen.insert(branches);
                for p in LawParameter::all() {
                    let analytic = law.gradient_parameter_derivative(&inv, p);
                    if !params.contains(&p) {
                        assert_eq!(analytic, [0.0; 3], "{set} {p}");
                        continue;
                    }
                    let p0 = p.value(&law).expect("the law has it");
                    let at = |v: f64| p.with_value(&law, v).expect("the law has it");
                    let h = step(p0, |v| at(v).branches(&inv) == branches);
                    for (k, &a) in analytic.iter().enumerate() {
                        let value = |v: f64| {
                            let l = at(v);
                            (
                                l.evaluate_invariants(inv, false).gradient[k],
                                gradient_scales(&l, &inv)[k],
                            )
                        };
                        check(a, p0, h, &value).unwrap_or_else(|e| {
                            panic!("{set} ∂g{k}/∂{p} at {inv:?} ({branches:?}): {e}")
                        });
                        checks += 1;
                    }
                }
            }
            assert_covered(&set, &law, &seen);
        }
        eprintln!("{checks} gradient derivative checks");
    }

    #[test]
    fn stress_derivatives_are_the_gradient_derivatives_mapped_and_match_differences() {
        let mut rng = Rng(0x5eed_0003);
        for (set, law) in laws() {
            let params = LawParameter::of_law(&law);
            let mut batch = vec![Sym2::zeros(); params.len()];
            for n in 0..60 {
                let frame = FibreFrame::from_angle(0.37 * n as f64);
                // C = Fᵀ F for a random F near the identity.
                let f = nalgebra::Matrix2::new(
                    1.0 + rng.range(-0.3, 0.3),
                    rng.range(-0.6, 0.6),
                    rng.range(-0.6, 0.6),
                    1.0 + rng.range(-0.3, 0.3),
                );
                let cm = f.transpose() * f;
                let c = Sym2::new(cm[(0, 0)], cm[(1, 1)], cm[(0, 1)]);
                let Ok(inv) = Invariants::new(&c, &frame) else {
                    continue;
                };
                let branches = law.branches(&inv);
                law.stress_parameter_derivatives(&c, &frame, &params, &mut batch)
                    .expect("admissible state");
                for (&p, batch_ds) in params.iter().zip(&batch) {
                    let ds = law
                        .stress_parameter_derivative(&c, &frame, p)
                        .expect("admissible state");
                    let mapped =
                        stress_from_gradient(&law.gradient_parameter_derivative(&inv, p), &frame);
                    assert_eq!(ds, mapped, "{set} {p}");
                    assert_eq!(&ds, batch_ds, "{set} {p}: batch");
                    // Against the law's own stress, S = 2 Σ g_k N_k.
                    let p0 = p.value(&law).expect("the law has it");
                    let at = |v: f64| p.with_value(&law, v).expect("the law has it");
                    let h = step(p0, |v| {
                        at(v).branches(&Invariants::new(&c, &frame).expect("admissible"))
                            == branches
                    });
                    for j in 0..3 {
                        let value = |v: f64| {
                            let l = at(v);
                            let scales = gradient_scales(&l, &inv);
                            let n = frame.structural();
                            let scale =
                                2.0 * (0..3).map(|k| scales[k] * n[k][j].abs()).sum::<f64>();
                            (l.stress(&c, &frame).expect("admissible").stress[j], scale)
                        };
                        check(ds[j], p0, h, &value)
                            .unwrap_or_else(|e| panic!("{set} ∂S{j}/∂{p}: {e}"));
                    }
                }
            }
        }
    }

    #[test]
    fn stress_derivatives_reject_degenerate_states() {
        let law = law_of(&MaterialSpec::default_set());
        let frame = FibreFrame::from_angle(0.3);
        let p = LawParameter::Term(TermName::W6, TermParameter::SIni);
        let mut out = [Sym2::zeros(); 1];
        for (c, expected) in [
            (
                Sym2::new(1.0, 1.0, 1.0),
                MaterialError::NonPositiveDeterminant { det: 0.0 },
            ),
            (Sym2::new(f64::NAN, 1.0, 0.0), MaterialError::NonFinite),
        ] {
            assert_eq!(
                law.stress_parameter_derivative(&c, &frame, p),
                Err(expected)
            );
            assert_eq!(
                law.stress_parameter_derivatives(&c, &frame, &[p], &mut out),
                Err(expected)
            );
        }
        // Unequal lengths: the pairs are zipped, nothing panics.
        let c = Sym2::new(1.1, 0.9, 0.2);
        let mut long = [Sym2::new(7.0, 7.0, 7.0); 3];
        law.stress_parameter_derivatives(&c, &frame, &[p], &mut long)
            .expect("admissible");
        assert_eq!(long[1], Sym2::new(7.0, 7.0, 7.0));
        law.stress_parameter_derivatives(&c, &frame, &[p, p, p], &mut out[..0])
            .expect("admissible");
    }

    #[test]
    fn keys_and_values_follow_the_parameter_file() {
        for (set, law) in laws() {
            let spec_values: Vec<(String, f64)> = MaterialSpec {
                name: set.clone(),
                description: String::new(),
                source: set.clone(),
                material: Material::UdNcf(law),
            }
            .parameter_values();
            let ours: Vec<(String, f64)> = LawParameter::of_law(&law)
                .into_iter()
                .map(|p| (p.key(), p.value(&law).expect("of_law lists present ones")))
                .collect();
            assert_eq!(ours, spec_values, "{set}");
        }
        assert_eq!(LawParameter::all().count(), 27);
        for p in LawParameter::all() {
            assert_eq!(LawParameter::from_key(&p.key()), Some(p));
            assert_eq!(p.to_string(), p.key());
        }
        assert_eq!(
            LawParameter::from_key("w8.delta_s_mid"),
            Some(LawParameter::Term(TermName::W8, TermParameter::DeltaSMid))
        );
        assert_eq!(
            LawParameter::from_key("coupling.e11"),
            Some(LawParameter::Coupling(CouplingParameter::E11))
        );
        for bad in [
            "",
            "w6",
            "w6.",
            "w5.c_ini",
            "coupling.c_ini",
            "svk.e1",
            "w6.k_min",
        ] {
            assert_eq!(LawParameter::from_key(bad), None, "{bad}");
        }
        let law = law_of(&MaterialSpec::default_set());
        let w6_lock = LawParameter::Term(TermName::W6, TermParameter::CLock);
        assert_eq!(w6_lock.value(&law), None);
        assert_eq!(w6_lock.with_value(&law, 1.0), None);
        let w4_s = LawParameter::Term(TermName::W4, TermParameter::SIni);
        assert_eq!(w4_s.value(&law), None);
        assert_eq!(
            LawParameter::Term(TermName::W11, TermParameter::ILock).value(&law),
            Some(0.4)
        );
    }

    /// The middle-branch points of the shipped W6 at distance from `x_t`.
    fn middle_points(term: &GeneralizedTerm) -> Vec<f64> {
        (1..=40)
            .map(|i| term.transition_point() * (1.0 + 0.05 * i as f64))
            .collect()
    }

    #[test]
    fn the_checker_refuses_a_derivative_that_forgets_the_move_of_x_t() {
        let law = law_of(&MaterialSpec::default_set());
        for term in [law.w6, law.w8, law.w11] {
            let t = term.transition.expect("a transition");
            let (s0, c0) = (t.s_ini, term.c_ini);
            let m = t.c_mid / term.c_ini;
            for x in middle_points(&term) {
                let y = x - term.transition_point();
                let z = term.rate() * y;
                let decay = (-z).exp();
                // With x_t held fixed: ∂f/∂S_ini = 1, and ∂f/∂C_ini only
                // through c (y in place of x, no m x_t E1 term).
                let wrong_s = 1.0;
                let wrong_c = (1.0 + m * z) * decay * y;
                for (tp, p0, wrong) in [
                    (TermParameter::SIni, s0, wrong_s),
                    (TermParameter::CIni, c0, wrong_c),
                ] {
                    let at = |v: f64| tp.with_value(&term, v).expect("present");
                    let h = step(p0, |v| at(v).branch(x) == term.branch(x));
                    let stress = |v: f64| {
                        let t = at(v);
                        (t.eval(x).stress, stress_scale(&t, x))
                    };
                    let right = term.parameter_derivative(x, tp).1;
                    assert!(check(right, p0, h, &stress).is_ok());
                    assert!(
                        check(wrong, p0, h, &stress).is_err(),
                        "{tp:?} x = {x}: the wrong derivative {wrong} (right {right}) passes"
                    );
                }
            }
        }
    }

    #[test]
    fn the_checker_refuses_a_wrong_coupling_slope_and_a_missing_chain_rule() {
        for (set, law) in laws() {
            let c = law.coupling;
            let p0 = c.e11;
            for i11 in (1..=36).map(|i| 0.05 + 0.025 * i as f64) {
                // ∂k′/∂e11 without the `1 +` of s11 u^(e11−1) (1 + e11 ln u).
                let u = 1.0 - i11;
                let q = c.s11 * u.powf(c.e11);
                let dq = c.s11 * c.e11 * u.powf(c.e11 - 1.0);
                let scaled = (1.0 - c.k_min) * (-q).exp();
                let ln_u = u.ln();
                let wrong = scaled * (c.s11 * u.powf(c.e11 - 1.0) * c.e11 * ln_u - dq * q * ln_u);
                let slope = |v: f64| {
                    let cv = coupling_with(&c, CouplingParameter::E11, v);
                    (cv.eval(i11).dk, coupling_scales(&cv, i11).1)
                };
                let h = step(p0, |_| true);
                let right = c.parameter_derivative(i11, CouplingParameter::E11).1;
                assert!(check(right, p0, h, &slope).is_ok(), "{set} I11 = {i11}");
                assert!(check(wrong, p0, h, &slope).is_err(), "{set} I11 = {i11}");
            }
            // ∂g4/∂C_ini of W8 without the chain through I11: zero, while W8's
            // energy moves W_,11 = k11′ G8 wherever I11 < 1 and I8 > 1.
            let p = LawParameter::Term(TermName::W8, TermParameter::CIni);
            let p0 = p.value(&law).expect("present");
            let mut refused = 0;
            for (i6, i11) in [(0.3, 0.99), (0.5, 0.95), (0.6, 0.9), (0.45, 0.97)] {
                let inv = invariants(1.001, i6, i8_for(1.001, i6, i11)).expect("admissible");
                let at = |v: f64| p.with_value(&law, v).expect("present");
                let h = step(p0, |v| at(v).branches(&inv) == law.branches(&inv));
                let g4 = |v: f64| {
                    let l = at(v);
                    (
                        l.evaluate_invariants(inv, false).gradient[0],
                        gradient_scales(&l, &inv)[0],
                    )
                };
                let right = law.gradient_parameter_derivative(&inv, p)[0];
                assert!(check(right, p0, h, &g4).is_ok(), "{set}");
                if check(0.0, p0, h, &g4).is_err() {
                    refused += 1;
                }
            }
            assert_eq!(
                refused, 4,
                "{set}: the gradient without the chain rule passes"
            );
        }
    }

    #[test]
    fn lower_gamma3_matches_its_closed_form_and_its_integral() {
        for i in 1..=400 {
            let z = i as f64 * 0.01;
            let (decay, e1) = decay_pair(z);
            let e2 = one_minus_decay_times_one_plus(z, decay, e1);
            let series_or_closed = lower_gamma3(z, decay, e2);
            let closed = 2.0 - (-z).exp() * (z * z + 2.0 * z + 2.0);
            // The closed form loses about 2ε/γ(3, z) ≈ 6ε/z³ absolute.
            assert!(
                (series_or_closed - closed).abs() <= 8.0 * EPS * (1.0 + 6.0 / (z * z * z)),
                "z = {z}: {series_or_closed} vs {closed}"
            );
        }
        // The two forms agree at the switch z = 1 to round-off.
        let below = 1.0 - 1e-15;
        let (d, e1) = decay_pair(below);
        let e2 = one_minus_decay_times_one_plus(below, d, e1);
        let (d1, e11) = decay_pair(1.0);
        let e21 = one_minus_decay_times_one_plus(1.0, d1, e11);
        assert!((lower_gamma3(below, d, e2) - lower_gamma3(1.0, d1, e21)).abs() < 1e-14);
        // Small z: z³/3 − z⁴/4 + z⁵/10 to relative ε.
        let z: f64 = 1e-6;
        let (d, e1) = decay_pair(z);
        let e2 = one_minus_decay_times_one_plus(z, d, e1);
        let expected = z * z * z / 3.0 - z.powi(4) / 4.0 + z.powi(5) / 10.0;
        assert!((lower_gamma3(z, d, e2) - expected).abs() <= 4.0 * EPS * expected);
    }
}
