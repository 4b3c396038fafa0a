//! Range-profile plots in dB against range, like the thesis' figures: several curves overlaid
//! (Fourier and MUSIC), the true target ranges as vertical lines, an optional -3 dB reference.
//!
//! The format follows the extension: `.svg` (text drawn by the viewer) or `.png` (text rendered).
//! Both lay out text with the DejaVu Sans font embedded from `assets/`, so plots look the same on
//! every machine and need no system fonts.

use super::{atomic::write_atomic, profile::extension, StorageError};
use plotters::prelude::*;
use std::path::Path;

pub(crate) mod link;

/// The font embedded for PNG text (licence in assets/README.md).
static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

/// How a curve is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LineStyle {
    #[default]
    Solid,
    /// Dashed (thresholds, references).
    Dashed,
}

/// One curve: a label for the legend and the profile in dB on the plot's scale.
#[derive(Debug, Clone, PartialEq)]
pub struct Curve {
    pub label: String,
    pub range_m: Vec<f64>,
    pub db: Vec<f64>,
    pub style: LineStyle,
}

impl Curve {
    /// A solid curve.
    pub fn solid(label: impl Into<String>, range_m: Vec<f64>, db: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            range_m,
            db,
            style: LineStyle::Solid,
        }
    }
}

/// A point marked on the plot with its text (a detection: range and level).
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    pub range_m: f64,
    pub db: f64,
    pub label: String,
}

/// What one plot shows.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfilePlot {
    pub title: String,
    pub curves: Vec<Curve>,
    /// True target ranges, drawn as dashed vertical lines.
    pub targets_m: Vec<f64>,
    /// Ranges estimated without a profile (root-MUSIC, ESPRIT), drawn as dotted vertical lines.
    pub estimates_m: Vec<f64>,
    /// Detections, marked on the curve with their text.
    pub markers: Vec<Marker>,
    /// Range window to show; `None` = around the targets (or the whole axis without targets).
    pub window_m: Option<(f64, f64)>,
    /// Lowest dB shown (values below are clipped to it); `None`: from the data in the window.
    pub floor_db: Option<f64>,
    /// Draw a horizontal reference line at this level (the thesis' red dashed -3 dB line).
    pub reference_db: Option<f64>,
    /// The y axis' title.
    pub y_label: String,
    /// The x axis' title.
    pub x_label: String,
}

impl ProfilePlot {
    /// A plot of `curves` with nothing else marked, normalised-dB axis title.
    pub fn new(title: impl Into<String>, curves: Vec<Curve>) -> Self {
        Self {
            title: title.into(),
            curves,
            targets_m: Vec::new(),
            estimates_m: Vec::new(),
            markers: Vec::new(),
            window_m: None,
            floor_db: None,
            reference_db: None,
            y_label: "Normalised magnitude (dB)".into(),
            x_label: "Range (m)".into(),
        }
    }
}

/// Widest dynamic range an automatic floor shows, dB.
const MAX_AUTO_RANGE_DB: f64 = 120.0;

const SIZE: (u32, u32) = (960, 540);
pub(crate) const PALETTE: [RGBColor; 4] = [
    RGBColor(0, 90, 181),
    RGBColor(220, 50, 32),
    RGBColor(0, 140, 70),
    RGBColor(150, 80, 160),
];

/// Draws the plot to `path` (`.svg` or `.png`), atomically.
pub fn draw(path: &Path, plot: &ProfilePlot) -> Result<(), StorageError> {
    if plot.curves.iter().all(|c| c.range_m.is_empty()) {
        return Err(StorageError::BadData {
            path: path.to_path_buf(),
            reason: "nothing to plot: every curve is empty".into(),
        });
    }
    write_figure(path, plot)
}

/// A figure that draws itself on any plotters backend (SVG text or a PNG bitmap).
trait Render {
    fn render<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String>;
}

impl Render for ProfilePlot {
    fn render<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        render(root, self)
    }
}

