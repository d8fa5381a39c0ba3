//! The paging file (docs/DESIGN.md "File format", paper §6): one file holds an [`AtlasForest`] — build parameters,
//! materials, one or two trees as fixed-size Pod tables read in place from a memory map, and the texture
//! blocks (atlases and leaves' original textures), each 4 KiB aligned and checksummed so the paging read
//! ([`TreeFile::block`]) verifies what it loads.
//!
//! - [`format`](mod@format): the records and the header (little-endian, versioned).
//! - [`FileWriter`]: computes the layout up front from the block sizes, accepts blocks from many threads,
//!   and publishes the file atomically (temp file in the same directory, fsync, rename).
//! - [`TreeFile`]: maps (or reads) and validates a file, then hands out slices in place.
//! - [`shard`] and [`shard_plan`]: the files a sharded build exchanges (docs/DESIGN.md "Sharded builds").
//!
//! [`AtlasForest`]: crate::model::AtlasForest

pub mod format;
mod means;
mod positional;
mod read;
pub mod shard;
pub mod shard_plan;
mod validate;
mod write;

pub use read::{BlockReader, LoadMode, TreeFile, TreeView, check_block_padding, padding_range};
pub use write::{FileWriter, WriteSummary, predicted_file_len, table_prefix};

use crate::ids::BlockId;
use std::path::{Path, PathBuf};

/// Where the pixel pass puts encoded blocks: the paging file itself ([`FileWriter`]) or a shard file
/// ([`shard::ShardWriter`]) that the merge copies into it.
pub trait BlockSink: Sync {
    /// Stores block `id` (exactly its laid-out length, once) with its compression error `sse`.
    fn put_block(&self, id: BlockId, bytes: &[u8], sse: u64) -> Result<(), StoreError>;
}

impl BlockSink for FileWriter {
    fn put_block(&self, id: BlockId, bytes: &[u8], sse: u64) -> Result<(), StoreError> {
        self.write_block_measured(id, bytes, sse)
    }
}

