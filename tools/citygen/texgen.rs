//! Procedural texture content: facades with windows and printed ids, roofs, ground tiles, fences with a
//! lattice alpha, tree canopies with soft alpha, palette signs and photo-like JPEGs.
//!
//! Every generator is a pure function of its [`TexSpec`] (its own seed), so textures can be produced in
//! parallel in any order. Repeated textures tile seamlessly (noise lattices wrap at the image edge).

use crate::font;
use crate::rng::{Rng, fbm, hash01, value_noise};

/// How a texture is stored; decides the file extension and the PNG colour type.
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Encoding {
    PngRgb,
    PngRgba,
    PngGrey,
    PngPalette,
    Jpeg,
}

impl Encoding {
    pub fn ext(self) -> &'static str {
        if self == Encoding::Jpeg { "jpg" } else { "png" }
    }
    pub fn mime(self) -> &'static str {
        if self == Encoding::Jpeg {
            "image/jpeg"
        } else {
            "image/png"
        }
    }
}

/// Facade appearance: a `floors × cols` window grid per texture repetition, optional printed id.
#[derive(Clone, Debug)]
pub struct Facade {
    pub id: Option<u32>,
    pub floors: u32,
    pub cols: u32,
    pub wall: [u8; 3],
    pub frame: [u8; 3],
    pub glass: [u8; 3],
}

/// What to draw.
#[derive(Clone, Debug)]
pub enum TexKind {
    Facade(Facade),
    /// 0 gravel, 1 tar with seams, 2 clay tiles.
    Roof(u8),
    /// Grey asphalt (written as a greyscale PNG).
    Asphalt,
    Grass,
    /// Square pavers with grout, `n × n` per texture, with a diagonal shading so mirroring is visible.
    Paving {
        n: u32,
        base: [u8; 3],
    },
    /// Grey concrete panels (greyscale PNG).
    Concrete {
        panels: u32,
    },
    /// Chain-link lattice with a top rail and a post; alpha 0 between the wires.
    Fence {
        cells: u32,
        wire: [u8; 3],
    },
    /// Soft-edged canopy over a trunk; alpha falls off smoothly at the edge.
    Tree {
        leaf: [u8; 3],
    },
    /// A few-colour sign with a number (palette PNG).
    Sign {
        number: u32,
    },
    /// Aerial-photo-like noise with a road (JPEG).
    Photo,
}

/// One texture to produce.
#[derive(Clone, Debug)]
pub struct TexSpec {
    /// File name under `textures/`.
    pub file: String,
    pub width: u32,
    pub height: u32,
    pub kind: TexKind,
    pub encoding: Encoding,
    pub seed: u64,
}

/// Generated pixels: interleaved, `channels` per pixel (1 grey, 3 RGB, 4 RGBA), rows top to bottom.
/// For palette images `data` holds indices and `palette` the RGB entries.
pub struct Pixels {
    pub width: u32,
    pub height: u32,
    pub channels: u8,
    pub data: Vec<u8>,
    pub palette: Option<Vec<u8>>,
}

fn clamp8(x: f32) -> u8 {
    x.round().clamp(0.0, 255.0) as u8
}

fn shade(c: [u8; 3], f: f32) -> [f32; 3] {
    c.map(|v| f32::from(v) * f)
}

fn lerp3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [
        a[0] + (b[0] - a[0]) * t,
        a[1] + (b[1] - a[1]) * t,
        a[2] + (b[2] - a[2]) * t,
    ]
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// Fills an image of `channels` by evaluating `f(x, y, u, v)` per pixel (u, v at pixel centres in [0,1)).
fn render(
    w: u32,
    h: u32,
    channels: u8,
    mut f: impl FnMut(u32, u32, f32, f32) -> [f32; 4],
) -> Pixels {
    let mut data = Vec::with_capacity(w as usize * h as usize * usize::from(channels));
    for y in 0..h {
        let v = (y as f32 + 0.5) / h as f32;
        for x in 0..w {
            let u = (x as f32 + 0.5) / w as f32;
            let c = f(x, y, u, v);
            data.extend(c[..usize::from(channels)].iter().map(|c| clamp8(*c)));
        }
    }
    Pixels {
        width: w,
        height: h,
        channels,
        data,
        palette: None,
    }
}

