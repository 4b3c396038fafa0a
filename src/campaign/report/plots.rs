//! The report's charts as SVG text (inlined into `report.html`): points with error bars against a
//! numeric or categorical axis, reference lines (bounds, the thesis' values), a log scale for
//! bit-error rates. Drawn with plotters and the embedded font of `storage::plot`, like
//! every other plot of radbench.

use crate::storage::plot::{
    draw_colour_bar, draw_legend, heat_colour, register_font_once, render_png_sized, Axes,
    COLOUR_BAR_PX, PALETTE,
};
use plotters::prelude::*;

/// Size of every chart, pixels.
pub(crate) const SIZE: (u32, u32) = (800, 450);
/// Reference lines (bounds, the thesis' values), apart from the data's palette.
const REFERENCE: [RGBColor; 2] = [RGBColor(40, 40, 40), RGBColor(230, 140, 0)];
/// Vertical reference lines (resolution cells).
const VERTICAL: [RGBColor; 3] = [
    RGBColor(120, 120, 120),
    RGBColor(160, 60, 120),
    RGBColor(40, 130, 130),
];
/// Roughly the plotting area's height (the size less caption, margins and the x labels).
const PLOT_HEIGHT_PX: f64 = 350.0;

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    /// Markers joined by a solid line.
    Line,
    /// A dashed line without markers (theory).
    Dashed,
    /// Markers only.
    Markers,
    /// A thin solid line without markers (a range profile); an empty label adds no legend
    /// entry.
    Trace,
}

/// One point; `filled = false` draws a hollow marker (not resolved, no bit errors).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Point {
    pub x: f64,
    pub y: f64,
    /// Error bar (low, high) in y units.
    pub bar: Option<(f64, f64)>,
    pub filled: bool,
}

impl Point {
    pub fn new(x: f64, y: f64) -> Self {
        Self {
            x,
            y,
            bar: None,
            filled: true,
        }
    }

    /// With a symmetric bar of +-`std` (none when zero or absent).
    pub(crate) fn with_std(mut self, std: Option<f64>) -> Self {
        if let Some(s) = std.filter(|s| *s > 0.0) {
            self.bar = Some((self.y - s, self.y + s));
        }
        self
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub label: String,
    pub points: Vec<Point>,
    pub style: Style,
}

/// A horizontal reference line.
#[derive(Debug, Clone, PartialEq)]
pub struct HLine {
    pub y: f64,
    pub label: String,
    pub dashed: bool,
}

/// One chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    /// y on a log10 scale (all values > 0; non-positive ones are left out).
    pub log_y: bool,
    /// Categorical axes: point x (or y) k is category k.
    pub x_categories: Option<Vec<String>>,
    pub y_categories: Option<Vec<String>>,
    pub series: Vec<Series>,
    pub hlines: Vec<HLine>,
    /// Vertical reference lines (x, label), dotted; their x widens the axis to show them.
    pub vlines: Vec<(f64, String)>,
    /// A heat map under the series (its colour bar at the right).
    pub(crate) heat: Option<Heat>,
}

/// Rows of cells over x, each at its own y, coloured by a value from `-depth` (dark) to 0
/// (bright).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Heat {
    /// Cell centres along x, ascending and uniform (at least 2).
    pub x: Vec<f64>,
    /// (y, one value per x cell), ascending y, one unit apart at most.
    pub rows: Vec<(f64, Vec<f64>)>,
    pub depth: f64,
    /// The colour bar's label.
    pub label: String,
}

impl Heat {
    fn cell(&self) -> f64 {
        self.x[1] - self.x[0]
    }

    /// The half height of a row: half the smallest step between rows (0.5 for one row).
    fn half_row(&self) -> f64 {
        self.rows
            .windows(2)
            .map(|w| w[1].0 - w[0].0)
            .fold(1.0, f64::min)
            / 2.0
    }
}

impl Chart {
    pub fn new(title: impl Into<String>, x_label: &str, y_label: &str) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            log_y: false,
            x_categories: None,
            y_categories: None,
            series: Vec::new(),
            hlines: Vec::new(),
            vlines: Vec::new(),
            heat: None,
        }
    }
}

fn span(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    lo.is_finite().then_some((lo, hi))
}

