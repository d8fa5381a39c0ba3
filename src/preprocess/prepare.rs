//! Per-triangle preparation shared by every node of a build: sizing (§5.2.1), the per-triangle UV period
//! shift, world area and plane midpoint (§5.3). Computed once, then only indexed.

use crate::ids::MaterialId;
use crate::model::sizing::{SizeEstimate, SizeMethod, texels_per_uv};
use crate::scene::{Scene, UpAxis, Wrap};
use glam::{DVec2, DVec3};

/// What the builder knows about one triangle (or one piece of a tessellated scene triangle).
///
/// Laid out for the layout's passes, which visit the records in midpoint order (random in memory): the
/// fields the split and the leaf needs read ([`TriInfo::SPLIT_BYTES`]: midpoint, material, class, size,
/// UVs) come first, and 32-byte alignment (128-byte records) keeps them within two cache lines of every
/// record, the midpoint within one; [`walk_prefix`] fetches only those lines. The corners are not stored
/// here: a whole scene triangle's are the scene's, a cut piece's are in [`Prepared::pieces`] ([`Corners`]:
/// 64 bytes a triangle less in the plan).
#[derive(Copy, Clone, Debug)]
#[repr(C, align(32))]
pub struct TriInfo {
    /// Midpoint in the distribution plane (the split sorts on it, §5.3).
    pub mid: DVec2,
    pub material: MaterialId,
    /// Density class: `floor(log2(texels per repetition))` after the source cap, [`POINT_CLASS`] for
    /// triangles with no density (constant UVs, world-degenerate). A node atlas gets one area per
    /// (material, class), so a few dense triangles cannot inflate the area of a material's many sparse ones.
    pub class: i32,
    /// Required texels per UV unit at d_min (already multiplied by f_proj).
    pub size: SizeEstimate,
    /// The UVs after the period shift (see [`period_shift`]).
    pub uv: [DVec2; 3],
    /// World-space area (the split balances it, §5.3).
    pub area: f64,
    /// Index of the triangle in `Scene::triangles` this triangle is (a piece of).
    pub scene_tri: u32,
    /// Where a cut piece's own corners are in [`Prepared::pieces`]; [`WHOLE`] for a whole scene triangle
    /// (its corners are the scene's). In the record's padding: no byte more.
    pub piece: u32,
}

/// [`TriInfo::piece`] of a whole scene triangle.
pub const WHOLE: u32 = u32::MAX;

const _: () = {
    assert!(std::mem::size_of::<TriInfo>() == 128);
    assert!(TriInfo::SPLIT_BYTES == 96 && TriInfo::MID_BYTES == 16);
};

impl TriInfo {
    /// Bytes from a record's start that the demand passes and the leaf needs read: midpoint, material,
    /// class, size and UVs.
    pub const SPLIT_BYTES: usize = std::mem::offset_of!(TriInfo, area);
    /// Bytes from a record's start that hold the midpoint.
    pub const MID_BYTES: usize = std::mem::offset_of!(TriInfo, material);
}

/// How many records ahead of its use [`walk`] prefetches: enough to cover a memory latency (~100 ns)
/// at the few ns a pass spends per triangle.
pub const PREFETCH_AHEAD: usize = 16;

/// `infos[i]` for every `i` of `items`, in order, each record prefetched [`PREFETCH_AHEAD`] items
/// before it is used. The layout visits a node's triangles in midpoint order, which is random in memory:
/// without the hint its passes wait on ~3 cache misses a triangle (`perf annotate` of the demand pass:
/// ~80 % of its samples on the loads of `material`, `uv` and `size`).
pub fn walk<'a>(infos: &'a [TriInfo], items: &'a [u32]) -> impl Iterator<Item = &'a TriInfo> + 'a {
    walk_prefix(infos, items, std::mem::size_of::<TriInfo>())
}

/// [`walk`] for a pass that reads only the first `bytes` of each record ([`TriInfo::SPLIT_BYTES`],
/// [`TriInfo::MID_BYTES`]): only their cache lines are prefetched (2 and 1 of a record's 3–4), so the
/// memory system carries what the pass reads.
pub fn walk_prefix<'a>(
    infos: &'a [TriInfo],
    items: &'a [u32],
    bytes: usize,
) -> impl Iterator<Item = &'a TriInfo> + 'a {
    items.iter().enumerate().map(move |(k, &i)| {
        if let Some(ahead) = items
            .get(k + PREFETCH_AHEAD)
            .and_then(|&a| infos.get(a as usize))
        {
            crate::util::prefetch_prefix(ahead, bytes);
        }
        &infos[i as usize]
    })
}

