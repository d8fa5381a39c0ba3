//! Where coverage-preserving alpha mips apply ([`super::image_ops::AlphaMips::Coverage`], issue 26 part 2):
//! the MASK areas of an alpha tree's atlases, each leaf rect's outer area mapped into its own atlas and
//! every ancestor's (an inner atlas holds its four children halved, child `q` in quadrant
//! `(q & 1, q >> 1)`, §5.1), with its material's cutoff.

use super::image_ops::{AlphaMips, CoverageRegion};
use crate::ids::NodeId;
use crate::model::{AtlasTree, TreeKind};
use crate::scene::{AlphaMode, Material};

/// Per material: its MASK cutoff where `mode` preserves coverage, else `None` (BLEND and OPAQUE materials
/// are never rescaled). Empty for [`AlphaMips::Plain`].
pub fn mask_cutoffs(mode: AlphaMips, materials: &[Material]) -> Vec<Option<f32>> {
    match mode {
        AlphaMips::Plain => Vec::new(),
        AlphaMips::Coverage => materials
            .iter()
            .map(|m| match m.alpha {
                AlphaMode::Mask { cutoff } if cutoff.is_finite() => Some(cutoff),
                _ => None,
            })
            .collect(),
    }
}

/// The MASK regions of node `id`'s atlas (side `atlas_size`) in its level-0 texels: the outer rect of
/// every MASK material's area in the leaves below, scaled by ½ per level between leaf and node. Empty for
/// opaque trees or without cutoffs. Quadrants smaller than a texel are not descended into.
pub fn node_regions(
    tree: &AtlasTree,
    id: NodeId,
    atlas_size: u32,
    cutoffs: &[Option<f32>],
) -> Vec<CoverageRegion> {
    let mut out = Vec::new();
    if tree.kind != TreeKind::Alpha || cutoffs.is_empty() {
        return out;
    }
    let side = f64::from(atlas_size);
    // (node, scale from its texels to id's, its origin in id's texels)
    let mut stack = vec![(id, 1.0f64, [0.0f64; 2])];
    while let Some((n, scale, origin)) = stack.pop() {
        let Some(node) = tree.nodes.get(n.idx()) else {
            continue;
        };
        if let Some(leaf) = node.leaf.and_then(|l| tree.leaves.get(l.idx())) {
            for r in &leaf.rects {
                let Some(Some(cutoff)) = cutoffs.get(r.material.idx()) else {
                    continue;
                };
                let [x, y, w, h] = r.outer.map(f64::from);
                out.push(CoverageRegion {
                    rect: [
                        origin[0] + x * scale,
                        origin[1] + y * scale,
                        origin[0] + (x + w) * scale,
                        origin[1] + (y + h) * scale,
                    ],
                    cutoff: *cutoff,
                });
            }
        }
        let half = side * scale / 2.0;
        if half < 1.0 {
            continue;
        }
        for (q, c) in node.children.iter().enumerate() {
            if let Some(c) = c {
                let o = [
                    origin[0] + (q & 1) as f64 * half,
                    origin[1] + (q >> 1) as f64 * half,
                ];
                stack.push((*c, scale / 2.0, o));
            }
        }
    }
    out
}
