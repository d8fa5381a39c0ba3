//! The pager (paper §6): the ideal block set under a capacity `k`, the request queue re-ranked every frame,
//! and residency with eviction. Pure CPU and deterministic; the renderer and the simulator drive the same
//! code, the renderer with real loaders and uploads, the simulator with an I/O model.
//!
//! Per frame:
//! 1. [`Pager::plan`]: usage traversal ([`super::usage::classify`]), ranking by the [`Policy`], the ideal
//!    set (the first `k` admitted candidates, closed under parents; an originals block enters only together
//!    with every other block of a leaf that uses it — the most important such leaf whose group fits —,
//!    since a leaf draws its originals only when all of them are resident: with shared originals a leaf
//!    may need several blocks), cancellation of requests that left it,
//!    and the wanted requests in priority order (bounded by `max_queue`) for the loader;
//! 2. the loader runs and returns [`Arrival`]s;
//! 3. [`Pager::accept`]: arrivals are staged, then made resident in rank order within the upload budget,
//!    evicting the least important resident block outside the ideal set when the capacity is reached.
//!
//! Invariants (checked by [`Pager::check_invariants`] and the tests): never more than `k` resident blocks;
//! every tree's root atlas always resident; the resident set is closed under parents (an atlas's ancestors'
//! atlases, a leaf's originals' leaf atlas); a block of the ideal set is never evicted, and a victim always
//! ranks below the block that replaces it.

mod invariants;

use super::blocks::BlockTable;
use super::budget::UploadBudget;
use super::policy::Policy;
use super::residency::Retry;
use super::source::SourceError;
use super::usage::{Candidate, UsageCounts, UsageScratch, ViewInput, classify};
use crate::ids::{BlockId, NodeId};
use crate::store::format::NodeRecord;
use serde::Serialize;
use std::time::Instant;

/// `xxh3_64` of the sorted block ids: a compact fingerprint of a resident set (logged per frame by the
/// renderer and the simulator, so their resident sets can be compared).
pub fn resident_fingerprint(blocks: &[BlockId]) -> u64 {
    let mut ids: Vec<u32> = blocks.iter().map(|b| b.0).collect();
    ids.sort_unstable();
    xxhash_rust::xxh3::xxh3_64(bytemuck::cast_slice(&ids))
}

/// Doublings of [`PagerOptions::retry_frames`] at most: the longest back-off is `64 × retry_frames`.
const MAX_BACKOFF_DOUBLINGS: u8 = 6;

/// Options of a [`Pager`].
#[derive(Copy, Clone, Debug, PartialEq, Serialize)]
pub struct PagerOptions {
    /// Maximum number of resident blocks `k` (≥ the number of trees: the roots are always resident).
    pub capacity: u32,
    /// Maximum outstanding requests (requested or arrived-but-not-yet-resident blocks).
    pub max_queue: u32,
    pub budget: UploadBudget,
    pub policy: Policy,
    /// Frames to wait before re-requesting a block whose load failed; doubles per consecutive failure
    /// (up to 64×).
    pub retry_frames: u32,
}

impl Default for PagerOptions {
    fn default() -> Self {
        PagerOptions {
            capacity: 160,
            max_queue: 8,
            budget: UploadBudget::Unlimited,
            policy: Policy::Paper,
            retry_frames: 8,
        }
    }
}

/// Why a pager could not be made, or could not load its roots.
#[derive(Debug, thiserror::Error)]
pub enum PagerError {
    #[error(
        "capacity k = {capacity} is below the {roots} root atlases that must always be resident"
    )]
    CapacityBelowRoots { capacity: u32, roots: u32 },
    #[error("queue length must be at least 1 (got {max_queue})")]
    EmptyQueue { max_queue: u32 },
    /// A root atlas could not be fetched (after the source's own retries, counted in the error).
    #[error("loading root atlas {block} failed")]
    RootLoad {
        block: BlockId,
        #[source]
        error: SourceError,
    },
}

/// A request for the loader: one block, with its size.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Request {
    pub block: BlockId,
    pub bytes: u64,
}

