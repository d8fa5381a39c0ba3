//! `atlastree simulate`: paging-budget experiments without a GPU. Flags → [`SimulateConfig`]
//! ([`SimulateArgs::validate`]) → [`execute`]: cameras, grid runs, files, report.

use super::args::{QueueArgs, Viewport, ViewportArgs, parse_list};
use anyhow::{Context, bail};
use atlastree::camera::{Camera, Ground, PathKind};
use atlastree::paging::{PagerOptions, Policy};
use atlastree::sim::SimInput;
use atlastree::sim::grid::{GridSpec, RunResult, run_grid, write_csvs, write_plots};
use atlastree::store::TreeFile;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

// Its --help text is the doc comment of `cli::Command::Simulate` (clap shows the variant's, not this struct's).
#[derive(Args, Debug)]
pub(crate) struct SimulateArgs {
    /// The paging file (only its tables are read).
    pub file: PathBuf,
    /// Camera path: overview-dive, street, orbit, or a keyframe JSON file: `{"keyframes": [{"time": s,
    /// "eye": [x, y, z], "target": [x, y, z], "fov": degrees}, …], "up": [0, 1, 0], "near": 0.25,
    /// "far": 100000}` (the scene's units; `aspect`, if given, is not used: frames take the viewport's).
    #[arg(long, default_value = "overview-dive")]
    pub path: PathKind,
    /// Capacities k (blocks), comma-separated; `all` = no budget.
    #[arg(long, default_value = "40,80,160,320", value_delimiter = ',')]
    pub capacity: Vec<String>,
    /// Bandwidths, comma-separated (`5MB/s`, `50MiB/s`); `instant` = no I/O model (blocks arrive in the
    /// frame they are requested).
    #[arg(
        long,
        default_value = "5MB/s,50MB/s,500MB/s",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub bandwidth: Vec<String>,
    /// Latencies per request, comma-separated, each with its unit (`0ms`, `80ms`, `0.2s`; a bare number
    /// other than 0 is refused, not read as seconds).
    #[arg(
        long,
        default_value = "0ms,80ms",
        value_delimiter = ',',
        allow_hyphen_values = true
    )]
    pub latency: Vec<String>,
    /// Policies, comma-separated: paper, distance, lru, ours.
    #[arg(long, default_value = "paper", value_delimiter = ',')]
    pub policy: Vec<Policy>,
    /// Frame clock, frames per second.
    #[arg(long, default_value_t = 60.0)]
    pub fps: f64,
    /// Frames to simulate: frame i is the camera at path time start + i / `--fps` (fewer frames than the
    /// path's duration covers its start only; more hold its last camera). Default: the path's duration,
    /// its first and, where it falls on a frame, its last keyframe included.
    #[arg(long)]
    pub frames: Option<usize>,
    /// Requests in flight at once (I/O model).
    #[arg(long, default_value_t = 4)]
    pub in_flight: u32,
    /// Extra time per request with its unit, e.g. `2ms` for HTTP request overhead (a bare number other
    /// than 0 is refused), in every run of the grid: the model adds it to each request's latency (so
    /// `--overhead 200ms --latency 0ms` equals `--latency 200ms`); the table and `--json` state it.
    #[arg(long, default_value = "0ms", allow_hyphen_values = true)]
    pub overhead: String,
    /// Output directory.
    #[arg(long, default_value = "out/simulate")]
    pub out: PathBuf,
    /// Print the summary as JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    #[command(flatten, next_help_heading = "Queue")]
    pub queue: QueueArgs,
    #[command(flatten, next_help_heading = "Viewport")]
    pub viewport: ViewportArgs,
}

/// A checked `simulate` run.
#[derive(Debug, Clone)]
pub(crate) struct SimulateConfig {
    pub file: PathBuf,
    pub path: PathKind,
    /// The grid axes and shared settings (a byte budget or none: a time budget is refused).
    pub spec: GridSpec,
    /// `None`: the path's duration at `spec.fps`.
    pub frames: Option<usize>,
    pub viewport: Viewport,
    pub out: PathBuf,
    pub json: bool,
}

/// A list value that is `word` (`None`: no limit) or what `f` parses.
fn or_word<T>(
    word: &'static str,
    f: impl Fn(&str) -> Option<T>,
) -> impl Fn(&str) -> Option<Option<T>> {
    move |s| {
        if s == word {
            Some(None)
        } else {
            f(s).map(Some)
        }
    }
}

