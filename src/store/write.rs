//! Writing a paging file: the whole layout is fixed up front from the forest (block sizes are known before any
//! pixel exists), blocks arrive from many threads in any order, and the file appears at its path atomically.

use super::format::{
    BLOCK_ALIGN, BlockRecord, FORMAT_VERSION, HEADER_SIZE, Header, KNOWN_FLAGS, LeafRecord, MAGIC,
    MaterialRecord, NodeRecord, OriginalRecord, ParamsRecord, Range64, RectRecord, SECTION_ALIGN,
    SECTION_COUNT, Section, SectionEntry, TreeRecord, align_up,
};
use super::means::{RectMeans, TreeRects};
use super::validate::{self, TreeCounts, TreeTables};
use super::{StoreError, check_endian};
use crate::ids::BlockId;
use crate::model::{AtlasForest, AtlasTree};
use crate::util::AtomicFile;
use bytemuck::Zeroable;
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicU8, AtomicU64, Ordering};

/// Bytes of a written file, by part.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct WriteSummary {
    /// The header, bytes.
    pub header_bytes: u64,
    /// Each section's length, bytes, indexed by `Section as usize`.
    pub section_bytes: [u64; SECTION_COUNT],
    /// End of the last section (header + tables + alignment gaps), bytes.
    pub tables_end: u64,
    /// Number of blocks.
    pub blocks: u64,
    /// Sum of all blocks' lengths, bytes.
    pub block_bytes: u64,
    /// Alignment gaps (between sections and before/between blocks), bytes.
    pub padding_bytes: u64,
    /// The file length, bytes.
    pub total: u64,
}

impl WriteSummary {
    /// Length of `section`, bytes.
    pub fn bytes(&self, section: Section) -> u64 {
        self.section_bytes[section as usize]
    }
}

const UNWRITTEN: u8 = 0;
const WRITING: u8 = 1;
const WRITTEN: u8 = 2;

/// A paging file being written. Create it from the forest, hand `&FileWriter` to the rasteriser threads
/// ([`FileWriter::write_block`] is `&self` and thread-safe), then [`FileWriter::finish`].
///
/// Until `finish` succeeds the data lives in a temp file next to the target; dropping the writer deletes it
/// and leaves any existing file at the target untouched.
pub struct FileWriter {
    target: PathBuf,
    /// The temp file beside the target ([`AtomicFile`]: unique per writer, removed on drop).
    temp: AtomicFile,
    header: Header,
    /// Block table with checksums still 0.
    blocks: Vec<BlockRecord>,
    state: Vec<AtomicU8>,
    checksums: Vec<AtomicU64>,
    /// Compression error of each block ([`BlockRecord::sse`]).
    errors: Vec<AtomicU64>,
    summary: WriteSummary,
    /// Serialises seek + write where positional writes are not available (non-unix).
    lock: Mutex<()>,
    /// The rects' means, measured as leaf atlas blocks arrive; the rect table is written again at
    /// [`FileWriter::finish`].
    means: RectMeans,
}

/// The encoded tables of one tree (its big arrays stay borrowed from the forest).
struct EncodedTree {
    record: TreeRecord,
    nodes: Vec<NodeRecord>,
    leaves: Vec<LeafRecord>,
    rects: Vec<RectRecord>,
    originals: Vec<OriginalRecord>,
}

/// Everything the tables hold, encoded.
struct Encoded {
    params: ParamsRecord,
    materials: Vec<MaterialRecord>,
    strings: Vec<u8>,
    trees: Vec<EncodedTree>,
}

fn overflow(what: &'static str) -> StoreError {
    StoreError::LayoutOverflow { what }
}

fn to_u32(value: usize, what: &'static str) -> Result<u32, StoreError> {
    u32::try_from(value).map_err(|_| overflow(what))
}

fn encode_materials(forest: &AtlasForest) -> Result<(Vec<MaterialRecord>, Vec<u8>), StoreError> {
    let mut strings = Vec::new();
    let mut records = Vec::with_capacity(forest.materials.len());
    for m in &forest.materials {
        let offset = to_u32(strings.len(), "material names")?;
        let len = to_u32(m.name.len(), "material name")?;
        strings.extend_from_slice(m.name.as_bytes());
        records.push(MaterialRecord::encode(m, offset, len));
    }
    to_u32(strings.len(), "material names")?;
    Ok((records, strings))
}

