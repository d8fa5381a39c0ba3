//! A static HTTP/1.1 server for one paging file, with range requests (`206 Partial Content`), built on
//! axum and tower-http's `ServeFile`; what `atlastree serve` runs and what tests start on port 0.
//!
//! The file is served at `/<its file name>` (percent-encoded), anything else is `404`. The server runs
//! on its own thread with a single-threaded tokio runtime (file reads go to tokio's blocking pool), so it
//! needs no async code from the caller. [`ServerHandle::shutdown`] (or dropping the handle) stops
//! accepting, lets requests in progress finish for up to [`SHUTDOWN_GRACE`], then closes everything and
//! frees the port: a new server can bind the same address at once.

use std::future::IntoFuture;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::sync::oneshot;
use tower_http::services::ServeFile;

/// How long a shutdown waits for requests in progress before closing their connections.
pub const SHUTDOWN_GRACE: Duration = Duration::from_secs(2);

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
}

/// A running server. Dropping it shuts the server down (as [`ServerHandle::shutdown`]).
pub struct ServerHandle {
    addr: SocketAddr,
    url: String,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl ServerHandle {
    /// The address the server listens on (the real port when started on port 0).
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// The file's URL, `http://ADDR/NAME`.
    pub fn url(&self) -> &str {
        &self.url
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

/// Serves `path` on `addr` (port 0: any free port) from a background thread. Returns once the socket is
/// bound, so the URL works immediately.
pub fn spawn(path: &Path, addr: SocketAddr) -> Result<ServerHandle, ServeError> {
    let meta = std::fs::metadata(path).map_err(|source| ServeError::File {
        path: path.to_path_buf(),
        source,
    })?;
    if !meta.is_file() {
        return Err(ServeError::NotAFile {
            path: path.to_path_buf(),
        });
    }
    let bind_err = |source| ServeError::Bind { addr, source };
    let listener = std::net::TcpListener::bind(addr).map_err(bind_err)?;
    listener.set_nonblocking(true).map_err(bind_err)?;
    let addr = listener.local_addr().map_err(bind_err)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_io()
        .enable_time()
        .build()
        .map_err(|source| ServeError::Runtime { source })?;
    let route = url_path(path);
    let url = format!("http://{addr}{route}");
    let (stop, stopped) = oneshot::channel();
    let file = path.to_path_buf();
    let thread = std::thread::Builder::new()
        .name("atlastree-serve".into())
        .spawn(move || run(runtime, listener, file, route, stopped))
        .map_err(|source| ServeError::Runtime { source })?;
    Ok(ServerHandle {
        addr,
        url,
        stop: Some(stop),
        thread: Some(thread),
    })
}

/// The server thread: serve until `stop` fires (or its sender is dropped), then shut down gracefully.
fn run(
    runtime: tokio::runtime::Runtime,
    listener: std::net::TcpListener,
    file: PathBuf,
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
        let app = axum::Router::new().route_service(&route, ServeFile::new(&file));
        let (graceful, shutting_down) = oneshot::channel::<()>();
        let server = axum::serve(listener, app).with_graceful_shutdown(async move {
            let _ = shutting_down.await;
        });
        let server = tokio::spawn(server.into_future());
        let _ = stop.await;
        let _ = graceful.send(());
        match tokio::time::timeout(SHUTDOWN_GRACE, server).await {
            Ok(Ok(Err(e))) => tracing::warn!("serve: {e}"),
            Err(_) => tracing::warn!("serve: requests still running after {SHUTDOWN_GRACE:?}"),
            _ => {}
        }
    });
    runtime.shutdown_timeout(Duration::from_millis(200));
}

/// `/` + the percent-encoded file name (unreserved characters kept), `/file` if there is no name.
pub fn url_path(path: &Path) -> String {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let name = name.unwrap_or_else(|| "file".into());
    let mut out = String::from("/");
    for b in name.bytes() {
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
    fn url_path_keeps_unreserved_and_encodes_the_rest() {
        assert_eq!(
            url_path(Path::new("/tmp/city.atlastree")),
            "/city.atlastree"
        );
        assert_eq!(url_path(Path::new("a b{c}/x y%.bin")), "/x%20y%25.bin");
        assert_eq!(url_path(Path::new("/")), "/file");
    }
}
