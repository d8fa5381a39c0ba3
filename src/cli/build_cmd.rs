use super::args::BuildParamsArgs;
use super::build_report::{print_import, print_report, print_stage_peaks, print_times};
use super::{UpArg, load_scene_within, progress::Bars};
use anyhow::Context;
use atlastree::preprocess::shard::{ShardSpec, shard_from_env};
use atlastree::preprocess::{
    BuildOptions, DMin, ShardPlanError, ShardReport, ShardedOptions, build, build_shard,
    build_shard_planned, plan_shards, shard_plan_key,
};
use atlastree::store::shard_plan::{PlanFile, plan_path};
use atlastree::texfmt::Compression;
use atlastree::util::human_bytes;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

// Its --help text is the doc comment of `cli::Command::Build` (clap shows the variant's, not this struct's).
#[derive(Args, Debug)]
pub(crate) struct BuildArgs {
    /// The glTF scene (.gltf or .glb). What it asks for and is not drawn is one counted warning per
    /// feature (vertex colours, NEAREST magnification, emission, skins); not warned: every triangle is
    /// drawn from both sides (`doubleSided: false`, the default of most files, is not culled).
    pub scene: PathBuf,
    /// Output paging file, written atomically: an interrupted build (Ctrl-C, SIGTERM) leaves no partial
    /// file; a killed one (SIGKILL, the OOM killer) leaves a hidden `.NAME.tmp.PID.*` beside it, removed
    /// by the next build of the same output. A symbolic link is written through (the file it names is
    /// replaced).
    #[arg(short, long)]
    pub out: PathBuf,
    /// d_min in metres (world units). Conflicts with --d-min-ratio.
    #[arg(long, conflicts_with = "d_min_ratio")]
    pub d_min: Option<f64>,
    /// d_min = scene diagonal / R (the paper: 151 for Berlin, 62 for Chemnitz). Default 151.
    #[arg(long)]
    pub d_min_ratio: Option<f64>,
    /// Side of every atlas in texels (power of two).
    #[arg(long, default_value_t = 1024)]
    pub atlas_size: u32,
    /// Border around each packed texture area, texels. It keeps log2(border) mip levels of a leaf atlas
    /// free of neighbouring textures, one level fewer per tree level up. Default 16 (the paper used 8: on
    /// data/city root-atlas views lose 5 dB against the original textures at 8); with --compress a 4×4 block
    /// never mixes two textures at the two finest protected levels.
    #[arg(long, default_value_t = 16)]
    pub border: u32,
    /// Down-sampling kernel of the atlas mip chains and inner atlases: `box` (2×2 mean) or `kaiser`
    /// (Kaiser-windowed sinc, sharper, slight clamped ringing). Original textures always use `box`.
    #[arg(long, default_value = "box")]
    pub filter: atlastree::preprocess::image_ops::MipFilter,
    /// Alpha through the mips of alpha-tested (MASK) textures, in atlases and original textures. `plain`:
    /// filtered like colour, so foliage, fences and railings thin out with distance (their α-test coverage
    /// falls); `coverage`: each level's alpha rescaled per texture area to keep level 0's coverage (Castaño
    /// 2010). BLEND materials are never changed. See `sweep` for what it buys against a supersampled
    /// reference.
    #[arg(long, default_value = "plain")]
    pub alpha_mips: atlastree::preprocess::image_ops::AlphaMips,
    /// Block compression of every atlas and original texture, every mip level (paper §6: S3TC shrinks the
    /// paging file and each page-in). `bc1`: BC1 (8 bytes per 4×4 texels, 1/8 of RGBA8) for the opaque tree,
    /// BC3 (16 bytes) for the alpha tree; `bc7`: BC7 (16 bytes, better quality) for both. The report gives
    /// each tree's PSNR against the uncompressed atlases.
    #[arg(long, value_enum, default_value_t = CompressArg::None)]
    pub compress: CompressArg,
    /// How repeated textures are stored. `wrap`: each atlas rect holds at most one period of its texture
    /// (the used range when shorter) at the texels per period d_min needs, with a border filled by the
    /// sampler's own rule, and the fragment shader wraps the UV into it: the file no longer grows with how
    /// often a texture repeats. `bake`: every period a triangle's UVs span is copied into the atlas
    /// (triangles shifted by whole periods share them) and big triangles are cut into pieces (the paper's §5.2.2; the sweep's reference for what wrapping costs).
    #[arg(long, default_value = "wrap")]
    pub repeat: atlastree::preprocess::RepeatMode,
    /// Build the tree over the triangles of these materials only (comma-separated glob patterns on glTF
    /// material names, `*` and `?`), e.g. `--materials 'facade_*'` for the paper's Berlin test, whose atlas
    /// tree held only the facades (§7). d_min ratios then refer to the kept geometry's diagonal.
    #[arg(long, value_delimiter = ',', value_name = "GLOB")]
    pub materials: Vec<String>,
    /// Up axis; `auto` takes the axis of least extent where it is under half the next least, else y
    /// (glTF's convention).
    #[arg(long, value_enum, default_value_t = UpArg::Auto)]
    pub up: UpArg,
    /// One step of a sharded build (city scale, docs/city-scale.md). `plan`: plan the whole tree once
    /// (every triangle in memory, no pixels) into `OUT.plan` (and its report, `….json`). `I/N` (0-based,
    /// e.g. `3/16`): rasterise about 1/N of the texel work into `OUT.shard-I-of-N` (and `….json`) beside OUT;
    /// with `OUT.plan` present (same scene and flags, else refused) the shard reads it and imports only the
    /// scene's images, without it every shard plans the whole tree itself (identically). `atlastree merge OUT`
    /// then makes OUT, byte-identical to a build without --shard. `auto` takes I and N from the scheduler:
    /// Slurm job arrays (SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT), Kubernetes Indexed Jobs
    /// (JOB_COMPLETION_INDEX and ATLASTREE_SHARD_COUNT set to the completions), AWS Batch arrays
    /// (AWS_BATCH_JOB_ARRAY_INDEX and ATLASTREE_SHARD_COUNT set to the array size).
    #[arg(long, value_name = "plan|I/N|auto", allow_hyphen_values = true)]
    pub shard: Option<String>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
    #[command(flatten, next_help_heading = "Build parameters (shared with sweep)")]
    pub params: BuildParamsArgs,
}