/// Running position of each section while trees are appended.
#[derive(Default)]
struct Bases {
    nodes: u64,
    leaves: u64,
    rects: u64,
    originals: u64,
    vertices: u64,
    indices: u64,
    source_triangles: u64,
}

fn take(base: &mut u64, count: usize) -> Result<Range64, StoreError> {
    let r = Range64 {
        first: *base,
        count: count as u64,
    };
    *base = r.end().ok_or(overflow("tree ranges"))?;
    Ok(r)
}

fn encode_tree(tree: &AtlasTree, bases: &mut Bases) -> Result<EncodedTree, StoreError> {
    let nodes: Vec<NodeRecord> = tree.nodes.iter().map(NodeRecord::encode).collect();
    let mut leaves = Vec::with_capacity(tree.leaves.len());
    let mut rects = Vec::new();
    let mut originals = Vec::new();
    for leaf in &tree.leaves {
        let first_rect = to_u32(rects.len(), "rects")?;
        let first_original = to_u32(originals.len(), "originals")?;
        rects.extend(leaf.rects.iter().map(RectRecord::encode));
        originals.extend(leaf.originals.iter().map(OriginalRecord::encode));
        let record =
            LeafRecord::encode(leaf, first_rect, first_original).ok_or(overflow("leaf ranges"))?;
        leaves.push(record);
    }
    to_u32(rects.len(), "rects")?;
    to_u32(originals.len(), "originals")?;
    let record = TreeRecord {
        kind: TreeRecord::encode_kind(tree.kind),
        format: tree.format.code(),
        nodes: take(&mut bases.nodes, nodes.len())?,
        leaves: take(&mut bases.leaves, leaves.len())?,
        rects: take(&mut bases.rects, rects.len())?,
        originals: take(&mut bases.originals, originals.len())?,
        vertices: take(&mut bases.vertices, tree.vertices.len())?,
        indices: take(&mut bases.indices, tree.indices.len())?,
        source_triangles: take(&mut bases.source_triangles, tree.source_triangles.len())?,
    };
    Ok(EncodedTree {
        record,
        nodes,
        leaves,
        rects,
        originals,
    })
}

fn encode(forest: &AtlasForest) -> Result<Encoded, StoreError> {
    let (materials, strings) = encode_materials(forest)?;
    let mut bases = Bases::default();
    let trees = forest
        .trees
        .iter()
        .map(|t| encode_tree(t, &mut bases))
        .collect::<Result<Vec<_>, _>>()?;
    to_u32(forest.trees.len(), "trees")?;
    to_u32(forest.blocks.len(), "blocks")?;
    Ok(Encoded {
        params: ParamsRecord::encode(&forest.params),
        materials,
        strings,
        trees,
    })
}

/// Record counts of every section, in [`Section::ALL`] order.
fn section_counts(e: &Encoded, blocks: usize) -> [u64; SECTION_COUNT] {
    let sum = |f: &dyn Fn(&TreeRecord) -> u64| e.trees.iter().map(|t| f(&t.record)).sum::<u64>();
    [
        1,
        e.materials.len() as u64,
        e.strings.len() as u64,
        e.trees.len() as u64,
        sum(&|r| r.nodes.count),
        sum(&|r| r.leaves.count),
        sum(&|r| r.rects.count),
        sum(&|r| r.originals.count),
        sum(&|r| r.vertices.count),
        sum(&|r| r.indices.count),
        sum(&|r| r.source_triangles.count),
        blocks as u64,
    ]
}

