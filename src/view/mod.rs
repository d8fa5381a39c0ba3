//! `atlastree view`: an interactive fly-through window over a paging file with a live inspector.
//!
//! The window (winit) shows the frames of the same [`crate::render::Renderer`] as `atlastree render`: one
//! plan of the [`crate::plan::FramePlanner`] per frame on the wall clock, executed into the renderer's
//! offscreen target ([`crate::render::FrameLoop`]), copied into a composite image, the egui
//! inspector ([`overlay`]) drawn on top, and blitted into the window's surface (`present`,
//! `shaders/blit.wgsl`). Camera: fly/orbit controls, framing and recording ([`controls`]), or following a
//! [`CameraPath`].
//!
//! Keys: `W A S D` move, `Q E` down/up, `Shift` fast, drag to look, wheel for speed (orbit: distance),
//! `O` fly/orbit, `F` frame the scene, `1 2 3` tree/original/dummy, `L` level colours, `B` node bounds,
//! `G` freeze the selection, `H` hide the inspector, `P` screenshot (PNG), `R` start/stop recording the
//! flown path (JSON), `Esc` quit.
//!
//! Paging: all blocks are resident until the pager lands; the inspector shows its counters as n/a and the
//! capacity slider disabled ([`overlay::PagingStats`] is what a pager reports per frame).

mod app;
pub mod controls;
pub mod overlay;
mod present;

pub use app::{run, window_panic_caught};
pub use present::ShotSource;

use crate::camera::{Camera, CameraError, CameraPath};
use crate::gpu::GpuError;
use crate::render::{Mode, RenderError};
use crate::select::SelectError;
use crate::store::TreeFile;
use glam::DVec3;
use std::path::PathBuf;

/// What the viewer starts with.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// Initial window size, physical pixels (the window manager may change it).
    pub width: u32,
    pub height: u32,
    /// Tree, Original or Dummy; [`Mode::TreeLevels`] starts in tree mode with level colouring on.
    pub mode: Mode,
    /// Required texels per pixel at start.
    pub texel_ratio: f64,
    /// Block capacity `k` for the pager (`None`: every block resident).
    pub capacity: Option<u32>,
    /// Initial camera; `None` frames the scene (or starts the path).
    pub camera: Option<Camera>,
    /// Camera path to follow from the start.
    pub path: Option<CameraPath>,
    /// Follow the path in fixed steps of `1 / path_fps` seconds per frame (frame `i` shows path time
    /// `start + i / path_fps`, as `render --fps`) instead of in real time.
    pub path_fps: Option<f64>,
    /// Write a screenshot to `screenshot` after this many frames.
    pub screenshot_after: Option<u64>,
    /// Quit after that screenshot.
    pub exit_after_screenshot: bool,
    /// File of the `screenshot_after` screenshot.
    pub screenshot: PathBuf,
    /// Directory for `P` screenshots and recorded paths.
    pub out_dir: PathBuf,
    /// Start with the inspector hidden (`H` shows it).
    pub hide_overlay: bool,
    /// Start with node bounds drawn.
    pub bounds: bool,
    /// Wait for vertical sync when presenting.
    pub vsync: bool,
    /// Measure GPU time with timestamp queries where supported.
    pub gpu_timing: bool,
}

/// What a viewer session did (for the CLI's report).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ViewReport {
    pub adapter: String,
    pub frames: u64,
    /// Final window size, physical pixels.
    pub size: (u32, u32),
    /// Screenshots written, with where their pixels came from.
    pub screenshots: Vec<(PathBuf, ShotSource)>,
    /// Camera paths written by `R`.
    pub recordings: Vec<PathBuf>,
    /// Mean frames per second over the session.
    pub fps: f64,
    /// What went wrong while paging (the first failed block load, the last failed residency change),
    /// drawn coarser meanwhile: `view --capacity` on a file with corrupt blocks drew a degraded frame
    /// and said nothing (fault hunt, session 37).
    pub warnings: Vec<String>,
}

/// winit's reason without where in winit it was raised: its `OsError` prints
/// "os error at …/winit-0.30.13/src/platform_impl/linux/mod.rs:765: why", a path on the machine that built
/// the binary.
fn winit_reason(text: &str) -> String {
    match text.find(".rs:") {
        Some(i) => text[i..]
            .split_once(": ")
            .map_or(text, |(_, why)| why)
            .to_string(),
        None => text.to_string(),
    }
}

impl From<winit::error::EventLoopError> for ViewError {
    fn from(e: winit::error::EventLoopError) -> Self {
        ViewError::EventLoop {
            reason: winit_reason(&e.to_string()),
        }
    }
}

impl From<winit::error::OsError> for ViewError {
    fn from(e: winit::error::OsError) -> Self {
        ViewError::Window {
            reason: winit_reason(&e.to_string()),
        }
    }
}

/// Errors of the viewer.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    /// No window system: no `DISPLAY`/`WAYLAND_DISPLAY`, or the connection failed.
    #[error("cannot open the window system (is DISPLAY or WAYLAND_DISPLAY set?): {reason}")]
    EventLoop { reason: String },
    #[error("cannot create the window: {reason}")]
    Window { reason: String },
    /// The window system failed under a running session (an X server that went away: winit panics
    /// where its connection fails; the panic was a backtrace and exit 101, fault hunt session 37).
    #[error(
        "the window system failed while viewing (did the X server or Wayland compositor go away?): {reason}"
    )]
    WindowSystem { reason: String },
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Select(#[from] SelectError),
    #[error(transparent)]
    Camera(#[from] CameraError),
    #[error("window surface: {message}")]
    Surface { message: String },
    #[error("{path}: {message}")]
    Write { path: PathBuf, message: String },
    #[error("the paging file has no nodes, there is nothing to view")]
    EmptyFile,
}

/// Union of the root bounds of every tree, `None` for a file without nodes.
pub fn scene_bounds(file: &TreeFile) -> Option<(DVec3, DVec3)> {
    (0..file.trees())
        .filter_map(|t| file.tree(t)?.nodes.first().copied())
        .map(|root| {
            (
                DVec3::from_array(root.bounds_min),
                DVec3::from_array(root.bounds_max),
            )
        })
        .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn winit_reasons_drop_the_source_location() {
        let raw = "os error at /root/.cargo/registry/src/index.crates.io-1/winit-0.30.13/src/platform_impl/linux/\
                   mod.rs:765: neither WAYLAND_DISPLAY nor DISPLAY is set";
        assert_eq!(
            winit_reason(raw),
            "neither WAYLAND_DISPLAY nor DISPLAY is set"
        );
        assert_eq!(winit_reason("no display"), "no display");
    }
}
