//! Files written atomically ([`AtomicFile`], [`write_atomic`]) and the temps they leave.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

/// A file being written beside its target and published by rename, so a reader of `target` sees the old
/// file or the complete new one, never a part (also when the writer is killed, or two write at once).
///
/// - The temp file is `.<target name>.tmp.<pid>.<random>` in the target's directory, created exclusively
///   (`O_EXCL`): concurrent writers of one target never share a temp file. It is locked (advisory,
///   `flock`) for the writer's life.
/// - Dropping an uncommitted `AtomicFile` (an error, a panic) removes the temp file. A writer that was
///   killed leaves it; the next [`AtomicFile::create`] for the same target removes such stale temps (those
///   whose process is gone and whose lock is free) before creating its own.
/// - [`AtomicFile::commit`] fsyncs the file, renames it over the target and fsyncs the directory (unix),
///   so after it returns the new file survives a crash.
pub struct AtomicFile {
    target: PathBuf,
    temp: tempfile::NamedTempFile,
    /// Dropped after `temp` (declaration order): the temp file is removed, then forgotten.
    _live: LiveTemp,
}

/// The temp files and folders of this process's live [`AtomicFile`]s and [`LiveTempDir`]s, for
/// [`remove_live_temps`]; `true` marks a folder the work created above its temp folder, removed only if
/// empty.
static LIVE_TEMPS: std::sync::Mutex<Vec<(PathBuf, bool)>> = std::sync::Mutex::new(Vec::new());

fn live_temps() -> std::sync::MutexGuard<'static, Vec<(PathBuf, bool)>> {
    LIVE_TEMPS.lock().unwrap_or_else(|e| e.into_inner())
}

/// One entry of [`LIVE_TEMPS`], removed when the [`AtomicFile`] holding it goes (committed or dropped).
struct LiveTemp(PathBuf, bool);

impl LiveTemp {
    fn register(path: &Path) -> LiveTemp {
        Self::register_as(path, false)
    }

    fn register_as(path: &Path, if_empty: bool) -> LiveTemp {
        Self::register_in(&mut live_temps(), path, if_empty)
    }

    /// [`Self::register_as`] in a registry whose lock the caller holds.
    fn register_in(live: &mut Vec<(PathBuf, bool)>, path: &Path, if_empty: bool) -> LiveTemp {
        live.push((path.to_path_buf(), if_empty));
        LiveTemp(path.to_path_buf(), if_empty)
    }
}

impl Drop for LiveTemp {
    fn drop(&mut self) {
        let mut live = live_temps();
        if let Some(i) = live.iter().position(|(p, e)| *p == self.0 && *e == self.1) {
            live.swap_remove(i);
        }
    }
}

/// Removes the temp file of every [`AtomicFile`] of this process not yet committed; returns how many. For a
/// handler of Ctrl-C or SIGTERM (a scheduler cancelling a job) that then ends the process, so an
/// interrupted build leaves no temp file (a killed one, SIGKILL, still leaves its temp to the next
/// [`AtomicFile::create`] of the same target: [`remove_stale_temps`]).
/// Folders created above a temp folder go last, deepest first, and only if empty.
pub fn remove_live_temps() -> usize {
    remove_listed(&live_temps())
}

/// [`remove_live_temps`] for a handler of Ctrl-C or SIGTERM: `say` is told how many were removed and
/// how many committed outputs are still there, with the last ([`kept_outputs`]), then `end` ends the
/// process while it still holds the registry's lock, so a temp that [`AtomicFile::create`] (which
/// creates and registers under that lock) was making is either removed here or never made (one created
/// while the handler ran stayed behind; fault hunt, session 28).
pub fn remove_live_temps_and_exit(
    end: impl FnOnce() -> std::convert::Infallible,
    say: impl FnOnce(usize, Option<&(usize, PathBuf)>),
) -> ! {
    let live = live_temps();
    let committed = committed();
    let removed = remove_listed(&live);
    say(removed, kept_outputs(&committed).as_ref());
    match end() {}
}

