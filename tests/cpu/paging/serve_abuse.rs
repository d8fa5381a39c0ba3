//! `atlastree serve` under abuse (issue 23 D): other paths, malformed, unsatisfiable, multi and huge
//! `Range` headers, slow clients (slowloris), more connections than slots, and a bounded load test against
//! the server as a child process (200 concurrent connections × 3 requests, 50 slowloris connections and
//! malformed ranges at once; no failure, right statuses, still answering after, peak RSS reported).
//!
//! Range rules (see `paging::http::range`): one range → 206; none satisfiable → 416 with
//! `Content-Range: bytes */LEN`; malformed → ignored, 200 with the whole file (RFC 9110 §14.2 "MAY
//! ignore"); touching ranges coalesce into one 206; disjoint ones → 200; a head over 16 KiB → 431.

use super::http::{Fixture, any_port, fixture};
use atlastree::paging::serve::{self, ServeOptions};
use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Barrier};
use std::time::{Duration, Instant};

/// One parsed answer.
#[derive(Debug)]
struct Answer {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Answer {
    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(k, _)| k.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }
}

/// Reads one response (head, then `Content-Length` body bytes; none for HEAD).
fn read_answer(r: &mut impl BufRead, head_only: bool) -> std::io::Result<Answer> {
    let mut line = String::new();
    if r.read_line(&mut line)? == 0 {
        return Err(std::io::ErrorKind::UnexpectedEof.into());
    }
    let status = line
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| std::io::Error::other(format!("bad status line {line:?}")))?;
    let mut headers = Vec::new();
    loop {
        let mut h = String::new();
        r.read_line(&mut h)?;
        let h = h.trim_end();
        if h.is_empty() {
            break;
        }
        if let Some((k, v)) = h.split_once(':') {
            headers.push((k.trim().to_string(), v.trim().to_string()));
        }
    }
    let mut a = Answer {
        status,
        headers,
        body: Vec::new(),
    };
    let n: usize = a
        .header("content-length")
        .and_then(|v| v.parse().ok())
        .unwrap_or(0);
    if !head_only {
        a.body.resize(n, 0);
        r.read_exact(&mut a.body)?;
    }
    Ok(a)
}

/// One request on a fresh connection (`extra` header lines end in `\r\n`).
fn request(addr: SocketAddr, method: &str, path: &str, extra: &str) -> Answer {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    let req = format!("{method} {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n{extra}\r\n");
    s.write_all(req.as_bytes()).unwrap();
    read_answer(&mut BufReader::new(s), method == "HEAD").unwrap()
}

fn range(addr: SocketAddr, spec: &str) -> Answer {
    request(
        addr,
        "GET",
        "/city.atlastree",
        &format!("Range: {spec}\r\n"),
    )
}

#[test]
fn serve_refuses_other_paths_and_methods() {
    let fx = fixture();
    let server = serve::spawn(&fx.path, any_port()).unwrap();
    let addr = server.addr();
    for path in [
        "/",
        "/other",
        "/city.atlastree/x",
        "/../city.atlastree",
        "/city.atlastre",
        "/%2e%2e/etc/passwd",
    ] {
        let a = request(addr, "GET", path, "");
        assert_eq!(a.status, 404, "{path}");
    }
    for method in ["POST", "PUT", "DELETE"] {
        for path in ["/city.atlastree", "/city%2Eatlastree"] {
            let a = request(addr, method, path, "Content-Length: 0\r\n");
            assert_eq!(a.status, 405, "{method} {path}");
            assert_eq!(a.header("allow"), Some("GET,HEAD"), "{method} {path}");
        }
    }
    // The route written with other escapes names the file (a 404: fault hunt, session 32).
    for path in [
        "/city%2Eatlastree",
        "/%63ity.atlastree",
        "/city.%61tlastree",
    ] {
        let a = request(addr, "GET", path, "");
        assert_eq!(
            (a.status, a.body.as_slice()),
            (200, fx.bytes.as_slice()),
            "{path}"
        );
        let a = request(addr, "HEAD", path, "");
        assert_eq!((a.status, a.body.len()), (200, 0), "{path}");
    }
    let a = request(addr, "HEAD", "/city.atlastree", "");
    assert_eq!(a.status, 200);
    assert_eq!(
        a.header("content-length"),
        Some(fx.bytes.len().to_string().as_str())
    );
    // Ranges are for GET only, and an If-Range this server cannot match (it sends no validators) asks
    // for the whole file (RFC 9110 §14.2, §13.1.5).
    let a = request(addr, "HEAD", "/city.atlastree", "Range: bytes=0-9\r\n");
    assert_eq!(a.status, 200);
    assert_eq!(a.header("content-range"), None);
    let a = request(
        addr,
        "GET",
        "/city.atlastree",
        "Range: bytes=0-9\r\nIf-Range: \"abc\"\r\n",
    );
    assert_eq!((a.status, a.body.as_slice()), (200, fx.bytes.as_slice()));
    let a = request(addr, "GET", "/city.atlastree", "");
    assert_eq!((a.status, a.body.as_slice()), (200, fx.bytes.as_slice()));
    // The four above and the six of the equivalent paths; 404s and 405s are not the file's.
    assert_eq!(server.stats().requests, 10);
}

