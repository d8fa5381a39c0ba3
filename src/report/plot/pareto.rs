//! Scatter plots with the Pareto front marked: named groups of labelled (cost, measure) points; lower x
//! (the cost) is always better, higher or lower y as [`Better`] says. The front is computed over all
//! visible points ([`crate::report::metrics::pareto_front`]), drawn as a black line with rings, and
//! returned as (group, point) indices in ascending x.

use super::axes::{XyContent, XyFigure, data_ranges};
use super::canvas::{
    DrawResult, Fonts, PlotFiles, PlotOptions, Swatch, legend, render, series_colour,
};
use crate::report::ReportError;
use crate::report::metrics::pareto_front;
use plotters::coord::ranged1d::Ranged;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// A labelled point of a scatter plot.
#[derive(Clone, Debug, PartialEq)]
pub struct LabelledPoint {
    pub x: f64,
    pub y: f64,
    pub label: String,
}

/// A named group of points of a scatter plot (one colour).
#[derive(Clone, Debug, PartialEq)]
pub struct ScatterSeries {
    pub name: String,
    pub points: Vec<LabelledPoint>,
}

/// Which y is better on a Pareto plot (lower x is always better: x is the cost).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Better {
    /// Accuracy measures such as PSNR, SSIM.
    HigherY,
    /// Error measures such as the coarser screen share.
    LowerY,
}

/// Which points of a scatter plot get their label written beside them.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum PointLabels {
    All,
    /// Only the points on the Pareto front.
    Front,
    None,
}

/// Scatter plot of labelled points, one colour per group, with the Pareto front over all points marked
/// (black line and rings): lower x (the cost) is better, and higher or lower y as `better` says.
/// Returns the files and the front as (group, point) indices in ascending x.
pub fn scatter_pareto(
    out: &Path,
    opts: &PlotOptions,
    groups: &[ScatterSeries],
    better: Better,
    labels: PointLabels,
) -> Result<(PlotFiles, Vec<(usize, usize)>), ReportError> {
    let flat: Vec<(usize, usize)> = groups
        .iter()
        .enumerate()
        .flat_map(|(g, s)| (0..s.points.len()).map(move |p| (g, p)))
        .collect();
    let visible = |p: &LabelledPoint| {
        p.x.is_finite()
            && p.y.is_finite()
            && (!opts.log_x || p.x > 0.0)
            && (!opts.log_y || p.y > 0.0)
    };
    let costs: Vec<(f64, f64)> = flat
        .iter()
        .map(|&(g, p)| {
            let pt = &groups[g].points[p];
            if !visible(pt) {
                (f64::NAN, f64::NAN)
            } else if better == Better::HigherY {
                (pt.x, pt.y)
            } else {
                (pt.x, -pt.y)
            }
        })
        .collect();
    let front: Vec<(usize, usize)> = pareto_front(&costs).into_iter().map(|i| flat[i]).collect();
    let pts = groups
        .iter()
        .flat_map(|s| s.points.iter().map(|p| (p.x, p.y)));
    let (xr, yr) = data_ranges(out, opts, pts)?;
    let fig = XyFigure {
        opts,
        xr,
        yr,
        legend: legend(groups.iter().map(|s| s.name.as_str()), Swatch::Dot)
            .into_iter()
            .chain([("Pareto front".to_string(), BLACK, Swatch::Ring)])
            .collect(),
        content: ScatterContent {
            groups,
            front: &front,
            labels,
            better,
            visible: &visible,
        },
    };
    Ok((render(out, opts, &fig)?, front))
}

struct ScatterContent<'a, V> {
    groups: &'a [ScatterSeries],
    front: &'a [(usize, usize)],
    labels: PointLabels,
    better: Better,
    visible: &'a V,
}

impl<V: Fn(&LabelledPoint) -> bool> XyContent for ScatterContent<'_, V> {
    fn draw_content<DB: DrawingBackend, X, Y>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
        fonts: &Fonts,
    ) -> DrawResult<DB>
    where
        X: Ranged<ValueType = f64>,
        Y: Ranged<ValueType = f64>,
    {
        let at = |&(g, p): &(usize, usize)| {
            let pt = &self.groups[g].points[p];
            (pt.x, pt.y)
        };
        chart.draw_series(LineSeries::new(
            self.front.iter().map(at),
            BLACK.mix(0.7).stroke_width(2),
        ))?;
        for (g, s) in self.groups.iter().enumerate() {
            let colour = series_colour(g);
            chart.draw_series(
                s.points
                    .iter()
                    .filter(|p| (self.visible)(p))
                    .map(|p| Circle::new((p.x, p.y), 5, colour.filled())),
            )?;
        }
        chart.draw_series(
            self.front
                .iter()
                .map(|gp| Circle::new(at(gp), 9, BLACK.stroke_width(2))),
        )?;
        // Labels on the side away from the front line: it rises to the right when higher y is
        // better (labels below-right), falls otherwise (labels above-right).
        let dx = fonts.px(9.0) as i32;
        let (dy, v_pos) = match self.better {
            Better::HigherY => (dx / 2, VPos::Top),
            Better::LowerY => (-dx / 2, VPos::Bottom),
        };
        let style = fonts.small().pos(Pos::new(HPos::Left, v_pos));
        for (g, s) in self.groups.iter().enumerate() {
            for (p, pt) in s.points.iter().enumerate() {
                let on_front = self.front.contains(&(g, p));
                let show = match self.labels {
                    PointLabels::All => true,
                    PointLabels::Front => on_front,
                    PointLabels::None => false,
                };
                if show && !pt.label.is_empty() && (self.visible)(pt) {
                    chart.draw_series(std::iter::once(
                        EmptyElement::at((pt.x, pt.y))
                            + Text::new(pt.label.clone(), (dx, dy), style.clone()),
                    ))?;
                }
            }
        }
        Ok(())
    }
}
