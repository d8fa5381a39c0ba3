//! Per-frame node selection: the cut through the atlas tree (paper §4). Pure data in, pure data out.
//!
//! The tree is traversed top-down. A node whose bounds are outside the view frustum is skipped
//! (hierarchical culling: planes a node is inside are not tested again below it). For a visible node the
//! distance `d` from the eye to its bounds decides:
//!
//! - `d > scale · min_distance`: the node's atlas is sharp enough; all triangles of its subtree are drawn
//!   with it (one [`CutItem`], [`Source::Atlas`]).
//! - otherwise an inner node descends to its children, and a leaf is drawn with the **original**
//!   textures ([`Source::Original`]).
//!
//! **At `d == scale · min_distance` the traversal descends** (atlas only for a strictly greater distance,
//! the paper's "if d is greater than N.minDistance"). That is the finer, never-magnifying choice, and it
//! is stable: the decision is one f64 comparison of values computed the same way every time, so the same
//! nodes, camera and scale always give the same cut ([`atlas_suffices`] is the single place it is made).
//!
//! The traversal itself ([`traverse`]) is separate from what it produces, so the paging traversal of §6,
//! which "does not stop at missing nodes" and also classifies culled nodes, reuses the same visibility and
//! distance code ([`evaluate`]) with a different visitor.

use crate::camera::{Camera, Frustum, PlaneMask, Visibility, distance_to_aabb};
use crate::ids::{NONE, NodeId};
use crate::model::BuildParams;
use crate::store::format::NodeRecord;
use glam::DVec3;
use serde::Serialize;

/// Run-time viewing conditions; the tree's `min_distance` values are rescaled to them
/// ([`min_distance_scale`]), so none requires a rebuild.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct SelectOptions {
    /// Viewport width, pixels.
    pub screen_width: u32,
    /// Required texels per pixel (1.0 = the paper's 1:1; > 1 for anti-aliasing, < 1 for slow GPUs).
    pub texel_ratio: f64,
    /// Horizontal field of view of the camera, degrees.
    pub fov_x_deg: f64,
}

impl SelectOptions {
    /// The conditions the tree was built for (scale 1).
    pub fn built_for(p: &BuildParams) -> SelectOptions {
        SelectOptions {
            screen_width: p.screen_width,
            texel_ratio: p.texel_ratio,
            fov_x_deg: p.fov_deg,
        }
    }
}

/// Invalid viewing conditions or build parameters, with the offending field and value.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SelectError {
    #[error("select option {field} is {value}; it must be {}", rule(.field))]
    BadOption { field: &'static str, value: f64 },
    #[error("build parameter {field} is {value}; it must be {}", rule(.field))]
    BadBuildParams { field: &'static str, value: f64 },
}

/// What a field of [`SelectError`] must be.
fn rule(field: &str) -> &'static str {
    if field.starts_with("fov") {
        "in (0, 180) degrees"
    } else {
        "finite and > 0"
    }
}

fn check(
    field: &'static str,
    value: f64,
    max: f64,
    err: fn(&'static str, f64) -> SelectError,
) -> Result<f64, SelectError> {
    if value.is_finite() && value > 0.0 && value < max {
        Ok(value)
    } else {
        Err(err(field, value))
    }
}

/// The factor every node's `min_distance` is multiplied by under `opts` (paper §4 end, docs/DESIGN.md
/// "Texel-per-pixel control").
///
/// Derivation from `f_proj = r · w / (2 d tan(c/2))` (§5.2.1, texels per world unit required at distance
/// `d` for screen width `w`, texel ratio `r`, horizontal fov `c`): a node's atlas has a fixed texel
/// density `ρ`, and was given `min_distance = m₀` such that `f_proj(m₀)` under the build conditions
/// `(w₀, r₀, c₀)` equals `ρ`. Under the run-time conditions `(w, r, c)` the atlas suffices from the `m`
/// with `r w / (2 m tan(c/2)) = ρ = r₀ w₀ / (2 m₀ tan(c₀/2))`, i.e.
///
/// `m / m₀ = (w / w₀) · (r / r₀) · (tan(c₀/2) / tan(c/2))`:
///
/// linear in the screen width and the texel ratio, and growing as the field of view narrows (zoom).
pub fn min_distance_scale(built: &BuildParams, opts: &SelectOptions) -> Result<f64, SelectError> {
    let b = |f, v| SelectError::BadBuildParams { field: f, value: v };
    let o = |f, v| SelectError::BadOption { field: f, value: v };
    let w0 = check(
        "screen_width",
        f64::from(built.screen_width),
        f64::INFINITY,
        b,
    )?;
    let r0 = check("texel_ratio", built.texel_ratio, f64::INFINITY, b)?;
    let c0 = check("fov_deg", built.fov_deg, 180.0, b)?;
    let w = check(
        "screen_width",
        f64::from(opts.screen_width),
        f64::INFINITY,
        o,
    )?;
    let r = check("texel_ratio", opts.texel_ratio, f64::INFINITY, o)?;
    let c = check("fov_x_deg", opts.fov_x_deg, 180.0, o)?;
    let tan_half = |deg: f64| (deg.to_radians() * 0.5).tan();
    Ok((w / w0) * (r / r0) * (tan_half(c0) / tan_half(c)))
}

/// Which textures a selected node is drawn with.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Source {
    /// The node's atlas, for all triangles of its subtree.
    Atlas,
    /// The leaf's original textures (camera closer than the leaf's scaled `min_distance`).
    Original,
}

