//! What memory this process uses and may use (Linux `/proc` and cgroups): the build's per-stage peaks and
//! the default `--max-memory` budget.

use std::path::Path;

/// The `kB` fields `keys` of a Linux `/proc` file (`status`, `meminfo`), in bytes, from one read; `None`
/// where the file or a field is unavailable.
fn proc_kb_fields<const N: usize>(path: &str, keys: [&str; N]) -> Option<[u64; N]> {
    kb_fields(&std::fs::read_to_string(path).ok()?, keys)
}

/// The `kB` fields `keys` of a `/proc` text, in bytes ([`proc_kb_fields`]).
fn kb_fields<const N: usize>(s: &str, keys: [&str; N]) -> Option<[u64; N]> {
    let mut out = [0u64; N];
    for (o, key) in out.iter_mut().zip(keys) {
        let line = s.lines().find(|l| l.starts_with(key))?;
        let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
        *o = kb * 1024;
    }
    Some(out)
}

fn status_bytes(key: &str) -> Option<u64> {
    proc_kb_fields("/proc/self/status", [key]).map(|[v]| v)
}

/// This process's resident set size now and its peak (`VmRSS`, `VmHWM`), bytes, from one read.
pub fn rss_and_peak_bytes() -> Option<[u64; 2]> {
    proc_kb_fields("/proc/self/status", ["VmRSS:", "VmHWM:"])
}

/// Peak resident set size of this process in bytes (Linux `VmHWM`); `None` where unavailable. Never reset
/// by this crate, so `/usr/bin/time`, Slurm's `MaxRSS` and cgroup accounting see the true peak.
pub fn peak_rss_bytes() -> Option<u64> {
    status_bytes("VmHWM:")
}

/// Resident set size of this process now, bytes (Linux `VmRSS`); `None` where unavailable.
pub fn rss_bytes() -> Option<u64> {
    status_bytes("VmRSS:")
}

/// The machine's physical memory (Linux `MemTotal`), bytes; `None` where the platform does not tell.
pub fn machine_memory_bytes() -> Option<u64> {
    proc_kb_fields("/proc/meminfo", ["MemTotal:"]).map(|[v]| v)
}

/// The memory this process may use, bytes: the machine's ([`machine_memory_bytes`]), or the memory limit
/// of its cgroup where that is smaller (a Slurm job, a Kubernetes pod, a container: half of a 256 GiB
/// node is no budget for a job allowed 8 GiB, which the kernel kills past its limit), or what its
/// address-space limit leaves where smaller still (`ulimit -v`, an HPC job's `h_vmem`: past it every
/// allocation fails and the process aborts; [`address_space_left`], measured now). `None` where the
/// platform tells none of them.
pub fn memory_limit_bytes() -> Option<u64> {
    let cgroup = cgroup_memory_limit(Path::new("/proc/self/cgroup"), Path::new("/sys/fs/cgroup"));
    let address_space = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|text| address_space_limit(&text))
        .map(|limit| {
            // What the limit leaves for data: not what this process has already mapped (`VmSize`), nor
            // what the worker threads reserve without touching it (their stacks, and glibc's malloc
            // arenas up to the cap the binary sets: `address_space_left`),
            // which count against it though never resident: 16 threads under `ulimit -v 600000` aborted in
            // malloc with ~90 MiB resident (review, session 29).
            // One read of `status` for both the mapped size and the thread count.
            let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
            let mapped = kb_fields(&status, ["VmSize:"]).map_or(0, |[v]| v);
            let workers = std::env::var("RAYON_NUM_THREADS")
                .ok()
                .and_then(|v| v.trim().parse::<u64>().ok())
                .filter(|&n| n > 0)
                .or_else(|| {
                    std::thread::available_parallelism()
                        .ok()
                        .map(|n| n.get() as u64)
                })
                .unwrap_or(1);
            // `MALLOC_ARENA_MAX` set: the binary leaves glibc's arenas to it (set to what glibc does not
            // take, glibc's own default of 8 a core: one a worker here).
            let arenas = match std::env::var_os("MALLOC_ARENA_MAX") {
                None => malloc_arenas_under(limit),
                Some(v) => (v.to_str())
                    .and_then(|v| v.trim().parse::<u64>().ok())
                    .filter(|&n| n > 0)
                    .unwrap_or(u64::MAX),
            };
            let running = threads_of(&status).unwrap_or(1);
            address_space_left(
                limit,
                mapped,
                Threads {
                    workers,
                    running,
                    arenas,
                },
            )
        });
    [machine_memory_bytes(), cgroup, address_space]
        .into_iter()
        .flatten()
        .min()
}

