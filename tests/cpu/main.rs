//! Every CPU integration test, in one binary (`cargo test --test cpu`): one link of the dependency graph
//! instead of one per file. Modules follow the library's subjects, not the issues that added them; filter
//! by path, e.g. `cargo test --test cpu -- preprocess::` or `-- select::props`.
//!
//! Helpers: [`built`] (tiny builds into temp dirs and the checks every built tree gets) and
//! `tests/fixtures/` (scenes and trees shared with the GPU suite `tests/gpu` and the benches in
//! `tools/bench`). Timings are criterion benches in `tools/bench`, not tests.
//!
//! Proptest keeps the seeds of past failures in `tests/proptest-regressions/<module path>.txt` (its
//! default: a sibling of the directory that holds this `main.rs`, e.g. `paging/props.txt` for
//! `paging/props.rs`); commit them.

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test code: a failed unwrap is a failed test"
)]

mod built;
#[path = "../fixtures/mod.rs"]
mod fixtures;

mod architecture;
mod build_faults;
mod camera;
mod citygen;
mod cli;
mod docs;
mod export;
mod import;
mod paging;
mod plan;
mod preprocess;
mod render;
mod report;
mod select;
mod shaders;
mod shard;
mod shard_images;
mod shard_plan;
mod shared_originals;
mod sim;
mod store;
mod store_bytes;
mod sweep;
mod texfmt;
mod tour;
mod views;
