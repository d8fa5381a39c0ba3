//! Target `paging_file`: structure-aware mutants of a small built paging file (a synthetic city, 64² atlases)
//! fed to `TreeFile::from_bytes`, the block reads the renderer uses (`FileSource::fetch`, the block table),
//! the CPU half of the renderer's load (`render::resident::gather_tables`) and `inspect::verify` (what
//! `atlastree inspect --verify` runs); a resealed mutant that opens is also exported as 3D Tiles
//! (`atlastree export 3dtiles`, which trusts what open checked and must refuse the rest with an error,
//! never a panic, and leave nothing behind).
//!
//! Mutations, drawn from the case's bytes:
//! - raw: byte flips (one to eight, most in the header, tables and padding), truncation, appended bytes,
//!   and one header field (a section's offset, length, count, checksum, record size or kind, or the file
//!   length, version, flags, alignments) set to an edge value with the header checksum fixed up. Every
//!   byte of a file is covered by a checksum, a zero check or a layout rule (issue 23), so a raw mutant
//!   that changes the file and passes `verify` is an accepted corruption (a failure).
//! - resealed: a word of one record (tables, block records) set to an edge value, then every section
//!   checksum and the header checksum recomputed, so the cross-reference and tree checks see the edit.
//!   Such a file is internally consistent by construction (a deliberate rewrite, not a corruption), so
//!   passing `verify` is `Accepted`; what must not happen is a panic or a hang in open, the block reads
//!   or verify.

use super::harness::{self, Verdict};
use arbitrary::Unstructured;
use atlastree::ids::BlockId;
use atlastree::paging::{BlockSource, BlockTable, FileSource};
use atlastree::store::TreeFile;
use atlastree::store::format::{HEADER_SIZE, Header, SECTION_COUNT, Section};
use std::sync::Arc;

/// CI cases (≈ 3 s in release on 2 cores).
const DEFAULT_CASES: u64 = 5000;

/// The base file: the shared tiny paging file (`tests/fixtures/tiny_store.rs`).
fn base() -> &'static [u8] {
    super::tiny_store::tiny_paging_file()
}

fn header_of(bytes: &[u8]) -> Header {
    bytemuck::pod_read_unaligned(&bytes[..HEADER_SIZE])
}

fn put_header(bytes: &mut [u8], h: &Header) {
    bytes[..HEADER_SIZE].copy_from_slice(bytemuck::bytes_of(h));
}

/// Recomputes every section checksum and the header checksum.
fn reseal(bytes: &mut [u8]) {
    let mut h = header_of(bytes);
    for s in h.sections.iter_mut() {
        if let Some(data) = bytes.get(s.offset as usize..(s.offset + s.length) as usize) {
            s.checksum = xxhash_rust::xxh3::xxh3_64(data);
        }
    }
    h.checksum = h.compute_checksum();
    put_header(bytes, &h);
}

/// An edge value for a field now holding `old`, `bits` wide.
fn edge(u: &mut Unstructured<'_>, old: u64, bits: u32, file_len: u64) -> arbitrary::Result<u64> {
    let max = if bits == 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    };
    let v = match u.int_in_range(0u8..=11)? {
        0 => 0,
        1 => 1,
        2 => max,
        3 => max - 1,
        4 => old.wrapping_add(1),
        5 => old.wrapping_sub(1),
        6 => old.wrapping_add(16),
        7 => old.wrapping_add(4096),
        8 => file_len,
        9 => old ^ (1 << u.int_in_range(0..=bits - 1)?),
        10 => 1 << u.int_in_range(0..=bits - 1)?,
        _ => u.arbitrary::<u64>()?,
    };
    Ok(v & max)
}