/// `--compress` values.
#[derive(clap::ValueEnum, Copy, Clone, Debug, PartialEq, Eq)]
pub(crate) enum CompressArg {
    /// RGBA8 (4 bytes per texel).
    None,
    /// BC1 opaque tree, BC3 alpha tree.
    Bc1,
    /// BC7 for both trees.
    Bc7,
}

impl CompressArg {
    pub(crate) fn compression(self) -> Compression {
        match self {
            CompressArg::None => Compression::None,
            CompressArg::Bc1 => Compression::Bc1,
            CompressArg::Bc7 => Compression::Bc7,
        }
    }
}

impl BuildArgs {
    /// The build options: these flags over the shared build parameters.
    pub(crate) fn options(&self) -> BuildOptions {
        let base = BuildOptions {
            d_min: match (self.d_min, self.d_min_ratio) {
                (Some(m), _) => DMin::Metres(m),
                (None, Some(r)) => DMin::Ratio(r),
                (None, None) => DMin::Ratio(151.0),
            },
            atlas_size: self.atlas_size,
            border: self.border,
            mip_filter: self.filter,
            alpha_mips: self.alpha_mips,
            compress: self.compress.compression(),
            repeat: self.repeat,
            ..BuildOptions::default()
        };
        self.params.apply(base)
    }
}

