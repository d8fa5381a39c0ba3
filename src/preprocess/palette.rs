//! Palette cells: constant-UV triangles get one rect per source texel they show (§5.2.1's 1×1 area).
//!
//! A triangle whose three UVs are equal ([`SizeMethod::AllUvEqual`]) shows one colour at every distance:
//! the source's level-0 sample at that UV (its UV derivatives are zero, so the original texture is never
//! minified). Game levels paint whole models this way from a small palette texture, a few dozen cells
//! used by thousands of triangles. Kept in one rect per (material, node) — the used part of the palette
//! at its source resolution — each such triangle read a neighbourhood of cells wherever the rect had
//! fewer texels than its source: in a leaf scaled to fit (`scale < 1`) and in every ancestor (each level
//! halves it), so it drew a mix of neighbouring palette colours with no warning (session 28's hunt: 17–28
//! dB in a leaf at scale 0.25, 12–14 dB from the root, against 59 dB at scale 1).
//!
//! Here every such triangle of a material that uses at most `limit` distinct cells (a [`SUBCELLS`]-th of a
//! source texel per axis: real palettes name each colour by one UV; a triangle whose UVs differ by float
//! noise counts, at their centre, and is stored with that one UV: [`point_of`]) gets a density class of its
//! own cell
//! ([`TriInfo::class`] = [`POINT_CLASS`] + 1 + the cell's rank among the material's), so the layout gives
//! it a point rect ([`is_cell_class`]) whose inner 1 × 1 texel is the source at that UV and whose border
//! repeats it: uniform,
//! so no leaf scale changes it, the halved levels above keep it while the rect spans a few of their
//! texels, and beyond that the shader shows the rect's mean, the same colour (`rect_texel` in
//! `shaders/tree.wgsl`: a zero footprint nearer the outer edge than its filter reaches). A material past
//! the limit keeps the one rect and is counted ([`PaletteReport::over_limit`]); the build warns.

use super::prepare::{POINT_CLASS, TriInfo};
use crate::ids::MaterialId;
use crate::model::sizing::{SizeEstimate, SizeMethod};
use crate::scene::{Scene, Wrap};
use glam::DVec2;

/// Most cells of one material kept as their own rects, whatever the atlas (see [`cell_limit`]).
pub const MAX_CELLS: u32 = 256;

/// The spread, in f32 steps of the UVs' magnitude, up to which a triangle's UVs are one UV (float noise:
/// an exporter's arithmetic, a format's rounding).
const F32_NOISE_STEPS: f64 = 8.0;

/// Cells per source texel along each axis: constant UVs within `1 / SUBCELLS` of a texel of each other
/// share a rect, others get their own (two quads on one texel at UVs `0.55` and `0.95` of it, or at float
/// noise apart, took one rect spanning the texel, which the leaf's scale then averaged with its
/// neighbours: the palette hunt of session 29). A cell's rect is a point ([`is_cell_class`]): its
/// border is its own colour to within `border / SUBCELLS` of a texel of bilinear change.
pub const SUBCELLS: u32 = 64;

/// Whether `class` is a cell's ([`assign_classes`]): its rect is a point, never widened to its source's
/// texel grid.
pub fn is_cell_class(class: i32) -> bool {
    class > POINT_CLASS && class <= POINT_CLASS + MAX_CELLS as i32
}

/// The most distinct cells of one material given rects of their own, for rects of `cell_texels` outer
/// texels (a 1 × 1 inner rect with its border) in atlases of `atlas_texels`: [`MAX_CELLS`], and at most
/// an eighth of an atlas for one material's cells, so a node holding a palette still fits others.
pub fn cell_limit(cell_texels: u64, atlas_texels: u64) -> u32 {
    let by_area = atlas_texels / 8 / cell_texels.max(1);
    by_area.min(u64::from(MAX_CELLS)) as u32
}

/// What [`assign_classes`] did, for the build report.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct PaletteReport {
    /// Materials whose constant-UV triangles got per-cell rects.
    pub materials: u64,
    /// Distinct cells of those materials (rects per node that holds them all).
    pub cells: u64,
    /// Materials past the limit: their constant-UV triangles share one rect, and scaled leaves and
    /// ancestors draw them averaged with neighbouring cells.
    pub over_limit: Vec<OverLimit>,
    /// The limit applied ([`cell_limit`]; 0 where no cell's rect fits an eighth of an atlas).
    pub limit: u32,
}

/// A material whose constant-UV triangles show more distinct texels than [`cell_limit`].
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct OverLimit {
    pub material: u32,
    /// The material's name, escaped for a terminal ([`crate::util::printable`]).
    pub name: String,
    /// Distinct cells its constant-UV triangles show.
    pub cells: u64,
}

