//! PNG line plots with an embedded font (DejaVu Sans), so pictures render
//! the same on any machine without system fonts.

use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;
use plotters::style::{FontStyle, register_font};

static FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
static REGISTER: Once = Once::new();

/// Why a PNG plot or contour map was not written. The Display texts name
/// the file (or the map) and say what failed.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// Drawing or writing a line plot failed.
    #[error("{}: cannot draw plot: {message}", .path.display())]
    Plot {
        /// The PNG file.
        path: PathBuf,
        /// The drawing backend's message.
        message: String,
    },
    /// Drawing or writing a contour map failed.
    #[error("{}: cannot draw contour map: {message}", .path.display())]
    ContourMap {
        /// The PNG file.
        path: PathBuf,
        /// The drawing backend's message.
        message: String,
    },
    /// The maps of a contour picture cannot be laid out (`error` says why).
    #[error("{}: {error}", .path.display())]
    Layout {
        /// The PNG file.
        path: PathBuf,
        /// What is wrong with the maps or the picture's size.
        error: Box<PlotError>,
    },
    /// A contour picture without maps.
    #[error("no map to draw")]
    NoMap,
    /// A map's colour-bar range is not an increasing finite pair.
    #[error("map \"{title}\": the range ({lo}, {hi}) is not an increasing finite pair")]
    BadRange {
        /// The map's title.
        title: String,
        /// The range's lower end.
        lo: f64,
        /// The range's upper end.
        hi: f64,
    },
    /// The picture leaves too little room for a map's axes and colour bar.
    #[error("map \"{title}\": a picture of {width}×{height} px is too small for {maps} map(s)")]
    TooSmall {
        /// The map's title.
        title: String,
        /// The picture's width in pixels.
        width: u32,
        /// The picture's height in pixels.
        height: u32,
        /// The number of maps side by side.
        maps: usize,
    },
    /// A map has not one value per triangle.
    #[error("map \"{title}\": {values} values for {triangles} triangles")]
    ValueCount {
        /// The map's title.
        title: String,
        /// The number of values.
        values: usize,
        /// The number of triangles.
        triangles: usize,
    },
    /// A map's point is not finite.
    #[error("map \"{title}\": point {point} is not finite")]
    PointNotFinite {
        /// The map's title.
        title: String,
        /// The point's index.
        point: usize,
    },
    /// A point of an outline drawn over a map is not finite.
    #[error("map \"{title}\": point {point} of outline \"{outline}\" is not finite")]
    OutlineNotFinite {
        /// The map's title.
        title: String,
        /// The outline's label.
        outline: String,
        /// The point's index in the outline.
        point: usize,
    },
    /// A map's triangle refers to a point past the end of the points.
    #[error(
        "map \"{title}\": triangle {triangle} refers to point {point}, but there are {points} points"
    )]
    PointOutOfRange {
        /// The map's title.
        title: String,
        /// The triangle's index.
        triangle: usize,
        /// The index it refers to.
        point: usize,
        /// The number of points.
        points: usize,
    },
}

