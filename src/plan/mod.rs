//! The frame planner: what a frame draws, decided on the CPU as plain data (vello's "decide on the CPU,
//! execute on the GPU"). Camera, clock and min-distance scale go in; a [`FramePlan`] comes out:
//!
//! 1. **select** (paper §4): the cut of every tree for the selecting camera (the frame's, or a frozen one);
//! 2. **page** (§6, only when blocks are paged): usage and ideal set under the capacity k, the request
//!    queue handed to the loader, arrivals accepted; each residency change is handed to the executor's
//!    [`Residency`] as it happens, and a change the executor cannot apply is taken back by the pager (the
//!    block is not resident, counted as a failed load and retried), so residency never names a block
//!    that cannot be drawn;
//! 3. **resolve**: every cut item against the pager's residency (drawing with missing blocks: the nearest
//!    resident ancestor atlas), with the screen-space accounting of what is drawn coarser.
//!
//! The renderer executes a plan (colour or density pass, as often as it likes, without stepping the
//! pager again); the simulator records it with [`RecordResidency`]; the viewer, `render` and `sweep` drive the
//! same planner. This is the one per-frame loop of the code base.
//!
//! Clock: every paged plan names its time (seconds); it must not run backwards
//! ([`PlanError::TimeBackwards`]). [`FramePlanner::plan_still`] plans without paging (select and resolve
//! against current residency, no clock), for warm-up draws and previews.

use crate::camera::{Camera, Frustum};
use crate::ids::BlockId;
use crate::paging::{
    Applied, BlockSource, BlockTable, BlockTableError, Coarseness, Event, ImmediateLoader, Loader,
    Pager, PagerError, PagerFrameStats, PagerOptions, PagingSession, ResidencyError, Resolved,
    SessionFrame, SourceError, ThreadedLoader, resident_fingerprint, resolve_frame,
};
use crate::select::{Cut, select};
use crate::store::TreeFile;
use crate::store::format::NodeRecord;
use std::borrow::Cow;
use std::sync::Arc;
use std::time::Instant;

/// Where the executor applies residency changes (GPU uploads and frees for the renderer; nothing for the
/// simulator).
pub trait Residency {
    /// Applies one change of the pager; returns the bytes uploaded. An error means the change could not
    /// be applied: for a loaded block the pager then takes it back (drawn coarser) and asks for it again
    /// as the error's [`ResidencyError::retry`] says.
    fn apply(&mut self, event: &Event) -> Result<u64, ResidencyError>;

    /// Whether [`Residency::apply`] reports real uploads. An executor that uploads nothing (the
    /// simulator's) has its loads counted at the bytes a renderer uploads for them and the byte budget
    /// counts ([`crate::paging::BlockMeta::upload_bytes`]), so `bytes_uploaded` means the same in both.
    fn uploads(&self) -> bool {
        true
    }
}

/// The simulator's executor: nothing to upload, every change applies.
#[derive(Copy, Clone, Debug, Default)]
pub struct NoResidency;

impl Residency for NoResidency {
    fn apply(&mut self, _: &Event) -> Result<u64, ResidencyError> {
        Ok(0)
    }

    fn uploads(&self) -> bool {
        false
    }
}

/// A recorder: applies nothing, hands every change to a closure (the simulator's event log).
pub struct RecordResidency<F: FnMut(&Event)>(pub F);

impl<F: FnMut(&Event)> Residency for RecordResidency<F> {
    fn apply(&mut self, event: &Event) -> Result<u64, ResidencyError> {
        (self.0)(event);
        Ok(0)
    }

    fn uploads(&self) -> bool {
        false
    }
}

