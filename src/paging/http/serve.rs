//! A static HTTP/1.1 server for one paging file with range requests (`206 Partial Content`): what
//! `atlastree serve` runs and what tests start on port 0. Built to stay up under abuse:
//!
//! - **paths**: the file is served at `/<its file name>` (percent-encoded), `GET` and `HEAD` only; any
//!   other path is `404`, another method `405`; a path is compared after its escapes are decoded, so
//!   `%c3%bc` and `%2E` name what `%C3%BC` and `.` name (RFC 3986 §6.2.2);
//! - **ranges**: see [`super::range`] — `206` for one range (several are coalesced when they touch),
//!   `416` with `Content-Range: bytes */LEN` when none is satisfiable, the whole file with `200` for a
//!   malformed `Range` (ignored, as RFC 9110 §14.2 allows; never `400`) or disjoint ranges; a request head
//!   larger than [`ServeOptions::max_head_bytes`] is refused by hyper with `431`;
//! - **memory**: bodies are streamed from the file in [`CHUNK`]-byte reads (a range is never buffered
//!   whole), at most [`ServeOptions::max_connections`] connections are served at once and the blocking
//!   file reads run on at most [`BLOCKING_THREADS`] threads, so memory is bounded whatever the load;
//! - **connections**: one over the limit waits up to [`ServeOptions::admission_wait`] for a free slot,
//!   then gets `503` with `Retry-After: 1` and is closed (at most `max_connections` wait at once; the
//!   rest get `503` at once); counted in [`ServeStats::rejected`];
//! - **slow clients** (slowloris): a request head must arrive within [`ServeOptions::header_timeout`]
//!   (idle keep-alive connections are closed after it too), and a connection that moves no byte either
//!   way for [`ServeOptions::io_timeout`] (a client that stops reading a body) is closed.
//!
//! The server runs on its own thread with a single-threaded tokio runtime, so it needs no async code
//! from the caller. [`ServerHandle::shutdown`] (or dropping the handle) stops accepting, lets requests
//! in progress finish for up to [`SHUTDOWN_GRACE`], then closes everything and frees the port: a new
//! server can bind the same address at once.

use super::range::{self, RangeAnswer};
use axum::body::Body;
use axum::extract::State;
use axum::http::{HeaderMap, HeaderValue, Method, StatusCode, header};
use axum::response::Response;
use std::io;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncSeekExt, AsyncWrite, AsyncWriteExt, ReadBuf};
use tokio::sync::{Semaphore, oneshot, watch};
use tokio::task::JoinSet;

/// How long a shutdown waits for requests in progress before closing their connections.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);
/// Bytes read from the file per body chunk.
pub const CHUNK: usize = 64 * 1024;
/// Threads for blocking file reads.
pub const BLOCKING_THREADS: usize = 8;

/// Limits of a server.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct ServeOptions {
    /// Connections served at once.
    pub max_connections: usize,
    /// How long a connection over the limit waits for a free slot before its `503`.
    pub admission_wait: Duration,
    /// Limit on receiving a whole request head (and on an idle keep-alive connection).
    pub header_timeout: Duration,
    /// A connection that moves no byte in either direction this long is closed.
    pub io_timeout: Duration,
    /// Largest request head, bytes (hyper's read buffer; at least 8192); larger ones get `431`.
    pub max_head_bytes: usize,
}

impl Default for ServeOptions {
    /// 256 connections, 2 s admission wait, 10 s header timeout, 30 s I/O timeout, 16 KiB heads.
    fn default() -> Self {
        ServeOptions {
            max_connections: 256,
            admission_wait: Duration::from_secs(2),
            header_timeout: Duration::from_secs(10),
            io_timeout: Duration::from_secs(30),
            max_head_bytes: 16 * 1024,
        }
    }
}

