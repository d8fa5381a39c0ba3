//! Paging over HTTP under faults (issue 23): the planner's root fetch and the pager's loads against a
//! server that fails one block. A root whose first requests fail (5xx, wrong `Content-Range`, corrupt body)
//! still loads within the source's retries; a root that stays broken ends the run with an error naming
//! the block, the URL, the attempts and the last cause, after exactly the configured attempts; a non-root
//! that stays broken is counted, drawn coarser and asked for again with a bounded back-off.

use super::http::{Fixture, fault_server, fixture, quick};
use super::http_server::Faults;
use atlastree::camera::{Camera, CameraPath, Ground};
use atlastree::ids::BlockId;
use atlastree::paging::{
    BlockTable, Event, FileSource, HttpSource, PagerError, PagerOptions, ResidencyError,
    SourceError,
};
use atlastree::plan::{
    FramePlanner, NoResidency, PagingSetup, PlanError, RecordResidency, Residency,
};
use std::error::Error;
use std::sync::Arc;

fn cameras(fx: &Fixture, n: usize) -> (Vec<Camera>, f64) {
    let ground = Ground::from_tree(&fx.file).unwrap();
    let path = CameraPath::overview_dive_on(&ground).unwrap();
    let cams: Vec<Camera> = path.frames(30.0, n).collect();
    let scale = crate::views::scale_800(&fx.file.to_params(), cams[0].fov_x_deg);
    (cams, scale)
}

fn setup(source: Arc<dyn atlastree::paging::BlockSource>) -> PagingSetup {
    PagingSetup {
        pager: PagerOptions {
            capacity: 8,
            ..PagerOptions::default()
        },
        source,
        loader_threads: 0,
    }
}

fn root(fx: &Fixture) -> BlockId {
    let table = BlockTable::from_file(&fx.file).unwrap();
    let roots: Vec<BlockId> = table.roots().collect();
    assert_eq!(roots.len(), 1, "the fixture has one tree");
    roots[0]
}

#[test]
fn a_root_whose_first_requests_fail_still_loads() {
    let fx = fixture();
    let server = fault_server(&fx);
    let root = root(&fx);
    let offset = fx.file.blocks()[root.idx()].offset;
    // quick(): 3 retries, so up to 3 failed requests of the root are ridden out.
    for (what, faults) in [
        (
            "500",
            Faults {
                status: Some((500, 3)),
                ..Faults::default()
            },
        ),
        (
            "wrong Content-Range",
            Faults {
                wrong_range: 3,
                ..Faults::default()
            },
        ),
        (
            "corrupt body",
            Faults {
                corrupt: 3,
                ..Faults::default()
            },
        ),
        (
            "truncated body",
            Faults {
                truncate: 3,
                ..Faults::default()
            },
        ),
    ] {
        let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
        let src = Arc::new(src);
        let faults_before = server.seen().faults;
        server.set_faults(Faults {
            target: Some(offset),
            ..faults
        });
        let mut planner = FramePlanner::paged_from_file(&remote, setup(src.clone()))
            .unwrap_or_else(|e| panic!("{what}: {e}"));
        let events = planner.take_bootstrap();
        assert!(
            matches!(events.as_slice(), [Event::Loaded { block, data: Some(d) }]
                if *block == root && d.as_slice() == fx.file.block(root).unwrap().into_owned()),
            "{what}"
        );
        assert_eq!(server.seen().faults - faults_before, 3, "{what}");
        let s = src.stats();
        assert_eq!(
            (s.retries, s.failures, s.blocks),
            (3, 0, 1),
            "{what}: {s:?}"
        );
    }
}

