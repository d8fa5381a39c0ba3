//! The preprocessor (paper §5): scene → texture-atlas tree(s) → one paging file.
//!
//! Stages, each a module with one job:
//! 1. [`prepare`]: per-triangle sizing (§5.2.1), UV period shift, area and midpoint.
//! 2. [`layout`]: try an atlas per node (§5.2.2 areas via [`area`], §5.2.3 packing via [`pack`]); split on
//!    failure (§5.3). Sizes only, no pixels.
//! 3. [`assemble`]: nodes in pre-order, leaves in tree order, geometry in the exact single-UV-set form
//!    ([`crate::model::transform`]), original-texture extents, the block table with every block's byte size
//!    (original textures once per tree, cut into blocks by their users in [`originals`]).
//! 4. [`raster`]: the pixel pass ([`image_ops`]), streamed into [`crate::store::FileWriter`] at offsets fixed
//!    in stage 3, then the file is finished atomically.
//!
//! `plan_forest` runs stages 1–3 for every tree (the plan each shard repeats or reads from a plan file);
//! [`build`] here adds stage 4 and the write.

pub mod alpha_coverage;
pub mod area;
pub mod assemble;
pub mod cover;
pub mod demand;
mod finish;
pub mod image_cache;
pub mod image_ops;
pub mod layout;
mod leaf;
pub mod memory;
mod merge;
pub mod originals;
pub mod pack;
pub mod palette;
mod plan_forest;
pub mod prepare;
pub mod raster;
mod report;
pub mod shard;
mod shard_files;
mod shard_plan;
mod shard_run;
pub mod sizing;
mod stage_log;

pub use merge::{MergeError, MergeReport, merge};
use report::{build_report, resized_warnings, tree_warnings};
pub use shard_plan::{
    ShardPlanError, ShardPlanReport, build_shard_planned, plan_shards, shard_plan_key,
};
pub use shard_run::{ShardReport, ShardedOptions, build_shard};
pub use stage_log::StageLog;

use plan_forest::{Planned, empty_scene, plan_build};

use crate::model::{AtlasForest, BuildParams, TreeKind};
use crate::scene::Scene;
use crate::store::{FileWriter, StoreError};
use serde::Serialize;
use std::path::Path;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Whether `side` is an atlas side a build takes: a power of two from 64 to 16384 texels.
pub fn valid_atlas_size(side: u32) -> bool {
    side.is_power_of_two() && (64..=16384).contains(&side)
}

/// Whether `border` texels leave room in an atlas of `side`: less than a quarter of it (saturating, so a
/// border past `u32::MAX / 4` is refused, not wrapped to 0).
pub fn valid_border(border: u32, side: u32) -> bool {
    border.saturating_mul(4) < side
}

/// How d_min is given.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub enum DMin {
    /// Metres (world units).
    Metres(f64),
    /// `d_min = scene diagonal / R` (the paper used R = 151 for Berlin and 62 for Chemnitz).
    Ratio(f64),
}

/// How repeated textures are stored (docs/DESIGN.md "Repeats").
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Hash, Serialize)]
pub enum RepeatMode {
    /// At most one period per rect; the fragment shader wraps the UV into it (default).
    #[default]
    Wrap,
    /// Every repetition the UVs span copied into the atlas (the paper's §5.2.2), big triangles cut into
    /// pieces: the reference the sweep compares against.
    Bake,
}

impl RepeatMode {
    pub fn label(self) -> &'static str {
        match self {
            RepeatMode::Wrap => "wrap",
            RepeatMode::Bake => "bake",
        }
    }
}

impl std::str::FromStr for RepeatMode {
    type Err = String;
    fn from_str(s: &str) -> Result<RepeatMode, String> {
        match s.to_ascii_lowercase().as_str() {
            "wrap" => Ok(RepeatMode::Wrap),
            "bake" => Ok(RepeatMode::Bake),
            _ => Err(format!("unknown repeat mode {s:?} (wrap or bake)")),
        }
    }
}

