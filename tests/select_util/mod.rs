//! Shared helpers of the `select_*` tests and the `select` bench: hand-made and synthetic atlas trees as
//! `NodeRecord`s, a naive reference of the §4 traversal, and the cut invariants.
#![allow(dead_code)]

use atlastree::camera::{Camera, Frustum, Visibility};
use atlastree::ids::{Cell, NONE, NodeId};
use atlastree::select::{Cut, Source, atlas_suffices};
use atlastree::store::format::NodeRecord;
use glam::DVec3;

/// A quadtree shape. Quadrant bit 0 = +x, bit 1 = +z (y is up).
#[derive(Clone, Debug)]
pub enum Shape {
    /// A leaf with `tris` triangles, its geometry `height` tall, its resolution clamp (1 = none).
    Leaf { tris: u32, height: f64, clamp: f64 },
    /// An inner node; at least one child should be present.
    Inner(Box<[Option<Shape>; 4]>),
}

impl Shape {
    pub fn leaf(tris: u32, height: f64) -> Shape {
        Shape::Leaf {
            tris,
            height,
            clamp: 1.0,
        }
    }
    pub fn inner(children: [Option<Shape>; 4]) -> Shape {
        Shape::Inner(Box::new(children))
    }
}

/// Where a tree sits: footprint corner (x, ground y, z), side length, and d_min; `inset` shrinks each
/// leaf's footprint by this fraction of its cell on every side (0 = the full cell).
#[derive(Copy, Clone, Debug)]
pub struct Placement {
    pub corner: DVec3,
    pub size: f64,
    pub d_min: f64,
    pub inset: f64,
}

/// Node records of `shape` in pre-order, with index ranges (leaves in tree order), cells, parents,
/// leaf ids and `min_distance` as the paper defines it (leaf: d_min / clamp; inner: 2 · max of children).
pub fn build_tree(shape: &Shape, at: Placement) -> Vec<NodeRecord> {
    let mut b = Builder {
        nodes: Vec::new(),
        indices: 0,
        leaves: 0,
        at,
    };
    b.add(
        shape,
        NONE,
        0,
        Cell::default(),
        at.corner.x,
        at.corner.z,
        at.size,
    );
    b.nodes
}

struct Builder {
    nodes: Vec<NodeRecord>,
    indices: u32,
    leaves: u32,
    at: Placement,
}

impl Builder {
    #[allow(clippy::too_many_arguments)]
    fn add(
        &mut self,
        shape: &Shape,
        parent: u32,
        level: u32,
        cell: Cell,
        x: f64,
        z: f64,
        s: f64,
    ) -> u32 {
        let id = self.nodes.len() as u32;
        self.nodes.push(NodeRecord {
            bounds_min: [0.0; 3],
            bounds_max: [0.0; 3],
            min_distance: 0.0,
            cell,
            level,
            parent,
            children: [NONE; 4],
            first_index: self.indices,
            index_count: 0,
            atlas_block: id,
            leaf: NONE,
        });
        let ground = self.at.corner.y;
        match shape {
            Shape::Leaf {
                tris,
                height,
                clamp,
            } => {
                let i = s * self.at.inset;
                let n = &mut self.nodes[id as usize];
                n.bounds_min = [x + i, ground, z + i];
                n.bounds_max = [x + s - i, ground + height, z + s - i];
                n.min_distance = self.at.d_min / clamp;
                n.index_count = tris * 3;
                n.leaf = self.leaves;
                self.leaves += 1;
                self.indices += tris * 3;
            }
            Shape::Inner(children) => {
                let mut lo = DVec3::splat(f64::INFINITY);
                let mut hi = DVec3::splat(f64::NEG_INFINITY);
                let mut md: f64 = 0.0;
                let h = s * 0.5;
                for (q, c) in children.iter().enumerate() {
                    let Some(c) = c else { continue };
                    let (cx, cz) = (x + h * (q & 1) as f64, z + h * (q >> 1) as f64);
                    let cid = self.add(c, id, level + 1, cell.child(q as u32), cx, cz, h);
                    let cn = self.nodes[cid as usize];
                    lo = lo.min(cn.bounds_min.into());
                    hi = hi.max(cn.bounds_max.into());
                    md = md.max(cn.min_distance);
                    self.nodes[id as usize].children[q] = cid;
                }
                let n = &mut self.nodes[id as usize];
                n.bounds_min = lo.to_array();
                n.bounds_max = hi.to_array();
                n.min_distance = 2.0 * md;
                n.index_count = self.indices - n.first_index;
            }
        }
        id
    }
}

