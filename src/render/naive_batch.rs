//! The draws of the naive baseline (`--mode original`, [`crate::render::Mode::Original`]) as plain data (no
//! wgpu types), planned once per renderer: every leaf's triangles regrouped per (leaf, original texture),
//! one [`NaiveDraw`] per group with at least one triangle, in its own index buffer. The renderer's naive
//! module uploads the indices, one texture per distinct original and one bind group per (material,
//! original) pair, and per frame draws
//! the groups of the visible leaves one `draw_indexed` after one `set_bind_group` each.
//!
//! No triangle is dropped: a leaf whose index range, vertex, original or texture-array mapping (TAM) entry
//! cannot be found is a [`NaiveBatchError`]; a (leaf, original) pair without triangles has nothing to draw
//! and is counted ([`NaiveBatch::empty_pairs`]).

use super::batch::{Pass, TreeBatchInfo};
use super::wgsl::naive::{ALPHA_MASK, ALPHA_OPAQUE};
use super::wgsl::tree::{LeafInfo, TamEntry};
use crate::select::Cut;
use crate::store::TreeFile;

/// One draw: a leaf's triangles that use one original texture.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct NaiveDraw {
    /// First index in [`NaiveBatch::indices`].
    pub first_index: u32,
    pub index_count: u32,
    /// The tree's first vertex in the shared vertex buffer (indices are tree-local).
    pub base_vertex: i32,
    /// The tree's leaf base (which tree's leaves the draw belongs to; not drawn: naive.wgsl reads the
    /// vertex's own global leaf).
    pub leaf_base: u32,
    /// Index into the (material, distinct original texture) pairs (`Resident::material_originals`, one
    /// bind group each).
    pub texture: u32,
    pub pass: Pass,
}

/// The naive baseline's draw data for every tree of a file.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct NaiveBatch {
    /// Tree-local vertex indices regrouped per (leaf, original): the naive index buffer.
    pub indices: Vec<u32>,
    /// In tree order, leaf order, original order.
    pub draws: Vec<NaiveDraw>,
    /// Per global leaf: its draws `[first, first + count)` in `draws`.
    pub leaf_draws: Vec<(u32, u32)>,
    /// (leaf, original) pairs no triangle uses: nothing to draw, no draw made.
    pub empty_pairs: u32,
}

/// A draw the naive plan cannot make (the file's tables disagree with each other).
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum NaiveBatchError {
    #[error("the file has no tree {tree}")]
    MissingTree { tree: usize },
    #[error(
        "tree {tree} leaf {leaf}: indices {first}..+{count} reach past the tree's {len} indices"
    )]
    LeafIndices {
        tree: usize,
        leaf: usize,
        first: u32,
        count: u32,
        len: usize,
    },
    #[error("tree {tree} leaf {leaf}: {count} indices are not whole triangles")]
    PartialTriangle {
        tree: usize,
        leaf: usize,
        count: u32,
    },
    #[error(
        "tree {tree} leaf {leaf}: index {index} names vertex {vertex}; the tree has {vertices}"
    )]
    Vertex {
        tree: usize,
        leaf: usize,
        index: u32,
        vertex: u32,
        vertices: usize,
    },
    #[error(
        "tree {tree} leaf {leaf}: a triangle uses original {original}; the leaf has {originals}"
    )]
    Original {
        tree: usize,
        leaf: usize,
        original: u32,
        originals: u32,
    },
    #[error("global leaf {leaf} has no GPU leaf record ({leaves} records)")]
    MissingLeaf { leaf: usize, leaves: usize },
    #[error(
        "global leaf {leaf}, original {original}: TAM entry {entry} is missing ({entries} entries, \
         {pairs} (material, original) indices)"
    )]
    MissingTam {
        leaf: usize,
        original: u32,
        entry: usize,
        entries: usize,
        pairs: usize,
    },
    #[error("more than 2^32 naive indices")]
    TooLarge,
    #[error("tree {tree}: cut item node {node} is not in the tree's {nodes} nodes")]
    CutNode {
        tree: usize,
        node: usize,
        nodes: usize,
    },
    #[error("global leaf {leaf} has no draw list ({leaves} lists)")]
    MissingDrawList { leaf: usize, leaves: usize },
    #[error("global leaf {leaf}: draws {first}..+{count} reach past the {draws} draws")]
    DrawRange {
        leaf: usize,
        first: u32,
        count: u32,
        draws: usize,
    },
}

