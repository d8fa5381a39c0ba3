use super::args::{Capacity, PagingArgs, WindowArgs};
use anyhow::{Context, bail};
use atlastree::camera::{Camera, Ground, PathKind};
use atlastree::render::Mode;
use atlastree::store::TreeFile;
use atlastree::view::{ViewOptions, ViewReport};
use clap::Args;
use glam::DVec3;
use std::path::PathBuf;
use std::process::ExitCode;

// Its --help text is the doc comment of `cli::Command::View` (clap shows the variant's, not this struct's).
#[derive(Args, Debug)]
// `render`'s paging flags beyond --capacity are refused here ("means nothing for view"): not listed.
#[command(
    mut_arg("source", |a| a.hide(true)),
    mut_arg("upload_budget", |a| a.hide(true)),
    mut_arg("max_queue", |a| a.hide(true)),
    mut_arg("policy", |a| a.hide(true)),
    mut_arg("loader_threads", |a| a.hide(true)),
    mut_arg("http_timeout", |a| a.hide(true)),
    mut_arg("http_retries", |a| a.hide(true))
)]
pub(crate) struct ViewArgs {
    /// The paging file.
    pub file: PathBuf,
    /// Start mode: tree (the product), original (naive per-texture draws), dummy (the tree's draws with one texture and a trivial fragment shader),
    /// tree-levels (tree with level colouring).
    #[arg(long, default_value = "tree")]
    pub mode: Mode,
    /// Follow a camera path (overview-dive, street, orbit, or a keyframe JSON file, e.g. one recorded
    /// with R). Moving the camera leaves follow mode; the inspector's "follow" resumes it.
    #[arg(long)]
    pub path: Option<String>,
    /// Follow the path in fixed steps: frame i shows path time start + i / FPS (as `render --fps`),
    /// instead of in real time.
    #[arg(long, requires = "path")]
    pub path_fps: Option<f64>,
    /// Start camera `EX,EY,EZ,TX,TY,TZ[,FOV]`: eye, target (world units) and horizontal field of view
    /// (degrees, default 60). The near plane is 0.25 units, the far plane reaches the scene's farthest
    /// corner (at least 100 km). Default: frame the whole scene.
    #[arg(long, conflicts_with = "path", allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Write a screenshot of the N-th frame (1 = the first) to --screenshot.
    #[arg(long, value_name = "N")]
    pub screenshot_after: Option<u64>,
    /// Quit after the --screenshot-after screenshot.
    #[arg(long, requires = "screenshot_after")]
    pub exit: bool,
    /// File of the --screenshot-after screenshot [default: OUT/screenshot.png].
    #[arg(long, requires = "screenshot_after")]
    pub screenshot: Option<PathBuf>,
    /// Directory for P screenshots and recorded paths.
    #[arg(long, default_value = "out/view")]
    pub out: PathBuf,
    /// Start with the inspector hidden (H toggles it).
    #[arg(long)]
    pub hide_overlay: bool,
    /// Start with the node bounds of the cut drawn (B toggles them).
    #[arg(long)]
    pub bounds: bool,
    /// Present as fast as possible instead of waiting for vertical sync.
    #[arg(long)]
    pub no_vsync: bool,
    /// Skip GPU timestamp queries.
    #[arg(long)]
    pub no_gpu_timing: bool,
    /// Print the session report as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Initial window size and texel ratio (the inspector's slider changes the ratio live).
    #[command(flatten, next_help_heading = "Viewport")]
    pub viewport: WindowArgs,
    /// `--capacity K` pages blocks (paper §6) with at most k resident, loaded from the file by two loader
    /// threads with the paper policy; the inspector shows the paging counters and its capacity slider
    /// changes k live (up to this k). Without it (or with `--capacity all`) every block is uploaded at
    /// start and the paging rows read n/a. The other paging flags are `render`'s.
    #[command(flatten, next_help_heading = "Paging")]
    pub paging: PagingArgs,
}