/// Options of a build. Defaults follow the paper (800 px, ratio 1) and the issue (atlas 1024, depth cap 24),
/// except the border: 16 texels, not the paper's 8. Every level up the tree halves it, and views drawn
/// with an atlas beyond its min_distance sample coarser mips, where a thin border lets neighbouring areas
/// bleed in: on data/city (depth 3) root-atlas views measure 33.1 dB against the original textures at
/// border 8 and 38.3 dB at 16, for 18 % more texture data (`atlastree sweep`, border knob).
/// The deepest tree a build makes ([`BuildOptions::max_depth`]): level 30's cells are 2⁻³⁰ of the
/// scene's side.
pub const MAX_DEPTH: u8 = 30;

#[derive(Clone, Debug, Serialize)]
pub struct BuildOptions {
    pub d_min: DMin,
    pub screen_width: u32,
    pub fov_deg: f64,
    pub texel_ratio: f64,
    pub atlas_size: u32,
    pub border: u32,
    pub max_depth: u8,
    /// Never store more texels per texture repetition than the source has.
    pub cap_to_source: bool,
    /// Bound on decoded images held at once, bytes (lowered to fit `max_memory_bytes`).
    pub image_cache_bytes: u64,
    /// Memory budget of the whole build, bytes ([`memory`]): it sizes the image cache, and a build that
    /// cannot fit is refused before any work with the number it needs. `None`: no budget.
    pub max_memory_bytes: Option<u64>,
    /// At most this many pieces per scene triangle when splitting triangles too big for one atlas
    /// (1 = never split: such triangles are clamped instead).
    pub max_pieces: u32,
    /// Refuse (before writing anything) a build whose paging file would exceed this many bytes.
    pub max_file_bytes: u64,
    /// Down-sampling kernel of the atlas mip chains, and hence of every inner atlas (the 2×2 combination
    /// of its children's level 1, §5.1). Original-texture blocks and the source images sampled into leaf
    /// atlases keep the box filter, so `--mode original` stays the same reference for every build.
    pub mip_filter: image_ops::MipFilter,
    /// Alpha through the mips of the alpha tree's MASK areas, atlases and original textures alike: filtered
    /// like colour (plain, the default) or rescaled per level to keep level 0's α-test coverage
    /// ([`image_ops::AlphaMips`]; the original textures then differ from plain builds too).
    pub alpha_mips: image_ops::AlphaMips,
    /// Block compression of atlases and original textures (every mip level), per tree kind.
    pub compress: crate::texfmt::Compression,
    /// Repeats wrapped in the shader (one period per rect) or baked into the atlas.
    pub repeat: RepeatMode,
    /// A node that does not fit one atlas is not split when its original textures need at most this many
    /// atlases' worth of texels: it becomes a leaf whose atlas holds its content scaled to fit
    /// (`min_distance` raised by that scale), its originals drawn nearer ([`layout::LeafReason`]). 0: split
    /// every node that does not fit (the paper's tree).
    pub leaf_originals_atlases: f64,
    /// What the split of §5.3 balances (texel demand; world area as the paper).
    pub split: layout::SplitRule,
}

impl BuildOptions {
    /// The pixel options of this build that the paging file's tables do not hold.
    pub fn pixel_options(&self) -> raster::PixelOptions {
        raster::PixelOptions {
            mip_filter: self.mip_filter,
            alpha_mips: self.alpha_mips,
        }
    }
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            d_min: DMin::Ratio(151.0),
            screen_width: 800,
            fov_deg: 60.0,
            texel_ratio: 1.0,
            atlas_size: 1024,
            border: 16,
            max_depth: 24,
            cap_to_source: true,
            image_cache_bytes: 2 << 30,
            max_memory_bytes: memory::default_budget(),
            max_pieces: 4096,
            max_file_bytes: 64 << 30,
            mip_filter: image_ops::MipFilter::Box,
            alpha_mips: image_ops::AlphaMips::Plain,
            compress: crate::texfmt::Compression::None,
            repeat: RepeatMode::Wrap,
            leaf_originals_atlases: 16.0,
            split: layout::SplitRule::Demand,
        }
    }
}

/// Receives progress of the long stages (the CLI draws indicatif bars; tests pass [`NoProgress`]).
pub trait Progress: Sync {
    /// A stage begins; `total` is known for bar-like stages.
    fn stage(&self, name: &str, total: Option<u64>);
    /// Position within the current stage.
    fn set(&self, pos: u64);
    /// The current stage ended.
    fn finish_stage(&self);
}