/// The same records translated by `t`.
pub fn translate(nodes: &[NodeRecord], t: DVec3) -> Vec<NodeRecord> {
    nodes
        .iter()
        .map(|n| NodeRecord {
            bounds_min: (DVec3::from(n.bounds_min) + t).to_array(),
            bounds_max: (DVec3::from(n.bounds_max) + t).to_array(),
            ..*n
        })
        .collect()
}

/// Total index count of the tree (the root's range).
pub fn total_indices(nodes: &[NodeRecord]) -> u32 {
    nodes.first().map_or(0, |r| r.index_count)
}

/// `(node, source)` pairs of a cut.
pub fn pairs(cut: &Cut) -> Vec<(u32, Source)> {
    cut.items.iter().map(|i| (i.node.0, i.source)).collect()
}

/// Paper §4 written as plainly as possible: recursion, full six-plane test at every node.
pub fn reference(
    nodes: &[NodeRecord],
    camera: &Camera,
    frustum: &Frustum,
    scale: f64,
) -> Vec<(u32, Source)> {
    fn go(
        nodes: &[NodeRecord],
        i: u32,
        c: &Camera,
        f: &Frustum,
        scale: f64,
        out: &mut Vec<(u32, Source)>,
    ) {
        let n = &nodes[i as usize];
        let (lo, hi) = (DVec3::from(n.bounds_min), DVec3::from(n.bounds_max));
        if f.classify_aabb(lo, hi) == Visibility::Outside {
            return;
        }
        let d = atlastree::camera::distance_to_aabb(c.eye, lo, hi);
        if atlas_suffices(d, n.min_distance, scale) {
            out.push((i, Source::Atlas));
        } else if n.leaf != NONE {
            out.push((i, Source::Original));
        } else {
            for &ch in &n.children {
                if ch != NONE {
                    go(nodes, ch, c, f, scale, out);
                }
            }
        }
    }
    let mut out = Vec::new();
    if !nodes.is_empty() {
        go(nodes, 0, camera, frustum, scale, &mut out);
    }
    out
}

/// True if `a` is a proper ancestor of `b`.
pub fn is_ancestor(nodes: &[NodeRecord], a: u32, b: u32) -> bool {
    let mut p = nodes[b as usize].parent;
    while p != NONE {
        if p == a {
            return true;
        }
        p = nodes[p as usize].parent;
    }
    false
}

