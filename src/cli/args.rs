//! Flag groups shared by several commands (`#[command(flatten)]`), each with its validate step: parsed
//! flags → a checked value the command's `run` uses. A flag of a group that means nothing for one command
//! is refused there with a message naming the flag and why (see [`PagingArgs::given_beyond_capacity`]).

use anyhow::{Context, bail};
use atlastree::camera::{Camera, CameraPath};
use atlastree::model::BuildParams;
use atlastree::paging::HttpOptions;
use atlastree::paging::{PagerOptions, Policy, UploadBudget};
use atlastree::preprocess::BuildOptions;
use atlastree::select::{SelectOptions, min_distance_scale};
use clap::Args;

/// Most frames one `render`, `simulate` or `demo` run takes (as `sweep`): 100,000 frames is ~55 min of
/// path at 30 fps; the per-frame records of more would exhaust memory before the first frame.
pub(crate) const MAX_FRAMES: usize = 100_000;

/// Most loader threads a paged run starts.
pub(crate) const MAX_LOADER_THREADS: usize = 64;

/// Slowest frame clock a flag takes (frames per second): a frame every ~11.6 days. Below it the clock of
/// a long run leaves f64 (`--fps 1e-308` rendered two frames, then failed on an infinite time).
pub(crate) const MIN_FPS: f64 = 1e-6;

/// A frame rate of a flag (`flag` names it): finite and at least [`MIN_FPS`].
pub(crate) fn check_fps(flag: &str, fps: f64) -> anyhow::Result<()> {
    if !(fps.is_finite() && fps >= MIN_FPS) {
        bail!(
            "{flag} must be a finite number of frames per second, at least {MIN_FPS:e} (got {})",
            atlastree::util::short_number(fps)
        );
    }
    Ok(())
}

/// A frame count of a flag (`flag` names it) is 1 to [`MAX_FRAMES`].
pub(crate) fn check_frames(flag: &str, frames: usize) -> anyhow::Result<()> {
    if frames == 0 || frames > MAX_FRAMES {
        bail!("{flag} must be 1 to {MAX_FRAMES} (got {frames})");
    }
    Ok(())
}

