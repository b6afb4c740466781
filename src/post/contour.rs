//! Contour maps: PNG pictures of a per-element field on a deformed 2D
//! triangle mesh (strain or shear-angle maps of a specimen), several maps
//! side by side, each with its colour bar.
//!
//! Each map is drawn at equal scale in x and y (1 mm in x is as many pixels
//! as 1 mm in y), with axes in mm. Triangles are filled with the colour of
//! their value on the viridis colormap; triangles whose value is NaN or
//! infinite are grey ([`NO_VALUE_GREY`]). The triangles are rasterised here
//! (pixel centres sampled, integer edge functions on a 1/256-pixel grid with
//! a tie rule, so neighbouring triangles leave neither gaps nor overlaps) and
//! blitted into the picture; plotters draws the text, axes and colour bar
//! with the embedded DejaVu Sans font.
//!
//! [`contour_layout`] tells where each map lands in the picture (the pixel
//! of a point in mm, the colour of a value), for annotations and tests.
//!
//! [`write_contour_png_overlaid`] draws a [`MapOverlay`] over the maps:
//! labelled polylines (tool outlines) with a legend, and for a categorical
//! field a fixed colour per class with a legend instead of the colour bar
//! ([`contour_layout_overlaid`] tells where things land).

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::post::plot::{PlotError, ensure_font, save_png};

/// The colour of a triangle whose value is not finite.
pub const NO_VALUE_GREY: [u8; 3] = [150, 150, 150];

/// One map: a field with one value per triangle on a 2D mesh.
#[derive(Debug, Clone)]
pub struct ContourMap<'a> {
    /// Title above the map.
    pub title: String,
    /// Node coordinates `(x, y)` \[mm\], e.g. the deformed mesh projected on
    /// its plane.
    pub points: &'a [[f64; 2]],
    /// Triangles as indices into `points`.
    pub triangles: &'a [[usize; 3]],
    /// One value per triangle; NaN or infinity is drawn grey.
    pub values: &'a [f64],
    /// Colour-bar label with the unit, e.g. `γ [deg]`.
    pub label: String,
    /// The value range of the colour bar; values outside take the end
    /// colours. `None`: the minimum and maximum of the finite values (a
    /// constant field gets a small range symmetric about its value).
    pub range: Option<(f64, f64)>,
}

/// Where [`write_contour_png`] draws one map, in pixels of the picture
/// (x to the right, y down, pixel `(i, j)` covering `[i, i+1) × [j, j+1)`).
#[derive(Debug, Clone, PartialEq)]
pub struct MapFrame {
    /// Top-left pixel of the plotting rectangle (inside the axes).
    pub plot_origin: (i32, i32),
    /// Width and height of the plotting rectangle \[px\].
    pub plot_size: (u32, u32),
    /// The x range shown \[mm\].
    pub x_range: (f64, f64),
    /// The y range shown \[mm\].
    pub y_range: (f64, f64),
    /// Scale [px/mm], the same in x and y.
    pub pixels_per_mm: f64,
    /// Top-left pixel of the colour bar's colour strip.
    pub bar_origin: (i32, i32),
    /// Width and height of the colour strip \[px\].
    pub bar_size: (u32, u32),
    /// The value range of the colour bar (bottom, top).
    pub value_range: (f64, f64),
    /// The tick values of the colour bar.
    pub ticks: Vec<f64>,
}

impl MapFrame {
    /// The position of the point `p` \[mm\] in the picture, in continuous
    /// pixel coordinates (the centre of pixel `(i, j)` is `(i + 0.5, j + 0.5)`).
    pub fn to_pixel(&self, p: [f64; 2]) -> (f64, f64) {
        let s = self.pixels_per_mm;
        let u = f64::from(self.plot_origin.0) + 0.5 + (p[0] - self.x_range.0) * s;
        let bottom = f64::from(self.plot_origin.1) + f64::from(self.plot_size.1) - 0.5;
        let v = bottom - (p[1] - self.y_range.0) * s;
        (u, v)
    }

    /// The colour of `value` on this map: viridis over
    /// [`value_range`](Self::value_range), clamped at the ends, and
    /// [`NO_VALUE_GREY`] for NaN or infinity.
    pub fn colour(&self, value: f64) -> [u8; 3] {
        colour_of(value, self.value_range)
    }
}

/// Viridis anchors: entries 0, 17, 34, …, 255 of the 256-entry table of
/// matplotlib's `viridis` (van der Walt, Smith and Firing, `_cm_listed.py`
/// of matplotlib, first published in the CC0 `mpl-colormaps` repository).
/// Linear interpolation between these 16 anchors differs from the full table
/// by at most 7/255 in any channel.
const VIRIDIS: [[f64; 3]; 16] = [
    [0.267004, 0.004874, 0.329415],
    [0.282656, 0.100196, 0.422160],
    [0.277134, 0.185228, 0.489898],
    [0.253935, 0.265254, 0.529983],
    [0.221989, 0.339161, 0.548752],
    [0.190631, 0.407061, 0.556089],
    [0.163625, 0.471133, 0.558148],
    [0.139147, 0.533812, 0.555298],
    [0.120565, 0.596422, 0.543611],
    [0.134692, 0.658636, 0.517649],
    [0.208030, 0.718701, 0.472873],
    [0.327796, 0.773980, 0.406640],
    [0.477504, 0.821444, 0.318195],
    [0.647257, 0.858400, 0.209861],
    [0.824940, 0.884720, 0.106217],
    [0.993248, 0.906157, 0.143936],
];

