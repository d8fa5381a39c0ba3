//! The checks of a tree's rects, originals and geometry: rect sides and UV boxes within the atlas, the
//! originals table's materials, blocks and power-of-two sides, vertex values finite, and each leaf's
//! vertices and indices its own ([`super::check_tree`] runs them after the node and leaf tables).

use super::{TreeTables, bad_ref, bad_value, in_range};
use crate::model::{MAX_ORIGINAL_CLASS, MIN_ORIGINAL_CLASS};
use crate::store::StoreError;
use crate::store::format::{BlockRecord, RectRecord};

pub(super) fn check_rects_originals(
    t: &TreeTables<'_>,
    materials: usize,
    blocks: &[BlockRecord],
    atlas_size: u32,
) -> Result<(), StoreError> {
    let m = materials as u64;
    for (i, r) in t.rects.iter().enumerate() {
        let gi = t.record.rects.first + i as u64;
        in_range("rects", gi, "material", u64::from(r.material), m)?;
        if r.wrap().is_none() {
            return Err(bad_value("rects", gi, "flags", u64::from(r.flags)));
        }
        if r._reserved != 0 {
            return Err(bad_value("rects", gi, "_reserved", u64::from(r._reserved)));
        }
        check_rect_geometry(r, gi, atlas_size)?;
    }
    for (i, o) in t.originals.iter().enumerate() {
        let gi = t.record.originals.first + i as u64;
        in_range("originals", gi, "material", u64::from(o.material), m)?;
        in_range(
            "originals",
            gi,
            "block",
            u64::from(o.block),
            blocks.len() as u64,
        )?;
        // Each side a power of two in the class range (the renderer picks the class array by the larger).
        for (field, side) in [("width", o.width), ("height", o.height)] {
            let range = MIN_ORIGINAL_CLASS..=MAX_ORIGINAL_CLASS;
            if !side.is_power_of_two() || !range.contains(&u32::from(side)) {
                return Err(bad_value("originals", gi, field, u64::from(side)));
            }
        }
    }
    Ok(())
}

/// A rect's geometry: the outer rectangle inside the atlas (`x + w ≤ atlas_size`, in u64), a non-empty
/// inner one inside the outer, and a finite UV rectangle with `uv_min ≤ uv_max` (what the shader, the border
/// checks and the texel transforms assume; a resealed edit could otherwise make them loop over 2³² texels
/// or divide by a NaN width).
fn check_rect_geometry(r: &RectRecord, index: u64, atlas_size: u32) -> Result<(), StoreError> {
    let size = u64::from(atlas_size);
    const OUTER: [&str; 4] = ["outer.x", "outer.y", "outer.w", "outer.h"];
    const INNER: [&str; 4] = ["inner.x", "inner.y", "inner.w", "inner.h"];
    for k in 0..2 {
        let (o0, ow) = (u64::from(r.outer[k]), u64::from(r.outer[k + 2]));
        let (i0, iw) = (u64::from(r.inner[k]), u64::from(r.inner[k + 2]));
        if o0 + ow > size {
            return Err(bad_value("rects", index, OUTER[k + 2], ow));
        }
        if i0 < o0 {
            return Err(bad_value("rects", index, INNER[k], i0));
        }
        if i0 >= o0 + ow {
            return Err(bad_value("rects", index, INNER[k], i0));
        }
        if iw == 0 || i0 + iw > o0 + ow {
            return Err(bad_value("rects", index, INNER[k + 2], iw));
        }
        let (lo, hi) = (r.uv_min[k], r.uv_max[k]);
        if !lo.is_finite() || !hi.is_finite() || lo > hi {
            let (field, value, rule) = match (lo.is_finite(), hi.is_finite()) {
                (false, _) => ("uv_min", lo, "finite"),
                (true, false) => ("uv_max", hi, "finite"),
                (true, true) => ("uv_max", hi, "at least uv_min"),
            };
            return Err(StoreError::BadFloat {
                table: "rects",
                index,
                field,
                value,
                rule,
            });
        }
    }
    Ok(())
}

pub(super) fn check_vertices_indices(t: &TreeTables<'_>) -> Result<(), StoreError> {
    let leaves = t.leaves.len() as u32;
    if let Some(i) = t.vertices.iter().position(|v| v.leaf >= leaves) {
        let value = u64::from(t.vertices[i].leaf);
        return Err(bad_ref(
            "vertices",
            t.record.vertices.first + i as u64,
            "leaf",
            value,
            leaves.into(),
        ));
    }
    // Every vertex's rect is one of its leaf's (the shader indexes the rect table with it unchecked).
    if let Some(i) = t
        .vertices
        .iter()
        .position(|v| v.rect >= t.leaves[v.leaf as usize].rect_count)
    {
        let v = &t.vertices[i];
        return Err(bad_ref(
            "vertices",
            t.record.vertices.first + i as u64,
            "rect",
            u64::from(v.rect),
            u64::from(t.leaves[v.leaf as usize].rect_count),
        ));
    }
    // Positions and UVs every reader draws or exports as they are.
    let not_finite = t.vertices.iter().enumerate().find_map(|(i, v)| {
        let c = v.pos.iter().chain(&v.orig_uv).find(|c| !c.is_finite())?;
        Some((i, *c))
    });
    if let Some((i, value)) = not_finite {
        return Err(StoreError::BadFloat {
            table: "vertices",
            index: t.record.vertices.first + i as u64,
            field: "pos/orig_uv",
            value: f64::from(value),
            rule: "finite",
        });
    }
    let limit = t.vertices.len() as u64;
    if let Some(i) = t.indices.iter().position(|&x| u64::from(x) >= limit) {
        let value = u64::from(t.indices[i]);
        return Err(bad_ref(
            "indices",
            t.record.indices.first + i as u64,
            "value",
            value,
            limit,
        ));
    }
    check_leaf_geometry(t)
}

/// Every leaf's vertices are its own (their `leaf` is the leaf, their `original` one of its originals)
/// and its triangles index only them: what the renderer and the exporter assume of a leaf's ranges. Runs
/// after the ranges, the vertices' leaves and rects and the index values are checked.
fn check_leaf_geometry(t: &TreeTables<'_>) -> Result<(), StoreError> {
    for (l, leaf) in t.leaves.iter().enumerate() {
        let first = leaf.first_vertex as usize;
        let verts = &t.vertices[first..first + leaf.vertex_count as usize];
        if let Some(k) = verts
            .iter()
            .position(|v| v.leaf != l as u32 || v.original >= leaf.original_count)
        {
            let v = &verts[k];
            let gv = t.record.vertices.first + (first + k) as u64;
            return Err(if v.leaf != l as u32 {
                bad_value("vertices", gv, "leaf", u64::from(v.leaf))
            } else {
                bad_ref(
                    "vertices",
                    gv,
                    "original",
                    u64::from(v.original),
                    u64::from(leaf.original_count),
                )
            });
        }
        let fi = leaf.first_index as usize;
        let indices = &t.indices[fi..fi + leaf.index_count as usize];
        if let Some(k) = indices
            .iter()
            .position(|&x| t.vertices[x as usize].leaf != l as u32)
        {
            return Err(bad_value(
                "indices",
                t.record.indices.first + (fi + k) as u64,
                "value",
                u64::from(indices[k]),
            ));
        }
    }
    Ok(())
}
