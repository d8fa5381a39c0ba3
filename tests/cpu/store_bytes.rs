//! Every byte of a paging file is accounted for (issue 23): a small built file (64² atlases, the smallest
//! the builder accepts) refuses every single-byte change (XOR 0xFF) — header, tables, padding and block
//! payloads, every byte of the file — every truncation and any appended bytes: at open
//! (`TreeFile::from_bytes`, `TreeFile::open` with mmap and read) or in `inspect::verify`, the library side of
//! `atlastree inspect --verify`.

use atlastree::ids::BlockId;
use atlastree::inspect;
use atlastree::store::format::{BLOCK_ALIGN, HEADER_SIZE};
use atlastree::store::{LoadMode, StoreError, TreeFile, padding_range};
use std::path::PathBuf;
use std::process::Command;

/// The shared tiny paging file (`tests/fixtures/tiny_store.rs`): 64² atlases, every region kind.
fn tiny() -> &'static [u8] {
    crate::fixtures::tiny_store::tiny_paging_file()
}

/// The regions of a file, in file order: `(name, from, to)`, covering `0..len` exactly.
fn regions(file: &TreeFile) -> Vec<(String, u64, u64)> {
    let mut out = vec![("header".to_string(), 0, HEADER_SIZE as u64)];
    let tables_end = file
        .header()
        .sections
        .iter()
        .map(|s| s.offset + s.length)
        .max()
        .unwrap();
    out.push(("tables".into(), HEADER_SIZE as u64, tables_end));
    let blocks = file.blocks();
    let first = blocks.first().map_or(tables_end, |b| b.offset);
    out.push(("padding before block 0".into(), tables_end, first));
    for (i, b) in blocks.iter().enumerate() {
        out.push((format!("block {i}"), b.offset, b.offset + b.length));
        let (from, to) = padding_range(b, file.file_len());
        out.push((format!("padding after block {i}"), from, to));
    }
    out
}

/// Why the bytes are refused (open, then `inspect::verify`), or `None` if they pass both.
fn refusal(bytes: &[u8]) -> Option<String> {
    let file = match TreeFile::from_bytes(bytes) {
        Ok(f) => f,
        Err(e) => return Some(format!("open: {e}")),
    };
    let v = inspect::verify(&file);
    (!v.ok()).then(|| format!("verify: {}", v.violations.join("; ")))
}

/// Why the paging read of block `k` refuses the bytes (open, then `TreeFile::block`), or `None`.
fn read_refusal(bytes: &[u8], k: usize) -> Option<String> {
    match TreeFile::from_bytes(bytes) {
        Err(e) => Some(format!("open: {e}")),
        Ok(file) => file
            .block(BlockId(k as u32))
            .err()
            .map(|e| format!("read: {e}")),
    }
}