/// The viridis colour at `t` ∈ [0, 1] (clamped; NaN gives the `t = 0`
/// colour), as 8-bit RGB.
pub fn viridis(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (VIRIDIS.len() - 1) as f64;
    let k = (x.floor() as usize).min(VIRIDIS.len() - 2);
    let f = x - k as f64;
    let (a, b) = (VIRIDIS[k], VIRIDIS[k + 1]);
    let c = |i: usize| ((a[i] + (b[i] - a[i]) * f) * 255.0).round() as u8;
    [c(0), c(1), c(2)]
}

/// The colour of `value` over `(lo, hi)`; grey for a non-finite value.
fn colour_of(value: f64, (lo, hi): (f64, f64)) -> [u8; 3] {
    if value.is_finite() {
        viridis((value - lo) / (hi - lo))
    } else {
        NO_VALUE_GREY
    }
}

/// The colour-bar range of a map: its own, or that of the finite values.
fn value_range(map: &ContourMap) -> Result<(f64, f64), PlotError> {
    if let Some((lo, hi)) = map.range {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(PlotError::BadRange {
                title: map.title.clone(),
                lo,
                hi,
            });
        }
        return Ok((lo, hi));
    }
    let (lo, hi) = map
        .values
        .iter()
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        // No finite value at all: every triangle is grey.
        return Ok((0.0, 1.0));
    }
    let scale = lo.abs().max(hi.abs());
    if hi - lo <= 1e-9 * scale || hi - lo < 1e-300 {
        let c = 0.5 * (lo + hi);
        let d = 0.01 * c.abs().max(1.0);
        return Ok((c - d, c + d));
    }
    Ok((lo, hi))
}

/// Tick values in `[lo, hi]` at a round step (1, 1.5, 2, 2.5, 3, 4, 5, 6 or
/// 8 × 10ᵏ), 5 or 6 of them where such a step exists (otherwise the count
/// nearest to that), with the step.
fn nice_ticks(lo: f64, hi: f64) -> (Vec<f64>, f64) {
    const MANTISSAS: [(f64, u8); 9] = [
        (1.0, 0),
        (2.0, 0),
        (5.0, 0),
        (2.5, 1),
        (4.0, 1),
        (1.5, 2),
        (3.0, 2),
        (6.0, 2),
        (8.0, 2),
    ];
    let span = hi - lo;
    let e0 = (span / 10.0).log10().floor() as i32;
    let mut best: Option<((f64, u8), f64, i64, i64)> = None;
    for e in e0..=e0 + 2 {
        for &(m, rank) in &MANTISSAS {
            let step = m * 10f64.powi(e);
            let k0 = (lo / step - 1e-9).ceil() as i64;
            let k1 = (hi / step + 1e-9).floor() as i64;
            let count = k1 - k0 + 1;
            let miss = if (5..=6).contains(&count) {
                0.0
            } else {
                (count as f64 - 5.5).abs()
            };
            let better = match best {
                None => true,
                Some(((bm, brank), ..)) => (miss, rank) < (bm, brank),
            };
            if better {
                best = Some(((miss, rank), step, k0, k1));
            }
        }
    }
    let (_, step, k0, k1) = best.expect("at least one candidate step");
    let ticks = (k0..=k1).map(|k| k as f64 * step + 0.0).collect();
    (ticks, step)
}

/// Formats a tick value with as many decimals as the step needs
/// (a shared power of ten for very small or large values).
fn format_tick(v: f64, step: f64, max_abs: f64) -> String {
    let e = step.log10().floor();
    let m = step / 10f64.powf(e);
    let frac = usize::from((m - m.round()).abs() > 1e-6);
    if max_abs >= 1e5 || step < 1e-3 {
        // One exponent for all ticks of the bar: 0.75e-4, 1.00e-4, …
        let big = max_abs.log10().floor();
        let decimals = (big - e + frac as f64).max(0.0) as usize;
        let mantissa = v / 10f64.powf(big) + 0.0;
        format!("{mantissa:.decimals$}e{big}")
    } else {
        let decimals = (frac as f64 - e).max(0.0) as usize;
        format!("{v:.decimals$}")
    }
}

/// Formats an axis value [mm] with the fewest decimals (up to 6) that show
/// it to within a millionth of the axis span: `50`, `12.5`, `0.3`.
fn format_axis(v: f64, span: f64) -> String {
    let tol = 1e-6 * span;
    for decimals in 0..6 {
        let q = 10f64.powi(decimals as i32);
        if ((v * q).round() / q - v).abs() <= tol {
            return format!("{:.decimals$}", v + 0.0);
        }
    }
    format!("{:.6}", v + 0.0)
}

// Layout in pixels, per map panel.
const TITLE_H: i32 = 40;
const MARGIN: i32 = 10;
const Y_LABEL_AREA: i32 = 64;
const X_LABEL_AREA: i32 = 50;
const BAR_GAP: i32 = 18;
const BAR_W: i32 = 22;
const BAR_LABEL_AREA: i32 = 96;
const BAR_MIN_H: i32 = 220;
const FONT_TITLE: u32 = 20;
const FONT_TICKS: u32 = 14;
const FONT_DESC: u32 = 16;

