//! The sweep runner: build each build-time variant once, render each runtime variant over the same frames,
//! measure every frame against the reference. Plain rows out; no files but the builds.

use super::SweepError;
use super::grid::{BuildKnobs, Plan, PlannedBuild, RuntimeKnobs, variant_id};
use crate::camera::{Camera, CameraPath};
use crate::gpu::{GpuContext, GpuError};
use crate::paging::{FileSource, PagerOptions};
use crate::plan::{FramePlanner, PagingSetup};
use crate::preprocess::{BuildOptions, NoProgress, build};
use crate::render::reference::Reference;
use crate::render::{FrameLoop, FrameStats, Mode, RenderError, Renderer, RendererOptions};
use crate::report::metrics::{Histogram, magnified_share, psnr, psnr_masked, ssim};
use crate::scene::Scene;
use crate::select::{SelectOptions, min_distance_scale};
use crate::store::TreeFile;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Range of the texel-density histograms: bins `[2^e, 2^(e+1))` for `e` in `HIST_MIN_EXP..HIST_MAX_EXP`.
pub(super) const HIST_MIN_EXP: i32 = -4;
pub(super) const HIST_MAX_EXP: i32 = 5;

/// How a sweep runs.
#[derive(Clone, Debug)]
pub struct SweepOptions {
    /// Where the paging files go (created if missing).
    pub builds_dir: PathBuf,
    /// Keep the paging files (else each is deleted once its variants are rendered).
    pub keep_builds: bool,
    /// Untimed frames per renderer before measuring (shader compilation); paged renderers get none, so
    /// paging starts cold from frame 0.
    pub warmup: usize,
    /// Outstanding block requests of paged variants (loads are synchronous: loader threads 0).
    pub max_queue: u32,
    /// GPU timestamp queries (when the device supports them).
    pub gpu_timing: bool,
    /// Sampler anisotropy of every render, the reference included ([`RendererOptions::anisotropy`]).
    pub anisotropy: u16,
    /// What every frame is compared with: the original textures at the frame's resolution (the default),
    /// or the supersampled ground truth ([`Reference::Supersampled`]), against which the original textures
    /// are measured too.
    pub reference: Reference,
    /// The options of every build beside the grid's knobs ([`BuildKnobs`] replace d_min, atlas size,
    /// border, filter, compression and repeat mode).
    pub build: BuildOptions,
}

impl SweepOptions {
    /// The renderer options of every render of `plan` (its frame size, these timing and sampler settings).
    pub fn renderer(&self, plan: &Plan) -> RendererOptions {
        RendererOptions {
            width: plan.width,
            height: plan.height,
            gpu_timing: self.gpu_timing,
            anisotropy: self.anisotropy,
        }
    }
}

impl Default for SweepOptions {
    fn default() -> Self {
        SweepOptions {
            builds_dir: PathBuf::from("builds"),
            keep_builds: false,
            warmup: 1,
            max_queue: 8,
            gpu_timing: true,
            anisotropy: RendererOptions::ANISOTROPY,
            reference: Reference::Original,
            build: BuildOptions::default(),
        }
    }
}

/// Receives the sweep's progress (the CLI draws an indicatif bar with ETA).
pub trait SweepProgress {
    /// Total work units: a build counts as `frames` units, each rendered frame (reference included) one.
    fn begin(&self, total: u64);
    /// What is being done now.
    fn message(&self, msg: &str);
    fn advance(&self, units: u64);
    fn finish(&self);
}

/// Progress sink that ignores everything.
pub struct NoSweepProgress;
impl SweepProgress for NoSweepProgress {
    fn begin(&self, _: u64) {}
    fn message(&self, _: &str) {}
    fn advance(&self, _: u64) {}
    fn finish(&self) {}
}

/// One build of the sweep with its cost.
#[derive(Clone, Debug, Serialize)]
pub struct BuildRow {
    pub knobs: BuildKnobs,
    pub file_bytes: u64,
    pub nodes: u64,
    pub leaves: u64,
    pub depth: u8,
    pub blocks: u64,
    /// Seconds per stage (`sizing Opaque`, `layout Opaque`, `assemble Opaque`, …, `rasterise`, `write`),
    /// as [`crate::preprocess::BuildReport::timings`] without `total`.
    pub stage_s: Vec<(String, f64)>,
    /// Wall time of the whole build, seconds.
    pub build_s: f64,
    /// Peak resident memory during the build, bytes: the largest of its stages' peaks
    /// ([`crate::memory_window::MemoryWindow`]); `None` where the platform does not tell.
    pub peak_rss_bytes: Option<u64>,
}

