//! Cross-reference checks on decoded tables, shared by the writer (refuse to write a file the reader would
//! reject) and the reader (refuse to hand out tables that index out of range).
//!
//! Every check is a linear pass over a table (the originals' slot check sorts the original references,
//! O(n log n) in their count), so validating a file of 10k nodes and 1M vertices costs a few milliseconds. Indices reported in errors are positions in the file's section
//! (tree base + tree-local index), so they name the exact record.

use super::format::{
    BLOCK_ATLAS, BLOCK_ORIGINALS, BlockRecord, MaterialRecord, NodeRecord, ParamsRecord,
};
use super::{StoreError, TreeView};
use crate::ids::NONE;

mod geometry;
use geometry::{check_rects_originals, check_vertices_indices};

/// The largest atlas side a file may record, texels (the builder's limit, `--atlas-size`).
pub(crate) const MAX_ATLAS_SIZE: u32 = 16384;

/// The tables of one tree ([`TreeView`]) and the tree's index, which error messages and block checks need.
pub(crate) struct TreeTables<'a> {
    /// Index of the tree.
    pub tree: u32,
    pub view: TreeView<'a>,
    /// The geometry sections were not read (their slices are empty): their bytes are vouched for by a
    /// hash over the whole prefix (a plan file's), so only their record counts are checked against.
    pub geometry_vouched: bool,
}

impl TreeTables<'_> {
    /// Vertices of the tree: the slice's length, or the record's count when the geometry was not read.
    fn vertex_count(&self) -> u64 {
        if self.geometry_vouched {
            self.record.vertices.count
        } else {
            self.vertices.len() as u64
        }
    }

    /// Indices of the tree, as [`TreeTables::vertex_count`].
    fn index_count(&self) -> u64 {
        if self.geometry_vouched {
            self.record.indices.count
        } else {
            self.indices.len() as u64
        }
    }

    /// Source triangles of the tree, as [`TreeTables::vertex_count`].
    fn source_count(&self) -> u64 {
        if self.geometry_vouched {
            self.record.source_triangles.count
        } else {
            self.source_triangles.len() as u64
        }
    }
}

impl<'a> std::ops::Deref for TreeTables<'a> {
    type Target = TreeView<'a>;
    fn deref(&self) -> &TreeView<'a> {
        &self.view
    }
}

fn bad_ref(
    table: &'static str,
    index: u64,
    field: &'static str,
    value: u64,
    limit: u64,
) -> StoreError {
    StoreError::BadReference {
        table,
        index,
        field,
        value,
        limit,
    }
}

fn bad_value(table: &'static str, index: u64, field: &'static str, value: u64) -> StoreError {
    StoreError::BadValue {
        table,
        index,
        field,
        value,
    }
}

/// Checks that every value of `values` is finite.
fn finite(
    table: &'static str,
    index: u64,
    field: &'static str,
    values: &[f64],
) -> Result<(), StoreError> {
    match values.iter().find(|v| !v.is_finite()) {
        None => Ok(()),
        Some(&value) => Err(StoreError::BadFloat {
            table,
            index,
            field,
            value,
            rule: "finite",
        }),
    }
}

/// Checks `0 < value < max` (and finite).
fn positive_below(
    table: &'static str,
    index: u64,
    field: &'static str,
    value: f64,
    max: f64,
    rule: &'static str,
) -> Result<(), StoreError> {
    if value.is_finite() && value > 0.0 && value < max {
        Ok(())
    } else {
        Err(StoreError::BadFloat {
            table,
            index,
            field,
            value,
            rule,
        })
    }
}

/// Checks `value < limit`.
fn in_range(
    table: &'static str,
    index: u64,
    field: &'static str,
    value: u64,
    limit: u64,
) -> Result<(), StoreError> {
    if value < limit {
        Ok(())
    } else {
        Err(bad_ref(table, index, field, value, limit))
    }
}

/// Checks that `[first, first + count)` lies in `[0, limit)`, without overflow.
fn range_in(
    table: &'static str,
    index: u64,
    field: &'static str,
    first: u64,
    count: u64,
    limit: u64,
) -> Result<(), StoreError> {
    match first.checked_add(count) {
        Some(end) if end <= limit => Ok(()),
        _ => Err(bad_ref(
            table,
            index,
            field,
            first.saturating_add(count),
            limit,
        )),
    }
}

