//! Table prefixes read from a file in pieces: hashed without being held ([`stream_hash128`]), or read
//! without their geometry ([`TreeFile::skeleton_prefix`]: what a planned shard and a merge hold of the
//! tables, issue 22).

use super::{Backing, HEADER_SIZE, Section, StoreError, TreeFile, check_endian, parse_header};
use crate::store::positional::read_exact_at;
use std::fs::File;
use std::path::PathBuf;

/// `xxh3_128` of the `len` bytes at `offset` of `file`, read in 1 MiB pieces (never held whole).
pub(in crate::store) fn stream_hash128(
    file: &File,
    offset: u64,
    len: u64,
) -> std::io::Result<[u64; 2]> {
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    stream_update(&mut hasher, file, offset, len)?;
    Ok(crate::util::digest_words(hasher.digest128()))
}

/// Feeds the `len` bytes at `offset` of `file` to `hasher` in 1 MiB pieces.
pub(in crate::store) fn stream_update(
    hasher: &mut xxhash_rust::xxh3::Xxh3,
    file: &File,
    offset: u64,
    len: u64,
) -> std::io::Result<()> {
    for_each_piece(
        file,
        offset,
        len,
        |e| e,
        |_, piece| {
            hasher.update(piece);
            Ok(())
        },
    )
}

/// Reads the `len` bytes at `offset` of `file` in 1 MiB pieces and hands each to `f` with its position
/// (bytes from `offset`); a read error becomes `E` by `read_err`. One buffer, never the whole range.
pub(in crate::store) fn for_each_piece<E>(
    file: &File,
    offset: u64,
    len: u64,
    read_err: impl Fn(std::io::Error) -> E,
    mut f: impl FnMut(u64, &[u8]) -> Result<(), E>,
) -> Result<(), E> {
    let mut buf = vec![0u8; len.min(1 << 20) as usize];
    let mut done = 0u64;
    while done < len {
        let n = (len - done).min(buf.len() as u64) as usize;
        let piece = &mut buf[..n];
        read_exact_at(file, piece, offset + done).map_err(&read_err)?;
        f(done, piece)?;
        done += n as u64;
    }
    Ok(())
}

impl TreeFile {
    /// The table prefix of `len` bytes at `offset` of `file` without its geometry: the header and every
    /// section but the vertices, indices and source triangles ([`Section::is_geometry`]) are read and
    /// validated as [`TreeFile::from_table_prefix`] does, the geometry sections only by their placement and
    /// counts; they stay unread (their slices empty), so the memory held is a few bytes per node, leaf and
    /// rect, none per triangle.
    ///
    /// The caller vouches for the geometry's bytes by other means: a plan file's hash over the whole
    /// prefix, checked before (`store::shard_plan`). [`TreeFile::to_skeleton`] is what such a file gives.
    pub fn skeleton_prefix(
        file: &File,
        offset: u64,
        len: u64,
        name: &str,
    ) -> Result<TreeFile, StoreError> {
        check_endian()?;
        let path = PathBuf::from(name);
        let io = |e| StoreError::io(&path, e);
        let mut head = vec![0u8; len.min(HEADER_SIZE as u64) as usize];
        read_exact_at(file, &mut head, offset).map_err(io)?;
        let header = parse_header(&path, &head)?;
        if len > header.file_len {
            return Err(StoreError::TrailingBytes {
                path,
                len,
                expected: header.file_len,
            });
        }
        let n = usize::try_from(len).map_err(|_| StoreError::LayoutOverflow { what: "prefix" })?;
        // Zeroed, so the unread geometry is never touched: its pages are not resident.
        let mut words = vec![0u64; n.div_ceil(8)];
        let buf = &mut bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..n];
        buf[..HEADER_SIZE].copy_from_slice(&head);
        for s in Section::ALL.into_iter().filter(|s| !s.is_geometry()) {
            let e = header.section(s);
            let end = e.offset.checked_add(e.length).filter(|&end| end <= len);
            let Some(end) = end else {
                return Err(StoreError::Truncated {
                    path,
                    len,
                    needed: e.offset.saturating_add(e.length),
                });
            };
            let part = &mut buf[e.offset as usize..end as usize];
            let at = offset
                .checked_add(e.offset)
                .ok_or(StoreError::LayoutOverflow { what: "prefix" })?;
            read_exact_at(file, part, at).map_err(io)?;
        }
        let backing = Backing::Owned { words, len: n };
        Self::validate_with(path, backing, header.file_len, false, false)
    }
}
