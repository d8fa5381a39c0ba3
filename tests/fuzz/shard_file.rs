//! Target `shard_file`: mutants of one shard file of a two-shard build of the tiny city (the paging file
//! fixture's scene and flags) fed to `merge` (issue 22: a corrupt, truncated or foreign shard is named,
//! never merged into a wrong file).
//!
//! Mutations: byte flips (one to eight, most in the header and tables), truncation, appended bytes, and
//! resealed edits (a header field or a word of the block or handoff tables set to an edge value, then
//! the tables' and header's checksums recomputed). A merge that succeeds must write exactly the
//! one-process file, except after a resealed edit of a block's compression error (`sse`, stored as
//! written: a deliberate rewrite, accepted). Anything else it writes is an accepted corruption.

use super::harness::{self, Verdict};
use arbitrary::Unstructured;
use atlastree::preprocess::shard::{ShardSpec, shard_path};
use atlastree::preprocess::{NoProgress, ShardedOptions, build, build_shard, merge};
use atlastree::store::shard::ShardHeader;
use std::path::PathBuf;
use std::sync::OnceLock;

/// CI cases (each a merge of two small shard files).
const DEFAULT_CASES: u64 = 400;

struct Base {
    /// The two shard files' bytes.
    shards: [Vec<u8>; 2],
    /// The one-process paging file.
    reference: Vec<u8>,
}

fn base() -> &'static Base {
    static BASE: OnceLock<Base> = OnceLock::new();
    BASE.get_or_init(|| {
        let (scene, opts) = (
            super::tiny_store::tiny_scene(),
            super::tiny_store::tiny_options(),
        );
        let dir = tempfile::tempdir().expect("temp dir");
        let one = dir.path().join("one.atlastree");
        build(&scene, &opts, &one, &NoProgress).expect("the small city builds");
        let out = dir.path().join("tiny.atlastree");
        let shards = [0, 1].map(|index| {
            let spec = ShardSpec { index, count: 2 };
            let sharded = ShardedOptions {
                spec,
                argv: vec!["atlastree".into()],
                import: None,
            };
            build_shard(&scene, &opts, &out, &sharded, &NoProgress).expect("shard builds");
            std::fs::read(shard_path(&out, spec)).expect("read shard")
        });
        Base {
            shards,
            reference: std::fs::read(&one).expect("read the build"),
        }
    })
}

const HEADER: usize = size_of::<ShardHeader>();

fn header_of(b: &[u8]) -> ShardHeader {
    bytemuck::pod_read_unaligned(&b[..HEADER])
}

/// Start and end of the tables (after the header, up to the first payload), clamped to the file.
fn tables_range(b: &[u8]) -> (usize, usize) {
    let h = header_of(b);
    let a = |x: u64| x.saturating_add(15) / 16 * 16;
    // Block and handoff entries (40 bytes), then one image entry (32 bytes) per scene image.
    let entries = h
        .blocks
        .saturating_add(h.handoffs)
        .saturating_mul(40)
        .saturating_add(h.images.saturating_mul(32));
    let end = (HEADER as u64)
        .saturating_add(a(h.argv_len))
        .saturating_add(a(h.prefix_len))
        .saturating_add(entries);
    (HEADER, end.min(b.len() as u64) as usize)
}

fn reseal(b: &mut [u8]) {
    let (from, to) = tables_range(b);
    let mut h = header_of(b);
    h.tables_checksum = xxhash_rust::xxh3::xxh3_64(&b[from..to.max(from)]);
    let bytes = bytemuck::bytes_of(&h);
    h.checksum = xxhash_rust::xxh3::xxh3_64(&bytes[..HEADER - 8]);
    b[..HEADER].copy_from_slice(bytemuck::bytes_of(&h));
}

