//! Flattening a layout into the stored tree (paper §3, §5.1): nodes in pre-order, leaves in tree order,
//! per-leaf geometry in the exact single-UV-set form of docs/DESIGN.md "Precision", original-texture classes,
//! and the block table (one block per atlas; the tree's original textures, each once, in blocks of about an
//! atlas' size grouped by the leaves that draw them, [`super::originals`]).

use super::layout::{LayoutKind, LayoutNode, LeafLayout};
use super::originals::{MAX_BLOCK_WASTE, OriginalItem, group_by_users};
use super::prepare::{Corners, TriInfo, walk};
use crate::ids::{BlockId, LeafId, MaterialId, NodeId};
use crate::model::{
    AtlasRect, AtlasTree, BlockDesc, BlockKind, BuildParams, Leaf, Node, OriginalRef, TreeKind,
    TreeVertex,
};
use crate::scene::Scene;
use crate::texfmt::TexFormat;
use glam::{DVec2, DVec3};
use rustc_hash::FxHashMap;
use std::collections::HashMap;
use std::ops::Range;

pub use super::originals::{original_class, original_extent};
pub use crate::model::{MAX_ORIGINAL_CLASS, MIN_ORIGINAL_CLASS};

/// Where a tree goes in its forest.
#[derive(Copy, Clone, Debug)]
pub struct TreeSlot {
    pub kind: TreeKind,
    /// Index of the tree in the forest.
    pub tree_index: u32,
    /// Number of blocks of the forest's earlier trees (this tree's first block id).
    pub first_block: u32,
    /// Storage format of the tree's blocks (fixes every block's byte size).
    pub format: TexFormat,
}

/// Output of [`assemble`].
pub struct Assembled {
    pub tree: AtlasTree,
    pub blocks: Vec<BlockDesc>,
    /// Occupancy per leaf atlas (0..1), in leaf order.
    pub occupancy: Vec<f64>,
    /// Each leaf's rects' [`crate::preprocess::layout::PlannedRect::need_over_source`] (parallel to
    /// `tree.leaves[i].rects`; above 1 where the rect was capped to its source).
    pub capped: Vec<Vec<f64>>,
    /// Σ over rects of the UV area (periods) their inner rectangles show, and of the UV hull area of
    /// their triangles (what baking would store).
    pub periods_stored: f64,
    pub periods_spanned: f64,
}

struct Asm<'a> {
    scene: &'a Scene,
    infos: &'a [TriInfo],
    corners: Corners<'a>,
    order: &'a [u32],
    params: &'a BuildParams,
    tree_index: u32,
    format: TexFormat,
    out: Assembled,
    next_block: u32,
    /// The tree's stored original textures in order of first use: stored bytes and the leaves that
    /// draw it. Each is stored once, however many materials draw it ([`StoredOriginal`]);
    /// [`Asm::place_originals`] cuts them into blocks ([`group_by_users`]) when every leaf is known
    /// (docs/DESIGN.md "Originals").
    pending: Vec<(StoredOriginal, OriginalItem)>,
    pending_of: HashMap<StoredOriginal, usize>,
    /// Indices of the leaves walked so far (3 per triangle): a node's `first_index` before its geometry
    /// exists.
    index_cursor: u32,
    /// Leaves whose geometry is still to be made, in leaf order ([`Asm::make_geometry`]).
    geometry: Vec<GeometryJob>,
}

/// What makes two materials' stored original textures the same bytes: the image, its wrap (resampling
/// reads across the edges it wraps) and, in an alpha tree, a MASK material's cutoff (coverage-keeping
/// alpha mips rescale by it; kept apart whatever the build's alpha mips, so the tables do not depend on
/// that pixel option). Materials with one key share one stored original, encoded once by the leaf that
/// writes it (`image_cache::ImageCache::original`, whose `image_cache::OriginalKey` adds only what is fixed per
/// tree; MASK materials of one image with other cutoffs encode the same bytes twice under plain alpha
/// mips, a rare case left so).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
struct StoredOriginal {
    image: crate::ids::ImageId,
    wrap: [crate::scene::Wrap; 2],
    mask_cutoff: Option<u32>,
}

