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
//! The submodules are private: everything a caller uses is re-exported here, under one path (and the
//! range server as [`serve`]).
//!
//! Everything here is plain CPU data and deterministic given the arrivals; the renderer and the simulator
//! drive the same [`Pager`].

mod blocks;
mod budget;
mod http;
mod loader;
mod pager;
mod policy;
mod residency;
mod resolve;
mod session;
mod source;
mod usage;

pub use blocks::{BlockItem, BlockMeta, BlockTable, BlockTableError};
pub use budget::UploadBudget;
pub use http::{HttpOptions, HttpSource, HttpStats, redact_url, serve};
pub use loader::{ImmediateLoader, Loader, ThreadedLoader};
pub use pager::{
    Applied, Arrival, Event, Pager, PagerError, PagerFrameStats, PagerOptions, PagerTotals,
    Request, resident_fingerprint,
};
pub use policy::Policy;
pub use residency::{ResidencyError, Retry};
pub use resolve::{Coarseness, Resolved, resolve, resolve_cut, screen_fraction};
pub use session::{PagingSession, SessionFrame, resolve_frame};
pub use source::{BlockSource, FileSource, SourceError};
pub use usage::{Candidate, Usage, UsageCounts, UsageScratch, ViewInput, classify};
