//! Plots of experiment results, each written as `STEM.svg` and `STEM.png` (temp file + rename).
//!
//! Four kinds, all taking plain data:
//! - [`line_chart`]: named series of (x, y) points (NaN breaks a line), e.g. coarser share per frame;
//! - [`heat_map`]: a rows × columns grid with labels, the value in each cell and a colour bar (viridis);
//! - [`scatter_pareto`]: named groups of labelled points with the Pareto front marked (cost on x);
//! - [`bar_chart`] / [`histogram_chart`]: grouped bars over categories, e.g. texel-per-pixel histograms.
//!
//! Text is laid out and rasterised with an embedded subset of DejaVu Sans (`data/fonts/`, Bitstream Vera
//! licence) through plotters' `ab_glyph` backend: no system font, fontconfig or freetype is needed, and
//! the same data give byte-identical SVG and PNG files on every machine. The SVG names the font family
//! `sans-serif`; viewers substitute their own sans font. The PNG is 8-bit RGB.
//!
//! Legends sit in a panel right of the plot (never over the data); series colours are Tableau 10,
//! cycled.
//!
//! Where things are: `canvas.rs` holds what every plot shares ([`PlotOptions`], the two output files,
//! colours, font sizes, title and legend panel); `text.rs` the embedded font and the PNG text
//! rasteriser; `axes.rs` tick labels, value ranges and the x–y chart; one file per kind draws it
//! (`line.rs`, `pareto.rs`, `heatmap.rs`, `bars.rs`).

mod axes;
mod bars;
mod canvas;
mod heatmap;
mod line;
mod pareto;
mod text;

pub use axes::format_tick;
pub use bars::{BarSeries, bar_chart, histogram_chart};
pub use canvas::{PlotFiles, PlotOptions, series_colour, viridis};
pub use heatmap::{HeatMap, heat_map};
pub use line::{Series, line_chart};
pub use pareto::{Better, LabelledPoint, PointLabels, ScatterSeries, scatter_pareto};
