//! The shard files beside a merge's OUT, found by their names (`OUT.shard-I-of-N`, [`shard_path`]'s own):
//! which count to merge, and what to say when a set is incomplete.

use super::merge::MergeError;
use super::shard::{self, ShardSpec, shard_path};
use std::path::{Path, PathBuf};

/// The shard files beside `out`, by their names: `(index, count, path)`.
pub(super) fn shard_files(out: &Path) -> Vec<(u32, u32, PathBuf)> {
    let dir = crate::util::parent_dir(out);
    let Some(base) = out.file_name() else {
        return Vec::new();
    };
    // Bytes, not UTF-8: any name the OS takes is a name a build may have written.
    let prefix = [base.as_encoded_bytes(), b".shard-"].concat();
    let mut found = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else {
        return found;
    };
    for e in entries.flatten() {
        let name = e.file_name();
        let rest = name.as_encoded_bytes().strip_prefix(prefix.as_slice());
        let Some((i, n)) = rest
            .and_then(|r| std::str::from_utf8(r).ok())
            .and_then(|r| r.split_once("-of-"))
        else {
            continue;
        };
        // Only names a build writes (`shard_path`'s own): a stray `-of-0`, `-of-4294967295` or
        // `-of-04` is no shard count.
        if let (Ok(index), Ok(count)) = (i.parse::<u32>(), n.parse::<u32>())
            && (1..=shard::MAX_SHARDS).contains(&count)
            && index < count
            && shard_path(out, ShardSpec { index, count }).file_name() == Some(name.as_os_str())
        {
            found.push((index, count, out.with_file_name(name)));
        }
    }
    found.sort();
    found
}

/// The shard count of the only build whose shard files lie beside `out`.
pub(super) fn only_count(out: &Path) -> Result<u32, MergeError> {
    let mut counts: Vec<u32> = shard_files(out).iter().map(|f| f.1).collect();
    counts.sort_unstable();
    counts.dedup();
    match counts.as_slice() {
        [] => Err(MergeError::NoShards {
            out: out.to_path_buf(),
        }),
        [n] => Ok(*n),
        _ => Err(MergeError::AmbiguousCount {
            out: out.to_path_buf(),
            counts,
        }),
    }
}

/// Counts other than `count` whose every shard lies beside `out`, said as a hint (`--shards 3` beside a
/// complete set of 16 named only shard 0 of 3 as missing; fault hunt, session 34); empty if none.
pub(super) fn complete_sets_text(out: &Path, count: u32) -> String {
    let files = shard_files(out);
    let mut counts: Vec<u32> = files.iter().map(|f| f.1).filter(|&c| c != count).collect();
    counts.sort_unstable();
    counts.dedup();
    let complete: Vec<String> = counts
        .into_iter()
        .filter(|&c| (0..c).all(|i| files.iter().any(|f| f.1 == c && f.0 == i)))
        .map(|c| {
            format!("all {c} shards of a {c}-shard build (`atlastree merge OUT --shards {c}`)")
        })
        .collect();
    if complete.is_empty() {
        String::new()
    } else {
        format!("; beside it lie {}", complete.join(" and "))
    }
}