pub(crate) fn ensure_font() {
    REGISTER.call_once(|| {
        // The embedded font is a valid TrueType file; failure would be a
        // build defect, and plotting then falls back to no text.
        let _ = register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// One curve of a panel.
#[derive(Debug, Clone)]
pub struct Series {
    /// Legend label.
    pub label: String,
    /// `(x, y)` points in drawing order.
    pub points: Vec<(f64, f64)>,
}

/// One set of axes.
#[derive(Debug, Clone)]
pub struct Panel {
    /// Title above the axes.
    pub title: String,
    /// x-axis label with unit.
    pub x_label: String,
    /// y-axis label with unit.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series>,
}

/// The `i`-th colour of the plots' palette (repeating after ten).
pub(crate) fn palette(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

const PALETTE: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
    RGBColor(23, 190, 207),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
];

/// A tick label with as many decimals as a span of `span` needs for
/// neighbouring ticks to differ (plotters' default shows too few for
/// small spans).
fn tick_label(value: f64, span: f64) -> String {
    let decimals = if span > 0.0 && span.is_finite() {
        (2.0 - span.log10().floor()).clamp(0.0, 12.0) as usize
    } else {
        3
    };
    let text = format!("{:.*}", decimals, value + 0.0);
    if text.starts_with('-') && text[1..].chars().all(|c| c == '0' || c == '.') {
        text[1..].to_string()
    } else {
        text
    }
}

/// Saves the RGB pixels `buffer` of a `dims` picture as a PNG at `path`
/// (PNG whatever the name: outputs are written under a temporary name).
pub(crate) fn save_png(path: &Path, buffer: &[u8], dims: (u32, u32)) -> image::ImageResult<()> {
    image::save_buffer_with_format(
        path,
        buffer,
        dims.0,
        dims.1,
        image::ColorType::Rgb8,
        image::ImageFormat::Png,
    )
}

/// Draws `panels` on a grid of `rows × cols` into a PNG of
/// `width × height` pixels.
///
/// # Errors
/// [`PlotError::Plot`], naming the file, when drawing or writing fails.
pub fn write_panels(
    path: &Path,
    panels: &[Panel],
    (rows, cols): (usize, usize),
    (width, height): (u32, u32),
) -> Result<(), PlotError> {
    ensure_font();
    let fail = |e: &dyn std::fmt::Display| PlotError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let dims = (width, height);
    let mut buffer = vec![0; 3 * dims.0 as usize * dims.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, dims).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let areas = root.split_evenly((rows, cols));
        for (panel, area) in panels.iter().zip(areas.iter()) {
            draw_panel(panel, area).map_err(|e| fail(&e))?;
        }
        root.present().map_err(|e| fail(&e))?;
    }
    save_png(path, &buffer, dims).map_err(|e| fail(&e))?;
    Ok(())
}

fn bounds(panel: &Panel) -> ((f64, f64), (f64, f64)) {
    let mut x = (f64::INFINITY, f64::NEG_INFINITY);
    let mut y = (f64::INFINITY, f64::NEG_INFINITY);
    for s in &panel.series {
        for &(px, py) in &s.points {
            if px.is_finite() && py.is_finite() {
                x = (x.0.min(px), x.1.max(px));
                y = (y.0.min(py), y.1.max(py));
            }
        }
    }
    // Axes span at most ±1e300, so that the span and its margin stay finite
    // (an infinite range would never finish placing its ticks).
    let pad = |(lo, hi): (f64, f64), margin: f64| {
        let (lo, hi) = (lo.max(-1e300), hi.min(1e300));
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            (0.0, 1.0)
        } else if hi - lo <= f64::EPSILON * hi.abs().max(1.0) {
            (lo - 0.5 * lo.abs().max(1.0), hi + 0.5 * hi.abs().max(1.0))
        } else {
            let m = margin * (hi - lo);
            (lo - m, hi + m)
        }
    };
    (pad(x, 0.0), pad(y, 0.05))
}

fn draw_panel<DB: DrawingBackend>(
    panel: &Panel,
    area: &DrawingArea<DB, plotters::coord::Shift>,
) -> Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let ((x0, x1), (y0, y1)) = bounds(panel);
    let mut chart = ChartBuilder::on(area)
        .caption(&panel.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart
        .configure_mesh()
        .x_label_formatter(&|v| tick_label(*v, x1 - x0))
        .y_label_formatter(&|v| tick_label(*v, y1 - y0))
        .x_desc(&panel.x_label)
        .y_desc(&panel.y_label)
        .label_style(("sans-serif", 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()?;
    for (i, s) in panel.series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        chart
            .draw_series(LineSeries::new(
                s.points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite()),
                color.stroke_width(2),
            ))?
            .label(&s.label)
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
            });
    }
    if panel.series.len() > 1 || panel.series.iter().any(|s| !s.label.is_empty()) {
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()?;
    }
    Ok(())
}