pub(super) fn run(a: BuildArgs) -> anyhow::Result<ExitCode> {
    let step = shard_step(a.shard.as_deref())?;
    // Before any work, in every step: `-o` naming the scene or another file that is not a paging file
    // fails at once, not after the shards have run (the merge writes OUT).
    super::reject_output_url(&a.out, "-o")?;
    atlastree::store::check_replaceable(&a.out)?;
    // This step's own output too (the magic without its version byte: an older plan or shard is ours).
    match step {
        ShardStep::Whole => {}
        ShardStep::Plan => {
            let plan = plan_path(&a.out);
            let magic = &atlastree::store::shard_plan::PLAN_MAGIC[..6];
            atlastree::store::check_replaceable_as(&plan, magic, "plan file")?;
        }
        ShardStep::Shard(spec) => {
            let shard = atlastree::preprocess::shard::shard_path(&a.out, spec);
            let magic = &atlastree::store::shard::SHARD_MAGIC[..7];
            atlastree::store::check_replaceable_as(&shard, magic, "shard file")?;
        }
    }
    warn_wide_border(&a);
    warn_budget_above_limit(&a);
    // An atlas size that is none is refused by its own check, later.
    let pixels = step != ShardStep::Plan && atlastree::preprocess::valid_atlas_size(a.atlas_size);
    if let (Some(budget), true) = (a.params.memory_budget(), pixels) {
        let threads = rayon::current_num_threads() as u64;
        atlastree::preprocess::memory::check_pixel_floor(budget, a.atlas_size, threads)?;
    }
    // A claim on this shard's output from the start (a temp of it, locked, removed when the run ends):
    // the shard's own temp comes only when its pixels are written, so a merge started meanwhile (a wrong
    // `afterok`) called the shard missing and offered the command that runs it twice (fault hunt,
    // session 39); it now says the shard is being written. Where it cannot be made, the shard's writer
    // reports why.
    let _claim = match step {
        ShardStep::Shard(spec) => {
            let shard = atlastree::preprocess::shard::shard_path(&a.out, spec);
            atlastree::util::AtomicFile::create(&shard, 0o644).ok()
        }
        _ => None,
    };
    let bars = Bars::new(a.quiet || a.json);
    if let ShardStep::Shard(spec) = step {
        let plan = plan_path(&a.out);
        if plan.exists() {
            return run_planned_shard(&a, spec, &plan, &bars);
        }
    }
    let t = std::time::Instant::now();
    // A scene past what the budget's plan holds is refused while its nodes are walked, not after a
    // node graph sharing children has instanced gigabytes of triangles.
    use atlastree::preprocess::memory::{max_input_bytes, max_json_bytes, max_plan_triangles};
    let budget = a.params.memory_budget();
    let (max_triangles, max_json) = (budget.map(max_plan_triangles), budget.map(max_json_bytes));
    let max_input = budget.map(max_input_bytes);
    let mut scene =
        load_scene_within(&a.scene, a.up, max_triangles, max_json, max_input).map_err(|e| {
            let plan_step = matches!(step, ShardStep::Plan);
            over_budget(e, budget, a.params.max_memory.is_some(), plan_step)
        })?;
    if !a.materials.is_empty() {
        let kept = super::retain_materials(&mut scene, &a.materials)?;
        if !(a.quiet || a.json) {
            println!(
                "materials {}: kept {} materials, dropped {} triangles",
                a.materials.join(","),
                kept.materials_kept,
                kept.triangles_dropped
            );
        }
    }
    let import_s = t.elapsed().as_secs_f64();
    // The import's own peak (the process's so far); each stage of the build then reports its own
    // (build summary, `memory_window::MemoryWindow`).
    let import_peak = atlastree::util::peak_rss_bytes();
    match step {
        ShardStep::Shard(spec) => {
            return run_shard(&a, &scene, spec, (import_s, import_peak), &bars);
        }
        ShardStep::Plan => return run_plan(&a, &scene, (import_s, import_peak), &bars),
        ShardStep::Whole => {}
    }
    let mut report = build(&scene, &a.options(), &a.out, &bars)
        .with_context(|| format!("building {} into {}", a.scene.display(), a.out.display()))?;
    report.stages.prepend("import", import_s, import_peak);
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_report(&report, &a.out);
    }
    Ok(ExitCode::SUCCESS)
}

/// Which step of a build `--shard` asks for.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum ShardStep {
    /// No `--shard`: the whole build in this process.
    Whole,
    /// `--shard plan`: the plan, once, into `OUT.plan`.
    Plan,
    /// `--shard I/N` or `auto` (from the scheduler's environment).
    Shard(ShardSpec),
}

