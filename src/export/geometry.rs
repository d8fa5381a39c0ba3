//! One leaf's geometry as a glTF binary buffer, written once and shared by every tile that draws the leaf
//! (issue 25 "geometry once"): positions relative to the leaf origin (as stored), the original UV
//! (`TEXCOORD_0`), the leaf-atlas UV (`TEXCOORD_1`, in units of the atlas side) and index lists grouped
//! the two ways a tile draws them: by atlas material (atlas tiles) and by original texture (the originals
//! tile below the leaf).
//!
//! A standard viewer cannot wrap a UV inside an atlas rect per fragment as `shaders/tree.wgsl` does, so
//! each rect is classified ([`rect_is_affine`]): where every triangle of the rect reaches its rect by one
//! affine map per axis (slope 1, or −1 under MIRRORED_REPEAT; no seam inside a triangle) the per-vertex leaf-atlas UV
//! ([`crate::model::transform::rect_texel`], margin 0) is exact and the triangles join the tile's atlas
//! material; a rect with a triangle across a wrap seam becomes a *period* group drawn with its own image
//! (the rect's inner rectangle at the tile's resolution) and the sampler's own wrap mode.

use crate::model::transform::rect_t;
use crate::model::{AtlasRect, AtlasTree, Leaf, RectWrap};
use crate::scene::{AlphaMode, Material};
use glam::DVec2;

/// Which triangles one index list holds.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub(super) enum GroupKey {
    /// Triangles of affine rects drawn from the tile's atlas, by alpha mode (`alpha`: 0 opaque, 1 mask, 2
    /// blend; `cutoff`: the MASK cutoff's bits, 0 otherwise).
    Atlas { alpha: u8, cutoff: u32 },
    /// The triangles of one wrapping rect (index into the leaf's rects), drawn with its own period image or,
    /// where its period is too small at the tile's level, with the period's average. Sorted by alpha, then
    /// by the inner rectangle's smaller side (leaf texels, ascending): the rects a tile averages are a
    /// prefix of each alpha's run, drawn as one primitive.
    Period {
        alpha: u8,
        cutoff: u32,
        side: u32,
        rect: u32,
    },
    /// The triangles drawn with one of the leaf's original textures (index into the leaf's originals).
    Original { original: u32 },
}

/// One index list inside the leaf's buffer.
#[derive(Clone, Debug)]
pub(super) struct IndexGroup {
    pub(super) key: GroupKey,
    /// Byte offset of the first index within the index section of the buffer.
    pub(super) offset: u64,
    /// Number of indices (3 per triangle).
    pub(super) count: u32,
}

/// A leaf's buffer and what is in it. Sections, tightly packed in this order, each 4-byte aligned:
/// positions (`f32 × 3`), `TEXCOORD_0` (`f32 × 2`), `TEXCOORD_1` (`f32 × 2`: the leaf-atlas UV of an affine
/// rect's vertex, else the centre of the rect's texel in the tree's averages image, [`AverageGrid`]),
/// indices (`u16` when the leaf has fewer than 65,536 vertices, else `u32`).
pub(super) struct LeafMesh {
    /// The buffer (taken out once written; [`LeafMesh::bin_len`] stays).
    pub(super) bin: Vec<u8>,
    pub(super) bin_len: u64,
    pub(super) vertices: u32,
    pub(super) pos_min: [f32; 3],
    pub(super) pos_max: [f32; 3],
    /// Byte size of one index (2 or 4).
    pub(super) index_size: u32,
    pub(super) atlas_groups: Vec<IndexGroup>,
    pub(super) original_groups: Vec<IndexGroup>,
    /// Rects drawn as period groups (index into the leaf's rects), ascending.
    pub(super) period_rects: Vec<u32>,
}

impl LeafMesh {
    pub(super) fn positions_offset(&self) -> u64 {
        0
    }
    pub(super) fn uv0_offset(&self) -> u64 {
        12 * u64::from(self.vertices)
    }
    pub(super) fn uv1_offset(&self) -> u64 {
        20 * u64::from(self.vertices)
    }
    pub(super) fn index_offset(&self) -> u64 {
        28 * u64::from(self.vertices)
    }
    pub(super) fn index_bytes(&self) -> u64 {
        self.bin_len - self.index_offset()
    }
}

