//! Shard files (issue 22, docs/DESIGN.md "Sharded builds"): what one shard of a sharded build hands to
//! the merge — the blocks it rasterised, the level 1 of each subtree root it owns (the merge combines
//! those into the atlases above the cut, paper §5.1), and, in shard 0 only, the paging file's table prefix
//! ([`crate::store::table_prefix`]).
//!
//! Layout (little-endian, every part 16-byte aligned, every length known before a pixel exists, so a rerun
//! writes the same bytes whatever order its threads finish in):
//!
//! ```text
//! ShardHeader | command line (JSON) | table prefix | BlockEntry × blocks | HandoffEntry × handoffs
//!             | ImageEntry × images | block payloads (entry order)
//!             | handoff payloads (entry order, RGBA f32 texels)
//! ```
//!
//! The header carries the fingerprint of scene and flags (the merge refuses a mix), an `xxh3_64` of itself
//! and one of everything up to the payloads; each payload has its own checksum in its entry. The image
//! entries hold the hash of the pixels each scene image decoded to in this shard, before any alpha is
//! dropped (version 3; version 2 hashed them after, so the two scene images one glTF image becomes for
//! OPAQUE and alpha materials could not be compared): the fingerprint names an image by name, size and
//! byte length only, so the merge compares these to refuse shards that read two versions of one image.

use super::StoreError;
use crate::ids::BlockId;
use crate::util::AtomicFile;
use bytemuck::{Pod, Zeroable};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU8, AtomicU64, Ordering};

/// First bytes of every shard file.
pub const SHARD_MAGIC: [u8; 8] = *b"ATSHARD\x01";
/// Version of the layout above.
pub const SHARD_VERSION: u32 = 3;
/// Alignment of every part, bytes.
const ALIGN: u64 = 16;

/// The fixed header of a shard file.
#[repr(C)]
#[derive(Copy, Clone, Debug, Pod, Zeroable, PartialEq, Eq)]
pub struct ShardHeader {
    /// [`SHARD_MAGIC`].
    pub magic: [u8; 8],
    /// [`SHARD_VERSION`].
    pub version: u32,
    /// This shard's index, `0..count`.
    pub shard: u32,
    /// Number of shards of the build.
    pub count: u32,
    /// The pixel options (atlas mip kernel, alpha mips: `preprocess::raster::PixelOptions::code`): the
    /// merge makes the atlases above the cut with them.
    pub pixel_options: u32,
    /// `xxh3_128` of scene and flags ([`crate::preprocess::shard`]): equal in every shard of one build.
    pub fingerprint: [u64; 2],
    /// `xxh3_128` of the table prefix (which only shard 0 holds).
    pub prefix_hash: [u64; 2],
    /// Bytes of the command line (a JSON array of strings).
    pub argv_len: u64,
    /// Bytes of the table prefix (0 except in shard 0).
    pub prefix_len: u64,
    /// Number of [`BlockEntry`]s.
    pub blocks: u64,
    /// Number of [`HandoffEntry`]s.
    pub handoffs: u64,
    /// Number of [`ImageEntry`]s: the scene's images.
    pub images: u64,
    pub _reserved: u64,
    /// Exact file length, bytes.
    pub file_len: u64,
    /// `xxh3_64` of every byte from the end of the header to the first payload.
    pub tables_checksum: u64,
    /// `xxh3_64` of the header bytes before this field.
    pub checksum: u64,
}
const HEADER_BYTES: u64 = size_of::<ShardHeader>() as u64;
const _: () = assert!(size_of::<ShardHeader>() == 128);

impl ShardHeader {
    fn compute_checksum(&self) -> u64 {
        let bytes = bytemuck::bytes_of(self);
        xxhash_rust::xxh3::xxh3_64(&bytes[..bytes.len() - size_of::<u64>()])
    }
}

/// One block a shard wrote, in the paging file's block numbering.
#[repr(C)]
#[derive(Copy, Clone, Debug, Pod, Zeroable, PartialEq, Eq)]
pub struct BlockEntry {
    pub block: u32,
    pub _pad: u32,
    /// Offset of the payload in the shard file, bytes.
    pub offset: u64,
    pub length: u64,
    /// `xxh3_64` of the payload (the paging file's block checksum).
    pub checksum: u64,
    /// Compression error of the block (the paging file's `BlockRecord::sse`).
    pub sse: u64,
}

