//! Paging file: write a synthetic forest from many threads, read it back (mmap, read, in-memory) and compare
//! every table and block; reject truncation and corruption with errors, never panics; atomic publication.
//! The forest generator is `tests/fixtures/store_forest.rs` (shared with the `store` bench, which times
//! a 10k-node file).

use crate::fixtures::store_forest::*;
use atlastree::ids::BlockId;
use atlastree::model::{AtlasForest, TreeKind};
use atlastree::store::format::{HEADER_SIZE, Header, NodeRecord, Section};
use atlastree::store::{FileWriter, LoadMode, StoreError, TreeFile};
use atlastree::texfmt::TexFormat;
use proptest::prelude::*;

fn json<T: serde::Serialize>(v: &T) -> String {
    serde_json::to_string(v).unwrap()
}

/// Every table and every block of `file` equals `forest` / the generated contents.
fn assert_same(file: &TreeFile, forest: &AtlasForest, seed: u64) {
    assert_eq!(file.to_params(), forest.params);
    assert_eq!(
        json(&file.to_forest()),
        json(forest),
        "decoded forest differs"
    );
    assert_eq!(file.trees(), forest.trees.len());
    for (i, t) in forest.trees.iter().enumerate() {
        let v = file.tree(i).unwrap();
        assert_eq!(v.kind, t.kind);
        assert_eq!(v.format(), t.format);
        assert_eq!(v.record.format, t.format.code());
        let nodes: Vec<NodeRecord> = t.nodes.iter().map(NodeRecord::encode).collect();
        assert_eq!(v.nodes, &nodes[..]);
        assert_eq!(v.leaves.len(), t.leaves.len());
        assert_eq!(v.vertices, &t.vertices[..]);
        assert_eq!(v.indices, &t.indices[..]);
        assert_eq!(v.source_triangles, &t.source_triangles[..]);
    }
    assert!(file.tree(forest.trees.len()).is_none());
    for (i, m) in forest.materials.iter().enumerate() {
        assert_eq!(file.material_name(i), Some(m.name.as_str()));
    }
    assert_eq!(file.material_name(forest.materials.len()), None);
    assert_eq!(file.blocks().len(), forest.blocks.len());
    for (i, b) in forest.blocks.iter().enumerate() {
        let got = file.block(BlockId(i as u32)).unwrap();
        assert_eq!(got, &block_bytes(seed, i, b.bytes)[..], "block {i}");
        assert_eq!(file.blocks()[i].sse, block_sse(seed, i), "block {i} error");
        assert_eq!(file.blocks()[i].offset % 4096, 0);
    }
    file.verify_blocks().unwrap();
}

#[test]
fn roundtrip_two_trees_all_load_modes() {
    let seed = 7;
    let forest = synth_forest(seed, &small_specs());
    assert_eq!(forest.trees.len(), 2);
    assert!(forest.blocks.len() > 30, "{} blocks", forest.blocks.len());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("city.atlastree");
    let summary = write_forest(&path, &forest, seed);

    let on_disk = std::fs::metadata(&path).unwrap().len();
    assert_eq!(summary.total, on_disk);
    let nodes: usize = forest.trees.iter().map(|t| t.nodes.len()).sum();
    assert_eq!(summary.bytes(Section::Nodes), nodes as u64 * 104);
    assert_eq!(
        summary.block_bytes,
        forest.blocks.iter().map(|b| b.bytes).sum::<u64>()
    );
    assert_eq!(
        summary.header_bytes
            + summary.section_bytes.iter().sum::<u64>()
            + summary.block_bytes
            + summary.padding_bytes,
        summary.total
    );

    let mapped = TreeFile::open_with(&path, LoadMode::Mmap).unwrap();
    assert!(mapped.is_mapped());
    assert_same(&mapped, &forest, seed);
    let read = TreeFile::open_with(&path, LoadMode::Read).unwrap();
    assert!(!read.is_mapped());
    assert_same(&read, &forest, seed);
    let mem = TreeFile::from_bytes(&std::fs::read(&path).unwrap()).unwrap();
    assert_same(&mem, &forest, seed);
    let auto = TreeFile::open(&path).unwrap();
    assert_same(&auto, &forest, seed);
    // Only the temp-free target remains in the directory.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn empty_blocks_and_single_tree_roundtrip() {
    let spec = TreeSpec {
        kind: TreeKind::Opaque,
        depth: 0,
        full: true,
        verts_per_leaf: 3,
        tris_per_leaf: 1,
        block_bytes: (0, 0),
        max_original_blocks: 3,
        format: TexFormat::Rgba8,
    };
    let forest = synth_forest(3, &[spec]);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("one.atlastree");
    let summary = write_forest(&path, &forest, 3);
    // Empty atlas blocks; the leaf's original-texture block holds its chains (every leaf has one).
    let atlas_bytes: u64 = forest
        .blocks
        .iter()
        .filter(|b| matches!(b.kind, atlastree::model::BlockKind::Atlas { .. }))
        .map(|b| b.bytes)
        .sum();
    assert_eq!(atlas_bytes, 0);
    let all: u64 = forest.blocks.iter().map(|b| b.bytes).sum();
    assert_eq!(summary.block_bytes, all);
    let f = TreeFile::open(&path).unwrap();
    assert_same(&f, &forest, 3);
    assert_eq!(f.tree(0).unwrap().nodes.len(), 1);
}

