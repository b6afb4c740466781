//! `ncform material curves`: the stress functions of W6, W8, W11, the
//! coupling k11 and the energy contributions over their working range, as
//! CSV and PNG (like the paper's Fig. 2b, 2c and 5), so a user sees what a
//! parameter set means.

use std::path::{Path, PathBuf};

use crate::material::{GeneralizedTerm, Material, MaterialSpec, UdNcf};
use crate::post::csv::write_csv;
use crate::post::plot::{Panel, Series, write_panels};

/// Number of samples per curve.
pub const SAMPLES: usize = 401;
/// Working range of `|I6|` (up to `sin 60°`, beyond the largest OAT shear).
pub const SHEAR_RANGE: (f64, f64) = (0.0, 0.866);
/// Working range of `E22 = I8 − 1`.
pub const STITCHING_RANGE: (f64, f64) = (0.0, 0.4);
/// Working range of the compaction `1 − I11`.
pub const COMPACTION_RANGE: (f64, f64) = (0.0, 0.7);
/// Working range of `I11` for the coupling.
pub const COUPLING_RANGE: (f64, f64) = (0.3, 1.1);
/// `I11` values at which the coupled transverse stress `k11 f8` is drawn.
pub const COUPLED_I11: [f64; 4] = [0.9, 0.8, 0.7, 0.6];

fn samples((lo, hi): (f64, f64)) -> impl Iterator<Item = f64> {
    (0..SAMPLES).map(move |i| lo + (hi - lo) * i as f64 / (SAMPLES - 1) as f64)
}

/// Rows `[x, f, f′, G]` of a generalized term over `range`.
fn term_rows(term: &GeneralizedTerm, range: (f64, f64)) -> Vec<Vec<f64>> {
    samples(range)
        .map(|x| {
            let v = term.eval(x);
            vec![x, v.stress, v.modulus, v.energy]
        })
        .collect()
}

fn column(rows: &[Vec<f64>], x: usize, y: usize) -> Vec<(f64, f64)> {
    rows.iter().map(|r| (r[x], r[y])).collect()
}

fn describe(term: &GeneralizedTerm) -> String {
    let mut s = format!("C_ini = {} MPa", term.c_ini);
    if let Some(t) = term.transition {
        s += &format!(
            ", S_ini = {} MPa, C_mid = {} MPa, delta_S_mid = {} MPa (x_t = {:.6})",
            t.s_ini,
            t.c_mid,
            t.delta_s_mid,
            term.transition_point()
        );
    }
    if let Some(l) = term.lock {
        s += &format!(", C_lock = {} MPa, I_lock = {}", l.c_lock, l.i_lock);
    }
    s
}

/// Why the curves of a parameter set cannot be drawn or written.
#[derive(Debug, thiserror::Error)]
pub enum CurvesError {
    /// The set is not a UD-NCF law.
    #[error("{source_file}: material curves needs a UD-NCF parameter set (law = \"ud-ncf\")")]
    NotUdNcf {
        /// The parameter file or set.
        source_file: String,
    },
    /// A term's stress, modulus or energy overflows in the plotted range.
    #[error(
        "{source_file}: [{term}]: the {quantity} is {value} at {x_name} = {x}: the parameters overflow the law within the plotted range {range:?}; expected moduli and stresses that stay finite (nothing written)"
    )]
    TermOverflow {
        /// The parameter file or set.
        source_file: String,
        /// The term (`w6`, `w8`, `w11`).
        term: &'static str,
        /// The quantity (stress, modulus, energy).
        quantity: &'static str,
        /// Its value.
        value: f64,
        /// The term's argument.
        x_name: &'static str,
        /// Where.
        x: f64,
        /// The plotted range.
        range: (f64, f64),
    },
    /// The coupling overflows in the plotted range.
    #[error(
        "{source_file}: [coupling]: k11 = {k}, dk11/dI11 = {dk} at I11 = {i11}: expected finite values (nothing written)"
    )]
    CouplingOverflow {
        /// The parameter file or set.
        source_file: String,
        /// `k11`.
        k: f64,
        /// `dk11/dI11`.
        dk: f64,
        /// Where.
        i11: f64,
    },
    /// A file or the folder could not be written.
    #[error("{path}: {error}")]
    Write {
        /// The path.
        path: String,
        /// Why.
        error: std::io::Error,
    },
    /// A picture could not be drawn or written.
    #[error("{0}")]
    Plot(#[from] crate::post::plot::PlotError),
}