/// The build parameters decode (known up axis, depth fits a byte), the atlas side is a power of two of at
/// most [`MAX_ATLAS_SIZE`] and the padding field is zero.
pub(crate) fn check_params(p: &ParamsRecord) -> Result<(), StoreError> {
    if p._pad != 0 {
        return Err(bad_value("params", 0, "_pad", u64::from(p._pad)));
    }
    // A power of two up to the builder's largest (what every atlas decode and mip chain assumes).
    if !p.atlas_size.is_power_of_two() || p.atlas_size > MAX_ATLAS_SIZE {
        return Err(bad_value(
            "params",
            0,
            "atlas_size",
            u64::from(p.atlas_size),
        ));
    }
    // What selection and export divide by and take tangents of.
    positive_below(
        "params",
        0,
        "d_min",
        p.d_min,
        f64::INFINITY,
        "finite and > 0",
    )?;
    positive_below(
        "params",
        0,
        "fov_deg",
        p.fov_deg,
        180.0,
        "in (0, 180) degrees",
    )?;
    positive_below(
        "params",
        0,
        "texel_ratio",
        p.texel_ratio,
        f64::INFINITY,
        "finite and > 0",
    )?;
    if p.screen_width == 0 {
        return Err(bad_value("params", 0, "screen_width", 0));
    }
    if p.decode().is_none() {
        let (field, value) = if p.up > 2 {
            ("up", p.up)
        } else {
            ("max_depth", p.max_depth)
        };
        return Err(bad_value("params", 0, field, u64::from(value)));
    }
    Ok(())
}

/// Every material has known wrap and alpha codes, a UTF-8 name inside the Strings section and a zero `_pad`.
pub(crate) fn check_materials(
    materials: &[MaterialRecord],
    strings: &[u8],
) -> Result<(), StoreError> {
    for (i, m) in materials.iter().enumerate() {
        let i = i as u64;
        if m._pad != 0 {
            return Err(bad_value("materials", i, "_pad", u64::from(m._pad)));
        }
        if m.alpha().is_none() {
            return Err(bad_value(
                "materials",
                i,
                "alpha_mode",
                u64::from(m.alpha_mode),
            ));
        }
        let factor = m.base_color_factor.map(f64::from);
        finite("materials", i, "base_color_factor", &factor)?;
        finite("materials", i, "alpha_cutoff", &[f64::from(m.alpha_cutoff)])?;
        if m.wraps().is_none() {
            return Err(bad_value(
                "materials",
                i,
                "wrap",
                u64::from(m.wrap[0].max(m.wrap[1])),
            ));
        }
        let first = u64::from(m.name_offset);
        range_in(
            "materials",
            i,
            "name",
            first,
            u64::from(m.name_len),
            strings.len() as u64,
        )?;
        let name = strings.get(m.name_offset as usize..(first + u64::from(m.name_len)) as usize);
        if name.and_then(|n| std::str::from_utf8(n).ok()).is_none() {
            return Err(bad_value("materials", i, "name", first));
        }
    }
    Ok(())
}

/// A file holds one or two trees (opaque; alpha only if the scene has alpha materials).
pub(crate) fn check_tree_count(trees: usize) -> Result<(), StoreError> {
    if (1..=2).contains(&trees) {
        Ok(())
    } else {
        Err(bad_value("trees", 0, "count", trees as u64))
    }
}

/// Node and leaf counts of every tree, for [`check_block_meta`].
pub(crate) struct TreeCounts {
    pub nodes: u64,
    pub leaves: u64,
}