/// Up front, on stderr (the build may take long and write much): a border over 1/16 of the atlas side
/// takes most of every atlas (`--border 255` at 1024 built 3.2 GiB from a scene whose default file is
/// 0.1 GiB, silently).
fn warn_wide_border(a: &BuildArgs) {
    // A border of a quarter of the atlas or more is refused, with its own message, right after; so is an
    // atlas size that is none (`--atlas-size 100` was warned about before it was refused; docs hunt,
    // session 34).
    let refused = !atlastree::preprocess::valid_border(a.border, a.atlas_size)
        || !atlastree::preprocess::valid_atlas_size(a.atlas_size);
    if a.border.saturating_mul(16) > a.atlas_size && !refused {
        eprintln!(
            "warning: --border {} is more than 1/16 of --atlas-size {}: every packed texture takes at least \
             {} texels a side, so few fit one atlas and the tree and the file grow (a border protects \
             log2(border) mip levels; the default is 16)",
            a.border,
            a.atlas_size,
            (2 * a.border + 1).div_ceil(4) * 4
        );
    }
}

/// An explicit `--max-memory` above what this process may use (RAM, its cgroup's limit, `ulimit -v`) is
/// said up front; the budget is that limit (`args::within_limit`): a 4 GiB budget under `ulimit -v
/// 700000` was accepted without a word and the build aborted in malloc (session 30's memory hunt).
fn warn_budget_above_limit(a: &BuildArgs) {
    let Some(asked) = a.params.max_memory.map(|m| m.bytes()) else {
        return;
    };
    let (Some(asked), Some(limit)) = (asked, super::args::process_memory_limit()) else {
        return;
    };
    if asked > limit {
        eprintln!(
            "warning: --max-memory {} is more than the {} this process may use (the machine's memory, or its \
             cgroup's limit or what ulimit -v leaves where smaller): the budget is {} (a build that needs more is \
             refused up front; above it an allocation would fail mid-build)",
            atlastree::util::human_bytes(asked),
            atlastree::util::human_bytes(limit),
            atlastree::util::human_bytes(limit)
        );
    }
}

fn shard_step(arg: Option<&str>) -> anyhow::Result<ShardStep> {
    match arg {
        None => Ok(ShardStep::Whole),
        Some("plan") => Ok(ShardStep::Plan),
        Some("auto") => {
            // A value that is not Unicode is read lossily (U+FFFD), so it is refused as a bad value,
            // not taken for an unset variable.
            let get = |k: &str| {
                std::env::var_os(k).map(|v| {
                    v.into_string()
                        .unwrap_or_else(|v| v.to_string_lossy().into_owned())
                })
            };
            let (spec, scheduler) = shard_from_env(&get)?;
            eprintln!("--shard auto: shard {spec} from the {scheduler} environment");
            for (variable, value) in
                atlastree::preprocess::shard::ignored_scheduler_variables(&get, scheduler)
            {
                eprintln!(
                    "warning: --shard auto: {variable}={value:?} is set too and ignored (the {scheduler} \
                     environment comes first)"
                );
            }
            Ok(ShardStep::Shard(spec))
        }
        Some(s) => Ok(ShardStep::Shard(s.parse::<ShardSpec>()?)),
    }
}

/// `out` as the shell word an `atlastree merge OUT` hint shows (quoted where it must be).
fn merge_arg(out: &std::path::Path) -> String {
    use atlastree::util::shell_words::{path_to_recorded, shell_word};
    shell_word(&path_to_recorded(out))
}

/// The scene error somewhere in `e`'s chain (a planned shard's comes wrapped in a build error).
fn scene_error(e: &anyhow::Error) -> Option<&atlastree::scene::SceneError> {
    use atlastree::preprocess::BuildError;
    e.chain()
        .find_map(|c| match c.downcast_ref::<BuildError>() {
            Some(BuildError::Scene(s)) => Some(&**s),
            _ => c.downcast_ref(),
        })
}

