//! The contents of the tiles: a node drawn with its atlas (affine rects from the atlas, wrapping rects from
//! period images or their averages) and leaves drawn with their original textures (module doc of
//! [`super`]).

use super::geometry::{self, GroupKey};
use super::gltf_doc::{
    self, CLAMP_TO_EDGE, GltfDoc, LeafPlacement, MIRRORED_REPEAT, MaterialSpec, REPEAT,
};
use super::images::{self, ImageCodec};
use super::{
    ExportError, ExportOptions, ImageSummary, TileSummary, TreeCtx, encode_image, tileset,
    write_file,
};
use crate::model::{AtlasForest, RectWrap};
use crate::store::TreeFile;
use rayon::prelude::*;

/// The glTF wrap code a rect axis gets in its period image.
fn period_wrap(w: RectWrap) -> u32 {
    match w {
        RectWrap::Repeat => REPEAT,
        RectWrap::Mirror => MIRRORED_REPEAT,
        RectWrap::Linear | RectWrap::Clamp => CLAMP_TO_EDGE,
    }
}

/// Where a leaf's node puts its positions (scene frame, relative to the leaf origin) in its tile: the
/// leaf origin relative to the tree origin and the turn that makes the scene's up axis glTF's y, both
/// in glTF's frame (`tileset::to_gltf_frame`).
fn leaf_placement(ctx: &TreeCtx<'_>, leaf: usize) -> LeafPlacement {
    let d = tileset::to_gltf_frame(ctx.tree.leaves[leaf].origin - ctx.origin, ctx.up);
    LeafPlacement {
        translation: [d.x as f32, d.y as f32, d.z as f32],
        rotation: tileset::gltf_rotation(ctx.up).map(|q| q.map(|c| c as f32)),
    }
}

