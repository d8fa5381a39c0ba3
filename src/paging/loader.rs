//! Loaders: who turns the pager's [`Request`]s into [`Arrival`]s.
//!
//! - [`ImmediateLoader`]: fetches every wanted block synchronously in [`Loader::poll`], in priority order
//!   (deterministic; the file "as it would deliver", used by tests and the renderer/simulator agreement);
//! - [`ThreadedLoader`]: loader threads off the render thread; the wanted list is replaced every frame
//!   (re-ranked), workers always take the most important request not yet in flight; a request that left
//!   the list while in flight is finished but its bytes are discarded by the pager (a blocking read cannot
//!   be interrupted, but its result never becomes resident).
//!
//! The simulator's I/O model (`crate::sim`) is a third implementation.

use super::pager::{Arrival, Request};
use super::source::{BlockSource, SourceError};
use crate::ids::BlockId;
use crate::store::format::BlockRecord;
use std::collections::HashSet;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;

/// A block loader driven once per frame.
pub trait Loader {
    /// Replaces the outstanding requests (most important first). Requests not in `wanted` are cancelled.
    fn set_requests(&mut self, wanted: &[Request]);
    /// Collects what arrived by `now` (seconds on the frame clock; real loaders ignore it).
    fn poll(&mut self, now: f64, out: &mut Vec<Arrival>);
    /// Requests not yet started.
    fn queued(&self) -> u32;
    /// Requests being transferred.
    fn in_flight(&self) -> u32;
}

/// Fetches all wanted blocks synchronously at [`Loader::poll`].
pub struct ImmediateLoader {
    source: Arc<dyn BlockSource>,
    records: Vec<BlockRecord>,
    wanted: Vec<Request>,
}

impl ImmediateLoader {
    pub fn new(source: Arc<dyn BlockSource>, records: Vec<BlockRecord>) -> ImmediateLoader {
        ImmediateLoader {
            source,
            records,
            wanted: Vec::new(),
        }
    }
}

fn fetch(source: &dyn BlockSource, records: &[BlockRecord], block: BlockId) -> Arrival {
    let result = match records.get(block.idx()) {
        Some(r) => source.fetch(block, r).map(Some),
        None => Err(SourceError::NotInTable {
            block,
            blocks: records.len() as u64,
        }),
    };
    Arrival { block, result }
}

impl Loader for ImmediateLoader {
    fn set_requests(&mut self, wanted: &[Request]) {
        self.wanted.clear();
        self.wanted.extend_from_slice(wanted);
    }

    fn poll(&mut self, _now: f64, out: &mut Vec<Arrival>) {
        for r in self.wanted.drain(..) {
            out.push(fetch(&*self.source, &self.records, r.block));
        }
    }

    fn queued(&self) -> u32 {
        self.wanted.len() as u32
    }

    fn in_flight(&self) -> u32 {
        0
    }
}

#[derive(Default)]
struct Shared {
    wanted: Vec<Request>,
    in_flight: HashSet<BlockId>,
    done: Vec<Arrival>,
    shutdown: bool,
}

/// Loader threads reading from a [`BlockSource`].
pub struct ThreadedLoader {
    shared: Arc<(Mutex<Shared>, Condvar)>,
    workers: Vec<JoinHandle<()>>,
}

fn lock(m: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // A worker that panicked while holding the lock cannot leave `Shared` inconsistent in a way that
    // matters here (every field is valid on its own), so recover the guard.
    m.lock().unwrap_or_else(|e| e.into_inner())
}

impl ThreadedLoader {
    /// Starts `threads` (≥ 1) workers; at most `threads` requests are in flight at once.
    pub fn new(
        source: Arc<dyn BlockSource>,
        records: Vec<BlockRecord>,
        threads: usize,
    ) -> std::io::Result<ThreadedLoader> {
        let shared: Arc<(Mutex<Shared>, Condvar)> = Arc::default();
        let records: Arc<[BlockRecord]> = records.into();
        let mut loader = ThreadedLoader {
            shared,
            workers: Vec::new(),
        };
        for i in 0..threads.max(1) {
            let shared = Arc::clone(&loader.shared);
            let source = Arc::clone(&source);
            let records = Arc::clone(&records);
            // On error `loader` is dropped, which stops the workers already started.
            loader.workers.push(
                std::thread::Builder::new()
                    .name(format!("atlastree-loader-{i}"))
                    .spawn(move || worker(&shared, &*source, &records))?,
            );
        }
        Ok(loader)
    }
}