/// Every block names an existing tree and an existing node (atlas) or leaf (originals) of it.
pub(crate) fn check_block_meta(
    blocks: &[BlockRecord],
    trees: &[TreeCounts],
) -> Result<(), StoreError> {
    for (i, b) in blocks.iter().enumerate() {
        let i = i as u64;
        in_range("blocks", i, "tree", u64::from(b.tree), trees.len() as u64)?;
        let counts = &trees[b.tree as usize];
        match b.kind {
            BLOCK_ATLAS => {
                in_range("blocks", i, "item", u64::from(b.item), counts.nodes)?;
                if b.part != 0 {
                    return Err(bad_value("blocks", i, "part", u64::from(b.part)));
                }
            }
            BLOCK_ORIGINALS => in_range("blocks", i, "item", u64::from(b.item), counts.leaves)?,
            other => return Err(bad_value("blocks", i, "kind", u64::from(other))),
        }
    }
    Ok(())
}

/// All cross-references of one tree: node links (parent before child, child cells and levels, leaf ↔ node),
/// index/vertex/rect/original ranges, material and block ids, vertex leaf ids and index values.
pub(crate) fn check_tree(
    t: &TreeTables<'_>,
    materials: &[MaterialRecord],
    blocks: &[BlockRecord],
    atlas_size: u32,
) -> Result<(), StoreError> {
    if t.record.tree_kind().is_none() {
        return Err(bad_value(
            "trees",
            u64::from(t.tree),
            "kind",
            u64::from(t.record.kind),
        ));
    }
    if t.record.tex_format().is_none() {
        return Err(bad_value(
            "trees",
            u64::from(t.tree),
            "format",
            u64::from(t.record.format),
        ));
    }
    if t.nodes.is_empty() {
        return Err(bad_value("trees", u64::from(t.tree), "nodes.count", 0));
    }
    let tris = t.index_count() / 3;
    let sources = t.source_count();
    if !t.index_count().is_multiple_of(3) || sources != tris {
        let value = sources;
        return Err(bad_value(
            "trees",
            u64::from(t.tree),
            "source_triangles.count",
            value,
        ));
    }
    check_nodes(t, blocks)?;
    check_leaves(t, blocks)?;
    check_rects_originals(t, materials.len(), blocks, atlas_size)?;
    check_original_slots(t, materials, blocks)?;
    if t.geometry_vouched {
        return Ok(());
    }
    check_vertices_indices(t)
}

/// Every originals block of the tree holds exactly the chains its references name: one (image, wrap,
/// extent, and in an alpha tree MASK cutoff) per `(block, slot)` however many leaves and materials reference it (materials of one image
/// and wrap share a stored original, docs/DESIGN.md "Originals"), slots `0..n` without a gap, and the
/// chains' bytes in the tree's format summing to the block's length (the renderer reads a slot at the
/// sum of the chains before it). Runs after [`check_rects_originals`] (block ids and sides are valid).
fn check_original_slots(
    t: &TreeTables<'_>,
    materials: &[MaterialRecord],
    blocks: &[BlockRecord],
) -> Result<(), StoreError> {
    let Some(format) = t.record.tex_format() else {
        return Ok(());
    };
    // (image, wrap, sides, MASK cutoff in an alpha tree): what `assemble::StoredOriginal` shares by.
    type Stored = (u32, [u32; 2], [u32; 2], Option<u32>);
    let alpha = t.record.tree_kind() == Some(crate::model::TreeKind::Alpha);
    let mut slots: std::collections::BTreeMap<(u32, u32), (u64, Stored)> = Default::default();
    for (i, o) in t.originals.iter().enumerate() {
        let gi = t.record.originals.first + i as u64;
        // `check_rects_originals` checked the material's index.
        let m = materials.get(o.material as usize);
        let wrap = m.map_or([0; 2], |m| m.wrap);
        let cutoff = m
            .filter(|m| alpha && m.alpha_mode == super::format::ALPHA_MASK)
            .map(|m| m.alpha_cutoff.to_bits());
        let stored = (o.image, wrap, o.extent(), cutoff);
        let entry = slots.entry((o.block, o.slot)).or_insert((gi, stored));
        if entry.1 != stored {
            return Err(bad_value("originals", gi, "slot", u64::from(o.slot)));
        }
    }
    let mut by_block: std::collections::BTreeMap<u32, (u32, u64)> = Default::default();
    for (&(block, slot), &(gi, (_, _, [w, h], _))) in &slots {
        let (next, bytes) = by_block.entry(block).or_insert((0, 0));
        if slot != *next {
            return Err(bad_value("originals", gi, "slot", u64::from(slot)));
        }
        *next += 1;
        *bytes += format.chain_bytes_rect(w, h);
    }
    for (block, (_, bytes)) in by_block {
        let length = blocks[block as usize].length;
        if length != bytes {
            return Err(bad_value("blocks", u64::from(block), "length", length));
        }
    }
    Ok(())
}

