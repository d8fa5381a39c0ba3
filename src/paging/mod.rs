//! Prioritised block paging (paper §6): usage categories, the ideal block set under a capacity `k`, the
//! request queue, residency, and the block sources the loader reads from.

pub mod http;
pub mod source;

pub use http::{HttpOptions, HttpSource, HttpStats};
pub use source::{BlockSource, FileSource, SourceError};
