//! Subcommands. Each `*Args` struct is the clap view, with flag groups shared between commands in
//! [`args`]; a command's validate step turns its parsed flags into a checked configuration (refusing a
//! flag that means nothing for it, with a message), and its `run` only runs.

mod args;
mod build_cmd;
mod demo;
mod export_cmd;
mod inspect_cmd;
mod merge_cmd;
mod os_limits;
mod progress;
mod render_cmd;
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
    propagate_version = true
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub(crate) enum Command {
    /// Run the whole pipeline on the embedded default scene (data/city) and show what each stage did.
    Demo(demo::DemoArgs),
    /// Summarise a glTF scene: triangles, textures, UV ranges and repeats, wrap and alpha modes, planarity.
    SceneInfo(scene_info::SceneInfoArgs),
    /// Preprocess a glTF scene into a texture-atlas tree paging file (paper §5).
    Build(build_cmd::BuildArgs),
    /// Merge the shard files of a sharded build (`build --shard I/N`) into the paging file, byte-identical
    /// to a one-process build.
    Merge(merge_cmd::MergeArgs),
    /// Show a paging file's tree shape and per-level statistics; `--verify` checks every checksum and
    /// invariant and exits non-zero on any violation.
    Inspect(inspect_cmd::InspectArgs),
    /// Render a camera path offscreen with the texture-array-batched renderer; PNGs, contact sheet, stats.csv.
    Render(render_cmd::RenderArgs),
    /// Paging-budget experiments without a GPU: capacity × bandwidth × latency × policy over a camera path.
    Simulate(simulate_cmd::SimulateArgs),
    /// Export a paging file for other viewers: `export 3dtiles FILE -o DIR` writes a 3D Tiles 1.1
    /// tileset (CesiumJS, 3DTilesRendererJS, …) with one tile per node and the original textures below the
    /// leaves.
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
    View(view_cmd::ViewArgs),
    /// What accuracy costs in time: build and render a grid of knob values on one scene and path, compare
    /// every frame with the original textures; sweep.csv, frames.csv, report.md and Pareto plots.
    Sweep(sweep_cmd::SweepArgs),
}

/// Which axis points up (the other two span the distribution plane).
#[derive(Copy, Clone, Debug, Default, ValueEnum)]
pub(crate) enum UpArg {
    /// The axis of least extent.
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
    let filter = tracing_subscriber::EnvFilter::try_from_env("ATLASTREE_LOG")
        .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new("warn"));
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
        // Ctrl-C, or SIGTERM from a scheduler cancelling a job, ends the process with 130 and no temp file
        // left (a paging file's is its whole length, reserved up front). `serve` handles Ctrl-C itself.
        let _ = ctrlc::set_handler(|| {
            atlastree::util::remove_live_temps_and_exit(130, |removed| {
                // Said, so an interrupted step is not read as a finished one (it ended without a word).
                eprintln!(
                    "interrupted: stopped before finishing; {removed} unfinished output(s) removed, \
                     earlier outputs left as they were"
                );
            })
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
    let names: Vec<String> = scene
        .materials
        .iter()
        .take(8)
        .map(|m| m.name.clone())
        .collect();
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

/// An http(s) URL that is not also a local path gets a clear error (only `render` pages over HTTP)
/// instead of "No such file or directory".
pub(crate) fn reject_url(path: &std::path::Path, command: &str) -> anyhow::Result<()> {
    if path.exists() {
        return Ok(());
    }
    let raw = path.to_string_lossy();
    let text = atlastree::paging::redact_url(&raw);
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

/// Before any work: `--out` must be a folder or not exist yet (a file there failed only when the outputs
/// were written, as "File exists (os error 17)" or "Not a directory").
pub(crate) fn check_out_folder(out: &std::path::Path) -> anyhow::Result<()> {
    if out.exists() && !out.is_dir() {
        anyhow::bail!(
            "--out {}: exists and is not a folder (the outputs go into a folder: name a new or existing one)",
            out.display()
        );
    }
    Ok(())
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
    load_scene_within(path, up, max).map_err(|e| {
        match e.downcast_ref::<atlastree::scene::SceneError>() {
            Some(atlastree::scene::SceneError::OverTriangleBudget {
                file,
                triangles,
                instances,
                max,
            }) => anyhow::anyhow!(
                "{file}: {triangles} triangles over {instances} mesh instances, more than the {max} this \
                 machine's memory could build (nodes shared by many parents instance their meshes once per \
                 path; `build --max-memory` says what a build of it needs)"
            ),
            _ => e,
        }
    })
}

/// [`load_scene`] refusing, during the node walk, a scene of more than `max_triangles`
/// ([`atlastree::scene::ImportOptions::max_triangles`]).
pub(crate) fn load_scene_within(
    path: &std::path::Path,
    up: UpArg,
    max_triangles: Option<u64>,
) -> anyhow::Result<atlastree::scene::Scene> {
    let opts = atlastree::scene::ImportOptions {
        up: up.to_option(),
        max_triangles,
    };
    atlastree::scene::import(path, &opts).map_err(|e| {
        // Most scene errors already start with the file; name it once.
        let file = path.display().to_string();
        if e.to_string().contains(&file) {
            anyhow::Error::new(e)
        } else {
            anyhow::Error::new(e).context(format!("importing {file}"))
        }
    })
}
