//! The `Range` header of a request for one file (RFC 9110 §14.2), as `atlastree serve` answers it:
//!
//! - no header, another unit than `bytes`, a malformed header (bad syntax, a range with first > last,
//!   non-UTF-8, longer than [`MAX_RANGE_HEADER`] bytes or more than [`MAX_RANGES`] ranges): **ignored**,
//!   the whole file is sent with `200` (RFC 9110 §14.2: "a server MAY ignore the Range header field"; we
//!   do not answer `400`, so a client that sent junk still gets correct bytes);
//! - well-formed, no range satisfiable (every first byte at or past the end, `-0`, an empty file;
//!   numbers past `u64::MAX` are well-formed and saturate, so such a last byte clamps to the file):
//!   `416` with `Content-Range: bytes */LEN`;
//! - well-formed: the satisfiable ranges are clamped to the file, sorted and coalesced (overlapping or
//!   adjacent); one left → `206` for it; several disjoint ones → the whole file with `200` (we send no
//!   `multipart/byteranges`, which RFC 9110 allows a server to decline by ignoring the header).

/// Longest `Range` value read, bytes; a longer one is ignored as malformed.
pub(crate) const MAX_RANGE_HEADER: usize = 1024;
/// Most ranges in one `Range` value; more are ignored as malformed (RFC 9110 §14.2 warns of many small
/// or overlapping ranges as a denial of service).
pub(crate) const MAX_RANGES: usize = 16;

/// How to answer a request for a file of known length.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(crate) enum RangeAnswer {
    /// `200` with the whole file.
    Full,
    /// `206` with bytes `first..=last` (inclusive, within the file).
    Partial { first: u64, last: u64 },
    /// `416`: no range can be satisfied.
    Unsatisfiable,
}

/// The answer to `Range: header` (raw bytes, `None` when absent) for a file of `len` bytes.
pub(crate) fn answer(header: Option<&[u8]>, len: u64) -> RangeAnswer {
    let Some(raw) = header else {
        return RangeAnswer::Full;
    };
    if raw.len() > MAX_RANGE_HEADER {
        return RangeAnswer::Full;
    }
    let Ok(text) = std::str::from_utf8(raw) else {
        return RangeAnswer::Full;
    };
    let Some((unit, set)) = text.trim().split_once('=') else {
        return RangeAnswer::Full;
    };
    if !unit.trim().eq_ignore_ascii_case("bytes") {
        return RangeAnswer::Full;
    }
    let mut ranges: Vec<(u64, u64)> = Vec::new();
    let mut count = 0usize;
    for spec in set.split(',') {
        let spec = spec.trim();
        if spec.is_empty() {
            continue; // RFC 9110 list syntax allows empty elements
        }
        count += 1;
        if count > MAX_RANGES {
            return RangeAnswer::Full;
        }
        let Some(r) = parse_spec(spec) else {
            return RangeAnswer::Full;
        };
        if let Some(r) = satisfiable(r, len) {
            ranges.push(r);
        }
    }
    if count == 0 {
        return RangeAnswer::Full;
    }
    ranges.sort_unstable();
    let mut merged: Vec<(u64, u64)> = Vec::with_capacity(ranges.len());
    for (a, b) in ranges {
        match merged.last_mut() {
            Some(last) if a <= last.1.saturating_add(1) => last.1 = last.1.max(b),
            _ => merged.push((a, b)),
        }
    }
    match merged.as_slice() {
        [] => RangeAnswer::Unsatisfiable,
        [(first, last)] => RangeAnswer::Partial {
            first: *first,
            last: *last,
        },
        _ => RangeAnswer::Full,
    }
}

/// One range spec: `a-b`, `a-` or `-n`.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
enum Spec {
    Bounded(u64, u64),
    From(u64),
    Suffix(u64),
}

/// A decimal number; one past `u64::MAX` (still well-formed: RFC 9110 bounds no digit count) saturates,
/// so a last byte past 2⁶⁴ clamps to the file's end and a first byte there is unsatisfiable.
fn digits(s: &str) -> Option<u64> {
    let s = s.trim();
    if s.is_empty() || !s.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    Some(s.parse().unwrap_or(u64::MAX))
}

fn parse_spec(spec: &str) -> Option<Spec> {
    let (a, b) = spec.split_once('-')?;
    match (a.trim().is_empty(), b.trim().is_empty()) {
        (true, true) => None,
        (true, false) => digits(b).map(Spec::Suffix),
        (false, true) => digits(a).map(Spec::From),
        (false, false) => {
            let (a, b) = (digits(a)?, digits(b)?);
            (a <= b).then_some(Spec::Bounded(a, b))
        }
    }
}

