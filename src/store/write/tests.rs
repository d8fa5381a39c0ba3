use super::*;

#[cfg(unix)]
#[test]
fn folder_names_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let out = format!("{}/city.atlastree/", dir.path().display());
    let err = check_replaceable(Path::new(&out)).unwrap_err();
    assert!(err.to_string().contains("drop the trailing /"), "{err}");
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
