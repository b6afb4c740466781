//! `ncform collect DIR`: one row per point in `DIR/results.csv` — the
//! varied keys, the status, the scalar results of that kind of case, the
//! wall time, the sweep file's responses and whether each point meets its
//! constraints — and the pictures a person looks at: each result against
//! each factor, a map for a two-factor grid, and the sensitivity indices
//! of a Sobol' or Morris design (`docs/studies.md`, "Collecting").

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use plotters::prelude::*;
use serde_json::Value as Json;

use super::sensitivity;
use super::spec::ResponseSource;
use super::sweep::{
    Manifest, Observed, SensitivityDesign, SweepError, observe, observed_name, read_status,
    write_atomic,
};

/// One point's row.
#[derive(Debug, Clone)]
pub struct Row {
    /// The point.
    pub index: usize,
    /// Its state (`complete`, `failed`, `pending`, …).
    pub status: String,
    /// The varied values, in factor order (numbers, or text).
    pub factors: Vec<Json>,
    /// The results by column (`force_final [N]`), in column order.
    pub results: BTreeMap<String, f64>,
    /// Whether it meets every constraint (None: not complete, or no
    /// constraint).
    pub feasible: Option<bool>,
}

/// What `collect` gathered.
#[derive(Debug, Clone)]
pub struct Collected {
    /// The factors' keys.
    pub factors: Vec<String>,
    /// The result columns, in order.
    pub columns: Vec<String>,
    /// The rows.
    pub rows: Vec<Row>,
    /// The files written.
    pub written: Vec<PathBuf>,
    /// The sensitivity indices, as text, when the design has them.
    pub sensitivity: Option<String>,
}

/// Gathers the results of the sweep in `dir` into `results.csv`, the
/// plots in `plots/` and, for a Sobol' or Morris design,
/// `sensitivity.json` and its plot.
///
/// # Errors
/// [`SweepError::Folder`] when the manifest cannot be read or a file
/// cannot be written.
pub fn collect(dir: &Path) -> Result<Collected, SweepError> {
    let manifest = Manifest::load(dir)?;
    let mut columns: Vec<String> = Vec::new();
    let mut rows = Vec::with_capacity(manifest.points.len());
    for p in &manifest.points {
        let observed = observe(dir, &manifest, p.index);
        let pdir = manifest.point_dir(dir, p.index);
        let mut results: Vec<(String, f64)> = Vec::new();
        let summary = read_json(&pdir.join("run/summary.json"));
        if let (Some(summary), Observed::Complete | Observed::Changed(_)) = (&summary, &observed) {
            results.extend(scalar_results(summary));
            for r in &manifest.responses {
                let value = match &r.source {
                    ResponseSource::Summary(path) => {
                        json_path(summary, path).and_then(Json::as_f64)
                    }
                    ResponseSource::History {
                        column,
                        at_column,
                        at,
                    } => history_at(&pdir.join("run"), column, at_column.as_deref(), *at),
                };
                results.push((r.name.clone(), value.unwrap_or(f64::NAN)));
            }
        }
        if let Some(w) = read_status(&pdir).and_then(|s| s.wall_seconds) {
            results.push(("wall_seconds [s]".into(), w));
        }
        for (name, _) in &results {
            if !columns.contains(name) {
                columns.push(name.clone());
            }
        }
        let results: BTreeMap<String, f64> = results.into_iter().collect();
        let feasible = (matches!(observed, Observed::Complete | Observed::Changed(_))
            && !manifest.constraints.is_empty())
        .then(|| {
            manifest.constraints.iter().all(|c| {
                let v = results.get(&c.column).copied().unwrap_or(f64::NAN);
                v.is_finite() && c.min.is_none_or(|m| v >= m) && c.max.is_none_or(|m| v <= m)
            })
        });
        rows.push(Row {
            index: p.index,
            status: observed_name(&observed).to_string(),
            factors: p.values.iter().map(|(_, v)| v.clone()).collect(),
            results,
            feasible,
        });
    }
    // The wall time last, after the case's results and the responses.
    if let Some(i) = columns.iter().position(|c| c == "wall_seconds [s]") {
        let w = columns.remove(i);
        columns.push(w);
    }
    // Constraints on columns no point has are a mistake in the sweep file:
    // say so in the CSV's header rather than judging every point infeasible.
    let mut notes = Vec::new();
    for c in &manifest.constraints {
        if !columns.contains(&c.column) && rows.iter().any(|r| r.status == "complete") {
            notes.push(format!(
                "constraint on '{}': no such column (the columns are: {})",
                c.column,
                columns.join(", ")
            ));
        }
    }
    let mut collected = Collected {
        factors: manifest.factors.clone(),
        columns,
        rows,
        written: Vec::new(),
        sensitivity: None,
    };
    let csv = results_csv(&manifest, &collected, &notes);
    let path = dir.join("results.csv");
    write_atomic(&path, &csv)?;
    collected.written.push(path);
    let plots = dir.join("plots");
    std::fs::create_dir_all(&plots).map_err(|e| SweepError::Folder {
        path: plots.display().to_string(),
        reason: e.to_string(),
    })?;
    let numeric: Vec<bool> = (0..collected.factors.len())
        .map(|f| {
            collected
                .rows
                .iter()
                .all(|r| r.factors[f].as_f64().is_some())
        })
        .collect();
    for column in &collected.columns {
        let path = plots.join(format!("{}.png", file_stem(column)));
        if plot_against_factors(&path, &manifest, &collected, column, &numeric).is_ok() {
            collected.written.push(path);
        }
        if manifest.design == "grid" && collected.factors.len() == 2 {
            let path = plots.join(format!("{}-map.png", file_stem(column)));
            if plot_grid_map(&path, &collected, column).is_ok() {
                collected.written.push(path);
            }
        }
    }
    if let Some(design) = &manifest.sensitivity {
        let (text, json) = sensitivity_of(design, &collected);
        let path = dir.join("sensitivity.json");
        write_atomic(
            &path,
            &serde_json::to_string_pretty(&json).unwrap_or_default(),
        )?;
        collected.written.push(path);
        collected.sensitivity = Some(text);
    }
    Ok(collected)
}

