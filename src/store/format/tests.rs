use super::*;

#[test]
fn section_record_sizes_match_types() {
    assert_eq!(Section::Nodes.record_size(), 104);
    assert_eq!(Section::Vertices.record_size(), 32);
    assert_eq!(Section::Blocks.record_size(), 48);
    for (i, s) in Section::ALL.iter().enumerate() {
        assert_eq!(*s as usize, i, "{}", s.name());
    }
}

#[test]
fn align_up_rounds_and_detects_overflow() {
    assert_eq!(align_up(0, 16), Some(0));
    assert_eq!(align_up(1, 16), Some(16));
    assert_eq!(align_up(4096, 4096), Some(4096));
    assert_eq!(align_up(4097, 4096), Some(8192));
    assert_eq!(align_up(u64::MAX - 3, 16), None);
}

#[test]
fn header_checksum_covers_every_byte_but_itself() {
    let mut h = Header::zeroed();
    h.magic = MAGIC;
    let base = h.compute_checksum();
    h.checksum = 12345;
    assert_eq!(h.compute_checksum(), base, "checksum field is excluded");
    let mut bytes = bytemuck::bytes_of(&h).to_vec();
    for i in 0..HEADER_SIZE - 8 {
        bytes[i] ^= 1;
        let flipped: Header = bytemuck::pod_read_unaligned(&bytes);
        assert_ne!(flipped.compute_checksum(), base, "byte {i}");
        bytes[i] ^= 1;
    }
}

#[test]
fn enum_codes_roundtrip() {
    for up in [UpAxis::X, UpAxis::Y, UpAxis::Z] {
        assert_eq!(decode_up(encode_up(up)), Some(up));
    }
    for w in [Wrap::Repeat, Wrap::MirroredRepeat, Wrap::ClampToEdge] {
        assert_eq!(decode_wrap(encode_wrap(w)), Some(w));
    }
    assert_eq!(decode_up(3), None);
    assert_eq!(decode_wrap(3), None);
    let b = BlockRecord {
        kind: 2,
        ..BlockRecord::default()
    };
    assert_eq!(b.block_kind(), None);
}