/// Declares a viewport flag group with a command's default frame size (a const-generic struct would
/// share one default string between its instances: clap keeps it in a static of the generic function).
macro_rules! viewport_args {
    ($(#[$doc:meta])* $name:ident, $w:expr, $h:expr) => {
        $(#[$doc])*
        #[derive(Args, Debug, Clone, Copy)]
        pub(crate) struct $name {
            /// Frame width, pixels (node min_distances scale linearly with it, paper §4).
            #[arg(long, default_value_t = $w)]
            pub(crate) width: u32,
            /// Frame height, pixels.
            #[arg(long, default_value_t = $h)]
            pub(crate) height: u32,
            /// Texels per pixel required (node min_distances scale linearly with it).
            #[arg(long, default_value_t = 1.0)]
            pub(crate) texel_ratio: f64,
        }

        impl $name {
            /// Checks the sizes and the ratio.
            pub(crate) fn validate(self) -> anyhow::Result<Viewport> {
                Viewport::new(self.width, self.height, self.texel_ratio)
            }
        }
    };
}

viewport_args!(
    /// Frame size and texel-per-pixel target of an offscreen run (`render`, `simulate`): 800×600 by default.
    ViewportArgs,
    800,
    600
);
viewport_args!(
    /// Window size and texel-per-pixel target of `view`: 1280×720 by default.
    WindowArgs,
    1280,
    720
);

/// A checked [`ViewportArgs`]: width and height > 0, texel ratio finite and > 0.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Viewport {
    pub width: u32,
    pub height: u32,
    pub texel_ratio: f64,
}

impl Viewport {
    /// Checks width and height > 0 and a finite texel ratio > 0.
    pub(crate) fn new(width: u32, height: u32, texel_ratio: f64) -> anyhow::Result<Viewport> {
        if width == 0 || height == 0 {
            bail!("--width and --height must be > 0 (got {width}×{height})");
        }
        if !(texel_ratio.is_finite() && texel_ratio > 0.0) {
            bail!("--texel-ratio must be finite and > 0 (got {texel_ratio})");
        }
        Ok(Viewport {
            width,
            height,
            texel_ratio,
        })
    }

    /// Width / height.
    pub(crate) fn aspect(&self) -> f64 {
        f64::from(self.width) / f64::from(self.height)
    }

    /// `frames` cameras of `path` at `fps` (path time `i / fps`) with this viewport's aspect.
    pub(crate) fn cameras(&self, path: &CameraPath, fps: f64, frames: usize) -> Vec<Camera> {
        let aspect = self.aspect();
        path.frames(fps, frames)
            .map(|mut c| {
                c.aspect = aspect;
                c
            })
            .collect()
    }

    /// The factor of every node's `min_distance` for this width and texel ratio at horizontal field of
    /// view `fov_x_deg` ([`min_distance_scale`], paper §4).
    pub(crate) fn scale(&self, params: &BuildParams, fov_x_deg: f64) -> anyhow::Result<f64> {
        Ok(min_distance_scale(
            params,
            &SelectOptions {
                screen_width: self.width,
                texel_ratio: self.texel_ratio,
                fov_x_deg,
            },
        )?)
    }

    /// [`Self::scale`] for each of `cameras` at its own field of view (a path may change it: the
    /// overview-dive's street part is at 75°).
    pub(crate) fn scales(
        &self,
        params: &BuildParams,
        cameras: &[atlastree::camera::Camera],
    ) -> anyhow::Result<Vec<f64>> {
        cameras
            .iter()
            .map(|c| self.scale(params, c.fov_x_deg))
            .collect()
    }
}

/// How blocks queue and become resident per frame (`render --capacity`, `simulate`). Unset flags take
/// the defaults of [`PagerOptions`].
#[derive(Args, Debug, Clone, Default)]
pub(crate) struct QueueArgs {
    /// Upload budget per frame: `unlimited` (or a bare `0`), bytes (`8MB`, `512KiB`) or, for `render`,
    /// time (`2ms`): blocks are accepted while the frame's total is below it (the block that crosses it
    /// too, so a frame may exceed it by one block); at least one block per frame is always accepted, so a
    /// zero size with a unit (`0B`) is refused as meaningless [default: unlimited]
    #[arg(long, value_name = "BUDGET")]
    pub upload_budget: Option<UploadBudget>,
    /// Maximum outstanding block requests [default: 8]
    #[arg(long, value_name = "N")]
    pub max_queue: Option<u32>,
}

impl QueueArgs {
    /// The first flag given, for "means nothing here" messages.
    pub(crate) fn given(&self) -> Option<&'static str> {
        if self.upload_budget.is_some() {
            Some("--upload-budget")
        } else if self.max_queue.is_some() {
            Some("--max-queue")
        } else {
            None
        }
    }

    /// `base` with the given flags applied.
    pub(crate) fn apply(&self, base: PagerOptions) -> anyhow::Result<PagerOptions> {
        if self.max_queue == Some(0) {
            bail!("--max-queue must be > 0");
        }
        Ok(PagerOptions {
            budget: self.upload_budget.unwrap_or(base.budget),
            max_queue: self.max_queue.unwrap_or(base.max_queue),
            ..base
        })
    }

    /// The budget for the simulator, which has no uploads to time: a time budget is refused.
    pub(crate) fn byte_budget(&self) -> anyhow::Result<UploadBudget> {
        match self.upload_budget.unwrap_or_default() {
            UploadBudget::Millis(ms) => bail!(
                "--upload-budget {ms}ms: simulate has no uploads to time (its executor only records the \
                 residency changes, so a time budget would time that bookkeeping on this machine); give \
                 a byte budget such as 8MB, or unlimited"
            ),
            b => Ok(b),
        }
    }
}

/// `--capacity`: a block count ≥ 1, or `all` (every block may be resident).
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub(crate) enum Capacity {
    All,
    Blocks(u32),
}

impl Capacity {
    /// The block count; `None` for `all`.
    pub(crate) fn blocks(self) -> Option<u32> {
        match self {
            Capacity::All => None,
            Capacity::Blocks(k) => Some(k),
        }
    }
}

