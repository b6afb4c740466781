//! Measured data of an off-axis tension test for `ncform fit`: one CSV
//! file per specimen ([`read_measured`]), its conversion from image
//! correlation (DIC) strains to ncform's strain measures
//! ([`dic_to_measures`]), and the resampling of the replicates to the
//! fit's schedule of displacements ([`MeasuredQuantity`]). File format,
//! conversion formulas and the resampling rules: `docs/fit.md`,
//! "Measured data".

use std::path::{Path, PathBuf};

use nalgebra::Vector2;

use super::input::FitInputError;
use crate::config::readable_number;
use crate::material::{FibreFrame, Invariants, MaterialError, Sym2};

/// A measured quantity of an OAT, one column of the measured file and one
/// history column of ncform's own outputs (`docs/cases.md`,
/// "`mdz_strains.csv`").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Quantity {
    /// The clamp force \[N\] (the `y` reaction of the moving clamp).
    Force,
    /// `E22 = I8 − 1`, the strain along the stitching \[-\] (MDZ mean).
    E22,
    /// The shear angle `γ = I10` \[deg\] (MDZ mean).
    ShearAngle,
    /// `E⊥ = I11 − 1`, the strain across the current rovings \[-\] (MDZ
    /// mean).
    EPerp,
}

impl Quantity {
    /// Every quantity, in the order of the files and reports.
    pub const ALL: [Quantity; 4] = [
        Quantity::Force,
        Quantity::E22,
        Quantity::ShearAngle,
        Quantity::EPerp,
    ];

    /// The name the fit file's `noise` table uses: `force`, `E22`,
    /// `shear_angle`, `E_perp`.
    pub fn name(self) -> &'static str {
        match self {
            Quantity::Force => "force",
            Quantity::E22 => "E22",
            Quantity::ShearAngle => "shear_angle",
            Quantity::EPerp => "E_perp",
        }
    }

    /// The measured file's column header: `force [N]`, `E22 [-]`,
    /// `shear_angle [deg]`, `E_perp [-]` (the headers ncform writes).
    pub fn column(self) -> &'static str {
        match self {
            Quantity::Force => "force [N]",
            Quantity::E22 => "E22 [-]",
            Quantity::ShearAngle => "shear_angle [deg]",
            Quantity::EPerp => "E_perp [-]",
        }
    }

    /// The unit: `N`, `-` (a strain), `deg`.
    pub fn unit(self) -> &'static str {
        match self {
            Quantity::Force => "N",
            Quantity::E22 | Quantity::EPerp => "-",
            Quantity::ShearAngle => "deg",
        }
    }
}

/// The header of the displacement column (required) \[mm\].
pub const DISPLACEMENT_COLUMN: &str = "displacement [mm]";

/// The headers of the image-correlation columns: Green–Lagrange strains in
/// specimen axes, `x` across the specimen, `y` along the load axis,
/// `Exy` the tensor (not engineering) shear strain \[-\].
pub const DIC_COLUMNS: [&str; 3] = ["Exx [-]", "Eyy [-]", "Exy [-]"];

/// Every column header a measured file may have.
pub fn known_columns() -> Vec<&'static str> {
    let mut names = vec![DISPLACEMENT_COLUMN];
    names.extend(Quantity::ALL.iter().map(|q| q.column()));
    names.extend(DIC_COLUMNS);
    names
}

/// ncform's strain measures `[E22, γ, E⊥]` (`[-]`, `[deg]`, `[-]`) of a
/// Green–Lagrange strain given in specimen axes (`exx` across, `eyy` along
/// the load axis, `exy` the tensor shear strain), for rovings at
/// `bias_angle_deg` from the load axis: `C = I + 2E`, the roving direction
/// `a0 = (sin θ, cos θ)`, the stitching `b0 = (−cos θ, sin θ)` (`a0`
/// turned by +90° about the specimen normal `+z`, as the membrane
/// elements of a generated OAT mesh have it), and then
/// [`Invariants::new`]: `E22 = I8 − 1`, `γ = I10`, `E⊥ = I11 − 1`.
///
/// # Errors
/// A strain whose `C` is not positive definite (`det C ≤ 0` or `I4 ≤ 0`)
/// or not finite.
pub fn dic_to_measures(
    exx: f64,
    eyy: f64,
    exy: f64,
    bias_angle_deg: f64,
) -> Result<[f64; 3], MaterialError> {
    let theta = bias_angle_deg.to_radians();
    let frame = FibreFrame::from_direction(Vector2::new(theta.sin(), theta.cos()))
        .ok_or(MaterialError::NonFinite)?;
    let c = Sym2::new(1.0 + 2.0 * exx, 1.0 + 2.0 * eyy, 2.0 * exy);
    let inv = Invariants::new(&c, &frame)?;
    Ok([inv.i8 - 1.0, inv.i10().to_degrees(), inv.i11 - 1.0])
}

/// One quantity's column of a measured file, row by row.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredColumn {
    /// The quantity.
    pub quantity: Quantity,
    /// Its value at each row, in the quantity's unit; `None` for an empty
    /// cell (not fitted at that row).
    pub values: Vec<Option<f64>>,
    /// Whether the values were converted from the DIC columns
    /// ([`DIC_COLUMNS`]).
    pub from_dic: bool,
}

