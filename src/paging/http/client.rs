//! [`HttpSource`]: the paging file's blocks from any HTTP/1.1 static file server, by range requests.
//!
//! Policy, per fetch (one block, or the tables at open):
//! - one `GET` with `Range: bytes=a-b`; a `206` must carry `Content-Range: bytes a-b/…` and exactly
//!   `b - a + 1` body bytes; a block's bytes must match its checksum;
//! - a `200` (a server that ignores `Range`) is accepted: the body is streamed, the bytes before `a` are
//!   skipped, the range is kept, the rest is not read (the connection is dropped). Counted in
//!   [`HttpStats::full_responses`] so a misconfigured server shows up in the stats;
//! - retried, up to [`HttpOptions::retries`] times with exponential backoff (deterministic jitter): the
//!   faults a network or an overloaded server produces and that may pass — connection, reset and timeout
//!   errors (a server that sends its headers and then stalls included), `5xx`, `408`, `429`, short or
//!   broken bodies, a `206` for another range, a block (or at open the tables) whose bytes fail their
//!   checksum (a corrupt transfer);
//! - not retried: other `4xx` and statuses, a request that cannot be built, a `Content-Range` whose total
//!   says the server's file ends before the range.
//!
//! The error of a fetch that failed names the URL, the block, the attempts made and the last cause
//! ([`SourceError`]); [`SourceError::is_transient`] tells the pager whether to ask again soon.
//!
//! Every attempt is bounded by [`HttpOptions::connect_timeout`] and [`HttpOptions::timeout`] (the whole
//! request: connect, headers and body), so a fetch ends within about `(retries + 1) × timeout + Σ backoff`;
//! against a stopped server (connection refused) within `Σ backoff`.

use super::super::source::{BlockSource, SourceError, verify};
use crate::ids::BlockId;
use crate::store::format::{BlockRecord, HEADER_SIZE, Header};
use crate::store::{StoreError, TreeFile};
use std::io::Read;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Duration;

/// Timeouts and retry policy of an [`HttpSource`].
#[derive(Clone, Debug, PartialEq)]
pub struct HttpOptions {
    /// Limit on establishing a connection (a dead host fails this fast).
    pub connect_timeout: Duration,
    /// Limit on one whole request: connect, send, receive headers and body.
    pub timeout: Duration,
    /// Attempts after the first for a retryable failure (0: no retry).
    pub retries: u32,
    /// Wait before the first retry; doubled per retry, times a jitter factor in [0.5, 1].
    pub backoff_initial: Duration,
    /// Upper bound on one wait.
    pub backoff_max: Duration,
    /// The most bytes of tables [`HttpSource::open`] fetches (they are held in memory, beside the
    /// renderer's textures): a header claiming more is refused before they are asked for. Default: a
    /// quarter of the memory this process may use ([`crate::util::memory_limit_bytes`]; 2 GiB where the
    /// platform does not tell). The tables of a 6 M-triangle world are ~0.3 GB.
    pub max_table_bytes: u64,
}

impl Default for HttpOptions {
    /// 2 s to connect, 30 s per request, 3 retries, backoff 100 ms doubling up to 2 s.
    fn default() -> Self {
        HttpOptions {
            connect_timeout: Duration::from_secs(2),
            timeout: Duration::from_secs(30),
            retries: 3,
            backoff_initial: Duration::from_millis(100),
            backoff_max: Duration::from_secs(2),
            max_table_bytes: crate::util::memory_limit_bytes().map_or(2 << 30, |m| m / 4),
        }
    }
}

