//! A forming run's histories: `history.csv` / `reactions.png` (every
//! tool's displacement and force, every boundary's reaction, every probe,
//! the contact figures of each step), `forming.csv` / `forming.png`
//! (stroke force, lifts, draw-in and zone means against the stroke) and
//! `energy.csv` / `energy.png` of an explicit run (`docs/cases.md`,
//! "Forming outputs").

use std::path::Path;

use super::readout::{Readout, ZoneValue};
use crate::case::forming::FormingCase;
use crate::case::forming_model::FormingModel;
use crate::post::csv::write_csv;
use crate::post::plot::{Panel, Series, write_panels};
use crate::report::folder::Outputs;
use crate::report::rows::FormingRow;
use crate::report::{UNITS, io_err, plot_suffix};
use crate::solver::{ExplicitRecord, RunStatus};

/// The status line of the file headers, in programme fractions.
pub(crate) fn status_line(status: &RunStatus) -> String {
    crate::report::status_line(
        status,
        |load| format!("programme fraction {load}"),
        |load| load.to_string(),
    )
}

/// `history.csv` and `reactions.png`.
pub(super) fn write_history(
    case: &FormingCase,
    built: &FormingModel,
    out: &Path,
    history: &[FormingRow],
    status: &RunStatus,
    files: &mut Outputs,
) {
    let mut header: Vec<String> = vec!["programme fraction [-]".into(), "time [s]".into()];
    for t in &built.tools {
        header.push(format!("{} displacement [mm]", t.spec.name));
        header.push(format!("{} force [N]", t.spec.name));
    }
    for (i, b) in case.boundaries.iter().enumerate() {
        for axis in ["x", "y", "z"] {
            header.push(format!(
                "boundary {} ({}) reaction {axis} [N]",
                i + 1,
                b.nodes
            ));
        }
    }
    for (i, p) in case.probes.iter().enumerate() {
        for axis in ["x", "y", "z"] {
            header.push(format!(
                "probe {} ({}) displacement {axis} [mm]",
                i + 1,
                p.nodes
            ));
        }
    }
    for h in [
        "iterations [-]",
        "augmentations [-]",
        "max penetration [mm]",
        "multiplier change [-]",
        "closed contacts [-]",
        "slipping contacts [-]",
        "residual [N]",
        "internal energy [N*mm]",
        "stabilisation energy [N*mm]",
        "kinetic energy [N*mm]",
    ] {
        header.push(h.into());
    }
    let rows: Vec<Vec<f64>> = history
        .iter()
        .map(|h| {
            let mut row = vec![h.load, h.time.unwrap_or(0.0)];
            for t in &h.tools {
                row.extend([t.displacement, t.force]);
            }
            for r in &h.reactions {
                row.extend(r);
            }
            for p in &h.probes {
                row.extend(p);
            }
            let (closed, slipping) = h.contacts.unwrap_or((0, 0));
            row.extend([
                h.iterations.unwrap_or(0) as f64,
                h.augmentations.unwrap_or(0) as f64,
                h.max_penetration.unwrap_or(0.0),
                h.multiplier_change.unwrap_or(0.0),
                closed as f64,
                slipping as f64,
                h.residual.unwrap_or(0.0),
                h.internal_energy.unwrap_or(0.0),
                h.stabilisation_energy.unwrap_or(0.0),
                h.kinetic_energy.unwrap_or(0.0),
            ]);
            row
        })
        .collect();
    let path = out.join("history.csv");
    let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
    files.write(&path, |p| write_csv(
        p,
        &[
            "ncform run: forming history (tools, boundary reactions, contact)".to_string(),
            format!("case: {} ({})", case.title, case.source),
            status_line(status),
            "tool force: force of the plies on the tool along its direction (what drives or holds it; positive when the plies resist its motion)".into(),
            format!("units: {UNITS}"),
        ],
        &header_refs,
        &rows,
    )
    .map_err(|e| io_err(&path, e)));
    let panels = reaction_panels(case, built, history, status);
    if panels.is_empty() {
        return;
    }
    let cols = panels.len().min(3);
    let rows = panels.len().div_ceil(cols);
    let path = out.join("reactions.png");
    files.write(&path, |p| {
        write_panels(
            p,
            &panels,
            (rows, cols),
            (600 * cols as u32, 500 * rows as u32),
        )
    });
}