/// The cell (a [`SUBCELLS`]-th of a source texel per axis) a constant UV `uv` (period-shifted,
/// [`super::prepare::period_shift`]) lies in, as a key: per axis the cell index in `[0, n)` for `n =
/// SUBCELLS · side` on repeat and clamp-to-edge (clamped), `[0, 2n)` on mirrored repeat (the shifted UV
/// lies in `[0, 2)`; [`assign_classes`] folds the second period back first). `None` for a non-finite UV.
pub fn cell_key(uv: DVec2, source: [u32; 2], wrap: [Wrap; 2]) -> Option<u64> {
    if !uv.is_finite() {
        return None;
    }
    let axis = |u: f64, n: u32, w: Wrap| {
        let n = u64::from(n.max(1)) * u64::from(SUBCELLS);
        let span = if w == Wrap::MirroredRepeat { 2 } else { 1 };
        let cells = n * span;
        let c = (u * n as f64).floor();
        // Also clamps a clamp-to-edge UV outside [0, 1] onto its edge cell.
        (c.max(0.0) as u64).min(cells - 1)
    };
    let (w, h) = (source[0], source[1]);
    let x = axis(uv.x, w, wrap[0]);
    let y = axis(uv.y, h, wrap[1]);
    // Row stride of the widest axis range (2n on mirrored repeat).
    Some(y * 2 * u64::from(w.max(1)) * u64::from(SUBCELLS) + x)
}

/// Gives every constant-UV record of a material with at most `limit` distinct cells the class of its
/// cell (see the module docs); `limit` 0 leaves every class as it is. Deterministic: the ranks are
/// those of the sorted cells, whatever the thread count.
pub fn assign_classes(scene: &Scene, infos: &mut [TriInfo], limit: u32) -> PaletteReport {
    use rayon::prelude::*;
    let mut report = PaletteReport {
        limit,
        ..PaletteReport::default()
    };
    let mut pairs: Vec<(MaterialId, u64)> = infos
        .par_iter()
        .filter_map(|t| point_of(scene, t).map(|p| (t.material, p.cell)))
        .collect();
    if pairs.is_empty() {
        return report;
    }
    pairs.par_sort_unstable();
    pairs.dedup();
    // Per material (by index) its sorted cells, where within the limit.
    let mut cells: Vec<Option<Vec<u64>>> = vec![None; scene.materials.len()];
    for run in pairs.chunk_by(|a, b| a.0 == b.0) {
        let (mat, n) = (run[0].0, run.len() as u64);
        if n > u64::from(limit) {
            // One cell alone in its material's rect (the limit is 0 only where no cell's rect fits an
            // atlas's eighth): a point range, drawn as its own rect would be; nothing to warn about.
            if n < 2 {
                continue;
            }
            let name = scene
                .materials
                .get(mat.idx())
                .map_or("", |m| m.name.as_str());
            report.over_limit.push(OverLimit {
                material: mat.0,
                name: crate::util::printable(name).into_owned(),
                cells: n,
            });
            continue;
        }
        report.materials += 1;
        report.cells += n;
        if let Some(slot) = cells.get_mut(mat.idx()) {
            *slot = Some(run.iter().map(|p| p.1).collect());
        }
    }
    infos.par_iter_mut().for_each(|t| {
        let Some(Some(of_mat)) = cells.get(t.material.idx()) else {
            return;
        };
        let Some(p) = point_of(scene, t) else {
            return;
        };
        if let Ok(rank) = of_mat.binary_search(&p.cell) {
            // rank < limit ≤ MAX_CELLS: far from the density classes (about −1100 ..= 1100).
            t.class = POINT_CLASS + 1 + rank as i32;
            // Its one UV, exactly (a UV spread within its cell, a mirrored period folded back).
            if p.changed {
                t.uv = [p.uv; 3];
                t.size = SizeEstimate {
                    w: 0.0,
                    h: 0.0,
                    method: SizeMethod::AllUvEqual,
                };
            }
        }
    });
    report
}

