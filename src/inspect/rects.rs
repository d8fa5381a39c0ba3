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

/// A period (texels, along the axis a border runs across) shorter than two 4×4 blocks: every block that
/// holds its border holds some of its inner texels too, so block compression moves the border and its
/// partner by as much as it moves the texture's own detail.
const SMALL_BLOCK_PERIOD: u32 = 8;

/// Mean difference (the metric of [`BorderSide::mean_difference`]) between neighbouring texels inside
/// `inner` (`[x, y, w, h]`), along both axes: how much detail a 4×4 block's few colours must flatten.
fn neighbour_contrast(img: &[u8], size: u32, inner: [u32; 4]) -> f64 {
    let at = |x: u32, y: u32| texel(img, size, x, y);
    let [x0, y0, w, h] = inner;
    let (mut sum, mut n) = (0.0f64, 0u64);
    for y in y0..y0 + h {
        for x in x0..x0 + w {
            let u = at(x, y);
            let right = (x + 1 < x0 + w).then(|| at(x + 1, y));
            let below = (y + 1 < y0 + h).then(|| at(x, y + 1));
            for v in [right, below].into_iter().flatten() {
                sum += texel_difference(u, v);
                n += 4;
            }
        }
    }
    if n == 0 { 0.0 } else { sum / n as f64 }
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
    let f = f_proj * leaf.clamp_scale;
    let need = texels_per_uv(pos, uv, f);
    if need.method != SizeMethod::Exact {
        return;
    }
    let slack = storage_slack(pos, uv, f, [need.w, need.h]);
    let a = rect.decode();
    let tpu = a.texels_per_uv();
    for (k, want) in [need.w, need.h].into_iter().enumerate() {
        // A collapsed axis (UVs wholly outside a clamp-to-edge texture: every sample reads its edge
        // line) holds no period; one texel is exact there.
        let collapsed = a.uv_max[k] == a.uv_min[k];
        if a.capped[k] || want <= 0.0 || collapsed {
            continue;
        }
        // What the file's f32 storage can tell: the build sized the f64 triangle, which may need up to
        // `slack` less. A need within the slack is not decidable from the file.
        let want = want - slack[k];
        if want <= 0.0 {
            r.periods_undecidable += 1;
            continue;
        }
        let ratio = tpu[k] / want;
        r.periods_checked += 1;
        r.period_ratio_min = Some(r.period_ratio_min.map_or(ratio, |m| m.min(ratio)));
        if ratio < 1.0 - PERIOD_TOLERANCE {
            r.fail(format!(
                "rect of material {} axis {k}: {:.3} texels per period but a triangle needs {want:.3} at the \
                 leaf's min_distance",
                rect.material, tpu[k]
            ));
        }
    }
}

/// Per UV axis, a bound on how much the f32 storage of the leaf-relative positions and the shifted UVs
/// (each coordinate within 2⁻²⁴ of its magnitude) can change [`texels_per_uv`]'s texels per period
/// (times `f`): first-order perturbation of `J = E·D⁻¹` (world edges `E`, UV edges `D`), column `k`:
/// `|ΔE·D⁻¹e_k| + |J|·|ΔD·D⁻¹e_k|`. Negligible for ordinary triangles; for a centimetre triangle two
/// kilometres from its leaf's origin with near-parallel UV edges (the all-tracks world's scaled leaves
/// span kilometres) it exceeds the need itself.
fn storage_slack(pos: [DVec3; 3], uv: [DVec2; 3], f: f64, need: [f64; 2]) -> [f64; 2] {
    let unit = 2f64.powi(-24);
    let m = pos
        .iter()
        .map(|p| p.abs().max_element())
        .fold(0.0, f64::max);
    let mu = uv.iter().map(|t| t.abs().max_element()).fold(0.0, f64::max);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let det = d1.perp_dot(d2).abs();
    if det == 0.0 {
        return [f64::INFINITY; 2];
    }
    // D⁻¹ = [[d2.y, −d2.x], [−d1.y, d1.x]] / det: column k weights edge 1 and edge 2.
    let cols = [
        (d2.y.abs() + d1.y.abs()) / det,
        (d2.x.abs() + d1.x.abs()) / det,
    ];
    // An edge is a difference of two rounded corners: per component ≤ 2·m·u, per edge ≤ 2√3·m·u.
    let de = 2.0 * 3f64.sqrt() * m * unit;
    let dd = 2.0 * 2f64.sqrt() * mu.max(1.0) * unit;
    // |J|_F times f.
    let j = need[0].hypot(need[1]);
    [0, 1].map(|k| (f * de + j * dd) * cols[k])
}

