//! Paging-budget experiments without a GPU (issue "Paging-budget experiments"): the renderer's very
//! [`FramePlanner`] (select, usage, ideal set, queue, residency, resolution with its screen accounting)
//! driven by a camera path on a frame clock, with an optional I/O model in place of the loader threads and
//! nothing in place of the GPU uploads.
//!
//! Only the effects a run asks for are modelled: without an [`IoModel`] a block arrives in the frame it is
//! requested (the local file "as it would deliver"), without a capacity nothing is ever evicted (`k` = all
//! blocks), without an upload budget everything that arrived becomes resident at once.
//!
//! Deterministic: no threads inside a run, no clocks but the frame clock, so the same inputs give the same
//! rows byte for byte (runs of a grid execute in parallel, each on its own).

use crate::camera::Camera;
use crate::ids::BlockId;
use crate::paging::{Arrival, BlockTable, Loader, PagerOptions, Request};
use crate::plan::{FramePlanner, PagingFrame, PlanError, RecordResidency};
use crate::store::format::NodeRecord;
use serde::Serialize;

pub mod grid;
pub mod tour;

/// A transfer model: one pipe of `bandwidth` bytes/s shared by all requests (transfers are serialised in
/// start order), a fixed `latency` per request (overlapping: requests in flight wait in parallel), an extra
/// `overhead` per request (HTTP request/response cost), and at most `max_in_flight` requests at once.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct IoModel {
    /// Bytes per second.
    pub bandwidth: f64,
    /// Seconds from request to first byte.
    pub latency: f64,
    /// Seconds added per request (e.g. HTTP headers and connection handling).
    pub overhead: f64,
    pub max_in_flight: u32,
}

/// The simulated loader of an [`IoModel`].
#[derive(Clone, Debug)]
pub struct ModelLoader {
    model: IoModel,
    wanted: Vec<Request>,
    /// Requests the last poll found no free slot for (the frame's `queued`; the pager asks again).
    waiting: u32,
    /// `(block, finish time)` in start order.
    in_flight: Vec<(BlockId, f64)>,
    pipe_free_at: f64,
}

impl ModelLoader {
    pub fn new(model: IoModel) -> ModelLoader {
        ModelLoader {
            model,
            wanted: Vec::new(),
            waiting: 0,
            in_flight: Vec::new(),
            pipe_free_at: 0.0,
        }
    }
}

impl ModelLoader {
    /// Moves the transfers that finished by `now` (start order) to `out`.
    fn arrive(&mut self, now: f64, out: &mut Vec<Arrival>) {
        let mut i = 0;
        while i < self.in_flight.len() {
            if self.in_flight[i].1 <= now + 1e-12 {
                let (block, _) = self.in_flight.remove(i);
                out.push(Arrival {
                    block,
                    result: Ok(None),
                });
            } else {
                i += 1;
            }
        }
    }
}

impl Loader for ModelLoader {
    fn set_requests(&mut self, wanted: &[Request]) {
        // Requests in flight that are no longer wanted are cancelled; their pipe time is not returned
        // (the bytes were on their way).
        self.in_flight
            .retain(|(b, _)| wanted.iter().any(|r| r.block == *b));
        self.wanted.clear();
        self.wanted.extend(
            wanted
                .iter()
                .filter(|r| !self.in_flight.iter().any(|(b, _)| *b == r.block)),
        );
    }