/// Produces the pixels of `spec`.
pub fn generate(spec: &TexSpec) -> Pixels {
    let (w, h, s) = (spec.width.max(1), spec.height.max(1), spec.seed);
    match &spec.kind {
        TexKind::Facade(f) => facade(f, w, h, s),
        TexKind::Roof(k) => roof(*k, w, h, s),
        TexKind::Asphalt => render(w, h, 1, |x, y, u, v| {
            let n = fbm(s, u, v, 4, 4);
            let grit = if hash01(s ^ 1, i64::from(x), i64::from(y)) > 0.97 {
                18.0
            } else {
                0.0
            };
            let crack = (value_noise(s ^ 2, u, v, 3, 3) - 0.5).abs() < 0.008;
            let g = 70.0 + 40.0 * n + grit - if crack { 25.0 } else { 0.0 };
            [g, g, g, 255.0]
        }),
        TexKind::Grass => render(w, h, 3, |x, y, u, v| {
            let n = fbm(s, u, v, 4, 4);
            let blade = hash01(s ^ 3, i64::from(x), i64::from(y / 3)) * 0.25;
            let c = lerp3(
                [48.0, 92.0, 30.0],
                [110.0, 150.0, 60.0],
                (n + blade).min(1.0),
            );
            [c[0], c[1], c[2], 255.0]
        }),
        TexKind::Paving { n, base } => paving(*n, *base, w, h, s),
        TexKind::Concrete { panels } => {
            let p = (*panels).max(1);
            render(w, h, 1, |_, _, u, v| {
                let n = fbm(s, u, v, 2 * p, 3);
                let fu = (u * p as f32).fract();
                let fv = (v * p as f32).fract();
                let joint = fu.min(1.0 - fu).min(fv.min(1.0 - fv)) < 0.02;
                let g = 150.0 + 50.0 * n - if joint { 60.0 } else { 0.0 } - 20.0 * v;
                [g, g, g, 255.0]
            })
        }
        TexKind::Fence { cells, wire } => fence(*cells, *wire, w, h, s),
        TexKind::Tree { leaf } => tree(*leaf, w, h, s),
        TexKind::Sign { number } => sign(*number, w, h, s),
        TexKind::Photo => render(w, h, 3, |_, _, u, v| {
            let n = fbm(s, u, v, 3, 5);
            let field = lerp3([96.0, 120.0, 60.0], [170.0, 150.0, 100.0], n);
            let road = (v - 0.5 - 0.15 * (u * std::f32::consts::TAU).sin()).abs() < 0.03;
            let c = if road { [90.0, 90.0, 95.0] } else { field };
            [c[0], c[1], c[2], 255.0]
        }),
    }
}