/// Errors of planning.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    #[error(transparent)]
    Pager(#[from] PagerError),
    #[error(transparent)]
    Blocks(#[from] BlockTableError),
    #[error("starting loader threads: {0}")]
    Loader(std::io::Error),
    #[error("root atlas {block} could not be made resident")]
    RootApply {
        block: BlockId,
        #[source]
        error: ResidencyError,
    },
    #[error("the planner does not page (a paged run was asked of an all-resident planner)")]
    NotPaged,
    #[error("the frame clock is not a finite time: {time}")]
    TimeNotFinite { time: f64 },
    #[error("the frame clock ran backwards: {time} s after {last} s")]
    TimeBackwards { time: f64, last: f64 },
    #[error("{cameras} cameras but {scales} min-distance scales (one per camera)")]
    ScaleCount { cameras: usize, scales: usize },
}

/// How a paged planner gets its blocks.
pub struct PagingSetup {
    pub pager: PagerOptions,
    pub source: Arc<dyn BlockSource>,
    /// Loader threads; 0 loads synchronously inside the frame (deterministic, for tests and comparisons).
    pub loader_threads: usize,
}

/// Paging counters of one plan (the paging columns of `stats.csv` and `frames.csv`).
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct PagingFrame {
    pub session: SessionFrame,
    /// Screen accounting of the draws: share rendered coarser than the selection asked for.
    pub coarse: Coarseness,
    /// Time spent in the executor applying residency changes (uploads, frees), ms, and bytes it uploaded.
    pub upload_ms: f64,
    pub uploaded_bytes: u64,
    /// Of the bytes the pager loaded this frame, those of original-texture blocks (the rest are atlases).
    pub loaded_original_bytes: u64,
    /// Bytes of the resident blocks after the frame, atlases and original textures apart.
    pub resident_atlas_bytes: u64,
    pub resident_original_bytes: u64,
    /// `xxh3_64` of the sorted resident block ids (compared between renderer and simulator).
    pub resident_hash: u64,
    /// Loads the executor could not apply this frame (taken back by the pager, drawn coarser, retried).
    pub apply_errors: u32,
    /// Evictions the executor could not apply this frame (the block is gone from residency either way;
    /// the executor's bookkeeping reported a broken invariant).
    pub evict_errors: u32,
}

impl PagingFrame {
    /// The pager's counters of the frame (usage, residency, loads, bytes, failures).
    pub fn pager(&self) -> &PagerFrameStats {
        &self.session.pager
    }
}

/// Counters of one plan.
#[derive(Copy, Clone, Debug, Default, PartialEq)]
pub struct PlanStats {
    /// Nodes evaluated by the traversals (all trees), culled ones included.
    pub nodes_visited: u32,
    /// Cut items (selected nodes) of all trees.
    pub nodes_drawn: u32,
    /// CPU time of the traversal (select), µs.
    pub select_us: f64,
    /// CPU time of the paging step and resolution, µs (0 when not paged).
    pub page_us: f64,
    /// `None` when every block is resident.
    pub paging: Option<PagingFrame>,
}

/// One frame, decided: plain data the renderer executes and the simulator records.
#[derive(Clone, Debug)]
pub struct FramePlan {
    /// Plans made so far by this planner, this one included (1 for the first).
    pub frame: u64,
    /// Clock time of the plan, seconds (`None` for [`FramePlanner::plan_still`]).
    pub time: Option<f64>,
    /// The camera the frame is drawn with, and the one the cut was selected for (they differ while the
    /// selection is frozen).
    pub camera: Camera,
    pub selector: Camera,
    /// `min_distance` scale of the selection ([`crate::select::min_distance_scale`]).
    pub scale: f64,
    /// One cut per tree.
    pub cuts: Vec<Cut>,
    /// Per tree and cut item, how it is drawn with the resident blocks; `None` when every block is
    /// resident (every item as selected).
    pub resolved: Option<Vec<Vec<Resolved>>>,
    pub stats: PlanStats,
}

impl FramePlan {
    /// The resolution of tree `t`'s cut (`None`: every item as selected).
    pub fn resolved(&self, t: usize) -> Option<&[Resolved]> {
        self.resolved
            .as_ref()
            .and_then(|r| r.get(t))
            .map(Vec::as_slice)
    }
}

struct PagingState {
    session: PagingSession,
    loader: Box<dyn Loader>,
    table: BlockTable,
    /// The capacity the executor was sized for: `set_capacity` never goes above it.
    max_capacity: u32,
    /// Root loads of the bootstrap, applied to the executor at the first plan.
    pending: Vec<Event>,
    last_time: Option<f64>,
    last_error: Option<String>,
}

/// Plans frames of one set of trees. See the module docs.
pub struct FramePlanner<'a> {
    /// Borrowed where the caller holds them; a paging file's are copies (`from_file`,
    /// `paged_from_file`), so a file rewritten in place while it is drawn cannot change the selection
    /// under the frames.
    trees: Vec<Cow<'a, [NodeRecord]>>,
    paging: Option<PagingState>,
    frozen: Option<Camera>,
    plan: Option<FramePlan>,
}