/// The threads an address-space limit has to leave room for.
struct Threads {
    /// Rasteriser workers the pool will run.
    workers: u64,
    /// Threads running now, this one included.
    running: u64,
    /// glibc malloc arenas at most, the main one included (`MALLOC_ARENA_MAX`, else
    /// [`malloc_arenas_under`] the limit, as the binary sets it before any thread starts).
    arenas: u64,
}

/// What an address-space `limit` leaves for data (bytes): less what the process has mapped (`mapped`,
/// `VmSize`: its running threads' reservations included) and what the workers not yet running (beyond
/// the running threads but this one) will reserve: each its stack ([`RESERVED_STACK`]), and each its own
/// malloc arena ([`RESERVED_ARENA`]) until the arenas' cap is reached; past it threads share arenas.
/// Counting an arena for every worker left 16 threads under `ulimit -v 1200000` a budget of ~0, though
/// the binary caps glibc at two arenas there and the build peaked at 114 MiB (fault hunt, session 38).
fn address_space_left(limit: u64, mapped: u64, t: Threads) -> u64 {
    let to_start = t.workers.saturating_sub(t.running.saturating_sub(1));
    // Arenas beyond the main one: one a thread but the main thread, up to the cap.
    let extra = |threads: u64| threads.min(t.arenas.saturating_sub(1));
    let arenas_to_come = extra(t.workers).saturating_sub(extra(t.running.saturating_sub(1)));
    limit
        .saturating_sub(mapped)
        .saturating_sub(to_start.saturating_mul(RESERVED_STACK))
        .saturating_sub(arenas_to_come.saturating_mul(RESERVED_ARENA))
}

/// The malloc arenas the binary allows under an address-space `limit` (bytes): one per 512 MiB, at least
/// one, at most 1024 (`cli::os_limits`: the arenas' reservations, 64 MiB each, starved the heap under
/// `ulimit -v 250000`; fault hunt, session 31).
pub fn malloc_arenas_under(limit: u64) -> u64 {
    (limit / (512 << 20)).clamp(1, 1024)
}

/// The thread count of a `/proc/PID/status` text (Linux `Threads:`).
fn threads_of(text: &str) -> Option<u64> {
    text.lines()
        .find_map(|l| l.strip_prefix("Threads:"))
        .and_then(|v| v.trim().parse().ok())
}

/// Address space a glibc malloc arena reserves without using it (64 MiB on 64-bit systems).
const RESERVED_ARENA: u64 = 64 << 20;
/// Address space a worker thread's stack reserves (rayon's 2 MiB, rounded up).
const RESERVED_STACK: u64 = 8 << 20;

/// The soft address-space limit in a `/proc/PID/limits` text (`Max address space  SOFT  HARD  bytes`),
/// bytes; `None` where it is "unlimited" or absent.
fn address_space_limit(limits: &str) -> Option<u64> {
    soft_limit(limits, "Max address space")
}

/// The soft limit of the `/proc/PID/limits` line starting with `name`; `None` where it is "unlimited"
/// or absent.
fn soft_limit(limits: &str, name: &str) -> Option<u64> {
    let line = limits.lines().find(|l| l.starts_with(name))?;
    line[name.len()..].split_whitespace().next()?.parse().ok()
}

/// This process's soft open-files limit (`ulimit -n`, Linux `/proc/self/limits`): `Ok(None)` where it
/// is unlimited or the platform does not tell, `Err` where no file can be opened to read it (the limit
/// reached).
pub fn open_files_limit() -> Result<Option<u64>, std::io::Error> {
    match std::fs::read_to_string("/proc/self/limits") {
        Ok(limits) => Ok(soft_limit(&limits, "Max open files")),
        Err(e) if super::is_out_of_descriptors(&e) => Err(e),
        Err(_) => Ok(None),
    }
}