/// The length of the paging file [`FileWriter::create`] writes for `forest` (header, every table and every
/// block with their alignment gaps), from the record counts alone: what `--max-file-gib` limits, so a
/// geometry-heavy file is not judged by its blocks alone (a 600,000-triangle scene wrote 3.9× its limit;
/// fault hunt, session 32).
pub fn predicted_file_len(forest: &AtlasForest) -> Result<u64, StoreError> {
    let strings: u64 = forest.materials.iter().map(|m| m.name.len() as u64).sum();
    let per_tree = |f: &dyn Fn(&AtlasTree) -> usize| forest.trees.iter().map(|t| f(t) as u64).sum();
    let counts = [
        1,
        forest.materials.len() as u64,
        strings,
        forest.trees.len() as u64,
        per_tree(&|t| t.nodes.len()),
        per_tree(&|t| t.leaves.len()),
        per_tree(&|t| t.leaves.iter().map(|l| l.rects.len()).sum()),
        per_tree(&|t| t.leaves.iter().map(|l| l.originals.len()).sum()),
        per_tree(&|t| t.vertices.len()),
        per_tree(&|t| t.indices.len()),
        per_tree(&|t| t.source_triangles.len()),
        forest.blocks.len() as u64,
    ];
    Ok(layout(&counts, forest.blocks.iter().map(|b| b.bytes))?.3)
}

/// Places the sections after the header (16-byte aligned) and the blocks after the tables (4 KiB aligned,
/// in block-id order). Returns the section entries (checksums 0), the tables' end and the block offsets.
fn layout(
    counts: &[u64; SECTION_COUNT],
    block_lengths: impl Iterator<Item = u64>,
) -> Result<([SectionEntry; SECTION_COUNT], u64, Vec<u64>, u64), StoreError> {
    let mut sections = [SectionEntry::zeroed(); SECTION_COUNT];
    let mut end = HEADER_SIZE as u64;
    for (i, s) in Section::ALL.iter().enumerate() {
        let record_size = s.record_size();
        let offset = align_up(end, SECTION_ALIGN).ok_or(overflow(s.name()))?;
        let length = counts[i]
            .checked_mul(u64::from(record_size))
            .ok_or(overflow(s.name()))?;
        end = offset.checked_add(length).ok_or(overflow(s.name()))?;
        sections[i] = SectionEntry {
            offset,
            length,
            count: counts[i],
            checksum: 0,
            record_size,
            kind: *s as u32,
        };
    }
    let tables_end = end;
    let mut offsets = Vec::new();
    for len in block_lengths {
        let offset = align_up(end, BLOCK_ALIGN).ok_or(overflow("blocks"))?;
        end = offset.checked_add(len).ok_or(overflow("blocks"))?;
        offsets.push(offset);
    }
    Ok((sections, tables_end, offsets, end))
}

fn validate_encoded(
    forest: &AtlasForest,
    e: &Encoded,
    blocks: &[BlockRecord],
) -> Result<(), StoreError> {
    validate::check_params(&e.params)?;
    validate::check_materials(&e.materials, &e.strings)?;
    validate::check_tree_count(e.trees.len())?;
    let counts: Vec<TreeCounts> = e
        .trees
        .iter()
        .map(|t| TreeCounts {
            nodes: t.nodes.len() as u64,
            leaves: t.leaves.len() as u64,
        })
        .collect();
    validate::check_block_meta(blocks, &counts)?;
    for (i, (t, src)) in e.trees.iter().zip(&forest.trees).enumerate() {
        let tables = TreeTables {
            tree: i as u32,
            view: super::TreeView {
                kind: src.kind,
                record: &t.record,
                nodes: &t.nodes,
                leaves: &t.leaves,
                rects: &t.rects,
                originals: &t.originals,
                vertices: &src.vertices,
                indices: &src.indices,
                source_triangles: &src.source_triangles,
            },
            geometry_vouched: false,
        };
        validate::check_tree(&tables, &e.materials, blocks, e.params.atlas_size)?;
    }
    Ok(())
}

/// Writes `bytes` at `offset`: positional on unix (concurrent writers need no lock), seek + write under
/// `lock` elsewhere.
fn write_all_at(file: &File, lock: &Mutex<()>, offset: u64, bytes: &[u8]) -> std::io::Result<()> {
    // Positional writes need no lock; the seek + write fallback does.
    let _guard =
        (!cfg!(unix)).then(|| lock.lock().unwrap_or_else(|poisoned| poisoned.into_inner()));
    super::positional::write_all_at(file, bytes, offset)
}

