use anyhow::{Context, bail};
use atlastree::camera::{Camera, Ground, PathKind};
use atlastree::gpu::{GpuContext, GpuOptions};
use atlastree::paging::{BlockSource, FileSource, HttpOptions, HttpSource, PagerOptions};
use atlastree::plan::{FramePlanner, PagingFrame, PagingSetup};
use atlastree::render::{FrameStats, Mode, Renderer, RendererOptions};
use atlastree::select::{SelectOptions, min_distance_scale};
use atlastree::store::TreeFile;
use atlastree::sweep::summary::median;
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::sync::Arc;

/// Render a camera path through a paging file offscreen and measure every frame. Writes PNG frames (every
/// k-th), a contact sheet and `stats.csv` per mode.
///
/// Without `--capacity` every block is uploaded at start. With `--capacity k` blocks are paged (paper §6):
/// at most k blocks resident, loaded by priority from `--source`, missing ones drawn with the nearest
/// resident ancestor atlas; `stats.csv` then gains the paging columns (blocks needed / ideal / resident /
/// queued / in flight, bytes loaded, ideal fraction resident, coarser screen share, evictions).
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// The paging file, or an http(s) URL of one (then blocks are paged over HTTP; `--capacity` defaults
    /// to all blocks).
    pub file: PathBuf,
    /// Camera path: overview-dive, street, orbit, or a keyframe JSON file.
    #[arg(long, default_value = "overview-dive")]
    pub path: String,
    /// Output directory (one subdirectory per mode when several modes are given).
    #[arg(long, default_value = "out/render")]
    pub out: PathBuf,
    #[arg(long, default_value_t = 800)]
    pub width: u32,
    #[arg(long, default_value_t = 600)]
    pub height: u32,
    /// tree (the product), original (naive per-texture draws), dummy (one 1×1 texture), tree-levels (colour
    /// by level). Comma-separated to measure several modes in one run on the same frames.
    #[arg(long, default_value = "tree", value_delimiter = ',')]
    pub mode: Vec<Mode>,
    /// Texels per pixel required (min_distance scales linearly with it and with the width).
    #[arg(long, default_value_t = 1.0)]
    pub texel_ratio: f64,
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
    /// Page blocks with at most this many resident (the paper used 160). Omit to load everything.
    #[arg(long)]
    pub capacity: Option<u32>,
    /// Where blocks come from when paging: `file` (the paging file, memory-mapped) or an http(s) URL of
    /// the same file on any static server that supports range requests (see `atlastree serve`).
    #[arg(long, default_value = "file")]
    pub source: String,
    /// Upload budget per frame when paging: `unlimited`, bytes (`8MB`, `512KiB`) or time (`2ms`).
    #[arg(long, default_value = "unlimited")]
    pub upload_budget: atlastree::paging::UploadBudget,
    /// Maximum outstanding block requests when paging.
    #[arg(long, default_value_t = 8)]
    pub max_queue: u32,
    /// Paging policy: paper (§6), distance, lru, ours (paper + hysteresis + lookahead).
    #[arg(long, default_value = "paper")]
    pub policy: atlastree::paging::Policy,
    /// Loader threads when paging; 0 loads synchronously within the frame (deterministic).
    #[arg(long, default_value_t = 2)]
    pub loader_threads: usize,
}

/// The block source named by `--source`.
fn block_source(source: &str, file: &TreeFile) -> anyhow::Result<Arc<dyn BlockSource>> {
    if source == "file" {
        let reopened = TreeFile::open(file.path())
            .with_context(|| format!("reopening {}", file.path().display()))?;
        return Ok(Arc::new(FileSource::new(Arc::new(reopened))));
    }
    if is_url(source) {
        let (tables, http) = HttpSource::open(source, HttpOptions::default())
            .with_context(|| format!("opening {source}"))?;
        if tables.header().file_len != file.header().file_len || tables.blocks() != file.blocks() {
            bail!(
                "{source} is not the same paging file as {} (block tables differ)",
                file.path().display()
            );
        }
        return Ok(Arc::new(http));
    }
    bail!("unknown --source {source:?}: expected `file` or an http:// URL")
}

fn is_url(s: &str) -> bool {
    s.starts_with("http://") || s.starts_with("https://")
}

/// Mean and max of a column.
fn mean_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut n, mut sum, mut max) = (0usize, 0.0, f64::NEG_INFINITY);
    for v in values {
        n += 1;
        sum += v;
        max = max.max(v);
    }
    if n == 0 {
        (0.0, 0.0)
    } else {
        (sum / n as f64, max)
    }
}

