//! What repeated textures cost in a tree, and what the alternative would: drawing them from their
//! originals' mip chains at every level instead of holding one period per rect in every atlas (issue 15's
//! "next step by numbers").
//!
//! A rect is *a repeat rect* when one of its axes is REPEAT or MIRRORED_REPEAT and holds a full period
//! (the used UV range was at least one period). Inner atlases are the children's halved (§5.1), so a
//! leaf rect of `A` texels occupies `A / 4^k` texels in its ancestor `k` levels up: the rect's texels over
//! all levels are `A · Σ_{k=0..=level} 4^−k`. Texel counts here are level-0 texels of a mip chain (a
//! chain is 4/3 of that); bytes follow from the tree's format.

use crate::model::RectWrap;
use crate::store::TreeFile;
use crate::store::format::RectRecord;
use serde::Serialize;
use std::collections::BTreeMap;

/// Repeat rects of one tree and the originals they stand for.
#[derive(Clone, Debug, Default, Serialize, PartialEq)]
pub struct RepeatCost {
    /// Leaf rects holding a full period on a REPEAT / MIRRORED_REPEAT axis.
    pub rects: u64,
    /// Their texels in the atlases over every level (module docs).
    pub atlas_texels: f64,
    /// Texels of every atlas of the tree (`atlas blocks × atlas²`).
    pub all_atlas_texels: u64,
    /// Distinct images behind the repeat rects.
    pub images: u64,
    /// Σ over the stored originals behind them (one per image, wrap and MASK cutoff) of their texels,
    /// `w × h`, each once: what drawing them from their mip chains at every level would store, and the
    /// most it would keep resident.
    pub original_texels_once: u64,
    /// The same summed over every leaf that references them (one copy per leaf, as files before format 4
    /// stored them; a leaf whose materials share one counts it once).
    pub original_texels_per_leaf: u64,
}

/// True if `r` holds a full period on a wrapped axis.
fn is_repeat_rect(r: &RectRecord) -> bool {
    let Some(wrap) = r.wrap() else {
        return false;
    };
    (0..2).any(|k| {
        matches!(wrap[k], RectWrap::Repeat | RectWrap::Mirror)
            && r.uv_max[k] - r.uv_min[k] >= 1.0 - 1e-9
    })
}

/// [`RepeatCost`] of tree `tree` of `file` (`None` if there is no such tree).
pub(super) fn repeat_cost(file: &TreeFile, tree: usize, atlas_size: u32) -> Option<RepeatCost> {
    let t = file.tree(tree)?;
    let mut c = RepeatCost {
        all_atlas_texels: t
            .nodes
            .iter()
            .filter(|n| n.atlas_block != crate::ids::NONE)
            .count() as u64
            * u64::from(atlas_size).pow(2),
        ..RepeatCost::default()
    };
    // Per stored original `(block, slot)`: its texels `w × h` and how many leaves hold it (counted per
    // material reference, 64 materials of one leaf on one image read as 64 leaves; fault hunt, session 34).
    let mut stored: BTreeMap<(u32, u32), (u64, u64)> = BTreeMap::new();
    let mut images = std::collections::BTreeSet::new();
    for leaf in t.leaves {
        let level = t.nodes.get(leaf.node as usize).map_or(0, |n| n.level);
        let levels: f64 = (0..=level).map(|k| 0.25f64.powi(k as i32)).sum();
        let mut materials = Vec::new();
        for r in t.leaf_rects(leaf).iter().filter(|r| is_repeat_rect(r)) {
            c.rects += 1;
            c.atlas_texels += f64::from(r.outer[2]) * f64::from(r.outer[3]) * levels;
            materials.push(r.material);
        }
        let mut in_leaf = std::collections::BTreeSet::new();
        for o in t
            .leaf_originals(leaf)
            .iter()
            .filter(|o| materials.contains(&o.material))
        {
            images.insert(o.image);
            if !in_leaf.insert((o.block, o.slot)) {
                continue;
            }
            let [w, h] = o.extent();
            let e = stored.entry((o.block, o.slot)).or_insert((0, 0));
            e.0 = u64::from(w) * u64::from(h);
            e.1 += 1;
        }
    }
    c.images = images.len() as u64;
    c.original_texels_once = stored.values().map(|&(s, _)| s).sum();
    c.original_texels_per_leaf = stored.values().map(|&(s, n)| s * n).sum();
    Some(c)
}
