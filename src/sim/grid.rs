//! The experiment grid of `atlastree simulate`: capacity × bandwidth × latency × policy, each cell one
//! deterministic [`simulate`] run (cells in parallel), written as `frames.csv`, `summary.csv` and plots.

use super::{FrameRow, IoModel, RunSummary, SimInput, SimOptions, simulate};
use crate::camera::Camera;
use crate::paging::{PagerOptions, Policy, UploadBudget};
use crate::plan::PlanError;
use crate::report::ReportError;
use crate::report::columns;
use crate::report::csv::{Cell, CsvWriter};
use crate::report::plot::{HeatMap, PlotOptions, Series, heat_map, line_chart};
use rayon::prelude::*;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The axes of a grid and the settings shared by all cells.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct GridSpec {
    /// Capacities k; `None` = no budget (every block may stay resident).
    pub capacities: Vec<Option<u32>>,
    /// Bandwidths in bytes/s; `None` = no I/O model (blocks arrive in the frame they are requested).
    pub bandwidths: Vec<Option<f64>>,
    /// Latencies in seconds (only modelled with a bandwidth).
    pub latencies: Vec<f64>,
    pub policies: Vec<Policy>,
    pub fps: f64,
    pub max_queue: u32,
    pub budget: UploadBudget,
    pub max_in_flight: u32,
    /// Per-request overhead, seconds (HTTP).
    pub overhead: f64,
}

/// One cell of the grid.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct RunKey {
    pub capacity: Option<u32>,
    /// Bytes per second; `None`: instant.
    #[serde(rename = "bandwidth_bytes_per_s")]
    pub bandwidth: Option<f64>,
    /// Seconds.
    #[serde(rename = "latency_s")]
    pub latency: f64,
    pub policy: Policy,
}

impl RunKey {
    /// Whether the run of `self` answers for the cell `cell`: the same capacity, bandwidth and policy, and
    /// the same latency unless the bandwidth is instant (run at the first latency only:
    /// [`GridSpec::cells`]).
    pub fn answers(&self, cell: &RunKey) -> bool {
        self.capacity == cell.capacity
            && self.bandwidth == cell.bandwidth
            && self.policy == cell.policy
            && (self.latency == cell.latency || self.bandwidth.is_none())
    }

    /// A short, file-name-safe label, e.g. `k160_50MBps_80ms_paper`.
    pub fn label(&self) -> String {
        format!(
            "k{}_{}_{}ms_{}",
            self.capacity.map_or("all".to_string(), |k| k.to_string()),
            self.bandwidth.map_or("instant".to_string(), |b| format!(
                "{}MBps",
                crate::util::short_number(b / 1e6)
            )),
            crate::util::short_number(self.latency * 1e3),
            self.policy.name()
        )
    }
}

impl GridSpec {
    /// The first two cells with the same [`RunKey::label`] (a value given twice: the runs' rows would be
    /// mixed in the CSVs under one key), if any.
    pub fn duplicate_label(&self) -> Option<String> {
        let mut seen = std::collections::HashSet::new();
        self.cells()
            .iter()
            .map(RunKey::label)
            .find(|l| !seen.insert(l.clone()))
    }

    /// The cells in a fixed order (capacity, bandwidth, latency, policy; each in the order given). An
    /// instant bandwidth (no I/O model) runs at the first latency only.
    pub fn cells(&self) -> Vec<RunKey> {
        let mut out = Vec::new();
        for &capacity in &self.capacities {
            for &bandwidth in &self.bandwidths {
                // Instant loads model no I/O, so latency changes nothing: one run, at the first latency
                // (two identical runs under two labels read as "80 ms had no effect").
                let latencies = match bandwidth {
                    None => &self.latencies[..self.latencies.len().min(1)],
                    Some(_) => &self.latencies[..],
                };
                for &latency in latencies {
                    for &policy in &self.policies {
                        out.push(RunKey {
                            capacity,
                            bandwidth,
                            latency,
                            policy,
                        });
                    }
                }
            }
        }
        out
    }

    /// The simulator options of one cell.
    pub fn options(&self, key: &RunKey) -> SimOptions {
        SimOptions {
            fps: self.fps,
            pager: PagerOptions {
                capacity: key.capacity.unwrap_or(u32::MAX),
                max_queue: self.max_queue,
                budget: self.budget,
                policy: key.policy,
                ..PagerOptions::default()
            },
            io: key.bandwidth.map(|bandwidth| IoModel {
                bandwidth,
                latency: key.latency,
                overhead: self.overhead,
                max_in_flight: self.max_in_flight,
            }),
        }
    }
}

