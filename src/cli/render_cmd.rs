//! `atlastree render`: flags → [`RenderConfig`] ([`RenderArgs::validate`]) → [`execute`], a run in named
//! phases: open the source, sample the cameras, set up the frame loop, warm up, fly, write and report.

use super::args::{
    Capacity, Paging, PagingArgs, SourceArg, Viewport, ViewportArgs, check_url, is_url,
};
use super::render_out::{
    clear_earlier_run, earlier_modes, mark_earlier_summary, mark_earlier_summary_stale,
    remove_earlier_frames,
};
use anyhow::{Context, bail};
use atlastree::camera::{Camera, Ground, PathKind};
use atlastree::gpu::{GpuContext, GpuOptions};
use atlastree::paging::{BlockSource, FileSource, HttpOptions, HttpSource};
use atlastree::plan::PagingSetup;
use atlastree::render::reference::Reference;
use atlastree::render::{FrameLoop, FrameStats, Mode, RendererOptions};
use atlastree::report::metrics;
use atlastree::store::TreeFile;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;

// Its --help text is the doc comment of `cli::Command::Render` (clap shows the variant's, not this struct's).
#[derive(Args, Debug)]
pub(crate) struct RenderArgs {
    /// The paging file, or an http(s) URL of one (then blocks are paged over HTTP; `--capacity` defaults
    /// to all blocks). A local file's tables are memory-mapped: truncating it while it renders can stop
    /// the run with SIGBUS. The node tables and parameters are copied as the run starts and paged blocks
    /// are read through a handle of their own, checked against their checksums, so in tree modes a file
    /// rewritten in place afterwards costs counted load failures (`--mode original` reads its geometry
    /// tables at its first frame). Publish a new file by renaming it over the old one (as `build` does),
    /// or set ATLASTREE_NO_MMAP=1 to read the file into memory.
    pub file: PathBuf,
    /// Camera path: overview-dive, street, orbit, or a keyframe JSON file: `{"keyframes": [{"time": s,
    /// "eye": [x, y, z], "target": [x, y, z], "fov": degrees}, …], "up": [0, 1, 0], "near": 0.25,
    /// "far": 100000}` (the scene's units; `aspect`, if given, is not used: frames take the viewport's).
    #[arg(long, default_value = "overview-dive")]
    pub path: PathKind,
    /// Output directory (one subdirectory per mode when several modes are given).
    #[arg(long, default_value = "out/render")]
    pub out: PathBuf,
    /// tree (the product), original (naive per-texture draws), dummy (the tree's draws with one texture and a trivial fragment shader), tree-levels (colour
    /// by level). Comma-separated to measure several modes in one run on the same frames.
    #[arg(long, default_value = "tree", value_delimiter = ',')]
    pub mode: Vec<Mode>,
    /// Number of frames.
    #[arg(long, default_value_t = 120)]
    pub frames: usize,
    /// Save every k-th frame as PNG (0: none).
    #[arg(long, default_value_t = 10)]
    pub every: usize,
    /// Path sampling rate, frames per second of path time.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// Unrecorded frames rendered per mode before measuring (shader compilation, first uploads).
    #[arg(long, default_value_t = 3)]
    pub warmup: usize,
    /// Skip GPU timestamp queries.
    #[arg(long)]
    pub no_gpu_timing: bool,
    /// Anisotropy clamp of the samplers, 1 (isotropic trilinear) to 16, in every mode alike; `auto`: 16 on
    /// a GPU, 1 on a software rasteriser (lavapipe's anisotropic filtering with the explicit gradients of
    /// wrapped atlas UVs costs ~100× per pixel). Lower values trade sharpness at grazing angles for time.
    #[arg(long, default_value = "auto", value_parser = parse_anisotropy)]
    pub anisotropy: u16,
    /// Measure every frame of modes tree, dummy and original against a reference (PSNR and SSIM, printed
    /// and in summary.json): `original` (the original textures at the frame's resolution) or
    /// `supersampled[:S]` (the original textures at S × S the pixels, box-filtered in linear light; S = 4
    /// by default): ground truth where the original itself aliases. Needs every block resident.
    #[arg(long)]
    pub reference: Option<Reference>,
    /// Write OUT/selection.json: per frame, the nodes the selection chooses in every tree (node, level,
    /// atlas or original, distance) and what drew each (paged: a resident ancestor's atlas where a block
    /// is missing, with the levels it is coarser), e.g. to compare with the tiles a 3D Tiles viewer shows
    /// for the same camera (`atlastree export 3dtiles`).
    #[arg(long)]
    pub selection: bool,
    #[command(flatten, next_help_heading = "Viewport")]
    pub viewport: ViewportArgs,
    #[command(flatten, next_help_heading = "Paging")]
    pub paging: PagingArgs,
}

