//! Peak resident memory of a span of work (a build stage, one sweep variant) without resetting the
//! process's own peak.
//!
//! Resetting `VmHWM` (`/proc/self/clear_refs`) gave exact per-stage peaks but also reset what
//! `getrusage` reports, so `/usr/bin/time`, Slurm's `MaxRSS` and the sharded-build benchmarks saw only the
//! last stages' peak (a 23.8 M-triangle build: 3.1 GiB reported against a true 5.3 GiB). Instead a
//! [`MemoryWindow`] reads the process peak at its start and end: if the peak rose inside the window, that
//! new peak is the window's, exactly; otherwise the window's peak is the largest resident size a sampler
//! thread saw during it (every [`SAMPLE_PERIOD`]; a spike shorter than that can be missed), or the
//! resident size at its ends, never more than the process peak at its end. Windows may overlap or nest (each
//! holds one of [`SLOTS`] sampler slots).

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::time::Duration;

/// How often the sampler reads the resident size.
pub const SAMPLE_PERIOD: Duration = Duration::from_millis(5);
/// Windows open at once that the sampler serves; beyond, a window has only its end points.
pub const SLOTS: usize = 32;

static SLOT_PEAK: [AtomicU64; SLOTS] = [const { AtomicU64::new(0) }; SLOTS];
static SLOT_USED: AtomicU32 = AtomicU32::new(0);
static SAMPLER: OnceLock<bool> = OnceLock::new();

/// Starts the sampler thread once per process (where the platform reports a resident size).
fn sampler_running() -> bool {
    *SAMPLER.get_or_init(|| {
        crate::util::rss_bytes().is_some()
            && std::thread::Builder::new()
                .name("rss-sampler".into())
                .spawn(|| {
                    loop {
                        let used = SLOT_USED.load(Ordering::Acquire);
                        if used != 0
                            && let Some(rss) = crate::util::rss_bytes()
                        {
                            for (i, slot) in SLOT_PEAK.iter().enumerate() {
                                if used & (1 << i) != 0 {
                                    slot.fetch_max(rss, Ordering::AcqRel);
                                }
                            }
                        }
                        std::thread::sleep(SAMPLE_PERIOD);
                    }
                })
                .is_ok()
    })
}

/// Claims a free sampler slot, `None` when all [`SLOTS`] are taken.
fn claim_slot() -> Option<usize> {
    let mut used = SLOT_USED.load(Ordering::Acquire);
    loop {
        let free = (!used).trailing_zeros() as usize;
        if free >= SLOTS {
            return None;
        }
        match SLOT_USED.compare_exchange(
            used,
            used | (1 << free),
            Ordering::AcqRel,
            Ordering::Acquire,
        ) {
            Ok(_) => return Some(free),
            Err(now) => used = now,
        }
    }
}

/// The peak resident memory of the work between [`MemoryWindow::start`] (or the last
/// [`MemoryWindow::close`]) and the next `close`. See the module documentation for how it is measured.
#[derive(Debug)]
pub struct MemoryWindow {
    /// The process peak when the window (re)started.
    peak_at_start: Option<u64>,
    slot: Option<usize>,
}

impl MemoryWindow {
    /// A window starting now.
    pub fn start() -> Self {
        let slot = if sampler_running() {
            claim_slot()
        } else {
            None
        };
        let mut w = MemoryWindow {
            peak_at_start: None,
            slot,
        };
        w.restart(crate::util::rss_and_peak_bytes());
        w
    }

    /// Starts the next window at the reading `now` (`[resident, peak]`).
    fn restart(&mut self, now: Option<[u64; 2]>) {
        if let Some(i) = self.slot {
            SLOT_PEAK[i].store(now.map_or(0, |[rss, _]| rss), Ordering::Release);
        }
        self.peak_at_start = now.map(|[_, peak]| peak);
    }

    /// The window's peak resident memory, bytes (`None` where the platform does not tell); the next
    /// window starts now.
    pub fn close(&mut self) -> Option<u64> {
        let now = crate::util::rss_and_peak_bytes();
        let sampled = self
            .slot
            .map(|i| SLOT_PEAK[i].load(Ordering::Acquire))
            .max(now.map(|[rss, _]| rss));
        let result = match (now, self.peak_at_start) {
            (Some([_, p]), Some(s)) if p > s => Some(p),
            // The kernel's resident counters are per-CPU and summed lazily, so a sampled resident size can
            // exceed the peak the kernel records by a few dozen pages (seen: 37); a window never reports
            // more than the process peak read at its end.
            (Some([_, p]), _) => sampled.map(|s| s.min(p)),
            (None, _) => None,
        };
        self.restart(now);
        result
    }
}

impl Default for MemoryWindow {
    fn default() -> Self {
        Self::start()
    }
}

impl Clone for MemoryWindow {
    /// A new window starting now (a slot has one owner).
    fn clone(&self) -> Self {
        Self::start()
    }
}

impl Drop for MemoryWindow {
    fn drop(&mut self) {
        if let Some(i) = self.slot {
            SLOT_USED.fetch_and(!(1 << i), Ordering::AcqRel);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A transient allocation inside a window is its peak, whether it set a new process peak (exact) or
    /// was seen by the sampler; and the process peak is never reset.
    #[test]
    fn a_transient_allocation_is_the_windows_peak_and_the_process_peak_stays() {
        if crate::util::rss_bytes().is_none() {
            eprintln!("SKIP: no /proc/self/status here");
            return;
        }
        const BIG: usize = 256 << 20;
        for round in 0..2 {
            let mut w = MemoryWindow::start();
            let before = crate::util::rss_bytes().unwrap_or(0);
            let v = vec![1u8; BIG];
            std::thread::sleep(SAMPLE_PERIOD * 8);
            std::hint::black_box(&v);
            drop(v);
            let peak = w.close().unwrap_or(0);
            assert!(
                peak >= before + BIG as u64 * 9 / 10,
                "round {round}: window peak {peak} B, resident before {before} B"
            );
            let process = crate::util::peak_rss_bytes().unwrap_or(0);
            assert!(
                process >= peak,
                "round {round}: process peak {process} B < {peak} B"
            );
            // The next window starts after the allocation was freed: it does not report it again.
            let again = w.close().unwrap_or(u64::MAX);
            assert!(
                again < peak,
                "round {round}: the closed window's peak leaked into the next"
            );
        }
    }

    #[test]
    fn slots_are_claimed_and_released() {
        if crate::util::rss_bytes().is_none() {
            eprintln!("SKIP: no /proc/self/status here (no sampler, no slots)");
            return;
        }
        let a = MemoryWindow::start();
        let b = MemoryWindow::start();
        let (Some(x), Some(y)) = (a.slot, b.slot) else {
            panic!("the sampler runs here, so both windows hold a slot");
        };
        assert_ne!(x, y);
        drop(a);
        assert_eq!(SLOT_USED.load(Ordering::Acquire) & (1 << x), 0);
    }
}