/// Reads a JSON file, if it is one.
fn read_json(path: &Path) -> Option<Json> {
    serde_json::from_str(&std::fs::read_to_string(path).ok()?).ok()
}

/// The value at a dotted path with `[i]` indices (`forces[3][1]`,
/// `defects.final[0].wrinkled_area`).
pub fn json_path<'a>(root: &'a Json, path: &str) -> Option<&'a Json> {
    let mut v = root;
    for part in path.split('.') {
        let (name, rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if !name.is_empty() {
            v = v.get(name)?;
        }
        for idx in rest.split('[').skip(1) {
            let i: usize = idx.strip_suffix(']')?.parse().ok()?;
            v = v.get(i)?;
        }
    }
    Some(v)
}

/// The scalar results of a run's `summary.json`: for an OAT the final and
/// largest force, the final MDZ means and the force at each reported
/// displacement; for a forming run each tool's final and largest force,
/// the stroke, each ply's draw-in at each point and each zone's means at
/// the last state, and each ply's defect areas at the last state.
pub fn scalar_results(summary: &Json) -> Vec<(String, f64)> {
    let mut out = Vec::new();
    let num = |v: Option<&Json>| v.and_then(Json::as_f64);
    let history = summary.get("history").and_then(Json::as_array);
    if summary.get("plies").is_none() {
        // An OAT.
        if let Some(h) = history {
            let forces: Vec<f64> = h.iter().filter_map(|r| num(r.get("force"))).collect();
            if let Some(last) = h.last() {
                if let Some(f) = num(last.get("force")) {
                    out.push(("force_final [N]".into(), f));
                }
                out.push((
                    "force_max [N]".into(),
                    forces.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                ));
                for (key, name) in [
                    ("displacement", "displacement_final [mm]"),
                    ("mdz_shear_angle_deg", "mdz_shear_angle_final [deg]"),
                    ("mdz_e22", "mdz_e22_final [-]"),
                    ("mdz_e_perp", "mdz_e_perp_final [-]"),
                ] {
                    if let Some(v) = num(last.get(key)) {
                        out.push((name.into(), v));
                    }
                }
            }
        }
        if let Some(forces) = summary.get("forces").and_then(Json::as_array) {
            for pair in forces {
                if let (Some(d), Some(f)) = (num(pair.get(0)), num(pair.get(1))) {
                    out.push((format!("force_at_{d}mm [N]"), f));
                }
            }
        }
        return out;
    }
    let tools: Vec<String> = summary
        .get("tools")
        .and_then(Json::as_array)
        .map(|t| {
            t.iter()
                .map(|n| {
                    let s = n.as_str().unwrap_or("tool");
                    s.split(" (").next().unwrap_or(s).to_string()
                })
                .collect()
        })
        .unwrap_or_default();
    if let Some(h) = history {
        for (i, name) in tools.iter().enumerate() {
            let forces: Vec<f64> = h
                .iter()
                .filter_map(|r| {
                    num(r
                        .get("tools")
                        .and_then(|t| t.get(i))
                        .and_then(|t| t.get("force")))
                })
                .collect();
            if let Some(&last) = forces.last() {
                out.push((format!("{name}_force_final [N]"), last));
                out.push((
                    format!("{name}_force_max [N]"),
                    forces.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                ));
            }
        }
        if let Some(s) = h.last().and_then(|r| num(r.get("stroke"))) {
            out.push(("stroke_final [mm]".into(), s));
        }
    }
    let plies: Vec<String> = summary
        .get("plies")
        .and_then(Json::as_array)
        .map(|p| {
            p.iter()
                .map(|x| {
                    x.get("name")
                        .and_then(Json::as_str)
                        .unwrap_or("ply")
                        .to_string()
                })
                .collect()
        })
        .unwrap_or_default();
    let forming = summary.get("forming");
    let last_state = forming
        .and_then(|f| f.get("states"))
        .and_then(Json::as_array)
        .and_then(|s| s.last());
    if let (Some(points), Some(state)) = (
        forming
            .and_then(|f| f.get("draw_in_points"))
            .and_then(Json::as_array),
        last_state,
    ) {
        for (p, ply_points) in points.iter().enumerate() {
            let ply = plies.get(p).cloned().unwrap_or_else(|| format!("ply{p}"));
            for (k, point) in ply_points.as_array().into_iter().flatten().enumerate() {
                let name = point.get(0).and_then(Json::as_str).unwrap_or("point");
                if let Some(v) = num(state
                    .get("draw_in")
                    .and_then(|d| d.get(p))
                    .and_then(|d| d.get(k)))
                {
                    out.push((format!("draw_in {ply} {name} [mm]"), v));
                }
            }
        }
    }
    if let (Some(zones), Some(state)) = (
        forming
            .and_then(|f| f.get("zones"))
            .and_then(Json::as_array),
        last_state,
    ) {
        for (z, zone) in zones.iter().enumerate() {
            let name = zone.get(0).and_then(Json::as_str).unwrap_or("zone");
            let values = state.get("zones").and_then(|v| v.get(z));
            for (key, label) in [
                ("shear_angle_mean", "shear_angle_mean [deg]"),
                ("e22_mean", "e22_mean [-]"),
                ("e_perp_mean", "e_perp_mean [-]"),
            ] {
                if let Some(v) = num(values.and_then(|v| v.get(key))) {
                    out.push((format!("zone {name} {label}"), v));
                }
            }
        }
    }
    if let Some(last) = summary
        .get("defects")
        .and_then(|d| d.get("final"))
        .and_then(Json::as_array)
    {
        for ply in last {
            let name = ply.get("ply").and_then(Json::as_str).unwrap_or("ply");
            for (key, label) in [
                ("wrinkled_area", "wrinkled_area [mm^2]"),
                ("gapping_area", "gapping_area [mm^2]"),
                ("waviness_risk_area", "waviness_risk_area [mm^2]"),
                ("off_tool_area", "off_tool_area [mm^2]"),
                ("max_gap_width", "max_gap_width [mm]"),
            ] {
                if let Some(v) = num(ply.get(key)) {
                    out.push((format!("{name} {label}"), v));
                }
            }
        }
    }
    out
}

