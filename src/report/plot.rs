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

use super::metrics::{Histogram, pareto_front};
use super::{ReportError, write_atomic};
use plotters::coord::Shift;
use plotters::coord::ranged1d::{AsRangedCoord, Ranged, ValueFormatter};
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::ops::Range;
use std::path::{Path, PathBuf};

/// The embedded font (see `data/fonts/LICENSE-DejaVu.txt`).
static FONT: &[u8] = include_bytes!("../../data/fonts/DejaVuSans-subset.ttf");
/// The family name every text style of this module uses.
const FAMILY: &str = "sans-serif";

/// Registers [`FONT`] with plotters once per process; false if the font failed to parse.
fn font_ready() -> bool {
    static READY: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *READY.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok())
}

/// Title, axis labels, size and axis scales of a plot.
#[derive(Clone, Debug, PartialEq)]
pub struct PlotOptions {
    pub title: String,
    /// Label of the x axis (for a heat map: of the columns), with its unit.
    pub x_label: String,
    /// Label of the y axis (for a heat map: of the rows), with its unit.
    pub y_label: String,
    /// Picture size in pixels (the SVG's user units).
    pub width: u32,
    pub height: u32,
    /// Logarithmic x axis, ticks at powers of two (line and scatter plots). Points with x ≤ 0 are
    /// left out.
    pub log_x: bool,
    /// Logarithmic y axis, ticks at powers of two (line, scatter and bar plots). Points with y ≤ 0 are
    /// left out (bars ≤ 0 are not drawn).
    pub log_y: bool,
    /// Fixed x range (else the data's, padded by 4 %).
    pub x_range: Option<(f64, f64)>,
    /// Fixed y range (else the data's, padded by 4 %; bar charts start at 0).
    pub y_range: Option<(f64, f64)>,
}

impl PlotOptions {
    /// 960 × 600 pixels, linear axes, ranges from the data.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> PlotOptions {
        PlotOptions {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            width: 960,
            height: 600,
            log_x: false,
            log_y: false,
            x_range: None,
            y_range: None,
        }
    }
}

/// The two files a plot function wrote.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PlotFiles {
    pub svg: PathBuf,
    pub png: PathBuf,
}

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

/// A named series of bar heights, one per category.
#[derive(Clone, Debug, PartialEq)]
pub struct BarSeries {
    pub name: String,
    pub values: Vec<f64>,
}

const PALETTE: [RGBColor; 10] = [
    RGBColor(0x4e, 0x79, 0xa7),
    RGBColor(0xf2, 0x8e, 0x2b),
    RGBColor(0xe1, 0x57, 0x59),
    RGBColor(0x76, 0xb7, 0xb2),
    RGBColor(0x59, 0xa1, 0x4f),
    RGBColor(0xed, 0xc9, 0x48),
    RGBColor(0xb0, 0x7a, 0xa1),
    RGBColor(0xff, 0x9d, 0xa7),
    RGBColor(0x9c, 0x75, 0x5f),
    RGBColor(0xba, 0xb0, 0xac),
];

/// The colour of series `i` (Tableau 10, cycled).
pub fn series_colour(i: usize) -> RGBColor {
    PALETTE[i % PALETTE.len()]
}

/// Viridis (matplotlib) at `t` ∈ [0, 1], linear between 9 samples.
pub fn viridis(t: f64) -> RGBColor {
    const V: [(u8, u8, u8); 9] = [
        (68, 1, 84),
        (72, 40, 120),
        (62, 73, 137),
        (49, 104, 142),
        (38, 130, 142),
        (31, 158, 137),
        (53, 183, 121),
        (110, 206, 88),
        (253, 231, 37),
    ];
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) } * (V.len() - 1) as f64;
    let i = (t.floor() as usize).min(V.len() - 2);
    let f = t - i as f64;
    let lerp = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * f).round() as u8;
    let (a, b) = (V[i], V[i + 1]);
    RGBColor(lerp(a.0, b.0), lerp(a.1, b.1), lerp(a.2, b.2))
}