/// One variant on one frame.
#[derive(Clone, Debug)]
pub struct FrameRow {
    pub build: BuildKnobs,
    pub runtime: RuntimeKnobs,
    pub frame: usize,
    /// Seconds along the camera path.
    pub time_s: f64,
    /// PSNR against the reference over the whole frame, dB (99 = identical).
    pub psnr_db: f64,
    /// PSNR over the covered pixels (drawn on the reference's density pass), dB.
    pub psnr_covered_db: f64,
    pub covered_pixels: u64,
    /// SSIM of the luma (Gaussian 11×11 window), 1 = identical.
    pub ssim: f64,
    /// The build's original textures (drawn naively at the frame's resolution) against the supersampled
    /// reference: PSNR, covered PSNR, SSIM; NaN when the reference is the original textures themselves.
    pub original_psnr_db: f64,
    pub original_psnr_covered_db: f64,
    pub original_ssim: f64,
    /// Share of drawn pixels with fewer than 1 texel per pixel along the least-sampled direction (paged
    /// variants too: the density pass executes the frame's plan again without stepping the pager).
    pub magnified_share: f64,
    /// Share of drawn pixels with fewer texels per pixel than the variant's texel ratio.
    pub below_target_share: f64,
    /// What the frame's plan and the renderer counted (the paging counters in `stats.plan.paging` when
    /// the variant is paged), written through [`crate::report::columns`].
    pub stats: FrameStats,
}

impl FrameRow {
    pub fn variant_id(&self) -> String {
        variant_id(&self.build, &self.runtime)
    }
}

/// Everything a sweep measured.
#[derive(Clone, Debug)]
pub struct SweepData {
    pub plan: Plan,
    pub builds: Vec<BuildRow>,
    /// Per variant (in plan order) and frame.
    pub frames: Vec<FrameRow>,
    /// Texel-density histogram (least-sampled direction) per non-paged variant, over all its frames, with
    /// the variant's build and runtime knobs.
    pub histograms: Vec<(BuildKnobs, RuntimeKnobs, Histogram)>,
    /// Bytes of textures uploaded by the non-paged renderer of each build (everything resident).
    pub resident_bytes: Vec<u64>,
    pub adapter: String,
    /// Sampler anisotropy of every render, as the device applies it (1 without anisotropic filtering).
    pub anisotropy: u16,
    /// What the frames were compared with.
    pub reference: Reference,
    /// The adapter is a software rasteriser (timings are CPU timings; see the report's note).
    pub software: bool,
    /// Builds whose variants could not be rendered with every block resident (the device ran out of
    /// memory or texture-array layers), with the error: built and measured as builds, not as variants
    /// (their `resident_bytes` entry is 0).
    /// The base build is never skipped (the reference needs it): its failure ends the sweep.
    pub skipped: Vec<(String, String)>,
}

impl SweepData {
    /// No frame covers a pixel of the scene (a path that never looks at it): every PSNR and SSIM is the
    /// value of an empty comparison (99 dB, 1; covered PSNR NaN), so neither they nor a recommendation
    /// measure anything.
    pub fn measures_nothing(&self) -> bool {
        !self.frames.is_empty() && self.frames.iter().all(|f| f.covered_pixels == 0)
    }

    /// The frames (by index) whose reference covers no pixel of the scene, left out of covered PSNR:
    /// the same for every variant, as the reference is.
    pub fn empty_frames(&self) -> Vec<usize> {
        let mut empty: Vec<usize> = (self.frames.iter())
            .filter(|f| f.covered_pixels == 0)
            .map(|f| f.frame)
            .collect();
        empty.sort_unstable();
        empty.dedup();
        empty
    }
}

/// The reference of one frame (the original-texture render, or the supersampled one) and the covered
/// pixels.
struct RefFrame {
    rgba: Vec<u8>,
    covered: Vec<bool>,
}

/// The original textures' own accuracy on one frame against a supersampled reference: (PSNR dB, covered
/// PSNR dB, SSIM).
type OriginalQuality = (f64, f64, f64);

