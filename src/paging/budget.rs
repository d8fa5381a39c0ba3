//! The per-frame upload budget of the pager (paper §6: how much may become resident in one frame).

use serde::Serialize;

/// How much may become resident per frame.
#[derive(Copy, Clone, Debug, PartialEq, Default, Serialize)]
pub enum UploadBudget {
    /// Everything that arrived.
    #[default]
    Unlimited,
    /// Bytes uploaded per frame, as [`crate::paging::BlockMeta::upload_bytes`] counts them (original
    /// textures as their class layers): blocks are accepted while the frame's accepted bytes are below
    /// the budget, so the block that crosses it is accepted too (a frame can upload up to the budget plus
    /// one block), and at least one block per frame always is, so a block larger than the budget still
    /// loads.
    Bytes(u64),
    /// Milliseconds of upload work per frame, measured around the upload callback (same minimum).
    Millis(f64),
}

impl std::str::FromStr for UploadBudget {
    type Err = String;
    /// `unlimited` (or a bare `0`, as in other tools' "0 = no limit"), a byte size per frame (`8MB`,
    /// `512KiB`), or a time per frame (`2ms`); zero sizes and times with a unit are refused.
    fn from_str(s: &str) -> Result<UploadBudget, String> {
        let t = s.trim();
        if t.eq_ignore_ascii_case("unlimited") || t == "0" {
            return Ok(UploadBudget::Unlimited);
        }
        if t.ends_with("ms") || t.ends_with("us") || t.ends_with("µs") {
            return match crate::util::parse_seconds(t) {
                Some(v) if v > 0.0 => Ok(UploadBudget::Millis(v * 1e3)),
                Some(_) => Err(format!(
                    "bad upload budget {s:?}: zero time uploads nothing; give a positive time, or 0 or \
                     unlimited for no limit"
                )),
                None => Err(format!("bad upload budget {s:?}: expected e.g. 2ms")),
            };
        }
        match crate::util::parse_bytes(t) {
            Some(0) => Err(format!(
                "bad upload budget {s:?}: zero uploads nothing; give a positive size, or 0 or unlimited \
                 for no limit"
            )),
            Some(b) => Ok(UploadBudget::Bytes(b)),
            None => Err(format!(
                "bad upload budget {s:?}: expected unlimited, 8MB, 512KiB or 2ms"
            )),
        }
    }
}