/// Progress sink that ignores everything.
pub struct NoProgress;
impl Progress for NoProgress {
    fn stage(&self, _: &str, _: Option<u64>) {}
    fn set(&self, _: u64) {}
    fn finish_stage(&self) {}
}

impl From<memory::MemoryError> for BuildError {
    fn from(e: memory::MemoryError) -> BuildError {
        BuildError::Memory(Box::new(e))
    }
}

/// Errors of a build; every variant names what and where.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    #[error("invalid build parameter --{name} {value}: {why}")]
    InvalidParam {
        name: &'static str,
        value: String,
        why: std::borrow::Cow<'static, str>,
    },
    /// d_min from the scene's diagonal (`--d-min-ratio`, the default) where that diagonal is 0: every
    /// position the same point (a zero scale, all-zero positions).
    #[error(
        "the scene {path} spans a diagonal of {d} world units, so d_min = diagonal / {r} is no \
         distance: its positions are all one point (a zero scale?); give --d-min in metres to build it \
         anyway",
        d = crate::util::short_number(*.diagonal),
        r = crate::util::short_number(*.ratio)
    )]
    DegenerateExtent {
        path: String,
        diagonal: f64,
        ratio: f64,
    },
    /// A scene wider than the 32-bit floats its vertices are stored in (relative to their leaf) hold.
    #[error(
        "the scene {path} spans {e} world units along one axis, more than the 3.4e38 a vertex's 32-bit \
         float holds (a node matrix or accessor scaling by an absurd factor?); nothing built",
        e = crate::util::short_number(*.extent)
    )]
    ExtentOverflow { path: String, extent: f64 },
    /// `detail` says why: what the import skipped (counted, with its first warnings), or that nothing
    /// was skipped.
    #[error(
        "the scene {path} has no triangles to build a tree from: the import skipped {skipped_primitives} \
         primitives and {skipped_triangles} triangles{detail}"
    )]
    EmptyScene {
        path: String,
        skipped_primitives: u64,
        skipped_triangles: u64,
        detail: String,
    },
    #[error("layout of the {kind:?} tree: {source}")]
    Layout {
        kind: TreeKind,
        #[source]
        source: layout::LayoutError,
    },
    #[error(
        "the tree would need {nodes} nodes (depth {depth}) and {blocks} blocks, a file of {predicted} bytes \
         (tables, geometry and blocks), over the limit of {limit} bytes (--max-file-gib): {advice}"
    )]
    TooLarge {
        nodes: u64,
        depth: u8,
        blocks: u64,
        predicted: u64,
        limit: u64,
        /// What would shrink it, of what applies to the build's options.
        advice: String,
    },
    #[error(transparent)]
    Store(#[from] StoreError),
    /// Boxed: the refusal names every share of the budget, and the error type stays small.
    #[error(transparent)]
    Memory(Box<memory::MemoryError>),
    #[error(transparent)]
    PlanStepMemory(#[from] memory::PlanStepMemoryError),
    #[error(transparent)]
    Plan(Box<shard_plan::ShardPlanError>),
    #[error(transparent)]
    Scene(Box<crate::scene::SceneError>),
    #[error(transparent)]
    Shard(Box<crate::store::shard::ShardFileError>),
    #[error("encoding the {what}: {source}")]
    Encode {
        what: String,
        #[source]
        source: crate::texfmt::TexFormatError,
    },
    #[error(
        "internal error: the shard cut of the {tree:?} tree does not cover leaf node {node} (please report)"
    )]
    CutUncovered { tree: TreeKind, node: u32 },
    /// A second decode of an image (after the cache evicted it) gave other pixels than the first.
    #[error(
        "image {image} ({name}) decoded to other pixels the second time: its file changed during the \
         build, so the atlases would mix two versions of it; nothing written, build again"
    )]
    ImageChanged { image: u32, name: String },
    #[error("rasterising the {what}: {source}")]
    Image {
        what: String,
        #[source]
        source: image_ops::ImageOpsError,
    },
}