/// Everything that can go wrong writing or reading a paging file. Variants carry the numbers involved.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The output exists and is not a paging file: a build or merge never replaces it (`-o` pointing at
    /// the scene, its buffer or an image would destroy the input). `what` says what it is instead ("a
    /// directory", or its first bytes as text).
    #[error(
        "{path} exists and is not an atlastree {kind} ({what}): refusing to replace it; remove it first or \
         choose another output"
    )]
    NotReplaceable {
        path: PathBuf,
        kind: &'static str,
        what: String,
    },
    #[error("{path}: a paging file's name, not a folder's, is needed (it ends in /, /. or /..)")]
    FolderName { path: PathBuf },
    /// The output's folder is missing (or a file): found before any work, not when the file is written.
    #[error("{path}: its folder {dir} {what}: create it first or choose another output")]
    NoOutputDir {
        path: PathBuf,
        dir: PathBuf,
        what: &'static str,
    },
    /// Opened twice ([`TreeFile::reopen`]), the path held another paging file the second time.
    #[error(
        "{path} was replaced while it was being opened (its tables differ between two reads: another build \
         published over it?); run again once it stays put"
    )]
    Replaced { path: PathBuf },
    /// The file does not start with [`format::MAGIC`]; the message says what it looks like instead
    /// ([`describe_start`]: a shard or plan file, a scene, an image, text).
    #[error("{path}: not an atlastree paging file ({})", describe_start(found))]
    BadMagic { path: PathBuf, found: Vec<u8> },
    #[error(
        "unsupported format version {found} (this build reads version {supported}; files of older versions \
         must be rebuilt from their scene with `atlastree build`)"
    )]
    UnsupportedVersion { found: u32, supported: u32 },
    #[error("{path}: file is {len} bytes, {needed} needed")]
    Truncated {
        path: PathBuf,
        len: u64,
        needed: u64,
    },
    #[error("{path}: file is {len} bytes, header says {expected}")]
    TrailingBytes {
        path: PathBuf,
        len: u64,
        expected: u64,
    },
    #[error("section {section}: bytes {offset}..+{len} outside the file of {file_len} bytes")]
    SectionOutOfBounds {
        section: &'static str,
        offset: u64,
        len: u64,
        file_len: u64,
    },
    #[error("section {section}: {field} is {found}, expected {expected}")]
    SectionLayout {
        section: &'static str,
        field: &'static str,
        found: u64,
        expected: u64,
    },
    #[error("{what} at offset {offset} is not {align}-byte aligned")]
    Misaligned {
        what: String,
        offset: u64,
        align: u64,
    },
    #[error("padding between the tables or before the first block at byte {offset} is not zero")]
    NonZeroPadding { offset: u64 },
    #[error("padding after {block} at byte {offset} is not zero")]
    BlockPadding { block: BlockId, offset: u64 },
    #[error("checksum mismatch in {what}: expected {expected:#018x}, found {found:#018x}")]
    ChecksumMismatch {
        what: String,
        expected: u64,
        found: u64,
    },
    #[error("{table}[{index}].{field} = {value} is out of range (limit {limit})")]
    BadReference {
        table: &'static str,
        index: u64,
        field: &'static str,
        value: u64,
        limit: u64,
    },
    #[error("{table}[{index}].{field} has invalid value {value}")]
    BadValue {
        table: &'static str,
        index: u64,
        field: &'static str,
        value: u64,
    },
    /// A floating-point field outside what every reader assumes (`rule` says what).
    #[error("{table}[{index}].{field} is {value}: it must be {rule}")]
    BadFloat {
        table: &'static str,
        index: u64,
        field: &'static str,
        value: f64,
        rule: &'static str,
    },
    #[error("{block}: bytes {offset}..+{len} outside the file of {file_len} bytes")]
    BlockOutOfBounds {
        block: BlockId,
        offset: u64,
        len: u64,
        file_len: u64,
    },
    #[error(
        "{block} starts at byte {offset}, expected {expected} (the end of what precedes it rounded up to \
         the block alignment)"
    )]
    BlockPlacement {
        block: BlockId,
        offset: u64,
        expected: u64,
    },
    #[error("{block}: expected {expected} bytes, got {got}")]
    BlockLength {
        block: BlockId,
        expected: u64,
        got: u64,
    },
    #[error(
        "{path}: {block} is not held: this file was opened from its tables only; blocks come from a block source"
    )]
    BlocksNotHeld { path: PathBuf, block: BlockId },
    #[error("{block} written twice")]
    BlockWrittenTwice { block: BlockId },
    #[error("{block} was never written")]
    BlockMissing { block: BlockId },
    #[error(
        "{path}: the table prefix handed to the writer is not the one these tables were opened from"
    )]
    PrefixMismatch { path: PathBuf },
    #[error("{path}: pixel hashes of {got} images handed to the writer, the scene has {expected}")]
    ShardImages {
        path: PathBuf,
        expected: usize,
        got: usize,
    },
    #[error("{path}: the bytes at {offset} were put twice")]
    ShardPutTwice { path: PathBuf, offset: u64 },
    #[error("{path}: {block} does not belong to this shard")]
    ShardForeignBlock { path: PathBuf, block: BlockId },
    #[error("{path}: tree {tree} node {node} is not a subtree root of this shard")]
    ShardForeignHandoff { path: PathBuf, tree: u32, node: u32 },
    #[error("handoff of tree {tree} node {node}: expected {expected} bytes, got {got}")]
    ShardHandoffSize {
        tree: u32,
        node: u32,
        expected: u64,
        got: u64,
    },
    #[error("the handoff of tree {tree} node {node} was never written")]
    ShardHandoffMissing { tree: u32, node: u32 },
    #[error("layout overflows 64 bits at {what}")]
    LayoutOverflow { what: &'static str },
    #[error("the paging file is little-endian; this target is big-endian")]
    BigEndian,
    /// The output's filesystem cannot hold the file: found when its space is reserved, before any block is
    /// written ([`positional::size_and_reserve`]); the temp file is removed and nothing appears at `target`.
    #[error(
        "{target}: the new file needs {needed} bytes ({needed_h}) on its filesystem, only {available} ({available_h}) \
         are free: free space there or choose another output (an existing file is replaced only after the new one \
         is complete, so both must fit)",
        needed_h = crate::util::human_bytes(*needed),
        available_h = crate::util::human_bytes(*available)
    )]
    NoSpace {
        target: PathBuf,
        needed: u64,
        available: u64,
    },
    /// Writing the file failed (disk full, file size limit, I/O error); the temp file is removed and
    /// nothing appears at `target`.
    #[error("writing {target} failed, nothing written there: {source} (temp file {temp})")]
    Write {
        target: PathBuf,
        temp: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// The output's temp file could not be created (a read-only folder, a full disk): nothing was written.
    #[error("creating {target} failed, nothing written: {source}")]
    Create {
        target: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
}

impl StoreError {
    pub(crate) fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        StoreError::Io {
            path: path.to_path_buf(),
            source,
        }
    }
}

/// Refuses big-endian targets (the format is little-endian and read in place).
pub(crate) fn check_endian() -> Result<(), StoreError> {
    if cfg!(target_endian = "big") {
        Err(StoreError::BigEndian)
    } else {
        Ok(())
    }
}

/// Whether a paging file may be written at `path`: it does not exist, is empty, or is a paging file (any
/// format version: [`format::MAGIC`]). Anything else — the scene, its buffer, an image, a directory — is refused
/// with [`StoreError::NotReplaceable`] before any work, so a mistyped `-o` cannot destroy an input; a
/// folder that does not exist is [`StoreError::NoOutputDir`], also before any work.
pub fn check_replaceable(path: &Path) -> Result<(), StoreError> {
    check_replaceable_as(path, &format::MAGIC, "paging file")
}