/// What a leaf's geometry needs besides its triangles ([`leaf_geometry`]).
struct GeometryJob {
    leaf: LeafId,
    range: Range<usize>,
    origin: DVec3,
    /// The leaf's rects: how many, the one of each (material, density class), and the slot of each
    /// material's original texture.
    rects: usize,
    rect_of: FxHashMap<(MaterialId, i32), u32>,
    slot_of: FxHashMap<MaterialId, u32>,
}

/// One leaf's geometry: its deduplicated vertices in order of first use, indices into them (3 per
/// triangle, leaf-local) and per rect the UV hull of its triangles.
struct LeafGeometry {
    vertices: Vec<TreeVertex>,
    indices: Vec<u32>,
    hulls: Vec<(DVec2, DVec2)>,
}

/// Triangles of the leaves whose geometry is made side by side before it is appended (bounds the copies
/// held at once to about this many triangles' vertices and indices, ~30 MiB).
const GEOMETRY_BATCH: usize = 1 << 18;

/// Flattens `root` (a layout over `infos`, permutation `order`) into tree `tree_index` of a forest whose
/// blocks so far number `first_block`.
pub fn assemble(
    scene: &Scene,
    infos: &[TriInfo],
    corners: Corners<'_>,
    order: &[u32],
    root: &LayoutNode,
    params: &BuildParams,
    slot: TreeSlot,
) -> Assembled {
    let TreeSlot {
        kind,
        tree_index,
        first_block,
        format,
    } = slot;
    let mut a = Asm {
        scene,
        infos,
        corners,
        order,
        params,
        tree_index,
        format,
        out: Assembled {
            tree: AtlasTree {
                kind,
                format,
                nodes: Vec::new(),
                leaves: Vec::new(),
                vertices: Vec::new(),
                indices: Vec::new(),
                source_triangles: Vec::new(),
            },
            blocks: Vec::new(),
            occupancy: Vec::new(),
            capped: Vec::new(),
            periods_stored: 0.0,
            periods_spanned: 0.0,
        },
        next_block: first_block,
        pending: Vec::new(),
        pending_of: HashMap::new(),
        index_cursor: 0,
        geometry: Vec::new(),
    };
    a.node(root, None);
    a.place_originals();
    a.make_geometry();
    a.out
}

/// Material `m`'s [`StoredOriginal`] in a tree of `kind`.
fn stored_original(scene: &Scene, kind: TreeKind, m: MaterialId) -> StoredOriginal {
    let mat = &scene.materials[m.idx()];
    let mask_cutoff = match (kind, mat.alpha) {
        // As `alpha_coverage::mask_cutoffs` picks the cutoffs it keeps coverage for.
        (TreeKind::Alpha, crate::scene::AlphaMode::Mask { cutoff }) if cutoff.is_finite() => {
            Some(cutoff.to_bits())
        }
        _ => None,
    };
    StoredOriginal {
        image: mat.image,
        wrap: mat.wrap,
        mask_cutoff,
    }
}