impl From<shard_plan::ShardPlanError> for BuildError {
    fn from(e: shard_plan::ShardPlanError) -> Self {
        BuildError::Plan(Box::new(e))
    }
}

impl From<crate::scene::SceneError> for BuildError {
    fn from(e: crate::scene::SceneError) -> Self {
        BuildError::Scene(Box::new(e))
    }
}

/// Per-tree numbers of a build report.
#[derive(Clone, Debug, Serialize)]
pub struct TreeReport {
    pub kind: TreeKind,
    /// Storage format of the tree's blocks.
    pub format: crate::texfmt::TexFormat,
    /// PSNR (dB, 8-bit sRGB values, all levels) of the stored atlases against the uncompressed ones they
    /// were encoded from ([`crate::texfmt::psnr`]); the cap, 99 dB, for RGBA8 (lossless).
    pub atlas_psnr_db: f64,
    /// Scene triangles in this tree.
    pub triangles: u64,
    /// Triangles after splitting those too big for one atlas.
    pub pieces: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub depth: u8,
    pub vertices: u64,
    pub clamped_leaves: u64,
    /// Leaves by why they ended ([`layout::LeafReason`]) and the originals source-resolution leaves imply.
    pub leaf_reasons: layout::LeafCounts,
    pub capped_rects: u64,
    /// How much coarser than their sources the capped rects are drawn, from their leaves and above.
    pub capped_shortfall: CappedShortfall,
    /// Periods stored in the leaf atlases (Σ over rects of the UV area their inner rectangle shows) and
    /// periods the UVs span (Σ over rects of the UV hull area of their triangles): what wrapping saves.
    pub periods_stored: f64,
    pub periods_spanned: f64,
    pub occupancy_mean: f64,
    pub occupancy_min: f64,
    pub occupancy_max: f64,
    pub root_min_distance: f64,
    pub sizing: prepare::PrepareReport,
    /// The original textures' bytes against their sources once ([`originals::OriginalsCost`]).
    pub originals: originals::OriginalsCost,
}

/// At most the factor by which capped rects ([`TreeReport::capped_rects`]: textures stored at their
/// source's resolution where `d_min` asked for more) are drawn with fewer texels than their original
/// textures show at the same distance: from their leaf (only a leaf scaled below 1 falls short), from the
/// node one level up, and from the root. 1 where nothing falls short. Each level up halves a rect while
/// its min_distance only doubles (docs/DESIGN.md "Where the guarantee does not hold: capped rects above
/// their leaf").
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct CappedShortfall {
    pub at_leaf: f64,
    pub one_up: f64,
    pub at_root: f64,
}

impl Default for CappedShortfall {
    fn default() -> Self {
        Self {
            at_leaf: 1.0,
            one_up: 1.0,
            at_root: 1.0,
        }
    }
}

/// What a build did, with the numbers (printed by `atlastree build`, JSON with `--json`).
#[derive(Clone, Debug, Serialize)]
pub struct BuildReport {
    pub params: BuildParams,
    pub scene_diagonal: f64,
    pub trees: Vec<TreeReport>,
    pub blocks: u64,
    pub atlas_blocks: u64,
    pub original_blocks: u64,
    pub file_bytes: u64,
    /// Seconds and peak memory of each stage (flattened: `timings`, `stage_peak_rss`, `peak_rss_bytes`).
    #[serde(flatten)]
    pub stages: StageLog,
    pub images_decoded: u64,
    /// Texels of the images decoded by the pixel pass, and texels of every stored chain (atlases and
    /// originals, every level): the rasteriser's input and output (the summary's throughput line).
    pub texels_decoded: u64,
    pub texels_stored: u64,
    /// Images drawn as the magenta/black fallback: missing or unreadable at import, or failed to decode.
    pub image_fallbacks: u64,
    /// Images used only by OPAQUE materials whose alpha channel (some texel below 255) was ignored, as
    /// glTF specifies: their colour is kept where alpha is 0.
    pub images_alpha_ignored: u64,
    /// How the memory budget was split, if there was one.
    pub memory: Option<memory::MemoryPlan>,
    pub warnings: Vec<String>,
    /// What the import of the scene skipped or replaced (missing images drawn with the fallback checker,
    /// skipped primitives and triangles), with its warnings: the build's output shows them.
    pub import: crate::scene::ImportReport,
}

