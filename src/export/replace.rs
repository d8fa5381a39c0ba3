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
    token: &str,
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
    let old = parent.join(format!(".{name}.old-{token}"));
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

/// What names one export's hidden siblings (`.NAME.partial-TOKEN`, `.NAME.old-TOKEN`,
/// `.NAME.lock-TOKEN`): its pid and a random part, so exports of one pid on two machines (two pods' PID 1)
/// never share a folder (review, session 39: the second deleted the first's live partial folder).
pub(super) fn export_token() -> String {
    use std::hash::BuildHasher;
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    let salt = std::collections::hash_map::RandomState::new().hash_one(nanos) as u32;
    format!("{}-{salt:08x}", std::process::id())
}

/// The lock an export holds for its life in `.NAME.lock-TOKEN` beside its `.NAME.partial-TOKEN` folder: an
/// export on another machine of a shared filesystem sees no process `PID` in its own `/proc`, and took the
/// folder of one still running for a stale one and deleted it (the running one then failed on a tile
/// file that had vanished; fault hunt, session 39). A file, not the folder, is locked: NFS locks only
/// files open for writing. Made and locked under `.NAME.locking-TOKEN`, then renamed into place, so the
/// lock's name never shows an unlocked file. Removed when the export ends (and, interrupted, by the
/// signal handler); one a killed export left is removed by the next export once its lock is free.
pub(super) struct ExportLock {
    path: std::path::PathBuf,
    _file: std::fs::File,
    _live: crate::util::LiveTempFile,
}

impl ExportLock {
    /// Takes the lock of export `token` named `name` in `parent`; `None` where it cannot be made or
    /// taken (a read-only parent: the export fails on its folder with a clear error anyway; a
    /// filesystem without locks), leaving no file.
    pub(super) fn take(parent: &Path, name: &str, token: &str) -> Option<ExportLock> {
        let path = lock_path(parent, name, token);
        let making = parent.join(format!(".{name}.locking-{token}"));
        let live = crate::util::LiveTempFile::register(&path);
        let live_making = crate::util::LiveTempFile::register(&making);
        let file = std::fs::File::create(&making).ok()?;
        let taken = file.try_lock().is_ok() && std::fs::rename(&making, &path).is_ok();
        drop(live_making);
        if !taken {
            let _ = std::fs::remove_file(&making);
            return None;
        }
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

/// Where export `token` holds its [`ExportLock`].
fn lock_path(parent: &Path, name: &str, token: &str) -> std::path::PathBuf {
    parent.join(format!(".{name}.lock-{token}"))
}

/// Removes the hidden siblings of exports named `name` in `parent` that nobody is writing: a
/// `.NAME.partial-TOKEN` or `.NAME.old-TOKEN` folder (an export killed by SIGKILL leaves one; Ctrl-C and
/// SIGTERM remove their own), and a lock file, where the token's pid runs on no process here other than
/// this one and its [`ExportLock`] is free or gone (an export on another machine sharing the folder holds
/// its own; this process has made none yet). Linux only (`/proc`); elsewhere nothing is removed.
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
        let tags = [".partial-", ".old-", ".lock-", ".locking-"];
        let Some((tag, token)) = tags.iter().find_map(|tag| {
            (file_name.strip_prefix(&format!(".{name}{tag}"))).map(|token| (*tag, token))
        }) else {
            continue;
        };
        // `PID-RANDOM`, or `PID` as before session 39.
        let Some(pid) = token.split('-').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        let lock = match tag {
            ".locking-" => entry.path(),
            _ => lock_path(parent, name, token),
        };
        let gone = pid == std::process::id() || !crate::util::process_may_run(pid);
        if gone && (!lock.exists() || crate::util::lock_is_free(&lock)) {
            if entry.path().is_dir() {
                let _ = std::fs::remove_dir_all(entry.path());
            } else {
                let _ = std::fs::remove_file(entry.path());
            }
        }
    }
}