/// A written small file and its forest.
fn small_file(seed: u64) -> (AtlasForest, Vec<u8>) {
    let forest = synth_forest(seed, &small_specs());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.atlastree");
    write_forest(&path, &forest, seed);
    (forest, std::fs::read(&path).unwrap())
}

pub(crate) fn header_of(bytes: &[u8]) -> Header {
    bytemuck::pod_read_unaligned(&bytes[..HEADER_SIZE])
}

/// First byte of the block area (end of what header and table checksums and zero checks cover).
fn first_block_offset(bytes: &[u8]) -> usize {
    TreeFile::from_bytes(bytes).unwrap().blocks()[0].offset as usize
}

#[test]
fn truncation_at_every_table_length_and_into_blocks_is_an_error() {
    let (_, bytes) = small_file(11);
    let file_len = bytes.len() as u64;
    let tables = first_block_offset(&bytes);
    let mut rng = Rng(5);
    let into_blocks = (0..200).map(|_| tables + rng.below(file_len - tables as u64) as usize);
    for len in (0..=tables).chain(into_blocks) {
        match TreeFile::from_bytes(&bytes[..len]) {
            Err(StoreError::Truncated { len: l, needed, .. }) => {
                assert_eq!(l, len as u64);
                let want = if len < HEADER_SIZE {
                    HEADER_SIZE as u64
                } else {
                    file_len
                };
                assert_eq!(needed, want, "len {len}");
            }
            other => panic!("len {len}: expected Truncated, got {:?}", other.err()),
        }
    }
    // The file paths (mmap and read) report the same.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("t.atlastree");
    for len in [0, 7, 100, HEADER_SIZE + 1, tables, bytes.len() - 1] {
        std::fs::write(&path, &bytes[..len]).unwrap();
        for mode in [LoadMode::Mmap, LoadMode::Read, LoadMode::Auto] {
            let r = TreeFile::open_with(&path, mode);
            assert!(
                matches!(r, Err(StoreError::Truncated { .. })),
                "len {len} {mode:?}: {:?}",
                r.err()
            );
        }
    }
    let mut long = bytes.clone();
    long.push(0);
    assert!(matches!(
        TreeFile::from_bytes(&long),
        Err(StoreError::TrailingBytes { .. })
    ));
}

#[test]
fn every_byte_flip_in_header_and_tables_is_an_error() {
    let (_, mut bytes) = small_file(12);
    let tables = first_block_offset(&bytes);
    for i in 0..tables {
        bytes[i] ^= 0xFF;
        assert!(
            TreeFile::from_bytes(&bytes).is_err(),
            "flip at {i} of {tables} accepted"
        );
        bytes[i] ^= 0xFF;
    }
    TreeFile::from_bytes(&bytes).unwrap();
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    #[test]
    fn random_flip_in_header_or_tables_is_an_error(pos in 0.0f64..1.0, mask in 1u8..=255) {
        let (_, mut bytes) = SMALL.with(|s| s.clone());
        let tables = first_block_offset(&bytes);
        let i = ((pos * tables as f64) as usize).min(tables - 1);
        bytes[i] ^= mask;
        prop_assert!(TreeFile::from_bytes(&bytes).is_err(), "flip {mask:#x} at {i} accepted");
    }
}

