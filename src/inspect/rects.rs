//! `verify` of the leaf rects (docs/DESIGN.md "Repeats: one period per rect, wrapped in the shader"): every
//! triangle lands inside its rect under the rect's per-axis wrap, every rect holds the texels per period
//! that its triangles need at the leaf's `min_distance` (the d_min guarantee of paper §5.2.1 at the leaves;
//! `min_distance` doubling up the tree carries it to every ancestor), and every wrap border of a leaf atlas
//! holds what the sampler's rule puts there (the periodic partner for REPEAT, the reflection for
//! MIRRORED_REPEAT, the edge for CLAMP_TO_EDGE), so filtering across a seam reads what the original
//! texture would show.

use super::VerifyReport;
use crate::model::sizing::{SizeMethod, texels_per_uv};
use crate::model::transform::mirror_image;
use crate::model::transform::rect_t;
use crate::model::{BuildParams, RectWrap};
use crate::store::format::{LeafRecord, RectRecord};
use crate::store::{TreeFile, TreeView};
use crate::texfmt::TexFormat;
use glam::{DVec2, DVec3};

/// Relative shortfall of texels per period tolerated (f32 positions and UVs in the file against the f64
/// ones the build sized with).
const PERIOD_TOLERANCE: f64 = 1e-3;

/// Largest mean difference (sRGB8 levels) allowed between a wrap border and what the sampler's rule puts
/// there: exact up to rounding uncompressed; block compression encodes the two sides in different 4×4
/// blocks.
pub fn wrap_border_tolerance(format: TexFormat) -> f64 {
    match format {
        TexFormat::Rgba8 => 1.0,
        TexFormat::Bc7 => 8.0,
        _ => 16.0,
    }
}

/// UV tolerance of a containment check for UVs of magnitude up to `m` (f32 storage: 2⁻²³ relative).
fn uv_tol(m: f64) -> f64 {
    m.max(1.0) * 4.0 * f64::from(f32::EPSILON) + 1e-6
}

/// Checks one leaf's rects and triangles into `r`.
pub(super) fn verify_leaf(
    t: &TreeView<'_>,
    ti: usize,
    li: usize,
    params: &BuildParams,
    r: &mut VerifyReport,
) {
    let l = &t.leaves[li];
    let rects = t.leaf_rects(l);
    let originals = t.leaf_originals(l);
    for (ri, rect) in rects.iter().enumerate() {
        r.rects_checked += 1;
        if let Err(msg) = check_rect(rect) {
            r.fail(format!("tree {ti} leaf {li} rect {ri}: {msg}"));
        }
    }
    let end = l.first_index.saturating_add(l.index_count) as usize;
    // The leaf's index range is inside the index table: checked by `TreeFile::open`.
    let Some(idx) = t.indices.get(l.first_index as usize..end) else {
        return;
    };
    let f_proj = params.f_proj();
    for tri in idx.chunks_exact(3) {
        let mut verts = Vec::with_capacity(3);
        for &vi in tri {
            if vi < l.first_vertex || vi >= l.first_vertex.saturating_add(l.vertex_count) {
                r.fail(format!(
                    "tree {ti} leaf {li}: index {vi} outside its vertices"
                ));
                continue;
            }
            let v = t.vertices[vi as usize];
            r.vertices_checked += 1;
            if v.leaf as usize != li {
                r.fail(format!(
                    "tree {ti} vertex {vi}: leaf {} but used by leaf {li}",
                    v.leaf
                ));
            }
            let finite = v.pos.iter().chain(&v.orig_uv).all(|c| c.is_finite());
            match (originals.get(v.original as usize), rects.get(v.rect as usize)) {
                (Some(o), Some(rect)) if o.material == rect.material && finite => verts.push(v),
                (o, rect) => r.fail(format!(
                    "tree {ti} leaf {li} vertex {vi}: original {} of {}, rect {} of {}, materials {:?} / {:?}, \
                     finite {finite}",
                    v.original,
                    originals.len(),
                    v.rect,
                    rects.len(),
                    o.map(|o| o.material),
                    rect.map(|x| x.material)
                )),
            }
        }
        let Ok(verts) = <[_; 3]>::try_from(verts) else {
            continue;
        };
        if verts.iter().any(|v| v.rect != verts[0].rect) {
            r.fail(format!(
                "tree {ti} leaf {li}: a triangle's vertices name rects {}, {}, {}",
                verts[0].rect, verts[1].rect, verts[2].rect
            ));
            continue;
        }
        let rect = &rects[verts[0].rect as usize];
        let uv = verts.map(|v| DVec2::new(f64::from(v.orig_uv[0]), f64::from(v.orig_uv[1])));
        for k in [0usize, 1] {
            let axis = uv.map(|p| p[k]);
            if let Err(msg) = check_inside(rect, k, axis) {
                r.fail(format!("tree {ti} leaf {li} rect {}: {msg}", verts[0].rect));
            }
        }
        let pos = verts.map(|v| DVec3::from_array(v.pos.map(f64::from)));
        check_periods(rect, l, pos, uv, f_proj, r);
    }
}