/// The level 1 of a subtree root a shard rasterised (what its parent above the cut is combined from).
#[repr(C)]
#[derive(Copy, Clone, Debug, Pod, Zeroable, PartialEq, Eq)]
pub struct HandoffEntry {
    /// Tree index in the forest.
    pub tree: u32,
    /// Node id in that tree.
    pub node: u32,
    pub width: u32,
    pub height: u32,
    pub offset: u64,
    /// `width × height × 16` bytes: premultiplied linear RGBA, f32.
    pub length: u64,
    pub checksum: u64,
}

/// Bytes of a [`BlockEntry`] or a [`HandoffEntry`].
const ENTRY_BYTES: u64 = 40;
const _: () = assert!(size_of::<BlockEntry>() == 40 && size_of::<HandoffEntry>() == 40);

/// One scene image as this shard decoded it (or did not need it).
#[repr(C)]
#[derive(Copy, Clone, Debug, Pod, Zeroable, PartialEq, Eq)]
pub struct ImageEntry {
    /// `xxh3_128` of the decoded RGBA8 pixels as the file holds them, before an OPAQUE-only image's
    /// alpha is dropped (`preprocess::image_cache::ImageCache::pixel_hashes`); 0 when not decoded.
    pub pixels: [u64; 2],
    /// Index of the image in the scene.
    pub image: u32,
    /// Its glTF image index, `u32::MAX` for none (a solid colour): scene images of one glTF image hold
    /// one file's pixels, compared across shards.
    pub gltf_image: u32,
    /// 1 when this shard decoded the image, else 0.
    pub decoded: u32,
    pub _pad: u32,
}
const IMAGE_ENTRY_BYTES: u64 = size_of::<ImageEntry>() as u64;
const _: () = assert!(IMAGE_ENTRY_BYTES == 32);

/// What a shard file holds, known before any pixel: the input of [`ShardWriter::create`].
pub struct ShardLayout {
    pub shard: u32,
    pub count: u32,
    pub pixel_options: u32,
    pub fingerprint: [u64; 2],
    pub prefix_hash: [u64; 2],
    /// The command line that builds this shard (JSON array), for the merge's "rebuild with".
    pub argv: Vec<u8>,
    /// The table prefix (shard 0), or empty.
    pub prefix: Vec<u8>,
    /// Blocks and their lengths, ascending by id.
    pub blocks: Vec<(BlockId, u64)>,
    /// `(tree, node, width, height)` of each handoff, ascending by (tree, node).
    pub handoffs: Vec<(u32, u32, u32, u32)>,
    /// The glTF image index of each scene image (`u32::MAX`: none); their pixel hashes come at
    /// [`ShardWriter::finish`].
    pub images: Vec<u32>,
}

fn align(x: u64) -> u64 {
    x.div_ceil(ALIGN) * ALIGN
}

const UNWRITTEN: u8 = 0;
const WRITING: u8 = 1;
const WRITTEN: u8 = 2;

/// A shard file being written: create it from its [`ShardLayout`], put blocks and handoffs from any thread
/// in any order, then [`ShardWriter::finish`] (atomic, as the paging file: nothing partial appears).
pub struct ShardWriter {
    temp: AtomicFile,
    header: ShardHeader,
    blocks: Vec<BlockEntry>,
    handoffs: Vec<HandoffEntry>,
    block_state: Vec<AtomicU8>,
    block_sums: Vec<AtomicU64>,
    block_sse: Vec<AtomicU64>,
    handoff_state: Vec<AtomicU8>,
    handoff_sums: Vec<AtomicU64>,
    /// Each scene image's glTF index ([`ShardLayout::images`]).
    images: Vec<u32>,
    /// The command line and the prefix, written at finish with the tables.
    head: Vec<u8>,
}