/// What a loader returns: the block's bytes (`None` when simulated), or why it failed (the pager decides
/// from [`SourceError::is_transient`] how soon to ask again).
#[derive(Debug)]
pub struct Arrival {
    pub block: BlockId,
    pub result: Result<Option<Vec<u8>>, SourceError>,
}

/// A residency change the renderer must apply (upload into / free a layer).
#[derive(Debug)]
pub enum Event {
    Loaded {
        block: BlockId,
        data: Option<Vec<u8>>,
    },
    Evicted {
        block: BlockId,
    },
}

/// Whether the executor could apply a residency change ([`Pager::accept`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum Applied {
    Done,
    /// Not applied: a loaded block is taken back (not resident, a failure, asked for again as the
    /// [`Retry`] says).
    Failed(Retry),
}

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum State {
    Absent,
    Requested,
    /// Arrived, waiting for the upload budget or for its parent.
    Staged,
    Resident,
}

/// Per-frame counters of the pager (columns of `stats.csv` and `frames.csv`).
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct PagerFrameStats {
    pub usage: UsageCounts,
    /// Size of the ideal set (≤ k).
    pub ideal: u32,
    /// Blocks resident after this frame.
    pub resident: u32,
    /// Ideal blocks resident after this frame.
    pub ideal_resident: u32,
    /// Outstanding requests (requested, not arrived).
    pub requested: u32,
    /// Arrived, not yet resident.
    pub staged: u32,
    /// Blocks made resident this frame, and their bytes.
    pub loaded: u32,
    pub bytes_loaded: u64,
    pub evictions: u32,
    /// Requests cancelled because they left the ideal set (queued or in flight).
    pub cancelled: u32,
    /// Arrivals discarded (cancelled meanwhile, or no longer ideal when their turn came), and their bytes.
    pub discarded: u32,
    pub discarded_bytes: u64,
    /// Loads that failed this frame (source errors).
    pub failures: u32,
    /// Evictions of a block that ranked above the one replacing it (must stay 0).
    pub priority_violations: u32,
}

impl PagerFrameStats {
    /// The state these stats describe (usage, ideal, resident, requested, staged) without any of the
    /// step's per-frame deltas (loads, evictions, cancellations, failures …): a frame that steps nothing.
    pub fn state_only(&self) -> PagerFrameStats {
        PagerFrameStats {
            usage: self.usage,
            ideal: self.ideal,
            resident: self.resident,
            ideal_resident: self.ideal_resident,
            requested: self.requested,
            staged: self.staged,
            ..PagerFrameStats::default()
        }
    }

    /// Share of the ideal set that is resident (1 when the ideal set is empty).
    pub fn ideal_fraction(&self) -> f64 {
        if self.ideal == 0 {
            1.0
        } else {
            f64::from(self.ideal_resident) / f64::from(self.ideal)
        }
    }
}

/// Totals over a pager's life.
#[derive(Copy, Clone, Debug, Default, PartialEq, Serialize)]
pub struct PagerTotals {
    pub frames: u64,
    pub loaded: u64,
    pub bytes_loaded: u64,
    pub evictions: u64,
    pub cancelled: u64,
    pub discarded: u64,
    pub failures: u64,
    pub peak_resident: u32,
    pub priority_violations: u64,
}

/// The block pager. See the module docs.
pub struct Pager {
    table: BlockTable,
    opts: PagerOptions,
    state: Vec<State>,
    /// Resident blocks whose parent is this block.
    resident_children: Vec<u32>,
    /// Last frame the block was in the ideal set (LRU recency).
    last_used: Vec<u64>,
    /// Rank in this frame's ideal order; `u32::MAX` outside the ideal set.
    rank: Vec<u32>,
    /// Position in this frame's full candidate order; `u32::MAX` for blocks that are not candidates.
    order: Vec<u32>,
    /// Frame at which the block was requested (LRU's FIFO order).
    requested_at: Vec<u64>,
    /// Per block: the frame whose ideal set last left it out as an originals block whose leaf's group
    /// did not fit in k (its eviction is then no priority violation).
    group_left_out: Vec<u64>,
    failed_until: Vec<u64>,
    fail_count: Vec<u8>,
    is_root: Vec<bool>,
    resident: Vec<BlockId>,
    staged: Vec<(BlockId, Option<Vec<u8>>)>,
    candidates: Vec<Candidate>,
    ideal: Vec<BlockId>,
    wanted: Vec<Request>,
    scratch: UsageScratch,
    frame: u64,
    stats: PagerFrameStats,
    totals: PagerTotals,
    /// The first load that failed: its block and why ([`Pager::first_load_error`]).
    first_load_error: Option<String>,
}