/// Density class of triangles without a density (constant UVs, world-degenerate).
pub const POINT_CLASS: i32 = i32::MIN;

/// The density class of a triangle needing `w × h` texels per repetition (already capped).
pub fn density_class(w: f64, h: f64, method: SizeMethod) -> i32 {
    let d = w.max(h);
    match method {
        SizeMethod::Exact | SizeMethod::EdgeFallback if d.is_finite() && d > 0.0 => {
            d.log2().floor() as i32
        }
        _ => POINT_CLASS,
    }
}

/// The whole-period shift that moves a triangle's UVs next to the origin without changing what it shows:
/// by `floor(min)` on repeat axes, by an even integer on mirrored axes, not at all on clamped axes.
///
/// This bounds the atlas area A_tex of a texture in a node to `[0, 1 + max triangle span]` instead of the
/// union of all repetitions the scene happens to use (the paper copies the whole union, §5.2.2), and keeps
/// stored original UVs small enough for f32 (UV offsets of 1e5 or −2.9e9 occur in real data). Per axis the
/// shift of the triangle's lowest UV by the sampler's rule (`image_ops::period_shift`, the raster's too).
pub fn period_shift(uv: [DVec2; 3], wrap: [Wrap; 2]) -> DVec2 {
    let lo = uv[0].min(uv[1]).min(uv[2]);
    let axis = super::image_ops::period_shift;
    DVec2::new(axis(lo.x, wrap[0]), axis(lo.y, wrap[1]))
}

/// Options of [`prepare`].
#[derive(Clone, Debug)]
pub struct PrepareOptions {
    /// Texels per world unit at d_min.
    pub f_proj: f64,
    pub up: UpAxis,
    /// Cap texels per repetition at the source resolution (as the area stage does).
    pub cap_to_source: bool,
    /// A triangle whose texel footprint exceeds this on either texture axis is split (texels).
    pub split_limit: f64,
    /// At most this many pieces per scene triangle; beyond, the layout clamps the piece's resolution.
    pub max_pieces: u32,
    /// Repeats are wrapped in the shader ([`super::RepeatMode::Wrap`]): a rect holds at most one period,
    /// so no triangle is cut for its UV range and every triangle of a material shares one density class
    /// (one rect per material and node, at the largest density its triangles need).
    pub wrap: bool,
    /// Most distinct cells (64ths of a source texel) a material's constant UVs may lie in and still get a
    /// rect per cell ([`super::palette::cell_limit`]; 0: none, every material with two or more is over).
    pub palette_cells: u32,
}

impl PrepareOptions {
    /// The most pieces a triangle becomes: `max_pieces` where repeats are baked, 1 where they wrap (no
    /// triangle is cut for its UV range). [`prepare`] and its count [`count_pieces`] read this one rule.
    fn max_pieces_used(&self) -> u32 {
        if self.wrap { 1 } else { self.max_pieces }
    }
}

