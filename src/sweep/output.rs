//! The sweep's files: `sweep.csv` (one row per variant, means), `frames.csv` (per variant and frame),
//! `builds.csv` (per build, stage times), `report.md`, and the plots (SVG + PNG, each written atomically).

use super::SweepError;
use super::run::{BuildRow, FrameRow, SweepData};
use super::summary::{ReportContext, VariantRow, markdown, summarise};
use crate::render::FrameStats;
use crate::render::reference::Reference;
use crate::report::columns;
use crate::report::csv::{Cell, write_csv};
use crate::report::plot::{
    Better, LabelledPoint, PlotOptions, PointLabels, ScatterSeries, Series, histogram_chart,
    line_chart, scatter_pareto,
};
use crate::report::write_atomic;
use std::path::{Path, PathBuf};

/// Columns of `sweep.csv`.
pub const SWEEP_HEADER: [&str; 30] = [
    "variant",
    "d_min_ratio",
    "atlas_size",
    "border",
    "filter",
    "compress",
    "repeat",
    "alpha_mips",
    "texel_ratio",
    "capacity",
    "frames",
    "psnr_db",
    "psnr_covered_db",
    "ssim",
    "original_psnr_db",
    "original_psnr_covered_db",
    "original_ssim",
    "magnified_share",
    "below_target_share",
    "coarser_share",
    "select_us",
    "encode_us",
    "gpu_ms",
    "frame_ms",
    "frame_ms_median",
    "bytes_loaded",
    "file_bytes",
    "build_s",
    "peak_build_rss_bytes",
    "build",
];

/// The columns of `frames.csv` before the per-frame counters: the variant and what it was compared with.
const FRAME_KEY_HEADER: [&str; 15] = [
    "variant",
    "build",
    "texel_ratio",
    "capacity",
    "frame",
    "time_s",
    "psnr_db",
    "psnr_covered_db",
    "covered_pixels",
    "ssim",
    "original_psnr_db",
    "original_psnr_covered_db",
    "original_ssim",
    "magnified_share",
    "below_target_share",
];

/// The columns of one `frames.csv` row after its key: the frame's counters and timings, then its paging
/// counters (empty cells for variants with every block resident), both through [`columns`].
fn frame_counters(stats: &FrameStats) -> Vec<columns::Column> {
    let mut c = crate::render::frame_columns(stats);
    c.extend(columns::paging_columns_or_empty(stats.paging()));
    c
}

/// Columns of `frames.csv`.
pub fn frames_header() -> Vec<&'static str> {
    let mut h = FRAME_KEY_HEADER.to_vec();
    h.extend(columns::names(&frame_counters(&FrameStats::default())));
    h
}

fn capacity_cell(c: Option<u32>) -> Cell {
    c.map_or(Cell::Text("all".into()), |k| Cell::UInt(u64::from(k)))
}

fn sweep_row(r: &VariantRow) -> Vec<Cell> {
    vec![
        Cell::Text(r.id.clone()),
        Cell::Float(r.build.d_min_ratio),
        Cell::UInt(u64::from(r.build.atlas_size)),
        Cell::UInt(u64::from(r.build.border)),
        Cell::Text(r.build.filter.name().into()),
        Cell::Text(r.build.compress.label().into()),
        Cell::Text(r.build.repeat.label().into()),
        Cell::Text(r.build.alpha_mips.name().into()),
        Cell::Float(r.runtime.texel_ratio),
        capacity_cell(r.runtime.capacity),
        Cell::UInt(r.frames as u64),
        Cell::Float(r.psnr_db),
        measured(r.psnr_covered_db),
        Cell::Float(r.ssim),
        measured(r.original_psnr_db),
        measured(r.original_psnr_covered_db),
        measured(r.original_ssim),
        Cell::Float(r.magnified_share),
        Cell::Float(r.below_target_share),
        Cell::Float(r.coarser_share),
        Cell::Float(r.select_us),
        Cell::Float(r.encode_us),
        Cell::Float(r.gpu_ms),
        Cell::Float(r.frame_ms),
        Cell::Float(r.frame_ms_median),
        Cell::UInt(r.bytes_loaded),
        Cell::UInt(r.file_bytes),
        Cell::Float(r.build_s),
        r.peak_rss_bytes
            .map_or(Cell::Text(String::new()), Cell::UInt),
        Cell::Text(r.build.id()),
    ]
}

