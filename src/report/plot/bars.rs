//! Bar charts: for each category (x, left to right) one bar per series, side by side, on a linear
//! (from 0) or log₂ y axis; and [`histogram_chart`], the bars of histograms with the same edges.

use super::axes::{format_tick, log_pad, min_max, widen};
use super::canvas::{
    DrawResult, Figure, Fonts, PlotFiles, PlotOptions, Swatch, input_err, legend, render,
    series_colour, titled, with_legend,
};
use crate::report::ReportError;
use crate::report::metrics::Histogram;
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;
use std::path::Path;

/// A named series of bar heights, one per category.
#[derive(Clone, Debug, PartialEq)]
pub struct BarSeries {
    pub name: String,
    pub values: Vec<f64>,
}

/// Grouped bar chart: for each category (x, left to right) one bar per series, side by side. Bars with
/// a NaN height are left out.
pub fn bar_chart(
    out: &Path,
    opts: &PlotOptions,
    categories: &[String],
    series: &[BarSeries],
) -> Result<PlotFiles, ReportError> {
    if categories.is_empty() || series.is_empty() {
        return Err(input_err(
            out,
            "bar chart without categories or series".into(),
        ));
    }
    if let Some(s) = series.iter().find(|s| s.values.len() != categories.len()) {
        return Err(input_err(
            out,
            format!(
                "series {:?} has {} values for {} categories",
                s.name,
                s.values.len(),
                categories.len()
            ),
        ));
    }
    let heights = series.iter().flat_map(|s| s.values.iter().copied());
    let yr = match opts.y_range {
        Some(r) => widen(r),
        None if opts.log_y => {
            let (lo, hi) = min_max(heights.filter(|v| *v > 0.0))
                .ok_or_else(|| input_err(out, "no positive bar on a log axis".into()))?;
            log_pad(lo, hi)
        }
        None => {
            let (lo, hi) = min_max(heights).unwrap_or((0.0, 1.0));
            let (lo, hi) = (lo.min(0.0), hi.max(0.0));
            widen((lo, hi + 0.04 * (hi - lo)))
        }
    };
    let fig = BarFigure {
        opts,
        categories,
        series,
        yr: yr.0..yr.1,
    };
    render(out, opts, &fig)
}

/// Bars of several [`Histogram`]s with the same edges (fractions of each histogram's drawn pixels,
/// labelled by the lower bin edge; `<` and `≥` bars for the values outside the edges). A typical
/// `opts.y_label` is "share of drawn pixels".
pub fn histogram_chart(
    out: &Path,
    opts: &PlotOptions,
    histograms: &[(String, &Histogram)],
) -> Result<PlotFiles, ReportError> {
    let Some((_, first)) = histograms.first() else {
        return Err(input_err(out, "no histogram".into()));
    };
    if let Some((name, _)) = histograms.iter().find(|(_, h)| h.edges != first.edges) {
        return Err(input_err(
            out,
            format!("histogram {name:?} has other bin edges than the first"),
        ));
    }
    let (categories, _) = first.bars();
    let series: Vec<BarSeries> = histograms
        .iter()
        .map(|(name, h)| BarSeries {
            name: name.clone(),
            values: h.bars().1,
        })
        .collect();
    bar_chart(out, opts, &categories, &series)
}

struct BarFigure<'a> {
    opts: &'a PlotOptions,
    categories: &'a [String],
    series: &'a [BarSeries],
    yr: Range<f64>,
}

impl Figure for BarFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let fonts = Fonts::new(self.opts);
        let area = titled(root, self.opts, &fonts)?;
        let entries = legend(self.series.iter().map(|s| s.name.as_str()), Swatch::Box);
        let area = with_legend(&area, &entries, &fonts)?;
        let yr = self.yr.clone();
        if self.opts.log_y {
            self.chart(root, &area, &fonts, yr.log_scale().base(2.0))
        } else {
            self.chart(root, &area, &fonts, yr)
        }
    }
}

impl BarFigure<'_> {
    /// `root` is the whole picture (absolute pixel coordinates, for the category labels).
    fn chart<DB: DrawingBackend, YS>(
        &self,
        root: &DrawingArea<DB, Shift>,
        area: &DrawingArea<DB, Shift>,
        fonts: &Fonts,
        ys: YS,
    ) -> DrawResult<DB>
    where
        YS: AsRangedCoord<Value = f64>,
        YS::CoordDescType: ValueFormatter<f64>,
    {
        let n = self.categories.len();
        let mut chart = ChartBuilder::on(area)
            .margin(fonts.px(14.0) as u32)
            .x_label_area_size(fonts.px(50.0) as u32)
            .y_label_area_size(fonts.px(72.0) as u32)
            .build_cartesian_2d(0f64..n as f64, ys)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .x_labels(0)
            .x_desc(self.opts.x_label.as_str())
            .y_desc(self.opts.y_label.as_str())
            .y_label_formatter(&|v| format_tick(*v))
            .label_style(fonts.tick())
            .axis_desc_style(fonts.axis())
            .bold_line_style(BLACK.mix(0.12))
            .light_line_style(BLACK.mix(0.04))
            .max_light_lines(4)
            .draw()?;
        let base = chart.y_range().start.max(if self.opts.log_y {
            f64::MIN_POSITIVE
        } else {
            0.0
        });
        let k = self.series.len() as f64;
        let (pad, gap) = (0.12, 0.02);
        let bw = (1.0 - 2.0 * pad) / k;
        for (s, series) in self.series.iter().enumerate() {
            let colour = series_colour(s);
            chart.draw_series(
                series
                    .values
                    .iter()
                    .enumerate()
                    .filter(|(_, v)| v.is_finite() && (!self.opts.log_y || **v > 0.0))
                    .map(|(c, &v)| {
                        let x0 = c as f64 + pad + s as f64 * bw;
                        Rectangle::new(
                            [(x0 + gap / 2.0, base), (x0 + bw - gap / 2.0, v)],
                            colour.filled(),
                        )
                    }),
            )?;
        }
        // Category labels under the axis, centred on each group.
        let y_min = chart.y_range().start;
        let style = fonts.tick().pos(Pos::new(HPos::Center, VPos::Top));
        for (c, label) in self.categories.iter().enumerate() {
            let (x, y) = chart.backend_coord(&(c as f64 + 0.5, y_min));
            root.draw(&Text::new(
                label.clone(),
                (x, y + fonts.px(8.0) as i32),
                style.clone(),
            ))?;
        }
        Ok(())
    }
}