/// A broken invariant of the tables (they were validated at open, so this is a bug or a corrupt file that
/// passed its checksums).
#[derive(Debug, thiserror::Error)]
pub enum GeometryError {
    #[error("leaf {leaf}: index {index} outside its vertex range {first}..{end}")]
    IndexOutsideLeaf {
        leaf: usize,
        index: u32,
        first: u32,
        end: u32,
    },
    #[error(
        "leaf {leaf}: vertex {vertex} names rect {rect} of {rects} or original {original} of {originals}"
    )]
    BadReference {
        leaf: usize,
        vertex: u32,
        rect: u32,
        rects: usize,
        original: u32,
        originals: usize,
    },
    #[error("leaf {leaf}: original {slot} of block {block} was not decoded")]
    MissingOriginal { leaf: usize, block: u32, slot: u32 },
    #[error("leaf {leaf}: material {material} of {materials}")]
    BadMaterial {
        leaf: usize,
        material: u32,
        materials: usize,
    },
}

/// Where each rect of a tree keeps its period's average: rect `g` (the tree's running rect index, leaf by
/// leaf) at texel `(g mod cols, g / cols)` of a square-ish grid over the whole tree (`cols = max(128,
/// ⌈√rects⌉)`: 16,384² holds 268 M rects). A tile's averages image is the band of rows its leaves' rects
/// occupy (they are contiguous), reached from the tree-wide UV by a `KHR_texture_transform` on `v`
/// ([`AverageGrid::band`]).
#[derive(Copy, Clone, Debug)]
pub(super) struct AverageGrid {
    pub(super) cols: u32,
    pub(super) rows: u32,
}

impl AverageGrid {
    /// The grid of a tree with `rects` rects in all.
    pub(super) fn for_rects(rects: u64) -> AverageGrid {
        let cols = ((rects as f64).sqrt().ceil() as u64).max(128);
        AverageGrid {
            cols: cols as u32,
            rows: (rects.div_ceil(cols).max(1)) as u32,
        }
    }

    /// The texel of rect `g`.
    pub(super) fn texel(self, g: u32) -> (u32, u32) {
        (g % self.cols, g / self.cols)
    }

    /// The UV of the centre of rect `g`'s texel.
    pub(super) fn uv(self, g: u32) -> [f32; 2] {
        let (x, y) = self.texel(g);
        [
            ((f64::from(x) + 0.5) / f64::from(self.cols)) as f32,
            ((f64::from(y) + 0.5) / f64::from(self.rows)) as f32,
        ]
    }

    /// The rows holding rects `g0..g1` (`first row`, `row count`), and the transform (offset, scale) that
    /// takes a tree-wide UV into that band: `v' = v · rows/count − first/count`.
    pub(super) fn band(self, g0: u32, g1: u32) -> ((u32, u32), ([f64; 2], [f64; 2])) {
        let first = g0 / self.cols;
        let last = g1.saturating_sub(1).max(g0) / self.cols;
        let count = last - first + 1;
        let (rows, c) = (f64::from(self.rows), f64::from(count));
        (
            (first, count),
            ([0.0, -f64::from(first) / c], [1.0, rows / c]),
        )
    }
}

/// The alpha key of a material ([`GroupKey::Atlas`]).
pub(super) fn alpha_key(m: &Material) -> (u8, u32) {
    match m.alpha {
        AlphaMode::Opaque => (0, 0),
        AlphaMode::Mask { cutoff } => (1, cutoff.to_bits()),
        AlphaMode::Blend => (2, 0),
    }
}

/// Whether one axis of a triangle maps into its rect by one affine function `t = a·u + b` (see the module
/// doc). `us`: the vertices' UVs on the axis; `ts`: their [`rect_t`] under `wrap`. The slope is 1, or −1
/// under MIRRORED_REPEAT only (a reversed copy): under REPEAT a triangle whose UVs end on the period's
/// seam (`u` ∈ {0.5, 1} in a full-period rect: `t` ∈ {0.5, 0}) also fits `t = 1 − u`, which would draw
/// the other half of the period, mirrored.
fn axis_is_affine(us: [f64; 3], ts: [f64; 3], wrap: RectWrap) -> bool {
    let eps = |u: f64| 1e-6 * (1.0 + u.abs());
    let slopes: &[f64] = if wrap == RectWrap::Mirror {
        &[1.0, -1.0]
    } else {
        &[1.0]
    };
    slopes.iter().any(|&a| {
        let b = ts[0] - a * us[0];
        (0..3).all(|i| (a * us[i] + b - ts[i]).abs() <= eps(us[i]))
    })
}