/// The targets of the [`AtomicFile`]s this process committed, in order.
static COMMITTED: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn committed() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    COMMITTED.lock().unwrap_or_else(|e| e.into_inner())
}

/// How many of the `committed` outputs are still there, and the last of them: a sweep's build is
/// committed and then deleted once measured, or removed as a [`LiveTempFile`] by the interrupt, and was
/// named "left in place" (fault hunt, session 31).
fn kept_outputs(committed: &[PathBuf]) -> Option<(usize, PathBuf)> {
    // A target committed twice (`render` writes its summary twice) is one output, last at its last commit.
    let mut kept: Vec<&PathBuf> = Vec::new();
    for p in committed.iter().rev() {
        if !kept.contains(&p) && p.exists() {
            kept.push(p);
        }
    }
    kept.first().map(|last| (kept.len(), (*last).clone()))
}

/// Removes `live`'s temps (see [`remove_live_temps`]).
fn remove_listed(live: &[(PathBuf, bool)]) -> usize {
    let removed = live
        .iter()
        .filter(|(p, if_empty)| {
            if *if_empty {
                false
            } else if p.is_dir() {
                remove_dir_under_writers(p)
            } else {
                std::fs::remove_file(p).is_ok()
            }
        })
        .count();
    let mut parents: Vec<&PathBuf> = live.iter().filter(|e| e.1).map(|e| &e.0).collect();
    parents.sort_by_key(|p| std::cmp::Reverse(p.components().count()));
    for p in parents {
        let _ = std::fs::remove_dir(p);
    }
    removed
}

/// Removes folder `p` while other threads may still be writing into it (an export interrupted by a
/// signal): renamed aside first, so writers that create files by path fail instead of refilling it
/// (`remove_dir_all` of the live folder could meet new entries and give up, leaving it), then removed.
fn remove_dir_under_writers(p: &Path) -> bool {
    let mut aside = p.as_os_str().to_owned();
    aside.push(".removing");
    let target = if std::fs::rename(p, &aside).is_ok() {
        PathBuf::from(aside)
    } else {
        p.to_path_buf()
    };
    (0..3).any(|_| remove_dir_tree(&target).is_ok() || !target.exists())
}

/// `std::fs::remove_dir_all`, and where the open-files limit stops it (it holds a descriptor a level;
/// a failed export under `ulimit -n` left its partial folder: fault hunt, session 38) the same walk
/// holding one descriptor at a time: each folder's entries listed and closed before any is removed.
pub fn remove_dir_tree(p: &Path) -> std::io::Result<()> {
    match std::fs::remove_dir_all(p) {
        Err(e) if is_out_of_descriptors(&e) => remove_dir_tree_listed(p),
        other => other,
    }
}

/// [`remove_dir_tree`]'s walk by listed entries; a link is removed, not followed.
fn remove_dir_tree_listed(p: &Path) -> std::io::Result<()> {
    if std::fs::symlink_metadata(p)?.file_type().is_symlink() {
        return std::fs::remove_file(p);
    }
    // Paths, not `DirEntry`s: each holds its folder's descriptor open.
    let entries = (std::fs::read_dir(p)?)
        .map(|e| e.and_then(|e| Ok((e.path(), e.file_type()?.is_dir()))))
        .collect::<std::io::Result<Vec<_>>>()?;
    for (path, dir) in entries {
        if dir {
            remove_dir_tree_listed(&path)?;
        } else {
            std::fs::remove_file(path)?;
        }
    }
    std::fs::remove_dir(p)
}

/// A finished file the work deletes when done with it (a sweep's build without `--keep-builds`), which
/// [`remove_live_temps`] removes if the process is interrupted while this guard lives (an interrupted
/// sweep left its 83 MB build). Dropping the guard only forgets the file.
pub struct LiveTempFile {
    _live: LiveTemp,
}