/// A tick label: up to 4 decimals without trailing zeros; `1e6`-style from 10⁶ and below 10⁻³.
pub fn format_tick(v: f64) -> String {
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

// ---------------------------------------------------------------------------------------------------
// Public plot functions
// ---------------------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------------------
// Rendering to both files
// ---------------------------------------------------------------------------------------------------

type DrawResult<DB> = Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Something drawable on any plotters backend.
trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB>;
}

/// `out` with `.ext` appended (not replacing a dot already in the name).
fn with_ext(out: &Path, ext: &str) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

fn input_err(out: &Path, message: String) -> ReportError {
    ReportError::PlotInput {
        path: out.to_path_buf(),
        message,
    }
}

fn draw_err<E: std::fmt::Display>(path: &Path) -> impl Fn(E) -> ReportError + '_ {
    move |e| ReportError::Draw {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Draws `fig` into an SVG string and an RGB buffer and writes both files atomically.
fn render(out: &Path, opts: &PlotOptions, fig: &impl Figure) -> Result<PlotFiles, ReportError> {
    let (svg_path, png_path) = (with_ext(out, "svg"), with_ext(out, "png"));
    if !font_ready() || glyph_font().is_none() {
        return Err(draw_err(&svg_path)("the embedded font does not parse"));
    }
    let (w, h) = (opts.width.max(64), opts.height.max(64));
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (w, h)).into_drawing_area();
        fig.draw(&root).map_err(draw_err(&svg_path))?;
        root.present().map_err(draw_err(&svg_path))?;
    }
    let mut rgb = vec![0u8; w as usize * h as usize * 3];
    {
        let backend = GlyphBitmap(BitMapBackend::with_buffer(&mut rgb, (w, h)));
        let root = backend.into_drawing_area();
        fig.draw(&root).map_err(draw_err(&png_path))?;
        root.present().map_err(draw_err(&png_path))?;
    }
    let png = encode_png(&rgb, w, h).map_err(|e| ReportError::io(&png_path, e))?;
    write_atomic(&svg_path, svg.as_bytes())?;
    write_atomic(&png_path, &png)?;
    Ok(PlotFiles {
        svg: svg_path,
        png: png_path,
    })
}

fn encode_png(rgb: &[u8], w: u32, h: u32) -> std::io::Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(png::ColorType::Rgb);
    enc.set_depth(png::BitDepth::Eight);
    let mut writer = enc.write_header().map_err(std::io::Error::other)?;
    writer
        .write_image_data(rgb)
        .map_err(std::io::Error::other)?;
    writer.finish().map_err(std::io::Error::other)?;
    Ok(out)
}

// ---------------------------------------------------------------------------------------------------
// Bitmap text
// ---------------------------------------------------------------------------------------------------

/// plotters' bitmap backend with its own text rasteriser. plotters 0.3.7's `ab_glyph` text drops each
/// glyph's left side bearing and rounds the pen position per glyph, which scatters letters ("texe l");
/// this one places every glyph at its exact outline bounds (same font, same advances and kerning as the
/// layout estimate, so label areas still fit). Everything else is delegated.
struct GlyphBitmap<'a>(BitMapBackend<'a>);

type BackendResult<E> = Result<(), plotters_backend::DrawingErrorKind<E>>;