/// Single-byte flips (XOR 0xFF), each mutant refused. Header, tables and the padding before the first
/// block: every byte, through open and `inspect::verify` (what `atlastree inspect --verify` runs). The
/// padding after each block: every byte, through open and the paging read of that block
/// (`TreeFile::block`, what the renderer and `serve` clients call). Block payloads (covered by the
/// block's `xxh3_64`): the first and last 64 bytes of each block and every 31st byte, through the
/// paging read. Every 97th byte of blocks and padding also goes through `inspect::verify`.
/// `ATLASTREE_EVERY_BYTE_VERIFY=1` tries every byte of the file and sends each through
/// `inspect::verify` too (≈ 7 min in release on 2 cores; the default run takes seconds).
#[test]
fn every_single_byte_change_is_refused_naming_its_region() {
    let bytes = tiny();
    let file = TreeFile::from_bytes(bytes).unwrap();
    assert!(inspect::verify(&file).ok(), "the clean file verifies");
    let regions = regions(&file);
    // The regions tile the file: nothing is left out of the accounting.
    let mut at = 0;
    for (name, from, to) in &regions {
        assert_eq!(*from, at, "{name} starts where the previous region ends");
        at = *to;
    }
    assert_eq!(
        at,
        bytes.len() as u64,
        "the regions end where the file ends"
    );
    let blocks = file.blocks().len();
    assert!(blocks >= 4, "{blocks} blocks");
    let full = std::env::var_os("ATLASTREE_EVERY_BYTE_VERIFY").is_some_and(|v| v == "1");
    let mut mutant = bytes.to_vec();
    let (mut tried, mut verified, mut padding_tried) = (0u64, 0u64, 0u64);
    for (name, from, to) in &regions {
        // The block a region belongs to (its payload or the padding after it).
        let block: Option<usize> = name
            .strip_prefix("padding after block ")
            .or_else(|| name.strip_prefix("block "))
            .map(|i| i.parse().unwrap());
        let payload = name.starts_with("block ");
        for pos in *from..*to {
            if payload && !full && pos - from >= 64 && to - pos > 64 && pos % 31 != 0 {
                continue;
            }
            let p = pos as usize;
            mutant[p] ^= 0xFF;
            let through_verify = full || block.is_none() || pos % 97 == 0;
            let why = match block {
                Some(k) => read_refusal(&mutant, k),
                None => refusal(&mutant),
            };
            let verify_why = (through_verify && block.is_some()).then(|| refusal(&mutant));
            mutant[p] ^= 0xFF;
            tried += 1;
            verified += u64::from(through_verify);
            let Some(why) = why else {
                panic!("flip at byte {pos} ({name}) accepted");
            };
            if let Some(v) = verify_why {
                assert!(v.is_some(), "flip at byte {pos} ({name}) passes verify");
            }
            if name.starts_with("padding after block ") {
                padding_tried += 1;
                // The message names the block and the byte.
                let want = format!(
                    "padding after {} at byte {pos} is not zero",
                    BlockId(block.unwrap() as u32)
                );
                assert!(why.contains(&want), "byte {pos}: {why}");
            }
        }
    }
    assert!(padding_tried > 0);
    if full {
        assert_eq!(tried, bytes.len() as u64, "every byte tried");
    }
    println!(
        "every-byte test: {tried} single-byte mutants of a {}-byte file ({blocks} blocks, {padding_tried} \
         padding bytes after blocks) all refused; {verified} of them also through inspect::verify",
        bytes.len()
    );
}

#[test]
fn truncation_and_appended_bytes_are_refused() {
    let bytes = tiny();
    let len = bytes.len();
    // Every length up to the first block, every 4 KiB boundary ± 1, and 300 spread over the blocks.
    let first = TreeFile::from_bytes(bytes).unwrap().blocks()[0].offset as usize;
    let mut cuts: Vec<usize> = (0..=first).collect();
    for page in (first..len).step_by(BLOCK_ALIGN as usize) {
        cuts.extend([page - 1, page, page + 1]);
    }
    cuts.extend((0..300).map(|k| first + (len - first) * k / 300));
    cuts.push(len - 1);
    cuts.retain(|&c| c < len);
    cuts.sort_unstable();
    cuts.dedup();
    for &cut in &cuts {
        match TreeFile::from_bytes(&bytes[..cut]) {
            Err(StoreError::Truncated { .. }) => {}
            other => panic!("cut at {cut} of {len}: {:?}", other.err()),
        }
    }
    for extra in [1usize, 4096] {
        for fill in [0u8, 0xAB] {
            let mut long = bytes.to_vec();
            long.resize(len + extra, fill);
            assert!(
                matches!(
                    TreeFile::from_bytes(&long),
                    Err(StoreError::TrailingBytes { .. })
                ),
                "{extra} bytes of {fill:#x} appended"
            );
        }
    }
    println!(
        "truncation test: {} cuts and 4 extensions of a {len}-byte file all refused",
        cuts.len()
    );
}

