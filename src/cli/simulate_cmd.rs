//! `atlastree simulate`: paging-budget experiments without a GPU.

use anyhow::{Context, bail};
use atlastree::camera::{Camera, Ground, PathKind};
use atlastree::paging::{Policy, UploadBudget};
use atlastree::select::{SelectOptions, min_distance_scale};
use atlastree::sim::SimInput;
use atlastree::sim::grid::{GridSpec, run_grid, write_csvs, write_plots};
use atlastree::store::TreeFile;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

/// Simulate block paging (paper §6) along a camera path for a grid of capacities, bandwidths, latencies
/// and policies — the same selection and paging code as `render --capacity`, with an I/O model instead of
/// a disk or network and CPU screen accounting instead of a GPU. Deterministic: the same inputs give the
/// same CSVs byte for byte.
///
/// Writes `frames.csv` (per run and frame: needed, ideal, resident, queued, in flight, bytes, coarser
/// screen share, time to ideal), `summary.csv` (per run: mean/p95/max coarser share, bytes, peak resident,
/// frames to converge after each jump, stalls) and plots (SVG + PNG): coarser share over time per k, bytes
/// per frame, and heat maps of the mean coarser share over capacity × bandwidth.
///
/// Example: `atlastree simulate city.atlastree --path overview-dive --capacity 40,80,160,320
/// --bandwidth 5MB/s,50MB/s,500MB/s --latency 0ms,80ms --out sim/`
#[derive(Args, Debug)]
pub struct SimulateArgs {
    /// The paging file (only its tables are read).
    pub file: PathBuf,
    /// Camera path: overview-dive, street, orbit, or a keyframe JSON file.
    #[arg(long, default_value = "overview-dive")]
    pub path: String,
    /// Capacities k (blocks), comma-separated; `all` = no budget.
    #[arg(long, default_value = "40,80,160,320", value_delimiter = ',')]
    pub capacity: Vec<String>,
    /// Bandwidths, comma-separated (`5MB/s`, `50MiB/s`); `instant` = no I/O model (blocks arrive in the
    /// frame they are requested).
    #[arg(long, default_value = "5MB/s,50MB/s,500MB/s", value_delimiter = ',')]
    pub bandwidth: Vec<String>,
    /// Latencies per request, comma-separated (`0ms`, `80ms`).
    #[arg(long, default_value = "0ms,80ms", value_delimiter = ',')]
    pub latency: Vec<String>,
    /// Policies, comma-separated: paper, distance, lru, ours.
    #[arg(long, default_value = "paper", value_delimiter = ',')]
    pub policy: Vec<Policy>,
    /// Frame clock, frames per second.
    #[arg(long, default_value_t = 60.0)]
    pub fps: f64,
    /// Frames to simulate (the path is stretched over them at `--fps`; default: the path's duration).
    #[arg(long)]
    pub frames: Option<usize>,
    /// Upload budget per frame: unlimited or bytes (`8MB`).
    #[arg(long, default_value = "unlimited")]
    pub upload_budget: UploadBudget,
    /// Maximum outstanding block requests.
    #[arg(long, default_value_t = 8)]
    pub max_queue: u32,
    /// Requests in flight at once (I/O model).
    #[arg(long, default_value_t = 4)]
    pub in_flight: u32,
    /// Extra time per request, e.g. `2ms` for HTTP request overhead.
    #[arg(long, default_value = "0ms")]
    pub overhead: String,
    /// Screen width in pixels and texel-per-pixel ratio the selection targets.
    #[arg(long, default_value_t = 800)]
    pub width: u32,
    #[arg(long, default_value_t = 600)]
    pub height: u32,
    #[arg(long, default_value_t = 1.0)]
    pub texel_ratio: f64,
    #[arg(long, default_value = "out/simulate")]
    pub out: PathBuf,
    /// Print the summary as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
}

fn parse_list<T>(
    what: &str,
    items: &[String],
    f: impl Fn(&str) -> Option<T>,
) -> anyhow::Result<Vec<T>> {
    items
        .iter()
        .map(|s| f(s.trim()).with_context(|| format!("bad --{what} value {s:?}")))
        .collect()
}

