use super::*;
use crate::store::check_replaceable;

#[cfg(unix)]
#[test]
fn folder_names_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    for tail in ["city.atlastree/", "new/.", "new/..", "."] {
        let out = format!("{}/{tail}", dir.path().display());
        let err = check_replaceable(Path::new(&out)).unwrap_err();
        assert!(
            matches!(err, StoreError::FolderName { .. }),
            "{tail}: {err}"
        );
        assert!(err.to_string().contains("not a folder's"), "{err}");
    }
    // A name that only starts with a dot is a file's.
    let out = dir.path().join(".city.atlastree");
    check_replaceable(&out).unwrap();
}

/// A link is written through: the file it names is replaced and the link kept (it was replaced by a
/// regular file, the linked file left stale; fault hunt, session 28).
#[cfg(unix)]
#[test]
fn an_output_behind_a_link_replaces_the_linked_file() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("store")).unwrap();
    let real = dir.path().join("store/city.bin");
    std::fs::write(&real, b"old").unwrap();
    let link = dir.path().join("current.bin");
    std::os::unix::fs::symlink("store/city.bin", &link).unwrap();
    let f = crate::util::AtomicFile::create(&link, 0o644).unwrap();
    std::io::Write::write_all(&mut f.file(), b"new").unwrap();
    f.commit().unwrap();
    assert!(
        std::fs::symlink_metadata(&link)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert_eq!(std::fs::read(&real).unwrap(), b"new");
    // A dangling link: the file it names is created.
    std::fs::remove_file(&real).unwrap();
    let f = crate::util::AtomicFile::create(&link, 0o644).unwrap();
    f.commit().unwrap();
    assert!(real.is_file());
    // A loop is refused, the links kept; a dangling link into a missing folder is refused up front.
    let (a, b) = (dir.path().join("a.bin"), dir.path().join("b.bin"));
    std::os::unix::fs::symlink("b.bin", &a).unwrap();
    std::os::unix::fs::symlink("a.bin", &b).unwrap();
    let e = crate::util::AtomicFile::create(&a, 0o644).err().unwrap();
    assert!(e.to_string().contains("or a loop"), "{e}");
    assert!(
        std::fs::symlink_metadata(&a)
            .unwrap()
            .file_type()
            .is_symlink()
    );
    assert!(check_replaceable(&a).is_err());
    let lost = dir.path().join("lost.bin");
    std::os::unix::fs::symlink("missing/city.bin", &lost).unwrap();
    let e = check_replaceable(&lost).unwrap_err();
    assert!(matches!(e, StoreError::NoOutputDir { .. }), "{e}");
}

#[cfg(unix)]
#[test]
fn device_outputs_are_refused() {
    let err = check_replaceable(Path::new("/dev/null")).unwrap_err();
    assert!(
        err.to_string()
            .contains("a character device, not a regular file"),
        "{err}"
    );
}

#[test]
fn layout_aligns_sections_and_blocks() {
    let counts = [1, 2, 5, 1, 3, 1, 1, 1, 7, 9, 3, 2];
    let (s, tables_end, offsets, end) = layout(&counts, [5000u64, 0, 10].into_iter()).unwrap();
    assert_eq!(s[0].offset, HEADER_SIZE as u64);
    for w in s.windows(2) {
        assert_eq!(w[1].offset % SECTION_ALIGN, 0);
        assert!(w[1].offset >= w[0].offset + w[0].length);
        assert!(w[1].offset < w[0].offset + w[0].length + SECTION_ALIGN);
    }
    assert_eq!(tables_end, s[11].offset + s[11].length);
    assert_eq!(offsets, vec![4096, 12288, 12288]);
    assert_eq!(end, 12298);
}

#[test]
fn layout_reports_overflow() {
    let mut counts = [0; SECTION_COUNT];
    counts[Section::Nodes as usize] = u64::MAX / 50;
    assert!(matches!(
        layout(&counts, std::iter::empty()),
        Err(StoreError::LayoutOverflow { what: "nodes" })
    ));
    let counts = [0; SECTION_COUNT];
    assert!(matches!(
        layout(&counts, [u64::MAX - 10].into_iter()),
        Err(StoreError::LayoutOverflow { what: "blocks" })
    ));
}