/// The value of the history column `column` where the column `at_column`
/// (default: the first) equals `at`, linearly interpolated, from the run
/// folder's history CSV (`force_displacement.csv` of an OAT,
/// `forming.csv` of a forming run); `None` outside the recorded range.
pub fn history_at(run: &Path, column: &str, at_column: Option<&str>, at: f64) -> Option<f64> {
    let text = ["force_displacement.csv", "forming.csv"]
        .iter()
        .find_map(|f| std::fs::read_to_string(run.join(f)).ok())?;
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let header: Vec<&str> = lines.next()?.split(',').map(str::trim).collect();
    let c = header.iter().position(|h| *h == column)?;
    let a = match at_column {
        Some(name) => header.iter().position(|h| *h == name)?,
        None => 0,
    };
    let rows: Vec<(f64, f64)> = lines
        .filter_map(|l| {
            let cells: Vec<&str> = l.split(',').collect();
            Some((
                cells.get(a)?.trim().parse().ok()?,
                cells.get(c)?.trim().parse().ok()?,
            ))
        })
        .collect();
    for w in rows.windows(2) {
        let ((x0, y0), (x1, y1)) = (w[0], w[1]);
        if (x0 - at) * (x1 - at) <= 0.0 && x0 != x1 {
            return Some(y0 + (at - x0) / (x1 - x0) * (y1 - y0));
        }
    }
    rows.iter().find(|(x, _)| *x == at).map(|(_, y)| *y)
}

