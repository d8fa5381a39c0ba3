//! Running one shard of a sharded build ([`build_shard`]); the merge is [`super::merge`]. The stages and
//! the cut are in [`super::shard`]; the shard file in [`crate::store::shard`].

use super::shard::{
    self, ShardSpec, choose_cut, fingerprint, handoff_side, shard_blocks, shard_path,
};
use super::{BuildError, BuildOptions, CacheBound, Progress};
use crate::scene::Scene;
use crate::store::shard::{ShardLayout, ShardWriter, hash128};
use crate::store::{StoreError, table_prefix};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What a shard needs beyond the build options.
pub struct ShardedOptions {
    /// Which shard.
    pub spec: ShardSpec,
    /// The command line that builds this shard, stored for the merge's "rebuild with" hint.
    pub argv: Vec<String>,
    /// An import the caller timed before the call (the CLI's: seconds, peak memory), counted among the
    /// report's stages and in their total, so the merge's table and critical path count it (they left it
    /// out).
    pub import: Option<(f64, Option<u64>)>,
}

/// What one shard did (printed by `atlastree build --shard`, saved beside the shard file as JSON for the
/// merge's per-shard table).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ShardReport {
    pub shard: u32,
    pub count: u32,
    /// The shard file.
    #[serde(serialize_with = "crate::util::path_lossy")]
    pub path: PathBuf,
    /// Subtrees rasterised, their nodes, blocks written and the estimated work against the mean.
    pub units: u64,
    pub nodes: u64,
    pub blocks: u64,
    pub work: u64,
    pub work_mean: f64,
    pub file_bytes: u64,
    /// Seconds and peak memory of each stage (flattened: `timings`, `stage_peak_rss`, `peak_rss_bytes`).
    #[serde(flatten)]
    pub stages: super::StageLog,
    pub images_decoded: u64,
    /// Images that failed to decode and were drawn as the magenta fallback, and the warnings of the
    /// shard's rasterisation (each naming its image): the merge repeats them, so a sharded build's user
    /// learns of a fallback in the merged file as a one-process build's does.
    #[serde(default)]
    pub image_fallbacks: u64,
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The scene import's warnings of a shard that planned itself (a missing image, a skipped
    /// primitive; a planned shard's are the plan's): in `--json` and the merge's list, not only in the
    /// printed summary (fault hunt, session 31).
    #[serde(default)]
    pub import_warnings: Vec<String>,
    /// How the memory budget was split, if there was one.
    pub memory: Option<super::memory::MemoryPlan>,
}

/// Builds shard `sharded.spec` of the build of `scene` into `out` and writes `OUT.shard-I-of-N` beside
/// `out` (atomically), with a JSON report beside it (`….json`). The shard plans the whole scene itself
/// (identically in every shard); [`super::build_shard_planned`] reads a plan instead.
pub fn build_shard(
    scene: &Scene,
    opts: &BuildOptions,
    out: &Path,
    sharded: &ShardedOptions,
    progress: &dyn Progress,
) -> Result<ShardReport, BuildError> {
    let t_all = Instant::now();
    let super::Planned {
        memory_plan,
        timings,
        forest,
        reports,
        ..
    } = super::plan_build(scene, opts, super::plan_forest::Budget::Build, progress)?;
    let t = Instant::now();
    let prefix = table_prefix(&forest)?;
    let prefix_hash = hash128(&prefix);
    let held = if sharded.spec.index == 0 {
        prefix
    } else {
        Vec::new()
    };
    let input = ShardInput {
        scene,
        forest: &forest,
        prefix_hash,
        prefix: held,
        memory_plan,
        timings,
        plan_warnings: super::tree_warnings(&reports),
        import_warnings: scene.report.warnings.clone(),
    };
    rasterise_shard(input, opts, out, sharded, progress, (t, t_all))
}

/// What a shard rasterises from, however it got its plan.
pub(super) struct ShardInput<'a> {
    /// Images and materials (a planned shard's scene has no geometry).
    pub(super) scene: &'a Scene,
    /// The whole forest's tables (a planned shard's without geometry).
    pub(super) forest: &'a crate::model::AtlasForest,
    pub(super) prefix_hash: [u64; 2],
    /// The table prefix this shard file carries: shard 0's when no plan file holds it, else empty.
    pub(super) prefix: Vec<u8>,
    pub(super) memory_plan: Option<super::memory::MemoryPlan>,
    pub(super) timings: super::StageLog,
    /// What planning the trees warned about ([`super::tree_warnings`]; a planned shard's were said by
    /// the plan step).
    pub(super) plan_warnings: Vec<String>,
    /// The import's warnings, where this shard imported the scene (a planned shard's are the plan's).
    pub(super) import_warnings: Vec<String>,
}