impl<'a> DrawingBackend for GlyphBitmap<'a> {
    type ErrorType = <BitMapBackend<'a> as DrawingBackend>::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.0.get_size()
    }
    fn ensure_prepared(&mut self) -> BackendResult<Self::ErrorType> {
        self.0.ensure_prepared()
    }
    fn present(&mut self) -> BackendResult<Self::ErrorType> {
        self.0.present()
    }
    fn draw_pixel(
        &mut self,
        point: plotters_backend::BackendCoord,
        color: plotters_backend::BackendColor,
    ) -> BackendResult<Self::ErrorType> {
        self.0.draw_pixel(point, color)
    }
    fn draw_line<S: plotters_backend::BackendStyle>(
        &mut self,
        from: plotters_backend::BackendCoord,
        to: plotters_backend::BackendCoord,
        style: &S,
    ) -> BackendResult<Self::ErrorType> {
        self.0.draw_line(from, to, style)
    }
    fn draw_rect<S: plotters_backend::BackendStyle>(
        &mut self,
        upper_left: plotters_backend::BackendCoord,
        bottom_right: plotters_backend::BackendCoord,
        style: &S,
        fill: bool,
    ) -> BackendResult<Self::ErrorType> {
        self.0.draw_rect(upper_left, bottom_right, style, fill)
    }
    fn draw_path<
        S: plotters_backend::BackendStyle,
        I: IntoIterator<Item = plotters_backend::BackendCoord>,
    >(
        &mut self,
        path: I,
        style: &S,
    ) -> BackendResult<Self::ErrorType> {
        self.0.draw_path(path, style)
    }
    fn draw_circle<S: plotters_backend::BackendStyle>(
        &mut self,
        center: plotters_backend::BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> BackendResult<Self::ErrorType> {
        self.0.draw_circle(center, radius, style, fill)
    }
    fn fill_polygon<
        S: plotters_backend::BackendStyle,
        I: IntoIterator<Item = plotters_backend::BackendCoord>,
    >(
        &mut self,
        vert: I,
        style: &S,
    ) -> BackendResult<Self::ErrorType> {
        self.0.fill_polygon(vert, style)
    }
    fn blit_bitmap(
        &mut self,
        pos: plotters_backend::BackendCoord,
        size: (u32, u32),
        src: &[u8],
    ) -> BackendResult<Self::ErrorType> {
        self.0.blit_bitmap(pos, size, src)
    }

    /// Lays out `text` on a baseline (advances + kerning of [`FONT`] at the style's pixel size), anchors
    /// the box (width = advance sum, height = ascent − descent) at `pos`, rotates it by the style's
    /// transform and blends each glyph's coverage.
    fn draw_text<TStyle: plotters_backend::BackendTextStyle>(
        &mut self,
        text: &str,
        style: &TStyle,
        pos: plotters_backend::BackendCoord,
    ) -> BackendResult<Self::ErrorType> {
        use ab_glyph::{Font, ScaleFont};
        use plotters_backend::text_anchor::{HPos, VPos};
        let colour = style.color();
        let Some(font) = glyph_font() else {
            return Ok(());
        };
        if colour.alpha == 0.0 || text.is_empty() {
            return Ok(());
        }
        let scale = ab_glyph::PxScale::from(style.size() as f32);
        let sf = font.as_scaled(scale);
        let mut coverage: Vec<(i32, i32, f32)> = Vec::new();
        let (mut caret, mut prev) = (0f32, None);
        for c in text.chars() {
            let id = sf.glyph_id(c);
            if let Some(p) = prev {
                caret += sf.kern(p, id);
            }
            let glyph = id.with_scale_and_position(scale, ab_glyph::point(caret, sf.ascent()));
            caret += sf.h_advance(id);
            prev = Some(id);
            if let Some(outline) = font.outline_glyph(glyph) {
                let b = outline.px_bounds();
                let (bx, by) = (b.min.x as i32, b.min.y as i32);
                outline.draw(|x, y, v| coverage.push((bx + x as i32, by + y as i32, v)));
            }
        }
        let (width, height) = (caret.round() as i32, sf.height().round() as i32);
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Center => -width / 2,
            HPos::Right => -width,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        let trans = style.transform();
        let (w, h) = self.get_size();
        for (x, y, v) in coverage {
            let (x, y) = trans.transform(x + dx, y + dy);
            let (x, y) = (pos.0 + x, pos.1 + y);
            if v > 0.0 && x >= 0 && y >= 0 && x < w as i32 && y < h as i32 {
                let c = plotters_backend::BackendColor {
                    alpha: colour.alpha * f64::from(v.min(1.0)),
                    rgb: colour.rgb,
                };
                self.0.draw_pixel((x, y), c)?;
            }
        }
        Ok(())
    }
}

