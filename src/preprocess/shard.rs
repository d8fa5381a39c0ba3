//! Sharded builds (issue 22, docs/DESIGN.md "Sharded builds"): the pixel pass cut into N shards that run
//! anywhere (an array job of a cluster scheduler), then merged into the file a one-process build writes.
//!
//! Stage boundaries: every shard runs the same plan (stages 1–3 of [`super`]: sizing, layout, assembly —
//! deterministic, so identical everywhere) and the same [`choose_cut`], which splits the forest into
//! subtrees ("units") and deals them to shards so each carries about the same rasterisation work.
//! A shard rasterises its units (stage 4, [`super::raster::raster_subtrees`]) into a shard file
//! ([`crate::store::shard`]) with each unit root's level 1; the merge copies every block into the paging
//! file and makes the atlases above the cut from those levels ([`super::raster::raster_above`], §5.1:
//! four children halved). A plain build is the same path with one shard, the cut at the roots, in memory.

use super::raster::{self, AtlasOut, Handoff};
use crate::ids::{BlockId, NodeId};
use crate::model::{AtlasForest, AtlasTree};
use crate::scene::{ImageData, Scene};
use crate::store::shard::hash128;
use std::path::{Path, PathBuf};

/// Most shards of one build.
pub const MAX_SHARDS: u32 = 4096;

/// Shard `index` of `count` (0-based).
#[derive(Copy, Clone, Debug, PartialEq, Eq, serde::Serialize)]
pub struct ShardSpec {
    pub index: u32,
    pub count: u32,
}

/// Why a `--shard` value or the scheduler's environment gave no shard.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum ShardSpecError {
    #[error("--shard {0}: expected I/N with 0 ≤ I < N ≤ {MAX_SHARDS} (e.g. 3/16), or auto")]
    Syntax(String),
    #[error(
        "--shard auto: no scheduler environment found (Slurm job array: SLURM_ARRAY_TASK_ID and \
         SLURM_ARRAY_TASK_COUNT; Kubernetes Indexed Job: JOB_COMPLETION_INDEX and ATLASTREE_SHARD_COUNT; \
         AWS Batch array: AWS_BATCH_JOB_ARRAY_INDEX and ATLASTREE_SHARD_COUNT)"
    )]
    NoScheduler,
    #[error("--shard auto ({scheduler}): {variable}={value:?} is not {expected}")]
    BadVariable {
        scheduler: &'static str,
        variable: &'static str,
        value: String,
        expected: &'static str,
    },
    #[error("--shard auto ({scheduler}): {index_var} is set but {count_var} is not")]
    NoCount {
        scheduler: &'static str,
        index_var: &'static str,
        count_var: &'static str,
    },
    #[error(
        "--shard auto (Slurm): the array runs from {min} to {max}; {why}, so submit it as --array=0-{last} \
         (N = {count})"
    )]
    SlurmArrayRange {
        /// Why the range cannot be the shards: they start at 0, or a step or gaps leave numbers out.
        why: &'static str,
        min: u32,
        max: u32,
        last: u32,
        count: u32,
    },
    #[error(
        "--shard auto ({scheduler}): {count_var}={count} shards, a build takes 1 to {MAX_SHARDS}"
    )]
    BadCount {
        scheduler: &'static str,
        count_var: &'static str,
        count: u32,
    },
    #[error("--shard auto ({scheduler}): shard {index} is outside 0..{count}")]
    OutOfRange {
        scheduler: &'static str,
        index: u32,
        count: u32,
    },
}

impl std::str::FromStr for ShardSpec {
    type Err = ShardSpecError;
    fn from_str(s: &str) -> Result<ShardSpec, ShardSpecError> {
        let bad = || ShardSpecError::Syntax(s.to_string());
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let index: u32 = i.trim().parse().map_err(|_| bad())?;
        let count: u32 = n.trim().parse().map_err(|_| bad())?;
        if count == 0 || count > MAX_SHARDS || index >= count {
            return Err(bad());
        }
        Ok(ShardSpec { index, count })
    }
}