/// Writes `parts` back to back at `section`'s offset through `put` and records their checksum in `header`.
fn put_section(
    header: &mut Header,
    section: Section,
    parts: &[&[u8]],
    put: &mut dyn FnMut(u64, &[u8]),
) {
    let mut offset = header.section(section).offset;
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    for part in parts {
        put(offset, part);
        hasher.update(part);
        offset += part.len() as u64;
    }
    header.sections[section as usize].checksum = hasher.digest();
}

/// Every table but the block table, through `put` (offset, bytes), their checksums into `header`: the one
/// writer of the tables, behind both [`FileWriter::create`] and [`table_prefix`].
fn put_tables(
    header: &mut Header,
    forest: &AtlasForest,
    e: &Encoded,
    put: &mut dyn FnMut(u64, &[u8]),
) {
    use bytemuck::{bytes_of, cast_slice};
    let trees: Vec<TreeRecord> = e.trees.iter().map(|t| t.record).collect();
    put_section(header, Section::Params, &[bytes_of(&e.params)], put);
    put_section(header, Section::Materials, &[cast_slice(&e.materials)], put);
    put_section(header, Section::Strings, &[&e.strings], put);
    put_section(header, Section::Trees, &[cast_slice(&trees)], put);
    let per_tree = |f: &dyn for<'a> Fn(&'a EncodedTree) -> &'a [u8]| -> Vec<&[u8]> {
        e.trees.iter().map(f).collect()
    };
    put_section(
        header,
        Section::Nodes,
        &per_tree(&|t| cast_slice(&t.nodes)),
        put,
    );
    put_section(
        header,
        Section::Leaves,
        &per_tree(&|t| cast_slice(&t.leaves)),
        put,
    );
    put_section(
        header,
        Section::Rects,
        &per_tree(&|t| cast_slice(&t.rects)),
        put,
    );
    put_section(
        header,
        Section::Originals,
        &per_tree(&|t| cast_slice(&t.originals)),
        put,
    );
    let of_trees = |f: &dyn for<'a> Fn(&'a AtlasTree) -> &'a [u8]| -> Vec<&[u8]> {
        forest.trees.iter().map(f).collect()
    };
    put_section(
        header,
        Section::Vertices,
        &of_trees(&|t| cast_slice(&t.vertices)),
        put,
    );
    put_section(
        header,
        Section::Indices,
        &of_trees(&|t| cast_slice(&t.indices)),
        put,
    );
    put_section(
        header,
        Section::SourceTriangles,
        &of_trees(&|t| cast_slice(&t.source_triangles)),
        put,
    );
}

/// The layout of a forest's file: header (checksums still 0), block records (checksums 0), tables' end.
struct FileLayout {
    header: Header,
    blocks: Vec<BlockRecord>,
    tables_end: u64,
    encoded: Encoded,
}

/// Encodes and lays out `forest`, checking its tables as the reader would.
fn plan_file(forest: &AtlasForest) -> Result<FileLayout, StoreError> {
    check_endian()?;
    let encoded = encode(forest)?;
    let counts = section_counts(&encoded, forest.blocks.len());
    let (sections, tables_end, offsets, file_len) =
        layout(&counts, forest.blocks.iter().map(|b| b.bytes))?;
    let blocks: Vec<BlockRecord> = forest
        .blocks
        .iter()
        .zip(&offsets)
        .map(|(d, &o)| BlockRecord::encode(d, o))
        .collect();
    validate_encoded(forest, &encoded, &blocks)?;
    Ok(FileLayout {
        header: Header {
            magic: MAGIC,
            version: FORMAT_VERSION,
            flags: KNOWN_FLAGS,
            file_len,
            header_size: HEADER_SIZE as u32,
            section_count: SECTION_COUNT as u32,
            block_align: BLOCK_ALIGN as u32,
            section_align: SECTION_ALIGN as u32,
            sections,
            checksum: 0,
        },
        blocks,
        tables_end,
        encoded,
    })
}