/// `count` cameras spread evenly over the whole path (first and last keyframe included when
/// `count ≥ 2`; the middle when 1), with the given aspect, and their path times.
pub fn sample_path(path: &CameraPath, count: usize, aspect: f64) -> Vec<(f64, Camera)> {
    let (start, dur) = (path.start(), path.duration());
    (0..count)
        .map(|i| {
            let f = if count <= 1 {
                0.5
            } else {
                i as f64 / (count - 1) as f64
            };
            let t = start + dur * f;
            let mut c = path.sample(t);
            c.aspect = aspect;
            (t, c)
        })
        .collect()
}

/// Most frames [`repeated_views`] compares (all pairs: ~32,000 at this count).
const REPEAT_CHECK_MAX: usize = 256;

/// Pairs `(i, j)`, `i < j`, of `cameras` that see almost the same view: eyes and targets within 5 % of
/// the eye–target distance, the same field of view. A closed path's first and last keyframe are such a
/// pair (the overview-dive starts and ends at the overview): with `--frames 2` every variant measured one
/// view twice, and a knob seemed to change nothing. A repeat weighs in a small sample only: past
/// [`REPEAT_CHECK_MAX`] frames none is looked for (the pairs grow with the square of the count, and a
/// sweep may take 100,000 frames).
pub fn repeated_views(cameras: &[(f64, Camera)]) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    if cameras.len() > REPEAT_CHECK_MAX {
        return out;
    }
    for (i, (_, a)) in cameras.iter().enumerate() {
        for (j, (_, b)) in cameras.iter().enumerate().skip(i + 1) {
            let reach = 0.05 * (a.target - a.eye).length();
            if (a.eye - b.eye).length() <= reach
                && (a.target - b.target).length() <= reach
                && a.fov_x_deg == b.fov_x_deg
            {
                out.push((i, j));
            }
        }
    }
    out
}

/// Runs the whole plan: for each build (base first), build it into `opts.builds_dir`, render its
/// runtime variants on `cameras`, and (base build) render the reference frames first.
pub fn run_sweep(
    ctx: &GpuContext,
    scene: &Scene,
    plan: &Plan,
    cameras: &[(f64, Camera)],
    opts: &SweepOptions,
    progress: &dyn SweepProgress,
) -> Result<SweepData, SweepError> {
    check_capacities(scene, plan)?;
    std::fs::create_dir_all(&opts.builds_dir).map_err(|e| SweepError::Io {
        path: opts.builds_dir.clone(),
        source: e,
    })?;
    let n = cameras.len() as u64;
    let renders: u64 = plan.variants() as u64 * n + n;
    progress.begin(plan.builds.len() as u64 * n + renders);
    let mut data = SweepData {
        plan: plan.clone(),
        builds: Vec::new(),
        frames: Vec::new(),
        histograms: Vec::new(),
        resident_bytes: Vec::new(),
        adapter: ctx.adapter_summary(),
        anisotropy: opts.renderer(plan).device_anisotropy(ctx),
        software: ctx.info.is_software(),
        reference: opts.reference,
        skipped: Vec::new(),
    };
    let mut reference: Vec<RefFrame> = Vec::new();
    for pb in &plan.builds {
        let path = opts.builds_dir.join(format!("{}.atlastree", pb.knobs.id()));
        progress.message(&format!("build {}", pb.knobs.id()));
        data.builds
            .push(build_one(scene, &pb.knobs, &opts.build, &path)?);
        // Deleted once measured; by the Ctrl-C handler if the sweep is interrupted before.
        let _temporary = (!opts.keep_builds).then(|| crate::util::LiveTempFile::register(&path));
        progress.advance(n);
        let file = TreeFile::open(&path).map_err(|source| SweepError::Open {
            path: path.clone(),
            source,
        })?;
        let result = run_build(
            ctx,
            &file,
            pb,
            plan,
            cameras,
            opts,
            progress,
            &mut reference,
            &mut data,
        );
        drop(file);
        if !opts.keep_builds {
            let _ = std::fs::remove_file(&path);
        }
        result?;
    }
    progress.finish();
    Ok(data)
}

