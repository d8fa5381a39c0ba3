use super::args::BuildParamsArgs;
use super::{UpArg, load_scene};
use anyhow::{Context, bail};
use atlastree::camera::{Ground, PathKind};
use atlastree::gpu::{GpuContext, GpuOptions};
use atlastree::preprocess::BuildOptions;
use atlastree::render::reference::Reference;
use atlastree::sweep::output::write_outputs;
use atlastree::sweep::summary::{MEASURED_NOTHING, empty_frames_note, recommendation};
use atlastree::sweep::{Grid, Plan, SweepOptions, SweepProgress, run_sweep, sample_path};
use clap::Args;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

// Its --help text is the doc comment of `cli::Command::Sweep` (clap shows the variant's, not this struct's).
#[derive(Args, Debug)]
pub(crate) struct SweepArgs {
    /// The glTF scene (.gltf or .glb).
    pub scene: PathBuf,
    /// Camera path: overview-dive, street, orbit, or a keyframe JSON file: `{"keyframes": [{"time": s,
    /// "eye": [x, y, z], "target": [x, y, z], "fov": degrees}, …], "up": [0, 1, 0], "near": 0.25,
    /// "far": 100000}` (the scene's units; `aspect`, if given, is not used: frames take the viewport's).
    #[arg(long, default_value = "overview-dive")]
    pub path: PathKind,
    /// Output directory.
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
    /// Grid: `small`, `full`, or a JSON file.
    #[arg(long, default_value = "small")]
    pub grid: String,
    /// Frames spread evenly over the path (overrides the grid's).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Frame width in pixels (overrides the grid's).
    #[arg(long)]
    pub width: Option<u32>,
    /// Frame height in pixels (overrides the grid's).
    #[arg(long)]
    pub height: Option<u32>,
    /// Keep the paging files in OUT/builds (by default each is deleted once its variants are measured). A
    /// later sweep into the same OUT removes the builds its grid does not make, kept or not (they would
    /// sit beside its report as if they were its own): copy them elsewhere to keep them.
    #[arg(long)]
    pub keep_builds: bool,
    /// Sampler anisotropy (1–16, or `auto`: 16 on a GPU, 1 on a software rasteriser) of every render, the
    /// reference included. On lavapipe the tree's draws (explicit gradients) and the reference (implicit)
    /// filter differently under anisotropy (measured 28–44 dB apart at 16, 75 dB at 1), and the
    /// explicit-gradient path costs ~100× per pixel: 1 isolates the atlas tree's own error.
    #[arg(long, default_value = "auto", value_parser = super::render_cmd::parse_anisotropy)]
    pub anisotropy: u16,
    /// What every frame is compared with: `original` (the original textures at the frame's resolution,
    /// the default) or `supersampled[:S]` (ground truth: the original textures at S × S the pixels, S = 4
    /// by default, box-filtered in linear light); against the latter the original textures are measured
    /// too, per build, so the report shows where they fall short as well.
    #[arg(long, default_value = "original")]
    pub reference: Reference,
    /// Up axis; `auto` takes the axis of least extent where it is under half the next least, else y
    /// (glTF's convention).
    #[arg(long, value_enum, default_value_t = UpArg::Auto)]
    pub up: UpArg,
    /// Print the variant rows and the recommendation as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// No progress bar.
    #[arg(short, long)]
    pub quiet: bool,
    #[command(
        flatten,
        next_help_heading = "Build parameters (every build of the grid)"
    )]
    pub build: BuildParamsArgs,
}

/// An indicatif bar with ETA for the sweep.
struct Bar(ProgressBar);

impl SweepProgress for Bar {
    fn begin(&self, total: u64) {
        self.0.set_length(total);
    }
    fn message(&self, msg: &str) {
        self.0.set_message(msg.to_string());
    }
    fn advance(&self, units: u64) {
        self.0.inc(units);
    }
    fn finish(&self) {
        self.0.finish_and_clear();
    }
}

fn load_grid(spec: &str) -> anyhow::Result<Grid> {
    if let Some(g) = Grid::preset(spec) {
        return Ok(g);
    }
    if !spec.to_ascii_lowercase().ends_with(".json") {
        bail!("unknown --grid {spec:?}: expected small, full or a .json file");
    }
    let text = atlastree::util::read_text_file(std::path::Path::new(spec))
        .with_context(|| format!("reading grid {spec}"))?;
    Ok(Grid::from_json(&text, spec)?)
}

/// A checked `sweep` run.
pub(crate) struct SweepConfig {
    pub scene: PathBuf,
    pub up: UpArg,
    pub path: PathKind,
    pub out: PathBuf,
    /// The grid with the command line's overrides, validated, as a plan.
    pub plan: Plan,
    pub keep_builds: bool,
    pub anisotropy: u16,
    pub reference: Reference,
    /// Options of every build beside the grid's knobs.
    pub build: BuildOptions,
    pub json: bool,
    pub quiet: bool,
}