/// Where the tree comes from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum TreeSource {
    Local(PathBuf),
    /// An http(s) URL: tables read over HTTP, blocks paged from it.
    Remote(String),
}

impl TreeSource {
    /// The tree as messages name it: the path, or the URL with its password redacted.
    fn shown(&self) -> String {
        match self {
            TreeSource::Local(p) => p.display().to_string(),
            TreeSource::Remote(u) => atlastree::paging::redact_url(u),
        }
    }
}

/// A checked `render` run.
#[derive(Debug, Clone)]
pub(crate) struct RenderConfig {
    pub tree: TreeSource,
    pub path: PathKind,
    pub out: PathBuf,
    pub viewport: Viewport,
    /// Non-empty, no duplicates.
    pub modes: Vec<Mode>,
    /// > 0.
    pub frames: usize,
    pub every: usize,
    /// Finite, > 0.
    pub fps: f64,
    pub warmup: usize,
    pub gpu_timing: bool,
    pub anisotropy: u16,
    /// Frames measured against this reference (never with paging).
    pub reference: Option<Reference>,
    /// Write `OUT/selection.json`.
    pub selection: bool,
    /// `None`: every block uploaded at start.
    pub paging: Option<RenderPaging>,
}

/// Paging of a `render` run.
#[derive(Debug, Clone)]
pub(crate) struct RenderPaging {
    /// `None`: all blocks (`--capacity all`, or a remote file without `--capacity`).
    pub capacity: Option<u32>,
    pub paging: Paging,
}

