//! Tests of the material layer: the UD-NCF law (docs/theory.md, paper Eq. 3–16 with
//! the errata of docs/theory.md), the SVK cross-check law, parameter files
//! and the `material` commands. Each test names the requirement it checks.

// Tensor identities read best in index notation.
#![allow(clippy::needless_range_loop)]

use std::collections::BTreeSet;

use ncform::cli::{material_curves, material_eval};
use ncform::material::diagnostics::{
    FdCheck, SampleRanges, StateSampler, branches_at, c_from_invariants, fd_check,
    stencil_on_one_branch,
};
use ncform::material::params::ParamsError;
use ncform::material::{
    FibreFrame, Invariants, Material, MaterialError, MaterialSpec, MembraneMaterial, StressState,
    Sym2, Tangent, TermBranch, UdNcf,
};

use ncform::material::diagnostics::{BALANCED_TEST_SET as BALANCED, SVK_TEST_SET as SVK};

fn balanced() -> MaterialSpec {
    MaterialSpec::from_toml_str(BALANCED, "balanced-test").expect("valid test set")
}

fn udncf(spec: &MaterialSpec) -> UdNcf {
    match spec.material {
        Material::UdNcf(law) => law,
        Material::OrthotropicSvk(_) => panic!("not a UD-NCF set"),
    }
}

fn all_sets() -> Vec<MaterialSpec> {
    vec![
        MaterialSpec::named("schaefer2024").unwrap(),
        MaterialSpec::named("schaefer2024-printed").unwrap(),
        balanced(),
        MaterialSpec::from_toml_str(SVK, "svk-test").unwrap(),
    ]
}

/// Requirement: S = 2∂W/∂C and ℂ = 2∂S/∂C agree with finite
/// differences, within the bound derived from the step size
/// (`ncform::material::diagnostics`), at ≥ 10,000 random states per set that
/// cover every branch of every term, both signs of I4 − 1 and I6, I8 ≷ 1,
/// I11 ≷ 1, and fibre angles over [0°, 180°).
#[test]
fn stress_and_tangent_match_finite_differences_on_every_branch() {
    const STATES: usize = 10_000;
    for (set_index, spec) in all_sets().iter().enumerate() {
        let mut sampler = StateSampler::new(20241 + set_index as u64, SampleRanges::default());
        let mut checked = 0;
        let mut straddling = 0;
        let mut seen: BTreeSet<String> = BTreeSet::new();
        let (mut min_angle, mut max_angle) = (f64::INFINITY, f64::NEG_INFINITY);
        let mut worst: Option<(f64, FdCheck)> = None;
        while checked < STATES {
            let (c, angle) = sampler.sample();
            let d = sampler.direction();
            let frame = FibreFrame::from_angle(angle);
            if !stencil_on_one_branch(&spec.material, &c, &frame, &d) {
                straddling += 1;
                continue;
            }
            let check = fd_check(&spec.material, &c, &frame, &d).expect("admissible state");
            assert!(
                check.passed(),
                "{}: finite-difference check failed at C = {c:?}, angle = {angle}, D = {d:?}: {check:?}",
                spec.name
            );
            let ratio = (check.stress_error / check.stress_tolerance)
                .max(check.tangent_error / check.tangent_tolerance);
            if worst.is_none_or(|(r, _)| ratio > r) {
                worst = Some((ratio, check));
            }
            if let Some(b) = branches_at(&spec.material, &c, &frame) {
                seen.insert(format!("I4>=1:{}", b.roving_tension));
                seen.insert(format!("I6>=0:{}", b.positive_shear));
                seen.insert(format!("w4:{:?}", b.w4));
                seen.insert(format!("w6:{:?}", b.w6));
                seen.insert(format!("w8:{:?}", b.w8));
                seen.insert(format!("w11:{:?}", b.w11));
            }
            min_angle = min_angle.min(angle.to_degrees());
            max_angle = max_angle.max(angle.to_degrees());
            checked += 1;
        }
        // Stencils across a kink are rare: a few per cent at most.
        assert!(
            straddling < STATES / 20,
            "{}: {straddling} straddling stencils",
            spec.name
        );
        assert!(
            min_angle < 2.0 && max_angle > 178.0,
            "angles {min_angle}..{max_angle}"
        );
        let expected: &[&str] = match spec.name.as_str() {
            "schaefer2024" => &[
                "I4>=1:true",
                "I4>=1:false",
                "I6>=0:true",
                "I6>=0:false",
                "w4:Initial",
                "w6:Initial",
                "w6:Middle",
                "w8:None",
                "w8:Some(Initial)",
                "w8:Some(Middle)",
                "w11:None",
                "w11:Some(Initial)",
                "w11:Some(Middle)",
                "w11:Some(MiddleLocked)",
            ],
            "schaefer2024-printed" => &[
                "I4>=1:true",
                "I4>=1:false",
                "I6>=0:true",
                "I6>=0:false",
                "w4:Initial",
                "w6:Initial",
                "w6:Middle",
                "w8:None",
                "w8:Some(Initial)",
                "w8:Some(Middle)",
                "w11:None",
                "w11:Some(Initial)",
                "w11:Some(Middle)",
            ],
            "balanced-test" => &[
                "I4>=1:true",
                "I4>=1:false",
                "I6>=0:true",
                "I6>=0:false",
                "w4:Initial",
                "w4:Middle",
                "w4:MiddleLocked",
                "w6:Initial",
                "w6:Middle",
                "w6:MiddleLocked",
                "w8:None",
                "w8:Some(Initial)",
                "w8:Some(Middle)",
                "w8:Some(MiddleLocked)",
                "w11:None",
                "w11:Some(Initial)",
                "w11:Some(Middle)",
                "w11:Some(MiddleLocked)",
            ],
            _ => &[],
        };
        for branch in expected {
            assert!(
                seen.contains(*branch),
                "{}: branch {branch} never sampled; saw {seen:?}",
                spec.name
            );
        }
        eprintln!(
            "{}: {checked} states checked, {straddling} straddling stencils skipped, worst error/tolerance {:.3e}",
            spec.name,
            worst.map(|w| w.0).unwrap_or(0.0)
        );
    }
}