/// [`FONT`] parsed for [`GlyphBitmap`] (`None` if it does not parse; [`render`] checks it first).
fn glyph_font() -> Option<&'static ab_glyph::FontRef<'static>> {
    static F: std::sync::OnceLock<Option<ab_glyph::FontRef<'static>>> = std::sync::OnceLock::new();
    F.get_or_init(|| ab_glyph::FontRef::try_from_slice(FONT).ok())
        .as_ref()
}

// ---------------------------------------------------------------------------------------------------
// Layout helpers
// ---------------------------------------------------------------------------------------------------

/// Font sizes scaled with the picture height (600 px = 1).
struct Fonts {
    scale: f64,
}

impl Fonts {
    fn new(opts: &PlotOptions) -> Fonts {
        Fonts {
            scale: (opts.height as f64 / 600.0).clamp(0.85, 3.0),
        }
    }
    fn px(&self, size: f64) -> f64 {
        (size * self.scale).round()
    }
    fn style(&self, size: f64) -> TextStyle<'static> {
        TextStyle::from((FAMILY, self.px(size)).into_font()).color(&BLACK)
    }
    fn title(&self) -> TextStyle<'static> {
        self.style(22.0)
    }
    fn axis(&self) -> TextStyle<'static> {
        self.style(16.0)
    }
    fn tick(&self) -> TextStyle<'static> {
        self.style(13.0)
    }
    fn small(&self) -> TextStyle<'static> {
        self.style(11.0)
    }
}

/// Fills `root` white, writes the title and returns the area below it.
fn titled<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    opts: &PlotOptions,
    fonts: &Fonts,
) -> Result<DrawingArea<DB, Shift>, DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    if opts.title.is_empty() {
        Ok(root.clone())
    } else {
        root.titled(&opts.title, fonts.title())
    }
}

/// A legend line: name, colour, swatch.
type LegendEntry = (String, RGBColor, Swatch);

/// Legend entries of named series (colour by position); empty names are skipped.
fn legend<'a>(names: impl Iterator<Item = &'a str>, swatch: Swatch) -> Vec<LegendEntry> {
    names
        .enumerate()
        .filter(|(_, n)| !n.is_empty())
        .map(|(i, n)| (n.to_string(), series_colour(i), swatch))
        .collect()
}