/// [`check_replaceable`] for another of atlastree's outputs, a `kind` of file (`"plan file"`) that
/// starts with `magic` (a shard's or plan's name beside OUT held a user's file, replaced without a word;
/// fault hunt, session 31).
pub fn check_replaceable_as(
    path: &Path,
    magic: &[u8],
    kind: &'static str,
) -> Result<(), StoreError> {
    use std::io::Read;
    let refuse = |what: String| StoreError::NotReplaceable {
        path: path.to_path_buf(),
        kind,
        what,
    };
    // `OUT/`, `OUT/.` and `OUT/..` name a folder: the rename at the end would fail after all the work
    // (`new/.` of a folder that does not exist was found out only then; fault hunt, session 28).
    let raw = path.as_os_str().as_encoded_bytes();
    let last = raw.rsplit(|&b| b == b'/').next().unwrap_or(raw);
    if raw.last() == Some(&b'/') || last == b"." || last == b".." {
        return Err(StoreError::FolderName {
            path: path.to_path_buf(),
        });
    }
    // Where a link points (the file that is written): its folder must exist (a dangling link into a
    // missing folder failed only at the write; review, session 28).
    let resolved = crate::util::follow_output_links(path).map_err(|e| refuse(e.to_string()))?;
    let dir = crate::util::parent_dir(&resolved);
    if !dir.is_dir() {
        let what = if dir.exists() {
            "is not a folder"
        } else {
            "does not exist"
        };
        return Err(StoreError::NoOutputDir {
            path: path.to_path_buf(),
            dir: dir.to_path_buf(),
            what,
        });
    }
    // Absent, or metadata unreadable (the write itself then reports the error with its own context).
    let Ok(meta) = std::fs::metadata(path) else {
        return Ok(());
    };
    if meta.is_dir() {
        return Err(refuse("a directory".to_string()));
    }
    // A device, FIFO or socket (`-o /dev/null` as root): the atomic rename would replace the node itself.
    if !meta.is_file() {
        return Err(refuse(format!(
            "{}, not a regular file",
            crate::util::node_kind(&meta)
        )));
    }
    if meta.len() == 0 {
        return Ok(());
    }
    let mut head = Vec::with_capacity(magic.len());
    // Unreadable: refused too, as it is not known to be a paging file.
    if let Err(e) =
        std::fs::File::open(path).and_then(|f| f.take(magic.len() as u64).read_to_end(&mut head))
    {
        return Err(refuse(format!("unreadable: {e}")));
    }
    if head == magic {
        return Ok(());
    }
    Err(refuse(describe_start(&head)))
}

/// The temp file beside `path` that an atomic write of it fills ([`crate::util::AtomicFile`]); a failure
/// (a read-only folder, a full disk) is [`StoreError::Create`] naming `path`, not the temp file.
pub(crate) fn create_output(path: &std::path::Path) -> Result<crate::util::AtomicFile, StoreError> {
    crate::util::AtomicFile::create(path, 0o666).map_err(|source| StoreError::Create {
        target: path.to_path_buf(),
        source,
    })
}

/// What a file that is not a paging file looks like, from its first bytes: the tool's own shard and plan
/// files (with what to do with them), a glTF or GLB scene, an image, or its start as text.
pub fn describe_start(head: &[u8]) -> String {
    let starts = |m: &[u8]| head.starts_with(m) || (!head.is_empty() && m.starts_with(head));
    if head.starts_with(&format::MAGIC) {
        "an atlastree paging file, already whole: open it with `inspect`, `render` or `view`".into()
    } else if head.starts_with(&shard::SHARD_MAGIC[..6]) {
        "a shard of a sharded build: `atlastree merge OUT` makes the paging file from its shards"
            .into()
    } else if head.starts_with(&shard_plan::PLAN_MAGIC[..6]) {
        "the plan of a sharded build: build the shards with `--shard I/N`, then `atlastree merge OUT`".into()
    } else if starts(b"glTF") {
        "a GLB scene: `atlastree build SCENE -o OUT.atlastree` makes a paging file of it".into()
    } else if starts(b"\x89PNG") {
        "a PNG image".into()
    } else if starts(&[0xff, 0xd8, 0xff]) {
        "a JPEG image".into()
    } else if crate::scene::looks_like_json(head) {
        "JSON text: a glTF scene (`atlastree build` it), a camera path or a report?".into()
    } else if starts(b"\x7fELF") {
        "an executable program".into()
    } else if !head.is_empty()
        && head
            .iter()
            .all(|&b| b.is_ascii_graphic() || b.is_ascii_whitespace())
    {
        format!(
            "text starting \"{}\"",
            String::from_utf8_lossy(head).trim_end().escape_debug()
        )
    } else {
        // Binary of no known kind: its first bytes in hex (escaped text of control bytes reads as noise).
        let hex: Vec<String> = head.iter().take(8).map(|b| format!("{b:02x}")).collect();
        format!("binary data starting {}", hex.join(" "))
    }
}