thread_local! {
    static SMALL: (AtlasForest, Vec<u8>) = small_file(13);
}

#[test]
fn flipped_block_byte_fails_only_that_block() {
    let (forest, mut bytes) = small_file(14);
    let file = TreeFile::from_bytes(&bytes).unwrap();
    let k = (0..forest.blocks.len())
        .find(|&i| forest.blocks[i].bytes > 100)
        .unwrap();
    let at = file.blocks()[k].offset as usize + 50;
    bytes[at] ^= 0x10;
    let file = TreeFile::from_bytes(&bytes).unwrap();
    for i in 0..forest.blocks.len() {
        let r = file.block(BlockId(i as u32));
        if i == k {
            match r {
                Err(StoreError::ChecksumMismatch {
                    what,
                    expected,
                    found,
                }) => {
                    let b = &file.blocks()[k];
                    let place = format!("block {k} (bytes {}..{})", b.offset, b.offset + b.length);
                    assert!(what.ends_with(&place), "{what}");
                    assert_ne!(expected, found);
                }
                other => panic!("block {k}: {:?}", other.map(|b| b.len())),
            }
        } else {
            r.unwrap();
        }
    }
    assert!(matches!(
        file.verify_blocks(),
        Err(StoreError::ChecksumMismatch { .. })
    ));
    let out = file.block(BlockId(forest.blocks.len() as u32));
    assert!(matches!(
        out,
        Err(StoreError::BadReference {
            table: "blocks",
            ..
        })
    ));
}

/// Recomputes every section checksum and the header checksum after a deliberate edit, so the edit reaches
/// the cross-reference checks.
pub(crate) fn reseal(bytes: &mut [u8]) {
    let mut h = header_of(bytes);
    for s in h.sections.iter_mut() {
        let data = &bytes[s.offset as usize..(s.offset + s.length) as usize];
        s.checksum = xxhash_rust::xxh3::xxh3_64(data);
    }
    h.checksum = h.compute_checksum();
    bytes[..HEADER_SIZE].copy_from_slice(bytemuck::bytes_of(&h));
}

/// Byte offset of record `index` of `section`.
pub(crate) fn record_at(bytes: &[u8], section: Section, index: usize) -> usize {
    let e = *header_of(bytes).section(section);
    e.offset as usize + index * e.record_size as usize
}

