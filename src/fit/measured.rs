//! Measured data of an off-axis tension test for `ncform fit`: one CSV
//! file per specimen ([`read_measured`]), its conversion from image
//! correlation (DIC) strains to ncform's strain measures
//! ([`dic_to_measures`]), and the resampling of the replicates to the
//! fit's schedule of displacements ([`MeasuredQuantity`]). File format,
//! conversion formulas and the resampling rules: `docs/fit.md`,
//! "Measured data".

use std::path::{Path, PathBuf};

use nalgebra::Vector2;

use super::error::FitInputError;
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
/// resampled by local linear fits over bins ([`ReplicateCurve::bin_fit`])
/// or interpolated linearly in between.
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
        h * h / 8.0 * self.curvature_at(d)
    }

    /// The estimate of `|f″|` at `d`: the larger second difference of the
    /// rows at the two ends of the measured interval holding `d` (0
    /// outside the range and for a curve of two rows).
    fn curvature_at(&self, d: f64) -> f64 {
        let Some(i) = self.interval(d) else {
            return 0.0;
        };
        [i, i + 1]
            .iter()
            .filter_map(|&j| self.second_difference(j))
            .fold(0.0_f64, |m, c| m.max(c.abs()))
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

/// One replicate's local linear least-squares fit over a bin
/// ([`ReplicateCurve::bin_fit`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BinFit {
    /// The fit's value at the bin's centre, in the quantity's unit.
    pub value: f64,
    /// The fit's slope, in the quantity's unit per mm.
    pub slope: f64,
    /// `c = √(1/n + (d − d̄)²/Sxx)`: the value's standard deviation in
    /// units of one row's noise (1 for the interpolation fallback).
    pub factor: f64,
    /// The rows in the bin (`n`).
    pub rows: usize,
    /// The resampling error bound, in the quantity's unit.
    pub error: f64,
    /// The curvature estimate `|f″|` the bound uses, in the quantity's
    /// unit per mm².
    pub curvature: f64,
}

impl ReplicateCurve {
    /// The indices `[start, end)` of the rows in the bin `[lo, hi)` (the
    /// last row included when `hi` reaches it): half-open, so that bins
    /// that touch share no row.
    fn bin_rows(&self, lo: f64, hi: f64) -> (usize, usize) {
        let x = &self.displacement;
        let start = x.partition_point(|&xi| xi < lo);
        let end = match x.last() {
            Some(&last) if hi >= last => x.len(),
            _ => x.partition_point(|&xi| xi < hi),
        };
        (start, end.max(start))
    }