/// Parses `EX,EY,EZ,TX,TY,TZ[,FOV]`.
fn parse_camera(s: &str, up: DVec3) -> anyhow::Result<Camera> {
    let v: Vec<f64> = s
        .split(',')
        .map(|p| p.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .with_context(|| format!("--camera {s:?}: expected numbers EX,EY,EZ,TX,TY,TZ[,FOV]"))?;
    let (eye, target, fov) = match v.as_slice() {
        [ex, ey, ez, tx, ty, tz] => (DVec3::new(*ex, *ey, *ez), DVec3::new(*tx, *ty, *tz), 60.0),
        [ex, ey, ez, tx, ty, tz, fov] => {
            (DVec3::new(*ex, *ey, *ez), DVec3::new(*tx, *ty, *tz), *fov)
        }
        _ => bail!(
            "--camera {s:?}: expected 6 or 7 numbers (EX,EY,EZ,TX,TY,TZ[,FOV]), got {}",
            v.len()
        ),
    };
    if !(eye.is_finite() && target.is_finite()) || eye == target {
        bail!("--camera {s:?}: eye and target must be finite and different");
    }
    if !(atlastree::camera::MIN_FOV_DEG..180.0).contains(&fov) {
        bail!(
            "--camera {s:?}: field of view {fov}° is outside [{}°, 180°)",
            atlastree::camera::MIN_FOV_DEG
        );
    }
    Ok(Camera {
        eye,
        target,
        up,
        fov_x_deg: fov,
        aspect: 1.0,
        near: 0.25,
        far: 1.0e5,
    })
}

impl ViewArgs {
    /// The checks that need no file: refused flags, ranges.
    fn check_flags(&self) -> anyhow::Result<()> {
        self.viewport.validate()?;
        if let Some(flag) = self.paging.given_beyond_capacity() {
            bail!(
                "{flag} means nothing for view: it pages from the file with two loader threads, the paper \
                 policy and the default queue (only --capacity applies; use `render` for the others)"
            );
        }
        if let Some(f) = self.path_fps {
            super::args::check_fps("--path-fps", f)?;
        }
        if self.screenshot_after == Some(0) {
            bail!("--screenshot-after counts frames from 1");
        }
        super::check_out_folder(&self.out)?;
        if let Some(shot) = &self.screenshot {
            super::reject_output_url(shot, "--screenshot")?;
            super::check_parent_folders(shot, "--screenshot")?;
        }
        Ok(())
    }

    /// Checks the flags and derives the viewer's options (the path and camera resolved on `file`).
    fn validate(&self, file: &TreeFile) -> anyhow::Result<ViewOptions> {
        self.check_flags()?;
        let viewport = self.viewport.validate()?;
        let params = file.to_params();
        let path = match &self.path {
            Some(p) => Some(
                p.parse::<PathKind>()?
                    .resolve_with(|| Ground::from_tree(file))?,
            ),
            None => None,
        };
        let camera = self
            .camera
            .as_deref()
            .map(|s| parse_camera(s, params.up.vector()))
            .transpose()?;
        Ok(ViewOptions {
            width: viewport.width,
            height: viewport.height,
            mode: self.mode,
            texel_ratio: viewport.texel_ratio,
            capacity: self.paging.capacity.and_then(Capacity::blocks),
            camera,
            path,
            path_fps: self.path_fps,
            screenshot_after: self.screenshot_after,
            exit_after_screenshot: self.exit,
            screenshot: self
                .screenshot
                .clone()
                .unwrap_or_else(|| self.out.join("screenshot.png")),
            out_dir: self.out.clone(),
            hide_overlay: self.hide_overlay,
            bounds: self.bounds,
            vsync: !self.no_vsync,
            gpu_timing: !self.no_gpu_timing,
        })
    }
}

pub(super) fn run(a: ViewArgs) -> anyhow::Result<ExitCode> {
    a.check_flags()?;
    // The tables in memory, as `render` (a file truncated under a long session: SIGBUS).
    let file = super::open_local(&a.file, "view", atlastree::store::LoadMode::Tables)?;
    let opts = a.validate(&file)?;
    let report = atlastree::view::run(&file, opts)?;
    print_report(&report, a.json);
    Ok(ExitCode::SUCCESS)
}

fn print_report(r: &ViewReport, json: bool) {
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    if json {
        let v = serde_json::json!({
            "adapter": r.adapter,
            "frames": r.frames,
            "size": [r.size.0, r.size.1],
            "fps": r.fps,
            "screenshots": r.screenshots.iter().map(|(p, s)| serde_json::json!({
                "file": p.display().to_string(),
                "source": s.name(),
            })).collect::<Vec<_>>(),
            "recordings": r.recordings.iter().map(|p| p.display().to_string()).collect::<Vec<_>>(),
            "warnings": r.warnings,
        });
        println!("{v}");
        return;
    }
    println!(
        "view: {} frames at {:.1} fps, {}x{}, adapter {}",
        r.frames, r.fps, r.size.0, r.size.1, r.adapter
    );
    for (p, source) in &r.screenshots {
        println!("screenshot: {} (from the {})", p.display(), source.name());
    }
    for p in &r.recordings {
        println!("recorded path: {}", p.display());
    }
}