impl Pager {
    /// A pager over `table` with nothing resident yet; call [`Pager::bootstrap`] next.
    pub fn new(table: BlockTable, opts: PagerOptions) -> Result<Pager, PagerError> {
        let roots: Vec<BlockId> = table.roots().collect();
        if opts.capacity < roots.len() as u32 {
            return Err(PagerError::CapacityBelowRoots {
                capacity: opts.capacity,
                roots: roots.len() as u32,
            });
        }
        if opts.max_queue == 0 {
            return Err(PagerError::EmptyQueue {
                max_queue: opts.max_queue,
            });
        }
        let n = table.len();
        let mut is_root = vec![false; n];
        for r in &roots {
            is_root[r.idx()] = true;
        }
        Ok(Pager {
            table,
            opts,
            state: vec![State::Absent; n],
            resident_children: vec![0; n],
            last_used: vec![0; n],
            rank: vec![u32::MAX; n],
            order: vec![u32::MAX; n],
            requested_at: vec![0; n],
            group_left_out: vec![0; n],
            failed_until: vec![0; n],
            fail_count: vec![0; n],
            is_root,
            resident: Vec::new(),
            staged: Vec::new(),
            candidates: Vec::new(),
            ideal: Vec::new(),
            wanted: Vec::new(),
            scratch: UsageScratch::default(),
            frame: 0,
            stats: PagerFrameStats::default(),
            totals: PagerTotals::default(),
            first_load_error: None,
        })
    }

    /// Loads every tree's root atlas synchronously with `fetch` (the roots are always resident) and
    /// returns their `Loaded` events.
    pub fn bootstrap(
        &mut self,
        mut fetch: impl FnMut(BlockId) -> Result<Option<Vec<u8>>, SourceError>,
    ) -> Result<Vec<Event>, PagerError> {
        let roots: Vec<BlockId> = self.table.roots().collect();
        let mut events = Vec::new();
        for block in roots {
            if self.state[block.idx()] == State::Resident {
                continue;
            }
            let data = fetch(block).map_err(|error| PagerError::RootLoad { block, error })?;
            self.make_resident(block);
            self.totals.loaded += 1;
            self.totals.bytes_loaded += self.table.meta(block).bytes;
            events.push(Event::Loaded { block, data });
        }
        self.totals.peak_resident = self.totals.peak_resident.max(self.resident.len() as u32);
        Ok(events)
    }

    pub fn table(&self) -> &BlockTable {
        &self.table
    }

    pub fn options(&self) -> &PagerOptions {
        &self.opts
    }

    /// Changes the capacity (live, e.g. a viewer slider). Never below the roots; excess resident blocks
    /// are evicted as new ones arrive (and at the end of [`Pager::accept`]).
    pub fn set_capacity(&mut self, capacity: u32) {
        let roots = self.is_root.iter().filter(|&&r| r).count() as u32;
        self.opts.capacity = capacity.max(roots);
    }

    pub fn is_resident(&self, b: BlockId) -> bool {
        self.state.get(b.idx()) == Some(&State::Resident)
    }

    /// The resident blocks (unordered).
    pub fn resident(&self) -> &[BlockId] {
        &self.resident
    }

    /// This frame's ideal set, most important first.
    pub fn ideal(&self) -> &[BlockId] {
        &self.ideal
    }

    /// The requests of the last [`Pager::plan`], most important first.
    pub fn wanted(&self) -> &[Request] {
        &self.wanted
    }

    pub fn frame_stats(&self) -> &PagerFrameStats {
        &self.stats
    }

    pub fn totals(&self) -> &PagerTotals {
        &self.totals
    }