impl<'a> FramePlanner<'a> {
    /// This planner selecting from copies of `file`'s node tables ([`file_trees_copied`]), taken now.
    fn with_copied_trees(mut self, file: &TreeFile) -> Self {
        self.trees = file_trees_copied(file)
            .into_iter()
            .map(Cow::Owned)
            .collect();
        self
    }

    /// Tree `t`'s node table as the planner selects from it (its own copy for a paging file).
    pub fn tree(&self, t: usize) -> Option<&[NodeRecord]> {
        self.trees.get(t).map(|t| &**t)
    }

    /// A planner with every block resident (no paging).
    pub fn new(trees: Vec<&'a [NodeRecord]>) -> FramePlanner<'a> {
        FramePlanner {
            trees: trees.into_iter().map(Cow::Borrowed).collect(),
            paging: None,
            frozen: None,
            plan: None,
        }
    }

    /// Every tree of `file`, every block resident.
    pub fn from_file(file: &'a TreeFile) -> FramePlanner<'a> {
        FramePlanner::new(Vec::new()).with_copied_trees(file)
    }

    /// A paging planner: the pager with `opts` (capacity clamped to the table's blocks), the root atlases
    /// fetched now with `fetch_root` (applied to the executor at the first plan), `loader` for the rest.
    pub fn paged(
        trees: Vec<&'a [NodeRecord]>,
        table: BlockTable,
        mut opts: PagerOptions,
        loader: Box<dyn Loader>,
        fetch_root: impl FnMut(BlockId) -> Result<Option<Vec<u8>>, SourceError>,
    ) -> Result<FramePlanner<'a>, PlanError> {
        opts.capacity = opts.capacity.min(table.len().max(1) as u32);
        let mut pager = Pager::new(table.clone(), opts)?;
        let pending = pager.bootstrap(fetch_root)?;
        let max_capacity = pager.options().capacity;
        Ok(FramePlanner {
            trees: trees.into_iter().map(Cow::Borrowed).collect(),
            paging: Some(PagingState {
                session: PagingSession::new(pager),
                loader,
                table,
                max_capacity,
                pending,
                last_time: None,
                last_error: None,
            }),
            frozen: None,
            plan: None,
        })
    }

    /// A paging planner over `file` whose blocks come from `setup.source` (the renderer's and viewer's).
    pub fn paged_from_file(
        file: &'a TreeFile,
        setup: PagingSetup,
    ) -> Result<FramePlanner<'a>, PlanError> {
        let table = BlockTable::from_file(file)?;
        let records = file.blocks().to_vec();
        let source = setup.source;
        let fetch = {
            let (source, records) = (source.clone(), records.clone());
            move |b: BlockId| {
                let r = records.get(b.idx()).ok_or(SourceError::NotInTable {
                    block: b,
                    blocks: records.len() as u64,
                })?;
                source.fetch(b, r).map(Some)
            }
        };
        let loader: Box<dyn Loader> = if setup.loader_threads == 0 {
            Box::new(ImmediateLoader::new(source, records))
        } else {
            Box::new(
                ThreadedLoader::new(source, records, setup.loader_threads)
                    .map_err(PlanError::Loader)?,
            )
        };
        let planner = FramePlanner::paged(Vec::new(), table, setup.pager, loader, fetch)?;
        Ok(planner.with_copied_trees(file))
    }