#[test]
fn resealed_bad_references_are_named() {
    let (forest, bytes) = small_file(15);
    let n0 = forest.trees[0].nodes.len();
    let v0 = forest.trees[0].vertices.len();
    // Root's child 0 slot (offset 72 in NodeRecord) points past the tree.
    let mut b = bytes.clone();
    let root = record_at(&b, Section::Nodes, 0);
    let q = forest.trees[0].nodes[0]
        .children
        .iter()
        .position(|c| c.is_some())
        .unwrap();
    b[root + 72 + 4 * q..][..4].copy_from_slice(&(n0 as u32 + 5).to_le_bytes());
    reseal(&mut b);
    match TreeFile::from_bytes(&b) {
        Err(StoreError::BadReference {
            table: "nodes",
            index: 0,
            field: "children",
            value,
            limit,
        }) => {
            assert_eq!((value, limit), (n0 as u64 + 5, n0 as u64));
        }
        other => panic!("{:?}", other.err()),
    }
    // An index past the tree's vertices.
    let mut b = bytes.clone();
    let at = record_at(&b, Section::Indices, 4);
    b[at..at + 4].copy_from_slice(&(v0 as u32).to_le_bytes());
    reseal(&mut b);
    match TreeFile::from_bytes(&b) {
        Err(StoreError::BadReference {
            table: "indices",
            index: 4,
            field: "value",
            value,
            limit,
        }) => {
            assert_eq!((value, limit), (v0 as u64, v0 as u64));
        }
        other => panic!("{:?}", other.err()),
    }
    // A rect's inner x past its outer rectangle is named as `inner.x` (it was reported as `inner.w`), a
    // NaN `uv_min` as a float (it was its bit pattern).
    let mut b = bytes.clone();
    let at = record_at(&b, Section::Rects, 0);
    b[at + 52..at + 56].copy_from_slice(&5000u32.to_le_bytes());
    reseal(&mut b);
    match TreeFile::from_bytes(&b) {
        Err(StoreError::BadValue {
            table: "rects",
            index: 0,
            field: "inner.x",
            value: 5000,
        }) => {}
        other => panic!("{:?}", other.err()),
    }
    let mut b = bytes.clone();
    b[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
    reseal(&mut b);
    match TreeFile::from_bytes(&b) {
        Err(
            e @ StoreError::BadFloat {
                table: "rects",
                index: 0,
                field: "uv_min",
                ..
            },
        ) => assert!(e.to_string().contains("NaN"), "{e}"),
        other => panic!("{:?}", other.err()),
    }
    // A block offset moved off its place (the end of the block before, rounded up to 4 KiB).
    let mut b = bytes.clone();
    let at = record_at(&b, Section::Blocks, 1);
    let off = u64::from_le_bytes(b[at..at + 8].try_into().unwrap());
    b[at..at + 8].copy_from_slice(&(off + 16).to_le_bytes());
    reseal(&mut b);
    assert!(matches!(
        TreeFile::from_bytes(&b),
        Err(StoreError::BlockPlacement { block: BlockId(1), offset, expected })
            if offset == off + 16 && expected == off
    ));
    // An original whose width is not a power of two (OriginalRecord::width at byte 8), and one whose
    // chain no longer fits its block (height doubled: the block's slots sum to more than its length).
    let mut b = bytes.clone();
    let at = record_at(&b, Section::Originals, 0) + 8;
    b[at..at + 2].copy_from_slice(&48u16.to_le_bytes());
    reseal(&mut b);
    assert!(
        matches!(
            TreeFile::from_bytes(&b),
            Err(StoreError::BadValue {
                table: "originals",
                index: 0,
                field: "width",
                value: 48
            })
        ),
        "{:?}",
        TreeFile::from_bytes(&b).err()
    );
    let mut b = bytes.clone();
    let at = record_at(&b, Section::Originals, 0) + 10;
    let h = u16::from_le_bytes(b[at..at + 2].try_into().unwrap());
    assert!(
        h <= 1024,
        "the fixture's sides stay small, so twice the height is still a valid side"
    );
    b[at..at + 2].copy_from_slice(&(h * 2).to_le_bytes());
    reseal(&mut b);
    assert!(
        matches!(
            TreeFile::from_bytes(&b),
            Err(StoreError::BadValue {
                table: "blocks",
                field: "length",
                ..
            })
        ),
        "{:?}",
        TreeFile::from_bytes(&b).err()
    );
    // A future version, and versions 1 (RGBA8 only, 40-byte block records), 2 (baked atlas UVs in the
    // vertices), 3 (originals stored per leaf), 4 (originals at square classes) and 5 (no rect means):
    // all refused by number, the message says to rebuild.
    for found in [7u32, 5, 4, 3, 2, 1] {
        let mut b = bytes.clone();
        b[8..12].copy_from_slice(&found.to_le_bytes());
        reseal(&mut b);
        match TreeFile::from_bytes(&b) {
            Err(
                e @ StoreError::UnsupportedVersion {
                    found: f,
                    supported: 6,
                },
            ) => {
                assert_eq!(f, found);
                assert!(e.to_string().contains("rebuilt"), "{e}");
            }
            other => panic!("version {found}: {:?}", other.err()),
        }
    }
    // An unknown block format code in tree 1 (TreeRecord::format at byte 4).
    let mut b = bytes.clone();
    let at = record_at(&b, Section::Trees, 1) + 4;
    b[at..at + 4].copy_from_slice(&4u32.to_le_bytes());
    reseal(&mut b);
    assert!(matches!(
        TreeFile::from_bytes(&b),
        Err(StoreError::BadValue {
            table: "trees",
            index: 1,
            field: "format",
            value: 4
        })
    ));
    // Not our file.
    let mut b = bytes;
    b[0] = b'X';
    assert!(matches!(
        TreeFile::from_bytes(&b),
        Err(StoreError::BadMagic { .. })
    ));
    // What it looks like instead, not its bytes in hex: the tool's own shard and plan files say what to do.
    use atlastree::store::describe_start;
    for (head, says) in [
        (
            &atlastree::store::shard::SHARD_MAGIC[..],
            "`atlastree merge OUT`",
        ),
        (
            &atlastree::store::shard_plan::PLAN_MAGIC[..],
            "build the shards",
        ),
        (&atlastree::store::format::MAGIC[..], "already whole"),
        (b"glTF\x02\0\0\0".as_slice(), "a GLB scene"),
        (b"\x89PNG\r\n\x1a\n", "a PNG image"),
        (b"\n  {\"asse", "JSON text"),
        (b"ATLTREX\0", "binary data starting 41 54 4c 54 52 45 58 00"),
        (b"\x7fELF\x02\x01\x01\0", "an executable program"),
        (b"hello, w", "text starting \"hello, w\""),
    ] {
        assert!(
            describe_start(head).contains(says),
            "{head:?}: {}",
            describe_start(head)
        );
    }
    let e = TreeFile::from_bytes(b"{\"asset\": {}}       ")
        .err()
        .unwrap();
    assert!(
        e.to_string()
            .contains("not an atlastree paging file (JSON text"),
        "{e}"
    );
}

#[test]
fn dropped_writer_leaves_no_file() {
    let forest = synth_forest(21, &small_specs());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.atlastree");
    {
        let w = FileWriter::create(&path, &forest).unwrap();
        w.write_block(BlockId(0), &block_bytes(21, 0, forest.blocks[0].bytes))
            .unwrap();
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            1,
            "the temp file exists"
        );
    }
    assert!(!path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "temp file left behind"
    );
}