fn pad((lo, hi): (f64, f64)) -> (f64, f64) {
    let d = hi - lo;
    if d <= 0.0 {
        let m = lo.abs().max(1.0) * 0.1;
        (lo - m, hi + m)
    } else {
        (lo - 0.08 * d, hi + 0.08 * d)
    }
}

/// The chart as an SVG document (`<svg ...>...</svg>`).
pub fn svg(chart: &Chart) -> Result<String, String> {
    let (x, y, ty) = extent(chart)?;
    register_font_once();
    let mut out = String::new();
    {
        let root = SVGBackend::with_string(&mut out, SIZE).into_drawing_area();
        render(root, chart, x, y, &ty).map_err(|e| format!("{}: {e}", chart.title))?;
    }
    Ok(out)
}

/// The chart as a PNG image (`report.md` embeds these; `report.html` a heat map).
pub(crate) fn png(chart: &Chart) -> Result<Vec<u8>, String> {
    let (x, y, ty) = extent(chart)?;
    register_font_once();
    render_png_sized(SIZE, |root| render(root, chart, x, y, &ty))
        .map_err(|e| format!("{}: {e}", chart.title))
}

type YTransform = Box<dyn Fn(f64) -> Option<f64>>;
/// The x and y ranges of a chart and its y transform.
type Extent = ((f64, f64), (f64, f64), YTransform);

/// The axes' ranges (the legend's room above the data included) and the y transform.
fn extent(chart: &Chart) -> Result<Extent, String> {
    if let Some(h) = chart
        .heat
        .as_ref()
        .filter(|h| h.x.len() >= 2 && !h.rows.is_empty())
    {
        let (dx, dy) = (h.cell() / 2.0, h.half_row());
        let x = (h.x[0] - dx, h.x[h.x.len() - 1] + dx);
        let y = (h.rows[0].0 - dy, h.rows[h.rows.len() - 1].0 + dy);
        return Ok((x, y, Box::new(Some)));
    }
    let log_y = chart.log_y;
    let ty = move |y: f64| -> Option<f64> {
        if log_y {
            (y > 0.0).then(|| y.log10())
        } else {
            Some(y)
        }
    };
    let xs = chart
        .series
        .iter()
        .flat_map(|s| s.points.iter().map(|p| p.x))
        .chain(chart.vlines.iter().map(|v| v.0));
    let x = match &chart.x_categories {
        Some(c) => (-0.5, c.len() as f64 - 0.5),
        None => pad(span(xs).ok_or("nothing to plot: no points")?),
    };
    let ys = chart.series.iter().flat_map(|s| {
        s.points.iter().flat_map(|p| {
            [Some(p.y), p.bar.map(|b| b.0), p.bar.map(|b| b.1)]
                .into_iter()
                .flatten()
        })
    });
    let ys = ys
        .chain(chart.hlines.iter().map(|h| h.y))
        .filter_map(ty)
        .collect::<Vec<f64>>();
    let y = match &chart.y_categories {
        Some(c) => (-0.5, c.len() as f64 - 0.5),
        None if chart.log_y => {
            let (lo, hi) = span(ys.into_iter()).ok_or("nothing to plot: no positive value")?;
            (lo.floor(), hi.ceil().max(lo.floor() + 1.0))
        }
        None => pad(span(ys.into_iter()).ok_or("nothing to plot: no points")?),
    };
    // Room above the data for the legend (upper right), so it hides no point.
    let entries = chart.series.iter().filter(|s| !s.label.is_empty()).count()
        + chart.vlines.len()
        + chart.hlines.iter().filter(|h| !h.label.is_empty()).count();
    let legend = (entries as f64 * 18.0 + 20.0) / PLOT_HEIGHT_PX;
    let y = (y.0, y.1 + (y.1 - y.0) * legend / (1.0 - legend).max(0.2));
    Ok((x, y, Box::new(ty)))
}

/// A tick label: six decimals at most, no "-0".
fn number(v: f64) -> String {
    let r = (v * 1e6).round() / 1e6;
    if r == 0.0 {
        "0".into()
    } else {
        format!("{r}")
    }
}

fn category(c: &[String], v: f64) -> String {
    let k = v.round();
    if (v - k).abs() > 1e-6 || k < 0.0 {
        return String::new();
    }
    c.get(k as usize).cloned().unwrap_or_default()
}