/// The smallest memory limit on the way from this process's cgroups (`proc_cgroup`: lines
/// `id:controllers:path`) up to the hierarchy's root under `root`: cgroup v2 (`0::/path`,
/// `memory.max`; "max" is no limit) and v1 (the `memory` controller, `memory/…/memory.limit_in_bytes`;
/// "unlimited" is a huge number, which the machine's memory undercuts).
fn cgroup_memory_limit(proc_cgroup: &Path, root: &Path) -> Option<u64> {
    let text = std::fs::read_to_string(proc_cgroup).ok()?;
    let mut smallest: Option<u64> = None;
    for line in text.lines() {
        let mut parts = line.splitn(3, ':');
        let (Some(_), Some(controllers), Some(path)) = (parts.next(), parts.next(), parts.next())
        else {
            continue;
        };
        let (base, file) = if controllers.is_empty() {
            (root.to_path_buf(), "memory.max")
        } else if controllers.split(',').any(|c| c == "memory") {
            (root.join("memory"), "memory.limit_in_bytes")
        } else {
            continue;
        };
        let mut dir = base.join(path.trim_start_matches('/'));
        while dir.starts_with(&base) {
            let limit = std::fs::read_to_string(dir.join(file))
                .ok()
                .and_then(|v| v.trim().parse::<u64>().ok());
            if let Some(limit) = limit {
                smallest = Some(smallest.map_or(limit, |s| s.min(limit)));
            }
            if !dir.pop() {
                break;
            }
        }
    }
    smallest
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_address_space_left_counts_threads_once() {
        const MIB: u64 = 1 << 20;
        let t = |workers, running, arenas| Threads {
            workers,
            running,
            arenas,
        };
        // 3000 MiB allowed, 100 mapped, 16 workers, only the main thread running: 16 stacks and, with
        // 64 arenas allowed, 16 arenas to come.
        let left = address_space_left(3000 * MIB, 100 * MIB, t(16, 1, 64));
        assert_eq!(left, 2900 * MIB - 16 * (RESERVED_STACK + RESERVED_ARENA));
        // Capped at 2 arenas (the main one and one more): the workers share the second.
        let left = address_space_left(1200 * MIB, 100 * MIB, t(16, 1, 2));
        assert_eq!(left, 1100 * MIB - 16 * RESERVED_STACK - RESERVED_ARENA);
        // The pool running (17 threads): its reservations are in the mapped size already.
        assert_eq!(
            address_space_left(3000 * MIB, 100 * MIB, t(16, 17, 64)),
            2900 * MIB
        );
        // Past the limit: nothing left, not an underflow.
        assert_eq!(address_space_left(1000 * MIB, 100 * MIB, t(16, 1, 64)), 0);
        assert_eq!(malloc_arenas_under(1200 * MIB), 2);
        assert_eq!(malloc_arenas_under(100 * MIB), 1);
        let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
        assert!(threads_of(&status).is_some_and(|n| n >= 1));
    }

    #[test]
    fn the_address_space_limit_is_read_from_proc_limits() {
        let text = "Limit                     Soft Limit           Hard Limit           Units     \n\
                    Max file size             unlimited            unlimited            bytes     \n\
                    Max address space         307200000            unlimited            bytes     \n";
        assert_eq!(address_space_limit(text), Some(307_200_000));
        let unlimited = text.replace("307200000", "unlimited");
        assert_eq!(address_space_limit(&unlimited), None);
        assert_eq!(address_space_limit(""), None);
        let files =
            "Max open files            7                    7                    files     \n";
        assert_eq!(soft_limit(files, "Max open files"), Some(7));
        assert!(open_files_limit().unwrap().is_some_and(|n| n > 0));
    }

    #[test]
    fn cgroup_limits_are_the_smallest_on_the_way_up() {
        let dir = tempfile::tempdir().unwrap();
        let root = dir.path().join("cg");
        let write = |rel: &str, text: &str| {
            let p = root.join(rel);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, text).unwrap();
        };
        // v2: a Slurm step under a job limited to 8 GiB, the step itself unlimited.
        write("memory.max", "max\n");
        write("system.slice/job_7/memory.max", "8589934592\n");
        write("system.slice/job_7/step_0/memory.max", "max\n");
        let proc = dir.path().join("cgroup");
        std::fs::write(&proc, "0::/system.slice/job_7/step_0\n").unwrap();
        assert_eq!(cgroup_memory_limit(&proc, &root), Some(8 << 30));
        // v1: the memory controller's limit (unlimited is a huge number), other controllers ignored.
        write("memory/pod/memory.limit_in_bytes", "2147483648\n");
        write("memory/memory.limit_in_bytes", "9223372036854771712\n");
        std::fs::write(&proc, "4:memory:/pod\n3:cpuset:/\n").unwrap();
        assert_eq!(cgroup_memory_limit(&proc, &root), Some(2 << 30));
        // No limit anywhere: none.
        std::fs::write(&proc, "0::/\n").unwrap();
        assert_eq!(cgroup_memory_limit(&proc, &root), None);
        assert_eq!(cgroup_memory_limit(&dir.path().join("absent"), &root), None);
    }
}