/// What an [`HttpSource`] has done so far (a snapshot of its atomic counters).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct HttpStats {
    /// HTTP requests sent: every attempt, the tables' included.
    pub requests: u64,
    /// Attempts repeated after a retryable failure.
    pub retries: u64,
    /// Fetches (a block, or the tables at open) that failed after all their attempts.
    pub failures: u64,
    /// Body bytes received over all attempts (skipped bytes of `200` answers included).
    pub bytes: u64,
    /// Blocks delivered and verified.
    pub blocks: u64,
    /// `200` answers to a range request (the server ignores `Range`; the range was cut from the stream).
    pub full_responses: u64,
    /// Answers whose bytes did not match the block's checksum (every attempt counted; retried).
    pub checksum_failures: u64,
    /// Block fetches that failed with every attempt's answer failing its checksum, which points at the
    /// served file itself (a fetch with any attempt failing for another cause is not counted).
    pub checksum_fetch_failures: u64,
    /// Failed fetches since the last successful one: non-zero means "source failing, drawing coarser".
    pub consecutive_failures: u64,
}

impl HttpStats {
    /// True while the latest fetch failed.
    pub fn is_failing(&self) -> bool {
        self.consecutive_failures > 0
    }
}

/// The live counters behind [`HttpStats`].
#[derive(Default)]
struct Counters {
    requests: AtomicU64,
    retries: AtomicU64,
    failures: AtomicU64,
    bytes: AtomicU64,
    blocks: AtomicU64,
    full_responses: AtomicU64,
    checksum_failures: AtomicU64,
    checksum_fetch_failures: AtomicU64,
    consecutive_failures: AtomicU64,
}

fn bump(counter: &AtomicU64, by: u64) {
    counter.fetch_add(by, Ordering::Relaxed);
}

impl Counters {
    fn snapshot(&self) -> HttpStats {
        let get = |c: &AtomicU64| c.load(Ordering::Relaxed);
        HttpStats {
            requests: get(&self.requests),
            retries: get(&self.retries),
            failures: get(&self.failures),
            bytes: get(&self.bytes),
            blocks: get(&self.blocks),
            full_responses: get(&self.full_responses),
            checksum_failures: get(&self.checksum_failures),
            checksum_fetch_failures: get(&self.checksum_fetch_failures),
            consecutive_failures: get(&self.consecutive_failures),
        }
    }

    fn outcome(&self, ok: bool) {
        if ok {
            self.consecutive_failures.store(0, Ordering::Relaxed);
        } else {
            bump(&self.failures, 1);
            bump(&self.consecutive_failures, 1);
        }
    }
}

/// Why one attempt failed.
#[derive(Debug)]
enum Failure {
    /// Connection, timeout, protocol or body read error.
    Transport(String),
    /// A request that cannot succeed as built (bad URL, too many redirects, TLS setup).
    Request(String),
    /// An unexpected status.
    Status(u16),
    /// The body ended early (or the file is shorter than the range); `head`: its first bytes (up to 64).
    Short { got: u64, head: Vec<u8> },
    /// A whole answer for the header's range, shorter than a header and not the start of a paging file
    /// (an HTML page): its first bytes. Not retried: no attempt makes it one (a short page read "got 29 of
    /// 528 bytes" after four tries, where a longer one said what it was; fault hunt, session 34).
    NotPaging(Vec<u8>),
    /// A `206` for another range than asked for; `permanent` when its total ends before the range or
    /// differs from the length at open (a replaced file): asking again cannot help.
    WrongRange { message: String, permanent: bool },
    /// The bytes of a block do not match its checksum.
    Checksum { found: u64 },
    /// The tables' bytes fail one of their checksums (corrupt in transit).
    Corrupt(String),
}

impl Failure {
    fn retryable(&self) -> bool {
        match self {
            Failure::Transport(_)
            | Failure::Short { .. }
            | Failure::Checksum { .. }
            | Failure::Corrupt(_) => true,
            Failure::Status(status) => *status >= 500 || matches!(status, 408 | 429),
            Failure::WrongRange { permanent, .. } => !permanent,
            Failure::Request(_) | Failure::NotPaging(_) => false,
        }
    }

    /// A timeout names the one that ran out (ureq says "timeout: global"; fault hunt, session 36).
    fn from_ureq(e: ureq::Error, options: &HttpOptions) -> Failure {
        use ureq::Error as E;
        match e {
            E::Timeout(ureq::Timeout::Connect) => Failure::Transport(format!(
                "no connection within the connect timeout of {} s",
                crate::util::short_number(options.connect_timeout.as_secs_f64())
            )),
            E::Timeout(_) => Failure::Transport(timed_out(options)),
            E::Http(_)
            | E::BadUri(_)
            | E::InvalidProxyUrl
            | E::TooManyRedirects
            | E::RedirectFailed
            | E::RequireHttpsOnly(_) => Failure::Request(e.to_string()),
            _ => Failure::Transport(e.to_string()),
        }
    }

