//! Command lines recorded as text (a shard's or plan's "rebuild it with: …" hint) and printed back as
//! shell words that run as typed.
//!
//! A Unix argument is bytes, not text; a file name need not be UTF-8. Recorded lossily (U+FFFD), the
//! hint names another file and fails when run. So [`os_to_recorded`] keeps every byte: valid UTF-8 as
//! itself, each other byte `b` as the private-use character U+10FF00 + `b` (Plane 16's last 256 code
//! points; a real character there is kept as its own UTF-8 bytes, each escaped, so decoding is exact),
//! and [`shell_word`] prints such an argument in bash's `$'…'` quoting with `\xNN` for those bytes.

use std::ffi::OsStr;
use std::path::Path;

/// The first of the 256 code points that stand for one raw byte each in a recorded argument.
const RAW_BYTE: u32 = 0x10_FF00;

fn raw_byte(c: char) -> Option<u8> {
    (c as u32)
        .checked_sub(RAW_BYTE)
        .and_then(|b| u8::try_from(b).ok())
}

/// `s` as recorded text: exact for any bytes (see the module docs); plain UTF-8 arguments unchanged.
pub fn os_to_recorded(s: &OsStr) -> String {
    #[cfg(unix)]
    {
        use std::os::unix::ffi::OsStrExt;
        let mut out = String::with_capacity(s.len());
        for chunk in s.as_bytes().utf8_chunks() {
            for c in chunk.valid().chars() {
                if raw_byte(c).is_some() {
                    let mut buf = [0u8; 4];
                    for &b in c.encode_utf8(&mut buf).as_bytes() {
                        out.push(char::from_u32(RAW_BYTE + u32::from(b)).unwrap_or('\u{FFFD}'));
                    }
                } else {
                    out.push(c);
                }
            }
            for &b in chunk.invalid() {
                out.push(char::from_u32(RAW_BYTE + u32::from(b)).unwrap_or('\u{FFFD}'));
            }
        }
        out
    }
    #[cfg(not(unix))]
    {
        s.to_string_lossy().into_owned()
    }
}

/// A path as recorded text ([`os_to_recorded`]).
pub fn path_to_recorded(p: &Path) -> String {
    os_to_recorded(p.as_os_str())
}

/// One recorded argument as a shell word: as is when it holds only `[A-Za-z0-9-_./=:,]`, in single quotes
/// when it is text, in bash's `$'…'` with `\xNN` escapes when it holds raw bytes or control characters.
pub fn shell_word(arg: &str) -> String {
    if !arg.is_empty()
        && arg
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./=:,".contains(c))
    {
        return arg.to_string();
    }
    // Raw bytes and control characters (a newline, ESC: printed as they are, they would act on the
    // terminal that shows the hint) only in `$'…'`, escaped.
    if !arg.chars().any(|c| raw_byte(c).is_some() || c.is_control()) {
        return format!("'{}'", arg.replace('\'', "'\\''"));
    }
    let mut out = String::from("$'");
    for c in arg.chars() {
        match (raw_byte(c), c) {
            (Some(b), _) => out.push_str(&format!("\\x{b:02x}")),
            (None, '\\' | '\'') => {
                out.push('\\');
                out.push(c);
            }
            (None, c) if c.is_ascii_control() => out.push_str(&format!("\\x{:02x}", c as u32)),
            (None, c) if c.is_control() => out.push_str(&format!("\\u{:04x}", c as u32)),
            (None, c) => out.push(c),
        }
    }
    out.push('\'');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plain_and_text_words() {
        assert_eq!(shell_word("--shard=1/4"), "--shard=1/4");
        assert_eq!(shell_word("a b"), "'a b'");
        assert_eq!(shell_word("it's"), "'it'\\''s'");
        assert_eq!(shell_word(""), "''");
        assert_eq!(shell_word("straße"), "'straße'");
        // Control characters are escaped, never printed raw.
        assert_eq!(shell_word("a\nb\u{1b}c\u{85}"), "$'a\\x0ab\\x1bc\\u0085'");
    }

    #[cfg(unix)]
    #[test]
    fn raw_bytes_survive_and_print_as_escapes() {
        use std::os::unix::ffi::OsStrExt;
        let name = OsStr::from_bytes(b"sc\xff 'x'.gltf");
        let recorded = os_to_recorded(name);
        assert_eq!(shell_word(&recorded), "$'sc\\xff \\'x\\'.gltf'");
        // A real character among the 256 escapes is kept as its own bytes, not mistaken for one.
        let tricky = "a\u{10FF41}";
        let recorded = os_to_recorded(OsStr::new(tricky));
        assert_eq!(shell_word(&recorded), "$'a\\xf4\\x8f\\xbd\\x81'");
        assert_eq!(os_to_recorded(OsStr::new("plain/x.gltf")), "plain/x.gltf");
    }
}