/// Compares every wrap border of every leaf atlas (level 0) with what the sampler's rule puts there.
pub(super) fn verify_wrap_borders(file: &TreeFile, r: &mut VerifyReport) {
    let (size, border) = (file.params().atlas_size, file.params().border);
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
            let level0 = level0_rgba8(format, &bytes, size);
            let Some(img) = level0 else {
                r.fail(format!(
                    "tree {ti} leaf {li}: atlas block {} does not decode",
                    node.atlas_block
                ));
                continue;
            };
            for (ri, rect) in rects.iter().enumerate() {
                // Measured once a rect, where a side needs it.
                let mut contrast = None;
                for side in border_sides(rect) {
                    let mean = side.mean_difference(&img, size);
                    r.wrap_borders_checked += 1;
                    r.wrap_border_mean_max = r.wrap_border_mean_max.max(mean);
                    // A period under two blocks, or a border under one: the texture's own detail,
                    // flattened by the blocks a border shares with it, is part of what the border may
                    // differ by (a 5×7 noise texture: 21 levels in BC1, a 3-texel alpha-tested one 27.6
                    // in BC7; a 64² one at --border 1: 18). A longer period's share is capped at twice
                    // the format's own allowance (a wrong border of a noisy texture differs by more).
                    let small = rect.inner[side.axis + 2] < SMALL_BLOCK_PERIOD;
                    let tol = if format.is_compressed() && (small || border < 4) {
                        let c = *contrast
                            .get_or_insert_with(|| neighbour_contrast(&img, size, rect.inner));
                        tol + if small { c } else { c.min(2.0 * tol) }
                    } else {
                        tol
                    };
                    if mean > tol {
                        r.fail(format!(
                            "tree {ti} leaf {li} rect {ri}: {} border differs from the sampler's rule by {mean:.2} \
                             sRGB levels on average (tolerance {tol:.2} for {})",
                            side.name,
                            format.name()
                        ));
                    }
                }
            }
        }
    }
}

/// Every rect's stored mean ([`crate::model::AtlasRect::mean`]) against the one its leaf's stored atlas
/// gives ([`crate::texfmt::rect_means`], what the writer measured: equal, else a violation), and against
/// the mean of its level-0 texels ([`crate::texfmt::area_mean`]: the largest difference is reported).
pub(super) fn verify_rect_means(file: &TreeFile, r: &mut VerifyReport) {
    let size = file.params().atlas_size;
    for ti in 0..file.trees() {
        let Some(t) = file.tree(ti) else { continue };
        let format = t.format();
        for (li, l) in t.leaves.iter().enumerate() {
            let rects = t.leaf_rects(l);
            let Some(node) = t.nodes.get(l.node as usize) else {
                continue;
            };
            let Ok(bytes) = file.block(crate::ids::BlockId(node.atlas_block)) else {
                continue; // a bad checksum is reported by the block pass
            };
            let inners: Vec<[u32; 4]> = rects.iter().map(|x| x.inner).collect();
            let exact = t.kind == crate::model::TreeKind::Alpha;
            // `None` for a block that is not one atlas chain (what the writer measures no mean on).
            let means = crate::texfmt::rect_means(format, &bytes, size, &inners, exact);
            let (Some(means), Some(level0)) = (means, level0_rgba8(format, &bytes, size)) else {
                r.fail(format!(
                    "tree {ti} leaf {li}: atlas block {} is not one atlas chain of {} (its rects have no mean)",
                    node.atlas_block,
                    format.name()
                ));
                continue;
            };
            for (ri, (rect, mean)) in rects.iter().zip(means).enumerate() {
                r.rect_means_checked += 1;
                if rect.mean != mean {
                    r.fail(format!(
                        "tree {ti} leaf {li} rect {ri}: stored mean {:?}, its atlas gives {mean:?}",
                        rect.mean
                    ));
                }
                let [x, y, w, h] = rect.inner.map(f64::from);
                let exact = crate::texfmt::area_mean(&level0, size, size, [x, y, x + w, y + h]);
                let diff = (exact.iter().zip(&mean)).map(|(a, b)| u32::from(a.abs_diff(*b)));
                r.rect_mean_level0_max = r.rect_mean_level0_max.max(diff.max().unwrap_or(0));
            }
        }
    }
}