/// A measure that is NaN where it was not taken (the original's, without a reference): an empty cell, as
/// other columns write what they lack, not `nan`.
fn measured(v: f64) -> Cell {
    if v.is_nan() {
        Cell::Text(String::new())
    } else {
        Cell::Float(v)
    }
}

fn frame_row(f: &FrameRow) -> Vec<Cell> {
    let mut row = vec![
        Cell::Text(f.variant_id()),
        Cell::Text(f.build.id()),
        Cell::Float(f.runtime.texel_ratio),
        capacity_cell(f.runtime.capacity),
        Cell::UInt(f.frame as u64),
        Cell::Float(f.time_s),
        Cell::Float(f.psnr_db),
        measured(f.psnr_covered_db),
        Cell::UInt(f.covered_pixels),
        Cell::Float(f.ssim),
        measured(f.original_psnr_db),
        measured(f.original_psnr_covered_db),
        measured(f.original_ssim),
        Cell::Float(f.magnified_share),
        Cell::Float(f.below_target_share),
    ];
    row.extend(columns::cells(frame_counters(&f.stats)));
    row
}

/// `builds.csv`: knobs, size, shape, build seconds, peak memory and one column per stage.
fn write_builds(path: &Path, builds: &[BuildRow]) -> Result<(), SweepError> {
    let mut stages: Vec<String> = Vec::new();
    for b in builds {
        for (n, _) in &b.stage_s {
            if !stages.contains(n) {
                stages.push(n.clone());
            }
        }
    }
    let stage_cols: Vec<String> = stages
        .iter()
        .map(|s| format!("{}_s", s.to_lowercase().replace(' ', "_")))
        .collect();
    let mut header: Vec<&str> = vec![
        "build",
        "d_min_ratio",
        "atlas_size",
        "border",
        "filter",
        "compress",
        "repeat",
        "alpha_mips",
        "file_bytes",
        "nodes",
        "leaves",
        "depth",
        "blocks",
        "build_s",
        "peak_rss_bytes",
    ];
    header.extend(stage_cols.iter().map(String::as_str));
    let rows: Vec<Vec<Cell>> = builds
        .iter()
        .map(|b| {
            let mut row = vec![
                Cell::Text(b.knobs.id()),
                Cell::Float(b.knobs.d_min_ratio),
                Cell::UInt(u64::from(b.knobs.atlas_size)),
                Cell::UInt(u64::from(b.knobs.border)),
                Cell::Text(b.knobs.filter.name().into()),
                Cell::Text(b.knobs.compress.label().into()),
                Cell::Text(b.knobs.repeat.label().into()),
                Cell::Text(b.knobs.alpha_mips.name().into()),
                Cell::UInt(b.file_bytes),
                Cell::UInt(b.nodes),
                Cell::UInt(b.leaves),
                Cell::UInt(u64::from(b.depth)),
                Cell::UInt(b.blocks),
                Cell::Float(b.build_s),
                b.peak_rss_bytes
                    .map_or(Cell::Text(String::new()), Cell::UInt),
            ];
            for s in &stages {
                let v = b.stage_s.iter().find(|(n, _)| n == s).map(|(_, v)| *v);
                row.push(Cell::Float(v.unwrap_or(f64::NAN)));
            }
            row
        })
        .collect();
    write_csv(path, &header, &rows)?;
    Ok(())
}

