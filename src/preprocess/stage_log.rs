//! The per-stage log of a build, a shard or a merge: seconds and peak resident memory of each stage.

use serde::Serialize;
use std::time::Instant;

/// What each stage of a build, a shard or a merge took, in the order the stages ended: its seconds and
/// its peak resident memory. Build and shard reports carry one (flattened into their JSON).
#[derive(Clone, Debug, Default, Serialize, serde::Deserialize)]
pub struct StageLog {
    /// (stage, seconds).
    pub timings: Vec<(String, f64)>,
    /// (stage, peak resident memory during it, bytes), where the platform tells (Linux).
    pub stage_peak_rss: Vec<(String, u64)>,
    /// The largest of those peaks.
    pub peak_rss_bytes: Option<u64>,
    /// The window of the stage under way.
    #[serde(skip)]
    window: crate::memory_window::MemoryWindow,
}

impl StageLog {
    /// Records stage `name` as begun at `start` and ended now, with the peak memory since the previous
    /// stage ended ([`crate::memory_window::MemoryWindow`]; the process's own peak is never reset). `total` gets
    /// the largest peak.
    pub(super) fn push(&mut self, name: &str, start: Instant) {
        let now = self.window.close();
        let peak = if name == "total" {
            self.peak_rss_bytes.max(now)
        } else {
            now
        };
        self.record(name, start.elapsed().as_secs_f64(), peak, false);
    }

    /// The seconds of stage `name`, if it ran.
    pub fn seconds(&self, name: &str) -> Option<f64> {
        self.timings
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, s)| *s)
    }

    /// Puts a stage that ran before the library's (the CLI's import) first, and counts it in `total`
    /// (which left the import out: stages summed to more than their total).
    pub fn prepend(&mut self, name: &str, seconds: f64, peak: Option<u64>) {
        if let Some((_, total)) = self.timings.iter_mut().find(|(n, _)| n == "total") {
            *total += seconds;
        }
        if let (Some(p), Some((_, total_peak))) = (
            peak,
            (self.stage_peak_rss.iter_mut()).find(|(n, _)| n == "total"),
        ) {
            *total_peak = (*total_peak).max(p);
        }
        self.record(name, seconds, peak, true);
    }

    fn record(&mut self, name: &str, seconds: f64, peak: Option<u64>, first: bool) {
        let at = |len: usize| if first { 0 } else { len };
        self.timings
            .insert(at(self.timings.len()), (name.to_string(), seconds));
        if let Some(p) = peak {
            self.stage_peak_rss
                .insert(at(self.stage_peak_rss.len()), (name.to_string(), p));
            self.peak_rss_bytes = self.peak_rss_bytes.max(Some(p));
        }
    }
}
