//! The plan step of a sharded build (issue 22, docs/DESIGN.md "Sharded builds"): planned once
//! ([`plan_shards`], `atlastree build --shard plan`) into `OUT.plan`, then read by every shard
//! ([`build_shard_planned`]) and by the merge. A planned shard imports the scene's images and nothing else:
//! no triangle of the scene is in its memory, and it does not repeat the plan.

use super::shard::images_identity;
use super::shard_run::{ShardInput, ShardReport, ShardedOptions, rasterise_shard};
use super::{BuildError, BuildOptions, Progress, StageLog};
use crate::scene::Scene;
use crate::store::shard::hash128;
use crate::store::shard_plan::{PlanFile, PlanFileError, PlanManifest, plan_path, write_plan};
use crate::store::table_prefix;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What the plan step did (printed by `atlastree build --shard plan`).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct ShardPlanReport {
    /// The plan file (`OUT.plan`).
    #[serde(serialize_with = "crate::util::path_lossy")]
    pub path: PathBuf,
    pub file_bytes: u64,
    /// The plan's key (its header's: scene input and the flags that shape the tables), so the merge
    /// takes only this plan's report (`None` in a report of an older binary).
    #[serde(default)]
    pub key: Option<[u64; 2]>,
    /// Scene triangles planned, nodes and blocks of the forest.
    pub triangles: u64,
    pub nodes: u64,
    pub blocks: u64,
    #[serde(flatten)]
    pub stages: StageLog,
    /// The memory budget's check, if there was a budget.
    pub memory: Option<super::memory::MemoryPlan>,
    /// What planning the trees warned about ([`super::tree_warnings`]).
    #[serde(default)]
    pub warnings: Vec<String>,
    /// The scene import's warnings (a missing image, a skipped primitive): in `--json` and the merge's
    /// list, not only in the printed summary (fault hunt, session 31).
    #[serde(default)]
    pub import_warnings: Vec<String>,
}

impl ShardPlanReport {
    /// Saves the report beside the plan (`OUT.plan.json`, atomically), where the merge finds its time and
    /// peak memory for the critical path; the caller first adds what it timed before [`plan_shards`] (the
    /// CLI's import).
    /// The plan file is complete and committed by now: a report that cannot be written is a warning in
    /// this report, not an error that reads as a failed plan (it said `error:` with a usable plan left
    /// behind), and an earlier run's report is removed (the merge would print its times and warnings;
    /// fault hunt, session 31), as a shard does.
    pub fn save(&mut self) {
        let lacks = "the merge does not show the plan's time, memory and warnings";
        if let Some(w) = super::shard_run::save_sidecar_or_warn(&self.path, &*self, "plan", lacks) {
            self.warnings.push(w);
        }
    }

    /// Seconds of the whole plan step: its stages' total, which counts the import before them
    /// ([`super::stage_log::StageLog::prepend`]; it was added again here).
    pub fn seconds(&self) -> Option<f64> {
        self.stages.seconds("total")
    }
}

/// Why a plan file cannot serve a shard or a merge.
#[derive(Debug, thiserror::Error)]
pub enum ShardPlanError {
    #[error(transparent)]
    File(#[from] PlanFileError),
    #[error(
        "{path} was planned from another scene or with other flags than this shard's; plan again with this \
         shard's flags (`atlastree build SCENE -o OUT FLAGS --shard plan`) or remove it (then every shard plans \
         for itself). The plan was made by: {planned_by}"
    )]
    OtherInput { path: PathBuf, planned_by: String },
    #[error(
        "{path}: the scene's images changed after the plan (name, size or byte length of at least one of its {images} \
         images differs); plan again (`--shard plan`)"
    )]
    ImagesChanged { path: PathBuf, images: usize },
    #[error(
        "{path}: a plan file needs every image to come from the glTF file; image {image} ({name}) was made in memory"
    )]
    NotPlannable {
        path: PathBuf,
        image: usize,
        name: String,
    },
}

/// The key that ties a plan to its input: the scene's bytes ([`crate::scene::input_digest`]: the glTF
/// file and its buffers), the build options that shape the tables (not the memory budget, the cache, the
/// file-size limit, or the pixel options, which shards carry in their own headers), and `selection`: the
/// caller's scene filters in words (the CLI's `--materials` and `--up`), as they change the scene the
/// plan is made from.
pub fn shard_plan_key(
    opts: &BuildOptions,
    scene_path: &Path,
    selection: &str,
) -> Result<[u64; 2], BuildError> {
    let keyed = BuildOptions {
        image_cache_bytes: 0,
        max_memory_bytes: None,
        max_file_bytes: 0,
        mip_filter: super::image_ops::MipFilter::Box,
        alpha_mips: super::image_ops::AlphaMips::Plain,
        ..opts.clone()
    };
    let json = serde_json::to_string(&keyed).unwrap_or_default();
    let digest = crate::scene::input_digest(scene_path)?;
    let text = format!(
        "atlastree plan v1|{json}|{selection}|{:016x}{:016x}",
        digest[0], digest[1]
    );
    Ok(hash128(text.as_bytes()))
}

