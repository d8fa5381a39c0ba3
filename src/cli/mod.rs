//! Subcommands. Each `*Args` struct is the clap view, with flag groups shared between commands in
//! [`args`]; a command's validate step turns its parsed flags into a checked configuration (refusing a
//! flag that means nothing for it, with a message), and its `run` only runs.

mod args;
mod build_cmd;
mod build_report;
mod demo;
mod export_cmd;
mod inspect_cmd;
mod merge_cmd;
mod os_limits;
mod progress;
mod render_cmd;
mod render_out;
mod render_report;
mod scene_info;
mod serve_cmd;
mod simulate_cmd;
mod sweep_cmd;
mod view_cmd;

use clap::{Parser, Subcommand, ValueEnum};
use std::process::ExitCode;

/// Texture-atlas trees for massively textured, planar-distributed 3D scenes (city models, landscapes,
/// game levels): preprocess a glTF scene into a quadtree of fixed-size atlases with texel-per-pixel control
/// (Buchholz & Döllner 2005), page it under a memory budget, render it with texture-array batching.
///
/// Start with `atlastree demo`; then `atlastree scene-info SCENE`, `atlastree build SCENE -o OUT.atlastree`,
/// `atlastree inspect OUT.atlastree --verify`.
#[derive(Parser, Debug)]
#[command(
    name = "atlastree",
    version,
    about,
    long_about,
    propagate_version = true,
    after_long_help = ENVIRONMENT_HELP
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

/// The environment variables the binary reads, under `atlastree --help` (they were documented nowhere
/// but in the source, and `RUST_LOG` was ignored; session 38).
const ENVIRONMENT_HELP: &str = "Environment:
  RAYON_NUM_THREADS  Worker threads (default: one a core); each rasteriser
                     thread adds its atlases to a build's --max-memory need
  ATLASTREE_LOG      Log filter on stderr, in tracing's EnvFilter syntax
                     (`info`, `atlastree=debug,wgpu=warn`); RUST_LOG where
                     it is unset; default `warn`
  ATLASTREE_NO_MMAP  `1`: read paging files whole, not memory-mapped
  ATLASTREE_SCALAR   Set: scalar kernels instead of AVX2 (the same bytes)
  WGPU_BACKEND       The GPU backends to try (`vulkan`, `metal`, `dx12`, `gl`)
  SLURM_ARRAY_TASK_ID, SLURM_ARRAY_TASK_COUNT, JOB_COMPLETION_INDEX,
  AWS_BATCH_JOB_ARRAY_INDEX, ATLASTREE_SHARD_COUNT
                     `build --shard auto` reads its shard from the
                     scheduler's array (`build --help`)";

