//! Fuzz target `http`: the HTTP block source ([`HttpSource`]) against a loopback fake server whose every
//! answer is chosen by the fuzz bytes — a right `206`, a wrong `Content-Range`, a short or a long body,
//! `200` with the whole file instead of `206`, `416`/`500`/`503`/`404`, garbage instead of a response
//! head, a stalled connection, a connection closed mid-body or before answering, a corrupt body.
//!
//! Each case starts the server (std::net on 127.0.0.1:0, one thread per connection), opens the file with
//! small millisecond timeouts and few retries, and reads a few blocks. Refused: open or a fetch failed
//! with an error. Accepted: every read succeeded. AcceptedCorruption: the tables differ from the file's or
//! a block's bytes differ from the true block (a wrong block delivered as right).

use crate::harness::{self, Verdict};
use arbitrary::Unstructured;
use atlastree::ids::BlockId;
use atlastree::paging::{BlockSource, HttpOptions, HttpSource};
use atlastree::store::TreeFile;
use std::io::{BufRead, BufReader, Write};
use std::net::{Shutdown, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// About 15 s in CI release on 2 cores (220 cases took 5.2 s; stalls cost a client timeout each).
const DEFAULT_CASES: u64 = 600;
/// Client timeout per request: a stalled answer costs this much.
const TIMEOUT: Duration = Duration::from_millis(60);
/// A stalled connection is held at most this long (the case's stop ends it sooner).
const STALL_MAX: Duration = Duration::from_millis(400);

/// The true file: the shared tiny paging file (`tests/fixtures/tiny_store.rs`) and its parsed tables.
struct Truth {
    bytes: &'static [u8],
    file: &'static TreeFile,
}

fn truth() -> Truth {
    Truth {
        bytes: crate::tiny_store::tiny_paging_file(),
        file: crate::tiny_store::tiny_paging_tree(),
    }
}

/// What the server does with one request.
#[derive(Copy, Clone, Debug, arbitrary::Arbitrary)]
enum Action {
    Right,
    /// `206` whose `Content-Range` is off by `shift` (first and last), or names another total.
    WrongRange {
        shift: i8,
        other_total: bool,
    },
    /// `Content-Length` as asked, `keep` of 256ths of the body sent, then closed.
    ShortBody {
        keep: u8,
    },
    /// `extra` bytes more than asked, declared in `Content-Length`.
    LongBody {
        extra: u8,
    },
    /// `200` with the whole file.
    Full,
    Status {
        which: u8,
    },
    /// Random bytes instead of a response head.
    Garbage {
        len: u8,
        seed: u8,
    },
    /// Headers (or nothing) then silence until the case ends.
    Stall {
        after_headers: bool,
    },
    CloseBeforeAnswer,
    /// One byte of the body flipped.
    Corrupt {
        at: u16,
    },
}

struct Script {
    actions: Vec<Action>,
    next: AtomicUsize,
}

impl Script {
    /// The action of the next request (the script repeats its last action, or answers right when empty).
    fn take(&self) -> Action {
        let i = self.next.fetch_add(1, Ordering::Relaxed);
        match self.actions.get(i) {
            Some(a) => *a,
            None => Action::Right,
        }
    }
}

struct FakeServer {
    url: String,
    stop: Arc<AtomicBool>,
    accept: Option<JoinHandle<()>>,
    conns: Arc<Mutex<Vec<JoinHandle<()>>>>,
}

impl FakeServer {
    fn start(script: Script) -> std::io::Result<FakeServer> {
        let listener = TcpListener::bind("127.0.0.1:0")?;
        listener.set_nonblocking(true)?;
        let url = format!("http://{}/city.atlastree", listener.local_addr()?);
        let stop = Arc::new(AtomicBool::new(false));
        let conns: Arc<Mutex<Vec<JoinHandle<()>>>> = Arc::default();
        let script = Arc::new(script);
        let (s, c) = (stop.clone(), conns.clone());
        let accept = std::thread::spawn(move || {
            while !s.load(Ordering::SeqCst) {
                match listener.accept() {
                    Ok((stream, _)) => {
                        let (s, script) = (s.clone(), script.clone());
                        let h = std::thread::spawn(move || connection(stream, &script, &s));
                        c.lock().unwrap_or_else(|e| e.into_inner()).push(h);
                    }
                    Err(_) => std::thread::sleep(Duration::from_millis(1)),
                }
            }
        });
        Ok(FakeServer {
            url,
            stop,
            accept: Some(accept),
            conns,
        })
    }
}

impl Drop for FakeServer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(a) = self.accept.take() {
            let _ = a.join();
        }
        let conns = std::mem::take(&mut *self.conns.lock().unwrap_or_else(|e| e.into_inner()));
        for c in conns {
            let _ = c.join();
        }
    }
}

