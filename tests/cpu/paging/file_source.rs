//! Blocks paged from a local file (`paging::FileSource`): read through a handle of their own, so a file
//! truncated or rewritten in place while it is paged from gives errors for the blocks it lost, and the
//! process lives on (through the memory map it ended with SIGBUS).

use crate::fixtures::store_forest::*;
use atlastree::ids::BlockId;
use atlastree::paging::{BlockSource, FileSource, SourceError};
use atlastree::store::{LoadMode, TreeFile};
use std::sync::Arc;

#[test]
fn a_file_truncated_while_paged_from_gives_errors_not_sigbus() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("f.atlastree");
    write_forest(&path, &synth_forest(41, &small_specs()), 41);
    let file = Arc::new(TreeFile::open_with(&path, LoadMode::Mmap).unwrap());
    assert!(file.is_mapped());
    let source = FileSource::new(Arc::clone(&file));
    let blocks = file.blocks().to_vec();
    for (i, b) in blocks.iter().enumerate() {
        let got = source.fetch(BlockId(i as u32), b).unwrap();
        assert_eq!(got, file.block(BlockId(i as u32)).unwrap().into_owned());
    }
    // Cut the file in place just past the first block: the blocks after it are gone.
    let first_end = blocks[0].offset + blocks[0].length;
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(first_end)
        .unwrap();
    assert!(source.fetch(BlockId(0), &blocks[0]).is_ok());
    let lost = (blocks.iter().enumerate().skip(1))
        .filter(|(i, b)| source.fetch(BlockId(*i as u32), b).is_err())
        .count();
    assert_eq!(lost, blocks.len() - 1);
    // Rewritten in place with other bytes: a checksum error, never the other file's block.
    std::fs::write(&path, vec![7u8; first_end as usize]).unwrap();
    match source.fetch(BlockId(0), &blocks[0]) {
        Err(SourceError::Checksum { .. }) => {}
        other => panic!("expected a checksum error, got {other:?}"),
    }
}