impl RenderArgs {
    /// Checks the flags and derives the run.
    pub(crate) fn validate(self) -> anyhow::Result<RenderConfig> {
        super::args::check_frames("--frames", self.frames)?;
        if self.warmup > super::args::MAX_FRAMES {
            bail!(
                "--warmup must be at most {} (got {})",
                super::args::MAX_FRAMES,
                self.warmup
            );
        }
        super::args::check_fps("--fps", self.fps)?;
        let mut modes: Vec<Mode> = Vec::new();
        for m in self.mode {
            if modes.contains(&m) {
                bail!("--mode {} is given twice", m.name());
            }
            modes.push(m);
        }
        if modes.is_empty() {
            bail!("--mode needs at least one mode");
        }
        let name = self.file.to_string_lossy();
        let tree = if is_url(&name) {
            check_url(&name)?;
            TreeSource::Remote(super::args::normalised_url(&name))
        } else {
            // Another scheme is named here (a local FILE of that name aside), not "No such file".
            super::reject_url(&self.file, "render")?;
            TreeSource::Local(self.file.clone())
        };
        let paged = self.paging.capacity.is_some() || matches!(tree, TreeSource::Remote(_));
        if !paged && let Some(flag) = self.paging.given_beyond_capacity() {
            bail!(
                "{flag} means nothing without --capacity: every block is uploaded at start (give \
                 --capacity K, or all, to page)"
            );
        }
        if matches!(tree, TreeSource::Remote(_)) && self.paging.source.is_some() {
            bail!(
                "--source means nothing when FILE is a URL: blocks are paged from {}",
                tree.shown()
            );
        }
        let paging = if paged {
            Some(RenderPaging {
                capacity: self.paging.capacity.and_then(Capacity::blocks),
                paging: self.paging.validate()?,
            })
        } else {
            None
        };
        let local = matches!(tree, TreeSource::Local(_))
            && paging
                .as_ref()
                .is_some_and(|p| p.paging.source == SourceArg::File);
        if local && (self.paging.http_timeout.is_some() || self.paging.http_retries.is_some()) {
            bail!(
                "--http-timeout and --http-retries mean nothing without HTTP: give FILE as a URL or \
                 --source URL"
            );
        }
        // Why this run pages: a URL always does (its blocks come over HTTP), a local file with --capacity.
        let why_paged = match &tree {
            TreeSource::Remote(_) => format!(
                "a tree read from {} is always paged over HTTP; render a local copy",
                tree.shown()
            ),
            TreeSource::Local(_) => "not when paging (--capacity)".to_string(),
        };
        if paging.is_some()
            && let Some(r) = self.reference
        {
            bail!(
                "--reference {} draws the original textures and needs every block resident: {why_paged}",
                r.name()
            );
        }
        if let Some(r) = self.reference
            && !modes.iter().any(|&m| measured(m, Some(r)))
        {
            bail!(
                "--reference {} measures modes tree, dummy and original (original only against a \
                 supersampled reference); --mode {} draws none of them",
                r.name(),
                modes.iter().map(|m| m.name()).collect::<Vec<_>>().join(",")
            );
        }
        if paging.is_some() && modes.contains(&Mode::Original) {
            bail!(
                "--mode original draws every original texture naively and needs every block resident: \
                 {why_paged}"
            );
        }
        let viewport = self.viewport.validate()?;
        let window = atlastree::report::metrics::SSIM_WINDOW;
        if let Some(r) = self.reference
            && !atlastree::report::metrics::ssim_fits(viewport.width, viewport.height)
        {
            bail!(
                "--reference {} scores frames by SSIM, which needs at least {window}×{window} pixels (got \
                 {}×{})",
                r.name(),
                viewport.width,
                viewport.height
            );
        }
        Ok(RenderConfig {
            tree,
            path: self.path,
            out: self.out,
            viewport,
            modes,
            frames: self.frames,
            every: self.every,
            fps: self.fps,
            warmup: self.warmup,
            gpu_timing: !self.no_gpu_timing,
            anisotropy: self.anisotropy,
            reference: self.reference,
            selection: self.selection,
            paging,
        })
    }
}

pub(super) fn run(a: RenderArgs) -> anyhow::Result<ExitCode> {
    execute(&a.validate()?)?;
    Ok(ExitCode::SUCCESS)
}

/// What a run measured: per mode, in `--mode` order, every frame's counters.
pub(super) type Measured = Vec<(Mode, Vec<FrameStats>)>;

/// Runs a checked configuration; returns what it measured.
pub(super) fn execute(cfg: &RenderConfig) -> anyhow::Result<Measured> {
    super::OutFolder::open(&cfg.out)?.run(|| execute_in(cfg))
}

/// [`execute`] while `--out` is held.
fn execute_in(cfg: &RenderConfig) -> anyhow::Result<Measured> {
    // Until phase 4 replaces the earlier run's summary, it says it is not this run's: incomplete from
    // here (an interrupt ends the run without a word), and why where this run fails.
    mark_earlier_summary(&cfg.out, None);
    measure(cfg).map_err(|e| mark_earlier_summary_stale(&cfg.out, e))
}

