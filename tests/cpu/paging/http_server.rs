//! A tiny hand-written HTTP/1.1 static server (std::net only) for one file in memory, with single-range
//! support and injectable faults: "any other static file server must work", and the failures a real
//! network produces. Each connection runs on its own thread; keep-alive is honoured; `stop` closes the
//! listener and every open connection, so the port can be bound again by `start` at once.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Write};
use std::net::{Shutdown, SocketAddr, TcpListener, TcpStream};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Duration;

/// What the next requests get. Counts are consumed one per request, in this order of precedence:
/// `status`, `close`, `stall`, `stall_body`, `truncate`, `wrong_range`, `corrupt`; with `target` set,
/// only by requests whose range starts at that offset (the others are answered normally).
#[derive(Clone, Debug, Default)]
pub struct Faults {
    /// Answer the next `n` requests with this status and an empty body.
    pub status: Option<(u16, u32)>,
    /// Close the next `n` connections without answering.
    pub close: u32,
    /// Accept the next `n` requests and never answer (until the server stops).
    pub stall: u32,
    /// Send the headers with the full `Content-Length` but only half the body, then close.
    pub truncate: u32,
    /// Flip one byte in the middle of the body of the next `n` answers.
    pub corrupt: u32,
    /// Send the headers (full `Content-Length`) and then nothing, until the server stops.
    pub stall_body: u32,
    /// Answer `206` with a `Content-Range` one byte off (the right body).
    pub wrong_range: u32,
    /// Apply the faults only to requests whose range starts at this byte offset (one block).
    pub target: Option<u64>,
    /// Ignore `Range` and answer `200` with the whole file (persistent).
    pub ignore_range: bool,
    /// Send this `Content-Encoding` with every answer, the bytes unchanged (persistent).
    pub encoding: Option<&'static str>,
    /// Claim this total in every `Content-Range` (a file replaced by one of another length; persistent).
    pub claimed_total: Option<u64>,
}

/// What the server saw.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Seen {
    /// Requests read (well-formed or not).
    pub requests: u64,
    /// Requests answered `206`.
    pub partial: u64,
    /// Faults applied.
    pub faults: u64,
}

struct Shared {
    data: Arc<Vec<u8>>,
    path: String,
    faults: Mutex<Faults>,
    seen: Mutex<Seen>,
    stop: AtomicBool,
    conns: Mutex<Vec<TcpStream>>,
}

pub struct FaultServer {
    addr: SocketAddr,
    shared: Arc<Shared>,
    accept: Option<JoinHandle<()>>,
}

impl FaultServer {
    /// Serves `data` at `http://addr/path` (`path` starts with `/`); port 0 picks a free one.
    pub fn start(data: Arc<Vec<u8>>, path: &str, addr: SocketAddr) -> std::io::Result<FaultServer> {
        let listener = TcpListener::bind(addr)?;
        listener.set_nonblocking(true)?;
        let addr = listener.local_addr()?;
        let shared = Arc::new(Shared {
            data,
            path: path.to_string(),
            faults: Mutex::new(Faults::default()),
            seen: Mutex::new(Seen::default()),
            stop: AtomicBool::new(false),
            conns: Mutex::new(Vec::new()),
        });
        let s = shared.clone();
        let accept = std::thread::spawn(move || accept_loop(listener, s));
        Ok(FaultServer {
            addr,
            shared,
            accept: Some(accept),
        })
    }

    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    pub fn url(&self) -> String {
        format!("http://{}{}", self.addr, self.shared.path)
    }

    /// Replaces the fault plan.
    pub fn set_faults(&self, faults: Faults) {
        *self.shared.faults.lock().unwrap() = faults;
    }

    pub fn seen(&self) -> Seen {
        self.shared.seen.lock().unwrap().clone()
    }

    /// Closes the listener and every connection; returns when the port is free.
    pub fn stop(mut self) {
        self.stop_now();
    }

    fn stop_now(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.accept.take() {
            let _ = t.join();
        }
        for c in self.shared.conns.lock().unwrap().drain(..) {
            let _ = c.shutdown(Shutdown::Both);
        }
    }
}

impl Drop for FaultServer {
    fn drop(&mut self) {
        self.stop_now();
    }
}