/// Refuses, before any build, a capacity below the root atlases every build of `scene` has (one per
/// tree: opaque, and alpha where a material uses alpha), which no paged renderer can run with.
pub fn check_capacities(scene: &Scene, plan: &Plan) -> Result<(), SweepError> {
    // The build's own split into trees, so the two cannot drift apart.
    let roots = crate::preprocess::partition_triangles(scene).len() as u32;
    let caps = plan.builds.iter().flat_map(|b| &b.runtimes);
    match caps.filter_map(|r| r.capacity).min() {
        Some(k) if k < roots => Err(SweepError::Grid {
            origin: "capacity".into(),
            message: format!(
                "capacity {k} is below the {roots} root atlases of every build of this scene (one per \
                 tree): a paged renderer needs at least {roots}"
            ),
        }),
        _ => Ok(()),
    }
}

/// The options of the build of `knobs`: the knobs over `base`.
pub(super) fn build_options(knobs: &BuildKnobs, base: &BuildOptions) -> BuildOptions {
    let k = knobs.options();
    BuildOptions {
        d_min: k.d_min,
        atlas_size: k.atlas_size,
        border: k.border,
        mip_filter: k.mip_filter,
        alpha_mips: k.alpha_mips,
        compress: k.compress,
        repeat: k.repeat,
        ..base.clone()
    }
}

/// Builds one variant, timing it and its peak memory.
fn build_one(
    scene: &Scene,
    knobs: &BuildKnobs,
    base: &BuildOptions,
    out: &Path,
) -> Result<BuildRow, SweepError> {
    let t = std::time::Instant::now();
    let r = build(scene, &build_options(knobs, base), out, &NoProgress).map_err(|source| {
        SweepError::Build {
            build: knobs.id(),
            source: Box::new(source),
        }
    })?;
    let build_s = t.elapsed().as_secs_f64();
    Ok(BuildRow {
        knobs: *knobs,
        file_bytes: r.file_bytes,
        nodes: r.trees.iter().map(|t| t.nodes).sum(),
        leaves: r.trees.iter().map(|t| t.leaves).sum(),
        depth: r.trees.iter().map(|t| t.depth).max().unwrap_or(0),
        blocks: r.blocks,
        stage_s: r
            .stages
            .timings
            .into_iter()
            .filter(|(n, _)| n != "total")
            .collect(),
        build_s,
        peak_rss_bytes: r.stages.peak_rss_bytes,
    })
}

/// `min_distance` scale of `texel_ratio` at the plan's width for `cam`.
fn scale(file: &TreeFile, plan: &Plan, texel_ratio: f64, cam: &Camera) -> Result<f64, SweepError> {
    min_distance_scale(
        &file.to_params(),
        &SelectOptions {
            screen_width: plan.width,
            texel_ratio,
            fov_x_deg: cam.fov_x_deg,
        },
    )
    .map_err(|source| SweepError::Scale {
        variant: format!("texel ratio {texel_ratio}"),
        source,
    })
}

