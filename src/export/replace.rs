//! Putting a finished export in place of OUT, and clearing what earlier exports left beside it.

use super::{ExportError, io};
use std::path::Path;

/// Puts the finished export `temp` at `out`. Without `force` by one rename, which the kernel refuses onto
/// a non-empty directory or a file: an `out` that appeared or filled while the export ran is kept and
/// refused as the check up front refuses it (it was moved aside and deleted: fault hunt, session 32).
/// With `force`, an old `out` directory is renamed aside first and deleted only once the new one is in
/// place (put back if that rename fails), so a failure never leaves `out` empty; an old one that cannot
/// be deleted then is a warning, the export done.
pub(super) fn replace_dir(
    temp: &Path,
    out: &Path,
    name: &str,
    force: bool,
) -> Result<(), ExportError> {
    if !force || !out.exists() {
        let renamed = std::fs::rename(temp, out).or_else(|e| {
            // Windows renames onto no directory, not even an empty one: an empty one goes first
            // (`remove_dir` refuses a non-empty one, which stays refused).
            if std::fs::remove_dir(out).is_ok() {
                std::fs::rename(temp, out)
            } else {
                Err(e)
            }
        });
        return renamed.map_err(|e| match e.kind() {
            std::io::ErrorKind::DirectoryNotEmpty | std::io::ErrorKind::AlreadyExists => {
                ExportError::Exists {
                    dir: out.to_path_buf(),
                }
            }
            std::io::ErrorKind::NotADirectory => ExportError::BadOutput {
                dir: out.to_path_buf(),
                why: "exists and is not a directory",
            },
            _ => io(out)(e),
        });
    }
    if !out.is_dir() {
        return Err(ExportError::BadOutput {
            dir: out.to_path_buf(),
            why: "exists and is not a directory",
        });
    }
    let parent = crate::util::parent_dir(out);
    let old = parent.join(format!(".{name}.old-{}", std::process::id()));
    if old.exists() {
        std::fs::remove_dir_all(&old).map_err(io(&old))?;
    }
    std::fs::rename(out, &old).map_err(io(out))?;
    if let Err(e) = std::fs::rename(temp, out) {
        let _ = std::fs::rename(&old, out);
        return Err(io(out)(e));
    }
    // The new export is in place: an old one that cannot be removed (an immutable file in it) is left
    // with a warning, not reported as a failed export; a later export removes it once it can.
    if let Err(e) = std::fs::remove_dir_all(&old) {
        tracing::warn!(
            "the new export is at {}, but its predecessor, moved aside to {}, could not be removed: {e}",
            out.display(),
            old.display()
        );
    }
    Ok(())
}

/// The lock an export holds for its life in `.NAME.lock-PID` beside its `.NAME.partial-PID` folder: an
/// export on another machine of a shared filesystem sees no process `PID` in its own `/proc`, and took the
/// folder of one still running for a stale one and deleted it (the running one then failed on a tile
/// file that had vanished; fault hunt, session 39). A file, not the folder, is locked: NFS locks only
/// files open for writing. Removed when the export ends (and, interrupted, by the signal handler); one a
/// killed export left is removed by the next export once its lock is free.
pub(super) struct ExportLock {
    path: std::path::PathBuf,
    _file: std::fs::File,
    _live: crate::util::LiveTempFile,
}

impl ExportLock {
    /// Takes this process's lock for exports named `name` in `parent`; `None` where it cannot be made
    /// or taken (a read-only parent: the export fails on its folder with a clear error anyway).
    pub(super) fn take(parent: &Path, name: &str) -> Option<ExportLock> {
        let path = lock_path(parent, name, std::process::id());
        let live = crate::util::LiveTempFile::register(&path);
        let file = std::fs::File::create(&path).ok()?;
        file.try_lock().ok()?;
        Some(ExportLock {
            path,
            _file: file,
            _live: live,
        })
    }
}

impl Drop for ExportLock {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Where the export of process `pid` holds its [`ExportLock`].
fn lock_path(parent: &Path, name: &str, pid: u32) -> std::path::PathBuf {
    parent.join(format!(".{name}.lock-{pid}"))
}

/// Removes `.NAME.partial-PID` and `.NAME.old-PID` folders in `parent` whose process is gone (an export
/// killed by SIGKILL leaves one; Ctrl-C and SIGTERM remove their own) and whose [`ExportLock`] nobody
/// holds (an export on another machine sharing the folder holds its own), and such locks left alone.
/// Linux only (`/proc`); elsewhere nothing is removed.
pub(super) fn remove_stale_partials(parent: &Path, name: &str) {
    if !Path::new("/proc/self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for entry in entries.flatten() {
        let file_name = entry.file_name();
        let file_name = file_name.to_string_lossy();
        let pid = [".partial-", ".old-", ".lock-"].iter().find_map(|tag| {
            file_name
                .strip_prefix(&format!(".{name}{tag}"))
                .and_then(|pid| pid.parse::<u32>().ok())
        });
        let Some(pid) = pid else { continue };
        let lock = lock_path(parent, name, pid);
        if pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
            && (!lock.exists() || crate::util::lock_is_free(&lock))
        {
            if entry.path() == lock {
                let _ = std::fs::remove_file(&lock);
            } else {
                let _ = std::fs::remove_dir_all(entry.path());
            }
        }
    }
}
