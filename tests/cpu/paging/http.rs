//! Blocks over HTTP (issue #5 item 5): `HttpSource` against the axum server (`atlastree serve`) and
//! against a hand-written std::net server (any static server must work), byte-for-byte equality with the
//! local file, tables from a prefix equal the file's, and the faults a network produces: 503s, corrupt,
//! truncated and dropped answers, a server that stalls, stops, and comes back on the same port, 404s.
//! Every failure is an error value within a bounded time; nothing panics.

use super::http_server::{FaultServer, Faults};
use atlastree::ids::BlockId;
use atlastree::paging::serve;
use atlastree::paging::{BlockSource, HttpOptions, HttpSource, SourceError};
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::scene::synthetic::small_city;
use atlastree::store::format::HEADER_SIZE;
use atlastree::store::{StoreError, TreeFile};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

/// A built tree file in a temporary directory.
pub(super) struct Fixture {
    _dir: tempfile::TempDir,
    pub(super) path: PathBuf,
    pub(super) bytes: Arc<Vec<u8>>,
    pub(super) file: TreeFile,
}

/// The bytes of a small built tree (23 blocks, about 1.4 MB, depth 2), built once per test binary; each
/// test gets its own copy on disk.
fn tree_bytes() -> Arc<Vec<u8>> {
    static BYTES: OnceLock<Arc<Vec<u8>>> = OnceLock::new();
    BYTES
        .get_or_init(|| {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("city.atlastree");
            let opts = BuildOptions {
                d_min: DMin::Ratio(20.0),
                atlas_size: 128,
                max_file_bytes: 1 << 30,
                border: 8,
                // The paper's tree: every node that does not fit one atlas is split (multi-level).
                leaf_originals_atlases: 0.0,
                ..BuildOptions::default()
            };
            build(&small_city(2, 64), &opts, &path, &NoProgress).unwrap();
            Arc::new(std::fs::read(&path).unwrap())
        })
        .clone()
}

pub(super) fn fixture() -> Fixture {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("city.atlastree");
    let bytes = tree_bytes();
    std::fs::write(&path, bytes.as_slice()).unwrap();
    let file = TreeFile::open(&path).unwrap();
    assert!(file.blocks().len() >= 8, "{} blocks", file.blocks().len());
    Fixture {
        _dir: dir,
        path,
        bytes,
        file,
    }
}

pub(super) fn any_port() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

/// Fast retries for tests: 3 retries, 10 → 40 ms backoff, 2 s request timeout.
pub(super) fn quick() -> HttpOptions {
    HttpOptions {
        connect_timeout: Duration::from_secs(1),
        timeout: Duration::from_secs(2),
        retries: 3,
        backoff_initial: Duration::from_millis(10),
        backoff_max: Duration::from_millis(40),
        ..HttpOptions::default()
    }
}

pub(super) fn fault_server(fx: &Fixture) -> FaultServer {
    FaultServer::start(fx.bytes.clone(), "/city.atlastree", any_port()).unwrap()
}

pub(super) fn fetch(src: &HttpSource, file: &TreeFile, i: u32) -> Result<Vec<u8>, SourceError> {
    src.fetch(BlockId(i), &file.blocks()[i as usize])
}

/// The tables of `a` and `b` are identical: header, every record of every section, decoded forest.
fn assert_same_tables(a: &TreeFile, b: &TreeFile) {
    assert_eq!(a.header(), b.header());
    assert_eq!(a.params(), b.params());
    assert_eq!(a.materials(), b.materials());
    assert_eq!(a.blocks(), b.blocks());
    assert_eq!(a.trees(), b.trees());
    for i in 0..a.trees() {
        let (x, y) = (a.tree(i).unwrap(), b.tree(i).unwrap());
        assert_eq!(x.kind, y.kind);
        assert_eq!(x.record, y.record);
        assert_eq!(x.nodes, y.nodes);
        assert_eq!(x.leaves, y.leaves);
        assert_eq!(x.rects, y.rects);
        assert_eq!(x.originals, y.originals);
        assert_eq!(x.vertices, y.vertices);
        assert_eq!(x.indices, y.indices);
        assert_eq!(x.source_triangles, y.source_triangles);
    }
    for i in 0..a.materials().len() {
        assert_eq!(a.material_name(i), b.material_name(i));
    }
    let json = |f: &TreeFile| serde_json::to_value(f.to_forest()).unwrap();
    assert_eq!(json(a), json(b));
}