/// A law whose stress or tangent is off by a relative 1e-6.
struct Perturbed {
    law: Material,
    stress_factor: f64,
    tangent_factor: f64,
}

impl MembraneMaterial for Perturbed {
    fn stress(&self, c: &Sym2, frame: &FibreFrame) -> Result<StressState, MaterialError> {
        let mut s = self.law.stress(c, frame)?;
        s.stress *= self.stress_factor;
        Ok(s)
    }
    fn stress_tangent(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
    ) -> Result<(StressState, Tangent), MaterialError> {
        let (mut s, t) = self.law.stress_tangent(c, frame)?;
        s.stress *= self.stress_factor;
        Ok((s, t * self.tangent_factor))
    }
}

/// Requirement: the finite-difference check can fail — it detects a stress
/// or a tangent that is wrong by a relative 1e-6, far below any real
/// derivative error.
#[test]
fn finite_difference_check_detects_a_wrong_derivative() {
    let law = balanced().material;
    for (stress_factor, tangent_factor) in [(1.0 + 1e-6, 1.0), (1.0, 1.0 + 1e-6)] {
        let wrong = Perturbed {
            law,
            stress_factor,
            tangent_factor,
        };
        let mut sampler = StateSampler::new(7, SampleRanges::default());
        let mut caught = 0;
        for _ in 0..200 {
            let (c, angle) = sampler.sample();
            let d = sampler.direction();
            let frame = FibreFrame::from_angle(angle);
            if !fd_check(&wrong, &c, &frame, &d).unwrap().passed() {
                caught += 1;
            }
        }
        // Only states where ½S:D or ½ℂ:D is nearly zero can escape.
        assert!(
            caught >= 190,
            "caught only {caught}/200 (factors {stress_factor}, {tangent_factor})"
        );
    }
}

fn rel_close(a: f64, b: f64, tol: f64, scale: f64) -> bool {
    (a - b).abs() <= tol * scale
}

/// Requirement (docs/verification.md): roving slip `F = I + g a0⊗b0` with
/// `a0 = e1` gives `I4 = 1`, `I6 = g`, `I8 = 1 + g²`, `I11 = 1`, and by hand
/// (docs/theory.md) `W = G6(|g|) + G8(g²)`, `S11 = 0`,
/// `S12 = sgn(g) f6(|g|)`, `S22 = 2 f8(g²)`. Tolerance 1e-12 relative: the
/// code and the formula differ only by round-off in I11 = sqrt(I8 − I6²/I4).
#[test]
fn roving_slip_matches_hand_derivation() {
    for spec in [MaterialSpec::default_set(), balanced()] {
        let law = udncf(&spec);
        for &g in &[-0.6, -0.25, -0.05, 0.01, 0.1, 0.3, 0.7] {
            let c = Sym2::new(1.0, 1.0 + g * g, g);
            let frame = FibreFrame::from_angle(0.0);
            let inv = Invariants::new(&c, &frame).unwrap();
            assert_eq!((inv.i4, inv.i6, inv.i8), (1.0, g, 1.0 + g * g));
            assert!((inv.i11 - 1.0).abs() <= 4.0 * f64::EPSILON);
            let f6 = law.w6.eval(g.abs());
            let f8 = law.w8.eval(g * g);
            let w = f6.energy + f8.energy;
            let s_hand = Sym2::new(0.0, 2.0 * f8.stress, f6.stress.copysign(g));
            let state = law.stress(&c, &frame).unwrap();
            let scale = s_hand.norm();
            assert!(
                rel_close(state.energy, w, 1e-12, w),
                "{}: W at g = {g}",
                spec.name
            );
            for k in 0..3 {
                assert!(
                    rel_close(state.stress[k], s_hand[k], 1e-12, scale),
                    "{}: S[{k}] at g = {g}: {} vs {}",
                    spec.name,
                    state.stress[k],
                    s_hand[k]
                );
            }
        }
    }
}