/// The first bytes of `forest`'s paging file as a table prefix (issue 22: what a sharded build hands to
/// its merge): header and every table up to the first block's offset (at most the file length), with the
/// block table's checksums 0 and the header checksum set, so [`crate::store::TreeFile::from_prefix`] opens
/// it and [`FileWriter::from_prefix_file`] turns it into the same file [`FileWriter::create`] writes.
pub fn table_prefix(forest: &AtlasForest) -> Result<Vec<u8>, StoreError> {
    let FileLayout {
        mut header,
        blocks,
        tables_end,
        encoded,
    } = plan_file(forest)?;
    let len = align_up(tables_end, BLOCK_ALIGN)
        .ok_or(overflow("tables"))?
        .min(header.file_len);
    let mut bytes = vec![0u8; usize::try_from(len).map_err(|_| overflow("tables"))?];
    let mut put = |offset: u64, part: &[u8]| {
        let at = offset as usize;
        bytes[at..at + part.len()].copy_from_slice(part);
    };
    put_tables(&mut header, forest, &encoded, &mut put);
    put_section(
        &mut header,
        Section::Blocks,
        &[bytemuck::cast_slice(&blocks)],
        &mut put,
    );
    header.checksum = header.compute_checksum();
    bytes[..HEADER_SIZE].copy_from_slice(bytemuck::bytes_of(&header));
    Ok(bytes)
}

impl FileWriter {
    /// Lays out the file for `forest`, creates a temp file next to `path`, sizes it and writes every table
    /// but the block table (whose checksums come with the blocks); the rect table's means are zero until
    /// [`FileWriter::finish`] writes it again with those measured on the leaf atlases.
    ///
    /// Fails before touching the disk if the forest's tables are inconsistent (the same checks the reader
    /// applies), so a file that `finish`es always opens.
    pub fn create(path: &Path, forest: &AtlasForest) -> Result<FileWriter, StoreError> {
        let FileLayout {
            header,
            blocks,
            tables_end,
            encoded,
        } = plan_file(forest)?;
        // `--max-file-gib` judged the file by its twin, from the counts alone.
        debug_assert_eq!(predicted_file_len(forest).ok(), Some(header.file_len));
        let trees: Vec<TreeRects<'_>> = (encoded.trees.iter())
            .map(|t| TreeRects {
                format: t.record.tex_format().unwrap_or_default(),
                exact: t.record.tree_kind() == Some(crate::model::TreeKind::Alpha),
                nodes: &t.nodes,
                leaves: &t.leaves,
                rects: &t.rects,
            })
            .collect();
        let means = RectMeans::new(encoded.params.atlas_size, blocks.len(), &trees)
            .ok_or(StoreError::LayoutOverflow { what: "rect means" })?;
        let mut writer = FileWriter::with_layout(path, header, blocks, tables_end, means)?;
        writer.write_tables(forest, &encoded)?;
        Ok(writer)
    }

    /// A writer for the file whose [`table_prefix`] is the `len` bytes at `src_offset` of `src`, opened (and
    /// so validated) as `tables`: the prefix is copied verbatim, so the finished file is the one
    /// [`FileWriter::create`] writes for the same forest. It is copied in pieces, never held whole, and
    /// checked on the way: its `xxh3_128` must be `hash` (a plan file's) and
    /// its header the one `tables` were opened from, else [`StoreError::PrefixMismatch`] and nothing is
    /// published. `tables` may be a skeleton ([`super::TreeFile::skeleton_prefix`]).
    pub fn from_prefix_file(
        path: &Path,
        tables: &super::TreeFile,
        src: &File,
        src_offset: u64,
        len: u64,
        hash: [u64; 2],
    ) -> Result<FileWriter, StoreError> {
        let expected_header = bytemuck::bytes_of(tables.header());
        let writer = FileWriter::for_tables(path, tables)?;
        let mismatch = || StoreError::PrefixMismatch {
            path: tables.path().to_path_buf(),
        };
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        let read_err = |e| StoreError::io(tables.path(), e);
        super::read::for_each_piece(src, src_offset, len, read_err, |at, piece| {
            if at == 0 && piece.get(..HEADER_SIZE) != Some(expected_header) {
                return Err(mismatch());
            }
            hasher.update(piece);
            write_all_at(writer.temp.file(), &writer.lock, at, piece)
                .map_err(|e| writer.temp_err(e))
        })?;
        if crate::util::digest_words(hasher.digest128()) != hash {
            return Err(mismatch());
        }
        Ok(writer)
    }