/// Renders the variants of one build (and, for the base build, the reference first).
#[allow(clippy::too_many_arguments)]
fn run_build(
    ctx: &GpuContext,
    file: &TreeFile,
    pb: &PlannedBuild,
    plan: &Plan,
    cameras: &[(f64, Camera)],
    opts: &SweepOptions,
    progress: &dyn SweepProgress,
    reference: &mut Vec<RefFrame>,
    data: &mut SweepData,
) -> Result<(), SweepError> {
    let ropts = opts.renderer(plan);
    let render_err = |variant: String, frame: usize| {
        move |source| SweepError::Render {
            variant,
            frame,
            source: Box::new(source),
        }
    };
    let mut full = match FrameLoop::new(ctx, file, ropts) {
        Ok(r) => r,
        Err(
            e
            @ (RenderError::Gpu(GpuError::OutOfMemory { .. }) | RenderError::TooManyLayers { .. }),
        ) if !pb.is_base => {
            tracing::warn!("sweep: skipping the variants of {}: {e}", pb.knobs.id());
            data.skipped.push((pb.knobs.id(), e.to_string()));
            data.resident_bytes.push(0);
            progress.advance((pb.runtimes.len() * cameras.len()) as u64);
            return Ok(());
        }
        Err(e) => return Err(render_err(pb.knobs.id(), 0)(e)),
    };
    data.resident_bytes
        .push(full.renderer.resident.stats.texture_bytes);
    if pb.is_base {
        progress.message("reference frames (original textures)");
        *reference = reference_frames(
            &mut full.planner,
            &mut full.renderer,
            file,
            plan,
            cameras,
            opts,
            progress,
        )?;
    }
    let originals = match opts.reference {
        Reference::Original => Vec::new(),
        Reference::Supersampled(_) => {
            progress.message("original textures against the supersampled reference");
            original_quality(
                &mut full.planner,
                &mut full.renderer,
                file,
                plan,
                cameras,
                reference,
            )?
        }
    };
    for rt in &pb.runtimes {
        let id = variant_id(&pb.knobs, rt);
        progress.message(&id);
        match rt.capacity {
            None => {
                let mut hist = Histogram::log2(&[], HIST_MIN_EXP, HIST_MAX_EXP);
                let ctx = VariantCtx {
                    file,
                    plan,
                    knobs: (pb.knobs, *rt),
                    id: &id,
                    reference,
                    originals: &originals,
                };
                for k in 0..opts.warmup.min(cameras.len()) {
                    let (_, cam) = &cameras[k * cameras.len() / opts.warmup.max(1)];
                    let s = scale(file, plan, rt.texel_ratio, cam)?;
                    let warm = full
                        .planner
                        .plan_still(cam, s, &mut full.renderer.residency())
                        .map_err(|e| render_err(id.clone(), k)(e.into()))?;
                    full.renderer
                        .execute(warm, Mode::Tree)
                        .map_err(render_err(id.clone(), k))?;
                }
                for (i, (t, cam)) in cameras.iter().enumerate() {
                    let row = ctx.measure(
                        &mut full.planner,
                        &mut full.renderer,
                        i,
                        *t,
                        cam,
                        Some(&mut hist),
                    )?;
                    data.frames.push(row);
                    progress.advance(1);
                }
                data.histograms.push((pb.knobs, *rt, hist));
            }
            Some(k) => {
                let source = Arc::new(FileSource::new(Arc::new(file.reopen().map_err(
                    |source| SweepError::Open {
                        path: file.path().to_path_buf(),
                        source,
                    },
                )?)));
                let setup = PagingSetup {
                    pager: PagerOptions {
                        capacity: k,
                        max_queue: opts.max_queue,
                        ..PagerOptions::default()
                    },
                    source,
                    loader_threads: 0,
                };
                let mut paged = FrameLoop::new_paged(ctx, file, ropts, setup)
                    .map_err(render_err(id.clone(), 0))?;
                let ctx = VariantCtx {
                    file,
                    plan,
                    knobs: (pb.knobs, *rt),
                    id: &id,
                    reference,
                    originals: &originals,
                };
                for (i, (t, cam)) in cameras.iter().enumerate() {
                    let s = scale(file, plan, rt.texel_ratio, cam)?;
                    let settled = settle(&mut paged.planner, &mut paged.renderer, cam, *t, s)
                        .map_err(|e| render_err(id.clone(), i)(e.into()))?;
                    let mut row =
                        ctx.measure(&mut paged.planner, &mut paged.renderer, i, *t, cam, None)?;
                    if let Some(p) = row.stats.plan.paging.as_mut() {
                        p.session.pager.loaded += settled.loaded;
                        p.session.pager.bytes_loaded += settled.bytes;
                    }
                    data.frames.push(row);
                    progress.advance(1);
                }
            }
        }
    }
    Ok(())
}

/// Most paging steps [`settle`] takes at one camera.
const SETTLE_MAX_STEPS: u32 = 4096;

/// What [`settle`] loaded.
#[derive(Clone, Copy, Debug, Default)]
struct Settled {
    loaded: u32,
    bytes: u64,
}