/// Requirement (docs/verification.md): trellis shear by γ with `a0 = e1` gives
/// `C = [[1, sin γ], [sin γ, 1]]`, `I6 = sin γ`, `I8 = 1`, `I11 = cos γ`,
/// `I10 = γ`; by hand `W = G6(|s|) + G11(1 − cos γ)`, and with
/// `f11 = f11(1 − cos γ)`: `S11 = −f11 s²/cos γ`, `S22 = −f11/cos γ`,
/// `S12 = sgn(s) f6(|s|) + f11 s/cos γ`. Tolerance 1e-12 relative.
#[test]
fn trellis_shear_matches_hand_derivation() {
    for spec in [
        MaterialSpec::default_set(),
        MaterialSpec::named("schaefer2024-printed").unwrap(),
        balanced(),
    ] {
        let law = udncf(&spec);
        for &gamma_deg in &[-60.0_f64, -35.0, -5.0, 3.0, 20.0, 45.0, 58.0, 64.0] {
            let gamma = gamma_deg.to_radians();
            let (s, cg) = gamma.sin_cos();
            let c = Sym2::new(1.0, 1.0, s);
            let frame = FibreFrame::from_angle(0.0);
            let inv = Invariants::new(&c, &frame).unwrap();
            assert!(rel_close(inv.i11, cg, 1e-14, 1.0));
            assert!(
                rel_close(inv.i10(), gamma, 1e-12, 1.0),
                "I10 {} vs {gamma}",
                inv.i10()
            );
            let f6 = law.w6.eval(s.abs());
            let f11 = law.w11.eval(1.0 - cg);
            let w = f6.energy + f11.energy;
            let s_hand = Sym2::new(
                -f11.stress * s * s / cg,
                -f11.stress / cg,
                f6.stress.copysign(s) + f11.stress * s / cg,
            );
            let state = law.stress(&c, &frame).unwrap();
            assert!(
                rel_close(state.energy, w, 1e-12, w),
                "{}: W at {gamma_deg}°",
                spec.name
            );
            for k in 0..3 {
                assert!(
                    rel_close(state.stress[k], s_hand[k], 1e-12, s_hand.norm()),
                    "{}: S[{k}] at {gamma_deg}°: {} vs {}",
                    spec.name,
                    state.stress[k],
                    s_hand[k]
                );
            }
        }
    }
}

/// Requirement (docs/theory.md, Eq. 12): f is C¹ at x_t (by the choice of x_t and
/// c) and at I_lock, and G is continuous there. Compared: the two one-sided
/// values at the boundary, to 1e-12 relative (exact in real arithmetic).
#[test]
fn generalized_function_is_c1_at_transition_and_lock() {
    let mut boundaries = 0;
    for spec in [
        MaterialSpec::default_set(),
        MaterialSpec::named("schaefer2024-printed").unwrap(),
        balanced(),
    ] {
        let law = udncf(&spec);
        for term in [law.w4, law.w6, law.w8, law.w11] {
            let mut points = vec![];
            if term.transition.is_some() {
                points.push(term.transition_point());
            }
            if let Some(lock) = term.lock {
                points.push(lock.i_lock);
            }
            for x in points {
                let below = term.eval(x * (1.0 - 1e-15) - 1e-300);
                let at = term.eval(x);
                assert_ne!(term.branch(x * (1.0 - 1e-15) - 1e-300), term.branch(x));
                // Over one ulp-sized step the smooth parts move by f′·δx.
                let dx = x * 1e-15 + 1e-300;
                let tol = |v: f64| 1e-12 * v.abs().max(term.c_ini * x.max(1e-3));
                assert!(
                    (at.stress - below.stress).abs()
                        <= tol(at.stress) + at.modulus.abs() * dx * 2.0
                );
                assert!(
                    (at.modulus - below.modulus).abs() <= 1e-12 * at.modulus.abs().max(term.c_ini)
                );
                assert!(
                    (at.energy - below.energy).abs() <= tol(at.energy) + at.stress.abs() * dx * 2.0
                );
                boundaries += 1;
            }
        }
    }
    assert!(boundaries >= 10, "only {boundaries} boundaries checked");
}