    /// The writer of the file `tables` were opened from (header and block table as they will be
    /// finished), nothing written yet: the caller writes the table prefix.
    fn for_tables(path: &Path, tables: &super::TreeFile) -> Result<FileWriter, StoreError> {
        let mut header = *tables.header();
        header.checksum = 0;
        let blocks: Vec<BlockRecord> = (tables.blocks().iter())
            .map(|b| BlockRecord {
                checksum: 0,
                sse: 0,
                ..*b
            })
            .collect();
        let tables_end = super::read::sections_end(&header).ok_or(overflow("sections"))?;
        let views: Option<Vec<super::TreeView<'_>>> =
            (0..tables.trees()).map(|t| tables.tree(t)).collect();
        let views = views.ok_or(StoreError::LayoutOverflow { what: "trees" })?;
        let trees: Vec<TreeRects<'_>> = (views.iter())
            .map(|t| TreeRects {
                format: t.format(),
                exact: t.kind == crate::model::TreeKind::Alpha,
                nodes: t.nodes,
                leaves: t.leaves,
                rects: t.rects,
            })
            .collect();
        let means = RectMeans::new(tables.params().atlas_size, blocks.len(), &trees)
            .ok_or(StoreError::LayoutOverflow { what: "rect means" })?;
        FileWriter::with_layout(path, header, blocks, tables_end, means)
    }

    /// The temp file sized for `header.file_len`, nothing written yet.
    fn with_layout(
        path: &Path,
        header: Header,
        blocks: Vec<BlockRecord>,
        tables_end: u64,
        means: RectMeans,
    ) -> Result<FileWriter, StoreError> {
        super::check_replaceable(path)?;
        // The permissions of a plain `File::create` once renamed (0o666 less the umask); a private 0o600
        // would make a paging file unservable by another user's server.
        let temp = super::create_output(path)?;
        let file_len = header.file_len;
        let writer = FileWriter {
            target: path.to_path_buf(),
            summary: summarize(&header.sections, tables_end, &blocks, file_len),
            header,
            state: blocks.iter().map(|_| AtomicU8::new(UNWRITTEN)).collect(),
            checksums: blocks.iter().map(|_| AtomicU64::new(0)).collect(),
            errors: blocks.iter().map(|_| AtomicU64::new(0)).collect(),
            blocks,
            temp,
            lock: Mutex::new(()),
            means,
        };
        let temp = &writer.temp;
        super::positional::size_and_reserve(
            temp.file(),
            file_len,
            &writer.target,
            temp.temp_path(),
        )?;
        Ok(writer)
    }

    /// An I/O error while writing, naming the target (what the user asked for) and the temp file.
    fn temp_err(&self, source: std::io::Error) -> StoreError {
        StoreError::Write {
            target: self.target.clone(),
            temp: self.temp.temp_path().to_path_buf(),
            source,
        }
    }

    fn write_tables(&mut self, forest: &AtlasForest, e: &Encoded) -> Result<(), StoreError> {
        let (file, lock) = (self.temp.file(), &self.lock);
        let mut failure = None;
        let mut put = |offset: u64, bytes: &[u8]| {
            let r = write_all_at(file, lock, offset, bytes);
            if let Err(err) = r {
                failure.get_or_insert(err);
            }
        };
        put_tables(&mut self.header, forest, e, &mut put);
        match failure {
            Some(err) => Err(self.temp_err(err)),
            None => Ok(()),
        }
    }

    /// The path the file will appear at.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Writes block `id`: exactly `forest.blocks[id].bytes` bytes, once. Thread-safe; blocks may arrive in
    /// any order. On an I/O error the block stays unwritten and may be retried.
    pub fn write_block(&self, id: BlockId, bytes: &[u8]) -> Result<(), StoreError> {
        self.write_block_measured(id, bytes, 0)
    }