    fn message(&self, expected: u64) -> String {
        match self {
            Failure::Transport(m) | Failure::Request(m) | Failure::Corrupt(m) => m.clone(),
            Failure::Status(s) => format!("HTTP status {s}"),
            Failure::Short { got, .. } => format!("got {got} of {expected} bytes"),
            Failure::NotPaging(head) => format!(
                "not an atlastree paging file ({})",
                crate::store::describe_start(head)
            ),
            Failure::WrongRange { message, .. } => message.clone(),
            Failure::Checksum { found } => format!("checksum {found:#018x} does not match"),
        }
    }
}

/// The whole request's timeout ran out ([`HttpOptions::timeout`]: `--http-timeout` in the CLI).
fn timed_out(options: &HttpOptions) -> String {
    format!(
        "no complete answer within the request timeout of {} s (--http-timeout)",
        crate::util::short_number(options.timeout.as_secs_f64())
    )
}

/// The bytes of one successful range request.
struct Ranged {
    bytes: Vec<u8>,
    /// The file's length as the server reports it (`Content-Range` total, or a `200`'s length).
    total: Option<u64>,
}

/// `url` with the password of its userinfo replaced by `***` (`http://alice:***@host/…`; a user without
/// a password, often a token, as `***@host`) and the value of each query and fragment parameter too
/// (`?X-Amz-Signature=***`: a presigned URL's signature is a credential; it was shown in messages, fault
/// hunt, session 31), for messages, names and reports; the requests use the URL as given. A URL with
/// neither is returned as is.
pub fn redact_url(url: &str) -> String {
    let Some((scheme, rest)) = url.split_once("://") else {
        return url.to_string();
    };
    let authority_end = rest.find(['/', '?', '#']).unwrap_or(rest.len());
    let (authority, path) = rest.split_at(authority_end);
    let authority = match authority.rsplit_once('@') {
        Some((userinfo, host)) => match userinfo.split_once(':') {
            Some((user, _password)) => format!("{user}:***@{host}"),
            // A user alone is often a token (`https://TOKEN@host/`).
            None => format!("***@{host}"),
        },
        None => authority.to_string(),
    };
    format!("{scheme}://{authority}{}", redact_query(path))
}

/// `path` (from the first `/`, `?` or `#` after the authority) with each value of its query and of its
/// fragment replaced by `***`: no request sends the fragment, but a pasted OAuth redirect carries
/// `#access_token=…` there (fault hunt, session 31).
fn redact_query(path: &str) -> String {
    let (path, fragment) = match path.split_once('#') {
        Some((p, f)) => (p, Some(f)),
        None => (path, None),
    };
    let path = match path.split_once('?') {
        Some((before, query)) => format!("{before}?{}", redact_pairs(query)),
        None => path.to_string(),
    };
    match fragment {
        Some(f) => format!("{path}#{}", redact_pairs(f)),
        None => path,
    }
}

/// `key=value&…` with every non-empty value replaced by `***`; a part without `=` is kept.
fn redact_pairs(pairs: &str) -> String {
    let parts: Vec<String> = (pairs.split('&'))
        .map(|pair| match pair.split_once('=') {
            Some((key, value)) if !value.is_empty() => format!("{key}=***"),
            _ => pair.to_string(),
        })
        .collect();
    parts.join("&")
}

/// A [`BlockSource`] reading blocks from `url` with HTTP range requests. Cheap to share between loader
/// threads (`Arc<HttpSource>`); connections are pooled.
pub struct HttpSource {
    url: String,
    /// [`redact_url`] of `url`: what messages and [`BlockSource::name`] show.
    shown: String,
    agent: ureq::Agent,
    options: HttpOptions,
    file_len: u64,
    counters: Counters,
}

