//! The link's plot of one capture: the received data symbols over the ideal constellation on
//! the left, two panels on the right (OFDM: the channel estimate's magnitude and phase per
//! subcarrier; MSK-LFM: the phase trajectory of the dechirped signal against the ideal one).

use super::{write_figure, Render, StorageError, PALETTE};
use plotters::prelude::*;
use std::path::Path;

/// One line of a panel.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct PanelLine {
    pub label: String,
    pub points: Vec<(f64, f64)>,
    pub dashed: bool,
}

/// One panel on the right.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub lines: Vec<PanelLine>,
}

/// The whole link figure.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct LinkPlot {
    pub title: String,
    /// Received symbols (I, Q).
    pub symbols: Vec<(f64, f64)>,
    /// The ideal constellation points.
    pub ideal: Vec<(f64, f64)>,
    pub panels: Vec<Panel>,
}

/// Draws `plot` to `path` (`.svg` or `.png`), atomically.
pub(crate) fn draw_link(path: &Path, plot: &LinkPlot) -> Result<(), StorageError> {
    if plot.symbols.is_empty() {
        return Err(StorageError::BadData {
            path: path.to_path_buf(),
            reason: "nothing to plot: no symbols".into(),
        });
    }
    write_figure(path, plot)
}

impl Render for LinkPlot {
    fn render<DB: DrawingBackend>(
        &self,
        root: DrawingArea<DB, plotters::coord::Shift>,
    ) -> Result<(), String> {
        let e = |err: DrawingAreaErrorKind<_>| format!("{err}");
        root.fill(&WHITE).map_err(e)?;
        let root = root.titled(&self.title, ("sans-serif", 20)).map_err(e)?;
        let (w, _) = root.dim_in_pixel();
        let (left, right) = root.split_horizontally(w * 9 / 20);
        // The constellation, square, symmetric about 0.
        let reach = self
            .symbols
            .iter()
            .chain(&self.ideal)
            .map(|(i, q)| i.abs().max(q.abs()))
            .filter(|v| v.is_finite())
            .fold(0.0_f64, f64::max)
            .clamp(1e-9, 1e9)
            * 1.15;
        let mut chart = ChartBuilder::on(&left)
            .caption("Constellation (data symbols)", ("sans-serif", 15))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(-reach..reach, -reach..reach)
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("I")
            .y_desc("Q")
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(e)?;
        chart
            .draw_series(
                self.ideal
                    .iter()
                    .map(|&(i, q)| Cross::new((i, q), 9, PALETTE[1].stroke_width(2))),
            )
            .map_err(e)?;
        let dot = PALETTE[0].mix(0.45);
        let radius = if self.symbols.len() > 500 { 1 } else { 3 };
        chart
            .draw_series(
                self.symbols
                    .iter()
                    .filter(|(i, q)| i.is_finite() && q.is_finite())
                    .map(|&(i, q)| Circle::new((i, q), radius, dot.filled())),
            )
            .map_err(e)?;
        let areas = right.split_evenly((self.panels.len().max(1), 1));
        for (panel, area) in self.panels.iter().zip(areas) {
            let all = panel.lines.iter().flat_map(|l| l.points.iter());
            let (x0, x1, y0, y1) = all.filter(|(x, y)| x.is_finite() && y.is_finite()).fold(
                (
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                ),
                |(a, b, c, d), &(x, y)| (a.min(x), b.max(x), c.min(y), d.max(y)),
            );
            if !(x1 > x0 && y1.is_finite()) {
                continue;
            }
            let pad = ((y1 - y0) * 0.08).max(1e-3);
            let mut chart = ChartBuilder::on(&area)
                .caption(&panel.title, ("sans-serif", 14))
                .margin(8)
                .x_label_area_size(32)
                .y_label_area_size(55)
                .build_cartesian_2d(x0..x1, y0 - pad..y1 + pad)
                .map_err(e)?;
            chart
                .configure_mesh()
                .x_desc(panel.x_label.as_str())
                .y_desc(panel.y_label.as_str())
                .label_style(("sans-serif", 11))
                .draw()
                .map_err(e)?;
            for (k, line) in panel.lines.iter().enumerate() {
                let color = PALETTE[k % PALETTE.len()];
                let pts = line
                    .points
                    .iter()
                    .copied()
                    .filter(|(x, y)| x.is_finite() && y.is_finite());
                if line.dashed {
                    chart
                        .draw_series(DashedLineSeries::new(pts, 5, 4, color.stroke_width(1)))
                        .map_err(e)?
                        .label(line.label.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
                } else {
                    chart
                        .draw_series(LineSeries::new(pts, color.stroke_width(1)))
                        .map_err(e)?
                        .label(line.label.as_str())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], color));
                }
            }
            if panel.lines.len() > 1 {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 11))
                    .position(SeriesLabelPosition::UpperRight)
                    .draw()
                    .map_err(e)?;
            }
        }
        root.present().map_err(e)?;
        Ok(())
    }
}
