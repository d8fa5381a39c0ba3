//! The file's framing, checked before any table is read: header (magic, version, checksum, constants),
//! file length, sections in bounds and in order with zero gaps, blocks inside the file on their alignment
//! with zero padding (docs/DESIGN.md "Checksums and alignment").

use super::super::StoreError;
use super::super::format::{
    BLOCK_ALIGN, BlockRecord, FORMAT_VERSION, HEADER_SIZE, Header, KNOWN_FLAGS, MAGIC,
    SECTION_ALIGN, SECTION_COUNT, Section, align_up,
};
use crate::ids::BlockId;
use std::path::Path;

/// `bytes[offset..offset + len]`, `None` if outside.
pub(super) fn slice_at(bytes: &[u8], offset: u64, len: u64) -> Option<&[u8]> {
    let start = usize::try_from(offset).ok()?;
    let end = usize::try_from(offset.checked_add(len)?).ok()?;
    bytes.get(start..end)
}

/// Fails on the first non-zero byte in `bytes[from..to]`, as far as `bytes` reaches (a table prefix may
/// end inside the gap).
pub(super) fn check_zero(bytes: &[u8], from: u64, to: u64) -> Result<(), StoreError> {
    let to = to.min(bytes.len() as u64);
    let gap = slice_at(bytes, from, to.saturating_sub(from)).unwrap_or(&[]);
    match gap.iter().position(|&b| b != 0) {
        Some(p) => Err(StoreError::NonZeroPadding {
            offset: from + p as u64,
        }),
        None => Ok(()),
    }
}

pub(super) fn checksum(what: String, expected: u64, bytes: &[u8]) -> Result<(), StoreError> {
    let found = xxhash_rust::xxh3::xxh3_64(bytes);
    if found == expected {
        Ok(())
    } else {
        Err(StoreError::ChecksumMismatch {
            what,
            expected,
            found,
        })
    }
}

/// Magic, version, header checksum, constants (not the file length: see [`check_file_len`]).
pub(super) fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header, StoreError> {
    let len = bytes.len() as u64;
    if let Some(magic) = bytes.get(..MAGIC.len())
        && magic != MAGIC
    {
        return Err(StoreError::BadMagic {
            path: path.to_path_buf(),
            found: magic.to_vec(),
        });
    }
    let Some(head) = bytes.get(..HEADER_SIZE) else {
        return Err(StoreError::Truncated {
            path: path.to_path_buf(),
            len,
            needed: HEADER_SIZE as u64,
        });
    };
    let header: Header = bytemuck::pod_read_unaligned(head);
    if header.version != FORMAT_VERSION {
        return Err(StoreError::UnsupportedVersion {
            found: header.version,
            supported: FORMAT_VERSION,
        });
    }
    let expected = header.compute_checksum();
    if header.checksum != expected {
        let found = header.checksum;
        return Err(StoreError::ChecksumMismatch {
            what: "header".into(),
            expected,
            found,
        });
    }
    let constants = [
        ("flags", header.flags, KNOWN_FLAGS),
        ("header_size", header.header_size, HEADER_SIZE as u32),
        ("section_count", header.section_count, SECTION_COUNT as u32),
        ("block_align", header.block_align, BLOCK_ALIGN as u32),
        ("section_align", header.section_align, SECTION_ALIGN as u32),
    ];
    for (field, found, want) in constants {
        if found != want {
            return Err(StoreError::BadValue {
                table: "header",
                index: 0,
                field,
                value: found.into(),
            });
        }
    }
    Ok(header)
}

/// The file is exactly as long as the header says (`len` is the whole file's length, also when only a
/// prefix of it is in memory).
pub(super) fn check_file_len(path: &Path, header: &Header, len: u64) -> Result<(), StoreError> {
    if len < header.file_len {
        return Err(StoreError::Truncated {
            path: path.to_path_buf(),
            len,
            needed: header.file_len,
        });
    }
    if len > header.file_len {
        let expected = header.file_len;
        return Err(StoreError::TrailingBytes {
            path: path.to_path_buf(),
            len,
            expected,
        });
    }
    Ok(())
}

/// End of the last section (the tables), from the header alone; `None` on overflow.
pub(in crate::store) fn sections_end(header: &Header) -> Option<u64> {
    (header.sections.iter()).try_fold(HEADER_SIZE as u64, |end, e| {
        Some(end.max(e.offset.checked_add(e.length)?))
    })
}