/// Prepares the triangles `tris` (indices into `scene.triangles`) for a build. Parallel over triangles.
///
/// With repeats baked (`!opts.wrap`), triangles whose texture footprint at d_min is larger than
/// `split_limit` texels on a texture axis (a ground quad with a tile repeated hundreds of times, a long
/// wall) are split at the midpoint of their
/// longest edge, measured in texels, until every piece fits (bounded by `max_pieces`). Splitting is exact
/// (positions and UVs are affine on a triangle), keeps `min_distance = d_min` for their leaves, and lets the
/// pieces spread over several leaves. Without it the paper loops forever, and plain clamping would coarsen
/// every ancestor of that leaf (`min_distance` doubles upwards from the clamped value).
pub fn prepare(scene: &Scene, tris: &[u32], opts: &PrepareOptions) -> Prepared {
    use rayon::prelude::*;
    let max_pieces = opts.max_pieces_used();
    if max_pieces <= 1 {
        // One piece a triangle (`tessellate` returns its input): an indexed map collects in place, where
        // the flat map below collects per task and then copies every record once more (~1 s and 4.4 GB
        // moved for the 24 M triangles of the all-tracks world tiled 2 × 2).
        let mut infos: Vec<TriInfo> = tris
            .par_iter()
            .map(|&ti| {
                let s = SizedTriangle::of(scene, ti, opts);
                s.piece(s.pos, s.uv, opts)
            })
            .collect();
        let palette = super::palette::assign_classes(scene, &mut infos, opts.palette_cells);
        return Prepared {
            infos,
            pieces: Vec::new(),
            palette,
        };
    }
    // Every record with its corners, a cut piece's marked (`piece` 0 for now); then only the cut
    // pieces' corners are kept, in order (a triangle `tessellate` returns whole has the scene's).
    let (mut infos, mut pieces): (Vec<TriInfo>, Vec<[DVec3; 3]>) = tris
        .par_iter()
        .flat_map_iter(|&ti| {
            let s = SizedTriangle::of(scene, ti, opts);
            let parts = tessellate(s.pos, s.uv, s.w, s.h, opts.split_limit, max_pieces);
            let cut = parts.len() > 1;
            parts.into_iter().map(move |(p, uv0)| {
                let mut t = s.piece(p, uv0, opts);
                if cut {
                    t.piece = 0;
                }
                (t, p)
            })
        })
        .unzip();
    let mut kept = 0;
    for (i, t) in infos.iter_mut().enumerate() {
        if t.piece != WHOLE {
            pieces[kept] = pieces[i];
            t.piece = kept as u32;
            kept += 1;
        }
    }
    pieces.truncate(kept);
    pieces.shrink_to_fit();
    let palette = super::palette::assign_classes(scene, &mut infos, opts.palette_cells);
    Prepared {
        infos,
        pieces,
        palette,
    }
}

/// How many records [`prepare`] makes of `tris` (with repeats baked, the pieces [`tessellate`] cuts),
/// without making them: the memory budget counts them before they exist (a baked build of 2,048
/// triangles accepted under `--max-memory 300MiB` made millions of pieces and peaked at 1.08 GiB; fault
/// hunt, session 32). Parallel over triangles.
pub fn count_pieces(scene: &Scene, tris: &[u32], opts: &PrepareOptions) -> u64 {
    use rayon::prelude::*;
    let max_pieces = opts.max_pieces_used();
    if max_pieces <= 1 {
        return tris.len() as u64;
    }
    tris.par_iter()
        .map(|&ti| {
            let s = SizedTriangle::of(scene, ti, opts);
            let n = tessellate_count(s.uv, s.w, s.h, opts.split_limit, max_pieces);
            n as u64
        })
        .sum()
}

/// The number of pieces [`tessellate`] returns for these arguments, by the same cuts ([`cut`]) of the
/// UVs alone (its analyzer twin: no positions, no pieces kept).
fn tessellate_count(uv: [DVec2; 3], w: f64, h: f64, limit: f64, max_pieces: u32) -> usize {
    let mut n = 0;
    cut(
        [(); 3],
        uv,
        (w, h, limit, max_pieces),
        |_, _| (),
        |_, _| n += 1,
    );
    n
}

/// The prepared triangles of a tree ([`prepare`]).
pub struct Prepared {
    pub infos: Vec<TriInfo>,
    /// The corners of the cut pieces (repeats baked), where [`TriInfo::piece`] says; a whole scene
    /// triangle's corners are the scene's.
    pub pieces: Vec<[DVec3; 3]>,
    /// The constant-UV triangles given per-texel classes ([`super::palette`]).
    pub palette: super::palette::PaletteReport,
}

impl Prepared {
    /// Where the corners of these records are read.
    pub fn corners<'a>(&'a self, scene: &'a Scene) -> Corners<'a> {
        Corners {
            scene,
            pieces: &self.pieces,
        }
    }
}

/// The world corners of prepared records: the scene triangle's, or the cut piece's own.
#[derive(Copy, Clone)]
pub struct Corners<'a> {
    scene: &'a Scene,
    pieces: &'a [[DVec3; 3]],
}

impl Corners<'_> {
    /// The corners of record `t`.
    #[inline]
    pub fn of(&self, t: &TriInfo) -> [DVec3; 3] {
        if t.piece == WHOLE {
            self.scene
                .tri_positions(&self.scene.triangles[t.scene_tri as usize])
        } else {
            self.pieces[t.piece as usize]
        }
    }
}