/// Commands with numeric flags take negative numbers as values (`--fov -10` reaches the flag's own check,
/// which names it and its range; clap read `-1` as an unknown flag and quoted a token never typed: fault
/// hunt, session 32).
#[derive(Subcommand, Debug)]
pub(crate) enum Command {
    /// Run the whole pipeline on the embedded default scene (data/city) and show what each stage did.
    #[command(allow_negative_numbers = true)]
    Demo(demo::DemoArgs),
    /// Summarise a glTF scene: triangles, textures, UV ranges and repeats, wrap and alpha modes, planarity.
    SceneInfo(scene_info::SceneInfoArgs),
    /// Preprocess a glTF scene into a texture-atlas tree paging file (paper §5).
    ///
    /// Texel-per-pixel control (paper §5.2.1): the atlas of a leaf is sized so that a camera at least d_min
    /// away sees at least `texel-ratio` texels per screen pixel (screen `screen-width` pixels wide, horizontal
    /// field of view `fov`). Smaller d_min: deeper tree, bigger file, original textures needed less often.
    #[command(allow_negative_numbers = true)]
    Build(build_cmd::BuildArgs),
    /// Merge the shard files of a sharded build (`build --shard I/N`) into the paging file, byte-identical
    /// to a one-process build.
    ///
    /// Finds `OUT.shard-I-of-N` for I in 0..N beside OUT (written by `atlastree build SCENE -o OUT --shard I/N`
    /// on any machines that share the directory), checks each (present, intact, same scene and flags, the
    /// part of the tree the cut gives it), copies their blocks, makes the atlases above the cut from the
    /// shards' subtree roots (four children halved) and writes OUT atomically: byte-identical to
    /// `atlastree build SCENE -o OUT` with the same flags. A missing or broken shard is named with the command
    /// that rebuilds it; rerunning a merge writes the same file. The shard files are left in place.
    Merge(merge_cmd::MergeArgs),
    /// Show a paging file's tree shape and per-level statistics; `--verify` checks every checksum and
    /// invariant and exits non-zero on any violation.
    Inspect(inspect_cmd::InspectArgs),
    /// Render a camera path offscreen with the texture-array-batched renderer; PNGs, contact sheet, stats.csv.
    ///
    /// Measures every frame. Writes PNG frames (every k-th), a contact sheet and `stats.csv` per mode.
    ///
    /// Without `--capacity` every block is uploaded at start. With `--capacity k` blocks are paged (paper §6):
    /// at most k blocks resident, loaded by priority from `--source`, missing ones drawn with the nearest
    /// resident ancestor atlas; `stats.csv` then gains the paging columns (blocks needed / ideal / resident /
    /// queued / in flight, bytes loaded, ideal fraction resident, coarser screen share, evictions, …; the
    /// README's "Changelog" lists the column names).
    #[command(allow_negative_numbers = true)]
    Render(render_cmd::RenderArgs),
    /// Paging-budget experiments without a GPU: capacity × bandwidth × latency × policy over a camera path.
    ///
    /// The same selection and paging code as `render --capacity`, with an I/O model instead of
    /// a disk or network and CPU screen accounting instead of a GPU. Deterministic: the same inputs give the
    /// same CSVs byte for byte (so the upload budget is bytes or unlimited: there are no uploads to time).
    ///
    /// Writes `frames.csv` (per run and frame: the paging counters under the same names as `render`'s
    /// `stats.csv` — blocks_needed, ideal, resident, queued, in_flight, bytes_loaded, coarser_share, … — and
    /// time_to_ideal), `summary.csv` (per run: mean/p95/max coarser share, bytes, peak resident,
    /// frames to converge after each jump, stalls) and plots (SVG + PNG): coarser share over time per k, bytes
    /// per frame, and heat maps of the mean coarser share over capacity × bandwidth.
    ///
    /// Example: `atlastree simulate city.atlastree --path overview-dive --capacity 40,80,160,320
    /// --bandwidth 5MB/s,50MB/s,500MB/s --latency 0ms,80ms --out sim/`
    #[command(allow_negative_numbers = true)]
    Simulate(simulate_cmd::SimulateArgs),
    /// Export a paging file for other viewers: `export 3dtiles FILE -o DIR` writes a 3D Tiles 1.1
    /// tileset (CesiumJS, 3DTilesRendererJS, …) with one tile per node and the original textures below the
    /// leaves.
    #[command(allow_negative_numbers = true)]
    Export(export_cmd::ExportArgs),
    /// Serve a paging file over HTTP with range requests (for `render --source http://…`); Ctrl-C stops.
    ///
    /// Any static file server that answers `Range: bytes=a-b` with `206 Partial Content` works as well
    /// (one that ignores ranges works too, slowly: the client cuts each block out of the whole file and
    /// counts it); this one needs no setup. The file is checked (header, tables, block layout) before
    /// serving, then served read-only at `http://BIND:PORT/<file name>` until Ctrl-C. The server keeps
    /// the file it checked: one renamed over it (as `build -o` publishes a new file) is not served until
    /// a restart. Do not rewrite the file in place while it is served.
    Serve(serve_cmd::ServeArgs),
    /// Fly through a paging file in a window with a live inspector (egui): fps, counters, knobs, node
    /// bounds, frozen selection, screenshots, path recording.
    ///
    /// Keys: W A S D move, Q E down/up, Shift fast, drag the mouse to look, wheel for speed (orbit: distance);
    /// O fly/orbit; F frame the scene; 1 2 3 tree/original/dummy; L level colours; B node bounds; G freeze the
    /// selection (fly away and look at the cut from outside); H hide the inspector; P screenshot (PNG in
    /// --out); R start/stop recording the flown path (JSON camera path in --out, replay with --path or
    /// `render --path`); Esc quit.
    ///
    /// Scripted: `--screenshot-after N --exit` writes the N-th frame to --screenshot and quits, e.g. under
    /// `xvfb-run -a` on a machine without a display (any wgpu backend; lavapipe works).
    View(view_cmd::ViewArgs),
    /// What accuracy costs in time: build and render a grid of knob values on one scene and path, compare
    /// every frame with the original textures; sweep.csv, frames.csv, report.md and Pareto plots.
    ///
    /// Builds every build-time variant of the grid once (d_min ratio,
    /// atlas size, border, down-sampling filter, compression, repeats, alpha mips), renders every runtime
    /// variant (texel ratio, paging capacity k) over the same frames of the path, and compares each frame
    /// with the reference: the same view drawn with the original textures at full resolution (`render --mode
    /// original`), or ground truth with `--reference supersampled`. A paged variant is measured at the
    /// steady state its k gives each view: its pager is stepped there until it loads nothing more (the
    /// loads counted in that frame's bytes_loaded).
    ///
    /// The grid is a star around a base variant: the base plus each listed value of one knob at a time.
    /// `--grid small` (4 builds, 17 variants, 6 frames of 320×240; CI time on data/city), `--grid full`
    /// (12 builds, 50 variants, 12 frames of 640×480), or a JSON file, e.g.
    /// `{"base": {"d_min_ratio": 8, "atlas_size": 1024, "border": 8, "filter": "box", "texel_ratio": 1},
    ///   "atlas_size": [512, 1024, 2048], "texel_ratio": [0.25, 0.5, 1, 2], "capacity": [64], "frames": 8}`.
    ///
    /// Writes into `--out`: sweep.csv (one row per variant: means, bytes_loaded summed over the frames),
    /// frames.csv (per variant and frame),
    /// builds.csv (stage times), report.md (tables, recommended defaults, plots) and the plots as SVG + PNG:
    /// accuracy vs frame time with the Pareto front, vs file size, vs build time, vs texel ratio, and the
    /// texel-per-pixel histograms.
    #[command(allow_negative_numbers = true)]
    Sweep(sweep_cmd::SweepArgs),
}

