//! Positional file I/O, the one pair every store reader and writer uses: `pread`/`pwrite` on unix
//! (threads share one file without a lock), seek + read/write elsewhere (callers that share a file between
//! threads there hold a lock: [`super::FileWriter`] does); and [`size_and_reserve`], which sizes a new file and claims its whole
//! length on its filesystem before the first block is written.

use std::fs::File;

/// Reads exactly `buf.len()` bytes at `offset` of `file`.
pub(super) fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
    }
    #[cfg(not(unix))]
    {
        use std::io::{Read, Seek, SeekFrom};
        let mut f = file;
        f.seek(SeekFrom::Start(offset))?;
        f.read_exact(buf)
    }
}

/// Writes all of `bytes` at `offset` of `file`. Positional on unix; elsewhere seek + write, so callers
/// that share a file between threads there must hold a lock ([`crate::store::FileWriter`] does).
pub(super) fn write_all_at(file: &File, bytes: &[u8], offset: u64) -> std::io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::write_all_at(file, bytes, offset)
    }
    #[cfg(not(unix))]
    {
        use std::io::{Seek, SeekFrom, Write};
        let mut f = file;
        f.seek(SeekFrom::Start(offset))?;
        f.write_all(bytes)
    }
}

/// Sizes `file` (`temp`, the temp file of `target`) to `len` bytes and reserves them on its filesystem before any
/// block is written, so an output whose disk is too small fails at once with both sizes
/// ([`super::StoreError::NoSpace`]) instead of after the pixel pass, and a build that started cannot
/// run out of space half-way. Reserved bytes read as zeros, as the sized file's holes did, so the file is
/// the same. A filesystem that cannot reserve (some network filesystems: `fallocate` unsupported) is
/// left to report a full disk when a write fails, as before.
pub(super) fn size_and_reserve(
    file: &File,
    len: u64,
    target: &std::path::Path,
    temp: &std::path::Path,
) -> Result<(), super::StoreError> {
    use fs4::FileExt;
    file.set_len(len)
        .map_err(|source| super::StoreError::Write {
            target: target.to_path_buf(),
            temp: temp.to_path_buf(),
            source,
        })?;
    // Measured before reserving: a failed reservation may hold part of the space until the temp file goes.
    let available = fs4::available_space(crate::util::parent_dir(temp));
    reservation_outcome(file.allocate(len), len, available, target, temp)
}

/// What a reservation of `len` bytes that ended in `result` means for the write ([`size_and_reserve`]): a full
/// disk is [`super::StoreError::NoSpace`] with `available` (the free bytes measured before it), a
/// filesystem that cannot reserve is no error, any other failure is a write error.
fn reservation_outcome(
    result: std::io::Result<()>,
    len: u64,
    available: std::io::Result<u64>,
    target: &std::path::Path,
    temp: &std::path::Path,
) -> Result<(), super::StoreError> {
    use std::io::ErrorKind;
    let write_err = |source| super::StoreError::Write {
        target: target.to_path_buf(),
        temp: temp.to_path_buf(),
        source,
    };
    match result {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == ErrorKind::StorageFull => Err(super::StoreError::NoSpace {
            target: target.to_path_buf(),
            needed: len,
            available: available.map_err(write_err)?,
        }),
        Err(e) if matches!(e.kind(), ErrorKind::Unsupported | ErrorKind::InvalidInput) => Ok(()),
        Err(e) => Err(write_err(e)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::{Error, ErrorKind};
    use std::path::Path;

    #[test]
    fn a_full_disk_names_both_sizes_and_an_unsupported_reservation_is_no_error() {
        let (target, temp) = (
            Path::new("/out/city.atlastree"),
            Path::new("/out/.city.tmp"),
        );
        let full = reservation_outcome(
            Err(Error::from(ErrorKind::StorageFull)),
            507_321_004,
            Ok(62_914_560),
            target,
            temp,
        );
        let msg = full.unwrap_err().to_string();
        assert!(
            msg.starts_with("/out/city.atlastree: the new file needs 507321004 bytes (483.82 MiB) on its filesystem, only 62914560 (60.00 MiB) are free"),
            "{msg}"
        );
        for kind in [ErrorKind::Unsupported, ErrorKind::InvalidInput] {
            assert!(reservation_outcome(Err(Error::from(kind)), 1, Ok(0), target, temp).is_ok());
        }
        let other = reservation_outcome(Err(Error::other("EIO")), 1, Ok(0), target, temp);
        assert!(
            matches!(other, Err(crate::store::StoreError::Write { .. })),
            "{other:?}"
        );
        // A file that fits is reserved for real in this machine's temp directory.
        #[cfg(unix)]
        reserves_for_real();
    }

    #[cfg(unix)]
    fn reserves_for_real() {
        use std::os::unix::fs::MetadataExt;
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f");
        let file = File::create(&path).unwrap();
        size_and_reserve(&file, 1 << 20, &path, &path).unwrap();
        let meta = file.metadata().unwrap();
        assert_eq!(meta.len(), 1 << 20);
        assert!(meta.blocks() * 512 >= 1 << 20);
    }
}