fn accept_loop(listener: TcpListener, shared: Arc<Shared>) {
    while !shared.stop.load(Ordering::SeqCst) {
        match listener.accept() {
            Ok((stream, _)) => {
                let _ = stream.set_nonblocking(false);
                let _ = stream.set_nodelay(true);
                if let Ok(c) = stream.try_clone() {
                    shared.conns.lock().unwrap().push(c);
                }
                let s = shared.clone();
                std::thread::spawn(move || serve_connection(stream, s));
            }
            Err(_) => std::thread::sleep(Duration::from_millis(2)),
        }
    }
}

/// A parsed request head.
struct Request {
    method: String,
    path: String,
    range: Option<String>,
    close: bool,
}

fn read_request(reader: &mut impl BufRead) -> Option<Request> {
    let mut line = String::new();
    if reader.read_line(&mut line).ok()? == 0 {
        return None;
    }
    let mut parts = line.split_whitespace();
    let method = parts.next()?.to_string();
    let path = parts.next()?.to_string();
    let (mut range, mut close) = (None, false);
    loop {
        let mut h = String::new();
        if reader.read_line(&mut h).ok()? == 0 {
            return None;
        }
        let h = h.trim_end();
        if h.is_empty() {
            break;
        }
        let (name, value) = h.split_once(':')?;
        match name.trim().to_ascii_lowercase().as_str() {
            "range" => range = Some(value.trim().to_string()),
            "connection" => close = value.trim().eq_ignore_ascii_case("close"),
            _ => {}
        }
    }
    Some(Request {
        method,
        path,
        range,
        close,
    })
}

/// `bytes=a-b`, `bytes=a-`, `bytes=-n` against a file of `len` bytes → inclusive range; `Err(())` if
/// unsatisfiable, `Ok(None)` if not a single byte range (ignored, as RFC 9110 allows).
#[allow(clippy::result_unit_err)]
pub fn parse_range(spec: &str, len: u64) -> Result<Option<(u64, u64)>, ()> {
    let Some(r) = spec.strip_prefix("bytes=") else {
        return Ok(None);
    };
    if r.contains(',') {
        return Ok(None);
    }
    let Some((a, b)) = r.split_once('-') else {
        return Ok(None);
    };
    let (a, b) = (a.trim(), b.trim());
    let range = match (a.parse::<u64>(), b.parse::<u64>()) {
        (Ok(a), Ok(b)) if a <= b => (a, b.min(len.saturating_sub(1))),
        (Ok(a), Err(_)) if b.is_empty() => (a, len.saturating_sub(1)),
        (Err(_), Ok(n)) if a.is_empty() && n > 0 => (len.saturating_sub(n), len.saturating_sub(1)),
        _ => return Ok(None),
    };
    if range.0 >= len {
        return Err(());
    }
    Ok(Some(range))
}

enum Plan {
    Status(u16),
    Close,
    Stall,
    StallBody,
    Truncate,
    WrongRange,
    Corrupt,
    Normal,
}

/// The first byte a request asks for (`bytes=a-…`), if any.
fn range_start(req: &Request) -> Option<u64> {
    let spec = req.range.as_deref()?.strip_prefix("bytes=")?;
    spec.split('-').next()?.trim().parse().ok()
}

fn take_fault(shared: &Shared, req: &Request) -> (Plan, bool) {
    let mut f = shared.faults.lock().unwrap();
    let ignore = f.ignore_range;
    if f.target.is_some() && f.target != range_start(req) {
        return (Plan::Normal, ignore);
    }
    let plan = if let Some((status, n)) = f.status.filter(|&(_, n)| n > 0) {
        f.status = Some((status, n - 1));
        Plan::Status(status)
    } else if f.close > 0 {
        f.close -= 1;
        Plan::Close
    } else if f.stall > 0 {
        f.stall -= 1;
        Plan::Stall
    } else if f.stall_body > 0 {
        f.stall_body -= 1;
        Plan::StallBody
    } else if f.truncate > 0 {
        f.truncate -= 1;
        Plan::Truncate
    } else if f.wrong_range > 0 {
        f.wrong_range -= 1;
        Plan::WrongRange
    } else if f.corrupt > 0 {
        f.corrupt -= 1;
        Plan::Corrupt
    } else {
        Plan::Normal
    };
    (plan, ignore)
}