    /// The first block whose load failed, and why ("block 21: … checksum …"): a run reported only how
    /// many failed, and `inspect --verify` had to find which (fault hunt, session 32).
    pub fn first_load_error(&self) -> Option<&str> {
        self.first_load_error.as_deref()
    }

    /// Frames planned so far.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Step 1 of a frame: usage, ranking, the ideal set, cancellations and the wanted requests (returned,
    /// most important first; hand them to the loader).
    pub fn plan(&mut self, trees: &[&[NodeRecord]], view: &ViewInput) -> &[Request] {
        self.frame += 1;
        self.stats = PagerFrameStats::default();
        self.rank_candidates(trees, view);
        self.choose_ideal_set();
        let outstanding = self.cancel_requests_left_behind();
        self.request_ideal_blocks(outstanding);
        self.collect_wanted();
        self.totals.cancelled += u64::from(self.stats.cancelled);
        &self.wanted
    }

    /// Phase 1: the usage traversal ([`classify`]) into this frame's candidates, those the policy admits
    /// (roots always), sorted roots first, then by the policy.
    fn rank_candidates(&mut self, trees: &[&[NodeRecord]], view: &ViewInput) {
        let mut view = *view;
        if !self.opts.policy.uses_lookahead() {
            view.lookahead = None;
        }
        for c in &self.candidates {
            self.order[c.block.idx()] = u32::MAX;
        }
        let mut candidates = std::mem::take(&mut self.candidates);
        classify(
            &self.table,
            trees,
            &view,
            &mut self.scratch,
            &mut candidates,
        );
        self.stats.usage = self.scratch.counts();
        let policy = self.opts.policy;
        candidates.retain(|c| policy.admits(c.usage) || self.is_root[c.block.idx()]);
        let state = &self.state;
        let is_root = &self.is_root;
        candidates.sort_unstable_by(|a, b| {
            // Roots first, always.
            is_root[b.block.idx()]
                .cmp(&is_root[a.block.idx()])
                .then_with(|| policy.compare(a, b, |c| state[c.block.idx()] == State::Resident))
        });
        for (pos, c) in candidates.iter().enumerate() {
            self.order[c.block.idx()] = pos as u32;
        }
        self.candidates = candidates;
    }

    /// Phase 2: the ideal set, the first k candidates closed under parents, an originals block taken in
    /// only with the rest of a leaf's group; stamps recency.
    fn choose_ideal_set(&mut self) {
        for &b in &self.ideal {
            self.rank[b.idx()] = u32::MAX;
        }
        self.ideal.clear();
        let k = self.opts.capacity as usize;
        let candidates = std::mem::take(&mut self.candidates);
        let mut group = Vec::new();
        for c in &candidates {
            if self.ideal.len() >= k {
                break;
            }
            if self.rank[c.block.idx()] != u32::MAX {
                continue; // taken in with a leaf's group of original blocks
            }
            if !self.parent_ideal(c.block) {
                continue;
            }
            if self.table.meta(c.block).item.is_atlas() {
                self.rank[c.block.idx()] = self.ideal.len() as u32;
                self.ideal.push(c.block);
                continue;
            }
            // An originals block only serves a leaf whose originals are all resident: take it in with the
            // rest of such a leaf's group ([`Pager::leaf_group`]) if it fits in what is left of k, or leave
            // its room to the blocks after it (shared originals, format 4: a leaf may need several blocks).
            if self.leaf_group(c.block, k - self.ideal.len(), &mut group) {
                let lead = self.order[c.block.idx()];
                for &b in &group {
                    self.rank[b.idx()] = self.ideal.len() as u32;
                    // Taken in with its lead: it ranks as the lead does (eviction order, violations).
                    self.order[b.idx()] = self.order[b.idx()].min(lead);
                    self.ideal.push(b);
                }
            } else {
                self.group_left_out[c.block.idx()] = self.frame;
            }
        }
        self.candidates = candidates;
        for &b in &self.ideal {
            self.last_used[b.idx()] = self.frame;
        }
        self.stats.ideal = self.ideal.len() as u32;
    }