impl ShardWriter {
    /// Lays out the shard file and creates its temp file beside `path`.
    pub fn create(path: &Path, layout: ShardLayout) -> Result<ShardWriter, StoreError> {
        let argv_len = layout.argv.len() as u64;
        let mut head = layout.argv;
        head.resize(align(head.len() as u64) as usize, 0);
        head.extend_from_slice(&layout.prefix);
        head.resize(align(head.len() as u64) as usize, 0);
        let tables_start = HEADER_BYTES + head.len() as u64;
        let entries = (layout.blocks.len() + layout.handoffs.len()) as u64 * ENTRY_BYTES
            + layout.images.len() as u64 * IMAGE_ENTRY_BYTES;
        let mut at = align(tables_start + entries);
        let mut blocks = Vec::with_capacity(layout.blocks.len());
        for &(id, length) in &layout.blocks {
            blocks.push(BlockEntry {
                block: id.0,
                _pad: 0,
                offset: at,
                length,
                checksum: 0,
                sse: 0,
            });
            at = align(at + length);
        }
        let mut handoffs = Vec::with_capacity(layout.handoffs.len());
        for &(tree, node, width, height) in &layout.handoffs {
            let length = u64::from(width) * u64::from(height) * 16;
            handoffs.push(HandoffEntry {
                tree,
                node,
                width,
                height,
                offset: at,
                length,
                checksum: 0,
            });
            at = align(at + length);
        }
        let header = ShardHeader {
            magic: SHARD_MAGIC,
            version: SHARD_VERSION,
            shard: layout.shard,
            count: layout.count,
            pixel_options: layout.pixel_options,
            fingerprint: layout.fingerprint,
            prefix_hash: layout.prefix_hash,
            argv_len,
            prefix_len: layout.prefix.len() as u64,
            blocks: blocks.len() as u64,
            handoffs: handoffs.len() as u64,
            images: layout.images.len() as u64,
            _reserved: 0,
            file_len: at,
            tables_checksum: 0,
            checksum: 0,
        };
        let temp = super::create_output(path)?;
        let w = ShardWriter {
            block_state: blocks.iter().map(|_| AtomicU8::new(UNWRITTEN)).collect(),
            block_sums: blocks.iter().map(|_| AtomicU64::new(0)).collect(),
            block_sse: blocks.iter().map(|_| AtomicU64::new(0)).collect(),
            handoff_state: handoffs.iter().map(|_| AtomicU8::new(UNWRITTEN)).collect(),
            handoff_sums: handoffs.iter().map(|_| AtomicU64::new(0)).collect(),
            temp,
            header,
            blocks,
            handoffs,
            images: layout.images,
            head,
        };
        super::positional::size_and_reserve(w.temp.file(), at, path, w.temp.temp_path())?;
        Ok(w)
    }

    fn temp_err(&self, source: std::io::Error) -> StoreError {
        StoreError::Write {
            target: self.temp.target().to_path_buf(),
            temp: self.temp.temp_path().to_path_buf(),
            source,
        }
    }

    /// Claims `state` (one block or handoff) and writes `bytes` at `offset`.
    fn put(&self, state: &AtomicU8, offset: u64, bytes: &[u8]) -> Result<(), StoreError> {
        if state
            .compare_exchange(UNWRITTEN, WRITING, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            return Err(StoreError::ShardPutTwice {
                path: self.temp.target().to_path_buf(),
                offset,
            });
        }
        if let Err(e) = write_at(self.temp.file(), offset, bytes) {
            state.store(UNWRITTEN, Ordering::Release);
            return Err(self.temp_err(e));
        }
        Ok(())
    }

    /// Writes block `id` (exactly its laid-out length, once) with its compression error `sse`.
    pub fn put_block(&self, id: BlockId, bytes: &[u8], sse: u64) -> Result<(), StoreError> {
        let i = self
            .blocks
            .binary_search_by_key(&id.0, |e| e.block)
            .map_err(|_| StoreError::ShardForeignBlock {
                path: self.temp.target().to_path_buf(),
                block: id,
            })?;
        let e = &self.blocks[i];
        if bytes.len() as u64 != e.length {
            return Err(StoreError::BlockLength {
                block: id,
                expected: e.length,
                got: bytes.len() as u64,
            });
        }
        self.put(&self.block_state[i], e.offset, bytes)?;
        self.block_sums[i].store(xxhash_rust::xxh3::xxh3_64(bytes), Ordering::Relaxed);
        self.block_sse[i].store(sse, Ordering::Relaxed);
        self.block_state[i].store(WRITTEN, Ordering::Release);
        Ok(())
    }

    /// Writes the handoff of `(tree, node)`: `texels` row-major, `width × height` as laid out.
    pub fn put_handoff(&self, tree: u32, node: u32, texels: &[[f32; 4]]) -> Result<(), StoreError> {
        let i = self
            .handoffs
            .binary_search_by_key(&(tree, node), |e| (e.tree, e.node))
            .map_err(|_| StoreError::ShardForeignHandoff {
                path: self.temp.target().to_path_buf(),
                tree,
                node,
            })?;
        let e = &self.handoffs[i];
        let bytes: &[u8] = bytemuck::cast_slice(texels);
        if bytes.len() as u64 != e.length {
            return Err(StoreError::ShardHandoffSize {
                tree,
                node,
                expected: e.length,
                got: bytes.len() as u64,
            });
        }
        self.put(&self.handoff_state[i], e.offset, bytes)?;
        self.handoff_sums[i].store(xxhash_rust::xxh3::xxh3_64(bytes), Ordering::Relaxed);
        self.handoff_state[i].store(WRITTEN, Ordering::Release);
        Ok(())
    }

