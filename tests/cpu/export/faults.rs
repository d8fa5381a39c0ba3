//! `export 3dtiles` against what is already there: an existing directory is refused and kept, a failed
//! export leaves nothing, `--force` replaces an earlier export (through a link too) and never the folder
//! that holds the input.

use super::*;

#[test]
fn an_existing_directory_is_kept_and_a_failed_export_leaves_nothing() {
    let file = TreeFile::open(&city().1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("tiles");
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("keep.txt"), b"mine").unwrap();
    let e = export_3dtiles(&file, &out, &ExportOptions::default(), NO_PROGRESS).unwrap_err();
    assert!(e.to_string().contains("not an earlier export"), "{e}");
    assert_eq!(std::fs::read(out.join("keep.txt")).unwrap(), b"mine");
    // Nor with --force: it replaces only an earlier export (fault hunt, session 34: it deleted a
    // scene's folder).
    let forced = forced();
    let e = export_3dtiles(&file, &out, &forced, NO_PROGRESS).unwrap_err();
    assert!(e.to_string().contains("not an earlier export"), "{e}");
    assert_eq!(std::fs::read(out.join("keep.txt")).unwrap(), b"mine");
    // An earlier export (with a file of the user's beside it) is replaced as a whole.
    std::fs::remove_file(out.join("keep.txt")).unwrap();
    export_3dtiles(&file, &out, &ExportOptions::default(), NO_PROGRESS).unwrap();
    std::fs::write(out.join("keep.txt"), b"mine").unwrap();
    // Without --force it is offered, not done.
    let e = export_3dtiles(&file, &out, &ExportOptions::default(), NO_PROGRESS).unwrap_err();
    assert!(e.to_string().contains("pass --force"), "{e}");
    export_3dtiles(&file, &out, &forced, NO_PROGRESS).unwrap();
    assert!(!out.join("keep.txt").exists() && out.join("tileset.json").is_file());
    // Never into a file, nor into a path that names no directory of its own (`.`: replacing it would
    // remove the user's files).
    let a_file = dir.path().join("a_file");
    std::fs::write(&a_file, b"x").unwrap();
    for bad in [
        a_file.as_path(),
        Path::new("."),
        &dir.path().join("tiles/.."),
    ] {
        let e = export_3dtiles(&file, bad, &forced, NO_PROGRESS).unwrap_err();
        assert!(
            matches!(e, atlastree::export::ExportError::BadOutput { .. }),
            "{}: {e}",
            bad.display()
        );
    }
    assert_eq!(std::fs::read(&a_file).unwrap(), b"x");

    // A paging file whose last atlas block is corrupt (checksums are checked on every block load).
    let bad = dir.path().join("bad.atlastree");
    std::fs::copy(&city().1, &bad).unwrap();
    let f = TreeFile::open(&bad).unwrap();
    let rec = f.blocks()[f.tree(0).unwrap().nodes[0].atlas_block as usize];
    drop(f);
    let mut bytes = std::fs::read(&bad).unwrap();
    bytes[rec.offset as usize + 100] ^= 0x5a;
    std::fs::write(&bad, &bytes).unwrap();
    let f = TreeFile::open(&bad).unwrap();
    let out2 = dir.path().join("tiles2");
    let e = export_3dtiles(&f, &out2, &ExportOptions::default(), NO_PROGRESS).unwrap_err();
    assert!(
        e.to_string().contains("checksum") || e.to_string().contains("block"),
        "{e}"
    );
    assert!(!out2.exists());
    // Nor the folders it made above a nested OUT.
    let nested = dir.path().join("n1/n2/tiles");
    export_3dtiles(&f, &nested, &ExportOptions::default(), NO_PROGRESS).unwrap_err();
    assert!(!dir.path().join("n1").exists());
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert!(!left.iter().any(|n| n.contains("partial")), "{left:?}");
}

/// The defaults with `--force`.
fn forced() -> ExportOptions {
    ExportOptions {
        force: true,
        ..ExportOptions::default()
    }
}

/// `--force` onto `DIR/.` replaces DIR (it emptied DIR and then failed on `rmdir("DIR/.")`); onto a folder
/// that holds the paging file being exported it is refused (it deleted the input).
#[test]
fn force_replaces_dir_dot_and_never_the_folder_of_the_input() {
    let dir = tempfile::tempdir().unwrap();
    let forced = forced();
    let file = TreeFile::open(&city().1).unwrap();
    let out = dir.path().join("tiles");
    export_3dtiles(&file, &out, &forced, NO_PROGRESS).unwrap();
    std::fs::write(out.join("old.txt"), b"old").unwrap();
    export_3dtiles(&file, &out.join("."), &forced, NO_PROGRESS).unwrap();
    assert!(out.join("tileset.json").is_file() && !out.join("old.txt").exists());
    let hidden: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(hidden, ["tiles"], "no partial or old folder left");

    let input = out.join("city.atlastree");
    std::fs::copy(&city().1, &input).unwrap();
    let inside = TreeFile::open(&input).unwrap();
    let e = export_3dtiles(&inside, &out, &forced, NO_PROGRESS).unwrap_err();
    assert!(
        e.to_string()
            .contains("holds the paging file being exported"),
        "{e}"
    );
    assert!(input.is_file() && out.join("tileset.json").is_file());
}

