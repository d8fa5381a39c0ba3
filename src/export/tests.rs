//! Unit tests of the export's finishing step.

use super::replace::replace_dir;
use super::*;

/// Without `--force` the finished export never replaces what appeared at OUT while it ran: a
/// non-empty folder or a file is kept and refused, an empty folder is replaced; with `--force` the
/// folder is replaced and a file still refused.
#[test]
fn finishing_replaces_only_what_force_allows() {
    let dir = tempfile::tempdir().unwrap();
    let (temp, out) = (dir.path().join(".out.partial"), dir.path().join("out"));
    let fresh = || {
        std::fs::create_dir_all(&temp).unwrap();
        std::fs::write(temp.join("tileset.json"), b"{}").unwrap();
    };
    fresh();
    std::fs::create_dir(&out).unwrap();
    std::fs::write(out.join("notes.txt"), b"mine").unwrap();
    let err = replace_dir(&temp, &out, "out", "1-0", false).unwrap_err();
    assert!(matches!(err, ExportError::Exists { .. }), "{err}");
    assert_eq!(std::fs::read(out.join("notes.txt")).unwrap(), b"mine");
    replace_dir(&temp, &out, "out", "1-0", true).unwrap();
    assert!(out.join("tileset.json").exists() && !out.join("notes.txt").exists());
    // An empty folder is replaced without --force.
    std::fs::remove_dir_all(&out).unwrap();
    std::fs::create_dir(&out).unwrap();
    fresh();
    replace_dir(&temp, &out, "out", "1-0", false).unwrap();
    assert!(out.join("tileset.json").exists());
    // A file at OUT is refused either way and kept.
    std::fs::remove_dir_all(&out).unwrap();
    std::fs::write(&out, b"file").unwrap();
    fresh();
    for force in [false, true] {
        let err = replace_dir(&temp, &out, "out", "1-0", force).unwrap_err();
        assert!(
            matches!(err, ExportError::BadOutput { .. }),
            "{force}: {err}"
        );
        assert_eq!(std::fs::read(&out).unwrap(), b"file");
    }
}