/// Draws closed outlines in the plane (e.g. a ply's outer contour at several
/// depths) into a square PNG of `size × size` pixels at equal scale in x and
/// y, each series closed back to its first point, with the legend in the
/// middle of the picture (which outer contours leave free).
///
/// # Errors
/// [`PlotError::Plot`], naming the file, when drawing or writing fails.
pub fn write_outlines_png(
    path: &Path,
    title: &str,
    outlines: &[Series],
    size: u32,
) -> Result<(), PlotError> {
    ensure_font();
    let fail = |e: &dyn std::fmt::Display| PlotError::Plot {
        path: path.to_path_buf(),
        message: e.to_string(),
    };
    let dims = (size, size);
    let mut buffer = vec![0; 3 * dims.0 as usize * dims.1 as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, dims).into_drawing_area();
        root.fill(&WHITE).map_err(|e| fail(&e))?;
        let mut x = (f64::INFINITY, f64::NEG_INFINITY);
        let mut y = (f64::INFINITY, f64::NEG_INFINITY);
        for &(px, py) in outlines.iter().flat_map(|s| &s.points) {
            if px.is_finite() && py.is_finite() {
                x = (x.0.min(px), x.1.max(px));
                y = (y.0.min(py), y.1.max(py));
            }
        }
        if !(x.0 <= x.1 && y.0 <= y.1) {
            x = (-1.0, 1.0);
            y = (-1.0, 1.0);
        }
        // Equal scale: the ranges get the aspect ratio of the plotting area
        // (the titled area less the margins and label areas).
        let area = root
            .titled(title, ("sans-serif", 20))
            .map_err(|e| fail(&e))?;
        let (w, h) = area.dim_in_pixel();
        let (margin, x_labels, y_labels) = (12u32, 50u32, 70u32);
        let plot_w = f64::from(w.saturating_sub(2 * margin + y_labels).max(1));
        let plot_h = f64::from(h.saturating_sub(2 * margin + x_labels).max(1));
        let scale =
            (1.06 * (x.1 - x.0).max(1e-9) / plot_w).max(1.06 * (y.1 - y.0).max(1e-9) / plot_h);
        let (hx, hy) = (0.5 * scale * plot_w, 0.5 * scale * plot_h);
        let (cx, cy) = (0.5 * (x.0 + x.1), 0.5 * (y.0 + y.1));
        let mut chart = ChartBuilder::on(&area)
            .margin(margin)
            .x_label_area_size(x_labels)
            .y_label_area_size(y_labels)
            .build_cartesian_2d(cx - hx..cx + hx, cy - hy..cy + hy)
            .map_err(|e| fail(&e))?;
        chart
            .configure_mesh()
            .x_desc("x [mm]")
            .y_desc("y [mm]")
            .label_style(("sans-serif", 14))
            .light_line_style(RGBColor(235, 235, 235))
            .draw()
            .map_err(|e| fail(&e))?;
        for (i, s) in outlines.iter().enumerate() {
            let color = PALETTE[i % PALETTE.len()];
            let closed = s
                .points
                .iter()
                .chain(s.points.first())
                .copied()
                .filter(|(x, y)| x.is_finite() && y.is_finite());
            chart
                .draw_series(LineSeries::new(closed, color.stroke_width(2)))
                .map_err(|e| fail(&e))?
                .label(&s.label)
                .legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 14))
            // Outer contours enclose the blank's centre, so the middle of the
            // picture is free of lines; a corner is where the blank's corners are.
            .position(SeriesLabelPosition::MiddleMiddle)
            .draw()
            .map_err(|e| fail(&e))?;
        root.present().map_err(|e| fail(&e))?;
    }
    save_png(path, &buffer, dims).map_err(|e| fail(&e))?;
    Ok(())
}