/// Plans the build of `scene` (import done, filters applied) and writes `OUT.plan` atomically, keyed by
/// `key` ([`shard_plan_key`]); `argv` is stored for the hint a refused plan prints.
pub fn plan_shards(
    scene: &Scene,
    opts: &BuildOptions,
    out: &Path,
    key: [u64; 2],
    argv: Vec<String>,
    progress: &dyn Progress,
) -> Result<ShardPlanReport, BuildError> {
    let t_all = Instant::now();
    let path = plan_path(out);
    let images = (scene.images.iter().enumerate())
        .map(|(i, img)| {
            img.image_ref().ok_or_else(|| ShardPlanError::NotPlannable {
                path: path.clone(),
                image: i,
                name: img.name.clone(),
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    // The plan step runs no pixel pass: its budget covers the plan alone.
    let super::Planned {
        mut timings,
        forest,
        reports,
        memory_plan: memory,
        ..
    } = super::plan_build(scene, opts, super::plan_forest::Budget::PlanStep, progress)?;
    let t = Instant::now();
    progress.stage("write plan", None);
    let prefix = table_prefix(&forest)?;
    let manifest = PlanManifest {
        argv,
        images,
        triangles: scene.triangles.len() as u64,
    };
    let identity = hash128(images_identity(&scene.images).as_bytes());
    let file_bytes = write_plan(&path, key, identity, &manifest, &prefix)?;
    // As a shard does: an earlier plan's report never stands beside this plan.
    super::shard_run::remove_stale_sidecar(&path);
    progress.finish_stage();
    timings.push("write plan", t);
    timings.push("total", t_all);
    let report = ShardPlanReport {
        path,
        file_bytes,
        key: Some(key),
        triangles: manifest.triangles,
        nodes: super::plan_forest::forest_shape(&forest).0,
        blocks: forest.blocks.len() as u64,
        stages: timings,
        memory,
        warnings: super::tree_warnings(&reports),
        import_warnings: scene.report.warnings.clone(),
    };
    Ok(report)
}

/// Builds shard `sharded.spec` from the plan file `plan` (opened by the caller; its key is checked against
/// `key`, the shard's own [`shard_plan_key`]): reads the scene's images named by the plan from `scene_path`,
/// decodes the plan's tables without their geometry, and rasterises its part exactly as
/// [`super::build_shard`] does. The shard file carries no table prefix: the merge reads it from the plan.
pub fn build_shard_planned(
    plan: &PlanFile,
    key: [u64; 2],
    scene_path: &Path,
    opts: &BuildOptions,
    out: &Path,
    sharded: &ShardedOptions,
    progress: &dyn Progress,
) -> Result<ShardReport, BuildError> {
    let t_all = Instant::now();
    let path = plan.path().to_path_buf();
    if plan.header.key != key {
        let words: Vec<String> = (plan.manifest.argv.iter())
            .map(|a| crate::util::shell_words::shell_word(a))
            .collect();
        let planned_by = words.join(" ");
        return Err(ShardPlanError::OtherInput { path, planned_by }.into());
    }
    let mut timings = StageLog::default();
    let t = Instant::now();
    progress.stage("read plan", None);
    // The scene file is read whole for its images' places (a GLB's BIN chunk with it), within the budget;
    // it is freed before any pixel, so the pixel pass's shares below do not hold it.
    let max_input = opts.max_memory_bytes.map(super::memory::max_input_bytes);
    let (images, report) =
        crate::scene::import_images(scene_path, &plan.manifest.images, max_input)?;
    if hash128(images_identity(&images).as_bytes()) != plan.header.images {
        let images = images.len();
        return Err(ShardPlanError::ImagesChanged { path, images }.into());
    }
    let tables = plan.skeleton().map_err(ShardPlanError::File)?;
    let forest = tables.to_skeleton();
    let file_len = tables.header().file_len;
    drop(tables);
    // The plan's key leaves `--max-file-gib` out (a limit, not a shape), so a shard checks it against the
    // file the plan lays out, as the plan step and a one-process build do (fault hunt, session 35: a
    // planned shard wrote its part of a file over the limit it was given).
    use super::plan_forest::{FileSizeFix, check_file_size};
    check_file_size(file_len, &forest, opts, FileSizeFix::LimitOnly)?;
    // Refused before any pixel: the shard holds the tables' skeleton, no triangle.
    let threads = rayon::current_num_threads() as u64;
    let memory_plan = match opts.max_memory_bytes {
        None => None,
        Some(budget) => Some(
            super::memory::planned_shard_memory(
                budget,
                skeleton_bytes(&forest),
                opts.atlas_size,
                threads,
                super::image_load(&images, opts.alpha_mips, threads),
                opts.image_cache_bytes,
            )
            .map_err(|e| e.naming(super::largest_image_name(&images)))?,
        ),
    };
    let scene = Scene {
        source: scene_path.to_path_buf(),
        up: forest.params.up,
        vertices: Vec::new(),
        triangles: Vec::new(),
        materials: forest.materials.clone(),
        images,
        report,
    };
    progress.finish_stage();
    timings.push("read plan", t);
    let t = Instant::now();
    let input = ShardInput {
        scene: &scene,
        forest: &forest,
        prefix_hash: plan.header.prefix_hash,
        prefix: Vec::new(),
        memory_plan,
        timings,
        // Said by the plan step.
        plan_warnings: Vec::new(),
        import_warnings: Vec::new(),
    };
    rasterise_shard(input, opts, out, sharded, progress, (t, t_all))
}

/// Bytes of a forest's skeleton in memory: its node, leaf, rect and original records and its blocks.
fn skeleton_bytes(forest: &crate::model::AtlasForest) -> u64 {
    use std::mem::size_of_val;
    let trees: usize = (forest.trees.iter())
        .map(|t| {
            size_of_val(t.nodes.as_slice())
                + (t.leaves.iter())
                    .map(|l| {
                        size_of_val(l)
                            + size_of_val(l.rects.as_slice())
                            + size_of_val(l.originals.as_slice())
                    })
                    .sum::<usize>()
        })
        .sum();
    (trees + size_of_val(forest.blocks.as_slice())) as u64
}