impl LiveTempFile {
    pub fn register(path: &Path) -> LiveTempFile {
        LiveTempFile {
            _live: LiveTemp::register(path),
        }
    }
}

/// A temp directory (an export being written) that [`remove_live_temps`] removes with its contents if the
/// process is interrupted while this guard lives. Dropping the guard only forgets the directory.
pub struct LiveTempDir {
    _live: LiveTemp,
    _parents: LiveMadeFolders,
}

impl LiveTempDir {
    pub fn register(path: &Path) -> LiveTempDir {
        Self::register_with_parents(path, &[])
    }

    /// [`Self::register`], and `parents`: folders the work created above `path`, removed after it
    /// (deepest first) if they are empty then.
    pub fn register_with_parents(path: &Path, parents: &[PathBuf]) -> LiveTempDir {
        LiveTempDir {
            _live: LiveTemp::register(path),
            _parents: LiveMadeFolders::register(parents),
        }
    }
}

/// Folders a run made for its outputs (an `--out`, the folders above it, a folder it makes inside),
/// which [`remove_live_temps`] removes, deepest first and only if empty, if the process is interrupted
/// while this guard lives: a sweep interrupted by Ctrl-C left its new `--out` with an empty `builds/`
/// (fault hunt, session 37). Registered before the folders are made (an empty one is all it removes).
/// Dropping the guard only forgets them.
pub struct LiveMadeFolders {
    _live: Vec<LiveTemp>,
}

impl LiveMadeFolders {
    pub fn register(folders: &[PathBuf]) -> LiveMadeFolders {
        LiveMadeFolders {
            _live: (folders.iter())
                .map(|p| LiveTemp::register_as(p, true))
                .collect(),
        }
    }
}

/// The output path `path` names with its symbolic links followed (a dangling link gives the path it
/// names), so a file is written where a link points. Refused ([`std::io::ErrorKind::InvalidInput`]): a
/// chain of more than 40 links or a loop (the kernel's limit), and, as the kernel's
/// `protected_symlinks` does, a link in a sticky world-writable folder (`/tmp`) owned neither by the
/// folder's owner nor by this process's user (Linux: `/proc/self`'s owner) — another user's link there
/// could point a build's output anywhere its user may write.
pub fn follow_output_links(path: &Path) -> std::io::Result<PathBuf> {
    let refuse = |why: String| std::io::Error::new(std::io::ErrorKind::InvalidInput, why);
    let mut p = path.to_path_buf();
    for _ in 0..=40 {
        let Ok(meta) = std::fs::symlink_metadata(&p) else {
            return Ok(p);
        };
        if !meta.file_type().is_symlink() {
            return Ok(p);
        }
        #[cfg(unix)]
        {
            use std::os::unix::fs::MetadataExt;
            let dir = std::fs::metadata(parent_dir(&p))?;
            let shared = dir.mode() & 0o1002 == 0o1002;
            let user = std::fs::metadata("/proc/self").map(|m| m.uid()).ok();
            if shared && meta.uid() != dir.uid() && Some(meta.uid()) != user {
                return Err(refuse(format!(
                    "{} is a symbolic link in a shared folder (sticky, writable by all) that its owner \
                     did not make: not followed; remove it or choose another output",
                    p.display()
                )));
            }
        }
        let to = std::fs::read_link(&p)?;
        p = if to.is_absolute() {
            to
        } else {
            parent_dir(&p).join(to)
        };
    }
    Err(refuse(format!(
        "{}: more than 40 symbolic links, or a loop",
        path.display()
    )))
}

/// The directory `path` lives in (`.` for a bare name).
pub fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The prefix of every temp file of `target`: `.<name>.tmp.`.
fn temp_prefix(target: &Path) -> String {
    let name = target
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    format!(".{name}.tmp.")
}