/// Which axis points up (the other two span the distribution plane).
#[derive(Copy, Clone, Debug, Default, ValueEnum)]
pub(crate) enum UpArg {
    /// The axis of least extent where it is under half the next least, else y (glTF's convention).
    #[default]
    Auto,
    X,
    Y,
    Z,
}

impl UpArg {
    pub(crate) fn to_option(self) -> Option<atlastree::scene::UpAxis> {
        use atlastree::scene::UpAxis;
        match self {
            UpArg::Auto => None,
            UpArg::X => Some(UpAxis::X),
            UpArg::Y => Some(UpAxis::Y),
            UpArg::Z => Some(UpAxis::Z),
        }
    }
}

pub(crate) fn init_tracing() {
    // `ATLASTREE_LOG`, else `RUST_LOG` (the Rust ecosystem's name, which was ignored); a filter that
    // does not parse is said, not silently replaced by the default.
    let var = ["ATLASTREE_LOG", "RUST_LOG"]
        .into_iter()
        .find(|v| std::env::var_os(v).is_some());
    let filter = match var.map(|v| (v, tracing_subscriber::EnvFilter::try_from_env(v))) {
        Some((_, Ok(filter))) => filter,
        Some((v, Err(e))) => {
            use std::io::Write;
            let _ = writeln!(
                std::io::stderr(),
                "warning: {v}: {e}: logging at the default level, warn (`atlastree --help` lists the \
                 environment variables)"
            );
            tracing_subscriber::EnvFilter::new("warn")
        }
        None => tracing_subscriber::EnvFilter::new("warn"),
    };
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        // Colour codes only on a terminal: a log redirected to a file stays plain text.
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .try_init();
}

