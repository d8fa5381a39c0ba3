//! Usage categories and block priorities (paper §6).
//!
//! "The usage categories ordered by decreasing priority are needed, culled, parent needed, and not
//! needed." The usage of every block is found by a traversal of its own which, unlike the rendering
//! traversal, does not stop at missing nodes and also descends into culled subtrees:
//!
//! - **needed**: blocks the frame would use if the whole tree were in memory: the atlas of every visible
//!   cut node drawn with its atlas, the atlas and original textures of every visible leaf drawn with its
//!   originals, and (closure) every block on the path from the root to those;
//! - **culled**: the same for cut nodes outside the view frustum ("appropriate texture accuracy, but not
//!   needed due to view-frustum culling"), the paper's prefetch of what may become visible soon;
//! - **parent needed**: prefetch one step finer than the frame: the children's atlases of a node whose atlas
//!   is needed, and the original textures of a leaf whose atlas is needed;
//! - **not needed**: everything else.
//!
//! Among equal usage the nearer block (distance from the eye to the node's bounds) comes first, and among
//! equal usage and distance the lower level. Because a parent's bounds contain its children's, a parent is
//! never farther than its child, so every prefix of the order is closed under
//! [`BlockMeta::parent`](crate::paging::BlockMeta::parent), which is what keeps the resident set a union of root paths.

use super::blocks::BlockTable;
use crate::camera::{Frustum, Visibility, distance_to_aabb};
use crate::ids::{BlockId, NONE, NodeId};
use crate::select::{Step, TraversalStack, traverse};
use crate::store::format::NodeRecord;
use glam::DVec3;
use serde::Serialize;

/// A block's usage this frame, most important first.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[repr(u8)]
pub enum Usage {
    Needed = 0,
    Culled = 1,
    ParentNeeded = 2,
    NotNeeded = 3,
}

/// A block that has a usage other than [`Usage::NotNeeded`] this frame.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Candidate {
    pub block: BlockId,
    pub usage: Usage,
    /// Distance from the eye to the block's node bounds, world units (the minimum over the current and the
    /// predicted eye when a lookahead is given).
    pub distance: f64,
    /// See [`super::blocks::BlockMeta::level`].
    pub level: u32,
}

/// Where the frame looks from: the inputs of the usage traversal.
#[derive(Copy, Clone, Debug)]
pub struct ViewInput<'a> {
    pub eye: DVec3,
    pub frustum: &'a Frustum,
    /// The selection's `min_distance` scale ([`crate::select::min_distance_scale`]).
    pub scale: f64,
    /// A predicted eye position (motion extrapolation); distances are the minimum over both eyes.
    pub lookahead: Option<DVec3>,
}

/// Reusable buffers of [`classify`]: per-block usage and distance, reset in O(touched).
#[derive(Clone, Debug, Default)]
pub struct UsageScratch {
    stack: TraversalStack,
    usage: Vec<Usage>,
    distance: Vec<f64>,
    touched: Vec<BlockId>,
    counts: UsageCounts,
}

/// How many blocks fell in each category (the "blocks needed" column and friends).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct UsageCounts {
    pub needed: u32,
    pub culled: u32,
    pub parent_needed: u32,
}

impl UsageScratch {
    fn reset(&mut self, blocks: usize) {
        if self.usage.len() != blocks {
            self.usage = vec![Usage::NotNeeded; blocks];
            self.distance = vec![f64::INFINITY; blocks];
            self.touched.clear();
        }
        for &b in &self.touched {
            self.usage[b.idx()] = Usage::NotNeeded;
            self.distance[b.idx()] = f64::INFINITY;
        }
        self.touched.clear();
        self.counts = UsageCounts::default();
    }

    /// Raises block `b` to `usage` (if more important than what it has) at `distance`.
    fn mark(&mut self, b: BlockId, usage: Usage, distance: f64) {
        let i = b.idx();
        if self.usage[i] == Usage::NotNeeded && self.distance[i] == f64::INFINITY {
            self.touched.push(b);
        }
        if usage < self.usage[i] {
            self.usage[i] = usage;
        }
        if distance < self.distance[i] {
            self.distance[i] = distance;
        }
    }

