//! Files read only where they are regular ([`open_regular`], [`read_regular`]), and the text files a
//! user names ([`read_text_file`]: a FIFO too); [`node_kind`] names what anything else is.

use std::fs::File;
use std::path::Path;

use super::human_bytes;

/// What a file-system node is, for messages: "a directory", "a FIFO", "a character device", … ("a regular
/// file" for one).
pub fn node_kind(meta: &std::fs::Metadata) -> &'static str {
    if meta.is_file() {
        return "a regular file";
    }
    if meta.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a FIFO";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// Opens `path` for reading if it is a regular file (also behind a symlink). Anything else — a directory,
/// a FIFO (whose `open` would block until a writer comes), a device (`/dev/zero` never ends) or a
/// socket — is refused with [`std::io::ErrorKind::InvalidInput`] naming what it is, before it is opened.
pub fn open_regular(path: &Path) -> std::io::Result<File> {
    refuse_non_regular(&std::fs::metadata(path)?)?;
    File::open(path)
}

/// [`std::io::ErrorKind::InvalidInput`] naming what `meta` is, unless it is a regular file.
fn refuse_non_regular(meta: &std::fs::Metadata) -> std::io::Result<()> {
    if meta.is_file() {
        return Ok(());
    }
    Err(std::io::Error::new(
        std::io::ErrorKind::InvalidInput,
        format!("{}, not a regular file", node_kind(meta)),
    ))
}

/// The bytes of regular file `path` ([`open_regular`]), at most `limit` of them.
pub fn read_regular(path: &Path, limit: Option<u64>) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let file = open_regular(path)?;
    let len = file.metadata()?.len();
    let want = limit.map_or(len, |l| l.min(len));
    let mut bytes = Vec::with_capacity(usize::try_from(want).unwrap_or(0));
    file.take(limit.unwrap_or(u64::MAX))
        .read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// Largest text file [`read_text_file`] reads (camera paths, sweep grids, CSV reports).
pub const MAX_TEXT_FILE_BYTES: u64 = 256 << 20;

/// The UTF-8 text of a file a user names on the command line: a regular file, or a FIFO (`--path
/// <(make-path)`, read to its end); at most [`MAX_TEXT_FILE_BYTES`] (a longer one, `/dev/zero` included,
/// is [`std::io::ErrorKind::InvalidData`]); directories and devices are refused as [`open_regular`] does.
/// A leading UTF-8 byte-order mark is dropped.
pub fn read_text_file(path: &Path) -> std::io::Result<String> {
    use std::io::Read;
    let meta = std::fs::metadata(path)?;
    #[cfg(unix)]
    let fifo = std::os::unix::fs::FileTypeExt::is_fifo(&meta.file_type());
    #[cfg(not(unix))]
    let fifo = false;
    if !fifo {
        refuse_non_regular(&meta)?;
    }
    let file = File::open(path)?;
    let mut bytes = Vec::new();
    file.take(MAX_TEXT_FILE_BYTES + 1).read_to_end(&mut bytes)?;
    if bytes.len() as u64 > MAX_TEXT_FILE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("longer than {}", human_bytes(MAX_TEXT_FILE_BYTES)),
        ));
    }
    let mut text = String::from_utf8(bytes)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))?;
    // A byte-order mark some editors write is not text (JSON and CSV parsers refuse it).
    if text.starts_with('\u{feff}') {
        text.drain(..'\u{feff}'.len_utf8());
    }
    Ok(text)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn only_regular_files_are_read() {
        let e = open_regular(Path::new("/dev/zero")).unwrap_err();
        assert_eq!(e.to_string(), "a character device, not a regular file");
        let dir = tempfile::tempdir().unwrap();
        let e = read_regular(dir.path(), None).unwrap_err();
        assert_eq!(e.to_string(), "a directory, not a regular file");
        let f = dir.path().join("f");
        std::fs::write(&f, b"0123456789").unwrap();
        assert_eq!(read_regular(&f, Some(4)).unwrap(), b"0123");
        assert_eq!(read_regular(&f, Some(40)).unwrap(), b"0123456789");
        assert_eq!(read_text_file(&f).unwrap(), "0123456789");
        std::fs::write(&f, b"\xef\xbb\xbf{\"a\": 1}").unwrap();
        assert_eq!(
            read_text_file(&f).unwrap(),
            "{\"a\": 1}",
            "the byte-order mark dropped"
        );
        let e = read_text_file(Path::new("/dev/zero")).unwrap_err();
        assert_eq!(e.to_string(), "a character device, not a regular file");
        // A FIFO a user names is read to its end (process substitution).
        let fifo = dir.path().join("p");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        assert!(made.is_ok_and(|s| s.success()), "mkfifo {}", fifo.display());
        let writer = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::write(fifo, b"{\"a\": 1}"))
        };
        assert_eq!(read_text_file(&fifo).unwrap(), "{\"a\": 1}");
        writer.join().unwrap().unwrap();
        assert!(open_regular(&fifo).is_err());
    }
}
