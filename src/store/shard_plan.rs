//! Plan files (issue 22, docs/DESIGN.md "Sharded builds"): the plan of a sharded build made once
//! (`atlastree build --shard plan`) and read by every shard and the merge, so no shard holds the scene's
//! triangles.
//!
//! Layout (little-endian, parts 16-byte aligned):
//!
//! ```text
//! PlanHeader | manifest (JSON: PlanManifest) | table prefix (crate::store::table_prefix)
//! ```
//!
//! The header carries the plan key (scene input and the flags that shape the plan: a shard with other
//! flags or another scene refuses the plan), the hash of the scene's image identities (a shard whose images
//! changed refuses it), the prefix's `xxh3_128`, lengths, and checksums of the manifest and of itself.

use super::shard::{hash128, read_at, write_at};
use super::{FileWriter, StoreError, TreeFile};
use crate::scene::ImageRef;
use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};
use std::fs::File;
use std::path::{Path, PathBuf};

/// First bytes of every plan file.
pub const PLAN_MAGIC: [u8; 8] = *b"ATPLAN\x00\x01";
/// Version of the layout above.
pub const PLAN_VERSION: u32 = 1;
/// The largest manifest a reader accepts, bytes (a manifest holds a line per image and the command line).
pub const MAX_MANIFEST_BYTES: u64 = 64 << 20;
const ALIGN: u64 = 16;

/// The fixed header of a plan file.
#[repr(C)]
#[derive(Copy, Clone, Debug, Pod, Zeroable, PartialEq, Eq)]
pub struct PlanHeader {
    /// [`PLAN_MAGIC`].
    pub magic: [u8; 8],
    /// [`PLAN_VERSION`].
    pub version: u32,
    pub _pad: u32,
    /// `xxh3_128` of the scene input (the glTF file and its buffers) and the flags that shape the plan
    /// (`preprocess::shard_plan_key`).
    pub key: [u64; 2],
    /// `xxh3_128` of the scene's image identities (`preprocess::shard::images_identity`).
    pub images: [u64; 2],
    /// `xxh3_128` of the table prefix.
    pub prefix_hash: [u64; 2],
    /// Bytes of the manifest (JSON).
    pub manifest_len: u64,
    /// Bytes of the table prefix.
    pub prefix_len: u64,
    /// Exact file length, bytes.
    pub file_len: u64,
    /// `xxh3_64` of the manifest bytes.
    pub manifest_checksum: u64,
    pub _reserved: u64,
    /// `xxh3_64` of the header bytes before this field.
    pub checksum: u64,
}
const HEADER_BYTES: u64 = size_of::<PlanHeader>() as u64;
const _: () = assert!(size_of::<PlanHeader>() == 112);

impl PlanHeader {
    fn compute_checksum(&self) -> u64 {
        let bytes = bytemuck::bytes_of(self);
        xxhash_rust::xxh3::xxh3_64(&bytes[..bytes.len() - size_of::<u64>()])
    }

    /// Offset of the table prefix: after the header and the manifest, aligned; `None` on overflow.
    fn prefix_at(&self) -> Option<u64> {
        HEADER_BYTES
            .checked_add(self.manifest_len)?
            .checked_next_multiple_of(ALIGN)
    }
}

/// What a plan file says besides its tables.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PlanManifest {
    /// The command line that made the plan (the hint a refused plan prints).
    pub argv: Vec<String>,
    /// The scene's images in image-id order, as the pixel pass needs them.
    pub images: Vec<ImageRef>,
    /// Scene triangles the plan covers.
    pub triangles: u64,
}

/// Why a plan file was refused. Every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum PlanFileError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "{path}: not an atlastree plan file ({})",
        super::describe_start(found)
    )]
    BadMagic { path: PathBuf, found: Vec<u8> },
    #[error("{path}: plan format version {found}, this build reads {PLAN_VERSION}")]
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
        what: &'static str,
        expected: u64,
        found: u64,
    },
    #[error("{path}: {what}")]
    Layout { path: PathBuf, what: String },
    #[error("{path}: its table prefix does not open: {source}")]
    Tables {
        path: PathBuf,
        #[source]
        source: StoreError,
    },
}