pub fn run(a: SimulateArgs) -> anyhow::Result<ExitCode> {
    if !(a.fps.is_finite() && a.fps > 0.0) {
        bail!("--fps must be finite and > 0");
    }
    let capacities = parse_list("capacity", &a.capacity, |s| {
        if s == "all" {
            Some(None)
        } else {
            s.parse::<u32>().ok().filter(|&k| k > 0).map(Some)
        }
    })?;
    let bandwidths = parse_list("bandwidth", &a.bandwidth, |s| {
        if s == "instant" {
            Some(None)
        } else {
            atlastree::util::parse_rate(s).map(Some)
        }
    })?;
    let latencies = parse_list("latency", &a.latency, atlastree::util::parse_seconds)?;
    let overhead = atlastree::util::parse_seconds(&a.overhead)
        .with_context(|| format!("bad --overhead {:?}", a.overhead))?;
    if a.policy.is_empty() || capacities.is_empty() || bandwidths.is_empty() || latencies.is_empty()
    {
        bail!("every grid axis needs at least one value");
    }
    let file = TreeFile::open(&a.file).with_context(|| format!("opening {}", a.file.display()))?;
    let params = file.to_params();
    let kind: PathKind = a.path.parse()?;
    let path = kind.resolve_with(|| Ground::from_tree(&file))?;
    let frames = a
        .frames
        .unwrap_or_else(|| (path.duration() * a.fps).ceil().max(1.0) as usize);
    let aspect = f64::from(a.width) / f64::from(a.height.max(1));
    let cameras: Vec<Camera> = path
        .frames(a.fps, frames)
        .map(|mut c| {
            c.aspect = aspect;
            c
        })
        .collect();
    let fov = cameras.first().map_or(60.0, |c| c.fov_x_deg);
    let scale = min_distance_scale(
        &params,
        &SelectOptions {
            screen_width: a.width,
            texel_ratio: a.texel_ratio,
            fov_x_deg: fov,
        },
    )?;
    let input = SimInput::from_file(&file)?;
    let spec = GridSpec {
        capacities,
        bandwidths,
        latencies,
        policies: a.policy.clone(),
        fps: a.fps,
        max_queue: a.max_queue,
        budget: a.upload_budget,
        max_in_flight: a.in_flight,
        overhead,
    };
    let cells = spec.cells().len();
    println!(
        "{}: {} blocks ({}), {} frames at {} fps, {} runs",
        a.file.display(),
        input.table.len(),
        atlastree::util::human_bytes(input.table.total_bytes()),
        cameras.len(),
        a.fps,
        cells
    );
    let bar = indicatif::ProgressBar::new(cells as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed} (ETA {eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let t = std::time::Instant::now();
    let results = run_grid(&input, &cameras, scale, &spec, &|| bar.inc(1))?;
    bar.finish_and_clear();
    let wall = t.elapsed().as_secs_f64();
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    let mut written = write_csvs(&a.out, &results)?;
    written.extend(write_plots(&a.out, &spec, &results)?);
    if a.json {
        let rows: Vec<serde_json::Value> = results
            .iter()
            .map(
                |r| serde_json::json!({ "run": r.key.label(), "key": r.key, "summary": r.summary }),
            )
            .collect();
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else {
        println!(
            "{:<32} {:>8} {:>8} {:>8} {:>10} {:>10} {:>6} {:>6} {:>6}  converge (frames after each jump)",
            "run", "mean", "p95", "max", "MB", "orig MB", "peak", "jumps", "stalls"
        );
        for r in &results {
            let s = &r.summary;
            println!(
                "{:<32} {:>8.4} {:>8.4} {:>8.4} {:>10.1} {:>10.1} {:>6} {:>6} {:>6}  {:?}",
                r.key.label(),
                s.mean_coarser,
                s.p95_coarser,
                s.max_coarser,
                s.bytes_total as f64 / 1e6,
                s.bytes_originals_total as f64 / 1e6,
                s.peak_resident,
                s.jumps,
                s.stalls,
                s.converge_frames
            );
        }
    }
    let per_cell = results.iter().map(|r| r.seconds).fold(0.0, f64::max);
    println!(
        "{cells} runs in {wall:.2} s wall (slowest run {per_cell:.2} s for {} frames)",
        cameras.len()
    );
    println!("wrote:");
    for p in written {
        println!("  {}", p.display());
    }
    Ok(ExitCode::SUCCESS)
}