/// [`execute_in`]'s phases, the first error ending the run.
fn measure(cfg: &RenderConfig) -> anyhow::Result<Measured> {
    let http_options = cfg.paging.as_ref().map(|p| p.paging.http_options());
    let (file, http) = open_tree(&cfg.tree, http_options.unwrap_or_default())?;
    let cameras = sample_cameras(cfg, &file)?;
    let ctx = GpuContext::new_headless(&GpuOptions::default())?;
    println!("adapter: {}", ctx.adapter_summary());
    if let Some(Reference::Supersampled(k)) = cfg.reference {
        let (w, h) = (cfg.viewport.width, cfg.viewport.height);
        atlastree::render::reference::check_supersample(&ctx, w, h, k)?;
    }
    let (mut fl, http) = frame_loop(&ctx, &file, cfg, http)?;
    let mut runs = mode_runs(cfg, cameras.len())?;
    warm_up(&mut fl, cfg, &file, &cameras, &runs)?;
    fly(&mut fl, cfg, &file, &cameras, &mut runs)?;
    for w in fl.planner.failure_warnings() {
        eprintln!("warning: during the run, {w} (stats.csv counts them)");
    }
    let http = http.map(|h| h.stats());
    super::render_report::write_and_report(&cfg.out, cfg.reference, &runs, http)?;
    Ok(runs.into_iter().map(|r| (r.mode, r.stats)).collect())
}

/// Phase 1: the tree's tables, from the file or over HTTP (with the HTTP source for its blocks).
fn open_tree(
    tree: &TreeSource,
    http: HttpOptions,
) -> anyhow::Result<(TreeFile, Option<Arc<HttpSource>>)> {
    Ok(match tree {
        TreeSource::Remote(url) => {
            let (tables, source) =
                HttpSource::open(url, http).with_context(|| format!("opening {}", tree.shown()))?;
            (tables, Some(Arc::new(source)))
        }
        // The tables in memory, blocks read through the handle: the renderer's setup reads geometry
        // for a while, and a file truncated then killed it by SIGBUS (fault hunt, session 37).
        TreeSource::Local(path) => (
            TreeFile::open_with(path, atlastree::store::LoadMode::Tables)
                .with_context(|| format!("opening {}", path.display()))?,
            None,
        ),
    })
}

/// Phase 2: one camera per frame, path time `i / fps`, with the viewport's aspect.
fn sample_cameras(cfg: &RenderConfig, file: &TreeFile) -> anyhow::Result<Vec<Camera>> {
    let path = cfg.path.resolve_with(|| Ground::from_tree(file))?;
    Ok(cfg.viewport.cameras(&path, cfg.fps, cfg.frames))
}

/// A paged run's block source, and the same source as HTTP where it is one.
type PagedSource = (Arc<dyn BlockSource>, Option<Arc<HttpSource>>);

/// The block source of a paged run: the HTTP source of a remote tree, else `--source`; with the HTTP
/// source again where it is one (its counters are reported at the end).
fn block_source(
    paging: &Paging,
    file: &TreeFile,
    http: Option<Arc<HttpSource>>,
) -> anyhow::Result<PagedSource> {
    if let Some(h) = http {
        return Ok((h.clone(), Some(h)));
    }
    match &paging.source {
        SourceArg::File => {
            let reopened = file
                .reopen()
                .with_context(|| format!("reopening {}", file.path().display()))?;
            Ok((Arc::new(FileSource::new(Arc::new(reopened))), None))
        }
        SourceArg::Url(url) => {
            let (tables, http) = HttpSource::open(url, paging.http_options())
                .with_context(|| format!("opening {}", atlastree::paging::redact_url(url)))?;
            if tables.header().file_len != file.header().file_len
                || tables.blocks() != file.blocks()
            {
                bail!(
                    "{} is not the same paging file as {} (block tables differ)",
                    atlastree::paging::redact_url(url),
                    file.path().display()
                );
            }
            let http = Arc::new(http);
            Ok((http.clone(), Some(http)))
        }
    }
}

