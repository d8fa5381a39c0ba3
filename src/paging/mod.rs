//! Prioritised block paging (paper §6): usage categories, the ideal block set under a capacity `k`, the
//! request queue, residency, drawing with missing blocks, and the block sources the loaders read from.
//!
//! ```text
//! cut/camera ──usage::classify──▶ candidates ──Policy──▶ ideal set (≤ k, parent-closed)
//!                                                          │ wanted requests (≤ max_queue, re-ranked)
//!                                              Loader ◀────┘   (ImmediateLoader | ThreadedLoader | sim)
//!                                                │ arrivals
//!                       Pager::accept (budget, eviction) ──▶ Events (Loaded / Evicted) ──▶ GPU layers
//!  cut + residency ──resolve──▶ draw with the nearest resident ancestor; Coarseness (screen share)
//! ```
//!
//! Everything here is plain CPU data and deterministic given the arrivals; the renderer and the simulator
//! drive the same [`Pager`].

pub mod blocks;
pub mod budget;
pub mod http;
pub mod loader;
pub mod pager;
pub mod policy;
pub mod residency;
pub mod resolve;
pub mod session;
pub mod source;
pub mod usage;

pub use blocks::{BlockItem, BlockMeta, BlockTable, BlockTableError};
pub use http::{HttpOptions, HttpSource, HttpStats};
pub use loader::{ImmediateLoader, Loader, ThreadedLoader};
pub use pager::{
    Applied, Arrival, Event, Pager, PagerError, PagerFrameStats, PagerOptions, PagerTotals,
    Request, UploadBudget, resident_fingerprint,
};
pub use policy::Policy;
pub use residency::{ResidencyError, Retry};
pub use resolve::{Coarseness, Resolved, resolve, resolve_cut, screen_fraction};
pub use session::{PagingSession, SessionFrame, resolve_frame};
pub use source::{BlockSource, FileSource, SourceError};
pub use usage::{Candidate, Usage, UsageCounts, ViewInput};