#[test]
fn serve_answers_ranges_as_rfc_9110_allows() {
    let fx = fixture();
    let server = serve::spawn(&fx.path, any_port()).unwrap();
    let addr = server.addr();
    let len = fx.bytes.len();
    let whole = |a: &Answer| a.status == 200 && a.body == *fx.bytes;
    // One range, clamped; suffix; open-ended.
    let a = range(addr, "bytes=10-19");
    assert_eq!((a.status, a.body.as_slice()), (206, &fx.bytes[10..20]));
    assert_eq!(
        a.header("content-range"),
        Some(format!("bytes 10-19/{len}").as_str())
    );
    let a = range(addr, &format!("bytes={}-99999999999", len - 5));
    assert_eq!((a.status, a.body.as_slice()), (206, &fx.bytes[len - 5..]));
    let a = range(addr, "bytes=-7");
    assert_eq!((a.status, a.body.as_slice()), (206, &fx.bytes[len - 7..]));
    // A last byte past 2⁶⁴ is well-formed (RFC 9110 bounds no digit count): clamped like any other.
    let a = range(addr, "bytes=0-99999999999999999999999");
    assert_eq!((a.status, a.body.as_slice()), (206, &fx.bytes[..]));
    // Unsatisfiable: 416 with the length.
    for spec in [
        format!("bytes={len}-"),
        "bytes=-0".into(),
        format!("bytes={}-{}", len + 10, len + 20),
        "bytes=18446744073709551616-".into(),
    ] {
        let a = range(addr, &spec);
        assert_eq!(a.status, 416, "{spec}");
        assert_eq!(
            a.header("content-range"),
            Some(format!("bytes */{len}").as_str()),
            "{spec}"
        );
    }
    // Malformed: ignored, the whole file.
    for spec in [
        "bytes=5-1",
        "bytes=x-y",
        "lines=0-1",
        "bytes",
        "bytes=1-2-3",
    ] {
        assert!(whole(&range(addr, spec)), "{spec}");
    }
    // Several ranges: touching ones coalesce; disjoint ones get the whole file; too many are ignored.
    let a = range(addr, "bytes=0-9,10-19,5-12");
    assert_eq!((a.status, a.body.as_slice()), (206, &fx.bytes[..20]));
    assert!(whole(&range(addr, "bytes=0-9,100-109")));
    let many: Vec<String> = (0..500).map(|i| format!("{}-{}", 2 * i, 2 * i)).collect();
    assert!(whole(&range(addr, &format!("bytes={}", many.join(",")))));
    // A head over 16 KiB: 431, and the server goes on.
    let huge = format!("bytes=0-0{}", ",0-0".repeat(6000));
    assert_eq!(range(addr, &huge).status, 431);
    let s = server.stats();
    assert_eq!((s.partial, s.unsatisfiable), (5, 4), "{s:?}");
    assert_eq!(range(addr, "bytes=0-0").status, 206);
}

/// Opens a connection that sends a request head one byte per `every` and never finishes it.
/// A file renamed over the served path (as `build -o` publishes a new one) is not served: the server
/// keeps the file it checked at start (it re-opened the path per request, so a running `render URL`
/// got another file's bytes, failed every block's checksum and drew coarser to the end).
#[test]
fn a_file_renamed_over_the_served_path_is_not_served() {
    let fx = fixture();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("city.atlastree");
    std::fs::copy(&fx.path, &path).unwrap();
    let server = serve::spawn(&path, any_port()).unwrap();
    let addr = server.addr();
    assert_eq!(range(addr, "bytes=0-4095").body, fx.bytes[..4096]);
    let other = dir.path().join("other.tmp");
    std::fs::write(&other, vec![0xA5u8; fx.bytes.len()]).unwrap();
    std::fs::rename(&other, &path).unwrap();
    let a = range(addr, "bytes=0-4095");
    assert_eq!((a.status, &a.body[..]), (206, &fx.bytes[..4096]));
    let whole = request(addr, "GET", "/city.atlastree", "");
    assert!(whole.body == *fx.bytes, "the whole file is the one checked");
}