/// Phase 3: the planner and the renderer ([`FrameLoop`]), all blocks resident or paged; prints what
/// became resident. Returns the HTTP source blocks are paged from, if any.
fn frame_loop<'f>(
    ctx: &'f GpuContext,
    file: &'f TreeFile,
    cfg: &RenderConfig,
    http: Option<Arc<HttpSource>>,
) -> anyhow::Result<(FrameLoop<'f>, Option<Arc<HttpSource>>)> {
    let t = std::time::Instant::now();
    let ropts = RendererOptions {
        width: cfg.viewport.width,
        height: cfg.viewport.height,
        gpu_timing: cfg.gpu_timing,
        anisotropy: cfg.anisotropy,
    };
    let what = || format!("setting up the renderer for {}", cfg.tree.shown());
    let mut paged_from = None;
    let fl = match &cfg.paging {
        None => FrameLoop::new(ctx, file, ropts).map_err(|e| {
            let needs_all = cfg.modes.contains(&Mode::Original) || cfg.reference.is_some();
            super::render_out::setup_error(e, needs_all, what())
        })?,
        Some(p) => {
            let (source, from) = block_source(&p.paging, file, http)?;
            paged_from = from;
            let k = p.capacity.unwrap_or(file.blocks().len() as u32);
            println!(
                "paging: k = {k}, source {}, policy {}",
                source.name(),
                p.paging.pager.policy.name()
            );
            let setup = PagingSetup {
                pager: atlastree::paging::PagerOptions {
                    capacity: k,
                    ..p.paging.pager
                },
                source,
                loader_threads: p.paging.loader_threads,
            };
            FrameLoop::new_paged(ctx, file, ropts, setup).with_context(what)?
        }
    };
    print_resident(ctx, &fl, cfg.paging.is_some(), t.elapsed().as_secs_f64());
    Ok((fl, paged_from))
}

/// What the frame loop made resident at start, and how the atlas arrays are stored.
fn print_resident(ctx: &GpuContext, fl: &FrameLoop<'_>, paged: bool, seconds: f64) {
    let s = &fl.renderer.resident.stats;
    let textures = if paged {
        "root atlases uploaded, the rest paged in per frame (stats.csv: resident_bytes_atlases, resident_bytes_originals)".to_string()
    } else {
        format!(
            "{:.1} MiB of textures",
            s.texture_bytes as f64 / (1 << 20) as f64
        )
    };
    println!(
        "resident: {} trees, {} nodes, {} leaves, {} vertices; {} atlas layers in {} array(s), {} original layers in {} class arrays, {textures} ({:.2} s)",
        s.trees,
        s.nodes,
        s.leaves,
        s.vertices,
        s.atlas_layers,
        s.atlas_arrays,
        s.original_layers,
        s.class_arrays,
        seconds
    );
    let formats: Vec<&str> = fl
        .renderer
        .resident
        .atlas_arrays
        .iter()
        .map(|a| a.format.name())
        .collect();
    println!(
        "  atlas array formats: {}; adapter BC support: {}; {} compressed mip chains decoded to RGBA8 on load, {} BC1 chains widened to BC3",
        formats.join(", "),
        ctx.features.texture_compression_bc,
        s.decoded_on_load,
        s.widened_on_load
    );
}