/// Requirement: zero energy and zero stress in the reference state C = I,
/// for any fibre angle.
#[test]
fn reference_state_is_stress_free() {
    for spec in all_sets() {
        for k in 0..36 {
            let frame = FibreFrame::from_angle((5.0 * k as f64).to_radians());
            let state = spec
                .material
                .stress(&Sym2::new(1.0, 1.0, 0.0), &frame)
                .unwrap();
            assert!(
                state.energy.abs() <= 1e-15,
                "{}: W = {}",
                spec.name,
                state.energy
            );
            assert!(
                state.stress.norm() <= 1e-12,
                "{}: S = {:?}",
                spec.name,
                state.stress
            );
        }
    }
}

fn full(t: &Tangent) -> [[[[f64; 2]; 2]; 2]; 2] {
    material_eval::tangent_tensor(t)
}

fn to_matrix(s: &Sym2) -> [[f64; 2]; 2] {
    [[s[0], s[2]], [s[2], s[1]]]
}

/// Requirement: invariance under a rotation of the reference frame together
/// with the fibre: `W(Q C Qᵀ, Q a0) = W(C, a0)`, `S′ = Q S Qᵀ`,
/// `ℂ′_ijkl = Q_ip Q_jq Q_kr Q_ls ℂ_pqrs`. Tolerances: rotating `C` rounds
/// it by a few ulps, `δC ≈ 16 u |C|`, which moves `S` by up to `|ℂ| δC` and
/// `ℂ` by up to `|∂ℂ/∂C| δC`; with the 1000 MPa roving modulus that exceeds
/// 1e-12 |S|. So S is held to `1e-12 |S| + 16 u |C| |ℂ|`, and ℂ to
/// `1e-12 |ℂ| + 16 u |C| |ℂ| / min(x_t)`, `x_t ≥ 0.02` being the shortest
/// scale on which the named sets' moduli change.
#[test]
fn response_is_invariant_under_rotation_of_frame_and_fibre() {
    for spec in all_sets() {
        let mut sampler = StateSampler::new(99, SampleRanges::default());
        for _ in 0..300 {
            let (c, angle) = sampler.sample();
            let phi: f64 = 0.4 + angle * 1.7;
            let (sp, cp) = phi.sin_cos();
            let q = [[cp, -sp], [sp, cp]];
            let cm = to_matrix(&c);
            let mut rc = [[0.0; 2]; 2];
            for i in 0..2 {
                for j in 0..2 {
                    for p in 0..2 {
                        for r in 0..2 {
                            rc[i][j] += q[i][p] * q[j][r] * cm[p][r];
                        }
                    }
                }
            }
            let c_rot = Sym2::new(rc[0][0], rc[1][1], 0.5 * (rc[0][1] + rc[1][0]));
            let (s0, t0) = spec
                .material
                .stress_tangent(&c, &FibreFrame::from_angle(angle))
                .unwrap();
            let (s1, t1) = spec
                .material
                .stress_tangent(&c_rot, &FibreFrame::from_angle(angle + phi))
                .unwrap();
            assert!(rel_close(
                s0.energy,
                s1.energy,
                1e-12,
                s0.energy.abs().max(1e-300)
            ));
            let (sm0, sm1) = (to_matrix(&s0.stress), to_matrix(&s1.stress));
            let rounding = 16.0 * f64::EPSILON * c.norm() * t0.norm();
            let s_scale = s0.stress.norm() + rounding * 1e12;
            let (f0, f1) = (full(&t0), full(&t1));
            let t_scale = t0.norm() + rounding / 0.02 * 1e12;
            for i in 0..2 {
                for j in 0..2 {
                    let mut expected = 0.0;
                    for p in 0..2 {
                        for r in 0..2 {
                            expected += q[i][p] * q[j][r] * sm0[p][r];
                        }
                    }
                    assert!(
                        rel_close(sm1[i][j], expected, 1e-12, s_scale),
                        "{}: S{i}{j} {} vs {expected} (|S| {s_scale}, C {c:?}, angle {angle})",
                        spec.name,
                        sm1[i][j]
                    );
                    for k in 0..2 {
                        for l in 0..2 {
                            let mut expected = 0.0;
                            for p in 0..2 {
                                for r in 0..2 {
                                    for s in 0..2 {
                                        for t in 0..2 {
                                            expected += q[i][p]
                                                * q[j][r]
                                                * q[k][s]
                                                * q[l][t]
                                                * f0[p][r][s][t];
                                        }
                                    }
                                }
                            }
                            assert!(
                                rel_close(f1[i][j][k][l], expected, 1e-12, t_scale),
                                "{}: C",
                                spec.name
                            );
                        }
                    }
                }
            }
        }
    }
}