fn slowloris(
    addr: SocketAddr,
    every: Duration,
    stop: Instant,
) -> std::thread::JoinHandle<Option<Duration>> {
    std::thread::spawn(move || {
        let t = Instant::now();
        let mut s = TcpStream::connect(addr).ok()?;
        s.set_read_timeout(Some(Duration::from_millis(20))).ok()?;
        let head = b"GET /city.atlastree HTTP/1.1\r\nHost: x\r\nX-Slow: ";
        let mut i = 0usize;
        let mut buf = [0u8; 256];
        while Instant::now() < stop {
            let byte = head.get(i).copied().unwrap_or(b'a');
            i += 1;
            if s.write_all(&[byte]).is_err() {
                return Some(t.elapsed());
            }
            match s.read(&mut buf) {
                Ok(0) | Ok(_) => return Some(t.elapsed()), // closed (or answered 408)
                Err(e)
                    if e.kind() == std::io::ErrorKind::WouldBlock
                        || e.kind() == std::io::ErrorKind::TimedOut => {}
                Err(_) => return Some(t.elapsed()),
            }
            std::thread::sleep(every);
        }
        None // still open at the deadline
    })
}

#[test]
fn slow_clients_are_closed_and_the_server_keeps_answering() {
    let fx = fixture();
    let options = ServeOptions {
        header_timeout: Duration::from_millis(400),
        ..ServeOptions::default()
    };
    let server = serve::spawn_with(&fx.path, any_port(), options).unwrap();
    let addr = server.addr();
    let stop = Instant::now() + Duration::from_secs(5);
    let slow: Vec<_> = (0..20)
        .map(|_| slowloris(addr, Duration::from_millis(50), stop))
        .collect();
    std::thread::sleep(Duration::from_millis(100));
    let a = range(addr, "bytes=0-99");
    assert_eq!((a.status, a.body.as_slice()), (206, &fx.bytes[..100]));
    for h in slow {
        let closed = h
            .join()
            .unwrap()
            .expect("a slowloris connection outlived 5 s");
        assert!(closed < Duration::from_secs(2), "closed after {closed:?}");
    }
    assert!(server.stats().closed_on_error >= 20, "{:?}", server.stats());
    assert_eq!(range(addr, "bytes=0-0").status, 206);
}

#[test]
fn connections_over_the_limit_wait_then_get_503() {
    let fx = fixture();
    let options = ServeOptions {
        max_connections: 4,
        admission_wait: Duration::from_millis(300),
        header_timeout: Duration::from_secs(3),
        ..ServeOptions::default()
    };
    let server = serve::spawn_with(&fx.path, any_port(), options).unwrap();
    let addr = server.addr();
    // Four connections hold every slot (heads never finished).
    let holders: Vec<TcpStream> = (0..4)
        .map(|_| {
            let mut s = TcpStream::connect(addr).unwrap();
            s.write_all(b"GET /city.atlastree HTTP/1.1\r\n").unwrap();
            s
        })
        .collect();
    std::thread::sleep(Duration::from_millis(100));
    let t = Instant::now();
    let a = range(addr, "bytes=0-9");
    let waited = t.elapsed();
    assert_eq!(a.status, 503);
    assert_eq!(a.header("retry-after"), Some("1"));
    assert!(
        waited >= Duration::from_millis(250) && waited < Duration::from_secs(3),
        "{waited:?}"
    );
    assert_eq!(server.stats().rejected, 1);
    // A slot freed while waiting: served.
    let waiter = std::thread::spawn(move || range(addr, "bytes=0-9"));
    std::thread::sleep(Duration::from_millis(50));
    drop(holders);
    let a = waiter.join().unwrap();
    assert_eq!((a.status, a.body.as_slice()), (206, &fx.bytes[..10]));
    assert_eq!(server.stats().rejected, 1);
}

/// `VmHWM` (peak resident set) of process `pid`, kB.
fn peak_rss_kb(pid: u32) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