impl std::fmt::Display for ShardSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// The schedulers `--shard auto` reads, in order: `(name, index variable, count variable)`. Slurm gives
/// both numbers; the other two give only the index, so their job sets `ATLASTREE_SHARD_COUNT`.
const SCHEDULERS: [(&str, &str, &str); 3] = [
    ("Slurm", "SLURM_ARRAY_TASK_ID", "SLURM_ARRAY_TASK_COUNT"),
    (
        "Kubernetes",
        "JOB_COMPLETION_INDEX",
        "ATLASTREE_SHARD_COUNT",
    ),
    (
        "AWS Batch",
        "AWS_BATCH_JOB_ARRAY_INDEX",
        "ATLASTREE_SHARD_COUNT",
    ),
];

/// The shard a scheduler's array task is, from its environment (`get` reads a variable): Slurm job
/// arrays, Kubernetes Indexed Jobs and AWS Batch array jobs, in that order. Slurm gives both numbers;
/// the other two give only the index, so their job sets `ATLASTREE_SHARD_COUNT` (the completions or
/// array size). Returns the shard and the scheduler's name.
pub fn shard_from_env(
    get: &dyn Fn(&str) -> Option<String>,
) -> Result<(ShardSpec, &'static str), ShardSpecError> {
    for (scheduler, index_var, count_var) in SCHEDULERS {
        let Some(index) = get(index_var) else {
            continue;
        };
        let number = |variable: &'static str, value: String, expected| {
            value
                .trim()
                .parse::<u32>()
                .map_err(|_| ShardSpecError::BadVariable {
                    scheduler,
                    variable,
                    value,
                    expected,
                })
        };
        let index = number(index_var, index, "a shard index")?;
        let count = get(count_var).ok_or(ShardSpecError::NoCount {
            scheduler,
            index_var,
            count_var,
        })?;
        let count = number(count_var, count, "a shard count")?;
        // Before the array's range: a count of 0 is no array to renumber.
        if count == 0 || count > MAX_SHARDS {
            return Err(ShardSpecError::BadCount {
                scheduler,
                count_var,
                count,
            });
        }
        // `--array=1-4` numbers tasks 1..=4 with a count of 4: task 4 would be out of range and shard 0
        // never built. The array must be 0-(N-1).
        let bound = |variable: &'static str| -> Result<Option<u32>, ShardSpecError> {
            get(variable)
                .map(|v| number(variable, v, "an array task number"))
                .transpose()
        };
        if scheduler == "Slurm"
            && let (Some(min), Some(max)) = (
                bound("SLURM_ARRAY_TASK_MIN")?,
                bound("SLURM_ARRAY_TASK_MAX")?,
            )
            && (min != 0 || max.checked_add(1) != Some(count))
        {
            let why = if min != 0 {
                "shards are numbered from 0"
            } else {
                // `--array=0-6:2` or `--array=0,2,5`: as many tasks as shards, but not 0..N-1.
                "its tasks are not every number from 0 to N - 1 (a step or a list with gaps)"
            };
            return Err(ShardSpecError::SlurmArrayRange {
                why,
                min,
                max,
                last: count.saturating_sub(1),
                count,
            });
        }
        if index >= count {
            return Err(ShardSpecError::OutOfRange {
                scheduler,
                index,
                count,
            });
        }
        return Ok((ShardSpec { index, count }, scheduler));
    }
    Err(ShardSpecError::NoScheduler)
}

/// The variables of the schedulers [`shard_from_env`] did not take its shard from (`chosen`) that are
/// set anyway, as `(variable, value)`: two schedulers' environments at once (a Kubernetes job launched
/// from a Slurm allocation, an `ATLASTREE_SHARD_COUNT` left beside a Slurm array) are said, not silently
/// ignored.
pub fn ignored_scheduler_variables(
    get: &dyn Fn(&str) -> Option<String>,
    chosen: &str,
) -> Vec<(&'static str, String)> {
    let used: Vec<&str> = SCHEDULERS
        .iter()
        .filter(|(s, _, _)| *s == chosen)
        .flat_map(|&(_, index, count)| [index, count])
        .collect();
    let mut out: Vec<(&'static str, String)> = Vec::new();
    for (_, index, count) in SCHEDULERS {
        for v in [index, count] {
            if !used.contains(&v)
                && !out.iter().any(|(seen, _)| *seen == v)
                && let Some(value) = get(v)
            {
                out.push((v, value));
            }
        }
    }
    out
}

/// Where shard `spec` of the build of `out` writes: `OUT.shard-I-of-N`, beside `out`.
pub fn shard_path(out: &Path, spec: ShardSpec) -> PathBuf {
    let mut name = out.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".shard-{}-of-{}", spec.index, spec.count));
    out.with_file_name(name)
}