#[test]
fn a_root_that_stays_broken_ends_with_a_clear_error_after_the_configured_attempts() {
    let fx = fixture();
    let server = fault_server(&fx);
    let root = root(&fx);
    let offset = fx.file.blocks()[root.idx()].offset;
    for (what, faults, cause) in [
        (
            "500",
            Faults {
                status: Some((500, 1000)),
                ..Faults::default()
            },
            "HTTP status 500",
        ),
        (
            "wrong Content-Range",
            Faults {
                wrong_range: 1000,
                ..Faults::default()
            },
            "Content-Range",
        ),
        (
            "corrupt",
            Faults {
                corrupt: 1000,
                ..Faults::default()
            },
            "checksum",
        ),
    ] {
        let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
        let faults_before = server.seen().faults;
        server.set_faults(Faults {
            target: Some(offset),
            ..faults
        });
        let e = FramePlanner::paged_from_file(&remote, setup(Arc::new(src)))
            .err()
            .unwrap_or_else(|| panic!("{what}: the broken root loaded"));
        // Exactly retries + 1 = 4 requests of the root.
        assert_eq!(server.seen().faults - faults_before, 4, "{what}");
        let PlanError::Pager(PagerError::RootLoad { block, error }) = &e else {
            panic!("{what}: {e}");
        };
        assert_eq!(*block, root);
        assert_eq!(error.attempts(), 4, "{what}: {error}");
        assert!(error.is_transient(), "{what}: {error}");
        // The whole chain, as the CLI prints it: block, URL, attempts, last cause.
        let mut text = e.to_string();
        let mut cause_of = e.source();
        while let Some(c) = cause_of {
            text += &format!(": {c}");
            cause_of = c.source();
        }
        for needle in [
            &format!("{root}"),
            server.url().as_str(),
            "4 attempt",
            cause,
        ] {
            assert!(
                text.contains(needle),
                "{what}: {needle:?} missing from {text}"
            );
        }
        server.set_faults(Faults::default());
    }
}

#[test]
fn a_block_that_stays_broken_is_counted_drawn_coarser_and_retried_with_back_off() {
    let fx = fixture();
    let (cams, scale) = cameras(&fx, 150);
    let victim = first_loaded(&fx, &cams, scale);
    assert_ne!(victim, root(&fx));

    let server = fault_server(&fx);
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    let src = Arc::new(src);
    let mut p = FramePlanner::paged_from_file(&remote, setup(src.clone())).unwrap();
    p.take_bootstrap();
    server.set_faults(Faults {
        target: Some(fx.file.blocks()[victim.idx()].offset),
        status: Some((503, u32::MAX)),
        ..Faults::default()
    });
    let (mut failures, mut coarser_frames, mut loaded) = (0u64, 0u32, 0u64);
    for (i, c) in cams.iter().enumerate() {
        let plan = p.plan(c, i as f64 / 30.0, scale, &mut NoResidency).unwrap();
        let s = plan.stats.paging.unwrap();
        failures += u64::from(s.session.pager.failures);
        loaded += u64::from(s.session.pager.loaded);
        coarser_frames += u32::from(s.coarse.coarser_items > 0);
        let pager = p.pager().unwrap();
        assert!(!pager.is_resident(victim), "frame {i}");
        pager.check_invariants().unwrap();
    }
    let fetches = server.seen().faults / 4; // 4 attempts per fetch
    assert_eq!(server.seen().faults % 4, 0);
    assert_eq!(failures, fetches, "every failed fetch is counted once");
    assert_eq!(p.pager().unwrap().totals().failures, failures);
    // The run can name the block and why (it reported only a count: fault hunt, session 32).
    let first = p.first_load_error().expect("the first failed load is kept");
    assert!(
        first.starts_with(&format!("block {}: ", victim.0)) && first.contains("503"),
        "{first}"
    );
    // Asked for again after 8, 16, 32, 64 … frames: at least twice, and at most once per back-off.
    assert!(
        (2..=5).contains(&fetches),
        "{fetches} fetches of the broken block in {} frames",
        cams.len()
    );
    assert!(
        coarser_frames > 0,
        "what needed the broken block is drawn coarser"
    );
    assert!(loaded > 0, "the other blocks load");
    let s = src.stats();
    assert_eq!(s.failures, fetches);
    let e = SourceError::Status {
        url: String::new(),
        block: victim,
        status: 503,
        offset: 0,
        len: 0,
        attempts: 4,
    };
    assert!(e.is_transient());
}

