//! Sensitivities of an off-axis tension test by direct differentiation
//! (`docs/fit.md`, "Sensitivities").
//!
//! At a converged state the residual of the free dofs vanishes for every
//! parameter set, `R_f(u(p), p) = 0`, so
//!
//! ```text
//! K_ff du_f/dp = −∂R_f/∂p          (one back-substitution per parameter)
//! dF/dp = Σ_c w_c (K_cf du_f/dp + ∂R_c/∂p)      (the clamp reaction)
//! ```
//!
//! with `K` the consistent tangent at the converged state, `∂R/∂p = Σ_e
//! t A0 B_eᵀ ∂S/∂p` the internal force's derivative at fixed `u` and `w_c`
//! the clamp's displacement per unit load. The prescribed displacements do
//! not depend on `p`. The MDZ means follow from `du/dp` through the strain
//! measures: `dC = dFᵀF + FᵀdF`, `dI_k = N_k : dC`, `E22 = I8 − 1`,
//! `E⊥ = I11 − 1` with `∂I11/∂(I4, I6, I8)` (Eq. A.5) and `γ = I10 =
//! π/2 − arccos(I6/√(I4 I8))`. The law is hyperelastic, so each step's
//! sensitivity does not depend on the path.
//!
//! [`SensitivityReport`] is a [`Report`] of the one runner: it asks for the
//! converged tangent and evaluates the values and sensitivities at the
//! scheduled clamp displacements.

use rayon::prelude::*;

use crate::case::OatModel;
use crate::material::{FibreFrame, Invariants, MaterialError, Sym2};
use crate::model::MembraneModel;
use crate::report::{Built, Recorded, Report, RunError, Solved};
use crate::solver::{ConvergedTangent, Snapshot, StepRecord};

/// The quantities an OAT is fitted on, in the order of
/// [`PointValues::values`].
pub const QUANTITIES: usize = 4;

/// Index of the clamp force \[N\] in [`PointValues::values`].
pub const FORCE: usize = 0;
/// Index of the MDZ mean of `E22 = I8 − 1` \[-\].
pub const E22: usize = 1;
/// Index of the MDZ mean of the shear angle `γ = I10` \[deg\].
pub const SHEAR_ANGLE: usize = 2;
/// Index of the MDZ mean of `E⊥ = I11 − 1` \[-\].
pub const E_PERP: usize = 3;

/// `∂S/∂p` of a law for a list of parameters, at fixed `C`: what the
/// sensitivities need of the material.
pub trait StressSensitivity: Sync {
    /// Number of parameters.
    fn count(&self) -> usize;

    /// `out[j] = ∂S/∂p_j` at `C` (reference basis, [`Sym2`] storage)
    /// \[MPa per unit of `p_j`\].
    ///
    /// # Errors
    /// A state the law cannot evaluate.
    fn stress_derivatives(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
        out: &mut [Sym2],
    ) -> Result<(), MaterialError>;
}

/// The values of one scheduled state and their derivatives.
#[derive(Debug, Clone, PartialEq)]
pub struct PointValues {
    /// Clamp displacement \[mm\].
    pub displacement: f64,
    /// Force \[N\], MDZ means of E22 \[-\], γ \[deg\], E⊥ \[-\]
    /// (indices [`FORCE`], [`E22`], [`SHEAR_ANGLE`], [`E_PERP`]).
    pub values: [f64; QUANTITIES],
    /// `derivatives[q][j] = d values[q] / d p_j`.
    pub derivatives: [Vec<f64>; QUANTITIES],
    /// An estimate of the 1-norm condition number of `K_ff` here
    /// (Hager's estimator), `None` when it could not be computed.
    pub condition: Option<f64>,
    /// Why the sensitivities could not be computed here (a singular
    /// tangent), `None` when they were.
    pub failure: Option<String>,
}