/// The most threads `RAYON_NUM_THREADS` may ask for: 99,999 aborted inside the thread pool's start (a
/// stack guard page it could not map) or ran on for minutes before the memory check could refuse it
/// (fault hunt, session 28).
const MAX_RAYON_THREADS: usize = 1024;

/// Runs `handler` with the signal's number (SIGINT, SIGTERM, SIGHUP; 2 for a Ctrl-C where there are no
/// signals) on a thread of its own when the first one arrives; a second one while it runs is ignored. A
/// signal the process started with ignored stays ignored (`nohup` ignores SIGHUP, a script's `cmd &`
/// SIGINT: caught, a logout ended a nohup'd build; review, session 36). Not installed (a line on
/// stderr) where the signals cannot be caught.
fn on_interrupt(handler: fn(i32)) {
    #[cfg(unix)]
    let installed = {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        let caught: Vec<i32> = [SIGINT, SIGTERM, SIGHUP]
            .into_iter()
            .filter(|&s| !os_limits::ignored_at_start(s))
            .collect();
        signal_hook::iterator::Signals::new(&caught).and_then(|mut signals| {
            std::thread::Builder::new()
                .name("interrupt".into())
                .spawn(move || {
                    if let Some(signal) = signals.forever().next() {
                        handler(signal);
                    }
                })
                .map(drop)
        })
    };
    #[cfg(not(unix))]
    let installed = ctrlc::set_handler(move || handler(2));
    if let Err(e) = installed {
        eprintln!("warning: interrupts not caught ({e}): Ctrl-C may leave a temporary file behind");
    }
}

/// What an interrupt did, said so an interrupted step is not read as a finished one (it ended without a
/// word), nor a complete output as an unfinished one: `removed` unfinished outputs, and the committed
/// outputs still there with the last of them.
fn say_interrupted(removed: usize, committed: Option<&(usize, std::path::PathBuf)>) {
    // Not `eprintln!`: a stderr whose reader has gone would panic here, under the temps' lock that the
    // panic hook's cleanup takes again (a hang; review, session 37).
    use std::io::Write;
    let _ = match committed {
        Some((n, last)) => writeln!(
            std::io::stderr(),
            "interrupted: {n} output(s) of this run were already complete (the last {}, left in place); \
             {removed} unfinished output(s) removed",
            last.display()
        ),
        None => writeln!(
            std::io::stderr(),
            "interrupted: stopped before finishing; {removed} unfinished output(s) removed, earlier \
             outputs left as they were"
        ),
    };
}

/// Ends the process as `signal` itself would (its default action, raised again), so the shell sees a
/// process killed by it: a loop of builds stops at a Ctrl-C (bash goes on after a child that exited on
/// its own; review, session 36). `$?` is 128 + the signal's number (130, 143), the exit code where the
/// signal cannot be raised.
fn end_by(signal: i32) -> std::convert::Infallible {
    #[cfg(unix)]
    let _ = signal_hook::low_level::emulate_default_handler(signal);
    std::process::exit(128 + signal)
}