/// A position, mostly outside the block payloads (whose bytes only their checksum guards).
fn position(u: &mut Unstructured<'_>, file: &TreeFile, len: usize) -> arbitrary::Result<usize> {
    let blocks = file.blocks();
    let first = blocks.first().map_or(len, |b| b.offset as usize);
    Ok(match u.int_in_range(0u8..=9)? {
        0..=3 => u.choose_index(first.max(1))?,
        4..=6 if !blocks.is_empty() => {
            // The padding after a block (or the block's last bytes when it has none).
            let b = &blocks[u.choose_index(blocks.len())?];
            let end = (b.offset + b.length) as usize;
            let pad = atlastree::store::padding_range(b, file.file_len());
            let to = (pad.1 as usize).max(end);
            end.saturating_sub(2) + u.choose_index(to - end.saturating_sub(2) + 1)?
        }
        _ => u.choose_index(len)?,
    }
    .min(len - 1))
}

/// One raw mutation; returns its description.
fn raw(u: &mut Unstructured<'_>, file: &TreeFile, m: &mut Vec<u8>) -> arbitrary::Result<String> {
    let len = m.len();
    Ok(match u.int_in_range(0u8..=9)? {
        0..=3 => {
            let p = position(u, file, len)?;
            let mask = u.int_in_range(1u8..=255)?;
            m[p] ^= mask;
            format!("flip {mask:#04x} at {p}")
        }
        4 => {
            let n = u.int_in_range(2usize..=8)?;
            for _ in 0..n {
                let p = position(u, file, len)?;
                m[p] ^= u.int_in_range(1u8..=255)?;
            }
            format!("{n} flips")
        }
        5 => {
            let cut = u.choose_index(len)?;
            m.truncate(cut);
            format!("truncated to {cut}")
        }
        6 => {
            let n = *u.choose(&[1usize, 2, 15, 16, 4095, 4096, 4097])?;
            let fill = *u.choose(&[0u8, 0xFF, 1])?;
            m.resize(len + n, fill);
            format!("{n} bytes of {fill:#x} appended")
        }
        _ => {
            let mut h = header_of(m);
            let fl = h.file_len;
            let what = match u.int_in_range(0u8..=9)? {
                0 => {
                    h.file_len = edge(u, fl, 64, fl)?;
                    "file_len".to_string()
                }
                1 => {
                    h.version = edge(u, h.version.into(), 32, fl)? as u32;
                    "version".into()
                }
                2 => {
                    h.flags = edge(u, h.flags.into(), 32, fl)? as u32;
                    "flags".into()
                }
                3 => {
                    h.block_align = edge(u, h.block_align.into(), 32, fl)? as u32;
                    "block_align".into()
                }
                _ => {
                    let i = u.choose_index(SECTION_COUNT)?;
                    let s = &mut h.sections[i];
                    let field = match u.int_in_range(0u8..=5)? {
                        0 => {
                            s.offset = edge(u, s.offset, 64, fl)?;
                            "offset"
                        }
                        1 => {
                            s.length = edge(u, s.length, 64, fl)?;
                            "length"
                        }
                        2 => {
                            s.count = edge(u, s.count, 64, fl)?;
                            "count"
                        }
                        3 => {
                            s.checksum = edge(u, s.checksum, 64, fl)?;
                            "checksum"
                        }
                        4 => {
                            s.record_size = edge(u, s.record_size.into(), 32, fl)? as u32;
                            "record_size"
                        }
                        _ => {
                            s.kind = edge(u, s.kind.into(), 32, fl)? as u32;
                            "kind"
                        }
                    };
                    format!("section {} {field}", Section::ALL[i].name())
                }
            };
            h.checksum = h.compute_checksum();
            put_header(m, &h);
            format!("header {what}")
        }
    })
}