/// A scene refused in the node walk for the memory budget, with what its plan alone needs (every
/// triangle held at once; a whole build or shard needs the pixel pass's share on top, the plan step
/// nothing more). `given`: the budget is `--max-memory`'s, else the default.
fn over_budget(
    e: anyhow::Error,
    budget: Option<u64>,
    given: bool,
    plan_step: bool,
) -> anyhow::Error {
    use atlastree::preprocess::memory::{
        BASE_BYTES, JSON_BYTES_FACTOR, PLAN_BYTES_PER_EXTRA_VERTEX, PLAN_BYTES_PER_TRIANGLE,
        PlanLoad,
    };
    use atlastree::scene::SceneError;
    let scene = scene_error(&e);
    let source = if given {
        "--max-memory"
    } else {
        "the default budget (half of this machine's memory, or of its cgroup's or address-space limit)"
    };
    if let (Some(&SceneError::OverInputBudget { bytes, .. }), Some(budget)) = (scene, budget) {
        return e.context(format!(
            "the budget is too small: reading {} of scene input needs about {} MiB ({} MiB of process \
             base besides it), over {source} of {} MiB: give a larger --max-memory",
            atlastree::util::human_bytes(bytes),
            BASE_BYTES.saturating_add(bytes).div_ceil(1 << 20),
            BASE_BYTES >> 20,
            budget >> 20
        ));
    }
    if let (Some(&SceneError::OverJsonBudget { json_bytes, .. }), Some(budget)) = (scene, budget) {
        let needed = BASE_BYTES.saturating_add(json_bytes.saturating_mul(JSON_BYTES_FACTOR));
        return e.context(format!(
            "the budget is too small: parsing {} of glTF JSON needs about {} MiB ({} MiB of process \
             base and ~{JSON_BYTES_FACTOR} bytes a byte of JSON), over {source} of {} MiB: give a larger \
             --max-memory",
            atlastree::util::human_bytes(json_bytes),
            needed.div_ceil(1 << 20),
            BASE_BYTES >> 20,
            budget >> 20
        ));
    }
    let (
        Some(&SceneError::OverTriangleBudget {
            triangles,
            vertices,
            json_bytes,
            ..
        }),
        Some(budget),
    ) = (scene, budget)
    else {
        return e;
    };
    // The triangles and the vertices beyond one a triangle, as the plan's own check counts them (it said
    // 723 MiB where this said 303 for a soup of 10⁶ triangles; fault hunt, session 39), and the JSON
    // parsed beside them while they are read.
    let extra_vertices = vertices.saturating_sub(triangles);
    let load = PlanLoad {
        extra_vertices,
        ..PlanLoad::triangles(triangles)
    };
    let plan = BASE_BYTES
        .saturating_add(load.bytes())
        .saturating_add(json_bytes.saturating_mul(JSON_BYTES_FACTOR));
    let vertex_share = if extra_vertices > 0 {
        format!(
            ", ~{PLAN_BYTES_PER_EXTRA_VERTEX} bytes a vertex beyond one a triangle ({extra_vertices})"
        )
    } else {
        String::new()
    };
    let pixels = if plan_step {
        ""
    } else {
        " and the pixel pass more"
    };
    let json = if json_bytes > 0 {
        format!(
            ", and ~{JSON_BYTES_FACTOR} bytes a byte of the {} of glTF JSON parsed beside them",
            atlastree::util::human_bytes(json_bytes)
        )
    } else {
        String::new()
    };
    e.context(format!(
        "the budget is too small: {triangles} triangles need at least {} MiB for the plan alone \
         ({} MiB of process base and ~{PLAN_BYTES_PER_TRIANGLE} bytes a triangle{vertex_share}, all held at once{json}){pixels}, \
         over {source} of {} MiB: give a larger --max-memory",
        plan.div_ceil(1 << 20),
        BASE_BYTES >> 20,
        budget >> 20
    ))
}

/// The scene filters of these flags in words: part of a plan's key, as they change the scene it covers.
fn selection(a: &BuildArgs) -> String {
    format!("materials={:?};up={:?}", a.materials, a.up)
}

/// The command line a shard or plan records for the "rebuild it with: …" hints of merge and of a refused
/// plan: as typed, but with the program, the scene and the output as absolute paths (resolved against this
/// process's working directory, without touching the file system), so the hint works from wherever merge
/// runs. A program named without a `/` is left for the shell's search path.
/// Every argument is recorded byte for byte (`util::shell_words`: a name that is not UTF-8, valid on Unix,
/// prints back in `$'…'` quoting and runs).
fn recorded_argv(
    args: impl Iterator<Item = std::ffi::OsString>,
    scene: &std::path::Path,
    out: &std::path::Path,
) -> Vec<String> {
    use atlastree::util::shell_words::path_to_recorded;
    let absolute = |p: &std::path::Path| {
        path_to_recorded(&std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf()))
    };
    let out_bytes = out.as_os_str().as_encoded_bytes();
    args.enumerate()
        .map(|(i, arg)| {
            let bytes = arg.as_encoded_bytes();
            let program = i == 0 && bytes.contains(&b'/');
            let path = i > 0 && (arg == scene.as_os_str() || arg == out.as_os_str());
            if program || path {
                return absolute(std::path::Path::new(&arg));
            }
            // The output attached to its flag: `--out=PATH`, `-o=PATH`, `-oPATH`.
            for flag in ["--out=", "-o=", "-o"] {
                if bytes.strip_prefix(flag.as_bytes()) == Some(out_bytes) {
                    return format!("{flag}{}", absolute(out));
                }
            }
            path_to_recorded(std::path::Path::new(&arg))
        })
        .collect()
}