/// The one UV a triangle shows ([`Point`]), if it shows one texel's colour and has an area to show it on: a constant UV ([`SizeMethod::AllUvEqual`]), or UVs that
/// differ by float noise alone ([`F32_NOISE_STEPS`] f32 steps of their magnitude per axis), or UVs of no
/// mapping ([`SizeMethod::EdgeFallback`]: one corner moved off the others) within a [`SUBCELLS`]-th of a
/// source texel, at their centre (one f32 step of spread took a palette triangle out of its cell, 15 dB
/// where its twin with equal UVs drew 99; session 30's hunt). A well-formed mapping of a small UV patch —
/// a texel magnified over a finely tessellated terrain — is not a cell: it is drawn as sized (snapping it
/// faceted the terrain, crowded the atlas with point rects and pushed real palettes past their limit).
/// On a mirrored-repeat axis the second period `[1, 2)` folds back to `2 − u`, the same texel (a cell
/// drawn at `u` and at `2 − u` took two cells).
fn point_of(scene: &Scene, t: &TriInfo) -> Option<Point> {
    let mat = scene.materials.get(t.material.idx())?;
    let img = scene.images.get(mat.image.idx())?;
    let constant = t.size.method == SizeMethod::AllUvEqual;
    // A triangle of no world area draws nothing: no cell of its own (two such on sandtrack took two).
    if t.size.method == SizeMethod::WorldDegenerate {
        return None;
    }
    let uv = if constant {
        t.uv[0]
    } else {
        let lo = t.uv[0].min(t.uv[1]).min(t.uv[2]);
        let hi = t.uv[0].max(t.uv[1]).max(t.uv[2]);
        let texels = (hi - lo) * DVec2::new(f64::from(img.width), f64::from(img.height));
        // Float noise: a few f32 steps of the UVs' magnitude, whatever the sizing made of it.
        let noise = F32_NOISE_STEPS
            * f64::from(f32::EPSILON)
            * lo.abs().max(hi.abs()).max_element().max(1.0);
        // UVs that name no mapping (edge fallback: rank-deficient) within a cell.
        let cell = t.size.method == SizeMethod::EdgeFallback
            && texels.max_element() <= 1.0 / f64::from(SUBCELLS);
        if !(texels.is_finite() && ((hi - lo).max_element() <= noise || cell)) {
            return None;
        }
        (lo + hi) * 0.5
    };
    if !uv.is_finite() {
        return None;
    }
    let fold = |u: f64, w: Wrap| {
        if w == Wrap::MirroredRepeat && u > 1.0 {
            2.0 - u
        } else {
            u
        }
    };
    let folded = DVec2::new(fold(uv.x, mat.wrap[0]), fold(uv.y, mat.wrap[1]));
    Some(Point {
        cell: cell_key(folded, [img.width, img.height], mat.wrap)?,
        uv: folded,
        changed: !constant || folded != uv,
    })
}

/// The one UV a triangle shows ([`point_of`]): its cell ([`cell_key`]), the UV, and whether the
/// triangle's stored UVs differ from it.
struct Point {
    cell: u64,
    uv: DVec2,
    changed: bool,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cell_keys_name_the_subtexel_cell_a_constant_uv_lies_in() {
        let rep = [Wrap::Repeat; 2];
        // A 2 × 1 source: 128 × 64 cells, rows of 256 keys.
        let k = |u: f64, v: f64, wrap| cell_key(DVec2::new(u, v), [2, 1], wrap);
        let s = f64::from(SUBCELLS);
        // Within a 64th of a texel: one cell; a texel's centre and its 0.95 are not.
        assert_eq!(k(0.0, 0.0, rep), Some(0));
        assert_eq!(k(0.9 / s / 2.0, 0.9 / s, rep), Some(0));
        assert_eq!(k(0.25, 0.5, rep), Some(32 * 256 + 32));
        assert_ne!(k(0.25, 0.5, rep), k(0.475, 0.5, rep));
        // The last cell, and a UV of exactly 1 (a period shift's upper end) on it too.
        assert_eq!(k(1.0, 1.0, rep), Some(63 * 256 + 127));
        // Clamp-to-edge: outside [0, 1] the edge cells.
        let clamp = [Wrap::ClampToEdge; 2];
        assert_eq!(k(-3.0, 5.0, clamp), Some(63 * 256));
        // Mirrored repeat: the second period has cells of its own.
        let mirror = [Wrap::MirroredRepeat; 2];
        assert_eq!(k(1.0 + 0.5 / s / 2.0, 0.0, mirror), Some(128));
        assert_eq!(k(f64::NAN, 0.0, rep), None);
        // Cell classes are told from the density classes and the point class.
        assert!(is_cell_class(POINT_CLASS + 1) && is_cell_class(POINT_CLASS + MAX_CELLS as i32));
        assert!(!is_cell_class(POINT_CLASS) && !is_cell_class(0) && !is_cell_class(-1100));
    }

    #[test]
    fn the_limit_leaves_an_eighth_of_an_atlas() {
        // Border 8: a 1 × 1 inner rect is 20 × 20 outer.
        assert_eq!(cell_limit(400, 1024 * 1024), 256);
        assert_eq!(cell_limit(400, 512 * 512), 81);
        assert_eq!(cell_limit(400, 64 * 64), 1);
        assert_eq!(cell_limit(400, 32 * 32), 0);
        assert_eq!(cell_limit(0, 32 * 32), 128);
    }
}
