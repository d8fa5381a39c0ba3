//! Small process-level helpers, and the one atomic file writer ([`AtomicFile`], [`write_atomic`]) every
//! output goes through (paging files, reports, plots, saved views).

mod files;
mod memory;
mod regular;
pub mod shell_words;
pub mod srgb;

pub use files::{
    AtomicFile, LiveMadeFolders, LiveTempDir, LiveTempFile, follow_output_links,
    is_out_of_descriptors, is_resource_exhaustion, lock_is_free, parent_dir, process_may_run,
    remove_dir_tree, remove_earlier_outputs, remove_live_temps, remove_live_temps_and_exit,
    remove_stale_outputs, remove_stale_temps, save_png, write_atomic, writer_of,
};
pub use regular::{MAX_TEXT_FILE_BYTES, node_kind, open_regular, read_regular, read_text_file};

pub use memory::{
    machine_memory_bytes, malloc_arenas_under, memory_limit_bytes, open_files_limit,
    peak_rss_bytes, rss_and_peak_bytes, rss_bytes,
};

/// A number for a label or a file name: 12 significant digits, trailing zeros dropped (`80`, `80.5`), in exponent form
/// outside `[0.001, 10¹⁵)` (`1e-4`, `1e303`). Values that round alike get one label
/// (`sim::grid::GridSpec::duplicate_label` finds them).
pub fn short_number(v: f64) -> String {
    fn trim(m: &str) -> &str {
        if m.contains('.') {
            m.trim_end_matches('0').trim_end_matches('.')
        } else {
            m
        }
    }
    let a = v.abs();
    if (1e-3..1e15).contains(&a) || v == 0.0 {
        let decimals = if v == 0.0 {
            0
        } else {
            (11 - a.log10().floor() as i32).max(0) as usize
        };
        trim(&format!("{v:.decimals$}")).to_string()
    } else {
        let text = format!("{v:.11e}");
        match text.split_once('e') {
            Some((m, e)) => format!("{}e{e}", trim(m)),
            None => text,
        }
    }
}

/// A measured number for a summary line: `decimals` places in `[0.001, 10¹⁵)` (`227.878`), else
/// [`short_number`]'s exponent form (`1e-300`), so an absurd flag value never prints hundreds of digits.
pub fn fixed_number(v: f64, decimals: usize) -> String {
    if (1e-3..1e15).contains(&v.abs()) || v == 0.0 {
        format!("{v:.decimals$}")
    } else {
        short_number(v)
    }
}

/// Serialises a path as text, any bytes that are not UTF-8 replaced (`U+FFFD`), for the reports a
/// script reads: serde refuses a non-UTF-8 `PathBuf`, and a shard's report was written as an empty file
/// and `merge --json` failed after the merged file was written (fault hunt, session 37). For
/// `#[serde(serialize_with = "crate::util::path_lossy")]`.
pub fn path_lossy<S: serde::Serializer>(path: &std::path::Path, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&path.to_string_lossy())
}

/// The text of a panic payload (`&str` or `String`), or a placeholder.
pub fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(a panic without a message)".to_string())
}

/// Whether the AVX2 kernels run: the CPU has AVX2 (asked at run time) and the environment variable
/// `ATLASTREE_SCALAR` is not set (it makes every pass take its scalar rule, so a test can check that
/// both write the same file). Asked once per process. The kernels (`image_ops::srgb_simd`,
/// `texfmt::bc1::interior_band_sse`) are twins of scalar rules that run everywhere else.
#[inline]
pub fn has_avx2() -> bool {
    static AVX2: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *AVX2.get_or_init(|| {
        #[cfg(target_arch = "x86_64")]
        let cpu = std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let cpu = false;
        cpu && std::env::var_os("ATLASTREE_SCALAR").is_none()
    })
}

/// Asks the CPU to bring the cache lines of `value` in (x86-64 `prefetcht0`; elsewhere nothing): a hint
/// for passes that visit records in an order memory does not predict, issued some records ahead of use.
/// Reads nothing and has no effect on results.
#[inline(always)]
pub fn prefetch<T>(value: &T) {
    prefetch_prefix(value, std::mem::size_of::<T>());
}

/// [`prefetch`] of the cache lines that hold the first `bytes` of `value` (at most its size): for passes
/// that read only the leading fields of a record.
#[inline(always)]
pub fn prefetch_prefix<T>(value: &T, bytes: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let start = (value as *const T).cast::<i8>();
        let bytes = bytes.min(std::mem::size_of::<T>());
        let lines = (start as usize % 64 + bytes).div_ceil(64);
        for line in 0..lines {
            // SAFETY: a prefetch is a hint that never faults and reads nothing architecturally, so any
            // address is sound; this one lies within the line of `value`'s last requested byte, which the
            // borrow keeps alive.
            #[allow(
                unsafe_code,
                reason = "prefetch hint: the intrinsic takes a raw pointer"
            )]
            unsafe {
                _mm_prefetch::<_MM_HINT_T0>(start.wrapping_add(64 * line));
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (value, bytes);
}