/// Refuses a parameter set whose stress functions, moduli, energies or
/// coupling are not finite somewhere in the plotted ranges (huge moduli
/// overflow): the message names the set, the term, the quantity and `x`,
/// and nothing is written.
fn check_finite(spec: &MaterialSpec, law: &UdNcf) -> Result<(), CurvesError> {
    let terms = [
        ("w6", "x = |I6|", &law.w6, SHEAR_RANGE),
        ("w8", "x = I8 - 1", &law.w8, STITCHING_RANGE),
        ("w11", "x = 1 - I11", &law.w11, COMPACTION_RANGE),
    ];
    for (name, x_name, term, range) in terms {
        for row in term_rows(term, range) {
            for (value, quantity) in row[1..].iter().zip(["stress f", "modulus df", "energy W"]) {
                if !value.is_finite() {
                    return Err(CurvesError::TermOverflow {
                        source_file: spec.source.clone(),
                        term: name,
                        quantity,
                        value: *value,
                        x_name,
                        x: row[0],
                        range,
                    });
                }
            }
        }
    }
    for i11 in samples(COUPLING_RANGE) {
        let k = law.coupling.eval(i11);
        if !(k.k.is_finite() && k.dk.is_finite()) {
            return Err(CurvesError::CouplingOverflow {
                source_file: spec.source.clone(),
                k: k.k,
                dk: k.dk,
                i11,
            });
        }
    }
    Ok(())
}

/// The UD-NCF law of `spec` if its curves can be drawn: a UD-NCF set whose
/// values stay finite over the plotted ranges. [`write_curves`] checks
/// this first; a caller can check it alone to tell bad input from a write
/// failure.
///
/// # Errors
/// Another law, or values that overflow, naming the set.
pub fn curves_law(spec: &MaterialSpec) -> Result<UdNcf, CurvesError> {
    let Material::UdNcf(law) = spec.material else {
        return Err(CurvesError::NotUdNcf {
            source_file: spec.source.clone(),
        });
    };
    check_finite(spec, &law)?;
    Ok(law)
}

/// Writes the curves of a UD-NCF parameter set into `out` and returns the
/// files written.
///
/// # Errors
/// A message naming the file on I/O failure, or when the set is not a
/// UD-NCF law.
pub fn write_curves(spec: &MaterialSpec, out: &Path) -> Result<Vec<PathBuf>, CurvesError> {
    write_law_curves(spec, &curves_law(spec)?, out)
}

/// As [`write_curves`] for the law [`curves_law`] returned for `spec`.
///
/// # Errors
/// A message naming the file on I/O failure.
pub fn write_law_curves(
    spec: &MaterialSpec,
    law: &UdNcf,
    out: &Path,
) -> Result<Vec<PathBuf>, CurvesError> {
    let law = *law;
    let io = |path: &Path, error: std::io::Error| CurvesError::Write {
        path: path.display().to_string(),
        error,
    };
    std::fs::create_dir_all(out).map_err(|e| io(out, e))?;
    let mut written = Vec::new();
    let preamble = |what: &str, term: Option<&GeneralizedTerm>| {
        let mut lines = vec![
            format!("ncform material curves: {what}"),
            format!("parameter set: {} ({})", spec.name, spec.source),
            "units: stresses, moduli and energy densities in MPa; invariants dimensionless"
                .to_string(),
        ];
        if let Some(t) = term {
            lines.push(format!("parameters: {}", describe(t)));
        }
        lines
    };

    // W6: shear, x = |I6|; also the trellis-shear angle asin(I6).
    let w6 = term_rows(&law.w6, SHEAR_RANGE);
    let w6_rows: Vec<Vec<f64>> = w6
        .iter()
        .map(|r| vec![r[0], r[0].asin().to_degrees(), r[1], r[2], r[3]])
        .collect();
    let path = out.join("w6_shear.csv");
    write_csv(
        &path,
        &preamble(
            "W6 shear term, x = |I6|; gamma = asin(I6) for trellis shear",
            Some(&law.w6),
        ),
        &[
            "I6 [-]",
            "trellis_shear_angle [deg]",
            "f6 [MPa]",
            "df6 [MPa]",
            "W6 [MPa]",
        ],
        &w6_rows,
    )
    .map_err(|e| io(&path, e))?;
    written.push(path);

    // W8: stitching tension, x = I8 − 1, and k11·f8 at several I11.
    let w8 = term_rows(&law.w8, STITCHING_RANGE);
    let k_at: Vec<f64> = COUPLED_I11
        .iter()
        .map(|&i| law.coupling.eval(i).k)
        .collect();
    let w8_rows: Vec<Vec<f64>> = w8
        .iter()
        .map(|r| {
            let mut row = r.clone();
            row.extend(k_at.iter().map(|k| k * r[1]));
            row
        })
        .collect();
    let coupled_names: Vec<String> = COUPLED_I11
        .iter()
        .map(|i| format!("k11*f8 at I11={i} [MPa]"))
        .collect();
    let mut w8_columns = vec![
        "E22 = I8-1 [-]",
        "f8 [MPa]",
        "df8 [MPa]",
        "W8 at k11=1 [MPa]",
    ];
    w8_columns.extend(coupled_names.iter().map(String::as_str));
    let path = out.join("w8_transverse_tension.csv");
    write_csv(
        &path,
        &preamble(
            "W8 transverse tension term, x = I8 - 1 (active for I8 > 1)",
            Some(&law.w8),
        ),
        &w8_columns,
        &w8_rows,
    )
    .map_err(|e| io(&path, e))?;
    written.push(path);

    // W11: compaction, x = 1 − I11.
    let w11 = term_rows(&law.w11, COMPACTION_RANGE);
    let w11_rows: Vec<Vec<f64>> = w11
        .iter()
        .map(|r| vec![1.0 - r[0], r[0], r[1], r[2], r[3]])
        .collect();
    let path = out.join("w11_compaction.csv");
    write_csv(
        &path,
        &preamble(
            "W11 compaction term, x = 1 - I11 (active for I11 < 1)",
            Some(&law.w11),
        ),
        &[
            "I11 [-]",
            "1-I11 [-]",
            "f11 [MPa]",
            "df11 [MPa]",
            "W11 [MPa]",
        ],
        &w11_rows,
    )
    .map_err(|e| io(&path, e))?;
    written.push(path);

    // k11 coupling.
    let k_rows: Vec<Vec<f64>> = samples(COUPLING_RANGE)
        .map(|i11| {
            let k = law.coupling.eval(i11);
            vec![i11, k.k, k.dk]
        })
        .collect();
    let path = out.join("k11_coupling.csv");
    let c = law.coupling;
    write_csv(
        &path,
        &[
            "ncform material curves: coupling k11(I11) (Eq. 15, corrected)".to_string(),
            format!("parameter set: {} ({})", spec.name, spec.source),
            format!(
                "parameters: k_min = {}, s11 = {}, e11 = {}",
                c.k_min, c.s11, c.e11
            ),
            "units: dimensionless".to_string(),
        ],
        &["I11 [-]", "k11 [-]", "dk11/dI11 [-]"],
        &k_rows,
    )
    .map_err(|e| io(&path, e))?;
    written.push(path);

    written.extend(write_pngs(
        spec, &law, out, &w6_rows, &w8_rows, &w11_rows, &k_rows,
    )?);
    Ok(written)
}