#[test]
fn existing_target_replaced_only_on_success() {
    let forest = synth_forest(22, &small_specs());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.atlastree");
    // A previous paging file (its magic; a file without it is never replaced: `check_replaceable`).
    let old = [&atlastree::store::format::MAGIC[..], b" old"].concat();
    std::fs::write(&path, &old).unwrap();

    let w = FileWriter::create(&path, &forest).unwrap();
    let missing = 3;
    for (i, b) in forest
        .blocks
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != missing)
    {
        w.write_block(BlockId(i as u32), &block_bytes(22, i, b.bytes))
            .unwrap();
    }
    match w.finish() {
        Err(StoreError::BlockMissing { block }) => assert_eq!(block, BlockId(missing as u32)),
        other => panic!("{other:?}"),
    }
    assert_eq!(std::fs::read(&path).unwrap(), old);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);

    write_forest(&path, &forest, 22);
    assert_same(&TreeFile::open(&path).unwrap(), &forest, 22);
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn block_written_twice_wrong_length_or_unknown_is_refused() {
    let forest = synth_forest(23, &small_specs());
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.atlastree");
    let w = FileWriter::create(&path, &forest).unwrap();
    let len = forest.blocks[2].bytes;
    let data = block_bytes(23, 2, len);
    match w.write_block(BlockId(2), &data[..data.len() - 1]) {
        Err(StoreError::BlockLength {
            block,
            expected,
            got,
        }) => {
            assert_eq!((block, expected, got), (BlockId(2), len, len - 1));
        }
        other => panic!("{other:?}"),
    }
    w.write_block(BlockId(2), &data).unwrap();
    assert!(matches!(
        w.write_block(BlockId(2), &data),
        Err(StoreError::BlockWrittenTwice { block: BlockId(2) })
    ));
    let n = forest.blocks.len() as u32;
    assert!(matches!(
        w.write_block(BlockId(n), &[]),
        Err(StoreError::BadReference { table: "blocks", limit, .. }) if limit == u64::from(n)
    ));
}