/// Whether process `pid` (not this one) may still run: `/proc/<pid>` exists and is not a zombie (Linux:
/// a SIGKILLed build whose parent has not yet collected it stays in `/proc` as state `Z`, and its temp
/// was kept as a live writer's; fault hunt, session 36); elsewhere always `true` (then a stale temp is
/// left for the user, never a live one removed).
pub fn process_may_run(pid: u32) -> bool {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return true;
    }
    match std::fs::read_to_string(proc.join(pid.to_string()).join("stat")) {
        // `pid (comm) S …`: the state follows the last `)` (a command name may hold one).
        Ok(stat) => stat
            .rsplit_once(')')
            .and_then(|(_, rest)| rest.trim_start().chars().next())
            .is_none_or(|state| !matches!(state, 'Z' | 'X')),
        Err(_) => proc.join(pid.to_string()).exists(),
    }
}

/// The process id of a writer writing `target` now: a temp file of it ([`temp_prefix`], beside the
/// target its output links name) whose lock another holder has (the writer holds it for its life: a
/// dead one's is let go). `None` where none is, and where locks are not supported (a dead writer's temp
/// is then not taken for a live one).
pub fn writer_of(target: &Path) -> Option<u32> {
    let target = follow_output_links(target).unwrap_or_else(|_| target.to_path_buf());
    let prefix = temp_prefix(&target);
    let entries = std::fs::read_dir(parent_dir(&target)).ok()?;
    entries.flatten().find_map(|entry| {
        let name = entry.file_name().to_string_lossy().into_owned();
        let pid = name
            .strip_prefix(&prefix)?
            .split('.')
            .next()?
            .parse()
            .ok()?;
        // A held lock is a live holder, here or on another machine of a shared filesystem, whose
        // processes this one cannot see (a merge on another node called a running shard missing).
        let held = open_to_lock(&entry.path())
            .is_ok_and(|f| matches!(f.try_lock(), Err(std::fs::TryLockError::WouldBlock)));
        held.then_some(pid)
    })
}

/// Removes the temp files of `target` left by writers that were killed: named by [`temp_prefix`], their
/// pid gone and their lock free. A temp named with this process's own pid that this process is not
/// writing is another process's that had the same pid — a container's PID 1, a retried Kubernetes pod,
/// a killed Job writing to the same volume — and goes by its lock alone (a killed shard pod's temp, the
/// size of the shard, was never removed: `/proc/1` always exists; fault hunt, session 32). Returns how
/// many were removed. Errors (a racing remover, permissions) only leave a temp in place.
pub fn remove_stale_temps(target: &Path) -> usize {
    let prefix = temp_prefix(target);
    let Ok(entries) = std::fs::read_dir(parent_dir(target)) else {
        return 0;
    };
    let mut removed = 0;
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        let Some(rest) = name.strip_prefix(&prefix) else {
            continue;
        };
        let Some(pid) = rest.split('.').next().and_then(|p| p.parse::<u32>().ok()) else {
            continue;
        };
        let path = entry.path();
        if pid == std::process::id() {
            if live_temps().iter().any(|(p, _)| *p == path) {
                continue;
            }
        } else if process_may_run(pid) {
            continue;
        }
        // A free lock confirms the owner is gone (another pid namespace may share the directory).
        let free = lock_is_free(&path);
        if free && std::fs::remove_file(&path).is_ok() {
            removed += 1;
        }
    }
    removed
}

