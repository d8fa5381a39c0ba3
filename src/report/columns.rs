//! One schema for the per-frame counters of every CSV: `render`'s `stats.csv`, `simulate`'s `frames.csv`
//! and `sweep`'s `frames.csv` write a frame's counters through these mappings, so a counter has one name
//! everywhere (the README's "Changelog" lists the names this replaced).
//!
//! Each mapping destructures its struct exhaustively (no `..`): a field added to [`PagingFrame`],
//! [`SessionFrame`], [`PagerFrameStats`], [`UsageCounts`], [`Coarseness`] or [`PlanStats`] breaks the build
//! here, where it gets its column (or is named as left out, with the reason); the renderer's `FrameStats`
//! has its mapping beside it (`render::frame_columns`, built from these). Every column is a [`Column`]: its
//! name, its cell, and whether it is a wall-clock time ([`Column::timing`]); the simulator's tables are
//! byte-for-byte deterministic and leave timings out.

use super::csv::Cell;
use crate::paging::{Coarseness, PagerFrameStats, SessionFrame, UsageCounts};
use crate::plan::{PagingFrame, PlanStats};
use Column as C;

/// One column of a per-frame table.
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    pub name: &'static str,
    pub cell: Cell,
    /// A wall-clock time (µs or ms, differs from run to run); every other column is a counter, the same
    /// for the same inputs.
    pub timing: bool,
}

impl Column {
    /// A counter: the same for the same inputs.
    pub fn counter(name: &'static str, cell: impl Into<Cell>) -> Column {
        Column {
            name,
            cell: cell.into(),
            timing: false,
        }
    }

    /// A wall-clock time (left out of deterministic tables).
    pub fn timing(name: &'static str, cell: impl Into<Cell>) -> Column {
        Column {
            name,
            cell: cell.into(),
            timing: true,
        }
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
        C::counter("blocks_needed", needed),
        C::counter("blocks_culled", culled),
        C::counter("blocks_parent_needed", parent_needed),
        C::counter("ideal", ideal),
        C::counter("ideal_resident", ideal_resident),
        C::counter("ideal_fraction", ideal_fraction),
        C::counter("resident", resident),
        C::counter("requested", requested),
        C::counter("staged", staged),
        C::counter("queued", queued),
        C::counter("in_flight", in_flight),
        C::counter("loaded", loaded),
        C::counter("bytes_loaded", bytes_loaded),
        C::counter("bytes_loaded_originals", loaded_original_bytes),
        C::counter("bytes_uploaded", uploaded_bytes),
        C::counter("resident_bytes_atlases", resident_atlas_bytes),
        C::counter("resident_bytes_originals", resident_original_bytes),
        C::counter("evictions", evictions),
        C::counter("cancelled", cancelled),
        C::counter("discarded", discarded),
        C::counter("discarded_bytes", discarded_bytes),
        C::counter("failures", failures),
        C::counter("priority_violations", priority_violations),
        C::counter("drawn_items", items),
        C::counter("coarser_items", coarser_items),
        C::counter("coarser_share", coarser_share),
        C::counter("coarser_gap", coarser_gap),
        C::counter("apply_errors", apply_errors),
        C::counter("evict_errors", evict_errors),
        C::counter("resident_hash", Cell::Text(format!("{resident_hash:016x}"))),
        C::timing("upload_ms", upload_ms),
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
        C::counter("nodes_visited", nodes_visited),
        C::counter("nodes_drawn", nodes_drawn),
        C::timing("select_us", select_us),
        C::timing("page_us", page_us),
    ]
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