fn worker(shared: &(Mutex<Shared>, Condvar), source: &dyn BlockSource, records: &[BlockRecord]) {
    let (m, cv) = shared;
    loop {
        let block = {
            let mut s = lock(m);
            loop {
                if s.shutdown {
                    return;
                }
                let next = s
                    .wanted
                    .iter()
                    .map(|r| r.block)
                    .find(|b| !s.in_flight.contains(b));
                if let Some(b) = next {
                    s.in_flight.insert(b);
                    s.wanted.retain(|r| r.block != b);
                    break b;
                }
                s = cv.wait(s).unwrap_or_else(|e| e.into_inner());
            }
        };
        let arrival = fetch(source, records, block);
        let mut s = lock(m);
        s.in_flight.remove(&block);
        s.done.push(arrival);
    }
}

impl Loader for ThreadedLoader {
    fn set_requests(&mut self, wanted: &[Request]) {
        let (m, cv) = &*self.shared;
        let mut s = lock(m);
        s.wanted.clear();
        let busy: HashSet<BlockId> = (s.in_flight.iter().copied())
            .chain(s.done.iter().map(|a| a.block))
            .collect();
        let fresh: Vec<Request> = wanted
            .iter()
            .copied()
            .filter(|r| !busy.contains(&r.block))
            .collect();
        s.wanted = fresh;
        cv.notify_all();
    }

    fn poll(&mut self, _now: f64, out: &mut Vec<Arrival>) {
        out.append(&mut lock(&self.shared.0).done);
    }

    fn queued(&self) -> u32 {
        lock(&self.shared.0).wanted.len() as u32
    }

    fn in_flight(&self) -> u32 {
        lock(&self.shared.0).in_flight.len() as u32
    }
}

/// How long [`ThreadedLoader`]'s drop waits for workers still in a request before it leaves them behind.
const DROP_GRACE: std::time::Duration = std::time::Duration::from_millis(200);

impl Drop for ThreadedLoader {
    /// Stops the workers: idle ones exit at once; one still in a request (a stalled server holds it up to
    /// the source's timeout × attempts, minutes over HTTP) is waited for [`DROP_GRACE`], then left to
    /// finish on its own — its result is dropped, and a process that exits takes it along. `render` over a
    /// server that stopped answering used to sit two minutes after its last frame.
    fn drop(&mut self) {
        {
            let (m, cv) = &*self.shared;
            lock(m).shutdown = true;
            cv.notify_all();
        }
        let deadline = std::time::Instant::now() + DROP_GRACE;
        while self.workers.iter().any(|w| !w.is_finished()) && std::time::Instant::now() < deadline
        {
            std::thread::sleep(std::time::Duration::from_millis(2));
        }
        for w in self.workers.drain(..) {
            if w.is_finished() {
                let _ = w.join();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bytemuck::Zeroable;
    use std::time::{Duration, Instant};

    /// A source whose every fetch takes `stall` (a server that stopped answering, up to its timeout).
    struct Stalled {
        stall: Duration,
    }

    impl BlockSource for Stalled {
        fn name(&self) -> String {
            "stalled".into()
        }

        fn fetch(&self, _: BlockId, _: &BlockRecord) -> Result<Vec<u8>, SourceError> {
            std::thread::sleep(self.stall);
            Ok(Vec::new())
        }
    }

    #[test]
    fn drop_leaves_workers_stuck_in_a_request_behind() {
        let record = BlockRecord::zeroed();
        let mut loader = ThreadedLoader::new(
            Arc::new(Stalled {
                stall: Duration::from_secs(5),
            }),
            vec![record; 4],
            2,
        )
        .unwrap();
        let wanted: Vec<Request> = (0..4)
            .map(|b| Request {
                block: BlockId(b),
                bytes: 1,
            })
            .collect();
        loader.set_requests(&wanted);
        let start = Instant::now();
        while loader.in_flight() < 2 {
            assert!(
                start.elapsed() < Duration::from_secs(5),
                "workers never started"
            );
            std::thread::sleep(Duration::from_millis(1));
        }
        let start = Instant::now();
        drop(loader);
        let waited = start.elapsed();
        assert!(
            waited >= DROP_GRACE && waited < Duration::from_secs(2),
            "drop waited {waited:?}"
        );
    }
}
