//! The project's own fuzzing (`cargo test --release --test fuzz`): structure-aware mutants of every input
//! atlastree reads from strangers, on stable Rust, with a fixed seed so a CI run is reproducible.
//!
//! Each target is a module with one `#[test]` that calls [`harness::run`] with a mutator. A mutator draws its
//! choices from an [`arbitrary::Unstructured`] (so the same targets can later be driven by cargo-fuzz) and
//! says what the library did with the mutant ([`harness::Verdict`]). The harness counts outcomes, catches
//! panics, flags cases that run longer than [`harness::HANG_LIMIT`], and fails the test on any panic, hang or
//! accepted corruption, writing the failing input under `target/fuzz-failures/<target>/` so it can be
//! committed to `tests/fuzz/corpus/<target>/` as a regression case. Every file in a target's corpus folder
//! is replayed first, on every run.
//!
//! - CI: the defaults, a few thousand cases over all targets (`ATLASTREE_FUZZ_CASES` per target unset).
//! - A long run: `ATLASTREE_FUZZ_CASES=25000 ATLASTREE_FUZZ_SEED=$RANDOM cargo test --release --test fuzz
//!   -- --nocapture` (each target prints its counts; ≥ 100 k cases over the targets).

#![allow(
    clippy::unwrap_used,
    clippy::expect_used,
    clippy::panic,
    reason = "test code: a failed unwrap is a failed test"
)]

#[allow(dead_code)] // targets arrive module by module
mod harness;

mod camera_path;
mod gltf;
mod http;
mod json_mut;
mod paging_file;
mod plan_file;
mod shard_file;
mod sweep_grid;
#[path = "../fixtures/tiny_store.rs"]
mod tiny_store;

/// Every folder under `tests/fuzz/corpus/` is named after a target ([`harness::TARGETS`]) and holds at
/// least one input, so every committed regression input is replayed.
#[test]
fn every_corpus_folder_belongs_to_a_target() {
    let mut folders = Vec::new();
    for entry in std::fs::read_dir(harness::corpus_root()).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name().to_string_lossy().into_owned();
        assert!(
            harness::TARGETS.contains(&name.as_str()),
            "tests/fuzz/corpus/{name} is no target's corpus (targets: {:?})",
            harness::TARGETS
        );
        let inputs = std::fs::read_dir(entry.path()).unwrap().count();
        assert!(inputs > 0, "tests/fuzz/corpus/{name} is empty");
        folders.push(name);
    }
    assert!(folders.len() >= 5, "corpus folders: {folders:?}");
}
