//! Per-level numbers of one tree ([`LevelStats`]): nodes, leaves, min_distances, and the scene triangles
//! and pieces the level's leaves store.

use crate::ids::NONE;
use serde::Serialize;

/// Per-level numbers of one tree.
#[derive(Clone, Debug, Serialize)]
pub struct LevelStats {
    pub level: u8,
    pub nodes: u64,
    pub leaves: u64,
    pub min_distance_min: f64,
    pub min_distance_max: f64,
    /// Distinct scene triangles with a piece stored in the level's leaves (the tree line's
    /// `triangles`, where every triangle's pieces lie in one level).
    pub triangles_in_leaves: u64,
    /// Triangles stored in the level's leaves: the pieces of those triangles (more than them where
    /// repeats are baked or large triangles cut; the column summed the pieces under the triangles'
    /// name: fault hunt, session 38).
    pub pieces_in_leaves: u64,
}

/// The [`LevelStats`] of tree `t`, root level first.
pub(super) fn level_stats(t: &crate::store::TreeView<'_>) -> Vec<LevelStats> {
    let mut levels: Vec<LevelStats> = Vec::new();
    let mut sources: Vec<std::collections::HashSet<u32>> = Vec::new();
    for n in t.nodes {
        let l = n.level as usize;
        while levels.len() <= l {
            sources.push(Default::default());
            levels.push(LevelStats {
                level: levels.len() as u8,
                nodes: 0,
                leaves: 0,
                min_distance_min: f64::INFINITY,
                min_distance_max: 0.0,
                triangles_in_leaves: 0,
                pieces_in_leaves: 0,
            });
        }
        let s = &mut levels[l];
        s.nodes += 1;
        s.min_distance_min = s.min_distance_min.min(n.min_distance);
        s.min_distance_max = s.min_distance_max.max(n.min_distance);
        if n.leaf != NONE {
            s.leaves += 1;
            s.pieces_in_leaves += u64::from(n.index_count / 3);
            let first = n.first_index as usize / 3;
            let pieces = first..first + n.index_count as usize / 3;
            // Validated at open: every index range lies in the tree's indices.
            if let Some(ids) = t.source_triangles.get(pieces) {
                sources[l].extend(ids.iter().copied());
            }
        }
    }
    for (s, ids) in levels.iter_mut().zip(&sources) {
        s.triangles_in_leaves = ids.len() as u64;
    }
    levels
}