    /// The pager (`None` when every block is resident).
    pub fn pager(&self) -> Option<&Pager> {
        self.paging.as_ref().map(|p| &p.session.pager)
    }

    /// The block table of a paging planner.
    pub fn table(&self) -> Option<&BlockTable> {
        self.paging.as_ref().map(|p| &p.table)
    }

    /// The capacity the executor must be sized for (`None` when not paged): the capacity at creation,
    /// clamped to the number of blocks.
    pub fn max_capacity(&self) -> Option<u32> {
        self.paging.as_ref().map(|p| p.max_capacity)
    }

    /// Changes the capacity k live (a viewer slider), clamped to [`FramePlanner::max_capacity`]: k counts
    /// atlas and original-texture blocks alike, and the executor's arrays hold any k blocks up to that.
    pub fn set_capacity(&mut self, capacity: u32) {
        if let Some(p) = &mut self.paging {
            p.session
                .pager
                .set_capacity(capacity.min(p.max_capacity.max(1)));
        }
    }

    /// The root loads of the bootstrap not yet applied, taken: an executor that holds the roots already (or
    /// a simulator whose log starts with the first frame) takes them; otherwise the first plan applies them.
    pub fn take_bootstrap(&mut self) -> Vec<Event> {
        self.paging
            .as_mut()
            .map(|p| std::mem::take(&mut p.pending))
            .unwrap_or_default()
    }

    /// The last residency change the executor could not apply, if any.
    pub fn last_error(&self) -> Option<&str> {
        self.paging.as_ref().and_then(|p| p.last_error.as_deref())
    }

    /// The first block whose load failed and why ([`crate::paging::Pager::first_load_error`]); `None`
    /// when none did or nothing is paged.
    pub fn first_load_error(&self) -> Option<&str> {
        (self.paging.as_ref()).and_then(|p| p.session.pager.first_load_error())
    }

    /// What went wrong while paging, as warnings for the end of a run (`render`) or a session (`view`):
    /// the last residency change that failed and the first failed block load, each drawn coarser
    /// meanwhile; empty where nothing failed.
    pub fn failure_warnings(&self) -> Vec<String> {
        let mut out = Vec::new();
        if let Some(e) = self.last_error() {
            out.push(format!(
                "residency changes failed (drawn coarser, counted in apply_errors); the last: {e}"
            ));
        }
        if let Some(e) = self.first_load_error() {
            out.push(format!(
                "block loads failed (those nodes were drawn coarser); the first: {e}"
            ));
        }
        out
    }

    /// Selects every following plan's cut for `camera` instead of the frame's own camera (`None`: the
    /// frame's camera again): the viewer's "freeze selection". Draws still use the frame's camera.
    pub fn freeze_selection(&mut self, camera: Option<Camera>) {
        self.frozen = camera;
    }

    /// The last plan made.
    pub fn last(&self) -> Option<&FramePlan> {
        self.plan.as_ref()
    }

    /// Plans the frame of `camera` at clock `time` (seconds) with min-distance `scale`: select, one
    /// paging step whose residency changes go to `residency`, resolve. See the module docs.
    pub fn plan(
        &mut self,
        camera: &Camera,
        time: f64,
        scale: f64,
        residency: &mut dyn Residency,
    ) -> Result<&FramePlan, PlanError> {
        self.plan_inner(camera, Some(time), scale, residency)
    }

    /// Plans `camera` without a paging step: select, and resolve against the residency as it is (no
    /// clock, no loads, no evictions). For warm-up draws and previews; a paged executor must already hold
    /// the roots, so this applies the bootstrap's root loads if no plan did yet.
    pub fn plan_still(
        &mut self,
        camera: &Camera,
        scale: f64,
        residency: &mut dyn Residency,
    ) -> Result<&FramePlan, PlanError> {
        self.plan_inner(camera, None, scale, residency)
    }