fn run_plan(
    a: &BuildArgs,
    scene: &atlastree::scene::Scene,
    (import_s, import_peak): (f64, Option<u64>),
    bars: &Bars,
) -> anyhow::Result<ExitCode> {
    let opts = a.options();
    let key = shard_plan_key(&opts, &a.scene, &selection(a))?;
    let argv = recorded_argv(std::env::args_os(), &a.scene, &a.out);
    let mut report = plan_shards(scene, &opts, &a.out, key, argv, bars)
        .with_context(|| format!("planning {} for {}", a.scene.display(), a.out.display()))?;
    report.stages.prepend("import", import_s, import_peak);
    report.save();
    if a.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "wrote plan {} ({}): {} triangles → {} nodes, {} blocks",
        report.path.display(),
        human_bytes(report.file_bytes),
        report.triangles,
        report.nodes,
        report.blocks
    );
    print_times(&report.stages.timings);
    println!(
        "  peak memory {}",
        report.stages.peak_rss_bytes.map_or("?".into(), human_bytes)
    );
    print_stage_peaks(&report.stages.stage_peak_rss);
    print_import(&scene.report);
    for w in &report.warnings {
        println!("  warning: {w}");
    }
    println!(
        "  next: each shard with the same flags (`--shard I/N` or `auto`) reads this plan instead of planning; then \
         atlastree merge {}",
        merge_arg(&a.out)
    );
    Ok(ExitCode::SUCCESS)
}

/// A shard whose plan is `OUT.plan`: it imports only the scene's images.
fn run_planned_shard(
    a: &BuildArgs,
    spec: ShardSpec,
    plan: &std::path::Path,
    bars: &Bars,
) -> anyhow::Result<ExitCode> {
    let opts = a.options();
    let file = PlanFile::open(plan)
        .map_err(ShardPlanError::File)
        .with_context(|| {
            format!("reading the plan of shard {spec} (remove it to let the shard plan itself)")
        })?;
    let key = shard_plan_key(&opts, &a.scene, &selection(a))?;
    let sharded = ShardedOptions {
        spec,
        argv: recorded_argv(std::env::args_os(), &a.scene, &a.out),
        import: None,
    };
    if !(a.quiet || a.json) {
        println!("shard {spec}: planned by {}", plan.display());
    }
    let report = build_shard_planned(&file, key, &a.scene, &opts, &a.out, &sharded, bars)
        .map_err(|e| {
            // A plan file whose bytes fail their checks (found only by the streamed pass over its
            // tables) says what to do, as a truncated one does.
            let corrupt = matches!(&e, atlastree::preprocess::BuildError::Plan(p)
                if matches!(**p, ShardPlanError::File(_)));
            let e = anyhow::Error::new(e);
            if corrupt {
                e.context(format!(
                    "the plan {} is corrupt: make it again with `--shard plan`, or remove it to let the \
                     shard plan itself",
                    plan.display()
                ))
            } else {
                // Its images' input past the budget says what it needs, as a plain build's does (it
                // named no number and no flag; fault hunt, session 37).
                let budget = a.params.memory_budget();
                over_budget(e, budget, a.params.max_memory.is_some(), false)
            }
        })
        .with_context(|| {
            format!(
                "building shard {spec} of {} for {}",
                a.scene.display(),
                a.out.display()
            )
        })?;
    print_shard(a, spec, &report)
}