    /// Transfers that finished by `now` arrive first, so their slots take new requests in the same
    /// poll (computed before them, a full pipe drained in one frame stayed idle for the next: loads
    /// alternated 4, 0, 4, 0 at 4 in flight, and any bandwidth above that gave the same frames; fault
    /// hunt, session 28); a request started here that finishes by `now` (zero latency, instant
    /// bandwidth) arrives here too and frees its slot again.
    fn poll(&mut self, now: f64, out: &mut Vec<Arrival>) {
        let m = self.model;
        let max_in_flight = m.max_in_flight.max(1) as usize;
        let mut started = 0;
        loop {
            self.arrive(now, out);
            let slots = max_in_flight.saturating_sub(self.in_flight.len());
            let end = self.wanted.len().min(started + slots);
            if end == started {
                break;
            }
            for r in &self.wanted[started..end] {
                let start_transfer = (now + m.latency + m.overhead).max(self.pipe_free_at);
                let finish = start_transfer + r.bytes as f64 / m.bandwidth;
                self.pipe_free_at = finish;
                self.in_flight.push((r.block, finish));
            }
            started = end;
        }
        self.waiting = (self.wanted.len() - started) as u32;
        self.wanted.clear();
    }

    fn queued(&self) -> u32 {
        self.waiting
    }

    fn in_flight(&self) -> u32 {
        self.in_flight.len() as u32
    }
}

/// Without an I/O model: every wanted block arrives in the frame it is requested.
#[derive(Clone, Debug, Default)]
pub struct InstantLoader {
    wanted: Vec<Request>,
}

impl Loader for InstantLoader {
    fn set_requests(&mut self, wanted: &[Request]) {
        self.wanted.clear();
        self.wanted.extend_from_slice(wanted);
    }

    fn poll(&mut self, _now: f64, out: &mut Vec<Arrival>) {
        out.extend(self.wanted.drain(..).map(|r| Arrival {
            block: r.block,
            result: Ok(None),
        }));
    }

    fn queued(&self) -> u32 {
        self.wanted.len() as u32
    }

    fn in_flight(&self) -> u32 {
        0
    }
}

/// One simulated run's settings.
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct SimOptions {
    /// Frame clock, frames per second (the camera path is sampled at `i / fps`).
    pub fps: f64,
    /// Pager settings; `capacity` = `u32::MAX` means "no budget" (all blocks may be resident).
    pub pager: PagerOptions,
    pub io: Option<IoModel>,
}

/// One frame of a run (a row of `frames.csv`: these fields, then the paging counters through
/// [`crate::report::columns::paging_columns`], timings left out).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct FrameRow {
    pub frame: u32,
    /// Clock, seconds.
    pub time: f64,
    /// The plan's paging counters; `upload_ms` is 0 (there are no uploads, and the time the planner took
    /// in the recording executor measures nothing), so rows compare equal between identical runs.
    pub paging: PagingFrame,
    /// Frames from this one until the ideal set is next fully resident (−1: never within the run).
    pub time_to_ideal: i32,
}

impl FrameRow {
    /// Share of the drawn screen area rendered coarser than the target (see `paging::resolve`).
    pub fn coarser_share(&self) -> f64 {
        self.paging.coarse.share()
    }

    /// Share of the ideal set resident after the frame.
    pub fn ideal_fraction(&self) -> f64 {
        self.paging.pager().ideal_fraction()
    }

    /// Bytes the pager loaded this frame (the root atlases, resident before the first frame, are not
    /// counted in any frame).
    pub fn bytes_loaded(&self) -> u64 {
        self.paging.pager().bytes_loaded
    }
}

/// One run's summary (a row of `summary.csv`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct RunSummary {
    pub frames: u32,
    pub mean_coarser: f64,
    pub p95_coarser: f64,
    pub max_coarser: f64,
    /// Bytes loaded over the path, after the root atlases (resident before the first frame).
    pub bytes_total: u64,
    /// Of `bytes_total`, those of original-texture blocks.
    pub bytes_originals_total: u64,
    pub loads: u64,
    pub peak_resident: u32,
    /// Frames where the ideal set suddenly lost residency (the path "jumped"): the ideal fraction fell by
    /// at least 0.25 from the previous frame.
    pub jumps: u32,
    /// Frames to reach the ideal set again after each jump (−1: not within the run).
    pub converge_frames: Vec<i32>,
    /// Frames with at least half of the drawn area coarser than the target.
    pub stalls: u32,
    pub cancelled: u64,
    pub discarded: u64,
}