/// A facade tile: plaster with floor slabs, a window grid with frames, reflections, lit windows and blinds,
/// and, if `f.id` is set, the id printed large on a plaque in the middle (paper §7's labelled textures).
fn facade(f: &Facade, w: u32, h: u32, seed: u64) -> Pixels {
    let floors = f.floors.max(1);
    let cols = f.cols.max(1);
    let mut rng = Rng::derive(seed, crate::rng::Stream::Texture, 0);
    let win_w = rng.range(0.45, 0.7) as f32;
    let win_h = rng.range(0.45, 0.65) as f32;
    let frame_t = rng.range(0.05, 0.1) as f32;
    let mullion = rng.chance(0.6);
    // Per-window state: 0 dark, 1 lit, 2 blind half down.
    let states: Vec<u8> = (0..floors * cols)
        .map(|_| match rng.below(10) {
            0 | 1 => 1,
            2 => 2,
            _ => 0,
        })
        .collect();
    let text = f.id.map(|id| id.to_string());
    let (scale, tw, th) = match &text {
        Some(t) => {
            let by_h = (h as f32 * 0.22 / font::GLYPH_H as f32) as u32;
            let (w1, _) = font::text_size(t, 1);
            let by_w = (w as f32 * 0.85 / w1.max(1) as f32) as u32;
            let sc = by_h.min(by_w).max(1);
            let (tw, th) = font::text_size(t, sc);
            (sc, tw, th)
        }
        None => (1, 0, 0),
    };
    let tx0 = w.saturating_sub(tw) / 2;
    let ty0 = h.saturating_sub(th) / 2;
    let pad = (scale * 2).max(2);
    render(w, h, 3, |x, y, u, v| {
        // Plaque with the id.
        if let Some(t) = &text {
            let in_plaque =
                x + pad >= tx0 && x < tx0 + tw + pad && y + pad >= ty0 && y < ty0 + th + pad;
            if in_plaque {
                let ink = x >= tx0 && y >= ty0 && font::text_ink(t, scale, x - tx0, y - ty0);
                let c = if ink {
                    [25.0, 25.0, 35.0]
                } else {
                    [235.0, 228.0, 200.0]
                };
                return [c[0], c[1], c[2], 255.0];
            }
        }
        let n = fbm(seed, u, v, 8, 3);
        let mut c = shade(f.wall, 0.85 + 0.3 * n);
        let fy = v * floors as f32;
        let (row, ry) = (fy as u32, fy.fract());
        let fx = u * cols as f32;
        let (col, rx) = (fx as u32, fx.fract());
        // Floor slab band at the bottom of each storey.
        if ry > 0.93 {
            c = shade(f.wall, 0.7);
        }
        let x0 = (1.0 - win_w) / 2.0;
        let y0 = (1.0 - win_h) / 2.0;
        let lx = (rx - x0) / win_w;
        let ly = (ry - y0) / win_h;
        if (0.0..1.0).contains(&lx) && (0.0..1.0).contains(&ly) {
            let ft = frame_t;
            let on_frame = lx < ft
                || lx > 1.0 - ft
                || ly < ft
                || ly > 1.0 - ft
                || (mullion && (lx - 0.5).abs() < ft * 0.5);
            c = if on_frame {
                shade(f.frame, 1.0)
            } else {
                let state = states
                    .get((row * cols + col) as usize)
                    .copied()
                    .unwrap_or(0);
                let sky = lerp3(shade(f.glass, 1.25), shade(f.glass, 0.7), ly);
                match state {
                    1 => lerp3([250.0, 215.0, 130.0], [200.0, 160.0, 90.0], ly),
                    2 if ly < 0.55 => shade([200, 190, 170], 0.9 + 0.1 * ((ly * 40.0).fract())),
                    _ => sky,
                }
            };
        }
        [c[0], c[1], c[2], 255.0]
    })
}

fn roof(kind: u8, w: u32, h: u32, s: u64) -> Pixels {
    render(w, h, 3, |x, y, u, v| match kind {
        0 => {
            let n = fbm(s, u, v, 8, 3);
            let speck = hash01(s, i64::from(x / 2), i64::from(y / 2)) * 30.0;
            let g = 110.0 + 50.0 * n + speck;
            [g, g * 0.95, g * 0.85, 255.0]
        }
        1 => {
            let n = fbm(s, u, v, 4, 3);
            let seam = (v * 4.0).fract() < 0.03 || (u * 2.0).fract() < 0.015;
            let g = 45.0 + 25.0 * n + if seam { 30.0 } else { 0.0 };
            [g, g, g * 1.05, 255.0]
        }
        _ => {
            let rows = 16.0;
            let ry = (v * rows).fract();
            let stagger = if ((v * rows) as u32).is_multiple_of(2) {
                0.0
            } else {
                0.5
            };
            let rx = (u * 12.0 + stagger).fract();
            let n = fbm(s, u, v, 8, 2);
            let f = 0.6 + 0.4 * ry + 0.15 * n - if rx < 0.05 { 0.2 } else { 0.0 };
            [170.0 * f, 75.0 * f, 50.0 * f, 255.0]
        }
    })
}