impl Asm<'_> {
    fn block(&mut self, kind: BlockKind, bytes: u64) -> BlockId {
        let id = BlockId(self.next_block);
        self.next_block += 1;
        self.out.blocks.push(BlockDesc {
            tree: self.tree_index,
            kind,
            bytes,
        });
        id
    }

    /// Cuts the tree's original textures into blocks of about one atlas ([`group_by_users`]), appends
    /// them after the tree's atlas blocks (each owned by its first user leaf) and points every leaf's
    /// references at their block and slot.
    fn place_originals(&mut self) {
        let budget = self.format.chain_bytes(self.params.atlas_size);
        let kind = self.out.tree.kind;
        let items: Vec<OriginalItem> = self.pending.iter().map(|p| p.1.clone()).collect();
        let blocks = group_by_users(&items, budget, MAX_BLOCK_WASTE);
        let mut place: HashMap<StoredOriginal, (BlockId, u32)> = HashMap::new();
        let mut parts: HashMap<u32, u32> = HashMap::new();
        for b in &blocks {
            let part = parts.entry(b.owner).or_default();
            let id = self.block(
                BlockKind::Originals {
                    leaf: LeafId(b.owner),
                    part: *part,
                },
                b.bytes,
            );
            *part += 1;
            for (slot, &i) in b.items.iter().enumerate() {
                place.insert(self.pending[i].0, (id, slot as u32));
            }
        }
        for o in self
            .out
            .tree
            .leaves
            .iter_mut()
            .flat_map(|l| &mut l.originals)
        {
            // Every pending original is in exactly one block (group_by_users' contract).
            if let Some(&(block, slot)) = place.get(&stored_original(self.scene, kind, o.material))
            {
                (o.block, o.slot) = (block, slot);
            }
        }
    }

    fn node(&mut self, n: &LayoutNode, parent: Option<NodeId>) -> NodeId {
        let id = NodeId(self.out.tree.nodes.len() as u32);
        let atlas_block = self.block(
            BlockKind::Atlas { node: id },
            self.format.chain_bytes(self.params.atlas_size),
        );
        let first_index = self.index_cursor;
        self.out.tree.nodes.push(Node {
            bounds_min: n.lo,
            bounds_max: n.hi,
            level: n.level,
            cell: n.cell,
            parent,
            children: [None; 4],
            min_distance: 0.0,
            first_index,
            index_count: 0,
            atlas_block,
            leaf: None,
        });
        let min_distance = match &n.kind {
            LayoutKind::Leaf(l) => {
                let leaf = self.leaf(n, l, id);
                self.out.tree.nodes[id.idx()].leaf = Some(leaf);
                self.params.d_min / l.clamp_scale
            }
            LayoutKind::Inner { children, order } => {
                let mut md: f64 = 0.0;
                for &q in order {
                    if let Some(c) = &children[q as usize] {
                        let cid = self.node(c, Some(id));
                        self.out.tree.nodes[id.idx()].children[q as usize] = Some(cid);
                        md = md.max(self.out.tree.nodes[cid.idx()].min_distance);
                    }
                }
                2.0 * md
            }
        };
        let end = self.index_cursor;
        let node = &mut self.out.tree.nodes[id.idx()];
        node.min_distance = min_distance;
        node.index_count = end - first_index;
        id
    }

    fn leaf(&mut self, n: &LayoutNode, l: &LeafLayout, node: NodeId) -> LeafId {
        let leaf_id = LeafId(self.out.tree.leaves.len() as u32);
        let origin = (n.lo + n.hi) * 0.5;
        let origin = if origin.is_finite() {
            origin
        } else {
            DVec3::ZERO
        };

        // Original textures: one reference per material, each stored original recorded once with its
        // users; the blocks are cut once all leaves are known (`place_originals` fills in `block` and
        // `slot`).
        let mut seen_materials = std::collections::HashSet::new();
        let mut originals: Vec<OriginalRef> = Vec::new();
        let mut slot_of: FxHashMap<MaterialId, u32> = FxHashMap::default();
        for r in l.rects.iter().filter(|r| seen_materials.insert(r.material)) {
            let mat = &self.scene.materials[r.material.idx()];
            let img = &self.scene.images[mat.image.idx()];
            let extent = original_extent(img.width, img.height);
            let key = stored_original(self.scene, self.out.tree.kind, r.material);
            let next = self.pending.len();
            let k = *self.pending_of.entry(key).or_insert(next);
            if k == next {
                self.pending.push((
                    key,
                    OriginalItem {
                        bytes: self.format.chain_bytes_rect(extent[0], extent[1]),
                        layer_bytes: self.format.chain_bytes(extent[0].max(extent[1])),
                        users: Vec::new(),
                    },
                ));
            }
            // Two materials of this leaf may share it: the leaf is one user.
            let users = &mut self.pending[k].1.users;
            if users.last() != Some(&leaf_id.0) {
                users.push(leaf_id.0);
            }
            slot_of.insert(r.material, originals.len() as u32);
            originals.push(OriginalRef {
                material: r.material,
                image: mat.image,
                extent,
                block: BlockId(crate::ids::NONE),
                slot: crate::ids::NONE,
            });
        }

        // Geometry: made later, leaves side by side (`make_geometry`); its index range is known now.
        let rect_of: FxHashMap<(MaterialId, i32), u32> = l
            .rects
            .iter()
            .enumerate()
            .map(|(i, r)| ((r.material, r.class), i as u32))
            .collect();
        let first_index = self.index_cursor;
        let index_count = 3 * n.range.len() as u32;
        self.index_cursor += index_count;
        self.geometry.push(GeometryJob {
            leaf: leaf_id,
            range: n.range.clone(),
            origin,
            rects: l.rects.len(),
            rect_of,
            slot_of,
        });
        self.out.occupancy.push(l.occupancy);
        self.out
            .capped
            .push(l.rects.iter().map(|r| r.need_over_source).collect());
        for r in &l.rects {
            let stored = r.uv_max - r.uv_min;
            self.out.periods_stored += stored.x * stored.y;
        }
        self.out.tree.leaves.push(Leaf {
            node,
            origin,
            // Filled in when the geometry is appended (`append_geometry`).
            first_vertex: 0,
            vertex_count: 0,
            first_index,
            index_count,
            rects: l
                .rects
                .iter()
                .map(|r| AtlasRect {
                    material: r.material,
                    outer: r.outer,
                    inner: r.inner,
                    uv_min: r.uv_min.to_array(),
                    uv_max: r.uv_max.to_array(),
                    wrap: r.wrap,
                    capped: r.capped,
                    mean: [0; 4],
                })
                .collect(),
            originals,
            clamp_scale: l.clamp_scale,
        });
        leaf_id
    }

    /// Makes every leaf's geometry ([`leaf_geometry`]) in batches of about [`GEOMETRY_BATCH`] triangles,
    /// the leaves of a batch on the rayon pool, and appends it in leaf order: the vertices, indices and
    /// source triangles a leaf-by-leaf walk would give, and the spanned periods summed in the same order.
    fn make_geometry(&mut self) {
        use rayon::prelude::*;
        let jobs = std::mem::take(&mut self.geometry);
        let mut rest = jobs.as_slice();
        while !rest.is_empty() {
            let mut take = 0;
            let mut triangles = 0;
            while take < rest.len() && (take == 0 || triangles < GEOMETRY_BATCH) {
                triangles += rest[take].range.len();
                take += 1;
            }
            let (batch, tail) = rest.split_at(take);
            rest = tail;
            let made: Vec<LeafGeometry> = batch
                .par_iter()
                .map(|job| leaf_geometry(self.infos, self.corners, self.order, job))
                .collect();
            for (job, g) in batch.iter().zip(made) {
                self.append_geometry(job, g);
            }
        }
    }

    fn append_geometry(&mut self, job: &GeometryJob, g: LeafGeometry) {
        let tree = &mut self.out.tree;
        let first_vertex = tree.vertices.len() as u32;
        tree.vertices.extend_from_slice(&g.vertices);
        tree.indices
            .extend(g.indices.iter().map(|&i| first_vertex + i));
        tree.source_triangles.extend(
            self.order[job.range.clone()]
                .iter()
                .map(|&ti| self.infos[ti as usize].scene_tri),
        );
        let leaf = &mut tree.leaves[job.leaf.idx()];
        leaf.first_vertex = first_vertex;
        leaf.vertex_count = g.vertices.len() as u32;
        for (lo, hi) in &g.hulls {
            let spanned = (*hi - *lo).max(DVec2::ZERO);
            if spanned.is_finite() {
                self.out.periods_spanned += spanned.x * spanned.y;
            }
        }
    }
}