/// Where each map goes in a picture of `size` pixels: the maps side by side
/// in equal columns, each with its plot at equal scale in x and y (the mesh's
/// bounding box padded by 3 %) centred with its colour bar.
///
/// # Errors
/// A [`PlotError`] naming the map when its data are inconsistent (values and
/// triangles of different lengths, an index past the points, a point that is
/// not finite, a range that is not increasing) or the picture is too small
/// ([`PlotError::NoMap`] when there is no map).
pub fn contour_layout(maps: &[ContourMap], size: (u32, u32)) -> Result<Vec<MapFrame>, PlotError> {
    if maps.is_empty() {
        return Err(PlotError::NoMap);
    }
    let (w, h) = (size.0 as i32, size.1 as i32);
    let n = maps.len() as i32;
    let mut frames = Vec::with_capacity(maps.len());
    for (k, map) in maps.iter().enumerate() {
        check_map(map)?;
        let px0 = k as i32 * w / n;
        let px1 = (k as i32 + 1) * w / n;
        let avail_w = px1 - px0 - 2 * MARGIN;
        let aw = avail_w - Y_LABEL_AREA - BAR_GAP - BAR_W - BAR_LABEL_AREA;
        let ah = h - TITLE_H - MARGIN - X_LABEL_AREA;
        if aw < 40 || ah < 40 {
            return Err(PlotError::TooSmall {
                title: map.title.clone(),
                width: size.0,
                height: size.1,
                maps: maps.len(),
            });
        }
        let (bx, by) = bounding_box(map);
        let pad = 0.03 * (bx.1 - bx.0).max(by.1 - by.0);
        let (bx, by) = ((bx.0 - pad, bx.1 + pad), (by.0 - pad, by.1 + pad));
        let (dx, dy) = (bx.1 - bx.0, by.1 - by.0);
        let s = (f64::from(aw - 1) / dx).min(f64::from(ah - 1) / dy);
        let pw = ((dx * s).floor() as i32 + 1).clamp(2, aw);
        let ph = ((dy * s).floor() as i32 + 1).clamp(2, ah);
        // The shown ranges: exactly (pw − 1)/s and (ph − 1)/s wide, centred
        // on the padded box.
        let (cx, cy) = (0.5 * (bx.0 + bx.1), 0.5 * (by.0 + by.1));
        let (hx, hy) = (0.5 * f64::from(pw - 1) / s, 0.5 * f64::from(ph - 1) / s);
        let group_w = Y_LABEL_AREA + pw + BAR_GAP + BAR_W + BAR_LABEL_AREA;
        let left = px0 + MARGIN + (avail_w - group_w) / 2;
        let top = TITLE_H + (ah - ph) / 2;
        let bar_h = ph.max(BAR_MIN_H.min(ah));
        let bar_top = (top + (ph - bar_h) / 2).max(TITLE_H);
        let value_range = value_range(map)?;
        let (ticks, _) = nice_ticks(value_range.0, value_range.1);
        frames.push(MapFrame {
            plot_origin: (left + Y_LABEL_AREA, top),
            plot_size: (pw as u32, ph as u32),
            x_range: (cx - hx, cx + hx),
            y_range: (cy - hy, cy + hy),
            pixels_per_mm: s,
            bar_origin: (left + Y_LABEL_AREA + pw + BAR_GAP, bar_top),
            bar_size: (BAR_W as u32, bar_h as u32),
            value_range,
            ticks,
        });
    }
    Ok(frames)
}

fn check_map(map: &ContourMap) -> Result<(), PlotError> {
    if map.values.len() != map.triangles.len() {
        return Err(PlotError::ValueCount {
            title: map.title.clone(),
            values: map.values.len(),
            triangles: map.triangles.len(),
        });
    }
    let n = map.points.len();
    if let Some(i) = map
        .points
        .iter()
        .position(|p| !(p[0].is_finite() && p[1].is_finite()))
    {
        return Err(PlotError::PointNotFinite {
            title: map.title.clone(),
            point: i,
        });
    }
    for (e, t) in map.triangles.iter().enumerate() {
        if let Some(&k) = t.iter().find(|&&k| k >= n) {
            return Err(PlotError::PointOutOfRange {
                title: map.title.clone(),
                triangle: e,
                point: k,
                points: n,
            });
        }
    }
    Ok(())
}

/// The bounding box of the points used by triangles (a unit box around the
/// origin or the single point when there is no extent).
fn bounding_box(map: &ContourMap) -> ((f64, f64), (f64, f64)) {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for t in map.triangles {
        for &k in t {
            let p = map.points[k];
            x = (x.0.min(p[0]), x.1.max(p[0]));
            y = (y.0.min(p[1]), y.1.max(p[1]));
        }
    }
    if x.0 > x.1 {
        return ((-0.5, 0.5), (-0.5, 0.5));
    }
    let d = (x.1 - x.0).max(y.1 - y.0);
    if d <= 0.0 {
        let h = 0.5 * x.0.abs().max(y.0.abs()).max(1.0);
        return ((x.0 - h, x.1 + h), (y.0 - h, y.1 + h));
    }
    // A very thin mesh still gets some height so the picture is not a line.
    let min_extent = 1e-3 * d;
    let widen = |(lo, hi): (f64, f64)| {
        let extra = 0.5 * (min_extent - (hi - lo)).max(0.0);
        (lo - extra, hi + extra)
    };
    (widen(x), widen(y))
}

