//! One evaluation of the fit's model: every test's OAT run at a parameter
//! set, with its sensitivities, turned into the weighted residual and its
//! Jacobian (`docs/fit.md`, "The residual").
//!
//! The scaled parameters `θ` are the free law parameters (`θ = ln p` for
//! [`Scaling::Log`], `θ = p / scale` for [`Scaling::Linear`]) followed by
//! the free displacement offsets. Each residual entry is
//! `r = (sim(d_k) − meas(d_k + δ)) / σ_k` at a scheduled clamp
//! displacement `d_k`; `∂r/∂p_j = (∂sim/∂p_j)/σ_k`, `∂r/∂δ =
//! −slope_meas/σ_k`. The tests run in parallel.

use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

use super::input::{FitSpec, Scaling, TestSpec};
use super::measured::Quantity;
use super::sensitivity::{PointValues, SensitivityReport, StressSensitivity};
use crate::case::Case;
use crate::material::{
    FibreFrame, LawParameter, Material, MaterialError, MaterialSpec, Sym2, UdNcf,
};
use crate::report::{Progress, run};
use crate::solver::{CancelToken, RunStatus};

/// The index of `quantity` in [`PointValues::values`].
pub fn quantity_index(quantity: Quantity) -> usize {
    match quantity {
        Quantity::Force => super::sensitivity::FORCE,
        Quantity::E22 => super::sensitivity::E22,
        Quantity::ShearAngle => super::sensitivity::SHEAR_ANGLE,
        Quantity::EPerp => super::sensitivity::E_PERP,
    }
}

/// The analytic `∂S/∂p` of the UD-NCF law for a list of its parameters.
pub struct LawSensitivity {
    /// The law.
    pub law: UdNcf,
    /// The parameters.
    pub parameters: Vec<LawParameter>,
}

impl StressSensitivity for LawSensitivity {
    fn count(&self) -> usize {
        self.parameters.len()
    }

    fn stress_derivatives(
        &self,
        c: &Sym2,
        frame: &FibreFrame,
        out: &mut [Sym2],
    ) -> Result<(), MaterialError> {
        self.law
            .stress_parameter_derivatives(c, frame, &self.parameters, out)
    }
}

/// One scaled parameter: a law parameter or a test's offset.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaledParameter {
    /// Its name: the law key, or `offset.<test>`.
    pub key: String,
    /// The law parameter, `None` for an offset.
    pub law: Option<LawParameter>,
    /// The test of an offset.
    pub test: Option<usize>,
    /// How it is scaled.
    pub scaling: Scaling,
    /// The scale of a linear parameter (`θ = p / scale`).
    pub scale: f64,
    /// Start and bounds, in the parameter's own unit.
    pub start: f64,
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
}

impl ScaledParameter {
    /// `θ` of the value `p`.
    pub fn theta(&self, p: f64) -> f64 {
        match self.scaling {
            Scaling::Log => p.ln(),
            Scaling::Linear => p / self.scale,
        }
    }

    /// The value `p` of `θ`.
    pub fn value(&self, theta: f64) -> f64 {
        match self.scaling {
            Scaling::Log => theta.exp(),
            Scaling::Linear => theta * self.scale,
        }
    }

    /// `dp/dθ` at `θ`.
    pub fn derivative(&self, theta: f64) -> f64 {
        match self.scaling {
            Scaling::Log => theta.exp(),
            Scaling::Linear => self.scale,
        }
    }
}