/// Validates `opts` against `scene` and derives the stored [`BuildParams`].
pub fn resolve_params(
    scene: &Scene,
    opts: &BuildOptions,
) -> Result<(BuildParams, f64), BuildError> {
    let bad = |name, value: String, why: &'static str| {
        Err(BuildError::InvalidParam {
            name,
            value,
            why: why.into(),
        })
    };
    if !valid_atlas_size(opts.atlas_size) {
        return bad(
            "atlas-size",
            opts.atlas_size.to_string(),
            "must be a power of two from 64 to 16384",
        );
    }
    if !valid_border(opts.border, opts.atlas_size) {
        let why = format!(
            "must be less than a quarter of the atlas size {}: at most {} (or a larger --atlas-size)",
            opts.atlas_size,
            (opts.atlas_size / 4).saturating_sub(1)
        );
        return Err(BuildError::InvalidParam {
            name: "border",
            value: opts.border.to_string(),
            why: why.into(),
        });
    }
    if !(opts.fov_deg > 0.0 && opts.fov_deg < 180.0) {
        return bad(
            "fov",
            crate::util::short_number(opts.fov_deg),
            "must be between 0 and 180 degrees",
        );
    }
    if !(opts.texel_ratio.is_finite() && opts.texel_ratio > 0.0) {
        return bad(
            "texel-ratio",
            crate::util::short_number(opts.texel_ratio),
            "must be a finite number > 0",
        );
    }
    if opts.screen_width == 0 {
        return bad("screen-width", "0".into(), "must be positive");
    }
    if !(opts.leaf_originals_atlases.is_finite() && opts.leaf_originals_atlases >= 0.0) {
        return bad(
            "leaf-originals",
            crate::util::short_number(opts.leaf_originals_atlases),
            "must be a finite number of atlases ≥ 0",
        );
    }
    if opts.max_depth > MAX_DEPTH {
        return Err(BuildError::InvalidParam {
            name: "max-depth",
            value: opts.max_depth.to_string(),
            why: format!("must be from 0 (one leaf per tree) to {MAX_DEPTH}").into(),
        });
    }
    let (lo, hi) = scene.bounds().ok_or_else(|| empty_scene(scene))?;
    let diagonal = (hi - lo).length();
    // A vertex is stored as 32-bit floats relative to its leaf's centre: a scene wider than an f32 holds
    // (a node matrix scaling by 1e300) would store every position as 0, one point, without this.
    let extent = (hi - lo).max_element();
    if !(diagonal.is_finite() && extent <= f64::from(f32::MAX)) {
        return Err(BuildError::ExtentOverflow {
            path: scene.source.display().to_string(),
            extent,
        });
    }
    let d_min = match opts.d_min {
        DMin::Metres(m) => m,
        DMin::Ratio(r) => {
            if !(r.is_finite() && r > 0.0) {
                return bad(
                    "d-min-ratio",
                    crate::util::short_number(r),
                    "must be a finite number > 0",
                );
            }
            diagonal / r
        }
    };
    if !(d_min.is_finite() && d_min > 0.0) {
        if let DMin::Ratio(r) = opts.d_min {
            return Err(BuildError::DegenerateExtent {
                path: scene.source.display().to_string(),
                diagonal,
                ratio: r,
            });
        }
        return bad(
            "d-min",
            crate::util::short_number(d_min),
            // Given in metres: the scene's extent plays no part (the single-point hint is the ratio's).
            "must be a finite distance > 0, in metres",
        );
    }
    let params = BuildParams {
        d_min,
        screen_width: opts.screen_width,
        fov_deg: opts.fov_deg,
        texel_ratio: opts.texel_ratio,
        atlas_size: opts.atlas_size,
        border: opts.border,
        max_depth: opts.max_depth,
        up: scene.up,
    };
    // Texels per world unit at d_min (§5.2.1): overflowing (a d_min near the smallest f64, or a huge
    // --texel-ratio × --screen-width) it would size every triangle at 0 texels, the coarsest tree.
    let f_proj = params.f_proj();
    if !(f_proj.is_finite() && f_proj > 0.0) {
        return bad(
            "d-min",
            crate::util::short_number(d_min),
            "gives no finite texel density with these --screen-width, --fov and --texel-ratio \
             (screen width × texel ratio / (2 d_min tan(fov/2)) overflows): raise --d-min or lower \
             --texel-ratio",
        );
    }
    Ok((params, diagonal))
}