/// Each section: kind, record size, alignment, length = count × record size, order, bounds, zero gaps,
/// checksum. Returns the end of the tables. `bytes` may be a prefix of the file (see
/// [`TreeFile::from_prefix`]); a section inside the file but past the prefix is reported as truncation.
/// With `holds_geometry` false the geometry sections' checksums are not computed (their bytes were not
/// read: a hash over the whole prefix vouches for them, [`TreeFile::skeleton_prefix`]).
pub(super) fn check_sections(
    path: &Path,
    header: &Header,
    bytes: &[u8],
    holds_geometry: bool,
) -> Result<u64, StoreError> {
    let file_len = header.file_len;
    let mut prev_end = HEADER_SIZE as u64;
    for (i, s) in Section::ALL.iter().enumerate() {
        let e = header.section(*s);
        let section = s.name();
        let layout = |field, found: u64, expected: u64| StoreError::SectionLayout {
            section,
            field,
            found,
            expected,
        };
        if e.kind != i as u32 {
            return Err(layout("kind", e.kind.into(), i as u64));
        }
        if e.record_size != s.record_size() {
            return Err(layout(
                "record_size",
                e.record_size.into(),
                s.record_size().into(),
            ));
        }
        if !e.offset.is_multiple_of(SECTION_ALIGN) {
            let what = format!("section {section}");
            return Err(StoreError::Misaligned {
                what,
                offset: e.offset,
                align: SECTION_ALIGN,
            });
        }
        let expected_len = e.count.checked_mul(u64::from(e.record_size));
        if expected_len != Some(e.length) {
            return Err(layout("length", e.length, expected_len.unwrap_or(u64::MAX)));
        }
        // Canonical placement: the end of what precedes, rounded up to SECTION_ALIGN (so every gap is
        // shorter than SECTION_ALIGN and zero-checked below).
        let expected_offset = align_up(prev_end, SECTION_ALIGN).unwrap_or(u64::MAX);
        if e.offset != expected_offset {
            return Err(layout("offset", e.offset, expected_offset));
        }
        let end = e
            .offset
            .checked_add(e.length)
            .filter(|&end| end <= file_len);
        let data = match (slice_at(bytes, e.offset, e.length), end) {
            (Some(data), _) => data,
            (None, Some(end)) => {
                return Err(StoreError::Truncated {
                    path: path.to_path_buf(),
                    len: bytes.len() as u64,
                    needed: end,
                });
            }
            (None, None) => {
                return Err(StoreError::SectionOutOfBounds {
                    section,
                    offset: e.offset,
                    len: e.length,
                    file_len,
                });
            }
        };
        check_zero(bytes, prev_end, e.offset)?;
        if holds_geometry || !s.is_geometry() {
            checksum(format!("section {section}"), e.checksum, data)?;
        }
        prev_end = e.offset + e.length;
    }
    if header.section(Section::Params).count != 1 {
        let count = header.section(Section::Params).count;
        return Err(StoreError::SectionLayout {
            section: "params",
            field: "count",
            found: count,
            expected: 1,
        });
    }
    Ok(prev_end)
}

/// Block placement: block `i` starts exactly at the end of what precedes it (the tables for block 0)
/// rounded up to [`BLOCK_ALIGN`], inside the file, and the file ends exactly where the last block ends (at
/// the tables' end when there is no block). So the only bytes not covered by a checksum are the zero
/// padding in front of each block, shorter than [`BLOCK_ALIGN`]: the padding before block 0 is checked here
/// (as far as `bytes` reaches: all of it for a whole file, up to the prefix's end for a table prefix), the
/// padding after block `i` when block `i` is read ([`TreeFile::block`]).
pub(super) fn check_block_layout(
    blocks: &[BlockRecord],
    tables_end: u64,
    bytes: &[u8],
    file_len: u64,
) -> Result<(), StoreError> {
    let mut prev_end = tables_end;
    for (i, b) in blocks.iter().enumerate() {
        let block = BlockId(i as u32);
        let expected =
            align_up(prev_end, BLOCK_ALIGN).ok_or(StoreError::LayoutOverflow { what: "blocks" })?;
        if b.offset != expected {
            return Err(StoreError::BlockPlacement {
                block,
                offset: b.offset,
                expected,
            });
        }
        let end = b
            .offset
            .checked_add(b.length)
            .filter(|&e| e <= file_len)
            .ok_or(StoreError::BlockOutOfBounds {
                block,
                offset: b.offset,
                len: b.length,
                file_len,
            })?;
        if i == 0 {
            check_zero(bytes, tables_end, b.offset)?;
        }
        prev_end = end;
    }
    if prev_end != file_len {
        return Err(StoreError::SectionLayout {
            section: "blocks",
            field: "file_len",
            found: file_len,
            expected: prev_end,
        });
    }
    Ok(())
}

/// The zero padding after block `record` (id `id`): from its end to the next [`BLOCK_ALIGN`] boundary,
/// or to `file_len` for the last block (none: the file ends where it ends). `padding` holds those bytes
/// ([`padding_range`]); fails naming the first non-zero byte.
pub fn check_block_padding(
    id: BlockId,
    record: &BlockRecord,
    file_len: u64,
    padding: &[u8],
) -> Result<(), StoreError> {
    let (from, to) = padding_range(record, file_len);
    if padding.len() as u64 != to - from {
        return Err(StoreError::BlockLength {
            block: id,
            expected: to - from,
            got: padding.len() as u64,
        });
    }
    match padding.iter().position(|&b| b != 0) {
        Some(p) => Err(StoreError::BlockPadding {
            block: id,
            offset: from + p as u64,
        }),
        None => Ok(()),
    }
}

/// The byte range `[from, to)` of the padding after block `record` in a file of `file_len` bytes (empty
/// for the last block and for a record outside the file).
pub fn padding_range(record: &BlockRecord, file_len: u64) -> (u64, u64) {
    let end = record.offset.saturating_add(record.length).min(file_len);
    let to = align_up(end, BLOCK_ALIGN).unwrap_or(u64::MAX).min(file_len);
    (end, to)
}