/// Draws `figure` to `path`, `.svg` or `.png` by its extension, atomically.
fn write_figure(path: &Path, figure: &impl Render) -> Result<(), StorageError> {
    // Both backends measure text with the registered font (the SVG one to lay out labels).
    register_font_once();
    match extension(path).as_deref() {
        Some("svg") => {
            let mut svg = String::new();
            {
                let root = SVGBackend::with_string(&mut svg, SIZE).into_drawing_area();
                figure.render(root).map_err(|r| plot_error(path, r))?;
            }
            write_atomic(path, svg.as_bytes())
        }
        Some("png") => {
            let png = render_png(|root| figure.render(root)).map_err(|r| plot_error(path, r))?;
            write_atomic(path, &png)
        }
        _ => Err(StorageError::UnsupportedFormat {
            path: path.to_path_buf(),
            allowed: "plots are written as .svg or .png",
        }),
    }
}

fn plot_error(path: &Path, reason: String) -> StorageError {
    StorageError::Plot {
        path: path.to_path_buf(),
        reason,
    }
}

/// Renders into memory and encodes a PNG, so the file is written like every other output
/// (atomically, through an unpredictable temporary name, never through a symlink).
fn render_png(
    draw: impl FnOnce(DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<Vec<u8>, String> {
    render_png_sized(SIZE, draw)
}

/// [`render_png`] at `size` pixels.
pub(crate) fn render_png_sized(
    size: (u32, u32),
    draw: impl FnOnce(DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<(), String>,
) -> Result<Vec<u8>, String> {
    let (w, h) = size;
    let mut rgb = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area();
        draw(root)?;
    }
    let image = image::RgbImage::from_raw(w, h, rgb)
        .ok_or_else(|| "the rendered image has the wrong size".to_string())?;
    let mut png = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut png, image::ImageFormat::Png)
        .map_err(|e| e.to_string())?;
    Ok(png.into_inner())
}

pub(crate) fn register_font_once() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The font is compiled in and known good; a failure would only mean PNGs without text.
        if plotters::style::register_font("sans-serif", FontStyle::Normal, FONT).is_err() {
            tracing::warn!("the embedded DejaVu Sans font could not be registered");
        }
    });
}

/// The x window: the requested one, else 0.5 m around the targets, else the whole axis.
fn x_window(plot: &ProfilePlot) -> (f64, f64) {
    if let Some(w) = plot.window_m {
        return w;
    }
    let (lo, hi) = plot
        .targets_m
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &r| {
            (lo.min(r), hi.max(r))
        });
    if lo.is_finite() {
        return ((lo - 0.5).max(0.0), hi + 0.5);
    }
    let all = plot.curves.iter().flat_map(|c| c.range_m.iter().copied());
    let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), r| {
        (lo.min(r), hi.max(r))
    });
    (lo, hi)
}

/// The y range: the requested floor (or one from the data: the lowest curve value in the window,
/// at most [`MAX_AUTO_RANGE_DB`] under the highest) up to a little above the highest value.
fn y_range(plot: &ProfilePlot, x0: f64, x1: f64) -> (f64, f64) {
    let values = plot.curves.iter().flat_map(|c| {
        c.range_m
            .iter()
            .zip(&c.db)
            .filter(move |(r, d)| **r >= x0 && **r <= x1 && d.is_finite())
            .map(|(_, d)| *d)
    });
    let (lo, hi) = values
        .chain(plot.markers.iter().map(|m| m.db))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), d| {
            (lo.min(d), hi.max(d))
        });
    let hi = if hi.is_finite() { hi } else { 0.0 };
    let top = hi + 0.08 * (hi - lo).clamp(10.0, MAX_AUTO_RANGE_DB) + 3.0;
    let bottom = match plot.floor_db {
        Some(f) => f,
        None if lo.is_finite() => (lo - 3.0).max(hi - MAX_AUTO_RANGE_DB),
        None => hi - 60.0,
    };
    (bottom.min(top - 1.0), top)
}

/// A chart on two linear axes (a log axis is plotted as its exponent).
pub(crate) type Axes<'a, DB> = ChartContext<
    'a,
    DB,
    Cartesian2d<plotters::coord::types::RangedCoordf64, plotters::coord::types::RangedCoordf64>,
>;