/// The cut invariants: items in index order; no item is an ancestor of another; originals only at
/// leaves; every triangle drawn at most once, and every triangle of a leaf that is not outside the
/// frustum exactly once. Returns the first violation.
pub fn check_cut(nodes: &[NodeRecord], frustum: &Frustum, cut: &Cut) -> Result<(), String> {
    for w in cut.items.windows(2) {
        if w[0].first_index + w[0].index_count > w[1].first_index {
            return Err(format!(
                "items out of index order or overlapping: {:?} then {:?}",
                w[0], w[1]
            ));
        }
    }
    for a in &cut.items {
        for b in &cut.items {
            if is_ancestor(nodes, a.node.0, b.node.0) {
                return Err(format!(
                    "{} is an ancestor of {} and both are drawn",
                    a.node, b.node
                ));
            }
        }
        let n = &nodes[a.node.idx()];
        if a.source == Source::Original && n.leaf == NONE {
            return Err(format!(
                "{} is drawn with original textures but is not a leaf",
                a.node
            ));
        }
        if (a.first_index, a.index_count, u32::from(a.level))
            != (n.first_index, n.index_count, n.level)
        {
            return Err(format!("{} item does not match its record", a.node));
        }
    }
    let tris = (total_indices(nodes) / 3) as usize;
    let mut drawn = vec![0u32; tris];
    for item in &cut.items {
        for t in item.first_index / 3..(item.first_index + item.index_count) / 3 {
            drawn[t as usize] += 1;
        }
    }
    for (i, n) in nodes.iter().enumerate() {
        if n.leaf == NONE {
            continue;
        }
        let visible =
            frustum.classify_aabb(n.bounds_min.into(), n.bounds_max.into()) != Visibility::Outside;
        for t in n.first_index / 3..(n.first_index + n.index_count) / 3 {
            let c = drawn[t as usize];
            if c > 1 || (visible && c != 1) {
                return Err(format!(
                    "triangle {t} of leaf node {i} (visible: {visible}) drawn {c} times"
                ));
            }
        }
    }
    Ok(())
}

/// For each triangle, the `(level, original?)` fineness of the item drawing it (None if not drawn).
pub fn fineness(nodes: &[NodeRecord], cut: &Cut) -> Vec<Option<(u32, bool, u32)>> {
    let mut out = vec![None; (total_indices(nodes) / 3) as usize];
    for item in &cut.items {
        for t in item.first_index / 3..(item.first_index + item.index_count) / 3 {
            out[t as usize] = Some((
                u32::from(item.level),
                item.source == Source::Original,
                item.node.0,
            ));
        }
    }
    out
}

/// splitmix64: a tiny deterministic generator for synthetic trees.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// A Berlin-sized synthetic tree: a 10 km × 10 km city, irregular quadtree of depth 7, denser in the
/// centre, some quadrants empty, leaves with 200–4,000 triangles and 8–150 m tall geometry, d_min 100 m
/// (some leaves clamped to half resolution). Deterministic for a seed; about 3,000–5,000 nodes.
pub fn berlin(seed: u64) -> Vec<NodeRecord> {
    fn grow(rng: &mut Rng, depth: u32, cx: f64, cz: f64) -> Shape {
        // Distance of the cell centre from the city centre, 0 at the centre, ~1 at the corners.
        let r = ((cx - 0.5).powi(2) + (cz - 0.5).powi(2)).sqrt() / 0.707;
        let p_split = if depth <= 1 {
            1.0
        } else {
            1.6 - 0.14 * depth as f64 - 0.55 * r
        };
        if depth < 7 && rng.unit() < p_split {
            let h = 0.5f64.powi(depth as i32 + 2);
            let mut children: [Option<Shape>; 4] = Default::default();
            let keep = (rng.next_u64() % 4) as usize;
            for (q, c) in children.iter_mut().enumerate() {
                if q == keep || rng.unit() > 0.08 {
                    let (qx, qz) = (
                        cx + if q & 1 == 1 { h } else { -h },
                        cz + if q >> 1 == 1 { h } else { -h },
                    );
                    *c = Some(grow(rng, depth + 1, qx, qz));
                }
            }
            Shape::inner(children)
        } else {
            let clamp = if rng.unit() < 0.1 { 0.5 } else { 1.0 };
            Shape::Leaf {
                tris: 200 + (rng.next_u64() % 3800) as u32,
                height: rng.range(8.0, 150.0),
                clamp,
            }
        }
    }
    let mut rng = Rng(seed);
    let shape = grow(&mut rng, 0, 0.5, 0.5);
    build_tree(
        &shape,
        Placement {
            corner: DVec3::new(0.0, 34.0, 0.0),
            size: 10_000.0,
            d_min: 100.0,
            inset: 0.03,
        },
    )
}

/// A node's id as `NodeId`.
pub fn id(i: u32) -> NodeId {
    NodeId(i)
}