#[test]
fn writer_refuses_inconsistent_forest_before_touching_disk() {
    let mut forest = synth_forest(24, &small_specs());
    let n = forest.blocks.len() as u32;
    forest.trees[1].nodes[2].atlas_block = BlockId(n);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.atlastree");
    let base = forest.trees[0].nodes.len() as u64;
    match FileWriter::create(&path, &forest) {
        Err(StoreError::BadReference {
            table: "nodes",
            index,
            field: "atlas_block",
            value,
            limit,
        }) => {
            assert_eq!(
                (index, value, limit),
                (base + 2, u64::from(n), u64::from(n))
            );
        }
        other => panic!("{:?}", other.err()),
    }
    // Missing source-triangle ids.
    let mut forest = synth_forest(24, &small_specs());
    forest.trees[0].source_triangles.pop();
    assert!(matches!(
        FileWriter::create(&path, &forest),
        Err(StoreError::BadValue {
            table: "trees",
            field: "source_triangles.count",
            ..
        })
    ));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Consistent-looking garbage (checksums recomputed) in the tables never panics: open either rejects it
    /// or every accessor works.
    #[test]
    fn resealed_garbage_in_tables_never_panics(
        edits in proptest::collection::vec((0.0f64..1.0, any::<u32>()), 1..4),
    ) {
        let (_, mut bytes) = SMALL.with(|s| s.clone());
        let h = header_of(&bytes);
        let start = h.sections[0].offset as usize;
        let end = { let b = h.section(Section::Blocks); (b.offset + b.length) as usize };
        for (pos, value) in edits {
            let at = (start + (pos * (end - start - 4) as f64) as usize) & !3;
            bytes[at..at + 4].copy_from_slice(&value.to_le_bytes());
        }
        reseal(&mut bytes);
        if let Ok(f) = TreeFile::from_bytes(&bytes) {
            let forest = f.to_forest();
            prop_assert_eq!(forest.trees.len(), f.trees());
            for i in 0..f.blocks().len() {
                let _ = f.block(BlockId(i as u32));
            }
            for i in 0..f.materials().len() {
                prop_assert!(f.material_name(i).is_some());
            }
        }
    }
}

#[test]
fn tree_file_is_send_and_sync() {
    fn check<T: Send + Sync>() {}
    check::<TreeFile>();
    check::<FileWriter>();
}

/// `inspect --verify` checks that a leaf node's bounds hold its vertices: selection and culling trust the
/// bounds, and a writer that shrank them (the file resealed, every checksum right) verified clean.
#[test]
fn verify_finds_vertices_outside_their_leaf_bounds() {
    use crate::built::build_ok;
    use crate::fixtures::peel_strip::{peel_strip, strip_options};
    let built = build_ok(&peel_strip(3), &strip_options());
    assert!(atlastree::inspect::verify(&built.file).ok());
    let t = built.file.tree(0).unwrap();
    let (ni, node) = (t.nodes.iter().enumerate())
        .find(|(_, n)| n.leaf != atlastree::ids::NONE)
        .unwrap();
    let mut bytes = std::fs::read(&built.path).unwrap();
    // bounds_max.x (NodeRecord bytes 24..32) pulled halfway in.
    let x = (node.bounds_min[0] + node.bounds_max[0]) / 2.0;
    let at = record_at(&bytes, Section::Nodes, ni) + 24;
    bytes[at..at + 8].copy_from_slice(&x.to_le_bytes());
    reseal(&mut bytes);
    let file = TreeFile::from_bytes(&bytes).unwrap();
    let v = atlastree::inspect::verify(&file);
    assert!(!v.ok());
    let leaf = node.leaf;
    assert!(
        v.violations
            .iter()
            .any(|m| m.contains(&format!("leaf {leaf} (node {ni})"))
                && m.contains("lies outside the node's bounds")),
        "{:?}",
        v.violations
    );
}