    /// Counts of the last [`classify`].
    pub fn counts(&self) -> UsageCounts {
        self.counts
    }
}

fn node_distance(node: &NodeRecord, view: &ViewInput) -> f64 {
    let lo = DVec3::from_array(node.bounds_min);
    let hi = DVec3::from_array(node.bounds_max);
    let d = distance_to_aabb(view.eye, lo, hi);
    match view.lookahead {
        Some(p) => d.min(distance_to_aabb(p, lo, hi)),
        None => d,
    }
}

/// The paper's usage traversal over all trees: fills `out` with every block whose usage is not
/// [`Usage::NotNeeded`] (unsorted). `trees[t]` are tree `t`'s nodes, as in `table`.
///
/// The root atlas of every tree is always needed (the paper keeps it in memory so that every triangle
/// has at least an approximate texture).
pub fn classify(
    table: &BlockTable,
    trees: &[&[NodeRecord]],
    view: &ViewInput,
    scratch: &mut UsageScratch,
    out: &mut Vec<Candidate>,
) {
    scratch.reset(table.len());
    out.clear();
    for (t, nodes) in trees.iter().enumerate() {
        if let Some(root) = table.atlas(t, NodeId(0)) {
            scratch.mark(root, Usage::Needed, 0.0);
        }
        let mut stack = std::mem::take(&mut scratch.stack);
        traverse(
            nodes,
            view.frustum,
            view.eye,
            view.scale,
            &mut stack,
            |id, node, eval| {
                let visible = eval.visibility != Visibility::Outside;
                let is_leaf = node.leaf != NONE;
                if !eval.atlas_suffices && !is_leaf {
                    return Step::Descend;
                }
                let usage = if visible {
                    Usage::Needed
                } else {
                    Usage::Culled
                };
                let d = node_distance(node, view);
                if let Some(a) = table.atlas(t, id) {
                    scratch.mark(a, usage, d);
                }
                if eval.atlas_suffices {
                    if visible {
                        // Prefetch one step finer: children's atlases, or the leaf's originals.
                        for &c in &node.children {
                            if let (true, Some(child), Some(a)) =
                                (c != NONE, nodes.get(c as usize), table.atlas(t, NodeId(c)))
                            {
                                scratch.mark(a, Usage::ParentNeeded, node_distance(child, view));
                            }
                        }
                        for &b in table.originals(t, id) {
                            scratch.mark(b, Usage::ParentNeeded, d);
                        }
                    }
                } else {
                    for &b in table.originals(t, id) {
                        scratch.mark(b, usage, d);
                    }
                }
                Step::Stop
            },
        );
        scratch.stack = stack;
    }
    // Closure: every block on the path to a marked block gets at least its usage.
    let touched = scratch.touched.len();
    for i in 0..touched {
        let b = scratch.touched[i];
        let usage = scratch.usage[b.idx()];
        let mut p = table.meta(b).parent;
        while let Some(pb) = p {
            if scratch.usage[pb.idx()] <= usage && scratch.distance[pb.idx()].is_finite() {
                break;
            }
            let m = table.meta(pb);
            let d = trees
                .get(m.tree as usize)
                .and_then(|n| n.get(m.item.node().idx()))
                .map_or(0.0, |n| node_distance(n, view));
            scratch.mark(pb, usage, d);
            p = m.parent;
        }
    }
    for &b in &scratch.touched {
        let usage = scratch.usage[b.idx()];
        match usage {
            Usage::Needed => scratch.counts.needed += 1,
            Usage::Culled => scratch.counts.culled += 1,
            Usage::ParentNeeded => scratch.counts.parent_needed += 1,
            Usage::NotNeeded => continue,
        }
        out.push(Candidate {
            block: b,
            usage,
            distance: scratch.distance[b.idx()],
            level: table.meta(b).level,
        });
    }
}