/// A subtree rasterised by one shard: its root.
#[derive(Copy, Clone, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, serde::Serialize)]
pub struct Unit {
    /// Tree index in the forest.
    pub tree: u32,
    /// Root node of the subtree.
    pub node: u32,
}

/// The cut of a forest into shards' units.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Cut {
    /// Units of each shard, ascending.
    pub shards: Vec<Vec<Unit>>,
    /// Estimated work of each shard ([`subtree_work`] units).
    pub work: Vec<u64>,
}

/// Relative cost of a leaf atlas texel (resampled from sources in linear light) against an inner one
/// (2×2 combine) and an original-texture texel (resampled once): measured ratios of the pixel pass on
/// data/city and SuperTuxKart tracks, rounded.
const LEAF_WEIGHT: u64 = 4;
const ORIGINAL_WEIGHT: u64 = 2;

/// Per node of `tree`, the estimated rasterisation work of its subtree: bytes of every atlas (leaf atlases
/// ×[`LEAF_WEIGHT`]) and of the original-texture blocks its leaves own (×[`ORIGINAL_WEIGHT`]). Block
/// bytes stand for texels: within one build every block of a tree has the same bytes per texel.
pub fn subtree_work(forest: &AtlasForest, tree: &AtlasTree) -> Vec<u64> {
    let bytes = |b: BlockId| forest.blocks.get(b.idx()).map_or(0, |d| d.bytes);
    let owned = raster::leaf_owned_blocks(tree);
    let mut work = vec![0u64; tree.nodes.len()];
    // Pre-order: every child has a larger id than its parent.
    for i in (0..tree.nodes.len()).rev() {
        let n = &tree.nodes[i];
        let mut w = bytes(n.atlas_block);
        if let Some(leaf) = n.leaf {
            w *= LEAF_WEIGHT;
            let orig: u64 = owned
                .get(leaf.idx())
                .map_or(0, |bs| bs.iter().map(|&b| bytes(b)).sum());
            w += orig * ORIGINAL_WEIGHT;
        }
        for c in n.children.iter().flatten() {
            w += work.get(c.idx()).copied().unwrap_or(0);
        }
        work[i] = w;
    }
    work
}

/// Splits `forest` into units and deals them to `count` shards: starting from the tree roots, the unit
/// with the most work is replaced by its children while it holds more than 1/(8·count) of the total and
/// there are fewer than 32·count units; then the units go to shards as contiguous regions in tree order
/// ([`deal_in_tree_order`]), unless that leaves a shard more than [`REGION_IMBALANCE`] times the mean
/// work and dealing largest first to the least loaded shard ([`deal_largest_first`]) loads its most
/// loaded shard less. Deterministic: every shard and the merge compute the same cut. With one shard the
/// cut is the roots.
pub fn choose_cut(forest: &AtlasForest, count: u32) -> Cut {
    let count = count.max(1);
    let works: Vec<Vec<u64>> = forest
        .trees
        .iter()
        .map(|t| subtree_work(forest, t))
        .collect();
    let work_of = |u: &Unit| works[u.tree as usize][u.node as usize];
    let mut units: Vec<Unit> = (0..forest.trees.len() as u32)
        .filter(|&t| !forest.trees[t as usize].nodes.is_empty())
        .map(|tree| Unit { tree, node: 0 })
        .collect();
    if count > 1 {
        let total: u64 = units.iter().map(work_of).sum();
        let target = total / (8 * u64::from(count));
        let max_units = 32 * count as usize;
        while units.len() < max_units {
            let splittable = units
                .iter()
                .enumerate()
                .filter(|(_, u)| {
                    let n = &forest.trees[u.tree as usize].nodes[u.node as usize];
                    n.leaf.is_none() && n.children.iter().any(Option::is_some)
                })
                .max_by(|(_, a), (_, b)| work_of(a).cmp(&work_of(b)).then(b.cmp(a)));
            let Some((i, &u)) = splittable else {
                break;
            };
            if work_of(&u) <= target {
                break;
            }
            units.swap_remove(i);
            let node = &forest.trees[u.tree as usize].nodes[u.node as usize];
            units.extend(node.children.iter().flatten().map(|c| Unit {
                tree: u.tree,
                node: c.0,
            }));
        }
    }
    let works: Vec<(Unit, u64)> = units.into_iter().map(|u| (u, work_of(&u))).collect();
    deal(&works, count)
}