/// One measured file (one specimen), as read: the displacement of every
/// row and the columns of the quantities it has.
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredCurve {
    /// The file.
    pub path: PathBuf,
    /// The clamp displacement of each row \[mm\], strictly increasing.
    pub displacement: Vec<f64>,
    /// The 1-based line of each row in the file.
    pub lines: Vec<usize>,
    /// The quantities' columns, in the order of [`Quantity::ALL`]; the
    /// force always, the strains when the file has them.
    pub columns: Vec<MeasuredColumn>,
}

impl MeasuredCurve {
    /// The column of `quantity`, if the file has it.
    pub fn column(&self, quantity: Quantity) -> Option<&MeasuredColumn> {
        self.columns.iter().find(|c| c.quantity == quantity)
    }

    /// The rows of `quantity` that have a value, as a curve, if the file
    /// has the column.
    pub fn curve(&self, quantity: Quantity) -> Option<ReplicateCurve> {
        let column = self.column(quantity)?;
        let (displacement, values) = self
            .displacement
            .iter()
            .zip(&column.values)
            .filter_map(|(&d, v)| v.map(|v| (d, v)))
            .unzip();
        Some(ReplicateCurve {
            file: self.path.clone(),
            displacement,
            values,
        })
    }
}

/// One specimen's measured values of one quantity: the rows with a value,
/// interpolated linearly in between.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplicateCurve {
    /// The measured file.
    pub file: PathBuf,
    /// Clamp displacements \[mm\], strictly increasing, at least two.
    pub displacement: Vec<f64>,
    /// The values there, in the quantity's unit.
    pub values: Vec<f64>,
}

impl ReplicateCurve {
    /// The first and last displacement with a value \[mm\].
    pub fn range(&self) -> (f64, f64) {
        (
            self.displacement.first().copied().unwrap_or(0.0),
            self.displacement.last().copied().unwrap_or(0.0),
        )
    }

    /// The index `i` of the interval `[x_i, x_{i+1}]` holding `d`, if `d`
    /// is within the measured range.
    fn interval(&self, d: f64) -> Option<usize> {
        let x = &self.displacement;
        if x.len() < 2 || !(d >= x[0] && d <= x[x.len() - 1]) {
            return None;
        }
        let i = x.partition_point(|&xi| xi <= d).saturating_sub(1);
        Some(i.min(x.len() - 2))
    }

    /// The linear interpolation at displacement `d` \[mm\], `None` outside
    /// the measured range.
    pub fn at(&self, d: f64) -> Option<f64> {
        let i = self.interval(d)?;
        let (x0, x1) = (self.displacement[i], self.displacement[i + 1]);
        let (f0, f1) = (self.values[i], self.values[i + 1]);
        let t = (d - x0) / (x1 - x0);
        Some(f0 + t * (f1 - f0))
    }

    /// The second difference of the data at row `j` (an interior row): the
    /// estimate of `f″` there.
    fn second_difference(&self, j: usize) -> Option<f64> {
        if j == 0 || j + 1 >= self.displacement.len() {
            return None;
        }
        let (x, f) = (&self.displacement, &self.values);
        let right = (f[j + 1] - f[j]) / (x[j + 1] - x[j]);
        let left = (f[j] - f[j - 1]) / (x[j] - x[j - 1]);
        Some(2.0 * (right - left) / (x[j + 1] - x[j - 1]))
    }

    /// The bound `h²/8 · max|f″|` of the linear interpolation's error at
    /// `d` (0 outside the range, and for a curve of two rows: a line),
    /// with `h` the spacing of the measured interval holding `d` and `f″`
    /// the larger second difference at its two ends. The second
    /// differences of noisy data hold the noise divided by `h²`, so on
    /// noisy data the bound overestimates the error (it tends to about
    /// the noise's size): read it as an upper bound.
    pub fn interpolation_bound(&self, d: f64) -> f64 {
        let Some(i) = self.interval(d) else {
            return 0.0;
        };
        let h = self.displacement[i + 1] - self.displacement[i];
        let curvature = [i, i + 1]
            .iter()
            .filter_map(|&j| self.second_difference(j))
            .fold(0.0_f64, |m, c| m.max(c.abs()));
        h * h / 8.0 * curvature
    }
}

/// The measurement noise of a quantity, as the fit file's `noise` table
/// gives it: `σ_model = relative·|value| + absolute` (in the quantity's
/// unit; the strains have no relative part).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Noise {
    /// Relative part \[-\] (force only; 0 for the strains).
    pub relative: f64,
    /// Absolute part, in the quantity's unit.
    pub absolute: f64,
}

impl Noise {
    /// `σ_model` at the (measured) value.
    pub fn sigma(&self, value: f64) -> f64 {
        self.relative * value.abs() + self.absolute
    }
}

/// A measured value at one displacement.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// The replicate mean, in the quantity's unit.
    pub value: f64,
    /// Its standard deviation for the residual, in the quantity's unit
    /// (> 0).
    pub sigma: f64,
    /// The derivative of the replicate mean with respect to the
    /// displacement there, in the quantity's unit per mm.
    pub slope: f64,
}

