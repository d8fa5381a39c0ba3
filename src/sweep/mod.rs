//! What accuracy costs in time: measure every knob that trades image fidelity for speed or memory on one
//! scene and camera path (issue 7).
//!
//! - `grid.rs`: the knobs and their values, a star around a base variant ([`Grid`], presets `small`
//!   and `full`, JSON files), expanded into builds and runtime variants ([`Plan`]).
//! - `run.rs` ([`run_sweep`]): builds each build-time variant once, renders each runtime variant over the same frames and
//!   compares every frame with the reference: the same view drawn with the original textures at their
//!   stored full resolution ([`crate::render::Mode::Original`], the naive renderer), on the base build,
//!   or ground truth (`SweepOptions::reference`: the same at S × S the pixels, box-filtered in linear
//!   light), against which each build's original textures are scored too. Produces plain rows
//!   ([`BuildRow`], [`FrameRow`]).
//! - [`summary`]: pure functions over the rows: per-variant means ([`summary::VariantRow`]), the Pareto
//!   front of accuracy against frame time, recommended defaults, the markdown report.
//! - [`output`]: `sweep.csv`, `frames.csv`, `builds.csv`, `report.md` and the plots (SVG + PNG).
//!
//! Accuracy measures per frame: PSNR over the whole frame and over the covered pixels (those the
//! texel-density pass drew on the reference view), SSIM (Gaussian 11×11, luma), the share of drawn
//! pixels whose texel density along the least-sampled direction is below 1 texel per pixel (magnified)
//! and below the variant's texel ratio, and, when paged, the screen share drawn coarser than selected.
//! Cost measures: build time per stage, file size, peak resident memory of the build, and per frame the
//! CPU select and encode µs, GPU ms (timestamp queries, when the device has them), frame ms and bytes
//! paged in.

mod grid;
pub mod output;
mod run;
pub mod summary;

pub use grid::{BuildKnobs, Grid, Plan, RuntimeKnobs};
pub use run::{
    BuildRow, FrameRow, NoSweepProgress, SweepData, SweepOptions, SweepProgress, check_capacities,
    merge_histogram, repeated_views, run_sweep, sample_path,
};

use crate::camera::CameraError;
use crate::preprocess::BuildError;
use crate::render::RenderError;
use crate::report::ReportError;
use crate::select::SelectError;
use crate::store::StoreError;
use std::path::PathBuf;

/// Errors of a sweep; each names the grid, build or variant it is about.
#[derive(Debug, thiserror::Error)]
pub enum SweepError {
    #[error("grid {origin}: {message}")]
    Grid { origin: String, message: String },
    #[error("build {build}: {source}")]
    Build {
        build: String,
        #[source]
        source: Box<BuildError>,
    },
    #[error("opening build {path}: {source}")]
    Open {
        path: PathBuf,
        #[source]
        source: StoreError,
    },
    #[error("variant {variant}, frame {frame}: {source}")]
    Render {
        variant: String,
        frame: usize,
        #[source]
        source: Box<RenderError>,
    },
    #[error("variant {variant}: {source}")]
    Scale {
        variant: String,
        #[source]
        source: SelectError,
    },
    #[error("camera path: {0}")]
    Camera(#[from] CameraError),
    #[error("variant {variant}, frame {frame}: {source}")]
    Metric {
        variant: String,
        frame: usize,
        #[source]
        source: ReportError,
    },
    #[error(transparent)]
    Report(#[from] ReportError),
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("the scene has no vertices: no camera path can be made")]
    EmptyScene,
}