impl std::str::FromStr for Capacity {
    type Err = String;
    fn from_str(s: &str) -> Result<Capacity, String> {
        if s == "all" {
            return Ok(Capacity::All);
        }
        match s.parse::<u32>() {
            Ok(k) if k > 0 => Ok(Capacity::Blocks(k)),
            Ok(_) => Err("must be > 0 (omit it to upload every block at start)".into()),
            Err(e) if *e.kind() == std::num::IntErrorKind::PosOverflow => Err(format!(
                "{s} blocks is more than a capacity holds (at most {}; `all` keeps every block)",
                u32::MAX
            )),
            Err(_) => Err(format!("expected a block count ≥ 1 or `all`, got {s:?}")),
        }
    }
}

/// Paging under a capacity (paper §6) for `render` and `view`.
#[derive(Args, Debug, Clone, Default)]
pub(crate) struct PagingArgs {
    /// Page blocks with at most this many resident (the paper used 160); missing blocks are drawn with
    /// the nearest resident ancestor atlas. `all`: `render` pages every block on demand and evicts none
    /// (as `simulate --capacity all`); `view` uploads every block at start, as without the flag. Omit
    /// to upload every block at start.
    #[arg(long, value_name = "K|all")]
    pub capacity: Option<Capacity>,
    /// Where paged blocks come from: `file` (the paging file, memory-mapped) or an http(s) URL of the
    /// same file on any static server that supports range requests (see `atlastree serve`)
    /// [default: file]
    #[arg(long, value_name = "file|URL")]
    pub source: Option<String>,
    #[command(flatten)]
    pub queue: QueueArgs,
    /// Paging policy: paper (§6), distance, lru, ours (paper + hysteresis + lookahead) [default: paper]
    #[arg(long)]
    pub policy: Option<Policy>,
    /// Loader threads; 0 loads synchronously within the frame (deterministic; over HTTP a server that
    /// stalls then holds the frame for up to `--http-retries` + 1 attempts of `--http-timeout` a block,
    /// where loader threads count the block as failed and draw on) [default: 2]
    #[arg(long, value_name = "N")]
    pub loader_threads: Option<usize>,
    /// Over HTTP: seconds one request may take before it counts as failed (and is retried)
    /// [default: 30]
    #[arg(long, value_name = "SECONDS", value_parser = clap::value_parser!(u64).range(1..=3600))]
    pub http_timeout: Option<u64>,
    /// Over HTTP: retries of a failed request, with a doubling back-off [default: 3]
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(0..=20))]
    pub http_retries: Option<u32>,
}

/// Where paged blocks come from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) enum SourceArg {
    /// The paging file itself, memory-mapped.
    File,
    /// An http(s) URL of the same file.
    Url(String),
}

/// A checked [`PagingArgs`] for a paged run (the capacity is decided by the command).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Paging {
    /// Pager options; `capacity` is filled in by the command.
    pub pager: PagerOptions,
    pub source: SourceArg,
    pub loader_threads: usize,
    /// `--http-timeout` and `--http-retries` (the defaults of [`HttpOptions`] where not given).
    pub http_timeout: std::time::Duration,
    pub http_retries: u32,
}

impl Paging {
    /// The HTTP client's options of this run: [`HttpOptions::default`] with the run's timeout and
    /// retries.
    pub(crate) fn http_options(&self) -> HttpOptions {
        HttpOptions {
            timeout: self.http_timeout,
            retries: self.http_retries,
            ..HttpOptions::default()
        }
    }
}

/// Whether `s` is an http(s) URL (the scheme in any case, as RFC 3986 §3.1 allows).
pub(super) fn is_url(s: &str) -> bool {
    url_scheme(s).is_some_and(|scheme| {
        scheme.eq_ignore_ascii_case("http") || scheme.eq_ignore_ascii_case("https")
    })
}

/// `u` with its scheme in lower case (`HTTP://host/f` → `http://host/f`), as requests and messages use it.
pub(super) fn normalised_url(u: &str) -> String {
    match url_scheme(u) {
        Some(scheme) => format!("{}{}", scheme.to_ascii_lowercase(), &u[scheme.len()..]),
        None => u.to_string(),
    }
}

