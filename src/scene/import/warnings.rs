//! The warning list of an import: [`ImportReport::warn`] keeps at most [`MAX_WARNINGS`] messages and
//! counts every one; [`ImportReport::close_warnings`] appends "... and N more" for those not kept.
//!
//! Every stage of the import warns through these two methods (an inherent `impl` visible to the
//! import's files only), so the cap is applied in one place.

use crate::scene::ImportReport;

/// At most this many warning strings are kept; the rest are counted in `warnings_total`.
pub(super) const MAX_WARNINGS: usize = 100;

impl ImportReport {
    /// Records a warning: the string is kept while fewer than [`MAX_WARNINGS`] are, the total is exact.
    pub(super) fn warn(&mut self, msg: String) {
        self.warnings_total += 1;
        if self.warnings.len() < MAX_WARNINGS {
            self.warnings.push(msg);
        }
    }

    /// Appends "... and N more" when warnings were counted but not kept.
    pub(super) fn close_warnings(&mut self) {
        let kept = self.warnings.len() as u64;
        if self.warnings_total > kept {
            let more = self.warnings_total - kept;
            self.warnings.push(format!("... and {more} more"));
        }
    }
}
