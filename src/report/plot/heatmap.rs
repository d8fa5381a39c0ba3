//! Heat maps: a rows × columns grid of values, each cell coloured by its value (viridis, low = dark)
//! and annotated with it, NaN cells grey; row and column labels beside the cells and a colour bar with
//! the value label on the right.

use super::axes::{format_tick, min_max, widen};
use super::canvas::{
    DrawResult, Figure, Fonts, PlotFiles, PlotOptions, input_err, render, titled, viridis,
};
use super::text::FAMILY;
use crate::report::ReportError;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::Path;

/// A rows × columns grid of values for [`heat_map`].
#[derive(Clone, Debug, PartialEq)]
pub struct HeatMap {
    /// Labels of the rows, bottom to top.
    pub row_labels: Vec<String>,
    /// Labels of the columns, left to right.
    pub col_labels: Vec<String>,
    /// Row-major values, `rows × cols`; NaN marks a cell without data (grey, "–").
    pub values: Vec<f64>,
    /// Decimals of the value written in each cell.
    pub decimals: usize,
    /// Colour scale range (else the finite values' min and max).
    pub value_range: Option<(f64, f64)>,
    /// Label of the colour bar (the measure and its unit).
    pub value_label: String,
}

/// Heat map of a rows × columns grid: cells coloured by value (viridis, low = dark), each annotated with
/// its value, a colour bar on the right; `opts.x_label` names the columns, `opts.y_label` the rows.
pub fn heat_map(out: &Path, opts: &PlotOptions, map: &HeatMap) -> Result<PlotFiles, ReportError> {
    let (rows, cols) = (map.row_labels.len(), map.col_labels.len());
    if rows == 0 || cols == 0 || map.values.len() != rows * cols {
        return Err(input_err(
            out,
            format!(
                "heat map of {rows} rows × {cols} columns needs {} values, got {}",
                rows * cols,
                map.values.len()
            ),
        ));
    }
    let range = match map.value_range {
        Some(r) => r,
        None => min_max(map.values.iter().copied()).unwrap_or((0.0, 1.0)),
    };
    let range = widen((range.0, range.1));
    render(out, opts, &HeatFigure { opts, map, range })
}

struct HeatFigure<'a> {
    opts: &'a PlotOptions,
    map: &'a HeatMap,
    range: (f64, f64),
}

impl HeatFigure<'_> {
    fn t(&self, v: f64) -> f64 {
        (v - self.range.0) / (self.range.1 - self.range.0)
    }
}

impl Figure for HeatFigure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB> {
        let fonts = Fonts::new(self.opts);
        let area = titled(root, self.opts, &fonts)?;
        let (w, _) = area.dim_in_pixel();
        let bar_w = fonts.px(130.0) as u32;
        let (main, bar) = area.split_horizontally(w.saturating_sub(bar_w));
        let (rows, cols) = (self.map.row_labels.len(), self.map.col_labels.len());
        let (margin, x_area) = (fonts.px(14.0) as u32, fonts.px(50.0) as u32);
        let y_area = {
            let style = fonts.tick();
            let widest = self
                .map
                .row_labels
                .iter()
                .map(|l| main.estimate_text_size(l, &style).map(|s| s.0))
                .try_fold(0u32, |m, w| w.map(|w| m.max(w)))?;
            widest + fonts.px(40.0) as u32
        };
        let mut chart = ChartBuilder::on(&main)
            .margin(margin)
            .x_label_area_size(x_area)
            .y_label_area_size(y_area)
            .build_cartesian_2d(0f64..cols as f64, 0f64..rows as f64)?;
        chart
            .configure_mesh()
            .disable_mesh()
            .x_labels(0)
            .y_labels(0)
            .x_desc(self.opts.x_label.as_str())
            .y_desc(self.opts.y_label.as_str())
            .axis_desc_style(fonts.axis())
            .draw()?;
        let (pw, ph) = chart.plotting_area().dim_in_pixel();
        let (cell_w, cell_h) = (pw as f64 / cols as f64, ph as f64 / rows as f64);
        let text_len = self.map.decimals + 3;
        let size = (cell_h * 0.3)
            .min(cell_w / (text_len as f64 * 0.62))
            .clamp(8.0, fonts.px(18.0));
        for r in 0..rows {
            for c in 0..cols {
                let v = self.map.values[r * cols + c];
                let (fill, text) = if v.is_finite() {
                    (viridis(self.t(v)), format!("{v:.*}", self.map.decimals))
                } else {
                    (RGBColor(0xdd, 0xdd, 0xdd), "–".to_string())
                };
                let (x, y) = (c as f64, r as f64);
                chart.draw_series(std::iter::once(Rectangle::new(
                    [(x, y), (x + 1.0, y + 1.0)],
                    fill.filled(),
                )))?;
                let luminance =
                    0.299 * fill.0 as f64 + 0.587 * fill.1 as f64 + 0.114 * fill.2 as f64;
                let ink = if luminance > 140.0 { BLACK } else { WHITE };
                let style = TextStyle::from((FAMILY, size).into_font())
                    .color(&ink)
                    .pos(Pos::new(HPos::Center, VPos::Center));
                chart.draw_series(std::iter::once(Text::new(text, (x + 0.5, y + 0.5), style)))?;
            }
        }
        // Row and column labels beside the cells (absolute pixels on the root).
        let gap = fonts.px(8.0) as i32;
        let x_style = fonts.tick().pos(Pos::new(HPos::Center, VPos::Top));
        for (c, label) in self.map.col_labels.iter().enumerate() {
            let (x, y) = chart.backend_coord(&(c as f64 + 0.5, 0.0));
            root.draw(&Text::new(label.clone(), (x, y + gap), x_style.clone()))?;
        }
        let y_style = fonts.tick().pos(Pos::new(HPos::Right, VPos::Center));
        for (r, label) in self.map.row_labels.iter().enumerate() {
            let (x, y) = chart.backend_coord(&(0.0, r as f64 + 0.5));
            root.draw(&Text::new(label.clone(), (x - gap, y), y_style.clone()))?;
        }
        self.colour_bar(&bar, &fonts, margin, x_area)
    }
}

impl HeatFigure<'_> {
    /// The colour bar: the value range bottom (dark) to top, ticks and the value label on the right.
    fn colour_bar<DB: DrawingBackend>(
        &self,
        area: &DrawingArea<DB, Shift>,
        fonts: &Fonts,
        margin: u32,
        x_area: u32,
    ) -> DrawResult<DB> {
        let (lo, hi) = self.range;
        let mut chart = ChartBuilder::on(area)
            .margin_top(margin)
            .margin_bottom(margin + x_area)
            .margin_left(fonts.px(10.0) as u32)
            .margin_right(fonts.px(4.0) as u32)
            .right_y_label_area_size(fonts.px(80.0) as u32)
            .build_cartesian_2d(0f64..1f64, lo..hi)?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .disable_y_mesh()
            .disable_x_axis()
            .y_desc(self.map.value_label.as_str())
            .y_label_formatter(&|v| format_tick(*v))
            .label_style(fonts.tick())
            .axis_desc_style(fonts.axis())
            .y_labels(6)
            .draw()?;
        const STEPS: usize = 64;
        chart.draw_series((0..STEPS).map(|i| {
            let (a, b) = (i as f64 / STEPS as f64, (i + 1) as f64 / STEPS as f64);
            let colour = viridis((a + b) / 2.0);
            Rectangle::new(
                [(0.0, lo + a * (hi - lo)), (1.0, lo + b * (hi - lo))],
                colour.filled(),
            )
        }))?;
        Ok(())
    }
}