impl HttpSource {
    /// Opens the paging file at `url` (`http://host:port/path`): fetches its header, then its tables
    /// (everything before the first block) with range requests, and validates them exactly as a local open
    /// does. Returns the table-only file (its [`TreeFile::block`] fails: blocks come from the source) and
    /// the source. Errors: [`SourceError::Tables`] when the server cannot deliver the bytes,
    /// [`SourceError::Store`] when they are not a valid paging file (or the server's length differs from
    /// the header's).
    pub fn open(url: &str, options: HttpOptions) -> Result<(TreeFile, HttpSource), SourceError> {
        let mut source = HttpSource::new(url, options);
        let (prefix_len, head) =
            source.get_tables(0, HEADER_SIZE as u64, |r| TreeFile::prefix_len(&r.bytes))?;
        if prefix_len > source.options.max_table_bytes {
            return Err(SourceError::TablesTooLarge {
                url: source.shown.clone(),
                bytes: prefix_len,
                limit: source.options.max_table_bytes,
            });
        }
        let header: Header = bytemuck::pod_read_unaligned(&head.bytes[..HEADER_SIZE]);
        let file_len = |r: &Ranged| r.total.or(head.total).unwrap_or(header.file_len);
        let shown = source.shown.clone();
        let (file, prefix) = source.get_tables(0, prefix_len, |r| {
            TreeFile::from_prefix(&r.bytes, file_len(r), &shown)
        })?;
        source.file_len = file_len(&prefix);
        Ok((file, source))
    }

    fn new(url: &str, options: HttpOptions) -> HttpSource {
        let config = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_connect(Some(options.connect_timeout))
            .timeout_global(Some(options.timeout))
            .max_idle_connections_per_host(16)
            .user_agent(concat!("atlastree/", env!("CARGO_PKG_VERSION")))
            .build();
        HttpSource {
            url: url.to_string(),
            shown: redact_url(url),
            agent: config.into(),
            options,
            file_len: 0,
            counters: Counters::default(),
        }
    }

    /// The URL blocks are read from as messages show it: its password redacted ([`redact_url`]).
    pub fn shown_url(&self) -> &str {
        &self.shown
    }

    /// Length of the remote file, bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// The options in force.
    pub fn options(&self) -> &HttpOptions {
        &self.options
    }

    /// A snapshot of the counters (relaxed loads: fields may be from slightly different instants).
    pub fn stats(&self) -> HttpStats {
        self.counters.snapshot()
    }

    /// `len` bytes at `offset` for the tables, parsed by `parse`, with retries. A transfer whose bytes fail
    /// a checksum or hold non-zero padding ([`StoreError::ChecksumMismatch`],
    /// [`StoreError::NonZeroPadding`]: corrupt in transit) counts as a failed attempt and is
    /// asked again; another parse error is returned at once as [`SourceError::Store`]; a fetch that fails
    /// after every attempt is [`SourceError::Tables`].
    fn get_tables<T>(
        &self,
        offset: u64,
        len: u64,
        parse: impl Fn(&Ranged) -> Result<T, StoreError>,
    ) -> Result<(T, Ranged), SourceError> {
        let parsed = std::cell::RefCell::new(None);
        let check = |r: &Ranged| match parse(r) {
            Err(e @ (StoreError::ChecksumMismatch { .. } | StoreError::NonZeroPadding { .. })) => {
                bump(&self.counters.checksum_failures, 1);
                Err(Failure::Corrupt(e.to_string()))
            }
            other => {
                *parsed.borrow_mut() = Some(other);
                Ok(())
            }
        };
        let result = self.get_with_retries(offset, len, u64::MAX, check);
        let tables_error = |failure: Failure, attempts| SourceError::Tables {
            url: self.shown.clone(),
            offset,
            len,
            attempts,
            message: failure.message(len),
        };
        let value = match (result, parsed.into_inner()) {
            (Ok(ranged), Some(Ok(value))) => Ok((value, ranged)),
            (Ok(_), Some(Err(error))) => Err(SourceError::Store {
                source_name: self.shown.clone(),
                error,
            }),
            (Ok(_), None) => Err(tables_error(
                Failure::Corrupt("the tables were not parsed".into()),
                1,
            )),
            (Err((Failure::NotPaging(found), _)), _) => Err(SourceError::Store {
                source_name: self.shown.clone(),
                error: StoreError::BadMagic {
                    path: self.shown.clone().into(),
                    found,
                },
            }),
            (Err((failure, attempts)), _) => Err(tables_error(failure, attempts)),
        };
        self.counters.outcome(value.is_ok());
        value
    }

