//! The fuzz driver shared by every target: seeded inputs, corpus replay, panic and hang detection, counts.
//!
//! A case is a byte string. A target's mutator turns it into a structured mutant (through
//! [`arbitrary::Unstructured`]) and feeds it to the library; the same bytes always give the same mutant, so
//! a failing case is reproduced by its bytes alone (saved under `target/fuzz-failures/<target>/`, committed
//! under `tests/fuzz/corpus/<target>/`).

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// A case running longer than this is a hang (the test fails and names the case).
pub const HANG_LIMIT: Duration = Duration::from_secs(20);
/// Bytes of seeded input per case: plenty of choices for every mutator here.
pub const INPUT_LEN: usize = 512;

/// What the library did with one mutant.
#[derive(Debug)]
pub enum Verdict {
    /// Read or run without error (the mutant was harmless, or the change was benign and allowed).
    Accepted,
    /// Refused with an error (the message, for the counts and the sample printed at the end).
    Refused(String),
    /// Accepted although it must have been refused (a corrupt file passing its checks): a failure.
    AcceptedCorruption(String),
    /// The mutator could not build a mutant from these bytes (not counted as a case).
    Skipped,
}

/// The counts of one run of one target.
#[derive(Debug, Default)]
pub struct Counts {
    pub cases: u64,
    pub corpus_cases: u64,
    pub accepted: u64,
    pub refused: u64,
    pub skipped: u64,
    pub panics: u64,
    pub hangs: u64,
    pub accepted_corruptions: u64,
}