fn run_shard(
    a: &BuildArgs,
    scene: &atlastree::scene::Scene,
    spec: ShardSpec,
    import: (f64, Option<u64>),
    bars: &Bars,
) -> anyhow::Result<ExitCode> {
    let sharded = ShardedOptions {
        spec,
        argv: recorded_argv(std::env::args_os(), &a.scene, &a.out),
        import: Some(import),
    };
    let report = build_shard(scene, &a.options(), &a.out, &sharded, bars).with_context(|| {
        format!(
            "building shard {spec} of {} for {}",
            a.scene.display(),
            a.out.display()
        )
    })?;
    let code = print_shard(a, spec, &report)?;
    if !a.json {
        print_import(&scene.report);
    }
    Ok(code)
}

fn print_shard(a: &BuildArgs, spec: ShardSpec, report: &ShardReport) -> anyhow::Result<ExitCode> {
    if a.json {
        println!("{}", serde_json::to_string_pretty(report)?);
        return Ok(ExitCode::SUCCESS);
    }
    let r = report;
    println!(
        "wrote shard {spec}: {} ({}) — {} subtrees, {} nodes, {} blocks, work {:.2}× the mean",
        r.path.display(),
        human_bytes(r.file_bytes),
        r.units,
        r.nodes,
        r.blocks,
        r.work as f64 / r.work_mean.max(1.0)
    );
    print_times(&r.stages.timings);
    println!(
        "  images decoded {} ({} fallbacks), peak memory {}",
        r.images_decoded,
        r.image_fallbacks,
        r.stages.peak_rss_bytes.map_or("?".into(), human_bytes)
    );
    print_stage_peaks(&r.stages.stage_peak_rss);
    for w in &r.warnings {
        println!("  warning: {w}");
    }
    println!(
        "  when all {} shards are written: atlastree merge {}",
        spec.count,
        merge_arg(&a.out)
    );
    Ok(ExitCode::SUCCESS)
}

#[cfg(test)]
mod tests {
    use super::{over_budget, recorded_argv};
    use std::path::Path;

    /// Only the factors above 1 are named (a depth-0 tree has no level above its leaf); nothing short,
    /// no line.
    #[test]
    fn the_capped_line_names_only_what_falls_short() {
        use atlastree::preprocess::CappedShortfall;
        let s = |at_leaf, one_up, at_root| CappedShortfall {
            at_leaf,
            one_up,
            at_root,
        };
        let line = super::super::build_report::capped_line(3, &s(2.6, 1.0, 2.6)).unwrap();
        assert!(
            line.contains("up to 2.6× in leaves scaled to fit (close"),
            "{line}"
        );
        let line = super::super::build_report::capped_line(3, &s(1.0, 2.0, 19.0)).unwrap();
        assert!(
            line.contains("up to 2.0× one level above their leaf, 19.0× from the root ("),
            "{line}"
        );
        assert_eq!(
            super::super::build_report::capped_line(3, &s(1.0, 1.0, 1.0)),
            None
        );
        assert_eq!(
            super::super::build_report::capped_line(0, &s(2.0, 4.0, 8.0)),
            None
        );
    }

    /// PSNR text: the cap is lossless, a negative one (only a forged recorded error gives one) says it is
    /// impossible.
    #[test]
    fn psnr_text_names_lossless_and_impossible_values() {
        use super::super::build_report::fmt_psnr;
        assert_eq!(fmt_psnr(atlastree::texfmt::PSNR_CAP_DB), "lossless");
        assert_eq!(fmt_psnr(30.0), "30.00 dB");
        assert_eq!(fmt_psnr(0.0), "0.00 dB");
        let forged = fmt_psnr(-12.5);
        assert!(forged.starts_with("-12.50 dB (impossible") && forged.contains("--verify"));
    }