/// Phase 4: one output directory per mode (the output directory itself for a single mode).
fn mode_runs(cfg: &RenderConfig, frames: usize) -> anyhow::Result<Vec<ModeRun>> {
    // `--out` exists: `OutFolder::open` made it and holds it.
    let earlier = earlier_modes(&cfg.out);
    clear_earlier_run(&cfg.out, &earlier, &cfg.modes, cfg.selection)?;
    // Until this run's summary replaces it: a summary that names this run's modes (so a later run
    // still finds its folders) and says it is incomplete. An interrupted run left the earlier run's
    // summary, frame count and all, beside its own frames.
    let running = serde_json::json!({
        "complete": false,
        "modes": cfg.modes.iter().map(|m| (m.name().to_string(), serde_json::Value::Null))
            .collect::<serde_json::Map<_, _>>(),
    });
    let summary = cfg.out.join("summary.json");
    atlastree::util::write_atomic(&summary, (running.to_string() + "\n").as_bytes())
        .with_context(|| format!("writing {}", summary.display()))?;
    let mut runs = Vec::new();
    for &mode in &cfg.modes {
        let dir = if cfg.modes.len() > 1 {
            cfg.out.join(mode.name())
        } else {
            cfg.out.clone()
        };
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        // An earlier run's frames, contact sheet and stats would sit beside this run's as if they were
        // its own (until this run's end, or for good where it is interrupted). Only where a render
        // wrote there (its summary named modes): a folder of the user's `frame_holiday.png` lost it
        // (fault hunt, session 34).
        let removed = remove_earlier_frames(&dir, &earlier, mode, cfg.modes.len() == 1)?;
        if removed > 0 {
            eprintln!(
                "note: removed {removed} frame PNG(s), contact sheet or stats of an earlier run from {}",
                dir.display()
            );
        }
        runs.push(ModeRun {
            mode,
            dir,
            stats: Vec::with_capacity(frames),
            quality: Vec::new(),
            thumbs: Vec::new(),
        });
    }
    Ok(runs)
}

/// Phase 5: every mode drawn on `warmup` frames spread over the path (shader compilation, first
/// uploads) with still plans: they select and resolve but step no pager and move no clock, so a paged
/// run starts from the bootstrap at time 0 whatever the warm-up.
fn warm_up(
    fl: &mut FrameLoop<'_>,
    cfg: &RenderConfig,
    file: &TreeFile,
    cameras: &[Camera],
    runs: &[ModeRun],
) -> anyhow::Result<()> {
    let params = file.to_params();
    for run in runs {
        for k in 0..cfg.warmup {
            if let Some(cam) = cameras.get(k * cameras.len() / cfg.warmup.max(1)) {
                let scale = cfg.viewport.scale(&params, cam.fov_x_deg)?;
                let plan = fl
                    .planner
                    .plan_still(cam, scale, &mut fl.renderer.residency())?;
                fl.renderer.execute(plan, run.mode)?;
            }
        }
    }
    Ok(())
}