/// Steps a paged planner at `camera` (clock `time`, held) until a step requests, loads and has in flight
/// nothing (at most [`SETTLE_MAX_STEPS`]), so a paged variant is measured at the steady state its
/// capacity k gives this view, not at a cold start: the sweep samples a few frames seconds apart and
/// each frame had one paging step, so k = 100,000 over a 13-block file scored 36.8 dB against the
/// all-resident 99 and its frame time held the synchronous loads (fault hunt, session 32). The loads are
/// returned for the measured frame's `loaded` and `bytes_loaded` (what reaching the view cost); its other
/// paging counters are its own step's.
fn settle(
    planner: &mut FramePlanner<'_>,
    r: &mut Renderer<'_>,
    camera: &Camera,
    time: f64,
    scale: f64,
) -> Result<Settled, crate::plan::PlanError> {
    let mut out = Settled::default();
    for _ in 0..SETTLE_MAX_STEPS {
        let frame = planner.plan(camera, time, scale, &mut r.residency())?;
        let Some(p) = frame.stats.paging.as_ref() else {
            return Ok(out);
        };
        let (pager, session) = (p.pager(), &p.session);
        out.loaded += pager.loaded;
        out.bytes += pager.bytes_loaded;
        if pager.requested == 0
            && pager.loaded == 0
            && pager.staged == 0
            && session.queued == 0
            && session.in_flight == 0
        {
            return Ok(out);
        }
    }
    tracing::warn!(
        "the pager still loaded after {SETTLE_MAX_STEPS} steps at one view (time {time} s): the paged \
         frame is measured as it stands"
    );
    Ok(out)
}

/// The reference of every frame: [`Mode::Original`] (original textures, naive draws) and the pixels the
/// density pass covers, at texel ratio 1 on the base build.
fn reference_frames(
    planner: &mut FramePlanner<'_>,
    r: &mut Renderer<'_>,
    file: &TreeFile,
    plan: &Plan,
    cameras: &[(f64, Camera)],
    opts: &SweepOptions,
    progress: &dyn SweepProgress,
) -> Result<Vec<RefFrame>, SweepError> {
    let err = |frame: usize| {
        move |source| SweepError::Render {
            variant: "reference".into(),
            frame,
            source: Box::new(source),
        }
    };
    if opts.warmup > 0
        && let Some((_, cam)) = cameras.first()
    {
        let warm = planner
            .plan_still(cam, scale(file, plan, 1.0, cam)?, &mut r.residency())
            .map_err(|e| err(0)(e.into()))?;
        r.execute(warm, Mode::Original).map_err(err(0))?;
    }
    let mut out = Vec::with_capacity(cameras.len());
    for (i, (t, cam)) in cameras.iter().enumerate() {
        let s = scale(file, plan, 1.0, cam)?;
        let frame = planner
            .plan(cam, *t, s, &mut r.residency())
            .map_err(|e| err(i)(e.into()))?;
        r.execute(frame, Mode::Original).map_err(err(i))?;
        let rgba = r.read_frame().map_err(err(i))?;
        let (_, density) = r.execute_density(frame).map_err(err(i))?;
        // Covered: where the tree (the base build, alpha-tested) or the original textures draw. The
        // tree's pixels alone left out foliage the reference draws and an atlas cuts away, hiding the
        // alpha coverage lost (review, session 38); the background is exactly the clear colour.
        let sky = crate::render::sky_srgb8();
        let covered = (density.pixels.iter().zip(rgba.chunks_exact(4)))
            .map(|(d, p)| d.is_some() || p[..3] != sky)
            .collect();
        let rgba = match opts.reference {
            Reference::Original => rgba,
            Reference::Supersampled(k) => r.execute_supersampled(frame, k).map_err(err(i))?,
        };
        out.push(RefFrame { rgba, covered });
        progress.advance(1);
    }
    Ok(out)
}

/// The build's original textures against the (supersampled) reference on every frame: the frame planned
/// still (all blocks resident, texel ratio 1), drawn in [`Mode::Original`] at the frame's resolution.
fn original_quality(
    planner: &mut FramePlanner<'_>,
    r: &mut Renderer<'_>,
    file: &TreeFile,
    plan: &Plan,
    cameras: &[(f64, Camera)],
    reference: &[RefFrame],
) -> Result<Vec<OriginalQuality>, SweepError> {
    let (w, h) = (plan.width, plan.height);
    let render_err = |frame: usize| {
        move |source| SweepError::Render {
            variant: "original textures".into(),
            frame,
            source: Box::new(source),
        }
    };
    let metric_err = |frame: usize| {
        move |source| SweepError::Metric {
            variant: "original textures".into(),
            frame,
            source,
        }
    };
    let mut out = Vec::with_capacity(cameras.len());
    for (i, ((_, cam), truth)) in cameras.iter().zip(reference).enumerate() {
        let s = scale(file, plan, 1.0, cam)?;
        let frame = planner
            .plan_still(cam, s, &mut r.residency())
            .map_err(|e| render_err(i)(e.into()))?;
        r.execute(frame, Mode::Original).map_err(render_err(i))?;
        let rgba = r.read_frame().map_err(render_err(i))?;
        let full = psnr(&rgba, &truth.rgba, w, h).map_err(metric_err(i))?;
        let (covered, _) =
            psnr_masked(&rgba, &truth.rgba, w, h, &truth.covered).map_err(metric_err(i))?;
        let ssim = ssim(&rgba, &truth.rgba, w, h).map_err(metric_err(i))?;
        out.push((full, covered, ssim));
    }
    Ok(out)
}