/// `bytes=a-b` of a request head, if any.
fn read_range(reader: &mut impl BufRead) -> Option<Option<(u64, u64)>> {
    let mut line = String::new();
    if reader.read_line(&mut line).ok()? == 0 {
        return None;
    }
    let mut range = None;
    loop {
        let mut h = String::new();
        if reader.read_line(&mut h).ok()? == 0 {
            return None;
        }
        let h = h.trim_end();
        if h.is_empty() {
            return Some(range);
        }
        if let Some((name, value)) = h.split_once(':')
            && name.trim().eq_ignore_ascii_case("range")
            && let Some((a, b)) = value.trim().trim_start_matches("bytes=").split_once('-')
        {
            range = a.parse().ok().zip(b.parse().ok());
        }
    }
}

fn connection(stream: TcpStream, script: &Script, stop: &AtomicBool) {
    let _ = stream.set_read_timeout(Some(STALL_MAX));
    let Ok(mut out) = stream.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(stream);
    while let Some(range) = read_range(&mut reader) {
        if !answer(&mut out, range, script.take(), stop) {
            break;
        }
    }
    let _ = out.shutdown(Shutdown::Both);
}

fn stall(stop: &AtomicBool) {
    let t = Instant::now();
    while !stop.load(Ordering::SeqCst) && t.elapsed() < STALL_MAX {
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// Answers one request; false when the connection must close.
fn answer(
    out: &mut TcpStream,
    range: Option<(u64, u64)>,
    action: Action,
    stop: &AtomicBool,
) -> bool {
    let data = truth().bytes;
    let len = data.len() as u64;
    let (first, last) = range.unwrap_or((0, len.saturating_sub(1)));
    let last = last.min(len.saturating_sub(1));
    let body: &[u8] = data.get(first as usize..=last as usize).unwrap_or(&[]);
    let head = |status: &str, headers: &[String]| {
        let mut t = format!("HTTP/1.1 {status}\r\n");
        for h in headers {
            t.push_str(h);
            t.push_str("\r\n");
        }
        t.push_str("\r\n");
        t.into_bytes()
    };
    let partial = |cr: String, n: usize| {
        head(
            "206 Partial Content",
            &[
                format!("Content-Range: {cr}"),
                format!("Content-Length: {n}"),
            ],
        )
    };
    let right = format!("bytes {first}-{last}/{len}");
    let w = |out: &mut TcpStream, bytes: &[u8]| out.write_all(bytes).is_ok();
    match action {
        Action::Right => w(out, &partial(right, body.len())) && w(out, body),
        Action::WrongRange { shift, other_total } => {
            let s = i64::from(shift);
            let total = if other_total { len + 4096 } else { len };
            let cr = format!(
                "bytes {}-{}/{total}",
                (first as i64 + s).max(0),
                (last as i64 + s).max(0)
            );
            w(out, &partial(cr, body.len())) && w(out, body)
        }
        Action::ShortBody { keep } => {
            let n = body.len() * usize::from(keep) / 256;
            let _ = w(out, &partial(right, body.len())) && w(out, &body[..n]);
            false
        }
        Action::LongBody { extra } => {
            let mut b = body.to_vec();
            b.extend(std::iter::repeat_n(0xAB, usize::from(extra)));
            w(out, &partial(right, b.len())) && w(out, &b)
        }
        Action::Full => {
            w(out, &head("200 OK", &[format!("Content-Length: {len}")])) && w(out, data)
        }
        Action::Status { which } => {
            let status = [
                "416 Range Not Satisfiable",
                "500 Internal Server Error",
                "503 Service Unavailable",
                "404 Not Found",
            ][usize::from(which % 4)];
            w(out, &head(status, &["Content-Length: 0".into()]))
        }
        Action::Garbage { len, seed } => {
            let junk: Vec<u8> = (0..u32::from(len) + 1)
                .map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed))
                .collect();
            let _ = w(out, &junk);
            false
        }
        Action::Stall { after_headers } => {
            if after_headers {
                let _ = w(out, &partial(right, body.len()));
            }
            stall(stop);
            false
        }
        Action::CloseBeforeAnswer => false,
        Action::Corrupt { at } => {
            let mut b = body.to_vec();
            if !b.is_empty() {
                let i = usize::from(at) % b.len();
                b[i] ^= 0x10;
            }
            w(out, &partial(right, b.len())) && w(out, &b)
        }
    }
}