/// One selected node: a contiguous index range drawn with one texture source.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct CutItem {
    pub node: NodeId,
    pub source: Source,
    /// Depth of the node, root = 0.
    pub level: u8,
    /// The node's index range in the tree's index buffer (its whole subtree).
    pub first_index: u32,
    pub index_count: u32,
    /// Distance from the eye to the node's bounds, world units (0 inside).
    pub distance: f64,
}

/// The nodes to draw this frame. Reuse one `Cut` across frames: [`select`] clears it and allocates
/// nothing once its buffers have grown to the tree's needs.
#[derive(Clone, Debug, Default)]
pub struct Cut {
    /// In tree pre-order, which is index-buffer order: `first_index` increases along the list.
    pub items: Vec<CutItem>,
    /// Nodes evaluated (frustum test and distance), culled ones included.
    pub visited: u32,
    /// Nodes found outside the frustum (roots of culled subtrees; their descendants are not visited).
    pub culled: u32,
    stack: TraversalStack,
}

impl Cut {
    pub fn new() -> Cut {
        Cut::default()
    }

    /// `(node, source)` of every item, for comparing selections regardless of distances.
    pub fn selection(&self) -> impl Iterator<Item = (NodeId, Source)> + '_ {
        self.items.iter().map(|i| (i.node, i.source))
    }
}

/// What [`evaluate`] found out about one node.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct NodeEval {
    pub visibility: Visibility,
    /// Planes the node still straddles (tested again for its children).
    pub planes: PlaneMask,
    /// Distance from the eye to the node's bounds, world units.
    pub distance: f64,
    /// `distance > scale · min_distance`: the node's atlas is sharp enough ([`atlas_suffices`]).
    pub atlas_suffices: bool,
}

/// The paper's §4 test, the only place it is made: the atlas of a node with `min_distance` suffices at
/// `distance` iff `distance > scale · min_distance` (strictly; see the module docs). NaN never suffices.
#[inline]
pub fn atlas_suffices(distance: f64, min_distance: f64, scale: f64) -> bool {
    distance > scale * min_distance
}

/// Evaluates `node` for a camera at `eye`: frustum test against the planes in `planes` (pass
/// [`PlaneMask::ALL`] for a root, the parent's [`NodeEval::planes`] below it), distance and the
/// atlas-sufficiency test.
#[inline]
pub fn evaluate(
    node: &NodeRecord,
    frustum: &Frustum,
    eye: DVec3,
    planes: PlaneMask,
    scale: f64,
) -> NodeEval {
    let lo = DVec3::from_array(node.bounds_min);
    let hi = DVec3::from_array(node.bounds_max);
    let (visibility, planes) = frustum.classify_aabb_masked(lo, hi, planes);
    let distance = distance_to_aabb(eye, lo, hi);
    NodeEval {
        visibility,
        planes,
        distance,
        atlas_suffices: atlas_suffices(distance, node.min_distance, scale),
    }
}

/// Whether [`traverse`] continues below a node.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Step {
    /// Do not visit the node's children.
    Stop,
    /// Visit the node's children.
    Descend,
}