fn paving(n: u32, base: [u8; 3], w: u32, h: u32, s: u64) -> Pixels {
    let n = n.max(1);
    render(w, h, 3, |_, _, u, v| {
        let (fu, fv) = (u * n as f32, v * n as f32);
        let (iu, iv) = (fu as i64, fv as i64);
        let (ru, rv) = (fu.fract(), fv.fract());
        let grout = ru < 0.06 || rv < 0.06;
        let tile = 0.85 + 0.3 * hash01(s, iu, iv);
        // Diagonal gradient over the whole texture: MIRRORED_REPEAT differs visibly from REPEAT.
        let grad = 0.8 + 0.3 * (u + v) * 0.5;
        let bevel = 1.0 - 0.15 * (ru.min(rv) * 8.0).min(1.0);
        let f = if grout {
            0.55
        } else {
            tile * grad * (1.05 - bevel * 0.1)
        };
        let c = shade(base, f + 0.05 * fbm(s ^ 5, u, v, 2 * n, 2));
        [c[0], c[1], c[2], 255.0]
    })
}

fn fence(cells: u32, wire: [u8; 3], w: u32, h: u32, s: u64) -> Pixels {
    let p = cells.max(1) as f32;
    render(w, h, 4, |_, _, u, v| {
        let rail = v < 0.06;
        let post = u < 0.04;
        // Chain link: two diagonal families of lines, `cells` diamonds across the width.
        let a = ((u * p + v * p * h as f32 / w as f32) % 1.0 + 1.0) % 1.0;
        let b = ((u * p - v * p * h as f32 / w as f32) % 1.0 + 1.0) % 1.0;
        let wire_hit = a.min(1.0 - a) < 0.07 || b.min(1.0 - b) < 0.07;
        let n = 0.85 + 0.3 * value_noise(s, u, v, 4, 4);
        if rail || post {
            let c = shade([90, 90, 95], n);
            [c[0], c[1], c[2], 255.0]
        } else if wire_hit {
            let c = shade(wire, n);
            [c[0], c[1], c[2], 255.0]
        } else {
            [0.0, 0.0, 0.0, 0.0]
        }
    })
}

fn tree(leaf: [u8; 3], w: u32, h: u32, s: u64) -> Pixels {
    render(w, h, 4, |_, _, u, v| {
        let trunk = (u - 0.5).abs() < 0.04 && v > 0.6;
        let (dx, dy) = (u - 0.5, (v - 0.4) * 1.1);
        let r = (dx * dx + dy * dy).sqrt();
        let edge = 0.36 + 0.06 * (value_noise(s, u, v, 6, 6) - 0.5);
        let canopy = 1.0 - smoothstep(edge - 0.08, edge, r);
        let clump = fbm(s ^ 7, u, v, 8, 3);
        let alpha = canopy * (0.55 + 0.45 * clump);
        let light = 0.7 + 0.5 * (0.5 - dx - dy).clamp(0.0, 1.0) * clump;
        if alpha > 0.02 {
            let c = shade(leaf, light);
            [c[0], c[1], c[2], 255.0 * alpha]
        } else if trunk {
            [92.0, 64.0, 40.0, 255.0]
        } else {
            [0.0, 0.0, 0.0, 0.0]
        }
    })
}