/// A file on disk: the mmap and read opens and the CLI refuse a flipped padding byte after a block, naming
/// the block and the byte, while every other block still reads.
#[test]
fn padding_flip_refused_on_disk_by_open_modes_and_the_cli() {
    let bytes = tiny();
    let file = TreeFile::from_bytes(bytes).unwrap();
    let (k, (from, to)) = (file.blocks().iter().enumerate())
        .map(|(i, b)| (i, padding_range(b, file.file_len())))
        .find(|(_, (f, t))| t > f)
        .unwrap();
    let pos = to - 1;
    assert!(pos >= from);
    let mut bad = bytes.to_vec();
    bad[pos as usize] ^= 0xFF;
    let dir = tempfile::tempdir().unwrap();
    let path: PathBuf = dir.path().join("bad.atlastree");
    std::fs::write(&path, &bad).unwrap();
    for mode in [LoadMode::Mmap, LoadMode::Read, LoadMode::Tables] {
        let f = TreeFile::open_with(&path, mode).unwrap();
        for i in 0..f.blocks().len() {
            let r = f.block(BlockId(i as u32));
            if i == k {
                match r {
                    Err(StoreError::BlockPadding { block, offset }) => {
                        assert_eq!((block, offset), (BlockId(k as u32), pos), "{mode:?}");
                    }
                    other => panic!("{mode:?} block {k}: {:?}", other.map(|b| b.len())),
                }
            } else {
                r.unwrap();
            }
        }
        assert!(f.verify_blocks().is_err());
    }
    let out = Command::new(env!("CARGO_BIN_EXE_atlastree"))
        .args(["inspect", "--verify"])
        .arg(&path)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{stdout}");
    let want = format!(
        "padding after {} at byte {pos} is not zero",
        BlockId(k as u32)
    );
    assert!(stdout.contains(&want), "{stdout}");
}

/// A file truncated while it is open: with its tables in memory (`LoadMode::Tables`, what `export` and
/// `inspect` use) or mapped, every block it lost is an error naming the block, read through the file's
/// handle — through the map the first one ended the process with SIGBUS (fault hunt, session 28) — and
/// the tables still read.
#[test]
fn blocks_of_a_file_truncated_while_open_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path: PathBuf = dir.path().join("t.atlastree");
    for mode in [LoadMode::Tables, LoadMode::Mmap] {
        std::fs::write(&path, tiny()).unwrap();
        let f = TreeFile::open_with(&path, mode).unwrap();
        let first = f.blocks()[0].offset;
        std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_len(first)
            .unwrap();
        for i in 0..f.blocks().len() {
            match f.block(BlockId(i as u32)) {
                Err(StoreError::Io { source, .. }) => {
                    let text = source.to_string();
                    assert!(text.contains(&format!("block {i} ")), "{mode:?}: {text}");
                }
                other => panic!("{mode:?} block {i}: {:?}", other.map(|b| b.len())),
            }
        }
        if mode == LoadMode::Tables {
            assert!(f.tree(0).is_some_and(|t| !t.nodes.is_empty()));
        }
    }
}

/// A file reopened (the pager's second handle) is read as the first was: with its tables in memory, a
/// truncation after the reopen leaves the reopened tables readable. Reopened as a map, its geometry was
/// read through the map, and `render --capacity` on a file truncated during its setup ended by SIGBUS
/// (fault hunt, session 37).
#[test]
fn a_reopened_file_keeps_its_tables_in_memory() {
    let dir = tempfile::tempdir().unwrap();
    let path: PathBuf = dir.path().join("t.atlastree");
    std::fs::write(&path, tiny()).unwrap();
    let f = TreeFile::open_with(&path, LoadMode::Tables).unwrap();
    let again = f.reopen().unwrap();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(0)
        .unwrap();
    let tree = again.tree(0).unwrap();
    assert!(!tree.nodes.is_empty());
    assert_eq!(tree.nodes.len(), f.tree(0).unwrap().nodes.len());
    assert!(again.block(BlockId(0)).is_err());
}