#[derive(Copy, Clone, Debug)]
struct Pending {
    node: u32,
    planes: PlaneMask,
    /// An ancestor was outside the frustum: so is this node (its bounds are inside the ancestor's).
    outside: bool,
}

/// The explicit stack of [`traverse`]; keep one and reuse it so traversal does not allocate.
#[derive(Clone, Debug, Default)]
pub struct TraversalStack {
    pending: Vec<Pending>,
}

/// Top-down traversal of `nodes` (root `nodes[0]`, children after their parent) with an explicit
/// stack, in the stored pre-order: children by increasing node id, which is index-buffer order (the builder
/// stores a node's quadrants in the order 0, 2, 1, 3, so quadrant order would not be; hand-made trees in
/// quadrant order are visited in quadrant order). Every visited node is [`evaluate`]d and handed
/// to `visit`, which decides whether to descend. Below a node that is outside the frustum, descendants
/// are reported `Outside` without testing (only a visitor that descends into culled nodes sees them,
/// e.g. the paging traversal).
///
/// Robust against unvalidated records: a child id that is out of range or not greater than its
/// parent's id is ignored (validated files never have one), so the traversal always ends and visits
/// each node at most once per parent link. An empty slice visits nothing.
pub fn traverse(
    nodes: &[NodeRecord],
    frustum: &Frustum,
    eye: DVec3,
    scale: f64,
    stack: &mut TraversalStack,
    mut visit: impl FnMut(NodeId, &NodeRecord, &NodeEval) -> Step,
) {
    let pending = &mut stack.pending;
    pending.clear();
    if nodes.is_empty() {
        return;
    }
    pending.push(Pending {
        node: 0,
        planes: PlaneMask::ALL,
        outside: false,
    });
    while let Some(p) = pending.pop() {
        let Some(node) = nodes.get(p.node as usize) else {
            continue;
        };
        let eval = if p.outside {
            let lo = DVec3::from_array(node.bounds_min);
            let hi = DVec3::from_array(node.bounds_max);
            let distance = distance_to_aabb(eye, lo, hi);
            NodeEval {
                visibility: Visibility::Outside,
                planes: PlaneMask::NONE,
                distance,
                atlas_suffices: atlas_suffices(distance, node.min_distance, scale),
            }
        } else {
            evaluate(node, frustum, eye, p.planes, scale)
        };
        if visit(NodeId(p.node), node, &eval) == Step::Stop {
            continue;
        }
        let outside = eval.visibility == Visibility::Outside;
        // Decreasing ids on the stack → increasing ids (index order) when popped. `NONE` sorts last.
        let mut children = node.children;
        children.sort_unstable();
        for &c in children.iter().rev() {
            if c != NONE && c > p.node && (c as usize) < nodes.len() {
                pending.push(Pending {
                    node: c,
                    planes: eval.planes,
                    outside,
                });
            }
        }
    }
}

/// Computes this frame's cut into `out` (cleared first): the paper's §4 rendering traversal with all
/// nodes in memory. `scale` is [`min_distance_scale`]; distances are measured from `camera.eye`, culling
/// uses `frustum` (normally `camera.frustum()`, passed in so callers can reuse or widen it).
///
/// A leaf is a node with a leaf record (`leaf != NONE`). Every triangle of a leaf that is not outside the
/// frustum is drawn by exactly one item, and no item is an ancestor of another.
pub fn select(nodes: &[NodeRecord], camera: &Camera, frustum: &Frustum, scale: f64, out: &mut Cut) {
    let Cut {
        items,
        visited,
        culled,
        stack,
    } = out;
    items.clear();
    *visited = 0;
    *culled = 0;
    traverse(
        nodes,
        frustum,
        camera.eye,
        scale,
        stack,
        |id, node, eval| {
            *visited += 1;
            if eval.visibility == Visibility::Outside {
                *culled += 1;
                return Step::Stop;
            }
            let source = if eval.atlas_suffices {
                Source::Atlas
            } else if node.leaf != NONE {
                Source::Original
            } else {
                return Step::Descend;
            };
            items.push(CutItem {
                node: id,
                source,
                level: u8::try_from(node.level).unwrap_or(u8::MAX),
                first_index: node.first_index,
                index_count: node.index_count,
                distance: eval.distance,
            });
            Step::Stop
        },
    );
}