/// The bytes of `spec` within a file of `len` bytes, `None` when it holds none.
fn satisfiable(spec: Spec, len: u64) -> Option<(u64, u64)> {
    let end = len.checked_sub(1)?;
    match spec {
        Spec::Bounded(a, b) => (a <= end).then(|| (a, b.min(end))),
        Spec::From(a) => (a <= end).then_some((a, end)),
        Spec::Suffix(0) => None,
        Spec::Suffix(n) => Some((len.saturating_sub(n), end)),
    }
}

#[cfg(test)]
mod tests {
    use super::RangeAnswer::{Full, Partial, Unsatisfiable};
    use super::*;

    fn a(h: &str, len: u64) -> RangeAnswer {
        answer(Some(h.as_bytes()), len)
    }

    #[test]
    fn single_ranges_clamp_to_the_file() {
        // Numbers past 2⁶⁴ are well-formed: the last byte clamps, a first byte there is past the end.
        let huge = b"bytes=0-99999999999999999999999";
        assert_eq!(answer(Some(huge), 100), Partial { first: 0, last: 99 });
        assert_eq!(
            answer(Some(b"bytes=99999999999999999999999-"), 100),
            Unsatisfiable
        );
        assert_eq!(answer(None, 100), Full);
        assert_eq!(a("bytes=0-9", 100), Partial { first: 0, last: 9 });
        assert_eq!(
            a("bytes=90-200", 100),
            Partial {
                first: 90,
                last: 99
            }
        );
        assert_eq!(
            a("bytes=95-", 100),
            Partial {
                first: 95,
                last: 99
            }
        );
        assert_eq!(
            a("bytes=-10", 100),
            Partial {
                first: 90,
                last: 99
            }
        );
        assert_eq!(a("bytes=-1000", 100), Partial { first: 0, last: 99 });
        assert_eq!(a("BYTES = 1-1", 100), Partial { first: 1, last: 1 });
        assert_eq!(
            a("bytes=0-18446744073709551615", 100),
            Partial { first: 0, last: 99 }
        );
    }

    #[test]
    fn unsatisfiable_is_416_and_malformed_is_ignored() {
        for h in [
            "bytes=100-",
            "bytes=100-200",
            "bytes=-0",
            "bytes=200-300,100-",
        ] {
            assert_eq!(a(h, 100), Unsatisfiable, "{h}");
        }
        assert_eq!(a("bytes=0-", 0), Unsatisfiable);
        // A first byte past 2⁶⁴ is a well-formed range past the end, not junk.
        assert_eq!(a("bytes=18446744073709551616-", 100), Unsatisfiable);
        for h in [
            "bytes=5-1",
            "bytes=a-b",
            "bytes=-",
            "bytes=1-2-3",
            "bytes=+1-2",
            "items=0-1",
            "bytes",
            "bytes=",
            "0-10",
            "bytes=0-1,x",
        ] {
            assert_eq!(a(h, 100), Full, "{h}");
        }
        assert_eq!(answer(Some(&[0xff, 0xfe]), 100), Full);
        let long = format!("bytes=0-1{}", " ".repeat(MAX_RANGE_HEADER));
        assert_eq!(a(&long, 100), Full);
    }

    #[test]
    fn several_ranges_coalesce_or_fall_back_to_the_whole_file() {
        assert_eq!(a("bytes=0-9,10-19", 100), Partial { first: 0, last: 19 });
        assert_eq!(a("bytes=5-9,0-7", 100), Partial { first: 0, last: 9 });
        assert_eq!(a("bytes=0-9, 500-600", 100), Partial { first: 0, last: 9 });
        assert_eq!(a("bytes=0-9,20-29", 100), Full);
        let many = (0..=MAX_RANGES)
            .map(|i| format!("{i}-{i}"))
            .collect::<Vec<_>>();
        assert_eq!(a(&format!("bytes={}", many.join(",")), 100), Full);
        let just = (0..MAX_RANGES)
            .map(|i| format!("{i}-{i}"))
            .collect::<Vec<_>>();
        assert_eq!(
            a(&format!("bytes={}", just.join(",")), 100),
            Partial {
                first: 0,
                last: MAX_RANGES as u64 - 1
            }
        );
    }
}