    /// Phase 3: cancels requests that left the ideal set (not in flight under LRU: it never cancels);
    /// returns the requests still outstanding (requested or staged).
    fn cancel_requests_left_behind(&mut self) -> u32 {
        let cancels = self.opts.policy.cancels_in_flight();
        let mut outstanding = 0u32;
        for (i, s) in self.state.iter_mut().enumerate() {
            if *s == State::Requested {
                if self.rank[i] == u32::MAX && cancels {
                    *s = State::Absent;
                    self.stats.cancelled += 1;
                } else {
                    outstanding += 1;
                }
            }
        }
        outstanding + self.staged.len() as u32
    }

    /// Phase 4: new requests in ideal order, up to `max_queue` outstanding: absent blocks past their
    /// back-off whose parent is resident or on its way.
    fn request_ideal_blocks(&mut self, mut outstanding: u32) {
        for &b in &self.ideal {
            if outstanding >= self.opts.max_queue {
                break;
            }
            let i = b.idx();
            if self.state[i] != State::Absent || self.failed_until[i] > self.frame {
                continue;
            }
            let parent_ok = self.table.meta(b).parent.is_none_or(|p| {
                matches!(
                    self.state[p.idx()],
                    State::Resident | State::Requested | State::Staged
                )
            });
            if parent_ok {
                self.state[i] = State::Requested;
                self.requested_at[i] = self.frame;
                outstanding += 1;
            }
        }
    }

    /// Phase 5: the wanted list, every requested block by rank (LRU: by request frame, then rank).
    fn collect_wanted(&mut self) {
        self.wanted.clear();
        for (i, s) in self.state.iter().enumerate() {
            if *s == State::Requested {
                self.wanted.push(Request {
                    block: BlockId(i as u32),
                    bytes: self.table.blocks[i].bytes,
                });
            }
        }
        let rank = &self.rank;
        let at = &self.requested_at;
        if self.opts.policy.evicts_lru() {
            self.wanted
                .sort_by_key(|r| (at[r.block.idx()], rank[r.block.idx()], r.block));
        } else {
            self.wanted.sort_by_key(|r| (rank[r.block.idx()], r.block));
        }
    }