/// Triangles of one leaf deduplicated as one run; a bigger leaf (the alpha tree's leaves can hold a
/// world's vegetation) is cut into runs made side by side and merged in order ([`leaf_geometry`]).
const GEOMETRY_RUN: usize = 1 << 16;

/// The geometry of one leaf: deduplicated vertices, positions relative to the leaf's origin, each naming
/// its rect and original-texture slot, in order of first use over the leaf's triangles.
///
/// A leaf of more than [`GEOMETRY_RUN`] triangles is made run by run on the rayon pool, each run
/// deduplicated on its own ([`run_geometry`]), then merged in run order: a vertex a run meets first gets
/// the next number exactly when no earlier run met it, which is the order of first use over the whole
/// leaf, so the vertices and indices are the ones one walk gives; the hulls' min and max do not depend on
/// the order. The merge looks up each run's distinct vertices (about a third of its corners).
fn leaf_geometry(
    infos: &[TriInfo],
    corners: Corners<'_>,
    order: &[u32],
    job: &GeometryJob,
) -> LeafGeometry {
    use rayon::prelude::*;
    let tris = &order[job.range.clone()];
    if tris.len() <= GEOMETRY_RUN {
        return run_geometry(infos, corners, tris, job);
    }
    let mut out = LeafGeometry {
        vertices: Vec::new(),
        indices: Vec::with_capacity(3 * tris.len()),
        hulls: vec![(DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)); job.rects],
    };
    let mut number: FxHashMap<[u32; 8], u32> = FxHashMap::default();
    let mut global = Vec::new();
    // A few runs per thread at a time: their copies stay ~10 MiB, not the leaf's size.
    let group = GEOMETRY_RUN * 4 * rayon::current_num_threads();
    let runs = tris.chunks(group).flat_map(|tris| {
        tris.par_chunks(GEOMETRY_RUN)
            .map(|run| run_geometry(infos, corners, run, job))
            .collect::<Vec<_>>()
    });
    for run in runs {
        global.clear();
        for v in &run.vertices {
            let key: [u32; 8] = bytemuck::cast(*v);
            let id = *number.entry(key).or_insert_with(|| {
                out.vertices.push(*v);
                out.vertices.len() as u32 - 1
            });
            global.push(id);
        }
        out.indices
            .extend(run.indices.iter().map(|&i| global[i as usize]));
        for (hull, run_hull) in out.hulls.iter_mut().zip(&run.hulls) {
            hull.0 = hull.0.min(run_hull.0);
            hull.1 = hull.1.max(run_hull.1);
        }
    }
    out
}