/// The scheme of `s` where it starts like a URL (`scheme://`, the scheme letters, digits, `+`, `-`, `.`
/// after a letter), else `None`.
pub(super) fn url_scheme(s: &str) -> Option<&str> {
    let (scheme, _) = s.split_once("://")?;
    let mut chars = scheme.chars();
    (chars.next()?.is_ascii_alphabetic()
        && chars.all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.')))
    .then_some(scheme)
}

/// Refuses, before any request, an https URL where this build has no TLS (the `https` cargo feature):
/// every attempt would fail the same way.
pub(super) fn check_url(u: &str) -> anyhow::Result<()> {
    if !cfg!(feature = "https") && url_scheme(u).is_some_and(|s| s.eq_ignore_ascii_case("https")) {
        bail!(
            "{}: this atlastree was built without TLS (cargo feature `https`), so it pages over plain \
             http:// only; serve the file with `atlastree serve` (http) or rebuild with `--features https`",
            atlastree::paging::redact_url(u)
        );
    }
    // An empty port is the scheme's default, as URLs have it. The port's text is not echoed: with an
    // unescaped `/` in a password it is part of the password.
    if let Some(port) = url_port(u)
        && !port.is_empty()
        && !(port.bytes().all(|b| b.is_ascii_digit()) && port.parse::<u16>().is_ok_and(|p| p > 0))
    {
        bail!(
            "{}: its port is not a port (digits, 1 to 65535); it would have been read as the scheme's \
             default",
            atlastree::paging::redact_url(u)
        );
    }
    Ok(())
}

/// The port text of `u`'s authority (after the host's first `:`, outside an IPv6 `[…]`), if it
/// names one: `http://127.0.0.1:70000/f` was sent to port 80 (fault hunt, session 34).
fn url_port(u: &str) -> Option<&str> {
    let (_, rest) = u.split_once("://")?;
    let authority = rest.split(['/', '?', '#']).next().unwrap_or("");
    let host_port = authority.rsplit_once('@').map_or(authority, |(_, h)| h);
    let after_host = match host_port.strip_prefix('[') {
        Some(v6) => v6.split_once(']')?.1,
        None => host_port.find(':').map_or("", |i| &host_port[i..]),
    };
    after_host.strip_prefix(':')
}

impl PagingArgs {
    /// The first flag given besides `--capacity`, for "means nothing here" messages.
    pub(crate) fn given_beyond_capacity(&self) -> Option<&'static str> {
        if self.source.is_some() {
            Some("--source")
        } else if let Some(f) = self.queue.given() {
            Some(f)
        } else if self.policy.is_some() {
            Some("--policy")
        } else if self.loader_threads.is_some() {
            Some("--loader-threads")
        } else if self.http_timeout.is_some() {
            Some("--http-timeout")
        } else if self.http_retries.is_some() {
            Some("--http-retries")
        } else {
            None
        }
    }

    /// The paging settings (capacity left at the default for the caller to set).
    pub(crate) fn validate(&self) -> anyhow::Result<Paging> {
        let source = match self.source.as_deref() {
            None | Some("file") => SourceArg::File,
            Some(u) if is_url(u) => {
                check_url(u)?;
                SourceArg::Url(normalised_url(u))
            }
            Some(other) => bail!("unknown --source {other:?}: expected `file` or an http(s) URL"),
        };
        if let Some(n) = self.loader_threads.filter(|&n| n > MAX_LOADER_THREADS) {
            bail!("--loader-threads must be 0 to {MAX_LOADER_THREADS} (got {n})");
        }
        let base = PagerOptions::default();
        let pager = self.queue.apply(PagerOptions {
            policy: self.policy.unwrap_or(base.policy),
            ..base
        })?;
        let http = HttpOptions::default();
        Ok(Paging {
            pager,
            source,
            loader_threads: self.loader_threads.unwrap_or(2),
            http_timeout: self
                .http_timeout
                .map_or(http.timeout, std::time::Duration::from_secs),
            http_retries: self.http_retries.unwrap_or(http.retries),
        })
    }
}