/// A report that evaluates an OAT's force and MDZ means and their
/// sensitivities to the law's parameters at scheduled clamp displacements.
pub struct SensitivityReport<'s> {
    schedule: Vec<f64>,
    sensitivity: &'s dyn StressSensitivity,
    /// The membrane and the MDZ, taken at `begin`.
    membrane: Option<MembraneModel>,
    mdz: Vec<usize>,
    /// The points evaluated, in schedule order.
    pub points: Vec<PointValues>,
    /// The set-up error, if the run failed before solving.
    pub error: Option<String>,
    /// The solve's figures, once it ended.
    pub solved: Option<Solved>,
    /// Whether to estimate the tangent's condition number at each point
    /// (a few back-substitutions more).
    pub estimate_condition: bool,
}

impl<'s> SensitivityReport<'s> {
    /// A report for the clamp displacements `schedule` \[mm\] (sorted) and
    /// the parameters of `sensitivity`.
    pub fn new(schedule: Vec<f64>, sensitivity: &'s dyn StressSensitivity) -> Self {
        Self {
            schedule,
            sensitivity,
            membrane: None,
            mdz: Vec::new(),
            points: Vec::new(),
            error: None,
            solved: None,
            estimate_condition: true,
        }
    }

    /// The index of the scheduled displacement `load` is, if any.
    fn scheduled(&self, load: f64) -> Option<usize> {
        let tiny = 1e-9 * self.schedule.last().copied().unwrap_or(1.0).abs().max(1.0);
        self.schedule.iter().position(|d| (d - load).abs() <= tiny)
    }
}

impl Report for SensitivityReport<'_> {
    fn begin(&mut self, built: &Built) -> Result<(), RunError> {
        if let Built::Oat { model, .. } = built {
            let OatModel { model, mdz, .. } = &**model;
            self.membrane = Some(model.clone());
            self.mdz = mdz.clone();
        }
        Ok(())
    }

    fn record(&mut self, _built: &Built, _state: &Recorded) {}

    fn end(&mut self, _built: &Built, solved: &Solved) {
        self.solved = Some(solved.clone());
    }

    fn fail(&mut self, error: &RunError) {
        self.error = Some(error.to_string());
    }

    fn wants_tangent(&self) -> bool {
        true
    }

    fn tangent(
        &mut self,
        _built: &Built,
        step: &StepRecord,
        snapshot: &Snapshot,
        tangent: &mut ConvergedTangent,
    ) {
        let Some(index) = self.scheduled(step.load) else {
            return;
        };
        let Some(membrane) = &self.membrane else {
            return;
        };
        let point = evaluate_point(
            membrane,
            &self.mdz,
            self.sensitivity,
            step,
            snapshot,
            tangent,
            self.estimate_condition,
        );
        debug_assert!(self.points.len() <= index);
        self.points.push(point);
    }
}

/// The MDZ means of `E22`, `γ` \[deg\], `E⊥` at `u` and, for each change
/// `du` in `changes`, their derivatives.
fn mdz_means(
    membrane: &MembraneModel,
    mdz: &[usize],
    u: &[f64],
    changes: &[Vec<f64>],
) -> Result<([f64; 3], Vec<[f64; 3]>), MaterialError> {
    let mut area = 0.0;
    let mut sums = [0.0; 3];
    let mut derivative_sums = vec![[0.0; 3]; changes.len()];
    for &e in mdz {
        let reference = &membrane.references[e];
        let x = membrane.element_displacements(e, u);
        let kin = reference.kinematics(&x);
        let inv = Invariants::new(&kin.c, &reference.frame)?;
        let w = reference.area;
        area += w;
        let (i4, i6, i8) = (inv.i4, inv.i6, inv.i8);
        let q = i6 / (i4 * i8).sqrt();
        sums[0] += w * (i8 - 1.0);
        sums[1] += w * inv.i10().to_degrees();
        sums[2] += w * (inv.i11 - 1.0);
        let di11 = inv.i11_gradient();
        // dI10 = dq / √(1 − q²), dq = dI6/√(I4 I8) − ½ q (dI4/I4 + dI8/I8).
        let root = (1.0 - q * q).max(f64::MIN_POSITIVE).sqrt();
        let [g1, g2] = kin.g;
        for (change, sum) in changes.iter().zip(&mut derivative_sums) {
            let du = membrane.element_displacements(e, change);
            let [dg1, dg2] = reference.deformation_change(&du);
            let dc = Sym2::new(
                2.0 * g1.dot(&dg1),
                2.0 * g2.dot(&dg2),
                g1.dot(&dg2) + g2.dot(&dg1),
            );
            let frame = &reference.frame;
            let (d4, d6, d8) = (
                crate::material::frame::contract(&frame.n4, &dc),
                crate::material::frame::contract(&frame.n6, &dc),
                crate::material::frame::contract(&frame.n8, &dc),
            );
            let dq = d6 / (i4 * i8).sqrt() - 0.5 * q * (d4 / i4 + d8 / i8);
            sum[0] += w * d8;
            sum[1] += w * (dq / root).to_degrees();
            sum[2] += w * (di11[0] * d4 + di11[1] * d6 + di11[2] * d8);
        }
    }
    let mean = |v: f64| if area > 0.0 { v / area } else { 0.0 };
    Ok((
        sums.map(mean),
        derivative_sums.into_iter().map(|s| s.map(mean)).collect(),
    ))
}