/// The scaled parameters of a fit: the free law parameters, then the free
/// offsets.
///
/// # Errors
/// A free key that is not a UD-NCF parameter (the input checks refuse it
/// first; kept as an error, never a panic).
pub fn scaled_parameters(spec: &FitSpec) -> Result<Vec<ScaledParameter>, String> {
    let mut out = Vec::new();
    for free in &spec.free {
        let law = LawParameter::from_key(&free.key)
            .ok_or_else(|| format!("{}: not a parameter of the ud-ncf law", free.key))?;
        out.push(ScaledParameter {
            key: free.key.clone(),
            law: Some(law),
            test: None,
            scaling: free.scaling,
            scale: linear_scale(free.start, free.lower, free.upper),
            start: free.start,
            lower: free.lower,
            upper: free.upper,
        });
    }
    for (t, test) in spec.tests.iter().enumerate() {
        if let Some(offset) = test.offset.filter(|o| o.free) {
            out.push(ScaledParameter {
                key: format!("offset.{}", test.name),
                law: None,
                test: Some(t),
                scaling: Scaling::Linear,
                scale: linear_scale(offset.start, offset.lower, offset.upper),
                start: offset.start,
                lower: offset.lower,
                upper: offset.upper,
            });
        }
    }
    Ok(out)
}

/// The unit of a linear parameter's `θ`: its start's magnitude, or a tenth
/// of its range when the start is (near) 0 — so that a unit change of `θ`
/// is a relative change of the order of the value, as for a logarithm.
fn linear_scale(start: f64, lower: f64, upper: f64) -> f64 {
    let range = 0.1 * (upper - lower);
    let scale = start.abs().max(range);
    if scale > 0.0 && scale.is_finite() {
        scale
    } else {
        1.0
    }
}

/// A test's forward run at one parameter set.
#[derive(Debug, Clone)]
pub struct TestRun {
    /// The scheduled points with their values and sensitivities.
    pub points: Vec<PointValues>,
    /// Newton iterations of the run.
    pub newton_iterations: usize,
    /// Factorisations of the run.
    pub factorisations: usize,
    /// Wall time of the run \[s\].
    pub seconds: f64,
}

/// One evaluation: every test's run, the residual and Jacobian in `θ`.
#[derive(Debug, Clone)]
pub struct Evaluation {
    /// Per test.
    pub runs: Vec<TestRun>,
    /// The weighted residual.
    pub residual: DVector<f64>,
    /// `∂r/∂θ`.
    pub jacobian: DMatrix<f64>,
    /// Per residual entry: (test, quantity, point).
    pub rows: Vec<(usize, Quantity, usize)>,
}

/// The law of a material set (the fit takes UD-NCF sets only).
fn ud_ncf(spec: &MaterialSpec) -> Result<UdNcf, String> {
    match spec.material {
        Material::UdNcf(law) => Ok(law),
        Material::OrthotropicSvk(_) => Err("the fit supports law ud-ncf only".into()),
    }
}

/// The material set at the scaled parameters `theta`.
///
/// # Errors
/// A value the law refuses (named with its key).
pub fn material_at(
    spec: &FitSpec,
    parameters: &[ScaledParameter],
    theta: &[f64],
) -> Result<MaterialSpec, String> {
    let values: Vec<(LawParameter, f64)> = parameters
        .iter()
        .zip(theta)
        .filter_map(|(p, &t)| p.law.map(|law| (law, p.value(t))))
        .collect();
    spec.start
        .with_parameters(&values)
        .map_err(|e| e.to_string())
}

/// Runs `test` with `material` and the sensitivities to `law_parameters`.
///
/// # Errors
/// A run that cannot be set up, stops before the last scheduled
/// displacement, or has a point without sensitivities: why, naming the test.
pub fn run_test(
    test: &TestSpec,
    material: &MaterialSpec,
    law_parameters: &[LawParameter],
    newton_tolerance: f64,
) -> Result<TestRun, String> {
    let law = ud_ncf(material)?;
    let sensitivity = LawSensitivity {
        law,
        parameters: law_parameters.to_vec(),
    };
    let mut case = test.case.clone();
    case.material = material.clone();
    case.output_displacements = test.schedule.clone();
    case.solver.residual_tolerance = newton_tolerance;
    let mut report = SensitivityReport::new(test.schedule.clone(), &sensitivity);
    let clock = std::time::Instant::now();
    let outcome = run(
        &Case::Oat(case),
        &mut report,
        &mut Progress::Quiet,
        &CancelToken::default(),
    )
    .map_err(|e| format!("test {}: {e}", test.name))?;
    let solved = &outcome.solved;
    if let RunStatus::Incomplete {
        load_reached,
        reason,
        ..
    } = &solved.status
    {
        return Err(format!(
            "test {}: the forward run stopped at {load_reached} mm: {reason}",
            test.name
        ));
    }
    if report.points.len() != test.schedule.len() {
        return Err(format!(
            "test {}: {} of {} scheduled displacements reached",
            test.name,
            report.points.len(),
            test.schedule.len()
        ));
    }
    if let Some(point) = report.points.iter().find(|p| p.failure.is_some()) {
        return Err(format!(
            "test {} at {} mm: no sensitivities: {}",
            test.name,
            point.displacement,
            point.failure.clone().unwrap_or_default()
        ));
    }
    Ok(TestRun {
        points: report.points,
        newton_iterations: solved.newton_iterations,
        factorisations: solved.factorisations,
        seconds: clock.elapsed().as_secs_f64(),
    })
}