/// Shell-style match of a whole name against `pattern`: `*` any run of characters (also none), `?` one
/// character, everything else literally (case-sensitive). Two-pointer matcher that backtracks to the
/// last `*` only: O(|pattern| · |name|) at worst, no recursion.
pub fn glob_match(pattern: &str, name: &str) -> bool {
    let (p, n): (Vec<char>, Vec<char>) = (pattern.chars().collect(), name.chars().collect());
    let (mut i, mut j) = (0, 0);
    let mut star: Option<(usize, usize)> = None;
    while j < n.len() {
        if i < p.len() && (p[i] == '?' || (p[i] != '*' && p[i] == n[j])) {
            i += 1;
            j += 1;
        } else if i < p.len() && p[i] == '*' {
            star = Some((i, j));
            i += 1;
        } else if let Some((si, sj)) = star {
            i = si + 1;
            j = sj + 1;
            star = Some((si, sj + 1));
        } else {
            return false;
        }
    }
    p[i..].iter().all(|&c| c == '*')
}

/// `text` with its control characters escaped (`\u{1b}`): names from a scene file (an image's URI or
/// `name`) and the warnings that quote them reach a terminal, where raw ESC or BEL bytes could clear
/// the screen or set its title (fault hunt, session 28).
pub fn printable(text: &str) -> std::borrow::Cow<'_, str> {
    if !text.chars().any(char::is_control) {
        return std::borrow::Cow::Borrowed(text);
    }
    let mut out = String::with_capacity(text.len() + 8);
    for c in text.chars() {
        if c.is_control() {
            out.extend(c.escape_default());
        } else {
            out.push(c);
        }
    }
    std::borrow::Cow::Owned(out)
}

/// A scale (or any positive fraction) with three decimals, or three significant digits below 0.001:
/// a leaf scaled to 5·10⁻⁵ printed as "scale 0.000" (fault hunt, session 31).
pub fn fraction_text(x: f64) -> String {
    if x != 0.0 && x.abs() < 0.0005 {
        format!("{x:.2e}")
    } else {
        format!("{x:.3}")
    }
}

/// Human-readable bytes (binary units).
pub fn human_bytes(b: u64) -> String {
    const U: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut v = b as f64;
    let mut i = 0;
    while v >= 1024.0 && i + 1 < U.len() {
        v /= 1024.0;
        i += 1;
    }
    if i == 0 {
        format!("{b} B")
    } else {
        format!("{v:.2} {}", U[i])
    }
}

/// Why [`parse_size`] refused a text.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
pub enum SizeError {
    #[error("is not a size")]
    Malformed,
    #[error("has an unknown unit")]
    Unit,
    #[error("is negative or not finite")]
    Negative,
    #[error("is more bytes than a 64-bit count holds (16 EiB)")]
    TooLarge,
    #[error("is a fraction of one byte")]
    Fraction,
}

/// Parses a byte size: a number (`12`, `1.5`, `1e6`, `1.5e3`) with an optional unit `B`, `KB`, `MB`,
/// `GB`, `TB` (powers of 1000) or `KiB`, `MiB`, `GiB`, `TiB` (powers of 1024), case-insensitive, spaces
/// allowed between, e.g. `8MB`, `512KiB`, `1.5e3MiB`, `1TiB`. The unit is the trailing run of letters.
/// Refused, with the reason: malformed, an unknown unit, negative or not finite, past `u64`, or a
/// fraction of one byte (`0.5B`: rounding it would turn a size the user meant as nothing or as a typo
/// into 1 byte).
pub fn parse_size(s: &str) -> Result<u64, SizeError> {
    let t = s.trim();
    let unit_at = t
        .char_indices()
        .rev()
        .take_while(|(_, c)| c.is_ascii_alphabetic())
        .last()
        .map_or(t.len(), |(i, _)| i);
    let (num, unit) = t.split_at(unit_at);
    let v: f64 = num.trim().parse().map_err(|_| SizeError::Malformed)?;
    let mul = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1.0,
        "kb" | "k" => 1e3,
        "mb" | "m" => 1e6,
        "gb" | "g" => 1e9,
        "tb" | "t" => 1e12,
        "kib" => 1024.0,
        "mib" => 1024.0 * 1024.0,
        "gib" => 1024.0 * 1024.0 * 1024.0,
        "tib" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => return Err(SizeError::Unit),
    };
    let b = v * mul;
    if b.is_nan() || b < 0.0 || v.is_infinite() {
        return Err(SizeError::Negative);
    }
    // 1.8e19 < 2^64 ≈ 1.845e19: every value below it rounds into a u64.
    if b >= 1.8e19 {
        return Err(SizeError::TooLarge);
    }
    if b > 0.0 && b < 1.0 {
        return Err(SizeError::Fraction);
    }
    Ok(b.round() as u64)
}

