//! Drawing with missing blocks (paper §6): "When a texture atlas is not sufficient for a node N and one or
//! more child nodes are not in memory, all triangles of the missing child nodes are nevertheless rendered
//! immediately using the atlas texture of N." A selected node whose atlas is not resident is drawn with its
//! nearest resident ancestor's atlas (the per-node texture transform handles any level gap); a leaf whose
//! original textures are not all resident is drawn with its atlas (or that fallback). The root atlas is
//! always resident, so every selected triangle is drawn.
//!
//! Also the screen-space accounting shared by the renderer and the simulator: the share of the drawn
//! screen area that is rendered coarser than the target, and by how many levels.

use crate::camera::Camera;
use crate::ids::{NONE, NodeId};
use crate::select::{CutItem, Source};
use crate::store::format::NodeRecord;
use glam::{DVec3, DVec4};
use serde::Serialize;

/// How one cut item is drawn this frame.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Resolved {
    /// Whose atlas: `None` draws the leaf's original textures.
    pub atlas_node: Option<NodeId>,
    /// Levels coarser than the selection asked for (0 = as selected). Original textures count as one
    /// level finer than the leaf atlas.
    pub coarser_levels: u32,
}

/// Resolves `item` given residency: `atlas_resident(node)` and `originals_ready(leaf node)`.
/// If no ancestor is resident (only possible when the root is not, which the pager never allows) the root
/// is returned with the full gap, so the caller still draws.
pub fn resolve(
    nodes: &[NodeRecord],
    item: &CutItem,
    atlas_resident: impl Fn(NodeId) -> bool,
    originals_ready: impl Fn(NodeId) -> bool,
) -> Resolved {
    let level = |n: NodeId| nodes.get(n.idx()).map_or(0, |r| r.level);
    let (start, target_level) = match item.source {
        Source::Original => {
            if originals_ready(item.node) {
                return Resolved {
                    atlas_node: None,
                    coarser_levels: 0,
                };
            }
            (item.node, level(item.node) + 1)
        }
        Source::Atlas => (item.node, level(item.node)),
    };
    let mut n = start;
    let mut steps = 0usize;
    loop {
        if atlas_resident(n) {
            break;
        }
        let parent = nodes.get(n.idx()).map_or(NONE, |r| r.parent);
        // A parent id must be smaller (validated files); the step bound guards hand-made cycles.
        if parent == NONE || parent >= n.0 || steps > 64 {
            n = NodeId(0);
            break;
        }
        n = NodeId(parent);
        steps += 1;
    }
    Resolved {
        atlas_node: Some(n),
        coarser_levels: target_level.saturating_sub(level(n)),
    }
}

/// Fraction of the viewport (0–1) covered by the screen rectangle of the projected box `lo..hi`: a
/// conservative estimate of a node's screen area (the box's 2-D bounding rectangle, clipped to the
/// viewport; a box that reaches behind the near plane while intersecting the view counts as the whole
/// viewport).
pub fn screen_fraction(camera: &Camera, lo: DVec3, hi: DVec3) -> f64 {
    let vp = camera.view_proj_relative();
    let (mut x0, mut y0, mut x1, mut y1) =
        (f64::INFINITY, f64::INFINITY, -f64::INFINITY, -f64::INFINITY);
    let mut behind = false;
    for i in 0..8 {
        let p = DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        ) - camera.eye;
        let c: DVec4 = vp * p.extend(1.0);
        if c.w <= camera.near * 0.5 {
            behind = true;
            continue;
        }
        let (x, y) = (c.x / c.w, c.y / c.w);
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if behind {
        return 1.0;
    }
    let w = (x1.min(1.0) - x0.max(-1.0)).max(0.0);
    let h = (y1.min(1.0) - y0.max(-1.0)).max(0.0);
    (w * h / 4.0).clamp(0.0, 1.0)
}

/// Screen-space accounting of one frame's draws.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct Coarseness {
    /// Items drawn, and items drawn coarser than selected.
    pub items: u32,
    pub coarser_items: u32,
    /// Summed [`screen_fraction`] of all drawn items, and of the coarser ones.
    pub area: f64,
    pub coarser_area: f64,
    /// Coarser area by level gap: 1, 2, 3, ≥ 4 levels.
    pub coarser_area_by_gap: [f64; 4],
}

impl Coarseness {
    /// Adds one drawn item with its screen fraction and resolution.
    pub fn add(&mut self, fraction: f64, r: &Resolved) {
        self.items += 1;
        self.area += fraction;
        if r.coarser_levels > 0 {
            self.coarser_items += 1;
            self.coarser_area += fraction;
            self.coarser_area_by_gap[(r.coarser_levels.min(4) - 1) as usize] += fraction;
        }
    }

    /// The share of the drawn screen area rendered coarser than the target (0–1; 0 when nothing drawn).
    /// Overlapping rectangles are counted once per item on both sides of the ratio.
    pub fn share(&self) -> f64 {
        if self.area > 0.0 {
            self.coarser_area / self.area
        } else {
            0.0
        }
    }

    /// Mean level gap over the coarser area (0 when none).
    pub fn mean_gap(&self) -> f64 {
        if self.coarser_area <= 0.0 {
            return 0.0;
        }
        let g = &self.coarser_area_by_gap;
        (g[0] + 2.0 * g[1] + 3.0 * g[2] + 4.0 * g[3]) / self.coarser_area
    }
}

/// Resolves every item of `cut_items` and accounts its screen fraction; `out[i]` is item `i`'s resolution.
pub fn resolve_cut(
    nodes: &[NodeRecord],
    items: &[CutItem],
    camera: &Camera,
    atlas_resident: impl Fn(NodeId) -> bool,
    originals_ready: impl Fn(NodeId) -> bool,
    out: &mut Vec<Resolved>,
    acc: &mut Coarseness,
) {
    out.clear();
    for item in items {
        let r = resolve(nodes, item, &atlas_resident, &originals_ready);
        let f = nodes.get(item.node.idx()).map_or(0.0, |n| {
            screen_fraction(
                camera,
                DVec3::from_array(n.bounds_min),
                DVec3::from_array(n.bounds_max),
            )
        });
        acc.add(f, &r);
        out.push(r);
    }
}