/// Requirement: ℂ has major (ℂ_ijkl = ℂ_klij) and minor
/// (ℂ_ijkl = ℂ_jikl = ℂ_ijlk) symmetry. Major symmetry is checked on the
/// computed Voigt matrix to 1e-14 relative (round-off of one product);
/// minor symmetry on the 2×2×2×2 array the CLI writes.
#[test]
fn tangent_has_major_and_minor_symmetry() {
    for spec in all_sets() {
        let mut sampler = StateSampler::new(5, SampleRanges::default());
        for _ in 0..1000 {
            let (c, angle) = sampler.sample();
            let (_, t) = spec
                .material
                .stress_tangent(&c, &FibreFrame::from_angle(angle))
                .unwrap();
            let scale = t.norm();
            for a in 0..3 {
                for b in 0..3 {
                    assert!(
                        (t[(a, b)] - t[(b, a)]).abs() <= 1e-14 * scale,
                        "{}: major",
                        spec.name
                    );
                }
            }
            let f = full(&t);
            for i in 0..2 {
                for j in 0..2 {
                    for k in 0..2 {
                        for l in 0..2 {
                            assert_eq!(f[i][j][k][l], f[j][i][k][l]);
                            assert_eq!(f[i][j][k][l], f[i][j][l][k]);
                            assert!((f[i][j][k][l] - f[k][l][i][j]).abs() <= 1e-14 * scale);
                        }
                    }
                }
            }
        }
    }
}

/// Requirement (docs/theory.md): det C ≤ 0 or I4 ≤ 0 (inverted or collapsed
/// element) and non-finite C are errors, never NaN; nearly degenerate but
/// admissible states give finite values.
#[test]
fn degenerate_states_are_errors_not_nan() {
    let frame = FibreFrame::from_angle(0.3);
    for spec in all_sets() {
        let m = &spec.material;
        assert!(matches!(
            m.stress(&Sym2::new(1.0, 1.0, 1.0), &frame),
            Err(MaterialError::NonPositiveDeterminant { .. })
        ));
        assert!(matches!(
            m.stress_tangent(&Sym2::new(1.0, 1.0, 2.0), &frame),
            Err(MaterialError::NonPositiveDeterminant { .. })
        ));
        assert!(matches!(
            m.stress(&Sym2::new(-1.0, 1.0, 0.0), &FibreFrame::from_angle(0.0)),
            Err(MaterialError::CollapsedRovings { .. })
        ));
        assert!(matches!(
            m.stress(&Sym2::new(0.0, 0.0, 0.0), &frame),
            Err(MaterialError::CollapsedRovings { .. })
        ));
        assert!(matches!(
            m.stress(&Sym2::new(f64::NAN, 1.0, 0.0), &frame),
            Err(MaterialError::NonFinite)
        ));
        assert!(matches!(
            m.energy(&Sym2::new(1.0, f64::INFINITY, 0.0), &frame),
            Err(MaterialError::NonFinite)
        ));
        for det in [1e-6, 1e-10, 1e-14] {
            let c = c_from_invariants(1.0, 0.8, 0.64 + det, 0.3);
            if let Ok((s, t)) = m.stress_tangent(&c, &frame) {
                assert!(s.energy.is_finite() && s.stress.iter().all(|v| v.is_finite()));
                assert!(t.iter().all(|v| v.is_finite()));
            }
        }
    }
}

fn invalid(text: &str) -> String {
    let err = MaterialSpec::from_toml_str(text, "user.toml").expect_err("must be rejected");
    err.to_string()
}

fn default_with(replace: &str, with: &str) -> String {
    let text = MaterialSpec::named_text("schaefer2024").unwrap();
    assert!(text.contains(replace), "fixture: {replace}");
    text.replacen(replace, with, 1)
}