/// What measuring one frame of a variant needs.
struct VariantCtx<'a> {
    file: &'a TreeFile,
    plan: &'a Plan,
    knobs: (BuildKnobs, RuntimeKnobs),
    id: &'a str,
    reference: &'a [RefFrame],
    /// Per frame, the build's original textures against a supersampled reference (empty otherwise).
    originals: &'a [OriginalQuality],
}

impl VariantCtx<'_> {
    /// Plans frame `i` (one paging step when paged), renders it in tree mode, compares it with the
    /// reference, and runs the density pass of the same plan for the magnified shares (and, when `hist` is
    /// given, the histogram).
    fn measure(
        &self,
        planner: &mut FramePlanner<'_>,
        r: &mut Renderer<'_>,
        i: usize,
        time_s: f64,
        cam: &Camera,
        hist: Option<&mut Histogram>,
    ) -> Result<FrameRow, SweepError> {
        let (w, h) = (self.plan.width, self.plan.height);
        let rt = self.knobs.1;
        let render_err = |source| SweepError::Render {
            variant: self.id.to_string(),
            frame: i,
            source: Box::new(source),
        };
        let metric_err = |source| SweepError::Metric {
            variant: self.id.to_string(),
            frame: i,
            source,
        };
        let s = scale(self.file, self.plan, rt.texel_ratio, cam)?;
        let frame = planner
            .plan(cam, time_s, s, &mut r.residency())
            .map_err(|e| render_err(e.into()))?;
        let stats: FrameStats = r.execute(frame, Mode::Tree).map_err(render_err)?;
        let rgba = r.read_frame().map_err(render_err)?;
        let reference = self.reference.get(i).ok_or(SweepError::Grid {
            origin: self.id.to_string(),
            message: format!("no reference frame {i}"),
        })?;
        let full = psnr(&rgba, &reference.rgba, w, h).map_err(metric_err)?;
        let (covered_db, covered) =
            psnr_masked(&rgba, &reference.rgba, w, h, &reference.covered).map_err(metric_err)?;
        let ssim = ssim(&rgba, &reference.rgba, w, h).map_err(metric_err)?;
        let original = self
            .originals
            .get(i)
            .copied()
            .unwrap_or((f64::NAN, f64::NAN, f64::NAN));
        // The density pass executes the same plan: it steps no pager, so paged variants get it too.
        let (_, density) = r.execute_density(frame).map_err(render_err)?;
        let d = density.min_density();
        let magnified = magnified_share(&d, 1.0).fraction();
        let below = magnified_share(&d, rt.texel_ratio).fraction();
        if let Some(hist) = hist {
            merge_histogram(hist, &Histogram::log2(&d, HIST_MIN_EXP, HIST_MAX_EXP));
        }
        Ok(FrameRow {
            build: self.knobs.0,
            runtime: rt,
            frame: i,
            time_s,
            psnr_db: full,
            psnr_covered_db: covered_db,
            covered_pixels: covered as u64,
            ssim,
            original_psnr_db: original.0,
            original_psnr_covered_db: original.1,
            original_ssim: original.2,
            magnified_share: magnified,
            below_target_share: below,
            stats,
        })
    }
}

/// Adds `more`'s counts to `into` (same edges; different edges leave `into` unchanged).
pub fn merge_histogram(into: &mut Histogram, more: &Histogram) {
    if into.edges != more.edges {
        return;
    }
    for (a, b) in into.counts.iter_mut().zip(&more.counts) {
        *a += b;
    }
    into.below += more.below;
    into.above += more.above;
    into.skipped += more.skipped;
}
