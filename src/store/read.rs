//! Reading a paging file: map it, read it whole, or read its tables only (`LoadMode`) once, validate
//! everything that is cheap to validate, then hand out the tables in place as typed slices and the blocks
//! as checksum-verified bytes (`Cow`: lent by a file held in memory, read through the file's handle
//! otherwise).

use super::format::{
    BLOCK_ALIGN, BlockRecord, HEADER_SIZE, Header, LeafRecord, MaterialRecord, NodeRecord,
    OriginalRecord, ParamsRecord, Range64, RectRecord, Section, TreeRecord, align_up,
};
use super::validate::{self, TreeCounts, TreeTables};
use super::{StoreError, check_endian};
use crate::ids::BlockId;
use crate::model::{AtlasForest, AtlasTree, BuildParams, TreeKind, TreeVertex};
use crate::scene::Material;
use bytemuck::Pod;
use rayon::prelude::*;
use std::borrow::Cow;
use std::fs::File;
use std::io::Read;

mod framing;
mod prefix;

pub(super) use framing::sections_end;
use framing::{
    check_block_layout, check_file_len, check_sections, checksum, parse_header, slice_at,
};
pub use framing::{check_block_padding, padding_range};
pub(super) use prefix::{for_each_piece, stream_hash128, stream_update};
use std::path::{Path, PathBuf};

/// How [`TreeFile::open_with`] gets the bytes.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq)]
pub enum LoadMode {
    /// Memory-map; read the whole file instead if mapping fails or `ATLASTREE_NO_MMAP=1`.
    #[default]
    Auto,
    /// Memory-map or fail.
    Mmap,
    /// Read the whole file into an 8-byte-aligned buffer.
    Read,
    /// Read the tables (header and sections) into memory, and each block, when asked for, through the
    /// file's handle: a file truncated or rewritten in place while it is read gives errors naming what it
    /// lost, never SIGBUS (`export`, `inspect`: they read for long). Costs memory the size of the tables,
    /// geometry included (~300 MB for the 6 M-triangle all-tracks world), where a map's pages are the
    /// kernel's to reclaim.
    Tables,
}

/// `len` bytes in 8-byte-aligned storage (the records' alignment), filled by `fill`.
fn aligned(
    len: usize,
    fill: impl FnOnce(&mut [u8]) -> std::io::Result<()>,
) -> std::io::Result<Vec<u64>> {
    let mut words = vec![0u64; len.div_ceil(8)];
    fill(&mut bytemuck::cast_slice_mut::<u64, u8>(&mut words)[..len])?;
    Ok(words)
}

/// The bytes of an open file.
enum Backing {
    /// The map, and a handle on the file it maps for positional reads of blocks ([`TreeFile::block`]).
    Mmap { map: memmap2::Mmap, file: File },
    /// `words` holds `len` bytes; `u64` storage guarantees the 8-byte alignment the records need.
    Owned { words: Vec<u64>, len: usize },
    /// [`LoadMode::Tables`]: the file's first `len` bytes (header and sections) in `words`, and a handle
    /// on the file for positional reads of blocks.
    Tables {
        words: Vec<u64>,
        len: usize,
        file: File,
    },
}

impl Backing {
    fn bytes(&self) -> &[u8] {
        match self {
            Backing::Mmap { map, .. } => map,
            Backing::Owned { words, len } | Backing::Tables { words, len, .. } => {
                bytemuck::cast_slice::<u64, u8>(words)
                    .get(..*len)
                    .unwrap_or(&[])
            }
        }
    }

    /// The handle blocks are read through, where the file is not held in memory whole.
    fn positional(&self) -> Option<&File> {
        match self {
            Backing::Mmap { file, .. } | Backing::Tables { file, .. } => Some(file),
            Backing::Owned { .. } => None,
        }
    }

