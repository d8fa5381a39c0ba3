//! Process limits set before any work (Unix; nothing elsewhere), so the operating system's limits end
//! in the tool's own errors instead of a signal (fault hunt, session 29):
//!
//! - **SIGXFSZ ignored.** Under a file-size limit (`ulimit -f`, a scheduler's), the kernel killed the
//!   process on the write past it (exit 153, no message) and left its hidden temp file. Ignored, that
//!   write fails with `EFBIG` ("File too large"), which every writer reports, naming the file, and the
//!   temp is removed as on any other write error.
//! - **Open files: the soft limit raised to the hard one.** A merge opens every shard at once (up to
//!   4096, `--shard`'s limit) and failed at 1,019 shards under the usual soft limit of 1024, reported
//!   as a corrupt shard; `serve`'s connections count too. Raising the soft limit up to the hard one is
//!   what the hard limit is for (no privilege needed).

/// Applies both (see the module docs). Failures are ignored: the limits stay as they were.
pub(super) fn prepare_process() {
    #[cfg(unix)]
    #[allow(
        unsafe_code,
        reason = "signal(2) and get/setrlimit(2) through libc: plain system calls on values owned here"
    )]
    // SAFETY: `signal` installs SIG_IGN (no handler code runs); `getrlimit` writes into `lim`, a valid
    // local; `setrlimit` reads it. None of them touches memory the Rust code owns elsewhere.
    unsafe {
        libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
        let mut lim = libc::rlimit {
            rlim_cur: 0,
            rlim_max: 0,
        };
        if libc::getrlimit(libc::RLIMIT_NOFILE, &mut lim) == 0 && lim.rlim_cur < lim.rlim_max {
            lim.rlim_cur = lim.rlim_max;
            libc::setrlimit(libc::RLIMIT_NOFILE, &lim);
        }
    }
}