/// Fixed-point subdivisions of a pixel for the rasteriser.
const SUB: f64 = 256.0;

/// Fills the triangles of `map` into an RGB image of the plotting rectangle
/// (white background), each in the colour `colour` gives its value.
fn rasterise(map: &ContourMap, frame: &MapFrame, colour: impl Fn(f64) -> [u8; 3]) -> Vec<u8> {
    let (w, h) = (frame.plot_size.0 as i64, frame.plot_size.1 as i64);
    let mut img = vec![255u8; (w * h * 3) as usize];
    let (ox, oy) = (
        f64::from(frame.plot_origin.0),
        f64::from(frame.plot_origin.1),
    );
    // Vertices in 1/SUB pixel units relative to the plotting rectangle,
    // clamped to a generous box so the integer products cannot overflow.
    let limit = (SUB * (w.max(h) as f64 + 16.0)) as i64;
    let fixed = |p: [f64; 2]| {
        let (u, v) = frame.to_pixel(p);
        (
            (((u - ox) * SUB).round() as i64).clamp(-limit, limit),
            (((v - oy) * SUB).round() as i64).clamp(-limit, limit),
        )
    };
    let half = (SUB / 2.0) as i64;
    let sub = SUB as i64;
    for (t, &value) in map.triangles.iter().zip(map.values) {
        let a = fixed(map.points[t[0]]);
        let mut b = fixed(map.points[t[1]]);
        let mut c = fixed(map.points[t[2]]);
        let area = (b.0 - a.0) * (c.1 - a.1) - (b.1 - a.1) * (c.0 - a.0);
        if area == 0 {
            continue;
        }
        if area < 0 {
            std::mem::swap(&mut b, &mut c);
        }
        let rgb = colour(value);
        // Pixel range whose centres (i·SUB + SUB/2) may lie inside.
        let lo_x = a.0.min(b.0).min(c.0);
        let hi_x = a.0.max(b.0).max(c.0);
        let lo_y = a.1.min(b.1).min(c.1);
        let hi_y = a.1.max(b.1).max(c.1);
        let i0 = ((lo_x - half).div_euclid(sub)).max(0);
        let i1 = ((hi_x - half).div_euclid(sub) + 1).min(w - 1);
        let j0 = ((lo_y - half).div_euclid(sub)).max(0);
        let j1 = ((hi_y - half).div_euclid(sub) + 1).min(h - 1);
        let edges = [(a, b), (b, c), (c, a)];
        // Edge function E(p) = (q − p0) × (p − p0) > 0 inside; on an edge
        // (E = 0) a pixel belongs to the triangle whose edge runs "forward"
        // (dy > 0, or dy = 0 and dx > 0), so a pixel centre on an edge
        // shared by two triangles is filled exactly once.
        let bias: [i64; 3] = edges.map(|(p, q)| {
            let (dx, dy) = (q.0 - p.0, q.1 - p.1);
            if dy > 0 || (dy == 0 && dx > 0) { 0 } else { -1 }
        });
        for j in j0..=j1 {
            let py = j * sub + half;
            let row = (j * w) as usize;
            for i in i0..=i1 {
                let px = i * sub + half;
                let inside = edges.iter().zip(&bias).all(|(&(p, q), &bias)| {
                    (q.0 - p.0) * (py - p.1) - (q.1 - p.1) * (px - p.0) + bias >= 0
                });
                if inside {
                    let k = 3 * (row + i as usize);
                    img[k..k + 3].copy_from_slice(&rgb);
                }
            }
        }
    }
    img
}

/// The colour strip of a colour bar: top row = top of the range.
fn bar_image(frame: &MapFrame) -> Vec<u8> {
    let (w, h) = (frame.bar_size.0 as usize, frame.bar_size.1 as usize);
    let (lo, hi) = frame.value_range;
    let mut img = Vec::with_capacity(w * h * 3);
    for j in 0..h {
        let t = 1.0 - (j as f64 + 0.5) / h as f64;
        let rgb = frame.colour(lo + t * (hi - lo));
        for _ in 0..w {
            img.extend_from_slice(&rgb);
        }
    }
    img
}

/// Draws `maps` side by side into a PNG of `size` pixels, each with its
/// title, axes in mm at equal scale and a vertical colour bar labelled with
/// the map's label (see [`contour_layout`] for where things go).
///
/// # Errors
/// A [`PlotError`] naming the file when a map's data are inconsistent
/// ([`PlotError::Layout`], see [`contour_layout`]) or drawing or writing
/// fails ([`PlotError::ContourMap`]).
pub fn write_contour_png(
    path: &Path,
    maps: &[ContourMap],
    size: (u32, u32),
) -> Result<(), PlotError> {
    write_contour_png_viewed(path, maps, size, MapView::Above)
}

/// Which way a map of a sheet in the xy-plane is looked at.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MapView {
    /// From +z: x to the right, y up.
    Above,
    /// From −z, as a camera under a transparent die sees the sheet: the
    /// picture is mirrored, x to the left, y up (the x tick labels keep the
    /// true coordinates).
    Below,
}

/// [`write_contour_png`] with the maps seen from `view`. Seen from below,
/// the points are mirrored in x before the layout (so
/// [`contour_layout`] of the mirrored maps tells where things land) and the
/// x axis is labelled with the true coordinates.
///
/// # Errors
/// As [`write_contour_png`].
pub fn write_contour_png_viewed(
    path: &Path,
    maps: &[ContourMap],
    size: (u32, u32),
    view: MapView,
) -> Result<(), PlotError> {
    write_contour_png_overlaid(path, maps, size, view, &MapOverlay::default())
}

