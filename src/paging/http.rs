//! Blocks over HTTP (paper §6 "dynamic loading" from a remote store): a [`BlockSource`] that reads the
//! paging file from any static file server with HTTP/1.1 range requests, and `atlastree serve`, a small
//! range-capable server for the file.
//!
//! - [`HttpSource`] (blocking, [`ureq`]): [`HttpSource::open`] fetches the header and the tables with range
//!   requests and validates them ([`TreeFile::from_prefix`]); [`BlockSource::fetch`] fetches one block
//!   with `Range: bytes=a-b`, with timeouts, bounded retries and exponential backoff, and verifies the
//!   block's checksum on arrival. Counters ([`HttpStats`]) tell the renderer when the source is failing.
//! - [`serve`]: axum routing on hyper connections (a connection limit, header and I/O timeouts, ranges
//!   streamed from the file, [`range`] for the `Range` rules) on a small tokio runtime; [`serve::spawn`]
//!   for tests and tools, `atlastree serve FILE --port P` for people.
//!
//! [`BlockSource`]: super::BlockSource
//! [`BlockSource::fetch`]: super::BlockSource::fetch
//! [`TreeFile::from_prefix`]: crate::store::TreeFile::from_prefix

mod client;
pub(super) mod range;
pub mod serve;

pub use client::{HttpOptions, HttpSource, HttpStats, redact_url};