pub fn run(a: RenderArgs) -> anyhow::Result<ExitCode> {
    if a.frames == 0 || !(a.fps.is_finite() && a.fps > 0.0) {
        bail!("--frames must be > 0 and --fps finite and > 0");
    }
    let name = a.file.to_string_lossy().to_string();
    let remote = is_url(&name);
    let (file, http) = if remote {
        let (tables, source) = HttpSource::open(&name, HttpOptions::default())
            .with_context(|| format!("opening {name}"))?;
        (tables, Some(Arc::new(source)))
    } else {
        let f = TreeFile::open(&a.file).with_context(|| format!("opening {}", a.file.display()))?;
        (f, None)
    };
    let capacity = match (a.capacity, remote) {
        (Some(k), _) => Some(k),
        (None, true) => Some(file.blocks().len() as u32),
        (None, false) => None,
    };
    let params = file.to_params();
    let kind: PathKind = a.path.parse()?;
    let path = kind.resolve_with(|| Ground::from_tree(&file))?;
    let aspect = f64::from(a.width) / f64::from(a.height.max(1));
    let cameras: Vec<Camera> = path
        .frames(a.fps, a.frames)
        .map(|mut c| {
            c.aspect = aspect;
            c
        })
        .collect();

    let ctx = GpuContext::new_headless(&GpuOptions::default())?;
    println!("adapter: {}", ctx.adapter_summary());
    let t = std::time::Instant::now();
    let ropts = RendererOptions {
        width: a.width,
        height: a.height,
        gpu_timing: !a.no_gpu_timing,
        anisotropy: a.anisotropy,
    };
    let (mut planner, mut renderer) = match capacity {
        None => (
            FramePlanner::from_file(&file),
            Renderer::new(&ctx, &file, ropts)?,
        ),
        Some(k) => {
            let source: Arc<dyn BlockSource> = match &http {
                Some(h) => h.clone(),
                None => block_source(&a.source, &file)?,
            };
            println!(
                "paging: k = {k}, source {}, policy {}",
                source.name(),
                a.policy.name()
            );
            let mut planner = FramePlanner::paged_from_file(
                &file,
                PagingSetup {
                    pager: PagerOptions {
                        capacity: k,
                        max_queue: a.max_queue,
                        budget: a.upload_budget,
                        policy: a.policy,
                        ..PagerOptions::default()
                    },
                    source,
                    loader_threads: a.loader_threads,
                },
            )?;
            let renderer = Renderer::new_paged(&ctx, &file, ropts, &mut planner)?;
            (planner, renderer)
        }
    };
    let s = &renderer.resident.stats;
    println!(
        "resident: {} trees, {} nodes, {} leaves, {} vertices; {} atlas layers in {} array(s), {} original layers in {} class arrays, {:.1} MiB of textures ({:.2} s)",
        s.trees,
        s.nodes,
        s.leaves,
        s.vertices,
        s.atlas_layers,
        s.atlas_arrays,
        s.original_layers,
        s.class_arrays,
        s.texture_bytes as f64 / (1 << 20) as f64,
        t.elapsed().as_secs_f64()
    );
    let formats: Vec<&str> = renderer
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
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut runs = Vec::new();
    for &mode in &a.mode {
        let dir = if a.mode.len() > 1 {
            a.out.join(mode.name())
        } else {
            a.out.clone()
        };
        std::fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))?;
        runs.push(ModeRun {
            mode,
            dir,
            stats: Vec::with_capacity(cameras.len()),
            thumbs: Vec::new(),
        });
    }
    // Warm up every mode on frames spread over the path (shader compilation, first uploads) with still
    // plans: they select and resolve but step no pager and move no clock, so a paged run starts from the
    // bootstrap at time 0 whatever the warm-up. Then each frame is planned once, at i / fps, and that one
    // plan is drawn in every mode back to back: load changes on the machine hit every mode alike, and the
    // modes draw the same cut and residency.
    for run in &runs {
        for k in 0..a.warmup {
            if let Some(cam) = cameras.get(k * cameras.len() / a.warmup.max(1)) {
                let plan = planner.plan_still(
                    cam,
                    scale_of(&a, &params, cam)?,
                    &mut renderer.residency(),
                )?;
                renderer.execute(plan, run.mode)?;
            }
        }
    }
    for (i, cam) in cameras.iter().enumerate() {
        let scale = scale_of(&a, &params, cam)?;
        let plan = planner.plan(cam, i as f64 / a.fps, scale, &mut renderer.residency())?;
        for run in &mut runs {
            let s = renderer.execute(plan, run.mode)?;
            run.stats.push(s);
            if a.every > 0 && i % a.every == 0 {
                run.save_frame(&renderer, &a, i)?;
            }
        }
    }
    if let Some(e) = planner.last_error() {
        eprintln!(
            "warning: residency changes failed during the run (drawn coarser, counted in stats.csv apply_errors); last: {e}"
        );
    }
    let mut medians = Vec::new();
    for run in &runs {
        write_csv(&run.dir.join("stats.csv"), &run.stats)?;
        if !run.thumbs.is_empty() {
            contact_sheet(&run.thumbs)
                .save(run.dir.join("contact_sheet.png"))
                .context("writing the contact sheet")?;
        }
        let frame = median(run.stats.iter().map(|s| s.frame_ms));
        medians.push((run.mode, frame));
        print_summary(run.mode, &run.stats, &run.dir);
    }
    let median_of = |m: Mode| medians.iter().find(|(k, _)| *k == m).map(|(_, v)| *v);
    if let (Some(t), Some(d)) = (median_of(Mode::Tree), median_of(Mode::Dummy)) {
        println!("median frame time tree / dummy: {:.3}", t / d);
    }
    if let (Some(t), Some(o)) = (median_of(Mode::Tree), median_of(Mode::Original)) {
        println!("median frame time original / tree: {:.3}", o / t);
    }
    Ok(ExitCode::SUCCESS)
}