/// Splits off a legend panel on the right wide enough for the longest name; draws the entries.
fn with_legend<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    entries: &[LegendEntry],
    fonts: &Fonts,
) -> Result<DrawingArea<DB, Shift>, DrawingAreaErrorKind<DB::ErrorType>> {
    if entries.is_empty() {
        return Ok(area.clone());
    }
    let style = fonts.tick();
    let text_w = entries
        .iter()
        .map(|(n, _, _)| area.estimate_text_size(n, &style).map(|s| s.0))
        .try_fold(0u32, |m, w| w.map(|w| m.max(w)))?;
    let (w, _) = area.dim_in_pixel();
    let sw = fonts.px(28.0) as u32;
    let panel = (text_w + sw + fonts.px(24.0) as u32).min(w / 3);
    let (plot, legend) = area.split_horizontally(w - panel);
    let line_h = fonts.px(22.0) as i32;
    let top = fonts.px(20.0) as i32;
    // As many entries as fit; the rest are counted on a last line.
    let (_, h) = legend.dim_in_pixel();
    let fit = ((h as i32 - top) / line_h).max(1) as usize;
    let shown = if entries.len() > fit {
        fit - 1
    } else {
        entries.len()
    };
    if shown < entries.len() {
        legend.draw(&Text::new(
            format!("… {} more", entries.len() - shown),
            (fonts.px(4.0) as i32, top + shown as i32 * line_h),
            style.pos(Pos::new(HPos::Left, VPos::Center)),
        ))?;
    }
    for (i, (name, colour, swatch)) in entries.iter().take(shown).enumerate() {
        let y = top + i as i32 * line_h;
        let x0 = fonts.px(4.0) as i32;
        match swatch {
            Swatch::Line => {
                legend.draw(&PathElement::new(
                    vec![(x0, y), (x0 + sw as i32 - 6, y)],
                    colour.stroke_width(3),
                ))?;
            }
            Swatch::Dot => {
                legend.draw(&Circle::new(
                    (x0 + sw as i32 / 2 - 3, y),
                    5,
                    colour.filled(),
                ))?;
            }
            Swatch::Box => {
                legend.draw(&Rectangle::new(
                    [(x0 + 4, y - 6), (x0 + sw as i32 - 10, y + 6)],
                    colour.filled(),
                ))?;
            }
            Swatch::Ring => {
                legend.draw(&Circle::new(
                    (x0 + sw as i32 / 2 - 3, y),
                    8,
                    colour.stroke_width(2),
                ))?;
            }
        }
        legend.draw(&Text::new(
            name.clone(),
            (x0 + sw as i32, y),
            style.pos(Pos::new(HPos::Left, VPos::Center)),
        ))?;
    }
    Ok(plot)
}

#[derive(Copy, Clone)]
enum Swatch {
    Line,
    Dot,
    Box,
    /// The ring that marks Pareto-front points.
    Ring,
}

fn min_max(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| v.is_finite())
        .fold(None, |acc, v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// A non-empty range: equal ends are spread by ±max(|v|·0.1, 0.5), reversed ends swapped.
fn widen((lo, hi): (f64, f64)) -> (f64, f64) {
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (hi, lo) };
    if hi > lo {
        (lo, hi)
    } else {
        let d = (lo.abs() * 0.1).max(0.5);
        (lo - d, hi + d)
    }
}

/// Pads a positive range by a factor 2^0.1 on each side (a single value gets one octave each side).
fn log_pad(lo: f64, hi: f64) -> (f64, f64) {
    if hi > lo {
        let f = 2f64.powf(0.1);
        (lo / f, hi * f)
    } else {
        (lo / 2.0, hi * 2.0)
    }
}

/// The x and y ranges of a line or scatter plot: the options' fixed ranges, else the finite data (on a
/// log axis: the positive data) padded by 4 % (log: 2^0.1).
fn data_ranges(
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

// ---------------------------------------------------------------------------------------------------
// x–y figures (lines, scatter) on linear or log axes
// ---------------------------------------------------------------------------------------------------

/// What is drawn inside an x–y chart, for any coordinate type of f64 axes.
trait XyContent {
    fn draw_content<DB: DrawingBackend, X, Y>(
        &self,
        chart: &mut ChartContext<'_, DB, Cartesian2d<X, Y>>,
        fonts: &Fonts,
    ) -> DrawResult<DB>
    where
        X: Ranged<ValueType = f64>,
        Y: Ranged<ValueType = f64>;
}

struct XyFigure<'a, C> {
    opts: &'a PlotOptions,
    xr: Range<f64>,
    yr: Range<f64>,
    legend: Vec<LegendEntry>,
    content: C,
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
            for run in s.points.split(|p| !ok(p)).filter(|r| !r.is_empty()) {
                chart.draw_series(LineSeries::new(run.iter().copied(), colour.stroke_width(2)))?;
            }
            // Markers make sparse series readable (and single points visible at all).
            let finite = s.points.iter().filter(|p| ok(p)).count();
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

// ---------------------------------------------------------------------------------------------------
// Heat map
// ---------------------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------------------
// Bars
// ---------------------------------------------------------------------------------------------------

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