/// Smallest `σ`, relative to the largest `|mean|` of the quantity over the
/// test's schedule: `σ` is never below `1e-3` of it (so never 0).
pub const SIGMA_FLOOR_RELATIVE: f64 = 1e-3;

/// Smallest `σ` when the quantity's means are all 0 over the schedule, in
/// the quantity's unit.
pub const SIGMA_FLOOR_ABSOLUTE: f64 = 1e-12;

/// One quantity of one test, resampled to the fit's schedule: the mean of
/// the replicates, its standard deviation and the interpolation-error
/// bound, plus the replicates' curves for [`MeasuredQuantity::sample`] and
/// plots. Rules: `docs/fit.md`, "Resampling".
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredQuantity {
    /// The quantity.
    pub quantity: Quantity,
    /// The replicate mean at each schedule displacement `d_k` shifted by
    /// the offset's start (`d_k + δ`), in the quantity's unit.
    pub values: Vec<f64>,
    /// The standard deviation `σ_k` of each value, in the quantity's unit
    /// (> 0).
    pub sigma: Vec<f64>,
    /// How many replicates have the quantity (`m`).
    pub replicates: usize,
    /// The bound of the linear-interpolation error over the schedule
    /// (`h²/8 · max|f″|`, the largest over the points and replicates;
    /// [`ReplicateCurve::interpolation_bound`]), in the quantity's unit.
    /// An overestimate on noisy data, whose second differences hold the
    /// noise.
    pub interpolation_error: f64,
    /// The replicates' measured curves.
    pub curves: Vec<ReplicateCurve>,
    /// The noise given in the fit file (`None`: the replicates' scatter
    /// alone).
    pub noise: Option<Noise>,
    /// The smallest `σ` ([`SIGMA_FLOOR_RELATIVE`] of the largest `|mean|`
    /// over the schedule), in the quantity's unit.
    pub sigma_floor: f64,
    /// Half-width of the centred difference of [`Sample::slope`] \[mm\]:
    /// half the smallest gap of the schedule (the gap from 0 to the first
    /// point included).
    pub slope_window: f64,
    /// The offset `δ` at which `values` and `sigma` were taken \[mm\].
    pub offset: f64,
}

impl MeasuredQuantity {
    /// Resamples `curves` (the replicates that have the quantity) to
    /// `schedule` \[mm\] shifted by `offset` \[mm\]; `None` when a point
    /// lies outside a replicate's range or there is no replicate.
    pub fn new(
        quantity: Quantity,
        curves: Vec<ReplicateCurve>,
        schedule: &[f64],
        offset: f64,
        noise: Option<Noise>,
    ) -> Option<Self> {
        if curves.is_empty() {
            return None;
        }
        let mut gaps = schedule.windows(2).map(|w| w[1] - w[0]).collect::<Vec<_>>();
        gaps.extend(schedule.first().copied());
        let slope_window = 0.5 * gaps.iter().copied().fold(f64::INFINITY, f64::min);
        let mut quantity = Self {
            quantity,
            values: Vec::with_capacity(schedule.len()),
            sigma: Vec::with_capacity(schedule.len()),
            replicates: curves.len(),
            interpolation_error: 0.0,
            curves,
            noise,
            sigma_floor: SIGMA_FLOOR_ABSOLUTE,
            slope_window: if slope_window.is_finite() {
                slope_window
            } else {
                0.5
            },
            offset,
        };
        let mut scatter = Vec::with_capacity(schedule.len());
        for &d in schedule {
            let (mean, s) = quantity.mean_and_scatter(d + offset)?;
            quantity.values.push(mean);
            scatter.push(s);
            for curve in &quantity.curves {
                quantity.interpolation_error = quantity
                    .interpolation_error
                    .max(curve.interpolation_bound(d + offset));
            }
        }
        let largest = quantity.values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        quantity.sigma_floor = (SIGMA_FLOOR_RELATIVE * largest).max(SIGMA_FLOOR_ABSOLUTE);
        quantity.sigma = quantity
            .values
            .iter()
            .zip(&scatter)
            .map(|(&mean, &s)| quantity.sigma_of(mean, s))
            .collect();
        Some(quantity)
    }

    /// The common range of the replicates \[mm\] (measured displacement).
    pub fn range(&self) -> (f64, f64) {
        self.curves
            .iter()
            .fold((f64::NEG_INFINITY, f64::INFINITY), |(a, b), c| {
                let (first, last) = c.range();
                (a.max(first), b.min(last))
            })
    }