/// The legend: a framed, lightly opaque box at `position`.
pub(crate) fn draw_legend<'a, DB: DrawingBackend + 'a, CT: CoordTranslate>(
    chart: &mut ChartContext<'a, DB, CT>,
    position: SeriesLabelPosition,
    font_px: u32,
) -> Result<(), String> {
    chart
        .configure_series_labels()
        .position(position)
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font(("sans-serif", font_px))
        .draw()
        .map_err(|e| e.to_string())
}

/// Dashed vertical lines at `xs` over `ys`, dashes and gaps `(dash, gap)` pixels long, the
/// first one named `label` in the legend.
fn vertical_lines<DB: DrawingBackend>(
    chart: &mut Axes<'_, DB>,
    xs: impl Iterator<Item = f64>,
    (y0, y1): (f64, f64),
    (dash, gap): (u32, u32),
    style: ShapeStyle,
    label: &str,
) -> Result<(), String> {
    for (i, x) in xs.enumerate() {
        let series = chart
            .draw_series(DashedLineSeries::new(
                vec![(x, y0), (x, y1)],
                dash,
                gap,
                style,
            ))
            .map_err(|err| err.to_string())?;
        if i == 0 {
            series
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
    }
    Ok(())
}

/// The detections in view: a cross at each, labelled.
fn draw_detections<DB: DrawingBackend>(
    chart: &mut Axes<'_, DB>,
    markers: &[Marker],
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> Result<(), String> {
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| err.to_string();
    let marker_color = RGBColor(200, 30, 30);
    let shown: Vec<&Marker> = markers
        .iter()
        .filter(|m| (x0..=x1).contains(&m.range_m))
        .collect();
    if !shown.is_empty() {
        chart
            .draw_series(shown.iter().map(|m| {
                Cross::new(
                    (m.range_m, m.db.clamp(y0, y1)),
                    6,
                    marker_color.stroke_width(2),
                )
            }))
            .map_err(e)?
            .label("detection")
            .legend(move |(x, y)| Cross::new((x + 10, y), 5, marker_color.stroke_width(2)));
        for m in shown {
            chart
                .draw_series(std::iter::once(Text::new(
                    m.label.clone(),
                    (m.range_m, (m.db + 0.04 * (y1 - y0)).min(y1)),
                    ("sans-serif", 13).into_font().color(&marker_color),
                )))
                .map_err(e)?;
        }
    }
    Ok(())
}

fn render<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    plot: &ProfilePlot,
) -> Result<(), String> {
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| err.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (x0, x1) = x_window(plot);
    let (x0, x1) = if x1 > x0 {
        (x0, x1)
    } else {
        (x0 - 0.5, x0 + 0.5)
    };
    let (y0, y1) = y_range(plot, x0, x1);
    let mut chart = ChartBuilder::on(&root)
        .caption(&plot.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc(plot.x_label.as_str())
        .y_desc(plot.y_label.as_str())
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    for (i, curve) in plot.curves.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let points: Vec<(f64, f64)> = curve
            .range_m
            .iter()
            .zip(&curve.db)
            .filter(|(r, _)| **r >= x0 && **r <= x1)
            .map(|(&r, &d)| (r, if d.is_finite() { d.clamp(y0, y1) } else { y0 }))
            .collect();
        let style = color.stroke_width(2);
        let series = match curve.style {
            LineStyle::Solid => chart
                .draw_series(LineSeries::new(points, style))
                .map_err(e)?,
            LineStyle::Dashed => chart
                .draw_series(DashedLineSeries::new(points, 5, 4, color.stroke_width(1)))
                .map_err(e)?,
        };
        series
            .label(curve.label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    let in_view = plot
        .estimates_m
        .iter()
        .copied()
        .filter(|r| (x0..=x1).contains(r));
    let estimate_style = RGBColor(150, 80, 160).stroke_width(2);
    vertical_lines(
        &mut chart,
        in_view,
        (y0, y1),
        (2, 3),
        estimate_style,
        "estimated range",
    )?;
    draw_detections(&mut chart, &plot.markers, (x0, x1), (y0, y1))?;
    if let Some(level) = plot.reference_db {
        let style = RED.stroke_width(1);
        chart
            .draw_series(DashedLineSeries::new(
                vec![(x0, level), (x1, level)],
                6,
                4,
                style,
            ))
            .map_err(e)?
            .label(format!("{level} dB"))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    let target_style = BLACK.mix(0.6).stroke_width(1);
    let targets = plot.targets_m.iter().copied();
    vertical_lines(
        &mut chart,
        targets,
        (y0, y1),
        (4, 4),
        target_style,
        "true range",
    )?;
    draw_legend(&mut chart, SeriesLabelPosition::UpperRight, 14)?;
    root.present().map_err(e)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plot() -> ProfilePlot {
        let range_m: Vec<f64> = (0..400).map(|i| i as f64 * 0.015).collect();
        let db = range_m
            .iter()
            .map(|r| -40.0 * (r - 3.0_f64).abs().min(1.0))
            .collect();
        ProfilePlot {
            targets_m: vec![3.0],
            floor_db: Some(-50.0),
            reference_db: Some(-3.0),
            markers: vec![Marker {
                range_m: 3.0,
                db: 0.0,
                label: "3.000 m, 0.0 dB".into(),
            }],
            ..ProfilePlot::new(
                "one target at 3 m",
                vec![Curve::solid("Fourier", range_m, db)],
            )
        }
    }

    #[test]
    fn svg_contains_the_title_and_legend() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.svg");
        draw(&path, &plot()).unwrap();
        let svg = std::fs::read_to_string(&path).unwrap();
        assert!(svg.starts_with("<svg") && svg.contains("one target at 3 m"));
        assert!(svg.contains("Fourier") && svg.contains("true range"));
        assert!(svg.contains("3.000 m, 0.0 dB") && svg.contains("detection"));
    }

    #[test]
    fn png_is_written_with_its_signature() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.png");
        draw(&path, &plot()).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn other_extensions_are_refused() {
        let dir = tempfile::tempdir().unwrap();
        let err = draw(&dir.path().join("p.jpg"), &plot()).unwrap_err();
        assert!(matches!(err, StorageError::UnsupportedFormat { .. }));
    }
}

/// A map over range and another axis (velocity), in dB.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Heatmap {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// Cell centres along x (range, m) and y (velocity, m/s), ascending and uniform.
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    /// `db[ix * y.len() + iy]`.
    pub db: Vec<f64>,
    /// x range shown.
    pub x_window: (f64, f64),
    /// Dynamic range shown under the maximum, dB.
    pub range_db: f64,
    /// Points marked (detections: x, y).
    pub marks: Vec<(f64, f64)>,
}

/// Most cells drawn per axis: finer maps are reduced (maximum of each block) first.
const HEATMAP_CELLS: (usize, usize) = (480, 240);

/// A perceptually even blue-green-yellow scale (viridis' endpoints and midpoints).
pub(crate) fn heat_colour(f: f64) -> RGBColor {
    const STOPS: [(f64, (f64, f64, f64)); 5] = [
        (0.0, (68.0, 1.0, 84.0)),
        (0.25, (59.0, 82.0, 139.0)),
        (0.5, (33.0, 145.0, 140.0)),
        (0.75, (94.0, 201.0, 98.0)),
        (1.0, (253.0, 231.0, 37.0)),
    ];
    let f = f.clamp(0.0, 1.0);
    let k = STOPS.iter().position(|s| s.0 >= f).unwrap_or(4).max(1);
    let (a, b) = (STOPS[k - 1], STOPS[k]);
    let t = (f - a.0) / (b.0 - a.0);
    let mix = |x: f64, y: f64| (x + (y - x) * t).round() as u8;
    RGBColor(
        mix(a.1 .0, b.1 .0),
        mix(a.1 .1, b.1 .1),
        mix(a.1 .2, b.1 .2),
    )
}

/// Width of a heat map's colour bar (its scale and label included), pixels.
pub(crate) const COLOUR_BAR_PX: u32 = 110;

/// The colour scale of a heat map in `area` (a strip at the plot's right): `heat_colour` from
/// `lo` (0) to `hi` (1) in `label`'s unit, with round ticks.
pub(crate) fn draw_colour_bar<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    (lo, hi): (f64, f64),
    label: &str,
    top_px: u32,
) -> Result<(), String> {
    let e = |err: DrawingAreaErrorKind<DB::ErrorType>| format!("{err}");
    let mut bar = ChartBuilder::on(area)
        .margin_top(top_px)
        .margin_bottom(12)
        .margin_right(8)
        .y_label_area_size(0)
        .right_y_label_area_size(70)
        .x_label_area_size(45)
        .build_cartesian_2d(0.0..1.0, lo..hi)
        .map_err(e)?;
    bar.configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_label_formatter(&|v: &f64| format!("{}", (v * 1e6).round() / 1e6 + 0.0))
        .y_desc(label)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    const STEPS: usize = 64;
    let d = (hi - lo) / STEPS as f64;
    bar.draw_series((0..STEPS).map(|k| {
        let y = lo + k as f64 * d;
        Rectangle::new(
            [(0.0, y), (1.0, y + d)],
            heat_colour((k as f64 + 0.5) / STEPS as f64).filled(),
        )
    }))
    .map_err(e)?;
    Ok(())
}

/// Draws `map` as a PNG heat map (colour = dB under the maximum, its scale beside), atomically.
pub(crate) fn draw_heatmap(path: &Path, map: &Heatmap) -> Result<(), StorageError> {
    let bad = |reason: &str| StorageError::BadData {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    };
    let (nx, ny) = (map.x.len(), map.y.len());
    if nx < 2 || ny < 2 || map.db.len() != nx * ny {
        return Err(bad(
            "a heat map needs at least 2 x 2 cells and one value per cell",
        ));
    }
    if extension(path).as_deref() != Some("png") {
        return Err(StorageError::UnsupportedFormat {
            path: path.to_path_buf(),
            allowed: "heat maps are written as .png",
        });
    }
    register_font_once();
    let (x0, x1) = map.x_window;
    let cols: Vec<usize> = (0..nx)
        .filter(|&i| map.x[i] >= x0 && map.x[i] <= x1)
        .collect();
    if cols.len() < 2 {
        return Err(bad("the x window holds fewer than 2 cells"));
    }
    // Reduce to at most HEATMAP_CELLS, keeping each block's maximum (peaks stay visible).
    let bx = cols.len().div_ceil(HEATMAP_CELLS.0);
    let by = ny.div_ceil(HEATMAP_CELLS.1);
    let max = cols
        .iter()
        .flat_map(|&i| map.db[i * ny..(i + 1) * ny].iter())
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    let dx = map.x[1] - map.x[0];
    let dy = map.y[1] - map.y[0];
    let png = render_png(|root| -> Result<(), String> {
        let e = |err: DrawingAreaErrorKind<_>| format!("{err}");
        root.fill(&WHITE).map_err(e)?;
        let y0 = map.y[0] - dy / 2.0;
        let y1 = map.y[ny - 1] + dy / 2.0;
        let (plot, scale) = root.split_horizontally(SIZE.0 - COLOUR_BAR_PX);
        draw_colour_bar(&scale, (-map.range_db, 0.0), "dB under the peak", 44)?;
        let mut chart = ChartBuilder::on(&plot)
            .caption(&map.title, ("sans-serif", 20))
            .margin(12)
            .x_label_area_size(45)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, y0..y1)
            .map_err(e)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_desc(map.x_label.as_str())
            .y_desc(map.y_label.as_str())
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        let mut cells = Vec::new();
        for block in cols.chunks(bx) {
            let xa = map.x[block[0]] - dx / 2.0;
            let xb = map.x[*block.last().expect("non-empty")] + dx / 2.0;
            for iy in (0..ny).step_by(by) {
                let top = (iy + by).min(ny);
                let v = block
                    .iter()
                    .flat_map(|&i| map.db[i * ny + iy..i * ny + top].iter())
                    .copied()
                    .fold(f64::NEG_INFINITY, f64::max);
                let f = 1.0 - (max - v) / map.range_db;
                let ya = map.y[iy] - dy / 2.0;
                let yb = map.y[top - 1] + dy / 2.0;
                cells.push(Rectangle::new(
                    [(xa, ya), (xb, yb)],
                    heat_colour(f).filled(),
                ));
            }
        }
        chart.draw_series(cells).map_err(e)?;
        let mark = RGBColor(230, 30, 30);
        chart
            .draw_series(
                map.marks
                    .iter()
                    .filter(|(x, _)| (x0..=x1).contains(x))
                    .map(|&(x, y)| Circle::new((x, y), 7, mark.stroke_width(2))),
            )
            .map_err(e)?;
        root.present().map_err(e)?;
        Ok(())
    })
    .map_err(|reason| plot_error(path, reason))?;
    write_atomic(path, &png)
}