fn draw_map<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    map: &ContourMap,
    frame: &MapFrame,
    (px0, px1): (i32, i32),
    view: MapView,
    plot_image: Vec<u8>,
    colour_bar: bool,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let x_sign = if view == MapView::Below { -1.0 } else { 1.0 };
    // Title, centred over the plot just above it.
    let (pw, ph) = (frame.plot_size.0 as i32, frame.plot_size.1 as i32);
    let (x0, y0) = frame.plot_origin;
    let title_style = TextStyle::from(("sans-serif", FONT_TITLE).into_font())
        .pos(Pos::new(HPos::Center, VPos::Bottom));
    let title_x = (x0 + pw / 2).clamp(px0 + 10, px1 - 10);
    root.draw_text(
        &map.title,
        &title_style,
        (title_x, y0.min(frame.bar_origin.1) - 10),
    )?;

    // The mesh: axes built around the plotting rectangle of the frame.
    let area = root.clone().shrink(
        (x0 - Y_LABEL_AREA, y0),
        (Y_LABEL_AREA + pw, ph + X_LABEL_AREA),
    );
    let mut chart = ChartBuilder::on(&area)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(
            frame.x_range.0..frame.x_range.1,
            frame.y_range.0..frame.y_range.1,
        )?;
    debug_assert_eq!(
        chart.plotting_area().get_pixel_range(),
        (x0..x0 + pw, y0..y0 + ph),
        "contour layout and plotters disagree on the plotting rectangle"
    );
    if let Some(el) = BitMapElement::with_owned_buffer((x0, y0), frame.plot_size, plot_image) {
        root.draw(&el)?;
    }
    chart
        .configure_mesh()
        .disable_mesh()
        .x_labels(((pw / 70) as usize).max(2))
        .y_labels(((ph / 80) as usize).max(2))
        .x_label_formatter(&|v| format_axis(x_sign * *v + 0.0, frame.x_range.1 - frame.x_range.0))
        .y_label_formatter(&|v| format_axis(*v, frame.y_range.1 - frame.y_range.0))
        .x_desc(if view == MapView::Below {
            "x [mm] (seen from below)"
        } else {
            "x [mm]"
        })
        .y_desc("y [mm]")
        .label_style(("sans-serif", FONT_TICKS))
        .axis_desc_style(("sans-serif", FONT_DESC))
        .draw()?;
    let frame_style = ShapeStyle::from(&BLACK).stroke_width(1);
    // A frame just outside the plotting rectangle (its left and bottom
    // sides fall on the axis lines plotters draws).
    root.draw(&Rectangle::new(
        [(x0 - 1, y0 - 1), (x0 + pw, y0 + ph)],
        frame_style,
    ))?;
    if !colour_bar {
        return Ok(());
    }

    // The colour bar: strip, frame, ticks on the right, label beyond them.
    let (bx, by) = frame.bar_origin;
    let (bw, bh) = (frame.bar_size.0 as i32, frame.bar_size.1 as i32);
    if let Some(el) = BitMapElement::with_owned_buffer((bx, by), frame.bar_size, bar_image(frame)) {
        root.draw(&el)?;
    }
    root.draw(&Rectangle::new(
        [(bx - 1, by - 1), (bx + bw, by + bh)],
        frame_style,
    ))?;
    let (lo, hi) = frame.value_range;
    let (_, step) = nice_ticks(lo, hi);
    let max_abs = frame.ticks.iter().fold(0.0f64, |m, t| m.max(t.abs()));
    let tick_style = TextStyle::from(("sans-serif", FONT_TICKS).into_font())
        .pos(Pos::new(HPos::Left, VPos::Center));
    let mut label_w = 0;
    for &t in &frame.ticks {
        let y = by + (((hi - t) / (hi - lo) * f64::from(bh)).floor() as i32).clamp(0, bh - 1);
        root.draw(&PathElement::new(
            vec![(bx + bw, y), (bx + bw + 6, y)],
            frame_style,
        ))?;
        let text = format_tick(t, step, max_abs);
        let (tw, _) = root.estimate_text_size(&text, &tick_style)?;
        label_w = label_w.max(tw as i32);
        root.draw_text(&text, &tick_style, (bx + bw + 9, y))?;
    }
    let desc_style = TextStyle::from(
        ("sans-serif", FONT_DESC)
            .into_font()
            .transform(FontTransform::Rotate270),
    )
    .pos(Pos::new(HPos::Center, VPos::Center));
    let desc_x = (bx + bw + 9 + label_w + 14).min(px1 - FONT_DESC as i32 / 2 - 2);
    root.draw_text(&map.label, &desc_style, (desc_x, by + bh / 2))?;
    Ok(())
}

/// A polyline drawn over a map, e.g. the outline of a tool, with the label
/// the legend shows for it.
#[derive(Debug, Clone, PartialEq)]
pub struct LabelledPolyline {
    /// Legend label, e.g. `punch`.
    pub label: String,
    /// Points `(x, y)` in the map's coordinates \[mm\], in drawing order.
    pub points: Vec<[f64; 2]>,
    /// Whether the last point is joined back to the first.
    pub closed: bool,
}