/// Requirement: unknown keys, missing keys and values
/// outside their physical range are rejected with a message naming the file,
/// the key, the value and the allowed range.
#[test]
fn bad_parameter_files_are_rejected_with_file_key_value_and_range() {
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            default_with("c_ini = 0.14", "c_ini = -0.14"),
            vec!["user.toml:", "w6.c_ini", "-0.14", "> 0"],
        ),
        (
            default_with("k_min = 0.4", "k_min = 1.5"),
            vec!["user.toml:", "coupling.k_min", "1.5", "[0, 1]"],
        ),
        (
            default_with("e11 = 2.0", "e11 = 0.5"),
            vec!["user.toml:", "coupling.e11", "0.5", "≥ 1"],
        ),
        (
            default_with("s11 = 10.0", "s11 = -1.0"),
            vec!["coupling.s11", "-1", "≥ 0"],
        ),
        (
            default_with("c_mid = 0.01\n", ""),
            vec![
                "user.toml:",
                "w6.c_mid",
                "missing",
                "s_ini, c_mid and delta_s_mid",
            ],
        ),
        (
            default_with("i_lock = 0.4\n", ""),
            vec!["user.toml:", "w11.i_lock", "c_lock and i_lock"],
        ),
        (
            default_with("c_mid = 0.03", "c_mid = nan"),
            vec!["w8.c_mid", "= nan"],
        ),
        (
            default_with("delta_s_mid = 0.02", "delta_s_mid = 0.0"),
            vec!["w8.delta_s_mid", "> 0"],
        ),
        (
            default_with("c_ini = 1.1", "c_ini = 1.1\nstiffness = 3.0"),
            vec!["user.toml", "unknown field", "stiffness"],
        ),
        (
            default_with("[coupling]\nk_min = 0.4\n", "[coupling]\n"),
            vec!["user.toml", "missing field", "k_min"],
        ),
        (
            default_with("law = \"ud-ncf\"", "law = \"udncf\""),
            vec![
                "user.toml:",
                "law",
                "udncf",
                "\"ud-ncf\" or \"orthotropic-svk\"",
            ],
        ),
        (default_with("[w8]", "[w8x]"), vec!["user.toml", "w8x"]),
        (
            SVK.replace("nu12 = 0.3", "nu12 = 3.5"),
            vec!["user.toml:", "svk.nu12", "3.5", "sqrt(e1/e2)"],
        ),
        (
            SVK.replace("g12 = 1.0", "g12 = 0.0"),
            vec!["svk.g12", "> 0"],
        ),
        (
            format!("{SVK}\n[w4]\nc_ini = 1.0\n"),
            vec!["[w4]", "orthotropic-svk"],
        ),
        (
            "law = \"ud-ncf\"\n[w4]\nc_ini = 1.0\n".to_string(),
            vec!["[w6]", "missing"],
        ),
        ("this is not toml".to_string(), vec!["user.toml", "line 1"]),
    ];
    for (text, needles) in cases {
        let message = invalid(&text);
        for needle in needles {
            assert!(
                message.contains(needle),
                "message {message:?} lacks {needle:?}"
            );
        }
    }
    // Line numbers point at the offending value.
    let text = default_with("k_min = 0.4", "k_min = 1.5");
    let line = text.lines().position(|l| l.starts_with("k_min")).unwrap() + 1;
    assert!(invalid(&text).starts_with(&format!("user.toml:{line}: coupling.k_min = 1.5")));
}

/// Requirement: the named sets exist, the default is the
/// reconstruction, the printed set is Table D.1 exactly; integers are
/// accepted where floats are expected; a missing file is reported.
#[test]
fn named_sets_and_file_loading() {
    let default = MaterialSpec::default_set();
    assert_eq!(default.name, "schaefer2024");
    let law = udncf(&default);
    let lock = law.w11.lock.unwrap();
    assert_eq!((lock.c_lock, lock.i_lock), (10.0, 0.4));
    let printed = udncf(&MaterialSpec::named("schaefer2024-printed").unwrap());
    let lock = printed.w11.lock.unwrap();
    assert_eq!((lock.c_lock, lock.i_lock), (0.045, 10.0));
    assert_eq!(printed.w4.c_ini, 1000.0);
    assert!(printed.w4.transition.is_none() && printed.w4.lock.is_none());
    let t6 = printed.w6.transition.unwrap();
    assert_eq!(
        (printed.w6.c_ini, t6.s_ini, t6.c_mid, t6.delta_s_mid),
        (0.14, 0.018, 0.01, 0.005)
    );
    let t8 = printed.w8.transition.unwrap();
    assert_eq!(
        (printed.w8.c_ini, t8.s_ini, t8.c_mid, t8.delta_s_mid),
        (1.1, 0.025, 0.03, 0.02)
    );
    let t11 = printed.w11.transition.unwrap();
    assert_eq!(
        (printed.w11.c_ini, t11.s_ini, t11.c_mid, t11.delta_s_mid),
        (0.01, 0.0025, 0.001, 0.4)
    );
    assert_eq!(
        (
            printed.coupling.k_min,
            printed.coupling.s11,
            printed.coupling.e11
        ),
        (0.4, 10.0, 2.0)
    );
    // Integers for floats.
    let spec =
        MaterialSpec::from_toml_str(&default_with("c_ini = 1000.0", "c_ini = 1000"), "int.toml")
            .unwrap();
    assert_eq!(udncf(&spec).w4.c_ini, 1000.0);
    // Files.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mine.toml");
    std::fs::write(&path, BALANCED).unwrap();
    let spec = MaterialSpec::load(path.to_str().unwrap()).unwrap();
    assert_eq!(spec.name, "balanced-test");
    let err = MaterialSpec::load("no-such-set-or-file.toml").unwrap_err();
    assert!(matches!(err, ParamsError::NotFound { .. }));
    assert!(err.to_string().contains("schaefer2024-printed"));
}