/// Fails every fetch of one block with the error `make` builds; the rest come from the file.
struct FailingSource {
    inner: FileSource,
    block: BlockId,
    make: fn(BlockId) -> SourceError,
    fetches: std::sync::atomic::AtomicU32,
}

impl atlastree::paging::BlockSource for FailingSource {
    fn name(&self) -> String {
        "failing".into()
    }

    fn fetch(
        &self,
        id: BlockId,
        record: &atlastree::store::format::BlockRecord,
    ) -> Result<Vec<u8>, SourceError> {
        if id == self.block {
            self.fetches
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            return Err((self.make)(id));
        }
        self.inner.fetch(id, record)
    }
}

/// Refuses every load of one block with the error `make` builds.
struct Refuse {
    block: BlockId,
    make: fn() -> ResidencyError,
    seen: u32,
}

impl Residency for Refuse {
    fn apply(&mut self, event: &Event) -> Result<u64, ResidencyError> {
        match event {
            Event::Loaded { block, .. } if *block == self.block => {
                self.seen += 1;
                Err((self.make)())
            }
            _ => Ok(0),
        }
    }
}

/// The first block a clean flight over `cams` loads after the roots.
fn first_loaded(fx: &Fixture, cams: &[Camera], scale: f64) -> BlockId {
    let mut clean = FramePlanner::paged_from_file(&fx.file, setup(file_source(fx))).unwrap();
    clean.take_bootstrap();
    let mut first = None;
    let mut record = RecordResidency(|e: &Event| {
        if let Event::Loaded { block, .. } = e {
            first.get_or_insert(*block);
        }
    });
    for (i, c) in cams.iter().enumerate() {
        clean.plan(c, i as f64 / 30.0, scale, &mut record).unwrap();
    }
    first.expect("the flight loads a block besides the root")
}

fn file_source(fx: &Fixture) -> Arc<FileSource> {
    Arc::new(FileSource::new(Arc::new(
        atlastree::store::TreeFile::open(&fx.path).unwrap(),
    )))
}

#[test]
fn the_pager_backs_off_on_transient_failures_and_gives_up_longer_on_permanent_ones() {
    let fx = fixture();
    // 150 frames; retry_frames 8: a transient failure is retried after 8, 16, 32, 64 frames (≥ 3 tries
    // while the block stays wanted); a permanent one waits the longest back-off, 64 × 8 = 512 frames.
    let (cams, scale) = cameras(&fx, 150);
    let victim = first_loaded(&fx, &cams, scale);
    type Make = fn(BlockId) -> SourceError;
    let transient: Make = |block| SourceError::Status {
        url: "u".into(),
        block,
        status: 503,
        offset: 0,
        len: 0,
        attempts: 4,
    };
    let permanent: Make = |block| SourceError::Status {
        url: "u".into(),
        block,
        status: 404,
        offset: 0,
        len: 0,
        attempts: 1,
    };
    let mut tries = Vec::new();
    for make in [transient, permanent] {
        assert_eq!(
            make(victim).is_transient(),
            std::ptr::fn_addr_eq(make, transient)
        );
        let source = Arc::new(FailingSource {
            inner: FileSource::new(Arc::new(
                atlastree::store::TreeFile::open(&fx.path).unwrap(),
            )),
            block: victim,
            make,
            fetches: Default::default(),
        });
        let mut p = FramePlanner::paged_from_file(&fx.file, setup(source.clone())).unwrap();
        p.take_bootstrap();
        for (i, c) in cams.iter().enumerate() {
            p.plan(c, i as f64 / 30.0, scale, &mut NoResidency).unwrap();
            assert!(!p.pager().unwrap().is_resident(victim));
        }
        let fetches = source.fetches.load(std::sync::atomic::Ordering::Relaxed);
        assert_eq!(p.pager().unwrap().totals().failures, u64::from(fetches));
        tries.push(fetches);
    }
    assert!(tries[0] >= 3, "transient: {tries:?}");
    assert_eq!(tries[1], 1, "permanent: {tries:?}");

    // The executor's errors: a failed upload may pass (backed off), no free layer cannot (given up).
    let mut seen = Vec::new();
    for make in [
        (|| ResidencyError::Upload {
            message: "device lost (test)".into(),
        }) as fn() -> ResidencyError,
        || ResidencyError::NoFreeLayer {
            what: "resident atlases".into(),
            needed: 9,
            limit: 8,
        },
    ] {
        let mut p = FramePlanner::paged_from_file(&fx.file, setup(file_source(&fx))).unwrap();
        p.take_bootstrap();
        let mut exec = Refuse {
            block: victim,
            make,
            seen: 0,
        };
        let mut errors = 0;
        for (i, c) in cams.iter().enumerate() {
            let plan = p.plan(c, i as f64 / 30.0, scale, &mut exec).unwrap();
            errors += plan.stats.paging.unwrap().apply_errors;
            assert!(!p.pager().unwrap().is_resident(victim));
        }
        assert_eq!(errors, exec.seen);
        seen.push(exec.seen);
    }
    assert!(seen[0] >= 3, "upload errors: {seen:?}");
    assert_eq!(seen[1], 1, "no free layer: {seen:?}");
}