/// One waveform's measured bit-error rates and its theory.
#[derive(Debug, Clone, PartialEq)]
pub struct BerSeries {
    pub label: String,
    pub eb_n0_db: Vec<f64>,
    pub ber: Vec<f64>,
    /// 95 % confidence interval of each measured point.
    pub ci: Vec<(f64, f64)>,
    pub theory: Vec<f64>,
}

/// BER against Eb/N0 on a log scale, measured points with their 95 % intervals, theory dashed.
pub fn draw_ber(path: &Path, title: &str, series: &[BerSeries]) -> Result<(), StorageError> {
    let all = series.iter().flat_map(|s| s.ber.iter().chain(&s.theory));
    let lowest = all
        .copied()
        .filter(|b| *b > 0.0)
        .fold(1.0_f64, f64::min)
        .max(1e-12);
    let y0 = 10f64.powf(lowest.log10().floor());
    let (x0, x1) = series
        .iter()
        .flat_map(|s| s.eb_n0_db.iter())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        });
    if !(x0.is_finite() && x1 > x0) {
        return Err(StorageError::BadData {
            path: path.to_path_buf(),
            reason: "nothing to plot: give at least two Eb/N0 points".into(),
        });
    }
    write_figure(
        path,
        &BerFigure {
            title,
            series,
            x: (x0, x1),
            y0,
        },
    )
}