/// The triangles of each tree: opaque materials, and (only if the scene has any) alpha materials.
pub fn partition_triangles(scene: &Scene) -> Vec<(TreeKind, Vec<u32>)> {
    let mut opaque = Vec::new();
    let mut alpha = Vec::new();
    for (i, t) in scene.triangles.iter().enumerate() {
        if scene.materials[t.material.idx()].alpha.uses_alpha() {
            alpha.push(i as u32);
        } else {
            opaque.push(i as u32);
        }
    }
    [(TreeKind::Opaque, opaque), (TreeKind::Alpha, alpha)]
        .into_iter()
        .filter(|(_, t)| !t.is_empty())
        .collect()
}

/// Builds the atlas tree(s) of `scene` and writes them atomically to `out`: the stages of the module docs,
/// one phase each.
pub fn build(
    scene: &Scene,
    opts: &BuildOptions,
    out: &Path,
    progress: &dyn Progress,
) -> Result<BuildReport, BuildError> {
    let t_all = Instant::now();
    let Planned {
        params,
        diagonal,
        memory_plan,
        mut timings,
        forest,
        mut reports,
    } = plan_build(scene, opts, plan_forest::Budget::Build, progress)?;

    // One shard, in memory: the cut at the roots, so nothing is left above it (module shard).
    let t = Instant::now();
    let writer = FileWriter::create(out, &forest)?;
    let cache = image_cache::ImageCache::new(scene, memory_plan.image_cache_bytes(opts));
    let cut = shard::choose_cut(&forest, 1);
    let units = cut.shards.first().map_or(&[][..], Vec::as_slice);
    let pass = pixel_pass(
        scene,
        opts.pixel_options(),
        &forest,
        units,
        &writer,
        &cache,
        progress,
    )?;
    for (report, db) in reports.iter_mut().zip(&pass.atlas_psnr_db) {
        report.atlas_psnr_db = *db;
    }
    let none = |_| {};
    let above = raster::AtlasOut::new(&forest, opts.pixel_options(), &writer, &none);
    let handoffs = |u| pass.handoffs.get(&u).map(|h| Ok(h.clone()));
    shard::raster_forest_above(&above, &forest, &handoffs)?;
    timings.push("rasterise", t);

    let t = Instant::now();
    progress.stage("write", None);
    let summary = writer.finish()?;
    progress.finish_stage();
    timings.push("write", t);
    timings.push("total", t_all);

    let mut report = build_report(
        params,
        diagonal,
        &forest,
        reports,
        summary.total,
        timings,
        &cache,
    );
    report.memory = memory_plan;
    report.import = scene.report.clone();
    Ok(report)
}

/// The memory budget's split for `scene` ([`memory::plan_memory`]), or `None` without a budget.
pub(super) fn plan_memory(
    scene: &Scene,
    opts: &BuildOptions,
    params: &BuildParams,
    load: memory::PlanLoad,
) -> Result<Option<memory::MemoryPlan>, BuildError> {
    let Some(budget) = opts.max_memory_bytes else {
        return Ok(None);
    };
    let threads = rayon::current_num_threads() as u64;
    let plan = memory::plan_memory(
        budget,
        load,
        params.atlas_size,
        threads,
        image_load(&scene.images, opts.alpha_mips, threads),
        opts.image_cache_bytes,
    )
    .map_err(|e| e.naming(largest_image_name(&scene.images)))?;
    Ok(Some(plan))
}