/// Phase 6: each frame planned once, at clock `i / fps`, and that one plan drawn in every mode back to
/// back: load changes on the machine hit every mode alike, and the modes draw the same cut and
/// residency. Every `every`-th frame is saved per mode.
fn fly(
    fl: &mut FrameLoop<'_>,
    cfg: &RenderConfig,
    file: &TreeFile,
    cameras: &[Camera],
    runs: &mut [ModeRun],
) -> anyhow::Result<()> {
    let params = file.to_params();
    let mut selections = Vec::new();
    if let Some(Reference::Supersampled(_)) = cfg.reference {
        let formats: Vec<String> = (0..file.trees())
            .filter_map(|i| file.tree(i).map(|t| t.format()))
            .filter(|f| *f != atlastree::texfmt::TexFormat::Rgba8)
            .map(|f| format!("{f:?}"))
            .collect();
        if !formats.is_empty() {
            eprintln!(
                "note: the supersampled reference draws this file's original textures as stored, \
                 block-compressed ({}): it carries their compression error, so it is the truth only up to \
                 that; build with --compress none for a reference without it",
                formats.join(", ")
            );
        }
    }
    // Reference frames of one colour throughout (the sky alone, or a view inside a wall).
    let (mut truths, mut flat_truths) = (0usize, 0usize);
    for (i, cam) in cameras.iter().enumerate() {
        let scale = cfg.viewport.scale(&params, cam.fov_x_deg)?;
        let plan = fl
            .planner
            .plan(cam, i as f64 / cfg.fps, scale, &mut fl.renderer.residency())?;
        if cfg.selection {
            selections.push(selection_json(i, plan));
        }
        let truth = match cfg.reference {
            None => None,
            Some(Reference::Supersampled(k)) => Some(fl.renderer.execute_supersampled(plan, k)?),
            Some(Reference::Original) => {
                fl.renderer.execute(plan, Mode::Original)?;
                Some(fl.renderer.read_frame()?)
            }
        };
        if let Some(t) = &truth {
            truths += 1;
            flat_truths += usize::from(is_one_colour(t));
        }
        for run in runs.iter_mut() {
            let s = fl.renderer.execute(plan, run.mode)?;
            if let Some(truth) = &truth
                && measured(run.mode, cfg.reference)
            {
                let rgba = fl.renderer.read_frame()?;
                let (w, h) = (cfg.viewport.width, cfg.viewport.height);
                run.quality.push((
                    metrics::psnr(&rgba, truth, w, h)?,
                    metrics::ssim(&rgba, truth, w, h)?,
                ));
            }
            run.stats.push(s);
            if cfg.every > 0 && i % cfg.every == 0 {
                run.save_frame(&fl.renderer, &cfg.viewport, i)?;
            }
        }
    }
    if truths > 0 && flat_truths == truths {
        eprintln!(
            "warning: every reference frame of the path is one colour (the sky alone: does the path look \
             at the scene, and is the scene larger than a pixel from it?): PSNR 99 dB and SSIM 1 measure \
             nothing here"
        );
    }
    if cfg.selection {
        let path = cfg.out.join("selection.json");
        let text = serde_json::to_string_pretty(&serde_json::json!({ "frames": selections }))?;
        atlastree::util::write_atomic(&path, text.as_bytes())
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(())
}

/// Whether every pixel of an RGBA8 frame has the first pixel's colour (the frame shows nothing).
fn is_one_colour(rgba: &[u8]) -> bool {
    let mut px = rgba.chunks_exact(4);
    let first = px.next();
    px.all(|p| Some(p) == first)
}

/// One frame's selection: every tree's cut items as selected (`node`, `source`), and what drew each
/// (`drawn_node`, `drawn_source`, `coarser_levels`): where a paged block is missing, a resident ancestor's
/// atlas, so `--selection` compares both the cuts and what the frames show.
fn selection_json(frame: usize, plan: &atlastree::plan::FramePlan) -> serde_json::Value {
    let name = |original: bool| if original { "original" } else { "atlas" };
    let items: Vec<serde_json::Value> = plan
        .cuts
        .iter()
        .enumerate()
        .flat_map(|(t, cut)| {
            let resolved = plan.resolved(t);
            cut.items.iter().enumerate().map(move |(k, i)| {
                let original = i.source == atlastree::select::Source::Original;
                let drawn = resolved.and_then(|r| r.get(k));
                let (drawn_node, drawn_original, coarser) = match drawn {
                    Some(d) => (
                        d.atlas_node.unwrap_or(i.node).0,
                        d.atlas_node.is_none(),
                        d.coarser_levels,
                    ),
                    None => (i.node.0, original, 0),
                };
                serde_json::json!({
                    "tree": t, "node": i.node.0, "level": i.level, "distance": i.distance,
                    "source": name(original),
                    "drawn_node": drawn_node, "drawn_source": name(drawn_original),
                    "coarser_levels": coarser,
                })
            })
        })
        .collect();
    // The camera as drawn, with the orthonormal frame the view matrix uses (`up` replaced where it is
    // parallel to the view direction), so another viewer can place the same camera.
    let cam = &plan.camera;
    let basis = cam.basis();
    serde_json::json!({
        "frame": frame, "scale": plan.scale, "items": items,
        "camera": {
            "eye": cam.eye.to_array(), "target": cam.target.to_array(), "up": basis.up.to_array(),
            "forward": basis.forward.to_array(), "fov_x_deg": cam.fov_x_deg, "aspect": cam.aspect,
            "near": cam.near, "far": cam.far,
        },
    })
}

/// Whether frames of `mode` are measured against `reference`: tree, dummy and original (not original
/// against itself), not the flat level colours.
fn measured(mode: Mode, reference: Option<Reference>) -> bool {
    !matches!(
        (mode, reference),
        (_, None) | (Mode::TreeLevels, _) | (Mode::Original, Some(Reference::Original))
    )
}

/// One mode's outputs.
pub(super) struct ModeRun {
    pub(super) mode: Mode,
    pub(super) dir: PathBuf,
    pub(super) stats: Vec<FrameStats>,
    pub(super) thumbs: Vec<image::RgbaImage>,
    /// Per frame (PSNR dB, SSIM) against `--reference`, for the modes measured.
    pub(super) quality: Vec<(f64, f64)>,
}

impl ModeRun {
    /// Writes the last frame as `frame_NNNN.png` and keeps a quarter-size thumbnail for the contact sheet.
    fn save_frame(
        &mut self,
        renderer: &atlastree::render::Renderer<'_>,
        v: &Viewport,
        i: usize,
    ) -> anyhow::Result<()> {
        let rgba = renderer.read_frame()?;
        let img = image::RgbaImage::from_raw(v.width, v.height, rgba)
            .context("frame readback has the wrong size")?;
        let png = self.dir.join(format!("frame_{i:04}.png"));
        atlastree::util::save_png(&png, &img)
            .with_context(|| format!("writing {}", png.display()))?;
        self.thumbs.push(image::imageops::resize(
            &img,
            (v.width / 4).max(1),
            (v.height / 4).max(1),
            image::imageops::FilterType::Triangle,
        ));
        Ok(())
    }
}

/// `auto` ([`RendererOptions::AUTO`]) or 1..=16.
pub(super) fn parse_anisotropy(s: &str) -> Result<u16, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(RendererOptions::AUTO);
    }
    match s.parse::<u16>() {
        Ok(v) if (1..=16).contains(&v) => Ok(v),
        _ => Err(format!("{s:?}: expected auto or an integer from 1 to 16")),
    }
}