impl SimulateArgs {
    /// Checks the flags and derives the grid.
    pub(crate) fn validate(self) -> anyhow::Result<SimulateConfig> {
        super::args::check_fps("--fps", self.fps)?;
        if let Some(frames) = self.frames {
            super::args::check_frames("--frames", frames)?;
        }
        if self.in_flight == 0 {
            bail!("--in-flight must be at least 1 (requests in flight at once)");
        }
        let capacities = parse_list(
            "capacity",
            "a block count from 1 to 4294967295, or all (every block resident)",
            &self.capacity,
            or_word("all", |s| s.parse::<u32>().ok().filter(|&k| k > 0)),
        )?;
        let bandwidths = parse_list(
            "bandwidth",
            "a rate > 0 such as 40MB/s, or instant",
            &self.bandwidth,
            or_word("instant", atlastree::util::parse_rate),
        )?;
        let latencies = parse_list(
            "latency",
            "a duration ≥ 0 with its unit, such as 8ms or 0.008s (a bare number other than 0 is refused)",
            &self.latency,
            atlastree::util::parse_duration_with_unit,
        )?;
        let overhead =
            atlastree::util::parse_duration_with_unit(&self.overhead).with_context(|| {
                format!(
                    "bad --overhead {:?}: a duration ≥ 0 with its unit, such as 2ms or 0.002s (a bare \
                     number other than 0 is refused)",
                    self.overhead
                )
            })?;
        if self.policy.is_empty()
            || capacities.is_empty()
            || bandwidths.is_empty()
            || latencies.is_empty()
        {
            bail!("every grid axis needs at least one value");
        }
        let budget = self.queue.byte_budget()?;
        let pager = self.queue.apply(PagerOptions::default())?;
        let spec = GridSpec {
            capacities,
            bandwidths,
            latencies,
            policies: self.policy,
            fps: self.fps,
            max_queue: pager.max_queue,
            budget,
            max_in_flight: self.in_flight,
            overhead,
        };
        if let Some(label) = spec.duplicate_label() {
            anyhow::bail!(
                "two runs of the grid are the same, {label}: a capacity, bandwidth, latency or policy is given twice"
            );
        }
        Ok(SimulateConfig {
            file: self.file,
            path: self.path,
            spec,
            frames: self.frames,
            viewport: self.viewport.validate()?,
            out: self.out,
            json: self.json,
        })
    }
}

pub(super) fn run(a: SimulateArgs) -> anyhow::Result<ExitCode> {
    execute(&a.validate()?)
}

/// Runs a checked configuration.
pub(super) fn execute(cfg: &SimulateConfig) -> anyhow::Result<ExitCode> {
    // Before the file is read and the runs: an --out that cannot be a folder (or made one, or written),
    // or that another run holds. A run refused (a missing file, a bad path, a capacity below the roots)
    // leaves no folder it made (as render and sweep leave none; fault hunt, session 35).
    super::OutFolder::open(&cfg.out)?.run(|| {
        // The tables in memory: a grid selects from them for minutes, and a file truncated or rewritten
        // meanwhile killed it by SIGBUS or changed its rows without a word (fault hunt, session 37).
        let file = super::open_local(&cfg.file, "simulate", atlastree::store::LoadMode::Tables)?;
        run_and_write(cfg, &file)
    })
}