    /// [`FileWriter::write_block`] recording the block's compression error `sse` ([`BlockRecord::sse`]).
    pub fn write_block_measured(
        &self,
        id: BlockId,
        bytes: &[u8],
        sse: u64,
    ) -> Result<(), StoreError> {
        let limit = self.blocks.len() as u64;
        let bad_id = || StoreError::BadReference {
            table: "blocks",
            index: u64::from(id.0),
            field: "id",
            value: u64::from(id.0),
            limit,
        };
        let record = self.blocks.get(id.idx()).ok_or_else(bad_id)?;
        let (state, checksum) = self
            .state
            .get(id.idx())
            .zip(self.checksums.get(id.idx()))
            .ok_or_else(bad_id)?;
        if bytes.len() as u64 != record.length {
            let got = bytes.len() as u64;
            return Err(StoreError::BlockLength {
                block: id,
                expected: record.length,
                got,
            });
        }
        if state
            .compare_exchange(UNWRITTEN, WRITING, Ordering::AcqRel, Ordering::Acquire)
            .is_err()
        {
            return Err(StoreError::BlockWrittenTwice { block: id });
        }
        self.means.record(id, bytes);
        let sum = xxhash_rust::xxh3::xxh3_64(bytes);
        if let Err(e) = write_all_at(self.temp.file(), &self.lock, record.offset, bytes) {
            state.store(UNWRITTEN, Ordering::Release);
            return Err(self.temp_err(e));
        }
        checksum.store(sum, Ordering::Relaxed);
        if let Some(e) = self.errors.get(id.idx()) {
            e.store(sse, Ordering::Relaxed);
        }
        state.store(WRITTEN, Ordering::Release);
        Ok(())
    }

    /// Writes the rect table again with its means (`store::means`), the block table (with the blocks'
    /// checksums) and the header, fsyncs, and renames the temp file onto the target (replacing any file
    /// there). Fails naming the first block never written; then
    /// nothing appears at the target.
    pub fn finish(mut self) -> Result<WriteSummary, StoreError> {
        for (i, state) in self.state.iter().enumerate() {
            if state.load(Ordering::Acquire) != WRITTEN {
                return Err(StoreError::BlockMissing {
                    block: BlockId(i as u32),
                });
            }
        }
        let mut blocks = std::mem::take(&mut self.blocks);
        for ((b, sum), sse) in blocks.iter_mut().zip(&self.checksums).zip(&self.errors) {
            b.checksum = sum.load(Ordering::Relaxed);
            b.sse = sse.load(Ordering::Relaxed);
        }
        let (file, lock) = (self.temp.file(), &self.lock);
        let mut failure = None;
        let mut put = |offset: u64, bytes: &[u8]| {
            if let Err(e) = write_all_at(file, lock, offset, bytes) {
                failure.get_or_insert(e);
            }
        };
        let rects = self.means.finished();
        let rect_bytes: Vec<&[u8]> = rects.iter().map(|r| bytemuck::cast_slice(r)).collect();
        put_section(&mut self.header, Section::Rects, &rect_bytes, &mut put);
        put_section(
            &mut self.header,
            Section::Blocks,
            &[bytemuck::cast_slice(&blocks)],
            &mut put,
        );
        if let Some(e) = failure {
            return Err(self.temp_err(e));
        }
        self.header.checksum = self.header.compute_checksum();
        let header = self.header;
        write_all_at(self.temp.file(), &self.lock, 0, bytemuck::bytes_of(&header))
            .map_err(|e| self.temp_err(e))?;
        let FileWriter {
            target,
            temp,
            summary,
            ..
        } = self;
        let temp_path = temp.temp_path().to_path_buf();
        temp.commit().map_err(|source| StoreError::Write {
            target,
            temp: temp_path,
            source,
        })?;
        Ok(summary)
    }
}

fn summarize(
    sections: &[SectionEntry; SECTION_COUNT],
    tables_end: u64,
    blocks: &[BlockRecord],
    file_len: u64,
) -> WriteSummary {
    let section_bytes = sections.map(|s| s.length);
    let block_bytes: u64 = blocks.iter().map(|b| b.length).sum();
    let used = HEADER_SIZE as u64 + section_bytes.iter().sum::<u64>() + block_bytes;
    WriteSummary {
        header_bytes: HEADER_SIZE as u64,
        section_bytes,
        tables_end,
        blocks: blocks.len() as u64,
        block_bytes,
        padding_bytes: file_len - used,
        total: file_len,
    }
}

#[cfg(test)]
mod tests;