/// Requirement: `material eval` answers every good line,
/// reports a bad line by its number on the error stream and as an error
/// object in place, keeps full f64 precision, and counts the failures.
#[test]
fn material_eval_answers_lines_and_reports_bad_ones() {
    let spec = MaterialSpec::default_set();
    let input = concat!(
        "{\"C\": [[1.02, 0.1], [0.1, 1.2]], \"fiber_angle_deg\": 30}\n",
        "\n",
        "{\"C\": [[1.0, 2.0], [2.0, 1.0]], \"fiber_angle_deg\": 0}\n",
        "not json\n",
        "{\"C\": [[1.0, 0.3], [0.2, 1.0]], \"fiber_angle_deg\": 0}\n",
        "{\"C\": [[1.0, 0.45], [0.45, 1.1]], \"fiber_angle_deg\": 0, \"extra\": 1}\n",
        "{\"C\": [[1.0, 0.45], [0.45, 1.1]], \"fiber_angle_deg\": 135}\n",
    );
    let mut out = Vec::new();
    let mut err = Vec::new();
    let summary = material_eval::run(
        &spec.material,
        input.as_bytes(),
        &mut out,
        &mut err,
        "stdin",
    )
    .unwrap();
    assert_eq!(
        summary,
        material_eval::EvalSummary {
            answered: 2,
            failed: 4
        }
    );
    let out = String::from_utf8(out).unwrap();
    let err = String::from_utf8(err).unwrap();
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 6, "one output line per non-blank input line");
    for (n, what) in [
        (3, "det C"),
        (4, "column"),
        (5, "not symmetric"),
        (6, "extra"),
    ] {
        assert!(
            err.contains(&format!("stdin:{n}: ")),
            "stderr lacks line {n}: {err}"
        );
        let obj = lines.iter().find(|v| v["line"] == n).expect("error object");
        assert!(obj["error"].as_str().unwrap().contains(what), "{obj}");
    }
    // Full precision: the written W is the library's value to the last bit.
    let c = Sym2::new(1.0, 1.1, 0.45);
    let frame = FibreFrame::from_angle(135f64.to_radians());
    let (state, tangent) = spec.material.stress_tangent(&c, &frame).unwrap();
    let last = lines.last().unwrap();
    assert_eq!(last["W"].as_f64().unwrap(), state.energy);
    assert_eq!(last["S"][0][1].as_f64().unwrap(), state.stress[2]);
    assert_eq!(
        last["tangent"][0][1][0][1].as_f64().unwrap(),
        tangent[(2, 2)]
    );
    assert_eq!(
        last["tangent"][0][0][1][1].as_f64().unwrap(),
        tangent[(0, 1)]
    );
    let i11 = Invariants::new(&c, &frame).unwrap().i11;
    assert_eq!(last["invariants"]["I11"].as_f64().unwrap(), i11);
}