    /// [`LoadMode::Tables`]: reads the header and the sections it lists (up to the first block); returns
    /// them with the file's length.
    fn tables(file: File, path: &Path) -> Result<(Backing, u64), StoreError> {
        let io = |e| StoreError::io(path, e);
        let file_len = file.metadata().map_err(io)?.len();
        let mut head = vec![0u8; HEADER_SIZE.min(usize::try_from(file_len).unwrap_or(HEADER_SIZE))];
        super::positional::read_exact_at(&file, &mut head, 0).map_err(io)?;
        let header = parse_header(path, &head)?;
        let end = sections_end(&header)
            .and_then(|end| align_up(end, BLOCK_ALIGN))
            .ok_or(StoreError::LayoutOverflow { what: "sections" })?;
        let len = end.min(header.file_len).min(file_len);
        let len = usize::try_from(len).map_err(|_| StoreError::LayoutOverflow { what: "file" })?;
        let words = aligned(len, |b| super::positional::read_exact_at(&file, b, 0)).map_err(io)?;
        Ok((Backing::Tables { words, len, file }, file_len))
    }

    /// An aligned copy of `bytes`.
    fn copy_of(bytes: &[u8]) -> Backing {
        let words = aligned(bytes.len(), |b| {
            b.copy_from_slice(bytes);
            Ok(())
        })
        .unwrap_or_default(); // the fill cannot fail
        Backing::Owned {
            words,
            len: bytes.len(),
        }
    }

    fn read(file: &mut File, path: &Path) -> Result<Backing, StoreError> {
        let len = file.metadata().map_err(|e| StoreError::io(path, e))?.len();
        let len = usize::try_from(len).map_err(|_| StoreError::LayoutOverflow { what: "file" })?;
        let words = aligned(len, |b| file.read_exact(b)).map_err(|e| StoreError::io(path, e))?;
        Ok(Backing::Owned { words, len })
    }

    /// Maps `file` read-only.
    #[allow(
        unsafe_code,
        reason = "memory-mapping the file: the one unsafe call, SAFETY below"
    )]
    fn map(file: &File, path: &Path) -> Result<Backing, StoreError> {
        // SAFETY: see the contract on `TreeFile`: the file is treated as immutable while mapped; the map is
        // read-only and every byte we interpret is validated (bounds, checksums) before use.
        let map = unsafe { memmap2::Mmap::map(file) }.map_err(|e| StoreError::io(path, e))?;
        let file = file.try_clone().map_err(|e| StoreError::io(path, e))?;
        Ok(Backing::Mmap { map, file })
    }
}

/// A paging file's blocks read with positional reads through a handle of their own, not the memory map:
/// a file truncated or rewritten in place while it is paged from gives an error for each block it lost
/// (counted by the pager, drawn coarser), where a read through the map would end the process with SIGBUS.
/// A file renamed over the path keeps being read from the file this handle opened.
pub struct BlockReader {
    file: File,
    path: PathBuf,
}

impl BlockReader {
    pub fn open(path: &Path) -> Result<BlockReader, StoreError> {
        let file = crate::util::open_regular(path).map_err(|e| StoreError::io(path, e))?;
        Ok(BlockReader {
            file,
            path: path.to_path_buf(),
        })
    }

    /// The `length` bytes at `offset` (a block's record); unchecked (the caller verifies the checksum).
    pub fn read(&self, offset: u64, length: u64) -> Result<Vec<u8>, StoreError> {
        let len = usize::try_from(length).map_err(|_| {
            StoreError::io(&self.path, std::io::Error::other("block length past usize"))
        })?;
        let mut bytes = vec![0u8; len];
        super::positional::read_exact_at(&self.file, &mut bytes, offset).map_err(|e| {
            let e = std::io::Error::new(e.kind(), format!("bytes {offset}..+{length}: {e}"));
            StoreError::io(&self.path, e)
        })?;
        Ok(bytes)
    }
}