/// Build parameters beside the knobs of a build's shape and storage: the conditions the texel-per-pixel
/// guarantee is computed for, the bounds a build keeps to, when a node becomes a leaf and how it splits.
/// Shared by `build` and `sweep` (where they apply to every build of the grid; the grid sets d_min, atlas
/// size, border, filter, compression and repeat mode). Defaults are [`BuildOptions::default`]'s.
#[derive(Args, Debug, Clone)]
pub(crate) struct BuildParamsArgs {
    /// Screen width in pixels the guarantee is computed for (rescaled at run time without rebuild).
    #[arg(long, default_value_t = 800)]
    pub screen_width: u32,
    /// Horizontal field of view, degrees.
    #[arg(long, default_value_t = 60.0)]
    pub fov: f64,
    /// Texels per pixel required at d_min.
    #[arg(long, default_value_t = 1.0)]
    pub texel_ratio: f64,
    /// Maximum tree depth, 0 (one leaf per tree) to 30; a region that needs more is an error naming it.
    #[arg(long, default_value_t = 24,
          value_parser = clap::value_parser!(u8).range(0..=i64::from(atlastree::preprocess::MAX_DEPTH)))]
    pub max_depth: u8,
    /// Allow more texels per texture repetition than the source image has (by default capped).
    #[arg(long)]
    pub no_source_cap: bool,
    /// Bound on decoded source images held in memory at once, MiB (lowered to fit --max-memory).
    #[arg(long, default_value_t = 2048, value_parser = clap::value_parser!(u64).range(0..=u64::MAX >> 20))]
    pub image_cache_mib: u64,
    /// Memory budget of the build (e.g. `2GiB`, `512MiB`; `none` for no budget). It sizes the image cache;
    /// a build that cannot fit (the plan holds ~250 bytes per triangle and ~550 per extra piece where
    /// `--repeat bake` cuts them, the import ~16 bytes per byte of glTF JSON and the scene file and the
    /// buffers it reads, each whole, the rasteriser a few atlases
    /// per thread, the cache the threads' largest images, one each, never more than every image once) is
    /// refused before any work, with the number it needs. Default: half of the memory this process may
    /// use (the machine's, or its cgroup's limit where smaller: a Slurm job's `--mem`, a Kubernetes pod's
    /// limit; or `ulimit -v`). The rasteriser runs a thread per core; `RAYON_NUM_THREADS=N` runs N,
    /// which need less (each holds its atlases and images).
    #[arg(long, value_name = "SIZE", value_parser = parse_memory, allow_hyphen_values = true)]
    pub max_memory: Option<MemoryArg>,
    /// With `--repeat bake`: split a triangle too big for one atlas (a ground quad with a tile repeated
    /// hundreds of times) into at most this many pieces; beyond that its leaf's resolution is clamped. 1
    /// disables splitting. Wrapped repeats (the default) store one period and never split a triangle.
    #[arg(long, default_value_t = 4096, value_parser = clap::value_parser!(u32).range(1..))]
    pub max_pieces: u32,
    /// Refuse, before writing anything, a build whose paging file would exceed this size (GiB; fractions
    /// allowed, e.g. 0.5).
    #[arg(long, default_value_t = 64.0, value_parser = parse_gib)]
    pub max_file_gib: f64,
    /// A node that does not fit one atlas is not split when its original textures need at most this many
    /// atlases' worth of texels: it becomes a leaf whose atlas holds its content scaled to fit
    /// (min_distance raised by that scale), and nearer than that its original textures are drawn. Deeper
    /// leaves would mostly copy those originals (at R151 most real textures are needed at their source
    /// resolution), so this keeps the tree shallow while what a close camera needs stays pageable. 0: split
    /// every node that does not fit (the paper's tree).
    #[arg(long, default_value_t = 16.0)]
    pub leaf_originals: f64,
    /// What the split of a node into four balances (paper §5.3): `demand`, the summed atlas area the
    /// halves' textures need (the paper's condition b itself: a texture shared by many triangles or
    /// repeated counts once), or `area`, their summed world area (the paper's approximation).
    #[arg(long, default_value = "demand")]
    pub split: atlastree::preprocess::layout::SplitRule,
}

/// `--max-memory`: a size, or `none`.
#[derive(Copy, Clone, Debug)]
pub(crate) struct MemoryArg(Option<u64>);

impl MemoryArg {
    /// The bytes asked for (`None`: no budget), before [`within_limit`].
    pub(crate) fn bytes(self) -> Option<u64> {
        self.0
    }
}

fn parse_memory(s: &str) -> Result<MemoryArg, String> {
    if s.eq_ignore_ascii_case("none") {
        return Ok(MemoryArg(None));
    }
    match atlastree::util::parse_size(s) {
        Ok(b) if b >= 1 << 20 => Ok(MemoryArg(Some(b))),
        Ok(b) => Err(format!(
            "{s:?} is {b} bytes: a build's budget is at least 1MiB (e.g. 2GiB), or none"
        )),
        Err(why) => Err(format!(
            "{s:?} {why}: give a size (e.g. 2GiB, 512MiB, 8GB, 1.5e3MiB) or none"
        )),
    }
}

