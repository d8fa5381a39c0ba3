//! Line charts: named series of (x, y) points in data units, drawn in order; a point with a NaN
//! coordinate (or ≤ 0 on a log axis) breaks the line. Sparse series (≤ 40 points) get markers.

use super::axes::{XyContent, XyFigure, data_ranges};
use super::canvas::{
    DrawResult, Fonts, PlotFiles, PlotOptions, Swatch, legend, render, series_colour,
};
use crate::report::ReportError;
use plotters::coord::ranged1d::Ranged;
use plotters::prelude::*;
use std::path::Path;

/// A named line of (x, y) points, drawn in the given order; a point with a NaN coordinate breaks it.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

impl Series {
    pub fn new(name: impl Into<String>, points: Vec<(f64, f64)>) -> Series {
        Series {
            name: name.into(),
            points,
        }
    }
}

/// Line chart of `series` with a legend; writes `out.svg` and `out.png` (`out` is a path without
/// extension; its directory must exist).
pub fn line_chart(
    out: &Path,
    opts: &PlotOptions,
    series: &[Series],
) -> Result<PlotFiles, ReportError> {
    let pts = series.iter().flat_map(|s| s.points.iter().copied());
    let (xr, yr) = data_ranges(out, opts, pts)?;
    let fig = XyFigure {
        opts,
        xr,
        yr,
        legend: legend(series.iter().map(|s| s.name.as_str()), Swatch::Line),
        content: LineContent {
            series,
            log_x: opts.log_x,
            log_y: opts.log_y,
        },
    };
    render(out, opts, &fig)
}

struct LineContent<'a> {
    series: &'a [Series],
    log_x: bool,
    log_y: bool,
}

impl XyContent for LineContent<'_> {
    fn draw_content<DB: DrawingBackend, X, Y>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
        _fonts: &Fonts,
    ) -> DrawResult<DB>
    where
        X: Ranged<ValueType = f64>,
        Y: Ranged<ValueType = f64>,
    {
        let ok = |&(x, y): &(f64, f64)| {
            x.is_finite() && y.is_finite() && (!self.log_x || x > 0.0) && (!self.log_y || y > 0.0)
        };
        for (i, s) in self.series.iter().enumerate() {
            let colour = series_colour(i);
            let finite = s.points.iter().filter(|p| ok(p)).count();
            // Dense series (a value per frame) in 1-px strokes: the bitmap backend joins a 2-px stroke's
            // segments with miters, which at a one-frame spike reached 63 px past the axis (bytes per
            // frame below 0, a share above 1).
            let width = if finite <= 40 { 2 } else { 1 };
            for run in s.points.split(|p| !ok(p)).filter(|r| !r.is_empty()) {
                chart.draw_series(LineSeries::new(
                    run.iter().copied(),
                    colour.stroke_width(width),
                ))?;
            }
            // Markers make sparse series readable (and single points visible at all).
            if finite <= 40 {
                chart.draw_series(
                    s.points
                        .iter()
                        .filter(|p| ok(p))
                        .map(|&p| Circle::new(p, 3, colour.filled())),
                )?;
            }
        }
        Ok(())
    }
}