    /// The local linear least-squares fit of the rows with displacement in
    /// the bin `[d − w, d + w)` (clipped to the measured range), evaluated
    /// at `d` \[mm\]; `None` when `d` is outside the measured range.
    ///
    /// With `n ≥ 2` rows in the bin (distinct displacements, as the rows
    /// are strictly increasing): value `a`, slope `b`, factor
    /// `c = √(1/n + (d − d̄)²/Sxx)` and the curvature bound
    /// `½·|f″|·|ĝ(d)|`, `ĝ` the same fit of `g(x) = (x − d)²` (the error of
    /// the fit of a quadratic with second derivative `f″`), `f″` that of
    /// the bin's quadratic least-squares fit (with two rows: the larger
    /// second difference of the rows at the ends of the measured interval
    /// holding `d`).
    ///
    /// With fewer rows (a bin narrower than the rows' spacing) it falls
    /// back to the linear interpolation between the rows: factor 1 (the
    /// `σ` of one row), the slope a centred difference of the
    /// interpolation over `± slope_window` (one-sided at the ends of the
    /// range) and the error bound of [`ReplicateCurve::interpolation_bound`].
    pub fn bin_fit(&self, d: f64, w: f64, slope_window: f64) -> Option<BinFit> {
        let value = self.at(d)?;
        let (first, last) = self.range();
        let (start, end) = self.bin_rows((d - w).max(first), (d + w).min(last));
        let n = end - start;
        if n >= 2 {
            let x = &self.displacement[start..end];
            let f = &self.values[start..end];
            let count = n as f64;
            let u_mean = x.iter().map(|xi| xi - d).sum::<f64>() / count;
            let f_mean = f.iter().sum::<f64>() / count;
            let g_mean = x.iter().map(|xi| (xi - d).powi(2)).sum::<f64>() / count;
            let (mut sxx, mut sxf, mut sxg) = (0.0, 0.0, 0.0);
            for (xi, fi) in x.iter().zip(f) {
                let du = xi - d - u_mean;
                sxx += du * du;
                sxf += du * (fi - f_mean);
                sxg += du * ((xi - d).powi(2) - g_mean);
            }
            if sxx > 0.0 && sxx.is_finite() {
                let slope = sxf / sxx;
                let g_slope = sxg / sxx;
                let g_at_d = g_mean - g_slope * u_mean;
                // f″ = 2·c₂ of the bin's quadratic least-squares fit, by
                // the residuals of f and of (x − d)² on the line
                // (Frisch–Waugh); the rows' second differences when the
                // bin has fewer than three rows.
                let (mut sqr, mut sqq) = (0.0, 0.0);
                for (xi, fi) in x.iter().zip(f) {
                    let du = xi - d - u_mean;
                    let q = (xi - d).powi(2) - g_mean - g_slope * du;
                    sqr += q * (fi - f_mean - slope * du);
                    sqq += q * q;
                }
                let fitted = n >= 3 && sqq > 0.0 && (sqr / sqq).is_finite();
                let curvature = if fitted {
                    (2.0 * sqr / sqq).abs()
                } else {
                    self.curvature_at(d)
                };

                return Some(BinFit {
                    value: f_mean - slope * u_mean,
                    slope,
                    factor: (1.0 / count + u_mean * u_mean / sxx).sqrt(),
                    rows: n,
                    error: 0.5 * curvature * g_at_d.abs(),
                    curvature,
                });
            }
        }
        let (lo, hi) = ((d - slope_window).max(first), (d + slope_window).min(last));
        let slope = match (self.at(hi), self.at(lo)) {
            (Some(f_hi), Some(f_lo)) if hi > lo => (f_hi - f_lo) / (hi - lo),
            _ => 0.0,
        };
        Some(BinFit {
            value,
            slope,
            factor: 1.0,
            rows: n,
            error: self.interpolation_bound(d),
            curvature: self.curvature_at(d),
        })
    }
}

/// How many times a bin may be halved over a sharp bend
/// (`MeasuredQuantity`'s bin narrowing): 8 halvings take a 5 mm bin to
/// 0.02 mm, below any load cell's row spacing, where the fit falls back to
/// interpolating the nearest rows.
pub const MAX_NARROWINGS: usize = 8;

/// The half-widths `w_k` of the schedule's bins \[mm\]: half the smaller
/// gap to the neighbouring points (the gap from 0 to the first point for
/// the first; the gap to the left neighbour for the last), so that the
/// bins `[d_k − w_k, d_k + w_k)` do not overlap.
pub fn bin_half_widths(schedule: &[f64]) -> Vec<f64> {
    let k = schedule.len();
    (0..k)
        .map(|i| {
            let left = if i == 0 {
                schedule[0]
            } else {
                schedule[i] - schedule[i - 1]
            };
            let right = if i + 1 < k {
                schedule[i + 1] - schedule[i]
            } else {
                left
            };
            0.5 * left.min(right).max(0.0)
        })
        .collect()
}

/// The replicates resampled at one displacement.
struct Resampled {
    /// The replicates' mean.
    mean: f64,
    /// The replicates' sample standard deviation (0 for one).
    scatter: f64,
    /// The replicates' mean of `c²`.
    factor2: f64,
    /// The replicates' mean slope.
    slope: f64,
    /// The largest resampling error bound of the replicates.
    error: f64,
}