#[allow(clippy::too_many_arguments)]
fn write_pngs(
    spec: &MaterialSpec,
    law: &UdNcf,
    out: &Path,
    w6: &[Vec<f64>],
    w8: &[Vec<f64>],
    w11: &[Vec<f64>],
    k: &[Vec<f64>],
) -> Result<Vec<PathBuf>, CurvesError> {
    let series = |label: &str, points| Series {
        label: label.to_string(),
        points,
    };
    let mut coupled: Vec<Series> = COUPLED_I11
        .iter()
        .enumerate()
        .map(|(i, i11)| series(&format!("k11 f8, I11 = {i11}"), column(w8, 0, 4 + i)))
        .collect();
    coupled.insert(0, series("f8 (k11 = 1)", column(w8, 0, 1)));
    let stress = [
        Panel {
            title: format!("Shear W6 ({})", spec.name),
            x_label: "|I6| [-]".into(),
            y_label: "f6 [MPa]".into(),
            series: vec![series("f6", column(w6, 0, 2))],
        },
        Panel {
            title: "Transverse tension W8, coupled".into(),
            x_label: "E22 = I8 - 1 [-]".into(),
            y_label: "k11 f8 [MPa]".into(),
            series: coupled,
        },
        Panel {
            title: "Compaction W11".into(),
            x_label: "1 - I11 [-]".into(),
            y_label: "f11 [MPa]".into(),
            series: vec![series("f11", column(w11, 1, 2))],
        },
        Panel {
            title: format!(
                "Coupling k11 (k_min = {}, s11 = {}, e11 = {})",
                law.coupling.k_min, law.coupling.s11, law.coupling.e11
            ),
            x_label: "I11 [-]".into(),
            y_label: "k11 [-]".into(),
            series: vec![series("k11", column(k, 0, 1))],
        },
    ];
    let stress_png = out.join("stress_functions.png");
    write_panels(&stress_png, &stress, (2, 2), (1400, 1000))?;

    let energy = [
        Panel {
            title: "W6 shear energy".into(),
            x_label: "|I6| [-]".into(),
            y_label: "W6 [MPa]".into(),
            series: vec![series("W6", column(w6, 0, 4))],
        },
        Panel {
            title: "W8 transverse tension energy (k11 = 1)".into(),
            x_label: "E22 = I8 - 1 [-]".into(),
            y_label: "W8 [MPa]".into(),
            series: vec![series("W8", column(w8, 0, 3))],
        },
        Panel {
            title: "W11 compaction energy".into(),
            x_label: "1 - I11 [-]".into(),
            y_label: "W11 [MPa]".into(),
            series: vec![series("W11", column(w11, 1, 4))],
        },
    ];
    let energy_png = out.join("energy_contributions.png");
    write_panels(&energy_png, &energy, (1, 3), (1800, 550))?;
    Ok(vec![stress_png, energy_png])
}