/// Whether every triangle (vertex UV triples) of a rect reaches it affinely on both axes: then per-vertex
/// leaf-atlas UVs are exact (linear interpolation of them is what the shader's per-fragment wrap gives).
pub(super) fn rect_is_affine(rect: &AtlasRect, triangles: &[[[f32; 2]; 3]]) -> bool {
    triangles.iter().all(|tri| {
        (0..2).all(|k| {
            if rect.wrap[k] == RectWrap::Linear {
                return true;
            }
            let us = tri.map(|uv| f64::from(uv[k]));
            let ts = us.map(|u| rect_t(u, rect.wrap[k], rect.uv_min[k], rect.uv_max[k]));
            axis_is_affine(us, ts, rect.wrap[k])
        })
    })
}

/// A period rect's triangle's UVs as its period image is read: the image holds the rect's inner rectangle,
/// `u' = (u − uv_min) / span` per axis, wrapped by the sampler's own mode. Per axis: where the triangle maps
/// affinely ([`axis_is_affine`]) each vertex takes its value inside the rect (`uv_min + rect_t(u)`: no wrap
/// needed, mirror's reversed copies included); where it crosses a seam it keeps its shape and is moved by
/// whole periods so the crossing lies where the image's own wrap reproduces it: REPEAT only crosses in a
/// full-period rect (any shift), MIRRORED_REPEAT folds at integers, at 0 (the rect starts at 0) or 1 (it
/// ends at 1) once shifted by an even number, CLAMP_TO_EDGE needs no shift.
fn period_uvs(rect: &AtlasRect, tri: [[f32; 2]; 3]) -> [[f32; 2]; 3] {
    let mut out = tri;
    for k in 0..2 {
        let us = tri.map(|uv| f64::from(uv[k]));
        let (wrap, lo, hi) = (rect.wrap[k], rect.uv_min[k], rect.uv_max[k]);
        let ts = us.map(|u| rect_t(u, wrap, lo, hi));
        let fixed: [f64; 3] = if wrap == RectWrap::Linear {
            us
        } else if axis_is_affine(us, ts, wrap) {
            ts.map(|t| lo + t)
        } else if wrap == RectWrap::Mirror {
            // The fold the triangle crosses: the first integer above its lowest UV (several: a full-period
            // rect, any even shift). An even one sits on 0, an odd one on 1.
            let min = us.iter().copied().fold(f64::INFINITY, f64::min);
            let n = min.floor() + 1.0;
            let shift = if n.rem_euclid(2.0) == 0.0 { n } else { n - 1.0 };
            us.map(|u| u - shift)
        } else {
            us
        };
        for (o, f) in out.iter_mut().zip(fixed) {
            o[k] = f as f32;
        }
    }
    out
}

/// A triangle of a leaf: its vertices (leaf-local), rect and original.
type Triangle = ([u32; 3], u32, u32);