/// The naive draws of one frame, by pass ([`Pass::ALL`] order), each list in cut order: the draws of every
/// leaf below a cut item (the tree modes' culling). `leaf_draws` is
/// [`NaiveBatch::leaf_draws`] (per global leaf, its draws). A cut item, leaf or draw range the tables do
/// not have is an error, not a skipped draw.
pub fn visible_draws(
    infos: &[TreeBatchInfo],
    cuts: &[Cut],
    leaf_draws: &[(u32, u32)],
    draws: &[NaiveDraw],
) -> Result<[Vec<NaiveDraw>; 3], NaiveBatchError> {
    let mut lists: [Vec<NaiveDraw>; 3] = Default::default();
    for (tree, (info, cut)) in infos.iter().zip(cuts).enumerate() {
        for item in &cut.items {
            let node = item.node.idx();
            let &(first, count) = info.leaf_ranges.get(node).ok_or(NaiveBatchError::CutNode {
                tree,
                node,
                nodes: info.leaf_ranges.len(),
            })?;
            for l in first..first.saturating_add(count) {
                let leaf = info.leaf_base.saturating_add(l) as usize;
                let &(d0, dn) = leaf_draws
                    .get(leaf)
                    .ok_or(NaiveBatchError::MissingDrawList {
                        leaf,
                        leaves: leaf_draws.len(),
                    })?;
                let range = draws
                    .get(d0 as usize..(d0 as usize).saturating_add(dn as usize))
                    .ok_or(NaiveBatchError::DrawRange {
                        leaf,
                        first: d0,
                        count: dn,
                        draws: draws.len(),
                    })?;
                for draw in range {
                    lists[draw.pass as usize].push(*draw);
                }
            }
        }
    }
    Ok(lists)
}

/// The tables the plan reads besides the file: the renderer's (`render::resident::gather_tables`).
#[derive(Copy, Clone, Debug)]
pub struct NaiveTables<'a> {
    /// Per tree (in file order): leaf base and vertex base.
    pub infos: &'a [TreeBatchInfo],
    /// Per global leaf: its first TAM entry.
    pub leaves: &'a [LeafInfo],
    /// Per TAM entry: the material's alpha mode (the draw's pass).
    pub tam: &'a [TamEntry],
    /// Per TAM entry: its (material, distinct original texture) pair.
    pub tam_material_original: &'a [u32],
}

