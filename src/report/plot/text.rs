//! The embedded font and the bitmap text rasteriser.
//!
//! [`FONT`] is a subset of DejaVu Sans (`data/fonts/`, Bitstream Vera licence), registered with plotters
//! under [`FAMILY`] for layout and for the SVG backend, and parsed with `ab_glyph` for [`GlyphBitmap`],
//! which draws the PNG's text: every glyph at its exact outline bounds, with the same advances and
//! kerning as the layout estimate. No system font, fontconfig or freetype is needed, so the same data
//! give byte-identical pictures on every machine.

use plotters::prelude::*;

/// The embedded font (see `data/fonts/LICENSE-DejaVu.txt`).
static FONT: &[u8] = include_bytes!("../../../data/fonts/DejaVuSans-subset.ttf");

/// The family name every text style of this module uses.
pub(super) const FAMILY: &str = "sans-serif";

/// Registers [`FONT`] with plotters once per process; false if the font failed to parse.
pub(super) fn font_ready() -> bool {
    static READY: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *READY.get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok())
}

/// plotters' bitmap backend with its own text rasteriser. plotters 0.3.7's `ab_glyph` text drops each
/// glyph's left side bearing and rounds the pen position per glyph, which scatters letters ("texe l");
/// this one places every glyph at its exact outline bounds (same font, same advances and kerning as the
/// layout estimate, so label areas still fit). Everything else is delegated.
pub(super) struct GlyphBitmap<'a>(pub(super) BitMapBackend<'a>);

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

/// [`FONT`] parsed for [`GlyphBitmap`] (`None` if it does not parse; [`super::canvas::render`] checks
/// it first).
pub(super) fn glyph_font() -> Option<&'static ab_glyph::FontRef<'static>> {
    static F: std::sync::OnceLock<Option<ab_glyph::FontRef<'static>>> = std::sync::OnceLock::new();
    F.get_or_init(|| ab_glyph::FontRef::try_from_slice(FONT).ok())
        .as_ref()
}