/// What a server has done so far.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ServeStats {
    /// Connections accepted from the socket (rejected ones included).
    pub connections: u64,
    /// Connections answered `503` because every slot stayed busy.
    pub rejected: u64,
    /// Requests for the file answered (`200`, `206`, `416`).
    pub requests: u64,
    /// Of those, `206` and `416` answers.
    pub partial: u64,
    pub unsatisfiable: u64,
    /// Connections closed by the header or I/O timeout, or by a protocol error (bad or oversized head).
    pub closed_on_error: u64,
}

#[derive(Default)]
struct Counters {
    connections: AtomicU64,
    rejected: AtomicU64,
    requests: AtomicU64,
    partial: AtomicU64,
    unsatisfiable: AtomicU64,
    closed_on_error: AtomicU64,
}

impl Counters {
    fn snapshot(&self) -> ServeStats {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        ServeStats {
            connections: get(&self.connections),
            rejected: get(&self.rejected),
            requests: get(&self.requests),
            partial: get(&self.partial),
            unsatisfiable: get(&self.unsatisfiable),
            closed_on_error: get(&self.closed_on_error),
        }
    }
}

fn bump(c: &AtomicU64) {
    c.fetch_add(1, Ordering::Relaxed);
}

/// Why a server could not start.
#[derive(Debug, thiserror::Error)]
pub enum ServeError {
    #[error("{path}: {source}")]
    File {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a regular file")]
    NotAFile { path: PathBuf },
    #[error("binding {addr}: {source}")]
    Bind {
        addr: SocketAddr,
        #[source]
        source: std::io::Error,
    },
    #[error("starting the server thread: {source}")]
    Runtime {
        #[source]
        source: std::io::Error,
    },
    #[error(
        "max_connections must be from 1 to 2^61 − 1 and max_head_bytes at least 8192 (got {connections}, {head})"
    )]
    Options { connections: usize, head: usize },
}