/// Scatter groups of the variants by build, with `x` from `cost`.
fn by_build(rows: &[VariantRow], cost: &dyn Fn(&VariantRow) -> f64) -> Vec<ScatterSeries> {
    let mut groups: Vec<ScatterSeries> = Vec::new();
    for r in rows {
        let name = r.build.id();
        let point = LabelledPoint {
            x: cost(r),
            y: r.psnr_covered_db,
            label: r.runtime.id(),
        };
        match groups.iter_mut().find(|g| g.name == name) {
            Some(g) => g.points.push(point),
            None => groups.push(ScatterSeries {
                name,
                points: vec![point],
            }),
        }
    }
    groups
}

/// Writes the plots into `dir`; returns (file stem, caption) of each.
fn write_plots(
    dir: &Path,
    data: &SweepData,
    rows: &[VariantRow],
) -> Result<Vec<(String, String)>, SweepError> {
    let mut plots = Vec::new();
    let psnr = match data.reference {
        Reference::Original => "covered PSNR vs original textures (dB)",
        Reference::Supersampled(_) => "covered PSNR vs supersampled reference (dB)",
    };
    let scatter = |stem: &str, title: &str, x: &str, cost: &dyn Fn(&VariantRow) -> f64| {
        let mut o = PlotOptions::new(title, x, psnr);
        o.log_x = true;
        scatter_pareto(
            &dir.join(stem),
            &o,
            &by_build(rows, cost),
            Better::HigherY,
            PointLabels::Front,
        )
        .map(|_| ())
    };
    let measured = !data.measures_nothing();
    if measured {
        scatter(
            "pareto_frame_time",
            "Accuracy vs frame time (Pareto front marked)",
            "median frame time (ms, log)",
            &|r| r.frame_ms_median,
        )?;
        plots.push((
            "pareto_frame_time".into(),
            "Accuracy vs median frame time; the black line is the Pareto front".into(),
        ));
        scatter(
            "accuracy_vs_file_size",
            "Accuracy vs paging-file size",
            "file size (MiB, log)",
            &|r| r.file_bytes as f64 / f64::from(1u32 << 20),
        )?;
        plots.push((
            "accuracy_vs_file_size".into(),
            "Accuracy vs file size".into(),
        ));
        scatter(
            "accuracy_vs_build_time",
            "Accuracy vs build time",
            "build time (s, log)",
            &|r| r.build_s,
        )?;
        plots.push((
            "accuracy_vs_build_time".into(),
            "Accuracy vs build time".into(),
        ));
    }
    // PSNR against the texel ratio, one line per build (everything resident).
    let mut series: Vec<Series> = Vec::new();
    for b in &data.builds {
        let mut pts: Vec<(f64, f64)> = rows
            .iter()
            .filter(|r| r.build == b.knobs && r.runtime.capacity.is_none())
            .map(|r| (r.runtime.texel_ratio, r.psnr_covered_db))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        if pts.len() > 1 {
            series.push(Series::new(b.knobs.id(), pts));
        }
    }
    if measured && !series.is_empty() {
        let mut o = PlotOptions::new("Accuracy vs texel ratio", "texel ratio (log)", psnr);
        o.log_x = true;
        line_chart(&dir.join(OPTIONAL_PLOTS[0]), &o, &series)?;
        plots.push((
            "accuracy_vs_texel_ratio".into(),
            "Covered PSNR against the runtime texel ratio, per build".into(),
        ));
    }
    // Texel-per-pixel histograms of the base build's non-paged variants.
    if let Some(base) = data.builds.first() {
        let hists = base_histograms(&base.knobs, &data.histograms);
        if !hists.is_empty() {
            let o = PlotOptions::new(
                format!(
                    "Texels per pixel (least-sampled direction), build {}",
                    base.knobs.id()
                ),
                "texels per pixel (log2 bins)",
                "share of drawn pixels",
            );
            histogram_chart(&dir.join(OPTIONAL_PLOTS[1]), &o, &hists)?;
            plots.push((
                "texel_density_histograms".into(),
                "Texel-per-pixel histograms of the base build per texel ratio".into(),
            ));
        }
    }
    Ok(plots)
}