/// An open, validated paging file.
///
/// # Safety contract of the memory map
/// With [`LoadMode::Auto`] or [`LoadMode::Mmap`] the file is memory-mapped and its tables are read in place.
/// The file **must not be modified or truncated while a `TreeFile` maps it**: another process writing it
/// would change bytes behind validated slices (Rust's aliasing rules), and truncating it makes reads of the
/// tables fault (SIGBUS; blocks are read through the file's handle, never the map, so a lost block is an
/// error). The writer never does this — it replaces files by atomic rename, which leaves an existing map
/// on the old inode intact. We treat the mapping as read-only and never write through it. Where that
/// contract cannot be guaranteed (network file systems, files shared with other writers), use
/// [`LoadMode::Read`] or set `ATLASTREE_NO_MMAP=1`.
///
/// Everything is validated at open (see [`TreeFile::open_with`]) except block contents, which are verified
/// on each [`TreeFile::block`] load.
pub struct TreeFile {
    path: PathBuf,
    backing: Backing,
    header: Header,
    /// False for a table prefix ([`TreeFile::from_prefix`]): blocks come from a `BlockSource`.
    holds_blocks: bool,
    /// False for a prefix read without its geometry ([`TreeFile::skeleton_prefix`]): the trees' vertices,
    /// indices and source triangles are empty.
    holds_geometry: bool,
}

/// One tree of a file: its tables as slices into the file. Ids are tree-local.
#[derive(Copy, Clone, Debug)]
pub struct TreeView<'a> {
    pub kind: TreeKind,
    /// The tree's record (its ranges in the file's sections).
    pub record: &'a TreeRecord,
    /// `nodes[0]` is the root; parents precede children.
    pub nodes: &'a [NodeRecord],
    /// In tree order.
    pub leaves: &'a [LeafRecord],
    /// All leaves' rects; a leaf's are [`TreeView::leaf_rects`].
    pub rects: &'a [RectRecord],
    /// All leaves' originals; a leaf's are [`TreeView::leaf_originals`].
    pub originals: &'a [OriginalRecord],
    pub vertices: &'a [TreeVertex],
    /// Indices into `vertices` (validated in range).
    pub indices: &'a [u32],
    /// Scene triangle of each triangle of `indices`.
    pub source_triangles: &'a [u32],
}

impl TreeView<'_> {
    /// The storage format of the tree's blocks (validated at open).
    pub fn format(&self) -> crate::texfmt::TexFormat {
        self.record.tex_format().unwrap_or_default()
    }

    /// The rects of `leaf`, empty for an out-of-range leaf.
    pub fn leaf_rects(&self, leaf: &LeafRecord) -> &[RectRecord] {
        sub(self.rects, leaf.first_rect, leaf.rect_count)
    }

    /// The originals of `leaf`, empty for an out-of-range leaf.
    pub fn leaf_originals(&self, leaf: &LeafRecord) -> &[OriginalRecord] {
        sub(self.originals, leaf.first_original, leaf.original_count)
    }

    /// Decodes the tree into its in-memory form.
    pub fn to_tree(&self) -> Option<AtlasTree> {
        let mut tree = self.to_skeleton()?;
        tree.vertices = self.vertices.to_vec();
        tree.indices = self.indices.to_vec();
        tree.source_triangles = self.source_triangles.to_vec();
        Some(tree)
    }

    /// The tree without its geometry (vertices, indices and source triangles empty): nodes, leaves, rects
    /// and originals, all a merge of shards needs (a few bytes per node, none per triangle).
    pub fn to_skeleton(&self) -> Option<AtlasTree> {
        Some(AtlasTree {
            kind: self.kind,
            format: self.format(),
            nodes: self
                .nodes
                .iter()
                .map(NodeRecord::decode)
                .collect::<Option<Vec<_>>>()?,
            leaves: self
                .leaves
                .iter()
                .map(|l| l.decode(self.leaf_rects(l), self.leaf_originals(l)))
                .collect(),
            vertices: Vec::new(),
            indices: Vec::new(),
            source_triangles: Vec::new(),
        })
    }
}

fn sub<T>(items: &[T], first: u32, count: u32) -> &[T] {
    let first = first as usize;
    items
        .get(first..first.saturating_add(count as usize))
        .unwrap_or(&[])
}

fn range<'a, T>(items: &'a [T], r: &Range64) -> Option<&'a [T]> {
    let first = usize::try_from(r.first).ok()?;
    let end = usize::try_from(r.end()?).ok()?;
    items.get(first..end)
}

impl TreeFile {
    /// Opens `path` with [`LoadMode::Auto`].
    pub fn open(path: &Path) -> Result<TreeFile, StoreError> {
        Self::open_with(path, LoadMode::Auto)
    }

