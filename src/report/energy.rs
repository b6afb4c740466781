//! `energy.csv` and `energy.png`: the energy history of an explicit run,
//! the same writer for off-axis tension tests and forming cases.

use std::path::Path;

use super::folder::Outputs;
use crate::post::csv::write_csv;
use crate::post::plot::{Panel, Series, write_panels};
use crate::solver::{ExplicitRecord, RunStatus};

/// What the history is plotted against.
pub(crate) struct EnergyAxis {
    /// CSV header of the second column, the load parameter (the first is
    /// the time), e.g. `displacement [mm]`.
    pub header: &'static str,
    /// Axis label of the plots.
    pub label: &'static str,
    /// The plotted abscissa of a record.
    pub value: fn(&ExplicitRecord) -> f64,
}

/// Writes `energy.csv` (with `preamble` as its comment lines) and
/// `energy.png` into `out` for a run that ended with `status`, each
/// recorded in `files` (a failure of one does not stop the other). With
/// `with_contact`, the columns of contact, load work and friction are
/// added (forming); the others are those of every explicit run.
pub(crate) fn write_energy(
    out: &Path,
    preamble: &[String],
    records: &[ExplicitRecord],
    status: &RunStatus,
    axis: &EnergyAxis,
    with_contact: bool,
    files: &mut Outputs,
) {
    let path = out.join("energy.csv");
    let mut header = vec![
        "time [s]",
        axis.header,
        "internal [N*mm]",
        "kinetic [N*mm]",
        "external work [N*mm]",
        "damping [N*mm]",
    ];
    if with_contact {
        header.extend(["contact [N*mm]", "load work [N*mm]", "friction [N*mm]"]);
    }
    header.extend([
        "balance error [N*mm]",
        "relative balance error [-]",
        "kinetic/internal [-]",
    ]);
    let rows: Vec<Vec<f64>> = records
        .iter()
        .map(|r| {
            let e = &r.energies;
            let mut row = vec![
                r.time,
                r.load,
                e.internal,
                e.kinetic,
                e.external_work,
                e.damping,
            ];
            if with_contact {
                row.extend([e.contact, e.load_work, e.friction]);
            }
            row.extend([e.balance_error, e.relative_balance_error, e.kinetic_ratio()]);
            row
        })
        .collect();
    files.write(&path, |p| {
        write_csv(p, preamble, &header, &rows).map_err(|e| format!("{}: {e}", path.display()))
    });
    let series = |label: &str, f: fn(&ExplicitRecord) -> f64| Series {
        label: label.to_string(),
        points: records.iter().map(|r| ((axis.value)(r), f(r))).collect(),
    };
    let suffix = super::plot_suffix(status);
    let mut energies = vec![
        series("internal", |r| r.energies.internal),
        series("external work", |r| r.energies.external_work),
        series("kinetic", |r| r.energies.kinetic),
        series("damping", |r| r.energies.damping),
    ];
    if with_contact {
        energies.extend([
            series("contact", |r| r.energies.contact),
            series("friction", |r| r.energies.friction),
        ]);
    }
    let path = out.join("energy.png");
    files.write(&path, |p| {
        write_panels(
            p,
            &[
                Panel {
                    title: format!("energies{suffix}"),
                    x_label: axis.label.into(),
                    y_label: "energy [N*mm]".into(),
                    series: energies,
                },
                Panel {
                    title: "kinetic / stored energy".into(),
                    x_label: axis.label.into(),
                    y_label: "KE / (IE + CE) [%]".into(),
                    series: vec![series("KE/(IE+CE)", |r| 100.0 * r.energies.kinetic_ratio())],
                },
                Panel {
                    title: "energy balance error".into(),
                    x_label: axis.label.into(),
                    y_label: "log10 of the relative balance error [-]".into(),
                    // Near round-off (1e-12 … 1e-9): a logarithmic scale reads.
                    series: vec![series("log10(|balance| / scale)", |r| {
                        r.energies.relative_balance_error.max(1e-300).log10()
                    })],
                },
            ],
            (1, 3),
            (1800, 550),
        )
    });
}