    /// The phases of a plan: check the clock, apply the bootstrap's pending root loads, select, and (paged
    /// only) one paging step at `time` (none for `None`) and the resolution against residency.
    fn plan_inner(
        &mut self,
        camera: &Camera,
        time: Option<f64>,
        scale: f64,
        residency: &mut dyn Residency,
    ) -> Result<&FramePlan, PlanError> {
        self.check_clock(time)?;
        if let Some(p) = &mut self.paging {
            p.apply_pending(residency)?;
        }
        let t0 = Instant::now();
        let selector = self.frozen.unwrap_or(*camera);
        let frustum = selector.frustum();
        let previous = self.plan.take();
        let frame = previous.as_ref().map_or(0, |p| p.frame) + 1;
        let (mut cuts, reuse_resolved) =
            previous.map_or((Vec::new(), None), |p| (p.cuts, p.resolved));
        let trees: Vec<&[NodeRecord]> = self.trees.iter().map(|t| &**t).collect();
        let mut stats = select_cuts(&trees, &selector, &frustum, scale, &mut cuts);
        let t1 = Instant::now();
        stats.select_us = (t1 - t0).as_secs_f64() * 1e6;
        let mut resolved = None;
        if let Some(p) = &mut self.paging {
            let view = View {
                trees: &trees,
                selector: &selector,
                frustum: &frustum,
                scale,
            };
            let mut frame_stats = match time {
                Some(now) => p.step(&view, now, residency),
                // Nothing happened: the state of the last step, none of its per-frame deltas.
                None => PagingFrame {
                    session: SessionFrame {
                        pager: p.session.pager.frame_stats().state_only(),
                        ..SessionFrame::default()
                    },
                    ..PagingFrame::default()
                },
            };
            let mut out = reuse_resolved.unwrap_or_default();
            p.resolve(&view, &cuts, &mut frame_stats, &mut out);
            resolved = Some(out);
            stats.paging = Some(frame_stats);
            stats.page_us = t1.elapsed().as_secs_f64() * 1e6;
        }
        Ok(self.plan.insert(FramePlan {
            frame,
            time,
            camera: *camera,
            selector,
            scale,
            cuts,
            resolved,
            stats,
        }))
    }

    /// A plan's time must be finite, and a paged plan's must not run backwards.
    fn check_clock(&self, time: Option<f64>) -> Result<(), PlanError> {
        if let Some(t) = time
            && !t.is_finite()
        {
            return Err(PlanError::TimeNotFinite { time: t });
        }
        if let (Some(p), Some(t)) = (&self.paging, time)
            && let Some(last) = p.last_time
            && t < last
        {
            return Err(PlanError::TimeBackwards { time: t, last });
        }
        Ok(())
    }
}

/// The cut of every tree for `selector` into `cuts` (one per tree; the previous plan's, reused), and the
/// plan's counters of the traversal.
fn select_cuts(
    trees: &[&[NodeRecord]],
    selector: &Camera,
    frustum: &Frustum,
    scale: f64,
    cuts: &mut Vec<Cut>,
) -> PlanStats {
    cuts.resize_with(trees.len(), Cut::new);
    let mut stats = PlanStats::default();
    for (nodes, cut) in trees.iter().zip(cuts.iter_mut()) {
        select(nodes, selector, frustum, scale, cut);
        stats.nodes_visited += cut.visited;
        stats.nodes_drawn += cut.items.len() as u32;
    }
    stats
}

/// What the paging phases of one plan look at.
struct View<'v, 'a> {
    trees: &'v [&'a [NodeRecord]],
    selector: &'v Camera,
    frustum: &'v Frustum,
    scale: f64,
}

/// Hands a paging step's residency changes to the executor and counts what came of them.
struct Applier<'r, 't> {
    residency: &'r mut dyn Residency,
    table: &'t BlockTable,
    apply_time: std::time::Duration,
    uploaded: u64,
    loaded_originals: u64,
    load_errors: u32,
    evict_errors: u32,
    last_error: Option<String>,
}

