//! Stages 1–3 of a build, the plan every shard runs identically (module docs of [`super`]): parameters and
//! memory budget, then per tree sizing ([`super::prepare`]), layout ([`super::layout`]) and assembly
//! ([`super::assemble`]) into the forest without pixels, with a report per tree; a file over the size
//! limit is refused here, before any pixel.

use super::stage_log::StageLog;
use super::{
    BuildError, BuildOptions, Progress, RepeatMode, TreeReport, assemble, layout, memory,
    originals, partition_triangles, plan_memory, prepare, resolve_params,
};
use crate::model::{AtlasForest, BuildParams, TreeKind};
use crate::scene::Scene;
use std::time::Instant;

/// Stages 1–3 of a build (the plan every shard runs identically): parameters, memory budget, the forest
/// without pixels and its reports.
pub(super) struct Planned {
    pub(super) params: BuildParams,
    pub(super) diagonal: f64,
    pub(super) memory_plan: Option<memory::MemoryPlan>,
    pub(super) timings: StageLog,
    pub(super) forest: AtlasForest,
    pub(super) reports: Vec<TreeReport>,
}

/// How many of the import's warnings [`empty_scene`] quotes.
const EMPTY_SCENE_WARNINGS: usize = 3;

/// [`BuildError::EmptyScene`] for `scene`: what its import skipped and its first warnings, or, when it
/// skipped no primitive or triangle (its warnings are then about something else), that the scene (after
/// any filter) draws no triangles.
pub(super) fn empty_scene(scene: &Scene) -> BuildError {
    let report = &scene.report;
    let detail = if report.skipped_primitives == 0 && report.skipped_triangles == 0 {
        ": the default scene draws no triangle primitives (points and lines are not drawn), or the scene \
         filters kept none"
            .to_string()
    } else {
        let quoted: Vec<&str> = report
            .warnings
            .iter()
            .take(EMPTY_SCENE_WARNINGS)
            .map(String::as_str)
            .collect();
        format!(
            "; {} warnings, the first: {}",
            report.warnings_total,
            quoted.join("; ")
        )
    };
    BuildError::EmptyScene {
        path: scene.source.display().to_string(),
        skipped_primitives: report.skipped_primitives,
        skipped_triangles: report.skipped_triangles,
        detail,
    }
}

/// Checks `opts` against `scene`, splits the budget, plans the forest and refuses an oversized file, all
/// before any pixel.
pub(super) fn plan_build(
    scene: &Scene,
    opts: &BuildOptions,
    budget: Budget,
    progress: &dyn Progress,
) -> Result<Planned, BuildError> {
    let (params, diagonal) = resolve_params(scene, opts)?;
    let parts = partition_triangles(scene);
    if parts.is_empty() {
        return Err(empty_scene(scene));
    }
    let load = plan_load(scene, opts, &params, &parts);
    let memory_plan = match (budget, opts.max_memory_bytes) {
        (Budget::Build, _) => plan_memory(scene, opts, &params, load)?,
        (Budget::PlanStep, Some(b)) => Some(memory::plan_step_memory(b, load)?),
        (Budget::PlanStep, None) => None,
    };
    let mut timings = StageLog::default();
    let (forest, reports) = plan_forest(scene, opts, &params, &parts, progress, &mut timings)?;
    let predicted = crate::store::predicted_file_len(&forest)?;
    check_file_size(predicted, &forest, opts, FileSizeFix::Flags)?;
    Ok(Planned {
        params,
        diagonal,
        memory_plan,
        timings,
        forest,
        reports,
    })
}

/// What `--max-memory` must hold in a [`plan_build`]: the plan and the pixel pass after it (a build, a
/// self-planning shard), or the plan alone (the plan step of a sharded build, which runs no pixel pass).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Budget {
    Build,
    PlanStep,
}