/// One class of a categorical map: its legend name and fill colour.
#[derive(Debug, Clone, PartialEq)]
pub struct Category {
    /// Legend name, e.g. `sticking`.
    pub name: String,
    /// Fill colour, 8-bit RGB.
    pub colour: [u8; 3],
}

/// Fill colours for up to 8 classes of a categorical map: a light grey for
/// a "none" class 0, then the Okabe–Ito colours (distinct for colour-blind
/// readers): vermillion, blue, orange, reddish purple, bluish green, sky
/// blue, yellow.
pub const CATEGORY_COLOURS: [[u8; 3]; 8] = [
    [220, 220, 220],
    [213, 94, 0],
    [0, 114, 178],
    [230, 159, 0],
    [204, 121, 167],
    [0, 158, 115],
    [86, 180, 233],
    [240, 228, 66],
];

/// The colour of the centre line of an outline (it has a white rim, so it
/// stands out on dark and light fills alike).
pub const OUTLINE_COLOUR: [u8; 3] = [0, 0, 0];

/// What [`write_contour_png_overlaid`] draws over every map of a picture.
#[derive(Debug, Clone, Copy, Default)]
pub struct MapOverlay<'a> {
    /// Polylines drawn over the triangles (black, 2 px, with a thin white
    /// rim), the k-th solid, dashed, dotted or dash-dotted (k mod 4), each
    /// listed with its label in a legend right of the map. Parts outside the
    /// plotting rectangle are clipped (the triangles set the map's extent).
    pub outlines: &'a [LabelledPolyline],
    /// `Some`: the values are class indices; a finite integral value `k` in
    /// `0..categories.len()` is drawn in `categories[k].colour`, any other
    /// value in [`NO_VALUE_GREY`], and the colour bar is replaced by a
    /// legend with a swatch and the name of each class under the map's
    /// label (the map's range is ignored).
    pub categories: Option<&'a [Category]>,
}

impl MapOverlay<'_> {
    fn is_empty(&self) -> bool {
        self.outlines.is_empty() && self.categories.is_none()
    }
}

// Legend column reserved right of each map with an overlay.
const LEGEND_W: i32 = 170;
const LEGEND_ROW: i32 = 24;
const SWATCH: i32 = 18;
const SAMPLE_W: u32 = 34;
const SAMPLE_H: u32 = 14;
// Outline line: core and rim half-widths [px]; dash patterns [px on, off, …].
const OUTLINE_CORE: f64 = 1.0;
const OUTLINE_RIM: f64 = 2.2;
const OUTLINE_DASHES: [&[f64]; 4] = [&[], &[10.0, 5.0], &[2.5, 3.5], &[10.0, 4.0, 2.5, 4.0]];
// Pixel coordinates of outline points are kept within ±this (points farther
// away, e.g. 1e300 mm, would overflow).
const OUTLINE_FAR: f64 = 1e9;

/// The colour of `value` as a class index among `categories`.
fn category_colour(value: f64, categories: &[Category]) -> [u8; 3] {
    if value.is_finite() && value >= 0.0 && value.fract() == 0.0 && value < categories.len() as f64
    {
        categories[value as usize].colour
    } else {
        NO_VALUE_GREY
    }
}

/// Where each map of [`write_contour_png_overlaid`] goes: as
/// [`contour_layout`] when the overlay is empty; otherwise each map's
/// column is laid out narrower by a legend strip on its right. For a
/// categorical overlay the colour-bar fields of the frame tell where the
/// legend starts.
///
/// # Errors
/// As [`contour_layout`], and [`PlotError::OutlineNotFinite`] (naming the
/// first map and the outline) when an outline has a point that is not
/// finite.
pub fn contour_layout_overlaid(
    maps: &[ContourMap],
    size: (u32, u32),
    overlay: &MapOverlay,
) -> Result<Vec<MapFrame>, PlotError> {
    if overlay.is_empty() {
        return contour_layout(maps, size);
    }
    if maps.is_empty() {
        return Err(PlotError::NoMap);
    }
    let (w, n) = (size.0 as i32, maps.len() as i32);
    let mut frames = Vec::with_capacity(maps.len());
    for (k, map) in maps.iter().enumerate() {
        for outline in overlay.outlines {
            if let Some(i) = outline
                .points
                .iter()
                .position(|p| !(p[0].is_finite() && p[1].is_finite()))
            {
                return Err(PlotError::OutlineNotFinite {
                    title: map.title.clone(),
                    outline: outline.label.clone(),
                    point: i,
                });
            }
        }
        let px0 = k as i32 * w / n;
        let px1 = (k as i32 + 1) * w / n;
        let column = (px1 - px0 - LEGEND_W).max(0) as u32;
        let map = ContourMap {
            range: if overlay.categories.is_some() {
                None
            } else {
                map.range
            },
            ..map.clone()
        };
        let mut frame = match contour_layout(std::slice::from_ref(&map), (column, size.1)) {
            Ok(mut f) => f.remove(0),
            Err(PlotError::TooSmall { title, .. }) => {
                return Err(PlotError::TooSmall {
                    title,
                    width: size.0,
                    height: size.1,
                    maps: maps.len(),
                });
            }
            Err(e) => return Err(e),
        };
        frame.plot_origin.0 += px0;
        frame.bar_origin.0 += px0;
        frames.push(frame);
    }
    Ok(frames)
}