impl SweepArgs {
    /// Loads the grid, applies `--frames`, `--width` and `--height`, and validates it.
    pub(crate) fn validate(self) -> anyhow::Result<SweepConfig> {
        let mut grid = load_grid(&self.grid)?;
        if let Some(f) = self.frames {
            grid.frames = f;
        }
        if let Some(w) = self.width {
            grid.width = w;
        }
        if let Some(h) = self.height {
            grid.height = h;
        }
        // Values from flags are named as flags, not blamed on the grid file.
        let flags: Vec<String> = [
            ("--frames", self.frames.map(|f| f.to_string())),
            ("--width", self.width.map(|w| w.to_string())),
            ("--height", self.height.map(|h| h.to_string())),
        ]
        .into_iter()
        .filter_map(|(flag, v)| v.map(|v| format!("{flag} {v}")))
        .collect();
        let given = if flags.is_empty() {
            self.grid.clone()
        } else {
            format!("{} with {}", self.grid, flags.join(" "))
        };
        grid.validate(&given)?;
        Ok(SweepConfig {
            scene: self.scene,
            up: self.up,
            path: self.path,
            out: self.out,
            plan: grid.plan(),
            keep_builds: self.keep_builds,
            anisotropy: self.anisotropy,
            reference: self.reference,
            build: self.build.apply(BuildOptions::default()),
            json: self.json,
            quiet: self.quiet,
        })
    }
}

pub(super) fn run(a: SweepArgs) -> anyhow::Result<ExitCode> {
    execute(&a.validate()?)
}