/// A CSV cell for a factor value.
fn cell(v: &Json) -> String {
    match v {
        Json::String(s) => format!("\"{}\"", s.replace('"', "\"\"")),
        Json::Number(n) => n.to_string(),
        other => format!("\"{}\"", other.to_string().replace('"', "\"\"")),
    }
}

/// A CSV cell for a result (empty when absent).
fn number(v: Option<&f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x}"),
        _ => String::new(),
    }
}

/// The text of `results.csv`.
fn results_csv(manifest: &Manifest, c: &Collected, notes: &[String]) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "# ncform sweep results: {} ({} points, design {})",
        manifest.title,
        c.rows.len(),
        manifest.design
    );
    let _ = writeln!(
        out,
        "# units: {}; each column's unit is in its name; factors are the case keys",
        manifest.units
    );
    let _ = writeln!(
        out,
        "# status: complete | changed (complete, but its inputs or the ncform binary changed since it ran) | failed | interrupted | running | pending; results only for complete and changed points"
    );
    for con in &manifest.constraints {
        let _ = writeln!(
            out,
            "# constraint: {}{}{}",
            con.column,
            con.min.map_or(String::new(), |m| format!(" >= {m}")),
            con.max.map_or(String::new(), |m| format!(" <= {m}"))
        );
    }
    for n in notes {
        let _ = writeln!(out, "# warning: {n}");
    }
    let mut header = vec!["point".to_string()];
    header.extend(c.factors.iter().cloned());
    header.push("status".into());
    header.extend(c.columns.iter().cloned());
    if !manifest.constraints.is_empty() {
        header.push("feasible".into());
    }
    out.push_str(
        &header
            .iter()
            .map(|h| {
                if h.contains(',') {
                    format!("\"{h}\"")
                } else {
                    h.clone()
                }
            })
            .collect::<Vec<_>>()
            .join(","),
    );
    out.push('\n');
    for r in &c.rows {
        let mut cells = vec![r.index.to_string()];
        cells.extend(r.factors.iter().map(cell));
        cells.push(r.status.clone());
        cells.extend(c.columns.iter().map(|k| number(r.results.get(k))));
        if !manifest.constraints.is_empty() {
            cells.push(match r.feasible {
                Some(true) => "yes".into(),
                Some(false) => "no".into(),
                None => String::new(),
            });
        }
        out.push_str(&cells.join(","));
        out.push('\n');
    }
    out
}