impl BuildParamsArgs {
    /// The memory budget in force: `--max-memory`, else the default
    /// ([`atlastree::preprocess::memory::default_budget`]).
    pub(crate) fn memory_budget(&self) -> Option<u64> {
        self.max_memory
            .map_or_else(atlastree::preprocess::memory::default_budget, |m| {
                within_limit(m.0)
            })
    }

    /// `base` with these parameters.
    pub(crate) fn apply(&self, base: BuildOptions) -> BuildOptions {
        BuildOptions {
            max_memory_bytes: self
                .max_memory
                .map_or(base.max_memory_bytes, |m| within_limit(m.0)),
            screen_width: self.screen_width,
            fov_deg: self.fov,
            texel_ratio: self.texel_ratio,
            max_depth: self.max_depth,
            cap_to_source: !self.no_source_cap,
            image_cache_bytes: self.image_cache_mib << 20,
            max_pieces: self.max_pieces,
            max_file_bytes: (self.max_file_gib * (1u64 << 30) as f64) as u64,
            leaf_originals_atlases: self.leaf_originals,
            split: self.split,
            ..base
        }
    }
}

/// [`atlastree::util::memory_limit_bytes`], read once a process: each read walks `/proc` and the cgroup
/// tree, and a build asks at every use of its options.
pub(crate) fn process_memory_limit() -> Option<u64> {
    static LIMIT: std::sync::OnceLock<Option<u64>> = std::sync::OnceLock::new();
    *LIMIT.get_or_init(atlastree::util::memory_limit_bytes)
}

/// An explicit budget, at most what this process may use (`util::memory_limit_bytes`: memory, cgroup,
/// `ulimit -v`): above it the budget bounded nothing and a build aborted on a failed allocation (the build
/// warns, naming both numbers).
fn within_limit(budget: Option<u64>) -> Option<u64> {
    match (budget, process_memory_limit()) {
        (Some(b), Some(limit)) => Some(b.min(limit)),
        (b, _) => b,
    }
}

/// A size in GiB for `--max-file-gib`: a finite number > 0 of at most 2²⁴ GiB (16 PiB).
fn parse_gib(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(g) if g.is_finite() && g > 0.0 && g <= f64::from(1u32 << 24) => Ok(g),
        Ok(g) if g > f64::from(1u32 << 24) => Err(format!(
            "{s} GiB is over the largest limit, 16777216 GiB (16 PiB)"
        )),
        _ => Err(format!("{s} is not a size in GiB > 0 (e.g. 64 or 0.5)")),
    }
}