/// [`parse_size`] without the reason.
pub fn parse_bytes(s: &str) -> Option<u64> {
    parse_size(s).ok()
}

/// Parses a rate in bytes per second: a [`parse_bytes`] size followed by `/s`, e.g. `5MB/s`.
pub fn parse_rate(s: &str) -> Option<f64> {
    let t = s.trim();
    let t = t
        .strip_suffix("/s")
        .or_else(|| t.strip_suffix("ps"))
        .unwrap_or(t);
    parse_bytes(t).map(|b| b as f64).filter(|&b| b > 0.0)
}

/// Parses a duration into seconds: a number with unit `ms`, `s` or `us`/`µs` (default seconds), e.g.
/// `80ms`, `0.5s`.
pub fn parse_seconds(s: &str) -> Option<f64> {
    let t = s.trim();
    let (num, mul) = if let Some(n) = t.strip_suffix("ms") {
        (n, 1e-3)
    } else if let Some(n) = t.strip_suffix("us").or_else(|| t.strip_suffix("µs")) {
        (n, 1e-6)
    } else if let Some(n) = t.strip_suffix('s') {
        (n, 1.0)
    } else {
        (t, 1.0)
    };
    let v: f64 = num.trim().parse().ok()?;
    let secs = v * mul;
    (secs.is_finite() && secs >= 0.0).then_some(secs)
}

/// [`parse_seconds`] with the unit required (`80ms`, `0.08s`, `80us`), except for a bare `0`: a bare
/// latency of `80` read as 80 seconds made a simulation load nothing without a word (fault hunt,
/// session 34).
pub fn parse_duration_with_unit(s: &str) -> Option<f64> {
    let t = s.trim();
    let bare = t.parse::<f64>().is_ok();
    if bare && t.parse::<f64>() != Ok(0.0) {
        return None;
    }
    parse_seconds(t)
}

/// Which file `meta` describes: (device, inode) on unix, where two opens of one path can be told apart
/// when a file was renamed over it in between; `None` elsewhere.
pub fn file_identity(meta: &std::fs::Metadata) -> Option<(u64, u64)> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        Some((meta.dev(), meta.ino()))
    }
    #[cfg(not(unix))]
    {
        let _ = meta;
        None
    }
}

/// A 128-bit digest (`xxh3_128`) as the two `u64` words the file formats store, low word first.
pub fn digest_words(d: u128) -> [u64; 2] {
    [d as u64, (d >> 64) as u64]
}

/// Marsaglia's xorshift64 with shifts (13, 7, 17): a tiny deterministic generator for seeded test data,
/// benchmarks and sweeps (one sequence per seed on every platform). Not for anything that needs
/// statistical quality or unpredictability.
#[derive(Clone, Debug)]
pub struct XorShift64(u64);

impl XorShift64 {
    /// The generator seeded with `seed`; 0 (whose sequence would be all zeros) is replaced by a fixed
    /// non-zero seed.
    pub fn new(seed: u64) -> Self {
        Self(if seed == 0 {
            0x9e37_79b9_7f4a_7c15
        } else {
            seed
        })
    }

    /// The next state (also the value): never 0.
    pub fn next_u64(&mut self) -> u64 {
        let mut h = self.0;
        h ^= h << 13;
        h ^= h >> 7;
        h ^= h << 17;
        self.0 = h;
        h
    }