    /// The replicates' mean and sample standard deviation (0 for one
    /// replicate) at the measured displacement `d`, `None` outside a
    /// replicate's range.
    fn mean_and_scatter(&self, d: f64) -> Option<(f64, f64)> {
        let values = self
            .curves
            .iter()
            .map(|c| c.at(d))
            .collect::<Option<Vec<f64>>>()?;
        let m = values.len() as f64;
        let mean = values.iter().sum::<f64>() / m;
        let s = if values.len() >= 2 {
            (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt()
        } else {
            0.0
        };
        Some((mean, s))
    }

    /// `σ` of a mean with sample standard deviation `s`: with noise
    /// `√((σ_model² + s²)/m)`, `σ_model` taken at the measured mean (the
    /// relative part of the force noise weights the MEASURED force, not
    /// the simulated one, so that `σ` does not depend on the parameters
    /// and the cost stays a plain weighted least-squares sum); without
    /// `s/√m`; never below [`MeasuredQuantity::sigma_floor`].
    fn sigma_of(&self, mean: f64, s: f64) -> f64 {
        let m = self.replicates as f64;
        let sigma = match self.noise {
            Some(noise) => ((noise.sigma(mean).powi(2) + s * s) / m).sqrt(),
            None => s / m.sqrt(),
        };
        sigma.max(self.sigma_floor)
    }

    /// The measured value for the simulated displacement `d_sim` \[mm\]
    /// with the offset `offset` \[mm\]: the replicates at `d_sim + offset`
    /// (their mean, its `σ` as for the schedule, and the mean's slope from
    /// a centred difference over `± slope_window`, one-sided at the ends
    /// of the common range); `None` outside it.
    pub fn sample(&self, d_sim: f64, offset: f64) -> Option<Sample> {
        let d = d_sim + offset;
        let (mean, s) = self.mean_and_scatter(d)?;
        let (first, last) = self.range();
        let (lo, hi) = (
            (d - self.slope_window).max(first),
            (d + self.slope_window).min(last),
        );
        let slope = if hi > lo {
            let (f_hi, _) = self.mean_and_scatter(hi)?;
            let (f_lo, _) = self.mean_and_scatter(lo)?;
            (f_hi - f_lo) / (hi - lo)
        } else {
            0.0
        };
        Some(Sample {
            value: mean,
            sigma: self.sigma_of(mean, s),
            slope,
        })
    }
}

/// Largest magnitude of a measured cell: beyond it the replicates' mean
/// and scatter could overflow; no clamp force in N, displacement in mm or
/// strain is near it.
pub const CELL_MAX: f64 = 1e15;

/// What a measured file's column header stands for.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Header {
    Displacement,
    Quantity(Quantity),
    Dic(usize),
}

/// A cell error of `file` at `line`.
fn cell_error(
    file: &str,
    line: usize,
    column: &str,
    value: String,
    expected: &str,
) -> FitInputError {
    FitInputError::Cell {
        file: file.to_string(),
        line,
        column: column.to_string(),
        value,
        expected: expected.to_string(),
    }
}

/// Reads one measured file (one specimen): `#` comment lines anywhere,
/// a header line, then numeric rows, comma-separated; the DIC columns are
/// converted with `bias_angle_deg` ([`dic_to_measures`]). Format:
/// `docs/fit.md`, "Measured data".
///
/// # Errors
/// An unreadable file, or [`FitInputError::Cell`] naming the file, line,
/// column, value and what was expected.
pub fn read_measured(path: &Path, bias_angle_deg: f64) -> Result<MeasuredCurve, FitInputError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|e| FitInputError::Unreadable {
        file: file.clone(),
        reason: format!("{e}; expected a measured CSV file"),
    })?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        FitInputError::Cell {
            file: file.clone(),
            line: valid.iter().filter(|&&b| b == b'\n').count() + 1,
            column: "(line)".into(),
            value: "(bytes that are not UTF-8)".into(),
            expected: "expected a CSV text file (UTF-8)".into(),
        }
    })?;
    let mut curve = parse_measured(&text, &file, bias_angle_deg)?;
    curve.path = path.to_path_buf();
    Ok(curve)
}