/// Summary of a cut, for reports and the simulator (the analysis twin of [`Cut`]).
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct CutStats {
    /// Items drawn with an atlas / with original textures.
    pub atlas_nodes: u32,
    pub original_nodes: u32,
    /// Triangles drawn with atlases / with original textures.
    pub atlas_triangles: u64,
    pub original_triangles: u64,
    pub visited: u32,
    pub culled: u32,
    /// `levels[k]`: items at depth `k` (length = deepest item's level + 1; empty for an empty cut).
    pub levels: Vec<u32>,
}

impl CutStats {
    pub fn of(cut: &Cut) -> CutStats {
        let mut s = CutStats {
            visited: cut.visited,
            culled: cut.culled,
            ..CutStats::default()
        };
        for item in &cut.items {
            let tris = u64::from(item.index_count / 3);
            match item.source {
                Source::Atlas => {
                    s.atlas_nodes += 1;
                    s.atlas_triangles += tris;
                }
                Source::Original => {
                    s.original_nodes += 1;
                    s.original_triangles += tris;
                }
            }
            let level = usize::from(item.level);
            if s.levels.len() <= level {
                s.levels.resize(level + 1, 0);
            }
            s.levels[level] += 1;
        }
        s
    }

    /// All items.
    pub fn nodes(&self) -> u32 {
        self.atlas_nodes + self.original_nodes
    }