/// The checks every server must pass: open gives the file's tables; every block equals the local
/// file's byte for byte; the counters add up exactly.
fn check_every_block(fx: &Fixture, url: &str) -> HttpSource {
    let (remote, src) = HttpSource::open(url, quick()).unwrap();
    assert!(!remote.holds_blocks());
    assert_eq!(remote.path(), Path::new(url));
    assert_same_tables(&fx.file, &remote);
    assert_eq!(src.file_len(), fx.bytes.len() as u64);
    let prefix = TreeFile::prefix_len(&fx.bytes[..HEADER_SIZE]).unwrap();
    let mut block_bytes = 0;
    for i in 0..fx.file.blocks().len() as u32 {
        let got = fetch(&src, &remote, i).unwrap();
        assert_eq!(
            got,
            fx.file.block(BlockId(i)).unwrap().into_owned(),
            "block {i}"
        );
        block_bytes += got.len() as u64;
    }
    let n = fx.file.blocks().len() as u64;
    let s = src.stats();
    assert_eq!(s.requests, 2 + n, "{s:?}");
    assert_eq!(
        (s.retries, s.failures, s.full_responses),
        (0, 0, 0),
        "{s:?}"
    );
    assert_eq!(s.blocks, n);
    assert_eq!(s.bytes, HEADER_SIZE as u64 + prefix + block_bytes);
    assert!(!s.is_failing());
    src
}