/// `energy.csv` and `energy.png` of an explicit run.
pub(super) fn write_energy(
    case: &FormingCase,
    out: &Path,
    records: &[ExplicitRecord],
    status: &RunStatus,
    files: &mut Outputs,
) {
    crate::report::energy::write_energy(
        out,
        &[
            "ncform run: energy history of the explicit solver".to_string(),
            format!("case: {} ({})", case.title, case.source),
            status_line(status),
            "balance error = internal + contact + kinetic + damping + friction - external work - initial energy; relative to the largest of those".into(),
            format!("units: {UNITS}; energies in N*mm (= mJ)"),
        ],
        records,
        status,
        &crate::report::energy::EnergyAxis {
            header: "programme fraction [-]",
            label: "time [s]",
            value: |r| r.time,
        },
        true,
        files,
    );
}

/// One history row of `forming.csv`.
pub struct BlankRow {
    /// Stroke \[mm\].
    pub stroke: f64,
    /// The stroke tool's force \[N\].
    pub force: f64,
    /// Per floating tool, its lift: displacement against its direction \[mm\].
    pub lifts: Vec<f64>,
    /// Per ply, the draw-in at its points \[mm\].
    pub draw_in: Vec<Vec<f64>>,
    /// Per zone.
    pub zones: Vec<ZoneValue>,
}

/// `forming.csv` and `forming.png`: stroke force, lift of the floating
/// tools, draw-in and zone means against the stroke; `labels`: the files'
/// status line and the stroke's name. Each file is recorded in `files`,
/// whatever became of the other.
pub fn write_forming_history(
    case: &FormingCase,
    built: &FormingModel,
    readout: &Readout,
    rows: &[BlankRow],
    out: &Path,
    (status, stroke_label): (&RunStatus, &str),
    files: &mut Outputs,
) {
    let floating: Vec<&str> = readout
        .floating_tools
        .iter()
        .map(|&t| built.tools[t].spec.name.as_str())
        .collect();
    let stroke_name = readout
        .stroke_tool
        .map_or("stroke", |t| built.tools[t].spec.name.as_str());
    let mut header = vec![
        format!("{stroke_label} [mm]"),
        format!("{stroke_name} force [N]"),
    ];
    for f in &floating {
        header.push(format!("{f} lift [mm]"));
    }
    for (ply, points) in built.plies.iter().zip(readout.points()) {
        for point in points {
            header.push(format!("{} draw-in {} [mm]", ply.name, point.name));
        }
    }
    for z in &case.zones {
        header.push(format!("zone {} shear angle mean [deg]", z.zone.name));
        header.push(format!("zone {} shear angle std [deg]", z.zone.name));
        header.push(format!("zone {} E22 mean [-]", z.zone.name));
        header.push(format!("zone {} E_perp mean [-]", z.zone.name));
        header.push(format!("zone {} mixed-mode 1 share [-]", z.zone.name));
        header.push(format!("zone {} mixed-mode 2 share [-]", z.zone.name));
    }
    let data: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            let mut row = vec![r.stroke, r.force];
            row.extend(&r.lifts);
            for d in &r.draw_in {
                row.extend(d);
            }
            for z in &r.zones {
                row.extend([
                    z.shear_angle_mean,
                    z.shear_angle_std,
                    z.e22_mean,
                    z.e_perp_mean,
                    z.mode_fractions[1],
                    z.mode_fractions[2],
                ]);
            }
            row
        })
        .collect();
    let path = out.join("forming.csv");
    let header_refs: Vec<&str> = header.iter().map(String::as_str).collect();
    let zones: Vec<String> = case
        .zones
        .iter()
        .map(|z| {
            format!(
                "{} on ply \"{}\" centred at [{}, {}] mm, {} x {} mm",
                z.zone.name,
                built.plies[z.ply].name,
                z.zone.centre[0],
                z.zone.centre[1],
                z.zone.size[0],
                z.zone.size[1]
            )
        })
        .collect();
    let mut comments = vec![
        "ncform run: forming history read on the blank".to_string(),
        format!("case: {} ({})", case.title, case.source),
        status_line(status),
        "lift: displacement of a floating tool against its direction (positive when the plies push it back); draw-in: in-plane displacement of the blank's edge midpoints and corners towards the blank's centre (positive inwards)".into(),
        "zones: reference-area-weighted mean and standard deviation over the elements whose reference centroid lies in the window; gamma = I10, E22 = I8 - 1, E_perp = I11 - 1 (paper Section 4)".into(),
    ];
    if !zones.is_empty() {
        comments.push(format!("zones: {}", zones.join("; ")));
    }
    comments.push("units: mm, N; angles in degrees".into());
    files.write(&path, |p| {
        write_csv(p, &comments, &header_refs, &data).map_err(|e| io_err(&path, e))
    });

    let panels = forming_panels(
        (case, built, readout),
        rows,
        (&floating, stroke_name),
        (status, stroke_label),
    );
    let cols = 2.min(panels.len());
    let grid = panels.len().div_ceil(cols);
    let path = out.join("forming.png");
    files.write(&path, |p| {
        write_panels(
            p,
            &panels,
            (grid, cols),
            (700 * cols as u32, 520 * grid as u32),
        )
    });
}

