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

/// Removes `.NAME.partial-PID` and `.NAME.old-PID` folders in `parent` whose process is gone (an export
/// killed by SIGKILL leaves one; Ctrl-C and SIGTERM remove their own). Linux only (`/proc`); elsewhere
/// nothing is removed.
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
        let pid = [".partial-", ".old-"].iter().find_map(|tag| {
            file_name
                .strip_prefix(&format!(".{name}{tag}"))
                .and_then(|pid| pid.parse::<u32>().ok())
        });
        if let Some(pid) = pid
            && pid != std::process::id()
            && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = std::fs::remove_dir_all(entry.path());
        }
    }
}
