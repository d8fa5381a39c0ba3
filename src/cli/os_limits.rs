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
//! - **One malloc arena under an address-space limit** (glibc): see
//!   [`one_malloc_arena_under_address_limit`].

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
        one_malloc_arena_under_address_limit();
    }
}

/// Under an address-space limit (`ulimit -v`, a batch system's `h_vmem`), glibc's malloc keeps its arenas'
/// reservations within an eighth of the limit: each arena past the first (one per thread that allocates,
/// up to 8 a core) reserves 64 MiB of address space whether it is used or not, so a merge of two shards
/// under `ulimit -v 250000` aborted in `malloc` (`memory allocation of 4194304 bytes failed`) with most of
/// the limit reserved and unused, while the same merge under 150000 (no room for the arenas: glibc fell
/// back to the first) finished (fault hunt, session 31). So at most `limit / 512 MiB` arenas, at least
/// one (one arena serialises some allocations). Without a limit, or with `MALLOC_ARENA_MAX` set (the
/// user's choice), nothing changes.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(
    unsafe_code,
    reason = "getrlimit(2) and glibc's mallopt(3) through libc, before any thread is started"
)]
fn one_malloc_arena_under_address_limit() {
    let mut lim = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: `getrlimit` writes into `lim`, a valid local; `mallopt` sets a malloc parameter and
    // touches no memory the Rust code owns. Called from `main` before the thread pools start.
    unsafe {
        if std::env::var_os("MALLOC_ARENA_MAX").is_none()
            && libc::getrlimit(libc::RLIMIT_AS, &mut lim) == 0
            && lim.rlim_cur != libc::RLIM_INFINITY
        {
            let arenas = atlastree::util::malloc_arenas_under(lim.rlim_cur);
            libc::mallopt(libc::M_ARENA_MAX, arenas as libc::c_int);
        }
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn one_malloc_arena_under_address_limit() {}

/// Whether `signal`'s action is "ignore" (as the process was started: `nohup`, a script's `cmd &`);
/// `false` where it cannot be asked.
#[cfg(unix)]
#[allow(
    unsafe_code,
    reason = "sigaction(2) through libc, asking the current action without changing it"
)]
pub(super) fn ignored_at_start(signal: i32) -> bool {
    let mut old = std::mem::MaybeUninit::<libc::sigaction>::zeroed();
    // SAFETY: a null new action only reads the current one into `old`, a valid, zeroed local.
    let asked = unsafe { libc::sigaction(signal, std::ptr::null(), old.as_mut_ptr()) } == 0;
    // SAFETY: zero-initialised, then written by `sigaction` where it succeeded; read only then.
    asked && unsafe { old.assume_init() }.sa_sigaction == libc::SIG_IGN
}