    /// Step 3 of a frame: takes the loader's arrivals, makes blocks resident in rank order within the
    /// upload budget (evicting as needed), and reports each residency change to `apply` (which uploads or
    /// frees GPU layers). Returns this frame's statistics.
    pub fn accept(
        &mut self,
        arrivals: impl IntoIterator<Item = Arrival>,
        mut apply: impl FnMut(Event) -> Applied,
    ) -> PagerFrameStats {
        for a in arrivals {
            let i = a.block.idx();
            if i >= self.state.len() {
                continue;
            }
            if self.state[i] != State::Requested {
                match &a.result {
                    // Cancelled meanwhile (or a duplicate): the bytes were wasted.
                    Ok(_) => {
                        self.stats.discarded += 1;
                        self.stats.discarded_bytes += self.table.blocks[i].bytes;
                    }
                    // A failed fetch is a failure whether or not it is still wanted (it was counted as
                    // discarded bytes: a dead server read as a slow one; fault hunt, session 34), and
                    // a cancelled block backs off as a wanted one does.
                    Err(e) => {
                        if self.state[i] == State::Absent {
                            self.back_off(a.block, Retry::transient(e.is_transient()));
                        } else {
                            self.stats.failures += 1;
                        }
                        self.note_load_error(a.block, e);
                    }
                }
                continue;
            }
            match a.result {
                Ok(data) => {
                    // The failure count is reset once the executor has the block (below), so a block
                    // whose upload keeps failing backs off ever longer instead of being fetched again
                    // every `retry_frames`.
                    self.state[i] = State::Staged;
                    self.staged.push((a.block, data));
                }
                Err(e) => {
                    self.state[i] = State::Absent;
                    self.back_off(a.block, Retry::transient(e.is_transient()));
                    self.note_load_error(a.block, &e);
                }
            }
        }
        // Most important first; parents before children (their rank is lower).
        let rank = &self.rank;
        self.staged
            .sort_by_key(|(b, _)| (rank[b.idx()], self.table.blocks[b.idx()].level, *b));
        let start = Instant::now();
        let mut accepted_bytes = 0u64;
        let mut staged = std::mem::take(&mut self.staged);
        let mut keep = Vec::new();
        for (block, data) in staged.drain(..) {
            let i = block.idx();
            if self.rank[i] == u32::MAX {
                self.state[i] = State::Absent;
                self.stats.discarded += 1;
                self.stats.discarded_bytes += self.table.blocks[i].bytes;
                continue;
            }
            let over_budget = self.stats.loaded > 0
                && match self.opts.budget {
                    UploadBudget::Unlimited => false,
                    UploadBudget::Bytes(b) => accepted_bytes >= b,
                    UploadBudget::Millis(ms) => start.elapsed().as_secs_f64() * 1e3 >= ms,
                };
            let parent_ok = self
                .table
                .meta(block)
                .parent
                .is_none_or(|p| self.state[p.idx()] == State::Resident);
            if over_budget || !parent_ok {
                keep.push((block, data));
                continue;
            }
            if self.resident.len() as u32 >= self.opts.capacity {
                let Some(victim) = self.victim() else {
                    keep.push((block, data));
                    continue;
                };
                // A victim ranked before the block it makes room for is a violation, unless it is an
                // originals block this frame's ideal set left out because its leaf's group did not fit
                // in k: that room goes to the blocks after it by design (`choose_ideal_set`).
                if self.order[victim.idx()] < self.order[i]
                    && self.group_left_out[victim.idx()] != self.frame
                {
                    self.stats.priority_violations += 1;
                }
                self.evict(victim);
                // A failed eviction leaves a stale GPU layer; the executor counts it. The block is gone
                // from residency either way.
                let _ = apply(Event::Evicted { block: victim });
            }
            self.make_resident(block);
            if let Applied::Failed(retry) = apply(Event::Loaded { block, data }) {
                // The executor could not make it usable (e.g. no free layer, a failed upload): not
                // resident, counted as a failed load (not as a load) and asked for again as `retry` says,
                // so residency never names a block that cannot be drawn. Nothing was staged after it yet,
                // so no child depends on it.
                self.unmake_resident(block);
                self.back_off(block, retry);
                continue;
            }
            let bytes = self.table.blocks[i].bytes;
            accepted_bytes += self.table.blocks[i].upload_bytes;
            self.stats.loaded += 1;
            self.stats.bytes_loaded += bytes;
            self.fail_count[i] = 0;
        }
        // Over capacity after a capacity decrease: shed the least important non-ideal blocks.
        while self.resident.len() as u32 > self.opts.capacity {
            let Some(victim) = self.victim() else { break };
            self.evict(victim);
            let _ = apply(Event::Evicted { block: victim });
        }
        self.staged = keep;
        self.finish_stats();
        self.stats
    }

    fn finish_stats(&mut self) {
        let s = &mut self.stats;
        s.resident = self.resident.len() as u32;
        s.ideal_resident = self
            .ideal
            .iter()
            .filter(|b| self.state[b.idx()] == State::Resident)
            .count() as u32;
        s.requested = self
            .state
            .iter()
            .filter(|&&st| st == State::Requested)
            .count() as u32;
        s.staged = self.staged.len() as u32;
        let t = &mut self.totals;
        t.frames += 1;
        t.loaded += u64::from(s.loaded);
        t.bytes_loaded += s.bytes_loaded;
        t.evictions += u64::from(s.evictions);
        t.discarded += u64::from(s.discarded);
        t.failures += u64::from(s.failures);
        t.peak_resident = t.peak_resident.max(s.resident);
        t.priority_violations += u64::from(s.priority_violations);
    }

    /// The resident block to evict: outside the ideal set, not a root, without resident children; the
    /// lowest-ranked (blocks that are not candidates at all first, then the worst candidate; ties: least
    /// recently used, deepest, highest id), or under LRU the least recently used.
    fn victim(&self) -> Option<BlockId> {
        let lru = self.opts.policy.evicts_lru();
        self.resident
            .iter()
            .copied()
            .filter(|b| {
                let i = b.idx();
                self.rank[i] == u32::MAX && !self.is_root[i] && self.resident_children[i] == 0
            })
            .min_by_key(|b| {
                let i = b.idx();
                let deeper_first = u32::MAX - self.table.blocks[i].level;
                let recency = self.last_used[i];
                if lru {
                    (0, recency, deeper_first, u32::MAX - b.0)
                } else {
                    // Non-candidates (order MAX) first, then the worst-ranked candidate.
                    (
                        u32::MAX - self.order[i],
                        recency,
                        deeper_first,
                        u32::MAX - b.0,
                    )
                }
            })
    }