/// Requirement: `material curves` writes CSV files whose
/// header states units and parameters, and PNG pictures; a non-UD-NCF set is
/// refused with a message.
#[test]
fn material_curves_writes_csv_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let spec = MaterialSpec::default_set();
    let written = material_curves::write_curves(&spec, dir.path()).unwrap();
    let names: Vec<String> = written
        .iter()
        .map(|p| p.file_name().unwrap().to_string_lossy().into())
        .collect();
    for expected in [
        "w6_shear.csv",
        "w8_transverse_tension.csv",
        "w11_compaction.csv",
        "k11_coupling.csv",
        "stress_functions.png",
        "energy_contributions.png",
    ] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing from {names:?}"
        );
    }
    let w11 = std::fs::read_to_string(dir.path().join("w11_compaction.csv")).unwrap();
    assert!(
        w11.contains("# units:") && w11.contains("MPa") && w11.contains("i_lock")
            || w11.contains("I_lock")
    );
    let rows: Vec<Vec<f64>> = w11
        .lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    assert_eq!(rows.len(), material_curves::SAMPLES);
    // The CSV holds the law's own values: f11 at the last sample.
    let law = udncf(&spec);
    let last = rows.last().unwrap();
    assert_eq!(last[2], law.w11.eval(last[1]).stress);
    let png = std::fs::read(dir.path().join("stress_functions.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
    let svk = MaterialSpec::from_toml_str(SVK, "svk.toml").unwrap();
    let err = material_curves::write_curves(&svk, dir.path()).unwrap_err();
    let err = err.to_string();
    assert!(err.contains("svk.toml") && err.contains("ud-ncf"));
}

/// Requirement: the SVK law is `S = Q : E` in the fibre frame, plane stress.
/// Checked by hand at a state with fibres at 0°: `E = diag(0.01, −0.02)` +
/// shear `E12 = 0.015`.
#[test]
fn svk_is_plane_stress_hooke_in_the_fibre_frame() {
    let spec = MaterialSpec::from_toml_str(SVK, "svk").unwrap();
    let (e1, e2, nu12, g12) = (50.0, 5.0, 0.3, 1.0);
    let nu21 = nu12 * e2 / e1;
    let d = 1.0 - nu12 * nu21;
    let (q11, q22, q12) = (e1 / d, e2 / d, nu12 * e2 / d);
    let (ea, eb, eab) = (0.01, -0.02, 0.015);
    let c = Sym2::new(1.0 + 2.0 * ea, 1.0 + 2.0 * eb, 2.0 * eab);
    let state = spec
        .material
        .stress(&c, &FibreFrame::from_angle(0.0))
        .unwrap();
    let expected = Sym2::new(q11 * ea + q12 * eb, q12 * ea + q22 * eb, 2.0 * g12 * eab);
    assert!((state.stress - expected).norm() <= 1e-13 * expected.norm());
    let w = 0.5 * (q11 * ea * ea + 2.0 * q12 * ea * eb + q22 * eb * eb + 4.0 * g12 * eab * eab);
    assert!((state.energy - w).abs() <= 1e-14 * w);
}

/// Requirement: TermBranch covers the lock-before-transition case too.
#[test]
fn term_branches_follow_the_one_sided_convention() {
    let law = udncf(&balanced());
    let x_t = law.w4.transition_point();
    assert_eq!(law.w4.branch(0.0), TermBranch::Initial);
    assert_eq!(law.w4.branch(x_t), TermBranch::Middle);
    assert_eq!(law.w4.branch(0.03), TermBranch::MiddleLocked);
    let text = BALANCED.replacen("i_lock = 0.03", "i_lock = 0.005", 1);
    let law = udncf(&MaterialSpec::from_toml_str(&text, "t").unwrap());
    assert_eq!(law.w4.branch(0.007), TermBranch::InitialLocked);
}

/// Requirement (docs/theory.md §7): at the kinks I8 = 1 and I11 = 1 the
/// loading side is used, so the tangent of the undeformed state is positive
/// definite for every fibre angle: ℂ(C = I) = 4 [C4 N4⊗N4 + C6 N6⊗N6 +
/// (C8 + C11/4) N8⊗N8] (hand-derived: ∂I11/∂p = (0, 0, ½) at C = I).
#[test]
fn reference_tangent_is_positive_definite_and_exact() {
    for spec in [
        MaterialSpec::default_set(),
        MaterialSpec::named("schaefer2024-printed").unwrap(),
        balanced(),
    ] {
        let law = udncf(&spec);
        for k in 0..12 {
            let frame = FibreFrame::from_angle((15.0 * k as f64).to_radians());
            let (_, t) = law
                .stress_tangent(&Sym2::new(1.0, 1.0, 0.0), &frame)
                .unwrap();
            let n = frame.structural();
            let expected = 4.0
                * (law.w4.c_ini * n[0] * n[0].transpose()
                    + law.w6.c_ini * n[1] * n[1].transpose()
                    + (law.w8.c_ini + 0.25 * law.w11.c_ini) * n[2] * n[2].transpose());
            assert!(
                (t - expected).norm() <= 1e-12 * expected.norm(),
                "{}: {t} vs {expected}",
                spec.name
            );
            let eigen = t.symmetric_eigenvalues();
            assert!(
                eigen.iter().all(|&e| e > 0.0),
                "{}: eigenvalues {eigen}",
                spec.name
            );
        }
    }
}

/// `MaterialSpec::parameter_values` is the inverse of the parameter-file
/// reader: every named set (and the SVK cross-check set), written back as a
/// parameter file from its listed keys and values, reads as the same law —
/// no parameter missing, renamed or changed (values written with `{:?}`,
/// the shortest text that reads back as the same `f64`).
#[test]
fn parameter_values_read_back_as_the_same_law() {
    let mut specs: Vec<MaterialSpec> = ncform::material::params::NAMED_SETS
        .iter()
        .map(|(name, _)| MaterialSpec::named(name).unwrap())
        .collect();
    specs.push(MaterialSpec::from_toml_str(SVK, "svk").unwrap());
    for spec in specs {
        let mut tables: Vec<(String, Vec<String>)> = Vec::new();
        for (key, value) in spec.parameter_values() {
            let (table, name) = key.split_once('.').unwrap();
            if tables.last().is_none_or(|(t, _)| t != table) {
                tables.push((table.to_string(), Vec::new()));
            }
            tables
                .last_mut()
                .unwrap()
                .1
                .push(format!("{name} = {value:?}"));
        }
        let mut text = format!("law = \"{}\"\n", spec.law_name());
        for (table, lines) in tables {
            text.push_str(&format!("[{table}]\n{}\n", lines.join("\n")));
        }
        let back = MaterialSpec::from_toml_str(&text, "written back")
            .unwrap_or_else(|e| panic!("{}: {e}\n{text}", spec.name));
        assert_eq!(back.material, spec.material, "{}:\n{text}", spec.name);
    }
}