/// [`write_contour_png_viewed`] with `overlay` drawn over every map: tool
/// outlines with a legend, and for a categorical field a fixed colour per
/// class with a legend instead of the colour bar (see [`MapOverlay`];
/// [`contour_layout_overlaid`] tells where things land). Seen from below,
/// the outlines are mirrored in x with the maps. With an empty overlay the
/// picture is that of [`write_contour_png_viewed`].
///
/// # Errors
/// As [`write_contour_png`]; an outline point that is not finite is a
/// [`PlotError::Layout`] wrapping [`PlotError::OutlineNotFinite`], and no
/// file is written.
pub fn write_contour_png_overlaid(
    path: &Path,
    maps: &[ContourMap],
    size: (u32, u32),
    view: MapView,
    overlay: &MapOverlay,
) -> Result<(), PlotError> {
    let mirrored_points: Vec<Vec<[f64; 2]>>;
    let mirrored: Vec<ContourMap>;
    let mirrored_outlines: Vec<LabelledPolyline>;
    let (maps, outlines) = match view {
        MapView::Above => (maps, overlay.outlines),
        MapView::Below => {
            mirrored_points = maps
                .iter()
                .map(|m| m.points.iter().map(|p| [-p[0], p[1]]).collect())
                .collect();
            mirrored = maps
                .iter()
                .zip(&mirrored_points)
                .map(|(m, points)| ContourMap {
                    points,
                    ..m.clone()
                })
                .collect();
            mirrored_outlines = overlay
                .outlines
                .iter()
                .map(|o| LabelledPolyline {
                    points: o.points.iter().map(|p| [-p[0], p[1]]).collect(),
                    ..o.clone()
                })
                .collect();
            (&mirrored[..], &mirrored_outlines[..])
        }
    };
    let overlay = MapOverlay {
        outlines,
        categories: overlay.categories,
    };
    ensure_font();
    let frames = contour_layout_overlaid(maps, size, &overlay).map_err(|e| PlotError::Layout {
        path: path.to_path_buf(),
        error: Box::new(e),
    })?;
    let fail = |e: &dyn std::fmt::Display| PlotError::ContourMap {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let reserve = if overlay.is_empty() { 0 } else { LEGEND_W };
    let dims = size;
    let mut buffer = vec![0; 3 * dims.0 as usize * dims.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, dims).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        for (k, (map, frame)) in maps.iter().zip(&frames).enumerate() {
            let px0 = k as i32 * size.0 as i32 / maps.len() as i32;
            let px1 = (k as i32 + 1) * size.0 as i32 / maps.len() as i32;
            let mut img = match overlay.categories {
                Some(c) => rasterise(map, frame, |v| category_colour(v, c)),
                None => rasterise(map, frame, |v| frame.colour(v)),
            };
            draw_outlines(&mut img, frame, overlay.outlines);
            let colour_bar = overlay.categories.is_none();
            draw_map(
                &root,
                map,
                frame,
                (px0, px1 - reserve),
                view,
                img,
                colour_bar,
            )
            .map_err(|e| fail(&e))?;
            if !overlay.is_empty() {
                let (x, top) = if colour_bar {
                    (px1 - reserve + 6, frame.bar_origin.1)
                } else {
                    (
                        frame.bar_origin.0,
                        frame.plot_origin.1.min(frame.bar_origin.1),
                    )
                };
                draw_legend(&root, map, &overlay, (x, top)).map_err(|e| fail(&e))?;
            }
        }
        root.present().map_err(|e| fail(&e))?;
    }
    save_png(path, &buffer, dims).map_err(|e| fail(&e))?;
    Ok(())
}

/// Draws the outlines into the plotting rectangle's image: first the white
/// rims of all, then the black cores (so a rim never covers a core).
fn draw_outlines(img: &mut [u8], frame: &MapFrame, outlines: &[LabelledPolyline]) {
    let (ox, oy) = (
        f64::from(frame.plot_origin.0),
        f64::from(frame.plot_origin.1),
    );
    let pixels: Vec<Vec<(f64, f64)>> = outlines
        .iter()
        .map(|o| {
            o.points
                .iter()
                .map(|&p| {
                    let (u, v) = frame.to_pixel(p);
                    let far = |z: f64| z.clamp(-OUTLINE_FAR, OUTLINE_FAR);
                    (far(u - ox), far(v - oy))
                })
                .collect()
        })
        .collect();
    for (radius, colour) in [(OUTLINE_RIM, [255; 3]), (OUTLINE_CORE, OUTLINE_COLOUR)] {
        for (k, (o, pts)) in outlines.iter().zip(&pixels).enumerate() {
            let dashes = OUTLINE_DASHES[k % OUTLINE_DASHES.len()];
            stroke(img, frame.plot_size, pts, o.closed, dashes, radius, colour);
        }
    }
}

/// Whether arc length `s` [px] falls on a dash of the pattern `dashes`
/// (on, off, on, off … lengths; empty: a solid line).
fn on_dash(s: f64, dashes: &[f64]) -> bool {
    let period: f64 = dashes.iter().sum();
    if dashes.is_empty() || period <= 0.0 {
        return true;
    }
    let mut m = s.rem_euclid(period);
    for (i, &d) in dashes.iter().enumerate() {
        if m < d {
            return i % 2 == 0;
        }
        m -= d;
    }
    true
}