/// The panels of `forming.png`: the stroke force, the floating tools'
/// lift, each ply's draw-in and the zones' mean shear against the stroke.
fn forming_panels(
    (case, built, readout): (&FormingCase, &FormingModel, &Readout),
    rows: &[BlankRow],
    (floating, stroke_name): (&[&str], &str),
    (status, stroke_label): (&RunStatus, &str),
) -> Vec<Panel> {
    let incomplete = plot_suffix(status);
    let x_label = format!("{stroke_label} [mm]");
    let curve = |label: String, f: &dyn Fn(&BlankRow) -> f64| Series {
        label,
        points: rows.iter().map(|r| (r.stroke, f(r))).collect(),
    };
    let mut panels = vec![Panel {
        title: format!("{stroke_name} force{incomplete}"),
        x_label: x_label.clone(),
        y_label: "force [N]".into(),
        series: vec![curve(String::new(), &|r| r.force)],
    }];
    if !floating.is_empty() {
        panels.push(Panel {
            title: format!("lift of the floating tools{incomplete}"),
            x_label: x_label.clone(),
            y_label: "lift [mm]".into(),
            series: floating
                .iter()
                .enumerate()
                .map(|(i, f)| curve((*f).to_string(), &|r| r.lifts[i]))
                .collect(),
        });
    }
    for (p, (ply, points)) in built.plies.iter().zip(readout.points()).enumerate() {
        panels.push(Panel {
            title: format!("draw-in, ply \"{}\"{incomplete}", ply.name),
            x_label: x_label.clone(),
            y_label: "draw-in [mm]".into(),
            series: points
                .iter()
                .enumerate()
                .map(|(k, point)| curve(point.name.clone(), &|r| r.draw_in[p][k]))
                .collect(),
        });
    }
    if !case.zones.is_empty() {
        panels.push(Panel {
            title: format!("zone shear angle (mean){incomplete}"),
            x_label,
            y_label: "shear angle γ [deg]".into(),
            series: case
                .zones
                .iter()
                .enumerate()
                .map(|(k, spec)| {
                    curve(format!("zone {}", spec.zone.name), &|r| {
                        r.zones[k].shear_angle_mean
                    })
                })
                .collect(),
        });
    }
    panels
}

/// The panels of `reactions.png`: each tool's force against its
/// displacement and each boundary's reaction against `λ`.
fn reaction_panels(
    case: &FormingCase,
    built: &FormingModel,
    history: &[FormingRow],
    status: &RunStatus,
) -> Vec<Panel> {
    let suffix = plot_suffix(status);
    let mut panels = Vec::new();
    for (i, t) in built.tools.iter().enumerate() {
        panels.push(Panel {
            title: format!("{}{suffix}", t.spec.name),
            x_label: format!("{} displacement [mm]", t.spec.name),
            y_label: "force [N]".into(),
            series: vec![Series {
                label: "force".into(),
                points: history
                    .iter()
                    .map(|h| (h.tools[i].displacement, h.tools[i].force))
                    .collect(),
            }],
        });
    }
    for (i, b) in case.boundaries.iter().enumerate() {
        panels.push(Panel {
            title: format!("boundary {} ({}){suffix}", i + 1, b.nodes),
            x_label: "programme fraction [-]".into(),
            y_label: "reaction [N]".into(),
            series: ["x", "y", "z"]
                .iter()
                .enumerate()
                .map(|(k, axis)| Series {
                    label: (*axis).into(),
                    points: history
                        .iter()
                        .map(|h| (h.load, h.reactions[i][k]))
                        .collect(),
                })
                .collect(),
        });
    }
    panels
}