/// Writes a plan file to `path` atomically: an interrupted write leaves no file.
pub fn write_plan(
    path: &Path,
    key: [u64; 2],
    images: [u64; 2],
    manifest: &PlanManifest,
    prefix: &[u8],
) -> Result<u64, StoreError> {
    let manifest_bytes = serde_json::to_vec(manifest).map_err(|e| StoreError::Write {
        target: path.to_path_buf(),
        temp: path.to_path_buf(),
        source: std::io::Error::other(e),
    })?;
    let mut header = PlanHeader {
        magic: PLAN_MAGIC,
        version: PLAN_VERSION,
        _pad: 0,
        key,
        images,
        prefix_hash: hash128(prefix),
        manifest_len: manifest_bytes.len() as u64,
        prefix_len: prefix.len() as u64,
        file_len: 0,
        manifest_checksum: xxhash_rust::xxh3::xxh3_64(&manifest_bytes),
        _reserved: 0,
        checksum: 0,
    };
    let prefix_at = header
        .prefix_at()
        .ok_or(StoreError::LayoutOverflow { what: "plan" })?;
    header.file_len = prefix_at + header.prefix_len;
    header.checksum = header.compute_checksum();
    let temp = super::create_output(path)?;
    let write_err = |source| StoreError::Write {
        target: path.to_path_buf(),
        temp: temp.temp_path().to_path_buf(),
        source,
    };
    let file = temp.file();
    write_at(file, 0, bytemuck::bytes_of(&header)).map_err(write_err)?;
    write_at(file, HEADER_BYTES, &manifest_bytes).map_err(write_err)?;
    write_at(file, prefix_at, prefix).map_err(write_err)?;
    file.set_len(header.file_len).map_err(write_err)?;
    let temp_path = temp.temp_path().to_path_buf();
    temp.commit().map_err(|source| StoreError::Write {
        target: path.to_path_buf(),
        temp: temp_path,
        source,
    })?;
    Ok(header.file_len)
}

/// A plan file opened by a shard or the merge: header and manifest checked; the prefix read (and checked)
/// on demand.
pub struct PlanFile {
    path: PathBuf,
    file: File,
    pub header: PlanHeader,
    pub manifest: PlanManifest,
}