impl Applier<'_, '_> {
    /// Applies one change; a failed one is counted (load or eviction) and handed back to the pager.
    fn apply(&mut self, ev: &Event) -> Applied {
        let t = Instant::now();
        let result = self.residency.apply(ev);
        self.apply_time += t.elapsed();
        let load = match ev {
            Event::Loaded { block, .. } => Some(*block),
            Event::Evicted { .. } => None,
        };
        match result {
            Ok(bytes) => {
                self.uploaded += match load {
                    Some(block) if !self.residency.uploads() => self.table.meta(block).upload_bytes,
                    _ => bytes,
                };
                if let Some(block) = load {
                    self.loaded_originals += self.table.bytes_by_kind([block]).1;
                }
                Applied::Done
            }
            Err(e) => {
                if load.is_some() {
                    self.load_errors += 1;
                } else {
                    self.evict_errors += 1;
                }
                let retry = e.retry();
                self.last_error = Some(e.to_string());
                Applied::Failed(retry)
            }
        }
    }
}

impl PagingState {
    /// Applies the bootstrap's root loads, one at a time, each removed once applied: after an error the
    /// rest stay pending for a retry.
    fn apply_pending(&mut self, residency: &mut dyn Residency) -> Result<(), PlanError> {
        while let Some(ev) = self.pending.first() {
            let block = match ev {
                Event::Loaded { block, .. } | Event::Evicted { block } => *block,
            };
            residency
                .apply(ev)
                .map_err(|error| PlanError::RootApply { block, error })?;
            self.pending.remove(0);
        }
        Ok(())
    }

    /// One paging step at clock `now`, its residency changes applied through `residency`.
    fn step(
        &mut self,
        view: &View<'_, '_>,
        now: f64,
        residency: &mut dyn Residency,
    ) -> PagingFrame {
        self.last_time = Some(now);
        let mut applier = Applier {
            residency,
            table: &self.table,
            apply_time: std::time::Duration::ZERO,
            uploaded: 0,
            loaded_originals: 0,
            load_errors: 0,
            evict_errors: 0,
            last_error: None,
        };
        let session = self.session.frame(
            view.trees,
            view.selector,
            view.frustum,
            view.scale,
            now,
            &mut *self.loader,
            |ev| applier.apply(&ev),
        );
        if applier.last_error.is_some() {
            self.last_error = applier.last_error;
        }
        PagingFrame {
            session,
            upload_ms: applier.apply_time.as_secs_f64() * 1e3,
            uploaded_bytes: applier.uploaded,
            loaded_original_bytes: applier.loaded_originals,
            apply_errors: applier.load_errors,
            evict_errors: applier.evict_errors,
            ..PagingFrame::default()
        }
    }

    /// Resolves every cut item against the pager's residency into `out`, with the screen accounting and the
    /// resident bytes and fingerprint in `frame`.
    fn resolve(
        &self,
        view: &View<'_, '_>,
        cuts: &[Cut],
        frame: &mut PagingFrame,
        out: &mut Vec<Vec<Resolved>>,
    ) {
        let pager = &self.session.pager;
        let table = &self.table;
        frame.coarse = resolve_frame(
            view.trees,
            cuts,
            view.selector,
            |t, n| table.atlas(t, n).is_some_and(|b| pager.is_resident(b)),
            |t, n| table.originals(t, n).iter().all(|&b| pager.is_resident(b)),
            out,
        );
        let (atlases, originals) = table.bytes_by_kind(pager.resident().iter().copied());
        frame.resident_atlas_bytes = atlases;
        frame.resident_original_bytes = originals;
        frame.resident_hash = resident_fingerprint(pager.resident());
    }
}

/// [`file_trees`] copied out of the file (104 bytes a node): what a planner drawing a paging file
/// selects from, so bytes rewritten in place under a memory map cannot change the nodes it draws (frames
/// of no geometry, no warning); the blocks are fetched through their copied records and checksums.
pub fn file_trees_copied(file: &TreeFile) -> Vec<Vec<NodeRecord>> {
    file_trees(file).into_iter().map(<[_]>::to_vec).collect()
}

/// The node tables of every tree of `file`, in tree order.
pub fn file_trees(file: &TreeFile) -> Vec<&[NodeRecord]> {
    (0..file.trees())
        .filter_map(|t| file.tree(t).map(|v| v.nodes))
        .collect()
}
