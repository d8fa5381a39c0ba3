//! One schema for the per-frame counters of every CSV: `render`'s `stats.csv`, `simulate`'s `frames.csv`
//! and `sweep`'s `frames.csv` write a frame's counters through these mappings, so a counter has one name
//! everywhere (the README's "Changelog" lists the names this replaced).
//!
//! Each mapping destructures its struct exhaustively (no `..`): a field added to [`PagingFrame`],
//! [`SessionFrame`], [`PagerFrameStats`], [`UsageCounts`], [`Coarseness`], [`PlanStats`] or
//! [`FrameStats`] breaks the build here, where it gets its column (or is named as left out, with the
//! reason). Every column is a [`Column`]: its name, its cell, and whether it is a wall-clock time
//! ([`Column::timing`]); the simulator's tables are byte-for-byte deterministic and leave timings out.

use super::csv::Cell;
use crate::paging::{Coarseness, PagerFrameStats, SessionFrame, UsageCounts};
use crate::plan::{PagingFrame, PlanStats};
use crate::render::FrameStats;

/// One column of a per-frame table.
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    pub name: &'static str,
    pub cell: Cell,
    /// A wall-clock time (µs or ms, differs from run to run); every other column is a counter, the same
    /// for the same inputs.
    pub timing: bool,
}

fn counter(name: &'static str, cell: impl Into<Cell>) -> Column {
    Column {
        name,
        cell: cell.into(),
        timing: false,
    }
}

fn timing(name: &'static str, cell: impl Into<Cell>) -> Column {
    Column {
        name,
        cell: cell.into(),
        timing: true,
    }
}

/// Columns of one plan's paging counters (paper §6): usage categories, ideal set, residency, the
/// frame's loads, evictions and failures, queue and in-flight requests, the screen share drawn coarser
/// than selected, the executor's uploads and errors, and the resident-set fingerprint. Units: blocks,
/// bytes, ms; shares in [0, 1].
pub fn paging_columns(p: &PagingFrame) -> Vec<Column> {
    let PagingFrame {
        session,
        coarse,
        upload_ms,
        uploaded_bytes,
        loaded_original_bytes,
        resident_atlas_bytes,
        resident_original_bytes,
        resident_hash,
        apply_errors,
        evict_errors,
    } = *p;
    let SessionFrame {
        pager,
        queued,
        in_flight,
    } = session;
    let ideal_fraction = pager.ideal_fraction();
    let PagerFrameStats {
        usage,
        ideal,
        resident,
        ideal_resident,
        requested,
        staged,
        loaded,
        bytes_loaded,
        evictions,
        cancelled,
        discarded,
        discarded_bytes,
        failures,
        priority_violations,
    } = pager;
    let UsageCounts {
        needed,
        culled,
        parent_needed,
    } = usage;
    let (coarser_share, coarser_gap) = (coarse.share(), coarse.mean_gap());
    let Coarseness {
        items,
        coarser_items,
        // In `coarser_share` and `coarser_gap`.
        area: _,
        coarser_area: _,
        coarser_area_by_gap: _,
    } = coarse;
    vec![
        counter("blocks_needed", needed),
        counter("blocks_culled", culled),
        counter("blocks_parent_needed", parent_needed),
        counter("ideal", ideal),
        counter("ideal_resident", ideal_resident),
        counter("ideal_fraction", ideal_fraction),
        counter("resident", resident),
        counter("requested", requested),
        counter("staged", staged),
        counter("queued", queued),
        counter("in_flight", in_flight),
        counter("loaded", loaded),
        counter("bytes_loaded", bytes_loaded),
        counter("bytes_loaded_originals", loaded_original_bytes),
        counter("bytes_uploaded", uploaded_bytes),
        counter("resident_bytes_atlases", resident_atlas_bytes),
        counter("resident_bytes_originals", resident_original_bytes),
        counter("evictions", evictions),
        counter("cancelled", cancelled),
        counter("discarded", discarded),
        counter("discarded_bytes", discarded_bytes),
        counter("failures", failures),
        counter("priority_violations", priority_violations),
        counter("drawn_items", items),
        counter("coarser_items", coarser_items),
        counter("coarser_share", coarser_share),
        counter("coarser_gap", coarser_gap),
        counter("apply_errors", apply_errors),
        counter("evict_errors", evict_errors),
        counter("resident_hash", Cell::Text(format!("{resident_hash:016x}"))),
        timing("upload_ms", upload_ms),
    ]
}

/// [`paging_columns`] of `p`, or the same columns with empty cells when the frame was not paged.
pub fn paging_columns_or_empty(p: Option<&PagingFrame>) -> Vec<Column> {
    match p {
        Some(p) => paging_columns(p),
        None => paging_columns(&PagingFrame::default())
            .into_iter()
            .map(|c| Column {
                cell: Cell::Text(String::new()),
                ..c
            })
            .collect(),
    }
}

/// Columns of a plan's own counters (its paging counters are [`paging_columns`]).
pub fn plan_columns(s: &PlanStats) -> Vec<Column> {
    let PlanStats {
        nodes_visited,
        nodes_drawn,
        select_us,
        page_us,
        // Its own columns: `paging_columns`.
        paging: _,
    } = *s;
    vec![
        counter("nodes_visited", nodes_visited),
        counter("nodes_drawn", nodes_drawn),
        timing("select_us", select_us),
        timing("page_us", page_us),
    ]
}

/// Columns of an executed frame: the plan's counters ([`plan_columns`]), then the renderer's draw
/// counters and timings (the paging counters are [`paging_columns`]). `gpu_ms` is NaN (`nan`) without
/// timestamp queries.
pub fn frame_columns(s: &FrameStats) -> Vec<Column> {
    let FrameStats {
        plan,
        indirect_records,
        original_records,
        draw_calls,
        bind_group_changes,
        pipeline_changes,
        triangles,
        encode_us,
        gpu_ms,
        frame_ms,
        skipped_draws,
        atlas_layers_used,
        original_layers_used,
    } = *s;
    let mut out = plan_columns(&plan);
    out.extend([
        counter("indirect_records", indirect_records),
        counter("original_records", original_records),
        counter("draw_calls", draw_calls),
        counter("bind_group_changes", bind_group_changes),
        counter("pipeline_changes", pipeline_changes),
        counter("triangles", triangles),
        counter("skipped_draws", skipped_draws),
        counter("atlas_layers_used", atlas_layers_used),
        counter("original_layers_used", original_layers_used),
        timing("encode_us", encode_us),
        timing("gpu_ms", gpu_ms.unwrap_or(f64::NAN)),
        timing("frame_ms", frame_ms),
    ]);
    out
}

/// The names of `columns`, for a header.
pub fn names(columns: &[Column]) -> Vec<&'static str> {
    columns.iter().map(|c| c.name).collect()
}

/// The cells of `columns`, for a row.
pub fn cells(columns: Vec<Column>) -> Vec<Cell> {
    columns.into_iter().map(|c| c.cell).collect()
}

/// `columns` without the wall-clock timings (for tables that must be deterministic).
pub fn counters_only(columns: Vec<Column>) -> Vec<Column> {
    columns.into_iter().filter(|c| !c.timing).collect()
}