pub(crate) fn run() -> anyhow::Result<ExitCode> {
    let cli = Cli::parse();
    os_limits::prepare_process();
    if let Some(n) = std::env::var("RAYON_NUM_THREADS")
        .ok()
        .and_then(|v| v.trim().parse::<usize>().ok())
        .filter(|&n| n > MAX_RAYON_THREADS)
    {
        anyhow::bail!(
            "RAYON_NUM_THREADS={n}: more worker threads than this tool starts (at most \
             {MAX_RAYON_THREADS}; unset it for one a core)"
        );
    }
    if !matches!(cli.command, Command::Serve(_)) {
        // Ctrl-C, or SIGTERM from a scheduler cancelling a job, ends the process by that signal ($? 130,
        // 143) with no temp file left (a paging file's is its whole length, reserved up front). `serve`
        // handles Ctrl-C itself.
        on_interrupt(|signal| {
            atlastree::util::remove_live_temps_and_exit(|| end_by(signal), say_interrupted)
        });
    }
    match cli.command {
        Command::Demo(a) => demo::run(a),
        Command::SceneInfo(a) => scene_info::run(a),
        Command::Build(a) => build_cmd::run(a),
        Command::Merge(a) => merge_cmd::run(a),
        Command::Inspect(a) => inspect_cmd::run(a),
        Command::Render(a) => render_cmd::run(a),
        Command::Simulate(a) => simulate_cmd::run(a),
        Command::Serve(a) => serve_cmd::run(a),
        Command::Export(a) => export_cmd::run(a),
        Command::View(a) => view_cmd::run(a),
        Command::Sweep(a) => sweep_cmd::run(a),
    }
}

/// Keeps the triangles of the materials matching any of `globs` ([`atlastree::util::glob_match`]); an error
/// naming the patterns and a few material names when nothing is left.
pub(crate) fn retain_materials(
    scene: &mut atlastree::scene::Scene,
    globs: &[String],
) -> anyhow::Result<atlastree::scene::RetainReport> {
    // Quoted: a name holding a comma or a newline read as several (fault hunt, session 37).
    let names: Vec<String> = scene
        .materials
        .iter()
        .take(8)
        .map(|m| format!("{:?}", m.name))
        .collect();
    // `'a, b'` is two patterns (the space is not part of a name), and each must match a material: one
    // mistyped pattern of several dropped its materials without a word (fault hunt, session 31).
    let globs: Vec<&str> = globs.iter().map(|g| g.trim()).collect();
    if let Some(missing) = globs
        .iter()
        .find(|g| !(scene.materials.iter()).any(|m| atlastree::util::glob_match(g, &m.name)))
    {
        anyhow::bail!(
            "{}: --materials pattern {missing:?} matches no material (materials include: {}; patterns are \
             split at commas: `?` matches a comma inside a name)",
            scene.source.display(),
            names.join(", ")
        );
    }
    let report = scene.retain_materials(|m| {
        globs
            .iter()
            .any(|g| atlastree::util::glob_match(g, &m.name))
    });
    if scene.triangles.is_empty() {
        anyhow::bail!(
            "{}: no triangle has a material matching {} (materials include: {})",
            scene.source.display(),
            globs.join(","),
            names.join(", ")
        );
    }
    Ok(report)
}

/// Opens a local paging file for `command` ([`reject_url`] first) with `mode` (`LoadMode::Tables` for a
/// command that reads blocks for long: a file truncated meanwhile is then an error, not SIGBUS).
pub(crate) fn open_local(
    path: &std::path::Path,
    command: &str,
    mode: atlastree::store::LoadMode,
) -> anyhow::Result<atlastree::store::TreeFile> {
    reject_url(path, command)?;
    anyhow::Context::with_context(atlastree::store::TreeFile::open_with(path, mode), || {
        format!("opening {}", path.display())
    })
}

/// `path` as written and as shown (credentials redacted), where no local file or folder has that name:
/// what [`reject_url`] and [`reject_scene_url`] read as a URL.
fn url_not_path(path: &std::path::Path) -> Option<(String, String)> {
    if path.exists() {
        return None;
    }
    let raw = path.to_string_lossy().into_owned();
    let text = atlastree::paging::redact_url(&raw);
    Some((raw, text))
}

