//! What every plot shares: options, the two output files, colours, font sizes, the title and the
//! legend panel.
//!
//! A plot kind builds a [`Figure`] (something drawable on any plotters backend); [`render`] draws it
//! twice, into an SVG string and into an 8-bit RGB buffer (text by [`GlyphBitmap`]), and writes
//! `STEM.svg` and `STEM.png` atomically. Sizes are pixels (the SVG's user units); font sizes scale with
//! the picture height ([`Fonts`], 600 px = 1). Series colours are Tableau 10, cycled; scalar colour
//! scales are viridis.

use super::text::{FAMILY, GlyphBitmap, font_ready, glyph_font};
use crate::report::{ReportError, write_atomic};
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::path::{Path, PathBuf};

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

/// Tableau 10, then ten of Tableau 20's lighter and darker twins (a full sweep grid draws 12 builds: with
/// ten colours two pairs of its series looked alike).
const PALETTE: [RGBColor; 20] = [
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
    RGBColor(0xa0, 0xcb, 0xe8),
    RGBColor(0xff, 0xbe, 0x7d),
    RGBColor(0x8c, 0xd1, 0x7d),
    RGBColor(0xb6, 0x99, 0x2d),
    RGBColor(0x49, 0x98, 0x94),
    RGBColor(0x79, 0x70, 0x6e),
    RGBColor(0xd3, 0x72, 0x95),
    RGBColor(0xd4, 0xa6, 0xc8),
    RGBColor(0xd7, 0xb5, 0xa6),
    RGBColor(0x2f, 0x4b, 0x7c),
];

/// The colour of series `i` (20 colours, cycled).
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

pub(super) type DrawResult<DB> =
    Result<(), DrawingAreaErrorKind<<DB as DrawingBackend>::ErrorType>>;

/// Something drawable on any plotters backend.
pub(super) trait Figure {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> DrawResult<DB>;
}

/// `out` with `.ext` appended (not replacing a dot already in the name).
fn with_ext(out: &Path, ext: &str) -> PathBuf {
    let mut s = out.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

pub(super) fn input_err(out: &Path, message: String) -> ReportError {
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
pub(super) fn render(
    out: &Path,
    opts: &PlotOptions,
    fig: &impl Figure,
) -> Result<PlotFiles, ReportError> {
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

/// Font sizes scaled with the picture height (600 px = 1).
pub(super) struct Fonts {
    scale: f64,
}

impl Fonts {
    pub(super) fn new(opts: &PlotOptions) -> Fonts {
        Fonts {
            scale: (opts.height as f64 / 600.0).clamp(0.85, 3.0),
        }
    }
    pub(super) fn px(&self, size: f64) -> f64 {
        (size * self.scale).round()
    }
    pub(super) fn style(&self, size: f64) -> TextStyle<'static> {
        TextStyle::from((FAMILY, self.px(size)).into_font()).color(&BLACK)
    }
    pub(super) fn title(&self) -> TextStyle<'static> {
        self.style(22.0)
    }
    pub(super) fn axis(&self) -> TextStyle<'static> {
        self.style(16.0)
    }
    pub(super) fn tick(&self) -> TextStyle<'static> {
        self.style(13.0)
    }
    pub(super) fn small(&self) -> TextStyle<'static> {
        self.style(11.0)
    }
}

/// Fills `root` white, writes the title and returns the area below it.
pub(super) fn titled<DB: DrawingBackend>(
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
pub(super) type LegendEntry = (String, RGBColor, Swatch);

/// Legend entries of named series (colour by position); empty names are skipped.
pub(super) fn legend<'a>(names: impl Iterator<Item = &'a str>, swatch: Swatch) -> Vec<LegendEntry> {
    names
        .enumerate()
        .filter(|(_, n)| !n.is_empty())
        .map(|(i, n)| (n.to_string(), series_colour(i), swatch))
        .collect()
}

/// Splits off a legend panel on the right wide enough for the longest name; draws the entries.
pub(super) fn with_legend<DB: DrawingBackend>(
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
pub(super) enum Swatch {
    Line,
    Dot,
    Box,
    /// The ring that marks Pareto-front points.
    Ring,
}