/// The tables a simulation needs (from an open file, or hand-made in tests).
pub struct SimInput<'a> {
    pub trees: Vec<&'a [NodeRecord]>,
    pub table: BlockTable,
}

impl<'a> SimInput<'a> {
    pub fn from_file(
        file: &'a crate::store::TreeFile,
    ) -> Result<SimInput<'a>, crate::paging::BlockTableError> {
        Ok(SimInput {
            trees: crate::plan::file_trees(file),
            table: BlockTable::from_file(file)?,
        })
    }
}

/// `cameras` each with its min-distance scale, `scales[i]`; [`PlanError::ScaleCount`] when the counts
/// differ.
pub(crate) fn with_scales<'a>(
    cameras: &'a [Camera],
    scales: &'a [f64],
) -> Result<impl Iterator<Item = (&'a Camera, f64)> + 'a, PlanError> {
    if scales.len() != cameras.len() {
        return Err(PlanError::ScaleCount {
            cameras: cameras.len(),
            scales: scales.len(),
        });
    }
    Ok(cameras.iter().zip(scales.iter().copied()))
}

/// Runs `cameras` (one per frame, clock `i / fps`), camera `i` at min-distance scale `scales[i]` (it
/// follows the camera's field of view, as the renderer's does); returns one row per frame and the
/// summary. `scales` of another length than `cameras`: [`PlanError::ScaleCount`].
pub fn simulate(
    input: &SimInput,
    cameras: &[Camera],
    scales: &[f64],
    opts: &SimOptions,
) -> Result<(Vec<FrameRow>, RunSummary), PlanError> {
    simulate_with(input, cameras, scales, opts, &mut |_, _| {})
}

/// [`simulate`], reporting every residency change (`frame`, event) to `events` — the log the renderer
/// would apply to the GPU.
pub fn simulate_with(
    input: &SimInput,
    cameras: &[Camera],
    scales: &[f64],
    opts: &SimOptions,
    events: &mut dyn FnMut(u32, &crate::paging::Event),
) -> Result<(Vec<FrameRow>, RunSummary), PlanError> {
    let views = with_scales(cameras, scales)?;
    let loader: Box<dyn Loader> = match opts.io {
        Some(m) => Box::new(ModelLoader::new(m)),
        None => Box::new(InstantLoader::default()),
    };
    let mut planner = FramePlanner::paged(
        input.trees.clone(),
        input.table.clone(),
        opts.pager,
        loader,
        |_| Ok(None),
    )?;
    // The roots are resident before the first frame; the log starts with frame 0's changes.
    planner.take_bootstrap();
    let mut rows = Vec::with_capacity(cameras.len());
    for (i, (cam, scale)) in views.enumerate() {
        let now = i as f64 / opts.fps;
        let frame = i as u32;
        let plan = planner.plan(
            cam,
            now,
            scale,
            &mut RecordResidency(|e: &crate::paging::Event| events(frame, e)),
        )?;
        let paging = plan.stats.paging.ok_or(PlanError::NotPaged)?;
        rows.push(FrameRow {
            frame,
            time: now,
            // No uploads here: the planner timed the recording closure, which is no measure of anything.
            paging: PagingFrame {
                upload_ms: 0.0,
                ..paging
            },
            time_to_ideal: -1,
        });
    }
    fill_time_to_ideal(&mut rows);
    let t = planner.pager().map(|p| *p.totals()).unwrap_or_default();
    let summary = summarise(&rows, t.cancelled, t.discarded);
    Ok((rows, summary))
}

fn fill_time_to_ideal(rows: &mut [FrameRow]) {
    let mut next_full: Option<usize> = None;
    for i in (0..rows.len()).rev() {
        if rows[i].ideal_fraction() >= 1.0 {
            next_full = Some(i);
        }
        rows[i].time_to_ideal = next_full.map_or(-1, |j| (j - i) as i32);
    }
}

/// Summary statistics of a run's rows (see [`RunSummary`] for the definitions).
pub fn summarise(rows: &[FrameRow], cancelled: u64, discarded: u64) -> RunSummary {
    let n = rows.len();
    let mut shares: Vec<f64> = rows.iter().map(FrameRow::coarser_share).collect();
    shares.sort_by(f64::total_cmp);
    let p95 = if n == 0 {
        0.0
    } else {
        shares[((n as f64 * 0.95).ceil() as usize).clamp(1, n) - 1]
    };
    let mut jumps = 0;
    let mut converge = Vec::new();
    for i in 1..n {
        if rows[i - 1].ideal_fraction() - rows[i].ideal_fraction() >= 0.25 {
            jumps += 1;
            converge.push(rows[i].time_to_ideal);
        }
    }
    RunSummary {
        frames: n as u32,
        mean_coarser: if n == 0 {
            0.0
        } else {
            shares.iter().sum::<f64>() / n as f64
        },
        p95_coarser: p95,
        max_coarser: shares.last().copied().unwrap_or(0.0),
        bytes_total: rows.iter().map(FrameRow::bytes_loaded).sum(),
        bytes_originals_total: rows.iter().map(|r| r.paging.loaded_original_bytes).sum(),
        loads: rows
            .iter()
            .map(|r| u64::from(r.paging.pager().loaded))
            .sum(),
        peak_resident: rows
            .iter()
            .map(|r| r.paging.pager().resident)
            .max()
            .unwrap_or(0),
        jumps,
        converge_frames: converge,
        stalls: rows.iter().filter(|r| r.coarser_share() >= 0.5).count() as u32,
        cancelled,
        discarded,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1 MB/s, no latency, 4 requests in flight.
    const ONE_MB_PER_S: IoModel = IoModel {
        bandwidth: 1e6,
        latency: 0.0,
        overhead: 0.0,
        max_in_flight: 4,
    };

    /// Seven 1 MB blocks.
    fn seven_blocks() -> Vec<Request> {
        (0..7)
            .map(|i| Request {
                block: BlockId(i),
                bytes: 1_000_000,
            })
            .collect()
    }

    /// Requests beyond the free transfer slots are the frame's `queued` (frames.csv), as a real loader's
    /// waiting requests are; it read 0 always (the poll had cleared them).
    #[test]
    fn requests_past_the_free_slots_are_queued() {
        let mut l = ModelLoader::new(ONE_MB_PER_S);
        let wanted = seven_blocks();
        l.set_requests(&wanted);
        let mut out = Vec::new();
        l.poll(0.0, &mut out);
        assert_eq!((l.in_flight(), l.queued()), (4, 3));
        assert!(out.is_empty());
    }

    /// A slot whose transfer finished by the poll takes a waiting request in that poll: at 1 MB/s, four
    /// 1 MB blocks in flight from t = 0 have all arrived at t = 4, and the three waiting start at once
    /// (they sat out a frame with nothing in flight before). With instant transfers every request
    /// arrives in the poll that starts it, whatever `max_in_flight`.
    #[test]
    fn finished_transfers_free_their_slots_in_the_same_poll() {
        let model = ONE_MB_PER_S;
        let wanted = seven_blocks();
        let mut l = ModelLoader::new(model);
        let mut out = Vec::new();
        l.set_requests(&wanted);
        l.poll(0.0, &mut out);
        l.set_requests(&wanted);
        l.poll(4.0, &mut out);
        let arrived: Vec<u32> = out.iter().map(|a| a.block.0).collect();
        assert_eq!(arrived, [0, 1, 2, 3]);
        assert_eq!((l.in_flight(), l.queued()), (3, 0));
        let mut l = ModelLoader::new(IoModel {
            bandwidth: f64::INFINITY,
            ..model
        });
        out.clear();
        l.set_requests(&wanted);
        l.poll(0.0, &mut out);
        assert_eq!(out.len(), 7);
        assert_eq!((l.in_flight(), l.queued()), (0, 0));
    }
}