/// An http(s) URL that is not also a local path gets a clear error (only `render` pages over HTTP)
/// instead of "No such file or directory".
pub(crate) fn reject_url(path: &std::path::Path, command: &str) -> anyhow::Result<()> {
    let Some((raw, text)) = url_not_path(path) else {
        return Ok(());
    };
    if args::is_url(&raw) {
        anyhow::bail!(
            "{text}: `atlastree {command}` reads a local paging file, not a URL (`atlastree render URL` pages \
             over HTTP; download the file for {command})"
        );
    }
    if let Some(scheme) = args::url_scheme(&raw) {
        anyhow::bail!(
            "{text}: unsupported URL scheme '{scheme}' (`atlastree render` pages over http:// and https://; \
             other commands read a local file)"
        );
    }
    Ok(())
}

/// An output named as an http(s) or other URL that is not also a local path gets a clear error: "its
/// folder http://127.0.0.1:9 does not exist: create it first" led to a local folder named `http:`
/// (fault hunt, session 36). `what` is the flag or argument, e.g. "-o" or "--out".
pub(crate) fn reject_output_url(path: &std::path::Path, what: &str) -> anyhow::Result<()> {
    reject_any_url(path, |text| {
        format!(
            "{what} {text}: outputs are written to local files and folders, not URLs; name a local path \
             (`atlastree serve FILE` serves a paging file over HTTP)"
        )
    })
}

/// `message(shown URL)` as the error where `path` has a URL scheme and names no local file or folder.
fn reject_any_url(path: &std::path::Path, message: impl Fn(&str) -> String) -> anyhow::Result<()> {
    match url_not_path(path) {
        Some((raw, text)) if args::url_scheme(&raw).is_some() => anyhow::bail!(message(&text)),
        _ => Ok(()),
    }
}

/// A scene given as an http(s) or other URL that is not also a local path gets a clear error (it read
/// "cannot read: No such file or directory"; fault hunt, session 34), as [`reject_url`] does for paging
/// files.
fn reject_scene_url(path: &std::path::Path) -> anyhow::Result<()> {
    reject_any_url(path, |text| {
        format!(
            "{text}: scenes are read from local glTF or GLB files, not URLs; download the scene with its \
             images first (only `atlastree render URL` reads over HTTP, and it reads paging files)"
        )
    })
}

/// Before any work: `--out` must be a folder or not exist yet (a file there failed only when the outputs
/// were written, as "File exists (os error 17)" or "Not a directory").
pub(crate) fn check_out_folder(out: &std::path::Path) -> anyhow::Result<()> {
    reject_output_url(out, "--out")?;
    if out.exists() && !out.is_dir() {
        anyhow::bail!(
            "--out {}: exists and is not a folder (the outputs go into a folder: name a new or existing one)",
            out.display()
        );
    }
    check_parent_folders(out, "--out")
}

/// Before any work: the nearest existing folder above `path` (given as `flag`) must be a folder, so
/// that the folders below it can be made (`view --screenshot notafolder/shot.png` failed after its
/// frames as "File exists (os error 17)"; fault hunt, session 37).
pub(crate) fn check_parent_folders(path: &std::path::Path, flag: &str) -> anyhow::Result<()> {
    let existing = (path.ancestors().skip(1))
        .filter(|p| !p.as_os_str().is_empty())
        .find(|p| p.exists());
    match existing {
        Some(p) if !p.is_dir() => anyhow::bail!(
            "{flag} {}: {} exists and is not a folder, so nothing can be written below it",
            path.display(),
            p.display()
        ),
        _ => Ok(()),
    }
}