impl AtomicFile {
    /// Creates the temp file for `target` (whose directory must exist) with unix permissions `mode` less
    /// the umask, after removing stale temps of `target` ([`remove_stale_temps`]).
    ///
    /// A target that exists and is not a regular file (a directory, device, FIFO or socket, also behind a
    /// symlink) is refused with [`std::io::ErrorKind::InvalidInput`]: the rename would replace the node
    /// itself (`-o /dev/null` run as root would delete `/dev/null`).
    pub fn create(target: &Path, mode: u32) -> std::io::Result<AtomicFile> {
        // A link is written through: the file it names is replaced, the link kept (renamed over, the
        // link became a regular file and the file it named stayed stale; fault hunt, session 28).
        let target = &follow_output_links(target)?;
        if let Ok(meta) = std::fs::metadata(target)
            && !meta.is_file()
        {
            return Err(std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{} exists and is not a regular file: refusing to replace it",
                    target.display()
                ),
            ));
        }
        remove_stale_temps(target);
        let prefix = format!("{}{}.", temp_prefix(target), std::process::id());
        let mut builder = tempfile::Builder::new();
        builder.prefix(&prefix).rand_bytes(8);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            builder.permissions(std::fs::Permissions::from_mode(mode));
        }
        #[cfg(not(unix))]
        let _ = mode;
        let dir = parent_dir(target);
        // Created and registered under one hold of the registry's lock: an interrupt's
        // `remove_live_temps_and_exit` sees this temp, or ends the process before it is made.
        let mut registry = live_temps();
        let temp = builder.tempfile_in(dir).map_err(|e| {
            // tempfile's error names the random temp path (`at path ".x.tmp.123.AbC"`), which means
            // nothing to a user: say which folder refused, with the OS's own words.
            let text = e.to_string();
            let cause = text.split(" at path \"").next().unwrap_or(&text);
            std::io::Error::new(
                e.kind(),
                format!("cannot create a file in {}: {cause}", dir.display()),
            )
        })?;
        // Best effort: where advisory locks are unsupported the pid alone guards the temp.
        let _ = temp.as_file().try_lock();
        let live = LiveTemp::register_in(&mut registry, temp.path(), false);
        drop(registry);
        Ok(AtomicFile {
            target: target.to_path_buf(),
            temp,
            _live: live,
        })
    }

    /// The open temp file (write through it: `Write for &File`, or positional writes).
    pub fn file(&self) -> &File {
        self.temp.as_file()
    }

    /// The temp file's path.
    pub fn temp_path(&self) -> &Path {
        self.temp.path()
    }

    /// The path the file will appear at.
    pub fn target(&self) -> &Path {
        &self.target
    }

    /// Fsyncs the temp file, renames it over the target (replacing any file there: readers that hold the
    /// old one open keep it) and fsyncs the directory. On error the temp file is removed and the target
    /// is untouched.
    pub fn commit(self) -> std::io::Result<()> {
        self.temp.as_file().sync_all()?;
        let AtomicFile { target, temp, .. } = self;
        {
            // Under the registry's lock, so an interrupt's handler ([`remove_live_temps_and_exit`])
            // runs before the rename or after it is recorded: one after it said "stopped before
            // finishing" of a complete output (fault hunt, session 31).
            let _live = live_temps();
            temp.persist(&target).map_err(|e| e.error)?;
            let mut done = committed();
            // Once per target, last where it was last committed (a `view` session saves one path often).
            done.retain(|p| *p != target);
            done.push(target.clone());
        }
        sync_dir(parent_dir(&target))
    }
}