/// [`leaf_geometry`] of the triangles `tris` walked in order, deduplicated among themselves.
fn run_geometry(
    infos: &[TriInfo],
    corners: Corners<'_>,
    tris: &[u32],
    job: &GeometryJob,
) -> LeafGeometry {
    let mut out = LeafGeometry {
        vertices: Vec::new(),
        indices: Vec::with_capacity(3 * tris.len()),
        hulls: vec![(DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY)); job.rects],
    };
    let mut dedup: FxHashMap<[u32; 8], u32> = FxHashMap::default();
    for t in walk(infos, tris) {
        let ri = job.rect_of[&(t.material, t.class)];
        let hull = &mut out.hulls[ri as usize];
        for uv in t.uv.iter().filter(|uv| uv.is_finite()) {
            hull.0 = hull.0.min(*uv);
            hull.1 = hull.1.max(*uv);
        }
        for (k, p) in corners.of(t).iter().enumerate() {
            let v = TreeVertex {
                pos: finite3((*p - job.origin).as_vec3().to_array()),
                orig_uv: finite2(t.uv[k].as_vec2().to_array()),
                leaf: job.leaf.0,
                original: job.slot_of[&t.material],
                rect: ri,
            };
            let key: [u32; 8] = bytemuck::cast(v);
            let vi = *dedup.entry(key).or_insert_with(|| {
                out.vertices.push(v);
                out.vertices.len() as u32 - 1
            });
            out.indices.push(vi);
        }
    }
    out
}