/// A column name made safe for a file name: the run files' stem
/// ([`crate::report::forming::file_stem`]) without leading, trailing or
/// doubled underscores (`force_final [N]` → `force_final_N`).
pub fn file_stem(name: &str) -> String {
    crate::report::forming::file_stem(name)
        .trim_matches('_')
        .replace("__", "_")
}

/// Colours: feasible (or unconstrained) points, infeasible points.
const FEASIBLE: RGBColor = RGBColor(31, 119, 180);
const INFEASIBLE: RGBColor = RGBColor(214, 39, 40);

/// `plots/<column>.png`: the column against each numeric factor, one
/// panel per factor; infeasible points as red crosses. In a grid the
/// points that differ only in the panel's factor are joined by lines.
fn plot_against_factors(
    path: &Path,
    manifest: &Manifest,
    c: &Collected,
    column: &str,
    numeric: &[bool],
) -> Result<(), String> {
    crate::post::plot::ensure_font();
    let factors: Vec<usize> = (0..c.factors.len()).filter(|&f| numeric[f]).collect();
    if factors.is_empty() {
        return Err("no numeric factor".into());
    }
    let cols = factors.len().min(3);
    let rows_n = factors.len().div_ceil(cols);
    let dims = (480 * cols as u32, 380 * rows_n as u32 + 40);
    let mut buffer = vec![0u8; 3 * dims.0 as usize * dims.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, dims).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let root = root
            .titled(
                &format!("{} — {column}", manifest.title),
                ("sans-serif", 20),
            )
            .map_err(|e| e.to_string())?;
        let areas = root.split_evenly((rows_n, cols));
        for (&f, area) in factors.iter().zip(areas.iter()) {
            let pts: Vec<(f64, f64, Option<bool>, usize)> = c
                .rows
                .iter()
                .filter_map(|r| {
                    let x = r.factors[f].as_f64()?;
                    let y = *r.results.get(column)?;
                    y.is_finite().then_some((x, y, r.feasible, r.index))
                })
                .collect();
            let (x0, x1) = span(pts.iter().map(|p| p.0));
            let (y0, y1) = span(pts.iter().map(|p| p.1));
            let mut chart = ChartBuilder::on(area)
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc(c.factors[f].as_str())
                .y_desc(column)
                .label_style(("sans-serif", 14))
                .light_line_style(RGBColor(235, 235, 235))
                .draw()
                .map_err(|e| e.to_string())?;
            if manifest.design == "grid" {
                // Lines through the points equal in every other factor.
                let mut groups: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
                for r in &c.rows {
                    let (Some(x), Some(y)) = (r.factors[f].as_f64(), r.results.get(column)) else {
                        continue;
                    };
                    let key: String = r
                        .factors
                        .iter()
                        .enumerate()
                        .filter(|(g, _)| *g != f)
                        .map(|(_, v)| v.to_string())
                        .collect::<Vec<_>>()
                        .join(",");
                    groups.entry(key).or_default().push((x, *y));
                }
                for (i, (label, mut line)) in groups.into_iter().enumerate() {
                    line.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let colour = crate::post::plot::palette(i);
                    let series = chart
                        .draw_series(LineSeries::new(line, colour.stroke_width(1)))
                        .map_err(|e| e.to_string())?;
                    if !label.is_empty() && c.factors.len() == 2 {
                        let other = c.factors[1 - f].clone();
                        series
                            .label(format!("{other} = {label}"))
                            .legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2))
                            });
                    }
                }
                if c.factors.len() == 2 {
                    chart
                        .configure_series_labels()
                        .background_style(WHITE.mix(0.85))
                        .border_style(BLACK)
                        .label_font(("sans-serif", 13))
                        .position(SeriesLabelPosition::UpperLeft)
                        .draw()
                        .map_err(|e| e.to_string())?;
                }
            }
            chart
                .draw_series(pts.iter().map(|&(x, y, feasible, _)| {
                    let colour = if feasible == Some(false) {
                        INFEASIBLE
                    } else {
                        FEASIBLE
                    };
                    if feasible == Some(false) {
                        Cross::new((x, y), 5, colour.stroke_width(2)).into_dyn()
                    } else {
                        Circle::new((x, y), 4, colour.filled()).into_dyn()
                    }
                }))
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    crate::post::plot::save_png(path, &buffer, dims).map_err(|e| e.to_string())
}