/// A child's bounds lie inside its parent's and its indices inside its parent's range: what selection
/// and drawing assume. Checked only by `inspect --verify` before, so a file with consistent checksums and
/// a child outside its parent was drawn wrong without a word (16.3 dB; fault hunt, session 31).
fn check_nested(parent: &NodeRecord, child: &NodeRecord, gi: u64) -> Result<(), StoreError> {
    if let Some(k) = (0..3).find(|&k| {
        child.bounds_min[k] < parent.bounds_min[k] || child.bounds_max[k] > parent.bounds_max[k]
    }) {
        let value = if child.bounds_min[k] < parent.bounds_min[k] {
            child.bounds_min[k]
        } else {
            child.bounds_max[k]
        };
        return Err(StoreError::BadFloat {
            table: "nodes",
            index: gi,
            field: "bounds",
            value,
            rule: "inside its parent's bounds",
        });
    }
    let end = |n: &NodeRecord| u64::from(n.first_index) + u64::from(n.index_count);
    if child.first_index < parent.first_index || end(child) > end(parent) {
        return Err(bad_value(
            "nodes",
            gi,
            "index_range",
            u64::from(child.first_index),
        ));
    }
    Ok(())
}

/// An inner node's `min_distance` is twice its children's largest (paper §5.1; relative 1e-9, as `inspect
/// --verify` allows): selection refines a node nearer than it, so a wrong one drew coarse or over-fine
/// levels without a word (an inner node's set to 0 or 1e300: 22.6 / 29.4 dB; fault hunt, session 31).
fn check_min_distance(t: &TreeTables<'_>, n: &NodeRecord, gi: u64) -> Result<(), StoreError> {
    let kids = n.children.iter().filter(|&&c| c != NONE);
    let Some(largest) = kids
        .filter_map(|&c| t.nodes.get(c as usize))
        .map(|c| c.min_distance)
        .reduce(f64::max)
    else {
        return Ok(());
    };
    let want = 2.0 * largest;
    if (n.min_distance - want).abs() > 1e-9 * n.min_distance.abs().max(want.abs()).max(1.0) {
        return Err(StoreError::BadFloat {
            table: "nodes",
            index: gi,
            field: "min_distance",
            value: n.min_distance,
            rule: "twice its children's largest",
        });
    }
    Ok(())
}