/// Stages 1–3 for every tree: the forest without pixels (every block's size fixed), with a report per tree.
fn plan_forest(
    scene: &Scene,
    opts: &BuildOptions,
    params: &BuildParams,
    parts: &[(TreeKind, Vec<u32>)],
    progress: &dyn Progress,
    timings: &mut StageLog,
) -> Result<(AtlasForest, Vec<TreeReport>), BuildError> {
    let mut forest = AtlasForest {
        params: params.clone(),
        materials: scene.materials.clone(),
        trees: vec![],
        blocks: vec![],
    };
    let mut reports = Vec::new();
    for (kind, tris) in parts {
        let slot = assemble::TreeSlot {
            kind: *kind,
            tree_index: forest.trees.len() as u32,
            first_block: forest.blocks.len() as u32,
            format: kind.format(opts.compress),
        };
        let (asm, report) = plan_tree(scene, opts, params, tris, slot, progress, timings)?;
        reports.push(report);
        forest.trees.push(asm.tree);
        forest.blocks.extend(asm.blocks);
    }
    Ok((forest, reports))
}

/// Stages 1–3 for one tree: sizing, layout, assembly.
fn plan_tree(
    scene: &Scene,
    opts: &BuildOptions,
    params: &BuildParams,
    tris: &[u32],
    slot: assemble::TreeSlot,
    progress: &dyn Progress,
    timings: &mut StageLog,
) -> Result<(assemble::Assembled, TreeReport), BuildError> {
    let kind = slot.kind;
    let wrap = opts.repeat == RepeatMode::Wrap;

    let t = Instant::now();
    progress.stage(&format!("sizing {kind:?}"), None);
    let popts = prepare_options(params, opts);
    let prepared = prepare::prepare(scene, tris, &popts);
    let (infos, corners) = (&prepared.infos, prepared.corners(scene));
    let sizing = prepare::analyze(&prepared);
    progress.finish_stage();
    timings.push(&format!("sizing {kind:?}"), t);

    let t = Instant::now();
    progress.stage(&format!("layout {kind:?} (nodes)"), None);
    let lopts = layout::LayoutOptions {
        atlas_size: params.atlas_size,
        border: params.border,
        max_depth: params.max_depth,
        cap_to_source: opts.cap_to_source,
        wrap,
        split: opts.split,
        leaf_originals: (opts.leaf_originals_atlases.max(0.0)
            * f64::from(params.atlas_size)
            * f64::from(params.atlas_size)) as u64,
    };
    let lay = layout::layout(scene, infos, corners, &lopts, &|n| progress.set(n))
        .map_err(|source| BuildError::Layout { kind, source })?;
    progress.finish_stage();
    timings.push(&format!("layout {kind:?}"), t);

    let t = Instant::now();
    let asm = assemble::assemble(scene, infos, corners, &lay.order, &lay.root, params, slot);
    timings.push(&format!("assemble {kind:?}"), t);

    let report = tree_report(scene, tris.len(), infos.len(), &lay, &asm, sizing);
    Ok((asm, report))
}

/// How [`prepare::prepare`] sizes and cuts the triangles of every tree of a build.
fn prepare_options(params: &BuildParams, opts: &BuildOptions) -> prepare::PrepareOptions {
    prepare::PrepareOptions {
        f_proj: params.f_proj(),
        up: params.up,
        cap_to_source: opts.cap_to_source,
        split_limit: f64::from(params.atlas_size / 4),
        max_pieces: opts.max_pieces,
        wrap: opts.repeat == RepeatMode::Wrap,
        palette_cells: palette_cell_limit(params, opts.cap_to_source),
    }
}