/// The shard's part of the pixel pass into its shard file, and its report; `t` = (start of the shard
/// layout stage, start of the whole shard).
pub(super) fn rasterise_shard(
    input: ShardInput<'_>,
    opts: &BuildOptions,
    out: &Path,
    sharded: &ShardedOptions,
    progress: &dyn Progress,
    (t, t_all): (Instant, Instant),
) -> Result<ShardReport, BuildError> {
    let ShardInput {
        scene,
        forest,
        prefix_hash,
        prefix,
        memory_plan,
        mut timings,
        plan_warnings,
        import_warnings,
    } = input;
    let spec = sharded.spec;
    let cut = choose_cut(forest, spec.count);
    let units = cut.shards[spec.index as usize].clone();
    let side = handoff_side(forest.params.atlas_size);
    let layout = ShardLayout {
        shard: spec.index,
        count: spec.count,
        pixel_options: opts.pixel_options().code(),
        fingerprint: fingerprint(prefix_hash, opts.pixel_options(), scene),
        prefix_hash,
        argv: serde_json::to_vec(&sharded.argv).unwrap_or_else(|_| b"[]".to_vec()),
        prefix,
        blocks: shard_blocks(forest, &units),
        handoffs: units.iter().map(|u| (u.tree, u.node, side, side)).collect(),
        images: (scene.images.iter())
            .map(|i| i.gltf_image.unwrap_or(u32::MAX))
            .collect(),
    };
    let blocks = layout.blocks.len() as u64;
    let path = shard_path(out, spec);
    let writer = ShardWriter::create(&path, layout)?;
    timings.push("shard layout", t);

    let t = Instant::now();
    let cache = super::image_cache::ImageCache::new(scene, memory_plan.image_cache_bytes(opts));
    let pass = super::pixel_pass(
        scene,
        opts.pixel_options(),
        forest,
        &units,
        &writer,
        &cache,
        progress,
    )?;
    for (u, h) in &pass.handoffs {
        writer.put_handoff(u.tree, u.node, &h.data)?;
    }
    timings.push("rasterise", t);
    let t = Instant::now();
    progress.stage("write shard", None);
    let file_bytes = writer.finish(&cache.pixel_hashes())?;
    // An earlier run's report goes as soon as this shard is committed (not before: a failed rewrite
    // keeps the earlier shard, and its report): killed before its own report, this shard would otherwise
    // stand beside the earlier one's times and warnings, which the merge prints as its own (fault hunt,
    // session 34).
    remove_stale_sidecar(&path);
    progress.finish_stage();
    timings.push("write", t);
    timings.push("total", t_all);
    if let Some((seconds, peak)) = sharded.import {
        timings.prepend("import", seconds, peak);
    }

    let nodes = units
        .iter()
        .map(|u| shard::subtree_nodes(&forest.trees[u.tree as usize], crate::ids::NodeId(u.node)))
        .sum();
    let mut report = ShardReport {
        shard: spec.index,
        count: spec.count,
        path: path.clone(),
        units: units.len() as u64,
        nodes,
        blocks,
        work: cut.work[spec.index as usize],
        work_mean: cut.work.iter().sum::<u64>() as f64 / f64::from(spec.count),
        file_bytes,
        stages: timings,
        images_decoded: cache.decodes.load(std::sync::atomic::Ordering::Relaxed),
        image_fallbacks: cache.fallbacks(),
        import_warnings,
        warnings: {
            let mut w = plan_warnings;
            w.extend(cache.warnings.lock().map(|w| w.clone()).unwrap_or_default());
            w.extend(super::resized_warnings(&cache));
            w.extend(cache.redecode_warning());
            w
        },
        memory: memory_plan,
    };
    // The shard file is complete and committed: a report that cannot be written (a disk full by a few
    // KiB) is said, not an error that reads as a failed shard (the merge's table shows '-' for it).
    if let Some(w) = save_sidecar_or_warn(
        &path,
        &report,
        "shard",
        "the merge's table lacks this shard's times and memory",
    ) {
        report.warnings.push(w);
    }
    Ok(report)
}

/// Removes `path`'s report ([`sidecar_path`]) once `path` was replaced. Best effort: what cannot be
/// removed here (a directory in its place) cannot be read as a report either, and the report written
/// after the file says what went wrong ([`save_sidecar_or_warn`]).
pub(super) fn remove_stale_sidecar(path: &Path) {
    let _ = std::fs::remove_file(sidecar_path(path));
}

/// `PATH.json`, where the report of the shard or plan file `path` lives.
pub(super) fn sidecar_path(path: &Path) -> PathBuf {
    let mut name = path.as_os_str().to_os_string();
    name.push(".json");
    PathBuf::from(name)
}

/// [`write_sidecar`] after its `what` file (`"shard"`, `"plan"`) was committed: on failure an earlier
/// run's report is removed (it would be read as this run's) and the warning to add is returned, saying
/// what the merge then `lacks`.
pub(super) fn save_sidecar_or_warn(
    path: &Path,
    report: &impl Serialize,
    what: &str,
    lacks: &str,
) -> Option<String> {
    let e = write_sidecar(path, report).err()?;
    let _ = std::fs::remove_file(sidecar_path(path));
    Some(format!(
        "the {what} file is complete, but its report could not be written: {e} ({lacks})"
    ))
}

/// `PATH.json`: the shard's report, written atomically (the merge reads it for its table; the shard file
/// itself holds nothing that differs between reruns).
pub(super) fn write_sidecar(path: &Path, report: &impl Serialize) -> Result<(), BuildError> {
    use std::io::Write;
    let target = sidecar_path(path);
    let write_err = |source: std::io::Error| {
        BuildError::Store(StoreError::io(
            &target,
            std::io::Error::new(source.kind(), format!("writing: {source}")),
        ))
    };
    let mut f = crate::util::AtomicFile::create(&target, 0o666).map_err(write_err)?;
    let json = serde_json::to_vec_pretty(report).map_err(|e| write_err(e.into()))?;
    f.write_all(&json).map_err(write_err)?;
    f.commit().map_err(write_err)
}
