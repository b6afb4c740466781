//! The fit's outputs in its folder (`docs/fit.md`, "Outputs"):
//! `fitted.toml` (a parameter file a case can use unchanged), `fit.json`
//! (values, σ, bounds, correlation, singular values, χ², misfits,
//! warnings), `fit.csv` (the iteration history), `fit_curves.csv`
//! (measured, starting and fitted curves), and the pictures
//! `fit_<test>.png` (measured against fitted, the start faint behind) and
//! `correlation.png` (the correlation matrix as a heat map).

use std::collections::BTreeMap;
use std::path::Path;

use plotters::prelude::*;
use serde::Serialize;

use super::evaluate::quantity_index;
use super::input::FitSpec;
use super::measured::Quantity;
use super::run::FitOutcome;
use crate::post::plot::{Panel, PlotError, Series, ensure_font, save_png, write_panels};
use crate::report::folder::Outputs;

/// Units of every output, written into each file.
pub const UNITS: &str =
    "units: mm, N, MPa; shear angle in degrees; E22 = I8 - 1, E_perp = I11 - 1 (dimensionless)";

#[derive(Serialize)]
struct ParameterJson {
    value: f64,
    start: f64,
    sigma: f64,
    relative_sigma: f64,
    bounds: [f64; 2],
    at_bound: bool,
}

#[derive(Serialize)]
struct MisfitJson {
    quantity: &'static str,
    points: usize,
    weighted_rms: f64,
    rms: f64,
    unit: &'static str,
    interpolation_error: f64,
}

#[derive(Serialize)]
struct WeakJson {
    singular_value: f64,
    combination: BTreeMap<String, f64>,
}

#[derive(Serialize)]
struct FitJson<'a> {
    units: &'static str,
    fit_file: String,
    title: &'a str,
    converged: bool,
    stop: String,
    parameters: BTreeMap<String, ParameterJson>,
    parameter_order: Vec<String>,
    correlation: Vec<Vec<f64>>,
    singular_values: Vec<f64>,
    weak_combinations: Vec<WeakJson>,
    chi2: f64,
    dof: usize,
    variance_factor: f64,
    iterations: usize,
    evaluations: usize,
    seconds: f64,
    tests: BTreeMap<String, Vec<MisfitJson>>,
    /// Per test, the largest estimated condition number of the converged
    /// tangent over the scheduled points at the optimum.
    largest_condition: BTreeMap<String, f64>,
    condition_limit: f64,
    warnings: &'a [String],
    notes: [&'static str; 3],
}

/// Writes every output of `outcome` into `outputs`' folder; what could not
/// be written is recorded there (and said on stderr).
pub fn write_outputs(spec: &FitSpec, outcome: &FitOutcome, outputs: &mut Outputs) {
    let root = outputs.root().to_path_buf();
    if let Some(material) = &outcome.material {
        let header = provenance(spec, outcome);
        let text = material.to_toml(&header);
        outputs.write(&root.join("fitted.toml"), |p| std::fs::write(p, &text));
    }
    outputs.write_json(&root.join("fit.json"), &fit_json(spec, outcome));
    outputs.write(&root.join("fit.csv"), |p| {
        std::fs::write(p, history_csv(outcome))
    });
    outputs.write(&root.join("fit_curves.csv"), |p| {
        std::fs::write(p, curves_csv(spec, outcome))
    });
    if !outcome.final_runs.is_empty() {
        for (t, test) in spec.tests.iter().enumerate() {
            let path = root.join(format!("fit_{}.png", file_stem(&test.name)));
            outputs.write(&path, |p| curves_png(p, spec, outcome, t));
        }
    }
    if let Some(id) = &outcome.identifiability {
        let keys: Vec<String> = outcome.parameters.iter().map(|p| p.key.clone()).collect();
        outputs.write(&root.join("correlation.png"), |p| {
            correlation_png(p, &keys, &id.correlation)
        });
    }
}