impl<'a> NaiveTables<'a> {
    /// The tables of [`crate::render::resident::gather_tables`].
    pub fn of(g: &'a crate::render::resident::GpuTables) -> NaiveTables<'a> {
        NaiveTables {
            infos: &g.infos,
            leaves: &g.leaves,
            tam: &g.tam,
            tam_material_original: &g.tam_material_original,
        }
    }
}

/// The pass of an original-texture draw of a material with alpha code `alpha_mode`.
fn pass_of(alpha_mode: u32) -> Pass {
    match alpha_mode {
        ALPHA_OPAQUE => Pass::Opaque,
        ALPHA_MASK => Pass::Mask,
        _ => Pass::Blend,
    }
}

/// Plans the naive draws of every tree of `file` (see the module docs).
pub fn plan_naive(file: &TreeFile, tables: NaiveTables<'_>) -> Result<NaiveBatch, NaiveBatchError> {
    let mut batch = NaiveBatch::default();
    for (t, info) in tables.infos.iter().enumerate() {
        let view = file
            .tree(t)
            .ok_or(NaiveBatchError::MissingTree { tree: t })?;
        for (li, leaf) in view.leaves.iter().enumerate() {
            let start = batch.draws.len() as u32;
            let groups = regroup_leaf(t, li, leaf, view.indices, view.vertices)?;
            let global_leaf = info.leaf_base as usize + li;
            let first_tam = tables
                .leaves
                .get(global_leaf)
                .ok_or(NaiveBatchError::MissingLeaf {
                    leaf: global_leaf,
                    leaves: tables.leaves.len(),
                })?
                .first_tam as usize;
            // The texture and pass of each original of the leaf.
            let mut kinds = Vec::with_capacity(groups.len());
            for o in 0..groups.len() as u32 {
                let entry = first_tam + o as usize;
                let (Some(&texture), Some(e)) = (
                    tables.tam_material_original.get(entry),
                    tables.tam.get(entry),
                ) else {
                    return Err(NaiveBatchError::MissingTam {
                        leaf: global_leaf,
                        original: o,
                        entry,
                        entries: tables.tam.len(),
                        pairs: tables.tam_material_original.len(),
                    });
                };
                kinds.push((texture, pass_of(e.alpha_mode)));
            }
            let mut blends = false;
            for (tris, &(texture, pass)) in groups.iter().zip(&kinds) {
                if tris.is_empty() {
                    batch.empty_pairs += 1;
                    continue;
                }
                // Blended triangles are drawn below, in index order; here, in the mask pass, their
                // opaque texels write colour and depth first, as the tree's blend nodes do (without it a
                // far BLEND quad's opaque texels were blended over a near one's: 18.8 dB between the
                // modes; session 30's alpha hunt).
                let pass = if pass == Pass::Blend {
                    blends = true;
                    Pass::Mask
                } else {
                    pass
                };
                let first_index =
                    u32::try_from(batch.indices.len()).map_err(|_| NaiveBatchError::TooLarge)?;
                batch.indices.extend(tris.iter().flatten());
                batch.draws.push(NaiveDraw {
                    first_index,
                    index_count: 3 * tris.len() as u32,
                    base_vertex: info.vertex_base,
                    leaf_base: info.leaf_base,
                    texture,
                    pass,
                });
            }
            // Blending is not commutative: a leaf's blended triangles are drawn in index-buffer order, as
            // the tree's blend pass draws them (`batch::blend_list`), one draw per run of one original.
            // Grouped by original, overlapping BLEND quads of two materials drew in the other order than
            // the tree's (32.6 dB between the modes; fault hunt, session 28).
            if blends {
                let range = leaf_triangles(t, li, leaf, view.indices)?;
                for tri in range.chunks_exact(3) {
                    let Some(o) = view.vertices.get(tri[0] as usize).map(|v| v.original) else {
                        continue; // checked by regroup_leaf
                    };
                    let Some(&(texture, Pass::Blend)) = kinds.get(o as usize) else {
                        continue;
                    };
                    let first_index = u32::try_from(batch.indices.len())
                        .map_err(|_| NaiveBatchError::TooLarge)?;
                    batch.indices.extend_from_slice(tri);
                    // Only a draw of this leaf (one made here: contiguous and blended) is extended.
                    let this_leaf = batch.draws.len() as u32 > start;
                    match batch.draws.last_mut() {
                        Some(d)
                            if this_leaf
                                && d.pass == Pass::Blend
                                && d.texture == texture
                                && d.first_index + d.index_count == first_index =>
                        {
                            d.index_count += 3;
                        }
                        _ => batch.draws.push(NaiveDraw {
                            first_index,
                            index_count: 3,
                            base_vertex: info.vertex_base,
                            leaf_base: info.leaf_base,
                            texture,
                            pass: Pass::Blend,
                        }),
                    }
                }
            }
            batch
                .leaf_draws
                .push((start, batch.draws.len() as u32 - start));
        }
    }
    u32::try_from(batch.indices.len()).map_err(|_| NaiveBatchError::TooLarge)?;
    Ok(batch)
}

/// The indices of leaf `li` of tree `t`: whole triangles inside `indices`.
fn leaf_triangles<'a>(
    t: usize,
    li: usize,
    leaf: &crate::store::format::LeafRecord,
    indices: &'a [u32],
) -> Result<&'a [u32], NaiveBatchError> {
    let first = leaf.first_index as usize;
    let range = indices
        .get(first..first.saturating_add(leaf.index_count as usize))
        .ok_or(NaiveBatchError::LeafIndices {
            tree: t,
            leaf: li,
            first: leaf.first_index,
            count: leaf.index_count,
            len: indices.len(),
        })?;
    if range.len() % 3 != 0 {
        return Err(NaiveBatchError::PartialTriangle {
            tree: t,
            leaf: li,
            count: leaf.index_count,
        });
    }
    Ok(range)
}

/// The triangles of leaf `li` of tree `t` per original texture (`[original][triangle]`, each list in index
/// order). A triangle belongs to the original of its first vertex (the preprocessor gives all three the
/// same).
fn regroup_leaf(
    t: usize,
    li: usize,
    leaf: &crate::store::format::LeafRecord,
    indices: &[u32],
    vertices: &[crate::model::TreeVertex],
) -> Result<Vec<Vec<[u32; 3]>>, NaiveBatchError> {
    let range = leaf_triangles(t, li, leaf, indices)?;
    let mut groups = vec![Vec::new(); leaf.original_count as usize];
    for (k, tri) in range.chunks_exact(3).enumerate() {
        let tri = [tri[0], tri[1], tri[2]];
        let v = vertices
            .get(tri[0] as usize)
            .ok_or(NaiveBatchError::Vertex {
                tree: t,
                leaf: li,
                index: leaf.first_index + 3 * k as u32,
                vertex: tri[0],
                vertices: vertices.len(),
            })?;
        groups
            .get_mut(v.original as usize)
            .ok_or(NaiveBatchError::Original {
                tree: t,
                leaf: li,
                original: v.original,
                originals: leaf.original_count,
            })?
            .push(tri);
    }
    Ok(groups)
}