/// Cases per target: `ATLASTREE_FUZZ_CASES`, or the target's default (a CI-sized run).
pub fn cases(default: u64) -> u64 {
    std::env::var("ATLASTREE_FUZZ_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

/// The run's seed: `ATLASTREE_FUZZ_SEED`, else a fixed one (CI is reproducible).
pub fn seed() -> u64 {
    std::env::var("ATLASTREE_FUZZ_SEED")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(0x5EED_A71A_5EED)
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The seeded input of case `index`: `INPUT_LEN` bytes from SplitMix64 of `(seed, index)`.
pub fn input(seed: u64, index: u64) -> Vec<u8> {
    let mut state = seed ^ index.wrapping_mul(0xD1B5_4A32_D192_ED03);
    let mut out = Vec::with_capacity(INPUT_LEN);
    while out.len() < INPUT_LEN {
        out.extend_from_slice(&splitmix64(&mut state).to_le_bytes());
    }
    out.truncate(INPUT_LEN);
    out
}

/// Every target's name, as it calls [`run`] and names its corpus folder: a target renamed without its
/// folder (or a folder renamed) would silently drop the folder's regression inputs, so both are checked
/// against this list.
pub const TARGETS: [&str; 7] = [
    "camera_path",
    "gltf",
    "http",
    "paging_file",
    "plan_file",
    "shard_file",
    "sweep_grid",
];

/// The folder that holds every target's corpus folder.
pub fn corpus_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fuzz/corpus")
}

fn corpus_dir(target: &str) -> PathBuf {
    corpus_root().join(target)
}

fn failure_dir(target: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("target/fuzz-failures")
        .join(target)
}

/// The target's committed regression inputs, sorted by name.
fn corpus(target: &str) -> Vec<(String, Vec<u8>)> {
    let Ok(dir) = std::fs::read_dir(corpus_dir(target)) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = dir.filter_map(|e| e.ok().map(|e| e.path())).collect();
    files.sort();
    files
        .into_iter()
        .filter(|p| p.is_file())
        .map(|p| {
            let name = p
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_default();
            let bytes = std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (name, bytes)
        })
        .collect()
}

/// The outcome of running one case on a worker thread.
enum Outcome {
    Verdict(Verdict),
    Panic(String),
    Hang,
}

type Mutator = Arc<dyn Fn(&[u8]) -> Verdict + Send + Sync>;

fn run_case(mutator: &Mutator, bytes: &[u8]) -> Outcome {
    let (tx, rx) = mpsc::channel();
    let m = Arc::clone(mutator);
    let data = bytes.to_vec();
    std::thread::spawn(move || {
        let r = catch_unwind(AssertUnwindSafe(|| m(&data)));
        let _ = tx.send(r);
    });
    match rx.recv_timeout(HANG_LIMIT) {
        Ok(Ok(v)) => Outcome::Verdict(v),
        Ok(Err(payload)) => {
            let msg = payload
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| payload.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_else(|| "(non-string panic)".into());
            Outcome::Panic(msg)
        }
        Err(_) => Outcome::Hang,
    }
}

/// Runs `target`: its corpus first, then `cases(default_cases)` seeded inputs. Prints the counts and
/// fails (panics) if any case panicked, hung or was an accepted corruption, after saving those inputs.
pub fn run(
    target: &str,
    default_cases: u64,
    mutator: impl Fn(&[u8]) -> Verdict + Send + Sync + 'static,
) -> Counts {
    assert!(
        TARGETS.contains(&target),
        "fuzz target {target} is not in harness::TARGETS"
    );
    let mutator: Mutator = Arc::new(mutator);
    let seed = seed();
    let n = cases(default_cases);
    let mut counts = Counts::default();
    let mut failures: Vec<(String, String, Vec<u8>)> = Vec::new();
    let mut refusals: std::collections::BTreeMap<String, u64> = Default::default();
    let start = Instant::now();
    let corpus = corpus(target);
    let seeded = (0..n).map(|i| (format!("seed-{seed}-case-{i}"), input(seed, i)));
    let all = corpus
        .into_iter()
        .map(|(name, b)| (name, b, true))
        .chain(seeded.map(|(n, b)| (n, b, false)));
    for (name, bytes, from_corpus) in all {
        let outcome = run_case(&mutator, &bytes);
        let failure = match outcome {
            Outcome::Verdict(Verdict::Skipped) => {
                counts.skipped += 1;
                continue;
            }
            Outcome::Verdict(Verdict::Accepted) => {
                counts.accepted += 1;
                None
            }
            Outcome::Verdict(Verdict::Refused(msg)) => {
                counts.refused += 1;
                // The message's first words sort refusals into kinds for the summary.
                let kind: String = msg.split_whitespace().take(4).collect::<Vec<_>>().join(" ");
                *refusals.entry(kind).or_default() += 1;
                None
            }
            Outcome::Verdict(Verdict::AcceptedCorruption(msg)) => {
                counts.accepted_corruptions += 1;
                Some(format!("accepted corruption: {msg}"))
            }
            Outcome::Panic(msg) => {
                counts.panics += 1;
                Some(format!("panic: {msg}"))
            }
            Outcome::Hang => {
                counts.hangs += 1;
                Some(format!("hang: over {HANG_LIMIT:?}"))
            }
        };
        counts.cases += 1;
        if from_corpus {
            counts.corpus_cases += 1;
        }
        if let Some(why) = failure {
            failures.push((name, why, bytes));
            if counts.hangs > 0 {
                break; // the hung worker still runs: stop here rather than pile up threads
            }
        }
    }
    println!(
        "fuzz {target}: {} cases ({} corpus) in {:.1} s, seed {seed}: {} accepted, {} refused, {} skipped, \
         {} panics, {} hangs, {} accepted corruptions",
        counts.cases,
        counts.corpus_cases,
        start.elapsed().as_secs_f64(),
        counts.accepted,
        counts.refused,
        counts.skipped,
        counts.panics,
        counts.hangs,
        counts.accepted_corruptions
    );
    for (kind, n) in refusals.iter().rev().take(8) {
        println!("fuzz {target}:   refused {n}× «{kind} …»");
    }
    if !failures.is_empty() {
        let dir = failure_dir(target);
        std::fs::create_dir_all(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        for (name, why, bytes) in &failures {
            let path = dir.join(name);
            std::fs::write(&path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            eprintln!(
                "fuzz {target}: {name}: {why}\n  input saved to {}",
                path.display()
            );
        }
        panic!(
            "fuzz {target}: {} failing cases (inputs under {}; copy them to {} once fixed)",
            failures.len(),
            dir.display(),
            corpus_dir(target).display()
        );
    }
    counts
}