/// Level 0 of an atlas block as RGBA8 texels.
fn level0_rgba8(format: TexFormat, bytes: &[u8], size: u32) -> Option<Vec<u8>> {
    super::atlases::level_rgba8(format, bytes, size, 0)
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
    /// Mean difference per channel, sRGB8 levels, of each border line against its partner: colour
    /// premultiplied by alpha (`|c₀·a₀ − c₁·a₁| / 255`: what blending or the alpha test can show; fully
    /// transparent texels carry the colour bled in from their nearest visible texel, which depends on the
    /// neighbourhood and shows nowhere), alpha as stored. Block compression's colour error under low alpha
    /// (a semi-transparent foliage period of 19 texels in BC3: 16.1 levels straight, the border itself
    /// exact uncompressed) does not count beyond what it shows.
    fn mean_difference(&self, img: &[u8], size: u32) -> f64 {
        let (mut sum, mut n) = (0.0f64, 0u64);
        for &(b, p) in &self.pairs {
            for o in self.span.0..self.span.1 {
                let (x0, y0, x1, y1) = if self.axis == 0 {
                    (b, o, p, o)
                } else {
                    (o, b, o, p)
                };
                sum += texel_difference(texel(img, size, x0, y0), texel(img, size, x1, y1));
                n += 4;
            }
        }
        if n == 0 { 0.0 } else { sum / n as f64 }
    }
}

/// Texel `(x, y)` of an RGBA8 image `size` texels wide (zeros outside it).
fn texel(img: &[u8], size: u32, x: u32, y: u32) -> [i32; 4] {
    let i = ((y as usize * size as usize) + x as usize) * 4;
    let t = img.get(i..i + 4).unwrap_or(&[0; 4]);
    [t[0], t[1], t[2], t[3]].map(i32::from)
}