/// Removes the files directly in `dir` whose names `stale` picks (an earlier run's outputs that this run
/// may not overwrite: frames past its count, plots it does not draw), so the folder holds one run's
/// outputs. Returns how many were removed; a missing folder removes nothing.
pub fn remove_stale_outputs(dir: &Path, stale: impl Fn(&str) -> bool) -> std::io::Result<usize> {
    let entries = match std::fs::read_dir(dir) {
        Ok(e) => e,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(0),
        Err(e) => return Err(e),
    };
    let mut removed = 0;
    for entry in entries {
        let entry = entry?;
        let name = entry.file_name();
        if entry.file_type()?.is_file() && name.to_str().is_some_and(&stale) {
            std::fs::remove_file(entry.path())?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// [`remove_stale_outputs`] only where `marker` (the report an earlier run of the same command wrote, such
/// as its `summary.csv`) is a file: a folder no run of it reported into holds no outputs of its, only the
/// user's (render deleted a user's `frame_holiday.png`; fault hunt, session 34).
pub fn remove_earlier_outputs(
    dir: &Path,
    marker: &Path,
    stale: impl Fn(&str) -> bool,
) -> std::io::Result<usize> {
    if !marker.is_file() {
        return Ok(0);
    }
    remove_stale_outputs(dir, stale)
}

/// Whether the lock of the file at `path` is free (taken and let go here): its writer is gone. `false`
/// where the file cannot be opened or the lock is held.
pub fn lock_is_free(path: &Path) -> bool {
    open_to_lock(path).is_ok_and(|f| f.try_lock().is_ok())
}

/// `path` opened to ask for its lock: for writing where allowed (NFS emulates `flock` with POSIX locks,
/// and an exclusive one needs a file open for writing: opened read-only, every lock there seemed held, so
/// no stale temp or export lock was ever removed; review, session 39), else for reading. Never created.
fn open_to_lock(path: &Path) -> std::io::Result<File> {
    std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open(path)
        .or_else(|_| File::open(path))
}

/// Writes go to the temp file (so a `BufWriter<AtomicFile>` streams into it).
impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.temp.as_file().write(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.temp.as_file().flush()
    }
}

/// Makes a rename in `dir` durable (unix: fsync the directory). A no-op elsewhere.
fn sync_dir(dir: &Path) -> std::io::Result<()> {
    #[cfg(unix)]
    File::open(dir)?.sync_all()?;
    #[cfg(not(unix))]
    let _ = dir;
    Ok(())
}

/// Writes `bytes` to `path` atomically ([`AtomicFile`]), readable by all (0o644 less the umask, like a
/// plain `File::create`). The parent directory must exist.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let file = AtomicFile::create(path, 0o644)?;
    file.file().write_all(bytes)?;
    file.commit()
}

/// Writes `img` as a PNG at `path` atomically (encoded in memory, then [`write_atomic`]): a failed write
/// (a full disk, Ctrl-C) leaves the old file or none, never a truncated picture.
pub fn save_png(path: &Path, img: &image::RgbaImage) -> std::io::Result<()> {
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(std::io::Error::other)?;
    write_atomic(path, &bytes)
}

/// Whether `e` is the process's or the system's open-files limit (`EMFILE`, `ENFILE`; on Windows
/// `ERROR_TOO_MANY_OPEN_FILES`): a limit of the machine, not a fault of the file being opened.
pub fn is_out_of_descriptors(e: &std::io::Error) -> bool {
    #[cfg(unix)]
    return matches!(e.raw_os_error(), Some(libc::EMFILE | libc::ENFILE));
    // ERROR_TOO_MANY_OPEN_FILES, and WSAEMFILE from a socket's accept.
    #[cfg(windows)]
    return matches!(e.raw_os_error(), Some(4 | 10024));
    #[cfg(not(any(unix, windows)))]
    {
        let _ = e;
        false
    }
}

/// [`is_out_of_descriptors`], or the kernel out of memory for it (`ENOBUFS`, `ENOMEM`): what a server
/// that cannot accept connections should say, where a reset connection is routine.
pub fn is_resource_exhaustion(e: &std::io::Error) -> bool {
    #[cfg(unix)]
    if matches!(e.raw_os_error(), Some(libc::ENOBUFS | libc::ENOMEM)) {
        return true;
    }
    // WSAENOBUFS.
    #[cfg(windows)]
    if e.raw_os_error() == Some(10055) {
        return true;
    }
    is_out_of_descriptors(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A commit is recorded under the registry's lock, for the interrupt handler's message: the count
    /// grows; a dropped file leaves nothing.
    #[test]
    fn commits_are_recorded_for_the_interrupt_message() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("out.bin");
        let f = AtomicFile::create(&target, 0o644).unwrap();
        std::io::Write::write_all(&mut f.file(), b"x").unwrap();
        drop(AtomicFile::create(&dir.path().join("dropped.bin"), 0o644).unwrap());
        f.commit().unwrap();
        // Other tests commit in parallel: this target is recorded, the dropped one is not.
        let recorded = committed().clone();
        assert!(recorded.contains(&target), "{recorded:?}");
        assert!(!recorded.contains(&dir.path().join("dropped.bin")));
        assert!(target.exists());
        assert!(!dir.path().join("dropped.bin").exists());
    }

    /// A temp of this process's pid that it is not writing (another container's PID 1 killed mid-write)
    /// is removed once its lock is free; this process's own live temp is kept.
    #[test]
    fn a_temp_of_this_pid_that_this_process_does_not_write_is_stale() {
        let dir = tempfile::tempdir().unwrap();
        let target = dir.path().join("shard.bin");
        let live = AtomicFile::create(&target, 0o644).unwrap();
        let stale = dir.path().join(format!(
            "{}{}.ZZZZZZZZ",
            temp_prefix(&target),
            std::process::id()
        ));
        std::fs::write(&stale, b"left by a killed writer").unwrap();
        assert_eq!(remove_stale_temps(&target), 1);
        assert!(!stale.exists());
        assert!(live.temp_path().exists(), "the live temp was removed");
        drop(live);
    }

    #[test]
    fn outputs_removed_after_their_commit_are_not_counted_as_kept() {
        let dir = tempfile::tempdir().unwrap();
        let [a, b, c] = ["a", "b", "c"].map(|n| dir.path().join(n));
        std::fs::write(&a, b"a").unwrap();
        std::fs::write(&b, b"b").unwrap();
        // `c` was committed last and then deleted (a sweep's measured build).
        let list = [a.clone(), b.clone(), c];
        assert_eq!(kept_outputs(&list), Some((2, b.clone())));
        // A target committed twice is one output.
        assert_eq!(
            kept_outputs(&[a.clone(), b.clone(), a.clone()]),
            Some((2, a.clone()))
        );
        std::fs::remove_file(&a).unwrap();
        std::fs::remove_file(&b).unwrap();
        assert_eq!(kept_outputs(&list), None);
        assert_eq!(kept_outputs(&[]), None);
    }

    #[test]
    #[cfg(unix)]
    fn descriptor_exhaustion_is_told_from_other_errors() {
        let emfile = std::io::Error::from_raw_os_error(libc::EMFILE);
        assert!(is_out_of_descriptors(&emfile) && is_resource_exhaustion(&emfile));
        let enobufs = std::io::Error::from_raw_os_error(libc::ENOBUFS);
        assert!(!is_out_of_descriptors(&enobufs) && is_resource_exhaustion(&enobufs));
        let reset = std::io::Error::from_raw_os_error(libc::ECONNRESET);
        assert!(!is_resource_exhaustion(&reset));
        assert!(!is_out_of_descriptors(&std::io::Error::other("no code")));
    }

    #[test]
    fn stale_outputs_are_the_picked_files_only() {
        let dir = tempfile::tempdir().unwrap();
        for name in [
            "frame_0000.png",
            "frame_0005.png",
            "stats.csv",
            "frame_notes.txt",
        ] {
            std::fs::write(dir.path().join(name), b"x").unwrap();
        }
        std::fs::create_dir(dir.path().join("frame_dir.png")).unwrap();
        let is_frame = |n: &str| n.starts_with("frame_") && n.ends_with(".png");
        assert_eq!(remove_stale_outputs(dir.path(), is_frame).unwrap(), 2);
        let mut left: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["frame_dir.png", "frame_notes.txt", "stats.csv"]);
        assert_eq!(
            remove_stale_outputs(&dir.path().join("none"), is_frame).unwrap(),
            0
        );
    }

    /// [`remove_live_temps`] of the temps under `dir` only: the whole registry holds the temps of every
    /// test running beside this one, and removing them made `commit` fail in another test.
    fn remove_live_temps_in(dir: &Path) -> usize {
        let mine: Vec<(PathBuf, bool)> = (live_temps().iter())
            .filter(|(p, _)| p.starts_with(dir))
            .cloned()
            .collect();
        remove_listed(&mine)
    }

    #[test]
    fn live_temp_dirs_are_removed_with_their_contents_while_registered() {
        let dir = tempfile::tempdir().unwrap();
        let partial = dir.path().join(".tiles.partial-1");
        std::fs::create_dir_all(partial.join("a/b")).unwrap();
        std::fs::write(partial.join("a/b/c.glb"), b"x").unwrap();
        let guard = LiveTempDir::register(&partial);
        assert!(remove_live_temps_in(dir.path()) >= 1);
        assert!(!partial.exists());
        drop(guard);
        std::fs::create_dir(&partial).unwrap();
        remove_live_temps_in(dir.path());
        assert!(partial.exists(), "a dropped guard forgets its folder");
    }

    /// An export interrupted by a signal leaves no folder it created above its temp folder (SIGTERM left
    /// `new/deep/` behind: only the error path removed them); a parent that holds something else stays.
    #[test]
    fn live_temp_dirs_take_the_empty_parents_they_created() {
        let dir = tempfile::tempdir().unwrap();
        let (new, deep) = (dir.path().join("new"), dir.path().join("new/deep"));
        let partial = deep.join(".out.partial-1");
        std::fs::create_dir_all(partial.join("x")).unwrap();
        let guard = LiveTempDir::register_with_parents(&partial, &[deep.clone(), new.clone()]);
        remove_live_temps_in(dir.path());
        assert!(!new.exists(), "{}", new.display());
        drop(guard);
        std::fs::create_dir_all(partial.join("x")).unwrap();
        std::fs::write(new.join("keep.txt"), b"x").unwrap();
        let guard = LiveTempDir::register_with_parents(&partial, &[deep.clone(), new.clone()]);
        remove_live_temps_in(dir.path());
        assert!(!deep.exists() && new.join("keep.txt").exists());
        drop(guard);
    }

    /// A process that ended but was not yet collected by its parent (a zombie: a SIGKILLed build under a
    /// parent that has not waited) does not run; one that runs does.
    #[cfg(target_os = "linux")]
    #[test]
    fn a_zombie_does_not_run() {
        let mut live = std::process::Command::new("sleep")
            .arg("30")
            .spawn()
            .unwrap();
        assert!(process_may_run(live.id()));
        live.kill().unwrap();
        let _ = live.wait();
        let mut done = std::process::Command::new("true").spawn().unwrap();
        let stat = format!("/proc/{}/stat", done.id());
        let started = std::time::Instant::now();
        while !std::fs::read_to_string(&stat).is_ok_and(|s| s.contains(") Z")) {
            assert!(started.elapsed().as_secs() < 30, "no zombie within 30 s");
            std::thread::sleep(std::time::Duration::from_millis(5));
        }
        assert!(!process_may_run(done.id()), "a zombie");
        done.wait().unwrap();
        assert!(!process_may_run(done.id()), "collected");
    }

    #[test]
    fn a_temp_file_that_cannot_be_created_names_the_folder_not_the_temp() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("gone");
        let err = AtomicFile::create(&missing.join("x.atlastree"), 0o644)
            .err()
            .unwrap();
        let msg = err.to_string();
        assert_eq!(err.kind(), std::io::ErrorKind::NotFound, "{msg}");
        assert!(
            msg.starts_with(&format!("cannot create a file in {}: ", missing.display()))
                && !msg.contains("at path")
                && !msg.contains(".tmp."),
            "{msg}"
        );
    }

    #[cfg(unix)]
    #[test]
    fn atomic_file_never_replaces_a_device_or_directory() {
        for target in ["/dev/null", "/tmp"] {
            let err = AtomicFile::create(Path::new(target), 0o644).err().unwrap();
            assert_eq!(err.kind(), std::io::ErrorKind::InvalidInput, "{target}");
        }
        assert!(
            !std::fs::metadata("/dev/null")
                .unwrap()
                .file_type()
                .is_file()
        );
    }
}