    fn make_resident(&mut self, b: BlockId) {
        self.state[b.idx()] = State::Resident;
        self.resident.push(b);
        if let Some(p) = self.table.meta(b).parent {
            self.resident_children[p.idx()] += 1;
        }
    }

    /// The blocks not yet ideal of the most important leaf (its atlas earliest among this frame's
    /// candidates) among those that use originals block `b`, whose missing blocks are all candidates with
    /// ideal parents and fit in `room`; into `out`, `b` first. Leaves whose atlas is no candidate (not in
    /// this frame's traversal) are not considered. False (and `out` empty) when no leaf's group fits.
    fn leaf_group(&self, b: BlockId, room: usize, out: &mut Vec<BlockId>) -> bool {
        out.clear();
        let tree = self.table.meta(b).tree as usize;
        let users = self.table.users(b);
        let importance = |leaf: NodeId| {
            self.table
                .atlas(tree, leaf)
                .map_or(u32::MAX, |a| self.order[a.idx()])
        };
        let mut best: Option<(u32, NodeId)> = None;
        for &leaf in users {
            let order = importance(leaf);
            if order == u32::MAX || best.is_some_and(|(o, _)| o <= order) {
                continue;
            }
            let blocks = self.table.originals(tree, leaf);
            let mut missing = 0usize;
            let feasible = blocks.iter().all(|&x| {
                let i = x.idx();
                if self.rank[i] != u32::MAX {
                    return true;
                }
                missing += 1;
                self.order[i] != u32::MAX && self.parent_ideal(x)
            });
            if feasible && missing <= room {
                best = Some((order, leaf));
            }
        }
        let Some((_, leaf)) = best else {
            return false;
        };
        out.push(b);
        let blocks = self.table.originals(tree, leaf);
        out.extend(
            blocks
                .iter()
                .copied()
                .filter(|&x| x != b && self.rank[x.idx()] == u32::MAX),
        );
        true
    }

    /// One failure more for `b`: not requested again before the back-off (doubling per failure, capped at
    /// 64×; [`Retry::GiveUp`] goes to the cap at once).
    fn back_off(&mut self, b: BlockId, retry: Retry) {
        let i = b.idx();
        self.stats.failures += 1;
        if retry == Retry::GiveUp {
            self.fail_count[i] = self.fail_count[i].max(MAX_BACKOFF_DOUBLINGS);
        }
        let n = self.fail_count[i].min(MAX_BACKOFF_DOUBLINGS);
        self.fail_count[i] = self.fail_count[i].saturating_add(1);
        self.failed_until[i] = self.frame + u64::from(self.opts.retry_frames.max(1)) * (1u64 << n);
    }

    /// Keeps the run's first load error, for the report ([`Pager::first_load_error`]).
    fn note_load_error(&mut self, b: BlockId, e: &SourceError) {
        if self.first_load_error.is_none() {
            self.first_load_error = Some(format!("block {}: {e}", b.0));
        }
    }

    /// Removes `b` from residency (absent again), the inverse of [`Pager::make_resident`].
    fn unmake_resident(&mut self, b: BlockId) {
        self.state[b.idx()] = State::Absent;
        if let Some(pos) = self.resident.iter().position(|&r| r == b) {
            self.resident.swap_remove(pos);
        }
        if let Some(p) = self.table.meta(b).parent {
            self.resident_children[p.idx()] -= 1;
        }
    }

    /// Whether `b`'s parent (if any) is in the ideal set built so far.
    fn parent_ideal(&self, b: BlockId) -> bool {
        self.table
            .meta(b)
            .parent
            .is_none_or(|p| self.rank[p.idx()] != u32::MAX)
    }

    fn evict(&mut self, b: BlockId) {
        self.unmake_resident(b);
        self.stats.evictions += 1;
    }
}