/// What the plan of `scene` holds ([`memory::PlanLoad`]): its triangles and, where repeats are baked
/// and a budget is set, the pieces beyond one a triangle that sizing will cut them into, counted before
/// any is made ([`prepare::count_pieces`]).
pub(super) fn plan_load(
    scene: &Scene,
    opts: &BuildOptions,
    params: &BuildParams,
    parts: &[(TreeKind, Vec<u32>)],
) -> memory::PlanLoad {
    let triangles = scene.triangles.len() as u64;
    let extra_vertices = (scene.vertices.len() as u64).saturating_sub(triangles);
    if opts.max_memory_bytes.is_none() {
        return memory::PlanLoad {
            extra_vertices,
            ..memory::PlanLoad::triangles(triangles)
        };
    }
    let popts = prepare_options(params, opts);
    let (pieces, whole) = parts.iter().fold((0u64, 0u64), |(p, w), (_, tris)| {
        let n = prepare::count_pieces(scene, tris, &popts);
        (p.saturating_add(n), w + tris.len() as u64)
    });
    memory::PlanLoad {
        triangles,
        extra_pieces: pieces.saturating_sub(whole),
        extra_vertices,
    }
}

/// [`super::palette::cell_limit`] for this build's atlas and border: the outer size of a 1 × 1 rect.
fn palette_cell_limit(params: &BuildParams, cap_to_source: bool) -> u32 {
    use super::area::{AreaInput, AreaOptions, required_area};
    let input = AreaInput {
        w: 0.0,
        h: 0.0,
        uv_min: [0.0; 2],
        uv_max: [0.0; 2],
        source: [1, 1],
    };
    let aopts = AreaOptions {
        border: params.border,
        scale: 1.0,
        cap_to_source,
        max_side: params.atlas_size,
        cap_floor: true,
    };
    let atlas = u64::from(params.atlas_size).pow(2);
    required_area(&input, &aopts).map_or(0, |a| super::palette::cell_limit(a.outer_texels(), atlas))
}

/// The report of one tree after assembly (its atlas PSNR is filled in by the pixel pass).
fn tree_report(
    scene: &Scene,
    triangles: usize,
    pieces: usize,
    lay: &layout::Layout,
    asm: &assemble::Assembled,
    sizing: prepare::PrepareReport,
) -> TreeReport {
    let occ = &asm.occupancy;
    TreeReport {
        kind: asm.tree.kind,
        format: asm.tree.format,
        atlas_psnr_db: crate::texfmt::PSNR_CAP_DB,
        triangles: triangles as u64,
        pieces: pieces as u64,
        nodes: asm.tree.nodes.len() as u64,
        leaves: asm.tree.leaves.len() as u64,
        depth: asm.tree.nodes.iter().map(|n| n.level.0).max().unwrap_or(0),
        vertices: asm.tree.vertices.len() as u64,
        clamped_leaves: lay.clamped_leaves as u64,
        leaf_reasons: lay.leaves.clone(),
        capped_rects: asm.capped.iter().flatten().filter(|&&r| r > 1.0).count() as u64,
        capped_shortfall: capped_shortfall(&asm.tree, &asm.capped, |m| scene.source_size(m)),
        periods_stored: asm.periods_stored,
        periods_spanned: asm.periods_spanned,
        occupancy_mean: occ.iter().sum::<f64>() / occ.len().max(1) as f64,
        occupancy_min: occ.iter().copied().fold(f64::INFINITY, f64::min),
        occupancy_max: occ.iter().copied().fold(0.0, f64::max),
        root_min_distance: asm.tree.nodes.first().map_or(0.0, |n| n.min_distance),
        sizing,
        originals: originals::originals_cost(&asm.tree, scene),
    }
}

/// The forest's node count (all trees), depth (deepest level) and block count.
pub(super) fn forest_shape(forest: &AtlasForest) -> (u64, u8, u64) {
    let nodes = (forest.trees.iter()).flat_map(|t| &t.nodes);
    let depth = nodes.clone().map(|n| n.level.0).max().unwrap_or(0);
    (nodes.count() as u64, depth, forest.blocks.len() as u64)
}

/// What a build refused for `--max-file-gib` may change: any flag that shapes the file (a build, the
/// plan step, a self-planning shard), or only the limit (a shard that reads a plan, whose key holds the
/// flags that shape it: following the flags' advice there got the shard refused as another build's).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum FileSizeFix {
    Flags,
    LimitOnly,
}