/// A scene triangle sized for [`prepare`]: its corners and UVs, material, density and class.
struct SizedTriangle {
    ti: u32,
    material: MaterialId,
    wrap: [Wrap; 2],
    pos: [DVec3; 3],
    uv: [DVec2; 3],
    size: SizeEstimate,
    /// Texels per UV unit after the source cap.
    w: f64,
    h: f64,
    class: i32,
}

impl SizedTriangle {
    fn of(scene: &Scene, ti: u32, opts: &PrepareOptions) -> SizedTriangle {
        let t = &scene.triangles[ti as usize];
        let pos = scene.tri_positions(t);
        let uv = scene.tri_uvs(t);
        let mat = &scene.materials[t.material.idx()];
        let img = &scene.images[mat.image.idx()];
        let size = texels_per_uv(pos, uv, opts.f_proj);
        let (mut w, mut h) = (size.w, size.h);
        if opts.cap_to_source {
            w = w.min(f64::from(img.width));
            h = h.min(f64::from(img.height));
        }
        let class = if opts.wrap {
            0
        } else {
            density_class(w, h, size.method)
        };
        SizedTriangle {
            ti,
            material: t.material,
            wrap: mat.wrap,
            pos,
            uv,
            size,
            w,
            h,
            class,
        }
    }

    /// The record of the piece with corners `p` and UVs `uv0` (the whole triangle or a part of it).
    fn piece(&self, p: [DVec3; 3], uv0: [DVec2; 3], opts: &PrepareOptions) -> TriInfo {
        let shift = period_shift(uv0, self.wrap);
        let uv = uv0.map(|u| u - shift);
        let area = 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let mid = opts.up.plane((p[0] + p[1] + p[2]) / 3.0);
        TriInfo {
            scene_tri: self.ti,
            piece: WHOLE,
            material: self.material,
            mid: if mid.is_finite() { mid } else { DVec2::ZERO },
            area: if area.is_finite() { area } else { 0.0 },
            size: self.size,
            class: self.class,
            uv,
        }
    }
}

/// Texel length of a UV edge at `w × h` texels per UV unit.
fn texel_len(d: DVec2, w: f64, h: f64) -> f64 {
    ((d.x * w).powi(2) + (d.y * h).powi(2)).sqrt()
}

/// Splits a triangle at the midpoint of its longest edge (in texels) until each piece's UV bounding box
/// spans at most `limit` texels on both axes, or `max_pieces` pieces exist. Pieces tile the triangle
/// exactly (same plane, same affine UV map). Non-finite inputs are returned unsplit.
pub fn tessellate(
    p: [DVec3; 3],
    uv: [DVec2; 3],
    w: f64,
    h: f64,
    limit: f64,
    max_pieces: u32,
) -> Vec<([DVec3; 3], [DVec2; 3])> {
    let mut out = Vec::new();
    let mid = |a: DVec3, b: DVec3| (a + b) * 0.5;
    cut(p, uv, (w, h, limit, max_pieces), mid, |p, uv| {
        out.push((p, uv))
    });
    out
}

/// The cuts of [`tessellate`] and [`tessellate_count`], one rule for both: a triangle of corners `p` (any
/// payload, split at an edge's midpoint by `mid`) and UVs `uv` at `w × h` texels per UV unit, halved at its
/// longest edge in texels until each piece spans at most `limit` texels on both axes or `max_pieces`
/// exist; `emit` gets every piece in order.
fn cut<T: Copy>(
    p: [T; 3],
    uv: [DVec2; 3],
    (w, h, limit, max_pieces): (f64, f64, f64, u32),
    mid: impl Fn(T, T) -> T,
    mut emit: impl FnMut([T; 3], [DVec2; 3]),
) {
    let too_big = |uv: &[DVec2; 3]| {
        let lo = uv[0].min(uv[1]).min(uv[2]);
        let hi = uv[0].max(uv[1]).max(uv[2]);
        (hi.x - lo.x) * w > limit || (hi.y - lo.y) * h > limit
    };
    let finite = w.is_finite() && h.is_finite() && limit > 0.0 && uv.iter().all(|u| u.is_finite());
    if !finite || !too_big(&uv) {
        emit(p, uv);
        return;
    }
    let mut done = 0;
    let mut todo = vec![(p, uv)];
    while let Some((p, uv)) = todo.pop() {
        if !too_big(&uv) || done + todo.len() + 2 > max_pieces as usize {
            done += 1;
            emit(p, uv);
            continue;
        }
        let len = |i: usize| texel_len(uv[(i + 1) % 3] - uv[i], w, h);
        let e = (0..3)
            .max_by(|&a, &b| len(a).total_cmp(&len(b)))
            .unwrap_or(0);
        let (a, b, c) = (e, (e + 1) % 3, (e + 2) % 3);
        let pm = mid(p[a], p[b]);
        let um = (uv[a] + uv[b]) * 0.5;
        todo.push(([p[a], pm, p[c]], [uv[a], um, uv[c]]));
        todo.push(([pm, p[b], p[c]], [um, uv[b], uv[c]]));
    }
}