/// One mode's outputs.
struct ModeRun {
    mode: Mode,
    dir: PathBuf,
    stats: Vec<FrameStats>,
    thumbs: Vec<image::RgbaImage>,
}

impl ModeRun {
    /// Writes the last frame as `frame_NNNN.png` and keeps a quarter-size thumbnail for the contact sheet.
    fn save_frame(
        &mut self,
        renderer: &Renderer<'_>,
        a: &RenderArgs,
        i: usize,
    ) -> anyhow::Result<()> {
        let rgba = renderer.read_frame()?;
        let img = image::RgbaImage::from_raw(a.width, a.height, rgba)
            .context("frame readback has the wrong size")?;
        let png = self.dir.join(format!("frame_{i:04}.png"));
        img.save(&png)
            .with_context(|| format!("writing {}", png.display()))?;
        self.thumbs.push(image::imageops::resize(
            &img,
            (a.width / 4).max(1),
            (a.height / 4).max(1),
            image::imageops::FilterType::Triangle,
        ));
        Ok(())
    }
}

/// `min_distance` scale for the run-time width, texel ratio and the camera's field of view.
fn scale_of(
    a: &RenderArgs,
    params: &atlastree::model::BuildParams,
    cam: &Camera,
) -> anyhow::Result<f64> {
    Ok(min_distance_scale(
        params,
        &SelectOptions {
            screen_width: a.width,
            texel_ratio: a.texel_ratio,
            fov_x_deg: cam.fov_x_deg,
        },
    )?)
}

fn contact_sheet(thumbs: &[image::RgbaImage]) -> image::RgbaImage {
    let cols = (thumbs.len() as f64).sqrt().ceil().max(1.0) as u32;
    let rows = (thumbs.len() as u32).div_ceil(cols);
    let (tw, th) = thumbs.first().map_or((1, 1), |t| t.dimensions());
    let mut sheet = image::RgbaImage::from_pixel(cols * tw, rows * th, image::Rgba([0, 0, 0, 255]));
    for (i, t) in thumbs.iter().enumerate() {
        let (x, y) = ((i as u32 % cols) * tw, (i as u32 / cols) * th);
        image::imageops::replace(&mut sheet, t, i64::from(x), i64::from(y));
    }
    sheet
}

fn write_csv(path: &Path, stats: &[FrameStats]) -> anyhow::Result<()> {
    let mut f = std::io::BufWriter::new(
        std::fs::File::create(path).with_context(|| format!("creating {}", path.display()))?,
    );
    let paged = stats.iter().any(|s| s.paging.is_some());
    write!(
        f,
        "frame,nodes_visited,nodes_drawn,indirect_records,draw_calls,bind_group_changes,triangles,skipped_draws,select_us,encode_us,gpu_ms,frame_ms"
    )?;
    if paged {
        write!(f, ",{PAGING_HEADER}")?;
    }
    writeln!(f)?;
    for (i, s) in stats.iter().enumerate() {
        write!(
            f,
            "{i},{},{},{},{},{},{},{},{:.1},{:.1},{},{:.3}",
            s.nodes_visited,
            s.nodes_drawn,
            s.indirect_records,
            s.draw_calls,
            s.bind_group_changes,
            s.triangles,
            s.skipped_draws,
            s.select_us,
            s.encode_us,
            s.gpu_ms.map_or(String::new(), |g| format!("{g:.3}")),
            s.frame_ms
        )?;
        if let Some(p) = &s.paging {
            write!(f, ",{}", paging_row(s, p))?;
        }
        writeln!(f)?;
    }
    f.flush()?;
    Ok(())
}