/// One finished cell.
#[derive(Clone, Debug)]
pub struct RunResult {
    pub key: RunKey,
    pub rows: Vec<FrameRow>,
    pub summary: RunSummary,
    /// Wall time of the run, seconds (not part of any CSV: the CSVs stay deterministic).
    pub seconds: f64,
}

impl RunResult {
    /// Whether any frame drew a node of the tree: `false` where the path never looks at the scene, so
    /// every coarser share of 0 means nothing drawn, not ideal paging (`summary.csv`'s `drew_nodes`).
    pub fn drew_nodes(&self) -> bool {
        self.rows.iter().any(|f| f.paging.coarse.items > 0)
    }
}

/// Runs every cell (in parallel); `tick` is called after each cell. Results are in [`GridSpec::cells`]
/// order.
pub fn run_grid(
    input: &SimInput,
    cameras: &[Camera],
    scales: &[f64],
    spec: &GridSpec,
    tick: &(dyn Fn() + Sync),
) -> Result<Vec<RunResult>, PlanError> {
    spec.cells()
        .into_par_iter()
        .map(|key| {
            let t = std::time::Instant::now();
            let (rows, summary) = simulate(input, cameras, scales, &spec.options(&key))?;
            tick();
            Ok(RunResult {
                key,
                rows,
                summary,
                seconds: t.elapsed().as_secs_f64(),
            })
        })
        .collect()
}

fn key_cells(k: &RunKey, overhead: f64) -> Vec<Cell> {
    vec![
        Cell::Text(k.label()),
        Cell::Text(k.capacity.map_or("all".into(), |c| c.to_string())),
        Cell::Text(k.bandwidth.map_or("instant".into(), |b| format!("{b}"))),
        Cell::Float(k.latency * 1e3),
        Cell::Float(overhead * 1e3),
        Cell::Text(k.policy.name().into()),
    ]
}

/// Units in the names: bytes per second (it read `bandwidth_bps`, bits by convention) and milliseconds.
/// The per-request overhead is the grid's (`--overhead`), on every row: a run with 200 ms of overhead
/// and none of latency read as one with neither (fault hunt, session 37).
const KEY_HEADER: [&str; 6] = [
    "run",
    "capacity",
    "bandwidth_bytes_per_s",
    "latency_ms",
    "overhead_ms",
    "policy",
];

/// Writes `frames.csv` and `summary.csv` into `dir` for a grid of per-request overhead `overhead`
/// (seconds, [`GridSpec::overhead`]); returns their paths.
pub fn write_csvs(
    dir: &Path,
    results: &[RunResult],
    overhead: f64,
) -> Result<Vec<PathBuf>, ReportError> {
    // The paging counters of every frame through the one schema; timings are left out (the executor
    // here only records, and the table must be the same bytes for the same inputs).
    let counters =
        |p: &crate::plan::PagingFrame| columns::counters_only(columns::paging_columns(p));
    let mut header: Vec<&str> = KEY_HEADER.to_vec();
    header.extend(["frame", "time_s"]);
    header.extend(columns::names(&counters(&Default::default())));
    header.push("time_to_ideal");
    let mut frames = CsvWriter::create(&dir.join("frames.csv"), &header)?;
    for r in results {
        for f in &r.rows {
            let mut row = key_cells(&r.key, overhead);
            row.extend([Cell::UInt(f.frame.into()), Cell::Float(f.time)]);
            row.extend(columns::cells(counters(&f.paging)));
            row.push(Cell::Int(f.time_to_ideal.into()));
            frames.row(&row)?;
        }
    }
    let mut header: Vec<&str> = KEY_HEADER.to_vec();
    header.extend([
        "frames",
        "mean_coarser",
        "p95_coarser",
        "max_coarser",
        "bytes_total",
        "bytes_originals_total",
        "loads",
        "peak_resident",
        "jumps",
        "converge_frames",
        "stalls",
        "cancelled",
        "discarded",
        "drew_nodes",
    ]);
    let mut summary = CsvWriter::create(&dir.join("summary.csv"), &header)?;
    for r in results {
        let s = &r.summary;
        let mut row = key_cells(&r.key, overhead);
        row.extend([
            Cell::UInt(s.frames.into()),
            Cell::Float(s.mean_coarser),
            Cell::Float(s.p95_coarser),
            Cell::Float(s.max_coarser),
            Cell::UInt(s.bytes_total),
            Cell::UInt(s.bytes_originals_total),
            Cell::UInt(s.loads),
            Cell::UInt(s.peak_resident.into()),
            Cell::UInt(s.jumps.into()),
            Cell::Text(
                s.converge_frames
                    .iter()
                    .map(|c| c.to_string())
                    .collect::<Vec<_>>()
                    .join(" "),
            ),
            Cell::UInt(s.stalls.into()),
            Cell::UInt(s.cancelled),
            Cell::UInt(s.discarded),
            Cell::Text(r.drew_nodes().to_string()),
        ]);
        summary.row(&row)?;
    }
    Ok(vec![frames.finish()?, summary.finish()?])
}