/// Refuses, before anything is written, a paging file of `predicted` bytes (tables, geometry and blocks:
/// the whole file, not only its blocks) over `--max-file-gib`, naming `forest`'s shape. The plan, a
/// one-process build and a shard that reads a plan (the plan's file length) all ask it.
pub(super) fn check_file_size(
    predicted: u64,
    forest: &AtlasForest,
    opts: &BuildOptions,
    fix: FileSizeFix,
) -> Result<(), BuildError> {
    let limit = opts.max_file_bytes;
    if predicted > limit {
        let (nodes, depth, blocks) = forest_shape(forest);
        let advice = match fix {
            FileSizeFix::Flags => too_large_advice(opts, depth, BlockBytes::of(forest)),
            FileSizeFix::LimitOnly => format!(
                "raise --max-file-gib to at least {:.2} where the disk holds it (the plan fixes the file's \
                 size), or plan again with flags that make a smaller file",
                (predicted as f64 / f64::from(1u32 << 30) * 100.0).ceil() / 100.0
            ),
        };
        return Err(BuildError::TooLarge {
            nodes,
            depth,
            blocks,
            predicted,
            limit,
            advice,
        });
    }
    Ok(())
}

/// The bytes of a forest's atlas blocks and of its original-texture blocks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct BlockBytes {
    atlases: u64,
    originals: u64,
}

impl BlockBytes {
    fn of(forest: &AtlasForest) -> BlockBytes {
        let mut out = BlockBytes::default();
        for b in &forest.blocks {
            match b.kind {
                crate::model::BlockKind::Atlas { .. } => out.atlases += b.bytes,
                crate::model::BlockKind::Originals { .. } => out.originals += b.bytes,
            }
        }
        out
    }
}

/// What would shrink a file over `--max-file-gib`, of what applies to these options (the same fixed text
/// said "keep the source cap" to a build that kept it, and "raise --d-min" to a one-node tree), with the
/// atlases' and the original textures' shares: the originals are stored at their own resolution, so
/// `--d-min` and `--atlas-size` do not shrink them, and a smaller atlas shrinks only a one-node tree's
/// atlas (deeper trees store the same texels in more, smaller atlases: a city of 8 GB stayed 8 GB at
/// 512 and 256 and grew at 128; fault hunt, session 39).
fn too_large_advice(opts: &BuildOptions, depth: u8, bytes: BlockBytes) -> String {
    let total = bytes.atlases + bytes.originals;
    let mut ways = vec!["raise --max-file-gib where the disk holds it".to_string()];
    if opts.compress == crate::texfmt::Compression::None {
        ways.push("--compress bc1 or bc7 (4 to 8 times smaller)".into());
    }
    // Only where the atlases are a fair share of the file: the rest is original textures.
    if depth > 0 && bytes.atlases.saturating_mul(3) >= total {
        ways.push("raise --d-min (or lower --d-min-ratio)".into());
    }
    if opts.texel_ratio > 1.0 {
        ways.push("lower --texel-ratio".into());
    }
    if !opts.cap_to_source {
        ways.push("keep the source cap (drop --no-source-cap)".into());
    }
    if opts.repeat == super::RepeatMode::Bake {
        ways.push("--repeat wrap (one period per rect)".into());
    }
    if depth == 0 && opts.atlas_size > 256 && bytes.atlases > bytes.originals {
        ways.push("a smaller --atlas-size (the tree is one node)".into());
    }
    ways.push("fewer materials (--materials)".into());
    format!(
        "{}; the atlases take {}, the original textures {} (stored at their own resolution for close \
         views: --d-min and --atlas-size do not shrink them)",
        ways.join(", "),
        crate::util::human_bytes(bytes.atlases),
        crate::util::human_bytes(bytes.originals)
    )
}