    /// Opens and validates `path`: magic, version, header checksum, file length; every section's kind,
    /// record size, alignment, length, order, bounds and checksum, zero gaps; block placement; and the
    /// cross-references between tables (node links, ranges, material and block ids, vertex leaf ids, index
    /// values). Block contents are checked later, per load.
    pub fn open_with(path: &Path, mode: LoadMode) -> Result<TreeFile, StoreError> {
        check_endian()?;
        let mut file = crate::util::open_regular(path).map_err(|e| StoreError::io(path, e))?;
        let no_mmap = std::env::var_os("ATLASTREE_NO_MMAP").is_some_and(|v| v == "1");
        let backing = match mode {
            LoadMode::Mmap => Backing::map(&file, path)?,
            LoadMode::Read => Backing::read(&mut file, path)?,
            LoadMode::Tables => {
                let (backing, file_len) = Backing::tables(file, path)?;
                return Self::validate(path.to_path_buf(), backing, file_len, true);
            }
            LoadMode::Auto if no_mmap => Backing::read(&mut file, path)?,
            LoadMode::Auto => match Backing::map(&file, path) {
                Ok(m) => m,
                Err(_) => Backing::read(&mut file, path)?,
            },
        };
        Self::from_backing(path.to_path_buf(), backing)
    }

    /// Opens this file's path again (a second handle for the pager's loader threads) and checks that it
    /// still holds the same file: header (every table's checksum in it) and block table equal. A file
    /// published over the path in between (a build's atomic rename) is refused with
    /// [`StoreError::Replaced`], never drawn with its blocks under these tables.
    pub fn reopen(&self) -> Result<TreeFile, StoreError> {
        // The same way of reading as this one: a tables-only file reopened as a map read its blocks
        // through the map, and a file truncated meanwhile killed `render --capacity` by SIGBUS (fault
        // hunt, session 37).
        let mode = match self.backing {
            Backing::Mmap { .. } => LoadMode::Auto,
            Backing::Owned { .. } => LoadMode::Read,
            Backing::Tables { .. } => LoadMode::Tables,
        };
        let again = Self::open_with(&self.path, mode)?;
        if again.header() != self.header() || again.blocks() != self.blocks() {
            return Err(StoreError::Replaced {
                path: self.path.clone(),
            });
        }
        Ok(again)
    }

    /// Validates a file held in memory (tests, HTTP). The bytes are copied into an aligned buffer.
    pub fn from_bytes(bytes: &[u8]) -> Result<TreeFile, StoreError> {
        check_endian()?;
        Self::from_backing(PathBuf::from("<memory>"), Backing::copy_of(bytes))
    }

    /// Validates the tables of a file whose blocks are elsewhere (a server): `bytes` is the file's prefix
    /// (at least [`TreeFile::prefix_len`] bytes: header and every section), `file_len` the whole file's
    /// length, `name` what errors and [`TreeFile::path`] call it (a URL). Validation is exactly
    /// [`TreeFile::open_with`]'s, except that bytes past the prefix (the blocks, and any zero gap beyond
    /// it) are not checked; [`TreeFile::block`] then fails with [`StoreError::BlocksNotHeld`] — blocks
    /// come from a `paging::BlockSource`, which verifies each on arrival.
    pub fn from_prefix(bytes: &[u8], file_len: u64, name: &str) -> Result<TreeFile, StoreError> {
        check_endian()?;
        let path = PathBuf::from(name);
        if bytes.len() as u64 > file_len {
            return Err(StoreError::TrailingBytes {
                path,
                len: bytes.len() as u64,
                expected: file_len,
            });
        }
        Self::validate(path, Backing::copy_of(bytes), file_len, false)
    }

    /// [`TreeFile::from_prefix`] of a table prefix that is the whole file's ([`crate::store::table_prefix`]):
    /// the file length is the one its header claims (checked with everything else).
    pub fn from_table_prefix(bytes: &[u8], name: &str) -> Result<TreeFile, StoreError> {
        let Some(head) = bytes.get(..HEADER_SIZE) else {
            return Err(StoreError::Truncated {
                path: PathBuf::from(name),
                len: bytes.len() as u64,
                needed: HEADER_SIZE as u64,
            });
        };
        let claimed: Header = bytemuck::pod_read_unaligned(head);
        Self::from_prefix(bytes, claimed.file_len, name)
    }