/// One resealed record edit; returns its description.
fn resealed(u: &mut Unstructured<'_>, m: &mut [u8]) -> arbitrary::Result<String> {
    let h = header_of(m);
    let fl = h.file_len;
    // Every record section (strings hold bytes, not records), the block table three times as often.
    let pick: Vec<Section> = (Section::ALL.iter().copied())
        .filter(|&s| s != Section::Strings)
        .chain([Section::Blocks, Section::Blocks])
        .collect();
    let s = *u.choose(&pick)?;
    let e = h.section(s);
    if e.count == 0 {
        return Err(arbitrary::Error::IncorrectFormat);
    }
    let rec = u.choose_index(e.count as usize)?;
    let size = e.record_size as usize;
    let wide = size.is_multiple_of(8) && u.arbitrary::<bool>()?;
    let w = if wide { 8 } else { 4 };
    let word = u.choose_index(size / w)?;
    let at = e.offset as usize + rec * size + word * w;
    let old = if wide {
        u64::from_le_bytes(m[at..at + 8].try_into().unwrap_or_default())
    } else {
        u64::from(u32::from_le_bytes(
            m[at..at + 4].try_into().unwrap_or_default(),
        ))
    };
    let v = edge(u, old, 8 * w as u32, fl)?;
    m[at..at + w].copy_from_slice(&v.to_le_bytes()[..w]);
    reseal(m);
    Ok(format!(
        "{}[{rec}] word {word} ({w} bytes) {old} → {v}, resealed",
        s.name()
    ))
}

/// Open, read every block as the renderer does, verify.
fn judge(bytes: &[u8]) -> Result<(), String> {
    let file = TreeFile::from_bytes(bytes).map_err(|e| format!("open: {e}"))?;
    let file = Arc::new(file);
    BlockTable::from_file(&file).map_err(|e| format!("block table: {e}"))?;
    let source = FileSource::new(Arc::clone(&file));
    for (i, record) in file.blocks().iter().enumerate() {
        source
            .fetch(BlockId(i as u32), record)
            .map_err(|e| format!("fetch: {e}"))?;
    }
    // The renderer's CPU half of a load (tables, TAM, blend lists): an error is fine, a panic is not.
    let _ = atlastree::render::resident::gather_tables(&file);
    let v = atlastree::inspect::verify(&file);
    if v.ok() {
        Ok(())
    } else {
        Err(format!("verify: {}", v.violations.join("; ")))
    }
}

/// Exports a file that opens into a fresh temp dir (`None` when it does not open). An export error is
/// fine; `Err` when the failed export left its output or temp directory behind.
fn export(bytes: &[u8]) -> Option<Result<(), String>> {
    let file = TreeFile::from_bytes(bytes).ok()?;
    let dir = tempfile::tempdir().ok()?;
    let out = dir.path().join("tiles");
    let opts = atlastree::export::ExportOptions::default();
    let result = atlastree::export::export_3dtiles(&file, &out, &opts, &|_, _| {});
    let left = std::fs::read_dir(dir.path()).map_or(0, |d| d.count());
    Some(match result {
        Err(e) if left > 0 => Err(format!("export failed ({e}) and left {left} entries")),
        _ => Ok(()),
    })
}

fn mutate(data: &[u8]) -> Verdict {
    let (base, file) = (base(), super::tiny_store::tiny_paging_tree());
    let mut u = Unstructured::new(data);
    let mut m = base.to_vec();
    let is_raw = u.ratio(3u8, 4u8).unwrap_or(true);
    let what = if is_raw {
        raw(&mut u, file, &mut m)
    } else {
        resealed(&mut u, &mut m)
    };
    let Ok(what) = what else {
        return Verdict::Skipped;
    };
    if m == base {
        return Verdict::Accepted; // the edit restored the same bytes: no change
    }
    if !is_raw && let Some(Err(why)) = export(&m) {
        return Verdict::AcceptedCorruption(format!("{what}: {why}"));
    }
    match judge(&m) {
        Err(why) => Verdict::Refused(why),
        Ok(()) if is_raw => {
            Verdict::AcceptedCorruption(format!("{what}: the changed file verifies"))
        }
        Ok(()) => Verdict::Accepted,
    }
}

#[test]
fn paging_file() {
    let counts = harness::run("paging_file", DEFAULT_CASES, mutate);
    assert!(counts.refused > 0, "{counts:?}");
}