#[cfg(test)]
mod tests {
    use super::RenderArgs;
    use clap::Parser;

    /// A frame of the clear colour alone is one colour (the warning's case); one pixel drawn, or an empty
    /// frame's single pixel, decides it.
    #[test]
    fn a_frame_of_one_colour_is_told_from_one_with_a_pixel_drawn() {
        use super::is_one_colour;
        let mut frame = [40u8, 90, 200, 255].repeat(64);
        assert!(is_one_colour(&frame));
        frame[4 * 37 + 1] = 91;
        assert!(!is_one_colour(&frame));
        assert!(is_one_colour(&[1, 2, 3, 4]));
    }

    #[derive(Parser)]
    struct Render {
        #[command(flatten)]
        args: RenderArgs,
    }

    fn refusal(argv: &[&str]) -> String {
        let args = Render::parse_from([&["render"], argv].concat()).args;
        match args.validate() {
            Ok(_) => panic!("{argv:?} accepted"),
            Err(e) => e.to_string(),
        }
    }

    /// A reference or original mode needs every block resident; the refusal says why this run pages.
    #[test]
    fn a_paged_reference_is_refused_saying_why_the_run_pages() {
        let url = "http://127.0.0.1:9/city.atlastree";
        let e = refusal(&[url, "--reference", "original"]);
        assert!(
            e.contains(&format!("a tree read from {url} is always paged")),
            "{e}"
        );
        let e = refusal(&[
            "city.atlastree",
            "--capacity",
            "8",
            "--mode",
            "tree,original",
        ]);
        assert!(e.ends_with("not when paging (--capacity)"), "{e}");
        // A reference no chosen mode is measured against (it was rendered for nothing).
        let e = refusal(&[
            "city.atlastree",
            "--mode",
            "tree-levels",
            "--reference",
            "supersampled:2",
        ]);
        assert!(e.contains("draws none of them"), "{e}");
    }
}