    /// Writes the tables (with `pixels`, the hash of each scene image this shard decoded, `None` for one
    /// it did not) and the header and publishes the file; fails naming the first block or handoff never
    /// written (then nothing appears). Returns the file length.
    pub fn finish(mut self, pixels: &[Option<[u64; 2]>]) -> Result<u64, StoreError> {
        if pixels.len() != self.images.len() {
            return Err(StoreError::ShardImages {
                path: self.temp.target().to_path_buf(),
                expected: self.images.len(),
                got: pixels.len(),
            });
        }
        for (i, s) in self.block_state.iter().enumerate() {
            if s.load(Ordering::Acquire) != WRITTEN {
                return Err(StoreError::BlockMissing {
                    block: BlockId(self.blocks[i].block),
                });
            }
        }
        for (i, s) in self.handoff_state.iter().enumerate() {
            if s.load(Ordering::Acquire) != WRITTEN {
                let e = &self.handoffs[i];
                return Err(StoreError::ShardHandoffMissing {
                    tree: e.tree,
                    node: e.node,
                });
            }
        }
        for ((e, sum), sse) in self
            .blocks
            .iter_mut()
            .zip(&self.block_sums)
            .zip(&self.block_sse)
        {
            e.checksum = sum.load(Ordering::Relaxed);
            e.sse = sse.load(Ordering::Relaxed);
        }
        for (e, sum) in self.handoffs.iter_mut().zip(&self.handoff_sums) {
            e.checksum = sum.load(Ordering::Relaxed);
        }
        let mut tables = std::mem::take(&mut self.head);
        tables.extend_from_slice(bytemuck::cast_slice(&self.blocks));
        tables.extend_from_slice(bytemuck::cast_slice(&self.handoffs));
        for (i, (&gltf_image, hash)) in self.images.iter().zip(pixels).enumerate() {
            let entry = ImageEntry {
                pixels: hash.unwrap_or([0; 2]),
                image: i as u32,
                gltf_image,
                decoded: u32::from(hash.is_some()),
                _pad: 0,
            };
            tables.extend_from_slice(bytemuck::bytes_of(&entry));
        }
        self.header.tables_checksum = xxhash_rust::xxh3::xxh3_64(&tables);
        self.header.checksum = self.header.compute_checksum();
        let file = self.temp.file();
        write_at(file, 0, bytemuck::bytes_of(&self.header)).map_err(|e| self.temp_err(e))?;
        write_at(file, HEADER_BYTES, &tables).map_err(|e| self.temp_err(e))?;
        let len = self.header.file_len;
        let target = self.temp.target().to_path_buf();
        let temp_path = self.temp.temp_path().to_path_buf();
        self.temp.commit().map_err(|source| StoreError::Write {
            target,
            temp: temp_path,
            source,
        })?;
        Ok(len)
    }
}

impl super::BlockSink for ShardWriter {
    fn put_block(&self, id: BlockId, bytes: &[u8], sse: u64) -> Result<(), StoreError> {
        ShardWriter::put_block(self, id, bytes, sse)
    }
}

pub(super) fn write_at(file: &File, offset: u64, bytes: &[u8]) -> std::io::Result<()> {
    super::positional::write_all_at(file, bytes, offset)
}

pub(super) fn read_at(file: &File, offset: u64, len: u64) -> std::io::Result<Vec<u8>> {
    let mut buf = vec![0u8; len as usize];
    super::positional::read_exact_at(file, &mut buf, offset)?;
    Ok(buf)
}

/// Why a shard file was refused. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ShardFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "{path}: not an atlastree shard file ({})",
        super::describe_start(found)
    )]
    BadMagic { path: PathBuf, found: Vec<u8> },
    #[error("{path}: shard format version {found}, this build reads {SHARD_VERSION}")]
    Version { path: PathBuf, found: u32 },
    #[error("{path}: {len} bytes, {expected} expected (truncated or extended)")]
    Length {
        path: PathBuf,
        len: u64,
        expected: u64,
    },
    #[error("{path}: {what} checksum mismatch (expected {expected:#018x}, found {found:#018x})")]
    Checksum {
        path: PathBuf,
        what: String,
        expected: u64,
        found: u64,
    },
    #[error("{path}: {what}")]
    Layout { path: PathBuf, what: String },
}