/// An `--out` folder a run writes into: made (with the parents it lacked), checked writable and locked
/// for the run (an advisory lock on the folder itself), so a second run into the same folder is refused
/// instead of mixing its outputs with this one's: two renders both exited 0 with frames of two sizes
/// beside one "complete" summary, two simulations with one grid's `frames.csv` beside the other's
/// `summary.csv`, and a read-only folder was found only after the whole grid ran (fault hunt, session 36).
/// The folders it made are removed (where still empty) unless the run succeeds.
pub(crate) struct OutFolder {
    /// The folders this run made, deepest first; emptied once the run succeeds.
    created: Vec<std::path::PathBuf>,
    /// `created`, registered for removal if the process is interrupted (a signal ends it without
    /// running `Drop`).
    live: Option<atlastree::util::LiveMadeFolders>,
    /// The folder, open for its lock until the run ends; `None` where a folder cannot be locked (not
    /// unix, or a file system without locks).
    _lock: Option<std::fs::File>,
}

impl OutFolder {
    /// Makes and locks `out` ([`check_out_folder`] first): an error naming the folder where another
    /// process holds it or it cannot be written.
    pub(crate) fn open(out: &std::path::Path) -> anyhow::Result<Self> {
        use anyhow::Context;
        // A link to a folder not made yet is followed, as `export -o` and `build -o` follow theirs: the
        // folder it names is made (`create_dir_all` of the link failed with "File exists"; fault hunt,
        // session 38), and its own parents are checked. The run writes through the link.
        reject_output_url(out, "--out")?;
        let out = &atlastree::util::follow_output_links(out)
            .with_context(|| format!("--out {}", out.display()))?;
        check_out_folder(out)?;
        let mut folder = OutFolder {
            created: (out.ancestors())
                .take_while(|p| !p.as_os_str().is_empty() && !p.exists())
                .map(std::path::Path::to_path_buf)
                .collect(),
            live: None,
            _lock: None,
        };
        folder.live = Some(atlastree::util::LiveMadeFolders::register(&folder.created));
        std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
        #[cfg(unix)]
        {
            let dir =
                std::fs::File::open(out).with_context(|| format!("opening {}", out.display()))?;
            match dir.try_lock() {
                Ok(()) => folder._lock = Some(dir),
                Err(std::fs::TryLockError::WouldBlock) => {
                    // Not ours to remove: the folder is the other run's now.
                    folder.created.clear();
                    folder.live = None;
                    anyhow::bail!(
                        "--out {}: another process holds this folder (another atlastree run writing into \
                         it? two runs into one folder would mix their outputs): wait for it to end, or \
                         name another folder",
                        out.display()
                    )
                }
                Err(std::fs::TryLockError::Error(_)) => {}
            }
        }
        tempfile::Builder::new()
            .prefix(".atlastree-write-check-")
            .tempfile_in(out)
            .with_context(|| format!("--out {}: cannot write into this folder", out.display()))?;
        Ok(folder)
    }

    /// Runs `f` while the folder is held; the folders [`OutFolder::open`] made stay only if it succeeds
    /// (a failed run that wrote something leaves that too: only empty folders are removed).
    pub(crate) fn run<T>(mut self, f: impl FnOnce() -> anyhow::Result<T>) -> anyhow::Result<T> {
        let result = f();
        if result.is_ok() {
            self.created.clear();
            self.live = None;
        }
        result
    }

    /// Makes `sub`, a folder inside this one, as part of the run: removed with the folders
    /// [`OutFolder::open`] made where the run fails or is interrupted, if it is empty then (a failed
    /// sweep left its new `--out` with an empty `builds/`; fault hunt, session 37).
    pub(crate) fn make(&mut self, sub: &std::path::Path) -> anyhow::Result<()> {
        use anyhow::Context;
        if sub.exists() {
            return Ok(());
        }
        self.created.insert(0, sub.to_path_buf());
        self.live = Some(atlastree::util::LiveMadeFolders::register(&self.created));
        std::fs::create_dir_all(sub).with_context(|| format!("creating {}", sub.display()))?;
        Ok(())
    }
}