/// `-o LINK --force` replaces the export the link names and keeps the link (the link was replaced by a
/// new folder, the linked export left stale; fault hunt, session 28).
#[cfg(unix)]
#[test]
fn force_through_a_link_replaces_the_linked_export() {
    let dir = tempfile::tempdir().unwrap();
    let forced = forced();
    let file = TreeFile::open(&city().1).unwrap();
    let real = dir.path().join("store/tiles");
    std::fs::create_dir_all(&real).unwrap();
    // An earlier export (`--force` replaces nothing else) with a file beside it.
    std::fs::write(real.join("old.txt"), b"old").unwrap();
    std::fs::write(real.join(atlastree::export::EXPORT_REPORT), b"{}").unwrap();
    let link = dir.path().join("current");
    std::os::unix::fs::symlink("store/tiles", &link).unwrap();
    export_3dtiles(&file, &link, &forced, NO_PROGRESS).unwrap();
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(real.join("tileset.json").is_file() && !real.join("old.txt").exists());
}

/// An export that fails while writing names the file at its place under OUT, not under the hidden
/// sibling gone when the command returns, and leaves no partial folder, also where the open-files limit
/// failed it (its cleanup, out of descriptors too, left the folder; fault hunt, session 38). The real
/// binary under `ulimit`: `-f` (file size, 512-byte blocks) and `-n` (open files).
#[cfg(unix)]
#[test]
fn a_failing_export_names_out_and_leaves_nothing_under_os_limits() {
    let dir = tempfile::tempdir().unwrap();
    let export = |limit: &str, name: &str| {
        let o = std::process::Command::new("sh")
            .arg("-c")
            .arg(format!("ulimit {limit} && exec \"$@\""))
            .arg("sh")
            .arg(env!("CARGO_BIN_EXE_atlastree"))
            .args(["export", "3dtiles", "-q", "-o"])
            .arg(dir.path().join(name))
            .arg(&city().1)
            .stdin(std::process::Stdio::null())
            .output()
            .unwrap();
        (
            o.status.success(),
            String::from_utf8_lossy(&o.stderr).into_owned(),
        )
    };
    let left = || -> Vec<String> {
        std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with('.'))
            .collect()
    };
    let (ok, e) = export("-f 100", "big");
    assert!(!ok && e.contains("File too large"), "{e}");
    let named = dir.path().join("big").join("t0");
    assert!(
        e.contains(&*named.to_string_lossy()) && !e.contains(".partial"),
        "{e}"
    );
    assert!(left().is_empty(), "{:?}", left());
    let mut failed = 0;
    for n in 5..=8 {
        let name = format!("t{n}");
        let (ok, e) = export(&format!("-n {n}"), &name);
        failed += usize::from(!ok);
        assert!(ok || !dir.path().join(&name).exists(), "ulimit -n {n}: {e}");
        assert!(left().is_empty(), "ulimit -n {n}: {:?} left; {e}", left());
    }
    assert!(
        failed > 0,
        "no open-files limit from 5 to 8 failed the export"
    );
}

/// A partial export of a process this machine does not run (another node on a shared filesystem) is
/// kept while its lock beside it is held, and removed, with the lock file, once nobody holds it; an export
/// leaves no lock file of its own (fault hunt, session 39: the second node's export deleted the first's
/// live partial folder).
#[test]
#[cfg(target_os = "linux")] // stale partials are found through /proc
fn a_partial_export_another_machine_holds_is_kept() {
    let file = TreeFile::open(&city().1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    // A pid no Linux machine gives out (above the largest pid_max, 2²²).
    let pid = 4_194_305u32;
    let partial = dir.path().join(format!(".tiles.partial-{pid}"));
    std::fs::create_dir(&partial).unwrap();
    std::fs::write(partial.join("tileset.json"), b"{}").unwrap();
    let lock_path = dir.path().join(format!(".tiles.lock-{pid}"));
    let lock = std::fs::File::create(&lock_path).unwrap();
    lock.try_lock().unwrap();
    let out = dir.path().join("tiles");
    export_3dtiles(&file, &out, &ExportOptions::default(), NO_PROGRESS).unwrap();
    assert!(
        partial.join("tileset.json").is_file(),
        "a held partial was removed"
    );
    drop(lock);
    export_3dtiles(&file, &out, &forced(), NO_PROGRESS).unwrap();
    let mut left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    left.sort();
    assert_eq!(
        left,
        ["tiles"],
        "the stale partial and lock, and no lock of this export"
    );
}