/// A running server. Dropping it shuts the server down (as [`ServerHandle::shutdown`]).
pub struct ServerHandle {
    addr: SocketAddr,
    url: String,
    /// [`crate::util::file_identity`] of the file it serves, as opened.
    file_identity: Option<(u64, u64)>,
    counters: Arc<Counters>,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl ServerHandle {
    /// Which file it serves ([`crate::util::file_identity`] of the handle it opened): a caller that
    /// checked the path before compares it with the file it checked.
    pub fn file_identity(&self) -> Option<(u64, u64)> {
        self.file_identity
    }

    /// The address the server listens on (the real port when started on port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The file's URL, `http://ADDR/NAME`.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// A snapshot of the counters.
    pub fn stats(&self) -> ServeStats {
        self.counters.snapshot()
    }

    /// Stops the server and waits until its port is closed (at most about [`SHUTDOWN_GRACE`]).
    pub fn shutdown(mut self) {
        self.stop_and_join();
    }

    fn stop_and_join(&mut self) {
        if let Some(stop) = self.stop.take() {
            let _ = stop.send(());
        }
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl Drop for ServerHandle {
    fn drop(&mut self) {
        self.stop_and_join();
    }
}

/// Serves `path` on `addr` (port 0: any free port) with the default [`ServeOptions`].
pub fn spawn(path: &Path, addr: SocketAddr) -> Result<ServerHandle, ServeError> {
    spawn_with(path, addr, ServeOptions::default())
}

/// Serves `path` on `addr` (port 0: any free port) from a background thread under `options`. Returns
/// once the socket is bound, so the URL works immediately.
pub fn spawn_with(
    path: &Path,
    addr: SocketAddr,
    options: ServeOptions,
) -> Result<ServerHandle, ServeError> {
    if options.max_connections == 0
        || options.max_connections > Semaphore::MAX_PERMITS
        || options.max_head_bytes < 8192
    {
        return Err(ServeError::Options {
            connections: options.max_connections,
            head: options.max_head_bytes,
        });
    }
    let meta = std::fs::metadata(path).map_err(|source| ServeError::File {
        path: path.to_path_buf(),
        source,
    })?;
    if !meta.is_file() {
        return Err(ServeError::NotAFile {
            path: path.to_path_buf(),
        });
    }
    let held = std::fs::File::open(path).map_err(|source| ServeError::File {
        path: path.to_path_buf(),
        source,
    })?;
    let file_identity = (held.metadata().ok()).and_then(|m| crate::util::file_identity(&m));
    let bind_err = |source| ServeError::Bind { addr, source };
    let listener = std::net::TcpListener::bind(addr).map_err(bind_err)?;
    listener.set_nonblocking(true).map_err(bind_err)?;
    let addr = listener.local_addr().map_err(bind_err)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .enable_time()
        .max_blocking_threads(BLOCKING_THREADS)
        .build()
        .map_err(|source| ServeError::Runtime { source })?;
    let route = url_path(path);
    let url = format!("http://{addr}{route}");
    let (stop, stopped) = oneshot::channel();
    let counters = Arc::new(Counters::default());
    let server = Server {
        file: path.to_path_buf(),
        held,
        options,
        counters: counters.clone(),
    };
    let thread = std::thread::Builder::new()
        .name("atlastree-serve".into())
        .spawn(move || run(runtime, listener, server, route, stopped))
        .map_err(|source| ServeError::Runtime { source })?;
    Ok(ServerHandle {
        addr,
        url,
        file_identity,
        counters,
        stop: Some(stop),
        thread: Some(thread),
    })
}

/// What every connection and request handler shares.
struct Server {
    file: PathBuf,
    /// The file opened at start: every answer reads it, so a file renamed over `file` (as `build -o`
    /// publishes a new one) does not change what a running server serves.
    held: std::fs::File,
    options: ServeOptions,
    counters: Arc<Counters>,
}

/// How often an `accept` failing for lack of descriptors or memory is warned about (other failures, and
/// those in between, are logged at debug level).
const ACCEPT_WARN_EVERY: Duration = Duration::from_secs(10);

/// The server thread: accept until `stop` fires (or its sender is dropped), then shut down gracefully.
fn run(
    runtime: tokio::runtime::Runtime,
    listener: std::net::TcpListener,
    server: Server,
    route: String,
    stop: oneshot::Receiver<()>,
) {
    runtime.block_on(async move {
        let listener = match tokio::net::TcpListener::from_std(listener) {
            Ok(l) => l,
            Err(e) => {
                tracing::error!("serve: cannot register the listener: {e}");
                return;
            }
        };
        let server = Arc::new(server);
        // One handler for every path: the file's own route is its canonical form (`url_path` writes it
        // so), other spellings of it the same file, the rest 404 (a route beside the fallback answered
        // the file twice over, and wrote its 405 beside the fallback's).
        let app = axum::Router::new()
            .fallback(serve_equivalent)
            .with_state((server.clone(), Arc::new(route)));
        let slots = Arc::new(Semaphore::new(server.options.max_connections));
        let queue = Arc::new(Semaphore::new(server.options.max_connections));
        let (closing, closing_rx) = watch::channel(false);
        let mut connections = JoinSet::new();
        let mut stop = stop;
        let mut last_warned = None;
        loop {
            tokio::select! {
                _ = &mut stop => break,
                Some(_) = connections.join_next(), if !connections.is_empty() => {}
                accepted = listener.accept() => match accepted {
                    Ok((stream, _)) => {
                        bump(&server.counters.connections);
                        connections.spawn(connection(
                            stream,
                            app.clone(),
                            server.clone(),
                            slots.clone(),
                            queue.clone(),
                            closing_rx.clone(),
                        ));
                    }
                    // Out of file descriptors or a connection reset before accept: go on shortly. Out of
                    // descriptors (clients wait unanswered) is warned about at most every
                    // ACCEPT_WARN_EVERY; the rest, a reset among them, is logged at debug level.
                    Err(e) => {
                        if crate::util::is_resource_exhaustion(&e)
                            && last_warned.is_none_or(|t: std::time::Instant| {
                                t.elapsed() >= ACCEPT_WARN_EVERY
                            })
                        {
                            tracing::warn!(
                                "serve: cannot accept a connection: {e} (clients wait; with too many open \
                                 files, raise the limit: ulimit -n)"
                            );
                            last_warned = Some(std::time::Instant::now());
                        } else {
                            tracing::debug!("serve: accept: {e}");
                        }
                        tokio::time::sleep(Duration::from_millis(10)).await;
                    }
                },
            }
        }
        drop(listener);
        let _ = closing.send(true);
        let drained = tokio::time::timeout(SHUTDOWN_GRACE, async {
            while connections.join_next().await.is_some() {}
        })
        .await;
        if drained.is_err() {
            tracing::warn!("serve: requests still running after {SHUTDOWN_GRACE:?}");
            connections.abort_all();
        }
    });
    runtime.shutdown_timeout(Duration::from_millis(200));
}

/// One connection: a slot (waiting for one, or `503`), then HTTP/1.1 with the timeouts, until the
/// client closes, a timeout fires or the server shuts down.
async fn connection(
    stream: tokio::net::TcpStream,
    app: axum::Router,
    server: Arc<Server>,
    slots: Arc<Semaphore>,
    queue: Arc<Semaphore>,
    mut closing: watch::Receiver<bool>,
) {
    let _ = stream.set_nodelay(true);
    let o = server.options;
    let slot = match slots.clone().try_acquire_owned() {
        Ok(slot) => slot,
        Err(_) => {
            let waited = match queue.try_acquire() {
                Ok(_place) => tokio::time::timeout(o.admission_wait, slots.acquire_owned())
                    .await
                    .ok()
                    .and_then(Result::ok),
                Err(_) => None,
            };
            match waited {
                Some(slot) => slot,
                None => {
                    bump(&server.counters.rejected);
                    reject_busy(stream).await;
                    return;
                }
            }
        }
    };
    let io = hyper_util::rt::TokioIo::new(Deadline::new(stream, o.io_timeout));
    let service = hyper_util::service::TowerToHyperService::new(app);
    let mut builder = hyper::server::conn::http1::Builder::new();
    builder
        .timer(hyper_util::rt::TokioTimer::new())
        .header_read_timeout(o.header_timeout)
        .max_buf_size(o.max_head_bytes);
    let conn = builder.serve_connection(io, service);
    tokio::pin!(conn);
    let closing_now = async move {
        // A closed channel (the server is gone) also means closing.
        let _ = closing.wait_for(|&c| c).await.map(|_| ());
    };
    let result = tokio::select! {
        r = conn.as_mut() => r,
        () = closing_now => {
            conn.as_mut().graceful_shutdown();
            conn.await
        }
    };
    if result.is_err() {
        bump(&server.counters.closed_on_error);
    }
    drop(slot);
}

/// `503` with `Retry-After: 1` to a connection over the limit, then close (bounded by one second).
async fn reject_busy(mut stream: tokio::net::TcpStream) {
    const BUSY: &[u8] = b"HTTP/1.1 503 Service Unavailable\r\nRetry-After: 1\r\nContent-Length: 0\r\nConnection: close\r\n\r\n";
    let _ = tokio::time::timeout(Duration::from_secs(1), async {
        stream.write_all(BUSY).await?;
        stream.shutdown().await
    })
    .await;
}

/// Every request: the file's route, also written with other escapes (lower-case hex, an escaped
/// unreserved character: it was `404`; fault hunt, session 32), is the file's, `GET` or `HEAD` with or
/// without `Range`, other methods `405`; the rest `404`.
async fn serve_equivalent(
    State((server, route)): State<(Arc<Server>, Arc<String>)>,
    method: Method,
    uri: axum::http::Uri,
    headers: HeaderMap,
) -> Response {
    if canonical_path(uri.path()) != *route {
        return status_only(StatusCode::NOT_FOUND);
    }
    if method != Method::GET && method != Method::HEAD {
        let mut r = status_only(StatusCode::METHOD_NOT_ALLOWED);
        r.headers_mut()
            .insert(header::ALLOW, HeaderValue::from_static("GET,HEAD"));
        return r;
    }
    serve_answer(server, method, headers).await
}

/// A `GET` or `HEAD` of the file.
async fn serve_answer(server: Arc<Server>, method: Method, headers: HeaderMap) -> Response {
    match answer_file(&server, &method, &headers).await {
        Ok(r) => r,
        Err(e) => {
            tracing::warn!("serve: {}: {e}", server.file.display());
            status_only(StatusCode::INTERNAL_SERVER_ERROR)
        }
    }
}

/// A fresh open of the file held since start (Linux: `/proc/self/fd/N`, an open file description of
/// its own, so concurrent answers seek independently); elsewhere the path.
async fn open_held(server: &Server) -> io::Result<tokio::fs::File> {
    #[cfg(target_os = "linux")]
    {
        use std::os::fd::AsRawFd;
        let fd = format!("/proc/self/fd/{}", server.held.as_raw_fd());
        if let Ok(f) = tokio::fs::File::open(&fd).await {
            return Ok(f);
        }
    }
    tokio::fs::File::open(&server.file).await
}

async fn answer_file(
    server: &Server,
    method: &Method,
    headers: &HeaderMap,
) -> io::Result<Response> {
    let mut file = open_held(server).await?;
    let len = file.metadata().await?.len();
    bump(&server.counters.requests);
    // Ranges are defined for GET only, and with `If-Range` only when its validator matches; this server
    // sends no validators, so none can match: the whole file (RFC 9110 §14.2, §13.1.5).
    let range_header = headers
        .get(header::RANGE)
        .map(HeaderValue::as_bytes)
        .filter(|_| *method == Method::GET && !headers.contains_key(header::IF_RANGE));
    let (status, first, count, content_range) = match range::answer(range_header, len) {
        RangeAnswer::Full => (StatusCode::OK, 0, len, None),
        RangeAnswer::Partial { first, last } => {
            bump(&server.counters.partial);
            let cr = format!("bytes {first}-{last}/{len}");
            (
                StatusCode::PARTIAL_CONTENT,
                first,
                last - first + 1,
                Some(cr),
            )
        }
        RangeAnswer::Unsatisfiable => {
            bump(&server.counters.unsatisfiable);
            let mut r = status_only(StatusCode::RANGE_NOT_SATISFIABLE);
            if let Ok(v) = HeaderValue::from_str(&format!("bytes */{len}")) {
                r.headers_mut().insert(header::CONTENT_RANGE, v);
            }
            return Ok(r);
        }
    };
    let body = if *method == Method::HEAD || count == 0 {
        Body::empty()
    } else {
        file.seek(io::SeekFrom::Start(first)).await?;
        let stream = tokio_util::io::ReaderStream::with_capacity(file.take(count), CHUNK);
        Body::from_stream(stream)
    };
    let mut r = Response::new(body);
    *r.status_mut() = status;
    let h = r.headers_mut();
    h.insert(header::ACCEPT_RANGES, HeaderValue::from_static("bytes"));
    h.insert(
        header::CONTENT_TYPE,
        HeaderValue::from_static("application/octet-stream"),
    );
    h.insert(header::CONTENT_LENGTH, HeaderValue::from(count));
    if let Some(cr) = content_range.and_then(|c| HeaderValue::from_str(&c).ok()) {
        h.insert(header::CONTENT_RANGE, cr);
    }
    Ok(r)
}

fn status_only(status: StatusCode) -> Response {
    let mut r = Response::new(Body::empty());
    *r.status_mut() = status;
    r.headers_mut()
        .insert(header::CONTENT_LENGTH, HeaderValue::from(0u64));
    r
}

/// A stream that fails with `TimedOut` once no byte moved either way for `timeout` while the
/// connection waits on it (a client that stops reading the body, or stops sending).
struct Deadline<T> {
    io: T,
    timeout: Duration,
    sleep: Pin<Box<tokio::time::Sleep>>,
}

impl<T> Deadline<T> {
    fn new(io: T, timeout: Duration) -> Deadline<T> {
        Deadline {
            io,
            timeout,
            sleep: Box::pin(tokio::time::sleep(timeout)),
        }
    }

    fn progress(&mut self) {
        let at = tokio::time::Instant::now() + self.timeout;
        self.sleep.as_mut().reset(at);
    }

    fn expired<R>(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<R>> {
        match self.sleep.as_mut().poll(cx) {
            Poll::Ready(()) => Poll::Ready(Err(io::Error::new(
                io::ErrorKind::TimedOut,
                "no progress within the I/O timeout",
            ))),
            Poll::Pending => Poll::Pending,
        }
    }
}

impl<T: AsyncRead + Unpin> AsyncRead for Deadline<T> {
    fn poll_read(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let before = buf.filled().len();
        match Pin::new(&mut this.io).poll_read(cx, buf) {
            Poll::Ready(r) => {
                if buf.filled().len() > before {
                    this.progress();
                }
                Poll::Ready(r)
            }
            Poll::Pending => this.expired(cx),
        }
    }
}

impl<T: AsyncWrite + Unpin> AsyncWrite for Deadline<T> {
    fn poll_write(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        buf: &[u8],
    ) -> Poll<io::Result<usize>> {
        let this = self.get_mut();
        match Pin::new(&mut this.io).poll_write(cx, buf) {
            Poll::Ready(r) => {
                if matches!(r, Ok(n) if n > 0) {
                    this.progress();
                }
                Poll::Ready(r)
            }
            Poll::Pending => this.expired(cx),
        }
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        match Pin::new(&mut this.io).poll_flush(cx) {
            Poll::Pending => this.expired(cx),
            r => r,
        }
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        Pin::new(&mut self.get_mut().io).poll_shutdown(cx)
    }
}

/// `/` + the percent-encoded file name (unreserved characters kept), `/file` if there is no name.
pub fn url_path(path: &Path) -> String {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    encoded_path(name.unwrap_or_else(|| "file".into()).as_bytes())
}

/// A request path as [`url_path`] writes it: its escapes decoded, then every byte but the unreserved
/// ones encoded (upper-case hex). A `/` inside the name stays encoded, so no other path matches.
fn canonical_path(path: &str) -> String {
    let name = path.strip_prefix('/').unwrap_or(path);
    let bytes: Vec<u8> = percent_encoding::percent_decode_str(name).collect();
    encoded_path(&bytes)
}

/// `/` + `name` percent-encoded, unreserved characters kept.
fn encoded_path(name: &[u8]) -> String {
    let mut out = String::from("/");
    for &b in name {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(b as char);
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::url_path;
    use std::path::Path;

    #[test]
    fn equivalent_escapes_name_the_same_path() {
        use super::canonical_path;
        let route = url_path(std::path::Path::new("/d/Müll city.atlastree"));
        assert_eq!(route, "/M%C3%BCll%20city.atlastree");
        for same in [
            "/M%C3%BCll%20city.atlastree",
            "/M%c3%bcll%20city.atlastree",
            "/M%C3%BCll%20city%2Eatlastree",
            "/%4D%C3%BCll%20city.atlastree",
        ] {
            assert_eq!(canonical_path(same), route, "{same}");
        }
        for other in [
            "/",
            "/..%2FM%C3%BCll%20city.atlastree",
            "/M%C3%BCll city.atlastre",
        ] {
            assert_ne!(canonical_path(other), route, "{other}");
        }
        assert_eq!(canonical_path("/%2e%2e/etc/passwd"), "/..%2Fetc%2Fpasswd");
    }

    #[test]
    fn url_path_keeps_unreserved_and_encodes_the_rest() {
        assert_eq!(
            url_path(Path::new("/tmp/city.atlastree")),
            "/city.atlastree"
        );
        assert_eq!(url_path(Path::new("a b{c}/x y%.bin")), "/x%20y%25.bin");
        assert_eq!(url_path(Path::new("/")), "/file");
    }
}