    /// How many leading bytes of a file [`TreeFile::from_prefix`] needs, from its first [`HEADER_SIZE`]
    /// bytes (checked: magic, version, checksum, constants): the end of the tables rounded up to
    /// [`BLOCK_ALIGN`] (where the writer puts the first block, so the zero gap is checked too), at most the
    /// file length.
    pub fn prefix_len(header_bytes: &[u8]) -> Result<u64, StoreError> {
        check_endian()?;
        let header = parse_header(Path::new("<header>"), header_bytes)?;
        let end = sections_end(&header)
            .and_then(|end| align_up(end, BLOCK_ALIGN))
            .ok_or(StoreError::LayoutOverflow { what: "sections" })?;
        Ok(end.min(header.file_len))
    }

    fn from_backing(path: PathBuf, backing: Backing) -> Result<TreeFile, StoreError> {
        let len = backing.bytes().len() as u64;
        Self::validate(path, backing, len, true)
    }

    /// The validation shared by whole files and table prefixes; `file_len` is the whole file's length.
    fn validate(
        path: PathBuf,
        backing: Backing,
        file_len: u64,
        holds_blocks: bool,
    ) -> Result<TreeFile, StoreError> {
        Self::validate_with(path, backing, file_len, holds_blocks, true)
    }

    fn validate_with(
        path: PathBuf,
        backing: Backing,
        file_len: u64,
        holds_blocks: bool,
        holds_geometry: bool,
    ) -> Result<TreeFile, StoreError> {
        let bytes = backing.bytes();
        let header = parse_header(&path, bytes)?;
        check_file_len(&path, &header, file_len)?;
        let tables_end = check_sections(&path, &header, bytes, holds_geometry)?;
        let file = TreeFile {
            path,
            backing,
            header,
            holds_blocks,
            holds_geometry,
        };
        check_block_layout(file.blocks(), tables_end, file.bytes(), file_len)?;
        file.check_tables()?;
        Ok(file)
    }

    fn check_tables(&self) -> Result<(), StoreError> {
        validate::check_params(self.params())?;
        validate::check_materials(self.materials(), self.records(Section::Strings))?;
        validate::check_tree_count(self.trees())?;
        let mut counts = Vec::with_capacity(self.trees());
        for i in 0..self.trees() {
            let t = self.tree_checked(i)?;
            counts.push(TreeCounts {
                nodes: t.nodes.len() as u64,
                leaves: t.leaves.len() as u64,
            });
        }
        validate::check_block_meta(self.blocks(), &counts)?;
        for i in 0..self.trees() {
            let t = self.tree_checked(i)?;
            let tables = TreeTables {
                tree: i as u32,
                view: t,
                geometry_vouched: !self.holds_geometry,
            };
            validate::check_tree(
                &tables,
                self.materials(),
                self.blocks(),
                self.params().atlas_size,
            )?;
        }
        Ok(())
    }