/// `render`, `sweep` and `view` open a paging file for its tables, then again for the loader threads: a
/// file published over the path in between (another build's atomic rename) is refused, not drawn as the
/// first file's tables with the second file's blocks.
#[test]
fn a_file_replaced_between_two_opens_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("x.atlastree");
    write_forest(&path, &synth_forest(31, &small_specs()), 31);
    let first = TreeFile::open(&path).unwrap();
    let again = first.reopen().unwrap();
    assert_eq!(again.header(), first.header());
    // The same bytes published again (a rerun of the same build) are the same file.
    let same = dir.path().join("same.atlastree");
    write_forest(&same, &synth_forest(31, &small_specs()), 31);
    std::fs::rename(&same, &path).unwrap();
    first.reopen().expect("an identical file republished");
    // Another file of the same shape (other block bytes, so other checksums), published over the path.
    let other = dir.path().join("y.atlastree");
    write_forest(&other, &synth_forest(31, &small_specs()), 32);
    std::fs::rename(&other, &path).unwrap();
    match first.reopen() {
        Err(e @ StoreError::Replaced { .. }) => assert!(e.to_string().contains("x.atlastree")),
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("a replaced file was accepted"),
    }
}

/// A reference of another scene with the same tree shape (one node per tree, the same parameters) is
/// told apart by its geometry and materials, not reported as atlas errors ("recorded error … but …
/// measured"): one textured quad against two.
#[test]
fn a_reference_of_another_scene_is_named_by_its_geometry() {
    use atlastree::scene::synthetic::SceneBuilder;
    use atlastree::scene::{AlphaMode, UpAxis, Wrap};
    let scene = |quads: usize| {
        let mut b = SceneBuilder::new(UpAxis::Y);
        for i in 0..quads {
            let img = b.pattern_image(&format!("t{i}"), 32, i as u32);
            let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
            crate::built::ground_quad(&mut b, [20.0 * i as f64, 0.0], 10.0, 1.0, m);
        }
        b.build()
    };
    let dir = tempfile::tempdir().unwrap();
    let opts = crate::built::tiny_opts(1024, 5.0);
    let paths: Vec<_> = [1, 2]
        .iter()
        .map(|&q| {
            let p = dir.path().join(format!("q{q}.atlastree"));
            atlastree::preprocess::build(&scene(q), &opts, &p, &atlastree::preprocess::NoProgress)
                .unwrap();
            p
        })
        .collect();
    let [a, b] = [&paths[0], &paths[1]].map(|p| TreeFile::open(p).unwrap());
    assert_eq!(
        a.tree(0).unwrap().nodes.len(),
        b.tree(0).unwrap().nodes.len()
    );
    let why = atlastree::inspect::reference_mismatch(&a, &b).expect("another scene");
    assert!(
        why.contains("geometry") && why.contains("materials 2 (this file: 1)"),
        "{why}"
    );
    assert_eq!(atlastree::inspect::reference_mismatch(&a, &a), None);
}

/// A compressed atlas block whose record claims more error than 8-bit values can have (255² a sample;
/// forged, the checksums recomputed) is a verify violation naming the block: it verified and printed a
/// negative PSNR (fault hunt, session 38). The unedited file verifies.
#[test]
fn an_impossible_recorded_error_is_a_violation() {
    use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
    let scene_path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&scene_path, &Default::default()).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bc1.atlastree");
    let opts = BuildOptions {
        d_min: DMin::Ratio(4.0),
        atlas_size: 256,
        compress: atlastree::texfmt::Compression::Bc1,
        ..BuildOptions::default()
    };
    build(&scene, &opts, &out, &NoProgress).unwrap();
    let bytes = std::fs::read(&out).unwrap();
    let file = TreeFile::from_bytes(&bytes).unwrap();
    assert!(atlastree::inspect::verify(&file).ok());
    let block = file.tree(0).unwrap().nodes[0].atlas_block as usize;
    drop(file);
    let mut edited = bytes.clone();
    // `sse` is the fourth u64 of a block record.
    let at = record_at(&edited, Section::Blocks, block) + 24;
    edited[at..at + 8].copy_from_slice(&(1u64 << 62).to_le_bytes());
    reseal(&mut edited);
    let file = TreeFile::from_bytes(&edited).unwrap();
    let v = atlastree::inspect::verify(&file);
    let said = v.violations.join("; ");
    assert!(
        !v.ok() && said.contains(&format!("atlas block {block} records error {}", 1u64 << 62)),
        "{said}"
    );
}