/// [`execute`] once `--out` exists: the runs, their CSVs, plots and report.
fn run_and_write(cfg: &SimulateConfig, file: &TreeFile) -> anyhow::Result<ExitCode> {
    let cameras = sample_cameras(cfg, file)?;
    let scales = cfg.viewport.scales(&file.to_params(), &cameras)?;
    let input = SimInput::from_file(file)?;
    let cells = cfg.spec.cells().len();
    // With --json, stdout holds the JSON alone; what people read goes to stderr.
    let say = |line: String| {
        if cfg.json {
            eprintln!("{line}");
        } else {
            println!("{line}");
        }
    };
    say(format!(
        "{}: {} blocks ({}), {} frames at {} fps, {} runs",
        cfg.file.display(),
        input.table.len(),
        atlastree::util::human_bytes(input.table.total_bytes()),
        cameras.len(),
        atlastree::util::short_number(cfg.spec.fps),
        cells
    ));
    if cfg.spec.bandwidths.contains(&None) && cfg.spec.latencies.len() > 1 {
        say(format!(
            "note: --bandwidth instant models no I/O, so --latency changes nothing there: one instant run \
             per capacity and policy (labelled at {} ms)",
            atlastree::util::short_number(cfg.spec.latencies[0] * 1e3)
        ));
    }
    let bar = indicatif::ProgressBar::new(cells as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed} (ETA {eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let t = std::time::Instant::now();
    let results = run_grid(&input, &cameras, &scales, &cfg.spec, &|| bar.inc(1))?;
    bar.finish_and_clear();
    // A path that never looks at the scene pages only the roots: every run would read as ideal.
    if !results
        .iter()
        .any(atlastree::sim::grid::RunResult::drew_nodes)
    {
        eprintln!(
            "warning: no frame of the path draws any node of the tree (does it look at the scene?): the \
             runs measure nothing, and their coarser shares of 0 mean nothing drawn, not ideal paging"
        );
    }
    let wall = t.elapsed().as_secs_f64();
    // Only where a simulation wrote (its summary.csv is there, before this run replaces it): never the
    // user's own files of those names.
    let marker = cfg.out.join("summary.csv");
    let earlier_run = marker.is_file();
    let mut written = write_csvs(&cfg.out, &results, cfg.spec.overhead)?;
    written.extend(write_plots(&cfg.out, &cfg.spec, &results)?);
    // An earlier grid's plots that this one did not draw (other latencies or policies) would sit beside
    // this run's summary as if they were its own. Removed once this run's are written, so a rerun
    // stopped before then leaves the earlier plots, not none (fault hunt, session 36).
    let plot = |n: &str| {
        let stem = n.strip_suffix(".png").or_else(|| n.strip_suffix(".svg"));
        stem.is_some_and(|s| {
            s.starts_with("heatmap_") || s == "coarser_over_time" || s == "bytes_per_frame"
        }) && !written
            .iter()
            .any(|w| w.file_name().is_some_and(|f| f == n))
    };
    let removed = if earlier_run {
        atlastree::util::remove_stale_outputs(&cfg.out, plot).with_context(|| {
            format!("removing an earlier run's plots from {}", cfg.out.display())
        })?
    } else {
        0
    };
    if removed > 0 {
        say(format!(
            "note: removed {removed} plot file(s) of an earlier run from {}",
            cfg.out.display()
        ));
    }
    print_results(&results, cfg.json, &cfg.spec)?;
    let per_cell = results.iter().map(|r| r.seconds).fold(0.0, f64::max);
    say(format!(
        "{cells} runs in {wall:.2} s wall (slowest run {per_cell:.2} s for {} frames)",
        cameras.len()
    ));
    say("wrote:".to_string());
    for p in written {
        say(format!("  {}", p.display()));
    }
    Ok(ExitCode::SUCCESS)
}

/// One camera per frame at `start + i / fps` (default frame count: the path's duration, both ends).
fn sample_cameras(cfg: &SimulateConfig, file: &TreeFile) -> anyhow::Result<Vec<Camera>> {
    let path = cfg.path.resolve_with(|| Ground::from_tree(file))?;
    let frames = match cfg.frames {
        Some(frames) => frames,
        None => {
            // The path's duration at --fps, its end included where it falls on a frame (a 1 s path at 1
            // fps is 2 frames; the overview-dive's 20 s at 60 fps ended at 19.983 s; fault hunt, session
            // 32), bounded as --frames is.
            let n = default_frames(path.duration(), cfg.spec.fps);
            if n > super::args::MAX_FRAMES as f64 {
                bail!(
                    "the path's {:.1} s at --fps {} are {n:.3e} frames, over the {} a run takes: lower \
                     --fps or give --frames",
                    path.duration(),
                    atlastree::util::short_number(cfg.spec.fps),
                    super::args::MAX_FRAMES
                );
            }
            n as usize
        }
    };
    Ok(cfg.viewport.cameras(&path, cfg.spec.fps, frames))
}

/// The per-run summaries, as JSON or a table.
fn print_results(results: &[RunResult], json: bool, spec: &GridSpec) -> anyhow::Result<()> {
    // Settings of every run that its label does not carry (a run with --overhead read as one without:
    // fault hunt, session 32).
    let shared = serde_json::json!({
        "overhead_s": spec.overhead,
        "max_in_flight": spec.max_in_flight,
        "max_queue": spec.max_queue,
        "fps": spec.fps,
    });
    if json {
        let rows: Vec<serde_json::Value> = results
            .iter()
            .map(
                // `drew_nodes` false: the path never looks at the scene, the run measures nothing.
                |r| {
                    let drew = r.drew_nodes();
                    serde_json::json!({ "run": r.key.label(), "key": r.key, "settings": shared, "drew_nodes": drew, "summary": r.summary })
                },
            )
            .collect();
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    println!("MB: loaded over the path after the root atlases (resident before the first frame)");
    if spec.overhead > 0.0 {
        println!(
            "every run: {} ms of overhead per request, added to its latency",
            atlastree::util::short_number(spec.overhead * 1e3)
        );
    }
    println!(
        "{:<32} {:>8} {:>8} {:>8} {:>10} {:>10} {:>6} {:>6} {:>6}  converge (frames after each jump)",
        "run", "mean", "p95", "max", "MB", "orig MB", "peak", "jumps", "stalls"
    );
    for r in results {
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
    Ok(())
}

/// Frames `start + i / fps` that lie on a path of `duration` seconds, both ends included: ⌊duration · fps⌋
/// + 1 (a product within 10⁻⁹ of a whole number counts as it, so 0.1 s at 30 fps is 4 frames).
fn default_frames(duration: f64, fps: f64) -> f64 {
    let steps = duration * fps;
    (steps + 1e-9 * steps.max(1.0)).floor().max(0.0) + 1.0
}

#[cfg(test)]
mod frame_tests {
    use super::default_frames;

    #[test]
    fn the_default_frames_reach_the_paths_end() {
        assert_eq!(default_frames(1.0, 1.0), 2.0);
        assert_eq!(default_frames(20.0, 60.0), 1201.0);
        assert_eq!(default_frames(0.0, 60.0), 1.0);
        assert_eq!(default_frames(0.1, 30.0), 4.0);
        assert_eq!(default_frames(1.5, 1.0), 2.0);
    }
}