fn case(bytes: &[u8]) -> Verdict {
    let t = truth();
    let mut u = Unstructured::new(bytes);
    let Ok(n) = u.int_in_range(0..=12usize) else {
        return Verdict::Skipped;
    };
    let mut actions = Vec::with_capacity(n);
    for _ in 0..n {
        let Ok(a) = u.arbitrary::<Action>() else {
            return Verdict::Skipped;
        };
        actions.push(a);
    }
    let (Ok(retries), Ok(picks)) = (u.int_in_range(0..=2u32), u.int_in_range(1..=3usize)) else {
        return Verdict::Skipped;
    };
    let blocks = t.file.blocks().len() as u32;
    let mut which = Vec::with_capacity(picks);
    for _ in 0..picks {
        match u.int_in_range(0..=blocks - 1) {
            Ok(b) => which.push(b),
            Err(_) => return Verdict::Skipped,
        }
    }
    let server = match FakeServer::start(Script {
        actions,
        next: AtomicUsize::new(0),
    }) {
        Ok(s) => s,
        // A harness fault, not the source's refusal.
        Err(e) => panic!("cannot start the fake server: {e}"),
    };
    let options = HttpOptions {
        connect_timeout: Duration::from_millis(200),
        timeout: TIMEOUT,
        retries,
        backoff_initial: Duration::from_millis(1),
        backoff_max: Duration::from_millis(2),
        ..HttpOptions::default()
    };
    let (remote, src) = match HttpSource::open(&server.url, options) {
        Ok(x) => x,
        Err(e) => {
            return Verdict::Refused(format!(
                "open: {}",
                e.to_string().replace(&server.url, "URL")
            ));
        }
    };
    if remote.header() != t.file.header() || remote.blocks() != t.file.blocks() {
        return Verdict::AcceptedCorruption("opened with other tables than the file's".into());
    }
    let mut refused = None;
    for b in which {
        let id = BlockId(b);
        let truth = t.file.block(id).expect("the true file's blocks read");
        match src.fetch(id, &t.file.blocks()[b as usize]) {
            Ok(got) if got.as_slice() == &*truth => {}
            Ok(_) => return Verdict::AcceptedCorruption(format!("{id}: wrong bytes accepted")),
            Err(e) => {
                refused = Some(format!(
                    "fetch: {}",
                    e.to_string().replace(&server.url, "URL")
                ))
            }
        }
    }
    match refused {
        Some(m) => Verdict::Refused(m),
        None => Verdict::Accepted,
    }
}

#[test]
fn http() {
    let c = harness::run("http", DEFAULT_CASES, case);
    assert!(c.accepted > 0 && c.refused > 0, "{c:?}");
}