/// The UV range one rect's wrap modes allow. Placement (outer inside the atlas, a non-empty inner inside
/// the outer) and finite ordered UVs are `TreeFile::open`'s checks (`store::validate`).
fn check_rect(rect: &RectRecord) -> Result<(), String> {
    let Some(wrap) = rect.wrap() else {
        return Err(format!("unknown flags {:#x}", rect.flags));
    };
    for (k, &axis_wrap) in wrap.iter().enumerate() {
        let (lo, hi) = (rect.uv_min[k], rect.uv_max[k]);
        let ok = match axis_wrap {
            RectWrap::Linear => true,
            RectWrap::Repeat => hi - lo <= 1.0 + 1e-12 && (0.0..1.0).contains(&lo),
            RectWrap::Mirror | RectWrap::Clamp => lo >= 0.0 && hi <= 1.0,
        };
        if !ok {
            return Err(format!(
                "axis {k}: {axis_wrap:?} range [{lo}, {hi}] is not what the mode allows"
            ));
        }
    }
    Ok(())
}

/// Every point of the triangle's UV interval along axis `k` lands in `[0, span]` under the rect's wrap.
fn check_inside(rect: &RectRecord, k: usize, u: [f64; 3]) -> Result<(), String> {
    let Some(wrap) = rect.wrap() else {
        return Err("unknown flags".into());
    };
    let (lo, hi) = (u[0].min(u[1]).min(u[2]), u[0].max(u[1]).max(u[2]));
    let (a, b) = (rect.uv_min[k], rect.uv_max[k]);
    let span = b - a;
    let tol = uv_tol(lo.abs().max(hi.abs()));
    let inside = |t: f64| t >= -tol && t <= span + tol;
    let ok = match wrap[k] {
        RectWrap::Linear | RectWrap::Clamp => {
            inside(rect_t(lo, wrap[k], a, b)) && inside(rect_t(hi, wrap[k], a, b))
        }
        RectWrap::Mirror => {
            let (m0, m1) = mirror_image(lo, hi);
            m0 >= a - tol && m1 <= b + tol
        }
        RectWrap::Repeat => {
            span >= 1.0 - 1e-12 || {
                let t0 = rect_t(lo, wrap[k], a, b);
                inside(t0) && inside(t0 + (hi - lo))
            }
        }
    };
    if ok {
        Ok(())
    } else {
        Err(format!(
            "axis {k}: triangle UVs [{lo}, {hi}] leave the {:?} range [{a}, {b}]",
            wrap[k]
        ))
    }
}