/// The progress bar of a run (hidden with `--quiet` or `--json`).
fn progress_bar(cfg: &SweepConfig) -> ProgressBar {
    let pb = ProgressBar::new(0).with_style(
        ProgressStyle::with_template("{wide_msg} [{bar:30}] {pos}/{len} {elapsed} eta {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    if cfg.quiet || cfg.json {
        pb.set_draw_target(ProgressDrawTarget::hidden());
    } else {
        pb.enable_steady_tick(Duration::from_millis(200));
    }
    pb
}

/// Most pairs of frames that see almost the same view named one by one; more are counted.
const MAX_REPEAT_NOTES: usize = 5;

/// Notes on stderr of frames that see almost the same view (each counts in every mean). A path of one
/// time (`still`: a single keyframe) has one view: one note, not one per pair of frames, and no hint that
/// more frames would see more; a static path of several keyframes lists at most [`MAX_REPEAT_NOTES`]
/// pairs (fault hunt and review, session 36).
fn note_repeated_views(cameras: &[(f64, atlastree::camera::Camera)], still: bool) {
    if still {
        if cameras.len() > 1 {
            eprintln!(
                "note: the path has one view (all its keyframes at one time): its {} frames all measure \
                 that view; give the path keyframes at other times to measure more",
                cameras.len()
            );
        }
        return;
    }
    let pairs = atlastree::sweep::repeated_views(cameras);
    for &(i, j) in pairs.iter().take(MAX_REPEAT_NOTES) {
        eprintln!(
            "note: frames {i} and {j} (path times {:.1} s and {:.1} s) see almost the same view, which \
             counts twice in every mean{}",
            cameras[i].0,
            cameras[j].0,
            if cameras.len() == 2 {
                " and is the only view measured: more --frames measure the path's other views"
            } else {
                ""
            }
        );
    }
    if pairs.len() > MAX_REPEAT_NOTES {
        eprintln!(
            "note: … and {} more pairs of frames that see almost the same view",
            pairs.len() - MAX_REPEAT_NOTES
        );
    }
}

/// Runs a checked configuration: import, sample the path, build and measure, write and report.
pub(super) fn execute(cfg: &SweepConfig) -> anyhow::Result<ExitCode> {
    let mut out = super::OutFolder::open(&cfg.out)?;
    out.make(&builds_dir(cfg))?;
    out.run(|| execute_in(cfg))
}

/// Where the sweep's builds go while they are measured.
fn builds_dir(cfg: &SweepConfig) -> std::path::PathBuf {
    cfg.out.join("builds")
}

/// [`execute`] while `--out` is held.
fn execute_in(cfg: &SweepConfig) -> anyhow::Result<ExitCode> {
    let plan = &cfg.plan;
    // A budget below what any of the grid's builds needs, refused before the scene is read, as `build`
    // does (review, session 38).
    let largest_atlas = plan.builds.iter().map(|b| b.knobs.atlas_size).max();
    if let (Some(budget), Some(atlas)) = (cfg.build.max_memory_bytes, largest_atlas) {
        let threads = rayon::current_num_threads() as u64;
        atlastree::preprocess::memory::check_pixel_floor(budget, atlas, threads)?;
    }
    let scene = load_scene(&cfg.scene, cfg.up)?;
    let path = cfg.path.resolve_with(|| Ground::from_scene(&scene))?;
    let aspect = f64::from(plan.width) / f64::from(plan.height);
    let cameras = sample_path(&path, plan.frames, aspect);
    note_repeated_views(&cameras, path.duration() == 0.0);

    let ctx = GpuContext::new_headless(&GpuOptions::default())?;
    // Before any build: the supersampled frame must fit the device.
    if let Reference::Supersampled(k) = cfg.reference {
        atlastree::render::reference::check_supersample(&ctx, plan.width, plan.height, k)?;
    }
    if !cfg.json {
        println!(
            "adapter: {}\nsweep: {} builds, {} variants, {} frames of {}×{}",
            ctx.adapter_summary(),
            plan.builds.len(),
            plan.variants(),
            plan.frames,
            plan.width,
            plan.height
        );
    }
    let opts = SweepOptions {
        builds_dir: builds_dir(cfg),
        keep_builds: cfg.keep_builds,
        anisotropy: cfg.anisotropy,
        reference: cfg.reference,
        build: cfg.build.clone(),
        ..SweepOptions::default()
    };
    let t = std::time::Instant::now();
    let data = run_sweep(&ctx, &scene, plan, &cameras, &opts, &Bar(progress_bar(cfg)))?;
    // An earlier grid's builds that this one did not make (kept with --keep-builds) would sit beside
    // this run's report as if they were its own.
    let planned: std::collections::HashSet<String> = (plan.builds.iter())
        .map(|b| format!("{}.atlastree", b.knobs.id()))
        .collect();
    let stale = |n: &str| n.ends_with(".atlastree") && !planned.contains(n);
    // Only where an earlier sweep reported into this folder (its sweep.csv, written after its builds).
    let marker = cfg.out.join("sweep.csv");
    let removed = atlastree::util::remove_earlier_outputs(&opts.builds_dir, &marker, stale)
        .with_context(|| {
            format!(
                "removing an earlier run's builds from {}",
                opts.builds_dir.display()
            )
        })?;
    if removed > 0 {
        eprintln!(
            "note: removed {removed} build(s) of an earlier run from {}",
            opts.builds_dir.display()
        );
    }
    if !cfg.keep_builds {
        let _ = std::fs::remove_dir(&opts.builds_dir);
    }
    let (rows, written) = write_outputs(
        &cfg.out,
        &data,
        &cfg.scene.display().to_string(),
        &cfg.path.to_string(),
    )?;
    // A path that never looks at the scene covers no pixel: covered PSNR is NaN (`null` in the JSON, an
    // empty cell in the CSVs, `-` here). The report says so too, and the JSON has `"measured": false` and
    // no recommendation.
    let measured = !data.measures_nothing();
    if !measured {
        eprintln!("warning: {MEASURED_NOTHING}");
    }
    if let Some(note) = empty_frames_note(&data) {
        eprintln!("warning: {note}");
    }
    let rec = recommendation(&data, &rows);
    if cfg.json {
        let out = serde_json::json!({
            "measured": measured,
            "variants": rows,
            "builds": data.builds,
            "recommendation": rec,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!("done in {:.1} s", t.elapsed().as_secs_f64());
    println!("reference: {}", cfg.reference.name());
    // NaN (nothing measured) as `-`, not "NaN dB".
    let db = |v: f64| match v.is_finite() {
        true => format!("{v:>6.2}"),
        false => format!("{:>6}", "-"),
    };
    for r in &rows {
        let original = match cfg.reference {
            Reference::Original => String::new(),
            Reference::Supersampled(_) => format!(
                "  original: covered PSNR {} dB  SSIM {:.4}",
                db(r.original_psnr_covered_db),
                r.original_ssim
            ),
        };
        println!(
            "  {:<32} covered PSNR {} dB  SSIM {:.4}  frame {:>7.2} ms  file {}{original}",
            r.id,
            db(r.psnr_covered_db),
            r.ssim,
            r.frame_ms_median,
            atlastree::util::human_bytes(r.file_bytes)
        );
    }
    if let Some(rec) = rec {
        println!(
            "recommended (fastest frames within {} dB of the best {:.2} dB; times within {:.0} % of the \
             least count as equal): {}",
            rec.tolerance_db,
            rows[rec.best].psnr_covered_db,
            atlastree::sweep::summary::TIME_TIE_SHARE * 100.0,
            rows[rec.fastest_frames].id
        );
    }
    for w in written {
        println!("wrote {}", w.display());
    }
    Ok(ExitCode::SUCCESS)
}