/// The range of `values` with a margin (a unit range around a single
/// value).
fn span(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !(lo.is_finite() && hi.is_finite()) {
        (0.0, 1.0)
    } else if hi - lo <= f64::EPSILON * hi.abs().max(1.0) {
        (lo - 0.5 * lo.abs().max(1.0), hi + 0.5 * hi.abs().max(1.0))
    } else {
        let m = 0.06 * (hi - lo);
        (lo - m, hi + m)
    }
}

/// `plots/<column>-map.png` of a two-factor grid: one cell per point,
/// coloured by the column on one shared scale (viridis), the value
/// written in the cell; infeasible cells crossed, points without a result
/// grey.
fn plot_grid_map(path: &Path, c: &Collected, column: &str) -> Result<(), String> {
    crate::post::plot::ensure_font();
    let levels = |f: usize| -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for r in &c.rows {
            let s = r.factors[f].to_string();
            if !v.contains(&s) {
                v.push(s);
            }
        }
        v
    };
    let (xs, ys) = (levels(0), levels(1));
    let values: Vec<f64> = c
        .rows
        .iter()
        .filter_map(|r| r.results.get(column).copied())
        .filter(|v| v.is_finite())
        .collect();
    let (lo, hi) = values
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
            (a.min(v), b.max(v))
        });
    let dims = (760u32, 620u32);
    let mut buffer = vec![0u8; 3 * dims.0 as usize * dims.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, dims).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!("{column} (colour: {lo:.4} to {hi:.4}; × infeasible)"),
                ("sans-serif", 18),
            )
            .margin(14)
            .x_label_area_size(50)
            .y_label_area_size(90)
            .build_cartesian_2d(
                -0.5f64..xs.len() as f64 - 0.5,
                -0.5f64..ys.len() as f64 - 0.5,
            )
            .map_err(|e| e.to_string())?;
        let (xl, yl) = (xs.clone(), ys.clone());
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(xs.len())
            .y_labels(ys.len())
            .x_label_formatter(&move |v| label_at(&xl, *v))
            .y_label_formatter(&move |v| label_at(&yl, *v))
            .x_desc(c.factors[0].as_str())
            .y_desc(c.factors[1].as_str())
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(|e| e.to_string())?;
        for r in &c.rows {
            let (Some(i), Some(j)) = (
                xs.iter()
                    .position(|s| s.as_str() == r.factors[0].to_string().as_str()),
                ys.iter()
                    .position(|s| s.as_str() == r.factors[1].to_string().as_str()),
            ) else {
                continue;
            };
            let (x, y) = (i as f64 - 0.5, j as f64 - 0.5);
            let value = r.results.get(column).copied().filter(|v| v.is_finite());
            let colour = match value {
                Some(v) => {
                    let t = if hi > lo { (v - lo) / (hi - lo) } else { 0.5 };
                    let [cr, cg, cb] = crate::post::contour::viridis(t);
                    RGBColor(cr, cg, cb)
                }
                None => RGBColor(200, 200, 200),
            };
            chart
                .draw_series(std::iter::once(Rectangle::new(
                    [(x + 0.02, y + 0.02), (x + 0.98, y + 0.98)],
                    colour.filled(),
                )))
                .map_err(|e| e.to_string())?;
            let text = value.map_or_else(|| r.status.clone(), |v| format!("{v:.4}"));
            let ink = if value.is_some_and(|v| hi > lo && (v - lo) / (hi - lo) > 0.6) {
                BLACK
            } else {
                WHITE
            };
            chart
                .draw_series(std::iter::once(Text::new(
                    text,
                    (x + 0.1, y + 0.55),
                    ("sans-serif", 15).into_font().color(&ink),
                )))
                .map_err(|e| e.to_string())?;
            if r.feasible == Some(false) {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(x + 0.1, y + 0.1), (x + 0.9, y + 0.9)],
                        INFEASIBLE.stroke_width(3),
                    )))
                    .map_err(|e| e.to_string())?;
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(x + 0.1, y + 0.9), (x + 0.9, y + 0.1)],
                        INFEASIBLE.stroke_width(3),
                    )))
                    .map_err(|e| e.to_string())?;
            }
        }
        root.present().map_err(|e| e.to_string())?;
    }
    crate::post::plot::save_png(path, &buffer, dims).map_err(|e| e.to_string())
}