/// [`read_measured`] on the file's `text`, named `file` in messages (the
/// curve's `path` is `file`).
///
/// # Errors
/// As [`read_measured`].
pub fn parse_measured(
    text: &str,
    file: &str,
    bias_angle_deg: f64,
) -> Result<MeasuredCurve, FitInputError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut header: Option<(usize, Vec<Header>)> = None;
    let mut displacement = Vec::new();
    let mut lines = Vec::new();
    let mut values: [Vec<Option<f64>>; 4] = Default::default();
    let mut dic = [Vec::new(), Vec::new(), Vec::new()];
    let mut dic_values: Vec<[Option<f64>; 3]> = Vec::new();
    for (n, raw) in text.lines().enumerate() {
        let line = n + 1;
        let t = raw.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let cells: Vec<&str> = t.split(',').map(str::trim).collect();
        let Some((_, columns)) = &header else {
            header = Some((line, parse_header(&cells, file, line)?));
            continue;
        };
        if cells.len() != columns.len() {
            return Err(cell_error(
                file,
                line,
                "(row)",
                format!("{} cells", cells.len()),
                &format!(
                    "expected {} cells, one per header column ({})",
                    columns.len(),
                    header_names(columns).join(", ")
                ),
            ));
        }
        let mut row_dic = [None; 3];
        for (cell, column) in cells.iter().zip(columns) {
            let name = header_name(*column);
            let required = matches!(
                column,
                Header::Displacement | Header::Quantity(Quantity::Force)
            );
            let value = if cell.is_empty() {
                if required {
                    return Err(cell_error(
                        file,
                        line,
                        name,
                        "(empty)".into(),
                        "expected a number (a required column has a value in every row)",
                    ));
                }
                None
            } else {
                match cell.parse::<f64>() {
                    Ok(x) if x.is_finite() && x.abs() <= CELL_MAX => Some(x),
                    Ok(_) => {
                        return Err(cell_error(
                            file,
                            line,
                            name,
                            (*cell).to_string(),
                            &format!(
                                "expected a finite number (of magnitude at most {CELL_MAX:e})"
                            ),
                        ));
                    }
                    Err(_) => {
                        return Err(cell_error(
                            file,
                            line,
                            name,
                            format!("{cell:?}"),
                            "expected a number",
                        ));
                    }
                }
            };
            match column {
                Header::Displacement => {
                    let d = value.unwrap_or(0.0);
                    if let (Some(&previous), Some(&previous_line)) =
                        (displacement.last(), lines.last())
                        && d <= previous
                    {
                        return Err(cell_error(
                            file,
                            line,
                            name,
                            readable_number(d),
                            &format!(
                                "expected a displacement greater than {} mm of line {previous_line}: rows in increasing displacement, none repeated",
                                readable_number(previous)
                            ),
                        ));
                    }
                    displacement.push(d);
                    lines.push(line);
                }
                Header::Quantity(q) => values[*q as usize].push(value),
                Header::Dic(i) => row_dic[*i] = value,
            }
        }
        dic_values.push(row_dic);
    }
    let Some((header_line, columns)) = header else {
        return Err(cell_error(
            file,
            0,
            "(header)",
            "(none)".into(),
            &format!(
                "expected a header line naming the columns ({}) and then the rows",
                known_columns().join(", ")
            ),
        ));
    };
    if displacement.len() < 2 {
        return Err(cell_error(
            file,
            lines.last().copied().unwrap_or(header_line),
            DISPLACEMENT_COLUMN,
            format!("{} data row(s)", displacement.len()),
            "expected at least 2 data rows",
        ));
    }
    let has_dic = columns.iter().any(|c| matches!(c, Header::Dic(_)));
    if has_dic {
        for (row, cells) in dic_values.iter().enumerate() {
            let line = lines[row];
            let converted = match cells {
                [Some(exx), Some(eyy), Some(exy)] => Some(
                    dic_to_measures(*exx, *eyy, *exy, bias_angle_deg).map_err(|e| {
                        cell_error(
                            file,
                            line,
                            &DIC_COLUMNS.join(", "),
                            format!(
                                "({}, {}, {})",
                                readable_number(*exx),
                                readable_number(*eyy),
                                readable_number(*exy)
                            ),
                            &format!("expected a Green–Lagrange strain with C = I + 2E positive definite ({e})"),
                        )
                    })?,
                ),
                [None, None, None] => None,
                _ => {
                    return Err(cell_error(
                        file,
                        line,
                        &DIC_COLUMNS.join(", "),
                        "(some cells empty)".into(),
                        "expected all three DIC strains of a row, or none",
                    ));
                }
            };
            for (i, d) in dic.iter_mut().enumerate() {
                d.push(converted.map(|m| m[i]));
            }
        }
    }
    let mut out = Vec::new();
    for q in Quantity::ALL {
        let (column, from_dic) = if columns.contains(&Header::Quantity(q)) {
            (std::mem::take(&mut values[q as usize]), false)
        } else if has_dic && q != Quantity::Force {
            (std::mem::take(&mut dic[q as usize - 1]), true)
        } else {
            continue;
        };
        let present = column.iter().flatten().count();
        if present < 2 {
            let name = if from_dic {
                DIC_COLUMNS.join(", ")
            } else {
                q.column().to_string()
            };
            return Err(cell_error(
                file,
                header_line,
                &name,
                format!("{present} values"),
                "expected at least 2 rows with a value in an optional column, or no such column",
            ));
        }
        out.push(MeasuredColumn {
            quantity: q,
            values: column,
            from_dic,
        });
    }
    Ok(MeasuredCurve {
        path: PathBuf::from(file),
        displacement,
        lines,
        columns: out,
    })
}

/// The header of a column.
fn header_name(h: Header) -> &'static str {
    match h {
        Header::Displacement => DISPLACEMENT_COLUMN,
        Header::Quantity(q) => q.column(),
        Header::Dic(i) => DIC_COLUMNS[i],
    }
}

/// The headers of the columns, in file order.
fn header_names(columns: &[Header]) -> Vec<&'static str> {
    columns.iter().map(|&c| header_name(c)).collect()
}

