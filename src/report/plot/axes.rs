//! Axes: tick labels, value ranges, and the x–y chart (linear or log₂ axes) that lines and scatter
//! plots draw into.
//!
//! Ranges are in data units: a fixed range from [`PlotOptions`] is used as given (widened if empty),
//! else the finite data (on a log axis: the positive data) padded by 4 % (log: a factor 2^0.1 each
//! side). Log axes have base 2 and ticks at powers of two.

use super::canvas::{
    DrawResult, Figure, Fonts, LegendEntry, PlotOptions, input_err, titled, with_legend,
};
use crate::report::ReportError;
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;

/// A tick label: up to 4 decimals without trailing zeros; `1e6`-style from 10⁶ and below 10⁻³. A tick
/// within 10⁻¹² of 0 is the tick arithmetic's rounding of 0 and reads "0" (a one-frame plot labelled its
/// middle tick `-5.55e-17`; fault hunt, session 32).
pub fn format_tick(v: f64) -> String {
    let v = if v.abs() < 1e-12 { 0.0 } else { v };
    if v == 0.0 || !v.is_finite() {
        return if v.is_nan() {
            "nan".into()
        } else if v == 0.0 {
            "0".into()
        } else {
            format!("{v}")
        };
    }
    let a = v.abs();
    if !(1e-3..1e6).contains(&a) {
        let s = format!("{v:.2e}");
        let (m, e) = s.split_once('e').unwrap_or((&s, "0"));
        return format!("{}e{e}", trim_zeros(m));
    }
    trim_zeros(&format!("{v:.4}")).to_string()
}

fn trim_zeros(s: &str) -> &str {
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.')
    } else {
        s
    }
}

pub(super) fn min_max(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// A non-empty range: equal ends are spread by ±max(|v|·0.1, 0.5), reversed ends swapped.
pub(super) fn widen((lo, hi): (f64, f64)) -> (f64, f64) {
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (hi, lo) };
    if hi > lo {
        (lo, hi)
    } else {
        let d = (lo.abs() * 0.1).max(0.5);
        (lo - d, hi + d)
    }
}

/// Pads a positive range by a factor 2^0.1 on each side (a single value gets one octave each side).
pub(super) fn log_pad(lo: f64, hi: f64) -> (f64, f64) {
    if hi > lo {
        let f = 2f64.powf(0.1);
        (lo / f, hi * f)
    } else {
        (lo / 2.0, hi * 2.0)
    }
}

/// The x and y ranges of a line or scatter plot: the options' fixed ranges, else the finite data (on a
/// log axis: the positive data) padded by 4 % (log: 2^0.1).
pub(super) fn data_ranges(
    out: &Path,
    opts: &PlotOptions,
    pts: impl Iterator<Item = (f64, f64)>,
) -> Result<(Range<f64>, Range<f64>), ReportError> {
    let pts: Vec<(f64, f64)> = pts
        .filter(|(x, y)| {
            x.is_finite() && y.is_finite() && (!opts.log_x || *x > 0.0) && (!opts.log_y || *y > 0.0)
        })
        .collect();
    let axis = |fixed: Option<(f64, f64)>, log: bool, vals: &mut dyn Iterator<Item = f64>| {
        if let Some((lo, hi)) = fixed {
            if log && (lo <= 0.0 || hi <= 0.0) {
                return Err(input_err(
                    out,
                    format!("log axis range {lo}..{hi} is not positive"),
                ));
            }
            let (lo, hi) = widen((lo, hi));
            return Ok(lo..hi);
        }
        let (lo, hi) =
            min_max(vals).ok_or_else(|| input_err(out, "no finite point to plot".to_string()))?;
        let (lo, hi) = if log {
            log_pad(lo, hi)
        } else {
            let (lo, hi) = widen((lo, hi));
            let pad = 0.04 * (hi - lo);
            (lo - pad, hi + pad)
        };
        Ok(lo..hi)
    };
    let xr = axis(opts.x_range, opts.log_x, &mut pts.iter().map(|p| p.0))?;
    let yr = axis(opts.y_range, opts.log_y, &mut pts.iter().map(|p| p.1))?;
    Ok((xr, yr))
}

/// What is drawn inside an x–y chart, for any coordinate type of f64 axes.
pub(super) trait XyContent {
    fn draw_content<DB: DrawingBackend, X, Y>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
        fonts: &Fonts,
    ) -> DrawResult<DB>
    where
        X: Ranged<ValueType = f64>,
        Y: Ranged<ValueType = f64>;
}

pub(super) struct XyFigure<'a, C> {
    pub(super) opts: &'a PlotOptions,
    pub(super) xr: Range<f64>,
    pub(super) yr: Range<f64>,
    pub(super) legend: Vec<LegendEntry>,
    pub(super) content: C,
}

impl<C: XyContent> Figure for XyFigure<'_, C> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let fonts = Fonts::new(self.opts);
        let area = titled(root, self.opts, &fonts)?;
        let area = with_legend(&area, &self.legend, &fonts)?;
        let (xr, yr) = (self.xr.clone(), self.yr.clone());
        match (self.opts.log_x, self.opts.log_y) {
            (false, false) => self.chart(&area, &fonts, xr, yr),
            (true, false) => self.chart(&area, &fonts, xr.log_scale().base(2.0), yr),
            (false, true) => self.chart(&area, &fonts, xr, yr.log_scale().base(2.0)),
            (true, true) => self.chart(
                &area,
                &fonts,
                xr.log_scale().base(2.0),
                yr.log_scale().base(2.0),
            ),
        }
    }
}

impl<C: XyContent> XyFigure<'_, C> {
    fn chart<DB: DrawingBackend, XS, YS>(
        &self,
        area: &DrawingArea<DB, Shift>,
        fonts: &Fonts,
        xs: XS,
        ys: YS,
    ) -> DrawResult<DB>
    where
        XS: AsRangedCoord<Value = f64>,
        YS: AsRangedCoord<Value = f64>,
        XS::CoordDescType: ValueFormatter<f64>,
        YS::CoordDescType: ValueFormatter<f64>,
    {
        let mut chart = ChartBuilder::on(area)
            .margin(fonts.px(14.0) as u32)
            .x_label_area_size(fonts.px(50.0) as u32)
            .y_label_area_size(fonts.px(72.0) as u32)
            .build_cartesian_2d(xs, ys)?;
        chart
            .configure_mesh()
            .x_desc(self.opts.x_label.as_str())
            .y_desc(self.opts.y_label.as_str())
            .x_label_formatter(&|v| format_tick(*v))
            .y_label_formatter(&|v| format_tick(*v))
            .label_style(fonts.tick())
            .axis_desc_style(fonts.axis())
            .bold_line_style(BLACK.mix(0.12))
            .light_line_style(BLACK.mix(0.04))
            .max_light_lines(4)
            .x_labels(10)
            .y_labels(8)
            .draw()?;
        self.content.draw_content(&mut chart, fonts)
    }
}