    /// One range with retries, each answer checked by `check` (a failed check is one failed attempt).
    /// `seed` varies the backoff jitter (the block id), so loader threads that fail together do not retry
    /// in lockstep. Errors carry the number of attempts made.
    fn get_with_retries(
        &self,
        offset: u64,
        len: u64,
        seed: u64,
        check: impl Fn(&Ranged) -> Result<(), Failure>,
    ) -> Result<Ranged, (Failure, u32)> {
        let mut attempt = 0u32;
        loop {
            match self
                .get_range(offset, len)
                .and_then(|r| check(&r).map(|()| r))
            {
                Ok(r) => return Ok(r),
                Err(f) if f.retryable() && attempt < self.options.retries => {
                    bump(&self.counters.retries, 1);
                    std::thread::sleep(backoff(&self.options, attempt, seed));
                    attempt += 1;
                }
                Err(f) => return Err((f, attempt + 1)),
            }
        }
    }

    /// One `GET` of bytes `offset..offset + len` (`len > 0`).
    fn get_range(&self, offset: u64, len: u64) -> Result<Ranged, Failure> {
        bump(&self.counters.requests, 1);
        // Sizes come from the server's header: an empty or overflowing range is refused, not computed.
        let last = (offset.checked_add(len))
            .and_then(|end| end.checked_sub(1))
            .filter(|_| len > 0)
            .ok_or_else(|| Failure::Request(format!("no byte range {offset}+{len}")))?;
        let response = (self.agent.get(&self.url))
            .header("Range", format!("bytes={offset}-{last}"))
            .call()
            .map_err(|e| Failure::from_ureq(e, &self.options))?;
        let status = response.status().as_u16();
        let content_range = (response.headers().get("content-range"))
            .and_then(|v| v.to_str().ok())
            .map(str::to_owned);
        let content_length = response.body().content_length();
        // Bytes encoded on the way (a gzip the client did not ask for: a pre-compressed object on S3 or a
        // CDN) are not the file's: named, not retried ("got 320 of 528 bytes" after four tries; fault
        // hunt, session 36). Only where the body would be the file's bytes: a gzipped 503 page is a 503.
        let encodings: Vec<&str> = (response.headers().get_all("content-encoding").iter())
            .filter_map(|v| v.to_str().ok())
            .flat_map(|v| v.split(','))
            .map(str::trim)
            .filter(|e| !e.is_empty() && !e.eq_ignore_ascii_case("identity"))
            .collect();
        if matches!(status, 200 | 206) && !encodings.is_empty() {
            return Err(Failure::Request(format!(
                "the server sent the bytes with Content-Encoding: {}, not as stored: serve the paging \
                 file uncompressed (`atlastree serve` does)",
                encodings.join(", ")
            )));
        }
        let mut body = response.into_body().into_reader();
        match status {
            206 => {
                let total = check_content_range(content_range.as_deref(), offset, last)?;
                let bytes = self.read_len(&mut body, len)?;
                Ok(Ranged { bytes, total })
            }
            200 => {
                bump(&self.counters.full_responses, 1);
                self.skip(&mut body, offset)?;
                let bytes = match self.read_len(&mut body, len) {
                    // The whole answer from the file's start, shorter than asked for (with or without a
                    // `Content-Length`): if it does not start as a paging file, nothing will.
                    Err(Failure::Short { got, head }) if offset == 0 && got > 0 => {
                        let magic = &crate::store::format::MAGIC;
                        let n = head.len().min(magic.len());
                        return Err(if magic.starts_with(&head[..n]) {
                            Failure::Short { got, head }
                        } else {
                            Failure::NotPaging(head)
                        });
                    }
                    other => other?,
                };
                Ok(Ranged {
                    bytes,
                    total: content_length,
                })
            }
            s => Err(Failure::Status(s)),
        }
    }