/// The units with their works dealt to `count` shards as [`choose_cut`] says: regions in tree order,
/// largest first where regions would be too unbalanced and largest first does better; each shard's units
/// sorted.
fn deal(works: &[(Unit, u64)], count: u32) -> Cut {
    let regions = deal_in_tree_order(works, count);
    let cut = if max_over_mean(&regions) <= REGION_IMBALANCE {
        regions
    } else {
        let balanced = deal_largest_first(works, count);
        let max = |c: &Cut| c.work.iter().copied().max().unwrap_or(0);
        if max(&regions) <= max(&balanced) {
            regions
        } else {
            balanced
        }
    };
    let Cut { mut shards, work } = cut;
    for s in &mut shards {
        s.sort();
    }
    Cut { shards, work }
}

/// How far over the mean work the most loaded shard of [`deal_in_tree_order`] may be before
/// [`choose_cut`] compares it with [`deal_largest_first`].
pub const REGION_IMBALANCE: f64 = 1.1;

/// The most loaded shard's work over the mean (1 for an empty cut).
fn max_over_mean(cut: &Cut) -> f64 {
    let total: u64 = cut.work.iter().sum();
    let max = cut.work.iter().copied().max().unwrap_or(0);
    if total == 0 {
        return 1.0;
    }
    max as f64 * cut.work.len() as f64 / total as f64
}

/// Units in tree order (tree, then node: nodes are in pre-order, so a run of units is one region of the
/// quadtree) dealt as contiguous runs of about equal work: unit `i` goes to shard
/// `⌊(work before it + half its own) · count / total⌋`. A shard then draws one region, so the images
/// neighbouring leaves share are decoded by one shard, not several (all-tracks world, 4 shards: 1,190
/// decodes instead of 1,734, shards 8 % faster).
fn deal_in_tree_order(works: &[(Unit, u64)], count: u32) -> Cut {
    let mut ordered = works.to_vec();
    ordered.sort();
    let total: u64 = ordered.iter().map(|(_, w)| w).sum();
    let mut shards = vec![Vec::new(); count as usize];
    let mut work = vec![0u64; count as usize];
    let mut before = 0u64;
    for (u, w) in ordered {
        let at = u128::from(before + w / 2) * u128::from(count) / u128::from(total.max(1));
        let i = usize::try_from(at)
            .unwrap_or(usize::MAX)
            .min(count as usize - 1);
        before += w;
        work[i] += w;
        shards[i].push(u);
    }
    Cut { shards, work }
}

/// Units dealt largest first to the least loaded shard (ties to the lower index): the best balance, but
/// each shard draws units from everywhere.
fn deal_largest_first(works: &[(Unit, u64)], count: u32) -> Cut {
    let mut ordered = works.to_vec();
    ordered.sort_by(|(a, wa), (b, wb)| wb.cmp(wa).then(a.cmp(b)));
    let mut shards = vec![Vec::new(); count as usize];
    let mut work = vec![0u64; count as usize];
    for (u, w) in ordered {
        let (i, _) = work
            .iter()
            .enumerate()
            .min_by_key(|(i, w)| (**w, *i))
            .unwrap_or((0, &0));
        work[i] += w;
        shards[i].push(u);
    }
    Cut { shards, work }
}

/// Nodes in the subtree of `tree` rooted at `root`.
pub fn subtree_nodes(tree: &AtlasTree, root: NodeId) -> u64 {
    let mut n = 0;
    let mut stack = vec![root];
    while let Some(id) = stack.pop() {
        if let Some(node) = tree.nodes.get(id.idx()) {
            n += 1;
            stack.extend(node.children.iter().flatten());
        }
    }
    n
}