/// The columns of a header line: known names, each once; the
/// displacement and the force; the DIC columns all three or none, and
/// not with the strain columns they replace.
fn parse_header(cells: &[&str], file: &str, line: usize) -> Result<Vec<Header>, FitInputError> {
    let mut columns = Vec::with_capacity(cells.len());
    for (i, cell) in cells.iter().enumerate() {
        let h = if *cell == DISPLACEMENT_COLUMN {
            Header::Displacement
        } else if let Some(q) = Quantity::ALL.iter().find(|q| q.column() == *cell) {
            Header::Quantity(*q)
        } else if let Some(k) = DIC_COLUMNS.iter().position(|c| c == cell) {
            Header::Dic(k)
        } else {
            return Err(cell_error(
                file,
                line,
                &format!("header column {}", i + 1),
                format!("{cell:?}"),
                &format!(
                    "expected one of the columns {} (exactly so spelt)",
                    known_columns().join(", ")
                ),
            ));
        };
        if columns.contains(&h) {
            return Err(cell_error(
                file,
                line,
                &format!("header column {}", i + 1),
                format!("{cell:?}"),
                "expected each column once",
            ));
        }
        columns.push(h);
    }
    for required in [Header::Displacement, Header::Quantity(Quantity::Force)] {
        if !columns.contains(&required) {
            return Err(cell_error(
                file,
                line,
                header_name(required),
                "(missing)".into(),
                &format!(
                    "expected a header with the required columns {DISPLACEMENT_COLUMN} and force [N] (found: {})",
                    cells.join(", ")
                ),
            ));
        }
    }
    let dic = (0..3)
        .filter(|k| columns.contains(&Header::Dic(*k)))
        .count();
    if dic > 0 && dic < 3 {
        let missing = (0..3)
            .find(|k| !columns.contains(&Header::Dic(*k)))
            .map_or("", |k| DIC_COLUMNS[k]);
        return Err(cell_error(
            file,
            line,
            missing,
            "(missing)".into(),
            &format!("expected all three DIC columns {}", DIC_COLUMNS.join(", ")),
        ));
    }
    if dic == 3
        && let Some(q) = [Quantity::E22, Quantity::ShearAngle, Quantity::EPerp]
            .into_iter()
            .find(|q| columns.contains(&Header::Quantity(*q)))
    {
        return Err(cell_error(
            file,
            line,
            q.column(),
            "(given with the DIC columns)".into(),
            &format!(
                "expected either the strain columns E22 [-], shear_angle [deg], E_perp [-] or the DIC columns {}, not both",
                DIC_COLUMNS.join(", ")
            ),
        ));
    }
    Ok(columns)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::case::OatCase;
    use nalgebra::Matrix2;

    fn parse(text: &str) -> Result<MeasuredCurve, FitInputError> {
        parse_measured(text, "m.csv", 30.0)
    }

    fn message(text: &str) -> String {
        match parse(text) {
            Ok(_) => panic!("accepted: {text}"),
            Err(e) => e.to_string(),
        }
    }

    #[test]
    fn reads_columns_in_any_order_with_comments_and_empty_cells() {
        let curve = parse(
            "# a comment\n force [N] , displacement [mm],E22 [-]\n0.0,0.0,0.0\n# mid\n1.5,1.0,\n3.0,2.0,0.02\n",
        )
        .unwrap();
        assert_eq!(curve.displacement, vec![0.0, 1.0, 2.0]);
        assert_eq!(curve.lines, vec![3, 5, 6]);
        let force = curve.curve(Quantity::Force).unwrap();
        assert_eq!(force.values, vec![0.0, 1.5, 3.0]);
        let e22 = curve.curve(Quantity::E22).unwrap();
        assert_eq!(e22.displacement, vec![0.0, 2.0]);
        assert!(curve.column(Quantity::ShearAngle).is_none());
    }

    #[test]
    fn refuses_a_non_numeric_cell() {
        let m = message("displacement [mm],force [N]\n0,0\n1,abc\n");
        assert!(
            m.starts_with("m.csv:3: force [N] = \"abc\": expected a number"),
            "{m}"
        );
    }

    #[test]
    fn refuses_nan_and_inf() {
        let m = message("displacement [mm],force [N]\n0,0\n1,NaN\n");
        assert!(
            m.starts_with("m.csv:3: force [N] = NaN: expected a finite number"),
            "{m}"
        );
        let m = message("displacement [mm],force [N]\n0,0\ninf,1\n");
        assert!(m.starts_with("m.csv:3: displacement [mm] = inf"), "{m}");
        let m = message("displacement [mm],force [N]\n0,0\n1,1e300\n");
        assert!(
            m.starts_with(
                "m.csv:3: force [N] = 1e300: expected a finite number (of magnitude at most 1e15)"
            ),
            "{m}"
        );
    }

    #[test]
    fn refuses_a_missing_required_column() {
        let m = message("displacement [mm],E22 [-]\n0,0\n1,0.1\n");
        assert!(m.starts_with("m.csv:1: force [N] = (missing)"), "{m}");
        let m = message("force [N]\n0\n1\n");
        assert!(
            m.starts_with("m.csv:1: displacement [mm] = (missing)"),
            "{m}"
        );
    }

    #[test]
    fn refuses_an_unknown_column_listing_the_known_ones() {
        let m = message("displacement [mm],force [N],strain\n0,0,0\n1,1,1\n");
        assert!(
            m.starts_with("m.csv:1: header column 3 = \"strain\""),
            "{m}"
        );
        assert!(
            m.contains("shear_angle [deg]") && m.contains("Exx [-]"),
            "{m}"
        );
    }

    #[test]
    fn refuses_a_row_with_the_wrong_number_of_cells() {
        let m = message("displacement [mm],force [N]\n0,0\n1,1,2\n");
        assert!(
            m.starts_with("m.csv:3: (row) = 3 cells: expected 2 cells"),
            "{m}"
        );
    }

    #[test]
    fn refuses_a_decreasing_or_repeated_displacement() {
        let m = message("displacement [mm],force [N]\n0,0\n2,1\n1.5,2\n");
        assert!(m.starts_with("m.csv:4: displacement [mm] = 1.5: expected a displacement greater than 2 mm of line 3"), "{m}");
        let m = message("displacement [mm],force [N]\n0,0\n2,1\n2,2\n");
        assert!(m.starts_with("m.csv:4: displacement [mm] = 2:"), "{m}");
    }

    #[test]
    fn refuses_fewer_than_two_rows() {
        let m = message("# only one\ndisplacement [mm],force [N]\n0,0\n");
        assert!(
            m.starts_with(
                "m.csv:3: displacement [mm] = 1 data row(s): expected at least 2 data rows"
            ),
            "{m}"
        );
    }

    #[test]
    fn refuses_an_empty_required_cell_and_partial_dic_rows() {
        let m = message("displacement [mm],force [N]\n0,0\n1,\n");
        assert!(m.starts_with("m.csv:3: force [N] = (empty)"), "{m}");
        let m = message(
            "displacement [mm],force [N],Exx [-],Eyy [-],Exy [-]\n0,0,0,0,0\n1,1,0.01,,0\n2,2,0,0,0\n",
        );
        assert!(
            m.starts_with("m.csv:3: Exx [-], Eyy [-], Exy [-] = (some cells empty)"),
            "{m}"
        );
    }

    #[test]
    fn refuses_dic_columns_with_strain_columns_or_incomplete() {
        let m = message("displacement [mm],force [N],Exx [-],Eyy [-]\n0,0,0,0\n1,1,0,0\n");
        assert!(m.starts_with("m.csv:1: Exy [-] = (missing)"), "{m}");
        let m = message(
            "displacement [mm],force [N],Exx [-],Eyy [-],Exy [-],E22 [-]\n0,0,0,0,0,0\n1,1,0,0,0,0\n",
        );
        assert!(m.contains("not both"), "{m}");
    }

    /// `E = ½(FᵀF − I)` in specimen axes as `[Exx, Eyy, Exy]`.
    fn green_lagrange(f: &Matrix2<f64>) -> [f64; 3] {
        let c = f.transpose() * f;
        [
            0.5 * (c[(0, 0)] - 1.0),
            0.5 * (c[(1, 1)] - 1.0),
            0.5 * c[(0, 1)],
        ]
    }

    /// The fields ncform itself computes on an OAT mesh at `θ` deformed
    /// homogeneously by `f` (every element alike).
    fn ncform_fields(theta: f64, f: &Matrix2<f64>) -> [f64; 3] {
        let text = format!(
            "[specimen]\nwidth = 100.0\nlength = 300.0\nbias_angle_deg = {theta}\n[mesh]\nelement_size = 40.0\n[loading]\ndisplacement = 80.0\n"
        );
        let case = OatCase::from_toml_str(&text, "dic.toml", Path::new(".")).unwrap();
        let built = case.build().unwrap();
        let model = &built.model;
        let mut u = vec![0.0; 3 * model.nodes.len()];
        for (n, x) in model.nodes.iter().enumerate() {
            let moved = f * nalgebra::Vector2::new(x.x, x.y);
            u[3 * n] = moved.x - x.x;
            u[3 * n + 1] = moved.y - x.y;
        }
        let fields = crate::post::fields::element_fields(model, &u).unwrap();
        let first = fields[0];
        for other in &fields {
            assert!((other.shear_angle_deg - first.shear_angle_deg).abs() < 1e-9);
        }
        [first.e22, first.shear_angle_deg, first.e_perp]
    }

    #[test]
    fn dic_conversion_agrees_with_ncforms_own_fields() {
        let cases = [
            // pure shear (symmetric stretch at 45° to the axes, volume kept)
            Matrix2::new(1.0, 0.15, 0.15, 1.0) / (1.0_f64 - 0.15 * 0.15).sqrt(),
            // uniaxial stretch along the load axis
            Matrix2::new(1.0, 0.0, 0.0, 1.2),
            // a general one
            Matrix2::new(1.05, 0.1, -0.03, 1.18),
        ];
        for theta in [30.0, 45.0, 60.0] {
            for f in &cases {
                let [exx, eyy, exy] = green_lagrange(f);
                let converted = dic_to_measures(exx, eyy, exy, theta).unwrap();
                let own = ncform_fields(theta, f);
                for (a, b) in converted.iter().zip(&own) {
                    assert!(
                        (a - b).abs() < 1e-10,
                        "θ = {theta}: {converted:?} vs {own:?}"
                    );
                }
            }
        }
        // Uniaxial stretch λ along y at θ = 30°, by hand: C = diag(1, λ²),
        // a0 = (sin θ, cos θ), b0 = (−cos θ, sin θ).
        let (l, t) = (1.2_f64, 30.0_f64.to_radians());
        let (s, c) = t.sin_cos();
        let i4 = s * s + l * l * c * c;
        let i8 = c * c + l * l * s * s;
        let i6 = -s * c + l * l * c * s;
        let gamma = (std::f64::consts::FRAC_PI_2 - (i6 / (i4 * i8).sqrt()).acos()).to_degrees();
        let i11 = (l * l / i4).sqrt();
        let [e22, g, ep] = dic_to_measures(0.0, 0.5 * (l * l - 1.0), 0.0, 30.0).unwrap();
        assert!((e22 - (i8 - 1.0)).abs() < 1e-14);
        assert!((g - gamma).abs() < 1e-12);
        assert!(g > 0.0);
        assert!((ep - (i11 - 1.0)).abs() < 1e-14);
    }

    #[test]
    fn dic_columns_are_converted_in_the_file() {
        let f = Matrix2::new(1.05, 0.1, -0.03, 1.18);
        let [exx, eyy, exy] = green_lagrange(&f);
        let text = format!(
            "Exy [-],Eyy [-],Exx [-],displacement [mm],force [N]\n0,0,0,0,0\n{exy},{eyy},{exx},1,1\n"
        );
        let curve = parse(&text).unwrap();
        let expected = dic_to_measures(exx, eyy, exy, 30.0).unwrap();
        for (q, e) in [Quantity::E22, Quantity::ShearAngle, Quantity::EPerp]
            .into_iter()
            .zip(expected)
        {
            let column = curve.column(q).unwrap();
            assert!(column.from_dic);
            assert_eq!(column.values[1], Some(e));
            assert_eq!(column.values[0], Some(0.0));
        }
        let bad = "displacement [mm],force [N],Exx [-],Eyy [-],Exy [-]\n0,0,0,0,0\n1,1,-0.5,0,0\n";
        let m = message(bad);
        assert!(
            m.starts_with("m.csv:3: Exx [-], Eyy [-], Exy [-] = (-0.5, 0, 0)"),
            "{m}"
        );
    }

    fn curve(x: Vec<f64>, f: Vec<f64>) -> ReplicateCurve {
        ReplicateCurve {
            file: PathBuf::from("c.csv"),
            displacement: x,
            values: f,
        }
    }

    #[test]
    fn interpolation_bound_is_zero_for_linear_and_positive_for_curved_data() {
        let x: Vec<f64> = (0..=10).map(f64::from).collect();
        let linear = curve(x.clone(), x.iter().map(|d| 2.0 * d + 1.0).collect());
        let q = MeasuredQuantity::new(
            Quantity::Force,
            vec![linear],
            &[2.5, 5.0, 7.5],
            0.0,
            Some(Noise {
                relative: 0.0,
                absolute: 0.1,
            }),
        )
        .unwrap();
        assert_eq!(q.interpolation_error, 0.0);
        assert_eq!(q.values, vec![6.0, 11.0, 16.0]);
        // f = d²: f″ = 2, h = 1: bound 1/8·2 = 0.25, the true error at a
        // midpoint (0.25) reaches it.
        let square = curve(x.clone(), x.iter().map(|d| d * d).collect());
        let q =
            MeasuredQuantity::new(Quantity::Force, vec![square], &[2.5, 5.0], 0.0, None).unwrap();
        assert!((q.interpolation_error - 0.25).abs() < 1e-12);
        assert!((q.values[0] - 6.5).abs() < 1e-12);
        assert!((q.values[0] - 2.5 * 2.5 - q.interpolation_error).abs() < 1e-12);
    }

    #[test]
    fn sample_gives_mean_sigma_and_slope_with_the_offset() {
        let x: Vec<f64> = (0..=10).map(f64::from).collect();
        let a = curve(x.clone(), x.iter().map(|d| 2.0 * d).collect());
        let b = curve(x.clone(), x.iter().map(|d| 2.0 * d + 0.2).collect());
        let q = MeasuredQuantity::new(
            Quantity::Force,
            vec![a, b],
            &[2.0, 4.0, 6.0],
            0.5,
            Some(Noise {
                relative: 0.1,
                absolute: 0.0,
            }),
        )
        .unwrap();
        let s = q.sample(2.0, 0.5).unwrap();
        assert!((s.value - 5.1).abs() < 1e-12);
        assert!((s.value - q.values[0]).abs() < 1e-12);
        let scatter = (2.0_f64 * 0.1 * 0.1 / 1.0).sqrt();
        let expected = ((0.1_f64 * 5.1).powi(2) / 2.0 + scatter * scatter / 2.0).sqrt();
        assert!((s.sigma - expected).abs() < 1e-12);
        assert!((q.sigma[0] - expected).abs() < 1e-12);
        assert!((s.slope - 2.0).abs() < 1e-12);
        assert_eq!(q.slope_window, 1.0);
        // At the end of the range the slope is one-sided; beyond, None.
        assert!((q.sample(9.5, 0.5).unwrap().slope - 2.0).abs() < 1e-12);
        assert!(q.sample(9.6, 0.5).is_none());
        assert!(q.sample(-1.0, 0.5).is_none());
    }
}