/// The summed difference of two texels over their four channels, sRGB8 levels: colour premultiplied by
/// alpha, alpha as stored ([`BorderSide::mean_difference`]'s metric).
fn texel_difference(u: [i32; 4], v: [i32; 4]) -> f64 {
    let colour: f64 = (0..3)
        .map(|c| f64::from((u[c] * u[3] - v[c] * v[3]).abs()) / 255.0)
        .sum();
    colour + f64::from((u[3] - v[3]).abs())
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

#[cfg(test)]
mod tests {
    use super::*;

    /// Three triangles of the all-tracks world as its file stores them (leaf-relative f32 positions,
    /// shifted UVs), each a few centimetres wide and 0.4–2.1 km from its leaf's origin, whose need
    /// recomputed from the file was 0.3–43 % above what the build sized in f64.
    fn stored() -> [([DVec3; 3], [DVec2; 3]); 3] {
        [
            (
                [
                    DVec3::new(388.7140808105469, 66.60296630859375, 17.29596710205078),
                    DVec3::new(388.6571044921875, 66.66885375976563, 17.276039123535156),
                    DVec3::new(388.6639099121094, 66.66108703613281, 17.278223037719727),
                ],
                [
                    DVec2::new(0.6416015625, 0.572265625),
                    DVec2::new(0.646484375, 0.54443359375),
                    DVec2::new(0.64599609375, 0.54736328125),
                ],
            ),
            (
                [
                    DVec3::new(586.8795776367188, 72.95427703857422, -168.85842895507813),
                    DVec3::new(586.8032836914063, 72.97328186035156, -168.85308837890625),
                    DVec3::new(586.789306640625, 72.97584533691406, -168.8524169921875),
                ],
                [
                    DVec2::new(0.2841796875, 0.529296875),
                    DVec2::new(0.288330078125, 0.50830078125),
                    DVec2::new(0.2890625, 0.5048828125),
                ],
            ),
            (
                [
                    DVec3::new(2102.824462890625, -38.294010162353516, -111.39128112792969),
                    DVec3::new(2102.798828125, -38.29388427734375, -111.39128112792969),
                    DVec3::new(2102.79931640625, -38.29386520385742, -111.39128112792969),
                ],
                [
                    DVec2::new(0.233642578125, 0.20166015625),
                    DVec2::new(0.247314453125, 0.2015380859375),
                    DVec2::new(0.2471923828125, 0.2015380859375),
                ],
            ),
        ]
    }

    /// Any f64 triangle that rounds to the stored one needs within `storage_slack` of what the stored
    /// one needs (checked on random such triangles: every coordinate moved by up to half an f32 ulp).
    #[test]
    fn storage_slack_bounds_what_f32_rounding_moves() {
        let f = 3.04;
        let mut rng = crate::util::XorShift64::new(7);
        let mut unit = || (rng.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0;
        let half_ulp = |x: f64| (x as f32).abs() as f64 * 2f64.powi(-24);
        let mut worst = 0.0f64;
        for (pos, uv) in stored() {
            let need = texels_per_uv(pos, uv, f);
            let slack = storage_slack(pos, uv, f, [need.w, need.h]);
            for _ in 0..2000 {
                let p = pos.map(|v| {
                    DVec3::new(
                        v.x + unit() * half_ulp(v.x),
                        v.y + unit() * half_ulp(v.y),
                        v.z + unit() * half_ulp(v.z),
                    )
                });
                let t = uv.map(|v| {
                    DVec2::new(v.x + unit() * half_ulp(v.x), v.y + unit() * half_ulp(v.y))
                });
                let truth = texels_per_uv(p, t, f);
                for (k, (a, b)) in [(need.w, truth.w), (need.h, truth.h)]
                    .into_iter()
                    .enumerate()
                {
                    assert!(
                        (a - b).abs() <= slack[k],
                        "axis {k}: {a} vs {b}, slack {}",
                        slack[k]
                    );
                    worst = worst.max((a - b).abs() / slack[k]);
                }
            }
        }
        // The bound is not vacuous: random roundings reach a good share of it.
        assert!(worst > 0.05, "worst share of the slack {worst}");
    }

    /// An ordinary triangle near its leaf's origin keeps a slack far below the 1e-3 tolerance.
    #[test]
    fn storage_slack_is_negligible_for_ordinary_triangles() {
        let pos = [
            DVec3::new(1.0, 0.0, 2.0),
            DVec3::new(3.0, 0.0, 2.0),
            DVec3::new(1.0, 0.0, 4.0),
        ];
        let uv = [DVec2::ZERO, DVec2::new(1.0, 0.0), DVec2::new(0.0, 1.0)];
        let need = texels_per_uv(pos, uv, 100.0);
        let slack = storage_slack(pos, uv, 100.0, [need.w, need.h]);
        assert!(
            slack[0] < 1e-5 * need.w && slack[1] < 1e-5 * need.h,
            "{slack:?} {need:?}"
        );
    }
}