fn check_nodes(t: &TreeTables<'_>, blocks: &[BlockRecord]) -> Result<(), StoreError> {
    let base = t.record.nodes.first;
    let count = t.nodes.len() as u64;
    for (i, n) in t.nodes.iter().enumerate() {
        let gi = base + i as u64;
        finite("nodes", gi, "bounds_min", &n.bounds_min)?;
        finite("nodes", gi, "bounds_max", &n.bounds_max)?;
        if let Some(k) = (0..3).find(|&k| n.bounds_min[k] > n.bounds_max[k]) {
            return Err(StoreError::BadFloat {
                table: "nodes",
                index: gi,
                field: "bounds_min",
                value: n.bounds_min[k],
                rule: "at most bounds_max",
            });
        }
        if !(n.min_distance.is_finite() && n.min_distance >= 0.0) {
            return Err(StoreError::BadFloat {
                table: "nodes",
                index: gi,
                field: "min_distance",
                value: n.min_distance,
                rule: "finite and >= 0",
            });
        }
        if n.level >= 32 || (n.cell.ix >> n.level) != 0 || (n.cell.iy >> n.level) != 0 {
            return Err(bad_value(
                "nodes",
                gi,
                "cell",
                u64::from(n.cell.ix.max(n.cell.iy)),
            ));
        }
        if i == 0 {
            if n.parent != NONE || n.level != 0 {
                return Err(bad_value("nodes", gi, "parent", u64::from(n.parent)));
            }
        } else {
            // Pre-order: a parent precedes its children.
            in_range("nodes", gi, "parent", u64::from(n.parent), i as u64)?;
        }
        for (q, &c) in n.children.iter().enumerate() {
            if c == NONE {
                continue;
            }
            in_range("nodes", gi, "children", u64::from(c), count)?;
            let child = &t.nodes[c as usize];
            let cell = n.cell.child(q as u32);
            let consistent = c as usize > i
                && child.parent == i as u32
                && child.level == n.level + 1
                && child.cell == cell;
            if !consistent {
                return Err(bad_value("nodes", gi, "children", u64::from(c)));
            }
            check_nested(n, child, base + u64::from(c))?;
        }
        check_min_distance(t, n, gi)?;
        range_in(
            "nodes",
            gi,
            "index_range",
            u64::from(n.first_index),
            u64::from(n.index_count),
            t.index_count(),
        )?;
        if n.first_index % 3 != 0 || n.index_count % 3 != 0 {
            return Err(bad_value(
                "nodes",
                gi,
                "index_range",
                u64::from(n.first_index),
            ));
        }
        in_range(
            "nodes",
            gi,
            "atlas_block",
            u64::from(n.atlas_block),
            blocks.len() as u64,
        )?;
        let b = &blocks[n.atlas_block as usize];
        if b.tree != t.tree || b.kind != BLOCK_ATLAS || b.item != i as u32 {
            return Err(bad_value(
                "nodes",
                gi,
                "atlas_block",
                u64::from(n.atlas_block),
            ));
        }
        if n.leaf != NONE {
            in_range(
                "nodes",
                gi,
                "leaf",
                u64::from(n.leaf),
                t.leaves.len() as u64,
            )?;
            if t.leaves[n.leaf as usize].node != i as u32 {
                return Err(bad_value("nodes", gi, "leaf", u64::from(n.leaf)));
            }
        }
    }
    Ok(())
}

fn check_leaves(t: &TreeTables<'_>, blocks: &[BlockRecord]) -> Result<(), StoreError> {
    let base = t.record.leaves.first;
    for (l, leaf) in t.leaves.iter().enumerate() {
        let gl = base + l as u64;
        if leaf._pad != 0 {
            return Err(bad_value("leaves", gl, "_pad", u64::from(leaf._pad)));
        }
        finite("leaves", gl, "origin", &leaf.origin)?;
        positive_below(
            "leaves",
            gl,
            "clamp_scale",
            leaf.clamp_scale,
            f64::INFINITY,
            "finite and > 0",
        )?;
        in_range(
            "leaves",
            gl,
            "node",
            u64::from(leaf.node),
            t.nodes.len() as u64,
        )?;
        if t.nodes[leaf.node as usize].leaf != l as u32 {
            return Err(bad_value("leaves", gl, "node", u64::from(leaf.node)));
        }
        let ranges = [
            (
                "vertex_range",
                leaf.first_vertex,
                leaf.vertex_count,
                t.vertex_count(),
            ),
            (
                "index_range",
                leaf.first_index,
                leaf.index_count,
                t.index_count(),
            ),
            (
                "rect_range",
                leaf.first_rect,
                leaf.rect_count,
                t.rects.len() as u64,
            ),
            (
                "original_range",
                leaf.first_original,
                leaf.original_count,
                t.originals.len() as u64,
            ),
        ];
        for (field, first, count, limit) in ranges {
            range_in(
                "leaves",
                gl,
                field,
                u64::from(first),
                u64::from(count),
                limit,
            )?;
        }
        let first = leaf.first_original as usize;
        let originals = &t.originals[first..first + leaf.original_count as usize];
        for (k, o) in originals.iter().enumerate() {
            let go = t.record.originals.first + (first + k) as u64;
            in_range(
                "originals",
                go,
                "block",
                u64::from(o.block),
                blocks.len() as u64,
            )?;
            // Stored once per tree (format 4): the block may belong to an earlier leaf of the tree.
            let b = &blocks[o.block as usize];
            if b.tree != t.tree || b.kind != BLOCK_ORIGINALS || b.item > l as u32 {
                return Err(bad_value("originals", go, "block", u64::from(o.block)));
            }
        }
    }
    Ok(())
}