/// How much coarser than their sources capped rects are drawn ([`super::CappedShortfall`]; docs/DESIGN.md
/// "Where the guarantee does not hold: capped rects above their leaf"): a rect capped at a source `r`
/// times coarser than `d_min` asked for, in a leaf of scale `s` at depth `D`, shows at its leaf's
/// distance `min(r · s, 1)` of its source's texels per UV where it stores `k` of them (`k = s`, or more
/// where the scaled-leaf floor kept them: [`super::area::SCALED_CAP_FLOOR`]), so it falls short by
/// `min(r · s, 1) / k`; one level up by at most `min(r · s, 2) / k`, from the root `min(r · s, 2^D) / k`
/// (with `k = s`: the `min(r, 2^D / s)` of before; a 4 × 4 texture the floor kept whole was said to fall
/// 2.3× short; fault hunt, session 31). An ancestor's min_distance may come from a more scaled sibling:
/// then it falls short by less. `source_of` gives a material's source size.
fn capped_shortfall(
    tree: &crate::model::AtlasTree,
    capped: &[Vec<f64>],
    source_of: impl Fn(crate::ids::MaterialId) -> [u32; 2],
) -> super::CappedShortfall {
    let mut out = super::CappedShortfall::default();
    for (leaf, rects) in tree.leaves.iter().zip(capped) {
        let s = leaf.clamp_scale;
        let depth = tree.nodes.get(leaf.node.idx()).map_or(0, |n| n.level.0);
        for (rect, &r) in leaf.rects.iter().zip(rects) {
            if r <= 1.0 {
                continue;
            }
            // Stored texels per source texel on the capped axes (the fewest), `s` where unknown.
            let src = source_of(rect.material);
            let kept = (0..2)
                .filter(|&a| rect.capped[a])
                .filter_map(|a| {
                    let extent = rect.uv_max[a] - rect.uv_min[a];
                    (extent > 0.0)
                        .then(|| f64::from(rect.inner[2 + a]) / extent / f64::from(src[a].max(1)))
                })
                .fold(f64::INFINITY, f64::min);
            // At least `s` (the inner size's rounding can leave it a hair below), so never past the
            // old bound `min(r · s, 2^D) / s`; at most a whole source.
            let kept = if kept.is_finite() {
                kept.min(1.0).max(s)
            } else {
                s
            };
            let short = |levels: i32| ((r * s).min(2f64.powi(levels)) / kept).max(1.0);
            out.at_leaf = out.at_leaf.max(short(0));
            out.at_root = out.at_root.max(short(i32::from(depth)));
            if depth > 0 {
                out.one_up = out.one_up.max(short(1));
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{BlockBytes, BuildOptions, too_large_advice};

    const MIB: u64 = 1 << 20;

    #[test]
    fn the_advice_offers_only_what_shrinks_the_file() {
        let opts = BuildOptions::default();
        // Originals dominate: neither --d-min nor --atlas-size shrinks them (fault hunt, session 39).
        let originals = BlockBytes {
            atlases: 5 * MIB,
            originals: 85 * MIB,
        };
        for depth in [0, 3] {
            let a = too_large_advice(&opts, depth, originals);
            assert!(
                !a.contains("--atlas-size (") && !a.contains("raise --d-min"),
                "{a}"
            );
            assert!(
                a.contains("--compress bc1") && a.contains("85.00 MiB"),
                "{a}"
            );
        }
        // Atlases dominate: a deeper tree shrinks with --d-min, a one-node tree with a smaller atlas.
        let atlases = BlockBytes {
            atlases: 85 * MIB,
            originals: 5 * MIB,
        };
        let deep = too_large_advice(&opts, 3, atlases);
        assert!(
            deep.contains("raise --d-min") && !deep.contains("a smaller --atlas-size"),
            "{deep}"
        );
        let root = too_large_advice(&opts, 0, atlases);
        assert!(
            root.contains("a smaller --atlas-size") && !root.contains("raise --d-min"),
            "{root}"
        );
    }
}