/// One quantity of one test, resampled to the fit's schedule: the mean of
/// the replicates' local linear fits over non-overlapping bins, its
/// standard deviation and the resampling error bound, plus the
/// replicates' curves for [`MeasuredQuantity::sample`] and plots. Rules:
/// `docs/fit.md`, "Resampling".
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
    /// The resampling error bound over the schedule (the largest over the
    /// points and replicates; [`BinFit::error`]), in the quantity's unit.
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
    /// Half-width of the centred difference of [`Sample::slope`] for a
    /// replicate with fewer than two rows in a bin \[mm\]: half the
    /// smallest gap of the schedule (the gap from 0 to the first point
    /// included).
    pub slope_window: f64,
    /// The offset `δ` at which `values` and `sigma` were taken \[mm\].
    pub offset: f64,
    /// The schedule (simulated displacements) \[mm\].
    pub schedule: Vec<f64>,
    /// The bins' half-widths at the schedule points ([`bin_half_widths`])
    /// \[mm\].
    pub half_widths: Vec<f64>,
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
            schedule: schedule.to_vec(),
            half_widths: bin_half_widths(schedule),
        };
        let mut resampled = Vec::with_capacity(schedule.len());
        for (&d, &w) in schedule.iter().zip(&quantity.half_widths) {
            let r = quantity.resample(d + offset, w)?;
            quantity.values.push(r.mean);
            quantity.interpolation_error = quantity.interpolation_error.max(r.error);
            resampled.push(r);
        }
        let largest = quantity.values.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
        quantity.sigma_floor = (SIGMA_FLOOR_RELATIVE * largest).max(SIGMA_FLOOR_ABSOLUTE);
        quantity.sigma = resampled.iter().map(|r| quantity.sigma_of(r)).collect();
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

    /// The bin half-width for the simulated displacement `d_sim` \[mm\]:
    /// that of the nearest schedule point.
    fn half_width(&self, d_sim: f64) -> f64 {
        self.schedule
            .iter()
            .zip(&self.half_widths)
            .fold(
                (f64::INFINITY, self.slope_window),
                |(best, w), (&d, &wk)| {
                    let distance = (d - d_sim).abs();
                    if distance < best {
                        (distance, wk)
                    } else {
                        (best, w)
                    }
                },
            )
            .1
    }

    /// The replicates' bin fits at the measured displacement `d` with
    /// half-width `w`, combined; `None` outside a replicate's range.
    /// The bin fit of `curve` at `d`, its bin halved (up to
    /// [`MAX_NARROWINGS`] times) while the curvature bias bound exceeds
    /// half the fit's own σ (`σ_model · c`): a line does not describe a
    /// bin over a sharp bend of the curve, and a narrower bin trades
    /// precision for the bias. A bias of at most σ/2 adds at most 12 % to
    /// the value's RMS error (`√(1 + ¼)`). The bound uses the bin's own
    /// curvature estimate, noise included, so noise alone narrows some
    /// bins too: that only widens their σ (measured: the coverage of the
    /// reported intervals, `docs/fit.md`). Without a noise model there is
    /// no σ to compare with, and the bin is kept.
    fn narrowed_fit(&self, curve: &ReplicateCurve, d: f64, w: f64) -> Option<BinFit> {
        let mut w = w;
        let mut fit = curve.bin_fit(d, w, self.slope_window)?;
        if let Some(noise) = self.noise {
            for _ in 0..MAX_NARROWINGS {
                let row_sigma = noise.sigma(fit.value);
                if fit.rows < 3 || fit.error <= 0.5 * row_sigma * fit.factor {
                    break;
                }
                w *= 0.5;
                fit = curve.bin_fit(d, w, self.slope_window)?;
            }
        }
        Some(fit)
    }

    fn resample(&self, d: f64, w: f64) -> Option<Resampled> {
        let fits = self
            .curves
            .iter()
            .map(|c| self.narrowed_fit(c, d, w))
            .collect::<Option<Vec<BinFit>>>()?;
        let m = fits.len() as f64;
        let mean = fits.iter().map(|f| f.value).sum::<f64>() / m;
        let scatter = if fits.len() >= 2 {
            (fits.iter().map(|f| (f.value - mean).powi(2)).sum::<f64>() / (m - 1.0)).sqrt()
        } else {
            0.0
        };
        Some(Resampled {
            mean,
            scatter,
            factor2: fits.iter().map(|f| f.factor * f.factor).sum::<f64>() / m,
            slope: fits.iter().map(|f| f.slope).sum::<f64>() / m,
            error: fits.iter().fold(0.0_f64, |e, f| e.max(f.error)),
        })
    }

    /// `σ` of a resampled mean: with noise `√((σ_model²·⟨c²⟩ + s²)/m)`,
    /// `σ_model` taken at the measured mean (the relative part of the
    /// force noise weights the MEASURED force, not the simulated one, so
    /// that `σ` does not depend on the parameters and the cost stays a
    /// plain weighted least-squares sum) and `⟨c²⟩` the replicates' mean
    /// of the bins' `c²`; without `s/√m`; never below
    /// [`MeasuredQuantity::sigma_floor`].
    fn sigma_of(&self, r: &Resampled) -> f64 {
        let m = self.replicates as f64;
        let s = r.scatter;
        let sigma = match self.noise {
            Some(noise) => ((noise.sigma(r.mean).powi(2) * r.factor2 + s * s) / m).sqrt(),
            None => s / m.sqrt(),
        };
        sigma.max(self.sigma_floor)
    }

    /// The measured value for the simulated displacement `d_sim` \[mm\]
    /// with the offset `offset` \[mm\]: the replicates' bin fits at
    /// `d_sim + offset` with the bin half-width of the nearest schedule
    /// point (their mean, its `σ` as for the schedule, and the mean of
    /// their slopes); `None` outside the common range. At a schedule point
    /// with the offset of [`MeasuredQuantity::offset`] it gives
    /// [`MeasuredQuantity::values`] and [`MeasuredQuantity::sigma`].
    pub fn sample(&self, d_sim: f64, offset: f64) -> Option<Sample> {
        let r = self.resample(d_sim + offset, self.half_width(d_sim))?;
        Some(Sample {
            value: r.mean,
            sigma: self.sigma_of(&r),
            slope: r.slope,
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

    /// A seeded standard normal sample (Box–Muller).
    fn normal(rng: &mut rand::rngs::StdRng) -> f64 {
        use rand::RngExt;
        let u: f64 = 1.0 - rng.random::<f64>();
        let v: f64 = rng.random();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }

    /// 400 rows over (0, 80] mm, jittered by ±0.05 mm about a 0.2 mm
    /// spacing (the last at 80 mm): `f = a + 0.3 d` plus normal noise of
    /// `sigma`.
    fn noisy_linear(seed: u64, a: f64, sigma: f64) -> ReplicateCurve {
        use rand::{RngExt, SeedableRng};
        let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
        let x: Vec<f64> = (0..400)
            .map(|i| {
                let jitter = 0.1 * rng.random::<f64>() - 0.05;
                0.2 * f64::from(i + 1) + if i < 399 { jitter } else { 0.0 }
            })
            .collect();
        let f = x
            .iter()
            .map(|d| a + 0.3 * d + sigma * normal(&mut rng))
            .collect();
        curve(x, f)
    }

    /// The schedule 4, 8, …, `last` \[mm\].
    fn every_four(last: u32) -> Vec<f64> {
        (1..=last / 4).map(|k| 4.0 * f64::from(k)).collect()
    }

    #[test]
    fn bins_tile_without_overlap() {
        assert_eq!(
            bin_half_widths(&[1.0, 3.0, 4.0, 8.0, 9.5]),
            vec![0.5, 0.5, 0.5, 0.75, 0.75]
        );
        assert_eq!(bin_half_widths(&[0.5]), vec![0.25]);
        for schedule in [
            vec![1.0, 3.0, 4.0, 8.0, 9.5],
            (1..=12).map(|k| 5.0 * f64::from(k)).collect(),
            vec![0.5],
            vec![2.0, 2.1, 7.0],
        ] {
            let w = bin_half_widths(&schedule);
            assert!(schedule[0] - w[0] >= 0.0);
            for k in 0..schedule.len() {
                assert!(w[k] > 0.0);
                if k + 1 < schedule.len() {
                    assert!(schedule[k] + w[k] <= schedule[k + 1] - w[k + 1] + 1e-12);
                }
            }
        }
        // Rows on the bins' common edges (every 0.25 mm, edges at 1.5,
        // 2.5, …) belong to one bin each.
        let x: Vec<f64> = (0..=40).map(|i| 0.25 * f64::from(i)).collect();
        let c = curve(x.clone(), x.clone());
        let schedule: Vec<f64> = (1..=10).map(f64::from).collect();
        let w = bin_half_widths(&schedule);
        let bins: Vec<(usize, usize)> = schedule
            .iter()
            .zip(&w)
            .map(|(d, w)| c.bin_rows(d - w, (d + w).min(10.0)))
            .collect();
        for pair in bins.windows(2) {
            assert_eq!(pair[0].1, pair[1].0, "{bins:?}");
        }
        assert_eq!(bins[0], (2, 6));
        assert_eq!(bins[9], (38, 41));
    }

    #[test]
    fn exactly_linear_data_give_exact_values_and_sigma_row_times_c() {
        // Rows every 0.1 mm, half a spacing off the schedule: centred
        // bins of 40 rows each.
        let x: Vec<f64> = (0..800).map(|i| 0.05 + 0.1 * f64::from(i)).collect();
        let c = curve(x.clone(), x.iter().map(|d| 3.0 + 0.5 * d).collect());
        let noise = Noise {
            relative: 0.01,
            absolute: 0.5,
        };
        let schedule = every_four(76);
        let q = MeasuredQuantity::new(
            Quantity::Force,
            vec![c.clone()],
            &schedule,
            0.0,
            Some(noise),
        )
        .unwrap();
        assert!(q.interpolation_error < 1e-9);
        for (k, &d) in schedule.iter().enumerate() {
            let fit = c.bin_fit(d, q.half_widths[k], q.slope_window).unwrap();
            assert_eq!(fit.rows, 40);
            assert!((fit.factor - 1.0 / 40.0_f64.sqrt()).abs() < 1e-12);
            assert!((fit.slope - 0.5).abs() < 1e-12);
            let truth = 3.0 + 0.5 * d;
            assert!((q.values[k] - truth).abs() < 1e-12);
            let expected = noise.sigma(q.values[k]) / 40.0_f64.sqrt();
            assert!((q.sigma[k] - expected).abs() < 1e-12 * expected);
        }
    }

    #[test]
    fn noisy_linear_data_have_standardised_residuals_of_unit_variance() {
        // 10 seeds × 20 points: Σ z² over N = 200 independent points is
        // χ²_N; its 0.1 % … 99.9 % range by Wilson–Hilferty
        // (N (1 − 2/(9N) ± z √(2/(9N)))³, z = 3.0902), ≈ 0.72 … 1.34 of N.
        // (The σ of one row instead would give about N/20.)
        let noise = Noise {
            relative: 0.0,
            absolute: 0.3,
        };
        let schedule = every_four(80);
        let mut sum = 0.0;
        let mut count = 0;
        for seed in 0..10 {
            let c = noisy_linear(seed, 2.0, noise.absolute);
            let q = MeasuredQuantity::new(Quantity::Force, vec![c], &schedule, 0.0, Some(noise))
                .unwrap();
            // The bins' parabolas average the noise out of f″: the bound
            // stays near σ_k (≈ 0.07), far below the rows' second
            // differences (≈ 4·0.3/0.2² per row).
            assert!(q.interpolation_error < 0.5, "{}", q.interpolation_error);
            for (k, &d) in schedule.iter().enumerate() {
                let z = (q.values[k] - (2.0 + 0.3 * d)) / q.sigma[k];
                sum += z * z;
                count += 1;
            }
        }
        let n = f64::from(count);
        let (a, b) = (1.0 - 2.0 / (9.0 * n), 3.0902 * (2.0 / (9.0 * n)).sqrt());
        let (lo, hi) = ((a - b).powi(3), (a + b).powi(3));
        let variance = sum / n;
        eprintln!(
            "variance of z over {count} points: {variance:.3} (0.1 %…99.9 %: {lo:.3}…{hi:.3})"
        );
        assert!(
            variance > lo && variance < hi,
            "{variance} not in [{lo}, {hi}]"
        );
    }

    #[test]
    fn the_curvature_bound_holds_on_quadratic_data() {
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
        // f = d², f″ = 2: at 2.5 the bin holds the rows 2 and 3 (the
        // chord: 6.5, error ½·2·0.25); at 5 the rows 4, 5, 6 (25 + 2/3,
        // error ½·2·⟨(x − 5)²⟩ = 2/3). The bound is reached exactly.
        let square = curve(x.clone(), x.iter().map(|d| d * d).collect());
        let q =
            MeasuredQuantity::new(Quantity::Force, vec![square], &[2.5, 5.0], 0.0, None).unwrap();
        assert!((q.values[0] - 6.5).abs() < 1e-12);
        assert!((q.values[1] - (25.0 + 2.0 / 3.0)).abs() < 1e-12);
        assert!((q.interpolation_error - 2.0 / 3.0).abs() < 1e-12);
        // Unevenly spread rows, asymmetric and clipped bins.
        let x: Vec<f64> = (0..=60)
            .map(|i| {
                let i = f64::from(i);
                (i + 0.4 * (1.7 * i).sin()) / 3.0
            })
            .collect();
        let f = |d: f64| 0.5 * d * d - d + 3.0;
        let c = curve(x.clone(), x.iter().map(|&d| f(d)).collect());
        let schedule = [0.7, 2.0, 2.6, 5.0, 9.0, 13.0, 17.0, 20.0];
        let w = bin_half_widths(&schedule);
        let mut reached = false;
        for (&d, &w) in schedule.iter().zip(&w) {
            let fit = c.bin_fit(d, w, 0.5).unwrap();
            let error = (fit.value - f(d)).abs();
            assert!(
                error <= fit.error * (1.0 + 1e-9) + 1e-12,
                "{d}: {error} > {}",
                fit.error
            );
            reached |= fit.rows >= 3 && (error - fit.error).abs() < 1e-9;
        }
        assert!(reached);
    }

    #[test]
    fn replicates_average_c_squared_and_add_their_scatter() {
        // A: rows every 0.1 mm (40 per bin, c² = 1/40); B: rows every 4 mm
        // (one per bin: the interpolation, c = 1), 0.3 above A.
        let xa: Vec<f64> = (0..800).map(|i| 0.05 + 0.1 * f64::from(i)).collect();
        let a = curve(xa.clone(), xa.iter().map(|d| 1.0 + 0.2 * d).collect());
        let xb: Vec<f64> = (0..=20).map(|k| 4.0 * f64::from(k)).collect();
        let b = curve(xb.clone(), xb.iter().map(|d| 1.3 + 0.2 * d).collect());
        let schedule = every_four(76);
        let noise = Noise {
            relative: 0.0,
            absolute: 0.05,
        };
        let q = MeasuredQuantity::new(
            Quantity::Force,
            vec![a.clone(), b.clone()],
            &schedule,
            0.0,
            Some(noise),
        )
        .unwrap();
        assert_eq!(q.replicates, 2);
        let s2 = 0.3_f64 * 0.3 / 2.0;
        let c2 = (1.0 / 40.0 + 1.0) / 2.0;
        let expected = ((0.05_f64 * 0.05 * c2 + s2) / 2.0).sqrt();
        for (k, &d) in schedule.iter().enumerate() {
            assert!((q.values[k] - (1.15 + 0.2 * d)).abs() < 1e-12);
            assert!((q.sigma[k] - expected).abs() < 1e-12, "{}", q.sigma[k]);
        }
        // Without noise: the scatter alone, s/√m.
        let q = MeasuredQuantity::new(Quantity::E22, vec![a, b], &schedule, 0.0, None).unwrap();
        for s in &q.sigma {
            assert!((s - 0.15).abs() < 1e-12);
        }
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
        // At 2.5 the bin [1.5, 3.5) holds the rows 2 and 3: c² = 1/2.
        let s = q.sample(2.0, 0.5).unwrap();
        assert!((s.value - 5.1).abs() < 1e-12);
        assert!((s.value - q.values[0]).abs() < 1e-12);
        let scatter = (2.0_f64 * 0.1 * 0.1 / 1.0).sqrt();
        let expected = ((0.1_f64 * 5.1).powi(2) * 0.5 / 2.0 + scatter * scatter / 2.0).sqrt();
        assert!((s.sigma - expected).abs() < 1e-12);
        assert!((q.sigma[0] - expected).abs() < 1e-12);
        assert!((s.slope - 2.0).abs() < 1e-12);
        assert_eq!(q.slope_window, 1.0);
        // At the end of the range the bin is clipped; beyond, None.
        assert!((q.sample(9.5, 0.5).unwrap().slope - 2.0).abs() < 1e-12);
        assert!(q.sample(9.6, 0.5).is_none());
        assert!(q.sample(-1.0, 0.5).is_none());
    }

    #[test]
    fn sample_at_the_schedule_equals_the_precomputed_values() {
        let noise = Noise {
            relative: 0.02,
            absolute: 0.1,
        };
        let schedule = every_four(72);
        let offset = 0.7;
        let curves = vec![noisy_linear(1, 2.0, 0.3), noisy_linear(2, 2.4, 0.3)];
        let q =
            MeasuredQuantity::new(Quantity::Force, curves, &schedule, offset, Some(noise)).unwrap();
        let mut slopes = Vec::new();
        for (k, &d) in schedule.iter().enumerate() {
            let s = q.sample(d, offset).unwrap();
            assert_eq!((s.value, s.sigma), (q.values[k], q.sigma[k]));
            // The slope is the derivative in the offset (the bins' rows
            // stay the same for a small change).
            let h = 1e-6;
            let up = q.sample(d, offset + h).unwrap().value;
            let down = q.sample(d, offset - h).unwrap().value;
            assert!(((up - down) / (2.0 * h) - s.slope).abs() < 1e-6);
            slopes.push(s.slope);
        }
        // A bin narrowed where its noisy curvature estimate suggested a
        // bend has a noisier slope; the slopes still scatter about the
        // data's 0.3 (their mean within 0.1).
        let mean = slopes.iter().sum::<f64>() / slopes.len() as f64;
        assert!((mean - 0.3).abs() < 0.1, "{mean}");
    }
}