/// `∂R/∂p_j` over every dof at `u` (membrane forces only; the OAT has no
/// other parameter-dependent term): `Σ_e t A0 B_eᵀ ∂S/∂p_j`.
fn force_parameter_derivatives(
    membrane: &MembraneModel,
    sensitivity: &dyn StressSensitivity,
    u: &[f64],
) -> Result<Vec<Vec<f64>>, MaterialError> {
    let n = sensitivity.count();
    // Per element and parameter its nine nodal forces, in parallel; then
    // summed into the dofs in element order (one buffer, not one dof
    // vector per task and parameter).
    let per_element = 9 * n;
    let mut local = vec![0.0; membrane.triangles.len() * per_element];
    local
        .par_chunks_mut(per_element.max(1))
        .enumerate()
        .try_for_each_init(
            || vec![Sym2::zeros(); n],
            |ds, (e, out)| -> Result<(), MaterialError> {
                let reference = &membrane.references[e];
                let x = membrane.element_displacements(e, u);
                let kin = reference.kinematics(&x);
                sensitivity.stress_derivatives(&kin.c, &reference.frame, ds)?;
                for (s, f_out) in ds.iter().zip(out.chunks_exact_mut(9)) {
                    let f = reference.stress_force(&kin.g, s, membrane.thickness);
                    f_out.copy_from_slice(f.as_slice());
                }
                Ok(())
            },
        )?;
    let mut total = vec![vec![0.0; u.len()]; n];
    if n > 0 {
        for (nodes, forces) in membrane
            .triangles
            .iter()
            .zip(local.chunks_exact(per_element))
        {
            for (total_j, f) in total.iter_mut().zip(forces.chunks_exact(9)) {
                for (a, &node) in nodes.iter().enumerate() {
                    for d in 0..3 {
                        total_j[3 * node + d] += f[3 * a + d];
                    }
                }
            }
        }
    }
    Ok(total)
}

/// Hager's estimate of `‖K_ff⁻¹‖₁` for the symmetric `K_ff` (LAPACK's
/// `dlacon` without its refinements): at most five solves.
fn inverse_norm_estimate(tangent: &mut ConvergedTangent, n: usize) -> Option<f64> {
    let mut x = vec![1.0 / n as f64; n];
    let mut estimate = 0.0;
    for _ in 0..5 {
        let mut y = x.clone();
        tangent.solve(&mut y).ok()?;
        let norm: f64 = y.iter().map(|v| v.abs()).sum();
        let mut z: Vec<f64> = y
            .iter()
            .map(|v| if *v >= 0.0 { 1.0 } else { -1.0 })
            .collect();
        tangent.solve(&mut z).ok()?;
        let (j, largest) = z.iter().enumerate().fold((0, 0.0_f64), |(k, m), (i, v)| {
            if v.abs() > m { (i, v.abs()) } else { (k, m) }
        });
        let zx: f64 = z.iter().zip(&x).map(|(a, b)| a * b).sum();
        estimate = norm;
        if largest <= zx {
            break;
        }
        x.fill(0.0);
        x[j] = 1.0;
    }
    Some(estimate)
}