/// The blocks shard `units` writes, ascending, with their lengths.
pub fn shard_blocks(forest: &AtlasForest, units: &[Unit]) -> Vec<(BlockId, u64)> {
    let owned: Vec<Vec<Vec<BlockId>>> = (forest.trees.iter())
        .map(raster::leaf_owned_blocks)
        .collect();
    let mut ids: Vec<BlockId> = units
        .iter()
        .flat_map(|u| {
            let t = u.tree as usize;
            raster::subtree_blocks(&forest.trees[t], &owned[t], NodeId(u.node))
        })
        .collect();
    ids.sort();
    ids.dedup();
    ids.into_iter()
        .map(|b| (b, forest.blocks.get(b.idx()).map_or(0, |d| d.bytes)))
        .collect()
}

/// Side of a handoff (the level 1 of an atlas of side `atlas_size`).
pub fn handoff_side(atlas_size: u32) -> u32 {
    (atlas_size / 2).max(1)
}

/// The fingerprint of scene and flags every shard of one build shares: the table prefix (geometry,
/// materials, parameters, tree structure, block sizes and formats) by its hash, the pixel options the
/// tables do not hold (mip filter, alpha mips; plain alpha mips add nothing, so plain fingerprints are
/// those of shard files written before the knob), and each image's identity (name, size, colour type,
/// and the byte length of an external file or the hash of embedded bytes — a cheap check, not a content
/// hash of files).
pub fn fingerprint(
    prefix_hash: [u64; 2],
    pixels: super::raster::PixelOptions,
    scene: &Scene,
) -> [u64; 2] {
    let mut s = format!(
        "atlastree shard v1|{:016x}{:016x}|{}|",
        prefix_hash[0],
        prefix_hash[1],
        pixels.mip_filter.name()
    );
    if pixels.alpha_mips != super::image_ops::AlphaMips::Plain {
        s.push_str(&format!("alpha {}|", pixels.alpha_mips.name()));
    }
    s.push_str(&images_identity(&scene.images));
    hash128(s.as_bytes())
}

/// Each image's identity, in image-id order (the part of [`fingerprint`] a plan file checks against the
/// images a shard finds): name, size, colour type, and the byte length of an external file or the hash of
/// embedded bytes.
pub fn images_identity(images: &[crate::scene::ImageSource]) -> String {
    let mut s = String::new();
    for img in images {
        let data = match &img.data {
            ImageData::File(p) => format!(
                "file:{}",
                std::fs::metadata(p).map_or(u64::MAX, |m| m.len())
            ),
            ImageData::Bytes(b) => format!("bytes:{:?}", hash128(b)),
            ImageData::Solid(c) => format!("solid:{c:?}"),
            ImageData::Fallback => "fallback".into(),
        };
        s.push_str(&format!(
            "{}:{}x{}:{}:{data}|",
            img.name, img.width, img.height, img.color
        ));
    }
    s
}

/// The units of `cut` in shard order as a map from unit to handoff slot (the merge's expectations).
pub fn units_of(cut: &Cut) -> Vec<(usize, Unit)> {
    cut.shards
        .iter()
        .enumerate()
        .flat_map(|(i, us)| us.iter().map(move |&u| (i, u)))
        .collect()
}