    /// A value in `[0, 1)` from the top 53 bits of [`Self::next_u64`].
    pub fn next_f64(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[cfg(test)]
mod parse_tests {
    use super::*;

    #[test]
    fn sizes_rates_and_durations() {
        assert_eq!(parse_bytes("8MB"), Some(8_000_000));
        assert_eq!(parse_bytes("512KiB"), Some(524_288));
        assert_eq!(parse_bytes("1e6"), Some(1_000_000));
        assert_eq!(parse_bytes("12"), Some(12));
        assert_eq!(parse_bytes("-1MB"), None);
        assert_eq!(parse_bytes("5XB"), None);
        assert_eq!(parse_bytes("1TiB"), Some(1 << 40));
        assert_eq!(parse_bytes("2 TB"), Some(2_000_000_000_000));
        assert_eq!(parse_bytes("20000000TiB"), None);
        assert_eq!(parse_bytes("0.5B"), None);
        assert_eq!(parse_bytes("0.0001KB"), None);
        assert_eq!(parse_bytes("0"), Some(0));
        assert_eq!(parse_bytes("1.5B"), Some(2));
        assert_eq!(parse_bytes("1.5e3MiB"), Some(1500 << 20));
        assert_eq!(fraction_text(0.465), "0.465");
        assert_eq!(fraction_text(0.0), "0.000");
        assert_eq!(fraction_text(5.1e-5), "5.10e-5");
        assert_eq!(parse_bytes("1e3 KB"), Some(1_000_000));
        assert_eq!(parse_size("1e30"), Err(SizeError::TooLarge));
        assert_eq!(parse_size("18446744073709551616"), Err(SizeError::TooLarge));
        assert_eq!(parse_size("5XB"), Err(SizeError::Unit));
        assert_eq!(parse_size("e6"), Err(SizeError::Malformed));
        assert_eq!(parse_size("1e"), Err(SizeError::Unit));
        assert_eq!(parse_size("nan"), Err(SizeError::Malformed));
        assert_eq!(parse_size("NaN B"), Err(SizeError::Negative));
        assert_eq!(parse_size("inf"), Err(SizeError::Malformed));
        assert_eq!(parse_size("-1MB"), Err(SizeError::Negative));
        assert_eq!(parse_size("0.5"), Err(SizeError::Fraction));
        assert_eq!(parse_rate("5MB/s"), Some(5e6));
        assert_eq!(parse_rate("0MB/s"), None);
        assert_eq!(parse_seconds("80ms"), Some(0.08));
        assert_eq!(parse_seconds("0ms"), Some(0.0));
        assert_eq!(parse_seconds("2"), Some(2.0));
        assert_eq!(parse_seconds("x"), None);
        assert_eq!(parse_duration_with_unit("80ms"), Some(0.08));
        assert_eq!(parse_duration_with_unit("0.5s"), Some(0.5));
        assert_eq!(parse_duration_with_unit("0"), Some(0.0));
        assert_eq!(parse_duration_with_unit("80"), None);
    }

    #[test]
    fn glob_matches_whole_names() {
        assert!(glob_match("facade_*", "facade_00012"));
        assert!(!glob_match("facade_*", "roof_1"));
        assert!(!glob_match("facade_*", "c00011_facade"));
        assert!(glob_match("*facade*", "c00011_facade"));
        assert!(glob_match("roof_?", "roof_2"));
        assert!(!glob_match("roof_?", "roof_12"));
        assert!(glob_match("*", ""));
        assert!(!glob_match("?", ""));
        assert!(glob_match("a*b*c", "a_x_b_y_b_c"));
        assert!(!glob_match("a*b*c", "a_x_b_y_b_"));
        assert!(glob_match("asphalt", "asphalt"));
        assert!(!glob_match("asphalt", "asphalt2"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_numbers_are_short_and_read_back_within_12_digits() {
        for (v, text) in [
            (0.0, "0"),
            (151.0, "151"),
            (0.5, "0.5"),
            (80.5, "80.5"),
            (1e-7 * 1e3, "1e-4"),
            (1e300, "1e300"),
            (-2.25, "-2.25"),
            (123456789012345.0, "123456789012345"),
            (1e15, "1e15"),
        ] {
            assert_eq!(short_number(v), text, "{v:e}");
        }
        for v in [
            0.001234567891234,
            987.654321987654,
            5e-320,
            1.7976931348623157e308,
        ] {
            let back: f64 = short_number(v).parse().unwrap();
            assert!((back - v).abs() <= v.abs() * 1e-11, "{v:e} -> {back:e}");
        }
    }

    #[test]
    fn xorshift64_is_the_13_7_17_sequence_and_never_zero() {
        // The first values written out by hand from the shifts (an independent twin of next_u64).
        let mut twin = 0x9e37_79b9_7f4a_7c15u64;
        let mut rng = XorShift64::new(twin);
        for _ in 0..1000 {
            twin ^= twin << 13;
            twin ^= twin >> 7;
            twin ^= twin << 17;
            assert_eq!(rng.next_u64(), twin);
        }
        let mut zero = XorShift64::new(0);
        assert!((0..100).all(|_| zero.next_u64() != 0));
        let f = XorShift64::new(5).next_f64();
        assert!((0.0..1.0).contains(&f));
    }
}