fn serve_connection(stream: TcpStream, shared: Arc<Shared>) {
    let Ok(mut out) = stream.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(stream);
    while let Some(req) = read_request(&mut reader) {
        shared.seen.lock().unwrap().requests += 1;
        match answer(&mut out, &req, &shared) {
            Ok(true) if !req.close => continue,
            _ => break,
        }
    }
    let _ = out.shutdown(Shutdown::Both);
}

fn head(out: &mut TcpStream, status: &str, headers: &[(String, String)]) -> std::io::Result<()> {
    let mut text = format!("HTTP/1.1 {status}\r\n");
    for (k, v) in headers {
        text.push_str(&format!("{k}: {v}\r\n"));
    }
    text.push_str("\r\n");
    out.write_all(text.as_bytes())
}

/// Answers one request; `Ok(true)` if the connection may be reused.
fn answer(out: &mut TcpStream, req: &Request, shared: &Shared) -> std::io::Result<bool> {
    let len = shared.data.len() as u64;
    let (plan, ignore_range) = take_fault(shared, req);
    let (encoding, claimed_total) = {
        let f = shared.faults.lock().unwrap();
        (f.encoding, f.claimed_total)
    };
    if !matches!(plan, Plan::Normal) {
        shared.seen.lock().unwrap().faults += 1;
    }
    let empty = |status: &str, out: &mut TcpStream| {
        head(out, status, &[("Content-Length".into(), "0".into())]).map(|()| true)
    };
    match plan {
        Plan::Status(s) => return empty(&format!("{s} Injected"), out),
        Plan::Close => return Ok(false),
        Plan::Stall => {
            while !shared.stop.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(5));
            }
            return Ok(false);
        }
        _ => {}
    }
    if req.path != shared.path {
        return empty("404 Not Found", out);
    }
    if req.method != "GET" && req.method != "HEAD" {
        return empty("405 Method Not Allowed", out);
    }
    let range = match req.range.as_deref().map(|r| parse_range(r, len)) {
        _ if ignore_range => None,
        None | Some(Ok(None)) => None,
        Some(Ok(Some(r))) => Some(r),
        Some(Err(())) => {
            let h = [
                ("Content-Range".into(), format!("bytes */{len}")),
                ("Content-Length".into(), "0".into()),
            ];
            return head(out, "416 Range Not Satisfiable", &h).map(|()| true);
        }
    };
    let (first, last) = range.unwrap_or((0, len.saturating_sub(1)));
    let mut body = if len == 0 {
        Vec::new()
    } else {
        shared.data[first as usize..=last as usize].to_vec()
    };
    let mut headers = vec![
        ("Content-Length".into(), body.len().to_string()),
        ("Accept-Ranges".into(), "bytes".into()),
    ];
    if let Some(encoding) = encoding {
        headers.push(("Content-Encoding".into(), encoding.into()));
    }
    let status = match range {
        Some(_) => {
            shared.seen.lock().unwrap().partial += 1;
            let shift = u64::from(matches!(plan, Plan::WrongRange));
            headers.push((
                "Content-Range".into(),
                format!(
                    "bytes {}-{}/{}",
                    first + shift,
                    last + shift,
                    claimed_total.unwrap_or(len)
                ),
            ));
            "206 Partial Content"
        }
        None => "200 OK",
    };
    head(out, status, &headers)?;
    if req.method == "HEAD" {
        return Ok(true);
    }
    match plan {
        Plan::StallBody => {
            out.flush()?;
            while !shared.stop.load(Ordering::SeqCst) {
                std::thread::sleep(Duration::from_millis(5));
            }
            Ok(false)
        }
        Plan::Truncate => {
            out.write_all(&body[..body.len() / 2])?;
            Ok(false)
        }
        Plan::Corrupt => {
            let mid = body.len() / 2;
            if let Some(b) = body.get_mut(mid) {
                *b ^= 0x5a;
            }
            out.write_all(&body).map(|()| true)
        }
        _ => out.write_all(&body).map(|()| true),
    }
}