/// Values and sensitivities at one converged, scheduled state.
fn evaluate_point(
    membrane: &MembraneModel,
    mdz: &[usize],
    sensitivity: &dyn StressSensitivity,
    step: &StepRecord,
    snapshot: &Snapshot,
    tangent: &mut ConvergedTangent,
    estimate_condition: bool,
) -> PointValues {
    let n = sensitivity.count();
    let u = snapshot.u;
    let mut point = PointValues {
        displacement: step.load,
        values: [step.reaction, 0.0, 0.0, 0.0],
        derivatives: std::array::from_fn(|_| vec![0.0; n]),
        condition: None,
        failure: None,
    };
    let fail = |mut point: PointValues, why: String| {
        point.failure = Some(why);
        point
    };
    let free: Vec<usize> = tangent.free_dofs().to_vec();
    let constrained: Vec<(usize, f64)> = tangent
        .constrained()
        .iter()
        .map(|c| (c.dof, c.per_unit_load))
        .collect();
    let dr = match force_parameter_derivatives(membrane, sensitivity, u) {
        Ok(dr) => dr,
        Err(e) => return fail(point, format!("∂R/∂p: {e}")),
    };
    // du/dp_j (all dofs, zero on the constrained ones).
    let mut changes: Vec<Vec<f64>> = Vec::with_capacity(n);
    let mut rhs = vec![0.0; free.len()];
    for dr_j in &dr {
        for (k, &d) in free.iter().enumerate() {
            rhs[k] = -dr_j[d];
        }
        if let Err(e) = tangent.solve(&mut rhs) {
            return fail(point, format!("the converged tangent: {e}"));
        }
        let mut du = vec![0.0; u.len()];
        for (k, &d) in free.iter().enumerate() {
            du[d] = rhs[k];
        }
        changes.push(du);
    }
    // Reactions: dF = Σ_c w_c (K du + ∂R/∂p)_c.
    let mut k_du = vec![0.0; u.len()];
    for (j, du) in changes.iter().enumerate() {
        tangent.multiply_all(du, &mut k_du);
        point.derivatives[FORCE][j] = constrained
            .iter()
            .map(|&(dof, w)| w * (k_du[dof] + dr[j][dof]))
            .sum();
    }
    match mdz_means(membrane, mdz, u, &changes) {
        Ok((means, derivatives)) => {
            point.values[E22..].copy_from_slice(&means);
            for (j, d) in derivatives.iter().enumerate() {
                for (q, value) in d.iter().enumerate() {
                    point.derivatives[1 + q][j] = *value;
                }
            }
        }
        Err(e) => return fail(point, format!("the MDZ strains: {e}")),
    }
    if estimate_condition {
        point.condition =
            inverse_norm_estimate(tangent, free.len()).map(|inverse| inverse * tangent.norm_one());
    }
    point
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::{Case, OatCase};
    use crate::fit::evaluate::LawSensitivity;
    use crate::material::{LawParameter, Material, UdNcf};
    use crate::report::{Progress, run};
    use crate::solver::CancelToken;

    /// The forward solves' residual tolerance.
    const NEWTON_TOLERANCE: f64 = 1e-10;

    /// A coarse OAT (12 mm triangles, 40 mm stroke) with `law`; `steps`
    /// picks one of two load-step schedules.
    fn coarse_oat(angle: f64, law: UdNcf, steps: usize) -> OatCase {
        let (first, largest) = [(1.0, 5.0), (0.7, 3.3)][steps];
        let text = format!(
            "title = \"coarse\"\n[specimen]\nwidth = 100.0\nlength = 300.0\nbias_angle_deg = {angle}\n[mesh]\nelement_size = 12.0\n[material]\nparams = \"schaefer2024\"\n[loading]\ndisplacement = 40.0\n[solver]\nresidual_tolerance = {NEWTON_TOLERANCE}\ninitial_increment = {first}\nmax_increment = {largest}\n"
        );
        let mut case = OatCase::from_toml_str(&text, "coarse.toml", std::path::Path::new("."))
            .expect("a valid case");
        case.material.material = Material::UdNcf(law);
        case
    }

    fn points(
        case: OatCase,
        sensitivity: &dyn StressSensitivity,
        schedule: &[f64],
    ) -> Vec<PointValues> {
        let mut case = case;
        case.output_displacements = schedule.to_vec();
        let mut report = SensitivityReport::new(schedule.to_vec(), sensitivity);
        run(
            &Case::Oat(case),
            &mut report,
            &mut Progress::Quiet,
            &CancelToken::default(),
        )
        .expect("the run");
        assert_eq!(report.points.len(), schedule.len());
        report.points
    }

    /// The sensitivities of whole coarse OATs against central differences
    /// of whole runs, for the ten parameters the OATs inform and W4's,
    /// W11's and the coupling's exponent.
    ///
    /// Tolerance, derived per value: the forward solves reproduce a value
    /// `Q` only to `ε_Q`: Newton stops once the residual is below
    /// `τ = 1e-10` of the reactions, which leaves the reaction and the
    /// strains relatively about `τ` off; the difference of two runs with
    /// different load-step schedules (the solution at a load does not
    /// depend on the path) measures it too, and the larger is taken. A
    /// central difference `D(h)` then carries noise `≤ ε_Q/h` and
    /// truncation `T(h) ∝ h²`; `|D(h) − D(2h)| ≥ 3 T(h) − 1.5 ε_Q/h`
    /// bounds the truncation. The exact sensitivity is evaluated at a state
    /// off by the same error, relatively `ε_Q/|Q|`. So
    /// `|exact − D(h)| ≤ |D(h) − D(2h)| + 3 ε_Q/h + |exact| ε_Q/|Q|`.
    #[test]
    fn whole_run_sensitivities_match_central_differences() {
        let law = match crate::material::MaterialSpec::default_set().material {
            Material::UdNcf(law) => law,
            Material::OrthotropicSvk(_) => unreachable!("the default set is ud-ncf"),
        };
        let keys = [
            "w6.c_ini",
            "w6.s_ini",
            "w6.c_mid",
            "w6.delta_s_mid",
            "w8.c_ini",
            "w8.s_ini",
            "w8.c_mid",
            "w8.delta_s_mid",
            "coupling.k_min",
            "coupling.s11",
            "coupling.e11",
            "w4.c_ini",
            "w11.c_ini",
        ];
        let parameters: Vec<LawParameter> = keys
            .iter()
            .map(|k| LawParameter::from_key(k).expect("a law key"))
            .collect();
        let schedule = [10.0, 25.0, 40.0];
        let none = LawSensitivity {
            law,
            parameters: Vec::new(),
        };
        let mut checked = 0;
        for angle in [30.0, 45.0, 60.0] {
            let exact = LawSensitivity {
                law,
                parameters: parameters.clone(),
            };
            let at = points(coarse_oat(angle, law, 0), &exact, &schedule);
            let other = points(coarse_oat(angle, law, 1), &none, &schedule);
            for (j, p) in parameters.iter().enumerate() {
                let value = p.value(&law).expect("the set has it");
                let h = 1e-4 * value.abs();
                let run_at = |v: f64| {
                    let moved = p.with_value(&law, v).expect("settable");
                    points(coarse_oat(angle, moved, 0), &none, &schedule)
                };
                let (p1, m1) = (run_at(value + h), run_at(value - h));
                let (p2, m2) = (run_at(value + 2.0 * h), run_at(value - 2.0 * h));
                for k in 0..schedule.len() {
                    for q in 0..QUANTITIES {
                        let d1 = (p1[k].values[q] - m1[k].values[q]) / (2.0 * h);
                        let d2 = (p2[k].values[q] - m2[k].values[q]) / (4.0 * h);
                        let noise = (at[k].values[q] - other[k].values[q])
                            .abs()
                            .max(NEWTON_TOLERANCE * at[k].values[q].abs());
                        let e = at[k].derivatives[q][j];
                        let tolerance = (d1 - d2).abs()
                            + 3.0 * noise / h
                            + e.abs() * noise / at[k].values[q].abs().max(f64::MIN_POSITIVE);
                        assert!(
                            (e - d1).abs() <= tolerance,
                            "{angle}° {} at {} mm, quantity {q}: exact {e:e}, difference {d1:e} (tolerance {tolerance:e})",
                            keys[j],
                            schedule[k]
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 3 * keys.len() * 3 * QUANTITIES);
    }
}