/// One mutation of `m`; returns its description and whether it was resealed.
fn mutate_bytes(u: &mut Unstructured<'_>, m: &mut Vec<u8>) -> arbitrary::Result<(String, bool)> {
    let len = m.len();
    let (_, tables_end) = tables_range(m);
    Ok(match u.int_in_range(0u8..=9)? {
        0..=3 => {
            let p = if u.ratio(2u8, 3u8)? {
                u.choose_index(tables_end.min(len))?
            } else {
                u.choose_index(len)?
            };
            let mask = u.int_in_range(1u8..=255)?;
            m[p] ^= mask;
            (format!("flip {mask:#04x} at {p}"), false)
        }
        4 => {
            let n = u.int_in_range(2usize..=8)?;
            for _ in 0..n {
                let p = u.choose_index(len)?;
                m[p] ^= u.int_in_range(1u8..=255)?;
            }
            (format!("{n} flips"), false)
        }
        5 => {
            let cut = u.choose_index(len)?;
            m.truncate(cut);
            (format!("truncated to {cut}"), false)
        }
        6 => {
            let n = *u.choose(&[1usize, 15, 16, 4096])?;
            m.resize(len + n, 0);
            (format!("{n} zero bytes appended"), false)
        }
        _ => {
            // A resealed word: in the header (before the checksums) or in the entry tables.
            let h = header_of(m);
            let a = |x: u64| x.div_ceil(16) * 16;
            let entries_at = HEADER as u64 + a(h.argv_len) + a(h.prefix_len);
            if entries_at as usize + 40 * ((h.blocks + h.handoffs) as usize) > m.len() {
                return Err(arbitrary::Error::IncorrectFormat);
            }
            let n_entries = (h.blocks + h.handoffs) as usize;
            let at = if u.arbitrary::<bool>()? || n_entries == 0 {
                8 * u.choose_index((HEADER - 16) / 8)?
            } else {
                entries_at as usize + 40 * u.choose_index(n_entries)? + 8 * u.choose_index(5)?
            };
            let old = u64::from_le_bytes(m[at..at + 8].try_into().unwrap_or_default());
            let v = match u.int_in_range(0u8..=5)? {
                0 => 0,
                1 => u64::MAX,
                2 => old.wrapping_add(1),
                3 => old.wrapping_sub(1),
                4 => old ^ (1 << u.int_in_range(0..=63)?),
                _ => u.arbitrary::<u64>()?,
            };
            m[at..at + 8].copy_from_slice(&v.to_le_bytes());
            reseal(m);
            (format!("word at {at}: {old} → {v}, resealed"), true)
        }
    })
}

fn mutate(data: &[u8]) -> Verdict {
    let base = base();
    let mut u = Unstructured::new(data);
    let Ok(which) = u.choose_index(2) else {
        return Verdict::Skipped;
    };
    let mut m = base.shards[which].clone();
    let Ok((what, resealed)) = mutate_bytes(&mut u, &mut m) else {
        return Verdict::Skipped;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out: PathBuf = dir.path().join("tiny.atlastree");
    for (i, bytes) in base.shards.iter().enumerate() {
        let spec = ShardSpec {
            index: i as u32,
            count: 2,
        };
        let b = if i == which { &m } else { bytes };
        std::fs::write(shard_path(&out, spec), b).expect("write shard");
    }
    match merge(&out, None, &NoProgress) {
        Err(e) => {
            if out.exists() {
                return Verdict::AcceptedCorruption(format!(
                    "{what}: failed ({e}) but wrote the output"
                ));
            }
            Verdict::Refused(e.to_string())
        }
        Ok(_) => {
            let merged = std::fs::read(&out).expect("read merged");
            if merged == base.reference {
                return Verdict::Accepted;
            }
            // A resealed sse edit changes only the block table's sse (and the checksums over it).
            let ok = resealed && atlastree::store::TreeFile::from_bytes(&merged).is_ok();
            if ok {
                Verdict::Accepted
            } else {
                Verdict::AcceptedCorruption(format!(
                    "shard {which}: {what}: merged into a file that differs from the one-process build"
                ))
            }
        }
    }
}

#[test]
fn shard_file() {
    let counts = harness::run("shard_file", DEFAULT_CASES, mutate);
    assert!(counts.refused > 0 && counts.accepted > 0, "{counts:?}");
}