/// The node tiles of a tree: `(content uri, summary)` per node.
pub(super) fn node_tiles(
    file: &TreeFile,
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    opts: &ExportOptions,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<TileSummary>, ExportError> {
    (0..ctx.tree.nodes.len())
        .into_par_iter()
        .map(|n| {
            let tile = if opts.naive {
                let (lo, hi) = ctx.leaf_ranges[n];
                originals_tile(forest, ctx, n, lo..hi, "atlas", format!("n{n}.gltf"))?
            } else {
                atlas_tile(file, forest, ctx, opts, n)?
            };
            tick();
            Ok(tile)
        })
        .collect()
}

fn atlas_tile(
    file: &TreeFile,
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    opts: &ExportOptions,
    n: usize,
) -> Result<TileSummary, ExportError> {
    let tree = ctx.tree;
    let node = &tree.nodes[n];
    let size = forest.params.atlas_size;
    let atlas = images::atlas_level0(file, node.atlas_block, tree.format, size)?;
    let atlas_uri = format!("img/n{n}.{}", ctx.codec.extension());
    let (atlas_image, atlas_src) = encode_image(&ctx.dir, &atlas_uri, &atlas, ctx.codec, false)?;
    let mut images = vec![atlas_image];
    let mut doc = GltfDoc::default();
    let atlas_tex = doc.texture(
        (&atlas_src, &atlas_uri),
        [CLAMP_TO_EDGE, CLAMP_TO_EDGE],
        false,
    );
    let avg_uri = format!("img/n{n}-avg.png");
    let (lo, hi) = ctx.leaf_ranges[n];
    let keep = period_threshold(ctx, node, lo..hi, opts.max_period_images);
    // The averages image: every averaged rect's period mean at this level (PNG: exact texels).
    // The band of rows of the tile's rects (contiguous: its leaves are).
    let g0 = ctx.rect_base.get(lo).copied().unwrap_or(0);
    let g1 = if hi > lo {
        ctx.rect_base[hi - 1] + tree.leaves[hi - 1].rects.len() as u32
    } else {
        g0
    };
    let ((row0, band_rows), band_xf) = ctx.grid.band(g0, g1);
    let band_xf = (band_rows != ctx.grid.rows).then_some(band_xf);
    let mut averages = image::RgbaImage::new(ctx.grid.cols, band_rows);
    let (mut averaged, mut avg_tex) = (0usize, None);
    for l in lo..hi {
        let leaf = &tree.leaves[l];
        let mesh = &ctx.meshes[l];
        let leaf_node = &tree.nodes[leaf.node.0 as usize];
        let (ox, oy, d) =
            crate::model::transform::cell_offset(leaf_node.cell, leaf_node.level, node.level);
        let s = (-(f64::from(d))).exp2();
        let transform = (d > 0).then_some(([f64::from(ox) * s, f64::from(oy) * s], [s, s]));
        let uri = format!("geom/l{l}.bin");
        let mut prims: Vec<(geometry::IndexGroup, usize, bool)> = Vec::new();
        for g in &mesh.atlas_groups {
            match g.key {
                GroupKey::Atlas { alpha, cutoff } => {
                    let material = doc.material(MaterialSpec {
                        texture: atlas_tex,
                        tex_coord: 1,
                        transform,
                        factor: [1.0; 4],
                        alpha,
                        cutoff: f32::from_bits(cutoff),
                    });
                    prims.push((g.clone(), material, true));
                }
                GroupKey::Period {
                    alpha,
                    cutoff,
                    side,
                    rect,
                } if f64::from(side) * s < keep => {
                    // Averaged: its stored mean (format 6, as the tree shader's flat fragments) in its
                    // texel of the averages image, its triangles joined to the run of averaged rects of
                    // the same alpha before it (contiguous: sorted by side).
                    let r = &leaf.rects[rect as usize];
                    let (x, y) = ctx.grid.texel(ctx.rect_base[l] + rect);
                    averages.put_pixel(x, y - row0, image::Rgba(r.mean));
                    averaged += 1;
                    let tex = *avg_tex.get_or_insert_with(|| {
                        // Its URI is set once the image is complete (below).
                        doc.texture((&avg_uri, &avg_uri), [CLAMP_TO_EDGE, CLAMP_TO_EDGE], true)
                    });
                    let material = doc.material(MaterialSpec {
                        texture: tex,
                        tex_coord: 1,
                        transform: band_xf,
                        factor: [1.0; 4],
                        alpha,
                        cutoff: f32::from_bits(cutoff),
                    });
                    match prims.last_mut() {
                        Some((last, m, _))
                            if *m == material
                                && last.offset
                                    + u64::from(last.count) * u64::from(mesh.index_size)
                                    == g.offset =>
                        {
                            last.count += g.count;
                        }
                        _ => prims.push((g.clone(), material, true)),
                    }
                }
                GroupKey::Period {
                    alpha,
                    cutoff,
                    rect,
                    ..
                } => {
                    let r = &leaf.rects[rect as usize];
                    let img = images::crop_scaled(&atlas, r.inner, (ox, oy, d));
                    let puri = format!("img/n{n}-l{l}-r{rect}.{}", ctx.codec.extension());
                    let (summary, src) = encode_image(&ctx.dir, &puri, &img, ctx.codec, true)?;
                    images.push(summary);
                    let wrap = [period_wrap(r.wrap[0]), period_wrap(r.wrap[1])];
                    let tex = doc.texture((&src, &puri), wrap, false);
                    let span = |k: usize| {
                        let s = r.uv_max[k] - r.uv_min[k];
                        if s > 0.0 { s } else { 1.0 }
                    };
                    let scale = [1.0 / span(0), 1.0 / span(1)];
                    let offset = [-r.uv_min[0] * scale[0], -r.uv_min[1] * scale[1]];
                    let material = doc.material(MaterialSpec {
                        texture: tex,
                        tex_coord: 0,
                        transform: Some((offset, scale)),
                        factor: [1.0; 4],
                        alpha,
                        cutoff: f32::from_bits(cutoff),
                    });
                    prims.push((g.clone(), material, false));
                }
                GroupKey::Original { .. } => {}
            }
        }
        doc.leaf_node(l, mesh, &uri, leaf_placement(ctx, l), &prims);
    }
    if avg_tex.is_some() {
        let (summary, src) = encode_image(&ctx.dir, &avg_uri, &averages, ImageCodec::Png, true)?;
        doc.set_image_uri(&avg_uri, &src);
        images.push(summary);
    }
    let mut tile = finish_tile(ctx, n, "atlas", format!("n{n}.gltf"), doc, images, lo..hi)?;
    tile.averaged_rects = averaged;
    Ok(tile)
}

/// The smallest period side (texels of the tile's level) a rect keeps its own period image at in the tile
/// of `node`: 2 (below, atlastree's shader draws the period's average too: at the distances a tile is
/// drawn a pixel covers 1–2 of its texels), raised so that at most `budget` rects of the tile get one
/// (the smallest periods are averaged first).
fn period_threshold(
    ctx: &TreeCtx<'_>,
    node: &crate::model::Node,
    leaves: std::ops::Range<usize>,
    budget: usize,
) -> f64 {
    let mut sides: Vec<f64> = Vec::new();
    for l in leaves {
        let leaf_node = &ctx.tree.nodes[ctx.tree.leaves[l].node.0 as usize];
        let d = leaf_node.level.0.saturating_sub(node.level.0);
        let s = (-(f64::from(d))).exp2();
        for g in &ctx.meshes[l].atlas_groups {
            if let GroupKey::Period { side, .. } = g.key
                && f64::from(side) * s >= MIN_PERIOD_TEXELS
            {
                sides.push(f64::from(side) * s);
            }
        }
    }
    if sides.len() <= budget {
        return MIN_PERIOD_TEXELS;
    }
    sides.sort_unstable_by(|a, b| b.total_cmp(a));
    // Keep the `budget` largest; ties with the first one left out are averaged too.
    let cut = sides[budget];
    let mut next = cut;
    for &x in &sides[..budget] {
        if x > cut {
            next = x;
        }
    }
    if next > cut { next } else { f64::INFINITY }
}

/// Below this many texels of the tile's level, a wrapping rect is drawn with its period's average.
pub const MIN_PERIOD_TEXELS: f64 = 2.0;

/// A tile drawing leaves `leaves` with their original textures.
fn originals_tile(
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    n: usize,
    leaves: std::ops::Range<usize>,
    source: &'static str,
    name: String,
) -> Result<TileSummary, ExportError> {
    let tree = ctx.tree;
    let mut doc = GltfDoc::default();
    let mut images: Vec<ImageSummary> = Vec::new();
    for l in leaves.clone() {
        let leaf = &tree.leaves[l];
        let mesh = &ctx.meshes[l];
        let mut prims = Vec::new();
        for g in &mesh.original_groups {
            let GroupKey::Original { original } = g.key else {
                continue;
            };
            let o = &leaf.originals[original as usize];
            let bad = |source| ExportError::Geometry {
                tree: ctx.index,
                source,
            };
            let img = ctx.originals.get(&(o.block.0, o.slot)).ok_or_else(|| {
                bad(geometry::GeometryError::MissingOriginal {
                    leaf: l,
                    block: o.block.0,
                    slot: o.slot,
                })
            })?;
            if !images.iter().any(|i| i.uri == img.uri) {
                images.push(img.clone());
            }
            let m = forest.materials.get(o.material.0 as usize).ok_or_else(|| {
                bad(geometry::GeometryError::BadMaterial {
                    leaf: l,
                    material: o.material.0,
                    materials: forest.materials.len(),
                })
            })?;
            let wrap = [
                gltf_doc::wrap_code(m.wrap[0]),
                gltf_doc::wrap_code(m.wrap[1]),
            ];
            let tex = doc.texture((&img.uri, &img.uri), wrap, false);
            let (alpha, cutoff) = geometry::alpha_key(m);
            let material = doc.material(MaterialSpec {
                texture: tex,
                tex_coord: 0,
                transform: None,
                factor: m.base_color_factor,
                alpha,
                cutoff: f32::from_bits(cutoff),
            });
            prims.push((g.clone(), material, false));
        }
        doc.leaf_node(
            l,
            mesh,
            &format!("geom/l{l}.bin"),
            leaf_placement(ctx, l),
            &prims,
        );
    }
    finish_tile(ctx, n, source, name, doc, images, leaves)
}

fn finish_tile(
    ctx: &TreeCtx<'_>,
    n: usize,
    source: &'static str,
    name: String,
    doc: GltfDoc,
    images: Vec<ImageSummary>,
    leaves: std::ops::Range<usize>,
) -> Result<TileSummary, ExportError> {
    let node = &ctx.tree.nodes[n];
    let draw_calls = doc.primitives;
    let text = doc.finish();
    let gltf_bytes = write_file(&ctx.dir.join(&name), text.as_bytes())?;
    let geometry_bytes = leaves.clone().map(|l| ctx.meshes[l].bin_len).sum();
    Ok(TileSummary {
        tree: ctx.index,
        node: n as u32,
        level: node.level.0,
        source,
        uri: format!("t{}/{name}", ctx.index),
        min_distance: node.min_distance,
        geometric_error: 0.0,
        bounds_min: node.bounds_min.to_array(),
        bounds_max: node.bounds_max.to_array(),
        images,
        draw_calls,
        leaves: leaves.len(),
        geometry_bytes,
        averaged_rects: 0,
        gltf_bytes,
    })
}

/// The original-texture tile below each leaf, in leaf order.
pub(super) fn original_tiles(
    forest: &AtlasForest,
    ctx: &TreeCtx<'_>,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<TileSummary>, ExportError> {
    (0..ctx.tree.leaves.len())
        .into_par_iter()
        .map(|l| {
            let n = ctx.tree.leaves[l].node.0 as usize;
            let t = originals_tile(
                forest,
                ctx,
                n,
                l..l + 1,
                "original",
                format!("n{n}-orig.gltf"),
            )?;
            tick();
            Ok(t)
        })
        .collect()
}