/// Writes the plots: coarser share over time per k and bytes per frame (for the first bandwidth, latency
/// and policy), and per (latency, policy) a heat map of the mean coarser share over capacity × bandwidth.
pub fn write_plots(
    dir: &Path,
    spec: &GridSpec,
    results: &[RunResult],
) -> Result<Vec<PathBuf>, ReportError> {
    let mut out = Vec::new();
    let (Some(&bw), Some(&lat), Some(&pol)) = (
        spec.bandwidths.first(),
        spec.latencies.first(),
        spec.policies.first(),
    ) else {
        return Ok(out);
    };
    let first: Vec<&RunResult> = results
        .iter()
        .filter(|r| r.key.bandwidth == bw && r.key.latency == lat && r.key.policy == pol)
        .collect();
    let cond = RunKey {
        capacity: None,
        bandwidth: bw,
        latency: lat,
        policy: pol,
    }
    .label();
    let cond = cond.trim_start_matches("kall_");
    let series = |f: &dyn Fn(&FrameRow) -> f64| -> Vec<Series> {
        first
            .iter()
            .map(|r| {
                Series::new(
                    format!(
                        "k = {}",
                        r.key.capacity.map_or("all".into(), |k| k.to_string())
                    ),
                    r.rows.iter().map(|x| (x.time, f(x))).collect(),
                )
            })
            .collect()
    };
    if !first.is_empty() {
        let p = line_chart(
            &dir.join("coarser_over_time"),
            &PlotOptions {
                // A share: the axis is 0..1 whatever the data (a flat series was widened to −0.4..1.4).
                y_range: Some((0.0, 1.0)),
                ..PlotOptions::new(
                    format!("Screen share coarser than target ({cond})"),
                    "time (s)",
                    "coarser share of drawn area",
                )
            },
            &series(&|x| x.coarser_share()),
        )?;
        out.extend([p.svg, p.png]);
        let p = line_chart(
            &dir.join("bytes_per_frame"),
            &PlotOptions::new(
                format!("Bytes loaded per frame ({cond})"),
                "time (s)",
                "MB per frame",
            ),
            &series(&|x| x.bytes_loaded() as f64 / 1e6),
        )?;
        out.extend([p.svg, p.png]);
    }
    for &lat in &spec.latencies {
        for &pol in &spec.policies {
            let mut values = Vec::new();
            for &k in &spec.capacities {
                for &b in &spec.bandwidths {
                    let v = results
                        .iter()
                        .find(|r| {
                            r.key.answers(&RunKey {
                                capacity: k,
                                bandwidth: b,
                                latency: lat,
                                policy: pol,
                            })
                        })
                        .map_or(f64::NAN, |r| r.summary.mean_coarser);
                    values.push(v);
                }
            }
            let map = HeatMap {
                row_labels: spec
                    .capacities
                    .iter()
                    .map(|k| k.map_or("all".into(), |k| k.to_string()))
                    .collect(),
                col_labels: spec
                    .bandwidths
                    .iter()
                    .map(|b| {
                        b.map_or("instant".into(), |b| {
                            format!("{} MB/s", crate::util::short_number(b / 1e6))
                        })
                    })
                    .collect(),
                values,
                decimals: 3,
                value_range: Some((0.0, 1.0)),
                value_label: "mean coarser share".into(),
            };
            let name = format!(
                "heatmap_{}ms_{}",
                crate::util::short_number(lat * 1e3),
                pol.name()
            );
            let p = heat_map(
                &dir.join(&name),
                &PlotOptions::new(
                    format!(
                        "Mean screen share coarser than target ({} ms latency, {} policy)",
                        crate::util::short_number(lat * 1e3),
                        pol.name()
                    ),
                    "bandwidth",
                    "capacity k (blocks)",
                ),
                &map,
            )?;
            out.extend([p.svg, p.png]);
        }
    }
    Ok(out)
}
