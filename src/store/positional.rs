//! Positional file I/O, the one pair every store reader and writer uses: `pread`/`pwrite` on unix
//! (threads share one file without a lock), seek + read/write elsewhere (callers that share a file between
//! threads there hold a lock: [`super::FileWriter`] does).

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