/// The rect's texels per period against what the triangle needs at the leaf's `min_distance`
/// (`d_min / clamp_scale`), on the axes the source cap did not limit.
fn check_periods(
    rect: &RectRecord,
    leaf: &LeafRecord,
    pos: [DVec3; 3],
    uv: [DVec2; 3],
    f_proj: f64,
    r: &mut VerifyReport,
) {
    // Slivers and huge UVs lose their sizing to f32 storage: skip them (the build sized them in f64).
    let e1 = pos[1] - pos[0];
    let e2 = pos[2] - pos[0];
    let longest = e1
        .length_squared()
        .max(e2.length_squared())
        .max((e2 - e1).length_squared());
    let sliver = e1.cross(e2).length() <= 1e-4 * longest;
    if sliver || uv.iter().any(|u| u.abs().max_element() > 1e4) {
        return;
    }
    let need = texels_per_uv(pos, uv, f_proj * leaf.clamp_scale);
    if need.method != SizeMethod::Exact {
        return;
    }
    let a = rect.decode();
    let tpu = a.texels_per_uv();
    for (k, want) in [need.w, need.h].into_iter().enumerate() {
        if a.capped[k] || want <= 0.0 {
            continue;
        }
        let ratio = tpu[k] / want;
        r.periods_checked += 1;
        r.period_ratio_min = if r.periods_checked == 1 {
            ratio
        } else {
            r.period_ratio_min.min(ratio)
        };
        if ratio < 1.0 - PERIOD_TOLERANCE {
            r.fail(format!(
                "rect of material {} axis {k}: {:.3} texels per period but a triangle needs {want:.3} at the \
                 leaf's min_distance",
                rect.material, tpu[k]
            ));
        }
    }
}

/// Compares every wrap border of every leaf atlas (level 0) with what the sampler's rule puts there.
pub(super) fn verify_wrap_borders(file: &TreeFile, r: &mut VerifyReport) {
    let size = file.params().atlas_size;
    for ti in 0..file.trees() {
        let Some(t) = file.tree(ti) else { continue };
        let format = t.format();
        let tol = wrap_border_tolerance(format);
        for (li, l) in t.leaves.iter().enumerate() {
            let rects = t.leaf_rects(l);
            let wrapped = rects.iter().any(|x| {
                x.wrap()
                    .is_some_and(|w| w.iter().any(|&m| m != RectWrap::Linear))
            });
            if !wrapped {
                continue;
            }
            let Some(node) = t.nodes.get(l.node as usize) else {
                continue;
            };
            let Ok(bytes) = file.block(crate::ids::BlockId(node.atlas_block)) else {
                continue; // a bad checksum is reported by the block pass
            };
            let level0 = level0_rgba8(format, bytes, size);
            let Some(img) = level0 else {
                r.fail(format!(
                    "tree {ti} leaf {li}: atlas block {} does not decode",
                    node.atlas_block
                ));
                continue;
            };
            for (ri, rect) in rects.iter().enumerate() {
                for side in border_sides(rect) {
                    let mean = side.mean_difference(&img, size);
                    r.wrap_borders_checked += 1;
                    r.wrap_border_mean_max = r.wrap_border_mean_max.max(mean);
                    if mean > tol {
                        r.fail(format!(
                            "tree {ti} leaf {li} rect {ri}: {} border differs from the sampler's rule by {mean:.2} \
                             sRGB levels on average (tolerance {tol} for {})",
                            side.name,
                            format.name()
                        ));
                    }
                }
            }
        }
    }
}

/// Level 0 of an atlas block as RGBA8 texels.
fn level0_rgba8(format: TexFormat, bytes: &[u8], size: u32) -> Option<Vec<u8>> {
    let n = format.level_bytes(size) as usize;
    let level = bytes.get(..n)?;
    Some(if format.is_compressed() {
        crate::texfmt::decode_level(format, level, size)
    } else {
        level.to_vec()
    })
}

/// One border side of a rect and the texels it must match.
struct BorderSide {
    name: &'static str,
    /// Axis the border runs across (0: columns left/right, 1: rows top/bottom).
    axis: usize,
    /// Pairs `(border line, partner line)` along `axis`.
    pairs: Vec<(u32, u32)>,
    /// The lines of the other axis compared (the inner rectangle's).
    span: (u32, u32),
}

impl BorderSide {
    fn mean_difference(&self, img: &[u8], size: u32) -> f64 {
        let (mut sum, mut n) = (0u64, 0u64);
        let at = |x: u32, y: u32, c: usize| {
            img.get(((y as usize * size as usize) + x as usize) * 4 + c)
                .copied()
                .unwrap_or(0)
        };
        for &(b, p) in &self.pairs {
            for o in self.span.0..self.span.1 {
                let (x0, y0, x1, y1) = if self.axis == 0 {
                    (b, o, p, o)
                } else {
                    (o, b, o, p)
                };
                // Fully transparent texels carry the colour bled in from their nearest visible texel
                // (alpha trees), which depends on the neighbourhood: only their alpha is compared.
                let transparent = at(x0, y0, 3) == 0 && at(x1, y1, 3) == 0;
                for c in 0..4 {
                    if !(transparent && c < 3) {
                        sum += u64::from(at(x0, y0, c).abs_diff(at(x1, y1, c)));
                    }
                    n += 1;
                }
            }
        }
        if n == 0 { 0.0 } else { sum as f64 / n as f64 }
    }
}