/// The name made safe for a file name.
fn file_stem(name: &str) -> String {
    name.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The comment lines of `fitted.toml`.
fn provenance(spec: &FitSpec, outcome: &FitOutcome) -> String {
    let mut lines = vec![
        format!(
            "Fitted by ncform {} from {}",
            env!("CARGO_PKG_VERSION"),
            spec.source.display()
        ),
        format!(
            "starting set: {}; stop: {:?}",
            spec.start.source, outcome.stop
        ),
    ];
    if let Some(id) = &outcome.identifiability {
        lines.push(format!(
            "chi2 = {:.6e} over {} degrees of freedom (variance factor {:.3})",
            id.chi2, id.dof, id.variance_factor
        ));
    }
    for p in &outcome.parameters {
        lines.push(format!(
            "{} = {:.6e} +- {:.3e} (1 sigma; start {:.6e}){}",
            p.key,
            p.value,
            p.sigma,
            p.start,
            if p.at_bound { ", at a bound" } else { "" }
        ));
    }
    lines.push("Units: moduli and stresses in MPa. Report: fit.json beside this file.".into());
    lines.join("\n")
}

fn fit_json<'a>(spec: &'a FitSpec, outcome: &'a FitOutcome) -> FitJson<'a> {
    let parameters = outcome
        .parameters
        .iter()
        .map(|p| {
            (
                p.key.clone(),
                ParameterJson {
                    value: p.value,
                    start: p.start,
                    sigma: p.sigma,
                    relative_sigma: p.sigma / p.value.abs(),
                    bounds: [p.bounds.0, p.bounds.1],
                    at_bound: p.at_bound,
                },
            )
        })
        .collect();
    let mut tests: BTreeMap<String, Vec<MisfitJson>> = BTreeMap::new();
    for m in &outcome.misfits {
        tests.entry(m.test.clone()).or_default().push(MisfitJson {
            quantity: m.quantity.name(),
            points: m.points,
            weighted_rms: m.weighted_rms,
            rms: m.rms,
            unit: m.quantity.unit(),
            interpolation_error: m.interpolation_error,
        });
    }
    let keys: Vec<String> = outcome.parameters.iter().map(|p| p.key.clone()).collect();
    let (correlation, singular_values, weak, chi2, dof, variance_factor) =
        match &outcome.identifiability {
            Some(id) => (
                id.correlation.clone(),
                id.singular_values.clone(),
                id.weak
                    .iter()
                    .map(|w| WeakJson {
                        singular_value: w.singular_value,
                        combination: w
                            .combination
                            .iter()
                            .map(|(i, c)| (keys[*i].clone(), *c))
                            .collect(),
                    })
                    .collect(),
                id.chi2,
                id.dof,
                id.variance_factor,
            ),
            None => (Vec::new(), Vec::new(), Vec::new(), f64::NAN, 0, f64::NAN),
        };
    FitJson {
        units: UNITS,
        fit_file: spec.source.display().to_string(),
        title: &spec.title,
        converged: outcome.converged(),
        stop: format!("{:?}", outcome.stop),
        parameters,
        parameter_order: keys,
        correlation,
        singular_values,
        weak_combinations: weak,
        chi2,
        dof,
        variance_factor,
        iterations: outcome.history.len().saturating_sub(1),
        evaluations: outcome.evaluations,
        seconds: outcome.seconds,
        tests,
        largest_condition: spec
            .tests
            .iter()
            .zip(&outcome.final_runs)
            .map(|(t, r)| {
                let largest = r
                    .points
                    .iter()
                    .filter_map(|p| p.condition)
                    .fold(0.0, f64::max);
                (t.name.clone(), largest)
            })
            .collect(),
        condition_limit: super::run::CONDITION_LIMIT,
        warnings: &outcome.warnings,
        notes: [
            "sigma: 1 sigma of the parameter itself (not of its logarithm), Cov = s2 (J^T W J)^-1 with s2 = max(1, chi2/dof)",
            "the relative force noise is weighted with the measured force",
            "serially correlated noise and model error make sigma optimistic",
        ],
    }
}

/// `fit.csv`: one row per iteration.
fn history_csv(outcome: &FitOutcome) -> String {
    let mut text =
        format!("# ncform fit: iteration history; {UNITS}; parameters in their own units\n");
    let keys: Vec<&str> = outcome.parameters.iter().map(|p| p.key.as_str()).collect();
    text.push_str("iteration,cost,damping,step,accepted,elapsed [s]");
    for k in &keys {
        text.push(',');
        text.push_str(k);
    }
    text.push('\n');
    for (i, it) in outcome.history.iter().enumerate() {
        text.push_str(&format!(
            "{},{:e},{:e},{:e},{},{:.3}",
            it.iteration,
            it.cost,
            it.damping,
            it.step,
            it.accepted,
            outcome.elapsed.get(i).copied().unwrap_or(0.0)
        ));
        for value in outcome.history_values(i).iter() {
            text.push_str(&format!(",{value:e}"));
        }
        text.push('\n');
    }
    text
}

/// `fit_curves.csv`: per test, quantity and scheduled displacement the
/// measured value and σ, the starting and the fitted simulation.
fn curves_csv(spec: &FitSpec, outcome: &FitOutcome) -> String {
    let mut text =
        format!("# ncform fit: measured and simulated curves at the fit's schedule; {UNITS}\n");
    text.push_str("test,quantity,displacement [mm],measured,sigma,start,fitted\n");
    for (t, test) in spec.tests.iter().enumerate() {
        for measured in &test.measured {
            let q = quantity_index(measured.quantity);
            for (k, d) in test.schedule.iter().enumerate() {
                let value = |runs: &[super::evaluate::TestRun]| {
                    runs.get(t)
                        .and_then(|r| r.points.get(k))
                        .map_or(String::new(), |p| format!("{:e}", p.values[q]))
                };
                text.push_str(&format!(
                    "{},{},{d},{:e},{:e},{},{}\n",
                    test.name,
                    measured.quantity.name(),
                    measured.values[k],
                    measured.sigma[k],
                    value(&outcome.start_runs),
                    value(&outcome.final_runs)
                ));
            }
        }
    }
    text
}

/// `fit_<test>.png`: one panel per quantity, measured (every replicate's
/// raw curve), fitted, and the start.
fn curves_png(
    path: &Path,
    spec: &FitSpec,
    outcome: &FitOutcome,
    t: usize,
) -> Result<(), PlotError> {
    let test = &spec.tests[t];
    let mut panels = Vec::new();
    for quantity in Quantity::ALL {
        let Some(measured) = test.quantity(quantity) else {
            continue;
        };
        let q = quantity_index(quantity);
        let curve = |runs: &[super::evaluate::TestRun]| -> Vec<(f64, f64)> {
            runs.get(t)
                .map(|r| {
                    std::iter::once((0.0, 0.0))
                        .filter(|_| quantity == Quantity::Force)
                        .chain(r.points.iter().map(|p| (p.displacement, p.values[q])))
                        .collect()
                })
                .unwrap_or_default()
        };
        let mut series = vec![
            Series {
                label: "measured (schedule)".into(),
                points: test
                    .schedule
                    .iter()
                    .zip(&measured.values)
                    .map(|(d, v)| (*d, *v))
                    .collect(),
            },
            Series {
                label: "fitted".into(),
                points: curve(&outcome.final_runs),
            },
            Series {
                label: "start".into(),
                points: curve(&outcome.start_runs),
            },
        ];
        series.retain(|s| !s.points.is_empty());
        panels.push(Panel {
            title: format!("{}: {}", test.name, quantity.name()),
            x_label: "clamp displacement [mm]".into(),
            y_label: quantity.column().into(),
            series,
        });
    }
    let cols = panels.len().clamp(1, 2);
    let rows = panels.len().div_ceil(cols);
    write_panels(
        path,
        &panels,
        (rows, cols),
        (560 * cols as u32, 420 * rows as u32),
    )
}

/// `correlation.png`: the correlation matrix as a heat map (blue −1, white
/// 0, red +1), each cell labelled.
fn correlation_png(
    path: &Path,
    keys: &[String],
    correlation: &[Vec<f64>],
) -> Result<(), PlotError> {
    ensure_font();
    let fail = |e: &dyn std::fmt::Display| PlotError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let n = keys.len().max(1);
    let cell = 64u32;
    let margin = 170u32;
    let dims = (margin + cell * n as u32 + 20, margin + cell * n as u32 + 40);
    let mut buffer = vec![0; 3 * dims.0 as usize * dims.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, dims).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let title = ("sans-serif", 18).into_font();
        root.draw_text(
            "parameter correlation (blue -1, white 0, red +1)",
            &title.color(&BLACK),
            (10, 8),
        )
        .map_err(|e| fail(&e))?;
        let font = ("sans-serif", 13).into_font();
        for (i, key) in keys.iter().enumerate() {
            let y = (margin + cell * i as u32 + cell / 2 - 6) as i32;
            root.draw_text(key, &font.color(&BLACK), (6, y))
                .map_err(|e| fail(&e))?;
            let x = (margin + cell * i as u32 + 4) as i32;
            root.draw_text(
                key,
                &font.transform(FontTransform::Rotate270).color(&BLACK),
                (x, margin as i32 - 6),
            )
            .map_err(|e| fail(&e))?;
        }
        for (i, row) in correlation.iter().enumerate() {
            for (j, &c) in row.iter().enumerate() {
                let c = if c.is_finite() {
                    c.clamp(-1.0, 1.0)
                } else {
                    0.0
                };
                let fade = |v: f64| (255.0 * (1.0 - v.abs())) as u8;
                let colour = if c >= 0.0 {
                    RGBColor(255, fade(c), fade(c))
                } else {
                    RGBColor(fade(c), fade(c), 255)
                };
                let x0 = (margin + cell * j as u32) as i32;
                let y0 = (margin + cell * i as u32) as i32;
                root.draw(&Rectangle::new(
                    [(x0, y0), (x0 + cell as i32, y0 + cell as i32)],
                    colour.filled(),
                ))
                .map_err(|e| fail(&e))?;
                root.draw(&Rectangle::new(
                    [(x0, y0), (x0 + cell as i32, y0 + cell as i32)],
                    RGBColor(200, 200, 200).stroke_width(1),
                ))
                .map_err(|e| fail(&e))?;
                root.draw_text(
                    &format!("{c:+.2}"),
                    &font.color(&BLACK),
                    (x0 + 12, y0 + cell as i32 / 2 - 6),
                )
                .map_err(|e| fail(&e))?;
            }
        }
        root.present().map_err(|e| fail(&e))?;
    }
    save_png(path, &buffer, dims).map_err(|e| fail(&e))
}