/// Evaluates every test at `theta` (in parallel) and builds the residual
/// and Jacobian.
///
/// # Errors
/// A parameter value the law refuses or a forward run that fails: why.
pub fn evaluate(
    spec: &FitSpec,
    parameters: &[ScaledParameter],
    theta: &[f64],
) -> Result<Evaluation, String> {
    let material = material_at(spec, parameters, theta)?;
    let law_parameters: Vec<LawParameter> = parameters.iter().filter_map(|p| p.law).collect();
    let runs: Vec<TestRun> = spec
        .tests
        .par_iter()
        .map(|test| {
            run_test(
                test,
                &material,
                &law_parameters,
                spec.options.newton_tolerance,
            )
        })
        .collect::<Result<_, _>>()?;
    assemble(spec, parameters, theta, runs)
}

/// The residual and Jacobian of `runs` at `theta`.
///
/// # Errors
/// A measured value missing at a displaced schedule point (an offset
/// beyond the measured range).
pub fn assemble(
    spec: &FitSpec,
    parameters: &[ScaledParameter],
    theta: &[f64],
    runs: Vec<TestRun>,
) -> Result<Evaluation, String> {
    let mut residual = Vec::new();
    let mut jacobian_rows: Vec<Vec<f64>> = Vec::new();
    let mut rows = Vec::new();
    let n = parameters.len();
    for (t, (test, run)) in spec.tests.iter().zip(&runs).enumerate() {
        let offset_column = parameters.iter().position(|p| p.test == Some(t));
        let offset = match offset_column {
            Some(c) => parameters[c].value(theta[c]),
            None => test.offset.map_or(0.0, |o| o.start),
        };
        for measured in &test.measured {
            let q = quantity_index(measured.quantity);
            for (k, point) in run.points.iter().enumerate() {
                let sample = measured.sample(point.displacement, offset).ok_or_else(|| {
                    format!(
                        "test {}: no measured {} at {} mm (offset {offset} mm)",
                        test.name,
                        measured.quantity.name(),
                        point.displacement + offset
                    )
                })?;
                let sigma = sample.sigma;
                residual.push((point.values[q] - sample.value) / sigma);
                let mut row = vec![0.0; n];
                let mut law_index = 0;
                for (c, p) in parameters.iter().enumerate() {
                    if p.law.is_some() {
                        row[c] = point.derivatives[q][law_index] * p.derivative(theta[c]) / sigma;
                        law_index += 1;
                    } else if Some(c) == offset_column {
                        row[c] = -sample.slope * p.derivative(theta[c]) / sigma;
                    }
                }
                jacobian_rows.push(row);
                rows.push((t, measured.quantity, k));
            }
        }
    }
    let m = residual.len();
    let jacobian = DMatrix::from_fn(m, n, |i, j| jacobian_rows[i][j]);
    if residual.iter().any(|r| !r.is_finite()) || jacobian.iter().any(|v| !v.is_finite()) {
        return Err("a residual or sensitivity is not finite at this parameter set".into());
    }
    Ok(Evaluation {
        runs,
        residual: DVector::from_vec(residual),
        jacobian,
        rows,
    })
}