impl PlanFile {
    /// Opens `path` and checks magic, version, header checksum, exact length and the manifest's checksum
    /// and syntax.
    pub fn open(path: &Path) -> Result<PlanFile, PlanFileError> {
        let io = |source| PlanFileError::Io {
            path: path.to_path_buf(),
            source,
        };
        let layout = |what: String| PlanFileError::Layout {
            path: path.to_path_buf(),
            what,
        };
        let file = crate::util::open_regular(path).map_err(io)?;
        let len = file.metadata().map_err(io)?.len();
        if len < HEADER_BYTES {
            return Err(PlanFileError::Length {
                path: path.to_path_buf(),
                len,
                expected: HEADER_BYTES,
            });
        }
        let hb = read_at(&file, 0, HEADER_BYTES).map_err(io)?;
        let header: PlanHeader = bytemuck::pod_read_unaligned(&hb);
        if header.magic != PLAN_MAGIC {
            return Err(PlanFileError::BadMagic {
                path: path.to_path_buf(),
                found: header.magic.to_vec(),
            });
        }
        if header.version != PLAN_VERSION {
            return Err(PlanFileError::Version {
                path: path.to_path_buf(),
                found: header.version,
            });
        }
        let sum = header.compute_checksum();
        if sum != header.checksum {
            return Err(PlanFileError::Checksum {
                path: path.to_path_buf(),
                what: "header",
                expected: header.checksum,
                found: sum,
            });
        }
        if header.file_len != len {
            return Err(PlanFileError::Length {
                path: path.to_path_buf(),
                len,
                expected: header.file_len,
            });
        }
        if header.manifest_len > MAX_MANIFEST_BYTES {
            return Err(layout(format!(
                "manifest of {} bytes, at most {MAX_MANIFEST_BYTES} expected",
                header.manifest_len
            )));
        }
        let end = header
            .prefix_at()
            .and_then(|at| at.checked_add(header.prefix_len));
        if end != Some(len) {
            return Err(layout(format!(
                "header, manifest ({} bytes) and table prefix ({} bytes) do not end at the file's {len} bytes",
                header.manifest_len, header.prefix_len
            )));
        }
        let mb = read_at(&file, HEADER_BYTES, header.manifest_len).map_err(io)?;
        let sum = xxhash_rust::xxh3::xxh3_64(&mb);
        if sum != header.manifest_checksum {
            return Err(PlanFileError::Checksum {
                path: path.to_path_buf(),
                what: "manifest",
                expected: header.manifest_checksum,
                found: sum,
            });
        }
        let manifest: PlanManifest = serde_json::from_slice(&mb)
            .map_err(|e| layout(format!("manifest is not a plan manifest: {e}")))?;
        Ok(PlanFile {
            path: path.to_path_buf(),
            file,
            header,
            manifest,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The plan's tables without their geometry ([`TreeFile::skeleton_prefix`]: a few bytes per node, leaf
    /// and rect in memory, none per triangle), after one streamed pass over the whole prefix checks its
    /// hash (which vouches for the geometry left unread).
    pub fn skeleton(&self) -> Result<TreeFile, PlanFileError> {
        self.check_prefix()?;
        let (at, len) = (self.prefix_at(), self.header.prefix_len);
        let name = self.path.display().to_string();
        TreeFile::skeleton_prefix(&self.file, at, len, &name).map_err(|source| {
            PlanFileError::Tables {
                path: self.path.clone(),
                source,
            }
        })
    }

    /// A writer of `out` whose tables are this plan's (`tables`, its [`PlanFile::skeleton`]), the prefix
    /// copied in pieces and checked against the plan's hash on the way.
    pub fn writer(&self, out: &Path, tables: &TreeFile) -> Result<FileWriter, StoreError> {
        let (at, len) = (self.prefix_at(), self.header.prefix_len);
        FileWriter::from_prefix_file(out, tables, &self.file, at, len, self.header.prefix_hash)
    }

    /// Checks the table prefix against the header's `prefix_hash` in one streamed pass.
    fn check_prefix(&self) -> Result<(), PlanFileError> {
        let (at, len) = (self.prefix_at(), self.header.prefix_len);
        let found = super::read::stream_hash128(&self.file, at, len).map_err(|source| {
            PlanFileError::Io {
                path: self.path.clone(),
                source,
            }
        })?;
        if found != self.header.prefix_hash {
            return Err(PlanFileError::Checksum {
                path: self.path.clone(),
                what: "table prefix",
                expected: self.header.prefix_hash[0],
                found: found[0],
            });
        }
        Ok(())
    }

    fn prefix_at(&self) -> u64 {
        self.header.prefix_at().unwrap_or(u64::MAX)
    }
}

/// `OUT.plan`: the plan file of the build that writes `out`.
pub fn plan_path(out: &Path) -> PathBuf {
    let mut name = out.as_os_str().to_os_string();
    name.push(".plan");
    PathBuf::from(name)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn manifest() -> PlanManifest {
        PlanManifest {
            argv: vec!["atlastree".into(), "build".into()],
            images: vec![ImageRef::Gltf(3), ImageRef::Solid([1, 2, 3, 255])],
            triangles: 12,
        }
    }

    #[test]
    fn round_trip_and_every_damage_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("x.plan");
        let prefix: Vec<u8> = (0..1000u32).map(|i| (i * 7) as u8).collect();
        let len = write_plan(&path, [1, 2], [3, 4], &manifest(), &prefix).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), len);
        let p = PlanFile::open(&path).unwrap();
        assert_eq!(p.manifest, manifest());
        assert_eq!((p.header.key, p.header.images), ([1, 2], [3, 4]));
        p.check_prefix().unwrap();
        let written = std::fs::read(&path).unwrap();
        assert_eq!(&written[written.len() - prefix.len()..], &prefix[..]);

        let good = std::fs::read(&path).unwrap();
        // Truncated, extended, a flipped byte in header, manifest and prefix.
        let cases: Vec<(&str, Vec<u8>)> = vec![
            ("truncated", good[..good.len() - 1].to_vec()),
            ("extended", [good.clone(), vec![0]].concat()),
            ("short", good[..50].to_vec()),
            ("header", flip(&good, 20)),
            ("manifest", flip(&good, HEADER_BYTES as usize + 3)),
            ("prefix", flip(&good, good.len() - 5)),
            ("magic", flip(&good, 0)),
        ];
        for (what, bytes) in cases {
            std::fs::write(&path, &bytes).unwrap();
            let refused = PlanFile::open(&path).and_then(|p| p.check_prefix());
            let err = refused.expect_err(what).to_string();
            assert!(err.contains("x.plan"), "{what}: {err}");
        }
        assert_eq!(
            plan_path(Path::new("a/out.atlastree")),
            Path::new("a/out.atlastree.plan")
        );
    }

    fn flip(bytes: &[u8], at: usize) -> Vec<u8> {
        let mut b = bytes.to_vec();
        b[at] ^= 0x5a;
        b
    }
}