/// What `images` weigh in the image cache, drawn by `threads` rasteriser threads (the count the memory
/// check is given, one number for both) with `alpha_mips`.
pub(super) fn image_load(
    images: &[crate::scene::ImageSource],
    alpha_mips: image_ops::AlphaMips,
    threads: u64,
) -> memory::ImageLoad {
    let sides = images.iter().map(|i| (i.width, i.height));
    match alpha_mips {
        image_ops::AlphaMips::Plain => memory::ImageLoad::of(sides, threads),
        image_ops::AlphaMips::Coverage => memory::ImageLoad::with_coverage_mips(sides, threads),
    }
}

/// The name of the largest of `images` (the first of equals), for [`memory::MemoryError::naming`].
pub(super) fn largest_image_name(images: &[crate::scene::ImageSource]) -> &str {
    let mut largest: Option<&crate::scene::ImageSource> = None;
    for image in images {
        if largest.is_none_or(|l| image.texels() > l.texels()) {
            largest = Some(image);
        }
    }
    largest.map_or("none", |i| i.name.as_str())
}

/// The image cache bound of a build: the memory plan's, or the option's without a budget.
pub(super) trait CacheBound {
    fn image_cache_bytes(&self, opts: &BuildOptions) -> u64;
}

impl CacheBound for Option<memory::MemoryPlan> {
    fn image_cache_bytes(&self, opts: &BuildOptions) -> u64 {
        self.as_ref()
            .map_or(opts.image_cache_bytes, |m| m.image_cache_bytes)
    }
}

/// Stage 4 below the cut: the subtrees `units` of every tree into `sink` (the shard's part of the pixel
/// pass); returns each unit root's level 1. Each tree's report gets the PSNR of the atlases rasterised
/// here against the uncompressed atlases they were encoded from.
#[allow(clippy::too_many_arguments)]
pub(super) fn pixel_pass(
    scene: &Scene,
    pixels: raster::PixelOptions,
    forest: &AtlasForest,
    units: &[shard::Unit],
    sink: &dyn crate::store::BlockSink,
    cache: &image_cache::ImageCache<'_>,
    progress: &dyn Progress,
) -> Result<PixelPass, BuildError> {
    let mut total_nodes = 0u64;
    for u in units {
        let tree = &forest.trees[u.tree as usize];
        total_nodes += shard::subtree_nodes(tree, crate::ids::NodeId(u.node));
    }
    progress.stage("rasterise atlases", Some(total_nodes));
    let set = |n: u64| progress.set(n);
    let ctx = raster::RasterCtx {
        scene,
        cache,
        out: raster::AtlasOut::new(forest, pixels, sink, &set),
    };
    // The trees side by side: a small alpha tree (one leaf of many originals, each decoded on one
    // thread) no longer runs alone after the opaque tree. Every block has its offset already, so the
    // file does not depend on the order.
    use rayon::prelude::*;
    let per_tree: Vec<Vec<(shard::Unit, raster::Handoff)>> = forest
        .trees
        .par_iter()
        .enumerate()
        .map(|(t, tree)| {
            let mine: Vec<shard::Unit> = units
                .iter()
                .filter(|u| u.tree as usize == t)
                .copied()
                .collect();
            let roots: Vec<crate::ids::NodeId> =
                mine.iter().map(|u| crate::ids::NodeId(u.node)).collect();
            let levels = raster::raster_subtrees(&ctx, tree, &roots)?;
            Ok(mine.into_iter().zip(levels).collect())
        })
        .collect::<Result<_, BuildError>>()?;
    cache.check_decodes()?;
    let handoffs = per_tree.into_iter().flatten().collect();
    let atlas_psnr_db = forest
        .trees
        .iter()
        .map(|tree| {
            let [sse, samples] = &ctx.out.atlas_error[tree.kind.index()];
            crate::texfmt::psnr(sse.load(Ordering::Relaxed), samples.load(Ordering::Relaxed))
        })
        .collect();
    progress.finish_stage();
    Ok(PixelPass {
        handoffs,
        atlas_psnr_db,
    })
}

/// What [`pixel_pass`] hands back: the units' handoffs and each tree's atlas PSNR against the
/// uncompressed atlases it rasterised.
pub(super) struct PixelPass {
    pub(super) handoffs: std::collections::HashMap<shard::Unit, raster::Handoff>,
    pub(super) atlas_psnr_db: Vec<f64>,
}