    /// Exactly `len` bytes of `body` (a longer body is cut: its extra bytes are never read).
    fn read_len(&self, body: &mut impl Read, len: u64) -> Result<Vec<u8>, Failure> {
        // `len` is bounded before any request: a block's by the checked tables, the tables' by
        // `max_table_bytes`. Reserved exactly, so the body is read without the doublings of a growing
        // vector (a 6 GiB table peaked at 12 GiB); an allocation the machine refuses is an error, not an
        // abort.
        let mut bytes = Vec::new();
        let reserve = usize::try_from(len)
            .map_err(|_| Failure::Request(format!("{len} bytes do not fit in memory")))?;
        bytes
            .try_reserve_exact(reserve)
            .map_err(|e| Failure::Request(format!("allocating {len} bytes: {e}")))?;
        let read = body.take(len).read_to_end(&mut bytes);
        bump(&self.counters.bytes, bytes.len() as u64);
        read.map_err(|e| self.body_error(&e))?;
        match bytes.len() as u64 {
            got if got == len => Ok(bytes),
            got => Err(Failure::Short {
                got,
                head: bytes[..bytes.len().min(64)].to_vec(),
            }),
        }
    }

    /// A body read's error; a timeout named as [`Failure::from_ureq`] names it.
    fn body_error(&self, e: &std::io::Error) -> Failure {
        if e.kind() == std::io::ErrorKind::TimedOut {
            return Failure::Transport(format!("reading the body: {}", timed_out(&self.options)));
        }
        Failure::Transport(format!("reading the body: {e}"))
    }

    /// Discards the first `n` bytes of a `200` body.
    fn skip(&self, body: &mut impl Read, n: u64) -> Result<(), Failure> {
        let skipped = std::io::copy(&mut body.take(n), &mut std::io::sink());
        let skipped = skipped.map_err(|e| self.body_error(&e))?;
        bump(&self.counters.bytes, skipped);
        if skipped < n {
            return Err(Failure::Short {
                got: 0,
                head: Vec::new(),
            });
        }
        Ok(())
    }

    fn block_error(
        &self,
        id: BlockId,
        record: &BlockRecord,
        f: Failure,
        attempts: u32,
    ) -> SourceError {
        let (url, offset, len) = (self.shown.clone(), record.offset, record.length);
        match f {
            Failure::Status(status) => SourceError::Status {
                url,
                block: id,
                status,
                offset,
                len,
                attempts,
            },
            Failure::Short { got, .. } => SourceError::Length {
                source_name: url,
                block: id,
                expected: len,
                got,
                attempts,
            },
            Failure::Checksum { found } => SourceError::Checksum {
                source_name: url,
                block: id,
                expected: record.checksum,
                found,
                attempts,
            },
            Failure::WrongRange { message, permanent } => SourceError::WrongRange {
                url,
                block: id,
                attempts,
                message,
                permanent,
            },
            Failure::Request(message) => SourceError::Request {
                url,
                block: id,
                message,
            },
            f @ (Failure::Transport(_) | Failure::Corrupt(_) | Failure::NotPaging(_)) => {
                SourceError::Transport {
                    message: f.message(len),
                    url,
                    block: id,
                    attempts,
                }
            }
        }
    }