/// Builds leaf `leaf_index`'s buffer (see [`LeafMesh`]). `atlas_size`: texels per atlas side.
/// `rect_base`: the tree's running index of the leaf's first rect ([`AverageGrid`]).
pub(super) fn leaf_mesh(
    tree: &AtlasTree,
    leaf_index: usize,
    materials: &[Material],
    atlas_size: u32,
    (rect_base, grid): (u32, AverageGrid),
) -> Result<LeafMesh, GeometryError> {
    let leaf: &Leaf = &tree.leaves[leaf_index];
    let first = leaf.first_vertex;
    let end = first + leaf.vertex_count;
    let verts = &tree.vertices[first as usize..end as usize];
    let tris =
        &tree.indices[leaf.first_index as usize..(leaf.first_index + leaf.index_count) as usize];
    // Every vertex's rect and original belong to this leaf (the file's open-time checks test them against
    // the leaf a vertex names, `inspect --verify` that it is this one).
    for (i, v) in verts.iter().enumerate() {
        if v.rect as usize >= leaf.rects.len() || v.original as usize >= leaf.originals.len() {
            return Err(GeometryError::BadReference {
                leaf: leaf_index,
                vertex: first + i as u32,
                rect: v.rect,
                rects: leaf.rects.len(),
                original: v.original,
                originals: leaf.originals.len(),
            });
        }
    }
    // Per triangle: local vertex indices, rect and original (a triangle's vertices share them).
    let mut triangles: Vec<Triangle> = Vec::with_capacity(tris.len() / 3);
    for t in tris.chunks_exact(3) {
        let mut local = [0u32; 3];
        for (l, &i) in local.iter_mut().zip(t) {
            if i < first || i >= end {
                return Err(GeometryError::IndexOutsideLeaf {
                    leaf: leaf_index,
                    index: i,
                    first,
                    end,
                });
            }
            *l = i - first;
        }
        let v = verts[local[0] as usize];
        triangles.push((local, v.rect, v.original));
    }
    // Rect classification.
    let mut per_rect: Vec<Vec<[[f32; 2]; 3]>> = vec![Vec::new(); leaf.rects.len()];
    for (local, rect, _) in &triangles {
        per_rect[*rect as usize].push(local.map(|i| verts[i as usize].orig_uv));
    }
    let affine: Vec<bool> = leaf
        .rects
        .iter()
        .zip(&per_rect)
        .map(|(r, t)| rect_is_affine(r, t))
        .collect();
    let mut rect_alpha = Vec::with_capacity(leaf.rects.len());
    for r in &leaf.rects {
        let m = materials
            .get(r.material.0 as usize)
            .ok_or(GeometryError::BadMaterial {
                leaf: leaf_index,
                material: r.material.0,
                materials: materials.len(),
            })?;
        rect_alpha.push(alpha_key(m));
    }
    // Vertices: the leaf's own, then copies for the triangles of period rects (one per vertex and UV), whose TEXCOORD_0
    // is its UV as the rect's period image is read (`period_uvs`) and TEXCOORD_1 its rect's texel in the
    // averages image.
    let mut extra: Vec<([f32; 3], [f32; 2], [f32; 2])> = Vec::new();
    let mut period_tri: Vec<[u32; 3]> = vec![[0; 3]; triangles.len()];
    let mut copies: std::collections::HashMap<(u32, u32, u32), u32> =
        std::collections::HashMap::new();
    for (t, (local, rect, _)) in triangles.iter().enumerate() {
        if affine[*rect as usize] {
            continue;
        }
        let r = &leaf.rects[*rect as usize];
        let uvs = period_uvs(r, local.map(|i| verts[i as usize].orig_uv));
        for k in 0..3 {
            // Shared again where triangles of the rect give a vertex the same UV.
            let key = (local[k], uvs[k][0].to_bits(), uvs[k][1].to_bits());
            period_tri[t][k] = *copies.entry(key).or_insert_with(|| {
                extra.push((
                    verts[local[k] as usize].pos,
                    uvs[k],
                    grid.uv(rect_base + rect),
                ));
                (verts.len() + extra.len() - 1) as u32
            });
        }
    }
    let n = verts.len() + extra.len();
    let index_size: u32 = if n < 65_536 { 2 } else { 4 };
    let mut bin = Vec::with_capacity(n * 28 + 2 * tris.len() * index_size as usize);
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    let positions = verts.iter().map(|v| v.pos).chain(extra.iter().map(|e| e.0));
    for p in positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
            bin.extend_from_slice(&p[k].to_le_bytes());
        }
    }
    for uv in verts
        .iter()
        .map(|v| v.orig_uv)
        .chain(extra.iter().map(|e| e.1))
    {
        bin.extend_from_slice(&uv[0].to_le_bytes());
        bin.extend_from_slice(&uv[1].to_le_bytes());
    }
    let size = f64::from(atlas_size);
    for v in verts {
        let r = &leaf.rects[v.rect as usize];
        // The leaf-atlas UV of an affine rect's vertex; a period rect's own vertices are not drawn with
        // TEXCOORD_1 (their triangles use the unshared copies), the averages texel keeps it meaningful.
        let uv = if affine[v.rect as usize] {
            let p = crate::model::transform::rect_texel(
                DVec2::new(f64::from(v.orig_uv[0]), f64::from(v.orig_uv[1])),
                r,
                DVec2::ZERO,
            );
            [(p.x / size) as f32, (p.y / size) as f32]
        } else {
            grid.uv(rect_base + v.rect)
        };
        bin.extend_from_slice(&uv[0].to_le_bytes());
        bin.extend_from_slice(&uv[1].to_le_bytes());
    }
    for e in &extra {
        bin.extend_from_slice(&e.2[0].to_le_bytes());
        bin.extend_from_slice(&e.2[1].to_le_bytes());
    }
    // Index sections: atlas groups then original groups, each group's triangles in stored order.
    let atlas_key = |rect: u32| {
        if affine[rect as usize] {
            let (alpha, cutoff) = rect_alpha[rect as usize];
            GroupKey::Atlas { alpha, cutoff }
        } else {
            let (alpha, cutoff) = rect_alpha[rect as usize];
            let r = &leaf.rects[rect as usize];
            GroupKey::Period {
                alpha,
                cutoff,
                side: r.inner[2].min(r.inner[3]),
                rect,
            }
        }
    };
    let write_groups = |keys: &dyn Fn(&Triangle) -> GroupKey, own: bool, bin: &mut Vec<u8>| {
        let mut order: Vec<(GroupKey, usize)> = triangles
            .iter()
            .enumerate()
            .map(|(i, t)| (keys(t), i))
            .collect();
        order.sort_unstable();
        let base = 28 * n as u64;
        let mut groups: Vec<IndexGroup> = Vec::new();
        for (key, i) in order {
            if groups.last().is_none_or(|g| g.key != key) {
                groups.push(IndexGroup {
                    key,
                    offset: bin.len() as u64 - base,
                    count: 0,
                });
            }
            if let Some(g) = groups.last_mut() {
                g.count += 3;
            }
            // Period rects' triangles in atlas tiles draw their unshared vertices.
            let corners = if own || affine[triangles[i].1 as usize] {
                triangles[i].0
            } else {
                period_tri[i]
            };
            for l in corners {
                if index_size == 2 {
                    bin.extend_from_slice(&(l as u16).to_le_bytes());
                } else {
                    bin.extend_from_slice(&l.to_le_bytes());
                }
            }
        }
        // Keep the next section 4-byte aligned.
        while !bin.len().is_multiple_of(4) {
            bin.push(0);
        }
        groups
    };
    let atlas_groups = write_groups(&|t| atlas_key(t.1), false, &mut bin);
    let original_groups = write_groups(&|t| GroupKey::Original { original: t.2 }, true, &mut bin);
    let period_rects = (0..leaf.rects.len() as u32)
        .filter(|&r| !affine[r as usize] && !per_rect[r as usize].is_empty())
        .collect();
    if n == 0 {
        (lo, hi) = ([0.0; 3], [0.0; 3]);
    }
    Ok(LeafMesh {
        bin_len: bin.len() as u64,
        bin,
        vertices: n as u32,
        pos_min: lo,
        pos_max: hi,
        index_size,
        atlas_groups,
        original_groups,
        period_rects,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn rect(wrap: RectWrap, lo: f64, hi: f64) -> AtlasRect {
        AtlasRect {
            material: crate::ids::MaterialId(0),
            outer: [0, 0, 72, 72],
            inner: [4, 4, 64, 64],
            uv_min: [lo, lo],
            uv_max: [hi, hi],
            wrap: [wrap, wrap],
            capped: [false, false],
            mean: [0; 4],
        }
    }

    #[test]
    fn a_tiles_band_of_the_averages_grid_reads_its_own_texels() {
        let g = AverageGrid::for_rects(300);
        assert_eq!((g.cols, g.rows), (128, 3));
        let big = AverageGrid::for_rects(2_000_000);
        assert!(big.cols <= 16_384 && big.rows <= 16_384, "{big:?}");
        // Rects 130..140 lie in row 1: a one-row band; rect 135's centre lands in its middle.
        let ((first, count), (offset, scale)) = g.band(130, 140);
        assert_eq!((first, count), (1, 1));
        let [u, v] = g.uv(135);
        assert_eq!(f64::from(u), 7.5 / 128.0);
        assert!((f64::from(v) * scale[1] + offset[1] - 0.5).abs() < 1e-6);
        // The whole tree: every row, the identity.
        assert_eq!(g.band(0, 300), ((0, 3), ([0.0, 0.0], [1.0, 1.0])));
    }

    #[test]
    fn a_triangle_across_a_repeat_seam_is_not_affine() {
        let r = rect(RectWrap::Repeat, 0.0, 1.0);
        assert!(rect_is_affine(&r, &[[[0.1, 0.1], [0.8, 0.1], [0.5, 0.9]]]));
        assert!(!rect_is_affine(
            &r,
            &[[[0.9, 0.1], [1.05, 0.1], [0.95, 0.5]]]
        ));
        // The period's second half, ending on the seam: `t` runs 0.5 → 0 there, which slope −1 would fit
        // (the first half, mirrored); only MIRRORED_REPEAT reverses.
        let half = [[[0.5, 0.1], [1.0, 0.1], [1.0, 0.5]]];
        assert!(!rect_is_affine(&r, &half));
        assert!(rect_is_affine(&rect(RectWrap::Mirror, 0.0, 1.0), &half));
    }

    #[test]
    fn a_mirrored_triangle_is_affine_with_slope_minus_one() {
        let r = rect(RectWrap::Mirror, 0.0, 1.0);
        // [1.0, 1.5] folds backwards onto [0.5, 1.0]: one affine piece, the vertex at the fold included.
        assert!(rect_is_affine(&r, &[[[1.0, 0.2], [1.5, 0.2], [1.2, 0.6]]]));
        assert!(!rect_is_affine(&r, &[[[0.9, 0.2], [1.1, 0.2], [1.0, 0.6]]]));
    }

    /// What a viewer samples for `u` in a period image of `r` (axis 0): `(u − uv_min)/span` wrapped by the
    /// sampler, back in the rect's UV.
    fn viewer(r: &AtlasRect, u: f64) -> f64 {
        let span = r.uv_max[0] - r.uv_min[0];
        let t = (u - r.uv_min[0]) / span;
        let w = match r.wrap[0] {
            RectWrap::Repeat => t - t.floor(),
            RectWrap::Mirror => crate::model::transform::mirror(t),
            _ => t.clamp(0.0, 1.0),
        };
        r.uv_min[0] + w * span
    }

    /// Along the triangle's edges, the viewer's value equals the shader's (`uv_min + rect_t`).
    fn check_period(r: &AtlasRect, tri: [[f32; 2]; 3]) {
        let fixed = period_uvs(r, tri);
        for (a, b) in [(0, 1), (1, 2), (2, 0)] {
            for s in 0..=20 {
                let w = f64::from(s) / 20.0;
                let lerp =
                    |p: [[f32; 2]; 3]| f64::from(p[a][0]) * (1.0 - w) + f64::from(p[b][0]) * w;
                let want = r.uv_min[0] + rect_t(lerp(tri), r.wrap[0], r.uv_min[0], r.uv_max[0]);
                let got = viewer(r, lerp(fixed));
                // A value on a seam may be read from either side (u and u ± period under REPEAT).
                let span = r.uv_max[0] - r.uv_min[0];
                let d = (got - want).abs();
                assert!(
                    d < 1e-5 || (d - span).abs() < 1e-5,
                    "{:?} {tri:?}: at {} viewer {got}, shader {want}",
                    r.wrap,
                    lerp(tri)
                );
            }
        }
    }

    #[test]
    fn period_uvs_read_what_the_shader_reads() {
        let m = |lo, hi| rect(RectWrap::Mirror, lo, hi);
        // Mirror symmetric about 0, stored around 2 (folds at 2 ≡ 0): the rect [0, 0.3].
        check_period(&m(0.0, 0.3), [[1.8, 0.0], [2.2, 0.0], [2.0, 0.5]]);
        // Around 1 with the rect ending at 1.
        check_period(&m(0.6, 1.0), [[0.7, 0.0], [1.3, 0.0], [1.1, 0.5]]);
        // A reversed copy not touching a fold, in a rect reaching neither 0 nor 1.
        check_period(&m(0.2, 0.5), [[1.6, 0.0], [1.7, 0.0], [1.8, 0.5]]);
        // Repeat: a partial period past 1 ([0.9, 1.2]) with the triangle stored at [0, 0.2].
        check_period(
            &rect(RectWrap::Repeat, 0.9, 1.2),
            [[0.0, 0.0], [0.2, 0.0], [0.1, 0.5]],
        );
        // Repeat: the period's second half, ending on the seam.
        check_period(
            &rect(RectWrap::Repeat, 0.0, 1.0),
            [[0.5, 0.0], [1.0, 0.0], [1.0, 0.5]],
        );
        // Repeat across a seam of a full period.
        check_period(
            &rect(RectWrap::Repeat, 0.0, 1.0),
            [[0.8, 0.0], [1.3, 0.0], [1.0, 0.5]],
        );
        // Clamp beyond 1 with the rect ending at 1.
        check_period(
            &rect(RectWrap::Clamp, 0.5, 1.0),
            [[0.6, 0.0], [1.4, 0.0], [0.9, 0.5]],
        );
    }

    #[test]
    fn clamped_vertices_outside_the_unit_range_are_not_affine() {
        let r = rect(RectWrap::Clamp, 0.0, 1.0);
        assert!(rect_is_affine(&r, &[[[0.0, 0.0], [1.0, 0.0], [0.5, 1.0]]]));
        assert!(!rect_is_affine(&r, &[[[0.5, 0.0], [1.5, 0.0], [0.5, 1.0]]]));
    }
}
