//! Reporting building blocks for experiments (`simulate`, `sweep`): image metrics, CSV tables and plots.
//!
//! - [`metrics`]: PSNR and SSIM of RGBA8 frames, shares and log2 histograms of the texel-per-pixel
//!   density pass ([`crate::render::density`]), the Pareto front of (cost, accuracy) points. Pure CPU.
//! - [`supersample`]: the supersampled reference's box filter in linear light (CPU twin of the GPU pass).
//! - [`columns`]: the one schema of per-frame counters (plan, renderer, paging) every per-frame CSV writes.
//! - [`csv`]: deterministic CSV tables (fixed float formatting), written atomically; a reader for tests.
//! - [`plot`]: line charts, heat maps, scatter plots with a marked Pareto front and bar charts, each
//!   written as `NAME.svg` and `NAME.png` (temp file + rename) with an embedded font, so the pictures are
//!   byte-identical on any machine, with or without system fonts.
//!
//! Every output file appears whole or not at all: written to a temp file in the same directory, then
//! renamed over the target.

pub mod columns;
pub mod csv;
pub mod metrics;
pub mod plot;
pub mod supersample;

use std::path::{Path, PathBuf};

/// Errors of the report module; each names the file or input it is about.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    /// Reading or writing `path` failed.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        source: std::io::Error,
    },
    /// An RGBA8 buffer does not hold `width × height × 4` bytes.
    #[error("{what}: {len} bytes, but a {width}×{height} RGBA8 frame has {expected}")]
    FrameSize {
        what: &'static str,
        len: usize,
        width: u32,
        height: u32,
        expected: usize,
    },
    /// A frame is smaller than the SSIM window in one dimension.
    #[error("SSIM needs frames of at least {window}×{window} pixels, got {width}×{height}")]
    FrameTooSmall {
        width: u32,
        height: u32,
        window: u32,
    },
    /// A mask or density buffer has the wrong length.
    #[error("{what}: {len} entries, expected {expected}")]
    Length {
        what: &'static str,
        len: usize,
        expected: usize,
    },
    /// A CSV row has the wrong number of cells, or the file is malformed.
    #[error("{path}:{line}: {message}")]
    Csv {
        path: PathBuf,
        line: usize,
        message: String,
    },
    /// The plot input cannot be drawn (no finite point, mismatched lengths, …).
    #[error("plot {path}: {message}")]
    PlotInput { path: PathBuf, message: String },
    /// plotters failed while drawing.
    #[error("plot {path}: drawing failed: {message}")]
    Draw { path: PathBuf, message: String },
}

impl ReportError {
    pub(crate) fn io(path: &Path, source: std::io::Error) -> ReportError {
        ReportError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// Writes `bytes` to `path` atomically ([`crate::util::write_atomic`]). The parent directory must exist.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ReportError> {
    crate::util::write_atomic(path, bytes).map_err(|e| ReportError::io(path, e))
}