    fn fetch_verified(&self, id: BlockId, record: &BlockRecord) -> Result<Vec<u8>, SourceError> {
        if record.length == 0 {
            verify(&self.shown, id, record, &[])?;
            return Ok(Vec::new());
        }
        // Attempts of this fetch whose answer failed the checksum: all of them, where it fails, point at
        // the served file (a timeout, then a bad checksum, does not).
        let mismatches = std::cell::Cell::new(0u32);
        let check = |r: &Ranged| {
            // A file of another length answering for the one opened: replaced on the server (its blocks
            // failed their checksums, reported as corruption; fault hunt, session 36).
            if let Some(total) = r.total.filter(|&t| t != self.file_len) {
                return Err(Failure::WrongRange {
                    message: format!(
                        "the server's file is now {total} bytes, {} when it was opened: it was replaced \
                         (open the URL again for the new file)",
                        self.file_len
                    ),
                    permanent: true,
                });
            }
            let found = xxhash_rust::xxh3::xxh3_64(&r.bytes);
            if found == record.checksum {
                return Ok(());
            }
            bump(&self.counters.checksum_failures, 1);
            mismatches.set(mismatches.get() + 1);
            Err(Failure::Checksum { found })
        };
        let ranged = self
            .get_with_retries(record.offset, record.length, id.0.into(), check)
            .map_err(|(f, attempts)| {
                if mismatches.get() == attempts {
                    bump(&self.counters.checksum_fetch_failures, 1);
                }
                self.block_error(id, record, f, attempts)
            })?;
        Ok(ranged.bytes)
    }
}

impl BlockSource for HttpSource {
    fn name(&self) -> String {
        self.shown.clone()
    }

    /// Fetches and verifies block `id` (see the module docs for the retry policy). Blocking; call it from
    /// a loader thread.
    fn fetch(&self, id: BlockId, record: &BlockRecord) -> Result<Vec<u8>, SourceError> {
        let result = self.fetch_verified(id, record);
        self.counters.outcome(result.is_ok());
        if result.is_ok() {
            bump(&self.counters.blocks, 1);
        }
        result
    }
}

/// Checks `Content-Range: bytes first-last/total` against the range asked for; returns the total (`None`
/// for `*`). A mismatch whose total ends before `last` says the server's file is shorter (permanent).
fn check_content_range(
    header: Option<&str>,
    first: u64,
    last: u64,
) -> Result<Option<u64>, Failure> {
    let wrong = |permanent: bool| Failure::WrongRange {
        message: format!(
            "206 with {}, expected bytes {first}-{last}/…",
            header.map_or("no Content-Range".to_string(), |h| format!(
                "Content-Range \"{h}\""
            ))
        ),
        permanent,
    };
    let spec = header
        .and_then(|h| {
            // The unit is case-insensitive (RFC 9110 §14.1).
            let h = h.trim();
            h.get(..6)
                .filter(|unit| unit.eq_ignore_ascii_case("bytes "))
                .map(|_| &h[6..])
        })
        .ok_or_else(|| wrong(false))?;
    let (range, total) = spec.split_once('/').ok_or_else(|| wrong(false))?;
    let parse = |s: &str| s.trim().parse::<u64>().ok();
    let total = match total.trim() {
        "*" => None,
        t => Some(parse(t).ok_or_else(|| wrong(false))?),
    };
    let (a, b) = range.split_once('-').ok_or_else(|| wrong(false))?;
    let shorter = total.is_some_and(|t| t <= last);
    if parse(a) != Some(first) || parse(b) != Some(last) || shorter {
        return Err(wrong(shorter));
    }
    Ok(total)
}

/// The wait before retry `attempt` (0-based): `backoff_initial × 2^attempt`, at most `backoff_max`, times
/// a jitter factor in [0.5, 1] that is a hash of `(seed, attempt)` (deterministic, different per block).
fn backoff(options: &HttpOptions, attempt: u32, seed: u64) -> Duration {
    let doubled = options
        .backoff_initial
        .saturating_mul(1u32 << attempt.min(20));
    // At most an hour, whatever a caller set (Duration::mul_f64 panics past Duration::MAX).
    let base = doubled
        .min(options.backoff_max)
        .min(Duration::from_secs(3600));
    let hash = splitmix64(seed ^ u64::from(attempt).rotate_left(32));
    let jitter = 0.5 + 0.5 * (hash >> 11) as f64 / (1u64 << 53) as f64;
    base.mul_f64(jitter)
}

fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passwords_are_redacted_from_shown_urls() {
        assert_eq!(
            redact_url("http://alice:s3cret@127.0.0.1:8080/f.atlastree"),
            "http://alice:***@127.0.0.1:8080/f.atlastree"
        );
        // An '@' in the path is not userinfo; a user without a password shows as given.
        for same in [
            "http://127.0.0.1/a@b.atlastree",
            "http://host:80/f?flag&empty=",
            "not a url",
        ] {
            assert_eq!(redact_url(same), same);
        }
        assert_eq!(redact_url("http://TOKEN@host/f"), "http://***@host/f");
        // Query and fragment values are credentials too (presigned URLs, OAuth redirects); keys and a
        // bare fragment stay.
        assert_eq!(
            redact_url("http://host:80/f?x=a:b@c"),
            "http://host:80/f?x=***"
        );
        assert_eq!(
            redact_url("https://u:p@b.example/t.atlastree?X-Amz-Signature=abc&v=2#frag"),
            "https://u:***@b.example/t.atlastree?X-Amz-Signature=***&v=***#frag"
        );
        assert_eq!(
            redact_url("https://host/f#access_token=abc&state=x"),
            "https://host/f#access_token=***&state=***"
        );
        assert_eq!(
            redact_url("https://host/f?a=1#t=2"),
            "https://host/f?a=***#t=***"
        );
    }

    #[test]
    fn content_range_must_match_the_request() {
        assert_eq!(
            check_content_range(Some("bytes 10-19/100"), 10, 19).unwrap(),
            Some(100)
        );
        assert_eq!(
            check_content_range(Some("bytes 10-19/*"), 10, 19).unwrap(),
            None
        );
        // The unit is case-insensitive.
        assert_eq!(
            check_content_range(Some("Bytes 10-19/100"), 10, 19).unwrap(),
            Some(100)
        );
        for bad in [
            "bytes 10-18/100",
            "bytes 0-19/100",
            "10-19/100",
            "bytes 10-19",
            "bytes 10-19/x",
        ] {
            assert!(check_content_range(Some(bad), 10, 19).is_err(), "{bad}");
        }
        assert!(check_content_range(None, 10, 19).is_err());
        // A total that ends before the range: the server's file is shorter, asking again cannot help.
        let shorter = |h: &str| match check_content_range(Some(h), 10, 19) {
            Err(Failure::WrongRange { permanent, .. }) => Some(permanent),
            _ => None,
        };
        assert_eq!(shorter("bytes 0-9/10"), Some(true));
        assert_eq!(shorter("bytes 10-18/19"), Some(true));
        assert_eq!(shorter("bytes 10-18/100"), Some(false));
        assert_eq!(shorter("bytes 10-18/*"), Some(false));
        // The asked range, but a total that cannot hold it.
        assert_eq!(shorter("bytes 10-19/15"), Some(true));
        assert!(
            Failure::WrongRange {
                message: String::new(),
                permanent: false
            }
            .retryable()
        );
        assert!(Failure::Checksum { found: 1 }.retryable());
        assert!(!Failure::Status(404).retryable() && Failure::Status(429).retryable());
    }

    #[test]
    fn backoff_doubles_is_capped_and_jitters_within_half() {
        let o = HttpOptions {
            backoff_initial: Duration::from_millis(100),
            backoff_max: Duration::from_millis(350),
            ..HttpOptions::default()
        };
        let bases = [100u64, 200, 350, 350, 350];
        for (attempt, base) in bases.iter().enumerate() {
            for seed in 0..50 {
                let d = backoff(&o, attempt as u32, seed).as_secs_f64() * 1000.0;
                assert!(
                    d >= *base as f64 * 0.5 - 1e-6 && d <= *base as f64 + 1e-6,
                    "{attempt} {d}"
                );
            }
        }
        assert_eq!(backoff(&o, 1, 7), backoff(&o, 1, 7));
        assert_ne!(backoff(&o, 1, 7), backoff(&o, 1, 8));
        assert!(backoff(&o, u32::MAX, 1) <= o.backoff_max);
    }
}