impl Drop for OutFolder {
    fn drop(&mut self) {
        for dir in &self.created {
            let _ = std::fs::remove_dir(dir);
        }
    }
}

/// Imports a scene with a clear error naming the file, refusing in the node walk a scene of more
/// triangles than a build's plan could hold in all of this machine's memory (twice the build's default
/// budget, which these commands do not take): a 2.4 KB glTF whose nodes list one child twice at 25
/// levels instances 2²⁵ meshes, and `scene-info` aborted allocating 4.8 GB where `build` refused it.
pub(crate) fn load_scene(
    path: &std::path::Path,
    up: UpArg,
) -> anyhow::Result<atlastree::scene::Scene> {
    use atlastree::preprocess::memory::max_plan_triangles;
    let max = atlastree::util::memory_limit_bytes().map(max_plan_triangles);
    load_scene_within(path, up, max, None, None).map_err(|e| {
        match e.downcast_ref::<atlastree::scene::SceneError>() {
            Some(atlastree::scene::SceneError::OverTriangleBudget {
                file,
                triangles,
                instances,
                max,
                ..
            }) => anyhow::anyhow!(
                "{file}: {triangles} triangles over {instances} mesh instances, more than the {max} this \
                 machine's memory could build (nodes shared by many parents instance their meshes once per \
                 path; `build --max-memory` says what a build of it needs)"
            ),
            _ => e,
        }
    })
}

/// What the file at `path` is, where its first bytes say it is neither JSON text nor a GLB
/// ([`atlastree::store::describe_start`]); `None` for those (their parse error says more).
fn not_a_scene(path: &std::path::Path) -> Option<String> {
    use std::io::Read;
    // Room for a byte-order mark and a pretty-printer's indent before the first `{`.
    let mut head = Vec::with_capacity(256);
    std::fs::File::open(path)
        .and_then(|f| f.take(256).read_to_end(&mut head))
        .ok()?;
    let scene_like = atlastree::scene::looks_like_json(&head) || head.starts_with(b"glTF");
    // Described by its first bytes, as before the longer sniff.
    let start = &head[..head.len().min(16)];
    (!scene_like && !head.is_empty()).then(|| atlastree::store::describe_start(start))
}

/// [`load_scene`] refusing, during the node walk, a scene of more than `max_triangles`
/// ([`atlastree::scene::ImportOptions::max_triangles`]), and before parsing, glTF JSON of more than
/// `max_json_bytes`.
pub(crate) fn load_scene_within(
    path: &std::path::Path,
    up: UpArg,
    max_triangles: Option<u64>,
    max_json_bytes: Option<u64>,
    max_input_bytes: Option<u64>,
) -> anyhow::Result<atlastree::scene::Scene> {
    reject_scene_url(path)?;
    let opts = atlastree::scene::ImportOptions {
        up: up.to_option(),
        max_triangles,
        max_json_bytes,
        max_input_bytes,
    };
    atlastree::scene::import(path, &opts).map_err(|e| {
        // A file that is not JSON or GLB at all says what it is (a paging file given to `build` read
        // "expected value at line 1 column 1"; fault hunt, session 31), as `inspect` does of a scene.
        // So does one too large to read in the budget (a paging file is checked by its length first).
        use atlastree::scene::SceneError;
        if let SceneError::Parse { file, .. } | SceneError::OverInputBudget { file, .. } = &e
            && let Some(what) = not_a_scene(path)
        {
            return anyhow::anyhow!("{file}: not a glTF or GLB scene: {what}");
        }
        // Most scene errors already start with the file; name it once.
        let file = path.display().to_string();
        if e.to_string().contains(&file) {
            anyhow::Error::new(e)
        } else {
            anyhow::Error::new(e).context(format!("importing {file}"))
        }
    })
}