/// A palette image: background stripes, border and the sign number.
fn sign(number: u32, w: u32, h: u32, s: u64) -> Pixels {
    let mut rng = Rng::derive(s, crate::rng::Stream::Texture, 1);
    let palette: Vec<u8> = (0..6)
        .flat_map(|_| {
            [
                rng.int(20, 250) as u8,
                rng.int(20, 250) as u8,
                rng.int(20, 250) as u8,
            ]
        })
        .collect();
    let text = number.to_string();
    let (w1, h1) = font::text_size(&text, 1);
    let scale = ((w as f32 * 0.8) / w1.max(1) as f32)
        .min(h as f32 * 0.6 / h1 as f32)
        .max(1.0) as u32;
    let (tw, th) = font::text_size(&text, scale);
    let (tx0, ty0) = (w.saturating_sub(tw) / 2, h.saturating_sub(th) / 2);
    let border = (w.min(h) / 16).max(1);
    let mut data = Vec::with_capacity(w as usize * h as usize);
    for y in 0..h {
        for x in 0..w {
            let idx = if x < border || y < border || x + border >= w || y + border >= h {
                0
            } else if x >= tx0 && y >= ty0 && font::text_ink(&text, scale, x - tx0, y - ty0) {
                1
            } else {
                2 + ((x + y) / (border * 3).max(1)) % 4
            };
            data.push(idx as u8);
        }
    }
    Pixels {
        width: w,
        height: h,
        channels: 1,
        data,
        palette: Some(palette),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(kind: TexKind, enc: Encoding, w: u32, h: u32) -> TexSpec {
        TexSpec {
            file: String::new(),
            width: w,
            height: h,
            kind,
            encoding: enc,
            seed: 42,
        }
    }

    fn distinct_values(p: &Pixels) -> usize {
        let mut seen = std::collections::BTreeSet::new();
        for px in p.data.chunks_exact(usize::from(p.channels)) {
            seen.insert(px.to_vec());
        }
        seen.len()
    }

    #[test]
    fn every_kind_has_real_content() {
        let fac = Facade {
            id: Some(4299),
            floors: 4,
            cols: 3,
            wall: [180, 150, 120],
            frame: [240, 240, 240],
            glass: [80, 110, 140],
        };
        let kinds = [
            TexKind::Facade(fac),
            TexKind::Roof(0),
            TexKind::Roof(1),
            TexKind::Roof(2),
            TexKind::Asphalt,
            TexKind::Grass,
            TexKind::Paving {
                n: 4,
                base: [160, 150, 140],
            },
            TexKind::Concrete { panels: 2 },
            TexKind::Fence {
                cells: 6,
                wire: [150, 150, 150],
            },
            TexKind::Tree {
                leaf: [60, 110, 40],
            },
            TexKind::Sign { number: 17 },
            TexKind::Photo,
        ];
        for k in kinds {
            let p = generate(&spec(k.clone(), Encoding::PngRgb, 64, 64));
            assert_eq!(p.data.len(), 64 * 64 * usize::from(p.channels), "{k:?}");
            // Not flat: at least 5 distinct pixel values (the palette sign has 6 entries).
            assert!(
                distinct_values(&p) >= 5,
                "{k:?} has {} values",
                distinct_values(&p)
            );
        }
    }

    #[test]
    fn alpha_textures_have_transparent_and_opaque_texels() {
        for k in [
            TexKind::Fence {
                cells: 6,
                wire: [150, 150, 150],
            },
            TexKind::Tree {
                leaf: [60, 110, 40],
            },
        ] {
            let p = generate(&spec(k, Encoding::PngRgba, 64, 64));
            let alphas: Vec<u8> = p.data.chunks_exact(4).map(|c| c[3]).collect();
            assert!(alphas.contains(&0));
            assert!(alphas.contains(&255));
        }
        // The canopy has a soft edge: intermediate alpha values exist.
        let p = generate(&spec(
            TexKind::Tree {
                leaf: [60, 110, 40],
            },
            Encoding::PngRgba,
            128,
            128,
        ));
        assert!(p.data.chunks_exact(4).any(|c| c[3] > 20 && c[3] < 235));
    }

    #[test]
    fn facade_id_is_printed_in_dark_ink() {
        let fac = |id| Facade {
            id,
            floors: 4,
            cols: 3,
            wall: [180, 150, 120],
            frame: [240, 240, 240],
            glass: [80, 110, 140],
        };
        let with = generate(&spec(
            TexKind::Facade(fac(Some(88))),
            Encoding::PngRgb,
            128,
            128,
        ));
        let without = generate(&spec(
            TexKind::Facade(fac(None)),
            Encoding::PngRgb,
            128,
            128,
        ));
        let ink = |p: &Pixels| {
            p.data
                .chunks_exact(3)
                .filter(|c| c == &[25, 25, 35])
                .count()
        };
        assert_eq!(ink(&without), 0);
        // "88": 2 glyphs × 17 set font pixels each, at an integer scale ≥ 3 → ≥ 34·9 ink pixels.
        assert!(ink(&with) >= 34 * 9, "{}", ink(&with));
    }
}
