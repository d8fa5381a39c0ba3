//! Block sources (paper §6 "dynamic loading"): where the bytes of a block come from. One trait, two
//! implementations: the memory-mapped local file ([`FileSource`]) and HTTP range requests
//! (`HttpSource`, see `paging::http`). Sources are called from loader threads, never from the render
//! thread; every source verifies the block's checksum on arrival, so a corrupt transfer is an error, not
//! a wrong image.

use crate::ids::BlockId;
use crate::store::TreeFile;
use crate::store::format::BlockRecord;
use std::sync::Arc;

/// Why a block could not be fetched. The pager counts these and keeps drawing coarser atlases.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// Local read failed (the store's own error: out of bounds, checksum, I/O).
    #[error("{source_name}: {error}")]
    Store {
        source_name: String,
        error: crate::store::StoreError,
    },
    /// The server answered with an unexpected status.
    #[error("{url}: HTTP status {status} for {block} (bytes {offset}..+{len})")]
    Status {
        url: String,
        block: BlockId,
        status: u16,
        offset: u64,
        len: u64,
    },
    /// Connection, timeout or transport error after all retries.
    #[error("{url}: {block} failed after {attempts} attempts: {message}")]
    Transport {
        url: String,
        block: BlockId,
        attempts: u32,
        message: String,
    },
    /// Opening a remote file: its header or tables could not be fetched (after all retries).
    #[error(
        "{url}: reading the tables (bytes {offset}..+{len}) failed after {attempts} attempts: {message}"
    )]
    Tables {
        url: String,
        offset: u64,
        len: u64,
        attempts: u32,
        message: String,
    },
    /// The bytes arrived but are too short or too long.
    #[error("{source_name}: {block}: expected {expected} bytes, got {got}")]
    Length {
        source_name: String,
        block: BlockId,
        expected: u64,
        got: u64,
    },
    /// The bytes arrived but do not match the block's checksum.
    #[error("{source_name}: {block}: checksum {found:#018x}, expected {expected:#018x}")]
    Checksum {
        source_name: String,
        block: BlockId,
        expected: u64,
        found: u64,
    },
}

/// A place blocks can be read from. Implementations are blocking and thread-safe; the loader calls
/// [`BlockSource::fetch`] from its own threads.
pub trait BlockSource: Send + Sync {
    /// A human-readable name for messages (a path or URL).
    fn name(&self) -> String;

    /// The bytes of block `id`, whose table record is `record` (offset, length, checksum), verified
    /// against the record's checksum.
    fn fetch(&self, id: BlockId, record: &BlockRecord) -> Result<Vec<u8>, SourceError>;
}

/// Blocks from an open (memory-mapped or read) paging file.
pub struct FileSource {
    file: Arc<TreeFile>,
}

impl FileSource {
    pub fn new(file: Arc<TreeFile>) -> FileSource {
        FileSource { file }
    }
}

impl BlockSource for FileSource {
    fn name(&self) -> String {
        self.file.path().display().to_string()
    }

    fn fetch(&self, id: BlockId, _record: &BlockRecord) -> Result<Vec<u8>, SourceError> {
        self.file
            .block(id)
            .map(<[u8]>::to_vec)
            .map_err(|error| SourceError::Store {
                source_name: self.name(),
                error,
            })
    }
}

/// Checks `bytes` against `record` (length and `xxh3_64`); the check every source runs on arrival.
pub fn verify(
    source_name: &str,
    id: BlockId,
    record: &BlockRecord,
    bytes: &[u8],
) -> Result<(), SourceError> {
    if bytes.len() as u64 != record.length {
        return Err(SourceError::Length {
            source_name: source_name.to_string(),
            block: id,
            expected: record.length,
            got: bytes.len() as u64,
        });
    }
    let found = xxhash_rust::xxh3::xxh3_64(bytes);
    if found != record.checksum {
        return Err(SourceError::Checksum {
            source_name: source_name.to_string(),
            block: id,
            expected: record.checksum,
            found,
        });
    }
    Ok(())
}