#[test]
fn prefix_tables_equal_the_files_and_validate_like_open() {
    let fx = fixture();
    let len = fx.bytes.len() as u64;
    let n = TreeFile::prefix_len(&fx.bytes[..HEADER_SIZE]).unwrap();
    let b = fx.file.blocks();
    assert_eq!(
        n, b[0].offset,
        "the prefix ends where the first block starts"
    );
    assert!(n < len);
    let prefix = TreeFile::from_prefix(&fx.bytes[..n as usize], len, "http://x/city").unwrap();
    assert_same_tables(&fx.file, &prefix);
    assert!(fx.file.holds_blocks() && !prefix.holds_blocks());
    let err = prefix.block(BlockId(0)).unwrap_err();
    assert!(
        matches!(
            err,
            StoreError::BlocksNotHeld {
                block: BlockId(0),
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("http://x/city"), "{err}");
    // The whole file is a valid prefix too; a block past the table is still an out-of-range reference.
    assert!(TreeFile::from_prefix(&fx.bytes, len, "whole").is_ok());
    let past = prefix.block(BlockId(b.len() as u32)).unwrap_err();
    assert!(matches!(past, StoreError::BadReference { .. }), "{past}");

    // Too short: the missing section is named as truncation, with the length needed.
    let blocks_end = {
        let e = fx.file.header().sections[11];
        e.offset + e.length
    };
    let short = TreeFile::from_prefix(&fx.bytes[..blocks_end as usize - 1], len, "p")
        .err()
        .unwrap();
    assert!(
        matches!(short, StoreError::Truncated { needed, .. } if needed == blocks_end),
        "{short}"
    );
    // The length the server reports must be the header's.
    let e = TreeFile::from_prefix(&fx.bytes[..n as usize], len + 4096, "p")
        .err()
        .unwrap();
    assert!(matches!(e, StoreError::TrailingBytes { .. }), "{e}");
    let e = TreeFile::from_prefix(&fx.bytes[..n as usize], len - 1, "p")
        .err()
        .unwrap();
    assert!(matches!(e, StoreError::Truncated { .. }), "{e}");
    // A flipped byte in a section or in the zero gap before the first block: the checks of open().
    let mut bad = fx.bytes[..n as usize].to_vec();
    bad[fx.file.header().sections[4].offset as usize] ^= 1;
    let e = TreeFile::from_prefix(&bad, len, "p").err().unwrap();
    assert!(matches!(e, StoreError::ChecksumMismatch { .. }), "{e}");
    let mut bad = fx.bytes[..n as usize].to_vec();
    if blocks_end < n {
        bad[n as usize - 1] = 7;
        let e = TreeFile::from_prefix(&bad, len, "p").err().unwrap();
        assert!(
            matches!(e, StoreError::NonZeroPadding { offset } if offset == n - 1),
            "{e}"
        );
    }
    // prefix_len checks the header.
    let mut head = fx.bytes[..HEADER_SIZE].to_vec();
    head[20] ^= 1;
    assert!(TreeFile::prefix_len(&head).is_err());
    assert!(TreeFile::prefix_len(&fx.bytes[..HEADER_SIZE - 1]).is_err());
}

#[test]
fn every_block_over_axum_serve_equals_the_file() {
    let fx = fixture();
    let server = serve::spawn(&fx.path, any_port()).unwrap();
    assert_eq!(
        server.url(),
        format!("http://{}/city.atlastree", server.addr())
    );
    check_every_block(&fx, server.url());
    server.shutdown();
}

#[test]
fn every_block_over_a_hand_written_server_equals_the_file() {
    let fx = fixture();
    let server = fault_server(&fx);
    check_every_block(&fx, &server.url());
    let seen = server.seen();
    assert_eq!(seen.requests, 2 + fx.file.blocks().len() as u64);
    assert_eq!(seen.partial, seen.requests);
}

#[test]
fn tables_past_the_clients_memory_are_refused_before_they_are_fetched() {
    let fx = fixture();
    let server = fault_server(&fx);
    let prefix = TreeFile::prefix_len(&fx.bytes[..HEADER_SIZE]).unwrap();
    let options = HttpOptions {
        max_table_bytes: prefix - 1,
        ..quick()
    };
    let e = HttpSource::open(&server.url(), options).err().unwrap();
    match &e {
        SourceError::TablesTooLarge { bytes, limit, .. } => {
            assert_eq!((*bytes, *limit), (prefix, prefix - 1));
        }
        other => panic!("expected TablesTooLarge, got {other}"),
    }
    assert!(e.to_string().contains("of tables, more than"), "{e}");
    // Only the header was asked for.
    assert_eq!(server.seen().requests, 1);
    // At the limit the tables are fetched.
    let options = HttpOptions {
        max_table_bytes: prefix,
        ..quick()
    };
    let (remote, _) = HttpSource::open(&server.url(), options).unwrap();
    assert_same_tables(&fx.file, &remote);
}

#[test]
fn a_server_that_ignores_range_works_and_is_counted() {
    let fx = fixture();
    let server = fault_server(&fx);
    server.set_faults(Faults {
        ignore_range: true,
        ..Faults::default()
    });
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    assert_same_tables(&fx.file, &remote);
    for i in 0..fx.file.blocks().len() as u32 {
        assert_eq!(
            fetch(&src, &remote, i).unwrap(),
            fx.file.block(BlockId(i)).unwrap().into_owned()
        );
    }
    let s = src.stats();
    assert_eq!(s.full_responses, s.requests);
    assert_eq!((s.retries, s.failures), (0, 0));
    assert_eq!(server.seen().partial, 0);
    eprintln!(
        "{} blocks, {} bytes; {s:?}",
        fx.file.blocks().len(),
        fx.bytes.len()
    );
}

#[test]
fn unavailable_503_then_ok_succeeds_after_retries() {
    let fx = fixture();
    let server = fault_server(&fx);
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    let before = src.stats();
    server.set_faults(Faults {
        status: Some((503, 2)),
        ..Faults::default()
    });
    assert_eq!(
        fetch(&src, &remote, 3).unwrap(),
        fx.file.block(BlockId(3)).unwrap().into_owned()
    );
    let s = src.stats();
    assert_eq!(s.requests - before.requests, 3);
    assert_eq!(s.retries - before.retries, 2);
    assert_eq!(s.failures, 0);

    // More 503s than retries: a Status error after exactly retries + 1 requests; then it recovers.
    server.set_faults(Faults {
        status: Some((503, 10)),
        ..Faults::default()
    });
    let before = src.stats();
    let e = fetch(&src, &remote, 3).unwrap_err();
    assert!(matches!(e, SourceError::Status { status: 503, .. }), "{e}");
    let s = src.stats();
    assert_eq!(s.requests - before.requests, 4);
    assert_eq!((s.failures, s.consecutive_failures), (1, 1));
    assert!(s.is_failing());
    server.set_faults(Faults::default());
    assert!(fetch(&src, &remote, 3).is_ok());
    assert!(!src.stats().is_failing());
}

#[test]
fn not_found_is_not_retried() {
    let fx = fixture();
    let server = fault_server(&fx);
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    server.set_faults(Faults {
        status: Some((404, 10)),
        ..Faults::default()
    });
    let before = src.stats();
    let e = fetch(&src, &remote, 1).unwrap_err();
    assert!(matches!(e, SourceError::Status { status: 404, .. }), "{e}");
    let s = src.stats();
    assert_eq!((s.requests - before.requests, s.retries), (1, 0));

    // A wrong path at open, on both servers: one request, a Tables error naming the status.
    let axum = serve::spawn(&fx.path, any_port()).unwrap();
    for url in [
        format!("{}.missing", server.url()),
        format!("{}x", axum.url()),
    ] {
        let t = Instant::now();
        let e = HttpSource::open(&url, quick()).err().unwrap();
        assert!(
            matches!(&e, SourceError::Tables { attempts: 1, message, .. } if message.contains("404")),
            "{e}"
        );
        assert!(t.elapsed() < Duration::from_secs(2));
    }
}

#[test]
fn corrupted_bytes_are_retried_then_a_checksum_error() {
    let fx = fixture();
    let server = fault_server(&fx);
    // Corrupt tables at open (the header, then the prefix): asked again, then opened.
    for faults in [
        Faults {
            corrupt: 1,
            ..Faults::default()
        },
        Faults {
            corrupt: 2,
            ..Faults::default()
        },
    ] {
        server.set_faults(faults);
        let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
        assert_same_tables(&fx.file, &remote);
        let s = src.stats();
        assert_eq!((s.checksum_failures, s.failures), (s.retries, 0), "{s:?}");
        assert!(s.retries >= 1, "{s:?}");
    }
    server.set_faults(Faults {
        corrupt: 100,
        ..Faults::default()
    });
    let e = HttpSource::open(&server.url(), quick()).err().unwrap();
    assert!(
        matches!(&e, SourceError::Tables { attempts: 4, message, .. } if message.contains("checksum")),
        "{e}"
    );
    server.set_faults(Faults::default());
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    // Once corrupt (a transfer that may pass): retried, then the right bytes.
    server.set_faults(Faults {
        corrupt: 1,
        ..Faults::default()
    });
    let before = src.stats();
    assert_eq!(
        fetch(&src, &remote, 2).unwrap(),
        fx.file.block(BlockId(2)).unwrap().into_owned()
    );
    let s = src.stats();
    assert_eq!(
        (s.requests - before.requests, s.retries - before.retries),
        (2, 1)
    );
    assert_eq!((s.checksum_failures, s.failures), (1, 0));
    // Always corrupt: a Checksum error after exactly retries + 1 attempts, transient for the pager.
    server.set_faults(Faults {
        corrupt: 100,
        ..Faults::default()
    });
    let before = src.stats();
    let e = fetch(&src, &remote, 2).unwrap_err();
    let expected = fx.file.blocks()[2].checksum;
    assert!(
        matches!(e, SourceError::Checksum { block: BlockId(2), expected: x, attempts: 4, .. } if x == expected),
        "{e}"
    );
    assert!(e.is_transient() && e.attempts() == 4);
    let s = src.stats();
    assert_eq!(
        (s.requests - before.requests, s.retries - before.retries),
        (4, 3)
    );
    assert_eq!((s.checksum_failures, s.failures), (5, 1));
    server.set_faults(Faults::default());
    assert_eq!(
        fetch(&src, &remote, 2).unwrap(),
        fx.file.block(BlockId(2)).unwrap().into_owned()
    );
}

#[test]
fn a_wrong_content_range_is_retried_then_reported() {
    let fx = fixture();
    let server = fault_server(&fx);
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    server.set_faults(Faults {
        wrong_range: 2,
        ..Faults::default()
    });
    let before = src.stats();
    assert_eq!(
        fetch(&src, &remote, 5).unwrap(),
        fx.file.block(BlockId(5)).unwrap().into_owned()
    );
    assert_eq!(src.stats().requests - before.requests, 3);
    server.set_faults(Faults {
        wrong_range: 100,
        ..Faults::default()
    });
    let e = fetch(&src, &remote, 5).unwrap_err();
    assert!(
        matches!(
            &e,
            SourceError::WrongRange {
                block: BlockId(5),
                attempts: 4,
                permanent: false,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.is_transient());
    assert!(e.to_string().contains("after 4 attempt"), "{e}");
}

#[test]
fn headers_then_a_stalled_body_times_out_and_is_retried() {
    let fx = fixture();
    let server = fault_server(&fx);
    let options = HttpOptions {
        timeout: Duration::from_millis(300),
        retries: 2,
        ..quick()
    };
    let (remote, src) = HttpSource::open(&server.url(), options).unwrap();
    // Headers sent, body never: one timed-out attempt, then the right bytes.
    server.set_faults(Faults {
        stall_body: 1,
        ..Faults::default()
    });
    let t = Instant::now();
    assert_eq!(
        fetch(&src, &remote, 1).unwrap(),
        fx.file.block(BlockId(1)).unwrap().into_owned()
    );
    let took = t.elapsed();
    assert!(
        took >= Duration::from_millis(300) && took < Duration::from_secs(5),
        "{took:?}"
    );
    // Always stalled: Transport after retries + 1 attempts, each bounded by the timeout.
    server.set_faults(Faults {
        stall_body: 100,
        ..Faults::default()
    });
    let t = Instant::now();
    let e = fetch(&src, &remote, 1).unwrap_err();
    let took = t.elapsed();
    assert!(
        matches!(e, SourceError::Transport { attempts: 3, .. }),
        "{e}"
    );
    assert!(e.is_transient());
    assert!(
        took >= Duration::from_millis(900) && took < Duration::from_secs(8),
        "{took:?}"
    );
}

#[test]
fn truncated_and_dropped_answers_are_retried_then_reported() {
    let fx = fixture();
    let server = fault_server(&fx);
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    let block = |i: u32| fx.file.block(BlockId(i)).unwrap().to_vec();

    // Once truncated, once closed without an answer: both retried, then the right bytes.
    for faults in [
        Faults {
            truncate: 1,
            ..Faults::default()
        },
        Faults {
            close: 1,
            ..Faults::default()
        },
    ] {
        server.set_faults(faults);
        let before = src.stats();
        assert_eq!(fetch(&src, &remote, 4).unwrap(), block(4));
        let s = src.stats();
        assert_eq!(
            (s.requests - before.requests, s.retries - before.retries),
            (2, 1)
        );
    }

    // Always truncated: a Transport (or Length) error after retries + 1 attempts.
    server.set_faults(Faults {
        truncate: 100,
        ..Faults::default()
    });
    let before = src.stats();
    let e = fetch(&src, &remote, 4).unwrap_err();
    assert!(
        matches!(
            e,
            SourceError::Transport { attempts: 4, .. } | SourceError::Length { .. }
        ),
        "{e}"
    );
    assert_eq!(src.stats().requests - before.requests, 4);
}

#[test]
fn a_stalled_server_times_out() {
    let fx = fixture();
    let server = fault_server(&fx);
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    let options = HttpOptions {
        timeout: Duration::from_millis(300),
        retries: 1,
        ..quick()
    };
    let (_, slow) = HttpSource::open(&server.url(), options).unwrap();
    server.set_faults(Faults {
        stall: 2,
        ..Faults::default()
    });
    let t = Instant::now();
    let e = fetch(&slow, &remote, 0).unwrap_err();
    let took = t.elapsed();
    // The timeout that ran out is named with its value (ureq's "timeout: global"; session 36).
    assert!(
        matches!(&e, SourceError::Transport { attempts: 2, message, .. }
            if message.contains("request timeout of 0.3 s (--http-timeout)")),
        "{e}"
    );
    assert!(took >= Duration::from_millis(600), "{took:?}");
    assert!(took < Duration::from_secs(10), "{took:?}");
    assert!(fetch(&src, &remote, 0).is_ok());
}

/// Stop the server: fetches fail fast with an error; restart on the same port: fetches work again.
fn stop_and_restart<S>(
    fx: &Fixture,
    start: impl Fn(SocketAddr) -> S,
    url: impl Fn(&S) -> String,
    stop: impl Fn(S),
) {
    let server = start(any_port());
    let addr_url = url(&server);
    let (remote, src) = HttpSource::open(&addr_url, quick()).unwrap();
    assert!(fetch(&src, &remote, 0).is_ok());
    let port: SocketAddr = addr_url
        .trim_start_matches("http://")
        .split('/')
        .next()
        .unwrap()
        .parse()
        .unwrap();
    stop(server);
    for i in 1..4 {
        let t = Instant::now();
        let e = fetch(&src, &remote, i).unwrap_err();
        let took = t.elapsed();
        assert!(matches!(e, SourceError::Transport { .. }), "{e}");
        assert!(took < Duration::from_secs(10), "{took:?}");
        eprintln!("stopped server: block {i} failed in {took:?}: {e}");
    }
    assert!(src.stats().consecutive_failures >= 3);
    let again = start(port);
    assert_eq!(url(&again), addr_url);
    for i in 0..fx.file.blocks().len() as u32 {
        assert_eq!(
            fetch(&src, &remote, i).unwrap(),
            fx.file.block(BlockId(i)).unwrap().into_owned()
        );
    }
    assert!(!src.stats().is_failing());
    stop(again);
}

#[test]
fn stopped_then_restarted_axum_server() {
    let fx = fixture();
    stop_and_restart(
        &fx,
        |addr| serve::spawn(&fx.path, addr).unwrap(),
        |s| s.url().to_string(),
        |s| s.shutdown(),
    );
}

#[test]
fn stopped_then_restarted_hand_written_server() {
    let fx = fixture();
    stop_and_restart(
        &fx,
        |addr| FaultServer::start(fx.bytes.clone(), "/city.atlastree", addr).unwrap(),
        |s| s.url(),
        |s| s.stop(),
    );
}

#[test]
fn opening_a_dead_server_fails_quickly() {
    let addr = {
        let l = std::net::TcpListener::bind(any_port()).unwrap();
        l.local_addr().unwrap()
    };
    let t = Instant::now();
    let e = HttpSource::open(&format!("http://{addr}/city.atlastree"), quick())
        .err()
        .unwrap();
    assert!(matches!(e, SourceError::Tables { attempts: 4, .. }), "{e}");
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    // Not HTTP at all: a bad URL is not retried.
    let e = HttpSource::open("not a url", quick()).err().unwrap();
    assert!(matches!(e, SourceError::Tables { attempts: 1, .. }), "{e}");
}

#[test]
fn a_server_holding_another_file_is_refused() {
    let fx = fixture();
    // Same tables, one byte more at the end: the lengths disagree.
    let mut longer = fx.bytes.to_vec();
    longer.push(0);
    let server = FaultServer::start(Arc::new(longer), "/city.atlastree", any_port()).unwrap();
    let e = HttpSource::open(&server.url(), quick()).err().unwrap();
    assert!(
        matches!(
            &e,
            SourceError::Store {
                error: StoreError::TrailingBytes { .. },
                ..
            }
        ),
        "{e}"
    );
    // Not a paging file.
    let not_paging = |e: &SourceError| {
        matches!(
            e,
            SourceError::Store {
                error: StoreError::BadMagic { .. },
                ..
            }
        )
    };
    let junk = FaultServer::start(Arc::new(vec![7u8; 4096]), "/j", any_port()).unwrap();
    let e = HttpSource::open(&junk.url(), quick()).err().unwrap();
    assert!(not_paging(&e), "{e}");
    // Shorter than a header: the server answers a shorter range than asked for; refused, not retried.
    let tiny = FaultServer::start(Arc::new(vec![0u8; 10]), "/t", any_port()).unwrap();
    let e = HttpSource::open(&tiny.url(), quick()).err().unwrap();
    assert!(matches!(&e, SourceError::Tables { attempts: 1, .. }), "{e}");
    // A short page from a server that ignores Range (a `200` of 29 bytes): said to be no paging file,
    // once, not "got 29 of 528 bytes" after four tries (fault hunt, session 34).
    let page = b"<html><body>hi</body></html>\n".to_vec();
    let html = FaultServer::start(Arc::new(page), "/index.html", any_port()).unwrap();
    html.set_faults(Faults {
        ignore_range: true,
        ..Faults::default()
    });
    let e = HttpSource::open(&html.url(), quick()).err().unwrap();
    assert!(not_paging(&e) && e.to_string().contains("<html>"), "{e}");
    assert_eq!(html.seen().requests, 1);
}

#[test]
fn concurrent_loader_threads_get_every_block() {
    let fx = fixture();
    let server = serve::spawn(&fx.path, any_port()).unwrap();
    let (remote, src) = HttpSource::open(server.url(), quick()).unwrap();
    let (remote, src) = (Arc::new(remote), Arc::new(src));
    let n = fx.file.blocks().len() as u32;
    let threads: Vec<_> = (0..4u32)
        .map(|t| {
            let (remote, src) = (remote.clone(), src.clone());
            std::thread::spawn(move || {
                (0..n)
                    .filter(|i| i % 4 == t)
                    .map(|i| (i, fetch(&src, &remote, i).unwrap()))
                    .collect::<Vec<_>>()
            })
        })
        .collect();
    let mut got = 0;
    for t in threads {
        for (i, bytes) in t.join().unwrap() {
            assert_eq!(bytes, fx.file.block(BlockId(i)).unwrap().into_owned());
            got += 1;
        }
    }
    assert_eq!(got, n);
    assert_eq!(src.stats().blocks, n as u64);
}

/// A server that sends the bytes with a `Content-Encoding` (a pre-compressed object on a CDN) is named at
/// once, not retried and read as a short body; one whose `Content-Range` total is no longer the length
/// the file had when opened (replaced on the server) is named so, not read as corrupt blocks; a fetch
/// whose every answer failed its checksum is counted apart from failures of other causes (fault hunt,
/// session 36).
#[test]
fn an_encoded_body_a_replaced_file_and_checksum_fetches_are_named() {
    let fx = fixture();
    let server = fault_server(&fx);
    let (remote, src) = HttpSource::open(&server.url(), quick()).unwrap();
    server.set_faults(Faults {
        encoding: Some("gzip"),
        ..Faults::default()
    });
    let before = src.stats();
    let e = fetch(&src, &remote, 1).unwrap_err();
    assert!(
        matches!(&e, SourceError::Request { message, .. } if message.contains("Content-Encoding: gzip")),
        "{e}"
    );
    assert_eq!(src.stats().requests - before.requests, 1, "not retried");
    let len = fx.bytes.len() as u64;
    server.set_faults(Faults {
        claimed_total: Some(len + 4096),
        ..Faults::default()
    });
    let before = src.stats();
    let e = fetch(&src, &remote, 1).unwrap_err();
    let says = format!("now {} bytes, {len} when it was opened", len + 4096);
    assert!(
        matches!(&e, SourceError::WrongRange { message, permanent: true, .. } if message.contains(&says)),
        "{e}"
    );
    assert!(!e.is_transient());
    let s = src.stats();
    assert_eq!(s.requests - before.requests, 1, "not retried");
    assert_eq!(s.checksum_failures, before.checksum_failures);
    // Failures of other causes are not checksum fetch failures; a block corrupt on every attempt is.
    assert_eq!(s.checksum_fetch_failures, 0);
    server.set_faults(Faults {
        corrupt: 100,
        ..Faults::default()
    });
    let e = fetch(&src, &remote, 2).unwrap_err();
    assert!(matches!(e, SourceError::Checksum { .. }), "{e}");
    assert_eq!(src.stats().checksum_fetch_failures, 1);
}