/// The level label at the middle of cell `v` (none between cells).
fn label_at(levels: &[String], v: f64) -> String {
    let i = v.round();
    if (v - i).abs() < 0.01 && i >= 0.0 {
        levels.get(i as usize).cloned().unwrap_or_default()
    } else {
        String::new()
    }
}

/// The sensitivity indices of every result column: text for the terminal
/// and the JSON of `sensitivity.json`.
fn sensitivity_of(design: &SensitivityDesign, c: &Collected) -> (String, Json) {
    let mut text = String::new();
    let mut json = serde_json::Map::new();
    for column in &c.columns {
        let y: Vec<f64> = c
            .rows
            .iter()
            .map(|r| r.results.get(column).copied().unwrap_or(f64::NAN))
            .collect();
        match design {
            SensitivityDesign::Sobol { n, d } => match sensitivity::sobol_indices(&y, *n, *d) {
                Ok(s) => {
                    let _ = writeln!(text, "{column}: Sobol' first-order / total");
                    for (f, key) in c.factors.iter().enumerate() {
                        let _ = writeln!(
                            text,
                            "  {key}: S1 = {:.3} ± {:.3}, ST = {:.3} ± {:.3}",
                            s.first[f], s.first_ci[f], s.total[f], s.total_ci[f]
                        );
                    }
                    json.insert(
                        column.clone(),
                        serde_json::json!({
                            "factors": c.factors, "first": s.first, "first_ci95": s.first_ci,
                            "total": s.total, "total_ci95": s.total_ci, "variance": s.variance,
                        }),
                    );
                }
                Err(e) => {
                    json.insert(
                        column.clone(),
                        serde_json::json!({ "error": e.to_string() }),
                    );
                }
            },
            SensitivityDesign::Morris { steps, scale } => {
                let m = super::design::MorrisDesign {
                    points: Vec::new(),
                    steps: steps
                        .iter()
                        .map(
                            |&(trajectory, from, to, factor, delta)| super::design::MorrisStep {
                                trajectory,
                                from,
                                to,
                                factor,
                                delta,
                            },
                        )
                        .collect(),
                };
                match sensitivity::morris_effects(&m, &y, scale) {
                    Ok(e) => {
                        let _ = writeln!(
                            text,
                            "{column}: Morris mu* / sigma (per unit of the factor)"
                        );
                        for (f, key) in c.factors.iter().enumerate() {
                            let _ = writeln!(
                                text,
                                "  {key}: mu* = {:.4e}, sigma = {:.4e} ({} effects)",
                                e.mu_star[f], e.sigma[f], e.count[f]
                            );
                        }
                        json.insert(column.clone(), serde_json::json!({
                            "factors": c.factors, "mu": e.mu, "mu_star": e.mu_star, "sigma": e.sigma, "effects": e.count,
                        }));
                    }
                    Err(e) => {
                        json.insert(
                            column.clone(),
                            serde_json::json!({ "error": e.to_string() }),
                        );
                    }
                }
            }
        }
    }
    (text, Json::Object(json))
}