/// A fetch that fails after its request was cancelled (the block left the ideal set while the server
/// died) is a failure, with its error kept for the report, not a discarded arrival charged the block's
/// bytes: a dead server read as a slow one (fault hunt, session 34). A cancelled fetch that arrives
/// with bytes is still discarded.
#[test]
fn a_failed_fetch_of_a_cancelled_request_is_a_failure() {
    use atlastree::paging::{Arrival, Pager, ViewInput};
    let fx = fixture();
    let table = BlockTable::from_file(&fx.file).unwrap();
    let trees: Vec<&[atlastree::store::format::NodeRecord]> = (0..fx.file.trees())
        .map(|i| fx.file.tree(i).unwrap().nodes)
        .collect();
    let mut pager = Pager::new(table, PagerOptions::default()).unwrap();
    let (cams, scale) = cameras(&fx, 150);
    let mut requests_at = |c: &Camera| -> Vec<BlockId> {
        let frustum = c.frustum();
        let view = ViewInput {
            eye: c.eye,
            frustum: &frustum,
            scale,
            lookahead: None,
        };
        pager.plan(&trees, &view).iter().map(|r| r.block).collect()
    };
    // Requested at the first camera...
    let wanted = requests_at(&cams[0]);
    assert!(wanted.len() >= 2, "{wanted:?}");
    // ...then cancelled: a camera that sees nothing (far below the ground, looking down).
    let away = Camera {
        eye: cams[0].eye - glam::DVec3::Y * 1e6,
        target: cams[0].eye - glam::DVec3::Y * 2e6,
        up: glam::DVec3::Z,
        ..cams[0]
    };
    let still = requests_at(&away);
    let cancelled: Vec<BlockId> = wanted.into_iter().filter(|b| !still.contains(b)).collect();
    assert!(cancelled.len() >= 2, "{cancelled:?}");
    let failed = SourceError::Status {
        url: "u".into(),
        block: cancelled[0],
        status: 503,
        offset: 0,
        len: 0,
        attempts: 4,
    };
    let arrivals = [
        Arrival {
            block: cancelled[0],
            result: Err(failed),
        },
        Arrival {
            block: cancelled[1],
            result: Ok(None),
        },
    ];
    pager.accept(arrivals, |_| atlastree::paging::Applied::Done);
    let t = pager.totals();
    assert!(t.cancelled >= 2, "{t:?}");
    assert_eq!((t.failures, t.discarded), (1, 1));
    assert!(pager.first_load_error().is_some_and(|e| e.contains("503")));
}