fn print_summary(mode: Mode, stats: &[FrameStats], dir: &Path) {
    let col = |f: &dyn Fn(&FrameStats) -> f64| mean_max(stats.iter().map(f));
    let rows: [(&str, (f64, f64)); 9] = [
        ("nodes visited", col(&|s| f64::from(s.nodes_visited))),
        ("nodes drawn", col(&|s| f64::from(s.nodes_drawn))),
        ("indirect records", col(&|s| f64::from(s.indirect_records))),
        ("draw calls", col(&|s| f64::from(s.draw_calls))),
        (
            "bind-group changes",
            col(&|s| f64::from(s.bind_group_changes)),
        ),
        ("triangles", col(&|s| s.triangles as f64)),
        ("select µs", col(&|s| s.select_us)),
        ("encode µs", col(&|s| s.encode_us)),
        ("frame ms", col(&|s| s.frame_ms)),
    ];
    println!(
        "mode {} ({} frames, {}):",
        mode.name(),
        stats.len(),
        dir.display()
    );
    for (name, (mean, max)) in rows {
        println!("  {name:<20} mean {mean:>10.2}  max {max:>10.2}");
    }
    let skipped: u64 = stats.iter().map(|s| u64::from(s.skipped_draws)).sum();
    if skipped > 0 {
        println!(
            "  warning: {skipped} draws skipped over the run (their atlas held no GPU layer; see stats.csv skipped_draws)"
        );
    }
    let gpu: Vec<f64> = stats.iter().filter_map(|s| s.gpu_ms).collect();
    if !gpu.is_empty() {
        let (mean, max) = mean_max(gpu.iter().copied());
        println!("  {:<20} mean {mean:>10.2}  max {max:>10.2}", "GPU ms");
    }
    let paged: Vec<&PagingFrame> = stats.iter().filter_map(|s| s.paging.as_ref()).collect();
    if !paged.is_empty() {
        let peak = paged
            .iter()
            .map(|p| p.session.pager.resident)
            .max()
            .unwrap_or(0);
        let bytes: u64 = paged.iter().map(|p| p.session.pager.bytes_loaded).sum();
        let (share, max_share) = mean_max(paged.iter().map(|p| p.coarse.share()));
        let failures: u32 = paged.iter().map(|p| p.session.pager.failures).sum();
        println!(
            "  paging: peak resident {peak}, {} loaded, coarser share mean {:.3} max {:.3}, {} load failures",
            atlastree::util::human_bytes(bytes),
            share,
            max_share,
            failures
        );
    }
    // Medians: robust against one-off stalls (a software rasteriser compiles shader variants on first use).
    let frame: Vec<f64> = stats.iter().map(|s| s.frame_ms).collect();
    println!(
        "  {:<20} median {:>8.2}  GPU median {:>8.2}",
        "frame ms",
        median(frame),
        median(gpu)
    );
}

/// The paging columns of `stats.csv`.
const PAGING_HEADER: &str = "blocks_needed,blocks_culled,blocks_parent_needed,ideal,resident,queued,in_flight,loaded,bytes_loaded,bytes_loaded_originals,resident_bytes_atlases,resident_bytes_originals,ideal_fraction,coarser_share,coarser_items,evictions,cancelled,discarded,failures,upload_ms,atlas_layers_used,original_layers_used,apply_errors,evict_errors,resident_hash";

fn paging_row(f: &FrameStats, p: &PagingFrame) -> String {
    let s = &p.session.pager;
    format!(
        "{},{},{},{},{},{},{},{},{},{},{},{},{:.4},{:.4},{},{},{},{},{},{:.3},{},{},{},{},{:016x}",
        s.usage.needed,
        s.usage.culled,
        s.usage.parent_needed,
        s.ideal,
        s.resident,
        p.session.queued,
        p.session.in_flight,
        s.loaded,
        s.bytes_loaded,
        p.loaded_original_bytes,
        p.resident_atlas_bytes,
        p.resident_original_bytes,
        s.ideal_fraction(),
        p.coarse.share(),
        p.coarse.coarser_items,
        s.evictions,
        s.cancelled,
        s.discarded,
        s.failures,
        p.upload_ms,
        f.atlas_layers_used,
        f.original_layers_used,
        p.apply_errors,
        p.evict_errors,
        p.resident_hash
    )
}

/// `auto` ([`RendererOptions::AUTO`]) or 1..=16.
pub fn parse_anisotropy(s: &str) -> Result<u16, String> {
    if s.eq_ignore_ascii_case("auto") {
        return Ok(RendererOptions::AUTO);
    }
    match s.parse::<u16>() {
        Ok(v) if (1..=16).contains(&v) => Ok(v),
        _ => Err(format!("{s:?}: expected auto or an integer from 1 to 16")),
    }
}