/// Counts of sizing methods over prepared triangles (the report twin of [`prepare`]).
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PrepareReport {
    pub triangles: u64,
    pub exact: u64,
    pub edge_fallback: u64,
    pub all_uv_equal: u64,
    pub world_degenerate: u64,
    /// The constant-UV triangles' per-cell rects ([`Prepared::palette`]).
    pub palette: super::palette::PaletteReport,
}

pub fn analyze(prepared: &Prepared) -> PrepareReport {
    let infos = &prepared.infos;
    let mut r = PrepareReport {
        triangles: infos.len() as u64,
        palette: prepared.palette.clone(),
        ..Default::default()
    };
    for t in infos {
        match t.size.method {
            SizeMethod::Exact => r.exact += 1,
            SizeMethod::EdgeFallback => r.edge_fallback += 1,
            SizeMethod::AllUvEqual => r.all_uv_equal += 1,
            SizeMethod::WorldDegenerate => r.world_degenerate += 1,
        }
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 400 × 300 m right triangle over 95 × 55 repetitions.
    fn big_triangle() -> ([DVec3; 3], [DVec2; 3]) {
        let p = [
            DVec3::ZERO,
            DVec3::new(400.0, 0.0, 0.0),
            DVec3::new(0.0, 0.0, 300.0),
        ];
        (
            p,
            [DVec2::ZERO, DVec2::new(95.0, 0.0), DVec2::new(0.0, 55.0)],
        )
    }

    #[test]
    fn tessellation_tiles_the_triangle_and_bounds_pieces() {
        let (p, uv) = big_triangle();
        let pieces = tessellate(p, uv, 48.0, 48.0, 256.0, 4096);
        assert!(pieces.len() > 100, "{}", pieces.len());
        let area = |p: &[DVec3; 3]| 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let total: f64 = pieces.iter().map(|(p, _)| area(p)).sum();
        assert!((total - area(&p)).abs() < 1e-9 * area(&p));
        for (q, u) in &pieces {
            let lo = u[0].min(u[1]).min(u[2]);
            let hi = u[0].max(u[1]).max(u[2]);
            assert!((hi - lo).max_element() * 48.0 <= 256.0);
            // The affine map is preserved: UV/position pairs lie on the original map u = 95·x/400.
            for k in 0..3 {
                assert!((u[k].x - 95.0 * q[k].x / 400.0).abs() < 1e-9);
            }
        }
        // The budget bounds the count.
        assert!(tessellate(p, uv, 48.0, 48.0, 256.0, 16).len() <= 16);
        // Small triangles are untouched; NaN is returned as is.
        assert_eq!(tessellate(p, uv, 1.0, 1.0, 256.0, 4096).len(), 1);
        assert_eq!(
            tessellate(p, [DVec2::NAN; 3], 48.0, 48.0, 256.0, 4096).len(),
            1
        );
    }

    #[test]
    fn corners_of_whole_triangles_are_the_scenes_and_of_cut_pieces_their_own() {
        use crate::scene::AlphaMode;
        use crate::scene::synthetic::SceneBuilder;
        // Baked repeats: a big triangle over 40 periods is cut, a small one over one period is not.
        let mut b = SceneBuilder::new(UpAxis::Z);
        let image = b.pattern_image("t", 64, 0);
        let material = b.material(image, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let big = [
            DVec3::ZERO,
            DVec3::new(40.0, 0.0, 0.0),
            DVec3::new(0.0, 40.0, 0.0),
        ];
        b.triangle(
            big,
            [DVec2::ZERO, DVec2::new(40.0, 0.0), DVec2::new(0.0, 40.0)],
            material,
        );
        let small = [
            DVec3::new(50.0, 0.0, 0.0),
            DVec3::new(51.0, 0.0, 0.0),
            DVec3::new(50.0, 1.0, 0.0),
        ];
        b.triangle(small, [DVec2::ZERO, DVec2::X, DVec2::Y], material);
        let scene = b.build();
        let opts = PrepareOptions {
            f_proj: 64.0,
            up: UpAxis::Z,
            cap_to_source: true,
            split_limit: 256.0,
            max_pieces: 4096,
            wrap: false,
            palette_cells: 0,
        };
        let prepared = prepare(&scene, &[0, 1], &opts);
        // The memory budget's count is the records this makes, before they exist; wrapped, one each.
        assert_eq!(
            count_pieces(&scene, &[0, 1], &opts),
            prepared.infos.len() as u64
        );
        let wrapped = PrepareOptions { wrap: true, ..opts };
        assert_eq!(count_pieces(&scene, &[0, 1], &wrapped), 2);
        let corners = prepared.corners(&scene);
        let (cut, whole): (Vec<&TriInfo>, Vec<&TriInfo>) =
            prepared.infos.iter().partition(|t| t.scene_tri == 0);
        assert!(cut.len() > 1, "the big triangle is cut");
        assert_eq!(
            prepared.pieces.len(),
            cut.len(),
            "only cut pieces keep corners"
        );
        assert_eq!(whole.len(), 1);
        assert_eq!(whole[0].piece, WHOLE);
        assert_eq!(corners.of(whole[0]), small);
        // The pieces tile the big triangle: their areas sum to its area, every corner inside it.
        let area = |p: [DVec3; 3]| 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length();
        let sum: f64 = cut.iter().map(|t| area(corners.of(t))).sum();
        assert!((sum - area(big)).abs() < 1e-6, "{sum}");
        for t in &cut {
            assert!(t.piece != WHOLE);
            for p in corners.of(t) {
                assert!(
                    p.x >= -1e-9 && p.y >= -1e-9 && p.x + p.y <= 40.0 + 1e-9,
                    "{p}"
                );
            }
        }
    }

    #[test]
    fn walk_yields_the_records_of_the_items_in_their_order() {
        let info = |k: u32| TriInfo {
            scene_tri: k,
            piece: WHOLE,
            material: crate::ids::MaterialId(0),
            mid: DVec2::ZERO,
            class: 0,
            area: 0.0,
            size: SizeEstimate {
                w: 0.0,
                h: 0.0,
                method: SizeMethod::AllUvEqual,
            },
            uv: [DVec2::ZERO; 3],
        };
        let infos: Vec<TriInfo> = (0..100).map(info).collect();
        // Shorter and longer than the prefetch distance; repeats and any order.
        for items in [
            vec![],
            vec![7, 7, 3],
            (0..100).rev().chain(0..40).collect::<Vec<u32>>(),
        ] {
            let walked: Vec<u32> = walk(&infos, &items).map(|t| t.scene_tri).collect();
            assert_eq!(walked, items);
        }
    }

    #[test]
    fn period_shift_per_wrap_mode() {
        let uv = [
            DVec2::new(1e5 + 0.25, -3.5),
            DVec2::new(1e5 + 1.5, -2.0),
            DVec2::new(1e5 + 0.75, -3.0),
        ];
        let s = period_shift(uv, [Wrap::Repeat, Wrap::MirroredRepeat]);
        assert_eq!(s, DVec2::new(1e5, -4.0));
        let s = period_shift(uv, [Wrap::ClampToEdge, Wrap::ClampToEdge]);
        assert_eq!(s, DVec2::ZERO);
        // A mirrored axis is only shifted by even periods: −3.5 → shift −4, leaving 0.5 (same mirror phase).
        let shifted = uv[0] - period_shift(uv, [Wrap::Repeat, Wrap::MirroredRepeat]);
        assert!((shifted.x - 0.25).abs() < 1e-9 && (shifted.y - 0.5).abs() < 1e-12);
    }
}