/// The histograms of build `base`'s variants, labelled by their runtime id.
fn base_histograms<'a>(
    base: &super::BuildKnobs,
    histograms: &'a [(
        super::BuildKnobs,
        super::RuntimeKnobs,
        crate::report::metrics::Histogram,
    )],
) -> Vec<(String, &'a crate::report::metrics::Histogram)> {
    (histograms.iter())
        .filter(|(b, _, _)| b == base)
        .map(|(_, r, h)| (r.id(), h))
        .collect()
}

/// The plots [`write_outputs`] draws only when the grid has their data: every accuracy plot only where
/// some frame covers the scene (with none, every covered PSNR is NaN and nothing is plotted; the sweep
/// failed on "no finite point to plot" before its report; review, session 38).
const OPTIONAL_PLOTS: [&str; 5] = [
    "accuracy_vs_texel_ratio",
    "texel_density_histograms",
    "pareto_frame_time",
    "accuracy_vs_file_size",
    "accuracy_vs_build_time",
];

/// Writes every output file of a sweep into `dir` (created if missing); returns the variant rows and the
/// paths written.
pub fn write_outputs(
    dir: &Path,
    data: &SweepData,
    scene: &str,
    path: &str,
) -> Result<(Vec<VariantRow>, Vec<PathBuf>), SweepError> {
    std::fs::create_dir_all(dir).map_err(|e| SweepError::Io {
        path: dir.to_path_buf(),
        source: e,
    })?;
    // The plots a grid may not draw (one texel ratio, no histogram): an earlier sweep's would stay beside
    // this report. Only where an earlier sweep reported here (its sweep.csv; review of session 34).
    let optional = |n: &str| {
        OPTIONAL_PLOTS.iter().any(|p| {
            n.strip_prefix(p)
                .is_some_and(|ext| ext == ".png" || ext == ".svg")
        })
    };
    crate::util::remove_earlier_outputs(dir, &dir.join("sweep.csv"), optional).map_err(|e| {
        SweepError::Io {
            path: dir.to_path_buf(),
            source: e,
        }
    })?;
    let rows = summarise(&data.builds, &data.frames);
    let sweep_csv = dir.join("sweep.csv");
    write_csv(
        &sweep_csv,
        &SWEEP_HEADER,
        &rows.iter().map(sweep_row).collect::<Vec<_>>(),
    )?;
    let frames_csv = dir.join("frames.csv");
    write_csv(
        &frames_csv,
        &frames_header(),
        &data.frames.iter().map(frame_row).collect::<Vec<_>>(),
    )?;
    let builds_csv = dir.join("builds.csv");
    write_builds(&builds_csv, &data.builds)?;
    let plots = write_plots(dir, data, &rows)?;
    let cx = ReportContext {
        scene: scene.to_string(),
        path: path.to_string(),
        plots: plots.clone(),
    };
    let report = dir.join("report.md");
    write_atomic(&report, markdown(data, &rows, &cx).as_bytes())?;
    let mut written = vec![sweep_csv, frames_csv, builds_csv, report];
    for (stem, _) in plots {
        written.push(dir.join(format!("{stem}.png")));
        written.push(dir.join(format!("{stem}.svg")));
    }
    Ok((rows, written))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The histogram chart of the base build holds its own variants only, not those of a build whose id
    /// extends the base's (`…_bc1`, `…_bake`).
    #[test]
    fn base_histograms_are_the_base_builds_own() {
        let plan = super::super::Grid::preset("small").unwrap().plan();
        let h = crate::report::metrics::Histogram::log2(&[1.0], 0, 2);
        let all: Vec<_> = (plan.builds.iter())
            .flat_map(|b| b.runtimes.iter().map(|r| (b.knobs, *r, h.clone())))
            .collect();
        let base = &plan.builds[0];
        assert!(plan.builds.len() > 1 && all.len() > base.runtimes.len());
        let labels: Vec<String> = base_histograms(&base.knobs, &all)
            .into_iter()
            .map(|(l, _)| l)
            .collect();
        let want: Vec<String> = base.runtimes.iter().map(|r| r.id()).collect();
        assert_eq!(labels, want);
    }
}