fn render<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    chart: &Chart,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    ty: &dyn Fn(f64) -> Option<f64>,
) -> Result<(), String> {
    let e = |err: DrawingAreaErrorKind<_>| format!("{err}");
    root.fill(&WHITE).map_err(e)?;
    let y_area = if chart.y_categories.is_some() {
        170
    } else {
        70
    };
    let area = match &chart.heat {
        Some(h) => {
            let (plot, scale) = root.split_horizontally(SIZE.0 - COLOUR_BAR_PX);
            draw_colour_bar(&scale, (-h.depth, 0.0), &h.label, 42)?;
            plot
        }
        None => root.clone(),
    };
    let mut c = ChartBuilder::on(&area)
        .caption(&chart.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(50)
        .y_label_area_size(y_area)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(e)?;
    let x_fmt = |v: &f64| match &chart.x_categories {
        Some(c) => category(c, *v),
        None => number(*v),
    };
    let y_fmt = |v: &f64| match &chart.y_categories {
        Some(c) => category(c, *v),
        None if chart.log_y => {
            if (v - v.round()).abs() < 1e-6 {
                format!("1e{}", v.round())
            } else {
                String::new()
            }
        }
        None => number(*v),
    };
    let mut mesh = c.configure_mesh();
    mesh.x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .label_style(("sans-serif", 13));
    if let Some(cat) = &chart.x_categories {
        mesh.x_labels(cat.len() * 2 + 1);
    }
    if let Some(cat) = &chart.y_categories {
        mesh.y_labels(cat.len() * 2 + 1);
    }
    if chart.log_y {
        mesh.y_labels(((y1 - y0) as usize + 1).max(2));
    }
    if chart.heat.is_some() {
        mesh.disable_mesh();
    }
    mesh.draw().map_err(e)?;
    if let Some(h) = &chart.heat {
        draw_heat(&mut c, h)?;
    }
    draw_reference_lines(&mut c, chart, (x0, x1), (y0, y1), ty)?;
    draw_series(&mut c, chart, y0, ty)?;
    draw_legend(&mut c, SeriesLabelPosition::UpperRight, 13)?;
    root.present().map_err(e)?;
    Ok(())
}

/// The heat map's cells, one rectangle each.
fn draw_heat<DB: DrawingBackend>(c: &mut Axes<'_, DB>, h: &Heat) -> Result<(), String> {
    let (dx, dy) = (h.cell() / 2.0, h.half_row());
    let cells = h.rows.iter().flat_map(|(y, values)| {
        h.x.iter().zip(values).map(move |(x, v)| {
            Rectangle::new(
                [(x - dx, y - dy), (x + dx, y + dy)],
                heat_colour(1.0 + v / h.depth).filled(),
            )
        })
    });
    c.draw_series(cells).map_err(drawing_error)?;
    Ok(())
}

fn drawing_error<E: std::error::Error + Send + Sync>(err: DrawingAreaErrorKind<E>) -> String {
    format!("{err}")
}

/// Horizontal bounds (solid or dashed, one legend entry per bound) and vertical markers.
fn draw_reference_lines<DB: DrawingBackend>(
    c: &mut Axes<'_, DB>,
    chart: &Chart,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
    ty: &dyn Fn(f64) -> Option<f64>,
) -> Result<(), String> {
    let e = drawing_error;
    let mut reference = 0;
    for (i, h) in chart.hlines.iter().enumerate() {
        let Some(y) = ty(h.y) else { continue };
        // An unlabelled line repeats the previous labelled one (the other side of a bound).
        if !h.label.is_empty() || i == 0 {
            reference += 1;
        }
        let color = REFERENCE[(reference - 1) % REFERENCE.len()];
        let line = vec![(x0, y), (x1, y)];
        let style = color.stroke_width(2);
        let drawn = if h.dashed {
            c.draw_series(DashedLineSeries::new(line, 6, 4, style))
                .map_err(e)?
        } else {
            c.draw_series(LineSeries::new(line, style)).map_err(e)?
        };
        // An empty label: the same bound drawn again (its negative side), one legend entry.
        if !h.label.is_empty() {
            drawn
                .label(h.label.as_str())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
        }
    }
    for (k, (x, label)) in chart.vlines.iter().enumerate() {
        let color = VERTICAL[k % VERTICAL.len()];
        let style = color.stroke_width(2);
        c.draw_series(DashedLineSeries::new(vec![(*x, y0), (*x, y1)], 2, 4, style))
            .map_err(e)?
            .label(label.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
    }
    Ok(())
}

/// Each series: markers (filled or open) with error bars, a line or a dashed line.
fn draw_series<DB: DrawingBackend>(
    c: &mut Axes<'_, DB>,
    chart: &Chart,
    y0: f64,
    ty: &dyn Fn(f64) -> Option<f64>,
) -> Result<(), String> {
    let e = drawing_error;
    for (i, s) in chart.series.iter().enumerate() {
        let color = PALETTE[i % PALETTE.len()];
        let pts: Vec<(f64, f64, Point)> = s
            .points
            .iter()
            .filter_map(|p| ty(p.y).map(|y| (p.x, y, *p)))
            .collect();
        let line: Vec<(f64, f64)> = pts.iter().map(|(x, y, _)| (*x, *y)).collect();
        match s.style {
            Style::Dashed => {
                c.draw_series(DashedLineSeries::new(line, 8, 5, color.stroke_width(2)))
                    .map_err(e)?
                    .label(s.label.as_str())
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
                continue;
            }
            Style::Line => {
                c.draw_series(LineSeries::new(line, color.stroke_width(1)))
                    .map_err(e)?;
            }
            Style::Trace => {
                let drawn = c
                    .draw_series(LineSeries::new(line, color.stroke_width(1)))
                    .map_err(e)?;
                if !s.label.is_empty() {
                    drawn.label(s.label.as_str()).legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                    });
                }
                continue;
            }
            Style::Markers => {}
        }
        c.draw_series(pts.iter().map(|(x, y, p)| {
            let style = if p.filled {
                color.filled()
            } else {
                color.stroke_width(2)
            };
            Circle::new((*x, *y), 5, style)
        }))
        .map_err(e)?
        .label(s.label.as_str())
        .legend(move |(x, y)| Circle::new((x + 10, y), 5, color.filled()));
        c.draw_series(pts.iter().filter_map(|(x, _, p)| {
            let (lo, hi) = p.bar?;
            let (lo, hi) = (ty(lo).unwrap_or(y0), ty(hi)?);
            Some(PathElement::new(
                vec![(*x, lo), (*x, hi)],
                color.stroke_width(2),
            ))
        }))
        .map_err(e)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chart_is_one_svg_element_and_an_empty_one_is_refused() {
        let mut c = Chart::new("t", "x", "y");
        assert!(svg(&c).is_err());
        c.series.push(Series {
            label: "s".into(),
            points: vec![
                Point::new(1.0, 2.0).with_std(Some(0.5)),
                Point::new(2.0, 3.0),
            ],
            style: Style::Line,
        });
        c.hlines.push(HLine {
            y: 2.5,
            label: "bound".into(),
            dashed: true,
        });
        let s = svg(&c).unwrap();
        assert!(s.trim_start().starts_with("<svg"), "{}", &s[..40]);
        assert!(s.trim_end().ends_with("</svg>"));
        assert!(s.contains("bound") && s.contains("<circle"));
        // Log scale: non-positive values are left out, the rest drawn.
        c.log_y = true;
        c.series[0].points.push(Point::new(3.0, 0.0));
        assert!(svg(&c).is_ok());
    }

    #[test]
    fn a_heat_map_draws_its_cells_and_its_colour_bar() {
        let mut c = Chart::new("t", "range (m)", "step");
        c.heat = Some(Heat {
            x: vec![1.0, 1.1, 1.2],
            rows: vec![
                (1.0, vec![0.0, -20.0, -40.0]),
                (2.0, vec![-40.0, 0.0, -3.0]),
            ],
            depth: 40.0,
            label: "dB under the peak".into(),
        });
        let s = svg(&c).unwrap();
        // 6 cells and the colour bar's 64 bands.
        assert!(s.matches("<rect").count() >= 6 + 64, "{s}");
        assert!(s.contains("dB under the peak"));
        assert!(png(&c).unwrap().starts_with(b"\x89PNG"));
    }
}