/// Parses a comma-separated list flag's values with `f`, naming the flag, the value and `why` (what a
/// value must be) on failure.
pub(super) fn parse_list<T>(
    what: &str,
    why: &str,
    items: &[String],
    f: impl Fn(&str) -> Option<T>,
) -> anyhow::Result<Vec<T>> {
    items
        .iter()
        .map(|s| f(s.trim()).with_context(|| format!("bad --{what} value {s}: {why}")))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[test]
    fn a_port_that_is_not_one_is_refused() {
        assert_eq!(url_port("http://h:8077/f"), Some("8077"));
        assert_eq!(url_port("http://u:p@h:99/f?q=1"), Some("99"));
        assert_eq!(url_port("http://[::1]:70000/f"), Some("70000"));
        assert_eq!(url_port("http://[::1]/f"), None);
        assert_eq!(url_port("http://h/f:1"), None);
        assert!(check_url("http://127.0.0.1:8077/f").is_ok());
        assert!(check_url("http://h/f").is_ok());
        assert!(check_url("http://h:/f").is_ok(), "empty: the default port");
        for bad in [
            "http://127.0.0.1:70000/f",
            "http://h:0/f",
            "http://h:abc/f",
            "http://h:+80/f",
        ] {
            let e = check_url(bad).unwrap_err().to_string();
            assert!(e.contains("is not a port"), "{bad}: {e}");
        }
    }

    #[test]
    fn url_schemes_are_read_in_any_case() {
        assert!(is_url("http://h/f") && is_url("HTTP://h/f") && is_url("Https://h/f"));
        assert!(!is_url("ftp://h/f") && !is_url("city.atlastree") && !is_url("://h"));
        assert_eq!(url_scheme("ftp://h/f"), Some("ftp"));
        assert_eq!(url_scheme("a b://h"), None);
        assert_eq!(normalised_url("HTTP://Host/F"), "http://Host/F");
    }

    #[derive(Parser)]
    struct Build {
        #[command(flatten)]
        params: BuildParamsArgs,
    }

    /// Without flags the shared build parameters are the library's defaults, so `sweep` builds exactly
    /// what it built before it took them.
    #[test]
    fn build_parameter_defaults_are_the_librarys() {
        let b = Build::parse_from(["build"]);
        let ours = serde_json::to_value(b.params.apply(BuildOptions::default())).unwrap();
        let lib = serde_json::to_value(BuildOptions::default()).unwrap();
        assert_eq!(ours, lib);
    }

    #[test]
    fn simulate_refuses_a_time_budget_and_keeps_bytes() {
        let q = |b: &str| QueueArgs {
            upload_budget: Some(b.parse().unwrap()),
            max_queue: None,
        };
        let e = q("2ms").byte_budget().unwrap_err().to_string();
        assert!(
            e.contains("--upload-budget 2ms") && e.contains("no uploads"),
            "{e}"
        );
        assert_eq!(
            q("8MB").byte_budget().unwrap(),
            UploadBudget::Bytes(8_000_000)
        );
        assert_eq!(
            QueueArgs::default().byte_budget().unwrap(),
            UploadBudget::Unlimited
        );
    }

    #[test]
    fn capacity_takes_a_block_count_or_all() {
        #[derive(Parser)]
        struct Paged {
            #[command(flatten)]
            paging: PagingArgs,
        }
        let k =
            |v: &str| Paged::try_parse_from(["render", "--capacity", v]).map(|p| p.paging.capacity);
        assert_eq!(k("160").unwrap(), Some(Capacity::Blocks(160)));
        assert_eq!(k("all").unwrap(), Some(Capacity::All));
        assert_eq!(Capacity::All.blocks(), None);
        for bad in ["0", "-1", "ALL", "1.5", ""] {
            assert!(k(bad).is_err(), "{bad:?} accepted");
        }
    }

    /// `--http-timeout` and `--http-retries` reach the HTTP client (a stalled server held a synchronous
    /// loader for 4 attempts of 30 s a block, with no way to shorten it); without them its defaults;
    /// out of range refused by the parser.
    #[test]
    fn http_flags_reach_the_client_options() {
        #[derive(Parser)]
        struct Paged {
            #[command(flatten)]
            paging: PagingArgs,
        }
        let argv = [
            "render",
            "--capacity",
            "8",
            "--http-timeout",
            "2",
            "--http-retries",
            "0",
        ];
        let given = Paged::parse_from(argv).paging;
        assert_eq!(given.given_beyond_capacity(), Some("--http-timeout"));
        let o = given.validate().unwrap().http_options();
        assert_eq!(
            (o.timeout, o.retries),
            (std::time::Duration::from_secs(2), 0)
        );
        let d = Paged::parse_from(["render", "--capacity", "8"]).paging;
        let (o, def) = (d.validate().unwrap().http_options(), HttpOptions::default());
        assert_eq!((o.timeout, o.retries), (def.timeout, def.retries));
        for bad in [["--http-timeout", "0"], ["--http-retries", "21"]] {
            assert!(Paged::try_parse_from([&["render"][..], &bad[..]].concat()).is_err());
        }
    }

    #[test]
    fn viewport_defaults_differ_per_group() {
        #[derive(Parser)]
        struct Window {
            #[command(flatten)]
            window: WindowArgs,
        }
        #[derive(Parser)]
        struct Offscreen {
            #[command(flatten)]
            viewport: ViewportArgs,
        }
        let w = Window::parse_from(["view"]).window;
        let v = Offscreen::parse_from(["render"]).viewport;
        assert_eq!(
            (w.width, w.height, v.width, v.height),
            (1280, 720, 800, 600)
        );
        let zero = Offscreen::parse_from(["render", "--width", "0"]).viewport;
        assert!(zero.validate().is_err());
        assert!(v.validate().is_ok());
    }
}