/// A shard file opened for the merge: header and tables validated, payloads read (and checked) on demand.
pub struct ShardFile {
    path: PathBuf,
    file: File,
    pub header: ShardHeader,
    pub argv: Vec<String>,
    pub blocks: Vec<BlockEntry>,
    pub handoffs: Vec<HandoffEntry>,
    /// Each scene image's pixel hash as this shard decoded it.
    pub images: Vec<ImageEntry>,
    prefix_at: u64,
}

impl ShardFile {
    /// Opens `path` and checks magic, version, header checksum, exact length, the tables' checksum and
    /// that every payload lies inside the file, in order, without overlap.
    pub fn open(path: &Path) -> Result<ShardFile, ShardFileError> {
        let io = |source| ShardFileError::Io {
            path: path.to_path_buf(),
            source,
        };
        let layout = |what: String| ShardFileError::Layout {
            path: path.to_path_buf(),
            what,
        };
        let file = crate::util::open_regular(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        if len < HEADER_BYTES {
            return Err(ShardFileError::Length {
                path: path.to_path_buf(),
                len,
                expected: HEADER_BYTES,
            });
        }
        let hb = read_at(&file, 0, HEADER_BYTES).map_err(io)?;
        let header: ShardHeader = bytemuck::pod_read_unaligned(&hb);
        if header.magic != SHARD_MAGIC {
            return Err(ShardFileError::BadMagic {
                path: path.to_path_buf(),
                found: header.magic.to_vec(),
            });
        }
        if header.version != SHARD_VERSION {
            return Err(ShardFileError::Version {
                path: path.to_path_buf(),
                found: header.version,
            });
        }
        let sum = header.compute_checksum();
        if sum != header.checksum {
            return Err(ShardFileError::Checksum {
                path: path.to_path_buf(),
                what: "header".into(),
                expected: header.checksum,
                found: sum,
            });
        }
        if header.file_len != len {
            return Err(ShardFileError::Length {
                path: path.to_path_buf(),
                len,
                expected: header.file_len,
            });
        }
        let aligned = |x: u64| x.checked_next_multiple_of(ALIGN);
        let head = header
            .blocks
            .checked_add(header.handoffs)
            .and_then(|n| n.checked_mul(ENTRY_BYTES))
            .zip(header.images.checked_mul(IMAGE_ENTRY_BYTES))
            .and_then(|(a, b)| a.checked_add(b))
            .zip(aligned(header.argv_len).zip(aligned(header.prefix_len)))
            .and_then(|(e, (a, p))| a.checked_add(p)?.checked_add(e))
            .filter(|&t| t <= len - HEADER_BYTES)
            .ok_or_else(|| layout("tables larger than the file".into()))?;
        // The prefix (shard 0: the paging file's tables, ≈ 50 bytes per triangle) is hashed in pieces,
        // never held; the command line and the entries are read.
        let (argv_part, prefix_part) = (align(header.argv_len), align(header.prefix_len));
        let argv_bytes = read_at(&file, HEADER_BYTES, argv_part).map_err(io)?;
        let entries_at = HEADER_BYTES + argv_part + prefix_part;
        let entries = read_at(&file, entries_at, head - argv_part - prefix_part).map_err(io)?;
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        hasher.update(&argv_bytes);
        super::read::stream_update(&mut hasher, &file, HEADER_BYTES + argv_part, prefix_part)
            .map_err(io)?;
        hasher.update(&entries);
        let sum = hasher.digest();
        if sum != header.tables_checksum {
            return Err(ShardFileError::Checksum {
                path: path.to_path_buf(),
                what: "tables".into(),
                expected: header.tables_checksum,
                found: sum,
            });
        }
        let argv: Vec<String> = serde_json::from_slice(&argv_bytes[..header.argv_len as usize])
            .map_err(|e| layout(format!("command line: {e}")))?;
        let split = (header.blocks * ENTRY_BYTES) as usize;
        let split_images = ((header.blocks + header.handoffs) * ENTRY_BYTES) as usize;
        let blocks: Vec<BlockEntry> = entries[..split]
            .chunks_exact(ENTRY_BYTES as usize)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let handoffs: Vec<HandoffEntry> = entries[split..split_images]
            .chunks_exact(ENTRY_BYTES as usize)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        let images: Vec<ImageEntry> = entries[split_images..]
            .chunks_exact(IMAGE_ENTRY_BYTES as usize)
            .map(bytemuck::pod_read_unaligned)
            .collect();
        for (i, e) in images.iter().enumerate() {
            if e.image != i as u32 || e.decoded > 1 || (e.decoded == 0 && e.pixels != [0; 2]) {
                return Err(layout(format!("image entry {i} is malformed")));
            }
        }
        let mut end = align(HEADER_BYTES + head);
        for (what, offset, length) in blocks
            .iter()
            .map(|b| (format!("block {}", b.block), b.offset, b.length))
            .chain(handoffs.iter().map(|h| {
                (
                    format!("handoff of tree {} node {}", h.tree, h.node),
                    h.offset,
                    h.length,
                )
            }))
        {
            if offset != end || offset.checked_add(length).is_none_or(|e| e > len) {
                return Err(layout(format!(
                    "{what} at {offset}+{length}, expected at {end} inside {len} bytes"
                )));
            }
            end = align(offset + length);
        }
        if blocks.windows(2).any(|w| w[0].block >= w[1].block) {
            return Err(layout("block entries not in ascending order".into()));
        }
        if handoffs
            .iter()
            .any(|h| u64::from(h.width) * u64::from(h.height) * 16 != h.length)
        {
            return Err(layout(
                "a handoff's length is not width × height × 16".into(),
            ));
        }
        Ok(ShardFile {
            path: path.to_path_buf(),
            file,
            header,
            argv,
            blocks,
            handoffs,
            images,
            prefix_at: HEADER_BYTES + align(header.argv_len),
        })
    }

    /// The file's path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    fn payload(
        &self,
        what: String,
        offset: u64,
        length: u64,
        checksum: u64,
    ) -> Result<Vec<u8>, ShardFileError> {
        let bytes = read_at(&self.file, offset, length).map_err(|source| ShardFileError::Io {
            path: self.path.clone(),
            source,
        })?;
        let found = xxhash_rust::xxh3::xxh3_64(&bytes);
        if found != checksum {
            return Err(ShardFileError::Checksum {
                path: self.path.clone(),
                what,
                expected: checksum,
                found,
            });
        }
        Ok(bytes)
    }

