//! Block sources (paper §6 "dynamic loading"): where the bytes of a block come from. One trait, two
//! implementations: the memory-mapped local file ([`FileSource`]) and HTTP range requests
//! (`HttpSource`, see `paging::http`). Sources are called from loader threads, never from the render
//! thread; every source verifies the block's checksum on arrival, so a corrupt transfer is an error, not
//! a wrong image.

use crate::ids::BlockId;
use crate::store::TreeFile;
use crate::store::format::BlockRecord;
use std::borrow::Cow;
use std::sync::Arc;

/// Why a block could not be fetched. The pager counts these, keeps drawing coarser atlases, and decides
/// from [`SourceError::is_transient`] how soon it asks again; a root atlas that cannot be fetched ends the
/// run with this error as its cause. Variants of remote fetches name the URL, the block, the attempts
/// made (the source's own retries included) and the last cause.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// Local read failed (the store's own error: out of bounds, checksum, I/O).
    #[error("{source_name}: {error}")]
    Store {
        source_name: String,
        error: crate::store::StoreError,
    },
    /// A block id outside the block table (a caller's bug, never retried).
    #[error("{block} is not in the block table ({blocks} blocks)")]
    NotInTable { block: BlockId, blocks: u64 },
    /// The server answered with an unexpected status (the last of `attempts`).
    #[error(
        "{url}: HTTP status {status} for {block} (bytes {offset}..+{len}) after {attempts} attempt(s)"
    )]
    Status {
        url: String,
        block: BlockId,
        status: u16,
        offset: u64,
        len: u64,
        attempts: u32,
    },
    /// Connection, timeout, reset or broken body after all attempts.
    #[error("{url}: {block} failed after {attempts} attempt(s): {message}")]
    Transport {
        url: String,
        block: BlockId,
        attempts: u32,
        message: String,
    },
    /// A request that cannot succeed as built (bad URL, redirect loop, TLS setup); not retried.
    #[error("{url}: {block}: the request cannot succeed: {message}")]
    Request {
        url: String,
        block: BlockId,
        message: String,
    },
    /// A `206` for another range than asked for (the last of `attempts`).
    #[error("{url}: {block} failed after {attempts} attempt(s): {message}")]
    WrongRange {
        url: String,
        block: BlockId,
        attempts: u32,
        message: String,
        /// The server's `Content-Range` total says its file ends before the range, or is another length
        /// than when it was opened (replaced): asking again cannot help.
        permanent: bool,
    },
    /// Opening a remote file: its header claims more bytes of tables than the client holds in memory
    /// ([`crate::paging::http::HttpOptions::max_table_bytes`]); nothing past the header was fetched.
    #[error(
        "{url}: the header claims {} of tables, more than this client holds ({}: a quarter of the memory this process may use)",
        crate::util::human_bytes(*.bytes),
        crate::util::human_bytes(*.limit)
    )]
    TablesTooLarge { url: String, bytes: u64, limit: u64 },
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
    /// The bytes arrived but are too short or too long (the last of `attempts`).
    #[error(
        "{source_name}: {block}: expected {expected} bytes, got {got} after {attempts} attempt(s)"
    )]
    Length {
        source_name: String,
        block: BlockId,
        expected: u64,
        got: u64,
        attempts: u32,
    },
    /// The bytes arrived but do not match the block's checksum (the last of `attempts`).
    #[error(
        "{source_name}: {block}: checksum {found:#018x}, expected {expected:#018x} after {attempts} attempt(s)"
    )]
    Checksum {
        source_name: String,
        block: BlockId,
        expected: u64,
        found: u64,
        attempts: u32,
    },
}

impl SourceError {
    /// Whether asking again later may succeed: connection and timeout errors, `5xx`, `408` and `429`,
    /// short bodies, wrong `Content-Range`s (unless the server's file is shorter) and checksum mismatches
    /// (a corrupt transfer) are transient; a `4xx`, a bad request, a block outside the table, a local
    /// file's format error and a failed open are not (the pager then waits its longest back-off).
    pub fn is_transient(&self) -> bool {
        match self {
            SourceError::Store { error, .. } => {
                matches!(error, crate::store::StoreError::Io { .. })
            }
            SourceError::Status { status, .. } => *status >= 500 || matches!(status, 408 | 429),
            SourceError::WrongRange { permanent, .. } => !permanent,
            SourceError::Transport { .. }
            | SourceError::Length { .. }
            | SourceError::Checksum { .. } => true,
            SourceError::NotInTable { .. }
            | SourceError::Request { .. }
            | SourceError::Tables { .. }
            | SourceError::TablesTooLarge { .. } => false,
        }
    }

    /// Attempts made before this error was returned (1 for sources that do not retry; 0 for tables refused
    /// before they were asked for).
    pub fn attempts(&self) -> u32 {
        match self {
            SourceError::Status { attempts, .. }
            | SourceError::Transport { attempts, .. }
            | SourceError::WrongRange { attempts, .. }
            | SourceError::Tables { attempts, .. }
            | SourceError::Length { attempts, .. }
            | SourceError::Checksum { attempts, .. } => *attempts,
            SourceError::Store { .. }
            | SourceError::NotInTable { .. }
            | SourceError::Request { .. } => 1,
            SourceError::TablesTooLarge { .. } => 0,
        }
    }
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

/// Blocks from an open paging file: where it is memory-mapped, read through a handle of their own
/// ([`crate::store::BlockReader`]: a file truncated in place gives counted load failures, not SIGBUS);
/// otherwise through [`TreeFile::block`] (its bytes where it was read into memory whole, its own handle
/// where only its tables were).
pub struct FileSource {
    file: Arc<TreeFile>,
    reader: Option<crate::store::BlockReader>,
}

impl FileSource {
    pub fn new(file: Arc<TreeFile>) -> FileSource {
        let reader = (file.is_mapped())
            .then(|| crate::store::BlockReader::open(file.path()).ok())
            .flatten();
        FileSource { file, reader }
    }
}

impl BlockSource for FileSource {
    fn name(&self) -> String {
        self.file.path().display().to_string()
    }

    fn fetch(&self, id: BlockId, record: &BlockRecord) -> Result<Vec<u8>, SourceError> {
        let store = |error| SourceError::Store {
            source_name: self.name(),
            error,
        };
        let Some(reader) = &self.reader else {
            return self.file.block(id).map(Cow::into_owned).map_err(store);
        };
        let bytes = reader.read(record.offset, record.length).map_err(store)?;
        verify(&self.name(), id, record, &bytes)?;
        Ok(bytes)
    }
}

/// Checks `bytes` against `record` (length and `xxh3_64`); the check every source runs on arrival.
pub(super) fn verify(
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
            attempts: 1,
        });
    }
    let found = xxhash_rust::xxh3::xxh3_64(bytes);
    if found != record.checksum {
        return Err(SourceError::Checksum {
            source_name: source_name.to_string(),
            block: id,
            expected: record.checksum,
            found,
            attempts: 1,
        });
    }
    Ok(())
}