/// Sets the pixels of an RGB image of `size` whose centres lie within
/// `radius` of the polyline `pts` (pixel coordinates, the centre of pixel
/// `(i, j)` at `(i + 0.5, j + 0.5)`) and on a dash of `dashes`, to `colour`.
/// Segments are clipped to the image first, so far points cost nothing.
fn stroke(
    img: &mut [u8],
    size: (u32, u32),
    pts: &[(f64, f64)],
    closed: bool,
    dashes: &[f64],
    radius: f64,
    colour: [u8; 3],
) {
    let (w, h) = (i64::from(size.0), i64::from(size.1));
    let margin = radius + 1.0;
    let (xmin, xmax) = (-margin, w as f64 + margin);
    let (ymin, ymax) = (-margin, h as f64 + margin);
    let mut segments: Vec<((f64, f64), (f64, f64))> =
        pts.windows(2).map(|s| (s[0], s[1])).collect();
    if closed && pts.len() > 2 {
        segments.push((pts[pts.len() - 1], pts[0]));
    }
    let mut s0 = 0.0;
    for (a, b) in segments {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let len = dx.hypot(dy);
        // Liang–Barsky clipping of a + t (b − a), t ∈ [0, 1].
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, q) in [
            (-dx, a.0 - xmin),
            (dx, xmax - a.0),
            (-dy, a.1 - ymin),
            (dy, ymax - a.1),
        ] {
            if p == 0.0 {
                if q < 0.0 {
                    t1 = -1.0;
                }
            } else if p < 0.0 {
                t0 = t0.max(q / p);
            } else {
                t1 = t1.min(q / p);
            }
        }
        if t0 <= t1 {
            let c = (a.0 + t0 * dx, a.1 + t0 * dy);
            let d = (a.0 + t1 * dx, a.1 + t1 * dy);
            let (cx, cy) = (d.0 - c.0, d.1 - c.1);
            let clen2 = cx * cx + cy * cy;
            let start = s0 + t0 * len;
            let i0 = ((c.0.min(d.0) - radius - 0.5).floor() as i64).max(0);
            let i1 = ((c.0.max(d.0) + radius).ceil() as i64).min(w - 1);
            let j0 = ((c.1.min(d.1) - radius - 0.5).floor() as i64).max(0);
            let j1 = ((c.1.max(d.1) + radius).ceil() as i64).min(h - 1);
            for j in j0..=j1 {
                let py = j as f64 + 0.5;
                for i in i0..=i1 {
                    let px = i as f64 + 0.5;
                    let t = if clen2 > 0.0 {
                        (((px - c.0) * cx + (py - c.1) * cy) / clen2).clamp(0.0, 1.0)
                    } else {
                        0.0
                    };
                    let (qx, qy) = (c.0 + t * cx, c.1 + t * cy);
                    if (px - qx).hypot(py - qy) <= radius
                        && on_dash(start + t * clen2.sqrt(), dashes)
                    {
                        let k = 3 * (j * w + i) as usize;
                        img[k..k + 3].copy_from_slice(&colour);
                    }
                }
            }
        }
        s0 += len;
    }
}

/// Draws the legend of a map from `(x, top)` down: for a categorical
/// overlay the map's label and a swatch with the name of each class, then
/// a sample of each outline's line with its label.
fn draw_legend<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    map: &ContourMap,
    overlay: &MapOverlay,
    (x, top): (i32, i32),
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let text = TextStyle::from(("sans-serif", FONT_TICKS).into_font())
        .pos(Pos::new(HPos::Left, VPos::Center));
    let heading = TextStyle::from(("sans-serif", FONT_DESC).into_font())
        .pos(Pos::new(HPos::Left, VPos::Center));
    let frame_style = ShapeStyle::from(&BLACK).stroke_width(1);
    let mut y = top + LEGEND_ROW / 2;
    if let Some(categories) = overlay.categories {
        root.draw_text(&map.label, &heading, (x, y))?;
        y += LEGEND_ROW;
        for c in categories {
            let [r, g, b] = c.colour;
            let (sx, sy) = (x, y - SWATCH / 2);
            root.draw(&Rectangle::new(
                [(sx, sy), (sx + SWATCH, sy + SWATCH)],
                RGBColor(r, g, b).filled(),
            ))?;
            root.draw(&Rectangle::new(
                [(sx, sy), (sx + SWATCH, sy + SWATCH)],
                frame_style,
            ))?;
            root.draw_text(&c.name, &text, (x + SWATCH + 8, y))?;
            y += LEGEND_ROW;
        }
        y += LEGEND_ROW / 2;
    }
    for (k, o) in overlay.outlines.iter().enumerate() {
        let (sw, sh) = (SAMPLE_W, SAMPLE_H);
        let mut img = vec![255u8; (3 * sw * sh) as usize];
        let line = [
            (1.0, f64::from(sh) / 2.0),
            (f64::from(sw) - 1.0, f64::from(sh) / 2.0),
        ];
        let dashes = OUTLINE_DASHES[k % OUTLINE_DASHES.len()];
        stroke(
            &mut img,
            (sw, sh),
            &line,
            false,
            dashes,
            OUTLINE_CORE,
            OUTLINE_COLOUR,
        );
        if let Some(el) = BitMapElement::with_owned_buffer((x, y - sh as i32 / 2), (sw, sh), img) {
            root.draw(&el)?;
        }
        root.draw_text(&o.label, &text, (x + sw as i32 + 8, y))?;
        y += LEGEND_ROW;
    }
    Ok(())
}