fn finite2(a: [f32; 2]) -> [f32; 2] {
    a.map(|x| if x.is_finite() { x } else { 0.0 })
}
fn finite3(a: [f32; 3]) -> [f32; 3] {
    a.map(|x| if x.is_finite() { x } else { 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::sizing::{SizeEstimate, SizeMethod};
    use crate::preprocess::prepare::Prepared;

    /// A grid of `cells × cells` quads (two triangles each, sharing corners with their neighbours).
    /// Records of a `cells²` grid of quads (two triangles each), with their corners as cut pieces.
    fn grid(cells: u32) -> Prepared {
        let corner = |x: u32, y: u32| DVec3::new(f64::from(x), 0.0, f64::from(y));
        let uv = |p: DVec3| DVec2::new(p.x / 7.0, p.z / 5.0);
        let tri = |(piece, pos): (usize, [DVec3; 3])| TriInfo {
            scene_tri: 0,
            piece: piece as u32,
            material: MaterialId(0),
            mid: DVec2::ZERO,
            class: 0,
            area: 0.5,
            size: SizeEstimate {
                w: 1.0,
                h: 1.0,
                method: SizeMethod::Exact,
            },
            uv: pos.map(uv),
        };
        let mut pieces = Vec::new();
        for y in 0..cells {
            for x in 0..cells {
                let (a, b) = (corner(x, y), corner(x + 1, y));
                let (c, d) = (corner(x, y + 1), corner(x + 1, y + 1));
                pieces.push([a, b, c]);
                pieces.push([b, d, c]);
            }
        }
        Prepared {
            infos: pieces.iter().copied().enumerate().map(tri).collect(),
            pieces,
            palette: Default::default(),
        }
    }

    #[test]
    fn a_leaf_made_in_runs_equals_one_walk() {
        // 2 · 190² = 72,200 triangles: two runs; a scrambled order puts shared corners in both.
        let prepared = grid(190);
        let scene = crate::scene::synthetic::SceneBuilder::new(crate::scene::UpAxis::Y).build();
        let (infos, corners) = (&prepared.infos, prepared.corners(&scene));
        let n = infos.len() as u32;
        assert!(n as usize > GEOMETRY_RUN);
        let order: Vec<u32> = (0..n).map(|i| (i * 7919) % n).collect();
        let job = GeometryJob {
            leaf: LeafId(3),
            range: 0..order.len(),
            origin: DVec3::new(1.0, 0.0, 2.0),
            rects: 1,
            rect_of: [((MaterialId(0), 0), 0)].into_iter().collect(),
            slot_of: [(MaterialId(0), 0)].into_iter().collect(),
        };
        let runs = leaf_geometry(infos, corners, &order, &job);
        let walk = run_geometry(infos, corners, &order, &job);
        assert_eq!(runs.vertices, walk.vertices);
        assert_eq!(runs.indices, walk.indices);
        assert_eq!(runs.hulls, walk.hulls);
        // Each grid corner once: the runs' shared corners were merged.
        assert_eq!(walk.vertices.len(), 191 * 191);
        let split = order.split_at(GEOMETRY_RUN);
        let distinct = |tris: &[u32]| run_geometry(infos, corners, tris, &job).vertices.len();
        assert!(distinct(split.0) + distinct(split.1) > walk.vertices.len());
    }
}