fn keep_alive_requests(addr: SocketAddr, fx: &Fixture, seed: u64, n: usize) -> Result<(), String> {
    let s = TcpStream::connect(addr).map_err(|e| e.to_string())?;
    s.set_read_timeout(Some(Duration::from_secs(20)))
        .map_err(|e| e.to_string())?;
    let mut w = s.try_clone().map_err(|e| e.to_string())?;
    let mut r = BufReader::new(s);
    let blocks = fx.file.blocks();
    for k in 0..n {
        let b = &blocks[((seed * 7 + k as u64 * 13) % blocks.len() as u64) as usize];
        let (first, last) = (b.offset, b.offset + b.length - 1);
        let req = format!(
            "GET /city.atlastree HTTP/1.1\r\nHost: x\r\nRange: bytes={first}-{last}\r\n\r\n"
        );
        w.write_all(req.as_bytes()).map_err(|e| e.to_string())?;
        let a = read_answer(&mut r, false).map_err(|e| e.to_string())?;
        if a.status != 206 || a.body != fx.bytes[first as usize..=last as usize] {
            return Err(format!("status {} for bytes {first}-{last}", a.status));
        }
    }
    Ok(())
}

#[test]
fn serve_child_under_load_200_connections_50_slowloris_and_malformed_ranges() {
    const CONNECTIONS: usize = 200;
    const REQUESTS: usize = 3;
    const SLOWLORIS: usize = 50;
    let fx = Arc::new(fixture());
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_atlastree"))
        .args(["serve", "--port", "0", "--json", "--header-timeout", "1s"])
        .arg(&fx.path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let pid = child.id();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    let v: serde_json::Value = serde_json::from_str(&line).unwrap();
    let addr: SocketAddr = v["addr"].as_str().unwrap().parse().unwrap();
    let rss_idle = peak_rss_kb(pid);
    let t = Instant::now();
    let stop = t + Duration::from_secs(8);
    let slow: Vec<_> = (0..SLOWLORIS)
        .map(|_| slowloris(addr, Duration::from_millis(100), stop))
        .collect();
    let failures = Arc::new(AtomicU64::new(0));
    let barrier = Arc::new(Barrier::new(CONNECTIONS));
    let workers: Vec<_> = (0..CONNECTIONS)
        .map(|i| {
            let (fx, failures, barrier) = (fx.clone(), failures.clone(), barrier.clone());
            std::thread::spawn(move || {
                barrier.wait();
                if let Err(e) = keep_alive_requests(addr, &fx, i as u64, REQUESTS) {
                    eprintln!("connection {i}: {e}");
                    failures.fetch_add(1, Ordering::Relaxed);
                }
            })
        })
        .collect();
    // Malformed and unsatisfiable ranges meanwhile.
    let len = fx.bytes.len();
    for _ in 0..10 {
        assert_eq!(range(addr, "bytes=9-1").status, 200);
        assert_eq!(range(addr, &format!("bytes={len}-")).status, 416);
        assert_eq!(range(addr, "bytes=0-0,5-5").status, 200);
        assert_eq!(request(addr, "GET", "/nope", "").status, 404);
    }
    for w in workers {
        w.join().unwrap();
    }
    let served_in = t.elapsed();
    let slow_closed: Vec<Option<Duration>> = slow.into_iter().map(|h| h.join().unwrap()).collect();
    let a = range(addr, "bytes=0-99");
    assert_eq!(
        (a.status, a.body.as_slice()),
        (206, &fx.bytes[..100]),
        "still answering"
    );
    let rss_peak = peak_rss_kb(pid);
    let killed = std::process::Command::new("kill")
        .args(["-INT", &pid.to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    assert!(child.wait().unwrap().success());
    let failures = failures.load(Ordering::Relaxed);
    let open_slow = slow_closed.iter().filter(|c| c.is_none()).count();
    let max_slow = slow_closed
        .iter()
        .flatten()
        .max()
        .copied()
        .unwrap_or_default();
    eprintln!(
        "serve load: {CONNECTIONS} connections × {REQUESTS} requests ({} bytes file) + {SLOWLORIS} slowloris + 40 \
         malformed/unsatisfiable/404: {failures} failures in {served_in:?}; slowloris closed within {max_slow:?} \
         ({open_slow} still open); server peak RSS {rss_peak} kB (idle {rss_idle} kB)",
        len
    );
    assert_eq!(failures, 0);
    assert_eq!(
        open_slow, 0,
        "slowloris connections outlived the header timeout"
    );
    assert!(max_slow < Duration::from_secs(3), "{max_slow:?}");
    // Streaming: far less than every request buffering a block (200 × ~60 kB) on top of the idle size.
    assert!(
        rss_peak < rss_idle + 64 * 1024,
        "peak RSS {rss_peak} kB, idle {rss_idle} kB"
    );
}