    /// The table prefix's tables without their geometry ([`super::TreeFile::skeleton_prefix`]); the prefix's
    /// bytes were checked when the file was opened (the tables checksum covers them) and are checked again
    /// against `prefix_hash` when [`ShardFile::writer`] copies them.
    pub fn skeleton(&self) -> Result<super::TreeFile, StoreError> {
        let name = self.path.display().to_string();
        super::TreeFile::skeleton_prefix(&self.file, self.prefix_at, self.header.prefix_len, &name)
    }

    /// A writer of `out` whose tables are this shard's prefix (`tables`, its [`ShardFile::skeleton`]),
    /// copied in pieces and checked against the prefix hash on the way.
    pub fn writer(
        &self,
        out: &Path,
        tables: &super::TreeFile,
    ) -> Result<super::FileWriter, StoreError> {
        let (at, len) = (self.prefix_at, self.header.prefix_len);
        super::FileWriter::from_prefix_file(
            out,
            tables,
            &self.file,
            at,
            len,
            self.header.prefix_hash,
        )
    }

    /// The payload of block entry `i`, checksum verified.
    pub fn block(&self, i: usize) -> Result<Vec<u8>, ShardFileError> {
        let e = self.blocks[i];
        self.payload(format!("block {}", e.block), e.offset, e.length, e.checksum)
    }

    /// The texels of handoff entry `i`, checksum verified.
    pub fn handoff(&self, i: usize) -> Result<Vec<[f32; 4]>, ShardFileError> {
        let e = self.handoffs[i];
        let bytes = self.payload(
            format!("handoff of tree {} node {}", e.tree, e.node),
            e.offset,
            e.length,
            e.checksum,
        )?;
        Ok(bytes
            .chunks_exact(16)
            .map(bytemuck::pod_read_unaligned::<[f32; 4]>)
            .collect())
    }
}

/// `xxh3_128` as the two words the header stores.
pub fn hash128(bytes: &[u8]) -> [u64; 2] {
    crate::util::digest_words(xxhash_rust::xxh3::xxh3_128(bytes))
}