    /// A scene the node walk refused for `--max-memory` says what its plan needs, from the whole
    /// scene's count, against the budget given (not one rebuilt from the triangle cap).
    #[test]
    fn a_scene_over_the_triangle_budget_says_what_it_needs() {
        let refused = || {
            anyhow::Error::new(atlastree::scene::SceneError::OverTriangleBudget {
                file: "s.gltf".into(),
                triangles: 1_000_000,
                vertices: 3_000_000,
                instances: 3,
                max: 0,
                json_bytes: 0,
            })
        };
        // 64 MiB + 10⁶ × 250 bytes + 2·10⁶ × 220 bytes = 722.0 MiB (a soup: three vertices a triangle).
        let msg = format!("{:#}", over_budget(refused(), Some(32 << 20), true, false));
        assert!(
            msg.contains("at least 723 MiB for the plan alone")
                && msg.contains("a vertex beyond one a triangle (2000000)")
                && msg.contains("--max-memory of 32 MiB"),
            "{msg}"
        );
        assert!(
            msg.contains("1000000 triangles over 3 mesh instances"),
            "{msg}"
        );
        let msg = format!("{:#}", over_budget(refused(), Some(32 << 20), false, true));
        assert!(msg.contains("the default budget (half of"), "{msg}");
        // The plan step has no pixel pass.
        assert!(!msg.contains("pixel pass"), "{msg}");
        // No budget, or another error: unchanged.
        let none = over_budget(refused(), None, false, false);
        assert_eq!(format!("{none:#}"), format!("{:#}", refused()));
        let other = over_budget(anyhow::anyhow!("x"), Some(1), true, false);
        assert_eq!(format!("{other:#}"), "x");
    }

    #[test]
    fn the_recorded_command_line_names_program_scene_and_output_absolutely() {
        let cwd = std::env::current_dir().unwrap();
        let args = [
            "target/release/atlastree",
            "build",
            "scn/scene.gltf",
            "-o",
            "out/x.atlastree",
            "--shard",
            "0/2",
            "--compress",
            "bc1",
        ]
        .map(std::ffi::OsString::from);
        let got = recorded_argv(
            args.into_iter(),
            Path::new("scn/scene.gltf"),
            Path::new("out/x.atlastree"),
        );
        let abs = |p: &str| cwd.join(p).display().to_string();
        assert_eq!(
            got,
            [
                abs("target/release/atlastree"),
                "build".into(),
                abs("scn/scene.gltf"),
                "-o".into(),
                abs("out/x.atlastree"),
                "--shard".into(),
                "0/2".into(),
                "--compress".into(),
                "bc1".into(),
            ]
        );
        // `--out=`, an absolute scene and a program found on the search path are kept or made absolute.
        let args = ["atlastree", "build", "/data/s.glb", "--out=o.atlastree"]
            .map(std::ffi::OsString::from);
        let got = recorded_argv(
            args.into_iter(),
            Path::new("/data/s.glb"),
            Path::new("o.atlastree"),
        );
        assert_eq!(
            got,
            [
                "atlastree".to_string(),
                "build".into(),
                "/data/s.glb".into(),
                format!("--out={}", abs("o.atlastree")),
            ]
        );
        // `-oPATH` (clap's attached short form) too; another flag's value equal to no path is kept.
        let args =
            ["atlastree", "build", "s.glb", "-oout/x.at", "-q"].map(std::ffi::OsString::from);
        let got = recorded_argv(args.into_iter(), Path::new("s.glb"), Path::new("out/x.at"));
        assert_eq!(got[3], format!("-o{}", abs("out/x.at")));
        assert_eq!(got[4], "-q");
        let args = ["atlastree", "build", "s.glb", "-o=out/x.at"].map(std::ffi::OsString::from);
        let got = recorded_argv(args.into_iter(), Path::new("s.glb"), Path::new("out/x.at"));
        assert_eq!(got[3], format!("-o={}", abs("out/x.at")));
    }

    /// A scene whose name is not UTF-8 is made absolute and recorded byte for byte, so the hint quotes
    /// it as `$'…\xff…'` and runs (it printed U+FFFD and named no file).
    #[cfg(unix)]
    #[test]
    fn non_utf8_names_are_recorded_exactly() {
        use std::ffi::{OsStr, OsString};
        use std::os::unix::ffi::OsStrExt;
        let scene = OsStr::from_bytes(b"/data/sc\xff.gltf");
        let args = [
            OsString::from("atlastree"),
            OsString::from("build"),
            scene.to_owned(),
            OsString::from("-o"),
            OsString::from("/o/m.at"),
        ];
        let got = recorded_argv(args.into_iter(), Path::new(scene), Path::new("/o/m.at"));
        assert_eq!(
            atlastree::util::shell_words::shell_word(&got[2]),
            "$'/data/sc\\xff.gltf'"
        );
        assert_eq!(got[4], "/o/m.at");
    }
}