/// The atlases above the cut of every tree, from the units' handoffs (keyed by unit, taken), into `out`.
pub fn raster_forest_above(
    out: &AtlasOut<'_>,
    forest: &AtlasForest,
    handoffs: &(dyn Fn(Unit) -> Option<Result<Handoff, super::BuildError>> + Sync),
) -> Result<(), super::BuildError> {
    for (t, tree) in forest.trees.iter().enumerate() {
        if !tree.nodes.is_empty() {
            let mine = |id: NodeId| {
                handoffs(Unit {
                    tree: t as u32,
                    node: id.0,
                })
            };
            raster::raster_above(out, tree, &mine, NodeId(0))?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn units(works: &[u64]) -> Vec<(Unit, u64)> {
        (works.iter().enumerate())
            .map(|(i, &w)| {
                let unit = Unit {
                    tree: (i / 8) as u32,
                    node: (i % 8) as u32,
                };
                (unit, w)
            })
            .collect()
    }

    #[test]
    fn regions_are_contiguous_runs_of_about_equal_work() {
        // Given out of order: dealt in tree order, four runs of four.
        let mut works = units(&[10; 16]);
        works.reverse();
        let cut = deal_in_tree_order(&works, 4);
        assert_eq!(cut.work, vec![40; 4]);
        for (i, shard) in cut.shards.iter().enumerate() {
            let expected: Vec<Unit> = units(&[10; 16])[4 * i..4 * i + 4]
                .iter()
                .map(|(u, _)| *u)
                .collect();
            assert_eq!(shard, &expected, "shard {i}");
        }
        // Uneven works still split where half of each unit's work falls.
        let cut = deal_in_tree_order(&units(&[30, 10, 10, 10, 20, 20]), 2);
        assert_eq!(cut.work, vec![50, 50]);
    }

    #[test]
    fn an_unbalanced_region_falls_back_to_largest_first() {
        // A heavy unit in the middle: the first region takes it and three more (120 against 80).
        let works = units(&[10, 10, 10, 90, 10, 10, 10, 50]);
        let regions = deal_in_tree_order(&works, 2);
        assert_eq!(regions.work, vec![120, 80]);
        assert!(max_over_mean(&regions) > REGION_IMBALANCE);
        let balanced = deal_largest_first(&works, 2);
        assert_eq!(balanced.work, vec![100, 100]);
        assert!(max_over_mean(&regions) > max_over_mean(&balanced));
        // The cut takes the balanced dealing here, and the regions where they are balanced enough.
        assert_eq!(deal(&works, 2).work, vec![100, 100]);
        let even = units(&[10; 16]);
        assert_eq!(deal(&even, 4).shards, deal_in_tree_order(&even, 4).shards);
    }

    #[test]
    fn shard_spec_parses_i_of_n_and_refuses_the_rest() {
        assert_eq!(
            "3/16".parse::<ShardSpec>(),
            Ok(ShardSpec {
                index: 3,
                count: 16
            })
        );
        assert_eq!(
            "0/1".parse::<ShardSpec>(),
            Ok(ShardSpec { index: 0, count: 1 })
        );
        for bad in ["4/4", "0/0", "1", "a/2", "-1/2", "0/4097", "1/2/3", ""] {
            assert!(bad.parse::<ShardSpec>().is_err(), "{bad:?}");
        }
    }

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| {
            vars.iter()
                .find(|(n, _)| *n == k)
                .map(|(_, v)| v.to_string())
        }
    }

    #[test]
    fn shard_auto_reads_each_scheduler() {
        let slurm = [
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
        ];
        assert_eq!(
            shard_from_env(&env(&slurm)),
            Ok((ShardSpec { index: 2, count: 4 }, "Slurm"))
        );
        let k8s = [
            ("JOB_COMPLETION_INDEX", "7"),
            ("ATLASTREE_SHARD_COUNT", "8"),
        ];
        assert_eq!(
            shard_from_env(&env(&k8s)),
            Ok((ShardSpec { index: 7, count: 8 }, "Kubernetes"))
        );
        let aws = [
            ("AWS_BATCH_JOB_ARRAY_INDEX", "0"),
            ("ATLASTREE_SHARD_COUNT", "3"),
        ];
        assert_eq!(
            shard_from_env(&env(&aws)),
            Ok((ShardSpec { index: 0, count: 3 }, "AWS Batch"))
        );
        assert_eq!(shard_from_env(&env(&[])), Err(ShardSpecError::NoScheduler));
        assert!(matches!(
            shard_from_env(&env(&[("JOB_COMPLETION_INDEX", "1")])),
            Err(ShardSpecError::NoCount { .. })
        ));
        assert!(matches!(
            shard_from_env(&env(&[
                ("SLURM_ARRAY_TASK_ID", "4"),
                ("SLURM_ARRAY_TASK_COUNT", "4")
            ])),
            Err(ShardSpecError::OutOfRange {
                index: 4,
                count: 4,
                ..
            })
        ));
        let e = shard_from_env(&env(&[
            ("JOB_COMPLETION_INDEX", "1"),
            ("ATLASTREE_SHARD_COUNT", "5000"),
        ]))
        .unwrap_err();
        assert!(
            matches!(e, ShardSpecError::BadCount { count: 5000, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("ATLASTREE_SHARD_COUNT=5000"), "{e}");
        assert!(matches!(
            shard_from_env(&env(&[
                ("SLURM_ARRAY_TASK_ID", "x"),
                ("SLURM_ARRAY_TASK_COUNT", "4")
            ])),
            Err(ShardSpecError::BadVariable { .. })
        ));
        // An array submitted as --array=1-4: refused in every task (task 1 built shard 1 and task 4 failed).
        let one_based = |id| {
            [
                ("SLURM_ARRAY_TASK_ID", id),
                ("SLURM_ARRAY_TASK_COUNT", "4"),
                ("SLURM_ARRAY_TASK_MIN", "1"),
                ("SLURM_ARRAY_TASK_MAX", "4"),
            ]
        };
        for id in ["1", "4"] {
            let e = shard_from_env(&env(&one_based(id))).unwrap_err();
            assert_eq!(
                e.to_string(),
                "--shard auto (Slurm): the array runs from 1 to 4; shards are numbered from 0, so submit \
                 it as --array=0-3 (N = 4)"
            );
        }
        // A count of 0 is refused as a count, before the array's range is looked at.
        let none = [
            ("SLURM_ARRAY_TASK_ID", "0"),
            ("SLURM_ARRAY_TASK_COUNT", "0"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "3"),
        ];
        assert!(matches!(
            shard_from_env(&env(&none)),
            Err(ShardSpecError::BadCount { count: 0, .. })
        ));
        // An array with a step (`--array=0-6:2`): 4 tasks, 0 to 6; the message says why.
        let stepped = [
            ("SLURM_ARRAY_TASK_ID", "2"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "6"),
        ];
        assert_eq!(
            shard_from_env(&env(&stepped)).unwrap_err().to_string(),
            "--shard auto (Slurm): the array runs from 0 to 6; its tasks are not every number from 0 to N - 1 \
             (a step or a list with gaps), so submit it as --array=0-3 (N = 4)"
        );
        let zero_based = [
            ("SLURM_ARRAY_TASK_ID", "3"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "0"),
            ("SLURM_ARRAY_TASK_MAX", "3"),
        ];
        assert_eq!(
            shard_from_env(&env(&zero_based)),
            Ok((ShardSpec { index: 3, count: 4 }, "Slurm"))
        );
        // An array bound that is not a number is refused, not skipped.
        let mut bad_max = zero_based;
        bad_max[3] = ("SLURM_ARRAY_TASK_MAX", "x");
        assert!(matches!(
            shard_from_env(&env(&bad_max)),
            Err(ShardSpecError::BadVariable {
                variable: "SLURM_ARRAY_TASK_MAX",
                ..
            })
        ));
    }

    #[test]
    fn another_schedulers_variables_are_named() {
        let both = [
            ("SLURM_ARRAY_TASK_ID", "1"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("JOB_COMPLETION_INDEX", "2"),
            ("ATLASTREE_SHARD_COUNT", "8"),
        ];
        assert_eq!(
            shard_from_env(&env(&both)),
            Ok((ShardSpec { index: 1, count: 4 }, "Slurm"))
        );
        assert_eq!(
            ignored_scheduler_variables(&env(&both), "Slurm"),
            vec![
                ("JOB_COMPLETION_INDEX", "2".to_string()),
                ("ATLASTREE_SHARD_COUNT", "8".to_string())
            ]
        );
        let k8s = [
            ("JOB_COMPLETION_INDEX", "2"),
            ("ATLASTREE_SHARD_COUNT", "8"),
        ];
        assert!(ignored_scheduler_variables(&env(&k8s), "Kubernetes").is_empty());
    }

    #[test]
    fn shard_path_sits_beside_the_output() {
        let p = shard_path(
            Path::new("/d/city.atlastree"),
            ShardSpec {
                index: 1,
                count: 16,
            },
        );
        assert_eq!(p, Path::new("/d/city.atlastree.shard-1-of-16"));
    }
}