/// The border sides of `rect` that a wrap rule determines: both sides of a full-period REPEAT axis
/// (partner one period away), a MIRRORED_REPEAT axis at 0 or 1 (reflection about the edge), a
/// CLAMP_TO_EDGE axis at 0 or 1 (every border line equal to the outermost; the line next to the inner
/// rectangle is left out, its filter footprint still reaches inside).
fn border_sides(rect: &RectRecord) -> Vec<BorderSide> {
    let Some(wrap) = rect.wrap() else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (k, &axis_wrap) in wrap.iter().enumerate() {
        let (o0, ow) = (rect.outer[k], rect.outer[k + 2]);
        let (i0, iw) = (rect.inner[k], rect.inner[k + 2]);
        let (i_end, o_end) = (i0 + iw, o0 + ow);
        let j = 1 - k;
        let span = (rect.inner[j], rect.inner[j] + rect.inner[j + 2]);
        let (lo, hi) = (rect.uv_min[k], rect.uv_max[k]);
        let before: Vec<u32> = (o0..i0).collect();
        let after: Vec<u32> = (i_end..o_end).collect();
        let mut push = |name, pairs: Vec<(u32, u32)>| {
            if !pairs.is_empty() {
                out.push(BorderSide {
                    name,
                    axis: k,
                    pairs,
                    span,
                });
            }
        };
        match axis_wrap {
            RectWrap::Repeat if hi - lo >= 1.0 - 1e-12 => {
                // Partner one period (iw texels) away, inside the inner rectangle when the border is
                // narrower than the period.
                let fits = |p: u32| p >= i0 && p < i_end;
                push(
                    if k == 0 {
                        "left (repeat)"
                    } else {
                        "top (repeat)"
                    },
                    before
                        .iter()
                        .map(|&b| (b, b + iw))
                        .filter(|&(_, p)| fits(p))
                        .collect(),
                );
                push(
                    if k == 0 {
                        "right (repeat)"
                    } else {
                        "bottom (repeat)"
                    },
                    after
                        .iter()
                        .map(|&b| (b, b - iw))
                        .filter(|&(_, p)| fits(p))
                        .collect(),
                );
            }
            RectWrap::Mirror => {
                if lo == 0.0 {
                    push(
                        if k == 0 {
                            "left (mirror)"
                        } else {
                            "top (mirror)"
                        },
                        before
                            .iter()
                            .map(|&b| (b, 2 * i0 - 1 - b))
                            .filter(|&(_, p)| p < i_end)
                            .collect(),
                    );
                }
                if hi == 1.0 {
                    push(
                        if k == 0 {
                            "right (mirror)"
                        } else {
                            "bottom (mirror)"
                        },
                        after
                            .iter()
                            .filter_map(|&b| (2 * i_end).checked_sub(b + 1).map(|p| (b, p)))
                            .filter(|&(_, p)| p >= i0)
                            .collect(),
                    );
                }
            }
            RectWrap::Clamp => {
                if lo == 0.0 && before.len() > 1 {
                    push(
                        if k == 0 {
                            "left (clamp)"
                        } else {
                            "top (clamp)"
                        },
                        before[1..before.len() - 1]
                            .iter()
                            .map(|&b| (b, o0))
                            .collect(),
                    );
                }
                if hi == 1.0 && after.len() > 1 {
                    push(
                        if k == 0 {
                            "right (clamp)"
                        } else {
                            "bottom (clamp)"
                        },
                        after[1..after.len() - 1]
                            .iter()
                            .map(|&b| (b, o_end - 1))
                            .collect(),
                    );
                }
            }
            _ => {}
        }
    }
    out
}