/// The BER plot's inputs, ready to render.
struct BerFigure<'a> {
    title: &'a str,
    series: &'a [BerSeries],
    x: (f64, f64),
    y0: f64,
}

impl Render for BerFigure<'_> {
    fn render<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        render_ber(root, self.title, self.series, self.x, self.y0)
    }
}

fn render_ber<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    title: &str,
    series: &[BerSeries],
    (x0, x1): (f64, f64),
    y0: f64,
) -> Result<(), String> {
    let e = |err: DrawingAreaErrorKind<_>| format!("{err}");
    root.fill(&WHITE).map_err(e)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(x0 - 0.5..x1 + 0.5, (y0..1.0).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("Eb/N0 (dB)")
        .y_desc("Bit-error rate")
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(e)?;
    for (i, s) in series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let theory: Vec<(f64, f64)> = s
            .eb_n0_db
            .iter()
            .zip(&s.theory)
            .filter(|(_, t)| **t > 0.0)
            .map(|(x, t)| (*x, t.max(y0)))
            .collect();
        chart
            .draw_series(DashedLineSeries::new(theory, 6, 4, color.stroke_width(1)))
            .map_err(e)?
            .label(format!("{} theory", s.label))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
        let measured: Vec<(f64, f64)> = s
            .eb_n0_db
            .iter()
            .zip(&s.ber)
            .filter(|(_, b)| **b > 0.0)
            .map(|(x, b)| (*x, *b))
            .collect();
        chart
            .draw_series(
                measured
                    .iter()
                    .map(|&(x, b)| Circle::new((x, b), 4, color.filled())),
            )
            .map_err(e)?
            .label(format!("{} measured (95 % interval)", s.label))
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
        chart
            .draw_series(s.eb_n0_db.iter().zip(&s.ci).filter(|(_, c)| c.1 > 0.0).map(
                |(x, (lo, hi))| PathElement::new(vec![(*x, lo.max(y0)), (*x, hi.max(y0))], color),
            ))
            .map_err(e)?;
    }
    draw_legend(&mut chart, SeriesLabelPosition::LowerLeft, 14)?;
    root.present().map_err(e)?;
    Ok(())
}