    /// All triangles drawn.
    pub fn triangles(&self) -> u64 {
        self.atlas_triangles + self.original_triangles
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ids::Cell;
    use crate::scene::UpAxis;

    fn params() -> BuildParams {
        BuildParams {
            d_min: 100.0,
            screen_width: 1920,
            fov_deg: 60.0,
            texel_ratio: 1.0,
            atlas_size: 1024,
            border: 8,
            max_depth: 16,
            up: UpAxis::Y,
        }
    }

    #[test]
    fn scale_is_linear_in_width_and_ratio_and_follows_fov() {
        let p = params();
        let at = |w, r, c| {
            min_distance_scale(
                &p,
                &SelectOptions {
                    screen_width: w,
                    texel_ratio: r,
                    fov_x_deg: c,
                },
            )
        };
        assert_eq!(at(1920, 1.0, 60.0), Ok(1.0));
        assert_eq!(at(960, 1.0, 60.0), Ok(0.5));
        assert_eq!(at(3840, 2.0, 60.0), Ok(4.0));
        // Half the fov tangent → twice the distance (zoom by 2).
        let c = 2.0 * ((30f64.to_radians()).tan() * 0.5).atan().to_degrees();
        let s = at(1920, 1.0, c).unwrap_or(f64::NAN);
        assert!((s - 2.0).abs() < 1e-12, "{s}");
        // Consistent with f_proj: the distance where the run-time f_proj equals the built one.
        let scaled = BuildParams {
            screen_width: 2560,
            texel_ratio: 1.5,
            fov_deg: 45.0,
            ..p.clone()
        };
        let s = at(2560, 1.5, 45.0).unwrap_or(f64::NAN);
        let moved = BuildParams {
            d_min: p.d_min * s,
            ..scaled
        };
        assert!((moved.f_proj() - p.f_proj()).abs() < 1e-12 * p.f_proj());
        assert_eq!(
            at(0, 1.0, 60.0),
            Err(SelectError::BadOption {
                field: "screen_width",
                value: 0.0
            })
        );
        assert!(matches!(
            at(1920, f64::NAN, 60.0),
            Err(SelectError::BadOption {
                field: "texel_ratio",
                ..
            })
        ));
        assert!(matches!(
            at(1920, 1.0, 180.0),
            Err(SelectError::BadOption {
                field: "fov_x_deg",
                ..
            })
        ));
        let bad = BuildParams {
            fov_deg: 0.0,
            ..p.clone()
        };
        assert!(matches!(
            min_distance_scale(&bad, &SelectOptions::built_for(&p)),
            Err(SelectError::BadBuildParams {
                field: "fov_deg",
                ..
            })
        ));
    }

    fn node(
        lo: [f64; 3],
        hi: [f64; 3],
        min_distance: f64,
        children: [u32; 4],
        leaf: u32,
    ) -> NodeRecord {
        NodeRecord {
            bounds_min: lo,
            bounds_max: hi,
            min_distance,
            cell: Cell::default(),
            level: 0,
            parent: NONE,
            children,
            first_index: 0,
            index_count: 3,
            atlas_block: 0,
            leaf,
        }
    }

    fn camera(eye: DVec3, target: DVec3) -> Camera {
        Camera {
            eye,
            target,
            up: DVec3::Y,
            fov_x_deg: 60.0,
            aspect: 1.5,
            near: 0.1,
            far: 1e4,
        }
    }

    #[test]
    fn equality_descends_and_is_stable() {
        // A single leaf at distance exactly 100 from the eye, min_distance 100.
        let nodes = [node(
            [0.0, 0.0, -110.0],
            [10.0, 10.0, -100.0],
            100.0,
            [NONE; 4],
            0,
        )];
        let c = camera(DVec3::new(5.0, 5.0, 0.0), DVec3::new(5.0, 5.0, -1.0));
        let mut cut = Cut::new();
        select(&nodes, &c, &c.frustum(), 1.0, &mut cut);
        assert_eq!(cut.items.len(), 1);
        assert_eq!(cut.items[0].distance, 100.0);
        assert_eq!(
            cut.items[0].source,
            Source::Original,
            "d == min_distance descends"
        );
        select(&nodes, &c, &c.frustum(), 1.0 - 1e-12, &mut cut);
        assert_eq!(cut.items[0].source, Source::Atlas, "just beyond: atlas");
    }

    #[test]
    fn items_follow_the_stored_order_not_quadrant_order() {
        // Regression (issue 8, tests/cpu/select/real_tree.rs): the builder stores quadrants in the order
        // 0, 2, 1, 3 (node ids and index ranges); the cut must still come out in index order.
        let leaf = |first_index: u32, leaf: u32| NodeRecord {
            first_index,
            ..node([0.0; 3], [1.0; 3], 1e9, [NONE; 4], leaf)
        };
        let mut root = node([0.0; 3], [1.0; 3], 1e9, [1, 3, 2, 4], NONE);
        root.index_count = 12;
        let nodes = [root, leaf(0, 0), leaf(3, 1), leaf(6, 2), leaf(9, 3)];
        let c = camera(DVec3::new(0.5, 0.5, 3.0), DVec3::new(0.5, 0.5, 0.0));
        let mut cut = Cut::new();
        select(&nodes, &c, &c.frustum(), 1.0, &mut cut);
        let firsts: Vec<u32> = cut.items.iter().map(|i| i.first_index).collect();
        assert_eq!(firsts, [0, 3, 6, 9]);
    }

    #[test]
    fn corrupt_child_links_are_ignored_without_panic() {
        // Child pointing back at the root, out of range, and at itself.
        let nodes = [
            node([0.0; 3], [1.0; 3], 1e9, [0, 7, 1, NONE], NONE),
            node([0.0; 3], [1.0; 3], 1e9, [1, NONE, NONE, NONE], NONE),
        ];
        let c = camera(DVec3::new(0.5, 0.5, 10.0), DVec3::new(0.5, 0.5, 0.0));
        let mut cut = Cut::new();
        select(&nodes, &c, &c.frustum(), 1.0, &mut cut);
        assert_eq!(cut.visited, 2);
        assert!(
            cut.items.is_empty(),
            "inner nodes without valid children draw nothing"
        );
        select(&[], &c, &c.frustum(), 1.0, &mut cut);
        assert_eq!((cut.visited, cut.items.len()), (0, 0));
    }

    #[test]
    fn stats_count_sources_triangles_and_levels() {
        let item = |level, source, count| CutItem {
            node: NodeId(0),
            source,
            level,
            first_index: 0,
            index_count: count,
            distance: 0.0,
        };
        let cut = Cut {
            items: vec![
                item(0, Source::Atlas, 30),
                item(2, Source::Original, 9),
                item(2, Source::Atlas, 3),
            ],
            visited: 7,
            culled: 2,
            ..Cut::default()
        };
        let s = CutStats::of(&cut);
        assert_eq!((s.atlas_nodes, s.original_nodes), (2, 1));
        assert_eq!((s.atlas_triangles, s.original_triangles), (11, 3));
        assert_eq!(s.levels, vec![1, 0, 2]);
        assert_eq!(
            (s.nodes(), s.triangles(), s.visited, s.culled),
            (3, 14, 7, 2)
        );
    }
}