    /// The tree's view, or the error naming the first range outside its section.
    fn tree_checked(&self, i: usize) -> Result<TreeView<'_>, StoreError> {
        let trees: &[TreeRecord] = self.records(Section::Trees);
        let limit = trees.len() as u64;
        let record = trees.get(i).ok_or(StoreError::BadReference {
            table: "trees",
            index: i as u64,
            field: "id",
            value: i as u64,
            limit,
        })?;
        let kind = record.tree_kind().ok_or(StoreError::BadValue {
            table: "trees",
            index: i as u64,
            field: "kind",
            value: record.kind.into(),
        })?;
        fn pick<'a, T: Pod>(
            file: &'a TreeFile,
            i: usize,
            s: Section,
            r: &Range64,
        ) -> Result<&'a [T], StoreError> {
            let all: &[T] = file.records(s);
            let bad = |limit: u64| StoreError::BadReference {
                table: "trees",
                index: i as u64,
                field: s.name(),
                value: r.first.saturating_add(r.count),
                limit,
            };
            if s.is_geometry() && !file.holds_geometry {
                // Not read: the range is checked against the section's record count alone.
                let count = file.header.section(s).count;
                let end = r.first.checked_add(r.count).filter(|&end| end <= count);
                return end.map(|_| &[][..]).ok_or_else(|| bad(count));
            }
            range(all, r).ok_or_else(|| bad(all.len() as u64))
        }
        Ok(TreeView {
            kind,
            record,
            nodes: pick(self, i, Section::Nodes, &record.nodes)?,
            leaves: pick(self, i, Section::Leaves, &record.leaves)?,
            rects: pick(self, i, Section::Rects, &record.rects)?,
            originals: pick(self, i, Section::Originals, &record.originals)?,
            vertices: pick(self, i, Section::Vertices, &record.vertices)?,
            indices: pick(self, i, Section::Indices, &record.indices)?,
            source_triangles: pick(self, i, Section::SourceTriangles, &record.source_triangles)?,
        })
    }

    fn bytes(&self) -> &[u8] {
        self.backing.bytes()
    }

    /// The records of `section` in place (validated at open: aligned, in bounds, whole records).
    fn records<T: Pod>(&self, section: Section) -> &[T] {
        let e = self.header.section(section);
        let bytes = slice_at(self.bytes(), e.offset, e.length).unwrap_or(&[]);
        bytemuck::try_cast_slice(bytes).unwrap_or(&[])
    }

    /// The path the file was opened from (`<memory>` for [`TreeFile::from_bytes`], the name given to
    /// [`TreeFile::from_prefix`], e.g. a URL).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// False for a file opened from its tables only ([`TreeFile::from_prefix`]).
    pub fn holds_blocks(&self) -> bool {
        self.holds_blocks
    }

    /// True if the file is memory-mapped (false: read into memory whole, or its tables only:
    /// [`LoadMode::Tables`]).
    pub fn is_mapped(&self) -> bool {
        matches!(self.backing, Backing::Mmap { .. })
    }

    /// The validated header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// File length, bytes.
    pub fn file_len(&self) -> u64 {
        self.header.file_len
    }

    /// The build parameters record.
    pub fn params(&self) -> &ParamsRecord {
        static DEFAULT: ParamsRecord = ParamsRecord {
            d_min: 0.0,
            fov_deg: 0.0,
            texel_ratio: 0.0,
            screen_width: 0,
            atlas_size: 0,
            border: 0,
            max_depth: 0,
            up: 0,
            _pad: 0,
        };
        self.records::<ParamsRecord>(Section::Params)
            .first()
            .unwrap_or(&DEFAULT)
    }

    /// The build parameters (validated at open).
    pub fn to_params(&self) -> BuildParams {
        let p = self.params();
        p.decode().unwrap_or(BuildParams {
            d_min: p.d_min,
            screen_width: p.screen_width,
            fov_deg: p.fov_deg,
            texel_ratio: p.texel_ratio,
            atlas_size: p.atlas_size,
            border: p.border,
            max_depth: 0,
            up: Default::default(),
        })
    }

    /// The material records.
    pub fn materials(&self) -> &[MaterialRecord] {
        self.records(Section::Materials)
    }

    /// The name of material `i` (validated UTF-8); `None` if there is no material `i`.
    pub fn material_name(&self, i: usize) -> Option<&str> {
        let m = self.materials().get(i)?;
        let strings: &[u8] = self.records(Section::Strings);
        let name = slice_at(strings, m.name_offset.into(), m.name_len.into())?;
        std::str::from_utf8(name).ok()
    }

    /// Number of trees (1 or 2).
    pub fn trees(&self) -> usize {
        self.records::<TreeRecord>(Section::Trees).len()
    }

    /// Tree `i`; `None` if there is no tree `i`.
    pub fn tree(&self, i: usize) -> Option<TreeView<'_>> {
        self.tree_checked(i).ok()
    }

    /// The block table.
    pub fn blocks(&self) -> &[BlockRecord] {
        self.records(Section::Blocks)
    }

    /// The bytes of block `id`, after checking them against the block's checksum and the padding after it
    /// (up to the next [`BLOCK_ALIGN`] boundary) for zero (the paging read; at most 4095 bytes more, in
    /// the page holding the block's tail). A mapped file's block, or one of a file whose tables only are
    /// held ([`LoadMode::Tables`]), is a copy read through the file's own handle (a file truncated under a
    /// reader is an error, not SIGBUS); a file held in memory whole lends it.
    /// Fails with [`StoreError::BlocksNotHeld`] on a table prefix ([`TreeFile::from_prefix`]).
    pub fn block(&self, id: BlockId) -> Result<Cow<'_, [u8]>, StoreError> {
        let blocks = self.blocks();
        let b = blocks.get(id.idx()).ok_or(StoreError::BadReference {
            table: "blocks",
            index: id.0.into(),
            field: "id",
            value: id.0.into(),
            limit: blocks.len() as u64,
        })?;
        if !self.holds_blocks {
            return Err(StoreError::BlocksNotHeld {
                path: self.path.clone(),
                block: id,
            });
        }
        let out_of_bounds = StoreError::BlockOutOfBounds {
            block: id,
            offset: b.offset,
            len: b.length,
            file_len: self.file_len(),
        };
        let end = b.offset.saturating_add(b.length);
        let (from, to) = padding_range(b, self.file_len());
        let at = format!("block {} (bytes {}..{end})", id.0, b.offset);
        let place = format!("{}: {at}", self.path.display());
        // A mapped file's blocks (and their padding) are read through its handle, not the map: a file
        // truncated while it is read gives an error naming the block where a read through the map would
        // end the process with SIGBUS (fault hunt, session 28: `export` and `inspect --verify`). The tables
        // stay mapped (the contract on `TreeFile`).
        let (bytes, padding) = match self.backing.positional() {
            Some(file) => {
                if end > self.file_len() || to < from {
                    return Err(out_of_bounds);
                }
                let total = usize::try_from(to - b.offset).map_err(|_| out_of_bounds)?;
                let mut buf = vec![0u8; total];
                super::positional::read_exact_at(file, &mut buf, b.offset).map_err(|e| {
                    let why = if e.kind() == std::io::ErrorKind::UnexpectedEof {
                        "the file ends before it (truncated or rewritten while it was read?)"
                            .to_string()
                    } else {
                        e.to_string()
                    };
                    StoreError::io(
                        &self.path,
                        std::io::Error::new(e.kind(), format!("{at}: {why}")),
                    )
                })?;
                let padding = buf.split_off(b.length as usize);
                (Cow::Owned(buf), Cow::Owned(padding))
            }
            None => {
                let bytes = slice_at(self.bytes(), b.offset, b.length).ok_or(out_of_bounds)?;
                let padding = slice_at(self.bytes(), from, to - from).unwrap_or(&[]);
                (Cow::Borrowed(bytes), Cow::Borrowed(padding))
            }
        };
        checksum(place, b.checksum, &bytes)?;
        check_block_padding(id, b, self.file_len(), &padding)?;
        Ok(bytes)
    }

    /// Verifies every block's checksum (in parallel); fails naming a bad block.
    pub fn verify_blocks(&self) -> Result<(), StoreError> {
        (0..self.blocks().len())
            .into_par_iter()
            .try_for_each(|i| self.block(BlockId(i as u32)).map(|_| ()))
    }

    /// Decodes the whole file back into an [`AtlasForest`] (tables only; blocks stay in the file).
    pub fn to_forest(&self) -> AtlasForest {
        self.decode_forest(|t| t.to_tree())
    }

    /// [`TreeFile::to_forest`] without the trees' geometry ([`TreeView::to_skeleton`]).
    pub fn to_skeleton(&self) -> AtlasForest {
        self.decode_forest(|t| t.to_skeleton())
    }

    fn decode_forest(&self, tree: fn(&TreeView<'_>) -> Option<AtlasTree>) -> AtlasForest {
        let materials: Vec<Material> = (self.materials().iter().enumerate())
            .filter_map(|(i, m)| m.decode(self.material_name(i).unwrap_or("")))
            .collect();
        AtlasForest {
            params: self.to_params(),
            materials,
            trees: (0..self.trees())
                .filter_map(|i| tree(&self.tree(i)?))
                .collect(),
            blocks: self
                .blocks()
                .iter()
                .filter_map(BlockRecord::decode)
                .collect(),
        }
    }
}
